//! # Grey-box models
//!
//! A grey-box model is the simulator's chain with free parameters: per output i,
//! y_i = D_i[(1 + C_i) sum_j H_ij[u_j]] + offset_i, where H_ij is a hysteresis operator
//! (Prandtl-Ishlinskii by default, Bouc-Wen on request, a linear gain without `hysteresis`),
//! C_i a Kelvin-Voigt creep chain and D_i a second-order mode. Without `coupling` output i
//! sees only input i; with it, every input. The fitted model is a [`PlantSpec`](crate::plant::PlantSpec)
//! and is simulated by exactly the plant code.
//!
//! The fitter names no effect: each effect of the library says what it adds (a term on each
//! path, a filter on the output, which inputs drive an output, what the record must show) in
//! its own file ([`crate::effect::fitting`]).
//!
//! - [`GreyBoxConfig`]: the unfitted model (effects, operator, options); `fit` it to a record;
//! - [`FittedGreyBox`]: the fitted model, `simulate`, `save` and `load` (versioned file).
//!
//! Linear-in-parameter parts (path gains, PI weights, Bouc-Wen d and A, offset) are solved by
//! (non-negative) least squares inside a variable projection; the nonlinear parts (f_n, zeta,
//! creep gains, Bouc-Wen B and Gamma) by Levenberg-Marquardt. See `docs/graybox.md`.
//!
//! ## References
//! - K. Kuhnen, "Modeling, identification and compensation of complex hysteretic
//!   nonlinearities: a modified Prandtl-Ishlinskii approach", Eur. J. Control 9(4), 2003.
//! - M. Rakotondrabe, "Bouc-Wen modeling and inverse multiplicative structure to compensate
//!   hysteresis nonlinearity in piezoelectric actuators", IEEE T-ASE 8(2):428-431, 2011.
//! - D. Croft, G. Shedd, S. Devasia, "Creep, hysteresis, and vibration compensation for
//!   piezoactuators", ASME JDSMC 123(1):35-43, 2001.
//! - C. L. Lawson, R. J. Hanson, *Solving Least Squares Problems*, Prentice-Hall, 1974.
//! - G. H. Golub, V. Pereyra, SIAM J. Numer. Anal. 10(2):413-432, 1973.
//! - D. W. Marquardt, J. SIAM 11(2):431-441, 1963; J. J. More, LNM 630:105-116, 1978.

mod config;
mod driver;
mod error;
mod fit;
mod memo;
mod model;
pub mod nnls;
mod validate;

pub use config::{FitOptions, GreyBoxConfig, Selected, CV_FOLDS, RIDGES, STARTS_ROWS};
pub use driver::train_samples;
pub use error::GreyBoxError;
pub use memo::{ByConfig, FitMemo};
pub use model::{
    FirstStageParams, FitSummary, FittedGreyBox, GreyBoxFile, OutputFit, FORMAT, VERSION,
};
pub use validate::{blocks, CrossValidation};
