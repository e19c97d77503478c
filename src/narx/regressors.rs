//! # NARX regressors
//!
//! The regressor of sample k for one output y and exogenous signals u_1..u_m:
//! x(k) = [y(k-1), ..., y(k-n_y), u_1(k-d), ..., u_1(k-d-n_u+1), ..., u_m(k-d), ..., u_m(k-d-n_u+1)],
//! with output lags n_y, input lags n_u and input delay d (the source study: n_y = n_u = n, d = 1).
//! Any extra exogenous signal (a feature computed from the inputs, e.g. play operators or creep
//! filter states of the effect library) is simply one more u_j.
//! Signals are standardised with the training part's mean and standard deviation.
//!
//! ## References
//! - I. J. Leontaritis, S. A. Billings, "Input-output parametric models for non-linear systems",
//!   Int. J. Control 41(2):303-344, 1985.

use serde::{Deserialize, Serialize};

/// Lags and delay of a NARX regressor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Lags {
    /// n_y: past outputs y(k-1..k-n_y).
    pub output: usize,
    /// n_u: past values of each exogenous signal.
    pub input: usize,
    /// d: the newest input value used is u(k-d) (d = 1: strictly causal, as in the study).
    pub delay: usize,
}

impl Lags {
    /// The first sample that has a full regressor; samples before it seed the free run.
    pub fn start(&self) -> usize {
        self.output.max(self.input + self.delay - 1)
    }

    /// Regressor width for `n_signals` exogenous signals.
    pub fn width(&self, n_signals: usize) -> usize {
        self.output + self.input * n_signals
    }

    /// Write the exogenous part of the regressor of sample k (after the output lags).
    #[inline]
    pub fn fill_inputs(&self, u: &[Vec<f64>], k: usize, x: &mut [f64]) {
        let mut i = self.output;
        for s in u {
            for j in 0..self.input {
                x[i] = s[k - self.delay - j];
                i += 1;
            }
        }
    }

    /// Write the output lags of sample k from `y` (measured or simulated).
    #[inline]
    pub fn fill_outputs(&self, y: &[f64], k: usize, x: &mut [f64]) {
        for j in 0..self.output {
            x[j] = y[k - 1 - j];
        }
    }
}

/// Mean and standard deviation of one signal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Standardiser {
    pub mean: f64,
    pub std: f64,
}

impl Standardiser {
    /// From the training values; a constant signal gets std 1 (it is only centred).
    pub fn fit(x: &[f64]) -> Standardiser {
        let mean = crate::metrics::mean(x);
        let sd = crate::metrics::std_dev(x);
        Standardiser {
            mean,
            std: if sd > 0.0 && sd.is_finite() { sd } else { 1.0 },
        }
    }

    /// Standardise a signal.
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        x.iter().map(|&v| self.apply_one(v)).collect()
    }

    /// Standardise one value.
    #[inline]
    pub fn apply_one(&self, v: f64) -> f64 {
        (v - self.mean) / self.std
    }

    /// Back to physical units.
    #[inline]
    pub fn invert(&self, z: f64) -> f64 {
        z * self.std + self.mean
    }
}

/// One output and its exogenous signals, standardised, ready for regressors.
#[derive(Debug, Clone)]
pub struct Series {
    pub y: Vec<f64>,
    pub u: Vec<Vec<f64>>,
}

impl Series {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.y.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }

    /// Samples `range` as a series of their own.
    pub fn slice(&self, range: std::ops::Range<usize>) -> Series {
        Series {
            y: self.y[range.clone()].to_vec(),
            u: self.u.iter().map(|s| s[range.clone()].to_vec()).collect(),
        }
    }

    /// Row-major regressor matrix (rows k = start..len) and the targets y(k).
    pub fn regressor_matrix(&self, lags: &Lags) -> (Vec<f64>, Vec<f64>) {
        let p = lags.width(self.u.len());
        let s = lags.start();
        let n = self.len().saturating_sub(s);
        let mut x = vec![0.0; n * p];
        for (r, row) in x.chunks_exact_mut(p).enumerate() {
            let k = s + r;
            lags.fill_outputs(&self.y, k, row);
            lags.fill_inputs(&self.u, k, row);
        }
        (x, self.y[s..].to_vec())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regressor_layout_follows_the_definition() {
        let lags = Lags {
            output: 2,
            input: 3,
            delay: 1,
        };
        assert_eq!(lags.start(), 3);
        let s = Series {
            y: (0..6).map(|k| k as f64).collect(),
            u: vec![
                (0..6).map(|k| 10.0 + k as f64).collect(),
                (0..6).map(|k| 20.0 + k as f64).collect(),
            ],
        };
        let (x, t) = s.regressor_matrix(&lags);
        assert_eq!(t, vec![3.0, 4.0, 5.0]);
        assert_eq!(&x[..8], &[2.0, 1.0, 12.0, 11.0, 10.0, 22.0, 21.0, 20.0]);
        let lags0 = Lags {
            output: 1,
            input: 2,
            delay: 0,
        };
        assert_eq!(lags0.start(), 1);
        let (x, _) = s.regressor_matrix(&lags0);
        assert_eq!(&x[..5], &[0.0, 11.0, 10.0, 21.0, 20.0]);
    }
}

/// How the lags enter the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RegressorForm {
    /// The lags themselves, target y(k) (the source study).
    Lagged,
    /// Incremental (velocity) form of the same lags: the newest value and the successive
    /// differences, each difference block scaled to unit standard deviation; target the
    /// scaled increment y(k) - y(k-1). A linear, invertible change of coordinates of the same
    /// NARX model that makes the direction of motion (what hysteresis depends on) visible to the
    /// network at unit scale instead of 1e-3 of the signal's range.
    Incremental,
}

/// A regressor: lags, form and the scaling of the differences.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Regressor {
    pub lags: Lags,
    pub form: RegressorForm,
    /// 1 / std of y(k) - y(k-1) (standardised units), incremental form.
    pub dy_gain: f64,
    /// 1 / std of u_j(k) - u_j(k-1) per exogenous signal, incremental form.
    pub du_gain: Vec<f64>,
}

fn diff_gain(x: &[f64]) -> f64 {
    let d: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    inverse_std(&d)
}

/// 1 / the population standard deviation of `d` (1 when it is zero or not finite).
pub(crate) fn inverse_std(d: &[f64]) -> f64 {
    let m = crate::metrics::mean(d);
    let sd = (d.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / d.len().max(1) as f64).sqrt();
    if sd > 0.0 && sd.is_finite() {
        1.0 / sd
    } else {
        1.0
    }
}

impl Regressor {
    /// A regressor whose difference scaling comes from the training series.
    pub fn fit(lags: Lags, form: RegressorForm, s: &Series) -> Regressor {
        let (dy_gain, du_gain) = match form {
            RegressorForm::Lagged => (1.0, vec![1.0; s.u.len()]),
            RegressorForm::Incremental => {
                (diff_gain(&s.y), s.u.iter().map(|u| diff_gain(u)).collect())
            }
        };
        Regressor {
            lags,
            form,
            dy_gain,
            du_gain,
        }
    }

    /// Regressor width.
    pub fn width(&self) -> usize {
        self.lags.width(self.du_gain.len())
    }

    /// Output-lag part of the regressor of sample k.
    #[inline]
    pub fn fill_outputs(&self, y: &[f64], k: usize, x: &mut [f64]) {
        match self.form {
            RegressorForm::Lagged => self.lags.fill_outputs(y, k, x),
            RegressorForm::Incremental => {
                x[0] = y[k - 1];
                for j in 1..self.lags.output {
                    x[j] = (y[k - j] - y[k - j - 1]) * self.dy_gain;
                }
            }
        }
    }

    /// Exogenous part of the regressor of sample k.
    #[inline]
    pub fn fill_inputs(&self, u: &[Vec<f64>], k: usize, x: &mut [f64]) {
        match self.form {
            RegressorForm::Lagged => self.lags.fill_inputs(u, k, x),
            RegressorForm::Incremental => {
                let (nu, d) = (self.lags.input, self.lags.delay);
                let mut i = self.lags.output;
                for (s, g) in u.iter().zip(&self.du_gain) {
                    x[i] = s[k - d];
                    for j in 1..nu {
                        x[i + j] = (s[k - d - j + 1] - s[k - d - j]) * g;
                    }
                    i += nu;
                }
            }
        }
    }

    /// y(k) = base(k) + scale * network output.
    #[inline]
    pub fn base(&self, y: &[f64], k: usize) -> f64 {
        match self.form {
            RegressorForm::Lagged => 0.0,
            RegressorForm::Incremental => y[k - 1],
        }
    }

    /// Scale of the network output.
    #[inline]
    pub fn scale(&self) -> f64 {
        match self.form {
            RegressorForm::Lagged => 1.0,
            RegressorForm::Incremental => 1.0 / self.dy_gain,
        }
    }

    /// Gradients with respect to y(k-1-j), j = 0..n_y, given the gradient `gz` with respect to
    /// y(k) and `gx` with respect to the regressor (network input) of sample k.
    #[inline]
    pub fn output_lag_gradient(&self, gz: f64, gx: &[f64], g_lag: &mut [f64]) {
        let ny = self.lags.output;
        match self.form {
            RegressorForm::Lagged => g_lag[..ny].copy_from_slice(&gx[..ny]),
            RegressorForm::Incremental => {
                g_lag[..ny].iter_mut().for_each(|v| *v = 0.0);
                g_lag[0] = gz + gx[0];
                for j in 1..ny {
                    let g = gx[j] * self.dy_gain;
                    g_lag[j - 1] += g;
                    g_lag[j] -= g;
                }
            }
        }
    }

    /// Row-major regressor matrix (rows k = start..len) and network targets.
    pub fn regressor_matrix(&self, s: &Series) -> (Vec<f64>, Vec<f64>) {
        let p = self.width();
        let st = self.lags.start();
        let n = s.len().saturating_sub(st);
        let mut x = vec![0.0; n * p];
        let mut t = Vec::with_capacity(n);
        let sc = self.scale();
        for (r, row) in x.chunks_exact_mut(p).enumerate() {
            let k = st + r;
            self.fill_outputs(&s.y, k, row);
            self.fill_inputs(&s.u, k, row);
            t.push((s.y[k] - self.base(&s.y, k)) / sc);
        }
        (x, t)
    }
}
