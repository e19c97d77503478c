//! Ridge least squares on a few standardised regressors (the diagnosis's regressions, the
//! creep drift's slope).

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
