//! # `hystbench benchmark boucwen`
//!
//! Trains on the Bouc-Wen benchmark's training record and scores the free run on the two
//! official tests (multisine in periodic steady state, sine sweep from rest), for the NARX
//! identifier and the grey-box model (the benchmark's ODE structure, fitted), beside the
//! published table. See [`hystbench::benchmark`].
//!
//! ## References
//! - J.P. Noël, M. Schoukens, "Hysteretic benchmark with a dynamic nonlinearity", 2016.

use anyhow::Context;
use hystbench::benchmark::{
    self, io_record, narx_config, BenchmarkData, BenchmarkError, TestScores, GREYBOX_MAX_ITER,
    NARX_LAGS, NARX_NEURONS, PUBLISHED,
};
use hystbench::narx::Mode;
use std::path::PathBuf;

/// Which benchmark.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Which {
    /// Bouc-Wen hysteretic benchmark (Noël & Schoukens 2016).
    Boucwen,
    /// Measured MR damper (mr-damper-utfsm): train on the 1 ms sine records, test on the
    /// earthquake record, per current.
    MrDamper,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The benchmark.
    pub which: Which,
    /// The data folder. boucwen: the Bouc-Wen benchmark's records (Noel and Schoukens 2016,
    /// nonlinearbenchmark.org; 4TU.ResearchData doi:10.4121/12967592) as CSV with header
    /// `k,t_s,u_N,y_m`: boucwen_train_multisine_dynonet.csv (the training record as the dynoNet
    /// repository ships it), boucwen_test_multisine.csv and boucwen_test_sinesweep.csv (the two
    /// test records also ship in this repository's tests/data). mr-damper: the UTFSM MR damper
    /// records (github.com/DanielMaurelE/vRTHS_AMBC_MRdamper, MIT): earthquake_validation.csv
    /// and the 1 ms sine records (docs/benchmarks.md lists the columns).
    #[arg(long)]
    pub data_dir: PathBuf,
    /// Print only `{"narx": {...}, "greybox": {...}}`.
    #[arg(long)]
    pub json: bool,
    /// No progress spinner (it shows only when standard error is a terminal).
    #[arg(long)]
    pub quiet: bool,
    /// mr-damper: write the free-run predictions (one CSV per current) and the result JSON
    /// into this folder (which must exist).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Overwrite existing files in --out.
    #[arg(long)]
    pub force: bool,
}

/// Trains the NARX on the training record and scores it.
pub fn run_narx(data: &BenchmarkData) -> anyhow::Result<TestScores> {
    let tr = &data.train;
    let train = io_record("training record", &tr.u, Some(&tr.y), tr.ts);
    let model = narx_config()
        .fit(&train)
        .context("training the NARX on the benchmark's training record")?;
    let ts = tr.ts;
    benchmark::score_both(data, |u: &[f64]| -> anyhow::Result<Vec<f64>> {
        let rec = io_record("test input", u, None, ts);
        let p = model.predict(&rec, Mode::FreeRun)?;
        let p = &p[0];
        if let Some(k) = p.diverged_at {
            anyhow::bail!("the NARX free run diverged at sample {k}");
        }
        Ok(p.values.clone())
    })
}

/// Fits the grey-box model on the training record and scores it.
pub fn run_greybox(data: &BenchmarkData) -> anyhow::Result<(TestScores, benchmark::GreyBoxFit)> {
    let tr = &data.train;
    let fit = benchmark::fit_greybox(&tr.u, &tr.y, tr.ts, GREYBOX_MAX_ITER)?;
    let p = fit.params;
    let ts = tr.ts;
    let scores = benchmark::score_both(data, |u: &[f64]| -> anyhow::Result<Vec<f64>> {
        Ok(p.simulate(u, ts)?)
    })?;
    Ok((scores, fit))
}

/// `{"multisine_rms": …, "sinesweep_rms": …}` (shortest round-trip numbers).
fn json_scores(s: &TestScores) -> String {
    format!(
        "{{\"multisine_rms\": {:e}, \"sinesweep_rms\": {:e}}}",
        s.multisine_rms, s.sinesweep_rms
    )
}

/// The `--json` line, keys in the order `narx`, `greybox`.
pub fn json_line(narx: &TestScores, greybox: &TestScores) -> String {
    format!(
        "{{\"narx\": {}, \"greybox\": {}}}",
        json_scores(narx),
        json_scores(greybox)
    )
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let data_dir = args.data_dir.clone();
    let _spinner = crate::cli::progress::Progress::spinner(
        &format!("benchmark {:?} on {}", args.which, data_dir.display()),
        args.quiet,
    );
    if args.which == Which::MrDamper {
        return super::benchmark_mr::run(&data_dir, args.json, args.out.as_deref(), args.force);
    }
    if args.out.is_some() {
        anyhow::bail!("--out is only for `benchmark mr-damper`");
    }
    let data = benchmark::load(&data_dir).map_err(|e: BenchmarkError| anyhow::anyhow!(e))?;
    let t = std::time::Instant::now();
    let narx = run_narx(&data)?;
    let narx_secs = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let (grey, fit) = run_greybox(&data)?;
    let grey_secs = t.elapsed().as_secs_f64();
    if args.json {
        super::print(&json_line(&narx, &grey));
        return Ok(());
    }
    let mut s = String::new();
    s += "Bouc-Wen benchmark (Noël & Schoukens 2016): free-run RMS error in m\n";
    s += &format!(
        "data: {} (train {} samples, multisine {} (steady state: last of {} periods), sweep {} from rest)\n\n",
        data_dir.display(),
        data.train.u.len(),
        data.multisine.u.len(),
        benchmark::STEADY_STATE_PERIODS,
        data.sinesweep.u.len()
    );
    s += &format!(
        "{:<36} {:>12} {:>12}\n",
        "method", "multisine", "sine sweep"
    );
    s += &format!(
        "{:<36} {:>12.3e} {:>12.3e}   (this run, {narx_secs:.0} s)\n",
        format!("hystbench NARX ({NARX_LAGS} lags, {NARX_NEURONS} neurons)"),
        narx.multisine_rms,
        narx.sinesweep_rms
    );
    s += &format!(
        "{:<36} {:>12.3e} {:>12.3e}   (this run, {grey_secs:.0} s)\n",
        "hystbench grey-box (Bouc-Wen ODE)", grey.multisine_rms, grey.sinesweep_rms
    );
    for p in PUBLISHED {
        s += &format!(
            "{:<36} {:>12.3e} {:>12}   {}\n",
            p.method, p.multisine_rms, "-", p.source
        );
    }
    let g = fit.params;
    s += &format!(
        "\ngrey-box fit ({} LM iterations, training RMS {:.3e} -> {:.3e} m): m {:.4} kg, c {:.3} N s/m, \
         k {:.1} N/m, alpha {:.1} N/m, beta gamma {:.2} 1/m, beta delta {:.2} 1/m (beta = 1, nu = 1)\n",
        fit.iterations, fit.start_rms, fit.train_rms, g.mass_kg, g.damping_ns_per_m,
        g.stiffness_n_per_m, g.alpha, g.gamma, g.delta
    );
    s += "published values: docs/benchmarks.md (multisine only; no reliable sweep numbers found)\n";
    super::print(&s);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_line_is_valid_json_in_order() {
        let a = TestScores {
            multisine_rms: 2.0463097541448162e-5,
            sinesweep_rms: 1e-5,
        };
        let b = TestScores {
            multisine_rms: 1.5e-7,
            sinesweep_rms: 2.4e-6,
        };
        let line = json_line(&a, &b);
        assert!(
            line.starts_with("{\"narx\": {\"multisine_rms\": "),
            "{line}"
        );
        assert!(line.find("narx").unwrap() < line.find("greybox").unwrap());
        let v: serde_json::Value = serde_json::from_str(&line).unwrap();
        assert_eq!(v["narx"]["multisine_rms"].as_f64(), Some(a.multisine_rms));
        assert_eq!(v["greybox"]["sinesweep_rms"].as_f64(), Some(2.4e-6));
    }
}
