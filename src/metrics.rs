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

/// Root-mean-square error over the samples both signals have (0 for none).
pub fn rmse(measured: &[f64], predicted: &[f64]) -> f64 {
    let n = measured.len().min(predicted.len());
    if n == 0 {
        return 0.0;
    }
    let s: f64 = measured
        .iter()
        .zip(predicted)
        .map(|(y, p)| (y - p) * (y - p))
        .sum();
    (s / n as f64).sqrt()
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

    /// The Kolmogorov-Smirnov distance: 0 for the same values in any order, the share
    /// that lies beyond the other sample's values, 1 without overlap.
    #[test]
    fn ks_distance_counts_the_share_between_the_distributions() {
        let a: Vec<f64> = (0..100).map(f64::from).collect();
        let mut b = a.clone();
        b.reverse();
        assert_eq!(ks_distance(&a, &b), 0.0);
        assert_eq!(ks_distance(&a, &a[..50]), 0.5);
        assert_eq!(ks_distance(&a[..50], &a[50..]), 1.0);
        // ties: a staircase's two levels against one of them
        let two = [1.0, 1.0, 2.0, 2.0];
        assert_eq!(ks_distance(&two, &[1.0; 3]), 0.5);
        assert_eq!(ks_distance(&two, &[1.0, 2.0]), 0.0);
        assert_eq!(ks_distance(&[], &two), 0.0);
    }

    #[test]
    fn rmse_is_over_the_common_length_and_never_panics() {
        assert_eq!(rmse(&[1.0, 2.0, 3.0], &[1.0, 2.0]), 0.0);
        assert_eq!(rmse(&[], &[1.0]), 0.0);
        assert_eq!(rmse(&[0.0, 0.0], &[3.0, 4.0]), (12.5f64).sqrt());
    }

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

/// Batches of the error-difference series in [`significantly_lower_error`].
pub const COMPARISON_BATCHES: usize = 8;
/// One-sided 95 % quantile of Student's t with `COMPARISON_BATCHES - 1` = 7 degrees of freedom.
const T_7_95: f64 = 1.895;

/// Whether the errors `a` are significantly smaller than the errors `b` on the same samples,
/// at the 5 % level each, by either of two one-sided tests over [`COMPARISON_BATCHES`] contiguous
/// batches (free-run errors are strongly correlated in time, so single samples are not
/// independent; batch means are, nearly):
/// - the Diebold-Mariano test of equal mean squared error on the loss differences
///   d_k = a_k^2 - b_k^2 (Diebold and Mariano 1995), with the variance of their mean taken from
///   the batch means;
/// - a test that the ratio of the batch mean squared errors is below one, a t-test on their
///   logarithms or Wilcoxon's signed-rank test on them, when the total mean squared error of
///   `a` is lower too. It is scale-free: errors that grow along the record, or a burst in one
///   batch, leave the loss differences too uneven for the first test even when `a` is a
///   hundredfold lower in every batch; the rank test also holds when `b` is a little higher
///   in most batches and runs off in the last (the t-test on the logarithms then sees the
///   spread of the run-off).
///
/// Too few samples (fewer than two per batch) or a non-finite error: not significant.
///
/// Model selection uses it to keep the simpler model unless the richer one is clearly better
/// on held-out samples.
///
/// F. X. Diebold, R. S. Mariano, "Comparing predictive accuracy", J. Bus. Econ. Stat.
/// 13(3):253-263, 1995.
pub fn significantly_lower_error(a: &[f64], b: &[f64]) -> bool {
    let Some((ma, mb)) = batch_mses(a, b) else {
        return false;
    };
    let d: Vec<f64> = ma.iter().zip(&mb).map(|(x, y)| x - y).collect();
    if t_below(&d) {
        return true;
    }
    let (ta, tb) = (mean(&ma), mean(&mb));
    // a floor far below either error keeps an exact zero finite
    let floor = 1e-12 * (ta + tb) + f64::MIN_POSITIVE;
    let l: Vec<f64> = ma
        .iter()
        .zip(&mb)
        .map(|(x, y)| ((x + floor) / (y + floor)).ln())
        .collect();
    ta < tb && (t_below(&l) || signed_rank_below(&l))
}

/// Wilcoxon's signed-rank statistic W+ at or below which [`COMPARISON_BATCHES`] = 8 values
/// are significantly below zero, one-sided at 5 %: P(W+ <= 5) = 10/256 = 0.039 under the null.
const SIGNED_RANK_8_95: f64 = 5.0;

/// Whether the batch values `v` (8 of them) lie significantly below zero by Wilcoxon's
/// signed-rank test: a rank test, so one batch far above the others (a free run that drifts
/// off at the end of the held-out part) weighs as one rank, not as its size. Ties take their
/// mean rank; a zero counts half above.
///
/// F. Wilcoxon, "Individual comparisons by ranking methods", Biometrics Bulletin 1(6):80-83,
/// 1945.
fn signed_rank_below(v: &[f64]) -> bool {
    if v.len() != COMPARISON_BATCHES {
        return false;
    }
    let mut order: Vec<usize> = (0..v.len()).collect();
    order.sort_by(|&i, &j| v[i].abs().total_cmp(&v[j].abs()));
    let mut rank = vec![0.0; v.len()];
    let mut i = 0;
    while i < order.len() {
        let mut j = i;
        while j + 1 < order.len() && v[order[j + 1]].abs() == v[order[i]].abs() {
            j += 1;
        }
        // ranks i + 1 ..= j + 1 shared
        let mean_rank = (i + j + 2) as f64 / 2.0;
        for &k in &order[i..=j] {
            rank[k] = mean_rank;
        }
        i = j + 1;
    }
    let w_plus: f64 = v
        .iter()
        .zip(&rank)
        .map(|(&x, &r)| {
            if x > 0.0 {
                r
            } else if x == 0.0 {
                r / 2.0
            } else {
                0.0
            }
        })
        .sum();
    w_plus <= SIGNED_RANK_8_95
}

/// Model selection by held-out errors: of candidates ordered simplest first (`None`: failed or
/// diverged), the simplest whose errors the lowest-error candidate's do not clearly beat
/// ([`significantly_lower_error`]); the one-standard-error rule (Breiman, Friedman, Olshen and
/// Stone 1984, section 3.4.3) with a test in place of the standard error. All failed: 0.
pub fn simplest_not_clearly_worse(errors: &[Option<Vec<f64>>]) -> usize {
    simplest_kept(errors, |lowest, e| !significantly_lower_error(lowest, e))
}

/// Of candidates ordered simplest first (`None`: failed), the simplest whose errors `kept`
/// (the lowest-error candidate's errors, its errors) allows; else the lowest-error one. All
/// failed: 0.
fn simplest_kept(errors: &[Option<Vec<f64>>], kept: impl Fn(&[f64], &[f64]) -> bool) -> usize {
    let Some(best) = (0..errors.len())
        .filter_map(|i| errors[i].as_ref().map(|e| (i, mean_square(e))))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
    else {
        return 0;
    };
    let lowest = errors[best]
        .as_ref()
        .expect("the best candidate has errors");
    (0..best)
        .find(|&i| errors[i].as_ref().is_some_and(|e| kept(lowest, e)))
        .unwrap_or(best)
}

/// The mean squared errors of `a` and of `b` over [`COMPARISON_BATCHES`] contiguous batches of
/// their common length; `None` with fewer than two samples a batch or a non-finite error.
fn batch_mses(a: &[f64], b: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
    let n = a.len().min(b.len());
    let k = COMPARISON_BATCHES;
    if n < 2 * k || !a[..n].iter().chain(&b[..n]).all(|v| v.is_finite()) {
        return None;
    }
    Some((
        batch_mean_squares(&a[..n], k),
        batch_mean_squares(&b[..n], k),
    ))
}

/// The mean squares of `e` over `k` contiguous batches.
fn batch_mean_squares(e: &[f64], k: usize) -> Vec<f64> {
    let n = e.len();
    (0..k)
        .map(|i| mean_square(&e[i * n / k..(i + 1) * n / k]))
        .collect()
}

/// The mean of the squares of `e` (0 for none).
fn mean_square(e: &[f64]) -> f64 {
    e.iter().map(|v| v * v).sum::<f64>() / e.len().max(1) as f64
}

/// The most a candidate's held-out mean squared error may exceed the lowest one's in
/// [`lowest_geometric_mean_error`].
pub const MEAN_ERROR_RATIO: f64 = 2.0;

/// How far, in standard errors of the mean log ratio of batch errors, a simpler candidate may
/// lie above the lowest on a log scale and still be kept in [`lowest_geometric_mean_error`].
pub const LOG_STANDARD_ERRORS: f64 = 0.5;

/// Model selection by held-out errors on a log scale: of candidates ordered simplest first
/// (`None`: failed or diverged) whose mean squared error is at most [`MEAN_ERROR_RATIO`] times
/// the lowest, the one whose mean squared errors over [`COMPARISON_BATCHES`] contiguous
/// batches have the lowest geometric mean, or the simplest one above it by at most
/// [`LOG_STANDARD_ERRORS`] standard errors of the mean log ratio of their batch errors (on
/// fewer than two samples a batch, the lowest mean squared error). All failed: 0.
///
/// Held-out errors span orders of magnitude from batch to batch. A batch where every
/// candidate extrapolates (the first block of a blocked cross-validation) dominates a mean,
/// and a test on 8 batches lacks the power to prefer a candidate that is several times better
/// in all the others; the logarithm weighs each batch by the ratio between candidates (the
/// geometric mean relative error of Armstrong and Collopy 1992). A candidate whose mean is
/// more than twice the lowest errs far in some batch (a level of a validation part the
/// fitting part never held, a free run that drifts off), which a longer test record repeats:
/// it is not kept, however good the other batches. Within half a standard error the simpler
/// is kept (the one-standard-error rule of Breiman et al. 1984, section 3.4.3, on the log
/// scale): plays fitted to a few hundred samples can extrapolate badly where the two tie.
///
/// J. S. Armstrong, F. Collopy, "Error measures for generalizing about forecasting methods:
/// empirical comparisons", Int. J. Forecasting 8(1):69-80, 1992.
pub fn lowest_geometric_mean_error(errors: &[Option<Vec<f64>>]) -> usize {
    // each candidate's log batch mean squared errors (a floor keeps an exact zero finite)
    let log_batches = |e: &[f64]| -> Vec<f64> {
        let k = if e.len() >= 2 * COMPARISON_BATCHES {
            COMPARISON_BATCHES
        } else {
            1
        };
        batch_mean_squares(e, k)
            .into_iter()
            .map(|m| (m + f64::MIN_POSITIVE).ln())
            .collect()
    };
    let valid: Vec<(usize, &[f64])> = errors
        .iter()
        .enumerate()
        .filter_map(|(i, e)| e.as_deref().map(|e| (i, e)))
        .filter(|(_, e)| e.iter().all(|v| v.is_finite()))
        .collect();
    let lowest = valid
        .iter()
        .map(|(_, e)| mean_square(e))
        .fold(f64::INFINITY, f64::min);
    let kept: Vec<(usize, Vec<f64>)> = valid
        .into_iter()
        .filter(|(_, e)| mean_square(e) <= MEAN_ERROR_RATIO * lowest)
        .map(|(i, e)| (i, log_batches(e)))
        .collect();
    // (`min_by` keeps the first of equals)
    let Some((_, best)) = kept.iter().min_by(|a, b| mean(&a.1).total_cmp(&mean(&b.1))) else {
        return 0;
    };
    kept.iter()
        .find(|(_, l)| {
            // mean(d) <= c standard errors of it; one batch: not above
            let d: Vec<f64> = l.iter().zip(best).map(|(x, y)| x - y).collect();
            if d.len() > 1 {
                t_statistic(&d) <= LOG_STANDARD_ERRORS
            } else {
                d[0] <= 0.0
            }
        })
        .map_or(0, |(i, _)| *i)
}

/// Errors `e` scaled by 0.7 in the even batches of `batch` samples and by 1.2 in the odd ones:
/// lower in some batches and higher in others, neither clearly better nor worse (tests).
#[cfg(test)]
pub(crate) fn batches_up_and_down(e: &[f64], batch: usize) -> Vec<f64> {
    e.iter()
        .enumerate()
        .map(|(k, v)| {
            v * if (k / batch).is_multiple_of(2) {
                0.7
            } else {
                1.2
            }
        })
        .collect()
}

/// Whether the mean of the batch values `v` is significantly below zero: one-sided Student t
/// at 5 % with `v.len() - 1` = 7 degrees of freedom (all values equal: their sign).
fn t_below(v: &[f64]) -> bool {
    t_statistic(v) < -T_7_95
}

/// Student's t of the mean of `v` against zero (all values equal: infinite with their sign,
/// 0 when they are 0).
fn t_statistic(v: &[f64]) -> f64 {
    let k = v.len() as f64;
    let m = mean(v);
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0);
    if var == 0.0 {
        return if m == 0.0 { 0.0 } else { m * f64::INFINITY };
    }
    m / (var / k).sqrt()
}

/// The largest magnitude of a signal (0 for an empty one).
pub fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |a, v| a.max(v.abs()))
}

/// The smallest and largest value of a signal ((inf, -inf) for an empty one).
pub fn min_max(x: &[f64]) -> (f64, f64) {
    x.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// The Kolmogorov-Smirnov distance between the empirical distributions of the values of `a`
/// and of `b`: the largest difference of their cumulative shares at any value, 0 (the same
/// shares everywhere) to 1 (no overlap). 0 when either is empty.
pub fn ks_distance(a: &[f64], b: &[f64]) -> f64 {
    if a.is_empty() || b.is_empty() {
        return 0.0;
    }
    let sorted = |x: &[f64]| {
        let mut v = x.to_vec();
        v.sort_unstable_by(f64::total_cmp);
        v
    };
    let (a, b) = (sorted(a), sorted(b));
    let (na, nb) = (a.len() as f64, b.len() as f64);
    let (mut i, mut j, mut d) = (0, 0, 0.0f64);
    while i < a.len() && j < b.len() {
        // every value equal to the smaller one, from both samples, then the shares
        let x = a[i].min(b[j]);
        while i < a.len() && a[i] <= x {
            i += 1;
        }
        while j < b.len() && b[j] <= x {
            j += 1;
        }
        d = d.max((i as f64 / na - j as f64 / nb).abs());
    }
    d
}

/// Peak-to-peak range of a signal.
pub fn ptp(x: &[f64]) -> f64 {
    let (lo, hi) = min_max(x);
    if lo.is_finite() {
        hi - lo
    } else {
        0.0
    }
}

/// Holds of the input: (start, end) index ranges where it stays within 0.1 % of its range for
/// at least 0.5 s and 50 samples.
pub fn holds(u: &[f64], ts: f64) -> Vec<(usize, usize)> {
    let tol = 1e-3 * crate::metrics::ptp(u).max(f64::MIN_POSITIVE);
    let min_len = ((0.5 / ts) as usize).max(50);
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=u.len() {
        if k == u.len() || (u[k] - u[start]).abs() > tol {
            if k - start >= min_len {
                out.push((start, k));
            }
            start = k;
        }
    }
    out
}

/// Pearson correlation of two signals (0 when either is constant).
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let (ma, mb) = (mean(a), mean(b));
    let (mut s, mut sa, mut sb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        s += (x - ma) * (y - mb);
        sa += (x - ma) * (x - ma);
        sb += (y - mb) * (y - mb);
    }
    if sa > 0.0 && sb > 0.0 {
        s / (sa * sb).sqrt()
    } else {
        0.0
    }
}

/// Shoelace area of the (u, y) curve over the ordered samples (closed back to the start),
/// divided by ptp(u) ptp(y): positive for a counter-clockwise loop, about 0 for a memoryless map.
pub fn normalised_loop_area(u: &[f64], y: &[f64]) -> f64 {
    let n = u.len().min(y.len());
    if n < 3 {
        return 0.0;
    }
    let (um, ym) = (mean(u), mean(y));
    let mut a = 0.0;
    for k in 0..n {
        let j = (k + 1) % n;
        a += (u[k] - um) * (y[j] - ym) - (u[j] - um) * (y[k] - ym);
    }
    let b = ptp(&u[..n]) * ptp(&y[..n]);
    if b > 0.0 {
        0.5 * a / b
    } else {
        0.0
    }
}

/// Hysteresis width: over `bins` input bins between the 5th and 95th percentile of u, the mean
/// output on falling input minus the mean on rising input; the largest |difference| divided by
/// ptp(y). About 0 for a memoryless map, 0.1-0.2 for a typical piezo loop.
pub fn branch_gap(u: &[f64], y: &[f64], bins: usize) -> f64 {
    let n = u.len().min(y.len());
    if n < 3 || bins == 0 {
        return 0.0;
    }
    let mut sorted: Vec<f64> = u[..n].to_vec();
    sorted.sort_by(f64::total_cmp);
    let lo = sorted[n / 20];
    let hi = sorted[n - 1 - n / 20];
    if hi <= lo {
        return 0.0;
    }
    let mut rise = vec![(0.0, 0usize); bins];
    let mut fall = vec![(0.0, 0usize); bins];
    for k in 1..n {
        let du = u[k] - u[k - 1];
        if du == 0.0 || u[k] < lo || u[k] > hi {
            continue;
        }
        let b = (((u[k] - lo) / (hi - lo)) * bins as f64).min(bins as f64 - 1.0) as usize;
        let slot = if du > 0.0 { &mut rise[b] } else { &mut fall[b] };
        slot.0 += y[k];
        slot.1 += 1;
    }
    let range = ptp(&y[..n]);
    let gap = rise
        .iter()
        .zip(&fall)
        .filter(|(r, f)| r.1 > 0 && f.1 > 0)
        .map(|(r, f)| (f.0 / f.1 as f64 - r.0 / r.1 as f64).abs())
        .fold(0.0, f64::max);
    if range > 0.0 {
        gap / range
    } else {
        0.0
    }
}

/// Linear-interpolation quantile `q` in [0, 1] of sorted, non-empty values.
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    let x = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let (i, f) = (x.floor() as usize, x - x.floor());
    let j = (i + 1).min(sorted.len() - 1);
    sorted[i] + f * (sorted[j] - sorted[i])
}

/// [`quantile`] of unsorted values, by selection (linear time; `values` is reordered): the
/// same number as sorting first.
pub fn quantile_select(values: &mut [f64], q: f64) -> f64 {
    let x = q.clamp(0.0, 1.0) * (values.len() - 1) as f64;
    let (i, f) = (x.floor() as usize, x - x.floor());
    let (_, &mut lo, rest) = values.select_nth_unstable_by(i, f64::total_cmp);
    let hi = rest.iter().copied().min_by(f64::total_cmp).unwrap_or(lo);
    lo + f * (hi - lo)
}

#[cfg(test)]
mod loop_tests {
    use super::*;

    #[test]
    fn memoryless_map_has_no_loop() {
        let u: Vec<f64> = (0..3000)
            .map(|k| (k as f64 * std::f64::consts::TAU / 1000.0).sin())
            .collect();
        let y: Vec<f64> = u.iter().map(|v| 2.0 * v + v * v * v).collect();
        assert!(normalised_loop_area(&u, &y).abs() < 1e-3);
        assert!(branch_gap(&u, &y, 20) < 0.01);
    }

    #[test]
    fn selection_quantile_is_the_sorted_one() {
        let v: Vec<f64> = (0..1001)
            .map(|k| ((k * 7919) % 1009) as f64 * 0.37 - 3.0)
            .collect();
        let mut sorted = v.clone();
        sorted.sort_by(f64::total_cmp);
        for q in [0.0, 0.01, 0.25, 0.5, 0.7311, 0.99, 1.0] {
            let mut w = v.clone();
            assert_eq!(quantile_select(&mut w, q), quantile(&sorted, q));
        }
    }

    #[test]
    fn lagging_output_has_counter_clockwise_loop() {
        let u: Vec<f64> = (0..6284).map(|k| (k as f64 * 0.001).sin()).collect();
        let y: Vec<f64> = (0..6284).map(|k| (k as f64 * 0.001 - 0.3).sin()).collect();
        assert!(normalised_loop_area(&u, &y) > 0.1);
        assert!(branch_gap(&u, &y, 20) > 0.2);
    }

    #[test]
    fn a_clearly_lower_error_is_significant_a_slightly_lower_one_is_not() {
        let b: Vec<f64> = (0..400).map(|k| (k as f64 * 0.37).sin()).collect();
        let half: Vec<f64> = b.iter().map(|v| 0.5 * v).collect();
        assert!(significantly_lower_error(&half, &b));
        assert!(!significantly_lower_error(&b, &half));
        // lower in one stretch only, equal elsewhere: not significant
        let mut once = b.clone();
        once[..50].iter_mut().for_each(|v| *v *= 0.5);
        assert!(!significantly_lower_error(&once, &b));
        assert!(
            !significantly_lower_error(&half[..10], &b[..10]),
            "too few samples"
        );
    }

    #[test]
    fn a_hundredfold_lower_error_is_significant_however_uneven_the_batches() {
        // the simpler model's error bursts in the last two batches (a free run drifting away)
        let b: Vec<f64> = (0..64)
            .map(|k| (k as f64 * 0.37).sin() * if k >= 48 { 4.0 } else { 0.25 })
            .collect();
        let tiny: Vec<f64> = b.iter().map(|v| 0.01 * v).collect();
        assert!(significantly_lower_error(&tiny, &b));
        assert!(!significantly_lower_error(&b, &tiny));
        // lower in most batches but far worse in one: not clearly lower
        let mut mixed: Vec<f64> = b.iter().map(|v| 0.5 * v).collect();
        mixed[..8].iter_mut().for_each(|v| *v *= 40.0);
        assert!(!significantly_lower_error(&mixed, &b));
    }

    /// Errors of 80 samples (8 batches of 10), and the same with each batch's mean squared
    /// error multiplied by `ratios`.
    fn best_and_scaled(ratios: &[f64; 8]) -> (Vec<f64>, Vec<f64>) {
        let best: Vec<f64> = (0..80).map(|k| 0.01 * (k as f64 * 0.37).sin()).collect();
        let scaled = best
            .iter()
            .enumerate()
            .map(|(k, v)| v * ratios[k / 10].sqrt())
            .collect();
        (best, scaled)
    }

    /// The simpler model a little worse in six batches and run off in the last two (a
    /// development-zoo record: batch MSE ratios 1.4 to 2.3, then 10^4 and 10^5): clearly
    /// worse, though the run-off's spread hides it from both t-tests.
    #[test]
    fn a_run_off_at_the_end_is_clearly_worse() {
        let ratios: [f64; 8] = [1.62, 2.28, 1.71, 1.39, 2.37, 1.44, 1.26e4, 9.2e4];
        let (best, worse) = best_and_scaled(&ratios);
        assert!(significantly_lower_error(&best, &worse));
        assert!(!significantly_lower_error(&worse, &best));
        let l: Vec<f64> = ratios.iter().map(|r| -r.ln()).collect();
        assert!(!t_below(&l), "the t-test alone misses it");
        assert!(signed_rank_below(&l));
        // one batch the other way: 7 of 8 below, and the rank test weighs its size
        let mut one_up = l.clone();
        one_up[7] = 0.3;
        assert!(signed_rank_below(&one_up));
        one_up[7] = 20.0;
        assert!(!signed_rank_below(&one_up));
        assert!(!signed_rank_below(&[0.0; 8]), "equal errors");
    }

    #[test]
    fn the_simplest_candidate_not_clearly_worse_is_chosen() {
        // errors of one size but their own pattern (candidates do not err alike)
        let e = |scale: f64| -> Option<Vec<f64>> {
            let f = 0.3 + scale.fract();
            Some(
                (0..200)
                    .map(|k| scale * ((k as f64 * f).sin() + 0.5 * (k as f64 * 1.37 * f).cos()))
                    .collect(),
            )
        };
        // simplest first: a tenfold error, one a little above the best, the best
        assert_eq!(simplest_not_clearly_worse(&[e(10.0), e(1.02), e(1.0)]), 1);
        // a failed simpler candidate is passed over
        assert_eq!(simplest_not_clearly_worse(&[None, e(3.0), e(1.0)]), 2);
        assert_eq!(simplest_not_clearly_worse(&[e(3.0), None, e(1.0)]), 2);
        assert_eq!(simplest_not_clearly_worse(&[None, None]), 0);
        // the best first stays
        assert_eq!(simplest_not_clearly_worse(&[e(1.0), e(0.2)]), 1);
        assert_eq!(simplest_not_clearly_worse(&[e(0.2), e(1.0)]), 0);
    }

    /// A candidate four times better in seven batches and twelve times worse in one (where
    /// every candidate extrapolates) is the lowest on a log scale, not in mean, and is kept
    /// within twice the lowest mean; equals go to the simpler, failed ones are passed over.
    #[test]
    fn the_lowest_geometric_mean_error_is_chosen() {
        let (even, lower) = best_and_scaled(&[0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 12.0]);
        assert!(mean_square(&lower) > mean_square(&even));
        let (e, l) = (Some(even), Some(lower));
        assert_eq!(lowest_geometric_mean_error(&[e.clone(), l.clone()]), 1);
        assert_eq!(lowest_geometric_mean_error(&[l.clone(), e.clone()]), 0);
        assert_eq!(lowest_geometric_mean_error(&[e.clone(), e.clone()]), 0);
        assert_eq!(
            lowest_geometric_mean_error(&[None, e.clone(), l.clone()]),
            2
        );
        assert_eq!(lowest_geometric_mean_error(&[None, None]), 0);
        // lower in seven batches but over twice the mean: not kept
        let (even, far) = best_and_scaled(&[0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 20.0]);
        assert!(mean_square(&far) > MEAN_ERROR_RATIO * mean_square(&even));
        assert_eq!(lowest_geometric_mean_error(&[Some(even), Some(far)]), 0);
        // a simpler one within half a standard error on the log scale is kept
        let (even, tied) = best_and_scaled(&[0.9, 1.1, 0.9, 1.1, 0.9, 1.1, 0.9, 1.1]);
        let (e, t) = (Some(even), Some(tied));
        assert_eq!(lowest_geometric_mean_error(&[t.clone(), e.clone()]), 0);
        assert_eq!(lowest_geometric_mean_error(&[e, t]), 0);
        // too few samples for batches: the mean squared error
        assert_eq!(
            lowest_geometric_mean_error(&[Some(vec![1.0, 0.0]), Some(vec![0.5, 0.5])]),
            1
        );
    }
}
