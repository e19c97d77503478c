//! # MR damper study: train on sine tests, test on an earthquake record
//!
//! Measured magnetorheological damper (UTFSM data, `mr-damper-utfsm/README.md`), driven in
//! displacement x (mm), force F (N) measured, at several coil currents I (A).
//!
//! Protocol (fixed, printed by the command):
//! - training: the ten 1 ms sine records (10 mm at 1 Hz and 5 mm at 3 Hz, at 0, 0.25, 0.5,
//!   0.75 and 1.0 A) for every model; the grey-box models, which are continuous-time and run at
//!   each record's own sampling period, also train on the 5 ms sine records of the folder
//!   ([`OTHER_TESTS`]: 25 mm at 0.1, 0.25, 0.5 Hz and 2 mm at 5 Hz; their slow motions hold the
//!   low-velocity regime of the earthquake record). The NARX, whose lags count samples, does
//!   not: records of different sampling periods are refused together for it
//!   ([`check_sampling_periods`]) rather than silently resampled;
//! - test: the earthquake record (1 ms, 64,648 samples), one free run from rest per current
//!   0.2, 0.4, 0.6, 0.8, 1.0 A (none of them is a training current except 1.0 A), scored over
//!   the whole record: R^2 and RMS error in N;
//! - every model is run from rest on each record separately: no state, regressor or window ever
//!   crosses a record boundary.
//!
//! Grey-box: F = c0 dx/dt + k0 x + alpha g + f0, dx/dt the library's viscous operator (backward
//! difference), g either the library's Bouc-Wen state on x (n = 1, A = 1, mm; Spencer's simple
//! Bouc-Wen model, [`Structure::BoucWen`]) or tanh((dx/dt) / v0) (a smoothed Bingham plastic,
//! [`Structure::Bingham`]). For fixed (B, Gamma) or v0 the model is linear in
//! (c0, k0, alpha, f0): least squares inside, Nelder-Mead or golden section outside (variable
//! projection). Two ways to cover the currents:
//! - `scheduled`: one model for all currents, (B, Gamma) or v0 shared and c0, k0, alpha, f0
//!   affine in I (Spencer et al.'s c0 = c0a + c0b u, alpha = alpha_a + alpha_b u);
//! - `per-current`: one model per training current, every parameter interpolated linearly in I
//!   between the two neighbouring training currents.
//!
//! Spencer et al.'s full model ([`Structure::Spencer`], [`spencer`]) adds the pre-yield
//! dashpot c1 in series with the Bouc-Wen element and the accumulator spring k1; it is not
//! linear in its dashpots and is fitted by Levenberg-Marquardt on the simulation error
//! (scheduled: c0, alpha, c1 affine in I).
//!
//! The headline grey-box is the scheduled structure with the lowest leave-one-test-out error on
//! the training records ([`cross_validate`]); the test record plays no part in the choice.
//!
//! NARX: inputs x and I (a constant column), output F, trained on the ten records at once
//! ([`NarxConfig::fit_records`]) after subsampling every record by [`NARX_DECIMATION`] (1 ms ->
//! 10 ms: at 1 ms the lags would cover only a few ms of a 1-3 Hz motion; the records' moving
//! averages of >= 33 samples already remove what 10 ms cannot carry). Scored on the earthquake
//! record subsampled the same way.
//!
//! ## References
//! - B. F. Spencer Jr., S. J. Dyke, M. K. Sain, J. D. Carlson, "Phenomenological model for
//!   magnetorheological dampers", J. Eng. Mech. 123(3):230-238, 1997.
//! - J. A. Nelder, R. Mead, "A simplex method for function minimization", Comput. J.
//!   7(4):308-313, 1965.
//! - G. H. Golub, V. Pereyra, SIAM J. Numer. Anal. 10(2):413-432, 1973 (variable projection).
//! - Data: D. Maurel, M. Quiroz, github.com/DanielMaurelE/vRTHS_AMBC_MRdamper (MIT).

mod data;
mod model;
mod narx;
pub mod spencer;

pub use data::*;
pub use model::*;
pub use narx::*;

use crate::data::{read_csv, DataError, IoRecord, Record, Signal};
use crate::effect::bouc_wen::BoucWenSpec;
use crate::effect::viscous::rate;
use crate::effect::Operator;
use crate::metrics;
use crate::narx::{FittedNarx, Interaction, Lags, Mode, NarxConfig, NarxError};

use rayon::prelude::*;
use std::path::{Path, PathBuf};
// ---------------------------------------------------------------------------------------------
// Scoring and the whole study

/// The score of one model at one test current; `None` = the free run diverged.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CurrentScore {
    pub current: f64,
    pub r2: Option<f64>,
    pub rms_n: Option<f64>,
}

/// Scores a prediction (`None` or non-finite = diverged).
pub fn score(current: f64, measured: &[f64], predicted: Option<&[f64]>) -> CurrentScore {
    match predicted {
        Some(p) if p.len() == measured.len() && p.iter().all(|v| v.is_finite()) => {
            let s = metrics::scores(measured, p);
            CurrentScore {
                current,
                r2: s.r2,
                rms_n: Some(s.rmse),
            }
        }
        _ => CurrentScore {
            current,
            r2: None,
            rms_n: None,
        },
    }
}

/// One grey-box variant: a structure, scheduled (one model, affine in I) or per current
/// (interpolated), its fit and its test scores and predictions.
#[derive(Debug, Clone, PartialEq)]
pub struct GreyBoxVariant {
    pub structure: Structure,
    pub scheduled: bool,
    /// Scheduled: the one fit; per current: empty (see `per_current`).
    pub fit: Option<SpencerFit>,
    pub per_current: Option<PerCurrent>,
    /// Leave-one-test-out RMS (N) on the training records (scheduled variants only).
    pub cv_rms_n: Option<f64>,
    pub scores: Vec<CurrentScore>,
    /// Free run on the test record per current (1 ms).
    pub predictions: Vec<Vec<f64>>,
}

impl GreyBoxVariant {
    /// `bouc-wen scheduled`, `bingham per-current`…
    pub fn name(&self) -> String {
        format!(
            "{} {}",
            self.structure.as_str(),
            if self.scheduled {
                "scheduled"
            } else {
                "per-current"
            }
        )
    }

    /// The parameters at current `i`.
    pub fn at(&self, i: f64) -> Option<SpencerParams> {
        match (&self.fit, &self.per_current) {
            (Some(f), _) => Some(f.at(i)),
            (None, Some(p)) => Some(p.at(i)),
            _ => None,
        }
    }
}

/// Everything the study measures.
#[derive(Debug, Clone, PartialEq)]
pub struct MrDamperResult {
    pub narx: Vec<CurrentScore>,
    /// NARX free runs (10 ms; `None` when diverged).
    pub narx_predictions: Vec<Option<Vec<f64>>>,
    /// Every grey-box variant; `greybox[headline]` is the one chosen by cross-validation on
    /// the training records (lowest `cv_rms_n` among the scheduled variants).
    pub greybox: Vec<GreyBoxVariant>,
    pub headline: usize,
    pub narx_seconds: f64,
    pub greybox_seconds: f64,
    /// Samples of the 1 ms sine records (every model) and of the other ones (grey-box only).
    pub train_samples: usize,
    pub other_samples: usize,
    /// The other sine records used, by file name.
    pub other_files: Vec<String>,
    pub test_samples: usize,
}

/// Leave-one-test-out cross-validation of a scheduled structure on the training records:
/// for each test group (e.g. all 1 Hz records), fit on the others and run the held-out
/// records from rest; the pooled RMS error (N). `None` with fewer than two groups.
pub fn cross_validate(recs: &[DamperRecord], structure: Structure) -> Option<f64> {
    let mut groups: Vec<&str> = recs.iter().map(|r| r.group.as_str()).collect();
    groups.sort_unstable();
    groups.dedup();
    if groups.len() < 2 {
        return None;
    }
    let parts: Vec<Option<(f64, usize)>> = groups
        .par_iter()
        .map(|g| {
            let train: Vec<&DamperRecord> = recs.iter().filter(|r| r.group != *g).collect();
            let fit = fit_structure(&train, structure, true)?;
            let mut sse = 0.0;
            let mut n = 0;
            for r in recs.iter().filter(|r| r.group == *g) {
                let p = fit.at(r.current).simulate(&r.x, r.ts);
                sse += p
                    .iter()
                    .zip(&r.f)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>();
                n += r.f.len();
            }
            Some((sse, n))
        })
        .collect();
    let (mut sse, mut n) = (0.0, 0usize);
    for p in parts {
        let (s, k) = p?;
        sse += s;
        n += k;
    }
    let rms = (sse / n.max(1) as f64).sqrt();
    rms.is_finite().then_some(rms)
}

fn failed(what: &str) -> MrDamperError {
    MrDamperError::NoCurrent {
        current: f64::NAN,
        have: format!("(the {what} fit failed: non-finite least squares)"),
    }
}

/// The grey-box part: every structure, scheduled and per current, scored on the test record;
/// the headline is the scheduled structure with the lowest cross-validation error on the
/// training records (the test record plays no part in the choice).
pub fn run_greybox(data: &MrDamperData) -> Result<(Vec<GreyBoxVariant>, usize), MrDamperError> {
    // every sine record: the grey-box models run at each record's own sampling period
    let train: Vec<DamperRecord> = data.train.iter().chain(&data.other).cloned().collect();
    let all: Vec<&DamperRecord> = train.iter().collect();
    let t = &data.test;
    let mut out = Vec::new();
    for structure in [Structure::BoucWen, Structure::Bingham, Structure::Spencer] {
        let (fit, per) = match (
            fit_structure(&all, structure, true),
            fit_per_current(&train, structure),
        ) {
            (Some(f), Ok(p)) => (f, p),
            // the full model's nonlinear fit can find no finite start on odd data: the study
            // goes on with the simple models, which always fit (linear least squares inside)
            _ if structure == Structure::Spencer => continue,
            (None, _) => return Err(failed("scheduled")),
            (_, Err(e)) => return Err(e),
        };
        let cv = cross_validate(&train, structure);
        for (scheduled, fit, per) in [(true, Some(fit), None), (false, None, Some(per))] {
            let mut v = GreyBoxVariant {
                structure,
                scheduled,
                fit,
                per_current: per,
                cv_rms_n: if scheduled { cv } else { None },
                scores: Vec::new(),
                predictions: Vec::new(),
            };
            for (i, f) in &t.forces {
                let p = v
                    .at(*i)
                    .ok_or_else(|| failed("grey-box"))?
                    .simulate(&t.x, t.ts);
                v.scores.push(score(*i, f, Some(&p)));
                v.predictions.push(p);
            }
            out.push(v);
        }
    }
    let headline = (0..out.len())
        .filter(|&k| out[k].scheduled)
        .min_by(|&a, &b| {
            let c = |k: usize| out[k].cv_rms_n.unwrap_or(f64::INFINITY);
            c(a).total_cmp(&c(b))
        })
        .unwrap_or(0);
    Ok((out, headline))
}

/// NARX free runs per current (`None` when diverged).
pub type NarxPredictions = Vec<Option<Vec<f64>>>;

/// The NARX part: free run per current on the decimated test record.
pub fn score_narx(
    model: &FittedNarx,
    data: &MrDamperData,
) -> Result<(Vec<CurrentScore>, NarxPredictions), MrDamperError> {
    let t = &data.test;
    let mut scores = Vec::new();
    let mut preds = Vec::new();
    for (i, f) in &t.forces {
        let rec = narx_record(&t.path, &t.x, *i, None, t.ts);
        let p = model.predict(&rec, Mode::FreeRun)?;
        let p = &p[0];
        let measured = decimate(f, NARX_DECIMATION);
        let pred = p.diverged_at.is_none().then(|| p.values.clone());
        scores.push(score(*i, &measured, pred.as_deref()));
        preds.push(pred);
    }
    Ok((scores, preds))
}

/// The whole study: NARX and grey-box trained on the sine records, scored on the earthquake
/// record per current.
pub fn run(data: &MrDamperData) -> Result<MrDamperResult, MrDamperError> {
    let t = std::time::Instant::now();
    let (greybox, headline) = run_greybox(data)?;
    let greybox_seconds = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let model = fit_narx(data)?;
    let narx_seconds = t.elapsed().as_secs_f64();
    let (narx, narx_predictions) = score_narx(&model, data)?;
    Ok(MrDamperResult {
        narx,
        narx_predictions,
        greybox,
        headline,
        narx_seconds,
        greybox_seconds,
        train_samples: data.train.iter().map(|r| r.x.len()).sum(),
        other_samples: data.other.iter().map(|r| r.x.len()).sum(),
        other_files: data
            .other
            .iter()
            .map(|r| {
                r.path
                    .file_name()
                    .map(|f| f.to_string_lossy().to_string())
                    .unwrap_or_default()
            })
            .collect(),
        test_samples: data.test.x.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(i: f64, n: usize, ts: f64, p: &SpencerParams) -> DamperRecord {
        let x: Vec<f64> = (0..n)
            .map(|k| 5.0 * (2.0 * std::f64::consts::PI * 2.0 * k as f64 * ts).sin())
            .collect();
        let f = p.simulate(&x, ts);
        DamperRecord {
            path: PathBuf::from(format!("sim{i}")),
            group: format!("g{}", n % 2),
            x,
            f,
            current: i,
            ts,
        }
    }

    #[test]
    fn spencer_fit_recovers_a_simulated_damper() {
        let truth = |i: f64| SpencerParams {
            structure: Structure::BoucWen,
            v0: 0.0,
            c0: 1.0 + 2.0 * i,
            k0: 3.0,
            alpha: 50.0 + 100.0 * i,
            f0: 0.0,
            b: 2.0,
            gamma: 0.5,
            c1: 0.0,
            k1: 0.0,
        };
        let recs: Vec<DamperRecord> = [0.0, 0.5, 1.0]
            .iter()
            .map(|&i| sine(i, 2000, 1e-3, &truth(i)))
            .collect();
        let refs: Vec<&DamperRecord> = recs.iter().collect();
        let fit = fit_spencer(&refs, true).unwrap();
        assert!(fit.train_rms_n < 1e-4, "{fit:?}");
        let p = fit.at(0.25);
        let t = truth(0.25);
        assert!(
            (p.b - t.b).abs() < 1e-3 && (p.gamma - t.gamma).abs() < 1e-3,
            "{p:?}"
        );
        assert!(
            (p.c0 - t.c0).abs() < 1e-3 && (p.alpha - t.alpha).abs() < 1e-2,
            "{p:?}"
        );
        let per = fit_per_current(&recs, Structure::BoucWen).unwrap();
        let q = per.at(0.25);
        assert!((q.c0 - t.c0).abs() < 1e-3, "{q:?}");
    }

    #[test]
    fn mixed_sampling_periods_are_refused_naming_both() {
        let e = check_sampling_periods(&[
            (Path::new("a.csv"), 0.001),
            (Path::new("b.csv"), 0.001),
            (Path::new("c.csv"), 0.005),
        ])
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("c.csv")
                && e.contains("0.005")
                && e.contains("a.csv")
                && e.contains("0.001"),
            "{e}"
        );
    }

    #[test]
    fn diverged_is_not_a_number() {
        let s = score(0.2, &[1.0, 2.0], None);
        assert_eq!((s.r2, s.rms_n), (None, None));
        let s = score(0.2, &[1.0, 2.0], Some(&[1.0, f64::INFINITY]));
        assert_eq!(s.rms_n, None);
        let s = score(0.2, &[1.0, 2.0, 3.0], Some(&[1.0, 2.0, 4.0]));
        assert!((s.rms_n.unwrap() - (1.0f64 / 3.0).sqrt()).abs() < 1e-12);
    }
}
