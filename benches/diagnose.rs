//! `diagnose` on 50,000 samples (goal: under 2 s): a creep plant against a model without creep.
//! Run: `cargo bench --bench diagnose`.

use hystbench::diagnose::{diagnose, DiagnoseOptions};
use hystbench::effect::{creep, dynamics, hysteresis};
use hystbench::plant::EffectSpecs;
use hystbench::plant::PlantSpec;
use hystbench::scenario::ScenarioSpec;
use hystbench::simulator::simulate_scenario;
use std::path::Path;
use std::time::Instant;

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let ppath = root.join("plants/creep_piezo.json");
    let truth = PlantSpec::read(&ppath).unwrap();
    let mut spath = ScenarioSpec::read(&root.join("scenarios/creep_steps.json")).unwrap();
    spath.samples = 50_000;
    spath.sampling_period_s = 5e-4;
    spath.split = None;
    spath.inputs = vec![serde_json::from_str(
        r#"{"concat":[{"duration_s":5,"excitation":{"sum":[{"sine":{"amplitude":25,"frequency_hz":0.7}},{"random_steps":{"amplitude":8,"min_hold_s":0.05,"max_hold_s":0.3}}]}},
                     {"duration_s":20,"excitation":{"staircase":{"levels":[20,35,5,-20],"hold_s":5}}}]}"#,
    )
    .unwrap()];
    let sc = spath
        .check(&root.join("scenarios/creep_steps.json"))
        .unwrap();
    let rec = simulate_scenario(&truth.check(&ppath).unwrap(), &sc, None)
        .unwrap()
        .record;
    let mut model = truth.clone();
    model.outputs[0].remove(creep::NAME);
    let model = model.check(&ppath).unwrap();
    let u: Vec<&[f64]> = rec.inputs.iter().map(|s| s.values.as_slice()).collect();
    let pred = model.simulate(&u, rec.ts).unwrap();
    let mut best = f64::MAX;
    let mut missing = None;
    for _ in 0..3 {
        let t0 = Instant::now();
        let d = diagnose(
            &rec,
            &pred,
            &[hysteresis::NAME, dynamics::NAME],
            &DiagnoseOptions::default(),
        );
        best = best.min(t0.elapsed().as_secs_f64());
        missing = d.missing;
    }
    println!("| bench | samples | best of 3 | goal | result |");
    println!("|---|---|---|---|---|");
    println!(
        "| diagnose (creep missing) | {} | {:.3} s | < 2 s | missing = {:?} |",
        rec.len(),
        best,
        missing
    );
}
