//! `hystbench plot <kind>`: figures as PNG or SVG (the extension of `--out` picks the format).

use clap::{Args, Subcommand, ValueEnum};
use hystbench::plot::{self, LoopColour, LoopOptions, PlotRecord};
use std::path::{Path, PathBuf};

/// Draw a figure.
#[derive(Debug, Args)]
pub struct PlotArgs {
    #[command(subcommand)]
    pub kind: Kind,
}

/// Options every figure has.
#[derive(Debug, Args)]
pub struct OutArgs {
    /// Figure file: `.png` or `.svg`.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Replace an existing file.
    #[arg(long)]
    pub force: bool,
    /// Size in pixels, as WIDTHxHEIGHT (default: by kind and panel count).
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Figure title (default: by kind and record).
    #[arg(long)]
    pub title: Option<String>,
}

/// Column selection and time window.
#[derive(Debug, Args)]
pub struct ColumnArgs {
    /// Input columns (default: `u` or `u1,u2..`; a record with a time column and two other
    /// columns uses them as input and output).
    #[arg(long, value_delimiter = ',')]
    pub inputs: Option<Vec<String>>,
    /// Output columns (default: `y` or `y1,y2..`). `<output>_hat` columns are the model.
    #[arg(long, value_delimiter = ',')]
    pub outputs: Option<Vec<String>>,
    /// Start of the time window in seconds.
    #[arg(long, value_name = "S")]
    pub from: Option<f64>,
    /// End of the time window in seconds.
    #[arg(long, value_name = "S")]
    pub to: Option<f64>,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ColourBy {
    Time,
    Cycle,
    Series,
}

/// The figure kinds.
#[derive(Debug, Subcommand)]
pub enum Kind {
    /// Output against input (hysteresis loops); MIMO: grid of direct and cross loops.
    Loop {
        /// Record(s) to overlay (repeat --data, or use --data2).
        #[arg(long, required = true, value_name = "CSV")]
        data: Vec<PathBuf>,
        /// A second record to overlay (same as a second --data).
        #[arg(long, value_name = "CSV")]
        data2: Option<PathBuf>,
        #[command(flatten)]
        columns: ColumnArgs,
        /// Colour the (first) measured loop by time or by cycle; `series`: one colour per series.
        #[arg(long, value_enum)]
        color: Option<ColourBy>,
        /// Only direct loops (u_i -> y_i) for MIMO records.
        #[arg(long)]
        no_cross: bool,
        #[command(flatten)]
        out: OutArgs,
    },
    /// Measured, model and residual over time.
    Time {
        #[arg(long, value_name = "CSV")]
        data: PathBuf,
        #[command(flatten)]
        columns: ColumnArgs,
        #[command(flatten)]
        out: OutArgs,
    },
    /// Residual (y - y_hat) against input, with its normalised loop area.
    ResidualLoop {
        #[arg(long, value_name = "CSV")]
        data: PathBuf,
        #[command(flatten)]
        columns: ColumnArgs,
        #[command(flatten)]
        out: OutArgs,
    },
    /// Predicted against measured: one-step ahead and free run side by side.
    Parity {
        /// Prediction CSVs: first one-step ahead, then free run.
        #[arg(long, value_name = "CSV", conflicts_with_all = ["one_step", "free_run"])]
        data: Vec<PathBuf>,
        /// One-step-ahead prediction CSV.
        #[arg(long, value_name = "CSV")]
        one_step: Option<PathBuf>,
        /// Free-run prediction CSV.
        #[arg(long, value_name = "CSV")]
        free_run: Option<PathBuf>,
        #[command(flatten)]
        columns: ColumnArgs,
        #[command(flatten)]
        out: OutArgs,
    },
    /// Amplitude spectra of the measurement and of the residual.
    Spectrum {
        #[arg(long, value_name = "CSV")]
        data: PathBuf,
        #[command(flatten)]
        columns: ColumnArgs,
        #[command(flatten)]
        out: OutArgs,
    },
    /// Heat maps of free-run test R^2 over lags x neurons from a sweep's results.csv.
    Sweep {
        #[arg(long, value_name = "CSV")]
        results: PathBuf,
        /// Only this output (default: every output in the file).
        #[arg(long)]
        output: Option<String>,
        #[command(flatten)]
        out: OutArgs,
    },
    /// Error after each added effect (ladder.csv: step,effects,rmse,r2).
    Ladder {
        #[arg(long, value_name = "CSV")]
        data: PathBuf,
        #[command(flatten)]
        out: OutArgs,
    },
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}`: give the size as WIDTHxHEIGHT, e.g. 1200x900"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("`{s}`: `{v}` is not a whole number of pixels"))
    };
    Ok((p(w)?, p(h)?))
}

fn load(path: &Path, c: &ColumnArgs) -> anyhow::Result<PlotRecord> {
    let r = PlotRecord::load(path, c.inputs.as_deref(), c.outputs.as_deref())?;
    Ok(r.window(c.from, c.to)?)
}

/// Run `hystbench plot`. (Long on purpose: one arm per figure kind, each reading its inputs and
/// building its figure.)
pub fn run(args: PlotArgs) -> anyhow::Result<()> {
    let out = match &args.kind {
        Kind::Loop { out, .. }
        | Kind::Time { out, .. }
        | Kind::ResidualLoop { out, .. }
        | Kind::Parity { out, .. }
        | Kind::Spectrum { out, .. }
        | Kind::Sweep { out, .. }
        | Kind::Ladder { out, .. } => out,
    };
    // fail on the output path before reading any data
    plot::Format::from_path(&out.out)?;
    hystbench::data::check_writable(&out.out, out.force)?;
    let title = out.title.clone();
    match &args.kind {
        Kind::Loop {
            data,
            data2,
            columns,
            color,
            no_cross,
            ..
        } => {
            let mut records = Vec::new();
            for p in data.iter().chain(data2) {
                records.push(load(p, columns)?);
            }
            let options = LoopOptions {
                title,
                colour: color.map(|c| match c {
                    ColourBy::Time => LoopColour::Time,
                    ColourBy::Cycle => LoopColour::Cycle,
                    ColourBy::Series => LoopColour::Series,
                }),
                cross: !no_cross,
                ..LoopOptions::default()
            };
            plot::loop_figure(&records, &options, &out.out, out.size, out.force)?;
        }
        Kind::Time { data, columns, .. } => {
            let r = load(data, columns)?;
            plot::time_figure(&r, title, &out.out, out.size, out.force)?;
        }
        Kind::ResidualLoop { data, columns, .. } => {
            let r = load(data, columns)?;
            plot::residual_loop_figure(&r, title, &out.out, out.size, out.force)?;
        }
        Kind::Parity {
            data,
            one_step,
            free_run,
            columns,
            ..
        } => {
            let mut named: Vec<(String, PathBuf)> = Vec::new();
            if data.is_empty() {
                if let Some(p) = one_step {
                    named.push(("one-step ahead".into(), p.clone()));
                }
                if let Some(p) = free_run {
                    named.push(("free run".into(), p.clone()));
                }
            } else if data.len() > 2 {
                anyhow::bail!(
                    "parity takes at most two --data files (one-step ahead, then free run); {} were given",
                    data.len()
                );
            } else {
                for (p, name) in data.iter().zip(["one-step ahead", "free run"]) {
                    named.push((name.to_string(), p.clone()));
                }
            }
            if named.is_empty() {
                anyhow::bail!("parity needs predictions: --data OSA.csv --data FR.csv, or --one-step F and/or --free-run F");
            }
            let records = named
                .iter()
                .map(|(_, p)| load(p, columns))
                .collect::<anyhow::Result<Vec<_>>>()?;
            let panels = named
                .iter()
                .map(|(n, _)| n.clone())
                .zip(records.iter())
                .collect();
            plot::parity_figure(panels, title, &out.out, out.size, out.force)?;
        }
        Kind::Spectrum { data, columns, .. } => {
            let r = load(data, columns)?;
            plot::spectrum_figure(&r, title, &out.out, out.size, out.force)?;
        }
        Kind::Sweep {
            results, output, ..
        } => {
            plot::sweep_figure(
                results,
                output.as_deref(),
                title,
                &out.out,
                out.size,
                out.force,
            )?;
        }
        Kind::Ladder { data, .. } => {
            plot::ladder_figure(data, title, &out.out, out.size, out.force)?;
        }
    }
    eprintln!("wrote {}", out.out.display());
    Ok(())
}
