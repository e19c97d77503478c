//! The driver: checks a record against a configuration, sets up one problem per output, runs
//! the initialisation and Levenberg-Marquardt, and scores the fitted plant by simulating it.

use super::fit::{levenberg_marquardt, LmResult, OutputProblem, OutputStructure};
use super::{
    FitSummary, FittedGreyBox, GreyBoxConfig, GreyBoxError, HysteresisOperator, OutputFit,
};
use crate::data::IoRecord;
use crate::plant::{PlantSpec, Units};
use std::time::Instant;

/// Creep time constants: one per decade (powers of ten) from about 5 samples to about a third
/// of the record. `Err(needed samples)` when fewer than three (two decades) fit.
pub fn creep_time_constants(samples: usize, ts: f64) -> Result<Vec<f64>, usize> {
    let k_min = (5.0 * ts).log10().ceil() as i32;
    let span = samples as f64 * ts / 3.0;
    // the largest power of ten up to about twice a third of the record
    let k_max = (span.log10() + 0.3).floor() as i32;
    if k_max < k_min + 2 {
        let needed = (3.0 * 10f64.powf(k_min as f64 + 1.7) / ts).ceil() as usize;
        return Err(needed);
    }
    Ok((k_min..=k_max).map(|k| 10f64.powi(k)).collect())
}

/// Direction reversals of a signal (moves below 1e-9 of its range ignored).
pub fn reversals(u: &[f64]) -> usize {
    let ptp = crate::metrics::ptp(u);
    let tol = 1e-9 * ptp;
    let mut dir = 0.0;
    let mut count = 0;
    let mut anchor = u.first().copied().unwrap_or(0.0);
    for &v in u {
        let d = v - anchor;
        if d.abs() > tol {
            let s = d.signum();
            if dir != 0.0 && s != dir {
                count += 1;
            }
            dir = s;
            anchor = v;
        }
    }
    count
}

/// The longest run of samples over which the signal stays within 1e-6 of its range.
pub fn longest_hold(u: &[f64]) -> usize {
    let tol = 1e-6 * crate::metrics::ptp(u);
    let (mut best, mut run) = (0, 1);
    for w in u.windows(2) {
        if (w[1] - w[0]).abs() <= tol {
            run += 1;
        } else {
            run = 1;
        }
        best = best.max(run);
    }
    best
}

/// Fraction of the (mean-removed) input variance that passes a first-order low-pass of time
/// constant `tau`.
pub fn slow_fraction(u: &[f64], ts: f64, tau: f64) -> f64 {
    let m = crate::metrics::mean(u);
    let a = (-ts / tau).exp();
    let mut z = 0.0;
    let (mut num, mut den) = (0.0, 0.0);
    for &v in u {
        let x = v - m;
        z = a * z + (1.0 - a) * x;
        num += z * z;
        den += x * x;
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

/// Initialise (plus `extra` starts), then two Levenberg-Marquardt stages: creep held fixed from
/// each start, then everything from the best.
fn fit_problem(
    prob: &OutputProblem,
    coarse: &OutputProblem,
    extra: Vec<Vec<f64>>,
    options: &super::FitOptions,
) -> Result<LmResult, GreyBoxError> {
    let mut starts = prob.initial(coarse, 3);
    starts.extend(extra);
    let stage1 = prob.without_creep();
    let mut best: Option<LmResult> = None;
    let mut iterations = 0;
    for th0 in starts {
        let r = levenberg_marquardt(prob, th0, &stage1, options)?;
        iterations += r.iterations;
        if best.as_ref().is_none_or(|b| r.eval.cost < b.eval.cost) {
            best = Some(r);
        }
    }
    let mut res = best.expect("at least one start");
    if stage1.iter().any(|f| !f) {
        let all = vec![true; prob.n_theta()];
        res = levenberg_marquardt(prob, res.theta, &all, options)?;
        iterations += res.iterations;
    }
    res.iterations = iterations;
    Ok(res)
}

/// The number of samples a fit on the first `fraction` of `n` samples uses.
pub fn train_samples(n: usize, fraction: f64) -> usize {
    if fraction >= 1.0 {
        n
    } else {
        ((n as f64 * fraction).round() as usize).clamp(1, n)
    }
}

impl GreyBoxConfig {
    /// The structure of output `o` of a record with `n_inputs` inputs.
    fn structure(
        &self,
        rec: &IoRecord,
        o: usize,
        creep_taus: &[f64],
    ) -> Result<OutputStructure, GreyBoxError> {
        let n_in = rec.inputs.len();
        let paths = if self.coupling {
            (0..n_in).collect()
        } else if n_in == 1 {
            vec![0]
        } else if o < n_in {
            vec![o]
        } else {
            return Err(GreyBoxError::NoDirectInput {
                path: rec.path.clone(),
                output: o + 1,
                name: rec.outputs[o].name.clone(),
                inputs: n_in,
                names: rec.input_names().join(", "),
            });
        };
        Ok(OutputStructure {
            paths,
            operator: self.hysteresis,
            creep_taus: creep_taus.to_vec(),
            dynamics: self.dynamics,
            viscous: self.viscous,
        })
    }

    /// Check that the record can support this model; returns the creep time constants.
    fn check_record(&self, rec: &IoRecord) -> Result<Vec<f64>, GreyBoxError> {
        let n = rec.len();
        let effects = self.effect_list();
        if rec.outputs.is_empty() {
            return Err(GreyBoxError::NoOutputs {
                path: rec.path.clone(),
            });
        }
        if self.coupling && rec.inputs.len() < 2 {
            return Err(GreyBoxError::CouplingNeedsInputs {
                path: rec.path.clone(),
                inputs: rec.inputs.len(),
                names: rec.input_names().join(", "),
            });
        }
        let per_path = match self.hysteresis {
            None => 1,
            Some(HysteresisOperator::PrandtlIshlinskii) => 1 + self.options.plays,
            Some(HysteresisOperator::Combined) => 4 + self.options.plays,
            Some(HysteresisOperator::BoucWen) => 4,
        };
        let paths = if self.coupling { rec.inputs.len() } else { 1 };
        let params = per_path * paths + 1 + if self.dynamics { 2 } else { 0 } + 6;
        let needed = (10 * params).max(100);
        if n < needed {
            return Err(GreyBoxError::TooShort {
                path: rec.path.clone(),
                samples: n,
                needed,
                effects,
                why: format!("about ten samples per parameter ({params} parameters)"),
            });
        }
        for s in &rec.outputs {
            if crate::metrics::ptp(&s.values) == 0.0 {
                return Err(GreyBoxError::ConstantOutput {
                    path: rec.path.clone(),
                    column: s.name.clone(),
                });
            }
        }
        for s in &rec.inputs {
            if crate::metrics::ptp(&s.values) == 0.0 {
                return Err(GreyBoxError::PoorlyExcited {
                    path: rec.path.clone(),
                    input: s.name.clone(),
                    effect: effects.clone(),
                    why: "the input is constant".into(),
                });
            }
            if self.hysteresis.is_some() {
                let rev = reversals(&s.values);
                if rev < 2 {
                    return Err(GreyBoxError::PoorlyExcited {
                        path: rec.path.clone(),
                        input: s.name.clone(),
                        effect: "hysteresis".into(),
                        why: format!("it reverses direction {rev} times; a hysteresis loop needs the input to go up and down (at least 2 reversals, better several amplitudes)"),
                    });
                }
            }
        }
        if !self.creep {
            return Ok(Vec::new());
        }
        let taus = creep_time_constants(n, rec.ts).map_err(|needed| GreyBoxError::TooShort {
            path: rec.path.clone(),
            samples: n,
            needed,
            effects: effects.clone(),
            why: format!(
                "creep needs time constants over at least two decades between 5 samples ({:.3e} s) and a third of the record ({:.3e} s); record longer holds",
                5.0 * rec.ts,
                n as f64 * rec.ts / 3.0
            ),
        })?;
        let tau_mid = (taus[0] * taus[taus.len() - 1]).sqrt();
        for s in &rec.inputs {
            let hold = longest_hold(&s.values) as f64 * rec.ts;
            let slow = slow_fraction(&s.values, rec.ts, tau_mid);
            if hold < tau_mid && slow < 0.01 {
                return Err(GreyBoxError::PoorlyExcited {
                    path: rec.path.clone(),
                    input: s.name.clone(),
                    effect: "creep".into(),
                    why: format!(
                        "creep needs holds (the input held for {tau_mid:.3} s or more) or slow content (below {:.3} Hz); the longest hold is {hold:.3} s and the slow content carries {:.2} % of the input variance",
                        1.0 / (2.0 * std::f64::consts::PI * tau_mid),
                        100.0 * slow
                    ),
                });
            }
        }
        Ok(taus)
    }

    /// Fit the model to a record (inputs and outputs as selected in `rec`). The first
    /// `options.train_fraction` of the record is fitted; scores are on the rest when it is < 1,
    /// else on the whole record.
    pub fn fit(&self, rec: &IoRecord) -> Result<FittedGreyBox, GreyBoxError> {
        let start = Instant::now();
        let f = self.options.train_fraction;
        if !(f > 0.0 && f <= 1.0) {
            return Err(GreyBoxError::TrainFraction { value: f });
        }
        let n = rec.len();
        let n_train = train_samples(n, f);
        let train = rec.slice(0..n_train);
        let taus = self.check_record(&train)?;
        let input_names = rec.input_names();
        let u: Vec<&[f64]> = train.inputs.iter().map(|s| s.values.as_slice()).collect();
        let mut outputs = Vec::new();
        let mut runs = Vec::new();
        for (o, out) in train.outputs.iter().enumerate() {
            let st = self.structure(&train, o, &taus)?;
            let t0 = Instant::now();
            let u = &u;
            let names = &input_names;
            let problem = |st: &OutputStructure, plays: usize| {
                OutputProblem::new(
                    &out.name,
                    &out.values,
                    u.clone(),
                    names.clone(),
                    train.ts,
                    st,
                    plays,
                )
            };
            let prob = problem(&st, self.options.plays);
            // the combined operator also starts from the Bouc-Wen-only fit, so that it is never
            // worse than `bouc-wen` (its own starts keep it never worse than PI)
            let mut extra = Vec::new();
            let mut iterations = 0;
            if st.operator == Some(HysteresisOperator::Combined) {
                let st_bw = OutputStructure {
                    operator: Some(HysteresisOperator::BoucWen),
                    ..st.clone()
                };
                let bw = problem(&st_bw, 0);
                let r = fit_problem(&bw, &problem(&st_bw, 0), Vec::new(), &self.options)?;
                iterations += r.iterations;
                extra.push(prob.theta_from_bouc_wen(&bw, &r.theta));
            }
            let res = fit_problem(
                &prob,
                &problem(&st, self.options.plays.min(3)),
                extra,
                &self.options,
            )?;
            let mut res = res;
            res.iterations += iterations;
            if std::env::var_os("HYSTBENCH_TRACE").is_some() {
                eprintln!(
                    "{}: {:.2} s ({} iterations)",
                    out.name,
                    t0.elapsed().as_secs_f64(),
                    res.iterations
                );
            }
            outputs.push(prob.output_spec(&res.theta, &res.eval.coef));
            runs.push(res);
        }
        let spec = PlantSpec {
            name: "greybox".into(),
            description: format!(
                "grey-box model ({}) fitted by hystbench fit to {}",
                self.effect_list(),
                rec.path.display()
            ),
            units: Units::default(),
            default_scenario: None,
            inputs: input_names,
            outputs,
            ode: None,
        };
        let plant = spec.check(&rec.path)?;
        let mut model = FittedGreyBox {
            effects: self.effects(),
            hysteresis_operator: self.hysteresis,
            plant,
            fit: FitSummary {
                rmse: 0.0,
                r2: None,
                outputs: Vec::new(),
                iterations: 0,
                converged: true,
                seconds: 0.0,
                data_file: rec.path.clone(),
                sampling_period_s: rec.ts,
                samples: n,
                train_samples: n_train,
                scored_on: String::new(),
            },
        };
        let train_scores = model.scores(rec, 0..n_train)?;
        let (range, scored_on) = if n_train < n {
            (
                n_train..n,
                format!("held-out samples {n_train}..{n} (fitted on the first {n_train})"),
            )
        } else {
            (0..n, "whole record (the samples fitted)".to_string())
        };
        let scores = model.scores(rec, range)?;
        let mut per = Vec::new();
        for ((run, s), ts) in runs.iter().zip(&scores).zip(&train_scores) {
            per.push(OutputFit {
                name: String::new(),
                rmse: s.rmse,
                r2: s.r2,
                nrmse: s.nrmse,
                max_error: s.max_error,
                train_rmse: ts.rmse,
                train_r2: ts.r2,
                iterations: run.iterations,
                converged: run.converged,
                message: run.message.clone(),
            });
        }
        for (p, name) in per.iter_mut().zip(model.plant.outputs.iter()) {
            p.name = name.clone();
        }
        for p in &per {
            if !p.rmse.is_finite() {
                return Err(GreyBoxError::NonFinite {
                    output: p.name.clone(),
                    what: "the simulated output".into(),
                });
            }
        }
        let k = per.len() as f64;
        let r2s: Vec<f64> = per.iter().filter_map(|p| p.r2).collect();
        model.fit.rmse = per.iter().map(|p| p.rmse).sum::<f64>() / k;
        model.fit.r2 = if r2s.is_empty() {
            None
        } else {
            Some(r2s.iter().sum::<f64>() / r2s.len() as f64)
        };
        model.fit.iterations = per.iter().map(|p| p.iterations).sum();
        model.fit.converged = per.iter().all(|p| p.converged);
        model.fit.outputs = per;
        model.fit.scored_on = scored_on;
        model.fit.seconds = start.elapsed().as_secs_f64();
        Ok(model)
    }
}
