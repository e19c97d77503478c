//! The unfitted grey-box model: which effects (and which variant of each), fit options.

use super::GreyBoxError;
use crate::effect::fitting::Variant;
use crate::effect::{registry, Effect, EffectName};

/// Options of the fit.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Play operators per Prandtl-Ishlinskii path (besides the linear term).
    pub plays: usize,
    /// Levenberg-Marquardt iterations at most, per output.
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub tolerance: f64,
    /// Fraction of the record (from the start) used for fitting; 1 = the whole record.
    pub train_fraction: f64,
    /// Samples of the fitted part that the fit leaves out (the model runs through them):
    /// one block of a blocked cross-validation ([`GreyBoxConfig::cross_validate`]).
    pub held_out: Option<std::ops::Range<usize>>,
    /// Relative ridge on the hysteresis terms' coefficients (0: none): on the input map's and
    /// the Bouc-Wen column's, lambda * ||column||^2 * c^2 joins the cost, shrinking each path
    /// toward a linear gain; on a Prandtl-Ishlinskii term's plays (three or more), lambda
    /// times their mean ||column||^2 times the squared second differences of their weights,
    /// smoothing the density (a strong ridge leaves an affine density, not no loop). The
    /// identifier's bases choose it by cross-validation.
    pub ridge: f64,
    /// Choose each output's ridge among [`RIDGES`] by blocked cross-validation of the linear
    /// coefficients at the fitted nonlinear parameters (`OutputProblem::ridge_by_cross_validation`),
    /// then refit with it; `ridge` is then ignored.
    pub choose_ridge: bool,
    /// Relative ridge on the hysteresis terms of each cross path (0: none), on a record with
    /// as many inputs as outputs (input i drives output i; the other inputs' paths are its
    /// cross paths): lambda * ||column||^2 * c^2 joins the cost, times the ratio of the own
    /// path's gain column energy to the cross path's (as if the cross input moved as much as
    /// the own one). Where the record cannot tell the paths apart (inputs that move together
    /// in it), the loop goes to the output's own input, as in a multi-axis actuator whose
    /// axes are driven mostly by their own inputs; elsewhere its pull is of the order of
    /// lambda. The cross paths' gains are not shrunk. The identifier's bases use
    /// `narx::base::BASE_CROSS_RIDGE`.
    pub cross_ridge: f64,
    /// A record too short for `plays` (about ten samples per parameter) is fitted with the most
    /// of 19, 9, 5 or 3 plays that it supports instead of being refused (a parsimonious model
    /// for a short record); off: `plays` or an error.
    pub adapt_plays: bool,
    /// After the fit, try its second stage: the fitted Prandtl-Ishlinskii operators' outputs
    /// through Kuhnen's dead-zone superposition (saturating and asymmetric loops), kept when
    /// it fits better ([`GreyBoxConfig::fit_stages`] also gives the first stage's plant; a
    /// chosen ridge does not enter the second stage).
    pub output_map: bool,
    /// Fit the default operator's plays as generalised plays: their ascending and descending
    /// envelopes split by e(u) = c0 + c1 u + c2 u^2, three parameters more per path
    /// (`PrandtlIshlinskiiSpec::envelope_split`; Al Janaideh, Rakheja & Su 2011). Off by
    /// default: the NARX base cross-validates a short record's lists both ways and keeps the
    /// split where the held-out samples ask for it.
    pub envelope_split: bool,
    /// A record too short for creep time constants over two decades gets one or two (the
    /// most between 5 samples and a third of the record) instead of being refused.
    pub parsimonious_creep: bool,
    /// Samples the record must hold per parameter (10: a model that the record determines
    /// well; a caller that validates the model on held-out samples may ask for fewer).
    pub samples_per_parameter: usize,
    /// A record longer than twice this many samples has its starts chosen on its first part
    /// ([`FitOptions::starts_part`]), or as many samples in blocks spread over it where no
    /// first part shows the whole, the best refined on the whole ([`STARTS_ROWS`]).
    pub starts_rows: usize,
    /// Per output, the first-stage parameters of a fit of the same model on fewer samples
    /// ([`super::FittedGreyBox::first_stages`]): each output's first stage is refined from them
    /// (Levenberg-Marquardt, creep held fixed and then every parameter free) instead of being
    /// fitted from the grid of starts; an output whose parameters do not fit its problem
    /// (another number of creep time constants, say) is fitted from the starts. Empty: none.
    pub refine_from: Vec<super::FirstStageParams>,
    /// Free the optional parameters (a Bouc-Wen exponent) from a second starting grid too
    /// (`TermFit::optional_start_grid`: n = 2), where the fit at n = 1 sits at the bound far
    /// from the true n. On by default; the identifier's bases turn it off (held out on own
    /// zoo seed 1084, it cost a short 2-DoF record and 45 % of their time: `docs/benchmarks.md`).
    pub second_basin: bool,
}

/// The default [`FitOptions::starts_rows`]. The starts of a fit (a grid's best points, the
/// simpler variant's fit) each run to their own minimum and most of them lose: on a long
/// record they run on its first part and only the best is refined on the whole (a
/// 2,000,000-sample `fit --effects hysteresis,creep,dynamics` spent 190 of its 256 s in its
/// starts, 170 s in those that ended 18 to 50,000 times above the best). The zoo's records
/// (200,000 samples at most) and shorter ones run every start on all their samples.
pub const STARTS_ROWS: usize = 200_000;

/// The ridges tried when one is chosen by cross-validation, strongest (simplest model) first.
pub const RIDGES: [f64; 5] = [1.0, 0.1, 0.01, 1e-3, 0.0];

/// Blocks of the cross-validations that choose a ridge.
pub const CV_FOLDS: usize = 4;

/// The play counts a short record falls back to, most first (the hysteresis effect's ladder,
/// which a staircase's paths take too).
pub const FEWER_PLAYS: [usize; 4] = crate::effect::hysteresis::FEWER_PLAYS;

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            plays: 39,
            max_iterations: 100,
            tolerance: 1e-10,
            train_fraction: 1.0,
            held_out: None,
            ridge: 0.0,
            choose_ridge: false,
            cross_ridge: 0.0,
            adapt_plays: true,
            output_map: true,
            envelope_split: false,
            parsimonious_creep: true,
            samples_per_parameter: 10,
            starts_rows: STARTS_ROWS,
            refine_from: Vec::new(),
            second_basin: true,
        }
    }
}

impl FitOptions {
    /// The samples of a record of `n` samples on which its fit's starts are chosen: `None`
    /// (all of them) up to twice [`FitOptions::starts_rows`], else its first tenth, at least
    /// `starts_rows` (the part grows with the record, so that it holds the same share of its
    /// excitation; a part that is long in turn chooses on its own first tenth, so that the
    /// time stays linear in the record).
    pub fn starts_part(&self, n: usize) -> Option<usize> {
        let min = self.starts_rows.max(1);
        (n.saturating_sub(min) > min).then(|| (n / 10).max(min))
    }
}

/// An effect of a grey-box model and the variant chosen (index into `Effect::variants`;
/// 0 is the default, named as the effect).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Selected {
    pub effect: EffectName,
    pub variant: usize,
}

/// An unfitted grey-box model: per output, the sum of paths (a gain per input plus the terms of
/// the effects that act on a path) -> the output's filters -> + offset, with the effects that
/// are switched on. Fit it with [`GreyBoxConfig::fit`].
#[derive(Debug, Clone, PartialEq)]
pub struct GreyBoxConfig {
    /// The effects, in chain (registry) order.
    pub effects: Vec<Selected>,
    pub options: FitOptions,
}

fn valid_list() -> String {
    let variants: Vec<String> = registry::effects()
        .iter()
        .filter(|e| e.variants().len() > 1)
        .map(|e| {
            let names: Vec<&str> = e.variants()[1..].iter().map(|v| v.name).collect();
            format!("{} for {}", names.join(", "), e.name())
        })
        .collect();
    format!(
        "{} (or an operator: {}; `none` for a linear static model)",
        registry::names(),
        variants.join("; ")
    )
}

/// The effect and variant an effect-list item names (`creep`, `bouc-wen`).
fn lookup(item: &str) -> Option<(&'static dyn Effect, usize)> {
    let effects = registry::effects();
    if let Some(e) = effects.iter().find(|e| e.name().as_str() == item) {
        return Some((*e, 0));
    }
    effects.into_iter().find_map(|e| {
        e.variants()
            .iter()
            .position(|v| v.name == item)
            .map(|i| (e, i))
    })
}

impl GreyBoxConfig {
    /// A linear static model (no effect) with default options.
    pub fn linear() -> GreyBoxConfig {
        GreyBoxConfig {
            effects: Vec::new(),
            options: FitOptions::default(),
        }
    }

    /// Parse a comma-separated effect list such as `hysteresis,creep,dynamics` or
    /// `bouc-wen,dynamics`; `none` (or an empty list) is a linear static model.
    pub fn from_effect_list(list: &str) -> Result<GreyBoxConfig, GreyBoxError> {
        let mut cfg = GreyBoxConfig::linear();
        let mut seen: Vec<(String, EffectName)> = Vec::new();
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            if item == "none" {
                continue;
            }
            if seen.iter().any(|(s, _)| s == item) {
                return Err(GreyBoxError::RepeatedEffect { name: item.into() });
            }
            let (effect, variant) = lookup(item).ok_or_else(|| GreyBoxError::UnknownEffect {
                name: item.to_string(),
                valid: valid_list(),
            })?;
            if let Some((first, _)) = seen.iter().find(|(_, e)| *e == effect.name()) {
                let options: Vec<&str> = effect.variants().iter().map(|v| v.name).collect();
                return Err(GreyBoxError::TwoOperators {
                    effect: effect.name().to_string(),
                    first: first.clone(),
                    second: item.to_string(),
                    options: options.join(", "),
                });
            }
            seen.push((item.to_string(), effect.name()));
            cfg.effects.push(Selected {
                effect: effect.name(),
                variant,
            });
        }
        cfg.effects.sort_by_key(|s| s.effect);
        Ok(cfg)
    }

    /// With `fit`'s options: `plays` play operators per Prandtl-Ishlinskii path (fixed; `None`:
    /// as many as the record supports), fitted on the first `train_fraction` of the record
    /// (`None`: the whole record).
    pub fn with_fit_options(
        mut self,
        plays: Option<usize>,
        train_fraction: Option<f64>,
    ) -> Result<GreyBoxConfig, GreyBoxError> {
        if let Some(plays) = plays {
            if plays == 0 {
                return Err(GreyBoxError::NoPlays);
            }
            self.options.plays = plays;
            self.options.adapt_plays = false;
        }
        if let Some(f) = train_fraction {
            self.options.train_fraction = f;
        }
        let f = self.options.train_fraction;
        if !(f > 0.0 && f <= 1.0) {
            return Err(GreyBoxError::TrainFraction { value: f });
        }
        Ok(self)
    }

    /// The effects switched on, in chain order.
    pub fn effects(&self) -> Vec<EffectName> {
        self.effects.iter().map(|s| s.effect).collect()
    }

    /// True when the model has `effect`.
    pub fn has(&self, effect: EffectName) -> bool {
        self.effects.iter().any(|s| s.effect == effect)
    }

    /// The same model with one more effect (the "add the missing effect" step), at its
    /// default variant; no change when it has it.
    pub fn with_effect(&self, effect: EffectName) -> GreyBoxConfig {
        let mut c = self.clone();
        if !c.has(effect) {
            c.effects.push(Selected { effect, variant: 0 });
            c.effects.sort_by_key(|s| s.effect);
        }
        c
    }

    /// The variant of each selected effect that has variants.
    pub fn variants(&self) -> Vec<(EffectName, &'static Variant)> {
        self.effects
            .iter()
            .filter_map(|s| {
                let v = registry::effect(s.effect)?.variants().get(s.variant)?;
                Some((s.effect, v))
            })
            .collect()
    }

    /// The effect list as the command line writes it (`none` when empty).
    pub fn effect_list(&self) -> String {
        let v: Vec<&str> = self
            .effects
            .iter()
            .map(|s| {
                registry::effect(s.effect)
                    .and_then(|e| e.variants().get(s.variant))
                    .map_or(s.effect.as_str(), |v| v.name)
            })
            .collect();
        if v.is_empty() {
            "none".into()
        } else {
            v.join(",")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_effects_and_operators() {
        let c = GreyBoxConfig::from_effect_list("bouc-wen, creep,dynamics").unwrap();
        assert_eq!(c.effect_list(), "bouc-wen,creep,dynamics");
        assert_eq!(c.effects.len(), 3);
        assert_eq!(c.effects[0].variant, 2);
        let c = GreyBoxConfig::from_effect_list("coupling,hysteresis").unwrap();
        assert_eq!(c.effect_list(), "hysteresis,coupling");
        assert_eq!(c.effects[0].variant, 0);
        let c = GreyBoxConfig::from_effect_list("prandtl-ishlinskii").unwrap();
        assert_eq!(c.effects[0].variant, 1);
        assert_eq!(c.variants()[0].1.file, "prandtl-ishlinskii");
        assert_eq!(
            GreyBoxConfig::from_effect_list("none").unwrap().effects(),
            vec![]
        );
    }

    #[test]
    fn unknown_effect_lists_the_valid_ones() {
        let e = GreyBoxConfig::from_effect_list("hysteresis,friction")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("friction")
                && e.contains("creep, dynamics, coupling")
                && e.contains("bouc-wen"),
            "{e}"
        );
    }

    #[test]
    fn two_operators_refused() {
        assert!(GreyBoxConfig::from_effect_list("hysteresis,bouc-wen").is_err());
        assert!(GreyBoxConfig::from_effect_list("creep,creep").is_err());
    }
}
