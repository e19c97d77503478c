//! compare, diagnose, improve and demo from the command line: outputs, JSON shapes, bad input.

use std::path::{Path, PathBuf};

mod common;
use common::{hystbench as run, root, s};

/// A creep record and two plant files used as models: with and without creep.
fn setup(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let data = dir.join("d.csv");
    let plant = root().join("plants/hidden_creep_piezo.json");
    let o = run(&[
        "simulate",
        "--plant",
        s(&plant),
        "--scenario",
        s(&root().join("scenarios/hidden_effect_1khz.json")),
        "--out",
        s(&data),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut spec: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&plant).unwrap()).unwrap();
    spec["outputs"][0].as_object_mut().unwrap().remove("creep");
    let without = dir.join("without_creep.json");
    std::fs::write(&without, spec.to_string()).unwrap();
    (data, plant, without)
}

#[test]
fn diagnose_json_names_the_missing_effect_and_nothing_for_the_true_plant() {
    let dir = tempfile::tempdir().unwrap();
    let (data, plant, without) = setup(dir.path());
    let o = run(&[
        "diagnose",
        "--data",
        s(&data),
        "--model",
        s(&without),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["missing"], "creep");
    assert_eq!(v["ranking"][0]["effect"], "creep");
    assert!(v["ranking"][0]["explained"].as_f64().unwrap() > 0.5);
    let o = run(&[
        "diagnose",
        "--data",
        s(&data),
        "--model",
        s(&plant),
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["missing"].is_null(), "{v}");
    // words a user acts on
    let o = run(&["diagnose", "--data", s(&data), "--model", s(&without)]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("creep: after each step the error drifts by") && text.contains("per decade"),
        "{text}"
    );
}

#[test]
fn compare_writes_a_report_with_figures() {
    let dir = tempfile::tempdir().unwrap();
    let (data, _, without) = setup(dir.path());
    let rep = dir.path().join("rep");
    let o = run(&[
        "compare",
        "--data",
        s(&data),
        "--model",
        s(&without),
        "--report",
        s(&rep),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(rep.join("report.md")).unwrap();
    for needle in [
        "R^2",
        "rising input",
        "during holds",
        "frequency band",
        "Worst windows",
        "loop.png",
    ] {
        assert!(md.contains(needle), "report lacks {needle}");
    }
    assert!(rep.join("prediction.csv").exists() && rep.join("residual_loop.png").exists());
    // a folder of the user's is not written into without --force
    let mine = dir.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("notes.txt"), "mine").unwrap();
    let o = run(&[
        "compare",
        "--data",
        s(&data),
        "--model",
        s(&without),
        "--report",
        s(&mine),
    ]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--force"));
}

#[test]
fn improve_adds_the_hidden_effect_and_the_error_falls() {
    let dir = tempfile::tempdir().unwrap();
    let (data, _, _) = setup(dir.path());
    let start = dir.path().join("start.json");
    let o = run(&[
        "fit",
        "--data",
        s(&data),
        "--effects",
        "hysteresis,dynamics",
        "--out",
        s(&start),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.path().join("imp");
    let o = run(&[
        "improve",
        "--data",
        s(&data),
        "--model",
        s(&start),
        "--out",
        s(&out),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let ladder = v["ladder"].as_array().unwrap();
    assert_eq!(ladder[0]["missing"], "creep");
    let (r0, r1) = (
        ladder[0]["rmse"].as_f64().unwrap(),
        ladder[1]["rmse"].as_f64().unwrap(),
    );
    assert!(r0 / r1 >= 3.0, "{r0} -> {r1}");
    assert!(ladder.last().unwrap()["missing"].is_null());
    let csv = std::fs::read_to_string(out.join("ladder.csv")).unwrap();
    assert!(csv.starts_with("step,effects,rmse,r2\n") && csv.contains("creep"));
    assert!(out.join("ladder.png").exists() && out.join("model_1.json").exists());
}

#[test]
fn bad_model_and_record_combinations_are_explained() {
    let dir = tempfile::tempdir().unwrap();
    let (data, _, _) = setup(dir.path());
    // a 2-input model on a 1-input record
    let o = run(&[
        "diagnose",
        "--data",
        s(&data),
        "--model",
        s(&root().join("plants/piezo_2dof.json")),
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("u1") && e.contains("t, u, y"),
        "{e}"
    );
    // an unknown model format
    let m = dir.path().join("m.json");
    std::fs::write(&m, r#"{"format":"something-else","version":1}"#).unwrap();
    let o = run(&["compare", "--data", s(&data), "--model", s(&m)]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success()
            && e.contains("unknown model format")
            && e.contains("hystbench-greybox"),
        "{e}"
    );
    // an unknown effect
    let o = run(&[
        "fit",
        "--data",
        s(&data),
        "--effects",
        "hysteresis,magic",
        "--out",
        s(&dir.path().join("x.json")),
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("magic") && e.contains("creep"),
        "{e}"
    );
    assert!(!dir.path().join("x.json").exists());
}

/// A record too short to halve for the lags: `identify` says so, names `--test`, writes nothing.
#[test]
fn identify_on_a_record_too_short_to_halve_names_test() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("short.csv");
    std::fs::write(&data, "t,u,y\n0,1,2\n0.1,2,3\n0.2,3,1\n0.3,1,2\n").unwrap();
    let m = dir.path().join("m.json");
    let o = run(&["identify", "--data", s(&data), "--out", s(&m)]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success()
            && e.contains("short.csv")
            && e.contains("4 samples split in halves leave 2")
            && e.contains("--test"),
        "{e}"
    );
    assert!(!m.exists());
}

#[test]
fn demo_runs_the_whole_story() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let o = run(&["demo", "--out", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(out.join("README.md")).unwrap();
    assert!(
        md.contains("Identification") && md.contains("hidden effect") && md.contains("| creep |"),
        "{md}"
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("report:"));
    assert!(
        out.join("records/bouc_wen_piezo_loop.png").exists()
            && out.join("improve/ladder.png").exists()
            && out.join("compensation/loop.png").exists()
    );
    // the compensation step: the improved model's inverse cuts the tracking error
    let t: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("compensation/track.json")).unwrap(),
    )
    .unwrap();
    let ratio = t["outputs"][0]["ratio"].as_f64().unwrap();
    assert!(md.contains("Compensation") && ratio >= 5.0, "{t}");
}

#[test]
fn diagnose_and_compare_work_on_a_narx_model() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("bw.csv");
    let o = run(&[
        "simulate",
        "--plant",
        s(&root().join("plants/bouc_wen_piezo.json")),
        "--scenario",
        s(&root().join("scenarios/seed_1dof.json")),
        "--out",
        s(&data),
    ]);
    assert!(o.status.success());
    let m = dir.path().join("narx.json");
    let o = run(&[
        "identify",
        "--data",
        s(&data),
        "--out",
        s(&m),
        "--seed",
        "3",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&["diagnose", "--data", s(&data), "--model", s(&m), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // a NARX model has none of the library's effects: all that apply are ranked
    let ranked: Vec<&str> = v["ranking"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["effect"].as_str().unwrap())
        .collect();
    assert_eq!(ranked.len(), 7, "{v}");
    for e in [
        "hysteresis",
        "creep",
        "dynamics",
        "viscous",
        "spencer",
        "drift",
        "saturation",
    ] {
        assert!(ranked.contains(&e), "{e}: {v}");
    }
    let o = run(&["compare", "--data", s(&data), "--model", s(&m), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        v["outputs"][0]["scores"]["r2"].as_f64().unwrap() > 0.99,
        "{v}"
    );
}

#[test]
fn a_diverging_narx_free_run_is_reported_not_scored() {
    // trained on sines and steps, tested on long holds: this NARX leaves the data's range
    let dir = tempfile::tempdir().unwrap();
    let (data, _, _) = setup(dir.path());
    let m = dir.path().join("narx.json");
    let o = run(&["identify", "--data", s(&data), "--out", s(&m), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let y = &v["outputs"]["y"];
    let o = run(&["diagnose", "--data", s(&data), "--model", s(&m)]);
    if y["r2_fr_test"].is_null() {
        // never a number for a diverged free run, and diagnose refuses to score it
        assert!(
            y["diverged_at"].as_u64().is_some() && y["rmse_fr_test"].is_null(),
            "{v}"
        );
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && e.contains("diverged at sample"),
            "{e}"
        );
    } else {
        // a free run that holds is scored and diagnosed like any other model
        assert!(
            y["diverged_at"].is_null() && y["rmse_fr_test"].as_f64().is_some(),
            "{v}"
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
}
