//! The fitting algorithm for one output: variable projection (Golub & Pereyra 1973) with the
//! linear-in-parameter coefficients (path gains, the terms' columns, offset) solved by
//! (non-negative) least squares inside, and the nonlinear parameters (the terms' and the
//! filters', e.g. Bouc-Wen B and Gamma, creep gains, f_n and zeta) moved by Levenberg-Marquardt
//! outside, with Kaufman's projected Jacobian.
//!
//! What the model is made of comes from the effects ([`crate::effect::fitting`]): each path
//! has a gain column and the columns of the terms of its effects; the output's filters act on
//! the sum. [`Layout`] says where each part's columns and parameters are.
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
use super::{FitOptions, GreyBoxError};
use crate::effect::fitting::{FilterFit, OutputSetup, PathSetup, Prepared, TermFit, LIMIT};
use crate::effect::{Effect, EffectSpec};
use crate::numeric::lm::{self, LeastSquares, LmSettings, LmStop};
use crate::plant::{OutputSpec, PathSpec};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::borrow::Cow;
use std::ops::Range;

/// One column of the Jacobian: d yhat / d theta of one parameter, before projection.
type JacobianJob<'a> = Box<dyn Fn() -> Vec<f64> + Sync + 'a>;

/// A term of a path, with where its columns and parameters are.
struct PlacedTerm<'a> {
    term: Box<dyn TermFit + 'a>,
    /// Its columns in the basis.
    cols: Range<usize>,
    /// Its parameters in theta.
    params: Range<usize>,
}

impl<'a> PlacedTerm<'a> {
    /// `term` placed after `n_cols` columns and `n_theta` parameters (both moved past it).
    fn place(term: Box<dyn TermFit + 'a>, n_cols: &mut usize, n_theta: &mut usize) -> Self {
        let (nc, np) = (term.n_columns(), term.n_params());
        let placed = PlacedTerm {
            term,
            cols: *n_cols..*n_cols + nc,
            params: *n_theta..*n_theta + np,
        };
        *n_cols += nc;
        *n_theta += np;
        placed
    }
}

/// One path: its input, its gain column and its terms.
struct FitPath<'a> {
    input: usize,
    gain_col: usize,
    terms: Vec<PlacedTerm<'a>>,
}

/// An output filter with its parameters in theta.
struct PlacedFilter {
    filter: Box<dyn FilterFit>,
    params: Range<usize>,
}

/// Where every column and parameter of one output's model is. Columns: per path, the gain
/// column then each term's columns; the output terms' columns; the constant (offset) last. Parameters: the filters' from
/// the output back (the last filter of the chain first), then each path's terms in order.
struct Layout<'a> {
    paths: Vec<FitPath<'a>>,
    /// Terms added to the output after its filters (drift), their columns after the paths'.
    output_terms: Vec<PlacedTerm<'a>>,
    /// The first column that the filters do not act on (output terms, then the constant).
    unfiltered: usize,
    /// In chain order.
    filters: Vec<PlacedFilter>,
    n_cols: usize,
    n_theta: usize,
}

/// Everything needed to evaluate the model of one output for a parameter vector.
pub(crate) struct OutputProblem<'a> {
    pub name: String,
    /// The measured output, zero on the held-out samples.
    y: Cow<'a, [f64]>,
    /// Samples that the fit ignores (their rows of the basis, of the Jacobian and of `y` are
    /// zero): the model still runs through them, so that a held-out block inside the record
    /// scores it as a free run (blocked cross-validation).
    held_out: Option<Range<usize>>,
    /// Samples the fit also leaves out, wherever they are (a sensor's censored samples: the
    /// measurement there only bounds the model's value).
    excluded: Option<Vec<bool>>,
    /// Relative ridge on the terms' coefficients (not the path gains nor the offset):
    /// lambda * ||psi_i||^2 * c_i^2 is added to the cost, shrinking a path toward its linear
    /// gain; 0 = none.
    ridge: f64,
    u: Vec<&'a [f64]>,
    pub input_names: Vec<String>,
    layout: Layout<'a>,
    /// The effects every path must have a spec of (written from the gain when unselected).
    required: Vec<&'static dyn Effect>,
}

/// One evaluation of the projected problem.
pub(crate) struct Eval {
    pub cost: f64,
    pub r: Vec<f64>,
    pub coef: Vec<f64>,
    psi: Vec<Vec<f64>>,
    sol: NnlsSolution,
}

/// An effect chosen for a model, with its variant.
#[derive(Clone, Copy)]
pub(crate) struct Chosen {
    pub effect: &'static dyn Effect,
    pub variant: usize,
}

/// What the structure of one output is: its paths (input indices), the effects that add terms
/// to each path and the effects that filter the output (chain order).
#[derive(Clone)]
pub(crate) struct OutputStructure {
    pub paths: Vec<usize>,
    pub terms: Vec<Chosen>,
    pub filters: Vec<Chosen>,
    /// Effects that add columns to the output after its filters (drift).
    pub output_terms: Vec<Chosen>,
    /// Per path, its first-stage fit in the second stage of a two-stage fit (empty: none).
    pub previous: Vec<Option<crate::effect::fitting::PreviousPath>>,
    /// [`crate::effect::fitting::OutputSetup::parsimonious`].
    pub parsimonious: bool,
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

/// The prepared filters applied in order to a copy of `x` (NaN when one is invalid).
fn apply_chain(prepared: &[Prepared], x: &[f64]) -> Vec<f64> {
    apply_chain_owned(prepared, x.to_vec())
}

/// The prepared filters applied in order to `x` (NaN when one is invalid).
fn apply_chain_owned(prepared: &[Prepared], mut x: Vec<f64>) -> Vec<f64> {
    if prepared.iter().any(|p| matches!(p, Prepared::Invalid)) {
        x.fill(f64::NAN);
        return x;
    }
    for p in prepared {
        if let Prepared::Apply(f) = p {
            f(&mut x);
        }
    }
    x
}

impl<'a> OutputProblem<'a> {
    /// Set up the problem of one output; `plays` play operators per Prandtl-Ishlinskii path;
    /// the samples `held_out` do not enter the fit.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        name: &str,
        y: &'a [f64],
        u: Vec<&'a [f64]>,
        input_names: Vec<String>,
        ts: f64,
        structure: &OutputStructure,
        plays: usize,
        held_out: Option<Range<usize>>,
    ) -> OutputProblem<'a> {
        let held_out = held_out
            .map(|r| r.start.min(y.len())..r.end.min(y.len()))
            .filter(|r| !r.is_empty());
        let y: Cow<'a, [f64]> = match &held_out {
            Some(r) => {
                let mut v = y.to_vec();
                v[r.clone()].fill(0.0);
                Cow::Owned(v)
            }
            None => Cow::Borrowed(y),
        };
        let setup = |variant| OutputSetup {
            samples: y.len(),
            ts,
            variant,
            parsimonious: structure.parsimonious,
        };
        let built: Vec<Box<dyn FilterFit>> = structure
            .filters
            .iter()
            .filter_map(|c| c.effect.filter(&setup(c.variant)))
            .collect();
        // parameters: the filters from the output back, then the paths' terms
        let mut n_theta = 0;
        let mut at = vec![0..0; built.len()];
        for (i, f) in built.iter().enumerate().rev() {
            at[i] = n_theta..n_theta + f.n_params();
            n_theta += f.n_params();
        }
        let filters = built
            .into_iter()
            .zip(at)
            .map(|(filter, params)| PlacedFilter { filter, params })
            .collect();
        // sign of each path's gain from a linear fit (PI weights share it)
        let mut owned: Vec<Vec<f64>> = structure.paths.iter().map(|&j| u[j].to_vec()).collect();
        owned.push(vec![1.0; y.len()]);
        if let Some(r) = &held_out {
            owned.iter_mut().for_each(|c| c[r.clone()].fill(0.0));
        }
        let cols: Vec<&[f64]> = owned.iter().map(Vec::as_slice).collect();
        let lin = least_squares(&cols, &y);
        let mut paths = Vec::new();
        let mut n_cols = 0;
        for (k, &j) in structure.paths.iter().enumerate() {
            let gain_col = n_cols;
            n_cols += 1;
            let sign = if lin[k] < 0.0 { -1.0 } else { 1.0 };
            let mut terms = Vec::new();
            for c in &structure.terms {
                let path = PathSetup {
                    u: u[j],
                    held_out: held_out.clone(),
                    ts,
                    sign,
                    plays,
                    variant: c.variant,
                    previous: structure.previous.get(k).cloned().flatten(),
                };
                if let Some(term) = c.effect.term(&path) {
                    terms.push(PlacedTerm::place(term, &mut n_cols, &mut n_theta));
                }
            }
            paths.push(FitPath {
                input: j,
                gain_col,
                terms,
            });
        }
        let unfiltered = n_cols;
        let mut output_terms = Vec::new();
        for c in &structure.output_terms {
            if let Some(term) = c.effect.output_term(&setup(c.variant)) {
                output_terms.push(PlacedTerm::place(term, &mut n_cols, &mut n_theta));
            }
        }
        let chosen: Vec<_> = structure.terms.iter().map(|c| c.effect.name()).collect();
        let required = crate::effect::effects()
            .into_iter()
            .filter(|e| e.required_in_path() && !chosen.contains(&e.name()))
            .collect();
        OutputProblem {
            name: name.to_string(),
            y,
            held_out,
            excluded: None,
            ridge: 0.0,
            u,
            input_names,
            layout: Layout {
                paths,
                output_terms,
                unfiltered,
                filters,
                n_cols: n_cols + 1,
                n_theta,
            },
            required,
        }
    }

    pub fn n_theta(&self) -> usize {
        self.layout.n_theta
    }

    /// The same problem without the samples marked in `mask` (their rows of the basis, of the
    /// Jacobian and of `y` are zero; the model still runs through them).
    pub fn with_excluded(mut self, mask: Vec<bool>) -> Self {
        let mut y = self.y.into_owned();
        for (v, &m) in y.iter_mut().zip(&mask) {
            if m {
                *v = 0.0;
            }
        }
        self.y = Cow::Owned(y);
        self.excluded = Some(mask);
        self
    }

    /// The same problem with a relative ridge `lambda` on the terms' coefficients.
    pub fn with_ridge(mut self, lambda: f64) -> Self {
        self.ridge = lambda.max(0.0);
        self
    }

    /// Which basis columns a ridge shrinks: the terms' (not the gains, not the offset).
    fn term_columns(&self) -> Vec<bool> {
        let mut p = vec![false; self.layout.n_cols];
        for path in &self.layout.paths {
            for t in &path.terms {
                p[t.cols.clone()].fill(true);
            }
        }
        p
    }

    /// The basis at `th` through the filters (without the dynamics for the static model),
    /// held-out rows zero; the constant last.
    fn filtered_basis(&self, th: &[f64], with_dynamics: bool) -> (Vec<Vec<f64>>, Vec<bool>) {
        let (phi, cons) = self.basis(th);
        let prepared = self.prepared(th, with_dynamics);
        let unfiltered = self.layout.unfiltered;
        // each raw column is filtered in place (a term's own column is not copied): the basis
        // and its filtered form are never held whole at once
        let psi = phi
            .into_par_iter()
            .enumerate()
            .map(|(k, col)| {
                let mut c = if k >= unfiltered {
                    col.into_owned()
                } else {
                    apply_chain_owned(&prepared, col.into_owned())
                };
                self.hold_out(&mut c);
                c
            })
            .collect();
        (psi, cons)
    }

    /// The ridge of `ridges` (simplest model, i.e. strongest ridge, first) that a blocked
    /// cross-validation of the linear coefficients at the fitted nonlinear parameters `th`
    /// chooses ([`crate::metrics::simplest_not_clearly_worse`]). The Gram matrix is additive
    /// over samples, so each block's fit is the whole record's normal equations minus the
    /// block's: one pass over the record for every block and ridge. The nonlinear parameters
    /// (modes, creep, Bouc-Wen shape) stay those fitted on every sample, which makes it cheap
    /// on any record length; the plays, the input map and the gains are where a fit that saw a
    /// narrow input range goes wrong outside it.
    pub fn ridge_by_cross_validation(&self, th: &[f64], ridges: &[f64], folds: usize) -> f64 {
        let (psi, cons) = self.filtered_basis(th, true);
        let (m, n) = (psi.len(), self.y.len());
        let blocks = super::blocks(n, folds);
        let normal = |r: Range<usize>| {
            let g = DMatrix::from_fn(m, m, |i, j| dot(&psi[i][r.clone()], &psi[j][r.clone()]));
            let b = DVector::from_fn(m, |i, _| dot(&psi[i][r.clone()], &self.y[r.clone()]));
            (g, b)
        };
        let parts: Vec<(DMatrix<f64>, DVector<f64>)> =
            blocks.par_iter().map(|b| normal(b.clone())).collect();
        let (mut g_all, mut b_all) = (DMatrix::zeros(m, m), DVector::zeros(m));
        for (g, b) in &parts {
            g_all += g;
            b_all += b;
        }
        let terms = self.term_columns();
        let held = self.held_out.clone().unwrap_or(0..0);
        let errors: Vec<Option<Vec<f64>>> = ridges
            .par_iter()
            .map(|&lambda| {
                let mut e = Vec::with_capacity(n);
                for (block, (gb, bb)) in blocks.iter().zip(&parts) {
                    let mut g = &g_all - gb;
                    for i in (0..m).filter(|&i| terms[i]) {
                        g[(i, i)] *= 1.0 + lambda;
                    }
                    let coef = nnls_gram(&g, &(&b_all - bb), &cons).coef;
                    let skip = |k: &usize| {
                        held.contains(k) || self.excluded.as_ref().is_some_and(|m| m[*k])
                    };
                    for k in block.clone().filter(|k| !skip(k)) {
                        let fit: f64 = (0..m).map(|i| coef[i] * psi[i][k]).sum();
                        e.push(self.y[k] - fit);
                    }
                }
                e.iter().all(|v| v.is_finite()).then_some(e)
            })
            .collect();
        ridges[crate::metrics::simplest_not_clearly_worse(&errors)]
    }

    /// Zero a column's held-out rows.
    fn hold_out(&self, c: &mut [f64]) {
        if let Some(r) = &self.held_out {
            c[r.clone()].fill(0.0);
        }
        if let Some(m) = &self.excluded {
            for (v, &x) in c.iter_mut().zip(m) {
                if x {
                    *v = 0.0;
                }
            }
        }
    }

    /// The filters prepared at `th` (without those left out of the static model).
    fn prepared(&self, th: &[f64], with_dynamics: bool) -> Vec<Prepared> {
        self.layout
            .filters
            .iter()
            .filter(|f| with_dynamics || !f.filter.off_when_static())
            .map(|f| f.filter.prepare(&th[f.params.clone()]))
            .collect()
    }

    /// The raw basis columns (before the filters) and which must have c >= 0; the constant
    /// column (offset) is last.
    fn basis(&self, th: &[f64]) -> (Vec<Cow<'_, [f64]>>, Vec<bool>) {
        let mut cols: Vec<Cow<[f64]>> = Vec::with_capacity(self.layout.n_cols);
        let mut cons = Vec::with_capacity(self.layout.n_cols);
        for p in &self.layout.paths {
            cols.push(Cow::Borrowed(self.u[p.input]));
            cons.push(false);
            for t in &p.terms {
                for (c, nonneg) in t.term.columns(&th[t.params.clone()]) {
                    cols.push(c);
                    cons.push(nonneg);
                }
            }
        }
        for t in &self.layout.output_terms {
            for (c, nonneg) in t.term.columns(&th[t.params.clone()]) {
                cols.push(c);
                cons.push(nonneg);
            }
        }
        cols.push(Cow::Owned(vec![1.0; self.y.len()]));
        cons.push(false);
        (cols, cons)
    }

    /// Evaluate: basis through the filters, (non-negative) least squares, residual.
    /// `with_dynamics = false` evaluates the static model (initialisation).
    pub fn eval(&self, th: &[f64], with_dynamics: bool) -> Option<Eval> {
        let (psi, cons) = self.filtered_basis(th, with_dynamics);
        let m = psi.len();
        let rows: Vec<Vec<f64>> = (0..m)
            .into_par_iter()
            .map(|i| {
                (0..m)
                    .map(|j| if j < i { 0.0 } else { dot(&psi[i], &psi[j]) })
                    .collect()
            })
            .collect();
        let mut g = DMatrix::from_fn(m, m, |i, j| if j >= i { rows[i][j] } else { rows[j][i] });
        let b = DVector::from_iterator(m, psi.iter().map(|c| dot(c, &self.y)));
        if g.iter().any(|v| !v.is_finite()) || b.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let penalised: Vec<bool> = self
            .term_columns()
            .into_iter()
            .map(|t| t && self.ridge > 0.0)
            .collect();
        let energy: Vec<f64> = (0..m).map(|i| g[(i, i)]).collect();
        for (i, _) in penalised.iter().enumerate().filter(|(_, p)| **p) {
            g[(i, i)] += self.ridge * energy[i];
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
        let penalty: f64 = (0..m)
            .filter(|&i| penalised[i])
            .map(|i| self.ridge * energy[i] * sol.coef[i] * sol.coef[i])
            .sum();
        let cost = 0.5 * (r.iter().map(|v| v * v).sum::<f64>() + penalty);
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

    /// Kaufman's Jacobian of the fitted output with respect to the parameters `free` (in that
    /// order): partial derivatives at fixed linear coefficients, projected onto the orthogonal
    /// complement of the active regressors. Columns: d yhat / d theta. Each column is computed,
    /// projected and written in place: the derivatives are never held whole beside the matrix.
    fn jacobian(&self, th: &[f64], ev: &Eval, free: &[usize]) -> DMatrix<f64> {
        let n = self.y.len();
        let sol = &ev.sol;
        self.with_derivative_jobs(th, &ev.coef, |jobs| {
            let mut by_param: Vec<Option<&JacobianJob<'_>>> = vec![None; self.layout.n_theta];
            for (q, job) in &jobs {
                by_param[*q] = Some(job);
            }
            let mut j = DMatrix::zeros(n, free.len());
            if n == 0 {
                return j;
            }
            j.as_mut_slice()
                .par_chunks_mut(n)
                .zip(free.par_iter())
                .for_each(|(out, &q)| {
                    let Some(job) = by_param[q] else {
                        return;
                    };
                    let mut c = job();
                    self.hold_out(&mut c);
                    // projection onto the complement of the passive regressors
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
                    for (o, v) in out.iter_mut().zip(c) {
                        *o = if v.is_finite() { v } else { 0.0 };
                    }
                });
            j
        })
    }

    /// The model's output at parameters `th` and linear coefficients `coef` (held fixed).
    #[cfg(test)]
    pub(crate) fn output_at(&self, th: &[f64], coef: &[f64]) -> Vec<f64> {
        let (phi, _) = self.basis(th);
        let prepared = self.prepared(th, true);
        let f = self.layout.unfiltered;
        let mut out = vec![0.0; self.y.len()];
        for (k, (col, &c)) in phi.iter().zip(coef).enumerate() {
            let v = if k < f {
                apply_chain(&prepared, col)
            } else {
                col.to_vec()
            };
            for (o, v) in out.iter_mut().zip(v) {
                *o += c * v;
            }
        }
        out
    }

    /// d yhat / d theta_q at fixed linear coefficients, one column per parameter (before the
    /// projection): the filters' through the filters after them, the terms' through all.
    #[cfg(test)]
    pub(crate) fn derivatives(&self, th: &[f64], coef: &[f64]) -> Vec<(usize, Vec<f64>)> {
        self.with_derivative_jobs(th, coef, |jobs| {
            jobs.par_iter().map(|(q, f)| (*q, f())).collect()
        })
    }

    /// The jobs that compute each parameter's column of [`OutputProblem::derivatives`] (the
    /// parameter, the job), handed to `run`.
    fn with_derivative_jobs<R>(
        &self,
        th: &[f64],
        coef: &[f64],
        run: impl FnOnce(Vec<(usize, JacobianJob<'_>)>) -> R,
    ) -> R {
        let n = self.y.len();
        let (phi, _) = self.basis(th);
        let prepared = self.prepared(th, true);
        // the unfiltered sum of the paths
        let mut w = vec![0.0; n];
        let last = self.layout.unfiltered;
        for (col, &c) in phi[..last].iter().zip(&coef[..last]) {
            if c != 0.0 {
                for (wv, v) in w.iter_mut().zip(col.iter()) {
                    *wv += c * v;
                }
            }
        }
        let mut jobs: Vec<(usize, JacobianJob<'_>)> = Vec::new();
        let prepared = &prepared;
        for (i, f) in self.layout.filters.iter().enumerate() {
            if f.params.is_empty() {
                continue;
            }
            // the filter's input: the filters before it applied to the sum of the paths
            let x = std::sync::Arc::new(apply_chain(&prepared[..i], &w));
            for q in 0..f.params.len() {
                let x = x.clone();
                jobs.push((
                    f.params.start + q,
                    Box::new(move || {
                        let d = f.filter.derivative(&th[f.params.clone()], &x, q);
                        apply_chain_owned(&prepared[i + 1..], d)
                    }),
                ));
            }
        }
        for path in &self.layout.paths {
            for t in &path.terms {
                if t.params.is_empty() {
                    continue;
                }
                let cols: Vec<&[f64]> = phi[t.cols.clone()].iter().map(|c| c.as_ref()).collect();
                let cols = std::sync::Arc::new(cols);
                for q in 0..t.params.len() {
                    let cols = cols.clone();
                    let coef = &coef[t.cols.clone()];
                    jobs.push((
                        t.params.start + q,
                        Box::new(move || {
                            let d = t.term.derivative(&th[t.params.clone()], q, &cols, coef);
                            apply_chain_owned(prepared, d)
                        }),
                    ));
                }
            }
        }
        for t in &self.layout.output_terms {
            // after the filters: its derivative as it is
            let cols: Vec<&[f64]> = phi[t.cols.clone()].iter().map(|c| c.as_ref()).collect();
            let cols = std::sync::Arc::new(cols);
            for q in 0..t.params.len() {
                let cols = cols.clone();
                let coef = &coef[t.cols.clone()];
                jobs.push((
                    t.params.start + q,
                    Box::new(move || t.term.derivative(&th[t.params.clone()], q, &cols, coef)),
                ));
            }
        }
        run(jobs)
    }

    /// This problem's parameters from those of `other` (same filters, other variants of the
    /// terms): the filters' copied, and a term's copied where both terms name their parameters
    /// alike.
    pub fn theta_from(&self, other: &OutputProblem, th: &[f64]) -> Vec<f64> {
        let mut t = vec![0.0; self.layout.n_theta];
        for (a, b) in self.layout.filters.iter().zip(&other.layout.filters) {
            t[a.params.clone()].copy_from_slice(&th[b.params.clone()]);
        }
        for (pa, pb) in self.layout.paths.iter().zip(&other.layout.paths) {
            for (a, b) in pa.terms.iter().zip(&pb.terms) {
                let names = a.term.param_names();
                if !names.is_empty() && names == b.term.param_names() {
                    t[a.params.clone()].copy_from_slice(&th[b.params.clone()]);
                }
            }
        }
        t
    }

    /// Which parameters are free in the first Levenberg-Marquardt stage (the filters that are
    /// held first, creep, wait for the others to settle).
    pub fn first_stage(&self) -> Vec<bool> {
        let mut free = vec![true; self.layout.n_theta];
        for f in self.layout.filters.iter().filter(|f| f.filter.held_first()) {
            free[f.params.clone()].fill(false);
        }
        free
    }

    /// Starting points: the terms' static grid (point i of every term tried together on the
    /// model without dynamics), then the `starts` best points of a filter's grid (on a reduced
    /// problem `coarse`), the other parameters at their initial values.
    pub fn initial(&self, coarse: &OutputProblem, starts: usize) -> Vec<Vec<f64>> {
        let mut th = vec![0.0; self.layout.n_theta];
        for f in &self.layout.filters {
            th[f.params.clone()].copy_from_slice(&f.filter.initial());
        }
        let grids: Vec<(Range<usize>, Vec<Vec<f64>>)> = self
            .layout
            .paths
            .iter()
            .flat_map(|p| &p.terms)
            .map(|t| (t.params.clone(), t.term.start_grid()))
            .filter(|(_, g)| !g.is_empty())
            .collect();
        if let Some(points) = grids.iter().map(|(_, g)| g.len()).min() {
            let set = |t: &mut Vec<f64>, i: usize| {
                for (at, g) in &grids {
                    t[at.clone()].copy_from_slice(&g[i]);
                }
            };
            let mut best = (f64::INFINITY, None);
            for i in 0..points {
                let mut t = th.clone();
                set(&mut t, i);
                if let Some(e) = self.eval(&t, false) {
                    if e.cost < best.0 {
                        best = (e.cost, Some(i));
                    }
                }
            }
            if let Some(i) = best.1 {
                set(&mut th, i);
            }
        }
        for f in &self.layout.filters {
            let at = f.params.clone();
            let base = th.clone();
            let with = |local: &[f64]| {
                let mut t = base.clone();
                t[at.clone()].copy_from_slice(local);
                t
            };
            let cost = |local: &[f64]| {
                coarse
                    .eval(&with(local), true)
                    .map_or(f64::INFINITY, |e| e.cost)
            };
            if let Some(list) = f.filter.starts(&th[at.clone()], &cost, starts) {
                return list.iter().map(|local| with(local)).collect();
            }
        }
        vec![th]
    }

    /// The fitted output as a plant output spec.
    pub fn output_spec(&self, th: &[f64], coef: &[f64]) -> OutputSpec {
        let mut paths = Vec::new();
        for p in &self.layout.paths {
            let input = self.input_names[p.input].clone();
            let gain = coef[p.gain_col];
            let mut specs: Vec<Box<dyn EffectSpec>> = Vec::new();
            for t in &p.terms {
                let out = t
                    .term
                    .spec(&th[t.params.clone()], gain, &coef[t.cols.clone()]);
                for extra in out.extra_paths {
                    paths.push(PathSpec::new(input.clone(), vec![extra]));
                }
                specs.extend(out.spec);
            }
            for e in &self.required {
                specs.extend(e.path_without(gain));
            }
            paths.push(PathSpec::new(input, specs));
        }
        OutputSpec {
            name: self.name.clone(),
            paths,
            offset: coef[self.layout.n_cols - 1],
            effects: self
                .layout
                .filters
                .iter()
                .map(|f| f.filter.spec(&th[f.params.clone()]))
                .chain(self.layout.output_terms.iter().filter_map(|t| {
                    t.term
                        .spec(&th[t.params.clone()], 0.0, &coef[t.cols.clone()])
                        .spec
                }))
                .collect(),
        }
    }
}

/// The result of Levenberg-Marquardt on one output.
pub(crate) struct LmResult {
    pub theta: Vec<f64>,
    /// The ridge of the problem solved.
    pub ridge: f64,
    pub eval: Eval,
    pub iterations: usize,
    pub converged: bool,
    pub message: String,
}

/// The output problem as seen by Levenberg-Marquardt: the full model (with dynamics), the
/// Jacobian projected onto the free parameters.
struct WithDynamics<'p, 'a>(&'p OutputProblem<'a>);

impl LeastSquares for WithDynamics<'_, '_> {
    type Eval = Eval;
    fn eval(&self, th: &[f64]) -> Option<Eval> {
        self.0.eval(th, true)
    }
    fn cost(&self, ev: &Eval) -> f64 {
        ev.cost
    }
    fn normal_equations(
        &self,
        th: &[f64],
        ev: &Eval,
        free: &[usize],
    ) -> Option<(DMatrix<f64>, DVector<f64>)> {
        let j = self.0.jacobian(th, ev, free);
        // the residual is data - model, so J^T r is already the descent direction
        Some((j.tr_mul(&j), j.tr_mul(&DVector::from_column_slice(&ev.r))))
    }
    fn residual_norm(&self, ev: &Eval) -> f64 {
        (2.0 * ev.cost).sqrt()
    }
}

/// Levenberg-Marquardt with More's diagonal scaling on the projected problem; the parameters
/// where `free` is false are held.
pub(crate) fn levenberg_marquardt(
    prob: &OutputProblem,
    theta0: Vec<f64>,
    free: &[bool],
    opts: &FitOptions,
) -> Result<LmResult, GreyBoxError> {
    let ev = prob
        .eval(&theta0, true)
        .ok_or_else(|| GreyBoxError::NonFinite {
            output: prob.name.clone(),
            what: "the initial model".into(),
        })?;
    let idx: Vec<usize> = (0..prob.n_theta()).filter(|&i| free[i]).collect();
    let y_mean = prob.y.iter().sum::<f64>() / prob.y.len() as f64;
    let y_energy = 0.5 * prob.y.iter().map(|v| (v - y_mean).powi(2)).sum::<f64>();
    let settings = LmSettings {
        max_iterations: opts.max_iterations,
        tolerance: opts.tolerance,
        bound: LIMIT,
        zero_cost: 1e-24 * y_energy,
        ..LmSettings::default()
    };
    let out = lm::levenberg_marquardt(&WithDynamics(prob), theta0, ev, &idx, &settings);
    let message = match out.stop {
        LmStop::NoFreeParameter => "linear least squares (no nonlinear parameter)".into(),
        LmStop::ZeroResidual => "the residual is zero to rounding".into(),
        LmStop::GradientVanishes => "the gradient vanishes".into(),
        LmStop::NoDescent | LmStop::NoJacobian => {
            "no step lowers the cost further (a minimum to the precision of the Jacobian)".into()
        }
        LmStop::SmallChange => format!("the cost changed by less than {} twice", opts.tolerance),
        LmStop::MaxIterations => format!(
            "did not converge in {} iterations; the best parameters found are kept",
            opts.max_iterations
        ),
    };
    Ok(LmResult {
        theta: out.theta,
        ridge: prob.ridge,
        eval: out.eval,
        iterations: out.iterations,
        converged: out.stop.converged(),
        message,
    })
}
