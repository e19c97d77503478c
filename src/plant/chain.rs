//! Simulation of chain plants: paths (terms such as hysteresis + viscous, then path filters such
//! as dynamics) -> sum -> output filters and terms (creep, dynamics, drift) -> + offset -> sensor
//! (saturation), per output; each
//! operator runs over the whole signal at once.

use super::{OdePlant, OutputChain, Plant, PlantError, PlantKind};
use crate::effect::spec::BoxedOperator;
use crate::effect::{registry, EffectError, EffectParams, Slot};

fn effect_err(plant: &Plant, field: String, source: EffectError) -> PlantError {
    PlantError::Effect {
        path: plant.path.clone(),
        field,
        source,
    }
}

impl OutputChain {
    /// Noise-free response of this output to the plant's inputs (`o` is its index, for errors).
    /// Each operator runs over the whole signal in turn: paths, sum, creep, dynamics.
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
            let at = |e: &dyn EffectParams| format!("outputs[{o}].paths[{k}].{}", e.effect());
            let ops = |list: &[Box<dyn EffectParams>]| -> Result<Vec<BoxedOperator>, PlantError> {
                list.iter()
                    .map(|e| {
                        e.operator(ts)
                            .map_err(|err| effect_err(plant, at(e.as_ref()), err))
                    })
                    .collect()
            };
            paths.push((inputs[path.input], ops(&path.terms)?, ops(&path.filters)?));
        }
        let mut filters = self
            .filters
            .iter()
            .map(|e| {
                e.operator(ts)
                    .map_err(|err| effect_err(plant, format!("outputs[{o}].{}", e.effect()), err))
            })
            .collect::<Result<Vec<_>, _>>()?;
        // Each operator runs over the whole signal in one call (no virtual call per sample);
        // the operators do not share state, so this is the per-sample chain, the same bits.
        let mut w = vec![0.0; n];
        for (u, terms, filters) in paths.iter_mut() {
            let mut v = match terms.split_first_mut() {
                Some((first, rest)) => {
                    let mut v = first.apply(u);
                    for t in rest {
                        for (a, b) in v.iter_mut().zip(t.apply(u)) {
                            *a += b;
                        }
                    }
                    v
                }
                None => vec![0.0; n],
            };
            for f in filters.iter_mut() {
                v = f.apply(&v);
            }
            for (a, b) in w.iter_mut().zip(&v) {
                *a += b;
            }
        }
        // the output's filters and terms (creep, dynamics, drift), the offset, then the sensor
        let sensor: Vec<bool> = self
            .filters
            .iter()
            .map(|e| registry::effect(e.effect()).map(|x| x.slot()) == Some(Slot::Sensor))
            .collect();
        for (f, _) in filters.iter_mut().zip(&sensor).filter(|(_, s)| !**s) {
            w = f.apply(&w);
        }
        let mut out: Vec<f64> = w.into_iter().map(|v| v + self.offset).collect();
        for (f, _) in filters.iter_mut().zip(&sensor).filter(|(_, s)| **s) {
            out = f.apply(&out);
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
        self.simulate_each(inputs, ts)?.into_iter().collect()
    }

    /// [`Plant::simulate`] output by output: an output whose simulation fails (diverges, say)
    /// leaves the others' results standing. The error is for the plant as a whole (the number
    /// of inputs).
    #[allow(clippy::type_complexity)]
    pub fn simulate_each(
        &self,
        inputs: &[&[f64]],
        ts: f64,
    ) -> Result<Vec<Result<Vec<f64>, PlantError>>, PlantError> {
        if inputs.len() != self.inputs.len() {
            return Err(PlantError::InputCount {
                expected: self.inputs.len(),
                found: inputs.len(),
                names: self.inputs.join(", "),
            });
        }
        Ok(match &self.kind {
            PlantKind::Chain(chains) => chains
                .iter()
                .enumerate()
                .map(|(o, c)| c.simulate(self, o, inputs, ts))
                .collect(),
            PlantKind::Ode(OdePlant::BoucWenBenchmark(p)) => {
                vec![p.simulate(inputs[0], ts, false).map_err(PlantError::Ode)]
            }
        })
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
