//! Fits of one record, kept by configuration: [`GreyBoxConfig::fit`] is deterministic, so a
//! configuration met again on the same record (the improvement loop's refit of a model the
//! diagnosis has fitted already, the refit test of a structure that an earlier step tested)
//! takes the fit made the first time.

use super::{FittedGreyBox, GreyBoxConfig, GreyBoxError};
use crate::data::IoRecord;
use std::sync::Mutex;

/// The fits made on one record, by configuration (options included). Safe to share between
/// threads; a memo is for one record only (the caller keeps it so).
#[derive(Debug, Default)]
pub struct FitMemo {
    fits: Mutex<Vec<(GreyBoxConfig, FittedGreyBox)>>,
}

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

    /// The fit kept for `config`, if any.
    pub fn get(&self, config: &GreyBoxConfig) -> Option<FittedGreyBox> {
        let fits = self.fits.lock().unwrap_or_else(|p| p.into_inner());
        fits.iter()
            .find(|(c, _)| c == config)
            .map(|(_, f)| f.clone())
    }

    /// Keep `fitted` as the fit of `config` on this memo's record (a fit made elsewhere).
    pub fn insert(&self, config: GreyBoxConfig, fitted: FittedGreyBox) {
        let mut fits = self.fits.lock().unwrap_or_else(|p| p.into_inner());
        if !fits.iter().any(|(c, _)| *c == config) {
            fits.push((config, fitted));
        }
    }

    /// The number of fits kept.
    pub fn len(&self) -> usize {
        self.fits.lock().unwrap_or_else(|p| p.into_inner()).len()
    }

    /// No fit kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}
