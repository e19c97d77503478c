//! # Numerics shared by the modules
//!
//! - [`ridge`]: ridge least squares on a few standardised regressors.

pub mod ridge;
