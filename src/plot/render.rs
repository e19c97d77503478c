//! From a figure to bytes on disk: the format from the extension, the embedded font, rendering
//! in memory (PNG through an RGB buffer, SVG through a string) and an atomic write, so a failure
//! never leaves a partial file and nothing is overwritten without `force`.

use super::PlotError;
use crate::data::{check_writable, write_atomic};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::path::Path;
use std::sync::OnceLock;

static FONT_BYTES: &[u8] = include_bytes!("fonts/DejaVuSans.ttf");

/// Register the embedded DejaVu Sans under the three generic families, once. No system font is
/// ever looked up.
pub fn register_embedded_font() -> Result<(), PlotError> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        ["sans-serif", "serif", "monospace"]
            .iter()
            .all(|family| register_font(family, FontStyle::Normal, FONT_BYTES).is_ok())
    });
    if ok {
        Ok(())
    } else {
        Err(PlotError::Font)
    }
}

thread_local! {
    static BITMAP: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// True while a bitmap is being drawn on this thread (see [`super::axes::path_elements`]).
pub(crate) fn drawing_bitmap() -> bool {
    BITMAP.with(|b| b.get())
}

/// The two output formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Png,
    Svg,
}

impl Format {
    /// The format named by the file extension (`.png` or `.svg`, any case).
    pub fn from_path(path: &Path) -> Result<Format, PlotError> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "png" => Ok(Format::Png),
            "svg" => Ok(Format::Svg),
            _ => Err(PlotError::UnknownFormat {
                path: path.to_path_buf(),
                extension: if ext.is_empty() {
                    "(none)".to_string()
                } else {
                    format!(".{ext}")
                },
            }),
        }
    }
}

/// A figure that can draw itself on any plotters backend.
pub trait Figure {
    /// Size in pixels when the caller does not choose one.
    fn default_size(&self) -> (u32, u32);
    /// Draw on `root` (already filled white).
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError>;
}

/// Turn a plotters error into ours.
pub(crate) fn render_err<E: std::error::Error + Send + Sync>(
    e: DrawingAreaErrorKind<E>,
) -> PlotError {
    PlotError::Render(e.to_string())
}

/// Smallest and largest side accepted, in pixels.
pub const MIN_SIDE: u32 = 200;
pub const MAX_SIDE: u32 = 10_000;

fn check_size((w, h): (u32, u32)) -> Result<(), PlotError> {
    if !(MIN_SIDE..=MAX_SIDE).contains(&w) || !(MIN_SIDE..=MAX_SIDE).contains(&h) {
        return Err(PlotError::BadSize {
            width: w,
            height: h,
            min: MIN_SIDE,
            max: MAX_SIDE,
        });
    }
    Ok(())
}

/// PNGs up to this many pixels are drawn at twice their size and averaged down.
const SUPERSAMPLE_MAX_PIXELS: u64 = 16_000_000;

/// Average 2x2 blocks of an RGB buffer of size `2w x 2h` into `w x h`.
fn downsample2(big: &[u8], (w, h): (u32, u32)) -> Vec<u8> {
    let (w, h) = (w as usize, h as usize);
    let row = 2 * w * 3;
    let mut out = vec![0u8; w * h * 3];
    for y in 0..h {
        let r0 = &big[2 * y * row..(2 * y + 1) * row];
        let r1 = &big[(2 * y + 1) * row..(2 * y + 2) * row];
        let o = &mut out[y * w * 3..(y + 1) * w * 3];
        for x in 0..w {
            for c in 0..3 {
                let i = 6 * x + c;
                let sum = r0[i] as u32 + r0[i + 3] as u32 + r1[i] as u32 + r1[i + 3] as u32;
                o[3 * x + c] = ((sum + 2) / 4) as u8;
            }
        }
    }
    out
}

/// Render `fig` in memory and return the file's bytes.
pub fn render<F: Figure>(
    fig: &F,
    format: Format,
    size: Option<(u32, u32)>,
) -> Result<Vec<u8>, PlotError> {
    register_embedded_font()?;
    let size = size.unwrap_or_else(|| fig.default_size());
    check_size(size)?;
    match format {
        Format::Png => {
            // draw at twice the size and average 2x2 blocks: anti-aliased lines and text
            let scale = if size.0 as u64 * size.1 as u64 <= SUPERSAMPLE_MAX_PIXELS {
                2
            } else {
                1
            };
            let big = (size.0 * scale, size.1 * scale);
            let mut buf = vec![255u8; big.0 as usize * big.1 as usize * 3];
            {
                let root = BitMapBackend::with_buffer(&mut buf, big).into_drawing_area();
                root.fill(&WHITE).map_err(render_err)?;
                BITMAP.with(|b| b.set(true));
                let drawn = super::style::with_scale(scale, || fig.draw(&root));
                BITMAP.with(|b| b.set(false));
                drawn?;
                root.present().map_err(render_err)?;
            }
            let buf = if scale == 2 {
                downsample2(&buf, size)
            } else {
                buf
            };
            let mut png = Vec::new();
            image::codecs::png::PngEncoder::new_with_quality(
                &mut png,
                image::codecs::png::CompressionType::Best,
                image::codecs::png::FilterType::Adaptive,
            )
            .write_image(&buf, size.0, size.1, image::ColorType::Rgb8)
            .map_err(|e| PlotError::Encode(e.to_string()))?;
            Ok(png)
        }
        Format::Svg => {
            let mut s = String::new();
            {
                let root = SVGBackend::with_string(&mut s, size).into_drawing_area();
                root.fill(&WHITE).map_err(render_err)?;
                fig.draw(&root)?;
                root.present().map_err(render_err)?;
            }
            Ok(s.into_bytes())
        }
    }
}

/// Render `fig` and write it to `path` atomically (format from the extension). Checks the path
/// before drawing, so a wrong extension or an existing file costs no rendering.
pub fn save<F: Figure>(
    fig: &F,
    path: &Path,
    size: Option<(u32, u32)>,
    force: bool,
) -> Result<(), PlotError> {
    let format = Format::from_path(path)?;
    check_writable(path, force)?;
    let bytes = render(fig, format, size)?;
    write_atomic(path, &bytes, force)?;
    Ok(())
}

use image::ImageEncoder as _;
