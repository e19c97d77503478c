//! `hystbench fit`: fit a grey-box model (the simulator's chain with free parameters) to a
//! record and write the model file.

use anyhow::Context;
use hystbench::data::{check_writable, IoRecord};
use hystbench::graybox::GreyBoxConfig;
use std::path::PathBuf;

/// Fit a grey-box model (the chain of the library's effects, free parameters) to a record.
///
/// The model is fitted on the WHOLE record unless --train-fraction is given (then on the first
/// part, and the scores are on the held-out rest). Scores are those of a free-run simulation of
/// the fitted model from rest.
#[derive(Debug, clap::Args)]
#[command(after_help = super::effects::fit_help())]
pub struct Args {
    /// Record (CSV with a time column `t`, inputs `u` or `u1,u2..`, outputs `y` or `y1,y2..`).
    #[arg(long)]
    pub data: PathBuf,
    #[command(flatten)]
    pub screen: crate::cli::ScreenArgs,
    /// Input columns (default `u` or `u1,u2,..`).
    #[arg(long, value_delimiter = ',')]
    pub inputs: Vec<String>,
    /// Output columns (default `y` or `y1,y2,..`).
    #[arg(long, value_delimiter = ',')]
    pub outputs: Vec<String>,
    /// Comma-separated effects, e.g. hysteresis,creep,dynamics or bouc-wen,dynamics,coupling.
    #[arg(long)]
    pub effects: String,
    /// Model file to write (JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// Fit on the first fraction F of the record and score on the rest (default: fit and score
    /// on the whole record).
    #[arg(long)]
    pub train_fraction: Option<f64>,
    /// Play operators per Prandtl-Ishlinskii path (default: 39, or the most of 19, 9, 5, 3
    /// that a short record supports at about ten samples per parameter; a path whose input
    /// takes a few distinct levels, a staircase, gets no more than they determine).
    #[arg(long)]
    pub plays: Option<usize>,
    /// Generalised plays on the default hysteresis operator: ascending and descending
    /// envelopes apart, their split e(u) = c0 + c1 u + c2 u^2 fitted (Al Janaideh, Rakheja &
    /// Su 2011), for loops wider at one end of the input than at the other.
    #[arg(long)]
    pub envelope_split: bool,
    /// Overwrite an existing model file.
    #[arg(long)]
    pub force: bool,
    /// Print {"effects": [...], "rmse": .., "r2": ..} (and per output for several outputs).
    #[arg(long)]
    pub json: bool,
    /// No progress spinner (it shows only when standard error is a terminal).
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let mut cfg =
        GreyBoxConfig::from_effect_list(&a.effects)?.with_fit_options(a.plays, a.train_fraction)?;
    cfg.options.envelope_split = a.envelope_split;
    check_writable(&a.out, a.force)?;
    // the record itself is predicted; the fit's memory goes with the part it fits
    let io = crate::cli::read_screened(
        &a.data,
        a.screen.outliers,
        crate::cli::Work::Prediction,
        |r| {
            Ok(IoRecord::from_record(
                r,
                Some(&a.inputs),
                Some(&a.outputs),
                true,
            )?)
        },
    )?;
    hystbench::data::memory::check_record(
        &a.data,
        crate::cli::Work::GreyBoxFit,
        &io,
        hystbench::graybox::train_samples(io.len(), cfg.options.train_fraction),
    )?;
    let spinner = crate::cli::progress::Progress::spinner(
        &format!("fitting {} to {} samples", cfg.effect_list(), io.len()),
        a.quiet,
    );
    let model = cfg
        .fit(&io)
        .with_context(|| format!("fitting {}", cfg.effect_list()))?;
    drop(spinner);
    model
        .save(&a.out, a.force)
        .with_context(|| format!("writing {}", a.out.display()))?;
    let hysteresis = model
        .effects()
        .contains(&hystbench::effect::hysteresis::NAME);
    if hysteresis && model.fit.plays < cfg.options.plays {
        eprintln!(
            "note: {} play operators per path instead of {}: the most that {} fitted samples support at about ten samples per parameter (--plays N asks for N)",
            model.fit.plays, cfg.options.plays, model.fit.train_samples
        );
    }
    if let Some(s) = cfg
        .plays_supported(&io)
        .filter(|&s| hysteresis && s < model.fit.plays)
    {
        eprintln!(
            "note: a path whose input takes only a few distinct levels in the fitted samples (a staircase) gets {s} play operators: its levels determine no more"
        );
    }
    if !model.fit.converged {
        for o in model.fit.outputs.iter().filter(|o| !o.converged) {
            eprintln!("warning: output `{}`: {}", o.name, o.message);
        }
    }
    if a.json {
        println!("{}", serde_json::to_string(&model.summary_json())?);
    } else {
        let r2 =
            |r: Option<f64>| r.map_or("n/a (constant output)".to_string(), |v| format!("{v:.6}"));
        println!(
            "fitted {} to {} ({} samples, {}) in {:.2} s; scored on the {}",
            cfg.effect_list(),
            a.data.display(),
            io.len(),
            if model.fit.train_samples < io.len() {
                format!("fitted on the first {}", model.fit.train_samples)
            } else {
                "fitted on the whole record".into()
            },
            model.fit.seconds,
            model.fit.scored_on
        );
        for o in &model.fit.outputs {
            println!(
                "  {}: RMSE {:.6}, R^2 {}, {} iterations{}",
                o.name,
                o.rmse,
                r2(o.r2),
                o.iterations,
                if o.converged { "" } else { " (NOT converged)" }
            );
        }
        println!("wrote {}", a.out.display());
    }
    Ok(())
}
