//! The effect matrix: every effect of the registry, by the same harness (so that an effect added
//! later is tested the same way without a line here): a plant with the effect (its `example`
//! spec on a Bouc-Wen path, or, for a structure effect, its paths) is simulated, and
//! - the effect changes the output (well above the noise);
//! - the diagnosis of the same plant without it names it;
//! - the grey-box fit with the plant's effects recovers the record to near the noise, and the
//!   fitted model has the effect;
//! - its NARX features are defined on the record, recomputed identically from the model file,
//!   and a NARX model with them identifies the record (an effect of time or of the sensor, which
//!   is not a function of the input, says why it has none).

use hystbench::data::IoRecord;
use hystbench::diagnose::{diagnose, DiagnoseOptions};
use hystbench::effect::{effects, hysteresis, Effect, EffectName, Slot};
use hystbench::graybox::GreyBoxConfig;
use hystbench::model::{plant_effects, Model};
use hystbench::narx::{FittedNarx, Mode, NarxConfig};
use hystbench::plant::{OutputSpec, PathSpec, Plant, PlantSpec, Units};
use hystbench::scenario::ScenarioSpec;
use hystbench::simulator::simulate_scenario;
use std::path::Path;

const NOISE: f64 = 0.01;

/// 30 s at 1 kHz, two alike halves: two sines and random steps, then a staircase with 2 s holds
/// (creep shows in the holds, dynamics in the steps, hysteresis in the nested loops, a dashpot
/// in the rates).
fn scenario(inputs: usize) -> String {
    let one = |j: usize| {
        let f1 = 0.9 + j as f64 / 10.0;
        let part = |levels: &str| {
            format!(
                r#"{{"duration_s":9,"excitation":{{"sum":[{{"sine":{{"amplitude":22,"frequency_hz":{f1},"phase_rad":{j}}}}},{{"sine":{{"amplitude":8,"frequency_hz":4.3}}}},{{"random_steps":{{"amplitude":6,"min_hold_s":0.05,"max_hold_s":0.4}}}}]}}}},
   {{"duration_s":6,"excitation":{{"staircase":{{"levels":[{levels}],"hold_s":2}}}}}}"#
            )
        };
        format!(
            r#"{{"concat":[{},{}]}}"#,
            part("25,-10,30"),
            part("-20,15,5")
        )
    };
    let list: Vec<String> = (0..inputs).map(one).collect();
    format!(
        r#"{{"name":"matrix","sampling_period_s":0.001,"samples":30000,"seed":5,"noise_std":{NOISE},"inputs":[{}]}}"#,
        list.join(",")
    )
}

/// A plant of `n` inputs and outputs: per output, Bouc-Wen paths from `paths(o)`, the effect's
/// example spec where it sits (when `with`), else the required effects' linear path.
fn plant(effect: &dyn Effect, with: bool) -> PlantSpec {
    let structure = effect.slot() == Slot::None;
    let n = if structure { 2 } else { 1 };
    let names: Vec<String> = (1..=n).map(|j| format!("u{j}")).collect();
    let outputs = (0..n)
        .map(|o| {
            let inputs = match effect.path_inputs(n, o) {
                Some(p) if with && structure => p,
                _ => vec![o],
            };
            let paths = inputs
                .iter()
                .map(|&j| {
                    let h = if effect.name() == hysteresis::NAME && !with {
                        hysteresis::HysteresisEffect.path_without(0.7).unwrap()
                    } else {
                        hysteresis::HysteresisEffect.example().unwrap()
                    };
                    let mut specs = vec![h];
                    if with && effect.slot() == Slot::PathTerm && effect.name() != hysteresis::NAME
                    {
                        specs.push(effect.example().unwrap());
                    }
                    let mut p = PathSpec::new(names[j].clone(), specs);
                    if j != o {
                        // a cross path is weaker than the direct one
                        p.effects[0] = hysteresis::HysteresisEffect.path_without(0.15).unwrap();
                    }
                    p
                })
                .collect();
            let effects = match effect.slot() {
                Slot::Filter | Slot::OutputFilter | Slot::OutputTerm | Slot::Sensor if with => {
                    vec![effect.example().unwrap()]
                }
                _ => Vec::new(),
            };
            OutputSpec {
                name: format!("y{}", o + 1),
                paths,
                offset: 0.0,
                effects,
            }
        })
        .collect();
    PlantSpec {
        name: format!("matrix_{}", effect.name()),
        description: String::new(),
        units: Units::default(),
        default_scenario: None,
        inputs: names,
        outputs,
        ode: None,
    }
}

fn checked(spec: &PlantSpec) -> Plant {
    spec.check(Path::new("matrix.json")).unwrap()
}

fn record(plant: &Plant) -> IoRecord {
    let p = Path::new("matrix.json");
    let s = ScenarioSpec::parse(p, &scenario(plant.inputs.len()))
        .unwrap()
        .check(p)
        .unwrap();
    simulate_scenario(plant, &s, None).unwrap().record
}

fn rms_diff(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    let v: Vec<f64> = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| p - q))
        .collect();
    hystbench::metrics::rms(&v)
}

fn effect_list(e: &[EffectName]) -> String {
    e.iter().map(|x| x.as_str()).collect::<Vec<_>>().join(",")
}

fn check(effect: &dyn Effect) {
    let name = effect.name();
    let with = checked(&plant(effect, true));
    let without = checked(&plant(effect, false));
    assert!(
        plant_effects(&with).contains(&name),
        "{name}: {:?}",
        plant_effects(&with)
    );
    assert!(!plant_effects(&without).contains(&name), "{name}");
    let rec = record(&with);

    // simulated: the effect changes the output
    let (y_with, y_without) = (with.predict(&rec).unwrap(), without.predict(&rec).unwrap());
    let change = rms_diff(&y_with, &y_without);
    assert!(
        change > 10.0 * NOISE,
        "{name}: changes the output by {change}"
    );

    // diagnosed: the plant without it is told that it is missing
    let d = diagnose(
        &rec,
        &y_without,
        &plant_effects(&without),
        &DiagnoseOptions::default(),
    );
    assert_eq!(d.missing, Some(name), "{name}: ranking {:?}", d.ranking);

    // fitted: the grey-box model with the plant's effects comes near the noise
    let list = effect_list(&plant_effects(&with));
    let m = GreyBoxConfig::from_effect_list(&list)
        .unwrap()
        .fit(&rec)
        .unwrap();
    // the fitted plant holds the effect (its parameters, or its structure)
    assert!(
        plant_effects(&m.plant).contains(&name),
        "{name}: {:?}",
        plant_effects(&m.plant)
    );
    let err = rms_diff(
        &m.predict(&rec).unwrap(),
        &rec.outputs
            .iter()
            .map(|s| s.values.clone())
            .collect::<Vec<_>>(),
    );
    println!("{name}: change {change:.3}, fit ({list}) rms {err:.4}");
    assert!(err < 5.0 * NOISE, "{name}: fit {list} leaves {err}");

    // a NARX feature: defined, recomputed from the model file, and with the features of the
    // plant's other effects it identifies the record
    let inputs: Vec<&[f64]> = rec.inputs.iter().map(|s| s.values.as_slice()).collect();
    let features = effect.features(&inputs, rec.ts);
    if features.is_empty() {
        // an effect that is not a function of the input (drift in time, a sensor's limits on
        // the measured output) says why a NARX model has no feature of it
        println!("{name}: no NARX features: {}", effect.no_features());
        assert!(
            matches!(effect.slot(), Slot::OutputTerm | Slot::Sensor),
            "{name}: {}",
            effect.no_features()
        );
        return;
    }
    let (train, test) = rec.split_halves();
    let mut cfg = NarxConfig::new(train.input_names(), train.output_names());
    cfg.robust.try_features.clear();
    let tin: Vec<&[f64]> = train.inputs.iter().map(|s| s.values.as_slice()).collect();
    for e in plant_effects(&with) {
        let x = hystbench::effect::registry::effect(e).unwrap();
        for f in x.features(&tin, train.ts) {
            if !cfg.features.contains(&f) {
                cfg.features.push(f);
            }
        }
    }
    let narx = cfg.fit(&train).unwrap();
    let back = FittedNarx::from_json(Path::new("n.json"), &narx.to_json()).unwrap();
    assert_eq!(back.config.features, cfg.features, "{name}");
    // recomputed from the model file: the same signals as the definitions made on the
    // training record, bit for bit, and finite
    let fresh = cfg.features.clone();
    for (f, g) in back.config.features.iter().zip(&fresh) {
        let again = f.compute(&tin, train.ts);
        assert!(again.iter().all(|v| v.is_finite()), "{name}: {f:?}");
        assert_eq!(again, g.compute(&tin, train.ts), "{name}: {f:?}");
    }
    assert!(
        effect
            .features(&tin, train.ts)
            .iter()
            .all(|f| back.config.features.contains(f)),
        "{name}: its own features are in the model file"
    );
    let p = back.predict(&test, Mode::FreeRun).unwrap();
    for (o, po) in p.iter().enumerate() {
        let r2 = po.scores(&test.outputs[o].values).and_then(|s| s.r2);
        println!(
            "{name}: NARX with {} features, free-run test R^2 {r2:?}",
            cfg.features.len()
        );
        assert!(r2.is_some_and(|r| r > 0.9), "{name}: NARX R^2 {r2:?}");
    }
}

#[test]
fn every_registered_effect_is_simulated_diagnosed_fitted_and_a_narx_feature() {
    let all = effects();
    assert!(all.len() >= 5);
    for e in all {
        check(e);
    }
}
