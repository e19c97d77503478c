//! `hystbench inspect`: what a record holds, before any model (spikes, dropouts, clipping,
//! quantisation, gaps, drift, reversals), with the lines and what to do.

use hystbench::data::inspect::inspect;
use hystbench::data::IoRecord;
use std::path::PathBuf;

/// Report what a record holds before modelling: sampling, ranges, noise, reversals, and the
/// spikes, dropouts, clipping, quantisation, gaps and drift it carries.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Every finding names the column, the file's lines of the first samples and what to do. Example:\n  hystbench inspect --data lab.csv --inputs voltage_V --outputs displacement_um\nSee docs/user-guide.md (Records)."
)]
pub struct Args {
    /// The record (CSV with a header row).
    #[arg(long)]
    pub data: PathBuf,
    /// Input columns (default: `u` or `u1, u2...`).
    #[arg(long, value_delimiter = ',')]
    pub inputs: Option<Vec<String>>,
    /// Output columns (default: `y` or `y1, y2...`).
    #[arg(long, value_delimiter = ',')]
    pub outputs: Option<Vec<String>>,
    /// Print one JSON object (fields in docs/user-guide.md).
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let rec = crate::cli::read_data(&a.data)?;
    let io = IoRecord::from_record(&rec, a.inputs.as_deref(), a.outputs.as_deref(), false)?;
    let r = inspect(&rec, &io.input_names(), &io.output_names());
    let needs = needs(io.inputs.len().max(1))?;
    if a.json {
        let mut v = serde_json::to_value(&r)?;
        v["usable"]["needs"] = needs
            .iter()
            .map(|(c, n)| ((*c).to_string(), serde_json::Value::from(*n)))
            .collect::<serde_json::Map<_, _>>()
            .into();
        crate::cli::print(&serde_json::to_string(&v)?);
        return Ok(());
    }
    let mut out = format!(
        "{}: {} samples{}",
        a.data.display(),
        r.samples,
        r.sampling_period
            .map(|p| format!(
                " at {p:.4e} s (jitter {:.2} %)",
                100.0 * r.jitter.unwrap_or(0.0)
            ))
            .unwrap_or_default()
    );
    for c in &r.columns {
        out += &format!(
            "\n  {:<16} {:<6} {:>12.5e} .. {:<12.5e} noise {:.3e}",
            c.name, c.role, c.min, c.max, c.noise
        );
        if let Some(n) = c.reversals {
            out += &format!(
                ", {n} reversals (median travel {}), largest rate {:.4e}/s",
                c.median_travel.map_or("-".into(), |t| format!("{t:.4e}")),
                c.max_rate.unwrap_or(0.0)
            );
        }
    }
    out += &format!(
        "\n  usable in one piece (no gap, no dropout): {} samples, lines {}..{}",
        r.usable.samples, r.usable.first_line, r.usable.last_line
    );
    for (command, n) in &needs {
        out += &format!(
            "\n    {command}: needs {n}{}",
            if r.usable.samples >= *n {
                ""
            } else {
                " (too short)"
            }
        );
    }
    if r.findings.is_empty() {
        out += "\nnothing to report: no spike, dropout, clipping, quantisation, gap, drift; the inputs reverse";
    }
    for f in &r.findings {
        out += &format!("\nwarning: {}", f.summary());
    }
    crate::cli::print(&out);
    Ok(())
}

/// The fewest samples each modelling command takes on a record of `inputs` inputs (with the
/// defaults; the grey-box fit with fewer play operators on a short record).
fn needs(inputs: usize) -> anyhow::Result<Vec<(&'static str, usize)>> {
    let fit = |effects: &str| -> anyhow::Result<usize> {
        Ok(hystbench::graybox::GreyBoxConfig::from_effect_list(effects)?.samples_needed(inputs))
    };
    // identify: the lags' initial samples and two to train on, in each half
    let lags = hystbench::narx::NarxConfig::new(Vec::new(), Vec::new())
        .lags
        .start();
    Ok(vec![
        (
            "fit --effects hysteresis,dynamics",
            fit("hysteresis,dynamics")?,
        ),
        (
            "fit --effects hysteresis,creep,dynamics",
            fit("hysteresis,creep,dynamics")?,
        ),
        ("identify (default lags)", 2 * (lags + 2)),
    ])
}
