//! # Non-negative least squares on the normal equations
//!
//! min ||y - Psi c||^2 subject to c_i >= 0 for the constrained columns (the others are free), by
//! the active-set method of Lawson and Hanson, written on the Gram matrix G = Psi^T Psi and
//! b = Psi^T y. Columns are scaled to unit norm first; a tiny ridge keeps the Cholesky factor
//! of nearly collinear play-operator columns well defined.
//!
//! ## References
//! - C. L. Lawson, R. J. Hanson, *Solving Least Squares Problems*, Prentice-Hall, 1974, ch. 23.

use nalgebra::{DMatrix, DVector};

/// The solution of one (partly) non-negative least-squares problem.
#[derive(Debug, Clone)]
pub struct NnlsSolution {
    /// Coefficients in the original column scale.
    pub coef: Vec<f64>,
    /// Indices of the columns not held at zero (the passive set), ascending.
    pub passive: Vec<usize>,
    /// Cholesky factor L of the scaled Gram matrix restricted to `passive`.
    pub chol_l: DMatrix<f64>,
    /// Column scale factors: scaled column = column * scale.
    pub scale: Vec<f64>,
}

fn cholesky(a: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    let mut ridge = 1e-13;
    loop {
        let mut m = a.clone();
        for i in 0..n {
            m[(i, i)] += ridge;
        }
        if let Some(c) = m.cholesky() {
            return c.l();
        }
        ridge *= 100.0;
        if ridge > 1.0 {
            // cannot happen for a Gram matrix with unit diagonal; keep a safe identity
            return DMatrix::identity(n, n);
        }
    }
}

/// Solve L L^T x = b.
pub fn chol_solve(l: &DMatrix<f64>, b: &[f64]) -> Vec<f64> {
    let n = l.nrows();
    let mut x = b.to_vec();
    for i in 0..n {
        let mut s = x[i];
        for k in 0..i {
            s -= l[(i, k)] * x[k];
        }
        x[i] = s / l[(i, i)];
    }
    for i in (0..n).rev() {
        let mut s = x[i];
        for k in i + 1..n {
            s -= l[(k, i)] * x[k];
        }
        x[i] = s / l[(i, i)];
    }
    x
}

fn solve_subset(g: &DMatrix<f64>, b: &[f64], set: &[usize]) -> (Vec<f64>, DMatrix<f64>) {
    let n = set.len();
    let sub = DMatrix::from_fn(n, n, |i, j| g[(set[i], set[j])]);
    let l = cholesky(&sub);
    let rhs: Vec<f64> = set.iter().map(|&i| b[i]).collect();
    (chol_solve(&l, &rhs), l)
}

/// Solve the problem given G = Psi^T Psi, b = Psi^T y and which coefficients must be >= 0.
/// (Long on purpose: Lawson and Hanson's algorithm NNLS step by step, as in the book, so that
/// it can be checked against it.)
pub fn nnls_gram(g: &DMatrix<f64>, b: &DVector<f64>, constrained: &[bool]) -> NnlsSolution {
    let m = g.nrows();
    let scale: Vec<f64> = (0..m)
        .map(|i| {
            let d = g[(i, i)];
            if d > 0.0 && d.is_finite() {
                1.0 / d.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let gs = DMatrix::from_fn(m, m, |i, j| g[(i, j)] * scale[i] * scale[j]);
    let bs: Vec<f64> = (0..m).map(|i| b[i] * scale[i]).collect();
    let usable: Vec<bool> = scale.iter().map(|s| *s > 0.0).collect();
    let mut in_p: Vec<bool> = (0..m).map(|i| usable[i] && !constrained[i]).collect();
    let mut x = vec![0.0; m];
    let tol = 1e-12;
    let set_of = |in_p: &[bool]| (0..m).filter(|&i| in_p[i]).collect::<Vec<_>>();
    // start: the free columns
    let mut l = DMatrix::zeros(0, 0);
    let mut first = true;
    for _outer in 0..(3 * m + 10) {
        if !first {
            // gradient w = b - G x; add the constrained column with the largest positive w
            let mut best = None;
            let mut best_w = tol;
            for j in 0..m {
                if in_p[j] || !usable[j] {
                    continue;
                }
                let wj = bs[j] - (0..m).map(|k| gs[(j, k)] * x[k]).sum::<f64>();
                if wj > best_w {
                    best_w = wj;
                    best = Some(j);
                }
            }
            match best {
                Some(j) => in_p[j] = true,
                None => break,
            }
        }
        first = false;
        // inner loop: keep the constrained passive coefficients positive
        for _inner in 0..(3 * m + 10) {
            let set = set_of(&in_p);
            let (s, lf) = solve_subset(&gs, &bs, &set);
            l = lf;
            let mut alpha = f64::INFINITY;
            for (k, &i) in set.iter().enumerate() {
                if constrained[i] && s[k] <= 0.0 {
                    let a = x[i] / (x[i] - s[k]);
                    if a < alpha {
                        alpha = a;
                    }
                }
            }
            if !alpha.is_finite() {
                for v in x.iter_mut() {
                    *v = 0.0;
                }
                for (k, &i) in set.iter().enumerate() {
                    x[i] = s[k];
                }
                break;
            }
            let mut full_s = vec![0.0; m];
            for (k, &i) in set.iter().enumerate() {
                full_s[i] = s[k];
            }
            for i in 0..m {
                if in_p[i] {
                    x[i] += alpha * (full_s[i] - x[i]);
                    if constrained[i] && x[i] <= tol {
                        x[i] = 0.0;
                        in_p[i] = false;
                    }
                }
            }
        }
    }
    let passive = set_of(&in_p);
    if l.nrows() != passive.len() {
        l = solve_subset(&gs, &bs, &passive).1;
    }
    NnlsSolution {
        coef: (0..m).map(|i| x[i] * scale[i]).collect(),
        passive,
        chol_l: l,
        scale,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gram(cols: &[Vec<f64>], y: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
        let m = cols.len();
        let g = DMatrix::from_fn(m, m, |i, j| {
            cols[i].iter().zip(&cols[j]).map(|(a, b)| a * b).sum()
        });
        let b = DVector::from_fn(m, |i, _| cols[i].iter().zip(y).map(|(a, b)| a * b).sum());
        (g, b)
    }

    #[test]
    fn recovers_non_negative_and_free_coefficients() {
        let n = 200;
        let c0: Vec<f64> = (0..n).map(|k| (k as f64 * 0.1).sin()).collect();
        let c1: Vec<f64> = (0..n).map(|k| (k as f64 * 0.037).cos()).collect();
        let c2: Vec<f64> = (0..n).map(|_| 1.0).collect();
        let y: Vec<f64> = (0..n).map(|k| -2.0 * c0[k] + 0.5 * c1[k] + 3.0).collect();
        let (g, b) = gram(&[c0, c1, c2], &y);
        let s = nnls_gram(&g, &b, &[false, true, false]);
        assert!((s.coef[0] + 2.0).abs() < 1e-8, "{:?}", s.coef);
        assert!((s.coef[1] - 0.5).abs() < 1e-8);
        assert!((s.coef[2] - 3.0).abs() < 1e-8);
    }

    #[test]
    fn holds_a_negative_optimum_at_zero() {
        let n = 100;
        let c0: Vec<f64> = (0..n).map(|k| k as f64).collect();
        let c1: Vec<f64> = (0..n).map(|k| ((k * 7) % 13) as f64).collect();
        let y: Vec<f64> = (0..n).map(|k| c0[k] - 0.8 * c1[k]).collect();
        let (g, b) = gram(&[c0, c1], &y);
        let s = nnls_gram(&g, &b, &[true, true]);
        assert_eq!(s.coef[1], 0.0);
        assert!(s.coef[0] > 0.0);
        assert_eq!(s.passive, vec![0]);
    }
}
