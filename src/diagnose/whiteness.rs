//! Residual correlation tests: is anything left that the inputs or the residual's own past can
//! explain? Auto-correlation, cross-correlation with each input over negative and positive lags,
//! and the higher-order tests of Billings and Voon, all against the 95 % band +-1.96/sqrt(N).
//!
//! ## References
//! - S. A. Billings, W. S. F. Voon, "Correlation based model validity tests for non-linear
//!   models", Int. J. Control 44(1):235-244, 1986.
//! - S. A. Billings, Q. M. Zhu, "Nonlinear model validation using correlation tests",
//!   Int. J. Control 60(6):1107-1120, 1994.
//! - L. Ljung, *System Identification: Theory for the User*, 2nd ed., 1999, sec. 16.6.

use serde::Serialize;

/// One correlation test.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CorrelationTest {
    /// e.g. `phi_ee`, `phi_ue(u)`, `phi_u2e(u)`.
    pub name: String,
    /// Largest |normalised correlation| over the tested lags.
    pub max_abs: f64,
    /// Lag of that maximum.
    pub at_lag: i64,
    /// Share of tested lags outside the 95 % band.
    pub outside: f64,
    /// The band.
    pub bound: f64,
    /// More lags outside the band than chance allows.
    pub significant: bool,
}

/// All tests on one residual.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Whiteness {
    pub tests: Vec<CorrelationTest>,
    /// True when no test is significant: nothing the tests can see is left.
    pub white: bool,
}

fn centred(x: &[f64]) -> Vec<f64> {
    let m = crate::metrics::mean(x);
    x.iter().map(|v| v - m).collect()
}

/// Normalised cross-correlation of a and b at lags in `lags` (b delayed by lag).
fn xcorr(a: &[f64], b: &[f64], lags: impl Iterator<Item = i64>) -> Vec<(i64, f64)> {
    let a = centred(a);
    let b = centred(b);
    let n = a.len() as i64;
    let na = a.iter().map(|v| v * v).sum::<f64>();
    let nb = b.iter().map(|v| v * v).sum::<f64>();
    let norm = (na * nb).sqrt();
    lags.map(|lag| {
        let mut s = 0.0;
        for k in lag.max(0)..(n + lag.min(0)) {
            s += a[k as usize] * b[(k - lag) as usize];
        }
        (lag, if norm > 0.0 { s / norm } else { 0.0 })
    })
    .collect()
}

fn summarise(name: String, c: Vec<(i64, f64)>, n: usize) -> CorrelationTest {
    let bound = 1.96 / (n as f64).sqrt();
    let (at_lag, max_abs) =
        c.iter()
            .map(|(l, v)| (*l, v.abs()))
            .fold((0, 0.0), |m, x| if x.1 > m.1 { x } else { m });
    let outside_count = c.iter().filter(|(_, v)| v.abs() > bound).count();
    let outside = outside_count as f64 / c.len().max(1) as f64;
    // 5 % of lags fall outside by chance; allow a margin (binomial, about 3 sigma)
    let m = c.len() as f64;
    let allowed = 0.05 * m + 3.0 * (0.05 * 0.95 * m).sqrt();
    CorrelationTest {
        name,
        max_abs,
        at_lag,
        outside,
        bound,
        significant: outside_count as f64 > allowed,
    }
}

/// Run every test on residual `e` with inputs `inputs` (named), up to `max_lag` lags.
pub fn whiteness(e: &[f64], inputs: &[(&str, &[f64])], max_lag: usize) -> Whiteness {
    let n = e.len();
    let l = max_lag.min(n / 4).max(1) as i64;
    let mut tests = vec![summarise("phi_ee".into(), xcorr(e, e, 1..=l), n)];
    let ec = centred(e);
    let e2: Vec<f64> = ec.iter().map(|v| v * v).collect();
    for (name, u) in inputs {
        tests.push(summarise(format!("phi_ue({name})"), xcorr(e, u, -l..=l), n));
        let uc = centred(u);
        let u2: Vec<f64> = uc.iter().map(|v| v * v).collect();
        tests.push(summarise(
            format!("phi_u2e({name})"),
            xcorr(e, &u2, -l..=l),
            n,
        ));
        tests.push(summarise(
            format!("phi_u2e2({name})"),
            xcorr(&e2, &u2, -l..=l),
            n,
        ));
        let eu: Vec<f64> = (0..n)
            .map(|k| if k > 0 { ec[k - 1] * uc[k - 1] } else { 0.0 })
            .collect();
        tests.push(summarise(
            format!("phi_e(eu)({name})"),
            xcorr(e, &eu, 0..=l),
            n,
        ));
    }
    let white = tests.iter().all(|t| !t.significant);
    Whiteness { tests, white }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_noise_passes_and_structure_fails() {
        let mut g = crate::effect::noise::Gaussian::new(3, 0);
        let u: Vec<f64> = (0..5000).map(|k| (k as f64 * 0.02).sin() * 10.0).collect();
        let e: Vec<f64> = (0..5000).map(|_| g.standard_normal()).collect();
        let w = whiteness(&e, &[("u", &u)], 30);
        assert!(
            w.white,
            "{:?}",
            w.tests.iter().filter(|t| t.significant).collect::<Vec<_>>()
        );
        let e2: Vec<f64> = e
            .iter()
            .zip(&u)
            .map(|(e, u)| e + 0.2 * u * u / 10.0)
            .collect();
        assert!(!whiteness(&e2, &[("u", &u)], 30).white);
    }
}
