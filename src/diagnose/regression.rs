//! Least squares on a few regressors, and the out-of-sample share of a residual that a bank
//! explains.

pub use crate::numeric::ridge::{fit, fit_rows, predict_at};

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

/// Two-fold blocked cross-validation: the record is cut in [`BLOCKS`] contiguous blocks, the
/// even ones fit and the odd ones score, then the reverse; sums of squares are pooled. Blocks
/// keep the time structure while both folds see the whole experiment (a record that starts with
/// a rest and ends with motion is fitted on both).
///
/// Each baseline (e.g. the prediction alone, or the prediction and the banks of the effects a
/// model has; a constant is always in) is a regression of the residual; the reference is the
/// best of them on held-out rows, or the residual itself when every baseline regression does
/// worse out of sample than no correction (it extrapolates badly, e.g. from a rest to motion).
/// The bank is added to each baseline and the best held-out result is compared with the
/// reference: a bank is credited only with what it explains beyond everything already there.
pub fn explained_out_of_sample(
    residual: &[f64],
    baselines: &[&[&[f64]]],
    bank: &[&[f64]],
) -> Option<Explained> {
    let n = residual.len();
    let block = |k: usize| (k * BLOCKS / n.max(1)) % 2;
    let even: Vec<usize> = (0..n).filter(|&k| block(k) == 0).collect();
    let odd: Vec<usize> = (0..n).filter(|&k| block(k) == 1).collect();
    // held-out sum of squares of a regression of the residual on `cols`
    let held_out_sse = |cols: &[&[f64]]| -> Option<f64> {
        let mut sse = 0.0;
        for (train, test) in [(&even, &odd), (&odd, &even)] {
            let c = fit_rows(cols, residual, train, true)?;
            for &k in test.iter() {
                let r = residual[k] - predict_at(cols, &c, k);
                sse += r * r;
            }
        }
        Some(sse)
    };
    let count = even.len() + odd.len();
    let mut reference: f64 = residual.iter().map(|r| r * r).sum();
    let mut with_bank = f64::INFINITY;
    for base in baselines {
        reference = reference.min(held_out_sse(base)?);
        let full: Vec<&[f64]> = base.iter().chain(bank).copied().collect();
        with_bank = with_bank.min(held_out_sse(&full)?);
    }
    if count == 0 || reference <= 0.0 || !with_bank.is_finite() {
        return None;
    }
    Some(Explained {
        fraction: 1.0 - with_bank / reference,
        rms_baseline: (reference / count as f64).sqrt(),
        rms_with_bank: (with_bank / count as f64).sqrt(),
    })
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
