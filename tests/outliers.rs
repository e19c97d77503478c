//! A lab record with a glitch (one sample of 1e300): the modelling commands refuse it with the
//! line named, and with `--outliers repair` give the scores of the record without the glitch.

mod common;
use common::{hystbench, s, stderr};
use hystbench::narx::synthetic::{seed_1dof, Plant1};

/// The Bouc-Wen plant's `seed_1dof` record (6,000 samples) as CSV text, with `glitches`
/// (row, value) put into the output.
fn record(glitches: &[(usize, f64)]) -> String {
    let rec = seed_1dof(Plant1::BoucWen, 6_000, 4);
    let mut y = rec.outputs[0].values.clone();
    for &(k, v) in glitches {
        y[k] = v;
    }
    let mut text = String::from("t,u,y\n");
    for (k, (u, y)) in rec.inputs[0].values.iter().zip(&y).enumerate() {
        text += &format!("{},{u},{y}\n", k as f64 * rec.ts);
    }
    text
}

fn json(o: &std::process::Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", stderr(o));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn a_glitch_is_refused_by_name_and_repaired_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let clean = common::write(dir.path(), "clean.csv", &record(&[]));
    // one glitch in the training half, one in the test half (lines: row + 2)
    let glitched = common::write(
        dir.path(),
        "glitch.csv",
        &record(&[(1234, 1e300), (4321, -3e12)]),
    );
    for cmd in [
        vec!["identify", "--epochs", "30"],
        vec!["fit", "--effects", "hysteresis"],
    ] {
        let out = dir.path().join(format!("{}.json", cmd[0]));
        let mut args = cmd.clone();
        args.extend(["--data", s(&glitched), "--out", s(&out)]);
        let o = hystbench(&args);
        assert!(!o.status.success());
        let e = stderr(&o);
        assert!(
            e.contains("line 1236") && e.contains("1e300") && e.contains("--outliers repair"),
            "{e}"
        );
        assert!(e.contains("2 such sample(s), lines 1236"), "{e}");
        assert!(!out.exists(), "nothing written when refused");
    }
    // a modelling command on a record, with `extra` arguments: its JSON and its model file
    let model = |cmd: &[&str], data: &std::path::Path, extra: &[&str], name: &str| {
        let out = dir.path().join(name);
        let mut args = cmd.to_vec();
        args.extend(["--json", "--data", s(data), "--out", s(&out)]);
        args.extend_from_slice(extra);
        (json(&hystbench(&args)), out)
    };
    // identify: the same seed on the clean and the repaired record
    let score = |data: &std::path::Path, extra: &[&str], name: &str| {
        let v = model(&["identify", "--epochs", "30"], data, extra, name).0;
        let y = &v["outputs"]["y"];
        (
            y["r2_fr_train"].as_f64().unwrap(),
            y["r2_fr_test"].as_f64().unwrap(),
        )
    };
    let a = score(&clean, &[], "a.json");
    let b = score(&glitched, &["--outliers", "repair"], "b.json");
    assert!(
        (a.0 - b.0).abs() < 1e-3 && (a.1 - b.1).abs() < 1e-3,
        "clean {a:?}, repaired {b:?}"
    );
    // fit: the grey-box fitted on the clean and on the repaired record, scored on the clean one
    let fit = |data: &std::path::Path, extra: &[&str], name: &str| {
        let out = model(&["fit", "--effects", "hysteresis"], data, extra, name).1;
        let v = json(&hystbench(&[
            "compare",
            "--model",
            s(&out),
            "--data",
            s(&clean),
            "--json",
        ]));
        v["outputs"][0]["scores"]["r2"].as_f64().unwrap()
    };
    let (fa, fb) = (
        fit(&clean, &[], "fa.json"),
        fit(&glitched, &["--outliers", "repair"], "fb.json"),
    );
    assert!((fa - fb).abs() < 1e-3, "clean {fa}, repaired {fb}");
    // kept on request: the glitch goes into the model (and the scores show it)
    let o = hystbench(&[
        "identify",
        "--epochs",
        "30",
        "--data",
        s(&glitched),
        "--out",
        s(&dir.path().join("kept.json")),
        "--outliers",
        "keep",
    ]);
    assert!(stderr(&o).contains("outlier in `y`"), "{}", stderr(&o));
}
