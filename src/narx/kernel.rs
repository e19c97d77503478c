//! # Batched kernels for one-hidden-layer networks
//!
//! The hot loops of one-step training and of one-step evaluation for the networks NARX uses most
//! (inputs -> one tanh hidden layer -> one linear output, with or without the linear bypass),
//! written over a whole mini-batch at once: the batch's regressors are gathered into a
//! transposed, zero-padded buffer (one contiguous row per regressor), so the forward pass, tanh,
//! and the gradient's sums over the batch run lane-wise over samples in straight loops that the
//! compiler turns into SIMD code.
//!
//! Determinism: every operation is plain IEEE f64 arithmetic (no `exp` from libm, no fused
//! multiply-add: Rust never contracts `a * b + c`), the sums over the batch use a fixed
//! [`LANES`]-way split and a fixed reduction tree. So the numbers do not depend on the SIMD
//! width: the AVX2 build chosen at run time (x86_64) and the baseline SSE2 build give the same
//! bits, on every machine and at any thread count.
//!
//! ## References
//! - K. Goto, R. van de Geijn, "Anatomy of high-performance matrix multiplication", ACM TOMS
//!   34(3), 2008 (register blocking, packed operands).
//! - W. J. Cody, W. Waite, "Software Manual for the Elementary Functions", Prentice-Hall, 1980
//!   (argument reduction of `exp`, used by [`super::mlp::tanh`]).

use super::mlp::{tanh, Mlp};

/// Samples processed side by side; batches are padded to a multiple of it.
pub const LANES: usize = 8;

type Lanes = [f64; LANES];

/// Fixed-order sum of the lanes (the same tree on every machine): halves added lane-wise,
/// as a vector reduction does it.
#[inline(always)]
fn reduce(a: &Lanes) -> f64 {
    let h4 = [a[0] + a[4], a[1] + a[5], a[2] + a[6], a[3] + a[7]];
    let h2 = [h4[0] + h4[2], h4[1] + h4[3]];
    h2[0] + h2[1]
}

/// Workspace of the batched kernels (grows to the largest batch seen; no allocation after).
#[derive(Debug, Clone, Default)]
pub struct BatchWorkspace {
    /// Regressors packed by blocks of [`LANES`] samples: block c holds, for each regressor i,
    /// the `LANES` values of samples `c * LANES..`, contiguous (zero in the padding).
    xt: Vec<f64>,
    /// Targets, then the output gradient, per sample (zero in the padding).
    g: Vec<f64>,
    /// Hidden activations, packed by blocks like `xt`.
    a: Vec<f64>,
    /// Lane-wise gradient accumulators, in the layout of the parameters.
    acc: Vec<Lanes>,
    /// Padded batch length.
    bp: usize,
}

impl BatchWorkspace {
    /// An empty workspace.
    pub fn new() -> BatchWorkspace {
        BatchWorkspace::default()
    }

    fn prepare(&mut self, p: usize, h: usize, np: usize, b: usize) {
        let bp = b.div_ceil(LANES) * LANES;
        self.bp = bp;
        for (v, n) in [
            (&mut self.xt, p * bp),
            (&mut self.g, bp),
            (&mut self.a, h * bp),
        ] {
            if v.len() < n {
                v.resize(n, 0.0);
            }
        }
        if self.acc.len() < np {
            self.acc.resize(np, [0.0; LANES]);
        }
    }

    /// Packs rows `rows` of the row-major matrix `x` (`p` columns) and their targets.
    #[inline(always)]
    fn gather(
        &mut self,
        x: &[f64],
        t: &[f64],
        p: usize,
        rows: impl ExactSizeIterator<Item = usize>,
    ) {
        let b = rows.len();
        let bp = self.bp;
        let xt = &mut self.xt[..p * bp];
        for (s, r) in rows.enumerate() {
            let (c, l) = (s / LANES, s % LANES);
            let block = &mut xt[c * p * LANES..(c + 1) * p * LANES];
            for (v, dst) in x[r * p..(r + 1) * p]
                .iter()
                .zip(block.chunks_exact_mut(LANES))
            {
                dst[l] = *v;
            }
            self.g[s] = t[r];
        }
        if b < bp {
            let block = &mut xt[(bp - LANES) * p..];
            for dst in block.chunks_exact_mut(LANES) {
                dst[b % LANES..].fill(0.0);
            }
            self.g[b..bp].fill(0.0);
        }
    }
}

/// Parameters of a one-hidden-layer, one-output network, split.
struct Split<'a> {
    p: usize,
    h: usize,
    w1: &'a [f64],
    b1: &'a [f64],
    w2: &'a [f64],
    b2: f64,
    /// Bypass weights (empty without bypass).
    ws: &'a [f64],
}

impl<'a> Split<'a> {
    fn new(mlp: &'a Mlp) -> Split<'a> {
        let (p, h) = (mlp.sizes[0], mlp.sizes[1]);
        let (w1, rest) = mlp.params.split_at(p * h);
        let (b1, rest) = rest.split_at(h);
        let (w2, rest) = rest.split_at(h);
        Split {
            p,
            h,
            w1,
            b1,
            w2,
            b2: rest[0],
            ws: if mlp.bypass { &rest[1..1 + p] } else { &[] },
        }
    }
}

/// Whether the batched kernels apply to a network (one hidden layer, one output).
pub fn applies(mlp: &Mlp) -> bool {
    mlp.sizes.len() == 3 && mlp.sizes[2] == 1
}

/// Forward pass of the packed batch: every hidden activation into `a` (packed like `xt`).
/// The pre-activations of the whole batch first, then tanh over all of them in one long loop
/// (independent evaluations that the CPU overlaps).
#[inline(always)]
fn hidden(n: &Split, xt: &[f64], a: &mut [f64]) {
    for (xb, ab) in xt
        .chunks_exact(n.p * LANES)
        .zip(a.chunks_exact_mut(n.h * LANES))
    {
        for ((wrow, ao), &bo) in
            n.w1.chunks_exact(n.p)
                .zip(ab.chunks_exact_mut(LANES))
                .zip(n.b1)
        {
            let mut z = [bo; LANES];
            for (&wi, xi) in wrow.iter().zip(xb.chunks_exact(LANES)) {
                for l in 0..LANES {
                    z[l] += wi * xi[l];
                }
            }
            ao.copy_from_slice(&z);
        }
    }
    for v in a.iter_mut() {
        *v = tanh(*v);
    }
}

/// Network outputs of one packed block, from its regressors `xb` and activations `ab`.
#[inline(always)]
fn output_block(n: &Split, xb: &[f64], ab: &[f64]) -> Lanes {
    let mut out = [n.b2; LANES];
    for (&wo, ao) in n.w2.iter().zip(ab.chunks_exact(LANES)) {
        for l in 0..LANES {
            out[l] += wo * ao[l];
        }
    }
    for (&wi, xi) in n.ws.iter().zip(xb.chunks_exact(LANES)) {
        for l in 0..LANES {
            out[l] += wi * xi[l];
        }
    }
    out
}

/// Errors `out - t` of block `c` of a packed batch of `b` samples (the padding lanes beyond
/// the batch set to 0).
#[inline(always)]
fn block_error(n: &Split, xb: &[f64], ab: &[f64], tb: &[f64], c: usize, b: usize) -> Lanes {
    let out = output_block(n, xb, ab);
    let mut e = [0.0; LANES];
    for l in 0..LANES {
        e[l] = out[l] - tb[l];
    }
    let valid = b - c * LANES;
    if valid < LANES {
        e[valid..].fill(0.0);
    }
    e
}

/// Adds `u * v` lane-wise to `acc`.
#[inline(always)]
fn accumulate(acc: &mut Lanes, u: &Lanes, v: &[f64]) {
    for l in 0..LANES {
        acc[l] += u[l] * v[l];
    }
}

/// Gradient of `scale * sum_s 0.5 (out_s - t_s)^2` over the packed batch of `b` samples,
/// written into `grad` (overwritten, layout of [`Mlp::params`]). Block by block: forward,
/// output gradient, then every parameter's lane-wise accumulator; the lanes are summed at the
/// end in a fixed order.
#[inline(always)]
fn gradient(n: &Split, b: usize, scale: f64, grad: &mut [f64], w: &mut BatchWorkspace) {
    let (p, h, bp) = (n.p, n.h, w.bp);
    let np = grad.len();
    let acc = &mut w.acc[..np];
    acc.fill([0.0; LANES]);
    let (aw1, rest) = acc.split_at_mut(p * h);
    let (ab1, rest) = rest.split_at_mut(h);
    let (aw2, rest) = rest.split_at_mut(h);
    let (ab2, aws) = rest.split_at_mut(1);
    let xt = &w.xt[..p * bp];
    let a = &mut w.a[..h * bp];
    hidden(n, xt, a);
    for (c, ((xb, ab), gb)) in xt
        .chunks_exact(p * LANES)
        .zip(a.chunks_exact(h * LANES))
        .zip(w.g[..bp].chunks_exact_mut(LANES))
        .enumerate()
    {
        let mut g = block_error(n, xb, ab, gb, c, b);
        for gl in g.iter_mut() {
            *gl *= scale;
        }
        gb.copy_from_slice(&g);
        for l in 0..LANES {
            ab2[0][l] += g[l];
        }
        for (acc, xi) in aws.iter_mut().zip(xb.chunks_exact(LANES)) {
            accumulate(acc, &g, xi);
        }
        for ((((ao, &wo), accw2), accb1), accw1) in ab
            .chunks_exact(LANES)
            .zip(n.w2)
            .zip(aw2.iter_mut())
            .zip(ab1.iter_mut())
            .zip(aw1.chunks_exact_mut(p))
        {
            accumulate(accw2, &g, ao);
            let mut d = [0.0; LANES];
            for l in 0..LANES {
                d[l] = g[l] * wo * (1.0 - ao[l] * ao[l]);
            }
            for l in 0..LANES {
                accb1[l] += d[l];
            }
            for (acc, xi) in accw1.iter_mut().zip(xb.chunks_exact(LANES)) {
                accumulate(acc, &d, xi);
            }
        }
    }
    for (gi, acc) in grad.iter_mut().zip(w.acc.iter()) {
        *gi = reduce(acc);
    }
}

/// Sum of squared errors of the packed batch of `b` samples.
#[inline(always)]
fn sse(n: &Split, b: usize, w: &mut BatchWorkspace) -> f64 {
    let (p, h, bp) = (n.p, n.h, w.bp);
    let xt = &w.xt[..p * bp];
    let a = &mut w.a[..h * bp];
    hidden(n, xt, a);
    let mut acc = [0.0; LANES];
    for (c, ((xb, ab), tb)) in xt
        .chunks_exact(p * LANES)
        .zip(a.chunks_exact(h * LANES))
        .zip(w.g[..bp].chunks_exact(LANES))
        .enumerate()
    {
        let e = block_error(n, xb, ab, tb, c, b);
        for l in 0..LANES {
            acc[l] += e[l] * e[l];
        }
    }
    reduce(&acc)
}

#[inline(always)]
fn batch_gradient_body(
    mlp: &Mlp,
    x: &[f64],
    t: &[f64],
    rows: &[usize],
    scale: f64,
    grad: &mut [f64],
    w: &mut BatchWorkspace,
) {
    let n = Split::new(mlp);
    w.prepare(n.p, n.h, grad.len(), rows.len());
    w.gather(x, t, n.p, rows.iter().copied());
    gradient(&n, rows.len(), scale, grad, w);
}

#[inline(always)]
fn sse_body(mlp: &Mlp, x: &[f64], t: &[f64], block: usize, w: &mut BatchWorkspace) -> f64 {
    let n = Split::new(mlp);
    let rows = t.len();
    let mut total = 0.0;
    let mut r0 = 0;
    while r0 < rows {
        let b = block.min(rows - r0);
        w.prepare(n.p, n.h, 0, b);
        w.gather(x, t, n.p, r0..r0 + b);
        total += sse(&n, b, w);
        r0 += b;
    }
    total
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn batch_gradient_avx2(
    mlp: &Mlp,
    x: &[f64],
    t: &[f64],
    rows: &[usize],
    scale: f64,
    grad: &mut [f64],
    w: &mut BatchWorkspace,
) {
    batch_gradient_body(mlp, x, t, rows, scale, grad, w)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn sse_avx2(mlp: &Mlp, x: &[f64], t: &[f64], block: usize, w: &mut BatchWorkspace) -> f64 {
    sse_body(mlp, x, t, block, w)
}

/// Whether the AVX2 build of the kernels runs here (same results, only faster).
pub use crate::numeric::simd::uses_avx2;

/// Gradient of `scale * sum 0.5 (out - t)^2` over the rows `rows` of the row-major regressor
/// matrix `x` (targets `t`), written into `grad` (the layout of [`Mlp::params`]). The network
/// must satisfy [`applies`]. With `scale = 2 / rows.len()` this is the gradient of the batch's
/// mean squared error.
pub fn batch_gradient(
    mlp: &Mlp,
    x: &[f64],
    t: &[f64],
    rows: &[usize],
    scale: f64,
    grad: &mut [f64],
    w: &mut BatchWorkspace,
) {
    debug_assert!(applies(mlp));
    #[cfg(target_arch = "x86_64")]
    if uses_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { batch_gradient_avx2(mlp, x, t, rows, scale, grad, w) };
    }
    batch_gradient_body(mlp, x, t, rows, scale, grad, w)
}

/// Sum of squared one-step errors over all rows of `x` (targets `t`), in blocks of `block` rows
/// (the result depends on `block` only through the rounding of the sum). The network must
/// satisfy [`applies`].
pub fn sum_squared_errors(
    mlp: &Mlp,
    x: &[f64],
    t: &[f64],
    block: usize,
    w: &mut BatchWorkspace,
) -> f64 {
    debug_assert!(applies(mlp));
    let block = block.max(1);
    #[cfg(target_arch = "x86_64")]
    if uses_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { sse_avx2(mlp, x, t, block, w) };
    }
    sse_body(mlp, x, t, block, w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::Xoshiro256PlusPlus;
    use rand::SeedableRng;

    fn data(rows: usize, p: usize) -> (Vec<f64>, Vec<f64>) {
        let x = (0..rows * p).map(|k| (0.37 * k as f64).sin()).collect();
        let t = (0..rows).map(|k| (0.11 * k as f64).cos()).collect();
        (x, t)
    }

    /// Per-sample reference: forward and backward of the general network.
    fn reference(mlp: &Mlp, x: &[f64], t: &[f64], rows: &[usize], scale: f64) -> Vec<f64> {
        let p = mlp.n_in();
        let mut grad = vec![0.0; mlp.params.len()];
        let mut acts = vec![0.0; mlp.acts_len()];
        let mut scratch = vec![0.0; 2 * mlp.max_width()];
        for &r in rows {
            let xr = &x[r * p..(r + 1) * p];
            mlp.forward(xr, &mut acts);
            let e = mlp.output(&acts)[0] - t[r];
            mlp.backward(xr, &acts, &[scale * e], &mut grad, None, &mut scratch);
        }
        grad
    }

    #[test]
    fn batch_gradient_equals_per_sample_backward() {
        let (x, t) = data(300, 6);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(4);
        for bypass in [false, true] {
            let mut m = Mlp::glorot(&[6, 7, 1], bypass, 3);
            for p in m.params.iter_mut() {
                *p += 0.2 * (super::super::mlp::uniform01(&mut rng) - 0.5);
            }
            let mut w = BatchWorkspace::new();
            // batch sizes around the lane width, and one with repeated rows
            for rows in [
                vec![5],
                (0..8).collect::<Vec<_>>(),
                (3..40).rev().collect(),
                (0..300).step_by(2).collect(),
                vec![7, 7, 7, 100, 299, 0],
            ] {
                let scale = 2.0 / rows.len() as f64;
                let want = reference(&m, &x, &t, &rows, scale);
                let mut got = vec![f64::NAN; m.params.len()];
                batch_gradient(&m, &x, &t, &rows, scale, &mut got, &mut w);
                for (i, (a, b)) in got.iter().zip(&want).enumerate() {
                    assert!(
                        (a - b).abs() < 1e-13 * (1.0 + b.abs()),
                        "bypass {bypass}, {} rows, param {i}: {a} vs {b}",
                        rows.len()
                    );
                }
            }
        }
    }

    #[test]
    fn batched_errors_equal_per_sample_errors() {
        let (x, t) = data(203, 5);
        let m = Mlp::glorot(&[5, 4, 1], true, 9);
        let mut acts = vec![0.0; m.acts_len()];
        let want: f64 = (0..203)
            .map(|r| {
                m.forward(&x[r * 5..(r + 1) * 5], &mut acts);
                (m.output(&acts)[0] - t[r]).powi(2)
            })
            .sum();
        let mut w = BatchWorkspace::new();
        for block in [1, 8, 64, 1000] {
            let got = sum_squared_errors(&m, &x, &t, block, &mut w);
            assert!(
                (got - want).abs() < 1e-12 * want,
                "block {block}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn simd_and_baseline_builds_agree_bit_for_bit() {
        let (x, t) = data(500, 8);
        let m = Mlp::glorot(&[8, 10, 1], true, 1);
        let rows: Vec<usize> = (0..500).rev().step_by(3).collect();
        let mut w = BatchWorkspace::new();
        let mut a = vec![0.0; m.params.len()];
        let mut b = vec![0.0; m.params.len()];
        batch_gradient(&m, &x, &t, &rows, 0.01, &mut a, &mut w);
        batch_gradient_body(&m, &x, &t, &rows, 0.01, &mut b, &mut w);
        assert_eq!(
            a.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            b.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        let sa = sum_squared_errors(&m, &x, &t, 128, &mut w);
        let sb = sse_body(&m, &x, &t, 128, &mut w);
        assert_eq!(sa.to_bits(), sb.to_bits());
    }
}
