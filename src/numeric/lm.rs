//! Levenberg-Marquardt for nonlinear least squares (Levenberg 1944; Marquardt 1963), with the
//! damping scaled by the diagonal of the Gauss-Newton matrix (Moré 1978).
//!
//! The problem says how to evaluate a parameter vector and how to form the normal equations;
//! [`LmSettings`] holds the damping schedule and the stopping rules, so that callers with
//! different needs (the grey-box fit, the Bouc-Wen benchmark's physical model) share one loop.

use nalgebra::{DMatrix, DVector};

/// A nonlinear least-squares problem.
pub trait LeastSquares {
    /// What one evaluation keeps (residual, cost and whatever the Jacobian needs).
    type Eval;
    /// Evaluates the model at `theta`; `None` where it cannot be (non-finite, unstable).
    fn eval(&self, theta: &[f64]) -> Option<Self::Eval>;
    /// The cost a step must lower (any increasing function of the residual norm).
    fn cost(&self, eval: &Self::Eval) -> f64;
    /// The Gauss-Newton normal equations over the parameters `free`: `(J^T J, g)` with `g` the
    /// descent direction `-J^T r` for the residual `r = model - data`. `None` where the
    /// Jacobian cannot be computed.
    fn normal_equations(
        &self,
        theta: &[f64],
        eval: &Self::Eval,
        free: &[usize],
    ) -> Option<(DMatrix<f64>, DVector<f64>)>;
    /// The residual's Euclidean norm (for the gradient test).
    fn residual_norm(&self, eval: &Self::Eval) -> f64;
    /// Per parameter, the interval a step is projected onto (`None`: unbounded).
    fn bounds(&self) -> Option<Vec<(f64, f64)>> {
        None
    }
}

/// A least-squares problem given by its residual `model - data` alone: the cost is the RMS
/// residual, the Jacobian forward differences of step `step` in each free parameter (one
/// evaluation per parameter, in parallel, the sums in a fixed order: the same bytes whatever the
/// thread count). For simulation-error fits of physical models, where no derivative is at hand.
pub struct ForwardDifference<F> {
    pub residual: F,
    pub step: f64,
}

impl<F: Fn(&[f64]) -> Option<Vec<f64>> + Sync> LeastSquares for ForwardDifference<F> {
    type Eval = Vec<f64>;
    fn eval(&self, theta: &[f64]) -> Option<Vec<f64>> {
        (self.residual)(theta)
    }
    fn cost(&self, r: &Vec<f64>) -> f64 {
        (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt()
    }
    fn normal_equations(
        &self,
        theta: &[f64],
        r: &Vec<f64>,
        free: &[usize],
    ) -> Option<(DMatrix<f64>, DVector<f64>)> {
        use rayon::prelude::*;
        let h = self.step;
        let cols: Vec<Vec<f64>> = free
            .par_iter()
            .map(|&j| {
                let mut t = theta.to_vec();
                t[j] += h;
                (self.residual)(&t).map(|rj| rj.iter().zip(r).map(|(a, b)| (a - b) / h).collect())
            })
            .collect::<Option<_>>()?;
        let np = free.len();
        let mut jtj = DMatrix::<f64>::zeros(np, np);
        let mut jtr = DVector::<f64>::zeros(np);
        for a in 0..np {
            jtr[a] = cols[a].iter().zip(r).map(|(x, y)| x * y).sum();
            for b in a..np {
                let v: f64 = cols[a].iter().zip(&cols[b]).map(|(x, y)| x * y).sum();
                jtj[(a, b)] = v;
                jtj[(b, a)] = v;
            }
        }
        Some((jtj, -jtr))
    }
    fn residual_norm(&self, r: &Vec<f64>) -> f64 {
        r.iter().map(|v| v * v).sum::<f64>().sqrt()
    }
}

/// How the damping term scales each parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scaling {
    /// The current diagonal of `J^T J` (Marquardt).
    Current,
    /// The largest diagonal seen so far (Moré's invariant scaling).
    RunningMax,
}

/// The damping schedule and the stopping rules.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmSettings {
    pub max_iterations: usize,
    pub scaling: Scaling,
    /// The damping at the start, its floor after an accepted step and its ceiling (a step
    /// search that passes it stops the fit).
    pub lambda_start: f64,
    pub lambda_min: f64,
    pub lambda_max: f64,
    /// The damping's factor after a singular system, after a rejected step, and its divisor
    /// after an accepted one.
    pub grow_singular: f64,
    pub grow_rejected: f64,
    pub shrink: f64,
    /// Trial steps per iteration at the most.
    pub tries: usize,
    /// A step lowering the cost by a relative amount below `tolerance`, `patience` times in a
    /// row, ends the fit.
    pub tolerance: f64,
    pub patience: usize,
    /// Each parameter is kept inside `[-bound, bound]`.
    pub bound: f64,
    /// A cost at or below this ends the fit (the residual is zero to rounding).
    pub zero_cost: f64,
    /// The fit ends when the largest cosine between the residual and a Jacobian column falls
    /// below this (0 turns the test off).
    pub gradient_tolerance: f64,
}

impl Default for LmSettings {
    /// Moré's scaling, a cautious damping schedule and three stopping tests (a cost change
    /// below 1e-10 twice, a zero residual, a vanishing gradient), 100 iterations.
    fn default() -> Self {
        LmSettings {
            max_iterations: 100,
            scaling: Scaling::RunningMax,
            lambda_start: 1e-3,
            lambda_min: 1e-12,
            lambda_max: 1e16,
            grow_singular: 10.0,
            grow_rejected: 4.0,
            shrink: 3.0,
            tries: usize::MAX,
            tolerance: 1e-10,
            patience: 2,
            bound: f64::INFINITY,
            zero_cost: 0.0,
            gradient_tolerance: 1e-9,
        }
    }
}

/// Why the iteration stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LmStop {
    NoFreeParameter,
    ZeroResidual,
    GradientVanishes,
    /// No trial step lowered the cost (a minimum to the Jacobian's precision).
    NoDescent,
    /// The Jacobian could not be computed at the current parameters.
    NoJacobian,
    /// The cost changed by less than the tolerance `patience` times in a row.
    SmallChange,
    MaxIterations,
}

impl LmStop {
    /// Whether the stop is a convergence (not the iteration budget running out).
    pub fn converged(self) -> bool {
        self != LmStop::MaxIterations
    }
}

/// The result: the best parameters, their evaluation, the iterations taken and why it stopped.
pub struct LmOutcome<E> {
    pub theta: Vec<f64>,
    pub eval: E,
    pub iterations: usize,
    pub stop: LmStop,
}

/// Runs Levenberg-Marquardt from `theta` (already evaluated as `eval`) over the parameters
/// `free`; the others are held.
pub fn levenberg_marquardt<P: LeastSquares>(
    problem: &P,
    mut theta: Vec<f64>,
    mut eval: P::Eval,
    free: &[usize],
    s: &LmSettings,
) -> LmOutcome<P::Eval> {
    let p = free.len();
    let done = |theta, eval, iterations, stop| LmOutcome {
        theta,
        eval,
        iterations,
        stop,
    };
    if p == 0 {
        return done(theta, eval, 0, LmStop::NoFreeParameter);
    }
    let bounds = problem.bounds();
    let mut lambda = s.lambda_start;
    let mut dmax = vec![0.0f64; p];
    let mut small = 0;
    for it in 1..=s.max_iterations {
        if problem.cost(&eval) <= s.zero_cost {
            return done(theta, eval, it - 1, LmStop::ZeroResidual);
        }
        let Some((mut a, mut g)) = problem.normal_equations(&theta, &eval, free) else {
            return done(theta, eval, it, LmStop::NoJacobian);
        };
        let scale: &[f64] = match s.scaling {
            Scaling::RunningMax => {
                for (i, d) in dmax.iter_mut().enumerate() {
                    *d = d.max(a[(i, i)]);
                }
                &dmax
            }
            Scaling::Current => {
                for (i, d) in dmax.iter_mut().enumerate() {
                    *d = a[(i, i)];
                }
                &dmax
            }
        };
        if let Some(b) = &bounds {
            pin_at_bounds(&mut a, &mut g, &theta, free, b);
        }
        if s.gradient_tolerance > 0.0
            && max_cosine(&a, &g, problem.residual_norm(&eval)) < s.gradient_tolerance
        {
            return done(theta, eval, it - 1, LmStop::GradientVanishes);
        }
        let mut accepted = false;
        for _ in 0..s.tries {
            let mut m = a.clone();
            for (i, d) in scale.iter().enumerate() {
                m[(i, i)] += lambda * d.max(1e-30);
            }
            let Some(step) = m.cholesky().map(|c| c.solve(&g)) else {
                lambda *= s.grow_singular;
                if lambda > s.lambda_max {
                    break;
                }
                continue;
            };
            let mut trial = theta.clone();
            for (k, &i) in free.iter().enumerate() {
                trial[i] = (theta[i] + step[k]).clamp(-s.bound, s.bound);
                if let Some((lo, hi)) = bounds.as_ref().map(|b| b[i]) {
                    trial[i] = trial[i].clamp(lo, hi);
                }
            }
            match problem.eval(&trial) {
                Some(e) if problem.cost(&e) < problem.cost(&eval) => {
                    let (old, new) = (problem.cost(&eval), problem.cost(&e));
                    let rel = (old - new) / old;
                    theta = trial;
                    eval = e;
                    lambda = (lambda / s.shrink).max(s.lambda_min);
                    small = if rel < s.tolerance { small + 1 } else { 0 };
                    accepted = true;
                    break;
                }
                _ => {
                    lambda *= s.grow_rejected;
                    if lambda > s.lambda_max {
                        break;
                    }
                }
            }
        }
        if !accepted {
            return done(theta, eval, it, LmStop::NoDescent);
        }
        if small >= s.patience {
            return done(theta, eval, it, LmStop::SmallChange);
        }
    }
    done(theta, eval, s.max_iterations, LmStop::MaxIterations)
}

/// A parameter on its bound whose descent direction points out of it takes no part in the
/// step (an active set): its row and column of the normal equations are cleared, its
/// gradient set to 0, so that the others move as the bound lets them.
fn pin_at_bounds(
    a: &mut DMatrix<f64>,
    g: &mut DVector<f64>,
    theta: &[f64],
    free: &[usize],
    bounds: &[(f64, f64)],
) {
    for (k, &i) in free.iter().enumerate() {
        let (lo, hi) = bounds[i];
        if (theta[i] <= lo && g[k] < 0.0) || (theta[i] >= hi && g[k] > 0.0) {
            a.row_mut(k).fill(0.0);
            a.column_mut(k).fill(0.0);
            a[(k, k)] = 1.0;
            g[k] = 0.0;
        }
    }
}

/// The largest cosine between the residual (norm `rnorm`) and a Jacobian column.
fn max_cosine(a: &DMatrix<f64>, g: &DVector<f64>, rnorm: f64) -> f64 {
    (0..g.len())
        .map(|i| {
            let d = a[(i, i)].sqrt() * rnorm;
            if d > 0.0 {
                g[i].abs() / d
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// y = a exp(b t) on exact data.
    struct Exponential {
        t: Vec<f64>,
        y: Vec<f64>,
        bounds: Option<Vec<(f64, f64)>>,
    }

    impl LeastSquares for Exponential {
        type Eval = Vec<f64>;
        fn eval(&self, th: &[f64]) -> Option<Vec<f64>> {
            let r: Vec<f64> = (self.t.iter().zip(&self.y))
                .map(|(t, y)| th[0] * (th[1] * t).exp() - y)
                .collect();
            r.iter().all(|v| v.is_finite()).then_some(r)
        }
        fn cost(&self, r: &Vec<f64>) -> f64 {
            0.5 * r.iter().map(|v| v * v).sum::<f64>()
        }
        fn normal_equations(
            &self,
            th: &[f64],
            r: &Vec<f64>,
            free: &[usize],
        ) -> Option<(DMatrix<f64>, DVector<f64>)> {
            let j = DMatrix::from_fn(self.t.len(), free.len(), |k, c| {
                let t = self.t[k];
                match free[c] {
                    0 => (th[1] * t).exp(),
                    _ => th[0] * t * (th[1] * t).exp(),
                }
            });
            Some((j.tr_mul(&j), -j.tr_mul(&DVector::from_column_slice(r))))
        }
        fn residual_norm(&self, r: &Vec<f64>) -> f64 {
            r.iter().map(|v| v * v).sum::<f64>().sqrt()
        }
        fn bounds(&self) -> Option<Vec<(f64, f64)>> {
            self.bounds.clone()
        }
    }

    fn settings() -> LmSettings {
        LmSettings {
            tolerance: 1e-12,
            zero_cost: 1e-28,
            gradient_tolerance: 1e-10,
            ..LmSettings::default()
        }
    }

    /// Levenberg-Marquardt on `prob` from `th` over `free` with the tests' settings.
    fn fit(prob: &Exponential, th: &[f64], free: &[usize]) -> LmOutcome<Vec<f64>> {
        let e = prob.eval(th).unwrap();
        levenberg_marquardt(prob, th.to_vec(), e, free, &settings())
    }

    #[test]
    fn recovers_an_exponential_from_a_distant_start() {
        let t: Vec<f64> = (0..40).map(|k| k as f64 * 0.05).collect();
        let y = t.iter().map(|t| 2.5 * (-1.3 * t).exp()).collect();
        let prob = Exponential { t, y, bounds: None };
        let th0 = vec![1.0, 0.0];
        let e0 = prob.eval(&th0).unwrap();
        for scaling in [Scaling::RunningMax, Scaling::Current] {
            let s = LmSettings {
                scaling,
                ..settings()
            };
            let out = levenberg_marquardt(&prob, th0.clone(), e0.clone(), &[0, 1], &s);
            assert!(out.stop.converged(), "{:?}", out.stop);
            assert!((out.theta[0] - 2.5).abs() < 1e-8, "{:?}", out.theta);
            assert!((out.theta[1] + 1.3).abs() < 1e-8, "{:?}", out.theta);
        }
    }

    /// A bound the unconstrained minimum lies beyond: the steps are projected onto it, the fit
    /// ends on it with the other parameter at its best there.
    #[test]
    fn a_bounded_parameter_ends_on_its_bound() {
        let t: Vec<f64> = (0..40).map(|k| k as f64 * 0.05).collect();
        let y = t.iter().map(|t| 2.5 * (-1.3 * t).exp()).collect();
        let prob = Exponential {
            t,
            y,
            bounds: Some(vec![(f64::NEG_INFINITY, 2.0), (f64::NEG_INFINITY, 0.0)]),
        };
        let th0 = vec![1.0, 0.0];
        let out = fit(&prob, &th0, &[0, 1]);
        assert_eq!(out.theta[0], 2.0, "{:?}", out.theta);
        assert!(
            out.theta[1] < -1.0 && out.theta[1] > -1.3,
            "{:?}",
            out.theta
        );
        // the best rate for an amplitude of 2: a one-parameter fit from there agrees
        let free = Exponential {
            bounds: None,
            ..prob
        };
        let th = vec![2.0, out.theta[1]];
        let one = fit(&free, &th, &[1]);
        assert!(
            (one.theta[1] - out.theta[1]).abs() < 1e-6,
            "{:?} {:?}",
            one.theta,
            out.theta
        );
    }

    #[test]
    fn held_parameters_do_not_move_and_no_free_parameter_stops_at_once() {
        let t: Vec<f64> = (0..20).map(|k| k as f64 * 0.1).collect();
        let y = t.iter().map(|t| 3.0 * (-0.5 * t).exp()).collect();
        let prob = Exponential { t, y, bounds: None };
        let th0 = vec![1.0, -0.5];
        let out = fit(&prob, &th0, &[0]);
        assert_eq!(out.theta[1], -0.5);
        assert!((out.theta[0] - 3.0).abs() < 1e-10);
        let none = fit(&prob, &th0, &[]);
        assert_eq!((none.stop, none.iterations), (LmStop::NoFreeParameter, 0));
    }

    #[test]
    fn the_iteration_budget_is_reported_as_not_converged() {
        let t: Vec<f64> = (0..40).map(|k| k as f64 * 0.05).collect();
        let y = t.iter().map(|t| 2.5 * (-1.3 * t).exp()).collect();
        let prob = Exponential { t, y, bounds: None };
        let th0 = vec![1.0, 0.0];
        let s = LmSettings {
            max_iterations: 1,
            ..settings()
        };
        let out = levenberg_marquardt(&prob, th0.clone(), prob.eval(&th0).unwrap(), &[0, 1], &s);
        assert_eq!((out.stop, out.iterations), (LmStop::MaxIterations, 1));
        assert!(!out.stop.converged());
    }
}
