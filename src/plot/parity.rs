//! # Parity figure
//!
//! Predicted against measured output, with the identity line and R^2 in each panel's title:
//! one-step-ahead and free-run predictions side by side (columns), one row per output, as in the
//! source study's Figures 3.7 and 3.9. Each record is a prediction CSV (`<output>_hat` columns).

use super::axes;
use super::decimate::stride;
use super::render::{render_err, save, Figure};
use super::source::PlotRecord;
use super::style::{self, fmt_num, PANEL};
use super::PlotError;
use crate::metrics::r2;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Predicted against measured for one or more predictions (e.g. one-step ahead, free run).
pub struct ParityFigure<'a> {
    /// (name shown, e.g. "one-step ahead", prediction record).
    pub panels: Vec<(String, &'a PlotRecord)>,
    pub title: Option<String>,
    /// Points per panel at most (evenly strided).
    pub max_points: usize,
}

impl<'a> ParityFigure<'a> {
    /// Every record needs predictions of all its outputs, and all records the same outputs.
    pub fn new(
        panels: Vec<(String, &'a PlotRecord)>,
        title: Option<String>,
    ) -> Result<Self, PlotError> {
        let Some((_, first)) = panels.first() else {
            return Err(PlotError::Invalid {
                what: "parity figure".into(),
                problem: "no prediction record given".into(),
            });
        };
        for (_, r) in &panels {
            r.require_len(2, "parity")?;
            r.require_predictions()?;
            if r.io.output_names() != first.io.output_names() {
                return Err(PlotError::Invalid {
                    what: format!("{}", r.io.path.display()),
                    problem: format!(
                        "has outputs {:?} but {} has {:?}",
                        r.io.output_names(),
                        first.io.path.display(),
                        first.io.output_names()
                    ),
                });
            }
        }
        Ok(ParityFigure {
            panels,
            title,
            max_points: 6_000,
        })
    }
}

impl Figure for ParityFigure<'_> {
    fn default_size(&self) -> (u32, u32) {
        let cols = self.panels.len() as u32;
        let rows = self.panels[0].1.io.outputs.len() as u32;
        (PANEL.1 * cols + 40, PANEL.1 * rows + 60)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let first = self.panels[0].1;
        let title = self
            .title
            .clone()
            .unwrap_or_else(|| format!("Predicted against measured ({})", first.label));
        let body = axes::titled(root, &title)?;
        let (cols, rows) = (self.panels.len(), first.io.outputs.len());
        let areas = body.split_evenly((rows, cols));
        for i in 0..rows {
            // the same square range in every column of the row
            let mut range = (f64::INFINITY, f64::NEG_INFINITY);
            for (_, r) in &self.panels {
                range = axes::union(range, axes::padded_range(&r.io.outputs[i].values, 0.04));
                if let Some(p) = &r.predicted[i] {
                    range = axes::union(range, axes::padded_range(p, 0.04));
                }
            }
            for (c, (name, r)) in self.panels.iter().enumerate() {
                let y = &r.io.outputs[i].values;
                let Some(p) = r.predicted[i].as_deref() else {
                    continue;
                };
                let score = r2(y, p).map_or("undefined (constant output)".to_string(), fmt_num);
                let oname = &r.io.outputs[i].name;
                let caption = if rows > 1 {
                    format!("{name}, {oname}: R² = {score}")
                } else {
                    format!("{name}: R² = {score}")
                };
                let q = r.quantity(oname);
                let mut chart = axes::chart(
                    &areas[i * cols + c],
                    &caption,
                    range,
                    range,
                    &q.label_with(&format!("measured {}", q.name)),
                    &q.label_with(&format!("predicted {}", q.name)),
                )?;
                chart
                    .draw_series(DashedLineSeries::new(
                        vec![(range.0, range.0), (range.1, range.1)],
                        style::px(10),
                        style::px(6),
                        BLACK.mix(0.7).stroke_width(style::px(2)),
                    ))
                    .map_err(render_err)?;
                let colour = style::series_colour(c);
                chart
                    .draw_series(stride(y.len(), self.max_points).into_iter().map(|k| {
                        Circle::new((y[k], p[k]), style::px(3), colour.mix(0.45).filled())
                    }))
                    .map_err(render_err)?;
            }
        }
        Ok(())
    }
}

/// Draw a parity figure to `path`: one column per (name, prediction record).
pub fn parity_figure(
    panels: Vec<(String, &PlotRecord)>,
    title: Option<String>,
    path: &Path,
    size: Option<(u32, u32)>,
    force: bool,
) -> Result<(), PlotError> {
    save(&ParityFigure::new(panels, title)?, path, size, force)
}
