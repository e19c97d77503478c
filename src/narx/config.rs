//! The unfitted NARX model: which signals, which lags, which network, how to train it.

use super::regressors::Lags;
use super::NarxError;
use serde::{Deserialize, Serialize};

/// Gradient method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum OptimizerKind {
    /// RMSProp (rho 0.9, eps 1e-7, as Keras; the source study's).
    Rmsprop,
    /// Adam (0.9, 0.999, eps 1e-8).
    Adam,
}

/// Training protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Protocol {
    /// Reliable free run: linear bypass initialised by least squares, one-step pretraining with
    /// early stopping, then simulation-error training over windows (backpropagation through the
    /// fed-back outputs), restarts selected by free-run error on a validation part.
    Default,
    /// The source study: plain MLP, one-step-ahead training only, all training samples, no
    /// early stopping.
    Study,
}

/// An unfitted NARX model (one MISO network per output, all exogenous signals in each).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NarxConfig {
    /// Exogenous signals: the inputs, then any extra feature signals computed from them.
    pub inputs: Vec<String>,
    /// Modelled outputs.
    pub outputs: Vec<String>,
    pub lags: Lags,
    /// Neurons per hidden layer.
    pub neurons: usize,
    /// Hidden tanh layers.
    pub layers: usize,
    pub optimizer: OptimizerKind,
    /// Learning rate of the one-step phase.
    pub lr: f64,
    /// Mini-batch size of the one-step phase.
    pub batch: usize,
    /// Epochs of the one-step phase (a maximum when early stopping is on).
    pub epochs: usize,
    pub seed: u64,
    pub protocol: Protocol,
    /// Settings of the default protocol (ignored by `study`).
    #[serde(default)]
    pub robust: RobustSettings,
}

/// Settings of the default (free-run reliable) protocol.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobustSettings {
    /// Linear bypass from the regressor to the output, initialised by least squares (ARX).
    pub bypass: bool,
    /// Fraction of the training record kept (at its end) for validation.
    pub validation_fraction: f64,
    /// One-step phase: epochs without validation improvement before stopping.
    pub patience: usize,
    /// Independent initialisations; the best free run on validation wins. `None`: 2, or 8 for
    /// training records under 5,000 samples (cheap, and selection matters most there).
    pub restarts: Option<usize>,
    /// Simulation-error phase: maximum number of gradient steps.
    pub sim_steps: usize,
    /// Samples per window (multiple shooting: each window starts from measured outputs).
    pub window: usize,
    /// Simulated samples per gradient step (windows per step = this / window).
    pub samples_per_step: usize,
    /// Adam learning rate of the simulation-error phase.
    pub sim_lr: f64,
    /// Validate every this many steps.
    pub eval_every: usize,
    /// Evaluations without improvement before stopping.
    pub sim_patience: usize,
    /// L2 penalty on the hidden-layer weights in the simulation-error phase (smoother maps
    /// extrapolate better on short records).
    #[serde(default)]
    pub weight_decay: f64,
}

impl Default for RobustSettings {
    fn default() -> Self {
        RobustSettings {
            bypass: true,
            validation_fraction: 0.2,
            patience: 10,
            restarts: None,
            sim_steps: 300,
            window: 1000,
            samples_per_step: 8000,
            sim_lr: 2e-3,
            eval_every: 10,
            sim_patience: 6,
            weight_decay: 0.0,
        }
    }
}

impl RobustSettings {
    /// Restarts for a training record of `n` samples.
    pub fn restarts_for(&self, n: usize) -> usize {
        self.restarts.unwrap_or(if n < 5000 { 8 } else { 2 })
    }
}

impl NarxConfig {
    /// A configuration with the study's shape (4 lags, 10 neurons, one hidden layer) and the
    /// default protocol.
    pub fn new(inputs: Vec<String>, outputs: Vec<String>) -> NarxConfig {
        NarxConfig {
            inputs,
            outputs,
            lags: Lags {
                output: 4,
                input: 4,
                delay: 1,
            },
            neurons: 10,
            layers: 1,
            optimizer: OptimizerKind::Adam,
            lr: 0.01,
            batch: 128,
            epochs: 100,
            seed: 0,
            protocol: Protocol::Default,
            robust: RobustSettings::default(),
        }
    }

    /// Check every setting; the error names the field and the rule.
    pub fn check(&self) -> Result<(), NarxError> {
        let bad = |field, value: String, rule| Err(NarxError::InvalidConfig { field, value, rule });
        if self.inputs.is_empty() {
            return bad("inputs", "[]".into(), "name at least one input signal");
        }
        if self.outputs.is_empty() {
            return bad("outputs", "[]".into(), "name at least one output signal");
        }
        if self.lags.output == 0 {
            return bad(
                "lags (output)",
                "0".into(),
                "a NARX model needs at least one output lag",
            );
        }
        if self.lags.input == 0 {
            return bad("lags (input)", "0".into(), "needs at least one input lag");
        }
        if self.neurons == 0 {
            return bad(
                "neurons",
                "0".into(),
                "needs at least one neuron per hidden layer",
            );
        }
        if self.layers == 0 {
            return bad("layers", "0".into(), "needs at least one hidden layer");
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return bad("lr", self.lr.to_string(), "must be a finite number > 0");
        }
        if self.batch == 0 {
            return bad("batch", "0".into(), "must be at least 1");
        }
        if self.epochs == 0 {
            return bad("epochs", "0".into(), "must be at least 1");
        }
        let r = &self.robust;
        if !(r.validation_fraction >= 0.0 && r.validation_fraction < 0.9) {
            return bad(
                "validation_fraction",
                r.validation_fraction.to_string(),
                "must be in [0, 0.9)",
            );
        }
        if r.restarts == Some(0) {
            return bad("restarts", "0".into(), "must be at least 1");
        }
        if r.window < 2 || r.samples_per_step == 0 || r.eval_every == 0 {
            return bad(
                "window/samples_per_step/eval_every",
                format!("{}/{}/{}", r.window, r.samples_per_step, r.eval_every),
                "must be positive (window >= 2)",
            );
        }
        if !(r.sim_lr.is_finite() && r.sim_lr > 0.0) {
            return bad(
                "sim_lr",
                r.sim_lr.to_string(),
                "must be a finite number > 0",
            );
        }
        Ok(())
    }

    /// Network layer widths for `n_signals` exogenous signals.
    pub fn sizes(&self) -> Vec<usize> {
        let mut s = vec![self.lags.width(self.inputs.len())];
        s.extend(std::iter::repeat_n(self.neurons, self.layers));
        s.push(1);
        s
    }
}
