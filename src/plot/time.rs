//! # Time-series figure
//!
//! Measured output, model prediction (`<output>_hat`, one-step ahead or free run, whichever the
//! record holds) and residual `y - y_hat` over time, one pair of stacked panels per output, on a
//! shared time axis; a prediction band (`<output>_lo`, `<output>_hi`) is shaded around the model
//! and around zero under the residual. Without predictions, each input and output gets its own panel. The zoom
//! window is chosen with [`PlotRecord::window`] (`--from`/`--to`).

use super::axes::{self, legend, legend_line};
use super::decimate::decimate;
use super::render::{render_err, save, Figure};
use super::source::PlotRecord;
use super::style::{self, time_label};
use super::PlotError;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Time-series figure of one record.
pub struct TimeFigure<'a> {
    pub record: &'a PlotRecord,
    pub title: Option<String>,
    /// Points per series at most.
    pub max_points: usize,
}

enum Panel {
    Signal { name: String, values: Vec<f64> },
    Fit { j: usize },
    Residual { j: usize },
}

impl<'a> TimeFigure<'a> {
    /// A figure of `record` (at least 2 samples).
    pub fn new(record: &'a PlotRecord, title: Option<String>) -> Result<Self, PlotError> {
        record.require_len(2, "time")?;
        Ok(TimeFigure {
            record,
            title,
            max_points: 20_000,
        })
    }

    fn panels(&self) -> Vec<Panel> {
        let r = self.record;
        if r.has_predictions() {
            let mut p = Vec::new();
            for j in 0..r.io.outputs.len() {
                if r.predicted[j].is_some() {
                    p.push(Panel::Fit { j });
                    p.push(Panel::Residual { j });
                } else {
                    p.push(Panel::Signal {
                        name: r.io.outputs[j].name.clone(),
                        values: r.io.outputs[j].values.clone(),
                    });
                }
            }
            p
        } else {
            r.io.inputs
                .iter()
                .chain(&r.io.outputs)
                .map(|s| Panel::Signal {
                    name: s.name.clone(),
                    values: s.values.clone(),
                })
                .collect()
        }
    }
}

impl Figure for TimeFigure<'_> {
    fn default_size(&self) -> (u32, u32) {
        (1400, 80 + 340 * self.panels().len() as u32)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let r = self.record;
        let title = self.title.clone().unwrap_or_else(|| {
            if r.has_predictions() {
                format!("Measured, model and residual over time ({})", r.label)
            } else {
                format!("Record over time ({})", r.label)
            }
        });
        let body = axes::titled(root, &title)?;
        let panels = self.panels();
        let areas = body.split_evenly((panels.len(), 1));
        let n = r.len();
        let t: Vec<f64> = (0..n).map(|k| r.time(k)).collect();
        let xr = (t[0], t[n - 1]);
        let tl = time_label(&r.io.time_name);
        for (area, panel) in areas.iter().zip(&panels) {
            let mut series: Vec<(String, &[f64], RGBColor)> = Vec::new();
            let residual;
            let ylabel = match panel {
                Panel::Signal { name, values } => {
                    series.push((name.clone(), values, style::series_colour(0)));
                    r.quantity(name).label()
                }
                Panel::Fit { j } => {
                    let s = &r.io.outputs[*j];
                    series.push(("measured".into(), &s.values, style::series_colour(0)));
                    if let Some(p) = &r.predicted[*j] {
                        series.push(("model".into(), p, style::series_colour(1)));
                    }
                    r.quantity(&s.name).label()
                }
                Panel::Residual { j } => {
                    residual = r.residual(*j).unwrap_or_default();
                    series.push(("residual".into(), &residual, style::series_colour(2)));
                    let q = r.quantity(&r.io.outputs[*j].name);
                    q.label_with(&format!("residual {}", q.name))
                }
            };
            // the band: (centre, half-width), shaded under the lines
            let band: Option<(Vec<f64>, &[f64])> = match panel {
                Panel::Fit { j } => r.predicted[*j].clone().zip(r.band[*j].as_deref()),
                Panel::Residual { j } => r.band[*j].as_deref().map(|h| (vec![0.0; n], h)),
                Panel::Signal { .. } => None,
            };
            let mut yr = (f64::INFINITY, f64::NEG_INFINITY);
            for (_, v, _) in &series {
                yr = axes::union(yr, axes::padded_range(*v, 0.05));
            }
            if let Some((c, h)) = &band {
                let edges: Vec<f64> = c.iter().zip(*h).flat_map(|(c, h)| [c - h, c + h]).collect();
                yr = axes::union(yr, axes::padded_range(&edges, 0.05));
            }
            // the time axis is described once, under the bottom panel
            let last = std::ptr::eq(panel, panels.last().unwrap_or(panel));
            let xl = if last { tl.as_str() } else { "" };
            let mut chart = axes::chart(area, "", xr, yr, xl, &ylabel)?;
            if matches!(panel, Panel::Residual { .. }) {
                chart
                    .draw_series(axes::path_elements(
                        vec![(xr.0, 0.0), (xr.1, 0.0)],
                        BLACK.mix(0.5).stroke_width(style::px(1)),
                    ))
                    .map_err(render_err)?;
            }
            let sigs: Vec<&[f64]> = series.iter().map(|s| s.1).collect();
            let idx = decimate(&sigs, 0..n, self.max_points);
            if let Some((c, h)) = &band {
                let mut outline: Vec<(f64, f64)> =
                    idx.iter().map(|&k| (t[k], c[k] + h[k])).collect();
                outline.extend(idx.iter().rev().map(|&k| (t[k], c[k] - h[k])));
                let colour = style::series_colour(1).mix(0.2);
                chart
                    .draw_series(std::iter::once(Polygon::new(outline, colour.filled())))
                    .map_err(render_err)?
                    .label("prediction band (95 %)")
                    .legend(move |(x, y)| {
                        Rectangle::new([(x, y - 4), (x + 16, y + 4)], colour.filled())
                    });
            }
            for (name, v, c) in &series {
                chart
                    .draw_series(axes::path_elements(
                        idx.iter().map(|&k| (t[k], v[k])).collect::<Vec<_>>(),
                        c.stroke_width(style::px(style::LINE_WIDTH)),
                    ))
                    .map_err(render_err)?
                    .label(name.as_str())
                    .legend(legend_line(*c));
            }
            if series.len() > 1 || band.is_some() || matches!(panel, Panel::Residual { .. }) {
                legend(&mut chart, SeriesLabelPosition::UpperRight)?;
            }
        }
        Ok(())
    }
}

/// Draw a time figure of `record` to `path` (see [`TimeFigure`]).
pub fn time_figure(
    record: &PlotRecord,
    title: Option<String>,
    path: &Path,
    size: Option<(u32, u32)>,
    force: bool,
) -> Result<(), PlotError> {
    save(&TimeFigure::new(record, title)?, path, size, force)
}
