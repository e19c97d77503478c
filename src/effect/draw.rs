//! Random specs over documented physical ranges: what the plant zoo (`crate::zoo`) draws from
//! each effect ([`super::Effect::draw`]). Each effect documents its ranges beside its `draw`;
//! `docs/zoo.md` collects them.

use super::noise::Gaussian;

/// What a path or an output looks like to the effect being drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrawContext {
    /// Sampling period (s).
    pub ts: f64,
    /// The peak input the excitation reaches (input units).
    pub input_amplitude: f64,
    /// The direct path of an output, or a cross path (another axis' input).
    pub role: PathRole,
    /// The sign of the path's gain: -1 for a reversed polarity, or a cross path that bends
    /// the other way (a path term draws its magnitude, then this sign).
    pub sign: f64,
}

/// Which path of an output is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PathRole {
    /// The output's own input; its gain sets the output's scale.
    Direct,
    /// Another axis' input, with this gain relative to the direct path's.
    Cross { relative_gain: f64 },
}

/// A seeded source of the draws (portable: the same seed gives the same plants everywhere).
#[derive(Debug, Clone)]
pub struct Dice(Gaussian);

impl Dice {
    /// Stream `stream` of seed `seed`.
    pub fn new(seed: u64, stream: u64) -> Dice {
        Dice(Gaussian::new(seed, stream))
    }

    /// Uniform in `[a, b)`.
    pub fn uniform(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.0.uniform()
    }

    /// Log-uniform in `[a, b)` (a, b > 0): every decade as likely.
    pub fn log_uniform(&mut self, a: f64, b: f64) -> f64 {
        (a.ln() + (b.ln() - a.ln()) * self.0.uniform()).exp()
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.0.uniform() < p
    }

    /// An integer uniform in `a..=b`.
    pub fn int(&mut self, a: usize, b: usize) -> usize {
        a + ((b - a + 1) as f64 * self.0.uniform()) as usize
    }

    /// An index drawn with the given weights (need not sum to 1).
    pub fn pick(&mut self, weights: &[f64]) -> usize {
        let total: f64 = weights.iter().sum();
        let mut x = self.0.uniform() * total;
        for (i, w) in weights.iter().enumerate() {
            if x < *w {
                return i;
            }
            x -= w;
        }
        weights.len() - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_stay_in_their_ranges_and_repeat_with_the_seed() {
        let mut d = Dice::new(3, 1);
        for _ in 0..1000 {
            let u = d.uniform(-2.0, 5.0);
            assert!((-2.0..5.0).contains(&u));
            let l = d.log_uniform(0.05, 100.0);
            assert!((0.05..100.0).contains(&l));
            let i = d.int(2, 4);
            assert!((2..=4).contains(&i));
            assert!(d.pick(&[0.0, 1.0, 0.0]) == 1);
        }
        let a: Vec<f64> = (0..5).map(|_| Dice::new(9, 2).uniform(0.0, 1.0)).collect();
        assert!(a.windows(2).all(|w| w[0] == w[1]));
        assert_ne!(
            Dice::new(9, 2).uniform(0.0, 1.0),
            Dice::new(9, 3).uniform(0.0, 1.0)
        );
    }
}
