//! `hystbench improve`: the model-improvement loop. Diagnose the model against the record, add
//! the effect the diagnosis names, refit, and repeat until nothing significant is missing;
//! print and plot the ladder of errors.

use crate::cli::compare::{predict_io, write_figures};
use crate::data::read_csv;
use crate::diagnose::{diagnose, unit_of, DiagnoseOptions};
use crate::effect::EffectName;
use crate::graybox::{FittedGreyBox, GreyBoxConfig};
use crate::model::{load_model, plant_effects, Model};
use crate::plant::Plant;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Diagnose, add the missing effect, refit, repeat; write the ladder of errors.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The record (CSV with the model's input and output columns).
    #[arg(long)]
    pub data: PathBuf,
    /// The starting model: a grey-box model file or a plant file.
    #[arg(long)]
    pub model: PathBuf,
    /// Report folder: ladder.csv, ladder.png, report.md, the model of each step, figures.
    #[arg(long)]
    pub out: PathBuf,
    /// Fit every step on the first fraction F of the record and score it (and choose among
    /// the candidates) on the rest, the held-out part (default: fit and score on the whole
    /// record). The diagnosis always looks at the whole record.
    #[arg(long)]
    pub train_fraction: Option<f64>,
    /// At most this many effects are added.
    #[arg(long, default_value_t = 4)]
    pub max_steps: usize,
    /// Write into an existing folder that hystbench did not make.
    #[arg(long)]
    pub force: bool,
    /// Print the ladder as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Print nothing but errors (the report is still written).
    #[arg(long)]
    pub quiet: bool,
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
    pub model_file: String,
}

fn effect_list(effects: &[EffectName]) -> String {
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

/// The grey-box configuration that reproduces a starting model's structure.
fn start_config(path: &Path) -> anyhow::Result<GreyBoxConfig> {
    if let Ok(m) = FittedGreyBox::load(path) {
        return Ok(m.config());
    }
    match Plant::from_file(path) {
        Ok(p) => Ok(GreyBoxConfig::from_effect_list(&effect_list(&plant_effects(&p)))?),
        Err(_) => anyhow::bail!(
            "{}: `improve` adds effects to grey-box models (made by `hystbench fit`) and plant files; for a NARX model, add an effect's basis signals with `hystbench identify --features <effect>`",
            path.display()
        ),
    }
}

/// A model's prediction of a record and its mean scores over the outputs.
struct Evaluated {
    rmse: f64,
    r2: Option<f64>,
    pred: Vec<Vec<f64>>,
}

/// Scores on samples `from..` (the held-out part), the prediction on the whole record (the
/// model's memory runs through the fitted part).
fn mean_scores(
    model: &dyn Model,
    io: &crate::data::IoRecord,
    from: usize,
) -> anyhow::Result<Evaluated> {
    let pred = predict_io(model, io)?;
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

pub fn run(a: Args) -> anyhow::Result<()> {
    let mut config = start_config(&a.model)?;
    if let Some(f) = a.train_fraction {
        if !(f > 0.0 && f < 1.0) {
            anyhow::bail!("--train-fraction {f}: must be a number in (0, 1), e.g. 0.5 (fit on the first half, score on the second)");
        }
        config.options.train_fraction = f;
    } else {
        config.options.train_fraction = 1.0;
    }
    crate::cli::demo::prepare_report_folder(&a.out, a.force)?;
    let mut model: Box<dyn Model> = load_model(&a.model)?;
    let rec = read_csv(&a.data)?;
    let io_all = model.select(&rec)?;
    let from = match a.train_fraction {
        Some(f) => crate::graybox::train_samples(io_all.len(), f),
        None => 0,
    };
    if from >= io_all.len() {
        anyhow::bail!(
            "--train-fraction leaves no held-out samples in {} ({} samples)",
            a.data.display(),
            io_all.len()
        );
    }
    let opts = DiagnoseOptions::default();
    let mut rungs: Vec<Rung> = Vec::new();
    let mut model_file = a.model.display().to_string();
    let mut last = None;
    for step in 0..=a.max_steps {
        let Evaluated { rmse, r2, pred } = mean_scores(model.as_ref(), &io_all, from)?;
        let d = diagnose(&io_all, &pred, &model.effects(), &opts);
        let predicted = d
            .ranking
            .first()
            .filter(|r| Some(r.effect) == d.missing)
            .map(|r| r.rms_after);
        if !a.quiet {
            eprintln!(
                "step {step}: {} | RMS error {rmse:.4} | R^2 {} | missing: {}",
                effect_list(&model.effects()),
                r2.map_or("undefined".into(), |v| format!("{v:.5}")),
                d.missing
                    .map_or("nothing significant".into(), |m| m.to_string())
            );
        }
        rungs.push(Rung {
            step,
            effects: model.effects(),
            rmse,
            r2,
            missing: d.missing,
            predicted_rmse: predicted,
            tried: Vec::new(),
            model_file: model_file.clone(),
        });
        last = Some(pred);
        if let Some(prev) = rungs.len().checked_sub(2).map(|i| rungs[i].rmse) {
            if rmse >= prev {
                eprintln!("the error did not fall with the added effect; stopping");
                break;
            }
        }
        if d.missing.is_none() || step == a.max_steps {
            break;
        }
        // the diagnosis ranks by a linear proxy: refit with each candidate it calls missing
        // (at most three) and keep the one whose error falls most
        let mut best: Option<(f64, GreyBoxConfig, FittedGreyBox)> = None;
        let mut tried = Vec::new();
        for &effect in d.candidates.iter().take(3) {
            let trial = config.with_effect(effect);
            if !a.quiet {
                eprintln!("fitting {} ...", trial.effect_list());
            }
            let fitted = trial.fit(&io_all)?;
            let e = mean_scores(&fitted, &io_all, from)?.rmse;
            tried.push((effect, e));
            if best.as_ref().is_none_or(|(b, _, _)| e < *b) {
                best = Some((e, trial, fitted));
            }
        }
        if tried.len() > 1 && !a.quiet {
            let list: Vec<String> = tried.iter().map(|(e, r)| format!("{e} {r:.4}")).collect();
            eprintln!("tried: {} (RMS error); keeping the best", list.join(", "));
        }
        if let Some(r) = rungs.last_mut() {
            r.tried = tried;
        }
        let Some((_, chosen, fitted)) = best else {
            break;
        };
        config = chosen;
        let name = format!("model_{}.json", step + 1);
        fitted.save(&a.out.join(&name), true)?;
        model_file = a.out.join(&name).display().to_string();
        model = Box::new(fitted);
    }
    // ladder.csv and figures
    let mut csv = String::from("step,effects,rmse,r2\n");
    for r in &rungs {
        let eff = if r.effects.is_empty() {
            "linear".to_string()
        } else {
            r.effects
                .iter()
                .map(|e| e.as_str())
                .collect::<Vec<_>>()
                .join("+")
        };
        let _ = writeln!(
            csv,
            "{},{eff},{},{}",
            r.step,
            r.rmse,
            r.r2.map_or(String::new(), |v| v.to_string())
        );
    }
    let ladder = a.out.join("ladder.csv");
    crate::data::write_atomic(&ladder, csv.as_bytes(), true)?;
    crate::plot::ladder_figure(
        &ladder,
        Some("Model improvement: free-run RMS error per step".into()),
        &a.out.join("ladder.png"),
        None,
        true,
    )?;
    let pred = last.expect("at least one step");
    let figures = write_figures(&a.out, &io_all, &pred)?;
    let unit = io_all
        .outputs
        .first()
        .map(|s| unit_of(&s.name))
        .unwrap_or_default();
    let mut md = format!("# Model improvement on {}\n\n", a.data.display());
    if from > 0 {
        let _ = writeln!(
            md,
            "Each model fitted on samples 0..{from}; errors on the held-out samples {from}..{}.\n",
            io_all.len()
        );
    }
    md += "| step | effects | RMS error | R^2 | diagnosis: missing | predicted RMS with it | refitted with (RMS error) |\n|---|---|---|---|---|---|---|\n";
    for r in &rungs {
        let _ = writeln!(
            md,
            "| {} | {} | {:.4} {unit} | {} | {} | {} | {} |",
            r.step,
            effect_list(&r.effects),
            r.rmse,
            r.r2.map_or("undefined".into(), |v| format!("{v:.5}")),
            r.missing
                .map_or("nothing significant".into(), |m| m.to_string()),
            r.predicted_rmse
                .map_or("".into(), |v| format!("{v:.4} {unit}")),
            r.tried
                .iter()
                .map(|(e, v)| format!("{e} {v:.4}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    md += "\n![ladder](ladder.png)\n\n";
    for f in figures {
        md += &format!("![{f}]({f})\n\n");
    }
    crate::data::write_atomic(&a.out.join("report.md"), md.as_bytes(), true)?;
    if a.json {
        crate::cli::print(&serde_json::to_string(
            &serde_json::json!({ "ladder": rungs }),
        )?);
    } else {
        crate::cli::print(&md);
        crate::cli::print(&format!("report: {}", a.out.join("report.md").display()));
    }
    Ok(())
}
