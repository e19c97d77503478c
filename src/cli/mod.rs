//! # Command line
//!
//! One file per subcommand, each with its `Args` (clap) and a `run` that returns
//! `anyhow::Result`: the only place where errors of different modules meet.

use clap::{Parser, Subcommand};

pub mod demo;
pub mod fit;
pub mod simulate;

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
    /// The main job on built-in defaults: simulate the shipped plants and report.
    Demo(demo::Args),
    /// Simulate a plant on a scenario or a recorded input and write a record.
    Simulate(simulate::Args),
    /// Fit a grey-box model (hysteresis, creep, dynamics, coupling) to a record.
    Fit(fit::Args),
}

/// Run one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Demo(a) => demo::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Fit(a) => fit::run(a),
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
