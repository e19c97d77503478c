//! # Creep
//!
//! Linear creep as a chain of Kelvin-Voigt elements acting on the hysteresis output w:
//! w_c = (1 + sum_i g_i / (tau_i s + 1)) w. Each element is discretised exactly under a
//! zero-order hold: z_i(k+1) = a_i z_i(k) + (1 - a_i) w(k), a_i = exp(-Ts / tau_i), and
//! w_c(k) = w(k) + sum_i g_i z_i(k).
//!
//! With one time constant per decade and g_i = gamma, the step response follows the logarithmic
//! law w_c(t) ~ w [1 + gamma log10(t / t0)] over the covered decades ([`CreepSpec::from_log_rate`]).
//!
//! ## References
//! - D. Croft, G. Shedd, S. Devasia, ASME JDSMC 123(1):35-43, 2001.
//! - M. Rakotondrabe, C. Clevy, P. Lutz, IEEE T-ASE 7(3):440-450, 2010.
//! - Physik Instrumente, "Piezo tutorial: creep" (1-2 % per decade).

use super::basis::{BasisBank, BasisContext, EvidenceContext, Signal};
use super::draw::{Dice, DrawContext};
use super::feature::{FeatureKind, FeatureSpec};
use super::fitting::{
    FilterFit, FilterState, OutputSetup, Prepared, RecordError, RecordView, Variant,
};
use super::spec::{parse_spec, BoxedOperator, EffectSpec, Params, Spec};
use super::{finite, positive, Effect, EffectError, EffectName, Operator, Slot};
use serde::{Deserialize, Serialize};

/// The effect's name.
pub const NAME: EffectName = EffectName::new("creep");

/// Creep parameters as written in a plant file: the time constants and either the gains or a
/// logarithmic creep rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CreepSpec {
    /// tau_i in seconds, strictly increasing.
    pub time_constants_s: Vec<f64>,
    /// g_i (dimensionless), one per time constant.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gains: Option<Vec<f64>>,
    /// Creep rate in percent of the step per decade of time; sets the gains.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub percent_per_decade: Option<f64>,
}

/// Valid creep parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Creep {
    pub time_constants_s: Vec<f64>,
    pub gains: Vec<f64>,
}

impl CreepSpec {
    /// Gains from a logarithmic creep rate: g_i = gamma * log10 of the local ratio of time constants.
    pub fn from_log_rate(percent_per_decade: f64, time_constants_s: Vec<f64>) -> CreepSpec {
        CreepSpec {
            time_constants_s,
            gains: None,
            percent_per_decade: Some(percent_per_decade),
        }
    }

    /// Check the parameters.
    pub fn check(&self) -> Result<Creep, EffectError> {
        let taus = &self.time_constants_s;
        if taus.is_empty() {
            return Err(EffectError::Shape {
                field: "time_constants_s".into(),
                rule: "needs at least one time constant".into(),
            });
        }
        for (i, &t) in taus.iter().enumerate() {
            positive(&format!("time_constants_s[{i}]"), t)?;
            if i > 0 && t <= taus[i - 1] {
                return Err(EffectError::Invalid {
                    field: format!("time_constants_s[{i}]"),
                    value: t,
                    rule: "time constants must be strictly increasing".into(),
                });
            }
        }
        let gains = match (&self.gains, self.percent_per_decade) {
            (Some(g), None) => {
                if g.len() != taus.len() {
                    return Err(EffectError::Shape {
                        field: "gains".into(),
                        rule: format!(
                            "has {} entries but there are {} time constants",
                            g.len(),
                            taus.len()
                        ),
                    });
                }
                for (i, &v) in g.iter().enumerate() {
                    finite(&format!("gains[{i}]"), v)?;
                }
                g.clone()
            }
            (None, Some(rate)) => {
                finite("percent_per_decade", rate)?;
                log_rate_gains(rate / 100.0, taus)
            }
            _ => {
                return Err(EffectError::Shape {
                    field: "gains".into(),
                    rule: "give exactly one of `gains` and `percent_per_decade`".into(),
                })
            }
        };
        Ok(Creep {
            time_constants_s: taus.clone(),
            gains,
        })
    }
}

/// Gains that give `gamma` per decade for the given (log-spaced) time constants.
pub fn log_rate_gains(gamma: f64, taus: &[f64]) -> Vec<f64> {
    let n = taus.len();
    (0..n)
        .map(|i| {
            let span = if n == 1 {
                1.0
            } else if i == 0 {
                (taus[1] / taus[0]).log10()
            } else if i == n - 1 {
                (taus[n - 1] / taus[n - 2]).log10()
            } else {
                0.5 * (taus[i + 1] / taus[i - 1]).log10()
            };
            gamma * span
        })
        .collect()
}

impl Creep {
    /// The operator for sampling period `ts`, at rest.
    pub fn operator(&self, ts: f64) -> CreepOp {
        CreepOp {
            a: self
                .time_constants_s
                .iter()
                .map(|t| (-ts / t).exp())
                .collect(),
            g: self.gains.clone(),
            z: vec![0.0; self.gains.len()],
        }
    }

    /// Closed-form response at time t after a unit step applied at t = 0 (continuous time).
    pub fn step_response(&self, t: f64) -> f64 {
        1.0 + self
            .gains
            .iter()
            .zip(&self.time_constants_s)
            .map(|(g, tau)| g * (1.0 - (-t / tau).exp()))
            .sum::<f64>()
    }
}

/// A running creep chain.
#[derive(Debug, Clone, PartialEq)]
pub struct CreepOp {
    a: Vec<f64>,
    g: Vec<f64>,
    z: Vec<f64>,
}

impl Operator for CreepOp {
    fn reset(&mut self) {
        self.z.fill(0.0);
    }

    #[inline]
    fn step(&mut self, w: f64) -> f64 {
        let mut out = w;
        for ((z, &a), &g) in self.z.iter_mut().zip(&self.a).zip(&self.g) {
            out += g * *z;
            *z = a * *z + (1.0 - a) * w;
        }
        out
    }
}

/// One Kelvin-Voigt state (a first-order lag of time constant `tau`, exact under a zero-order
/// hold, starting at the first sample's value), one sample at a time.
#[derive(Debug, Clone)]
pub struct KelvinVoigtState {
    a: f64,
    z: Option<f64>,
}

impl KelvinVoigtState {
    pub fn new(tau: f64, ts: f64) -> KelvinVoigtState {
        KelvinVoigtState {
            a: (-ts / tau).exp(),
            z: None,
        }
    }
}

impl Operator for KelvinVoigtState {
    fn reset(&mut self) {
        self.z = None;
    }
    fn step(&mut self, v: f64) -> f64 {
        let z = self.z.unwrap_or(v);
        self.z = Some(self.a * z + (1.0 - self.a) * v);
        z
    }
}

/// Basis bank: slow first-order states of the model's prediction, time constants one per half
/// decade from 20 samples (at least 0.05 s) up to a third of the record.
pub fn basis<'a>(ctx: &BasisContext<'a>) -> BasisBank<'a> {
    let mut bank = BasisBank::new(NAME);
    let span = ctx.len() as f64 * ctx.ts;
    let mut tau = (20.0 * ctx.ts).max(0.05);
    while tau <= span / 3.0 {
        bank.push(
            format!("creep state(tau={tau:.3} s)"),
            Signal::samples(ctx.prediction).through(Box::new(KelvinVoigtState::new(tau, ctx.ts))),
        );
        tau *= 10f64.sqrt();
    }
    bank
}

impl Spec for CreepSpec {
    const EFFECT: EffectName = NAME;
    type Params = Creep;
    fn check(&self) -> Result<Creep, EffectError> {
        CreepSpec::check(self)
    }
}

impl Params for Creep {
    const EFFECT: EffectName = NAME;
    fn operator(&self, ts: f64) -> Result<BoxedOperator, EffectError> {
        Ok(Box::new(Creep::operator(self, ts)))
    }
}

/// The NARX feature: a first-order (Kelvin-Voigt) state of an input, starting at the input's
/// first value (the creep bank's filter).
pub static FIRST_ORDER: FeatureKind = FeatureKind {
    name: "first_order",
    params: &["tau_s"],
    valid: |p| p[0].is_finite() && p[0] > 0.0,
    label: |n, p| format!("first_order({n}, tau={:.4} s)", p[0]),
    operator: |p, ts| Box::new(KelvinVoigtState::new(p[0], ts)),
};

/// Creep time constants for the grey-box model: one per decade (powers of ten) from about 5
/// samples to about a third of the record. `Err(needed samples)` when fewer than three (two
/// decades) fit, or with `parsimonious` fewer than one.
pub fn creep_time_constants(
    samples: usize,
    ts: f64,
    parsimonious: bool,
) -> Result<Vec<f64>, usize> {
    time_constants_over(samples, ts, least_decades(parsimonious, 0))
}

/// The decades of time constants a grey-box variant needs at least: two in general, on a
/// parsimonious fit none (one time constant), or one for `log-creep` (two time constants: a
/// rate per decade to go on with).
fn least_decades(parsimonious: bool, variant: usize) -> i32 {
    match (parsimonious, variant) {
        (false, _) => 2,
        (true, LOG_CREEP) => 1,
        (true, _) => 0,
    }
}

/// Powers of ten from about 5 samples to about a third of the record, over `decades` at
/// least (else `Err(needed samples)`).
fn time_constants_over(samples: usize, ts: f64, decades: i32) -> Result<Vec<f64>, usize> {
    let k_min = (5.0 * ts).log10().ceil() as i32;
    let span = samples as f64 * ts / 3.0;
    // the largest power of ten up to about twice a third of the record
    let k_max = (span.log10() + 0.3).floor() as i32;
    if k_max < k_min + decades {
        let needed = (3.0 * 10f64.powf(k_min as f64 + decades as f64 - 0.3) / ts).ceil() as usize;
        return Err(needed);
    }
    Ok((k_min..=k_max).map(|k| 10f64.powi(k)).collect())
}

/// The longest run of samples over which the signal stays within 1e-6 of its range.
pub fn longest_hold(u: &[f64]) -> usize {
    let tol = 1e-6 * crate::metrics::ptp(u);
    let (mut best, mut run) = (0, 1);
    for w in u.windows(2) {
        if (w[1] - w[0]).abs() <= tol {
            run += 1;
        } else {
            run = 1;
        }
        best = best.max(run);
    }
    best
}

/// Fraction of the (mean-removed) input variance that passes a first-order low-pass of time
/// constant `tau`.
pub fn slow_fraction(u: &[f64], ts: f64, tau: f64) -> f64 {
    let m = crate::metrics::mean(u);
    let a = (-ts / tau).exp();
    let mut z = 0.0;
    let (mut num, mut den) = (0.0, 0.0);
    for &v in u {
        let x = v - m;
        z = a * z + (1.0 - a) * x;
        num += z * z;
        den += x * x;
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

/// Mean slope of the error against log10(time since the step) over the holds, and their count.
pub fn creep_drift(u: &[f64], e: &[f64], ts: f64) -> Option<(f64, usize)> {
    let hs = crate::metrics::holds(u, ts);
    let mut slopes = Vec::new();
    for &(a, b) in &hs {
        // skip the first 5 % (dynamics settling) and 10 samples at least
        let skip = ((b - a) / 20).max(10);
        let (x, y): (Vec<f64>, Vec<f64>) = (a + skip..b)
            .map(|k| (((k - a) as f64 * ts).log10(), e[k]))
            .unzip();
        if x.len() < 10 {
            continue;
        }
        let c = crate::numeric::ridge::fit(&[&x], &y, 0..x.len(), true)?;
        slopes.push(c[0]);
    }
    if slopes.is_empty() {
        return None;
    }
    Some((
        slopes.iter().map(|s| s.abs()).sum::<f64>() / slopes.len() as f64,
        slopes.len(),
    ))
}

/// The grey-box filter: a Kelvin-Voigt chain with fixed time constants, gains free (held at 0
/// in the first stage so that the fast dynamics settle first).
struct CreepFilter {
    taus: Vec<f64>,
    /// Time constants beyond the record that share the last fitted gain (the logarithmic
    /// law continued).
    tail: Vec<f64>,
    ts: f64,
}

impl CreepFilter {
    /// Every time constant: the fitted ones, then the tail.
    fn all_taus(&self) -> Vec<f64> {
        self.taus.iter().chain(&self.tail).copied().collect()
    }
    /// The gains of [`CreepFilter::all_taus`]: the parameters, then the last one again for
    /// each time constant of the tail.
    fn all_gains(&self, th: &[f64]) -> Vec<f64> {
        let last = th.last().copied().unwrap_or(0.0);
        th.iter()
            .copied()
            .chain(std::iter::repeat_n(last, self.tail.len()))
            .collect()
    }
}

impl FilterFit for CreepFilter {
    fn n_params(&self) -> usize {
        self.taus.len()
    }
    fn initial(&self) -> Vec<f64> {
        vec![0.0; self.taus.len()]
    }
    fn held_first(&self) -> bool {
        true
    }
    fn prepare(&self, th: &[f64]) -> Prepared {
        if th.iter().all(|g| *g == 0.0) {
            return Prepared::Identity;
        }
        let a: Vec<f64> = self
            .all_taus()
            .iter()
            .map(|t| (-self.ts / t).exp())
            .collect();
        let g = self.all_gains(th);
        Prepared::Apply(Box::new(
            move |cols: &mut [&mut [f64]], states: &mut [FilterState]| {
                debug_assert_eq!(cols.len(), states.len(), "a state per signal");
                for z in states.iter_mut().filter(|z| z.is_empty()) {
                    z.resize(a.len(), 0.0);
                }
                crate::numeric::simd::wide(
                    #[inline(always)]
                    || {
                        for (group, st) in cols.chunks_mut(4).zip(states.chunks_mut(4)) {
                            match (group, st) {
                                ([c0, c1, c2, c3], [z0, z1, z2, z3])
                                    if [c1.len(), c2.len(), c3.len()] == [c0.len(); 3] =>
                                {
                                    let mut z: Vec<[f64; 4]> = (0..a.len())
                                        .map(|i| [z0[i], z1[i], z2[i], z3[i]])
                                        .collect();
                                    kelvin_voigt4(&a, &g, [c0, c1, c2, c3], &mut z);
                                    for (i, zi) in z.iter().enumerate() {
                                        [z0[i], z1[i], z2[i], z3[i]] = *zi;
                                    }
                                }
                                (group, st) => {
                                    for (out, z) in group.iter_mut().zip(st.iter_mut()) {
                                        kelvin_voigt(&a, &g, out, z);
                                    }
                                }
                            }
                        }
                    },
                );
            },
        ))
    }
    fn derivative(&self, _th: &[f64], x: &[f64], q: usize) -> Vec<f64> {
        // the last gain also drives the tail
        let taus: Vec<f64> = if q + 1 == self.taus.len() {
            std::iter::once(self.taus[q])
                .chain(self.tail.iter().copied())
                .collect()
        } else {
            vec![self.taus[q]]
        };
        let one = Creep {
            gains: vec![1.0; taus.len()],
            time_constants_s: taus,
        };
        one.operator(self.ts)
            .apply(x)
            .iter()
            .zip(x)
            .map(|(a, b)| a - b)
            .collect()
    }
    fn spec(&self, th: &[f64]) -> Box<dyn EffectSpec> {
        Box::new(CreepSpec {
            time_constants_s: self.all_taus(),
            gains: Some(self.all_gains(th)),
            percent_per_decade: None,
        })
    }
}

/// The Kelvin-Voigt chain (pole `a_i`, gain `g_i` per element) on one signal in place, from
/// the elements' states `z` (updated): `o = w + sum_i g_i z_i`, then `z_i <- a_i z_i + (1 -
/// a_i) w`.
#[inline(always)]
fn kelvin_voigt(a: &[f64], g: &[f64], out: &mut [f64], z: &mut [f64]) {
    for v in out.iter_mut() {
        let w = *v;
        let mut o = w;
        for ((zi, &ai), &gi) in z.iter_mut().zip(a).zip(g) {
            o += gi * *zi;
            *zi = ai * *zi + (1.0 - ai) * w;
        }
        *v = o;
    }
}

/// [`kelvin_voigt`] on four signals of one length side by side (each signal's arithmetic is
/// the same as alone; the four recursions share their latency), `z[i]` element `i`'s states.
#[inline(always)]
fn kelvin_voigt4(a: &[f64], g: &[f64], cols: [&mut [f64]; 4], z: &mut [[f64; 4]]) {
    let [c0, c1, c2, c3] = cols;
    let n = c0.len();
    let (c1, c2, c3) = (&mut c1[..n], &mut c2[..n], &mut c3[..n]);
    for k in 0..n {
        let w = [c0[k], c1[k], c2[k], c3[k]];
        let mut o = w;
        for ((zi, &ai), &gi) in z.iter_mut().zip(a).zip(g) {
            for l in 0..4 {
                o[l] += gi * zi[l];
                zi[l] = ai * zi[l] + (1.0 - ai) * w[l];
            }
        }
        [c0[k], c1[k], c2[k], c3[k]] = o;
    }
}

/// The decades of time constants beyond the fitted ones that the `log-creep` variant adds,
/// each with the last fitted gain.
pub const LOG_TAIL_DECADES: i32 = 2;

/// The index of the `log-creep` variant in [`VARIANTS`].
const LOG_CREEP: usize = 1;

/// The grey-box variants: the Kelvin-Voigt chain over the decades the record spans, its gains
/// free (the default), or the same chain continued by [`LOG_TAIL_DECADES`] decades beyond
/// the record that share its last gain (`log-creep`): a creep that goes on by the same amount
/// per decade of time after the record ends, the logarithmic law of piezo creep (Physik
/// Instrumente's piezo tutorial; Jung & Gweon, Rev. Sci. Instrum. 71(4):1896-1900, 2000),
/// where the default chain stops creeping after its longest time constant. Which of the two
/// a record holds only a validation part after the fitting part in time can tell. The
/// variant needs two fitted time constants at least: a chain of one has no rate per decade
/// to go on with (its gain holds all the creep up to its time constant).
pub const VARIANTS: [Variant; 2] = [
    Variant {
        name: "creep",
        file: "kelvin-voigt",
        warm_start: None,
    },
    Variant {
        name: "log-creep",
        file: "logarithmic",
        warm_start: None,
    },
];

/// Creep as an effect of the library.
pub struct CreepEffect;

/// The zoo's creep: 1 to 3 time constants log-uniform in 0.05-100 s (at least a factor 2
/// apart), gains from a uniform split of a total creep of 0.5-20 % of the output
/// (log-uniform).
pub fn draw(dice: &mut Dice) -> CreepSpec {
    let k = dice.int(1, 3);
    let mut taus: Vec<f64> = Vec::with_capacity(k);
    while taus.len() < k {
        let t = dice.log_uniform(0.05, 100.0);
        if taus.iter().all(|&s| t / s > 2.0 || s / t > 2.0) {
            taus.push(t);
        }
    }
    taus.sort_by(f64::total_cmp);
    let total = dice.log_uniform(0.005, 0.2);
    let split: Vec<f64> = (0..k).map(|_| dice.uniform(0.2, 1.0)).collect();
    let sum: f64 = split.iter().sum();
    CreepSpec {
        time_constants_s: taus,
        gains: Some(split.iter().map(|w| total * w / sum).collect()),
        percent_per_decade: None,
    }
}

impl Effect for CreepEffect {
    fn name(&self) -> EffectName {
        NAME
    }
    fn summary(&self) -> &'static str {
        "slow drift after each move: a Kelvin-Voigt chain on the output (logarithmic creep)"
    }
    fn slot(&self) -> Slot {
        Slot::OutputFilter
    }
    fn parse_spec(
        &self,
        d: &mut dyn erased_serde::Deserializer<'_>,
    ) -> Result<Box<dyn EffectSpec>, erased_serde::Error> {
        parse_spec::<CreepSpec>(d)
    }
    /// 2.5 % per decade over 0.3 s to 30 s.
    fn example(&self) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(CreepSpec::from_log_rate(
            2.5,
            vec![0.3, 3.0, 30.0],
        )))
    }
    fn draw(&self, _ctx: &DrawContext, dice: &mut Dice) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(draw(dice)))
    }
    fn basis<'a>(&self, ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
        Some(basis(ctx))
    }
    fn evidence(&self, ctx: &EvidenceContext) -> String {
        match creep_drift(ctx.inputs[ctx.direct], ctx.error, ctx.ts) {
            Some((slope, holds)) => format!(
                "after each step the error drifts by {:.3}{} per decade of time ({holds} holds)",
                slope.abs(),
                ctx.unit
            ),
            None => "the error follows slow first-order trends of the output (no holds in the record to measure the drift per decade)".to_string(),
        }
    }
    fn feature_kinds(&self) -> &'static [FeatureKind] {
        std::slice::from_ref(&FIRST_ORDER)
    }
    /// For each input, first-order states with the creep bank's time constants (one per half
    /// decade from 20 samples, at least 0.05 s, up to a third of the record).
    fn features(&self, inputs: &[&[f64]], ts: f64) -> Vec<FeatureSpec> {
        let n = inputs.first().map_or(0, |u| u.len());
        let span = n as f64 * ts;
        let mut out = Vec::new();
        for j in 0..inputs.len() {
            let mut tau = (20.0 * ts).max(0.05);
            while tau <= span / 3.0 {
                out.push(FeatureSpec::new(&FIRST_ORDER, j, vec![tau]));
                tau *= 10f64.sqrt();
            }
        }
        out
    }
    fn no_features(&self) -> &'static str {
        "the record is too short for creep time constants of 20 samples or more"
    }
    fn variants(&self) -> &'static [Variant] {
        &VARIANTS
    }
    fn filter(&self, setup: &OutputSetup) -> Option<Box<dyn FilterFit>> {
        let decades = least_decades(setup.parsimonious, setup.variant);
        let taus = time_constants_over(setup.samples, setup.ts, decades).ok()?;
        let last = taus[taus.len() - 1];
        let tail = if setup.variant == LOG_CREEP {
            (1..=LOG_TAIL_DECADES)
                .map(|k| last * 10f64.powi(k))
                .collect()
        } else {
            Vec::new()
        };
        Some(Box::new(CreepFilter {
            taus,
            tail,
            ts: setup.ts,
        }))
    }
    fn check_record(&self, rec: &RecordView, variant: usize) -> Result<(), RecordError> {
        let (n, ts) = (rec.samples, rec.ts);
        let decades = least_decades(rec.parsimonious, variant);
        let taus = time_constants_over(n, ts, decades).map_err(|needed| RecordError::TooShort {
            needed,
            why: format!(
                "creep needs time constants (powers of ten{}) between 5 samples ({:.3e} s) and a third of the record ({:.3e} s); a longer record holds them",
                match decades {
                    2 => " over at least two decades",
                    1 => " over at least one decade: log-creep goes on at the rate of its last two",
                    _ => "",
                },
                5.0 * ts,
                n as f64 * ts / 3.0
            ),
        })?;
        let tau_mid = (taus[0] * taus[taus.len() - 1]).sqrt();
        for (name, u) in rec.input_names.iter().zip(rec.inputs) {
            let hold = longest_hold(u) as f64 * ts;
            let slow = slow_fraction(u, ts, tau_mid);
            if hold < tau_mid && slow < 0.01 {
                return Err(RecordError::PoorlyExcited {
                    input: name.to_string(),
                    why: format!(
                        "creep needs holds (the input held for {tau_mid:.3} s or more) or slow content (below {:.3} Hz); the longest hold is {hold:.3} s and the slow content carries {:.2} % of the input variance",
                        1.0 / (2.0 * std::f64::consts::PI * tau_mid),
                        100.0 * slow
                    ),
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_signals_side_by_side_are_four_signals_alone() {
        let f = CreepFilter {
            taus: vec![0.05, 1.0, 30.0],
            tail: vec![300.0],
            ts: 1e-3,
        };
        let Prepared::Apply(apply) = f.prepare(&[0.02, -0.01, 0.05]) else {
            panic!("creep with gains is a filter");
        };
        let signal = |j: usize| -> Vec<f64> {
            (0..999)
                .map(|i| (i as f64 * 0.01 * (j + 1) as f64).sin())
                .collect()
        };
        // five signals (four side by side, one alone) in two blocks, states carried over
        let mut together: Vec<Vec<f64>> = (0..5).map(signal).collect();
        let mut states = vec![FilterState::new(); 5];
        for rows in [0..400, 400..999] {
            let mut cols: Vec<&mut [f64]> =
                together.iter_mut().map(|c| &mut c[rows.clone()]).collect();
            apply(&mut cols, &mut states);
        }
        for (j, t) in together.iter().enumerate() {
            let mut alone = signal(j);
            apply(&mut [alone.as_mut_slice()], &mut [FilterState::new()]);
            let same = alone.iter().zip(t).all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "signal {j} differs side by side");
        }
    }

    /// The `log-creep` variant's filter adds 10 and 100 times the longest fitted time
    /// constant; the default adds none; a record that holds one time constant only is refused
    /// for the variant.
    #[test]
    fn the_log_creep_variant_adds_two_decades_and_needs_two_time_constants() {
        let setup = |samples: usize, variant: usize| OutputSetup {
            samples,
            rows: samples,
            blocks: None,
            ts: 1e-3,
            variant,
            parsimonious: true,
            paths: 1,
        };
        let taus = |variant: usize| {
            let f = CreepEffect.filter(&setup(30_000, variant)).unwrap();
            let spec = f.spec(&vec![0.01; f.n_params()]);
            let spec = format!("{spec:?}");
            (f.n_params(), spec)
        };
        let (n0, plain) = taus(0);
        let (n1, log) = taus(LOG_CREEP);
        assert_eq!(n0, n1, "the same free gains");
        assert!(plain.contains("[0.01, 0.1, 1.0, 10.0]"), "{plain}");
        assert!(
            log.contains("[0.01, 0.1, 1.0, 10.0, 100.0, 1000.0]"),
            "{log}"
        );
        let view = |samples: usize| RecordView {
            input_names: &["u"],
            inputs: &[&[0.0; 4]],
            samples,
            ts: 1e-3,
            parsimonious: true,
        };
        // 100 samples: a single time constant (0.01 s) within a third of 0.1 s
        assert_eq!(
            creep_time_constants(100, 1e-3, true).map(|t| t.len()),
            Ok(1)
        );
        let err = CreepEffect.check_record(&view(100), LOG_CREEP).unwrap_err();
        assert!(
            matches!(err, RecordError::TooShort { needed, .. } if needed > 100),
            "{err:?}"
        );
    }

    /// The tail's time constants carry the last fitted gain: in the spec, in the filter, and
    /// in the last parameter's derivative (the filter is linear in its gains, so a central
    /// difference is exact to rounding).
    #[test]
    fn the_tail_carries_the_last_gain() {
        let f = CreepFilter {
            taus: vec![0.01, 0.1],
            tail: vec![1.0, 10.0],
            ts: 1e-3,
        };
        let th = [0.03, 0.02];
        let spec = format!("{:?}", f.spec(&th));
        assert!(spec.contains("[0.01, 0.1, 1.0, 10.0]"), "{spec}");
        assert!(spec.contains("[0.03, 0.02, 0.02, 0.02]"), "{spec}");
        let x: Vec<f64> = (0..3000).map(|i| (i as f64 * 0.004).sin()).collect();
        let run = |th: &[f64]| {
            let Prepared::Apply(apply) = f.prepare(th) else {
                panic!("creep with gains is a filter");
            };
            let mut y = x.clone();
            apply(&mut [y.as_mut_slice()], &mut [FilterState::new()]);
            y
        };
        let h = 1e-3;
        let (up, down) = (run(&[0.03, 0.02 + h]), run(&[0.03, 0.02 - h]));
        let d = f.derivative(&th, &x, 1);
        for k in 0..x.len() {
            let fd = (up[k] - down[k]) / (2.0 * h);
            assert!((fd - d[k]).abs() < 1e-9, "sample {k}: {fd} vs {}", d[k]);
        }
        // the tail moves the output: without it the last gain's derivative is smaller late on
        let alone = CreepFilter {
            taus: f.taus.clone(),
            tail: Vec::new(),
            ts: f.ts,
        }
        .derivative(&th, &x, 1);
        assert!(
            (d[2999] - alone[2999]).abs() > 1e-3,
            "{} {}",
            d[2999],
            alone[2999]
        );
    }

    #[test]
    fn log_rate_gives_gamma_per_decade() {
        let c = CreepSpec::from_log_rate(2.0, vec![0.1, 1.0, 10.0, 100.0, 1000.0])
            .check()
            .unwrap();
        assert!(c.gains.iter().all(|g| (g - 0.02).abs() < 1e-12));
        // slope per decade in the middle of the covered span
        let s = c.step_response(10.0) - c.step_response(1.0);
        assert!((s - 0.02).abs() < 0.004, "per decade {s}");
    }

    #[test]
    fn needs_exactly_one_of_gains_and_rate() {
        let s = CreepSpec {
            time_constants_s: vec![1.0],
            gains: Some(vec![0.1]),
            percent_per_decade: Some(1.0),
        };
        assert!(s.check().unwrap_err().to_string().contains("exactly one"));
    }

    #[test]
    fn negative_time_constant_rejected() {
        let s = CreepSpec {
            time_constants_s: vec![-1.0],
            gains: Some(vec![0.1]),
            percent_per_decade: None,
        };
        assert!(s
            .check()
            .unwrap_err()
            .to_string()
            .contains("time_constants_s[0]"));
    }
}
