//! The name of an effect, as the command line, the files and the reports write it.
//!
//! A name is a `&'static str` owned by its effect (`Effect::name`); names parse and
//! deserialise only when an effect of the registry carries them, and they order as the
//! registry lists the effects (chain order), see `registry.rs`.

/// An effect's name (`hysteresis`, `creep`, ...). Compare, copy and print it freely; parse it
/// with `str::parse`, which checks it against the registry.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct EffectName(&'static str);

impl EffectName {
    /// The name an effect gives itself (its file's `NAME`); not checked against the registry.
    pub const fn new(name: &'static str) -> EffectName {
        EffectName(name)
    }

    /// The command-line name.
    pub fn as_str(self) -> &'static str {
        self.0
    }
}

impl std::fmt::Display for EffectName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }
}

impl std::fmt::Debug for EffectName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }
}

impl serde::Serialize for EffectName {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.0)
    }
}

impl<'de> serde::Deserialize<'de> for EffectName {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}
