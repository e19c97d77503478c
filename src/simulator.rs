//! # Simulator
//!
//! The driver that owns an experiment: it generates (or reads) the inputs, runs the plant, adds
//! seeded measurement noise and returns a record together with its provenance (plant, scenario,
//! seed, tool version), so that every file says where it came from.

use crate::data::{DataError, IoRecord, Signal};
use crate::effect::noise::white_noise;
use crate::plant::{Plant, PlantError};
use crate::scenario::{NoiseLevel, Scenario, ScenarioError};
use serde_json::json;

/// What can go wrong in a simulation run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimulateError {
    #[error(transparent)]
    Plant(#[from] PlantError),
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(transparent)]
    Data(#[from] DataError),
    #[error("{path}: the plant has {expected} inputs ({names}) but {found} input columns were selected; name them with --input-columns")]
    InputColumns {
        path: std::path::PathBuf,
        expected: usize,
        found: usize,
        names: String,
    },
}

/// A simulated record and where it came from.
#[derive(Debug, Clone)]
pub struct Simulation {
    pub record: IoRecord,
    /// JSON sidecar: plant, scenario, seed, tool version.
    pub provenance: serde_json::Value,
}

/// Add white Gaussian noise to each output (stream = output index).
fn add_noise(outputs: &mut [Vec<f64>], level: &NoiseLevel, seed: u64) {
    for (i, y) in outputs.iter_mut().enumerate() {
        let s = level.std(i);
        if s > 0.0 {
            let noise = white_noise(y.len(), s, seed, i as u64);
            for (v, e) in y.iter_mut().zip(noise) {
                *v += e;
            }
        }
    }
}

fn make_record(
    plant: &Plant,
    path: &std::path::Path,
    ts: f64,
    t0: f64,
    inputs: Vec<Vec<f64>>,
    outputs: Vec<Vec<f64>>,
) -> IoRecord {
    IoRecord {
        path: path.to_path_buf(),
        ts,
        t0,
        time_name: "t".into(),
        inputs: plant
            .inputs
            .iter()
            .zip(inputs)
            .map(|(n, v)| Signal {
                name: n.clone(),
                values: v,
            })
            .collect(),
        outputs: plant
            .outputs
            .iter()
            .zip(outputs)
            .map(|(n, v)| Signal {
                name: n.clone(),
                values: v,
            })
            .collect(),
    }
}

/// Run a plant on a scenario; `seed` overrides the scenario's seed.
pub fn simulate_scenario(
    plant: &Plant,
    scenario: &Scenario,
    seed: Option<u64>,
) -> Result<Simulation, SimulateError> {
    let spec = &scenario.spec;
    let seed = seed.unwrap_or(spec.seed);
    let inputs = scenario.inputs(seed)?;
    if inputs.len() != plant.inputs.len() {
        return Err(PlantError::InputCount {
            expected: plant.inputs.len(),
            found: inputs.len(),
            names: plant.inputs.join(", "),
        }
        .into());
    }
    let refs: Vec<&[f64]> = inputs.iter().map(Vec::as_slice).collect();
    let ts = spec.sampling_period_s;
    let mut outputs = match spec.steady_state_periods {
        Some(p) => plant.simulate_periodic(&refs, ts, p)?,
        None => plant.simulate(&refs, ts)?,
    };
    add_noise(&mut outputs, &spec.noise_std, seed);
    let provenance = json!({
        "tool": "hystbench",
        "version": env!("CARGO_PKG_VERSION"),
        "plant_file": plant.path,
        "plant": plant.spec,
        "scenario_file": scenario.path,
        "scenario": spec,
        "seed": seed,
        "samples": spec.samples,
        "sampling_period_s": ts,
        "split": spec.split,
    });
    Ok(Simulation {
        record: make_record(plant, &scenario.path, ts, 0.0, inputs, outputs),
        provenance,
    })
}

/// Drive a plant with recorded inputs (the inputs of `rec`, in plant order), adding noise of
/// standard deviation `noise` from `seed`.
pub fn simulate_recorded(
    plant: &Plant,
    rec: &IoRecord,
    noise: f64,
    seed: u64,
) -> Result<Simulation, SimulateError> {
    if rec.inputs.len() != plant.inputs.len() {
        return Err(SimulateError::InputColumns {
            path: rec.path.clone(),
            expected: plant.inputs.len(),
            found: rec.inputs.len(),
            names: plant.inputs.join(", "),
        });
    }
    let refs: Vec<&[f64]> = rec.inputs.iter().map(|s| s.values.as_slice()).collect();
    let mut outputs = plant.simulate(&refs, rec.ts)?;
    add_noise(&mut outputs, &NoiseLevel::All(noise), seed);
    let provenance = json!({
        "tool": "hystbench",
        "version": env!("CARGO_PKG_VERSION"),
        "plant_file": plant.path,
        "plant": plant.spec,
        "input_file": rec.path,
        "input_columns": rec.input_names(),
        "noise_std": noise,
        "seed": seed,
        "samples": rec.len(),
        "sampling_period_s": rec.ts,
    });
    let inputs = rec.inputs.iter().map(|s| s.values.clone()).collect();
    Ok(Simulation {
        record: make_record(plant, &rec.path, rec.ts, rec.t0, inputs, outputs),
        provenance,
    })
}
