//! # The region of input space a model was trained on, and where a record leaves it
//!
//! A data-driven model is only known where its training record went. The region keeps, per
//! input, the range of its values and of its rate of change, and for each pair of inputs of a
//! MIMO record the cells of an 8 x 8 grid over the two ranges that the training record visited
//! (the combinations the model has seen). [`InputRegion::outside`] lists, for another record,
//! the samples beyond each: the share, and the first and last sample.

use crate::data::IoRecord;
use serde::{Deserialize, Serialize};

/// Cells per side of the grid of a pair of inputs.
pub const PAIR_BINS: usize = 8;
/// A value beyond the training range by more than this share of the range counts as outside.
pub const RANGE_TOLERANCE: f64 = 0.05;
/// A rate above this multiple of the training record's largest counts as outside.
pub const RATE_TOLERANCE: f64 = 1.25;

/// The training record's region.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputRegion {
    pub inputs: Vec<InputRange>,
    /// Visited cells of each pair of inputs (row-major, `PAIR_BINS` x `PAIR_BINS`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pairs: Vec<PairCells>,
}

/// One input's range and largest rate (units per second).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputRange {
    pub name: String,
    pub min: f64,
    pub max: f64,
    pub max_rate: f64,
}

/// The visited cells of inputs `a` and `b`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairCells {
    pub a: usize,
    pub b: usize,
    pub cells: Vec<bool>,
}

/// Where a record leaves the region: what, the share of its samples, the first and last.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outside {
    pub what: String,
    pub share: f64,
    pub first: usize,
    pub last: usize,
}

impl std::fmt::Display for Outside {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {:.1} % of the samples (samples {}..={})",
            self.what,
            100.0 * self.share,
            self.first,
            self.last
        )
    }
}

fn rates(x: &[f64], ts: f64) -> impl Iterator<Item = f64> + '_ {
    x.windows(2).map(move |w| ((w[1] - w[0]) / ts).abs())
}

fn cell(v: f64, lo: f64, hi: f64) -> usize {
    let r = (hi - lo).max(f64::MIN_POSITIVE);
    (((v - lo) / r * PAIR_BINS as f64).floor().max(0.0) as usize).min(PAIR_BINS - 1)
}

impl InputRegion {
    /// The region of the training records' inputs (all of them together).
    pub fn of(records: &[IoRecord]) -> InputRegion {
        let n_in = records.first().map_or(0, |r| r.inputs.len());
        let inputs: Vec<InputRange> = (0..n_in)
            .map(|j| {
                let mut r = InputRange {
                    name: records[0].inputs[j].name.clone(),
                    min: f64::INFINITY,
                    max: f64::NEG_INFINITY,
                    max_rate: 0.0,
                };
                for rec in records {
                    let x = &rec.inputs[j].values;
                    r.min = x.iter().copied().fold(r.min, f64::min);
                    r.max = x.iter().copied().fold(r.max, f64::max);
                    r.max_rate = rates(x, rec.ts).fold(r.max_rate, f64::max);
                }
                r
            })
            .collect();
        let mut pairs = Vec::new();
        for a in 0..n_in {
            for b in a + 1..n_in {
                let mut cells = vec![false; PAIR_BINS * PAIR_BINS];
                for rec in records {
                    for (x, y) in rec.inputs[a].values.iter().zip(&rec.inputs[b].values) {
                        let i = cell(*x, inputs[a].min, inputs[a].max);
                        let k = cell(*y, inputs[b].min, inputs[b].max);
                        cells[i * PAIR_BINS + k] = true;
                    }
                }
                pairs.push(PairCells { a, b, cells });
            }
        }
        InputRegion { inputs, pairs }
    }

    /// Where `rec` (the same inputs, in order) leaves the region.
    pub fn outside(&self, rec: &IoRecord) -> Vec<Outside> {
        let n = rec.len();
        let mut out = Vec::new();
        let mut report = |what: String, flags: &mut dyn Iterator<Item = (usize, bool)>| {
            let (mut count, mut first, mut last) = (0usize, usize::MAX, 0usize);
            for (k, f) in flags {
                if f {
                    count += 1;
                    first = first.min(k);
                    last = k;
                }
            }
            if count > 0 {
                out.push(Outside {
                    what,
                    share: count as f64 / n.max(1) as f64,
                    first,
                    last,
                });
            }
        };
        for (r, s) in self.inputs.iter().zip(&rec.inputs) {
            let tol = RANGE_TOLERANCE * (r.max - r.min).max(f64::MIN_POSITIVE);
            let (lo, hi) = (r.min - tol, r.max + tol);
            report(
                format!(
                    "input `{}` beyond the training range [{:.4}, {:.4}]",
                    r.name, r.min, r.max
                ),
                &mut s.values.iter().map(|v| !(lo..=hi).contains(v)).enumerate(),
            );
            if r.max_rate > 0.0 {
                report(
                    format!(
                        "input `{}` faster than in training (|du/dt| above {:.4} per s)",
                        r.name,
                        RATE_TOLERANCE * r.max_rate
                    ),
                    &mut rates(&s.values, rec.ts)
                        .map(|v| v > RATE_TOLERANCE * r.max_rate)
                        .enumerate()
                        .map(|(k, f)| (k + 1, f)),
                );
            }
        }
        for p in &self.pairs {
            let (ra, rb) = (&self.inputs[p.a], &self.inputs[p.b]);
            let (xa, xb) = (&rec.inputs[p.a].values, &rec.inputs[p.b].values);
            report(
                format!(
                    "inputs `{}` and `{}` in combinations the training record did not visit",
                    ra.name, rb.name
                ),
                &mut xa
                    .iter()
                    .zip(xb)
                    .map(|(x, y)| {
                        let inside = (ra.min..=ra.max).contains(x) && (rb.min..=rb.max).contains(y);
                        inside
                            && !p.cells
                                [cell(*x, ra.min, ra.max) * PAIR_BINS + cell(*y, rb.min, rb.max)]
                    })
                    .enumerate(),
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Signal;

    fn rec(u: Vec<f64>, v: Vec<f64>) -> IoRecord {
        let n = u.len();
        IoRecord {
            path: "r.csv".into(),
            ts: 0.01,
            t0: 0.0,
            time_name: "t".into(),
            inputs: vec![
                Signal {
                    name: "u1".into(),
                    values: u,
                },
                Signal {
                    name: "u2".into(),
                    values: v,
                },
            ],
            outputs: vec![Signal {
                name: "y".into(),
                values: vec![0.0; n],
            }],
        }
    }

    #[test]
    fn a_doubled_amplitude_a_faster_input_and_a_new_combination_are_reported() {
        let t: Vec<f64> = (0..1000).map(|k| k as f64 * 0.01).collect();
        let s = |a: f64, f: f64, p: f64| -> Vec<f64> {
            t.iter()
                .map(|t| a * (std::f64::consts::TAU * f * t + p).sin())
                .collect()
        };
        // training: u2 follows u1 (the diagonal of the pair's grid)
        let train = rec(s(1.0, 0.5, 0.0), s(1.0, 0.5, 0.0));
        let region = InputRegion::of(std::slice::from_ref(&train));
        assert!(
            region.outside(&train).is_empty(),
            "{:?}",
            region.outside(&train)
        );
        // double amplitude
        let big = region.outside(&rec(s(2.0, 0.5, 0.0), s(1.0, 0.5, 0.0)));
        let amp = big.iter().find(|o| o.what.contains("`u1` beyond")).unwrap();
        assert!(amp.share > 0.3 && amp.share < 0.8, "{amp}");
        // twice as fast
        let fast = region.outside(&rec(s(1.0, 1.0, 0.0), s(1.0, 1.0, 0.0)));
        assert!(fast.iter().any(|o| o.what.contains("faster")), "{fast:?}");
        // opposite phases: combinations never seen
        let anti = region.outside(&rec(s(1.0, 0.5, 0.0), s(-1.0, 0.5, 0.0)));
        assert!(
            anti.iter().any(|o| o.what.contains("combinations")),
            "{anti:?}"
        );
    }
}
