//! # NARX training on several records
//!
//! [`NarxConfig::fit_records`]: the default protocol of [`NarxConfig::fit`] on a list of
//! records (several experiments of one system, e.g. one per operating point), such that no
//! regressor and no free-run window ever crosses a record boundary:
//!
//! - scalings: inputs and outputs standardised with the statistics of all records together;
//!   the incremental form's difference scalings from the differences *within* each record;
//! - one-step phase: the regressor rows of every record's first 80 % (per record) stacked;
//!   early stopping on the rows of every record's last 20 %;
//! - simulation-error phase: [`ROUNDS`] rounds over the records, each a call of
//!   [`train_simulation_error`] on one record alone (its windows stay inside that record;
//!   the weights with the best free run on that record's validation part are kept);
//! - the restart with the lowest mean free-run validation MSE over the records wins.
//!
//! The fitted model is an ordinary [`FittedNarx`] (predict, save, load as usual).
//!
//! ## References
//! - S. Chen, S. A. Billings, P. M. Grant, Int. J. Control 51(6):1191-1214, 1990.
//! - A. H. Ribeiro, L. A. Aguirre, Neurocomputing 316:222-231, 2018 (simulation error).

use super::config::{NarxConfig, Protocol, RobustSettings};
use super::mlp::Mlp;
use super::model::{FittedNarx, OutputModel, OutputTraining, RestartRecord, DIVERGENCE_RANGES};
use super::regressors::{Regressor, RegressorForm, Series, Standardiser};
use super::train::{
    free_run_score, init_output_layer, train_one_step, train_simulation_error, Design,
};
use super::NarxError;
use crate::data::IoRecord;
use crate::effect::noise::stream_seed;
use rayon::prelude::*;

/// Rounds of simulation-error training over the records.
pub const ROUNDS: usize = 3;

/// 1 / standard deviation of the differences within each segment (1 when constant).
fn pooled_diff_gain(segments: &[&[f64]]) -> f64 {
    let d: Vec<f64> = segments
        .iter()
        .flat_map(|x| x.windows(2).map(|w| w[1] - w[0]))
        .collect();
    let m = crate::metrics::mean(&d);
    let sd = (d.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / d.len().max(1) as f64).sqrt();
    if sd > 0.0 && sd.is_finite() {
        1.0 / sd
    } else {
        1.0
    }
}

fn stack(designs: &[Design]) -> Design {
    let width = designs.first().map_or(0, |d| d.width);
    Design {
        x: designs.iter().flat_map(|d| d.x.iter().copied()).collect(),
        t: designs.iter().flat_map(|d| d.t.iter().copied()).collect(),
        width,
    }
}

/// One record's standardised series and where its validation part starts.
struct Part {
    s: Series,
    fit_end: usize,
}

impl NarxConfig {
    /// Fit on several records (same inputs, outputs and sampling period); see the module
    /// documentation. Needs the default protocol. With a single record this is a variant of
    /// [`NarxConfig::fit`] (same phases), not bit-identical to it: no feature selection and
    /// one network per output (the fitted model's config says so).
    pub fn fit_records(&self, records: &[IoRecord]) -> Result<FittedNarx, NarxError> {
        self.check()?;
        let t0 = std::time::Instant::now();
        if self.protocol != Protocol::Default {
            return Err(NarxError::InvalidConfig {
                field: "protocol",
                value: "study".into(),
                rule: "training on several records needs the default protocol",
            });
        }
        let Some(first) = records.first() else {
            return Err(NarxError::InvalidConfig {
                field: "records",
                value: "0".into(),
                rule: "at least one training record is needed",
            });
        };
        let start = self.lags.start();
        for rec in records {
            if rec.input_names() != self.inputs || rec.output_names() != self.outputs {
                return Err(NarxError::ColumnMismatch {
                    path: rec.path.clone(),
                    what: "input/output",
                    expected: format!(
                        "[{}] -> [{}]",
                        self.inputs.join(", "),
                        self.outputs.join(", ")
                    ),
                    found: format!(
                        "[{}] -> [{}]",
                        rec.input_names().join(", "),
                        rec.output_names().join(", ")
                    ),
                });
            }
            if rec.len() < start + 20 {
                return Err(NarxError::TooShort {
                    path: rec.path.clone(),
                    rows: rec.len(),
                    needed: start + 20,
                    why: "each training record needs its initial lags plus a fitting and a validation part".into(),
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
        let raw: Vec<Vec<Vec<f64>>> = records
            .iter()
            .map(|r| {
                let u: Vec<&[f64]> = r.inputs.iter().map(|s| &s.values[..]).collect();
                self.exogenous(&u, r.ts)
            })
            .collect();
        let n_u = raw[0].len();
        let input_scaling: Vec<Standardiser> = (0..n_u)
            .map(|j| {
                let all: Vec<f64> = raw.iter().flat_map(|r| r[j].iter().copied()).collect();
                Standardiser::fit(&all)
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
        let restarts = self.robust.restarts_for(n_total);
        let r: RobustSettings = self.robust.clone();
        let mut outputs = Vec::new();
        for (o, name) in self.outputs.iter().enumerate() {
            let all_y: Vec<f64> = records
                .iter()
                .flat_map(|rec| rec.outputs[o].values.iter().copied())
                .collect();
            let first_y = all_y[0];
            if all_y.iter().all(|v| *v == first_y) {
                return Err(NarxError::ConstantOutput {
                    path: first.path.clone(),
                    name: name.clone(),
                    value: first_y,
                });
            }
            let scaling = Standardiser::fit(&all_y);
            let parts: Vec<Part> = records
                .iter()
                .zip(&u_std)
                .map(|(rec, u)| {
                    let n = rec.len();
                    let n_val = (n as f64 * r.validation_fraction).round() as usize;
                    let fit_end = if n_val >= 8 && n - n_val >= start + 8 {
                        n - n_val
                    } else {
                        n
                    };
                    Part {
                        s: Series {
                            y: scaling.apply(&rec.outputs[o].values),
                            u: u.clone(),
                        },
                        fit_end,
                    }
                })
                .collect();
            let form = RegressorForm::Incremental;
            let ys: Vec<&[f64]> = parts.iter().map(|p| &p.s.y[..]).collect();
            let reg = Regressor {
                lags: self.lags,
                form,
                dy_gain: pooled_diff_gain(&ys),
                du_gain: (0..n_u)
                    .map(|j| {
                        let segs: Vec<&[f64]> = parts.iter().map(|p| &p.s.u[j][..]).collect();
                        pooled_diff_gain(&segs)
                    })
                    .collect(),
            };
            let d_fit = stack(
                &parts
                    .iter()
                    .map(|p| Design::new(&p.s.slice(0..p.fit_end), &reg))
                    .collect::<Vec<_>>(),
            );
            let vals: Vec<Design> = parts
                .iter()
                .filter(|p| p.fit_end < p.s.len())
                .map(|p| Design::new(&p.s.slice(p.fit_end - start..p.s.len()), &reg))
                .collect();
            let d_val = (!vals.is_empty()).then(|| stack(&vals));
            let lo = all_y.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = all_y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let range = (hi - lo).max(f64::MIN_POSITIVE);
            let (zlo, zhi) = (
                (lo - DIVERGENCE_RANGES * range - scaling.mean) / scaling.std,
                (hi + DIVERGENCE_RANGES * range - scaling.mean) / scaling.std,
            );
            // validation free runs: from half-way into each record's fitting part
            let val_runs: Vec<(Series, usize)> = parts
                .iter()
                .map(|p| {
                    let val_from = if p.fit_end < p.s.len() {
                        p.fit_end
                    } else {
                        start
                    };
                    let sim_from = (p.fit_end / 2).max(start).min(val_from);
                    (
                        p.s.slice(sim_from - start..p.s.len()),
                        val_from + start - sim_from,
                    )
                })
                .collect();
            let score = |net: &Mlp| -> Option<f64> {
                let mut sum = 0.0;
                for (s, from) in &val_runs {
                    sum += free_run_score(net, &reg, s, *from, zlo, zhi)?;
                }
                Some(sum / val_runs.len() as f64)
            };
            let results: Vec<(Mlp, RestartRecord)> = (0..restarts)
                .into_par_iter()
                .map(|k| {
                    let seed = stream_seed(self.seed, (o as u64) << 32 | k as u64);
                    let mut net = self.network(r.bypass, stream_seed(seed, 1));
                    init_output_layer(&mut net, &d_fit, 1e-8);
                    let one_step = train_one_step(
                        &mut net,
                        &d_fit,
                        d_val.as_ref().or(Some(&d_fit)),
                        self.optimizer,
                        self.lr,
                        self.batch,
                        self.epochs,
                        Some(r.patience),
                        stream_seed(seed, 2),
                    );
                    let mut per = r.clone();
                    per.sim_steps = (r.sim_steps / (ROUNDS * parts.len())).max(r.eval_every);
                    let mut last = None;
                    for round in 0..ROUNDS {
                        for (i, (p, (val, vf))) in parts.iter().zip(&val_runs).enumerate() {
                            let job = (round * parts.len() + i) as u64;
                            last = Some(train_simulation_error(
                                &mut net,
                                &reg,
                                &p.s,
                                p.fit_end,
                                val,
                                *vf,
                                zlo,
                                zhi,
                                &per,
                                stream_seed(seed, 3 + job),
                            ));
                        }
                    }
                    let selection_mse = score(&net);
                    (
                        net,
                        RestartRecord {
                            seed,
                            one_step,
                            simulation: last,
                            selection_mse,
                        },
                    )
                })
                .collect();
            let chosen = super::model::best_restart(results.iter().map(|r| &r.1));
            let net = results[chosen].0.clone();
            if !net.params.iter().all(|p| p.is_finite()) {
                return Err(NarxError::NonFiniteWeights {
                    output: name.clone(),
                    lr: self.lr,
                });
            }
            let train_samples = parts.iter().map(|p| p.fit_end).sum();
            outputs.push(OutputModel {
                name: name.clone(),
                scaling,
                train_min: lo,
                train_max: hi,
                regressor: reg,
                network: net,
                ensemble: Vec::new(),
                training: OutputTraining {
                    train_samples,
                    validation_samples: n_total - train_samples,
                    restarts: results.into_iter().map(|r| r.1).collect(),
                    chosen_restart: chosen,
                    ensemble_restarts: Vec::new(),
                },
            });
        }
        // what was done: no feature selection, one network per output
        let mut config = self.clone();
        config.robust.try_features.clear();
        config.robust.ensemble = Some(1);
        Ok(FittedNarx {
            config,
            input_scaling,
            outputs,
            train_seconds: t0.elapsed().as_secs_f64(),
            feature_selection: None,
        })
    }
}
