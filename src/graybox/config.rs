//! The unfitted grey-box model: which effects, which hysteresis operator, fit options.

use super::GreyBoxError;
use crate::effect::EffectName;
use serde::{Deserialize, Serialize};
use std::str::FromStr;

/// The hysteresis operator of every path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum HysteresisOperator {
    /// The default of `hysteresis`: a classical Prandtl-Ishlinskii operator plus one Bouc-Wen
    /// term on the same input (two paths in the plant file). Exact for either kind of plant;
    /// the PI part alone cannot follow Bouc-Wen loops (no return-point memory, asymmetric
    /// branches for Gamma != 0) closer than about 0.3 % of the range.
    #[serde(rename = "prandtl-ishlinskii+bouc-wen")]
    Combined,
    /// Classical Prandtl-Ishlinskii: linear weight + plays with thresholds spread over the
    /// input range, non-negative play weights (Kuhnen 2003).
    PrandtlIshlinskii,
    /// Bouc-Wen, n = 1 (Rakotondrabe 2011 form): y = d u - h.
    BoucWen,
}

impl HysteresisOperator {
    /// The command-line name.
    pub fn as_str(self) -> &'static str {
        match self {
            HysteresisOperator::Combined => "hysteresis",
            HysteresisOperator::PrandtlIshlinskii => "prandtl-ishlinskii",
            HysteresisOperator::BoucWen => "bouc-wen",
        }
    }
}

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
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            plays: 39,
            max_iterations: 100,
            tolerance: 1e-10,
            train_fraction: 1.0,
        }
    }
}

/// An unfitted grey-box model: per output, the sum of paths H_ij[u_j] -> creep -> dynamics ->
/// + offset, with the effects that are switched on. Fit it with [`GreyBoxConfig::fit`].
#[derive(Debug, Clone, PartialEq)]
pub struct GreyBoxConfig {
    /// `None`: linear paths (no hysteresis).
    pub hysteresis: Option<HysteresisOperator>,
    pub creep: bool,
    pub dynamics: bool,
    pub coupling: bool,
    /// A term in each path input's rate, c du/dt (viscous damping), fitted by least squares.
    pub viscous: bool,
    pub options: FitOptions,
}

/// Names accepted in an effect list besides the effect names.
pub const OPERATOR_NAMES: [&str; 2] = ["prandtl-ishlinskii", "bouc-wen"];

fn valid_list() -> String {
    format!(
        "{} (or a hysteresis operator: {}; `none` for a linear static model)",
        EffectName::ALL.map(|e| e.as_str()).join(", "),
        OPERATOR_NAMES.join(", ")
    )
}

impl GreyBoxConfig {
    /// A model with the given effects and default options.
    pub fn new(
        hysteresis: Option<HysteresisOperator>,
        creep: bool,
        dynamics: bool,
        coupling: bool,
    ) -> GreyBoxConfig {
        GreyBoxConfig {
            hysteresis,
            creep,
            dynamics,
            coupling,
            viscous: false,
            options: FitOptions::default(),
        }
    }

    /// Parse a comma-separated effect list such as `hysteresis,creep,dynamics` or
    /// `bouc-wen,dynamics`; `none` (or an empty list) is a linear static model.
    pub fn from_effect_list(list: &str) -> Result<GreyBoxConfig, GreyBoxError> {
        let mut cfg = GreyBoxConfig::new(None, false, false, false);
        let mut seen: Vec<String> = Vec::new();
        let mut op_name: Option<String> = None;
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            if item == "none" {
                continue;
            }
            if seen.iter().any(|s| s == item) {
                return Err(GreyBoxError::RepeatedEffect { name: item.into() });
            }
            seen.push(item.to_string());
            let op = match item {
                "prandtl-ishlinskii" => Some(HysteresisOperator::PrandtlIshlinskii),
                "bouc-wen" => Some(HysteresisOperator::BoucWen),
                _ => None,
            };
            let effect = match op {
                Some(_) => EffectName::Hysteresis,
                None => EffectName::from_str(item).map_err(|_| GreyBoxError::UnknownEffect {
                    name: item.to_string(),
                    valid: valid_list(),
                })?,
            };
            match effect {
                EffectName::Hysteresis => {
                    if let Some(first) = &op_name {
                        return Err(GreyBoxError::TwoOperators {
                            first: first.clone(),
                            second: item.to_string(),
                        });
                    }
                    op_name = Some(item.to_string());
                    cfg.hysteresis = Some(op.unwrap_or(HysteresisOperator::Combined));
                }
                EffectName::Creep => cfg.creep = true,
                EffectName::Dynamics => cfg.dynamics = true,
                EffectName::Coupling => cfg.coupling = true,
                EffectName::Viscous => cfg.viscous = true,
            }
        }
        Ok(cfg)
    }

    /// The effects switched on, in chain order.
    pub fn effects(&self) -> Vec<EffectName> {
        let mut v = Vec::new();
        if self.hysteresis.is_some() {
            v.push(EffectName::Hysteresis);
        }
        if self.creep {
            v.push(EffectName::Creep);
        }
        if self.dynamics {
            v.push(EffectName::Dynamics);
        }
        if self.coupling {
            v.push(EffectName::Coupling);
        }
        if self.viscous {
            v.push(EffectName::Viscous);
        }
        v
    }

    /// The same model with one more effect (the "add the missing effect" step).
    pub fn with_effect(&self, effect: EffectName) -> GreyBoxConfig {
        let mut c = self.clone();
        match effect {
            EffectName::Hysteresis => {
                if c.hysteresis.is_none() {
                    c.hysteresis = Some(HysteresisOperator::Combined);
                }
            }
            EffectName::Creep => c.creep = true,
            EffectName::Dynamics => c.dynamics = true,
            EffectName::Coupling => c.coupling = true,
            EffectName::Viscous => c.viscous = true,
        }
        c
    }

    /// The effect list as the command line writes it (`none` when empty).
    pub fn effect_list(&self) -> String {
        let v: Vec<&str> = self
            .effects()
            .iter()
            .map(|e| match (e, self.hysteresis) {
                (EffectName::Hysteresis, Some(op)) => op.as_str(),
                (e, _) => e.as_str(),
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
        assert_eq!(c.hysteresis, Some(HysteresisOperator::BoucWen));
        assert!(c.creep && c.dynamics && !c.coupling);
        let c = GreyBoxConfig::from_effect_list("hysteresis,coupling").unwrap();
        assert_eq!(c.hysteresis, Some(HysteresisOperator::Combined));
        assert!(c.coupling);
        let c = GreyBoxConfig::from_effect_list("prandtl-ishlinskii").unwrap();
        assert_eq!(c.hysteresis, Some(HysteresisOperator::PrandtlIshlinskii));
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
