//! `hystbench compare`: a model against a record: scores and where it fails.

use hystbench::data::inspect::Outliers;
use hystbench::data::IoRecord;
use hystbench::diagnose::compare::{compare_model, BandCoverage, OutputComparison};
use hystbench::diagnose::unit_of;
use hystbench::model::{load_model, Model};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Compare a model (plant, grey-box or NARX file) with a measured record.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The record (CSV with the model's input and output columns).
    #[arg(long)]
    pub data: PathBuf,
    #[command(flatten)]
    pub screen: crate::cli::ScreenArgs,
    /// The model file.
    #[arg(long)]
    pub model: PathBuf,
    /// Write a Markdown report (and the prediction CSV) into this folder.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Overwrite an existing report.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Load, select and predict: the common start of compare, diagnose and improve.
pub fn predict_record(
    data: &std::path::Path,
    outliers: Outliers,
    model: &dyn Model,
    work: crate::cli::Work,
) -> anyhow::Result<(IoRecord, Vec<Vec<f64>>)> {
    let io = crate::cli::read_screened(data, outliers, work, |r| Ok(model.select(r)?))?;
    // said before predicting: a free run that extrapolates may diverge
    crate::cli::warn_outside(data, &model.outside(&io));
    let pred = predict_io(model, &io)?;
    Ok((io, pred))
}

/// Predict a selected record, refusing a prediction that left the finite range.
pub fn predict_io(model: &dyn Model, io: &IoRecord) -> anyhow::Result<Vec<Vec<f64>>> {
    Ok(hystbench::model::predict_finite(model, io)?)
}

/// The comparison as Markdown.
pub fn markdown(
    model: &dyn Model,
    data: &std::path::Path,
    cmp: &[OutputComparison],
    bands: &[BandCoverage],
) -> String {
    let mut s = format!("# {} against {}\n\n", model.describe(), data.display());
    for c in cmp {
        let u = unit_of(&c.output);
        let bracket = if u.is_empty() {
            String::new()
        } else {
            format!(" [{u}]")
        };
        let sc = &c.scores;
        let _ = writeln!(s, "## {}\n", c.output);
        let _ = writeln!(
            s,
            "R^2 {} | RMSE {:.4} {u} | NRMSE {} | fit {} % | max error {:.4} {u} | {} samples\n",
            sc.r2.map_or("undefined".into(), |v| format!("{v:.5}")),
            sc.rmse,
            sc.nrmse.map_or("undefined".into(), |v| format!("{v:.4}")),
            sc.fit_percent
                .map_or("undefined".into(), |v| format!("{v:.2}")),
            sc.max_error,
            sc.n
        );
        if let Some(b) = bands.iter().find(|b| b.output == c.output) {
            let _ = writeln!(
                s,
                "Prediction band ({:.0} %): holds {:.1} % of the measured samples (mean half-width {:.4} {u}).\n",
                100.0 * b.level,
                100.0 * b.coverage,
                b.mean_half_width
            );
        }
        let _ = writeln!(
            s,
            "Residual-against-{} loop area: {:.4} (0 for a model with the right memory).\n",
            c.input, c.residual_loop_area
        );
        let _ = writeln!(s, "| where | samples | RMS error{bracket} |\n|---|---|---|");
        for sl in c
            .by_direction
            .iter()
            .chain(&c.by_amplitude)
            .chain(&c.by_motion)
        {
            if sl.samples > 0 {
                let _ = writeln!(s, "| {} | {} | {:.4} |", sl.label, sl.samples, sl.rms);
            }
        }
        let _ = writeln!(s, "\n| frequency band | RMS error{bracket} |\n|---|---|");
        for sl in &c.by_frequency {
            let _ = writeln!(s, "| {} | {:.4} |", sl.label, sl.rms);
        }
        let _ = writeln!(s, "\nWorst windows:\n");
        for w in &c.worst_windows {
            let _ = writeln!(
                s,
                "- {:.3} s to {:.3} s: RMS {:.4} {u}",
                w.start_s, w.end_s, w.rms
            );
        }
        s.push('\n');
    }
    s
}

/// Loop (measured and predicted), time, residual-loop and spectrum figures beside a report;
/// their names.
pub fn write_figures(
    dir: &std::path::Path,
    io: &IoRecord,
    pred: &[Vec<f64>],
    bands: &[Option<Vec<f64>>],
) -> anyhow::Result<Vec<String>> {
    let mut rec = hystbench::plot::PlotRecord::from_io("measured", io.clone());
    for (j, p) in pred.iter().enumerate() {
        rec = rec.with_prediction(j, p.clone())?;
        if let Some(h) = bands.get(j).and_then(Option::as_ref) {
            rec = rec.with_band(j, h.clone())?;
        }
    }
    // staged together: all figures or none
    let paths = hystbench::plot::report_figures(&rec, dir, "", true)?;
    Ok(paths
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().to_string()))
        .collect())
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let model = load_model(&a.model)?;
    if let Some(dir) = &a.report {
        crate::cli::demo::prepare_report_folder(dir, a.force)?;
    }
    let (io, pred) = predict_record(
        &a.data,
        a.screen.outliers,
        model.as_ref(),
        crate::cli::Work::Prediction,
    )?;
    let report = compare_model(model.as_ref(), &io, &pred)?;
    let bands = &report.half_widths;
    let md = markdown(model.as_ref(), &a.data, &report.outputs, &report.bands);
    if let Some(dir) = &a.report {
        let (mut names, mut cols) = io.to_columns();
        for ((s, p), h) in io.outputs.iter().zip(&pred).zip(bands) {
            names.push(format!("{}_hat", s.name));
            cols.push(p.clone());
            if let Some(h) = h {
                names.extend([format!("{}_lo", s.name), format!("{}_hi", s.name)]);
                cols.push(p.iter().zip(h).map(|(v, h)| v - h).collect());
                cols.push(p.iter().zip(h).map(|(v, h)| v + h).collect());
            }
        }
        hystbench::data::write_csv_atomic(&dir.join("prediction.csv"), &names, &cols, true)?;
        let figures = write_figures(dir, &io, &pred, bands)?;
        let mut report = format!("{md}## Figures\n\n");
        for f in figures {
            report += &format!("![{f}]({f})\n\n");
        }
        hystbench::data::write_atomic(&dir.join("report.md"), report.as_bytes(), true)?;
        eprintln!("report: {}", dir.join("report.md").display());
    }
    if a.json {
        crate::cli::print(&report.to_json());
    } else {
        crate::cli::print(&md);
    }
    Ok(())
}
