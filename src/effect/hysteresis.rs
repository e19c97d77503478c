//! # Hysteresis (any operator)
//!
//! The hysteresis effect of a path from one input to one output: Bouc-Wen, Prandtl-Ishlinskii
//! (classical or with dead zones), or none (a linear gain, for models without hysteresis).
//! A plant file names the operator: `{"bouc_wen": {...}}`, `{"prandtl_ishlinskii": {...}}` or
//! `{"linear": {"gain": 0.8}}`.

use super::basis::{play_thresholds, BasisBank, BasisContext, EvidenceContext, Signal};
use super::bouc_wen::{BoucWen, BoucWenOp, BoucWenSpec};
use super::draw::{Dice, DrawContext, PathRole};
use super::feature::{FeatureKind, FeatureSpec};
use super::fitting::{
    Column, PathSetup, RecordError, RecordView, TermFit, TermSpec, TermState, Variant, FD_STEP,
    LIMIT, SECOND_STAGE_PARAM,
};
use super::play::{play_operator, Play};
use super::prandtl_ishlinskii::{
    dead_zone, envelope_split, DeadZoneSpec, EnvelopesSpec, PrandtlIshlinskii, PrandtlIshlinskiiOp,
    PrandtlIshlinskiiSpec, TanhEnvelope,
};
use super::spec::{parse_spec, BoxedOperator, EffectSpec, Params, Spec};
use super::{finite, Effect, EffectError, EffectName, Operator, Slot};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::ops::Range;

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

    /// The operator of the negated output, -H[u] (a reversed polarity, a cross path that bends
    /// the other way): a Bouc-Wen loop with d, A, Gamma and h(0) negated
    /// ([`crate::effect::bouc_wen`]); a Prandtl-Ishlinskii operator with its weights (plays,
    /// the input itself, the input map) negated and its dead zones mirrored, d_j -> -d_j
    /// (-S[-z] = sum_j c_j S_{-d_j}(z), increasing as S is); a gain negated.
    pub fn negated(&self) -> HysteresisSpec {
        match self {
            HysteresisSpec::BoucWen(s) => HysteresisSpec::BoucWen(BoucWenSpec {
                d: -s.d,
                a: -s.a,
                gamma: -s.gamma,
                initial_h: -s.initial_h,
                ..*s
            }),
            HysteresisSpec::PrandtlIshlinskii(s) => {
                let neg = |w: &[f64]| w.iter().map(|w| -w).collect();
                HysteresisSpec::PrandtlIshlinskii(PrandtlIshlinskiiSpec {
                    envelope_split: s.envelope_split,
                    envelopes: s.envelopes.clone(),
                    linear_weight: -s.linear_weight,
                    thresholds: s.thresholds.clone(),
                    weights: neg(&s.weights),
                    initial_state: s.initial_state,
                    input_map: s.input_map.as_ref().map(|m| DeadZoneSpec {
                        thresholds: m.thresholds.clone(),
                        weights: neg(&m.weights),
                    }),
                    dead_zones: s.dead_zones.as_ref().map(|d| DeadZoneSpec {
                        thresholds: d.thresholds.iter().rev().map(|t| -t).collect(),
                        weights: d.weights.iter().rev().copied().collect(),
                    }),
                })
            }
            HysteresisSpec::Linear(s) => HysteresisSpec::Linear(LinearSpec { gain: -s.gain }),
        }
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
pub fn basis<'a>(ctx: &BasisContext<'a>) -> BasisBank<'a> {
    let u = ctx.inputs[ctx.direct];
    let mut bank = BasisBank::new(NAME);
    let th = play_thresholds(u, 8);
    for r in th {
        bank.push(
            format!("play(u, r={r:.3})"),
            Signal::samples(u).through(Box::new(Play::new(r, 0.0))),
        );
    }
    bank
}

// ---------------------------------------------------------------------------------------------
// The effect: plant files, diagnosis, NARX features, grey-box terms.

/// The effect's name.
pub const NAME: EffectName = EffectName::new("hysteresis");

impl Spec for HysteresisSpec {
    const EFFECT: EffectName = NAME;
    type Params = Hysteresis;
    fn check(&self) -> Result<Hysteresis, EffectError> {
        HysteresisSpec::check(self)
    }
}

impl Params for Hysteresis {
    const EFFECT: EffectName = NAME;
    fn operator(&self, _ts: f64) -> Result<BoxedOperator, EffectError> {
        Ok(Box::new(Hysteresis::operator(self)))
    }
    fn is_active(&self) -> bool {
        self.is_hysteretic()
    }
}

/// The NARX feature: a play operator of an input, state 0 at the start.
pub static PLAY: FeatureKind = FeatureKind {
    name: "play",
    params: &["threshold"],
    valid: |p| p[0].is_finite() && p[0] >= 0.0,
    label: |n, p| format!("play({n}, r={:.4})", p[0]),
    operator: |p, _| Box::new(super::play::Play::new(p[0], 0.0)),
};

/// Thresholds spread over the input range: r_k = k R / (n + 1), k = 1..n, R = max |u|.
pub fn pi_thresholds(u: &[f64], n: usize) -> Vec<f64> {
    let r = crate::metrics::max_abs(u);
    (1..=n).map(|k| k as f64 * r / (n + 1) as f64).collect()
}

fn max_abs(u: &[f64]) -> f64 {
    crate::metrics::max_abs(u).max(1e-300)
}

/// -htilde for A = 1 and exponent `n`: h of amplitude A is A times the unit loop of
/// B A^(n-1), Gamma A^(n-1) (for n = 1, h is linear in A: the exact update scales with A).
fn bouc_wen_column(u: &[f64], b: f64, gamma: f64, n: f64) -> Vec<f64> {
    let spec = BoucWenSpec {
        n,
        ..BoucWenSpec::unit(b, gamma)
    };
    match spec.check() {
        Ok(p) => p.operator().apply(u),
        Err(_) => vec![f64::NAN; u.len()],
    }
}

/// The grey-box Bouc-Wen column's shape (B, Gamma, n) of the unit loop (A = 1):
/// n = 1 + theta_2 where the exponent is free ([`Bw::exponent`], else 1),
/// B = exp(theta_0) / range^n (so that theta_0 sets the loop's shape whatever the input's
/// unit), Gamma = B tanh(theta_1).
fn bouc_wen_params(th: &[f64], bw: Bw) -> (f64, f64, f64) {
    let n = if bw.exponent {
        1.0 + th[2].clamp(0.0, EXPONENT_LIMIT)
    } else {
        1.0
    };
    let b = th[0].exp() / bw.range.powf(n);
    (b, b * th[1].clamp(-LIMIT, LIMIT).tanh(), n)
}

/// A Bouc-Wen term of exponent `n` and gain `d` (0 beside a path's gain).
fn bouc_wen_term_spec(a: f64, b: f64, gamma: f64, n: f64, d: f64) -> HysteresisSpec {
    HysteresisSpec::BoucWen(BoucWenSpec {
        d,
        a,
        b,
        gamma,
        n,
        initial_h: 0.0,
    })
}

/// The zoo's hysteresis, for an input of peak `U = ctx.input_amplitude`:
///
/// | family (direct path) | share | parameters |
/// |---|---|---|
/// | Bouc-Wen | 40 % | gain d log-uniform 0.05-1.5 per input unit; B U log-uniform 0.5-20 (thin lens to flat-topped loop); Gamma / B uniform -0.8-0.8; loop height A / (B + Gamma) = w d U with w log-uniform 0.03-0.4; n = 1, or uniform 1.5-3 in 1 of 5 |
/// | classical Prandtl-Ishlinskii | 25 % | 4-12 plays at thresholds U k / (m + 1); weights decaying as e^(-c k / m), c uniform 0-3, summing to a share uniform 0.1-0.6 of the gain |
/// | asymmetric Prandtl-Ishlinskii (Kuhnen) | 20 % | as above, then dead zones at 0, a Y and -b Y (a, b uniform 0.2-0.7 of the peak output Y) with weights 1, c1, c2 uniform -0.35-0.35 |
/// | saturating Prandtl-Ishlinskii | 15 % | as above, dead zones at +-0.45 Y and +-0.75 Y taking 30-45 % and 25-40 % off the slope |
///
/// A cross path is linear (its gain) in 2 of 5 plants, else one of the families above; its
/// gain is the direct gain times the context's relative gain. The operator is then negated
/// ([`HysteresisSpec::negated`]) on a path of negative sign (`ctx.sign`).
pub fn draw(ctx: &DrawContext, dice: &mut Dice) -> HysteresisSpec {
    let d = dice.log_uniform(0.05, 1.5)
        * match ctx.role {
            PathRole::Direct => 1.0,
            PathRole::Cross { relative_gain } => relative_gain,
        };
    let spec = draw_positive(ctx, dice, d);
    if ctx.sign < 0.0 {
        spec.negated()
    } else {
        spec
    }
}

/// [`draw`]'s operator of positive gain `d`.
fn draw_positive(ctx: &DrawContext, dice: &mut Dice, d: f64) -> HysteresisSpec {
    let u = ctx.input_amplitude;
    if matches!(ctx.role, PathRole::Cross { .. }) && dice.chance(0.4) {
        return HysteresisSpec::Linear(LinearSpec { gain: d });
    }
    match dice.pick(&[0.40, 0.25, 0.20, 0.15]) {
        0 => {
            let b = dice.log_uniform(0.5, 20.0) / u;
            let gamma = b * dice.uniform(-0.8, 0.8);
            let w = dice.log_uniform(0.03, 0.4);
            HysteresisSpec::BoucWen(BoucWenSpec {
                d,
                a: w * d * u * (b + gamma),
                b,
                gamma,
                n: if dice.chance(0.2) {
                    dice.uniform(1.5, 3.0)
                } else {
                    1.0
                },
                initial_h: 0.0,
            })
        }
        family => {
            let m = dice.int(4, 12);
            let c = dice.uniform(0.0, 3.0);
            let share = dice.uniform(0.1, 0.6);
            let raw: Vec<f64> = (1..=m).map(|k| (-c * k as f64 / m as f64).exp()).collect();
            let total: f64 = raw.iter().sum();
            let weights: Vec<f64> = raw.iter().map(|w| w / total * share * d).collect();
            let thresholds = (1..=m).map(|k| u * k as f64 / (m + 1) as f64).collect();
            // the PI output's peak, roughly: the whole slope times the input's peak
            let y = d * u;
            let dead_zones = match family {
                1 => None,
                2 => Some(DeadZoneSpec {
                    thresholds: vec![-dice.uniform(0.2, 0.7) * y, 0.0, dice.uniform(0.2, 0.7) * y],
                    weights: vec![dice.uniform(-0.35, 0.35), 1.0, dice.uniform(-0.35, 0.35)],
                }),
                _ => {
                    let (c1, c2) = (dice.uniform(0.3, 0.45), dice.uniform(0.25, 0.4));
                    Some(DeadZoneSpec {
                        thresholds: vec![-0.75 * y, -0.45 * y, 0.0, 0.45 * y, 0.75 * y],
                        weights: vec![-c2, -c1, 1.0, -c1, -c2],
                    })
                }
            };
            HysteresisSpec::PrandtlIshlinskii(PrandtlIshlinskiiSpec {
                envelope_split: None,
                envelopes: None,
                linear_weight: d * (1.0 - share),
                thresholds,
                weights,
                initial_state: 0.0,
                input_map: None,
                dead_zones,
            })
        }
    }
}

/// Generalised plays drawn on a Prandtl-Ishlinskii operator driven by `input` (the zoo's
/// `--extra hysteresis`; Al Janaideh, Rakheja & Su 2011): tanh envelopes of slope 1 at u = 0,
/// one on the ascending edge and another on the descending edge
/// ([`TanhEnvelope::unit_slope`]), in place of Kuhnen's dead zones (a Bouc-Wen loop or a gain
/// is left as it is: `None`).
///
/// | parameter | range |
/// |---|---|
/// | ascending level L (saturation, input units) | the input's peak U over L uniform 0.4-1.6 (without skew, the slope at the peak 15-85 % of that at 0; with one, an end flattens sooner and the other later) |
/// | descending level | L times log-uniform 0.75-1.33 |
/// | skew of each (the tanh's offset) | uniform -0.4-0.4: one end bends sooner than the other |
///
/// The two are drawn apart, so they may cross (both pass through 0 with slope 1): where the
/// ascending one lies above the descending one, a play of threshold below half their gap has
/// no band there and follows the ascending one, as in the independent generator's draw of the
/// family (`benches/independent`).
pub fn draw_envelopes(
    spec: &HysteresisSpec,
    input: &[f64],
    dice: &mut Dice,
) -> Option<HysteresisSpec> {
    let HysteresisSpec::PrandtlIshlinskii(pi) = spec else {
        return None;
    };
    let peak = crate::metrics::max_abs(input);
    if !(peak > 0.0 && peak.is_finite()) {
        return None;
    }
    let level = peak / dice.uniform(0.4, 1.6);
    let ascending = TanhEnvelope::unit_slope(level, dice.uniform(-0.4, 0.4));
    let descending = TanhEnvelope::unit_slope(
        level * dice.log_uniform(0.75, 1.33),
        dice.uniform(-0.4, 0.4),
    );
    Some(HysteresisSpec::PrandtlIshlinskii(PrandtlIshlinskiiSpec {
        envelopes: Some(Box::new(EnvelopesSpec {
            ascending,
            descending,
        })),
        envelope_split: None,
        dead_zones: None,
        ..pi.clone()
    }))
}

/// A grey-box Bouc-Wen column: the scale of its B (the input's range) and the path's sign.
/// The column is sign (-h~) of A = 1, its weight c >= 0: on a path of negative gain it is the
/// mirrored loop, written A = -c, Gamma = -Gamma ([`crate::effect::bouc_wen`]), so that the
/// loop's shape has the same parameters on either sign ([`bw_spec`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bw {
    range: f64,
    sign: f64,
    /// Whether the exponent n is fitted (a third parameter, n - 1 in [0, [`EXPONENT_LIMIT`]];
    /// else n = 1).
    exponent: bool,
}

/// The largest n - 1 of a fitted Bouc-Wen exponent.
const EXPONENT_LIMIT: f64 = 3.0;

/// n - 1 of the second starting grid of a fitted exponent (n = 2): B and Gamma scale with the
/// amplitude to the power n, so the fit at n = 1 can lie far from the basin of n = 2 (a loop of
/// n = 2 fitted at n = 1 is a minimum at the bound that freeing n from it does not leave).
const EXPONENT_RESTART: f64 = 1.0;

/// The step of the exponent's forward difference: at n = 1 the column is the exact update
/// and beside it the sub-stepped RK4 of n > 1 ([`crate::effect::bouc_wen`]), whose error
/// (up to about 6e-6 of the loop) a step of [`FD_STEP`] would make larger than the
/// derivative; at 1e-3 it is below 1 % of it.
const EXPONENT_STEP: f64 = 1e-3;

/// The column of `bw` at `th` ([`Bw`]).
fn bw_column(u: &[f64], bw: Bw, th: &[f64]) -> Vec<f64> {
    let (b, g, n) = bouc_wen_params(th, bw);
    let mut c = bouc_wen_column(u, b, g, n);
    if bw.sign < 0.0 {
        c.iter_mut().for_each(|v| *v = -*v);
    }
    c
}

/// The Bouc-Wen term of weight `c` >= 0 on the column of `bw` at `th`, with gain `d`: A = c
/// and, for n > 1, the unit loop's B and Gamma over c^(n-1) ([`bouc_wen_column`]).
fn bw_spec(bw: Bw, th: &[f64], c: f64, d: f64) -> HysteresisSpec {
    let (b, g, n) = bouc_wen_params(th, bw);
    let s = if n == 1.0 { 1.0 } else { c.powf(n - 1.0) };
    bouc_wen_term_spec(bw.sign * c, b / s, bw.sign * g / s, n, d)
}

/// d/d theta_q of a_coef * (Bouc-Wen column) by a forward difference.
fn bouc_wen_derivative(
    u: &[f64],
    th: &[f64],
    q: usize,
    bw: Bw,
    base: &[f64],
    a_coef: f64,
) -> Vec<f64> {
    let mut step = if q == 2 { EXPONENT_STEP } else { FD_STEP };
    if q == 2 && th[2] + step > EXPONENT_LIMIT {
        // backward at the upper bound, where n stops
        step = -step;
    }
    let mut t2 = th.to_vec();
    t2[q] += step;
    let c1 = bw_column(u, bw, &t2);
    c1.iter()
        .zip(base.iter())
        .map(|(x, y)| a_coef * (x - y) / step)
        .collect()
}

const BOUC_WEN_PARAMS: [&str; 3] = [
    "bouc_wen.log_b",
    "bouc_wen.gamma_ratio",
    "bouc_wen.exponent",
];

/// The static starting grid of a Bouc-Wen term: B range 0.1..10, Gamma / B -0.5..0.5, and,
/// where the exponent is free, n = 1 (it is freed once the others have settled:
/// [`TermFit::optional_params`]).
fn bouc_wen_grid(exponent: bool) -> Vec<Vec<f64>> {
    let mut g = Vec::new();
    for br in [0.1f64, 0.3, 1.0, 3.0, 10.0] {
        for ratio in [-0.5f64, 0.0, 0.5] {
            let mut p = vec![br.ln(), ratio.atanh()];
            if exponent {
                p.push(0.0);
            }
            g.push(p);
        }
    }
    g
}

/// Prandtl-Ishlinskii plays (weights >= 0, sharing the sign of the path's gain), for the default
/// operator the ramps of a static input map (weights of either sign) and one Bouc-Wen column
/// (its weight >= 0, the loop mirrored on a negative path: [`Bw`]). Column order: plays, ramps, Bouc-Wen.
///
/// The plays and ramps are kept whole up to [`CACHED_COLUMNS_BYTES`]; beyond, a long record's
/// columns are computed where asked, a block of rows at a time ([`TermFit::columns_block`]),
/// the plays resuming from their states.
struct PiTerm<'a> {
    u: &'a [f64],
    thresholds: Vec<f64>,
    sign: f64,
    /// Knots z_j of the static input map (its ramps are S_{z_j}(u)).
    knots: Vec<f64>,
    /// The plays and ramps over the whole record, kept when they take at most
    /// [`CACHED_COLUMNS_BYTES`] (they do not depend on the parameters).
    cached: Option<Vec<Vec<f64>>>,
    /// The Bouc-Wen column at the last parameters it was computed for (the Jacobian's
    /// derivatives follow an evaluation at the same point).
    bw_memo: BwMemo,
    /// The Bouc-Wen column (its input range and the path's sign), when there is one.
    bw: Option<Bw>,
    /// The split of the plays' envelopes (generalised plays), fixed or fitted.
    split: Split,
}

/// The envelopes' split e(u) = c0 + c1 u + c2 u^2 of a term's plays
/// ([`PrandtlIshlinskiiSpec::envelope_split`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Split {
    /// Classical plays.
    None,
    /// A split given (the operator of a first stage, [`OutputMapTerm`]).
    Fixed([f64; 3]),
    /// Three parameters after the Bouc-Wen column's, e(u) = R (p0 + p1 u / R + p2 (u / R)^2)
    /// with R the input's range, each kept inside [-[`SPLIT_LIMIT`], [`SPLIT_LIMIT`]].
    Free { range: f64 },
}

/// The largest normalised split coefficient ([`Split::Free`]): e(u) at most the input's range.
const SPLIT_LIMIT: f64 = 1.0;

/// The names of the envelope split's parameters ([`Split::Free`]).
pub const SPLIT_PARAMS: [&str; 3] = [
    "generalised_play.split0",
    "generalised_play.split1",
    "generalised_play.split2",
];

/// How a pass over a term's plays runs.
#[derive(Debug, Clone, Copy)]
struct PlayPass {
    /// The plays generalised by this split (`None`: classical plays).
    split: Option<[f64; 3]>,
    /// The groups of plays in parallel or (false: under a lock, where a thread must not take
    /// other parallel work) one after the other.
    parallel: bool,
}

impl Split {
    fn n_params(&self) -> usize {
        if matches!(self, Split::Free { .. }) {
            3
        } else {
            0
        }
    }

    /// The coefficients [c0, c1, c2] at the term's split parameters `p` (None: classical).
    fn at(&self, p: &[f64]) -> Option<[f64; 3]> {
        match *self {
            Split::None => None,
            Split::Fixed(c) => Some(c),
            Split::Free { range } => {
                let c = [range * p[0], p[1], p[2] / range];
                c.iter().any(|&v| v != 0.0).then_some(c)
            }
        }
    }
}

/// Ramps of the static input map beside `plays` plays: 8 with 39 plays, fewer on the shorter
/// records that get fewer plays, none with 3 plays or fewer.
pub fn input_map_ramps(plays: usize) -> usize {
    match plays {
        0..=3 => 0,
        4..=5 => 2,
        6..=9 => 4,
        10..=19 => 6,
        _ => 8,
    }
}

/// Knots spread evenly inside the input's range [min u, max u] (never exactly 0, where the
/// ramp is the input itself, the path's gain column).
pub fn input_map_knots(u: &[f64], n: usize) -> Vec<f64> {
    let (lo, hi) = u
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return Vec::new();
    }
    (1..=n)
        .map(|j| lo + (hi - lo) * j as f64 / (n + 1) as f64)
        .map(|z| if z == 0.0 { 1e-9 * (hi - lo) } else { z })
        .collect()
}

/// [`input_map_knots`] kept only where the samples determine the map's slope on each side:
/// every interval between consecutive kept knots holds a value of `u` (the first one two), as
/// a linear spline's coefficients ask (Schoenberg-Whitney). A continuous input keeps them
/// all; a staircase of a few levels keeps those between levels (the ramps of the others would
/// be fitted to nothing and bend the map between levels the record never visits).
/// `values` are the distinct values of `u` ([`levels`]).
pub fn input_map_knots_by_levels(u: &[f64], values: &[f64], n: usize) -> Vec<f64> {
    let even = input_map_knots(u, n);
    let mut kept = Vec::with_capacity(even.len());
    let (mut next, mut need) = (0, 2);
    for z in even {
        let before = values[next..].partition_point(|&v| v < z);
        if before >= need {
            kept.push(z);
            next += before;
            need = 1;
        }
    }
    // the last interval holds max u, above every knot
    kept
}

/// The optional Bouc-Wen column beside a Prandtl-Ishlinskii term (the default operator):
/// its nonlinear parameters, start grid, column, and the extra path it writes when its
/// weight is positive.
fn bw_n_params(bw: Option<Bw>) -> usize {
    match bw {
        Some(b) if b.exponent => 3,
        Some(_) => 2,
        None => 0,
    }
}

fn bw_param_names(bw: Option<Bw>) -> Vec<&'static str> {
    BOUC_WEN_PARAMS[..bw_n_params(bw)].to_vec()
}

fn bw_param_bounds(bw: Option<Bw>) -> Vec<(f64, f64)> {
    let free = (f64::NEG_INFINITY, f64::INFINITY);
    match bw_n_params(bw) {
        3 => vec![free, free, (0.0, EXPONENT_LIMIT)],
        k => vec![free; k],
    }
}

fn bw_start_grid(bw: Option<Bw>) -> Vec<Vec<f64>> {
    bw.map_or_else(Vec::new, |b| bouc_wen_grid(b.exponent))
}

fn bw_extra_path(bw: Option<Bw>, th: &[f64], c: f64) -> Option<Box<dyn EffectSpec>> {
    let bw = bw?;
    (c > 0.0).then(|| Box::new(bw_spec(bw, th, c, 0.0)) as Box<dyn EffectSpec>)
}

/// A term keeps its parameter-free columns (the plays and ramps) over the whole record up to
/// this size; beyond, it computes them a block at a time where they are asked for.
const CACHED_COLUMNS_BYTES: usize = 128 << 20;

/// Plays computed side by side in [`PiTerm::columns_block`].
const PLAYS_SIDE_BY_SIDE: usize = 8;

/// The last Bouc-Wen column computed, with its parameters.
type BwMemo = std::sync::Mutex<Option<(Vec<f64>, std::sync::Arc<Vec<f64>>)>>;

/// The column of `bw` at `th`, from `memo` when it holds the column of `th`.
fn bw_memoized(u: &[f64], bw: Bw, th: &[f64], memo: &BwMemo) -> std::sync::Arc<Vec<f64>> {
    let mut m = memo.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((at, col)) = m.as_ref() {
        if at.len() == th.len() && at.iter().zip(th).all(|(a, b)| a.to_bits() == b.to_bits()) {
            return col.clone();
        }
    }
    let col = std::sync::Arc::new(bw_column(u, bw, th));
    *m = Some((th.to_vec(), col.clone()));
    col
}

impl<'a> PiTerm<'a> {
    fn new(u: &'a [f64], thresholds: Vec<f64>, sign: f64, knots: Vec<f64>, bw: Option<Bw>) -> Self {
        Self::with_split(u, thresholds, sign, knots, bw, Split::None)
    }

    fn with_split(
        u: &'a [f64],
        thresholds: Vec<f64>,
        sign: f64,
        knots: Vec<f64>,
        bw: Option<Bw>,
        split: Split,
    ) -> Self {
        let mut t = PiTerm {
            u,
            thresholds,
            sign,
            knots,
            cached: None,
            bw_memo: BwMemo::default(),
            bw,
            split,
        };
        let bytes = (t.thresholds.len() + t.knots.len()) * u.len() * 8;
        if bytes <= CACHED_COLUMNS_BYTES {
            let mut z = vec![0.0; t.thresholds.len()];
            let mut cols = vec![Vec::new(); t.thresholds.len() + t.knots.len()];
            let all = vec![true; cols.len()];
            let e = t.split.at(&[0.0; 3]);
            t.columns_on(0..u.len(), &mut z, None, e, &mut cols, &all);
            t.cached = Some(cols);
        }
        t
    }

    /// The envelopes' split at the term's parameters `th` (None: classical plays).
    fn split_at(&self, th: &[f64]) -> Option<[f64; 3]> {
        let at = bw_n_params(self.bw);
        self.split
            .at(th.get(at..at + self.split.n_params()).unwrap_or(&[]))
    }

    /// The Bouc-Wen column at `th`, when the term has one.
    fn bw_at(&self, th: &[f64]) -> Option<std::sync::Arc<Vec<f64>>> {
        self.bw.map(|bw| bw_memoized(self.u, bw, th, &self.bw_memo))
    }

    /// The plays (from states `z`, updated), the ramps and the Bouc-Wen column (from
    /// `bw_whole`, the column over the whole record) on the input samples `u` at `rows`,
    /// written into `out` (one buffer per column); only the columns where `wanted` is set (a
    /// play left out keeps its state: it is left out of the whole pass). The plays are
    /// generalised ones where `split` is given.
    fn columns_on(
        &self,
        rows: Range<usize>,
        z: &mut [f64],
        bw_whole: Option<&[f64]>,
        split: Option<[f64; 3]>,
        out: &mut [Vec<f64>],
        wanted: &[bool],
    ) {
        let pass = PlayPass {
            split,
            parallel: true,
        };
        self.columns_on_with(rows, z, bw_whole, out, wanted, pass)
    }

    /// [`PiTerm::columns_on`], run as `pass` says.
    fn columns_on_with(
        &self,
        rows: Range<usize>,
        z: &mut [f64],
        bw_whole: Option<&[f64]>,
        out: &mut [Vec<f64>],
        wanted: &[bool],
        pass: PlayPass,
    ) {
        let PlayPass { split, parallel } = pass;
        let u = &self.u[rows.clone()];
        // generalised plays: each sample's thresholds r - e(u)
        let shift: Option<Vec<f64>> =
            split.map(|c| u.iter().map(|&v| envelope_split(&c, v)).collect());
        let sign = self.sign;
        let np = self.thresholds.len();
        let (plays, rest) = out.split_at_mut(np);
        let mut jobs: Vec<(f64, &mut f64, &mut Vec<f64>)> = self
            .thresholds
            .iter()
            .zip(z.iter_mut())
            .zip(plays.iter_mut())
            .zip(wanted)
            .filter(|(_, w)| **w)
            .map(|(((&r, z), o), _)| (r, z, o))
            .collect();
        // eight plays side by side: their recursions interleave (each play's arithmetic is
        // that of `play_operator` alone)
        let run = |group: &mut [(f64, &mut f64, &mut Vec<f64>)]| {
            for (_, _, o) in group.iter_mut() {
                o.clear();
                o.reserve(u.len());
            }
            if let Some(e) = &shift {
                for (r, z, o) in group.iter_mut() {
                    o.extend(u.iter().zip(e).map(|(&v, &e)| {
                        **z = play_operator(v, *r - e, **z);
                        **z
                    }));
                }
            } else if let [a0, a1, a2, a3, a4, a5, a6, a7] = group {
                let r = [a0.0, a1.0, a2.0, a3.0, a4.0, a5.0, a6.0, a7.0];
                let mut zz = [*a0.1, *a1.1, *a2.1, *a3.1, *a4.1, *a5.1, *a6.1, *a7.1];
                for &v in u {
                    for l in 0..PLAYS_SIDE_BY_SIDE {
                        zz[l] = play_operator(v, r[l], zz[l]);
                    }
                    a0.2.push(zz[0]);
                    a1.2.push(zz[1]);
                    a2.2.push(zz[2]);
                    a3.2.push(zz[3]);
                    a4.2.push(zz[4]);
                    a5.2.push(zz[5]);
                    a6.2.push(zz[6]);
                    a7.2.push(zz[7]);
                }
                for (a, z) in group.iter_mut().zip(zz) {
                    *a.1 = z;
                }
            } else {
                for (r, z, o) in group.iter_mut() {
                    o.extend(u.iter().map(|&v| {
                        **z = play_operator(v, *r, **z);
                        **z
                    }));
                }
            }
            if sign <= 0.0 {
                for (_, _, o) in group.iter_mut() {
                    o.iter_mut().for_each(|v| *v = -*v);
                }
            }
        };
        if parallel {
            jobs.par_chunks_mut(PLAYS_SIDE_BY_SIDE).for_each(run);
        } else {
            jobs.chunks_mut(PLAYS_SIDE_BY_SIDE).for_each(run);
        }
        for ((o, &k), _) in rest
            .iter_mut()
            .zip(&self.knots)
            .zip(&wanted[np..])
            .filter(|(_, w)| **w)
        {
            o.clear();
            o.extend(u.iter().map(|&x| dead_zone(x, k)));
        }
        let at = self.knots.len();
        if let (Some(b), Some(o), Some(true)) = (bw_whole, rest.get_mut(at), wanted.get(np + at)) {
            o.clear();
            o.extend_from_slice(&b[rows]);
        }
    }

    /// d/dp_j of sum_i coef_i (sign P_i[u]) over the whole record, p_j the term's `j`-th split
    /// parameter: a play on its ascending edge u + e(u) - r moves with de/dp_j, on its
    /// descending edge u - e(u) + r against it, and holds its derivative in between (exact
    /// but at the switches, as the play's own derivative in its threshold).
    fn split_derivative(&self, th: &[f64], j: usize, coef: &[f64]) -> Vec<f64> {
        let mut sum = vec![0.0; self.u.len()];
        let Split::Free { range } = self.split else {
            return sum;
        };
        let c = self.split_at(th).unwrap_or([0.0; 3]);
        // c = [range p0, p1, p2 / range] (`Split::at`)
        let de = |v: f64| match j {
            0 => range,
            1 => v,
            _ => v * v / range,
        };
        for (&r, &k) in self.thresholds.iter().zip(coef) {
            if k == 0.0 {
                continue;
            }
            let w = if self.sign <= 0.0 { -k } else { k };
            let (mut z, mut dz) = (0.0, 0.0);
            for (s, &v) in sum.iter_mut().zip(self.u) {
                let t = r - envelope_split(&c, v);
                // play_operator: max(v - t, min(v + t, z))
                if v + t < z {
                    z = v + t;
                    dz = -de(v);
                }
                if v - t > z {
                    z = v - t;
                    dz = de(v);
                }
                *s += w * dz;
            }
        }
        sum
    }

    /// Which columns must have c >= 0: the plays and the Bouc-Wen column.
    fn nonnegative(&self) -> Vec<bool> {
        let mut v = vec![true; self.thresholds.len()];
        v.extend(std::iter::repeat_n(false, self.knots.len()));
        if self.bw.is_some() {
            v.push(true);
        }
        v
    }
}

impl TermFit for PiTerm<'_> {
    /// The plays: their weights sample the Prandtl-Ishlinskii density at evenly spaced
    /// thresholds (three or more have a second difference).
    fn density_columns(&self) -> Option<Range<usize>> {
        (self.thresholds.len() >= 3).then_some(0..self.thresholds.len())
    }
    fn n_columns(&self) -> usize {
        self.thresholds.len() + self.knots.len() + usize::from(self.bw.is_some())
    }
    fn n_params(&self) -> usize {
        bw_n_params(self.bw) + self.split.n_params()
    }
    fn param_names(&self) -> Vec<&'static str> {
        let mut names = bw_param_names(self.bw);
        if self.split.n_params() > 0 {
            names.extend(SPLIT_PARAMS);
        }
        names
    }
    fn param_bounds(&self) -> Vec<(f64, f64)> {
        let mut b = bw_param_bounds(self.bw);
        b.extend(std::iter::repeat_n(
            (-SPLIT_LIMIT, SPLIT_LIMIT),
            self.split.n_params(),
        ));
        b
    }
    /// The Bouc-Wen column's grid, the plays classical (a split of 0) at every point.
    fn start_grid(&self) -> Vec<Vec<f64>> {
        let mut g = bw_start_grid(self.bw);
        let n = self.split.n_params();
        if n > 0 {
            if g.is_empty() {
                g.push(Vec::new());
            }
            g.iter_mut()
                .for_each(|p| p.extend(std::iter::repeat_n(0.0, n)));
        }
        g
    }
    fn columns<'s>(&'s self, th: &[f64]) -> Vec<Column<'s>> {
        let bw = self.bw_at(th);
        let mut z = vec![0.0; self.thresholds.len()];
        let mut out = vec![Vec::new(); self.n_columns()];
        let all = vec![true; out.len()];
        let bw = bw.as_ref().map(|c| c.as_slice());
        let split = self.split_at(th);
        self.columns_on(0..self.u.len(), &mut z, bw, split, &mut out, &all);
        out.into_iter()
            .zip(self.nonnegative())
            .map(|(c, nonneg)| (Cow::Owned(c), nonneg))
            .collect()
    }
    fn columns_block(
        &self,
        th: &[f64],
        rows: Range<usize>,
        state: &mut TermState,
        out: &mut [Vec<f64>],
        wanted: &[bool],
    ) -> Vec<bool> {
        if rows.start == 0 {
            state.carry = vec![0.0; self.thresholds.len()];
        }
        let at = self.thresholds.len() + self.knots.len();
        let bw = if wanted.get(at) == Some(&true) {
            self.bw_at(th)
        } else {
            None
        };
        let bw = bw.as_ref().map(|c| c.as_slice());
        let split = self.split_at(th);
        // the kept columns are those at the term's own split (0 where it is fitted)
        let kept = self
            .cached
            .as_ref()
            .filter(|_| split == self.split.at(&[0.0; 3]));
        match kept {
            Some(cached) => {
                for ((o, c), _) in out.iter_mut().zip(cached).zip(wanted).filter(|(_, w)| **w) {
                    o.clear();
                    o.extend_from_slice(&c[rows.clone()]);
                }
                if let (Some(b), Some(o)) = (bw, out.get_mut(at)) {
                    o.clear();
                    o.extend_from_slice(&b[rows]);
                }
            }
            None => self.columns_on(rows, &mut state.carry, bw, split, out, wanted),
        }
        self.nonnegative()
    }
    fn derivative(&self, th: &[f64], q: usize, coef: &[f64]) -> Vec<f64> {
        let nbw = bw_n_params(self.bw);
        if q >= nbw {
            return self.split_derivative(th, q - nbw, coef);
        }
        let bw = self
            .bw
            .expect("a term with parameters has its Bouc-Wen column");
        let base = bw_memoized(self.u, bw, th, &self.bw_memo);
        bouc_wen_derivative(self.u, th, q, bw, &base, coef[coef.len() - 1])
    }
    fn spec(&self, th: &[f64], gain: f64, coef: &[f64]) -> TermSpec {
        let n = self.thresholds.len();
        let m = self.knots.len();
        if n + m == 0 && self.bw.is_none() {
            return TermSpec {
                spec: Some(Box::new(HysteresisSpec::Linear(LinearSpec { gain }))),
                extra_paths: Vec::new(),
            };
        }
        let input_map = (m > 0).then(|| DeadZoneSpec {
            thresholds: self.knots.clone(),
            weights: coef[n..n + m].to_vec(),
        });
        let spec = PrandtlIshlinskiiSpec {
            envelope_split: self.split_at(th),
            envelopes: None,
            linear_weight: gain,
            thresholds: self.thresholds.clone(),
            weights: coef[..n].iter().map(|w| self.sign * w).collect(),
            initial_state: 0.0,
            input_map,
            dead_zones: None,
        };
        let mut extra_paths: Vec<Box<dyn EffectSpec>> = Vec::new();
        if self.bw.is_some() {
            extra_paths.extend(bw_extra_path(self.bw, th, coef[n + m]));
        }
        TermSpec {
            spec: Some(Box::new(HysteresisSpec::PrandtlIshlinskii(spec))),
            extra_paths,
        }
    }
}

/// Knots of the dead-zone map on a first-stage Prandtl-Ishlinskii output z, per side of 0, as
/// fractions of the largest value z reaches on that side: `k` knots at j / (k + 1).
pub fn output_map_knot_fractions(k: usize) -> Vec<f64> {
    (1..=k).map(|j| j as f64 / (k + 1) as f64).collect()
}

/// Knots per side of the dead-zone map beside `plays` plays: 15 with 39 plays, 7 with 19, 3
/// with fewer (a short record's parsimonious model). A saturating loop's slope changes at
/// thresholds the fit does not know; a piecewise-linear map with more knots follows it closer
/// (a prototype of the joint fit on a 20,000-sample saturating Prandtl-Ishlinskii record of
/// the development zoo, noise 0.08 % of the range: 3, 7 and 15 knots per side left 5, 2.2 and
/// 1.3 times the noise).
pub fn output_map_knots(plays: usize) -> usize {
    match plays {
        0..=9 => 3,
        10..=19 => 7,
        _ => 15,
    }
}

/// Kuhnen's modified Prandtl-Ishlinskii operator as the second stage of a two-stage fit:
/// the operator of the first stage, z = w0 u + sum_i w_i P_{r_i}[u] (+ its static input map's
/// ramps), goes through a dead-zone superposition S[z] = c0 z + sum_j c_j S_{d_j}(z) (a
/// saturating or asymmetric loop: the branches' slopes change along the output, which plays on
/// the input cannot give), beside the path's gain and, on the default operator's positive
/// paths, the Bouc-Wen column. S is fitted as a piecewise-linear map through 0 with a
/// non-negative slope between consecutive knots (non-negative least squares): it increases,
/// as the operator must to be invertible, and its slopes convert to the dead zones' weights.
///
/// The operator's weights can be refitted with S (Gauss-Newton on z[w] = z0 + sum_q theta_q
/// x_q, d S[z] / d theta_q = S'(z) x_q, with x_q = u, the plays and the ramps): the first
/// stage fitted them to the output itself, which S bends. Their parameters are named
/// [`SECOND_STAGE_PARAM`] and start at 0. The knots stay where the first stage's z put them.
///
/// K. Kuhnen, "Modeling, identification and compensation of complex hysteretic
/// nonlinearities: a modified Prandtl-Ishlinskii approach", European Journal of Control
/// 9(4):407-418, 2003.
struct OutputMapTerm<'a> {
    u: &'a [f64],
    /// The first stage's operator (no dead zones).
    pi: PrandtlIshlinskiiSpec,
    /// Its output over `u` (theta = 0).
    z0: std::sync::Arc<Vec<f64>>,
    /// The operator's own columns x_q (after u): the plays at its thresholds, then the ramps
    /// of its input map (a positive Prandtl-Ishlinskii term's columns: kept whole on a short
    /// record, computed where asked on a long one).
    x: PiTerm<'a>,
    /// The Bouc-Wen column at the last parameters asked.
    bw_memo: BwMemo,
    /// The nonzero knots d_j, increasing.
    knots: Vec<f64>,
    /// The path's sign, which every play weight keeps ([`OutputMapTerm::weights_of`]).
    sign: f64,
    bw: Option<Bw>,
    /// S'(z) per sample at the last (weights, slopes) asked: every weight's derivative uses it.
    slope: std::sync::Mutex<Option<SlopeAt>>,
    /// The samples the fit sees (a cross-validation's held-out block left out).
    held_out: Option<Range<usize>>,
    /// On a part of blocks, the rows the fit leaves out (`PreviousPath::left_out`).
    left_out: Option<std::sync::Arc<Vec<bool>>>,
    /// The intervals' slopes tied ([`OutputMapTerm::ties_of`]) at the last weights asked.
    ties: std::sync::Mutex<Option<TiesAt>>,
}

/// The intervals' ties of the dead-zone map at the operator weights that gave them.
struct TiesAt {
    weights: Vec<f64>,
    ties: std::sync::Arc<Vec<usize>>,
}

/// The slope S'(z[k]) of the dead-zone map at each sample, for the operator weights and
/// map slopes that produced it.
struct SlopeAt {
    weights: Vec<f64>,
    slopes: Vec<f64>,
    at: std::sync::Arc<Vec<f64>>,
}

/// Rows of a block of the operator's output computed at once ([`OutputMapTerm::z`]).
const Z_ROWS: usize = 1 << 16;

/// The slopes of S below the smallest slope kept (relative to its steepest slope): the
/// dead-zone map must increase strictly.
const MIN_RELATIVE_SLOPE: f64 = 1e-6;

/// The fewest fitted samples of the operator's output z inside an interval of S for the
/// interval's slope to be fitted; an interval with fewer takes the slope of its neighbour
/// nearer to 0 ([`OutputMapTerm::ties_of`]). The operator's weights move z while the map is
/// fitted, and a slope fixed by the few samples that poke into an interval is free to take any
/// value there (a 2-DoF member of development zoo seed 25: a slope 10^6 times the others on an
/// interval that five samples entered by 2e-10 of z; the fit's free run R^2 0.99997, the
/// model's -2.1, its other slopes floored at 10^-6 of that one).
pub const MAP_INTERVAL_SAMPLES: usize = 10;

impl<'a> OutputMapTerm<'a> {
    fn new(
        setup: &PathSetup<'a>,
        prev: &super::fitting::PreviousPath,
        range: f64,
    ) -> Option<OutputMapTerm<'a>> {
        let Some(HysteresisSpec::PrandtlIshlinskii(pi)) =
            prev.spec.as_any().downcast_ref::<HysteresisSpec>()
        else {
            return None;
        };
        // the second stage refits classical or split plays (not tanh envelopes) under its map
        if pi.dead_zones.is_some() || pi.initial_state != 0.0 || pi.envelopes.is_some() {
            return None;
        }
        let z = prev.output.as_slice();
        let (lo, hi) = prev.range.unwrap_or_else(|| {
            super::fitting::PreviousPath::fitted_range(z, setup.held_out.as_ref())
        });
        let mut knots = Vec::new();
        for f in output_map_knot_fractions(output_map_knots(pi.thresholds.len())) {
            if hi > 0.0 {
                knots.push(f * hi);
            }
            if lo < 0.0 {
                knots.push(f * lo);
            }
        }
        knots.sort_by(f64::total_cmp);
        let ramps = pi
            .input_map
            .as_ref()
            .map_or_else(Vec::new, |m| m.thresholds.clone());
        let split = pi.envelope_split.map_or(Split::None, Split::Fixed);
        let x = PiTerm::with_split(setup.u, pi.thresholds.clone(), 1.0, ramps, None, split);
        Some(OutputMapTerm {
            u: setup.u,
            pi: pi.clone(),
            z0: prev.output.clone(),
            x,
            bw_memo: BwMemo::default(),
            knots,
            sign: setup.sign,
            bw: (setup.variant == 0).then_some(Bw {
                range,
                sign: setup.sign,
                exponent: false,
            }),
            slope: std::sync::Mutex::new(None),
            held_out: prev
                .left_out
                .is_none()
                .then(|| setup.held_out.clone())
                .flatten(),
            left_out: prev.left_out.clone(),
            ties: std::sync::Mutex::new(None),
        })
    }

    /// The number of the operator's columns x_q.
    fn x_len(&self) -> usize {
        self.x.n_columns()
    }

    /// The operator's column x_q over the whole record.
    fn x_whole(&self, q: usize) -> Cow<'_, [f64]> {
        if let Some(c) = &self.x.cached {
            return Cow::Borrowed(c[q].as_slice());
        }
        let mut out = vec![Vec::new(); self.x_len()];
        let mut wanted = vec![false; out.len()];
        wanted[q] = true;
        let mut z = vec![0.0; self.x.thresholds.len()];
        self.x.columns_on(
            0..self.u.len(),
            &mut z,
            None,
            self.x.split_at(&[]),
            &mut out,
            &wanted,
        );
        Cow::Owned(std::mem::take(&mut out[q]))
    }

    /// The operator's output at weights `w` on the rows `rows` (from the plays' states `z`,
    /// updated; `x` the buffers of its columns), added in the order of [`OutputMapTerm::z`].
    fn z_block(
        &self,
        w: &[f64],
        rows: Range<usize>,
        z: &mut [f64],
        x: &mut [Vec<f64>],
    ) -> Vec<f64> {
        self.z_block_with(w, rows, z, x, true)
    }

    /// [`OutputMapTerm::z_block`], the plays in parallel or not ([`PiTerm::columns_on_with`]).
    fn z_block_with(
        &self,
        w: &[f64],
        rows: Range<usize>,
        z: &mut [f64],
        x: &mut [Vec<f64>],
        parallel: bool,
    ) -> Vec<f64> {
        let wanted: Vec<bool> = w[1..].iter().map(|&t| t != 0.0).collect();
        let cols = self.x_block(rows.clone(), z, x, &wanted, parallel);
        self.z_of(w, rows, &cols)
    }

    /// The operator's columns x_q on the rows `rows` where `wanted` (from the plays' states
    /// `z`, updated; `x` the buffers), or all of them where they are kept.
    fn x_block<'s>(
        &'s self,
        rows: Range<usize>,
        z: &mut [f64],
        x: &'s mut [Vec<f64>],
        wanted: &[bool],
        parallel: bool,
    ) -> Vec<&'s [f64]> {
        match &self.x.cached {
            Some(c) => c.iter().map(|c| &c[rows.clone()]).collect(),
            None => {
                if wanted.iter().any(|w| *w) {
                    let pass = PlayPass {
                        split: self.x.split_at(&[]),
                        parallel,
                    };
                    self.x.columns_on_with(rows, z, None, x, wanted, pass);
                }
                x.iter().map(Vec::as_slice).collect()
            }
        }
    }

    /// The operator's output at weights `w` on the rows `rows` from its columns `x` there.
    fn z_of(&self, w: &[f64], rows: Range<usize>, x: &[&[f64]]) -> Vec<f64> {
        let mut out = self.z0[rows.clone()].to_vec();
        if w.iter().all(|&t| t == 0.0) {
            return out;
        }
        for (v, &u) in out.iter_mut().zip(&self.u[rows]) {
            *v += w[0] * u;
        }
        for (col, &t) in x.iter().zip(&w[1..]) {
            if t != 0.0 {
                for (v, &x) in out.iter_mut().zip(col.iter()) {
                    *v += t * x;
                }
            }
        }
        out
    }

    /// S'(v) of the map of slopes `s` (0 on a knot).
    fn slope_of(&self, bounds: &[(f64, f64)], s: &[f64], v: f64) -> f64 {
        self.interval_of(bounds, v).map_or(0.0, |i| s[i])
    }

    /// The interval of S (of `bounds`) that `v` lies inside; `None` on a knot.
    fn interval_of(&self, bounds: &[(f64, f64)], v: f64) -> Option<usize> {
        let i = self.knots.partition_point(|&d| d < v);
        (bounds[i].0 < v && v < bounds[i].1).then_some(i)
    }

    /// The map's columns S_j(z) - S_j(0) of the operator's output `z` where `wanted`, into
    /// `out`; an interval tied to another (`ties`) adds its column to that one's and has none.
    fn map_columns(&self, z: &[f64], out: &mut [Vec<f64>], wanted: &[bool], ties: &[usize]) {
        for (o, _) in out.iter_mut().zip(wanted).filter(|(_, w)| **w) {
            o.clear();
            o.resize(z.len(), 0.0);
        }
        for (j, (a, b)) in self.bounds().into_iter().enumerate() {
            let r = ties[j];
            if !wanted[r] {
                continue;
            }
            let at0 = 0.0f64.clamp(a, b);
            for (o, &v) in out[r].iter_mut().zip(z) {
                *o += v.clamp(a, b) - at0;
            }
        }
    }

    /// Per interval of S, the interval whose slope it takes: itself where at least
    /// [`MAP_INTERVAL_SAMPLES`] fitted samples of `z` lie inside it, else its neighbour's
    /// nearer to 0 (that neighbour's own, in turn); the interval around 0 always its own.
    fn ties_of(&self, z: &[f64]) -> Vec<usize> {
        let bounds = self.bounds();
        let mut count = vec![0usize; bounds.len()];
        for (k, &v) in z.iter().enumerate() {
            if !self.fitted(k) {
                continue;
            }
            if let Some(i) = self.interval_of(&bounds, v) {
                count[i] += 1;
            }
        }
        let mid = self.knots.iter().take_while(|&&d| d < 0.0).count();
        let mut ties: Vec<usize> = (0..bounds.len()).collect();
        for j in mid + 1..bounds.len() {
            if count[j] < MAP_INTERVAL_SAMPLES {
                ties[j] = ties[j - 1];
            }
        }
        for j in (0..mid).rev() {
            if count[j] < MAP_INTERVAL_SAMPLES {
                ties[j] = ties[j + 1];
            }
        }
        ties
    }

    /// Whether the fit sees row `k` (neither in the held-out block nor left out).
    fn fitted(&self, k: usize) -> bool {
        !(self.held_out.as_ref().is_some_and(|r| r.contains(&k))
            || self.left_out.as_ref().is_some_and(|m| m[k]))
    }

    /// [`OutputMapTerm::ties_of`] the operator's output at weights `w` (cached), from that
    /// output `z` where the caller has it at hand.
    fn ties_at(&self, w: &[f64], z: Option<&[f64]>) -> std::sync::Arc<Vec<usize>> {
        {
            let cache = self.ties.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(c) = cache.as_ref() {
                if c.weights == w {
                    return c.ties.clone();
                }
            }
        }
        let t = std::sync::Arc::new(match z {
            Some(z) => self.ties_of(z),
            None => self.ties_of(&self.z(w)),
        });
        *self.ties.lock().unwrap_or_else(|e| e.into_inner()) = Some(TiesAt {
            weights: w.to_vec(),
            ties: t.clone(),
        });
        t
    }

    /// The slopes of the intervals, those of the tied ones taken from their neighbours.
    fn tied(s: &[f64], ties: &[usize]) -> Vec<f64> {
        ties.iter().map(|&r| s[r]).collect()
    }

    /// The intervals of S: (-inf, d_1], [d_1, d_2], ..., [d_k, inf).
    fn bounds(&self) -> Vec<(f64, f64)> {
        let mut b = vec![f64::NEG_INFINITY];
        b.extend(&self.knots);
        b.push(f64::INFINITY);
        b.windows(2).map(|w| (w[0], w[1])).collect()
    }

    /// The operator's output at weights `w` (increments over the first stage's), computed a
    /// block of rows at a time where the operator's columns are not kept, on the calling
    /// thread alone.
    fn z(&self, w: &[f64]) -> Cow<'_, [f64]> {
        if w.iter().all(|&t| t == 0.0) {
            return Cow::Borrowed(self.z0.as_slice());
        }
        let n = self.u.len();
        let mut z = Vec::with_capacity(n);
        let mut states = vec![0.0; self.x.thresholds.len()];
        let mut x = vec![Vec::new(); self.x_len()];
        let mut at = 0;
        while at < n {
            let end = (at + Z_ROWS).min(n);
            // on this thread alone: `slope_at` calls this under its lock
            z.extend(self.z_block_with(w, at..end, &mut states, &mut x, false));
            at = end;
        }
        Cow::Owned(z)
    }

    /// The operator-weight increments of this term's parameters, a play's held where its
    /// weight would change sign: the first stage's play weights share the path's sign (a
    /// monotone operator, Kuhnen's condition for the inverse), and so do the second stage's.
    /// A play that the training input barely moves (a threshold near its half swing) is
    /// otherwise free to take a large weight of the other sign that cancels the output map's
    /// bend in training and blows up where a test input swings wider (held-out zoo seed 1019,
    /// member 23: a weight of -3.0 beside first-stage weights of 0.05-0.14, test R^2 -11.6).
    /// The fit keeps the increments inside [`OutputMapTerm::play_bounds`]; the model holds
    /// any increment given outside them (a start, a copy) on its bound too.
    fn weights_of(&self, th: &[f64]) -> Vec<f64> {
        let mut w = th[bw_n_params(self.bw)..].to_vec();
        for (t, &w0) in w[1..].iter_mut().zip(&self.pi.weights) {
            let (lo, hi) = self.play_bounds(w0);
            *t = t.clamp(lo, hi);
        }
        w
    }

    /// The interval of a play's increment that keeps its weight `w0 + increment` of the
    /// path's sign (`w0`: the first stage's weight, of that sign).
    fn play_bounds(&self, w0: f64) -> (f64, f64) {
        if self.sign > 0.0 {
            (-w0, f64::INFINITY)
        } else {
            (f64::NEG_INFINITY, -w0)
        }
    }

    /// Whether the operator parameter `q` (of this term's) is a play held on its bound
    /// ([`OutputMapTerm::weights_of`]): its derivative is 0.
    fn held(&self, th: &[f64], q: usize) -> bool {
        let k = q.wrapping_sub(bw_n_params(self.bw) + 1);
        self.pi.weights.get(k).is_some_and(|&w0| {
            let (lo, hi) = self.play_bounds(w0);
            th[q] < lo || th[q] > hi
        })
    }

    /// S'(z[k]) at operator weights `w` and map slopes `s` (cached: each weight's derivative
    /// asks for the same).
    fn slope_at(&self, w: &[f64], s: &[f64]) -> std::sync::Arc<Vec<f64>> {
        let mut cache = self.slope.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(c) = cache.as_ref() {
            if c.weights == w && c.slopes == s {
                return c.at.clone();
            }
        }
        let z = self.z(w);
        let bounds = self.bounds();
        let s = Self::tied(s, &self.ties_at(w, Some(&z)));
        let at: Vec<f64> = z.iter().map(|&v| self.slope_of(&bounds, &s, v)).collect();
        let at = std::sync::Arc::new(at);
        *cache = Some(SlopeAt {
            weights: w.to_vec(),
            slopes: s.to_vec(),
            at: at.clone(),
        });
        at
    }

    /// The dead-zone superposition (thresholds with 0 among them, weights) of the slopes
    /// `s` of S on the intervals between the knots, and beyond the operator's output range
    /// over the fitted samples `(lo, hi)` the gentlest slope of S on that side up to there
    /// (see [`OutputMapTerm::spec`]).
    fn dead_zones(&self, s: &[f64], (lo, hi): (f64, f64)) -> DeadZoneSpec {
        // the interval around 0: the first whose upper bound is above 0
        let mid = self.knots.iter().take_while(|&&d| d < 0.0).count();
        let steepest = s.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let floor = MIN_RELATIVE_SLOPE * steepest.max(f64::MIN_POSITIVE);
        let s: Vec<f64> = s.iter().map(|v| v.max(floor)).collect();
        let mut thresholds = Vec::with_capacity(self.knots.len() + 1);
        let mut weights = Vec::with_capacity(self.knots.len() + 1);
        for (j, &d) in self.knots.iter().enumerate() {
            if j == mid {
                thresholds.push(0.0);
                weights.push(s[mid]);
            }
            thresholds.push(d);
            // knot j lies between intervals j and j + 1
            weights.push(if d < 0.0 {
                s[j] - s[j + 1]
            } else {
                s[j + 1] - s[j]
            });
        }
        if mid == self.knots.len() {
            thresholds.push(0.0);
            weights.push(s[mid]);
        }
        // beyond the fitted range: the gentlest slope between 0 and the range's end
        let bounds = self.bounds();
        let at = |v: f64| bounds.partition_point(|b| b.1 < v).min(s.len() - 1);
        let mut edge = |z: f64, outer: f64, gentlest: f64| {
            if gentlest < outer && z.is_finite() {
                let i = thresholds.partition_point(|&d| d < z);
                if thresholds.get(i) == Some(&z) {
                    weights[i] += gentlest - outer;
                } else {
                    thresholds.insert(i, z);
                    weights.insert(i, gentlest - outer);
                }
            }
        };
        if hi > 0.0 {
            let i = at(hi);
            let gentlest = s[mid..=i].iter().fold(f64::INFINITY, |a, &v| a.min(v));
            edge(hi, s[i], gentlest);
        }
        if lo < 0.0 {
            let i = at(lo);
            let gentlest = s[i..=mid].iter().fold(f64::INFINITY, |a, &v| a.min(v));
            edge(lo, s[i], gentlest);
        }
        DeadZoneSpec {
            thresholds,
            weights,
        }
    }
}

impl TermFit for OutputMapTerm<'_> {
    fn n_columns(&self) -> usize {
        self.knots.len() + 1 + usize::from(self.bw.is_some())
    }
    fn n_params(&self) -> usize {
        bw_n_params(self.bw) + 1 + self.x_len()
    }
    fn param_names(&self) -> Vec<&'static str> {
        let mut names = bw_param_names(self.bw);
        names.extend(std::iter::repeat_n(SECOND_STAGE_PARAM, 1 + self.x_len()));
        names
    }
    /// A play's increment keeps its weight of the path's sign ([`OutputMapTerm::weights_of`]).
    fn param_bounds(&self) -> Vec<(f64, f64)> {
        let free = (f64::NEG_INFINITY, f64::INFINITY);
        let mut b = bw_param_bounds(self.bw);
        b.push(free);
        b.extend((0..self.x_len()).map(|k| {
            self.pi
                .weights
                .get(k)
                .map_or(free, |&w0| self.play_bounds(w0))
        }));
        b
    }
    fn start_grid(&self) -> Vec<Vec<f64>> {
        let extra = 1 + self.x_len();
        bw_start_grid(self.bw)
            .into_iter()
            .map(|mut p| {
                p.extend(std::iter::repeat_n(0.0, extra));
                p
            })
            .collect()
    }
    fn columns<'s>(&'s self, th: &[f64]) -> Vec<Column<'s>> {
        let w = self.weights_of(th);
        let z = self.z(&w);
        let m = self.knots.len() + 1;
        let mut out = vec![Vec::new(); m];
        self.map_columns(&z, &mut out, &vec![true; m], &self.ties_at(&w, Some(&z)));
        let mut cols: Vec<Column<'s>> = out.into_iter().map(|c| (Cow::Owned(c), true)).collect();
        if let Some(bw) = self.bw {
            let c = bw_memoized(self.u, bw, &th[..2], &self.bw_memo);
            cols.push((Cow::Owned(c.to_vec()), true));
        }
        cols
    }
    fn columns_block(
        &self,
        th: &[f64],
        rows: Range<usize>,
        state: &mut TermState,
        out: &mut [Vec<f64>],
        wanted: &[bool],
    ) -> Vec<bool> {
        if rows.start == 0 {
            state.carry = vec![0.0; self.x.thresholds.len()];
            state.scratch = vec![Vec::new(); self.x_len()];
        }
        let m = self.knots.len() + 1;
        if wanted[..m].iter().any(|w| *w) {
            let w = self.weights_of(th);
            let ties = self.ties_at(&w, None);
            let z = self.z_block(&w, rows.clone(), &mut state.carry, &mut state.scratch);
            self.map_columns(&z, &mut out[..m], &wanted[..m], &ties);
        }
        if let (Some(bw), Some(o), Some(true)) = (self.bw, out.get_mut(m), wanted.get(m)) {
            let c = bw_memoized(self.u, bw, &th[..2], &self.bw_memo);
            o.clear();
            o.extend_from_slice(&c[rows]);
        }
        let mut flags = vec![true; m];
        if self.bw.is_some() {
            flags.push(true);
        }
        flags
    }
    fn derivative(&self, th: &[f64], q: usize, coef: &[f64]) -> Vec<f64> {
        let nbw = bw_n_params(self.bw);
        if let Some(bw) = self.bw.filter(|_| q < nbw) {
            let base = bw_memoized(self.u, bw, &th[..2], &self.bw_memo);
            return bouc_wen_derivative(self.u, th, q, bw, &base, coef[coef.len() - 1]);
        }
        if self.held(th, q) {
            return vec![0.0; self.u.len()];
        }
        // S'(z) x_q
        let slope = self.slope_at(&self.weights_of(th), &coef[..self.knots.len() + 1]);
        let x = if q == nbw {
            Cow::Borrowed(self.u)
        } else {
            self.x_whole(q - nbw - 1)
        };
        slope.iter().zip(x.iter()).map(|(&d, &xq)| d * xq).collect()
    }
    /// The operator's weights: S'(z) x_q a block at a time, z and x_q computed there.
    fn derivatives_in_blocks(&self) -> Vec<usize> {
        (bw_n_params(self.bw)..self.n_params()).collect()
    }
    fn derivatives_block(
        &self,
        th: &[f64],
        qs: &[usize],
        coef: &[f64],
        rows: Range<usize>,
        state: &mut TermState,
        out: &mut [Vec<f64>],
    ) {
        if rows.start == 0 {
            state.carry = vec![0.0; self.x.thresholds.len()];
            state.scratch = vec![Vec::new(); self.x_len()];
        }
        let nbw = bw_n_params(self.bw);
        let w = self.weights_of(th);
        // the operator's columns for z (nonzero weights) and for the derivatives asked
        let mut wanted: Vec<bool> = w[1..].iter().map(|&t| t != 0.0).collect();
        for &q in qs.iter().filter(|&&q| q > nbw) {
            wanted[q - nbw - 1] = true;
        }
        let (carry, scratch) = (&mut state.carry, &mut state.scratch);
        let x = self.x_block(rows.clone(), carry, scratch, &wanted, true);
        let z = self.z_of(&w, rows.clone(), &x);
        let bounds = self.bounds();
        let s = Self::tied(&coef[..self.knots.len() + 1], &self.ties_at(&w, None));
        let slope: Vec<f64> = z.iter().map(|&v| self.slope_of(&bounds, &s, v)).collect();
        for (o, &q) in out.iter_mut().zip(qs) {
            if self.held(th, q) {
                o.clear();
                o.resize(rows.len(), 0.0);
                continue;
            }
            let xq = if q == nbw {
                &self.u[rows.clone()]
            } else {
                x[q - nbw - 1]
            };
            o.clear();
            o.extend(slope.iter().zip(xq).map(|(&d, &v)| d * v));
        }
    }
    fn spec(&self, th: &[f64], gain: f64, coef: &[f64]) -> TermSpec {
        let m = self.knots.len() + 1;
        let w = self.weights_of(th);
        let mut pi = self.pi.clone();
        pi.linear_weight += w[0];
        let nplays = pi.weights.len();
        for (v, &t) in pi.weights.iter_mut().zip(&w[1..]) {
            *v += t;
        }
        if let Some(map) = &mut pi.input_map {
            for (v, &t) in map.weights.iter_mut().zip(&w[1 + nplays..]) {
                *v += t;
            }
        }
        // beyond the operator's output over the fitted samples the map has no data: it goes on
        // with its gentlest slope on that side, not with the slope of its last interval,
        // which a staircase's one level there can fit to anything (held-out zoo seed 1043,
        // member 8: 457 times the slope around 0, a test level beyond the training range
        // predicted 1645 where the plant gave about 4)
        let z = self.z(&w);
        let slopes = Self::tied(&coef[..m], &self.ties_at(&w, Some(&z)));
        let range = super::fitting::PreviousPath::range_where(&z, |k| self.fitted(k));
        let spec = PrandtlIshlinskiiSpec {
            dead_zones: Some(self.dead_zones(&slopes, range)),
            ..pi
        };
        let mut extra_paths: Vec<Box<dyn EffectSpec>> = Vec::new();
        if gain != 0.0 {
            extra_paths.push(Box::new(HysteresisSpec::Linear(LinearSpec { gain })));
        }
        if self.bw.is_some() {
            extra_paths.extend(bw_extra_path(self.bw, th, coef[m]));
        }
        TermSpec {
            spec: Some(Box::new(HysteresisSpec::PrandtlIshlinskii(spec))),
            extra_paths,
        }
    }
}

/// Bouc-Wen (Rakotondrabe 2011 form): y = d u - A htilde, A of the path's sign (the mirrored
/// loop on a negative path: [`Bw`]), its exponent n held at 1 until the others settle, then
/// freed and kept where it fits significantly better ([`TermFit::optional_params`]).
struct BoucWenTerm<'a> {
    u: &'a [f64],
    bw: Bw,
    bw_memo: BwMemo,
}

impl TermFit for BoucWenTerm<'_> {
    fn n_columns(&self) -> usize {
        1
    }
    fn n_params(&self) -> usize {
        bw_n_params(Some(self.bw))
    }
    fn param_names(&self) -> Vec<&'static str> {
        bw_param_names(Some(self.bw))
    }
    fn param_bounds(&self) -> Vec<(f64, f64)> {
        bw_param_bounds(Some(self.bw))
    }
    /// The exponent: n = 1 unless a free n fits the record significantly better.
    fn optional_params(&self) -> Vec<bool> {
        (0..self.n_params()).map(|q| q == 2).collect()
    }
    fn start_grid(&self) -> Vec<Vec<f64>> {
        bw_start_grid(Some(self.bw))
    }
    /// The starting grid with the exponent at n = 1 + [`EXPONENT_RESTART`].
    fn optional_start_grid(&self) -> Vec<Vec<f64>> {
        let mut g = self.start_grid();
        if self.bw.exponent {
            g.iter_mut().for_each(|p| p[2] = EXPONENT_RESTART);
        } else {
            g.clear();
        }
        g
    }
    fn columns<'s>(&'s self, th: &[f64]) -> Vec<Column<'s>> {
        let c = bw_memoized(self.u, self.bw, th, &self.bw_memo);
        vec![(Cow::Owned(c.to_vec()), true)]
    }
    fn derivative(&self, th: &[f64], q: usize, coef: &[f64]) -> Vec<f64> {
        let base = bw_memoized(self.u, self.bw, th, &self.bw_memo);
        bouc_wen_derivative(self.u, th, q, self.bw, &base, coef[0])
    }
    fn spec(&self, th: &[f64], gain: f64, coef: &[f64]) -> TermSpec {
        let spec = if coef[0] > 0.0 {
            bw_spec(self.bw, th, coef[0], gain)
        } else {
            HysteresisSpec::Linear(LinearSpec { gain })
        };
        TermSpec {
            spec: Some(Box::new(spec)),
            extra_paths: Vec::new(),
        }
    }
}

/// The grey-box operators: the default combines a Prandtl-Ishlinskii operator with one
/// Bouc-Wen term on the same input (two paths in the plant file), exact for either kind of
/// plant (the PI part alone cannot follow Bouc-Wen loops closer than about 0.3 % of the range);
/// it also starts from the Bouc-Wen fit so that it is never worse than `bouc-wen`.
pub const VARIANTS: [Variant; 3] = [
    Variant {
        name: "hysteresis",
        file: "prandtl-ishlinskii+bouc-wen",
        warm_start: Some(2),
    },
    Variant {
        name: "prandtl-ishlinskii",
        file: "prandtl-ishlinskii",
        warm_start: None,
    },
    Variant {
        name: "bouc-wen",
        file: "bouc-wen",
        warm_start: None,
    },
];

/// Hysteresis as an effect of the library.
pub struct HysteresisEffect;

impl Effect for HysteresisEffect {
    fn name(&self) -> EffectName {
        NAME
    }
    fn summary(&self) -> &'static str {
        "rate-independent loops: Prandtl-Ishlinskii, Bouc-Wen (or a linear gain without it)"
    }
    fn slot(&self) -> Slot {
        Slot::PathTerm
    }
    fn required_in_path(&self) -> bool {
        true
    }
    fn parse_spec(
        &self,
        d: &mut dyn erased_serde::Deserializer<'_>,
    ) -> Result<Box<dyn EffectSpec>, erased_serde::Error> {
        parse_spec::<HysteresisSpec>(d)
    }
    /// A piezo stack's Bouc-Wen loop (d 0.7, A 0.25, B 0.018, Gamma 0.006; the shipped plants'
    /// order of magnitude).
    fn example(&self) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(bouc_wen_term_spec(0.25, 0.018, 0.006, 1.0, 0.7)))
    }
    fn draw(&self, ctx: &DrawContext, dice: &mut Dice) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(draw(ctx, dice)))
    }
    fn draw_onto_path(
        &self,
        existing: &dyn EffectSpec,
        input: &[f64],
        dice: &mut Dice,
    ) -> Option<Box<dyn EffectSpec>> {
        let spec = existing.as_any().downcast_ref::<HysteresisSpec>()?;
        draw_envelopes(spec, input, dice).map(|s| Box::new(s) as Box<dyn EffectSpec>)
    }
    fn draws_onto_paths(&self) -> bool {
        true
    }
    fn basis<'a>(&self, ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
        Some(basis(ctx))
    }
    fn evidence(&self, ctx: &EvidenceContext) -> String {
        format!(
            "the error forms a loop against {} (branch gap {:.1} % of the error's range)",
            ctx.input_names[ctx.direct],
            100.0 * crate::metrics::branch_gap(ctx.inputs[ctx.direct], ctx.error, 20)
        )
    }
    fn feature_kinds(&self) -> &'static [FeatureKind] {
        std::slice::from_ref(&PLAY)
    }
    /// For each input, 8 plays with thresholds spread over its half range.
    fn features(&self, inputs: &[&[f64]], _ts: f64) -> Vec<FeatureSpec> {
        let mut out = Vec::new();
        for (j, u) in inputs.iter().enumerate() {
            for r in play_thresholds(u, 8) {
                out.push(FeatureSpec::new(&PLAY, j, vec![r]));
            }
        }
        out
    }
    fn narx_candidate(&self) -> bool {
        true
    }
    fn variants(&self) -> &'static [Variant] {
        &VARIANTS
    }
    fn term<'a>(&self, setup: &PathSetup<'a>) -> Option<Box<dyn TermFit + 'a>> {
        let u = setup.u;
        if reversals_from_rest(setup.whole) < LOOP_REVERSALS {
            // no loop on this path's input (a cross path driven by a staircase, say): a
            // linear path, the gain column alone; check_record asks one input to reverse
            return Some(Box::new(PiTerm::new(
                u,
                Vec::new(),
                setup.sign,
                Vec::new(),
                None,
            )));
        }
        // thresholds, knots and ranges from the samples fitted
        let seen = setup.fitted_input();
        if let (Some(prev), 0 | 1) = (&setup.previous, setup.variant) {
            if let Some(t) = OutputMapTerm::new(setup, prev, max_abs(&seen)) {
                return Some(Box::new(t));
            }
        }
        Some(match setup.variant {
            2 => Box::new(BoucWenTerm {
                u,
                bw: Bw {
                    range: max_abs(&seen),
                    sign: setup.sign,
                    exponent: true,
                },
                bw_memo: BwMemo::default(),
            }),
            v => {
                // the input's distinct levels, sorted once for the plays and the knots
                let values = setup.plays_by_levels.then(|| levels(&seen));
                let count = values
                    .as_ref()
                    .map_or(setup.plays, |l| plays_for_levels(l.len(), setup.plays, v));
                let thresholds = pi_thresholds(&seen, count);
                let bw = (v == 0).then(|| Bw {
                    range: max_abs(&seen),
                    sign: setup.sign,
                    exponent: false,
                });
                let knots = match (v, &values) {
                    (0, Some(l)) => input_map_knots_by_levels(&seen, l, input_map_ramps(count)),
                    (0, None) => input_map_knots(&seen, input_map_ramps(count)),
                    _ => Vec::new(),
                };
                let split = if v == 0 && setup.envelope_split {
                    Split::Free {
                        range: max_abs(&seen),
                    }
                } else {
                    Split::None
                };
                Box::new(PiTerm::with_split(
                    u, thresholds, setup.sign, knots, bw, split,
                ))
            }
        })
    }
    fn path_without(&self, gain: f64) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(HysteresisSpec::Linear(LinearSpec { gain })))
    }
    fn parameter_count(&self, size: super::fitting::BasisSize) -> (usize, usize) {
        let split = if size.envelope_split {
            SPLIT_PARAMS.len()
        } else {
            0
        };
        let plays = size.plays;
        match size.variant {
            0 => (3 + split + plays + input_map_ramps(plays), 0),
            1 => (plays, 0),
            // the exponent is not counted: it is kept only where the record shows it
            _ => (3, 0),
        }
    }
    /// The fewest plays that [`plays_determined`] gives a path of `plays`, over the inputs
    /// that reverse (the paths of the others are linear).
    fn plays_supported(&self, inputs: &[&[f64]], variant: usize, plays: usize) -> Option<usize> {
        if variant == 2 {
            return None;
        }
        inputs
            .iter()
            .filter(|u| reversals_from_rest(u) >= LOOP_REVERSALS)
            .map(|u| plays_determined(u, plays, variant))
            .min()
    }
    /// One input at least must go up and down, counted from rest ([`reversals_from_rest`]);
    /// the paths of inputs that do not are linear.
    fn check_record(&self, rec: &RecordView, _variant: usize) -> Result<(), RecordError> {
        let revs: Vec<usize> = rec.inputs.iter().map(|u| reversals_from_rest(u)).collect();
        if revs.iter().any(|&r| r >= LOOP_REVERSALS) {
            return Ok(());
        }
        let (name, rev) = rec
            .input_names
            .iter()
            .zip(&revs)
            .next()
            .map_or(("input", 0), |(n, &r)| (*n, r));
        let others = if rec.inputs.len() > 1 {
            " (nor does any other input)"
        } else {
            ""
        };
        Err(RecordError::PoorlyExcited {
            input: name.to_string(),
            why: format!("from rest (an input of 0) it reverses direction {rev} times{others}; a hysteresis loop needs the input to go up and down (at least 2 reversals, better several amplitudes)"),
        })
    }
}

/// The play counts of a parsimonious model (a short record's, a staircase's paths), most first.
pub const FEWER_PLAYS: [usize; 4] = [19, 9, 5, 3];

/// The play operators of a path on input `u` (its fitted samples): `plays`, or fewer when the
/// input visits only a few distinct levels (a staircase). The path's operator is then seen at
/// those levels only, so its columns (the linear term, the plays and, for the default
/// operator (`variant` 0), the input map's ramps) are kept to no more than the levels; plays
/// beyond them would be fitted to nothing and predict the levels the record has not visited
/// badly. The count is then the most of [`FEWER_PLAYS`] that fits (3 at least; on the zoo's
/// improvement loop the ladder named more hidden effects than the largest count that fits).
/// A continuous input (sines, chirps, noise) has as many levels as samples.
pub fn plays_determined(u: &[f64], plays: usize, variant: usize) -> usize {
    plays_for_levels(levels(u).len(), plays, variant)
}

/// [`plays_determined`] for an input of `levels` distinct levels.
fn plays_for_levels(levels: usize, plays: usize, variant: usize) -> usize {
    let ramps = |p: usize| if variant == 0 { input_map_ramps(p) } else { 0 };
    if 1 + plays + ramps(plays) <= levels {
        return plays;
    }
    FEWER_PLAYS
        .into_iter()
        .find(|&p| p < plays && 1 + p + ramps(p) <= levels)
        .unwrap_or(plays.min(3))
}

/// The distinct values of a signal, increasing (values closer than 1e-9 of its range are one).
pub fn levels(u: &[f64]) -> Vec<f64> {
    let tol = 1e-9 * crate::metrics::ptp(u);
    let mut values = u.to_vec();
    values.sort_by(f64::total_cmp);
    values.dedup_by(|a, b| (*a - *b).abs() <= tol);
    values
}

/// Direction reversals of a signal (moves below 1e-9 of its range ignored).
pub fn reversals(u: &[f64]) -> usize {
    reversal_samples(u).len()
}

/// Direction reversals of the path that an operator started at rest follows over `u`: the
/// [`reversals`] of `u` after an input of 0 (moves below 1e-9 of the range, 0 included,
/// ignored). The plays and the Bouc-Wen term start relaxed at input 0, so a record whose
/// first sample lies away from 0 loads them from rest there: a staircase from 4 down to -3
/// and up to -2 takes the operator through a loading, a reversal and a branch, two
/// reversals of its path where the record's samples show one.
pub fn reversals_from_rest(u: &[f64]) -> usize {
    reversal_samples_from_rest(u).len()
}

/// The samples at which the path of an operator started at rest is first seen moving the
/// other way ([`reversals_from_rest`] of them).
fn reversal_samples_from_rest(u: &[f64]) -> Vec<usize> {
    let (lo, hi) = crate::metrics::min_max(u);
    reversals_after(u, 0.0, 1e-9 * (hi.max(0.0) - lo.min(0.0)))
}

/// The reversals from rest ([`reversals_from_rest`]) that make a loop: a path whose input
/// shows fewer is linear, and a record none of whose inputs shows them is refused.
pub const LOOP_REVERSALS: usize = 2;

/// The first samples of `u` that hold a loop of an operator started at rest: up to and with
/// its [`LOOP_REVERSALS`]-th reversal from rest (`None`: `u` holds fewer).
pub fn loop_samples(u: &[f64]) -> Option<usize> {
    reversal_samples_from_rest(u)
        .get(LOOP_REVERSALS - 1)
        .map(|&k| k + 1)
}

/// The samples at which a signal is first seen moving the other way, in order (moves below
/// 1e-9 of its range ignored): [`reversals`] of them.
pub fn reversal_samples(u: &[f64]) -> Vec<usize> {
    let start = u.first().copied().unwrap_or(0.0);
    reversals_after(u, start, 1e-9 * crate::metrics::ptp(u))
}

/// The samples at which `u`, coming from `anchor`, is first seen moving the other way, in
/// order (moves of `tol` or less ignored).
fn reversals_after(u: &[f64], mut anchor: f64, tol: f64) -> Vec<usize> {
    let mut dir = 0.0;
    let mut at = Vec::new();
    for (k, &v) in u.iter().enumerate() {
        let d = v - anchor;
        if d.abs() > tol {
            let s = d.signum();
            if dir != 0.0 && s != dir {
                at.push(k);
            }
            dir = s;
            anchor = v;
        }
    }
    at
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The negated operator of each family (Bouc-Wen with n = 1 and 2; Prandtl-Ishlinskii
    /// with an input map and asymmetric dead zones; a gain) gives -H[u], and checks.
    #[test]
    fn a_negated_operator_negates_the_output() {
        let u: Vec<f64> = (0..900)
            .map(|k| 6.0 * (k as f64 * 0.021).sin() + 2.5 * (k as f64 * 0.093).cos() - 0.7)
            .collect();
        let bw = |n| {
            HysteresisSpec::BoucWen(BoucWenSpec {
                d: 0.6,
                a: 0.4,
                b: 0.3,
                gamma: -0.1,
                n,
                initial_h: 0.1,
            })
        };
        let pi = HysteresisSpec::PrandtlIshlinskii(PrandtlIshlinskiiSpec {
            envelope_split: None,
            envelopes: None,
            linear_weight: 0.5,
            thresholds: vec![1.0, 2.5, 4.0],
            weights: vec![0.2, 0.1, 0.05],
            initial_state: 0.0,
            input_map: Some(DeadZoneSpec {
                thresholds: vec![-3.0, 0.0, 3.0],
                weights: vec![0.05, 0.0, -0.04],
            }),
            dead_zones: Some(DeadZoneSpec {
                thresholds: vec![-2.0, 0.0, 1.5],
                weights: vec![0.3, 1.0, -0.25],
            }),
        });
        // generalised plays on tanh envelopes, with the dead zones: the envelopes act on the
        // input, the weights and dead zones as before
        let mut gpi = pi.clone();
        if let HysteresisSpec::PrandtlIshlinskii(g) = &mut gpi {
            g.envelopes = Some(Box::new(EnvelopesSpec {
                ascending: TanhEnvelope::unit_slope(7.0, 0.3),
                descending: TanhEnvelope::unit_slope(8.0, -0.2),
            }));
        }
        let lin = HysteresisSpec::Linear(LinearSpec { gain: 0.7 });
        for spec in [bw(1.0), bw(2.0), pi, gpi, lin] {
            let y = spec.check().unwrap().operator().apply(&u);
            let neg = spec.negated().check().unwrap().operator().apply(&u);
            let err = y
                .iter()
                .zip(&neg)
                .map(|(a, b)| (a + b).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-12, "{spec:?}: max |y + y_neg| {err}");
            assert_eq!(spec.negated().negated(), spec);
        }
    }

    /// An operator starts at rest (input 0): a staircase that starts away from 0 shows its
    /// path one reversal more than its samples do, a signal that starts at 0 the same.
    #[test]
    fn reversals_from_rest_count_the_loading_from_0() {
        let stairs = [4.0, 4.0, -3.0, -3.0, -2.0, -2.0];
        assert_eq!((reversals(&stairs), reversals_from_rest(&stairs)), (1, 2));
        let rising_from_below = [-1.0, 0.5, 2.0];
        assert_eq!(
            (
                reversals(&rising_from_below),
                reversals_from_rest(&rising_from_below)
            ),
            (0, 1)
        );
        let sine: Vec<f64> = (0..400).map(|k| (k as f64 * 0.05).sin()).collect();
        assert_eq!(reversals_from_rest(&sine), reversals(&sine));
        let ramp: Vec<f64> = (0..10).map(f64::from).collect();
        assert_eq!(reversals_from_rest(&ramp), 0);
        assert_eq!(reversals_from_rest(&[]), 0);
    }

    /// `count` columns asked of `ask(rows, state, out)` for each of `rows` in order (one pass,
    /// one state), each column's blocks appended.
    fn in_blocks(
        count: usize,
        rows: &[Range<usize>],
        mut ask: impl FnMut(Range<usize>, &mut TermState, &mut [Vec<f64>]),
    ) -> Vec<Vec<f64>> {
        let mut state = TermState::default();
        let mut out = vec![Vec::new(); count];
        let mut blocks = vec![Vec::new(); count];
        for r in rows {
            ask(r.clone(), &mut state, &mut out);
            for (b, c) in blocks.iter_mut().zip(&out) {
                b.extend_from_slice(c);
            }
        }
        blocks
    }

    /// A Prandtl-Ishlinskii term's columns asked a block of rows at a time (the plays
    /// resuming from their states, nothing cached) are the same bits as over the whole record,
    /// on a positive and a negative path.
    #[test]
    fn pi_columns_in_blocks_are_the_columns_of_the_whole_record() {
        let u: Vec<f64> = (0..5000)
            .map(|k| 3.0 * (k as f64 * 0.013).sin() * (1.0 + 0.5 * (k as f64 * 0.001).cos()))
            .collect();
        for sign in [1.0, -1.0] {
            let thresholds = pi_thresholds(&u, 11);
            let knots = input_map_knots(&u, 4);
            let bw = Some(Bw {
                range: 3.0,
                sign,
                exponent: false,
            });
            let mut term = PiTerm::new(&u, thresholds, sign, knots, bw);
            assert!(term.cached.is_some());
            term.cached = None;
            let th = [0.3, -0.2][..term.n_params()].to_vec();
            let whole: Vec<Vec<f64>> = term
                .columns(&th)
                .into_iter()
                .map(|(c, _)| c.into_owned())
                .collect();
            assert_eq!(whole.len(), term.n_columns());
            let all = vec![true; whole.len()];
            let blocks = in_blocks(
                whole.len(),
                &[0..1, 1..777, 777..4096, 4096..5000],
                |r, s, o| {
                    term.columns_block(&th, r, s, o, &all);
                },
            );
            assert_eq!(blocks, whole, "sign {sign}");
        }
    }

    /// A continuous input keeps every knot of the input map and its plays; a staircase keeps
    /// the knots that have a level on each side (the first interval two), here 5 of 8, and the
    /// plays its levels determine.
    #[test]
    fn a_staircase_keeps_the_knots_and_plays_its_levels_determine() {
        let sine: Vec<f64> = (0..2000)
            .map(|k| 5.0 + 4.0 * (k as f64 * 0.01).sin())
            .collect();
        assert_eq!(
            input_map_knots_by_levels(&sine, &levels(&sine), 8),
            input_map_knots(&sine, 8)
        );
        let levels = [
            1.4752, 9.2164, 1.9056, 8.1608, 4.4683, 7.1358, 5.8024, 6.9184,
        ];
        let stairs: Vec<f64> = levels.iter().flat_map(|&l| [l; 50]).collect();
        let knots = input_map_knots_by_levels(&stairs, &super::levels(&stairs), 8);
        assert_eq!(knots.len(), 5, "{knots:?}");
        let mut sorted = levels.to_vec();
        sorted.sort_by(f64::total_cmp);
        let below = |z: f64| sorted.iter().filter(|&&v| v < z).count();
        assert!(below(knots[0]) >= 2);
        for w in knots.windows(2) {
            assert!(
                below(w[1]) > below(w[0]),
                "no level between {} and {}",
                w[0],
                w[1]
            );
        }
        assert!(below(knots[4]) < sorted.len());
        // the plays: 1 + plays + ramps <= 8 levels; all 39 on the sine
        assert_eq!(plays_determined(&stairs, 39, 0), 5);
        assert_eq!(plays_determined(&stairs, 39, 1), 5);
        assert_eq!(plays_determined(&stairs, 7, 1), 7);
        assert_eq!(plays_determined(&stairs, 3, 0), 3);
        assert_eq!(plays_determined(&sine, 39, 0), 39);
    }

    /// The second stage's term computes the first stage's columns where they are asked when
    /// it does not keep them (a long record): its columns a block at a time, and the
    /// derivatives in the operator's weights, are the same bits as with the columns kept.
    #[test]
    fn the_output_map_term_streamed_is_the_term_with_its_columns_kept() {
        let u: Vec<f64> = (0..6000)
            .map(|k| 4.0 * (k as f64 * 0.011).sin() * (1.0 + 0.4 * (k as f64 * 0.0013).cos()))
            .collect();
        let pi = PrandtlIshlinskiiSpec {
            envelope_split: None,
            envelopes: None,
            linear_weight: 0.7,
            thresholds: vec![0.5, 1.2, 2.0, 2.9],
            weights: vec![0.2, 0.1, 0.05, 0.02],
            initial_state: 0.0,
            input_map: Some(DeadZoneSpec {
                thresholds: vec![-2.0, 1.5],
                weights: vec![0.03, -0.04],
            }),
            dead_zones: None,
        };
        let mut op = pi.check().unwrap().operator();
        let z: Vec<f64> = u.iter().map(|&v| op.step(v)).collect();
        let prev = super::super::fitting::PreviousPath {
            output: std::sync::Arc::new(z),
            spec: std::sync::Arc::new(HysteresisSpec::PrandtlIshlinskii(pi)),
            range: None,
            left_out: None,
        };
        let setup = PathSetup {
            u: &u,
            whole: &u,
            held_out: None,
            ts: 1e-3,
            sign: 1.0,
            plays: 5,
            plays_by_levels: false,
            envelope_split: false,
            variant: 0,
            previous: Some(prev.clone()),
        };
        let kept = OutputMapTerm::new(&setup, &prev, 4.0).unwrap();
        let mut streamed = OutputMapTerm::new(&setup, &prev, 4.0).unwrap();
        assert!(kept.x.cached.is_some());
        streamed.x.cached = None;
        // Bouc-Wen B and Gamma, then the weights: u, four plays, two ramps
        let th = [0.2, -0.3, 0.01, 0.0, -0.02, 0.03, 0.0, 0.015, -0.01];
        assert_eq!(kept.n_params(), th.len());
        let whole: Vec<Vec<f64>> = kept
            .columns(&th)
            .into_iter()
            .map(|(c, _)| c.into_owned())
            .collect();
        let all = vec![true; whole.len()];
        let rows = [0..1, 1..2500, 2500..4096, 4096..6000];
        let blocks = in_blocks(whole.len(), &rows, |r, s, o| {
            streamed.columns_block(&th, r, s, o, &all);
        });
        assert_eq!(blocks, whole);
        let coef: Vec<f64> = (0..whole.len()).map(|j| 0.1 + 0.05 * j as f64).collect();
        for q in 0..th.len() {
            assert_eq!(
                kept.derivative(&th, q, &coef),
                streamed.derivative(&th, q, &coef),
                "parameter {q}"
            );
        }
        // the derivatives asked in parallel of a term that computes its columns (the slope's
        // lock is not held across parallel work: no thread waits on itself)
        let mut fresh = OutputMapTerm::new(&setup, &prev, 4.0).unwrap();
        fresh.x.cached = None;
        let par: Vec<Vec<f64>> = (0..th.len())
            .into_par_iter()
            .map(|q| fresh.derivative(&th, q, &coef))
            .collect();
        for (q, d) in par.iter().enumerate() {
            assert_eq!(
                *d,
                kept.derivative(&th, q, &coef),
                "parameter {q} in parallel"
            );
        }
        // the weights' derivatives a block at a time
        let qs = streamed.derivatives_in_blocks();
        assert_eq!(qs, (2..th.len()).collect::<Vec<_>>());
        let blocks = in_blocks(qs.len(), &rows, |r, s, o| {
            streamed.derivatives_block(&th, &qs, &coef, r, s, o);
        });
        for (b, &q) in blocks.iter().zip(&qs) {
            assert_eq!(
                *b,
                kept.derivative(&th, q, &coef),
                "parameter {q} in blocks"
            );
        }
    }

    /// A first-stage operator (one play) and its output `z`, as the output map's stage gets it.
    fn first_stage_of(z: &[f64]) -> (PrandtlIshlinskiiSpec, super::super::fitting::PreviousPath) {
        let pi = PrandtlIshlinskiiSpec {
            envelope_split: None,
            envelopes: None,
            linear_weight: 1.0,
            thresholds: vec![1.0],
            weights: vec![0.5],
            initial_state: 0.0,
            input_map: None,
            dead_zones: None,
        };
        let prev = super::super::fitting::PreviousPath {
            output: std::sync::Arc::new(z.to_vec()),
            spec: std::sync::Arc::new(HysteresisSpec::PrandtlIshlinskii(pi.clone())),
            range: None,
            left_out: None,
        };
        (pi, prev)
    }

    /// The path setup of an output map's stage on the input `u` (5 plays, the plain operator).
    fn map_setup<'a>(u: &'a [f64], prev: &super::super::fitting::PreviousPath) -> PathSetup<'a> {
        PathSetup {
            u,
            whole: u,
            held_out: None,
            ts: 1e-3,
            sign: 1.0,
            plays: 5,
            plays_by_levels: true,
            envelope_split: false,
            variant: 1,
            previous: Some(prev.clone()),
        }
    }

    /// The slopes of the piecewise-linear map fitted on the intervals between the knots
    /// convert to a dead-zone superposition that gives the same map, increasing, and a valid
    /// plant-file operator.
    #[test]
    fn the_output_map_slopes_convert_to_the_same_dead_zone_map() {
        let z: Vec<f64> = (0..=400).map(|k| -3.0 + 8.0 * k as f64 / 400.0).collect();
        let (pi, prev) = first_stage_of(&z);
        let u = vec![0.0; z.len()];
        let setup = map_setup(&u, &prev);
        let t = OutputMapTerm::new(&setup, &prev, 1.0).unwrap();
        // knots at 1/4, 1/2, 3/4 of -3 and of 5: seven intervals
        assert_eq!(t.knots.len(), 6);
        let cols = t.columns(&vec![0.0; t.n_params()]);
        assert_eq!(cols.len(), 7);
        let slopes = [0.2, 0.5, 0.9, 1.0, 0.7, 0.3, 0.05];
        let dz = t.dead_zones(&slopes, (-3.0, 5.0));
        let spec = PrandtlIshlinskiiSpec {
            dead_zones: Some(dz.clone()),
            ..pi.clone()
        };
        spec.check().expect("an increasing map is a valid operator");
        for (k, &v) in z.iter().enumerate() {
            let direct: f64 = slopes.iter().zip(&cols).map(|(s, c)| s * c.0[k]).sum();
            let zones: f64 = dz
                .thresholds
                .iter()
                .zip(&dz.weights)
                .map(|(&d, &c)| c * dead_zone(v, d))
                .sum();
            assert!((direct - zones).abs() < 1e-12, "z {v}: {direct} vs {zones}");
        }
        // a map that steepens again at either end goes on beyond the range with its gentlest
        // slope on that side: 0.5 below -3, 0.3 above 5
        let slopes = [0.6, 0.5, 0.9, 1.0, 0.7, 0.3, 0.4];
        let dz = t.dead_zones(&slopes, (-3.0, 5.0));
        let spec = PrandtlIshlinskiiSpec {
            dead_zones: Some(dz.clone()),
            ..pi
        };
        spec.check().expect("an increasing map is a valid operator");
        let map = |v: f64| -> f64 {
            dz.thresholds
                .iter()
                .zip(&dz.weights)
                .map(|(&d, &c)| c * dead_zone(v, d))
                .sum()
        };
        let direct = |k: usize| -> f64 { slopes.iter().zip(&cols).map(|(s, c)| s * c.0[k]).sum() };
        assert!((map(5.0) - direct(400)).abs() < 1e-12);
        assert!(
            (map(7.0) - (direct(400) + 0.3 * 2.0)).abs() < 1e-12,
            "{}",
            map(7.0)
        );
        assert!((map(-3.0) - direct(0)).abs() < 1e-12);
        assert!(
            (map(-4.0) - (direct(0) - 0.5)).abs() < 1e-12,
            "{}",
            map(-4.0)
        );
    }

    /// The second stage refits the first stage's play weights but keeps their sign (the
    /// path's): an increment that would take a weight across 0 holds it at 0, in the model
    /// and in the derivatives the fit sees.
    #[test]
    fn the_output_map_stage_keeps_the_play_weights_sign() {
        let u: Vec<f64> = (0..400).map(|k| 3.0 * (k as f64 * 0.05).sin()).collect();
        let (_, prev) = first_stage_of(&u);
        let setup = map_setup(&u, &prev);
        let t = OutputMapTerm::new(&setup, &prev, 3.0).unwrap();
        // the fit's bounds: the play's increment down to -0.5 (its weight 0.5), the linear
        // weight (the path's gain) free
        let inf = f64::INFINITY;
        assert_eq!(t.param_bounds(), vec![(-inf, inf), (-0.5, inf)]);
        let coef = vec![1.0; t.n_columns()];
        let weight = |th: &[f64]| match t
            .spec(th, 0.0, &coef)
            .spec
            .as_ref()
            .and_then(|s| s.as_any().downcast_ref::<HysteresisSpec>())
        {
            Some(HysteresisSpec::PrandtlIshlinskii(p)) => p.weights[0],
            _ => panic!("a Prandtl-Ishlinskii operator"),
        };
        // the first stage's weight 0.5: -0.3 moves it to 0.2, -0.8 would take it to -0.3
        assert!((weight(&[0.0, -0.3]) - 0.2).abs() < 1e-15);
        assert!(t
            .derivative(&[0.0, -0.3], 1, &coef)
            .iter()
            .any(|&d| d != 0.0));
        assert_eq!(weight(&[0.0, -0.8]), 0.0);
        assert!(t
            .derivative(&[0.0, -0.8], 1, &coef)
            .iter()
            .all(|&d| d == 0.0));
        // held at 0, the operator's output is the one with the weight at 0 exactly
        assert_eq!(t.weights_of(&[0.0, -0.8]), vec![0.0, -0.5]);
        // the linear weight (the path's gain) is not a play's: either sign
        assert!(t
            .derivative(&[-2.0, 0.0], 0, &coef)
            .iter()
            .any(|&d| d != 0.0));
    }

    /// An interval of the output map that fewer than [`MAP_INTERVAL_SAMPLES`] fitted samples
    /// enter has no column of its own and takes the slope of its neighbour nearer to 0: its own
    /// coefficient, whatever it is, does not reach the model.
    #[test]
    fn an_output_map_interval_that_few_samples_enter_takes_its_neighbours_slope() {
        // z over [-3, 3.7], and three samples beyond the last knot (3/4 of the peak 5)
        let mut z: Vec<f64> = (0..=400).map(|k| -3.0 + 6.7 * k as f64 / 400.0).collect();
        z.extend([4.0, 4.5, 5.0]);
        let (_, prev) = first_stage_of(&z);
        let u = vec![0.0; z.len()];
        let setup = map_setup(&u, &prev);
        let t = OutputMapTerm::new(&setup, &prev, 1.0).unwrap();
        assert_eq!(t.ties_of(&z), vec![0, 1, 2, 3, 4, 5, 5]);
        let th = vec![0.0; t.n_params()];
        let cols = t.columns(&th);
        assert!(cols[6].0.iter().all(|&v| v == 0.0));
        // the tied interval's samples count in its neighbour's column
        let last = z.len() - 1;
        assert!((cols[5].0[last] - (5.0 - 2.5)).abs() < 1e-12);
        // a slope of 10^6 on the tied interval does not reach the dead zones
        let spec = t.spec(&th, 0.0, &[0.2, 0.5, 0.9, 1.0, 0.7, 0.3, 1e6]);
        let dz = match spec
            .spec
            .as_ref()
            .and_then(|s| s.as_any().downcast_ref::<HysteresisSpec>())
        {
            Some(HysteresisSpec::PrandtlIshlinskii(p)) => p.dead_zones.clone().unwrap(),
            _ => panic!("a Prandtl-Ishlinskii operator with dead zones"),
        };
        assert!(dz.weights.iter().all(|w| w.abs() <= 1.0), "{dz:?}");
        // a held-out block's samples do not count: without most of (2.5, 3.75), that
        // interval and the outer one take the slope of (1.25, 2.5)
        let mut held = setup.clone();
        held.held_out = Some(330..398);
        let t = OutputMapTerm::new(&held, &prev, 1.0).unwrap();
        assert_eq!(t.ties_of(&z), vec![0, 1, 2, 3, 4, 4, 4]);
    }
}
