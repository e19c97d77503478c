//! # Numerics shared by the modules
//!
//! - [`ridge`]: ridge least squares on a few standardised regressors;
//! - [`lm`]: Levenberg-Marquardt for nonlinear least squares;
//! - [`lstsq`]: linear least squares by the normal equations (rows accumulated one at a time);
//! - [`optimize`]: Nelder-Mead (2-D) and golden-section search.

pub mod lm;
pub mod lstsq;
pub mod optimize;
pub mod ridge;
