//! A chain plant run one sample at a time, with its state in a value that can be copied: what
//! a compensator needs to try an input on a copy of the plant before it commits to one. The
//! same operators as [`super::Plant::simulate`], in the same order, so the same bits.

use super::{Plant, PlantError, PlantKind};
use crate::effect::spec::BoxedOperator;
use crate::effect::{registry, Slot};

/// One path: its input index, its terms and its filters.
#[derive(Clone)]
struct PathState {
    input: usize,
    terms: Vec<BoxedOperator>,
    filters: Vec<BoxedOperator>,
}

/// One output: its paths, its filters and terms (creep, dynamics, drift), the offset, then the
/// sensor (saturation).
#[derive(Clone)]
struct OutputState {
    paths: Vec<PathState>,
    filters: Vec<BoxedOperator>,
    offset: f64,
    sensors: Vec<BoxedOperator>,
}

/// A chain plant's state, one sample at a time.
#[derive(Clone)]
pub struct PlantState {
    outputs: Vec<OutputState>,
    inputs: usize,
}

impl Plant {
    /// The plant at rest, ready to be stepped at sampling period `ts`; `None` for an ODE plant
    /// (integrated over a whole record, not a sample at a time).
    pub fn state(&self, ts: f64) -> Result<Option<PlantState>, PlantError> {
        let PlantKind::Chain(chains) = &self.kind else {
            return Ok(None);
        };
        let op = |e: &dyn crate::effect::EffectParams, at: String| {
            e.operator(ts).map_err(|source| PlantError::Effect {
                path: self.path.clone(),
                field: at,
                source,
            })
        };
        let mut outputs = Vec::new();
        for (o, c) in chains.iter().enumerate() {
            let mut paths = Vec::new();
            for (k, p) in c.paths.iter().enumerate() {
                let at = |e: &dyn crate::effect::EffectParams| {
                    format!("outputs[{o}].paths[{k}].{}", e.effect())
                };
                paths.push(PathState {
                    input: p.input,
                    terms: p
                        .terms
                        .iter()
                        .map(|e| op(e.as_ref(), at(e.as_ref())))
                        .collect::<Result<_, _>>()?,
                    filters: p
                        .filters
                        .iter()
                        .map(|e| op(e.as_ref(), at(e.as_ref())))
                        .collect::<Result<_, _>>()?,
                });
            }
            let (mut filters, mut sensors) = (Vec::new(), Vec::new());
            for e in &c.filters {
                let f = op(e.as_ref(), format!("outputs[{o}].{}", e.effect()))?;
                if registry::effect(e.effect()).map(|x| x.slot()) == Some(Slot::Sensor) {
                    sensors.push(f);
                } else {
                    filters.push(f);
                }
            }
            outputs.push(OutputState {
                paths,
                filters,
                offset: c.offset,
                sensors,
            });
        }
        Ok(Some(PlantState {
            outputs,
            inputs: self.inputs.len(),
        }))
    }
}

impl PlantState {
    /// Number of inputs.
    pub fn inputs(&self) -> usize {
        self.inputs
    }

    /// Number of outputs.
    pub fn outputs(&self) -> usize {
        self.outputs.len()
    }

    /// One sample: the inputs `u` (one per plant input) in, the outputs written to `y`.
    pub fn step(&mut self, u: &[f64], y: &mut [f64]) {
        for (out, yo) in self.outputs.iter_mut().zip(y.iter_mut()) {
            let mut w = 0.0;
            for p in out.paths.iter_mut() {
                let x = u[p.input];
                let mut v = match p.terms.split_first_mut() {
                    Some((first, rest)) => {
                        let mut v = first.step(x);
                        for t in rest {
                            v += t.step(x);
                        }
                        v
                    }
                    None => 0.0,
                };
                for f in p.filters.iter_mut() {
                    v = f.step(v);
                }
                w += v;
            }
            for f in out.filters.iter_mut() {
                w = f.step(w);
            }
            let mut v = w + out.offset;
            for s in out.sensors.iter_mut() {
                v = s.step(v);
            }
            *yo = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::plant::PlantSpec;
    use std::path::Path;

    /// Stepping the state gives the same bits as simulating the whole record.
    #[test]
    fn stepping_is_simulating() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        for f in [
            "plants/piezo_2dof.json",
            "plants/hidden_creep_piezo.json",
            "plants/prandtl_ishlinskii_asymmetric.json",
        ] {
            let plant = PlantSpec::read(&root.join(f))
                .unwrap()
                .check(Path::new(f))
                .unwrap();
            let ni = plant.inputs.len();
            let u: Vec<Vec<f64>> = (0..ni)
                .map(|j| {
                    (0..3000)
                        .map(|k| 30.0 * (0.003 * k as f64 * (j + 1) as f64).sin())
                        .collect()
                })
                .collect();
            let refs: Vec<&[f64]> = u.iter().map(Vec::as_slice).collect();
            let whole = plant.simulate(&refs, 1e-4).unwrap();
            let mut s = plant.state(1e-4).unwrap().unwrap();
            let mut y = vec![0.0; s.outputs()];
            for k in 0..3000 {
                let uk: Vec<f64> = u.iter().map(|c| c[k]).collect();
                s.step(&uk, &mut y);
                for (o, v) in y.iter().enumerate() {
                    assert_eq!(
                        v.to_bits(),
                        whole[o][k].to_bits(),
                        "{f} output {o} sample {k}"
                    );
                }
            }
        }
    }
}
