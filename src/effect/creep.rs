//! # Creep
//!
//! Linear creep as a chain of Kelvin-Voigt elements acting on the hysteresis output w:
//! w_c = (1 + sum_i g_i / (tau_i s + 1)) w. Each element is discretised exactly under a
//! zero-order hold: z_i(k+1) = a_i z_i(k) + (1 - a_i) w(k), a_i = exp(-Ts / tau_i), and
//! w_c(k) = w(k) + sum_i g_i z_i(k).
//!
//! With one time constant per decade and g_i = gamma, the step response follows the logarithmic
//! law w_c(t) ~ w [1 + gamma log10(t / t0)] over the covered decades ([`CreepSpec::from_log_rate`]).
//!
//! ## References
//! - D. Croft, G. Shedd, S. Devasia, ASME JDSMC 123(1):35-43, 2001.
//! - M. Rakotondrabe, C. Clevy, P. Lutz, IEEE T-ASE 7(3):440-450, 2010.
//! - Physik Instrumente, "Piezo tutorial: creep" (1-2 % per decade).

use super::{finite, positive, EffectError, Operator};
use serde::{Deserialize, Serialize};

/// Creep parameters as written in a plant file: the time constants and either the gains or a
/// logarithmic creep rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CreepSpec {
    /// tau_i in seconds, strictly increasing.
    pub time_constants_s: Vec<f64>,
    /// g_i (dimensionless), one per time constant.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gains: Option<Vec<f64>>,
    /// Creep rate in percent of the step per decade of time; sets the gains.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub percent_per_decade: Option<f64>,
}

/// Valid creep parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Creep {
    pub time_constants_s: Vec<f64>,
    pub gains: Vec<f64>,
}

impl CreepSpec {
    /// Gains from a logarithmic creep rate: g_i = gamma * log10 of the local ratio of time constants.
    pub fn from_log_rate(percent_per_decade: f64, time_constants_s: Vec<f64>) -> CreepSpec {
        CreepSpec {
            time_constants_s,
            gains: None,
            percent_per_decade: Some(percent_per_decade),
        }
    }

    /// Check the parameters.
    pub fn check(&self) -> Result<Creep, EffectError> {
        let taus = &self.time_constants_s;
        if taus.is_empty() {
            return Err(EffectError::Shape {
                field: "time_constants_s".into(),
                rule: "needs at least one time constant".into(),
            });
        }
        for (i, &t) in taus.iter().enumerate() {
            positive(&format!("time_constants_s[{i}]"), t)?;
            if i > 0 && t <= taus[i - 1] {
                return Err(EffectError::Invalid {
                    field: format!("time_constants_s[{i}]"),
                    value: t,
                    rule: "time constants must be strictly increasing".into(),
                });
            }
        }
        let gains = match (&self.gains, self.percent_per_decade) {
            (Some(g), None) => {
                if g.len() != taus.len() {
                    return Err(EffectError::Shape {
                        field: "gains".into(),
                        rule: format!(
                            "has {} entries but there are {} time constants",
                            g.len(),
                            taus.len()
                        ),
                    });
                }
                for (i, &v) in g.iter().enumerate() {
                    finite(&format!("gains[{i}]"), v)?;
                }
                g.clone()
            }
            (None, Some(rate)) => {
                finite("percent_per_decade", rate)?;
                log_rate_gains(rate / 100.0, taus)
            }
            _ => {
                return Err(EffectError::Shape {
                    field: "gains".into(),
                    rule: "give exactly one of `gains` and `percent_per_decade`".into(),
                })
            }
        };
        Ok(Creep {
            time_constants_s: taus.clone(),
            gains,
        })
    }
}

/// Gains that give `gamma` per decade for the given (log-spaced) time constants.
pub fn log_rate_gains(gamma: f64, taus: &[f64]) -> Vec<f64> {
    let n = taus.len();
    (0..n)
        .map(|i| {
            let span = if n == 1 {
                1.0
            } else if i == 0 {
                (taus[1] / taus[0]).log10()
            } else if i == n - 1 {
                (taus[n - 1] / taus[n - 2]).log10()
            } else {
                0.5 * (taus[i + 1] / taus[i - 1]).log10()
            };
            gamma * span
        })
        .collect()
}

impl Creep {
    /// The operator for sampling period `ts`, at rest.
    pub fn operator(&self, ts: f64) -> CreepOp {
        CreepOp {
            a: self
                .time_constants_s
                .iter()
                .map(|t| (-ts / t).exp())
                .collect(),
            g: self.gains.clone(),
            z: vec![0.0; self.gains.len()],
        }
    }

    /// Closed-form response at time t after a unit step applied at t = 0 (continuous time).
    pub fn step_response(&self, t: f64) -> f64 {
        1.0 + self
            .gains
            .iter()
            .zip(&self.time_constants_s)
            .map(|(g, tau)| g * (1.0 - (-t / tau).exp()))
            .sum::<f64>()
    }
}

/// A running creep chain.
#[derive(Debug, Clone, PartialEq)]
pub struct CreepOp {
    a: Vec<f64>,
    g: Vec<f64>,
    z: Vec<f64>,
}

impl Operator for CreepOp {
    fn reset(&mut self) {
        self.z.fill(0.0);
    }

    #[inline]
    fn step(&mut self, w: f64) -> f64 {
        let mut out = w;
        for ((z, &a), &g) in self.z.iter_mut().zip(&self.a).zip(&self.g) {
            out += g * *z;
            *z = a * *z + (1.0 - a) * w;
        }
        out
    }
}

/// One Kelvin-Voigt state (a first-order lag of time constant `tau`, exact under a zero-order
/// hold, starting at the first sample's value).
pub fn kelvin_voigt_state(x: &[f64], tau: f64, ts: f64) -> Vec<f64> {
    let a = (-ts / tau).exp();
    let mut z = x.first().copied().unwrap_or(0.0);
    x.iter()
        .map(|&v| {
            let out = z;
            z = a * z + (1.0 - a) * v;
            out
        })
        .collect()
}

/// Basis bank: slow first-order states of the model's prediction, time constants one per half
/// decade from 20 samples (at least 0.05 s) up to a third of the record.
pub fn basis(ctx: &super::basis::BasisContext) -> super::basis::BasisBank {
    let mut bank = super::basis::BasisBank::new(super::EffectName::Creep);
    let span = ctx.len() as f64 * ctx.ts;
    let mut tau = (20.0 * ctx.ts).max(0.05);
    while tau <= span / 3.0 {
        bank.push(
            format!("creep state(tau={tau:.3} s)"),
            kelvin_voigt_state(ctx.prediction, tau, ctx.ts),
        );
        tau *= 10f64.sqrt();
    }
    bank
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_rate_gives_gamma_per_decade() {
        let c = CreepSpec::from_log_rate(2.0, vec![0.1, 1.0, 10.0, 100.0, 1000.0])
            .check()
            .unwrap();
        assert!(c.gains.iter().all(|g| (g - 0.02).abs() < 1e-12));
        // slope per decade in the middle of the covered span
        let s = c.step_response(10.0) - c.step_response(1.0);
        assert!((s - 0.02).abs() < 0.004, "per decade {s}");
    }

    #[test]
    fn needs_exactly_one_of_gains_and_rate() {
        let s = CreepSpec {
            time_constants_s: vec![1.0],
            gains: Some(vec![0.1]),
            percent_per_decade: Some(1.0),
        };
        assert!(s.check().unwrap_err().to_string().contains("exactly one"));
    }

    #[test]
    fn negative_time_constant_rejected() {
        let s = CreepSpec {
            time_constants_s: vec![-1.0],
            gains: Some(vec![0.1]),
            percent_per_decade: None,
        };
        assert!(s
            .check()
            .unwrap_err()
            .to_string()
            .contains("time_constants_s[0]"));
    }
}
