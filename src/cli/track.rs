//! `hystbench track`: a plant (the ground truth) driven with and without a model's compensator.

use crate::cli::compensate::{clipped_lines, parse_limits, read_reference};
use hystbench::compensate::{
    compensate_stepped, static_gain, tracking, CompensateOptions, Named, OutputTracking,
};
use hystbench::data::OutputGuard;
use hystbench::data::{IoRecord, Signal};
use hystbench::model::load_model;
use hystbench::plot::time::TimeFigure;
use hystbench::plot::{render, Format, LoopFigure, LoopOptions, PlotRecord};
use std::path::PathBuf;

/// Run a plant on a reference with and without a model's compensating input, and compare
/// the tracking errors.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Without compensation the plant gets the reference divided by the plant's static gain (the slope and offset of its output against its input over a slow triangle, as a user calibrates the actuator; the model's when the plant is an ODE). Example:\n  hystbench track --plant plants/bouc_wen_piezo.json --model model.json --reference ref.csv --out track\nSee docs/compensation.md."
)]
pub struct Args {
    /// The plant that plays the actuator (a plant file).
    #[arg(long)]
    pub plant: PathBuf,
    /// The model that is inverted (a plant file, a grey-box model or a NARX model).
    #[arg(long)]
    pub model: PathBuf,
    /// The reference: a CSV with a time column and one column per output.
    #[arg(long)]
    pub reference: PathBuf,
    /// Reference columns, one per output (default: the model's output names).
    #[arg(long, value_delimiter = ',')]
    pub columns: Option<Vec<String>>,
    /// The actuator's range per input, `lo:hi`.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub limits: Option<Vec<String>>,
    /// Folder for the figures and `track.json`.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace existing files in the folder.
    #[arg(long)]
    pub force: bool,
    /// Print the errors as JSON.
    #[arg(long)]
    pub json: bool,
}

/// What `track` found: the JSON it writes, and the warnings of clipped inputs.
pub struct TrackResult {
    pub json: serde_json::Value,
    pub outputs: Vec<OutputTracking>,
    pub warnings: Vec<String>,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let t = execute(&a)?;
    if a.json {
        crate::cli::print(&serde_json::to_string(&t.json)?);
    } else {
        for w in &t.warnings {
            eprintln!("{w}");
        }
        for t in &t.outputs {
            crate::cli::print(&format!(
                "{}: tracking RMS {:.4} -> {:.4} ({:.2} % -> {:.3} % of the range), max {:.4} -> {:.4}: {} smaller",
                t.output,
                t.uncompensated.rms,
                t.compensated.rms,
                t.uncompensated.rms_percent,
                t.compensated.rms_percent,
                t.uncompensated.max,
                t.compensated.max,
                if t.ratio < 1e6 {
                    format!("{:.1}x", t.ratio)
                } else {
                    "more than a million times".to_string()
                }
            ));
        }
        crate::cli::print(&format!("wrote {}/track.json and figures", a.out.display()));
    }
    Ok(())
}

/// Compensate, run the plant both ways, write the figures and `track.json`.
pub fn execute(a: &Args) -> anyhow::Result<TrackResult> {
    let truth = hystbench::plant::Plant::from_file(&a.plant)?;
    let model = load_model(&a.model)?;
    let (input_names, output_names) = (model.input_names(), model.output_names());
    if truth.inputs.len() != input_names.len() || truth.outputs.len() != output_names.len() {
        anyhow::bail!(
            "{} has {} inputs and {} outputs, {} has {} and {}: the model must be of the plant",
            a.plant.display(),
            truth.inputs.len(),
            truth.outputs.len(),
            a.model.display(),
            input_names.len(),
            output_names.len()
        );
    }
    let files = [
        "track.json",
        "loop.png",
        "time_compensated.png",
        "time_uncompensated.png",
    ];
    for f in files {
        let p = a.out.join(f);
        if p.exists() && !a.force {
            hystbench::data::check_writable(&p, false)?;
        }
    }
    let r = read_reference(&a.reference, model.as_ref(), a.columns.as_deref())?;
    let opts = CompensateOptions {
        limits: parse_limits(a.limits.as_deref(), &input_names)?,
        ..Default::default()
    };
    let refs: Vec<&[f64]> = r.signals.iter().map(Vec::as_slice).collect();
    let named = Named::of(model.as_ref(), r.ts, &a.model)?;
    let c = compensate_stepped(&named, &refs, &opts)?;
    let uc: Vec<&[f64]> = c.inputs.iter().map(Vec::as_slice).collect();
    let y_c = truth.simulate(&uc, r.ts)?;
    // without compensation: each input is its reference through the inverse of the plant's
    // static gain (what a user calibrates on the actuator; the model's for an ODE plant)
    let calibrated = truth.state(r.ts)?;
    let u0: Vec<Vec<f64>> = (0..input_names.len())
        .map(|j| {
            let o = j.min(r.signals.len() - 1);
            let (g, b) = match &calibrated {
                Some(p) => static_gain(p, j, o, &c.inputs[j]),
                None => static_gain(&named.state, j, o, &c.inputs[j]),
            };
            // the same actuator range as the compensated run
            let (lo, hi) = opts.limits[j].unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
            r.signals[o]
                .iter()
                .map(|v| ((v - b) / g).clamp(lo, hi))
                .collect()
        })
        .collect();
    let u0r: Vec<&[f64]> = u0.iter().map(Vec::as_slice).collect();
    let y_0 = truth.simulate(&u0r, r.ts)?;
    // the preview's first samples cannot be tracked: scored after them
    let from = c.delay.min(r.time.len());
    let outputs: Vec<OutputTracking> = (0..r.signals.len())
        .map(|o| {
            let unc = tracking(&r.signals[o], &y_0[o], from);
            let com = tracking(&r.signals[o], &y_c[o], from);
            OutputTracking {
                output: output_names[o].clone(),
                uncompensated: unc,
                compensated: com,
                ratio: unc.rms / com.rms.max(f64::MIN_POSITIVE),
            }
        })
        .collect();
    std::fs::create_dir_all(&a.out)
        .map_err(|e| anyhow::anyhow!("{}: cannot make the folder: {e}", a.out.display()))?;
    // figures: output against reference with and without, and each run in time
    let io = |y: &[Vec<f64>]| IoRecord {
        path: a.reference.clone(),
        ts: r.ts,
        t0: r.time.first().copied().unwrap_or(0.0),
        time_name: r.time_name.clone(),
        inputs: r
            .names
            .iter()
            .zip(&r.signals)
            .map(|(n, s)| Signal {
                name: format!("reference {n}"),
                values: s.clone(),
            })
            .collect(),
        outputs: output_names
            .iter()
            .zip(y)
            .map(|(n, s)| Signal {
                name: n.clone(),
                values: s.clone(),
            })
            .collect(),
    };
    let unc = PlotRecord::from_io("uncompensated", io(&y_0));
    let com = PlotRecord::from_io("compensated", io(&y_c));
    let loops = LoopOptions {
        title: Some("Output against reference: uncompensated and compensated".into()),
        cross: false,
        ..Default::default()
    };
    // every file staged, then renamed into place together: a failure leaves nothing half written
    let mut guard = OutputGuard::new(a.force);
    let figure = render(
        &LoopFigure::new(&[unc.clone(), com.clone()], &loops)?,
        Format::Png,
        None,
    )?;
    guard.stage(&a.out.join("loop.png"), &figure)?;
    let mut timed =
        |rec: &PlotRecord, y: &[Vec<f64>], name: &str, title: &str| -> anyhow::Result<()> {
            let mut rec = rec.clone();
            rec.io.outputs = r
                .names
                .iter()
                .zip(&r.signals)
                .map(|(n, s)| Signal {
                    name: n.clone(),
                    values: s.clone(),
                })
                .collect();
            rec = PlotRecord::from_io(rec.label.clone(), rec.io);
            for (o, v) in y.iter().enumerate() {
                rec = rec.with_prediction(o, v.clone())?;
            }
            let figure = render(
                &TimeFigure::new(&rec, Some(title.into()))?,
                Format::Png,
                None,
            )?;
            guard.stage(&a.out.join(name), &figure)?;
            Ok(())
        };
    timed(
        &com,
        &y_c,
        "time_compensated.png",
        "Compensated: reference (measured), output (model) and tracking error",
    )?;
    timed(
        &unc,
        &y_0,
        "time_uncompensated.png",
        "Uncompensated: reference (measured), output (model) and tracking error",
    )?;
    let json = serde_json::json!({
        "delay": c.delay,
        "relative_degree": c.relative_degree,
        "samples": r.time.len(),
        "seeded": c.seeded,
        "clipped": c.clipped,
        "unreachable": c.unreachable,
        "outputs": outputs,
    });
    guard.stage(
        &a.out.join("track.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    guard.commit()?;
    Ok(TrackResult {
        json,
        outputs,
        warnings: clipped_lines(&c, &r.time),
    })
}
