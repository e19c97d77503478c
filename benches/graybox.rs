//! Speed of `fit`: a three-effect grey-box model (hysteresis, creep, dynamics) on 50,000
//! samples (goal: under 10 s). Run with `cargo bench --bench graybox`.

use hystbench::graybox::GreyBoxConfig;
use hystbench::plant::EffectSpecs;
use hystbench::plant::PlantSpec;
use hystbench::scenario::ScenarioSpec;
use hystbench::simulator::simulate_scenario;
use std::path::PathBuf;
use std::time::Instant;

const SCENARIO: &str = r#"{
  "name": "bench_50k", "sampling_period_s": 0.001, "samples": 50000, "noise_std": 0.01, "seed": 9,
  "inputs": [{"concat": [
    {"duration_s": 15.0, "excitation": {"decaying_sine": {"amplitude": 35.0, "frequency_hz": 1.0, "decay_time_s": 7.0}}},
    {"duration_s": 15.0, "excitation": {"staircase": {"levels": [20.0, -10.0, 30.0, -25.0, 5.0], "hold_s": 3.0}}},
    {"duration_s": 20.0, "excitation": {"random_steps": {"amplitude": 30.0, "min_hold_s": 0.05, "max_hold_s": 1.5}}}
  ]}]
}"#;

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let plant_path = root.join("plants/creep_piezo.json");
    let mut spec = PlantSpec::read(&plant_path).unwrap();
    // the creep_piezo chain with a 120 Hz mode, so that 1 kHz sampling resolves it
    if let Some(d) = spec.outputs[0].get_mut::<hystbench::effect::dynamics::DynamicsSpec>() {
        d.natural_frequency_hz = 120.0;
        d.damping_ratio = 0.05;
    }
    let plant = spec.check(&plant_path).unwrap();
    let sp = root.join("scenarios/bench.json");
    let scenario = ScenarioSpec::parse(&sp, SCENARIO)
        .unwrap()
        .check(&sp)
        .unwrap();
    let rec = simulate_scenario(&plant, &scenario, None).unwrap().record;
    println!(
        "fit on {} samples at 1 kHz (threads: {})",
        rec.len(),
        rayon::current_num_threads()
    );
    println!(
        "{:<34} {:>9} {:>12} {:>10} {:>6}",
        "effects", "seconds", "rmse", "r2", "iter"
    );
    for effects in [
        "hysteresis,creep,dynamics",
        "bouc-wen,creep,dynamics",
        "prandtl-ishlinskii,creep,dynamics",
    ] {
        let cfg = GreyBoxConfig::from_effect_list(effects).unwrap();
        let t = Instant::now();
        let m = cfg.fit(&rec).unwrap();
        let s = t.elapsed().as_secs_f64();
        println!(
            "{:<34} {:>9.2} {:>12.4e} {:>10.6} {:>6}{}",
            effects,
            s,
            m.fit.rmse,
            m.fit.r2.unwrap_or(f64::NAN),
            m.fit.iterations,
            if s < 10.0 {
                ""
            } else {
                "  (over the 10 s goal)"
            }
        );
    }
}
