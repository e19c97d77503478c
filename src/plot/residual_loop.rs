//! # Residual loop figure
//!
//! The residual `e = y - y_hat` against the input. A model that captures the hysteresis leaves
//! a residual without memory: a single-valued cloud around zero. A residual loop with area is the
//! signature of missing memory (hysteresis or creep the model lacks). The normalised loop area,
//! `|shoelace area| / cycles / (ptp(u) * ptp(e))`, goes in the title (0 for no loop, pi/4 for a
//! circle).
//!
//! ## References
//! - Shoelace formula: B. Braden, "The surveyor's area formula", College Math. J. 17(4), 1986,
//!   doi:10.2307/2686282.

use super::axes::{self};
use super::decimate::decimate;
use super::render::{render_err, save, Figure};
use super::source::{normalised_loop_area, PlotRecord};
use super::style::{self, fmt_num, PANEL};
use super::PlotError;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Residual against input for every (output, input) pair of a predicted record.
pub struct ResidualLoopFigure<'a> {
    pub record: &'a PlotRecord,
    pub title: Option<String>,
    residuals: Vec<Vec<f64>>,
}

impl<'a> ResidualLoopFigure<'a> {
    /// Needs a prediction of every output.
    pub fn new(record: &'a PlotRecord, title: Option<String>) -> Result<Self, PlotError> {
        record.require_len(3, "residual-loop")?;
        record.require_predictions()?;
        let residuals = (0..record.io.outputs.len())
            .map(|j| record.residual(j).unwrap_or_default())
            .collect();
        Ok(ResidualLoopFigure {
            record,
            title,
            residuals,
        })
    }

    /// Normalised loop area of residual `i` against input `j` and the cycles it was averaged over.
    pub fn area(&self, i: usize, j: usize) -> (f64, u32) {
        normalised_loop_area(&self.record.io.inputs[j].values, &self.residuals[i])
    }
}

impl Figure for ResidualLoopFigure<'_> {
    fn default_size(&self) -> (u32, u32) {
        let (ni, no) = (
            self.record.io.inputs.len() as u32,
            self.record.io.outputs.len() as u32,
        );
        (PANEL.0 * ni, PANEL.1 * no + 60)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let r = self.record;
        let (ni, no) = (r.io.inputs.len(), r.io.outputs.len());
        let single = ni == 1 && no == 1;
        let title = self.title.clone().unwrap_or_else(|| {
            if single {
                let (a, c) = self.area(0, 0);
                format!(
                    "Residual loop ({}): area/box = {} per cycle ({c} cycles)",
                    r.label,
                    fmt_num(a)
                )
            } else {
                format!("Residual loops ({})", r.label)
            }
        });
        let body = axes::titled(root, &title)?;
        let areas = body.split_evenly((no, ni));
        for i in 0..no {
            for j in 0..ni {
                let area = &areas[i * ni + j];
                let u = &r.io.inputs[j].values;
                let e = &self.residuals[i];
                let q = r.quantity(&r.io.outputs[i].name);
                let caption = if single {
                    String::new()
                } else {
                    format!(
                        "{} → e({}): area/box = {}",
                        r.io.inputs[j].name,
                        r.io.outputs[i].name,
                        fmt_num(self.area(i, j).0)
                    )
                };
                let mut chart = axes::chart(
                    area,
                    &caption,
                    axes::padded_range(u, 0.04),
                    axes::padded_range(e, 0.06),
                    &r.quantity(&r.io.inputs[j].name).label(),
                    &q.label_with(&format!("residual {}", q.name)),
                )?;
                let xr = axes::padded_range(u, 0.04);
                chart
                    .draw_series(axes::path_elements(
                        vec![(xr.0, 0.0), (xr.1, 0.0)],
                        BLACK.mix(0.5).stroke_width(style::px(1)),
                    ))
                    .map_err(render_err)?;
                let idx = decimate(&[u, e], 0..r.len(), 40_000);
                chart
                    .draw_series(axes::path_elements(
                        idx.iter().map(|&k| (u[k], e[k])).collect::<Vec<_>>(),
                        style::series_colour(0).stroke_width(style::px(style::LINE_WIDTH)),
                    ))
                    .map_err(render_err)?;
            }
        }
        Ok(())
    }
}

/// Draw a residual-loop figure of `record` to `path` (see [`ResidualLoopFigure`]).
pub fn residual_loop_figure(
    record: &PlotRecord,
    title: Option<String>,
    path: &Path,
    size: Option<(u32, u32)>,
    force: bool,
) -> Result<(), PlotError> {
    save(&ResidualLoopFigure::new(record, title)?, path, size, force)
}
