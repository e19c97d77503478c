//! # A linear ARX model: the baseline every identifier must beat
//!
//! Per output, y(k) = c + sum_i a_i y(k - i) + sum_j sum_i b_ji u_j(k - d - i + 1) with the same
//! [`Lags`] as the NARX model (its own past outputs and every input), fitted by least squares
//! on the training record's one-step errors (columns scaled; a tiny ridge). Its free run starts
//! from the record's first measured outputs and is declared diverged when it leaves the
//! training range widened by [`DIVERGENCE_RANGES`] ranges on each side, as the NARX model's is.
//!
//! ## References
//! - L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall, 1999, ch. 4.

use super::model::DIVERGENCE_RANGES;
use super::{Lags, NarxError};
use crate::data::IoRecord;
use crate::metrics::{scores, Scores};
use crate::numeric::lstsq::{solve_scaled, NormalEquations};

/// A fitted ARX model: one linear equation per output.
#[derive(Debug, Clone, PartialEq)]
pub struct Arx {
    pub lags: Lags,
    pub outputs: Vec<ArxOutput>,
}

/// One output's equation: the intercept, then the output lags, then each input's lags.
#[derive(Debug, Clone, PartialEq)]
pub struct ArxOutput {
    pub name: String,
    pub coef: Vec<f64>,
    /// The training range (for the divergence test).
    pub train_min: f64,
    pub train_max: f64,
}

/// The regressor row of output `y` at sample `k`: 1, y(k-1..k-na), u_j(k-d..k-d-nb+1).
fn row(lags: Lags, y: &[f64], u: &[&[f64]], k: usize, out: &mut Vec<f64>) {
    out.clear();
    out.push(1.0);
    out.extend((1..=lags.output).map(|i| y[k - i]));
    for uj in u {
        out.extend((0..lags.input).map(|i| uj[k - lags.delay - i]));
    }
}

/// Fits an ARX model on `train` with `lags` (delay at least 1).
pub fn fit_arx(train: &IoRecord, lags: Lags) -> Result<Arx, NarxError> {
    let start = lags.start();
    if lags.delay == 0 || train.len() < start + 2 {
        return Err(NarxError::TooShort {
            path: train.path.clone(),
            rows: train.len(),
            needed: start + 2,
            why: "the ARX lags (delay at least 1) need their initial samples, plus at least 2"
                .into(),
        });
    }
    let u: Vec<&[f64]> = train.inputs.iter().map(|s| &s.values[..]).collect();
    let p = 1 + lags.width(u.len());
    let mut outputs = Vec::new();
    for o in &train.outputs {
        let y = &o.values;
        let mut ne = NormalEquations::new(p);
        let mut r = Vec::with_capacity(p);
        for k in start..y.len() {
            row(lags, y, &u, k, &mut r);
            ne.add_row(&r, y[k]);
        }
        let (g, b) = ne.into_parts();
        let coef = solve_scaled(&g, &b, 1e-10)
            .filter(|c| c.iter().all(|v| v.is_finite()))
            .map(|c| c.iter().copied().collect())
            .ok_or_else(|| NarxError::Singular {
                path: train.path.clone(),
                output: o.name.clone(),
            })?;
        outputs.push(ArxOutput {
            name: o.name.clone(),
            coef,
            train_min: y.iter().copied().fold(f64::INFINITY, f64::min),
            train_max: y.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        });
    }
    Ok(Arx { lags, outputs })
}

/// A free run of one output: the prediction (the first `start` samples measured) and the
/// first sample where it diverged.
#[derive(Debug, Clone, PartialEq)]
pub struct ArxFreeRun {
    pub values: Vec<f64>,
    pub start: usize,
    pub diverged_at: Option<usize>,
}

impl ArxFreeRun {
    /// Scores against the measured signal over `start..`; `None` when diverged.
    pub fn scores(&self, measured: &[f64]) -> Option<Scores> {
        if self.diverged_at.is_some() || self.values.len() != measured.len() {
            return None;
        }
        Some(scores(&measured[self.start..], &self.values[self.start..]))
    }
}

impl Arx {
    /// The free run of every output on `rec` (its inputs, and its first measured outputs).
    pub fn free_run(&self, rec: &IoRecord) -> Vec<ArxFreeRun> {
        let u: Vec<&[f64]> = rec.inputs.iter().map(|s| &s.values[..]).collect();
        let start = self.lags.start().min(rec.len());
        let mut r = Vec::new();
        self.outputs
            .iter()
            .zip(&rec.outputs)
            .map(|(o, measured)| {
                let range = (o.train_max - o.train_min).max(f64::MIN_POSITIVE);
                let lo = o.train_min - DIVERGENCE_RANGES * range;
                let hi = o.train_max + DIVERGENCE_RANGES * range;
                let mut y = measured.values[..start].to_vec();
                let mut diverged_at = None;
                for k in start..rec.len() {
                    row(self.lags, &y, &u, k, &mut r);
                    let v: f64 = r.iter().zip(&o.coef).map(|(a, b)| a * b).sum();
                    if !(v.is_finite() && (lo..=hi).contains(&v)) {
                        diverged_at = Some(k);
                        break;
                    }
                    y.push(v);
                }
                ArxFreeRun {
                    values: y,
                    start,
                    diverged_at,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(n: usize, seed: u64) -> IoRecord {
        let mut g = crate::effect::noise::Gaussian::new(seed, 0);
        let u: Vec<f64> = (0..n).map(|_| g.standard_normal()).collect();
        let mut y = vec![0.0; n];
        for k in 2..n {
            y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2] + 0.5 * u[k - 1] + 0.2 * u[k - 2] + 0.1;
        }
        IoRecord::siso("arx.csv", 0.01, u, y)
    }

    #[test]
    fn recovers_a_linear_system_and_runs_it_free() {
        let lags = Lags {
            output: 2,
            input: 2,
            delay: 1,
        };
        let m = fit_arx(&record(400, 1), lags).unwrap();
        let want = [0.1, 1.5, -0.7, 0.5, 0.2];
        for (c, w) in m.outputs[0].coef.iter().zip(want) {
            assert!((c - w).abs() < 1e-8, "{:?}", m.outputs[0].coef);
        }
        let test = record(300, 2);
        let run = &m.free_run(&test)[0];
        let s = run.scores(&test.outputs[0].values).unwrap();
        assert!(s.r2.unwrap() > 0.999_999, "{s:?}");
    }

    #[test]
    fn an_unstable_free_run_is_reported_as_diverged() {
        let lags = Lags {
            output: 1,
            input: 1,
            delay: 1,
        };
        let mut m = fit_arx(&record(200, 3), lags).unwrap();
        m.outputs[0].coef = vec![0.0, 1.5, 1.0];
        let run = &m.free_run(&record(200, 4))[0];
        assert!(run.diverged_at.is_some());
        assert!(run.scores(&record(200, 4).outputs[0].values).is_none());
    }
}
