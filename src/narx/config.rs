//! The unfitted NARX model: which signals, which lags, which network, how to train it.

use super::mlp::Mlp;
use super::regressors::Lags;
use super::NarxError;
use crate::effect::EffectName;
use crate::effect::FeatureSpec;
use serde::{Deserialize, Serialize};

/// The NARX features of the named effects on a training record, in the order named:
/// `identify --features hysteresis,creep`.
pub fn features_of(
    effects: &[EffectName],
    train: &crate::data::IoRecord,
) -> Result<Vec<FeatureSpec>, NarxError> {
    let inputs: Vec<&[f64]> = train.inputs.iter().map(|s| &s.values[..]).collect();
    let mut specs: Vec<FeatureSpec> = Vec::new();
    for &e in effects {
        let Some(effect) = crate::effect::registry::effect(e) else {
            continue;
        };
        let f = effect.features(&inputs, train.ts);
        if f.is_empty() {
            return Err(NarxError::NoFeatures {
                effect: e.to_string(),
                why: effect.no_features(),
            });
        }
        specs.extend(f);
    }
    Ok(specs)
}

/// A setting named on the command line: its names and how they parse.
macro_rules! named_setting {
    ($t:ty, $( $v:ident => $n:literal ),+ $(,)?) => {
        impl $t {
            /// The names, as the command line and model files write them.
            pub const NAMES: &'static [&'static str] = &[$($n),+];
            /// This setting's name.
            pub fn as_str(self) -> &'static str {
                match self { $(Self::$v => $n),+ }
            }
        }
        impl std::str::FromStr for $t {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                match s {
                    $($n => Ok(Self::$v),)+
                    _ => Err(format!("`{s}`: one of {}", Self::NAMES.join(", "))),
                }
            }
        }
    };
}
pub(crate) use named_setting;

named_setting!(OptimizerKind, Rmsprop => "rmsprop", Adam => "adam");
named_setting!(Protocol, Default => "default", Study => "study");
named_setting!(Interaction, Full => "full", Additive => "additive");

/// Gradient method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OptimizerKind {
    /// RMSProp (rho 0.9, eps 1e-7, as Keras; the source study's).
    Rmsprop,
    /// Adam (0.9, 0.999, eps 1e-8).
    Adam,
}

/// Training protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
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

/// How the exogenous signals meet inside the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Interaction {
    /// Every hidden neuron sees every regressor column (the source study's MLP; the value of
    /// model files written before this setting existed).
    #[default]
    Full,
    /// Additive in the inputs: the hidden neurons are split into one group per input (neuron j
    /// serves input j mod m); a group sees the output lags and the lags of its own input and of
    /// the features computed from it. The inputs' contributions add up (through the output
    /// lags they still shape each other's dynamics), as the paths from separate electrodes
    /// superpose in a 2-DoF piezo cantilever (PHYSICS.md section 4). A short record visits only
    /// some combinations of the inputs; a full network maps the others by extrapolation, an
    /// additive one does not need them. With one input it is the full network.
    Additive,
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
    /// How the inputs meet inside the network (default of [`NarxConfig::new`]: additive).
    #[serde(default)]
    pub interaction: Interaction,
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
    /// Extra exogenous signals computed from the inputs (effect-library basis signals with
    /// numbers fixed on the training record), after the inputs; recomputed on every record.
    #[serde(default)]
    pub features: Vec<FeatureSpec>,
    /// The model's sampling: every `decimation`-th sample of a record (the model runs on each
    /// of the record's `decimation` phases and their predictions interleave). 1: every sample.
    /// The default protocol chooses it on the training record (`robust.try_decimation`).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub decimation: usize,
}

fn one() -> usize {
    1
}

fn is_one(v: &usize) -> bool {
    *v == 1
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
    /// Records shorter than [`SHORT_RECORD`] samples get the short-record settings (see
    /// [`RobustSettings::for_record`]) for every field left at its default.
    #[serde(default = "yes")]
    pub short_record_settings: bool,
    /// Feature selection by the protocol: the model is fitted without and with these effects'
    /// basis signals (`Effect::features` on the training record, added to
    /// `features`), and the one with the lower free-run validation error (training record only,
    /// summed over the outputs in standardised units) is kept. Default: empty, no selection
    /// (the grey-box base carries the physics; `identify --features auto` and
    /// [`crate::effect::registry::narx_candidates`] try the hysteresis plays). Ignored by
    /// `study` and on records under [`SHORT_RECORD`] samples (no validation part to decide on).
    #[serde(default)]
    pub try_features: Vec<EffectName>,
    /// The features are kept only when they bring the free-run validation MSE below this
    /// fraction of the plain model's: a clear win, not noise (the criterion itself varies by
    /// up to 5x between restarts and seeds of the same model on the same plant).
    #[serde(default = "feature_gain")]
    pub feature_gain: f64,
    /// Ensemble: the model keeps this many restarts (best training free runs first) per output
    /// and predicts with their [`Combine`] (one-step predictions and free runs alike). `None`
    /// (default): [`SHORT_ENSEMBLE`] networks on records under [`SHORT_RECORD`] samples (with
    /// `short_record_settings`), one network on longer records. `Some(1)`: one network (the
    /// best restart) everywhere.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ensemble: Option<usize>,
    /// How the members of an ensemble are combined, sample by sample. Model files written
    /// before this setting existed used the mean (the value when the field is missing); new
    /// models use the median.
    #[serde(default)]
    pub combine: Combine,
    /// Try coarser model samplings on an oversampled record (decimations of 4, 16, 64 that keep
    /// the record's 99 % bandwidth below an eighth of the new sampling rate and leave 1,000
    /// samples per phase) and keep the one with the lowest free-run validation error.
    #[serde(default = "yes")]
    pub try_decimation: bool,
    /// Try a grey-box base under the networks ([`crate::narx::base`]): a grey-box model of
    /// the effect library, alone or with a network on its residual, kept per output where it
    /// validates better than the network.
    #[serde(default = "yes")]
    pub try_greybox: bool,
    /// Restarts, the prediction's own networks included, whose free runs' spread widens the
    /// prediction band where they part ([`crate::narx::band`]); 1: a band of constant width
    /// around one network.
    #[serde(default = "band_restarts")]
    pub band_restarts: usize,
}

/// Networks kept per output on short records (the median of 8 free runs: one or two members
/// that extrapolate wildly out of a short record do not move it).
pub const SHORT_ENSEMBLE: usize = 8;

/// How an ensemble's predictions are combined at each sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Combine {
    /// The mean of the members.
    #[default]
    Mean,
    /// The median of the members (the mean of the middle two for an even number).
    Median,
}

impl Combine {
    /// The members' values combined (reorders `v`); one value is returned as it is.
    pub fn apply(self, v: &mut [f64]) -> f64 {
        let k = v.len();
        if k == 1 {
            return v[0];
        }
        match self {
            Combine::Mean => v.iter().sum::<f64>() / k as f64,
            Combine::Median => {
                v.sort_unstable_by(|a, b| a.total_cmp(b));
                if k % 2 == 1 {
                    v[k / 2]
                } else {
                    0.5 * (v[k / 2 - 1] + v[k / 2])
                }
            }
        }
    }
}

fn band_restarts() -> usize {
    SHORT_ENSEMBLE
}

fn feature_gain() -> f64 {
    0.1
}

fn yes() -> bool {
    true
}

/// Training records under this many samples are "short" (the study's 2-DoF record: 250).
pub const SHORT_RECORD: usize = 1000;

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
            short_record_settings: true,
            try_features: Vec::new(),
            feature_gain: feature_gain(),
            ensemble: None,
            combine: Combine::Median,
            try_decimation: true,
            try_greybox: true,
            band_restarts: band_restarts(),
        }
    }
}

impl RobustSettings {
    /// Restarts for a training record of `n` samples.
    pub fn restarts_for(&self, n: usize) -> usize {
        self.restarts.unwrap_or(if n < SHORT_RECORD {
            16
        } else if n < 5000 {
            8
        } else {
            2
        })
    }

    /// Networks kept per output on a training record of `n` samples.
    pub fn ensemble_size(&self, n: usize) -> usize {
        match self.ensemble {
            Some(k) => k,
            None if n < SHORT_RECORD && self.short_record_settings => SHORT_ENSEMBLE,
            None => 1,
        }
    }

    /// The settings used on a training record of `n` samples. A short record (under
    /// [`SHORT_RECORD`]) cannot spare a validation part: the whole record trains the
    /// simulation error and the free run over the whole record (from its start, transient
    /// included) selects the weights and the restart; simulation-error training runs longer
    /// (3000 steps, patience 50, learning rate 5e-3; each step is cheap). Only fields left at
    /// their default values change.
    pub fn for_record(&self, n: usize) -> RobustSettings {
        let mut r = self.clone();
        if n >= SHORT_RECORD || !self.short_record_settings {
            return r;
        }
        let d = RobustSettings::default();
        if r.validation_fraction == d.validation_fraction {
            r.validation_fraction = 0.0;
        }
        if r.sim_steps == d.sim_steps {
            r.sim_steps = 3000;
        }
        if r.sim_patience == d.sim_patience {
            r.sim_patience = 50;
        }
        if r.sim_lr == d.sim_lr {
            r.sim_lr = 5e-3;
        }
        r
    }
}

/// The widest hidden layer [`NarxConfig::check`] accepts.
pub const MAX_NEURONS: usize = 4096;
/// The most hidden layers [`NarxConfig::check`] accepts.
pub const MAX_LAYERS: usize = 16;
// the refusal's message says these numbers
const _: () = assert!(MAX_NEURONS == 4096 && MAX_LAYERS == 16);

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
            interaction: Interaction::Additive,
            optimizer: OptimizerKind::Adam,
            lr: 0.01,
            batch: 128,
            epochs: 100,
            seed: 0,
            protocol: Protocol::Default,
            robust: RobustSettings::default(),
            features: Vec::new(),
            decimation: 1,
        }
    }

    /// Exogenous signals per output: inputs plus features.
    pub fn n_signals(&self) -> usize {
        self.inputs.len() + self.features.len()
    }

    /// The exogenous signals of a record with the configuration's inputs (in order): the
    /// inputs, then each feature computed from them.
    pub fn exogenous(&self, inputs: &[&[f64]], ts: f64) -> Vec<Vec<f64>> {
        let mut v: Vec<Vec<f64>> = inputs.iter().map(|u| u.to_vec()).collect();
        for f in &self.features {
            v.push(f.compute(inputs, ts));
        }
        v
    }

    /// Check every setting; the error names the field and the rule. (Long on purpose: one
    /// line per setting, read as a table of rules.)
    pub fn check(&self) -> Result<(), NarxError> {
        let bad = |field, value: String, rule| Err(NarxError::InvalidConfig { field, value, rule });
        if self.decimation == 0 {
            return bad(
                "decimation",
                "0".into(),
                "must be at least 1 (every sample)",
            );
        }
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
        if self.neurons > MAX_NEURONS || self.layers > MAX_LAYERS {
            return bad(
                if self.neurons > MAX_NEURONS { "neurons" } else { "layers" },
                format!("{} x {}", self.neurons, self.layers),
                "at most 4096 neurons a layer and 16 layers (a NARX model of a hysteretic device needs tens)",
            );
        }
        if self.interaction == Interaction::Additive && self.neurons < self.inputs.len() {
            return bad(
                "neurons",
                self.neurons.to_string(),
                "interaction additive gives each input its own neurons: at least one per input (raise --neurons or use --interaction full)",
            );
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
        for f in &self.features {
            if let Err(why) = f.check(self.inputs.len()) {
                return bad(
                    "features",
                    why,
                    "input index below the number of inputs; finite, positive parameters",
                );
            }
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
        if r.ensemble == Some(0) {
            return bad("ensemble", "0".into(), "must be at least 1");
        }
        if r.window < 2 || r.samples_per_step == 0 || r.eval_every == 0 {
            return bad(
                "window/samples_per_step/eval_every",
                format!("{}/{}/{}", r.window, r.samples_per_step, r.eval_every),
                "must be positive (window >= 2)",
            );
        }
        if !(r.feature_gain.is_finite() && r.feature_gain > 0.0 && r.feature_gain <= 1.0) {
            return bad(
                "feature_gain",
                r.feature_gain.to_string(),
                "must be in (0, 1]",
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

    /// A fresh network for one output: Glorot weights from `seed`, the hidden neurons grouped
    /// by input when the interaction is additive.
    pub fn network(&self, bypass: bool, seed: u64) -> Mlp {
        let net = Mlp::glorot(&self.sizes(), bypass, seed);
        match self.interaction {
            Interaction::Full => net,
            Interaction::Additive => {
                // exogenous signal -> the input it comes from
                let source: Vec<usize> = (0..self.inputs.len())
                    .chain(self.features.iter().map(|f| f.input()))
                    .collect();
                let mut columns = vec![None; self.lags.output];
                for s in source {
                    columns.extend(std::iter::repeat_n(Some(s), self.lags.input));
                }
                net.grouped(&columns, self.inputs.len())
            }
        }
    }

    /// Network layer widths for `n_signals` exogenous signals.
    pub fn sizes(&self) -> Vec<usize> {
        let mut s = vec![self.lags.width(self.n_signals())];
        s.extend(std::iter::repeat_n(self.neurons, self.layers));
        s.push(1);
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn combine_takes_the_mean_or_the_median() {
        assert_eq!(Combine::Median.apply(&mut [3.0, -1.0, 100.0]), 3.0);
        assert_eq!(Combine::Median.apply(&mut [4.0, 1.0, 2.0, 100.0]), 3.0);
        assert_eq!(Combine::Mean.apply(&mut [4.0, 1.0, 2.0, 1.0]), 2.0);
        for c in [Combine::Mean, Combine::Median] {
            assert_eq!(c.apply(&mut [-0.5]), -0.5);
        }
    }

    #[test]
    fn short_records_get_eight_networks_unless_told() {
        let r = RobustSettings::default();
        assert_eq!(r.ensemble_size(250), SHORT_ENSEMBLE);
        assert_eq!(r.ensemble_size(SHORT_RECORD), 1);
        let one = RobustSettings {
            ensemble: Some(1),
            ..RobustSettings::default()
        };
        assert_eq!(one.ensemble_size(250), 1);
    }
}
