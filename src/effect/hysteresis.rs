//! # Hysteresis (any operator)
//!
//! The hysteresis effect of a path from one input to one output: Bouc-Wen, Prandtl-Ishlinskii
//! (classical or with dead zones), or none (a linear gain, for models without hysteresis).
//! A plant file names the operator: `{"bouc_wen": {...}}`, `{"prandtl_ishlinskii": {...}}` or
//! `{"linear": {"gain": 0.8}}`.

use super::bouc_wen::{BoucWen, BoucWenOp, BoucWenSpec};
use super::prandtl_ishlinskii::{PrandtlIshlinskii, PrandtlIshlinskiiOp, PrandtlIshlinskiiSpec};
use super::{finite, EffectError, Operator};
use serde::{Deserialize, Serialize};

/// A linear path: y = gain * u.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinearSpec {
    pub gain: f64,
}

/// A hysteresis operator as written in a plant file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum HysteresisSpec {
    BoucWen(BoucWenSpec),
    PrandtlIshlinskii(PrandtlIshlinskiiSpec),
    Linear(LinearSpec),
}

/// A valid hysteresis operator.
#[derive(Debug, Clone, PartialEq)]
pub enum Hysteresis {
    BoucWen(BoucWen),
    PrandtlIshlinskii(PrandtlIshlinskii),
    Linear(f64),
}

impl HysteresisSpec {
    /// Check the parameters; errors carry the operator's name in the field path.
    pub fn check(&self) -> Result<Hysteresis, EffectError> {
        Ok(match self {
            HysteresisSpec::BoucWen(s) => {
                Hysteresis::BoucWen(s.check().map_err(|e| e.within("bouc_wen"))?)
            }
            HysteresisSpec::PrandtlIshlinskii(s) => Hysteresis::PrandtlIshlinskii(
                s.check().map_err(|e| e.within("prandtl_ishlinskii"))?,
            ),
            HysteresisSpec::Linear(s) => Hysteresis::Linear(finite("linear.gain", s.gain)?),
        })
    }
}

impl Hysteresis {
    /// The operator at its initial state.
    pub fn operator(&self) -> HysteresisOp {
        match self {
            Hysteresis::BoucWen(p) => HysteresisOp::BoucWen(p.operator()),
            Hysteresis::PrandtlIshlinskii(p) => HysteresisOp::PrandtlIshlinskii(p.operator()),
            Hysteresis::Linear(g) => HysteresisOp::Linear(*g),
        }
    }

    /// True when the operator has memory.
    pub fn is_hysteretic(&self) -> bool {
        !matches!(self, Hysteresis::Linear(_))
    }
}

/// A running hysteresis operator (enum dispatch keeps the per-sample loop inlined).
#[derive(Debug, Clone, PartialEq)]
pub enum HysteresisOp {
    BoucWen(BoucWenOp),
    PrandtlIshlinskii(PrandtlIshlinskiiOp),
    Linear(f64),
}

impl Operator for HysteresisOp {
    fn reset(&mut self) {
        match self {
            HysteresisOp::BoucWen(o) => o.reset(),
            HysteresisOp::PrandtlIshlinskii(o) => o.reset(),
            HysteresisOp::Linear(_) => {}
        }
    }

    #[inline]
    fn step(&mut self, u: f64) -> f64 {
        match self {
            HysteresisOp::BoucWen(o) => o.step(u),
            HysteresisOp::PrandtlIshlinskii(o) => o.step(u),
            HysteresisOp::Linear(g) => *g * u,
        }
    }

    fn apply(&mut self, u: &[f64]) -> Vec<f64> {
        match self {
            HysteresisOp::BoucWen(o) => o.apply(u),
            HysteresisOp::PrandtlIshlinskii(o) => o.apply(u),
            HysteresisOp::Linear(g) => u.iter().map(|v| *g * v).collect(),
        }
    }
}

/// Basis bank: plays of the direct input at thresholds spread over its half range.
pub fn basis(ctx: &super::basis::BasisContext) -> super::basis::BasisBank {
    let u = ctx.inputs[ctx.direct];
    let mut bank = super::basis::BasisBank::new(super::EffectName::Hysteresis);
    let th = super::basis::play_thresholds(u, 8);
    for (r, z) in th.iter().zip(super::play::play_bank(u, &th)) {
        bank.push(format!("play(u, r={r:.3})"), z);
    }
    bank
}
