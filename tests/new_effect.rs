//! Adding an effect without touching `src/` (the worked example of `docs/adding-an-effect.md`).
//!
//! Electrostriction, a strain in the square of the field (y_e = c u^2: strong in PMN
//! actuators, weak in PZT), is defined in this file, registered with one line, and is then
//! simulated from a plant file, fitted by the grey-box model, named by the diagnosis when a
//! model lacks it, and used as a NARX feature that travels in the model file.
//!
//! ## References
//! - K. Uchino, *Piezoelectric Actuators and Ultrasonic Motors*, Kluwer, 1997, ch. 2
//!   (electrostriction: strain proportional to the square of the polarisation).

use hystbench::data::IoRecord;
use hystbench::diagnose::{diagnose, DiagnoseOptions};
use hystbench::effect::basis::{BasisBank, BasisContext, EvidenceContext, Signal};
use hystbench::effect::fitting::{Column, PathSetup, TermFit, TermSpec};
use hystbench::effect::spec::{parse_spec, BoxedOperator};
use hystbench::effect::{
    hysteresis, register, Effect, EffectError, EffectName, EffectSpec, FeatureKind, FeatureSpec,
    Operator, Params, Slot, Spec,
};
use hystbench::graybox::{FittedGreyBox, GreyBoxConfig};
use hystbench::model::Model;
use hystbench::narx::{FittedNarx, Mode, NarxConfig};
use hystbench::plant::{EffectSpecs, PlantSpec};
use hystbench::scenario::ScenarioSpec;
use hystbench::simulator::simulate_scenario;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::path::Path;

// ---- the effect: what its own file in src/effect/ would hold -------------------------------

/// The effect's name (its key in plant files, its name on the command line).
const NAME: EffectName = EffectName::new("electrostriction");

/// The parameters as written in a plant file: `"electrostriction": {"coefficient": 0.002}`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ElectrostrictionSpec {
    /// c, output units per input unit squared.
    coefficient: f64,
}

/// Valid parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Electrostriction {
    coefficient: f64,
}

impl Spec for ElectrostrictionSpec {
    const EFFECT: EffectName = NAME;
    type Params = Electrostriction;
    fn check(&self) -> Result<Electrostriction, EffectError> {
        if self.coefficient.is_finite() {
            Ok(Electrostriction {
                coefficient: self.coefficient,
            })
        } else {
            Err(EffectError::Invalid {
                field: "coefficient".into(),
                value: self.coefficient,
                rule: "must be a finite number".into(),
            })
        }
    }
}

/// The sampled operator: memoryless, c u(k)^2.
#[derive(Clone)]
struct Square {
    c: f64,
}

impl Operator for Square {
    fn reset(&mut self) {}
    fn step(&mut self, u: f64) -> f64 {
        self.c * u * u
    }
}

impl Params for Electrostriction {
    const EFFECT: EffectName = NAME;
    fn operator(&self, _ts: f64) -> Result<BoxedOperator, EffectError> {
        Ok(Box::new(Square {
            c: self.coefficient,
        }))
    }
}

fn square(u: &[f64]) -> Vec<f64> {
    u.iter().map(|v| v * v).collect()
}

/// The NARX feature: the square of an input.
static SQUARE: FeatureKind = FeatureKind {
    name: "square",
    params: &[],
    valid: |_| true,
    label: |n, _| format!("{n}^2"),
    operator: |_, _| Box::new(Square { c: 1.0 }),
};

/// The grey-box term: one column u^2, its coefficient free.
struct SquareTerm {
    u2: Vec<f64>,
}

impl TermFit for SquareTerm {
    fn n_columns(&self) -> usize {
        1
    }
    fn columns<'s>(&'s self, _th: &[f64]) -> Vec<Column<'s>> {
        vec![(Cow::Borrowed(self.u2.as_slice()), false)]
    }
    fn spec(&self, _th: &[f64], _gain: f64, coef: &[f64]) -> TermSpec {
        TermSpec {
            spec: Some(Box::new(ElectrostrictionSpec {
                coefficient: coef[0],
            })),
            extra_paths: Vec::new(),
        }
    }
}

struct ElectrostrictionEffect;

impl Effect for ElectrostrictionEffect {
    fn name(&self) -> EffectName {
        NAME
    }
    fn summary(&self) -> &'static str {
        "a strain in the square of the field, c u^2"
    }
    fn slot(&self) -> Slot {
        Slot::PathTerm
    }
    fn parse_spec(
        &self,
        d: &mut dyn erased_serde::Deserializer<'_>,
    ) -> Result<Box<dyn EffectSpec>, erased_serde::Error> {
        parse_spec::<ElectrostrictionSpec>(d)
    }
    fn basis<'a>(&self, ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
        let mut bank = BasisBank::new(NAME);
        let u = ctx.inputs[ctx.direct];
        bank.push("u^2".into(), Signal::of(move |k| u[k] * u[k]));
        Some(bank)
    }
    fn evidence(&self, ctx: &EvidenceContext) -> String {
        format!(
            "the error follows the square of {}",
            ctx.input_names[ctx.direct]
        )
    }
    fn feature_kinds(&self) -> &'static [FeatureKind] {
        std::slice::from_ref(&SQUARE)
    }
    fn features(&self, inputs: &[&[f64]], _ts: f64) -> Vec<FeatureSpec> {
        (0..inputs.len())
            .map(|j| FeatureSpec::new(&SQUARE, j, Vec::new()))
            .collect()
    }
    fn term<'a>(&self, setup: &PathSetup<'a>) -> Option<Box<dyn TermFit + 'a>> {
        Some(Box::new(SquareTerm {
            u2: square(setup.u),
        }))
    }
    fn parameter_count(&self, _size: hystbench::effect::fitting::BasisSize) -> (usize, usize) {
        (1, 0)
    }
}

static ELECTROSTRICTION: ElectrostrictionEffect = ElectrostrictionEffect;

// ---- the test: simulate, fit, diagnose, NARX feature ---------------------------------------

const PLANT: &str = r#"{"name":"pmn","inputs":["u"],"outputs":[{"name":"y","paths":[{"input":"u",
  "hysteresis":{"bouc_wen":{"d":0.7,"A":0.25,"B":0.018,"Gamma":0.006}},
  "electrostriction":{"coefficient":0.004}}],
  "dynamics":{"natural_frequency_hz":60,"damping_ratio":0.3}}]}"#;

const SCENARIO: &str = r#"{"name":"s","sampling_period_s":0.001,"samples":12000,"seed":3,
 "noise_std":0.01,
 "inputs":[{"sum":[{"sine":{"amplitude":30,"frequency_hz":0.5}},{"sine":{"amplitude":9,"frequency_hz":3.1}}]}]}"#;

fn record() -> IoRecord {
    let p = Path::new("pmn.json");
    let plant = PlantSpec::parse(p, PLANT).unwrap().check(p).unwrap();
    let s = ScenarioSpec::parse(p, SCENARIO).unwrap().check(p).unwrap();
    simulate_scenario(&plant, &s, None).unwrap().record
}

fn rmse(rec: &IoRecord, m: &dyn Model) -> f64 {
    let pred = m.predict(rec).unwrap();
    hystbench::metrics::rmse(&rec.outputs[0].values, &pred[0])
}

#[test]
fn an_effect_defined_here_is_simulated_fitted_diagnosed_and_a_narx_feature() {
    // the one registry line
    register(&ELECTROSTRICTION).unwrap();
    assert_eq!("electrostriction".parse::<EffectName>().unwrap(), NAME);

    // simulated: the plant file names it; the output is the plant without it plus c u^2
    let p = Path::new("pmn.json");
    let spec = PlantSpec::parse(p, PLANT).unwrap();
    let path = &spec.outputs[0].paths[0];
    assert_eq!(
        path.get::<ElectrostrictionSpec>().unwrap().coefficient,
        0.004
    );
    let plant = spec.check(p).unwrap();
    let mut without = spec.clone();
    without.outputs[0].paths[0].remove(NAME);
    let without = without.check(p).unwrap();
    assert_eq!(
        plant.effects(),
        vec![hysteresis::NAME, "dynamics".parse().unwrap(), NAME]
    );
    let u: Vec<f64> = (0..2000).map(|k| 30.0 * (0.003 * k as f64).sin()).collect();
    let ts = 1e-3;
    let (a, b) = (
        plant.simulate(&[&u], ts).unwrap(),
        without.simulate(&[&u], ts).unwrap(),
    );
    // the square term passes through the output's dynamics (unit gain, 60 Hz): compare slowly
    let late = 1500;
    let diff = a[0][late] - b[0][late];
    assert!(
        (diff - 0.004 * u[late - 1] * u[late - 1]).abs() < 0.02 * 0.004 * 900.0,
        "{diff}"
    );
    // a plant file with it round-trips through its JSON
    let text = serde_json::to_string(&spec).unwrap();
    assert!(
        text.contains(r#""electrostriction":{"coefficient":0.004}"#),
        "{text}"
    );
    assert_eq!(PlantSpec::parse(p, &text).unwrap(), spec);

    // fitted: the grey-box model with it recovers c and its error falls to the noise
    let rec = record();
    let fit = |effects: &str| {
        GreyBoxConfig::from_effect_list(effects)
            .unwrap()
            .fit(&rec)
            .unwrap()
    };
    let lacking = fit("bouc-wen,dynamics");
    let complete = fit("bouc-wen,dynamics,electrostriction");
    let (before, after) = (rmse(&rec, &lacking), rmse(&rec, &complete));
    println!("rmse without {before:.4}, with {after:.4}");
    assert!(after < 0.2 * before, "{before} -> {after}");
    assert!(after < 0.02, "{after} (noise 0.01)");
    let c = complete.plant.spec.outputs[0].paths[0]
        .get::<ElectrostrictionSpec>()
        .unwrap()
        .coefficient;
    assert!((c - 0.004).abs() < 0.0002, "fitted c = {c}");
    // the model file names it and reads back
    let back = FittedGreyBox::parse(Path::new("m.json"), &complete.to_json().unwrap()).unwrap();
    assert_eq!(back.effects(), complete.effects());
    assert_eq!(
        complete.config().effect_list(),
        "bouc-wen,dynamics,electrostriction"
    );

    // diagnosed: the fitted model without it is told that electrostriction is missing
    let pred = Model::predict(&lacking, &rec).unwrap();
    let d = diagnose(&rec, &pred, &lacking.effects(), &DiagnoseOptions::default());
    println!("{:?}", d.summary);
    assert_eq!(d.missing, Some(NAME), "{:?}", d.ranking);
    assert!(d.summary.iter().any(|s| s.contains("the square of u")));

    // a NARX feature: its definition travels in the model file and is recomputed
    let (train, test) = rec.split_halves();
    let mut cfg = NarxConfig::new(train.input_names(), train.output_names());
    cfg.robust.try_features.clear();
    let inputs: Vec<&[f64]> = train.inputs.iter().map(|s| &s.values[..]).collect();
    cfg.features = ELECTROSTRICTION.features(&inputs, train.ts);
    assert_eq!(cfg.features[0].label(&train.input_names()), "u^2");
    let m = cfg.fit(&train).unwrap();
    let text = m.to_json();
    assert!(text.contains("\"square\""), "{text}");
    let back = FittedNarx::from_json(Path::new("n.json"), &text).unwrap();
    assert_eq!(back.config.features, cfg.features);
    let p = back.predict(&test, Mode::FreeRun).unwrap();
    let r2 = p[0].scores(&test.outputs[0].values).and_then(|s| s.r2);
    println!("NARX with the square feature: free-run test R^2 {r2:?}");
    assert!(r2.is_some_and(|r| r > 0.99), "{r2:?}");
}
