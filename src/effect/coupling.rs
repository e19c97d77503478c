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

use super::basis::{play_thresholds, BasisBank, BasisContext};
use super::play::play_bank;
use super::EffectName;

/// The other axes: every input but the direct one, and a few of their plays;
/// `None` for a single-input record.
pub fn basis(ctx: &BasisContext) -> Option<BasisBank> {
    if ctx.inputs.len() < 2 {
        return None;
    }
    let mut bank = BasisBank::new(EffectName::Coupling);
    for (j, u) in ctx.inputs.iter().enumerate() {
        if j == ctx.direct {
            continue;
        }
        bank.push(format!("u{}", j + 1), u.to_vec());
        let th = play_thresholds(u, 4);
        for (r, z) in th.iter().zip(play_bank(u, &th)) {
            bank.push(format!("play(u{}, r={r:.3})", j + 1), z);
        }
    }
    Some(bank)
}
