//! Blocked cross-validation of a grey-box model: the record is cut into contiguous blocks; for
//! each block the model is fitted on the rest of the record (the block's samples do not enter
//! its cost, [`FitOptions::held_out`](super::FitOptions::held_out)) and run free over the whole
//! record, and its output on the block is kept. Every sample is then predicted by a model that
//! did not see it, by a free run from the record's start, as a test record would be.
//!
//! A record of a few hundred samples judged on one held-out tail gives a noisy verdict: the
//! tail may not reach the input's extremes or the input combinations of the rest. Every block
//! in turn is a verdict four to five times as large, and the blocks that hold the record's
//! extremes make each candidate extrapolate (Arlot and Celisse 2010; for dependent data,
//! blocks rather than single samples: Burman, Chow and Nolan 1994; Bergmeir and Benitez 2012).
//!
//! ## References
//! - S. Arlot, A. Celisse, "A survey of cross-validation procedures for model selection",
//!   Statistics Surveys 4:40-79, 2010.
//! - P. Burman, E. Chow, D. Nolan, "A cross-validatory method for dependent data",
//!   Biometrika 81(2):351-358, 1994.
//! - C. Bergmeir, J. M. Benitez, "On the use of cross-validation for time series predictor
//!   evaluation", Information Sciences 191:192-213, 2012.

use super::{FittedGreyBox, GreyBoxConfig, GreyBoxError};
use crate::data::IoRecord;
use rayon::prelude::*;
use std::ops::Range;

/// The blocks of a `folds`-fold blocked cross-validation of `n` samples: contiguous, in order,
/// sizes within one sample of each other (the last ends at `n`).
pub fn blocks(n: usize, folds: usize) -> Vec<Range<usize>> {
    let k = folds.clamp(1, n.max(1));
    (0..k).map(|i| i * n / k..(i + 1) * n / k).collect()
}

/// The out-of-block free runs of a model: per output, every sample from the model fitted
/// without its block.
#[derive(Debug, Clone)]
pub struct CrossValidation {
    /// The blocks, in order.
    pub blocks: Vec<Range<usize>>,
    /// Per output, the out-of-block prediction of every sample of the record.
    pub predictions: Vec<Vec<f64>>,
    /// The model fitted without each block.
    pub fits: Vec<FittedGreyBox>,
}

impl GreyBoxConfig {
    /// Blocked cross-validation on `rec` with `folds` contiguous blocks (module documentation).
    /// The folds are fitted in parallel and collected in order (the same bits whatever the
    /// thread count); a fold that cannot be fitted or simulated is the error.
    pub fn cross_validate(
        &self,
        rec: &IoRecord,
        folds: usize,
    ) -> Result<CrossValidation, GreyBoxError> {
        let n = rec.len();
        let blocks = blocks(n, folds);
        let runs: Vec<(FittedGreyBox, Vec<Vec<f64>>)> = blocks
            .par_iter()
            .map(|b| {
                let mut cfg = self.clone();
                cfg.options.train_fraction = 1.0;
                cfg.options.held_out = Some(b.clone());
                let model = cfg.fit(rec)?;
                let sim = model.simulate(rec)?;
                Ok((model, sim))
            })
            .collect::<Result<_, GreyBoxError>>()?;
        let outputs = rec.outputs.len();
        let mut predictions = vec![vec![f64::NAN; n]; outputs];
        for (b, (_, sim)) in blocks.iter().zip(&runs) {
            for (p, s) in predictions.iter_mut().zip(sim) {
                p[b.clone()].copy_from_slice(&s[b.clone()]);
            }
        }
        Ok(CrossValidation {
            blocks,
            predictions,
            fits: runs.into_iter().map(|(m, _)| m).collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Signal;
    use crate::effect::hysteresis::HysteresisSpec;
    use crate::plant::EffectSpecs;

    #[test]
    fn blocks_tile_the_record() {
        let b = blocks(250, 4);
        assert_eq!(b, vec![0..62, 62..125, 125..187, 187..250]);
        assert_eq!(blocks(3, 8).len(), 3);
    }

    /// A held-out block does not enter the fit: an output damaged inside the block gives the
    /// same model as the clean one, and the out-of-block predictions of a model that the
    /// record determines are close to the output everywhere.
    #[test]
    fn a_held_out_block_does_not_enter_the_fit() {
        let n = 400;
        let ts = 1e-3;
        let u: Vec<f64> = (0..n)
            .map(|k| 10.0 * (k as f64 * 0.05).sin() + 3.0 * (k as f64 * 0.17).sin())
            .collect();
        let y: Vec<f64> = u.iter().map(|v| 0.7 * v + 1.5).collect();
        let rec = |y: Vec<f64>| IoRecord {
            path: "cv.csv".into(),
            ts,
            t0: 0.0,
            time_name: "t".into(),
            inputs: vec![Signal {
                name: "u".into(),
                values: u.clone(),
            }],
            outputs: vec![Signal {
                name: "y".into(),
                values: y,
            }],
        };
        let cfg = GreyBoxConfig::linear();
        let mut damaged = y.clone();
        damaged[100..200].iter_mut().for_each(|v| *v += 50.0);
        let mut held = cfg.clone();
        held.options.held_out = Some(100..200);
        let a = held.fit(&rec(damaged.clone())).unwrap();
        let b = cfg.fit(&rec(y.clone())).unwrap();
        let (sa, sb) = (
            a.simulate(&rec(y.clone())).unwrap(),
            b.simulate(&rec(y.clone())).unwrap(),
        );
        for (x, z) in sa[0].iter().zip(&sb[0]) {
            assert!((x - z).abs() < 1e-9, "{x} {z}");
        }
        // the damage is seen by a fit that keeps the block
        let c = cfg.fit(&rec(damaged)).unwrap();
        assert!((c.simulate(&rec(y.clone())).unwrap()[0][0] - sb[0][0]).abs() > 1.0);
        let cv = cfg.cross_validate(&rec(y.clone()), 4).unwrap();
        assert_eq!(cv.fits.len(), 4);
        for (p, v) in cv.predictions[0].iter().zip(&y) {
            assert!((p - v).abs() < 1e-9);
        }
    }

    /// The ridge chosen by cross-validation: the strongest on a linear plant (the hysteresis
    /// terms explain nothing there), a weaker one that keeps the fit on a hysteretic plant.
    #[test]
    fn the_cross_validated_ridge_follows_the_plant() {
        let n = 3000;
        let u: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64;
                10.0 * (0.01 * t).sin() * (1.0 + 0.5 * (0.0013 * t).sin())
            })
            .collect();
        // a deterministic noise of 0.1 % of the range
        let noise = |k: usize| 0.02 * ((k as f64 * 12.9898).sin() * 43758.5453).fract();
        let mut z = 0.0;
        let play: Vec<f64> = u
            .iter()
            .map(|&v| {
                z = crate::effect::play::play_operator(v, 3.0, z);
                z
            })
            .collect();
        let rec = |y: Vec<f64>| IoRecord {
            path: "ridge.csv".into(),
            ts: 1e-3,
            t0: 0.0,
            time_name: "t".into(),
            inputs: vec![Signal {
                name: "u".into(),
                values: u.clone(),
            }],
            outputs: vec![Signal {
                name: "y".into(),
                values: y,
            }],
        };
        let mut cfg = GreyBoxConfig::from_effect_list("hysteresis").unwrap();
        cfg.options.choose_ridge = true;
        let linear = rec((0..n).map(|k| 0.7 * u[k] + noise(k)).collect());
        let fit = cfg.fit(&linear).unwrap();
        assert_eq!(fit.fit.outputs[0].ridge, crate::graybox::RIDGES[0]);
        let hysteretic = rec((0..n)
            .map(|k| 0.4 * u[k] + 0.5 * play[k] + noise(k))
            .collect());
        let fit = cfg.fit(&hysteretic).unwrap();
        assert!(fit.fit.outputs[0].ridge < crate::graybox::RIDGES[0]);
        assert!(fit.fit.r2.unwrap() > 0.9999, "{:?}", fit.fit.r2);
        // a fixed ridge smooths the plays' weights (the density's second differences) rather
        // than shrinking each
        let weights = |ridge: f64| -> Vec<f64> {
            let mut cfg = GreyBoxConfig::from_effect_list("hysteresis").unwrap();
            cfg.options.ridge = ridge;
            let fit = cfg.fit(&hysteretic).unwrap();
            fit.plant.spec.outputs[0]
                .paths
                .iter()
                .flat_map(|p| p.specs())
                .find_map(|e| match e.as_any().downcast_ref::<HysteresisSpec>() {
                    Some(HysteresisSpec::PrandtlIshlinskii(p)) => Some(p.weights.clone()),
                    _ => None,
                })
                .expect("a Prandtl-Ishlinskii operator on a path")
        };
        let roughness = |w: &[f64]| -> f64 {
            let d2: f64 = w
                .windows(3)
                .map(|t| (t[0] - 2.0 * t[1] + t[2]).powi(2))
                .sum();
            d2 / w.iter().map(|v| v * v).sum::<f64>()
        };
        // unridged: the lone play; a strong ridge: a smooth density that still carries the
        // loop (a ridge on each weight would have shrunk them all toward nothing)
        let (free, smooth) = (weights(0.0), weights(1e3));
        assert!(free.len() >= 3 && smooth.len() >= 3, "{free:?} {smooth:?}");
        assert!(roughness(&free) > 1.0, "{free:?}");
        assert!(roughness(&smooth) < 1e-3, "{smooth:?}");
        assert!(smooth.iter().sum::<f64>() > 0.2, "{smooth:?}");
    }
}
