//! External ground truth for the Bouc-Wen benchmark plant (Noël & Schoukens, 2016): the
//! simulator driven by the official test inputs reproduces the official noiseless outputs.
//!
//! Data: tests/data/boucwen_test_{multisine,sinesweep}.csv (see tests/data/README.md).
//! Run with `cargo test --release --test ode_benchmark -- --nocapture` to see the RMS errors.

use hystbench::data::read_csv;
use hystbench::plant::ode::bouc_wen_benchmark::IntegratorKind;
use hystbench::plant::ode::{BoucWenBenchmarkSpec, InputInterpolation};
use std::path::Path;

/// (u, y, ts) of a test file.
fn load(name: &str) -> (Vec<f64>, Vec<f64>, f64) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    let rec = read_csv(&path).expect("test data present");
    let u = rec.column("u_N").unwrap().to_vec();
    let y = rec.column("y_m").unwrap().to_vec();
    let t = rec.column("t_s").unwrap();
    let ts = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    assert!((ts - 1.0 / 750.0).abs() < 1e-12);
    (u, y, 1.0 / 750.0)
}

fn rms_error(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    (a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / a.len() as f64).sqrt()
}

fn plant_from_shipped_spec() -> BoucWenBenchmarkSpec {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/bouc_wen_benchmark.json");
    let text = std::fs::read_to_string(path).expect("plants/bouc_wen_benchmark.json");
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    serde_json::from_value(v["ode"]["bouc_wen_benchmark"].clone()).expect("valid spec")
}

fn run(spec: &BoucWenBenchmarkSpec, file: &str, periodic: bool) -> (f64, f64) {
    let (u, y_ref, ts) = load(file);
    let plant = spec.check().unwrap();
    let t = std::time::Instant::now();
    let y = plant.simulate(&u, ts, periodic).unwrap();
    let secs = t.elapsed().as_secs_f64();
    let e = rms_error(&y, &y_ref);
    let rms_ref = rms_error(&y_ref, &vec![0.0; y_ref.len()]);
    println!(
        "{file}: {:?}/{:?} rtol {:e} x{}: RMS error {e:.3e} m (output RMS {rms_ref:.3e} m), {secs:.2} s",
        spec.integrator, spec.input_interpolation, spec.rtol, spec.oversampling
    );
    (e, rms_ref)
}

#[test]
fn multisine_periodic_steady_state_matches_official_output() {
    let spec = plant_from_shipped_spec();
    let (e, rms_ref) = run(&spec, "boucwen_test_multisine.csv", true);
    assert!(rms_ref > 6e-4 && rms_ref < 7e-4);
    assert!(e <= 2e-6, "multisine RMS error {e:e} m > 2e-6 m");
}

#[test]
fn sine_sweep_from_rest_matches_official_output() {
    let spec = plant_from_shipped_spec();
    let (e, rms_ref) = run(&spec, "boucwen_test_sinesweep.csv", false);
    assert!(rms_ref > 6e-4 && rms_ref < 7e-4);
    assert!(e <= 5e-6, "sweep RMS error {e:e} m > 5e-6 m");
}

/// Exploration of the options (not an acceptance test):
/// `cargo test --release --test ode_benchmark -- --ignored --nocapture`.
#[test]
#[ignore]
fn option_survey() {
    let base = BoucWenBenchmarkSpec::default();
    for (integrator, interp, rtol, os) in [
        (
            IntegratorKind::Dopri5,
            InputInterpolation::Bandlimited,
            1e-8,
            20,
        ),
        (
            IntegratorKind::Dopri5,
            InputInterpolation::Bandlimited,
            1e-10,
            20,
        ),
        (
            IntegratorKind::Rk4,
            InputInterpolation::Bandlimited,
            1e-8,
            20,
        ),
        (
            IntegratorKind::Rk4,
            InputInterpolation::Bandlimited,
            1e-8,
            10,
        ),
        (
            IntegratorKind::Rk4,
            InputInterpolation::Bandlimited,
            1e-8,
            5,
        ),
        (IntegratorKind::Rk4, InputInterpolation::Linear, 1e-8, 20),
        (IntegratorKind::Rk4, InputInterpolation::Zoh, 1e-8, 20),
    ] {
        let spec = BoucWenBenchmarkSpec {
            integrator,
            input_interpolation: interp,
            rtol,
            oversampling: os,
            ..base.clone()
        };
        run(&spec, "boucwen_test_multisine.csv", true);
        run(&spec, "boucwen_test_sinesweep.csv", false);
    }
}

/// The fast path (hand-written RK4, 10 and 20 steps per sample) against the reference path
/// (ode_solvers Dopri5, rtol 1e-10) on the official multisine and the first 20 s of the sweep.
/// The |y'| and |z| kinks of the right-hand side cut RK4 to about second order (measured on the
/// multisine, max difference to RK4 x320: 2.6e-7 m at x10, 7.9e-8 m at x20, 4.9e-9 m at x80;
/// Dopri5 rtol 1e-10: 5.4e-10 m), so the bounds are 5e-7 m (x10) and 2e-7 m (x20), about
/// 2e-4 and 1e-4 of the largest |y|.
#[test]
fn rk4_fast_path_agrees_with_dopri5() {
    for (file, periodic, len) in [
        ("boucwen_test_multisine.csv", true, 8192),
        ("boucwen_test_sinesweep.csv", false, 15_000),
    ] {
        let (u, _, ts) = load(file);
        let u = &u[..len];
        let dopri5 = BoucWenBenchmarkSpec {
            integrator: IntegratorKind::Dopri5,
            rtol: 1e-10,
            ..BoucWenBenchmarkSpec::default()
        };
        let a = dopri5.check().unwrap().simulate(u, ts, periodic).unwrap();
        let max_y = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(max_y > 5e-4, "the test must move the plant");
        for (oversampling, bound) in [(10, 5e-7), (20, 2e-7)] {
            let rk4 = BoucWenBenchmarkSpec {
                integrator: IntegratorKind::Rk4,
                oversampling,
                ..BoucWenBenchmarkSpec::default()
            };
            let b = rk4.check().unwrap().simulate(u, ts, periodic).unwrap();
            let max_diff = a
                .iter()
                .zip(&b)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            println!(
                "{file}: max |rk4 x{oversampling} - dopri5| = {max_diff:.3e} m (max |y| {max_y:.3e} m)"
            );
            assert!(
                max_diff < bound,
                "{file}: RK4 x{oversampling} and Dopri5 differ by {max_diff:e} m > {bound:e} m"
            );
        }
    }
}
