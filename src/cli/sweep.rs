//! `hystbench sweep`: the source study's grid (lags x neurons x learning rate x batch), every
//! setting trained in parallel with its own seed, written as `results.csv` and a Markdown report
//! laid out like the study's tables.

use super::identify::load_records;
use super::Shard;
use anyhow::Context;
use clap::Args;
use hystbench::data::{check_writable, OutputGuard};
use hystbench::effect::noise::stream_seed;
use hystbench::narx::model::OutputEvaluation;
use hystbench::narx::{NarxConfig, NarxSettings};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Train a grid of NARX settings and report one-step and free-run R^2 for each.
#[derive(Debug, Clone, Args)]
#[command(
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    after_help = "A grid larger than one machine: run `--shard K/N` for K = 1..N (each a job of a cluster scheduler, the same seeds per setting as the whole grid), then `hystbench sweep merge DIR... --out DIR`. See docs/cluster.md."
)]
pub struct SweepArgs {
    #[command(subcommand)]
    pub merge: Option<SweepSub>,
    /// Record (CSV); first half trains, second half tests (unless --test).
    #[arg(long, required = true)]
    pub data: Option<PathBuf>,
    #[command(flatten)]
    pub screen: crate::cli::ScreenArgs,
    /// Separate test record.
    #[arg(long)]
    pub test: Option<PathBuf>,
    /// Input columns (default `u` or `u1,u2,...`).
    #[arg(long, value_delimiter = ',')]
    pub inputs: Vec<String>,
    /// Output columns (default `y` or `y1,y2,...`).
    #[arg(long, value_delimiter = ',')]
    pub outputs: Vec<String>,
    /// Lags to try.
    #[arg(long, value_delimiter = ',', default_values_t = vec![2, 3, 4, 5])]
    pub lags: Vec<usize>,
    /// Neuron counts to try (overrides the single --neurons of the network settings).
    #[arg(long = "neurons", value_delimiter = ',', default_values_t = vec![6, 8, 10, 12])]
    pub neuron_grid: Vec<usize>,
    /// Learning rates to try.
    #[arg(long, value_delimiter = ',', default_values_t = vec![0.001, 0.01])]
    pub lr: Vec<f64>,
    /// Batch sizes to try.
    #[arg(long, value_delimiter = ',', default_values_t = vec![1, 128])]
    pub batch: Vec<usize>,
    #[command(flatten)]
    pub net: SweepNetArgs,
    /// Folder for results.csv and report.md (created if missing); with --shard, for
    /// results.csv and shard.json of that part.
    #[arg(long, required = true)]
    pub out: Option<PathBuf>,
    /// Run only the K-th of N parts of the grid (settings K, K+N, K+2N... in report order),
    /// each with the seed it has in the whole grid; `sweep merge` joins the parts.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,
    /// Overwrite existing results.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object with every result.
    #[arg(long)]
    pub json: bool,
    /// No progress bar (it shows only when standard error is a terminal).
    #[arg(long)]
    pub quiet: bool,
}

/// The network settings of `identify` minus the neuron count (a grid axis here).
#[derive(Debug, Clone, Args)]
pub struct SweepNetArgs {
    /// Hidden tanh layers.
    #[arg(long, default_value_t = 1)]
    pub layers: usize,
    /// How the inputs meet in the network (additive by default, full with --protocol study).
    #[arg(long, value_parser = super::choice::<hystbench::narx::Interaction>(hystbench::narx::Interaction::NAMES))]
    pub interaction: Option<hystbench::narx::Interaction>,
    /// Optimizer (default: adam; rmsprop with --protocol study).
    #[arg(long, value_parser = super::choice::<hystbench::narx::OptimizerKind>(hystbench::narx::OptimizerKind::NAMES))]
    pub optimizer: Option<hystbench::narx::OptimizerKind>,
    /// Epochs of the one-step phase.
    #[arg(long, default_value_t = 100)]
    pub epochs: usize,
    /// Base seed; setting i gets its own seed derived from it and i.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// `default` or `study`.
    #[arg(long, value_parser = super::choice::<hystbench::narx::Protocol>(hystbench::narx::Protocol::NAMES), default_value = "default")]
    pub protocol: hystbench::narx::Protocol,
    /// Restarts per setting (default protocol).
    #[arg(long)]
    pub restarts: Option<usize>,
    /// Simulation-error phase: maximum gradient steps per restart (default protocol).
    #[arg(long)]
    pub sim_steps: Option<usize>,
}

/// `sweep merge`.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum SweepSub {
    /// Join the folders of `sweep --shard K/N` (all N of them, of one grid) into the
    /// results.csv and report.md of the unsharded sweep.
    Merge {
        /// The shard folders.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Folder for results.csv and report.md.
        #[arg(long)]
        out: PathBuf,
        /// Overwrite existing results.
        #[arg(long)]
        force: bool,
    },
}

/// One grid point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setting {
    pub lags: usize,
    pub neurons: usize,
    pub lr: f64,
    pub batch: usize,
    pub seed: u64,
}

/// One setting's outcome.
#[derive(Debug, Clone)]
pub struct SettingResult {
    pub setting: Setting,
    pub evaluation: Result<Vec<OutputEvaluation>, String>,
    pub train_seconds: f64,
}

/// The grid in report order: learning rate, batch, lags, neurons.
pub fn grid(a: &SweepArgs) -> Vec<Setting> {
    let mut v = Vec::new();
    for &lr in &a.lr {
        for &batch in &a.batch {
            for &lags in &a.lags {
                for &neurons in &a.neuron_grid {
                    let i = v.len() as u64;
                    v.push(Setting {
                        lags,
                        neurons,
                        lr,
                        batch,
                        seed: stream_seed(a.net.seed, i),
                    });
                }
            }
        }
    }
    v
}

fn config(a: &SweepArgs, s: &Setting, inputs: Vec<String>, outputs: Vec<String>) -> NarxConfig {
    let settings = NarxSettings {
        lags: s.lags,
        neurons: s.neurons,
        layers: a.net.layers,
        interaction: a.net.interaction,
        optimizer: a.net.optimizer,
        lr: s.lr,
        batch: s.batch,
        epochs: a.net.epochs,
        seed: s.seed,
        protocol: a.net.protocol,
        restarts: a.net.restarts,
        sim_steps: a.net.sim_steps,
        ..NarxSettings::default()
    };
    let mut c = settings.network(inputs, outputs);
    // the grid studies the plain network at each setting (and keeps the study grid's time): no
    // feature selection, no choice of the model's sampling
    c.robust.try_features.clear();
    c.robust.try_decimation = false;
    c.robust.try_greybox = false;
    c
}

fn opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |x| format!("{x}"))
}

/// `results.csv` text.
pub fn results_csv(results: &[SettingResult], epochs: usize, outputs: &[String]) -> String {
    let mut s = String::from(
        "output,lags,neurons,lr,batch,epochs,seed,r2_osa_train,r2_fr_train,r2_osa_test,r2_fr_test,rmse_fr_test,diverged,train_seconds\n",
    );
    for r in results {
        let st = &r.setting;
        for (i, name) in outputs.iter().enumerate() {
            let e = r.evaluation.as_ref().ok().map(|v| &v[i]);
            let div =
                e.is_none_or(|e| e.diverged_at_test.is_some() || e.diverged_at_train.is_some());
            let _ = writeln!(
                s,
                "{name},{},{},{},{},{epochs},{},{},{},{},{},{},{},{:.3}",
                st.lags,
                st.neurons,
                st.lr,
                st.batch,
                st.seed,
                opt(e.and_then(|e| e.r2_osa_train)),
                opt(e.and_then(|e| e.r2_fr_train)),
                opt(e.and_then(|e| e.r2_osa_test)),
                opt(e.and_then(|e| e.r2_fr_test)),
                opt(e.and_then(|e| e.rmse_fr_test)),
                div as u8,
                r.train_seconds
            );
        }
    }
    s
}

fn md_cell(v: Option<f64>, div: Option<usize>) -> String {
    match (v, div) {
        (_, Some(k)) => format!("diverged at {k}"),
        (Some(x), None) => format!("{x:.4}"),
        (None, None) => "-".into(),
    }
}

/// `report.md` text: per output, learning rate and batch, a table over lags x neurons.
pub fn report_md(
    a: &SweepArgs,
    results: &[SettingResult],
    outputs: &[String],
    wall: f64,
) -> String {
    let mut s = String::new();
    let data = a.data.as_deref().unwrap_or(std::path::Path::new("-"));
    let _ = writeln!(s, "# NARX sweep of {}\n", data.display());
    let _ = writeln!(
        s,
        "Protocol `{:?}`, {} epochs, {} settings, base seed {}; wall time {:.1} s on {} threads.\n",
        a.net.protocol,
        a.net.epochs,
        results.len(),
        a.net.seed,
        wall,
        rayon::current_num_threads()
    );
    for (i, name) in outputs.iter().enumerate() {
        let _ = writeln!(s, "## Output `{name}`\n");
        let frs: Vec<Option<f64>> = results
            .iter()
            .map(|r| r.evaluation.as_ref().ok().and_then(|v| v[i].r2_fr_test))
            .collect();
        let n = frs.len();
        let c99 = frs.iter().filter(|v| v.is_some_and(|x| x >= 0.99)).count();
        let c90 = frs.iter().filter(|v| v.is_some_and(|x| x >= 0.9)).count();
        let ndiv = frs.iter().filter(|v| v.is_none()).count();
        let _ = writeln!(
            s,
            "Free-run test R^2 >= 0.99: {c99} of {n}; >= 0.9: {c90} of {n}; diverged or undefined: {ndiv}.\n"
        );
        for &lr in &a.lr {
            for &batch in &a.batch {
                let _ = writeln!(s, "### Learning rate {lr}, batch {batch}\n");
                let _ = writeln!(
                    s,
                    "| lags | neurons | R^2 OSA train | R^2 FR train | R^2 OSA test | R^2 FR test | time per model (s) |"
                );
                let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|");
                for r in results
                    .iter()
                    .filter(|r| r.setting.lr == lr && r.setting.batch == batch)
                {
                    let st = &r.setting;
                    match &r.evaluation {
                        Ok(v) => {
                            let e = &v[i];
                            let _ = writeln!(
                                s,
                                "| {} | {} | {} | {} | {} | {} | {:.2} |",
                                st.lags,
                                st.neurons,
                                md_cell(e.r2_osa_train, None),
                                md_cell(e.r2_fr_train, e.diverged_at_train),
                                md_cell(e.r2_osa_test, None),
                                md_cell(e.r2_fr_test, e.diverged_at_test),
                                r.train_seconds
                            );
                        }
                        Err(msg) => {
                            let _ = writeln!(
                                s,
                                "| {} | {} | failed: {msg} | | | | {:.2} |",
                                st.lags, st.neurons, r.train_seconds
                            );
                        }
                    }
                }
                s.push('\n');
            }
        }
    }
    s
}

/// Run `sweep`.
pub fn run(a: SweepArgs) -> anyhow::Result<()> {
    if let Some(SweepSub::Merge { dirs, out, force }) = &a.merge {
        return merge(dirs, out, *force);
    }
    let (Some(data), Some(out)) = (a.data.clone(), a.out.clone()) else {
        anyhow::bail!("sweep needs --data and --out (or `sweep merge DIR... --out DIR`)");
    };
    let csv_path = out.join("results.csv");
    let md_path = out.join(if a.shard.is_some() {
        SHARD_FILE
    } else {
        "report.md"
    });
    if out.is_dir() {
        check_writable(&csv_path, a.force)?;
        check_writable(&md_path, a.force)?;
    }
    let (train, test) = load_records(
        &data,
        a.test.as_ref(),
        &a.inputs,
        &a.outputs,
        a.screen.outliers,
    )?;
    let all = grid(&a);
    if all.is_empty() {
        anyhow::bail!(
            "the grid is empty: give at least one value to --lags, --neurons, --lr and --batch"
        );
    }
    if let Some(sh) = a.shard {
        if sh.n > all.len() {
            anyhow::bail!(
                "--shard {}/{}: the grid has only {} settings; use at most {} parts",
                sh.k,
                sh.n,
                all.len(),
                all.len()
            );
        }
    }
    let indices: Vec<usize> = (0..all.len())
        .filter(|&i| a.shard.is_none_or(|sh| sh.holds(i)))
        .collect();
    let settings: Vec<Setting> = indices.iter().map(|&i| all[i]).collect();
    for s in &settings {
        config(&a, s, train.input_names(), train.output_names())
            .check()
            .with_context(|| {
                format!(
                    "setting lags {} neurons {} lr {} batch {}",
                    s.lags, s.neurons, s.lr, s.batch
                )
            })?;
    }
    let outputs = train.output_names();
    let total = settings.len();
    let t0 = std::time::Instant::now();
    let progress = super::progress::Progress::bar(total as u64, "settings", a.quiet);
    let results: Vec<SettingResult> = settings
        .par_iter()
        .map(|s| {
            let cfg = config(&a, s, train.input_names(), train.output_names());
            let t = std::time::Instant::now();
            let evaluation = cfg
                .fit(&train)
                .and_then(|m| m.evaluate(&train, &test))
                .map_err(|e| e.to_string());
            let train_seconds = t.elapsed().as_secs_f64();
            progress.inc();
            SettingResult {
                setting: *s,
                evaluation,
                train_seconds,
            }
        })
        .collect();
    let wall = t0.elapsed().as_secs_f64();
    drop(progress);
    let csv = results_csv(&results, a.net.epochs, &outputs);
    let md = match a.shard {
        None => report_md(&a, &results, &outputs, wall),
        Some(sh) => shard_json(&a, sh, all.len(), &indices, &results, &outputs, wall)?,
    };
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut g = OutputGuard::new(a.force);
    g.stage(&csv_path, csv.as_bytes())?;
    g.stage(&md_path, md.as_bytes())?;
    g.commit()?;
    if a.json {
        let rows: Vec<serde_json::Value> = results
            .iter()
            .map(|r| {
                let mut outs = serde_json::Map::new();
                if let Ok(v) = &r.evaluation {
                    for e in v {
                        outs.insert(e.name.clone(), e.to_json());
                    }
                }
                serde_json::json!({
                    "lags": r.setting.lags, "neurons": r.setting.neurons, "lr": r.setting.lr,
                    "batch": r.setting.batch, "seed": r.setting.seed, "outputs": outs,
                    "error": r.evaluation.as_ref().err(), "train_seconds": r.train_seconds,
                })
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({"settings": rows, "wall_seconds": wall})
        );
    } else {
        eprintln!(
            "wrote {} and {} ({wall:.1} s)",
            csv_path.display(),
            md_path.display()
        );
    }
    Ok(())
}

/// The file a `sweep --shard` part writes beside its results.csv.
pub const SHARD_FILE: &str = "shard.json";
const SHARD_FORMAT: &str = "hystbench-sweep-shard";

/// The sweep a part belongs to: its arguments without the part, the folder and the switches
/// that change no result.
fn sweep_key(a: &SweepArgs) -> String {
    let mut k = a.clone();
    (k.merge, k.out, k.shard, k.force, k.json, k.quiet) = (None, None, None, false, false, false);
    format!("{k:?}")
}

/// FNV-1a of the record files: the parts of one sweep read the same data.
fn data_fingerprint(a: &SweepArgs) -> anyhow::Result<String> {
    let mut h = 0xcbf29ce484222325u64;
    for p in a.data.iter().chain(a.test.iter()) {
        let bytes = std::fs::read(p).with_context(|| format!("cannot read {}", p.display()))?;
        for b in bytes {
            h = (h ^ b as u64).wrapping_mul(0x100000001b3);
        }
    }
    Ok(format!("{h:016x}"))
}

/// `shard.json`: the part's results in full (every number as computed) and what identifies its
/// sweep.
fn shard_json(
    a: &SweepArgs,
    sh: Shard,
    settings: usize,
    indices: &[usize],
    results: &[SettingResult],
    outputs: &[String],
    wall: f64,
) -> anyhow::Result<String> {
    let rows: Vec<serde_json::Value> = indices
        .iter()
        .zip(results)
        .map(|(i, r)| {
            serde_json::json!({
                "index": i, "lags": r.setting.lags, "neurons": r.setting.neurons,
                "lr": r.setting.lr, "batch": r.setting.batch, "seed": r.setting.seed,
                "evaluation": r.evaluation.as_ref().ok(), "error": r.evaluation.as_ref().err(),
                "train_seconds": r.train_seconds,
            })
        })
        .collect();
    Ok(serde_json::to_string_pretty(&serde_json::json!({
        "format": SHARD_FORMAT,
        "shard": sh.k,
        "of": sh.n,
        "settings": settings,
        "sweep": sweep_key(a),
        "argv": std::env::args().collect::<Vec<_>>(),
        "data_fnv1a": data_fingerprint(a)?,
        "outputs": outputs,
        "wall_seconds": wall,
        "results": rows,
    }))?)
}

/// One part as read back.
#[derive(serde::Deserialize)]
struct ShardFile {
    format: String,
    shard: usize,
    of: usize,
    settings: usize,
    sweep: String,
    argv: Vec<String>,
    data_fnv1a: String,
    outputs: Vec<String>,
    wall_seconds: f64,
    results: Vec<ShardRow>,
}

#[derive(serde::Deserialize)]
struct ShardRow {
    index: usize,
    lags: usize,
    neurons: usize,
    lr: f64,
    batch: usize,
    seed: u64,
    evaluation: Option<Vec<OutputEvaluation>>,
    error: Option<String>,
    train_seconds: f64,
}

/// `sweep merge`: the parts of one sweep joined into the unsharded results.csv and report.md.
fn merge(dirs: &[PathBuf], out: &std::path::Path, force: bool) -> anyhow::Result<()> {
    let mut parts: Vec<(PathBuf, ShardFile)> = Vec::new();
    for d in dirs {
        let p = d.join(SHARD_FILE);
        let text = std::fs::read_to_string(&p).with_context(|| {
            format!(
                "{}: no {SHARD_FILE}; give the folders that `sweep --shard K/N --out DIR` wrote",
                d.display()
            )
        })?;
        let f: ShardFile = hystbench::data::parse_json_file(&p, &text)?;
        if f.format != SHARD_FORMAT {
            anyhow::bail!(
                "{}: `format` is `{}`, not `{SHARD_FORMAT}`",
                p.display(),
                f.format
            );
        }
        parts.push((p, f));
    }
    let (first_path, first) = &parts[0];
    for (p, f) in &parts[1..] {
        let differs = if f.sweep != first.sweep {
            Some("the sweep's arguments (data, grid, network settings)")
        } else if f.data_fnv1a != first.data_fnv1a {
            Some("the record files' contents")
        } else if f.of != first.of || f.settings != first.settings {
            Some("the number of parts")
        } else {
            None
        };
        if let Some(what) = differs {
            anyhow::bail!(
                "{} and {} are parts of different sweeps: {what} differ; merge the parts of one `sweep --shard K/N` command",
                first_path.display(),
                p.display()
            );
        }
    }
    let found: Vec<(&std::path::Path, Shard)> = parts
        .iter()
        .map(|(p, f)| {
            (
                p.as_path(),
                Shard {
                    k: f.shard,
                    n: f.of,
                },
            )
        })
        .collect();
    Shard::check_parts(
        &found,
        first.of,
        "run `sweep ... --shard K/N` for them and give every part's folder",
    )?;
    let mut rows: Vec<Option<SettingResult>> = vec![None; first.settings];
    for (p, f) in &parts {
        for r in &f.results {
            let slot = rows
                .get_mut(r.index)
                .filter(|s| s.is_none())
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "{}: setting {} is out of the grid or given twice",
                        p.display(),
                        r.index
                    )
                })?;
            *slot = Some(SettingResult {
                setting: Setting {
                    lags: r.lags,
                    neurons: r.neurons,
                    lr: r.lr,
                    batch: r.batch,
                    seed: r.seed,
                },
                evaluation: match (&r.evaluation, &r.error) {
                    (Some(e), _) => Ok(e.clone()),
                    (None, e) => Err(e.clone().unwrap_or_default()),
                },
                train_seconds: r.train_seconds,
            });
        }
    }
    let results: Vec<SettingResult> = rows
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            r.ok_or_else(|| {
                anyhow::anyhow!("setting {i} is in no part: a part's shard.json was cut short")
            })
        })
        .collect::<anyhow::Result<_>>()?;
    let a = match <crate::cli::Cli as clap::Parser>::try_parse_from(&first.argv) {
        Ok(crate::cli::Cli {
            command: crate::cli::Command::Sweep(a),
        }) => a,
        _ => anyhow::bail!(
            "{}: `argv` is not a sweep command line",
            first_path.display()
        ),
    };
    let wall = parts
        .iter()
        .map(|(_, f)| f.wall_seconds)
        .fold(0.0, f64::max);
    let csv = results_csv(&results, a.net.epochs, &first.outputs);
    let md = report_md(&a, &results, &first.outputs, wall);
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let (csv_path, md_path) = (out.join("results.csv"), out.join("report.md"));
    let mut g = OutputGuard::new(force);
    g.stage(&csv_path, csv.as_bytes())?;
    g.stage(&md_path, md.as_bytes())?;
    g.commit()?;
    eprintln!(
        "merged {} parts ({} settings): wrote {} and {}",
        parts.len(),
        results.len(),
        csv_path.display(),
        md_path.display()
    );
    Ok(())
}
