//! The fitted grey-box model and its versioned file.
//!
//! The model is a [`PlantSpec`]: the fitted model is simulated by exactly the plant code, and a
//! model file's `plant` can be read as a plant. The file wraps it with what was fitted and how:
//! `{"format": "hystbench-greybox", "version": 1, "effects": [...], "inputs": [...],
//! "outputs": [...], "plant": {...}, "fit": {...}}`.

use super::{GreyBoxConfig, GreyBoxError, HysteresisOperator};
use crate::data::IoRecord;
use crate::effect::EffectName;
use crate::metrics::Scores;
use crate::plant::{Plant, PlantSpec};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The `format` field of a grey-box model file.
pub const FORMAT: &str = "hystbench-greybox";
/// The file version this code writes and reads.
pub const VERSION: u32 = 1;

/// The scores and the optimiser's state for one output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputFit {
    pub name: String,
    /// Free-run RMSE on the scored samples (output units).
    pub rmse: f64,
    /// R^2 on the scored samples; null for a constant output.
    pub r2: Option<f64>,
    pub nrmse: Option<f64>,
    pub max_error: f64,
    /// RMSE and R^2 on the samples the model was fitted on.
    pub train_rmse: f64,
    pub train_r2: Option<f64>,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    pub converged: bool,
    /// How the optimiser stopped.
    pub message: String,
}

/// How the model was fitted and how well it fits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitSummary {
    /// Mean over outputs of the free-run RMSE on the scored samples.
    pub rmse: f64,
    /// Mean over outputs of R^2 (null if every output is constant).
    pub r2: Option<f64>,
    pub outputs: Vec<OutputFit>,
    /// Total Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// True when every output's fit converged.
    pub converged: bool,
    /// Wall-clock time of the fit.
    pub seconds: f64,
    pub data_file: PathBuf,
    pub sampling_period_s: f64,
    pub samples: usize,
    /// Samples used for fitting (the first ones).
    pub train_samples: usize,
    /// `whole record`, or the held-out samples the scores are on.
    pub scored_on: String,
}

/// A grey-box model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GreyBoxFile {
    pub format: String,
    pub version: u32,
    pub effects: Vec<EffectName>,
    /// The hysteresis operator of the paths, when `hysteresis` is one of the effects.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hysteresis_operator: Option<HysteresisOperator>,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    pub plant: PlantSpec,
    pub fit: FitSummary,
}

/// A fitted grey-box model: a checked plant plus how it was fitted.
#[derive(Debug, Clone, PartialEq)]
pub struct FittedGreyBox {
    pub effects: Vec<EffectName>,
    pub hysteresis_operator: Option<HysteresisOperator>,
    pub plant: Plant,
    pub fit: FitSummary,
}

impl FittedGreyBox {
    /// The unfitted model this one was fitted from (effects and operator, default options):
    /// `model.config().with_effect(EffectName::Creep).fit(&rec)` refits with one more effect.
    pub fn config(&self) -> GreyBoxConfig {
        let has = |e: EffectName| self.effects.contains(&e);
        let mut c = GreyBoxConfig::new(
            if has(EffectName::Hysteresis) {
                Some(
                    self.hysteresis_operator
                        .unwrap_or(HysteresisOperator::Combined),
                )
            } else {
                None
            },
            has(EffectName::Creep),
            has(EffectName::Dynamics),
            has(EffectName::Coupling),
        );
        c.viscous = has(EffectName::Viscous);
        c
    }

    /// Input names, in model order.
    pub fn inputs(&self) -> &[String] {
        &self.plant.inputs
    }

    /// Output names, in model order.
    pub fn outputs(&self) -> &[String] {
        &self.plant.outputs
    }

    /// Free-run simulation of the model's outputs on the record's inputs (picked by name),
    /// from rest, at the record's sampling period.
    pub fn simulate(&self, rec: &IoRecord) -> Result<Vec<Vec<f64>>, GreyBoxError> {
        let mut refs = Vec::new();
        for name in &self.plant.inputs {
            let s = rec
                .inputs
                .iter()
                .chain(&rec.outputs)
                .find(|s| &s.name == name)
                .ok_or_else(|| GreyBoxError::MissingColumn {
                    path: rec.path.clone(),
                    what: "input".into(),
                    name: name.clone(),
                    available: rec.input_names().join(", "),
                })?;
            refs.push(s.values.as_slice());
        }
        Ok(self.plant.simulate(&refs, rec.ts)?)
    }

    /// Scores of the free-run simulation against the record's outputs (by name) on `range`.
    pub fn scores(
        &self,
        rec: &IoRecord,
        range: std::ops::Range<usize>,
    ) -> Result<Vec<Scores>, GreyBoxError> {
        let pred = self.simulate(rec)?;
        self.plant
            .outputs
            .iter()
            .zip(&pred)
            .map(|(name, p)| {
                let m = rec
                    .outputs
                    .iter()
                    .find(|s| &s.name == name)
                    .ok_or_else(|| GreyBoxError::MissingColumn {
                        path: rec.path.clone(),
                        what: "output".into(),
                        name: name.clone(),
                        available: rec.output_names().join(", "),
                    })?;
                Ok(crate::metrics::scores(
                    &m.values[range.clone()],
                    &p[range.clone()],
                ))
            })
            .collect()
    }

    /// The file form.
    pub fn to_file(&self) -> GreyBoxFile {
        GreyBoxFile {
            format: FORMAT.into(),
            version: VERSION,
            effects: self.effects.clone(),
            hysteresis_operator: self.hysteresis_operator,
            inputs: self.plant.inputs.clone(),
            outputs: self.plant.outputs.clone(),
            plant: self.plant.spec.clone(),
            fit: self.fit.clone(),
        }
    }

    /// The model file's text (pretty JSON); refuses non-finite numbers.
    pub fn to_json(&self) -> Result<String, GreyBoxError> {
        let text =
            serde_json::to_string_pretty(&self.to_file()).map_err(|e| GreyBoxError::NonFinite {
                output: self.plant.outputs.join(","),
                what: e.to_string(),
            })?;
        // serde_json writes NaN and infinity as null: refuse a plant with a non-finite number
        let v: serde_json::Value = serde_json::from_str(&text).unwrap_or_default();
        if has_null_number(&v["plant"]) || !self.fit.rmse.is_finite() {
            return Err(GreyBoxError::NonFinite {
                output: self.plant.outputs.join(","),
                what: "a parameter or a score".into(),
            });
        }
        Ok(text + "\n")
    }

    /// Write the model file atomically (never overwrites without `force`).
    pub fn save(&self, path: &Path, force: bool) -> Result<(), GreyBoxError> {
        let text = self.to_json()?;
        crate::data::write_atomic(path, text.as_bytes(), force)?;
        Ok(())
    }

    /// Read and check a model file.
    pub fn load(path: &Path) -> Result<FittedGreyBox, GreyBoxError> {
        let text = std::fs::read_to_string(path).map_err(|source| GreyBoxError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(path, &text)
    }

    /// Parse a model file's text; `path` labels the errors.
    pub fn parse(path: &Path, text: &str) -> Result<FittedGreyBox, GreyBoxError> {
        let json_err = |e: serde_json::Error| GreyBoxError::Json {
            path: path.to_path_buf(),
            line: e.line(),
            column: e.column(),
            message: e
                .to_string()
                .split(" at line")
                .next()
                .unwrap_or_default()
                .to_string(),
        };
        let v: serde_json::Value = serde_json::from_str(text).map_err(json_err)?;
        match v.get("format") {
            Some(serde_json::Value::String(s)) if s == FORMAT => {}
            other => {
                return Err(GreyBoxError::WrongFormat {
                    path: path.to_path_buf(),
                    found: other.map_or("missing".into(), |f| f.to_string()),
                })
            }
        }
        match v.get("version") {
            Some(n) if n.as_u64() == Some(VERSION as u64) => {}
            other => {
                return Err(GreyBoxError::WrongVersion {
                    path: path.to_path_buf(),
                    found: other.map_or("missing".into(), |f| f.to_string()),
                    supported: VERSION,
                })
            }
        }
        let file: GreyBoxFile = serde_json::from_str(text).map_err(json_err)?;
        let plant = file.plant.check(path)?;
        let inconsistent = |field: &str, rule: String| GreyBoxError::Inconsistent {
            path: path.to_path_buf(),
            field: field.into(),
            rule,
        };
        if file.inputs != plant.inputs {
            return Err(inconsistent(
                "inputs",
                format!(
                    "[{}] differ from the plant's inputs [{}]",
                    file.inputs.join(", "),
                    plant.inputs.join(", ")
                ),
            ));
        }
        if file.outputs != plant.outputs {
            return Err(inconsistent(
                "outputs",
                format!(
                    "[{}] differ from the plant's outputs [{}]",
                    file.outputs.join(", "),
                    plant.outputs.join(", ")
                ),
            ));
        }
        Ok(FittedGreyBox {
            effects: file.effects,
            hysteresis_operator: file.hysteresis_operator,
            plant,
            fit: file.fit,
        })
    }
}

fn has_null_number(v: &serde_json::Value) -> bool {
    match v {
        serde_json::Value::Null => true,
        serde_json::Value::Array(a) => a.iter().any(has_null_number),
        serde_json::Value::Object(o) => o.values().any(has_null_number),
        _ => false,
    }
}
