//! # Prediction bands
//!
//! Every free run of a fitted model carries a band that should hold the measured output with
//! probability [`BAND_LEVEL`]. It is calibrated by split conformal prediction on the training
//! record's own validation part (never seen by the gradient steps): the free run there gives
//! residuals r_t, and with the ensemble's spread s_t (the members' scaled median absolute
//! deviation; zero for one network) and the validation RMS error e, the normalised scores |r_t| / (s_t + e) give
//! their `level` quantile q (the ceil((n + 1) level)-th smallest of n). On any record the band
//! is then prediction +- q (s_t + e): as wide as the validation errors where the members agree,
//! wider where they part (typically outside the training region), and never narrower than the
//! `level` quantile of the validation residuals' magnitudes ([`Band::with_floor`]; on a short
//! record, of its cross-validated residuals; on a record with no validation part at all, of the
//! in-sample residuals).
//!
//! On a short record's output that its grey-box base's committee predicts
//! ([`super::consensus`]), the second opinion's disagreement is the larger of the network's and
//! the committee's own spread ([`super::consensus::committee_spread`]), at prediction only: the
//! band widens where the fits the record supports part.
//!
//! On a long record's output that uses its grey-box base (alone or under a residual network),
//! the band is at least [`spread_cover`] of the spread of the base's witnesses
//! (`super::base::BaseChoice::witnesses`: the other candidates that fit the validation part
//! about as well) with the base's run, at prediction only: where they part, typically where
//! the test input leaves the training range and their operators extrapolate apart, the band
//! covers them as it would normal scatter of that spread; where they agree it is as before.
//!
//! The validation part comes after the fitting part in time, so the band carries the model's
//! drift as well as the noise; its free-run residuals are correlated, so the coverage is a
//! measured property (see `hystbench zoo score`), not a guarantee.
//!
//! ## References
//! - V. Vovk, A. Gammerman, G. Shafer, *Algorithmic Learning in a Random World*, Springer, 2005.
//! - J. Lei, M. G'Sell, A. Rinaldo, R. J. Tibshirani, L. Wasserman, "Distribution-free
//!   predictive inference for regression", JASA 113(523):1094-1111, 2018 (normalised scores).

use serde::{Deserialize, Serialize};

/// The probability the bands are calibrated for.
pub const BAND_LEVEL: f64 = 0.95;

/// A calibrated band of one output (physical units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Band {
    /// The probability it is calibrated for.
    pub level: f64,
    /// The quantile q of the normalised validation scores.
    pub quantile: f64,
    /// The validation RMS error e (physical units, > 0).
    pub rms: f64,
    /// Validation samples it was calibrated on.
    pub samples: usize,
    /// The narrowest half-width (physical units, >= 0; 0: none): the `level` quantile of the
    /// magnitudes of the validation residuals, or on a short record of the cross-validated
    /// residuals over every sample ([`Band::with_floor`]).
    #[serde(default, skip_serializing_if = "crate::data::is_default")]
    pub floor: f64,
}

/// The split-conformal quantile of `scores` (not empty) at `level`: the ceil((n + 1) level)-th
/// smallest of n (the largest when that passes n).
fn conformal_quantile(mut scores: Vec<f64>, level: f64) -> f64 {
    let n = scores.len();
    scores.sort_by(f64::total_cmp);
    let k = (((n + 1) as f64 * level).ceil() as usize).clamp(1, n);
    scores[k - 1]
}

impl Band {
    /// Calibrates from validation residuals and the ensemble's spread at the same samples
    /// (physical units). `None` without residuals, or when they are all zero or not finite.
    pub fn calibrate(residuals: &[f64], spreads: &[f64], level: f64) -> Option<Band> {
        let n = residuals.len();
        if n == 0 || spreads.len() != n || !(0.0..1.0).contains(&level) {
            return None;
        }
        let rms = (residuals.iter().map(|r| r * r).sum::<f64>() / n as f64).sqrt();
        if !(rms.is_finite() && rms > 0.0 && spreads.iter().all(|s| s.is_finite())) {
            return None;
        }
        let scores: Vec<f64> = residuals
            .iter()
            .zip(spreads)
            .map(|(r, s)| r.abs() / (s + rms))
            .collect();
        Some(Band {
            level,
            quantile: conformal_quantile(scores, level),
            rms,
            samples: n,
            floor: 0.0,
        })
    }

    /// The band never narrower than the `level` quantile of `residuals` (its
    /// ceil((n + 1) level)-th smallest magnitude), the constant-width split-conformal band.
    ///
    /// On a longer record `residuals` are the validation residuals the band was calibrated on:
    /// the normalised band then holds where the spread is small though the errors are not
    /// (where the members agree on the same error, as on a record whose noise is larger than
    /// their disagreement), since a normalised quantile calibrated where the spread is large
    /// can leave q e below the noise.
    ///
    /// A short record's band is calibrated on the
    /// tail its network did not see, a quarter of a few hundred samples, whose errors can be
    /// smaller than those of the blocks where the model extrapolates; the cross-validated
    /// residuals of every sample (each predicted by a fit that did not see its block) set the
    /// floor (the CV+ of Barber, Candes, Ramdas & Tibshirani, "Predictive inference with the
    /// jackknife+", Ann. Statist. 49(1):486-507, 2021, with a constant width). Residuals that
    /// are not all finite leave the band as it is.
    pub fn with_floor(mut self, residuals: &[f64]) -> Band {
        if residuals.is_empty() || !residuals.iter().all(|r| r.is_finite()) {
            return self;
        }
        self.floor = conformal_quantile(residuals.iter().map(|r| r.abs()).collect(), self.level);
        self
    }

    /// The half-width at a sample where the ensemble's spread is `spread`.
    pub fn half_width(&self, spread: f64) -> f64 {
        (self.quantile * (spread + self.rms)).max(self.floor)
    }

    /// Valid numbers (a loaded file).
    pub fn check(&self) -> Result<(), String> {
        let ok = self.level > 0.0
            && self.level < 1.0
            && self.quantile.is_finite()
            && self.quantile >= 0.0
            && self.rms.is_finite()
            && self.rms > 0.0
            && self.floor.is_finite()
            && self.floor >= 0.0;
        if ok {
            Ok(())
        } else {
            Err(format!(
                "band: level {} (in (0, 1)), quantile {} (>= 0), rms {} (> 0) and floor {} (>= 0) are not valid",
                self.level, self.quantile, self.rms, self.floor
            ))
        }
    }
}

/// The two-sided standard normal quantile of [`BAND_LEVEL`]: P(|Z| <= z) = 0.95.
pub const BAND_Z: f64 = 1.959_964;

/// The half-width that covers a spread `s` of plausible runs (a standard deviation: their
/// scaled median absolute deviation) at [`BAND_LEVEL`], as it would normal scatter:
/// [`BAND_Z`] s.
pub fn spread_cover(s: f64) -> f64 {
    BAND_Z * s
}

/// Coverage of a band over `from..`: the share of measured samples within prediction +- half
/// width (`None` over no sample).
pub fn coverage(measured: &[f64], pred: &[f64], half: &[f64], from: usize) -> Option<f64> {
    let n = measured.len().min(pred.len()).min(half.len());
    if from >= n {
        return None;
    }
    let inside = (from..n)
        .filter(|&k| (measured[k] - pred[k]).abs() <= half[k])
        .count();
    Some(inside as f64 / (n - from) as f64)
}

/// A band's mean half-width over `from..`, over the standard deviation of the measured samples
/// there (`None` over fewer than two samples or a constant measurement).
pub fn relative_width(measured: &[f64], half: &[f64], from: usize) -> Option<f64> {
    let n = measured.len().min(half.len());
    if from + 2 > n {
        return None;
    }
    let std = crate::metrics::std_dev(&measured[from..n]);
    (std > 0.0).then(|| crate::metrics::mean(&half[from..n]) / std)
}

/// The members' spread at each sample: their median absolute deviation from their median,
/// times 1.4826 (the standard deviation for normal scatter; one stray member barely moves it).
/// Zeros for one run.
pub fn spread(runs: &[&[f64]], len: usize) -> Vec<f64> {
    let k = runs.len();
    if k < 2 {
        return vec![0.0; len];
    }
    let median = |v: &mut [f64]| {
        v.sort_unstable_by(f64::total_cmp);
        if k % 2 == 1 {
            v[k / 2]
        } else {
            0.5 * (v[k / 2 - 1] + v[k / 2])
        }
    };
    let mut v = vec![0.0; k];
    (0..len)
        .map(|t| {
            for (vj, r) in v.iter_mut().zip(runs) {
                *vj = r[t];
            }
            let m = median(&mut v);
            for x in v.iter_mut() {
                *x = (*x - m).abs();
            }
            1.4826 * median(&mut v)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The width is in standard deviations of the measurement over `from..`.
    #[test]
    fn the_relative_width_is_in_output_standard_deviations() {
        let y = [9.0, 9.0, 1.0, -1.0, 1.0, -1.0];
        let half = [5.0, 5.0, 2.0, 2.0, 2.0, 2.0];
        assert_eq!(relative_width(&y, &half, 2), Some(2.0));
        assert_eq!(relative_width(&y, &half, 5), None);
        assert_eq!(relative_width(&[1.0; 4], &half, 0), None);
    }

    #[test]
    fn gaussian_residuals_give_about_two_rms() {
        // deterministic normal-looking residuals from a fixed stream
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(7);
        let mut unit = || (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        let r: Vec<f64> = (0..4000)
            .map(|_| {
                let (a, b) = (unit(), unit());
                (-2.0 * (1.0 - a).ln()).sqrt() * (std::f64::consts::TAU * b).cos()
            })
            .collect();
        let b = Band::calibrate(&r, &vec![0.0; r.len()], 0.95).unwrap();
        assert!((b.quantile - 1.96).abs() < 0.1, "{b:?}");
        let half = vec![b.half_width(0.0); r.len()];
        let c = coverage(&r, &vec![0.0; r.len()], &half, 0).unwrap();
        assert!((c - 0.95).abs() < 0.01, "{c}");
    }

    /// The z of the band's level is the tabled one (a change of [`BAND_LEVEL`] must change
    /// it too).
    #[test]
    fn the_spread_is_covered_at_the_bands_level() {
        assert_eq!((BAND_LEVEL, BAND_Z), (0.95, 1.959_964));
    }

    #[test]
    fn spread_widens_the_band_and_bad_input_gives_none() {
        let b = Band::calibrate(&[1.0, -1.0, 0.5], &[0.0; 3], 0.9).unwrap();
        assert!(b.half_width(2.0) > b.half_width(0.0));
        assert!(Band::calibrate(&[], &[], 0.95).is_none());
        assert!(Band::calibrate(&[0.0, 0.0], &[0.0, 0.0], 0.95).is_none());
        assert!(Band::calibrate(&[1.0], &[f64::NAN], 0.95).is_none());
        assert_eq!(spread(&[&[1.0, 2.0][..], &[3.0, 2.0][..]], 2)[1], 0.0);
    }

    /// The floor is the level quantile of the residuals' magnitudes: a band calibrated on
    /// small tail residuals is widened to cover larger errors elsewhere; a floor below the band
    /// changes nothing; a model file without a floor loads with none.
    #[test]
    fn the_floor_covers_the_cross_validated_errors() {
        let tail = [0.1, -0.1, 0.05, -0.05];
        let b = Band::calibrate(&tail, &[0.0; 4], 0.95).unwrap();
        let every: Vec<f64> = (1..=99)
            .map(|k| if k % 2 == 0 { k as f64 } else { -k as f64 } / 100.0)
            .collect();
        let f = b.clone().with_floor(&every);
        // ceil(100 * 0.95) = 95th smallest of |r| = 0.95
        assert_eq!(f.floor, 0.95);
        assert_eq!(f.half_width(0.0), 0.95);
        let half = vec![f.half_width(0.0); every.len()];
        let c = coverage(&every, &vec![0.0; every.len()], &half, 0).unwrap();
        assert!(c >= 0.95, "{c}");
        assert_eq!(
            b.clone().with_floor(&[0.001, -0.001]).half_width(0.0),
            b.half_width(0.0)
        );
        assert_eq!(b.clone().with_floor(&[f64::NAN]).floor, 0.0);
        let json = serde_json::to_string(&b).unwrap();
        assert!(!json.contains("floor"), "{json}");
        let back: Band = serde_json::from_str(&json).unwrap();
        assert_eq!(back, b);
        assert!(f.check().is_ok());
        let mut bad = f;
        bad.floor = f64::NAN;
        assert!(bad.check().is_err());
    }
}
