use std::path::PathBuf;

/// Everything that can be wrong with a record or an output path.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DataError {
    #[error("{path}: {what}{} needs about {} of memory, and {} is available to it: {advice}, or a machine with more memory (HYSTBENCH_MEMORY_AVAILABLE=BYTES sets the figure to go by)", samples_text(*samples), super::memory::human(*needed), super::memory::human(*available))]
    TooLarge {
        path: PathBuf,
        what: String,
        advice: &'static str,
        samples: usize,
        needed: u64,
        available: u64,
    },
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: the file is empty; a record needs a header row and at least one data row")]
    Empty { path: PathBuf },
    #[error("{path}: line {line}: the header has an empty column name at position {position}")]
    EmptyHeaderName {
        path: PathBuf,
        line: usize,
        position: usize,
    },
    #[error("{path}: line {line}: the column name `{name}` appears twice")]
    DuplicateColumn {
        path: PathBuf,
        line: usize,
        name: String,
    },
    #[error("{path}: line {line}: {found} cells, but the header has {expected} columns")]
    RaggedRow {
        path: PathBuf,
        line: usize,
        expected: usize,
        found: usize,
    },
    #[error("{path}: line {line}, column `{column}`: `{cell}` is not a number (every cell must be a finite decimal number)")]
    NotANumber {
        path: PathBuf,
        line: usize,
        column: String,
        cell: String,
    },
    #[error("{path}: line {line}, column `{column}`: missing value (empty cell); fill or remove the row")]
    MissingCell {
        path: PathBuf,
        line: usize,
        column: String,
    },
    #[error("{path}: line {line}, column `{column}`: `{cell}` is not finite (NaN or infinity are not allowed)")]
    NotFinite {
        path: PathBuf,
        line: usize,
        column: String,
        cell: String,
    },
    #[error("{path}: column `{column}` has {found} values, the time has {expected}; give every signal one value per sample")]
    ArrayLength {
        path: PathBuf,
        column: String,
        found: usize,
        expected: usize,
    },
    #[error("{path}: has no column `{name}`; the columns are: {available}")]
    MissingColumn {
        path: PathBuf,
        name: String,
        available: String,
    },
    #[error("{path}: {what}; the columns are: {available}")]
    NoDefaultColumns {
        path: PathBuf,
        what: String,
        available: String,
    },
    #[error("{path}: line {line}: time `{column}` = {time} breaks uniform sampling ({deviation:.3e} s off the grid of period {period} s from the start). {detail}")]
    NonUniformTime {
        path: PathBuf,
        line: usize,
        column: String,
        time: f64,
        period: f64,
        deviation: f64,
        /// The record's time steps in words (gaps, jitter) and what to do.
        detail: String,
    },
    #[error(
        "{path}: time column `{column}` does not increase (line {line}: {time} after {previous})"
    )]
    TimeNotIncreasing {
        path: PathBuf,
        line: usize,
        column: String,
        time: f64,
        previous: f64,
    },
    #[error("{path}: {rows} data rows are too few: {needed} needed ({why})")]
    TooShort {
        path: PathBuf,
        rows: usize,
        needed: usize,
        why: String,
    },
    #[error("{path}: output `{name}` is constant ({value}); R^2 and the normalised errors are undefined for a constant signal")]
    ConstantOutput {
        path: PathBuf,
        name: String,
        value: f64,
    },
    #[error("{path}: line {line}, column `{column}`: {value:e} is a gross outlier, beyond {ranges} times the column's range from its neighbours (a glitch of the logger; {count} such sample(s), lines {lines}); repair the lines, or pass `--outliers repair` (each replaced by the line between its good neighbours) or `--outliers keep`; `hystbench inspect` lists them all", ranges = crate::data::inspect::GROSS_RANGES)]
    GrossOutlier {
        path: PathBuf,
        line: usize,
        column: String,
        value: f64,
        count: usize,
        /// The file's lines of the first few (comma-separated).
        lines: String,
    },
    #[error("{path}: already exists; pass --force to overwrite it")]
    Exists { path: PathBuf },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(
        "refusing to write a non-finite value ({value}) in column `{column}`, row {row}, to {path}"
    )]
    NonFiniteOutput {
        path: PathBuf,
        column: String,
        row: usize,
        value: f64,
    },
}

/// " on N samples" (nothing when the size is not yet known).
fn samples_text(samples: usize) -> String {
    if samples == 0 {
        String::new()
    } else {
        format!(" on {samples} samples")
    }
}
