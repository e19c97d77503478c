//! Least squares on a few regressors, and the out-of-sample share of a residual that a bank
//! explains.

use nalgebra::{DMatrix, DVector};

/// Ridge least squares on standardised columns: coefficients for `cols` (plus an intercept
/// when `intercept`), fitted on rows `fit`.
pub fn fit(
    cols: &[&[f64]],
    y: &[f64],
    fit: std::ops::Range<usize>,
    intercept: bool,
) -> Option<Vec<f64>> {
    let rows: Vec<usize> = fit.collect();
    fit_rows(cols, y, &rows, intercept)
}

/// [`fit`] on an arbitrary set of rows.
pub fn fit_rows(cols: &[&[f64]], y: &[f64], rows: &[usize], intercept: bool) -> Option<Vec<f64>> {
    let p = cols.len() + intercept as usize;
    let n = rows.len();
    if n <= p || p == 0 {
        return None;
    }
    // column scales for conditioning
    let scale: Vec<f64> = cols
        .iter()
        .map(|c| {
            let v: Vec<f64> = rows.iter().map(|&k| c[k]).collect();
            let s = crate::metrics::std_dev(&v);
            if s > 0.0 {
                s
            } else {
                1.0
            }
        })
        .collect();
    let mut g = DMatrix::<f64>::zeros(p, p);
    let mut b = DVector::<f64>::zeros(p);
    let mut row = vec![0.0; p];
    for &k in rows {
        for (j, c) in cols.iter().enumerate() {
            row[j] = c[k] / scale[j];
        }
        if intercept {
            row[p - 1] = 1.0;
        }
        for i in 0..p {
            b[i] += row[i] * y[k];
            for j in 0..=i {
                g[(i, j)] += row[i] * row[j];
            }
        }
    }
    for i in 0..p {
        for j in 0..i {
            g[(j, i)] = g[(i, j)];
        }
    }
    let ridge = 1e-8 * (0..p).map(|i| g[(i, i)]).sum::<f64>() / p as f64;
    for i in 0..p {
        g[(i, i)] += ridge;
    }
    let sol = g.cholesky()?.solve(&b);
    let mut coef: Vec<f64> = (0..cols.len()).map(|j| sol[j] / scale[j]).collect();
    if intercept {
        coef.push(sol[p - 1]);
    }
    coef.iter().all(|c| c.is_finite()).then_some(coef)
}

/// Prediction of a fitted regression at row k.
pub fn predict_at(cols: &[&[f64]], coef: &[f64], k: usize) -> f64 {
    let mut v: f64 = cols.iter().zip(coef).map(|(c, b)| c[k] * b).sum();
    if coef.len() > cols.len() {
        v += coef[cols.len()];
    }
    v
}

/// Out-of-sample result of explaining a residual with a bank on top of a baseline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Explained {
    /// 1 - SSE(baseline + bank) / SSE(baseline), both on held-out rows.
    pub fraction: f64,
    /// Held-out RMS after the baseline alone.
    pub rms_baseline: f64,
    /// Held-out RMS after baseline + bank.
    pub rms_with_bank: f64,
}

/// Number of contiguous blocks of the two-fold cross-validation.
pub const BLOCKS: usize = 8;

/// Two-fold blocked cross-validation: the record is cut in [`BLOCKS`] contiguous blocks, the
/// even ones fit and the odd ones score, then the reverse; sums of squares are pooled. Blocks
/// keep the time structure while both folds see the whole experiment (a record that starts with
/// a rest and ends with motion is fitted on both). The baseline (e.g. the prediction and a
/// constant) is always in.
pub fn explained_out_of_sample(
    residual: &[f64],
    baseline: &[&[f64]],
    bank: &[&[f64]],
) -> Option<Explained> {
    let n = residual.len();
    let block = |k: usize| (k * BLOCKS / n.max(1)) % 2;
    let even: Vec<usize> = (0..n).filter(|&k| block(k) == 0).collect();
    let odd: Vec<usize> = (0..n).filter(|&k| block(k) == 1).collect();
    let full: Vec<&[f64]> = baseline.iter().chain(bank).copied().collect();
    let (mut sse_base, mut sse_full, mut count) = (0.0, 0.0, 0usize);
    for (train, test) in [(&even, &odd), (&odd, &even)] {
        let cb = fit_rows(baseline, residual, train, true)?;
        let cf = fit_rows(&full, residual, train, true)?;
        for &k in test {
            let eb = residual[k] - predict_at(baseline, &cb, k);
            let ef = residual[k] - predict_at(&full, &cf, k);
            sse_base += eb * eb;
            sse_full += ef * ef;
            count += 1;
        }
    }
    if count == 0 || sse_base <= 0.0 {
        return None;
    }
    Some(Explained {
        fraction: 1.0 - sse_full / sse_base,
        rms_baseline: (sse_base / count as f64).sqrt(),
        rms_with_bank: (sse_full / count as f64).sqrt(),
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
        let good = explained_out_of_sample(&e, &[&base], &[&x]).unwrap();
        assert!(good.fraction > 0.95, "{good:?}");
        let junk: Vec<f64> = (0..2000).map(|_| g.standard_normal()).collect();
        let bad = explained_out_of_sample(&noise, &[&base], &[&junk]).unwrap();
        assert!(bad.fraction < 0.01, "{bad:?}");
    }
}
