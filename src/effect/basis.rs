//! # Basis banks
//!
//! Each effect offers a bank of basis signals computed from the inputs (and from the model's own
//! prediction, itself a function of the inputs) that spans what the effect would add to a model:
//! play operators for hysteresis, slow first-order states for creep, short lags for dynamics, the
//! other axes for coupling. The diagnosis regresses a residual on each bank and scores it out of
//! sample; the NARX identifier can take the same signals as extra regressors.
//!
//! ## References
//! - S. A. Billings, S. Chen, M. J. Korenberg, "Identification of MIMO non-linear systems using a
//!   forward-regression orthogonal estimator", Int. J. Control 49(6):2157-2189, 1989 (ranking
//!   regressors by the error they explain).

use super::EffectName;

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

/// The signals of one effect's bank.
#[derive(Debug, Clone, PartialEq)]
pub struct BasisBank {
    pub effect: EffectName,
    /// One label per signal (e.g. `play(u, r=4.0)`).
    pub labels: Vec<String>,
    pub signals: Vec<Vec<f64>>,
}

impl BasisBank {
    /// An empty bank for `effect`.
    pub fn new(effect: EffectName) -> BasisBank {
        BasisBank {
            effect,
            labels: Vec::new(),
            signals: Vec::new(),
        }
    }

    /// Add one signal.
    pub fn push(&mut self, label: String, signal: Vec<f64>) {
        self.labels.push(label);
        self.signals.push(signal);
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
