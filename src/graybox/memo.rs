//! Fits of one record, kept by configuration: [`GreyBoxConfig::fit`] is deterministic, so a
//! configuration met again on the same record (the improvement loop's refit of a model the
//! diagnosis has fitted already, the refit test of a structure that an earlier step tested)
//! takes the fit made the first time.

use super::{FittedGreyBox, GreyBoxConfig, GreyBoxError};
use crate::data::IoRecord;
use std::sync::Mutex;

/// Values kept by configuration (options included), for one record. Safe to share between
/// threads; the caller keeps a memo to one record.
#[derive(Debug)]
pub struct ByConfig<T> {
    kept: Mutex<Vec<(GreyBoxConfig, T)>>,
}

impl<T> Default for ByConfig<T> {
    fn default() -> Self {
        ByConfig {
            kept: Mutex::new(Vec::new()),
        }
    }
}

impl<T: Clone> ByConfig<T> {
    /// The value kept for `config`, if any.
    pub fn get(&self, config: &GreyBoxConfig) -> Option<T> {
        let kept = self.kept.lock().unwrap_or_else(|p| p.into_inner());
        kept.iter()
            .find(|(c, _)| c == config)
            .map(|(_, v)| v.clone())
    }

    /// Keep `value` for `config` (the first value kept stays).
    pub fn insert(&self, config: GreyBoxConfig, value: T) {
        let mut kept = self.kept.lock().unwrap_or_else(|p| p.into_inner());
        if !kept.iter().any(|(c, _)| *c == config) {
            kept.push((config, value));
        }
    }

    /// The number of values kept.
    pub fn len(&self) -> usize {
        self.kept.lock().unwrap_or_else(|p| p.into_inner()).len()
    }

    /// Nothing kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The fits made on one record, by configuration.
pub type FitMemo = ByConfig<FittedGreyBox>;

impl FitMemo {
    /// An empty memo.
    pub fn new() -> FitMemo {
        FitMemo::default()
    }

    /// The fit of `config` on `rec`: the one kept, or a new one (then kept). Errors are not
    /// kept.
    pub fn fit(
        &self,
        config: &GreyBoxConfig,
        rec: &IoRecord,
    ) -> Result<FittedGreyBox, GreyBoxError> {
        if let Some(f) = self.get(config) {
            return Ok(f);
        }
        let f = config.fit(rec)?;
        self.insert(config.clone(), f.clone());
        Ok(f)
    }
}
