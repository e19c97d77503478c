//! # The `Effect` trait: everything an effect contributes
//!
//! One implementation per effect file; the registry (`registry.rs`) lists them. The simulator,
//! the grey-box fit, the diagnosis and the NARX features ask the effect and never match on its
//! name. Every method but the name has a default, so that an effect implements only what it
//! has: a bank for the diagnosis, features for the NARX model, a term or filter for the
//! grey-box model, a place in plant files.

use super::basis::{BasisBank, BasisContext, EvidenceContext};
use super::draw::{Dice, DrawContext};
use super::feature::{FeatureKind, FeatureSpec};
use super::fitting::{
    FilterFit, OutputSetup, PathSetup, RecordError, RecordView, SensorFit, TermFit, Variant,
};
use super::spec::EffectSpec;
use super::EffectName;

/// Where an effect's spec sits in a plant file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// In a path, added to the path's signal (hysteresis, viscous damping).
    PathTerm,
    /// In a path or in an output, filtering the signal (dynamics).
    Filter,
    /// In an output only, filtering the sum of the paths (creep).
    OutputFilter,
    /// In an output, added after its filters: a signal of time, not of the input (drift).
    OutputTerm,
    /// In an output, a static map of the measured signal after the offset (saturation).
    Sensor,
    /// Nowhere: the effect is a structure of the plant (coupling: cross paths).
    None,
}

/// What a plant's structure looks like, for the effects that are a structure.
#[derive(Debug, Clone)]
pub struct StructureView {
    pub n_inputs: usize,
    /// Per output, the input index of each path.
    pub path_inputs: Vec<Vec<usize>>,
}

/// Everything an effect contributes. See `docs/adding-an-effect.md`.
pub trait Effect: Send + Sync + 'static {
    /// The name on the command line, in files and in reports.
    fn name(&self) -> EffectName;
    /// One line for `--help` and the docs.
    fn summary(&self) -> &'static str;

    // --- plant files and simulation ---

    /// Where the spec sits in a plant file (its key is the effect's name).
    fn slot(&self) -> Slot {
        Slot::None
    }
    /// Every path must have it (hysteresis: a linear path writes `{"linear": ...}`).
    fn required_in_path(&self) -> bool {
        false
    }
    /// Read the spec from a plant file's value.
    fn parse_spec(
        &self,
        _d: &mut dyn erased_serde::Deserializer<'_>,
    ) -> Result<Box<dyn EffectSpec>, erased_serde::Error> {
        Err(serde::de::Error::custom(format!(
            "the effect `{}` has no parameters in a plant file",
            self.name()
        )))
    }
    /// A typical spec (for test plants, examples and the effect-matrix test); `None` for an
    /// effect that is a structure.
    fn example(&self) -> Option<Box<dyn EffectSpec>> {
        None
    }
    /// A random spec over the effect's documented physical ranges, for the plant zoo; `None`
    /// for an effect the zoo does not draw (or, for a path term, a role it does not take).
    fn draw(&self, _ctx: &DrawContext, _dice: &mut Dice) -> Option<Box<dyn EffectSpec>> {
        None
    }
    /// A random spec for an output whose noiseless signal (without this effect) is `output`,
    /// sampled every `ts` seconds, for the zoo's `--extra` effects: an effect whose size is a
    /// share of the output's range (a drift, a sensor's limits). `None`: not drawn this way.
    fn draw_on_output(
        &self,
        _output: &[f64],
        _ts: f64,
        _dice: &mut Dice,
    ) -> Option<Box<dyn EffectSpec>> {
        None
    }
    /// For the zoo's `--extra` effects on an output that already has this effect: `existing`
    /// with more drawn on top of it (a second mode and a hold on a mode). `None`: the output
    /// keeps what it has.
    fn draw_onto(
        &self,
        _existing: &dyn EffectSpec,
        _output: &[f64],
        _ts: f64,
        _dice: &mut Dice,
    ) -> Option<Box<dyn EffectSpec>> {
        None
    }
    /// For the zoo's `--extra` effects on a path term: `existing` (this effect's spec on a path
    /// driven by `input`) with a drawn variant on top of it (tanh envelopes on a
    /// Prandtl-Ishlinskii operator). `None`: the path keeps what it has.
    fn draw_onto_path(
        &self,
        _existing: &dyn EffectSpec,
        _input: &[f64],
        _dice: &mut Dice,
    ) -> Option<Box<dyn EffectSpec>> {
        None
    }
    /// Whether [`Effect::draw_onto_path`] draws anything for some paths.
    fn draws_onto_paths(&self) -> bool {
        false
    }
    /// For an effect that is a structure: does the plant have it?
    fn in_structure(&self, _plant: &StructureView) -> bool {
        false
    }

    // --- diagnosis ---

    /// The bank of basis signals, or `None` when it does not apply to the record.
    fn basis<'a>(&self, _ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
        None
    }
    /// The share of a residual this effect's bank must explain out of sample before the
    /// diagnosis' refit test tries the effect (`None`: always tried). For an effect whose
    /// signature in the residual is direct (a slow trend in time, a flattened extreme), a bank
    /// that sees nothing means a refit would find nothing, and the refit is skipped.
    fn refit_evidence(&self) -> Option<f64> {
        None
    }
    /// What in the residual shows this effect (the diagnosis sentence's evidence).
    fn evidence(&self, _ctx: &EvidenceContext) -> String {
        format!("its basis explains part of the residual ({})", self.name())
    }

    // --- NARX features ---

    /// The kinds of feature signal this effect defines.
    fn feature_kinds(&self) -> &'static [FeatureKind] {
        &[]
    }
    /// The feature definitions for a training record with these inputs.
    fn features(&self, _inputs: &[&[f64]], _ts: f64) -> Vec<FeatureSpec> {
        Vec::new()
    }
    /// Why a record gives no features (said when `features` is empty).
    fn no_features(&self) -> &'static str {
        "too few samples"
    }
    /// The NARX protocol's feature selection tries this effect by default.
    fn narx_candidate(&self) -> bool {
        false
    }

    // --- grey-box model ---

    /// Variants the command line can pick (index 0 is the default, named as the effect).
    fn variants(&self) -> &'static [Variant] {
        &[]
    }
    /// The inputs that drive output `o` when the model has this effect (coupling: all).
    fn path_inputs(&self, _n_inputs: usize, _o: usize) -> Option<Vec<usize>> {
        None
    }
    /// The term this effect adds to a path.
    fn term<'a>(&self, _setup: &PathSetup<'a>) -> Option<Box<dyn TermFit + 'a>> {
        None
    }
    /// The filter this effect adds to an output.
    fn filter(&self, _setup: &OutputSetup) -> Option<Box<dyn FilterFit>> {
        None
    }
    /// The columns this effect adds to an output after its filters (an output term: drift).
    fn output_term(&self, _setup: &OutputSetup) -> Option<Box<dyn TermFit>> {
        None
    }
    /// The sensor this effect puts on an output (saturation).
    fn sensor(&self) -> Option<Box<dyn SensorFit>> {
        None
    }
    /// The spec of a path without this effect (required effects: a linear gain).
    fn path_without(&self, _gain: f64) -> Option<Box<dyn EffectSpec>> {
        None
    }
    /// Parameters it adds per path and per output (to size the record it needs).
    fn parameter_count(&self, _size: super::fitting::BasisSize) -> (usize, usize) {
        (0, 0)
    }
    /// The play operators a path of `plays` gets on the record's fitted inputs: fewer where
    /// they determine fewer (a staircase of a few levels); `None`: the effect sets no limit.
    fn plays_supported(&self, _inputs: &[&[f64]], _variant: usize, _plays: usize) -> Option<usize> {
        None
    }
    /// Can the record support the effect? (Reversals for hysteresis, holds for creep...)
    fn check_record(&self, _rec: &RecordView, _variant: usize) -> Result<(), RecordError> {
        Ok(())
    }
}
