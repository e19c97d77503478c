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

/// CPU time of this thread in seconds (Linux: /proc/thread-self/stat, clock ticks of 10 ms),
/// so that a machine shared with other jobs does not inflate the numbers; None elsewhere.
fn thread_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").ok()?;
    // Fields after the command name (which is in parentheses): utime is field 14, stime 15.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn main() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/boucwen_test_sinesweep.csv");
    let rec = read_csv(&path).expect("tests/data/boucwen_test_sinesweep.csv");
    let u = rec.column("u_N").unwrap().to_vec();
    let y_ref = rec.column("y_m").unwrap().to_vec();
    let ts = 1.0 / 750.0;
    let n = u.len();
    println!("Bouc-Wen benchmark plant, sine sweep, {n} output samples, single thread");
    println!(
        "{:<34} {:>9} {:>12} {:>12} {:>12} {:>10}",
        "path", "wall [s]", "samples/s", "per CPU-s", "RMS err [m]", "RHS/sample"
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
        "{:<34} {:>9.4} {:>12.3e} {:>12} {:>12} {:>10}",
        "input only (band-limited)",
        secs,
        n as f64 / secs,
        "-",
        "-",
        "-"
    );
    let cases = [
        ("dopri5 rtol 1e-8", IntegratorKind::Dopri5, 1e-8, 20),
        (
            "dopri5 rtol 1e-6 (plants/bouc_wen_benchmark.json)",
            IntegratorKind::Dopri5,
            1e-6,
            20,
        ),
        ("rk4 x20", IntegratorKind::Rk4, 1e-8, 20),
        ("rk4 x10", IntegratorKind::Rk4, 1e-8, 10),
        ("rk4 x5", IntegratorKind::Rk4, 1e-8, 5),
    ];
    let cases = cases.map(|(a, b, c, d)| (a, b, c, d, InputInterpolation::Bandlimited));
    let cases = cases.into_iter().chain([(
        "rk4 x20, zoh input (no interpolation)",
        IntegratorKind::Rk4,
        1e-8,
        20,
        InputInterpolation::Zoh,
    )]);
    for (name, integrator, rtol, os, interp) in cases {
        let plant = BoucWenBenchmarkSpec {
            integrator,
            rtol,
            oversampling: os,
            input_interpolation: interp,
            ..BoucWenBenchmarkSpec::default()
        }
        .check()
        .unwrap();
        // One warm-up run, then the best of three.
        let (mut y, evals) = plant.simulate_counted(&u, ts, false).unwrap();
        let mut best = f64::INFINITY;
        let reps = 5;
        let cpu0 = thread_cpu_seconds();
        for _ in 0..reps {
            let t = Instant::now();
            y = std::hint::black_box(plant.simulate(&u, ts, false).unwrap());
            best = best.min(t.elapsed().as_secs_f64());
        }
        let per_cpu = match (cpu0, thread_cpu_seconds()) {
            (Some(a), Some(b)) if b > a => format!("{:.3e}", (reps * n) as f64 / (b - a)),
            _ => "-".to_string(),
        };
        let e = (y
            .iter()
            .zip(&y_ref)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            / n as f64)
            .sqrt();
        println!(
            "{:<34} {:>9.4} {:>12.3e} {:>12} {:>12.3e} {:>10.1}",
            name,
            best,
            n as f64 / best,
            per_cpu,
            e,
            evals as f64 / n as f64
        );
    }
}
