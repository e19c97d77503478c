//! # Viscous damping (a term in the input's rate)
//!
//! A force (or output) proportional to the rate of the input: y_v = c du/dt, e.g. the dashpot
//! c0 dx/dt of an MR damper driven in displacement (Spencer's phenomenological model:
//! F = c0 dx/dt + k0 x + alpha z, with z a Bouc-Wen state driven by dx/dt). Sampled as the
//! backward difference y_v(k) = c (u(k) - u(k-1)) / Ts, y_v(0) = 0 (the input held before the
//! record starts); exact for an input linear between samples, with half a sample of delay.
//!
//! Hysteresis and creep depend on the input's path, not on its rate: a model made of them
//! cannot produce a force that grows with the rate at the same displacement, and its residual
//! correlates with du/dt (and with low-pass versions of it: a filtered rate).
//!
//! ## References
//! - B. F. Spencer Jr., S. J. Dyke, M. K. Sain, J. D. Carlson, "Phenomenological model for
//!   magnetorheological dampers", J. Eng. Mech. 123(3):230-238, 1997.

use super::basis::{BasisBank, BasisContext, EvidenceContext, Signal};
use super::feature::{FeatureKind, FeatureSpec};
use super::fitting::{Column, PathSetup, TermFit, TermSpec};
use super::spec::{parse_spec, BoxedOperator, EffectSpec, Params, Spec};
use super::{finite, positive, Effect, EffectError, EffectName, Operator, Slot};
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

/// The effect's name.
pub const NAME: EffectName = EffectName::new("viscous");

/// Viscous parameters as written in a plant file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViscousSpec {
    /// c: output units per (input unit / s), e.g. N s/mm. Any sign (a rate term of a fitted
    /// model may be negative).
    pub coefficient: f64,
}

/// Valid viscous parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Viscous {
    pub coefficient: f64,
}

impl ViscousSpec {
    /// Check the parameters (the coefficient must be finite).
    pub fn check(&self) -> Result<Viscous, EffectError> {
        Ok(Viscous {
            coefficient: finite("coefficient", self.coefficient)?,
        })
    }
}

impl Viscous {
    /// The sampled operator for sampling period `ts` (s).
    pub fn operator(&self, ts: f64) -> Result<ViscousOp, EffectError> {
        positive("ts", ts)?;
        Ok(ViscousOp {
            gain: self.coefficient / ts,
            last: None,
        })
    }
}

/// The sampled viscous term: c (u(k) - u(k-1)) / Ts, 0 at the first sample.
#[derive(Debug, Clone, PartialEq)]
pub struct ViscousOp {
    gain: f64,
    last: Option<f64>,
}

impl Operator for ViscousOp {
    fn reset(&mut self) {
        self.last = None;
    }

    fn step(&mut self, x: f64) -> f64 {
        let y = match self.last {
            Some(p) => self.gain * (x - p),
            None => 0.0,
        };
        self.last = Some(x);
        y
    }
}

/// The rate of a signal, (u(k) - u(k-1)) / Ts with 0 at the first sample.
pub fn rate(u: &[f64], ts: f64) -> Vec<f64> {
    Rate::new(ts).apply(u)
}

/// [`rate`] one sample at a time.
#[derive(Debug, Clone)]
pub struct Rate {
    ts: f64,
    last: Option<f64>,
}

impl Rate {
    pub fn new(ts: f64) -> Rate {
        Rate { ts, last: None }
    }
}

impl Operator for Rate {
    fn reset(&mut self) {
        self.last = None;
    }
    fn step(&mut self, x: f64) -> f64 {
        let r = self.last.map_or(0.0, |p| (x - p) / self.ts);
        self.last = Some(x);
        r
    }
}

/// First-order low-pass (exact ZOH, unit gain, state 0 at the start), one sample at a time.
#[derive(Debug, Clone)]
struct LowPass {
    a: f64,
    s: f64,
}

impl LowPass {
    fn new(tau: f64, ts: f64) -> LowPass {
        LowPass {
            a: (-ts / tau).exp(),
            s: 0.0,
        }
    }
}

impl Operator for LowPass {
    fn reset(&mut self) {
        self.s = 0.0;
    }
    fn step(&mut self, v: f64) -> f64 {
        self.s = self.a * self.s + (1.0 - self.a) * v;
        self.s
    }
}

/// Time constants (in samples) of the bank's low-passed rates.
pub const BANK_TAUS: [f64; 2] = [5.0, 25.0];

/// Basis bank: the rate of the direct input and low-passed versions of it ([`BANK_TAUS`]
/// samples): what a dashpot adds to a model, alone or behind a compliance (a Maxwell element,
/// spring k in series with dashpot c: force = c du/dt low-passed with tau = c / k).
pub fn basis<'a>(ctx: &BasisContext<'a>) -> BasisBank<'a> {
    let mut bank = BasisBank::new(NAME);
    let u = ctx.inputs[ctx.direct];
    let r = || Signal::samples(u).through(Box::new(Rate::new(ctx.ts)));
    for m in BANK_TAUS {
        let tau = m * ctx.ts;
        bank.push(
            format!("rate(u, low-pass tau={tau:.4} s)"),
            r().through(Box::new(LowPass::new(tau, ctx.ts))),
        );
    }
    bank.push("rate(u)".into(), r());
    bank
}

impl Spec for ViscousSpec {
    const EFFECT: EffectName = NAME;
    type Params = Viscous;
    fn check(&self) -> Result<Viscous, EffectError> {
        ViscousSpec::check(self)
    }
}

impl Params for Viscous {
    const EFFECT: EffectName = NAME;
    fn operator(&self, ts: f64) -> Result<BoxedOperator, EffectError> {
        Ok(Box::new(Viscous::operator(self, ts)?))
    }
}

/// The NARX feature: the rate of an input.
pub static RATE: FeatureKind = FeatureKind {
    name: "rate",
    params: &[],
    valid: |_| true,
    label: |n, _| format!("rate({n})"),
    operator: |_, ts| Box::new(Rate::new(ts)),
};

/// The grey-box term: c du/dt, c by least squares.
struct RateTerm {
    rate: Vec<f64>,
}

impl TermFit for RateTerm {
    fn n_columns(&self) -> usize {
        1
    }
    fn columns<'s>(&'s self, _th: &[f64]) -> Vec<Column<'s>> {
        vec![(Cow::Borrowed(self.rate.as_slice()), false)]
    }
    fn spec(&self, _th: &[f64], _gain: f64, coef: &[f64]) -> TermSpec {
        TermSpec {
            spec: Some(Box::new(ViscousSpec {
                coefficient: coef[0],
            })),
            extra_paths: Vec::new(),
        }
    }
}

/// Viscous damping as an effect of the library.
pub struct ViscousEffect;

impl Effect for ViscousEffect {
    fn name(&self) -> EffectName {
        NAME
    }
    fn summary(&self) -> &'static str {
        "a term in the input's rate, c du/dt (the dashpot of an MR damper)"
    }
    fn slot(&self) -> Slot {
        Slot::PathTerm
    }
    fn parse_spec(
        &self,
        d: &mut dyn erased_serde::Deserializer<'_>,
    ) -> Result<Box<dyn EffectSpec>, erased_serde::Error> {
        parse_spec::<ViscousSpec>(d)
    }
    /// A dashpot of 0.003 output units per input unit per second.
    fn example(&self) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(ViscousSpec { coefficient: 0.003 }))
    }
    fn basis<'a>(&self, ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
        Some(basis(ctx))
    }
    fn evidence(&self, ctx: &EvidenceContext) -> String {
        let name = ctx.input_names[ctx.direct];
        format!(
            "the error follows the rate of {name} (correlation {:.2}): a force in d{name}/dt (viscous damping) is not in the model",
            crate::metrics::correlation(&rate(ctx.inputs[ctx.direct], ctx.ts), ctx.error),
        )
    }
    fn feature_kinds(&self) -> &'static [FeatureKind] {
        std::slice::from_ref(&RATE)
    }
    fn features(&self, inputs: &[&[f64]], _ts: f64) -> Vec<FeatureSpec> {
        (0..inputs.len())
            .map(|j| FeatureSpec::new(&RATE, j, Vec::new()))
            .collect()
    }
    fn term<'a>(&self, setup: &PathSetup<'a>) -> Option<Box<dyn TermFit + 'a>> {
        Some(Box::new(RateTerm {
            rate: rate(setup.u, setup.ts),
        }))
    }
    /// Not counted in the record length the fit needs (as before the effect library became one
    /// trait: the same records are refused).
    fn parameter_count(&self, _size: super::fitting::BasisSize) -> (usize, usize) {
        (0, 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn operator_is_the_scaled_backward_difference() {
        let v = ViscousSpec { coefficient: 2.0 }.check().unwrap();
        let mut op = v.operator(0.5).unwrap();
        let y = op.apply(&[1.0, 2.0, 4.0, 3.0]);
        assert_eq!(y, vec![0.0, 4.0, 8.0, -4.0]);
        op.reset();
        assert_eq!(op.step(10.0), 0.0);
        // a ramp of slope 3 gives c * 3 after the first sample
        let u: Vec<f64> = (0..10).map(|k| 3.0 * k as f64 * 0.01).collect();
        let y = v.operator(0.01).unwrap().apply(&u);
        assert!(y[1..].iter().all(|v| (v - 6.0).abs() < 1e-9), "{y:?}");
    }

    #[test]
    fn bad_parameters_name_the_field() {
        let e = ViscousSpec {
            coefficient: f64::NAN,
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("coefficient"), "{e}");
        let e = ViscousSpec { coefficient: 1.0 }
            .check()
            .unwrap()
            .operator(0.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("ts"), "{e}");
    }
}
