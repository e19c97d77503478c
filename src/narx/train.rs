//! # Training
//!
//! The algorithms that fit one MISO network to one output, in standardised units:
//! - [`Optimizer`]: RMSProp and Adam on the flat parameter vector;
//! - [`train_one_step`]: mini-batch one-step-ahead (series-parallel) training, seeded shuffling,
//!   optional early stopping on a validation part;
//! - [`init_output_layer`]: least squares for the output layer and the linear bypass given the
//!   (random) hidden layers, i.e. an ARX fit plus random tanh features;
//! - [`train_simulation_error`]: simulation-error (parallel, output-error) training over windows
//!   that each start from measured outputs (multiple shooting), with exact backpropagation
//!   through the fed-back outputs inside a window, Adam and gradient-norm clipping;
//! - [`free_run`]: the simulation used by prediction and validation, with divergence detection.
//!
//! ## References
//! - K. S. Narendra, K. Parthasarathy, "Identification and control of dynamical systems using
//!   neural networks", IEEE TNN 1(1):4-27, 1990 (series-parallel vs parallel models).
//! - A. H. Ribeiro, L. A. Aguirre, "'Parallel training considered harmful?': Comparing
//!   series-parallel and parallel feedforward network training", Neurocomputing 316:222-231, 2018.
//! - G. Beintema, R. Toth, M. Schoukens, "Nonlinear state-space identification using deep encoder
//!   networks", L4DC 2021 (truncated simulation loss over sub-sections, multiple shooting).
//! - D. P. Kingma, J. Ba, "Adam: a method for stochastic optimization", ICLR 2015.
//! - T. Tieleman, G. Hinton, "RMSProp", COURSERA Neural Networks lecture 6.5, 2012.

use super::config::{OptimizerKind, RobustSettings};
use super::kernel::{self, BatchWorkspace};
use super::mlp::{uniform01, Mlp};
use super::regressors::{Regressor, Series};
use crate::numeric::lstsq::NormalEquations;
use rand::rngs::Xoshiro256PlusPlus;
use rand::SeedableRng;
use serde::{Deserialize, Serialize};

/// RMSProp or Adam state for a flat parameter vector.
#[derive(Debug, Clone)]
pub struct Optimizer {
    kind: OptimizerKind,
    lr: f64,
    m: Vec<f64>,
    v: Vec<f64>,
    t: i32,
}

impl Optimizer {
    /// A fresh optimiser for `n` parameters.
    pub fn new(kind: OptimizerKind, lr: f64, n: usize) -> Optimizer {
        Optimizer {
            kind,
            lr,
            m: vec![0.0; n],
            v: vec![0.0; n],
            t: 0,
        }
    }

    /// One update with gradient `g`.
    #[inline]
    pub fn step(&mut self, params: &mut [f64], g: &[f64]) {
        match self.kind {
            OptimizerKind::Rmsprop => {
                let (rho, eps) = (0.9, 1e-7);
                for ((p, v), gi) in params.iter_mut().zip(self.v.iter_mut()).zip(g) {
                    *v = rho * *v + (1.0 - rho) * gi * gi;
                    *p -= self.lr * gi / (v.sqrt() + eps);
                }
            }
            OptimizerKind::Adam => {
                let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-8);
                self.t = self.t.saturating_add(1);
                let c1 = 1.0 - b1.powi(self.t);
                let c2 = 1.0 - b2.powi(self.t);
                let a = self.lr * c2.sqrt() / c1;
                for (((p, m), v), gi) in params
                    .iter_mut()
                    .zip(self.m.iter_mut())
                    .zip(self.v.iter_mut())
                    .zip(g)
                {
                    *m = b1 * *m + (1.0 - b1) * gi;
                    *v = b2 * *v + (1.0 - b2) * gi * gi;
                    *p -= a * *m / (v.sqrt() + eps * c2.sqrt());
                }
            }
        }
    }
}

/// A row-major regressor matrix with its targets.
#[derive(Debug, Clone)]
pub struct Design {
    pub x: Vec<f64>,
    pub t: Vec<f64>,
    pub width: usize,
}

impl Design {
    /// Regressors of a standardised series.
    pub fn new(s: &Series, reg: &Regressor) -> Design {
        let (x, t) = reg.regressor_matrix(s);
        Design {
            x,
            t,
            width: reg.width(),
        }
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.t.len()
    }

    fn row(&self, i: usize) -> &[f64] {
        &self.x[i * self.width..(i + 1) * self.width]
    }

    /// Mean squared one-step error of a network.
    pub fn mse(&self, mlp: &Mlp) -> f64 {
        if kernel::applies(mlp) {
            let sse = kernel::sum_squared_errors(
                mlp,
                &self.x,
                &self.t,
                MSE_BLOCK,
                &mut BatchWorkspace::new(),
            );
            return sse / self.rows().max(1) as f64;
        }
        let mut acts = vec![0.0; mlp.acts_len()];
        let mut s = 0.0;
        for i in 0..self.rows() {
            mlp.forward(self.row(i), &mut acts);
            let e = mlp.output(&acts)[0] - self.t[i];
            s += e * e;
        }
        s / self.rows().max(1) as f64
    }
}

/// Rows per block of the batched one-step error.
const MSE_BLOCK: usize = 256;

/// Smallest mini-batch trained with the batched kernel; smaller ones go sample by sample.
const MIN_KERNEL_BATCH: usize = 4;

/// What the one-step phase did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OneStepRecord {
    pub epochs_run: usize,
    /// Epoch whose weights were kept (0 = the initial weights).
    pub best_epoch: usize,
    pub train_mse: f64,
    pub validation_mse: Option<f64>,
}

/// Mini-batch one-step-ahead training; with `val` and `patience`, keeps the weights of the best
/// validation epoch and stops after `patience` epochs without improvement.
#[allow(clippy::too_many_arguments)]
pub fn train_one_step(
    mlp: &mut Mlp,
    train: &Design,
    val: Option<&Design>,
    kind: OptimizerKind,
    lr: f64,
    batch: usize,
    epochs: usize,
    patience: Option<usize>,
    seed: u64,
) -> OneStepRecord {
    let n = train.rows();
    let np = mlp.params.len();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut order: Vec<usize> = (0..n).collect();
    let mut opt = Optimizer::new(kind, lr, np);
    let mut grad = vec![0.0; np];
    let mut acts = vec![0.0; mlp.acts_len()];
    let mut scratch = vec![0.0; 2 * mlp.max_width()];
    let batched = kernel::applies(mlp) && batch >= MIN_KERNEL_BATCH;
    let mut bw = BatchWorkspace::new();
    let mut best = val.map(|v| (v.mse(mlp), 0usize, mlp.params.clone()));
    let mut epochs_run = 0;
    for epoch in 1..=epochs {
        // Fisher-Yates shuffle
        for i in (1..n).rev() {
            let j = (uniform01(&mut rng) * (i + 1) as f64) as usize;
            order.swap(i, j.min(i));
        }
        for chunk in order.chunks(batch) {
            let scale = 2.0 / chunk.len() as f64;
            if batched {
                kernel::batch_gradient(mlp, &train.x, &train.t, chunk, scale, &mut grad, &mut bw);
                mlp.hold(&mut grad);
                opt.step(&mut mlp.params, &grad);
                continue;
            }
            grad.iter_mut().for_each(|g| *g = 0.0);
            if mlp.sizes.len() == 3 {
                for &i in chunk {
                    one_hidden_step(mlp, train.row(i), train.t[i], scale, &mut grad, &mut acts);
                }
            } else {
                for &i in chunk {
                    let x = train.row(i);
                    mlp.forward(x, &mut acts);
                    let e = mlp.output(&acts)[0] - train.t[i];
                    mlp.backward(x, &acts, &[scale * e], &mut grad, None, &mut scratch);
                }
            }
            mlp.hold(&mut grad);
            opt.step(&mut mlp.params, &grad);
        }
        epochs_run = epoch;
        if !mlp.params.iter().all(|p| p.is_finite()) {
            break;
        }
        if let (Some(v), Some(b)) = (val, best.as_mut()) {
            let m = v.mse(mlp);
            if m < b.0 {
                *b = (m, epoch, mlp.params.clone());
            } else if patience.is_some_and(|p| epoch - b.1 >= p) {
                break;
            }
        }
    }
    let (validation_mse, best_epoch) = match best {
        Some((m, e, p)) => {
            mlp.params = p;
            (Some(m), e)
        }
        None => (None, epochs_run),
    };
    OneStepRecord {
        epochs_run,
        best_epoch,
        train_mse: train.mse(mlp),
        validation_mse,
    }
}

/// Forward and backward pass of one sample of a one-hidden-layer, one-output network, fused
/// (the hot loop of one-step training): adds `scale * e * d(out)/d(params)` to `grad`.
#[inline]
fn one_hidden_step(mlp: &Mlp, x: &[f64], t: f64, scale: f64, grad: &mut [f64], a: &mut [f64]) {
    let (p, h) = (mlp.sizes[0], mlp.sizes[1]);
    let (w1, rest) = mlp.params.split_at(p * h);
    let (b1, rest) = rest.split_at(h);
    let (w2, rest) = rest.split_at(h);
    let b2 = rest[0];
    let ws = &rest[1..];
    let a = &mut a[..h];
    // pre-activations, then tanh over all neurons in one loop (vectorised), then the output
    for ((ao, row), &bo) in a.iter_mut().zip(w1.chunks_exact(p)).zip(b1) {
        let mut z = bo;
        for (wi, xi) in row.iter().zip(x) {
            z += wi * xi;
        }
        *ao = z;
    }
    for v in a.iter_mut() {
        *v = super::mlp::tanh(*v);
    }
    let mut out = b2;
    for (&ao, &wo) in a.iter().zip(w2) {
        out += wo * ao;
    }
    if mlp.bypass {
        for (wi, xi) in ws.iter().zip(x) {
            out += wi * xi;
        }
    }
    let g = scale * (out - t);
    let (gw1, grest) = grad.split_at_mut(p * h);
    let (gb1, grest) = grest.split_at_mut(h);
    let (gw2, grest) = grest.split_at_mut(h);
    grest[0] += g;
    if mlp.bypass {
        for (gi, xi) in grest[1..].iter_mut().zip(x) {
            *gi += g * xi;
        }
    }
    for ((((grow, gbo), gwo), &ao), &wo) in gw1
        .chunks_exact_mut(p)
        .zip(gb1.iter_mut())
        .zip(gw2.iter_mut())
        .zip(a.iter())
        .zip(w2)
    {
        *gwo += g * ao;
        let d = g * wo * (1.0 - ao * ao);
        *gbo += d;
        for (gi, xi) in grow.iter_mut().zip(x) {
            *gi += d * xi;
        }
    }
}

/// Least-squares output layer (and bypass) given the hidden layers: minimises the one-step error
/// with a small ridge term. With random hidden weights this is an ARX fit plus random tanh
/// features; a sound start for gradient training.
pub fn init_output_layer(mlp: &mut Mlp, d: &Design, ridge: f64) {
    let nl = mlp.sizes.len() - 1;
    let h = mlp.sizes[nl - 1];
    let p = d.width;
    let cols = h + 1 + if mlp.bypass { p } else { 0 };
    let mut ne = NormalEquations::new(cols);
    let mut acts = vec![0.0; mlp.acts_len()];
    let mut row = vec![0.0; cols];
    let hid_end = mlp.acts_len() - 1;
    for i in 0..d.rows() {
        let x = d.row(i);
        mlp.forward(x, &mut acts);
        row[..h].copy_from_slice(&acts[hid_end - h..hid_end]);
        row[h] = 1.0;
        if mlp.bypass {
            row[h + 1..].copy_from_slice(x);
        }
        ne.add_row(&row, d.t[i]);
    }
    let Some(w) = ne.solve(ridge * d.rows() as f64) else {
        return;
    };
    let off = mlp.bypass_offset() - h - 1;
    for j in 0..h {
        mlp.params[off + j] = w[j];
    }
    mlp.params[off + h] = w[h];
    if mlp.bypass {
        let bo = mlp.bypass_offset();
        for j in 0..p {
            mlp.params[bo + j] = w[h + 1 + j];
        }
    }
}

/// The linear candidate in a network with a bypass: the output layer's hidden weights set to
/// zero, its bias and the bypass fitted by least squares on the one-step error (with a small
/// ridge): an ARX model in the network's regressors. False (the network unchanged) without a
/// bypass or when the least squares has no solution.
pub fn linear_output_layer(mlp: &mut Mlp, d: &Design, ridge: f64) -> bool {
    if !mlp.bypass {
        return false;
    }
    let h = mlp.sizes[mlp.sizes.len() - 2];
    let p = d.width;
    let mut ne = NormalEquations::new(1 + p);
    let mut row = vec![0.0; 1 + p];
    row[0] = 1.0;
    for i in 0..d.rows() {
        row[1..].copy_from_slice(d.row(i));
        ne.add_row(&row, d.t[i]);
    }
    let Some(w) = ne.solve(ridge * d.rows() as f64) else {
        return false;
    };
    let off = mlp.bypass_offset() - h - 1;
    mlp.params[off..off + h].fill(0.0);
    mlp.params[off + h] = w[0];
    let bo = mlp.bypass_offset();
    mlp.params[bo..bo + p].copy_from_slice(&w.as_slice()[1..]);
    true
}

/// A free run of a standardised series: the first `lags.start()` outputs are the measured ones,
/// after that the network's own. Stops at the first sample outside `[lo, hi]` (or non-finite) and
/// returns its index as the divergence point.
pub fn free_run(
    mlp: &Mlp,
    reg: &Regressor,
    s: &Series,
    lo: f64,
    hi: f64,
) -> (Vec<f64>, Option<usize>) {
    let n = s.len();
    let start = reg.lags.start().min(n);
    let mut y = Vec::with_capacity(n);
    y.extend_from_slice(&s.y[..start]);
    let p = reg.width();
    let mut x = vec![0.0; p];
    let mut acts = vec![0.0; mlp.acts_len()];
    let sc = reg.scale();
    for k in start..n {
        reg.fill_outputs(&y, k, &mut x);
        reg.fill_inputs(&s.u, k, &mut x);
        mlp.forward(&x, &mut acts);
        let v = reg.base(&y, k) + sc * mlp.output(&acts)[0];
        if !(v >= lo && v <= hi) {
            return (y, Some(k));
        }
        y.push(v);
    }
    (y, None)
}

/// Fast free run for prediction of a one-hidden-layer network: the exogenous part of the first
/// layer is computed once per sample, only the output lags go through the loop. Same numbers
/// as [`free_run`] up to rounding order. Falls back to [`free_run`] for deeper networks.
pub fn free_run_fast(
    mlp: &Mlp,
    reg: &Regressor,
    s: &Series,
    lo: f64,
    hi: f64,
) -> (Vec<f64>, Option<usize>) {
    if mlp.sizes.len() != 3 {
        return free_run(mlp, reg, s, lo, hi);
    }
    #[cfg(target_arch = "x86_64")]
    if kernel::uses_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { free_run_one_hidden_avx2(mlp, reg, s, lo, hi) };
    }
    free_run_one_hidden(mlp, reg, s, lo, hi)
}

/// [`free_run_fast`] built for AVX2 (the same operations in the same order: same bits).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn free_run_one_hidden_avx2(
    mlp: &Mlp,
    reg: &Regressor,
    s: &Series,
    lo: f64,
    hi: f64,
) -> (Vec<f64>, Option<usize>) {
    free_run_one_hidden(mlp, reg, s, lo, hi)
}

/// The body of [`free_run_fast`]: per sample, every neuron's input (exogenous regressors, then
/// output lags, each added to all neurons at once), tanh over all neurons in whole vectors, and
/// the output sum in neuron order ([`OneHidden::output`]).
#[inline(always)]
fn free_run_one_hidden(
    mlp: &Mlp,
    reg: &Regressor,
    s: &Series,
    lo: f64,
    hi: f64,
) -> (Vec<f64>, Option<usize>) {
    let n = s.len();
    let start = reg.lags.start().min(n);
    let net = OneHidden::new(mlp, reg.lags.output);
    let sc = reg.scale();
    let mut y = Vec::with_capacity(n);
    y.extend_from_slice(&s.y[..start]);
    let mut w = net.workspace();
    for k in start..n {
        reg.fill_inputs(&s.u, k, &mut w.x);
        reg.fill_outputs(&y, k, &mut w.x);
        let v = reg.base(&y, k) + sc * net.output(&mut w);
        if !(v >= lo && v <= hi) {
            return (y, Some(k));
        }
        y.push(v);
    }
    (y, None)
}

/// A one-hidden-layer network packed for one regressor at a time: W1 by groups of 4 neurons
/// (padded with zeros), group c holding, for each regressor in the order of the sums
/// (exogenous first, then output lags), its 4 weights. The free run of prediction and the
/// compensator's stepped model ([`super::state`]) share it: the same operations in the same
/// order, so the same bits.
#[derive(Debug, Clone)]
pub(super) struct OneHidden {
    p: usize,
    ny: usize,
    w1c: Vec<f64>,
    b1p: Vec<f64>,
    w2: Vec<f64>,
    b2: f64,
    /// Bypass weights of the exogenous regressors and of the output lags (empty: no bypass).
    wsu: Vec<f64>,
    wsy: Vec<f64>,
}

/// The buffers of [`OneHidden::output`]: `x` is the regressor (output lags first, as
/// [`Regressor`] writes it).
#[derive(Debug, Clone)]
pub(super) struct OneHiddenWork {
    pub x: Vec<f64>,
    xo: Vec<f64>,
    act: Vec<f64>,
}

const V: usize = 4;

/// A one-hidden-layer network's first layer by groups of [`V`] neurons (padded with zeros):
/// group c holds, for each regressor in `order`, its [`V`] weights; then the biases, padded.
fn pack_hidden(mlp: &Mlp, order: &[usize]) -> (Vec<f64>, Vec<f64>) {
    let (p, h) = (mlp.sizes[0], mlp.sizes[1]);
    let hp = h.div_ceil(V) * V;
    let mut w1c = vec![0.0; hp * p];
    for o in 0..h {
        let (c, l) = (o / V, o % V);
        for (jj, &j) in order.iter().enumerate() {
            w1c[(c * p + jj) * V + l] = mlp.params[o * p + j];
        }
    }
    let mut b1p = vec![0.0; hp];
    b1p[..h].copy_from_slice(&mlp.params[p * h..p * h + h]);
    (w1c, b1p)
}

impl OneHidden {
    /// `mlp` must have one hidden layer (`mlp.sizes.len() == 3`); `ny` output lags.
    pub fn new(mlp: &Mlp, ny: usize) -> OneHidden {
        let (p, h) = (mlp.sizes[0], mlp.sizes[1]);
        let order: Vec<usize> = (ny..p).chain(0..ny).collect();
        let (w1c, b1p) = pack_hidden(mlp, &order);
        let (wsu, wsy) = if mlp.bypass {
            let ws = &mlp.params[mlp.bypass_offset()..];
            (ws[ny..].to_vec(), ws[..ny].to_vec())
        } else {
            (Vec::new(), vec![0.0; ny])
        };
        OneHidden {
            p,
            ny,
            w1c,
            b1p,
            w2: mlp.params[p * h + h..p * h + 2 * h].to_vec(),
            b2: mlp.params[p * h + 2 * h],
            wsu,
            wsy,
        }
    }

    pub fn workspace(&self) -> OneHiddenWork {
        OneHiddenWork {
            x: vec![0.0; self.p],
            xo: vec![0.0; self.p],
            act: vec![0.0; self.b1p.len()],
        }
    }

    /// The network's output for the regressor in `w.x`. (Long on purpose: the hot loop of
    /// every free run, kept in one piece so that the compiler keeps its buffers in registers.)
    #[inline(always)]
    pub fn output(&self, w: &mut OneHiddenWork) -> f64 {
        let (p, ny) = (self.p, self.ny);
        let x = &w.x;
        w.xo[..p - ny].copy_from_slice(&x[ny..]);
        w.xo[p - ny..].copy_from_slice(&x[..ny]);
        let mut out = self.b2;
        for (wi, xi) in self.wsu.iter().zip(&x[ny..]) {
            out += wi * xi;
        }
        // four neurons at a time: bias, exogenous regressors, output lags, tanh
        for ((ac, bc), wc) in w
            .act
            .chunks_exact_mut(V)
            .zip(self.b1p.chunks_exact(V))
            .zip(self.w1c.chunks_exact(p * V))
        {
            let mut a = [bc[0], bc[1], bc[2], bc[3]];
            for (wj, &xj) in wc.chunks_exact(V).zip(&w.xo) {
                for l in 0..V {
                    a[l] += wj[l] * xj;
                }
            }
            for l in 0..V {
                ac[l] = super::mlp::tanh(a[l]);
            }
        }
        for (wo, a) in self.w2.iter().zip(&w.act) {
            out += wo * a;
        }
        for (wi, xi) in self.wsy.iter().zip(&x[..ny]) {
            out += wi * xi;
        }
        out
    }
}

/// Workspace of the simulation-error gradient over one window.
struct SimWorkspace {
    yb: Vec<f64>,
    xs: Vec<f64>,
    acts: Vec<f64>,
    carry: Vec<f64>,
    gx: Vec<f64>,
    glag: Vec<f64>,
    scratch: Vec<f64>,
}

impl SimWorkspace {
    fn new(mlp: &Mlp, reg: &Regressor, window: usize) -> SimWorkspace {
        SimWorkspace {
            yb: vec![0.0; reg.lags.output + window],
            xs: vec![0.0; window * mlp.n_in()],
            acts: vec![0.0; window * mlp.acts_len()],
            carry: vec![0.0; window],
            gx: vec![0.0; mlp.n_in()],
            glag: vec![0.0; reg.lags.output],
            scratch: vec![0.0; 2 * mlp.max_width()],
        }
    }
}

/// A network's forward pass of one sample, as [`Mlp::forward`] gives it.
trait Pass {
    fn forward(&self, x: &[f64], acts: &mut [f64]);
}

impl Pass for Mlp {
    #[inline(always)]
    fn forward(&self, x: &[f64], acts: &mut [f64]) {
        Mlp::forward(self, x, acts);
    }
}

/// A one-hidden-layer network of one output packed for [`Pass`]: W1 by groups of [`V`] neurons
/// ([`pack_hidden`], the regressors in order), so that a group's sums run in the lanes of one
/// register. Each neuron's sum and the output's take [`Mlp::forward`]'s operations in its
/// order: the same bits.
struct InOrder<'a> {
    mlp: &'a Mlp,
    /// Regressors and hidden neurons.
    p: usize,
    h: usize,
    w1c: Vec<f64>,
    b1p: Vec<f64>,
    /// Whether the processor has AVX2 (the tanh of a group in one register's lanes).
    avx2: bool,
}

impl<'a> InOrder<'a> {
    /// The tanh of a group's sums.
    #[inline(always)]
    fn tanh(&self, a: [f64; V]) -> [f64; V] {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the processor has AVX2 (`avx2` is set so only then)
            return unsafe { super::mlp::tanh_4(a) };
        }
        a.map(super::mlp::tanh)
    }

    /// `None` unless `mlp` has one hidden layer and one output.
    fn new(mlp: &'a Mlp) -> Option<InOrder<'a>> {
        if mlp.sizes.len() != 3 || mlp.sizes[2] != 1 {
            return None;
        }
        let (p, h) = (mlp.sizes[0], mlp.sizes[1]);
        let (w1c, b1p) = pack_hidden(mlp, &(0..p).collect::<Vec<_>>());
        Some(InOrder {
            mlp,
            p,
            h,
            w1c,
            b1p,
            avx2: crate::numeric::simd::uses_avx2(),
        })
    }
}

impl Pass for InOrder<'_> {
    #[inline(always)]
    fn forward(&self, x: &[f64], acts: &mut [f64]) {
        let (p, h) = (self.p, self.h);
        let params = &self.mlp.params;
        for (c, (bc, wc)) in self
            .b1p
            .chunks_exact(V)
            .zip(self.w1c.chunks_exact(p * V))
            .enumerate()
        {
            let mut a = [bc[0], bc[1], bc[2], bc[3]];
            for (wj, &xj) in wc.chunks_exact(V).zip(x) {
                for l in 0..V {
                    a[l] += wj[l] * xj;
                }
            }
            // all lanes' tanh side by side (the padding's is dropped)
            let t: [f64; V] = self.tanh(a);
            let k = h.saturating_sub(c * V).min(V);
            acts[c * V..c * V + k].copy_from_slice(&t[..k]);
        }
        let w2 = &params[p * h + h..p * h + 2 * h];
        let mut out = params[p * h + 2 * h];
        for (w, a) in w2.iter().zip(&acts[..h]) {
            out += w * a;
        }
        acts[h] = out;
        if self.mlp.bypass {
            let mut s = 0.0;
            for (w, xi) in params[self.mlp.bypass_offset()..].iter().zip(&x[..p]) {
                s += w * xi;
            }
            acts[h] += s;
        }
    }
}

/// Simulation error over the window `s0..s0 + len` (which starts from measured outputs) and its
/// exact gradient (added to `grad`, unnormalised: d/dθ sum e^2). Returns (sum e^2, samples).
/// A window whose simulation leaves `[-bound, bound]` is cut there. A network of one hidden
/// layer runs packed ([`InOrder`]), built for AVX2 where the processor has it: the same bits.
#[allow(clippy::too_many_arguments)]
fn window_gradient(
    mlp: &Mlp,
    reg: &Regressor,
    s: &Series,
    s0: usize,
    len: usize,
    bound: f64,
    grad: &mut [f64],
    ws: &mut SimWorkspace,
) -> (f64, usize) {
    match InOrder::new(mlp) {
        Some(net) => crate::numeric::simd::wide(
            #[inline(always)]
            || window_gradient_of(&net, mlp, reg, s, s0, len, bound, grad, ws),
        ),
        None => window_gradient_of(mlp, mlp, reg, s, s0, len, bound, grad, ws),
    }
}

/// The body of [`window_gradient`] with the forward pass of `net` (the network `mlp`).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn window_gradient_of(
    net: &impl Pass,
    mlp: &Mlp,
    reg: &Regressor,
    s: &Series,
    s0: usize,
    len: usize,
    bound: f64,
    grad: &mut [f64],
    ws: &mut SimWorkspace,
) -> (f64, usize) {
    let ny = reg.lags.output;
    let p = mlp.n_in();
    let na = mlp.acts_len();
    let sc = reg.scale();
    // yb[i] holds y(s0 - ny + i)
    ws.yb[..ny].copy_from_slice(&s.y[s0 - ny..s0]);
    let mut n_eff = len;
    for t in 0..len {
        let k = s0 + t;
        let x = &mut ws.xs[t * p..(t + 1) * p];
        // regressor from the window buffer: index k in the series is ny + t in yb
        reg.fill_outputs(&ws.yb, ny + t, x);
        reg.fill_inputs(&s.u, k, x);
        let acts = &mut ws.acts[t * na..(t + 1) * na];
        net.forward(x, acts);
        let v = reg.base(&ws.yb, ny + t) + sc * acts[na - 1];
        if v.is_nan() || v.abs() > bound {
            n_eff = t;
            break;
        }
        ws.yb[ny + t] = v;
    }
    let mut sse = 0.0;
    ws.carry[..n_eff].iter_mut().for_each(|c| *c = 0.0);
    for t in (0..n_eff).rev() {
        let e = ws.yb[ny + t] - s.y[s0 + t];
        sse += e * e;
        let gz = 2.0 * e + ws.carry[t];
        let x = &ws.xs[t * p..(t + 1) * p];
        let acts = &ws.acts[t * na..(t + 1) * na];
        mlp.backward(x, acts, &[gz * sc], grad, Some(&mut ws.gx), &mut ws.scratch);
        reg.output_lag_gradient(gz, &ws.gx, &mut ws.glag);
        for j in 0..ny.min(t) {
            ws.carry[t - 1 - j] += ws.glag[j];
        }
    }
    (sse, n_eff)
}

/// What the simulation-error phase did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimulationRecord {
    pub steps_run: usize,
    /// Step whose weights were kept (0 = the one-step weights).
    pub best_step: usize,
    pub window: usize,
    pub windows_per_step: usize,
    /// Free-run validation MSE (standardised units) before and after.
    pub validation_mse_before: Option<f64>,
    pub validation_mse_after: Option<f64>,
}

/// Free-run validation score: simulate the whole series from its start and take the MSE over
/// samples `from..` (standardised units); `None` when the run diverges.
pub fn free_run_score(
    mlp: &Mlp,
    reg: &Regressor,
    s: &Series,
    from: usize,
    lo: f64,
    hi: f64,
) -> Option<f64> {
    let (y, div) = free_run_fast(mlp, reg, s, lo, hi);
    if div.is_some() {
        return None;
    }
    let from = from.max(reg.lags.start());
    let n = s.len() - from;
    if n == 0 {
        return None;
    }
    let sse: f64 = (from..s.len()).map(|k| (y[k] - s.y[k]).powi(2)).sum();
    Some(sse / n as f64)
}

/// Simulation-error training on `s.slice(0..fit_end)` with windows; every `eval_every` steps the
/// free run of the validation series `val`, scored on `val_from..`, decides which weights to keep.
/// (Long on purpose: one training loop whose steps share the window, optimiser and best-so-far
/// state; split, they would pass all of it around.)
#[allow(clippy::too_many_arguments)]
pub fn train_simulation_error(
    mlp: &mut Mlp,
    reg: &Regressor,
    s: &Series,
    fit_end: usize,
    val: &Series,
    val_from: usize,
    lo: f64,
    hi: f64,
    r: &RobustSettings,
    seed: u64,
) -> SimulationRecord {
    let start = reg.lags.start();
    let avail = fit_end.saturating_sub(start);
    // A short record is one window (full simulation-error gradient).
    let (window, per_step) = if avail <= 2 * r.window {
        (avail, 1)
    } else {
        (r.window, (r.samples_per_step / r.window).max(1))
    };
    let before = free_run_score(mlp, reg, val, val_from, lo, hi);
    let mut best = (before.unwrap_or(f64::INFINITY), 0usize, mlp.params.clone());
    let mut rec = SimulationRecord {
        steps_run: 0,
        best_step: 0,
        window,
        windows_per_step: per_step,
        validation_mse_before: before,
        validation_mse_after: before,
    };
    if window < 2 {
        return rec;
    }
    // Windows are cut where the simulation leaves three times the data's amplitude: beyond
    // that the trajectory carries no useful gradient, only overflow.
    let amp = s.y[..fit_end].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let bound = (3.0 * amp).max(1.0);
    let mut skipped = 0;
    let np = mlp.params.len();
    let mut opt = Optimizer::new(OptimizerKind::Adam, r.sim_lr, np);
    let mut grad = vec![0.0; np];
    let mut ws = SimWorkspace::new(mlp, reg, window);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut since_best = 0;
    for step in 1..=r.sim_steps {
        grad.iter_mut().for_each(|g| *g = 0.0);
        let mut n_tot = 0usize;
        for w in 0..per_step {
            // The first window of every step starts at the record's start, so the model also
            // learns from (and stays stable through) whatever transient the record begins with.
            let s0 = if (per_step == 1 && window == avail) || w == 0 {
                start
            } else {
                start + (uniform01(&mut rng) * (avail - window + 1) as f64) as usize
            };
            let (_, n) = window_gradient(mlp, reg, s, s0, window, bound, &mut grad, &mut ws);
            n_tot += n;
        }
        // the weights held at zero take no part in the step, nor in its clipping norm
        mlp.hold(&mut grad);
        let scale = 1.0 / n_tot.max(1) as f64;
        let mut norm = 0.0;
        for g in grad.iter_mut() {
            *g *= scale;
            norm += *g * *g;
        }
        if r.weight_decay > 0.0 {
            // hidden layers' weights only (not biases, output layer or bypass)
            let mut off = 0;
            for l in 0..mlp.sizes.len() - 2 {
                let (ni, no) = (mlp.sizes[l], mlp.sizes[l + 1]);
                for (g, p) in grad[off..off + ni * no]
                    .iter_mut()
                    .zip(&mlp.params[off..off + ni * no])
                {
                    *g += 2.0 * r.weight_decay * p;
                }
                off += ni * no + no;
            }
        }
        let norm = norm.sqrt();
        if !norm.is_finite() {
            // an overflowing step is skipped; many in a row end the phase
            skipped += 1;
            if skipped >= 20 {
                break;
            }
            continue;
        }
        skipped = 0;
        if norm > 1.0 {
            grad.iter_mut().for_each(|g| *g /= norm);
        }
        opt.step(&mut mlp.params, &grad);
        rec.steps_run = step;
        if step % r.eval_every == 0 || step == r.sim_steps {
            let sc = free_run_score(mlp, reg, val, val_from, lo, hi).unwrap_or(f64::INFINITY);
            if sc < best.0 {
                best = (sc, step, mlp.params.clone());
                since_best = 0;
            } else {
                since_best += 1;
                if since_best >= r.sim_patience {
                    break;
                }
            }
        }
    }
    mlp.params = best.2;
    rec.best_step = best.1;
    rec.validation_mse_after = best.0.is_finite().then_some(best.0);
    rec
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;
    use crate::narx::regressors::{Lags, RegressorForm};

    fn lags(output: usize, input: usize) -> Lags {
        Lags {
            output,
            input,
            delay: 1,
        }
    }

    fn series(n: usize, m: usize) -> Series {
        Series {
            y: (0..n)
                .map(|k| (0.2 * k as f64).sin() + 0.1 * (0.9 * k as f64).cos())
                .collect(),
            u: (0..m)
                .map(|j| {
                    (0..n)
                        .map(|k| (0.13 * (j + 1) as f64 * k as f64).cos())
                        .collect()
                })
                .collect(),
        }
    }

    #[test]
    fn simulation_gradient_matches_finite_differences() {
        let lags = lags(3, 2);
        let s = series(60, 2);
        for form in [RegressorForm::Lagged, RegressorForm::Incremental] {
            let reg = Regressor::fit(lags, form, &s);
            let mut m = Mlp::glorot(&[reg.width(), 6, 1], true, 5);
            let mut r = Xoshiro256PlusPlus::seed_from_u64(9);
            for p in m.params.iter_mut() {
                *p = 0.3 * *p + 0.05 * (uniform01(&mut r) - 0.5);
            }
            let (s0, len) = (5, 40);
            let mut ws = SimWorkspace::new(&m, &reg, len);
            let mut grad = vec![0.0; m.params.len()];
            let (sse, ne) = window_gradient(&m, &reg, &s, s0, len, 1e9, &mut grad, &mut ws);
            assert_eq!(ne, len);
            assert!(sse > 0.0);
            let h = 1e-6;
            for i in 0..m.params.len() {
                let mut g0 = vec![0.0; m.params.len()];
                let mut mp = m.clone();
                mp.params[i] += h;
                let (sp, _) = window_gradient(&mp, &reg, &s, s0, len, 1e9, &mut g0, &mut ws);
                let mut mm = m.clone();
                mm.params[i] -= h;
                let (sm, _) = window_gradient(&mm, &reg, &s, s0, len, 1e9, &mut g0, &mut ws);
                let fd = (sp - sm) / (2.0 * h);
                assert!(
                    (fd - grad[i]).abs() < 1e-6 * (1.0 + fd.abs()),
                    "{form:?} param {i}: fd {fd} vs {}",
                    grad[i]
                );
            }
        }
    }

    /// A window with the packed forward pass ([`InOrder`], in AVX2 lanes where the processor has them)
    /// give the bits of [`Mlp`]'s own, with and without the bypass, for 1 to 9 neurons, and
    /// over a window cut where its simulation leaves the bound.
    #[test]
    fn packed_window_passes_equal_the_network_s_own() {
        let s = series(120, 2);
        let reg = Regressor::fit(lags(3, 2), RegressorForm::Incremental, &s);
        for (h, bypass, bound) in [
            (1, true, 1e9),
            (4, false, 1e9),
            (9, true, 1e9),
            (6, true, 0.5),
        ] {
            let mut m = Mlp::glorot(&[reg.width(), h, 1], bypass, h as u64);
            let mut r = Xoshiro256PlusPlus::seed_from_u64(3);
            for p in m.params.iter_mut() {
                *p = 0.4 * *p + 0.2 * (uniform01(&mut r) - 0.5);
            }
            let len = 100;
            let (mut wa, mut wb) = (
                SimWorkspace::new(&m, &reg, len),
                SimWorkspace::new(&m, &reg, len),
            );
            let (mut ga, mut gb) = (vec![0.0; m.params.len()], vec![0.0; m.params.len()]);
            let net = InOrder::new(&m).expect("one hidden layer");
            let a = crate::numeric::simd::wide(|| {
                window_gradient_of(&net, &m, &reg, &s, 5, len, bound, &mut ga, &mut wa)
            });
            let b = window_gradient_of(&m, &m, &reg, &s, 5, len, bound, &mut gb, &mut wb);
            assert_eq!(a.1, b.1, "{h} neurons: samples");
            assert_eq!(a.0.to_bits(), b.0.to_bits(), "{h} neurons: sum of squares");
            assert!(
                ga.iter().zip(&gb).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{h} neurons"
            );
        }
    }

    #[test]
    fn fast_free_run_equals_plain_free_run_and_window_simulation() {
        let lags = lags(4, 3);
        let s = series(300, 2);
        for form in [RegressorForm::Lagged, RegressorForm::Incremental] {
            let reg = Regressor::fit(lags, form, &s);
            let mut m = Mlp::glorot(&[reg.width(), 7, 1], true, 2);
            let bo = m.bypass_offset();
            m.params[bo] = 0.5;
            m.params.iter_mut().for_each(|p| *p *= 0.2);
            let (a, da) = free_run(&m, &reg, &s, -1e3, 1e3);
            let (b, db) = free_run_fast(&m, &reg, &s, -1e3, 1e3);
            assert_eq!(da, None);
            assert_eq!(da, db);
            for (x, y) in a.iter().zip(&b) {
                assert!((x - y).abs() < 1e-9);
            }
            // the training simulation is the same free run
            let st = lags.start();
            let mut ws = SimWorkspace::new(&m, &reg, 300 - st);
            let mut g = vec![0.0; m.params.len()];
            let (sse, _) = window_gradient(&m, &reg, &s, st, 300 - st, 1e9, &mut g, &mut ws);
            let want: f64 = (st..300).map(|k| (a[k] - s.y[k]).powi(2)).sum();
            assert!((sse - want).abs() < 1e-9 * (1.0 + want), "{sse} vs {want}");
        }
    }

    /// On an AVX2 machine this compares the two builds of the free run (same operations in the
    /// same order: it fails if either gains fused multiply-adds or a reordering); elsewhere
    /// both calls run the portable build.
    #[test]
    fn free_run_is_the_same_in_the_simd_and_the_baseline_build() {
        let lags = lags(4, 3);
        let s = series(400, 1);
        let reg = Regressor::fit(lags, RegressorForm::Incremental, &s);
        let mut m = Mlp::glorot(&[reg.width(), 10, 1], true, 8);
        m.params.iter_mut().for_each(|p| *p *= 0.3);
        let (a, da) = free_run_fast(&m, &reg, &s, -1e3, 1e3);
        let (b, db) = free_run_one_hidden(&m, &reg, &s, -1e3, 1e3);
        assert_eq!(da, db);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a), bits(&b));
    }

    #[test]
    fn fused_one_hidden_step_equals_forward_backward() {
        for bypass in [false, true] {
            let mut m = Mlp::glorot(&[5, 7, 1], bypass, 4);
            m.params
                .iter_mut()
                .enumerate()
                .for_each(|(i, p)| *p += 0.01 * i as f64);
            let x = [0.3, -0.2, 0.5, 1.1, -0.7];
            let mut g1 = vec![0.0; m.params.len()];
            let mut g2 = vec![0.0; m.params.len()];
            let mut acts = vec![0.0; m.acts_len()];
            let mut scratch = vec![0.0; 2 * m.max_width()];
            one_hidden_step(&m, &x, 0.4, 0.5, &mut g1, &mut acts);
            m.forward(&x, &mut acts);
            let e = m.output(&acts)[0] - 0.4;
            m.backward(&x, &acts, &[0.5 * e], &mut g2, None, &mut scratch);
            for (a, b) in g1.iter().zip(&g2) {
                assert!((a - b).abs() < 1e-14, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn least_squares_init_recovers_a_linear_arx() {
        let lags = lags(2, 2);
        let n = 500;
        let u: Vec<f64> = (0..n)
            .map(|k| (0.1 * k as f64).sin() + (0.37 * k as f64).cos())
            .collect();
        let mut y = vec![0.0; n];
        for k in 2..n {
            y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2] + 0.3 * u[k - 1] + 0.1 * u[k - 2];
        }
        let s = Series { y, u: vec![u] };
        for form in [RegressorForm::Lagged, RegressorForm::Incremental] {
            let reg = Regressor::fit(lags, form, &s);
            let d = Design::new(&s, &reg);
            let mut m = Mlp::glorot(&[4, 5, 1], true, 1);
            init_output_layer(&mut m, &d, 1e-14);
            assert!(d.mse(&m) < 1e-12, "{form:?}: {}", d.mse(&m));
        }
    }
}
