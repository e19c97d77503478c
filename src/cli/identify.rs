//! `hystbench identify`: fit a NARX-MLP to a record, score it one-step-ahead and in free run on
//! the training and test parts, and write the model file.

use anyhow::Context;
use clap::Args;
use hystbench::data::inspect::Outliers;
use hystbench::data::{check_writable, write_atomic, IoRecord};
use hystbench::narx::{Interaction, NarxConfig, NarxError, NarxSettings, OptimizerKind, Protocol};
use std::path::PathBuf;

/// Identify a record with a NARX neural network (one MISO model per output).
#[derive(Debug, Clone, Args)]
pub struct IdentifyArgs {
    /// Training record (CSV); without --test its first half trains and its second half tests.
    #[arg(long)]
    pub data: PathBuf,
    #[command(flatten)]
    pub screen: crate::cli::ScreenArgs,
    /// Separate test record with the same columns.
    #[arg(long)]
    pub test: Option<PathBuf>,
    /// Input columns (default `u` or `u1,u2,...`).
    #[arg(long, value_delimiter = ',')]
    pub inputs: Vec<String>,
    /// Output columns (default `y` or `y1,y2,...`).
    #[arg(long, value_delimiter = ',')]
    pub outputs: Vec<String>,
    /// Lags n of outputs and inputs (the study's equal orders).
    #[arg(long, default_value_t = 4)]
    pub lags: usize,
    /// Learning rate of the one-step phase.
    #[arg(long, default_value_t = 0.01)]
    pub lr: f64,
    /// Mini-batch size of the one-step phase.
    #[arg(long, default_value_t = 128)]
    pub batch: usize,
    #[command(flatten)]
    pub net: NetArgs,
    /// Effects whose basis signals (computed from the inputs, numbers fixed on the training
    /// record and stored in the model) are added as extra regressors: any effect that
    /// `hystbench effects` lists with NARX features; `none` (default) for the plain network (the
    /// default protocol's grey-box base carries the physics); `auto` fits both the plain network
    /// and one with hysteresis features (play operators) and keeps the better free run on the
    /// training record's validation part.
    #[arg(long, value_delimiter = ',')]
    pub features: Vec<String>,
    /// The grey-box base candidate of the default protocol: `auto` fits a grey-box model of
    /// the effect library (hysteresis, creep, dynamics, coupling: what the record supports) and
    /// keeps it per output, alone or under a network on its residual, where it validates better
    /// than the network; `off` fits networks only.
    #[arg(long, default_value = "auto", value_parser = ["auto", "off"])]
    pub greybox: String,
    /// Model file to write (JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// Overwrite an existing model file.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object with the scores instead of a table.
    #[arg(long)]
    pub json: bool,
    /// No progress spinner (it shows only when standard error is a terminal).
    #[arg(long)]
    pub quiet: bool,
}

/// Network and training settings shared by `identify` and `sweep`.
#[derive(Debug, Clone, Args)]
pub struct NetArgs {
    /// Hidden neurons per layer.
    #[arg(long, default_value_t = 10)]
    pub neurons: usize,
    /// Hidden tanh layers.
    #[arg(long, default_value_t = 1)]
    pub layers: usize,
    /// How the inputs meet in the network: additive (hidden neurons grouped by input, each
    /// group sees the output lags and its own input; the default) or full (every neuron sees
    /// every input; the default with --protocol study, as in the source study).
    #[arg(long, value_parser = super::choice::<Interaction>(Interaction::NAMES))]
    pub interaction: Option<Interaction>,
    /// Output lags (default: --lags).
    #[arg(long)]
    pub output_lags: Option<usize>,
    /// Input lags (default: --lags).
    #[arg(long)]
    pub input_lags: Option<usize>,
    /// Input delay d: the newest input in the regressor is u(k-d).
    #[arg(long, default_value_t = 1)]
    pub delay: usize,
    /// Optimizer of the one-step phase (default: adam; rmsprop with --protocol study).
    #[arg(long, value_parser = super::choice::<OptimizerKind>(OptimizerKind::NAMES))]
    pub optimizer: Option<OptimizerKind>,
    /// Epochs of the one-step phase.
    #[arg(long, default_value_t = 100)]
    pub epochs: usize,
    /// Seed of initialisation, shuffling and windows.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// `default`: free-run reliable training; `study`: the source study's one-step training.
    #[arg(long, value_parser = super::choice::<Protocol>(Protocol::NAMES), default_value = "default")]
    pub protocol: Protocol,
    /// Independent restarts of the default protocol (best free run on validation wins).
    #[arg(long)]
    pub restarts: Option<usize>,
    /// Simulation-error phase (default protocol): maximum gradient steps.
    #[arg(long)]
    pub sim_steps: Option<usize>,
    /// Simulation-error phase: Adam learning rate.
    #[arg(long)]
    pub sim_lr: Option<f64>,
    /// Simulation-error phase: samples per window.
    #[arg(long)]
    pub window: Option<usize>,
    /// Simulation-error phase: validations without improvement before stopping.
    #[arg(long)]
    pub sim_patience: Option<usize>,
    /// Simulation-error phase: L2 penalty on hidden weights.
    #[arg(long)]
    pub weight_decay: Option<f64>,
    /// Fraction of the training record kept for validation (default protocol).
    #[arg(long)]
    pub validation_fraction: Option<f64>,
    /// Networks kept per output (the best restarts; predictions are their median, sample by
    /// sample). Default: 8 on records under 1,000 samples, 1 on longer ones.
    #[arg(long)]
    pub ensemble: Option<usize>,
}

impl NetArgs {
    /// The library's settings with these options and the given lags, learning rate and batch.
    pub fn settings(&self, lags: usize, lr: f64, batch: usize) -> NarxSettings {
        NarxSettings {
            lags,
            output_lags: self.output_lags,
            input_lags: self.input_lags,
            delay: self.delay,
            neurons: self.neurons,
            layers: self.layers,
            interaction: self.interaction,
            optimizer: self.optimizer,
            lr,
            batch,
            epochs: self.epochs,
            seed: self.seed,
            protocol: self.protocol,
            restarts: self.restarts,
            sim_steps: self.sim_steps,
            sim_lr: self.sim_lr,
            window: self.window,
            sim_patience: self.sim_patience,
            weight_decay: self.weight_decay,
            validation_fraction: self.validation_fraction,
            ensemble: self.ensemble,
            features: Vec::new(),
            greybox: true,
        }
    }
}

/// Train and test records from `--data` / `--test`, with the selected columns.
pub fn load_records(
    data: &std::path::Path,
    test: Option<&PathBuf>,
    inputs: &[String],
    outputs: &[String],
    outliers: Outliers,
) -> anyhow::Result<(IoRecord, IoRecord)> {
    let sel = |v: &[String]| (!v.is_empty()).then(|| v.to_vec());
    let (i, o) = (sel(inputs), sel(outputs));
    let rec = crate::cli::read_screened(data, outliers, crate::cli::Work::Identification, |r| {
        Ok(IoRecord::from_record(r, i.as_deref(), o.as_deref(), true)?)
    })?;
    match test {
        None => Ok(rec.split_halves()),
        Some(t) => {
            let names_i = rec.input_names();
            let names_o = rec.output_names();
            let te = crate::cli::read_screened(t, outliers, crate::cli::Work::Prediction, |r| {
                Ok(IoRecord::from_record(
                    r,
                    Some(&names_i),
                    Some(&names_o),
                    true,
                )?)
            })?;
            Ok((rec, te))
        }
    }
}

/// A score cell for tables.
pub fn cell(v: Option<f64>, diverged: Option<usize>) -> String {
    match (v, diverged) {
        (_, Some(k)) => format!("diverged@{k}"),
        (Some(x), None) => format!("{x:.5}"),
        (None, None) => "undefined".into(),
    }
}

/// Run `identify`.
pub fn run(args: IdentifyArgs) -> anyhow::Result<()> {
    check_writable(&args.out, args.force)?;
    let (train, test) = load_records(
        &args.data,
        args.test.as_ref(),
        &args.inputs,
        &args.outputs,
        args.screen.outliers,
    )?;
    let mut settings = args.net.settings(args.lags, args.lr, args.batch);
    settings.features = args.features.clone();
    settings.greybox = args.greybox != "off";
    let cfg = settings.config(&train).context("--features")?;
    run_with(args, cfg, train, test)
}

fn run_with(
    args: IdentifyArgs,
    cfg: NarxConfig,
    train: IoRecord,
    test: IoRecord,
) -> anyhow::Result<()> {
    let spinner = crate::cli::progress::Progress::spinner(
        &format!("identifying on {} samples", train.len()),
        args.quiet,
    );
    // without --test, the halves of one record: a grey-box base runs on through the test half
    let (model, eval) = cfg
        .identify(&train, &test, args.test.is_none())
        .map_err(|e| match e {
            NarxError::HalvesTooShort { .. } => anyhow::anyhow!("{e} with --test"),
            e => anyhow::Error::new(e).context("training failed; nothing written"),
        })?;
    drop(spinner);
    write_atomic(&args.out, model.to_json().as_bytes(), args.force)?;
    let outside = model.outside(&test);
    crate::cli::warn_outside(args.test.as_ref().unwrap_or(&args.data), &outside);
    if args.json {
        let v = model.report_json(&eval, &outside);
        println!("{v}");
    } else {
        println!(
            "{:<12} {:>12} {:>12} {:>12} {:>12} {:>12}",
            "output", "R2 OSA train", "R2 FR train", "R2 OSA test", "R2 FR test", "RMSE FR test"
        );
        for e in &eval {
            println!(
                "{:<12} {:>12} {:>12} {:>12} {:>12} {:>12}",
                e.name,
                cell(e.r2_osa_train, None),
                cell(e.r2_fr_train, e.diverged_at_train),
                cell(e.r2_osa_test, None),
                cell(e.r2_fr_test, e.diverged_at_test),
                e.rmse_fr_test.map_or("-".into(), |v| format!("{v:.4e}")),
            );
        }
        for e in &eval {
            if let Some(c) = e.band_coverage_test {
                println!(
                    "{}: the 95 % band holds {:.1} % of the test samples{}",
                    e.name,
                    100.0 * c,
                    e.band_width_test.map_or(String::new(), |w| format!(
                        " (half-width {w:.3} test standard deviations on average)"
                    ))
                );
            }
        }
        for e in &eval {
            if let Some(d) = &e.base_departure_test {
                println!("{} on the test record: {d}", e.name);
            }
        }
        for (e, o) in eval.iter().zip(&model.outputs) {
            if !o.ensemble.is_empty() {
                println!(
                    "{}: ensemble of {} networks (restarts {:?}, predictions: their {}){}",
                    o.name,
                    1 + o.ensemble.len(),
                    o.training.ensemble_restarts,
                    match model.config.robust.combine {
                        hystbench::narx::config::Combine::Mean => "mean",
                        hystbench::narx::config::Combine::Median => "median",
                    },
                    if e.diverged_members_test.is_empty() {
                        String::new()
                    } else if e.diverged_members_test.len() == 1 + o.ensemble.len()
                        && model.base.is_some()
                    {
                        // every member left out: the grey-box base stands in
                        format!(
                            "; members {:?} (most or all) diverged on the test record: the \
                             grey-box base alone predicts it",
                            e.diverged_members_test
                        )
                    } else {
                        format!(
                            "; members {:?} diverged on the test record and were left out",
                            e.diverged_members_test
                        )
                    }
                );
            }
        }
        let c = &model.config;
        println!(
            "network: {} output lags, {} input lags (delay {}), {} x {} tanh neurons{}",
            c.lags.output,
            c.lags.input,
            c.lags.delay,
            c.layers,
            c.neurons,
            match c.interaction {
                Interaction::Additive if c.inputs.len() > 1 => format!(
                    ", additive in the inputs ({} groups of about {} neurons; --interaction full mixes them)",
                    c.inputs.len(),
                    c.neurons / c.inputs.len()
                ),
                _ => String::new(),
            }
        );
        if let Some(fs) = &model.feature_selection {
            let names: Vec<String> = fs.tried.iter().map(|e| e.to_string()).collect();
            println!(
                "features {}: {} (free-run validation MSE {} without, {} with)",
                names.join(","),
                if fs.chosen { "kept" } else { "not kept" },
                fs.selection_mse_without
                    .map_or("diverged".into(), |v| format!("{v:.3e}")),
                fs.selection_mse_with
                    .map_or("diverged".into(), |v| format!("{v:.3e}")),
            );
        }
        if let Some(ds) = &model.decimation_selection {
            let tried: Vec<String> = ds
                .tried
                .iter()
                .map(|(s, m)| {
                    format!(
                        "{s}: {}",
                        m.map_or("diverged".into(), |v| format!("{v:.3e}"))
                    )
                })
                .collect();
            println!(
                "model sampling: every {} sample(s) of the record (free-run validation MSE per decimation: {})",
                ds.chosen,
                tried.join(", ")
            );
        }
        if let Some(b) = &model.base {
            print_base(b);
        }
        println!(
            "trained in {:.2} s; model written to {}",
            model.train_seconds,
            args.out.display()
        );
    }
    Ok(())
}

/// One line per output: which model the grey-box candidate left it with, and the validation
/// errors that decided.
fn print_base(b: &hystbench::narx::base::GreyBoxBase) {
    use hystbench::narx::base::BaseUse;
    let e = |v: Option<f64>| v.map_or("diverged".into(), |v| format!("{v:.3e}"));
    for c in &b.outputs {
        let what = match c.model {
            BaseUse::Network => "the network",
            BaseUse::Base => "the grey-box model alone",
            BaseUse::BaseAndNetwork => "the grey-box model plus a network on its residual",
        };
        let residual = c.residual_mse.map_or(String::new(), |v| {
            format!(", with a network on its residual {v:.3e}")
        });
        println!(
            "{}: {what} (grey-box {}; free-run validation MSE: network {}, grey-box {}{residual})",
            c.name,
            c.effects,
            e(c.network_mse),
            e(c.base_mse),
        );
    }
}
