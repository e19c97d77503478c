//! `hystbench zoo`: draw random plants from the effect library and a record of each
//! (`zoo --count N --seed S --out DIR`); `zoo score DIR`: the default identifier against a
//! linear ARX baseline on every record, per class.

use anyhow::Context;
use hystbench::data::write_atomic;
use hystbench::zoo;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Make a plant zoo, or score one.
#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Args {
    #[command(subcommand)]
    pub score: Option<Sub>,
    /// How many plants to draw.
    #[arg(long, default_value_t = 20)]
    pub count: usize,
    /// The zoo's seed (member i of seed s is the same whatever the count).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The zoo folder to write (written whole or not at all).
    #[arg(long, default_value = "hystbench-zoo")]
    pub out: PathBuf,
    /// Only members of these classes (comma-separated: 1dof-long, 1dof-short, 1dof-tiny,
    /// 2dof-short, 2dof-long); each keeps its index in the whole zoo.
    #[arg(long, value_delimiter = ',')]
    pub classes: Vec<zoo::Class>,
    /// Effects drawn on top of the default zoo, sized by each output's range (comma-separated:
    /// drift, saturation); each output gets each with probability 1/2, from a stream of its
    /// own, so that the rest of every member is the default zoo's.
    #[arg(long, value_delimiter = ',')]
    pub extra: Vec<hystbench::effect::EffectName>,
    /// Replace an existing zoo folder.
    #[arg(long)]
    pub force: bool,
}

/// What to do with an existing zoo.
#[derive(Debug, clap::Subcommand)]
pub enum Sub {
    /// Run the default identifier and a linear ARX baseline on every record (first half trains,
    /// second half tests); write DIR/score/{results.csv, report.md, r2.png} and print the report.
    Score(ScoreArgs),
    /// Score the model-improvement loop: per member, diagnose the complete grey-box model (a
    /// named effect is a false alarm), then hide each of its plant's effects in turn, fit the
    /// others and run `improve`; report per effect how often the diagnosis named it, the error
    /// fall and how close to the noise the loop ends. Writes DIR/loop/{results.csv, report.md}.
    Loop(LoopArgs),
}

#[derive(Debug, clap::Args)]
pub struct LoopArgs {
    /// The zoo folder (made by `hystbench zoo`).
    pub dir: PathBuf,
    /// Fit and score on each record's first samples only.
    #[arg(long, default_value_t = 20_000)]
    pub max_samples: usize,
    /// Print the summary and every member's cases as JSON instead of the report.
    #[arg(long)]
    pub json: bool,
    /// Print nothing while working.
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Debug, clap::Args)]
pub struct ScoreArgs {
    /// The zoo folder (made by `hystbench zoo`).
    pub dir: PathBuf,
    /// Print the summary and every record's scores as JSON instead of the report.
    #[arg(long)]
    pub json: bool,
    /// Print nothing while scoring.
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    match a.score {
        Some(Sub::Score(s)) => score(s),
        Some(Sub::Loop(l)) => hidden_loop(l),
        None => make(a),
    }
}

fn make(a: Args) -> anyhow::Result<()> {
    let done = AtomicUsize::new(0);
    let count = a.count;
    let index = zoo::make(
        &a.out,
        a.count,
        a.seed,
        &a.classes,
        &a.extra,
        a.force,
        &|e| {
            let k = done.fetch_add(1, Ordering::Relaxed) + 1;
            eprintln!(
                "[{k}/{count}] member {:>4}: {:<10} {:>7} samples at {:.3} ms",
                e.index,
                e.class.name(),
                e.samples,
                e.sampling_period_s * 1e3
            );
        },
    )?;
    let mut per_class = std::collections::BTreeMap::new();
    for m in &index.members {
        *per_class.entry(m.class.name()).or_insert(0) += 1;
    }
    let classes: Vec<String> = per_class.iter().map(|(c, n)| format!("{n} {c}")).collect();
    crate::cli::print(&format!(
        "zoo of seed {}: {} members ({}) in {}; score it with `hystbench zoo score {}`",
        index.seed,
        index.members.len(),
        classes.join(", "),
        a.out.display(),
        a.out.display()
    ));
    Ok(())
}

fn score(a: ScoreArgs) -> anyhow::Result<()> {
    let n = zoo::ZooIndex::read(&a.dir)?.members.len();
    let mut k = 0;
    let result = zoo::score(&a.dir, &mut |r| {
        k += 1;
        if !a.quiet {
            let cells: Vec<String> = r
                .outputs
                .iter()
                .map(|o| {
                    format!(
                        "{} {} (ARX {})",
                        o.name,
                        o.r2.map_or("diverged".into(), |v| format!("{v:.5}")),
                        o.arx_r2.map_or("diverged".into(), |v| format!("{v:.5}"))
                    )
                })
                .collect();
            eprintln!(
                "[{k}/{n}] member {:>4} {:<10} {:>7} samples: {} in {:.1} s",
                r.index,
                r.class.name(),
                r.samples,
                cells.join(", "),
                r.seconds
            );
        }
    })?;
    let out = a.dir.join("score");
    std::fs::create_dir_all(&out).with_context(|| format!("cannot make {}", out.display()))?;
    hystbench::plot::zoo_figure(result.curves(), &out.join("r2.png"), true)?;
    let md = result.to_markdown() + "\n![free-run test error per class](r2.png)\n";
    report(&out, &result.to_csv(), &md, a.json.then_some(&result))
}

/// Write `out/{results.csv, report.md}` and print the report, or `json` when given.
fn report(
    out: &std::path::Path,
    csv: &str,
    md: &str,
    json: Option<&impl serde::Serialize>,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot make {}", out.display()))?;
    write_atomic(&out.join("results.csv"), csv.as_bytes(), true)?;
    write_atomic(&out.join("report.md"), md.as_bytes(), true)?;
    match json {
        Some(v) => crate::cli::print(&serde_json::to_string(v)?),
        None => {
            crate::cli::print(md);
            crate::cli::print(&format!("written: {}", out.display()));
        }
    }
    Ok(())
}

fn hidden_loop(a: LoopArgs) -> anyhow::Result<()> {
    if a.max_samples < 100 {
        anyhow::bail!(
            "--max-samples {}: too few to fit a model; use at least 100 (default 20000)",
            a.max_samples
        );
    }
    let n = zoo::ZooIndex::read(&a.dir)?.members.len();
    let done = AtomicUsize::new(0);
    let opts = zoo::LoopOptions {
        max_samples: a.max_samples,
        ..Default::default()
    };
    let result = zoo::score_loop(&a.dir, &opts, &|m| {
        let k = done.fetch_add(1, Ordering::Relaxed) + 1;
        if a.quiet {
            return;
        }
        let cases: Vec<String> = m
            .hidden
            .iter()
            .map(|c| {
                format!(
                    "{} hidden: named {} (refit /{:.1})",
                    c.effect,
                    c.named.map_or("nothing", |e| e.as_str()),
                    c.refit_fall
                )
            })
            .collect();
        eprintln!(
            "[{k}/{n}] member {:>4} {:<10} {}: complete {}; {} in {:.1} s",
            m.index,
            m.class.name(),
            hystbench::improve::effect_list(&m.effects),
            match (m.rmse_complete, m.false_alarm) {
                (None, _) => "not fitted".to_string(),
                (Some(_), Some(e)) => format!("false alarm ({e})"),
                (Some(_), None) => "nothing named".to_string(),
            },
            cases.join(", "),
            m.seconds
        );
    })?;
    report(
        &a.dir.join("loop"),
        &result.to_csv(),
        &result.to_markdown(),
        a.json.then_some(&result),
    )
}
