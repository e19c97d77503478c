//! # Records
//!
//! A record is a table of equally sampled signals read from, or written to, CSV with a header row.
//! `t` (or the first column named `t…`) is the time in seconds; inputs are `u`, `u1`, `u2`…;
//! outputs are `y`, `y1`, `y2`… unless the caller names other columns.
//!
//! Everything that touches the user's files lives here: parsing with line and column in every
//! error, the uniform-time check, the default column conventions and atomic writes that never leave
//! a partial file behind or overwrite without `force`.

mod csv;
mod error;
mod io_record;
mod json;
mod split;
mod write;

pub mod inspect;
pub mod memory;
pub use csv::{parse_csv, read_csv, CsvFormat, Record, TimeSteps};
pub use error::DataError;
pub use io_record::default_names;
pub use io_record::{IoRecord, Signal};
pub use json::{
    is_default, parse_json_file, read_json_file, read_json_text, FileHeader, JsonFileError,
};
pub use split::{split_at_gaps, Part, Split};
pub use write::{check_writable, format_csv, write_atomic, write_csv_atomic, OutputGuard};
