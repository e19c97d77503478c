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
            let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
            {
                let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
                root.fill(&WHITE).map_err(render_err)?;
                BITMAP.with(|b| b.set(true));
                let drawn = fig.draw(&root);
                BITMAP.with(|b| b.set(false));
                drawn?;
                root.present().map_err(render_err)?;
            }
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
