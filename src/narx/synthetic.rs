//! # Test records of known plants
//!
//! The shipped plants on the shipped `seed_1dof` / `seed_2dof` scenarios, simulated by the
//! project's simulator (built-in copies of `plants/` and `scenarios/`), for the identifier's
//! tests, benchmarks and examples.

use crate::data::IoRecord;
use crate::plant::builtin::BUILTIN;
use crate::plant::PlantSpec;
use crate::scenario::ScenarioSpec;
use crate::simulator::simulate_scenario;
use std::path::Path;

/// The 1-DoF plants of the `seed_1dof` scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plant1 {
    /// `plants/bouc_wen_piezo.json`: Bouc-Wen piezo with an 800 Hz mode.
    BoucWen,
    /// `plants/prandtl_ishlinskii_piezo.json`: Prandtl-Ishlinskii piezo with the same mode.
    PrandtlIshlinskii,
    /// `plants/creep_piezo.json`: Bouc-Wen with creep (0.1..100 s; 1.5 %/decade) and the mode.
    BoucWenCreep,
}

impl Plant1 {
    /// All of them.
    pub const ALL: [Plant1; 3] = [
        Plant1::BoucWen,
        Plant1::PrandtlIshlinskii,
        Plant1::BoucWenCreep,
    ];

    /// A short name.
    pub fn name(self) -> &'static str {
        match self {
            Plant1::BoucWen => "bouc_wen",
            Plant1::PrandtlIshlinskii => "prandtl_ishlinskii",
            Plant1::BoucWenCreep => "bouc_wen_creep",
        }
    }

    fn file(self) -> &'static str {
        match self {
            Plant1::BoucWen => "bouc_wen_piezo.json",
            Plant1::PrandtlIshlinskii => "prandtl_ishlinskii_piezo.json",
            Plant1::BoucWenCreep => "creep_piezo.json",
        }
    }
}

fn builtin(file: &str) -> (&'static str, &'static str) {
    BUILTIN
        .iter()
        .find(|b| b.0 == file)
        .map(|b| (b.1, b.3))
        .expect("a shipped plant")
}

fn simulate(plant_json: &str, scenario_json: &str, n: Option<usize>, seed: u64) -> IoRecord {
    let p = Path::new("plant.json");
    let plant = PlantSpec::parse(p, plant_json)
        .and_then(|s| s.check(p))
        .expect("shipped plant");
    let s = Path::new("scenario.json");
    let mut spec = ScenarioSpec::parse(s, scenario_json).expect("shipped scenario");
    if let Some(n) = n {
        spec.samples = n;
        spec.split = None;
    }
    let scenario = spec.check(s).expect("valid scenario");
    simulate_scenario(&plant, &scenario, Some(seed))
        .expect("simulation")
        .record
}

/// The `seed_1dof` record of a plant: Ts = 1e-4 s, `n` samples (50,000 in the scenario),
/// 0.01 um of output noise from `seed`.
pub fn seed_1dof(plant: Plant1, n: usize, seed: u64) -> IoRecord {
    let (p, _) = builtin(plant.file());
    let (_, s) = builtin("bouc_wen_piezo.json");
    simulate(p, s, Some(n), seed)
}

/// A broadband record of a 1-DoF plant for identifying a model to compensate with: a 0.9 Hz,
/// 22 V sine under a 0.5-60 Hz random-phase multisine of 5 V RMS, 40,000 samples at 10 kHz,
/// 0.01 um of output noise from `seed` (the compensation tests and bench).
pub fn broadband_1dof(plant: Plant1, seed: u64) -> IoRecord {
    let (p, _) = builtin(plant.file());
    simulate(p, BROADBAND_1DOF, None, seed)
}

const BROADBAND_1DOF: &str = r#"{"name": "broadband_1dof", "sampling_period_s": 0.0001,
    "samples": 40000, "noise_std": 0.01, "seed": 3, "inputs": [{"sum": [
        {"sine": {"amplitude": 22.0, "frequency_hz": 0.9}},
        {"multisine": {"rms": 5.0, "f_min_hz": 0.5, "f_max_hz": 60.0}}]}]}"#;

/// The `seed_2dof` record of the coupled 2-DoF piezo (500 samples, 0.01 um noise from `seed`).
pub fn seed_2dof(seed: u64) -> IoRecord {
    let (p, s) = builtin("piezo_2dof.json");
    simulate(p, s, None, seed)
}
