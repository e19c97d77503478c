//! Linear least squares by the normal equations: rows accumulated one at a time into
//! `G = A^T A` and `b = A^T y` (the record is never held as a matrix), then a Cholesky solve
//! with an optional ridge and column scaling. Every sum runs over the rows in order, so the
//! result is the same on every run.
//!
//! The non-negative variant (Lawson and Hanson's active set on the same Gram matrix) is in
//! `graybox::nnls`.

use nalgebra::{DMatrix, DVector};

/// The normal equations of a least-squares problem with `p` columns.
#[derive(Debug, Clone)]
pub struct NormalEquations {
    gram: DMatrix<f64>,
    rhs: DVector<f64>,
    rows: usize,
}

impl NormalEquations {
    pub fn new(p: usize) -> Self {
        NormalEquations {
            gram: DMatrix::zeros(p, p),
            rhs: DVector::zeros(p),
            rows: 0,
        }
    }

    /// Adds one row of the design matrix and its target (the upper triangle of `G` only).
    #[inline]
    pub fn add_row(&mut self, row: &[f64], target: f64) {
        let p = self.rhs.len();
        debug_assert_eq!(row.len(), p);
        for a in 0..p {
            let ra = row[a];
            self.rhs[a] += ra * target;
            for (b, &rb) in row.iter().enumerate().skip(a) {
                self.gram[(a, b)] += ra * rb;
            }
        }
        self.rows += 1;
    }

    /// The number of rows added.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// `(G, b)` with `G` made symmetric.
    pub fn into_parts(mut self) -> (DMatrix<f64>, DVector<f64>) {
        let p = self.rhs.len();
        for a in 0..p {
            for b in 0..a {
                self.gram[(a, b)] = self.gram[(b, a)];
            }
        }
        (self.gram, self.rhs)
    }

    /// Solves `(G + ridge I) x = b`; `None` where `G + ridge I` is not positive definite or
    /// the solution is not finite.
    pub fn solve(self, ridge: f64) -> Option<DVector<f64>> {
        let (g, b) = self.into_parts();
        solve_ridge(g, &b, ridge)
    }
}

/// Solves `(G + ridge I) x = b` by Cholesky; `None` where it is not positive definite or the
/// solution is not finite.
pub fn solve_ridge(mut g: DMatrix<f64>, b: &DVector<f64>, ridge: f64) -> Option<DVector<f64>> {
    for i in 0..b.len() {
        g[(i, i)] += ridge;
    }
    let x = g.cholesky()?.solve(b);
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Solves `G x = b` with the columns scaled to unit diagonal first (`G_ij / (d_i d_j)`,
/// `d_i = sqrt(G_ii)`) and `ridge` added to the scaled diagonal: well conditioned when the
/// columns differ in scale by many orders of magnitude.
pub fn solve_scaled(g: &DMatrix<f64>, b: &DVector<f64>, ridge: f64) -> Option<DVector<f64>> {
    let m = b.len();
    let d: Vec<f64> = (0..m).map(|i| g[(i, i)].max(1e-300).sqrt()).collect();
    let gs = DMatrix::from_fn(m, m, |i, j| {
        g[(i, j)] / (d[i] * d[j]) + if i == j { ridge } else { 0.0 }
    });
    let bs = DVector::from_fn(m, |i, _| b[i] / d[i]);
    let c = gs.cholesky()?.solve(&bs);
    Some(DVector::from_fn(m, |i, _| c[i] / d[i]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_exact_coefficients_and_refuses_a_singular_system() {
        let mut ne = NormalEquations::new(3);
        for k in 0..50 {
            let x = k as f64 * 0.1;
            let row = [1.0, x, x * x];
            ne.add_row(&row, 2.0 - 0.5 * x + 0.25 * x * x);
        }
        assert_eq!(ne.rows(), 50);
        let (g, b) = ne.clone().into_parts();
        assert_eq!(g, g.transpose());
        let x = ne.solve(0.0).unwrap();
        for (got, want) in x.iter().zip([2.0, -0.5, 0.25]) {
            assert!((got - want).abs() < 1e-9, "{x}");
        }
        let xs = solve_scaled(&g, &b, 0.0).unwrap();
        for (got, want) in xs.iter().zip([2.0, -0.5, 0.25]) {
            assert!((got - want).abs() < 1e-9, "{xs}");
        }
        let mut unused = NormalEquations::new(2);
        for k in 0..10 {
            unused.add_row(&[k as f64, 0.0], 1.0);
        }
        assert!(unused.clone().solve(0.0).is_none());
        assert!(unused.solve(1e-6).is_some(), "a ridge makes it solvable");
    }
}
