//! # ODE plants
//!
//! Plants given as ordinary differential equations driven by one sampled input, integrated
//! between the samples and read out at the sample times. Three parts, kept apart:
//!
//! - the definition: a [`DrivenOde`] (right-hand side and the input at any time), e.g.
//!   [`bouc_wen_benchmark::BoucWenBenchmark`];
//! - the input between samples: [`SampledInput`] (band-limited, linear or zero-order hold);
//! - the algorithm: an [`Integrator`] (`Dopri5` from ode_solvers, the accuracy reference, or a
//!   hand-written fixed-step `Rk4`, the fast path), see [`integrator`].
//!
//! The band-limited input is what a sampled, band-limited excitation means physically: the
//! continuous signal whose samples were recorded. For a periodic input (one period given) it is
//! the exact trigonometric interpolant, computed with a radix-2 FFT by zero-padding the spectrum
//! (any length that is not a power of two falls back to a wrapped windowed sinc). For a
//! non-periodic input it is a Kaiser-windowed sinc (32 taps per side, beta 8, unit DC gain per
//! phase) with the record extended past both ends by point reflection (`2 u[0] - u[-k]`, as
//! filtfilt/decimate do), so a record that starts or stops mid-swing has no jump. Both are
//! evaluated on a grid [`FINE_PER_SAMPLE`] times finer than the samples and joined by 4-point
//! Lagrange (cubic) interpolation, so every integrator stage sees a smooth input.
//!
//! ## References
//! - J.P. Noël, M. Schoukens, "Hysteretic benchmark with a dynamic nonlinearity", Workshop on
//!   Nonlinear System Identification Benchmarks, Brussels, 2016, pp. 7-14; data doi
//!   10.4121/12967592.
//! - J.F. Kaiser, R.W. Schafer, "On the use of the I0-sinh window for spectrum analysis",
//!   IEEE T-ASSP 28(1):105-107, 1980 (Kaiser window).
//! - J.W. Cooley, J.W. Tukey, "An algorithm for the machine calculation of complex Fourier
//!   series", Math. Comp. 19:297-301, 1965.

pub mod bouc_wen_benchmark;
pub mod integrator;

pub use bouc_wen_benchmark::IntegratorKind;
pub use bouc_wen_benchmark::{BoucWenBenchmark, BoucWenBenchmarkSpec};
pub use integrator::{Dopri5Integrator, DrivenOde, Integrator, IntegratorError, Rk4Integrator};

use nalgebra::Complex;
use serde::{Deserialize, Serialize};

/// What can go wrong with an ODE plant's parameters, input or integration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum OdeError {
    /// A parameter breaks a rule.
    #[error("`{field}` = {value}: {rule}")]
    Invalid {
        field: String,
        value: f64,
        rule: String,
    },
    /// The input signal is empty.
    #[error("the input has no samples; give at least 1 (at least 2 for a periodic input)")]
    EmptyInput,
    /// The input holds NaN or an infinity.
    #[error("input sample {index} is {value}; every input sample must be finite")]
    NonFiniteInput { index: usize, value: f64 },
    /// The sampling period is not a positive finite number.
    #[error("sampling period {ts} s: it must be finite and > 0")]
    SamplingPeriod { ts: f64 },
    /// The state became non-finite or left the amplitude guard.
    #[error(
        "the simulation diverged at sample {sample} (t = {time} s): state {state:?} is non-finite \
         or beyond the guard |y| <= {limit}; lower the input amplitude or check the parameters"
    )]
    Diverged {
        sample: usize,
        time: f64,
        state: Vec<f64>,
        limit: f64,
    },
    /// A periodic run would need too long a warm-up for its transient to die.
    #[error(
        "a periodic run needs {samples} warm-up samples (damping time constant 2m/c = \
         {time_constant} s), more than the limit of {limit}; simulate it as a non-periodic \
         input or increase the damping"
    )]
    SettlingTooLong {
        time_constant: f64,
        samples: usize,
        limit: usize,
    },
    /// The ODE solver gave up.
    #[error(
        "the integrator failed in the interval ending at sample {sample} (t = {time} s): {source}"
    )]
    Integration {
        sample: usize,
        time: f64,
        source: IntegratorError,
    },
}

impl OdeError {
    /// The same error with `prefix.` in front of a field name (to give the path in a plant
    /// file, e.g. `ode.bouc_wen_benchmark`).
    pub fn within(self, prefix: &str) -> OdeError {
        match self {
            OdeError::Invalid { field, value, rule } => OdeError::Invalid {
                field: format!("{prefix}.{field}"),
                value,
                rule,
            },
            e => e,
        }
    }
}

pub(crate) fn invalid(field: &str, value: f64, rule: &str) -> OdeError {
    OdeError::Invalid {
        field: field.to_string(),
        value,
        rule: rule.to_string(),
    }
}

/// How the input is continued between its samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InputInterpolation {
    /// Band-limited (below the Nyquist frequency): exact trigonometric interpolation for a
    /// periodic input, Kaiser-windowed sinc otherwise.
    #[default]
    Bandlimited,
    /// Straight lines between samples.
    Linear,
    /// Zero-order hold: each sample held until the next.
    Zoh,
}

/// Fine-grid points per sample of the band-limited input (between them: cubic interpolation).
pub const FINE_PER_SAMPLE: usize = 4;
/// Half length, in samples, of the windowed sinc for non-periodic inputs.
pub const SINC_HALF_TAPS: usize = 32;
/// Kaiser window shape parameter of that sinc (about 80 dB stop band).
pub const KAISER_BETA: f64 = 8.0;

/// A sampled input made continuous in time: `at(t)` for any t.
#[derive(Debug, Clone)]
pub struct SampledInput {
    /// Values on the evaluation grid (spacing `ts / per_sample`); grid index j (time
    /// j ts / per_sample) is stored at `j + pad`.
    grid: Vec<f64>,
    /// Stored points before grid index 0 (and at least as many after the last).
    pad: usize,
    /// Grid points of the record (non-periodic) or of one period (periodic).
    len: usize,
    periodic: bool,
    /// per_sample / ts.
    rate: f64,
    ts: f64,
    kind: InputInterpolation,
}

impl SampledInput {
    /// Builds the continuous input from samples `u` taken every `ts` seconds; `periodic` means
    /// `u` is one period of a periodic signal.
    pub fn new(
        u: &[f64],
        ts: f64,
        periodic: bool,
        kind: InputInterpolation,
    ) -> Result<Self, OdeError> {
        if !(ts.is_finite() && ts > 0.0) {
            return Err(OdeError::SamplingPeriod { ts });
        }
        if u.is_empty() || (periodic && u.len() < 2) {
            return Err(OdeError::EmptyInput);
        }
        if let Some((index, &value)) = u.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(OdeError::NonFiniteInput { index, value });
        }
        let n = u.len();
        let per_sample = match kind {
            InputInterpolation::Bandlimited => FINE_PER_SAMPLE,
            _ => 1,
        };
        let len = n * per_sample;
        // Two samples' worth of grid on each side: enough for the 4-point stencil.
        let pad = 2 * per_sample;
        let grid = match (kind, periodic) {
            (InputInterpolation::Bandlimited, true) => {
                let core = if n.is_power_of_two() {
                    fft_upsample(u, per_sample)
                } else {
                    sinc_upsample(u, per_sample, true, 0)
                };
                let mut g = Vec::with_capacity(len + 2 * pad);
                g.extend_from_slice(&core[len - pad..]);
                g.extend_from_slice(&core);
                g.extend_from_slice(&core[..pad]);
                g
            }
            (InputInterpolation::Bandlimited, false) => sinc_upsample(u, per_sample, false, 2),
            (_, true) => (-(pad as i64)..(len + pad) as i64)
                .map(|k| u[k.rem_euclid(n as i64) as usize])
                .collect(),
            (_, false) => (-(pad as i64)..(len + pad) as i64)
                .map(|k| reflected(u, k))
                .collect(),
        };
        debug_assert_eq!(grid.len(), len + 2 * pad);
        Ok(SampledInput {
            grid,
            pad,
            len,
            periodic,
            rate: per_sample as f64 / ts,
            ts,
            kind,
        })
    }

    /// Sampling period of the underlying samples.
    pub fn ts(&self) -> f64 {
        self.ts
    }

    /// Storage index of grid index `j` (wrapped when periodic, held at the ends otherwise).
    #[inline(always)]
    fn slot(&self, j: i64) -> usize {
        let j = if self.periodic {
            j.rem_euclid(self.len as i64)
        } else {
            j.clamp(1 - self.pad as i64, (self.len + self.pad) as i64 - 3)
        };
        (j + self.pad as i64) as usize
    }

    /// The input in the sample interval `k` (from sample k to k + 1) at time `t`: for a
    /// zero-order hold this is u[k] on the whole closed interval, including its end.
    #[inline(always)]
    pub fn in_interval(&self, k: usize, t: f64) -> f64 {
        match self.kind {
            InputInterpolation::Zoh => self.grid[self.slot(k as i64)],
            _ => self.at(t),
        }
    }

    /// The input at time `t` (seconds from the first sample).
    #[inline(always)]
    pub fn at(&self, t: f64) -> f64 {
        let s = t * self.rate;
        // floor without a libm call (baseline x86-64 has no rounding instruction).
        let mut j = s as i64;
        if (j as f64) > s {
            j -= 1;
        }
        let f = s - j as f64;
        let i = self.slot(j);
        match self.kind {
            InputInterpolation::Zoh => self.grid[i],
            InputInterpolation::Linear => {
                let w = &self.grid[i..i + 2];
                w[0] + f * (w[1] - w[0])
            }
            InputInterpolation::Bandlimited => {
                let w = &self.grid[i - 1..i + 3];
                // 4-point Lagrange on nodes -1, 0, 1, 2.
                let fm1 = f - 1.0;
                let fm2 = f - 2.0;
                let fp1 = f + 1.0;
                let a = f * fm1;
                let b = fp1 * fm2;
                (-w[0] * a * fm2 + w[3] * fp1 * a) * (1.0 / 6.0)
                    + (w[1] * fm1 * b - w[2] * f * b) * 0.5
            }
        }
    }
}

/// Sample `k` of `u` with point-reflection extension past both ends.
fn reflected(u: &[f64], k: i64) -> f64 {
    let n = u.len() as i64;
    if n == 1 {
        return u[0];
    }
    if k < 0 {
        let m = (-k).min(n - 1);
        2.0 * u[0] - u[m as usize]
    } else if k >= n {
        let m = (2 * (n - 1) - k).max(0);
        2.0 * u[(n - 1) as usize] - u[m as usize]
    } else {
        u[k as usize]
    }
}

/// Zeroth-order modified Bessel function of the first kind (power series).
fn bessel_i0(x: f64) -> f64 {
    let q = x * x / 4.0;
    let mut term = 1.0;
    let mut sum = 1.0;
    for k in 1..200 {
        term *= q / (k as f64 * k as f64);
        sum += term;
        if term < 1e-17 * sum {
            break;
        }
    }
    sum
}

/// Band-limited upsampling by `p` with a Kaiser-windowed sinc; `periodic` wraps indices,
/// otherwise the record is extended by point reflection and `pad` extra samples' worth of grid
/// are produced on each side.
fn sinc_upsample(u: &[f64], p: usize, periodic: bool, pad: usize) -> Vec<f64> {
    let n = u.len() as i64;
    let half = SINC_HALF_TAPS as i64;
    let i0b = bessel_i0(KAISER_BETA);
    // One normalised kernel per phase r/p, taps m = -half+1 ..= half (offset of sample from k).
    let kernels: Vec<Vec<f64>> = (0..p)
        .map(|r| {
            let frac = r as f64 / p as f64;
            let mut h: Vec<f64> = ((-half + 1)..=half)
                .map(|m| {
                    let x = frac - m as f64; // t - t_sample in samples
                    let w = (x / half as f64).abs();
                    if w >= 1.0 {
                        return 0.0;
                    }
                    let sinc = if x == 0.0 {
                        1.0
                    } else {
                        (std::f64::consts::PI * x).sin() / (std::f64::consts::PI * x)
                    };
                    sinc * bessel_i0(KAISER_BETA * (1.0 - w * w).sqrt()) / i0b
                })
                .collect();
            let s: f64 = h.iter().sum();
            h.iter_mut().for_each(|v| *v /= s);
            h
        })
        .collect();
    let pad = pad as i64;
    let (k_start, k_end) = if periodic { (0, n) } else { (-pad, n + pad) };
    // The samples every window needs, extended once.
    let first = k_start - half + 1;
    let ext: Vec<f64> = (first..k_end + half)
        .map(|k| {
            if periodic {
                u[k.rem_euclid(n) as usize]
            } else {
                reflected(u, k)
            }
        })
        .collect();
    let taps = 2 * SINC_HALF_TAPS;
    let mut out = Vec::with_capacity(((k_end - k_start) as usize) * p);
    for k in k_start..k_end {
        let s = (k - k_start) as usize;
        let window = &ext[s..s + taps];
        for h in &kernels {
            out.push(dot(h, window));
        }
    }
    out
}

/// Dot product with four independent sums (lets the compiler vectorise).
#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Exact periodic band-limited upsampling by `p` (both powers of two): zero-padded spectrum.
fn fft_upsample(u: &[f64], p: usize) -> Vec<f64> {
    let n = u.len();
    let big = n * p;
    let mut x: Vec<Complex<f64>> = u.iter().map(|&v| Complex::new(v, 0.0)).collect();
    crate::signal::fft_in_place(&mut x, false);
    let mut y = vec![Complex::new(0.0, 0.0); big];
    let half = n / 2;
    y[..half].copy_from_slice(&x[..half]);
    for k in 1..half {
        y[big - k] = x[n - k];
    }
    // The Nyquist bin is shared between +n/2 and -n/2, so the interpolant stays real.
    if n >= 2 && n.is_multiple_of(2) {
        y[half] = x[half] * 0.5;
        y[big - half] = x[half] * 0.5;
    }
    crate::signal::fft_in_place(&mut y, true);
    y.iter().map(|c| c.re / n as f64).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A periodic band-limited signal is reproduced exactly between its samples.
    #[test]
    fn periodic_bandlimited_is_exact_between_samples() {
        let n = 64;
        let ts = 0.01;
        let f = |t: f64| {
            (2.0 * std::f64::consts::PI * 3.0 * t / (n as f64 * ts)).sin()
                + 0.5 * (2.0 * std::f64::consts::PI * 17.0 * t / (n as f64 * ts) + 0.3).cos()
        };
        let u: Vec<f64> = (0..n).map(|k| f(k as f64 * ts)).collect();
        let inp = SampledInput::new(&u, ts, true, InputInterpolation::Bandlimited).unwrap();
        let mut worst: f64 = 0.0;
        for i in 0..(3 * n * 7) {
            let t = i as f64 * ts / 7.0 - 0.2;
            worst = worst.max((inp.at(t) - f(t)).abs());
        }
        // Limited by the cubic join of the fine grid, not by the FFT: the 17th harmonic sits
        // at 0.53 x Nyquist, where 4-point Lagrange on a 4x grid is good to about 3e-4.
        assert!(worst < 5e-4, "worst {worst}");
        // On the fine grid itself the interpolant is exact to round-off.
        for i in 0..(n * FINE_PER_SAMPLE) {
            let t = i as f64 * ts / FINE_PER_SAMPLE as f64;
            assert!((inp.at(t) - f(t)).abs() < 1e-12);
        }
    }

    /// A sine through the windowed sinc is reproduced to the window's accuracy, and the odd
    /// extension keeps the start (phase 0) exact; the end (arbitrary phase) is continuous but
    /// not band-limited, so the last few samples are excluded.
    #[test]
    fn sinc_reproduces_a_sine_including_the_start() {
        let ts = 1.0 / 750.0;
        let f = |t: f64| 40.0 * (2.0 * std::f64::consts::PI * 35.0 * t).sin();
        let u: Vec<f64> = (0..2000).map(|k| f(k as f64 * ts)).collect();
        let inp = SampledInput::new(&u, ts, false, InputInterpolation::Bandlimited).unwrap();
        let mut worst: f64 = 0.0;
        for i in 0..(1900 * 5) {
            let t = i as f64 * ts / 5.0 + 1e-5;
            worst = worst.max((inp.at(t) - f(t)).abs());
        }
        assert!(worst < 40.0 * 2e-4, "worst {worst}");
        let end = inp.at(1998.5 * ts);
        assert!((end - f(1998.5 * ts)).abs() < 40.0 * 1e-2, "end {end}");
    }

    /// A period that is not a power of two goes through the wrapped windowed sinc.
    #[test]
    fn periodic_bandlimited_without_power_of_two_length() {
        let n = 60;
        let ts = 0.01;
        let f = |t: f64| (2.0 * std::f64::consts::PI * 4.0 * t / (n as f64 * ts)).sin();
        let u: Vec<f64> = (0..n).map(|k| f(k as f64 * ts)).collect();
        let inp = SampledInput::new(&u, ts, true, InputInterpolation::Bandlimited).unwrap();
        let worst = (0..(2 * n * 7))
            .map(|i| i as f64 * ts / 7.0)
            .fold(0.0f64, |m, t| m.max((inp.at(t) - f(t)).abs()));
        assert!(worst < 1e-4, "worst {worst}");
    }

    #[test]
    fn linear_and_zoh() {
        let u = [0.0, 1.0, 3.0];
        let lin = SampledInput::new(&u, 0.5, false, InputInterpolation::Linear).unwrap();
        assert!((lin.at(0.25) - 0.5).abs() < 1e-12);
        assert!((lin.at(0.75) - 2.0).abs() < 1e-12);
        let zoh = SampledInput::new(&u, 0.5, false, InputInterpolation::Zoh).unwrap();
        assert_eq!(zoh.at(0.49), 0.0);
        assert_eq!(zoh.at(0.5), 1.0);
        assert_eq!(zoh.at(0.9), 1.0);
    }

    #[test]
    fn public_types_are_send_sync_clone() {
        fn check<T: Send + Sync + Clone>() {}
        check::<SampledInput>();
        check::<OdeError>();
        check::<BoucWenBenchmarkSpec>();
        check::<BoucWenBenchmark>();
        check::<Rk4Integrator>();
        check::<Dopri5Integrator>();
    }

    #[test]
    fn error_path_prefix() {
        let e = invalid("nu", 0.5, "must be >= 1").within("ode.bouc_wen_benchmark");
        assert_eq!(
            e.to_string(),
            "`ode.bouc_wen_benchmark.nu` = 0.5: must be >= 1"
        );
    }

    #[test]
    fn bad_inputs_are_named() {
        let e = SampledInput::new(&[1.0, f64::NAN], 0.1, false, InputInterpolation::Linear);
        assert!(matches!(e, Err(OdeError::NonFiniteInput { index: 1, .. })));
        let e = SampledInput::new(&[1.0], 0.0, false, InputInterpolation::Linear);
        assert!(matches!(e, Err(OdeError::SamplingPeriod { .. })));
        let e = SampledInput::new(&[], 0.1, false, InputInterpolation::Linear);
        assert!(matches!(e, Err(OdeError::EmptyInput)));
    }
}
