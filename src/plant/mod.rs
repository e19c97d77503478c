//! # Plants
//!
//! A plant is a composition of effects with fixed parameters: per output, the sum of its
//! input paths (each a hysteresis operator, with optional path dynamics: direct and cross paths
//! of a multi-DoF actuator), then creep, then dynamics:
//! y_i = D_i[(1 + C_i) sum_j H_ij[u_j]]. An ODE plant (the Bouc-Wen benchmark) is integrated
//! instead. Plant files live in `plants/`; they are checked into a [`Plant`] before use.
//!
//! ## References
//! - M. Rakotondrabe, "Multivariable classical Prandtl-Ishlinskii hysteresis modeling and
//!   compensation and sensorless control of a nonlinear 2-dof piezoactuator", Nonlinear Dyn., 2017.
//! - D. Habineza, M. Rakotondrabe, Y. Le Gorrec, "Bouc-Wen modeling and feedforward control of
//!   multivariable hysteresis in piezoelectric systems", IEEE TCST, 2015.

pub mod builtin;
mod chain;
mod error;
pub mod ode;
mod spec;
mod state;

pub use error::PlantError;
pub use spec::{
    EffectSpecs, OdePlant, OdeSpec, OutputChain, OutputSpec, PathParams, PathSpec, Plant,
    PlantKind, PlantSpec, Units,
};
pub use state::PlantState;
