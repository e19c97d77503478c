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

use super::{Record, TimeSteps};
use crate::effect::saturation;
use crate::metrics::quantile;
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
    let n = rec.columns.first().map_or(0, Vec::len);
    let mut findings = Vec::new();
    let time = rec.time_column().map(str::to_string);
    let (mut sampling_period, mut jitter) = (None, None);
    if let Some(tn) = &time {
        let t = &rec.columns[rec.names.iter().position(|x| x == tn).unwrap_or(0)];
        if t.len() >= 2 {
            let st = TimeSteps::of(t);
            sampling_period = Some(st.median);
            jitter = (st.median > 0.0).then(|| st.jitter.0 / st.median);
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
    // the columns with their outliers replaced by their neighbours' median, for the checks
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
        let mut sorted = x.clone();
        sorted.sort_by(f64::total_cmp);
        let (min, max) = (sorted[0], sorted[n - 1]);
        let central = (quantile(&sorted, 0.99) - quantile(&sorted, 0.01)).max(f64::MIN_POSITIVE);
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
        let mut ad: Vec<f64> = dev.iter().map(|d| d.abs()).collect();
        ad.sort_by(f64::total_cmp);
        let sigma = 1.4826 * quantile(&ad, 0.5);
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
        for &k in &out {
            cleaned[ci][k] = x[k] - dev[k];
        }
        let x_raw = x;
        let x = &cleaned[ci];
        if !out.is_empty() {
            let gross = out
                .iter()
                .filter(|&&k| dev[k].abs() > GROSS_RANGES * central)
                .count();
            findings.push(Finding {
                kind: "outlier",
                column: c.clone(),
                count: out.len(),
                lines: lines(rec, &out),
                message: format!(
                    "{} sample(s) far from their neighbours ({} of them gross, beyond {GROSS_RANGES} times the column's range), the largest {:.4e}",
                    out.len(),
                    gross,
                    out.iter().map(|&k| x_raw[k]).fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m })
                ),
                advice: "remove or repair these lines (a glitch of the logger) before modelling: a model fitted through them learns the glitch".into(),
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
        // quantisation: values on a grid of a step well above rounding
        let mut uniq = x.clone();
        uniq.sort_by(f64::total_cmp);
        uniq.dedup();
        if uniq.len() >= 3 {
            let steps: Vec<f64> = uniq.windows(2).map(|w| w[1] - w[0]).collect();
            let q = steps.iter().copied().fold(f64::INFINITY, f64::min);
            let range = uniq[uniq.len() - 1] - uniq[0];
            let on_grid = steps
                .iter()
                .filter(|&&d| ((d / q) - (d / q).round()).abs() < 0.01)
                .count();
            if q > 1e-9 * range.abs()
                && range / q <= 65_536.0
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
            let h = n / 2;
            let first: Vec<Vec<f64>> = ins.iter().map(|u| u[..h].to_vec()).collect();
            let second: Vec<Vec<f64>> = ins.iter().map(|u| u[h..].to_vec()).collect();
            let part = |ys: &[f64], us: &[Vec<f64>], ts: &[f64]| {
                let r: Vec<&Vec<f64>> = us.iter().collect();
                drift(ys, &r, ts).map(|d| 2.0 * d.0)
            };
            let range = columns
                .iter()
                .find(|c| &c.name == name)
                .map_or(1.0, |c| c.max - c.min);
            let whole = drift(y, &ins, &t);
            let a = part(&y[..h], &first, &t[..h]);
            let b = part(&y[h..], &second, &t[h..]);
            if let (Some((d, rms)), Some(a), Some(b)) = (whole, a, b) {
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
    Inspection {
        samples: n,
        sampling_period,
        jitter,
        columns,
        findings,
    }
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

/// The change over the record of an output's trend in time that a fit on its inputs leaves:
/// least squares of y on [1, t, and per input u, u^2, u^3 and nine plays of it].
/// Also the fit's residual RMS: a trend is only told from a misfit that happens to follow the
/// excitation in time (a chirp) when it stands above the residual.
fn drift(y: &[f64], inputs: &[&Vec<f64>], t: &[f64]) -> Option<(f64, f64)> {
    let n = y.len();
    let span = t.last()? - t.first()?;
    if span <= 0.0 {
        return None;
    }
    let mut cols: Vec<Vec<f64>> = vec![vec![1.0; n], t.iter().map(|v| (v - t[0]) / span).collect()];
    for u in inputs {
        let amp = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        cols.push(u.to_vec());
        cols.push(
            u.iter()
                .map(|v| v * v / amp.max(f64::MIN_POSITIVE))
                .collect(),
        );
        cols.push(
            u.iter()
                .map(|v| v * v * v / (amp * amp).max(f64::MIN_POSITIVE))
                .collect(),
        );
        for share in [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.85] {
            let mut play = crate::effect::play::Play::new(share * amp, 0.0);
            cols.push(crate::effect::Operator::apply(&mut play, u));
        }
    }
    // normal equations (p x p): memory and time linear in the record
    let p = cols.len();
    let mut ata = nalgebra::DMatrix::<f64>::zeros(p, p);
    let mut atb = nalgebra::DVector::<f64>::zeros(p);
    for i in 0..p {
        for j in i..p {
            let v: f64 = cols[i].iter().zip(&cols[j]).map(|(a, b)| a * b).sum();
            ata[(i, j)] = v;
            ata[(j, i)] = v;
        }
        atb[i] = cols[i].iter().zip(y).map(|(a, b)| a * b).sum();
    }
    let sol = ata.svd(true, true).solve(&atb, 1e-12).ok()?;
    let rms = ((0..n)
        .map(|k| {
            let f: f64 = (0..p).map(|j| sol[j] * cols[j][k]).sum();
            (f - y[k]).powi(2)
        })
        .sum::<f64>()
        / n as f64)
        .sqrt();
    Some((sol[1], rms))
}
