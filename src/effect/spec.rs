//! An effect's parameters in a plant file, behind one trait object.
//!
//! Each effect writes a spec type (`CreepSpec`, ...) that deserialises from its key of a plant
//! file and checks into valid parameters ([`Spec`], [`Params`]); the plant code holds them as
//! [`EffectSpec`] / [`EffectParams`] trait objects, so that it never names an effect. The
//! typed value is reached back with `downcast` (`path.get::<CreepSpec>()`).

use super::{EffectError, EffectName, Operator};
use std::any::Any;
use std::fmt::Debug;

/// A running operator that can move to another thread (plants simulate outputs in parallel).
pub type BoxedOperator = Box<dyn Operator + Send>;

/// An effect's spec type: the parameters as written in a plant file, unchecked.
pub trait Spec:
    serde::Serialize + serde::de::DeserializeOwned + Clone + PartialEq + Debug + Send + Sync + 'static
{
    /// The effect this spec belongs to (and its key in a plant file).
    const EFFECT: EffectName;
    /// The valid parameters.
    type Params: Params;
    /// Check the parameters; the error names the field, the value and the rule.
    fn check(&self) -> Result<Self::Params, EffectError>;
}

/// An effect's valid parameters.
pub trait Params: Clone + PartialEq + Debug + Send + Sync + 'static {
    /// The effect these parameters belong to.
    const EFFECT: EffectName;
    /// The operator at rest for sampling period `ts` (s).
    fn operator(&self, ts: f64) -> Result<BoxedOperator, EffectError>;
    /// False when the parameters make the effect absent (a linear gain is no hysteresis).
    fn is_active(&self) -> bool {
        true
    }
}

/// Any effect's spec, as a plant file holds it.
pub trait EffectSpec: erased_serde::Serialize + Debug + Send + Sync {
    fn effect(&self) -> EffectName;
    fn check(&self) -> Result<Box<dyn EffectParams>, EffectError>;
    fn clone_spec(&self) -> Box<dyn EffectSpec>;
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
    fn same(&self, other: &dyn EffectSpec) -> bool;
}

erased_serde::serialize_trait_object!(EffectSpec);

/// Any effect's valid parameters, as a checked plant holds them.
pub trait EffectParams: Debug + Send + Sync {
    fn effect(&self) -> EffectName;
    fn operator(&self, ts: f64) -> Result<BoxedOperator, EffectError>;
    fn is_active(&self) -> bool;
    fn clone_params(&self) -> Box<dyn EffectParams>;
    fn as_any(&self) -> &dyn Any;
    fn same(&self, other: &dyn EffectParams) -> bool;
}

impl<T: Spec> EffectSpec for T {
    fn effect(&self) -> EffectName {
        T::EFFECT
    }
    fn check(&self) -> Result<Box<dyn EffectParams>, EffectError> {
        Ok(Box::new(Spec::check(self)?))
    }
    fn clone_spec(&self) -> Box<dyn EffectSpec> {
        Box::new(self.clone())
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
    fn same(&self, other: &dyn EffectSpec) -> bool {
        other.as_any().downcast_ref::<T>() == Some(self)
    }
}

impl<T: Params> EffectParams for T {
    fn effect(&self) -> EffectName {
        T::EFFECT
    }
    fn operator(&self, ts: f64) -> Result<BoxedOperator, EffectError> {
        Params::operator(self, ts)
    }
    fn is_active(&self) -> bool {
        Params::is_active(self)
    }
    fn clone_params(&self) -> Box<dyn EffectParams> {
        Box::new(self.clone())
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn same(&self, other: &dyn EffectParams) -> bool {
        other.as_any().downcast_ref::<T>() == Some(self)
    }
}

impl Clone for Box<dyn EffectSpec> {
    fn clone(&self) -> Self {
        self.clone_spec()
    }
}

impl PartialEq for Box<dyn EffectSpec> {
    fn eq(&self, other: &Self) -> bool {
        self.same(other.as_ref())
    }
}

impl Clone for Box<dyn EffectParams> {
    fn clone(&self) -> Self {
        self.clone_params()
    }
}

impl PartialEq for Box<dyn EffectParams> {
    fn eq(&self, other: &Self) -> bool {
        self.same(other.as_ref())
    }
}

/// Read a spec of type `T` from any deserializer (an effect's `Effect::parse_spec`).
pub fn parse_spec<T: Spec>(
    d: &mut dyn erased_serde::Deserializer<'_>,
) -> Result<Box<dyn EffectSpec>, erased_serde::Error> {
    Ok(Box::new(erased_serde::deserialize::<T>(d)?))
}
