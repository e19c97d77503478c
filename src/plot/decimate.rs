//! Decimation of long records for drawing: keep what can be seen, never a loop's turning points.
//!
//! Two rules, both in time order:
//! 1. **Turning points**: every reversal of an input or output whose swing exceeds a small band
//!    (by default 1/1000 of the signal's range, well under a pixel) is kept. These are the corners
//!    of major and minor loops. If a noisy record has more reversals than the budget allows, the
//!    band is doubled until they fit (the reversals dropped then are noise, smaller than the band).
//! 2. **Min-max buckets** (the "M4" scheme): consecutive samples are grouped into buckets, and in
//!    each bucket the first, the last and the samples holding each signal's minimum and maximum
//!    are kept, so the envelope of what is drawn is that of the full record.
//!
//! ## References
//! - U. Jugel et al., "M4: a visualization-oriented time series data aggregation",
//!   Proc. VLDB Endow. 7(10), 2014, doi:10.14778/2732951.2732953.

use crate::metrics::ptp;
use std::ops::Range;

/// Indices of the reversals of `x` that swing more than `band` (hysteresis-band turning points,
/// as used in rainflow counting), in time order. The first and last samples are not included.
pub fn turning_points(x: &[f64], band: f64) -> Vec<usize> {
    let mut out = Vec::new();
    if x.len() < 3 {
        return out;
    }
    // direction: 0 unknown, +1 rising, -1 falling; `ext` the index of the running extreme
    let mut dir = 0i8;
    let mut ext = 0usize;
    let mut lo = 0usize;
    let mut hi = 0usize;
    for k in 1..x.len() {
        let v = x[k];
        match dir {
            0 => {
                if v < x[lo] {
                    lo = k;
                }
                if v > x[hi] {
                    hi = k;
                }
                if x[hi] - x[lo] > band {
                    // the earlier of the two extremes is a turning point only if it is not the start
                    dir = if hi > lo { 1 } else { -1 };
                    let first = hi.min(lo);
                    if first > 0 {
                        out.push(first);
                    }
                    ext = hi.max(lo);
                }
            }
            1 => {
                if v >= x[ext] {
                    ext = k;
                } else if x[ext] - v > band {
                    out.push(ext);
                    dir = -1;
                    ext = k;
                }
            }
            _ => {
                if v <= x[ext] {
                    ext = k;
                } else if v - x[ext] > band {
                    out.push(ext);
                    dir = 1;
                    ext = k;
                }
            }
        }
    }
    out
}

/// The sample indices to draw of the signals `signals` over `range` (all of the same length), at
/// most about `max_points` of them (turning points may add a few), sorted and unique.
/// Returns every index when the range is short enough.
pub fn decimate(signals: &[&[f64]], range: Range<usize>, max_points: usize) -> Vec<usize> {
    let n = range.len();
    if n <= max_points.max(8) || signals.is_empty() {
        return range.collect();
    }
    let start = range.start;
    // 1. turning points of every signal, band raised until they fit half the budget
    let mut keep: Vec<usize> = Vec::new();
    for s in signals {
        let s = &s[range.clone()];
        let mut band = 1e-3 * ptp(s);
        let budget = max_points / (2 * signals.len());
        let mut tp = turning_points(s, band);
        while tp.len() > budget && band > 0.0 {
            band *= 2.0;
            tp = turning_points(s, band);
        }
        keep.extend(tp.into_iter().map(|k| k + start));
    }
    // 2. min-max buckets on the other half of the budget
    let per_bucket = 2 + 2 * signals.len();
    let buckets = (max_points / 2 / per_bucket).max(1);
    let size = n.div_ceil(buckets);
    let mut b0 = start;
    while b0 < range.end {
        let b1 = (b0 + size).min(range.end);
        keep.push(b0);
        keep.push(b1 - 1);
        for s in signals {
            let (mut imin, mut imax) = (b0, b0);
            for k in b0..b1 {
                if s[k] < s[imin] {
                    imin = k;
                }
                if s[k] > s[imax] {
                    imax = k;
                }
            }
            keep.push(imin);
            keep.push(imax);
        }
        b0 = b1;
    }
    keep.sort_unstable();
    keep.dedup();
    keep
}

/// Every `step`-th index so that about `max_points` remain (for scatter plots, where order does
/// not matter and the density is what the eye reads).
pub fn stride(n: usize, max_points: usize) -> Vec<usize> {
    let step = n.div_ceil(max_points.max(1)).max(1);
    (0..n).step_by(step).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turning_points_of_a_triangle_wave() {
        let x: Vec<f64> = (0..100).map(|k| ((k % 20) as f64 - 10.0).abs()).collect();
        // minima at 10, 30, 50, 70, 90; maxima at 0 (start), 20, 40, 60, 80
        let tp = turning_points(&x, 0.5);
        assert_eq!(tp, vec![10, 20, 30, 40, 50, 60, 70, 80, 90]);
        // a band wider than the swing sees nothing
        assert!(turning_points(&x, 20.0).is_empty());
    }

    #[test]
    fn decimation_keeps_every_minor_loop_corner() {
        // a slow sine with fast minor loops: many reversals per bucket
        let n = 200_000;
        let x: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / n as f64;
                (2.0 * std::f64::consts::PI * 3.0 * t).sin()
                    + 0.1 * (2.0 * std::f64::consts::PI * 400.0 * t).sin()
            })
            .collect();
        let y: Vec<f64> = x.iter().map(|v| v * v).collect();
        let keep = decimate(&[&x, &y], 0..n, 20_000);
        assert!(keep.len() < 25_000, "{}", keep.len());
        assert!(keep.windows(2).all(|w| w[0] < w[1]));
        let tp = turning_points(&x, 1e-3 * 2.2);
        assert!(tp.len() > 700, "{}", tp.len());
        for k in tp {
            assert!(keep.binary_search(&k).is_ok(), "turning point {k} dropped");
        }
        // the global extremes of both signals are kept
        for s in [&x, &y] {
            let imax = (0..n).max_by(|&a, &b| s[a].total_cmp(&s[b])).unwrap();
            let imin = (0..n).min_by(|&a, &b| s[a].total_cmp(&s[b])).unwrap();
            assert!(keep.binary_search(&imax).is_ok() && keep.binary_search(&imin).is_ok());
        }
    }

    #[test]
    fn short_records_are_not_decimated() {
        let x = vec![1.0, 2.0, 3.0];
        assert_eq!(decimate(&[&x], 0..3, 10), vec![0, 1, 2]);
        assert_eq!(stride(10, 5), vec![0, 2, 4, 6, 8]);
    }
}
