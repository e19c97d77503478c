//! # Synthetic test records
//!
//! Records of known plants made directly with the effect library, for the identifier's tests,
//! benchmarks and examples (the lead's `seed_1dof` / `seed_2dof` scenarios): hysteresis ->
//! creep -> dynamics -> measurement noise. When the plant simulator is available, it is the
//! reference; these stay as a dependency-free check.
//!
//! ## References
//! - PHYSICS.md (project notes): Bouc-Wen piezo, Prandtl-Ishlinskii piezo, creep, coupled 2-DoF.

use crate::data::{IoRecord, Signal};
use crate::effect::bouc_wen::BoucWenSpec;
use crate::effect::creep::CreepSpec;
use crate::effect::dynamics::DynamicsSpec;
use crate::effect::noise::white_noise;
use crate::effect::prandtl_ishlinskii::PrandtlIshlinskiiSpec;
use crate::effect::Operator;
use std::f64::consts::PI;

/// The 1-DoF plants of the `seed_1dof` scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plant1 {
    /// Bouc-Wen piezo with an 800 Hz mode.
    BoucWen,
    /// Prandtl-Ishlinskii piezo with the same mode.
    PrandtlIshlinskii,
    /// Bouc-Wen with creep (0.1, 1, 10 s; 1.5 %/decade) and the mode.
    BoucWenCreep,
}

impl Plant1 {
    /// All of them.
    pub const ALL: [Plant1; 3] = [
        Plant1::BoucWen,
        Plant1::PrandtlIshlinskii,
        Plant1::BoucWenCreep,
    ];

    /// A short name.
    pub fn name(self) -> &'static str {
        match self {
            Plant1::BoucWen => "bouc_wen",
            Plant1::PrandtlIshlinskii => "prandtl_ishlinskii",
            Plant1::BoucWenCreep => "bouc_wen_creep",
        }
    }
}

fn bw(d: f64, a: f64, b: f64, gamma: f64) -> BoucWenSpec {
    BoucWenSpec {
        d,
        a,
        b,
        gamma,
        n: 1.0,
        initial_h: 0.0,
    }
}

fn mode(hz: f64, ts: f64, w: &[f64]) -> Vec<f64> {
    DynamicsSpec {
        natural_frequency_hz: hz,
        damping_ratio: 0.03,
        dc_gain: 1.0,
    }
    .check()
    .expect("valid dynamics")
    .operator(ts)
    .expect("valid sampling")
    .apply(w)
}

/// The `seed_1dof` excitation: 25 sin(2 pi 2 t) + 10 sin(2 pi 5.3 t + 1) + 5 sin(2 pi 11.7 t + 2) V.
pub fn seed_1dof_input(n: usize, ts: f64) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let t = k as f64 * ts;
            25.0 * (2.0 * PI * 2.0 * t).sin()
                + 10.0 * (2.0 * PI * 5.3 * t + 1.0).sin()
                + 5.0 * (2.0 * PI * 11.7 * t + 2.0).sin()
        })
        .collect()
}

/// Noise-free response of a 1-DoF plant.
pub fn plant1_response(plant: Plant1, u: &[f64], ts: f64) -> Vec<f64> {
    let w = match plant {
        Plant1::BoucWen | Plant1::BoucWenCreep => bw(0.8, 0.3, 0.02, 0.01)
            .check()
            .expect("valid")
            .operator()
            .apply(u),
        Plant1::PrandtlIshlinskii => PrandtlIshlinskiiSpec {
            linear_weight: 0.6,
            thresholds: (1..=9).map(|i| 4.0 * i as f64).collect(),
            weights: (1..=9).map(|i| 0.12 * (-0.25 * i as f64).exp()).collect(),
            initial_state: 0.0,
            dead_zones: None,
        }
        .check()
        .expect("valid")
        .operator()
        .apply(u),
    };
    let w = if plant == Plant1::BoucWenCreep {
        CreepSpec::from_log_rate(1.5, vec![0.1, 1.0, 10.0])
            .check()
            .expect("valid")
            .operator(ts)
            .apply(&w)
    } else {
        w
    };
    mode(800.0, ts, &w)
}

fn record(ts: f64, inputs: Vec<(String, Vec<f64>)>, outputs: Vec<(String, Vec<f64>)>) -> IoRecord {
    let sig = |(name, values)| Signal { name, values };
    IoRecord {
        path: "synthetic".into(),
        ts,
        t0: 0.0,
        time_name: "t".into(),
        inputs: inputs.into_iter().map(sig).collect(),
        outputs: outputs.into_iter().map(sig).collect(),
    }
}

/// The `seed_1dof` record of a plant: Ts = 1e-4 s, `n` samples (50,000 in the scenario),
/// 0.01 um of output noise from `seed`.
pub fn seed_1dof(plant: Plant1, n: usize, seed: u64) -> IoRecord {
    let ts = 1e-4;
    let u = seed_1dof_input(n, ts);
    let mut y = plant1_response(plant, &u, ts);
    for (v, e) in y.iter_mut().zip(white_noise(n, 0.01, seed, 1)) {
        *v += e;
    }
    record(ts, vec![("u".into(), u)], vec![("y".into(), y)])
}

/// The `seed_2dof` record of the coupled 2-DoF piezo: Ts = 2e-4 s, 500 samples,
/// u1 = 40 sin(2 pi 20 t), u2 = 40 sin(2 pi 30 t + 0.5); y_i = sum_j D_ij[BW_ij[u_j]] with
/// direct modes 1.5 kHz (y1) and 1.0 kHz (y2), cross paths through the mean of both modes;
/// 0.01 um noise.
pub fn seed_2dof(seed: u64) -> IoRecord {
    let (ts, n) = (2e-4, 500);
    let t = |k: usize| k as f64 * ts;
    let u1: Vec<f64> = (0..n)
        .map(|k| 40.0 * (2.0 * PI * 20.0 * t(k)).sin())
        .collect();
    let u2: Vec<f64> = (0..n)
        .map(|k| 40.0 * (2.0 * PI * 30.0 * t(k) + 0.5).sin())
        .collect();
    let h = |s: BoucWenSpec, u: &[f64]| s.check().expect("valid").operator().apply(u);
    let yy = h(bw(0.80, 0.30, 0.020, 0.010), &u1);
    let zz = h(bw(1.00, 0.35, 0.020, 0.010), &u2);
    let yz = h(bw(0.12, 0.06, 0.030, 0.010), &u2);
    let zy = h(bw(0.08, 0.04, 0.030, 0.010), &u1);
    let cross = |w: &[f64]| -> Vec<f64> {
        mode(1500.0, ts, w)
            .iter()
            .zip(mode(1000.0, ts, w))
            .map(|(a, b)| 0.5 * (a + b))
            .collect()
    };
    let add = |a: Vec<f64>, b: Vec<f64>, stream| -> Vec<f64> {
        a.iter()
            .zip(&b)
            .zip(white_noise(n, 0.01, seed, stream))
            .map(|((x, y), e)| x + y + e)
            .collect()
    };
    let y1 = add(mode(1500.0, ts, &yy), cross(&yz), 1);
    let y2 = add(mode(1000.0, ts, &zz), cross(&zy), 2);
    record(
        ts,
        vec![("u1".into(), u1), ("u2".into(), u2)],
        vec![("y1".into(), y1), ("y2".into(), y2)],
    )
}
