//! # Fitting a NARX model: one path for one record and for several
//!
//! [`NarxConfig::fit`] trains on one record (with the default protocol's feature selection);
//! [`NarxConfig::fit_records`] on several experiments of one system (e.g. one per operating
//! point). Both run one routine (`fit_fixed`), in which no regressor and no free-run window ever
//! crosses a record boundary:
//!
//! - scalings: inputs and outputs standardised with the statistics of all records together;
//!   the incremental form's difference scalings from the differences *within* each record;
//! - one-step phase: the regressor rows of every record's fitting part (its first 80 %)
//!   stacked; early stopping on the rows of every record's validation part;
//! - simulation-error phase: [`train_simulation_error`] on each record alone (its windows stay
//!   inside that record; the weights with the best free run on its validation part are kept),
//!   [`ROUNDS`] rounds over the records when there are several;
//! - restarts and ensemble members chosen by the mean free-run validation MSE over the records.
//!
//! Every (output, restart) job runs in parallel; the results do not depend on the thread count.
//!
//! ## References
//! - S. Chen, S. A. Billings, P. M. Grant, Int. J. Control 51(6):1191-1214, 1990.
//! - A. H. Ribeiro, L. A. Aguirre, Neurocomputing 316:222-231, 2018 (simulation error).

use super::band::{Band, BAND_LEVEL};
use super::config::{NarxConfig, Protocol, RobustSettings};
use super::mlp::Mlp;
use super::model::{
    best_restart, ensemble_free_run, input_slices, names_str, DecimationSelection,
    FeatureSelection, FittedNarx, LinearProbe, OutputEvaluation, OutputModel, OutputTraining,
    RestartRecord, DIVERGENCE_RANGES,
};
use super::region::InputRegion;
use super::regressors::{inverse_std, Regressor, RegressorForm, Series, Standardiser};
use super::train::{
    free_run_score, init_output_layer, linear_output_layer, train_one_step, train_simulation_error,
    Design,
};
use super::NarxError;
use crate::data::IoRecord;
use crate::effect::noise::stream_seed;
use crate::effect::{registry, FeatureSpec};
use rayon::prelude::*;
use std::borrow::Cow;

/// Rounds of simulation-error training over the records when there are several.
pub const ROUNDS: usize = 3;

/// The phases of a decimated record that train the model (evenly spread).
pub const MAX_PHASES: usize = 4;

/// The tail of a short record that the linear probe holds out ([`NarxConfig::fit`]).
pub const PROBE_TAIL: f64 = 0.25;

/// The segments one after another (borrowed when there is one).
fn pooled<'a>(segments: &[&'a [f64]]) -> Cow<'a, [f64]> {
    match segments {
        [one] => Cow::Borrowed(one),
        _ => Cow::Owned(segments.concat()),
    }
}

/// 1 / standard deviation of the differences within each segment (1 when constant).
fn pooled_diff_gain(segments: &[&[f64]]) -> f64 {
    let d: Vec<f64> = segments
        .iter()
        .flat_map(|x| x.windows(2).map(|w| w[1] - w[0]))
        .collect();
    inverse_std(&d)
}

fn stack(designs: Vec<Design>) -> Design {
    if designs.len() == 1 {
        return designs.into_iter().next().expect("one design");
    }
    let width = designs.first().map_or(0, |d| d.width);
    Design {
        x: designs.iter().flat_map(|d| d.x.iter().copied()).collect(),
        t: designs.iter().flat_map(|d| d.t.iter().copied()).collect(),
        width,
    }
}

/// One record's standardised series, where its fitting part ends, and its validation free run
/// (the series from half-way into the fitting part, scored from `val_from`).
struct Part {
    s: Series,
    fit_end: usize,
    val: Series,
    val_from: usize,
}

/// Everything one output's restarts share.
struct OutputData {
    scaling: Standardiser,
    reg: Regressor,
    parts: Vec<Part>,
    d_fit: Design,
    d_val: Option<Design>,
    /// The plausible range of the free run (standardised units).
    lo: f64,
    hi: f64,
    train_min: f64,
    train_max: f64,
}

/// One restart: the network, its record, and the numbers of fitting and validation samples.
type Restart = (Mlp, RestartRecord, usize, usize);

/// The network restarts of a short record whose grey-box base describes every output
/// (`base::SHORT_BASE_DESCRIBES`): the base is kept on every output there, and the networks
/// only widen its band where the two part and stand in where its free run fails. With 4
/// instead of 8 (own zoo development seed 38, 40 short records; independent development
/// seed 2, 120): the same test R^2 on every output; own 2-DoF short records 99 -> 79 s summed
/// (one run after the other), mean band coverage 93.3 -> 92.6 % (`docs/benchmarks.md`).
pub const SECOND_OPINION_RESTARTS: usize = 4;

impl NarxConfig {
    /// `identify`: fits on `train` and scores on `test`, with `split` when they are the two
    /// halves of one record (a grey-box base then runs on through the test half); halves too
    /// short for the lags are refused before any work.
    pub fn identify(
        &self,
        train: &IoRecord,
        test: &IoRecord,
        split: bool,
    ) -> Result<(FittedNarx, Vec<OutputEvaluation>), NarxError> {
        let needed = self.lags.start() + 2;
        if split && train.len() < needed {
            return Err(NarxError::HalvesTooShort {
                path: train.path.clone(),
                total: train.len() + test.len(),
                train: train.len(),
                needed,
            });
        }
        let model = self.fit(train)?;
        let eval = if split {
            model.evaluate_split(train, test)?
        } else {
            model.evaluate(train, test)?
        };
        Ok((model, eval))
    }

    /// Fit one network per output on a training record whose inputs and outputs are the
    /// configuration's signals (in order). With the default protocol and
    /// `robust.try_features` (default: hysteresis), the model is fitted without and with those
    /// effects' basis signals and the lower free-run validation error decides (see
    /// [`FeatureSelection`]); the chosen features end up in the fitted model's `config.features`.
    pub fn fit(&self, train: &IoRecord) -> Result<FittedNarx, NarxError> {
        let t0 = std::time::Instant::now();
        // a short record's base first: where it describes every output, the networks are only
        // its second opinion (the band's spread, a fallback) and a few restarts serve
        let short_base = self.short_base(train);
        let mut cfg = self.clone();
        if short_base
            .as_ref()
            .is_some_and(|b| b.describes_every_output)
        {
            cfg.robust.restarts = Some(
                self.robust
                    .restarts_for(train.len())
                    .min(SECOND_OPINION_RESTARTS),
            );
        }
        let m = cfg.fit_selecting_features(train)?;
        let (m, probe) = cfg.probe_linear(train, m)?;
        let m = cfg.choose_decimation(train, m)?;
        let mut m = cfg.choose_base(train, m, probe.as_ref(), short_base)?;
        m.input_region = Some(InputRegion::of(std::slice::from_ref(train)));
        m.sampling_period_s = Some(train.ts);
        m.train_seconds = t0.elapsed().as_secs_f64();
        Ok(m)
    }

    /// On a record too short for a validation part the linear candidate meets the networks on
    /// the training free run, where the networks always win. A probe decides instead: the
    /// plain network (up to 4 restarts) and the linear candidate trained on the record but its
    /// last [`PROBE_TAIL`], and run free on that tail. Outputs whose linear
    /// candidate validates at least as well there are refitted linear on the whole record.
    /// The probe's prediction bands, calibrated on that tail, become the model's. Returns the
    /// probe too (the grey-box base candidate meets it on the same tail).
    fn probe_linear(
        &self,
        train: &IoRecord,
        m: FittedNarx,
    ) -> Result<(FittedNarx, Option<FittedNarx>), NarxError> {
        let n = train.len();
        if self.protocol != Protocol::Default
            || !self.robust.bypass
            || self.robust.for_record(n).validation_fraction != 0.0
        {
            return Ok((m, None));
        }
        let mut probe = self.clone();
        probe.robust.validation_fraction = PROBE_TAIL;
        probe.robust.restarts = Some(self.robust.restarts_for(n).min(4));
        probe.robust.ensemble = Some(1);
        probe.robust.band_restarts = 1;
        probe.robust.try_features.clear();
        let Ok(p) = probe.fit_fixed(std::slice::from_ref(train)) else {
            return Ok((m, None));
        };
        let results: Vec<LinearProbe> = p
            .outputs
            .iter()
            .map(|o| LinearProbe {
                network_mse: o.training.restarts[o.training.chosen_restart].selection_mse,
                linear_mse: o.training.linear_selection_mse,
                linear: o.training.linear,
            })
            .collect();
        let force: Vec<bool> = results.iter().map(|r| r.linear).collect();
        let mut out = if force.iter().any(|&f| f) {
            self.fit_fixed_forcing(std::slice::from_ref(train), &force)?
        } else {
            m
        };
        // the bands: the probe's, calibrated on a tail its fit did not see (the final fit has
        // no held-out part; its own residuals would give bands too narrow)
        for (o, po) in out.outputs.iter_mut().zip(&p.outputs) {
            if po.band.is_some() {
                o.band.clone_from(&po.band);
            }
        }
        out.linear_probe = Some(results);
        Ok((out, Some(p)))
    }

    /// The decimations worth trying on `train`: 4, 16 and 64 where the record's 99 % bandwidth
    /// (inputs and outputs) stays below an eighth of the decimated sampling rate and each phase
    /// keeps 1,000 samples; none with the study protocol, with `try_decimation` off, or when
    /// the configuration fixes a decimation.
    pub fn decimation_candidates(&self, train: &IoRecord) -> Vec<usize> {
        if self.protocol != Protocol::Default || !self.robust.try_decimation || self.decimation != 1
        {
            return Vec::new();
        }
        let f_bw = train
            .inputs
            .iter()
            .chain(&train.outputs)
            .map(|s| crate::signal::bandwidth(&s.values, train.ts, 0.99))
            .fold(0.0, f64::max);
        if f_bw <= 0.0 {
            return Vec::new();
        }
        let s_max = 1.0 / (8.0 * train.ts * f_bw);
        [4, 16, 64]
            .into_iter()
            .filter(|&s| s as f64 <= s_max && train.len() / s >= 1000)
            .collect()
    }

    /// Fits the plain network at each candidate decimation (on up to [`MAX_PHASES`] of the
    /// record's phases as separate records) and keeps the model with the lowest free-run validation error,
    /// `m` (every sample) included.
    fn choose_decimation(&self, train: &IoRecord, m: FittedNarx) -> Result<FittedNarx, NarxError> {
        let candidates = self.decimation_candidates(train);
        if candidates.is_empty() {
            return Ok(m);
        }
        let mut tried = vec![(1, m.selection_mse())];
        let mut best = m;
        for s in candidates {
            let mut c = self.clone();
            c.decimation = s;
            c.robust.try_features.clear();
            let Ok(ms) = c.fit_fixed(std::slice::from_ref(train)) else {
                continue;
            };
            let mse = ms.selection_mse();
            tried.push((s, mse));
            let better = match (mse, best.selection_mse()) {
                (Some(a), Some(b)) => a < b,
                (Some(_), None) => true,
                _ => false,
            };
            if better {
                best = ms;
            }
        }
        best.decimation_selection = Some(DecimationSelection {
            tried,
            chosen: best.config.decimation,
        });
        Ok(best)
    }

    /// [`NarxConfig::fit`] at every sample: the plain network, or the network with the
    /// effect-library features when they validate clearly better.
    fn fit_selecting_features(&self, train: &IoRecord) -> Result<FittedNarx, NarxError> {
        self.check()?;
        let records = std::slice::from_ref(train);
        // Without a validation part (a short record, see `RobustSettings::for_record`) the
        // selection would score the training free run, which favours the richer model.
        if self.protocol != Protocol::Default
            || self.robust.try_features.is_empty()
            || self.robust.for_record(train.len()).validation_fraction == 0.0
        {
            return self.fit_fixed(records);
        }
        let t0 = std::time::Instant::now();
        let mut plain = self.clone();
        plain.robust.try_features.clear();
        // errors (columns, length, constant output) come from the plain fit
        let without = plain.fit_fixed(records)?;
        let inputs = input_slices(train);
        let mut candidates: Vec<FeatureSpec> = Vec::new();
        for e in &self.robust.try_features {
            let specs =
                registry::effect(*e).map_or_else(Vec::new, |x| x.features(&inputs, train.ts));
            for f in specs {
                if !self.features.contains(&f) && !candidates.contains(&f) {
                    candidates.push(f);
                }
            }
        }
        if candidates.is_empty() {
            let mut m = without;
            m.train_seconds = t0.elapsed().as_secs_f64();
            return Ok(m);
        }
        let mut rich = plain.clone();
        rich.features.extend(candidates.iter().cloned());
        let with = rich.fit_fixed(records)?;
        let (a, b) = (without.selection_mse(), with.selection_mse());
        let gain = self.robust.feature_gain;
        let use_them = match (a, b) {
            (None, Some(_)) => true,
            (Some(a), Some(b)) => b < gain * a,
            _ => false,
        };
        let mut m = if use_them { with } else { without };
        m.feature_selection = Some(FeatureSelection {
            tried: self.robust.try_features.clone(),
            candidates,
            selection_mse_without: a,
            selection_mse_with: b,
            chosen: use_them,
        });
        m.train_seconds = t0.elapsed().as_secs_f64();
        Ok(m)
    }

    /// Fit on several records (same inputs, outputs and sampling period); see the module
    /// documentation. Needs the default protocol; runs no feature selection (the fitted
    /// model's config says so). On one record it is [`NarxConfig::fit`] without the selection.
    pub fn fit_records(&self, records: &[IoRecord]) -> Result<FittedNarx, NarxError> {
        self.check()?;
        if self.protocol != Protocol::Default {
            return Err(NarxError::InvalidConfig {
                field: "protocol",
                value: "study".into(),
                rule: "training on several records needs the default protocol",
            });
        }
        let mut m = self.fit_fixed(records)?;
        m.config.robust.try_features.clear();
        m.input_region = Some(InputRegion::of(records));
        m.sampling_period_s = records.first().map(|r| r.ts);
        Ok(m)
    }

    /// The fit with the configuration's features as they are (no selection). With a
    /// decimation s > 1 every record is replaced by up to 4 of its phases (evenly spread).
    pub(super) fn fit_fixed(&self, records: &[IoRecord]) -> Result<FittedNarx, NarxError> {
        self.fit_fixed_forcing(records, &[])
    }

    /// [`Self::fit_fixed`] with the outputs where `force_linear` is true given the linear
    /// candidate whatever the validation says.
    fn fit_fixed_forcing(
        &self,
        records: &[IoRecord],
        force_linear: &[bool],
    ) -> Result<FittedNarx, NarxError> {
        self.check()?;
        let s = self.decimation;
        if s > 1 {
            let k = s.min(MAX_PHASES);
            let phases: Vec<IoRecord> = records
                .iter()
                .flat_map(|r| (0..k).map(move |i| r.phase(s, i * s / k)))
                .collect();
            return self.fit_native(&phases, force_linear);
        }
        self.fit_native(records, force_linear)
    }

    /// [`Self::fit_fixed`] on records at the model's sampling.
    fn fit_native(
        &self,
        records: &[IoRecord],
        force_linear: &[bool],
    ) -> Result<FittedNarx, NarxError> {
        let t0 = std::time::Instant::now();
        self.check_training(records)?;
        let raw: Vec<Vec<Vec<f64>>> = records
            .iter()
            .map(|r| self.exogenous(&input_slices(r), r.ts))
            .collect();
        let input_scaling: Vec<Standardiser> = (0..raw[0].len())
            .map(|j| {
                let segs: Vec<&[f64]> = raw.iter().map(|r| &r[j][..]).collect();
                Standardiser::fit(&pooled(&segs))
            })
            .collect();
        let u_std: Vec<Vec<Vec<f64>>> = raw
            .iter()
            .map(|r| {
                r.iter()
                    .zip(&input_scaling)
                    .map(|(s, sc)| sc.apply(s))
                    .collect()
            })
            .collect();
        let n_total: usize = records.iter().map(IoRecord::len).sum();
        let settings = self.robust.for_record(n_total);
        let data: Vec<OutputData> = (0..self.outputs.len())
            .map(|o| self.output_data(records, &u_std, o, &settings))
            .collect();
        let restarts = match self.protocol {
            Protocol::Default => self.robust.restarts_for(n_total),
            Protocol::Study => 1,
        };
        // every (output, restart) job in parallel; results in order
        let jobs: Vec<(usize, usize)> = (0..data.len())
            .flat_map(|o| (0..restarts).map(move |r| (o, r)))
            .collect();
        let results: Vec<Restart> = jobs
            .par_iter()
            .map(|&(o, r)| {
                let seed = stream_seed(self.seed, (o as u64) << 32 | r as u64);
                self.fit_one(&data[o], &settings, seed)
            })
            .collect();
        let size = match self.protocol {
            Protocol::Default => self.robust.ensemble_size(n_total),
            Protocol::Study => 1,
        };
        let linear: Vec<Option<(Mlp, Option<f64>)>> = data
            .par_iter()
            .map(|d| self.linear_candidate(d, &settings))
            .collect();
        let mut outputs = Vec::new();
        for ((o, d), lin) in data.into_iter().enumerate().zip(linear) {
            let mine = &results[o * restarts..(o + 1) * restarts];
            let force = force_linear.get(o).copied().unwrap_or(false);
            outputs.push(self.output_model(o, d, mine, size, lin, force)?);
        }
        Ok(FittedNarx {
            config: self.clone(),
            input_scaling,
            outputs,
            train_seconds: t0.elapsed().as_secs_f64(),
            feature_selection: None,
            decimation_selection: None,
            linear_probe: None,
            input_region: None,
            base: None,
            sampling_period_s: None,
        })
    }

    /// The records carry the configuration's columns, are long enough for the lags, share one
    /// sampling period, and no output is constant over all of them.
    fn check_training(&self, records: &[IoRecord]) -> Result<(), NarxError> {
        let Some(first) = records.first() else {
            return Err(NarxError::InvalidConfig {
                field: "records",
                value: "0".into(),
                rule: "at least one training record is needed",
            });
        };
        let start = self.lags.start();
        for rec in records {
            for (what, expected, found) in [
                ("input", &self.inputs, rec.input_names()),
                ("output", &self.outputs, rec.output_names()),
            ] {
                if found != *expected {
                    return Err(NarxError::ColumnMismatch {
                        path: rec.path.clone(),
                        what,
                        expected: names_str(expected),
                        found: names_str(&found),
                    });
                }
            }
            let needed = start + 2;
            if rec.len() < needed {
                return Err(NarxError::TooShort {
                    path: rec.path.clone(),
                    rows: rec.len(),
                    needed,
                    why: format!(
                        "{} output lags, {} input lags with delay {} need {} initial samples, plus at least 2 to train on",
                        self.lags.output, self.lags.input, self.lags.delay, start
                    ),
                });
            }
            if (rec.ts - first.ts).abs() > 1e-9 * first.ts {
                return Err(NarxError::InvalidConfig {
                    field: "records",
                    value: format!(
                        "{} s in {}, {} s in {}",
                        rec.ts,
                        rec.path.display(),
                        first.ts,
                        first.path.display()
                    ),
                    rule: "all training records must share one sampling period",
                });
            }
        }
        for (o, name) in self.outputs.iter().enumerate() {
            let value = first.outputs[o].values[0];
            if records
                .iter()
                .all(|r| r.outputs[o].values.iter().all(|v| *v == value))
            {
                return Err(NarxError::ConstantOutput {
                    path: first.path.clone(),
                    name: name.clone(),
                    value,
                });
            }
        }
        Ok(())
    }

    /// Output `o`'s scaling, regressor, designs and validation runs over all records.
    fn output_data(
        &self,
        records: &[IoRecord],
        u_std: &[Vec<Vec<f64>>],
        o: usize,
        r: &RobustSettings,
    ) -> OutputData {
        let start = self.lags.start();
        let ys: Vec<&[f64]> = records.iter().map(|r| &r.outputs[o].values[..]).collect();
        let all_y = pooled(&ys);
        let scaling = Standardiser::fit(&all_y);
        let series: Vec<Series> = ys
            .iter()
            .zip(u_std)
            .map(|(y, u)| Series {
                y: scaling.apply(y),
                u: u.clone(),
            })
            .collect();
        let reg = match self.protocol {
            Protocol::Study => Regressor::fit(self.lags, RegressorForm::Lagged, &series[0]),
            Protocol::Default => Regressor {
                lags: self.lags,
                form: RegressorForm::Incremental,
                dy_gain: pooled_diff_gain(&series.iter().map(|s| &s.y[..]).collect::<Vec<_>>()),
                du_gain: (0..u_std[0].len())
                    .map(|j| {
                        pooled_diff_gain(&series.iter().map(|s| &s.u[j][..]).collect::<Vec<_>>())
                    })
                    .collect(),
            },
        };
        let parts: Vec<Part> = series
            .into_iter()
            .map(|s| {
                let n = s.len();
                let n_val = (n as f64 * r.validation_fraction).round() as usize;
                // validation needs a few samples beyond the initial lags; otherwise score on all
                let has_val =
                    self.protocol == Protocol::Default && n_val >= 8 && n - n_val >= start + 8;
                let (fit_end, val_from) = if has_val {
                    (n - n_val, n - n_val)
                } else {
                    (n, start)
                };
                // The validation free run starts half-way into the fitting part (away from any
                // start-up transient) and is scored on the validation part.
                let sim_from = (fit_end / 2).max(start).min(val_from);
                Part {
                    val: s.slice(sim_from - start..n),
                    val_from: val_from + start - sim_from,
                    s,
                    fit_end,
                }
            })
            .collect();
        let d_fit = stack(
            parts
                .iter()
                .map(|p| Design::new(&p.s.slice(0..p.fit_end), &reg))
                .collect(),
        );
        let vals: Vec<Design> = parts
            .iter()
            .filter(|p| p.fit_end < p.s.len())
            .map(|p| Design::new(&p.s.slice(p.fit_end - start..p.s.len()), &reg))
            .collect();
        let d_val = (!vals.is_empty()).then(|| stack(vals));
        let zs: Vec<&[f64]> = parts.iter().map(|p| &p.s.y[..]).collect();
        let (lo, hi) = plausible_range(&pooled(&zs));
        OutputData {
            scaling,
            reg,
            d_fit,
            d_val,
            lo,
            hi,
            train_min: all_y.iter().copied().fold(f64::INFINITY, f64::min),
            train_max: all_y.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            parts,
        }
    }

    /// One restart for one output.
    fn fit_one(&self, d: &OutputData, r: &RobustSettings, seed: u64) -> Restart {
        let fit_samples: usize = d.parts.iter().map(|p| p.fit_end).sum();
        let samples: usize = d.parts.iter().map(|p| p.s.len()).sum();
        if self.protocol == Protocol::Study {
            let mut net = self.network(false, stream_seed(seed, 1));
            let rec = train_one_step(
                &mut net,
                &d.d_fit,
                None,
                self.optimizer,
                self.lr,
                self.batch,
                self.epochs,
                None,
                stream_seed(seed, 2),
            );
            let record = RestartRecord {
                seed,
                one_step: rec,
                simulation: None,
                selection_mse: None,
            };
            return (net, record, samples, 0);
        }
        let mut net = self.network(r.bypass, stream_seed(seed, 1));
        init_output_layer(&mut net, &d.d_fit, 1e-8);
        let one_step = train_one_step(
            &mut net,
            &d.d_fit,
            d.d_val.as_ref().or(Some(&d.d_fit)),
            self.optimizer,
            self.lr,
            self.batch,
            self.epochs,
            Some(r.patience),
            stream_seed(seed, 2),
        );
        let (rounds, per) = if d.parts.len() == 1 {
            (1, r.clone())
        } else {
            let mut per = r.clone();
            per.sim_steps = (r.sim_steps / (ROUNDS * d.parts.len())).max(r.eval_every);
            (ROUNDS, per)
        };
        let mut simulation = None;
        for round in 0..rounds {
            for (i, p) in d.parts.iter().enumerate() {
                let job = (round * d.parts.len() + i) as u64;
                simulation = Some(train_simulation_error(
                    &mut net,
                    &d.reg,
                    &p.s,
                    p.fit_end,
                    &p.val,
                    p.val_from,
                    d.lo,
                    d.hi,
                    &per,
                    stream_seed(seed, 3 + job),
                ));
            }
        }
        let record = RestartRecord {
            seed,
            one_step,
            simulation,
            selection_mse: self.validation_mse(&net, d),
        };
        (net, record, fit_samples, samples - fit_samples)
    }

    /// The linear candidate of the default protocol (a network whose only path is its
    /// bypass, fitted by one-step least squares) and its free-run validation MSE; `None` with
    /// the study protocol or without a bypass.
    fn linear_candidate(&self, d: &OutputData, r: &RobustSettings) -> Option<(Mlp, Option<f64>)> {
        if self.protocol != Protocol::Default || !r.bypass {
            return None;
        }
        let mut net = self.network(true, 0);
        let h = net.sizes[net.sizes.len() - 2];
        let hidden_end = net.bypass_offset() - h - 1;
        net.params[..hidden_end].fill(0.0);
        if !linear_output_layer(&mut net, &d.d_fit, 1e-8) {
            return None;
        }
        let mse = self.validation_mse(&net, d);
        Some((net, mse))
    }

    /// The mean free-run validation MSE over the records (`None`: a free run diverged).
    fn validation_mse(&self, net: &Mlp, d: &OutputData) -> Option<f64> {
        let mut sum = 0.0;
        for p in &d.parts {
            sum += free_run_score(net, &d.reg, &p.val, p.val_from, d.lo, d.hi)?;
        }
        Some(sum / d.parts.len() as f64)
    }

    /// Output `o`'s model from its restarts: the best one, and the ensemble of `size`; or the
    /// linear candidate when it validates at least as well as the best network (or the
    /// networks diverged and it did not).
    fn output_model(
        &self,
        o: usize,
        d: OutputData,
        mine: &[Restart],
        size: usize,
        linear: Option<(Mlp, Option<f64>)>,
        force_linear: bool,
    ) -> Result<OutputModel, NarxError> {
        let name = &self.outputs[o];
        let chosen = best_restart(mine.iter().map(|r| &r.1));
        let best = mine[chosen].1.selection_mse;
        let (linear_net, linear_mse) = match linear {
            Some((net, mse)) => (Some(net), mse),
            None => (None, None),
        };
        let linear_wins = (force_linear && linear_net.is_some())
            || match (linear_mse, best) {
                (Some(l), Some(b)) => l <= b,
                (Some(_), None) => true,
                _ => false,
            };
        if linear_wins {
            let net = linear_net.expect("a linear candidate");
            // the networks widen the band where they part from it
            let band_members: Vec<Mlp> = choose_ensemble(mine, chosen, mine.len())
                .iter()
                .filter(|&&i| mine[i].1.selection_mse.is_some())
                .take(self.robust.band_restarts.saturating_sub(1))
                .map(|&i| mine[i].0.clone())
                .collect();
            let band = self.calibrate_band(&[&net], &band_members.iter().collect::<Vec<_>>(), &d);
            return Ok(OutputModel {
                name: name.clone(),
                scaling: d.scaling,
                train_min: d.train_min,
                train_max: d.train_max,
                regressor: d.reg,
                network: net,
                ensemble: Vec::new(),
                band,
                band_members,
                training: OutputTraining {
                    train_samples: mine[chosen].2,
                    validation_samples: mine[chosen].3,
                    restarts: mine.iter().map(|r| r.1.clone()).collect(),
                    chosen_restart: chosen,
                    ensemble_restarts: Vec::new(),
                    linear_selection_mse: linear_mse,
                    linear: true,
                },
            });
        }
        let net = mine[chosen].0.clone();
        if !net.params.iter().all(|p| p.is_finite()) {
            return Err(NarxError::NonFiniteWeights {
                output: name.clone(),
                lr: self.lr,
            });
        }
        let members = choose_ensemble(mine, chosen, size);
        let ensemble: Vec<Mlp> = members.iter().skip(1).map(|&i| mine[i].0.clone()).collect();
        let all: Vec<&Mlp> = std::iter::once(&net).chain(&ensemble).collect();
        // the other restarts (best validation first) widen the band where they part
        let others = choose_ensemble(mine, chosen, self.robust.band_restarts.max(members.len()));
        let band_members: Vec<Mlp> = others
            .iter()
            .filter(|i| !members.contains(i))
            .map(|&i| mine[i].0.clone())
            .collect();
        let band = self.calibrate_band(&all, &band_members.iter().collect::<Vec<_>>(), &d);
        Ok(OutputModel {
            name: name.clone(),
            scaling: d.scaling,
            train_min: d.train_min,
            train_max: d.train_max,
            regressor: d.reg,
            network: net,
            ensemble,
            band,
            band_members,
            training: OutputTraining {
                train_samples: mine[chosen].2,
                validation_samples: mine[chosen].3,
                restarts: mine.iter().map(|r| r.1.clone()).collect(),
                chosen_restart: chosen,
                ensemble_restarts: if members.len() > 1 {
                    members
                } else {
                    Vec::new()
                },
                linear_selection_mse: linear_mse,
                linear: false,
            },
        })
    }
}

impl NarxConfig {
    /// The prediction band of an output's final members, calibrated on their free runs over
    /// each training record, scored on its validation part (on the whole record without one;
    /// [`super::band`]); `None` when a run diverged.
    fn calibrate_band(&self, members: &[&Mlp], band_only: &[&Mlp], d: &OutputData) -> Option<Band> {
        let (mut residuals, mut spreads) = (Vec::new(), Vec::new());
        let start = self.lags.start();
        for p in &d.parts {
            // from the record's start, so that the validation residuals are those of a free
            // run as long as the training record (a test record's free run drifts as far)
            let run = ensemble_free_run(
                members,
                band_only,
                &d.reg,
                &p.s,
                d.lo,
                d.hi,
                self.robust.combine,
            );
            if run.diverged_at.is_some() {
                return None;
            }
            let from = if p.fit_end < p.s.len() {
                p.fit_end
            } else {
                start
            };
            for k in from.max(start)..p.s.len() {
                residuals.push((run.values[k] - p.s.y[k]) * d.scaling.std);
                spreads.push(run.spread[k] * d.scaling.std);
            }
        }
        Band::calibrate(&residuals, &spreads, BAND_LEVEL).map(|b| b.with_floor(&residuals))
    }
}

/// The restarts kept for one output: `chosen` first, then the others by their free-run
/// selection MSE (diverged ones left out), at most `size` (training record only).
fn choose_ensemble(mine: &[Restart], chosen: usize, size: usize) -> Vec<usize> {
    let mut ranked: Vec<(usize, f64)> = mine
        .iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let ok = r.0.params.iter().all(|p| p.is_finite());
            r.1.selection_mse.filter(|_| ok).map(|m| (i, m))
        })
        .collect();
    // stable sort: equal errors keep restart order
    ranked.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut order: Vec<usize> = vec![chosen];
    order.extend(ranked.iter().map(|r| r.0).filter(|&i| i != chosen));
    order.truncate(size.max(1));
    order
}

/// The training range widened by [`DIVERGENCE_RANGES`] ranges on each side.
fn plausible_range(y: &[f64]) -> (f64, f64) {
    let lo = y.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let r = (hi - lo).max(f64::MIN_POSITIVE);
    (lo - DIVERGENCE_RANGES * r, hi + DIVERGENCE_RANGES * r)
}
