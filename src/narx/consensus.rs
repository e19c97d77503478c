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
//! other candidates within `metrics::MEAN_ERROR_RATIO` of the lowest cross-validated error,
//! each refitted on the whole record (their fit without the last block where the refit fails),
//! in the cross-validation's order of preference, then the chosen candidate's own fits without
//! each block). The chosen run is the better over the record of its refit and those fits, so
//! where one of those fits is chosen it votes twice.
//! At every prediction they run beside it over the same inputs, and the output predicts their
//! pointwise median with the chosen base's run ([`committee_median`]). When the chosen base's
//! own run lies further than [`CONSENSUS_DEPARTURE`] standard deviations of the training
//! output from it (RMS), the departure is reported ([`Departure`]): the fits the record
//! supports disagree there, and the prediction is an extrapolation. The check reads the
//! inputs only: `predict` on a new record has it as the test half does.
//!
//! The median, not the chosen run alone: on a few hundred samples the cross-validated errors
//! rank candidates of comparable error by chance, and fits of one candidate on the record and
//! on its parts can part where the test half leaves the record (independent development seed
//! 2, 60 2-DoF short records: 39 -> 43 at 0.99 on both outputs, worse than the ARX 3 -> 0).
//! The median keeps a few wild members from moving it, where a mean followed them (the
//! chosen run and its own fits averaged: one output 0.90 -> 0.38 on the same seed).
//!
//! Only comparable candidates vote: a committee of every candidate outvotes a base with a mode
//! that the simpler lists lack (independent development seed 2, member 103: y1 0.988 -> 0.524
//! when the 21 others voted). The chosen candidate's own fits vote too: a refit whose
//! extrapolation its own folds do not share is the failure this guards against (held-out own
//! seed 1033, member 56, where no other candidate came within twice the lowest error).
//!
//! A long record's output keeps no committee: its validation part chooses among fits of
//! thousands of samples, and its base predicts alone. Its comparable candidates are kept as
//! witnesses (`super::base::BaseChoice::witnesses`) whose spread with the base widens its band
//! (`super::band::spread_cover`), without voting.
//!
//! This is query by committee (the committee's disagreement marks the inputs its data did not
//! decide) and bagging's aggregation (fits on parts of one record, combined) with a median.
//!
//! ## References
//! - H. S. Seung, M. Opper, H. Sompolinsky, "Query by committee", COLT 1992, 287-294.
//! - L. Breiman, "Bagging predictors", Machine Learning 24:123-140, 1996 (fits on resamples of
//!   one record as a committee).

use super::band::Band;
use crate::plant::OutputSpec;
use serde::{Deserialize, Serialize};

/// The RMS distance from the committee's pointwise median (in standard deviations of the
/// training output) beyond which the chosen base's departure is reported: a departure as large
/// as the output's own variation is no longer a matter of detail.
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
    /// The output's chain (in place of the base plant's output, it gives the member's run).
    pub output: OutputSpec,
    /// The band with which a member that replaced a departing base predicted, in files written
    /// before the committee's median predicted: read, not written, not used.
    #[serde(default, skip_serializing)]
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

/// An output whose grey-box base departed from its committee's median on a record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Departure {
    /// The base's effects.
    pub chosen: String,
    /// Its RMS distance from the committee's pointwise median (which predicts), in standard
    /// deviations of the training output.
    pub departure: f64,
}

impl std::fmt::Display for Departure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "its grey-box base `{}` departs by {:.3} standard deviations of the training output from the median of the fits the training record supports as well, which predicts instead: the fits disagree here, so treat the prediction as an extrapolation",
            self.chosen, self.departure
        )
    }
}

/// The pointwise median of the runs that are present, of the length of the first (the chosen
/// base's run) and finite; the first run itself where none is.
pub fn committee_median(runs: &[Option<&[f64]>]) -> Vec<f64> {
    let Some(first) = runs.first().copied().flatten() else {
        return Vec::new();
    };
    let n = first.len();
    let members = comparable(runs);
    if members.is_empty() {
        return first.to_vec();
    }
    let mut column = vec![0.0; members.len()];
    (0..n)
        .map(|k| {
            for (c, r) in column.iter_mut().zip(&members) {
                *c = r[k];
            }
            median(&mut column)
        })
        .collect()
}

/// The runs that are present, of the length of the first and finite: the members that vote.
fn comparable<'a>(runs: &[Option<&'a [f64]>]) -> Vec<&'a [f64]> {
    let n = runs.first().copied().flatten().map_or(0, <[f64]>::len);
    runs.iter()
        .flatten()
        .copied()
        .filter(|r| r.len() == n && r.iter().all(|v| v.is_finite()))
        .collect()
}

/// The committee's spread at each sample of the first run (the chosen base's): the members'
/// scaled median absolute deviation ([`super::band::spread`]) over the runs that vote in
/// [`committee_median`]; zeros with fewer than two. Where the fits the record supports part,
/// the prediction's band widens with it (`FittedNarx::predict`): they part where the record
/// did not decide the output (query by committee).
pub fn committee_spread(runs: &[Option<&[f64]>]) -> Vec<f64> {
    let n = runs.first().copied().flatten().map_or(0, <[f64]>::len);
    super::band::spread(&comparable(runs), n)
}

/// The median of `v` (sorted in place; the mean of the middle two of an even count), as
/// [`committee_median`] takes it at each sample (a stepped model too, `narx::state`).
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let m = v.len();
    if m % 2 == 1 {
        v[m / 2]
    } else {
        0.5 * (v[m / 2 - 1] + v[m / 2])
    }
}

/// The RMS distance of `run` from `median` in units of `std` (`None`: of another length, not
/// finite, or no unit).
pub fn departure(run: &[f64], median: &[f64], std: f64) -> Option<f64> {
    if run.is_empty() || run.len() != median.len() || std.is_nan() || std <= 0.0 {
        return None;
    }
    let ss: f64 = run
        .iter()
        .zip(median)
        .map(|(v, m)| ((v - m) / std).powi(2))
        .sum();
    let d = (ss / run.len() as f64).sqrt();
    d.is_finite().then_some(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_ignores_a_wild_run_and_measures_its_departure() {
        let a = vec![0.0, 1.0, 2.0, 3.0];
        let b = vec![0.1, 1.1, 2.1, 3.1];
        let c = [-0.1, 0.9, 1.9, 2.9];
        let wild = vec![0.0, 50.0, -80.0, 300.0];
        let runs = [
            Some(&wild[..]),
            Some(&a[..]),
            Some(&b[..]),
            Some(&c[..]),
            Some(&a[..]),
        ];
        // the median is `a` at every sample
        let m = committee_median(&runs);
        assert_eq!(m, a);
        assert!(departure(&wild, &m, 1.0).unwrap() > 100.0);
        assert!((departure(&b, &m, 1.0).unwrap() - 0.1).abs() < 1e-12);
        // std is the unit
        assert!((departure(&b, &m, 0.1).unwrap() - 1.0).abs() < 1e-9);
        // an even count: the middle two's mean
        let m = committee_median(&[Some(&b[..]), Some(&c[..])]);
        assert!(m.iter().zip(&a).all(|(x, y)| (x - y).abs() < 1e-12));
    }

    /// The spread is zero where the members agree and grows where they part; the runs the
    /// median leaves out (another length, not finite) take no part in it either.
    #[test]
    fn the_committee_spreads_where_its_members_part() {
        let a = [1.0, 2.0, 3.0];
        let b = [1.0, 2.5, 3.0];
        let c = [1.0, 1.5, 3.0];
        let nan = [f64::NAN, 9.0, 9.0];
        let short = [5.0];
        let s = committee_spread(&[Some(&a[..]), Some(&b[..]), Some(&c[..]), Some(&nan[..])]);
        assert_eq!(s.len(), 3);
        assert_eq!((s[0], s[2]), (0.0, 0.0));
        // the members' median absolute deviation (0.5) scaled to a standard deviation
        assert!((s[1] - 1.4826 * 0.5).abs() < 1e-12, "{s:?}");
        let with_short =
            committee_spread(&[Some(&a[..]), Some(&b[..]), Some(&c[..]), Some(&short[..])]);
        assert_eq!(with_short, s);
        // a base alone, or with nothing comparable, does not spread
        assert_eq!(committee_spread(&[Some(&a[..]), None]), vec![0.0; 3]);
        assert_eq!(
            committee_spread(&[Some(&a[..]), Some(&short[..])]),
            vec![0.0; 3]
        );
        assert!(committee_spread(&[None]).is_empty());
    }

    #[test]
    fn runs_that_cannot_be_compared_take_no_part() {
        let a = vec![0.0, 1.0];
        let short = vec![0.0];
        let nan = vec![f64::NAN, 1.0];
        let far = [10.0, 11.0];
        // the median of `a` and `far` alone
        let m = committee_median(&[
            Some(&a[..]),
            Some(&short[..]),
            Some(&nan[..]),
            None,
            Some(&far[..]),
        ]);
        assert_eq!(m, vec![5.0, 6.0]);
        // a base alone is its own median; a chosen run that is not finite leaves the others
        assert_eq!(committee_median(&[Some(&a[..]), None]), a);
        assert_eq!(committee_median(&[Some(&nan[..]), Some(&a[..])]), a);
        assert_eq!(committee_median(&[Some(&nan[..])])[1], 1.0);
        assert_eq!(departure(&short, &a, 1.0), None);
        assert_eq!(departure(&nan, &a, 1.0), None);
        assert_eq!(departure(&a, &a, 0.0), None);
    }
}
