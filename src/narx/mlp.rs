//! # Multilayer perceptron
//!
//! A small fully connected network written by hand for speed at NARX sizes (a few inputs, tens of
//! neurons): tanh hidden layers, a linear output layer and an optional linear bypass from the
//! inputs to the output (y = W_L tanh(...tanh(W_1 x + b_1)...) + b_L + W_s x). All parameters live
//! in one flat vector, so optimisers and model files see a plain `[f64]`. One sample at a time:
//! no allocation in `forward`/`backward`, the caller owns the workspaces.
//!
//! ## References
//! - X. Glorot, Y. Bengio, "Understanding the difficulty of training deep feedforward neural
//!   networks", AISTATS 2010 (uniform initialisation).
//! - S. Chen, S. A. Billings, P. M. Grant, "Non-linear system identification using neural
//!   networks", Int. J. Control 51(6):1191-1214, 1990 (MLP NARX).

use rand::rngs::Xoshiro256PlusPlus;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

/// Network shape and parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Mlp {
    /// Layer widths: inputs, hidden layers..., outputs.
    pub sizes: Vec<usize>,
    /// Linear bypass from the inputs to the outputs.
    pub bypass: bool,
    /// Flat parameters: per layer W (rows = outputs, row-major) then b; then the bypass matrix.
    pub params: Vec<f64>,
    /// Weights held at zero by training (a block-structured network, see [`Mlp::grouped`]);
    /// not stored in model files: the zeros are in `params`.
    #[serde(skip)]
    pub held_zero: Vec<usize>,
}

/// tanh as 1 - 2 / (exp(2x) + 1), with `exp` written out in plain arithmetic (Cody-Waite
/// reduction to |r| <= ln2/2, degree-13 Taylor polynomial, exponent set through the bits), so
/// that it inlines into the batched kernels and vectorises, and gives the same bits on every
/// IEEE-754 machine (no libm). Absolute error below 4e-16; saturates exactly at +-1; NaN stays
/// NaN.
#[inline(always)]
pub fn tanh(x: f64) -> f64 {
    // beyond |x| = 19.1 the result rounds to +-1; the clamp keeps 2^k in range
    let x = x.clamp(-20.0, 20.0);
    1.0 - 2.0 / (exp_reduced(2.0 * x) + 1.0)
}

const LOG2E: f64 = std::f64::consts::LOG2_E;
/// 1.5 * 2^52: adding it rounds to an integer, kept in the low bits of the mantissa
const ROUND: f64 = 6_755_399_441_055_744.0;
/// ln 2 split so that k * LN2_HI is exact (fdlibm)
const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
/// 1/k! for k = 2..=13
const C: [f64; 12] = [
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
    1.0 / 40320.0,
    1.0 / 362880.0,
    1.0 / 3628800.0,
    1.0 / 39916800.0,
    1.0 / 479001600.0,
    1.0 / 6227020800.0,
];

/// exp(y) for |y| <= 40 (see [`tanh`]).
#[inline(always)]
fn exp_reduced(y: f64) -> f64 {
    let t = y * LOG2E + ROUND;
    let k = t - ROUND;
    let r = (y - k * LN2_HI) - k * LN2_LO;
    // exp(r) = 1 + r (1 + r P(r)), P(r) = sum C[j] r^j by Estrin's scheme (short dependency
    // chains; its rounding is damped by r^2 <= 0.12), the last two steps by Horner's
    let r2 = r * r;
    let r4 = r2 * r2;
    let e0 = C[0] + C[1] * r;
    let e1 = C[2] + C[3] * r;
    let e2 = C[4] + C[5] * r;
    let e3 = C[6] + C[7] * r;
    let e4 = C[8] + C[9] * r;
    let e5 = C[10] + C[11] * r;
    let f0 = e0 + e1 * r2;
    let f1 = e2 + e3 * r2;
    let f2 = e4 + e5 * r2;
    let p = f0 + r4 * (f1 + r4 * f2);
    let q = 1.0 + r * (1.0 + r * p);
    // 2^k: the low bits of t hold k (two's complement); add the bias and shift into the exponent
    let scale = f64::from_bits(t.to_bits().wrapping_add(1023) << 52);
    q * scale
}

/// [`tanh`] of four values in the lanes of an AVX2 register: its operations in its order, lane
/// by lane (the same bits).
///
/// # Safety
/// The processor has AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub unsafe fn tanh_4(x: [f64; 4]) -> [f64; 4] {
    use std::arch::x86_64::*;
    let set = _mm256_set1_pd;
    let (add, sub, mul) = (_mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd);
    // SAFETY: four doubles
    let x = unsafe { _mm256_loadu_pd(x.as_ptr()) };
    // f64::clamp: below -20 to -20, then above 20 to 20 (NaN stays NaN)
    let lo = set(-20.0);
    let x = _mm256_blendv_pd(x, lo, _mm256_cmp_pd::<_CMP_LT_OQ>(x, lo));
    let hi = set(20.0);
    let x = _mm256_blendv_pd(x, hi, _mm256_cmp_pd::<_CMP_GT_OQ>(x, hi));
    let y = mul(set(2.0), x);
    // exp_reduced(y)
    let t = add(mul(y, set(LOG2E)), set(ROUND));
    let k = sub(t, set(ROUND));
    let r = sub(sub(y, mul(k, set(LN2_HI))), mul(k, set(LN2_LO)));
    let r2 = mul(r, r);
    let r4 = mul(r2, r2);
    let e = |i: usize| add(set(C[i]), mul(set(C[i + 1]), r));
    let (e0, e1, e2, e3, e4, e5) = (e(0), e(2), e(4), e(6), e(8), e(10));
    let f0 = add(e0, mul(e1, r2));
    let f1 = add(e2, mul(e3, r2));
    let f2 = add(e4, mul(e5, r2));
    let p = add(f0, mul(r4, add(f1, mul(r4, f2))));
    let one = set(1.0);
    let q = add(one, mul(r, add(one, mul(r, p))));
    let bits = _mm256_slli_epi64::<52>(_mm256_add_epi64(
        _mm256_castpd_si256(t),
        _mm256_set1_epi64x(1023),
    ));
    let e = mul(q, _mm256_castsi256_pd(bits));
    let out = sub(one, _mm256_div_pd(set(2.0), add(e, one)));
    let mut o = [0.0; 4];
    // SAFETY: four doubles
    unsafe { _mm256_storeu_pd(o.as_mut_ptr(), out) };
    o
}

/// Number of parameters of a shape.
pub fn parameter_count(sizes: &[usize], bypass: bool) -> usize {
    let layers: usize = sizes.windows(2).map(|w| w[0] * w[1] + w[1]).sum();
    layers
        + if bypass {
            sizes[0] * sizes[sizes.len() - 1]
        } else {
            0
        }
}

/// Uniform in [0, 1) from 53 random bits.
pub(crate) fn uniform01(rng: &mut Xoshiro256PlusPlus) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

impl Mlp {
    /// Glorot-uniform weights, zero biases, zero bypass, from `seed`.
    pub fn glorot(sizes: &[usize], bypass: bool, seed: u64) -> Mlp {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut params = Vec::with_capacity(parameter_count(sizes, bypass));
        for w in sizes.windows(2) {
            let lim = (6.0 / (w[0] + w[1]) as f64).sqrt();
            for _ in 0..w[0] * w[1] {
                params.push(lim * (2.0 * uniform01(&mut rng) - 1.0));
            }
            params.extend(std::iter::repeat_n(0.0, w[1]));
        }
        if bypass {
            params.extend(std::iter::repeat_n(0.0, sizes[0] * sizes[sizes.len() - 1]));
        }
        Mlp {
            sizes: sizes.to_vec(),
            bypass,
            params,
            held_zero: Vec::new(),
        }
    }

    /// Split the hidden neurons into `groups` groups (neuron j in group j mod `groups`) that do
    /// not see each other's inputs: a first-layer neuron sees input column c only if
    /// `column_group[c]` is `None` (shared by all groups) or its own group; a deeper hidden
    /// neuron sees only its own group in the layer before. The output layer and the bypass see
    /// everything, so the network is a sum of one sub-network per group. The cut weights are
    /// set to zero and held there by training ([`Mlp::hold`]). One group leaves the network as
    /// it is.
    pub fn grouped(mut self, column_group: &[Option<usize>], groups: usize) -> Mlp {
        self.held_zero.clear();
        if groups < 2 {
            return self;
        }
        let mut off = 0;
        for l in 0..self.sizes.len() - 2 {
            let (ni, no) = (self.sizes[l], self.sizes[l + 1]);
            // the group of each column of this layer's input (None: every group's)
            let group: Vec<Option<usize>> = if l == 0 {
                column_group.to_vec()
            } else {
                (0..ni).map(|c| Some(c % groups)).collect()
            };
            for j in 0..no {
                for (c, g) in group.iter().enumerate() {
                    if g.is_some_and(|g| g != j % groups) {
                        self.params[off + j * ni + c] = 0.0;
                        self.held_zero.push(off + j * ni + c);
                    }
                }
            }
            off += ni * no + no;
        }
        self
    }

    /// Zero the gradient of the weights held at zero (before an optimiser step).
    #[inline]
    pub fn hold(&self, g: &mut [f64]) {
        for &i in &self.held_zero {
            g[i] = 0.0;
        }
    }

    /// Number of inputs.
    pub fn n_in(&self) -> usize {
        self.sizes[0]
    }

    /// Number of outputs.
    pub fn n_out(&self) -> usize {
        self.sizes[self.sizes.len() - 1]
    }

    /// Length of the activation workspace (every layer's outputs, last = network output).
    pub fn acts_len(&self) -> usize {
        self.sizes[1..].iter().sum()
    }

    /// Widest layer (for the backward scratch).
    pub fn max_width(&self) -> usize {
        *self.sizes.iter().max().unwrap_or(&1)
    }

    /// Offset of the bypass matrix in `params`.
    pub fn bypass_offset(&self) -> usize {
        self.sizes.windows(2).map(|w| w[0] * w[1] + w[1]).sum()
    }

    /// Offset of the weights and of the biases of layer `l`.
    fn layer_offset(&self, l: usize) -> usize {
        self.sizes[..l + 1]
            .windows(2)
            .map(|w| w[0] * w[1] + w[1])
            .sum()
    }

    /// Forward pass of one sample; `acts` receives every layer's outputs, the network output last.
    #[inline]
    pub fn forward(&self, x: &[f64], acts: &mut [f64]) {
        let nl = self.sizes.len() - 1;
        let mut p = 0;
        let mut a_off = 0;
        for l in 0..nl {
            let (ni, no) = (self.sizes[l], self.sizes[l + 1]);
            let w = &self.params[p..p + ni * no];
            let b = &self.params[p + ni * no..p + ni * no + no];
            let (prev, cur) = acts.split_at_mut(a_off);
            let input: &[f64] = if l == 0 { x } else { &prev[a_off - ni..] };
            let out = &mut cur[..no];
            let hidden = l + 1 < nl;
            for ((o, row), &bo) in out.iter_mut().zip(w.chunks_exact(ni)).zip(b) {
                let mut s = bo;
                for (wi, xi) in row.iter().zip(input) {
                    s += wi * xi;
                }
                *o = if hidden { tanh(s) } else { s };
            }
            p += ni * no + no;
            a_off += no;
        }
        if self.bypass {
            let ni = self.sizes[0];
            let out = &mut acts[a_off - self.n_out()..a_off];
            for (o, row) in out.iter_mut().zip(self.params[p..].chunks_exact(ni)) {
                let mut s = 0.0;
                for (wi, xi) in row.iter().zip(x) {
                    s += wi * xi;
                }
                *o += s;
            }
        }
    }

    /// Output of the forward pass stored in `acts`.
    #[inline]
    pub fn output<'a>(&self, acts: &'a [f64]) -> &'a [f64] {
        &acts[acts.len() - self.n_out()..]
    }

    /// Backward pass of one sample after `forward(x, acts)`: adds d(loss)/d(params) to `grad`
    /// for the output gradient `gout`, and, when `gx` is given, writes d(loss)/dx into it.
    /// `scratch` needs `2 * max_width()` values.
    #[inline]
    pub fn backward(
        &self,
        x: &[f64],
        acts: &[f64],
        gout: &[f64],
        grad: &mut [f64],
        mut gx: Option<&mut [f64]>,
        scratch: &mut [f64],
    ) {
        let nl = self.sizes.len() - 1;
        let mw = self.max_width();
        let (delta, dprev) = scratch.split_at_mut(mw);
        let n_out = self.n_out();
        delta[..n_out].copy_from_slice(gout);
        let mut a_end = acts.len();
        for l in (0..nl).rev() {
            let (ni, no) = (self.sizes[l], self.sizes[l + 1]);
            let p = self.layer_offset(l);
            let a_start = a_end - no;
            let input: &[f64] = if l == 0 {
                x
            } else {
                &acts[a_start - ni..a_start]
            };
            {
                let (gw, gb) = grad[p..p + ni * no + no].split_at_mut(ni * no);
                for ((grow, gbo), &d) in
                    gw.chunks_exact_mut(ni).zip(gb.iter_mut()).zip(&delta[..no])
                {
                    *gbo += d;
                    for (g, xi) in grow.iter_mut().zip(input) {
                        *g += d * xi;
                    }
                }
            }
            let need_input_grad = l > 0 || gx.is_some();
            if need_input_grad {
                let w = &self.params[p..p + ni * no];
                let di = &mut dprev[..ni];
                di.iter_mut().for_each(|v| *v = 0.0);
                for (row, &d) in w.chunks_exact(ni).zip(&delta[..no]) {
                    for (v, wi) in di.iter_mut().zip(row) {
                        *v += d * wi;
                    }
                }
                if l > 0 {
                    for (i, v) in di.iter().enumerate() {
                        let a = input[i];
                        delta[i] = v * (1.0 - a * a);
                    }
                } else if let Some(g) = gx.as_deref_mut() {
                    g[..ni].copy_from_slice(di);
                }
            }
            a_end = a_start;
        }
        if self.bypass {
            let ni = self.sizes[0];
            let p = self.bypass_offset();
            for (o, &go) in gout.iter().enumerate() {
                let row = p + o * ni;
                for (g, xi) in grad[row..row + ni].iter_mut().zip(x) {
                    *g += go * xi;
                }
                if let Some(g) = gx.as_deref_mut() {
                    for (gi, wi) in g.iter_mut().zip(&self.params[row..row + ni]) {
                        *gi += go * wi;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    /// tanh four at a time in AVX2 lanes gives tanh's bits, through the clamp, at 0, at the
    /// infinities and for NaN.
    #[test]
    fn tanh_in_lanes_equals_tanh() {
        if !crate::numeric::simd::uses_avx2() {
            return;
        }
        let mut xs: Vec<f64> = (-4000..4000).map(|k| k as f64 * 0.00617).collect();
        xs.extend([0.0, -0.0, 19.1, 20.0, 20.5, -20.5, 1e300, -1e300]);
        xs.extend([f64::INFINITY, f64::NEG_INFINITY, f64::NAN, 1e-310]);
        for c in xs.chunks(4) {
            let x: [f64; 4] = std::array::from_fn(|l| c.get(l).copied().unwrap_or(0.3));
            // SAFETY: the processor has AVX2 (checked above)
            let lanes = unsafe { tanh_4(x) };
            for l in 0..4 {
                let one = tanh(x[l]);
                assert!(
                    lanes[l].to_bits() == one.to_bits() || (lanes[l].is_nan() && one.is_nan()),
                    "tanh({}) = {} in lanes, {} alone",
                    x[l],
                    lanes[l],
                    one
                );
            }
        }
    }

    fn loss(m: &Mlp, x: &[f64], t: &[f64]) -> f64 {
        let mut acts = vec![0.0; m.acts_len()];
        m.forward(x, &mut acts);
        m.output(&acts)
            .iter()
            .zip(t)
            .map(|(o, t)| 0.5 * (o - t) * (o - t))
            .sum()
    }

    #[test]
    fn gradient_matches_finite_differences() {
        for (sizes, bypass) in [
            (vec![5, 7, 1], true),
            (vec![4, 6, 5, 2], false),
            (vec![3, 4, 4, 4, 1], true),
        ] {
            let mut m = Mlp::glorot(&sizes, bypass, 7);
            // non-trivial biases and bypass
            let mut r = Xoshiro256PlusPlus::seed_from_u64(3);
            for p in m.params.iter_mut() {
                *p += 0.3 * (uniform01(&mut r) - 0.5);
            }
            let x: Vec<f64> = (0..sizes[0])
                .map(|i| 0.7 * (i as f64 + 1.0).sin())
                .collect();
            let t: Vec<f64> = (0..m.n_out()).map(|i| 0.2 * i as f64 - 0.1).collect();
            let mut acts = vec![0.0; m.acts_len()];
            m.forward(&x, &mut acts);
            let gout: Vec<f64> = m.output(&acts).iter().zip(&t).map(|(o, t)| o - t).collect();
            let mut grad = vec![0.0; m.params.len()];
            let mut gx = vec![0.0; sizes[0]];
            let mut scratch = vec![0.0; 2 * m.max_width()];
            m.backward(&x, &acts, &gout, &mut grad, Some(&mut gx), &mut scratch);
            let h = 1e-6;
            for i in 0..m.params.len() {
                let mut mp = m.clone();
                mp.params[i] += h;
                let mut mm = m.clone();
                mm.params[i] -= h;
                let fd = (loss(&mp, &x, &t) - loss(&mm, &x, &t)) / (2.0 * h);
                assert!(
                    (fd - grad[i]).abs() < 1e-7 * (1.0 + fd.abs()),
                    "param {i}: fd {fd} vs {}",
                    grad[i]
                );
            }
            for i in 0..x.len() {
                let mut xp = x.clone();
                xp[i] += h;
                let mut xm = x.clone();
                xm[i] -= h;
                let fd = (loss(&m, &xp, &t) - loss(&m, &xm, &t)) / (2.0 * h);
                assert!(
                    (fd - gx[i]).abs() < 1e-7 * (1.0 + fd.abs()),
                    "input {i}: fd {fd} vs {}",
                    gx[i]
                );
            }
        }
    }

    #[test]
    fn fast_tanh_is_accurate() {
        for i in -4000..=4000 {
            let x = i as f64 * 0.01;
            assert!((tanh(x) - x.tanh()).abs() < 4e-16, "{x}");
        }
        // random points, dense near 0 where 1 - 2/(e+1) cancels, and across the reduction's
        // interval boundaries
        let mut r = Xoshiro256PlusPlus::seed_from_u64(11);
        let mut worst: f64 = 0.0;
        for k in 0..200_000 {
            let x = (2.0 * uniform01(&mut r) - 1.0) * if k % 2 == 0 { 25.0 } else { 0.5 };
            worst = worst.max((tanh(x) - x.tanh()).abs());
        }
        assert!(worst < 4e-16, "worst {worst:e}");
        assert_eq!(tanh(1e3), 1.0);
        assert_eq!(tanh(-1e3), -1.0);
        assert_eq!(tanh(f64::INFINITY), 1.0);
        assert_eq!(tanh(0.0), 0.0);
        assert!(tanh(f64::NAN).is_nan());
    }

    #[test]
    fn parameter_count_matches_layout() {
        let m = Mlp::glorot(&[8, 10, 1], true, 1);
        assert_eq!(m.params.len(), 8 * 10 + 10 + 10 + 1 + 8);
        assert_eq!(parameter_count(&[8, 10, 1], false), 101);
    }
}
