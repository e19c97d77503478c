//! `benchmark mr-damper`: the protocol on a short piece of the data (tests/data/mr-damper-mini),
//! bad input (missing file, other columns, mixed sampling periods), NARX training on several
//! records, and the viscous effect: named by the diagnosis and recovered by the grey-box fit on
//! a simulated record.

use hystbench::benchmark::mr_damper::{self, MrDamperError, Structure};
use hystbench::data::IoRecord;
use hystbench::diagnose::{diagnose, DiagnoseOptions};
use hystbench::effect::hysteresis::HysteresisSpec;
use hystbench::graybox::GreyBoxConfig;
use hystbench::narx::{Interaction, Lags, Mode, NarxConfig};
use hystbench::plant::EffectSpecs;
use hystbench::plant::{Plant, PlantSpec};
use hystbench::scenario::ScenarioSpec;
use hystbench::simulator::simulate_scenario;
use std::path::{Path, PathBuf};

fn mini() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mr-damper-mini")
}

/// A copy of the mini folder in a temporary folder, to break.
fn copy_mini() -> tempfile::TempDir {
    let d = tempfile::tempdir().unwrap();
    for e in std::fs::read_dir(mini()).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), d.path().join(e.file_name())).unwrap();
    }
    d
}

#[test]
fn protocol_on_a_piece_of_the_data() {
    let data = mr_damper::load(&mini()).unwrap();
    assert_eq!(data.train.len(), 10);
    assert!(data.train.iter().all(|r| r.ts == 0.001));
    assert_eq!(data.test.forces.len(), 5);
    assert_eq!(data.test.x.len(), 1500);
    // currents read from the files, groups from the names
    let cur: Vec<f64> = data.train.iter().map(|r| r.current).collect();
    assert_eq!(cur[..5], [0.0, 0.25, 0.5, 0.75, 1.0]);
    assert_eq!(cur[5..], cur[..5]);
    assert_eq!(data.train[0].group, "sine_A10mm_f1Hz");
    assert!(data.other.is_empty());
    let (variants, headline) = mr_damper::run_greybox(&data).unwrap();
    assert_eq!(variants.len(), 6);
    assert!(variants[headline].scheduled);
    for v in &variants {
        assert_eq!(v.scores.len(), 5);
        for (s, p) in v.scores.iter().zip(&v.predictions) {
            assert_eq!(p.len(), 1500);
            // the score is the one of the prediction against the measured column
            let k = mr_damper::TEST_CURRENTS
                .iter()
                .position(|c| *c == s.current)
                .unwrap();
            let f = &data.test.forces[k].1;
            let rms = (p.iter().zip(f).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / f.len() as f64)
                .sqrt();
            assert!((s.rms_n.unwrap() - rms).abs() < 1e-9 * rms.max(1.0));
        }
    }
    // the scheduled Bouc-Wen fit explains the training records far better than their spread
    let bw = &variants[0];
    assert_eq!((bw.structure, bw.scheduled), (Structure::BoucWen, true));
    let spread = hystbench::metrics::std_dev(&data.train[9].f);
    assert!(bw.fit.as_ref().unwrap().train_rms_n < 0.3 * spread);
    // per-current models interpolate between the training currents
    let pc = variants[1].per_current.as_ref().unwrap();
    let (a, b, m) = (pc.at(0.25), pc.at(0.5), pc.at(0.375));
    assert!((m.c0 - 0.5 * (a.c0 + b.c0)).abs() < 1e-9 * a.c0.abs().max(1.0));
}

#[test]
fn missing_file_is_named() {
    let d = copy_mini();
    std::fs::remove_file(d.path().join("sine_A05mm_f3Hz_I0.75A.csv")).unwrap();
    let e = mr_damper::load(d.path()).unwrap_err();
    assert!(matches!(e, MrDamperError::MissingFile { .. }), "{e}");
    assert!(e.to_string().contains("sine_A05mm_f3Hz_I0.75A.csv"), "{e}");
    let e = mr_damper::load(Path::new("/no/such/folder")).unwrap_err();
    assert!(e.to_string().contains("--data-dir"), "{e}");
}

#[test]
fn other_columns_are_refused() {
    let d = copy_mini();
    let p = d.path().join("earthquake_validation.csv");
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replacen("F_I0.4A_N", "F_I0.5A_N", 1);
    std::fs::write(&p, text).unwrap();
    let e = mr_damper::load(d.path()).unwrap_err().to_string();
    assert!(
        e.contains("earthquake_validation.csv")
            && e.contains("F_I0.5A_N")
            && e.contains("F_I0.4A_N"),
        "{e}"
    );
    let p = d.path().join("sine_A10mm_f1Hz_I0.50A.csv");
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replacen("x_mm", "x_m", 1);
    std::fs::write(&p, text).unwrap();
    let e = mr_damper::read_sine(&p).unwrap_err().to_string();
    assert!(
        e.contains("x_m,") && e.contains("t_s,x_mm,v_mm_s,F_N,I_A"),
        "{e}"
    );
}

/// A 5 ms sine record in the folder trains the grey-box models (at its own sampling period)
/// but not the NARX; Spencer's full model runs on it from rest like the others.
#[test]
fn other_sampling_periods_train_the_grey_box() {
    let d = copy_mini();
    let five = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mr-damper-5ms-piece.csv");
    std::fs::copy(&five, d.path().join("sine_A25mm_f0.5Hz_I0.50A.csv")).unwrap();
    let data = mr_damper::load(d.path()).unwrap();
    assert_eq!((data.train.len(), data.other.len()), (10, 1));
    assert_eq!((data.other[0].ts, data.other[0].current), (0.005, 0.5));
    assert_eq!(data.other[0].group, "sine_A25mm_f0.5Hz");
    let refs: Vec<&mr_damper::DamperRecord> = data.train.iter().chain(&data.other).collect();
    let fit = mr_damper::fit_structure(&refs, Structure::Spencer, true).unwrap();
    let p = fit.at(0.5).simulate(&data.other[0].x, 0.005);
    let rms = hystbench::metrics::rmse(&data.other[0].f, &p);
    let spread = hystbench::metrics::std_dev(&data.other[0].f);
    assert!(rms < 0.5 * spread, "{rms} vs {spread}");
}

#[test]
fn mixed_sampling_periods_are_refused() {
    let m = mini();
    let five = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mr-damper-5ms-piece.csv");
    let train = vec![m.join("sine_A10mm_f1Hz_I0.50A.csv"), five];
    let e = mr_damper::load_files(&train, &m.join("earthquake_validation.csv")).unwrap_err();
    let s = e.to_string();
    assert!(matches!(e, MrDamperError::SamplingPeriods { .. }), "{s}");
    assert!(
        s.contains("mr-damper-5ms-piece.csv")
            && s.contains("0.005")
            && s.contains("sine_A10mm_f1Hz_I0.50A.csv")
            && s.contains("0.001"),
        "{s}"
    );
}

/// Two records of a first-order system at two operating points (a constant second input):
/// `fit_records` learns both, and a record of another length and period is refused.
#[test]
fn narx_trains_on_several_records() {
    let make = |level: f64, n: usize, seed: u64| -> IoRecord {
        let mut u = Vec::with_capacity(n);
        let mut s = seed;
        let mut v = 0.0;
        for k in 0..n {
            if k % 25 == 0 {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                v = ((s >> 33) as f64 / (1u64 << 31) as f64) * 2.0 - 1.0;
            }
            u.push(v);
        }
        let mut y = vec![0.0; n];
        for k in 1..n {
            y[k] = 0.9 * y[k - 1] + 0.1 * (1.0 + level) * u[k - 1];
        }
        IoRecord {
            path: PathBuf::from(format!("rec{level}")),
            ts: 0.01,
            t0: 0.0,
            time_name: "t".into(),
            inputs: vec![
                hystbench::data::Signal {
                    name: "u".into(),
                    values: u,
                },
                hystbench::data::Signal {
                    name: "I".into(),
                    values: vec![level; n],
                },
            ],
            outputs: vec![hystbench::data::Signal {
                name: "y".into(),
                values: y,
            }],
        }
    };
    let mut c = NarxConfig::new(vec!["u".into(), "I".into()], vec!["y".into()]);
    c.lags = Lags {
        output: 2,
        input: 2,
        delay: 1,
    };
    c.neurons = 6;
    // the level scales the gain (u and the level multiply): not additive
    c.interaction = Interaction::Full;
    c.robust.restarts = Some(1);
    c.robust.sim_steps = 60;
    let recs = vec![make(0.0, 1500, 1), make(1.0, 1500, 2)];
    let m = c.fit_records(&recs).unwrap();
    for (k, level) in [0.0, 1.0].into_iter().enumerate() {
        let test = make(level, 1000, 7 + k as u64);
        let p = m.predict(&test, Mode::FreeRun).unwrap();
        let s = p[0].scores(&test.outputs[0].values).unwrap();
        assert!(s.r2.unwrap() > 0.98, "level {level}: {s:?}");
    }
    let mut other = make(0.5, 1500, 3);
    other.ts = 0.02;
    let e = c
        .fit_records(&[recs[0].clone(), other])
        .unwrap_err()
        .to_string();
    assert!(e.contains("sampling period"), "{e}");
}

/// A simulated damper-like record: Bouc-Wen plus a viscous term on a two-frequency motion.
fn viscous_plant(coefficient: Option<f64>) -> Plant {
    let visc = coefficient
        .map(|c| format!(r#","viscous":{{"coefficient":{c}}}"#))
        .unwrap_or_default();
    let json = format!(
        r#"{{"name":"damper","inputs":["u"],"outputs":[{{"name":"y","paths":[{{"input":"u","hysteresis":{{"bouc_wen":{{"d":0.8,"A":0.3,"B":0.02,"Gamma":0.01}}}}{visc}}}]}}]}}"#
    );
    PlantSpec::parse(Path::new("damper.json"), &json)
        .unwrap()
        .check(Path::new("damper.json"))
        .unwrap()
}

const SINES: &str = r#"{"name":"two sines","sampling_period_s":0.001,"samples":12000,"seed":4,
 "inputs":[{"sum":[{"sine":{"amplitude":25,"frequency_hz":0.7}},{"sine":{"amplitude":10,"frequency_hz":3.1,"phase_rad":1}}]}]}"#;

fn viscous_record(noise: f64) -> IoRecord {
    let mut s = ScenarioSpec::parse(Path::new("s.json"), SINES).unwrap();
    s.noise_std = hystbench::scenario::NoiseLevel::All(noise);
    let sc = s.check(Path::new("s.json")).unwrap();
    simulate_scenario(&viscous_plant(Some(0.02)), &sc, None)
        .unwrap()
        .record
}

#[test]
fn missing_viscous_is_named() {
    for noise in [0.01, 0.1] {
        let rec = viscous_record(noise);
        let u: Vec<&[f64]> = rec.inputs.iter().map(|s| s.values.as_slice()).collect();
        let without = viscous_plant(None).simulate(&u, rec.ts).unwrap();
        let d = diagnose(
            &rec,
            &without,
            &[hystbench::effect::hysteresis::NAME],
            &DiagnoseOptions::default(),
        );
        assert_eq!(
            d.missing,
            Some(hystbench::effect::viscous::NAME),
            "noise {noise}: {:?}",
            d.ranking
        );
        let with = viscous_plant(Some(0.02)).simulate(&u, rec.ts).unwrap();
        let d = diagnose(
            &rec,
            &with,
            &[
                hystbench::effect::hysteresis::NAME,
                hystbench::effect::viscous::NAME,
            ],
            &DiagnoseOptions::default(),
        );
        assert_eq!(d.missing, None, "noise {noise}: {:?}", d.ranking);
    }
}

#[test]
fn viscous_coefficient_is_recovered() {
    let rec = viscous_record(0.0);
    let m = GreyBoxConfig::from_effect_list("bouc-wen,viscous")
        .unwrap()
        .fit(&rec)
        .unwrap();
    let r2 = m.fit.r2.unwrap();
    assert!(r2 > 0.99999, "r2 {r2}");
    let path = &m.plant.spec.outputs[0].paths[0];
    let c = path
        .get::<hystbench::effect::viscous::ViscousSpec>()
        .unwrap()
        .coefficient;
    assert!((c - 0.02).abs() < 2e-4, "coefficient {c}");
    assert!(matches!(
        path.get::<HysteresisSpec>().unwrap(),
        HysteresisSpec::BoucWen(_)
    ));
    // without the effect the fit is clearly worse
    let m0 = GreyBoxConfig::from_effect_list("bouc-wen")
        .unwrap()
        .fit(&rec)
        .unwrap();
    assert!(
        m0.fit.rmse > 20.0 * m.fit.rmse,
        "{} vs {}",
        m0.fit.rmse,
        m.fit.rmse
    );
}

/// A simulated MR damper: Spencer et al.'s full model (the library's `spencer` effect) beside
/// a spring k1 = 0.8 N/mm, offset 3 N, in N, mm and s.
fn spencer_plant() -> Plant {
    let json = r#"{"name":"damper","inputs":["x"],"outputs":[{"name":"F","offset":3.0,"paths":[{"input":"x","hysteresis":{"linear":{"gain":0.8}},"spencer":{"c0":6.0,"c1":100.0,"k0":1.0,"alpha":1900.0,"b":1.5,"gamma":-0.5}}]}]}"#;
    PlantSpec::parse(Path::new("damper.json"), json)
        .unwrap()
        .check(Path::new("damper.json"))
        .unwrap()
}

/// Two sines of the damper's stroke (5 and 2 mm at 0.7 and 3.1 Hz), 12 s at 1 kHz.
const DAMPER_SINES: &str = r#"{"name":"two sines","sampling_period_s":0.001,"samples":12000,"seed":4,
 "inputs":[{"sum":[{"sine":{"amplitude":5,"frequency_hz":0.7}},{"sine":{"amplitude":2,"frequency_hz":3.1,"phase_rad":1}}]}]}"#;

fn spencer_record(scenario: &str, noise: f64) -> IoRecord {
    let mut s = ScenarioSpec::parse(Path::new("s.json"), scenario).unwrap();
    s.noise_std = hystbench::scenario::NoiseLevel::All(noise);
    let sc = s.check(Path::new("s.json")).unwrap();
    let mut rec = simulate_scenario(&spencer_plant(), &sc, None)
        .unwrap()
        .record;
    rec.inputs[0].name = "x".into();
    rec
}

/// The library's Spencer effect is fitted by `fit --effects spencer` from two sines with noise
/// (2 N on about 1,300 N RMS), recovers its parameters, and predicts another motion (slow and
/// fast sines of other amplitudes) where the simple model (a Bouc-Wen term beside a dashpot)
/// fitted on the same record does far worse.
#[test]
fn spencer_damper_is_recovered_and_predicts_another_motion() {
    let train = spencer_record(DAMPER_SINES, 2.0);
    let test = spencer_record(
        r#"{"name":"other sines","sampling_period_s":0.001,"samples":12000,"seed":5,
 "inputs":[{"sum":[{"sine":{"amplitude":8,"frequency_hz":0.3}},{"sine":{"amplitude":1,"frequency_hz":2.3}},{"sine":{"amplitude":0.4,"frequency_hz":6.1,"phase_rad":2}}]}]}"#,
        0.0,
    );
    let m = GreyBoxConfig::from_effect_list("spencer")
        .unwrap()
        .fit(&train)
        .unwrap();
    // the noise: the fit leaves nothing else
    assert!(m.fit.rmse < 2.05, "rmse {}", m.fit.rmse);
    let path = &m.plant.spec.outputs[0].paths[0];
    let s = path
        .get::<hystbench::effect::spencer::SpencerSpec>()
        .unwrap();
    for (name, got, want) in [
        ("c0", s.c0, 6.0),
        ("c1", s.c1, 100.0),
        ("alpha", s.alpha, 1900.0),
        ("b", s.b, 1.5),
        ("gamma", s.gamma, -0.5),
    ] {
        assert!(
            (got - want).abs() < 0.01 * want.abs(),
            "{name}: {got} vs {want}"
        );
    }
    let u: Vec<&[f64]> = test.inputs.iter().map(|s| s.values.as_slice()).collect();
    let y = &test.outputs[0].values;
    let r2 = |plant: &Plant| {
        hystbench::metrics::r2(y, &plant.simulate(&u, test.ts).unwrap()[0]).unwrap()
    };
    let full = r2(&m.plant);
    assert!(full > 0.9999, "full model R^2 {full}");
    let simple = GreyBoxConfig::from_effect_list("bouc-wen,viscous")
        .unwrap()
        .fit(&train)
        .unwrap();
    let simple = r2(&simple.plant);
    assert!(simple < 0.99, "simple model R^2 {simple}");
}

/// The loop on a simulated damper: from the simple model (a Bouc-Wen term beside a dashpot,
/// what `hysteresis` + `viscous` give), the diagnosis names `spencer` and `improve` adds it; the
/// error falls from far above the noise (2 N) to the noise.
#[test]
fn the_loop_adds_spencer_to_the_simple_damper_model() {
    use hystbench::improve::{improve, ImproveOptions};
    let rec = spencer_record(DAMPER_SINES, 2.0);
    let start_config = GreyBoxConfig::from_effect_list("bouc-wen,viscous").unwrap();
    let start = start_config.fit(&rec).unwrap();
    let ladder = improve(
        Box::new(start),
        start_config,
        &rec,
        &ImproveOptions::default(),
        &mut |_| {},
    )
    .unwrap();
    let first = &ladder.rungs[0];
    assert_eq!(
        first.missing,
        Some(hystbench::effect::spencer::NAME),
        "{:?}",
        first.tried
    );
    let last = ladder.rungs.last().unwrap();
    assert!(last.effects.contains(&hystbench::effect::spencer::NAME));
    assert!(
        first.rmse > 20.0 * last.rmse,
        "{} -> {}",
        first.rmse,
        last.rmse
    );
    assert!(last.rmse < 2.1, "{}", last.rmse);
}
