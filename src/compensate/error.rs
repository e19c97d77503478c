use crate::plant::PlantError;

/// Why a model cannot be turned into a compensating input.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CompensateError {
    #[error(transparent)]
    Plant(#[from] PlantError),
    #[error("plant `{plant}` is integrated as an ODE over a whole record and cannot be stepped one sample at a time: compensate with a chain plant or a grey-box model of it")]
    NotAChain { plant: String },
    #[error("the model has {expected} outputs ({names}) but {found} reference signals were given; name the reference columns with --columns")]
    ReferenceCount {
        expected: usize,
        found: usize,
        names: String,
    },
    #[error("the reference of output `{output}` has {found} samples, the first one {expected}: give every output's reference over the same samples")]
    ReferenceLength {
        output: String,
        found: usize,
        expected: usize,
    },
    #[error("the model has {inputs} inputs for {outputs} outputs: a reference per output does not fix every input")]
    MoreInputsThanOutputs { inputs: usize, outputs: usize },
    #[error("no value of input `{input}` brings output `{output}` to {target} at sample {sample}: the model is not monotone in its newest input there (or diverges); check the model, or give actuator limits with --limits")]
    NoRoot {
        input: String,
        output: String,
        sample: usize,
        target: f64,
    },
}
