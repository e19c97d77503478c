//! `compensate` speed: samples per second of the inverse of each shipped 1-DoF plant and of the
//! 2-DoF cantilever, and of NARX models from the default identifier, on one thread (goals of
//! the compensation issue: 1 million samples/s for a grey-box model, 100,000 for a NARX model;
//! a real-time loop at 10 kHz needs 10,000). Run: `cargo bench --bench compensate`.

use hystbench::compensate::{compensate, CompensateOptions};
use hystbench::narx::base::BaseUse;
use hystbench::narx::synthetic::{broadband_1dof, Plant1};
use hystbench::narx::NarxConfig;
use hystbench::plant::PlantSpec;
use std::path::Path;
use std::time::Instant;

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let ts = 1e-4;
    let n = 100_000;
    let r = |phase: f64| -> Vec<f64> {
        (0..n)
            .map(|k| {
                let t = k as f64 * ts;
                let ramp = 0.5 - 0.5 * (std::f64::consts::PI * (t / 0.2).min(1.0)).cos();
                ramp * (15.0 * (2.0 * std::f64::consts::PI * 2.0 * t + phase).sin()
                    + 5.0 * (2.0 * std::f64::consts::PI * 13.0 * t).sin())
            })
            .collect()
    };
    println!("| plant | samples | seconds | samples/s |\n|---|---|---|---|");
    for name in [
        "prandtl_ishlinskii_piezo.json",
        "prandtl_ishlinskii_asymmetric.json",
        "bouc_wen_piezo.json",
        "hidden_creep_piezo.json",
        "piezo_2dof.json",
    ] {
        let path = root.join("plants").join(name);
        let plant = PlantSpec::read(&path).unwrap().check(&path).unwrap();
        let refs: Vec<Vec<f64>> = (0..plant.outputs.len()).map(|o| r(o as f64)).collect();
        let rr: Vec<&[f64]> = refs.iter().map(Vec::as_slice).collect();
        let mut best = f64::MAX;
        for _ in 0..3 {
            let t0 = Instant::now();
            let c = compensate(&plant, &rr, ts, &CompensateOptions::default()).unwrap();
            best = best.min(t0.elapsed().as_secs_f64());
            assert_eq!(c.inputs[0].len(), n);
        }
        println!("| {name} | {n} | {best:.3} | {:.0} |", n as f64 / best);
    }
    // NARX models identified on a noisy record that covers the references' band
    let r1 = r(0.0);
    for (kind, name) in [
        (Plant1::PrandtlIshlinskii, "prandtl_ishlinskii_piezo.json"),
        (Plant1::BoucWen, "bouc_wen_piezo.json"),
    ] {
        let rec = broadband_1dof(kind, 3);
        for greybox in [true, false] {
            let mut cfg = NarxConfig::new(rec.input_names(), rec.output_names());
            cfg.robust.try_greybox = greybox;
            let m = cfg.fit(&rec).unwrap();
            let what = match m.base.as_ref().map(|b| b.outputs[0].model) {
                Some(BaseUse::Base) => "grey-box base alone",
                Some(BaseUse::BaseAndNetwork) => "grey-box base + network",
                _ => "network",
            };
            let mut best = f64::MAX;
            for _ in 0..3 {
                let t0 = Instant::now();
                let c = compensate(&m, &[&r1], ts, &CompensateOptions::default()).unwrap();
                best = best.min(t0.elapsed().as_secs_f64());
                assert_eq!(c.inputs[0].len(), n);
            }
            println!(
                "| NARX of {name} ({what}) | {n} | {best:.3} | {:.0} |",
                n as f64 / best
            );
        }
    }
}
