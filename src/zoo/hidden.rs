//! # The model-improvement loop scored over the zoo: hide each effect in turn
//!
//! For every member the plant's own effects are known. The complete model (a grey-box fit with
//! every effect of the plant) is fitted and diagnosed: anything named there is a false alarm.
//! Then each effect is hidden in turn: the model of the other effects is fitted, and
//! [`crate::improve::improve`] runs from it, as a user runs `hystbench improve`. A case records
//! what the first diagnosis named, the error fall that the refit with the hidden effect gives
//! (the complete model's error against the hidden one's: the cases where it is 3x or more are
//! the ones the diagnosis must name), and the error after the loop against the noise level (the
//! member's plant re-simulated without noise).
//!
//! Every fit and score uses the record's first [`LoopOptions::max_samples`] samples (the loop
//! fits many models per member; the whole record is the user's, the bench's budget is not).

use super::{median, noiseless, share, Class, IndexEntry, ZooError, ZooIndex};
use crate::data::{read_csv, IoRecord};
use crate::diagnose::diagnose_model_with;
use crate::effect::EffectName;
use crate::graybox::GreyBoxConfig;
use crate::improve::{effect_list, improve_with_memo, ImproveOptions, RecordMemo};
use crate::metrics::rmse;
use crate::model::{plant_effects, predict_finite, Model};
use rayon::prelude::*;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

/// A refit that cuts the error by this factor or more is one the diagnosis must name.
pub const DECISIVE: f64 = 3.0;

/// After `improve`, an error within this factor of the noise level counts as recovered.
pub const NEAR_NOISE: f64 = 2.0;

/// Knobs of the zoo loop.
#[derive(Debug, Clone)]
pub struct LoopOptions {
    /// Fit and score on the record's first samples only.
    pub max_samples: usize,
    /// The loop as `hystbench improve` runs it.
    pub improve: ImproveOptions,
}

impl Default for LoopOptions {
    fn default() -> Self {
        LoopOptions {
            max_samples: 20_000,
            improve: ImproveOptions::default(),
        }
    }
}

/// One effect hidden from one member's model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HiddenCase {
    pub effect: EffectName,
    /// RMS error (mean over outputs) of the model without the effect.
    pub rmse_hidden: f64,
    /// What the diagnosis of that model named, and the candidates `improve` refitted at its
    /// first step (the diagnosis' best first).
    pub named: Option<EffectName>,
    pub candidates: Vec<EffectName>,
    /// The error fall of the refit with the hidden effect: `rmse_hidden` / the complete
    /// model's error.
    pub refit_fall: f64,
    /// The error and the effects after `improve`.
    pub rmse_improved: f64,
    pub improved_effects: Vec<EffectName>,
}

impl HiddenCase {
    /// A case the diagnosis must name: the refit with the hidden effect cuts the error
    /// [`DECISIVE`]x or more.
    pub fn decisive(&self) -> bool {
        self.refit_fall >= DECISIVE
    }
    /// Named right.
    pub fn right(&self) -> bool {
        self.named == Some(self.effect)
    }
    /// Named, but another effect.
    pub fn wrong(&self) -> bool {
        self.named.is_some_and(|n| n != self.effect)
    }
    /// After `improve`, within [`NEAR_NOISE`] times the member's noise level `noise_rms`.
    pub fn near_noise(&self, noise_rms: f64) -> bool {
        self.rmse_improved <= NEAR_NOISE * noise_rms
    }
}

/// One member of the zoo.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MemberLoop {
    pub index: usize,
    pub class: Class,
    /// Samples used (the record's first ones).
    pub samples: usize,
    /// The plant's effects (the complete model's).
    pub effects: Vec<EffectName>,
    /// RMS of the measurement noise, mean over outputs.
    pub noise_rms: f64,
    /// The complete model's RMS error (`None`: it could not be fitted; see `skipped`).
    pub rmse_complete: Option<f64>,
    /// What the diagnosis named on the complete model (a false alarm).
    pub false_alarm: Option<EffectName>,
    pub hidden: Vec<HiddenCase>,
    /// Why the member or some of its cases were not run.
    pub skipped: Vec<String>,
    pub seconds: f64,
}

/// Per hidden effect, over the zoo.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EffectSummary {
    pub effect: EffectName,
    pub cases: usize,
    /// Cases whose refit cuts the error [`DECISIVE`]x or more, and of those: named right,
    /// named wrong, not named.
    pub decisive: usize,
    pub decisive_right: usize,
    pub decisive_wrong: usize,
    pub decisive_missed: usize,
    /// Over every case: named right, named wrong.
    pub right: usize,
    pub wrong: usize,
    /// Median error fall of the refit, and of the loop (`rmse_hidden` / `rmse_improved`).
    pub median_refit_fall: Option<f64>,
    pub median_loop_fall: Option<f64>,
    /// Cases whose error after the loop is within [`NEAR_NOISE`]x of the noise level.
    pub near_noise: usize,
}

/// The loop over a whole zoo.
#[derive(Debug, Clone, Serialize)]
pub struct LoopScore {
    pub seed: u64,
    pub max_samples: usize,
    pub members: Vec<MemberLoop>,
    pub effects: Vec<EffectSummary>,
    /// Complete models fitted, and those on which something was named.
    pub complete: usize,
    pub false_alarms: usize,
    /// Complete models within [`NEAR_NOISE`]x of the noise level (the fitted family holds
    /// the plant).
    pub complete_near_noise: usize,
    pub seconds: f64,
}

/// Mean over outputs of a model's RMS error on `io`, and its prediction.
fn mean_rmse(model: &dyn Model, io: &IoRecord) -> Result<(f64, Vec<Vec<f64>>), String> {
    let pred = predict_finite(model, io).map_err(|e| e.to_string())?;
    let e = mean_over_outputs(io, &pred);
    Ok((e, pred))
}

/// Mean over the outputs of `io` of the RMS difference from `other` (one series per output,
/// over their common length).
fn mean_over_outputs(io: &IoRecord, other: &[Vec<f64>]) -> f64 {
    io.outputs
        .iter()
        .zip(other)
        .map(|(y, p)| rmse(&y.values, p))
        .sum::<f64>()
        / io.outputs.len().max(1) as f64
}

/// The loop on one member.
fn member_loop(dir: &Path, e: &IndexEntry, opts: &LoopOptions) -> Result<MemberLoop, ZooError> {
    let t0 = Instant::now();
    let path = dir.join(&e.record);
    let whole = IoRecord::from_record(&read_csv(&path)?, None, None, true)?;
    let n = whole.len().min(opts.max_samples);
    let io = whole.slice(0..n);
    let plant_path = dir.join(&e.plant);
    let plant = crate::plant::Plant::from_file(&plant_path).map_err(|source| ZooError::Plant {
        index: e.index,
        source,
    })?;
    let effects = plant_effects(&plant);
    let clean = noiseless(dir, e)?;
    let noise_rms = mean_over_outputs(&io, &clean);
    let mut out = MemberLoop {
        index: e.index,
        class: e.class,
        samples: n,
        effects: effects.clone(),
        noise_rms,
        rmse_complete: None,
        false_alarm: None,
        hidden: Vec::new(),
        skipped: Vec::new(),
        seconds: 0.0,
    };
    let config_of = |list: &[EffectName]| GreyBoxConfig::from_effect_list(&effect_list(list));
    // one memo for the member: the cases' refits and refit tests meet the complete model and
    // each other's structures again and again (the same bits as fitting them anew; a
    // structure fitted on other samples, `improve`'s training part say, is another key)
    let memo = RecordMemo::default();
    // the complete model
    let complete = config_of(&effects)
        .map_err(|e| e.to_string())
        .and_then(|c| {
            let m = memo.fits.fit(&c, &io).map_err(|e| e.to_string())?;
            let (r, p) = mean_rmse(&m, &io)?;
            Ok((c, r, p))
        });
    let rmse_complete = match complete {
        Ok((c, r, pred)) => {
            let d = diagnose_model_with(&io, &pred, &c, &opts.improve.diagnose, &memo.fits);
            out.false_alarm = d.missing;
            memo.diagnoses.insert(c, d);
            r
        }
        Err(why) => {
            out.skipped
                .push(format!("complete model ({}): {why}", effect_list(&effects)));
            out.seconds = t0.elapsed().as_secs_f64();
            return Ok(out);
        }
    };
    out.rmse_complete = Some(rmse_complete);
    for &hidden in &effects {
        let rest: Vec<EffectName> = effects.iter().copied().filter(|&x| x != hidden).collect();
        let case = config_of(&rest).map_err(|e| e.to_string()).and_then(|c| {
            let m = memo.fits.fit(&c, &io).map_err(|e| e.to_string())?;
            let (rmse_hidden, _) = mean_rmse(&m, &io)?;
            let ladder = improve_with_memo(Box::new(m), c, &io, &opts.improve, &memo, &mut |_| {})
                .map_err(|e| e.to_string())?;
            let first = &ladder.rungs[0];
            let named = first.missing;
            let candidates = first.tried.iter().map(|(e, _)| *e).collect();
            let best = ladder
                .rungs
                .iter()
                .min_by(|a, b| a.rmse.total_cmp(&b.rmse))
                .unwrap_or(first);
            Ok(HiddenCase {
                effect: hidden,
                rmse_hidden,
                named,
                candidates,
                refit_fall: rmse_hidden / rmse_complete,
                rmse_improved: best.rmse,
                improved_effects: best.effects.clone(),
            })
        });
        match case {
            Ok(c) => out.hidden.push(c),
            Err(why) => out
                .skipped
                .push(format!("{hidden} hidden ({}): {why}", effect_list(&rest))),
        }
    }
    out.seconds = t0.elapsed().as_secs_f64();
    Ok(out)
}

fn summarise(effect: EffectName, members: &[MemberLoop]) -> Option<EffectSummary> {
    // each case with its member's noise level
    let cases: Vec<(f64, &HiddenCase)> = members
        .iter()
        .flat_map(|m| m.hidden.iter().map(move |c| (m.noise_rms, c)))
        .filter(|(_, c)| c.effect == effect)
        .collect();
    if cases.is_empty() {
        return None;
    }
    let count = |f: &dyn Fn(&HiddenCase) -> bool| cases.iter().filter(|(_, c)| f(c)).count();
    Some(EffectSummary {
        effect,
        cases: cases.len(),
        decisive: count(&|c| c.decisive()),
        decisive_right: count(&|c| c.decisive() && c.right()),
        decisive_wrong: count(&|c| c.decisive() && c.wrong()),
        decisive_missed: count(&|c| c.decisive() && c.named.is_none()),
        right: count(&|c| c.right()),
        wrong: count(&|c| c.wrong()),
        median_refit_fall: median(cases.iter().map(|(_, c)| c.refit_fall).collect()),
        median_loop_fall: median(
            cases
                .iter()
                .map(|(_, c)| c.rmse_hidden / c.rmse_improved)
                .collect(),
        ),
        near_noise: cases
            .iter()
            .filter(|(noise, c)| c.near_noise(*noise))
            .count(),
    })
}

/// Run the loop on every member of the zoo in `dir` (members in parallel; the result does not
/// depend on the thread count). `progress` sees each member as it is done.
pub fn score_loop(
    dir: &Path,
    opts: &LoopOptions,
    progress: &(dyn Fn(&MemberLoop) + Sync),
) -> Result<LoopScore, ZooError> {
    let t0 = Instant::now();
    let index = ZooIndex::read(dir)?;
    let lock = Mutex::new(());
    let members = index
        .members
        .par_iter()
        .map(|e| {
            let m = member_loop(dir, e, opts)?;
            let _guard = lock.lock();
            progress(&m);
            Ok(m)
        })
        .collect::<Result<Vec<MemberLoop>, ZooError>>()?;
    let mut names: Vec<EffectName> = members.iter().flat_map(|m| m.effects.clone()).collect();
    names.sort();
    names.dedup();
    let effects = names
        .into_iter()
        .filter_map(|e| summarise(e, &members))
        .collect();
    let fitted: Vec<&MemberLoop> = members
        .iter()
        .filter(|m| m.rmse_complete.is_some())
        .collect();
    Ok(LoopScore {
        seed: index.seed,
        max_samples: opts.max_samples,
        complete: fitted.len(),
        false_alarms: fitted.iter().filter(|m| m.false_alarm.is_some()).count(),
        complete_near_noise: fitted
            .iter()
            .filter(|m| {
                m.rmse_complete
                    .is_some_and(|r| r <= NEAR_NOISE * m.noise_rms)
            })
            .count(),
        effects,
        members,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

fn opt(v: Option<f64>) -> String {
    v.map_or("-".into(), |x| format!("{x:.2}"))
}

impl LoopScore {
    /// One row per hidden case (and one per member whose complete model was not fitted).
    pub fn to_csv(&self) -> String {
        let mut s = String::from("index,class,samples,effects,noise_rms,rmse_complete,false_alarm,hidden,rmse_hidden,named,candidates,refit_fall,rmse_improved,improved_effects\n");
        let list = |v: &[EffectName]| effect_list(v).replace(',', "+");
        for m in &self.members {
            let head = format!(
                "{},{},{},{},{:e},{},{}",
                m.index,
                m.class,
                m.samples,
                list(&m.effects),
                m.noise_rms,
                m.rmse_complete.map_or(String::new(), |r| format!("{r:e}")),
                m.false_alarm.map_or("", |e| e.as_str())
            );
            if m.hidden.is_empty() {
                let _ = writeln!(s, "{head},,,,,,,");
            }
            for c in &m.hidden {
                let _ = writeln!(
                    s,
                    "{head},{},{:e},{},{},{:e},{:e},{}",
                    c.effect,
                    c.rmse_hidden,
                    c.named.map_or("", |e| e.as_str()),
                    list(&c.candidates),
                    c.refit_fall,
                    c.rmse_improved,
                    list(&c.improved_effects)
                );
            }
        }
        s
    }

    /// The report.
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "# The improvement loop over the zoo (seed {})\n\nEach member's complete model (the grey-box fit with every effect of its plant) is diagnosed: a named effect is a false alarm. Then each effect is hidden in turn: the model of the others is fitted and `improve` runs from it. A case is decisive when the refit with the hidden effect cuts the RMS error {DECISIVE}x or more. First {} samples of each record; {:.1} s.\n\n",
            self.seed, self.max_samples, self.seconds
        );
        s += "| hidden effect | cases | decisive | named right (decisive) | named wrong (decisive) | not named (decisive) | named right (all) | named wrong (all) | median refit fall | median loop fall | loop within 2x of noise |\n|---|---|---|---|---|---|---|---|---|---|---|\n";
        let (mut d, mut dr, mut n, mut nn) = (0, 0, 0, 0);
        for e in &self.effects {
            d += e.decisive;
            dr += e.decisive_right;
            n += e.cases;
            nn += e.near_noise;
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                e.effect,
                e.cases,
                e.decisive,
                share(e.decisive_right, e.decisive),
                share(e.decisive_wrong, e.decisive),
                share(e.decisive_missed, e.decisive),
                share(e.right, e.cases),
                share(e.wrong, e.cases),
                opt(e.median_refit_fall),
                opt(e.median_loop_fall),
                share(e.near_noise, e.cases)
            );
        }
        let _ = writeln!(
            s,
            "\nOver every hidden effect: named right in {} of the decisive cases; after `improve` within {NEAR_NOISE}x of the noise in {} of all cases.\n\nComplete models: {} fitted; a false alarm (an effect named) on {}; within {NEAR_NOISE}x of the noise on {} (the fitted family holds the plant).",
            share(dr, d),
            share(nn, n),
            self.complete,
            share(self.false_alarms, self.complete),
            share(self.complete_near_noise, self.complete)
        );
        s += "\n\n| class | members | complete fitted | false alarms | decisive cases named right | loop within 2x of noise | time (s, members summed) |\n|---|---|---|---|---|---|---|\n";
        for c in Class::ALL {
            let ms: Vec<&MemberLoop> = self.members.iter().filter(|m| m.class == c).collect();
            if ms.is_empty() {
                continue;
            }
            // each case with its member's noise level
            let cases: Vec<(f64, &HiddenCase)> = ms
                .iter()
                .flat_map(|m| m.hidden.iter().map(move |h| (m.noise_rms, h)))
                .collect();
            let dec = cases.iter().filter(|(_, h)| h.decisive()).count();
            let right = cases
                .iter()
                .filter(|(_, h)| h.decisive() && h.right())
                .count();
            let near = cases.iter().filter(|(n, h)| h.near_noise(*n)).count();
            let fitted = ms.iter().filter(|m| m.rmse_complete.is_some()).count();
            let alarms = ms.iter().filter(|m| m.false_alarm.is_some()).count();
            let seconds: f64 = ms.iter().map(|m| m.seconds).sum();
            let _ = writeln!(
                s,
                "| {c} | {} | {fitted} | {} | {} | {} | {seconds:.0} |",
                ms.len(),
                share(alarms, fitted),
                share(right, dec),
                share(near, cases.len())
            );
        }
        let skipped: Vec<String> = self
            .members
            .iter()
            .flat_map(|m| {
                m.skipped
                    .iter()
                    .map(move |w| format!("- member {}: {w}", m.index))
            })
            .collect();
        if !skipped.is_empty() {
            s += "\nNot run:\n\n";
            s += &skipped.join("\n");
            s += "\n";
        }
        s
    }
}
