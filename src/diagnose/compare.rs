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

/// Error in frequency bands: the residual's amplitude spectrum (Hann window, whole record)
/// summed in bands a factor 4 wide from Nyquist down, as RMS per band (a sinusoid of amplitude A
/// contributes A / sqrt(2); the Hann window's noise bandwidth of 1.5 bins is divided out).
fn frequency_bands(e: &[f64], ts: f64) -> Vec<Slice> {
    let (f, a) = crate::signal::amplitude_spectrum(e, ts);
    let mut out = Vec::new();
    let Some(&f_low) = f.first() else { return out };
    let mut hi = 0.5 / ts;
    while hi > 2.0 * f_low && out.len() < 8 {
        let lo = hi / 4.0;
        let (p, n) = f
            .iter()
            .zip(&a)
            .filter(|(f, _)| **f > lo && **f <= hi)
            .fold((0.0, 0usize), |(p, n), (_, a)| (p + a * a / 2.0, n + 1));
        out.push(Slice {
            label: format!("{lo:.3}-{hi:.3} Hz"),
            samples: n,
            rms: (p / 1.5).sqrt(),
        });
        hi = lo;
    }
    out
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

/// How one output's prediction band held the measurement.
#[derive(Debug, Clone, Serialize)]
pub struct BandCoverage {
    pub output: String,
    pub level: f64,
    /// Share of the samples inside prediction +- half-width.
    pub coverage: f64,
    pub mean_half_width: f64,
}

/// The coverage of each output's band (outputs without a band are left out).
pub fn band_coverage(
    io: &IoRecord,
    pred: &[Vec<f64>],
    bands: &[Option<Vec<f64>>],
) -> Vec<BandCoverage> {
    io.outputs
        .iter()
        .zip(pred)
        .zip(bands)
        .filter_map(|((y, p), h)| {
            let h = h.as_ref()?;
            Some(BandCoverage {
                output: y.name.clone(),
                level: crate::narx::band::BAND_LEVEL,
                coverage: crate::narx::band::coverage(&y.values, p, h, 0)?,
                mean_half_width: h.iter().sum::<f64>() / h.len().max(1) as f64,
            })
        })
        .collect()
}

/// A model against a record, as `compare --json` prints it.
#[derive(Debug, Clone, Serialize)]
pub struct CompareReport {
    /// How each output's prediction band (where the model has one) held the measurement.
    pub bands: Vec<BandCoverage>,
    /// Where the record leaves the region the model was trained on.
    pub extrapolation: Vec<crate::narx::region::Outside>,
    /// Scores and where each output fails.
    pub outputs: Vec<OutputComparison>,
    /// The prediction's band half-widths per output (not in the JSON: the figures draw them).
    #[serde(skip)]
    pub half_widths: Vec<Option<Vec<f64>>>,
}

impl CompareReport {
    /// `compare --json`'s text: every object's keys in alphabetical order.
    pub fn to_json(&self) -> String {
        serde_json::to_value(self).map_or_else(|_| "{}".into(), |v| v.to_string())
    }
}

/// Compare `model`'s free-run prediction `pred` of `io` with the measurement.
pub fn compare_model(
    model: &dyn crate::model::Model,
    io: &IoRecord,
    pred: &[Vec<f64>],
) -> Result<CompareReport, crate::model::ModelError> {
    let half_widths = model.band(io)?;
    Ok(CompareReport {
        bands: band_coverage(io, pred, &half_widths),
        extrapolation: model.outside(io),
        outputs: compare(io, pred),
        half_widths,
    })
}
