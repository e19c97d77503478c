//! `hystbench split` on a record with a logger pause and jittered stamps, and the error that
//! points to it when such a record is used directly.

use std::path::Path;

mod common;
use common::hystbench;

fn write_record(path: &Path) {
    // 300 samples at 10 ms with +-1 ms jitter, a 2 s pause, 200 more samples
    let mut s = String::from("t_s,x_mm,F_N\n");
    let mut t: f64 = 0.0;
    for k in 0..500 {
        if k == 300 {
            t += 2.0;
        }
        let stamp = t + if k % 4 == 1 { 0.001 } else { 0.0 };
        s += &format!("{stamp},{},{}\n", (stamp * 3.0).sin(), 2.0 * stamp + 1.0);
        t += 0.01;
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn a_record_with_a_pause_is_refused_with_the_way_out_and_split_makes_uniform_parts() {
    let dir = std::env::temp_dir().join(format!("hb_split_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let rec = dir.join("friction.csv");
    write_record(&rec);
    let r = rec.to_str().unwrap();
    let model = dir.join("m.json");
    let o = hystbench(&[
        "identify",
        "--data",
        r,
        "--inputs",
        "x_mm",
        "--outputs",
        "F_N",
        "--out",
        model.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("line 3") && err.contains("1 gap(s)"), "{err}");
    assert!(err.contains("hystbench split"), "{err}");
    assert!(!model.exists());

    let parts = dir.join("parts");
    let o = hystbench(&["split", "--data", r, "--out", parts.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (i, n) in [(1, 300), (2, 200)] {
        let p = parts.join(format!("friction_part{i}.csv"));
        let text = std::fs::read_to_string(&p).unwrap();
        let rows: Vec<Vec<f64>> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect();
        assert!((rows.len() as i64 - n).abs() <= 1, "{} rows", rows.len());
        for w in rows.windows(2) {
            assert!((w[1][0] - w[0][0] - 0.01).abs() < 1e-9);
        }
        // F is linear in t: interpolation is exact
        for row in &rows {
            assert!((row[2] - (2.0 * row[0] + 1.0)).abs() < 1e-9);
        }
    }
    // the parts identify without a time error
    let p1 = parts.join("friction_part1.csv");
    let o = hystbench(&[
        "fit",
        "--data",
        p1.to_str().unwrap(),
        "--inputs",
        "x_mm",
        "--outputs",
        "F_N",
        "--effects",
        "none",
        "--out",
        model.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // nothing overwritten without --force
    let o = hystbench(&["split", "--data", r, "--out", parts.to_str().unwrap()]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--force"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
