use crate::effect::EffectError;
use std::path::PathBuf;

/// What can be wrong with a plant file or a simulation.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlantError {
    /// The file cannot be read, or its JSON does not parse (with the line and column).
    #[error(transparent)]
    File(#[from] crate::data::JsonFileError),
    #[error("{path}: {field}: {source}")]
    Effect {
        path: PathBuf,
        field: String,
        source: EffectError,
    },
    #[error("{path}: `{field}`: {rule}")]
    Structure {
        path: PathBuf,
        field: String,
        rule: String,
    },
    #[error("the plant has {expected} inputs ({names}) but {found} input signals were given")]
    InputCount {
        expected: usize,
        found: usize,
        names: String,
    },
    #[error("simulation of output `{output}` left the finite range at sample {sample} (value {value}); check the parameters and the input amplitude")]
    Diverged {
        output: String,
        sample: usize,
        value: f64,
    },
    #[error("ODE plant: {0}")]
    Ode(#[from] super::ode::OdeError),
}
