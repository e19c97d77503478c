//! # Numerics shared by the modules
//!
//! - [`ridge`]: ridge least squares on a few standardised regressors;
//! - [`lm`]: Levenberg-Marquardt for nonlinear least squares;
//! - [`lstsq`]: linear least squares by the normal equations (rows accumulated one at a time);
//! - [`gram`]: cross products of long columns by row blocks (a fit's normal equations);
//! - [`optimize`]: Nelder-Mead (2-D) and golden-section search;
//! - [`simd`]: the hot loops compiled for wider vector registers where the processor has them.

pub mod gram;
pub mod lm;
pub mod lstsq;
pub mod optimize;
pub mod ridge;
pub mod simd;
