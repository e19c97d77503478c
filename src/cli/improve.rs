//! `hystbench improve`: the model-improvement loop. Diagnose the model against the record, add
//! the effect the diagnosis names, refit, and repeat until nothing significant is missing;
//! print and plot the ladder of errors.

use crate::cli::compare::write_figures;
use hystbench::data::IoRecord;
use hystbench::diagnose::unit_of;
use hystbench::improve::{
    effect_list, improve, start_config, ImproveOptions, Ladder, Progress, Rung,
};
use hystbench::model::{load_model, Model};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Diagnose, add the missing effect, refit, repeat; write the ladder of errors.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The record (CSV with the model's input and output columns).
    #[arg(long)]
    pub data: PathBuf,
    #[command(flatten)]
    pub screen: crate::cli::ScreenArgs,
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

/// Print the loop's progress as it goes (on `log`: nothing but the stop notice when quiet) and save
/// each chosen model into `out` as soon as it is fitted (the first error is kept in `saved`).
fn show<'a>(
    log: &'a crate::cli::progress::Progress,
    out: &'a std::path::Path,
    saved: &'a mut anyhow::Result<()>,
) -> impl FnMut(Progress) + 'a {
    move |p| match p {
        Progress::Chosen { step, model } if saved.is_ok() => {
            *saved = model
                .save(&out.join(format!("model_{step}.json")), true)
                .map_err(anyhow::Error::from);
        }
        Progress::Step {
            step,
            effects,
            rmse,
            r2,
            missing,
        } => {
            log.inc();
            log.line(&format!(
                "step {step}: {} | RMS error {rmse:.4} | R^2 {} | missing: {}",
                effect_list(effects),
                r2.map_or("undefined".into(), |v| format!("{v:.5}")),
                missing.map_or("nothing significant".into(), |m| m.to_string())
            ))
        }
        Progress::NoGain => log.notice("the error did not fall with the added effect; stopping"),
        Progress::Fitting(list) => log.line(&format!("fitting {list} ...")),
        Progress::Skipped(list, why) => log.line(&format!("left out {list}: {why}")),
        Progress::Tried(tried) => {
            let list: Vec<String> = tried.iter().map(|(e, r)| format!("{e} {r:.4}")).collect();
            log.line(&format!(
                "tried: {} (RMS error); keeping the best",
                list.join(", ")
            ));
        }
        _ => {}
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let config = start_config(&a.model)?;
    let opts = ImproveOptions {
        max_steps: a.max_steps,
        train_fraction: a.train_fraction,
        ..ImproveOptions::default()
    };
    opts.check()?;
    crate::cli::demo::prepare_report_folder(&a.out, a.force)?;
    let model: Box<dyn Model> = load_model(&a.model)?;
    let io_all = crate::cli::read_screened(
        &a.data,
        a.screen.outliers,
        crate::cli::Work::Diagnosis,
        |r| Ok(model.select(r)?),
    )?;
    let Ladder {
        mut rungs,
        prediction: pred,
        held_out_from: from,
    } = {
        let mut saved = Ok(());
        // the steps the loop may take: the starting model's and one per added effect
        let log = crate::cli::progress::Progress::bar(1 + a.max_steps as u64, "steps", a.quiet);
        let ladder = improve(
            model,
            config,
            &io_all,
            &opts,
            &mut show(&log, &a.out, &mut saved),
        );
        saved?;
        ladder?
    };
    let mut model_file = a.model.display().to_string();
    for r in rungs.iter_mut() {
        if r.model.is_some() {
            model_file = a
                .out
                .join(format!("model_{}.json", r.step))
                .display()
                .to_string();
        }
        r.model_file = model_file.clone();
    }
    let ladder = a.out.join("ladder.csv");
    hystbench::data::write_atomic(&ladder, ladder_csv(&rungs).as_bytes(), true)?;
    hystbench::plot::ladder_figure(
        &ladder,
        Some("Model improvement: free-run RMS error per step".into()),
        &a.out.join("ladder.png"),
        None,
        true,
    )?;
    let figures = write_figures(&a.out, &io_all, &pred, &[])?;
    let md = report(&a.data, &io_all, from, &rungs, &figures);
    hystbench::data::write_atomic(&a.out.join("report.md"), md.as_bytes(), true)?;
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

/// `ladder.csv`: one row per step (effects joined by `+`, `linear` for none).
fn ladder_csv(rungs: &[Rung]) -> String {
    let mut csv = String::from("step,effects,rmse,r2\n");
    for r in rungs {
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
    csv
}

/// `report.md`: the ladder as a table, with the figures.
fn report(
    data: &Path,
    io_all: &IoRecord,
    from: usize,
    rungs: &[Rung],
    figures: &[String],
) -> String {
    let unit = io_all
        .outputs
        .first()
        .map(|s| unit_of(&s.name))
        .unwrap_or_default();
    let mut md = format!("# Model improvement on {}\n\n", data.display());
    if from > 0 {
        let _ = writeln!(
            md,
            "Each model fitted on samples 0..{from}; errors on the held-out samples {from}..{}.\n",
            io_all.len()
        );
    }
    md += "| step | effects | RMS error | R^2 | diagnosis: missing | predicted RMS with it | refitted with (RMS error) |\n|---|---|---|---|---|---|---|\n";
    for r in rungs {
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
        let _ = write!(md, "![{f}]({f})\n\n");
    }
    md
}
