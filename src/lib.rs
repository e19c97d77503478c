//! # hystbench
//!
//! Simulate, identify, plot and improve models of hysteretic actuators: piezoelectric stacks,
//! benders and 2-DoF micromanipulators, MR dampers and other hysteretic devices.
//!
//! - [`effect`]: the effect library (hysteresis, creep, dynamics, coupling, noise), written once
//!   and shared by simulation, grey-box fitting, diagnosis and NARX features;
//! - [`plant`]: plant specs (`plants/*.json`) and the simulator;
//! - [`scenario`]: excitations, sampling, noise, seed and split (`scenarios/*.json`);
//! - [`data`]: records, CSV in and out, atomic writes;
//! - [`narx`]: the NARX-MLP identifier (one-step and free-run prediction, model files);
//! - [`metrics`]: R^2, RMSE, NRMSE / fit %, max error.

pub mod data;
pub mod effect;
pub mod metrics;
pub mod narx;
pub mod cli;
