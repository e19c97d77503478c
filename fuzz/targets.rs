//! The fuzz targets: each takes any bytes as the text of a user's file, reads it through the
//! library's one reading path and, where that accepts it, goes on as a command would (checks,
//! a short simulation or prediction). A target may return an error; it must never panic, hang
//! or abort. Shared by the fuzzer (`fuzz/main.rs`) and the regression test of the inputs it
//! found (`tests/fuzz_found.rs`).

use hystbench::data::inspect::{screen, Outliers};
use hystbench::data::{parse_csv, IoRecord, Signal};
use hystbench::plant::PlantSpec;
use hystbench::scenario::ScenarioSpec;
use std::path::Path;

/// The targets, by name: `csv` (records), `plant` (plant files), `scenario` (scenario files),
/// `model` (grey-box and NARX model files, and plant files read as models).
pub const TARGETS: &[&str] = &["csv", "plant", "scenario", "model"];

/// Samples of the short drives (a simulation, a prediction) after a file is accepted.
const DRIVE: usize = 64;
/// A scenario longer than this is checked but not generated (the fuzzer's time budget).
const SCENARIO_BUDGET: usize = 20_000;

/// Run `target` on `data`.
pub fn run(target: &str, data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let path = Path::new("fuzz-input");
    match target {
        "csv" => csv(path, &text),
        "plant" => plant(path, &text),
        "scenario" => scenario(path, &text),
        "model" => model(path, &text),
        other => panic!("unknown fuzz target `{other}`; one of {TARGETS:?}"),
    }
}

fn csv(path: &Path, text: &str) {
    let Ok(rec) = parse_csv(path, text) else {
        return;
    };
    let _ = rec.sampling_period();
    let _ = rec.format.notes(&rec.names);
    if let Ok(io) = IoRecord::from_record(&rec, None, None, false) {
        for policy in [Outliers::Refuse, Outliers::Repair] {
            let mut r = rec.clone();
            let _ = screen(&mut r, &io.input_names(), &io.output_names(), policy);
        }
        if !io.is_empty() {
            let _ = io.split_halves();
        }
    }
}

/// A short drive for each input: a sine over the samples.
fn drive(inputs: usize) -> Vec<Vec<f64>> {
    (0..inputs)
        .map(|i| {
            (0..DRIVE)
                .map(|k| (k as f64 * 0.3 + i as f64).sin())
                .collect()
        })
        .collect()
}

fn plant(path: &Path, text: &str) {
    let Ok(spec) = PlantSpec::parse(path, text) else {
        return;
    };
    let Ok(p) = spec.check(path) else {
        return;
    };
    let u = drive(p.inputs.len());
    let refs: Vec<&[f64]> = u.iter().map(Vec::as_slice).collect();
    let _ = p.simulate(&refs, 1e-3);
}

fn scenario(path: &Path, text: &str) {
    let Ok(spec) = ScenarioSpec::parse(path, text) else {
        return;
    };
    let Ok(sc) = spec.check(path) else {
        return;
    };
    if sc.spec.samples <= SCENARIO_BUDGET {
        let _ = sc.inputs(1);
    }
}

fn model(path: &Path, text: &str) {
    let Ok(m) = hystbench::model::parse_model(path, text) else {
        return;
    };
    let u = drive(m.input_names().len());
    let rec = IoRecord {
        path: path.to_path_buf(),
        ts: m.sampling_period().unwrap_or(1e-3),
        t0: 0.0,
        time_name: "t".into(),
        inputs: m
            .input_names()
            .into_iter()
            .zip(u)
            .map(|(name, values)| Signal { name, values })
            .collect(),
        outputs: m
            .output_names()
            .into_iter()
            .map(|name| Signal {
                name,
                values: vec![0.0; DRIVE],
            })
            .collect(),
    };
    let _ = m.predict(&rec);
    let _ = m.outside(&rec);
}
