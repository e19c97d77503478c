//! # Basis banks
//!
//! Each effect offers a bank of basis signals computed from the inputs (and from the model's own
//! prediction, itself a function of the inputs) that spans what the effect would add to a model:
//! play operators for hysteresis, slow first-order states for creep, short lags for dynamics, the
//! other axes for coupling. The diagnosis regresses a residual on each bank and scores it out of
//! sample; the NARX identifier can take the same signals as extra regressors. A bank's signals
//! are computed a block of rows at a time ([`Signal::fill`]): on a long record only the blocks
//! are held, never the bank.
//!
//! ## References
//! - S. A. Billings, S. Chen, M. J. Korenberg, "Identification of MIMO non-linear systems using a
//!   forward-regression orthogonal estimator", Int. J. Control 49(6):2157-2189, 1989 (ranking
//!   regressors by the error they explain).

use super::spec::BoxedOperator;
use super::EffectName;
use std::collections::VecDeque;
use std::ops::Range;

/// What a bank is computed from.
#[derive(Debug, Clone, Copy)]
pub struct BasisContext<'a> {
    /// Every input of the record.
    pub inputs: &'a [&'a [f64]],
    /// Index of the input that drives this output directly (same index, or the only input).
    pub direct: usize,
    /// The model's prediction of this output (or the direct input when there is no model).
    pub prediction: &'a [f64],
    /// Sampling period in seconds.
    pub ts: f64,
}

impl BasisContext<'_> {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.prediction.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.prediction.is_empty()
    }
}

/// A value of the record at a row (random access: the record is held whole; what a bank
/// derives from it is not).
pub type Source<'a> = Box<dyn Fn(usize) -> f64 + Send + Sync + 'a>;

/// One signal of a bank, computed in order a block of rows at a time, so that a long record's
/// bank is never held whole: `source(k)` through a chain of operators (filters, plays, states;
/// each started from its initial state at row 0), delayed by `delay` samples (the first value
/// repeated).
pub struct Signal<'a> {
    source: Source<'a>,
    ops: Vec<BoxedOperator>,
    delay: usize,
    /// The last `delay + 1` values before the delay.
    history: VecDeque<f64>,
    /// The next row `fill` expects.
    next: usize,
}

impl<'a> Signal<'a> {
    /// `source(k)` itself.
    pub fn of(source: impl Fn(usize) -> f64 + Send + Sync + 'a) -> Signal<'a> {
        Signal {
            source: Box::new(source),
            ops: Vec::new(),
            delay: 0,
            history: VecDeque::new(),
            next: 0,
        }
    }

    /// Samples of `x`.
    pub fn samples(x: &'a [f64]) -> Signal<'a> {
        Signal::of(move |k| x[k])
    }

    /// This signal through `op` (after the operators already there).
    pub fn through(mut self, op: BoxedOperator) -> Signal<'a> {
        self.ops.push(op);
        self
    }

    /// This signal delayed by `samples` (the first value repeated: `x[max(k - samples, 0)]`).
    pub fn delayed(mut self, samples: usize) -> Signal<'a> {
        self.delay += samples;
        self
    }

    /// The signal on `rows` into `out` (`out.len() == rows.len()`); rows must follow the
    /// previous call's, from row 0.
    pub fn fill(&mut self, rows: Range<usize>, out: &mut [f64]) {
        assert_eq!(rows.start, self.next, "a bank's rows are computed in order");
        assert_eq!(rows.len(), out.len(), "one value per row");
        self.next = rows.end;
        for (k, o) in rows.zip(out.iter_mut()) {
            let mut v = (self.source)(k);
            for op in &mut self.ops {
                v = op.step(v);
            }
            *o = if self.delay == 0 {
                v
            } else {
                if self.history.len() > self.delay {
                    self.history.pop_front();
                }
                self.history.push_back(v);
                self.history[0]
            };
        }
    }

    /// The signal on rows `0..n` (the whole record; for short records and tests).
    pub fn whole(mut self, n: usize) -> Vec<f64> {
        let mut out = vec![0.0; n];
        self.fill(0..n, &mut out);
        out
    }
}

/// The signals of one effect's bank, each computed when asked ([`Signal::fill`]).
pub struct BasisBank<'a> {
    pub effect: EffectName,
    /// One label per signal (e.g. `play(u, r=4.0)`).
    pub labels: Vec<String>,
    pub signals: Vec<Signal<'a>>,
}

impl<'a> BasisBank<'a> {
    /// An empty bank for `effect`.
    pub fn new(effect: EffectName) -> BasisBank<'a> {
        BasisBank {
            effect,
            labels: Vec::new(),
            signals: Vec::new(),
        }
    }

    /// Add one signal.
    pub fn push(&mut self, label: String, signal: Signal<'a>) {
        self.labels.push(label);
        self.signals.push(signal);
    }

    /// Number of signals.
    pub fn len(&self) -> usize {
        self.signals.len()
    }

    /// True when the bank has no signal.
    pub fn is_empty(&self) -> bool {
        self.signals.is_empty()
    }

    /// Every signal on rows `0..n` (the whole record; for short records and tests).
    pub fn whole(self, n: usize) -> Vec<Vec<f64>> {
        self.signals.into_iter().map(|s| s.whole(n)).collect()
    }
}

/// Thresholds for a play bank over the range of `u`: `m` values spread over (0, ptp/2).
pub fn play_thresholds(u: &[f64], m: usize) -> Vec<f64> {
    let half = 0.5 * crate::metrics::ptp(u);
    (1..=m).map(|i| half * i as f64 / (m + 1) as f64).collect()
}

/// What an effect's diagnosis sentence is written from: one output's residual and the record.
#[derive(Debug, Clone, Copy)]
pub struct EvidenceContext<'a> {
    /// Input names and values of the record.
    pub input_names: &'a [&'a str],
    pub inputs: &'a [&'a [f64]],
    /// Index of the input that drives this output directly.
    pub direct: usize,
    /// The output's name.
    pub output: &'a str,
    /// The residual y - y_hat.
    pub error: &'a [f64],
    /// Sampling period in seconds.
    pub ts: f64,
    /// The output's unit with a leading space (` um`), or "".
    pub unit: &'a str,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_delayed_signal_repeats_its_first_value() {
        let x = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(
            Signal::samples(&x).delayed(2).whole(5),
            [1.0, 1.0, 1.0, 2.0, 3.0]
        );
        assert_eq!(Signal::samples(&x).delayed(0).whole(5), x);
    }

    #[test]
    fn every_bank_in_blocks_is_the_bank_whole() {
        // two inputs (coupling's bank), a prediction with an offset and a few reversals
        let n = 3001;
        let u1: Vec<f64> = (0..n).map(|k| 5.0 * (k as f64 * 0.013).sin()).collect();
        let u2: Vec<f64> = (0..n).map(|k| (k as f64 * 0.031).cos() + 0.2).collect();
        let y: Vec<f64> = (0..n).map(|k| 3.0 + (k as f64 * 0.011).sin()).collect();
        let inputs: [&[f64]; 2] = [&u1, &u2];
        let ctx = BasisContext {
            inputs: &inputs,
            direct: 0,
            prediction: &y,
            ts: 1e-3,
        };
        let mut banks = 0;
        for effect in crate::effect::registry::effects() {
            let (Some(a), Some(b)) = (effect.basis(&ctx), effect.basis(&ctx)) else {
                continue;
            };
            banks += 1;
            let whole = a.whole(n);
            for (j, mut s) in b.signals.into_iter().enumerate() {
                let mut got = vec![0.0; n];
                let mut start = 0;
                for len in [1, 7, 500, 1000, 10_000].iter().cycle() {
                    let end = (start + len).min(n);
                    s.fill(start..end, &mut got[start..end]);
                    start = end;
                    if start == n {
                        break;
                    }
                }
                let same = got
                    .iter()
                    .zip(&whole[j])
                    .all(|(p, q)| p.to_bits() == q.to_bits());
                assert!(same, "{}: signal {j} differs in blocks", effect.name());
            }
        }
        assert!(banks >= 8, "{banks} banks");
    }
}
