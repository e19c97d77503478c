//! # Zoo figure
//!
//! How a population of records was identified: per class of the plant zoo, the share of
//! outputs whose free-run test error 1 - R^2 is at most x, against x on a log scale (an
//! empirical distribution function; further left and higher is better), for the identifier,
//! the linear ARX baseline and the true plant (the ceiling that the measurement noise sets).
//! Dashed lines mark R^2 = 0.99 and 0.999. A diverged free run never counts as reached.

use super::axes::{self, legend, legend_line};
use super::render::{render_err, save, Figure};
use super::style;
use super::PlotError;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// The smallest error drawn: 1 - R^2 below it is drawn at it.
const FLOOR: f64 = 1e-6;

/// One class of records: the free-run test R^2 of each output (`None`: diverged), per model.
#[derive(Debug, Clone, PartialEq)]
pub struct ZooClassCurves {
    pub class: String,
    /// (model name, R^2 per output).
    pub models: Vec<(String, Vec<Option<f64>>)>,
}

/// The distribution of 1 - R^2 per class.
pub struct ZooFigure {
    pub classes: Vec<ZooClassCurves>,
    pub title: Option<String>,
}

/// The step curve of the empirical distribution of log10(1 - R^2): (x, share) corners.
fn ecdf(r2: &[Option<f64>]) -> Vec<(f64, f64)> {
    let n = r2.len().max(1) as f64;
    let mut x: Vec<f64> = r2
        .iter()
        .filter_map(|v| *v)
        .map(|v| (1.0 - v).max(FLOOR).log10())
        .collect();
    x.sort_by(f64::total_cmp);
    let mut pts = vec![(FLOOR.log10(), 0.0)];
    for (i, &v) in x.iter().enumerate() {
        pts.push((v, i as f64 / n));
        pts.push((v, (i + 1) as f64 / n));
    }
    let last = pts.last().map_or(0.0, |p| p.1);
    pts.push((1.0, last));
    pts
}

impl Figure for ZooFigure {
    fn default_size(&self) -> (u32, u32) {
        let (c, r) = axes::grid(self.classes.len());
        (560 * c as u32 + 40, 80 + 460 * r as u32)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let title = self.title.clone().unwrap_or_else(|| {
            "Free-run test error per class: share of outputs with 1 - R² <= x".to_string()
        });
        let body = axes::titled(root, &title)?;
        let (c, r) = axes::grid(self.classes.len());
        let areas = body.split_evenly((r, c));
        for (area, cl) in areas.iter().zip(&self.classes) {
            let n = cl.models.first().map_or(0, |m| m.1.len());
            let caption = format!("{} ({n} outputs)", cl.class);
            let mut chart = axes::chart(
                area,
                &caption,
                (FLOOR.log10(), 1.0),
                (0.0, 1.02),
                "log10(1 - R²)",
                "share of outputs",
            )?;
            for x in [-2.0, -3.0] {
                chart
                    .draw_series(DashedLineSeries::new(
                        vec![(x, 0.0), (x, 1.02)],
                        style::px(6),
                        style::px(4),
                        BLACK.mix(0.45).stroke_width(style::px(1)),
                    ))
                    .map_err(render_err)?;
            }
            for (i, (name, r2)) in cl.models.iter().enumerate() {
                let colour = style::series_colour(i);
                chart
                    .draw_series(axes::path_elements(
                        ecdf(r2),
                        colour.stroke_width(style::px(style::LINE_WIDTH)),
                    ))
                    .map_err(render_err)?
                    .label(name.as_str())
                    .legend(legend_line(colour));
            }
            legend(&mut chart, SeriesLabelPosition::LowerRight)?;
        }
        Ok(())
    }
}

/// Draw a [`ZooFigure`] to `path`.
pub fn zoo_figure(classes: Vec<ZooClassCurves>, path: &Path, force: bool) -> Result<(), PlotError> {
    save(
        &ZooFigure {
            classes,
            title: None,
        },
        path,
        None,
        force,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_distribution_counts_diverged_runs_as_never_reached() {
        let e = ecdf(&[Some(0.999), None, Some(0.99)]);
        assert_eq!(e.last().unwrap().1, 2.0 / 3.0);
        assert!(
            (e[1].0 - (-3.0)).abs() < 1e-9 && (e[3].0 - (-2.0)).abs() < 1e-9,
            "{e:?}"
        );
        // a perfect fit is drawn at the floor
        assert_eq!(ecdf(&[Some(1.0)])[1].0, FLOOR.log10());
    }
}
