//! The fitted grey-box model and its versioned file.
//!
//! The model is a [`PlantSpec`]: the fitted model is simulated by exactly the plant code, and a
//! model file's `plant` can be read as a plant. The file wraps it with what was fitted and how:
//! `{"format": "hystbench-greybox", "version": 1, "effects": [...], "inputs": [...],
//! "outputs": [...], "plant": {...}, "fit": {...}}`.

use super::{GreyBoxConfig, GreyBoxError, Selected};
use crate::data::IoRecord;
use crate::effect::{registry, EffectName};
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
    /// The ridge on the hysteresis terms' coefficients (`FitOptions::ridge`; 0: none).
    #[serde(default)]
    pub ridge: f64,
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
    /// Play operators per Prandtl-Ishlinskii path (fewer than asked on a short record; 0 in
    /// files written before it was kept).
    #[serde(default)]
    pub plays: usize,
}

/// A grey-box model file. Besides the fields below, each effect with variants has its
/// variant's file name under `<effect>_operator` (`"hysteresis_operator": "bouc-wen"`).
#[derive(Debug, Clone, PartialEq)]
pub struct GreyBoxFile {
    pub format: String,
    pub version: u32,
    pub effects: Vec<EffectName>,
    /// `(effect, variant file name)` for the effects that have variants.
    pub operators: Vec<(EffectName, String)>,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    pub plant: PlantSpec,
    pub fit: FitSummary,
}

impl Serialize for GreyBoxFile {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("format", &self.format)?;
        m.serialize_entry("version", &self.version)?;
        m.serialize_entry("effects", &self.effects)?;
        for (e, v) in &self.operators {
            m.serialize_entry(&format!("{e}_operator"), v)?;
        }
        m.serialize_entry("inputs", &self.inputs)?;
        m.serialize_entry("outputs", &self.outputs)?;
        m.serialize_entry("plant", &self.plant)?;
        m.serialize_entry("fit", &self.fit)?;
        m.end()
    }
}

impl<'de> Deserialize<'de> for GreyBoxFile {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = GreyBoxFile;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a grey-box model file")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<GreyBoxFile, A::Error> {
                use serde::de::Error;
                let (mut format, mut version, mut effects) = (None, None, None);
                let (mut inputs, mut outputs, mut plant, mut fit) = (None, None, None, None);
                let mut operators: Vec<(EffectName, String)> = Vec::new();
                fn once<T, E: Error>(
                    slot: &mut Option<T>,
                    key: &'static str,
                    v: T,
                ) -> Result<(), E> {
                    if slot.is_some() {
                        return Err(E::duplicate_field(key));
                    }
                    *slot = Some(v);
                    Ok(())
                }
                while let Some(key) = map.next_key::<String>()? {
                    match key.as_str() {
                        "format" => once(&mut format, "format", map.next_value()?)?,
                        "version" => once(&mut version, "version", map.next_value()?)?,
                        "effects" => once(&mut effects, "effects", map.next_value()?)?,
                        "inputs" => once(&mut inputs, "inputs", map.next_value()?)?,
                        "outputs" => once(&mut outputs, "outputs", map.next_value()?)?,
                        "plant" => once(&mut plant, "plant", map.next_value()?)?,
                        "fit" => once(&mut fit, "fit", map.next_value()?)?,
                        k => {
                            let effect = k
                                .strip_suffix("_operator")
                                .and_then(registry::find)
                                .filter(|e| !e.variants().is_empty())
                                .ok_or_else(|| {
                                    A::Error::custom(format!(
                                        "unknown field `{k}`, expected one of `format`, `version`, `effects`, `<effect>_operator`, `inputs`, `outputs`, `plant`, `fit`"
                                    ))
                                })?;
                            let v: String = map.next_value()?;
                            if !effect.variants().iter().any(|x| x.file == v) {
                                let known: Vec<&str> =
                                    effect.variants().iter().map(|x| x.file).collect();
                                return Err(A::Error::custom(format!(
                                    "`{k}` is `{v}`; known: {}",
                                    known.join(", ")
                                )));
                            }
                            if operators.iter().any(|(e, _)| *e == effect.name()) {
                                return Err(A::Error::custom(format!("duplicate field `{k}`")));
                            }
                            operators.push((effect.name(), v));
                        }
                    }
                }
                Ok(GreyBoxFile {
                    format: format.ok_or_else(|| A::Error::missing_field("format"))?,
                    version: version.ok_or_else(|| A::Error::missing_field("version"))?,
                    effects: effects.ok_or_else(|| A::Error::missing_field("effects"))?,
                    operators,
                    inputs: inputs.ok_or_else(|| A::Error::missing_field("inputs"))?,
                    outputs: outputs.ok_or_else(|| A::Error::missing_field("outputs"))?,
                    plant: plant.ok_or_else(|| A::Error::missing_field("plant"))?,
                    fit: fit.ok_or_else(|| A::Error::missing_field("fit"))?,
                })
            }
        }
        d.deserialize_map(V)
    }
}

/// An output's first-stage parameters as its fit left them: where a refit of the same model
/// on more samples starts ([`super::FitOptions::refine_from`]). Not written to model files.
#[derive(Debug, Clone, PartialEq)]
pub struct FirstStageParams {
    pub theta: Vec<f64>,
    /// Whether the fit left out the filters that can switch off (a mode that ran to the edge
    /// of its band: the output without dynamics fitted better).
    pub without_static_filters: bool,
}

/// A fitted grey-box model: a checked plant plus how it was fitted.
#[derive(Debug, Clone, PartialEq)]
pub struct FittedGreyBox {
    /// The unfitted model it was fitted from (its effects and their variants; default options):
    /// `model.config.with_effect(creep).fit(&rec)` refits with one more effect.
    pub config: GreyBoxConfig,
    pub plant: Plant,
    pub fit: FitSummary,
    /// Per output, its first stage's parameters (empty for a model read from a file).
    pub first_stages: Vec<FirstStageParams>,
}

impl FittedGreyBox {
    /// The unfitted model this one was fitted from (effects and variants, default options).
    pub fn config(&self) -> GreyBoxConfig {
        let mut c = self.config.clone();
        c.options = super::FitOptions::default();
        c
    }

    /// The effects, in chain order.
    pub fn effects(&self) -> Vec<EffectName> {
        self.config.effects()
    }

    /// The fit's summary as `fit --json` prints it: the effects as `--effects` names them
    /// (variants: `bouc-wen`, `modes`), the mean RMSE and R^2 over the outputs, and each
    /// output's for several.
    pub fn summary_json(&self) -> serde_json::Value {
        let list = self.config.effect_list();
        let effects: Vec<&str> = if self.effects().is_empty() {
            Vec::new()
        } else {
            list.split(',').collect()
        };
        let mut v = serde_json::json!({
            "effects": effects,
            "rmse": self.fit.rmse,
            "r2": self.fit.r2,
        });
        if self.fit.outputs.len() > 1 {
            let mut outs = serde_json::Map::new();
            for o in &self.fit.outputs {
                outs.insert(
                    o.name.clone(),
                    serde_json::json!({"rmse": o.rmse, "r2": o.r2}),
                );
            }
            v["outputs"] = serde_json::Value::Object(outs);
        }
        v
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
            effects: self.effects(),
            operators: self
                .config
                .variants()
                .into_iter()
                .map(|(e, v)| (e, v.file.to_string()))
                .collect(),
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
        Self::parse(path, &crate::data::read_json_text(path)?)
    }

    /// Parse a model file's text; `path` labels the errors.
    pub fn parse(path: &Path, text: &str) -> Result<FittedGreyBox, GreyBoxError> {
        let header = crate::data::FileHeader::read(path, text)?;
        match &header.format {
            Some(serde_json::Value::String(s)) if s == FORMAT => {}
            other => {
                return Err(GreyBoxError::WrongFormat {
                    path: path.to_path_buf(),
                    found: other.as_ref().map_or("missing".into(), |f| f.to_string()),
                })
            }
        }
        match &header.version {
            Some(n) if n.as_u64() == Some(VERSION as u64) => {}
            other => {
                return Err(GreyBoxError::WrongVersion {
                    path: path.to_path_buf(),
                    found: other.as_ref().map_or("missing".into(), |f| f.to_string()),
                    supported: VERSION,
                })
            }
        }
        let file: GreyBoxFile = crate::data::parse_json_file(path, text)?;
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
        let mut config = GreyBoxConfig::linear();
        for e in &file.effects {
            let variant = registry::effect(*e)
                .and_then(|x| {
                    let (_, file_name) = file.operators.iter().find(|(o, _)| o == e)?;
                    x.variants().iter().position(|v| v.file == file_name)
                })
                .unwrap_or(0);
            config.effects.push(Selected {
                effect: *e,
                variant,
            });
        }
        config.effects.sort_by_key(|s| s.effect);
        Ok(FittedGreyBox {
            config,
            plant,
            fit: file.fit,
            first_stages: Vec::new(),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A model file with a repeated key is refused (the derived reading did so).
    #[test]
    fn repeated_keys_are_refused() {
        let text = r#"{"format":"hystbench-greybox","version":1,"effects":[],"effects":[],"inputs":[],"outputs":[],"plant":{"name":"x","inputs":["u"]},"fit":{}}"#;
        let e = FittedGreyBox::parse(Path::new("m.json"), text)
            .unwrap_err()
            .to_string();
        assert!(e.contains("duplicate field `effects`"), "{e}");
    }
}
