//! `inspect` finds each thing a lab record can carry, on a clean simulated record with one
//! damage at a time, names the lines, and reports nothing on the clean record.

use hystbench::data::inspect::{inspect, Inspection};
use hystbench::data::parse_csv;
use hystbench::narx::synthetic::{seed_1dof, Plant1};
use std::path::Path;

/// The Bouc-Wen plant's `seed_1dof` record (three sines, 0.01 um noise), 6,000 samples, as
/// columns t, u, y.
fn clean() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let rec = seed_1dof(Plant1::BoucWen, 6_000, 4);
    let t = (0..rec.len()).map(|k| k as f64 * rec.ts).collect();
    (
        t,
        rec.inputs[0].values.clone(),
        rec.outputs[0].values.clone(),
    )
}

fn run(t: &[f64], u: &[f64], y: &[f64]) -> Inspection {
    let mut text = String::from("# a record\nt,u,y\n");
    for k in 0..t.len() {
        text += &format!("{},{},{}\n", t[k], u[k], y[k]);
    }
    let rec = parse_csv(Path::new("r.csv"), &text).unwrap();
    inspect(&rec, &["u".into()], &["y".into()])
}

fn kinds(r: &Inspection) -> Vec<&'static str> {
    r.findings.iter().map(|f| f.kind).collect()
}

#[test]
fn a_clean_record_gives_nothing_to_report() {
    let (t, u, y) = clean();
    let r = run(&t, &u, &y);
    assert!(r.findings.is_empty(), "{:#?}", r.findings);
    assert_eq!(r.usable.samples, t.len());
    let input = &r.columns[0];
    assert!(input.reversals.unwrap() >= 4, "{input:?}");
    assert!((r.sampling_period.unwrap() - 1e-4).abs() < 1e-12);
}

#[test]
fn each_damage_is_found_with_its_lines() {
    let (t, u, y) = clean();
    // a spike at row 1000: line 1002 after the comment and the header
    let mut s = y.clone();
    s[1000] = 1e300;
    let r = run(&t, &u, &s);
    assert_eq!(kinds(&r), ["outlier"], "{:#?}", r.findings);
    assert_eq!(r.findings[0].lines, [1003]);
    assert!(r.findings[0].message.contains("1 of them gross"));
    // a dropout: the logger repeats a value for 300 samples
    let mut s = y.clone();
    for k in 2000..2300 {
        s[k] = s[1999];
    }
    let r = run(&t, &u, &s);
    assert_eq!(kinds(&r), ["dropout"], "{:#?}", r.findings);
    assert_eq!(r.findings[0].lines, [2002]);
    // the usable stretch: after the dropout, rows 2300..6000
    assert_eq!(r.usable.samples, 3700, "{:?}", r.usable);
    // clipping at 80 % of the top
    let top = y.iter().fold(f64::MIN, |m, v| m.max(*v));
    let s: Vec<f64> = y.iter().map(|v| v.min(0.8 * top)).collect();
    let r = run(&t, &u, &s);
    assert!(kinds(&r).contains(&"clipping"), "{:#?}", r.findings);
    // quantisation to 0.05 um
    let s: Vec<f64> = y.iter().map(|v| (v / 0.05).round() * 0.05).collect();
    let r = run(&t, &u, &s);
    assert_eq!(kinds(&r), ["quantisation"], "{:#?}", r.findings);
    // a gap of 50 steps at row 3000
    let mut g = t.clone();
    for v in g.iter_mut().skip(3000) {
        *v += 50e-4;
    }
    let r = run(&g, &u, &y);
    assert_eq!(kinds(&r), ["gap"], "{:#?}", r.findings);
    assert_eq!(r.findings[0].lines, [3003]);
    // the usable stretch: one side of the gap (the first of two equal ones), rows 0..3000
    // (lines 3..3002 after the comment and the header)
    assert_eq!(
        (r.usable.samples, r.usable.first_line, r.usable.last_line),
        (3000, 3, 3002),
        "{:?}",
        r.usable
    );
    // a slow drift of 10 % of the range
    let range = top - y.iter().fold(f64::MAX, |m, v| m.min(*v));
    let s: Vec<f64> = y
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.1 * range * k as f64 / y.len() as f64)
        .collect();
    let r = run(&t, &u, &s);
    assert_eq!(kinds(&r), ["drift"], "{:#?}", r.findings);
    // an input that only rises
    let ramp: Vec<f64> = (0..t.len()).map(|k| k as f64 * 0.01).collect();
    let r = run(&t, &ramp, &ramp.iter().map(|v| 0.7 * v).collect::<Vec<_>>());
    assert_eq!(kinds(&r), ["no_reversal"], "{:#?}", r.findings);
}

/// From the command line: text with the lines, JSON with the documented fields.
#[test]
fn inspect_from_the_command_line() {
    let (t, u, mut y) = clean();
    y[1500] = -1e300;
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("glitch.csv");
    let mut text = String::from("t,u,y\n");
    for k in 0..t.len() {
        text += &format!("{},{},{}\n", t[k], u[k], y[k]);
    }
    std::fs::write(&data, text).unwrap();
    let bin = env!("CARGO_BIN_EXE_hystbench");
    let o = std::process::Command::new(bin)
        .args(["inspect", "--data"])
        .arg(&data)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        out.contains("outlier") && out.contains("line 1502"),
        "{out}"
    );
    let o = std::process::Command::new(bin)
        .args(["inspect", "--json", "--data"])
        .arg(&data)
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for field in [
        "samples",
        "sampling_period",
        "jitter",
        "columns",
        "findings",
        "usable",
    ] {
        assert!(v.get(field).is_some(), "{field}: {v}");
    }
    // how many samples each modelling command needs, beside the usable stretch
    let needs = v["usable"]["needs"].as_object().unwrap();
    assert!(
        needs.len() == 3 && needs.values().all(|n| n.as_u64().unwrap() >= 10),
        "{needs:?}"
    );
    let f = &v["findings"][0];
    for field in ["kind", "column", "count", "lines", "message", "advice"] {
        assert!(f.get(field).is_some(), "{field}: {f}");
    }
}
