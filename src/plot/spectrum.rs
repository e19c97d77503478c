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
use std::f64::consts::PI;
use std::path::Path;

/// In-place iterative radix-2 FFT of (re, im); the length must be a power of two.
pub fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    debug_assert!(n.is_power_of_two() && im.len() == n);
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = -2.0 * PI / len as f64;
        let half = len / 2;
        // twiddles computed directly per index: exact enough and simple
        let tw: Vec<(f64, f64)> = (0..half)
            .map(|k| ((ang * k as f64).cos(), (ang * k as f64).sin()))
            .collect();
        for start in (0..n).step_by(len) {
            for (k, &(c, s)) in tw.iter().enumerate() {
                let (a, b) = (start + k, start + k + half);
                let (xr, xi) = (re[b] * c - im[b] * s, re[b] * s + im[b] * c);
                re[b] = re[a] - xr;
                im[b] = im[a] - xi;
                re[a] += xr;
                im[a] += xi;
            }
        }
        len <<= 1;
    }
}

/// Longest segment transformed at once; longer records are averaged over half-overlapping
/// segments of this length (Welch).
pub const MAX_SEGMENT: usize = 1 << 20;

/// Amplitude spectrum of `x` sampled every `ts` seconds: (frequencies in Hz, amplitudes), without
/// the 0 Hz bin. The whole record (up to [`MAX_SEGMENT`] samples; longer ones are Welch-averaged)
/// is Hann-windowed, mean-removed, zero-padded to a power of two and transformed, so the
/// resolution is that of the record's length. Needs at least 16 samples.
pub fn amplitude_spectrum(x: &[f64], ts: f64) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    if n < 16 {
        return (Vec::new(), Vec::new());
    }
    let l = n.min(MAX_SEGMENT);
    let nfft = l.next_power_of_two();
    let w: Vec<f64> = (0..l)
        .map(|k| 0.5 - 0.5 * (2.0 * PI * k as f64 / l as f64).cos())
        .collect();
    let wsum: f64 = w.iter().sum();
    let mut power = vec![0.0; nfft / 2 + 1];
    let mut segments = 0;
    let mut start = 0;
    let (mut re, mut im) = (vec![0.0; nfft], vec![0.0; nfft]);
    while start + l <= n {
        let seg = &x[start..start + l];
        let mean = seg.iter().sum::<f64>() / l as f64;
        re.iter_mut().for_each(|v| *v = 0.0);
        im.iter_mut().for_each(|v| *v = 0.0);
        for k in 0..l {
            re[k] = (seg[k] - mean) * w[k];
        }
        fft(&mut re, &mut im);
        for (k, p) in power.iter_mut().enumerate() {
            *p += re[k] * re[k] + im[k] * im[k];
        }
        segments += 1;
        start += l / 2;
    }
    let df = 1.0 / (nfft as f64 * ts);
    let f = (1..=nfft / 2).map(|k| k as f64 * df).collect();
    let a = (1..=nfft / 2)
        .map(|k| 2.0 * (power[k] / segments as f64).sqrt() / wsum)
        .collect();
    (f, a)
}

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
    fn fft_matches_the_direct_dft() {
        let n = 64;
        let x: Vec<f64> = (0..n).map(|k| ((k * 7 % 13) as f64 - 6.0) * 0.3).collect();
        let (mut re, mut im) = (x.clone(), vec![0.0; n]);
        fft(&mut re, &mut im);
        for f in 0..n {
            let (mut sr, mut si) = (0.0, 0.0);
            for (k, v) in x.iter().enumerate() {
                let a = -2.0 * PI * (f * k) as f64 / n as f64;
                sr += v * a.cos();
                si += v * a.sin();
            }
            assert!(
                (re[f] - sr).abs() < 1e-9 && (im[f] - si).abs() < 1e-9,
                "bin {f}"
            );
        }
    }

    #[test]
    fn a_sine_shows_its_amplitude_at_its_frequency() {
        let ts = 1e-3;
        let x: Vec<f64> = (0..20_000)
            .map(|k| 2.5 * (2.0 * PI * 50.0 * k as f64 * ts).sin() + 1.0)
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
