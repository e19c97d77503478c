//! `hystbench predict`: apply a model file to a record, one-step-ahead or in free run.

use anyhow::bail;
use clap::Args;
use hystbench::data::{check_writable, write_csv_atomic, IoRecord};
use hystbench::narx::{FittedNarx, Mode};
use std::path::PathBuf;

/// Predict a record's outputs with a NARX model file.
#[derive(Debug, Clone, Args)]
pub struct PredictArgs {
    /// Model file written by `identify`.
    #[arg(long)]
    pub model: PathBuf,
    /// Record with the model's input columns (and, for one-step, its output columns).
    #[arg(long)]
    pub data: PathBuf,
    /// `free-run` feeds back the model's own outputs; `one-step` uses the measured ones.
    #[arg(long, value_parser = super::choice::<Mode>(Mode::NAMES), default_value = "free-run")]
    pub mode: Mode,
    /// CSV to write: t, inputs, measured outputs if present, `<output>_hat` per output, and in
    /// free run its 95 % prediction band `<output>_lo`, `<output>_hi` (when the model has one).
    #[arg(long)]
    pub out: PathBuf,
    /// Overwrite an existing file.
    #[arg(long)]
    pub force: bool,
}

/// Run `predict`.
pub fn run(args: PredictArgs) -> anyhow::Result<()> {
    check_writable(&args.out, args.force)?;
    let model = FittedNarx::load(&args.model)?;
    let raw = crate::cli::read_data(&args.data)?;
    let inputs = &model.config.inputs;
    let outputs: Vec<String> = model
        .config
        .outputs
        .iter()
        .filter(|o| raw.names.contains(o))
        .cloned()
        .collect();
    let rec = IoRecord::from_record(&raw, Some(inputs), Some(&outputs), false).map_err(|e| {
        anyhow::anyhow!(
            "{e}\n(the model {} was trained on inputs {})",
            args.model.display(),
            inputs.join(", ")
        )
    })?;
    // `from_record` falls back to `y...` columns for an empty selection: keep only the model's
    let mut rec = rec;
    rec.outputs
        .retain(|s| model.config.outputs.contains(&s.name));
    hystbench::data::memory::check_record(
        &args.data,
        crate::cli::Work::Prediction,
        &rec,
        rec.len(),
    )?;
    crate::cli::warn_outside(&args.data, &model.outside(&rec));
    let preds = model.predict(&rec, args.mode)?;
    for p in &preds {
        if let Some(k) = p.diverged_at {
            bail!(
                "{}: the free run of `{}` diverged at sample {k} (t = {} s): it left the training range widened by {} ranges; nothing written",
                args.data.display(),
                p.name,
                rec.t0 + k as f64 * rec.ts,
                hystbench::narx::model::DIVERGENCE_RANGES
            );
        }
    }
    for p in &preds {
        if let Some(d) = &p.base_departure {
            eprintln!("warning: {}: `{}`: {d}", args.data.display(), p.name);
        }
    }
    let (mut names, mut cols) = rec.to_columns();
    for p in preds {
        let band = p.half_width.as_ref().map(|h| {
            let lo = p.values.iter().zip(h).map(|(v, h)| v - h).collect();
            let hi = p.values.iter().zip(h).map(|(v, h)| v + h).collect();
            (lo, hi)
        });
        names.push(format!("{}_hat", p.name));
        cols.push(p.values);
        if let Some((lo, hi)) = band {
            names.extend([format!("{}_lo", p.name), format!("{}_hi", p.name)]);
            cols.extend([lo, hi]);
        }
    }
    write_csv_atomic(&args.out, &names, &cols, args.force)?;
    eprintln!("wrote {}", args.out.display());
    Ok(())
}
