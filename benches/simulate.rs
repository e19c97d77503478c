//! Simulation throughput of the shipped chain plants, single core (issue: at least 20 million
//! samples/s for a 10-operator Prandtl-Ishlinskii and for Bouc-Wen with second-order dynamics).
//! Run: `cargo bench --bench simulate`.

use hystbench::plant::Plant;
use std::path::Path;
use std::time::Instant;

fn main() {
    let n = 2_000_000;
    let ts = 1e-4;
    let u: Vec<f64> = (0..n)
        .map(|k| {
            let t = k as f64 * ts;
            25.0 * (2.0 * std::f64::consts::PI * 2.0 * t).sin()
                + 10.0 * (2.0 * std::f64::consts::PI * 5.3 * t + 1.0).sin()
        })
        .collect();
    let u2: Vec<f64> = u.iter().rev().copied().collect();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("plants");
    println!("| plant | samples | best of 5 | output samples/s (single core) |");
    println!("|---|---|---|---|");
    for name in [
        "prandtl_ishlinskii_piezo",
        "bouc_wen_piezo",
        "prandtl_ishlinskii_asymmetric",
        "creep_piezo",
        "piezo_2dof",
    ] {
        let plant = Plant::from_file(&root.join(format!("{name}.json"))).unwrap();
        let inputs: Vec<&[f64]> = if plant.inputs.len() == 2 {
            vec![&u, &u2]
        } else {
            vec![&u]
        };
        let mut best = f64::MAX;
        for _ in 0..5 {
            let t0 = Instant::now();
            let y = plant.simulate(&inputs, ts).unwrap();
            std::hint::black_box(&y);
            best = best.min(t0.elapsed().as_secs_f64());
        }
        let outs = plant.outputs.len() as f64;
        println!(
            "| {name} | {n} | {:.1} ms | {:.1} M |",
            best * 1e3,
            n as f64 * outs / best / 1e6
        );
    }
}
