//! Spencer et al.'s full ("modified Bouc-Wen") MR damper model: the Bouc-Wen element with its
//! dashpot c0 and spring k0, in series with the pre-yield dashpot c1, beside the accumulator
//! spring k1 (Spencer, Dyke, Sain, Carlson 1997, eqs. 9-11, n = 1, A = 1):
//!
//! ```text
//! dy/dt = (alpha z + c0 dx/dt + k0 (x - y)) / (c0 + c1)
//! dz/dt = (dx/dt - dy/dt) - B |dx/dt - dy/dt| z - Gamma (dx/dt - dy/dt) |z|
//! F     = c1 dy/dt + k1 x + f0
//! ```
//!
//! At low velocity the stiff Bouc-Wen element has not yielded: y follows x and F is close to
//! c1 dx/dt + k1 x, the steep pre-yield slope; at high velocity the element yields, y lags x and
//! the slope falls to about c0 c1 / (c0 + c1). The simple model (`Structure::BoucWen`) has no y
//! and so one viscous slope.
//! With n = 1 the Bouc-Wen equation is homogeneous in z, so A is absorbed by alpha.
//!
//! Simulation: the library's effect `spencer` (`src/effect/spencer.rs`: x linear within each
//! sample, z semi-implicit, y by Euler) on a path whose linear gain is k1, with the offset f0,
//! in sub-steps of at most 1 ms whatever the stiffness (the search below meets wild parameters:
//! their simulation diverges and is refused instead of taking thousands of sub-steps).
//! Fit: Levenberg-Marquardt on the free-run simulation error from rest (forward-difference
//! Jacobian), from starts anchored on the simple model's fit of the same records.

use super::*;
use crate::effect::spencer::{self, SpencerSpec};
use crate::effect::Operator;
use crate::numeric::lm::{levenberg_marquardt, ForwardDifference, LeastSquares, LmSettings};

/// Levenberg-Marquardt iterations from every start, then at most for the two best.
const SCOUT_ITERATIONS: usize = 8;
const MAX_ITERATIONS: usize = 60;

/// The force of the full model from rest for a displacement `x` (mm) sampled at `ts` (s): the
/// library's effect ([`crate::effect::spencer`]) plus the spring k1 x and the offset f0;
/// parameters the effect refuses (a negative dashpot, |Gamma| > B, a non-finite value) or a
/// period <= 0 give NaN.
pub fn simulate_full(p: &SpencerParams, x: &[f64], ts: f64) -> Vec<f64> {
    let spec = SpencerSpec {
        c0: p.c0,
        c1: p.c1,
        k0: p.k0,
        alpha: p.alpha,
        b: p.b,
        gamma: p.gamma,
    };
    let m = spencer::substeps_by_time(ts);
    let Ok(mut op) = spec.check().and_then(|s| s.operator_in_substeps(ts, m)) else {
        return vec![f64::NAN; x.len()];
    };
    x.iter().map(|&v| op.step(v) + p.k1 * v + p.f0).collect()
}

/// Scales of a set of records that make the search coordinates dimensionless: the largest
/// |x| (mm) and the RMS force (N).
#[derive(Debug, Clone, Copy)]
struct Scales {
    x: f64,
    f: f64,
}

impl Scales {
    fn of(recs: &[&DamperRecord]) -> Scales {
        let x = recs
            .iter()
            .flat_map(|r| r.x.iter())
            .fold(0.0f64, |a, v| a.max(v.abs()))
            .max(1e-12);
        let n: usize = recs.iter().map(|r| r.f.len()).sum();
        let ff: f64 = recs.iter().flat_map(|r| r.f.iter()).map(|v| v * v).sum();
        Scales {
            x,
            f: (ff / n.max(1) as f64).sqrt().max(1e-12),
        }
    }
}

/// The search coordinates. Per current (8): ln c0, ln k0, ln alpha, ln c1, k1 x/F, f0/F,
/// ln(B x), atanh(Gamma/B). Scheduled (11): c0, alpha, c1 as a (1 + r I) with ln a and ln r
/// each (Spencer et al.'s c = ca + cb u with positive ca, cb), then the shared ln k0, k1 x/F,
/// f0/F, ln(B x), atanh(Gamma/B).
fn params_at(theta: &[f64], scheduled: bool, sc: Scales, i: f64) -> SpencerParams {
    let e = |v: f64| v.clamp(-40.0, 40.0).exp();
    let (c0, alpha, c1, rest) = if scheduled {
        (
            e(theta[0]) * (1.0 + e(theta[1]) * i),
            e(theta[2]) * (1.0 + e(theta[3]) * i),
            e(theta[4]) * (1.0 + e(theta[5]) * i),
            &theta[6..],
        )
    } else {
        (e(theta[0]), e(theta[2]), e(theta[3]), theta)
    };
    let (k0, k1, f0, lb, q) = if scheduled {
        (e(rest[0]), rest[1], rest[2], rest[3], rest[4])
    } else {
        (e(rest[1]), rest[4], rest[5], rest[6], rest[7])
    };
    let b = e(lb) / sc.x;
    SpencerParams {
        structure: Structure::Spencer,
        v0: 0.0,
        c0,
        k0,
        alpha,
        f0: f0 * sc.f,
        b,
        gamma: b * q.clamp(-20.0, 20.0).tanh(),
        c1,
        k1: k1 * sc.f / sc.x,
    }
}

/// The search coordinates of per-current parameters (the inverse of [`params_at`]).
fn theta_of(p: &SpencerParams, sc: Scales) -> Vec<f64> {
    let l = |v: f64| v.max(1e-300).ln();
    vec![
        l(p.c0),
        l(p.k0),
        l(p.alpha),
        l(p.c1),
        p.k1 * sc.x / sc.f,
        p.f0 / sc.f,
        l(p.b * sc.x),
        (p.gamma / p.b).clamp(-0.999_999, 0.999_999).atanh(),
    ]
}

/// Scheduled coordinates from per-current ones: no slope in I to start with (ln r = ln 1e-3).
fn scheduled_theta(t: &[f64]) -> Vec<f64> {
    let r = 1e-3f64.ln();
    vec![t[0], r, t[2], r, t[3], r, t[1], t[4], t[5], t[6], t[7]]
}

/// Fits the full model to records (`scheduled`: c0, alpha, c1 affine in I, the rest shared) by
/// Levenberg-Marquardt on the pooled simulation error, from starts anchored on the simple
/// Bouc-Wen model's fit `anchor` of the same records: its c0, k0, f0; c1 = 3, 10, 30 c0; (B,
/// Gamma) the anchor's or B x = 30, 300 with Gamma = -B/2, alpha rescaled to keep the anchor's
/// yield force alpha / (B + Gamma). Every start runs a few iterations, the two lowest go on
/// (at most [`MAX_ITERATIONS`] in all) and the lower of them wins (ties: the first start).
/// c0, k0, alpha and c1 are kept positive (logarithms); k1 and f0 are free.
pub fn fit_full(
    recs: &[&DamperRecord],
    scheduled: bool,
    anchor: &SpencerParams,
) -> Option<SpencerFit> {
    let sc = Scales::of(recs);
    let n: usize = recs.iter().map(|r| r.f.len()).sum();
    if n == 0 {
        return None;
    }
    let residual = |theta: &[f64]| -> Option<Vec<f64>> {
        let mut out = Vec::with_capacity(n);
        for r in recs {
            let p = params_at(theta, scheduled, sc, r.current);
            let f = simulate_full(&p, &r.x, r.ts);
            for (a, b) in f.iter().zip(&r.f) {
                let d = a - b;
                if !d.is_finite() {
                    return None;
                }
                out.push(d);
            }
        }
        Some(out)
    };
    let lsq = ForwardDifference {
        residual,
        step: 1e-6,
    };
    // the anchor's yield force; floors keep a degenerate anchor (alpha <= 0, B + Gamma = 0)
    // from starting alpha at zero or at infinity
    let yield_force = anchor.alpha.max(1e-3 * sc.f) / (anchor.b + anchor.gamma).max(1e-3 / sc.x);
    let bgs = [
        (anchor.b, anchor.gamma),
        (30.0 / sc.x, -15.0 / sc.x),
        (300.0 / sc.x, -150.0 / sc.x),
    ];
    let starts: Vec<Vec<f64>> = [3.0, 10.0, 30.0]
        .iter()
        .flat_map(|&c| bgs.iter().map(move |&bg| (c, bg)))
        .map(|(c, (b, gamma))| {
            let p = SpencerParams {
                structure: Structure::Spencer,
                v0: 0.0,
                c0: anchor.c0.max(1e-6 * sc.f),
                k0: anchor.k0.max(1e-3 * sc.f / sc.x),
                alpha: yield_force * (b + gamma),
                f0: anchor.f0,
                b,
                gamma,
                c1: c * anchor.c0.max(1e-6 * sc.f),
                k1: 0.0,
            };
            let t = theta_of(&p, sc);
            if scheduled {
                scheduled_theta(&t)
            } else {
                t
            }
        })
        .collect();
    // a few iterations from every start, then the two best go on to convergence
    let settings = |max_iterations| LmSettings {
        max_iterations,
        tolerance: 1e-7,
        bound: 60.0,
        ..LmSettings::default()
    };
    let free: Vec<usize> = (0..starts[0].len()).collect();
    let run = |t: &Vec<f64>, iterations: usize| -> Option<(Vec<f64>, f64)> {
        let e = lsq.eval(t)?;
        let out = levenberg_marquardt(&lsq, t.clone(), e, &free, &settings(iterations));
        let c = lsq.cost(&out.eval);
        c.is_finite().then_some((out.theta, c))
    };
    let mut first: Vec<(Vec<f64>, f64)> = starts
        .par_iter()
        .map(|t| run(t, SCOUT_ITERATIONS))
        .collect::<Vec<_>>()
        .into_iter()
        .flatten()
        .collect();
    // stable sort: ties keep the order of the starts
    first.sort_by(|a, b| a.1.total_cmp(&b.1));
    first.truncate(2);
    let (theta, rms) = first
        .par_iter()
        .map(|(t, _)| run(t, MAX_ITERATIONS))
        .collect::<Vec<_>>()
        .into_iter()
        .flatten()
        .fold(None, |best: Option<(Vec<f64>, f64)>, (t, c)| match best {
            Some((_, bc)) if bc <= c => best,
            _ => Some((t, c)),
        })?;
    let at0 = params_at(&theta, scheduled, sc, 0.0);
    let mut coef = vec![at0.c0, at0.k0, at0.alpha, at0.f0, at0.c1, at0.k1];
    if scheduled {
        let at1 = params_at(&theta, scheduled, sc, 1.0);
        coef.extend([
            at1.c0 - at0.c0,
            0.0,
            at1.alpha - at0.alpha,
            0.0,
            at1.c1 - at0.c1,
            0.0,
        ]);
    }
    Some(SpencerFit {
        structure: Structure::Spencer,
        v0: 0.0,
        b: at0.b,
        gamma: at0.gamma,
        coef,
        train_rms_n: rms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth(i: f64) -> SpencerParams {
        SpencerParams {
            structure: Structure::Spencer,
            v0: 0.0,
            c0: 2.0 + 4.0 * i,
            k0: 1.0,
            alpha: 400.0 + 1500.0 * i,
            f0: 3.0,
            b: 1.5,
            gamma: -0.5,
            c1: 40.0 + 60.0 * i,
            k1: 0.8,
        }
    }

    fn record(i: f64, amp: f64, hz: f64, group: &str) -> DamperRecord {
        let ts = 1e-3;
        let x: Vec<f64> = (0..3000)
            .map(|k| amp * (2.0 * std::f64::consts::PI * hz * k as f64 * ts).sin())
            .collect();
        let f = simulate_full(&truth(i), &x, ts);
        DamperRecord {
            path: PathBuf::from(format!("{group}_{i}")),
            group: group.into(),
            x,
            f,
            current: i,
            ts,
        }
    }

    #[test]
    fn the_pre_yield_dashpot_gives_a_steeper_slope_at_low_velocity() {
        // at a slow rate the force over velocity is far above the post-yield slope
        let p = truth(1.0);
        let ts = 1e-3;
        let x: Vec<f64> = (0..2000).map(|k| 0.01 * k as f64 * ts).collect();
        let f = simulate_full(&p, &x, ts);
        let early = (f[20] - p.k1 * x[20] - p.f0) / 0.01;
        assert!(early > 5.0 * p.c0, "{early}");
        assert!(f.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn the_full_model_is_recovered_from_its_own_sines() {
        let recs: Vec<DamperRecord> = [0.0, 0.5, 1.0]
            .iter()
            .flat_map(|&i| [record(i, 5.0, 2.0, "a"), record(i, 2.0, 4.0, "b")])
            .collect();
        let refs: Vec<&DamperRecord> = recs.iter().collect();
        let anchor = fit_structure(&refs, Structure::BoucWen, true)
            .unwrap()
            .at(0.5);
        let fit = fit_full(&refs, true, &anchor).unwrap();
        let frms = (recs
            .iter()
            .flat_map(|r| r.f.iter())
            .map(|v| v * v)
            .sum::<f64>()
            / (recs.len() * 3000) as f64)
            .sqrt();
        assert!(
            fit.train_rms_n < 1e-3 * frms,
            "{} vs {frms}",
            fit.train_rms_n
        );
        // a current between the training ones
        let r = record(0.25, 4.0, 1.0, "c");
        let p = simulate_full(&fit.at(0.25), &r.x, r.ts);
        let rms = metrics::rmse(&r.f, &p);
        assert!(rms < 1e-2 * frms, "{rms}");
    }
}
