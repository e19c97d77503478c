//! # Drift (a slow trend in time, added to an output)
//!
//! Thermal drift of a piezo stage or of its sensor: the output wanders with time, whatever the
//! input does, as the actuator and the mount warm up after power-on and settle (an exponential
//! settling) and as the room drifts (a slow ramp):
//! d(t) = r t + sum_i a_i (1 - exp(-t / tau_i)), t from the start of the record,
//! added to the output after its filters (it does not pass through creep or dynamics).
//!
//! The fitted drift has fixed time constants, [`FIT_TAUS`] of the training record's span, and
//! its rate and amplitudes by least squares (an output term of linear columns). A model with
//! drift applied to another record starts the drift again at that record's start: drift is a
//! property of one experiment, not of the device.
//!
//! ## References
//! - S. Devasia, E. Eleftheriou, S. O. R. Moheimani, "A survey of control issues in
//!   nanopositioning", IEEE T-CST 15(5):802-823, 2007 (thermal drift of nanopositioners).
//! - Physik Instrumente, "Piezo tutorial: drift and temperature" (thermal drift, settling).

use super::basis::{BasisBank, BasisContext, EvidenceContext, Signal};
use super::draw::Dice;
use super::fitting::{Column, OutputSetup, TermFit, TermSpec};
use super::spec::{parse_spec, BoxedOperator, EffectSpec, Params, Spec};
use super::{finite, positive, Effect, EffectError, EffectName, Operator, Slot};
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

/// Share of a residual the bank must explain before the refit test tries the effect.
pub const REFIT_EVIDENCE: f64 = 0.05;

/// The effect's name.
pub const NAME: EffectName = EffectName::new("drift");

/// Drift parameters as written in a plant file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriftSpec {
    /// r: output units per second (a ramp), any sign.
    #[serde(default)]
    pub rate: f64,
    /// a_i: output units, any sign; one per time constant.
    #[serde(default)]
    pub amplitudes: Vec<f64>,
    /// tau_i in seconds, > 0.
    #[serde(default)]
    pub time_constants_s: Vec<f64>,
}

/// Valid drift parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Drift {
    pub rate: f64,
    pub amplitudes: Vec<f64>,
    pub time_constants_s: Vec<f64>,
}

impl DriftSpec {
    /// Check the parameters: finite rate and amplitudes, positive time constants, as many
    /// amplitudes as time constants.
    pub fn check(&self) -> Result<Drift, EffectError> {
        finite("rate", self.rate)?;
        if self.amplitudes.len() != self.time_constants_s.len() {
            return Err(EffectError::Shape {
                field: "amplitudes".into(),
                rule: format!(
                    "needs one amplitude per time constant ({} amplitudes, {} time constants)",
                    self.amplitudes.len(),
                    self.time_constants_s.len()
                ),
            });
        }
        for (i, a) in self.amplitudes.iter().enumerate() {
            finite(&format!("amplitudes[{i}]"), *a)?;
        }
        for (i, t) in self.time_constants_s.iter().enumerate() {
            positive(&format!("time_constants_s[{i}]"), *t)?;
        }
        Ok(Drift {
            rate: self.rate,
            amplitudes: self.amplitudes.clone(),
            time_constants_s: self.time_constants_s.clone(),
        })
    }
}

impl Drift {
    /// d(t) at time `t` seconds from the start.
    pub fn at(&self, t: f64) -> f64 {
        self.rate * t
            + self
                .amplitudes
                .iter()
                .zip(&self.time_constants_s)
                .map(|(a, tau)| a * (1.0 - (-t / tau).exp()))
                .sum::<f64>()
    }

    /// The sampled operator: x(k) + d(k ts).
    pub fn operator(&self, ts: f64) -> Result<DriftOp, EffectError> {
        positive("ts", ts)?;
        Ok(DriftOp {
            drift: self.clone(),
            ts,
            k: 0,
        })
    }
}

/// The sampled drift: adds d(k ts) to sample k of its input.
#[derive(Debug, Clone, PartialEq)]
pub struct DriftOp {
    drift: Drift,
    ts: f64,
    k: u64,
}

impl Operator for DriftOp {
    fn reset(&mut self) {
        self.k = 0;
    }
    fn step(&mut self, x: f64) -> f64 {
        let y = x + self.drift.at(self.k as f64 * self.ts);
        self.k += 1;
        y
    }
}

impl Spec for DriftSpec {
    const EFFECT: EffectName = NAME;
    type Params = Drift;
    fn check(&self) -> Result<Drift, EffectError> {
        DriftSpec::check(self)
    }
}

impl Params for Drift {
    const EFFECT: EffectName = NAME;
    fn operator(&self, ts: f64) -> Result<BoxedOperator, EffectError> {
        Ok(Box::new(Drift::operator(self, ts)?))
    }
    fn is_active(&self) -> bool {
        self.rate != 0.0 || self.amplitudes.iter().any(|a| *a != 0.0)
    }
}

/// Cosines of time in the diagnosis bank (the slowest has a period of twice the record).
pub const BANK_COSINES: usize = 6;

/// Sample `j` of the `k`-th slow cosine of time over `n` samples, cos(pi k (j + 1/2) / n): the
/// first few are what a slow trend adds to a residual, whatever its shape.
pub fn slow_cosine(k: usize, j: usize, n: usize) -> f64 {
    (std::f64::consts::PI * k as f64 * (j as f64 + 0.5) / n as f64).cos()
}

/// Time constants of the fitted drift, as shares of the training record's span.
pub const FIT_TAUS: [f64; 2] = [0.1, 0.5];

/// The grey-box output term: r t and 1 - exp(-t / tau_i), coefficients by least squares.
struct DriftTerm {
    taus: Vec<f64>,
    columns: Vec<Vec<f64>>,
}

impl DriftTerm {
    /// The columns over the rows of `setup` (the record's first rows, or its blocks one after
    /// the other, each row at its time in the record); the time constants from all samples.
    fn new(setup: &OutputSetup) -> DriftTerm {
        let ts = setup.ts;
        let span = setup.samples as f64 * ts;
        let taus: Vec<f64> = FIT_TAUS.iter().map(|s| s * span).collect();
        let t: Vec<f64> = match setup.blocks {
            Some(blocks) => blocks
                .iter()
                .flat_map(Clone::clone)
                .map(|k| k as f64 * ts)
                .collect(),
            None => (0..setup.rows).map(|k| k as f64 * ts).collect(),
        };
        debug_assert_eq!(t.len(), setup.rows);
        let mut columns = vec![t.clone()];
        for tau in &taus {
            columns.push(t.iter().map(|v| 1.0 - (-v / tau).exp()).collect());
        }
        DriftTerm { taus, columns }
    }
}

impl TermFit for DriftTerm {
    fn n_columns(&self) -> usize {
        self.columns.len()
    }
    fn columns<'s>(&'s self, _th: &[f64]) -> Vec<Column<'s>> {
        self.columns
            .iter()
            .map(|c| (Cow::Borrowed(c.as_slice()), false))
            .collect()
    }
    fn spec(&self, _th: &[f64], _gain: f64, coef: &[f64]) -> TermSpec {
        TermSpec {
            spec: Some(Box::new(DriftSpec {
                rate: coef[0],
                amplitudes: coef[1..].to_vec(),
                time_constants_s: self.taus.clone(),
            })),
            extra_paths: Vec::new(),
        }
    }
}

/// Drift as an effect of the library.
pub struct DriftEffect;

impl Effect for DriftEffect {
    fn name(&self) -> EffectName {
        NAME
    }
    fn summary(&self) -> &'static str {
        "a slow trend in time added to the output, r t + sum a_i (1 - exp(-t/tau_i)) (thermal drift)"
    }
    fn slot(&self) -> Slot {
        Slot::OutputTerm
    }
    fn parse_spec(
        &self,
        d: &mut dyn erased_serde::Deserializer<'_>,
    ) -> Result<Box<dyn EffectSpec>, erased_serde::Error> {
        parse_spec::<DriftSpec>(d)
    }
    /// A warm-up of 1.5 output units settling in 8 s, and a ramp of 0.02 units per second.
    fn example(&self) -> Option<Box<dyn EffectSpec>> {
        Some(Box::new(DriftSpec {
            rate: 0.02,
            amplitudes: vec![1.5],
            time_constants_s: vec![8.0],
        }))
    }
    /// The zoo's drift (`zoo --extra drift`), for an output of range R over a record of
    /// span T: a settling of amplitude log-uniform 2-15 % of R (either sign) with a time
    /// constant log-uniform 0.05-1 T, and a ramp of 0-5 % of R over T (either sign).
    fn draw_on_output(
        &self,
        output: &[f64],
        ts: f64,
        dice: &mut Dice,
    ) -> Option<Box<dyn EffectSpec>> {
        let range = crate::metrics::ptp(output);
        let span = output.len() as f64 * ts;
        if !(range > 0.0 && span > 0.0) {
            return None;
        }
        let sign = |d: &mut Dice| if d.chance(0.5) { 1.0 } else { -1.0 };
        let amplitude = sign(dice) * dice.log_uniform(0.02, 0.15) * range;
        let tau = dice.log_uniform(0.05, 1.0) * span;
        let rate = sign(dice) * dice.uniform(0.0, 0.05) * range / span;
        Some(Box::new(DriftSpec {
            rate,
            amplitudes: vec![amplitude],
            time_constants_s: vec![tau],
        }))
    }
    fn basis<'a>(&self, ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
        let mut bank = BasisBank::new(NAME);
        let n = ctx.len();
        for k in 1..=BANK_COSINES {
            bank.push(
                format!("cos({k} pi t / T)"),
                Signal::of(move |j| slow_cosine(k, j, n)),
            );
        }
        Some(bank)
    }
    /// Tried by the refit test only when its bank explains 5 % of the residual (a slow trend shows
    /// in the bank directly).
    fn refit_evidence(&self) -> Option<f64> {
        Some(REFIT_EVIDENCE)
    }
    fn evidence(&self, ctx: &EvidenceContext) -> String {
        let n = ctx.error.len();
        let third = n / 3;
        let mean = |r: std::ops::Range<usize>| crate::metrics::mean(&ctx.error[r]);
        format!(
            "the error wanders slowly in time, whatever {} does (mean {:.3} in the first third of the record, {:.3} in the last{}): a drift of the output is not in the model",
            ctx.input_names.get(ctx.direct).copied().unwrap_or("the input"),
            mean(0..third.max(1)),
            mean(n - third.max(1)..n),
            ctx.unit
        )
    }
    fn no_features(&self) -> &'static str {
        "drift is a function of the time since the experiment started, not of the input: a NARX model of the input cannot hold it (fit it in a grey-box model)"
    }
    fn output_term(&self, setup: &OutputSetup) -> Option<Box<dyn TermFit>> {
        Some(Box::new(DriftTerm::new(setup)))
    }
    fn parameter_count(&self, _size: super::fitting::BasisSize) -> (usize, usize) {
        (0, 1 + FIT_TAUS.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn operator_adds_the_ramp_and_the_settling() {
        let d = DriftSpec {
            rate: 0.5,
            amplitudes: vec![2.0],
            time_constants_s: vec![1.0],
        }
        .check()
        .unwrap();
        let mut op = d.operator(0.5).unwrap();
        let y = op.apply(&[1.0, 1.0, 1.0]);
        assert_eq!(y[0], 1.0);
        assert!((y[1] - (1.0 + 0.25 + 2.0 * (1.0 - (-0.5f64).exp()))).abs() < 1e-12);
        assert!((y[2] - (1.0 + 0.5 + 2.0 * (1.0 - (-1.0f64).exp()))).abs() < 1e-12);
        op.reset();
        assert_eq!(op.step(3.0), 3.0);
    }

    /// On blocks spread over the record, each row's columns are the whole record's at that
    /// row (its time in the record), the time constants the whole record's.
    #[test]
    fn the_columns_on_blocks_are_the_records_at_their_rows() {
        let setup = |rows, blocks| OutputSetup {
            samples: 1000,
            rows,
            blocks,
            ts: 0.01,
            variant: 0,
            parsimonious: false,
            paths: 1,
        };
        let whole = DriftTerm::new(&setup(1000, None));
        let blocks = [0..10, 400..410, 990..1000];
        let part = DriftTerm::new(&setup(30, Some(&blocks)));
        assert_eq!(part.taus, whole.taus);
        let rows: Vec<usize> = blocks.iter().flat_map(Clone::clone).collect();
        for (c, w) in part.columns.iter().zip(&whole.columns) {
            let at: Vec<f64> = rows.iter().map(|&k| w[k]).collect();
            assert_eq!(c, &at);
        }
    }

    #[test]
    fn bad_parameters_name_the_field() {
        let e = DriftSpec {
            rate: 0.0,
            amplitudes: vec![1.0],
            time_constants_s: vec![-1.0],
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("time_constants_s[0]"), "{e}");
        let e = DriftSpec {
            rate: 0.0,
            amplitudes: vec![1.0, 2.0],
            time_constants_s: vec![1.0],
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("amplitudes"), "{e}");
    }
}
