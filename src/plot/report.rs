//! Figures beside a report: the set a command that writes a report (`compare`, `demo`, `sweep`)
//! puts next to it, staged together and renamed into place at once.

use super::loops::{LoopFigure, LoopOptions};
use super::render::{render, Format};
use super::residual_loop::ResidualLoopFigure;
use super::source::PlotRecord;
use super::spectrum::SpectrumFigure;
use super::time::TimeFigure;
use super::PlotError;
use crate::data::OutputGuard;
use std::path::{Path, PathBuf};

/// Write the standard figures of `record` into `dir` as PNG, each name starting with `prefix`:
/// `loop.png` always; with predictions also `time.png`, `residual_loop.png` and
/// `spectrum.png` (the spectrum needs 64 samples). All files are written or none. Returns the
/// paths written.
pub fn report_figures(
    record: &PlotRecord,
    dir: &Path,
    prefix: &str,
    force: bool,
) -> Result<Vec<PathBuf>, PlotError> {
    let mut guard = OutputGuard::new(force);
    let mut written = Vec::new();
    let mut stage = |name: &str, bytes: Vec<u8>| -> Result<(), PlotError> {
        let path = dir.join(format!("{prefix}{name}"));
        guard.stage(&path, &bytes)?;
        written.push(path);
        Ok(())
    };
    let options = LoopOptions::default();
    let records = std::slice::from_ref(record);
    stage(
        "loop.png",
        render(&LoopFigure::new(records, &options)?, Format::Png, None)?,
    )?;
    if record.has_predictions() {
        stage(
            "time.png",
            render(&TimeFigure::new(record, None)?, Format::Png, None)?,
        )?;
        if record.predicted.iter().all(Option::is_some) {
            stage(
                "residual_loop.png",
                render(&ResidualLoopFigure::new(record, None)?, Format::Png, None)?,
            )?;
        }
        if record.len() >= 64 {
            stage(
                "spectrum.png",
                render(&SpectrumFigure::new(record, None)?, Format::Png, None)?,
            )?;
        }
    }
    guard.commit()?;
    Ok(written)
}
