//! # hystbench
//!
//! Simulate, identify, plot and improve models of hysteretic actuators: piezoelectric stacks,
//! benders and 2-DoF micromanipulators, MR dampers and other hysteretic devices.
//!
//! - [`effect`]: the effect library (hysteresis, creep, dynamics, coupling, viscous, drift,
//!   saturation), one file
//!   per effect and one registry, shared by simulation, grey-box fitting, diagnosis and NARX
//!   features;
//! - [`plant`]: plant specs (`plants/*.json`), their composition and the ODE plants;
//! - [`scenario`]: excitations, sampling, noise, seed and split (`scenarios/*.json`);
//! - [`simulator`]: inputs -> plant -> noise -> record with provenance;
//! - [`narx`]: the NARX-MLP identifier (one-step and free-run prediction, model files);
//! - [`graybox`]: grey-box models, compositions of the effects fitted to a record;
//! - [`diagnose`]: where a model fails and which effect it misses;
//! - [`improve`]: the model-improvement loop (diagnose, add the effect, refit, repeat);
//! - [`compensate`]: inverse compensation, the input that makes a model follow a reference;
//! - [`model`]: any model (plant, grey-box, NARX) behind one trait;
//! - [`plot`]: figures (PNG, SVG): loops, time, residual loops, parity, spectra, sweeps, ladder;
//! - [`data`]: records, CSV in and out, atomic writes;
//! - [`signal`]: FFT and spectra;
//! - [`metrics`]: R^2, RMSE, NRMSE / fit %, max error, loop measures;
//! - [`numeric`]: numerics shared by the modules.
//!
//! The command line (`src/cli/`) belongs to the binary; everything it does is reachable from
//! this library (`docs/library.md`, `examples/simulate_and_fit.rs`).

pub mod benchmark;
pub mod compensate;
pub mod data;
pub mod diagnose;
pub mod effect;
pub mod graybox;
pub mod improve;
pub mod metrics;
pub mod model;
pub mod narx;
pub mod numeric;
pub mod plant;
pub mod plot;
pub mod scenario;
pub mod signal;
pub mod simulator;
pub mod zoo;

/// An error in words as the command line prints it: the whole chain of causes, without
/// repeating a cause that a message already quotes (the Python front raises the same words).
pub fn error_message(e: &anyhow::Error) -> String {
    let mut msg = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !msg.contains(&c) {
            msg = format!("{msg}: {c}");
        }
    }
    msg
}
