//! Plant files as read and as built in code: the hand-written reading of paths and outputs
//! refuses unknown, repeated, missing and misplaced keys (as the derived one did) and keeps the
//! position of a nested error; a plant built in code is checked like a file.

use hystbench::data::JsonFileError;
use hystbench::plant::{PlantError, PlantSpec};
use std::path::Path;

const PATH: &str = r#"{"input":"u","hysteresis":{"linear":{"gain":0.5}}"#;

fn plant(path_rest: &str, output_rest: &str) -> String {
    format!(
        r#"{{"name":"p","inputs":["u"],"outputs":[{{"name":"y","paths":[{PATH}{path_rest}}}]{output_rest}}}]}}"#
    )
}

fn error(text: &str) -> String {
    PlantSpec::parse(Path::new("p.json"), text)
        .map(|_| String::new())
        .unwrap_or_else(|e| e.to_string())
}

/// The hand-written reading of paths and outputs refuses what the derived one refused.
#[test]
fn unknown_repeated_missing_and_misplaced_keys_are_refused() {
    assert!(error(&plant("", "")).is_empty());
    let e = error(&plant(r#","friction":{}"#, ""));
    assert!(
        e.contains("unknown field `friction`") && e.contains("`viscous`"),
        "{e}"
    );
    let e = error(&plant(r#","hysteresis":{"linear":{"gain":1}}"#, ""));
    assert!(e.contains("duplicate field `hysteresis`"), "{e}");
    let e =
        error(r#"{"name":"p","inputs":["u"],"outputs":[{"name":"y","paths":[{"input":"u"}]}]}"#);
    assert!(e.contains("missing field `hysteresis`"), "{e}");
    // creep is an output filter, not a path effect; viscous is not an output effect
    let e = error(&plant(
        r#","creep":{"time_constants_s":[1],"gains":[0.1]}"#,
        "",
    ));
    assert!(e.contains("unknown field `creep`"), "{e}");
    let e = error(&plant("", r#","viscous":{"coefficient":1}"#));
    assert!(e.contains("unknown field `viscous`"), "{e}");
    // the position of a nested error is kept (line 3 here)
    let text = "{\"name\":\"p\",\"inputs\":[\"u\"],\"outputs\":[{\"name\":\"y\",\n\"paths\":[{\"input\":\"u\",\n\"hysteresis\":{\"linear\":{\"gain\":\"x\"}}}]}]}";
    match PlantSpec::parse(Path::new("p.json"), text) {
        Err(PlantError::File(JsonFileError::Parse { line, .. })) => assert_eq!(line, 3),
        other => panic!("{other:?}"),
    }
    // null means absent, as with the derived reading
    assert!(error(&plant(r#","viscous":null"#, r#","creep":null"#)).is_empty());
}

/// A plant built in code is checked like a file: a path effect on an output and an effect
/// given twice are refused; filters given out of order run in chain order.
#[test]
fn plants_built_in_code_are_checked_and_put_in_chain_order() {
    let p = Path::new("p.json");
    let mut spec = PlantSpec::parse(p, &plant("", "")).unwrap();
    spec.outputs[0].effects = vec![Box::new(hystbench::effect::viscous::ViscousSpec {
        coefficient: 1.0,
    })];
    let e = spec.check(p).unwrap_err().to_string();
    assert!(
        e.contains("viscous") && e.contains("not an effect of an output"),
        "{e}"
    );
    let dynamics = hystbench::effect::dynamics::DynamicsSpec {
        natural_frequency_hz: 20.0,
        damping_ratio: 0.5,
        dc_gain: 1.0,
        second_mode: None,
        first_order_hold: 0.0,
    };
    let creep = hystbench::effect::creep::CreepSpec::from_log_rate(2.0, vec![0.1, 1.0]);
    spec.outputs[0].effects = vec![Box::new(dynamics), Box::new(dynamics)];
    let e = spec.check(p).unwrap_err().to_string();
    assert!(e.contains("given twice"), "{e}");
    spec.outputs[0].effects = vec![Box::new(dynamics), Box::new(creep.clone())];
    let swapped = spec.check(p).unwrap();
    spec.outputs[0].effects = vec![Box::new(creep), Box::new(dynamics)];
    let ordered = spec.check(p).unwrap();
    let u: Vec<f64> = (0..400).map(|k| (0.05 * k as f64).sin()).collect();
    assert_eq!(
        swapped.simulate(&[&u], 1e-3).unwrap(),
        ordered.simulate(&[&u], 1e-3).unwrap()
    );
    assert_eq!(swapped.spec, ordered.spec);
}
