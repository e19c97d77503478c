//! # The model-improvement loop
//!
//! Diagnose a model against a record, add the effect the diagnosis names, refit, and repeat
//! until nothing significant is missing: the ladder of errors. The diagnosis ranks effects by a
//! linear proxy, so each step refits the model with each candidate it calls missing (at most
//! [`ImproveOptions::candidates`]) and keeps the one whose error falls most; the loop stops when
//! the error does not fall. `hystbench improve` is this loop plus the report.
//!
//! ```no_run
//! use hystbench::improve::{improve, start_config, ImproveOptions};
//! let model = hystbench::model::load_model("start.json".as_ref())?;
//! let config = start_config("start.json".as_ref())?;
//! let rec = model.select(&hystbench::data::read_csv("record.csv".as_ref())?)?;
//! let ladder = improve(model, config, &rec, &ImproveOptions::default(), &mut |_| {})?;
//! for r in &ladder.rungs {
//!     println!("{:?}: RMS error {:.4}", r.effects, r.rmse);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::data::IoRecord;
use crate::diagnose::{diagnose_model_with, DiagnoseOptions, Diagnosis};
use crate::effect::EffectName;
use crate::graybox::{ByConfig, FitMemo, FittedGreyBox, GreyBoxConfig, GreyBoxError};
use crate::model::{plant_effects, predict_finite, Model, ModelError};
use crate::plant::Plant;
use std::path::{Path, PathBuf};

/// What can stop the loop.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImproveError {
    #[error("{path}: `improve` adds effects to grey-box models (made by `hystbench fit`) and plant files; for a NARX model, add an effect's basis signals with `hystbench identify --features <effect>`")]
    NotAGreyBox { path: PathBuf },
    #[error("--train-fraction {value}: must be a number in (0, 1), e.g. 0.5 (fit on the first half, score on the second)")]
    TrainFraction { value: f64 },
    #[error("--train-fraction leaves no held-out samples in {path} ({samples} samples)")]
    NoHeldOut { path: PathBuf, samples: usize },
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(transparent)]
    GreyBox(#[from] GreyBoxError),
}

/// Knobs of the loop.
#[derive(Debug, Clone)]
pub struct ImproveOptions {
    /// At most this many effects are added.
    pub max_steps: usize,
    /// Fit every step on the first fraction of the record and score (and choose) on the rest;
    /// `None`: fit and score on the whole record. The diagnosis looks at the whole record.
    pub train_fraction: Option<f64>,
    /// Candidates refitted per step (the diagnosis' best first).
    pub candidates: usize,
    pub diagnose: DiagnoseOptions,
}

impl ImproveOptions {
    /// Check the options (before any work or output).
    pub fn check(&self) -> Result<(), ImproveError> {
        match self.train_fraction {
            Some(f) if !(f > 0.0 && f < 1.0) => Err(ImproveError::TrainFraction { value: f }),
            _ => Ok(()),
        }
    }
}

impl Default for ImproveOptions {
    fn default() -> Self {
        ImproveOptions {
            max_steps: 4,
            train_fraction: None,
            candidates: 3,
            diagnose: DiagnoseOptions::default(),
        }
    }
}

/// One rung of the ladder.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Rung {
    pub step: usize,
    pub effects: Vec<EffectName>,
    /// Mean over outputs.
    pub rmse: f64,
    pub r2: Option<f64>,
    /// The diagnosis of this model: what it says is missing.
    pub missing: Option<EffectName>,
    /// Its prediction of the RMS error once the effect is added.
    pub predicted_rmse: Option<f64>,
    /// The candidates refitted at this step and the RMS error each gave (the best is kept).
    pub tried: Vec<(EffectName, f64)>,
    /// Where the model of this rung is (the caller's to fill: the start model's file, the
    /// files it saved the fitted models to).
    pub model_file: String,
    /// The model fitted at this rung (`None` for the starting model).
    #[serde(skip)]
    pub model: Option<FittedGreyBox>,
}

/// The result of the loop.
#[derive(Debug, Clone)]
pub struct Ladder {
    pub rungs: Vec<Rung>,
    /// The last model's prediction of the whole record.
    pub prediction: Vec<Vec<f64>>,
    /// First held-out sample (0 when every step is scored on the whole record).
    pub held_out_from: usize,
}

/// What the loop is doing, for a progress display.
#[derive(Debug, Clone, Copy)]
pub enum Progress<'a> {
    /// A model was scored and diagnosed.
    Step {
        step: usize,
        effects: &'a [EffectName],
        rmse: f64,
        r2: Option<f64>,
        missing: Option<EffectName>,
    },
    /// The error did not fall with the added effect: the loop stops.
    NoGain,
    /// A candidate model is being fitted (its effect list).
    Fitting(&'a str),
    /// A candidate model could not be fitted (its effect list, why): it is left out.
    Skipped(&'a str, &'a GreyBoxError),
    /// The candidates of a step and their RMS errors.
    Tried(&'a [(EffectName, f64)]),
    /// The model chosen at a step, the model of rung `step` (save it here to keep it whatever
    /// happens later).
    Chosen {
        step: usize,
        model: &'a FittedGreyBox,
    },
}

/// The effect list as the command line writes it (`none` when empty).
pub fn effect_list(effects: &[EffectName]) -> String {
    if effects.is_empty() {
        "none".to_string()
    } else {
        effects
            .iter()
            .map(|e| e.as_str())
            .collect::<Vec<_>>()
            .join(",")
    }
}

/// The grey-box configuration that reproduces a starting model's structure: a grey-box model
/// file's own, or a plant file's effects.
pub fn start_config(path: &Path) -> Result<GreyBoxConfig, ImproveError> {
    if let Ok(m) = FittedGreyBox::load(path) {
        return Ok(m.config());
    }
    match Plant::from_file(path) {
        Ok(p) => plant_config(&p),
        Err(_) => Err(ImproveError::NotAGreyBox {
            path: path.to_path_buf(),
        }),
    }
}

/// The grey-box configuration with a plant's effects (its structure, free parameters).
pub fn plant_config(plant: &Plant) -> Result<GreyBoxConfig, ImproveError> {
    Ok(GreyBoxConfig::from_effect_list(&effect_list(
        &plant_effects(plant),
    ))?)
}

/// A model's prediction of a record and its mean scores over the outputs.
struct Evaluated {
    rmse: f64,
    r2: Option<f64>,
    pred: Vec<Vec<f64>>,
}

/// Scores on samples `from..` (the held-out part), the prediction on the whole record (the
/// model's memory runs through the fitted part).
fn mean_scores(model: &dyn Model, io: &IoRecord, from: usize) -> Result<Evaluated, ModelError> {
    let pred = predict_finite(model, io)?;
    let sc: Vec<_> = io
        .outputs
        .iter()
        .zip(&pred)
        .map(|(y, p)| crate::metrics::scores(&y.values[from..], &p[from..]))
        .collect();
    let n = sc.len().max(1) as f64;
    let rmse = sc.iter().map(|s| s.rmse).sum::<f64>() / n;
    let r2 = sc.iter().map(|s| s.r2).sum::<Option<f64>>().map(|s| s / n);
    Ok(Evaluated { rmse, r2, pred })
}

/// The best candidate of a step: its error, configuration and fitted model.
type Best = (f64, GreyBoxConfig, FittedGreyBox);

/// Every candidate's effect and error.
type Tried = Vec<(EffectName, f64)>;

/// Refit `config` with each candidate effect; the best (lowest error), and every candidate's
/// error.
fn refit_candidates(
    config: &GreyBoxConfig,
    candidates: &[EffectName],
    io: &IoRecord,
    from: usize,
    memo: &FitMemo,
    progress: &mut dyn FnMut(Progress),
) -> Result<(Option<Best>, Tried), ImproveError> {
    let mut best: Option<Best> = None;
    let mut tried = Vec::new();
    for &effect in candidates {
        let trial = config.with_effect(effect);
        progress(Progress::Fitting(&trial.effect_list()));
        // a candidate the record cannot support (too short for its time constants, say) is
        // left out; the error when none can be fitted
        let fitted = match memo.fit(&trial, io) {
            Ok(f) => f,
            Err(e) if candidates.len() > 1 => {
                progress(Progress::Skipped(&trial.effect_list(), &e));
                continue;
            }
            Err(e) => return Err(e.into()),
        };
        let e = mean_scores(&fitted, io, from)?.rmse;
        tried.push((effect, e));
        if best.as_ref().is_none_or(|(b, _, _)| e < *b) {
            best = Some((e, trial, fitted));
        }
    }
    Ok((best, tried))
}

/// Run the loop from `model` (whose structure `config` reproduces, see [`start_config`]) on
/// the record `io` (the model's inputs and outputs).
pub fn improve(
    model: Box<dyn Model>,
    config: GreyBoxConfig,
    io: &IoRecord,
    opts: &ImproveOptions,
    progress: &mut dyn FnMut(Progress),
) -> Result<Ladder, ImproveError> {
    improve_with_memo(model, config, io, opts, &RecordMemo::default(), progress)
}

/// What the loop has fitted and diagnosed on one record, by configuration (fit and
/// diagnosis are deterministic: the same configuration on the same record gives the same
/// bits). One memo is for one record and one [`DiagnoseOptions`]; the caller keeps it so.
#[derive(Debug, Default)]
pub struct RecordMemo {
    /// The fits (the diagnosis' refit test keeps its own here too).
    pub fits: FitMemo,
    /// The diagnoses of the fits, by the fit's configuration.
    pub diagnoses: ByConfig<Diagnosis>,
}

/// [`improve`] with what was fitted and diagnosed on `io` already: a fit or a diagnosis that
/// the memo holds is taken instead of made again, and the new ones are kept there. The ladder
/// is the same as without it (the zoo's loop shares one memo between a member's cases, whose
/// refits meet the complete model and its refit tests again and again).
pub fn improve_with_memo(
    mut model: Box<dyn Model>,
    mut config: GreyBoxConfig,
    io: &IoRecord,
    opts: &ImproveOptions,
    memo: &RecordMemo,
    progress: &mut dyn FnMut(Progress),
) -> Result<Ladder, ImproveError> {
    opts.check()?;
    config.options.train_fraction = opts.train_fraction.unwrap_or(1.0);
    let from = opts
        .train_fraction
        .map_or(0, |f| crate::graybox::train_samples(io.len(), f));
    if from >= io.len() {
        return Err(ImproveError::NoHeldOut {
            path: io.path.clone(),
            samples: io.len(),
        });
    }
    let mut rungs: Vec<Rung> = Vec::new();
    let mut fitted_now: Option<FittedGreyBox> = None;
    let mut last = Vec::new();
    for step in 0..=opts.max_steps {
        let Evaluated { rmse, r2, pred } = mean_scores(model.as_ref(), io, from)?;
        let effects = model.effects();
        // (a model of a step after the first is the fit of its configuration on `io`)
        let kept = if step > 0 {
            memo.diagnoses.get(&config)
        } else {
            None
        };
        let d = kept.unwrap_or_else(|| {
            let d = diagnose_model_with(io, &pred, &config, &opts.diagnose, &memo.fits);
            if step > 0 {
                memo.diagnoses.insert(config.clone(), d.clone());
            }
            d
        });
        progress(Progress::Step {
            step,
            effects: &effects,
            rmse,
            r2,
            missing: d.missing,
        });
        rungs.push(Rung {
            step,
            effects,
            rmse,
            r2,
            missing: d.missing,
            predicted_rmse: d
                .ranking
                .first()
                .filter(|r| Some(r.effect) == d.missing)
                .map(|r| r.rms_after),
            tried: Vec::new(),
            model_file: String::new(),
            model: fitted_now.take(),
        });
        last = pred;
        if let Some(prev) = rungs.len().checked_sub(2).map(|i| rungs[i].rmse) {
            if rmse >= prev {
                progress(Progress::NoGain);
                break;
            }
        }
        if d.missing.is_none() || step == opts.max_steps {
            break;
        }
        let candidates: Vec<EffectName> =
            d.candidates.iter().take(opts.candidates).copied().collect();
        let (best, tried) = refit_candidates(&config, &candidates, io, from, &memo.fits, progress)?;
        if tried.len() > 1 {
            progress(Progress::Tried(&tried));
        }
        if let Some(r) = rungs.last_mut() {
            r.tried = tried;
        }
        let Some((_, chosen, fitted)) = best else {
            break;
        };
        config = chosen;
        progress(Progress::Chosen {
            step: step + 1,
            model: &fitted,
        });
        fitted_now = Some(fitted.clone());
        model = Box::new(fitted);
    }
    Ok(Ladder {
        rungs,
        prediction: last,
        held_out_from: from,
    })
}
