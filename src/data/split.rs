//! # Split and resample a record with gaps
//!
//! Measured records are not always uniformly sampled: loggers pause between runs (gaps) and
//! time-stamp with jitter. Every model here needs one sampling period, so a record is cut at its
//! gaps (steps longer than a number of median steps, [`TimeSteps::GAP`] by default) and each part is resampled by linear
//! interpolation onto the uniform grid of the median step, starting at the part's first stamp.
//!
//! ## References
//! - L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall, 1999,
//!   sec. 14.1 (pre-treatment of data: segments, resampling).

use super::csv::{Record, TimeSteps};
use super::DataError;

/// One uniformly sampled part of a record.
#[derive(Debug, Clone)]
pub struct Part {
    /// CSV lines of the source covered (header = line 1).
    pub lines: (usize, usize),
    /// Source samples in the part.
    pub source_samples: usize,
    /// The resampled columns, in the record's column order (time first as in the source).
    pub columns: Vec<Vec<f64>>,
    /// Largest |step - period| inside the part (s): what the resampling smoothed out.
    pub jitter: f64,
}

/// The record cut at its gaps and resampled: the common period and the parts long enough.
#[derive(Debug, Clone)]
pub struct Split {
    pub period: f64,
    pub steps: TimeSteps,
    pub parts: Vec<Part>,
    /// Parts dropped for having fewer than `min_samples` samples: their CSV line ranges.
    pub dropped: Vec<(usize, usize)>,
}

/// Cut `rec` at its gaps (steps longer than `gap` median steps) and resample each part onto a uniform grid of the median step; parts
/// shorter than `min_samples` are dropped (and listed).
pub fn split_at_gaps(rec: &Record, gap: f64, min_samples: usize) -> Result<Split, DataError> {
    let Some(name) = rec.time_column() else {
        return Err(DataError::NoDefaultColumns {
            path: rec.path.clone(),
            what: "no time column (`t`, `time`, `t_<unit>` or `time_<unit>`) to split at".into(),
            available: rec.names.join(", "),
        });
    };
    let name = name.to_string();
    let ti = rec.names.iter().position(|n| *n == name).unwrap_or(0);
    let t = rec.column(&name)?;
    rec.check_increasing(&name, t)?;
    let steps = TimeSteps::with_gap(t, gap);
    let period = steps.median;
    let mut bounds = vec![0];
    bounds.extend(steps.gaps.iter().map(|&(k, _)| k));
    bounds.push(t.len());
    let mut parts = Vec::new();
    let mut dropped = Vec::new();
    for w in bounds.windows(2) {
        let (a, b) = (w[0], w[1]);
        let lines = (a + 2, b + 1);
        if b - a < min_samples.max(2) || period <= 0.0 {
            dropped.push(lines);
            continue;
        }
        let n_out = ((t[b - 1] - t[a]) / period + 1e-9).floor() as usize + 1;
        let mut columns = vec![Vec::with_capacity(n_out); rec.names.len()];
        let mut j = a;
        for k in 0..n_out {
            let tk = t[a] + k as f64 * period;
            while j + 1 < b - 1 && t[j + 1] <= tk {
                j += 1;
            }
            let (t0, t1) = (t[j], t[(j + 1).min(b - 1)]);
            let f = if t1 > t0 {
                ((tk - t0) / (t1 - t0)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            for (c, col) in rec.columns.iter().enumerate() {
                columns[c].push(if c == ti {
                    tk
                } else {
                    col[j] + f * (col[(j + 1).min(b - 1)] - col[j])
                });
            }
        }
        let jitter = t[a..b]
            .windows(2)
            .map(|w| (w[1] - w[0] - period).abs())
            .fold(0.0, f64::max);
        parts.push(Part {
            lines,
            source_samples: b - a,
            columns,
            jitter,
        });
    }
    Ok(Split {
        period,
        steps,
        parts,
        dropped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn record(t: Vec<f64>) -> Record {
        let y: Vec<f64> = t.iter().map(|v| 2.0 * v + 1.0).collect();
        Record {
            path: PathBuf::from("r.csv"),
            names: vec!["t_s".into(), "y".into()],
            columns: vec![t, y],
            format: Default::default(),
        }
    }

    #[test]
    fn cuts_at_gaps_and_resamples_linear_data_exactly() {
        // 0.00..0.49 with jitter, a 2 s gap, then 3.0..3.49
        let mut t: Vec<f64> = (0..50)
            .map(|k| k as f64 * 0.01 + if k % 3 == 1 { 0.001 } else { 0.0 })
            .collect();
        t.extend((0..50).map(|k| 3.0 + k as f64 * 0.01));
        let s = split_at_gaps(&record(t), TimeSteps::GAP, 20).unwrap();
        assert_eq!(s.parts.len(), 2);
        assert!((s.period - 0.01).abs() < 1e-12);
        assert_eq!(s.parts[0].lines, (2, 51));
        assert_eq!(s.parts[1].lines, (52, 101));
        for p in &s.parts {
            for (tk, yk) in p.columns[0].iter().zip(&p.columns[1]) {
                assert!((yk - (2.0 * tk + 1.0)).abs() < 1e-12);
            }
            let d: Vec<f64> = p.columns[0].windows(2).map(|w| w[1] - w[0]).collect();
            assert!(d.iter().all(|v| (v - 0.01).abs() < 1e-12));
        }
        assert!(s.parts[0].jitter > 0.0009 && s.parts[1].jitter < 1e-9);
    }

    #[test]
    fn short_parts_are_dropped_and_listed() {
        let mut t: Vec<f64> = (0..5).map(|k| k as f64 * 0.01).collect();
        t.extend((0..40).map(|k| 1.0 + k as f64 * 0.01));
        let s = split_at_gaps(&record(t), TimeSteps::GAP, 20).unwrap();
        assert_eq!(s.parts.len(), 1);
        assert_eq!(s.dropped, vec![(2, 6)]);
    }
}
