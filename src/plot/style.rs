//! Shared look: sizes, fonts, colours (colour-blind safe palette, viridis map) and axis labels
//! built from column names with units (`voltage_V` -> "voltage [V]").
//!
//! ## References
//! - M. Okabe, K. Ito, "Color Universal Design" (2008): the eight-colour palette.
//! - S. van der Walt, N. Smith, "viridis" colour map for matplotlib (2015), sampled at 9 points.

use plotters::style::RGBColor;

thread_local! {
    static SCALE: std::cell::Cell<u32> = const { std::cell::Cell::new(1) };
}

/// A length in figure pixels converted to drawing pixels: PNGs are drawn at twice their size and
/// averaged down (anti-aliasing), so every fixed length in the figures goes through this.
pub fn px(v: u32) -> u32 {
    v * SCALE.with(|s| s.get())
}

/// [`px`] for signed offsets.
pub fn pxi(v: i32) -> i32 {
    v * SCALE.with(|s| s.get()) as i32
}

/// Run `f` with lengths scaled by `scale`.
pub(crate) fn with_scale<T>(scale: u32, f: impl FnOnce() -> T) -> T {
    let old = SCALE.with(|s| s.replace(scale));
    let out = f();
    SCALE.with(|s| s.set(old));
    out
}

/// Default size of one panel in pixels.
pub const PANEL: (u32, u32) = (900, 680);
/// Font family (the embedded DejaVu Sans is registered under it).
pub const FONT: &str = "sans-serif";
/// Figure title size in pixels.
pub const TITLE_SIZE: u32 = 34;
/// Panel caption size.
pub const CAPTION_SIZE: u32 = 28;
/// Axis description size.
pub const LABEL_SIZE: u32 = 26;
/// Tick label size.
pub const TICK_SIZE: u32 = 22;
/// Legend text size.
pub const LEGEND_SIZE: u32 = 22;
/// Line width of data series.
pub const LINE_WIDTH: u32 = 2;

/// Okabe-Ito colour-blind safe palette, in the order series get them.
pub const PALETTE: [RGBColor; 7] = [
    RGBColor(0, 114, 178),   // blue
    RGBColor(213, 94, 0),    // vermillion
    RGBColor(0, 158, 115),   // bluish green
    RGBColor(204, 121, 167), // reddish purple
    RGBColor(230, 159, 0),   // orange
    RGBColor(86, 180, 233),  // sky blue
    RGBColor(0, 0, 0),       // black
];

/// Colour of the n-th series.
pub fn series_colour(n: usize) -> RGBColor {
    PALETTE[n % PALETTE.len()]
}

/// Grid line colours (major, minor).
pub const GRID_MAJOR: RGBColor = RGBColor(210, 210, 210);
pub const GRID_MINOR: RGBColor = RGBColor(238, 238, 238);
/// Colour of cells that diverged (sweep maps).
pub const DIVERGED: RGBColor = RGBColor(120, 120, 120);
/// Colour of cells without a run.
pub const MISSING: RGBColor = RGBColor(255, 255, 255);

const VIRIDIS: [(u8, u8, u8); 9] = [
    (68, 1, 84),
    (71, 44, 122),
    (59, 81, 139),
    (44, 113, 142),
    (33, 144, 141),
    (39, 173, 129),
    (92, 200, 99),
    (170, 220, 50),
    (253, 231, 37),
];

/// The viridis colour at `x` in [0, 1] (clamped), linearly interpolated.
pub fn viridis(x: f64) -> RGBColor {
    let x = if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = x * (VIRIDIS.len() - 1) as f64;
    let i = (s.floor() as usize).min(VIRIDIS.len() - 2);
    let f = s - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |p: u8, q: u8| (p as f64 + f * (q as f64 - p as f64)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Units recognised at the end of a column name, after the last `_`, and how they print.
const UNITS: &[(&str, &str)] = &[
    ("V", "V"),
    ("mV", "mV"),
    ("kV", "kV"),
    ("A", "A"),
    ("mA", "mA"),
    ("m", "m"),
    ("mm", "mm"),
    ("um", "µm"),
    ("µm", "µm"),
    ("nm", "nm"),
    ("N", "N"),
    ("mN", "mN"),
    ("kN", "kN"),
    ("s", "s"),
    ("ms", "ms"),
    ("us", "µs"),
    ("Hz", "Hz"),
    ("rad", "rad"),
    ("mrad", "mrad"),
    ("urad", "µrad"),
    ("deg", "°"),
    ("Pa", "Pa"),
    ("kPa", "kPa"),
    ("MPa", "MPa"),
    ("W", "W"),
    ("T", "T"),
    ("mps", "m/s"),
    ("m_s", "m/s"),
    ("mmps", "mm/s"),
    ("mps2", "m/s²"),
    ("g", "g"),
];

/// How a unit prints: `um` -> "µm", `deg` -> "°"; unknown units as given.
pub fn unit_display(unit: &str) -> String {
    UNITS
        .iter()
        .find(|(u, _)| *u == unit)
        .map_or(unit.to_string(), |(_, shown)| (*shown).to_string())
}

/// A column name split into a quantity and its unit: `displacement_um` -> ("displacement", "µm").
#[derive(Debug, Clone, PartialEq)]
pub struct Quantity {
    pub name: String,
    pub unit: Option<String>,
}

impl Quantity {
    /// Parse a column name; a trailing `_hat` (model prediction) is dropped first.
    pub fn from_column(column: &str) -> Quantity {
        let column = column.strip_suffix("_hat").unwrap_or(column);
        if let Some((name, unit)) = column.rsplit_once('_') {
            if !name.is_empty() {
                if let Some((_, shown)) = UNITS.iter().find(|(u, _)| *u == unit) {
                    return Quantity {
                        name: name.replace('_', " "),
                        unit: Some((*shown).to_string()),
                    };
                }
            }
        }
        Quantity {
            name: column.to_string(),
            unit: None,
        }
    }

    /// "name [unit]" or "name".
    pub fn label(&self) -> String {
        self.label_with(&self.name)
    }

    /// Another name with this unit: "residual [µm]".
    pub fn label_with(&self, name: &str) -> String {
        match &self.unit {
            Some(u) => format!("{name} [{u}]"),
            None => name.to_string(),
        }
    }
}

/// The axis label of a column: `voltage_V` -> "voltage [V]".
pub fn axis_label(column: &str) -> String {
    Quantity::from_column(column).label()
}

/// The axis label of the time column: `t_s` -> "t [s]"; a bare `t` is in seconds by convention.
pub fn time_label(column: &str) -> String {
    let q = Quantity::from_column(column);
    match q.unit {
        Some(_) => q.label(),
        None => format!("{} [s]", if column == "t" { "time" } else { column }),
    }
}

/// A short, readable number for titles and cell labels (4 significant digits).
pub fn fmt_num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{v:.3e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_are_read_from_column_names() {
        assert_eq!(axis_label("voltage_V"), "voltage [V]");
        assert_eq!(axis_label("displacement_um"), "displacement [µm]");
        assert_eq!(axis_label("y_m"), "y [m]");
        assert_eq!(axis_label("u_N"), "u [N]");
        assert_eq!(axis_label("displacement_um_hat"), "displacement [µm]");
        assert_eq!(axis_label("y1"), "y1");
        assert_eq!(axis_label("y_hat"), "y");
        assert_eq!(axis_label("tip_force_mN"), "tip force [mN]");
        assert_eq!(axis_label("some_thing"), "some_thing");
        assert_eq!(time_label("t_s"), "t [s]");
        assert_eq!(time_label("t"), "time [s]");
    }

    #[test]
    fn viridis_ends_and_clamps() {
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
        assert_eq!(viridis(7.0), viridis(1.0));
        assert_eq!(viridis(f64::NAN), viridis(0.0));
    }

    #[test]
    fn numbers_are_short() {
        assert_eq!(fmt_num(0.98765), "0.9877");
        assert_eq!(fmt_num(12.3456), "12.35");
        assert_eq!(fmt_num(-0.5), "-0.5000");
        assert_eq!(fmt_num(1.5e-6), "1.500e-6");
    }
}
