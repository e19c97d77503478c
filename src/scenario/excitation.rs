//! Excitation signals: what drives a plant in a scenario.
//!
//! ## References
//! - R. Pintelon, J. Schoukens, *System Identification: A Frequency Domain Approach*, 2nd ed.,
//!   Wiley-IEEE, 2012, ch. 5 (random-phase multisines).
//! - O. Nelles, *Nonlinear System Identification*, Springer, 2001, sec. 19.7 (APRBS: amplitude-
//!   modulated pseudo-random steps).

use crate::effect::noise::Gaussian;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// One excitation as written in a scenario file; `{"sine": {...}}`, `{"sum": [...]}`…
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ExcitationSpec {
    /// A * sin(2 pi f t + phase) + offset.
    Sine {
        amplitude: f64,
        frequency_hz: f64,
        #[serde(default)]
        phase_rad: f64,
        #[serde(default)]
        offset: f64,
    },
    /// A * exp(-t / decay_time_s) * sin(2 pi f t + phase) + offset: nested minor loops.
    DecayingSine {
        amplitude: f64,
        frequency_hz: f64,
        decay_time_s: f64,
        #[serde(default)]
        phase_rad: f64,
        #[serde(default)]
        offset: f64,
    },
    /// Random-phase multisine with a flat amplitude spectrum on the bins in [f_min, f_max] of a
    /// period `period_s` (default: the whole record), scaled to a peak `amplitude` or an `rms`.
    Multisine {
        #[serde(default)]
        amplitude: Option<f64>,
        #[serde(default)]
        rms: Option<f64>,
        f_min_hz: f64,
        f_max_hz: f64,
        #[serde(default)]
        period_s: Option<f64>,
        #[serde(default)]
        offset: f64,
    },
    /// Linear chirp from f0 to f1 over `duration_s` (default: the whole record).
    Chirp {
        amplitude: f64,
        f0_hz: f64,
        f1_hz: f64,
        #[serde(default)]
        duration_s: Option<f64>,
        #[serde(default)]
        offset: f64,
    },
    /// Held levels, `hold_s` each; the last level holds to the end (creep tests).
    Staircase { levels: Vec<f64>, hold_s: f64 },
    /// Symmetric triangle wave.
    Triangle {
        amplitude: f64,
        frequency_hz: f64,
        #[serde(default)]
        phase_rad: f64,
        #[serde(default)]
        offset: f64,
    },
    /// Amplitude-modulated random steps (APRBS): levels uniform in [offset - A, offset + A],
    /// each held for a duration uniform in [min_hold_s, max_hold_s].
    RandomSteps {
        amplitude: f64,
        min_hold_s: f64,
        max_hold_s: f64,
        #[serde(default)]
        offset: f64,
    },
    /// Band-limited Gaussian noise: white noise through a second-order Butterworth low-pass at
    /// `f_max_hz`, scaled to the standard deviation `rms` about `offset`.
    BandLimitedNoise {
        rms: f64,
        f_max_hz: f64,
        #[serde(default)]
        offset: f64,
    },
    /// A constant value.
    Constant { value: f64 },
    /// The sum of several excitations.
    Sum(Vec<ExcitationSpec>),
    /// Excitations one after another, each for its `duration_s` (local time restarts at 0);
    /// the last value holds to the end.
    Concat(Vec<Segment>),
    /// A column of a CSV file (path relative to the scenario file); its time column, if any,
    /// must have the scenario's sampling period.
    Csv { path: String, column: String },
}

/// One part of a concatenation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Segment {
    pub duration_s: f64,
    pub excitation: ExcitationSpec,
}

/// Context for generating: sampling, length, randomness, where relative files live.
pub struct Context<'a> {
    pub ts: f64,
    pub n: usize,
    pub seed: u64,
    pub base_dir: &'a std::path::Path,
}

/// A problem found while checking or generating, with the field path.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    pub field: String,
    pub value: String,
    pub rule: String,
    pub too_short: bool,
}

fn bad(field: &str, value: impl ToString, rule: &str) -> Problem {
    Problem {
        field: field.to_string(),
        value: value.to_string(),
        rule: rule.to_string(),
        too_short: false,
    }
}

fn fin(field: &str, name: &str, v: f64) -> Result<(), Problem> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(bad(
            &format!("{field}.{name}"),
            v,
            "must be a finite number",
        ))
    }
}

fn pos(field: &str, name: &str, v: f64) -> Result<(), Problem> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(bad(
            &format!("{field}.{name}"),
            v,
            "must be a finite number > 0",
        ))
    }
}

fn nyquist(field: &str, name: &str, f: f64, ts: f64) -> Result<(), Problem> {
    if f > 0.5 / ts {
        Err(bad(
            &format!("{field}.{name}"),
            f,
            &format!(
                "is above the Nyquist frequency {} Hz of the sampling period",
                0.5 / ts
            ),
        ))
    } else {
        Ok(())
    }
}

impl ExcitationSpec {
    /// Check parameters against the scenario's sampling and length; `field` is the path so far.
    ///
    /// Long on purpose: one short arm per excitation kind, read as a table of rules.
    pub fn check(&self, field: &str, ctx: &Context) -> Result<(), Problem> {
        let dur = ctx.n as f64 * ctx.ts;
        match self {
            ExcitationSpec::Sine {
                amplitude,
                frequency_hz,
                phase_rad,
                offset,
            }
            | ExcitationSpec::Triangle {
                amplitude,
                frequency_hz,
                phase_rad,
                offset,
            } => {
                let f = format!("{field}.{}", self.kind());
                fin(&f, "amplitude", *amplitude)?;
                pos(&f, "frequency_hz", *frequency_hz)?;
                nyquist(&f, "frequency_hz", *frequency_hz, ctx.ts)?;
                fin(&f, "phase_rad", *phase_rad)?;
                fin(&f, "offset", *offset)
            }
            ExcitationSpec::DecayingSine {
                amplitude,
                frequency_hz,
                decay_time_s,
                phase_rad,
                offset,
            } => {
                let f = format!("{field}.decaying_sine");
                fin(&f, "amplitude", *amplitude)?;
                pos(&f, "frequency_hz", *frequency_hz)?;
                nyquist(&f, "frequency_hz", *frequency_hz, ctx.ts)?;
                pos(&f, "decay_time_s", *decay_time_s)?;
                fin(&f, "phase_rad", *phase_rad)?;
                fin(&f, "offset", *offset)
            }
            ExcitationSpec::Multisine {
                amplitude,
                rms,
                f_min_hz,
                f_max_hz,
                period_s,
                offset,
            } => {
                let f = format!("{field}.multisine");
                match (amplitude, rms) {
                    (Some(a), None) => pos(&f, "amplitude", *a)?,
                    (None, Some(r)) => pos(&f, "rms", *r)?,
                    _ => {
                        return Err(bad(
                            &f,
                            "",
                            "give exactly one of `amplitude` (peak) and `rms`",
                        ))
                    }
                }
                if !(f_min_hz.is_finite() && *f_min_hz >= 0.0) {
                    return Err(bad(
                        &format!("{f}.f_min_hz"),
                        f_min_hz,
                        "must be a finite number >= 0",
                    ));
                }
                pos(&f, "f_max_hz", *f_max_hz)?;
                nyquist(&f, "f_max_hz", *f_max_hz, ctx.ts)?;
                if f_max_hz <= f_min_hz {
                    return Err(bad(
                        &format!("{f}.f_max_hz"),
                        f_max_hz,
                        "must be above f_min_hz",
                    ));
                }
                let p = period_s.unwrap_or(dur);
                pos(&f, "period_s", p)?;
                if p > dur + 0.5 * ctx.ts {
                    return Err(Problem {
                        too_short: true,
                        ..bad(
                            &format!("{f}.period_s"),
                            p,
                            &format!("the period is longer than the record ({dur} s)"),
                        )
                    });
                }
                if multisine_bins(*f_min_hz, *f_max_hz, p).is_empty() {
                    return Err(bad(
                        &f,
                        "",
                        &format!("no frequency line of the period grid (1/{p} Hz) falls in [f_min_hz, f_max_hz]; widen the band or lengthen the period"),
                    ));
                }
                fin(&f, "offset", *offset)
            }
            ExcitationSpec::Chirp {
                amplitude,
                f0_hz,
                f1_hz,
                duration_s,
                offset,
            } => {
                let f = format!("{field}.chirp");
                fin(&f, "amplitude", *amplitude)?;
                pos(&f, "f0_hz", *f0_hz)?;
                pos(&f, "f1_hz", *f1_hz)?;
                nyquist(&f, "f1_hz", *f1_hz, ctx.ts)?;
                nyquist(&f, "f0_hz", *f0_hz, ctx.ts)?;
                if let Some(d) = duration_s {
                    pos(&f, "duration_s", *d)?;
                }
                fin(&f, "offset", *offset)
            }
            ExcitationSpec::Staircase { levels, hold_s } => {
                let f = format!("{field}.staircase");
                if levels.is_empty() {
                    return Err(bad(
                        &format!("{f}.levels"),
                        "[]",
                        "needs at least one level",
                    ));
                }
                for (i, l) in levels.iter().enumerate() {
                    fin(&f, &format!("levels[{i}]"), *l)?;
                }
                pos(&f, "hold_s", *hold_s)?;
                let need = levels.len() as f64 * hold_s;
                if need > dur + 0.5 * ctx.ts {
                    return Err(Problem {
                        too_short: true,
                        ..bad(
                            &f,
                            "",
                            &format!("{} levels held {hold_s} s each need {need} s, the record is {dur} s", levels.len()),
                        )
                    });
                }
                Ok(())
            }
            ExcitationSpec::RandomSteps {
                amplitude,
                min_hold_s,
                max_hold_s,
                offset,
            } => {
                let f = format!("{field}.random_steps");
                fin(&f, "amplitude", *amplitude)?;
                pos(&f, "min_hold_s", *min_hold_s)?;
                pos(&f, "max_hold_s", *max_hold_s)?;
                if max_hold_s < min_hold_s {
                    return Err(bad(
                        &format!("{f}.max_hold_s"),
                        max_hold_s,
                        "must be >= min_hold_s",
                    ));
                }
                fin(&f, "offset", *offset)
            }
            ExcitationSpec::BandLimitedNoise {
                rms,
                f_max_hz,
                offset,
            } => {
                let f = format!("{field}.band_limited_noise");
                pos(&f, "rms", *rms)?;
                pos(&f, "f_max_hz", *f_max_hz)?;
                nyquist(&f, "f_max_hz", *f_max_hz, ctx.ts)?;
                fin(&f, "offset", *offset)
            }
            ExcitationSpec::Constant { value } => {
                fin(&format!("{field}.constant"), "value", *value)
            }
            ExcitationSpec::Sum(parts) => {
                if parts.is_empty() {
                    return Err(bad(
                        &format!("{field}.sum"),
                        "[]",
                        "needs at least one part",
                    ));
                }
                for (i, p) in parts.iter().enumerate() {
                    p.check(&format!("{field}.sum[{i}]"), ctx)?;
                }
                Ok(())
            }
            ExcitationSpec::Concat(parts) => {
                if parts.is_empty() {
                    return Err(bad(
                        &format!("{field}.concat"),
                        "[]",
                        "needs at least one segment",
                    ));
                }
                let mut total = 0.0;
                for (i, s) in parts.iter().enumerate() {
                    let f = format!("{field}.concat[{i}]");
                    pos(&f, "duration_s", s.duration_s)?;
                    total += s.duration_s;
                    let n = (s.duration_s / ctx.ts).round() as usize;
                    s.excitation.check(
                        &format!("{f}.excitation"),
                        &Context {
                            ts: ctx.ts,
                            n,
                            seed: ctx.seed,
                            base_dir: ctx.base_dir,
                        },
                    )?;
                }
                if total > dur + 0.5 * ctx.ts {
                    return Err(Problem {
                        too_short: true,
                        ..bad(
                            &format!("{field}.concat"),
                            "",
                            &format!("the segments last {total} s, the record is {dur} s"),
                        )
                    });
                }
                Ok(())
            }
            ExcitationSpec::Csv { path, column } => {
                let f = format!("{field}.csv");
                let p = ctx.base_dir.join(path);
                let rec = crate::data::read_csv(&p).map_err(|e| bad(&f, path, &e.to_string()))?;
                let col = rec
                    .column(column)
                    .map_err(|e| bad(&format!("{f}.column"), column, &e.to_string()))?;
                if col.len() < ctx.n {
                    return Err(Problem {
                        too_short: true,
                        ..bad(
                            &f,
                            path,
                            &format!("has {} rows, the scenario needs {}", col.len(), ctx.n),
                        )
                    });
                }
                if let Some(period) = rec
                    .sampling_period()
                    .map_err(|e| bad(&f, path, &e.to_string()))?
                {
                    if (period - ctx.ts).abs() > 1e-6 * ctx.ts {
                        return Err(bad(
                            &f,
                            path,
                            &format!("is sampled every {period} s but the scenario's sampling period is {} s", ctx.ts),
                        ));
                    }
                }
                Ok(())
            }
        }
    }

    fn kind(&self) -> &'static str {
        match self {
            ExcitationSpec::Sine { .. } => "sine",
            ExcitationSpec::Triangle { .. } => "triangle",
            _ => "excitation",
        }
    }

    /// Generate `ctx.n` samples; random parts draw from stream `stream` of the seed.
    /// Only call after [`ExcitationSpec::check`].
    ///
    /// Long on purpose: one arm per excitation kind, each its defining formula.
    pub fn generate(&self, ctx: &Context, stream: u64) -> Result<Vec<f64>, Problem> {
        let n = ctx.n;
        let ts = ctx.ts;
        let t = |k: usize| k as f64 * ts;
        Ok(match self {
            ExcitationSpec::Sine {
                amplitude,
                frequency_hz,
                phase_rad,
                offset,
            } => (0..n)
                .map(|k| offset + amplitude * (2.0 * PI * frequency_hz * t(k) + phase_rad).sin())
                .collect(),
            ExcitationSpec::DecayingSine {
                amplitude,
                frequency_hz,
                decay_time_s,
                phase_rad,
                offset,
            } => (0..n)
                .map(|k| {
                    offset
                        + amplitude
                            * (-t(k) / decay_time_s).exp()
                            * (2.0 * PI * frequency_hz * t(k) + phase_rad).sin()
                })
                .collect(),
            ExcitationSpec::Triangle {
                amplitude,
                frequency_hz,
                phase_rad,
                offset,
            } => (0..n)
                .map(|k| {
                    offset
                        + amplitude * 2.0 / PI
                            * (2.0 * PI * frequency_hz * t(k) + phase_rad).sin().asin()
                })
                .collect(),
            ExcitationSpec::Multisine {
                amplitude,
                rms,
                f_min_hz,
                f_max_hz,
                period_s,
                offset,
            } => {
                let p = period_s.unwrap_or(n as f64 * ts);
                let m = ((p / ts).round() as usize).max(1);
                let bins = multisine_bins(*f_min_hz, *f_max_hz, m as f64 * ts);
                let mut g = Gaussian::new(ctx.seed, stream);
                let phases: Vec<f64> = bins.iter().map(|_| 2.0 * PI * g.uniform()).collect();
                let mut one = vec![0.0; m];
                for (&b, &ph) in bins.iter().zip(&phases) {
                    let w = 2.0 * PI * b as f64 / m as f64;
                    // rotate a phasor: exact to rounding and fast
                    let (s, c) = w.sin_cos();
                    let (mut re, mut im) = (ph.cos(), ph.sin());
                    for v in one.iter_mut() {
                        *v += re;
                        let nre = re * c - im * s;
                        im = re * s + im * c;
                        re = nre;
                    }
                }
                let scale = match (amplitude, rms) {
                    (Some(a), _) => a / one.iter().fold(0.0f64, |m, v| m.max(v.abs())),
                    (_, Some(r)) => r / crate::metrics::rms(&one),
                    _ => 1.0,
                };
                (0..n).map(|k| offset + scale * one[k % m]).collect()
            }
            ExcitationSpec::Chirp {
                amplitude,
                f0_hz,
                f1_hz,
                duration_s,
                offset,
            } => {
                let d = duration_s.unwrap_or(n as f64 * ts);
                (0..n)
                    .map(|k| {
                        let tk = t(k).min(d);
                        offset
                            + amplitude
                                * (2.0 * PI * (f0_hz * tk + (f1_hz - f0_hz) * tk * tk / (2.0 * d)))
                                    .sin()
                    })
                    .collect()
            }
            ExcitationSpec::Staircase { levels, hold_s } => (0..n)
                .map(|k| {
                    let i = ((t(k) + 1e-9 * ts) / hold_s).floor() as usize;
                    levels[i.min(levels.len() - 1)]
                })
                .collect(),
            ExcitationSpec::RandomSteps {
                amplitude,
                min_hold_s,
                max_hold_s,
                offset,
            } => {
                let mut g = Gaussian::new(ctx.seed, stream);
                let mut out = Vec::with_capacity(n);
                while out.len() < n {
                    let level = offset + amplitude * (2.0 * g.uniform() - 1.0);
                    let hold = min_hold_s + (max_hold_s - min_hold_s) * g.uniform();
                    let len = ((hold / ts).round() as usize).max(1);
                    out.extend(std::iter::repeat_n(level, len.min(n - out.len())));
                }
                out
            }
            ExcitationSpec::BandLimitedNoise {
                rms,
                f_max_hz,
                offset,
            } => band_limited_noise(n, ts, *rms, *f_max_hz, *offset, ctx.seed, stream),
            ExcitationSpec::Constant { value } => vec![*value; n],
            ExcitationSpec::Sum(parts) => {
                let mut acc = vec![0.0; n];
                for (i, p) in parts.iter().enumerate() {
                    let x = p.generate(ctx, sub_stream(stream, i))?;
                    for (a, v) in acc.iter_mut().zip(x) {
                        *a += v;
                    }
                }
                acc
            }
            ExcitationSpec::Concat(parts) => {
                let mut out = Vec::with_capacity(n);
                for (i, s) in parts.iter().enumerate() {
                    let len = (s.duration_s / ts).round() as usize;
                    let sub = Context {
                        ts,
                        n: len,
                        seed: ctx.seed,
                        base_dir: ctx.base_dir,
                    };
                    out.extend(s.excitation.generate(&sub, sub_stream(stream, i))?);
                }
                out.truncate(n);
                let last = out.last().copied().unwrap_or(0.0);
                out.resize(n, last);
                out
            }
            ExcitationSpec::Csv { path, column } => {
                let p = ctx.base_dir.join(path);
                let rec =
                    crate::data::read_csv(&p).map_err(|e| bad("csv", path, &e.to_string()))?;
                let col = rec
                    .column(column)
                    .map_err(|e| bad("csv.column", column, &e.to_string()))?;
                col[..n.min(col.len())].to_vec()
            }
        })
    }
}

/// `n` samples of white Gaussian noise through a second-order Butterworth low-pass at `f_max`
/// (bilinear transform, pre-warped; started 20 time constants early so that the record begins
/// in steady state), scaled to standard deviation `rms` about `offset`.
fn band_limited_noise(
    n: usize,
    ts: f64,
    rms: f64,
    f_max: f64,
    offset: f64,
    seed: u64,
    stream: u64,
) -> Vec<f64> {
    let k = (PI * (f_max * ts).min(0.499)).tan();
    let norm = 1.0 / (1.0 + std::f64::consts::SQRT_2 * k + k * k);
    let (b0, b1, b2) = (k * k * norm, 2.0 * k * k * norm, k * k * norm);
    let a1 = 2.0 * (k * k - 1.0) * norm;
    let a2 = (1.0 - std::f64::consts::SQRT_2 * k + k * k) * norm;
    let warm = ((20.0 / (2.0 * PI * f_max * ts)).ceil() as usize).min(1_000_000);
    let mut g = Gaussian::new(seed, stream);
    let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
    let mut out = Vec::with_capacity(n);
    for i in 0..warm + n {
        let x = g.standard_normal();
        let y = b0 * x + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
        (x2, x1, y2, y1) = (x1, x, y1, y);
        if i >= warm {
            out.push(y);
        }
    }
    let m = crate::metrics::mean(&out);
    let sd = crate::metrics::std_dev(&out);
    let scale = if sd > 0.0 { rms / sd } else { 0.0 };
    out.iter().map(|v| offset + (v - m) * scale).collect()
}

/// Bin indices k (frequency k / period) inside [f_min, f_max], skipping DC.
fn multisine_bins(f_min: f64, f_max: f64, period: f64) -> Vec<usize> {
    let lo = (f_min * period).ceil().max(1.0) as usize;
    let hi = (f_max * period).floor() as usize;
    (lo..=hi).collect()
}

fn sub_stream(stream: u64, i: usize) -> u64 {
    stream.wrapping_mul(31).wrapping_add(i as u64 + 1)
}
