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
    /// drift, saturation; dynamics: a second mode and a hold on an output's mode; hysteresis:
    /// Al Janaideh's tanh envelopes on the output's Prandtl-Ishlinskii paths, sized by each
    /// path's input peak); each output gets each
    /// with probability 1/2, from a stream of its own, so that the rest of every member is the
    /// default zoo's. They are drawn in chain order (hysteresis, dynamics, drift, saturation),
    /// each once, whatever the order typed.
    #[arg(long, value_delimiter = ',')]
    pub extra: Vec<hystbench::effect::EffectName>,
    /// Draw the same plants and protocols with other records: every scenario's seed R further
    /// on (new noise, new draws of the random excitations); 0 is the zoo as drawn. Compare two
    /// identifiers on several realizations: on 80 short 2-DoF records the floor moved from 62
    /// records to 56 from one realization to the next.
    #[arg(long, default_value_t = 0)]
    pub realization: u64,
    /// Replace an existing zoo folder.
    #[arg(long)]
    pub force: bool,
    /// Print nothing while drawing.
    #[arg(long)]
    pub quiet: bool,
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
    /// Score only the K-th of N parts of the zoo (members K, K+N, ...) and write
    /// DIR/score/part-K-of-N.json; `--merge` joins the parts into the report.
    #[arg(long, value_name = "K/N", conflicts_with = "merge")]
    pub shard: Option<crate::cli::Shard>,
    /// Join the parts DIR/score/part-*-of-N.json (all N of them) into the report of the whole
    /// zoo, as one unsharded `zoo score` writes it.
    #[arg(long)]
    pub merge: bool,
    /// Score one record at a time, each fit with every thread, so that each record's time is
    /// that of a lone `identify` (by default records are scored side by side, sharing the
    /// threads: the whole zoo sooner, the same scores).
    #[arg(long, conflicts_with = "merge")]
    pub one_at_a_time: bool,
    /// Fit the identifier again on each record's noiseless training half (the plant's own
    /// output, simulated again) and report why the records below the floor miss it: the noise
    /// in the test half alone, the noise in the training half, a training half that does not
    /// determine the test half, or a model family that misses even the noiseless training
    /// half. Twice the time; for developers of the identifier.
    #[arg(long, conflicts_with = "merge")]
    pub noiseless_training: bool,
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
    let progress = crate::cli::progress::Progress::bar(count as u64, "members", a.quiet);
    let index = zoo::make(
        &a.out,
        a.count,
        a.seed,
        &a.classes,
        &a.extra,
        a.realization,
        a.force,
        &|e| {
            let k = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress.line(&format!(
                "[{k}/{count}] member {:>4}: {:<10} {:>7} samples at {:.3} ms",
                e.index,
                e.class.name(),
                e.samples,
                e.sampling_period_s * 1e3
            ));
            progress.inc();
        },
    )?;
    drop(progress);
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

/// A part of a zoo's score, as `zoo score --shard K/N` writes it.
#[derive(serde::Serialize, serde::Deserialize)]
struct ScorePart {
    format: String,
    shard: usize,
    of: usize,
    seed: u64,
    members: usize,
    records: Vec<zoo::RecordScore>,
}

const PART_FORMAT: &str = "hystbench-zoo-score-part";

/// The parts of `dir`'s score joined: every one of N once, of this zoo, every member scored.
fn merged(dir: &std::path::Path, index: &zoo::ZooIndex) -> anyhow::Result<zoo::ZooScore> {
    let folder = dir.join("score");
    let mut parts: Vec<(PathBuf, ScorePart)> = Vec::new();
    let mut names: Vec<PathBuf> = std::fs::read_dir(&folder)
        .with_context(|| {
            format!(
                "{}: no parts to merge (run `zoo score DIR --shard K/N` first)",
                folder.display()
            )
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("part-"))
        })
        .collect();
    names.sort();
    for p in names {
        let text = std::fs::read_to_string(&p)?;
        let part: ScorePart = hystbench::data::parse_json_file(&p, &text)?;
        if part.format != PART_FORMAT
            || part.seed != index.seed
            || part.members != index.members.len()
        {
            anyhow::bail!(
                "{}: a part of another zoo (seed {}, {} members; this zoo: seed {}, {} members); remove it",
                p.display(),
                part.seed,
                part.members,
                index.seed,
                index.members.len()
            );
        }
        parts.push((p, part));
    }
    let Some(of) = parts.first().map(|(_, p)| p.of) else {
        anyhow::bail!("{}: no part-K-of-N.json to merge", folder.display());
    };
    let found: Vec<(&std::path::Path, crate::cli::Shard)> = parts
        .iter()
        .map(|(p, part)| {
            let sh = crate::cli::Shard {
                k: part.shard,
                n: part.of,
            };
            (p.as_path(), sh)
        })
        .collect();
    crate::cli::Shard::check_parts(
        &found,
        of,
        &format!(
            "run `zoo score DIR --shard K/N` for them (into {})",
            folder.display()
        ),
    )?;
    let mut by_index: std::collections::BTreeMap<usize, zoo::RecordScore> = Default::default();
    for (_, part) in parts {
        for r in part.records {
            by_index.insert(r.index, r);
        }
    }
    let records: Vec<zoo::RecordScore> = index
        .members
        .iter()
        .map(|m| {
            by_index.remove(&m.index).ok_or_else(|| {
                anyhow::anyhow!("member {} is in no part: a part was cut short", m.index)
            })
        })
        .collect::<anyhow::Result<_>>()?;
    Ok(zoo::ZooScore::of(index.seed, records))
}

fn score(a: ScoreArgs) -> anyhow::Result<()> {
    let index = zoo::ZooIndex::read(&a.dir)?;
    let out = a.dir.join("score");
    if a.merge {
        let result = merged(&a.dir, &index)?;
        hystbench::plot::zoo_figure(result.curves(), &out.join("r2.png"), true)?;
        let md = result.to_markdown() + "\n![free-run test error per class](r2.png)\n";
        return report(&out, &result.to_csv(), &md, a.json.then_some(&result));
    }
    let n = match a.shard {
        Some(sh) if sh.n > index.members.len() => anyhow::bail!(
            "--shard {}/{}: the zoo has only {} members; use at most {} parts",
            sh.k,
            sh.n,
            index.members.len(),
            index.members.len()
        ),
        Some(sh) => (0..index.members.len()).filter(|&i| sh.holds(i)).count(),
        None => index.members.len(),
    };
    let k = std::sync::atomic::AtomicUsize::new(0);
    let progress = crate::cli::progress::Progress::bar(n as u64, "members", a.quiet);
    let take = |i: usize| a.shard.is_none_or(|sh| sh.holds(i));
    let schedule = if a.one_at_a_time {
        zoo::Schedule::OneAtATime
    } else {
        zoo::Schedule::SideBySide
    };
    let options = zoo::ScoreOptions {
        schedule,
        noiseless_training: a.noiseless_training,
    };
    let records = zoo::score_members(&a.dir, &take, options, &|r| {
        let k = k.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress.inc();
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
            progress.line(&format!(
                "[{k}/{n}] member {:>4} {:<10} {:>7} samples: {} in {:.1} s",
                r.index,
                r.class.name(),
                r.samples,
                cells.join(", "),
                r.seconds
            ));
        }
    })?;
    drop(progress);
    std::fs::create_dir_all(&out).with_context(|| format!("cannot make {}", out.display()))?;
    if let Some(sh) = a.shard {
        let part = ScorePart {
            format: PART_FORMAT.into(),
            shard: sh.k,
            of: sh.n,
            seed: index.seed,
            members: index.members.len(),
            records,
        };
        let path = out.join(format!("part-{}-of-{}.json", sh.k, sh.n));
        write_atomic(&path, serde_json::to_string_pretty(&part)?.as_bytes(), true)?;
        eprintln!(
            "wrote {} ({} members); join the parts with `hystbench zoo score {} --merge`",
            path.display(),
            part.records.len(),
            a.dir.display()
        );
        return Ok(());
    }
    let result = zoo::ZooScore::of(index.seed, records);
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
    let progress = crate::cli::progress::Progress::bar(n as u64, "members", a.quiet);
    let result = zoo::score_loop(&a.dir, &opts, &|m| {
        let k = done.fetch_add(1, Ordering::Relaxed) + 1;
        progress.inc();
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
        progress.line(&format!(
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
        ));
    })?;
    drop(progress);
    report(
        &a.dir.join("loop"),
        &result.to_csv(),
        &result.to_markdown(),
        a.json.then_some(&result),
    )
}
