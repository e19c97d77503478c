//! A grid run as 3 parts (3 processes, as a cluster scheduler's array job would) and merged
//! gives the results of the unsharded sweep, bit for bit but the time columns; a merge of
//! incomplete or mismatched parts is refused.

mod common;
use common::{hystbench, s, stderr};
use hystbench::narx::synthetic::{seed_1dof, Plant1};
use std::path::Path;

const GRID: [&str; 14] = [
    "--lags",
    "2,3",
    "--neurons",
    "3,5",
    "--lr",
    "0.01",
    "--batch",
    "64",
    "--epochs",
    "4",
    "--restarts",
    "1",
    "--sim-steps",
    "20",
];

fn sweep(data: &Path, out: &Path, extra: &[&str]) -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_hystbench"));
    c.args(["sweep", "--data", s(data), "--out", s(out)])
        .args(GRID)
        .args(extra);
    c
}

/// results.csv without its time column; report.md without its wall-time line and its tables'
/// time column.
fn without_time(dir: &Path) -> (String, String) {
    let csv = std::fs::read_to_string(dir.join("results.csv")).unwrap();
    let csv = csv
        .lines()
        .map(|l| l.rsplit_once(',').unwrap().0.to_string())
        .collect::<Vec<_>>()
        .join("\n");
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    // tables: the last cell is the time per model
    let md = md
        .lines()
        .filter(|l| !l.contains("wall time"))
        .map(|l| match l.trim_end_matches('|').rsplit_once('|') {
            Some((head, _)) if l.starts_with('|') => head.to_string(),
            _ => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    (csv, md)
}

#[test]
fn three_parts_merged_are_the_whole_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let rec = seed_1dof(Plant1::BoucWen, 1_200, 5);
    let mut text = String::from("t,u,y\n");
    for k in 0..rec.len() {
        text += &format!(
            "{},{},{}\n",
            k as f64 * rec.ts,
            rec.inputs[0].values[k],
            rec.outputs[0].values[k]
        );
    }
    let data = common::write(dir.path(), "d.csv", &text);
    let whole = dir.path().join("whole");
    let o = sweep(&data, &whole, &[]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    // the parts as 3 processes at once
    let parts: Vec<_> = (1..=3)
        .map(|k| dir.path().join(format!("part{k}")))
        .collect();
    let children: Vec<_> = parts
        .iter()
        .enumerate()
        .map(|(k, p)| {
            sweep(&data, p, &["--shard", &format!("{}/3", k + 1)])
                .stderr(std::process::Stdio::piped())
                .stdout(std::process::Stdio::null())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let merged = dir.path().join("merged");
    let mut args = vec!["sweep", "merge"];
    args.extend(parts.iter().rev().map(|p| s(p)));
    args.extend(["--out", s(&merged)]);
    let o = hystbench(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, b) = (without_time(&whole), without_time(&merged));
    assert_eq!(a.0, b.0, "results.csv");
    assert_eq!(a.1, b.1, "report.md");
    assert_eq!(a.0.lines().count(), 1 + 4);

    // two parts of three: refused, naming the missing one; nothing written
    let bad = dir.path().join("bad");
    let o = hystbench(&[
        "sweep",
        "merge",
        s(&parts[0]),
        s(&parts[2]),
        "--out",
        s(&bad),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("2/3 missing"), "{}", stderr(&o));
    assert!(!bad.join("results.csv").exists());
    // a part of another sweep (another base seed): refused
    let other = dir.path().join("other");
    let o = sweep(&data, &other, &["--shard", "2/3", "--seed", "7"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let o = hystbench(&[
        "sweep",
        "merge",
        s(&parts[0]),
        s(&other),
        s(&parts[2]),
        "--out",
        s(&bad),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("parts of different sweeps"),
        "{}",
        stderr(&o)
    );
    // a part given twice; a folder that is no part
    let o = hystbench(&[
        "sweep",
        "merge",
        s(&parts[0]),
        s(&parts[0]),
        "--out",
        s(&bad),
    ]);
    assert!(stderr(&o).contains("given twice"), "{}", stderr(&o));
    let o = hystbench(&["sweep", "merge", s(&whole), "--out", s(&bad)]);
    assert!(stderr(&o).contains("no shard.json"), "{}", stderr(&o));
    // more parts than settings
    let o = sweep(&data, &bad, &["--shard", "1/9"]).output().unwrap();
    assert!(stderr(&o).contains("only 4 settings"), "{}", stderr(&o));
}
