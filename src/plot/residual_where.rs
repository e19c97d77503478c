//! # Where the residual sits
//!
//! Three views of each output's residual e = y - y_hat, one per place where what a model lacks
//! concentrates ([`crate::diagnose::residual`]): against the prediction (a flat top or bottom:
//! saturation), against time (a slow trend: drift), and against the input's travel since its
//! last reversal, signed by the direction of motion (a ramp at small travel: backlash; a step:
//! friction). Each panel overlays the part of the residual its bank explains and says how much
//! it explains out of sample; the place the diagnosis describes is marked.

use super::axes;
use super::decimate::decimate;
use super::render::{render_err, save, Figure};
use super::source::PlotRecord;
use super::style::{self, PANEL};
use super::PlotError;
use crate::diagnose::residual::{self, Place, ResidualShape};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Travel since a reversal shown, as a share of the input's range.
const TRAVEL_SHOWN: f64 = 0.3;

/// Points drawn per panel at most.
const POINTS: usize = 6_000;

/// The residual of every output in the three views.
pub struct ResidualWhereFigure<'a> {
    pub record: &'a PlotRecord,
    pub title: Option<String>,
    shapes: Vec<ResidualShape>,
    residuals: Vec<Vec<f64>>,
}

impl<'a> ResidualWhereFigure<'a> {
    /// Needs a prediction of every output; `shapes` are the diagnosis' descriptions (one per
    /// output, in order).
    pub fn new(
        record: &'a PlotRecord,
        shapes: Vec<ResidualShape>,
        title: Option<String>,
    ) -> Result<Self, PlotError> {
        record.require_len(3, "residual-where")?;
        record.require_predictions()?;
        let residuals = (0..record.io.outputs.len())
            .map(|j| record.residual(j).unwrap_or_default())
            .collect();
        Ok(ResidualWhereFigure {
            record,
            title,
            shapes,
            residuals,
        })
    }

    /// The input that drives output `o` (same index, or the only one).
    fn input(&self, o: usize) -> &[f64] {
        let ins = &self.record.io.inputs;
        ins.get(o.min(ins.len().saturating_sub(1)))
            .map_or(&[][..], |s| s.values.as_slice())
    }

    /// The caption of `place`'s panel of output `o`.
    fn caption(&self, o: usize, place: Place) -> String {
        let shape = self.shapes.get(o);
        let share = shape
            .and_then(|s| s.shares.iter().find(|p| p.place == place))
            .map_or(String::new(), |p| {
                format!(": {:.0} % explained", 100.0 * p.explained.max(0.0))
            });
        let here = if shape.and_then(|s| s.place) == Some(place) {
            " (here)"
        } else {
            ""
        };
        format!("{}{share}{here}", place.as_str())
    }
}

impl Figure for ResidualWhereFigure<'_> {
    fn default_size(&self) -> (u32, u32) {
        (
            PANEL.0 * 3,
            PANEL.1 * self.record.io.outputs.len() as u32 + 60,
        )
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let r = self.record;
        let no = r.io.outputs.len();
        let title = self
            .title
            .clone()
            .unwrap_or_else(|| format!("Where the residual sits ({})", r.label));
        let body = axes::titled(root, &title)?;
        let areas = body.split_evenly((no, 3));
        for o in 0..no {
            let e = &self.residuals[o];
            let Some(yhat) = r.predicted[o].as_deref() else {
                continue;
            };
            let u = self.input(o);
            let q = r.quantity(&r.io.outputs[o].name);
            let e_label = q.label_with(&format!("residual {}", q.name));
            for (c, place) in Place::ALL.into_iter().enumerate() {
                let part = residual::explained_part(place, e, yhat, u);
                // x per sample, the residual's sign (reversals: times the direction of
                // motion), and the samples shown
                let (x, sign, shown, x_label): (Vec<f64>, Vec<f64>, Vec<usize>, String) =
                    match place {
                        Place::Extremes => (
                            yhat.to_vec(),
                            vec![1.0; e.len()],
                            (0..e.len()).collect(),
                            q.label_with(&format!("predicted {}", q.name)),
                        ),
                        Place::SlowTrend => (
                            (0..e.len()).map(|k| r.time(k)).collect(),
                            vec![1.0; e.len()],
                            (0..e.len()).collect(),
                            "time (s)".to_string(),
                        ),
                        Place::Reversals => {
                            let range = if u.is_empty() {
                                0.0
                            } else {
                                crate::metrics::ptp(u)
                            };
                            let m = residual::reversal_travel(u, residual::REVERSAL_MOVE * range);
                            let shown = (0..e.len())
                                .filter(|&k| m[k].1 <= TRAVEL_SHOWN * range && m[k].0 != 0.0)
                                .collect();
                            (
                                m.iter().map(|p| p.1).collect(),
                                m.iter().map(|p| p.0).collect(),
                                shown,
                                "input travel since the last reversal".to_string(),
                            )
                        }
                    };
                if shown.is_empty() {
                    continue;
                }
                let ys: Vec<f64> = shown.iter().map(|&k| sign[k] * e[k]).collect();
                let xs: Vec<f64> = shown.iter().map(|&k| x[k]).collect();
                let y_label = if place == Place::Reversals {
                    format!("{e_label} x direction")
                } else {
                    e_label.clone()
                };
                let mut chart = axes::chart(
                    &areas[o * 3 + c],
                    &self.caption(o, place),
                    axes::padded_range(&xs, 0.04),
                    axes::padded_range(&ys, 0.06),
                    &x_label,
                    &y_label,
                )?;
                let idx = decimate(&[&xs, &ys], 0..xs.len(), POINTS);
                chart
                    .draw_series(idx.iter().map(|&i| {
                        Circle::new(
                            (xs[i], ys[i]),
                            style::px(2),
                            style::series_colour(0).mix(0.35).filled(),
                        )
                    }))
                    .map_err(render_err)?;
                if let Some(p) = part {
                    let fit: Vec<f64> = shown.iter().map(|&k| sign[k] * p[k]).collect();
                    chart
                        .draw_series(idx.iter().map(|&i| {
                            Circle::new(
                                (xs[i], fit[i]),
                                style::px(2),
                                style::series_colour(1).filled(),
                            )
                        }))
                        .map_err(render_err)?;
                }
            }
        }
        Ok(())
    }
}

/// Draw the figure of `record` with the diagnosis' descriptions `shapes` to `path` (see
/// [`ResidualWhereFigure`]).
pub fn residual_where_figure(
    record: &PlotRecord,
    shapes: Vec<ResidualShape>,
    title: Option<String>,
    path: &Path,
    size: Option<(u32, u32)>,
    force: bool,
) -> Result<(), PlotError> {
    save(
        &ResidualWhereFigure::new(record, shapes, title)?,
        path,
        size,
        force,
    )
}
