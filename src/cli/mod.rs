//! # Command line
//!
//! One file per subcommand, each with its `Args` (clap) and a `run` that returns
//! `anyhow::Result`: the only place where errors of different modules meet.

use clap::{Parser, Subcommand};

pub mod compare;
pub mod demo;
pub mod diagnose;
pub mod plot;
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
    /// Compare a model with a record: scores and where it fails.
    Compare(compare::Args),
    /// Which physical effect does the model miss?
    Diagnose(diagnose::Args),
    /// The main job on built-in defaults: simulate the shipped plants and report.
    Demo(demo::Args),
    /// Simulate a plant on a scenario or a recorded input and write a record.
    Simulate(simulate::Args),
    /// Draw a figure (PNG or SVG): loop, time, residual-loop, parity, spectrum, sweep, ladder.
    Plot(plot::PlotArgs),
}

/// Print to standard output, ending with a newline; a closed pipe (`| head`) is not an error.
pub fn print(text: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    let _ = out.write_all(text.as_bytes());
    if !text.ends_with('\n') {
        let _ = out.write_all(b"\n");
    }
    let _ = out.flush();
}

/// Run one parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Compare(a) => compare::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Diagnose(a) => diagnose::run(a),
        Command::Simulate(a) => simulate::run(a),
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
