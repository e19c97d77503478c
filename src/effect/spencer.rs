//! # Spencer's MR damper (the full, "modified Bouc-Wen" model)
//!
//! A Bouc-Wen element (dashpot c0, spring k0, evolutionary variable z with weight alpha) in
//! series with a pre-yield dashpot c1, driven by the displacement x (Spencer, Dyke, Sain,
//! Carlson 1997, eqs. 9-11, n = 1, A = 1):
//!
//! ```text
//! dy/dt = (alpha z + c0 dx/dt + k0 (x - y)) / (c0 + c1)
//! dz/dt = (dx/dt - dy/dt) - B |dx/dt - dy/dt| z - Gamma (dx/dt - dy/dt) |z|
//! F     = c1 dy/dt  (+ k1 x + f0: the path's gain and the output's offset)
//! ```
//!
//! At low velocity the stiff Bouc-Wen element has not yielded: y follows x and the force is
//! close to c1 dx/dt, the steep pre-yield slope; at high velocity the element yields, y lags x
//! and the slope falls to about c0 c1 / (c0 + c1). The simple model (a Bouc-Wen term beside a
//! dashpot: `hysteresis` + `viscous`) is the limit of a rigid series dashpot (c1 -> infinity)
//! and has one viscous slope. With n = 1 the Bouc-Wen equation is homogeneous in z, so A is
//! absorbed by alpha.
//!
//! Sampled with x linear within each sample (dx/dt its backward difference, as `viscous`), in
//! sub-steps of at most [`MAX_SUBSTEP`] s and at most half the element's pre-yield time
//! constant (c0 + c1) / (k0 + |alpha|); z by a semi-implicit step that keeps it bounded for
//! any step (the denominator is at least 1 when |Gamma| <= B), y by Euler. The force is 0 at the
//! first sample (y starts at x, z at 0: the damper at rest).
//!
//! ## References
//! - B. F. Spencer Jr., S. J. Dyke, M. K. Sain, J. D. Carlson, "Phenomenological model for
//!   magnetorheological dampers", J. Eng. Mech. 123(3):230-238, 1997.

use super::basis::{BasisBank, BasisContext, EvidenceContext, Signal};
use super::feature::{FeatureKind, FeatureSpec};
use super::fitting::{
    log_bounded, log_bounded_inv, Column, PathSetup, TermFit, TermSpec, FD_STEP, LIMIT,
};
use super::spec::{parse_spec, BoxedOperator, EffectSpec, Params, Spec};
use super::{finite, non_negative, positive, Effect, EffectError, EffectName, Operator, Slot};
use crate::metrics::max_abs;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

/// The effect's name.
pub const NAME: EffectName = EffectName::new("spencer");

/// The largest integration sub-step (s): 1 ms (a record at 5 ms takes 5 sub-steps). On the
/// measured MR damper (mr-damper-utfsm, fitted on its 1 ms records), sub-steps of 0.1 ms
/// instead moved the earthquake R^2 by at most 1.1e-3 per current.
pub const MAX_SUBSTEP: f64 = 1e-3;
/// At most this many sub-steps per sample (a stiffer element is integrated less accurately).
pub const MAX_SUBSTEPS: usize = 1_000;

/// Spencer's full model as written in a plant file (the force term c1 dy/dt; the spring k1 is
/// the path's linear gain, the force offset f0 the output's offset).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpencerSpec {
    /// Post-yield dashpot c0 (force per velocity, e.g. N s/mm), >= 0.
    pub c0: f64,
    /// Pre-yield (series) dashpot c1, > 0.
    pub c1: f64,
    /// Spring of the Bouc-Wen element k0 (force per displacement), >= 0.
    pub k0: f64,
    /// Weight of the evolutionary variable alpha (force per displacement).
    pub alpha: f64,
    /// Bouc-Wen B (1 / displacement), >= 0.
    pub b: f64,
    /// Bouc-Wen Gamma, |Gamma| <= B (z bounded).
    pub gamma: f64,
}

/// Valid parameters of Spencer's full model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spencer {
    pub c0: f64,
    pub c1: f64,
    pub k0: f64,
    pub alpha: f64,
    pub b: f64,
    pub gamma: f64,
}

impl SpencerSpec {
    /// Check the parameters: dashpots and spring not negative (c1 > 0), every value finite,
    /// |Gamma| <= B.
    pub fn check(&self) -> Result<Spencer, EffectError> {
        let p = Spencer {
            c0: non_negative("c0", self.c0)?,
            c1: positive("c1", self.c1)?,
            k0: non_negative("k0", self.k0)?,
            alpha: finite("alpha", self.alpha)?,
            b: non_negative("b", self.b)?,
            gamma: finite("gamma", self.gamma)?,
        };
        if p.gamma.abs() > p.b {
            return Err(EffectError::Invalid {
                field: "gamma".into(),
                value: p.gamma,
                rule: format!("|gamma| must be <= b = {} (z bounded)", p.b),
            });
        }
        Ok(p)
    }
}

impl Spencer {
    /// The sampled operator for sampling period `ts` (s), in sub-steps of at most
    /// [`MAX_SUBSTEP`] and at most half the element's time constant (c0 + c1) / (k0 + |alpha|)
    /// (at most [`MAX_SUBSTEPS`] per sample).
    pub fn operator(&self, ts: f64) -> Result<SpencerOp, EffectError> {
        positive("ts", ts)?;
        Ok(self.operator_unchecked(ts))
    }

    fn operator_unchecked(&self, ts: f64) -> SpencerOp {
        let by_stiffness = (2.0 * ts * (self.k0 + self.alpha.abs()) / (self.c0 + self.c1)).ceil();
        let m = (by_stiffness.min(MAX_SUBSTEPS as f64) as usize).max(substeps_by_time(ts));
        self.op(ts, m)
    }

    fn op(&self, ts: f64, m: usize) -> SpencerOp {
        let m = m.max(1);
        SpencerOp {
            p: *self,
            ts,
            m,
            h: ts / m as f64,
            state: None,
        }
    }

    /// The sampled operator with `m` sub-steps per sample, whatever the stiffness (a fit that
    /// explores wild parameters refuses a diverging simulation rather than waiting for it).
    pub fn operator_in_substeps(&self, ts: f64, m: usize) -> Result<SpencerOp, EffectError> {
        positive("ts", ts)?;
        Ok(self.op(ts, m))
    }
}

/// Sub-steps of at most [`MAX_SUBSTEP`] in a period `ts` (a period a rounding above a whole
/// number of sub-steps takes no extra one).
pub fn substeps_by_time(ts: f64) -> usize {
    (ts / MAX_SUBSTEP * (1.0 - 1e-9)).ceil().max(1.0) as usize
}

/// The sampled model: the force c1 dy/dt at every sample, 0 at the first.
#[derive(Debug, Clone, PartialEq)]
pub struct SpencerOp {
    p: Spencer,
    ts: f64,
    /// Sub-steps per sample and their length.
    m: usize,
    h: f64,
    /// The last input, the internal displacement y and the evolutionary variable z.
    state: Option<(f64, f64, f64)>,
}

impl SpencerOp {
    /// Sub-steps per sample.
    pub fn substeps(&self) -> usize {
        self.m
    }
}

impl Operator for SpencerOp {
    fn reset(&mut self) {
        self.state = None;
    }

    fn step(&mut self, x: f64) -> f64 {
        let Some((last, mut y, mut z)) = self.state else {
            self.state = Some((x, x, 0.0));
            return 0.0;
        };
        let p = &self.p;
        let cs = p.c0 + p.c1;
        let (h, v) = (self.h, (x - last) / self.ts);
        let mut yd = 0.0;
        for s in 0..self.m {
            let xs = last + v * h * (s as f64 + 0.5);
            yd = (p.alpha * z + p.c0 * v + p.k0 * (xs - y)) / cs;
            let du = (v - yd) * h;
            let sg = if z >= 0.0 { 1.0 } else { -1.0 };
            z = (z + du) / (1.0 + p.b * du.abs() + p.gamma * du * sg);
            yd = (p.alpha * z + p.c0 * v + p.k0 * (xs - y)) / cs;
            y += yd * h;
        }
        self.state = Some((x, y, z));
        p.c1 * yd
    }
}

impl Spec for SpencerSpec {
    const EFFECT: EffectName = NAME;
    type Params = Spencer;
    fn check(&self) -> Result<Spencer, EffectError> {
        SpencerSpec::check(self)
    }
}

impl Params for Spencer {
    const EFFECT: EffectName = NAME;
    fn operator(&self, ts: f64) -> Result<BoxedOperator, EffectError> {
        Ok(Box::new(Spencer::operator(self, ts)?))
    }
}

/// The NARX feature: the force c1 dy/dt at c1 = 1 of an input, at a shape fixed on the training
/// record (parameters of the unit model: c0 / c1, k0 / c1, alpha / c1, B, Gamma).
pub static FORCE: FeatureKind = FeatureKind {
    name: "damper_force",
    params: &["c0", "k0", "alpha", "b", "gamma"],
    valid: |p| unit_from(p).check().is_ok(),
    label: |n, p| {
        format!(
            "damper_force({n}, c0={:.3}, alpha={:.3e}, B={:.3e})",
            p[0], p[2], p[3]
        )
    },
    operator: |p, ts| match unit_from(p).check() {
        Ok(s) => Box::new(s.operator_unchecked(ts)),
        // (a model file's features are checked by `valid` when read)
        Err(_) => Box::new(
            Spencer {
                c0: f64::NAN,
                c1: 1.0,
                k0: 0.0,
                alpha: 0.0,
                b: 0.0,
                gamma: 0.0,
            }
            .op(ts, 1),
        ),
    },
};

fn unit_from(p: &[f64]) -> SpencerSpec {
    SpencerSpec {
        c0: p[0],
        c1: 1.0,
        k0: p[1],
        alpha: p[2],
        b: p[3],
        gamma: p[4],
    }
}

/// The features of input `j`: the bank's shapes ([`BANK_SHAPES`]) on the training record.
fn features_of(u: &[f64], j: usize, ts: f64) -> Vec<FeatureSpec> {
    let term = SpencerTerm {
        u,
        ts,
        range: max_abs(u).max(1e-12),
    };
    BANK_SHAPES
        .iter()
        .map(|&(tau, br)| {
            let p = term.unit(&theta(0.05, tau, br, 0.0));
            FeatureSpec::new(&FORCE, j, vec![p.c0, p.k0, p.alpha, p.b, p.gamma])
        })
        .collect()
}

/// The grey-box term's parameters (transformed, each in [-LIMIT, LIMIT]):
/// - `log_c0_ratio`: c0 / c1 in [1e-4, 1e2] (post-yield slope c0 c1 / (c0 + c1));
/// - `log_pre_yield_time`: the pre-yield time constant (c0 + c1) / (k0 + alpha) in
///   [0.1, 1e6] samples;
/// - `spring_share`: k0 / (k0 + alpha) in [1e-6, 1] (log scale);
/// - `log_b`, `gamma_ratio`: B = exp(theta) / range, Gamma = B tanh(theta), as the hysteresis
///   effect's Bouc-Wen term.
///
/// The column is dy/dt at c1 = 1 (it depends on the ratios only); its coefficient is c1 >= 0.
const PARAMS: [&str; 5] = [
    "spencer.log_c0_ratio",
    "spencer.log_pre_yield_time",
    "spencer.spring_share",
    "spencer.log_b",
    "spencer.gamma_ratio",
];

struct SpencerTerm<'a> {
    u: &'a [f64],
    ts: f64,
    range: f64,
}

impl<'a> SpencerTerm<'a> {
    /// The model at c1 = 1 for transformed parameters `th`.
    fn unit(&self, th: &[f64]) -> Spencer {
        let c0 = log_bounded(th[0], 1e-4, 1e2);
        let tau = log_bounded(th[1], 0.1, 1e6) * self.ts;
        let share = log_bounded(th[2], 1e-6, 1.0);
        let stiffness = (1.0 + c0) / tau;
        let b = th[3].clamp(-LIMIT, LIMIT).exp() / self.range;
        Spencer {
            c0,
            c1: 1.0,
            k0: stiffness * share,
            alpha: stiffness * (1.0 - share),
            b,
            gamma: b * th[4].clamp(-LIMIT, LIMIT).tanh(),
        }
    }

    /// The column of `th` computed a block at a time (NaN where it cannot be discretised).
    fn signal(&self, th: &[f64]) -> Signal<'a> {
        match self.unit(th).operator(self.ts) {
            Ok(op) => Signal::samples(self.u).through(Box::new(op)),
            Err(_) => Signal::of(|_| f64::NAN),
        }
    }

    fn column(&self, th: &[f64]) -> Vec<f64> {
        match self.unit(th).operator(self.ts) {
            Ok(mut op) => op.apply(self.u),
            Err(_) => vec![f64::NAN; self.u.len()],
        }
    }
}

impl TermFit for SpencerTerm<'_> {
    fn n_params(&self) -> usize {
        PARAMS.len()
    }
    fn param_names(&self) -> Vec<&'static str> {
        PARAMS.to_vec()
    }
    /// c0 / c1 0.05 or 0.5; pre-yield time 3, 30, 300 samples; k0 a hundredth of the
    /// element's stiffness; B range 1, 10, 100; Gamma / B -0.5 or 0.5.
    fn start_grid(&self) -> Vec<Vec<f64>> {
        let mut g = Vec::new();
        for br in [10.0, 1.0, 100.0] {
            for tau in [30.0, 3.0, 300.0] {
                for c0 in [0.05, 0.5] {
                    for ratio in [-0.5, 0.5] {
                        g.push(theta(c0, tau, br, ratio).to_vec());
                    }
                }
            }
        }
        g
    }
    fn n_columns(&self) -> usize {
        1
    }
    fn columns<'s>(&'s self, th: &[f64]) -> Vec<Column<'s>> {
        vec![(Cow::Owned(self.column(th)), true)]
    }
    /// A forward difference (the model is an ODE; its sensitivities would double its state).
    fn derivative(&self, th: &[f64], q: usize, coef: &[f64]) -> Vec<f64> {
        let mut t2 = th.to_vec();
        t2[q] += FD_STEP;
        self.column(&t2)
            .iter()
            .zip(&self.column(th))
            .map(|(a, b)| coef[0] * (a - b) / FD_STEP)
            .collect()
    }
    fn spec(&self, th: &[f64], _gain: f64, coef: &[f64]) -> TermSpec {
        let c1 = coef[0];
        let u = self.unit(th);
        TermSpec {
            spec: (c1 > 0.0).then(|| {
                Box::new(SpencerSpec {
                    c0: u.c0 * c1,
                    c1,
                    k0: u.k0 * c1,
                    alpha: u.alpha * c1,
                    b: u.b,
                    gamma: u.gamma,
                }) as Box<dyn EffectSpec>
            }),
            extra_paths: Vec::new(),
        }
    }
}

/// Share of a residual the bank must explain before the refit test tries the effect.
pub const REFIT_EVIDENCE: f64 = 0.05;

/// Pre-yield time constants (samples) and B times the input range of the bank's columns.
pub const BANK_SHAPES: [(f64, f64); 6] = [
    (3.0, 3.0),
    (30.0, 3.0),
    (300.0, 3.0),
    (3.0, 30.0),
    (30.0, 30.0),
    (300.0, 30.0),
];

/// Basis bank: the force c1 dy/dt at c1 = 1 of the direct input for a few shapes
/// ([`BANK_SHAPES`]; c0 / c1 = 0.05, k0 a hundredth of the element's stiffness, Gamma = 0).
pub fn basis<'a>(ctx: &BasisContext<'a>) -> BasisBank<'a> {
    let mut bank = BasisBank::new(NAME);
    let u = ctx.inputs[ctx.direct];
    let term = SpencerTerm {
        u,
        ts: ctx.ts,
        range: max_abs(u).max(1e-12),
    };
    for (tau, br) in BANK_SHAPES {
        bank.push(
            format!("spencer(u, pre-yield {tau} samples, B range {br})"),
            term.signal(&theta(0.05, tau, br, 0.0)),
        );
    }
    bank
}

/// The term's transformed parameters of a shape: c0 / c1, pre-yield time `tau` samples, k0 a
/// hundredth of the element's stiffness, B times the range `br`, Gamma / B.
fn theta(c0_ratio: f64, tau: f64, br: f64, gamma_ratio: f64) -> [f64; 5] {
    [
        log_bounded_inv(c0_ratio, 1e-4, 1e2),
        log_bounded_inv(tau, 0.1, 1e6),
        log_bounded_inv(0.01, 1e-6, 1.0),
        f64::ln(br),
        f64::atanh(gamma_ratio),
    ]
}

/// Spencer's MR damper as an effect of the library.
pub struct SpencerEffect;

impl Effect for SpencerEffect {
    fn name(&self) -> EffectName {
        NAME
    }
    fn summary(&self) -> &'static str {
        "Spencer's MR damper: a Bouc-Wen element in series with a pre-yield dashpot (force c1 dy/dt)"
    }
    fn slot(&self) -> Slot {
        Slot::PathTerm
    }
    fn parse_spec(
        &self,
        d: &mut dyn erased_serde::Deserializer<'_>,
    ) -> Result<Box<dyn EffectSpec>, erased_serde::Error> {
        parse_spec::<SpencerSpec>(d)
    }
    /// A small damper on an input of about +-30 at 1 kHz (the effect-matrix test's): c0 = 0.001,
    /// c1 = 0.02, alpha = 0.6, B = 0.1 (pre-yield time 35 ms, yield force 6 output units, of the
    /// order of the example hysteresis path's loop). A damper in N, mm and s: `tests/mr_damper.rs`.
    fn example(&self) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(SpencerSpec {
            c0: 0.001,
            c1: 0.02,
            k0: 0.0,
            alpha: 0.6,
            b: 0.1,
            gamma: 0.0,
        }))
    }
    fn basis<'a>(&self, ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
        Some(basis(ctx))
    }
    /// A model of a specific device: the refit test tries it only where its bank sees
    /// something (on a damper's sine the bank explains 99.7 % of a linear model's residual;
    /// on a piezo actuator's, nothing), so that other diagnoses keep their number of tests.
    fn refit_evidence(&self) -> Option<f64> {
        Some(REFIT_EVIDENCE)
    }
    fn evidence(&self, ctx: &EvidenceContext) -> String {
        let name = ctx.input_names[ctx.direct];
        format!(
            "the error follows the force of a yielding damper driven by {name} (a pre-yield dashpot in series with a Bouc-Wen element: Spencer's MR damper model)"
        )
    }
    fn feature_kinds(&self) -> &'static [FeatureKind] {
        std::slice::from_ref(&FORCE)
    }
    fn features(&self, inputs: &[&[f64]], ts: f64) -> Vec<FeatureSpec> {
        inputs
            .iter()
            .enumerate()
            .flat_map(|(j, u)| features_of(u, j, ts))
            .collect()
    }
    fn term<'a>(&self, setup: &PathSetup<'a>) -> Option<Box<dyn TermFit + 'a>> {
        Some(Box::new(SpencerTerm {
            u: setup.u,
            ts: setup.ts,
            range: max_abs(&setup.fitted_input()).max(1e-12),
        }))
    }
    /// Five nonlinear parameters and the coefficient c1 per path.
    fn parameter_count(&self, _size: super::fitting::BasisSize) -> (usize, usize) {
        (6, 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn damper() -> Spencer {
        SpencerSpec {
            c0: 6.0,
            c1: 100.0,
            k0: 1.0,
            alpha: 1900.0,
            b: 1.5,
            gamma: -0.5,
        }
        .check()
        .unwrap()
    }

    #[test]
    fn bad_parameters_are_refused_by_name() {
        let ok = SpencerSpec {
            c0: 6.0,
            c1: 100.0,
            k0: 1.0,
            alpha: 1900.0,
            b: 1.5,
            gamma: -0.5,
        };
        for (spec, field) in [
            (SpencerSpec { c1: 0.0, ..ok }, "c1"),
            (SpencerSpec { c0: -1.0, ..ok }, "c0"),
            (SpencerSpec { k0: f64::NAN, ..ok }, "k0"),
            (SpencerSpec { gamma: 2.0, ..ok }, "gamma"),
        ] {
            let e = spec.check().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
        assert!(damper().operator(0.0).is_err());
    }

    #[test]
    fn the_force_starts_at_rest_and_rises_to_the_series_dashpot_force() {
        // a constant velocity of 10 mm/s: the element's force alpha z + k0 (x - y) (below its
        // yield force alpha / (B + Gamma) = 1900 N) comes to balance c1 v, y then follows x and
        // the force is c1 v; it rises from 0 without overshoot
        let p = damper();
        let ts = 1e-3;
        let v = 10.0;
        let x: Vec<f64> = (0..3000).map(|k| v * k as f64 * ts).collect();
        let f = p.operator(ts).unwrap().apply(&x);
        assert_eq!(f[0], 0.0);
        // after 20 ms: far above what the post-yield dashpot alone gives
        assert!(f[20] > 5.0 * p.c0 * v, "{}", f[20]);
        let settled = *f.last().unwrap();
        assert!((settled - p.c1 * v).abs() < 1e-3 * p.c1 * v, "{settled}");
        assert!(f
            .windows(2)
            .all(|w| w[1] >= w[0] && w[1] <= p.c1 * v * (1.0 + 1e-9)));
    }

    #[test]
    fn substeps_follow_the_period_and_the_stiffness() {
        let p = damper();
        assert_eq!(p.operator(1e-3).unwrap().substeps(), 1);
        assert_eq!(p.operator(5e-3).unwrap().substeps(), 5);
        let stiff = Spencer {
            c1: 1.0,
            c0: 0.0,
            ..p
        };
        // (k0 + alpha) / (c0 + c1) = 1901 /s: half a time constant is 0.26 ms
        assert_eq!(stiff.operator(1e-3).unwrap().substeps(), 4);
    }

    #[test]
    fn the_grey_box_column_depends_on_the_ratios_only() {
        let u: Vec<f64> = (0..2000).map(|k| 5.0 * (k as f64 * 0.004).sin()).collect();
        let term = SpencerTerm {
            u: &u,
            ts: 1e-3,
            range: 5.0,
        };
        let th = &term.start_grid()[3];
        let unit = term.unit(th);
        let col = term.column(th);
        let scaled = Spencer {
            c0: unit.c0 * 40.0,
            c1: 40.0,
            k0: unit.k0 * 40.0,
            alpha: unit.alpha * 40.0,
            ..unit
        };
        let f = scaled.operator(1e-3).unwrap().apply(&u);
        for (a, b) in f.iter().zip(&col) {
            assert!((a - 40.0 * b).abs() < 1e-9 * a.abs().max(1.0), "{a} vs {b}");
        }
    }
}
