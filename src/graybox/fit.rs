//! The fitting algorithm for one output: variable projection (Golub & Pereyra 1973) with the
//! linear-in-parameter coefficients (path gains, the terms' columns, offset) solved by
//! (non-negative) least squares inside, and the nonlinear parameters (the terms' and the
//! filters', e.g. Bouc-Wen B and Gamma, creep gains, f_n and zeta) moved by Levenberg-Marquardt
//! outside, with Kaufman's projected Jacobian.
//!
//! Both steps work on normal equations accumulated by row blocks ([`crate::numeric::gram`]):
//! the basis' Gram matrix for the linear step, Kaufman's `J^T J` for the nonlinear one, whose
//! projected Jacobian is formed and multiplied a block at a time. Only the passive
//! set's filtered columns outlive an evaluation, and on a long record not even those: its
//! basis is streamed, computed again a piece at a time by every pass that needs it
//! ([`OutputProblem::stream`]), with the same bits as held whole.
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
use crate::effect::fitting::{
    FilterFit, FilterState, OutputSetup, PathSetup, Prepared, TermFit, TermState, LIMIT,
};
use crate::effect::{Effect, EffectSpec};
use crate::numeric::gram;
use crate::numeric::lm::{self, LeastSquares, LmSettings, LmStop};
use crate::plant::{OutputSpec, PathSpec};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::borrow::Cow;
use std::ops::Range;

/// What a streamed pass hands each piece: its rows and the columns on them.
type PieceVisit<'v> = dyn FnMut(Range<usize>, &[&[f64]]) + 'v;

/// A filter's derivatives on each chain, each parameter's ([`FilterFit::derivatives_path`]).
type PathDerivatives = Vec<Vec<Vec<f64>>>;

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

impl<'a> Layout<'a> {
    /// Every term: the paths' in order, then the output terms.
    fn terms(&self) -> impl Iterator<Item = &PlacedTerm<'a>> {
        self.paths
            .iter()
            .flat_map(|p| &p.terms)
            .chain(&self.output_terms)
    }
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
    /// gain, but on a density's coefficients ([`OutputProblem::density_groups`]) the penalty
    /// of their second differences; 0 = none.
    ridge: f64,
    /// Relative ridge on the cross paths' terms ([`OutputProblem::with_cross_ridge`]).
    cross_ridge: f64,
    /// The input that drives this output directly (the others' paths are cross paths).
    own_input: Option<usize>,
    u: Vec<&'a [f64]>,
    pub input_names: Vec<String>,
    layout: Layout<'a>,
    /// The effects every path must have a spec of (written from the gain when unselected).
    required: Vec<&'static dyn Effect>,
    /// Rows of a piece of a streamed pass (the record's length or more: held whole).
    piece_rows: usize,
    /// The bytes of derivative columns held whole in double precision beyond which they are
    /// held in single ([`WHOLE_DERIVATIVES_BYTES`]).
    derivative_bytes: usize,
    /// The buffers of a streamed record's passes, kept from one pass to the next.
    pool: std::sync::Mutex<Vec<Vec<f64>>>,
}

/// One evaluation of the projected problem.
pub(crate) struct Eval {
    pub cost: f64,
    pub r: Vec<f64>,
    pub coef: Vec<f64>,
    /// The filtered basis columns of the passive set (`sol.passive`, in that order): what the
    /// Jacobian's projection needs (the columns held at zero are dropped once solved). `None`
    /// on a record whose basis is streamed (computed again where the projection needs it) and
    /// once released.
    pub(crate) passive_psi: Option<Vec<Vec<f64>>>,
    /// The unfiltered sum of the paths at the coefficients (what the filters' derivatives
    /// need), when the residual's pass over a streamed basis gave it.
    w: Option<Vec<f64>>,
    sol: NnlsSolution,
}

impl Eval {
    /// Drop the basis columns (kept while Levenberg-Marquardt iterates from this point; a
    /// finished fit needs its cost and coefficients only).
    fn release_basis(&mut self) {
        self.passive_psi = None;
        self.w = None;
    }
}

/// Chunks of the row-block sums ([`gram::CHUNK_ROWS`]) in a piece of a streamed pass: the
/// pieces start on chunk boundaries, so that sums over them are the same bits as over the
/// whole record, and a piece gives several threads a chunk each.
const PIECE_CHUNKS: usize = 4;

/// The filtered basis of a record is held whole (computed once per evaluation) up to this
/// size; beyond, it is streamed in pieces of [`PIECE_CHUNKS`] chunks and computed again by
/// each pass that needs it (the fit's memory then does not grow with samples x columns).
pub const WHOLE_BASIS_BYTES: usize = 128 << 20;

/// The states of one streamed pass's derivatives computed a block at a time: each term's,
/// each derivative's filters', and whether each has been finite so far.
struct BlockedPass {
    terms: Vec<TermState>,
    filters: Vec<Vec<FilterState>>,
    finite: Vec<bool>,
}

/// What a streamed pass gives for each piece of the record.
#[derive(Clone, Copy, PartialEq)]
enum Columns {
    /// The basis through the filters (without those left out of the static model when
    /// `with_dynamics` is false), held-out and excluded rows zero.
    Filtered { with_dynamics: bool },
    /// The basis before the filters, every row.
    Raw,
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
    /// [`crate::effect::fitting::PathSetup::plays_by_levels`].
    pub plays_by_levels: bool,
    /// [`crate::effect::fitting::PathSetup::envelope_split`].
    pub envelope_split: bool,
}

impl OutputStructure {
    /// The structure without the filters that the static model of the initialisation leaves
    /// out ([`FilterFit::off_when_static`]: dynamics), for `samples` samples at `ts`; `None`
    /// when it has none. Such a filter cannot become the identity (a sampled mode delays the
    /// output by a sample at least): an output without it is fitted both ways.
    pub fn without_static_off_filters(&self, samples: usize, ts: f64) -> Option<Self> {
        let off = |c: &Chosen| {
            c.effect
                .filter(&OutputSetup {
                    samples,
                    rows: samples,
                    blocks: None,
                    ts,
                    variant: c.variant,
                    parsimonious: self.parsimonious,
                    paths: self.paths.len(),
                })
                .is_some_and(|f| f.off_when_static())
        };
        if !self.filters.iter().any(off) {
            return None;
        }
        let mut st = self.clone();
        st.filters.retain(|c| !off(c));
        Some(st)
    }
}

/// Linear least squares of y on the columns (free coefficients), by the normal equations.
fn least_squares(cols: &[&[f64]], y: &[f64]) -> Vec<f64> {
    let (g, b) = normal_equations(cols, y);
    nnls_gram(&g, &b, &vec![false; cols.len()]).coef
}

/// Output lags of the linear model that gives the paths' signs ([`path_signs`]); its inputs
/// enter at lags 0 to `SIGN_LAGS - 1`.
const SIGN_LAGS: usize = 4;

/// The sign of each path's gain (+1 or -1), for the inputs `u` of the paths: that of the
/// steady-state gain of a linear ARX model of the output, y(k) = c + sum_i a_i y(k - i) +
/// sum_j sum_i b_ji u_j(k - i + 1), i = 1..[`SIGN_LAGS`] (Ljung, *System Identification*,
/// 1999, ch. 4): sum_i b_ji / (1 - sum_i a_i). Its lags take up the modes and creep that
/// tilt a static fit of y on u (an input above a mode's frequency turns a static slope
/// negative; on the 2-DoF short records of the development zoo of seed 30 the static fit's
/// sign was wrong on 66 of 400 direct paths, the ARX's on 12). Rows whose lags reach into
/// `held_out` are left out. `None` where the ARX does not give them: too few rows, a
/// singular fit, not stable (sum_i a_i >= 1) or a gain of 0 ([`static_signs`] then).
fn path_signs(u: &[&[f64]], y: &[f64], held_out: Option<&Range<usize>>) -> Option<Vec<f64>> {
    let (na, m) = (SIGN_LAGS, u.len());
    let p = na + SIGN_LAGS * m + 1;
    let mut ne = crate::numeric::lstsq::NormalEquations::new(p);
    let mut row = vec![0.0; p];
    for k in na..y.len() {
        if held_out.is_some_and(|r| r.start <= k && k - na < r.end) {
            continue;
        }
        for i in 1..=na {
            row[i - 1] = y[k - i];
        }
        for (j, uj) in u.iter().enumerate() {
            for i in 0..SIGN_LAGS {
                row[na + SIGN_LAGS * j + i] = uj[k - i];
            }
        }
        row[p - 1] = 1.0;
        ne.add_row(&row, y[k]);
    }
    if ne.rows() < 2 * p {
        return None;
    }
    let (g, b) = ne.into_parts();
    let th = crate::numeric::lstsq::solve_scaled(&g, &b, 1e-10)?;
    let den = 1.0 - th.iter().take(na).sum::<f64>();
    if !(den > 0.0 && den.is_finite()) {
        return None;
    }
    (0..m)
        .map(|j| {
            let gain: f64 = th.iter().skip(na + SIGN_LAGS * j).take(SIGN_LAGS).sum();
            (gain != 0.0 && gain.is_finite()).then(|| gain.signum())
        })
        .collect()
}

/// The sign of each path's gain in a static least-squares fit of y on the paths' inputs `u`
/// and an intercept, `held_out` left out ([`path_signs`]' fallback): it copies every path's
/// input over the record, so it runs only where the ARX gives no sign.
fn static_signs(u: &[&[f64]], y: &[f64], held_out: Option<&Range<usize>>) -> Vec<f64> {
    let mut owned: Vec<Vec<f64>> = u.iter().map(|c| c.to_vec()).collect();
    owned.push(vec![1.0; y.len()]);
    if let Some(r) = held_out {
        owned.iter_mut().for_each(|c| c[r.clone()].fill(0.0));
    }
    let cols: Vec<&[f64]> = owned.iter().map(Vec::as_slice).collect();
    least_squares(&cols, y)
        .iter()
        .take(u.len())
        .map(|&g| if g < 0.0 { -1.0 } else { 1.0 })
        .collect()
}

/// The normal equations `G = Psi^T Psi`, `b = Psi^T y` of the columns `cols`, by row blocks
/// ([`gram`]).
fn normal_equations(cols: &[&[f64]], y: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
    let m = cols.len();
    let mut all = cols.to_vec();
    all.push(y);
    let x = gram::gram(&all);
    (
        x.view((0, 0), (m, m)).into_owned(),
        x.view((0, m), (m, 1)).column(0).into_owned(),
    )
}

/// The prepared filters applied in order to a copy of `x` (NaN when one is invalid).
fn apply_chain(prepared: &[&Prepared], x: &[f64]) -> Vec<f64> {
    apply_chain_owned(prepared, x.to_vec())
}

/// The prepared filters applied in order to `x` (NaN when one is invalid).
fn apply_chain_owned(prepared: &[&Prepared], mut x: Vec<f64>) -> Vec<f64> {
    apply_chain_many(prepared, std::slice::from_mut(&mut x));
    x
}

/// The prepared filters applied in order to each of the columns `xs` (NaN when one is
/// invalid); a filter may run the columns side by side.
fn apply_chain_many(prepared: &[&Prepared], xs: &mut [Vec<f64>]) {
    if prepared.iter().any(|p| matches!(p, Prepared::Invalid)) {
        xs.iter_mut().for_each(|x| x.fill(f64::NAN));
        return;
    }
    let mut cols: Vec<&mut [f64]> = xs.iter_mut().map(Vec::as_mut_slice).collect();
    for p in prepared {
        if let Prepared::Apply(f) = p {
            let mut fresh = vec![FilterState::new(); cols.len()];
            f(&mut cols, &mut fresh);
        }
    }
}

/// An output's filters prepared at some parameters: each filter's, one per path for a
/// per-path filter ([`FilterFit::per_path`]).
struct Chains {
    filters: Vec<Vec<Prepared>>,
}

impl Chains {
    /// No filter (the raw basis).
    fn none() -> Chains {
        Chains {
            filters: Vec::new(),
        }
    }

    /// Whether some filter differs from path to path.
    fn per_path(&self) -> bool {
        self.filters.iter().any(|f| f.len() > 1)
    }

    /// Whether some filter is invalid at these parameters.
    fn invalid(&self) -> bool {
        self.filters
            .iter()
            .flatten()
            .any(|p| matches!(p, Prepared::Invalid))
    }

    /// The chain of path `p`, in order.
    fn of_path(&self, p: usize) -> Vec<&Prepared> {
        self.filters
            .iter()
            .map(|f| &f[p.min(f.len() - 1)])
            .collect()
    }
}

/// `s` cut into consecutive pieces of the lengths `lens` (which sum to its length at most).
fn split_lengths<'a, T>(mut s: &'a mut [T], lens: &[usize]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(lens.len());
    for &l in lens {
        let (a, b) = std::mem::take(&mut s).split_at_mut(l);
        out.push(a);
        s = b;
    }
    out
}

/// Groups of at most [`FILTER_GROUP`] consecutive items whose paths `path_of` gives: the
/// items in order, a group never spanning two paths when `by_path` (else groups of
/// [`FILTER_GROUP`] whatever the paths). Each group: its path (its first item's) and length.
fn filter_groups(path_of: &[usize], by_path: bool) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = Vec::new();
    for &p in path_of {
        match out.last_mut() {
            Some((q, len)) if *len < FILTER_GROUP && (!by_path || *q == p) => *len += 1,
            _ => out.push((p, 1)),
        }
    }
    out
}

/// `out += sign * sum_k coef_k cols_k` (`sign` +1 or -1), the columns added in order at
/// each row (rows in parallel blocks: the same bits as one after the other).
fn add_columns(out: &mut [f64], cols: &[&[f64]], coef: &[f64], sign: f64) {
    out.par_chunks_mut(gram::BLOCK_ROWS)
        .enumerate()
        .for_each(|(b, o)| {
            let at = b * gram::BLOCK_ROWS;
            for (col, &c) in cols.iter().zip(coef) {
                let col = &col[at..at + o.len()];
                if sign < 0.0 {
                    o.iter_mut().zip(col).for_each(|(v, x)| *v -= c * x);
                } else {
                    o.iter_mut().zip(col).for_each(|(v, x)| *v += c * x);
                }
            }
        });
}

/// The derivative columns of the Jacobian held whole (the parameters whose derivatives are
/// not computed a block at a time: the filters', say) beyond which they are held in single
/// precision (a record of 20,000,000 samples: 160 MB a column in double precision). Their
/// products are still summed in double precision; each value is rounded to 24 bits (a
/// relative 6e-8), which moves the step of Levenberg-Marquardt, not the cost it is judged by.
pub const WHOLE_DERIVATIVES_BYTES: usize = 1 << 30;

/// A column held over the whole record, in double or (to halve its memory) single precision.
enum HeldColumn {
    Double(Vec<f64>),
    Single(Vec<f32>),
}

impl HeldColumn {
    /// `c`, in single precision when `single` (and every value fits).
    fn held(c: Vec<f64>, single: bool) -> HeldColumn {
        if single {
            // (a value beyond single precision's range stays in double)
            let s: Vec<f32> = c.iter().map(|&v| v as f32).collect();
            if s.iter().all(|v| v.is_finite()) {
                return HeldColumn::Single(s);
            }
        }
        HeldColumn::Double(c)
    }

    /// Its values on `rows`, in double precision.
    fn rows(&self, rows: Range<usize>) -> Cow<'_, [f64]> {
        match self {
            HeldColumn::Double(v) => Cow::Borrowed(&v[rows]),
            HeldColumn::Single(v) => Cow::Owned(v[rows].iter().map(|&x| f64::from(x)).collect()),
        }
    }
}

/// The rows an [`OutputProblem`] runs over.
#[derive(Debug, Clone)]
pub enum Rows<'a> {
    /// The record's first rows (all of them: `usize::MAX`).
    First(usize),
    /// A part of the record made of blocks spread over it: its inputs and its output over
    /// those blocks, one after the other (the parameters still come from the whole record),
    /// and the record's rows of each block (`at`).
    Blocks {
        u: Vec<&'a [f64]>,
        y: &'a [f64],
        at: &'a [Range<usize>],
    },
}

/// Columns filtered together (the resonator's recursion runs up to this many side by side).
const FILTER_GROUP: usize = 8;

impl<'a> OutputProblem<'a> {
    /// Set up the problem of one output; `plays` play operators per Prandtl-Ishlinskii path;
    /// the samples `held_out` do not enter the fit. The problem runs over the first `rows`
    /// samples of the record (all of them, or a long record's first part on which its starts
    /// are chosen: [`super::STARTS_ROWS`]) with the parameters of the whole record (thresholds,
    /// knots, time constants and the paths' signs from all its samples), so that a parameter
    /// vector means the same on the part and on the whole (a two-stage fit's second stage
    /// too: its first-stage paths over the part's rows, with their range over the whole,
    /// `PreviousPath::range`). A part of blocks spread over the record
    /// ([`Rows::Blocks`]) runs over its own inputs and output; `held_out` then only shapes
    /// the parameters (the caller leaves those rows of the blocks out: `with_excluded`).
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
        rows: Rows<'a>,
    ) -> OutputProblem<'a> {
        let n = y.len();
        let (rows, part_u, part_y, blocks) = match rows {
            Rows::First(r) => {
                let r = r.min(n);
                (r, u.iter().map(|v| &v[..r]).collect::<Vec<_>>(), None, None)
            }
            Rows::Blocks { u, y, at } => (y.len(), u, Some(y), Some(at)),
        };
        // a second stage's first-stage paths run over the rows of the problem
        debug_assert!(structure
            .previous
            .iter()
            .flatten()
            .all(|p| p.output.len() == rows));
        let held_out = held_out
            .map(|r| r.start.min(n)..r.end.min(n))
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
            samples: n,
            rows,
            blocks,
            ts,
            variant,
            parsimonious: structure.parsimonious,
            paths: structure.paths.len(),
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
        // each path's sign (PI weights and the Bouc-Wen term share it)
        let path_u: Vec<&[f64]> = structure.paths.iter().map(|&j| u[j]).collect();
        let signs = path_signs(&path_u, &y, held_out.as_ref())
            .unwrap_or_else(|| static_signs(&path_u, &y, held_out.as_ref()));
        let mut paths = Vec::new();
        let mut n_cols = 0;
        for (k, &j) in structure.paths.iter().enumerate() {
            let gain_col = n_cols;
            n_cols += 1;
            let sign = signs[k];
            let mut terms = Vec::new();
            for c in &structure.terms {
                let path = PathSetup {
                    u: part_u[j],
                    whole: u[j],
                    held_out: held_out.clone(),
                    ts,
                    sign,
                    plays,
                    plays_by_levels: structure.plays_by_levels,
                    envelope_split: structure.envelope_split,
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
        // the rows the problem runs over
        let y = match (part_y, y) {
            (Some(p), _) => Cow::Borrowed(p),
            (None, Cow::Borrowed(v)) => Cow::Borrowed(&v[..rows]),
            (None, Cow::Owned(mut v)) => {
                v.truncate(rows);
                Cow::Owned(v)
            }
        };
        let held_out = held_out
            .filter(|_| part_y.is_none())
            .map(|r| r.start.min(rows)..r.end.min(rows))
            .filter(|r| !r.is_empty());
        let u = part_u;
        OutputProblem {
            name: name.to_string(),
            y,
            held_out,
            excluded: None,
            ridge: 0.0,
            cross_ridge: 0.0,
            own_input: None,
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
            piece_rows: usize::MAX,
            derivative_bytes: WHOLE_DERIVATIVES_BYTES,
            pool: Default::default(),
        }
        .with_piece_rows(None)
    }

    /// The same problem with its derivative columns held in single precision beyond `bytes`
    /// (in double) instead of [`WHOLE_DERIVATIVES_BYTES`].
    #[cfg(test)]
    pub(crate) fn with_derivative_bytes(mut self, bytes: usize) -> Self {
        self.derivative_bytes = bytes;
        self
    }

    /// The same problem with its basis streamed in pieces of `rows` rows (rounded up to whole
    /// chunks of [`gram::CHUNK_ROWS`]); `None`: held whole up to [`WHOLE_BASIS_BYTES`], in
    /// pieces of [`PIECE_CHUNKS`] chunks beyond. The results are the same bits either way.
    pub(crate) fn with_piece_rows(mut self, rows: Option<usize>) -> Self {
        let n = self.y.len();
        let whole = n.saturating_mul(self.layout.n_cols).saturating_mul(8) <= WHOLE_BASIS_BYTES;
        self.piece_rows = match rows {
            Some(r) => r.div_ceil(gram::CHUNK_ROWS).max(1) * gram::CHUNK_ROWS,
            None if whole => usize::MAX,
            None => PIECE_CHUNKS * gram::CHUNK_ROWS,
        };
        self
    }

    /// Whether the basis is held whole (one piece).
    pub(crate) fn held_whole(&self) -> bool {
        self.piece_rows >= self.y.len()
    }

    /// About the memory one Levenberg-Marquardt run of this problem holds beyond the record:
    /// its residual, the paths' sum and two more columns, a derivative per parameter (the
    /// Jacobian's columns held whole), and the filtered basis when it is held whole.
    pub(crate) fn run_bytes(&self) -> usize {
        let held = if self.held_whole() {
            self.layout.n_cols
        } else {
            0
        };
        let columns = self.layout.n_theta + 4 + held;
        columns.saturating_mul(self.y.len()).saturating_mul(8)
    }

    /// Whether an output filter has parameters (whose derivatives need the unfiltered sum).
    fn filters_have_params(&self) -> bool {
        self.layout.filters.iter().any(|f| !f.params.is_empty())
    }

    /// The pieces of a streamed pass, in order.
    pub(crate) fn pieces(&self) -> Vec<Range<usize>> {
        self.pieces_of(self.piece_rows)
    }

    /// The record cut in pieces of `rows` rows (the last shorter), in order.
    fn pieces_of(&self, rows: usize) -> Vec<Range<usize>> {
        let n = self.y.len();
        let step = rows.min(n).max(1);
        (0..n.div_ceil(step))
            .map(|k| k * step..((k + 1) * step).min(n))
            .collect()
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

    /// Per parameter, the interval its term keeps it inside (`TermFit::param_bounds`; the
    /// filters' are unbounded).
    pub fn bounds(&self) -> Vec<(f64, f64)> {
        let mut b = vec![(f64::NEG_INFINITY, f64::INFINITY); self.layout.n_theta];
        for t in self.layout.terms() {
            for (q, v) in t.params.clone().zip(t.term.param_bounds()) {
                b[q] = v;
            }
        }
        b
    }

    /// Per parameter, whether its term holds it at 0 unless freeing it pays
    /// (`TermFit::optional_params`; the filters' never).
    pub fn optional(&self) -> Vec<bool> {
        let mut o = vec![false; self.layout.n_theta];
        for t in self.layout.terms() {
            for (q, v) in t.params.clone().zip(t.term.optional_params()) {
                o[q] = v;
            }
        }
        o
    }

    /// Per parameter, whether it is held at `th`: an optional parameter at 0 (not freed, or
    /// freed and refused).
    pub fn held(&self, th: &[f64]) -> Vec<bool> {
        let o = self.optional();
        o.iter().zip(th).map(|(&o, &t)| o && t == 0.0).collect()
    }

    /// The same problem with a relative ridge `lambda` on the terms' coefficients.
    pub fn with_ridge(mut self, lambda: f64) -> Self {
        self.ridge = lambda.max(0.0);
        self
    }

    /// The same problem with a relative ridge `lambda` on the terms of its cross paths, the
    /// paths whose input is not `own_input` (the output's own: none, no cross paths). Each
    /// cross path's is scaled as if its input moved as much as the own one (by the ratio of
    /// the gain columns' energies), so that `lambda` weighs the paths' gains alike. Where
    /// the record cannot tell the paths apart (inputs that move together in it), the loop
    /// goes to the own input's path; elsewhere the pull is of the order of `lambda`. The
    /// cross paths keep their gains: a linear coupling is not shrunk.
    pub fn with_cross_ridge(mut self, lambda: f64, own_input: Option<usize>) -> Self {
        self.cross_ridge = lambda.max(0.0);
        self.own_input = own_input;
        self
    }

    /// Which basis columns a ridge shrinks one by one: the terms' (not the gains, not the
    /// offset), but for those of a density ([`OutputProblem::density_groups`]).
    fn term_columns(&self) -> Vec<bool> {
        let mut p = vec![false; self.layout.n_cols];
        for path in &self.layout.paths {
            for t in &path.terms {
                p[t.cols.clone()].fill(true);
            }
        }
        for g in self.density_groups() {
            p[g].fill(false);
        }
        p
    }

    /// The relative ridge on each basis column from [`OutputProblem::with_cross_ridge`]: on
    /// the terms of every path whose input is not the output's own, `cross_ridge` times the
    /// ratio of the own path's gain column energy to the path's (`energy`: the columns'
    /// squared norms), as if the cross input moved as much as the own one; 0 elsewhere.
    fn cross_columns(&self, energy: &[f64]) -> Vec<f64> {
        let mut p = vec![0.0; self.layout.n_cols];
        let Some(own) = self.own_input.filter(|_| self.cross_ridge > 0.0) else {
            return p;
        };
        let Some(own_gain) = self.layout.paths.iter().find(|path| path.input == own) else {
            return p;
        };
        let own_energy = energy[own_gain.gain_col];
        for path in self.layout.paths.iter().filter(|path| path.input != own) {
            let ratio = own_energy / energy[path.gain_col];
            let lambda = self.cross_ridge * ratio;
            if lambda.is_finite() {
                for t in &path.terms {
                    p[t.cols.clone()].fill(lambda);
                }
            }
        }
        p
    }

    /// The basis columns whose coefficients sample one density each
    /// ([`crate::effect::fitting::TermFit::density_columns`]): a ridge penalises their second
    /// differences (a smooth density; Tikhonov's second-order regularisation), relative to the
    /// group's mean column energy, instead of each coefficient.
    ///
    /// Reference: A. N. Tikhonov, V. Y. Arsenin, *Solutions of Ill-Posed Problems*, Winston,
    /// 1977; P. Eilers, B. Marx, Statistical Science 11(2):89-121, 1996 (difference penalties).
    fn density_groups(&self) -> Vec<Range<usize>> {
        self.layout
            .paths
            .iter()
            .flat_map(|p| &p.terms)
            .filter_map(|t| {
                let r = t.term.density_columns()?;
                Some(t.cols.start + r.start..t.cols.start + r.end)
            })
            .collect()
    }

    /// Adds `lambda` times the density groups' difference penalty to the Gram matrix `g`
    /// (its diagonal the columns' energies); returns each group with its weight `w` (lambda
    /// times the group's mean column energy), for the cost ([`OutputProblem::density_penalty`]).
    /// A group of fewer than three columns has no second difference and is left out.
    fn add_density_penalty(
        groups: &[Range<usize>],
        g: &mut DMatrix<f64>,
        lambda: f64,
    ) -> Vec<(Range<usize>, f64)> {
        let mut scales = Vec::new();
        if lambda <= 0.0 {
            return scales;
        }
        for grp in groups.iter().filter(|g| g.len() >= 3) {
            let n = grp.len();
            let s = grp.clone().map(|i| g[(i, i)]).sum::<f64>() / n as f64;
            let w = lambda * s;
            // D^T D of the second differences [1, -2, 1]
            for k in 0..n - 2 {
                let idx = [grp.start + k, grp.start + k + 1, grp.start + k + 2];
                let d = [1.0, -2.0, 1.0];
                for a in 0..3 {
                    for b in 0..3 {
                        g[(idx[a], idx[b])] += w * d[a] * d[b];
                    }
                }
            }
            scales.push((grp.clone(), w));
        }
        scales
    }

    /// The density penalty `sum w ||D c||^2` of the coefficients `coef`.
    fn density_penalty(scales: &[(Range<usize>, f64)], coef: &[f64]) -> f64 {
        scales
            .iter()
            .map(|(grp, w)| {
                let c = &coef[grp.clone()];
                w * c
                    .windows(3)
                    .map(|t| (t[0] - 2.0 * t[1] + t[2]).powi(2))
                    .sum::<f64>()
            })
            .sum()
    }

    /// One pass over the record at `th`: `visit(rows, columns)` for each piece in order, with
    /// the basis columns `wanted` (every column when `None`, in that order) on its rows, the
    /// constant last. The terms resume from their states and the filters from theirs (a few
    /// columns side by side, groups in parallel), so the columns are those of the whole
    /// record. Returns which columns must have c >= 0, and, when `keep` is set and the pass
    /// was one piece, every column over the whole record (the wanted ones as visited).
    fn stream(
        &self,
        th: &[f64],
        what: Columns,
        wanted: Option<&[usize]>,
        keep: bool,
        visit: impl FnMut(Range<usize>, &[&[f64]]),
    ) -> (Vec<bool>, Option<Vec<Vec<f64>>>) {
        self.stream_with_raw(th, what, wanted, keep, None, visit)
    }

    /// [`OutputProblem::stream`] that also hands `raw(rows, columns)` the wanted columns
    /// before the filters (in the same order), piece by piece.
    fn stream_with_raw(
        &self,
        th: &[f64],
        what: Columns,
        wanted: Option<&[usize]>,
        keep: bool,
        mut raw: Option<&mut PieceVisit<'_>>,
        mut visit: impl FnMut(Range<usize>, &[&[f64]]),
    ) -> (Vec<bool>, Option<Vec<Vec<f64>>>) {
        let m = self.layout.n_cols;
        let all: Vec<usize>;
        let wanted = match wanted {
            Some(w) => w,
            None => {
                all = (0..m).collect();
                &all
            }
        };
        let chains = match what {
            Columns::Filtered { with_dynamics } => self.prepared(th, with_dynamics),
            Columns::Raw => Chains::none(),
        };
        let invalid = chains.invalid();
        let mut is_wanted = vec![false; m];
        wanted.iter().for_each(|&k| is_wanted[k] = true);
        // the wanted columns that the filters act on (in column order), in groups side by
        // side (one path's columns in a group where a filter differs from path to path),
        // each group with its path's chain and its filters' states (group, filter, column)
        let filtered: Vec<bool> = (0..m)
            .map(|k| is_wanted[k] && k < self.layout.unfiltered)
            .collect();
        let col_paths = self.col_paths();
        let target_paths: Vec<usize> = (0..m)
            .filter(|&k| filtered[k])
            .map(|k| col_paths[k])
            .collect();
        let groups = filter_groups(&target_paths, chains.per_path());
        let group_lens: Vec<usize> = groups.iter().map(|g| g.1).collect();
        let group_chains: Vec<Vec<&Prepared>> =
            groups.iter().map(|g| chains.of_path(g.0)).collect();
        let n_filters = chains.filters.len();
        let mut states: Vec<Vec<Vec<FilterState>>> = groups
            .iter()
            .map(|&(_, len)| vec![vec![FilterState::new(); len]; n_filters])
            .collect();
        let terms: Vec<&PlacedTerm> = self.layout.terms().collect();
        let mut term_states: Vec<TermState> = terms.iter().map(|_| TermState::default()).collect();
        let mut cons = vec![false; m];
        // the raw basis is summed row by row: pieces of a few chunks whatever the record
        let pieces = match what {
            Columns::Raw => self.pieces_of(self.piece_rows.min(PIECE_CHUNKS * gram::CHUNK_ROWS)),
            Columns::Filtered { .. } => self.pieces(),
        };
        let single = pieces.len() <= 1;
        // a streamed record's buffers are kept from one pass to the next (their pages are not
        // handed back to the system and faulted in again)
        let pooled = !self.held_whole();
        let mut bufs: Vec<Vec<f64>> = if pooled {
            let mut pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
            (0..m).map(|_| pool.pop().unwrap_or_default()).collect()
        } else {
            vec![Vec::new(); m]
        };
        for rows in pieces {
            let len = rows.len();
            for p in &self.layout.paths {
                let b = &mut bufs[p.gain_col];
                b.clear();
                b.extend_from_slice(&self.u[p.input][rows.clone()]);
            }
            for (t, st) in terms.iter().zip(&mut term_states) {
                let th_t = &th[t.params.clone()];
                let out = &mut bufs[t.cols.clone()];
                let want = &is_wanted[t.cols.clone()];
                let flags = t.term.columns_block(th_t, rows.clone(), st, out, want);
                cons[t.cols.clone()].copy_from_slice(&flags);
            }
            bufs[m - 1].clear();
            bufs[m - 1].resize(len, 1.0);
            if let Some(raw) = raw.as_mut() {
                let view: Vec<&[f64]> = wanted.iter().map(|&k| bufs[k].as_slice()).collect();
                raw(rows.clone(), &view);
            }
            if what != Columns::Raw {
                let mut targets: Vec<&mut Vec<f64>> = bufs
                    .iter_mut()
                    .zip(&filtered)
                    .filter_map(|(b, f)| f.then_some(b))
                    .collect();
                if invalid {
                    targets.iter_mut().for_each(|b| b.fill(f64::NAN));
                } else if n_filters > 0 {
                    split_lengths(&mut targets, &group_lens)
                        .into_par_iter()
                        .zip(states.par_iter_mut())
                        .zip(&group_chains)
                        .for_each(|((group, st), chain)| {
                            let mut slices: Vec<&mut [f64]> =
                                group.iter_mut().map(|b| b.as_mut_slice()).collect();
                            for (p, s) in chain.iter().zip(st.iter_mut()) {
                                if let Prepared::Apply(f) = p {
                                    f(&mut slices, s);
                                }
                            }
                        });
                }
                bufs.par_iter_mut()
                    .zip(&is_wanted)
                    .filter(|(_, w)| **w)
                    .for_each(|(c, _)| self.hold_out_rows(c, rows.clone()));
            }
            let view: Vec<&[f64]> = wanted.iter().map(|&k| bufs[k].as_slice()).collect();
            visit(rows, &view);
        }
        if keep && single {
            return (cons, Some(bufs));
        }
        if pooled {
            self.pool
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .extend(bufs);
        }
        (cons, None)
    }

    /// The basis at `th` through the filters (without the dynamics for the static model),
    /// held-out rows zero, the constant last: whole columns.
    fn filtered_basis(&self, th: &[f64], with_dynamics: bool) -> (Vec<Vec<f64>>, Vec<bool>) {
        let n = self.y.len();
        let mut psi: Vec<Vec<f64>> = Vec::new();
        let what = Columns::Filtered { with_dynamics };
        let (cons, held) = self.stream(th, what, None, true, |rows, cols| {
            if rows.start == 0 && rows.end == n {
                return;
            }
            if psi.is_empty() {
                psi = cols.iter().map(|_| Vec::with_capacity(n)).collect();
            }
            for (p, c) in psi.iter_mut().zip(cols) {
                p.extend_from_slice(c);
            }
        });
        (held.unwrap_or(psi), cons)
    }

    /// The sum over the record's row blocks ([`gram::sum_by_row_blocks`]) of `block(rows,
    /// local, psi, extra)`, `psi` the filtered basis columns `cols` (at `th`, with the
    /// dynamics) on the block's rows `rows` of the record: taken from `held` (those columns
    /// whole) when given, else streamed, with `extra(piece)` the piece's columns of another
    /// kind (the derivatives computed a block at a time; `local` the block's rows in them).
    /// The same bits either way.
    fn sum_over_basis(
        &self,
        th: &[f64],
        held: Option<&[Vec<f64>]>,
        cols: &[usize],
        (r, c): (usize, usize),
        mut extra: impl FnMut(Range<usize>) -> Vec<Vec<f64>>,
        block: impl Fn(Range<usize>, Range<usize>, &[&[f64]], &[Vec<f64>]) -> DMatrix<f64> + Sync,
    ) -> DMatrix<f64> {
        if let Some(held) = held {
            return gram::sum_by_row_blocks(self.y.len(), r, c, |rows| {
                let psi: Vec<&[f64]> = held.iter().map(|p| &p[rows.clone()]).collect();
                block(rows.clone(), rows, &psi, &[])
            });
        }
        let mut sum = gram::ChunkSum::new(r, c);
        let what = Columns::Filtered {
            with_dynamics: true,
        };
        self.stream(th, what, Some(cols), false, |piece, psi| {
            let ex = extra(piece.clone());
            sum.add(gram::chunk_sums(piece.len(), r, c, |local| {
                let at = piece.start + local.start..piece.start + local.end;
                let p: Vec<&[f64]> = psi.iter().map(|v| &v[local.clone()]).collect();
                block(at, local, &p, &ex)
            }));
        });
        sum.total()
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
            let cols: Vec<&[f64]> = psi.iter().map(|c| &c[r.clone()]).collect();
            normal_equations(&cols, &self.y[r])
        };
        let parts: Vec<(DMatrix<f64>, DVector<f64>)> =
            blocks.par_iter().map(|b| normal(b.clone())).collect();
        let (mut g_all, mut b_all) = (DMatrix::zeros(m, m), DVector::zeros(m));
        for (g, b) in &parts {
            g_all += g;
            b_all += b;
        }
        let terms = self.term_columns();
        let energy_all: Vec<f64> = (0..m).map(|i| g_all[(i, i)]).collect();
        let cross = self.cross_columns(&energy_all);
        let groups = self.density_groups();
        let held = self.held_out.clone().unwrap_or(0..0);
        let errors: Vec<Option<Vec<f64>>> = ridges
            .par_iter()
            .map(|&lambda| {
                let mut e = Vec::with_capacity(n);
                for (block, (gb, bb)) in blocks.iter().zip(&parts) {
                    let mut g = &g_all - gb;
                    Self::add_density_penalty(&groups, &mut g, lambda);
                    for i in (0..m).filter(|&i| terms[i]) {
                        g[(i, i)] *= 1.0 + lambda;
                    }
                    for i in 0..m {
                        g[(i, i)] *= 1.0 + cross[i];
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

    /// Zero the held-out rows of a column's rows `rows` (`c` holds those rows).
    fn hold_out_rows(&self, c: &mut [f64], rows: Range<usize>) {
        if let Some(r) = &self.held_out {
            let (a, b) = (r.start.max(rows.start), r.end.min(rows.end));
            if a < b {
                c[a - rows.start..b - rows.start].fill(0.0);
            }
        }
        if let Some(m) = &self.excluded {
            for (v, &x) in c.iter_mut().zip(m.iter().skip(rows.start)) {
                if x {
                    *v = 0.0;
                }
            }
        }
    }

    /// Zero a column's held-out rows.
    fn hold_out(&self, c: &mut [f64]) {
        self.hold_out_rows(c, 0..c.len());
    }

    /// The filters prepared at `th` (without those left out of the static model), a per-path
    /// filter's for each path.
    fn prepared(&self, th: &[f64], with_dynamics: bool) -> Chains {
        let paths = self.layout.paths.len();
        Chains {
            filters: self
                .layout
                .filters
                .iter()
                .filter(|f| with_dynamics || !f.filter.off_when_static())
                .map(|f| {
                    let t = &th[f.params.clone()];
                    if f.filter.per_path() {
                        (0..paths).map(|p| f.filter.prepare_path(t, p)).collect()
                    } else {
                        vec![f.filter.prepare(t)]
                    }
                })
                .collect(),
        }
    }

    /// The path of each column the filters act on (the columns before `unfiltered`).
    fn col_paths(&self) -> Vec<usize> {
        let mut at = vec![0; self.layout.unfiltered];
        for (k, p) in self.layout.paths.iter().enumerate() {
            at[p.gain_col] = k;
            for t in &p.terms {
                at[t.cols.clone()].fill(k);
            }
        }
        at
    }

    /// Whether a filter differs from path to path ([`FilterFit::per_path`]).
    fn per_path_filters(&self) -> bool {
        self.layout.filters.iter().any(|f| f.filter.per_path())
    }

    /// The raw basis columns (before the filters) and which must have c >= 0; the constant
    /// column (offset) is last.
    #[cfg(test)]
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
        let m = self.layout.n_cols;
        let what = Columns::Filtered { with_dynamics };
        // the normal equations [Psi | y]^T [Psi | y], the upper triangle, by row blocks
        let mut sum = gram::ChunkSum::new(m + 1, m + 1);
        let (cons, held) = self.stream(th, what, None, true, |rows, psi| {
            let mut all = psi.to_vec();
            all.push(&self.y[rows.clone()]);
            sum.add(gram::chunk_sums(rows.len(), m + 1, m + 1, |r| {
                let x: Vec<&[f64]> = all.iter().map(|c| &c[r.clone()]).collect();
                gram::tr_mul_slices(&x, &x, true)
            }));
        });
        let mut x = sum.total();
        gram::mirror_upper(&mut x);
        let mut g = x.view((0, 0), (m, m)).into_owned();
        let b = x.view((0, m), (m, 1)).column(0).into_owned();
        if g.iter().any(|v| !v.is_finite()) || b.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let penalised: Vec<bool> = self
            .term_columns()
            .into_iter()
            .map(|t| t && self.ridge > 0.0)
            .collect();
        let energy: Vec<f64> = (0..m).map(|i| g[(i, i)]).collect();
        let density = Self::add_density_penalty(&self.density_groups(), &mut g, self.ridge);
        for (i, _) in penalised.iter().enumerate().filter(|(_, p)| **p) {
            g[(i, i)] += self.ridge * energy[i];
        }
        let cross = self.cross_columns(&energy);
        for i in 0..m {
            g[(i, i)] += cross[i] * energy[i];
        }
        let sol = nnls_gram(&g, &b, &cons);
        // the residual, the columns subtracted in order (from the columns held, or a second
        // pass over the record)
        let used: Vec<usize> = (0..m).filter(|&i| sol.coef[i] != 0.0).collect();
        let mut r = self.y.to_vec();
        let c_used: Vec<f64> = used.iter().map(|&i| sol.coef[i]).collect();
        let mut subtract = |rows: Range<usize>, cols: &[&[f64]]| {
            add_columns(&mut r[rows], cols, &c_used, -1.0);
        };
        let mut w = None;
        match &held {
            Some(psi) => {
                let cols: Vec<&[f64]> = used.iter().map(|&i| psi[i].as_slice()).collect();
                subtract(0..self.y.len(), &cols);
            }
            None if with_dynamics && self.filters_have_params() && !self.per_path_filters() => {
                // the unfiltered sum of the paths on the way (the Jacobian's filters need it)
                // the columns of the paths (before the output terms): a prefix of `used`
                let paths = used.partition_point(|&i| i < self.layout.unfiltered);
                let c_raw: Vec<f64> = used[..paths].iter().map(|&i| sol.coef[i]).collect();
                let mut sum = vec![0.0; self.y.len()];
                let mut add = |rows: Range<usize>, cols: &[&[f64]]| {
                    add_columns(&mut sum[rows], &cols[..paths], &c_raw, 1.0);
                };
                self.stream_with_raw(th, what, Some(&used), false, Some(&mut add), subtract);
                w = Some(sum);
            }
            None => {
                self.stream(th, what, Some(&used), false, subtract);
            }
        }
        let penalty: f64 = (0..m)
            .filter(|&i| penalised[i])
            .map(|i| self.ridge * energy[i] * sol.coef[i] * sol.coef[i])
            .sum::<f64>()
            + (0..m)
                .map(|i| cross[i] * energy[i] * sol.coef[i] * sol.coef[i])
                .sum::<f64>()
            + Self::density_penalty(&density, sol.coef.as_slice());
        let cost = 0.5 * (r.iter().map(|v| v * v).sum::<f64>() + penalty);
        if !cost.is_finite() {
            return None;
        }
        let passive_psi = held.map(|mut psi| {
            sol.passive
                .iter()
                .map(|&i| std::mem::take(&mut psi[i]))
                .collect()
        });
        Some(Eval {
            cost,
            r,
            coef: sol.coef.clone(),
            passive_psi,
            w,
            sol,
        })
    }

    /// The normal equations `J^T J`, `J^T r` of Kaufman's Jacobian of the fitted output with
    /// respect to the parameters `free` (in that order): partial derivatives `D` at fixed
    /// linear coefficients, projected onto the orthogonal complement of the active regressors
    /// `P`, `J = D - P A` with `A = (P^T P + ridge)^-1 P^T D` (the passive set's Cholesky
    /// factor). Computed by row blocks ([`gram`]): `P^T D` in one pass, then `J` block by block
    /// with its products in a second (`D` is held whole, `J` only a block at a time). A
    /// derivative with a non-finite value is not projected and its non-finite values count as
    /// zero (as is every non-finite value of `J`). `J^T J` is exactly symmetric: each of its
    /// entries is a [`gram::dot`], whose products commute.
    pub(crate) fn projected_normal_equations(
        &self,
        th: &[f64],
        ev: &Eval,
        free: &[usize],
    ) -> (DMatrix<f64>, DVector<f64>) {
        let n = self.y.len();
        let p = free.len();
        let sol = &ev.sol;
        let held = ev.passive_psi.as_deref();
        // on a streamed basis, the terms' parameters whose derivatives come a block at a
        // time: (position in `free`, term, the term's parameter)
        let terms: Vec<&PlacedTerm> = self.layout.paths.iter().flat_map(|p| &p.terms).collect();
        let mut blocked: Vec<(usize, usize, usize)> = Vec::new();
        if held.is_none() {
            for (ti, t) in terms.iter().enumerate() {
                for lq in t.term.derivatives_in_blocks() {
                    if let Some(pos) = free.iter().position(|&f| f == t.params.start + lq) {
                        blocked.push((pos, ti, lq));
                    }
                }
            }
        }
        let mut slot: Vec<Option<usize>> = vec![None; p];
        for (k, &(pos, _, _)) in blocked.iter().enumerate() {
            slot[pos] = Some(k);
        }
        let w = ev.w.as_deref();
        // the derivatives held whole in single precision where in double they would pass
        // [`WHOLE_DERIVATIVES_BYTES`] (a long record's)
        let single = n.saturating_mul(p - blocked.len()).saturating_mul(8) > self.derivative_bytes;
        let (derivatives, mut finite): (Vec<HeldColumn>, Vec<bool>) =
            self.with_derivative_jobs(th, &ev.coef, w, |jobs| {
                let mut by_param: Vec<Option<&JacobianJob<'_>>> = vec![None; self.layout.n_theta];
                for (q, job) in &jobs {
                    by_param[*q] = Some(job);
                }
                free.par_iter()
                    .enumerate()
                    .map(|(pos, &q)| {
                        if slot[pos].is_some() {
                            return (HeldColumn::Double(Vec::new()), true);
                        }
                        let Some(job) = by_param[q] else {
                            return (HeldColumn::held(vec![0.0; n], single), false);
                        };
                        let mut c = job();
                        self.hold_out(&mut c);
                        let finite = c.iter().all(|v| v.is_finite());
                        if !finite {
                            c.iter_mut()
                                .filter(|v| !v.is_finite())
                                .for_each(|v| *v = 0.0);
                        }
                        (HeldColumn::held(c, single), finite)
                    })
                    .unzip()
            });
        // the blocked derivatives on a piece: the terms', through their path's filters (each
        // from its state), held-out rows zero, non-finite values zero (and the parameter
        // marked)
        let chains = self.prepared(th, true);
        let invalid = chains.invalid();
        let n_filters = chains.filters.len();
        let term_paths: Vec<usize> = self
            .layout
            .paths
            .iter()
            .enumerate()
            .flat_map(|(k, p)| p.terms.iter().map(move |_| k))
            .collect();
        let blocked_paths: Vec<usize> = blocked.iter().map(|b| term_paths[b.1]).collect();
        let groups = filter_groups(&blocked_paths, chains.per_path());
        let group_lens: Vec<usize> = groups.iter().map(|g| g.1).collect();
        let group_chains: Vec<Vec<&Prepared>> =
            groups.iter().map(|g| chains.of_path(g.0)).collect();
        let piece = |pass: &mut BlockedPass, rows: Range<usize>| -> Vec<Vec<f64>> {
            let mut out = vec![Vec::new(); blocked.len()];
            for (ti, t) in terms.iter().enumerate() {
                let idx: Vec<usize> = (0..blocked.len()).filter(|&k| blocked[k].1 == ti).collect();
                if idx.is_empty() {
                    continue;
                }
                let qs: Vec<usize> = idx.iter().map(|&k| blocked[k].2).collect();
                let mut bufs = vec![Vec::new(); qs.len()];
                let (th_t, coef_t) = (&th[t.params.clone()], &ev.coef[t.cols.clone()]);
                let st = &mut pass.terms[ti];
                t.term
                    .derivatives_block(th_t, &qs, coef_t, rows.clone(), st, &mut bufs);
                for (k, b) in idx.into_iter().zip(bufs) {
                    out[k] = b;
                }
            }
            // through the filters in groups side by side (each column from its own states)
            split_lengths(&mut out, &group_lens)
                .into_par_iter()
                .zip(split_lengths(&mut pass.filters, &group_lens))
                .zip(&group_chains)
                .for_each(|((group, states), chain)| {
                    if invalid {
                        group.iter_mut().for_each(|c| c.fill(f64::NAN));
                        return;
                    }
                    let mut slices: Vec<&mut [f64]> =
                        group.iter_mut().map(|c| c.as_mut_slice()).collect();
                    for (i, p) in chain.iter().enumerate() {
                        if let Prepared::Apply(f) = p {
                            let mut st: Vec<FilterState> = states
                                .iter_mut()
                                .map(|s| std::mem::take(&mut s[i]))
                                .collect();
                            f(&mut slices, &mut st);
                            for (s, x) in states.iter_mut().zip(st) {
                                s[i] = x;
                            }
                        }
                    }
                });
            out.par_iter_mut()
                .zip(pass.finite.par_iter_mut())
                .for_each(|(c, fin)| {
                    self.hold_out_rows(c, rows.clone());
                    for v in c.iter_mut().filter(|v| !v.is_finite()) {
                        *v = 0.0;
                        *fin = false;
                    }
                });
            out
        };
        let new_pass = || BlockedPass {
            terms: terms.iter().map(|_| TermState::default()).collect(),
            filters: vec![vec![FilterState::new(); n_filters]; blocked.len()],
            finite: vec![true; blocked.len()],
        };
        // D on a block: the whole columns' rows, the blocked ones' from the piece
        fn d_at<'x>(
            slot: &[Option<usize>],
            whole: &'x [HeldColumn],
            (rows, local): (Range<usize>, Range<usize>),
            extra: &'x [Vec<f64>],
        ) -> Vec<Cow<'x, [f64]>> {
            slot.iter()
                .zip(whole)
                .map(|(s, d)| match s {
                    Some(k) => Cow::Borrowed(&extra[*k][local.clone()]),
                    None => d.rows(rows.clone()),
                })
                .collect()
        }
        let np = sol.passive.len();
        // A = S (L L^T)^-1 S P^T D, column by column (zero for a derivative not projected)
        let mut alpha = DMatrix::zeros(np, p);
        if np > 0 {
            let mut pass = new_pass();
            let pd = self.sum_over_basis(
                th,
                held,
                &sol.passive,
                (np, p),
                |rows| piece(&mut pass, rows),
                |rows, local, passive, extra| {
                    let d = d_at(&slot, &derivatives, (rows, local), extra);
                    let d: Vec<&[f64]> = d.iter().map(AsRef::as_ref).collect();
                    gram::tr_mul_slices(passive, &d, false)
                },
            );
            for (k, &(pos, _, _)) in blocked.iter().enumerate() {
                finite[pos] = pass.finite[k];
            }
            for (q, finite) in finite.iter().enumerate() {
                if !finite {
                    continue;
                }
                let v: Vec<f64> = sol
                    .passive
                    .iter()
                    .enumerate()
                    .map(|(k, &i)| pd[(k, q)] * sol.scale[i])
                    .collect();
                let a = chol_solve(&sol.chol_l, &v);
                for (k, &i) in sol.passive.iter().enumerate() {
                    alpha[(k, q)] = a[k] * sol.scale[i];
                }
            }
        }
        let r = ev.r.as_slice();
        let mut pass = new_pass();
        let products = self.sum_over_basis(
            th,
            held,
            &sol.passive,
            (p, p + 1),
            |rows| piece(&mut pass, rows),
            |rows, local, passive, extra| {
                // [J | r] on the block: J = D - P A, the passive columns subtracted in order
                let d = d_at(&slot, &derivatives, (rows.clone(), local), extra);
                let mut cols: Vec<&[f64]> = d.iter().map(AsRef::as_ref).collect();
                cols.push(&r[rows.clone()]);
                let len = rows.len();
                let mut jr = gram::block_of(&cols, 0..len);
                for (k, pk) in passive.iter().enumerate() {
                    for q in 0..p {
                        let a = alpha[(k, q)];
                        if a != 0.0 {
                            let jq = &mut jr.as_mut_slice()[q * len..(q + 1) * len];
                            for (v, x) in jq.iter_mut().zip(pk.iter()) {
                                *v -= a * x;
                            }
                        }
                    }
                }
                jr.as_mut_slice()[..p * len]
                    .iter_mut()
                    .filter(|v| !v.is_finite())
                    .for_each(|v| *v = 0.0);
                let j = jr.columns(0, p).into_owned();
                gram::tr_mul_block(&j, &jr, false)
            },
        );
        (
            products.columns(0, p).into_owned(),
            products.column(p).into_owned(),
        )
    }

    /// [`OutputProblem::projected_normal_equations`] the plain way (the test's reference):
    /// every derivative projected on its own over the whole record, then `J` held whole and
    /// multiplied column by column.
    #[cfg(test)]
    pub(crate) fn dense_normal_equations(
        &self,
        th: &[f64],
        ev: &Eval,
        free: &[usize],
    ) -> (DMatrix<f64>, DVector<f64>) {
        let sol = &ev.sol;
        let sum = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let derivatives = self.derivatives(th, &ev.coef);
        let j: Vec<Vec<f64>> = free
            .iter()
            .map(|&q| {
                let mut c = derivatives.iter().find(|(p, _)| *p == q).unwrap().1.clone();
                self.hold_out(&mut c);
                let v: Vec<f64> = sol
                    .passive
                    .iter()
                    .zip(ev.passive_psi.as_ref().expect("a basis held whole"))
                    .map(|(&i, p)| sum(p, &c) * sol.scale[i])
                    .collect();
                let a = chol_solve(&sol.chol_l, &v);
                let held = ev.passive_psi.as_ref().expect("a basis held whole");
                for (k, (&i, p)) in sol.passive.iter().zip(held).enumerate() {
                    for (cv, pv) in c.iter_mut().zip(p) {
                        *cv -= a[k] * sol.scale[i] * pv;
                    }
                }
                c
            })
            .collect();
        let p = j.len();
        (
            DMatrix::from_fn(p, p, |a, b| sum(&j[a], &j[b])),
            DVector::from_fn(p, |a, _| sum(&j[a], &ev.r)),
        )
    }

    /// The model's output at parameters `th` and linear coefficients `coef` (held fixed).
    #[cfg(test)]
    pub(crate) fn output_at(&self, th: &[f64], coef: &[f64]) -> Vec<f64> {
        let (phi, _) = self.basis(th);
        let chains = self.prepared(th, true);
        let col_paths = self.col_paths();
        let f = self.layout.unfiltered;
        let mut out = vec![0.0; self.y.len()];
        for (k, (col, &c)) in phi.iter().zip(coef).enumerate() {
            let v = if k < f {
                apply_chain(&chains.of_path(col_paths[k]), col)
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
        self.with_derivative_jobs(th, coef, None, |jobs| {
            jobs.par_iter().map(|(q, f)| (*q, f())).collect()
        })
    }

    /// The jobs that compute each parameter's column of [`OutputProblem::derivatives`] (the
    /// parameter, the job), handed to `run`.
    fn with_derivative_jobs<R>(
        &self,
        th: &[f64],
        coef: &[f64],
        w: Option<&[f64]>,
        run: impl FnOnce(Vec<(usize, JacobianJob<'_>)>) -> R,
    ) -> R {
        let n = self.y.len();
        let chains = self.prepared(th, true);
        // each path's chain (one for all where no filter differs from path to path)
        let per_path = chains.per_path();
        let n_chains = if per_path { self.layout.paths.len() } else { 1 };
        let chain_of: Vec<Vec<&Prepared>> = (0..n_chains).map(|p| chains.of_path(p)).collect();
        // the unfiltered sum of the paths (`w` when given), the columns added in order (a
        // pass over the basis before the filters), each path's alone where a filter differs
        // from path to path; only the filters' derivatives need it
        let ws: Vec<Cow<'_, [f64]>> = match w {
            Some(w) if !per_path => vec![Cow::Borrowed(w)],
            _ if !self.filters_have_params() => vec![Cow::Owned(Vec::new()); n_chains],
            _ => {
                let last = self.layout.unfiltered;
                let col_paths = self.col_paths();
                let used: Vec<usize> = (0..last).filter(|&i| coef[i] != 0.0).collect();
                let of: Vec<usize> = used
                    .iter()
                    .map(|&i| if per_path { col_paths[i] } else { 0 })
                    .collect();
                let mut sums = vec![vec![0.0; n]; n_chains];
                self.stream(th, Columns::Raw, Some(&used), false, |rows, cols| {
                    for (p, sum) in sums.iter_mut().enumerate() {
                        let (cs, cf): (Vec<&[f64]>, Vec<f64>) = used
                            .iter()
                            .zip(cols)
                            .zip(&of)
                            .filter(|(_, &q)| q == p)
                            .map(|((&i, c), _)| (*c, coef[i]))
                            .unzip();
                        add_columns(&mut sum[rows.clone()], &cs, &cf, 1.0);
                    }
                });
                sums.into_iter().map(Cow::Owned).collect()
            }
        };
        let mut jobs: Vec<(usize, JacobianJob<'_>)> = Vec::new();
        let chain_of = &chain_of;
        for (i, f) in self.layout.filters.iter().enumerate() {
            if f.params.is_empty() {
                continue;
            }
            // the filter's input on each chain: the filters before it applied to the sum
            let xs: std::sync::Arc<Vec<Vec<f64>>> = std::sync::Arc::new(
                chain_of
                    .iter()
                    .zip(&ws)
                    .map(|(c, w)| apply_chain(&c[..i], w))
                    .collect(),
            );
            // every parameter's derivative on each chain, where the filter computes them
            // together ([`FilterFit::derivatives_path`]): by the first job that asks
            let together: std::sync::Arc<std::sync::OnceLock<Option<PathDerivatives>>> =
                Default::default();
            for q in 0..f.params.len() {
                let (xs, together) = (xs.clone(), together.clone());
                jobs.push((
                    f.params.start + q,
                    Box::new(move || {
                        let th_f = &th[f.params.clone()];
                        let qs: Vec<usize> = (0..f.params.len()).collect();
                        let together = together.get_or_init(|| {
                            let of = |(p, x): (usize, &Vec<f64>)| {
                                let p = if per_path { p } else { 0 };
                                f.filter.derivatives_path(th_f, x, &qs, p)
                            };
                            xs.iter().enumerate().map(of).collect()
                        });
                        let derivative = |p: usize, x: &[f64]| match together {
                            Some(d) => d[p][q].clone(),
                            None if per_path => f.filter.derivative_path(th_f, x, q, p),
                            None => f.filter.derivative(th_f, x, q),
                        };
                        if !per_path {
                            let d = derivative(0, &xs[0]);
                            return apply_chain_owned(&chain_of[0][i + 1..], d);
                        }
                        let mut sum = vec![0.0; n];
                        for (p, x) in xs.iter().enumerate() {
                            let d = derivative(p, x);
                            let d = apply_chain_owned(&chain_of[p][i + 1..], d);
                            sum.iter_mut().zip(&d).for_each(|(s, v)| *s += v);
                        }
                        sum
                    }),
                ));
            }
        }
        for (k, path) in self.layout.paths.iter().enumerate() {
            let chain = &chain_of[if per_path { k } else { 0 }];
            for t in &path.terms {
                for q in 0..t.params.len() {
                    let coef = &coef[t.cols.clone()];
                    jobs.push((
                        t.params.start + q,
                        Box::new(move || {
                            let d = t.term.derivative(&th[t.params.clone()], q, coef);
                            apply_chain_owned(chain, d)
                        }),
                    ));
                }
            }
        }
        for t in &self.layout.output_terms {
            // after the filters: its derivative as it is
            for q in 0..t.params.len() {
                let coef = &coef[t.cols.clone()];
                jobs.push((
                    t.params.start + q,
                    Box::new(move || t.term.derivative(&th[t.params.clone()], q, coef)),
                ));
            }
        }
        run(jobs)
    }

    /// This problem's parameters from those of `other` (same filters, other variants of the
    /// terms): the filters' copied, and a term's copied where the other term names its
    /// parameters alike, followed only by optional parameters held at 0 (the `bouc-wen`
    /// fit's exponent left at n = 1 starts the default operator's Bouc-Wen term, of n = 1).
    pub fn theta_from(&self, other: &OutputProblem, th: &[f64]) -> Vec<f64> {
        let mut t = vec![0.0; self.layout.n_theta];
        for (a, b) in self.layout.filters.iter().zip(&other.layout.filters) {
            t[a.params.clone()].copy_from_slice(&th[b.params.clone()]);
        }
        for (pa, pb) in self.layout.paths.iter().zip(&other.layout.paths) {
            for (a, b) in pa.terms.iter().zip(&pb.terms) {
                let names = a.term.param_names();
                let theirs = b.term.param_names();
                let (m, from) = (names.len(), &th[b.params.clone()]);
                let held = b.term.optional_params();
                let rest_held = (m..theirs.len()).all(|k| held[k] && from[k] == 0.0);
                if m > 0 && theirs.len() >= m && names[..] == theirs[..m] && rest_held {
                    t[a.params.clone()].copy_from_slice(&from[..m]);
                }
            }
        }
        t
    }

    /// The names of the terms' parameters, term by term in the order of their parameters
    /// (after the filters'): what [`OutputProblem::theta_with_new`] maps by.
    pub fn term_param_names(&self) -> Vec<Vec<&'static str>> {
        let mut terms: Vec<&PlacedTerm> = self.layout.terms().collect();
        terms.sort_by_key(|t| t.params.start);
        terms.iter().map(|t| t.term.param_names()).collect()
    }

    /// This problem's parameters from `th`, the parameters of a problem with the same filters
    /// and terms whose parameters were named `first` ([`OutputProblem::term_param_names`]): a
    /// term's parameter copied from the one of the same name, those named in `new` (a second
    /// stage's added parameters, the envelope split's on classical plays) at 0, and those that
    /// this problem's term no longer has (the envelope split that a second stage holds in its
    /// operator) left out. `None` when `th` does not have the length that `first` names, or
    /// a parameter is not found there.
    pub fn theta_with_new(
        &self,
        th: &[f64],
        first: &[Vec<&'static str>],
        new: &[&str],
    ) -> Option<Vec<f64>> {
        let mut t = vec![0.0; self.layout.n_theta];
        let mut from = 0;
        for f in &self.layout.filters {
            t.get_mut(f.params.clone())?
                .copy_from_slice(th.get(f.params.clone())?);
            from = from.max(f.params.end);
        }
        let mut terms: Vec<&PlacedTerm> = self.layout.terms().collect();
        terms.sort_by_key(|t| t.params.start);
        if terms.len() != first.len() {
            return None;
        }
        for (term, before) in terms.into_iter().zip(first) {
            let names = term.term.param_names();
            for (k, at) in term.params.clone().enumerate() {
                let name = names.get(k).copied();
                if name.is_some_and(|n| new.contains(&n)) {
                    continue;
                }
                let j = if names == *before {
                    k
                } else {
                    before.iter().position(|&b| Some(b) == name)?
                };
                t[at] = *th.get(from + j)?;
            }
            from += before.len();
        }
        (from == th.len()).then_some(t)
    }

    /// Whether a filter is at its static edge at `th` ([`FilterFit::at_static_edge`]).
    pub fn at_static_edge(&self, th: &[f64]) -> bool {
        self.layout
            .filters
            .iter()
            .any(|f| f.filter.at_static_edge(&th[f.params.clone()]))
    }

    /// Every parameter free but the terms' parameters named `name`.
    pub fn free_except(&self, name: &str) -> Vec<bool> {
        let mut free = vec![true; self.layout.n_theta];
        for term in self.layout.terms() {
            let names = term.term.param_names();
            for (k, at) in term.params.clone().enumerate() {
                if names.get(k) == Some(&name) {
                    free[at] = false;
                }
            }
        }
        free
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
        if let Some(t) = self.best_grid_point(&th, |t| t.start_grid()) {
            th = t;
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

    /// The start of a fit with the optional parameters freed in their second basin: `th` (a
    /// fit with them held) with the terms' [`TermFit::optional_start_grid`] point of the
    /// lowest cost set in their slices (the other terms and the filters as fitted); `None`
    /// when no term has such a grid or no point runs.
    pub(crate) fn optional_start(&self, th: &[f64]) -> Option<Vec<f64>> {
        self.best_grid_point(th, |t| t.optional_start_grid())
    }

    /// `th` with the joint grid point of the lowest finite cost set in the terms' slices
    /// (point i of every term's `grid` together; the terms without one and the filters as in
    /// `th`; the first of equals); `None` when no term has a grid or no point runs.
    fn best_grid_point(
        &self,
        th: &[f64],
        grid: impl Fn(&dyn TermFit) -> Vec<Vec<f64>>,
    ) -> Option<Vec<f64>> {
        let grids: Vec<(Range<usize>, Vec<Vec<f64>>)> = self
            .layout
            .terms()
            .map(|t| (t.params.clone(), grid(t.term.as_ref())))
            .filter(|(_, g)| !g.is_empty())
            .collect();
        let points = grids.iter().map(|(_, g)| g.len()).min()?;
        let at = |i: usize| {
            let mut t = th.to_vec();
            for (r, g) in &grids {
                t[r.clone()].copy_from_slice(&g[i]);
            }
            t
        };
        let mut best = (f64::INFINITY, None);
        for i in 0..points {
            if let Some(e) = self.eval(&at(i), false) {
                if e.cost < best.0 {
                    best = (e.cost, Some(i));
                }
            }
        }
        best.1.map(at)
    }

    /// The fitted output as a plant output spec.
    pub fn output_spec(&self, th: &[f64], coef: &[f64]) -> OutputSpec {
        let mut paths = Vec::new();
        for (k, p) in self.layout.paths.iter().enumerate() {
            let input = self.input_names[p.input].clone();
            let gain = coef[p.gain_col];
            // a per-path filter on every plant path this path writes (a term's extra paths,
            // on the same input, share its filter)
            let filters = || -> Vec<Box<dyn EffectSpec>> {
                self.layout
                    .filters
                    .iter()
                    .filter(|f| f.filter.per_path())
                    .map(|f| f.filter.path_spec(&th[f.params.clone()], k))
                    .collect()
            };
            let mut specs: Vec<Box<dyn EffectSpec>> = Vec::new();
            for t in &p.terms {
                let out = t
                    .term
                    .spec(&th[t.params.clone()], gain, &coef[t.cols.clone()]);
                for extra in out.extra_paths {
                    let mut e = vec![extra];
                    e.extend(filters());
                    paths.push(PathSpec::new(input.clone(), e));
                }
                specs.extend(out.spec);
            }
            for e in &self.required {
                specs.extend(e.path_without(gain));
            }
            specs.extend(filters());
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
                .filter(|f| !f.filter.per_path())
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
        // the residual is data - model, so J^T r is already the descent direction
        Some(self.0.projected_normal_equations(th, ev, free))
    }
    fn residual_norm(&self, ev: &Eval) -> f64 {
        (2.0 * ev.cost).sqrt()
    }
    fn bounds(&self) -> Option<Vec<(f64, f64)>> {
        Some(self.0.bounds())
    }
}

/// Levenberg-Marquardt with More's diagonal scaling on the projected problem; the parameters
/// where `free` is false are held, and so are the optional ones at 0
/// ([`OutputProblem::held`]: not freed, or freed and refused).
pub(crate) fn levenberg_marquardt(
    prob: &OutputProblem,
    theta0: Vec<f64>,
    free: &[bool],
    opts: &FitOptions,
) -> Result<LmResult, GreyBoxError> {
    let held = prob.held(&theta0);
    let free: Vec<bool> = free.iter().zip(&held).map(|(&f, &h)| f && !h).collect();
    levenberg_marquardt_over(prob, theta0, &free, opts)
}

/// [`levenberg_marquardt`] from `res` with its optional parameters freed (every other
/// parameter free too), and with [`FitOptions::second_basin`] again from
/// [`OutputProblem::optional_start`] (the optional parameters' second basin), which replaces
/// the first where its fitting residual is significantly lower
/// ([`crate::metrics::significantly_lower_error`]); `None` when none is held at 0 (none, or
/// every one already freed by the start it came from). The caller keeps it where it lowers
/// the fitting error significantly.
pub(crate) fn free_optional(
    prob: &OutputProblem,
    res: &LmResult,
    opts: &FitOptions,
) -> Option<Result<LmResult, GreyBoxError>> {
    prob.held(&res.theta).contains(&true).then(|| {
        let all = vec![true; prob.n_theta()];
        let from_held = levenberg_marquardt_over(prob, res.theta.clone(), &all, opts);
        let Some(Ok(restart)) = opts
            .second_basin
            .then(|| prob.optional_start(&res.theta))
            .flatten()
            .map(|t| levenberg_marquardt_over(prob, t, &all, opts))
        else {
            return from_held;
        };
        // the second basin only where it fits significantly better than the first's
        // (a search over two basins finds a lower cost on noise more often than one)
        Ok(match from_held {
            Ok(a) if crate::metrics::significantly_lower_error(&restart.eval.r, &a.eval.r) => {
                LmResult {
                    iterations: a.iterations + restart.iterations,
                    ..restart
                }
            }
            Ok(mut a) => {
                a.iterations += restart.iterations;
                a
            }
            Err(_) => restart,
        })
    })
}

fn levenberg_marquardt_over(
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
    let mut out = lm::levenberg_marquardt(&WithDynamics(prob), theta0, ev, &idx, &settings);
    out.eval.release_basis();
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The density penalty is lambda times the group's mean energy times D^T D (D the second
    /// differences), the cost term is its quadratic form, and an affine density pays nothing.
    #[test]
    fn the_density_penalty_is_the_quadratic_form_of_second_differences() {
        let m = 7;
        let mut g = DMatrix::from_fn(m, m, |i, j| if i == j { 1.0 + i as f64 } else { 0.1 });
        let before = g.clone();
        let group = 1..6;
        let scales = OutputProblem::add_density_penalty(std::slice::from_ref(&group), &mut g, 0.5);
        // mean energy of columns 1..6: (2 + 3 + 4 + 5 + 6) / 5 = 4
        assert_eq!(scales, vec![(1..6, 2.0)]);
        let d = DMatrix::from_fn(3, m, |k, j| match j as i64 - (k as i64 + 1) {
            0 => 1.0,
            1 => -2.0,
            2 => 1.0,
            _ => 0.0,
        });
        let expected: DMatrix<f64> = &before + 2.0 * d.transpose() * &d;
        let diff: DMatrix<f64> = &g - &expected;
        assert!(diff.abs().max() < 1e-12);
        let c = [0.3, -1.0, 2.0, 0.5, 0.7, -0.2, 4.0];
        let cv = DVector::from_column_slice(&c);
        let quad = (cv.transpose() * (&g - &before) * &cv)[(0, 0)];
        let pen = OutputProblem::density_penalty(&scales, &c);
        assert!((quad - pen).abs() < 1e-12 * quad.abs().max(1.0));
        let affine = [9.0, 1.0, 1.5, 2.0, 2.5, 3.0, -9.0];
        assert!(OutputProblem::density_penalty(&scales, &affine).abs() < 1e-24);
        // no ridge: nothing added
        let mut h = before.clone();
        assert!(
            OutputProblem::add_density_penalty(std::slice::from_ref(&group), &mut h, 0.0)
                .is_empty()
        );
        assert_eq!(h, before);
    }

    /// A path of either sign behind a mode at 2 Hz, driven by sines at 3-5 Hz (above the mode:
    /// the output lags the input by more than 90 degrees, and a static fit of y on u takes
    /// the wrong sign); the ARX's steady-state gain gives the right one, also with a second,
    /// uncorrelated path and samples held out.
    #[test]
    fn the_paths_signs_come_through_a_mode_that_turns_a_static_slope() {
        let (ts, n) = (1e-3, 4000);
        let sines = |f1: f64, f2: f64, ph: f64| -> Vec<f64> {
            (0..n)
                .map(|k| {
                    let t = k as f64 * ts;
                    (2.0 * std::f64::consts::PI * f1 * t).sin()
                        + 0.5 * (2.0 * std::f64::consts::PI * f2 * t + ph).sin()
                })
                .collect()
        };
        // x'' + 2 zeta w x' + w^2 x = w^2 u, semi-implicit Euler
        let mode = |u: &[f64], gain: f64| -> Vec<f64> {
            let (w, zeta) = (2.0 * std::f64::consts::PI * 2.0, 0.2);
            let (mut x, mut v) = (0.0, 0.0);
            u.iter()
                .map(|&u| {
                    v += ts * (w * w * (gain * u - x) - 2.0 * zeta * w * v);
                    x += ts * v;
                    x
                })
                .collect()
        };
        let (u1, u2) = (sines(3.0, 5.0, 0.3), sines(4.2, 6.1, 1.1));
        for (g1, g2) in [(1.0, 0.3), (-1.0, 0.3), (1.0, -0.3), (-0.8, -0.4)] {
            let (y1, y2) = (mode(&u1, g1), mode(&u2, g2));
            let y: Vec<f64> = y1.iter().zip(&y2).map(|(a, b)| a + b + 2.0).collect();
            let want = [g1.signum(), g2.signum()];
            let fallback = static_signs(&[&u1, &u2], &y, None);
            assert!(
                fallback[0] != want[0],
                "the static fit's sign is wrong here: {fallback:?}"
            );
            for held in [None, Some(1000..1500)] {
                let got = path_signs(&[&u1, &u2], &y, held.as_ref());
                assert_eq!(
                    got,
                    Some(want.to_vec()),
                    "gains {g1}, {g2}, held out {held:?}"
                );
            }
        }
    }
}
