use std::path::PathBuf;

/// Everything that can go wrong when configuring, training, applying or loading a NARX model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NarxError {
    #[error("`{field}` = {value}: {rule}")]
    InvalidConfig {
        field: &'static str,
        value: String,
        rule: &'static str,
    },
    #[error("{path}: {rows} samples are too few: the lags need {needed} ({why})")]
    TooShort {
        path: PathBuf,
        rows: usize,
        needed: usize,
        why: String,
    },
    #[error("{path}: {total} samples split in halves leave {train} for training, the lags need {needed}: give a separate test record")]
    HalvesTooShort {
        path: PathBuf,
        total: usize,
        train: usize,
        needed: usize,
    },
    #[error("{path}: output `{name}` is constant ({value}) in the training part; R^2 is undefined for a constant signal and a model of it is meaningless")]
    ConstantOutput {
        path: PathBuf,
        name: String,
        value: f64,
    },
    #[error("{path}: the model expects {what} columns {expected}, the record has {found}; apply a model only to records with the columns it was trained on")]
    ColumnMismatch {
        path: PathBuf,
        what: &'static str,
        expected: String,
        found: String,
    },
    #[error("{path}: one-step-ahead prediction needs the measured outputs {expected}, which the record lacks")]
    OutputsNeeded { path: PathBuf, expected: String },
    #[error(
        "training of output `{output}` produced non-finite weights (learning rate {lr} too large?)"
    )]
    NonFiniteWeights { output: String, lr: f64 },
    #[error("{path}: the linear least squares of output `{output}` has no unique solution (an input or the output does not vary, or the columns repeat each other); check the record's columns")]
    Singular {
        path: std::path::PathBuf,
        output: String,
    },
    #[error("features `{value}`: {why}")]
    Features { value: String, why: String },
    #[error("{effect}: no basis signals for this record ({why})")]
    NoFeatures { effect: String, why: &'static str },
    #[error("{path}: not a hystbench NARX model file: {why}")]
    NotAModel { path: PathBuf, why: String },
    #[error("{path}: model file version {found} is not supported (this hystbench reads version {supported}); retrain the model with this version")]
    Version {
        path: PathBuf,
        found: String,
        supported: u32,
    },
    #[error("{path}: damaged model file: {why}")]
    Damaged { path: PathBuf, why: String },
    /// The file cannot be read, or its JSON does not parse (with the line and column).
    #[error(transparent)]
    File(#[from] crate::data::JsonFileError),
}
