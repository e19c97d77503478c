//! # Integrators for driven ODEs
//!
//! One small trait, [`Integrator`], advances the state of a [`DrivenOde`] over one sample
//! interval. Two implementations:
//!
//! - [`Dopri5Integrator`]: ode_solvers' Dormand-Prince 5(4) with adaptive steps, the accuracy
//!   reference. Each interval is integrated on local time `[0, dt]` with
//!   `OutputType::Sparse` (Dense output with `dx == x_end - x0` returns an extrapolated,
//!   wrong endpoint; see RUST-NOTES, ode_solvers pitfalls), and the last accepted full step is
//!   carried over as the next interval's first trial step.
//! - [`Rk4Integrator`]: a hand-written, allocation-free classical Runge-Kutta 4 with a fixed
//!   number of sub-steps per interval, the fast path. Its step count is exact (no
//!   `ceil((x_end - x) / h)` overshoot as in `ode_solvers::Rk4` on absolute time).
//!
//! ## References
//! - J.R. Dormand, P.J. Prince, "A family of embedded Runge-Kutta formulae",
//!   J. Comput. Appl. Math. 6(1):19-26, 1980.
//! - E. Hairer, S.P. Nørsett, G. Wanner, "Solving Ordinary Differential Equations I", 2nd ed.,
//!   Springer, 1993 (DOPRI5, step size control).

use nalgebra::SVector;
use ode_solvers::{Dopri5, OutputType, System};

/// An ODE x' = f(u(t), x) driven by one input signal u(t).
pub trait DrivenOde<const N: usize> {
    /// The input at absolute time `t`.
    fn input(&self, t: f64) -> f64;
    /// The state derivative for input `u` and state `x`.
    fn rhs(&self, u: f64, x: &SVector<f64, N>) -> SVector<f64, N>;
}

/// Why an integrator could not advance over an interval.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum IntegratorError {
    /// The adaptive solver failed (its own reason).
    #[error("{reason}")]
    Solver { reason: String },
    /// The solver returned no output for the interval.
    #[error("Dopri5 returned no output")]
    NoOutput,
    /// The solver stopped before the end of the interval.
    #[error("Dopri5 stopped at local time {stopped}, not at {end}")]
    Stopped { stopped: f64, end: f64 },
}

/// Advances a driven ODE over one interval.
pub trait Integrator<const N: usize> {
    /// Integrates `x` from `t0` to `t0 + dt` (absolute times, `dt > 0`); the caller adds where
    /// an error happened.
    fn advance<S: DrivenOde<N>>(
        &mut self,
        ode: &S,
        t0: f64,
        dt: f64,
        x: &mut SVector<f64, N>,
    ) -> Result<(), IntegratorError>;

    /// Right-hand-side evaluations so far.
    fn evaluations(&self) -> u64;
}

/// Hand-written fixed-step RK4, `substeps` steps per interval.
#[derive(Debug, Clone)]
pub struct Rk4Integrator {
    substeps: usize,
    evaluations: u64,
}

impl Rk4Integrator {
    /// `substeps` >= 1 steps per interval.
    pub fn new(substeps: usize) -> Self {
        Rk4Integrator {
            substeps: substeps.max(1),
            evaluations: 0,
        }
    }
}

impl<const N: usize> Integrator<N> for Rk4Integrator {
    #[inline(always)]
    fn advance<S: DrivenOde<N>>(
        &mut self,
        ode: &S,
        t0: f64,
        dt: f64,
        x: &mut SVector<f64, N>,
    ) -> Result<(), IntegratorError> {
        let n = self.substeps;
        let h = dt / n as f64;
        let mut u0 = ode.input(t0);
        for i in 0..n {
            let t = t0 + i as f64 * h;
            let um = ode.input(t + 0.5 * h);
            let u1 = ode.input(t0 + (i + 1) as f64 * h);
            let k1 = ode.rhs(u0, x);
            let k2 = ode.rhs(um, &(*x + k1 * (0.5 * h)));
            let k3 = ode.rhs(um, &(*x + k2 * (0.5 * h)));
            let k4 = ode.rhs(u1, &(*x + k3 * h));
            *x += (k1 + (k2 + k3) * 2.0 + k4) * (h / 6.0);
            u0 = u1;
        }
        self.evaluations += 4 * n as u64;
        Ok(())
    }

    fn evaluations(&self) -> u64 {
        self.evaluations
    }
}

/// ode_solvers' Dopri5 on each interval (Sparse output, local time).
#[derive(Debug, Clone)]
pub struct Dopri5Integrator {
    rtol: f64,
    atol: f64,
    /// Trial step for the next interval (0: let Dopri5 choose).
    h_next: f64,
    evaluations: u64,
}

impl Dopri5Integrator {
    /// Relative and absolute tolerances (the absolute one in state units).
    pub fn new(rtol: f64, atol: f64) -> Self {
        Dopri5Integrator {
            rtol,
            atol,
            h_next: 0.0,
            evaluations: 0,
        }
    }
}

/// The ODE seen on local time x in [0, dt], for ode_solvers.
struct LocalTime<'a, S> {
    ode: &'a S,
    t0: f64,
}

impl<S: DrivenOde<N>, const N: usize> System<f64, SVector<f64, N>> for LocalTime<'_, S> {
    #[inline]
    fn system(&self, x: f64, y: &SVector<f64, N>, dy: &mut SVector<f64, N>) {
        *dy = self.ode.rhs(self.ode.input(self.t0 + x), y);
    }
}

impl<const N: usize> Integrator<N> for Dopri5Integrator {
    fn advance<S: DrivenOde<N>>(
        &mut self,
        ode: &S,
        t0: f64,
        dt: f64,
        x: &mut SVector<f64, N>,
    ) -> Result<(), IntegratorError> {
        let h0 = if self.h_next > 0.0 && self.h_next < dt {
            self.h_next
        } else {
            0.0
        };
        let mut solver = Dopri5::from_param(
            LocalTime { ode, t0 },
            0.0,
            dt,
            dt,
            *x,
            self.rtol,
            self.atol,
            0.9,
            0.04,
            0.2,
            10.0,
            dt,
            h0,
            100_000,
            1000,
            OutputType::Sparse,
        );
        let stats = solver.integrate().map_err(|e| IntegratorError::Solver {
            reason: e.to_string(),
        })?;
        self.evaluations += stats.num_eval as u64;
        let (ts, ys) = (solver.x_out(), solver.y_out());
        let last = ys.last().ok_or(IntegratorError::NoOutput)?;
        let t_last = *ts.last().ok_or(IntegratorError::NoOutput)?;
        if (t_last - dt).abs() > 1e-9 * dt {
            return Err(IntegratorError::Stopped {
                stopped: t_last,
                end: dt,
            });
        }
        *x = *last;
        // The last step was cut to reach dt; the one before it is a full, accepted step.
        self.h_next = if ts.len() >= 3 {
            ts[ts.len() - 2] - ts[ts.len() - 3]
        } else {
            dt
        };
        Ok(())
    }

    fn evaluations(&self) -> u64 {
        self.evaluations
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Damped oscillator driven by a sine: both integrators against the closed-form steady
    /// state would need a transient; compare them with each other and with a fine RK4 instead.
    struct Oscillator;
    impl DrivenOde<2> for Oscillator {
        fn input(&self, t: f64) -> f64 {
            (7.0 * t).sin()
        }
        fn rhs(&self, u: f64, x: &SVector<f64, 2>) -> SVector<f64, 2> {
            SVector::<f64, 2>::new(x[1], u - 0.4 * x[1] - 25.0 * x[0])
        }
    }

    #[test]
    fn rk4_and_dopri5_agree_on_a_linear_oscillator() {
        let dt = 0.01;
        let mut a = SVector::<f64, 2>::zeros();
        let mut b = SVector::<f64, 2>::zeros();
        let mut rk4 = Rk4Integrator::new(4);
        let mut dp = Dopri5Integrator::new(1e-10, 1e-12);
        for k in 0..500 {
            rk4.advance(&Oscillator, k as f64 * dt, dt, &mut a).unwrap();
            dp.advance(&Oscillator, k as f64 * dt, dt, &mut b).unwrap();
        }
        assert!((a - b).norm() < 1e-8, "{a} vs {b}");
        assert!(a.norm() > 1e-2, "the test must move the state");
        assert_eq!(Integrator::<2>::evaluations(&rk4), 500 * 16);
    }

    /// y' = -y: RK4 is 4th order; halving the step divides the error by about 16.
    struct Decay;
    impl DrivenOde<1> for Decay {
        fn input(&self, _t: f64) -> f64 {
            0.0
        }
        fn rhs(&self, _u: f64, x: &SVector<f64, 1>) -> SVector<f64, 1> {
            -x * 10.0
        }
    }

    #[test]
    fn rk4_is_fourth_order() {
        let err = |n: usize| {
            let mut x = SVector::<f64, 1>::new(1.0);
            Rk4Integrator::new(n)
                .advance(&Decay, 0.0, 1.0, &mut x)
                .unwrap();
            (x[0] - (-10.0f64).exp()).abs()
        };
        let ratio = err(200) / err(400);
        assert!((ratio - 16.0).abs() < 0.5, "ratio {ratio}");
    }
}
