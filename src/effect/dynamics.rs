//! # Linear dynamics
//!
//! A second-order mode, y'' + 2 zeta wn y' + wn^2 y = g wn^2 w, discretised exactly under a
//! zero-order hold on w: x(k+1) = Phi x(k) + Gamma w(k), y(k) = x_1(k) (one sample of transport
//! delay). Phi and Gamma come from the matrix exponential of the augmented system.
//!
//! Two extensions, both off by default (a plant file without them is the mode above, bit for
//! bit):
//! - a **second mode** in parallel, D(s) = g [(1 - c) M_1(s) + c M_2(s)] (modal superposition:
//!   a bender's second mode, or a 2-DoF cross path that shows both axes' modes, PHYSICS.md
//!   section 4);
//! - the **input between samples**: held (the zero-order hold above) or ramped linearly from
//!   one sample to the next (the first-order, triangle hold: a continuous input sampled, which
//!   a measured record is), or a blend h of the two: x(k+1) = Phi x(k) + (Gamma_1 + h (Phi
//!   Gamma_2 - Gamma_2)) w(k), y(k) = x_1(k) + h (C Gamma_2) w(k), with Gamma_1, Gamma_2 from
//!   the exponential of [[A, B, 0], [0, 0, 1/T], [0, 0, 0]] T (the output then follows the
//!   input within the sample).
//!
//! ## References
//! - G. F. Franklin, J. D. Powell, M. Workman, *Digital Control of Dynamic Systems*, 3rd ed.,
//!   Addison-Wesley, 1998, ch. 4 (zero-order-hold equivalents) and ch. 6 (the triangle-hold
//!   equivalent).
//! - C. Moler, C. Van Loan, "Nineteen dubious ways to compute the exponential of a matrix,
//!   twenty-five years later", SIAM Review 45(1):3-49, 2003 (scaling and squaring).

use super::basis::{BasisBank, BasisContext, EvidenceContext, Signal};
use super::draw::{Dice, DrawContext};
use super::feature::{FeatureKind, FeatureSpec};
use super::fitting::{
    bounded, bounded_inv, log_bounded, log_bounded_inv, FilterFit, FilterState, OutputSetup,
    Prepared, Variant, FD_STEP,
};
use super::spec::{parse_spec, BoxedOperator, EffectSpec, Params, Spec};
use super::{non_negative, positive, Effect, EffectError, EffectName, Operator, Slot};
use nalgebra::{Matrix2, Matrix3, Matrix4, SMatrix, Vector2};
use serde::{Deserialize, Serialize};

/// The effect's name.
pub const NAME: EffectName = EffectName::new("dynamics");

/// Most resonators one input gets as NARX features (the dynamics bank's frequency ladder is
/// thinned evenly to this many).
pub const MAX_RESONATOR_FEATURES: usize = 6;

fn one() -> f64 {
    1.0
}

/// A second mode in parallel with the first, as written in a plant file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModeSpec {
    /// Natural frequency in Hz.
    pub natural_frequency_hz: f64,
    /// Damping ratio >= 0.
    pub damping_ratio: f64,
    /// Its share c of the static gain: D(s) = g [(1 - c) M_1(s) + c M_2(s)] (either sign: a
    /// mode's residue may be negative).
    pub share: f64,
}

/// Second-order dynamics as written in a plant file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsSpec {
    /// Natural frequency f_n in Hz.
    pub natural_frequency_hz: f64,
    /// Damping ratio zeta >= 0.
    pub damping_ratio: f64,
    /// Static gain (default 1).
    #[serde(default = "one")]
    pub dc_gain: f64,
    /// A second mode in parallel (none by default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub second_mode: Option<ModeSpec>,
    /// How the input runs between samples, 0 to 1: 0 held (zero-order hold: the output lags
    /// the input by a sample; the default), 1 ramped linearly to the next sample (first-order
    /// or triangle hold: a continuous input sampled), between them a blend of the two.
    #[serde(default, skip_serializing_if = "crate::data::is_default")]
    pub first_order_hold: f64,
}

impl DynamicsSpec {
    /// One mode of unit static gain under a zero-order hold.
    pub fn mode(natural_frequency_hz: f64, damping_ratio: f64) -> DynamicsSpec {
        DynamicsSpec {
            natural_frequency_hz,
            damping_ratio,
            dc_gain: 1.0,
            second_mode: None,
            first_order_hold: 0.0,
        }
    }
}

/// A valid second mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    pub natural_frequency_hz: f64,
    pub damping_ratio: f64,
    pub share: f64,
}

/// Valid second-order dynamics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dynamics {
    pub natural_frequency_hz: f64,
    pub damping_ratio: f64,
    pub dc_gain: f64,
    pub second_mode: Option<Mode>,
    pub first_order_hold: f64,
}

impl DynamicsSpec {
    /// Check the parameters.
    pub fn check(&self) -> Result<Dynamics, EffectError> {
        positive("natural_frequency_hz", self.natural_frequency_hz)?;
        non_negative("damping_ratio", self.damping_ratio)?;
        super::finite("dc_gain", self.dc_gain)?;
        let second_mode = match &self.second_mode {
            None => None,
            Some(m) => {
                positive("second_mode.natural_frequency_hz", m.natural_frequency_hz)?;
                non_negative("second_mode.damping_ratio", m.damping_ratio)?;
                super::finite("second_mode.share", m.share)?;
                Some(Mode {
                    natural_frequency_hz: m.natural_frequency_hz,
                    damping_ratio: m.damping_ratio,
                    share: m.share,
                })
            }
        };
        let h = self.first_order_hold;
        if !(0.0..=1.0).contains(&h) {
            return Err(EffectError::Invalid {
                field: "first_order_hold".into(),
                value: h,
                rule: "must lie between 0 (the input held between samples) and 1 (ramped to the next sample)".into(),
            });
        }
        Ok(Dynamics {
            natural_frequency_hz: self.natural_frequency_hz,
            damping_ratio: self.damping_ratio,
            dc_gain: self.dc_gain,
            second_mode,
            first_order_hold: h,
        })
    }
}

/// exp(M) by scaling and squaring with a Taylor series (accurate to rounding for small M), for
/// the augmented systems of the zero-order (3 x 3) and triangle-hold (4 x 4) equivalents.
pub fn expm<const N: usize>(m: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    let norm = m.abs().row_sum().max();
    let s = if norm > 0.5 {
        (norm / 0.5).log2().ceil() as i32
    } else {
        0
    };
    let a = m / 2f64.powi(s);
    let mut term = SMatrix::<f64, N, N>::identity();
    let mut sum = SMatrix::<f64, N, N>::identity();
    for k in 1..=20 {
        term = term * a / k as f64;
        sum += term;
    }
    for _ in 0..s {
        sum = sum * sum;
    }
    sum
}

/// One mode discretised: state matrix, input vector and feedthrough (0 under a zero-order
/// hold), its static gain in the input vector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Discrete {
    pub phi: Matrix2<f64>,
    pub gamma: Vector2<f64>,
    pub d: f64,
}

/// A mode (f, zeta) of static gain `gain` at sampling period `ts` under a blend `hold` of
/// the zero-order (0) and first-order (1) holds; `field` names the frequency in errors.
/// The last [`RECENT_MODES`] modes discretised on this thread are kept (a fit's central
/// differences move one mode of two at a time, and its evaluations and Jacobians prepare the
/// filters at the same parameters): the same values, without the matrix exponential.
fn discretise_mode(
    f: f64,
    z: f64,
    gain: f64,
    hold: f64,
    ts: f64,
    field: &str,
) -> Result<Discrete, EffectError> {
    type Recent = [Option<([u64; 5], Discrete)>; RECENT_MODES];
    thread_local! {
        static RECENT: std::cell::RefCell<(Recent, usize)> =
            const { std::cell::RefCell::new(([None; RECENT_MODES], 0)) };
    }
    let key = [f, z, gain, hold, ts].map(f64::to_bits);
    let found = RECENT.with_borrow(|(recent, _)| {
        recent
            .iter()
            .flatten()
            .find(|(k, _)| *k == key)
            .map(|(_, d)| *d)
    });
    if let Some(d) = found {
        return Ok(d);
    }
    let d = discretise_mode_anew(f, z, gain, hold, ts, field)?;
    RECENT.with_borrow_mut(|(recent, next)| {
        recent[*next] = Some((key, d));
        *next = (*next + 1) % RECENT_MODES;
    });
    Ok(d)
}

/// How many modes [`discretise_mode`] keeps on each thread.
const RECENT_MODES: usize = 16;

/// [`discretise_mode`] computed.
fn discretise_mode_anew(
    f: f64,
    z: f64,
    gain: f64,
    hold: f64,
    ts: f64,
    field: &str,
) -> Result<Discrete, EffectError> {
    let wn = 2.0 * std::f64::consts::PI * f;
    if wn * ts >= std::f64::consts::PI {
        return Err(EffectError::Invalid {
            field: field.into(),
            value: f,
            rule: format!(
                "is at or above the Nyquist frequency {} Hz of the sampling period {ts} s; sample faster",
                0.5 / ts
            ),
        });
    }
    let mut m = Matrix3::zeros();
    m[(0, 1)] = 1.0;
    m[(1, 0)] = -wn * wn;
    m[(1, 1)] = -2.0 * z * wn;
    m[(1, 2)] = gain * wn * wn;
    if let Some(v) = (m * ts).iter().find(|v| !v.is_finite()) {
        return Err(EffectError::Invalid {
            field: "damping_ratio".into(),
            value: z,
            rule: format!(
                "with natural_frequency_hz {f} and gain {gain} makes the mode's state matrix overflow ({v}); a mode this damped is a first-order lag: give a smaller damping ratio"
            ),
        });
    }
    if hold == 0.0 {
        let e = expm(&(m * ts));
        return Ok(Discrete {
            phi: Matrix2::new(e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]),
            gamma: Vector2::new(e[(0, 2)], e[(1, 2)]),
            d: 0.0,
        });
    }
    // [[A, B, 0], [0, 0, 1/T], [0, 0, 0]] T: Phi, Gamma_1, Gamma_2 (Franklin et al., ch. 6)
    let mut a = Matrix4::zeros();
    a.fixed_view_mut::<3, 3>(0, 0).copy_from(&(m * ts));
    a[(2, 3)] = 1.0;
    let e = expm(&a);
    let phi = Matrix2::new(e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]);
    let g1 = Vector2::new(e[(0, 2)], e[(1, 2)]);
    let g2 = Vector2::new(e[(0, 3)], e[(1, 3)]);
    Ok(Discrete {
        phi,
        gamma: g1 + hold * (phi * g2 - g2),
        d: hold * g2[0],
    })
}

impl Dynamics {
    /// The modes discretised for sampling period `ts`: the first (its share of the static
    /// gain in its input vector) and the second, where there is one.
    pub fn discrete_modes(&self, ts: f64) -> Result<(Discrete, Option<Discrete>), EffectError> {
        let h = self.first_order_hold;
        let c = self.second_mode.map_or(0.0, |m| m.share);
        let first = discretise_mode(
            self.natural_frequency_hz,
            self.damping_ratio,
            self.dc_gain * (1.0 - c),
            h,
            ts,
            "natural_frequency_hz",
        )?;
        let second = match self.second_mode {
            None => None,
            Some(m) => Some(discretise_mode(
                m.natural_frequency_hz,
                m.damping_ratio,
                self.dc_gain * m.share,
                h,
                ts,
                "second_mode.natural_frequency_hz",
            )?),
        };
        Ok((first, second))
    }

    /// Whether this is the plain mode (one mode, zero-order hold).
    pub fn plain(&self) -> bool {
        self.second_mode.is_none() && self.first_order_hold == 0.0
    }

    /// The zero-order-hold equivalent (Phi, Gamma) for sampling period `ts`.
    pub fn discretise(&self, ts: f64) -> Result<(Matrix2<f64>, Vector2<f64>), EffectError> {
        let wn = 2.0 * std::f64::consts::PI * self.natural_frequency_hz;
        if wn * ts >= std::f64::consts::PI {
            return Err(EffectError::Invalid {
                field: "natural_frequency_hz".into(),
                value: self.natural_frequency_hz,
                rule: format!(
                    "is at or above the Nyquist frequency {} Hz of the sampling period {ts} s; sample faster",
                    0.5 / ts
                ),
            });
        }
        let z = self.damping_ratio;
        let mut m = Matrix3::zeros();
        m[(0, 1)] = 1.0;
        m[(1, 0)] = -wn * wn;
        m[(1, 1)] = -2.0 * z * wn;
        m[(1, 2)] = self.dc_gain * wn * wn;
        // a finite matrix: the scaling and squaring of its exponential is then bounded (at most
        // ~1,000 squarings); an overflowing one (a damping ratio of 1e308) would not end
        if let Some(v) = (m * ts).iter().find(|v| !v.is_finite()) {
            return Err(EffectError::Invalid {
                field: "damping_ratio".into(),
                value: z,
                rule: format!(
                    "with natural_frequency_hz {} and dc_gain {} makes the mode's state matrix overflow ({v}); a mode this damped is a first-order lag: give a smaller damping ratio",
                    self.natural_frequency_hz, self.dc_gain
                ),
            });
        }
        let e = expm(&(m * ts));
        Ok((
            Matrix2::new(e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]),
            Vector2::new(e[(0, 2)], e[(1, 2)]),
        ))
    }

    /// The operator for sampling period `ts`, at rest.
    pub fn operator(&self, ts: f64) -> Result<DynamicsOp, EffectError> {
        if self.plain() {
            let (phi, gamma) = self.discretise(ts)?;
            return Ok(DynamicsOp {
                phi,
                gamma,
                x: Vector2::zeros(),
                d: 0.0,
                second: None,
            });
        }
        let (first, second) = self.discrete_modes(ts)?;
        Ok(DynamicsOp {
            phi: first.phi,
            gamma: first.gamma,
            x: Vector2::zeros(),
            d: first.d,
            second: second.map(|m| Box::new((m, Vector2::zeros()))),
        })
    }

    /// Closed-form unit-step response at time t (continuous time, from rest, 0 <= zeta < 1).
    pub fn step_response(&self, t: f64) -> f64 {
        let wn = 2.0 * std::f64::consts::PI * self.natural_frequency_hz;
        let z = self.damping_ratio;
        if z < 1.0 {
            let wd = wn * (1.0 - z * z).sqrt();
            let e = (-z * wn * t).exp();
            self.dc_gain * (1.0 - e * ((wd * t).cos() + z * wn / wd * (wd * t).sin()))
        } else if z == 1.0 {
            self.dc_gain * (1.0 - (1.0 + wn * t) * (-wn * t).exp())
        } else {
            let r = (z * z - 1.0).sqrt();
            let (p1, p2) = (-wn * (z - r), -wn * (z + r));
            self.dc_gain * (1.0 + (p2 * (p1 * t).exp() - p1 * (p2 * t).exp()) / (p1 - p2))
        }
    }
}

/// A running second-order filter (and its second mode, where it has one).
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicsOp {
    phi: Matrix2<f64>,
    gamma: Vector2<f64>,
    x: Vector2<f64>,
    /// Feedthrough (0 under a zero-order hold).
    d: f64,
    second: Option<Box<(Discrete, Vector2<f64>)>>,
}

impl Operator for DynamicsOp {
    fn reset(&mut self) {
        self.x = Vector2::zeros();
        if let Some(s) = self.second.as_mut() {
            s.1 = Vector2::zeros();
        }
    }

    #[inline]
    fn step(&mut self, w: f64) -> f64 {
        let mut y = self.x[0];
        self.x = self.phi * self.x + self.gamma * w;
        if self.d != 0.0 {
            y += self.d * w;
        }
        if let Some(s) = self.second.as_mut() {
            let (m, x) = &mut **s;
            y += x[0] + m.d * w;
            *x = m.phi * *x + m.gamma * w;
        }
        y
    }
}

/// The lowest resonator of the diagnosis bank: five periods in the record, and no lower than
/// Nyquist / 200 (a mode of a plant is seldom slower than a hundredth of the Nyquist frequency
/// it is sampled at).
fn lowest_resonator(span: f64, ts: f64) -> f64 {
    (5.0 / span).max(0.0025 / ts)
}

/// Basis bank: the model's prediction passed through lightly damped second-order resonators
/// (natural frequencies log-spaced by 1.3 from [`lowest_resonator`] to 0.35 / Ts,
/// damping 0.1; each with its one-sample delay, which spans the filter's two states), and a few
/// short delays of the prediction (first-order lags, delays): a missing mode or lag acting on
/// the prediction is a combination of them.
pub fn basis<'a>(ctx: &BasisContext<'a>) -> BasisBank<'a> {
    let mut bank = BasisBank::new(NAME);
    let y = ctx.prediction;
    let n = y.len();
    for lag in [1usize, 2, 3, 5] {
        if lag >= n {
            break;
        }
        bank.push(
            format!("prediction(k-{lag})"),
            Signal::samples(y).delayed(lag),
        );
    }
    let span = n as f64 * ctx.ts;
    let mut f = lowest_resonator(span, ctx.ts);
    let f_max = 0.35 / ctx.ts;
    // start the filters at the first value so that a non-zero start does not ring
    let y0 = y.first().copied().unwrap_or(0.0);
    while f <= f_max {
        let d = Dynamics {
            natural_frequency_hz: f,
            damping_ratio: 0.1,
            dc_gain: 1.0,
            second_mode: None,
            first_order_hold: 0.0,
        };
        if let Ok(op) = d.operator(ctx.ts) {
            let x = || Signal::of(move |k| y[k] - y0).through(Box::new(op.clone()));
            bank.push(format!("resonator({f:.2} Hz)"), x());
            bank.push(format!("resonator({f:.2} Hz)(k-1)"), x().delayed(1));
        }
        f *= 1.3;
    }
    bank
}

impl Spec for DynamicsSpec {
    const EFFECT: EffectName = NAME;
    type Params = Dynamics;
    fn check(&self) -> Result<Dynamics, EffectError> {
        DynamicsSpec::check(self)
    }
}

impl Params for Dynamics {
    const EFFECT: EffectName = NAME;
    fn operator(&self, ts: f64) -> Result<BoxedOperator, EffectError> {
        Ok(Box::new(Dynamics::operator(self, ts)?))
    }
}

/// A unit-gain second-order resonator on a signal, shifted by its first value so that a
/// non-zero start does not ring; zeros when it cannot be discretised at `ts`.
#[derive(Clone)]
struct Resonator {
    filter: Option<BoxedOperator>,
    u0: Option<f64>,
}

impl Resonator {
    fn new(hz: f64, zeta: f64, ts: f64) -> Resonator {
        let d = Dynamics {
            natural_frequency_hz: hz,
            damping_ratio: zeta,
            dc_gain: 1.0,
            second_mode: None,
            first_order_hold: 0.0,
        };
        Resonator {
            filter: d.operator(ts).ok().map(|op| Box::new(op) as BoxedOperator),
            u0: None,
        }
    }
}

impl Operator for Resonator {
    fn reset(&mut self) {
        self.u0 = None;
        if let Some(f) = self.filter.as_mut() {
            f.reset();
        }
    }
    fn step(&mut self, x: f64) -> f64 {
        let u0 = *self.u0.get_or_insert(x);
        self.filter.as_mut().map_or(0.0, |f| f.step(x - u0))
    }
}

/// The NARX feature: a unit-gain resonator on an input (the dynamics bank's filter).
pub static RESONATOR: FeatureKind = FeatureKind {
    name: "resonator",
    params: &["hz", "zeta"],
    valid: |p| p[0].is_finite() && p[0] > 0.0 && p[1].is_finite() && p[1] > 0.0,
    label: |n, p| format!("resonator({n}, {:.2} Hz, zeta={})", p[0], p[1]),
    operator: |p, ts| Box::new(Resonator::new(p[0], p[1], ts)),
};

/// The second-order filter (one sample of delay) on a signal; NaN when `d` cannot be
/// discretised at `ts`.
fn filtered(d: &Dynamics, ts: f64, x: &[f64]) -> Vec<f64> {
    match prepared(d, ts) {
        Prepared::Apply(f) => {
            let mut out = x.to_vec();
            f(&mut [&mut out], &mut [Vec::new()]);
            out
        }
        _ => vec![f64::NAN; x.len()],
    }
}

/// The discretised second-order filter (state matrix `p` row by row, input vector `gm`, one
/// sample of delay) on one signal in place, from state `x` (updated).
fn resonate(p: &[f64; 4], gm: &[f64; 2], out: &mut [f64], x: &mut [f64; 2]) {
    let [mut x0, mut x1] = *x;
    for v in out.iter_mut() {
        let w = *v;
        *v = x0;
        let n0 = p[0] * x0 + p[1] * x1 + gm[0] * w;
        let n1 = p[2] * x0 + p[3] * x1 + gm[1] * w;
        x0 = n0;
        x1 = n1;
    }
    *x = [x0, x1];
}

/// The signals of `cols` `N` at a time from the first, while each group's signals have one
/// length: `kernel` filters a group from its states (`K` values a signal; at rest when a
/// state is empty) and leaves them updated. Returns how many signals it filtered (the lane
/// kernels' shared loop).
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
fn in_groups<const N: usize, const K: usize>(
    cols: &mut [&mut [f64]],
    states: &mut [FilterState],
    mut kernel: impl FnMut(&mut [&mut [f64]], &mut [[f64; K]; N]),
) -> usize {
    let mut done = 0;
    for (group, st) in cols.chunks_exact_mut(N).zip(states.chunks_exact_mut(N)) {
        let n = group[0].len();
        if group.iter().any(|c| c.len() != n) {
            break;
        }
        let mut x: [[f64; K]; N] =
            std::array::from_fn(|l| st[l].as_slice().try_into().unwrap_or([0.0; K]));
        kernel(group, &mut x);
        for (s, x) in st.iter_mut().zip(x) {
            *s = x.to_vec();
        }
        done += N;
    }
    done
}

/// [`resonate`] on the signals of `cols` eight at a time in the lanes of AVX-512 registers,
/// where the processor has it: each block of eight samples of eight signals is transposed in
/// the registers, run through the recursion (lane `l` doing signal `l`'s arithmetic in
/// `resonate`'s order: the same bits) and transposed back; the rows after the last whole block
/// of eight run alone. Returns how many signals it filtered (a multiple of eight from the
/// first; none without AVX-512 or where the eight differ in length).
fn eight_lanes(
    p: &[f64; 4],
    gm: &[f64; 2],
    cols: &mut [&mut [f64]],
    states: &mut [FilterState],
) -> usize {
    #[cfg(target_arch = "x86_64")]
    if crate::numeric::simd::uses_avx512() {
        // SAFETY: the processor supports AVX-512F (checked above); eight signals of one length
        return in_groups::<8, 2>(cols, states, |g, x| unsafe { resonate_8(p, gm, g, x) });
    }
    let _ = (p, gm, cols, states);
    0
}

/// [`resonate`] on eight signals of one length, states `x` (updated): AVX-512 lanes over whole
/// blocks of eight samples, the rest alone.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn resonate_8(p: &[f64; 4], gm: &[f64; 2], cols: &mut [&mut [f64]], x: &mut [[f64; 2]; 8]) {
    use std::arch::x86_64::*;
    let n = cols[0].len();
    assert!(cols.len() == 8 && cols.iter().all(|c| c.len() == n));
    let full = n - n % 8;
    let [p0, p1, p2, p3] = p.map(|v| _mm512_set1_pd(v));
    let [g0, g1] = gm.map(|v| _mm512_set1_pd(v));
    let lanes = |i: usize| {
        _mm512_set_pd(
            x[7][i], x[6][i], x[5][i], x[4][i], x[3][i], x[2][i], x[1][i], x[0][i],
        )
    };
    let (mut x0, mut x1) = (lanes(0), lanes(1));
    let ptrs: [*mut f64; 8] = std::array::from_fn(|l| cols[l].as_mut_ptr());
    for s in (0..full).step_by(8) {
        // SAFETY: s + 8 <= full <= n, every signal's length
        let w = transpose_8x8(std::array::from_fn(|l| unsafe {
            _mm512_loadu_pd(ptrs[l].add(s))
        }));
        let mut o = [_mm512_setzero_pd(); 8];
        for (k, wk) in w.iter().enumerate() {
            o[k] = x0;
            let n0 = _mm512_add_pd(
                _mm512_add_pd(_mm512_mul_pd(p0, x0), _mm512_mul_pd(p1, x1)),
                _mm512_mul_pd(g0, *wk),
            );
            let n1 = _mm512_add_pd(
                _mm512_add_pd(_mm512_mul_pd(p2, x0), _mm512_mul_pd(p3, x1)),
                _mm512_mul_pd(g1, *wk),
            );
            x0 = n0;
            x1 = n1;
        }
        for (l, v) in transpose_8x8(o).into_iter().enumerate() {
            // SAFETY: as the loads
            unsafe { _mm512_storeu_pd(ptrs[l].add(s), v) };
        }
    }
    let (mut a, mut b) = ([0.0f64; 8], [0.0f64; 8]);
    // SAFETY: eight doubles each
    unsafe {
        _mm512_storeu_pd(a.as_mut_ptr(), x0);
        _mm512_storeu_pd(b.as_mut_ptr(), x1);
    }
    for (l, c) in cols.iter_mut().enumerate() {
        x[l] = [a[l], b[l]];
        resonate(p, gm, &mut c[full..], &mut x[l]);
    }
}

/// The 8 x 8 transpose of eight registers of eight doubles (row `l` becomes lane `l` of each).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn transpose_8x8(r: [std::arch::x86_64::__m512d; 8]) -> [std::arch::x86_64::__m512d; 8] {
    use std::arch::x86_64::*;
    // pairs of rows interleaved, then pairs of pairs, then the halves
    let s: [__m512d; 8] = std::array::from_fn(|i| {
        let (a, b) = (r[i & !1], r[i | 1]);
        if i % 2 == 0 {
            _mm512_unpacklo_pd(a, b)
        } else {
            _mm512_unpackhi_pd(a, b)
        }
    });
    let lo = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
    let hi = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
    let q = [
        _mm512_permutex2var_pd(s[0], lo, s[2]),
        _mm512_permutex2var_pd(s[1], lo, s[3]),
        _mm512_permutex2var_pd(s[0], hi, s[2]),
        _mm512_permutex2var_pd(s[1], hi, s[3]),
        _mm512_permutex2var_pd(s[4], lo, s[6]),
        _mm512_permutex2var_pd(s[5], lo, s[7]),
        _mm512_permutex2var_pd(s[4], hi, s[6]),
        _mm512_permutex2var_pd(s[5], hi, s[7]),
    ];
    let first = _mm512_set_epi64(11, 10, 9, 8, 3, 2, 1, 0);
    let second = _mm512_set_epi64(15, 14, 13, 12, 7, 6, 5, 4);
    std::array::from_fn(|k| {
        let idx = if k < 4 { first } else { second };
        _mm512_permutex2var_pd(q[k % 4], idx, q[4 + k % 4])
    })
}

/// [`resonate`] on the signals of `cols` four at a time in the lanes of AVX2 registers, where
/// the processor has it (as [`eight_lanes`] does with AVX-512: each block of four samples of
/// four signals transposed, lane `l` doing signal `l`'s arithmetic in `resonate`'s order, the
/// same bits). Returns how many signals it filtered (a multiple of four from the first; none
/// without AVX2 or where the four differ in length).
fn four_lanes(
    p: &[f64; 4],
    gm: &[f64; 2],
    cols: &mut [&mut [f64]],
    states: &mut [FilterState],
) -> usize {
    #[cfg(target_arch = "x86_64")]
    if crate::numeric::simd::uses_avx2() {
        // SAFETY: the processor supports AVX2 (checked above); four signals of one length
        return in_groups::<4, 2>(cols, states, |g, x| unsafe { resonate_4(p, gm, g, x) });
    }
    let _ = (p, gm, cols, states);
    0
}

/// [`resonate`] on four signals of one length, states `x` (updated): AVX2 lanes over whole
/// blocks of four samples, the rest alone.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn resonate_4(p: &[f64; 4], gm: &[f64; 2], cols: &mut [&mut [f64]], x: &mut [[f64; 2]; 4]) {
    use std::arch::x86_64::*;
    let n = cols[0].len();
    assert!(cols.len() == 4 && cols.iter().all(|c| c.len() == n));
    let full = n - n % 4;
    let [p0, p1, p2, p3] = p.map(|v| _mm256_set1_pd(v));
    let [g0, g1] = gm.map(|v| _mm256_set1_pd(v));
    let mut x0 = _mm256_set_pd(x[3][0], x[2][0], x[1][0], x[0][0]);
    let mut x1 = _mm256_set_pd(x[3][1], x[2][1], x[1][1], x[0][1]);
    let ptrs: [*mut f64; 4] = std::array::from_fn(|l| cols[l].as_mut_ptr());
    for s in (0..full).step_by(4) {
        // SAFETY: s + 4 <= full <= n, every signal's length
        let w = unsafe { load_transposed_4(&ptrs, s) };
        let mut o = [_mm256_setzero_pd(); 4];
        for (k, wk) in w.iter().enumerate() {
            o[k] = x0;
            let n0 = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(p0, x0), _mm256_mul_pd(p1, x1)),
                _mm256_mul_pd(g0, *wk),
            );
            let n1 = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(p2, x0), _mm256_mul_pd(p3, x1)),
                _mm256_mul_pd(g1, *wk),
            );
            x0 = n0;
            x1 = n1;
        }
        // SAFETY: as the loads
        unsafe { store_transposed_4(&ptrs, s, o) };
    }
    let (mut a, mut b) = ([0.0f64; 4], [0.0f64; 4]);
    // SAFETY: four doubles each
    unsafe {
        _mm256_storeu_pd(a.as_mut_ptr(), x0);
        _mm256_storeu_pd(b.as_mut_ptr(), x1);
    }
    for (l, c) in cols.iter_mut().enumerate() {
        x[l] = [a[l], b[l]];
        resonate(p, gm, &mut c[full..], &mut x[l]);
    }
}

/// Samples `s..s + 4` of four signals (at `ptrs`), transposed: register `k` holds sample
/// `s + k`, lane `l` signal `l`'s.
///
/// # Safety
/// The processor has AVX2 and each signal holds at least `s + 4` samples.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn load_transposed_4(ptrs: &[*mut f64; 4], s: usize) -> [std::arch::x86_64::__m256d; 4] {
    use std::arch::x86_64::_mm256_loadu_pd;
    // SAFETY: as the caller promises
    transpose_4x4(ptrs.map(|p| unsafe { _mm256_loadu_pd(p.add(s)) }))
}

/// The inverse of [`load_transposed_4`]: register `k`'s lanes stored as sample `s + k` of the
/// four signals.
///
/// # Safety
/// As [`load_transposed_4`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn store_transposed_4(ptrs: &[*mut f64; 4], s: usize, o: [std::arch::x86_64::__m256d; 4]) {
    use std::arch::x86_64::_mm256_storeu_pd;
    for (p, v) in ptrs.iter().zip(transpose_4x4(o)) {
        // SAFETY: as the caller promises
        unsafe { _mm256_storeu_pd(p.add(s), v) };
    }
}

/// The 4 x 4 transpose of four registers of four doubles (row `l` becomes lane `l` of each).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn transpose_4x4(r: [std::arch::x86_64::__m256d; 4]) -> [std::arch::x86_64::__m256d; 4] {
    use std::arch::x86_64::*;
    let t0 = _mm256_unpacklo_pd(r[0], r[1]);
    let t1 = _mm256_unpackhi_pd(r[0], r[1]);
    let t2 = _mm256_unpacklo_pd(r[2], r[3]);
    let t3 = _mm256_unpackhi_pd(r[2], r[3]);
    [
        _mm256_permute2f128_pd::<0x20>(t0, t2),
        _mm256_permute2f128_pd::<0x20>(t1, t3),
        _mm256_permute2f128_pd::<0x31>(t0, t2),
        _mm256_permute2f128_pd::<0x31>(t1, t3),
    ]
}

/// A signal's resonator state (at rest when empty).
fn state_of(s: &FilterState) -> [f64; 2] {
    match s.as_slice() {
        [a, b] => [*a, *b],
        _ => [0.0; 2],
    }
}

fn prepared(d: &Dynamics, ts: f64) -> Prepared {
    match d.discretise(ts) {
        Ok((phi, gam)) => {
            let p = [phi[(0, 0)], phi[(0, 1)], phi[(1, 0)], phi[(1, 1)]];
            let gm = [gam[0], gam[1]];
            let alone = move |out: &mut [f64], s: &mut FilterState| {
                let mut x = state_of(s);
                resonate(&p, &gm, out, &mut x);
                *s = x.to_vec();
            };
            Prepared::Apply(Box::new(
                move |cols: &mut [&mut [f64]], states: &mut [FilterState]| {
                    debug_assert_eq!(cols.len(), states.len(), "a state per signal");
                    // eight columns in the lanes of one register where the processor has
                    // AVX-512, else four side by side: the recursion's latency is shared (each
                    // column's arithmetic is the same as alone)
                    let eights = eight_lanes(&p, &gm, cols, states);
                    let (cols, states) = (&mut cols[eights..], &mut states[eights..]);
                    let fours = four_lanes(&p, &gm, cols, states);
                    let (cols, states) = (&mut cols[fours..], &mut states[fours..]);
                    for (group, st) in cols.chunks_mut(4).zip(states.chunks_mut(4)) {
                        match (group, st) {
                            ([a, b, c, d], [sa, sb, sc, sd])
                                if b.len() == a.len()
                                    && c.len() == a.len()
                                    && d.len() == a.len() =>
                            {
                                let s4 = [state_of(sa), state_of(sb), state_of(sc), state_of(sd)];
                                let mut x0 = s4.map(|s| s[0]);
                                let mut x1 = s4.map(|s| s[1]);
                                for k in 0..a.len() {
                                    let w = [a[k], b[k], c[k], d[k]];
                                    (a[k], b[k], c[k], d[k]) = (x0[0], x0[1], x0[2], x0[3]);
                                    for l in 0..4 {
                                        let n0 = p[0] * x0[l] + p[1] * x1[l] + gm[0] * w[l];
                                        let n1 = p[2] * x0[l] + p[3] * x1[l] + gm[1] * w[l];
                                        x0[l] = n0;
                                        x1[l] = n1;
                                    }
                                }
                                for (l, s) in [sa, sb, sc, sd].into_iter().enumerate() {
                                    *s = vec![x0[l], x1[l]];
                                }
                            }
                            (group, st) => {
                                for (out, s) in group.iter_mut().zip(st.iter_mut()) {
                                    alone(out, s);
                                }
                            }
                        }
                    }
                },
            ))
        }
        Err(_) => Prepared::Invalid,
    }
}

/// The grey-box filter: natural frequency in (fs / min(1000, N), 0.49 fs), N the fitted
/// samples (a mode whose period is longer than the record cannot be told from a drift: on a
/// short record it fits the noise and extrapolates wildly), and damping in (0.002, 5), both on
/// log scales; started from the best local minima of a grid.
struct DynamicsFilter {
    ts: f64,
    f_bounds: (f64, f64),
    z_bounds: (f64, f64),
}

impl DynamicsFilter {
    fn dynamics(&self, th: &[f64]) -> Dynamics {
        let (flo, fhi) = self.f_bounds;
        let (zlo, zhi) = self.z_bounds;
        Dynamics {
            natural_frequency_hz: log_bounded(th[0], flo, fhi),
            damping_ratio: log_bounded(th[1], zlo, zhi),
            dc_gain: 1.0,
            second_mode: None,
            first_order_hold: 0.0,
        }
    }

    fn params_of(&self, f: f64, z: f64) -> Vec<f64> {
        vec![
            log_bounded_inv(f, self.f_bounds.0, self.f_bounds.1),
            log_bounded_inv(z, self.z_bounds.0, self.z_bounds.1),
        ]
    }
}

impl FilterFit for DynamicsFilter {
    fn n_params(&self) -> usize {
        2
    }
    fn initial(&self) -> Vec<f64> {
        self.params_of(0.1 / self.ts, 0.1)
    }
    fn off_when_static(&self) -> bool {
        true
    }
    fn at_static_edge(&self, th: &[f64]) -> bool {
        self.dynamics(th).natural_frequency_hz * self.ts > 0.25
    }
    fn prepare(&self, th: &[f64]) -> Prepared {
        prepared(&self.dynamics(th), self.ts)
    }
    fn derivative(&self, th: &[f64], x: &[f64], q: usize) -> Vec<f64> {
        let d0 = self.dynamics(th);
        let mut t2 = th.to_vec();
        t2[q] += FD_STEP;
        let d1 = self.dynamics(&t2);
        let a = filtered(&d0, self.ts, x);
        let b = filtered(&d1, self.ts, x);
        b.iter().zip(&a).map(|(b, a)| (b - a) / FD_STEP).collect()
    }
    /// A grid of natural frequencies (x1.12 from twice the lower bound to 0.45 fs) and damping
    /// ratios (0.02, 0.1, 0.4, 1): the best damping per frequency, then the `count` best local
    /// minima along the frequency axis.
    fn starts(
        &self,
        _th: &[f64],
        cost: &dyn Fn(&[f64]) -> f64,
        count: usize,
    ) -> Option<Vec<Vec<f64>>> {
        let (flo, fhi) = (2.0 * self.f_bounds.0, 0.45 / self.ts);
        let steps = ((fhi / flo).ln() / 1.12f64.ln()).ceil() as usize;
        let grid: Vec<(f64, f64)> = (0..=steps)
            .flat_map(|i| {
                let f = flo * (fhi / flo).powf(i as f64 / steps as f64);
                [0.02, 0.1, 0.4, 1.0].map(|z| (f, z))
            })
            .collect();
        let costs: Vec<f64> = grid
            .iter()
            .map(|&(f, z)| cost(&self.params_of(f, z)))
            .collect();
        let per_f: Vec<usize> = (0..=steps)
            .map(|i| {
                (4 * i..4 * i + 4)
                    .min_by(|&a, &b| costs[a].total_cmp(&costs[b]))
                    .unwrap_or(4 * i)
            })
            .collect();
        let c = |i: usize| costs[per_f[i]];
        let mut minima: Vec<usize> = (0..per_f.len())
            .filter(|&i| (i == 0 || c(i) <= c(i - 1)) && (i + 1 == per_f.len() || c(i) <= c(i + 1)))
            .map(|i| per_f[i])
            .collect();
        minima.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]));
        minima.truncate(count.max(1));
        if minima.is_empty() {
            minima.push(0);
        }
        Some(
            minima
                .into_iter()
                .map(|best| self.params_of(grid[best].0, grid[best].1))
                .collect(),
        )
    }
    fn spec(&self, th: &[f64]) -> Box<dyn EffectSpec> {
        let d = self.dynamics(th);
        Box::new(DynamicsSpec {
            natural_frequency_hz: d.natural_frequency_hz,
            damping_ratio: d.damping_ratio,
            dc_gain: 1.0,
            second_mode: None,
            first_order_hold: 0.0,
        })
    }
}

/// The two modes of a path discretised (the first at its share of the gain, the second at
/// its own), on one signal in place from its state `[x1, x2, x3, x4]` (updated).
fn two_modes(a: &Discrete, b: &Discrete, out: &mut [f64], s: &mut FilterState) {
    if s.len() != 4 {
        *s = vec![0.0; 4];
    }
    let (mut x, mut z) = (Vector2::new(s[0], s[1]), Vector2::new(s[2], s[3]));
    for v in out.iter_mut() {
        let w = *v;
        *v = x[0] + a.d * w + z[0] + b.d * w;
        x = a.phi * x + a.gamma * w;
        z = b.phi * z + b.gamma * w;
    }
    s.copy_from_slice(&[x[0], x[1], z[0], z[1]]);
}

/// A path's two modes discretised: the first at its share of the gain, the second at its own.
type ModePair<'a> = (&'a Discrete, &'a Discrete);

/// [`two_modes`] on each signal of `cols` with its own pair of modes (`modes[i]` on `cols[i]`
/// from `states[i]`): eight at a time in the lanes of AVX-512 registers, then four at a time
/// in those of AVX2, where the processor has them, and the rest alone. Lane `l` does signal
/// `l`'s arithmetic in `two_modes`'s order (as [`four_lanes`] does for one mode): the same
/// bits. Groups stop where their signals differ in length.
fn two_modes_each(modes: &[ModePair<'_>], cols: &mut [&mut [f64]], states: &mut [FilterState]) {
    debug_assert!(modes.len() == cols.len() && cols.len() == states.len());
    #[allow(unused_mut)]
    let mut done = 0;
    #[cfg(target_arch = "x86_64")]
    {
        use crate::numeric::simd::{uses_avx2, uses_avx512};
        if uses_avx512() {
            let mut at = 0;
            done += in_groups::<8, 4>(cols, states, |g, x| {
                let m = &modes[at..at + 8];
                at += 8;
                // SAFETY: the processor supports AVX-512F (checked above); eight signals of
                // one length
                unsafe { two_modes_8(m, g, x) }
            });
        }
        if uses_avx2() {
            let mut at = done;
            done += in_groups::<4, 4>(&mut cols[done..], &mut states[done..], |g, x| {
                let m = &modes[at..at + 4];
                at += 4;
                // SAFETY: the processor supports AVX2 (checked above); four signals of one
                // length
                unsafe { two_modes_4(m, g, x) }
            });
        }
    }
    for ((m, c), s) in modes[done..]
        .iter()
        .zip(cols[done..].iter_mut())
        .zip(&mut states[done..])
    {
        two_modes(m.0, m.1, c, s);
    }
}

/// The coefficients of each lane's two modes (`m[l]` for lane `l`), coefficient by
/// coefficient: the first mode's Phi (row by row), Gamma and d, then the second's.
#[cfg(target_arch = "x86_64")]
fn lane_coefficients<const L: usize>(m: &[ModePair<'_>]) -> [[f64; L]; 14] {
    let mode = |x: &Discrete| {
        [
            x.phi[(0, 0)],
            x.phi[(0, 1)],
            x.phi[(1, 0)],
            x.phi[(1, 1)],
            x.gamma[0],
            x.gamma[1],
            x.d,
        ]
    };
    let each: [[[f64; 7]; 2]; L] = std::array::from_fn(|l| [mode(m[l].0), mode(m[l].1)]);
    std::array::from_fn(|i| std::array::from_fn(|l| each[l][i / 7][i % 7]))
}

/// [`two_modes`] on four signals of one length, each with its own modes (`m[l]`), states `x`
/// (`[x1, x2, x3, x4]` each, updated): AVX2 lanes over whole blocks of four samples, the rest
/// alone.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn two_modes_4(m: &[ModePair<'_>], cols: &mut [&mut [f64]], x: &mut [[f64; 4]; 4]) {
    use std::arch::x86_64::*;
    let n = cols[0].len();
    assert!(m.len() == 4 && cols.len() == 4 && cols.iter().all(|c| c.len() == n));
    let full = n - n % 4;
    // SAFETY: four doubles each
    let c = lane_coefficients::<4>(m).map(|v| unsafe { _mm256_loadu_pd(v.as_ptr()) });
    let (pa, ga, ad) = ([c[0], c[1], c[2], c[3]], [c[4], c[5]], c[6]);
    let (pb, gb, bd) = ([c[7], c[8], c[9], c[10]], [c[11], c[12]], c[13]);
    let lanes = |i: usize| _mm256_set_pd(x[3][i], x[2][i], x[1][i], x[0][i]);
    let (mut x0, mut x1, mut z0, mut z1) = (lanes(0), lanes(1), lanes(2), lanes(3));
    let ptrs: [*mut f64; 4] = std::array::from_fn(|l| cols[l].as_mut_ptr());
    let (add, mul) = (_mm256_add_pd, _mm256_mul_pd);
    for s in (0..full).step_by(4) {
        // SAFETY: s + 4 <= full <= n, every signal's length
        let w = unsafe { load_transposed_4(&ptrs, s) };
        let mut o = [_mm256_setzero_pd(); 4];
        for (k, &wk) in w.iter().enumerate() {
            // (x1 + d_a w + x3) + d_b w, as `two_modes`
            o[k] = add(add(add(x0, mul(ad, wk)), z0), mul(bd, wk));
            let n0 = add(add(mul(pa[0], x0), mul(pa[1], x1)), mul(ga[0], wk));
            let n1 = add(add(mul(pa[2], x0), mul(pa[3], x1)), mul(ga[1], wk));
            let m0 = add(add(mul(pb[0], z0), mul(pb[1], z1)), mul(gb[0], wk));
            let m1 = add(add(mul(pb[2], z0), mul(pb[3], z1)), mul(gb[1], wk));
            (x0, x1, z0, z1) = (n0, n1, m0, m1);
        }
        // SAFETY: as the loads
        unsafe { store_transposed_4(&ptrs, s, o) };
    }
    let mut st = [[0.0f64; 4]; 4];
    for (i, v) in [x0, x1, z0, z1].into_iter().enumerate() {
        // SAFETY: four doubles
        unsafe { _mm256_storeu_pd(st[i].as_mut_ptr(), v) };
    }
    for (l, c) in cols.iter_mut().enumerate() {
        let mut s: FilterState = (0..4).map(|i| st[i][l]).collect();
        two_modes(m[l].0, m[l].1, &mut c[full..], &mut s);
        x[l] = [s[0], s[1], s[2], s[3]];
    }
}

/// [`two_modes`] on eight signals of one length, each with its own modes (`m[l]`), states `x`
/// (updated): AVX-512 lanes over whole blocks of eight samples, the rest alone.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn two_modes_8(m: &[ModePair<'_>], cols: &mut [&mut [f64]], x: &mut [[f64; 4]; 8]) {
    use std::arch::x86_64::*;
    let n = cols[0].len();
    assert!(m.len() == 8 && cols.len() == 8 && cols.iter().all(|c| c.len() == n));
    let full = n - n % 8;
    // SAFETY: eight doubles each
    let c = lane_coefficients::<8>(m).map(|v| unsafe { _mm512_loadu_pd(v.as_ptr()) });
    let (pa, ga, ad) = ([c[0], c[1], c[2], c[3]], [c[4], c[5]], c[6]);
    let (pb, gb, bd) = ([c[7], c[8], c[9], c[10]], [c[11], c[12]], c[13]);
    let lanes = |i: usize| {
        _mm512_set_pd(
            x[7][i], x[6][i], x[5][i], x[4][i], x[3][i], x[2][i], x[1][i], x[0][i],
        )
    };
    let (mut x0, mut x1, mut z0, mut z1) = (lanes(0), lanes(1), lanes(2), lanes(3));
    let ptrs: [*mut f64; 8] = std::array::from_fn(|l| cols[l].as_mut_ptr());
    let (add, mul) = (_mm512_add_pd, _mm512_mul_pd);
    for s in (0..full).step_by(8) {
        // SAFETY: s + 8 <= full <= n, every signal's length
        let w = transpose_8x8(std::array::from_fn(|l| unsafe {
            _mm512_loadu_pd(ptrs[l].add(s))
        }));
        let mut o = [_mm512_setzero_pd(); 8];
        for (k, &wk) in w.iter().enumerate() {
            // (x1 + d_a w + x3) + d_b w, as `two_modes`
            o[k] = add(add(add(x0, mul(ad, wk)), z0), mul(bd, wk));
            let n0 = add(add(mul(pa[0], x0), mul(pa[1], x1)), mul(ga[0], wk));
            let n1 = add(add(mul(pa[2], x0), mul(pa[3], x1)), mul(ga[1], wk));
            let m0 = add(add(mul(pb[0], z0), mul(pb[1], z1)), mul(gb[0], wk));
            let m1 = add(add(mul(pb[2], z0), mul(pb[3], z1)), mul(gb[1], wk));
            (x0, x1, z0, z1) = (n0, n1, m0, m1);
        }
        for (l, v) in transpose_8x8(o).into_iter().enumerate() {
            // SAFETY: as the loads
            unsafe { _mm512_storeu_pd(ptrs[l].add(s), v) };
        }
    }
    let mut st = [[0.0f64; 8]; 4];
    for (i, v) in [x0, x1, z0, z1].into_iter().enumerate() {
        // SAFETY: eight doubles
        unsafe { _mm512_storeu_pd(st[i].as_mut_ptr(), v) };
    }
    for (l, c) in cols.iter_mut().enumerate() {
        let mut s: FilterState = (0..4).map(|i| st[i][l]).collect();
        two_modes(m[l].0, m[l].1, &mut c[full..], &mut s);
        x[l] = [s[0], s[1], s[2], s[3]];
    }
}

/// The shares a path's second mode is kept within (a 2-DoF cross path through both axes'
/// modes in equal parts has 0.5; one through the other axis' mode alone, 1).
pub const SHARE_BOUNDS: (f64, f64) = (-1.0, 2.0);

/// The grey-box filter of the `modes` variant: on each path two modes in parallel, the
/// second's share of the path's static gain the path's own (a 2-DoF cross path that shows
/// both axes' modes, a bender's second mode), and how the input runs between samples (the
/// blend of the zero- and first-order holds), shared by the paths. Parameters: f_1, zeta_1,
/// the hold, f_2, zeta_2, then one share per path.
struct ModesFilter {
    ts: f64,
    f_bounds: (f64, f64),
    z_bounds: (f64, f64),
    paths: usize,
}

/// Where the `modes` filter's parameters are.
const MODES_SHARED: usize = 5;

impl ModesFilter {
    fn dynamics(&self, th: &[f64], path: usize) -> Dynamics {
        let (flo, fhi) = self.f_bounds;
        let (zlo, zhi) = self.z_bounds;
        Dynamics {
            natural_frequency_hz: log_bounded(th[0], flo, fhi),
            damping_ratio: log_bounded(th[1], zlo, zhi),
            dc_gain: 1.0,
            second_mode: Some(Mode {
                natural_frequency_hz: log_bounded(th[3], flo, fhi),
                damping_ratio: log_bounded(th[4], zlo, zhi),
                share: bounded(th[MODES_SHARED + path], SHARE_BOUNDS.0, SHARE_BOUNDS.1),
            }),
            first_order_hold: bounded(th[2], 0.0, 1.0),
        }
    }

    /// The parameters of modes (f_1, zeta_1), (f_2, zeta_2), hold `h` and every path's share
    /// `share` (a hold of exactly 0 or 1 is taken a hundredth inside, where Levenberg-Marquardt can still move it).
    fn params_of(
        &self,
        (f1, z1): (f64, f64),
        h: f64,
        (f2, z2): (f64, f64),
        share: f64,
    ) -> Vec<f64> {
        let (fb, zb) = (self.f_bounds, self.z_bounds);
        let mut th = vec![
            log_bounded_inv(f1, fb.0, fb.1),
            log_bounded_inv(z1, zb.0, zb.1),
            bounded_inv(h.clamp(0.01, 0.99), 0.0, 1.0),
            log_bounded_inv(f2, fb.0, fb.1),
            log_bounded_inv(z2, zb.0, zb.1),
        ];
        th.extend(std::iter::repeat_n(
            bounded_inv(share, SHARE_BOUNDS.0, SHARE_BOUNDS.1),
            self.paths,
        ));
        th
    }
}

impl FilterFit for ModesFilter {
    fn n_params(&self) -> usize {
        MODES_SHARED + self.paths
    }
    fn initial(&self) -> Vec<f64> {
        let f = 0.1 / self.ts;
        self.params_of((f, 0.1), 0.5, (2.0 * f, 0.1), 0.0)
    }
    fn off_when_static(&self) -> bool {
        true
    }
    fn at_static_edge(&self, th: &[f64]) -> bool {
        self.dynamics(th, 0).natural_frequency_hz * self.ts > 0.25
    }
    fn prepare(&self, th: &[f64]) -> Prepared {
        self.prepare_path(th, 0)
    }
    fn per_path(&self) -> bool {
        true
    }
    fn prepare_path(&self, th: &[f64], path: usize) -> Prepared {
        let Ok((a, Some(b))) = self.dynamics(th, path).discrete_modes(self.ts) else {
            return Prepared::Invalid;
        };
        Prepared::Apply(Box::new(
            move |cols: &mut [&mut [f64]], states: &mut [FilterState]| {
                debug_assert_eq!(cols.len(), states.len(), "a state per signal");
                two_modes_each(&vec![(&a, &b); cols.len()], cols, states);
            },
        ))
    }
    fn derivative(&self, th: &[f64], x: &[f64], q: usize) -> Vec<f64> {
        self.derivative_path(th, x, q, 0)
    }
    fn derivative_path(&self, th: &[f64], x: &[f64], q: usize, path: usize) -> Vec<f64> {
        let d = self.derivatives_path(th, x, &[q], path);
        d.and_then(|d| d.into_iter().next())
            .expect("one derivative")
    }
    /// Central differences (as many filter runs as a forward one from `th`), zeros for another
    /// path's share; every parameter's two runs side by side in the lanes of [`two_modes_each`]
    /// (each its own modes).
    fn derivatives_path(
        &self,
        th: &[f64],
        x: &[f64],
        qs: &[usize],
        path: usize,
    ) -> Option<Vec<Vec<f64>>> {
        let moves = |q: usize| q < MODES_SHARED || q == MODES_SHARED + path;
        // each moved parameter's two runs (lower, upper), None where the modes are invalid
        let runs: Vec<Option<(Discrete, Discrete)>> = qs
            .iter()
            .filter(|&&q| moves(q))
            .flat_map(|&q| {
                let (mut lo, mut hi) = (th.to_vec(), th.to_vec());
                lo[q] -= FD_STEP;
                hi[q] += FD_STEP;
                [lo, hi].map(|t| match self.dynamics(&t, path).discrete_modes(self.ts) {
                    Ok((a, Some(b))) => Some((a, b)),
                    _ => None,
                })
            })
            .collect();
        let valid: Vec<ModePair<'_>> = runs.iter().flatten().map(|(a, b)| (a, b)).collect();
        let mut filtered = vec![x.to_vec(); valid.len()];
        let mut cols: Vec<&mut [f64]> = filtered.iter_mut().map(|c| c.as_mut_slice()).collect();
        two_modes_each(&valid, &mut cols, &mut vec![Vec::new(); valid.len()]);
        let mut filtered = filtered.into_iter();
        let runs: Vec<Vec<f64>> = runs
            .iter()
            .map(|r| match r {
                Some(_) => filtered.next().expect("a valid run filtered"),
                None => vec![f64::NAN; x.len()],
            })
            .collect();
        let mut pairs = runs.chunks_exact(2);
        let mut derivative = |q: usize| {
            if !moves(q) {
                return vec![0.0; x.len()];
            }
            let r = pairs.next().expect("a moved parameter's two runs");
            let (lo, hi) = (&r[0], &r[1]);
            hi.iter()
                .zip(lo)
                .map(|(b, a)| (b - a) / (2.0 * FD_STEP))
                .collect()
        };
        Some(qs.iter().map(|&q| derivative(q)).collect())
    }
    /// The one-mode grid of the plain filter (each path's second mode at no share) at the
    /// hold that costs least of held, half and ramped; then, at the best of its modes, a grid
    /// of second modes with every path's share at 0.3: the `count` best one-mode starts and
    /// the best two-mode one.
    fn starts(
        &self,
        _th: &[f64],
        cost: &dyn Fn(&[f64]) -> f64,
        count: usize,
    ) -> Option<Vec<Vec<f64>>> {
        let plain = DynamicsFilter {
            ts: self.ts,
            f_bounds: self.f_bounds,
            z_bounds: self.z_bounds,
        };
        let one = |m: &[f64], h: f64| {
            let (f, z) = (
                plain.dynamics(m).natural_frequency_hz,
                plain.dynamics(m).damping_ratio,
            );
            self.params_of((f, z), h, (2.0 * f, 0.1), 0.0)
        };
        let held = |m: &[f64]| cost(&one(m, 0.0));
        let modes = plain.starts(&[], &held, count)?;
        let best_hold = |m: &[f64]| {
            [0.0, 0.5, 1.0]
                .into_iter()
                .map(|h| (cost(&one(m, h)), h))
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map_or(0.0, |(_, h)| h)
        };
        let mut out: Vec<Vec<f64>> = modes.iter().map(|m| one(m, best_hold(m))).collect();
        if let Some(m) = modes.first() {
            let d = plain.dynamics(m);
            let h = bounded(out[0][2], 0.0, 1.0);
            let (flo, fhi) = (2.0 * self.f_bounds.0, 0.45 / self.ts);
            let steps = ((fhi / flo).ln() / 1.25f64.ln()).ceil() as usize;
            let second = (0..=steps)
                .flat_map(|i| {
                    let f = flo * (fhi / flo).powf(i as f64 / steps as f64);
                    [0.05, 0.3].map(|z| (f, z))
                })
                .map(|m2| {
                    let th = self.params_of((d.natural_frequency_hz, d.damping_ratio), h, m2, 0.3);
                    (cost(&th), th)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            out.extend(second.map(|(_, th)| th));
        }
        Some(out)
    }
    fn spec(&self, th: &[f64]) -> Box<dyn EffectSpec> {
        self.path_spec(th, 0)
    }
    fn path_spec(&self, th: &[f64], path: usize) -> Box<dyn EffectSpec> {
        let d = self.dynamics(th, path);
        let m = d.second_mode.expect("two modes");
        Box::new(DynamicsSpec {
            natural_frequency_hz: d.natural_frequency_hz,
            damping_ratio: d.damping_ratio,
            dc_gain: 1.0,
            second_mode: Some(ModeSpec {
                natural_frequency_hz: m.natural_frequency_hz,
                damping_ratio: m.damping_ratio,
                share: m.share,
            }),
            first_order_hold: d.first_order_hold,
        })
    }
}

/// The grey-box variants: one mode on the output (the default), or two modes on each path
/// with the second's share the path's own and the input's hold between samples fitted
/// (`modes`: a 2-DoF cross path through both axes' modes, a bender's second mode, a
/// continuous input sampled).
pub const VARIANTS: [Variant; 2] = [
    Variant {
        name: "dynamics",
        file: "one-mode",
        warm_start: None,
    },
    Variant {
        name: "modes",
        file: "two-modes",
        warm_start: None,
    },
];

/// Linear dynamics as an effect of the library.
pub struct DynamicsEffect;

/// The zoo's dynamics: a mode with natural frequency log-uniform from Nyquist / 100 to
/// Nyquist / 3 and damping ratio log-uniform 0.02-0.7 (unit static gain). A quasi-static plant
/// is one the zoo gives no dynamics.
pub fn draw(ctx: &DrawContext, dice: &mut Dice) -> DynamicsSpec {
    let nyquist = 0.5 / ctx.ts;
    DynamicsSpec {
        natural_frequency_hz: dice.log_uniform(nyquist / 100.0, nyquist / 3.0),
        damping_ratio: dice.log_uniform(0.02, 0.7),
        dc_gain: 1.0,
        second_mode: None,
        first_order_hold: 0.0,
    }
}

/// A second mode and a hold drawn on top of `base` (the zoo's `--extra dynamics`): the second
/// mode 1.5 to 5 times the first's frequency (below Nyquist/2), damping 0.02 to 0.3, a share
/// of 0.05 to 0.5 of either sign, and a hold between zero- and first-order uniform in [0, 1]
/// (what the plants written apart showed the one-mode family misses, docs/benchmarks.md).
pub fn draw_on_top(base: &DynamicsSpec, ts: f64, dice: &mut Dice) -> DynamicsSpec {
    let nyquist = 0.5 / ts;
    let f2 = (base.natural_frequency_hz * dice.log_uniform(1.5, 5.0)).min(0.5 * nyquist);
    let share = dice.log_uniform(0.05, 0.5) * if dice.chance(0.25) { -1.0 } else { 1.0 };
    DynamicsSpec {
        second_mode: Some(ModeSpec {
            natural_frequency_hz: f2.max(base.natural_frequency_hz * 1.01),
            damping_ratio: dice.log_uniform(0.02, 0.3),
            share,
        }),
        first_order_hold: dice.uniform(0.0, 1.0),
        ..*base
    }
}

impl Effect for DynamicsEffect {
    fn name(&self) -> EffectName {
        NAME
    }
    fn summary(&self) -> &'static str {
        "a second-order mode (natural frequency, damping) on a path or an output"
    }
    fn slot(&self) -> Slot {
        Slot::Filter
    }
    fn parse_spec(
        &self,
        d: &mut dyn erased_serde::Deserializer<'_>,
    ) -> Result<Box<dyn EffectSpec>, erased_serde::Error> {
        parse_spec::<DynamicsSpec>(d)
    }
    /// A lightly damped 60 Hz mode.
    fn example(&self) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(DynamicsSpec {
            natural_frequency_hz: 60.0,
            damping_ratio: 0.04,
            dc_gain: 1.0,
            second_mode: None,
            first_order_hold: 0.0,
        }))
    }
    fn draw(&self, ctx: &DrawContext, dice: &mut Dice) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(draw(ctx, dice)))
    }
    /// An output without dynamics: a mode as the zoo draws it, with a second mode and a hold.
    fn draw_on_output(
        &self,
        _output: &[f64],
        ts: f64,
        dice: &mut Dice,
    ) -> Option<Box<dyn EffectSpec>> {
        let nyquist = 0.5 / ts;
        let base = DynamicsSpec::mode(
            dice.log_uniform(nyquist / 100.0, nyquist / 3.0),
            dice.log_uniform(0.02, 0.7),
        );
        Some(Box::new(draw_on_top(&base, ts, dice)))
    }
    /// A mode without a second one: a second mode and a hold on top of it.
    fn draw_onto(
        &self,
        existing: &dyn EffectSpec,
        _output: &[f64],
        ts: f64,
        dice: &mut Dice,
    ) -> Option<Box<dyn EffectSpec>> {
        let base = existing.as_any().downcast_ref::<DynamicsSpec>()?;
        if base.second_mode.is_some() {
            return None;
        }
        Some(Box::new(draw_on_top(base, ts, dice)))
    }
    fn basis<'a>(&self, ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
        Some(basis(ctx))
    }
    fn evidence(&self, _ctx: &EvidenceContext) -> String {
        "the error follows the recent past of the output: a fast linear dynamics (a mode, a lag) is not in the model".to_string()
    }
    fn feature_kinds(&self) -> &'static [FeatureKind] {
        std::slice::from_ref(&RESONATOR)
    }
    /// For each input, resonators (zeta 0.1) from the dynamics bank's ladder (50 / span ..
    /// 0.35 / ts, x1.3), thinned to [`MAX_RESONATOR_FEATURES`].
    fn features(&self, inputs: &[&[f64]], ts: f64) -> Vec<FeatureSpec> {
        let n = inputs.first().map_or(0, |u| u.len());
        let span = n as f64 * ts;
        let mut out = Vec::new();
        for j in 0..inputs.len() {
            let mut fs = Vec::new();
            let mut f = (50.0 / span).max(1.0);
            while f <= 0.35 / ts {
                fs.push(f);
                f *= 1.3;
            }
            let m = fs.len().min(MAX_RESONATOR_FEATURES);
            for i in 0..m {
                let idx = if m > 1 {
                    i * (fs.len() - 1) / (m - 1)
                } else {
                    0
                };
                out.push(FeatureSpec::new(&RESONATOR, j, vec![fs[idx], 0.1]));
            }
        }
        out
    }
    fn variants(&self) -> &'static [Variant] {
        &VARIANTS
    }
    fn filter(&self, setup: &OutputSetup) -> Option<Box<dyn FilterFit>> {
        let fs = 1.0 / setup.ts;
        let f_bounds = (fs / setup.samples.clamp(1, 1000) as f64, 0.49 * fs);
        let z_bounds = (2e-3, 5.0);
        if setup.variant == 1 {
            return Some(Box::new(ModesFilter {
                ts: setup.ts,
                f_bounds,
                z_bounds,
                paths: setup.paths.max(1),
            }));
        }
        Some(Box::new(DynamicsFilter {
            ts: setup.ts,
            f_bounds,
            z_bounds,
        }))
    }
    fn parameter_count(&self, size: super::fitting::BasisSize) -> (usize, usize) {
        match size.variant {
            1 => (1, MODES_SHARED),
            _ => (0, 2),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_filtered_side_by_side_equal_each_filtered_alone() {
        let d = DynamicsSpec {
            natural_frequency_hz: 40.0,
            damping_ratio: 0.05,
            dc_gain: 1.0,
            second_mode: None,
            first_order_hold: 0.0,
        }
        .check()
        .unwrap();
        let Prepared::Apply(f) = prepared(&d, 1e-3) else {
            panic!("a valid filter")
        };
        // six columns (a group of four, then two alone), one of another length
        let cols: Vec<Vec<f64>> = (0..6)
            .map(|j| {
                let n = if j == 2 { 700 } else { 1000 };
                (0..n)
                    .map(|k| ((k * (j + 1)) as f64 * 0.01).sin())
                    .collect()
            })
            .collect();
        let each_alone = |cols: &[Vec<f64>]| -> Vec<Vec<f64>> {
            cols.iter()
                .map(|c| {
                    let mut c = c.clone();
                    f(&mut [c.as_mut_slice()], &mut [Vec::new()]);
                    c
                })
                .collect()
        };
        let together = |mut cols: Vec<Vec<f64>>| -> Vec<Vec<f64>> {
            let mut slices: Vec<&mut [f64]> = cols.iter_mut().map(Vec::as_mut_slice).collect();
            let mut states = vec![Vec::new(); slices.len()];
            f(&mut slices, &mut states);
            cols
        };
        let alone = each_alone(&cols);
        assert_eq!(together(cols), alone);
        // and five distinct columns of one length: a group of four takes the four-wide path
        let same: Vec<Vec<f64>> = [0, 1, 3, 4, 5].map(|j| alone[j].clone()).to_vec();
        assert_eq!(together(same.clone()), each_alone(&same));
        // in blocks, each resuming from the state the last one left: the same bits
        let in_blocks = |mut blocks: Vec<Vec<f64>>| -> Vec<Vec<f64>> {
            let mut states = vec![Vec::new(); blocks.len()];
            for rows in [0..1, 1..300, 300..301, 301..1000] {
                let mut slices: Vec<&mut [f64]> =
                    blocks.iter_mut().map(|c| &mut c[rows.clone()]).collect();
                f(&mut slices, &mut states);
            }
            blocks
        };
        assert_eq!(in_blocks(same.clone()), each_alone(&same));
        // thirteen columns of one length (eight in the lanes of AVX-512 registers where the
        // processor has it, then four, then one), whole and in blocks: the same bits
        let many: Vec<Vec<f64>> = (0..13)
            .map(|j| {
                (0..1000)
                    .map(|k| ((k * (j + 2)) as f64 * 0.013).cos())
                    .collect()
            })
            .collect();
        let want = each_alone(&many);
        let bits = |c: &[Vec<f64>]| -> Vec<Vec<u64>> {
            c.iter()
                .map(|c| c.iter().map(|v| v.to_bits()).collect())
                .collect()
        };
        assert_eq!(bits(&together(many.clone())), bits(&want));
        assert_eq!(bits(&in_blocks(many)), bits(&want));
    }

    #[test]
    fn two_modes_side_by_side_equal_each_filtered_alone() {
        let filter = ModesFilter {
            ts: 1e-3,
            f_bounds: (1.0, 400.0),
            z_bounds: (0.01, 2.0),
            paths: 1,
        };
        let th = filter.params_of((40.0, 0.05), 0.4, (150.0, 0.1), 0.3);
        let Prepared::Apply(f) = filter.prepare_path(&th, 0) else {
            panic!("a valid filter")
        };
        let col = |j: usize, n: usize| -> Vec<f64> {
            (0..n)
                .map(|k| ((k * (j + 2)) as f64 * 0.013).cos() + (k % 7) as f64 * 0.1)
                .collect()
        };
        // eleven columns of one length (two groups of four side by side, then three alone),
        // and one of another length among them
        let mut cols: Vec<Vec<f64>> = (0..11).map(|j| col(j, 1001)).collect();
        cols[5] = col(5, 700);
        let alone: Vec<Vec<u64>> = cols
            .iter()
            .map(|c| {
                let mut c = c.clone();
                f(&mut [c.as_mut_slice()], &mut [Vec::new()]);
                c.iter().map(|v| v.to_bits()).collect()
            })
            .collect();
        let together = |mut cols: Vec<Vec<f64>>, blocks: &[std::ops::Range<usize>]| {
            let mut states = vec![Vec::new(); cols.len()];
            for rows in blocks {
                let mut slices: Vec<&mut [f64]> = cols
                    .iter_mut()
                    .map(|c| {
                        let end = rows.end.min(c.len());
                        &mut c[rows.start.min(end)..end]
                    })
                    .collect();
                f(&mut slices, &mut states);
            }
            cols.iter()
                .map(|c| c.iter().map(|v| v.to_bits()).collect::<Vec<u64>>())
                .collect::<Vec<_>>()
        };
        let whole = 0..1001;
        assert_eq!(together(cols.clone(), std::slice::from_ref(&whole)), alone);
        // in blocks, each resuming from the state the last one left: the same bits
        let blocks = [0..1, 1..302, 302..303, 303..1001];
        assert_eq!(together(cols, &blocks), alone);
    }

    #[test]
    fn step_response_matches_closed_form() {
        for zeta in [0.03, 0.7, 1.0, 2.0] {
            let d = DynamicsSpec {
                natural_frequency_hz: 40.0,
                damping_ratio: zeta,
                dc_gain: 1.0,
                second_mode: None,
                first_order_hold: 0.0,
            }
            .check()
            .unwrap();
            let ts = 1e-3;
            let y = d.operator(ts).unwrap().apply(&[1.0; 400]);
            for (k, yk) in y.iter().enumerate() {
                let exact = d.step_response(k as f64 * ts);
                assert!(
                    (yk - exact).abs() < 1e-12,
                    "zeta {zeta} k {k}: {yk} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn above_nyquist_is_refused() {
        let d = DynamicsSpec {
            natural_frequency_hz: 800.0,
            damping_ratio: 0.03,
            dc_gain: 1.0,
            second_mode: None,
            first_order_hold: 0.0,
        }
        .check()
        .unwrap();
        assert!(d
            .operator(1e-3)
            .unwrap_err()
            .to_string()
            .contains("Nyquist"));
    }

    /// The first-order (triangle) hold is the continuous mode driven by the input ramped
    /// linearly between samples (fine RK4 integration); a blend is the two holds' outputs in
    /// proportion; the hold's output follows a step within its sample.
    #[test]
    fn the_first_order_hold_is_the_mode_under_a_ramped_input() {
        let (f, z, ts) = (50.0, 0.05, 1e-3);
        let w: Vec<f64> = (0..300)
            .map(|k| (k as f64 * 0.07).sin() + 0.3 * (k as f64 * 0.31).cos())
            .collect();
        let with = |h: f64| {
            let mut d = DynamicsSpec::mode(f, z);
            d.first_order_hold = h;
            d.check().unwrap().operator(ts).unwrap().apply(&w)
        };
        let wn = 2.0 * std::f64::consts::PI * f;
        // from rest a sample before the record, the input ramped from 0 to its first value
        // (what the discrete hold assumes of the sample before the first)
        let wr: Vec<f64> = std::iter::once(0.0).chain(w.iter().copied()).collect();
        let (mut x, mut v) = (0.0f64, 0.0f64);
        let sub = 200;
        let dt = ts / sub as f64;
        let mut exact = Vec::new();
        for k in 0..wr.len() - 1 {
            let rhs = |x: f64, v: f64, t: f64| {
                let u = wr[k] + (wr[k + 1] - wr[k]) * t / ts;
                (v, wn * wn * (u - x) - 2.0 * z * wn * v)
            };
            for i in 0..sub {
                let t = i as f64 * dt;
                let k1 = rhs(x, v, t);
                let k2 = rhs(x + 0.5 * dt * k1.0, v + 0.5 * dt * k1.1, t + 0.5 * dt);
                let k3 = rhs(x + 0.5 * dt * k2.0, v + 0.5 * dt * k2.1, t + 0.5 * dt);
                let k4 = rhs(x + dt * k3.0, v + dt * k3.1, t + dt);
                x += dt / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
                v += dt / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
            }
            exact.push(x);
        }
        let ramp = with(1.0);
        let err = ramp
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "first-order hold vs integration: {err}");
        let (held, half) = (with(0.0), with(0.5));
        for k in 0..w.len() {
            assert!((half[k] - 0.5 * (held[k] + ramp[k])).abs() < 1e-12);
        }
        // a step: held, nothing at its sample; ramped, the response has begun
        let step = |h: f64| {
            let mut d = DynamicsSpec::mode(f, z);
            d.first_order_hold = h;
            d.check()
                .unwrap()
                .operator(ts)
                .unwrap()
                .apply(&[0.0, 1.0, 1.0])
        };
        assert_eq!(step(0.0)[1], 0.0);
        assert!(step(1.0)[1] > 0.0);
    }

    /// Two modes in parallel are the sum of each alone at its share of the static gain; a
    /// plant file without the new fields reads and writes as before.
    #[test]
    fn a_second_mode_adds_in_parallel_and_old_files_are_unchanged() {
        let ts = 1e-3;
        let w: Vec<f64> = (0..400).map(|k| (k as f64 * 0.05).sin()).collect();
        let mut d = DynamicsSpec::mode(20.0, 0.1);
        d.dc_gain = 2.0;
        d.second_mode = Some(ModeSpec {
            natural_frequency_hz: 90.0,
            damping_ratio: 0.03,
            share: 0.3,
        });
        let both = d.check().unwrap().operator(ts).unwrap().apply(&w);
        let alone = |f: f64, z: f64, g: f64| {
            let mut m = DynamicsSpec::mode(f, z);
            m.dc_gain = g;
            m.check().unwrap().operator(ts).unwrap().apply(&w)
        };
        let (a, b) = (alone(20.0, 0.1, 1.4), alone(90.0, 0.03, 0.6));
        for k in 0..w.len() {
            assert!((both[k] - a[k] - b[k]).abs() < 1e-12);
        }
        let text = r#"{"natural_frequency_hz":20.0,"damping_ratio":0.1,"dc_gain":1.0}"#;
        let old: DynamicsSpec = serde_json::from_str(text).unwrap();
        assert_eq!(old, DynamicsSpec::mode(20.0, 0.1));
        assert_eq!(serde_json::to_string(&old).unwrap(), text);
        let mut bad = DynamicsSpec::mode(20.0, 0.1);
        bad.first_order_hold = 1.5;
        assert!(bad
            .check()
            .unwrap_err()
            .to_string()
            .contains("first_order_hold"));
        d.second_mode = Some(ModeSpec {
            natural_frequency_hz: 600.0,
            damping_ratio: 0.03,
            share: 0.3,
        });
        let e = d.check().unwrap().operator(ts).unwrap_err().to_string();
        assert!(
            e.contains("second_mode.natural_frequency_hz") && e.contains("Nyquist"),
            "{e}"
        );
    }

    /// Signals each with its own two modes, side by side in register lanes (eight, then four,
    /// then alone: 13 signals, one of another length), give the bits of each filtered alone.
    #[test]
    fn two_modes_side_by_side_equal_each_alone() {
        let ts = 1e-3;
        let modes: Vec<(Discrete, Discrete)> = (0..13)
            .map(|i| {
                let f = 10.0 + 7.0 * i as f64;
                let h = if i % 3 == 0 { 0.0 } else { 0.5 };
                (
                    discretise_mode(f, 0.05 + 0.01 * i as f64, 0.7, h, ts, "f").unwrap(),
                    discretise_mode(3.0 * f, 0.2, 0.3, h, ts, "f").unwrap(),
                )
            })
            .collect();
        let signal = |i: usize, n: usize| -> Vec<f64> {
            (0..n)
                .map(|k| ((k * (i + 1)) as f64 * 0.013).sin() + 0.1 * i as f64)
                .collect()
        };
        for odd in [None, Some(9)] {
            let lens: Vec<usize> = (0..13)
                .map(|i| if Some(i) == odd { 1001 } else { 1003 })
                .collect();
            let mut side: Vec<Vec<f64>> = (0..13).map(|i| signal(i, lens[i])).collect();
            let mut alone = side.clone();
            let pairs: Vec<ModePair<'_>> = modes.iter().map(|(a, b)| (a, b)).collect();
            let mut cols: Vec<&mut [f64]> = side.iter_mut().map(|c| c.as_mut_slice()).collect();
            let mut states = vec![FilterState::new(); 13];
            two_modes_each(&pairs, &mut cols, &mut states);
            for (i, c) in alone.iter_mut().enumerate() {
                let mut st = FilterState::new();
                two_modes(&modes[i].0, &modes[i].1, c, &mut st);
                assert_eq!(st, states[i], "signal {i}: state");
            }
            for i in 0..13 {
                let same = side[i]
                    .iter()
                    .zip(&alone[i])
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "signal {i} (odd length at {odd:?})");
            }
        }
    }

    /// The modes filter's derivatives computed together give the bits of each alone (and
    /// zeros for another path's share).
    #[test]
    fn modes_derivatives_together_equal_each_alone() {
        let filter = ModesFilter {
            ts: 1e-3,
            f_bounds: (0.5, 400.0),
            z_bounds: (0.005, 2.0),
            paths: 2,
        };
        let th = filter.params_of((35.0, 0.08), 0.4, (120.0, 0.05), 0.2);
        let x: Vec<f64> = (0..777).map(|k| (k as f64 * 0.021).sin().powi(3)).collect();
        let qs: Vec<usize> = (0..filter.n_params()).collect();
        // a parameter's central difference from the filter prepared at each side, alone
        let filtered = |th: &[f64], path: usize| match filter.prepare_path(th, path) {
            Prepared::Apply(f) => {
                let mut out = x.clone();
                f(&mut [&mut out], &mut [Vec::new()]);
                out
            }
            _ => vec![f64::NAN; x.len()],
        };
        let alone = |q: usize, path: usize| -> Vec<f64> {
            if q >= MODES_SHARED && q != MODES_SHARED + path {
                return vec![0.0; x.len()];
            }
            let (mut lo, mut hi) = (th.clone(), th.clone());
            lo[q] -= FD_STEP;
            hi[q] += FD_STEP;
            let (a, b) = (filtered(&lo, path), filtered(&hi, path));
            b.iter()
                .zip(&a)
                .map(|(b, a)| (b - a) / (2.0 * FD_STEP))
                .collect()
        };
        for path in 0..2 {
            let together = filter.derivatives_path(&th, &x, &qs, path).unwrap();
            for &q in &qs {
                let one = filter.derivative_path(&th, &x, q, path);
                assert!(one
                    .iter()
                    .zip(&together[q])
                    .all(|(a, b)| a.to_bits() == b.to_bits()));
                let alone = alone(q, path);
                let same = together[q]
                    .iter()
                    .zip(&alone)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "path {path}, parameter {q}");
            }
            assert!(together[MODES_SHARED + 1 - path].iter().all(|&v| v == 0.0));
        }
    }

    #[test]
    fn negative_damping_rejected() {
        let s = DynamicsSpec {
            natural_frequency_hz: 10.0,
            damping_ratio: -0.1,
            dc_gain: 1.0,
            second_mode: None,
            first_order_hold: 0.0,
        };
        assert!(s.check().unwrap_err().to_string().contains("damping_ratio"));
    }
}
