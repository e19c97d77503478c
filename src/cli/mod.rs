//! # Command line
//!
//! One file per subcommand, each with its `Args` (clap) and a `run` that returns
//! `anyhow::Result`: the only place where errors of different modules meet.

use clap::{Parser, Subcommand};

pub mod plot;

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
    /// Draw a figure (PNG or SVG): loop, time, residual-loop, parity, spectrum, sweep, ladder.
    Plot(plot::PlotArgs),
}

/// Run one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Plot(args) => plot::run(args),
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
