//! Grey-box fitting on noise-free records from the shipped plants (or plants of the same
//! structure): R^2, physical parameters, and the RMS error with and without each effect.
//! Long runs are `#[ignore]`: `cargo test --release --test graybox -- --ignored`.

use hystbench::data::IoRecord;
use hystbench::effect::hysteresis::HysteresisSpec;
use hystbench::graybox::{FittedGreyBox, GreyBoxConfig};
use hystbench::plant::{Plant, PlantSpec};
use hystbench::scenario::{Scenario, ScenarioSpec};
use hystbench::simulator::simulate_scenario;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn plant(name: &str) -> Plant {
    Plant::from_file(&root().join("plants").join(name)).unwrap()
}

/// A plant from a shipped one with its text edited.
fn plant_edited(name: &str, edit: impl Fn(&mut PlantSpec)) -> Plant {
    let p = root().join("plants").join(name);
    let mut spec = PlantSpec::read(&p).unwrap();
    edit(&mut spec);
    spec.check(&p).unwrap()
}

fn scenario(json: &str) -> Scenario {
    let p = root().join("scenarios").join("test.json");
    ScenarioSpec::parse(&p, json).unwrap().check(&p).unwrap()
}

fn record(plant: &Plant, scenario_json: &str) -> IoRecord {
    simulate_scenario(plant, &scenario(scenario_json), None)
        .unwrap()
        .record
}

fn fit(rec: &IoRecord, effects: &str) -> FittedGreyBox {
    let cfg = GreyBoxConfig::from_effect_list(effects).unwrap();
    let t = std::time::Instant::now();
    let m = cfg.fit(rec).unwrap();
    eprintln!(
        "fit {effects:<32} rmse {:.3e} r2 {:?} iterations {} converged {} ({:.2} s) {}",
        m.fit.rmse,
        m.fit.r2,
        m.fit.iterations,
        m.fit.converged,
        t.elapsed().as_secs_f64(),
        m.fit.outputs[0].message
    );
    m
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// 1-DoF at 10 kHz: nested loops (decaying sine) plus small random steps that ring the mode.
const SCENARIO_10K: &str = r#"{
  "name": "test_10k", "sampling_period_s": 0.0001, "samples": 15000, "noise_std": 0.0, "seed": 7,
  "inputs": [{"sum": [
     {"decaying_sine": {"amplitude": 35.0, "frequency_hz": 6.0, "decay_time_s": 0.7}},
     {"random_steps": {"amplitude": 4.0, "min_hold_s": 0.005, "max_hold_s": 0.03}}
  ]}]
}"#;

#[test]
fn bouc_wen_dynamics_recovered() {
    let p = plant("bouc_wen_piezo.json");
    let rec = record(&p, SCENARIO_10K);
    let m = fit(&rec, "bouc-wen,dynamics");
    let r2 = m.fit.r2.unwrap();
    let out = &m.plant.spec.outputs[0];
    eprintln!("{}", serde_json::to_string(out).unwrap());
    assert!(r2 >= 0.9999, "R^2 {r2}");
    let HysteresisSpec::BoucWen(bw) = &out.paths[0].hysteresis else {
        panic!("not Bouc-Wen")
    };
    let d = out.dynamics.unwrap();
    for (name, got, want) in [
        ("d", bw.d, 0.8),
        ("A", bw.a, 0.3),
        ("B", bw.b, 0.02),
        ("Gamma", bw.gamma, 0.01),
        ("f_n", d.natural_frequency_hz, 800.0),
        ("zeta", d.damping_ratio, 0.03),
    ] {
        eprintln!("{name}: {got} vs {want} ({:.3} %)", 100.0 * rel(got, want));
        assert!(rel(got, want) < 0.02, "{name}: {got} vs {want}");
    }
}
