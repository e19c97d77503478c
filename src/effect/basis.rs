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

/// The bank of `effect`, or `None` when it does not apply (coupling with one input).
pub fn basis_bank(effect: EffectName, ctx: &BasisContext) -> Option<BasisBank> {
    match effect {
        EffectName::Hysteresis => Some(super::hysteresis::basis(ctx)),
        EffectName::Creep => Some(super::creep::basis(ctx)),
        EffectName::Dynamics => Some(super::dynamics::basis(ctx)),
        EffectName::Coupling => super::coupling::basis(ctx),
        EffectName::Viscous => Some(super::viscous::basis(ctx)),
    }
}

/// Thresholds for a play bank over the range of `u`: `m` values spread over (0, ptp/2).
pub fn play_thresholds(u: &[f64], m: usize) -> Vec<f64> {
    let half = 0.5 * crate::metrics::ptp(u);
    (1..=m).map(|i| half * i as f64 / (m + 1) as f64).collect()
}

/// One basis signal as a fixed definition: thresholds, time constants and frequencies are
/// numbers chosen once (from a training record) and stored, so that the same signal is
/// recomputed identically on any other record (a NARX model's extra regressors).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum FeatureSpec {
    /// Play operator of input `input` (index into the record's inputs), state 0 at the start.
    Play { input: usize, threshold: f64 },
    /// First-order (Kelvin-Voigt) state of an input with time constant `tau_s`, starting at the
    /// input's first value (the creep bank's filter).
    FirstOrder { input: usize, tau_s: f64 },
    /// Unit-gain second-order resonator on an input (shifted by its first value, so that a
    /// non-zero start does not ring; the dynamics bank's filter).
    Resonator { input: usize, hz: f64, zeta: f64 },
    /// An input itself.
    Input { index: usize },
    /// The rate of an input, (u(k) - u(k-1)) / Ts, 0 at the start (the viscous bank's signal).
    Rate { input: usize },
}

impl FeatureSpec {
    /// The input this signal is computed from.
    pub fn input(&self) -> usize {
        match *self {
            FeatureSpec::Play { input, .. }
            | FeatureSpec::FirstOrder { input, .. }
            | FeatureSpec::Resonator { input, .. }
            | FeatureSpec::Rate { input } => input,
            FeatureSpec::Input { index } => index,
        }
    }

    /// A short label, e.g. `play(u1, r=4.000)`; `names` are the record's input names.
    pub fn label(&self, names: &[String]) -> String {
        let n = names
            .get(self.input())
            .cloned()
            .unwrap_or_else(|| format!("input{}", self.input()));
        match *self {
            FeatureSpec::Play { threshold, .. } => format!("play({n}, r={threshold:.4})"),
            FeatureSpec::FirstOrder { tau_s, .. } => format!("first_order({n}, tau={tau_s:.4} s)"),
            FeatureSpec::Resonator { hz, zeta, .. } => {
                format!("resonator({n}, {hz:.2} Hz, zeta={zeta})")
            }
            FeatureSpec::Input { .. } => n,
            FeatureSpec::Rate { .. } => format!("rate({n})"),
        }
    }

    /// Check the definition against `n_inputs` inputs; the error says what is wrong.
    pub fn check(&self, n_inputs: usize) -> Result<(), String> {
        if self.input() >= n_inputs {
            return Err(format!(
                "feature {self:?} uses input {} of a record with {n_inputs} inputs",
                self.input()
            ));
        }
        let ok = match *self {
            FeatureSpec::Play { threshold, .. } => threshold.is_finite() && threshold >= 0.0,
            FeatureSpec::FirstOrder { tau_s, .. } => tau_s.is_finite() && tau_s > 0.0,
            FeatureSpec::Resonator { hz, zeta, .. } => {
                hz.is_finite() && hz > 0.0 && zeta.is_finite() && zeta > 0.0
            }
            FeatureSpec::Input { .. } | FeatureSpec::Rate { .. } => true,
        };
        if ok {
            Ok(())
        } else {
            Err(format!(
                "feature {self:?}: parameters must be finite and positive"
            ))
        }
    }

    /// The signal on a record with these inputs and sampling period `ts` (seconds). A resonator
    /// that cannot be discretised at `ts` gives zeros.
    pub fn compute(&self, inputs: &[&[f64]], ts: f64) -> Vec<f64> {
        let u = inputs[self.input()];
        match *self {
            FeatureSpec::Play { threshold, .. } => super::play::play_bank(u, &[threshold])
                .pop()
                .unwrap_or_default(),
            FeatureSpec::FirstOrder { tau_s, .. } => super::creep::kelvin_voigt_state(u, tau_s, ts),
            FeatureSpec::Resonator { hz, zeta, .. } => {
                use super::Operator;
                let d = super::dynamics::Dynamics {
                    natural_frequency_hz: hz,
                    damping_ratio: zeta,
                    dc_gain: 1.0,
                };
                let u0 = u.first().copied().unwrap_or(0.0);
                let shifted: Vec<f64> = u.iter().map(|v| v - u0).collect();
                match d.operator(ts) {
                    Ok(mut op) => op.apply(&shifted),
                    Err(_) => vec![0.0; u.len()],
                }
            }
            FeatureSpec::Input { .. } => u.to_vec(),
            FeatureSpec::Rate { .. } => super::viscous::rate(u, ts),
        }
    }
}

/// Most resonators one input gets as NARX features (the dynamics bank's frequency ladder is
/// thinned evenly to this many).
pub const MAX_RESONATOR_FEATURES: usize = 6;

/// The feature definitions of `effect` for a training record with these inputs and sampling
/// period: the same signals as the effect's bank, computed from the inputs (not from a model's
/// prediction) and with their numbers fixed: for each input, hysteresis gives 8 plays with
/// [`play_thresholds`]; creep first-order states with the creep bank's time constants (one per
/// half decade from 20 samples, at least 0.05 s, up to a third of the record); dynamics
/// resonators (zeta 0.1) from the dynamics bank's ladder (50 / span .. 0.35 / ts, x1.3),
/// thinned to [`MAX_RESONATOR_FEATURES`]; coupling, with two or more inputs, 4 plays of each
/// input (the other axes' hysteresis; the inputs themselves are already NARX regressors).
pub fn feature_specs(effect: EffectName, inputs: &[&[f64]], ts: f64) -> Vec<FeatureSpec> {
    let mut out = Vec::new();
    let n = inputs.first().map_or(0, |u| u.len());
    let span = n as f64 * ts;
    for (j, u) in inputs.iter().enumerate() {
        match effect {
            EffectName::Hysteresis => {
                for r in play_thresholds(u, 8) {
                    out.push(FeatureSpec::Play {
                        input: j,
                        threshold: r,
                    });
                }
            }
            EffectName::Creep => {
                let mut tau = (20.0 * ts).max(0.05);
                while tau <= span / 3.0 {
                    out.push(FeatureSpec::FirstOrder {
                        input: j,
                        tau_s: tau,
                    });
                    tau *= 10f64.sqrt();
                }
            }
            EffectName::Dynamics => {
                let mut fs = Vec::new();
                let mut f = (50.0 / span).max(1.0);
                while f <= 0.35 / ts {
                    fs.push(f);
                    f *= 1.3;
                }
                let m = fs.len().min(MAX_RESONATOR_FEATURES);
                for i in 0..m {
                    let idx = if m > 1 {
                        i * (fs.len() - 1) / (m - 1)
                    } else {
                        0
                    };
                    out.push(FeatureSpec::Resonator {
                        input: j,
                        hz: fs[idx],
                        zeta: 0.1,
                    });
                }
            }
            EffectName::Viscous => out.push(FeatureSpec::Rate { input: j }),
            EffectName::Coupling => {
                if inputs.len() >= 2 {
                    for r in play_thresholds(u, 4) {
                        out.push(FeatureSpec::Play {
                            input: j,
                            threshold: r,
                        });
                    }
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::play::play_bank;
    use super::*;

    #[test]
    fn feature_specs_reuse_the_banks_numbers_and_recompute_identically() {
        let u: Vec<f64> = (0..2000).map(|k| 3.0 * (0.01 * k as f64).sin()).collect();
        let ts = 1e-3;
        let specs = feature_specs(EffectName::Hysteresis, &[&u], ts);
        assert_eq!(specs.len(), 8);
        let ctx = BasisContext {
            inputs: &[&u],
            direct: 0,
            prediction: &u,
            ts,
        };
        let bank = basis_bank(EffectName::Hysteresis, &ctx).unwrap();
        for (s, b) in specs.iter().zip(&bank.signals) {
            assert_eq!(&s.compute(&[&u], ts), b);
        }
        // the definition is fixed: on another record the thresholds stay
        let v: Vec<f64> = u.iter().map(|x| 0.1 * x).collect();
        assert_eq!(
            specs[0].compute(&[&v], ts),
            play_bank(&v, &[specs[0].clone().threshold()])
                .pop()
                .unwrap()
        );
        let creep = feature_specs(EffectName::Creep, &[&u], ts);
        assert!(!creep.is_empty());
        assert!(creep.iter().all(|c| c.check(1).is_ok()));
        assert!(feature_specs(EffectName::Coupling, &[&u], ts).is_empty());
        let dyn_ = feature_specs(EffectName::Dynamics, &[&u], ts);
        assert!(!dyn_.is_empty() && dyn_.len() <= MAX_RESONATOR_FEATURES);
        assert!(dyn_[0].compute(&[&u], ts).iter().all(|x| x.is_finite()));
        // serialisable
        let text = serde_json::to_string(&specs).unwrap();
        let back: Vec<FeatureSpec> = serde_json::from_str(&text).unwrap();
        assert_eq!(back, specs);
        assert!(FeatureSpec::Play {
            input: 1,
            threshold: 1.0
        }
        .check(1)
        .is_err());
    }

    impl FeatureSpec {
        fn threshold(self) -> f64 {
            match self {
                FeatureSpec::Play { threshold, .. } => threshold,
                _ => f64::NAN,
            }
        }
    }
}
