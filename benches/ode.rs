//! Throughput of the Bouc-Wen benchmark ODE plant: output samples per second on the official
//! sine-sweep input (153,000 samples at 750 Hz), single core, for each integrator path.
//!
//! Run: `cargo bench --bench ode`.

use hystbench::data::read_csv;
use hystbench::plant::ode::{
    BoucWenBenchmarkSpec, InputInterpolation, IntegratorKind, SampledInput,
};
use std::path::Path;
use std::time::Instant;

fn main() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/boucwen_test_sinesweep.csv");
    let rec = read_csv(&path).expect("tests/data/boucwen_test_sinesweep.csv");
    let u = rec.column("u_N").unwrap().to_vec();
    let y_ref = rec.column("y_m").unwrap().to_vec();
    let ts = 1.0 / 750.0;
    let n = u.len();
    println!("Bouc-Wen benchmark plant, sine sweep, {n} output samples, single thread");
    println!(
        "{:<40} {:>10} {:>14} {:>14}",
        "path", "time [s]", "samples/s", "RMS err [m]"
    );
    let t = Instant::now();
    let reps = 5;
    for _ in 0..reps {
        std::hint::black_box(
            SampledInput::new(&u, ts, false, InputInterpolation::Bandlimited).unwrap(),
        );
    }
    let secs = t.elapsed().as_secs_f64() / reps as f64;
    println!(
        "{:<40} {:>10.4} {:>14.3e} {:>14}",
        "input only (band-limited, 8x grid)",
        secs,
        n as f64 / secs,
        "-"
    );
    let cases = [
        (
            "dopri5 rtol 1e-8 (default)",
            IntegratorKind::Dopri5,
            1e-8,
            20,
        ),
        ("dopri5 rtol 1e-6", IntegratorKind::Dopri5, 1e-6, 20),
        ("rk4 x20", IntegratorKind::Rk4, 1e-8, 20),
        ("rk4 x10", IntegratorKind::Rk4, 1e-8, 10),
        ("rk4 x5", IntegratorKind::Rk4, 1e-8, 5),
    ];
    for (name, integrator, rtol, os) in cases {
        let plant = BoucWenBenchmarkSpec {
            integrator,
            rtol,
            oversampling: os,
            ..BoucWenBenchmarkSpec::default()
        }
        .check()
        .unwrap();
        // One warm-up run, then the best of three.
        let mut y = plant.simulate(&u, ts, false).unwrap();
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let t = Instant::now();
            y = std::hint::black_box(plant.simulate(&u, ts, false).unwrap());
            best = best.min(t.elapsed().as_secs_f64());
        }
        let e = (y
            .iter()
            .zip(&y_ref)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            / n as f64)
            .sqrt();
        println!(
            "{:<40} {:>10.4} {:>14.3e} {:>14.3e}",
            name,
            best,
            n as f64 / best,
            e
        );
    }
}
