//! # Measurement noise
//!
//! White Gaussian noise of a given standard deviation (output units), from an explicit seed.
//! Each stream comes from a portable named generator (Xoshiro256++), so the same seed gives the
//! same samples on every platform and at any thread count; normal variates come from the polar
//! Box-Muller method written here, so they do not depend on another crate's sampling algorithm.
//!
//! ## References
//! - G. Marsaglia, T. A. Bray, "A convenient method for generating normal variables",
//!   SIAM Review 6(3):260-264, 1964.

use rand::rngs::Xoshiro256PlusPlus;
use rand::{Rng, SeedableRng};

/// Mix a seed and a stream index into an independent 64-bit seed (SplitMix64 finaliser).
pub fn stream_seed(seed: u64, stream: u64) -> u64 {
    let mut z = seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A seeded source of uniform and Gaussian variates.
#[derive(Debug, Clone)]
pub struct Gaussian {
    rng: Xoshiro256PlusPlus,
    spare: Option<f64>,
}

impl Gaussian {
    /// Stream `stream` of seed `seed`.
    pub fn new(seed: u64, stream: u64) -> Gaussian {
        Gaussian {
            rng: Xoshiro256PlusPlus::seed_from_u64(stream_seed(seed, stream)),
            spare: None,
        }
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A standard normal variate.
    pub fn standard_normal(&mut self) -> f64 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        loop {
            let a = 2.0 * self.uniform() - 1.0;
            let b = 2.0 * self.uniform() - 1.0;
            let r = a * a + b * b;
            if r > 0.0 && r < 1.0 {
                let f = (-2.0 * r.ln() / r).sqrt();
                self.spare = Some(b * f);
                return a * f;
            }
        }
    }
}

/// `n` samples of white Gaussian noise of standard deviation `std`.
pub fn white_noise(n: usize, std: f64, seed: u64, stream: u64) -> Vec<f64> {
    let mut g = Gaussian::new(seed, stream);
    (0..n).map(|_| std * g.standard_normal()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_noise_other_seed_other_noise() {
        assert_eq!(white_noise(100, 1.0, 7, 0), white_noise(100, 1.0, 7, 0));
        assert_ne!(white_noise(100, 1.0, 7, 0), white_noise(100, 1.0, 8, 0));
        assert_ne!(white_noise(100, 1.0, 7, 0), white_noise(100, 1.0, 7, 1));
    }

    #[test]
    fn moments_are_right() {
        let x = white_noise(200_000, 0.5, 1, 0);
        let m = x.iter().sum::<f64>() / x.len() as f64;
        let v = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / x.len() as f64;
        assert!(m.abs() < 0.005, "mean {m}");
        assert!((v.sqrt() - 0.5).abs() < 0.005, "std {}", v.sqrt());
    }
}
