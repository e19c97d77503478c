//! `hystbench diagnose`: which physical effect does the model miss?

use crate::cli::compare::predict_record;
use hystbench::diagnose::refit::model_rms;
use hystbench::diagnose::{diagnose, with_refit, DiagnoseOptions, Diagnosis};
use hystbench::graybox::FitMemo;
use hystbench::model::LoadedModel;
use std::path::PathBuf;

/// Rank the effects a model lacks by how much of its residual each explains, out of sample.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The record (CSV with the model's input and output columns).
    #[arg(long)]
    pub data: PathBuf,
    #[command(flatten)]
    pub screen: crate::cli::ScreenArgs,
    /// The model file (plant, grey-box or NARX).
    #[arg(long)]
    pub model: PathBuf,
    /// Print one JSON object: {"ranking": [{"effect", "explained", ...}], "missing": ..., ...}.
    #[arg(long)]
    pub json: bool,
    /// Skip the refit test (a grey-box model's structure refitted without the record's middle
    /// 30 % with and without each candidate, scored on it): the basis banks alone decide.
    /// Faster on long records.
    #[arg(long)]
    pub no_refit: bool,
    /// Also draw where each output's residual sits (.png or .svg): against the prediction
    /// (extremes: saturation), time (a slow trend: drift) and the input's travel since its last
    /// reversal (backlash, friction), with the part each place explains.
    #[arg(long)]
    pub figure: Option<PathBuf>,
    /// Replace an existing figure file.
    #[arg(long)]
    pub force: bool,
}

/// The diagnosis in words.
pub fn text(d: &Diagnosis) -> String {
    let mut s = String::new();
    for od in &d.outputs {
        s += &format!("output {} (RMS error {:.4}):\n", od.output, od.rms);
        for m in &od.messages {
            s += &format!("  - {m}\n");
        }
        let sig: Vec<&str> = od
            .whiteness
            .tests
            .iter()
            .filter(|t| t.significant)
            .map(|t| t.name.as_str())
            .collect();
        s += &if sig.is_empty() {
            "  residual: white and uncorrelated with the inputs\n".to_string()
        } else {
            format!("  residual correlation tests failed: {}\n", sig.join(", "))
        };
        if !sig.is_empty() {
            s += &format!("  where: {}\n", od.residual.message);
        }
    }
    s += "ranking (share of the residual explained out of sample):\n";
    for r in &d.ranking {
        s += &format!(
            "  {:<11} {:>6.1} %\n",
            r.effect.as_str(),
            100.0 * r.explained.max(0.0)
        );
    }
    s += &format!(
        "missing: {}\n",
        d.missing
            .map_or("nothing significant".to_string(), |m| m.to_string())
    );
    for line in &d.summary {
        s += &format!("{line}\n");
    }
    s
}

pub fn run(a: Args) -> anyhow::Result<()> {
    if let Some(f) = &a.figure {
        // refuse before the work: a wrong extension, or a file that is there without --force
        hystbench::plot::Format::from_path(f)?;
        hystbench::data::check_writable(f, a.force)?;
    }
    let loaded = LoadedModel::load(&a.model)?;
    let model = loaded.as_model();
    let (io, pred) = predict_record(
        &a.data,
        a.screen.outliers,
        model,
        crate::cli::Work::Diagnosis,
    )?;
    let mut opts = DiagnoseOptions::default();
    if a.no_refit {
        opts.refit = None;
    }
    // a grey-box model or a plant file: its structure can be refitted
    let config = loaded.structure();
    let refit = config.as_ref().zip(opts.refit);
    // the effects of the structure the refits use, else the model's
    let effects = refit.map_or_else(|| model.effects(), |(c, _)| c.effects());
    let d = diagnose(&io, &pred, &effects, &opts);
    if let Some(f) = &a.figure {
        let label = a
            .data
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into_owned());
        let mut rec = hystbench::plot::PlotRecord::from_io(label, io.clone());
        for (j, p) in pred.iter().enumerate() {
            rec = rec.with_prediction(j, p.clone())?;
        }
        let shapes = d.outputs.iter().map(|o| o.residual.clone()).collect();
        hystbench::plot::residual_where_figure(&rec, shapes, None, f, None, a.force)?;
    }
    let d = match refit {
        Some((c, r)) => {
            let rms_model = model_rms(&io, &pred, &r);
            // the refits are fits of the whole record: its prediction is not held through them
            drop(pred);
            with_refit(d, &io, &rms_model, c, &opts, &FitMemo::new())
        }
        _ => d,
    };
    if a.json {
        crate::cli::print(&serde_json::to_string(&d)?);
    } else {
        crate::cli::print(&text(&d));
        if let Some(f) = &a.figure {
            crate::cli::print(&format!("wrote {}", f.display()));
        }
    }
    Ok(())
}
