//! # What an effect adds to a grey-box model
//!
//! The grey-box model of one output is y = F_m[... F_1[sum over paths p of (g_p u_p + terms)]]
//! plus an offset: each path has a gain column u_p, and the effects that act on a path add **terms**
//! ([`TermFit`]: columns whose coefficients are solved by (non-negative) least squares, with
//! nonlinear parameters of their own, e.g. the plays and the Bouc-Wen column of hysteresis, the
//! rate of viscous damping); the effects that act on the output are linear **filters**
//! ([`FilterFit`]: creep, dynamics) whose parameters Levenberg-Marquardt moves. An effect may
//! instead change which inputs drive an output (coupling: `Effect::path_inputs`).
//!
//! The fitter (`graybox/`) owns the layout: it asks each part for its columns, parameters,
//! derivatives and fitted spec, and never names an effect.

use super::spec::EffectSpec;
use std::borrow::Cow;
use std::ops::Range;

/// Finite-difference step in the (transformed) parameter space.
pub const FD_STEP: f64 = 1e-6;
/// Transformed parameters are kept in [-LIMIT, LIMIT] (the logistic maps saturate beyond).
pub const LIMIT: f64 = 30.0;

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

fn logit(p: f64) -> f64 {
    let p = p.clamp(1e-12, 1.0 - 1e-12);
    (p / (1.0 - p)).ln()
}

/// A value in [lo, hi] on a log scale from an unbounded parameter.
pub fn log_bounded(x: f64, lo: f64, hi: f64) -> f64 {
    (lo.ln() + (hi.ln() - lo.ln()) * sigmoid(x)).exp()
}

/// The unbounded parameter of a value in [lo, hi] ([`log_bounded`]'s inverse).
pub fn log_bounded_inv(v: f64, lo: f64, hi: f64) -> f64 {
    logit((v.ln() - lo.ln()) / (hi.ln() - lo.ln()))
}

/// A value in [lo, hi] on a linear scale from an unbounded parameter.
pub fn bounded(x: f64, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * sigmoid(x)
}

/// The unbounded parameter of a value in [lo, hi] ([`bounded`]'s inverse).
pub fn bounded_inv(v: f64, lo: f64, hi: f64) -> f64 {
    logit((v - lo) / (hi - lo))
}

/// A variant of an effect that the command line can pick instead of the effect's default
/// (`bouc-wen` for hysteresis).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Variant {
    /// The name in an effect list (`fit --effects bouc-wen`); the default variant's is the
    /// effect's own name.
    pub name: &'static str,
    /// The name written in a model file (`"hysteresis_operator": "bouc-wen"`).
    pub file: &'static str,
    /// Also start the fit from the fit with this (simpler) variant, so that this one is never
    /// worse than it.
    pub warm_start: Option<usize>,
}

/// A path's fitted operator and its output over the record, from the first stage of a
/// two-stage fit: the second stage builds its terms on them (Kuhnen's dead zones on the output
/// of a fitted Prandtl-Ishlinskii operator).
#[derive(Debug, Clone)]
pub struct PreviousPath {
    pub output: std::sync::Arc<Vec<f64>>,
    pub spec: std::sync::Arc<dyn super::EffectSpec>,
    /// Where `output` runs over a part of the record (the second stage's fit on a long
    /// record's part): the least and greatest of the operator's output over the whole
    /// record's fitted samples, so that the terms built on it mean the same on the part and on
    /// the whole. `None`: `output` covers the record.
    pub range: Option<(f64, f64)>,
    /// Where `output` runs over blocks spread over the record: the rows of the blocks that
    /// the fit leaves out (each later block's warm-up, a held-out block's rows), in place of
    /// the record's held-out block, whose rows number the whole record's.
    pub left_out: Option<std::sync::Arc<Vec<bool>>>,
}

impl PreviousPath {
    /// The least and greatest (0 included) of an operator's output `z` over the samples
    /// outside `held_out`: the range a second stage's knots spread over.
    pub fn fitted_range(z: &[f64], held_out: Option<&std::ops::Range<usize>>) -> (f64, f64) {
        Self::range_where(z, |k| held_out.is_none_or(|r| !r.contains(&k)))
    }

    /// The least and greatest (0 included) of `z` over the samples `k` where `fitted(k)`.
    pub fn range_where(z: &[f64], fitted: impl Fn(usize) -> bool) -> (f64, f64) {
        (0..z.len())
            .filter(|&k| fitted(k))
            .fold((0.0f64, 0.0f64), |(a, b), k| (a.min(z[k]), b.max(z[k])))
    }
}

/// The name of a term's parameters that only a second stage has (the first stage's operator
/// weights that it refits, say): they start at 0 from the first stage's fit
/// (`OutputProblem::theta_with_new`).
pub const SECOND_STAGE_PARAM: &str = "second_stage";

/// What sizes an effect's parameters on one output's model (`Effect::parameter_count`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BasisSize {
    /// The variant chosen (index into `Effect::variants`, 0 = the default).
    pub variant: usize,
    /// Play operators per Prandtl-Ishlinskii path.
    pub plays: usize,
    /// The default operator's plays generalised ([`PathSetup::envelope_split`]).
    pub envelope_split: bool,
}

/// What a path term is built from.
#[derive(Debug, Clone)]
pub struct PathSetup<'a> {
    /// The path's input over the rows the fit runs over: the training record, or the part
    /// of it on which a long record's starts are chosen (`graybox::STARTS_ROWS`: its first
    /// part, or blocks spread over it one after the other).
    pub u: &'a [f64],
    /// The path's input on the whole training record (`u` is a part of it): choices made
    /// from the data see it, so that a fit on a part has the parameters of the whole.
    pub whole: &'a [f64],
    /// Samples of `whole` whose outputs the fit leaves out (a block of a cross-validation;
    /// it may lie beyond the rows of `u`):
    /// choices made from the data (thresholds, knots, ranges) see [`PathSetup::fitted_input`].
    pub held_out: Option<std::ops::Range<usize>>,
    /// Sampling period in seconds.
    pub ts: f64,
    /// The sign of the path's gain in a linear fit of the output (+1 or -1).
    pub sign: f64,
    /// Basis size: play operators per Prandtl-Ishlinskii path (smaller in the coarse problem
    /// of the initialisation).
    pub plays: usize,
    /// Fewer plays on an input of a few distinct levels (a staircase), as many as they
    /// determine (`hysteresis::plays_determined`); off where a ridge bounds the terms.
    pub plays_by_levels: bool,
    /// The default hysteresis operator's plays generalised, their envelopes split by fitted
    /// parameters (`graybox::FitOptions::envelope_split`).
    pub envelope_split: bool,
    /// The variant chosen (index into `Effect::variants`, 0 = the default).
    pub variant: usize,
    /// The path's first-stage fit, in the second stage of a two-stage fit.
    pub previous: Option<PreviousPath>,
}

impl PathSetup<'_> {
    /// The path's input on the samples of the whole training record that the fit sees
    /// (without the held-out block).
    pub fn fitted_input(&self) -> std::borrow::Cow<'_, [f64]> {
        match &self.held_out {
            Some(r) if !r.is_empty() => {
                let mut v = self.whole[..r.start].to_vec();
                v.extend_from_slice(&self.whole[r.end..]);
                std::borrow::Cow::Owned(v)
            }
            _ => std::borrow::Cow::Borrowed(self.whole),
        }
    }
}

/// What an output filter is built from.
#[derive(Debug, Clone, Copy)]
pub struct OutputSetup<'a> {
    /// Samples of the training record.
    pub samples: usize,
    /// The rows the fit runs over: `samples`, or the part of the record on which a long
    /// record's starts are chosen (choices, such as time constants, still see `samples`).
    pub rows: usize,
    /// Where the part is made of blocks spread over the record, the record's rows of each
    /// block, one block after the other (a signal of time, drift, takes its times from them).
    pub blocks: Option<&'a [std::ops::Range<usize>]>,
    /// Sampling period in seconds.
    pub ts: f64,
    /// The variant chosen.
    pub variant: usize,
    /// A short record gets the fewest terms it supports (creep: one or two time constants
    /// where it would need three).
    pub parsimonious: bool,
    /// The output's paths (a filter with parameters per path: [`FilterFit::per_path`]).
    pub paths: usize,
}

/// One column of a term: the signal and whether its coefficient must be >= 0.
pub type Column<'a> = (Cow<'a, [f64]>, bool);

/// The fitted term as plant-file specs.
#[derive(Debug, Default)]
pub struct TermSpec {
    /// The spec of the effect on the path (`None`: the term vanished).
    pub spec: Option<Box<dyn EffectSpec>>,
    /// Whole extra paths on the same input, written before it (each holding one spec of the
    /// same effect).
    pub extra_paths: Vec<Box<dyn EffectSpec>>,
}

/// A term of one path: columns after the path's gain column.
pub trait TermFit: Send + Sync {
    /// Nonlinear parameters (moved by Levenberg-Marquardt).
    fn n_params(&self) -> usize {
        0
    }
    /// Their names: a warm start copies a term's parameters when the names agree.
    fn param_names(&self) -> Vec<&'static str> {
        Vec::new()
    }
    /// The interval each parameter is kept inside (Levenberg-Marquardt's steps are projected
    /// onto it); unbounded by default.
    fn param_bounds(&self) -> Vec<(f64, f64)> {
        vec![(f64::NEG_INFINITY, f64::INFINITY); self.n_params()]
    }
    /// The parameters held at 0 (their simplest model: a Bouc-Wen exponent of 1) while the
    /// fit runs from its starts, then freed from its result; their fit is kept only where it
    /// lowers the fitting error significantly
    /// ([`crate::metrics::significantly_lower_error`]), else the refits from that result
    /// (on a long record's whole, with a ridge) hold them at 0. None by default.
    fn optional_params(&self) -> Vec<bool> {
        vec![false; self.n_params()]
    }
    /// A second starting grid for the fit with the optional parameters freed, point i of every
    /// term together: the optional parameters away from 0, in the basin that the fit freed from
    /// its held result may not reach (a Bouc-Wen exponent of 2 where the fit at n = 1 sits at
    /// the bound). Empty by default (no optional parameter).
    fn optional_start_grid(&self) -> Vec<Vec<f64>> {
        Vec::new()
    }
    /// Joint static starting grid: point i of every term is tried together, on the model
    /// without the filters that [`FilterFit::off_when_static`] (empty: no grid).
    fn start_grid(&self) -> Vec<Vec<f64>> {
        Vec::new()
    }
    /// The term's columns (its own indices) whose coefficients sample one density over
    /// evenly spaced thresholds (the plays of a Prandtl-Ishlinskii term): a ridge smooths them
    /// (second differences) rather than shrinking each. None by default.
    fn density_columns(&self) -> Option<std::ops::Range<usize>> {
        None
    }
    /// Number of columns (fixed by the setup).
    fn n_columns(&self) -> usize;
    /// The columns over the whole record for parameters `th` (this term's slice).
    fn columns<'s>(&'s self, th: &[f64]) -> Vec<Column<'s>>;
    /// The columns on the rows `rows` of the record, written into `out` (one buffer per
    /// column, overwritten), in a pass that runs the record's rows in order from the first
    /// (`state` starts empty and carries what the term needs from one block to the next);
    /// returns which columns must have c >= 0. Only the columns where `wanted` is set need be
    /// written (the pass asks for the same ones at every block). The default computes
    /// [`TermFit::columns`] at the first block and keeps them for the pass (a term of a column
    /// or two); a term of many columns whose recursion can resume (the plays) carries its
    /// state instead, so that a long record's columns are never held whole.
    fn columns_block(
        &self,
        th: &[f64],
        rows: Range<usize>,
        state: &mut TermState,
        out: &mut [Vec<f64>],
        wanted: &[bool],
    ) -> Vec<bool> {
        let whole = state.whole.get_or_insert_with(|| {
            self.columns(th)
                .into_iter()
                .map(|(c, nonneg)| (c.into_owned(), nonneg))
                .collect()
        });
        for ((o, (c, _)), _) in out
            .iter_mut()
            .zip(whole.iter())
            .zip(wanted)
            .filter(|(_, w)| **w)
        {
            o.clear();
            o.extend_from_slice(&c[rows.clone()]);
        }
        whole.iter().map(|(_, nonneg)| *nonneg).collect()
    }
    /// The term's parameters (its own indices) whose derivatives it can give a block of rows
    /// at a time ([`TermFit::derivatives_block`]): a long record's fit asks for them so (the
    /// others come whole from [`TermFit::derivative`]). None by default.
    fn derivatives_in_blocks(&self) -> Vec<usize> {
        Vec::new()
    }
    /// [`TermFit::derivative`] of the parameters `qs` (among
    /// [`TermFit::derivatives_in_blocks`]) on the rows `rows`, into `out` (one buffer per
    /// parameter, overwritten), in a pass over the record's rows in order (`state` as in
    /// [`TermFit::columns_block`]): the same values as the whole columns'.
    fn derivatives_block(
        &self,
        _th: &[f64],
        _qs: &[usize],
        _coef: &[f64],
        _rows: Range<usize>,
        _state: &mut TermState,
        _out: &mut [Vec<f64>],
    ) {
    }
    /// d/d th_q of sum_k coef_k column_k (before the filters) at `th`, over the whole record.
    /// A term with parameters must give it (the default, for terms without parameters, is
    /// empty); `graybox`'s derivative test checks the built-in terms against central differences.
    fn derivative(&self, _th: &[f64], _q: usize, _coef: &[f64]) -> Vec<f64> {
        Vec::new()
    }
    /// The fitted term: `gain` is the path's gain coefficient, `coef` this term's coefficients.
    fn spec(&self, th: &[f64], gain: f64, coef: &[f64]) -> TermSpec;
}

/// What a term carries from one block of rows to the next in a pass over the record
/// ([`TermFit::columns_block`]); a pass starts from `TermState::default()`.
#[derive(Debug, Default)]
pub struct TermState {
    /// The columns over the whole record (the default [`TermFit::columns_block`]).
    pub whole: Option<Vec<(Vec<f64>, bool)>>,
    /// A recursion's state at the last row seen (the plays' outputs).
    pub carry: Vec<f64>,
    /// Buffers kept from one block to the next (columns the term computes on its way).
    pub scratch: Vec<Vec<f64>>,
}

/// A filter's state for one signal at the last sample filtered, carried to the next block of
/// the same signal; empty before the first block (the filter at rest).
pub type FilterState = Vec<f64>;

/// A filter that works in place on signals of one length, each filtered alone (a filter may
/// run them side by side for speed; each signal's arithmetic is the same as alone), each
/// resuming from its state (`states[k]` for signal `k`, updated): a signal filtered in blocks
/// gets the same values as filtered whole.
pub type InPlace = Box<dyn Fn(&mut [&mut [f64]], &mut [FilterState]) + Send + Sync>;

/// A filter applied to a signal in place, or a mark that it cannot be applied.
pub enum Prepared {
    /// The filter does nothing at these parameters.
    Identity,
    /// The parameters give no valid filter at this sampling period (the columns become NaN).
    Invalid,
    /// Apply in place.
    Apply(InPlace),
}

/// A linear filter on an output (creep, dynamics).
pub trait FilterFit: Send + Sync {
    fn n_params(&self) -> usize;
    /// Starting parameters.
    fn initial(&self) -> Vec<f64>;
    /// Held at their starting values in the first Levenberg-Marquardt stage (slow parameters
    /// that must wait for the fast ones).
    fn held_first(&self) -> bool {
        false
    }
    /// Left out of the static model of the initialisation.
    fn off_when_static(&self) -> bool {
        false
    }
    /// At parameters `th`, as close to no filter as this filter gets without being the
    /// identity (dynamics: a mode above a quarter of the sampling rate, where its response
    /// cannot be told from a sample's delay): the fit then also tries the output without the
    /// filters that [`FilterFit::off_when_static`].
    fn at_static_edge(&self, _th: &[f64]) -> bool {
        false
    }
    /// The filter at parameters `th` (this filter's slice).
    fn prepare(&self, th: &[f64]) -> Prepared;
    /// d/d th_q of the filter's output for input `x`.
    fn derivative(&self, th: &[f64], x: &[f64], q: usize) -> Vec<f64>;
    /// Several starting points from a grid: `cost` scores this filter's parameters on a coarse
    /// problem; `None` when the filter has no grid.
    fn starts(
        &self,
        _th: &[f64],
        _cost: &dyn Fn(&[f64]) -> f64,
        _count: usize,
    ) -> Option<Vec<Vec<f64>>> {
        None
    }
    /// The fitted filter as a plant-file spec.
    fn spec(&self, th: &[f64]) -> Box<dyn EffectSpec>;
    /// Whether the filter acts on each path of the output alone (its parameters then include
    /// some of each path's: a mode's share in each path, for a 2-DoF cross path that shows
    /// both axes' modes). The fitter filters each path's columns with
    /// [`FilterFit::prepare_path`], asks [`FilterFit::derivative_path`] of each path's sum and
    /// writes [`FilterFit::path_spec`] on the paths instead of [`FilterFit::spec`] on the
    /// output. At most one filter of an output is per path, the last of its chain.
    fn per_path(&self) -> bool {
        false
    }
    /// The filter of path `path` at parameters `th` (a per-path filter's).
    fn prepare_path(&self, th: &[f64], _path: usize) -> Prepared {
        self.prepare(th)
    }
    /// d/d th_q of path `path`'s filter output for its input `x` (a per-path filter's; zeros
    /// for a parameter of another path).
    fn derivative_path(&self, th: &[f64], x: &[f64], q: usize, _path: usize) -> Vec<f64> {
        self.derivative(th, x, q)
    }
    /// [`FilterFit::derivative_path`] of each parameter in `qs`, where the filter computes them
    /// together faster than one at a time (the same values); `None` asks for them one at a time.
    fn derivatives_path(
        &self,
        _th: &[f64],
        _x: &[f64],
        _qs: &[usize],
        _path: usize,
    ) -> Option<Vec<Vec<f64>>> {
        None
    }
    /// The fitted filter of path `path` as a plant-file spec (a per-path filter's).
    fn path_spec(&self, th: &[f64], _path: usize) -> Box<dyn EffectSpec> {
        self.spec(th)
    }
}

/// Why a record cannot support an effect of a grey-box model.
#[derive(Debug, Clone, PartialEq)]
pub enum RecordError {
    /// The record is too short.
    TooShort { needed: usize, why: String },
    /// An input does not excite the effect.
    PoorlyExcited { input: String, why: String },
    /// The effect needs more inputs than the record has.
    NeedsInputs { needed: usize, why: String },
}

/// What an effect's record check sees.
#[derive(Debug, Clone, Copy)]
pub struct RecordView<'a> {
    pub input_names: &'a [&'a str],
    pub inputs: &'a [&'a [f64]],
    pub samples: usize,
    pub ts: f64,
    /// See [`OutputSetup::parsimonious`].
    pub parsimonious: bool,
}

/// Where a sensor hides the model's value: samples at or beyond a limit are censored (the
/// measurement says only that the value is at least `upper`, or at most `lower`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Censoring {
    pub lower: Option<f64>,
    pub upper: Option<f64>,
    /// A sample within this distance of a limit is taken as censored (the noise on it).
    pub tolerance: f64,
}

impl Censoring {
    /// Is measured value `y` censored?
    pub fn censored(&self, y: f64) -> bool {
        self.upper.is_some_and(|h| y >= h - self.tolerance)
            || self.lower.is_some_and(|l| y <= l + self.tolerance)
    }

    /// Is the model's value `model` on the far side of the limit that censors `y`?
    pub fn beyond(&self, y: f64, model: f64) -> bool {
        match (self.upper, self.lower) {
            (Some(h), _) if y >= h - self.tolerance => model >= h,
            (_, Some(l)) if y <= l + self.tolerance => model <= l,
            _ => false,
        }
    }
}

/// A sensor's static map of the measured output (after the offset): what it hides and its
/// fitted spec. The fitter leaves the censored samples out and puts the sensor on the output.
pub trait SensorFit: Send + Sync {
    /// The limits that the measured output `y` (training samples) shows.
    fn censoring(&self, y: &[f64]) -> Censoring;
    /// The fitted sensor as a plant-file spec (`None`: the record shows no limit).
    fn spec(&self, c: &Censoring) -> Option<Box<dyn EffectSpec>>;
}
