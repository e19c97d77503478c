//! The fitted NARX model: fitting (the driver), prediction, scores and the model file.

use super::band::{spread, Band};
use super::config::Combine;
use super::config::NarxConfig;
use super::mlp::Mlp;
use super::regressors::{Regressor, Series, Standardiser};
use super::train::{free_run_fast, Design, OneStepRecord, SimulationRecord};
use super::NarxError;
use crate::data::{parse_json_file, read_json_text, FileHeader, IoRecord};
use crate::effect::EffectName;
use crate::effect::FeatureSpec;
use crate::metrics::{scores, Scores};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The model file's `format` field.
pub const FORMAT: &str = "hystbench-narx";
/// The model file version this code writes and reads.
pub const VERSION: u32 = 1;

/// A free run is declared diverged when it leaves the training output range widened by this
/// many ranges on each side (or becomes non-finite).
pub const DIVERGENCE_RANGES: f64 = 5.0;

/// How one restart went.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RestartRecord {
    pub seed: u64,
    pub one_step: OneStepRecord,
    pub simulation: Option<SimulationRecord>,
    /// Free-run validation MSE (standardised units) that selected the restart.
    pub selection_mse: Option<f64>,
}

/// Training record of one output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputTraining {
    pub train_samples: usize,
    pub validation_samples: usize,
    pub restarts: Vec<RestartRecord>,
    pub chosen_restart: usize,
    /// The restarts kept as an ensemble (`chosen_restart` first); empty: one network.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ensemble_restarts: Vec<usize>,
    /// The free-run validation MSE of the linear candidate (an ARX model in the network's
    /// regressors, see `train::linear_output_layer`), when one was tried.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub linear_selection_mse: Option<f64>,
    /// True when the linear candidate validated better than every network and is the model.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub linear: bool,
}

impl OutputTraining {
    /// The free-run validation MSE of the model kept (`None`: it diverged).
    pub fn selection_mse(&self) -> Option<f64> {
        if self.linear {
            self.linear_selection_mse
        } else {
            self.restarts[self.chosen_restart].selection_mse
        }
    }
}

/// One output's network and scaling.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputModel {
    pub name: String,
    pub scaling: Standardiser,
    /// Training output range (physical units), for divergence detection.
    pub train_min: f64,
    pub train_max: f64,
    /// Lags, form and difference scaling of the regressor.
    pub regressor: Regressor,
    pub network: Mlp,
    /// Further ensemble members (the networks of `training.ensemble_restarts[1..]`); empty: the
    /// model is `network` alone. Predictions combine `network` and these
    /// (`config.robust.combine`: the median for new models).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ensemble: Vec<Mlp>,
    pub training: OutputTraining,
    /// The prediction band calibrated on the validation part (`None`: none could be, or a
    /// model file written before bands).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub band: Option<Band>,
    /// Further restarts that only widen the band: their free runs count in the spread, not in
    /// the prediction (the other restarts, best validation first; empty: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub band_members: Vec<Mlp>,
}

impl OutputModel {
    /// Every network of this output: `network`, then the further ensemble members.
    pub fn members(&self) -> impl Iterator<Item = &Mlp> {
        std::iter::once(&self.network).chain(self.ensemble.iter())
    }

    /// The standardised range a free run must stay in: the training range widened by
    /// [`DIVERGENCE_RANGES`] ranges on each side (outside it, the run diverged).
    pub fn free_run_bounds(&self) -> (f64, f64) {
        let r = (self.train_max - self.train_min).max(f64::MIN_POSITIVE);
        let lo = (self.train_min - DIVERGENCE_RANGES * r - self.scaling.mean) / self.scaling.std;
        let hi = (self.train_max + DIVERGENCE_RANGES * r - self.scaling.mean) / self.scaling.std;
        (lo, hi)
    }
}

/// A fitted NARX model: one MISO network per output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FittedNarx {
    pub config: NarxConfig,
    /// Scaling of each exogenous signal (training statistics), in `config.inputs` order.
    pub input_scaling: Vec<Standardiser>,
    pub outputs: Vec<OutputModel>,
    /// Wall-clock training time (informative, not part of any result).
    pub train_seconds: f64,
    /// How the protocol chose the extra features (`None`: no selection ran).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feature_selection: Option<FeatureSelection>,
    /// How the protocol chose the model's sampling (`None`: no coarser one was tried).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decimation_selection: Option<DecimationSelection>,
    /// The short-record probe of the linear candidate, per output (`None`: not run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub linear_probe: Option<Vec<LinearProbe>>,
    /// The region of input space the training record covered (`None`: a model file written
    /// before it was kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_region: Option<super::region::InputRegion>,
    /// The grey-box base candidate and how each output uses it ([`super::base`]; `None`: not
    /// tried).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<super::base::GreyBoxBase>,
    /// The training records' sampling period, s (`None`: a model file written before it was
    /// kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampling_period_s: Option<f64>,
}

/// The linear probe of one output on a short record: the free-run MSE on the held-out tail of
/// the best plain network and of the linear candidate (`None`: diverged), and whether the
/// linear candidate won (the output is then linear).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinearProbe {
    pub network_mse: Option<f64>,
    pub linear_mse: Option<f64>,
    pub linear: bool,
}

/// The protocol's choice of the model's sampling on an oversampled training record: each
/// decimation tried with its free-run validation MSE (summed over the outputs, standardised
/// units; `None`: diverged), and the one kept.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DecimationSelection {
    pub tried: Vec<(usize, Option<f64>)>,
    pub chosen: usize,
}

/// The protocol's choice between the plain regressors and regressors plus effect-library
/// features, made on the training record alone: the free-run validation MSE of each output's
/// chosen restart (standardised units, the error that selects restarts), summed over outputs;
/// `None` when a free run diverged. The features are kept only when they bring it below
/// `robust.feature_gain` (default 0.1) times the plain model's, or when the plain model diverged
/// and they did not.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FeatureSelection {
    /// The effects tried (`robust.try_features`).
    pub tried: Vec<EffectName>,
    /// Their basis signals as defined on the training record.
    pub candidates: Vec<FeatureSpec>,
    pub selection_mse_without: Option<f64>,
    pub selection_mse_with: Option<f64>,
    /// True when the candidates were added to `config.features`.
    pub chosen: bool,
}

super::config::named_setting!(Mode, OneStep => "one-step", FreeRun => "free-run");

/// Prediction mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Measured past outputs in the regressor.
    OneStep,
    /// The model's own past outputs (simulation).
    FreeRun,
}

/// A prediction of one output.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputPrediction {
    pub name: String,
    /// Physical units; samples before `start` are the measured ones (the initial condition).
    /// Shorter than the record when the free run diverged.
    pub values: Vec<f64>,
    pub start: usize,
    /// First sample where the free run left the plausible range (for an ensemble: set only
    /// when every member diverged, the earliest of them).
    pub diverged_at: Option<usize>,
    /// Ensemble members (0: `network`) whose free run diverged. They are left out of the
    /// combination (listed here, and in the evaluation); when every member diverged, the
    /// output diverged. On an output with a grey-box base under its network, a residual
    /// network that diverged is left out the same way (every member listed) and the grey-box
    /// alone is the prediction; so is a network chosen over its base when most of its members
    /// diverged.
    pub diverged_members: Vec<usize>,
    /// Half-width of the prediction band at each sample (physical units; a free run of a model
    /// with a calibrated band, [`super::band`]), else `None`.
    pub half_width: Option<Vec<f64>>,
    /// On an output on the grey-box alone whose chosen base departed from its committee's median
    /// (which predicts) on this record ([`super::consensus`]): by how much.
    pub base_departure: Option<super::consensus::Departure>,
}

impl OutputPrediction {
    /// Scores against the measured signal over `start..`; `None` if diverged.
    pub fn scores(&self, measured: &[f64]) -> Option<Scores> {
        if self.diverged_at.is_some() || self.values.len() != measured.len() {
            return None;
        }
        Some(scores(&measured[self.start..], &self.values[self.start..]))
    }

    /// The band against the measured signal over `start..`: the share of samples inside it
    /// ([`super::band::coverage`]) and its mean half-width in standard deviations of the
    /// measurement ([`super::band::relative_width`]); `None` without a band or if diverged.
    pub fn band_scores(&self, measured: &[f64]) -> (Option<f64>, Option<f64>) {
        match self
            .half_width
            .as_ref()
            .filter(|_| self.diverged_at.is_none())
        {
            Some(h) => (
                super::band::coverage(measured, &self.values, h, self.start),
                super::band::relative_width(measured, h, self.start),
            ),
            None => (None, None),
        }
    }
}

/// The input columns of a record as slices.
pub(super) fn input_slices(rec: &IoRecord) -> Vec<&[f64]> {
    rec.inputs.iter().map(|s| &s.values[..]).collect()
}

pub(super) fn names_str(v: &[String]) -> String {
    format!("[{}]", v.join(", "))
}

/// The restart with the lowest free-run validation error (the first on ties; a restart whose
/// free run diverged, `None`, only when every one did).
pub(crate) fn best_restart<'a>(records: impl Iterator<Item = &'a RestartRecord>) -> usize {
    let scores: Vec<Option<f64>> = records.map(|r| r.selection_mse).collect();
    let mut chosen = 0;
    for (i, s) in scores.iter().enumerate() {
        let better = match (s, scores[chosen]) {
            (Some(a), Some(b)) => *a < b,
            (Some(_), None) => true,
            _ => false,
        };
        if better {
            chosen = i;
        }
    }
    chosen
}

impl FittedNarx {
    /// Where `rec` leaves the region of input space the model was trained on (empty: inside,
    /// or a model file without its region).
    pub fn outside(&self, rec: &IoRecord) -> Vec<super::region::Outside> {
        self.input_region
            .as_ref()
            .map_or_else(Vec::new, |r| r.outside(rec))
    }

    /// The free-run validation MSE that selected each output's restart, summed over outputs;
    /// `None` if any is missing (a diverged free run, or the study protocol).
    pub fn selection_mse(&self) -> Option<f64> {
        self.outputs
            .iter()
            .map(|o| o.training.selection_mse())
            .sum()
    }

    /// Check that a record has the model's inputs (names and order); outputs are optional.
    fn check_record(&self, rec: &IoRecord) -> Result<(), NarxError> {
        if rec.input_names() != self.config.inputs {
            return Err(NarxError::ColumnMismatch {
                path: rec.path.clone(),
                what: "input",
                expected: names_str(&self.config.inputs),
                found: names_str(&rec.input_names()),
            });
        }
        let start = self.config.lags.start();
        if rec.len() < start + 1 {
            return Err(NarxError::TooShort {
                path: rec.path.clone(),
                rows: rec.len(),
                needed: start + 1,
                why: format!("{start} initial samples plus at least one to predict"),
            });
        }
        Ok(())
    }

    fn series(&self, rec: &IoRecord, o: &OutputModel, measured: Option<&[f64]>) -> Series {
        Series {
            y: match measured {
                Some(y) => o.scaling.apply(y),
                // at rest: physical zero
                None => vec![o.scaling.apply(&[0.0])[0]; rec.len()],
            },
            u: self
                .config
                .exogenous(&input_slices(rec), rec.ts)
                .iter()
                .zip(&self.input_scaling)
                .map(|(s, sc)| sc.apply(s))
                .collect(),
        }
    }

    /// Predict every output of a record. One-step needs the measured outputs; a free run uses
    /// the first measured outputs as its initial condition (zeros when the record has none).
    /// A grey-box base runs from rest at the record's start.
    pub fn predict(&self, rec: &IoRecord, mode: Mode) -> Result<Vec<OutputPrediction>, NarxError> {
        self.predict_after(None, rec, mode)
    }

    /// [`FittedNarx::predict`] on a record that continues `history` (the test half after the
    /// training half): a grey-box base runs through `history` first, so that its states are
    /// the plant's at the record's start; the networks start from the record's own first
    /// samples as always. Without a base it is `predict`.
    pub fn predict_after(
        &self,
        history: Option<&IoRecord>,
        rec: &IoRecord,
        mode: Mode,
    ) -> Result<Vec<OutputPrediction>, NarxError> {
        let base = match &self.base {
            Some(b) if b.active() => b,
            _ => return self.predict_sampled(rec, mode),
        };
        if let Some(h) = history {
            if h.input_names() != rec.input_names() || h.ts != rec.ts {
                return Err(NarxError::ColumnMismatch {
                    path: rec.path.clone(),
                    what: "input (of the record it continues)",
                    expected: names_str(&h.input_names()),
                    found: names_str(&rec.input_names()),
                });
            }
        }
        self.check_record(rec)?;
        let Some(runs) = base.simulate(history, rec)? else {
            return self.predict_sampled(rec, mode);
        };
        // where a base's run diverged (`Err(sample)`), so does every prediction that needs it
        let base_diverged: Vec<Option<usize>> =
            runs.iter().map(|r| r.as_ref().err().copied()).collect();
        let mut g: Vec<Vec<f64>> = runs.into_iter().map(Result::unwrap_or_default).collect();
        // the networks see the residual of the outputs that have a base
        let mut resid = rec.clone();
        for s in resid.outputs.iter_mut() {
            if let Some(o) = self.outputs.iter().position(|m| m.name == s.name) {
                if base.uses(o) == super::base::BaseUse::BaseAndNetwork {
                    for (v, gv) in s.values.iter_mut().zip(&g[o]) {
                        *v -= gv;
                    }
                }
            }
        }
        let mut preds = self.predict_sampled(&resid, mode)?;
        let alone = self.networks_alone(base, rec, mode)?;
        for (o, p) in preds.iter_mut().enumerate() {
            let members = self.outputs[o].ensemble.len() + 1;
            let diverged = base_diverged.get(o).copied().flatten();
            match base.uses(o) {
                // the base that would stand in for an unstable network diverged too: the
                // network's own prediction stands (diverged only when every member did)
                super::base::BaseUse::Network if diverged.is_some() => {}
                super::base::BaseUse::Base | super::base::BaseUse::BaseAndNetwork
                    if diverged.is_some() =>
                {
                    // the base's run left the finite range: the prediction diverged with it
                    p.values.clear();
                    p.diverged_at = diverged;
                    p.half_width = None;
                    p.base_departure = None;
                }
                super::base::BaseUse::Network
                    if p.diverged_at.is_some() || 2 * p.diverged_members.len() > members =>
                {
                    // most of the ensemble left the plausible range on this record (inputs the
                    // training record did not visit): the network is unstable here, and the
                    // grey-box base it beat on validation stands in, with its own band
                    p.values = g[o].clone();
                    p.diverged_at = None;
                    p.diverged_members = (0..members).collect();
                    p.half_width = match (mode, &base.outputs[o].base_band) {
                        (Mode::FreeRun, Some(b)) => Some(vec![b.half_width(0.0); g[o].len()]),
                        _ => None,
                    };
                }
                super::base::BaseUse::Network => {}
                super::base::BaseUse::BaseAndNetwork if p.diverged_at.is_some() => {
                    // the residual network left its range (a record whose start the base,
                    // run from rest, does not know): it is left out like a diverged member,
                    // and the grey-box alone remains, with its own band
                    p.values = g[o].clone();
                    p.diverged_at = None;
                    p.diverged_members = (0..=self.outputs[o].ensemble.len()).collect();
                    p.half_width = match (mode, &base.outputs[o].base_band) {
                        (Mode::FreeRun, Some(b)) => Some(vec![b.half_width(0.0); g[o].len()]),
                        _ => None,
                    };
                }
                super::base::BaseUse::BaseAndNetwork => {
                    for (v, gv) in p.values.iter_mut().zip(&g[o]) {
                        *v += gv;
                    }
                    // the network alone's free run is the second opinion that widens the band;
                    // where it diverged the disagreement is unknown, and the grey-box alone's
                    // band (wider than the pair's where they agree) stands in
                    let kept = base.outputs[o].network_alone.is_some() && mode == Mode::FreeRun;
                    match (&alone[o], &self.outputs[o].band) {
                        (Some(a), Some(b)) => {
                            p.half_width = Some(
                                p.values
                                    .iter()
                                    .zip(a)
                                    .map(|(v, a)| b.half_width((v - a).abs()))
                                    .collect(),
                            );
                        }
                        (None, _) if kept => {
                            p.half_width = base.outputs[o]
                                .base_band
                                .as_ref()
                                .map(|b| vec![b.half_width(0.0); p.values.len()]);
                        }
                        _ => {}
                    }
                }
                super::base::BaseUse::Base => {
                    // the base predicts its committee's median, and says where its own run
                    // departs from it
                    let std = self.outputs[o].scaling.std;
                    let band = self.outputs[o].band.as_ref();
                    let committee = base.committee(o, &g[o], std, history, rec)?;
                    g[o] = committee.median;
                    p.base_departure = committee.departure;
                    // the output's network ran on the measured output: its free run is the
                    // second opinion whose disagreement with the base widens the band, and so
                    // does the committee's own spread where it is the larger (the fits the
                    // record supports part where it did not decide the output)
                    let net = std::mem::replace(&mut p.values, g[o].clone());
                    let net = if p.diverged_at.is_some() {
                        &[][..]
                    } else {
                        &net[..]
                    };
                    p.diverged_at = None;
                    p.diverged_members.clear();
                    p.half_width = match (mode, band) {
                        (Mode::FreeRun, Some(b)) => Some(
                            (0..g[o].len())
                                .map(|k| {
                                    let second = net.get(k).map_or(0.0, |a| (g[o][k] - a).abs());
                                    b.half_width(second.max(committee.spread[k]))
                                })
                                .collect(),
                        ),
                        _ => None,
                    };
                }
            }
            // on a long record, the base's witnesses widen the band, whichever stands, where
            // they part from its run (`GreyBoxBase::witness_spread`); they never narrow it
            if mode == Mode::FreeRun && base.uses(o) != super::base::BaseUse::Network {
                if let Some(h) = p.half_width.as_mut() {
                    let w = base.witness_spread(o, &g[o], history, rec)?;
                    for (h, w) in h.iter_mut().zip(&w) {
                        *h = h.max(super::band::spread_cover(*w));
                    }
                }
            }
        }
        Ok(preds)
    }

    /// The free runs of the networks alone that base-and-network outputs keep as second
    /// opinions ([`super::base::BaseChoice::network_alone`]) over `rec`, per output (`None`:
    /// none kept, not a free run, or it diverged).
    fn networks_alone(
        &self,
        base: &super::base::GreyBoxBase,
        rec: &IoRecord,
        mode: Mode,
    ) -> Result<Vec<Option<Vec<f64>>>, NarxError> {
        let kept = |o: usize| {
            base.outputs
                .get(o)
                .filter(|_| base.uses(o) == super::base::BaseUse::BaseAndNetwork)
                .and_then(|c| c.network_alone.as_ref())
        };
        let n = self.outputs.len();
        if mode != Mode::FreeRun || (0..n).all(|o| kept(o).is_none()) {
            return Ok(vec![None; n]);
        }
        let mut m = self.clone();
        m.base = None;
        for (o, out) in m.outputs.iter_mut().enumerate() {
            if let Some(a) = kept(o) {
                *out = a.clone();
            }
        }
        let runs = m.predict_sampled(rec, mode)?;
        Ok(runs
            .into_iter()
            .enumerate()
            .map(|(o, p)| (kept(o).is_some() && p.diverged_at.is_none()).then_some(p.values))
            .collect())
    }

    /// [`FittedNarx::predict`] of the networks alone, at the model's sampling.
    fn predict_sampled(
        &self,
        rec: &IoRecord,
        mode: Mode,
    ) -> Result<Vec<OutputPrediction>, NarxError> {
        let s = self.config.decimation;
        if s <= 1 {
            return self.predict_native(rec, mode);
        }
        self.check_record(rec)?;
        let n = rec.len();
        let start = self.config.lags.start();
        if n < s * (start + 1) {
            return Err(NarxError::TooShort {
                path: rec.path.clone(),
                rows: n,
                needed: s * (start + 1),
                why: format!(
                    "the model samples every {s}th sample and its lags need {start} initial samples per phase"
                ),
            });
        }
        let phases: Vec<Vec<OutputPrediction>> = (0..s)
            .map(|p| self.predict_native(&rec.phase(s, p), mode))
            .collect::<Result<_, _>>()?;
        Ok((0..self.outputs.len())
            .map(|o| interleave(phases.iter().map(|ph| &ph[o]).collect(), s, n))
            .collect())
    }

    /// [`FittedNarx::predict`] at the model's own sampling (every sample of `rec`).
    fn predict_native(
        &self,
        rec: &IoRecord,
        mode: Mode,
    ) -> Result<Vec<OutputPrediction>, NarxError> {
        self.check_record(rec)?;
        let lags = self.config.lags;
        let start = lags.start();
        let mut out = Vec::new();
        for o in &self.outputs {
            let measured = rec
                .outputs
                .iter()
                .find(|s| s.name == o.name)
                .map(|s| &s.values[..]);
            let s = self.series(rec, o, measured);
            let mut diverged_members = Vec::new();
            let mut half_width = None;
            let (z, diverged_at) = match mode {
                Mode::OneStep => {
                    if measured.is_none() {
                        return Err(NarxError::OutputsNeeded {
                            path: rec.path.clone(),
                            expected: names_str(&self.config.outputs),
                        });
                    }
                    let reg = &o.regressor;
                    let d = Design::new(&s, reg);
                    let mut acts = vec![0.0; o.network.acts_len()];
                    let mut z = s.y[..start].to_vec();
                    let combine = self.config.robust.combine;
                    let mut v = vec![0.0; 1 + o.ensemble.len()];
                    for (i, row) in d.x.chunks_exact(d.width).enumerate() {
                        for (vj, net) in v.iter_mut().zip(o.members()) {
                            net.forward(row, &mut acts);
                            *vj = net.output(&acts)[0];
                        }
                        let c = combine.apply(&mut v);
                        z.push(reg.base(&s.y, start + i) + reg.scale() * c);
                    }
                    (z, None)
                }
                Mode::FreeRun => {
                    let (lo, hi) = o.free_run_bounds();
                    let members: Vec<&Mlp> = o.members().collect();
                    let extra: Vec<&Mlp> = if o.band.is_some() {
                        o.band_members.iter().collect()
                    } else {
                        Vec::new()
                    };
                    let run = ensemble_free_run(
                        &members,
                        &extra,
                        &o.regressor,
                        &s,
                        lo,
                        hi,
                        self.config.robust.combine,
                    );
                    diverged_members = run.diverged_members;
                    half_width = o
                        .band
                        .as_ref()
                        .filter(|_| run.diverged_at.is_none())
                        .map(|b| {
                            run.spread
                                .iter()
                                .map(|sp| b.half_width(sp * o.scaling.std))
                                .collect()
                        });
                    (run.values, run.diverged_at)
                }
            };
            out.push(OutputPrediction {
                name: o.name.clone(),
                values: z.iter().map(|v| o.scaling.invert(*v)).collect(),
                start,
                diverged_at,
                diverged_members,
                half_width,
                base_departure: None,
            });
        }
        Ok(out)
    }

    /// The model file text.
    pub fn to_json(&self) -> String {
        let v = serde_json::json!({
            "format": FORMAT,
            "version": VERSION,
            "model": self,
        });
        serde_json::to_string_pretty(&v).expect("a model serialises")
    }

    /// Read a model file; another format or version, or a damaged file, is a clear error.
    pub fn from_json(path: &Path, text: &str) -> Result<FittedNarx, NarxError> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct File {
            #[allow(dead_code)]
            format: String,
            #[allow(dead_code)]
            version: u32,
            model: FittedNarx,
        }
        let header = FileHeader::read(path, text)?;
        match header.format_str() {
            Some(FORMAT) => {}
            Some(other) => {
                return Err(NarxError::NotAModel {
                    path: path.to_path_buf(),
                    why: format!("`format` is \"{other}\", expected \"{FORMAT}\""),
                })
            }
            None => {
                return Err(NarxError::NotAModel {
                    path: path.to_path_buf(),
                    why: format!("no `format` field (expected \"{FORMAT}\")"),
                })
            }
        }
        match header.version {
            Some(x) if x.as_u64() == Some(VERSION as u64) => {}
            other => {
                return Err(NarxError::Version {
                    path: path.to_path_buf(),
                    found: other.map_or("(missing)".into(), |x| x.to_string()),
                    supported: VERSION,
                })
            }
        }
        let m = parse_json_file::<File>(path, text)?.model;
        m.validate().map_err(|why| NarxError::Damaged {
            path: path.to_path_buf(),
            why,
        })?;
        Ok(m)
    }

    /// Internal consistency of a loaded model.
    fn validate(&self) -> Result<(), String> {
        self.config.check().map_err(|e| format!("config: {e}"))?;
        if self.input_scaling.len() != self.config.n_signals() {
            return Err(format!(
                "{} input scalings for {} inputs and features",
                self.input_scaling.len(),
                self.config.n_signals()
            ));
        }
        if self.outputs.len() != self.config.outputs.len() {
            return Err(format!(
                "{} output models for {} outputs",
                self.outputs.len(),
                self.config.outputs.len()
            ));
        }
        if let Some(b) = &self.base {
            if b.outputs.len() != self.outputs.len() {
                return Err(format!(
                    "grey-box base: {} output choices for {} outputs",
                    b.outputs.len(),
                    self.outputs.len()
                ));
            }
            if let Some(p) = b.plant(Path::new("")).map_err(|e| e.to_string())? {
                if p.inputs != self.config.inputs || p.outputs != self.config.outputs {
                    return Err(format!(
                        "grey-box base: its plant has inputs {} and outputs {}, the model {} and {}",
                        names_str(&p.inputs),
                        names_str(&p.outputs),
                        names_str(&self.config.inputs),
                        names_str(&self.config.outputs)
                    ));
                }
            }
            for c in &b.outputs {
                if let Some(band) = &c.base_band {
                    band.check()
                        .map_err(|e| format!("output `{}`: the grey-box alone's {e}", c.name))?;
                }
            }
        }
        for (o, name) in self.outputs.iter().zip(&self.config.outputs) {
            self.check_output(o, name)?;
        }
        if let Some(b) = &self.base {
            for (c, name) in b.outputs.iter().zip(&self.config.outputs) {
                if let Some(a) = &c.network_alone {
                    self.check_output(a, name)
                        .map_err(|e| format!("the network alone kept beside the grey-box: {e}"))?;
                }
            }
        }
        for (i, s) in self.input_scaling.iter().enumerate() {
            if !(s.mean.is_finite() && s.std.is_finite() && s.std > 0.0) {
                return Err(format!("exogenous signal {i}: invalid scaling"));
            }
        }
        Ok(())
    }

    /// One output's model against the configuration (the output `name`).
    fn check_output(&self, o: &OutputModel, name: &str) -> Result<(), String> {
        let width = self.config.lags.width(self.config.n_signals());
        if o.regressor.lags != self.config.lags
            || o.regressor.du_gain.len() != self.config.n_signals()
            || !(o.regressor.dy_gain.is_finite()
                && o.regressor.du_gain.iter().all(|g| g.is_finite()))
        {
            return Err(format!(
                "output `{}`: regressor does not match the configuration",
                o.name
            ));
        }
        if o.name != name {
            return Err(format!(
                "output model `{}` where `{name}` was expected",
                o.name
            ));
        }
        for net in o.members().chain(&o.band_members) {
            if net.sizes.len() < 3 || net.sizes[0] != width || net.sizes[net.sizes.len() - 1] != 1 {
                return Err(format!(
                    "output `{}`: network sizes {:?} do not fit a regressor of width {width}",
                    o.name, net.sizes
                ));
            }
            let np = super::mlp::parameter_count(&net.sizes, net.bypass);
            if net.params.len() != np {
                return Err(format!(
                    "output `{}`: {} parameters, the network shape needs {np}",
                    o.name,
                    net.params.len()
                ));
            }
            if let Some(i) = net.params.iter().position(|p| !p.is_finite()) {
                return Err(format!("output `{}`: parameter {i} is not finite", o.name));
            }
        }
        if let Some(b) = &o.band {
            b.check().map_err(|e| format!("output `{}`: {e}", o.name))?;
        }
        let sc = [o.scaling.mean, o.scaling.std, o.train_min, o.train_max];
        if !sc.iter().all(|v| v.is_finite()) || o.scaling.std <= 0.0 {
            return Err(format!("output `{}`: invalid scaling", o.name));
        }
        Ok(())
    }

    /// Read a model file from disk.
    pub fn load(path: &Path) -> Result<FittedNarx, NarxError> {
        FittedNarx::from_json(path, &read_json_text(path)?)
    }
}

/// Train and test scores of one output, as the source study reported them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputEvaluation {
    pub name: String,
    pub r2_osa_train: Option<f64>,
    pub r2_fr_train: Option<f64>,
    pub r2_osa_test: Option<f64>,
    pub r2_fr_test: Option<f64>,
    pub rmse_fr_test: Option<f64>,
    pub fr_test: Option<Scores>,
    /// Sample of the training free run where it diverged.
    pub diverged_at_train: Option<usize>,
    /// Sample of the test free run where it diverged.
    pub diverged_at_test: Option<usize>,
    /// Ensemble members whose test free run diverged (left out of the combination).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub diverged_members_test: Vec<usize>,
    /// Where the output's chosen grey-box base departed from its committee's median on the
    /// test record ([`super::consensus`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_departure_test: Option<super::consensus::Departure>,
    /// Share of the test samples whose measurement lies inside the free run's 95 % band
    /// (`None`: no band, or the free run diverged).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub band_coverage_test: Option<f64>,
    /// The band's mean half-width over the test samples, in standard deviations of the
    /// measured test output ([`super::band::relative_width`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub band_width_test: Option<f64>,
}

impl OutputEvaluation {
    /// The scores as `identify --json` writes them for one output.
    pub fn to_json(&self) -> serde_json::Value {
        let mut m = serde_json::Map::new();
        m.insert("r2_osa_train".into(), self.r2_osa_train.into());
        m.insert("r2_fr_train".into(), self.r2_fr_train.into());
        m.insert("r2_osa_test".into(), self.r2_osa_test.into());
        m.insert("r2_fr_test".into(), self.r2_fr_test.into());
        m.insert("rmse_fr_test".into(), self.rmse_fr_test.into());
        if let Some(k) = self.diverged_at_test {
            m.insert("diverged_at".into(), k.into());
        }
        if let Some(k) = self.diverged_at_train {
            m.insert("diverged_at_train".into(), k.into());
        }
        if !self.diverged_members_test.is_empty() {
            m.insert(
                "ensemble_members_diverged_test".into(),
                self.diverged_members_test.clone().into(),
            );
        }
        if let Some(d) = &self.base_departure_test {
            m.insert(
                "base_departure".into(),
                serde_json::to_value(d).unwrap_or_default(),
            );
        }
        if let Some(c) = self.band_coverage_test {
            m.insert("band_coverage_test".into(), c.into());
        }
        if let Some(w) = self.band_width_test {
            m.insert("band_width_test".into(), w.into());
        }
        serde_json::Value::Object(m)
    }
}

impl FittedNarx {
    /// The report of an identification, as `identify --json` prints it: the scores per output,
    /// the training time, the choices made (model sampling, grey-box base, features) and where
    /// the test record leaves the training region (`outside`).
    pub fn report_json(
        &self,
        eval: &[OutputEvaluation],
        outside: &[super::region::Outside],
    ) -> serde_json::Value {
        let mut outs = serde_json::Map::new();
        for e in eval {
            outs.insert(e.name.clone(), e.to_json());
        }
        let mut v = serde_json::json!({"outputs": outs, "train_seconds": self.train_seconds});
        if let Some(ds) = &self.decimation_selection {
            v["decimation"] = serde_json::json!({"chosen": ds.chosen, "tried": ds.tried});
        }
        v["extrapolation"] = serde_json::to_value(outside).unwrap_or_default();
        if let Some(b) = &self.base {
            v["greybox"] = serde_json::to_value(b).unwrap_or_default();
            if let Some(o) = v["greybox"].as_object_mut() {
                o.remove("plant");
            }
        }
        if let Some(fs) = &self.feature_selection {
            v["feature_selection"] = serde_json::json!({
                "tried": fs.tried,
                "chosen": fs.chosen,
                "validation_mse_without": fs.selection_mse_without,
                "validation_mse_with": fs.selection_mse_with,
            });
        }
        v
    }

    /// One-step and free-run scores on a training and a test record (both with outputs).
    pub fn evaluate(
        &self,
        train: &IoRecord,
        test: &IoRecord,
    ) -> Result<Vec<OutputEvaluation>, NarxError> {
        self.evaluate_with(train, test, false)
    }

    /// [`FittedNarx::evaluate`] when the test record continues the training record (the
    /// halves of one record): a grey-box base runs on through it ([`FittedNarx::predict_after`]).
    pub fn evaluate_split(
        &self,
        train: &IoRecord,
        test: &IoRecord,
    ) -> Result<Vec<OutputEvaluation>, NarxError> {
        self.evaluate_with(train, test, true)
    }

    fn evaluate_with(
        &self,
        train: &IoRecord,
        test: &IoRecord,
        continues: bool,
    ) -> Result<Vec<OutputEvaluation>, NarxError> {
        let history = continues.then_some(train);
        let osa_tr = self.predict(train, Mode::OneStep)?;
        let fr_tr = self.predict(train, Mode::FreeRun)?;
        let osa_te = self.predict_after(history, test, Mode::OneStep)?;
        let fr_te = self.predict_after(history, test, Mode::FreeRun)?;
        let measured = |rec: &IoRecord, name: &str| -> Vec<f64> {
            rec.outputs
                .iter()
                .find(|s| s.name == name)
                .map(|s| s.values.clone())
                .unwrap_or_default()
        };
        let mut out = Vec::new();
        for (i, o) in self.outputs.iter().enumerate() {
            let ytr = measured(train, &o.name);
            let yte = measured(test, &o.name);
            let fr_test = fr_te[i].scores(&yte);
            let (band_coverage_test, band_width_test) = fr_te[i].band_scores(&yte);
            out.push(OutputEvaluation {
                name: o.name.clone(),
                r2_osa_train: osa_tr[i].scores(&ytr).and_then(|s| s.r2),
                r2_fr_train: fr_tr[i].scores(&ytr).and_then(|s| s.r2),
                r2_osa_test: osa_te[i].scores(&yte).and_then(|s| s.r2),
                r2_fr_test: fr_test.and_then(|s| s.r2),
                rmse_fr_test: fr_test.map(|s| s.rmse),
                fr_test,
                diverged_at_train: fr_tr[i].diverged_at,
                diverged_at_test: fr_te[i].diverged_at,
                diverged_members_test: fr_te[i].diverged_members.clone(),
                base_departure_test: fr_te[i].base_departure.clone(),
                band_coverage_test,
                band_width_test,
            });
        }
        Ok(out)
    }
}

/// The predictions of the `s` phases of a record of `n` samples (phase p: samples p, p + s,
/// ...) put back in time order. A phase that diverged ends the prediction at its sample.
fn interleave(phases: Vec<&OutputPrediction>, s: usize, n: usize) -> OutputPrediction {
    let diverged_at = phases
        .iter()
        .enumerate()
        .filter_map(|(p, ph)| ph.diverged_at.map(|k| k * s + p))
        .min();
    let len = diverged_at.unwrap_or(n).min(
        (0..s)
            .map(|p| phases[p].values.len() * s + p)
            .min()
            .unwrap_or(0),
    );
    let mut diverged_members: Vec<usize> = phases
        .iter()
        .flat_map(|ph| ph.diverged_members.iter().copied())
        .collect();
    diverged_members.sort_unstable();
    diverged_members.dedup();
    let half_width = phases.iter().all(|ph| ph.half_width.is_some()).then(|| {
        (0..len)
            .map(|k| phases[k % s].half_width.as_ref().map_or(0.0, |h| h[k / s]))
            .collect()
    });
    OutputPrediction {
        name: phases[0].name.clone(),
        values: (0..len).map(|k| phases[k % s].values[k / s]).collect(),
        start: phases[0].start * s,
        diverged_at,
        diverged_members,
        half_width,
        base_departure: None,
    }
}

/// The free run of an ensemble (standardised units): the members' runs combined sample by
/// sample where they did not diverge, and the spread ([`spread`]) of those runs and of the
/// band-only members' that did not diverge.
pub(super) struct EnsembleRun {
    pub values: Vec<f64>,
    /// Set when every member diverged (the earliest).
    pub diverged_at: Option<usize>,
    pub diverged_members: Vec<usize>,
    pub spread: Vec<f64>,
}

/// Runs every member (and band-only member) free on `s` and combines them ([`EnsembleRun`]).
pub(super) fn ensemble_free_run(
    members: &[&Mlp],
    band_only: &[&Mlp],
    reg: &Regressor,
    s: &Series,
    lo: f64,
    hi: f64,
    combine: Combine,
) -> EnsembleRun {
    let runs: Vec<(Vec<f64>, Option<usize>)> = members
        .iter()
        .map(|net| free_run_fast(net, reg, s, lo, hi))
        .collect();
    let diverged_members: Vec<usize> = runs
        .iter()
        .enumerate()
        .filter(|(_, r)| r.1.is_some())
        .map(|(i, _)| i)
        .collect();
    let kept: Vec<&[f64]> = runs
        .iter()
        .filter(|r| r.1.is_none())
        .map(|r| &r.0[..])
        .collect();
    let across = |runs: &[&[f64]], len: usize| -> Vec<f64> {
        let mut v = vec![0.0; runs.len()];
        (0..len)
            .map(|t| {
                for (vj, r) in v.iter_mut().zip(runs) {
                    *vj = r[t];
                }
                combine.apply(&mut v)
            })
            .collect()
    };
    if kept.is_empty() {
        // every member diverged: the output diverged (the earliest)
        let len = runs.iter().map(|r| r.0.len()).min().unwrap_or(0);
        let all: Vec<&[f64]> = runs.iter().map(|r| &r.0[..]).collect();
        EnsembleRun {
            values: across(&all, len),
            diverged_at: runs.iter().filter_map(|r| r.1).min(),
            diverged_members,
            spread: vec![0.0; len],
        }
    } else {
        let extra: Vec<(Vec<f64>, Option<usize>)> = band_only
            .iter()
            .map(|net| free_run_fast(net, reg, s, lo, hi))
            .collect();
        let mut all = kept.clone();
        all.extend(extra.iter().filter(|r| r.1.is_none()).map(|r| &r.0[..]));
        EnsembleRun {
            values: across(&kept, s.len()),
            diverged_at: None,
            diverged_members,
            spread: spread(&all, s.len()),
        }
    }
}
