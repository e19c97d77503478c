//! `inspect` on 2,000,000 samples (goal: under 1 s on one core), and the share of the checks
//! in a modelling command's time (goal: under 2 %): the same record through `inspect` and
//! through the grey-box fit that `fit` runs on it.
//! Run: `cargo bench --bench inspect` (`RAYON_NUM_THREADS=1` for one core).

use hystbench::data::inspect::inspect;
use hystbench::data::{CsvFormat, Record};
use hystbench::plant::PlantSpec;
use hystbench::scenario::ScenarioSpec;
use hystbench::simulator::simulate_scenario;
use std::path::Path;
use std::time::Instant;

fn record(samples: usize) -> Record {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let ppath = root.join("plants/hidden_creep_piezo.json");
    let spath = root.join("scenarios/hidden_effect_1khz.json");
    let mut sc = ScenarioSpec::read(&spath).unwrap();
    // the scenario stretched: its 40 s pattern repeated
    let reps = samples.div_ceil(sc.samples);
    let one = sc.inputs[0].clone();
    sc.inputs = vec![serde_json::from_value(serde_json::json!({
        "concat": (0..reps).map(|_| serde_json::json!({"duration_s": 40.0, "excitation": one})).collect::<Vec<_>>()
    }))
    .unwrap()];
    sc.samples = samples;
    sc.split = None;
    let plant = PlantSpec::read(&ppath).unwrap().check(&ppath).unwrap();
    let rec = simulate_scenario(&plant, &sc.check(&spath).unwrap(), None)
        .unwrap()
        .record;
    let (names, columns) = rec.to_columns();
    Record {
        path: "bench.csv".into(),
        names,
        columns,
        format: CsvFormat::default(),
    }
}

fn main() {
    println!("| bench | samples | best of 3 | goal | findings |");
    println!("|---|---|---|---|---|");
    let mut at_200k = 0.0;
    for n in [200_000, 2_000_000] {
        let rec = record(n);
        let (ins, outs) = (vec!["u".to_string()], vec!["y".to_string()]);
        let mut best = f64::MAX;
        let mut found = 0;
        for _ in 0..3 {
            let t0 = Instant::now();
            let r = inspect(&rec, &ins, &outs);
            best = best.min(t0.elapsed().as_secs_f64());
            found = r.findings.len();
        }
        println!(
            "| inspect | {n} | {best:.3} s | {} | {found} |",
            if n == 2_000_000 { "< 1 s" } else { "" }
        );
        if n == 200_000 {
            at_200k = best;
        }
    }
    // the checks' share of the modelling commands that run them, on 200,000 samples
    let rec = record(200_000);
    let io = hystbench::data::IoRecord::from_record(&rec, None, None, true).unwrap();
    println!();
    println!("| command (library call), 200,000 samples | time | inspect's share | goal |");
    println!("|---|---|---|---|");
    let t0 = Instant::now();
    hystbench::graybox::GreyBoxConfig::from_effect_list("hysteresis,dynamics")
        .unwrap()
        .fit(&io)
        .unwrap();
    let fit = t0.elapsed().as_secs_f64();
    println!(
        "| fit --effects hysteresis,dynamics | {fit:.2} s | {:.2} % | < 2 % |",
        100.0 * at_200k / fit
    );
    let (train, _) = io.split_halves();
    let t0 = Instant::now();
    hystbench::narx::NarxConfig::new(train.input_names(), train.output_names())
        .fit(&train)
        .unwrap();
    let identify = t0.elapsed().as_secs_f64();
    println!(
        "| identify (default, first half trains) | {identify:.2} s | {:.2} % | < 2 % |",
        100.0 * at_200k / identify
    );
}
