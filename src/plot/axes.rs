//! Axes shared by every figure: padded ranges, a chart with caption, mesh, readable tick labels
//! and axis descriptions, a legend box and a colour bar.

use super::render::render_err;
use super::style::{self, FONT};
use super::PlotError;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// A 2-D chart with linear f64 axes.
pub type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// The range of `values` widened by `pad` (a fraction of the span) on both sides; a constant or
/// empty set gets a unit-wide range around its value.
pub fn padded_range<'a>(values: impl IntoIterator<Item = &'a f64>, pad: f64) -> (f64, f64) {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if lo > hi {
        return (0.0, 1.0);
    }
    let span = hi - lo;
    if span <= 1e-12 * lo.abs().max(hi.abs()) || span == 0.0 {
        let w = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        return (lo - w, hi + w);
    }
    (lo - pad * span, hi + pad * span)
}

/// Union of ranges.
pub fn union(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    (a.0.min(b.0), a.1.max(b.1))
}

/// Tick label with as many decimals as the tick spacing needs.
pub fn tick(v: f64, span: f64) -> String {
    let step = span / 8.0;
    if !(step.is_finite()) || step <= 0.0 {
        return format!("{v}");
    }
    let mag = v.abs().max(span);
    if !(1e-3..1e5).contains(&mag) {
        return format!("{v:.1e}");
    }
    let decimals = (-((step / 2.0).log10().floor()) as i32).clamp(0, 6) as usize;
    let mut s = format!("{v:.decimals$}");
    if s.contains('.') {
        s = s.trim_end_matches('0').trim_end_matches('.').to_string();
    }
    // avoid "-0"
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// A chart on `area` with `caption` (may be empty), `x` and `y` ranges, a light grid and labelled
/// axes.
pub fn chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    caption: &str,
    x: (f64, f64),
    y: (f64, f64),
    x_label: &str,
    y_label: &str,
) -> Result<Chart<'a, DB>, PlotError> {
    let mut b = ChartBuilder::on(area);
    b.margin(style::px(16))
        .margin_right(style::px(28))
        .x_label_area_size(style::px(70))
        .y_label_area_size(style::px(110));
    if !caption.is_empty() {
        b.caption(caption, (FONT, style::px(style::CAPTION_SIZE)));
    }
    let mut chart = b
        .build_cartesian_2d(x.0..x.1, y.0..y.1)
        .map_err(render_err)?;
    let (xs, ys) = (x.1 - x.0, y.1 - y.0);
    let xf = move |v: &f64| tick(*v, xs);
    let yf = move |v: &f64| tick(*v, ys);
    chart
        .configure_mesh()
        .bold_line_style(style::GRID_MAJOR.stroke_width(style::px(1)))
        .light_line_style(style::GRID_MINOR.stroke_width(style::px(1)))
        .max_light_lines(4)
        .axis_style(BLACK.stroke_width(style::px(1)))
        .set_all_tick_mark_size(style::px(6))
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&xf)
        .y_label_formatter(&yf)
        .label_style((FONT, style::px(style::TICK_SIZE)))
        .axis_desc_style((FONT, style::px(style::LABEL_SIZE)))
        .x_desc(x_label)
        .y_desc(y_label)
        .draw()
        .map_err(render_err)?;
    Ok(chart)
}

/// A polyline through `points` as drawable elements. SVG gets one path (the viewer joins the
/// segments properly). A bitmap gets one element per segment: plotters fills a wide polyline as
/// one polygon with unlimited miter joins, which draws spikes at sharp reversals and fills
/// self-crossing loops wrongly; separate segments have neither problem.
pub fn path_elements<C: Clone>(points: Vec<C>, style: ShapeStyle) -> Vec<PathElement<C>> {
    if points.len() < 2 || !super::render::drawing_bitmap() || style.stroke_width <= 1 {
        return vec![PathElement::new(points, style)];
    }
    points
        .windows(2)
        .map(|w| PathElement::new(vec![w[0].clone(), w[1].clone()], style))
        .collect()
}

/// Draw the legend of the series that were given labels.
pub fn legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> Result<(), PlotError> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.6))
        .label_font((FONT, style::px(style::LEGEND_SIZE)))
        .margin(style::px(12))
        .legend_area_size(style::px(36))
        .draw()
        .map_err(render_err)
}

/// A legend entry symbol: a short line in `colour`.
pub fn legend_line(colour: RGBColor) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| {
        PathElement::new(
            vec![(x, y), (x + style::pxi(28), y)],
            colour.stroke_width(style::px(4)),
        )
    }
}

/// A vertical viridis colour bar from `lo` to `hi` described by `label`, filling `area`.
pub fn colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    lo: f64,
    hi: f64,
    label: &str,
) -> Result<(), PlotError> {
    let (lo, hi) = if hi > lo {
        (lo, hi)
    } else {
        (lo - 0.5, lo + 0.5)
    };
    let span = hi - lo;
    let mut chart = ChartBuilder::on(area)
        .margin_top(style::px(60))
        .margin_bottom(style::px(86))
        .margin_right(style::px(8))
        .y_label_area_size(0)
        .right_y_label_area_size(style::px(90))
        .build_cartesian_2d(0.0..1.0, lo..hi)
        .map_err(render_err)?;
    let yf = move |v: &f64| tick(*v, span);
    chart
        .configure_mesh()
        .disable_x_mesh()
        .disable_y_mesh()
        .disable_x_axis()
        .y_labels(6)
        .y_label_formatter(&yf)
        .label_style((FONT, style::px(style::TICK_SIZE)))
        .axis_desc_style((FONT, style::px(style::LABEL_SIZE)))
        .y_desc(label)
        .draw()
        .map_err(render_err)?;
    let steps = 128;
    chart
        .draw_series((0..steps).map(|i| {
            let a = lo + span * i as f64 / steps as f64;
            let b = lo + span * (i + 1) as f64 / steps as f64;
            let c = style::viridis((i as f64 + 0.5) / steps as f64);
            Rectangle::new([(0.0, a), (1.0, b)], c.filled())
        }))
        .map_err(render_err)?;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(0.0, lo), (1.0, hi)],
            BLACK.stroke_width(style::px(1)),
        )))
        .map_err(render_err)?;
    Ok(())
}

/// Split `root` into a title strip (when `title` is not empty) and the rest.
pub fn titled<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
) -> Result<DrawingArea<DB, Shift>, PlotError> {
    if title.is_empty() {
        return Ok(root.clone());
    }
    let (w, _) = root.dim_in_pixel();
    let (strip, rest) = root.split_vertically(style::px(style::TITLE_SIZE + 28));
    // shrink the title until it fits the width
    let full = style::px(style::TITLE_SIZE);
    let mut size = full;
    while size > style::px(12) {
        let (tw, _) = root
            .estimate_text_size(title, &(FONT, size).into_text_style(root))
            .map_err(render_err)?;
        if tw + style::px(40) <= w {
            break;
        }
        size -= 2;
    }
    strip
        .draw(&Text::new(
            title.to_string(),
            (w as i32 / 2, style::pxi(14) + (full - size) as i32 / 2),
            (FONT, size)
                .into_font()
                .color(&BLACK)
                .pos(Pos::new(HPos::Center, VPos::Top)),
        ))
        .map_err(render_err)?;
    Ok(rest)
}

/// Grid layout for `n` panels: columns, rows.
pub fn grid(n: usize) -> (usize, usize) {
    match n {
        0 | 1 => (1, 1),
        2 => (2, 1),
        3 => (3, 1),
        4 => (2, 2),
        n => {
            let cols = (n as f64).sqrt().ceil() as usize;
            (cols, n.div_ceil(cols))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_are_padded_and_never_empty() {
        assert_eq!(padded_range(&[0.0, 10.0], 0.1), (-1.0, 11.0));
        assert_eq!(padded_range(&[2.0, 2.0], 0.1), (1.8, 2.2));
        assert_eq!(padded_range(&[0.0], 0.1), (-1.0, 1.0));
        assert_eq!(padded_range(&[], 0.1), (0.0, 1.0));
    }

    #[test]
    fn ticks_have_the_needed_decimals() {
        assert_eq!(tick(0.25, 1.0), "0.25");
        assert_eq!(tick(150.0, 300.0), "150");
        assert_eq!(tick(-0.0, 300.0), "0");
        assert_eq!(tick(2.0e-6, 1.0e-5), "2.0e-6");
    }
}
