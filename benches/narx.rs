//! NARX speed: time per one-step epoch at batch 128 and batch 1 (25,000 training samples,
//! 4 lags, 10 neurons, the Keras peer's setting), simulation-error gradient throughput, free-run
//! samples per second, default `identify` time per plant, and optionally the study's 64-setting
//! grid (`NARX_BENCH_GRID=1`). Run: `cargo bench --bench narx`.

use hystbench::narx::mlp::Mlp;
use hystbench::narx::regressors::{Lags, Regressor, RegressorForm, Series, Standardiser};
use hystbench::narx::synthetic::{seed_1dof, Plant1};
use hystbench::narx::train::{free_run_fast, train_one_step, Design};
use hystbench::narx::{NarxConfig, OptimizerKind, Protocol};
use std::hint::black_box;
use std::time::Instant;

/// CPU seconds of this process (user + system) from /proc/self/stat, so that the numbers mean
/// something on a machine shared with other jobs; `None` where unavailable.
fn cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = &s[s.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// Wall and CPU seconds of `f`.
fn timed<T>(f: impl FnOnce() -> T) -> (T, f64, Option<f64>) {
    let c0 = cpu_seconds();
    let t = Instant::now();
    let r = f();
    let wall = t.elapsed().as_secs_f64();
    let cpu = c0.and_then(|c0| cpu_seconds().map(|c1| c1 - c0));
    (r, wall, cpu)
}

fn ms(v: Option<f64>, per: f64) -> String {
    v.map_or("-".into(), |v| format!("{:.2}", v / per * 1e3))
}

fn main() {
    let rec = seed_1dof(Plant1::BoucWen, 50_000, 1);
    let (train, test) = rec.split_halves();
    let su = Standardiser::fit(&train.inputs[0].values);
    let sy = Standardiser::fit(&train.outputs[0].values);
    let s = Series {
        y: sy.apply(&train.outputs[0].values),
        u: vec![su.apply(&train.inputs[0].values)],
    };
    let lags = Lags {
        output: 4,
        input: 4,
        delay: 1,
    };
    println!("| measurement | wall | CPU |");
    println!("|---|---:|---:|");
    let reg = Regressor::fit(lags, RegressorForm::Lagged, &s);
    let d = Design::new(&s, &reg);
    for (batch, epochs) in [(128usize, 100usize), (1, 30)] {
        for kind in [OptimizerKind::Rmsprop, OptimizerKind::Adam] {
            let mut net = Mlp::glorot(&[8, 10, 1], false, 1);
            let (r, wall, cpu) =
                timed(|| train_one_step(&mut net, &d, None, kind, 0.01, batch, epochs, None, 2));
            black_box(r);
            println!(
                "| one-step epoch (ms), {} rows, batch {batch}, {kind:?} | {:.2} | {} |",
                d.rows(),
                wall / epochs as f64 * 1e3,
                ms(cpu, epochs as f64)
            );
        }
    }
    // free run of a 10-neuron model over the test half, repeated
    let reg = Regressor::fit(lags, RegressorForm::Incremental, &s);
    let mut net = Mlp::glorot(&[8, 10, 1], true, 3);
    net.params.iter_mut().for_each(|p| *p *= 0.05);
    let st = Series {
        y: sy.apply(&test.outputs[0].values),
        u: vec![su.apply(&test.inputs[0].values)],
    };
    let reps = 200;
    let (_, wall, cpu) = timed(|| {
        for _ in 0..reps {
            black_box(free_run_fast(&net, &reg, &st, -1e9, 1e9));
        }
    });
    let n = (reps * st.len()) as f64;
    println!(
        "| free run (M samples/s), 10 neurons, 4 lags | {:.2} | {} |",
        n / wall / 1e6,
        cpu.map_or("-".into(), |c| format!("{:.2}", n / c / 1e6))
    );
    // default identify per plant (whole pipeline, 2 restarts in parallel)
    for plant in Plant1::ALL {
        let rec = seed_1dof(plant, 50_000, 1);
        let (train, _) = rec.split_halves();
        let cfg = NarxConfig::new(train.input_names(), train.output_names());
        let (_, wall, cpu) = timed(|| cfg.fit(&train).unwrap());
        println!(
            "| default identify (s), {} (25,000 samples; 2 restarts on 2 threads) | {wall:.2} | {} |",
            plant.name(),
            cpu.map_or("-".into(), |c| format!("{c:.2}"))
        );
        let mut study = cfg.clone();
        study.protocol = Protocol::Study;
        study.optimizer = OptimizerKind::Rmsprop;
        let (_, wall, cpu) = timed(|| study.fit(&train).unwrap());
        println!(
            "| study protocol (s), 100 epochs, batch 128, {} | {wall:.2} | {} |",
            plant.name(),
            cpu.map_or("-".into(), |c| format!("{c:.2}"))
        );
    }
    if std::env::var_os("NARX_BENCH_GRID").is_some() {
        let t = Instant::now();
        let c0 = cpu_seconds();
        let mut good = 0;
        let mut n = 0;
        let settings: Vec<(f64, usize, usize, usize)> = [0.001, 0.01]
            .into_iter()
            .flat_map(|lr| [1, 128].into_iter().map(move |b| (lr, b)))
            .flat_map(|(lr, b)| [2, 3, 4, 5].into_iter().map(move |l| (lr, b, l)))
            .flat_map(|(lr, b, l)| [6, 8, 10, 12].into_iter().map(move |h| (lr, b, l, h)))
            .collect();
        use rayon::prelude::*;
        let r2: Vec<Option<f64>> = settings
            .par_iter()
            .enumerate()
            .map(|(i, &(lr, b, l, h))| {
                let mut c = NarxConfig::new(train.input_names(), train.output_names());
                c.lags.output = l;
                c.lags.input = l;
                c.neurons = h;
                c.lr = lr;
                c.batch = b;
                c.seed = i as u64;
                // as `hystbench sweep`: the grid studies the plain network (no feature selection)
                c.robust.try_features.clear();
                c.robust.try_decimation = false;
                c.robust.try_greybox = false;
                let m = c.fit(&train).unwrap();
                m.evaluate(&train, &test).unwrap()[0].r2_fr_test
            })
            .collect();
        for v in r2 {
            n += 1;
            if v.is_some_and(|x| x >= 0.99) {
                good += 1;
            }
        }
        println!(
            "| study grid (s), 64 settings, default protocol: {good}/{n} with FR test R^2 >= 0.99 | {:.1} | {} |",
            t.elapsed().as_secs_f64(),
            c0.and_then(|c0| cpu_seconds().map(|c| format!("{:.1}", c - c0))).unwrap_or_default()
        );
    }
}
