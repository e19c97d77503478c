//! `hystbench demo`: the main job on built-in defaults. It simulates every shipped plant on its
//! default scenario, writes the records with their sidecars, and a short summary, into a folder.

use crate::cli::simulate::write_simulation;
use crate::metrics::{branch_gap, ptp};
use crate::plant::builtin::BUILTIN;
use crate::plant::PlantSpec;
use crate::scenario::ScenarioSpec;
use crate::simulator::simulate_scenario;
use anyhow::Context;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const MARKER: &str = ".hystbench-report";

/// Run the whole story on built-in defaults and write a report folder.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Report folder (made if missing; a folder made by an earlier demo is refreshed).
    #[arg(long, default_value = "hystbench-demo")]
    pub out: PathBuf,
    /// Write into an existing folder that an earlier demo did not make.
    #[arg(long)]
    pub force: bool,
}

/// Make the report folder, refusing a folder of the user's unless forced.
pub fn prepare_report_folder(dir: &Path, force: bool) -> anyhow::Result<()> {
    if dir.exists() {
        let ours = dir.join(MARKER).exists();
        let empty = std::fs::read_dir(dir)
            .map(|mut d| d.next().is_none())
            .unwrap_or(false);
        if !ours && !empty && !force {
            anyhow::bail!(
                "{}: exists and was not made by hystbench; choose another folder or pass --force",
                dir.display()
            );
        }
    } else {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot make {}", dir.display()))?;
    }
    std::fs::write(dir.join(MARKER), "made by hystbench\n")
        .with_context(|| format!("cannot write in {}", dir.display()))?;
    Ok(())
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    prepare_report_folder(&a.out, a.force)?;
    let records = a.out.join("records");
    std::fs::create_dir_all(&records)?;
    let mut md =
        String::from("# hystbench demo\n\n## 1. Simulated plants (known ground truth)\n\n");
    md += "| plant | scenario | samples | sampling | inputs -> outputs | output range | hysteresis width |\n";
    md += "|---|---|---|---|---|---|---|\n";
    eprintln!("1. simulating the shipped plants on their default scenarios");
    for (plant_file, plant_json, scen_file, scen_json) in BUILTIN {
        let ppath = Path::new("plants").join(plant_file);
        let spath = Path::new("scenarios").join(scen_file);
        let plant = PlantSpec::parse(&ppath, plant_json)?.check(&ppath)?;
        let scenario = ScenarioSpec::parse(&spath, scen_json)?.check(&spath)?;
        let sim = simulate_scenario(&plant, &scenario, None)?;
        let out = records.join(format!("{}.csv", plant.name));
        write_simulation(&sim, &out, true)?;
        let r = &sim.record;
        let units = &plant.units;
        let rec = crate::plot::PlotRecord::from_io(plant.name.clone(), r.clone())
            .with_units(&units.input, &units.output);
        crate::plot::report_figures(&rec, &records, &format!("{}_", plant.name), true)?;
        for (o, y) in r.outputs.iter().enumerate() {
            // the direct input of this output (same index, or the only input)
            let u = &r.inputs[o.min(r.inputs.len() - 1)];
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} s | {} -> {} | {:.3} {} | {:.1} % |",
                plant.name,
                scenario.spec.name,
                r.len(),
                r.ts,
                u.name,
                y.name,
                ptp(&y.values),
                units.output,
                100.0 * branch_gap(&u.values, &y.values, 40),
            );
        }
        eprintln!("   {} -> {}", plant.name, out.display());
    }
    md += "\nLoops: `records/<plant>_loop.png`.\n";
    md += "\nHysteresis width: largest gap between the falling and rising branches over 40 input bins, in % of the output range.\n";
    let _ = writeln!(
        md,
        "\nMade by `hystbench demo` {} in {:.1} s.",
        env!("CARGO_PKG_VERSION"),
        t0.elapsed().as_secs_f64()
    );
    let report = a.out.join("README.md");
    crate::data::write_atomic(&report, md.as_bytes(), true)?;
    crate::cli::print(&md);
    crate::cli::print(&format!("report: {}", report.display()));
    Ok(())
}
