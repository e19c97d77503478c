//! Golden comparison: the effect library against an independent implementation's outputs
//! (`tests/data/reference/`, copied from the project's shared reference folder).

use hystbench::data::read_csv;
use hystbench::effect::bouc_wen::BoucWenSpec;
use hystbench::effect::creep::CreepSpec;
use hystbench::effect::dynamics::DynamicsSpec;
use hystbench::effect::play::Play;
use hystbench::effect::prandtl_ishlinskii::PrandtlIshlinskiiSpec;
use hystbench::effect::Operator;
use serde_json::Value;
use std::path::Path;

fn reference() -> (hystbench::data::Record, Value) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/reference");
    let rec = read_csv(&dir.join("operators.csv")).unwrap();
    let params: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("operators.json")).unwrap())
            .unwrap();
    (rec, params)
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

fn fv(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(f).collect()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn range(x: &[f64]) -> f64 {
    x.iter().cloned().fold(f64::MIN, f64::max) - x.iter().cloned().fold(f64::MAX, f64::min)
}

#[test]
fn play_operator_matches_reference_to_1e9() {
    let (rec, p) = reference();
    let u = rec.column("u").unwrap();
    let y = Play::new(f(&p["play"]["threshold"]), f(&p["play"]["initial_state"])).apply(u);
    let err = max_abs_diff(&y, rec.column("play").unwrap());
    assert!(err <= 1e-9, "play max error {err}");
}

#[test]
fn prandtl_ishlinskii_matches_reference_to_1e9() {
    let (rec, p) = reference();
    let q = &p["prandtl_ishlinskii"];
    let pi = PrandtlIshlinskiiSpec {
        linear_weight: f(&q["linear_weight"]),
        thresholds: fv(&q["thresholds"]),
        weights: fv(&q["weights"]),
        initial_state: f(&q["initial_state"]),
        input_map: None,
        dead_zones: None,
        envelope_split: None,
        envelopes: None,
    }
    .check()
    .unwrap();
    let y = pi.operator().apply(rec.column("u").unwrap());
    let err = max_abs_diff(&y, rec.column("prandtl_ishlinskii").unwrap());
    assert!(err <= 1e-9, "PI max error {err}");
}

#[test]
fn bouc_wen_matches_reference_to_1e6_of_range() {
    let (rec, p) = reference();
    let q = &p["bouc_wen"];
    let bw = BoucWenSpec {
        d: f(&q["d"]),
        a: f(&q["A"]),
        b: f(&q["B"]),
        gamma: f(&q["Gamma"]),
        n: f(&q["n"]),
        initial_h: f(&q["initial_h"]),
    }
    .check()
    .unwrap();
    let y = bw.operator().apply(rec.column("u").unwrap());
    let want = rec.column("bouc_wen").unwrap();
    let err = max_abs_diff(&y, want) / range(want);
    assert!(err <= 1e-6, "Bouc-Wen max error {err} of range");
}

#[test]
fn creep_matches_reference_to_1e6_of_range() {
    let (rec, p) = reference();
    let q = &p["creep"];
    let c = CreepSpec {
        time_constants_s: fv(&q["time_constants_s"]),
        gains: Some(fv(&q["gains"])),
        percent_per_decade: None,
    }
    .check()
    .unwrap();
    let ts = f(&p["sampling_period_s"]);
    let y = c.operator(ts).apply(rec.column("step").unwrap());
    let want = rec.column("creep").unwrap();
    let err = max_abs_diff(&y, want) / range(want);
    assert!(err <= 1e-6, "creep max error {err} of range");
}

#[test]
fn dynamics_matches_reference_to_1e6_of_range() {
    let (rec, p) = reference();
    let q = &p["dynamics"];
    let d = DynamicsSpec {
        natural_frequency_hz: f(&q["natural_frequency_hz"]),
        damping_ratio: f(&q["damping_ratio"]),
        dc_gain: f(&q["dc_gain"]),
        second_mode: None,
        first_order_hold: 0.0,
    }
    .check()
    .unwrap();
    let ts = f(&p["sampling_period_s"]);
    let y = d.operator(ts).unwrap().apply(rec.column("step").unwrap());
    let want = rec.column("dynamics").unwrap();
    let err = max_abs_diff(&y, want) / range(want);
    assert!(err <= 1e-6, "dynamics max error {err} of range");
}
