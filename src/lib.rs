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
//! - [`metrics`]: R^2, RMSE, NRMSE / fit %, max error;
//! - [`plot`]: figures (PNG, SVG): loops, time, residual loops, parity, spectra, sweeps, ladder.

pub mod cli;
pub mod data;
pub mod diagnose;
pub mod effect;
pub mod metrics;
pub mod model;
pub mod plant;
pub mod plot;
pub mod scenario;
pub mod signal;
pub mod simulator;
