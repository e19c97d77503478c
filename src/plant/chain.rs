//! Simulation of chain plants: paths (hysteresis + viscous, path dynamics) -> sum -> creep ->
//! dynamics, per output.

use super::{OdePlant, OutputChain, Plant, PlantError, PlantKind};
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
    /// One fused pass per sample: paths, sum, creep, dynamics.
    pub fn simulate(
        &self,
        plant: &Plant,
        o: usize,
        inputs: &[&[f64]],
        ts: f64,
    ) -> Result<Vec<f64>, PlantError> {
        let n = inputs[0].len();
        let mut paths = Vec::with_capacity(self.paths.len());
        for (k, path) in self.paths.iter().enumerate() {
            let dynamics = path
                .dynamics
                .as_ref()
                .map(|d| d.operator(ts))
                .transpose()
                .map_err(|e| effect_err(plant, format!("outputs[{o}].paths[{k}].dynamics"), e))?;
            let viscous = path
                .viscous
                .as_ref()
                .map(|v| v.operator(ts))
                .transpose()
                .map_err(|e| effect_err(plant, format!("outputs[{o}].paths[{k}].viscous"), e))?;
            paths.push((
                inputs[path.input],
                path.hysteresis.operator(),
                viscous,
                dynamics,
            ));
        }
        let mut creep = self.creep.as_ref().map(|c| c.operator(ts));
        let mut dynamics = self
            .dynamics
            .as_ref()
            .map(|d| d.operator(ts))
            .transpose()
            .map_err(|e| effect_err(plant, format!("outputs[{o}].dynamics"), e))?;
        let mut out = Vec::with_capacity(n);
        for k in 0..n {
            let mut w = 0.0;
            for (u, h, c, d) in paths.iter_mut() {
                let mut v = h.step(u[k]);
                if let Some(c) = c.as_mut() {
                    v += c.step(u[k]);
                }
                w += match d {
                    Some(d) => d.step(v),
                    None => v,
                };
            }
            if let Some(c) = creep.as_mut() {
                w = c.step(w);
            }
            if let Some(d) = dynamics.as_mut() {
                w = d.step(w);
            }
            out.push(w + self.offset);
        }
        if let Some((sample, &value)) = out.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(PlantError::Diverged {
                output: self.name.clone(),
                sample,
                value,
            });
        }
        Ok(out)
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
            PlantKind::Ode(OdePlant::BoucWenBenchmark(p)) => Ok(vec![p
                .simulate(inputs[0], ts, false)
                .map_err(|e| PlantError::Ode(e.to_string()))?]),
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
