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
//! inverse stable): the compensator previews the reference by `delay` samples.
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

use crate::plant::{Plant, PlantState};
use serde::Serialize;

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

/// Where one input was clipped at the actuator's limits.
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
    /// Per input, where it was clipped.
    pub clipped: Vec<Clipped>,
    /// The model's output under the compensating input (what it promises).
    pub model_output: Vec<Vec<f64>>,
}

/// The plant's relative degree: the fewest samples after which a change of an input shows in
/// an output (at most 4), probed from rest with pushes of both signs growing from `scale` by
/// decades (a play operator with a threshold above a small push does not move).
fn relative_degree(state: &PlantState, scale: &[f64]) -> usize {
    let (ni, no) = (state.inputs(), state.outputs());
    for d in 0..=4 {
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
fn ahead(state: &PlantState, u: &[f64], j: usize, v: f64, delay: usize, o: usize) -> f64 {
    let mut s = state.clone();
    let mut uu = u.to_vec();
    uu[j] = v;
    let mut y = vec![0.0; s.outputs()];
    for _ in 0..=delay {
        s.step(&uu, &mut y);
    }
    y[o]
}

/// The root of a monotone `g` near `start`, within `limits`: (value, clipped). `step` is the
/// first bracketing step; `tol` the accepted |g|.
fn solve(
    g: &dyn Fn(f64) -> f64,
    start: f64,
    step: f64,
    limits: Option<(f64, f64)>,
    tol: f64,
) -> Option<(f64, bool)> {
    let (lo_lim, hi_lim) = limits.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    let clamp = |v: f64| v.clamp(lo_lim, hi_lim);
    let x0 = clamp(start);
    let g0 = g(x0);
    if !g0.is_finite() {
        return None;
    }
    if g0.abs() <= tol {
        return Some((x0, false));
    }
    // bracket: expand in both directions until g changes sign
    let (mut a, mut ga) = (x0, g0);
    let mut b = x0;
    let mut gb = g0;
    let mut h = step;
    let mut found = false;
    for _ in 0..80 {
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
        if up == hi_lim && down == lo_lim {
            // the reference is beyond what the limits reach: the limit nearer to it
            let best = if gu.abs() < gd.abs() { up } else { down };
            return Some((best, true));
        }
        h *= 2.0;
    }
    if !found {
        return None;
    }
    // Illinois regula falsi on [a, b]
    let mut side = 0i32;
    for _ in 0..200 {
        let c = (a * gb - b * ga) / (gb - ga);
        let c = if c.is_finite() { c } else { 0.5 * (a + b) };
        let gc = g(c);
        if !gc.is_finite() {
            return None;
        }
        if gc.abs() <= tol || (b - a).abs() <= 1e-15 * (1.0 + a.abs().max(b.abs())) {
            return Some((c, false));
        }
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
    Some((c, false))
}

/// The input that makes `plant` (run from rest at sampling period `ts`) follow `reference`
/// (one signal per plant output, equal lengths).
pub fn compensate(
    plant: &Plant,
    reference: &[&[f64]],
    ts: f64,
    opts: &CompensateOptions,
) -> Result<Compensation, CompensateError> {
    let Some(state) = plant.state(ts)? else {
        return Err(CompensateError::NotAChain {
            plant: plant.name.clone(),
        });
    };
    let (ni, no) = (state.inputs(), state.outputs());
    if reference.len() != no {
        return Err(CompensateError::ReferenceCount {
            expected: no,
            found: reference.len(),
            names: plant.outputs.join(", "),
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
            output: plant.outputs[o].clone(),
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
    let delay = relative_degree(&state, &scale);
    let limits: Vec<Option<(f64, f64)>> = (0..ni)
        .map(|j| opts.limits.get(j).copied().flatten())
        .collect();
    let mut s = state;
    let mut u = vec![0.0; ni];
    for (j, l) in limits.iter().enumerate() {
        if let Some((lo, hi)) = l {
            u[j] = 0.0f64.clamp(*lo, *hi);
        }
    }
    let mut inputs = vec![Vec::with_capacity(n); ni];
    let mut model_output = vec![Vec::with_capacity(n); no];
    let mut clipped_at: Vec<Vec<usize>> = vec![Vec::new(); ni];
    let mut y = vec![0.0; no];
    for k in 0..n {
        let at = (k + delay).min(n - 1);
        let target: Vec<f64> = reference.iter().map(|r| r[at]).collect();
        let mut clipped = vec![false; ni];
        let sweeps = if ni == 1 { 1 } else { opts.sweeps.max(1) };
        for _ in 0..sweeps {
            for j in 0..ni {
                let o = j.min(no - 1);
                let tol = opts.tolerance * (1.0 + ranges[o]);
                let g = |v: f64| ahead(&s, &u, j, v, delay, o) - target[o];
                match solve(&g, u[j], scale[j], limits[j], tol) {
                    Some((v, c)) => {
                        u[j] = v;
                        clipped[j] = c;
                    }
                    None => {
                        return Err(CompensateError::NoRoot {
                            input: plant.inputs[j].clone(),
                            output: plant.outputs[o].clone(),
                            sample: k,
                            target: target[o],
                        })
                    }
                }
            }
        }
        for j in 0..ni {
            if clipped[j] {
                clipped_at[j].push(k);
            }
            inputs[j].push(u[j]);
        }
        s.step(&u, &mut y);
        for (o, v) in y.iter().enumerate() {
            model_output[o].push(*v);
        }
    }
    let clipped = clipped_at
        .iter()
        .enumerate()
        .map(|(j, c)| Clipped {
            input: plant.inputs[j].clone(),
            share: if n == 0 {
                0.0
            } else {
                c.len() as f64 / n as f64
            },
            first: c.first().copied(),
            last: c.last().copied(),
            count: c.len(),
        })
        .collect();
    Ok(Compensation {
        inputs,
        delay,
        clipped,
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

/// The static gain and offset a user calibrates: the least-squares line of the plant's
/// output against its input over a slow triangle (one period over the reference's duration,
/// at most 20,000 samples) spanning the compensating input's range (1 to 99 % quantiles, so
/// that the preview's first samples do not count).
pub fn static_gain(
    plant: &Plant,
    j: usize,
    o: usize,
    u: &[f64],
    ts: f64,
) -> Result<(f64, f64), CompensateError> {
    let mut s: Vec<f64> = u.iter().copied().filter(|v| v.is_finite()).collect();
    if s.is_empty() {
        return Ok((1.0, 0.0));
    }
    s.sort_by(f64::total_cmp);
    let q = |p: f64| s[((s.len() - 1) as f64 * p).round() as usize];
    let (lo, hi) = (q(0.01), q(0.99));
    let n = u.len().clamp(200, 20_000);
    let tri: Vec<f64> = (0..n)
        .map(|k| {
            let x = k as f64 / n as f64;
            let up = 1.0 - (2.0 * x - 1.0).abs();
            lo + (hi - lo) * up
        })
        .collect();
    let inputs: Vec<Vec<f64>> = (0..plant.inputs.len())
        .map(|i| if i == j { tri.clone() } else { vec![0.0; n] })
        .collect();
    let refs: Vec<&[f64]> = inputs.iter().map(Vec::as_slice).collect();
    let y = plant.simulate(&refs, ts)?;
    let (mu, my) = (crate::metrics::mean(&tri), crate::metrics::mean(&y[o]));
    let (mut num, mut den) = (0.0, 0.0);
    for (a, b) in tri.iter().zip(&y[o]) {
        num += (a - mu) * (b - my);
        den += (a - mu) * (a - mu);
    }
    let g = if den > 0.0 && num != 0.0 {
        num / den
    } else {
        1.0
    };
    Ok((g, my - g * mu))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::PlantSpec;
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
