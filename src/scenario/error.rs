use std::path::PathBuf;

/// What can be wrong with a scenario file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScenarioError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: line {line}, column {column}: {message}")]
    Json {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
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
