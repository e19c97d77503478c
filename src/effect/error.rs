/// What can be wrong with an effect's parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EffectError {
    #[error("`{field}` = {value}: {rule}")]
    Invalid {
        field: String,
        value: f64,
        rule: String,
    },
    #[error("`{field}`: {rule}")]
    Shape { field: String, rule: String },
    #[error("unknown effect `{name}`; the valid effects are: {valid}")]
    UnknownEffect { name: String, valid: String },
}

impl EffectError {
    /// The same error with `prefix.` in front of the field name (to give the path in a spec).
    pub fn within(self, prefix: &str) -> EffectError {
        match self {
            EffectError::Invalid { field, value, rule } => EffectError::Invalid {
                field: format!("{prefix}.{field}"),
                value,
                rule,
            },
            EffectError::Shape { field, rule } => EffectError::Shape {
                field: format!("{prefix}.{field}"),
                rule,
            },
            e => e,
        }
    }
}
