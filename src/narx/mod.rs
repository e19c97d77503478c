//! # NARX-MLP identification
//!
//! The source study's identifier (one MISO network per output, y(k) = F[y(k-1..k-n),
//! u(k-1..k-n)], F a tanh MLP), made reliable in free run and fast:
//!
//! - [`regressors`]: lags, delay, standardisation; extra exogenous signals (features from the
//!   effect library) enter exactly like inputs;
//! - [`mlp`]: a hand-written network with an optional linear bypass and hidden neurons grouped
//!   by input ([`Interaction`]);
//! - [`kernel`]: batched forward/backward of one-hidden-layer networks (the training hot loop);
//! - [`train`]: RMSProp / Adam one-step training, least-squares output-layer start,
//!   simulation-error training over windows, free run with divergence detection;
//! - [`config`]: the unfitted [`NarxConfig`] (protocol `default` or `study`);
//! - [`settings`]: the settings a user gives (`identify`'s options, Python's `Narx(...)`)
//!   turned into a [`NarxConfig`] in one place;
//! - [`model`]: the fitted [`FittedNarx`], prediction, scores and the versioned model file;
//! - [`state`]: a fitted model stepped one sample at a time (for the compensator);
//! - [`base`]: the grey-box base candidate (a grey-box model alone or under a network on its
//!   residual, chosen per output on the training record's validation part);
//! - [`consensus`]: a short record's base predicts its committee's median at every prediction;
//! - [`synthetic`]: records of known plants from the effect library, for tests and benches.
//!
//! ## References
//! - S. Chen, S. A. Billings, P. M. Grant, Int. J. Control 51(6):1191-1214, 1990.
//! - K. S. Narendra, K. Parthasarathy, IEEE TNN 1(1):4-27, 1990.
//! - A. H. Ribeiro, L. A. Aguirre, Neurocomputing 316:222-231, 2018.

pub mod arx;
pub mod band;
pub mod base;
pub mod config;
pub mod consensus;
mod error;
pub mod fit;
pub mod kernel;
pub mod mlp;
pub mod model;
pub mod region;
pub mod regressors;
pub mod settings;
pub mod state;
pub mod synthetic;
pub mod train;

pub use config::{features_of, Interaction, NarxConfig, OptimizerKind, Protocol, RobustSettings};
pub use error::NarxError;
pub use model::{FittedNarx, Mode, OutputPrediction};
pub use regressors::Lags;
pub use settings::NarxSettings;
pub use state::NarxState;
