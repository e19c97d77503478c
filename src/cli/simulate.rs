//! `hystbench simulate`: run a plant on a scenario (or on a recorded input) and write the record
//! with a JSON sidecar.

use anyhow::Context;
use hystbench::data::{IoRecord, OutputGuard};
use hystbench::plant::Plant;
use hystbench::scenario::Scenario;
use hystbench::simulator::{simulate_recorded, simulate_scenario, Simulation};
use std::path::{Path, PathBuf};

/// Simulate a plant and write a synthetic record (CSV + JSON sidecar).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Plant file (plants/*.json).
    #[arg(long)]
    pub plant: PathBuf,
    /// Scenario file (scenarios/*.json).
    #[arg(long, required_unless_present = "input", conflicts_with = "input")]
    pub scenario: Option<PathBuf>,
    /// Drive the plant with the inputs of a recorded CSV instead of a scenario.
    #[arg(long)]
    pub input: Option<PathBuf>,
    /// Columns of --input to use as the plant's inputs, in plant order (default: the plant's
    /// input names, else `u` or `u1,u2…`).
    #[arg(long, value_delimiter = ',', requires = "input")]
    pub input_columns: Vec<String>,
    /// Measurement noise standard deviation with --input (output units).
    #[arg(long, default_value_t = 0.0, requires = "input")]
    pub noise: f64,
    /// Seed for noise and random excitations (overrides the scenario's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Output CSV; the sidecar goes beside it with the extension .json.
    #[arg(long)]
    pub out: PathBuf,
    /// Overwrite existing outputs.
    #[arg(long)]
    pub force: bool,
}

/// The sidecar path of a record: same stem, `.json`.
pub fn sidecar_path(out: &Path) -> PathBuf {
    out.with_extension("json")
}

/// Write a simulation as CSV + sidecar, atomically and together.
pub fn write_simulation(sim: &Simulation, out: &Path, force: bool) -> anyhow::Result<()> {
    let (names, cols) = sim.record.to_columns();
    let side = sidecar_path(out);
    let mut g = OutputGuard::new(force);
    g.stage_csv(out, &names, &cols)?;
    g.stage(
        &side,
        (serde_json::to_string_pretty(&sim.provenance)? + "\n").as_bytes(),
    )?;
    g.commit()?;
    Ok(())
}

pub fn run(a: Args) -> anyhow::Result<()> {
    if a.out.extension().and_then(|e| e.to_str()) == Some("json") {
        anyhow::bail!(
            "{}: the record is CSV; its JSON sidecar is written beside it",
            a.out.display()
        );
    }
    hystbench::data::check_writable(&a.out, a.force)?;
    hystbench::data::check_writable(&sidecar_path(&a.out), a.force)?;
    let plant = Plant::from_file(&a.plant)?;
    let sim = match (&a.scenario, &a.input) {
        (Some(s), _) => {
            let scenario = Scenario::from_file(s)?;
            let columns = 1 + plant.spec.inputs.len() + plant.spec.outputs.len();
            hystbench::data::memory::check(
                s,
                crate::cli::Work::Simulation,
                scenario.spec.samples,
                plant.spec.inputs.len(),
                columns,
            )?;
            simulate_scenario(&plant, &scenario, a.seed)?
        }
        (None, Some(input)) => {
            if !(a.noise.is_finite() && a.noise >= 0.0) {
                anyhow::bail!("--noise {}: must be a finite number >= 0", a.noise);
            }
            let rec = crate::cli::read_data(input)?;
            let cols: Vec<String> = if !a.input_columns.is_empty() {
                a.input_columns.clone()
            } else if plant.inputs.iter().all(|n| rec.names.contains(n)) {
                plant.inputs.clone()
            } else {
                Vec::new()
            };
            let io = IoRecord::from_record(&rec, Some(&cols), None, false)?;
            hystbench::data::memory::check_record(
                input,
                crate::cli::Work::Simulation,
                &io,
                io.len(),
            )?;
            simulate_recorded(&plant, &io, a.noise, a.seed.unwrap_or(0))?
        }
        (None, None) => unreachable!("clap requires --scenario or --input"),
    };
    write_simulation(&sim, &a.out, a.force)
        .with_context(|| format!("writing {}", a.out.display()))?;
    eprintln!(
        "wrote {} ({} samples, {} -> {}) and {}",
        a.out.display(),
        sim.record.len(),
        sim.record.input_names().join(","),
        sim.record.output_names().join(","),
        sidecar_path(&a.out).display()
    );
    Ok(())
}
