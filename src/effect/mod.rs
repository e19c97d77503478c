//! # The effect library
//!
//! Every physical effect of a hysteretic actuator is written once, here, in one file, and serves
//! the plant simulator, the grey-box model, the diagnosis and the NARX features alike
//! (`docs/adding-an-effect.md`). Each effect file has the same shape:
//!
//! - a `…Spec`: the parameters as written in JSON (`plants/*.json`), unchecked ([`Spec`]);
//! - `…Spec::check` turns it into the valid parameter type ([`Params`]), or an [`EffectError`]
//!   that names the field, the value and the rule;
//! - the valid type builds an [`Operator`] for a sampling period: a sampled, stateful map from one
//!   signal to another;
//! - a unit struct implementing [`Effect`]: its place in plant files, its basis bank and
//!   diagnosis sentence, its NARX features, its grey-box term or filter, its record checks.
//!
//! [`registry`] is the one list of effects; nothing outside this folder names one.
//!
//! The core the effect files stand on, and that never imports them: [`basis`] (banks and
//! contexts), [`feature`] (NARX feature definitions), [`fitting`] (grey-box parts), [`spec`]
//! (specs behind trait objects), the [`Effect`] trait. The hysteresis effect's operators live
//! beside it: [`play`], [`prandtl_ishlinskii`], [`bouc_wen`]; [`noise`] is the measurement
//! noise of scenarios (a signal, not a plant effect).
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
pub mod draw;
pub mod drift;
pub mod dynamics;
mod error;
pub mod feature;
pub mod fitting;
pub mod hysteresis;
mod name;
pub mod noise;
pub mod play;
pub mod prandtl_ishlinskii;
pub mod registry;
pub mod saturation;
pub mod spec;
pub mod spencer;
mod traits;
pub mod viscous;

pub use error::EffectError;
pub use feature::{FeatureKind, FeatureSpec};
pub use name::EffectName;
pub use registry::{effects, register};
pub use spec::{EffectParams, EffectSpec, Params, Spec};
pub use traits::{Effect, Slot, StructureView};

/// A sampled operator on one signal with internal state (play states, filter states…).
///
/// `step` takes the input at sample k and returns the output at sample k. An operator is
/// `Clone` (its state copied: the compensator tries inputs on a copy of the plant).
pub trait Operator: OperatorClone {
    /// Back to the initial state.
    fn reset(&mut self);
    /// One sample.
    fn step(&mut self, x: f64) -> f64;
    /// A whole signal from the current state.
    fn apply(&mut self, x: &[f64]) -> Vec<f64> {
        x.iter().map(|&v| self.step(v)).collect()
    }
}

/// A copy of an operator behind a box (implemented for every `Clone` operator).
pub trait OperatorClone {
    fn clone_boxed(&self) -> spec::BoxedOperator;
}

impl<T: Operator + Clone + Send + 'static> OperatorClone for T {
    fn clone_boxed(&self) -> spec::BoxedOperator {
        Box::new(self.clone())
    }
}

impl Clone for spec::BoxedOperator {
    fn clone(&self) -> Self {
        self.clone_boxed()
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
