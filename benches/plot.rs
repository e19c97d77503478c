//! Loop figure of a 1,000,000-sample record (goal: under 2 s), PNG and SVG.
//!
//! Run: `cargo bench --bench plot`.

use hystbench::data::{IoRecord, Signal};
use hystbench::plot::{decimate::decimate, loop_figure, LoopColour, LoopOptions, PlotRecord};
use std::time::Instant;

fn record(n: usize) -> PlotRecord {
    let ts = 1e-5;
    let mut u = Vec::with_capacity(n);
    let mut y = Vec::with_capacity(n);
    let mut z = 0.0f64;
    let mut noise = 0x2545_f491_4f6c_dd1du64;
    for k in 0..n {
        let t = k as f64 * ts;
        // 20 major cycles with minor loops, a decaying envelope and a little noise
        let v = 150.0
            * (1.0 - 0.5 * t / (n as f64 * ts))
            * (2.0 * std::f64::consts::PI * 2.0 * t).sin()
            + 15.0 * (2.0 * std::f64::consts::PI * 37.0 * t).sin();
        z = z.clamp(v - 40.0, v + 40.0);
        noise ^= noise << 13;
        noise ^= noise >> 7;
        noise ^= noise << 17;
        let e = (noise >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        u.push(v);
        y.push(0.1 * z + 0.02 * v + 0.05 * e);
    }
    let io = IoRecord {
        path: "bench.csv".into(),
        ts,
        t0: 0.0,
        time_name: "t_s".into(),
        inputs: vec![Signal {
            name: "voltage_V".into(),
            values: u,
        }],
        outputs: vec![Signal {
            name: "displacement_um".into(),
            values: y,
        }],
    };
    PlotRecord::from_io("bench", io)
}

fn main() {
    let n = 1_000_000;
    let dir = tempfile::tempdir().expect("temp dir");
    let t = Instant::now();
    let rec = record(n);
    let gen = t.elapsed().as_secs_f64();
    let with_model = {
        let p: Vec<f64> = rec.io.outputs[0].values.iter().map(|v| 0.97 * v).collect();
        rec.clone().with_prediction(0, p).expect("prediction")
    };
    println!("loop figure of a {n}-sample record (record generated in {gen:.3} s)");
    println!("{:<44} {:>10} {:>12}", "case", "seconds", "file bytes");
    let u = &rec.io.inputs[0].values;
    let y = &rec.io.outputs[0].values;
    let t = Instant::now();
    let kept = decimate(&[u, y], 0..n, LoopOptions::default().max_points).len();
    println!(
        "{:<44} {:>10.3} {:>12}",
        format!("decimate only ({kept} points kept)"),
        t.elapsed().as_secs_f64(),
        "-"
    );
    let cases: Vec<(&str, &PlotRecord, Option<LoopColour>, &str)> = vec![
        ("PNG, colour by time", &rec, None, "png"),
        ("PNG, colour by cycle", &rec, Some(LoopColour::Cycle), "png"),
        ("PNG, measured + model overlay", &with_model, None, "png"),
        ("SVG, colour by time", &rec, None, "svg"),
    ];
    for (i, (name, r, colour, ext)) in cases.into_iter().enumerate() {
        let path = dir.path().join(format!("loop{i}.{ext}"));
        let options = LoopOptions {
            colour,
            ..LoopOptions::default()
        };
        let t = Instant::now();
        loop_figure(std::slice::from_ref(r), &options, &path, None, false).expect("figure");
        let s = t.elapsed().as_secs_f64();
        let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
        println!("{name:<44} {s:>10.3} {bytes:>12}");
    }
}
