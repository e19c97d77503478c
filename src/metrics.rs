//! # Metrics
//!
//! Scores of a prediction against a measurement, as the field reports them:
//! R^2 = 1 - sum(e^2)/sum((y - mean y)^2), RMSE, NRMSE = RMSE / std(y), fit % = 100 (1 - NRMSE)
//! (MATLAB's `compare`, nonlinear-benchmarks' `fit_index`), and the largest absolute error.
//! Normalised scores are `None` for a constant measurement, never NaN.

use serde::{Deserialize, Serialize};

/// The scores of one predicted signal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    /// Coefficient of determination; `None` when the measurement is constant.
    pub r2: Option<f64>,
    pub rmse: f64,
    /// RMSE over the standard deviation of the measurement; `None` when it is constant.
    pub nrmse: Option<f64>,
    /// 100 (1 - NRMSE).
    pub fit_percent: Option<f64>,
    pub max_error: f64,
    /// Number of samples scored.
    pub n: usize,
}

/// Root-mean-square of a signal.
pub fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// Mean of a signal (0 for an empty one).
pub fn mean(x: &[f64]) -> f64 {
    if x.is_empty() {
        0.0
    } else {
        x.iter().sum::<f64>() / x.len() as f64
    }
}

/// Population standard deviation.
pub fn std_dev(x: &[f64]) -> f64 {
    let m = mean(x);
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / x.len() as f64).sqrt()
}

/// Root-mean-square error.
pub fn rmse(measured: &[f64], predicted: &[f64]) -> f64 {
    assert_eq!(measured.len(), predicted.len());
    if measured.is_empty() {
        return 0.0;
    }
    let s: f64 = measured
        .iter()
        .zip(predicted)
        .map(|(y, p)| (y - p) * (y - p))
        .sum();
    (s / measured.len() as f64).sqrt()
}

/// R^2; `None` when the measurement is constant.
pub fn r2(measured: &[f64], predicted: &[f64]) -> Option<f64> {
    let m = mean(measured);
    let ss_tot: f64 = measured.iter().map(|y| (y - m) * (y - m)).sum();
    if ss_tot <= f64::MIN_POSITIVE * measured.len() as f64 || !ss_tot.is_finite() {
        return None;
    }
    let ss_res: f64 = measured
        .iter()
        .zip(predicted)
        .map(|(y, p)| (y - p) * (y - p))
        .sum();
    Some(1.0 - ss_res / ss_tot)
}

/// All scores at once.
pub fn scores(measured: &[f64], predicted: &[f64]) -> Scores {
    let e = rmse(measured, predicted);
    let sd = std_dev(measured);
    let nrmse = (sd > 0.0).then(|| e / sd);
    Scores {
        r2: r2(measured, predicted),
        rmse: e,
        nrmse,
        fit_percent: nrmse.map(|n| 100.0 * (1.0 - n)),
        max_error: measured
            .iter()
            .zip(predicted)
            .map(|(y, p)| (y - p).abs())
            .fold(0.0, f64::max),
        n: measured.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perfect_prediction() {
        let y = [1.0, 2.0, 3.0];
        let s = scores(&y, &y);
        assert_eq!(s.r2, Some(1.0));
        assert_eq!(s.rmse, 0.0);
        assert_eq!(s.fit_percent, Some(100.0));
    }

    #[test]
    fn mean_prediction_has_zero_r2_and_fit() {
        let y = [1.0, 2.0, 3.0, 4.0];
        let p = [2.5; 4];
        let s = scores(&y, &p);
        assert!(s.r2.unwrap().abs() < 1e-15);
        assert!(s.fit_percent.unwrap().abs() < 1e-12);
        assert_eq!(s.max_error, 1.5);
    }

    #[test]
    fn constant_measurement_gives_none() {
        let s = scores(&[2.0; 5], &[1.0; 5]);
        assert_eq!(s.r2, None);
        assert_eq!(s.nrmse, None);
        assert_eq!(s.rmse, 1.0);
    }
}
