//! # Bouc-Wen hysteresis
//!
//! Rakotondrabe's piezo form: y = d u - h, dh/dt = A du/dt - B |du/dt| |h|^(n-1) h - Gamma du/dt |h|^n.
//! With n = 1 the map u -> h is rate independent and, for an input linear between samples, has an
//! exact per-sample solution: with v = |du| and s = sgn(du), dh/dv = s A - k h where
//! k = B + s Gamma sgn(h), so h = h_inf + (h0 - h_inf) e^(-k v) with h_inf = s A / k; the step is
//! split where h crosses 0. This update is unconditionally stable. For n != 1 the same equation in
//! v is integrated by RK4 with sub-steps sized by the state's local rate (`bouc_wen_general`).
//!
//! Bounded and with a physical loop when A > 0, B + Gamma > 0 and B >= |Gamma|; then, with
//! h(0) = 0 and n = 1, |h| <= A / (B + Gamma).
//!
//! A negative A is a path of negative gain (a reversed polarity, a cross path that bends the
//! other way): h/A is unchanged when A changes sign with Gamma, so h(A, B, Gamma) =
//! -h(|A|, B, -Gamma), and the plant d u - h with d, A and Gamma negated is the negated plant.
//! Its conditions are those of the mirror: B >= |Gamma| and B - Gamma > 0, |h| <= |A| / (B - Gamma).
//!
//! ## References
//! - M. Rakotondrabe, IEEE T-ASE 8(2):428-431, 2011.
//! - C.-J. Lin, S.-R. Yang; F. Ikhouane, V. Manosa, J. Rodellar, "Dynamic properties of the
//!   hysteretic Bouc-Wen model", Syst. Control Lett. 56:197-205, 2007.
//! - M. Ismail, F. Ikhouane, J. Rodellar, "The hysteresis Bouc-Wen model, a survey",
//!   Arch. Comput. Methods Eng. 16:161-188, 2009.

use super::{finite, EffectError, Operator};
use serde::{Deserialize, Serialize};

fn one() -> f64 {
    1.0
}

/// Bouc-Wen parameters as written in a plant file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoucWenSpec {
    /// d_p: linear gain (output units per input unit).
    pub d: f64,
    /// A (output units per input unit).
    #[serde(rename = "A")]
    pub a: f64,
    /// B (1 / input unit).
    #[serde(rename = "B")]
    pub b: f64,
    /// Gamma (1 / input unit).
    #[serde(rename = "Gamma")]
    pub gamma: f64,
    /// Exponent n (default 1).
    #[serde(default = "one")]
    pub n: f64,
    /// h(0) (default 0).
    #[serde(default)]
    pub initial_h: f64,
}

/// Valid Bouc-Wen parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoucWen {
    pub d: f64,
    pub a: f64,
    pub b: f64,
    pub gamma: f64,
    pub n: f64,
    pub initial_h: f64,
}

impl BoucWenSpec {
    /// The unit loop of a Bouc-Wen state with shape B, Gamma: A = 1, no linear part, n = 1,
    /// from rest (h scales with A, so a fit takes A as a linear coefficient).
    pub fn unit(b: f64, gamma: f64) -> BoucWenSpec {
        BoucWenSpec {
            d: 0.0,
            a: 1.0,
            b,
            gamma,
            n: 1.0,
            initial_h: 0.0,
        }
    }

    /// Check the stability and boundedness conditions.
    pub fn check(&self) -> Result<BoucWen, EffectError> {
        finite("d", self.d)?;
        finite("A", self.a)?;
        if self.a == 0.0 {
            return Err(EffectError::Invalid {
                field: "A".into(),
                value: self.a,
                rule: "must not be 0 (no loop: write a linear path); a negative A is a path of \
                       negative gain"
                    .into(),
            });
        }
        finite("B", self.b)?;
        finite("Gamma", self.gamma)?;
        finite("initial_h", self.initial_h)?;
        if self.b < self.gamma.abs() {
            return Err(EffectError::Invalid {
                field: "B".into(),
                value: self.b,
                rule: format!(
                    "must be >= |Gamma| = {} for a bounded, physical loop (Ikhouane et al. 2007)",
                    self.gamma.abs()
                ),
            });
        }
        if self.b + self.a.signum() * self.gamma <= 0.0 {
            return Err(EffectError::Invalid {
                field: "B".into(),
                value: self.b,
                rule: if self.a > 0.0 {
                    format!("B + Gamma must be > 0 (Gamma = {})", self.gamma)
                } else {
                    format!(
                        "B - Gamma must be > 0 with a negative A (the mirrored loop; Gamma = {})",
                        self.gamma
                    )
                },
            });
        }
        if !(self.n.is_finite() && self.n >= 1.0) {
            return Err(EffectError::Invalid {
                field: "n".into(),
                value: self.n,
                rule: "the exponent must be a finite number >= 1".into(),
            });
        }
        Ok(BoucWen {
            d: self.d,
            a: self.a,
            b: self.b,
            gamma: self.gamma,
            n: self.n,
            initial_h: self.initial_h,
        })
    }
}

impl BoucWen {
    /// The bound |A| / (B + sgn(A) Gamma) on |h| (n = 1, h(0) = 0).
    pub fn h_bound(&self) -> f64 {
        self.a.abs() / (self.b + self.a.signum() * self.gamma)
    }

    /// The loop of positive A that this one mirrors (itself when A > 0): A, Gamma and
    /// initial_h times sgn(A).
    fn mirror(&self) -> BoucWen {
        let s = self.a.signum();
        BoucWen {
            a: s * self.a,
            gamma: s * self.gamma,
            initial_h: s * self.initial_h,
            ..*self
        }
    }

    /// The operator at rest: input 0 and h = initial_h (the first sample is reached along a
    /// straight path from 0).
    pub fn operator(&self) -> BoucWenOp {
        let p = self.mirror();
        BoucWenOp {
            p,
            general: General::of(&p),
            sign: self.a.signum(),
            h: p.initial_h,
            u_prev: 0.0,
        }
    }
}

/// A running Bouc-Wen operator: output d u - h, h = sign h~ where h~ runs the loop of
/// positive A ([`BoucWen::mirror`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BoucWenOp {
    p: BoucWen,
    /// The general exponent's scales (None: n = 1, the exact update).
    general: Option<General>,
    sign: f64,
    h: f64,
    u_prev: f64,
}

/// Exact update of h over an input path of length `v` in direction `s` (n = 1).
#[inline]
pub fn bouc_wen_exact(h0: f64, v: f64, s: f64, a: f64, b: f64, gamma: f64) -> f64 {
    let mut h = h0;
    let mut v = v;
    // sgn(h) as seen along the path: at h = 0 the state moves in direction s
    let sg = |h: f64| if h != 0.0 { h.signum() } else { s };
    let k = b + s * gamma * sg(h);
    if sg(h) != s {
        // moving towards 0: maybe cross it inside the step
        let v_cross = if k.abs() < 1e-300 {
            h.abs() / a
        } else {
            let h_inf = s * a / k;
            ((h_inf - h) / h_inf).ln() / k
        };
        if v_cross >= v {
            return if k.abs() < 1e-300 {
                h + s * a * v
            } else {
                let h_inf = s * a / k;
                h_inf + (h - h_inf) * (-k * v).exp()
            };
        }
        v -= v_cross;
        h = 0.0;
    }
    let k = b + gamma; // s * sgn(h) = +1 from here on
    let h_inf = s * a / k;
    h_inf + (h - h_inf) * (-k * v).exp()
}

/// The largest change of the general exponent's state x in one RK4 sub-step, against the
/// state's local rate constant |f'(x)| and its scale ([`bouc_wen_general`]): about 6e-6 of
/// the loop from the exact update near n = 1 (0.1: 4e-7, 0.05: 2e-8, at 1.4 and 2.3 times
/// the default `identify` time on a record of a fast multisine, the 0.05 build's exponent
/// difference of 1e-4 in place of 1e-3).
const SUB_STEP: f64 = 0.2;

/// The update of h over an input path of length `v` in direction `s` for any exponent n >= 1
/// (A > 0, the mirrored loop: [`BoucWen::mirror`]). In x = s h the equation is autonomous,
/// dx/dv = f(x) = A - B |x|^(n-1) x - Gamma |x|^n: A - (B + Gamma) x^n while h moves with the
/// input (x >= 0, towards x* = (A / (B + Gamma))^(1/n)) and A + (B - Gamma) |x|^n on the
/// way back to 0. RK4 in v with sub-steps chosen where the state is, not over the whole
/// step: each one keeps |f'(x)| dv (stiffness) and the change of x against
/// max(|x|, x_s) (x_s = (A / max(B + Gamma, B - Gamma))^(1/n), where the power begins to
/// count) below [`SUB_STEP`]; a state within 1e-14 of x* is there for the rest of the path.
/// A loop that saturates within a sample, or snaps back from far beyond x_s, costs up to a
/// couple of hundred sub-steps (each shrinks the distance to x* by about a fifth at the
/// stiffness limit), whatever the sample's length of path.
fn bouc_wen_general(h0: f64, v: f64, s: f64, p: &BoucWen, g: &General) -> f64 {
    let (a, n) = (p.a, p.n);
    let (up, down) = (p.b + p.gamma, p.b - p.gamma);
    // f(x) and the power term c |x|^n
    let f = |x: f64| {
        if x >= 0.0 {
            let q = up * x.powf(n);
            (a - q, q)
        } else {
            let q = down * (-x).powf(n);
            (a + q, q)
        }
    };
    let mut x = s * h0;
    let mut left = v;
    for _ in 0..100_000 {
        if left <= 0.0 {
            break;
        }
        if x >= 0.0 && (g.x_star - x).abs() <= 1e-14 * g.x_star {
            x = g.x_star;
            break;
        }
        if x < 0.0 && -x <= SUB_STEP * g.x_s {
            // near 0 on the way back: where f' jumps (B - Gamma to B + Gamma), the crossing
            // is found (Simpson in x: 1 / f is nearly 1 / A on [x, 0], smooth for n = 1 and
            // n >= 2, its |x|^n term of unbounded curvature at 0 for 1 < n < 2 costing a few
            // 1e-5 of x_s there) rather than stepped over
            let cross = -x / 6.0 * (1.0 / f(x).0 + 4.0 / f(0.5 * x).0 + 1.0 / a);
            if cross <= left {
                left -= cross;
                x = 0.0;
                continue;
            }
        }
        let (k1, q) = f(x);
        // |f'(x)| = n c |x|^(n-1)
        let stiffness = if x != 0.0 { n * q / x.abs() } else { 0.0 };
        let dv = left
            .min(SUB_STEP / stiffness.max(f64::MIN_POSITIVE))
            .min(SUB_STEP * x.abs().max(g.x_s) / k1.abs().max(f64::MIN_POSITIVE));
        let k2 = f(x + 0.5 * dv * k1).0;
        let k3 = f(x + 0.5 * dv * k2).0;
        let k4 = f(x + dv * k3).0;
        x += dv / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        left -= dv;
    }
    s * x
}

/// The scales of the general exponent's update ([`bouc_wen_general`]), once per operator.
#[derive(Debug, Clone, Copy, PartialEq)]
struct General {
    /// x* = (A / (B + Gamma))^(1/n), where h settles as it moves with the input.
    x_star: f64,
    /// x_s = (A / max(B + Gamma, B - Gamma))^(1/n).
    x_s: f64,
}

impl General {
    fn of(p: &BoucWen) -> Option<General> {
        (p.n != 1.0).then(|| {
            let (up, down) = (p.b + p.gamma, p.b - p.gamma);
            General {
                x_star: (p.a / up).powf(1.0 / p.n),
                x_s: (p.a / up.max(down)).powf(1.0 / p.n),
            }
        })
    }
}

impl Operator for BoucWenOp {
    fn reset(&mut self) {
        self.h = self.p.initial_h;
        self.u_prev = 0.0;
    }

    // always: the grey-box fit's Bouc-Wen column is this loop (a call per sample costs 3 %)
    #[inline(always)]
    fn step(&mut self, u: f64) -> f64 {
        let du = u - self.u_prev;
        if du != 0.0 {
            let s = du.signum();
            self.h = match &self.general {
                None => bouc_wen_exact(self.h, du.abs(), s, self.p.a, self.p.b, self.p.gamma),
                Some(g) => bouc_wen_general(self.h, du.abs(), s, &self.p, g),
            };
        }
        self.u_prev = u;
        self.p.d * u - self.sign * self.h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn piezo() -> BoucWen {
        BoucWenSpec {
            d: 0.8,
            a: 0.3,
            b: 0.02,
            gamma: 0.01,
            n: 1.0,
            initial_h: 0.0,
        }
        .check()
        .unwrap()
    }

    /// The largest absolute difference between `a` and `b`.
    fn max_error(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    /// Fine explicit integration of dh/du for comparison.
    fn euler(p: &BoucWen, u: &[f64], sub: usize) -> Vec<f64> {
        let mut h: f64 = 0.0;
        let mut out = Vec::new();
        let path: Vec<f64> = std::iter::once(0.0).chain(u.iter().copied()).collect();
        for w in path.windows(2) {
            let du = (w[1] - w[0]) / sub as f64;
            for _ in 0..sub {
                h += p.a * du
                    - p.b * du.abs() * h.abs().powf(p.n - 1.0) * h
                    - p.gamma * du * h.abs().powf(p.n);
            }
            out.push(p.d * w[1] - h);
        }
        out
    }

    #[test]
    fn exact_update_matches_fine_integration() {
        let p = piezo();
        let u: Vec<f64> = (0..800)
            .map(|k| 40.0 * (k as f64 * 0.02).sin() * (-(k as f64) / 600.0).exp())
            .collect();
        let y = p.operator().apply(&u);
        let y_ref = euler(&p, &u, 2000);
        let err = max_error(&y, &y_ref);
        assert!(err < 2e-3, "max error {err}");
    }

    #[test]
    fn general_exponent_matches_fine_integration() {
        let mut s = BoucWenSpec {
            d: 0.8,
            a: 0.3,
            b: 0.02,
            gamma: 0.01,
            n: 2.0,
            initial_h: 0.0,
        };
        s.b = 0.004;
        s.gamma = 0.002;
        let p = s.check().unwrap();
        let u: Vec<f64> = (0..400).map(|k| 40.0 * (k as f64 * 0.03).sin()).collect();
        let y = p.operator().apply(&u);
        let y_ref = euler(&p, &u, 2000);
        let err = max_error(&y, &y_ref);
        assert!(err < 2e-3, "max error {err}");
    }

    /// The general update near n = 1 is the exact one to 2e-5 of the loop (a grey-box fit's
    /// derivative in n compares them), on a loop of a few samples per branch, where a
    /// sample's path is many times the length over which h settles, on either side of a loop
    /// that snaps back.
    #[test]
    fn general_exponent_tends_to_the_exact_update() {
        let u: Vec<f64> = (0..300)
            .map(|k| 40.0 * (k as f64 * 0.9).sin() * (1.0 + 0.3 * (k as f64 * 0.05).cos()))
            .collect();
        for (b, gamma) in [(0.02, 0.01), (0.5, -0.45), (2.0, 1.5)] {
            let exact = BoucWenSpec {
                d: 0.0,
                a: 0.3,
                b,
                gamma,
                n: 1.0,
                initial_h: 0.0,
            };
            let near = BoucWenSpec {
                n: 1.0 + 1e-9,
                ..exact
            };
            let y = exact.check().unwrap().operator().apply(&u);
            let y_near = near.check().unwrap().operator().apply(&u);
            let scale = crate::metrics::max_abs(&y);
            let err = max_error(&y, &y_near) / scale;
            assert!(err < 2e-5, "B {b} Gamma {gamma}: relative error {err:e}");
        }
    }

    /// A stiff loop of n = 2.5 (it settles within a tenth of a sample's path) against fine
    /// integration.
    #[test]
    fn general_exponent_settles_within_a_sample() {
        let p = BoucWenSpec {
            d: 0.2,
            a: 1.0,
            b: 0.08,
            gamma: -0.05,
            n: 2.5,
            initial_h: 0.0,
        }
        .check()
        .unwrap();
        let u: Vec<f64> = (0..60).map(|k| 30.0 * (k as f64 * 0.7).sin()).collect();
        let y = p.operator().apply(&u);
        let y_ref = euler(&p, &u, 200_000);
        let err = max_error(&y, &y_ref);
        assert!(
            err < 1e-3 * crate::metrics::max_abs(&y_ref),
            "max error {err}"
        );
    }

    #[test]
    fn invalid_parameters_rejected() {
        let mut s = BoucWenSpec {
            d: 0.8,
            a: 0.3,
            b: 0.01,
            gamma: 0.02,
            n: 1.0,
            initial_h: 0.0,
        };
        let e = s.check().unwrap_err().to_string();
        assert!(e.contains("`B` = 0.01") && e.contains("|Gamma|"), "{e}");
        s.b = f64::NAN;
        assert!(s.check().is_err());
        s.b = 0.03;
        s.a = 0.0;
        assert!(s.check().unwrap_err().to_string().contains("`A`"));
        // a negative A mirrors the loop: B - Gamma must be > 0
        s.a = -1.0;
        s.gamma = 0.03;
        let e = s.check().unwrap_err().to_string();
        assert!(e.contains("B - Gamma"), "{e}");
    }

    /// d, A and Gamma negated give the negated plant, for n = 1 (the exact update) and n = 2
    /// (RK4), from rest and from a loaded initial state.
    #[test]
    fn a_negative_a_is_the_negated_plant() {
        let u: Vec<f64> = (0..600)
            .map(|k| 30.0 * (k as f64 * 0.025).sin() + 8.0 * (k as f64 * 0.11).cos())
            .collect();
        for (n, b, gamma, h0) in [(1.0, 0.02, 0.012, 0.0), (2.0, 0.004, -0.003, 0.5)] {
            let pos = BoucWenSpec {
                d: 0.8,
                a: 0.3,
                b,
                gamma,
                n,
                initial_h: h0,
            };
            let neg = BoucWenSpec {
                d: -pos.d,
                a: -pos.a,
                gamma: -pos.gamma,
                initial_h: -pos.initial_h,
                ..pos
            };
            let (p, q) = (pos.check().unwrap(), neg.check().unwrap());
            assert_eq!(p.h_bound(), q.h_bound());
            let (yp, yq) = (p.operator().apply(&u), q.operator().apply(&u));
            assert!(yp.iter().zip(&yq).all(|(a, b)| *a == -*b), "n = {n}");
            // and, from rest, it is the negative-A equation itself integrated finely (`euler`
            // starts at h = 0)
            if h0 == 0.0 {
                let y_ref = euler(&q, &u, 2000);
                let err = max_error(&yq, &y_ref);
                assert!(err < 2e-3, "n = {n}: max error {err}");
            }
        }
    }
}
