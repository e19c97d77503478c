//! Least squares on a few regressors, and the out-of-sample share of a residual that a bank
//! explains.

pub use crate::numeric::ridge::{fit, fit_rows, predict_at};

use crate::effect::basis::Signal;
use crate::numeric::gram::{self, BLOCK_ROWS};
use crate::numeric::lstsq::solve_ridge;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Out-of-sample result of explaining a residual with a bank on top of a baseline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Explained {
    /// 1 - SSE(baseline + bank) / SSE(reference), both on held-out rows; the reference is the
    /// better of the baseline regression and the residual itself (negative: the bank makes the
    /// held-out error worse than leaving the model alone).
    pub fraction: f64,
    /// Held-out RMS of the reference: the baseline regression, or the residual itself when the
    /// baseline regression does worse out of sample than no correction at all.
    pub rms_baseline: f64,
    /// Held-out RMS after baseline + bank.
    pub rms_with_bank: f64,
}

/// Number of contiguous blocks of the two-fold cross-validation. Many short blocks let each
/// fold see every level of a staircase and every phase of a slow sine (with 8 blocks a record of
/// four 5 s holds put the high levels in one fold and the low ones in the other, and every
/// regression extrapolated); the blocks stay long against the sampling period (a 40,000-sample
/// record gives blocks of 1,250 samples).
pub const BLOCKS: usize = 32;

/// The normal equations of the two folds of the blocked cross-validation
/// ([`FoldGrams::explained`]) for a set of signals and a residual: the cross products of `[signals, residual, 1]` over each fold's rows,
/// accumulated a block of rows at a time, so that no signal is held whole. Every regression on
/// a subset of the signals (plus a constant) and its held-out sum of squares then come from
/// these two small matrices: one pass over the record serves every bank and baseline.
///
/// Each signal and the residual are shifted by their mean over the first block of rows before
/// the products (a regression with a constant is the same on shifted columns; the products of
/// centred columns keep their precision when a column's mean is large against its spread).
#[derive(Debug, Clone)]
pub struct FoldGrams {
    /// Per fold, the cross products of the shifted `[signals, residual, 1]`.
    grams: [DMatrix<f64>; 2],
    /// Number of signals.
    signals: usize,
    /// Sum of squares of the residual over the record (not shifted).
    raw_sse: f64,
    /// Rows.
    count: usize,
}

impl FoldGrams {
    /// The folds' cross products of `signals` (each computed from row 0 to the residual's
    /// length) and `residual`.
    pub fn new(residual: &[f64], signals: &mut [Signal]) -> FoldGrams {
        let n = residual.len();
        let m = signals.len();
        let fold = |k: usize| (k * BLOCKS / n.max(1)) % 2;
        let mut grams = [DMatrix::zeros(m + 2, m + 2), DMatrix::zeros(m + 2, m + 2)];
        let mut buffers = vec![vec![0.0; BLOCK_ROWS.min(n)]; m + 2];
        let mut shift = vec![0.0; m + 1];
        let mut start = 0;
        while start < n {
            let rows = start..(start + BLOCK_ROWS).min(n);
            let len = rows.len();
            signals
                .par_iter_mut()
                .zip(buffers[..m].par_iter_mut())
                .for_each(|(s, b)| s.fill(rows.clone(), &mut b[..len]));
            buffers[m][..len].copy_from_slice(&residual[rows.clone()]);
            buffers[m + 1][..len].fill(1.0);
            if start == 0 {
                for (s, b) in shift.iter_mut().zip(&buffers) {
                    *s = b[..len].iter().sum::<f64>() / len as f64;
                }
            }
            for (s, b) in shift.iter().zip(buffers.iter_mut()) {
                b[..len].iter_mut().for_each(|v| *v -= s);
            }
            // the block's rows, cut where the fold changes
            let mut a = 0;
            while a < len {
                let f = fold(start + a);
                let mut b = a + 1;
                while b < len && fold(start + b) == f {
                    b += 1;
                }
                let cols: Vec<&[f64]> = buffers.iter().map(|c| &c[a..b]).collect();
                grams[f] += gram::tr_mul_slices(&cols, &cols, true);
                a = b;
            }
            start = rows.end;
        }
        for g in &mut grams {
            gram::mirror_upper(g);
        }
        FoldGrams {
            grams,
            signals: m,
            raw_sse: residual.iter().map(|r| r * r).sum(),
            count: n,
        }
    }

    /// The held-out sum of squares, pooled over both folds, of the regression of the residual
    /// on the signals `cols` (indices) and a constant, fitted on the other fold (ridge least
    /// squares on standardised columns, [`crate::numeric::ridge`]'s ridge); `None` when a fold
    /// has no more rows than coefficients or a system is singular.
    pub fn held_out_sse(&self, cols: &[usize]) -> Option<f64> {
        let (iy, ione) = (self.signals, self.signals + 1);
        let q = cols.len();
        let mut sse = 0.0;
        for (train, test) in [(0, 1), (1, 0)] {
            let g = &self.grams[train];
            let n = g[(ione, ione)];
            if n <= (q + 1) as f64 {
                return None;
            }
            // cross products of the columns centred on the training fold
            let centred = |i: usize, j: usize| g[(i, j)] - g[(i, ione)] * g[(j, ione)] / n;
            let scale: Vec<f64> = cols
                .iter()
                .map(|&i| {
                    let v = centred(i, i) / n;
                    if v > 0.0 {
                        v.sqrt()
                    } else {
                        1.0
                    }
                })
                .collect();
            let a = DMatrix::from_fn(q, q, |r, c| {
                centred(cols[r], cols[c]) / (scale[r] * scale[c])
            });
            let b = DVector::from_fn(q, |r, _| centred(cols[r], iy) / scale[r]);
            let ridge = 1e-8 * a.trace().max(n) / q.max(1) as f64;
            let sol = solve_ridge(a, &b, ridge)?;
            // the residual minus the regression, as weights on the test fold's columns
            let mut w = DVector::zeros(self.signals + 2);
            let mut intercept = g[(iy, ione)] / n;
            for (r, &i) in cols.iter().enumerate() {
                let c = sol[r] / scale[r];
                w[i] = -c;
                intercept -= c * g[(i, ione)] / n;
            }
            w[iy] = 1.0;
            w[ione] = -intercept;
            let fold_sse = (&self.grams[test] * &w).dot(&w);
            if !fold_sse.is_finite() {
                return None;
            }
            sse += fold_sse.max(0.0);
        }
        Some(sse)
    }

    /// Two-fold blocked cross-validation of the bank `bank` on top of the baselines `baselines`
    /// (each a set of signal indices): the record is cut in [`BLOCKS`] contiguous blocks, the
    /// even ones fit and the odd ones score, then the reverse; sums of squares are pooled.
    /// Blocks keep the time structure while both folds see the whole experiment (a record that
    /// starts with a rest and ends with motion is fitted on both).
    ///
    /// Each baseline (e.g. the prediction alone, or the prediction and the banks of the effects
    /// a model has; a constant is always in) is a regression of the residual; the reference is
    /// the best of them on held-out rows, or the residual itself when every baseline regression
    /// does worse out of sample than no correction (it extrapolates badly, e.g. from a rest to
    /// motion). The bank is added to each baseline and the best held-out result is compared
    /// with the reference: a bank is credited only with what it explains beyond everything
    /// already there.
    pub fn explained(&self, baselines: &[&[usize]], bank: &[usize]) -> Option<Explained> {
        let mut reference = self.raw_sse;
        let mut with_bank = f64::INFINITY;
        for base in baselines {
            reference = reference.min(self.held_out_sse(base)?);
            let full: Vec<usize> = base.iter().chain(bank).copied().collect();
            with_bank = with_bank.min(self.held_out_sse(&full)?);
        }
        if self.count == 0 || reference <= 0.0 || !with_bank.is_finite() {
            return None;
        }
        Some(Explained {
            fraction: 1.0 - with_bank / reference,
            rms_baseline: (reference / self.count as f64).sqrt(),
            rms_with_bank: (with_bank / self.count as f64).sqrt(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_coefficients() {
        let x1: Vec<f64> = (0..500).map(|k| (k as f64 * 0.1).sin()).collect();
        let x2: Vec<f64> = (0..500).map(|k| (k as f64 * 0.037).cos()).collect();
        let y: Vec<f64> = (0..500).map(|k| 2.0 * x1[k] - 0.5 * x2[k] + 3.0).collect();
        let c = fit(&[&x1, &x2], &y, 0..500, true).unwrap();
        assert!(
            (c[0] - 2.0).abs() < 1e-6 && (c[1] + 0.5).abs() < 1e-6 && (c[2] - 3.0).abs() < 1e-6
        );
    }

    /// The held-out sum of squares computed on the rows: each fold's regression fitted on its
    /// rows ([`fit_rows`]) and its error summed over the other fold's.
    fn held_out_sse_on_rows(residual: &[f64], cols: &[&[f64]]) -> Option<f64> {
        let n = residual.len();
        let fold = |k: usize| (k * BLOCKS / n) % 2;
        let mut sse = 0.0;
        for f in 0..2 {
            let train: Vec<usize> = (0..n).filter(|&k| fold(k) == f).collect();
            let c = fit_rows(cols, residual, &train, true)?;
            for k in (0..n).filter(|&k| fold(k) != f) {
                sse += (residual[k] - predict_at(cols, &c, k)).powi(2);
            }
        }
        Some(sse)
    }

    /// Six columns offset by `offset` times their index, and a residual partly in their span
    /// (noise 0.05) on a record longer than a block of rows.
    fn offset_columns(offset: f64) -> (Vec<Vec<f64>>, Vec<f64>) {
        let mut g = crate::effect::noise::Gaussian::new(3, 0);
        let n = 10_007;
        let cols: Vec<Vec<f64>> = (0..6)
            .map(|j| {
                (0..n)
                    .map(|k| offset * j as f64 + (k as f64 * 0.002 * (j + 1) as f64).sin())
                    .collect()
            })
            .collect();
        let e = (0..n)
            .map(|k| 0.3 * cols[1][k] - 0.7 * cols[4][k] + 0.05 * g.standard_normal() + 4.0)
            .collect();
        (cols, e)
    }

    #[test]
    fn the_folds_cross_products_give_the_held_out_error_on_the_rows() {
        // columns about zero, so that the ridge (on uncentred columns on the rows, centred
        // here) weighs alike
        let (cols, e) = offset_columns(0.0);
        let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
        let mut signals: Vec<Signal> = refs.iter().map(|c| Signal::samples(c)).collect();
        let grams = FoldGrams::new(&e, &mut signals);
        for subset in [vec![0], vec![1, 4], vec![0, 2, 3], (0..6).collect()] {
            let on_rows: Vec<&[f64]> = subset.iter().map(|&j| refs[j]).collect();
            let want = held_out_sse_on_rows(&e, &on_rows).unwrap();
            let got = grams.held_out_sse(&subset).unwrap();
            assert!(
                (got - want).abs() <= 1e-7 * want,
                "{subset:?}: {got} against {want} on the rows"
            );
        }
    }

    #[test]
    fn columns_far_from_zero_keep_their_precision() {
        // offsets of 100 to 500 against a spread of 1: the held-out error is the noise's
        // (the ridge on uncentred columns, on the rows, biased it: 9 % above the noise's)
        let (cols, e) = offset_columns(100.0);
        let mut signals: Vec<Signal> = cols.iter().map(|c| Signal::samples(c)).collect();
        let grams = FoldGrams::new(&e, &mut signals);
        let noise = e.len() as f64 * 0.05f64.powi(2);
        let got = grams.held_out_sse(&[1, 4]).unwrap();
        assert!((got / noise - 1.0).abs() < 0.05, "{got} against {noise}");
    }

    /// [`FoldGrams::explained`] of whole columns.
    fn explained_out_of_sample(
        residual: &[f64],
        baselines: &[&[&[f64]]],
        bank: &[&[f64]],
    ) -> Option<Explained> {
        // the bank's columns, then each baseline's
        let mut cols: Vec<&[f64]> = bank.to_vec();
        let mut sets = Vec::new();
        for base in baselines {
            sets.push((cols.len()..cols.len() + base.len()).collect::<Vec<usize>>());
            cols.extend_from_slice(base);
        }
        let mut signals: Vec<Signal> = cols.iter().map(|c| Signal::samples(c)).collect();
        let grams = FoldGrams::new(residual, &mut signals);
        let sets: Vec<&[usize]> = sets.iter().map(Vec::as_slice).collect();
        let bank: Vec<usize> = (0..bank.len()).collect();
        grams.explained(&sets, &bank)
    }

    #[test]
    fn a_bank_that_holds_the_signal_explains_it_and_noise_does_not() {
        let mut g = crate::effect::noise::Gaussian::new(1, 0);
        let x: Vec<f64> = (0..2000).map(|k| (k as f64 * 0.01).sin()).collect();
        let base: Vec<f64> = (0..2000).map(|k| (k as f64 * 0.003).cos()).collect();
        let noise: Vec<f64> = (0..2000).map(|_| 0.1 * g.standard_normal()).collect();
        let e: Vec<f64> = x.iter().zip(&noise).map(|(a, b)| a + b).collect();
        let good = explained_out_of_sample(&e, &[&[&base]], &[&x]).unwrap();
        assert!(good.fraction > 0.95, "{good:?}");
        let junk: Vec<f64> = (0..2000).map(|_| g.standard_normal()).collect();
        let bad = explained_out_of_sample(&noise, &[&[&base]], &[&junk]).unwrap();
        assert!(bad.fraction < 0.01, "{bad:?}");
    }

    #[test]
    fn an_overfitting_baseline_is_not_the_reference() {
        // random-walk columns extrapolate badly from one set of blocks to the other: the
        // baseline regression is worse than no correction, and a bank of more random walks
        // must not be credited with "explaining" the gap
        let mut g = crate::effect::noise::Gaussian::new(7, 0);
        let n = 600;
        let walk = |g: &mut crate::effect::noise::Gaussian| {
            let mut s = 0.0;
            (0..n)
                .map(|_| {
                    s += g.standard_normal();
                    s
                })
                .collect::<Vec<f64>>()
        };
        let base: Vec<Vec<f64>> = (0..40).map(|_| walk(&mut g)).collect();
        let bank: Vec<Vec<f64>> = (0..20).map(|_| walk(&mut g)).collect();
        let e: Vec<f64> = (0..n).map(|_| 0.1 * g.standard_normal()).collect();
        let b: Vec<&[f64]> = base.iter().map(Vec::as_slice).collect();
        let k: Vec<&[f64]> = bank.iter().map(Vec::as_slice).collect();
        let x = explained_out_of_sample(&e, &[&b], &k).unwrap();
        let raw = crate::metrics::rms(&e);
        // the reference is the raw residual: the baseline regression does worse out of sample
        assert!(
            (x.rms_baseline - raw).abs() < 1e-12 * (1.0 + raw),
            "{x:?} raw {raw}"
        );
        assert!(x.fraction < 0.05, "{x:?}");
    }
}
