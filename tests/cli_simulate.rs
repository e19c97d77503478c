//! `hystbench simulate` end to end: outputs, provenance, reproducibility and bad input.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{hystbench as run, root, stderr};

fn simulate(plant: &str, scenario: &Path, out: &Path, extra: &[&str]) -> Output {
    let p = root().join("plants").join(plant);
    let mut args = vec![
        "simulate",
        "--plant",
        p.to_str().unwrap(),
        "--scenario",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    run(&args)
}

#[test]
fn writes_record_and_sidecar_with_provenance() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d.csv");
    let o = simulate(
        "piezo_2dof.json",
        &root().join("scenarios/seed_2dof.json"),
        &out,
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.starts_with("t,u1,u2,y1,y2\n"));
    assert_eq!(text.lines().count(), 501);
    let side: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("d.json")).unwrap()).unwrap();
    assert_eq!(side["plant"]["name"], "piezo_2dof");
    assert_eq!(side["scenario"]["name"], "seed_2dof");
    assert_eq!(side["seed"], 2);
    assert_eq!(side["version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(side["split"]["train"], 250);
}

#[test]
fn same_seed_same_bytes_other_seed_other_noise() {
    let dir = tempfile::tempdir().unwrap();
    let sc = root().join("scenarios/seed_1dof.json");
    let (a, b, c) = (
        dir.path().join("a.csv"),
        dir.path().join("b.csv"),
        dir.path().join("c.csv"),
    );
    assert!(simulate("bouc_wen_piezo.json", &sc, &a, &["--seed", "9"])
        .status
        .success());
    assert!(simulate("bouc_wen_piezo.json", &sc, &b, &["--seed", "9"])
        .status
        .success());
    assert!(simulate("bouc_wen_piezo.json", &sc, &c, &["--seed", "10"])
        .status
        .success());
    let (ta, tb, tc) = (
        std::fs::read(&a).unwrap(),
        std::fs::read(&b).unwrap(),
        std::fs::read(&c).unwrap(),
    );
    assert_eq!(ta, tb);
    assert_ne!(ta, tc);
    // same inputs (deterministic excitation), other noise on y
    let ra = hystbench::data::read_csv(&a).unwrap();
    let rc = hystbench::data::read_csv(&c).unwrap();
    assert_eq!(ra.column("u").unwrap(), rc.column("u").unwrap());
    let d: Vec<f64> = ra
        .column("y")
        .unwrap()
        .iter()
        .zip(rc.column("y").unwrap())
        .map(|(x, y)| x - y)
        .collect();
    let sd = hystbench::metrics::std_dev(&d);
    assert!(
        (sd - 0.01 * 2f64.sqrt()).abs() < 0.002,
        "difference of two noises: std {sd}"
    );
}

#[test]
fn existing_output_needs_force() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d.csv");
    std::fs::write(&out, "keep me").unwrap();
    let sc = root().join("scenarios/seed_2dof.json");
    let o = simulate("piezo_2dof.json", &sc, &out, &[]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "keep me");
    assert!(simulate("piezo_2dof.json", &sc, &out, &["--force"])
        .status
        .success());
}

#[test]
fn drives_a_plant_with_a_recorded_input() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.csv");
    let mut s = String::from("time_s,volt,other\n");
    for k in 0..200 {
        let t = k as f64 * 1e-3;
        s += &format!(
            "{t},{},{}\n",
            30.0 * (2.0 * std::f64::consts::PI * 5.0 * t).sin(),
            k
        );
    }
    std::fs::write(&rec, s).unwrap();
    // a plant with slower dynamics for 1 kHz sampling
    let plant = dir.path().join("p.json");
    std::fs::write(
        &plant,
        r#"{"name":"p","inputs":["u"],"outputs":[{"name":"y","paths":[{"input":"u","hysteresis":{"bouc_wen":{"d":0.8,"A":0.3,"B":0.02,"Gamma":0.01}}}],"dynamics":{"natural_frequency_hz":100,"damping_ratio":0.1}}]}"#,
    )
    .unwrap();
    let out = dir.path().join("o.csv");
    let o = run(&[
        "simulate",
        "--plant",
        plant.to_str().unwrap(),
        "--input",
        rec.to_str().unwrap(),
        "--input-columns",
        "volt",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r = hystbench::data::read_csv(&out).unwrap();
    assert_eq!(r.names, ["t", "u", "y"]);
    assert_eq!(r.len(), 200);
    // missing column: named, with the available ones
    let o = run(&[
        "simulate",
        "--plant",
        plant.to_str().unwrap(),
        "--input",
        rec.to_str().unwrap(),
        "--input-columns",
        "volts",
        "--out",
        dir.path().join("x.csv").to_str().unwrap(),
    ]);
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("volts") && e.contains("time_s, volt, other"),
        "{e}"
    );
    assert!(!dir.path().join("x.csv").exists());
}

/// Write `text` as a file and return its path.
fn file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn expect_error(plant: &Path, scenario_or_input: (&str, &Path), needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.csv");
    let o = run(&[
        "simulate",
        "--plant",
        plant.to_str().unwrap(),
        scenario_or_input.0,
        scenario_or_input.1.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let e = stderr(&o);
    assert!(!o.status.success(), "should fail: {needles:?}");
    for n in needles {
        assert!(e.contains(n), "error lacks `{n}`: {e}");
    }
    assert!(
        !out.exists() && !dir.path().join("o.json").exists(),
        "nothing may be written"
    );
    assert!(!e.contains("panicked"), "{e}");
}

const GOOD_PLANT: &str = r#"{"name":"p","inputs":["u"],"outputs":[{"name":"y","paths":[{"input":"u","hysteresis":{"bouc_wen":{"d":0.8,"A":0.3,"B":0.02,"Gamma":0.01}}}],"dynamics":{"natural_frequency_hz":100,"damping_ratio":0.1}}]}"#;
const GOOD_SCENARIO: &str = r#"{"name":"s","sampling_period_s":0.001,"samples":100,"inputs":[{"sine":{"amplitude":10,"frequency_hz":5}}]}"#;

#[test]
fn bad_plant_files_are_named_and_explained() {
    let d = tempfile::tempdir().unwrap();
    let sc = file(d.path(), "s.json", GOOD_SCENARIO);
    let cases: &[(&str, &[&str])] = &[
        (
            &GOOD_PLANT.replace("\"B\":0.02", "\"B\":0.005"),
            &["p.json", "B", "0.005", "|Gamma|"],
        ),
        (
            &GOOD_PLANT.replace("\"damping_ratio\":0.1", "\"damping_ratio\":-0.1"),
            &["p.json", "damping_ratio", "-0.1", ">= 0"],
        ),
        (
            &GOOD_PLANT.replace("\"d\":0.8", "\"d\":0.8,\"colour\":1"),
            &["p.json", "unknown field `colour`", "line 1"],
        ),
        (
            &GOOD_PLANT.replace("\"d\":0.8", "\"d\":NaN"),
            &["p.json", "line 1"],
        ),
        (&GOOD_PLANT[..40], &["p.json", "EOF"]),
        (
            &GOOD_PLANT.replace("\"input\":\"u\"", "\"input\":\"v\""),
            &["p.json", "`v` is not one of the inputs"],
        ),
        (
            r#"{"name":"p","inputs":["u"],"outputs":[{"name":"y","paths":[{"input":"u","hysteresis":{"prandtl_ishlinskii":{"linear_weight":0.6,"thresholds":[4,2],"weights":[0.1,0.1]}}}]}]}"#,
            &["p.json", "thresholds[1]", "strictly increasing"],
        ),
        (
            r#"{"name":"p","inputs":["u"],"outputs":[{"name":"y","paths":[{"input":"u","hysteresis":{"prandtl_ishlinskii":{"linear_weight":0.6,"thresholds":[4],"weights":[0.1],"envelopes":{"ascending":{"a0":30,"a1":0.03,"a2":0,"a3":0},"descending":{"a0":30,"a1":-0.03,"a2":0,"a3":0}}}}}]}]}"#,
            &["p.json", "envelopes.descending.a1", "-0.03", "> 0"],
        ),
        (
            r#"{"name":"p","inputs":["u"],"outputs":[{"name":"y","paths":[{"input":"u","hysteresis":{"prandtl_ishlinskii":{"linear_weight":0.6,"thresholds":[4],"weights":[0.1],"envelopes":{"ascending":{"a0":30,"a1":0.03,"a2":0,"a3":0}}}}}]}]}"#,
            &["p.json", "missing field `descending`", "line 1"],
        ),
        (
            r#"{"name":"p","inputs":["u"],"outputs":[{"name":"y","paths":[{"input":"u","hysteresis":{"linear":{"gain":1}}}],"creep":{"time_constants_s":[-1],"gains":[0.1]}}]}"#,
            &["p.json", "time_constants_s[0]", "-1", "> 0"],
        ),
    ];
    for (text, needles) in cases {
        let p = file(d.path(), "p.json", text);
        expect_error(&p, ("--scenario", &sc), needles);
    }
}

#[test]
fn bad_scenarios_are_named_and_explained() {
    let d = tempfile::tempdir().unwrap();
    let p = file(d.path(), "p.json", GOOD_PLANT);
    let cases: &[(&str, &[&str])] = &[
        (
            &GOOD_SCENARIO.replace("0.001", "0"),
            &["s.json", "sampling_period_s", "> 0"],
        ),
        (
            &GOOD_SCENARIO.replace("0.001", "-0.001"),
            &["s.json", "sampling_period_s"],
        ),
        (
            r#"{"name":"s","sampling_period_s":0.001,"samples":100,"inputs":[{"staircase":{"levels":[1,2,3],"hold_s":0.05}}]}"#,
            &["s.json", "too short", "0.15"],
        ),
        (
            r#"{"name":"s","sampling_period_s":0.001,"samples":100,"inputs":[{"concat":[{"duration_s":0.08,"excitation":{"constant":{"value":1}}},{"duration_s":0.08,"excitation":{"constant":{"value":2}}}]}]}"#,
            &["s.json", "too short", "0.16"],
        ),
        (
            &GOOD_SCENARIO.replace("\"frequency_hz\":5", "\"frequency_hz\":900"),
            &["s.json", "frequency_hz", "Nyquist"],
        ),
        (
            &GOOD_SCENARIO.replace(
                "\"samples\":100",
                "\"samples\":100,\"split\":{\"train\":60,\"test\":60}",
            ),
            &["s.json", "split"],
        ),
        (
            &GOOD_SCENARIO.replace("\"amplitude\"", "\"amplitud\""),
            &["s.json", "unknown field `amplitud`"],
        ),
    ];
    for (text, needles) in cases {
        let s = file(d.path(), "s.json", text);
        expect_error(&p, ("--scenario", &s), needles);
    }
}

#[test]
fn bad_input_records_are_named_and_explained() {
    let d = tempfile::tempdir().unwrap();
    let p = file(d.path(), "p.json", GOOD_PLANT);
    let cases: &[(&str, &[&str])] = &[
        (
            "t,u\n0,1\n0.001,x\n",
            &["in.csv", "line 3", "`u`", "`x` is not a number"],
        ),
        ("t,u\n0,1\n0.001,\n", &["in.csv", "line 3", "missing"]),
        ("t,v\n0,1\n0.001,2\n", &["in.csv", "t, v"]),
        (
            "t,u\n0,1\n0.001,2\n0.005,3\n0.006,3\n",
            &["in.csv", "line 4", "uniform", "split"],
        ),
        ("t,u\n0,1\n0.001,nan\n", &["in.csv", "line 3", "not finite"]),
    ];
    for (text, needles) in cases {
        let i = file(d.path(), "in.csv", text);
        expect_error(&p, ("--input", &i), needles);
    }
}
