//! The study's grey-box models: Spencer's simple Bouc-Wen model and a smoothed Bingham plastic,
//! fitted by variable projection.

use super::*;
use crate::numeric::lstsq::{solve_scaled, NormalEquations};
use crate::numeric::optimize::{golden_section, nelder_mead};

// ---------------------------------------------------------------------------------------------
// Grey-box

/// The nonlinear force term g of F = c0 dx/dt + k0 x + alpha g + f0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Structure {
    /// g = z, the Bouc-Wen state (n = 1, A = 1) on x: Spencer's simple Bouc-Wen model.
    BoucWen,
    /// g = tanh((dx/dt) / v0): a Bingham plastic (yield force alpha, post-yield damping c0)
    /// smoothed over the velocity v0 (no displacement memory).
    Bingham,
    /// Spencer et al.'s full model: the Bouc-Wen element in series with the pre-yield dashpot
    /// c1, beside the spring k1 ([`super::spencer`]).
    Spencer,
}

impl Structure {
    /// Name in the report.
    pub fn as_str(self) -> &'static str {
        match self {
            Structure::BoucWen => "bouc-wen",
            Structure::Bingham => "bingham",
            Structure::Spencer => "spencer-full",
        }
    }
}

/// Parameters of the grey-box damper model at one current (x in mm, F in N).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SpencerParams {
    pub structure: Structure,
    /// Bingham: the smoothing velocity v0 (mm/s); 0 for Bouc-Wen.
    pub v0: f64,
    /// c0 (N s/mm).
    pub c0: f64,
    /// k0 (N/mm).
    pub k0: f64,
    /// alpha (N/mm): the Bouc-Wen state's weight.
    pub alpha: f64,
    /// Force offset (N).
    pub f0: f64,
    /// Bouc-Wen B (1/mm), A = 1.
    pub b: f64,
    /// Bouc-Wen Gamma (1/mm), |Gamma| <= B.
    pub gamma: f64,
    /// Full model only (0 otherwise): the pre-yield dashpot c1 (N s/mm) and the accumulator
    /// spring k1 (N/mm).
    pub c1: f64,
    pub k1: f64,
}

/// Rate (mm/s) and Bouc-Wen state z (mm, A = 1) of a displacement from rest.
pub fn states(x: &[f64], ts: f64, b: f64, gamma: f64) -> Option<(Vec<f64>, Vec<f64>)> {
    let spec = BoucWenSpec::unit(b, gamma);
    let p = spec.check().ok()?;
    // the operator gives y = d u - h = -h
    let z: Vec<f64> = p.operator().apply(x).into_iter().map(|v| -v).collect();
    Some((rate(x, ts), z))
}

/// Rate (mm/s) and the nonlinear term g of a displacement from rest.
pub fn shape_states(
    structure: Structure,
    x: &[f64],
    ts: f64,
    b: f64,
    gamma: f64,
    v0: f64,
) -> Option<(Vec<f64>, Vec<f64>)> {
    match structure {
        Structure::BoucWen => states(x, ts, b, gamma),
        Structure::Bingham => {
            if !(v0.is_finite() && v0 > 0.0) {
                return None;
            }
            let v = rate(x, ts);
            let g = v.iter().map(|w| (w / v0).tanh()).collect();
            Some((v, g))
        }
        Structure::Spencer => None,
    }
}

impl SpencerParams {
    /// The force from rest for a displacement `x` (mm) sampled at `ts` (s).
    pub fn simulate(&self, x: &[f64], ts: f64) -> Vec<f64> {
        if self.structure == Structure::Spencer {
            return super::spencer::simulate_full(self, x, ts);
        }
        match shape_states(self.structure, x, ts, self.b, self.gamma, self.v0) {
            Some((v, z)) => (0..x.len())
                .map(|k| self.c0 * v[k] + self.k0 * x[k] + self.alpha * z[k] + self.f0)
                .collect(),
            None => vec![f64::NAN; x.len()],
        }
    }

    /// Linear interpolation between `a` (at `ia`) and `b` (at `ib`) at current `i`.
    pub fn lerp(a: &SpencerParams, ia: f64, b: &SpencerParams, ib: f64, i: f64) -> SpencerParams {
        let w = if ib > ia { (i - ia) / (ib - ia) } else { 0.0 };
        let l = |p: f64, q: f64| p + w * (q - p);
        SpencerParams {
            structure: a.structure,
            v0: l(a.v0, b.v0),
            c0: l(a.c0, b.c0),
            k0: l(a.k0, b.k0),
            alpha: l(a.alpha, b.alpha),
            f0: l(a.f0, b.f0),
            b: l(a.b, b.b),
            gamma: l(a.gamma, b.gamma),
            c1: l(a.c1, b.c1),
            k1: l(a.k1, b.k1),
        }
    }
}

/// Linear columns of a record: with `scheduled`, each of (v, x, z, 1) also times I.
fn design_rows(r: &DamperRecord, v: &[f64], z: &[f64], scheduled: bool) -> Vec<[f64; 8]> {
    (0..r.x.len())
        .map(|k| {
            let base = [v[k], r.x[k], z[k], 1.0];
            let i = if scheduled { r.current } else { 0.0 };
            [
                base[0],
                base[1],
                base[2],
                base[3],
                i * base[0],
                i * base[1],
                i * base[2],
                i * base[3],
            ]
        })
        .collect()
}

/// Least squares of F on the columns of every record for fixed (B, Gamma); returns the
/// coefficients and the RMS residual (N). `m` = 4 (one current) or 8 (affine in I).
fn linear_fit(
    recs: &[&DamperRecord],
    structure: Structure,
    (b, gamma, v0): (f64, f64, f64),
    m: usize,
) -> Option<(Vec<f64>, f64)> {
    let mut ne = NormalEquations::new(m);
    let mut ff = 0.0;
    for r in recs {
        let (v, z) = shape_states(structure, &r.x, r.ts, b, gamma, v0)?;
        for (row, &f) in design_rows(r, &v, &z, m == 8).iter().zip(&r.f) {
            ne.add_row(&row[..m], f);
            ff += f * f;
        }
    }
    let n = ne.rows();
    let (g, rhs) = ne.into_parts();
    // columns scaled for conditioning (forces, velocities and states differ by decades)
    let coef: Vec<f64> = solve_scaled(&g, &rhs, 1e-12)?.iter().copied().collect();
    // residual energy = F'F - 2 c'b + c'Gc
    let mut sse = ff;
    for i in 0..m {
        sse -= 2.0 * coef[i] * rhs[i];
        for j in 0..m {
            sse += coef[i] * g[(i, j)] * coef[j];
        }
    }
    let rms = (sse.max(0.0) / n.max(1) as f64).sqrt();
    rms.is_finite().then_some((coef, rms))
}

/// (B, Gamma) from the search coordinates: B = exp(p) / range, Gamma = B tanh(q).
fn bg(p: &[f64; 2], range: f64) -> (f64, f64) {
    let b = p[0].clamp(-30.0, 30.0).exp() / range;
    (b, b * p[1].clamp(-20.0, 20.0).tanh())
}

/// A fit: (B, Gamma) and the linear coefficients, with the training RMS (N).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SpencerFit {
    pub structure: Structure,
    pub v0: f64,
    pub b: f64,
    pub gamma: f64,
    /// c0, k0, alpha, f0 (full model: then c1, k1) and, when scheduled, their slopes in I
    /// (per A) in the same order.
    pub coef: Vec<f64>,
    pub train_rms_n: f64,
}

impl SpencerFit {
    /// The parameters at current `i` (A).
    pub fn at(&self, i: f64) -> SpencerParams {
        let base = if self.structure == Structure::Spencer {
            6
        } else {
            4
        };
        let c = |k: usize| {
            if k >= base {
                return 0.0;
            }
            self.coef[k]
                + if self.coef.len() == 2 * base {
                    i * self.coef[k + base]
                } else {
                    0.0
                }
        };
        SpencerParams {
            structure: self.structure,
            v0: self.v0,
            c0: c(0),
            k0: c(1),
            alpha: c(2),
            f0: c(3),
            b: self.b,
            gamma: self.gamma,
            c1: c(4),
            k1: c(5),
        }
    }
}

/// Fits the Spencer (Bouc-Wen) model to records (`scheduled`: coefficients affine in I).
pub fn fit_spencer(recs: &[&DamperRecord], scheduled: bool) -> Option<SpencerFit> {
    fit_structure(recs, Structure::BoucWen, scheduled)
}

/// Fits a model of the given structure to records: one model (`scheduled`: coefficients
/// affine in I). Variable projection: least squares for (c0, k0, alpha, f0) inside; outside,
/// Bouc-Wen: a grid then Nelder-Mead on (ln B, atanh(Gamma / B)); Bingham: a grid then a
/// golden-section search on ln v0. The full model is not linear in any of its dashpots:
/// Levenberg-Marquardt from the simple Bouc-Wen model's fit ([`super::spencer::fit_full`]).
pub fn fit_structure(
    recs: &[&DamperRecord],
    structure: Structure,
    scheduled: bool,
) -> Option<SpencerFit> {
    let m = if scheduled { 8 } else { 4 };
    let (b, gamma, v0) = match structure {
        Structure::Spencer => {
            let mid = recs.iter().map(|r| r.current).sum::<f64>() / recs.len().max(1) as f64;
            let anchor = fit_structure(recs, Structure::BoucWen, scheduled)?.at(mid);
            return super::spencer::fit_full(recs, scheduled, &anchor);
        }
        Structure::BoucWen => {
            let range = recs
                .iter()
                .flat_map(|r| r.x.iter())
                .fold(0.0f64, |a, v| a.max(v.abs()))
                .max(1e-12);
            let cost = |p: &[f64; 2]| {
                let (b, g) = bg(p, range);
                linear_fit(recs, structure, (b, g, 0.0), m).map_or(f64::INFINITY, |(_, r)| r)
            };
            let grid: Vec<[f64; 2]> = [1.0f64, 3.0, 10.0, 30.0, 100.0, 300.0]
                .iter()
                .flat_map(|&br| [-0.5f64, 0.0, 0.5].map(|q| [br.ln(), q]))
                .collect();
            let costs: Vec<f64> = grid.par_iter().map(&cost).collect();
            let best = (0..grid.len()).min_by(|&a, &b| costs[a].total_cmp(&costs[b]))?;
            let p = nelder_mead(&cost, grid[best], 0.3, 200);
            let (b, g) = bg(&p, range);
            (b, g, 0.0)
        }
        Structure::Bingham => {
            let cost = |lv: f64| {
                linear_fit(recs, structure, (0.0, 0.0, lv.exp()), m)
                    .map_or(f64::INFINITY, |(_, r)| r)
            };
            let grid: Vec<f64> = [0.5f64, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0]
                .iter()
                .map(|v| v.ln())
                .collect();
            let costs: Vec<f64> = grid.par_iter().map(|&p| cost(p)).collect();
            let best = (0..grid.len()).min_by(|&a, &b| costs[a].total_cmp(&costs[b]))?;
            let lv = golden_section(&cost, grid[best] - 0.8, grid[best] + 0.8, 40);
            (0.0, 0.0, lv.exp())
        }
    };
    let (coef, train_rms_n) = linear_fit(recs, structure, (b, gamma, v0), m)?;
    Some(SpencerFit {
        structure,
        v0,
        b,
        gamma,
        coef,
        train_rms_n,
    })
}

/// One Spencer model per training current.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PerCurrent {
    /// (current, fit), by increasing current.
    pub fits: Vec<(f64, SpencerFit)>,
}

impl PerCurrent {
    /// Every parameter interpolated linearly between the neighbouring training currents
    /// (held at the end values outside them).
    pub fn at(&self, i: f64) -> SpencerParams {
        let f = &self.fits;
        let k = f.iter().position(|(c, _)| *c >= i).unwrap_or(f.len() - 1);
        if k == 0 || (f[k].0 - i).abs() < 1e-12 || f[k].0 < i {
            return f[k].1.at(i);
        }
        SpencerParams::lerp(&f[k - 1].1.at(i), f[k - 1].0, &f[k].1.at(i), f[k].0, i)
    }
}

/// Fits one model per distinct training current.
pub fn fit_per_current(
    recs: &[DamperRecord],
    structure: Structure,
) -> Result<PerCurrent, MrDamperError> {
    let mut currents: Vec<f64> = recs.iter().map(|r| r.current).collect();
    currents.sort_by(f64::total_cmp);
    currents.dedup();
    let fits: Vec<Option<SpencerFit>> = currents
        .par_iter()
        .map(|&i| {
            let mine: Vec<&DamperRecord> = recs.iter().filter(|r| r.current == i).collect();
            fit_structure(&mine, structure, false)
        })
        .collect();
    let mut out = Vec::new();
    for (i, f) in currents.into_iter().zip(fits) {
        out.push((
            i,
            f.ok_or(MrDamperError::NoCurrent {
                current: i,
                have: "(the fit at this current failed: non-finite least squares)".into(),
            })?,
        ));
    }
    if out.is_empty() {
        return Err(MrDamperError::NoCurrent {
            current: f64::NAN,
            have: "none".into(),
        });
    }
    Ok(PerCurrent { fits: out })
}
