use std::path::PathBuf;

/// What can be wrong with a scenario file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScenarioError {
    /// The file cannot be read, or its JSON does not parse (with the line and column).
    #[error(transparent)]
    File(#[from] crate::data::JsonFileError),
    #[error("{path}: `{field}` = {value}: {rule}")]
    Invalid {
        path: PathBuf,
        field: String,
        value: String,
        rule: String,
    },
    #[error("{path}: `{field}`: the scenario is too short for its parts: {detail}")]
    TooShort {
        path: PathBuf,
        field: String,
        detail: String,
    },
}
