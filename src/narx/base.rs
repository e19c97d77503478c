//! # A grey-box base under the networks
//!
//! The default protocol's physical candidate. A grey-box model (`crate::graybox`: hysteresis,
//! creep and dynamics from the effect library, as many of them as the record supports, with
//! coupling on a record of several inputs) is fitted on the training record's fitting part and
//! run free over the whole training record; its error on the validation part (the same samples
//! and units as the network's selection error) decides, per output, what the model is:
//!
//! - [`BaseUse::Network`]: the network alone, as before (the grey-box did not validate better);
//! - [`BaseUse::Base`]: the grey-box alone;
//! - [`BaseUse::BaseAndNetwork`]: the grey-box plus a network trained on its residual
//!   y - g(u) (the same configuration as the network, features and sampling included), kept
//!   when it validates better than the grey-box alone.
//!
//! A record too short for a validation part (see `RobustSettings::for_record`) compares the
//! grey-box fitted on all but the last [`super::fit::PROBE_TAIL`] with the linear probe's network
//! and linear candidate on that tail, refits the grey-box on the whole record when it wins, and
//! uses it alone (a network on the residual of 250 samples only learns their noise).
//!
//! The grey-box runs from rest. When the record predicted continues the training record (the
//! test half of `identify`), it runs on through the training record first
//! ([`super::FittedNarx::predict_after`]), so that its creep and hysteresis states are those
//! of the plant; a record on its own starts it from rest.
//!
//! Grey-box models extrapolate as physics does (a test half of larger amplitude, other input
//! combinations of a 2-DoF plant), where a network trained on 250 samples does not; a network
//! on the residual adds what the effect library does not describe.

use super::band::{Band, BAND_LEVEL};
use super::config::{NarxConfig, Protocol};
use super::fit::PROBE_TAIL;
use super::model::{FittedNarx, LinearProbe};
use super::NarxError;
use crate::data::IoRecord;
use crate::graybox::{FittedGreyBox, GreyBoxConfig};
use crate::plant::{Plant, PlantSpec};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The effect lists tried in turn; the first one the record supports is fitted (`coupling` is
/// added on a record of several inputs).
pub const BASE_EFFECTS: [&str; 3] = [
    "hysteresis,creep,dynamics",
    "hysteresis,dynamics",
    "dynamics",
];

/// What one output's model is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BaseUse {
    /// The network alone.
    Network,
    /// The grey-box model alone (the output's network is kept in the file but not run).
    Base,
    /// The grey-box model plus the output's network, trained on the grey-box residual.
    BaseAndNetwork,
}

/// The choice for one output: the free-run validation MSE of each candidate (standardised
/// units of the output, the network's selection error; `None`: not tried, or diverged).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseChoice {
    pub name: String,
    pub network_mse: Option<f64>,
    pub base_mse: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub residual_mse: Option<f64>,
    pub model: BaseUse,
}

/// The grey-box base of a fitted model and how each output uses it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GreyBoxBase {
    /// The grey-box model's effects (`hystbench fit --effects`).
    pub effects: String,
    /// Samples of the training record it was fitted on.
    pub fitted_samples: usize,
    /// The fitted grey-box model as a plant (every output); `None` when no output uses it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plant: Option<PlantSpec>,
    pub outputs: Vec<BaseChoice>,
}

impl GreyBoxBase {
    /// How output `o` uses the base.
    pub fn uses(&self, o: usize) -> BaseUse {
        if self.plant.is_none() {
            return BaseUse::Network;
        }
        self.outputs.get(o).map_or(BaseUse::Network, |c| c.model)
    }

    /// Whether some output uses the base.
    pub fn active(&self) -> bool {
        (0..self.outputs.len()).any(|o| self.uses(o) != BaseUse::Network)
    }

    /// The checked plant (a damaged model file is an error naming it).
    pub fn plant(&self, path: &Path) -> Result<Option<Plant>, NarxError> {
        match &self.plant {
            None => Ok(None),
            Some(spec) => spec.check(path).map(Some).map_err(|e| NarxError::Damaged {
                path: path.to_path_buf(),
                why: format!("its grey-box base: {e}"),
            }),
        }
    }

    /// The base's outputs over `rec` (one per output of the model, in order), run from rest
    /// through `history` first when `rec` continues it.
    pub fn simulate(
        &self,
        history: Option<&IoRecord>,
        rec: &IoRecord,
    ) -> Result<Option<Vec<Vec<f64>>>, NarxError> {
        let Some(plant) = self.plant(&rec.path)? else {
            return Ok(None);
        };
        let skip = history.map_or(0, IoRecord::len);
        let inputs: Vec<Vec<f64>> = rec
            .inputs
            .iter()
            .enumerate()
            .map(|(j, s)| {
                let mut v = history.map_or_else(Vec::new, |h| h.inputs[j].values.clone());
                v.extend_from_slice(&s.values);
                v
            })
            .collect();
        let refs: Vec<&[f64]> = inputs.iter().map(Vec::as_slice).collect();
        let y = plant
            .simulate(&refs, rec.ts)
            .map_err(|e| NarxError::Damaged {
                path: rec.path.clone(),
                why: format!("its grey-box base cannot be simulated: {e}"),
            })?;
        Ok(Some(y.into_iter().map(|v| v[skip..].to_vec()).collect()))
    }
}

/// Samples per parameter the base asks of the record: half the grey-box fit's default, since
/// the held-out samples judge it (the source study's 2-DoF record then fits hysteresis on
/// both paths of each output from 187 samples).
pub const BASE_SAMPLES_PER_PARAMETER: usize = 5;

/// The grey-box model of the first of [`BASE_EFFECTS`] that `train` supports, fitted on its
/// first `n_fit` samples and scored (free run from rest) on the rest; `None` when none fits.
pub fn fit_base(train: &IoRecord, n_fit: usize) -> Option<FittedGreyBox> {
    let coupling = if train.inputs.len() > 1 {
        ",coupling"
    } else {
        ""
    };
    let n = train.len();
    BASE_EFFECTS.iter().find_map(|list| {
        let mut cfg = GreyBoxConfig::from_effect_list(&format!("{list}{coupling}")).ok()?;
        cfg.options.train_fraction = n_fit as f64 / n as f64;
        cfg.options.samples_per_parameter = BASE_SAMPLES_PER_PARAMETER;
        cfg.fit(train).ok()
    })
}

/// Mean squared error of `g` against `y` over `range`, in units of `std`.
fn mse(y: &[f64], g: &[f64], range: std::ops::Range<usize>, std: f64) -> Option<f64> {
    let n = range.len();
    let s: f64 = range.map(|k| ((y[k] - g[k]) / std).powi(2)).sum();
    (n > 0 && s.is_finite()).then(|| s / n as f64)
}

/// The lower of two optional errors (`None`: diverged) is `a`'s strictly.
fn lower(a: Option<f64>, b: Option<f64>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => a < b,
        (Some(_), None) => true,
        _ => false,
    }
}

impl NarxConfig {
    /// The grey-box base candidate of the default protocol (module documentation): fitted on
    /// the part of `train` that the network's selection does not score, kept per output where
    /// it validates better than the network `m`.
    pub(super) fn choose_base(
        &self,
        train: &IoRecord,
        mut m: FittedNarx,
    ) -> Result<FittedNarx, NarxError> {
        if self.protocol != Protocol::Default || !self.robust.try_greybox {
            return Ok(m);
        }
        let n = train.len();
        let short = self.robust.for_record(n).validation_fraction == 0.0;
        let held = if short {
            PROBE_TAIL
        } else {
            self.robust.validation_fraction
        };
        let n_fit = n - (n as f64 * held).round() as usize;
        // the network's error on the same samples: its selection error, or the probe's
        let network: Vec<Option<f64>> = if short {
            match &m.linear_probe {
                Some(p) => p.iter().map(probe_mse).collect(),
                None => return Ok(m),
            }
        } else {
            m.outputs
                .iter()
                .map(|o| o.training.selection_mse())
                .collect()
        };
        let Some(g) = fit_base(train, n_fit) else {
            return Ok(m);
        };
        let Ok(sim) = g.simulate(train) else {
            return Ok(m);
        };
        let mut choices: Vec<BaseChoice> = m
            .outputs
            .iter()
            .enumerate()
            .map(|(o, om)| {
                let y = &train.outputs[o].values;
                let base_mse = mse(y, &sim[o], n_fit..n, om.scaling.std);
                BaseChoice {
                    name: om.name.clone(),
                    network_mse: network[o],
                    base_mse,
                    residual_mse: None,
                    model: if lower(base_mse, network[o]) {
                        BaseUse::Base
                    } else {
                        BaseUse::Network
                    },
                }
            })
            .collect();
        let chosen: Vec<usize> = (0..choices.len())
            .filter(|&o| choices[o].model == BaseUse::Base)
            .collect();
        let effects = g.config.effect_list();
        if chosen.is_empty() {
            m.base = Some(GreyBoxBase {
                effects,
                fitted_samples: n_fit,
                plant: None,
                outputs: choices,
            });
            return Ok(m);
        }
        // the band of the grey-box alone: its held-out residuals (it has one member)
        for &o in &chosen {
            let y = &train.outputs[o].values;
            let r: Vec<f64> = (n_fit..n).map(|k| y[k] - sim[o][k]).collect();
            m.outputs[o].band = Band::calibrate(&r, &vec![0.0; r.len()], BAND_LEVEL);
            m.outputs[o].band_members.clear();
        }
        let (g, fitted_samples) = if short {
            // refit on the whole record: every sample counts on a short record
            match fit_base_like(&g, train) {
                Some(full) => (full, n),
                None => (g, n_fit),
            }
        } else {
            self.fit_residual_networks(train, &sim, &chosen, &mut choices, &mut m)?;
            (g, n_fit)
        };
        m.base = Some(GreyBoxBase {
            effects,
            fitted_samples,
            plant: Some(g.plant.spec.clone()),
            outputs: choices,
        });
        Ok(m)
    }

    /// On a record with a validation part: a network on the grey-box residual of each chosen
    /// output, with the configuration `m` ended up with (features, sampling) and no further
    /// selection; it replaces the output's network when it validates better than the grey-box
    /// alone.
    fn fit_residual_networks(
        &self,
        train: &IoRecord,
        sim: &[Vec<f64>],
        chosen: &[usize],
        choices: &mut [BaseChoice],
        m: &mut FittedNarx,
    ) -> Result<(), NarxError> {
        let mut resid = train.clone();
        resid.outputs = chosen
            .iter()
            .map(|&o| {
                let mut s = train.outputs[o].clone();
                for (v, g) in s.values.iter_mut().zip(&sim[o]) {
                    *v -= g;
                }
                s
            })
            .collect();
        let mut cfg = m.config.clone();
        cfg.outputs = resid.output_names();
        cfg.robust.try_features.clear();
        cfg.robust.try_decimation = false;
        cfg.robust.try_greybox = false;
        // a residual at the noise level is constant to the network's eye: keep the base alone
        let Ok(r) = cfg.fit_fixed(std::slice::from_ref(&resid)) else {
            return Ok(());
        };
        for (k, &o) in chosen.iter().enumerate() {
            let ro = &r.outputs[k];
            let ratio = (ro.scaling.std / m.outputs[o].scaling.std).powi(2);
            let rm = ro.training.selection_mse().map(|v| v * ratio);
            choices[o].residual_mse = rm;
            if lower(rm, choices[o].base_mse) {
                choices[o].model = BaseUse::BaseAndNetwork;
                m.outputs[o] = ro.clone();
            }
        }
        Ok(())
    }
}

/// The probe's error of the candidate it kept.
fn probe_mse(p: &LinearProbe) -> Option<f64> {
    if p.linear {
        p.linear_mse
    } else {
        p.network_mse
    }
}

/// `g`'s model refitted on the whole of `train`.
fn fit_base_like(g: &FittedGreyBox, train: &IoRecord) -> Option<FittedGreyBox> {
    let mut cfg = g.config.clone();
    cfg.options.train_fraction = 1.0;
    cfg.options.samples_per_parameter = BASE_SAMPLES_PER_PARAMETER;
    cfg.fit(train).ok()
}
