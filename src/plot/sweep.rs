//! # Sweep heat maps
//!
//! Free-run test R^2 of a NARX hyper-parameter sweep over lags (x) and neurons (y), one heat map
//! per (output, learning rate, batch size): rows are (output, lr), columns batch sizes. Each cell
//! shows the R^2 and the training time; several runs of a setting (seeds, epochs) are summarised
//! by the median R^2 of the runs that did not diverge and the median training time. A setting
//! whose runs all diverged is drawn in a distinct grey marked "diverged"; if only some diverged,
//! the cell says how many. A setting without a run is white with a dash.
//!
//! ## `results.csv` (written by the sweep)
//! Header `output,lags,neurons,lr,batch,epochs,seed,r2_osa_train,r2_fr_train,r2_osa_test,
//! r2_fr_test,rmse_fr_test,diverged,train_seconds`. Of these this figure needs `output, lags,
//! neurons, lr, batch, r2_fr_test, diverged, train_seconds`; `r2_fr_test` is empty exactly when
//! `diverged` is 1.

use super::axes::{self, colour_bar};
use super::render::{render_err, save, Figure};
use super::style::{self, viridis, FONT};
use super::table::Table;
use super::PlotError;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// The columns a sweep figure reads.
pub const SWEEP_COLUMNS: [&str; 8] = [
    "output",
    "lags",
    "neurons",
    "lr",
    "batch",
    "r2_fr_test",
    "diverged",
    "train_seconds",
];

/// One run of a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRow {
    pub output: String,
    pub lags: u64,
    pub neurons: u64,
    pub lr: f64,
    pub batch: u64,
    /// Free-run test R^2; `None` when the free run diverged.
    pub r2_fr_test: Option<f64>,
    pub diverged: bool,
    pub train_seconds: f64,
}

/// Read a sweep's `results.csv` (empty `r2_fr_test` cells allowed only on diverged rows).
pub fn read_sweep(path: &Path) -> Result<Vec<SweepRow>, PlotError> {
    let t = Table::read(path, &SWEEP_COLUMNS)?;
    let mut rows = Vec::with_capacity(t.rows.len());
    for r in 0..t.rows.len() {
        let diverged = t.flag(r, "diverged")?;
        let r2 = t.number_or_empty(r, "r2_fr_test")?;
        if r2.is_none() && !diverged {
            return Err(t.error(
                r,
                "r2_fr_test",
                "missing value (empty cell) on a row with diverged=0; only diverged runs may leave it empty",
            ));
        }
        let output = t.text(r, "output").to_string();
        if output.is_empty() {
            return Err(t.error(r, "output", "missing output name"));
        }
        rows.push(SweepRow {
            output,
            lags: t.whole(r, "lags")?,
            neurons: t.whole(r, "neurons")?,
            lr: t.number(r, "lr")?,
            batch: t.whole(r, "batch")?,
            r2_fr_test: if diverged { None } else { r2 },
            diverged,
            train_seconds: t.number(r, "train_seconds")?,
        });
    }
    Ok(rows)
}

fn distinct<T: PartialOrd + Clone>(it: impl Iterator<Item = T>) -> Vec<T> {
    let mut v: Vec<T> = Vec::new();
    for x in it {
        if !v.contains(&x) {
            v.push(x);
        }
    }
    v.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
    v
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// Summary of the runs of one setting.
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    pub r2: Option<f64>,
    pub runs: usize,
    pub diverged: usize,
    pub seconds: f64,
}

/// Heat maps of a sweep.
pub struct SweepFigure {
    pub rows: Vec<SweepRow>,
    pub title: Option<String>,
    outputs: Vec<String>,
    lrs: Vec<f64>,
    batches: Vec<u64>,
    lags: Vec<u64>,
    neurons: Vec<u64>,
}

impl SweepFigure {
    /// Heat maps of `rows`, restricted to `output` when given.
    pub fn new(
        rows: Vec<SweepRow>,
        output: Option<&str>,
        title: Option<String>,
    ) -> Result<Self, PlotError> {
        let all = distinct(rows.iter().map(|r| r.output.clone()));
        let rows: Vec<SweepRow> = match output {
            Some(o) => rows.into_iter().filter(|r| r.output == o).collect(),
            None => rows,
        };
        if rows.is_empty() {
            return Err(PlotError::Invalid {
                what: "sweep figure".into(),
                problem: format!(
                    "no run of output `{}`; the outputs are: {}",
                    output.unwrap_or(""),
                    all.join(", ")
                ),
            });
        }
        Ok(SweepFigure {
            outputs: distinct(rows.iter().map(|r| r.output.clone())),
            lrs: distinct(rows.iter().map(|r| r.lr)),
            batches: distinct(rows.iter().map(|r| r.batch)),
            lags: distinct(rows.iter().map(|r| r.lags)),
            neurons: distinct(rows.iter().map(|r| r.neurons)),
            rows,
            title,
        })
    }

    /// The summary of one setting, if it ran.
    pub fn cell(&self, output: &str, lr: f64, batch: u64, lags: u64, neurons: u64) -> Option<Cell> {
        let runs: Vec<&SweepRow> = self
            .rows
            .iter()
            .filter(|r| {
                r.output == output
                    && r.lr == lr
                    && r.batch == batch
                    && r.lags == lags
                    && r.neurons == neurons
            })
            .collect();
        if runs.is_empty() {
            return None;
        }
        Some(Cell {
            r2: median(runs.iter().filter_map(|r| r.r2_fr_test).collect()),
            runs: runs.len(),
            diverged: runs.iter().filter(|r| r.diverged).count(),
            seconds: median(runs.iter().map(|r| r.train_seconds).collect()).unwrap_or(0.0),
        })
    }

    fn panels(&self) -> (usize, usize) {
        (self.batches.len(), self.outputs.len() * self.lrs.len())
    }

    fn colour_range(&self) -> (f64, f64) {
        let v: Vec<f64> = self
            .rows
            .iter()
            .filter_map(|r| r.r2_fr_test)
            .map(|v| v.max(-1.0))
            .collect();
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if !lo.is_finite() {
            (0.0, 1.0)
        } else if hi - lo < 1e-6 {
            (lo - 0.05, hi + 0.05)
        } else {
            (lo, hi)
        }
    }
}

fn fmt_seconds(s: f64) -> String {
    if s >= 100.0 {
        format!("{s:.0} s")
    } else if s >= 1.0 {
        format!("{s:.1} s")
    } else {
        format!("{s:.2} s")
    }
}

fn lr_label(lr: f64) -> String {
    if (1e-3..1e3).contains(&lr) {
        format!("{lr}")
    } else {
        format!("{lr:e}")
    }
}

impl Figure for SweepFigure {
    fn default_size(&self) -> (u32, u32) {
        let (c, r) = self.panels();
        let cw = (110 * self.lags.len() as u32 + 200).clamp(600, 1400);
        let ch = (80 * self.neurons.len() as u32 + 180).clamp(450, 1200);
        (cw * c as u32 + 170, ch * r as u32 + 60)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let title = self
            .title
            .clone()
            .unwrap_or_else(|| "NARX sweep: free-run test R² over lags and neurons".to_string());
        let body = axes::titled(root, &title)?;
        let w = body.dim_in_pixel().0;
        let (main, bar) = body.split_horizontally(w.saturating_sub(style::px(170)));
        let (lo, hi) = self.colour_range();
        colour_bar(&bar, lo, hi, "free-run test R²")?;
        let (cols, rows) = self.panels();
        let areas = main.split_evenly((rows, cols));
        let mut a = 0;
        for out in &self.outputs {
            for &lr in &self.lrs {
                for &batch in &self.batches {
                    self.draw_panel(&areas[a], out, lr, batch, (lo, hi))?;
                    a += 1;
                }
            }
        }
        Ok(())
    }
}

impl SweepFigure {
    /// One heat map: free-run test R^2 over lags (x) and neurons (y) for one output, learning
    /// rate and batch size.
    fn draw_panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        out: &str,
        lr: f64,
        batch: u64,
        (lo, hi): (f64, f64),
    ) -> Result<(), PlotError> {
        let (nx, ny) = (self.lags.len(), self.neurons.len());
        let (pw, ph) = area.dim_in_pixel();
        let cell_w = (pw.saturating_sub(style::px(150))) / nx.max(1) as u32;
        let cell_h = (ph.saturating_sub(style::px(160))) / ny.max(1) as u32;
        let text_size = (cell_w / 5)
            .min(cell_h / 3)
            .clamp(style::px(10), style::px(22));
        let mut caption = format!("lr = {}, batch = {batch}", lr_label(lr));
        if self.outputs.len() > 1 {
            caption = format!("{out}: {caption}");
        }
        let mut chart = ChartBuilder::on(area)
            .margin(style::px(16))
            .margin_right(style::px(24))
            .caption(caption, (FONT, style::px(style::CAPTION_SIZE)))
            .x_label_area_size(style::px(70))
            .y_label_area_size(style::px(90))
            .build_cartesian_2d(
                (0..nx as i32 - 1).into_segmented(),
                (0..ny as i32 - 1).into_segmented(),
            )
            .map_err(render_err)?;
        let lags = &self.lags;
        let neurons = &self.neurons;
        let xf = |v: &SegmentValue<i32>| match v {
            SegmentValue::CenterOf(i) => {
                lags.get(*i as usize).map_or(String::new(), u64::to_string)
            }
            _ => String::new(),
        };
        let yf = |v: &SegmentValue<i32>| match v {
            SegmentValue::CenterOf(i) => neurons
                .get(*i as usize)
                .map_or(String::new(), u64::to_string),
            _ => String::new(),
        };
        chart
            .configure_mesh()
            .disable_mesh()
            .axis_style(BLACK.stroke_width(style::px(1)))
            .set_all_tick_mark_size(style::px(6))
            .x_labels(nx + 1)
            .y_labels(ny + 1)
            .x_label_formatter(&xf)
            .y_label_formatter(&yf)
            .label_style((FONT, style::px(style::TICK_SIZE)))
            .axis_desc_style((FONT, style::px(style::LABEL_SIZE)))
            .x_desc("lags")
            .y_desc("neurons")
            .draw()
            .map_err(render_err)?;
        for (ix, &lg) in self.lags.iter().enumerate() {
            for (iy, &nn) in self.neurons.iter().enumerate() {
                let (fill, line1, line2) = cell_look(self.cell(out, lr, batch, lg, nn), lo, hi);
                let (x0, y0) = (
                    SegmentValue::Exact(ix as i32),
                    SegmentValue::Exact(iy as i32),
                );
                let (x1, y1) = (
                    SegmentValue::Exact(ix as i32 + 1),
                    SegmentValue::Exact(iy as i32 + 1),
                );
                chart
                    .draw_series([
                        Rectangle::new(
                            [(x0.clone(), y0.clone()), (x1.clone(), y1.clone())],
                            fill.filled(),
                        ),
                        Rectangle::new([(x0, y0), (x1, y1)], WHITE.stroke_width(style::px(2))),
                    ])
                    .map_err(render_err)?;
                let light = (fill.0 as u32 + fill.1 as u32 + fill.2 as u32) > 3 * 150;
                let tc = if light { BLACK } else { WHITE };
                let centre = (
                    SegmentValue::CenterOf(ix as i32),
                    SegmentValue::CenterOf(iy as i32),
                );
                let st = (FONT, text_size)
                    .into_font()
                    .color(&tc)
                    .pos(Pos::new(HPos::Center, VPos::Center));
                let st2 = (FONT, (text_size * 3 / 4).max(style::px(10)))
                    .into_font()
                    .color(&tc)
                    .pos(Pos::new(HPos::Center, VPos::Center));
                let dy = (text_size as i32 * 2) / 3;
                chart
                    .draw_series(std::iter::once(
                        EmptyElement::at(centre)
                            + Text::new(line1, (0, if line2.is_empty() { 0 } else { -dy }), st)
                            + Text::new(line2, (0, dy), st2),
                    ))
                    .map_err(render_err)?;
            }
        }
        Ok(())
    }
}

/// A cell's colour and its two text lines (R^2; time and diverged runs), for the colour range
/// `lo..hi`.
fn cell_look(cell: Option<Cell>, lo: f64, hi: f64) -> (RGBColor, String, String) {
    match cell {
        None => (style::MISSING, "–".to_string(), String::new()),
        Some(c) => match c.r2 {
            None => (
                style::DIVERGED,
                "diverged".to_string(),
                fmt_seconds(c.seconds),
            ),
            Some(r2) => {
                let x = (r2.max(-1.0) - lo) / (hi - lo);
                let mut l2 = fmt_seconds(c.seconds);
                if c.diverged > 0 {
                    l2 = format!("{l2}, {}/{} div.", c.diverged, c.runs);
                }
                (viridis(x), format!("{r2:.3}"), l2)
            }
        },
    }
}

/// Draw the heat maps of a sweep's `results.csv` to `path`.
pub fn sweep_figure(
    results: &Path,
    output: Option<&str>,
    title: Option<String>,
    path: &Path,
    size: Option<(u32, u32)>,
    force: bool,
) -> Result<(), PlotError> {
    let rows = read_sweep(results)?;
    save(&SweepFigure::new(rows, output, title)?, path, size, force)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_diverged_rows_and_summarises_cells() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("results.csv");
        std::fs::write(
            &p,
            "output,lags,neurons,lr,batch,epochs,seed,r2_osa_train,r2_fr_train,r2_osa_test,r2_fr_test,rmse_fr_test,diverged,train_seconds\n\
             y,2,10,0.01,32,100,1,0.99,0.98,0.99,0.97,0.1,0,3.0\n\
             y,2,10,0.01,32,100,2,0.99,,0.99,,,1,5.0\n\
             y,4,10,0.01,32,100,1,0.99,,0.99,,,1,4.0\n",
        )
        .unwrap();
        let rows = read_sweep(&p).unwrap();
        assert_eq!(rows.len(), 3);
        assert!(rows[1].diverged && rows[1].r2_fr_test.is_none());
        let f = SweepFigure::new(rows, None, None).unwrap();
        let c = f.cell("y", 0.01, 32, 2, 10).unwrap();
        assert_eq!(
            (c.r2, c.runs, c.diverged, c.seconds),
            (Some(0.97), 2, 1, 4.0)
        );
        let c = f.cell("y", 0.01, 32, 4, 10).unwrap();
        assert_eq!(c.r2, None);
        assert!(f.cell("y", 0.01, 32, 3, 10).is_none());
    }

    #[test]
    fn an_empty_r2_on_a_converged_row_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("results.csv");
        std::fs::write(
            &p,
            "output,lags,neurons,lr,batch,r2_fr_test,diverged,train_seconds\ny,2,10,0.01,32,,0,3\n",
        )
        .unwrap();
        let e = read_sweep(&p).unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("r2_fr_test"), "{e}");
        std::fs::write(&p, "output,lags,neurons,lr\ny,2,10,0.01\n").unwrap();
        let e = read_sweep(&p).unwrap_err().to_string();
        assert!(e.contains("no column `batch`"), "{e}");
    }
}
