//! # The registry: the one list of effects
//!
//! The command line's effect names, `fit --effects`, the diagnosis, the NARX features and the
//! plant files read this list; its order is the chain order (and the order of every report).
//! A program (or a test) adds its own effect with [`register`].

use super::feature::{FeatureKind, FeatureSpec};
use super::traits::Effect;
use super::{coupling, creep, dynamics, hysteresis, viscous, EffectError, EffectName};
use std::sync::RwLock;

/// The library's effects, in chain order.
static BUILTIN: [&dyn Effect; 5] = [
    &hysteresis::HysteresisEffect,
    &creep::CreepEffect,
    &dynamics::DynamicsEffect,
    &coupling::CouplingEffect,
    &viscous::ViscousEffect,
];

/// Effects registered at run time, after the built-in ones.
static REGISTERED: RwLock<Vec<&'static dyn Effect>> = RwLock::new(Vec::new());

/// Every effect, in chain order (the built-in ones, then the registered ones).
pub fn effects() -> Vec<&'static dyn Effect> {
    let mut v: Vec<&'static dyn Effect> = BUILTIN.to_vec();
    v.extend(REGISTERED.read().map(|r| r.clone()).unwrap_or_default());
    v
}

/// Add an effect to the registry (for the rest of the process); a name already taken is
/// refused. Registering the same effect twice is not an error.
pub fn register(effect: &'static dyn Effect) -> Result<(), EffectError> {
    let name = effect.name();
    if let Some(e) = find(name.as_str()) {
        if std::ptr::addr_eq(e, effect) {
            return Ok(());
        }
        return Err(EffectError::Shape {
            field: name.to_string(),
            rule: "an effect of this name is already registered".into(),
        });
    }
    let mut r = REGISTERED.write().unwrap_or_else(|e| e.into_inner());
    r.push(effect);
    Ok(())
}

/// The effect of this name.
pub fn find(name: &str) -> Option<&'static dyn Effect> {
    effects().into_iter().find(|e| e.name().as_str() == name)
}

/// The effect of this name (for a name that came from an effect).
pub fn effect(name: EffectName) -> Option<&'static dyn Effect> {
    find(name.as_str())
}

/// The names, comma-separated, in chain order.
pub fn names() -> String {
    effects()
        .iter()
        .map(|e| e.name().as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The feature kind of this name, from whichever effect defines it.
pub fn feature_kind(name: &str) -> Option<&'static FeatureKind> {
    effects()
        .into_iter()
        .flat_map(|e| e.feature_kinds().iter())
        .find(|k| k.name == name)
}

/// The effects the NARX protocol's feature selection tries by default.
pub fn narx_candidates() -> Vec<EffectName> {
    effects()
        .into_iter()
        .filter(|e| e.narx_candidate())
        .map(|e| e.name())
        .collect()
}

fn position(name: EffectName) -> usize {
    effects()
        .iter()
        .position(|e| e.name() == name)
        .unwrap_or(usize::MAX)
}

impl std::str::FromStr for EffectName {
    type Err = EffectError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        find(s.trim())
            .map(|e| e.name())
            .ok_or_else(|| EffectError::UnknownEffect {
                name: s.to_string(),
                valid: names(),
            })
    }
}

impl PartialOrd for EffectName {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// Chain order: the registry's.
impl Ord for EffectName {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        position(*self)
            .cmp(&position(*other))
            .then_with(|| self.as_str().cmp(other.as_str()))
    }
}

impl<'de> serde::Deserialize<'de> for FeatureSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let outer: std::collections::BTreeMap<String, serde_json::Map<String, serde_json::Value>> =
            serde::Deserialize::deserialize(d)?;
        let mut it = outer.into_iter();
        let (Some((name, inner)), None) = (it.next(), it.next()) else {
            return Err(D::Error::custom(
                "a feature is an object with one key, its kind (e.g. `play`)",
            ));
        };
        let kind = feature_kind(&name).ok_or_else(|| {
            let known: Vec<&str> = effects()
                .into_iter()
                .flat_map(|e| e.feature_kinds().iter().map(|k| k.name))
                .collect();
            D::Error::custom(format!(
                "unknown feature kind `{name}`; known: {}",
                known.join(", ")
            ))
        })?;
        let number = |key: &str| -> Result<f64, D::Error> {
            inner
                .get(key)
                .ok_or_else(|| D::Error::custom(format!("feature `{name}`: missing `{key}`")))?
                .as_f64()
                .ok_or_else(|| {
                    D::Error::custom(format!("feature `{name}`: `{key}` is not a number"))
                })
        };
        for key in inner.keys() {
            if key != "input" && !kind.params.contains(&key.as_str()) {
                return Err(D::Error::custom(format!(
                    "feature `{name}`: unknown field `{key}`, expected `input`, {}",
                    kind.params.join(", ")
                )));
            }
        }
        let input = inner.get("input").and_then(|v| v.as_u64()).ok_or_else(|| {
            D::Error::custom(format!("feature `{name}`: `input` must be an input index"))
        })?;
        let params = kind
            .params
            .iter()
            .map(|p| number(p))
            .collect::<Result<Vec<f64>, D::Error>>()?;
        Ok(FeatureSpec::new(kind, input as usize, params))
    }
}
