//! The settings of an identification as a user gives them (the options of `identify`, the
//! keywords of the Python `Narx(...)`): whatever is left unset takes the protocol's default.
//! One place turns them into a [`NarxConfig`] for a training record, so that the command line
//! and the Python front build the same model from the same settings.

use super::config::{features_of, Interaction, NarxConfig, OptimizerKind, Protocol};
use super::regressors::Lags;
use super::NarxError;
use crate::data::IoRecord;
use crate::effect::EffectName;

/// Network and training settings (the defaults are `identify`'s).
#[derive(Debug, Clone, PartialEq)]
pub struct NarxSettings {
    /// Lags n of outputs and inputs (the study's equal orders).
    pub lags: usize,
    /// Output lags (default: `lags`).
    pub output_lags: Option<usize>,
    /// Input lags (default: `lags`).
    pub input_lags: Option<usize>,
    /// Input delay d: the newest input in the regressor is u(k-d).
    pub delay: usize,
    pub neurons: usize,
    pub layers: usize,
    /// Default: additive (full with the study protocol).
    pub interaction: Option<Interaction>,
    /// Default: Adam (RMSProp with the study protocol).
    pub optimizer: Option<OptimizerKind>,
    pub lr: f64,
    pub batch: usize,
    pub epochs: usize,
    pub seed: u64,
    pub protocol: Protocol,
    pub restarts: Option<usize>,
    pub sim_steps: Option<usize>,
    pub sim_lr: Option<f64>,
    pub window: Option<usize>,
    pub sim_patience: Option<usize>,
    pub weight_decay: Option<f64>,
    pub validation_fraction: Option<f64>,
    pub ensemble: Option<usize>,
    /// Effect features: empty = the protocol's choice; `["none"]` = none; `["auto"]` = the plain
    /// network against one with hysteresis features; else effect names, taken as they are.
    pub features: Vec<String>,
    /// The grey-box base candidate of the default protocol.
    pub greybox: bool,
}

impl Default for NarxSettings {
    fn default() -> Self {
        NarxSettings {
            lags: 4,
            output_lags: None,
            input_lags: None,
            delay: 1,
            neurons: 10,
            layers: 1,
            interaction: None,
            optimizer: None,
            lr: 0.01,
            batch: 128,
            epochs: 100,
            seed: 0,
            protocol: Protocol::Default,
            restarts: None,
            sim_steps: None,
            sim_lr: None,
            window: None,
            sim_patience: None,
            weight_decay: None,
            validation_fraction: None,
            ensemble: None,
            features: Vec::new(),
            greybox: true,
        }
    }
}

impl NarxSettings {
    /// The configuration of a model of `outputs` from `inputs`, without effect features (see
    /// [`NarxSettings::config`]).
    pub fn network(&self, inputs: Vec<String>, outputs: Vec<String>) -> NarxConfig {
        let mut c = NarxConfig::new(inputs, outputs);
        c.lags = Lags {
            output: self.output_lags.unwrap_or(self.lags),
            input: self.input_lags.unwrap_or(self.lags),
            delay: self.delay,
        };
        c.neurons = self.neurons;
        c.layers = self.layers;
        c.interaction = self.interaction.unwrap_or(match self.protocol {
            Protocol::Default => Interaction::Additive,
            Protocol::Study => Interaction::Full,
        });
        c.protocol = self.protocol;
        c.optimizer = self.optimizer.unwrap_or(match self.protocol {
            Protocol::Default => OptimizerKind::Adam,
            Protocol::Study => OptimizerKind::Rmsprop,
        });
        c.lr = self.lr;
        c.batch = self.batch;
        c.epochs = self.epochs;
        c.seed = self.seed;
        let r = &mut c.robust;
        if let Some(v) = self.restarts {
            r.restarts = Some(v);
        }
        if let Some(v) = self.sim_steps {
            r.sim_steps = v;
        }
        if let Some(v) = self.sim_lr {
            r.sim_lr = v;
        }
        if let Some(v) = self.window {
            r.window = v;
        }
        if let Some(v) = self.validation_fraction {
            r.validation_fraction = v;
        }
        if let Some(v) = self.weight_decay {
            r.weight_decay = v;
        }
        if let Some(v) = self.sim_patience {
            r.sim_patience = v;
        }
        if let Some(v) = self.ensemble {
            r.ensemble = Some(v);
        }
        r.try_greybox &= self.greybox;
        c
    }

    /// The configuration for the training record `train` (its columns, and the effect
    /// features' numbers fixed on it).
    pub fn config(&self, train: &IoRecord) -> Result<NarxConfig, NarxError> {
        let mut c = self.network(train.input_names(), train.output_names());
        let only = |word: &str| self.features.len() == 1 && self.features[0] == word;
        if only("auto") {
            c.robust.try_features = crate::effect::registry::narx_candidates();
        } else if !self.features.is_empty() {
            // named features (or `none`) are taken as they are: no selection
            c.robust.try_features.clear();
            if !only("none") {
                c.features = features_of(&self.feature_effects()?, train)?;
            }
        }
        Ok(c)
    }

    /// The named feature effects (in the order named, duplicates once).
    fn feature_effects(&self) -> Result<Vec<EffectName>, NarxError> {
        let bad = |why: String| NarxError::Features {
            value: self.features.join(","),
            why,
        };
        let mut effects: Vec<EffectName> = Vec::new();
        for n in &self.features {
            if n == "none" || n == "auto" {
                return Err(bad(format!(
                    "`{n}` stands alone, it cannot be combined with effect names"
                )));
            }
            let e: EffectName = n.parse().map_err(|e| bad(format!("{e}")))?;
            if !effects.contains(&e) {
                effects.push(e);
            }
        }
        Ok(effects)
    }
}
