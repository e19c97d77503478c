//! `hystbench compensate`: the input that makes a model follow a reference.

use hystbench::compensate::{compensate_stepped, CompensateOptions, Compensation, Named};
use hystbench::data::write_csv_atomic;
use hystbench::model::{load_model, Model};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Compute the feedforward input that makes a model's output follow a reference.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "The model is inverted sample by sample (root finding on its newest input, on a copy of it, with a preview of its relative degree: one sample through second-order dynamics or a NARX model's input delay). Example:\n  hystbench compensate --model plants/prandtl_ishlinskii_piezo.json --reference ref.csv --out u.csv --limits -10:150\nSee docs/compensation.md."
)]
pub struct Args {
    /// The model: a plant file, a grey-box model (`hystbench fit`) or a NARX model
    /// (`hystbench identify`).
    #[arg(long)]
    pub model: PathBuf,
    /// The reference: a CSV with a time column and one column per model output.
    #[arg(long)]
    pub reference: PathBuf,
    /// Reference columns, one per model output in its order (default: the model's output
    /// names).
    #[arg(long, value_delimiter = ',')]
    pub columns: Option<Vec<String>>,
    /// The compensating input: time and one column per model input.
    #[arg(long)]
    pub out: PathBuf,
    /// The actuator's range per input, `lo:hi` (comma-separated for several inputs); inputs
    /// beyond it are clipped and reported.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub limits: Option<Vec<String>>,
    /// Replace an existing output file.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object: {"delay", "relative_degree", "samples", "seconds", "seeded", "clipped": [...], "unreachable": [...]}.
    #[arg(long)]
    pub json: bool,
}

/// The reference signals (one per model output), their time column and sampling period.
pub struct Reference {
    pub time_name: String,
    pub time: Vec<f64>,
    pub ts: f64,
    pub names: Vec<String>,
    pub signals: Vec<Vec<f64>>,
}

/// Read `path`'s columns for the model's outputs.
pub fn read_reference(
    path: &Path,
    model: &dyn Model,
    columns: Option<&[String]>,
) -> anyhow::Result<Reference> {
    let rec = crate::cli::read_data(path)?;
    let samples = rec.columns.first().map_or(0, Vec::len);
    hystbench::data::memory::check(
        path,
        crate::cli::Work::Prediction,
        samples,
        model.input_names().len(),
        rec.names.len(),
    )?;
    let outputs = model.output_names();
    let names: Vec<String> = match columns {
        Some(c) => c.to_vec(),
        None => outputs.clone(),
    };
    if names.len() != outputs.len() {
        anyhow::bail!(
            "{}: {} reference columns ({}) for {} model outputs ({}); give one per output with --columns",
            path.display(),
            names.len(),
            names.join(", "),
            outputs.len(),
            outputs.join(", ")
        );
    }
    let signals = names
        .iter()
        .map(|n| {
            rec.column(n).map(<[f64]>::to_vec).map_err(|_| {
                anyhow::anyhow!(
                    "{}: no column `{n}` (the columns are: {}); name the reference columns with --columns",
                    path.display(),
                    rec.names.join(", ")
                )
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let Some(time_name) = rec.time_column().map(str::to_string) else {
        anyhow::bail!(
            "{}: no time column (`t`, `time`, `t_<unit>`): the reference needs its sampling period",
            path.display()
        );
    };
    let Some(ts) = rec.sampling_period()? else {
        anyhow::bail!("{}: the time column has no steps", path.display());
    };
    if let Some(m) = model.sampling_period() {
        if ((ts - m) / m).abs() > 1e-6 {
            anyhow::bail!(
                "{}: sampling period {ts} s, but the model was fitted at {m} s: resample the reference to the model's period",
                path.display()
            );
        }
    }
    let time = rec.column(&time_name)?.to_vec();
    Ok(Reference {
        time_name,
        time,
        ts,
        names,
        signals,
    })
}

/// `lo:hi` per input.
pub fn parse_limits(
    limits: Option<&[String]>,
    inputs: &[String],
) -> anyhow::Result<Vec<Option<(f64, f64)>>> {
    let Some(list) = limits else {
        return Ok(vec![None; inputs.len()]);
    };
    if list.len() != inputs.len() {
        anyhow::bail!(
            "--limits: {} ranges for {} inputs ({}); give one `lo:hi` per input",
            list.len(),
            inputs.len(),
            inputs.join(", ")
        );
    }
    list.iter()
        .map(|s| {
            let bad =
                || anyhow::anyhow!("--limits: `{s}` is not `lo:hi` with lo < hi (e.g. -10:150)");
            let (a, b) = s.split_once(':').ok_or_else(bad)?;
            let (lo, hi): (f64, f64) = (
                a.trim().parse().map_err(|_| bad())?,
                b.trim().parse().map_err(|_| bad())?,
            );
            if lo.is_finite() && hi.is_finite() && lo < hi {
                Ok(Some((lo, hi)))
            } else {
                Err(bad())
            }
        })
        .collect()
}

/// Warnings for the inputs that were clipped, and where the model cannot reach the reference.
pub fn clipped_lines(c: &Compensation, time: &[f64]) -> Vec<String> {
    let at = |i: Option<usize>| i.and_then(|i| time.get(i)).copied().unwrap_or(0.0);
    let clipped = c.clipped.iter().filter(|k| k.count > 0).map(|k| {
        format!(
            "warning: input `{}` clipped at the actuator's limits on {} samples ({:.2} %), from t = {} s to t = {} s: the reference is beyond what the actuator reaches there",
            k.input,
            k.count,
            100.0 * k.share,
            at(k.first),
            at(k.last)
        )
    });
    let unreachable = c.unreachable.iter().filter(|k| k.count > 0).map(|k| {
        format!(
            "warning: on {} samples ({:.2} %), from t = {} s to t = {} s, no value of input `{}` brings the model's output to the reference (beyond the range the model reaches, e.g. a saturating sensor): the closest value is used",
            k.count,
            100.0 * k.share,
            at(k.first),
            at(k.last),
            k.input
        )
    });
    clipped.chain(unreachable).collect()
}

pub fn run(a: Args) -> anyhow::Result<()> {
    hystbench::data::check_writable(&a.out, a.force)?;
    let model = load_model(&a.model)?;
    let r = read_reference(&a.reference, model.as_ref(), a.columns.as_deref())?;
    let opts = CompensateOptions {
        limits: parse_limits(a.limits.as_deref(), &model.input_names())?,
        ..Default::default()
    };
    let refs: Vec<&[f64]> = r.signals.iter().map(Vec::as_slice).collect();
    let t0 = Instant::now();
    let named = Named::of(model.as_ref(), r.ts, &a.model)?;
    let c = compensate_stepped(&named, &refs, &opts)?;
    let seconds = t0.elapsed().as_secs_f64();
    let mut names = vec![r.time_name.clone()];
    names.extend(named.inputs.iter().cloned());
    let mut cols = vec![r.time.clone()];
    cols.extend(c.inputs.iter().cloned());
    write_csv_atomic(&a.out, &names, &cols, a.force)?;
    let n = r.time.len();
    if a.json {
        crate::cli::print(&serde_json::to_string(&serde_json::json!({
            "delay": c.delay,
            "relative_degree": c.relative_degree,
            "samples": n,
            "seconds": seconds,
            "seeded": c.seeded,
            "clipped": c.clipped,
            "unreachable": c.unreachable,
        }))?);
    } else {
        for w in clipped_lines(&c, &r.time) {
            eprintln!("{w}");
        }
        let longer = if c.delay > c.relative_degree {
            format!(
                ", longer than the {} after which the output answers: the inverse there missed \
                 the reference",
                c.relative_degree
            )
        } else {
            String::new()
        };
        crate::cli::print(&format!(
            "compensated {} ({} samples, preview {} sample{}{}) in {:.2} s; wrote {}",
            a.model.display(),
            n,
            c.delay,
            if c.delay == 1 { "" } else { "s" },
            longer,
            seconds,
            a.out.display()
        ));
    }
    Ok(())
}
