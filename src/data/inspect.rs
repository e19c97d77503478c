//! # Inspect: what a record holds, before any model
//!
//! A lab record can carry what no model should learn: a glitch, a dropout (a logger repeating
//! its last value), a sensor clipping at its limit, a coarse quantisation, a pause, a drifting
//! offset, an input that never reverses (no loop to identify). [`inspect`] finds each, with the
//! file's lines and what to do, and summarises what the record offers to modelling: sampling,
//! ranges, noise, reversals, the amplitudes and rates the input visits.
//!
//! The checks are robust (medians and median absolute deviations) and read the effect library
//! where it already knows the thing: a clipping limit is the `saturation` effect's
//! ([`crate::effect::saturation::detect`]), the noise level its estimate.

use super::{DataError, IoRecord, Record, TimeSteps};
use crate::effect::saturation;
use crate::metrics::{quantile, quantile_select};
use serde::Serialize;

/// One thing found, with where and what to do.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Finding {
    /// `gap`, `jitter`, `outlier`, `dropout`, `clipping`, `quantisation`, `drift`,
    /// `no_reversal`.
    pub kind: &'static str,
    /// The column (none: the record's sampling).
    pub column: Option<String>,
    /// How many samples.
    pub count: usize,
    /// The file's lines of the first few (at most 10).
    pub lines: Vec<usize>,
    pub message: String,
    pub advice: String,
}

impl Finding {
    /// One line: the kind, the column, what, the lines and what to do.
    pub fn summary(&self) -> String {
        format!(
            "{}{}: {}{}; {}",
            self.kind,
            self.column
                .as_ref()
                .map(|c| format!(" in `{c}`"))
                .unwrap_or_default(),
            self.message,
            if self.lines.is_empty() {
                String::new()
            } else {
                format!(
                    " (line{} {})",
                    if self.lines.len() > 1 { "s" } else { "" },
                    self.lines
                        .iter()
                        .map(usize::to_string)
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            },
            self.advice
        )
    }
}

/// One column's summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ColumnSummary {
    pub name: String,
    /// `input`, `output` or `other`.
    pub role: &'static str,
    pub min: f64,
    pub max: f64,
    /// Noise level (robust, from second differences).
    pub noise: f64,
    /// Reversals of an input (direction changes after travelling 1 % of its range), and the
    /// travel between them (median and largest) and the largest rate (units/s).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reversals: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub median_travel: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_rate: Option<f64>,
}

/// What a record holds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Inspection {
    pub samples: usize,
    /// Median time step (s), when the record has a time column.
    pub sampling_period: Option<f64>,
    /// Largest deviation of a step from the median, as a share of it.
    pub jitter: Option<f64>,
    pub columns: Vec<ColumnSummary>,
    pub findings: Vec<Finding>,
    /// The longest stretch without a gap or a dropout: what a command can model in one piece.
    pub usable: Stretch,
}

/// A stretch of a record, with the file's lines of its first and last samples.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Stretch {
    pub samples: usize,
    pub first_line: usize,
    pub last_line: usize,
}

/// The longest run of rows in `0..n` that `cuts` leave (each cut: the rows `a..b` out, and a
/// break before `a`).
fn longest_stretch(rec: &Record, n: usize, cuts: &mut [(usize, usize)]) -> Stretch {
    cuts.sort_unstable();
    let (mut best, mut from) = ((0, 0), 0);
    for &(a, b) in cuts.iter().chain(std::iter::once(&(n, n))) {
        if a > from && a - from > best.1 - best.0 {
            best = (from, a);
        }
        from = from.max(b);
    }
    Stretch {
        samples: best.1 - best.0,
        first_line: rec.format.line_of(best.0),
        last_line: rec.format.line_of(best.1.max(1) - 1),
    }
}

/// A sample farther than this many robust deviations from its neighbours' median, and than
/// [`OUTLIER_RANGE`] of the column's central range, while the samples around it agree with
/// each other, is an outlier.
pub const OUTLIER_SIGMAS: f64 = 12.0;
/// See [`OUTLIER_SIGMAS`].
pub const OUTLIER_RANGE: f64 = 0.2;
/// An outlier beyond this many central ranges is gross (a glitch, not a measurement).
pub const GROSS_RANGES: f64 = 10.0;
/// A run of one repeated value this long (and 0.1 % of the record) is a dropout, in a column
/// that otherwise seldom repeats.
pub const DROPOUT_RUN: usize = 20;
/// A drift above this share of the output's range over the record is reported.
pub const DRIFT_SHARE: f64 = 0.02;

/// A column on a grid of more levels than this (16 bits) is not reported as quantised.
pub const QUANTISATION_LEVELS: usize = 65_537;

/// The distinct values of `x`, sorted; empty when there are more than `most`.
fn distinct_levels(x: &[f64], most: usize) -> Vec<f64> {
    let mut seen = std::collections::HashSet::new();
    for v in x {
        // -0 and 0 are one level
        if seen.insert((v + 0.0).to_bits()) && seen.len() > most {
            return Vec::new();
        }
    }
    let mut levels: Vec<f64> = seen.into_iter().map(f64::from_bits).collect();
    levels.sort_unstable_by(f64::total_cmp);
    levels
}

/// Lines of the first few of `rows`.
fn lines(rec: &Record, rows: &[usize]) -> Vec<usize> {
    rows.iter()
        .take(10)
        .map(|&r| rec.format.line_of(r))
        .collect()
}

/// Inspect `rec`; `inputs` and `outputs` name the roles (the other columns but time are
/// `other`).
pub fn inspect(rec: &Record, inputs: &[String], outputs: &[String]) -> Inspection {
    examine(rec, inputs, outputs).inspection
}

/// The outliers of one column: all of them, and the gross ones.
struct ColumnOutliers {
    column: usize,
    rows: Vec<usize>,
    gross: Vec<usize>,
}

/// What [`inspect`] finds, with the columns whose outliers are repaired (see
/// [`Outliers::Repair`]).
struct Examined {
    inspection: Inspection,
    cleaned: Vec<Vec<f64>>,
    outliers: Vec<ColumnOutliers>,
}

fn examine(rec: &Record, inputs: &[String], outputs: &[String]) -> Examined {
    let n = rec.columns.first().map_or(0, Vec::len);
    let mut outliers = Vec::new();
    // rows out of the usable stretch: gaps (a break before the row), dropouts
    let mut cuts: Vec<(usize, usize)> = Vec::new();
    let mut findings = Vec::new();
    let time = rec.time_column().map(str::to_string);
    let (mut sampling_period, mut jitter) = (None, None);
    if let Some(tn) = &time {
        let t = &rec.columns[rec.names.iter().position(|x| x == tn).unwrap_or(0)];
        if t.len() >= 2 {
            let st = TimeSteps::of(t);
            sampling_period = Some(st.median);
            jitter = (st.median > 0.0).then(|| st.jitter.0 / st.median);
            cuts.extend(st.gaps.iter().map(|g| (g.0, g.0)));
            if !st.gaps.is_empty() {
                let rows: Vec<usize> = st.gaps.iter().map(|g| g.0).collect();
                findings.push(Finding {
                    kind: "gap",
                    column: Some(tn.clone()),
                    count: st.gaps.len(),
                    lines: lines(rec, &rows),
                    message: format!(
                        "{} gap(s) in time, the longest {:.4} s ({:.0} steps of {:.3e} s)",
                        st.gaps.len(),
                        st.gaps.iter().map(|g| g.1).fold(0.0, f64::max),
                        st.gaps.iter().map(|g| g.1).fold(0.0, f64::max) / st.median,
                        st.median
                    ),
                    advice: "split the record at its gaps (`hystbench split`)".into(),
                });
            }
            if jitter.is_some_and(|j| j > 0.01) && st.gaps.len() < t.len() / 2 {
                findings.push(Finding {
                    kind: "jitter",
                    column: Some(tn.clone()),
                    count: 1,
                    lines: lines(rec, &[st.jitter.1]),
                    message: format!(
                        "time steps vary by up to {:.1} % of the median step",
                        100.0 * jitter.unwrap_or(0.0)
                    ),
                    advice: "resample onto a uniform grid (`hystbench split` does)".into(),
                });
            }
        }
    }
    let ts = sampling_period.unwrap_or(1.0);
    let mut columns = Vec::new();
    // the columns with their outliers repaired, for the checks
    // that an outlier would blind (clipping, quantisation, drift)
    let mut cleaned: Vec<Vec<f64>> = rec.columns.clone();
    for (ci, (name, x)) in rec.names.iter().zip(&rec.columns).enumerate() {
        if Some(name) == time.as_ref() {
            continue;
        }
        let role = if inputs.contains(name) {
            "input"
        } else if outputs.contains(name) {
            "output"
        } else {
            "other"
        };
        let (min, max) = x
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let mut work = x.clone();
        let central = (quantile_select(&mut work, 0.99) - quantile_select(&mut work, 0.01))
            .max(f64::MIN_POSITIVE);
        let noise = saturation::noise_level(x);
        let c = Some(name.clone());
        // outliers: far from the median of their neighbours
        let dev: Vec<f64> = (0..n)
            .map(|k| {
                let lo = k.saturating_sub(2);
                let hi = (k + 3).min(n);
                let mut w = [0.0; 5];
                let w = &mut w[..hi - lo];
                w.copy_from_slice(&x[lo..hi]);
                w.sort_by(f64::total_cmp);
                x[k] - w[w.len() / 2]
            })
            .collect();
        work.iter_mut().zip(&dev).for_each(|(w, d)| *w = d.abs());
        let sigma = 1.4826 * quantile_select(&mut work, 0.5);
        // ... and isolated: the samples around it (a glitch of one or two samples) agree with
        // each other (a fast random-step excitation moves on instead)
        let isolated = |k: usize| {
            let agree = (x[k - 1] - x[k + 1])
                .abs()
                .min((x[k - 2] - x[k + 1]).abs())
                .min((x[k - 1] - x[k + 2]).abs());
            agree < 0.25 * dev[k].abs()
        };
        let out: Vec<usize> = (2..n.saturating_sub(2))
            .filter(|&k| {
                dev[k].abs() > OUTLIER_SIGMAS * sigma
                    && dev[k].abs() > OUTLIER_RANGE * central
                    && isolated(k)
            })
            .collect();
        // each replaced by the straight line between the nearest good samples either side
        for (i, &k) in out.iter().enumerate() {
            let mut a = k - 1;
            while a > 0 && out[..i].binary_search(&a).is_ok() {
                a -= 1;
            }
            let b = out[i + 1..]
                .iter()
                .zip(k + 1..)
                .take_while(|(o, r)| *o == r)
                .last()
                .map_or(k + 1, |(o, _)| o + 1);
            let (xa, xb) = (x[a], x.get(b).copied().unwrap_or(x[a]));
            cleaned[ci][k] = xa + (xb - xa) * (k - a) as f64 / (b - a) as f64;
        }
        let x_raw = x;
        let x = &cleaned[ci];
        if !out.is_empty() {
            let gross: Vec<usize> = out
                .iter()
                .copied()
                .filter(|&k| dev[k].abs() > GROSS_RANGES * central)
                .collect();
            findings.push(Finding {
                kind: "outlier",
                column: c.clone(),
                count: out.len(),
                lines: lines(rec, &out),
                message: format!(
                    "{} sample(s) far from their neighbours ({} of them gross, beyond {GROSS_RANGES} times the column's range), the largest {:.4e}",
                    out.len(),
                    gross.len(),
                    out.iter().map(|&k| x_raw[k]).fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m })
                ),
                advice: "repair these lines (a glitch of the logger) before modelling, by hand or with `--outliers repair` on the modelling command (each replaced by the line between its good neighbours): a model fitted through them learns the glitch".into(),
            });
            outliers.push(ColumnOutliers {
                column: ci,
                rows: out,
                gross,
            });
        }
        // clipping: an output piled up at an extreme (the saturation effect's reading) while
        // an input keeps moving there (a held staircase is not a clipped sensor)
        let cens = if role == "output" {
            saturation::detect(x)
        } else {
            crate::effect::fitting::Censoring {
                lower: None,
                upper: None,
                tolerance: 0.0,
            }
        };
        let mut clip_limits = Vec::new();
        for (limit, side) in [(cens.lower, "lower"), (cens.upper, "upper")] {
            if let Some(l) = limit {
                let rows: Vec<usize> = (0..n)
                    .filter(|&k| (x[k] - l).abs() <= cens.tolerance)
                    .collect();
                // in each stretch at the limit an input goes on and comes back (its extreme in
                // the stretch's middle); a loop's flat turn (a play) starts at the reversal
                let mut stretches = Vec::new();
                let mut start = 0;
                for i in 1..=rows.len() {
                    if i == rows.len() || rows[i] != rows[i - 1] + 1 {
                        if i - start >= 3 {
                            stretches.push((rows[start], rows[i - 1]));
                        }
                        start = i;
                    }
                }
                let clipped_like = |u: &[f64], (a, b): (usize, usize)| {
                    let (mut far, mut at) = (0.0, a);
                    for k in a..=b {
                        if (u[k] - u[a]).abs() > far {
                            (far, at) = ((u[k] - u[a]).abs(), k);
                        }
                    }
                    let len = (b - a) as f64;
                    let span = u.iter().fold(f64::NEG_INFINITY, |m, v| m.max(*v))
                        - u.iter().fold(f64::INFINITY, |m, v| m.min(*v));
                    far > 0.002 * span
                        && (at - a) as f64 > 0.2 * len
                        && ((b - at) as f64) > 0.2 * len
                };
                let moving = rows.len() >= 10
                    && rec.names.iter().zip(&cleaned).any(|(nm, u)| {
                        inputs.contains(nm)
                            && 2 * stretches.iter().filter(|&&st| clipped_like(u, st)).count()
                                >= stretches.len().max(1)
                    });
                if !moving {
                    continue;
                }
                clip_limits.push(l);
                findings.push(Finding {
                    kind: "clipping",
                    column: c.clone(),
                    count: rows.len(),
                    lines: lines(rec, &rows),
                    message: format!(
                        "{:.2} % of the samples sit at the {side} limit {l:.6}: clipped",
                        100.0 * rows.len() as f64 / n as f64
                    ),
                    advice: "model the sensor (`fit --effects ...,saturation`) or leave the clipped samples out".into(),
                });
            }
        }
        // dropouts: long runs of one value in a column that seldom repeats
        let repeats = x.windows(2).filter(|w| w[0] == w[1]).count();
        if (repeats as f64) < 0.1 * n as f64 {
            let need = DROPOUT_RUN.max(n / 1000);
            let mut runs = Vec::new();
            let mut start = 0;
            for k in 1..=n {
                if k == n || x[k] != x[start] {
                    let at_limit = clip_limits
                        .iter()
                        .any(|l| (x[start] - l).abs() <= cens.tolerance);
                    if k - start >= need && !at_limit {
                        runs.push((start, k - start));
                    }
                    start = k;
                }
            }
            // the run's first sample may be the last good one
            cuts.extend(runs.iter().map(|r| (r.0 + 1, r.0 + r.1)));
            if !runs.is_empty() {
                let rows: Vec<usize> = runs.iter().map(|r| r.0).collect();
                findings.push(Finding {
                    kind: "dropout",
                    column: c.clone(),
                    count: runs.iter().map(|r| r.1).sum(),
                    lines: lines(rec, &rows),
                    message: format!(
                        "{} run(s) of one repeated value, the longest {} samples: the sensor or logger stopped updating",
                        runs.len(),
                        runs.iter().map(|r| r.1).max().unwrap_or(0)
                    ),
                    advice: "cut these stretches out (`hystbench split` after removing them) or repair them".into(),
                });
            }
        }
        // quantisation: values on a grid of a step well above rounding, at most
        // QUANTISATION_LEVELS of them (counted until there are more)
        let uniq = distinct_levels(x, QUANTISATION_LEVELS);
        if uniq.len() >= 3 {
            let steps: Vec<f64> = uniq.windows(2).map(|w| w[1] - w[0]).collect();
            let q = steps.iter().copied().fold(f64::INFINITY, f64::min);
            let range = uniq[uniq.len() - 1] - uniq[0];
            let on_grid = steps
                .iter()
                .filter(|&&d| ((d / q) - (d / q).round()).abs() < 0.01)
                .count();
            if q > 1e-9 * range.abs()
                && range / q < QUANTISATION_LEVELS as f64
                && on_grid as f64 >= 0.99 * steps.len() as f64
                && (uniq.len() as f64) < 0.5 * n as f64
            {
                findings.push(Finding {
                    kind: "quantisation",
                    column: c.clone(),
                    count: uniq.len(),
                    lines: Vec::new(),
                    message: format!(
                        "values on a grid of {q:.4e} ({} levels over the range, {:.1} bits)",
                        (range / q).round() as u64 + 1,
                        (range / q + 1.0).log2()
                    ),
                    advice: format!(
                        "a model cannot be more precise than {:.4e} RMS (q / sqrt(12)); a finer converter, or averaging, helps",
                        q / 12f64.sqrt()
                    ),
                });
            }
        }
        let mut summary = ColumnSummary {
            name: name.clone(),
            role,
            min,
            max,
            noise,
            reversals: None,
            median_travel: None,
            max_rate: None,
        };
        if role == "input" {
            let (count, travel) = reversals(x, 0.01 * (max - min));
            summary.reversals = Some(count);
            let mut tr = travel.clone();
            tr.sort_by(f64::total_cmp);
            summary.median_travel = (!tr.is_empty()).then(|| quantile(&tr, 0.5));
            summary.max_rate = Some(
                x.windows(2)
                    .map(|w| ((w[1] - w[0]) / ts).abs())
                    .fold(0.0, f64::max),
            );
            if count == 0 {
                findings.push(Finding {
                    kind: "no_reversal",
                    column: c.clone(),
                    count: n,
                    lines: Vec::new(),
                    message: "the input never reverses: no hysteresis loop to identify".into(),
                    advice:
                        "record an excitation that goes up and down (sines, triangles, multisines)"
                            .into(),
                });
            }
        }
        columns.push(summary);
    }
    // drift: an output's slow trend that its inputs do not explain
    if let Some(tn) = &time {
        let t = rec.column(tn).map(<[f64]>::to_vec).unwrap_or_default();
        let ins: Vec<&Vec<f64>> = rec
            .names
            .iter()
            .zip(&cleaned)
            .filter(|(nm, _)| inputs.contains(nm))
            .map(|(_, x)| x)
            .collect();
        for (name, y) in rec.names.iter().zip(&cleaned) {
            if !outputs.contains(name) || n < 20 {
                continue;
            }
            // a drift runs through the record: the trend of each half (over the whole span)
            // agrees with the whole's (a step between a rest and the excitation does not)
            let range = columns
                .iter()
                .find(|c| &c.name == name)
                .map_or(1.0, |c| c.max - c.min);
            if let Some(Drift {
                whole: (d, rms),
                halves: (a, b),
            }) = drift(y, &ins, &t)
            {
                let through = d.abs() > 2.0 * rms
                    && a.signum() == d.signum()
                    && b.signum() == d.signum()
                    && a.abs().min(b.abs()) > 0.5 * DRIFT_SHARE * range;
                if d.abs() > DRIFT_SHARE * range && through {
                    findings.push(Finding {
                        kind: "drift",
                        column: Some(name.clone()),
                        count: n,
                        lines: Vec::new(),
                        message: format!(
                            "a slow trend of {d:.4e} over the record ({:.1} % of the range) that the inputs do not explain at once (a drift, or a slow response such as creep)",
                            100.0 * d.abs() / range
                        ),
                        advice: "fit it (`fit --effects ...,drift` or `...,creep`; `diagnose` tells which), or remove the offset trend before modelling".into(),
                    });
                }
            }
        }
    }
    Examined {
        inspection: Inspection {
            samples: n,
            sampling_period,
            jitter,
            columns,
            findings,
            usable: longest_stretch(rec, n, &mut cuts),
        },
        cleaned,
        outliers,
    }
}

/// What a modelling command does with the outliers of its record.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Outliers {
    /// Refuse a record with gross outliers (beyond [`GROSS_RANGES`] times a column's range);
    /// warn of the others.
    #[default]
    Refuse,
    /// Replace every outlier by the straight line between the nearest good samples either
    /// side.
    Repair,
    /// Model the record as it is.
    Keep,
}

impl Outliers {
    pub const NAMES: &'static [&'static str] = &["refuse", "repair", "keep"];
}

impl std::str::FromStr for Outliers {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "refuse" => Ok(Outliers::Refuse),
            "repair" => Ok(Outliers::Repair),
            "keep" => Ok(Outliers::Keep),
            _ => Err(format!(
                "unknown outlier policy `{s}`; one of: {}",
                Outliers::NAMES.join(", ")
            )),
        }
    }
}

/// What [`screen`] found and did.
#[derive(Debug, Clone, PartialEq)]
pub struct Screening {
    /// The findings left to warn of (repaired outliers are not among them).
    pub findings: Vec<Finding>,
    /// Samples repaired, and the file's lines of the first few.
    pub repaired: usize,
    pub repaired_lines: Vec<usize>,
}

/// The checks of [`inspect`] before modelling: a record with gross outliers is refused (the
/// error names the line, the column and the value) unless `policy` repairs or keeps them;
/// repaired outliers are replaced in `rec`.
pub fn screen(
    rec: &mut Record,
    inputs: &[String],
    outputs: &[String],
    policy: Outliers,
) -> Result<Screening, DataError> {
    let Examined {
        inspection,
        cleaned,
        outliers,
    } = examine(rec, inputs, outputs);
    let mut findings = inspection.findings;
    match policy {
        Outliers::Keep => Ok(Screening {
            findings,
            repaired: 0,
            repaired_lines: Vec::new(),
        }),
        Outliers::Refuse => match outliers.iter().find(|o| !o.gross.is_empty()) {
            Some(o) => {
                let k = o.gross[0];
                let all: usize = outliers.iter().map(|o| o.gross.len()).sum();
                Err(DataError::GrossOutlier {
                    path: rec.path.clone(),
                    line: rec.format.line_of(k),
                    column: rec.names[o.column].clone(),
                    value: rec.columns[o.column][k],
                    count: all,
                    lines: lines(rec, &o.gross)
                        .iter()
                        .map(usize::to_string)
                        .collect::<Vec<_>>()
                        .join(", "),
                })
            }
            None => Ok(Screening {
                findings,
                repaired: 0,
                repaired_lines: Vec::new(),
            }),
        },
        Outliers::Repair => {
            findings.retain(|f| f.kind != "outlier");
            let mut rows = Vec::new();
            for o in &outliers {
                for &k in &o.rows {
                    rec.columns[o.column][k] = cleaned[o.column][k];
                }
                rows.extend_from_slice(&o.rows);
            }
            rows.sort_unstable();
            Ok(Screening {
                findings,
                repaired: rows.len(),
                repaired_lines: lines(rec, &rows),
            })
        }
    }
}

/// The columns `select` picks from `rec` for modelling, after the checks of [`screen`]: what a
/// modelling command reads (the command says the findings); with repaired outliers, the
/// columns of the repaired record.
pub fn screened<E: From<DataError>>(
    mut rec: Record,
    policy: Outliers,
    select: impl Fn(&Record) -> Result<IoRecord, E>,
) -> Result<(IoRecord, Screening), E> {
    let io = select(&rec)?;
    let s = screen(&mut rec, &io.input_names(), &io.output_names(), policy)?;
    if s.repaired == 0 {
        return Ok((io, s));
    }
    Ok((select(&rec)?, s))
}

/// Reversals of `x` (direction changes after a move back of more than `band`, the diagnosis'
/// own tracking, [`crate::diagnose::residual::reversal_travel`]) and the travel of each
/// finished stroke, from the start or the last turning point to the next.
fn reversals(x: &[f64], band: f64) -> (usize, Vec<f64>) {
    let motion = crate::diagnose::residual::reversal_travel(x, band);
    let mut turns: Vec<f64> = x.first().copied().into_iter().collect();
    for k in 1..motion.len() {
        let ((before, _), (dir, travel)) = (motion[k - 1], motion[k]);
        if before != 0.0 && dir != before {
            // the extreme just left: the sample stands `travel` past it in the new direction
            turns.push(x[k] - dir * travel);
        }
    }
    let travel = turns.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    (turns.len().saturating_sub(1), travel)
}

/// A trend fitted over the record and over each half.
struct Drift {
    /// The change over the record, and the fit's residual RMS.
    whole: (f64, f64),
    /// The trend of each half, as a change over the whole record.
    halves: (f64, f64),
}

/// The regressors of [`drift`] at one sample: 1, t, and per input u, u^2, u^3 and nine plays.
struct DriftRow<'a> {
    inputs: &'a [&'a Vec<f64>],
    amps: Vec<f64>,
    plays: Vec<crate::effect::play::Play>,
    row: Vec<f64>,
}

const DRIFT_PLAYS: [f64; 9] = [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.85];

impl<'a> DriftRow<'a> {
    fn new(inputs: &'a [&'a Vec<f64>]) -> Self {
        let amps: Vec<f64> = inputs
            .iter()
            .map(|u| u.iter().fold(0.0f64, |m, v| m.max(v.abs())))
            .collect();
        let plays = amps
            .iter()
            .flat_map(|&amp| {
                DRIFT_PLAYS
                    .iter()
                    .map(move |share| crate::effect::play::Play::new(share * amp, 0.0))
            })
            .collect();
        DriftRow {
            inputs,
            row: vec![0.0; 2 + inputs.len() * (3 + DRIFT_PLAYS.len())],
            amps,
            plays,
        }
    }

    /// The row of sample `k` (samples in order: the plays step).
    fn at(&mut self, k: usize, time: f64) -> &[f64] {
        use crate::effect::Operator;
        self.row[0] = 1.0;
        self.row[1] = time;
        let mut c = 2;
        for (i, u) in self.inputs.iter().enumerate() {
            let (v, amp) = (u[k], self.amps[i]);
            self.row[c] = v;
            self.row[c + 1] = v * v / amp.max(f64::MIN_POSITIVE);
            self.row[c + 2] = v * v * v / (amp * amp).max(f64::MIN_POSITIVE);
            c += 3;
            for play in &mut self.plays[i * DRIFT_PLAYS.len()..(i + 1) * DRIFT_PLAYS.len()] {
                self.row[c] = play.step(v);
                c += 1;
            }
        }
        &self.row
    }
}

/// The change over the record of an output's trend in time that a fit on its inputs leaves:
/// least squares of y on [1, t, and per input u, u^2, u^3 and nine plays of it], over the
/// record and over each half (with the whole record's time scale).
/// Also the fit's residual RMS: a trend is only told from a misfit that happens to follow the
/// excitation in time (a chirp) when it stands above the residual.
/// Normal equations accumulated sample by sample: memory constant, time linear in the record.
fn drift(y: &[f64], inputs: &[&Vec<f64>], t: &[f64]) -> Option<Drift> {
    let n = y.len();
    let span = t.last()? - t.first()?;
    if span <= 0.0 {
        return None;
    }
    let p = 2 + inputs.len() * (3 + DRIFT_PLAYS.len());
    let h = n / 2;
    // packed upper triangles and right-hand sides of the two halves
    let mut ata = [vec![0.0; p * (p + 1) / 2], vec![0.0; p * (p + 1) / 2]];
    let mut atb = [vec![0.0; p], vec![0.0; p]];
    let mut rows = DriftRow::new(inputs);
    for k in 0..n {
        let half = usize::from(k >= h);
        let r = rows.at(k, (t[k] - t[0]) / span);
        let (a, b) = (&mut ata[half], &mut atb[half]);
        let mut idx = 0;
        for i in 0..p {
            let ri = r[i];
            b[i] += ri * y[k];
            for &rj in &r[i..] {
                a[idx] += ri * rj;
                idx += 1;
            }
        }
    }
    let solve = |parts: &[usize]| {
        let mut m = nalgebra::DMatrix::<f64>::zeros(p, p);
        let mut v = nalgebra::DVector::<f64>::zeros(p);
        for &part in parts {
            let mut idx = 0;
            for i in 0..p {
                v[i] += atb[part][i];
                for j in i..p {
                    m[(i, j)] += ata[part][idx];
                    if j != i {
                        m[(j, i)] += ata[part][idx];
                    }
                    idx += 1;
                }
            }
        }
        m.svd(true, true).solve(&v, 1e-12).ok()
    };
    let sol = solve(&[0, 1])?;
    let (first, second) = (solve(&[0])?, solve(&[1])?);
    let mut rows = DriftRow::new(inputs);
    let rss: f64 = (0..n)
        .map(|k| {
            let r = rows.at(k, (t[k] - t[0]) / span);
            let f: f64 = r.iter().zip(sol.iter()).map(|(a, b)| a * b).sum();
            (f - y[k]).powi(2)
        })
        .sum();
    Some(Drift {
        whole: (sol[1], (rss / n as f64).sqrt()),
        halves: (first[1], second[1]),
    })
}
