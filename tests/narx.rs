//! NARX identifier: recovery of known plants in free run, reproducibility at 1 and 2 threads,
//! model files, bad input. Records come from the effect library (`narx::synthetic`), the lead's
//! `seed_1dof` / `seed_2dof` scenarios.
//!
//! The long acceptance run (the study's 64-setting grid) is `#[ignore]`d:
//! `cargo test --release --test narx -- --ignored`.

mod common;

use hystbench::data::{IoRecord, Signal};
use hystbench::effect::hysteresis::HysteresisEffect;
use hystbench::effect::Effect;
use hystbench::narx::synthetic::{seed_1dof, seed_2dof, Plant1};
use hystbench::narx::{FittedNarx, Interaction, Mode, NarxConfig, NarxError, Protocol};
use std::process::Command;

fn config(rec: &IoRecord) -> NarxConfig {
    NarxConfig::new(rec.input_names(), rec.output_names())
}

/// The default protocol's networks alone (no grey-box base): for the tests of the network's
/// own machinery (features, ensembles, bands, sampling, divergence).
fn network_config(rec: &IoRecord) -> NarxConfig {
    let mut c = config(rec);
    c.robust.try_greybox = false;
    c
}

/// Fit on the first half, free-run R^2 on the second, per output.
fn free_run_test_r2(cfg: &NarxConfig, rec: &IoRecord) -> Vec<Option<f64>> {
    let (train, test) = rec.split_halves();
    let m = cfg.fit(&train).expect("fit");
    m.evaluate_split(&train, &test)
        .expect("evaluate")
        .iter()
        .map(|e| e.r2_fr_test)
        .collect()
}

/// Fit on the first half; the free-run test R^2 per output and whether the protocol kept the
/// hysteresis features.
fn fit_and_score(cfg: &NarxConfig, rec: &IoRecord) -> (Vec<Option<f64>>, Option<bool>) {
    let (train, test) = rec.split_halves();
    let m = cfg.fit(&train).expect("fit");
    let r2 = m
        .evaluate_split(&train, &test)
        .expect("evaluate")
        .iter()
        .map(|e| e.r2_fr_test)
        .collect();
    (r2, m.feature_selection.map(|f| f.chosen))
}

#[test]
fn default_protocol_recovers_bouc_wen_piezo_in_free_run() {
    let rec = seed_1dof(Plant1::BoucWen, 50_000, 1);
    let (r2, chosen) = fit_and_score(&config(&rec), &rec);
    let r2 = r2[0].expect("no divergence");
    assert!(r2 >= 0.999, "free-run test R^2 {r2}");
    // no feature selection by default (the grey-box base carries the physics)
    assert_eq!(chosen, None);
}

#[test]
fn default_protocol_recovers_bouc_wen_with_creep_in_free_run() {
    let rec = seed_1dof(Plant1::BoucWenCreep, 50_000, 1);
    let r2 = free_run_test_r2(&config(&rec), &rec)[0].expect("no divergence");
    assert!(r2 >= 0.999, "free-run test R^2 {r2}");
}

#[test]
fn default_protocol_recovers_prandtl_ishlinskii_and_the_feature_selection_keeps_the_plays() {
    let rec = seed_1dof(Plant1::PrandtlIshlinskii, 50_000, 1);
    let r2 = free_run_test_r2(&config(&rec), &rec)[0].expect("no divergence");
    assert!(r2 >= 0.9999, "free-run test R^2 {r2}");
    // The networks alone without features: 0.9980-0.9994 over record seeds 1-4 and --seed 0/1
    // (a finite-lag NARX cannot hold the nine play states of a PI operator); asked to select
    // (`identify --features auto`), the protocol keeps the play operators here (validation MSE
    // 4.5e-4 plain vs 6.0e-6 with): 0.99994.
    let mut cfg = network_config(&rec);
    cfg.robust.try_features = hystbench::effect::registry::narx_candidates();
    let (r2, chosen) = fit_and_score(&cfg, &rec);
    let r2 = r2[0].expect("no divergence");
    assert!(r2 >= 0.9999, "free-run test R^2 with the selection {r2}");
    assert_eq!(chosen, Some(true));
}

#[test]
fn hysteresis_features_improve_prandtl_ishlinskii_and_are_recomputed_on_another_record() {
    let rec = seed_1dof(Plant1::PrandtlIshlinskii, 50_000, 1);
    let (train, test) = rec.split_halves();
    let mut plain = network_config(&rec);
    plain.robust.try_features.clear();
    let plain = free_run_test_r2(&plain, &rec)[0].expect("no divergence");
    let mut cfg = network_config(&train);
    cfg.robust.try_features.clear();
    let u: Vec<&[f64]> = train.inputs.iter().map(|s| &s.values[..]).collect();
    cfg.features = HysteresisEffect.features(&u, train.ts);
    assert_eq!(cfg.features.len(), 8);
    let m = cfg.fit(&train).unwrap();
    let with = m.evaluate(&train, &test).unwrap()[0]
        .r2_fr_test
        .expect("no divergence");
    // measured 0.99994 against 0.99907 without
    assert!(with >= 0.9999, "with features {with}");
    assert!(
        (1.0 - with) < 0.2 * (1.0 - plain),
        "with {with} vs without {plain}"
    );
    // the definition travels in the model file and is recomputed from another record's input
    let back = FittedNarx::from_json(std::path::Path::new("m.json"), &m.to_json()).unwrap();
    assert_eq!(back.config.features, cfg.features);
    let other = seed_1dof(Plant1::PrandtlIshlinskii, 20_000, 2);
    let p = back.predict(&other, Mode::FreeRun).unwrap();
    let s = p[0]
        .scores(&other.outputs[0].values)
        .expect("no divergence");
    assert!(
        s.r2.unwrap() >= 0.999,
        "free run on another record {:?}",
        s.r2
    );
    // a scaled input: the thresholds stay those of the training record, the features follow
    // the new input, so the prediction changes
    let mut half = other.clone();
    half.inputs[0].values.iter_mut().for_each(|v| *v *= 0.5);
    let q = back.predict(&half, Mode::FreeRun).unwrap();
    assert_ne!(p[0].values, q[0].values);
}

#[test]
fn default_protocol_on_the_2dof_record_with_250_training_samples() {
    // Short-record settings (whole record for simulation error and selection, 16 restarts,
    // 3000 steps), the network additive in the inputs and the median of the best 8 restarts:
    // 72 of 72 outputs >= 0.99 over record seeds 1-8 x --seed 0-2 and 1-4 x 3-5 (lowest
    // 0.9906; docs/narx.md). Here record seed 1 at --seed 0 (the lowest of that record before:
    // 0.9848 / 0.9886).
    let rec = seed_2dof(1);
    let cfg = config(&rec);
    for (i, r2) in free_run_test_r2(&cfg, &rec).into_iter().enumerate() {
        let r2 = r2.expect("no divergence");
        assert!(r2 >= 0.99, "output {i}: free-run test R^2 {r2}");
    }
}

/// The default network of a 2-input record is additive in the inputs: with the output lags
/// held, the effect of moving u1 does not depend on u2 (the mixed difference is zero), and the
/// cut weights are still exactly zero after training. `Interaction::Full` mixes them.
#[test]
fn additive_interaction_keeps_the_inputs_apart() {
    let rec = seed_2dof(3);
    let (train, _) = rec.split_halves();
    let mixed = |interaction, layers| {
        let mut cfg = quick(config(&train));
        cfg.interaction = interaction;
        cfg.layers = layers;
        cfg.robust.ensemble = Some(1);
        let m = cfg.fit(&train).unwrap();
        let net = &m.outputs[0].network;
        let lags = m.config.lags;
        let width = net.sizes[0];
        assert_eq!(width, lags.output + 2 * lags.input);
        let mut acts = vec![0.0; net.acts_len()];
        let mut f = |x: &[f64]| {
            net.forward(x, &mut acts);
            net.output(&acts)[0]
        };
        let x: Vec<f64> = (0..width).map(|i| 0.3 * ((i as f64) * 1.7).sin()).collect();
        let shift = |x: &[f64], signal: usize, by: f64| {
            let mut x = x.to_vec();
            let from = lags.output + signal * lags.input;
            x[from..from + lags.input].iter_mut().for_each(|v| *v += by);
            x
        };
        let x1 = shift(&x, 0, 0.8);
        let x2 = shift(&x, 1, -0.6);
        let x12 = shift(&x1, 1, -0.6);
        let d = f(&x12) - f(&x1) - f(&x2) + f(&x);
        let h = net.sizes[1];
        let cut = (0..h)
            .flat_map(|j| (0..width).map(move |c| (j, c)))
            .filter(|&(j, c)| c >= lags.output && (c - lags.output) / lags.input != j % 2)
            .map(|(j, c)| net.params[j * width + c])
            .collect::<Vec<f64>>();
        (d, cut)
    };
    let (d, cut) = mixed(Interaction::Additive, 1);
    assert!(d.abs() < 1e-12, "mixed difference {d}");
    assert!(cut.iter().all(|w| *w == 0.0), "{cut:?}");
    // deeper networks stay a sum of one sub-network per input
    let (d, cut) = mixed(Interaction::Additive, 2);
    assert!(d.abs() < 1e-12, "mixed difference, 2 layers: {d}");
    assert!(cut.iter().all(|w| *w == 0.0), "{cut:?}");
    let (d, cut) = mixed(Interaction::Full, 1);
    assert!(d.abs() > 1e-6, "a full network mixes the inputs: {d}");
    assert!(cut.iter().any(|w| *w != 0.0));
    // each input needs its own neurons
    let mut cfg = config(&train);
    cfg.neurons = 1;
    let e = cfg.check().unwrap_err();
    assert!(e.to_string().contains("per input"), "{e}");
}

#[test]
fn default_protocol_beats_the_study_protocol_in_free_run() {
    let rec = seed_1dof(Plant1::BoucWen, 20_000, 3);
    let mut study = config(&rec);
    study.protocol = Protocol::Study;
    study.epochs = 5;
    let s = free_run_test_r2(&study, &rec)[0].unwrap_or(f64::NEG_INFINITY);
    let d = free_run_test_r2(&config(&rec), &rec)[0].expect("no divergence");
    assert!(d > s && d > 0.99, "default {d} vs study {s}");
}

/// Fewer restarts and steps, for tests that do not measure quality.
fn quick(mut c: NarxConfig) -> NarxConfig {
    c.robust.restarts = Some(2);
    c.robust.sim_steps = 200;
    c
}

/// `hystbench identify --data <data> --out <out> <args>`.
fn identify(data: &std::path::Path, out: &std::path::Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_hystbench"))
        .args(["identify", "--data"])
        .arg(data)
        .arg("--out")
        .arg(out)
        .args(args)
        .output()
        .unwrap()
}

fn model_bytes(m: &FittedNarx) -> String {
    let mut m = m.clone();
    m.train_seconds = 0.0;
    m.to_json()
}

#[test]
fn identical_models_at_one_and_two_threads() {
    let rec = seed_1dof(Plant1::BoucWen, 8_000, 2).split_halves().0;
    let mut cfg = config(&rec);
    cfg.robust.restarts = Some(3);
    cfg.epochs = 20;
    let fit = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| model_bytes(&cfg.fit(&rec).unwrap()))
    };
    let one = fit(1);
    let two = fit(2);
    assert!(one == two, "models differ between 1 and 2 threads");
    // and the seed matters
    cfg.seed = 1;
    assert_ne!(one, model_bytes(&cfg.fit(&rec).unwrap()));
}

/// One training path: on one record, `fit_records` is `fit` without its selections (features,
/// decimation; the linear probe runs on short records only), bit for bit; on two outputs, so
/// the joint (output, restart) jobs are exercised too.
#[test]
fn fit_records_on_one_record_is_fit_without_the_selections() {
    let mut rec = seed_1dof(Plant1::BoucWen, 2_400, 3);
    let y2 = Signal {
        name: "y2".into(),
        values: rec.outputs[0].values.iter().map(|v| 0.5 * v * v).collect(),
    };
    rec.outputs.push(y2);
    let mut cfg = quick(network_config(&rec));
    cfg.robust.try_features.clear();
    cfg.robust.try_decimation = false;
    let one = model_bytes(&cfg.fit(&rec).unwrap());
    let records = model_bytes(&cfg.fit_records(std::slice::from_ref(&rec)).unwrap());
    assert!(one == records, "fit and fit_records differ on one record");
}

#[test]
fn model_file_round_trip_and_refusals() {
    let rec = seed_2dof(4);
    let (train, test) = rec.split_halves();
    let m = quick(config(&train)).fit(&train).unwrap();
    let text = m.to_json();
    let p = std::path::Path::new("m.json");
    let back = FittedNarx::from_json(p, &text).unwrap();
    for mode in [Mode::OneStep, Mode::FreeRun] {
        assert_eq!(
            m.predict(&test, mode).unwrap(),
            back.predict(&test, mode).unwrap()
        );
    }
    let v2 = text.replacen("\"version\": 1", "\"version\": 2", 1);
    let e = FittedNarx::from_json(p, &v2).unwrap_err();
    assert!(matches!(e, NarxError::Version { .. }), "{e}");
    assert!(e.to_string().contains("version 2"), "{e}");
    let other = text.replacen("hystbench-narx", "something-else", 1);
    assert!(matches!(
        FittedNarx::from_json(p, &other),
        Err(NarxError::NotAModel { .. })
    ));
    let cut = &text[..text.len() / 2];
    let e = FittedNarx::from_json(p, cut).unwrap_err();
    assert!(matches!(e, NarxError::File(_)), "{e}");
    assert!(e.to_string().starts_with("m.json: line "), "{e}");
    // a weight removed: shape no longer matches
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["model"]["outputs"][0]["network"]["params"]
        .as_array_mut()
        .unwrap()
        .pop();
    let e = FittedNarx::from_json(p, &v.to_string()).unwrap_err();
    assert!(e.to_string().contains("parameters"), "{e}");
    // a key given twice is refused with its line (it would silently win otherwise)
    let twice = text.replacen("\"config\": {", "\"config\": {\n      \"lr\": 0.5,", 1);
    let e = FittedNarx::from_json(p, &twice).unwrap_err().to_string();
    assert!(
        e.contains("duplicate field `lr`") && e.contains("line"),
        "{e}"
    );
    // and so is a field the format does not have
    let extra = text.replacen("\"model\": {", "\"modle\": 1,\n  \"model\": {", 1);
    let e = FittedNarx::from_json(p, &extra).unwrap_err().to_string();
    assert!(e.contains("modle"), "{e}");
}

#[test]
fn a_diverging_free_run_is_reported_with_its_sample_not_scored() {
    let rec = seed_2dof(4);
    let (train, test) = rec.split_halves();
    let mut cfg = quick(network_config(&train));
    cfg.robust.ensemble = Some(1); // one network (ensembles: see the test below)
    let mut m = cfg.fit(&train).unwrap();
    // make output y1 unstable: a huge weight on y(k-1) in the bypass
    let net = &mut m.outputs[0].network;
    let bo = net.bypass_offset();
    net.params[bo] = 50.0;
    let p = m.predict(&test, Mode::FreeRun).unwrap();
    let k = p[0].diverged_at.expect("diverged");
    assert!(k >= m.config.lags.start() && k < test.len());
    assert!(p[0].values.iter().all(|v| v.is_finite()));
    assert_eq!(p[0].scores(&test.outputs[0].values), None);
    let e = m.evaluate(&train, &test).unwrap();
    assert_eq!(e[0].r2_fr_test, None);
    assert_eq!(e[0].diverged_at_test, Some(k));
    assert!(e[1].r2_fr_test.is_some());
}

fn tiny(n: usize, y: impl Fn(usize) -> f64) -> IoRecord {
    IoRecord {
        path: "tiny.csv".into(),
        ts: 1e-3,
        t0: 0.0,
        time_name: "t".into(),
        inputs: vec![Signal {
            name: "u".into(),
            values: (0..n).map(|k| (0.1 * k as f64).sin()).collect(),
        }],
        outputs: vec![Signal {
            name: "y".into(),
            values: (0..n).map(y).collect(),
        }],
    }
}

#[test]
fn bad_input_gives_clear_errors() {
    let short = tiny(5, |k| k as f64);
    let e = config(&short).fit(&short).unwrap_err();
    assert!(
        matches!(
            e,
            NarxError::TooShort {
                rows: 5,
                needed: 6,
                ..
            }
        ),
        "{e}"
    );
    let flat = tiny(100, |_| 2.5);
    let e = config(&flat).fit(&flat).unwrap_err();
    assert!(matches!(e, NarxError::ConstantOutput { .. }), "{e}");
    assert!(e.to_string().contains("R^2 is undefined"), "{e}");
    let ok = tiny(100, |k| (0.1 * k as f64).cos());
    for f in [
        |c: &mut NarxConfig| c.lags.output = 0,
        |c: &mut NarxConfig| c.lags.input = 0,
        |c: &mut NarxConfig| c.neurons = 0,
        |c: &mut NarxConfig| c.lr = f64::NAN,
    ] {
        let mut c = config(&ok);
        f(&mut c);
        assert!(matches!(c.fit(&ok), Err(NarxError::InvalidConfig { .. })));
    }
    let m = config(&ok).fit(&ok).unwrap();
    let mut other = ok.clone();
    other.inputs[0].name = "v".into();
    let e = m.predict(&other, Mode::FreeRun).unwrap_err();
    assert!(matches!(e, NarxError::ColumnMismatch { .. }), "{e}");
    let mut no_y = ok.clone();
    no_y.outputs.clear();
    assert!(matches!(
        m.predict(&no_y, Mode::OneStep),
        Err(NarxError::OutputsNeeded { .. })
    ));
    assert!(m.predict(&no_y, Mode::FreeRun).is_ok());
}

fn write_record(dir: &std::path::Path, name: &str, rec: &IoRecord) -> std::path::PathBuf {
    let (names, cols) = rec.to_columns();
    let p = dir.join(name);
    hystbench::data::write_csv_atomic(&p, &names, &cols, false).unwrap();
    p
}

#[test]
fn cli_identify_predict_and_refusals() {
    let exe = env!("CARGO_BIN_EXE_hystbench");
    let dir = tempfile::tempdir().unwrap();
    let data = write_record(dir.path(), "d.csv", &seed_2dof(1));
    let model = dir.path().join("m.json");
    let out = Command::new(exe)
        .args(["identify", "--data"])
        .arg(&data)
        .arg("--out")
        .arg(&model)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for y in ["y1", "y2"] {
        for k in [
            "r2_osa_train",
            "r2_fr_train",
            "r2_osa_test",
            "r2_fr_test",
            "rmse_fr_test",
        ] {
            assert!(v["outputs"][y][k].is_number(), "{y}.{k} in {v}");
        }
    }
    assert!(v["train_seconds"].is_number());
    // the model file says how the inputs meet: additive by default, full on request
    let text = std::fs::read_to_string(&model).unwrap();
    let file: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(file["model"]["config"]["interaction"], "additive");
    let full = dir.path().join("full.json");
    let out = identify(
        &data,
        &full,
        &[
            "--interaction",
            "full",
            "--restarts",
            "2",
            "--sim-steps",
            "50",
            "--json",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&full).unwrap()).unwrap();
    assert_eq!(file["model"]["config"]["interaction"], "full");
    // one neuron for two inputs cannot be additive: a clear error, nothing written
    let none = dir.path().join("none.json");
    let out = identify(&data, &none, &["--neurons", "1"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("neurons") && err.contains("--interaction full"),
        "{err}"
    );
    assert!(!none.exists());
    // refuses to overwrite
    let again = Command::new(exe)
        .args(["identify", "--data"])
        .arg(&data)
        .arg("--out")
        .arg(&model)
        .output()
        .unwrap();
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    // predict writes t, inputs, outputs and <output>_hat
    let pred = dir.path().join("p.csv");
    let out = Command::new(exe)
        .args(["predict", "--model"])
        .arg(&model)
        .arg("--data")
        .arg(&data)
        .args(["--mode", "free-run", "--out"])
        .arg(&pred)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&pred).unwrap();
    assert_eq!(
        text.lines().next().unwrap(),
        "t,u1,u2,y1,y2,y1_hat,y1_lo,y1_hi,y2_hat,y2_lo,y2_hi"
    );
    assert_eq!(text.lines().count(), 501);
    // unknown column and constant output: clear error, nothing written
    let bad = dir.path().join("bad.json");
    let out = Command::new(exe)
        .args(["identify", "--data"])
        .arg(&data)
        .args(["--inputs", "u1,nope", "--out"])
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("nope"));
    assert!(!bad.exists());
    let flat = write_record(dir.path(), "flat.csv", &tiny(100, |_| 1.0));
    let out = Command::new(exe)
        .args(["identify", "--data"])
        .arg(&flat)
        .arg("--out")
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("constant"));
    assert!(!bad.exists());
    // a model applied to a record with other columns
    let other = write_record(dir.path(), "o.csv", &tiny(100, |k| k as f64));
    let p2 = dir.path().join("p2.csv");
    let out = Command::new(exe)
        .args(["predict", "--model"])
        .arg(&model)
        .arg("--data")
        .arg(&other)
        .arg("--out")
        .arg(&p2)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("u1"));
    assert!(!p2.exists());
}

#[test]
fn cli_sweep_writes_the_schema() {
    let exe = env!("CARGO_BIN_EXE_hystbench");
    let dir = tempfile::tempdir().unwrap();
    let data = write_record(dir.path(), "d.csv", &seed_2dof(1));
    let out_dir = dir.path().join("sw");
    let out = Command::new(exe)
        .args(["sweep", "--data"])
        .arg(&data)
        .args([
            "--lags",
            "2,4",
            "--neurons",
            "4",
            "--lr",
            "0.01",
            "--batch",
            "1,128",
            "--epochs",
            "5",
            "--restarts",
            "2",
            "--sim-steps",
            "100",
            "--out",
        ])
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(out_dir.join("results.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "output,lags,neurons,lr,batch,epochs,seed,r2_osa_train,r2_fr_train,r2_osa_test,r2_fr_test,rmse_fr_test,diverged,train_seconds"
    );
    assert_eq!(lines.count(), 4 * 2);
    let md = std::fs::read_to_string(out_dir.join("report.md")).unwrap();
    assert!(md.contains("### Learning rate 0.01, batch 128"));
}

/// The issue's grid acceptance: at least 90 % of the study's 64 settings reach free-run test
/// R^2 >= 0.99 on the Bouc-Wen piezo record. Long: run with `-- --ignored`.
#[test]
#[ignore]
fn study_grid_on_bouc_wen_piezo() {
    let rec = seed_1dof(Plant1::BoucWen, 50_000, 1);
    let (train, test) = rec.split_halves();
    let mut good = 0;
    let mut total = 0;
    for lr in [0.001, 0.01] {
        for batch in [1, 128] {
            for lags in [2, 3, 4, 5] {
                for neurons in [6, 8, 10, 12] {
                    let mut c = config(&train);
                    c.lags.output = lags;
                    c.lags.input = lags;
                    c.neurons = neurons;
                    c.lr = lr;
                    c.batch = batch;
                    c.seed = total;
                    let m = c.fit(&train).unwrap();
                    let r2 = m.evaluate(&train, &test).unwrap()[0].r2_fr_test;
                    total += 1;
                    if r2.is_some_and(|r| r >= 0.99) {
                        good += 1;
                    }
                }
            }
        }
    }
    assert!(
        good * 10 >= total * 9,
        "{good} of {total} settings reach 0.99"
    );
}

#[test]
fn cli_identify_with_features_and_predict_on_another_record() {
    let exe = env!("CARGO_BIN_EXE_hystbench");
    let dir = tempfile::tempdir().unwrap();
    let a = write_record(
        dir.path(),
        "a.csv",
        &seed_1dof(Plant1::PrandtlIshlinskii, 10_000, 1),
    );
    let b = write_record(
        dir.path(),
        "b.csv",
        &seed_1dof(Plant1::PrandtlIshlinskii, 6_000, 2),
    );
    let model = dir.path().join("m.json");
    // unknown effect: the valid names are listed, nothing written
    let out = identify(&a, &model, &["--features", "hysteresis,friction"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("friction") && err.contains("hysteresis, creep, dynamics, coupling"),
        "{err}"
    );
    assert!(!model.exists());
    // coupling needs two inputs
    let out = identify(&a, &model, &["--features", "coupling"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("two inputs"));
    let out = identify(
        &a,
        &model,
        &["--features", "hysteresis", "--restarts", "1", "--json"],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&model).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let f = v["model"]["config"]["features"].as_array().unwrap();
    assert_eq!(f.len(), 8);
    assert!(f[0]["play"]["threshold"].is_number(), "{}", f[0]);
    // the other record has only t,u,y: the features are recomputed from its u
    let pred = dir.path().join("p.csv");
    let out = Command::new(exe)
        .args(["predict", "--model"])
        .arg(&model)
        .arg("--data")
        .arg(&b)
        .arg("--out")
        .arg(&pred)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let p = std::fs::read_to_string(&pred).unwrap();
    assert_eq!(p.lines().next().unwrap(), "t,u,y,y_hat,y_lo,y_hi");
    let (mut y, mut yh) = (Vec::new(), Vec::new());
    for l in p.lines().skip(1) {
        let c: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        y.push(c[2]);
        yh.push(c[3]);
    }
    let r2 = hystbench::metrics::r2(&y, &yh).unwrap();
    assert!(r2 > 0.999, "free run on the other record: R^2 {r2}");
}

/// The issue's 1-DoF acceptance over record seeds 1-4 x `--seed 0,1` (24 fits, about 1.5 min
/// CPU): `cargo test --release --test narx -- --ignored acceptance_1dof_over_seeds`.
/// Measured with the CLI on the same records: 24 of 24 >= 0.999.
#[test]
#[ignore]
fn acceptance_1dof_over_seeds() {
    let mut failed = Vec::new();
    for plant in Plant1::ALL {
        for rs in 1..=4 {
            let rec = seed_1dof(plant, 50_000, rs);
            for seed in 0..2 {
                let mut cfg = config(&rec);
                cfg.seed = seed;
                let (r2, _) = fit_and_score(&cfg, &rec);
                let r2 = r2[0].unwrap_or(f64::NEG_INFINITY);
                if r2 < 0.999 {
                    failed.push(format!("{} record {rs} seed {seed}: {r2}", plant.name()));
                }
            }
        }
    }
    assert!(
        failed.is_empty(),
        "below the thresholds:\n{}",
        failed.join("\n")
    );
}

/// The issue's 2-DoF acceptance over record seeds 1-8 x `--seed 0..2` (48 outputs, all >= 0.99
/// with the additive network and the median ensemble; docs/narx.md), about 2 minutes:
/// `cargo test --release --test narx -- --ignored acceptance_2dof_over_seeds`.
#[test]
#[ignore]
fn acceptance_2dof_over_seeds() {
    let mut failed = Vec::new();
    for rs in 1..=8 {
        let rec = seed_2dof(rs);
        for seed in 0..3 {
            let mut cfg = config(&rec);
            cfg.seed = seed;
            for (i, r2) in fit_and_score(&cfg, &rec).0.into_iter().enumerate() {
                let r2 = r2.unwrap_or(f64::NEG_INFINITY);
                if r2 < 0.99 {
                    failed.push(format!("2-DoF record {rs} seed {seed} y{}: {r2}", i + 1));
                }
            }
        }
    }
    assert!(
        failed.is_empty(),
        "below the thresholds:\n{}",
        failed.join("\n")
    );
}

#[test]
fn short_records_get_an_ensemble_that_loads_predicts_the_median_and_reports_divergence() {
    let rec = seed_2dof(2);
    let (train, test) = rec.split_halves();
    let mut cfg = quick(network_config(&train));
    cfg.robust.restarts = Some(4);
    let fit = |threads, cfg: &NarxConfig| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| cfg.fit(&train).unwrap())
    };
    let m = fit(2, &cfg);
    assert_eq!(model_bytes(&m), model_bytes(&fit(1, &cfg)));
    for o in &m.outputs {
        // 8 by default, clamped to the 4 restarts (fewer if a training free run diverged)
        let k = 1 + o.ensemble.len();
        assert!((2..=4).contains(&k), "{k} members");
        assert_eq!(o.training.ensemble_restarts.len(), k);
        assert_eq!(o.training.ensemble_restarts[0], o.training.chosen_restart);
    }
    // the file keeps every member
    let back = FittedNarx::from_json(std::path::Path::new("m.json"), &m.to_json()).unwrap();
    assert_eq!(model_bytes(&back), model_bytes(&m));
    // the prediction is the median of the members' free runs
    let median = |v: &mut Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    let p = m.predict(&test, Mode::FreeRun).unwrap();
    let mut runs = Vec::new();
    for net in m.outputs[0].members() {
        let mut single = m.clone();
        single.outputs[0].network = net.clone();
        single.outputs[0].ensemble.clear();
        runs.push(
            single.predict(&test, Mode::FreeRun).unwrap()[0]
                .values
                .clone(),
        );
    }
    assert!(runs.len() >= 2);
    for t in m.config.lags.start()..test.len() {
        let mid = median(&mut runs.iter().map(|r| r[t]).collect());
        assert!((p[0].values[t] - mid).abs() < 1e-9 * (1.0 + mid.abs()));
    }
    assert!(p[0].diverged_members.is_empty());
    // a file written when ensembles were combined by their mean (no `combine`) keeps the mean
    let mut v: serde_json::Value = serde_json::from_str(&m.to_json()).unwrap();
    v["model"]["config"]["robust"]
        .as_object_mut()
        .unwrap()
        .remove("combine");
    let legacy = FittedNarx::from_json(std::path::Path::new("old.json"), &v.to_string()).unwrap();
    let pm = legacy.predict(&test, Mode::FreeRun).unwrap();
    let t = test.len() - 1;
    let mean = runs.iter().map(|r| r[t]).sum::<f64>() / runs.len() as f64;
    assert!((pm[0].values[t] - mean).abs() < 1e-9 * (1.0 + mean.abs()));
    // forced to one network: no ensemble
    let mut one = cfg.clone();
    one.robust.ensemble = Some(1);
    assert!(fit(2, &one).outputs.iter().all(|o| o.ensemble.is_empty()));
    // a diverging member is reported and left out of the median
    let mut bad = m.clone();
    let net = &mut bad.outputs[0].ensemble[0];
    let bo = net.bypass_offset();
    net.params[bo] = 50.0;
    let q = bad.predict(&test, Mode::FreeRun).unwrap();
    assert_eq!(q[0].diverged_members, vec![1]);
    assert_eq!(q[0].diverged_at, None);
    let kept: Vec<&Vec<f64>> = (0..runs.len())
        .filter(|&i| i != 1)
        .map(|i| &runs[i])
        .collect();
    let mid = median(&mut kept.iter().map(|r| r[t]).collect());
    assert!((q[0].values[t] - mid).abs() < 1e-9 * (1.0 + mid.abs()));
    let e = bad.evaluate(&train, &test).unwrap();
    assert_eq!(e[0].diverged_members_test, vec![1]);
    // every member diverging: the output diverged, not scored
    let o = &mut bad.outputs[0];
    for net in o.ensemble.iter_mut().chain([&mut o.network]) {
        let bo = net.bypass_offset();
        net.params[bo] = 50.0;
    }
    let q = bad.predict(&test, Mode::FreeRun).unwrap();
    assert!(q[0].diverged_at.is_some());
    assert_eq!(q[0].scores(&test.outputs[0].values), None);
    // a model file from before ensembles (one network, no `ensemble` fields) still loads
    let mut v: serde_json::Value = serde_json::from_str(&m.to_json()).unwrap();
    for o in v["model"]["outputs"].as_array_mut().unwrap() {
        o.as_object_mut().unwrap().remove("ensemble");
        o["training"]
            .as_object_mut()
            .unwrap()
            .remove("ensemble_restarts");
    }
    let old = FittedNarx::from_json(std::path::Path::new("old.json"), &v.to_string()).unwrap();
    assert!(old.outputs.iter().all(|o| o.ensemble.is_empty()));
    assert!(old.predict(&test, Mode::FreeRun).is_ok());
}

/// The linear candidate: on a linear plant (a lightly damped mode, APRBS input) the default
/// identifier keeps a model whose validation error is no worse than the linear candidate's,
/// and its free-run test R^2 is at least the ARX baseline's (to 1e-4).
#[test]
fn on_a_linear_plant_the_identifier_is_no_worse_than_arx() {
    let plant = r#"{"name": "linear", "inputs": ["u"], "outputs": [{"name": "y",
        "paths": [{"input": "u", "hysteresis": {"linear": {"gain": 0.8}}}],
        "dynamics": {"natural_frequency_hz": 40.0, "damping_ratio": 0.1}}]}"#;
    let scenario = r#"{"name": "aprbs", "sampling_period_s": 0.001, "samples": 4000,
        "seed": 5, "inputs": [{"random_steps": {"amplitude": 10.0, "min_hold_s": 0.01,
        "max_hold_s": 0.1}}]}"#;
    let rec = common::record(plant, scenario, 0.01);
    let (train, test) = rec.split_halves();
    let m = config(&train).fit(&train).unwrap();
    let t = &m.outputs[0].training;
    let linear = t
        .linear_selection_mse
        .expect("a linear candidate was tried");
    assert!(t.selection_mse().is_some_and(|s| s <= linear), "{t:?}");
    let r2 = m.evaluate_split(&train, &test).unwrap()[0]
        .r2_fr_test
        .unwrap();
    let arx = hystbench::narx::arx::fit_arx(&train, m.config.lags).unwrap();
    let run = &arx.free_run(&test)[0];
    let arx_r2 = run.scores(&test.outputs[0].values).unwrap().r2.unwrap();
    assert!(r2 >= arx_r2 - 1e-4, "identifier {r2} < ARX {arx_r2}");
}

/// A slow sine at a fast sampling rate: the protocol offers coarser model samplings, and a
/// model that samples every 4th sample predicts every sample (its phases interleaved), keeps
/// its decimation in the model file, and scores like an undecimated one.
#[test]
fn an_oversampled_record_is_modelled_at_a_coarser_sampling() {
    let plant = r#"{"name": "bw", "inputs": ["u"], "outputs": [{"name": "y",
        "paths": [{"input": "u", "hysteresis": {"bouc_wen": {"d": 0.7, "A": 0.25,
        "B": 0.018, "Gamma": 0.006}}}]}]}"#;
    let scenario = r#"{"name": "slow", "sampling_period_s": 0.001, "samples": 24000,
        "inputs": [{"sum": [{"sine": {"amplitude": 30.0, "frequency_hz": 0.7}},
        {"sine": {"amplitude": 12.0, "frequency_hz": 2.3}}]}]}"#;
    let rec = common::record(plant, scenario, 0.02);
    let (train, test) = rec.split_halves();
    let cfg = network_config(&train);
    let candidates = cfg.decimation_candidates(&train);
    // 16 would leave fewer than 1,000 samples per phase of the 12,000
    assert_eq!(candidates, vec![4]);
    let mut c4 = quick(cfg.clone());
    c4.decimation = 4;
    c4.robust.try_features.clear();
    let m = c4.fit(&train).unwrap();
    assert_eq!(m.config.decimation, 4);
    let p = &m.predict(&test, Mode::FreeRun).unwrap()[0];
    assert_eq!(p.values.len(), test.len());
    assert_eq!(p.start, 4 * m.config.lags.start());
    let r2 = p.scores(&test.outputs[0].values).unwrap().r2.unwrap();
    assert!(r2 > 0.999, "decimated model R^2 {r2}");
    let text = m.to_json();
    assert!(text.contains("\"decimation\": 4"));
    let back = FittedNarx::from_json(std::path::Path::new("m.json"), &text).unwrap();
    assert_eq!(back.predict(&test, Mode::FreeRun).unwrap()[0], *p);
    // a record too short for the decimation is refused clearly
    let e = m.predict(&test.slice(0..10), Mode::FreeRun).unwrap_err();
    assert!(e.to_string().contains("every 4th sample"), "{e}");
    // and a broadband record offers no coarser sampling
    let steps = r#"{"name": "aprbs", "sampling_period_s": 0.001, "samples": 24000, "seed": 3,
        "inputs": [{"random_steps": {"amplitude": 30.0, "min_hold_s": 0.002,
        "max_hold_s": 0.01}}]}"#;
    let (train, _) = common::record(plant, steps, 0.02).split_halves();
    assert!(cfg.decimation_candidates(&train).is_empty());
}

/// Honest extrapolation: a test half that doubles the training amplitude makes `identify` warn
/// (with the share of samples and where) and list it in `--json`; `compare` and `predict` say
/// the same; a test half like the training half raises nothing.
#[test]
fn identify_warns_when_the_test_half_leaves_the_training_region() {
    let t = tempfile::tempdir().unwrap();
    let plant = common::root().join("plants/bouc_wen_piezo.json");
    let scenario = |amp2: f64| {
        format!(
            r#"{{"name": "doubling", "sampling_period_s": 0.0002, "samples": 4000, "noise_std": 0.01,
            "inputs": [{{"concat": [
              {{"duration_s": 0.4, "excitation": {{"sine": {{"amplitude": 20.0, "frequency_hz": 10.0}}}}}},
              {{"duration_s": 0.4, "excitation": {{"sine": {{"amplitude": {amp2}, "frequency_hz": 10.0}}}}}}]}}]}}"#
        )
    };
    for (amp2, warns) in [(40.0, true), (20.0, false)] {
        let sc = common::write(t.path(), &format!("s{amp2}.json"), &scenario(amp2));
        let data = t.path().join(format!("d{amp2}.csv"));
        let o = common::hystbench(&[
            "simulate",
            "--plant",
            common::s(&plant),
            "--scenario",
            common::s(&sc),
            "--out",
            common::s(&data),
        ]);
        assert!(o.status.success(), "{}", common::stderr(&o));
        let model = t.path().join(format!("m{amp2}.json"));
        let o = identify(&data, &model, &["--json"]);
        assert!(o.status.success(), "{}", common::stderr(&o));
        let err = common::stderr(&o);
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let ex = v["extrapolation"].as_array().unwrap();
        if warns {
            assert!(err.contains("beyond the training range"), "{err}");
            let amp = ex
                .iter()
                .find(|e| e["what"].as_str().unwrap().contains("beyond"))
                .unwrap();
            let share = amp["share"].as_f64().unwrap();
            assert!(share > 0.2 && share < 0.9, "{amp}");
            let test_half = t.path().join("second.csv");
            let text = std::fs::read_to_string(&data).unwrap();
            let lines: Vec<&str> = text.lines().collect();
            let second: Vec<&str> = std::iter::once(lines[0])
                .chain(lines[1 + lines.len() / 2..].iter().copied())
                .collect();
            std::fs::write(&test_half, second.join("\n") + "\n").unwrap();
            let o = common::hystbench(&[
                "compare",
                "--model",
                common::s(&model),
                "--data",
                common::s(&test_half),
                "--json",
            ]);
            assert!(common::stderr(&o).contains("beyond the training range"));
        } else {
            assert!(!err.contains("warning"), "{err}");
            assert!(ex.is_empty(), "{ex:?}");
        }
    }
}

/// Prediction bands: calibrated on the training record's validation part, they hold about 95 %
/// of a test half like the training half, never narrower than the validation errors' 95 %
/// quantile; `identify` reports their coverage; they survive the model file; `predict` writes them as
/// `y_lo`, `y_hi` around `y_hat`, and `compare --json` reports their coverage.
#[test]
fn prediction_bands_hold_a_test_half_like_the_training_half() {
    let plant = std::fs::read_to_string(common::root().join("plants/bouc_wen_piezo.json")).unwrap();
    let scenario = r#"{"name": "multisine", "sampling_period_s": 0.0005, "samples": 4000,
        "inputs": [{"multisine": {"amplitude": 30.0, "f_min_hz": 1.0, "f_max_hz": 20.0,
        "period_s": 1.0}}]}"#;
    let rec = common::record(&plant, scenario, 0.05);
    let (train, test) = rec.split_halves();
    let m = network_config(&rec).fit(&train).expect("fit");
    let band = m.outputs[0].band.clone().expect("a band");
    assert!(band.quantile > 0.0 && band.rms > 0.0, "{band:?}");
    let p = &m.predict(&test, Mode::FreeRun).unwrap()[0];
    let h = p.half_width.as_ref().expect("a free run carries its band");
    assert!(h.iter().all(|v| v.is_finite() && *v > 0.0));
    let c =
        hystbench::narx::band::coverage(&test.outputs[0].values, &p.values, h, p.start).unwrap();
    assert!(c >= 0.85, "coverage {c}");
    // never narrower than the validation residuals' 95 % quantile (the floor)
    assert!(band.floor > 0.0, "{band:?}");
    assert!(h.iter().all(|v| *v >= band.floor));
    // the evaluation (`identify`) reports the same coverage, and the width in test std
    let e = &m.evaluate(&train, &test).unwrap()[0];
    assert_eq!(e.band_coverage_test, Some(c));
    let w = e.band_width_test.expect("a width");
    assert!(w > 0.0 && w < 1.0, "{w}");
    // one-step predictions carry none
    assert!(m.predict(&test, Mode::OneStep).unwrap()[0]
        .half_width
        .is_none());
    // the model file keeps it
    let back = FittedNarx::from_json(std::path::Path::new("m.json"), &m.to_json()).unwrap();
    assert_eq!(back.predict(&test, Mode::FreeRun).unwrap()[0], *p);

    let t = tempfile::tempdir().unwrap();
    let data = write_record(t.path(), "test.csv", &test);
    let model = t.path().join("m.json");
    std::fs::write(&model, m.to_json()).unwrap();
    let out = t.path().join("p.csv");
    let o = common::hystbench(&[
        "predict",
        "--model",
        common::s(&model),
        "--data",
        common::s(&data),
        "--out",
        common::s(&out),
    ]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (hat, lo, hi) = (col("y_hat"), col("y_lo"), col("y_hi"));
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        assert!(v[lo] < v[hat] && v[hat] < v[hi], "{line}");
    }
    let o = common::hystbench(&[
        "compare",
        "--model",
        common::s(&model),
        "--data",
        common::s(&data),
        "--json",
    ]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let b = &v["bands"][0];
    assert_eq!(b["output"], "y");
    assert!(b["coverage"].as_f64().unwrap() >= 0.85, "{b}");
}
