//! Helpers shared by the integration tests: `mod common;` in a test file.
#![allow(dead_code)]

use hystbench::data::IoRecord;
use hystbench::plant::PlantSpec;
use hystbench::scenario::{NoiseLevel, ScenarioSpec};
use hystbench::simulator::simulate_scenario;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Run the `hystbench` binary with these arguments (no system fonts, as on a bare machine).
pub fn hystbench(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hystbench"))
        .args(args)
        .env_remove(hystbench::data::memory::AVAILABLE_VARIABLE)
        .env("FONTCONFIG_FILE", "/nonexistent")
        .env("FONTCONFIG_PATH", "/nonexistent")
        .output()
        .expect("run hystbench")
}

/// The command's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// The repository's root (plants/, scenarios/).
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

/// Write a text file into `dir`.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write a test file");
    p
}

/// A record simulated from a plant and a scenario given as JSON text, with measurement noise
/// of standard deviation `noise` on every output.
pub fn record(plant: &str, scenario: &str, noise: f64) -> IoRecord {
    let p = Path::new("test.json");
    let plant = PlantSpec::parse(p, plant).unwrap().check(p).unwrap();
    let mut s = ScenarioSpec::parse(p, scenario).unwrap();
    s.noise_std = NoiseLevel::All(noise);
    simulate_scenario(&plant, &s.check(p).unwrap(), None)
        .unwrap()
        .record
}
