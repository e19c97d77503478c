//! # Models
//!
//! Anything that predicts a record's outputs from its inputs: a plant file used as a model, a
//! fitted grey-box model, a NARX network. `compare`, `diagnose` and `improve` take any of them
//! through the [`Model`] trait; [`load_model`] reads a file and picks the kind from its `format`.

use crate::data::{DataError, IoRecord, Record};
use crate::effect::{EffectName, StructureView};
use crate::plant::{Plant, PlantError, PlantKind, PlantSpec};
use std::path::{Path, PathBuf};

/// What can go wrong when loading or running a model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// The file cannot be read, or its JSON does not parse (with the line and column).
    #[error(transparent)]
    File(#[from] crate::data::JsonFileError),
    #[error("{path}: unknown model format `{found}`; known: {known}")]
    UnknownFormat {
        path: PathBuf,
        found: String,
        known: String,
    },
    #[error("{model}: the prediction of `{output}` diverged at sample {sample}")]
    Diverged {
        model: String,
        output: String,
        sample: usize,
    },
    #[error(transparent)]
    Plant(#[from] PlantError),
    #[error(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    GreyBox(#[from] crate::graybox::GreyBoxError),
    #[error(transparent)]
    Narx(#[from] crate::narx::NarxError),
    #[error("the free run of `{output}` diverged at sample {sample} (it left the training range by 5 ranges)")]
    FreeRunDiverged { output: String, sample: usize },
}

/// A model that predicts outputs from inputs (free run: only the inputs are used).
pub trait Model {
    /// A short description (kind and file).
    fn describe(&self) -> String;
    /// The input columns it needs, in order.
    fn input_names(&self) -> Vec<String>;
    /// The output columns it predicts, in order.
    fn output_names(&self) -> Vec<String>;
    /// The library effects it contains.
    fn effects(&self) -> Vec<EffectName>;
    /// Free-run prediction of every output for the inputs of `rec`.
    fn predict(&self, rec: &IoRecord) -> Result<Vec<Vec<f64>>, ModelError>;

    /// The half-width of each output's free-run prediction band at each sample, where the model
    /// has one (a NARX model's, [`crate::narx::band`]); `None` per output otherwise.
    fn band(&self, rec: &IoRecord) -> Result<Vec<Option<Vec<f64>>>, ModelError> {
        Ok(vec![None; rec.outputs.len()])
    }

    /// Where `rec` leaves the region of input space the model is known on (a data-driven
    /// model: its training record's); empty for a physical model.
    fn outside(&self, _rec: &IoRecord) -> Vec<crate::narx::region::Outside> {
        Vec::new()
    }

    /// The sampling period the model was fitted at, where it keeps one (s).
    fn sampling_period(&self) -> Option<f64> {
        None
    }

    /// Per input, the range of values where the model is known (a data-driven model: its
    /// training record's, widened by a quarter of it on each side); `None`: everywhere (a
    /// physical model).
    fn known_inputs(&self) -> Vec<Option<(f64, f64)>> {
        vec![None; self.input_names().len()]
    }

    /// The model at rest, to be run one sample at a time at sampling period `ts` (`path`
    /// names its file in errors); `None` when it can only run over a whole record (a plant
    /// integrated as an ODE).
    fn stepped(&self, _ts: f64, _path: &Path) -> Result<Option<ModelState>, ModelError> {
        Ok(None)
    }

    /// Select this model's inputs and outputs from a record (clear error if they are not there).
    fn select(&self, rec: &Record) -> Result<IoRecord, ModelError> {
        Ok(IoRecord::from_record(
            rec,
            Some(&self.input_names()),
            Some(&self.output_names()),
            true,
        )?)
    }
}

/// A model run one sample at a time whose state can be copied: what a compensator inverts,
/// trying an input on a copy before it commits to one.
pub trait Stepped: Clone {
    fn inputs(&self) -> usize;
    fn outputs(&self) -> usize;
    /// One sample: the outputs for the inputs `u` (NaN where the model diverged).
    fn step(&mut self, u: &[f64], y: &mut [f64]);
    /// Samples from rest whose outputs do not depend on the inputs (a NARX model's seed).
    fn seeded(&self) -> usize {
        0
    }
    /// Output `o` after `delay` more samples with the inputs `u` held, on a copy (a
    /// compensator's trial of an input).
    fn ahead(&self, u: &[f64], delay: usize, o: usize) -> f64 {
        let mut c = self.clone();
        let mut y = vec![0.0; self.outputs()];
        for _ in 0..=delay {
            c.step(u, &mut y);
        }
        y[o]
    }
}

impl Stepped for crate::plant::PlantState {
    fn inputs(&self) -> usize {
        self.inputs()
    }
    fn outputs(&self) -> usize {
        self.outputs()
    }
    #[inline]
    fn step(&mut self, u: &[f64], y: &mut [f64]) {
        self.step(u, y)
    }
}

/// The stepped form of any model: a chain plant or a grey-box model's plant
/// ([`crate::plant::PlantState`]), or a NARX model ([`crate::narx::NarxState`]).
#[derive(Clone)]
pub enum ModelState {
    Plant(crate::plant::PlantState),
    Narx(crate::narx::NarxState),
}

impl Stepped for ModelState {
    fn inputs(&self) -> usize {
        match self {
            ModelState::Plant(s) => s.inputs(),
            ModelState::Narx(s) => s.inputs(),
        }
    }
    fn outputs(&self) -> usize {
        match self {
            ModelState::Plant(s) => s.outputs(),
            ModelState::Narx(s) => s.outputs(),
        }
    }
    #[inline]
    fn step(&mut self, u: &[f64], y: &mut [f64]) {
        match self {
            ModelState::Plant(s) => s.step(u, y),
            ModelState::Narx(s) => s.step(u, y),
        }
    }
    fn seeded(&self) -> usize {
        match self {
            ModelState::Plant(_) => 0,
            ModelState::Narx(s) => s.seeded(),
        }
    }
    fn ahead(&self, u: &[f64], delay: usize, o: usize) -> f64 {
        match self {
            ModelState::Plant(s) => Stepped::ahead(s, u, delay, o),
            ModelState::Narx(s) => s.ahead(u, delay, o),
        }
    }
}

/// The library effects a plant contains (chain order): those whose parameters it holds and
/// that are active (a linear gain is no hysteresis), and those its structure shows (cross
/// paths are coupling).
pub fn plant_effects(plant: &Plant) -> Vec<EffectName> {
    let mut out = Vec::new();
    if let PlantKind::Chain(chains) = &plant.kind {
        for c in chains {
            for e in c.paths.iter().flat_map(|p| p.effects()).chain(&c.filters) {
                if e.is_active() && !out.contains(&e.effect()) {
                    out.push(e.effect());
                }
            }
        }
        let view = StructureView {
            n_inputs: plant.inputs.len(),
            path_inputs: chains
                .iter()
                .map(|c| c.paths.iter().map(|p| p.input).collect())
                .collect(),
        };
        for e in crate::effect::effects() {
            if e.in_structure(&view) && !out.contains(&e.name()) {
                out.push(e.name());
            }
        }
    }
    out.sort();
    out
}

impl Model for Plant {
    fn describe(&self) -> String {
        format!("plant `{}` ({})", self.name, self.path.display())
    }
    fn input_names(&self) -> Vec<String> {
        self.inputs.clone()
    }
    fn output_names(&self) -> Vec<String> {
        self.outputs.clone()
    }
    fn effects(&self) -> Vec<EffectName> {
        plant_effects(self)
    }
    fn predict(&self, rec: &IoRecord) -> Result<Vec<Vec<f64>>, ModelError> {
        let u: Vec<&[f64]> = rec.inputs.iter().map(|s| s.values.as_slice()).collect();
        Ok(self.simulate(&u, rec.ts)?)
    }
    fn stepped(&self, ts: f64, _path: &Path) -> Result<Option<ModelState>, ModelError> {
        Ok(self.state(ts)?.map(ModelState::Plant))
    }
}

impl Model for crate::graybox::FittedGreyBox {
    fn describe(&self) -> String {
        if self.config.effects.is_empty() {
            return "grey-box model (linear, no effects)".to_string();
        }
        format!(
            "grey-box model ({})",
            crate::graybox::FittedGreyBox::effects(self)
                .iter()
                .map(|e| e.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )
    }
    fn input_names(&self) -> Vec<String> {
        self.inputs().to_vec()
    }
    fn output_names(&self) -> Vec<String> {
        self.outputs().to_vec()
    }
    fn effects(&self) -> Vec<EffectName> {
        crate::graybox::FittedGreyBox::effects(self)
    }
    fn predict(&self, rec: &IoRecord) -> Result<Vec<Vec<f64>>, ModelError> {
        Ok(self.simulate(rec)?)
    }
    fn sampling_period(&self) -> Option<f64> {
        Some(self.fit.sampling_period_s)
    }
    fn stepped(&self, ts: f64, _path: &Path) -> Result<Option<ModelState>, ModelError> {
        Ok(self.plant.state(ts)?.map(ModelState::Plant))
    }
}

impl Model for crate::narx::FittedNarx {
    fn describe(&self) -> String {
        format!(
            "NARX model ({} lags, {} neurons)",
            self.config.lags.start(),
            self.config.neurons
        )
    }
    fn input_names(&self) -> Vec<String> {
        self.config.inputs.clone()
    }
    fn output_names(&self) -> Vec<String> {
        self.config.outputs.clone()
    }
    fn effects(&self) -> Vec<EffectName> {
        Vec::new()
    }
    fn outside(&self, rec: &IoRecord) -> Vec<crate::narx::region::Outside> {
        crate::narx::FittedNarx::outside(self, rec)
    }
    fn sampling_period(&self) -> Option<f64> {
        self.sampling_period_s
    }
    fn known_inputs(&self) -> Vec<Option<(f64, f64)>> {
        let n = self.config.inputs.len();
        match &self.input_region {
            Some(r) if r.inputs.len() == n => r
                .inputs
                .iter()
                .map(|i| {
                    let m = 0.25 * (i.max - i.min);
                    Some((i.min - m, i.max + m))
                })
                .collect(),
            _ => vec![None; n],
        }
    }
    fn stepped(&self, ts: f64, path: &Path) -> Result<Option<ModelState>, ModelError> {
        Ok(Some(ModelState::Narx(self.state(ts, path)?)))
    }
    fn band(&self, rec: &IoRecord) -> Result<Vec<Option<Vec<f64>>>, ModelError> {
        let preds = crate::narx::FittedNarx::predict(self, rec, crate::narx::Mode::FreeRun)?;
        Ok(preds.into_iter().map(|p| p.half_width).collect())
    }
    /// Free run from the record's first measured outputs (the model's initial condition).
    fn predict(&self, rec: &IoRecord) -> Result<Vec<Vec<f64>>, ModelError> {
        let preds = crate::narx::FittedNarx::predict(self, rec, crate::narx::Mode::FreeRun)?;
        preds
            .into_iter()
            .map(|p| match p.diverged_at {
                Some(k) => Err(ModelError::FreeRunDiverged {
                    output: p.name,
                    sample: k,
                }),
                None => Ok(p.values),
            })
            .collect()
    }
}

/// The model's free-run prediction of a record, refused when an output is not finite or stops
/// short of the record (the error names the output and the sample).
pub fn predict_finite(model: &dyn Model, io: &IoRecord) -> Result<Vec<Vec<f64>>, ModelError> {
    let pred = model.predict(io)?;
    for (p, name) in pred.iter().zip(io.output_names()) {
        if p.len() < io.len() {
            return Err(ModelError::Diverged {
                model: model.describe(),
                output: name,
                sample: p.len(),
            });
        }
        if let Some(k) = p.iter().position(|v| !v.is_finite()) {
            return Err(ModelError::Diverged {
                model: model.describe(),
                output: name,
                sample: k,
            });
        }
    }
    Ok(pred)
}

/// Read a model file: a plant file, or a model file with a `format` field.
pub fn load_model(path: &Path) -> Result<Box<dyn Model>, ModelError> {
    parse_model(path, &crate::data::read_json_text(path)?)
}

/// [`load_model`] of a file's text (`path` labels the errors).
pub fn parse_model(path: &Path, text: &str) -> Result<Box<dyn Model>, ModelError> {
    Ok(LoadedModel::parse(path, text)?.into_model())
}

/// A model read from a file, of the kind its `format` says.
pub enum LoadedModel {
    Plant(Plant),
    GreyBox(crate::graybox::FittedGreyBox),
    Narx(crate::narx::FittedNarx),
}

impl LoadedModel {
    /// Read a model file: a plant file, or a model file with a `format` field.
    pub fn load(path: &Path) -> Result<LoadedModel, ModelError> {
        Self::parse(path, &crate::data::read_json_text(path)?)
    }

    /// [`LoadedModel::load`] of a file's text (`path` labels the errors).
    pub fn parse(path: &Path, text: &str) -> Result<LoadedModel, ModelError> {
        match crate::data::FileHeader::read(path, text)?.format_str() {
            None => Ok(LoadedModel::Plant(
                PlantSpec::parse(path, text)?.check(path)?,
            )),
            Some(crate::graybox::FORMAT) => Ok(LoadedModel::GreyBox(
                crate::graybox::FittedGreyBox::parse(path, text)?,
            )),
            Some(crate::narx::model::FORMAT) => Ok(LoadedModel::Narx(
                crate::narx::FittedNarx::from_json(path, text)?,
            )),
            Some(other) => Err(ModelError::UnknownFormat {
                path: path.to_path_buf(),
                found: other.to_string(),
                known: format!(
                    "{}, {}, or a plant file (no `format`)",
                    crate::graybox::FORMAT,
                    crate::narx::model::FORMAT
                ),
            }),
        }
    }

    /// The model behind the common trait.
    pub fn as_model(&self) -> &dyn Model {
        match self {
            LoadedModel::Plant(m) => m,
            LoadedModel::GreyBox(m) => m,
            LoadedModel::Narx(m) => m,
        }
    }

    /// The model boxed behind the common trait.
    pub fn into_model(self) -> Box<dyn Model> {
        match self {
            LoadedModel::Plant(m) => Box::new(m),
            LoadedModel::GreyBox(m) => Box::new(m),
            LoadedModel::Narx(m) => Box::new(m),
        }
    }

    /// The grey-box structure that refits it (a grey-box model's own, a plant's effects);
    /// `None` for a NARX model.
    pub fn structure(&self) -> Option<crate::graybox::GreyBoxConfig> {
        match self {
            LoadedModel::Plant(p) => crate::improve::plant_config(p).ok(),
            LoadedModel::GreyBox(m) => Some(m.config()),
            LoadedModel::Narx(_) => None,
        }
    }

    /// The text of its file (what `load` reads back).
    pub fn to_json(&self) -> Result<String, ModelError> {
        match self {
            // a checked spec holds finite numbers and string keys: it always serialises
            LoadedModel::Plant(p) => {
                Ok(serde_json::to_string_pretty(&p.spec).unwrap_or_default() + "\n")
            }
            LoadedModel::GreyBox(m) => Ok(m.to_json()?),
            LoadedModel::Narx(m) => Ok(m.to_json()),
        }
    }
}
