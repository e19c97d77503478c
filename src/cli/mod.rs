//! # Command line
//!
//! One file per subcommand, each with its `Args` (clap) and a `run` that returns
//! `anyhow::Result`: the only place where errors of different modules meet.

use clap::{Parser, Subcommand};
use hystbench::data::inspect::Outliers;
pub use hystbench::data::memory::Work;

pub mod benchmark;
pub mod benchmark_mr;
pub mod compare;
pub mod compensate;
pub mod demo;
pub mod diagnose;
pub mod effects;
pub mod fit;
pub mod identify;
pub mod improve;
pub mod inspect;
pub mod plot;
pub mod predict;
pub mod progress;
pub mod simulate;
pub mod split;
pub mod sweep;
pub mod track;
pub mod zoo;

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
    /// The main job on built-in defaults: simulate, identify, plot, find a hidden effect.
    Demo(demo::Args),
    /// Simulate a plant on a scenario or a recorded input and write a record.
    Simulate(simulate::Args),
    /// Identify a record with a NARX-MLP (one-step and free-run scores, model file).
    Identify(identify::IdentifyArgs),
    /// Train a grid of NARX settings in parallel and report them like the source study.
    Sweep(sweep::SweepArgs),
    /// Predict a record with a model file (one-step-ahead or free run).
    Predict(predict::PredictArgs),
    /// Fit a grey-box model (the effects of the library, free parameters) to a record.
    Fit(fit::Args),
    /// Compare a model with a record: scores and where it fails.
    Compare(compare::Args),
    /// Which physical effect does the model miss?
    Diagnose(diagnose::Args),
    /// Diagnose, add the missing effect, refit, repeat: the ladder of errors.
    Improve(improve::Args),
    /// The feedforward input that makes a model (plant file or grey-box) follow a reference.
    Compensate(compensate::Args),
    /// Drive a plant with and without a model's compensator and compare the tracking errors.
    Track(track::Args),
    /// Draw a figure (PNG or SVG): loop, time, residual-loop, parity, spectrum, sweep, ladder.
    Plot(plot::PlotArgs),
    /// Score the NARX and grey-box models on a benchmark (Bouc-Wen; measured MR damper).
    Benchmark(benchmark::Args),
    /// List the effects of the library (names for fit, identify, plant files).
    Effects(effects::Args),
    /// Cut a record at its time gaps and resample each part onto a uniform grid.
    Split(split::Args),
    /// What a record holds before modelling: spikes, dropouts, clipping, quantisation, gaps,
    /// drift, reversals.
    Inspect(inspect::Args),
    /// Draw random plants from the effect library with a record of each (`zoo score DIR`:
    /// the default identifier against a linear baseline on them).
    Zoo(zoo::Args),
}

/// The command-line parser of a library setting that has `NAMES` and `FromStr` (the library
/// does not depend on clap).
pub fn choice<T>(names: &'static [&'static str]) -> impl clap::builder::TypedValueParser<Value = T>
where
    T: std::str::FromStr<Err = String> + Clone + Send + Sync + 'static,
{
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(names).try_map(|s| s.parse::<T>())
}

/// Warn on standard error where a record leaves the region a model was trained on.
pub fn warn_outside(record: &std::path::Path, outside: &[hystbench::narx::region::Outside]) {
    if outside.is_empty() {
        return;
    }
    eprintln!(
        "warning: {}: the record leaves the region of inputs the model was trained on; its predictions there are extrapolations:",
        record.display()
    );
    for o in outside {
        eprintln!("  - {o}");
    }
}

/// Read a data file through the one reading path, and say on standard error what it accepted
/// beyond a plain CSV (a `;` separator, decimal commas, comments, units).
pub fn read_data(
    path: &std::path::Path,
) -> Result<hystbench::data::Record, hystbench::data::DataError> {
    let rec = hystbench::data::read_csv(path)?;
    let notes = rec.format.notes(&rec.names);
    if !notes.is_empty() {
        eprintln!("note: read {}: {}", path.display(), notes.join("; "));
    }
    Ok(rec)
}

/// What a modelling command does with a record's outliers (the checks of `inspect`).
#[derive(Debug, Clone, clap::Args)]
pub struct ScreenArgs {
    /// Samples far from their neighbours (`hystbench inspect` lists them): `refuse` a record
    /// with gross ones (beyond 10 times a column's range), `repair` them all (each replaced by
    /// the straight line between its good neighbours) or `keep` them.
    #[arg(long, default_value = "refuse", value_parser = choice::<Outliers>(Outliers::NAMES))]
    pub outliers: Outliers,
}

/// Read a record for modelling: the columns `select` picks, after the checks of `inspect`
/// (gross outliers refused, repaired or kept as `outliers` says; what else they find is said on
/// standard error, one line each).
pub fn read_screened(
    path: &std::path::Path,
    outliers: Outliers,
    work: Work,
    select: impl Fn(&hystbench::data::Record) -> anyhow::Result<hystbench::data::IoRecord>,
) -> anyhow::Result<hystbench::data::IoRecord> {
    let (io, s) = hystbench::data::inspect::screened(read_data(path)?, outliers, select)?;
    // a clear error before the work, not an abort in it
    hystbench::data::memory::check_record(path, work, &io, io.len())?;
    for f in &s.findings {
        eprintln!("warning: {}: {}", path.display(), f.summary());
    }
    if s.repaired > 0 {
        eprintln!(
            "note: {}: {} outlier(s) repaired (each replaced by the line between its good neighbours), lines {}",
            path.display(),
            s.repaired,
            s.repaired_lines
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    Ok(io)
}

/// The K-th of N parts of a job (1 <= K <= N): the items (a sweep's settings, a zoo's members)
/// whose position i has i % N = K - 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub k: usize,
    pub n: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("`{s}`: give the part as K/N with 1 <= K <= N, e.g. 2/8");
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (k, n): (usize, usize) = (
            k.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if k == 0 || k > n {
            return Err(bad());
        }
        Ok(Shard { k, n })
    }
}

impl Shard {
    /// Whether item `i` is in this part.
    pub fn holds(&self, i: usize) -> bool {
        i % self.n == self.k - 1
    }

    /// Check that `parts` (each: the file it was read from, the part it is) are every one of
    /// `of` parts once; `hint` says how to make a missing one.
    pub fn check_parts(
        parts: &[(&std::path::Path, Shard)],
        of: usize,
        hint: &str,
    ) -> anyhow::Result<()> {
        let mut seen: Vec<Option<&std::path::Path>> = vec![None; of];
        for &(p, sh) in parts {
            if sh.n != of || sh.k == 0 || sh.k > of {
                anyhow::bail!(
                    "{}: part {}/{} beside parts of {of}: the job was split two ways; keep the parts of one",
                    p.display(),
                    sh.k,
                    sh.n
                );
            }
            if let Some(other) = seen[sh.k - 1].replace(p) {
                anyhow::bail!(
                    "part {}/{of} given twice: {} and {}",
                    sh.k,
                    other.display(),
                    p.display()
                );
            }
        }
        let missing: Vec<String> = (1..=of)
            .filter(|k| seen[k - 1].is_none())
            .map(|k| format!("{k}/{of}"))
            .collect();
        if !missing.is_empty() {
            anyhow::bail!("incomplete: part(s) {} missing; {hint}", missing.join(", "));
        }
        Ok(())
    }
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
        Command::Demo(a) => demo::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Identify(a) => identify::run(a),
        Command::Sweep(a) => sweep::run(a),
        Command::Predict(a) => predict::run(a),
        Command::Fit(a) => fit::run(a),
        Command::Compare(a) => compare::run(a),
        Command::Diagnose(a) => diagnose::run(a),
        Command::Improve(a) => improve::run(a),
        Command::Plot(a) => plot::run(a),
        Command::Benchmark(a) => benchmark::run(a),
        Command::Split(a) => split::run(a),
        Command::Inspect(a) => inspect::run(a),
        Command::Compensate(a) => compensate::run(a),
        Command::Track(a) => track::run(a),
        Command::Effects(a) => effects::run(a),
        Command::Zoo(a) => zoo::run(a),
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
