//! The fitting algorithm for one output: variable projection (Golub & Pereyra 1973) with the
//! linear-in-parameter coefficients (path gains, Prandtl-Ishlinskii weights, Bouc-Wen d and A,
//! offset) solved by (non-negative) least squares inside, and the nonlinear parameters
//! (dynamics f_n and zeta, creep gains, Bouc-Wen B and Gamma) moved by Levenberg-Marquardt
//! outside, with Kaufman's projected Jacobian.
//!
//! ## References
//! - G. H. Golub, V. Pereyra, "The differentiation of pseudo-inverses and nonlinear least squares
//!   problems whose variables separate", SIAM J. Numer. Anal. 10(2):413-432, 1973.
//! - L. Kaufman, "A variable projection method for solving separable nonlinear least squares
//!   problems", BIT 15:49-57, 1975.
//! - D. W. Marquardt, "An algorithm for least-squares estimation of nonlinear parameters",
//!   J. SIAM 11(2):431-441, 1963; J. J. More, "The Levenberg-Marquardt algorithm:
//!   implementation and theory", Lecture Notes in Math. 630, 1978.

use super::nnls::{chol_solve, nnls_gram, NnlsSolution};
use super::{FitOptions, GreyBoxError, HysteresisOperator};
use crate::effect::bouc_wen::BoucWenSpec;
use crate::effect::creep::{Creep, CreepSpec};
use crate::effect::dynamics::{Dynamics, DynamicsSpec};
use crate::effect::hysteresis::{HysteresisSpec, LinearSpec};
use crate::effect::play::play_operator;
use crate::effect::prandtl_ishlinskii::PrandtlIshlinskiiSpec;
use crate::effect::viscous::ViscousSpec;
use crate::effect::Operator;
use crate::plant::{OutputSpec, PathSpec};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::borrow::Cow;

/// Finite-difference step in the (transformed) parameter space.
const FD_STEP: f64 = 1e-6;
/// Transformed parameters are kept in [-LIMIT, LIMIT] (the logistic maps saturate beyond).
const LIMIT: f64 = 30.0;

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

fn logit(p: f64) -> f64 {
    let p = p.clamp(1e-12, 1.0 - 1e-12);
    (p / (1.0 - p)).ln()
}

/// A value in [lo, hi] on a log scale from an unbounded parameter.
fn log_bounded(x: f64, lo: f64, hi: f64) -> f64 {
    (lo.ln() + (hi.ln() - lo.ln()) * sigmoid(x)).exp()
}

fn log_bounded_inv(v: f64, lo: f64, hi: f64) -> f64 {
    logit((v.ln() - lo.ln()) / (hi.ln() - lo.ln()))
}

/// The hysteresis of one path, as the fit sees it.
#[derive(Debug, Clone)]
enum PathKind {
    /// w = g u.
    Linear,
    /// w = p0 u + sign * sum p_k z_k, p_k >= 0 (plays precomputed), plus, with `bw`,
    /// - A htilde(B, Gamma), A >= 0 (the combined operator).
    Pi {
        thresholds: Vec<f64>,
        sign: f64,
        plays: Vec<Vec<f64>>,
        bw: Option<(usize, f64)>,
    },
    /// w = d u - A htilde(B, Gamma), A >= 0; B = exp(theta)/range, Gamma = B tanh(theta').
    BoucWen { at: usize, range: f64 },
}

#[derive(Debug, Clone)]
struct FitPath {
    input: usize,
    kind: PathKind,
}

/// Creep (Kelvin-Voigt chain, exact ZOH) then dynamics (second order, exact ZOH) with the
/// coefficients of `effect::creep` and `effect::dynamics`, in one pass without allocation
/// per sample.
struct LtiChain {
    a: Vec<f64>,
    g: Vec<f64>,
    dynamics: Option<([f64; 4], [f64; 2])>,
    invalid: bool,
}

impl LtiChain {
    fn new(ts: f64, creep: Option<&Creep>, dynamics: Option<&Dynamics>) -> LtiChain {
        let (a, g) = match creep {
            Some(c) if c.gains.iter().any(|g| *g != 0.0) => (
                c.time_constants_s.iter().map(|t| (-ts / t).exp()).collect(),
                c.gains.clone(),
            ),
            _ => (Vec::new(), Vec::new()),
        };
        let mut invalid = false;
        let dynamics = dynamics.and_then(|d| match d.discretise(ts) {
            Ok((phi, gam)) => Some((
                [phi[(0, 0)], phi[(0, 1)], phi[(1, 0)], phi[(1, 1)]],
                [gam[0], gam[1]],
            )),
            Err(_) => {
                invalid = true;
                None
            }
        });
        LtiChain {
            a,
            g,
            dynamics,
            invalid,
        }
    }

    fn apply(&self, x: &[f64]) -> Vec<f64> {
        if self.invalid {
            return vec![f64::NAN; x.len()];
        }
        let mut out = x.to_vec();
        if !self.a.is_empty() {
            let mut z = vec![0.0; self.a.len()];
            for v in out.iter_mut() {
                let w = *v;
                let mut o = w;
                for ((zi, &ai), &gi) in z.iter_mut().zip(&self.a).zip(&self.g) {
                    o += gi * *zi;
                    *zi = ai * *zi + (1.0 - ai) * w;
                }
                *v = o;
            }
        }
        if let Some((p, gm)) = self.dynamics {
            let (mut x0, mut x1) = (0.0, 0.0);
            for v in out.iter_mut() {
                let w = *v;
                *v = x0;
                let n0 = p[0] * x0 + p[1] * x1 + gm[0] * w;
                let n1 = p[2] * x0 + p[3] * x1 + gm[1] * w;
                x0 = n0;
                x1 = n1;
            }
        }
        out
    }
}

/// One column of the Jacobian: (parameter index, d yhat / d theta before projection).
type JacobianJob<'a> = Box<dyn Fn() -> (usize, Vec<f64>) + Sync + 'a>;

/// Everything needed to evaluate the model of one output for a parameter vector.
pub(crate) struct OutputProblem<'a> {
    pub name: String,
    y: &'a [f64],
    u: Vec<&'a [f64]>,
    pub input_names: Vec<String>,
    ts: f64,
    paths: Vec<FitPath>,
    taus: Vec<f64>,
    dynamics: bool,
    /// Per path, the rate of its input (empty without `viscous`).
    rates: Vec<Vec<f64>>,
    creep_at: usize,
    n_theta: usize,
    f_bounds: (f64, f64),
    z_bounds: (f64, f64),
}

/// One evaluation of the projected problem.
pub(crate) struct Eval {
    pub cost: f64,
    pub r: Vec<f64>,
    pub coef: Vec<f64>,
    psi: Vec<Vec<f64>>,
    sol: NnlsSolution,
}

/// What the structure of one output is: its paths (input index, operator) and the chain.
#[derive(Debug, Clone)]
pub(crate) struct OutputStructure {
    pub paths: Vec<usize>,
    pub operator: Option<HysteresisOperator>,
    pub creep_taus: Vec<f64>,
    pub dynamics: bool,
    /// A rate column c du/dt per path (viscous damping).
    pub viscous: bool,
}

/// Linear least squares of y on the columns (free coefficients), by the normal equations.
fn least_squares(cols: &[&[f64]], y: &[f64]) -> Vec<f64> {
    let m = cols.len();
    let g = DMatrix::from_fn(m, m, |i, j| dot(cols[i], cols[j]));
    let b = DVector::from_fn(m, |i, _| dot(cols[i], y));
    nnls_gram(&g, &b, &vec![false; m]).coef
}

/// Dot product with eight partial sums (lets the compiler vectorise; order is fixed, so the
/// result is the same on every run).
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 8];
    let ca = a.chunks_exact(8);
    let cb = b.chunks_exact(8);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    let mut s = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// Thresholds spread over the input range: r_k = k R / (n + 1), k = 1..n, R = max |u|.
pub(crate) fn pi_thresholds(u: &[f64], n: usize) -> Vec<f64> {
    let r = u.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    (1..=n).map(|k| k as f64 * r / (n + 1) as f64).collect()
}

fn max_abs(u: &[f64]) -> f64 {
    u.iter().fold(0.0f64, |a, v| a.max(v.abs())).max(1e-300)
}

fn plays_of(u: &[f64], thresholds: &[f64]) -> Vec<Vec<f64>> {
    thresholds
        .par_iter()
        .map(|&r| {
            let mut z = 0.0;
            u.iter()
                .map(|&v| {
                    z = play_operator(v, r, z);
                    z
                })
                .collect()
        })
        .collect()
}

/// -htilde for A = 1 (h is linear in A for fixed B and Gamma: the exact update scales with A).
fn bouc_wen_column(u: &[f64], b: f64, gamma: f64) -> Vec<f64> {
    let spec = BoucWenSpec {
        d: 0.0,
        a: 1.0,
        b,
        gamma,
        n: 1.0,
        initial_h: 0.0,
    };
    match spec.check() {
        Ok(p) => p.operator().apply(u),
        Err(_) => vec![f64::NAN; u.len()],
    }
}

impl<'a> OutputProblem<'a> {
    /// Set up the problem of one output; `plays` play operators per Prandtl-Ishlinskii path.
    pub fn new(
        name: &str,
        y: &'a [f64],
        u: Vec<&'a [f64]>,
        input_names: Vec<String>,
        ts: f64,
        structure: &OutputStructure,
        plays: usize,
    ) -> OutputProblem<'a> {
        let mut n_theta = 0;
        if structure.dynamics {
            n_theta += 2;
        }
        let creep_at = n_theta;
        n_theta += structure.creep_taus.len();
        // sign of each path's gain from a linear fit (PI weights share it)
        let mut cols: Vec<&[f64]> = structure.paths.iter().map(|&j| u[j]).collect();
        let ones = vec![1.0; y.len()];
        cols.push(&ones);
        let lin = least_squares(&cols, y);
        let mut paths = Vec::new();
        for (k, &j) in structure.paths.iter().enumerate() {
            let kind = match structure.operator {
                None => PathKind::Linear,
                Some(
                    op @ (HysteresisOperator::PrandtlIshlinskii | HysteresisOperator::Combined),
                ) => {
                    let thresholds = pi_thresholds(u[j], plays);
                    let plays = plays_of(u[j], &thresholds);
                    let sign = if lin[k] < 0.0 { -1.0 } else { 1.0 };
                    // a negative path cannot carry a Bouc-Wen term (A > 0 in the plant file)
                    let bw = if op == HysteresisOperator::Combined && sign > 0.0 {
                        let at = n_theta;
                        n_theta += 2;
                        Some((at, max_abs(u[j])))
                    } else {
                        None
                    };
                    PathKind::Pi {
                        thresholds,
                        sign,
                        plays,
                        bw,
                    }
                }
                Some(HysteresisOperator::BoucWen) => {
                    let at = n_theta;
                    n_theta += 2;
                    PathKind::BoucWen {
                        at,
                        range: max_abs(u[j]),
                    }
                }
            };
            paths.push(FitPath { input: j, kind });
        }
        let fs = 1.0 / ts;
        let rates = if structure.viscous {
            structure
                .paths
                .iter()
                .map(|&j| crate::effect::viscous::rate(u[j], ts))
                .collect()
        } else {
            Vec::new()
        };
        OutputProblem {
            rates,
            name: name.to_string(),
            y,
            u,
            input_names,
            ts,
            paths,
            taus: structure.creep_taus.clone(),
            dynamics: structure.dynamics,
            creep_at,
            n_theta,
            f_bounds: (fs / 1000.0, 0.49 * fs),
            z_bounds: (2e-3, 5.0),
        }
    }

    pub fn n_theta(&self) -> usize {
        self.n_theta
    }

    fn dynamics_of(&self, th: &[f64]) -> Option<Dynamics> {
        if !self.dynamics {
            return None;
        }
        let (flo, fhi) = self.f_bounds;
        let (zlo, zhi) = self.z_bounds;
        Some(Dynamics {
            natural_frequency_hz: log_bounded(th[0], flo, fhi),
            damping_ratio: log_bounded(th[1], zlo, zhi),
            dc_gain: 1.0,
        })
    }

    fn creep_of(&self, th: &[f64]) -> Option<Creep> {
        if self.taus.is_empty() {
            return None;
        }
        Some(Creep {
            time_constants_s: self.taus.clone(),
            gains: th[self.creep_at..self.creep_at + self.taus.len()].to_vec(),
        })
    }

    fn bouc_wen_params(th: &[f64], at: usize, range: f64) -> (f64, f64) {
        let b = th[at].exp() / range;
        (b, b * th[at + 1].clamp(-LIMIT, LIMIT).tanh())
    }

    /// The raw basis columns (before creep and dynamics) and which must have c >= 0; the
    /// constant column (offset) is last.
    fn basis(&self, th: &[f64]) -> (Vec<Cow<'_, [f64]>>, Vec<bool>) {
        let mut cols: Vec<Cow<[f64]>> = Vec::new();
        let mut cons = Vec::new();
        for (pi, p) in self.paths.iter().enumerate() {
            let u = self.u[p.input];
            cols.push(Cow::Borrowed(u));
            cons.push(false);
            match &p.kind {
                PathKind::Linear => {}
                PathKind::Pi {
                    sign, plays, bw, ..
                } => {
                    for z in plays {
                        if *sign > 0.0 {
                            cols.push(Cow::Borrowed(z.as_slice()));
                        } else {
                            cols.push(Cow::Owned(z.iter().map(|v| -v).collect()));
                        }
                        cons.push(true);
                    }
                    if let Some((at, range)) = bw {
                        let (b, g) = Self::bouc_wen_params(th, *at, *range);
                        cols.push(Cow::Owned(bouc_wen_column(u, b, g)));
                        cons.push(true);
                    }
                }
                PathKind::BoucWen { at, range } => {
                    let (b, g) = Self::bouc_wen_params(th, *at, *range);
                    cols.push(Cow::Owned(bouc_wen_column(u, b, g)));
                    cons.push(true);
                }
            }
            if let Some(r) = self.rates.get(pi) {
                cols.push(Cow::Borrowed(r.as_slice()));
                cons.push(false);
            }
        }
        cols.push(Cow::Owned(vec![1.0; self.y.len()]));
        cons.push(false);
        (cols, cons)
    }

    /// Creep then dynamics on one signal (the plant's recursions, fused in one pass).
    fn chain(&self, x: &[f64], creep: Option<&Creep>, dynamics: Option<&Dynamics>) -> Vec<f64> {
        LtiChain::new(self.ts, creep, dynamics).apply(x)
    }

    /// Evaluate: basis through the chain, (non-negative) least squares, residual.
    /// `with_dynamics = false` evaluates the static model (initialisation).
    pub fn eval(&self, th: &[f64], with_dynamics: bool) -> Option<Eval> {
        let (phi, cons) = self.basis(th);
        let creep = self.creep_of(th);
        let dynamics = if with_dynamics {
            self.dynamics_of(th)
        } else {
            None
        };
        let last = phi.len() - 1;
        let lti = LtiChain::new(self.ts, creep.as_ref(), dynamics.as_ref());
        let psi: Vec<Vec<f64>> = phi
            .par_iter()
            .enumerate()
            .map(|(k, col)| {
                if k == last {
                    col.to_vec()
                } else {
                    lti.apply(col)
                }
            })
            .collect();
        let m = psi.len();
        let rows: Vec<Vec<f64>> = (0..m)
            .into_par_iter()
            .map(|i| {
                (0..m)
                    .map(|j| if j < i { 0.0 } else { dot(&psi[i], &psi[j]) })
                    .collect()
            })
            .collect();
        let g = DMatrix::from_fn(m, m, |i, j| if j >= i { rows[i][j] } else { rows[j][i] });
        let b = DVector::from_iterator(m, psi.iter().map(|c| dot(c, self.y)));
        if g.iter().any(|v| !v.is_finite()) || b.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let sol = nnls_gram(&g, &b, &cons);
        let mut r = self.y.to_vec();
        for (c, col) in sol.coef.iter().zip(&psi) {
            if *c != 0.0 {
                for (rv, v) in r.iter_mut().zip(col) {
                    *rv -= c * v;
                }
            }
        }
        let cost = 0.5 * r.iter().map(|v| v * v).sum::<f64>();
        if !cost.is_finite() {
            return None;
        }
        Some(Eval {
            cost,
            r,
            coef: sol.coef.clone(),
            psi,
            sol,
        })
    }

    /// Kaufman's Jacobian of the fitted output with respect to theta: partial derivatives at
    /// fixed linear coefficients, projected onto the orthogonal complement of the active
    /// regressors. Columns: d yhat / d theta.
    fn jacobian(&self, th: &[f64], ev: &Eval) -> DMatrix<f64> {
        let n = self.y.len();
        let p = self.n_theta;
        let (phi, _) = self.basis(th);
        let creep = self.creep_of(th);
        let dynamics = self.dynamics_of(th);
        // the unfiltered hysteresis output and the column ranges of the BW paths
        let mut w = vec![0.0; n];
        let mut k = 0;
        let mut bw_cols = Vec::new();
        let extra = usize::from(!self.rates.is_empty());
        for path in &self.paths {
            let ncols = extra
                + match &path.kind {
                    PathKind::Linear => 1,
                    PathKind::Pi { plays, bw, .. } => match bw {
                        None => 1 + plays.len(),
                        Some((at, range)) => {
                            bw_cols.push((k + 1 + plays.len(), *at, *range, path.input));
                            2 + plays.len()
                        }
                    },
                    PathKind::BoucWen { at, range } => {
                        bw_cols.push((k + 1, *at, *range, path.input));
                        2
                    }
                };
            for (col, &coef) in phi[k..k + ncols].iter().zip(&ev.coef[k..k + ncols]) {
                if coef != 0.0 {
                    for (wv, v) in w.iter_mut().zip(col.iter()) {
                        *wv += coef * v;
                    }
                }
            }
            k += ncols;
        }
        let mut jobs: Vec<JacobianJob<'_>> = Vec::new();
        let w = &w;
        let creep_ref = creep.as_ref();
        if let Some(d0) = dynamics {
            let ws = match creep_ref {
                Some(c) => c.operator(self.ts).apply(w),
                None => w.clone(),
            };
            let ws = std::sync::Arc::new(ws);
            for q in 0..2 {
                let ws = ws.clone();
                jobs.push(Box::new(move || {
                    let mut t2 = th.to_vec();
                    t2[q] += FD_STEP;
                    let d1 = self.dynamics_of(&t2).unwrap_or(d0);
                    let a = self.chain(&ws, None, Some(&d0));
                    let b = self.chain(&ws, None, Some(&d1));
                    (
                        q,
                        b.iter().zip(&a).map(|(b, a)| (b - a) / FD_STEP).collect(),
                    )
                }));
            }
        }
        for i in 0..self.taus.len() {
            let tau = self.taus[i];
            jobs.push(Box::new(move || {
                let one = Creep {
                    time_constants_s: vec![tau],
                    gains: vec![1.0],
                };
                let z: Vec<f64> = one
                    .operator(self.ts)
                    .apply(w)
                    .iter()
                    .zip(w)
                    .map(|(a, b)| a - b)
                    .collect();
                (self.creep_at + i, self.chain(&z, None, dynamics.as_ref()))
            }));
        }
        for &(col, at, range, input) in &bw_cols {
            let a_coef = ev.coef[col];
            let base = std::sync::Arc::new(phi[col].to_vec());
            for q in 0..2 {
                let base = base.clone();
                jobs.push(Box::new(move || {
                    let mut t2 = th.to_vec();
                    t2[at + q] += FD_STEP;
                    let (b, g) = Self::bouc_wen_params(&t2, at, range);
                    let c1 = bouc_wen_column(self.u[input], b, g);
                    let diff: Vec<f64> = c1
                        .iter()
                        .zip(base.iter())
                        .map(|(x, y)| a_coef * (x - y) / FD_STEP)
                        .collect();
                    (at + q, self.chain(&diff, creep_ref, dynamics.as_ref()))
                }));
            }
        }
        let cols: Vec<(usize, Vec<f64>)> = jobs.par_iter().map(|f| f()).collect();
        // projection onto the complement of the passive regressors
        let sol = &ev.sol;
        let cols: Vec<(usize, Vec<f64>)> = cols
            .into_par_iter()
            .map(|(q, mut c)| {
                if c.iter().all(|v| v.is_finite()) && !sol.passive.is_empty() {
                    let v: Vec<f64> = sol
                        .passive
                        .iter()
                        .map(|&i| dot(&ev.psi[i], &c) * sol.scale[i])
                        .collect();
                    let a = chol_solve(&sol.chol_l, &v);
                    for (k, &i) in sol.passive.iter().enumerate() {
                        let alpha = a[k] * sol.scale[i];
                        for (cv, pv) in c.iter_mut().zip(&ev.psi[i]) {
                            *cv -= alpha * pv;
                        }
                    }
                }
                (q, c)
            })
            .collect();
        let mut j = DMatrix::zeros(n, p);
        for (q, c) in cols {
            for (i, v) in c.into_iter().enumerate() {
                j[(i, q)] = if v.is_finite() { v } else { 0.0 };
            }
        }
        j
    }

    /// Initial nonlinear parameters: Bouc-Wen from a grid of static fits, dynamics from a grid
    /// of natural frequencies and damping ratios (on a reduced problem `coarse`), creep at 0.
    /// The Bouc-Wen parameter slot of each path, if it has one.
    fn bouc_wen_slots(&self) -> Vec<Option<usize>> {
        self.paths
            .iter()
            .map(|p| match p.kind {
                PathKind::BoucWen { at, .. } => Some(at),
                PathKind::Pi {
                    bw: Some((at, _)), ..
                } => Some(at),
                _ => None,
            })
            .collect()
    }

    /// This problem's parameters from those of `other` (same chain, other operator): dynamics
    /// and creep copied, Bouc-Wen parameters copied path by path where both have them.
    pub fn theta_from_bouc_wen(&self, other: &OutputProblem, th: &[f64]) -> Vec<f64> {
        let mut t = vec![0.0; self.n_theta];
        let shared = self.creep_at + self.taus.len();
        t[..shared].copy_from_slice(&th[..shared]);
        for (a, b) in self
            .bouc_wen_slots()
            .into_iter()
            .zip(other.bouc_wen_slots())
        {
            if let (Some(a), Some(b)) = (a, b) {
                t[a] = th[b];
                t[a + 1] = th[b + 1];
            }
        }
        t
    }

    /// Which parameters are not creep gains (the first Levenberg-Marquardt stage holds the
    /// creep gains at zero so that the dynamics settle first).
    pub fn without_creep(&self) -> Vec<bool> {
        (0..self.n_theta)
            .map(|i| i < self.creep_at || i >= self.creep_at + self.taus.len())
            .collect()
    }

    /// Starting points: Bouc-Wen from a grid of static fits, then the `starts` best local
    /// minima of a grid of natural frequencies and damping ratios (on a reduced problem
    /// `coarse`), creep at 0.
    pub fn initial(&self, coarse: &OutputProblem, starts: usize) -> Vec<Vec<f64>> {
        let mut th = vec![0.0; self.n_theta];
        if self.dynamics {
            th[0] = log_bounded_inv(0.1 / self.ts, self.f_bounds.0, self.f_bounds.1);
            th[1] = log_bounded_inv(0.1, self.z_bounds.0, self.z_bounds.1);
        }
        let bw: Vec<usize> = self
            .paths
            .iter()
            .filter_map(|p| match p.kind {
                PathKind::BoucWen { at, .. } => Some(at),
                PathKind::Pi {
                    bw: Some((at, _)), ..
                } => Some(at),
                _ => None,
            })
            .collect();
        if !bw.is_empty() {
            let mut best = (f64::INFINITY, 0.0, 0.0);
            for br in [0.1f64, 0.3, 1.0, 3.0, 10.0] {
                for ratio in [-0.5f64, 0.0, 0.5] {
                    let mut t = th.clone();
                    for &at in &bw {
                        t[at] = br.ln();
                        t[at + 1] = ratio.atanh();
                    }
                    if let Some(e) = self.eval(&t, false) {
                        if e.cost < best.0 {
                            best = (e.cost, br.ln(), ratio.atanh());
                        }
                    }
                }
            }
            for &at in &bw {
                th[at] = best.1;
                th[at + 1] = best.2;
            }
        }
        if self.dynamics {
            let (flo, fhi) = (2.0 * self.f_bounds.0, 0.45 / self.ts);
            let steps = ((fhi / flo).ln() / 1.12f64.ln()).ceil() as usize;
            let grid: Vec<(f64, f64)> = (0..=steps)
                .flat_map(|i| {
                    let f = flo * (fhi / flo).powf(i as f64 / steps as f64);
                    [0.02, 0.1, 0.4, 1.0].map(|z| (f, z))
                })
                .collect();
            let costs: Vec<f64> = grid
                .iter()
                .map(|&(f, z)| {
                    let mut t = th.clone();
                    t[0] = log_bounded_inv(f, self.f_bounds.0, self.f_bounds.1);
                    t[1] = log_bounded_inv(z, self.z_bounds.0, self.z_bounds.1);
                    coarse.eval(&t, true).map_or(f64::INFINITY, |e| e.cost)
                })
                .collect();
            // best damping per frequency, then the local minima along the frequency axis
            let per_f: Vec<usize> = (0..=steps)
                .map(|i| {
                    (4 * i..4 * i + 4)
                        .min_by(|&a, &b| costs[a].total_cmp(&costs[b]))
                        .unwrap_or(4 * i)
                })
                .collect();
            let c = |i: usize| costs[per_f[i]];
            let mut minima: Vec<usize> = (0..per_f.len())
                .filter(|&i| {
                    (i == 0 || c(i) <= c(i - 1)) && (i + 1 == per_f.len() || c(i) <= c(i + 1))
                })
                .map(|i| per_f[i])
                .collect();
            minima.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]));
            minima.truncate(starts.max(1));
            if minima.is_empty() {
                minima.push(0);
            }
            return minima
                .into_iter()
                .map(|best| {
                    let mut t = th.clone();
                    t[0] = log_bounded_inv(grid[best].0, self.f_bounds.0, self.f_bounds.1);
                    t[1] = log_bounded_inv(grid[best].1, self.z_bounds.0, self.z_bounds.1);
                    t
                })
                .collect();
        }
        vec![th]
    }

    /// The fitted output as a plant output spec.
    pub fn output_spec(&self, th: &[f64], coef: &[f64]) -> OutputSpec {
        let mut k = 0;
        let mut paths = Vec::new();
        for (pi, p) in self.paths.iter().enumerate() {
            let input = self.input_names[p.input].clone();
            let hysteresis = match &p.kind {
                PathKind::Linear => {
                    k += 1;
                    HysteresisSpec::Linear(LinearSpec { gain: coef[k - 1] })
                }
                PathKind::Pi {
                    thresholds,
                    sign,
                    bw,
                    ..
                } => {
                    let n = thresholds.len();
                    let spec = PrandtlIshlinskiiSpec {
                        linear_weight: coef[k],
                        thresholds: thresholds.clone(),
                        weights: coef[k + 1..k + 1 + n].iter().map(|w| sign * w).collect(),
                        initial_state: 0.0,
                        dead_zones: None,
                    };
                    k += 1 + n;
                    if let Some((at, range)) = bw {
                        let a = coef[k];
                        k += 1;
                        if a > 0.0 {
                            let (b, g) = Self::bouc_wen_params(th, *at, *range);
                            paths.push(PathSpec {
                                input: input.clone(),
                                hysteresis: HysteresisSpec::BoucWen(BoucWenSpec {
                                    d: 0.0,
                                    a,
                                    b,
                                    gamma: g,
                                    n: 1.0,
                                    initial_h: 0.0,
                                }),
                                viscous: None,
                                dynamics: None,
                            });
                        }
                    }
                    HysteresisSpec::PrandtlIshlinskii(spec)
                }
                PathKind::BoucWen { at, range } => {
                    let (b, g) = Self::bouc_wen_params(th, *at, *range);
                    let (d, a) = (coef[k], coef[k + 1]);
                    k += 2;
                    if a > 0.0 {
                        HysteresisSpec::BoucWen(BoucWenSpec {
                            d,
                            a,
                            b,
                            gamma: g,
                            n: 1.0,
                            initial_h: 0.0,
                        })
                    } else {
                        HysteresisSpec::Linear(LinearSpec { gain: d })
                    }
                }
            };
            let viscous = (pi < self.rates.len()).then(|| {
                k += 1;
                ViscousSpec {
                    coefficient: coef[k - 1],
                }
            });
            paths.push(PathSpec {
                input,
                hysteresis,
                viscous,
                dynamics: None,
            });
        }
        let offset = coef[k];
        OutputSpec {
            name: self.name.clone(),
            paths,
            offset,
            creep: self.creep_of(th).map(|c| CreepSpec {
                time_constants_s: c.time_constants_s,
                gains: Some(c.gains),
                percent_per_decade: None,
            }),
            dynamics: self.dynamics_of(th).map(|d| DynamicsSpec {
                natural_frequency_hz: d.natural_frequency_hz,
                damping_ratio: d.damping_ratio,
                dc_gain: 1.0,
            }),
        }
    }
}

/// The result of Levenberg-Marquardt on one output.
pub(crate) struct LmResult {
    pub theta: Vec<f64>,
    pub eval: Eval,
    pub iterations: usize,
    pub converged: bool,
    pub message: String,
}

/// Levenberg-Marquardt with More's diagonal scaling on the projected problem.
pub(crate) fn levenberg_marquardt(
    prob: &OutputProblem,
    theta0: Vec<f64>,
    free: &[bool],
    opts: &FitOptions,
) -> Result<LmResult, GreyBoxError> {
    let non_finite = |what: &str| GreyBoxError::NonFinite {
        output: prob.name.clone(),
        what: what.into(),
    };
    let mut th = theta0;
    let mut ev = prob
        .eval(&th, true)
        .ok_or_else(|| non_finite("the initial model"))?;
    let idx: Vec<usize> = (0..prob.n_theta()).filter(|&i| free[i]).collect();
    let p = idx.len();
    if p == 0 {
        return Ok(LmResult {
            theta: th,
            eval: ev,
            iterations: 0,
            converged: true,
            message: "linear least squares (no nonlinear parameter)".into(),
        });
    }
    let y_mean = prob.y.iter().sum::<f64>() / prob.y.len() as f64;
    let y_energy = 0.5 * prob.y.iter().map(|v| (v - y_mean).powi(2)).sum::<f64>();
    let mut lambda = 1e-3;
    let mut dmax = vec![0.0f64; p];
    let mut small = 0;
    for it in 1..=opts.max_iterations {
        if ev.cost <= 1e-24 * y_energy {
            return Ok(LmResult {
                theta: th,
                eval: ev,
                iterations: it - 1,
                converged: true,
                message: "the residual is zero to rounding".into(),
            });
        }
        let j = prob.jacobian(&th, &ev).select_columns(idx.iter());
        let a = j.tr_mul(&j);
        let g = j.tr_mul(&DVector::from_column_slice(&ev.r));
        for i in 0..p {
            dmax[i] = dmax[i].max(a[(i, i)]);
        }
        // gradient test: cosine between the residual and each Jacobian column
        let rnorm = (2.0 * ev.cost).sqrt();
        let cosine = (0..p)
            .map(|i| {
                let d = a[(i, i)].sqrt() * rnorm;
                if d > 0.0 {
                    g[i].abs() / d
                } else {
                    0.0
                }
            })
            .fold(0.0, f64::max);
        if cosine < 1e-9 {
            return Ok(LmResult {
                theta: th,
                eval: ev,
                iterations: it - 1,
                converged: true,
                message: "the gradient vanishes".into(),
            });
        }
        loop {
            let mut m = a.clone();
            for i in 0..p {
                m[(i, i)] += lambda * dmax[i].max(1e-30);
            }
            let step = m.cholesky().map(|c| c.solve(&g));
            let Some(step) = step else {
                lambda *= 10.0;
                if lambda > 1e16 {
                    break;
                }
                continue;
            };
            let mut t_new = th.clone();
            for (k, &i) in idx.iter().enumerate() {
                t_new[i] = (th[i] + step[k]).clamp(-LIMIT, LIMIT);
            }
            match prob.eval(&t_new, true) {
                Some(e) if e.cost < ev.cost => {
                    let rel = (ev.cost - e.cost) / ev.cost;
                    th = t_new;
                    ev = e;
                    lambda = (lambda / 3.0).max(1e-12);
                    small = if rel < opts.tolerance { small + 1 } else { 0 };
                    break;
                }
                _ => {
                    lambda *= 4.0;
                    if lambda > 1e16 {
                        break;
                    }
                }
            }
        }
        if lambda > 1e16 {
            return Ok(LmResult {
                theta: th,
                eval: ev,
                iterations: it,
                converged: true,
                message:
                    "no step lowers the cost further (a minimum to the precision of the Jacobian)"
                        .into(),
            });
        }
        if small >= 2 {
            return Ok(LmResult {
                theta: th,
                eval: ev,
                iterations: it,
                converged: true,
                message: format!("the cost changed by less than {} twice", opts.tolerance),
            });
        }
    }
    Ok(LmResult {
        theta: th,
        eval: ev,
        iterations: opts.max_iterations,
        converged: false,
        message: format!(
            "did not converge in {} iterations; the best parameters found are kept",
            opts.max_iterations
        ),
    })
}
