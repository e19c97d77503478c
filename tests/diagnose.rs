//! The diagnosis names the missing effect: for each effect E, a record from a plant with E and a
//! model without E (here: the true plant with E removed; the grey-box tests refit instead);
//! with the complete model nothing is missing, at two noise levels.

use hystbench::data::IoRecord;
use hystbench::diagnose::{diagnose, DiagnoseOptions};
use hystbench::effect::EffectName;
use hystbench::plant::{Plant, PlantSpec};
use hystbench::scenario::ScenarioSpec;
use hystbench::simulator::simulate_scenario;
use std::path::Path;

fn plant(json: &str) -> PlantSpec {
    PlantSpec::parse(Path::new("test-plant.json"), json).unwrap()
}

fn record(p: &PlantSpec, scenario: &str, noise: f64) -> IoRecord {
    let mut s = ScenarioSpec::parse(Path::new("test-scenario.json"), scenario).unwrap();
    s.noise_std = hystbench::scenario::NoiseLevel::All(noise);
    let sc = s.check(Path::new("test-scenario.json")).unwrap();
    simulate_scenario(&p.check(Path::new("p.json")).unwrap(), &sc, None)
        .unwrap()
        .record
}

fn predict(p: &PlantSpec, rec: &IoRecord) -> Vec<Vec<f64>> {
    let plant: Plant = p.check(Path::new("model.json")).unwrap();
    let u: Vec<&[f64]> = rec.inputs.iter().map(|s| s.values.as_slice()).collect();
    plant.simulate(&u, rec.ts).unwrap()
}

/// 1 kHz, 40 s: a sine sweep of amplitudes and frequencies, then held steps.
const SCENARIO_1: &str = r#"{"name":"mix","sampling_period_s":0.001,"samples":40000,"seed":4,
 "inputs":[{"concat":[
   {"duration_s":20,"excitation":{"sum":[{"sine":{"amplitude":25,"frequency_hz":0.7}},{"sine":{"amplitude":10,"frequency_hz":3.1,"phase_rad":1}},{"random_steps":{"amplitude":5,"min_hold_s":0.05,"max_hold_s":0.3}}]}},
   {"duration_s":20,"excitation":{"staircase":{"levels":[20,35,5,-20,10],"hold_s":4}}}]}]}"#;

const BW: &str = r#"{"bouc_wen":{"d":0.8,"A":0.3,"B":0.02,"Gamma":0.01}}"#;

fn siso(hyst: &str, creep: bool, dynamics: bool) -> PlantSpec {
    let mut s = format!(
        r#"{{"name":"p","inputs":["u"],"outputs":[{{"name":"y","paths":[{{"input":"u","hysteresis":{hyst}}}]"#
    );
    if creep {
        s += r#","creep":{"time_constants_s":[0.1,1,10],"percent_per_decade":2.0}"#;
    }
    if dynamics {
        s += r#","dynamics":{"natural_frequency_hz":40,"damping_ratio":0.05}"#;
    }
    s += "}]}";
    plant(&s)
}

fn check_case(
    name: &str,
    truth: &PlantSpec,
    model: &PlantSpec,
    model_effects: &[EffectName],
    expect: Option<EffectName>,
    scenario: &str,
) {
    for noise in [0.01, 0.1] {
        let rec = record(truth, scenario, noise);
        let d = diagnose(
            &rec,
            &predict(model, &rec),
            model_effects,
            &DiagnoseOptions::default(),
        );
        let ranking: Vec<_> = d
            .ranking
            .iter()
            .map(|r| format!("{} {:.3}", r.effect, r.explained))
            .collect();
        println!(
            "{name} noise {noise}: missing {:?}, ranking {ranking:?}",
            d.missing
        );
        assert_eq!(
            d.missing, expect,
            "{name} at noise {noise}: ranking {ranking:?}; {:?}",
            d.summary
        );
        if let Some(e) = expect {
            assert_eq!(d.ranking[0].effect, e);
        }
    }
}

const LINEAR: &str = r#"{"linear":{"gain":0.8}}"#;
#[allow(non_upper_case_globals)]
const Hysteresis: EffectName = hystbench::effect::hysteresis::NAME;
#[allow(non_upper_case_globals)]
const Creep: EffectName = hystbench::effect::creep::NAME;
#[allow(non_upper_case_globals)]
const Dynamics: EffectName = hystbench::effect::dynamics::NAME;
#[allow(non_upper_case_globals)]
const Coupling: EffectName = hystbench::effect::coupling::NAME;

#[test]
fn missing_hysteresis_is_named() {
    check_case(
        "hysteresis",
        &siso(BW, true, true),
        &siso(LINEAR, true, true),
        &[Creep, Dynamics],
        Some(Hysteresis),
        SCENARIO_1,
    );
}

#[test]
fn missing_creep_is_named() {
    check_case(
        "creep",
        &siso(BW, true, true),
        &siso(BW, false, true),
        &[Hysteresis, Dynamics],
        Some(Creep),
        SCENARIO_1,
    );
}

#[test]
fn missing_dynamics_is_named() {
    check_case(
        "dynamics",
        &siso(BW, true, true),
        &siso(BW, true, false),
        &[Hysteresis, Creep],
        Some(Dynamics),
        SCENARIO_1,
    );
}

#[test]
fn complete_siso_model_has_nothing_missing() {
    let p = siso(BW, true, true);
    check_case(
        "complete",
        &p,
        &p,
        &[Hysteresis, Creep, Dynamics],
        None,
        SCENARIO_1,
    );
    // a plant without creep and dynamics, with a model that has what the plant has
    let p = siso(BW, false, false);
    check_case("complete-partial", &p, &p, &[Hysteresis], None, SCENARIO_1);
}

const SCENARIO_2: &str = r#"{"name":"mix2","sampling_period_s":0.001,"samples":40000,"seed":5,
 "inputs":[{"sum":[{"sine":{"amplitude":25,"frequency_hz":0.7}},{"random_steps":{"amplitude":10,"min_hold_s":0.1,"max_hold_s":0.5}}]},
           {"sum":[{"sine":{"amplitude":25,"frequency_hz":1.1}},{"random_steps":{"amplitude":10,"min_hold_s":0.1,"max_hold_s":0.5}}]}]}"#;

fn mimo(coupled: bool) -> PlantSpec {
    let cross = |u: &str| {
        format!(
            r#",{{"input":"{u}","hysteresis":{{"bouc_wen":{{"d":0.12,"A":0.06,"B":0.03,"Gamma":0.01}}}}}}"#
        )
    };
    plant(&format!(
        r#"{{"name":"m","inputs":["u1","u2"],"outputs":[
        {{"name":"y1","paths":[{{"input":"u1","hysteresis":{BW}}}{}],"dynamics":{{"natural_frequency_hz":40,"damping_ratio":0.05}}}},
        {{"name":"y2","paths":[{{"input":"u2","hysteresis":{BW}}}{}],"dynamics":{{"natural_frequency_hz":60,"damping_ratio":0.05}}}}]}}"#,
        if coupled { cross("u2") } else { String::new() },
        if coupled { cross("u1") } else { String::new() },
    ))
}

#[test]
fn missing_coupling_is_named_and_complete_mimo_is_clean() {
    check_case(
        "coupling",
        &mimo(true),
        &mimo(false),
        &[Hysteresis, Dynamics],
        Some(Coupling),
        SCENARIO_2,
    );
    check_case(
        "complete-mimo",
        &mimo(true),
        &mimo(true),
        &[Hysteresis, Dynamics, Coupling],
        None,
        SCENARIO_2,
    );
}

#[test]
fn the_missing_effect_ranks_above_other_absent_ones() {
    // the model lacks both creep and dynamics, the plant has only one of them
    check_case(
        "creep-only",
        &siso(BW, true, false),
        &siso(BW, false, false),
        &[Hysteresis],
        Some(Creep),
        SCENARIO_1,
    );
    check_case(
        "dynamics-only",
        &siso(BW, false, true),
        &siso(BW, false, false),
        &[Hysteresis],
        Some(Dynamics),
        SCENARIO_1,
    );
    check_case(
        "hysteresis-only",
        &siso(BW, false, false),
        &siso(LINEAR, false, false),
        &[],
        Some(Hysteresis),
        SCENARIO_1,
    );
}

/// 3 kHz, 1.6 s: a chirp from 2.5 to 6 Hz (one drive frequency at a time).
const CHIRP: &str = r#"{"name":"chirp","sampling_period_s":0.00033,"samples":4800,"seed":6,
 "inputs":[{"chirp":{"amplitude":75,"f0_hz":2.5,"f1_hz":6,"offset":30}}]}"#;

/// A well-damped 25 Hz mode under a chirp far below it acts as a small lag, which a refitted
/// hysteresis loop absorbs: the basis banks see little of it in the residual of a model
/// fitted without it, yet refitting with it cuts the error many times. The refit test (fit on
/// the record without its middle 30 %, both models run free through it, sign-flip test over
/// blocks) names it;
/// with the complete model refitted, nothing is named, at two noise levels.
#[test]
fn the_refit_test_names_a_lag_that_a_refitted_loop_hides() {
    use hystbench::diagnose::diagnose_model;
    use hystbench::graybox::GreyBoxConfig;
    use hystbench::model::predict_finite;
    let truth = plant(
        r#"{"name":"p","inputs":["u"],"outputs":[{"name":"y","paths":[{"input":"u","hysteresis":{"prandtl_ishlinskii":{"linear_weight":0.15,"thresholds":[14,28,41,55,68],"weights":[0.08,0.056,0.037,0.025,0.017]}}}],
          "dynamics":{"natural_frequency_hz":25,"damping_ratio":0.41}}]}"#,
    );
    for noise in [0.02, 0.2] {
        let rec = record(&truth, CHIRP, noise);
        let run = |list: &str| {
            let config = GreyBoxConfig::from_effect_list(list).unwrap();
            let m = config.fit(&rec).unwrap();
            let pred = predict_finite(&m, &rec).unwrap();
            diagnose_model(&rec, &pred, &config, &DiagnoseOptions::default())
        };
        let d = run("hysteresis");
        let check = d.refit.as_ref().expect("the refit test runs");
        println!("noise {noise}: {:?}", d.summary);
        assert_eq!(d.missing, Some(Dynamics), "noise {noise}: {:?}", d.summary);
        let dynamics = check.effects.iter().find(|e| e.effect == Dynamics).unwrap();
        // the fall is 3x or more, or as far as the noise lets it go
        let r = &dynamics.outputs[0];
        assert!(
            dynamics.fall >= 3.0 || r.rms_with <= 1.1 * noise,
            "{dynamics:?}"
        );
        assert!(dynamics.outputs[0].p_value <= check.level, "{dynamics:?}");
        let d = run("hysteresis,dynamics");
        assert_eq!(d.missing, None, "complete, noise {noise}: {:?}", d.summary);
    }
}

/// An asymmetric loop from an operator outside the library: the shipped Prandtl-Ishlinskii
/// plant's output passed through a polynomial y = m (z + 0.35 z^2 - 0.15 z^3), z = y_PI / m
/// (m its largest magnitude), 0.2 % noise. From a model with dynamics alone the refit test
/// names hysteresis, and the refit with it (the dead-zone stage of `fit` takes the
/// polynomial's bend) cuts the error 10x or more.
#[test]
fn an_asymmetric_loop_is_named_hysteresis_and_its_refit_cuts_the_error_tenfold() {
    use hystbench::data::Signal;
    use hystbench::diagnose::diagnose_model;
    use hystbench::graybox::GreyBoxConfig;
    use hystbench::model::predict_finite;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let spec = PlantSpec::read(&root.join("plants/prandtl_ishlinskii_piezo.json")).unwrap();
    let mut scen = ScenarioSpec::read(&root.join("scenarios/seed_1dof.json")).unwrap();
    scen.noise_std = hystbench::scenario::NoiseLevel::All(0.0);
    let sc = scen.check(Path::new("seed_1dof.json")).unwrap();
    let mut rec = simulate_scenario(&spec.check(Path::new("p.json")).unwrap(), &sc, None)
        .unwrap()
        .record;
    let y = &rec.outputs[0].values;
    let m = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let bent: Vec<f64> = y
        .iter()
        .map(|v| {
            let z = v / m;
            m * (z + 0.35 * z * z - 0.15 * z * z * z)
        })
        .collect();
    let range = bent.iter().cloned().fold(f64::MIN, f64::max)
        - bent.iter().cloned().fold(f64::MAX, f64::min);
    let mut g = hystbench::effect::noise::Gaussian::new(11, 0);
    let noisy: Vec<f64> = bent
        .iter()
        .map(|v| v + 0.002 * range * g.standard_normal())
        .collect();
    rec.outputs = vec![Signal {
        name: "y".into(),
        values: noisy,
    }];
    let fit = |list: &str| {
        let config = GreyBoxConfig::from_effect_list(list).unwrap();
        let model = config.fit(&rec).unwrap();
        (config, model)
    };
    let (config, start) = fit("dynamics");
    let pred = predict_finite(&start, &rec).unwrap();
    let d = diagnose_model(&rec, &pred, &config, &DiagnoseOptions::default());
    assert_eq!(d.missing, Some(Hysteresis), "{:?}", d.summary);
    let (_, refit) = fit("hysteresis,dynamics");
    let fall = start.fit.rmse / refit.fit.rmse;
    println!(
        "RMS error {:.4} -> {:.4} ({fall:.1}x), noise {:.4}",
        start.fit.rmse,
        refit.fit.rmse,
        0.002 * range
    );
    assert!(fall >= 10.0, "{fall}");
}

/// A complete model of a 500-sample 2-DoF record (development zoo seed 7, member 23: Bouc-Wen,
/// Prandtl-Ishlinskii and linear paths, creep and a mode on y1, a mode on y2, two-way coupling;
/// a multisine and a sine) is called complete. Its refit without the record's middle
/// extrapolates badly there (held-out RMS far above the model's own), and an extra effect cuts
/// that refit's error with a small p-value: the refit test named it until a named effect also
/// had to beat the model at hand on the held-out part. (Member 111, the case until the zoo drew
/// paths of negative gain and the paths' signs came from an ARX, no longer shows it.)
#[test]
fn a_refit_that_only_repairs_a_poor_extrapolation_names_nothing() {
    use hystbench::diagnose::diagnose_model;
    use hystbench::graybox::GreyBoxConfig;
    use hystbench::scenario::NoiseLevel;
    let mut m = hystbench::zoo::member(7, 23);
    let plant = m.plant.check(Path::new("p.json")).unwrap();
    let run = |s: &ScenarioSpec| {
        let sc = s.check(Path::new("s.json")).unwrap();
        simulate_scenario(&plant, &sc, None).unwrap().record
    };
    let clean = run(&m.scenario);
    let noise = clean
        .outputs
        .iter()
        .zip(&m.noise_share)
        .map(|(o, share)| share * hystbench::metrics::ptp(&o.values))
        .collect();
    m.scenario.noise_std = NoiseLevel::PerOutput(noise);
    let io = run(&m.scenario);
    assert_eq!((io.len(), io.outputs.len()), (500, 2));
    let config = GreyBoxConfig::from_effect_list("hysteresis,creep,dynamics,coupling").unwrap();
    let model = config.fit(&io).unwrap();
    let pred = hystbench::model::predict_finite(&model, &io).unwrap();
    let d = diagnose_model(&io, &pred, &config, &DiagnoseOptions::default());
    let check = d.refit.as_ref().expect("the refit test ran");
    assert_eq!(d.missing, None, "{:#?}", check.effects);
    // the case the condition is for: an effect that passes the held-out test alone
    let guarded = check.effects.iter().flat_map(|e| &e.outputs).any(|r| {
        r.fall >= check.min_fall
            && r.p_value <= check.level
            && r.rms_with * check.min_fall > r.rms_model
    });
    assert!(guarded, "{:#?}", check.effects);
}
