//! # Diagnosis: which physical effect is the model missing?
//!
//! Given a record and a model's prediction of it, every effect of the library offers a bank of
//! basis signals ([`crate::effect::basis`]). For each output, the residual e = y - y_hat is
//! regressed on each bank on top of a baseline (the prediction and a constant, so that a gain or
//! offset error is not mistaken for physics), with two-fold contiguous cross-validation: the bank
//! that explains most of the residual out of sample names the missing effect. The residual is
//! also tested for whiteness (auto-, cross- and higher-order correlations), so that "nothing
//! significant is missing" is a possible answer.
//!
//! The banks of the effects the model already has join the baseline when a missing effect is
//! scored: what a missing effect's bank explains is what the present effects, even refitted,
//! could not (a misfit of a present effect is not taken for a missing one).
//!
//! Decision rule: the top effect the model lacks is called missing when the residual is not
//! white and its bank explains at least [`DiagnoseOptions::threshold`] of the residual out of
//! sample.
//!
//! ## References
//! - S. A. Billings, W. S. F. Voon, Int. J. Control 44(1):235-244, 1986.
//! - S. A. Billings, S. Chen, M. J. Korenberg, Int. J. Control 49(6):2157-2189, 1989.
//! - PHYSICS.md section 6 (diagnostic signatures of missing effects).

pub mod compare;
pub mod refit;
pub mod regression;
pub mod residual;
pub mod whiteness;

use crate::data::IoRecord;
use crate::effect::basis::{BasisContext, EvidenceContext, Signal};
use crate::effect::{registry, EffectName};
use crate::graybox::FitMemo;
pub use crate::metrics::holds;
use crate::metrics::rms;
pub use refit::{refit_check, RefitCheck, RefitOptions};
use serde::Serialize;
use std::ops::Range;
pub use whiteness::{whiteness, Whiteness};

/// A smaller bank is named instead of the top one when the top bank explains less than this
/// share of what is left after the smaller one (out of sample).
pub const PARSIMONY: f64 = 0.05;

/// Knobs of the decision rule.
#[derive(Debug, Clone, Copy)]
pub struct DiagnoseOptions {
    /// Share of the residual a bank must explain out of sample to call its effect missing.
    pub threshold: f64,
    /// Lags of the correlation tests.
    pub max_lag: usize,
    /// The refit test ([`refit`]) of a grey-box model's candidates (`None`: the basis banks
    /// alone decide).
    pub refit: Option<RefitOptions>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            threshold: 0.3,
            max_lag: 30,
            refit: Some(RefitOptions::default()),
        }
    }
}

/// How much of one output's residual an effect's bank explains.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EffectScore {
    pub effect: EffectName,
    /// Out-of-sample share of the residual explained (on top of the baseline).
    pub explained: f64,
    /// Held-out RMS error now (after the baseline) and with the effect's bank.
    pub rms_now: f64,
    pub rms_after: f64,
    /// The model already has this effect.
    pub in_model: bool,
}

/// Diagnosis of one output.
#[derive(Debug, Clone, Serialize)]
pub struct OutputDiagnosis {
    pub output: String,
    pub rms: f64,
    pub scores: Vec<EffectScore>,
    pub whiteness: Whiteness,
    pub missing: Option<EffectName>,
    /// Every effect the model lacks that passes the test on this output, best first.
    pub candidates: Vec<EffectName>,
    pub messages: Vec<String>,
    /// Where the residual concentrates (extremes, slow trend, reversals), when it is not white.
    pub residual: residual::ResidualShape,
}

/// One line of the ranking over all outputs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Rank {
    pub effect: EffectName,
    /// Pooled over outputs: 1 - sum SSE(with bank) / sum SSE(baseline).
    pub explained: f64,
    pub rms_now: f64,
    pub rms_after: f64,
}

/// The whole diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Effects the model lacks, most explanatory first.
    pub ranking: Vec<Rank>,
    /// The effect to add, or `None` when nothing significant is missing.
    pub missing: Option<EffectName>,
    /// Every effect that passes the test on some output, best first (`missing` is the first).
    /// Regression on basis banks is a linear proxy: when two effects explain about as much, only
    /// a refit with each tells which one the record wants (`hystbench improve` does that).
    pub candidates: Vec<EffectName>,
    pub outputs: Vec<OutputDiagnosis>,
    /// The refit test of the candidates, when the model's structure could be refitted: then
    /// it decides `missing` and `candidates`.
    pub refit: Option<RefitCheck>,
    /// What to do, in words.
    pub summary: Vec<String>,
}

/// Unit of a column from its name suffix (`displacement_um` -> `um`), or "".
pub fn unit_of(name: &str) -> String {
    match name.rsplit_once('_') {
        Some((_, u))
            if !u.is_empty() && u.len() <= 6 && u.chars().all(|c| c.is_ascii_alphanumeric()) =>
        {
            u.to_string()
        }
        _ => String::new(),
    }
}

/// Diagnose `predictions` (one per output of `rec`) of a model that has `model_effects`.
pub fn diagnose(
    rec: &IoRecord,
    predictions: &[Vec<f64>],
    model_effects: &[EffectName],
    opts: &DiagnoseOptions,
) -> Diagnosis {
    let outputs: Vec<OutputDiagnosis> = (0..rec.outputs.len().min(predictions.len()))
        .map(|o| diagnose_output(rec, o, &predictions[o], model_effects, opts))
        .collect();
    let ranking = pooled_ranking(&outputs, model_effects);
    // the missing effect overall: the one called missing on the outputs where it explains most
    let missing = ranking
        .iter()
        .map(|r| r.effect)
        .find(|e| outputs.iter().any(|od| od.missing == Some(*e)));
    let mut candidates: Vec<EffectName> = ranking
        .iter()
        .map(|r| r.effect)
        .filter(|e| outputs.iter().any(|od| od.candidates.contains(e)))
        .collect();
    if let Some(m) = missing {
        // the named effect first, as on each output
        candidates.retain(|c| *c != m);
        candidates.insert(0, m);
    }
    let summary = summary(&ranking, missing, &candidates, &outputs, model_effects);
    Diagnosis {
        ranking,
        missing,
        candidates,
        outputs,
        refit: None,
        summary,
    }
}

/// The diagnosis `hystbench diagnose` makes: [`diagnose_model`] where the model's structure can
/// be refitted (`config`: a grey-box model's or a plant's) and the refit test is on, else
/// [`diagnose`] on the basis banks alone. (The command itself runs the two halves,
/// [`diagnose`] and [`with_refit`], to drop the prediction between them.)
pub fn diagnose_any(
    rec: &IoRecord,
    predictions: &[Vec<f64>],
    effects: &[EffectName],
    config: Option<&crate::graybox::GreyBoxConfig>,
    opts: &DiagnoseOptions,
) -> Diagnosis {
    match config {
        Some(c) if opts.refit.is_some() => diagnose_model(rec, predictions, c, opts),
        _ => diagnose(rec, predictions, effects, opts),
    }
}

/// Diagnose the prediction of a grey-box model whose structure `config` reproduces: the banks
/// rank the effects it lacks, and the refit test ([`refit`]) of each decides what is missing
/// (when `opts.refit` is set and the structure can be refitted on the record's first part).
pub fn diagnose_model(
    rec: &IoRecord,
    predictions: &[Vec<f64>],
    config: &crate::graybox::GreyBoxConfig,
    opts: &DiagnoseOptions,
) -> Diagnosis {
    diagnose_model_with(rec, predictions, config, opts, &FitMemo::new())
}

/// [`diagnose_model`] with the fits already made on `rec` (the refit test takes them, and
/// keeps its own there).
pub fn diagnose_model_with(
    rec: &IoRecord,
    predictions: &[Vec<f64>],
    config: &crate::graybox::GreyBoxConfig,
    opts: &DiagnoseOptions,
    memo: &FitMemo,
) -> Diagnosis {
    let d = diagnose(rec, predictions, &config.effects(), opts);
    match &opts.refit {
        Some(r) => with_refit(
            d,
            rec,
            &refit::model_rms(rec, predictions, r),
            config,
            opts,
            memo,
        ),
        None => d,
    }
}

/// The refit test ([`refit`]) of `d`'s ranked candidates (`d`: [`diagnose`] of a prediction of
/// the grey-box structure `config` on `rec`; `rms_model`: that prediction's held-out RMS error
/// per output, [`refit::model_rms`]); it decides `missing` and `candidates`. The prediction is
/// not needed any more: on a long record its caller can drop it before the refits.
pub fn with_refit(
    mut d: Diagnosis,
    rec: &IoRecord,
    rms_model: &[f64],
    config: &crate::graybox::GreyBoxConfig,
    opts: &DiagnoseOptions,
    memo: &FitMemo,
) -> Diagnosis {
    let Some(ropts) = opts.refit else {
        return d;
    };
    let effects = config.effects();
    // every ranked effect, but those whose direct signature the banks do not see
    let tested: Vec<EffectName> = d
        .ranking
        .iter()
        .filter(|r| {
            registry::effect(r.effect)
                .and_then(|e| e.refit_evidence())
                .is_none_or(|min| r.explained >= min)
        })
        .map(|r| r.effect)
        .collect();
    let Some(check) = refit_check(config, rec, rms_model, &tested, &ropts, memo) else {
        return d;
    };
    let named = check.named();
    d.missing = named.first().copied();
    d.candidates = named.clone();
    for od in &mut d.outputs {
        // the effects that pass on this output, the largest fall first
        let mut passing: Vec<(EffectName, f64)> = check
            .effects
            .iter()
            .filter_map(|e| {
                let r = e.outputs.iter().find(|r| r.output == od.output)?;
                r.passes.then_some((e.effect, r.fall))
            })
            .collect();
        passing.sort_by(|a, b| b.1.total_cmp(&a.1));
        od.missing = passing.first().map(|(e, _)| *e);
        od.candidates = named
            .iter()
            .copied()
            .filter(|e| passing.iter().any(|(p, _)| p == e))
            .collect();
    }
    d.summary = refit_summary(&check, &d, &effects);
    d.refit = Some(check);
    d
}

/// The commands that add `m` to a model with `model_effects`.
fn add_it(model_effects: &[EffectName], m: EffectName) -> String {
    let with: Vec<&str> = model_effects
        .iter()
        .chain(std::iter::once(&m))
        .map(|e| e.as_str())
        .collect();
    let narx = registry::effect(m).is_some_and(|e| !e.feature_kinds().is_empty());
    format!(
        "add it: hystbench fit --effects {} (grey-box){}; hystbench improve does the loop",
        with.join(","),
        if narx {
            format!(", or hystbench identify --features {m} (NARX)")
        } else {
            String::new()
        }
    )
}

/// What to do, in words, from the refit test.
fn refit_summary(check: &RefitCheck, d: &Diagnosis, model_effects: &[EffectName]) -> Vec<String> {
    let mut s = vec![format!(
        "refit test: `{}` refitted without samples {}..{} with and without each effect, both run free through them; an effect is named when it cuts the held-out RMS error {:.1}x or more with a sign-flip p-value <= {:.2e} (a 5 % false-alarm rate over all tests), and beats the model at hand there (`model` below) by as much",
        check.base, check.held_out.start, check.held_out.end, check.min_fall, check.level
    )];
    for e in &check.effects {
        let line = match &e.not_fitted {
            Some(why) => format!("  {}: not refitted: {why}", e.effect),
            None => {
                let outs: Vec<String> = e
                    .outputs
                    .iter()
                    .map(|r| {
                        format!(
                            "{} {:.4} -> {:.4} ({:.2}x, p = {:.2e}; model {:.4})",
                            r.output, r.rms_without, r.rms_with, r.fall, r.p_value, r.rms_model
                        )
                    })
                    .collect();
                format!(
                    "  {}{}: {}",
                    e.effect,
                    if e.significant { " (named)" } else { "" },
                    outs.join("; ")
                )
            }
        };
        s.push(line);
    }
    match d.missing {
        Some(m) => {
            if d.candidates.len() > 1 {
                let others: Vec<&str> = d.candidates[1..].iter().map(|e| e.as_str()).collect();
                s.push(format!(
                    "{m} cuts the held-out error most; {} also pass{} (`hystbench improve` adds them one at a time)",
                    others.join(", "),
                    if others.len() == 1 { "es" } else { "" }
                ));
            }
            s.push(add_it(model_effects, m));
        }
        None => {
            let white = d.outputs.iter().all(|o| o.whiteness.white);
            s.push(if white {
                "nothing significant is missing: no effect of the library, refitted, cuts the held-out error significantly, and the residual is white".to_string()
            } else {
                "nothing significant is missing from the library's effects: none of them, refitted, cuts the held-out error significantly; the residual is not white, so what is left is noise, a misfit of the effects the model has, or an effect the library lacks".to_string()
            });
            s.extend(where_left(&d.outputs));
        }
    }
    s
}

/// Where each output's residual concentrates, when it is not white (what is left when no
/// effect is named).
fn where_left(outputs: &[OutputDiagnosis]) -> Vec<String> {
    outputs
        .iter()
        .filter(|o| !o.whiteness.white)
        .map(|o| format!("{}: {}", o.output, o.residual.message))
        .collect()
}

/// The banks of one output's diagnosis, computed a block of rows at a time: each effect's
/// signals' place among the columns of the folds' cross products ([`regression::FoldGrams`],
/// column 0 the prediction).
struct Banks {
    /// Per effect with a bank (registry order): its name and its columns.
    columns: Vec<(EffectName, Range<usize>)>,
    grams: regression::FoldGrams,
}

impl Banks {
    /// The banks of every effect for the residual `e` of the prediction in `ctx` (none for a
    /// record without inputs, nor a bank of no signal): one pass over the record.
    fn new(e: &[f64], ctx: &BasisContext) -> Banks {
        let mut signals = vec![Signal::samples(ctx.prediction)];
        let mut columns = Vec::new();
        if !ctx.inputs.is_empty() {
            for effect in registry::effects() {
                if let Some(b) = effect.basis(ctx).filter(|b| !b.is_empty()) {
                    columns.push((b.effect, signals.len()..signals.len() + b.len()));
                    signals.extend(b.signals);
                }
            }
        }
        Banks {
            grams: regression::FoldGrams::new(e, &mut signals),
            columns,
        }
    }

    /// The columns of `effect`'s bank, if it has one.
    fn of(&self, effect: EffectName) -> Option<Range<usize>> {
        self.columns
            .iter()
            .find(|(n, _)| *n == effect)
            .map(|(_, r)| r.clone())
    }

    /// Number of signals in `effect`'s bank.
    fn size(&self, effect: EffectName) -> Option<usize> {
        self.of(effect).map(|c| c.len())
    }
}

/// How much of the residual each bank explains out of sample, best first. A present effect
/// is scored alone (how much of the residual is its misfit); a missing one on top of the
/// present ones (`baseline`: the prediction and the banks of the effects the model has), or of
/// the prediction alone when the present banks extrapolate badly out of sample.
fn score_banks(
    banks: &Banks,
    baseline: &[usize],
    model_effects: &[EffectName],
) -> Vec<EffectScore> {
    let mut scores = Vec::new();
    for (name, cols) in &banks.columns {
        let in_model = model_effects.contains(name);
        let cols: Vec<usize> = cols.clone().collect();
        let minimal: &[usize] = &[0];
        let bases: Vec<&[usize]> = if in_model {
            vec![minimal]
        } else {
            vec![baseline, minimal]
        };
        if let Some(x) = banks.grams.explained(&bases, &cols) {
            scores.push(EffectScore {
                effect: *name,
                explained: x.fraction,
                rms_now: x.rms_baseline,
                rms_after: x.rms_with_bank,
                in_model,
            });
        }
    }
    scores.sort_by(|a, b| b.explained.total_cmp(&a.explained));
    scores
}

/// Parsimony: a smaller bank that leaves the top bank almost nothing to add (nested
/// out-of-sample test) names the simpler effect (e.g. a dashpot rather than a mode when the
/// model is a static gain, whose prediction's lags contain the input's rate). Returns the
/// simpler effect and what the top bank adds on top of it.
fn simpler_effect(
    m: EffectName,
    scores: &[EffectScore],
    banks: &Banks,
    baseline: &[usize],
    threshold: f64,
) -> Option<(EffectName, f64)> {
    let top_size = banks.size(m)?;
    let mut cands: Vec<&EffectScore> = scores
        .iter()
        .filter(|s| !s.in_model && s.effect != m && s.explained >= threshold)
        .filter(|s| banks.size(s.effect).is_some_and(|n| n < top_size))
        .collect();
    cands.sort_by_key(|s| banks.size(s.effect).unwrap_or(usize::MAX));
    let top_cols: Vec<usize> = banks.of(m)?.collect();
    for c in cands {
        let Some(cb) = banks.of(c.effect) else {
            continue;
        };
        let base: Vec<usize> = baseline.iter().copied().chain(cb).collect();
        if let Some(x) = banks.grams.explained(&[&base], &top_cols) {
            if x.fraction < PARSIMONY {
                return Some((c.effect, x.fraction));
            }
        }
    }
    None
}

/// Diagnosis of output `o` from its prediction `yhat`.
fn diagnose_output(
    rec: &IoRecord,
    o: usize,
    yhat: &[f64],
    model_effects: &[EffectName],
    opts: &DiagnoseOptions,
) -> OutputDiagnosis {
    let inputs: Vec<&[f64]> = rec.inputs.iter().map(|s| s.values.as_slice()).collect();
    let named: Vec<(&str, &[f64])> = rec
        .inputs
        .iter()
        .map(|s| (s.name.as_str(), s.values.as_slice()))
        .collect();
    let y = &rec.outputs[o];
    let e: Vec<f64> = y.values.iter().zip(yhat).map(|(a, b)| a - b).collect();
    let direct = o.min(inputs.len().saturating_sub(1));
    let ctx = BasisContext {
        inputs: &inputs,
        direct,
        prediction: yhat,
        ts: rec.ts,
    };
    let banks = Banks::new(&e, &ctx);
    // the baseline: the prediction and the banks of the effects the model has, so that a
    // misfit of a present effect is not taken for a missing one
    let mut baseline: Vec<usize> = vec![0];
    for (name, cols) in &banks.columns {
        if model_effects.contains(name) {
            baseline.extend(cols.clone());
        }
    }
    let scores = score_banks(&banks, &baseline, model_effects);
    let w = whiteness(&e, &named, opts.max_lag);
    let shape = match inputs.get(direct) {
        Some(u) => residual::describe(&e, yhat, u, w.white),
        None => residual::describe(&e, yhat, &[], w.white),
    };
    let mut candidates: Vec<EffectName> = scores
        .iter()
        .filter(|s| !s.in_model && !w.white && s.explained >= opts.threshold)
        .map(|s| s.effect)
        .collect();
    let top = scores.iter().find(|s| !s.in_model);
    let mut missing = top
        .filter(|s| candidates.contains(&s.effect))
        .map(|s| s.effect);
    let mut simpler_than: Option<(EffectName, f64)> = None;
    if let (Some(m), Some(top)) = (missing, top) {
        let simpler = simpler_effect(m, &scores, &banks, &baseline, opts.threshold);
        if let Some((c, f)) = simpler {
            missing = Some(c);
            simpler_than = Some((top.effect, f));
        }
    }
    if let Some(m) = missing {
        // the named effect first among the candidates
        candidates.retain(|c| *c != m);
        candidates.insert(0, m);
    }
    let unit = unit_of(&y.name);
    let mut messages = Vec::new();
    for s in scores.iter().filter(|s| !s.in_model) {
        let mut msg = describe(rec, o, direct, &e, s, &unit);
        if let (Some(m), Some((t, f))) = (missing, simpler_than) {
            if s.effect == m {
                let adds = if f > 0.0 {
                    format!("only {:.1} %", 100.0 * f)
                } else {
                    "nothing".to_string()
                };
                msg += &format!(
                    " ({t} explains about as much but adds {adds} on top of {m} out of sample: the simpler effect, the smaller bank, is named)"
                );
            }
        }
        messages.push(msg);
    }
    OutputDiagnosis {
        output: y.name.clone(),
        rms: rms(&e),
        scores,
        whiteness: w,
        missing,
        candidates,
        messages,
        residual: shape,
    }
}

/// The effects the model lacks, ranked over all outputs: 1 - sum SSE(with bank) / sum
/// SSE(baseline).
fn pooled_ranking(outputs: &[OutputDiagnosis], model_effects: &[EffectName]) -> Vec<Rank> {
    let mut ranking = Vec::new();
    for effect in registry::effects().into_iter().map(|e| e.name()) {
        if model_effects.contains(&effect) {
            continue;
        }
        let (mut now, mut after, mut n) = (0.0, 0.0, 0usize);
        for od in outputs {
            if let Some(s) = od.scores.iter().find(|s| s.effect == effect) {
                now += s.rms_now * s.rms_now;
                after += s.rms_after * s.rms_after;
                n += 1;
            }
        }
        if n > 0 && now > 0.0 {
            ranking.push(Rank {
                effect,
                explained: 1.0 - after / now,
                rms_now: (now / n as f64).sqrt(),
                rms_after: (after / n as f64).sqrt(),
            });
        }
    }
    ranking.sort_by(|a, b| b.explained.total_cmp(&a.explained));
    ranking
}

/// What to do, in words.
fn summary(
    ranking: &[Rank],
    missing: Option<EffectName>,
    candidates: &[EffectName],
    outputs: &[OutputDiagnosis],
    model_effects: &[EffectName],
) -> Vec<String> {
    let mut summary = Vec::new();
    if let [first, second, ..] = candidates {
        let share = |e: &EffectName| {
            ranking
                .iter()
                .find(|r| r.effect == *e)
                .map_or(0.0, |r| 100.0 * r.explained)
        };
        summary.push(format!(
            "{first} ({:.0} %) and {second} ({:.0} %) both explain the residual: regression on their basis signals cannot tell which the record wants (on one drive frequency a lag and a loop look alike; holds show creep, several frequencies or amplitudes show rate-independent hysteresis); `hystbench improve` fits each and keeps the one whose error falls most",
            share(first),
            share(second)
        ));
    }
    match missing {
        Some(m) => {
            for od in outputs {
                if let Some(msg) = od.messages.iter().find(|t| t.starts_with(m.as_str())) {
                    summary.push(format!("{}: {msg}", od.output));
                }
            }
            summary.push(add_it(model_effects, m));
        }
        None => {
            let white = outputs.iter().all(|o| o.whiteness.white);
            summary.push(if white {
                "nothing significant is missing: the residual is white and uncorrelated with the inputs".to_string()
            } else {
                "nothing significant is missing from the library's effects: no effect the model lacks explains enough of the residual (what is left is noise or a misfit of the effects it has)".to_string()
            });
            summary.extend(where_left(outputs));
        }
    }
    summary
}

/// One sentence about what an effect would change, with its evidence (the effect's own).
fn describe(
    rec: &IoRecord,
    o: usize,
    direct: usize,
    e: &[f64],
    s: &EffectScore,
    unit: &str,
) -> String {
    let unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    };
    if s.explained < 0.05 {
        return format!(
            "{}: no evidence in this record: its basis explains none of the residual out of sample",
            s.effect
        );
    }
    let change = {
        format!(
            "adding {} should bring the RMS error from {:.3} to about {:.3}{unit} ({:.0} % of the residual explained out of sample)",
            s.effect,
            s.rms_now,
            s.rms_after,
            100.0 * s.explained
        )
    };
    let names: Vec<&str> = rec.inputs.iter().map(|x| x.name.as_str()).collect();
    let inputs: Vec<&[f64]> = rec.inputs.iter().map(|x| x.values.as_slice()).collect();
    let ctx = EvidenceContext {
        input_names: &names,
        inputs: &inputs,
        direct,
        output: &rec.outputs[o].name,
        error: e,
        ts: rec.ts,
        unit: &unit,
    };
    let evidence = registry::effect(s.effect).map_or_else(String::new, |x| x.evidence(&ctx));
    format!("{}: {evidence}; {change}", s.effect)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Signal;

    /// A record without inputs (an output logged alone) is diagnosed, not a panic: no bank
    /// applies, and nothing is named.
    #[test]
    fn a_record_without_inputs_is_diagnosed_without_panic() {
        let y: Vec<f64> = (0..500).map(|k| (0.05 * k as f64).sin()).collect();
        let rec = IoRecord {
            path: "y.csv".into(),
            ts: 1e-3,
            t0: 0.0,
            time_name: "t".into(),
            inputs: Vec::new(),
            outputs: vec![Signal {
                name: "y".into(),
                values: y.clone(),
            }],
        };
        let pred = vec![vec![0.0; y.len()]];
        let d = diagnose(&rec, &pred, &[], &DiagnoseOptions::default());
        assert_eq!(d.missing, None);
        assert!(d.ranking.is_empty());
        assert_eq!(d.outputs.len(), 1);
    }
}
