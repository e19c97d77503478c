//! Ridge least squares on a few standardised regressors (the diagnosis's regressions, the
//! creep drift's slope).

use super::lstsq::{solve_ridge, NormalEquations};

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
    let mut ne = NormalEquations::new(p);
    let mut row = vec![0.0; p];
    for &k in rows {
        for (j, c) in cols.iter().enumerate() {
            row[j] = c[k] / scale[j];
        }
        if intercept {
            row[p - 1] = 1.0;
        }
        ne.add_row(&row, y[k]);
    }
    let (g, b) = ne.into_parts();
    let ridge = 1e-8 * (0..p).map(|i| g[(i, i)]).sum::<f64>() / p as f64;
    let sol = solve_ridge(g, &b, ridge)?;
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
