//! # Scenarios
//!
//! What an experiment does to a plant: the excitation of each input, the sampling period, the
//! length, the measurement noise, the seed and the train/test split (`scenarios/*.json`).
//! A scenario file is checked into a [`Scenario`] before any sample is generated.

mod error;
pub mod excitation;

pub use error::ScenarioError;
pub use excitation::{ExcitationSpec, Segment};

use excitation::{Context, Problem};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Noise level: one standard deviation for every output, or one per output (output units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum NoiseLevel {
    All(f64),
    PerOutput(Vec<f64>),
}

impl Default for NoiseLevel {
    fn default() -> Self {
        NoiseLevel::All(0.0)
    }
}

impl NoiseLevel {
    /// The standard deviation for output `i`.
    pub fn std(&self, i: usize) -> f64 {
        match self {
            NoiseLevel::All(s) => *s,
            NoiseLevel::PerOutput(v) => v.get(i).copied().unwrap_or(0.0),
        }
    }
}

/// The longest scenario (11 hours at 10 kHz): a signal of this many samples takes 3.2 GB.
pub const MAX_SAMPLES: usize = 400_000_000;

/// Train/test split in samples (the record is written whole; the split travels in its sidecar).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Split {
    pub train: usize,
    pub test: usize,
}

/// A scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub sampling_period_s: f64,
    pub samples: usize,
    /// One excitation per plant input, in the plant's input order.
    pub inputs: Vec<ExcitationSpec>,
    #[serde(default)]
    pub noise_std: NoiseLevel,
    #[serde(default)]
    pub seed: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub split: Option<Split>,
    /// Periodic steady state: the inputs are one period, the plant runs this many periods from
    /// rest and the record is the last one (the Bouc-Wen benchmark's multisine test).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steady_state_periods: Option<usize>,
}

/// A valid scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    pub spec: ScenarioSpec,
    pub path: PathBuf,
    base_dir: PathBuf,
}

impl ScenarioSpec {
    /// Read a scenario file.
    pub fn read(path: &Path) -> Result<ScenarioSpec, ScenarioError> {
        Self::parse(path, &crate::data::read_json_text(path)?)
    }

    /// Parse scenario JSON; `path` labels the errors.
    pub fn parse(path: &Path, text: &str) -> Result<ScenarioSpec, ScenarioError> {
        Ok(crate::data::parse_json_file(path, text)?)
    }

    /// Check; relative CSV inputs are looked up beside `path`. (Long on purpose: the scenario's
    /// fields checked in file order, one rule each.)
    pub fn check(&self, path: &Path) -> Result<Scenario, ScenarioError> {
        let invalid = |field: &str, value: String, rule: &str| ScenarioError::Invalid {
            path: path.to_path_buf(),
            field: field.to_string(),
            value,
            rule: rule.to_string(),
        };
        let ts = self.sampling_period_s;
        if !(ts.is_finite() && ts > 0.0) {
            return Err(invalid(
                "sampling_period_s",
                ts.to_string(),
                "must be a finite number > 0",
            ));
        }
        if self.samples < 2 {
            return Err(invalid(
                "samples",
                self.samples.to_string(),
                "must be at least 2",
            ));
        }
        if self.samples > MAX_SAMPLES {
            return Err(invalid(
                "samples",
                self.samples.to_string(),
                &format!("must be at most {MAX_SAMPLES} (3.2 GB a signal, several signals in memory at once); simulate a longer experiment as several scenarios, one after the other"),
            ));
        }
        if self.inputs.is_empty() {
            return Err(invalid(
                "inputs",
                "[]".into(),
                "give one excitation per plant input",
            ));
        }
        match &self.noise_std {
            NoiseLevel::All(s) if !(s.is_finite() && *s >= 0.0) => {
                return Err(invalid(
                    "noise_std",
                    s.to_string(),
                    "must be a finite number >= 0",
                ))
            }
            NoiseLevel::PerOutput(v) => {
                for (i, s) in v.iter().enumerate() {
                    if !(s.is_finite() && *s >= 0.0) {
                        return Err(invalid(
                            &format!("noise_std[{i}]"),
                            s.to_string(),
                            "must be a finite number >= 0",
                        ));
                    }
                }
            }
            _ => {}
        }
        if let Some(s) = self.split {
            if s.train + s.test != self.samples || s.train == 0 || s.test == 0 {
                return Err(invalid(
                    "split",
                    format!("{} + {}", s.train, s.test),
                    &format!(
                        "train and test must be > 0 and add up to `samples` = {}",
                        self.samples
                    ),
                ));
            }
        }
        if self.steady_state_periods == Some(0) {
            return Err(invalid(
                "steady_state_periods",
                "0".into(),
                "must be at least 1",
            ));
        }
        let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let ctx = Context {
            ts,
            n: self.samples,
            seed: self.seed,
            base_dir: &base_dir,
        };
        for (i, e) in self.inputs.iter().enumerate() {
            e.check(&format!("inputs[{i}]"), &ctx)
                .map_err(|p| problem(path, p))?;
        }
        Ok(Scenario {
            spec: self.clone(),
            path: path.to_path_buf(),
            base_dir,
        })
    }
}

fn problem(path: &Path, p: Problem) -> ScenarioError {
    if p.too_short {
        let detail = if p.value.is_empty() {
            p.rule
        } else {
            format!("{} = {}: {}", p.field, p.value, p.rule)
        };
        ScenarioError::TooShort {
            path: path.to_path_buf(),
            field: p.field,
            detail,
        }
    } else {
        ScenarioError::Invalid {
            path: path.to_path_buf(),
            field: p.field,
            value: p.value,
            rule: p.rule,
        }
    }
}

impl Scenario {
    /// Read and check a scenario file.
    pub fn from_file(path: &Path) -> Result<Scenario, ScenarioError> {
        ScenarioSpec::read(path)?.check(path)
    }

    /// The input signals, one per plant input, with randomness from `seed`.
    pub fn inputs(&self, seed: u64) -> Result<Vec<Vec<f64>>, ScenarioError> {
        let ctx = Context {
            ts: self.spec.sampling_period_s,
            n: self.spec.samples,
            seed,
            base_dir: &self.base_dir,
        };
        self.spec
            .inputs
            .iter()
            .enumerate()
            .map(|(i, e)| {
                e.generate(&ctx, 1000 + i as u64)
                    .map_err(|p| problem(&self.path, p))
            })
            .collect()
    }
}
