//! # Ladder figure
//!
//! The model-improvement loop's error after each step: one bar per step on a log RMSE axis,
//! labelled with the effect the step added, the RMSE above the bar and the R^2 inside it.
//!
//! ## `ladder.csv`
//! Header `step,effects,rmse,r2`, one row per step in the order the effects were added:
//! - `step`: 0, 1, 2, … (whole number; rows are drawn sorted by it);
//! - `effects`: the effects in the model after the step, joined by `+`, e.g. `hysteresis`,
//!   `hysteresis+creep`, `hysteresis+creep+dynamics` (names as [`crate::effect::EffectName`];
//!   step 0 may be a baseline such as `linear`);
//! - `rmse`: the error of that model on the test data (free run), > 0, in the output's unit;
//! - `r2`: its R^2 on the same data; may be empty when undefined.
//!
//! Example:
//! ```text
//! step,effects,rmse,r2
//! 0,linear,2.31,0.912
//! 1,linear+hysteresis,0.42,0.9971
//! 2,linear+hysteresis+creep,0.18,0.9995
//! ```

use super::axes;
use super::render::{render_err, save, Figure};
use super::style::{self, fmt_num, FONT};
use super::table::Table;
use super::PlotError;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// One step of the model-improvement loop.
#[derive(Debug, Clone, PartialEq)]
pub struct LadderStep {
    pub step: u64,
    pub effects: Vec<String>,
    pub rmse: f64,
    pub r2: Option<f64>,
}

impl LadderStep {
    /// What this step added to `previous` (its effects not in `previous`), `+`-joined.
    pub fn added(&self, previous: Option<&LadderStep>) -> String {
        match previous {
            None => self.effects.join("+"),
            Some(p) => {
                let new: Vec<&str> = self
                    .effects
                    .iter()
                    .filter(|e| !p.effects.contains(e))
                    .map(String::as_str)
                    .collect();
                if new.is_empty() {
                    "(refit)".to_string()
                } else {
                    format!("+{}", new.join("+"))
                }
            }
        }
    }
}

/// Read a `ladder.csv` (see the module documentation for the schema).
pub fn read_ladder(path: &Path) -> Result<Vec<LadderStep>, PlotError> {
    let t = Table::read(path, &["step", "effects", "rmse", "r2"])?;
    let mut steps = Vec::new();
    for r in 0..t.rows.len() {
        let effects: Vec<String> = t
            .text(r, "effects")
            .split('+')
            .map(|s| s.trim().to_string())
            .filter(|s| !s.is_empty())
            .collect();
        if effects.is_empty() {
            return Err(t.error(
                r,
                "effects",
                "no effect named; write e.g. `hysteresis+creep`",
            ));
        }
        let rmse = t.number(r, "rmse")?;
        if rmse <= 0.0 {
            return Err(t.error(
                r,
                "rmse",
                format!("{rmse} is not > 0 (the axis is logarithmic)"),
            ));
        }
        steps.push(LadderStep {
            step: t.whole(r, "step")?,
            effects,
            rmse,
            r2: t.number_or_empty(r, "r2")?,
        });
    }
    steps.sort_by_key(|s| s.step);
    Ok(steps)
}

/// Bars of the error after each step.
pub struct LadderFigure {
    pub steps: Vec<LadderStep>,
    pub title: Option<String>,
}

impl Figure for LadderFigure {
    fn default_size(&self) -> (u32, u32) {
        ((260 * self.steps.len() as u32 + 300).clamp(800, 2400), 760)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let title = self
            .title
            .clone()
            .unwrap_or_else(|| "Model improvement: error after each added effect".to_string());
        let body = axes::titled(root, &title)?;
        let n = self.steps.len();
        let lo = self
            .steps
            .iter()
            .map(|s| s.rmse)
            .fold(f64::INFINITY, f64::min);
        let hi = self.steps.iter().map(|s| s.rmse).fold(0.0, f64::max);
        let (y0, y1) = (lo / 3.0, hi * 3.0);
        let labels: Vec<String> = (0..n)
            .map(|i| {
                let prev = if i == 0 {
                    None
                } else {
                    Some(&self.steps[i - 1])
                };
                self.steps[i].added(prev)
            })
            .collect();
        let mut chart = ChartBuilder::on(&body)
            .margin(style::px(16))
            .margin_right(style::px(48))
            .x_label_area_size(style::px(80))
            .y_label_area_size(style::px(110))
            .build_cartesian_2d((0..n as i32 - 1).into_segmented(), (y0..y1).log_scale())
            .map_err(render_err)?;
        let xf = |v: &SegmentValue<i32>| match v {
            SegmentValue::CenterOf(i) => labels.get(*i as usize).cloned().unwrap_or_default(),
            _ => String::new(),
        };
        let yf = |v: &f64| axes::tick(*v, *v);
        chart
            .configure_mesh()
            .disable_x_mesh()
            .bold_line_style(style::GRID_MAJOR.stroke_width(style::px(1)))
            .light_line_style(style::GRID_MINOR.stroke_width(style::px(1)))
            .axis_style(BLACK.stroke_width(style::px(1)))
            .set_all_tick_mark_size(style::px(6))
            .x_labels(n + 1)
            .y_labels(8)
            .x_label_formatter(&xf)
            .y_label_formatter(&yf)
            .label_style((FONT, style::px(style::TICK_SIZE)))
            .axis_desc_style((FONT, style::px(style::LABEL_SIZE)))
            .x_desc("effect added at each step")
            .y_desc("RMSE (log scale)")
            .draw()
            .map_err(render_err)?;
        for (i, s) in self.steps.iter().enumerate() {
            let c = style::series_colour(i);
            let mut bar = Rectangle::new(
                [
                    (SegmentValue::Exact(i as i32), y0),
                    (SegmentValue::Exact(i as i32 + 1), s.rmse),
                ],
                c.mix(0.85).filled(),
            );
            bar.set_margin(0, 0, style::px(24), style::px(24));
            chart
                .draw_series(std::iter::once(bar))
                .map_err(render_err)?;
            let top = (FONT, style::px(style::LEGEND_SIZE))
                .into_font()
                .color(&BLACK)
                .pos(Pos::new(HPos::Center, VPos::Bottom));
            let mut text = format!("RMSE {}", fmt_num(s.rmse));
            if let Some(r2) = s.r2 {
                text = format!("{text}, R² {}", fmt_num(r2));
            }
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((SegmentValue::CenterOf(i as i32), s.rmse))
                        + Text::new(text, (0, style::pxi(-8)), top),
                ))
                .map_err(render_err)?;
        }
        Ok(())
    }
}

/// Draw the ladder of `ladder_csv` to `path`.
pub fn ladder_figure(
    ladder_csv: &Path,
    title: Option<String>,
    path: &Path,
    size: Option<(u32, u32)>,
    force: bool,
) -> Result<(), PlotError> {
    let steps = read_ladder(ladder_csv)?;
    save(&LadderFigure { steps, title }, path, size, force)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_and_names_the_added_effect() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ladder.csv");
        std::fs::write(
            &p,
            "step,effects,rmse,r2\n1,hysteresis+creep,0.2,0.99\n0,hysteresis,1.5,\n",
        )
        .unwrap();
        let s = read_ladder(&p).unwrap();
        assert_eq!(s[0].step, 0);
        assert_eq!(s[0].r2, None);
        assert_eq!(s[1].added(Some(&s[0])), "+creep");
        assert_eq!(s[0].added(None), "hysteresis");
        std::fs::write(&p, "step,effects,rmse,r2\n0,hysteresis,0,\n").unwrap();
        assert!(read_ladder(&p).unwrap_err().to_string().contains("not > 0"));
    }
}
