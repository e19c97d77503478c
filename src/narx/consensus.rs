//! # The consensus of a short record's grey-box candidates
//!
//! A base cross-validated on a few hundred samples can fit every block of its record and still
//! leave by orders of magnitude at an input the record never showed: a 2-DoF staircase's new
//! pairing of levels, where a fitted output map or a coupling term meets values it was never
//! fitted on. The fits that the record supports as well (its own cross-validation fits, each
//! without one block, and the other candidates whose cross-validated error is comparable)
//! were fitted on the same samples; where they agree with one another and the chosen base
//! does not, the record gives no support to the chosen base's extrapolation.
//!
//! So each output predicted by the grey-box alone keeps that committee ([`Alternative`]: the
//! other candidates within `metrics::MEAN_ERROR_RATIO` of the lowest cross-validated error, each
//! one's fit without the last block, in the cross-validation's order of preference, then the
//! chosen candidate's own fits without each block; each with its band). At every prediction
//! they run beside it over the same inputs, and when the chosen base's RMS distance to their
//! pointwise median exceeds [`CONSENSUS_DEPARTURE`] standard deviations of the training
//! output, the first of them that stays within it predicts instead ([`Departure`] says which,
//! and by how much; when none does, the base predicts and the departure is reported). The
//! check reads the inputs only: `predict` on a new record has it as the test half does.
//!
//! Only comparable candidates vote: a committee of every candidate outvotes a base with a mode
//! that the simpler lists lack (independent development seed 2, member 103: y1 0.988 -> 0.524
//! when the 21 others voted). The chosen candidate's own fits vote too: a refit whose
//! extrapolation its own folds do not share is the failure this guards against (held-out own
//! seed 1033, member 56, where no other candidate came within twice the lowest error).
//!
//! This is query by committee (the committee's disagreement marks the inputs its data did not
//! decide) used to choose rather than to query; the median keeps a few wild members from
//! moving the reference.
//!
//! ## References
//! - H. S. Seung, M. Opper, H. Sompolinsky, "Query by committee", COLT 1992, 287-294.
//! - L. Breiman, "Bagging predictors", Machine Learning 24:123-140, 1996 (fits on resamples of
//!   one record as a committee).

use super::band::Band;
use crate::plant::OutputSpec;
use serde::{Deserialize, Serialize};

/// The RMS distance from the committee's pointwise median (in standard deviations of the
/// training output) beyond which the chosen base is replaced: a departure as large as the
/// output's own variation is no longer a matter of detail.
pub const CONSENSUS_DEPARTURE: f64 = 1.0;

/// A member of an output's committee: one output's chain of another candidate, or of the chosen
/// candidate fitted without one block.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Alternative {
    /// The candidate's effects (as `hystbench fit --effects` names them, and its stages).
    pub effects: String,
    /// The ridge on its hysteresis terms.
    pub ridge: f64,
    /// For the chosen candidate's own cross-validation fits: the block it was fitted without.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fold: Option<usize>,
    /// The output's chain (it replaces the base plant's output when it predicts).
    pub output: OutputSpec,
    /// Its band, calibrated as the chosen base's is (its cross-validated residuals).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub band: Option<Band>,
}

impl Alternative {
    /// Its effects and ridge, for messages.
    pub fn name(&self) -> String {
        let ridge = if self.ridge == 0.0 {
            "no ridge".to_string()
        } else {
            format!("ridge {:.0e}", self.ridge)
        };
        match self.fold {
            Some(k) => format!("{} ({ridge}, fitted without block {k})", self.effects),
            None => format!("{} ({ridge})", self.effects),
        }
    }
}

/// An output whose grey-box base departed from its candidates' consensus on a record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Departure {
    /// The base's effects.
    pub chosen: String,
    /// Its RMS distance from the candidates' pointwise median, in standard deviations of the
    /// training output.
    pub departure: f64,
    /// The candidate that predicted instead ([`Alternative::name`]); `None` when none stayed
    /// within [`CONSENSUS_DEPARTURE`] (the base then predicts, as chosen).
    pub replaced_by: Option<String>,
    /// The replacement's distance from the median.
    pub replacement_departure: Option<f64>,
}

impl std::fmt::Display for Departure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "its grey-box base `{}` departs by {:.3} standard deviations of the training output from the consensus of the fits the training record supports as well",
            self.chosen, self.departure
        )?;
        match (&self.replaced_by, self.replacement_departure) {
            (Some(r), Some(d)) => write!(f, "; `{r}` ({d:.3}) predicts it instead"),
            _ => write!(
                f,
                "; none of them stays within {CONSENSUS_DEPARTURE}, so it predicts as chosen: treat the prediction as an extrapolation"
            ),
        }
    }
}

/// The consensus check's verdict on an output that departed: by how much, and the member's
/// prediction and band that replace the base's (`None`: no member stays within).
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    pub departure: Departure,
    pub instead: Option<(Vec<f64>, Option<Band>)>,
}

/// Each run's RMS distance from the pointwise median of the runs (in units of `std`); `None`
/// for a run that is missing, of another length than the first, or not finite (it takes no
/// part in the median either).
pub fn departures(runs: &[Option<&[f64]>], std: f64) -> Vec<Option<f64>> {
    let Some(n) = runs.first().and_then(|r| r.map(<[f64]>::len)) else {
        return vec![None; runs.len()];
    };
    let valid: Vec<Option<&[f64]>> = runs
        .iter()
        .map(|r| r.filter(|r| r.len() == n && r.iter().all(|v| v.is_finite())))
        .collect();
    let members: Vec<&[f64]> = valid.iter().flatten().copied().collect();
    if n == 0 || members.is_empty() || std.is_nan() || std <= 0.0 {
        return vec![None; runs.len()];
    }
    let mut column = vec![0.0; members.len()];
    let median: Vec<f64> = (0..n)
        .map(|k| {
            for (c, r) in column.iter_mut().zip(&members) {
                *c = r[k];
            }
            column.sort_by(f64::total_cmp);
            let m = column.len();
            if m % 2 == 1 {
                column[m / 2]
            } else {
                0.5 * (column[m / 2 - 1] + column[m / 2])
            }
        })
        .collect();
    valid
        .iter()
        .map(|r| {
            r.map(|r| {
                let ss: f64 = r
                    .iter()
                    .zip(&median)
                    .map(|(v, m)| ((v - m) / std).powi(2))
                    .sum();
                (ss / n as f64).sqrt()
            })
        })
        .collect()
}

/// Which run predicts, given [`departures`] of the chosen base (first) and its committee in order
/// of preference: `None` while the chosen one stays within [`CONSENSUS_DEPARTURE`] (or its
/// departure is unknown), else `Some` of the first member within it (`Some(None)`: none is).
pub fn replacement(departures: &[Option<f64>]) -> Option<Option<usize>> {
    let within = |d: &Option<f64>| d.is_some_and(|d| d <= CONSENSUS_DEPARTURE);
    match departures.first() {
        Some(Some(d)) if *d > CONSENSUS_DEPARTURE => {
            Some((1..departures.len()).find(|&i| within(&departures[i])))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_far_from_the_others_departs_and_the_median_ignores_it() {
        let a = vec![0.0, 1.0, 2.0, 3.0];
        let b = vec![0.1, 1.1, 2.1, 3.1];
        let c = vec![-0.1, 0.9, 1.9, 2.9];
        let wild = vec![0.0, 50.0, -80.0, 300.0];
        let d = departures(&[Some(&wild), Some(&a), Some(&b), Some(&c), Some(&a)], 1.0);
        // the median is `a` at every sample
        assert_eq!(d[1], Some(0.0));
        assert!((d[2].unwrap() - 0.1).abs() < 1e-12);
        assert!(d[0].unwrap() > 100.0);
        assert_eq!(replacement(&d), Some(Some(1)));
        // the same runs with the base among them: kept
        let d = departures(&[Some(&b), Some(&a), Some(&wild), Some(&c), Some(&a)], 1.0);
        assert_eq!(replacement(&d), None);
    }

    #[test]
    fn runs_that_cannot_be_compared_take_no_part() {
        let a = vec![0.0, 1.0];
        let short = vec![0.0];
        let nan = vec![f64::NAN, 1.0];
        let d = departures(&[Some(&a), Some(&short), Some(&nan), None], 1.0);
        assert_eq!(d, vec![Some(0.0), None, None, None]);
        assert_eq!(replacement(&d), None);
        // a wild member is passed over; none within the limit: the base stays, reported
        let far = vec![10.0, 11.0];
        let wild = vec![-40.0, 30.0];
        let d = departures(
            &[Some(&far), Some(&wild), Some(&a), Some(&a), Some(&a)],
            1.0,
        );
        assert_eq!(replacement(&d), Some(Some(2)));
        let d = [Some(5.0), Some(3.0), None];
        assert_eq!(replacement(&d), Some(None));
        // std is the unit
        let d = departures(&[Some(&far), Some(&a), Some(&a)], 20.0);
        assert_eq!(replacement(&d), None);
    }
}
