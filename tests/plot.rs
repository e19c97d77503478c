//! `hystbench plot`: every figure kind rendered from generated data as PNG and SVG with no system
//! fonts available (FONTCONFIG_FILE pointing nowhere), and the bad inputs.

use std::path::{Path, PathBuf};

mod common;
use common::hystbench;

fn ok(args: &[&str]) {
    let o = hystbench(args);
    assert!(
        o.status.success(),
        "hystbench {args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn fails(args: &[&str]) -> String {
    let o = hystbench(args);
    assert!(!o.status.success(), "hystbench {args:?} should have failed");
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// A play-operator loop, with a few minor loops, and an imperfect "model" without memory.
fn siso(dir: &Path, name: &str, n: usize, shift: f64) -> PathBuf {
    let mut s = String::from("t,voltage_V,displacement_um,displacement_um_hat\n");
    let mut z = 0.0f64;
    for k in 0..n {
        let t = k as f64 * 1e-3;
        let u = 100.0 * (2.0 * std::f64::consts::PI * t).sin()
            + 20.0 * (2.0 * std::f64::consts::PI * 9.0 * t).sin();
        z = z.clamp(u - 30.0, u + 30.0);
        let y = 0.1 * z + 0.02 * u + shift;
        let y_hat = 0.11 * u + shift + 0.3 * (3.0 * t).sin();
        s += &format!("{t},{u},{y},{y_hat}\n");
    }
    let p = dir.join(name);
    std::fs::write(&p, s).unwrap();
    p
}

/// A 2-DoF record with cross coupling and predictions.
fn mimo(dir: &Path, n: usize) -> PathBuf {
    let mut s = String::from("t,u1,u2,y1,y2,y1_hat,y2_hat\n");
    let (mut z1, mut z2) = (0.0f64, 0.0f64);
    for k in 0..n {
        let t = k as f64 * 1e-3;
        let u1 = (2.0 * std::f64::consts::PI * t).sin();
        let u2 = (2.0 * std::f64::consts::PI * 0.7 * t).cos();
        z1 = z1.clamp(u1 - 0.3, u1 + 0.3);
        z2 = z2.clamp(u2 - 0.2, u2 + 0.2);
        let (y1, y2) = (z1 + 0.1 * u2, z2 + 0.2 * u1);
        s += &format!("{t},{u1},{u2},{y1},{y2},{u1},{u2}\n");
    }
    let p = dir.join("mimo.csv");
    std::fs::write(&p, s).unwrap();
    p
}

fn results(dir: &Path) -> PathBuf {
    let mut s = String::from("output,lags,neurons,lr,batch,epochs,seed,r2_osa_train,r2_fr_train,r2_osa_test,r2_fr_test,rmse_fr_test,diverged,train_seconds\n");
    for lr in ["0.001", "0.01"] {
        for batch in [32, 256] {
            for lags in [1, 2, 4] {
                for neurons in [5, 20, 50] {
                    let diverged = lr == "0.01" && lags == 4 && neurons == 50;
                    let r2 = 0.8 + 0.003 * (lags * neurons) as f64 / 2.0;
                    if diverged {
                        s += &format!(
                            "y,{lags},{neurons},{lr},{batch},100,1,0.99,,0.99,,,1,{}\n",
                            lags * neurons
                        );
                    } else {
                        s += &format!(
                            "y,{lags},{neurons},{lr},{batch},100,1,0.99,0.98,0.99,{r2},0.1,0,{}\n",
                            lags * neurons
                        );
                    }
                }
            }
        }
    }
    let p = dir.join("results.csv");
    std::fs::write(&p, s).unwrap();
    p
}

fn ladder(dir: &Path) -> PathBuf {
    let p = dir.join("ladder.csv");
    std::fs::write(
        &p,
        "step,effects,rmse,r2\n0,linear,2.31,0.912\n1,linear+hysteresis,0.42,0.9971\n2,linear+hysteresis+creep,0.18,0.9995\n",
    )
    .unwrap();
    p
}

/// Decode a PNG, check its size, and count the coloured (not grey, not white) pixels in the
/// central part of the image, where the plot areas are.
fn check_png(path: &Path, size: (u32, u32)) -> usize {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8();
    assert_eq!(img.dimensions(), size, "{}", path.display());
    let (w, h) = size;
    let mut coloured = 0;
    for y in h / 5..h * 4 / 5 {
        for x in w / 8..w * 7 / 8 {
            let p = img.get_pixel(x, y).0;
            let (mx, mn) = (p.iter().max().unwrap(), p.iter().min().unwrap());
            if mx - mn > 60 {
                coloured += 1;
            }
        }
    }
    coloured
}

/// A minimal well-formedness check: one root `<svg>`, every tag closed in order.
fn check_svg(path: &Path, title: &str) {
    let s = std::fs::read_to_string(path).unwrap();
    let body = s.trim();
    let start = body.find("<svg").expect("an <svg> element");
    assert!(
        body.ends_with("</svg>"),
        "{}: does not end with </svg>",
        path.display()
    );
    let mut stack: Vec<String> = Vec::new();
    let mut rest = &body[start..];
    while let Some(i) = rest.find('<') {
        let j = rest[i..].find('>').expect("unclosed tag") + i;
        let tag = &rest[i + 1..j];
        if tag.starts_with('?') || tag.starts_with('!') {
        } else if let Some(name) = tag.strip_prefix('/') {
            let open = stack.pop().unwrap_or_else(|| panic!("stray </{name}>"));
            assert_eq!(open, name.trim(), "{}: mismatched tags", path.display());
        } else if !tag.ends_with('/') {
            let name = tag.split_whitespace().next().unwrap_or("").to_string();
            stack.push(name);
        }
        rest = &rest[j + 1..];
    }
    assert!(stack.is_empty(), "{}: unclosed {stack:?}", path.display());
    assert!(
        s.contains(title),
        "{}: title `{title}` not found",
        path.display()
    );
    assert!(s.contains("font-family=\"sans-serif\""));
}

/// Render one kind as PNG (explicit size) and as SVG; check both.
fn render(dir: &Path, name: &str, args: &[&str], title: &str, min_coloured: usize) {
    let png = dir.join(format!("{name}.png"));
    let svg = dir.join(format!("{name}.svg"));
    let mut a: Vec<&str> = args.to_vec();
    a.extend(["--out", png.to_str().unwrap(), "--size", "1000x760"]);
    ok(&a);
    let coloured = check_png(&png, (1000, 760));
    assert!(
        coloured >= min_coloured,
        "{name}: only {coloured} coloured pixels in the plot area"
    );
    let mut a: Vec<&str> = args.to_vec();
    a.extend(["--out", svg.to_str().unwrap()]);
    ok(&a);
    check_svg(&svg, title);
}

#[test]
fn every_kind_renders_as_png_and_svg_without_system_fonts() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = siso(d, "a.csv", 4000, 0.0);
    let b = siso(d, "b.csv", 3000, 2.0);
    let m = mimo(d, 3000);
    let r = results(d);
    let l = ladder(d);
    let (a, b, m, r, l) = (
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        m.to_str().unwrap(),
        r.to_str().unwrap(),
        l.to_str().unwrap(),
    );
    render(
        d,
        "loop",
        &["plot", "loop", "--data", a],
        "Hysteresis loop: displacement vs voltage (a)",
        2000,
    );
    render(
        d,
        "loop_cycle",
        &[
            "plot",
            "loop",
            "--data",
            a,
            "--color",
            "cycle",
            "--title",
            "Loop by cycle",
        ],
        "Loop by cycle",
        2000,
    );
    render(
        d,
        "loop_two",
        &["plot", "loop", "--data", a, "--data", b],
        "Hysteresis loop",
        2000,
    );
    render(
        d,
        "loop_mimo",
        &["plot", "loop", "--data", m],
        "Hysteresis loops (mimo)",
        2000,
    );
    render(
        d,
        "time",
        &["plot", "time", "--data", a, "--from", "0.5", "--to", "2.5"],
        "Measured, model and residual over time (a)",
        2000,
    );
    render(
        d,
        "residual_loop",
        &["plot", "residual-loop", "--data", a],
        "Residual loop (a): area/box",
        1000,
    );
    render(
        d,
        "parity",
        &["plot", "parity", "--data", a, "--data", b],
        "Predicted against measured (a)",
        2000,
    );
    render(
        d,
        "parity_flags",
        &["plot", "parity", "--one-step", a, "--free-run", b],
        "R² = ",
        2000,
    );
    render(
        d,
        "spectrum",
        &["plot", "spectrum", "--data", a],
        "Amplitude spectra",
        1000,
    );
    render(
        d,
        "sweep",
        &["plot", "sweep", "--results", r],
        "free-run test R²",
        20_000,
    );
    render(
        d,
        "ladder",
        &["plot", "ladder", "--data", l],
        "Model improvement",
        20_000,
    );
    // the SVG sweep marks the diverged cell
    assert!(std::fs::read_to_string(d.join("sweep.svg"))
        .unwrap()
        .contains("diverged"));
}

#[test]
fn default_sizes_follow_the_panels() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let m = mimo(d, 500);
    let out = d.join("m.png");
    ok(&[
        "plot",
        "loop",
        "--data",
        m.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    // 2 x 2 panels of 900 x 680, a 60 px title strip
    assert!(check_png(&out, (1800, 1420)) > 1000);
    let out = d.join("d.png");
    ok(&[
        "plot",
        "loop",
        "--data",
        m.to_str().unwrap(),
        "--no-cross",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(check_png(&out, (1800, 740)) > 1000);
}

#[test]
fn a_blank_record_is_not_reported_as_drawn() {
    // guard for the checker itself: a constant record draws (almost) no coloured pixels
    // off the single horizontal line, whereas a loop fills many rows
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = d.join("flat.csv");
    let mut s = String::from("t,u,y\n");
    for k in 0..100 {
        s += &format!("{},{},1\n", k as f64 * 0.01, k as f64);
    }
    std::fs::write(&p, s).unwrap();
    let out = d.join("flat.png");
    ok(&[
        "plot",
        "loop",
        "--data",
        p.to_str().unwrap(),
        "--color",
        "series",
        "--out",
        out.to_str().unwrap(),
        "--size",
        "1000x760",
    ]);
    let flat = check_png(&out, (1000, 760));
    let a = siso(d, "a.csv", 2000, 0.0);
    let out2 = d.join("a.png");
    ok(&[
        "plot",
        "loop",
        "--data",
        a.to_str().unwrap(),
        "--color",
        "series",
        "--out",
        out2.to_str().unwrap(),
        "--size",
        "1000x760",
    ]);
    assert!(check_png(&out2, (1000, 760)) > 3 * flat, "{flat}");
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    v.sort();
    v
}

#[test]
fn bad_input_gets_clear_errors_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = siso(d, "a.csv", 500, 0.0);
    let a = a.to_str().unwrap();
    let out = d.join("fig.png");
    let o = out.to_str().unwrap();
    let before = files_in(d);

    // a column that does not exist: the error lists those that do
    let e = fails(&[
        "plot",
        "loop",
        "--data",
        a,
        "--outputs",
        "force_N",
        "--inputs",
        "voltage_V",
        "--out",
        o,
    ]);
    assert!(
        e.contains("force_N") && e.contains("t, voltage_V, displacement_um, displacement_um_hat"),
        "{e}"
    );

    // an empty record
    let empty = d.join("empty.csv");
    std::fs::write(&empty, "t,u,y\n").unwrap();
    let e = fails(&[
        "plot",
        "loop",
        "--data",
        empty.to_str().unwrap(),
        "--out",
        o,
    ]);
    assert!(e.contains("empty"), "{e}");

    // an unknown extension names the valid ones
    let e = fails(&[
        "plot",
        "loop",
        "--data",
        a,
        "--out",
        d.join("fig.jpg").to_str().unwrap(),
    ]);
    assert!(
        e.contains(".jpg") && e.contains(".png") && e.contains(".svg"),
        "{e}"
    );
    let e = fails(&[
        "plot",
        "loop",
        "--data",
        a,
        "--out",
        d.join("fig").to_str().unwrap(),
    ]);
    assert!(e.contains(".png"), "{e}");

    // an output folder that does not exist, or is a file
    let e = fails(&[
        "plot",
        "loop",
        "--data",
        a,
        "--out",
        d.join("no/such/dir/fig.png").to_str().unwrap(),
    ]);
    assert!(e.contains("does not exist"), "{e}");
    let e = fails(&[
        "plot",
        "loop",
        "--data",
        a,
        "--out",
        d.join("a.csv/fig.png").to_str().unwrap(),
    ]);
    assert!(e.contains("a.csv"), "{e}");

    // a size out of range, or not a size
    let e = fails(&["plot", "loop", "--data", a, "--size", "10x10", "--out", o]);
    assert!(e.contains("10x10") && e.contains("200..=10000"), "{e}");
    let e = fails(&["plot", "loop", "--data", a, "--size", "big", "--out", o]);
    assert!(e.contains("WIDTHxHEIGHT"), "{e}");

    // a model figure of a record without a model
    let plain = d.join("plain.csv");
    std::fs::write(&plain, "t,u,y\n0,0,0\n0.1,1,1\n0.2,0,0.5\n0.3,-1,-1\n").unwrap();
    let e = fails(&[
        "plot",
        "residual-loop",
        "--data",
        plain.to_str().unwrap(),
        "--out",
        o,
    ]);
    assert!(e.contains("y_hat") && e.contains("t, u, y"), "{e}");

    // a window outside the record
    let e = fails(&["plot", "time", "--data", a, "--from", "100", "--out", o]);
    assert!(e.contains("window") && e.contains("spans"), "{e}");

    // a sweep whose converged row lacks its R^2
    let r = d.join("results.csv");
    std::fs::write(
        &r,
        "output,lags,neurons,lr,batch,r2_fr_test,diverged,train_seconds\ny,2,10,0.01,32,,0,3\n",
    )
    .unwrap();
    let e = fails(&[
        "plot",
        "sweep",
        "--results",
        r.to_str().unwrap(),
        "--out",
        o,
    ]);
    assert!(e.contains("line 2") && e.contains("r2_fr_test"), "{e}");

    let mut expected = before.clone();
    expected.extend([
        "empty.csv".to_string(),
        "plain.csv".to_string(),
        "results.csv".to_string(),
    ]);
    expected.sort();
    assert_eq!(files_in(d), expected, "nothing written, no temporary left");

    // an existing file is kept without --force, replaced with it
    std::fs::write(&out, b"keep me").unwrap();
    let e = fails(&["plot", "loop", "--data", a, "--out", o]);
    assert!(e.contains("already exists") && e.contains("--force"), "{e}");
    assert_eq!(std::fs::read(&out).unwrap(), b"keep me");
    ok(&["plot", "loop", "--data", a, "--out", o, "--force"]);
    assert!(check_png(&out, (840, 780)) > 1000);
    assert!(!files_in(d).iter().any(|f| f.contains(".tmp")));
}

#[test]
fn the_library_draws_a_loop_without_the_command_line() {
    use hystbench::data::{IoRecord, Signal};
    use hystbench::plot::{loop_figure, render, Format, LoopFigure, LoopOptions, PlotRecord};
    let n = 5000;
    let u: Vec<f64> = (0..n).map(|k| (k as f64 * 0.01).sin()).collect();
    let mut z = 0.0f64;
    let y: Vec<f64> = u
        .iter()
        .map(|&v| {
            z = z.clamp(v - 0.2, v + 0.2);
            z
        })
        .collect();
    let io = IoRecord {
        path: "memory".into(),
        ts: 1e-3,
        t0: 0.0,
        time_name: "t".into(),
        inputs: vec![Signal {
            name: "u_N".into(),
            values: u.clone(),
        }],
        outputs: vec![Signal {
            name: "y_m".into(),
            values: y,
        }],
    };
    let rec = PlotRecord::from_io("memory", io)
        .with_prediction(0, u)
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    // the figure of `r` as SVG text, through a file
    let draw = |r: &PlotRecord, name: &str| {
        let p = dir.path().join(name);
        loop_figure(
            std::slice::from_ref(r),
            &LoopOptions::default(),
            &p,
            None,
            false,
        )
        .unwrap();
        std::fs::read_to_string(&p).unwrap()
    };
    let svg = draw(&rec, "loop.svg");
    assert!(
        svg.contains("u [N]") && svg.contains("y [m]") && svg.contains("model"),
        "axis labels with units"
    );
    assert!(
        !svg.contains("prediction band"),
        "no band given, none drawn"
    );
    assert!(!svg.contains("\n1.5\n"), "the loop alone stays within 1.04");
    // a band is drawn under the model's loop, and the axis holds its edges
    let svg = draw(&rec.clone().with_band(0, vec![0.5; n]).unwrap(), "band.svg");
    assert!(svg.contains("prediction band (95 %)"), "the band's legend");
    assert!(
        svg.contains("\n1.5\n"),
        "the y axis reaches the band's upper edge"
    );
    // in memory, for commands that stage several files in one OutputGuard
    let options = LoopOptions::default();
    let fig = LoopFigure::new(std::slice::from_ref(&rec), &options).unwrap();
    let png = render(&fig, Format::Png, Some((640, 480))).unwrap();
    assert_eq!(&png[1..4], b"PNG");
}

#[test]
fn units_come_from_the_simulate_sidecar_when_the_columns_have_none() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = d.join("sim.csv");
    let mut s = String::from("t,u,y\n");
    for k in 0..200 {
        let u = (k as f64 * 0.05).sin();
        s += &format!("{},{u},{}\n", k as f64 * 1e-3, 0.8 * u);
    }
    std::fs::write(&p, s).unwrap();
    let out = d.join("a.svg");
    ok(&[
        "plot",
        "loop",
        "--data",
        p.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let svg = std::fs::read_to_string(&out).unwrap();
    assert!(!svg.contains("u [V]"));
    std::fs::write(
        d.join("sim.json"),
        r#"{"plant": {"units": {"input": "V", "output": "um"}}}"#,
    )
    .unwrap();
    ok(&[
        "plot",
        "loop",
        "--data",
        p.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--force",
    ]);
    let svg = std::fs::read_to_string(&out).unwrap();
    assert!(
        svg.contains("u [V]") && svg.contains("y [µm]"),
        "units from sim.json"
    );
}
