//! # Features: basis signals with their numbers fixed
//!
//! A NARX model's extra regressors are basis signals whose thresholds, time constants and
//! frequencies were chosen once (on the training record) and stored, so that the same signal is
//! recomputed identically on any other record. Each kind of signal belongs to an effect
//! ([`FeatureKind`], listed by `Effect::feature_kinds`): a play belongs to hysteresis, a
//! first-order state to creep, a resonator to dynamics, a rate to viscous damping. In a model
//! file a feature reads `{"play": {"input": 0, "threshold": 0.25}}`.

use super::spec::BoxedOperator;

/// A kind of feature signal: its name, its parameters and how it is computed.
#[derive(Debug)]
pub struct FeatureKind {
    /// The key in a model file (`play`).
    pub name: &'static str,
    /// The parameters' names, in order (`threshold`).
    pub params: &'static [&'static str],
    /// True when the parameters are valid (finite, in range).
    pub valid: fn(&[f64]) -> bool,
    /// A short label from the input's name and the parameters.
    pub label: fn(&str, &[f64]) -> String,
    /// The signal as an operator at rest, from the parameters and the sampling period (s):
    /// stepped one sample at a time (a NARX model run forward by a compensator) or over a
    /// whole signal ([`FeatureSpec::compute`]), with the same bits.
    pub operator: fn(&[f64], f64) -> BoxedOperator,
}

/// One feature: a kind, the input it is computed from (index into the record's inputs) and its
/// parameters.
#[derive(Clone)]
pub struct FeatureSpec {
    pub kind: &'static FeatureKind,
    pub input: usize,
    pub params: Vec<f64>,
}

impl PartialEq for FeatureSpec {
    fn eq(&self, other: &Self) -> bool {
        self.kind.name == other.kind.name
            && self.input == other.input
            && self.params == other.params
    }
}

impl std::fmt::Debug for FeatureSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {{ input: {}", self.kind.name, self.input)?;
        for (n, v) in self.kind.params.iter().zip(&self.params) {
            write!(f, ", {n}: {v}")?;
        }
        f.write_str(" }")
    }
}

impl FeatureSpec {
    /// A feature of `kind` on input `input`.
    pub fn new(kind: &'static FeatureKind, input: usize, params: Vec<f64>) -> FeatureSpec {
        FeatureSpec {
            kind,
            input,
            params,
        }
    }

    /// The input this signal is computed from.
    pub fn input(&self) -> usize {
        self.input
    }

    /// A short label, e.g. `play(u1, r=4.000)`; `names` are the record's input names.
    pub fn label(&self, names: &[String]) -> String {
        let n = names
            .get(self.input)
            .cloned()
            .unwrap_or_else(|| format!("input{}", self.input));
        if self.params.len() != self.kind.params.len() {
            return format!(
                "{}({n}, {} parameters for {})",
                self.kind.name,
                self.params.len(),
                self.kind.params.len()
            );
        }
        (self.kind.label)(&n, &self.params)
    }

    /// Check the definition against `n_inputs` inputs; the error says what is wrong.
    pub fn check(&self, n_inputs: usize) -> Result<(), String> {
        if self.input >= n_inputs {
            return Err(format!(
                "feature {self:?} uses input {} of a record with {n_inputs} inputs",
                self.input
            ));
        }
        if self.params.len() == self.kind.params.len() && (self.kind.valid)(&self.params) {
            Ok(())
        } else {
            Err(format!(
                "feature {self:?}: parameters must be finite and positive"
            ))
        }
    }

    /// The signal on a record with these inputs and sampling period `ts` (seconds); NaN when
    /// the definition does not fit the record ([`FeatureSpec::check`] says why).
    pub fn compute(&self, inputs: &[&[f64]], ts: f64) -> Vec<f64> {
        let n = inputs.first().map_or(0, |u| u.len());
        match (inputs.get(self.input), self.operator(ts)) {
            (Some(u), Some(mut op)) => op.apply(u),
            _ => vec![f64::NAN; n],
        }
    }

    /// The signal as an operator at rest (`None` when the parameters do not fit the kind).
    pub fn operator(&self, ts: f64) -> Option<BoxedOperator> {
        (self.params.len() == self.kind.params.len())
            .then(|| (self.kind.operator)(&self.params, ts))
    }
}

impl serde::Serialize for FeatureSpec {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        struct Inner<'a>(&'a FeatureSpec);
        impl serde::Serialize for Inner<'_> {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                let f = self.0;
                let mut m = s.serialize_map(Some(1 + f.params.len()))?;
                m.serialize_entry("input", &f.input)?;
                for (n, v) in f.kind.params.iter().zip(&f.params) {
                    m.serialize_entry(n, v)?;
                }
                m.end()
            }
        }
        let mut m = s.serialize_map(Some(1))?;
        m.serialize_entry(self.kind.name, &Inner(self))?;
        m.end()
    }
}
