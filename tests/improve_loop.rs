//! The model-improvement loop on fitted models (issue acceptance): for each effect E, a record
//! from a plant with E, a grey-box model fitted without E; the diagnosis names E first; refitting
//! with E cuts the RMS error at least 3x; with the complete model nothing is missing, at two
//! noise levels. Records: 40,000 samples at 1 kHz, columns `t,u,y` or `t,u1,u2,y1,y2`.

use hystbench::data::IoRecord;
use hystbench::diagnose::{diagnose, DiagnoseOptions};
use hystbench::effect::EffectName;
use hystbench::graybox::GreyBoxConfig;
use hystbench::model::Model;

mod common;
use common::record;

const SISO: &str = r#"{"name":"hidden","inputs":["u"],"outputs":[{"name":"y","paths":[{"input":"u",
  "hysteresis":{"bouc_wen":{"d":0.7,"A":0.25,"B":0.018,"Gamma":0.006}}}],
  "creep":{"time_constants_s":[0.3,3,30],"percent_per_decade":2.5},
  "dynamics":{"natural_frequency_hz":60,"damping_ratio":0.04}}]}"#;

const SCENARIO: &str = r#"{"name":"s","sampling_period_s":0.001,"samples":40000,"seed":11,
 "inputs":[{"concat":[
   {"duration_s":20,"excitation":{"sum":[{"sine":{"amplitude":22,"frequency_hz":0.9}},{"sine":{"amplitude":8,"frequency_hz":4.3}},{"random_steps":{"amplitude":6,"min_hold_s":0.05,"max_hold_s":0.4}}]}},
   {"duration_s":20,"excitation":{"staircase":{"levels":[25,-10,30,5],"hold_s":5}}}]}]}"#;

/// RMS error (mean over outputs) and the diagnosis' missing effect and top rank.
fn fit_and_diagnose(
    rec: &IoRecord,
    effects: &str,
) -> (f64, Option<EffectName>, Option<EffectName>) {
    let m = GreyBoxConfig::from_effect_list(effects)
        .unwrap()
        .fit(rec)
        .unwrap();
    let pred = Model::predict(&m, rec).unwrap();
    let rmse = rec
        .outputs
        .iter()
        .zip(&pred)
        .map(|(y, p)| hystbench::metrics::rmse(&y.values, p))
        .sum::<f64>()
        / pred.len() as f64;
    let d = diagnose(rec, &pred, &m.effects(), &DiagnoseOptions::default());
    println!(
        "{effects}: rmse {rmse:.4}, ranking {:?}, missing {:?}",
        d.ranking
            .iter()
            .map(|r| (r.effect, (r.explained * 1000.0).round() / 1000.0))
            .collect::<Vec<_>>(),
        d.missing
    );
    (rmse, d.missing, d.ranking.first().map(|r| r.effect))
}

fn loop_for(rec: &IoRecord, without: &str, with: &str, effect: EffectName) {
    let (rmse0, missing, top) = fit_and_diagnose(rec, without);
    assert_eq!(top, Some(effect), "{effect} should rank first");
    assert_eq!(missing, Some(effect), "{effect} should be called missing");
    let (rmse1, _, _) = fit_and_diagnose(rec, with);
    assert!(
        rmse0 / rmse1 >= 3.0,
        "adding {effect}: RMS {rmse0} -> {rmse1}"
    );
}

#[test]
fn missing_creep_is_found_and_added() {
    let rec = record(SISO, SCENARIO, 0.01);
    loop_for(
        &rec,
        "hysteresis,dynamics",
        "hysteresis,creep,dynamics",
        hystbench::effect::creep::NAME,
    );
}

/// 5,000 samples at 1 kHz: 2.5 s of sines and steps, then 2.5 s of held levels.
const SHORT_SCENARIO: &str = r#"{"name":"short","sampling_period_s":0.001,"samples":5000,"seed":12,
 "inputs":[{"concat":[
   {"duration_s":2.5,"excitation":{"sum":[{"sine":{"amplitude":22,"frequency_hz":1.3}},{"sine":{"amplitude":8,"frequency_hz":4.3}},{"random_steps":{"amplitude":6,"min_hold_s":0.05,"max_hold_s":0.2}}]}},
   {"duration_s":2.5,"excitation":{"staircase":{"levels":[25,-10,30,5],"hold_s":0.625}}}]}]}"#;

/// A creep hidden in a short record (5,000 samples, 5 s against time constants of 0.3-30 s)
/// is named and adding it cuts the error 3x or more.
#[test]
fn missing_creep_is_found_and_added_on_a_short_record() {
    let rec = record(SISO, SHORT_SCENARIO, 0.01);
    assert_eq!(rec.len(), 5000);
    loop_for(
        &rec,
        "hysteresis,dynamics",
        "hysteresis,creep,dynamics",
        hystbench::effect::creep::NAME,
    );
}

#[test]
fn missing_hysteresis_is_found_and_added() {
    let rec = record(SISO, SCENARIO, 0.01);
    loop_for(
        &rec,
        "creep,dynamics",
        "hysteresis,creep,dynamics",
        hystbench::effect::hysteresis::NAME,
    );
}

#[test]
fn missing_dynamics_is_found_and_added() {
    let rec = record(SISO, SCENARIO, 0.01);
    loop_for(
        &rec,
        "hysteresis,creep",
        "hysteresis,creep,dynamics",
        hystbench::effect::dynamics::NAME,
    );
}

#[test]
fn complete_model_raises_no_alarm_at_two_noise_levels() {
    for noise in [0.01, 0.1] {
        let rec = record(SISO, SCENARIO, noise);
        let (_, missing, _) = fit_and_diagnose(&rec, "hysteresis,creep,dynamics");
        assert_eq!(missing, None, "noise {noise}");
    }
}

const MIMO: &str = r#"{"name":"hidden2","inputs":["u1","u2"],"outputs":[
 {"name":"y1","paths":[{"input":"u1","hysteresis":{"bouc_wen":{"d":0.8,"A":0.3,"B":0.02,"Gamma":0.01}}},
                       {"input":"u2","hysteresis":{"bouc_wen":{"d":0.1,"A":0.05,"B":0.03,"Gamma":0.01}}}],
  "dynamics":{"natural_frequency_hz":90,"damping_ratio":0.05}},
 {"name":"y2","paths":[{"input":"u2","hysteresis":{"bouc_wen":{"d":1.0,"A":0.35,"B":0.02,"Gamma":0.01}}},
                       {"input":"u1","hysteresis":{"bouc_wen":{"d":0.12,"A":0.05,"B":0.03,"Gamma":0.01}}}],
  "dynamics":{"natural_frequency_hz":140,"damping_ratio":0.05}}]}"#;

const SCENARIO2: &str = r#"{"name":"s2","sampling_period_s":0.001,"samples":40000,"seed":12,
 "inputs":[{"sum":[{"sine":{"amplitude":25,"frequency_hz":0.7}},{"random_steps":{"amplitude":10,"min_hold_s":0.1,"max_hold_s":0.5}}]},
           {"sum":[{"sine":{"amplitude":25,"frequency_hz":1.1}},{"random_steps":{"amplitude":10,"min_hold_s":0.1,"max_hold_s":0.5}}]}]}"#;

#[test]
fn missing_coupling_is_found_and_added_and_complete_mimo_is_clean() {
    let rec = record(MIMO, SCENARIO2, 0.01);
    loop_for(
        &rec,
        "bouc-wen,dynamics",
        "bouc-wen,dynamics,coupling",
        hystbench::effect::coupling::NAME,
    );
    for noise in [0.01, 0.1] {
        let rec = record(MIMO, SCENARIO2, noise);
        let (_, missing, _) = fit_and_diagnose(&rec, "bouc-wen,dynamics,coupling");
        assert_eq!(missing, None, "noise {noise}");
    }
}

/// Each rung's effects, error (its bits), diagnosis and tried candidates.
type RungKey = (
    Vec<EffectName>,
    u64,
    Option<EffectName>,
    Vec<(EffectName, u64)>,
);

fn rung_keys(ladder: &hystbench::improve::Ladder) -> Vec<RungKey> {
    ladder
        .rungs
        .iter()
        .map(|r| {
            let tried = r.tried.iter().map(|(e, x)| (*e, x.to_bits())).collect();
            (r.effects.clone(), r.rmse.to_bits(), r.missing, tried)
        })
        .collect()
}

#[test]
fn improve_with_a_memo_takes_its_fits_and_gives_the_same_ladder() {
    use hystbench::improve::{improve, improve_with_memo, ImproveOptions, RecordMemo};
    let whole = record(SISO, SCENARIO, 0.01);
    let rec = whole.slice(0..20_000);
    let opts = ImproveOptions::default();
    let start_config = GreyBoxConfig::from_effect_list("hysteresis,dynamics").unwrap();
    let start = start_config.fit(&rec).unwrap();
    let complete = GreyBoxConfig::from_effect_list("hysteresis,creep,dynamics").unwrap();
    let run = |memo: &RecordMemo| {
        improve_with_memo(
            Box::new(start.clone()),
            start_config.clone(),
            &rec,
            &opts,
            memo,
            &mut |_| {},
        )
        .unwrap()
    };
    let plain = improve(
        Box::new(start.clone()),
        start_config.clone(),
        &rec,
        &opts,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(
        plain.rungs[1].effects,
        complete.effects(),
        "the loop adds the hidden creep"
    );
    // a memo filled by a first run (every fit and the refit tests' fits) gives the same
    // ladder, and a second run on it fits nothing new
    let memo = RecordMemo::default();
    assert_eq!(rung_keys(&plain), rung_keys(&run(&memo)));
    let kept = memo.fits.len();
    assert!(kept >= 3, "{kept} fits kept");
    assert_eq!(rung_keys(&plain), rung_keys(&run(&memo)));
    assert_eq!(memo.fits.len(), kept);
    // the memo's fit is the one taken: the same structure fitted on another part of the
    // record scores differently on this one
    let other = RecordMemo::default();
    other.fits.insert(
        complete.clone(),
        complete.fit(&whole.slice(20_000..40_000)).unwrap(),
    );
    let taken = run(&other);
    assert_ne!(plain.rungs[1].rmse.to_bits(), taken.rungs[1].rmse.to_bits());
}
