//! # Numerics shared by the modules
//!
//! - [`ridge`]: ridge least squares on a few standardised regressors;
//! - [`optimize`]: Nelder-Mead (2-D) and golden-section search.

pub mod optimize;
pub mod ridge;
