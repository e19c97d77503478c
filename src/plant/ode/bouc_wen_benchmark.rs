//! # Bouc-Wen benchmark plant (Noël & Schoukens, 2016)
//!
//! A mass-spring-damper whose restoring force has a Bouc-Wen term driven by the velocity:
//!
//! ```text
//! m y'' + c y' + k y + z = u
//! z' = alpha y' - beta (gamma |y'| |z|^(nu-1) z + delta y' |z|^nu)
//! ```
//!
//! with the benchmark's values m = 2 kg, c = 10 N s/m, k = 5e4 N/m, alpha = 5e4 N/m,
//! beta = 1e3 1/m, gamma = 0.8, delta = -1.1, nu = 1, sampled at 750 Hz. u is a force in N and
//! y a displacement in m. The original data were made by Newmark integration at 15 kHz (20x
//! upsampling) followed by FIR decimation; here the ODE is integrated between the samples with
//! a band-limited input (see [`super`]) by Dopri5 (ode_solvers, default, the reference) or a
//! hand-written RK4 with `oversampling` steps per sample (the fast path).
//!
//! Paths: the default, `"integrator": "dopri5"` (rtol 1e-8 unless the plant file sets it; the
//! shipped `plants/bouc_wen_benchmark.json` uses 1e-6: same errors against the official records,
//! about 1.2 million samples/s), is the reference. The fast path
//! is `"integrator": "rk4"` with `"oversampling": 10`: on the official records it gives the
//! same errors against the official outputs and stays within 4e-7 m (2e-4 of the largest |y|)
//! of Dopri5 at rtol 1e-11 (measured: 2.6e-7 m on the multisine, 3.9e-7 m on the whole sweep;
//! the |y'| and |z| kinks make RK4 about second order here; `tests/ode_benchmark.rs` checks
//! it), at about a million output samples per second or more (`cargo bench --bench ode`).
//!
//! ```
//! use hystbench::plant::ode::BoucWenBenchmarkSpec;
//! let plant = BoucWenBenchmarkSpec::default().check()?;
//! let ts = 1.0 / 750.0;
//! let u: Vec<f64> = (0..750)
//!     .map(|k| 40.0 * (2.0 * std::f64::consts::PI * 20.0 * k as f64 * ts).sin())
//!     .collect();
//! let y = plant.simulate(&u, ts, false)?;
//! assert_eq!(y[0], 0.0);
//! assert!(y.iter().all(|v| v.abs() < 5e-3)); // metres
//! # Ok::<(), hystbench::plant::ode::OdeError>(())
//! ```
//!
//! Internally the state is scaled to one unit, q = (y, y'/w, z/kappa) with kappa = k + alpha
//! and w = sqrt(kappa/m), so one absolute tolerance (rtol times the static deflection under the
//! largest input) suits every component.
//!
//! With delta < 0 the loading branch stiffens exponentially (dz/dy = alpha + beta(|delta| -
//! gamma) z for the benchmark, about alpha + 300 z), so large amplitudes can blow up: a guard
//! stops the run with the sample where |y| left 1e4 static deflections or the state stopped
//! being finite.
//!
//! ## References
//! - J.P. Noël, M. Schoukens, "Hysteretic benchmark with a dynamic nonlinearity", Workshop on
//!   Nonlinear System Identification Benchmarks, Brussels, 2016, pp. 7-14; data
//!   doi 10.4121/12967592; <https://www.nonlinearbenchmark.org/benchmarks/bouc-wen>.
//! - M. Schoukens, J.P. Noël, "Three benchmarks addressing open challenges in nonlinear system
//!   identification", IFAC-PapersOnLine 50(1):446-451, 2017, doi 10.1016/j.ifacol.2017.08.071.

use super::integrator::{Dopri5Integrator, DrivenOde, Integrator, Rk4Integrator};
use super::{invalid, InputInterpolation, OdeError, SampledInput};
use nalgebra::SVector;
use serde::{Deserialize, Serialize};

/// The integrator used between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorKind {
    /// ode_solvers' Dopri5, adaptive, tolerance `rtol` (the reference).
    #[default]
    Dopri5,
    /// Hand-written classical RK4 with `oversampling` steps per sample (the fast path).
    Rk4,
}

fn default_oversampling() -> usize {
    20
}

fn default_rtol() -> f64 {
    1e-8
}

/// The plant as written in `plants/*.json` under `"ode": {"bouc_wen_benchmark": {...}}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoucWenBenchmarkSpec {
    /// m (kg), > 0.
    pub mass_kg: f64,
    /// c (N s/m), >= 0.
    pub damping_ns_per_m: f64,
    /// k (N/m), >= 0.
    pub stiffness_n_per_m: f64,
    /// alpha (N/m), >= 0.
    pub alpha: f64,
    /// beta (1/m), >= 0.
    pub beta: f64,
    /// gamma (dimensionless).
    pub gamma: f64,
    /// delta (dimensionless).
    pub delta: f64,
    /// nu >= 1.
    pub nu: f64,
    /// RK4 steps per sample (the original: Newmark at 20x); 1..=10000. Dopri5 picks its own.
    #[serde(default = "default_oversampling")]
    pub oversampling: usize,
    /// The input between samples: "bandlimited" (default), "linear" or "zoh".
    #[serde(default)]
    pub input_interpolation: InputInterpolation,
    /// "dopri5" (default) or "rk4".
    #[serde(default)]
    pub integrator: IntegratorKind,
    /// Dopri5 relative tolerance, in [1e-13, 1e-3].
    #[serde(default = "default_rtol")]
    pub rtol: f64,
}

impl Default for BoucWenBenchmarkSpec {
    /// The benchmark's own values (Noël & Schoukens 2016).
    fn default() -> Self {
        BoucWenBenchmarkSpec {
            mass_kg: 2.0,
            damping_ns_per_m: 10.0,
            stiffness_n_per_m: 5e4,
            alpha: 5e4,
            beta: 1e3,
            gamma: 0.8,
            delta: -1.1,
            nu: 1.0,
            oversampling: default_oversampling(),
            input_interpolation: InputInterpolation::default(),
            integrator: IntegratorKind::default(),
            rtol: default_rtol(),
        }
    }
}

impl BoucWenBenchmarkSpec {
    /// Checks every field and returns the valid plant, or an error naming the field, the value
    /// and the rule.
    pub fn check(&self) -> Result<BoucWenBenchmark, OdeError> {
        let fields = [
            ("mass_kg", self.mass_kg),
            ("damping_ns_per_m", self.damping_ns_per_m),
            ("stiffness_n_per_m", self.stiffness_n_per_m),
            ("alpha", self.alpha),
            ("beta", self.beta),
            ("gamma", self.gamma),
            ("delta", self.delta),
            ("nu", self.nu),
            ("rtol", self.rtol),
        ];
        for (name, v) in fields {
            if !v.is_finite() {
                return Err(invalid(name, v, "must be a finite number"));
            }
        }
        if self.mass_kg <= 0.0 {
            return Err(invalid("mass_kg", self.mass_kg, "the mass must be > 0"));
        }
        for (name, v) in [
            ("damping_ns_per_m", self.damping_ns_per_m),
            ("stiffness_n_per_m", self.stiffness_n_per_m),
            ("alpha", self.alpha),
            ("beta", self.beta),
        ] {
            if v < 0.0 {
                return Err(invalid(name, v, "must be >= 0"));
            }
        }
        if self.nu < 1.0 {
            return Err(invalid(
                "nu",
                self.nu,
                "must be >= 1 (below 1, |z|^(nu-1) is singular at z = 0)",
            ));
        }
        if !(1..=10_000).contains(&self.oversampling) {
            return Err(invalid(
                "oversampling",
                self.oversampling as f64,
                "must be an integer in 1..=10000 (RK4 steps per sample)",
            ));
        }
        if !(1e-13..=1e-3).contains(&self.rtol) {
            return Err(invalid("rtol", self.rtol, "must be in [1e-13, 1e-3]"));
        }
        let kappa = self.stiffness_n_per_m + self.alpha;
        Ok(BoucWenBenchmark {
            spec: self.clone(),
            kappa,
        })
    }
}

/// A checked Bouc-Wen benchmark plant, ready to simulate.
#[derive(Debug, Clone, PartialEq)]
pub struct BoucWenBenchmark {
    spec: BoucWenBenchmarkSpec,
    /// k + alpha (N/m): the small-signal stiffness, used for scaling.
    kappa: f64,
}

/// Number of decay time constants 2m/c simulated before the returned period of a periodic run.
pub const PERIODIC_SETTLE_TIME_CONSTANTS: f64 = 40.0;
/// Warm-up periods of a periodic run when c = 0 (no linear decay rate to go by).
pub const PERIODIC_WARMUP_UNDAMPED: usize = 10;
/// Longest warm-up of a periodic run, in samples.
pub const MAX_WARMUP_SAMPLES: usize = 100_000_000;
/// The amplitude guard: |y| may reach this many static deflections max|u| / (k + alpha).
pub const GUARD_STATIC_DEFLECTIONS: f64 = 1e4;

/// The right-hand side in the scaled state q = (y, y'/w, z/kappa), with every constant
/// folded in (no division in the hot loop):
/// q0' = w q1; q1' = (u - c w q1 - k q0 - kappa q2) / (m w);
/// q2' = (alpha w / kappa) q1 - beta w (gamma |q1| q2 + delta q1 |q2|) for nu = 1.
#[derive(Debug, Clone, Copy)]
struct ScaledRhs {
    w: f64,
    u_gain: f64,
    c_gain: f64,
    k_gain: f64,
    z_gain: f64,
    alpha_gain: f64,
    gamma_gain: f64,
    delta_gain: f64,
    /// nu, and kappa^(nu - 1) for the general exponent.
    nu: f64,
    kappa_pow: f64,
}

impl ScaledRhs {
    fn new(p: &BoucWenBenchmarkSpec, kappa: f64) -> Self {
        let m = p.mass_kg;
        let w = (kappa / m).sqrt();
        ScaledRhs {
            w,
            u_gain: 1.0 / (m * w),
            c_gain: p.damping_ns_per_m / m,
            k_gain: p.stiffness_n_per_m / (m * w),
            z_gain: kappa / (m * w),
            alpha_gain: p.alpha * w / kappa,
            gamma_gain: p.beta * p.gamma * w,
            delta_gain: p.beta * p.delta * w,
            nu: p.nu,
            kappa_pow: kappa.powf(p.nu - 1.0),
        }
    }

    #[inline(always)]
    fn eval(&self, u: f64, q: &SVector<f64, 3>) -> SVector<f64, 3> {
        let (y, q1, q2) = (q[0], q[1], q[2]);
        // Summed as a tree: RK4 on this small system is bound by the latency of this chain.
        let dq1 = (self.u_gain * u - self.k_gain * y) - (self.c_gain * q1 + self.z_gain * q2);
        let dq2 = if self.nu == 1.0 {
            self.alpha_gain * q1
                - (self.gamma_gain * q1.abs() * q2 + self.delta_gain * q1 * q2.abs())
        } else {
            // |z|^(nu-1) z / kappa = kappa^(nu-1) |q2|^(nu-1) q2, |z|^nu / kappa likewise.
            let zn = q2.abs().powf(self.nu) * self.kappa_pow;
            self.alpha_gain * q1
                - (self.gamma_gain * q1.abs() * zn * q2.signum() + self.delta_gain * q1 * zn)
        };
        SVector::<f64, 3>::new(self.w * q1, dq1, dq2)
    }
}

/// The plant over one sample interval.
struct IntervalOde<'a> {
    rhs: ScaledRhs,
    input: &'a SampledInput,
    interval: usize,
}

impl DrivenOde<3> for IntervalOde<'_> {
    #[inline(always)]
    fn input(&self, t: f64) -> f64 {
        self.input.in_interval(self.interval, t)
    }

    #[inline(always)]
    fn rhs(&self, u: f64, q: &SVector<f64, 3>) -> SVector<f64, 3> {
        self.rhs.eval(u, q)
    }
}

impl BoucWenBenchmark {
    /// The parameters it was checked from.
    pub fn spec(&self) -> &BoucWenBenchmarkSpec {
        &self.spec
    }

    /// Simulates the plant from rest for the input `u` sampled every `ts` seconds and returns
    /// y at the sample times (y[0] = 0 at rest). With `periodic`, `u` is one period of a
    /// periodic input: the plant runs until the transient has died (40 time constants 2m/c,
    /// at least one period; 10 periods when c = 0) and the last, steady-state period is
    /// returned.
    pub fn simulate(&self, u: &[f64], ts: f64, periodic: bool) -> Result<Vec<f64>, OdeError> {
        self.simulate_counted(u, ts, periodic).map(|(y, _)| y)
    }

    /// [`simulate`](Self::simulate), also returning the number of right-hand-side evaluations.
    pub fn simulate_counted(
        &self,
        u: &[f64],
        ts: f64,
        periodic: bool,
    ) -> Result<(Vec<f64>, u64), OdeError> {
        let input = SampledInput::new(u, ts, periodic, self.spec.input_interpolation)?;
        match self.spec.integrator {
            IntegratorKind::Rk4 => self.run(
                &input,
                u,
                periodic,
                Rk4Integrator::new(self.spec.oversampling),
            ),
            IntegratorKind::Dopri5 => {
                let atol = self.spec.rtol * self.static_deflection(u);
                self.run(
                    &input,
                    u,
                    periodic,
                    Dopri5Integrator::new(self.spec.rtol, atol),
                )
            }
        }
    }

    /// max|u| / (k + alpha), or max|u| / (m (2 pi / ts)^2)-like fallback when k + alpha = 0.
    fn static_deflection(&self, u: &[f64]) -> f64 {
        let umax = u.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        umax / self.kappa_eff()
    }

    fn kappa_eff(&self) -> f64 {
        if self.kappa > 0.0 {
            self.kappa
        } else {
            self.spec.mass_kg
        }
    }

    /// Warm-up periods before the returned one, for a periodic input of `n` samples.
    pub fn warmup_periods(&self, n: usize, ts: f64) -> usize {
        let period = n as f64 * ts;
        if self.spec.damping_ns_per_m > 0.0 {
            let settle = PERIODIC_SETTLE_TIME_CONSTANTS * 2.0 * self.spec.mass_kg
                / self.spec.damping_ns_per_m;
            // `as` saturates, so a vanishing damping gives a huge count, refused in `run`.
            ((settle / period).ceil() as usize).max(1)
        } else {
            PERIODIC_WARMUP_UNDAMPED
        }
    }

    fn run<I: Integrator<3>>(
        &self,
        input: &SampledInput,
        u: &[f64],
        periodic: bool,
        mut integrator: I,
    ) -> Result<(Vec<f64>, u64), OdeError> {
        let n = u.len();
        let ts = input.ts();
        let y_static = self.static_deflection(u);
        if y_static == 0.0 {
            // At rest with no force: it stays at rest.
            return Ok((vec![0.0; n], 0));
        }
        let limit = GUARD_STATIC_DEFLECTIONS * y_static;
        let kappa = self.kappa_eff();
        let rhs = ScaledRhs::new(&self.spec, kappa);
        let w = rhs.w;
        let (warmup, total_samples) = if periodic {
            let p = self.warmup_periods(n, ts);
            if p.saturating_mul(n) > MAX_WARMUP_SAMPLES {
                return Err(OdeError::SettlingTooLong {
                    time_constant: 2.0 * self.spec.mass_kg / self.spec.damping_ns_per_m,
                    samples: p.saturating_mul(n),
                    limit: MAX_WARMUP_SAMPLES,
                });
            }
            (p * n, (p + 1) * n)
        } else {
            (0, n)
        };
        let mut out = Vec::with_capacity(n);
        let mut q = SVector::<f64, 3>::zeros();
        if warmup == 0 {
            out.push(0.0);
        }
        for i in 0..total_samples - 1 {
            let ode = IntervalOde {
                rhs,
                input,
                interval: if periodic { i % n } else { i },
            };
            let t0 = i as f64 * ts;
            integrator
                .advance(&ode, t0, ts, &mut q)
                .map_err(|source| OdeError::Integration {
                    sample: i + 1,
                    time: t0 + ts,
                    source,
                })?;
            if !(q.iter().all(|v| v.is_finite()) && q[0].abs() <= limit) {
                return Err(OdeError::Diverged {
                    sample: i + 1,
                    time: t0 + ts,
                    state: vec![q[0], q[1] * w, q[2] * kappa],
                    limit,
                });
            }
            if i + 1 >= warmup {
                out.push(q[0]);
            }
        }
        debug_assert_eq!(out.len(), n);
        Ok((out, integrator.evaluations()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> BoucWenBenchmarkSpec {
        BoucWenBenchmarkSpec::default()
    }

    #[test]
    fn bad_parameters_name_the_field_value_and_rule() {
        let cases: Vec<(BoucWenBenchmarkSpec, &str)> = vec![
            (
                BoucWenBenchmarkSpec {
                    mass_kg: 0.0,
                    ..spec()
                },
                "mass_kg",
            ),
            (
                BoucWenBenchmarkSpec {
                    damping_ns_per_m: -1.0,
                    ..spec()
                },
                "damping_ns_per_m",
            ),
            (
                BoucWenBenchmarkSpec {
                    stiffness_n_per_m: -5.0,
                    ..spec()
                },
                "stiffness_n_per_m",
            ),
            (
                BoucWenBenchmarkSpec {
                    beta: -1e3,
                    ..spec()
                },
                "beta",
            ),
            (BoucWenBenchmarkSpec { nu: 0.5, ..spec() }, "nu"),
            (
                BoucWenBenchmarkSpec {
                    gamma: f64::NAN,
                    ..spec()
                },
                "gamma",
            ),
            (
                BoucWenBenchmarkSpec {
                    oversampling: 0,
                    ..spec()
                },
                "oversampling",
            ),
            (
                BoucWenBenchmarkSpec {
                    rtol: 0.5,
                    ..spec()
                },
                "rtol",
            ),
        ];
        for (s, field) in cases {
            let e = s.check().unwrap_err();
            let msg = e.to_string();
            assert!(msg.contains(field), "{msg}");
            assert!(matches!(e, OdeError::Invalid { .. }));
        }
        assert!(spec().check().is_ok());
    }

    #[test]
    fn spec_json_rejects_unknown_fields_and_fills_defaults() {
        let json = r#"{"mass_kg": 2, "damping_ns_per_m": 10, "stiffness_n_per_m": 5e4,
            "alpha": 5e4, "beta": 1e3, "gamma": 0.8, "delta": -1.1, "nu": 1}"#;
        let s: BoucWenBenchmarkSpec = serde_json::from_str(json).unwrap();
        assert_eq!(s, spec());
        let bad = json.replace("\"nu\"", "\"nu_typo\"");
        let e = serde_json::from_str::<BoucWenBenchmarkSpec>(&bad).unwrap_err();
        assert!(e.to_string().contains("unknown field"), "{e}");
        let s: BoucWenBenchmarkSpec = serde_json::from_str(&json.replace(
            "\"nu\": 1",
            "\"nu\": 1, \"integrator\": \"rk4\", \"input_interpolation\": \"zoh\"",
        ))
        .unwrap();
        assert_eq!(s.integrator, IntegratorKind::Rk4);
        assert_eq!(s.input_interpolation, InputInterpolation::Zoh);
    }

    /// Small constant force: static deflection u / (k + alpha) for a small load (z ~ alpha y).
    #[test]
    fn small_step_settles_near_the_linear_static_deflection() {
        let plant = BoucWenBenchmarkSpec {
            integrator: IntegratorKind::Rk4,
            input_interpolation: InputInterpolation::Zoh,
            ..spec()
        }
        .check()
        .unwrap();
        let u = vec![1e-3; 750 * 8];
        let y = plant.simulate(&u, 1.0 / 750.0, false).unwrap();
        assert_eq!(y[0], 0.0);
        let y_end = *y.last().unwrap();
        let lin = 1e-3 / (5e4 + 5e4);
        assert!((y_end - lin).abs() < 0.01 * lin, "{y_end} vs {lin}");
    }

    #[test]
    fn divergence_is_reported_with_its_sample() {
        // Exponential stiffening with delta < 0 blows up under a huge force.
        let plant = BoucWenBenchmarkSpec {
            integrator: IntegratorKind::Rk4,
            ..spec()
        }
        .check()
        .unwrap();
        let u: Vec<f64> = (0..3000)
            .map(|k| 1e6 * (2.0 * std::f64::consts::PI * 5.0 * k as f64 / 750.0).sin())
            .collect();
        match plant.simulate(&u, 1.0 / 750.0, false) {
            Err(OdeError::Diverged { sample, .. }) => assert!(sample > 0 && sample < 3000),
            other => panic!("expected divergence, got {other:?}"),
        }
    }

    fn two_tones(n: usize, ts: f64) -> Vec<f64> {
        let period = n as f64 * ts;
        (0..n)
            .map(|k| {
                let t = k as f64 * ts;
                let w = 2.0 * std::f64::consts::PI / period;
                30.0 * (3.0 * w * t).sin() + 20.0 * (35.0 * w * t + 0.4).cos()
            })
            .collect()
    }

    /// The periodic mode returns the steady state: the last period of a long run from rest on
    /// the repeated input.
    #[test]
    fn periodic_mode_is_the_steady_state_of_the_repeated_input() {
        let ts = 1.0 / 750.0;
        let n = 750;
        let plant = BoucWenBenchmarkSpec {
            integrator: IntegratorKind::Rk4,
            oversampling: 4,
            input_interpolation: InputInterpolation::Linear,
            ..spec()
        }
        .check()
        .unwrap();
        let u = two_tones(n, ts);
        let periods = plant.warmup_periods(n, ts) + 1;
        assert_eq!(periods, 17, "40 time constants of 0.4 s, 1 s periods");
        let y = plant.simulate(&u, ts, true).unwrap();
        let repeated: Vec<f64> = u.iter().cycle().take(periods * n + 1).cloned().collect();
        let long = plant.simulate(&repeated, ts, false).unwrap();
        let last = &long[(periods - 1) * n..periods * n];
        let diff = y
            .iter()
            .zip(last)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let max_y = y.iter().fold(0.0f64, |m, a| m.max(a.abs()));
        assert!(max_y > 1e-4, "{max_y}");
        assert!(diff < 1e-12 * 1e3 * max_y, "{diff}");
        // And it is periodic: the period before is the same to the decay of the transient.
        let before = &long[(periods - 2) * n..(periods - 1) * n];
        let drift = before
            .iter()
            .zip(last)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(drift < 1e-9 * max_y, "{drift}");
    }

    /// The general-exponent branch agrees with the nu = 1 branch at nu -> 1.
    #[test]
    fn general_exponent_is_continuous_at_one() {
        let ts = 1.0 / 750.0;
        let u = two_tones(1500, ts);
        let run = |nu: f64| {
            BoucWenBenchmarkSpec {
                integrator: IntegratorKind::Rk4,
                oversampling: 10,
                nu,
                ..spec()
            }
            .check()
            .unwrap()
            .simulate(&u, ts, false)
            .unwrap()
        };
        let (a, b, c) = (run(1.0), run(1.0 + 1e-9), run(1.5));
        let max_y = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let d_ab = a
            .iter()
            .zip(&b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        let d_ac = a
            .iter()
            .zip(&c)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(d_ab < 1e-6 * max_y, "{d_ab}");
        assert!(d_ac > 1e-3 * max_y, "nu must matter: {d_ac}");
    }

    #[test]
    fn periodic_run_refuses_an_endless_transient() {
        let plant = BoucWenBenchmarkSpec {
            damping_ns_per_m: 1e-9,
            ..spec()
        }
        .check()
        .unwrap();
        let e = plant
            .simulate(&[1.0, -1.0, 0.5, 0.0], 0.01, true)
            .unwrap_err();
        assert!(matches!(e, OdeError::SettlingTooLong { .. }), "{e}");
        assert!(e.to_string().contains("time constant"), "{e}");
    }

    #[test]
    fn zero_input_stays_at_rest() {
        let plant = spec().check().unwrap();
        assert_eq!(
            plant.simulate(&[0.0; 10], 0.01, false).unwrap(),
            vec![0.0; 10]
        );
    }
}
