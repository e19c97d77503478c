//! # Hysteresis loop figure
//!
//! Output against input, one panel per (output, input) pair: for a SISO record one loop, for a
//! 2-DoF record the direct loops u1->y1, u2->y2 and the cross loops u2->y1, u1->y2 (rows are
//! outputs, columns inputs). Several records are overlaid in palette colours; a model's
//! prediction (`<output>_hat`) is drawn over the measurement. The measurement can be coloured by
//! time or by cycle (input reversals / 2), with a colour bar, so minor loops can be told apart.
//! A prediction band (`<output>_lo`, `<output>_hi`) is drawn under the model's loop as vertical
//! strokes (at up to [`BAND_STROKES`] samples, turning points kept), from the band's lower edge
//! to its upper, in the model's colour: the strokes shade the region the band says the loop
//! lies in.
//!
//! Long records are decimated with [`decimate`](super::decimate::decimate): turning points and
//! per-bucket extremes are always kept.
//!
//! ## References
//! - I. D. Mayergoyz, *Mathematical Models of Hysteresis and their Applications*, Elsevier 2003
//!   (major and minor loops, return-point memory).

use super::axes::{self, colour_bar, legend, legend_line};
use super::decimate::decimate;
use super::render::{render_err, save, Figure};
use super::source::{cycle_index, PlotRecord};
use super::style::{self, viridis, PANEL};
use super::PlotError;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// How the measured loop is coloured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LoopColour {
    /// By time, along viridis, with a colour bar in seconds.
    Time,
    /// By cycle number (input reversals / 2), with a colour bar.
    Cycle,
    /// One solid colour per series, with a legend.
    Series,
}

/// Options of a loop figure.
#[derive(Debug, Clone)]
pub struct LoopOptions {
    /// Figure title; a default naming the record is used when `None`.
    pub title: Option<String>,
    /// Colouring; `None` picks `Time` for a single record without prediction, else `Series`.
    pub colour: Option<LoopColour>,
    /// Points drawn per series at most (before turning points are added).
    pub max_points: usize,
    /// Also draw the cross loops (input j against output i, j != i) of a MIMO record.
    pub cross: bool,
}

impl Default for LoopOptions {
    fn default() -> Self {
        LoopOptions {
            title: None,
            colour: None,
            max_points: 40_000,
            cross: true,
        }
    }
}

/// A loop figure of one or more records.
pub struct LoopFigure<'a> {
    pub records: &'a [PlotRecord],
    pub options: &'a LoopOptions,
    panels: Vec<(usize, usize)>,
    cols: usize,
    rows: usize,
}

impl<'a> LoopFigure<'a> {
    /// Check the records (same numbers of inputs and outputs, at least 2 samples each).
    pub fn new(records: &'a [PlotRecord], options: &'a LoopOptions) -> Result<Self, PlotError> {
        let first = records.first().ok_or_else(|| PlotError::Invalid {
            what: "loop figure".into(),
            problem: "no record given".into(),
        })?;
        for r in records {
            r.require_len(2, "loop")?;
            if r.io.inputs.len() != first.io.inputs.len()
                || r.io.outputs.len() != first.io.outputs.len()
            {
                return Err(PlotError::Invalid {
                    what: format!("{}", r.io.path.display()),
                    problem: format!(
                        "has {} inputs and {} outputs, but {} has {} and {}; overlaid records need the same shape",
                        r.io.inputs.len(),
                        r.io.outputs.len(),
                        first.io.path.display(),
                        first.io.inputs.len(),
                        first.io.outputs.len()
                    ),
                });
            }
        }
        let (ni, no) = (first.io.inputs.len(), first.io.outputs.len());
        let (panels, cols, rows) = if options.cross || ni == 1 {
            let p = (0..no).flat_map(|i| (0..ni).map(move |j| (i, j))).collect();
            (p, ni, no)
        } else {
            let p: Vec<_> = (0..no).map(|i| (i, i.min(ni - 1))).collect();
            let (c, r) = axes::grid(p.len());
            (p, c, r)
        };
        Ok(LoopFigure {
            records,
            options,
            panels,
            cols,
            rows,
        })
    }

    fn colour(&self) -> LoopColour {
        self.options.colour.unwrap_or(
            if self.records.len() == 1 && !self.records[0].has_predictions() {
                LoopColour::Time
            } else {
                LoopColour::Series
            },
        )
    }

    fn title(&self) -> String {
        if let Some(t) = &self.options.title {
            return t.clone();
        }
        let r = &self.records[0];
        let names: Vec<&str> = self.records.iter().map(|r| r.label.as_str()).collect();
        if r.io.inputs.len() == 1 && r.io.outputs.len() == 1 {
            let q = |n: &str| r.quantity(n).name;
            format!(
                "Hysteresis loop: {} vs {} ({})",
                q(&r.io.outputs[0].name),
                q(&r.io.inputs[0].name),
                names.join(", ")
            )
        } else {
            format!("Hysteresis loops ({})", names.join(", "))
        }
    }
}

/// Colour levels used for the time gradient.
const TIME_LEVELS: usize = 96;

/// The band's vertical strokes per record at most (turning points and extremes kept): enough
/// to shade the loop's band, few enough to draw fast.
const BAND_STROKES: usize = 4000;

impl Figure for LoopFigure<'_> {
    fn default_size(&self) -> (u32, u32) {
        let bar = if self.colour() == LoopColour::Series {
            0
        } else {
            150
        };
        let (w, h) = if self.panels.len() == 1 {
            (PANEL.0 - 60, PANEL.1 + 40)
        } else {
            PANEL
        };
        (w * self.cols as u32 + bar, h * self.rows as u32 + 60)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let body = axes::titled(root, &self.title())?;
        let colour = self.colour();
        let rec0 = &self.records[0];
        let cycles = match colour {
            LoopColour::Cycle => Some(cycle_index(&rec0.io.inputs[0].values)),
            _ => None,
        };
        let body = if colour == LoopColour::Series {
            body
        } else {
            let w = body.dim_in_pixel().0;
            let (main, bar) = body.split_horizontally(w.saturating_sub(style::px(150)));
            match &cycles {
                Some(c) => colour_bar(&bar, 0.0, c.last().copied().unwrap_or(0) as f64, "cycle")?,
                None => colour_bar(
                    &bar,
                    rec0.time(0),
                    rec0.time(rec0.len() - 1),
                    &style::time_label(&rec0.io.time_name),
                )?,
            }
            main
        };
        let areas = body.split_evenly((self.rows, self.cols));
        for (area, &(i, j)) in areas.iter().zip(&self.panels) {
            self.draw_panel(area, i, j, colour, cycles.as_deref())?;
        }
        Ok(())
    }
}

impl LoopFigure<'_> {
    /// The panel's axis ranges: every record's input `j` and output `i` (and its model), padded.
    fn panel_ranges(&self, i: usize, j: usize) -> ((f64, f64), (f64, f64)) {
        let mut xr = (f64::INFINITY, f64::NEG_INFINITY);
        let mut yr = xr;
        for r in self.records {
            xr = axes::union(xr, axes::padded_range(&r.io.inputs[j].values, 0.04));
            yr = axes::union(yr, axes::padded_range(&r.io.outputs[i].values, 0.04));
            if let Some(p) = &r.predicted[i] {
                yr = axes::union(yr, axes::padded_range(p, 0.04));
                if let Some(h) = &r.band[i] {
                    let edges: Vec<f64> =
                        p.iter().zip(h).flat_map(|(c, h)| [c - h, c + h]).collect();
                    yr = axes::union(yr, axes::padded_range(&edges, 0.04));
                }
            }
        }
        (xr, yr)
    }

    /// "direct: u1 → y1" / "cross: u2 → y1" on a figure of several panels; none on one.
    fn panel_caption(&self, i: usize, j: usize) -> String {
        if self.panels.len() <= 1 {
            return String::new();
        }
        let io = &self.records[0].io;
        let kind = if io.inputs.len() > 1 && i == j {
            "direct: "
        } else if io.inputs.len() > 1 {
            "cross: "
        } else {
            ""
        };
        format!("{kind}{} → {}", io.inputs[j].name, io.outputs[i].name)
    }

    /// Each record's measurement colour and model colour (`None`: no prediction), the series
    /// numbered in the order they are drawn; a record's model keeps its colour in every
    /// panel, predicted there or not. (The first record's measurement is drawn along viridis
    /// unless `colour` is `Series`; it still takes its number.)
    fn series_colours(&self, colour: LoopColour) -> Vec<(RGBColor, Option<RGBColor>)> {
        let mut n_series = 0;
        let mut next = || {
            n_series += 1;
            style::series_colour(n_series - 1)
        };
        self.records
            .iter()
            .enumerate()
            .map(|(ri, r)| {
                let measured = next();
                let model = r.has_predictions().then(|| {
                    if colour == LoopColour::Series {
                        next()
                    } else {
                        style::PALETTE[1 + ri % (style::PALETTE.len() - 1)]
                    }
                });
                (measured, model)
            })
            .collect()
    }

    fn draw_panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        i: usize,
        j: usize,
        colour: LoopColour,
        cycles: Option<&[u32]>,
    ) -> Result<(), PlotError> {
        let rec0 = &self.records[0];
        let (uname, yname) = (&rec0.io.inputs[j].name, &rec0.io.outputs[i].name);
        let (xr, yr) = self.panel_ranges(i, j);
        let mut chart = axes::chart(
            area,
            &self.panel_caption(i, j),
            xr,
            yr,
            &rec0.quantity(uname).label(),
            &rec0.quantity(yname).label(),
        )?;
        let mut labelled = 0;
        let colours = self.series_colours(colour);
        // the bands first, under every line
        let several = self.records.len() > 1;
        for (r, (_, c)) in self.records.iter().zip(&colours) {
            let (Some(p), Some(h), Some(c)) = (&r.predicted[i], &r.band[i], c) else {
                continue;
            };
            let u = &r.io.inputs[j].values;
            let idx = decimate(&[u, p], 0..r.len(), BAND_STROKES);
            let shade = c.mix(0.25);
            chart
                .draw_series(idx.iter().map(|&k| {
                    PathElement::new(
                        vec![(u[k], p[k] - h[k]), (u[k], p[k] + h[k])],
                        shade.stroke_width(style::px(2)),
                    )
                }))
                .map_err(render_err)?
                .label(if several {
                    format!("{} band (95 %)", r.label)
                } else {
                    "prediction band (95 %)".to_string()
                })
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 4), (x + 16, y + 4)], shade.filled())
                });
            labelled += 1;
        }
        for (ri, (r, &(measured, model))) in self.records.iter().zip(&colours).enumerate() {
            let u = &r.io.inputs[j].values;
            let y = &r.io.outputs[i].values;
            let pred = r.predicted[i].as_deref();
            let mut sigs: Vec<&[f64]> = vec![u, y];
            if let Some(p) = pred {
                sigs.push(p);
            }
            let idx = decimate(&sigs, 0..r.len(), self.options.max_points);
            let any_model = self.records.iter().any(PlotRecord::has_predictions);
            let label = match (self.records.len() > 1, any_model) {
                (true, true) => format!("{} measured", r.label),
                (true, false) => r.label.clone(),
                (false, _) => "measured".to_string(),
            };
            if ri == 0 && colour != LoopColour::Series {
                let (chunks, top) = coloured_by_level(u, y, &idx, cycles);
                chart
                    .draw_series(chunks.into_iter().flat_map(|(l, pts)| {
                        axes::path_elements(
                            pts,
                            viridis(l as f64 / top).stroke_width(style::px(style::LINE_WIDTH)),
                        )
                    }))
                    .map_err(render_err)?
                    .label(label)
                    .legend(legend_line(viridis(0.5)));
                labelled += 1;
            } else {
                chart
                    .draw_series(axes::path_elements(
                        idx.iter().map(|&k| (u[k], y[k])).collect::<Vec<_>>(),
                        measured.stroke_width(style::px(style::LINE_WIDTH)),
                    ))
                    .map_err(render_err)?
                    .label(label)
                    .legend(legend_line(measured));
                labelled += 1;
            }
            if let (Some(p), Some(c)) = (pred, model) {
                let label = if self.records.len() > 1 {
                    format!("{} model", r.label)
                } else {
                    "model".to_string()
                };
                chart
                    .draw_series(axes::path_elements(
                        idx.iter().map(|&k| (u[k], p[k])).collect::<Vec<_>>(),
                        c.stroke_width(style::px(style::LINE_WIDTH)),
                    ))
                    .map_err(render_err)?
                    .label(label)
                    .legend(legend_line(c));
                labelled += 1;
            }
        }
        if labelled > 1 {
            legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
        }
        Ok(())
    }
}

/// A colour level and the loop points drawn in it.
type LevelRun = (usize, Vec<(f64, f64)>);

/// The loop's points (decimated to `idx`) cut into runs of one colour level (the time decile,
/// or the cycle number when `cycles` is given), each run starting at the previous one's last
/// point; and the top level.
fn coloured_by_level(
    u: &[f64],
    y: &[f64],
    idx: &[usize],
    cycles: Option<&[u32]>,
) -> (Vec<LevelRun>, f64) {
    let n = u.len();
    let level = |k: usize| -> usize {
        match cycles {
            Some(c) => c[k] as usize,
            None => k * TIME_LEVELS / n,
        }
    };
    let top = match cycles {
        Some(c) => c.last().copied().unwrap_or(0).max(1) as f64,
        None => (TIME_LEVELS - 1) as f64,
    };
    let mut chunks: Vec<LevelRun> = Vec::new();
    let mut prev: Option<(f64, f64)> = None;
    for &k in idx {
        let p = (u[k], y[k]);
        let l = level(k);
        match chunks.last_mut() {
            Some((cl, pts)) if *cl == l => pts.push(p),
            _ => {
                let mut pts = Vec::new();
                if let Some(q) = prev {
                    pts.push(q);
                }
                pts.push(p);
                chunks.push((l, pts));
            }
        }
        prev = Some(p);
    }
    (chunks, top)
}

/// Draw a loop figure of `records` to `path` (`.png` or `.svg`), atomically; an existing file is
/// replaced only with `force`. This is the entry point for commands that write figures beside
/// their reports.
///
/// ```no_run
/// use hystbench::plot::{loop_figure, LoopOptions, PlotRecord};
/// let rec = PlotRecord::load("data.csv".as_ref(), None, None)?;
/// loop_figure(&[rec], &LoopOptions::default(), "loop.png".as_ref(), None, false)?;
/// # Ok::<(), hystbench::plot::PlotError>(())
/// ```
pub fn loop_figure(
    records: &[PlotRecord],
    options: &LoopOptions,
    path: &Path,
    size: Option<(u32, u32)>,
    force: bool,
) -> Result<(), PlotError> {
    save(&LoopFigure::new(records, options)?, path, size, force)
}
