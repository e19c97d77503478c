//! Effects a model leaves out that are not hysteresis, creep or dynamics: a thermal drift, a
//! sensor that saturates, a backlash. The diagnosis of a model fitted without them names the
//! library's `drift` and `saturation` (the refit with them cuts the held-out error), the fit
//! with them brings the error near the noise, and the residual's description points at where
//! the error sits: a slow trend, the output's extremes, the input's reversals.

use hystbench::data::IoRecord;
use hystbench::diagnose::residual::Place;
use hystbench::diagnose::{diagnose_model, DiagnoseOptions, Diagnosis};
use hystbench::effect::EffectName;
use hystbench::graybox::{FittedGreyBox, GreyBoxConfig};
use hystbench::model::predict_finite;
use hystbench::plant::PlantSpec;
use hystbench::scenario::ScenarioSpec;
use hystbench::simulator::simulate_scenario;
use std::path::Path;

const NOISE: f64 = 0.01;

/// 1 kHz, 12 s: three sines, so that the input reverses at many levels.
const SCENARIO: &str = r#"{"name":"three_sines","sampling_period_s":0.001,"samples":12000,"seed":3,
 "noise_std":0.01,"inputs":[{"sum":[{"sine":{"amplitude":25,"frequency_hz":0.7}},
 {"sine":{"amplitude":10,"frequency_hz":1.9,"phase_rad":1}},{"sine":{"amplitude":5,"frequency_hz":4.3,"phase_rad":2}}]}]}"#;

/// A Bouc-Wen piezo (um per V) with `extra` output effects.
fn plant(hysteresis: &str, extra: &str) -> PlantSpec {
    let json = format!(
        r#"{{"name":"p","inputs":["u"],"outputs":[{{"name":"y_um","paths":[{{"input":"u","hysteresis":{hysteresis}}}]{extra}}}]}}"#
    );
    PlantSpec::parse(Path::new("p.json"), &json).unwrap()
}

const BW: &str = r#"{"bouc_wen":{"d":0.8,"A":0.3,"B":0.02,"Gamma":0.01}}"#;

fn record(p: &PlantSpec) -> IoRecord {
    let s = ScenarioSpec::parse(Path::new("s.json"), SCENARIO)
        .unwrap()
        .check(Path::new("s.json"))
        .unwrap();
    simulate_scenario(&p.check(Path::new("p.json")).unwrap(), &s, None)
        .unwrap()
        .record
}

fn fit(rec: &IoRecord, list: &str) -> (GreyBoxConfig, FittedGreyBox) {
    let config = GreyBoxConfig::from_effect_list(list).unwrap();
    let model = config.fit(rec).unwrap();
    (config, model)
}

fn diagnosis(rec: &IoRecord, list: &str) -> (Diagnosis, f64) {
    let (config, model) = fit(rec, list);
    let pred = predict_finite(&model, rec).unwrap();
    (
        diagnose_model(rec, &pred, &config, &DiagnoseOptions::default()),
        model.fit.rmse,
    )
}

/// The missing effect is named, the residual concentrates where it acts, and the fit with it
/// cuts the error to near the noise.
fn check(extra: &str, effect: EffectName, place: Place) {
    let rec = record(&plant(BW, extra));
    let (d, before) = diagnosis(&rec, "hysteresis");
    let shape = &d.outputs[0].residual;
    println!("{effect}: {:?}\n  {}", d.summary, shape.message);
    assert_eq!(d.missing, Some(effect), "{:?}", d.summary);
    assert_eq!(shape.place, Some(place), "{shape:?}");
    let (_, with) = fit(&rec, &format!("hysteresis,{effect}"));
    let after = with.fit.rmse;
    println!("{effect}: RMS error {before:.4} -> {after:.4} (noise {NOISE})");
    assert!(before / after >= 3.0, "{before} -> {after}");
    assert!(after < 2.0 * NOISE, "{after}");
}

#[test]
fn a_thermal_drift_is_named_found_in_a_slow_trend_and_fitted() {
    check(
        r#","drift":{"rate":0.03,"amplitudes":[0.8],"time_constants_s":[3.0]}"#,
        hystbench::effect::drift::NAME,
        Place::SlowTrend,
    );
}

#[test]
fn a_saturating_sensor_is_named_found_at_the_extremes_and_fitted() {
    // the Bouc-Wen output reaches +-23.7 um: the sensor clips the top at 18 um
    check(
        r#","saturation":{"upper":18.0}"#,
        hystbench::effect::saturation::NAME,
        Place::Extremes,
    );
}

#[test]
fn a_backlash_is_found_at_the_reversals() {
    // a play of 3 V (a backlash) with a linear part: a model without hysteresis leaves the
    // error just after each reversal of the input
    let pi = r#"{"prandtl_ishlinskii":{"linear_weight":0.3,"thresholds":[3.0],"weights":[0.5]}}"#;
    let rec = record(&plant(pi, ""));
    let (d, _) = diagnosis(&rec, "dynamics");
    let shape = &d.outputs[0].residual;
    println!("{:?}\n  {}", d.summary, shape.message);
    assert_eq!(shape.place, Some(Place::Reversals), "{shape:?}");
    // the library's play operators are a backlash: hysteresis is what it names
    assert_eq!(d.missing, Some(hystbench::effect::hysteresis::NAME));
}

/// From the command line: `diagnose --json` says where the residual sits, `--figure` draws it,
/// and an existing figure is not replaced without `--force`.
#[test]
fn diagnose_draws_where_the_residual_sits_from_the_command_line() {
    use std::process::Command;
    let bin = env!("CARGO_BIN_EXE_hystbench");
    let dir = tempfile::tempdir().unwrap();
    let at = |f: &str| dir.path().join(f);
    let p = plant(
        BW,
        r#","drift":{"rate":0.03,"amplitudes":[0.8],"time_constants_s":[3.0]}"#,
    );
    std::fs::write(at("p.json"), serde_json::to_string(&p).unwrap()).unwrap();
    std::fs::write(at("s.json"), SCENARIO).unwrap();
    let run = |args: &[&str]| Command::new(bin).args(args).output().unwrap();
    let s = |f: &str| at(f).to_string_lossy().into_owned();
    let o = run(&[
        "simulate",
        "--plant",
        &s("p.json"),
        "--scenario",
        &s("s.json"),
        "--out",
        &s("r.csv"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&[
        "fit",
        "--data",
        &s("r.csv"),
        "--outputs",
        "y_um",
        "--effects",
        "hysteresis",
        "--out",
        &s("m.json"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let diagnose = |force: bool| {
        let mut args = vec![
            "diagnose".to_string(),
            "--data".into(),
            s("r.csv"),
            "--model".into(),
            s("m.json"),
            "--json".into(),
            "--no-refit".into(),
            "--figure".into(),
            s("where.svg"),
        ];
        if force {
            args.push("--force".into());
        }
        Command::new(bin).args(&args).output().unwrap()
    };
    let o = diagnose(false);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["outputs"][0]["residual"]["where"], "slow_trend", "{v}");
    let svg = std::fs::read_to_string(at("where.svg")).unwrap();
    assert!(svg.contains("slow trend") && svg.contains("(here)"));
    // there already: refused without --force, the file untouched
    let o = diagnose(false);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--force"), "{err}");
    assert_eq!(std::fs::read_to_string(at("where.svg")).unwrap(), svg);
    assert!(diagnose(true).status.success());
}
