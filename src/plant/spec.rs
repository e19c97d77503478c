//! Plant files (`plants/*.json`) and their check into valid plants.

use super::PlantError;
use crate::effect::creep::{Creep, CreepSpec};
use crate::effect::dynamics::{Dynamics, DynamicsSpec};
use crate::effect::hysteresis::{Hysteresis, HysteresisSpec};
use crate::effect::viscous::{Viscous, ViscousSpec};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Units of the signals, for labels and reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct Units {
    #[serde(default)]
    pub input: String,
    #[serde(default)]
    pub output: String,
}

/// One path from an input to an output: its hysteresis and, optionally, its own dynamics
/// (cross paths of a 2-DoF cantilever show both modes).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathSpec {
    /// Name of the input (one of the plant's `inputs`).
    pub input: String,
    pub hysteresis: HysteresisSpec,
    /// A term c du/dt added to the path (viscous damping), before the path's dynamics.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub viscous: Option<ViscousSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dynamics: Option<DynamicsSpec>,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// One output: the sum of its paths, then creep, then dynamics, plus a constant offset
/// (a sensor's zero).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    pub name: String,
    pub paths: Vec<PathSpec>,
    /// Added to the output (output units; default 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub offset: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub creep: Option<CreepSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dynamics: Option<DynamicsSpec>,
}

/// A plant file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantSpec {
    pub name: String,
    #[serde(default)]
    pub description: String,
    #[serde(default)]
    pub units: Units,
    /// The scenario the demo runs this plant on (path relative to the plant file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default_scenario: Option<String>,
    /// Input names, in column order (`u`, or `u1`, `u2`…).
    #[serde(default)]
    pub inputs: Vec<String>,
    /// Outputs of a chain plant.
    #[serde(default)]
    pub outputs: Vec<OutputSpec>,
    /// An ODE plant instead of a chain.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ode: Option<OdeSpec>,
}

/// The ODE plants, by name.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum OdeSpec {
    /// Noel & Schoukens' Bouc-Wen benchmark system (`src/plant/ode/`).
    BoucWenBenchmark(super::ode::BoucWenBenchmarkSpec),
}

/// A valid ODE plant.
#[derive(Debug, Clone, PartialEq)]
pub enum OdePlant {
    BoucWenBenchmark(super::ode::BoucWenBenchmark),
}

/// A valid path.
#[derive(Debug, Clone, PartialEq)]
pub struct PathParams {
    pub input: usize,
    pub hysteresis: Hysteresis,
    pub viscous: Option<Viscous>,
    pub dynamics: Option<Dynamics>,
}

/// A valid output chain.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputChain {
    pub name: String,
    pub paths: Vec<PathParams>,
    pub offset: f64,
    pub creep: Option<Creep>,
    pub dynamics: Option<Dynamics>,
}

/// What a plant is made of.
#[derive(Debug, Clone, PartialEq)]
pub enum PlantKind {
    /// hysteresis paths -> creep -> dynamics, per output.
    Chain(Vec<OutputChain>),
    /// An ODE plant with one input and one output.
    Ode(OdePlant),
}

/// A valid plant: only this reaches the simulator.
#[derive(Debug, Clone, PartialEq)]
pub struct Plant {
    pub name: String,
    pub description: String,
    pub units: Units,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    pub kind: PlantKind,
    /// The spec it was checked from (written into every record's sidecar).
    pub spec: PlantSpec,
    /// The file it was read from (labels errors found while simulating).
    pub path: PathBuf,
}

/// Turn a serde_json error into one that names the file, line and column.
pub(crate) fn json_error(path: &Path, e: serde_json::Error) -> PlantError {
    PlantError::Json {
        path: path.to_path_buf(),
        line: e.line(),
        column: e.column(),
        message: e
            .to_string()
            .split(" at line")
            .next()
            .unwrap_or_default()
            .to_string(),
    }
}

impl PlantSpec {
    /// Read a plant file.
    pub fn read(path: &Path) -> Result<PlantSpec, PlantError> {
        let text = std::fs::read_to_string(path).map_err(|source| PlantError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(path, &text)
    }

    /// Parse plant JSON; `path` labels the errors.
    pub fn parse(path: &Path, text: &str) -> Result<PlantSpec, PlantError> {
        serde_json::from_str(text).map_err(|e| json_error(path, e))
    }

    /// Check everything; `path` labels the errors.
    pub fn check(&self, path: &Path) -> Result<Plant, PlantError> {
        let p = || PathBuf::from(path);
        let structure = |field: &str, rule: String| PlantError::Structure {
            path: p(),
            field: field.to_string(),
            rule,
        };
        let effect = |field: String, source| PlantError::Effect {
            path: p(),
            field,
            source,
        };
        if self.inputs.is_empty() {
            return Err(structure(
                "inputs",
                "list the input names, e.g. [\"u\"] or [\"u1\", \"u2\"]".into(),
            ));
        }
        for (i, n) in self.inputs.iter().enumerate() {
            if n.trim().is_empty() || self.inputs[..i].contains(n) {
                return Err(structure(
                    &format!("inputs[{i}]"),
                    format!("`{n}` is empty or repeated"),
                ));
            }
        }
        let kind = match (&self.ode, self.outputs.is_empty()) {
            (Some(_), false) => {
                return Err(structure(
                    "ode",
                    "a plant is either a chain (`outputs`) or an ODE (`ode`), not both".into(),
                ))
            }
            (None, true) => {
                return Err(structure(
                    "outputs",
                    "needs at least one output (or an `ode`)".into(),
                ))
            }
            (Some(OdeSpec::BoucWenBenchmark(ode)), true) => {
                if self.inputs.len() != 1 {
                    return Err(structure(
                        "inputs",
                        "the ODE plant has exactly one input".into(),
                    ));
                }
                PlantKind::Ode(OdePlant::BoucWenBenchmark(
                    ode.check()
                        .map_err(|e| structure("ode.bouc_wen_benchmark", e.to_string()))?,
                ))
            }
            (None, false) => {
                let mut chains = Vec::new();
                for (o, out) in self.outputs.iter().enumerate() {
                    let at = format!("outputs[{o}]");
                    if out.paths.is_empty() {
                        return Err(structure(
                            &format!("{at}.paths"),
                            "needs at least one path".into(),
                        ));
                    }
                    let mut paths = Vec::new();
                    for (k, path) in out.paths.iter().enumerate() {
                        let pat = format!("{at}.paths[{k}]");
                        let input = self
                            .inputs
                            .iter()
                            .position(|n| *n == path.input)
                            .ok_or_else(|| {
                                structure(
                                    &format!("{pat}.input"),
                                    format!(
                                        "`{}` is not one of the inputs: {}",
                                        path.input,
                                        self.inputs.join(", ")
                                    ),
                                )
                            })?;
                        let hysteresis = path
                            .hysteresis
                            .check()
                            .map_err(|e| effect(format!("{pat}.hysteresis"), e))?;
                        let dynamics = path
                            .dynamics
                            .map(|d| d.check())
                            .transpose()
                            .map_err(|e| effect(format!("{pat}.dynamics"), e))?;
                        let viscous = path
                            .viscous
                            .map(|v| v.check())
                            .transpose()
                            .map_err(|e| effect(format!("{pat}.viscous"), e))?;
                        paths.push(PathParams {
                            input,
                            hysteresis,
                            viscous,
                            dynamics,
                        });
                    }
                    let creep = out
                        .creep
                        .as_ref()
                        .map(|c| c.check())
                        .transpose()
                        .map_err(|e| effect(format!("{at}.creep"), e))?;
                    let dynamics = out
                        .dynamics
                        .map(|d| d.check())
                        .transpose()
                        .map_err(|e| effect(format!("{at}.dynamics"), e))?;
                    if self.outputs[..o].iter().any(|x| x.name == out.name)
                        || self.inputs.contains(&out.name)
                    {
                        return Err(structure(
                            &format!("{at}.name"),
                            format!("`{}` is repeated", out.name),
                        ));
                    }
                    if !out.offset.is_finite() {
                        return Err(structure(
                            &format!("{at}.offset"),
                            format!("{} must be a finite number", out.offset),
                        ));
                    }
                    chains.push(OutputChain {
                        name: out.name.clone(),
                        paths,
                        offset: out.offset,
                        creep,
                        dynamics,
                    });
                }
                PlantKind::Chain(chains)
            }
        };
        let outputs = match &kind {
            PlantKind::Chain(c) => c.iter().map(|c| c.name.clone()).collect(),
            PlantKind::Ode(_) => vec!["y".to_string()],
        };
        Ok(Plant {
            name: self.name.clone(),
            description: self.description.clone(),
            units: self.units.clone(),
            inputs: self.inputs.clone(),
            outputs,
            kind,
            spec: self.clone(),
            path: p(),
        })
    }
}

impl Plant {
    /// Read and check a plant file.
    pub fn from_file(path: &Path) -> Result<Plant, PlantError> {
        PlantSpec::read(path)?.check(path)
    }
}
