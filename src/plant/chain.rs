//! Simulation of chain plants: paths -> sum -> creep -> dynamics, per output.

use super::{OutputChain, Plant, PlantError, PlantKind};
use crate::effect::{EffectError, Operator};

fn effect_err(plant: &Plant, field: String, source: EffectError) -> PlantError {
    PlantError::Effect {
        path: plant.path.clone(),
        field,
        source,
    }
}

impl OutputChain {
    /// Noise-free response of this output to the plant's inputs (`o` is its index, for errors).
    pub fn simulate(
        &self,
        plant: &Plant,
        o: usize,
        inputs: &[&[f64]],
        ts: f64,
    ) -> Result<Vec<f64>, PlantError> {
        let n = inputs[0].len();
        let mut acc = vec![0.0; n];
        for (k, path) in self.paths.iter().enumerate() {
            let mut w = path.hysteresis.operator().apply(inputs[path.input]);
            if let Some(d) = &path.dynamics {
                let mut op = d.operator(ts).map_err(|e| {
                    effect_err(plant, format!("outputs[{o}].paths[{k}].dynamics"), e)
                })?;
                w = op.apply(&w);
            }
            for (a, v) in acc.iter_mut().zip(&w) {
                *a += v;
            }
        }
        if let Some(c) = &self.creep {
            acc = c.operator(ts).apply(&acc);
        }
        if let Some(d) = &self.dynamics {
            let mut op = d
                .operator(ts)
                .map_err(|e| effect_err(plant, format!("outputs[{o}].dynamics"), e))?;
            acc = op.apply(&acc);
        }
        if self.offset != 0.0 {
            acc.iter_mut().for_each(|v| *v += self.offset);
        }
        if let Some((sample, &value)) = acc.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(PlantError::Diverged {
                output: self.name.clone(),
                sample,
                value,
            });
        }
        Ok(acc)
    }
}

impl Plant {
    /// Noise-free outputs for the given input signals (one per plant input, equal lengths),
    /// sampled every `ts` seconds, from rest.
    pub fn simulate(&self, inputs: &[&[f64]], ts: f64) -> Result<Vec<Vec<f64>>, PlantError> {
        if inputs.len() != self.inputs.len() {
            return Err(PlantError::InputCount {
                expected: self.inputs.len(),
                found: inputs.len(),
                names: self.inputs.join(", "),
            });
        }
        match &self.kind {
            PlantKind::Chain(chains) => chains
                .iter()
                .enumerate()
                .map(|(o, c)| c.simulate(self, o, inputs, ts))
                .collect(),
        }
    }

    /// Periodic steady state: the input is one period, repeated `periods` times from rest;
    /// the last period of the outputs is returned.
    pub fn simulate_periodic(
        &self,
        inputs: &[&[f64]],
        ts: f64,
        periods: usize,
    ) -> Result<Vec<Vec<f64>>, PlantError> {
        let n = inputs.first().map_or(0, |u| u.len());
        let long: Vec<Vec<f64>> = inputs.iter().map(|u| u.repeat(periods.max(1))).collect();
        let refs: Vec<&[f64]> = long.iter().map(Vec::as_slice).collect();
        let y = self.simulate(&refs, ts)?;
        Ok(y.into_iter().map(|v| v[v.len() - n..].to_vec()).collect())
    }
}
