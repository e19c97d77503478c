//! # The registry: the one list of effects
//!
//! The command line's effect names, `fit --effects`, the diagnosis, the NARX features and the
//! plant files read this list; its order is the chain order (and the order of every report).
//! A program (or a test) adds its own effect with [`register`].

use super::feature::{FeatureKind, FeatureSpec};
use super::traits::Effect;
use super::{
    coupling, creep, drift, dynamics, hysteresis, saturation, spencer, viscous, EffectError,
    EffectName,
};
use std::sync::RwLock;

/// The library's effects, in chain order: one line each.
static BUILTIN: &[&dyn Effect] = &[
    &hysteresis::HysteresisEffect,
    &creep::CreepEffect,
    &dynamics::DynamicsEffect,
    &coupling::CouplingEffect,
    &viscous::ViscousEffect,
    &spencer::SpencerEffect,
    &drift::DriftEffect,
    &saturation::SaturationEffect,
];

/// Effects registered at run time, after the built-in ones.
static REGISTERED: RwLock<Vec<&'static dyn Effect>> = RwLock::new(Vec::new());

/// Every effect, in chain order (the built-in ones, then the registered ones).
pub fn effects() -> Vec<&'static dyn Effect> {
    let mut v: Vec<&'static dyn Effect> = BUILTIN.to_vec();
    v.extend(REGISTERED.read().unwrap_or_else(|e| e.into_inner()).iter());
    v
}

/// Names an effect cannot take: the fixed keys of plant files and effect lists.
const RESERVED: [&str; 5] = ["input", "name", "paths", "offset", "none"];

/// Add an effect to the registry (for the rest of the process). A name that is taken (by an
/// effect, an operator of one, or a fixed key of the files) is refused; registering the same
/// effect twice is not an error.
pub fn register(effect: &'static dyn Effect) -> Result<(), EffectError> {
    let name = effect.name();
    let taken = |rule: &str| EffectError::Shape {
        field: name.to_string(),
        rule: rule.to_string(),
    };
    if RESERVED.contains(&name.as_str()) {
        return Err(taken("is a fixed key of plant files and effect lists"));
    }
    let mut r = REGISTERED.write().unwrap_or_else(|e| e.into_inner());
    let all = BUILTIN.iter().chain(r.iter());
    for e in all {
        if std::ptr::addr_eq(*e, effect) {
            return Ok(());
        }
        if e.name() == name {
            return Err(taken("an effect of this name is already registered"));
        }
        if e.variants().iter().any(|v| v.name == name.as_str()) {
            return Err(taken("is the name of another effect's operator"));
        }
    }
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

/// The feature kinds' names, each once, in registry order.
fn feature_kind_names() -> Vec<&'static str> {
    let mut names: Vec<&'static str> = Vec::new();
    for k in effects().into_iter().flat_map(|e| e.feature_kinds().iter()) {
        if !names.contains(&k.name) {
            names.push(k.name);
        }
    }
    names
}

/// `{"<kind>": {"input": i, "<param>": v, ...}}`: the kind is looked up in the registry, its
/// parameters are required, unknown and repeated fields are refused.
impl<'de> serde::Deserialize<'de> for FeatureSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::{DeserializeSeed, Error, MapAccess, Visitor};
        struct Params(&'static FeatureKind);
        impl<'de> DeserializeSeed<'de> for Params {
            type Value = FeatureSpec;
            fn deserialize<D: serde::Deserializer<'de>>(
                self,
                d: D,
            ) -> Result<FeatureSpec, D::Error> {
                d.deserialize_map(self)
            }
        }
        impl<'de> Visitor<'de> for Params {
            type Value = FeatureSpec;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "the fields of a `{}` feature", self.0.name)
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<FeatureSpec, A::Error> {
                let kind = self.0;
                let mut input: Option<usize> = None;
                let mut params: Vec<Option<f64>> = vec![None; kind.params.len()];
                while let Some(key) = map.next_key::<String>()? {
                    if key == "input" {
                        if input.is_some() {
                            return Err(A::Error::duplicate_field("input"));
                        }
                        input = Some(map.next_value()?);
                        continue;
                    }
                    let Some(i) = kind.params.iter().position(|p| *p == key) else {
                        return Err(A::Error::custom(format!(
                            "feature `{}`: unknown field `{key}`, expected `input`, {}",
                            kind.name,
                            kind.params.join(", ")
                        )));
                    };
                    if params[i].is_some() {
                        return Err(A::Error::duplicate_field(kind.params[i]));
                    }
                    params[i] = Some(map.next_value()?);
                }
                let input = input.ok_or_else(|| A::Error::missing_field("input"))?;
                let params = params
                    .into_iter()
                    .zip(kind.params)
                    .map(|(v, name)| v.ok_or_else(|| A::Error::missing_field(name)))
                    .collect::<Result<Vec<f64>, _>>()?;
                Ok(FeatureSpec::new(kind, input, params))
            }
        }
        struct Outer;
        impl<'de> Visitor<'de> for Outer {
            type Value = FeatureSpec;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a feature: an object with one key, its kind (e.g. `play`)")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<FeatureSpec, A::Error> {
                let name: String = map
                    .next_key()?
                    .ok_or_else(|| A::Error::custom("a feature needs its kind (e.g. `play`)"))?;
                let kind = feature_kind(&name).ok_or_else(|| {
                    A::Error::custom(format!(
                        "unknown feature kind `{name}`; known: {}",
                        feature_kind_names().join(", ")
                    ))
                })?;
                let f = map.next_value_seed(Params(kind))?;
                if let Some(other) = map.next_key::<String>()? {
                    return Err(A::Error::custom(format!(
                        "a feature has one kind; `{other}` follows `{name}`"
                    )));
                }
                Ok(f)
            }
        }
        d.deserialize_map(Outer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<FeatureSpec, String> {
        serde_json::from_str::<FeatureSpec>(text).map_err(|e| e.to_string())
    }

    #[test]
    fn features_read_back_and_bad_ones_are_refused() {
        let f = read(r#"{"play":{"input":1,"threshold":0.5}}"#).unwrap();
        assert_eq!(f.kind.name, "play");
        assert_eq!((f.input, f.params.clone()), (1, vec![0.5]));
        assert_eq!(
            serde_json::to_string(&f).unwrap(),
            r#"{"play":{"input":1,"threshold":0.5}}"#
        );
        let e = read(r#"{"play":{"input":0,"threshold":1,"threshold":2}}"#).unwrap_err();
        assert!(e.contains("duplicate field `threshold`"), "{e}");
        let e = read(r#"{"play":{"input":0}}"#).unwrap_err();
        assert!(e.contains("missing field `threshold`"), "{e}");
        let e = read(r#"{"play":{"input":0,"threshold":1,"r":2}}"#).unwrap_err();
        assert!(e.contains("unknown field `r`"), "{e}");
        let e = read(r#"{"wiggle":{"input":0}}"#).unwrap_err();
        assert!(
            e.contains("unknown feature kind") && e.matches("play").count() == 1,
            "{e}"
        );
    }

    #[test]
    fn taken_names_cannot_be_registered() {
        struct Named(&'static str);
        impl Effect for Named {
            fn name(&self) -> EffectName {
                EffectName::new(self.0)
            }
            fn summary(&self) -> &'static str {
                "a test effect"
            }
        }
        static CREEP_AGAIN: Named = Named("creep");
        static INPUT: Named = Named("input");
        static OPERATOR: Named = Named("bouc-wen");
        for e in [&CREEP_AGAIN, &INPUT, &OPERATOR] {
            assert!(register(e).is_err(), "{}", e.0);
        }
        assert!(register(&hysteresis::HysteresisEffect).is_ok());
    }
}
