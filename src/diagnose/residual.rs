//! # Where the residual concentrates
//!
//! When no effect of the library explains a residual that is not white, the diagnosis still
//! says where what is left sits, because the place points at the physics:
//!
//! - **at the output's extremes** (the model overshoots where the measurement flattens):
//!   a sensor or amplifier saturating, a stiffening or softening end stop;
//! - **in a slow trend in time**, unrelated to the input: thermal drift, a creeping offset;
//! - **just after the input reverses** (the output lags the reversal by a travel): backlash,
//!   a dead zone, stick-slip friction.
//!
//! Each place is a small bank of signals nonzero only there, regressed on the residual with the
//! diagnosis' blocked cross-validation ([`super::regression::FoldGrams::explained`]) on top
//! of the prediction and a constant: the place that explains the largest share out of sample,
//! when it explains at least [`DESCRIBED`], is where the residual concentrates.
//! - extremes: hinges of the prediction beyond its 3, 10, 90 and 97 % quantiles,
//!   max(y_hat - q, 0) and min(y_hat - q, 0) (the saturation effect's bank);
//! - slow trend: the first [`TREND_COSINES`] cosines of time over the record, cos(pi k t / T)
//!   (the drift effect's bank);
//! - reversals: after each reversal of the input (a move back by more than 1 % of its range),
//!   the direction of motion times max(d - travel, 0), for gaps d of 2, 5 and 15 % of the range,
//!   and the direction itself (a backlash of width d: its output waits for the input to take up
//!   the gap, then follows it offset by half the gap; Coulomb friction: a force of the sign of
//!   the motion; Tao & Kokotovic 1996).
//!
//! ## References
//! - G. Tao, P. V. Kokotovic, *Adaptive Control of Systems with Actuator and Sensor
//!   Nonlinearities*, Wiley, 1996 (backlash, dead zone, saturation as the non-smooth
//!   nonlinearities of actuators and sensors).
//! - S. A. Billings, W. S. F. Voon, Int. J. Control 44(1):235-244, 1986 (residual tests).

use super::regression::FoldGrams;
use crate::effect::basis::Signal;
use crate::effect::drift::slow_cosine;
use crate::effect::saturation::{hinge, hinge_levels};
use crate::effect::Operator;
use serde::Serialize;

/// Share of the residual a place must explain out of sample to be named.
pub const DESCRIBED: f64 = 0.2;
/// Cosines of time in the slow-trend bank (the slowest has a period of twice the record): the
/// drift effect's bank.
pub const TREND_COSINES: usize = crate::effect::drift::BANK_COSINES;
/// Gaps of the reversal bank, as shares of the input's range.
pub const REVERSAL_GAPS: [f64; 3] = [0.02, 0.05, 0.15];
/// A reversal is a move back by more than this share of the input's range.
pub const REVERSAL_MOVE: f64 = 0.01;

/// A place in the record where a residual can concentrate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Place {
    /// At the output's extremes (saturation, end stops).
    Extremes,
    /// A slow trend in time (drift).
    SlowTrend,
    /// Just after the input reverses (backlash, dead zone, friction).
    Reversals,
}

impl Place {
    /// Every place, in the order of the reports.
    pub const ALL: [Place; 3] = [Place::Extremes, Place::SlowTrend, Place::Reversals];

    /// The name in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Place::Extremes => "extremes",
            Place::SlowTrend => "slow trend",
            Place::Reversals => "reversals",
        }
    }

    /// What physics sits there.
    pub fn physics(self) -> &'static str {
        match self {
            Place::Extremes => {
                "the model overshoots where the measurement flattens: a sensor or amplifier saturating, an end stop (the library's `saturation`)"
            }
            Place::SlowTrend => {
                "a slow trend in time that the input does not explain: thermal drift, a wandering offset (the library's `drift`)"
            }
            Place::Reversals => {
                "the output lags each reversal of the input by a travel: backlash, a dead zone, stick-slip friction (a backlash is a play operator: the library's `hysteresis`)"
            }
        }
    }

    /// The figure that shows it.
    pub fn figure(self) -> &'static str {
        match self {
            Place::Extremes => {
                "`hystbench plot parity` (a flat top or bottom) or `diagnose --figure`"
            }
            Place::SlowTrend => {
                "`hystbench plot time` (the residual wanders) or `diagnose --figure`"
            }
            Place::Reversals => {
                "`hystbench plot residual-loop` (steps at the loop's tips) or `diagnose --figure`"
            }
        }
    }
}

/// How much of one place explains.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlaceShare {
    pub place: Place,
    /// Out-of-sample share of the residual explained by the place's bank.
    pub explained: f64,
}

/// Where one output's residual concentrates.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualShape {
    /// Each place's share, largest first.
    pub shares: Vec<PlaceShare>,
    /// The place that explains at least [`DESCRIBED`] and most, if any.
    #[serde(rename = "where")]
    pub place: Option<Place>,
    /// In words.
    pub message: String,
}

/// For each sample, the direction of motion (+1, -1, or 0 before the first move) and the
/// input's travel since the last reversal (a move back by more than `hysteresis`).
pub fn reversal_travel(u: &[f64], hysteresis: f64) -> Vec<(f64, f64)> {
    let mut t = ReversalTravel::new(hysteresis);
    u.iter().map(|&v| t.step(v)).collect()
}

/// [`reversal_travel`] one sample at a time.
#[derive(Debug, Clone)]
pub struct ReversalTravel {
    hysteresis: f64,
    /// The first value, the direction of motion, the extreme of the current motion and the
    /// last reversal.
    start: Option<f64>,
    dir: f64,
    extreme: f64,
    since: Option<f64>,
}

impl ReversalTravel {
    /// At rest before the first sample.
    pub fn new(hysteresis: f64) -> ReversalTravel {
        ReversalTravel {
            hysteresis,
            start: None,
            dir: 0.0,
            extreme: 0.0,
            since: None,
        }
    }

    /// The direction of motion and the travel since the last reversal at the next sample.
    pub fn step(&mut self, v: f64) -> (f64, f64) {
        let start = *self.start.get_or_insert_with(|| {
            self.extreme = v;
            v
        });
        if self.dir == 0.0 {
            if (v - start).abs() > self.hysteresis {
                self.dir = (v - start).signum();
                self.extreme = v;
            }
        } else if (v - self.extreme) * self.dir > 0.0 {
            self.extreme = v;
        } else if (self.extreme - v) * self.dir > self.hysteresis {
            // a reversal at the extreme just left
            self.since = Some(self.extreme);
            self.dir = -self.dir;
            self.extreme = v;
        }
        let travel = self.since.map_or(f64::INFINITY, |r: f64| (v - r).abs());
        (self.dir, travel)
    }
}

/// One signal of the reversal bank: direction times max(gap - travel, 0), or the direction
/// alone without a gap.
#[derive(Debug, Clone)]
struct ReversalSignal {
    travel: ReversalTravel,
    gap: Option<f64>,
}

impl Operator for ReversalSignal {
    fn reset(&mut self) {
        self.travel = ReversalTravel::new(self.travel.hysteresis);
    }
    fn step(&mut self, v: f64) -> f64 {
        let (dir, travel) = self.travel.step(v);
        self.gap.map_or(dir, |d| dir * (d - travel).max(0.0))
    }
}

/// The reversal bank: direction times max(d - travel since the reversal, 0), and the direction
/// of motion itself (a friction force's sign; the offset of a backlash's output in motion).
fn reversal_signals(u: &[f64]) -> Vec<Signal<'_>> {
    let range = if u.is_empty() {
        0.0
    } else {
        crate::metrics::ptp(u)
    };
    if range.is_nan() || range <= 0.0 {
        return Vec::new();
    }
    let travel = ReversalTravel::new(REVERSAL_MOVE * range);
    REVERSAL_GAPS
        .iter()
        .map(|g| Some(g * range))
        .chain([None])
        .map(|gap| {
            let travel = travel.clone();
            Signal::samples(u).through(Box::new(ReversalSignal { travel, gap }))
        })
        .collect()
}

/// The bank of `place` for a residual of prediction `yhat` driven by `u`, held whole.
pub fn bank(place: Place, yhat: &[f64], u: &[f64]) -> Vec<Vec<f64>> {
    let n = yhat.len();
    signals(place, yhat, u)
        .into_iter()
        .map(|s| s.whole(n))
        .collect()
}

/// [`bank`]'s signals, computed a block of rows at a time.
fn signals<'a>(place: Place, yhat: &'a [f64], u: &'a [f64]) -> Vec<Signal<'a>> {
    let n = yhat.len();
    match place {
        Place::Extremes => hinge_levels(yhat)
            .into_iter()
            .map(|h| Signal::of(move |k| hinge(yhat[k], h)))
            .collect(),
        Place::SlowTrend => (1..=TREND_COSINES)
            .map(|k| Signal::of(move |j| slow_cosine(k, j, n)))
            .collect(),
        Place::Reversals => reversal_signals(u),
    }
}

/// The part of the residual that `place`'s bank explains (a least-squares fit on the whole
/// record, on top of the prediction and a constant), for figures; `None` when the bank is
/// empty or the fit fails.
pub fn explained_part(place: Place, e: &[f64], yhat: &[f64], u: &[f64]) -> Option<Vec<f64>> {
    let bank = bank(place, yhat, u);
    if bank.is_empty() {
        return None;
    }
    let mut cols: Vec<&[f64]> = vec![yhat];
    cols.extend(bank.iter().map(Vec::as_slice));
    let c = super::regression::fit(&cols, e, 0..e.len(), true)?;
    Some(
        (0..e.len())
            .map(|k| super::regression::predict_at(&cols, &c, k))
            .collect(),
    )
}

/// Where the residual `e` of prediction `yhat` (driven by input `u`) concentrates; `white`:
/// the residual passed the correlation tests (then nothing is described).
pub fn describe(e: &[f64], yhat: &[f64], u: &[f64], white: bool) -> ResidualShape {
    // one place's bank at a time, its signals a block of rows at a time (columns: the bank,
    // then the prediction)
    let mut shares: Vec<PlaceShare> = Place::ALL
        .iter()
        .filter_map(|&place| {
            let mut cols = signals(place, yhat, u);
            let bank: Vec<usize> = (0..cols.len()).collect();
            if bank.is_empty() {
                return None;
            }
            cols.push(Signal::samples(yhat));
            let x = FoldGrams::new(e, &mut cols).explained(&[&[bank.len()]], &bank)?;
            Some(PlaceShare {
                place,
                explained: x.fraction,
            })
        })
        .collect();
    shares.sort_by(|a, b| b.explained.total_cmp(&a.explained));
    let top = shares.first().copied();
    let place = top
        .filter(|s| !white && s.explained >= DESCRIBED)
        .map(|s| s.place);
    let message = match (place, top) {
        (Some(p), Some(s)) => format!(
            "the residual concentrates at the {}: {:.0} % of it is explained there out of sample; {}; see {}",
            p.as_str(),
            100.0 * s.explained,
            p.physics(),
            p.figure()
        ),
        _ if white => "the residual is white: it concentrates nowhere".to_string(),
        (_, top) => format!(
            "the residual concentrates at no one place (the best, {}, explains {:.0} % out of sample, below {:.0} %): noise, or a misfit spread over the record",
            top.map_or("none", |s| s.place.as_str()),
            100.0 * top.map_or(0.0, |s| s.explained.max(0.0)),
            100.0 * DESCRIBED
        ),
    };
    ResidualShape {
        shares,
        place,
        message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effect::noise::Gaussian;
    use crate::effect::Operator;

    /// A multisine that reverses at many levels (so that extremes and reversals differ).
    fn multisine(n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| {
                let t = k as f64 * 1e-3;
                (2.0 * std::f64::consts::PI * 1.3 * t).sin()
                    + 0.6 * (2.0 * std::f64::consts::PI * 3.7 * t + 1.0).sin()
                    + 0.3 * (2.0 * std::f64::consts::PI * 7.9 * t + 2.0).sin()
            })
            .collect()
    }

    fn place_of(y: &[f64], yhat: &[f64], u: &[f64]) -> ResidualShape {
        let e: Vec<f64> = y.iter().zip(yhat).map(|(a, b)| a - b).collect();
        describe(&e, yhat, u, false)
    }

    #[test]
    fn each_place_is_found_where_it_was_put() {
        let n = 6000;
        let u = multisine(n);
        let mut g = Gaussian::new(3, 0);
        let noise: Vec<f64> = (0..n).map(|_| 0.005 * g.standard_normal()).collect();
        // saturation: the measurement clipped at 70 % of its peak
        let peak = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let clipped: Vec<f64> = u
            .iter()
            .zip(&noise)
            .map(|(v, e)| v.clamp(-0.7 * peak, 0.7 * peak) + e)
            .collect();
        let s = place_of(&clipped, &u, &u);
        assert_eq!(s.place, Some(Place::Extremes), "{s:?}");
        // drift: a slow exponential settling added
        let drift: Vec<f64> = (0..n)
            .map(|k| u[k] + 0.2 * (1.0 - (-(k as f64) / 2000.0).exp()) + noise[k])
            .collect();
        let s = place_of(&drift, &u, &u);
        assert_eq!(s.place, Some(Place::SlowTrend), "{s:?}");
        // backlash of width 0.1: the output waits for the input to take up the gap
        let mut b = crate::effect::play::Play::new(0.1, 0.0);
        let backlash: Vec<f64> = u.iter().zip(&noise).map(|(v, e)| b.step(*v) + e).collect();
        let s = place_of(&backlash, &u, &u);
        assert_eq!(s.place, Some(Place::Reversals), "{s:?}");
        // noise alone: nowhere
        let s = place_of(
            &u.iter().zip(&noise).map(|(a, b)| a + b).collect::<Vec<_>>(),
            &u,
            &u,
        );
        assert_eq!(s.place, None, "{s:?}");
    }

    #[test]
    fn reversals_are_found_with_their_travel() {
        let u = [0.0, 1.0, 2.0, 3.0, 2.5, 2.0, 3.0];
        let m = reversal_travel(&u, 0.1);
        assert_eq!(m[3], (1.0, f64::INFINITY));
        assert_eq!(m[4], (-1.0, 0.5));
        assert_eq!(m[5], (-1.0, 1.0));
        assert_eq!(m[6], (1.0, 1.0));
    }
}
