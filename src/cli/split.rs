//! `hystbench split`: cut a record at its time gaps and resample each part onto a uniform grid,
//! one CSV per part, so that records with logger pauses or jittered time stamps can be used.

use hystbench::data::{split_at_gaps, OutputGuard};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Cut a record at its time gaps and resample each part onto a uniform grid.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "A gap is a time step longer than --gap (5) median steps. Each part is resampled by linear interpolation onto the median step, starting at its first time stamp, and written as DIR/<name>_partN.csv with the source's columns.\nExample: hystbench split --data friction.csv --out parts"
)]
pub struct Args {
    /// The record (CSV with a time column `t`, `time`, `t_<unit>` or `time_<unit>`).
    #[arg(long)]
    pub data: PathBuf,
    /// Folder for the parts (made if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// A time step longer than this many median steps is a gap.
    #[arg(long, default_value_t = hystbench::data::TimeSteps::GAP)]
    pub gap: f64,
    /// Parts with fewer samples are dropped (and listed).
    #[arg(long, default_value_t = 50)]
    pub min_samples: usize,
    /// Overwrite existing part files.
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    if !(a.gap.is_finite() && a.gap > 1.0) {
        anyhow::bail!(
            "--gap {}: must be a number of median steps above 1 (default 5)",
            a.gap
        );
    }
    let rec = crate::cli::read_data(&a.data)?;
    let split = split_at_gaps(&rec, a.gap, a.min_samples)?;
    if split.parts.is_empty() {
        anyhow::bail!(
            "{}: no part has {} samples or more between gaps ({}); lower --min-samples",
            a.data.display(),
            a.min_samples,
            split.steps.describe()
        );
    }
    std::fs::create_dir_all(&a.out)
        .map_err(|e| anyhow::anyhow!("{}: cannot make the folder: {e}", a.out.display()))?;
    let stem = a
        .data
        .file_stem()
        .map_or("record".into(), |s| s.to_string_lossy().to_string());
    let mut guard = OutputGuard::new(a.force);
    let mut table = format!(
        "{}: {}\nperiod of every part: {} s\n\n| part | file | source lines | samples in | samples out | jitter smoothed [s] |\n|---|---|---|---|---|---|\n",
        a.data.display(),
        split.steps.describe(),
        split.period
    );
    for (i, p) in split.parts.iter().enumerate() {
        let path = a.out.join(format!("{stem}_part{}.csv", i + 1));
        guard.stage_csv(&path, &rec.names, &p.columns)?;
        let _ = writeln!(
            table,
            "| {} | {} | {}..{} | {} | {} | {:.3e} |",
            i + 1,
            path.display(),
            p.lines.0,
            p.lines.1,
            p.source_samples,
            p.columns.first().map_or(0, Vec::len),
            p.jitter
        );
    }
    guard.commit()?;
    if !split.dropped.is_empty() {
        let list: Vec<String> = split
            .dropped
            .iter()
            .map(|(a, b)| format!("{a}..{b}"))
            .collect();
        let _ = writeln!(
            table,
            "\ndropped (fewer than {} samples; lines): {}",
            a.min_samples,
            list.join(", ")
        );
    }
    crate::cli::print(&table);
    Ok(())
}
