//! # Signal processing
//!
//! The few transforms the tool needs, written once: an iterative radix-2 FFT (used by the ODE
//! plant's band-limited input interpolation, the spectra of the figures and the comparison's
//! frequency bands) and a Hann-windowed amplitude spectrum.
//!
//! ## References
//! - J. W. Cooley, J. W. Tukey, "An algorithm for the machine calculation of complex Fourier
//!   series", Math. Comp. 19:297-301, 1965.
//! - P. D. Welch, "The use of fast Fourier transform for the estimation of power spectra",
//!   IEEE Trans. Audio Electroacoust. 15(2):70-73, 1967.

pub use nalgebra::Complex;
use std::f64::consts::PI;

/// Iterative radix-2 FFT (length must be a power of two); `inverse` without scaling.
pub fn fft_in_place(a: &mut [Complex<f64>], inverse: bool) {
    let n = a.len();
    if n <= 1 {
        return;
    }
    debug_assert!(n.is_power_of_two());
    let bits = n.trailing_zeros();
    for i in 0..n {
        let j = i.reverse_bits() >> (usize::BITS - bits);
        if j > i {
            a.swap(i, j);
        }
    }
    let sign = if inverse { 1.0 } else { -1.0 };
    let mut len = 2;
    while len <= n {
        let ang = sign * 2.0 * std::f64::consts::PI / len as f64;
        let half = len / 2;
        // Twiddles computed directly (not by repeated multiplication) to keep round-off low.
        let tw: Vec<Complex<f64>> = (0..half)
            .map(|k| Complex::new((ang * k as f64).cos(), (ang * k as f64).sin()))
            .collect();
        for start in (0..n).step_by(len) {
            for k in 0..half {
                let x = a[start + k];
                let y = a[start + k + half] * tw[k];
                a[start + k] = x + y;
                a[start + k + half] = x - y;
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
    let mut buf = vec![Complex::new(0.0, 0.0); nfft];
    while start + l <= n {
        let seg = &x[start..start + l];
        let mean = seg.iter().sum::<f64>() / l as f64;
        buf.iter_mut().for_each(|v| *v = Complex::new(0.0, 0.0));
        for k in 0..l {
            buf[k].re = (seg[k] - mean) * w[k];
        }
        fft_in_place(&mut buf, false);
        for (k, p) in power.iter_mut().enumerate() {
            *p += buf[k].norm_sqr();
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

/// The frequency below which `share` (e.g. 0.99) of the power of `x` lies (its amplitude
/// spectrum, mean removed); 0 for a record too short for a spectrum or without power.
pub fn bandwidth(x: &[f64], ts: f64, share: f64) -> f64 {
    let (f, a) = amplitude_spectrum(x, ts);
    let total: f64 = a.iter().map(|v| v * v).sum();
    if !(total > 0.0 && total.is_finite()) {
        return 0.0;
    }
    let mut acc = 0.0;
    for (fk, ak) in f.iter().zip(&a) {
        acc += ak * ak;
        if acc >= share * total {
            return *fk;
        }
    }
    f.last().copied().unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_matches_the_direct_dft() {
        let x: Vec<f64> = (0..64)
            .map(|k| ((k * k) as f64 * 0.37).sin() + 0.1 * k as f64)
            .collect();
        let mut a: Vec<Complex<f64>> = x.iter().map(|&v| Complex::new(v, 0.0)).collect();
        fft_in_place(&mut a, false);
        for (m, am) in a.iter().enumerate() {
            let mut s = Complex::new(0.0, 0.0);
            for (k, &v) in x.iter().enumerate() {
                let ang = -2.0 * PI * (m * k) as f64 / 64.0;
                s += Complex::new(ang.cos(), ang.sin()) * v;
            }
            assert!((s - am).norm() < 1e-10);
        }
    }

    #[test]
    fn sine_amplitude_is_recovered() {
        let ts = 1e-3;
        let x: Vec<f64> = (0..4096)
            .map(|k| 2.5 * (2.0 * PI * 50.0 * k as f64 * ts).sin())
            .collect();
        let (f, a) = amplitude_spectrum(&x, ts);
        let (i, peak) = a
            .iter()
            .enumerate()
            .fold((0, 0.0), |m, (i, &v)| if v > m.1 { (i, v) } else { m });
        assert!(
            (f[i] - 50.0).abs() < 0.5 && (peak - 2.5).abs() < 0.1,
            "{} Hz {peak}",
            f[i]
        );
    }
}
