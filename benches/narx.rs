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
    println!("| measurement | value |");
    println!("|---|---:|");
    for form in [RegressorForm::Lagged] {
        let reg = Regressor::fit(lags, form, &s);
        let d = Design::new(&s, &reg);
        for (batch, epochs) in [(128usize, 20usize), (1, 3)] {
            for kind in [OptimizerKind::Rmsprop, OptimizerKind::Adam] {
                let mut net = Mlp::glorot(&[8, 10, 1], false, 1);
                let t = Instant::now();
                let r = train_one_step(&mut net, &d, None, kind, 0.01, batch, epochs, None, 2);
                let per = t.elapsed().as_secs_f64() / epochs as f64;
                black_box(r);
                println!(
                    "| one-step epoch, {} rows, batch {batch}, {kind:?} | {:.2} ms |",
                    d.rows(),
                    per * 1e3
                );
            }
        }
    }
    // free run of a trained-like 10-neuron model over the test half, repeated
    let reg = Regressor::fit(lags, RegressorForm::Incremental, &s);
    let mut net = Mlp::glorot(&[8, 10, 1], true, 3);
    net.params.iter_mut().for_each(|p| *p *= 0.05);
    let st = Series {
        y: sy.apply(&test.outputs[0].values),
        u: vec![su.apply(&test.inputs[0].values)],
    };
    let reps = 40;
    let t = Instant::now();
    for _ in 0..reps {
        black_box(free_run_fast(&net, &reg, &st, -1e9, 1e9));
    }
    let sps = (reps * st.len()) as f64 / t.elapsed().as_secs_f64();
    println!(
        "| free run, 10 neurons, 4 lags | {:.2} M samples/s |",
        sps / 1e6
    );
    // default identify per plant (whole pipeline, 2 restarts in parallel)
    for plant in Plant1::ALL {
        let rec = seed_1dof(plant, 50_000, 1);
        let (train, _) = rec.split_halves();
        let cfg = NarxConfig::new(train.input_names(), train.output_names());
        let m = cfg.fit(&train).unwrap();
        println!(
            "| default identify, {} (25,000 samples) | {:.2} s |",
            plant.name(),
            m.train_seconds
        );
        let mut study = cfg.clone();
        study.protocol = Protocol::Study;
        study.optimizer = OptimizerKind::Rmsprop;
        let m = study.fit(&train).unwrap();
        println!(
            "| study protocol 100 epochs batch 128, {} | {:.2} s |",
            plant.name(),
            m.train_seconds
        );
    }
    if std::env::var_os("NARX_BENCH_GRID").is_some() {
        let t = Instant::now();
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
            "| study grid, 64 settings, default protocol | {:.1} s, {good}/{n} with FR test R^2 >= 0.99 |",
            t.elapsed().as_secs_f64()
        );
    }
}
