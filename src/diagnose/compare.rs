//! Where a model fails: scores of a prediction against a record, and the error split by what
//! the input was doing (rising or falling, amplitude, frequency band, holding or moving), the
//! worst time windows, and the area of the residual-against-input loop.

use crate::data::IoRecord;
use crate::metrics::{normalised_loop_area, rms, scores, Scores};
use serde::Serialize;

/// RMS error over a subset of samples.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Slice {
    pub label: String,
    pub samples: usize,
    pub rms: f64,
}

/// A time window with a large error.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Window {
    pub start_s: f64,
    pub end_s: f64,
    pub rms: f64,
}

/// The comparison of one output.
#[derive(Debug, Clone, Serialize)]
pub struct OutputComparison {
    pub output: String,
    pub input: String,
    pub scores: Scores,
    pub worst_windows: Vec<Window>,
    pub by_direction: Vec<Slice>,
    pub by_amplitude: Vec<Slice>,
    pub by_frequency: Vec<Slice>,
    pub by_motion: Vec<Slice>,
    /// Shoelace area of the residual against the input over ptp(u) ptp(e): a loop with area is
    /// the signature of missing memory (hysteresis).
    pub residual_loop_area: f64,
}

fn slice(label: &str, e: &[f64], mask: impl Fn(usize) -> bool) -> Slice {
    let v: Vec<f64> = (0..e.len()).filter(|&k| mask(k)).map(|k| e[k]).collect();
    Slice {
        label: label.to_string(),
        samples: v.len(),
        rms: rms(&v),
    }
}

/// Error in frequency bands: the residual's power in octave bands, from a direct DFT of a
/// decimated copy (a few thousand points), reported as RMS per band.
fn frequency_bands(e: &[f64], ts: f64) -> Vec<Slice> {
    let step = (e.len() / 4096).max(1);
    let x: Vec<f64> = e.iter().step_by(step).copied().collect();
    let n = x.len();
    let dt = ts * step as f64;
    let fmax = 0.5 / dt;
    let mut bands = Vec::new();
    let mut hi = fmax;
    while hi > 1.0 / (n as f64 * dt) * 2.0 && bands.len() < 8 {
        let lo = hi / 4.0;
        bands.push((lo, hi));
        hi = lo;
    }
    let mut power = vec![0.0; bands.len()];
    for m in 1..n / 2 {
        let f = m as f64 / (n as f64 * dt);
        let Some(b) = bands.iter().position(|(lo, hi)| f > *lo && f <= *hi) else {
            continue;
        };
        let w = -2.0 * std::f64::consts::PI * m as f64 / n as f64;
        let (mut re, mut im) = (0.0, 0.0);
        for (k, v) in x.iter().enumerate() {
            let (s, c) = (w * k as f64).sin_cos();
            re += v * c;
            im += v * s;
        }
        power[b] += 2.0 * (re * re + im * im) / (n as f64 * n as f64);
    }
    bands
        .iter()
        .zip(power)
        .map(|((lo, hi), p)| Slice {
            label: format!("{lo:.3}-{hi:.3} Hz"),
            samples: n,
            rms: p.sqrt(),
        })
        .collect()
}

/// Compare predictions (one per output) with the record.
pub fn compare(rec: &IoRecord, predictions: &[Vec<f64>]) -> Vec<OutputComparison> {
    rec.outputs
        .iter()
        .zip(predictions)
        .enumerate()
        .map(|(o, (y, yhat))| {
            let u = &rec.inputs[o.min(rec.inputs.len() - 1)];
            let uv = &u.values;
            let e: Vec<f64> = y.values.iter().zip(yhat).map(|(a, b)| a - b).collect();
            let n = e.len();
            let du = |k: usize| if k == 0 { 0.0 } else { uv[k] - uv[k - 1] };
            let tol = 1e-3 * crate::metrics::ptp(uv).max(f64::MIN_POSITIVE);
            // windows of 1/20 of the record
            let w = (n / 20).max(1);
            let mut windows: Vec<Window> = (0..n)
                .step_by(w)
                .map(|a| {
                    let b = (a + w).min(n);
                    Window {
                        start_s: rec.t0 + a as f64 * rec.ts,
                        end_s: rec.t0 + b as f64 * rec.ts,
                        rms: rms(&e[a..b]),
                    }
                })
                .collect();
            windows.sort_by(|a, b| b.rms.total_cmp(&a.rms));
            windows.truncate(3);
            let (lo, hi) = uv
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                    (l.min(v), h.max(v))
                });
            let third = (hi - lo) / 3.0;
            let holds = super::holds(uv, rec.ts);
            let in_hold = |k: usize| holds.iter().any(|&(a, b)| k >= a && k < b);
            OutputComparison {
                output: y.name.clone(),
                input: u.name.clone(),
                scores: scores(&y.values, yhat),
                worst_windows: windows,
                by_direction: vec![
                    slice("rising input", &e, |k| du(k) > tol * 1e-3),
                    slice("falling input", &e, |k| du(k) < -tol * 1e-3),
                ],
                by_amplitude: vec![
                    slice("low third of the input range", &e, |k| uv[k] < lo + third),
                    slice("middle third", &e, |k| {
                        uv[k] >= lo + third && uv[k] <= hi - third
                    }),
                    slice("high third", &e, |k| uv[k] > hi - third),
                ],
                by_frequency: frequency_bands(&e, rec.ts),
                by_motion: vec![
                    slice("during holds", &e, in_hold),
                    slice("during motion", &e, |k| !in_hold(k)),
                ],
                residual_loop_area: normalised_loop_area(uv, &e),
            }
        })
        .collect()
}
