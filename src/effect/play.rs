//! # Play operator
//!
//! The backlash (play) operator of threshold r >= 0 on a sampled input:
//! z(k) = max(u(k) - r, min(u(k) + r, z(k-1))), exact for input monotone between samples.
//! It is the building block of the Prandtl-Ishlinskii model and of the hysteresis basis bank.
//! The generalised play ([`generalised_play`]) rides an ascending envelope gamma_l(u) - r and a
//! descending one gamma_r(u) + r in place of u -+ r.
//!
//! ## References
//! - M. A. Krasnosel'skii, A. V. Pokrovskii, *Systems with Hysteresis*, Springer, 1989.
//! - M. Brokate, J. Sprekels, *Hysteresis and Phase Transitions*, Springer, 1996.
//! - M. Al Janaideh, S. Rakheja, C.-Y. Su, IEEE/ASME TMech 16(4):734-744, 2011 (generalised play).

use super::Operator;

/// One play update: the new state for input `u`, threshold `r` and previous state `z`.
#[inline(always)]
pub fn play_operator(u: f64, r: f64, z: f64) -> f64 {
    (u - r).max((u + r).min(z))
}

/// One generalised play update (Al Janaideh, Rakheja & Su 2011): the play of threshold `r` whose
/// ascending edge follows the envelope value `up` - r and descending edge `down` + r,
/// z(k) = max(up - r, min(down + r, z(k-1))); with up = down = u it is [`play_operator`].
#[inline(always)]
pub fn generalised_play(up: f64, down: f64, r: f64, z: f64) -> f64 {
    (up - r).max((down + r).min(z))
}

/// A play operator with its state.
#[derive(Debug, Clone, PartialEq)]
pub struct Play {
    pub threshold: f64,
    pub initial_state: f64,
    state: f64,
}

impl Play {
    /// A play of threshold `r` starting at `z0`.
    pub fn new(threshold: f64, initial_state: f64) -> Play {
        Play {
            threshold,
            initial_state,
            state: initial_state,
        }
    }
}

impl Operator for Play {
    fn reset(&mut self) {
        self.state = self.initial_state;
    }
    #[inline]
    fn step(&mut self, u: f64) -> f64 {
        self.state = play_operator(u, self.threshold, self.state);
        self.state
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_threshold_is_identity() {
        let u = [0.0, 1.0, -2.0, 3.5];
        assert_eq!(Play::new(0.0, 0.0).apply(&u), u);
    }

    #[test]
    fn output_stays_within_threshold_of_input() {
        let u: Vec<f64> = (0..500).map(|k| 10.0 * (k as f64 * 0.05).sin()).collect();
        let z = Play::new(2.0, 0.0).apply(&u);
        for (a, b) in u.iter().zip(&z) {
            assert!((a - b).abs() <= 2.0 + 1e-12);
        }
    }

    #[test]
    fn generalised_play_with_the_identity_envelopes_is_the_play() {
        let u: Vec<f64> = (0..300)
            .map(|k| 3.0 * (k as f64 * 0.07).sin() * (k as f64 * 0.011).cos())
            .collect();
        let (mut z, mut g) = (0.0, 0.0);
        for &v in &u {
            z = play_operator(v, 0.8, z);
            g = generalised_play(v, v, 0.8, g);
            assert_eq!(z.to_bits(), g.to_bits());
        }
    }

    #[test]
    fn holds_inside_the_band() {
        let mut p = Play::new(1.0, 0.0);
        assert_eq!(p.step(0.5), 0.0);
        assert_eq!(p.step(2.0), 1.0);
        assert_eq!(p.step(1.5), 1.0);
        assert_eq!(p.step(-1.0), 0.0);
    }
}
