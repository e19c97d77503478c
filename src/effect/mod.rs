//! # The effect library
//!
//! Every physical effect of a hysteretic actuator is written once, here, and serves the plant
//! simulator, the grey-box model, the diagnosis and the NARX features alike
//! (`docs/adding-an-effect.md`). Each effect file has the same shape:
//!
//! - a `…Spec`: the parameters as written in JSON (`plants/*.json`), unchecked;
//! - `…Spec::check` turns it into the valid parameter type, or an [`EffectError`] that names the
//!   field, the value and the rule;
//! - the valid type builds an [`Operator`] for a sampling period: a sampled, stateful map from one
//!   signal to another.
//!
//! The chain of a plant output is hysteresis -> creep -> dynamics (`DESIGN.md`):
//! w = H[u], w_c = (1 + sum_i g_i/(tau_i s + 1)) w, y = wn^2/(s^2 + 2 zeta wn s + wn^2) w_c.
//!
//! ## References
//! - M. Rakotondrabe, "Bouc-Wen modeling and inverse multiplicative structure to compensate
//!   hysteresis nonlinearity in piezoelectric actuators", IEEE T-ASE 8(2):428-431, 2011.
//! - K. Kuhnen, "Modeling, identification and compensation of complex hysteretic
//!   nonlinearities: a modified Prandtl-Ishlinskii approach", Eur. J. Control 9(4):407-418, 2003.
//! - D. Croft, G. Shedd, S. Devasia, "Creep, hysteresis, and vibration compensation for
//!   piezoactuators", ASME J. Dyn. Syst. Meas. Control 123(1):35-43, 2001.

pub mod basis;
pub mod bouc_wen;
pub mod coupling;
pub mod creep;
pub mod dynamics;
mod error;
pub mod hysteresis;
pub mod noise;
pub mod play;
pub mod prandtl_ishlinskii;
pub mod viscous;

pub use error::EffectError;

use serde::{Deserialize, Serialize};

/// A sampled operator on one signal with internal state (play states, filter states…).
///
/// `step` takes the input at sample k and returns the output at sample k.
pub trait Operator {
    /// Back to the initial state.
    fn reset(&mut self);
    /// One sample.
    fn step(&mut self, x: f64) -> f64;
    /// A whole signal from the current state.
    fn apply(&mut self, x: &[f64]) -> Vec<f64> {
        x.iter().map(|&v| self.step(v)).collect()
    }
}

/// The effects a model can have, by the names the command line uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EffectName {
    Hysteresis,
    Creep,
    Dynamics,
    Coupling,
    Viscous,
}

impl EffectName {
    /// Every effect, in chain order.
    pub const ALL: [EffectName; 5] = [
        EffectName::Hysteresis,
        EffectName::Creep,
        EffectName::Dynamics,
        EffectName::Coupling,
        EffectName::Viscous,
    ];

    /// The command-line name.
    pub fn as_str(self) -> &'static str {
        match self {
            EffectName::Hysteresis => "hysteresis",
            EffectName::Creep => "creep",
            EffectName::Dynamics => "dynamics",
            EffectName::Coupling => "coupling",
            EffectName::Viscous => "viscous",
        }
    }
}

impl std::fmt::Display for EffectName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for EffectName {
    type Err = EffectError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        EffectName::ALL
            .into_iter()
            .find(|e| e.as_str() == s.trim())
            .ok_or_else(|| EffectError::UnknownEffect {
                name: s.to_string(),
                valid: EffectName::ALL.map(|e| e.as_str()).join(", "),
            })
    }
}

/// Check that a parameter is finite; the error names it.
pub(crate) fn finite(field: &str, value: f64) -> Result<f64, EffectError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(EffectError::Invalid {
            field: field.to_string(),
            value,
            rule: "must be a finite number".into(),
        })
    }
}

/// Check that a parameter is finite and positive.
pub(crate) fn positive(field: &str, value: f64) -> Result<f64, EffectError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(EffectError::Invalid {
            field: field.to_string(),
            value,
            rule: "must be a finite number > 0".into(),
        })
    }
}

/// Check that a parameter is finite and not negative.
pub(crate) fn non_negative(field: &str, value: f64) -> Result<f64, EffectError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(EffectError::Invalid {
            field: field.to_string(),
            value,
            rule: "must be a finite number >= 0".into(),
        })
    }
}
