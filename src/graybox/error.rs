use crate::data::DataError;
use crate::plant::PlantError;
use std::path::PathBuf;

/// What can go wrong when configuring, fitting, reading or simulating a grey-box model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GreyBoxError {
    #[error("unknown effect `{name}`; the valid effects are: {valid}")]
    UnknownEffect { name: String, valid: String },
    #[error("`{name}` is named twice in the effect list")]
    RepeatedEffect { name: String },
    #[error("two {effect} operators are named (`{first}` and `{second}`); name one of {options}")]
    TwoOperators {
        effect: String,
        first: String,
        second: String,
        options: String,
    },
    #[error(
        "{path}: `{effect}` needs a record with several inputs (at least {needed}), but it has {inputs} ({names}): {why}"
    )]
    NeedsInputs {
        path: PathBuf,
        effect: String,
        needed: usize,
        inputs: usize,
        names: String,
        why: String,
    },
    #[error("{path}: output {output} (`{name}`) has no input of the same index ({inputs} inputs: {names}); add `coupling` so that every output sees every input, or select fewer outputs")]
    NoDirectInput {
        path: PathBuf,
        output: usize,
        name: String,
        inputs: usize,
        names: String,
    },
    #[error("{path}: the record has {samples} samples; fitting {effects} needs at least {needed}: {why}")]
    TooShort {
        path: PathBuf,
        samples: usize,
        needed: usize,
        effects: String,
        why: String,
    },
    #[error("{path}: input `{input}` is too poorly excited for {effect}: {why}")]
    PoorlyExcited {
        path: PathBuf,
        input: String,
        effect: String,
        why: String,
    },
    #[error("{path}: the record has no output column to fit; name one with --outputs")]
    NoOutputs { path: PathBuf },
    #[error("{path}: `{column}` is constant; there is nothing to fit")]
    ConstantOutput { path: PathBuf, column: String },
    #[error("--plays 0: give at least one play operator")]
    NoPlays,
    #[error("--train-fraction {value}: must be a number in (0, 1]")]
    TrainFraction { value: f64 },
    #[error("{what} `{name}` of the model is not in the record {path} (its columns: {available})")]
    MissingColumn {
        path: PathBuf,
        what: String,
        name: String,
        available: String,
    },
    #[error(
        "the fit of output `{output}` produced a non-finite value ({what}); nothing was written"
    )]
    NonFinite { output: String, what: String },
    /// The file cannot be read, or its JSON does not parse (with the line and column).
    #[error(transparent)]
    File(#[from] crate::data::JsonFileError),
    #[error("{path}: not a grey-box model file (`format` is {found}; expected \"hystbench-greybox\"); a NARX model or a plant file is read by other commands")]
    WrongFormat { path: PathBuf, found: String },
    #[error("{path}: grey-box model file version {found} is not supported; this hystbench reads version {supported}")]
    WrongVersion {
        path: PathBuf,
        found: String,
        supported: u32,
    },
    #[error("{path}: `{field}`: {rule}")]
    Inconsistent {
        path: PathBuf,
        field: String,
        rule: String,
    },
    #[error(transparent)]
    Plant(#[from] PlantError),
    #[error(transparent)]
    Data(#[from] DataError),
}
