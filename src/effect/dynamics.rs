//! # Linear dynamics
//!
//! A second-order mode, y'' + 2 zeta wn y' + wn^2 y = g wn^2 w, discretised exactly under a
//! zero-order hold on w: x(k+1) = Phi x(k) + Gamma w(k), y(k) = x_1(k) (one sample of transport
//! delay). Phi and Gamma come from the matrix exponential of the augmented system.
//!
//! ## References
//! - G. F. Franklin, J. D. Powell, M. Workman, *Digital Control of Dynamic Systems*, 3rd ed.,
//!   Addison-Wesley, 1998, ch. 4 (zero-order-hold equivalents).
//! - C. Moler, C. Van Loan, "Nineteen dubious ways to compute the exponential of a matrix,
//!   twenty-five years later", SIAM Review 45(1):3-49, 2003 (scaling and squaring).

use super::{non_negative, positive, EffectError, Operator};
use nalgebra::{Matrix2, Matrix3, Vector2};
use serde::{Deserialize, Serialize};

fn one() -> f64 {
    1.0
}

/// Second-order dynamics as written in a plant file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsSpec {
    /// Natural frequency f_n in Hz.
    pub natural_frequency_hz: f64,
    /// Damping ratio zeta >= 0.
    pub damping_ratio: f64,
    /// Static gain (default 1).
    #[serde(default = "one")]
    pub dc_gain: f64,
}

/// Valid second-order dynamics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dynamics {
    pub natural_frequency_hz: f64,
    pub damping_ratio: f64,
    pub dc_gain: f64,
}

impl DynamicsSpec {
    /// Check the parameters.
    pub fn check(&self) -> Result<Dynamics, EffectError> {
        positive("natural_frequency_hz", self.natural_frequency_hz)?;
        non_negative("damping_ratio", self.damping_ratio)?;
        super::finite("dc_gain", self.dc_gain)?;
        Ok(Dynamics {
            natural_frequency_hz: self.natural_frequency_hz,
            damping_ratio: self.damping_ratio,
            dc_gain: self.dc_gain,
        })
    }
}

/// exp(M) by scaling and squaring with a Taylor series (accurate to rounding for small M).
pub fn expm3(m: &Matrix3<f64>) -> Matrix3<f64> {
    let norm = m.abs().row_sum().max();
    let s = if norm > 0.5 {
        (norm / 0.5).log2().ceil() as i32
    } else {
        0
    };
    let a = m / 2f64.powi(s);
    let mut term = Matrix3::identity();
    let mut sum = Matrix3::identity();
    for k in 1..=20 {
        term = term * a / k as f64;
        sum += term;
    }
    for _ in 0..s {
        sum = sum * sum;
    }
    sum
}

impl Dynamics {
    /// The zero-order-hold equivalent (Phi, Gamma) for sampling period `ts`.
    pub fn discretise(&self, ts: f64) -> Result<(Matrix2<f64>, Vector2<f64>), EffectError> {
        let wn = 2.0 * std::f64::consts::PI * self.natural_frequency_hz;
        if wn * ts >= std::f64::consts::PI {
            return Err(EffectError::Invalid {
                field: "natural_frequency_hz".into(),
                value: self.natural_frequency_hz,
                rule: format!(
                    "is at or above the Nyquist frequency {} Hz of the sampling period {ts} s; sample faster",
                    0.5 / ts
                ),
            });
        }
        let z = self.damping_ratio;
        let mut m = Matrix3::zeros();
        m[(0, 1)] = 1.0;
        m[(1, 0)] = -wn * wn;
        m[(1, 1)] = -2.0 * z * wn;
        m[(1, 2)] = self.dc_gain * wn * wn;
        let e = expm3(&(m * ts));
        Ok((
            Matrix2::new(e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]),
            Vector2::new(e[(0, 2)], e[(1, 2)]),
        ))
    }

    /// The operator for sampling period `ts`, at rest.
    pub fn operator(&self, ts: f64) -> Result<DynamicsOp, EffectError> {
        let (phi, gamma) = self.discretise(ts)?;
        Ok(DynamicsOp {
            phi,
            gamma,
            x: Vector2::zeros(),
        })
    }

    /// Closed-form unit-step response at time t (continuous time, from rest, 0 <= zeta < 1).
    pub fn step_response(&self, t: f64) -> f64 {
        let wn = 2.0 * std::f64::consts::PI * self.natural_frequency_hz;
        let z = self.damping_ratio;
        if z < 1.0 {
            let wd = wn * (1.0 - z * z).sqrt();
            let e = (-z * wn * t).exp();
            self.dc_gain * (1.0 - e * ((wd * t).cos() + z * wn / wd * (wd * t).sin()))
        } else if z == 1.0 {
            self.dc_gain * (1.0 - (1.0 + wn * t) * (-wn * t).exp())
        } else {
            let r = (z * z - 1.0).sqrt();
            let (p1, p2) = (-wn * (z - r), -wn * (z + r));
            self.dc_gain * (1.0 + (p2 * (p1 * t).exp() - p1 * (p2 * t).exp()) / (p1 - p2))
        }
    }
}

/// A running second-order filter.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicsOp {
    phi: Matrix2<f64>,
    gamma: Vector2<f64>,
    x: Vector2<f64>,
}

impl Operator for DynamicsOp {
    fn reset(&mut self) {
        self.x = Vector2::zeros();
    }

    #[inline]
    fn step(&mut self, w: f64) -> f64 {
        let y = self.x[0];
        self.x = self.phi * self.x + self.gamma * w;
        y
    }
}

/// Basis bank: the model's prediction passed through lightly damped second-order resonators
/// (natural frequencies log-spaced by 1.3 from max(1 Hz, 50 / record span) to 0.35 / Ts,
/// damping 0.1; each with its one-sample delay, which spans the filter's two states), and a few
/// short delays of the prediction (first-order lags, delays): a missing mode or lag acting on
/// the prediction is a combination of them.
pub fn basis(ctx: &super::basis::BasisContext) -> super::basis::BasisBank {
    let mut bank = super::basis::BasisBank::new(super::EffectName::Dynamics);
    let y = ctx.prediction;
    let n = y.len();
    for lag in [1usize, 2, 3, 5] {
        if lag >= n {
            break;
        }
        bank.push(
            format!("prediction(k-{lag})"),
            (0..n).map(|k| y[k.saturating_sub(lag)]).collect(),
        );
    }
    let span = n as f64 * ctx.ts;
    let mut f = (50.0 / span).max(1.0);
    let f_max = 0.35 / ctx.ts;
    // start the filters at the first value so that a non-zero start does not ring
    let y0 = y.first().copied().unwrap_or(0.0);
    let shifted: Vec<f64> = y.iter().map(|v| v - y0).collect();
    while f <= f_max {
        let d = Dynamics {
            natural_frequency_hz: f,
            damping_ratio: 0.1,
            dc_gain: 1.0,
        };
        if let Ok(mut op) = d.operator(ctx.ts) {
            let x = op.apply(&shifted);
            let x1: Vec<f64> = (0..n).map(|k| x[k.saturating_sub(1)]).collect();
            bank.push(format!("resonator({f:.2} Hz)"), x);
            bank.push(format!("resonator({f:.2} Hz)(k-1)"), x1);
        }
        f *= 1.3;
    }
    bank
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_response_matches_closed_form() {
        for zeta in [0.03, 0.7, 1.0, 2.0] {
            let d = DynamicsSpec {
                natural_frequency_hz: 40.0,
                damping_ratio: zeta,
                dc_gain: 1.0,
            }
            .check()
            .unwrap();
            let ts = 1e-3;
            let y = d.operator(ts).unwrap().apply(&[1.0; 400]);
            for (k, yk) in y.iter().enumerate() {
                let exact = d.step_response(k as f64 * ts);
                assert!(
                    (yk - exact).abs() < 1e-12,
                    "zeta {zeta} k {k}: {yk} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn above_nyquist_is_refused() {
        let d = DynamicsSpec {
            natural_frequency_hz: 800.0,
            damping_ratio: 0.03,
            dc_gain: 1.0,
        }
        .check()
        .unwrap();
        assert!(d
            .operator(1e-3)
            .unwrap_err()
            .to_string()
            .contains("Nyquist"));
    }

    #[test]
    fn negative_damping_rejected() {
        let s = DynamicsSpec {
            natural_frequency_hz: 10.0,
            damping_ratio: -0.1,
            dc_gain: 1.0,
        };
        assert!(s.check().unwrap_err().to_string().contains("damping_ratio"));
    }
}
