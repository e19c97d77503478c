//! Physics invariants of the effect library and the plants: rate independence, boundedness,
//! loop direction, closed-form step responses, decoupling.

use hystbench::effect::bouc_wen::BoucWenSpec;
use hystbench::effect::creep::CreepSpec;
use hystbench::effect::dynamics::DynamicsSpec;
use hystbench::effect::hysteresis::{Hysteresis, HysteresisSpec};
use hystbench::effect::prandtl_ishlinskii::{EnvelopesSpec, PrandtlIshlinskiiSpec, TanhEnvelope};
use hystbench::effect::Operator;
use hystbench::plant::{Plant, PlantSpec};
use std::path::Path;

fn piezo_bw() -> Hysteresis {
    HysteresisSpec::BoucWen(BoucWenSpec {
        d: 0.8,
        a: 0.3,
        b: 0.02,
        gamma: 0.01,
        n: 1.0,
        initial_h: 0.0,
    })
    .check()
    .unwrap()
}

fn piezo_pi() -> Hysteresis {
    piezo_pi_spec().check().unwrap()
}

fn piezo_pi_spec() -> HysteresisSpec {
    HysteresisSpec::PrandtlIshlinskii(PrandtlIshlinskiiSpec {
        linear_weight: 0.6,
        thresholds: (1..10).map(|i| 4.0 * i as f64).collect(),
        weights: (1..10).map(|i| 0.12 * (-0.25 * i as f64).exp()).collect(),
        initial_state: 0.0,
        input_map: None,
        dead_zones: None,
        envelope_split: None,
        envelopes: None,
    })
}

/// The shipped generalised plant's operator (`plants/prandtl_ishlinskii_generalised.json`):
/// the classical one on tanh envelopes, ascending and descending apart.
fn piezo_gpi() -> Hysteresis {
    let HysteresisSpec::PrandtlIshlinskii(mut pi) = piezo_pi_spec() else {
        unreachable!()
    };
    pi.envelopes = Some(Box::new(EnvelopesSpec {
        ascending: TanhEnvelope::unit_slope(45.0, 0.3),
        descending: TanhEnvelope::unit_slope(52.0, -0.2),
    }));
    HysteresisSpec::PrandtlIshlinskii(pi).check().unwrap()
}

/// An input path with nested reversals.
fn path(n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let t = k as f64 / n as f64;
            40.0 * (-1.5 * t).exp() * (2.0 * std::f64::consts::PI * 4.0 * t).sin()
                + 8.0 * (2.0 * std::f64::consts::PI * 13.0 * t).sin()
        })
        .collect()
}

/// The same path traversed `m` times slower: every segment split in `m` equal parts.
fn slower(u: &[f64], m: usize) -> Vec<f64> {
    let mut out = vec![u[0]];
    for w in u.windows(2) {
        for j in 1..=m {
            out.push(w[0] + (w[1] - w[0]) * j as f64 / m as f64);
        }
    }
    out
}

#[test]
fn hysteresis_is_rate_independent() {
    for h in [piezo_bw(), piezo_pi(), piezo_gpi()] {
        let u = path(2000);
        let fast = h.operator().apply(&u);
        let slow = h.operator().apply(&slower(&u, 7));
        let err = fast
            .iter()
            .enumerate()
            .map(|(k, y)| (y - slow[7 * k]).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "{h:?}: speed changed the loop by {err}");
    }
}

#[test]
fn bouc_wen_state_is_bounded_by_a_over_b_plus_gamma() {
    let p = BoucWenSpec {
        d: 0.8,
        a: 0.3,
        b: 0.02,
        gamma: 0.01,
        n: 1.0,
        initial_h: 0.0,
    }
    .check()
    .unwrap();
    let bound = p.h_bound();
    let mut g = hystbench::effect::noise::Gaussian::new(5, 0);
    let u: Vec<f64> = (0..20_000).map(|_| 500.0 * g.standard_normal()).collect();
    let y = p.operator().apply(&u);
    let h_max = u
        .iter()
        .zip(&y)
        .map(|(u, y)| (p.d * u - y).abs())
        .fold(0.0, f64::max);
    assert!(
        h_max <= bound * (1.0 + 1e-12),
        "|h| reached {h_max} > {bound}"
    );
    assert!(
        h_max > 0.99 * bound,
        "large inputs should approach the bound: {h_max}"
    );
}

/// Shoelace area of the (u, y) curve: positive when it turns counter-clockwise.
fn signed_area(u: &[f64], y: &[f64]) -> f64 {
    let n = u.len();
    (0..n)
        .map(|k| u[k] * y[(k + 1) % n] - u[(k + 1) % n] * y[k])
        .sum::<f64>()
        / 2.0
}

#[test]
fn piezo_loops_turn_counter_clockwise() {
    // y = d u - h lags the voltage: rising branch below, falling branch above.
    for h in [piezo_bw(), piezo_pi(), piezo_gpi()] {
        let n = 1000;
        let u: Vec<f64> = (0..3 * n)
            .map(|k| 30.0 * (2.0 * std::f64::consts::PI * k as f64 / n as f64).sin())
            .collect();
        let y = h.operator().apply(&u);
        let area = signed_area(&u[2 * n..], &y[2 * n..]);
        assert!(area > 0.0, "{h:?}: area {area}");
        // a loop of area close to nothing would mean no hysteresis
        let box_area = 60.0
            * (y[2 * n..].iter().cloned().fold(f64::MIN, f64::max)
                - y[2 * n..].iter().cloned().fold(f64::MAX, f64::min));
        assert!(
            area / box_area > 0.02,
            "{h:?}: normalised area {}",
            area / box_area
        );
    }
}

#[test]
fn creep_step_response_matches_closed_form() {
    let c = CreepSpec::from_log_rate(1.5, vec![0.1, 1.0, 10.0, 100.0])
        .check()
        .unwrap();
    let ts = 0.01;
    let y = c.operator(ts).apply(&vec![30.0; 20_000]);
    for (k, yk) in y.iter().enumerate().step_by(97) {
        let exact = 30.0 * c.step_response(k as f64 * ts);
        assert!((yk - exact).abs() < 1e-9 * 30.0, "k {k}: {yk} vs {exact}");
    }
    // the logarithmic law: about 1.5 % of the step per decade between 1 s and 10 s
    let per_decade = (y[1000] - y[100]) / 30.0;
    assert!((per_decade - 0.015).abs() < 0.003, "{per_decade}");
}

#[test]
fn dynamics_step_response_matches_closed_form() {
    let d = DynamicsSpec {
        natural_frequency_hz: 800.0,
        damping_ratio: 0.03,
        dc_gain: 1.0,
        second_mode: None,
        first_order_hold: 0.0,
    }
    .check()
    .unwrap();
    let ts = 1e-4;
    let y = d.operator(ts).unwrap().apply(&vec![1.0; 5000]);
    for (k, yk) in y.iter().enumerate() {
        assert!((yk - d.step_response(k as f64 * ts)).abs() < 1e-11);
    }
    let overshoot = y.iter().cloned().fold(f64::MIN, f64::max) - 1.0;
    assert!(
        (overshoot - (-std::f64::consts::PI * 0.03 / (1.0f64 - 0.0009).sqrt()).exp()).abs() < 0.02
    );
}

fn plants_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("plants")
}

#[test]
fn uncoupled_2dof_behaves_as_two_1dof_plants() {
    let path = plants_dir().join("piezo_2dof.json");
    let mut spec = PlantSpec::read(&path).unwrap();
    // keep only the direct paths
    for (i, out) in spec.outputs.iter_mut().enumerate() {
        let direct = format!("u{}", i + 1);
        out.paths.retain(|p| p.input == direct);
    }
    let two = spec.check(&path).unwrap();
    let u1: Vec<f64> = path_signal(3000, 1.0);
    let u2: Vec<f64> = path_signal(3000, 2.3);
    let y = two.simulate(&[&u1, &u2], 2e-4).unwrap();
    for (i, u) in [&u1, &u2].into_iter().enumerate() {
        let mut one = spec.clone();
        one.inputs = vec!["u".into()];
        one.outputs = vec![spec.outputs[i].clone()];
        one.outputs[0].paths[0].input = "u".into();
        let p: Plant = one.check(&path).unwrap();
        let y1 = p.simulate(&[u], 2e-4).unwrap();
        assert_eq!(y1[0], y[i], "output {i} differs from its 1-DoF plant");
    }
    // and with coupling, the cross input does change the output
    let coupled = Plant::from_file(&path).unwrap();
    let yc = coupled.simulate(&[&u1, &u2], 2e-4).unwrap();
    let diff = yc[0]
        .iter()
        .zip(&y[0])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(diff > 1.0, "the cross path adds {diff} um");
}

fn path_signal(n: usize, f: f64) -> Vec<f64> {
    (0..n)
        .map(|k| 40.0 * (2.0 * std::f64::consts::PI * f * 20.0 * k as f64 * 2e-4).sin())
        .collect()
}

#[test]
fn every_shipped_plant_checks() {
    for entry in std::fs::read_dir(plants_dir()).unwrap() {
        let p = entry.unwrap().path();
        let plant = Plant::from_file(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert!(!plant.outputs.is_empty());
    }
}
