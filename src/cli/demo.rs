//! `hystbench demo`: the main job on built-in defaults. It simulates every shipped plant on its
//! default scenario, writes the records with their sidecars, and a short summary, into a folder.

use crate::cli::simulate::write_simulation;
use anyhow::Context;
use hystbench::metrics::{branch_gap, ptp};
use hystbench::plant::builtin::BUILTIN;
use hystbench::plant::PlantSpec;
use hystbench::scenario::ScenarioSpec;
use hystbench::simulator::simulate_scenario;
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
    let mut md = String::from("# hystbench demo\n");
    simulate_plants(&records, &mut md)?;
    identify_records(&records, &mut md)?;
    hidden_effect(&a.out, &records, &mut md)?;
    compensation(&a.out, &mut md)?;
    let _ = writeln!(
        md,
        "\nMade by `hystbench demo` {} in {:.1} s.",
        env!("CARGO_PKG_VERSION"),
        t0.elapsed().as_secs_f64()
    );
    let report = a.out.join("README.md");
    hystbench::data::write_atomic(&report, md.as_bytes(), true)?;
    crate::cli::print(&md);
    crate::cli::print(&format!("report: {}", report.display()));
    Ok(())
}

/// 1. Simulates the shipped plants on their default scenarios into `records` (CSV and figures).
fn simulate_plants(records: &Path, md: &mut String) -> anyhow::Result<()> {
    *md += "\n## 1. Simulated plants (known ground truth)\n\n";
    *md += "| plant | scenario | samples | sampling rate | inputs -> outputs | output range | hysteresis width |\n";
    *md += "|---|---|---|---|---|---|---|\n";
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
        let rec = hystbench::plot::PlotRecord::from_io(plant.name.clone(), r.clone())
            .with_units(&units.input, &units.output);
        hystbench::plot::report_figures(&rec, records, &format!("{}_", plant.name), true)?;
        for (o, y) in r.outputs.iter().enumerate() {
            // the direct input of this output (same index, or the only input)
            let u = &r.inputs[o.min(r.inputs.len() - 1)];
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.0} Hz | {} -> {} | {:.3} {} | {:.1} % |",
                plant.name,
                scenario.spec.name,
                r.len(),
                1.0 / r.ts,
                u.name,
                y.name,
                ptp(&y.values),
                units.output,
                100.0 * branch_gap(&u.values, &y.values, 40),
            );
        }
        eprintln!("   {} -> {}", plant.name, out.display());
    }
    *md += "\nLoops: `records/<plant>_loop.png`.\n";
    *md += "\nHysteresis width: largest gap between the falling and rising branches over 40 input bins, in % of the output range.\n";
    Ok(())
}

/// 2. Identifies the simulated records with the default NARX (first half trains).
fn identify_records(records: &Path, md: &mut String) -> anyhow::Result<()> {
    eprintln!("2. identifying them with the NARX network (default protocol, first half trains, second half tests)");
    *md += "\n## 2. Identification: NARX free run on the test half\n\n";
    *md += "| record | output | one-step R^2 (test) | free-run R^2 (test) | target | met | train time |\n|---|---|---|---|---|---|---|\n";
    for (name, target) in [
        ("bouc_wen_piezo", 0.999),
        ("prandtl_ishlinskii_piezo", 0.999),
        ("prandtl_ishlinskii_asymmetric", 0.999),
        ("piezo_2dof", 0.99),
    ] {
        let rec = crate::cli::read_data(&records.join(format!("{name}.csv")))?;
        let io = hystbench::data::IoRecord::from_record(&rec, None, None, true)?;
        let (train, test) = io.split_halves();
        let t = std::time::Instant::now();
        let model =
            hystbench::narx::NarxConfig::new(io.input_names(), io.output_names()).fit(&train)?;
        let secs = t.elapsed().as_secs_f64();
        for ev in model.evaluate_split(&train, &test)? {
            let fr = ev.r2_fr_test;
            let _ = writeln!(
                md,
                "| {name} | {} | {} | {} | {target} | {} | {secs:.1} s |",
                ev.name,
                ev.r2_osa_test
                    .map_or("undefined".into(), |v| format!("{v:.6}")),
                match (fr, ev.diverged_at_test) {
                    (_, Some(k)) => format!("diverged at sample {k}"),
                    (Some(v), None) => format!("{v:.5}"),
                    (None, None) => "undefined".into(),
                },
                if fr.is_some_and(|v| v >= target) {
                    "yes"
                } else {
                    "no"
                },
            );
        }
    }
    Ok(())
}

/// 3. The hidden-effect loop: a grey-box start without creep, then `improve`.
fn hidden_effect(out: &Path, records: &Path, md: &mut String) -> anyhow::Result<()> {
    eprintln!("3. a record with a hidden effect: compare, diagnose, add it, watch the error fall");
    *md += "\n## 3. A hidden effect: diagnose, add, watch the error fall\n\n";
    let hidden = records.join("hidden_creep_piezo.csv");
    let rec = crate::cli::read_data(&hidden)?;
    let io = hystbench::data::IoRecord::from_record(&rec, None, None, true)?;
    let start =
        hystbench::graybox::GreyBoxConfig::from_effect_list("hysteresis,dynamics")?.fit(&io)?;
    let start_file = out.join("hidden_start_model.json");
    start.save(&start_file, true)?;
    let improve_dir = out.join("improve");
    *md += "The record `records/hidden_creep_piezo.csv` comes from a plant with creep; the starting model is a grey-box fit with hysteresis and dynamics only (`hidden_start_model.json`). `hystbench improve` then diagnoses it, adds what is missing and refits:\n\n";
    crate::cli::improve::run(crate::cli::improve::Args {
        data: hidden,
        screen: crate::cli::ScreenArgs {
            outliers: hystbench::data::inspect::Outliers::Refuse,
        },
        model: start_file,
        out: improve_dir.clone(),
        train_fraction: None,
        max_steps: 3,
        force: true,
        json: false,
        quiet: true,
    })?;
    let ladder = std::fs::read_to_string(improve_dir.join("report.md"))?;
    let table: String = ladder
        .lines()
        .filter(|l| l.starts_with('|'))
        .map(|l| format!("{l}\n"))
        .collect();
    *md += &table;
    *md += "\n![ladder](improve/ladder.png)\n\nFull report: `improve/report.md`.\n";
    Ok(())
}

/// Step 4, compensation: the model `improve` ended with, inverted; the plant (the ground
/// truth) driven with and without it along a reference the record did not contain.
fn compensation(out: &Path, md: &mut String) -> anyhow::Result<()> {
    eprintln!("4. compensation: the improved model's inverse drives the plant along a reference");
    *md += "\n## 4. Compensation: the model inverted, the loop flattened\n\n";
    let dir = out.join("compensation");
    std::fs::create_dir_all(&dir)?;
    // the plant that made the hidden-effect record, as a file for `track`
    let (file, json, _, _) = BUILTIN
        .iter()
        .find(|(f, ..)| f.starts_with("hidden_creep_piezo"))
        .ok_or_else(|| anyhow::anyhow!("the hidden-effect plant is not built in"))?;
    let plant_file = dir.join(file);
    hystbench::data::write_atomic(&plant_file, json.as_bytes(), true)?;
    let plant = PlantSpec::parse(&plant_file, json)?.check(&plant_file)?;
    // the last model of the improvement loop
    let model = (1..=9)
        .rev()
        .map(|k| out.join("improve").join(format!("model_{k}.json")))
        .find(|p| p.exists())
        .unwrap_or_else(|| out.join("hidden_start_model.json"));
    let ts = hystbench::graybox::FittedGreyBox::load(&model)?
        .fit
        .sampling_period_s;
    // 2 s of two sines and a 5 Hz triangle, from rest
    let n = (2.0 / ts).round() as usize;
    let mut csv = format!("t,{}\n", plant.outputs[0]);
    for k in 0..n {
        let t = k as f64 * ts;
        let ramp = 0.5 - 0.5 * (std::f64::consts::PI * (t / 0.2).min(1.0)).cos();
        let tri = 1.0 - 2.0 * (2.0 * (t * 5.0).fract() - 1.0).abs();
        let r = ramp
            * (12.0 * (2.0 * std::f64::consts::PI * 1.5 * t).sin()
                + 4.0 * (2.0 * std::f64::consts::PI * 11.0 * t).sin()
                + 3.0 * tri);
        let _ = writeln!(csv, "{t},{r}");
    }
    let reference = dir.join("reference.csv");
    hystbench::data::write_atomic(&reference, csv.as_bytes(), true)?;
    crate::cli::track::execute(&crate::cli::track::Args {
        plant: plant_file,
        model: model.clone(),
        reference,
        columns: None,
        limits: None,
        out: dir.clone(),
        force: true,
        json: true,
    })?;
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("track.json"))?)?;
    let _ = writeln!(
        md,
        "The model `improve` ended with (`{}`) is inverted sample by sample (`hystbench compensate`), and the plant that made the record is driven along a reference it never saw (`compensation/reference.csv`: 2 s of 1.5 Hz and 11 Hz sines and a 5 Hz triangle), with the compensating input and, for comparison, with the reference divided by the plant's static gain, as a user calibrates it (`hystbench track`):\n",
        model.file_name().map_or(String::new(), |f| f.to_string_lossy().into_owned())
    );
    *md += "| output | uncompensated RMS | compensated RMS | % of the range | smaller by |\n|---|---|---|---|---|\n";
    for o in v["outputs"].as_array().into_iter().flatten() {
        let f = |k: &str, m: &str| o[k][m].as_f64().unwrap_or(f64::NAN);
        let _ = writeln!(
            md,
            "| {} | {:.4} | {:.4} | {:.2} % -> {:.3} % | {:.1}x |",
            o["output"].as_str().unwrap_or(""),
            f("uncompensated", "rms"),
            f("compensated", "rms"),
            f("uncompensated", "rms_percent"),
            f("compensated", "rms_percent"),
            o["ratio"].as_f64().unwrap_or(f64::NAN)
        );
    }
    *md += "\n![output against reference](compensation/loop.png)\n\nFigures and `track.json`: `compensation/`.\n";
    Ok(())
}
