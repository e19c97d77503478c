//! # `hystbench benchmark mr-damper`
//!
//! Trains the NARX and the grey-box (Spencer's Bouc-Wen model with viscous damping, scheduled
//! in the coil current) on the 1 ms sine records of the measured MR damper and scores their
//! free runs on the earthquake record, per current. See [`crate::benchmark::mr_damper`].
//!
//! ## References
//! - B. F. Spencer Jr. et al., J. Eng. Mech. 123(3):230-238, 1997.

use crate::benchmark::mr_damper::{self, CurrentScore, MrDamperResult, NARX_DECIMATION};
use crate::data::OutputGuard;
use anyhow::Context;
use std::fmt::Write as _;
use std::path::Path;

/// `{"0.2": {"r2": …, "rms_n": …}, …}`; a diverged run is `{"diverged": true}`.
fn json_scores(v: &[CurrentScore]) -> String {
    let items: Vec<String> = v
        .iter()
        .map(|s| {
            let key = format!("{}", s.current);
            match (s.r2, s.rms_n) {
                (Some(r2), Some(rms)) => {
                    format!("\"{key}\": {{\"r2\": {r2:e}, \"rms_n\": {rms:e}}}")
                }
                (None, Some(rms)) => format!("\"{key}\": {{\"r2\": null, \"rms_n\": {rms:e}}}"),
                _ => format!("\"{key}\": {{\"diverged\": true}}"),
            }
        })
        .collect();
    format!("{{{}}}", items.join(", "))
}

/// The `--json` object: `narx`, `greybox` (scheduled), `greybox_per_current`, training times.
pub fn json_line(r: &MrDamperResult) -> String {
    format!(
        "{{\"narx\": {}, \"greybox\": {}, \"greybox_per_current\": {}, \"narx_train_s\": {:.1}, \"greybox_train_s\": {:.1}}}",
        json_scores(&r.narx),
        json_scores(&r.greybox),
        json_scores(&r.greybox_per_current),
        r.narx_seconds,
        r.greybox_seconds
    )
}

fn cell(s: &CurrentScore) -> String {
    match (s.r2, s.rms_n) {
        (Some(r2), Some(rms)) => format!("{r2:>8.4} {rms:>8.1}"),
        (None, Some(rms)) => format!("{:>8} {rms:>8.1}", "-"),
        _ => format!("{:>17}", "diverged"),
    }
}

/// The printed report.
pub fn table(r: &MrDamperResult, data_dir: &Path) -> String {
    let mut s = String::new();
    s += "MR damper (mr-damper-utfsm): free run on the earthquake record, per current\n";
    let _ = writeln!(
        s,
        "data: {}; training: the ten 1 ms sine records (10 mm @ 1 Hz, 5 mm @ 3 Hz; 0, 0.25, 0.5, 0.75, 1.0 A), {} samples; test: earthquake record, {} samples at 1 ms, from rest",
        data_dir.display(),
        r.train_samples,
        r.test_samples
    );
    let _ = writeln!(
        s,
        "NARX: inputs x, I; output F; records subsampled 1:{NARX_DECIMATION} (10 ms), {} lags, {} neurons, seed {}, scored at 10 ms",
        mr_damper::NARX_LAGS,
        mr_damper::NARX_NEURONS,
        mr_damper::NARX_SEED
    );
    s += "grey-box: F = c0 dx/dt + k0 x + alpha z + f0, z Bouc-Wen (n = 1) on x (Spencer et al. 1997);\n";
    s += "  scheduled: (B, Gamma) shared, c0, k0, alpha, f0 affine in I; per-current: one fit per training current, parameters interpolated in I\n\n";
    let _ = writeln!(
        s,
        "{:>6} | {:>17} | {:>17} | {:>17}",
        "I (A)", "NARX", "grey-box sched.", "grey-box per-I"
    );
    let _ = writeln!(
        s,
        "{:>6} | {:>8} {:>8} | {:>8} {:>8} | {:>8} {:>8}",
        "", "R^2", "RMS (N)", "R^2", "RMS (N)", "R^2", "RMS (N)"
    );
    for k in 0..r.greybox.len() {
        let _ = writeln!(
            s,
            "{:>6} | {} | {} | {}",
            r.greybox[k].current,
            cell(&r.narx[k]),
            cell(&r.greybox[k]),
            cell(&r.greybox_per_current[k])
        );
    }
    let _ = writeln!(
        s,
        "\ntraining time: NARX {:.1} s, grey-box (both) {:.1} s",
        r.narx_seconds, r.greybox_seconds
    );
    let f = &r.scheduled;
    let _ = writeln!(
        s,
        "scheduled grey-box (training RMS {:.1} N): B {:.4} 1/mm, Gamma {:.4} 1/mm; c0 {:.3} + {:.3} I N s/mm, k0 {:.2} + {:.2} I N/mm, alpha {:.1} + {:.1} I N/mm, f0 {:.1} + {:.1} I N",
        f.train_rms_n, f.b, f.gamma, f.coef[0], f.coef[4], f.coef[1], f.coef[5], f.coef[2], f.coef[6], f.coef[3], f.coef[7]
    );
    for (i, p) in &r.per_current.fits {
        let _ = writeln!(
            s,
            "  per-current {i:.2} A (training RMS {:.1} N): B {:.4}, Gamma {:.4}, c0 {:.3}, k0 {:.2}, alpha {:.1}, f0 {:.1}",
            p.train_rms_n, p.b, p.gamma, p.coef[0], p.coef[1], p.coef[2], p.coef[3]
        );
    }
    s
}

fn write_out(r: &MrDamperResult, dir: &Path, force: bool) -> anyhow::Result<()> {
    if !dir.is_dir() {
        anyhow::bail!("--out {}: no such folder (create it first)", dir.display());
    }
    let mut guard = OutputGuard::new(force);
    for ((i, sched, per), (_, narx)) in r.predictions.greybox.iter().zip(&r.predictions.narx) {
        let path = dir.join(format!("greybox_I{i:.1}A.csv"));
        let t: Vec<f64> = (0..sched.len()).map(|k| k as f64 * 1e-3).collect();
        let text = crate::data::format_csv(
            &path,
            &[
                "t_s".into(),
                "F_scheduled_N".into(),
                "F_per_current_N".into(),
            ],
            &[t, sched.clone(), per.clone()],
        )?;
        guard.stage(&path, text.as_bytes())?;
        if let Some(p) = narx {
            let path = dir.join(format!("narx_I{i:.1}A.csv"));
            let t: Vec<f64> = (0..p.len())
                .map(|k| k as f64 * 1e-3 * NARX_DECIMATION as f64)
                .collect();
            let text =
                crate::data::format_csv(&path, &["t_s".into(), "F_N".into()], &[t, p.clone()])?;
            guard.stage(&path, text.as_bytes())?;
        }
    }
    let path = dir.join("mr_damper_result.json");
    guard.stage(&path, (json_line(r) + "\n").as_bytes())?;
    guard.commit()?;
    Ok(())
}

pub fn run(data_dir: &Path, json: bool, out: Option<&Path>, force: bool) -> anyhow::Result<()> {
    let data = mr_damper::load(data_dir)?;
    let r = mr_damper::run(&data).context("the MR damper study")?;
    if let Some(dir) = out {
        write_out(&r, dir, force)?;
    }
    if json {
        super::print(&json_line(&r));
    } else {
        super::print(&table(&r, data_dir));
    }
    Ok(())
}
