//! # Coupling
//!
//! Cross-coupling of a multi-input multi-output actuator: each output may receive every input
//! through its own hysteresis path, y_i = D_i[(1 + C_i) sum_j H_ij[u_j]] (the cross paths j != i
//! are the coupling). In plant files the coupling is simply the paths from the other inputs
//! (`plants/piezo_2dof.json`); here live its basis bank (the other axes' inputs and their plays)
//! and the test of whether a record can show it.
//!
//! ## References
//! - M. Rakotondrabe, Nonlinear Dynamics, 2017 (multivariable Prandtl-Ishlinskii).
//! - D. Habineza, M. Rakotondrabe, Y. Le Gorrec, IEEE TCST, 2015 (multivariable Bouc-Wen).

use super::basis::{play_thresholds, BasisBank, BasisContext, EvidenceContext, Signal};
use super::feature::FeatureSpec;
use super::fitting::{RecordError, RecordView};
use super::play::Play;
use super::{Effect, EffectName, StructureView};

/// The effect's name.
pub const NAME: EffectName = EffectName::new("coupling");

/// The other axes: every input but the direct one, and a few of their plays;
/// `None` for a single-input record.
pub fn basis<'a>(ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
    if ctx.inputs.len() < 2 {
        return None;
    }
    let mut bank = BasisBank::new(NAME);
    for (j, u) in ctx.inputs.iter().enumerate() {
        if j == ctx.direct {
            continue;
        }
        bank.push(format!("u{}", j + 1), Signal::samples(u));
        for r in play_thresholds(u, 4) {
            bank.push(
                format!("play(u{}, r={r:.3})", j + 1),
                Signal::samples(u).through(Box::new(Play::new(r, 0.0))),
            );
        }
    }
    Some(bank)
}

/// Cross-coupling as an effect of the library: a structure (every input drives every output),
/// with no parameters of its own in a plant file.
pub struct CouplingEffect;

impl Effect for CouplingEffect {
    fn name(&self) -> EffectName {
        NAME
    }
    fn summary(&self) -> &'static str {
        "cross paths: every input drives every output (2-DoF actuators)"
    }
    fn in_structure(&self, plant: &StructureView) -> bool {
        let last = plant.n_inputs.saturating_sub(1);
        plant
            .path_inputs
            .iter()
            .enumerate()
            .any(|(o, paths)| paths.iter().any(|&j| j != o.min(last)))
    }
    fn basis<'a>(&self, ctx: &BasisContext<'a>) -> Option<BasisBank<'a>> {
        basis(ctx)
    }
    fn evidence(&self, ctx: &EvidenceContext) -> String {
        let best = ctx
            .inputs
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != ctx.direct)
            .map(|(j, u)| {
                (
                    ctx.input_names[j].to_string(),
                    crate::metrics::correlation(u, ctx.error).abs(),
                )
            })
            .fold((String::new(), 0.0), |m, x| if x.1 > m.1 { x } else { m });
        format!(
            "the error of {} follows {} (correlation {:.2})",
            ctx.output, best.0, best.1
        )
    }
    fn feature_kinds(&self) -> &'static [crate::effect::FeatureKind] {
        std::slice::from_ref(&super::hysteresis::PLAY)
    }
    /// With two or more inputs, 4 plays of each input (the other axes' hysteresis; the inputs
    /// themselves are already NARX regressors).
    fn features(&self, inputs: &[&[f64]], _ts: f64) -> Vec<FeatureSpec> {
        if inputs.len() < 2 {
            return Vec::new();
        }
        let mut out = Vec::new();
        for (j, u) in inputs.iter().enumerate() {
            for r in play_thresholds(u, 4) {
                out.push(FeatureSpec::new(&super::hysteresis::PLAY, j, vec![r]));
            }
        }
        out
    }
    fn no_features(&self) -> &'static str {
        "coupling needs at least two inputs"
    }
    fn path_inputs(&self, n_inputs: usize, _o: usize) -> Option<Vec<usize>> {
        Some((0..n_inputs).collect())
    }
    fn check_record(&self, rec: &RecordView, _variant: usize) -> Result<(), RecordError> {
        if rec.inputs.len() < 2 {
            return Err(RecordError::NeedsInputs {
                needed: 2,
                why: "coupling is the paths from the other inputs".into(),
            });
        }
        Ok(())
    }
}
