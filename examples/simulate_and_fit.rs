//! The whole loop from Rust: simulate a plant, identify it with a NARX network, fit a grey-box
//! model that lacks an effect, diagnose it, and let the improvement loop add what is missing.
//! `cargo run --release --example simulate_and_fit`; `tests/library_example.rs` runs it in CI.
//! Walked through in `docs/library.md`.

use hystbench::diagnose::{diagnose, DiagnoseOptions};
use hystbench::graybox::GreyBoxConfig;
use hystbench::improve::{improve, ImproveOptions, Progress};
use hystbench::model::Model;
use hystbench::narx::NarxConfig;
use hystbench::plant::Plant;
use hystbench::scenario::Scenario;
use hystbench::simulator::simulate_scenario;
use std::path::Path;

/// What the run found: the NARX free-run test R^2, the effect the diagnosis named, and the
/// improvement ladder's RMS errors.
pub struct Found {
    pub narx_r2: Option<f64>,
    pub missing: Option<hystbench::effect::EffectName>,
    pub ladder: Vec<f64>,
}

pub fn run() -> Result<Found, Box<dyn std::error::Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // 1. simulate: a piezo stack with creep (plants/hidden_creep_piezo.json), 40 s at 1 kHz
    let plant = Plant::from_file(&root.join("plants/hidden_creep_piezo.json"))?;
    let scenario = Scenario::from_file(&root.join("scenarios/hidden_effect_1khz.json"))?;
    let rec = simulate_scenario(&plant, &scenario, None)?.record;
    println!("simulated {} samples of {}", rec.len(), plant.name);

    // 2. identify: a NARX network on the first half of a record of the study's kind (sines;
    //    the record above holds levels in its second half only, which a NARX network trained
    //    on the first half has never seen), free run on the second half
    let study = Scenario::from_file(&root.join("scenarios/seed_1dof.json"))?;
    let (train, test) = simulate_scenario(&plant, &study, None)?
        .record
        .split_halves();
    let narx = NarxConfig::new(train.input_names(), train.output_names()).fit(&train)?;
    let eval = narx.evaluate_split(&train, &test)?;
    println!("NARX free-run test R^2: {:?}", eval[0].r2_fr_test);

    // 3. fit a grey-box model without creep, 4. diagnose it
    let config = GreyBoxConfig::from_effect_list("hysteresis,dynamics")?;
    let start = config.fit(&rec)?;
    let pred = start.predict(&rec)?;
    let d = diagnose(&rec, &pred, &start.effects(), &DiagnoseOptions::default());
    for line in &d.summary {
        println!("diagnosis: {line}");
    }

    // 5. improve: add the missing effect, refit, repeat
    let mut show = |p: Progress| {
        if let Progress::Step {
            step,
            rmse,
            missing,
            ..
        } = p
        {
            println!("step {step}: RMS error {rmse:.4}, missing {missing:?}");
        }
    };
    let ladder = improve(
        Box::new(start),
        config,
        &rec,
        &ImproveOptions::default(),
        &mut show,
    )?;
    for r in &ladder.rungs {
        println!("{:<32} RMS error {:.4}", format!("{:?}", r.effects), r.rmse);
    }
    Ok(Found {
        narx_r2: eval[0].r2_fr_test,
        missing: d.missing,
        ladder: ladder.rungs.iter().map(|r| r.rmse).collect(),
    })
}

#[allow(dead_code)]
fn main() -> Result<(), Box<dyn std::error::Error>> {
    run().map(|_| ())
}
