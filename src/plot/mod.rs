//! # Figures
//!
//! PNG and SVG figures of hysteretic records and of models fitted to them, good enough to go into
//! a paper as they come out. Text is drawn with the embedded DejaVu Sans (registered under
//! "sans-serif", "serif" and "monospace"), so no system font is needed.
//!
//! | kind | module | what it shows |
//! |---|---|---|
//! | loop | [`loops`] | output against input; MIMO grids with cross loops; overlays; colour by time or cycle |
//! | time | [`time`] | measured, model and residual over time, with a zoom window |
//! | residual-loop | [`residual_loop`] | residual against input, with its normalised loop area |
//! | parity | [`parity`] | predicted against measured, one-step ahead and free run side by side |
//! | spectrum | [`spectrum`] | amplitude spectra of measurement and residual (Welch, Hann window) |
//! | sweep | [`sweep`] | heat maps of free-run test R^2 over lags x neurons from a sweep's `results.csv` |
//! | ladder | [`ladder`] | the model-improvement loop's error after each added effect |
//! | zoo | [`zoo`] | per class of a plant zoo, the distribution of free-run test 1 - R^2 (identifier, ARX, true plant) |
//!
//! Each figure is a type implementing [`Figure`]; [`save`] renders it in memory and writes the
//! file atomically (the extension picks the format). Long records are decimated for drawing
//! without losing turning points ([`decimate`]).
//!
//! ## References
//! - plotters 0.3.7, <https://docs.rs/plotters/0.3.7>.
//! - DejaVu Sans, Bitstream Vera derived licence: `src/plot/fonts/DejaVuSans-LICENSE.txt`.

pub mod axes;
pub mod decimate;
mod error;
pub mod ladder;
pub mod loops;
pub mod parity;
pub mod render;
mod report;
pub mod residual_loop;
pub mod residual_where;
pub mod source;
pub mod spectrum;
pub mod style;
pub mod sweep;
mod table;
pub mod time;
pub mod zoo;

pub use error::PlotError;

pub use loops::{loop_figure, LoopColour, LoopFigure, LoopOptions};

pub use render::{register_embedded_font, render, save, Figure, Format};

pub use source::PlotRecord;

pub use ladder::{ladder_figure, read_ladder, LadderFigure, LadderStep};
pub use parity::{parity_figure, ParityFigure};
pub use report::report_figures;
pub use residual_loop::{residual_loop_figure, ResidualLoopFigure};
pub use residual_where::{residual_where_figure, ResidualWhereFigure};
pub use spectrum::{amplitude_spectrum, spectrum_figure, SpectrumFigure};
pub use sweep::{read_sweep, sweep_figure, SweepFigure, SweepRow};
pub use time::{time_figure, TimeFigure};
pub use zoo::{zoo_figure, ZooClassCurves, ZooFigure};
