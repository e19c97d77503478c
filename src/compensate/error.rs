use crate::model::ModelError;
use crate::plant::PlantError;

/// Why a model cannot be turned into a compensating input.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CompensateError {
    #[error(transparent)]
    Plant(#[from] PlantError),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error("{model} is integrated as an ODE over a whole record and cannot be stepped one sample at a time: compensate with a chain plant, a grey-box model or a NARX model of it")]
    NotStepped { model: String },
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
    #[error("the model's output `{output}` is not finite at sample {sample} for the values of input `{input}` that would bring it to {target}: the model diverges there (a NARX model leaving its training range); check it with `hystbench compare`, or keep the input within the range it was trained on with --limits")]
    Diverged {
        input: String,
        output: String,
        sample: usize,
        target: f64,
    },
}
