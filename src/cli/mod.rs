//! # Command line
//!
//! One file per subcommand, each with its `Args` (clap) and a `run` that returns
//! `anyhow::Result`: the only place where errors of different modules meet.

use clap::{Parser, Subcommand};

pub mod identify;
pub mod predict;
pub mod sweep;

/// Simulate, identify, plot and improve models of hysteretic actuators.
#[derive(Debug, Parser)]
#[command(name = "hystbench", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Identify a record with a NARX-MLP (one-step and free-run scores, model file).
    Identify(identify::IdentifyArgs),
    /// Train a grid of NARX settings in parallel and report them like the source study.
    Sweep(sweep::SweepArgs),
    /// Predict a record with a model file (one-step-ahead or free run).
    Predict(predict::PredictArgs),
}

/// Run one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Identify(a) => identify::run(a),
        Command::Sweep(a) => sweep::run(a),
        Command::Predict(a) => predict::run(a),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_is_consistent() {
        Cli::command().debug_assert();
    }
}
