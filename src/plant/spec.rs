//! Plant files (`plants/*.json`) and their check into valid plants.

use super::PlantError;
use crate::effect::{registry, Effect, EffectName, EffectParams, EffectSpec, Slot, Spec};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Units of the signals, for labels and reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct Units {
    #[serde(default)]
    pub input: String,
    #[serde(default)]
    pub output: String,
}

/// One path from an input to an output: the effects on it, each under its name. Terms
/// (hysteresis, which every path has, and e.g. `viscous`) add up; filters (e.g. `dynamics`:
/// cross paths of a 2-DoF cantilever show both modes) act on their sum.
#[derive(Debug, Clone, PartialEq)]
pub struct PathSpec {
    /// Name of the input (one of the plant's `inputs`).
    pub input: String,
    /// The effects' specs: terms first, then filters, each in registry order.
    pub effects: Vec<Box<dyn EffectSpec>>,
}

/// One output: the sum of its paths, then its filters (e.g. creep, then dynamics), plus a
/// constant offset (a sensor's zero).
#[derive(Debug, Clone, PartialEq)]
pub struct OutputSpec {
    pub name: String,
    pub paths: Vec<PathSpec>,
    /// Added to the output (output units; default 0).
    pub offset: f64,
    /// The output filters' specs, in registry (chain) order.
    pub effects: Vec<Box<dyn EffectSpec>>,
}

/// Canonical order of a list of specs: terms first, then the others, each in registry order.
fn canonical(specs: &mut [Box<dyn EffectSpec>]) {
    specs.sort_by_key(|s| {
        let term = registry::effect(s.effect()).map(|e| e.slot()) == Some(Slot::PathTerm);
        (!term, s.effect())
    });
}

/// Typed access to a list of specs (`path.get::<CreepSpec>()`).
pub trait EffectSpecs {
    fn specs(&self) -> &[Box<dyn EffectSpec>];
    fn specs_mut(&mut self) -> &mut Vec<Box<dyn EffectSpec>>;

    /// The spec of type `T`, if the list has it.
    fn get<T: Spec>(&self) -> Option<&T> {
        self.specs()
            .iter()
            .find_map(|s| s.as_any().downcast_ref::<T>())
    }
    /// The spec of type `T`, mutable.
    fn get_mut<T: Spec>(&mut self) -> Option<&mut T> {
        self.specs_mut()
            .iter_mut()
            .find_map(|s| s.as_any_mut().downcast_mut::<T>())
    }
    /// Set (or replace) the spec of `T`'s effect.
    fn set<T: Spec>(&mut self, spec: T) {
        self.remove(T::EFFECT);
        let v = self.specs_mut();
        v.push(Box::new(spec));
        canonical(v);
    }
    /// Remove the spec of an effect.
    fn remove(&mut self, effect: EffectName) -> Option<Box<dyn EffectSpec>> {
        let v = self.specs_mut();
        let i = v.iter().position(|s| s.effect() == effect)?;
        Some(v.remove(i))
    }
}

impl EffectSpecs for PathSpec {
    fn specs(&self) -> &[Box<dyn EffectSpec>] {
        &self.effects
    }
    fn specs_mut(&mut self) -> &mut Vec<Box<dyn EffectSpec>> {
        &mut self.effects
    }
}

impl EffectSpecs for OutputSpec {
    fn specs(&self) -> &[Box<dyn EffectSpec>] {
        &self.effects
    }
    fn specs_mut(&mut self) -> &mut Vec<Box<dyn EffectSpec>> {
        &mut self.effects
    }
}

impl PathSpec {
    /// A path from `input` with these effects (put in canonical order).
    pub fn new(input: String, mut effects: Vec<Box<dyn EffectSpec>>) -> PathSpec {
        canonical(&mut effects);
        PathSpec { input, effects }
    }
}

impl Serialize for PathSpec {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(Some(1 + self.effects.len()))?;
        m.serialize_entry("input", &self.input)?;
        for e in &self.effects {
            m.serialize_entry(e.effect().as_str(), e.as_ref())?;
        }
        m.end()
    }
}

impl Serialize for OutputSpec {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("name", &self.name)?;
        m.serialize_entry("paths", &self.paths)?;
        if self.offset != 0.0 {
            m.serialize_entry("offset", &self.offset)?;
        }
        for e in &self.effects {
            m.serialize_entry(e.effect().as_str(), e.as_ref())?;
        }
        m.end()
    }
}

/// Reads one effect's spec with the effect's own deserializer (errors keep their position).
struct SpecSeed(&'static dyn Effect);

impl<'de> serde::de::DeserializeSeed<'de> for SpecSeed {
    type Value = Box<dyn EffectSpec>;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        let mut erased = <dyn erased_serde::Deserializer>::erase(d);
        self.0
            .parse_spec(&mut erased)
            .map_err(serde::de::Error::custom)
    }
}

/// Reads an effect's spec, or `null` (the effect is absent, as in older plant files).
struct OptionalSpecSeed(&'static dyn Effect);

impl<'de> serde::de::DeserializeSeed<'de> for OptionalSpecSeed {
    type Value = Option<Box<dyn EffectSpec>>;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        struct V(&'static dyn Effect);
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Option<Box<dyn EffectSpec>>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "the parameters of `{}` or null", self.0.name())
            }
            fn visit_none<E: serde::de::Error>(self) -> Result<Self::Value, E> {
                Ok(None)
            }
            fn visit_unit<E: serde::de::Error>(self) -> Result<Self::Value, E> {
                Ok(None)
            }
            fn visit_some<D: serde::Deserializer<'de>>(
                self,
                d: D,
            ) -> Result<Self::Value, D::Error> {
                serde::de::DeserializeSeed::deserialize(SpecSeed(self.0), d).map(Some)
            }
        }
        d.deserialize_option(V(self.0))
    }
}

/// The effect of key `key` in a path (`in_path`) or an output, or the serde error that lists
/// what the object accepts.
fn effect_of_key<E: serde::de::Error>(
    key: &str,
    fixed: &[&str],
    in_path: bool,
) -> Result<&'static dyn Effect, E> {
    let fits = |e: &&'static dyn Effect| match e.slot() {
        Slot::PathTerm => in_path,
        Slot::Filter => true,
        Slot::OutputFilter | Slot::OutputTerm | Slot::Sensor => !in_path,
        Slot::None => false,
    };
    let mut all: Vec<&'static dyn Effect> = registry::effects().into_iter().filter(fits).collect();
    all.sort_by_key(|e| e.slot() != Slot::PathTerm);
    all.iter()
        .find(|e| e.name().as_str() == key)
        .copied()
        .ok_or_else(|| {
            let expected: Vec<String> = fixed
                .iter()
                .map(|f| format!("`{f}`"))
                .chain(all.iter().map(|e| format!("`{}`", e.name())))
                .collect();
            E::custom(format!(
                "unknown field `{key}`, expected one of {}",
                expected.join(", ")
            ))
        })
}

impl<'de> Deserialize<'de> for PathSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = PathSpec;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a path: {\"input\": ..., \"hysteresis\": ...}")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<PathSpec, A::Error> {
                use serde::de::Error;
                let mut input = None;
                let mut effects: Vec<Box<dyn EffectSpec>> = Vec::new();
                while let Some(key) = map.next_key::<String>()? {
                    if key == "input" {
                        if input.is_some() {
                            return Err(A::Error::duplicate_field("input"));
                        }
                        input = Some(map.next_value::<String>()?);
                        continue;
                    }
                    let e = effect_of_key::<A::Error>(&key, &["input"], true)?;
                    if effects.iter().any(|s| s.effect() == e.name()) {
                        return Err(A::Error::duplicate_field(e.name().as_str()));
                    }
                    effects.extend(map.next_value_seed(OptionalSpecSeed(e))?);
                }
                let input = input.ok_or_else(|| A::Error::missing_field("input"))?;
                for e in registry::effects()
                    .into_iter()
                    .filter(|e| e.required_in_path())
                {
                    if !effects.iter().any(|s| s.effect() == e.name()) {
                        return Err(A::Error::missing_field(e.name().as_str()));
                    }
                }
                Ok(PathSpec::new(input, effects))
            }
        }
        d.deserialize_map(V)
    }
}

impl<'de> Deserialize<'de> for OutputSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = OutputSpec;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("an output: {\"name\": ..., \"paths\": [...]}")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<OutputSpec, A::Error> {
                use serde::de::Error;
                let (mut name, mut paths, mut offset) = (None, None, None);
                let mut effects: Vec<Box<dyn EffectSpec>> = Vec::new();
                while let Some(key) = map.next_key::<String>()? {
                    match key.as_str() {
                        "name" if name.is_none() => name = Some(map.next_value::<String>()?),
                        "paths" if paths.is_none() => {
                            paths = Some(map.next_value::<Vec<PathSpec>>()?)
                        }
                        "offset" if offset.is_none() => offset = Some(map.next_value::<f64>()?),
                        "name" | "paths" | "offset" => {
                            return Err(A::Error::custom(format!("duplicate field `{key}`")))
                        }
                        _ => {
                            let e = effect_of_key::<A::Error>(
                                &key,
                                &["name", "paths", "offset"],
                                false,
                            )?;
                            if effects.iter().any(|s| s.effect() == e.name()) {
                                return Err(A::Error::duplicate_field(e.name().as_str()));
                            }
                            effects.extend(map.next_value_seed(OptionalSpecSeed(e))?);
                        }
                    }
                }
                canonical(&mut effects);
                Ok(OutputSpec {
                    name: name.ok_or_else(|| A::Error::missing_field("name"))?,
                    paths: paths.ok_or_else(|| A::Error::missing_field("paths"))?,
                    offset: offset.unwrap_or(0.0),
                    effects,
                })
            }
        }
        d.deserialize_map(V)
    }
}

/// A plant file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantSpec {
    pub name: String,
    #[serde(default)]
    pub description: String,
    #[serde(default)]
    pub units: Units,
    /// The scenario the demo runs this plant on (path relative to the plant file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default_scenario: Option<String>,
    /// Input names, in column order (`u`, or `u1`, `u2`…).
    #[serde(default)]
    pub inputs: Vec<String>,
    /// Outputs of a chain plant.
    #[serde(default)]
    pub outputs: Vec<OutputSpec>,
    /// An ODE plant instead of a chain.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ode: Option<OdeSpec>,
}

/// The ODE plants, by name.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum OdeSpec {
    /// Noel & Schoukens' Bouc-Wen benchmark system (`src/plant/ode/`).
    BoucWenBenchmark(super::ode::BoucWenBenchmarkSpec),
}

/// A valid ODE plant.
#[derive(Debug, Clone, PartialEq)]
pub enum OdePlant {
    BoucWenBenchmark(super::ode::BoucWenBenchmark),
}

/// A valid path.
#[derive(Debug, Clone, PartialEq)]
pub struct PathParams {
    pub input: usize,
    /// Added up (e.g. hysteresis, viscous damping).
    pub terms: Vec<Box<dyn EffectParams>>,
    /// Applied to the sum of the terms, in order (e.g. the path's own dynamics).
    pub filters: Vec<Box<dyn EffectParams>>,
}

/// A valid output chain.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputChain {
    pub name: String,
    pub paths: Vec<PathParams>,
    pub offset: f64,
    /// Applied to the sum of the paths, in chain order (e.g. creep, then dynamics).
    pub filters: Vec<Box<dyn EffectParams>>,
}

impl PathParams {
    /// Every effect's parameters on the path.
    pub fn effects(&self) -> impl Iterator<Item = &Box<dyn EffectParams>> {
        self.terms.iter().chain(&self.filters)
    }
}

/// What a plant is made of.
#[derive(Debug, Clone, PartialEq)]
pub enum PlantKind {
    /// hysteresis paths -> creep -> dynamics, per output.
    Chain(Vec<OutputChain>),
    /// An ODE plant with one input and one output.
    Ode(OdePlant),
}

/// A valid plant: only this reaches the simulator.
#[derive(Debug, Clone, PartialEq)]
pub struct Plant {
    pub name: String,
    pub description: String,
    pub units: Units,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    pub kind: PlantKind,
    /// The spec it was checked from (written into every record's sidecar).
    pub spec: PlantSpec,
    /// The file it was read from (labels errors found while simulating).
    pub path: PathBuf,
}

impl PlantSpec {
    /// Read a plant file.
    pub fn read(path: &Path) -> Result<PlantSpec, PlantError> {
        Self::parse(path, &crate::data::read_json_text(path)?)
    }

    /// Parse plant JSON; `path` labels the errors.
    pub fn parse(path: &Path, text: &str) -> Result<PlantSpec, PlantError> {
        Ok(crate::data::parse_json_file(path, text)?)
    }

    /// Check everything; `path` labels the errors.
    pub fn check(&self, path: &Path) -> Result<Plant, PlantError> {
        // the effects in chain order, whatever order a program put them in
        let mut spec = self.clone();
        for out in &mut spec.outputs {
            canonical(&mut out.effects);
            for p in &mut out.paths {
                canonical(&mut p.effects);
            }
        }
        spec.check_canonical(path)
    }

    fn check_canonical(&self, path: &Path) -> Result<Plant, PlantError> {
        let p = || PathBuf::from(path);
        let structure = |field: &str, rule: String| structure_error(path, field, rule);
        if self.inputs.is_empty() {
            return Err(structure(
                "inputs",
                "list the input names, e.g. [\"u\"] or [\"u1\", \"u2\"]".into(),
            ));
        }
        for (i, n) in self.inputs.iter().enumerate() {
            if n.trim().is_empty() || self.inputs[..i].contains(n) {
                return Err(structure(
                    &format!("inputs[{i}]"),
                    format!("`{n}` is empty or repeated"),
                ));
            }
        }
        let kind = match (&self.ode, self.outputs.is_empty()) {
            (Some(_), false) => {
                return Err(structure(
                    "ode",
                    "a plant is either a chain (`outputs`) or an ODE (`ode`), not both".into(),
                ))
            }
            (None, true) => {
                return Err(structure(
                    "outputs",
                    "needs at least one output (or an `ode`)".into(),
                ))
            }
            (Some(OdeSpec::BoucWenBenchmark(ode)), true) => {
                if self.inputs.len() != 1 {
                    return Err(structure(
                        "inputs",
                        "the ODE plant has exactly one input".into(),
                    ));
                }
                PlantKind::Ode(OdePlant::BoucWenBenchmark(
                    ode.check()
                        .map_err(|e| structure("ode.bouc_wen_benchmark", e.to_string()))?,
                ))
            }
            (None, false) => PlantKind::Chain(
                self.outputs
                    .iter()
                    .enumerate()
                    .map(|(o, out)| self.check_output(path, o, out))
                    .collect::<Result<_, _>>()?,
            ),
        };
        let outputs = match &kind {
            PlantKind::Chain(c) => c.iter().map(|c| c.name.clone()).collect(),
            PlantKind::Ode(_) => vec!["y".to_string()],
        };
        Ok(Plant {
            name: self.name.clone(),
            description: self.description.clone(),
            units: self.units.clone(),
            inputs: self.inputs.clone(),
            outputs,
            kind,
            spec: self.clone(),
            path: p(),
        })
    }
}

impl PlantSpec {
    /// Check output `o`: its paths, its filters, its name and offset.
    fn check_output(
        &self,
        file: &Path,
        o: usize,
        out: &OutputSpec,
    ) -> Result<OutputChain, PlantError> {
        let at = format!("outputs[{o}]");
        if out.paths.is_empty() {
            return Err(structure_error(
                file,
                &format!("{at}.paths"),
                "needs at least one path".into(),
            ));
        }
        let paths = out
            .paths
            .iter()
            .enumerate()
            .map(|(k, path)| self.check_path(file, &format!("{at}.paths[{k}]"), path))
            .collect::<Result<Vec<_>, _>>()?;
        let mut filters = Vec::new();
        for (i, e) in out.effects.iter().enumerate() {
            let name = e.effect();
            refuse_repeated(file, &at, &out.effects[..i], name)?;
            if !matches!(
                registry::effect(name).map(|e| e.slot()),
                Some(Slot::Filter | Slot::OutputFilter | Slot::OutputTerm | Slot::Sensor)
            ) {
                return Err(structure_error(
                    file,
                    &format!("{at}.{name}"),
                    "is not an effect of an output (put it in a path)".into(),
                ));
            }
            filters.push(
                e.check()
                    .map_err(|err| effect_error(file, format!("{at}.{name}"), err))?,
            );
        }
        if self.outputs[..o].iter().any(|x| x.name == out.name) || self.inputs.contains(&out.name) {
            return Err(structure_error(
                file,
                &format!("{at}.name"),
                format!("`{}` is repeated", out.name),
            ));
        }
        if !out.offset.is_finite() {
            return Err(structure_error(
                file,
                &format!("{at}.offset"),
                format!("{} must be a finite number", out.offset),
            ));
        }
        Ok(OutputChain {
            name: out.name.clone(),
            paths,
            offset: out.offset,
            filters,
        })
    }

    /// Check one path (`at` names it in errors): its input, its effects, the required ones.
    fn check_path(&self, file: &Path, at: &str, path: &PathSpec) -> Result<PathParams, PlantError> {
        let input = self
            .inputs
            .iter()
            .position(|n| *n == path.input)
            .ok_or_else(|| {
                structure_error(
                    file,
                    &format!("{at}.input"),
                    format!(
                        "`{}` is not one of the inputs: {}",
                        path.input,
                        self.inputs.join(", ")
                    ),
                )
            })?;
        let (mut terms, mut filters) = (Vec::new(), Vec::new());
        for (i, e) in path.effects.iter().enumerate() {
            let name = e.effect();
            refuse_repeated(file, at, &path.effects[..i], name)?;
            let p = e
                .check()
                .map_err(|err| effect_error(file, format!("{at}.{name}"), err))?;
            match registry::effect(name).map(|e| e.slot()) {
                Some(Slot::PathTerm) => terms.push(p),
                Some(Slot::Filter) => filters.push(p),
                _ => {
                    return Err(structure_error(
                        file,
                        &format!("{at}.{name}"),
                        "is not an effect of a path".into(),
                    ))
                }
            }
        }
        for e in registry::effects()
            .into_iter()
            .filter(|e| e.required_in_path())
        {
            if !path.effects.iter().any(|s| s.effect() == e.name()) {
                return Err(structure_error(
                    file,
                    &format!("{at}.{}", e.name()),
                    "every path needs it".into(),
                ));
            }
        }
        Ok(PathParams {
            input,
            terms,
            filters,
        })
    }
}

/// An effect may stand once in a path or an output: `name` against the effects before it.
fn refuse_repeated(
    file: &Path,
    at: &str,
    before: &[Box<dyn EffectSpec>],
    name: EffectName,
) -> Result<(), PlantError> {
    if before.iter().any(|x| x.effect() == name) {
        return Err(structure_error(
            file,
            &format!("{at}.{name}"),
            "is given twice".into(),
        ));
    }
    Ok(())
}

fn structure_error(file: &Path, field: &str, rule: String) -> PlantError {
    PlantError::Structure {
        path: file.to_path_buf(),
        field: field.to_string(),
        rule,
    }
}

fn effect_error(file: &Path, field: String, source: crate::effect::EffectError) -> PlantError {
    PlantError::Effect {
        path: file.to_path_buf(),
        field,
        source,
    }
}

impl Plant {
    /// Read and check a plant file.
    pub fn from_file(path: &Path) -> Result<Plant, PlantError> {
        PlantSpec::read(path)?.check(path)
    }
}
