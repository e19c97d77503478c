//! # Inverse compensation: the input that makes a model follow a reference
//!
//! A hysteresis model is used to cancel the hysteresis: the actuator is fed the model's
//! inverse of the wanted trajectory, and its output follows the reference instead of tracing a
//! loop (feedforward compensation, Croft, Shedd & Devasia 2001; Kuhnen 2003; Rakotondrabe 2011).
//!
//! One mechanism serves every model the effect library can build (a plant file, a fitted
//! grey-box model): the plant is stepped one sample at a time ([`crate::plant::PlantState`]),
//! and at each sample the input is found by root finding on a copy of the plant so that the
//! output `delay` samples later equals the reference there. `delay` is the plant's relative
//! degree, found by probing: 0 for hysteresis, creep, drift and saturation (the output moves
//! with the input), 1 through the library's second-order dynamics (its zero-order-hold
//! discretisation has a one-sample delay, and its sampling zero near -0.27 makes the one-step
//! inverse stable): the compensator previews the reference by `delay` samples. Where the
//! output answers its newest input only by a hair (a hold between zero and first order with a
//! small first-order share), the inverse at that delay cannot steer it and misses the
//! reference: a longer preview, up to [`MAX_PREVIEW`], is taken where it clearly misses fewer
//! samples.
//! Each effect is inverted in its own terms on the copy (a play operator's state, a creep
//! chain's memory, a mode's two states), so a new effect of the library is inverted without a
//! line here. A multi-input plant (a 2-DoF cantilever with cross paths) is inverted by
//! Gauss-Seidel sweeps: each input in turn makes its own output follow its reference with the
//! others held, until the cross-talk is cancelled.
//!
//! Root finding: the hysteresis operators of the library are monotone in the newest input for
//! valid parameters (a play operator is; Prandtl-Ishlinskii weights are >= 0; a Bouc-Wen loop is
//! for the stability conditions of PHYSICS.md), so a bracket found by expanding steps from the
//! previous input holds the root, and the Illinois variant of regula falsi closes it
//! (Dowell & Jarratt 1971). An input the actuator cannot give (`limits`) is clipped at the
//! limit and reported, with the samples where it happened.
//!
//! ## References
//! - D. Croft, G. Shedd, S. Devasia, "Creep, hysteresis, and vibration compensation for
//!   piezoactuators: atomic force microscopy application", ASME J. Dyn. Syst. Meas. Control
//!   123(1):35-43, 2001.
//! - K. Kuhnen, "Modeling, identification and compensation of complex hysteretic
//!   nonlinearities: a modified Prandtl-Ishlinskii approach", Eur. J. Control 9(4):407-418, 2003.
//! - M. Rakotondrabe, "Bouc-Wen modeling and inverse multiplicative structure to compensate
//!   hysteresis nonlinearity in piezoelectric actuators", IEEE T-ASE 8(2):428-431, 2011.
//! - M. Dowell, P. Jarratt, "A modified regula falsi method for computing the root of an
//!   equation", BIT 11:168-174, 1971.

mod error;
pub use error::CompensateError;

use crate::model::{Model, ModelState, Stepped};
use serde::Serialize;
use std::path::Path;

/// A stepped model with the names of its inputs and outputs.
pub struct Named<S> {
    pub state: S,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    /// Per input, where the model is known ([`Model::known_inputs`]): the inverse looks for
    /// inputs there only.
    pub known: Vec<Option<(f64, f64)>>,
}

impl Named<ModelState> {
    /// Any model at rest at sampling period `ts` (`path` names its file in errors).
    pub fn of(model: &dyn Model, ts: f64, path: &Path) -> Result<Self, CompensateError> {
        let Some(state) = model.stepped(ts, path)? else {
            return Err(CompensateError::NotStepped {
                model: model.describe(),
            });
        };
        Ok(Named {
            state,
            inputs: model.input_names(),
            outputs: model.output_names(),
            known: model.known_inputs(),
        })
    }
}

/// Knobs of the compensator.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensateOptions {
    /// Per input, the actuator's range (None: unlimited).
    pub limits: Vec<Option<(f64, f64)>>,
    /// Gauss-Seidel sweeps over the inputs of a multi-input plant.
    pub sweeps: usize,
    /// The output must match the reference to this share of the reference's range.
    pub tolerance: f64,
}

impl Default for CompensateOptions {
    fn default() -> Self {
        CompensateOptions {
            limits: Vec::new(),
            sweeps: 6,
            tolerance: 1e-12,
        }
    }
}

/// Where one input was clipped at the actuator's limits (or could not reach the reference).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Clipped {
    pub input: String,
    /// Share of the samples clipped.
    pub share: f64,
    /// The first and last clipped samples (0-based).
    pub first: Option<usize>,
    pub last: Option<usize>,
    pub count: usize,
}

/// The compensating input.
#[derive(Debug, Clone, PartialEq)]
pub struct Compensation {
    /// One signal per plant input.
    pub inputs: Vec<Vec<f64>>,
    /// The preview: the input at sample k aims at the reference at k + delay.
    pub delay: usize,
    /// The samples after which an input change first shows in an output ([`relative_degree`]);
    /// a longer `delay` was taken where the inverse at it missed the reference (the model then
    /// follows the reference closely, not exactly: the input at k moves the output before
    /// k + delay).
    pub relative_degree: usize,
    /// Samples from rest over which the model's outputs do not answer its inputs (a NARX
    /// model's seed; 0 for the effect library's models): the input stays at rest there.
    pub seeded: usize,
    /// Per input, where it was clipped.
    pub clipped: Vec<Clipped>,
    /// Per input, where no input value brings the model's output to the reference (beyond a
    /// saturating model's range, or beyond the inputs a data-driven model was trained on):
    /// the closest input is used.
    pub unreachable: Vec<Clipped>,
    /// The model's output under the compensating input (what it promises).
    pub model_output: Vec<Vec<f64>>,
}

/// The plant's relative degree: the fewest samples after which a change of an input shows in
/// an output (at most [`MAX_PREVIEW`]), probed from rest with pushes of both signs growing
/// from `scale` by decades (a play operator with a threshold above a small push does not move).
fn relative_degree<S: Stepped>(state: &S, scale: &[f64]) -> usize {
    let (ni, no) = (state.inputs(), state.outputs());
    // past the seed, where the outputs answer the inputs
    let mut state = state.clone();
    let mut y = vec![0.0; no];
    for _ in 0..state.seeded() {
        state.step(&vec![0.0; ni], &mut y);
    }
    for d in 0..=MAX_PREVIEW {
        for j in 0..ni {
            for m in 0..8 {
                for sign in [1.0, -1.0] {
                    let mut a = state.clone();
                    let mut b = state.clone();
                    let (mut ya, mut yb) = (vec![0.0; no], vec![0.0; no]);
                    let zero = vec![0.0; ni];
                    let mut push = zero.clone();
                    push[j] = sign * scale[j].max(1e-9) * 10f64.powi(m);
                    for step in 0..=d {
                        a.step(&zero, &mut ya);
                        b.step(if step == 0 { &push } else { &zero }, &mut yb);
                    }
                    if ya.iter().zip(&yb).any(|(p, q)| p != q) {
                        return d;
                    }
                }
            }
        }
    }
    0
}

/// Output `o` at `delay` samples after sample k, from a copy of `state`, when input `j` takes
/// value `v` (the other inputs as in `u`), all held over the preview.
fn ahead<S: Stepped>(state: &S, u: &[f64], j: usize, v: f64, delay: usize, o: usize) -> f64 {
    let mut uu = u.to_vec();
    uu[j] = v;
    state.ahead(&uu, delay, o)
}

/// How a sample's root finding ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reach {
    /// The output meets the reference.
    Met,
    /// The input stopped at the actuator's limit.
    Clipped,
    /// No input brings the output to the reference (a saturating model asked beyond its
    /// range): the input that comes closest.
    Unreachable,
}

/// The root of a monotone `g` near `start`, within `limits`, and the slope of `g` there.
/// `slope` is the slope at the previous sample's root (NaN: unknown): its secant step is tried
/// first, and usually brackets the root within a hair of it. `step` is the first bracketing
/// step otherwise; `tol` the accepted |g|. `None`: `g` is not finite where the root must be (the
/// model diverged).
fn solve(
    g: &dyn Fn(f64) -> f64,
    start: f64,
    step: f64,
    slope: f64,
    limits: Option<(f64, f64)>,
    tol: f64,
) -> Option<(f64, Reach, f64)> {
    let (lo_lim, hi_lim) = limits.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    let clamp = |v: f64| v.clamp(lo_lim, hi_lim);
    let x0 = clamp(start);
    let g0 = g(x0);
    if !g0.is_finite() {
        return None;
    }
    if g0.abs() <= tol {
        return Some((x0, Reach::Met, slope));
    }
    // bracket: the secant step, else expand in both directions until g changes sign,
    // keeping the closest miss
    let (mut a, mut ga) = (x0, g0);
    let mut b = x0;
    let mut gb = g0;
    let mut closest = (x0, g0.abs());
    let mut h = step;
    let mut found = false;
    if slope.is_finite() && slope != 0.0 {
        // secant steps from the last sample's slope, while |g| falls fast; the nearest points
        // on each side of the root are kept as the bracket
        let (mut xp, mut gp) = (x0, g0);
        let mut s = slope;
        let mut other: Option<(f64, f64)> = None;
        for _ in 0..4 {
            let x1 = clamp(xp - gp / s);
            if x1 == xp {
                break;
            }
            let g1 = g(x1);
            if !g1.is_finite() {
                break;
            }
            if g1.abs() <= tol {
                return Some((x1, Reach::Met, s));
            }
            if g1.signum() != gp.signum() {
                other = Some((xp, gp));
            }
            if g1.abs() < closest.1 {
                closest = (x1, g1.abs());
            }
            let fell = g1.abs() < 0.5 * gp.abs();
            let s1 = (g1 - gp) / (x1 - xp);
            (xp, gp) = (x1, g1);
            if !(fell && s1.is_finite() && s1 != 0.0) {
                break;
            }
            s = s1;
        }
        match other {
            // a root between the last point and one on the other side
            Some((xo, go)) if go.signum() != gp.signum() => {
                (a, ga, b, gb) = (xo, go, xp, gp);
                found = true;
            }
            _ => {
                // still on the start's side: bracket from there, steps a little longer
                // than the distance covered
                (a, ga) = (xp, gp);
                if gp.signum() != g0.signum() {
                    (b, gb) = (x0, g0);
                    found = true;
                } else {
                    h = (2.0 * (xp - x0).abs()).max(f64::MIN_POSITIVE);
                }
            }
        }
    }
    for _ in 0..80 {
        if found {
            break;
        }
        let up = clamp(x0 + h);
        let gu = g(up);
        if gu.is_finite() && gu.signum() != g0.signum() {
            (b, gb) = (up, gu);
            found = true;
            break;
        }
        let down = clamp(x0 - h);
        let gd = g(down);
        if gd.is_finite() && gd.signum() != g0.signum() {
            (b, gb) = (down, gd);
            found = true;
            break;
        }
        for (x, v) in [(up, gu), (down, gd)] {
            if v.is_finite() && v.abs() < closest.1 {
                closest = (x, v.abs());
            }
        }
        if up == hi_lim && down == lo_lim {
            // the reference is beyond what the limits reach: the limit nearer to it
            let best = if gu.abs() < gd.abs() { up } else { down };
            return Some((best, Reach::Clipped, f64::NAN));
        }
        h *= 2.0;
    }
    if !found {
        return Some((closest.0, Reach::Unreachable, f64::NAN));
    }
    // Illinois regula falsi on [a, b]; the slope from the last two evaluations (the
    // Illinois halvings only steer the steps)
    let mut side = 0i32;
    let mut prev = (b, gb);
    let secant = |(xa, fa): (f64, f64), (xb, fb): (f64, f64)| {
        let s = (fb - fa) / (xb - xa);
        if s.is_finite() && s != 0.0 {
            s
        } else {
            slope
        }
    };
    for _ in 0..200 {
        let c = (a * gb - b * ga) / (gb - ga);
        let c = if c.is_finite() { c } else { 0.5 * (a + b) };
        let gc = g(c);
        if !gc.is_finite() {
            return None;
        }
        if gc.abs() <= tol || (b - a).abs() <= 1e-15 * (1.0 + a.abs().max(b.abs())) {
            return Some((c, Reach::Met, secant(prev, (c, gc))));
        }
        prev = (c, gc);
        if gc.signum() == gb.signum() {
            (b, gb) = (c, gc);
            if side == -1 {
                ga *= 0.5;
            }
            side = -1;
        } else {
            (a, ga) = (c, gc);
            if side == 1 {
                gb *= 0.5;
            }
            side = 1;
        }
    }
    let c = if ga.abs() < gb.abs() { a } else { b };
    Some((c, Reach::Met, slope))
}

/// The input that makes `model` (run from rest at sampling period `ts`) follow `reference`
/// (one signal per model output, equal lengths). Any model that runs a sample at a time: a
/// chain plant, a grey-box model, a NARX model (root finding on its newest input; over its
/// seed, its first samples, the outputs do not answer the inputs and the input stays at rest).
pub fn compensate(
    model: &dyn Model,
    reference: &[&[f64]],
    ts: f64,
    opts: &CompensateOptions,
) -> Result<Compensation, CompensateError> {
    compensate_stepped(&Named::of(model, ts, Path::new("model"))?, reference, opts)
}

/// Where each input's samples were marked (clipped, unreachable).
fn marks(at: &[Vec<usize>], names: &[String], n: usize) -> Vec<Clipped> {
    at.iter()
        .zip(names)
        .map(|(c, name)| Clipped {
            input: name.clone(),
            share: if n == 0 {
                0.0
            } else {
                c.len() as f64 / n as f64
            },
            first: c.first().copied(),
            last: c.last().copied(),
            count: c.len(),
        })
        .collect()
}

/// The input that makes a stepped model follow `reference` (one signal per output).
pub fn compensate_stepped<S: Stepped>(
    model: &Named<S>,
    reference: &[&[f64]],
    opts: &CompensateOptions,
) -> Result<Compensation, CompensateError> {
    let state = &model.state;
    let (ni, no) = (state.inputs(), state.outputs());
    if reference.len() != no {
        return Err(CompensateError::ReferenceCount {
            expected: no,
            found: reference.len(),
            names: model.outputs.join(", "),
        });
    }
    if ni > no {
        return Err(CompensateError::MoreInputsThanOutputs {
            inputs: ni,
            outputs: no,
        });
    }
    let n = reference.first().map_or(0, |r| r.len());
    if let Some((o, r)) = reference.iter().enumerate().find(|(_, r)| r.len() != n) {
        return Err(CompensateError::ReferenceLength {
            output: model.outputs[o].clone(),
            found: r.len(),
            expected: n,
        });
    }
    let ranges: Vec<f64> = reference
        .iter()
        .map(|r| crate::metrics::ptp(r).max(r.iter().fold(0.0f64, |m, v| m.max(v.abs()))))
        .collect();
    // a first step for the brackets: a hundredth of the input a unit static gain would need
    let scale: Vec<f64> = (0..ni).map(|j| (0.01 * ranges[j]).max(1e-6)).collect();
    let first = relative_degree(state, &scale);
    // samples where the inverse did not meet the reference (an unstable one swings between
    // the bounds it may search in, the actuator's or the known inputs')
    let missed = |c: &Result<Compensation, CompensateError>| {
        c.as_ref().map_or(usize::MAX, |c| {
            c.unreachable
                .iter()
                .chain(&c.clipped)
                .map(|u| u.count)
                .sum()
        })
    };
    // the smallest preview whose inverse follows the reference; a longer one where it clearly
    // misses fewer samples (an output that answers its newest input only by a hair, as a
    // hold between zero and first order with a small first-order share does, cannot be
    // steered by it: the one-step inverse swings between the known inputs' bounds)
    let mut best = follow(model, reference, opts, &ranges, &scale, first, first);
    for delay in first + 1..=MAX_PREVIEW {
        let m = missed(&best);
        if m == 0 {
            break;
        }
        let next = follow(model, reference, opts, &ranges, &scale, first, delay);
        if missed(&next).saturating_mul(2) > m {
            break;
        }
        best = next;
    }
    best
}

/// The longest preview [`compensate_stepped`] tries (samples), as [`relative_degree`] probes.
pub const MAX_PREVIEW: usize = 4;

/// The compensating input of `model` at preview `delay` (`first`: its relative degree).
fn follow<S: Stepped>(
    model: &Named<S>,
    reference: &[&[f64]],
    opts: &CompensateOptions,
    ranges: &[f64],
    scale: &[f64],
    first: usize,
    delay: usize,
) -> Result<Compensation, CompensateError> {
    let state = &model.state;
    let (ni, no) = (state.inputs(), state.outputs());
    let n = reference.first().map_or(0, |r| r.len());
    let seeded = state.seeded();
    let actuator: Vec<Option<(f64, f64)>> = (0..ni)
        .map(|j| opts.limits.get(j).copied().flatten())
        .collect();
    // the search: the actuator's range within the range where the model is known
    let limits: Vec<Option<(f64, f64)>> = (0..ni)
        .map(
            |j| match (actuator[j], model.known.get(j).copied().flatten()) {
                (Some((a, b)), Some((c, d))) => Some((a.max(c), b.min(d)))
                    .filter(|(l, h)| l < h)
                    .or(Some((a, b))),
                (a, k) => a.or(k),
            },
        )
        .collect();
    let mut s = state.clone();
    let mut u = vec![0.0; ni];
    for (j, l) in limits.iter().enumerate() {
        if let Some((lo, hi)) = l {
            u[j] = 0.0f64.clamp(*lo, *hi);
        }
    }
    let mut inputs = vec![Vec::with_capacity(n); ni];
    let mut model_output = vec![Vec::with_capacity(n); no];
    let mut clipped_at: Vec<Vec<usize>> = vec![Vec::new(); ni];
    let mut unreachable_at: Vec<Vec<usize>> = vec![Vec::new(); ni];
    let mut y = vec![0.0; no];
    let mut slope = vec![f64::NAN; ni];
    for k in 0..n {
        let at = (k + delay).min(n - 1);
        // over the seed the outputs do not answer: the input stays at rest
        if k + delay >= seeded {
            let target: Vec<f64> = reference.iter().map(|r| r[at]).collect();
            let mut reach = vec![Reach::Met; ni];
            let sweeps = if ni == 1 { 1 } else { opts.sweeps.max(1) };
            for _ in 0..sweeps {
                for j in 0..ni {
                    let o = j.min(no - 1);
                    let tol = opts.tolerance * (1.0 + ranges[o]);
                    let g = |v: f64| ahead(&s, &u, j, v, delay, o) - target[o];
                    match solve(&g, u[j], scale[j], slope[j], limits[j], tol) {
                        Some((v, r, sl)) => {
                            u[j] = v;
                            slope[j] = sl;
                            // stopped at a bound that is not the actuator's: the model
                            // does not reach the reference within the inputs it knows
                            let at_actuator =
                                actuator[j].is_some_and(|(lo, hi)| v <= lo || v >= hi);
                            reach[j] = match r {
                                Reach::Clipped if !at_actuator => Reach::Unreachable,
                                r => r,
                            };
                        }
                        None => {
                            return Err(CompensateError::Diverged {
                                input: model.inputs[j].clone(),
                                output: model.outputs[o].clone(),
                                sample: k,
                                target: target[o],
                            })
                        }
                    }
                }
            }
            for j in 0..ni {
                match reach[j] {
                    Reach::Met => {}
                    Reach::Clipped => clipped_at[j].push(k),
                    Reach::Unreachable => unreachable_at[j].push(k),
                }
            }
        }
        for j in 0..ni {
            inputs[j].push(u[j]);
        }
        s.step(&u, &mut y);
        for (o, v) in y.iter().enumerate() {
            model_output[o].push(*v);
        }
    }
    Ok(Compensation {
        inputs,
        delay,
        relative_degree: first,
        seeded,
        clipped: marks(&clipped_at, &model.inputs, n),
        unreachable: marks(&unreachable_at, &model.inputs, n),
        model_output,
    })
}

/// Tracking error of one run (output minus reference), from sample `from`.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Tracking {
    pub rms: f64,
    pub max: f64,
    /// RMS as a share of the reference's range, in %.
    pub rms_percent: f64,
}

/// One output.
#[derive(Debug, Clone, Serialize)]
pub struct OutputTracking {
    pub output: String,
    pub uncompensated: Tracking,
    pub compensated: Tracking,
    /// uncompensated RMS / compensated RMS.
    pub ratio: f64,
}

pub fn tracking(r: &[f64], y: &[f64], from: usize) -> Tracking {
    let e: Vec<f64> = r[from..]
        .iter()
        .zip(&y[from..])
        .map(|(a, b)| b - a)
        .collect();
    let rms = crate::metrics::rms(&e);
    let range = crate::metrics::ptp(r).max(f64::MIN_POSITIVE);
    Tracking {
        rms,
        max: e.iter().fold(0.0, |m, v| m.max(v.abs())),
        rms_percent: 100.0 * rms / range,
    }
}

/// The static gain and offset a user calibrates: the least-squares line of the model's
/// output `o` against its input `j` over a slow triangle (one period over the reference's
/// duration, at most 20,000 samples) spanning the compensating input `u`'s range (1 to 99 %
/// quantiles, so that the preview's first samples do not count), the other inputs at rest.
pub fn static_gain<S: Stepped>(model: &S, j: usize, o: usize, u: &[f64]) -> (f64, f64) {
    let mut s: Vec<f64> = u.iter().copied().filter(|v| v.is_finite()).collect();
    if s.is_empty() {
        return (1.0, 0.0);
    }
    s.sort_by(f64::total_cmp);
    let q = |p: f64| s[((s.len() - 1) as f64 * p).round() as usize];
    let (lo, hi) = (q(0.01), q(0.99));
    let n = u.len().clamp(200, 20_000);
    let mut m = model.clone();
    let mut x = vec![0.0; m.inputs()];
    let mut y = vec![0.0; m.outputs()];
    let (mut tri, mut out) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for k in 0..n {
        let up = 1.0 - (2.0 * (k as f64 / n as f64) - 1.0).abs();
        x[j] = lo + (hi - lo) * up;
        m.step(&x, &mut y);
        if k >= m.seeded() && y[o].is_finite() {
            tri.push(x[j]);
            out.push(y[o]);
        }
    }
    let (mu, my) = (crate::metrics::mean(&tri), crate::metrics::mean(&out));
    let (mut num, mut den) = (0.0, 0.0);
    for (a, b) in tri.iter().zip(&out) {
        num += (a - mu) * (b - my);
        den += (a - mu) * (a - mu);
    }
    let g = if den > 0.0 && num != 0.0 {
        num / den
    } else {
        1.0
    };
    (g, my - g * mu)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::{Plant, PlantSpec};
    use std::path::Path;

    fn plant(name: &str) -> Plant {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        PlantSpec::read(&root.join("plants").join(name))
            .unwrap()
            .check(Path::new(name))
            .unwrap()
    }

    /// Composed with the plant, the inverse is the identity (quasi-static reference).
    #[test]
    fn the_inverse_composed_with_the_plant_is_the_identity() {
        for name in [
            "prandtl_ishlinskii_piezo.json",
            "prandtl_ishlinskii_asymmetric.json",
            "bouc_wen_piezo.json",
            "hidden_creep_piezo.json",
        ] {
            let p = plant(name);
            let ts = 1e-4;
            let r: Vec<f64> = (0..20000)
                .map(|k| {
                    let t = k as f64 * ts;
                    10.0 * (2.0 * std::f64::consts::PI * 0.5 * t).sin()
                        + 3.0 * (2.0 * std::f64::consts::PI * 1.7 * t).sin()
                })
                .collect();
            let c = compensate(&p, &[&r], ts, &CompensateOptions::default()).unwrap();
            let refs: Vec<&[f64]> = c.inputs.iter().map(Vec::as_slice).collect();
            let y = p.simulate(&refs, ts).unwrap();
            let worst = (0..r.len() - c.delay)
                .map(|k| (y[0][k + c.delay] - r[k + c.delay]).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-9, "{name}: delay {}, worst {worst}", c.delay);
        }
    }

    #[test]
    fn a_saturating_model_asked_beyond_its_range_says_where_it_cannot_reach() {
        let text = r#"{"name": "clipped", "inputs": ["u"], "outputs": [{"name": "y",
            "paths": [{"input": "u", "hysteresis": {"prandtl_ishlinskii":
                {"linear_weight": 0.8, "thresholds": [2.0], "weights": [0.2]}}}],
            "saturation": {"upper": 5.0}}]}"#;
        let path = Path::new("clipped.json");
        let p = PlantSpec::parse(path, text).unwrap().check(path).unwrap();
        // up to 8 and back: the sensor reads at most 5
        let r: Vec<f64> = (0..800)
            .map(|k| 8.0 * (1.0 - (k as f64 / 400.0 - 1.0).abs()))
            .collect();
        let c = compensate(&p, &[&r], 1e-3, &CompensateOptions::default()).unwrap();
        let un = &c.unreachable[0];
        let beyond = r.iter().filter(|v| **v > 5.0 + 1e-9).count();
        assert_eq!(un.count, beyond, "{un:?}");
        assert_eq!(c.clipped[0].count, 0);
        assert!(c.inputs[0].iter().all(|v| v.is_finite()));
        // where it can, the model follows
        for (k, (y, r)) in c.model_output[0].iter().zip(&r).enumerate() {
            if *r < 5.0 - 1e-9 {
                assert!((y - r).abs() < 1e-9, "sample {k}: {y} for {r}");
            } else {
                assert!((y - 5.0).abs() < 1e-9, "sample {k}: {y} at the limit");
            }
        }
    }

    /// A mode discretised with a little first-order hold answers its newest input by a hair:
    /// the one-step inverse at that delay swings between the actuator's limits; a longer
    /// preview follows the reference.
    #[test]
    fn a_hair_of_feedthrough_takes_a_longer_preview() {
        let text = r#"{"name": "held", "inputs": ["u"], "outputs": [{"name": "y",
            "paths": [{"input": "u", "hysteresis": {"prandtl_ishlinskii":
                {"linear_weight": 0.8, "thresholds": [1.0, 2.0], "weights": [0.1, 0.1]}}}],
            "dynamics": {"natural_frequency_hz": 40.0, "damping_ratio": 0.2,
                "first_order_hold": 0.01}}]}"#;
        let path = Path::new("held.json");
        let p = PlantSpec::parse(path, text).unwrap().check(path).unwrap();
        let ts = 1e-3;
        let r: Vec<f64> = (0..3000)
            .map(|k| 5.0 * (2.0 * std::f64::consts::PI * 2.0 * k as f64 * ts).sin())
            .collect();
        let opts = CompensateOptions {
            limits: vec![Some((-40.0, 40.0))],
            ..CompensateOptions::default()
        };
        let c = compensate(&p, &[&r], ts, &opts).unwrap();
        assert_eq!(c.relative_degree, 0);
        assert!(c.delay > 0, "preview {}", c.delay);
        assert_eq!(c.clipped[0].count + c.unreachable[0].count, 0, "{c:?}");
        let refs: Vec<&[f64]> = c.inputs.iter().map(Vec::as_slice).collect();
        let y = p.simulate(&refs, ts).unwrap();
        let e: Vec<f64> = (c.delay..r.len()).map(|k| y[0][k] - r[k]).collect();
        let rms = crate::metrics::rms(&e) / crate::metrics::ptp(&r);
        assert!(rms < 1e-3, "preview {}: RMS {rms} of the range", c.delay);
    }

    /// Along a smooth reference, the previous sample's slope brackets the next root at once:
    /// far fewer evaluations than growing a bracket from a fixed step.
    #[test]
    fn the_secant_start_saves_evaluations_along_a_smooth_reference() {
        use std::cell::Cell;
        let count = |use_slope: bool| {
            let evals = Cell::new(0usize);
            let (mut x, mut slope) = (0.0, f64::NAN);
            for k in 0..2000 {
                let r = 10.0 * (k as f64 * 0.003).sin();
                let g = |v: f64| {
                    evals.set(evals.get() + 1);
                    v * v * v + 2.0 * v - r
                };
                let (v, reach, s) = solve(&g, x, 0.1, slope, None, 1e-12 * 11.0).unwrap();
                assert_eq!(reach, Reach::Met);
                assert!(g(v).abs() <= 1e-10, "sample {k}");
                x = v;
                if use_slope {
                    slope = s;
                }
            }
            evals.get()
        };
        let (with, without) = (count(true), count(false));
        println!("evaluations: {with} with the slope, {without} without");
        assert!(with * 3 < without * 2, "{with} vs {without}");
    }

    #[test]
    fn limits_clip_and_say_where() {
        let p = plant("prandtl_ishlinskii_piezo.json");
        let r: Vec<f64> = (0..500).map(|k| 0.1 * k as f64).collect();
        let opts = CompensateOptions {
            limits: vec![Some((-10.0, 10.0))],
            ..Default::default()
        };
        let c = compensate(&p, &[&r], 1e-4, &opts).unwrap();
        assert!(c.inputs[0].iter().all(|v| (-10.0..=10.0).contains(v)));
        assert!(
            c.clipped[0].count > 0 && c.clipped[0].share < 1.0,
            "{:?}",
            c.clipped
        );
        assert_eq!(c.clipped[0].last, Some(499));
    }
}
