//! # Saturation (a sensor or amplifier that clips the measured output)
//!
//! A displacement sensor, its amplifier or the data acquisition has a range: beyond it the
//! measurement stays at the limit, y_m = min(max(y, lower), upper), applied to the output after
//! its offset (the limits are in the units of the measured column). Either limit may be absent.
//!
//! Fitting: the samples at a limit are censored (the true output is at least the upper limit,
//! or at most the lower one); the model is fitted to the other samples (the censored
//! regression of Tobin 1958, whose likelihood for a model without noise is the fit to the
//! uncensored samples) and the limits are put on its output. The limits are read from the
//! record: the mean of the samples within four noise levels of an extreme where they pile up
//! ([`detect`]); a record whose extremes are smooth peaks shows no limit, and the fitted model
//! gets no saturation.
//!
//! ## References
//! - G. Tao, P. V. Kokotovic, *Adaptive Control of Systems with Actuator and Sensor
//!   Nonlinearities*, Wiley, 1996 (saturation among the non-smooth nonlinearities).
//! - J. Tobin, "Estimation of relationships for limited dependent variables", Econometrica
//!   26(1):24-36, 1958 (censored regression).

use super::basis::{BasisBank, BasisContext, EvidenceContext, Signal};
use super::draw::Dice;
use super::fitting::{Censoring, SensorFit};
use super::spec::{parse_spec, BoxedOperator, EffectSpec, Params, Spec};
use super::{finite, Effect, EffectError, EffectName, Operator, Slot};
use crate::metrics::quantile;
use serde::{Deserialize, Serialize};

/// Share of a residual the bank must explain before the refit test tries the effect.
pub const REFIT_EVIDENCE: f64 = 0.05;

/// The effect's name.
pub const NAME: EffectName = EffectName::new("saturation");

/// Saturation parameters as written in a plant file (output units, after the offset).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SaturationSpec {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lower: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upper: Option<f64>,
}

/// Valid saturation parameters: at least one limit, lower < upper.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Saturation {
    pub lower: f64,
    pub upper: f64,
}

impl SaturationSpec {
    /// Check the parameters.
    pub fn check(&self) -> Result<Saturation, EffectError> {
        let lower = match self.lower {
            Some(v) => finite("lower", v)?,
            None => f64::NEG_INFINITY,
        };
        let upper = match self.upper {
            Some(v) => finite("upper", v)?,
            None => f64::INFINITY,
        };
        if self.lower.is_none() && self.upper.is_none() {
            return Err(EffectError::Shape {
                field: "upper".into(),
                rule: "a saturation needs a lower or an upper limit (or both)".into(),
            });
        }
        if lower >= upper {
            return Err(EffectError::Invalid {
                field: "upper".into(),
                value: upper,
                rule: format!("must be above lower ({lower})"),
            });
        }
        Ok(Saturation { lower, upper })
    }
}

/// The clipping operator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SaturationOp(Saturation);

impl Operator for SaturationOp {
    fn reset(&mut self) {}
    fn step(&mut self, x: f64) -> f64 {
        x.clamp(self.0.lower, self.0.upper)
    }
}

impl Spec for SaturationSpec {
    const EFFECT: EffectName = NAME;
    type Params = Saturation;
    fn check(&self) -> Result<Saturation, EffectError> {
        SaturationSpec::check(self)
    }
}

impl Params for Saturation {
    const EFFECT: EffectName = NAME;
    fn operator(&self, _ts: f64) -> Result<BoxedOperator, EffectError> {
        Ok(Box::new(SaturationOp(*self)))
    }
}

/// The levels of the hinges of a prediction beyond its 3, 10, 90 and 97 % quantiles
/// ([`hinge`]: max(y_hat - q, 0) and min(y_hat - q, 0), what clipping the top or the bottom of
/// a model's output takes away), in their order: (level, above) at the 90 % quantile above, the
/// 10 % below, then the 97 % above and the 3 % below.
pub fn hinge_levels(prediction: &[f64]) -> Vec<(f64, bool)> {
    let mut s: Vec<f64> = prediction
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    if s.len() < 2 {
        return Vec::new();
    }
    s.sort_by(f64::total_cmp);
    [0.9, 0.97]
        .iter()
        .flat_map(|&q| [(quantile(&s, q), true), (quantile(&s, 1.0 - q), false)])
        .collect()
}

/// One hinge of [`hinge_levels`] at a value of the prediction.
pub fn hinge(v: f64, (level, above): (f64, bool)) -> f64 {
    if above {
        (v - level).max(0.0)
    } else {
        (v - level).min(0.0)
    }
}

/// The standard deviation of white noise on a smooth signal, from its second differences
/// (1.4826 MAD / sqrt(6): a smooth signal's second differences are near zero).
pub fn noise_level(y: &[f64]) -> f64 {
    let mut d: Vec<f64> = y
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .filter(|v| v.is_finite())
        .collect();
    if d.is_empty() {
        return 0.0;
    }
    1.4826 * crate::metrics::quantile_select(&mut d, 0.5) / 6f64.sqrt()
}

/// Samples within eight noise levels of an extreme must outnumber those in the next band of
/// the same width by this factor for the extreme to be a limit (a smooth peak gives about 2.4,
/// a clipped one tens).
pub const PILE_UP: f64 = 4.0;

/// The limits a measured output shows: at each extreme, the samples within eight noise levels
/// of it are a limit's when they pile up there ([`PILE_UP`] times the samples in the next band
/// of that width, and at least 0.5 % of the record); the limit is their mean. An extreme
/// without a pile-up (a smooth peak) gives no limit. Samples within four noise levels of a
/// limit are censored.
pub fn detect(y: &[f64]) -> Censoring {
    let finite: Vec<f64> = y.iter().copied().filter(|v| v.is_finite()).collect();
    let (lo, hi) = finite
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let range = hi - lo;
    let tolerance = (4.0 * noise_level(&finite)).max(1e-9 * range.abs());
    // the limit at extreme `at`, seen from inside in direction `dir` (-1 below the top)
    let limit = |at: f64, dir: f64| -> Option<f64> {
        let depth = |v: f64| (v - at) * dir;
        let near: Vec<f64> = finite
            .iter()
            .copied()
            .filter(|&v| depth(v) <= 2.0 * tolerance)
            .collect();
        let next = finite
            .iter()
            .filter(|&&v| depth(v) > 2.0 * tolerance && depth(v) <= 4.0 * tolerance)
            .count();
        let enough = near.len() as f64 >= 0.005 * finite.len() as f64;
        (range.is_finite() && enough && near.len() as f64 >= PILE_UP * next.max(1) as f64)
            .then(|| crate::metrics::mean(&near))
    };
    let (mut lower, mut upper) = (limit(lo, 1.0), limit(hi, -1.0));
    if let (Some(l), Some(h)) = (lower, upper) {
        if h - l <= 2.0 * tolerance {
            (lower, upper) = (None, None);
        }
    }
    Censoring {
        lower,
        upper,
        tolerance,
    }
}

/// The grey-box sensor: limits read from the record.
struct SaturationFit;

impl SensorFit for SaturationFit {
    fn censoring(&self, y: &[f64]) -> Censoring {
        detect(y)
    }
    fn spec(&self, c: &Censoring) -> Option<Box<dyn EffectSpec>> {
        (c.lower.is_some() || c.upper.is_some()).then(|| {
            Box::new(SaturationSpec {
                lower: c.lower,
                upper: c.upper,
            }) as Box<dyn EffectSpec>
        })
    }
}

/// Saturation as an effect of the library.
pub struct SaturationEffect;

impl Effect for SaturationEffect {
    fn name(&self) -> EffectName {
        NAME
    }
    fn summary(&self) -> &'static str {
        "a sensor that clips the measured output at its limits, min(max(y, lower), upper)"
    }
    fn slot(&self) -> Slot {
        Slot::Sensor
    }
    fn parse_spec(
        &self,
        d: &mut dyn erased_serde::Deserializer<'_>,
    ) -> Result<Box<dyn EffectSpec>, erased_serde::Error> {
        parse_spec::<SaturationSpec>(d)
    }
    /// Limits at -9 and +9 output units.
    fn example(&self) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(SaturationSpec {
            lower: Some(-9.0),
            upper: Some(9.0),
        }))
    }
    /// The zoo's saturation (`zoo --extra saturation`): the top of the output clipped (half
    /// of the draws), its bottom (a quarter) or both (a quarter), each limit where a share
    /// log-uniform 2-15 % of the samples lies beyond it.
    fn draw_on_output(
        &self,
        output: &[f64],
        _ts: f64,
        dice: &mut Dice,
    ) -> Option<Box<dyn EffectSpec>> {
        let mut s: Vec<f64> = output.iter().copied().filter(|v| v.is_finite()).collect();
        if s.len() < 10 || crate::metrics::ptp(&s) <= 0.0 {
            return None;
        }
        s.sort_by(f64::total_cmp);
        let side = dice.pick(&[0.5, 0.25, 0.25]);
        let limit = |top: bool, d: &mut Dice| {
            let share = d.log_uniform(0.02, 0.15);
            quantile(&s, if top { 1.0 - share } else { share })
        };
        let upper = (side != 1).then(|| limit(true, dice));
        let lower = (side != 0).then(|| limit(false, dice));
        Some(Box::new(SaturationSpec { lower, upper }))
    }
    fn basis<'a>(&self, ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
        let mut bank = BasisBank::new(NAME);
        let y = ctx.prediction;
        for (i, h) in hinge_levels(y).into_iter().enumerate() {
            let (side, q) = (["above", "below"][i % 2], [90, 97][i / 2]);
            bank.push(
                format!("prediction {side} its {q} % quantile"),
                Signal::of(move |k| hinge(y[k], h)),
            );
        }
        Some(bank)
    }
    /// Tried by the refit test only when its bank explains 5 % of the residual (flattened extremes shows
    /// in the bank directly).
    fn refit_evidence(&self) -> Option<f64> {
        Some(REFIT_EVIDENCE)
    }
    fn evidence(&self, ctx: &EvidenceContext) -> String {
        format!(
            "the error concentrates where {} is at its extremes (the model overshoots where the measurement flattens): a sensor's limits are not in the model",
            ctx.output
        )
    }
    fn no_features(&self) -> &'static str {
        "a sensor's limits act on the measured output, which a NARX model already regresses on"
    }
    fn sensor(&self) -> Option<Box<dyn SensorFit>> {
        Some(Box::new(SaturationFit))
    }
    fn parameter_count(&self, _size: super::fitting::BasisSize) -> (usize, usize) {
        (0, 2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn operator_clips_and_one_limit_is_enough() {
        let s = SaturationSpec {
            lower: None,
            upper: Some(1.0),
        }
        .check()
        .unwrap();
        let mut op = SaturationOp(s);
        assert_eq!(op.apply(&[-5.0, 0.5, 2.0]), vec![-5.0, 0.5, 1.0]);
        let e = SaturationSpec {
            lower: Some(2.0),
            upper: Some(1.0),
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("upper"), "{e}");
        let e = SaturationSpec {
            lower: None,
            upper: None,
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("limit"), "{e}");
    }

    #[test]
    fn the_limits_are_read_from_a_clipped_noisy_record() {
        let mut g = crate::effect::noise::Gaussian::new(2, 0);
        let y: Vec<f64> = (0..5000)
            .map(|k| (0.01 * k as f64).sin().clamp(-0.8, 0.7) + 0.002 * g.standard_normal())
            .collect();
        let c = detect(&y);
        assert!((c.upper.unwrap() - 0.7).abs() < 0.003, "{c:?}");
        assert!((c.lower.unwrap() + 0.8).abs() < 0.003, "{c:?}");
        assert!(
            (noise_level(&y) - 0.002).abs() < 0.0005,
            "{}",
            noise_level(&y)
        );
        // a sine that is not clipped shows no limit; one clipped at the top only, one limit
        let smooth: Vec<f64> = (0..5000)
            .map(|k| (0.01 * k as f64).sin() + 0.002 * g.standard_normal())
            .collect();
        let c = detect(&smooth);
        assert_eq!((c.lower, c.upper), (None, None), "{c:?}");
        let top: Vec<f64> = (0..5000)
            .map(|k| (0.01 * k as f64).sin().min(0.6) + 0.002 * g.standard_normal())
            .collect();
        let c = detect(&top);
        assert!(
            c.lower.is_none() && c.upper.is_some_and(|h| (h - 0.6).abs() < 0.003),
            "{c:?} {}",
            noise_level(&top)
        );
    }
}
