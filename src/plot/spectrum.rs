//! # Amplitude spectrum figure
//!
//! Single-sided amplitude spectra of each measured output and of its residual `y - y_hat`, on
//! log-log axes. A residual that still holds the excitation frequency and its harmonics points at
//! a missing static or hysteretic effect; one that rises at low frequency at creep; a peak near a
//! resonance at missing dynamics.
//!
//! The whole record is Hann-windowed, mean-removed, zero-padded to a power of two and transformed
//! with an iterative radix-2 FFT, so the frequency resolution is that of the record's length
//! (a few periods of a 1 Hz excitation still resolve its harmonics); records longer than 2^20
//! samples are averaged over half-overlapping segments (Welch). The amplitudes are scaled so that
//! a sine of amplitude A shows as A at its frequency.
//!
//! ## References
//! - P. Welch, "The use of fast Fourier transform for the estimation of power spectra",
//!   IEEE Trans. Audio Electroacoust. 15(2), 1967, doi:10.1109/TAU.1967.1161901.
//! - J. W. Cooley, J. W. Tukey, "An algorithm for the machine calculation of complex Fourier
//!   series", Math. Comp. 19, 1965, doi:10.1090/S0025-5718-1965-0178586-1.

use super::axes::{self, legend, legend_line};
use super::render::{render_err, save, Figure};
use super::source::PlotRecord;
use super::style::{self, FONT, PANEL};
use super::PlotError;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

pub use crate::signal::{amplitude_spectrum, MAX_SEGMENT};

/// Indices of the bins to draw: per log-spaced frequency bucket the smallest and largest value.
fn log_decimate(f: &[f64], a: &[f64], buckets: usize) -> Vec<usize> {
    if f.len() <= 2 * buckets {
        return (0..f.len()).collect();
    }
    let (l0, l1) = (f[0].ln(), f[f.len() - 1].ln());
    let bucket = |k: usize| (((f[k].ln() - l0) / (l1 - l0)) * buckets as f64) as usize;
    let mut out = Vec::new();
    let mut k = 0;
    while k < f.len() {
        let b = bucket(k);
        let (mut lo, mut hi, mut e) = (k, k, k);
        while e < f.len() && bucket(e) == b {
            if a[e] < a[lo] {
                lo = e;
            }
            if a[e] > a[hi] {
                hi = e;
            }
            e += 1;
        }
        out.push(lo.min(hi));
        if hi != lo {
            out.push(lo.max(hi));
        }
        k = e;
    }
    out
}

fn log_tick(v: f64) -> String {
    if (1e-3..1e4).contains(&v.abs()) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// Spectra of every output of a record (and of the residuals, when predicted).
pub struct SpectrumFigure<'a> {
    pub record: &'a PlotRecord,
    pub title: Option<String>,
}

impl<'a> SpectrumFigure<'a> {
    /// Needs at least 64 samples.
    pub fn new(record: &'a PlotRecord, title: Option<String>) -> Result<Self, PlotError> {
        record.require_len(64, "spectrum")?;
        Ok(SpectrumFigure { record, title })
    }
}

impl Figure for SpectrumFigure<'_> {
    fn default_size(&self) -> (u32, u32) {
        (
            PANEL.0 + 200,
            PANEL.1 * self.record.io.outputs.len() as u32 + 60,
        )
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let r = self.record;
        let title = self.title.clone().unwrap_or_else(|| {
            if r.has_predictions() {
                format!(
                    "Amplitude spectra of measurement and residual ({})",
                    r.label
                )
            } else {
                format!("Amplitude spectra ({})", r.label)
            }
        });
        let body = super::axes::titled(root, &title)?;
        let areas = body.split_evenly((r.io.outputs.len(), 1));
        for (j, area) in areas.iter().enumerate() {
            let y = &r.io.outputs[j].values;
            let mut series = vec![("measured".to_string(), amplitude_spectrum(y, r.io.ts))];
            if let Some(e) = r.residual(j) {
                series.push(("residual".to_string(), amplitude_spectrum(&e, r.io.ts)));
            }
            let f = &series[0].1 .0;
            let amax = series
                .iter()
                .flat_map(|s| s.1 .1.iter())
                .fold(0.0f64, |m, &v| m.max(v));
            let amax = if amax > 0.0 { amax } else { 1.0 };
            let floor = amax * 1e-7;
            let amin = series
                .iter()
                .flat_map(|s| s.1 .1.iter())
                .fold(amax, |m, &v| if v > floor { m.min(v) } else { m });
            let (f0, f1) = (f[0], f[f.len() - 1]);
            let mut b = ChartBuilder::on(area);
            b.margin(style::px(16))
                .margin_right(style::px(28))
                .x_label_area_size(style::px(70))
                .y_label_area_size(style::px(110));
            if r.io.outputs.len() > 1 {
                b.caption(
                    &r.io.outputs[j].name,
                    (FONT, style::px(style::CAPTION_SIZE)),
                );
            }
            let mut chart = b
                .build_cartesian_2d((f0..f1).log_scale(), (amin * 0.5..amax * 2.0).log_scale())
                .map_err(render_err)?;
            chart
                .configure_mesh()
                .bold_line_style(style::GRID_MAJOR.stroke_width(style::px(1)))
                .light_line_style(style::GRID_MINOR.stroke_width(style::px(1)))
                .max_light_lines(4)
                .axis_style(BLACK.stroke_width(style::px(1)))
                .set_all_tick_mark_size(style::px(6))
                .x_labels(10)
                .y_labels(10)
                .x_label_formatter(&|v| log_tick(*v))
                .y_label_formatter(&|v| log_tick(*v))
                .label_style((FONT, style::px(style::TICK_SIZE)))
                .axis_desc_style((FONT, style::px(style::LABEL_SIZE)))
                .x_desc("frequency [Hz]")
                .y_desc(format!(
                    "amplitude of {}",
                    r.quantity(&r.io.outputs[j].name).label()
                ))
                .draw()
                .map_err(render_err)?;
            for (c, (name, (f, a))) in series.iter().enumerate() {
                let colour = style::series_colour(c);
                let idx = log_decimate(f, a, 1500);
                chart
                    .draw_series(axes::path_elements(
                        idx.iter()
                            .map(|&k| (f[k], a[k].max(floor)))
                            .collect::<Vec<_>>(),
                        colour.stroke_width(style::px(style::LINE_WIDTH)),
                    ))
                    .map_err(render_err)?
                    .label(name.as_str())
                    .legend(legend_line(colour));
            }
            legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        }
        Ok(())
    }
}

/// Draw a spectrum figure of `record` to `path` (see [`SpectrumFigure`]).
pub fn spectrum_figure(
    record: &PlotRecord,
    title: Option<String>,
    path: &Path,
    size: Option<(u32, u32)>,
    force: bool,
) -> Result<(), PlotError> {
    save(&SpectrumFigure::new(record, title)?, path, size, force)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sine_shows_its_amplitude_at_its_frequency() {
        let ts = 1e-3;
        let x: Vec<f64> = (0..20_000)
            .map(|k| 2.5 * (2.0 * std::f64::consts::PI * 50.0 * k as f64 * ts).sin() + 1.0)
            .collect();
        let (f, a) = amplitude_spectrum(&x, ts);
        let (kmax, amax) = a
            .iter()
            .enumerate()
            .fold((0, 0.0), |m, (k, &v)| if v > m.1 { (k, v) } else { m });
        assert!((f[kmax] - 50.0).abs() < 0.2, "{}", f[kmax]);
        // Hann scalloping loss is at most 15 %
        assert!(amax > 2.5 * 0.85 && amax < 2.5 * 1.01, "{amax}");
    }
}
