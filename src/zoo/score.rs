//! Scoring a zoo: the default identifier (`NarxConfig::new(..).fit`, what `hystbench identify`
//! runs without options) and a linear ARX baseline with the same lags, each trained on the first
//! half of every record and run free on the second; the free-run test R^2 per output, summed up
//! per class.

use super::{median, noiseless, share, Class, IndexEntry, ZooError, ZooIndex};
use crate::data::{read_csv, IoRecord};
use crate::narx::arx::fit_arx;
use crate::narx::base::BaseUse;
use crate::narx::NarxConfig;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// One output of one record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputScore {
    pub name: String,
    /// Free-run test R^2 of the default identifier (`None`: diverged, or undefined).
    pub r2: Option<f64>,
    pub diverged: bool,
    /// Its free-run R^2 on the training half.
    pub r2_train: Option<f64>,
    /// The same for the ARX baseline.
    pub arx_r2: Option<f64>,
    pub arx_diverged: bool,
    /// The R^2 of the true plant (its noiseless output) on the test half: the ceiling the
    /// measurement noise sets.
    pub truth_r2: Option<f64>,
    /// The identifier's and the baseline's free runs scored against the noiseless output
    /// instead of the measurement: the model's own error, without the noise.
    pub r2_clean: Option<f64>,
    pub arx_r2_clean: Option<f64>,
    /// Share of the test samples whose measurement lies inside the identifier's 95 % band
    /// (`None`: no band, or the free run diverged).
    pub coverage: Option<f64>,
    /// The band's mean half-width over the test samples, over the test output's standard
    /// deviation (`None` as for `coverage`): a coverage is only as good as the band is narrow.
    #[serde(default)]
    pub band_width: Option<f64>,
    /// What the identifier made of this output ([`crate::narx::base::BaseUse`]): the network,
    /// the grey-box model alone, or the grey-box model under a network on its residual.
    pub model: BaseUse,
    /// With `zoo score --noiseless-training`: the identifier fitted again on the noiseless
    /// training half.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noiseless_training: Option<NoiselessTraining>,
}

/// One output of the identifier fitted on the noiseless training half instead of the
/// measured one (`zoo score --noiseless-training`): its free-run R^2 on the noiseless training
/// half, and on the noiseless test half (`None`: diverged, or the fit failed).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoiselessTraining {
    pub r2_train: Option<f64>,
    pub r2: Option<f64>,
}

/// How much closer than its noiseless test half a model fitted on the noiseless training half
/// must fit that training half (the ratio of their errors, 1 - R^2) for [`Miss::NotDetermined`]:
/// a tenth, so that the test's error is not the training's carried on.
pub const DETERMINED_RATIO: f64 = 0.1;

/// Why an output below its class's threshold misses it, from the identifier fitted again on
/// the noiseless training half (`zoo score --noiseless-training`). The order is the
/// precedence of a record's outputs ([`Miss::of_record`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Miss {
    /// The true plant misses too: the measurement noise in the test half alone does it.
    NoiseCeiling,
    /// Fitted without noise, the identifier still misses the training half: the model family,
    /// or its fit, lacks what the plant does.
    FitMissesTraining,
    /// Fitted without noise, it fits the training half (its error there at most
    /// [`DETERMINED_RATIO`] of the test half's) and misses the test half: the training half
    /// leaves undetermined what the test half asks.
    NotDetermined,
    /// Fitted without noise, it reaches the threshold on the noiseless test half: the noise
    /// in the training half costs it.
    TrainingNoise,
}

impl Miss {
    /// Why output `o` misses `threshold` (`None`: it does not, or it was not fitted again
    /// without noise).
    pub fn of_output(o: &OutputScore, threshold: f64) -> Option<Miss> {
        if o.r2.is_some_and(|v| v >= threshold) {
            return None;
        }
        let n = o.noiseless_training.as_ref()?;
        if !o.truth_r2.is_some_and(|v| v >= threshold) {
            return Some(Miss::NoiseCeiling);
        }
        Some(match (n.r2_train, n.r2) {
            (_, Some(r2)) if r2 >= threshold => Miss::TrainingNoise,
            (Some(t), Some(r2)) if 1.0 - t <= DETERMINED_RATIO * (1.0 - r2) => Miss::NotDetermined,
            _ => Miss::FitMissesTraining,
        })
    }

    /// Why a record misses `threshold`: the first, in [`Miss`]'s order, of its outputs'.
    pub fn of_record(r: &RecordScore, threshold: f64) -> Option<Miss> {
        r.outputs
            .iter()
            .filter_map(|o| Miss::of_output(o, threshold))
            .min()
    }
}

/// The records of a class below its floor that were fitted again without noise, by
/// [`Miss`].
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Misses {
    pub noise_ceiling: usize,
    pub fit_misses_training: usize,
    pub not_determined: usize,
    pub training_noise: usize,
}

impl OutputScore {
    /// Worse than the linear baseline: a lower R^2, or diverged where the baseline did not.
    pub fn worse_than_arx(&self) -> bool {
        match (self.r2, self.arx_r2) {
            (Some(a), Some(b)) => a < b,
            (None, Some(_)) => true,
            _ => false,
        }
    }
}

/// One record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordScore {
    pub index: usize,
    pub class: Class,
    pub samples: usize,
    pub sampling_period_s: f64,
    pub outputs: Vec<OutputScore>,
    /// The largest share of the test half's samples outside the training region in one way
    /// (an input beyond its training range, faster than in training, or the inputs in
    /// combinations the training half did not visit: [`crate::narx::FittedNarx::outside`], what
    /// `identify` warns of); 0 inside. A score written before it was kept reads as 0.
    #[serde(default)]
    pub outside: f64,
    /// Wall-clock time of the default identifier's fit (s); records scored side by side
    /// ([`Schedule`]) share the threads, and each takes longer than alone.
    pub seconds: f64,
}

impl RecordScore {
    /// Whether some output was fitted again on its noiseless training half.
    fn fitted_without_noise(&self) -> bool {
        self.outputs.iter().any(|o| o.noiseless_training.is_some())
    }
}

/// The distribution of one score over a class.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Distribution {
    /// Quantiles 0, 0.05, 0.25, 0.5 of the R^2 (a diverged output counts as minus infinity,
    /// written `null`).
    pub min: Option<f64>,
    pub q05: Option<f64>,
    pub q25: Option<f64>,
    pub median: Option<f64>,
    /// Outputs with R^2 >= 0.99, >= 0.999, and diverged.
    pub at_least_099: usize,
    pub at_least_0999: usize,
    pub diverged: usize,
}

/// One class.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClassSummary {
    pub class: Class,
    pub records: usize,
    pub outputs: usize,
    pub narx: Distribution,
    pub arx: Distribution,
    /// The true plant's (the noise ceiling).
    pub truth: Distribution,
    /// Against the noiseless output.
    pub narx_clean: Distribution,
    pub arx_clean: Distribution,
    /// Records whose every output reaches 0.99 / 0.999.
    pub records_all_099: usize,
    pub records_all_0999: usize,
    /// The class's floor ([`Class::floor`]) and the records whose every output reaches its
    /// threshold: against the measurement, against the noiseless output, and the true plant
    /// against the measurement (the ceiling the noise sets).
    pub floor: f64,
    pub floor_share: Option<f64>,
    pub records_at_floor: usize,
    pub records_at_floor_clean: usize,
    pub records_at_floor_truth: usize,
    /// Outputs worse than the ARX baseline.
    pub worse_than_arx: usize,
    /// Outputs within 0.001 of the true plant's R^2 (as good as the noise allows).
    pub near_truth: usize,
    /// Outputs whose band covers at least 90 % of the test samples, and the mean coverage
    /// (over outputs with a band).
    pub covered_090: usize,
    pub mean_coverage: Option<f64>,
    /// The median over the outputs of the band's mean half-width over the test output's
    /// standard deviation.
    #[serde(default)]
    pub median_band_width: Option<f64>,
    /// Records whose test half leaves the training region on at least [`OUTSIDE_NOTED`] of its
    /// samples ([`RecordScore::outside`]), and of the records below the floor, those that do.
    pub leaving: usize,
    pub below_floor_leaving: usize,
    /// Outputs whose model is the grey-box base alone, and the base under a network.
    pub base_alone: usize,
    pub base_and_network: usize,
    /// With `--noiseless-training`: why the records below the floor miss it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub misses: Option<Misses>,
    /// Median of the train - test free-run R^2 gap.
    pub median_gap: Option<f64>,
    pub median_seconds: f64,
    pub total_seconds: f64,
}

/// The share of a test half's samples outside the training region from which a record counts
/// as leaving it in the report ([`ClassSummary::leaving`]).
pub const OUTSIDE_NOTED: f64 = 0.1;

/// A scored zoo.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ZooScore {
    pub seed: u64,
    pub records: Vec<RecordScore>,
    pub classes: Vec<ClassSummary>,
}

/// R^2 of a free run against the noiseless output over `start..` (`None` when diverged).
fn clean_r2(clean: &[f64], pred: &[f64], start: usize, diverged: Option<usize>) -> Option<f64> {
    if diverged.is_some() || pred.len() != clean.len() {
        return None;
    }
    crate::metrics::r2(&clean[start..], &pred[start..])
}

/// The identifier fitted on `train` with its outputs replaced by the noiseless ones `truth`
/// (of the whole record), scored per output on the noiseless training and test halves
/// (`None` where the fit fails: a noiseless output it cannot be fitted to).
fn noiseless_training(
    train: &IoRecord,
    test: &IoRecord,
    truth: &[Vec<f64>],
) -> Vec<NoiselessTraining> {
    let h = train.len();
    let mut clean = train.clone();
    for (s, t) in clean.outputs.iter_mut().zip(truth) {
        s.values = t[..h].to_vec();
    }
    let failed = || {
        vec![
            NoiselessTraining {
                r2_train: None,
                r2: None,
            };
            truth.len()
        ]
    };
    let Ok(model) = NarxConfig::new(clean.input_names(), clean.output_names()).fit(&clean) else {
        return failed();
    };
    let mode = crate::narx::Mode::FreeRun;
    let (Ok(on_train), Ok(on_test)) = (
        model.predict_after(None, &clean, mode),
        model.predict_after(Some(&clean), test, mode),
    ) else {
        return failed();
    };
    on_train
        .iter()
        .zip(&on_test)
        .zip(truth)
        .map(|((a, b), t)| NoiselessTraining {
            r2_train: clean_r2(&t[..h], &a.values, a.start, a.diverged_at),
            r2: clean_r2(&t[h..], &b.values, b.start, b.diverged_at),
        })
        .collect()
}

/// Scores one member's record (and with `with_noiseless`, fits it again on its noiseless
/// training half).
fn score_member(dir: &Path, e: &IndexEntry, with_noiseless: bool) -> Result<RecordScore, ZooError> {
    let path = dir.join(&e.record);
    let io = IoRecord::from_record(&read_csv(&path)?, None, None, true)?;
    let (train, test) = io.split_halves();
    let narx_err = |source| ZooError::Narx {
        path: path.clone(),
        source,
    };
    let t0 = Instant::now();
    let model = NarxConfig::new(train.input_names(), train.output_names())
        .fit(&train)
        .map_err(narx_err)?;
    let seconds = t0.elapsed().as_secs_f64();
    // the two free runs the score needs (what `evaluate` scores, without its one-step runs)
    // (the test half continues the training half: a grey-box base runs on through it)
    let free_run = |h: Option<&IoRecord>, rec: &IoRecord| {
        model.predict_after(h, rec, crate::narx::Mode::FreeRun)
    };
    let fr_train = free_run(None, &train).map_err(narx_err)?;
    let fr_test = free_run(Some(&train), &test).map_err(narx_err)?;
    let arx = fit_arx(&train, model.config.lags).map_err(narx_err)?;
    let runs = arx.free_run(&test);
    let truth = noiseless(dir, e)?;
    let h = train.len();
    let mut again = if with_noiseless {
        noiseless_training(&train, &test, &truth)
            .into_iter()
            .map(Some)
            .collect()
    } else {
        vec![None; truth.len()]
    };
    let r2 = |p: &crate::narx::OutputPrediction, y: &[f64]| p.scores(y).and_then(|s| s.r2);
    let outputs = (0..test.outputs.len())
        .map(|o| {
            let (y, fr, run, clean) = (
                &test.outputs[o].values,
                &fr_test[o],
                &runs[o],
                &truth[o][h..],
            );
            let (coverage, band_width) = fr.band_scores(y);
            OutputScore {
                name: fr.name.clone(),
                r2: r2(fr, y),
                diverged: fr.diverged_at.is_some(),
                r2_train: r2(&fr_train[o], &train.outputs[o].values),
                arx_r2: run.scores(y).and_then(|s| s.r2),
                arx_diverged: run.diverged_at.is_some(),
                truth_r2: crate::metrics::r2(y, clean),
                r2_clean: clean_r2(clean, &fr.values, fr.start, fr.diverged_at),
                arx_r2_clean: clean_r2(clean, &run.values, run.start, run.diverged_at),
                coverage,
                band_width,
                model: model.base.as_ref().map_or(BaseUse::Network, |b| b.uses(o)),
                noiseless_training: again[o].take(),
            }
        })
        .collect();
    Ok(RecordScore {
        index: e.index,
        class: e.class,
        samples: e.samples,
        sampling_period_s: e.sampling_period_s,
        outputs,
        outside: model
            .outside(&test)
            .iter()
            .map(|o| o.share)
            .fold(0.0, f64::max),
        seconds,
    })
}

/// How a zoo's records are scored: side by side (each fit's threads shared with the other
/// records', the machine kept busy) or one after another (each fit with every thread: the
/// records' times are those of a lone `identify`). The scores are the same bits either way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Schedule {
    SideBySide,
    OneAtATime,
}

/// How a zoo is scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScoreOptions {
    pub schedule: Schedule,
    /// Fit the identifier again on each record's noiseless training half
    /// ([`NoiselessTraining`], [`Miss`]): twice the time.
    pub noiseless_training: bool,
}

/// Scores every record of the zoo in `dir`. `progress` hears each record when it is scored.
pub fn score(
    dir: &Path,
    options: ScoreOptions,
    progress: &(dyn Fn(&RecordScore) + Sync),
) -> Result<ZooScore, ZooError> {
    let seed = ZooIndex::read(dir)?.seed;
    Ok(ZooScore::of(
        seed,
        score_members(dir, &|_| true, options, progress)?,
    ))
}

/// Scores the members of the zoo in `dir` whose position in its index `take` accepts (a part
/// of the zoo, for a cluster scheduler's array job), in the zoo's order whatever the
/// schedule (the first damaged record's error, in that order); [`ZooScore::of`] joins the
/// parts.
///
/// Side by side, a fit's parallel parts (its candidates, folds and starts) and the other
/// records' share the threads by work stealing: a fit alone leaves a core idle where its
/// parts end unevenly (about 8 % of two cores on a 200-record zoo).
pub fn score_members(
    dir: &Path,
    take: &(dyn Fn(usize) -> bool + Sync),
    options: ScoreOptions,
    progress: &(dyn Fn(&RecordScore) + Sync),
) -> Result<Vec<RecordScore>, ZooError> {
    let index = ZooIndex::read(dir)?;
    let members: Vec<&IndexEntry> = index
        .members
        .iter()
        .enumerate()
        .filter(|&(i, _)| take(i))
        .map(|(_, e)| e)
        .collect();
    let one = |e: &&IndexEntry| {
        let r = score_member(dir, e, options.noiseless_training);
        if let Ok(r) = &r {
            progress(r);
        }
        r
    };
    match options.schedule {
        // (stops at the first error)
        Schedule::OneAtATime => members.iter().map(one).collect(),
        Schedule::SideBySide => {
            let scored: Vec<Result<RecordScore, ZooError>> =
                members.par_iter().with_max_len(1).map(one).collect();
            scored.into_iter().collect()
        }
    }
}

impl ZooScore {
    /// The summary of scored records (in the zoo's order) of the zoo of `seed`.
    pub fn of(seed: u64, records: Vec<RecordScore>) -> ZooScore {
        let classes = Class::ALL
            .iter()
            .filter_map(|&c| summarise(c, &records))
            .collect();
        ZooScore {
            seed,
            records,
            classes,
        }
    }
}

/// The `q` quantile (nearest rank, from below) of sorted values.
fn quantile(sorted: &[f64], q: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let k = ((sorted.len() - 1) as f64 * q).floor() as usize;
    Some(sorted[k]).filter(|v| v.is_finite())
}

fn distribution(r2: &[Option<f64>]) -> Distribution {
    let mut v: Vec<f64> = r2.iter().map(|x| x.unwrap_or(f64::NEG_INFINITY)).collect();
    v.sort_by(f64::total_cmp);
    Distribution {
        min: quantile(&v, 0.0),
        q05: quantile(&v, 0.05),
        q25: quantile(&v, 0.25),
        median: quantile(&v, 0.5),
        at_least_099: v.iter().filter(|&&x| x >= 0.99).count(),
        at_least_0999: v.iter().filter(|&&x| x >= 0.999).count(),
        diverged: r2.iter().filter(|x| x.is_none()).count(),
    }
}

fn summarise(class: Class, records: &[RecordScore]) -> Option<ClassSummary> {
    let mine: Vec<&RecordScore> = records.iter().filter(|r| r.class == class).collect();
    if mine.is_empty() {
        return None;
    }
    let outs: Vec<&OutputScore> = mine.iter().flat_map(|r| &r.outputs).collect();
    // whether every output of a record reaches `t` in the score `f`
    let reaches = |r: &RecordScore, t: f64, f: fn(&OutputScore) -> Option<f64>| {
        r.outputs.iter().all(|o| f(o).is_some_and(|v| v >= t))
    };
    let every = |t: f64, f: fn(&OutputScore) -> Option<f64>| {
        mine.iter().filter(|r| reaches(r, t, f)).count()
    };
    let all = |t: f64| every(t, |o| o.r2);
    let (floor, floor_share) = class.floor();
    let gaps: Vec<f64> = outs
        .iter()
        .filter_map(|o| Some(o.r2_train? - o.r2?))
        .collect();
    Some(ClassSummary {
        class,
        records: mine.len(),
        outputs: outs.len(),
        narx: distribution(&outs.iter().map(|o| o.r2).collect::<Vec<_>>()),
        arx: distribution(&outs.iter().map(|o| o.arx_r2).collect::<Vec<_>>()),
        truth: distribution(&outs.iter().map(|o| o.truth_r2).collect::<Vec<_>>()),
        narx_clean: distribution(&outs.iter().map(|o| o.r2_clean).collect::<Vec<_>>()),
        arx_clean: distribution(&outs.iter().map(|o| o.arx_r2_clean).collect::<Vec<_>>()),
        records_all_099: all(0.99),
        records_all_0999: all(0.999),
        floor,
        floor_share,
        records_at_floor: all(floor),
        records_at_floor_clean: every(floor, |o| o.r2_clean),
        records_at_floor_truth: every(floor, |o| o.truth_r2),
        worse_than_arx: outs.iter().filter(|o| o.worse_than_arx()).count(),
        near_truth: outs
            .iter()
            .filter(|o| match (o.r2, o.truth_r2) {
                (Some(a), Some(t)) => a >= t - 1e-3,
                _ => false,
            })
            .count(),
        covered_090: outs
            .iter()
            .filter(|o| o.coverage.is_some_and(|c| c >= 0.9))
            .count(),
        mean_coverage: {
            let c: Vec<f64> = outs.iter().filter_map(|o| o.coverage).collect();
            (!c.is_empty()).then(|| c.iter().sum::<f64>() / c.len() as f64)
        },
        median_band_width: {
            let mut w: Vec<f64> = outs.iter().filter_map(|o| o.band_width).collect();
            w.sort_by(f64::total_cmp);
            quantile(&w, 0.5)
        },
        leaving: mine.iter().filter(|r| r.outside >= OUTSIDE_NOTED).count(),
        below_floor_leaving: mine
            .iter()
            .filter(|r| r.outside >= OUTSIDE_NOTED && !reaches(r, floor, |o| o.r2))
            .count(),
        base_alone: outs.iter().filter(|o| o.model == BaseUse::Base).count(),
        base_and_network: outs
            .iter()
            .filter(|o| o.model == BaseUse::BaseAndNetwork)
            .count(),
        misses: mine.iter().any(|r| r.fitted_without_noise()).then(|| {
            let mut m = Misses::default();
            for r in &mine {
                match Miss::of_record(r, floor) {
                    Some(Miss::NoiseCeiling) => m.noise_ceiling += 1,
                    Some(Miss::FitMissesTraining) => m.fit_misses_training += 1,
                    Some(Miss::NotDetermined) => m.not_determined += 1,
                    Some(Miss::TrainingNoise) => m.training_noise += 1,
                    None => {}
                }
            }
            m
        }),
        median_gap: median(gaps),
        median_seconds: median(mine.iter().map(|r| r.seconds).collect()).unwrap_or(0.0),
        total_seconds: mine.iter().map(|r| r.seconds).sum(),
    })
}

fn cell(v: Option<f64>) -> String {
    v.map_or("diverged".into(), |x| {
        if x.abs() >= 1e-3 || x == 0.0 {
            format!("{x:.4}")
        } else {
            format!("{x:.2e}")
        }
    })
}

impl ZooScore {
    /// Per class, the free-run test R^2 of every output for the identifier, the ARX baseline
    /// and the true plant (for [`crate::plot::zoo_figure`]).
    pub fn curves(&self) -> Vec<crate::plot::ZooClassCurves> {
        self.classes
            .iter()
            .map(|c| {
                let outs: Vec<&OutputScore> = self
                    .records
                    .iter()
                    .filter(|r| r.class == c.class)
                    .flat_map(|r| &r.outputs)
                    .collect();
                let of = |f: fn(&OutputScore) -> Option<f64>| outs.iter().map(|o| f(o)).collect();
                crate::plot::ZooClassCurves {
                    class: c.class.to_string(),
                    models: vec![
                        ("identifier".into(), of(|o| o.r2)),
                        ("ARX".into(), of(|o| o.arx_r2)),
                        ("true plant (noise ceiling)".into(), of(|o| o.truth_r2)),
                    ],
                }
            })
            .collect()
    }

    /// `results.csv`: one row per output of each record (with `--noiseless-training`, two
    /// columns more: [`NoiselessTraining`]).
    pub fn to_csv(&self) -> String {
        let again = self.records.iter().any(RecordScore::fitted_without_noise);
        let mut s = String::from("index,class,samples,sampling_period_s,output,r2_test,diverged,r2_train,arx_r2_test,arx_diverged,worse_than_arx,truth_r2_test,r2_clean,arx_r2_clean,band_coverage,band_width,model,outside_share,seconds");
        s += if again {
            ",noiseless_training_r2_train,noiseless_training_r2_clean\n"
        } else {
            "\n"
        };
        let opt = |v: Option<f64>| v.map_or(String::new(), |x| x.to_string());
        for r in &self.records {
            for o in &r.outputs {
                let _ = write!(
                    s,
                    "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    r.index,
                    r.class,
                    r.samples,
                    r.sampling_period_s,
                    o.name,
                    opt(o.r2),
                    o.diverged as u8,
                    opt(o.r2_train),
                    opt(o.arx_r2),
                    o.arx_diverged as u8,
                    o.worse_than_arx() as u8,
                    opt(o.truth_r2),
                    opt(o.r2_clean),
                    opt(o.arx_r2_clean),
                    opt(o.coverage),
                    opt(o.band_width),
                    o.model.as_str(),
                    r.outside,
                    r.seconds
                );
                if again {
                    let n = o.noiseless_training.as_ref();
                    let _ = write!(
                        s,
                        ",{},{}",
                        opt(n.and_then(|n| n.r2_train)),
                        opt(n.and_then(|n| n.r2))
                    );
                }
                s.push('\n');
            }
        }
        s
    }

    /// `report.md`: the per-class table.
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "# Plant zoo (seed {}): default identifier against a linear ARX\n\n",
            self.seed
        );
        s += "Free-run R^2 on the second half of each record (the first half trains). \
              Quantiles over the outputs of a class; a diverged free run counts as the lowest. \
              \"truth\": the true plant's noiseless output scored the same way, the ceiling \
              that the measurement noise sets.\n\n";
        s += "| class | records | outputs | R^2 min | 5 % | 25 % | median | >= 0.99 | >= 0.999 | diverged | records all >= 0.99 | ARX median | ARX >= 0.99 | ARX diverged | worse than ARX | truth >= 0.999 | within 0.001 of truth | median train-test gap | median time |\n";
        s += "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
        for c in &self.classes {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.2} s |",
                c.class,
                c.records,
                c.outputs,
                cell(c.narx.min),
                cell(c.narx.q05),
                cell(c.narx.q25),
                cell(c.narx.median),
                share(c.narx.at_least_099, c.outputs),
                share(c.narx.at_least_0999, c.outputs),
                c.narx.diverged,
                share(c.records_all_099, c.records),
                cell(c.arx.median),
                share(c.arx.at_least_099, c.outputs),
                c.arx.diverged,
                c.worse_than_arx,
                share(c.truth.at_least_0999, c.outputs),
                share(c.near_truth, c.outputs),
                c.median_gap.map_or("-".into(), |g| format!("{g:.2e}")),
                c.median_seconds
            );
        }
        s += "\nThe acceptance floors (every output of a record at the class's threshold): the records that reach it against the measurement, against the noiseless output (the model's own error), and the true plant against the measurement (the most the noise allows).\n\n| class | threshold | share asked | records | measured | noiseless | true plant (ceiling) |\n|---|---|---|---|---|---|---|\n";
        for c in &self.classes {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} |",
                c.class,
                c.floor,
                c.floor_share
                    .map_or("-".into(), |v| format!("{:.0} %", 100.0 * v)),
                c.records,
                share(c.records_at_floor, c.records),
                share(c.records_at_floor_clean, c.records),
                share(c.records_at_floor_truth, c.records),
            );
        }
        let _ = write!(
            s,
            "\nWhere the test half leaves the training region (the largest share of its samples outside it in one way: an input beyond its training range, faster than in training, or the inputs in new combinations; what `identify` warns of) on at least {:.0} % of its samples, and the records below the floor that do: a model there extrapolates.\n\n| class | records | leaving | below the floor | below the floor and leaving |\n|---|---|---|---|---|\n",
            100.0 * OUTSIDE_NOTED
        );
        for c in &self.classes {
            let below = c.records - c.records_at_floor;
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} |",
                c.class,
                c.records,
                share(c.leaving, c.records),
                below,
                share(c.below_floor_leaving, below),
            );
        }
        if self.classes.iter().any(|c| c.misses.is_some()) {
            let _ = write!(
                s,
                "\nWhy the records below the floor miss it (`--noiseless-training`: the identifier fitted again on each record's noiseless training half, scored on the noiseless test half). Per record the first that holds of its outputs below the threshold: the true plant misses too (the noise alone); fitted without noise it still misses the training half (the model family or its fit); it fits the noiseless training half, its error there at most {DETERMINED_RATIO} of the test half's, and misses the test half (the training half does not determine it); it reaches the threshold fitted without noise (the noise in the training half costs it).\n\n| class | below the floor | true plant misses too | misses the noiseless training half | training half does not determine the test half | reaches it fitted without noise |\n|---|---|---|---|---|---|\n"
            );
            for c in &self.classes {
                let Some(m) = &c.misses else {
                    continue;
                };
                let below = c.records - c.records_at_floor;
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} | {} |",
                    c.class,
                    below,
                    share(m.noise_ceiling, below),
                    share(m.fit_misses_training, below),
                    share(m.not_determined, below),
                    share(m.training_noise, below),
                );
            }
        }
        s += "\nAgainst the noiseless output (the model's own error, without the measurement noise):\n\n";
        s += "| class | outputs | R^2 5 % | median | >= 0.99 | >= 0.999 | ARX median | ARX >= 0.99 | ARX >= 0.999 |\n|---|---|---|---|---|---|---|---|---|\n";
        for c in &self.classes {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                c.class,
                c.outputs,
                cell(c.narx_clean.q05),
                cell(c.narx_clean.median),
                share(c.narx_clean.at_least_099, c.outputs),
                share(c.narx_clean.at_least_0999, c.outputs),
                cell(c.arx_clean.median),
                share(c.arx_clean.at_least_099, c.outputs),
                share(c.arx_clean.at_least_0999, c.outputs),
            );
        }
        s += "\nPrediction bands (95 %, calibrated on each training record's validation part): the share of test samples whose measurement lies inside, and the median over the outputs of the band's mean half-width in test output standard deviations.\n\n| class | outputs | mean coverage | outputs covered >= 90 % | median half-width |\n|---|---|---|---|---|\n";
        for c in &self.classes {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} |",
                c.class,
                c.outputs,
                c.mean_coverage
                    .map_or("-".into(), |v| format!("{:.1} %", 100.0 * v)),
                share(c.covered_090, c.outputs),
                c.median_band_width
                    .map_or("-".into(), |v| format!("{v:.3}")),
            );
        }
        s += "\nWhat the identifier chose per output (on the training record's validation part): the network, the grey-box model alone, or the grey-box model under a network on its residual.\n\n| class | outputs | network | grey-box | grey-box + network |\n|---|---|---|---|---|\n";
        for c in &self.classes {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} |",
                c.class,
                c.outputs,
                share(c.outputs - c.base_alone - c.base_and_network, c.outputs),
                share(c.base_alone, c.outputs),
                share(c.base_and_network, c.outputs),
            );
        }
        let total: f64 = self.classes.iter().map(|c| c.total_seconds).sum();
        let _ = writeln!(
            s,
            "\nIdentifier time over all records: {total:.1} s, each fit's wall clock (the ARX fits are not counted; records scored side by side share the threads, so each takes longer than alone: `zoo score --one-at-a-time` times a lone fit)."
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(index: usize, r2: f64, outside: f64) -> RecordScore {
        RecordScore {
            index,
            class: Class::OneDofShort,
            samples: 2000,
            sampling_period_s: 1e-3,
            outputs: vec![OutputScore {
                name: "y".into(),
                r2: Some(r2),
                diverged: false,
                r2_train: Some(r2),
                arx_r2: Some(0.5),
                arx_diverged: false,
                truth_r2: Some(0.999),
                r2_clean: Some(r2),
                arx_r2_clean: Some(0.5),
                coverage: None,
                band_width: None,
                model: BaseUse::Base,
                noiseless_training: None,
            }],
            outside,
            seconds: 1.0,
        }
    }

    /// An output below the threshold of 0.99 with the true plant's R^2 `truth` and, fitted
    /// again without noise, R^2 `train` on the training half and `test` on the test half.
    fn missing(truth: f64, train: Option<f64>, test: Option<f64>) -> OutputScore {
        let mut o = record(0, 0.95, 0.0).outputs.remove(0);
        o.truth_r2 = Some(truth);
        o.noiseless_training = Some(NoiselessTraining {
            r2_train: train,
            r2: test,
        });
        o
    }

    #[test]
    fn a_miss_is_told_by_the_noiseless_fit_and_a_record_by_its_first_cause() {
        let t = 0.99;
        // (true plant, noiseless fit on the training half, on the test half) -> cause
        let cases = [
            // the true plant misses: the noise alone, whatever the fit without it does
            ((0.98, Some(1.0), Some(1.0)), Miss::NoiseCeiling),
            // fitted without noise it reaches the threshold
            ((0.999, Some(0.9999), Some(0.995)), Miss::TrainingNoise),
            // it fits the training half ten times closer than the test half, misses the test
            ((0.999, Some(0.9995), Some(0.95)), Miss::NotDetermined),
            // ... or not (just above a tenth), or its fit failed or diverged
            ((0.999, Some(0.99499), Some(0.95)), Miss::FitMissesTraining),
            ((0.999, None, None), Miss::FitMissesTraining),
        ];
        for ((truth, train, test), cause) in cases {
            let o = missing(truth, train, test);
            assert_eq!(
                Miss::of_output(&o, t),
                Some(cause),
                "{truth} {train:?} {test:?}"
            );
        }
        let of = |o: &OutputScore| Miss::of_output(o, t);
        // at the threshold, or not fitted again: no cause
        let mut at = missing(0.999, None, None);
        at.r2 = Some(0.995);
        assert_eq!(of(&at), None);
        let mut unasked = missing(0.98, None, None);
        unasked.noiseless_training = None;
        assert_eq!(of(&unasked), None);
        // a record: the first cause in the order of [`Miss`]; the report counts records
        let mut r = record(1, 0.95, 0.0);
        r.outputs = vec![
            missing(0.999, Some(0.9999), Some(0.995)),
            missing(0.999, Some(0.9995), Some(0.95)),
        ];
        assert_eq!(Miss::of_record(&r, t), Some(Miss::NotDetermined));
        let mut noise = record(2, 0.95, 0.0);
        noise.outputs = vec![missing(0.999, Some(0.9999), Some(0.995))];
        let mut reached = record(3, 0.995, 0.0);
        reached.outputs[0].noiseless_training = Some(NoiselessTraining {
            r2_train: Some(1.0),
            r2: Some(1.0),
        });
        let score = ZooScore::of(1, vec![r, noise, reached]);
        let c = &score.classes[0];
        assert_eq!(
            c.misses,
            Some(Misses {
                noise_ceiling: 0,
                fit_misses_training: 0,
                not_determined: 1,
                training_noise: 1,
            })
        );
        let report = score.to_markdown();
        assert!(
            report.contains("| 1dof-short | 2 | 0 (0 %) | 0 (0 %) | 1 (50 %) | 1 (50 %) |"),
            "{report}"
        );
        let csv = score.to_csv();
        assert!(csv
            .lines()
            .next()
            .unwrap()
            .ends_with(",seconds,noiseless_training_r2_train,noiseless_training_r2_clean"));
        assert!(
            csv.lines().nth(1).unwrap().ends_with(",0.9999,0.995"),
            "{csv}"
        );
        // without the option: neither the table nor the columns
        let plain = ZooScore::of(1, vec![record(4, 0.95, 0.0)]);
        assert!(plain.classes[0].misses.is_none());
        assert!(!plain.to_markdown().contains("fitted without noise"));
        assert!(plain.to_csv().lines().next().unwrap().ends_with(",seconds"));
    }

    #[test]
    fn records_leaving_the_training_region_are_counted_below_the_floor_and_not() {
        // at the floor inside, at the floor leaving, below it leaving, below it just inside
        let records = [
            record(0, 0.995, 0.0),
            record(1, 0.995, 0.3),
            record(2, 0.95, OUTSIDE_NOTED),
            record(3, 0.95, 0.099),
        ];
        let c = summarise(Class::OneDofShort, &records).unwrap();
        assert_eq!(
            (c.records_at_floor, c.leaving, c.below_floor_leaving),
            (2, 2, 1)
        );
        let report = ZooScore::of(1, records.to_vec()).to_markdown();
        assert!(
            report.contains("| 1dof-short | 4 | 2 (50 %) | 2 | 1 (50 %) |"),
            "{report}"
        );
    }
}
