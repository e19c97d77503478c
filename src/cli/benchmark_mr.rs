//! # `hystbench benchmark mr-damper`
//!
//! Trains the NARX (on the 1 ms sine records) and the grey-box models (Spencer's simple and
//! full Bouc-Wen models, a Bingham plastic; on every sine record) of the measured MR damper and
//! scores their free runs on the earthquake record, per current. See [`hystbench::benchmark::mr_damper`].
//!
//! ## References
//! - B. F. Spencer Jr. et al., J. Eng. Mech. 123(3):230-238, 1997.

use anyhow::Context;
use hystbench::benchmark::mr_damper::{
    self, CurrentScore, MrDamperResult, SpencerParams, Structure, NARX_DECIMATION,
};
use hystbench::data::OutputGuard;
use std::fmt::Write as _;
use std::path::Path;

/// `{"0.2": {"r2": …, "rms_n": …}, …}`; a diverged run is `{"diverged": true}`.
fn json_scores(v: &[CurrentScore]) -> String {
    let items: Vec<String> = v
        .iter()
        .map(|s| {
            let key = format!("{:.1}", s.current);
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

/// The `--json` object: `narx`, `greybox` (the headline variant, chosen by cross-validation
/// on the training records), `greybox_model`, every variant under `greybox_all`, training times.
pub fn json_line(r: &MrDamperResult) -> String {
    let all: Vec<String> = r
        .greybox
        .iter()
        .map(|v| format!("\"{}\": {}", v.name(), json_scores(&v.scores)))
        .collect();
    format!(
        "{{\"narx\": {}, \"greybox\": {}, \"greybox_model\": \"{}\", \"greybox_all\": {{{}}}, \"narx_train_s\": {:.1}, \"greybox_train_s\": {:.1}}}",
        json_scores(&r.narx),
        json_scores(&r.greybox[r.headline].scores),
        r.greybox[r.headline].name(),
        all.join(", "),
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
    if !r.other_files.is_empty() {
        let _ = writeln!(
            s,
            "grey-box training also: {} other sine records ({} samples, each at its own sampling period): {}",
            r.other_files.len(),
            r.other_samples,
            r.other_files.join(", ")
        );
    }
    let _ = writeln!(
        s,
        "NARX: inputs x, I; output F; records subsampled 1:{NARX_DECIMATION} (10 ms), {} lags, {} neurons, seed {}, scored at 10 ms",
        mr_damper::NARX_LAGS,
        mr_damper::NARX_NEURONS,
        mr_damper::NARX_SEED
    );
    s += "grey-box: F = c0 dx/dt + k0 x + alpha g + f0; bouc-wen: g = z, Bouc-Wen (n = 1) on x (Spencer et al. 1997);\n";
    s += "  bingham: g = tanh((dx/dt) / v0) (smoothed Bingham plastic); scheduled: one model, c0, k0, alpha, f0 affine in I;\n";
    s += "  spencer-full: Spencer et al.'s full model, the Bouc-Wen element (c0, k0, alpha) in series with the pre-yield dashpot c1,\n";
    s += "  F = c1 dy/dt + k1 x + f0 (scheduled: c0, alpha, c1 affine in I, the rest shared);\n";
    s += "  per-current: one fit per training current, every parameter interpolated linearly in I\n\n";
    let _ = write!(s, "{:>6} | {:>17}", "I (A)", "NARX");
    for v in &r.greybox {
        let _ = write!(s, " | {:>21}", v.name());
    }
    s += "\n";
    let _ = write!(s, "{:>6} | {:>8} {:>8}", "", "R^2", "RMS (N)");
    for _ in &r.greybox {
        let _ = write!(s, " |     {:>8} {:>8}", "R^2", "RMS (N)");
    }
    s += "\n";
    for k in 0..r.narx.len() {
        let _ = write!(s, "{:>6.1} | {}", r.narx[k].current, cell(&r.narx[k]));
        for v in &r.greybox {
            let _ = write!(s, " |     {}", cell(&v.scores[k]));
        }
        s += "\n";
    }
    let _ = writeln!(
        s,
        "\ngrey-box choice (training records only): leave-one-test-out RMS, scheduled: {}; headline: {}",
        r.greybox
            .iter()
            .filter_map(|v| v.cv_rms_n.map(|c| format!("{} {c:.1} N", v.structure.as_str())))
            .collect::<Vec<_>>()
            .join(", "),
        r.greybox[r.headline].name()
    );
    let _ = writeln!(
        s,
        "training time: NARX {:.1} s, grey-box (all {}, with cross-validation) {:.1} s",
        r.narx_seconds,
        r.greybox.len(),
        r.greybox_seconds
    );
    for v in &r.greybox {
        if let Some(f) = &v.fit {
            let (p0, p1) = (f.at(0.0), f.at(1.0));
            let _ = writeln!(
                s,
                "{} (training RMS {:.1} N): {}; c0 {:.3} + {:.3} I N s/mm, k0 {:.2} + {:.2} I N/mm, alpha {:.1} + {:.1} I N, f0 {:.1} + {:.1} I N{}",
                v.name(), f.train_rms_n, shape(&p0), p0.c0, p1.c0 - p0.c0, p0.k0, p1.k0 - p0.k0, p0.alpha, p1.alpha - p0.alpha, p0.f0, p1.f0 - p0.f0, series(&p0, &p1)
            );
        }
        if let Some(pc) = &v.per_current {
            for (i, f) in &pc.fits {
                let p = f.at(*i);
                let _ = writeln!(
                    s,
                    "  {} {i:.2} A (training RMS {:.1} N): {}, c0 {:.3}, k0 {:.2}, alpha {:.1}, f0 {:.1}{}",
                    v.name(), f.train_rms_n, shape(&p), p.c0, p.k0, p.alpha, p.f0, series(&p, &p)
                );
            }
        }
    }
    s
}

/// The shape parameters of a structure, for the report.
fn shape(p: &SpencerParams) -> String {
    match p.structure {
        Structure::BoucWen | Structure::Spencer => {
            format!("B {:.4} 1/mm, Gamma {:.4} 1/mm", p.b, p.gamma)
        }
        Structure::Bingham => format!("v0 {:.3} mm/s", p.v0),
    }
}

/// The full model's series dashpot and accumulator spring (nothing for the simple models); at
/// I = 0 with the slope to I = 1 A.
fn series(p0: &SpencerParams, p1: &SpencerParams) -> String {
    if p0.structure != Structure::Spencer {
        return String::new();
    }
    if p0 == p1 {
        return format!(", c1 {:.2} N s/mm, k1 {:.3} N/mm", p0.c1, p0.k1);
    }
    format!(
        ", c1 {:.2} + {:.2} I N s/mm, k1 {:.3} N/mm",
        p0.c1,
        p1.c1 - p0.c1,
        p0.k1
    )
}

fn write_out(r: &MrDamperResult, dir: &Path, force: bool) -> anyhow::Result<()> {
    if !dir.is_dir() {
        anyhow::bail!("--out {}: no such folder (create it first)", dir.display());
    }
    let mut guard = OutputGuard::new(force);
    for (k, (i, _)) in r.greybox[0]
        .scores
        .iter()
        .map(|s| (s.current, ()))
        .enumerate()
    {
        let path = dir.join(format!("greybox_I{i:.1}A.csv"));
        let n = r.greybox[0].predictions[k].len();
        let mut names = vec!["t_s".to_string()];
        let mut cols = vec![(0..n).map(|j| j as f64 * 1e-3).collect::<Vec<f64>>()];
        for v in &r.greybox {
            names.push(format!("F_{}_N", v.name().replace(' ', "_")));
            cols.push(v.predictions[k].clone());
        }
        guard.stage_csv(&path, &names, &cols)?;
        if let Some(p) = &r.narx_predictions[k] {
            let path = dir.join(format!("narx_I{i:.1}A.csv"));
            let t: Vec<f64> = (0..p.len())
                .map(|j| j as f64 * 1e-3 * NARX_DECIMATION as f64)
                .collect();
            guard.stage_csv(&path, &["t_s".into(), "F_N".into()], &[t, p.clone()])?;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_keys_are_the_currents_and_diverged_is_not_a_number() {
        let v = vec![
            CurrentScore {
                current: 0.2,
                r2: Some(0.9),
                rms_n: Some(12.5),
            },
            CurrentScore {
                current: 1.0,
                r2: None,
                rms_n: None,
            },
        ];
        let text = json_scores(&v);
        let j: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(j["0.2"]["r2"].as_f64(), Some(0.9));
        assert_eq!(j["0.2"]["rms_n"].as_f64(), Some(12.5));
        assert_eq!(j["1.0"]["diverged"].as_bool(), Some(true));
        assert!(j["1.0"].get("rms_n").is_none());
    }
}
