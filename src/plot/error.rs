//! The one error type of the figure layer.

use crate::data::DataError;
use std::path::PathBuf;

/// Everything that can go wrong while making a figure.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// Reading the record or writing the figure failed (file, line, column in the message).
    #[error(transparent)]
    Data(#[from] DataError),
    #[error("{path}: unknown figure format `{extension}`; the extension picks the format: use .png or .svg")]
    UnknownFormat { path: PathBuf, extension: String },
    #[error(
        "{path}: {samples} samples are too few for a {what} figure: at least {needed} are needed"
    )]
    TooFewSamples {
        path: PathBuf,
        what: String,
        samples: usize,
        needed: usize,
    },
    #[error("{path}: no model prediction for output `{output}`: a column `{output}_hat` is needed (as written by `hystbench predict`); the columns are: {available}")]
    NoPrediction {
        path: PathBuf,
        output: String,
        available: String,
    },
    #[error("{path}: the window {from} s .. {to} s holds fewer than 2 samples; the record spans {start} s .. {end} s")]
    EmptyWindow {
        path: PathBuf,
        from: f64,
        to: f64,
        start: f64,
        end: f64,
    },
    #[error("{path}: line {line}, column `{column}`: {problem}")]
    BadCell {
        path: PathBuf,
        line: usize,
        column: String,
        problem: String,
    },
    #[error("{path}: line 1: the header has no column `{name}`; expected the columns {expected}; found: {available}")]
    MissingHeader {
        path: PathBuf,
        name: String,
        expected: String,
        available: String,
    },
    #[error("{path}: no data rows after the header")]
    NoRows { path: PathBuf },
    #[error("figure size {width}x{height} is out of range: each side must be within {min}..={max} pixels")]
    BadSize {
        width: u32,
        height: u32,
        min: u32,
        max: u32,
    },
    #[error(
        "the embedded font could not be loaded (src/plot/fonts/DejaVuSans.ttf is not a valid TTF)"
    )]
    Font,
    #[error("drawing the figure failed: {0}")]
    Render(String),
    #[error("encoding the PNG failed: {0}")]
    Encode(String),
    #[error("{what}: {problem}")]
    Invalid { what: String, problem: String },
}
