//! `hystbench fit` end to end: 40,000-sample records at 1 kHz with columns `t,u,y` and
//! `t,u1,u2,y1,y2`, the `--json` summary, the model file, and bad input (clear errors,
//! nothing written).

use hystbench::graybox::FittedGreyBox;
use hystbench::plant::EffectSpecs;
use std::path::{Path, PathBuf};

mod common;
use common::{hystbench as run, s, stderr, write};

/// A hidden-plant-like 1-DoF: Bouc-Wen (about 12 % hysteresis), 1.5 %/decade creep, 80 Hz mode.
const PLANT_1: &str = r#"{"name": "p1", "inputs": ["u"], "outputs": [{"name": "y", "offset": 2.0,
  "paths": [{"input": "u", "hysteresis": {"bouc_wen": {"d": 0.6, "A": 0.2, "B": 0.03, "Gamma": 0.005}}}],
  "creep": {"time_constants_s": [0.3, 3.0, 30.0], "percent_per_decade": 1.5},
  "dynamics": {"natural_frequency_hz": 80.0, "damping_ratio": 0.04}}]}"#;

const SCENARIO_1: &str = r#"{"name": "s1", "sampling_period_s": 0.001, "samples": 40000, "noise_std": 0.005, "seed": 3,
  "inputs": [{"concat": [
    {"duration_s": 10.0, "excitation": {"decaying_sine": {"amplitude": 30.0, "frequency_hz": 0.8, "decay_time_s": 6.0}}},
    {"duration_s": 15.0, "excitation": {"staircase": {"levels": [15.0, -20.0, 25.0, 0.0, -10.0], "hold_s": 3.0}}},
    {"duration_s": 15.0, "excitation": {"random_steps": {"amplitude": 25.0, "min_hold_s": 0.05, "max_hold_s": 1.0}}}
  ]}]}"#;

/// A hidden-plant-like 2-DoF: PI direct paths, Bouc-Wen cross paths, 150 Hz and 220 Hz modes.
const PLANT_2: &str = r#"{"name": "p2", "inputs": ["u1", "u2"], "outputs": [
  {"name": "y1", "paths": [
     {"input": "u1", "hysteresis": {"prandtl_ishlinskii": {"linear_weight": 0.5, "thresholds": [5.0, 10.0, 15.0, 20.0], "weights": [0.08, 0.05, 0.03, 0.02]}}},
     {"input": "u2", "hysteresis": {"bouc_wen": {"d": 0.1, "A": 0.05, "B": 0.03, "Gamma": 0.01}}}],
   "dynamics": {"natural_frequency_hz": 150.0, "damping_ratio": 0.03}},
  {"name": "y2", "paths": [
     {"input": "u1", "hysteresis": {"bouc_wen": {"d": 0.07, "A": 0.03, "B": 0.03, "Gamma": 0.0}}},
     {"input": "u2", "hysteresis": {"prandtl_ishlinskii": {"linear_weight": 0.7, "thresholds": [6.0, 12.0, 18.0], "weights": [0.1, 0.06, 0.03]}}}],
   "dynamics": {"natural_frequency_hz": 220.0, "damping_ratio": 0.06}}]}"#;

const SCENARIO_2: &str = r#"{"name": "s2", "sampling_period_s": 0.001, "samples": 40000, "noise_std": 0.0, "seed": 4,
  "inputs": [
    {"sum": [{"decaying_sine": {"amplitude": 25.0, "frequency_hz": 0.5, "decay_time_s": 15.0}},
             {"random_steps": {"amplitude": 3.0, "min_hold_s": 0.02, "max_hold_s": 0.2}}]},
    {"sum": [{"decaying_sine": {"amplitude": 25.0, "frequency_hz": 0.7, "decay_time_s": 12.0, "phase_rad": 1.0}},
             {"random_steps": {"amplitude": 3.0, "min_hold_s": 0.02, "max_hold_s": 0.2}}]}]}"#;

fn simulate(dir: &Path, plant: &str, scenario: &str, name: &str) -> PathBuf {
    let p = write(dir, &format!("{name}_plant.json"), plant);
    let s = write(dir, &format!("{name}_scenario.json"), scenario);
    let out = dir.join(format!("{name}.csv"));
    let o = run(&[
        "simulate",
        "--plant",
        p.to_str().unwrap(),
        "--scenario",
        s.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    out
}

/// Whether `v` holds no null and no string that spells a non-finite number.
fn no_nan_or_null(v: &serde_json::Value) -> bool {
    match v {
        serde_json::Value::Null => false,
        serde_json::Value::String(s) => !matches!(s.as_str(), "NaN" | "inf" | "-inf"),
        serde_json::Value::Array(a) => a.iter().all(no_nan_or_null),
        serde_json::Value::Object(o) => o.values().all(no_nan_or_null),
        _ => true,
    }
}

fn fit_json(data: &Path, effects: &str, out: &Path) -> serde_json::Value {
    fit_json_with(data, effects, out, &[])
}

fn fit_json_with(data: &Path, effects: &str, out: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "fit",
        "--data",
        data.to_str().unwrap(),
        "--effects",
        effects,
        "--out",
        out.to_str().unwrap(),
        "--json",
    ];
    args.extend_from_slice(extra);
    let o = run(&args);
    assert!(o.status.success(), "{effects}: {}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    eprintln!("{effects}: {v}");
    v
}

#[test]
fn fits_a_40k_sample_siso_record_at_1khz() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate(dir.path(), PLANT_1, SCENARIO_1, "siso");
    let text = std::fs::read_to_string(&data).unwrap();
    assert!(text.starts_with("t,u,y\n"));
    let full = fit_json(
        &data,
        "hysteresis,creep,dynamics",
        &dir.path().join("m.json"),
    );
    let keys: Vec<&String> = full.as_object().unwrap().keys().collect();
    assert_eq!(keys, ["effects", "r2", "rmse"]);
    assert_eq!(
        full["effects"],
        serde_json::json!(["hysteresis", "creep", "dynamics"])
    );
    // noise 0.005; the creep chain (one time constant per decade at powers of ten) only
    // approximates the plant's 0.3, 3, 30 s chain
    let rmse = full["rmse"].as_f64().unwrap();
    assert!(rmse < 0.02, "rmse {rmse}");
    assert!(full["r2"].as_f64().unwrap() > 0.9999);
    let m = FittedGreyBox::load(&dir.path().join("m.json")).unwrap();
    let d = *m.plant.spec.outputs[0]
        .get::<hystbench::effect::dynamics::DynamicsSpec>()
        .unwrap();
    assert!((d.natural_frequency_hz - 80.0).abs() < 0.8, "{d:?}");
    let v = fit_json(
        &data,
        "hysteresis,dynamics",
        &dir.path().join("m_creep.json"),
    );
    let ratio = v["rmse"].as_f64().unwrap() / rmse;
    assert!(ratio >= 3.0, "without creep: ratio {ratio}");
}

/// The same record without each effect in turn (long: run with --ignored).
#[test]
#[ignore]
fn siso_40k_without_each_effect() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate(dir.path(), PLANT_1, SCENARIO_1, "siso");
    let full = fit_json(
        &data,
        "hysteresis,creep,dynamics",
        &dir.path().join("m.json"),
    );
    let rmse = full["rmse"].as_f64().unwrap();
    for (effects, name) in [
        ("creep,dynamics", "hysteresis"),
        ("hysteresis,dynamics", "creep"),
        ("hysteresis,creep", "dynamics"),
    ] {
        let v = fit_json(&data, effects, &dir.path().join(format!("m_{name}.json")));
        let ratio = v["rmse"].as_f64().unwrap() / rmse;
        assert!(ratio >= 3.0, "without {name}: ratio {ratio}");
    }
}

#[test]
fn fits_a_40k_sample_mimo_record_at_1khz() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate(dir.path(), PLANT_2, SCENARIO_2, "mimo");
    let text = std::fs::read_to_string(&data).unwrap();
    assert!(text.starts_with("t,u1,u2,y1,y2\n"));
    // 15 plays per path keep the test short (the default is 39)
    let plays = ["--plays", "15"];
    let full = fit_json_with(
        &data,
        "hysteresis,dynamics,coupling",
        &dir.path().join("m.json"),
        &plays,
    );
    assert_eq!(
        full["effects"],
        serde_json::json!(["hysteresis", "dynamics", "coupling"])
    );
    let outs = full["outputs"].as_object().unwrap();
    assert_eq!(outs.keys().collect::<Vec<_>>(), ["y1", "y2"]);
    let (r1, r2) = (
        outs["y1"]["r2"].as_f64().unwrap(),
        outs["y2"]["r2"].as_f64().unwrap(),
    );
    assert!(r1 >= 0.9999 && r2 >= 0.9999, "{r1} {r2}");
    let mean = full["r2"].as_f64().unwrap();
    assert!((mean - 0.5 * (r1 + r2)).abs() < 1e-12);
    let without = fit_json_with(
        &data,
        "hysteresis,dynamics",
        &dir.path().join("m2.json"),
        &plays,
    );
    let ratio = without["rmse"].as_f64().unwrap() / full["rmse"].as_f64().unwrap();
    assert!(ratio >= 3.0, "without coupling: ratio {ratio}");
}

fn fit_err(dir: &Path, data: &Path, effects: &str) -> String {
    let out = dir.join("bad.json");
    let o = run(&[
        "fit",
        "--data",
        data.to_str().unwrap(),
        "--effects",
        effects,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success(), "{effects} should fail");
    assert!(!out.exists(), "nothing may be written");
    stderr(&o)
}

/// A short csv: `n` samples of a sine of frequency `f` (Hz) at 1 kHz, y = 0.8 u.
fn csv(dir: &Path, name: &str, n: usize, f: f64, two: bool) -> PathBuf {
    let mut s = if two {
        "t,u1,u2,y1,y2\n".to_string()
    } else {
        "t,u,y\n".to_string()
    };
    for k in 0..n {
        let t = k as f64 * 1e-3;
        let u = 10.0 * (2.0 * std::f64::consts::PI * f * t).sin();
        if two {
            s += &format!("{t},{u},{},{},{}\n", 0.5 * u, 0.8 * u, 0.3 * u);
        } else {
            s += &format!("{t},{u},{}\n", 0.8 * u);
        }
    }
    write(dir, name, &s)
}

#[test]
fn bad_input_gives_clear_errors_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let siso = csv(d, "siso.csv", 3000, 2.0, false);
    let e = fit_err(d, &siso, "hysteresis,friction");
    assert!(
        e.contains("unknown effect `friction`")
            && e.contains("hysteresis, creep, dynamics, coupling"),
        "{e}"
    );
    let e = fit_err(d, &siso, "hysteresis,coupling");
    assert!(
        e.contains("coupling") && e.contains("several inputs"),
        "{e}"
    );
    // 0.3 s at 1 kHz: too short for creep over two decades, creep gets the parsimonious time
    // constants that fit between 5 samples and a third of the record (10 and 100 ms)
    let short = csv(d, "short.csv", 300, 20.0, false);
    let m = d.join("short_model.json");
    let o = run(&[
        "fit",
        "--data",
        short.to_str().unwrap(),
        "--effects",
        "hysteresis,creep",
        "--out",
        m.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&m).unwrap()).unwrap();
    assert_eq!(
        v["plant"]["outputs"][0]["creep"]["time_constants_s"],
        serde_json::json!([0.01, 0.1]),
        "{v}"
    );
    // a fast sine and no holds: creep cannot be seen
    let fast = csv(d, "fast.csv", 40000, 100.0, false);
    let e = fit_err(d, &fast, "hysteresis,creep");
    assert!(
        e.contains("poorly excited for creep") && e.contains("holds"),
        "{e}"
    );
    // a ramp never reverses: no hysteresis loop
    let mut ramp = "t,u,y\n".to_string();
    for k in 0..2000 {
        ramp += &format!(
            "{},{},{}\n",
            k as f64 * 1e-3,
            k as f64 * 0.01,
            k as f64 * 0.008
        );
    }
    let ramp = write(d, "ramp.csv", &ramp);
    let e = fit_err(d, &ramp, "hysteresis");
    assert!(
        e.contains("poorly excited for hysteresis") && e.contains("reverses"),
        "{e}"
    );
    let tiny = csv(d, "tiny.csv", 50, 2.0, false);
    let e = fit_err(d, &tiny, "hysteresis");
    assert!(e.contains("50 samples") && e.contains("at least"), "{e}");
    // columns not in the record
    let out = d.join("m.json");
    let o = run(&[
        "fit",
        "--data",
        siso.to_str().unwrap(),
        "--effects",
        "hysteresis",
        "--inputs",
        "v",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success() && !out.exists());
    assert!(stderr(&o).contains("`v`"), "{}", stderr(&o));
    // without --force an existing model is kept
    std::fs::write(&out, "keep").unwrap();
    let o = run(&[
        "fit",
        "--data",
        siso.to_str().unwrap(),
        "--effects",
        "none",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "keep");
    let o = run(&[
        "fit",
        "--data",
        siso.to_str().unwrap(),
        "--effects",
        "none",
        "--out",
        out.to_str().unwrap(),
        "--force",
        "--train-fraction",
        "0.5",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = FittedGreyBox::load(&out).unwrap();
    assert_eq!(m.fit.train_samples, 1500);
    assert!(m.fit.scored_on.contains("held-out"));
    assert!(m.fit.r2.unwrap() > 0.999999);
}

#[test]
fn model_files_round_trip_and_damaged_ones_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = csv(d, "mimo.csv", 4000, 3.0, true);
    let out = d.join("m.json");
    let o = run(&[
        "fit",
        "--data",
        data.to_str().unwrap(),
        "--effects",
        "hysteresis,dynamics",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["outputs"]["y1"]["rmse"].is_number() && v["outputs"]["y2"]["r2"].is_number());
    // the summary names the variants fitted, as `--effects` does
    let variants = fit_json(&data, "bouc-wen,modes", &dir.path().join("variants.json"));
    assert_eq!(
        variants["effects"],
        serde_json::json!(["bouc-wen", "modes"])
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let file: serde_json::Value = serde_json::from_str(&text).unwrap();
    // a NaN would be written as null (or a string): none anywhere in the model (read from the
    // parsed file, not its text, which may name a temporary folder holding "NaN")
    assert!(no_nan_or_null(&file), "{text}");
    assert_eq!(file["format"], "hystbench-greybox");
    assert_eq!(file["version"], 1);
    assert_eq!(
        file["effects"],
        serde_json::json!(["hysteresis", "dynamics"])
    );
    assert_eq!(file["inputs"], serde_json::json!(["u1", "u2"]));
    for key in [
        "rmse",
        "r2",
        "outputs",
        "iterations",
        "converged",
        "seconds",
        "data_file",
        "sampling_period_s",
    ] {
        assert!(file["fit"].get(key).is_some(), "fit.{key} missing");
    }
    // the plant inside is a plant file
    let plant_path = write(d, "plant.json", &file["plant"].to_string());
    let plant = hystbench::plant::Plant::from_file(&plant_path).unwrap();
    assert_eq!(plant.outputs, ["y1", "y2"]);
    // the loaded model simulates the record as well as the fit said
    let m = FittedGreyBox::load(&out).unwrap();
    let rec = hystbench::data::read_csv(&data).unwrap();
    let io = hystbench::data::IoRecord::from_record(&rec, None, None, true).unwrap();
    let s = m.scores(&io, 0..io.len()).unwrap();
    assert!((s[0].rmse - m.fit.outputs[0].rmse).abs() < 1e-12);
    // another format, another version, damaged text
    let other = text.replace("hystbench-greybox", "hystbench-narx");
    let e = FittedGreyBox::parse(&out, &other).unwrap_err().to_string();
    assert!(e.contains("not a grey-box model file"), "{e}");
    let v2 = text.replace("\"version\": 1", "\"version\": 2");
    let e = FittedGreyBox::parse(&out, &v2).unwrap_err().to_string();
    assert!(e.contains("version 2 is not supported"), "{e}");
    // cut at a line end half-way (a cut inside a number, such as the fit's time, would read
    // as an invalid number rather than an early end)
    let cut = text[..text.len() / 2].rfind('\n').unwrap();
    let e = FittedGreyBox::parse(&out, &text[..cut])
        .unwrap_err()
        .to_string();
    assert!(e.contains("line") && e.contains("EOF while parsing"), "{e}");
    // a play threshold below 0 (every model of this record has plays; its outputs have no
    // mode of their own, so the fit keeps no dynamics)
    let bad = text.replacen("\"thresholds\": [", "\"thresholds\": [-1.0, ", 1);
    let e = FittedGreyBox::parse(&out, &bad).unwrap_err().to_string();
    assert!(e.contains("thresholds"), "{e}");
}

/// `hystbench` with the machine's available memory set to `bytes`
/// (`hystbench::data::memory::AVAILABLE_VARIABLE`).
fn run_with_memory(bytes: u64, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_hystbench"))
        .args(args)
        .env(
            hystbench::data::memory::AVAILABLE_VARIABLE,
            bytes.to_string(),
        )
        .output()
        .expect("run hystbench")
}

#[test]
fn a_record_too_large_for_memory_is_refused_before_the_work() {
    use hystbench::data::memory::Work;
    let dir = tempfile::tempdir().unwrap();
    let n = 20_000;
    let data = csv(dir.path(), "long.csv", n, 2.0, false);
    let text = std::fs::metadata(&data).unwrap().len();
    let fit_needs = Work::GreyBoxFit.bytes(n, 1, 3);
    assert!(
        text < fit_needs,
        "the test needs a fit that outgrows the reading"
    );
    let out = dir.path().join("m.json");
    let fit = |available: u64, extra: &[&str]| {
        let mut args = vec![
            "fit",
            "--data",
            s(&data),
            "--effects",
            "hysteresis",
            "--out",
            s(&out),
        ];
        args.extend_from_slice(extra);
        run_with_memory(available, &args)
    };
    // room to read the file and predict it, not to fit it: refused with the size, both
    // figures, advice
    let room = text + Work::Prediction.bytes(n, 1, 3);
    assert!(room < fit_needs);
    let o = fit(room, &[]);
    let e = stderr(&o);
    assert!(!o.status.success() && !out.exists(), "{e}");
    for needle in [
        "long.csv",
        "a grey-box fit on 20000 samples needs about",
        "available",
        "hystbench split",
        "--train-fraction",
    ] {
        assert!(e.contains(needle), "`{needle}` missing from: {e}");
    }
    // the fit's memory goes with the part it fits: a tenth of the record fits in that room
    assert!(Work::GreyBoxFit.bytes(n / 10, 1, 3) < room);
    let o = fit(room, &["--train-fraction", "0.1"]);
    assert!(o.status.success() && out.exists(), "{}", stderr(&o));
    std::fs::remove_file(&out).unwrap();
    // not even room to read it: refused before reading, by the file's size
    let o = run_with_memory(
        text - 1,
        &[
            "plot",
            "loop",
            "--data",
            s(&data),
            "--out",
            s(&dir.path().join("l.png")),
        ],
    );
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("reading the file needs about"),
        "{e}"
    );
    assert!(!dir.path().join("l.png").exists());
    // with the room the estimate asks for, the fit runs
    let o = fit(fit_needs + text, &[]);
    assert!(o.status.success() && out.exists(), "{}", stderr(&o));
}

/// The fit gives the same model file, bit for bit but the time, whatever instructions the hot
/// loops use (`hystbench::numeric::simd`: the baseline build, AVX2, and the widest the processor
/// has: AVX-512 here when it has it).
#[test]
fn the_fit_is_the_same_bits_whatever_the_instructions() {
    use hystbench::numeric::simd::SIMD_VARIABLE;
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("r.csv");
    let root = common::root();
    let sim = run(&[
        "simulate",
        "--plant",
        s(&root.join("plants/hidden_creep_piezo.json")),
        "--scenario",
        s(&root.join("scenarios/hidden_effect_1khz.json")),
        "--out",
        s(&data),
    ]);
    assert!(sim.status.success(), "{}", stderr(&sim));
    let fit = |level: Option<&str>| -> String {
        let out = dir
            .path()
            .join(format!("m-{}.json", level.unwrap_or("widest")));
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_hystbench"));
        cmd.args(["fit", "--data", s(&data), "--effects"])
            .args(["hysteresis,creep,dynamics", "--out", s(&out), "--quiet"])
            .env_remove(SIMD_VARIABLE);
        if let Some(level) = level {
            cmd.env(SIMD_VARIABLE, level);
        }
        let o = cmd.output().expect("run hystbench");
        assert!(o.status.success(), "{}", stderr(&o));
        let text = std::fs::read_to_string(&out).unwrap();
        // every line but the fit's time
        text.lines()
            .filter(|l| !l.contains("seconds"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let widest = fit(None);
    assert!(widest.contains("creep"), "a model with creep");
    assert_eq!(fit(Some("baseline")), widest, "the baseline build differs");
    assert_eq!(fit(Some("avx2")), widest, "the AVX2 build differs");
    if !hystbench::numeric::simd::uses_avx512() {
        eprintln!(
            "note: no AVX-512 here, the widest level is {:?}",
            hystbench::numeric::simd::level()
        );
    }
}
