//! A fitted NARX model run one sample at a time, with its state in a value that can be copied:
//! what a compensator needs to try an input on a copy of the model before it commits to one
//! ([`crate::compensate`]). The same operations as the free run of
//! [`FittedNarx::predict`] on a record without measured outputs (every output seeded at rest),
//! in the same order, so the same bits: the feature signals are stepped operators of the
//! effect library, each output's networks read their lags from short windows, a decimated
//! model keeps one state per phase, and a grey-box base is stepped beside it
//! ([`crate::plant::PlantState`]).
//!
//! An output of a short record on the grey-box base alone steps its committee beside it and
//! answers their median ([`super::consensus`]).
//!
//! One difference, by necessity: the free run of a record leaves an ensemble member (or a
//! committee member) that diverges anywhere out of the whole record, while a stepped model can
//! only leave it out from the sample where it diverges on. Both agree whenever no member
//! diverges.

use super::base::BaseUse;
use super::config::Combine;
use super::mlp::Mlp;
use super::regressors::{Regressor, Standardiser};
use super::train::{OneHidden, OneHiddenWork};
use super::{FittedNarx, NarxError};
use crate::effect::spec::BoxedOperator;
use crate::plant::PlantState;
use std::path::Path;
use std::sync::Arc;

/// One network, packed for one regressor at a time when it has one hidden layer.
#[derive(Debug, Clone)]
enum Net {
    OneHidden(OneHidden),
    Deep(Mlp),
}

/// What does not change while the model runs: each output's networks, regressor, scaling
/// and bounds.
#[derive(Debug)]
struct Shared {
    inputs: usize,
    outputs: Vec<OutputShared>,
    input_scaling: Vec<Standardiser>,
    /// The model samples every `decimation`th sample, one state per phase.
    decimation: usize,
    /// Samples (per phase) seeded at rest before the first full regressor.
    start: usize,
    combine: Combine,
    /// Exogenous window: n_u + d values.
    window: usize,
}

#[derive(Debug)]
struct OutputShared {
    regressor: Regressor,
    scaling: Standardiser,
    nets: Vec<Net>,
    bounds: (f64, f64),
    uses: BaseUse,
    /// The standardised value of a physical zero (the seed).
    seed: f64,
    /// Where this output's networks' workspaces start in [`Scratch::work`].
    work: usize,
}

/// One phase's state: its feature operators, the windows of its exogenous signals and of
/// each output's members' outputs, and which members still run.
#[derive(Clone)]
struct Phase {
    stepped: usize,
    features: Vec<(usize, BoxedOperator)>,
    u: Vec<Vec<f64>>,
    /// Per output, per member: the last n_y standardised outputs, oldest first.
    y: Vec<Vec<Vec<f64>>>,
    alive: Vec<Vec<bool>>,
}

/// A fitted NARX model's state, one sample at a time.
#[derive(Clone)]
pub struct NarxState {
    shared: Arc<Shared>,
    phases: Vec<Phase>,
    k: usize,
    base: Option<PlantState>,
    g: Vec<f64>,
    /// Per output, its committee's plants and whether each still runs (finite so far); the
    /// base's own run first ([`Committee`]).
    committees: Vec<Committee>,
    scratch: Scratch,
}

/// An output's grey-box committee, stepped beside the base: the output answers the median of
/// the base's run and the members' that still run (`narx::consensus::committee_median`).
#[derive(Clone, Default)]
struct Committee {
    members: Vec<PlantState>,
    /// The base's run first, then each member's.
    alive: Vec<bool>,
    /// A member's outputs (every output of its plant) at this sample.
    out: Vec<f64>,
    column: Vec<f64>,
}

impl Committee {
    /// Output `o`'s value at this sample, from the base's `g` and its members stepped on `u`.
    fn step(&mut self, o: usize, u: &[f64], g: f64) -> f64 {
        if self.members.is_empty() {
            return g;
        }
        self.column.clear();
        let at = |alive: &mut bool, v: f64, column: &mut Vec<f64>| {
            *alive &= v.is_finite();
            if *alive {
                column.push(v);
            }
        };
        at(&mut self.alive[0], g, &mut self.column);
        for (m, alive) in self.members.iter_mut().zip(&mut self.alive[1..]) {
            m.step(u, &mut self.out);
            at(alive, self.out[o], &mut self.column);
        }
        if self.column.is_empty() {
            return g;
        }
        super::consensus::median(&mut self.column)
    }
}

impl FittedNarx {
    /// The model at rest, ready to be stepped at sampling period `ts` (the record's, before
    /// any decimation of the model). `path` names the model file in errors.
    pub fn state(&self, ts: f64, path: &Path) -> Result<NarxState, NarxError> {
        let cfg = &self.config;
        let s = cfg.decimation.max(1);
        let base = match &self.base {
            Some(b) if b.active() => match b.plant(path)? {
                Some(p) => p.state(ts).map_err(|e| NarxError::Damaged {
                    path: path.to_path_buf(),
                    why: format!("its grey-box base cannot be stepped: {e}"),
                })?,
                None => None,
            },
            _ => None,
        };
        let uses = |o: usize| match &self.base {
            Some(b) if base.is_some() => b.uses(o),
            _ => BaseUse::Network,
        };
        // the committees of the outputs on the base alone (a member that cannot be stepped
        // takes no part, as one that cannot be run in the free run)
        let committees: Vec<Committee> = (0..self.outputs.len())
            .map(|o| match &self.base {
                Some(b) if uses(o) == BaseUse::Base => {
                    let members: Vec<PlantState> = b
                        .committee_plants(o, path)?
                        .iter()
                        .filter_map(|p| p.state(ts).ok().flatten())
                        .collect();
                    Ok(Committee {
                        alive: vec![true; members.len() + 1],
                        members,
                        out: vec![0.0; self.outputs.len()],
                        column: Vec::new(),
                    })
                }
                _ => Ok(Committee::default()),
            })
            .collect::<Result<_, NarxError>>()?;
        let mut first = 0;
        let outputs: Vec<OutputShared> = self
            .outputs
            .iter()
            .enumerate()
            .map(|(o, m)| OutputShared {
                work: {
                    let at = first;
                    first += 1 + m.ensemble.len();
                    at
                },
                regressor: m.regressor.clone(),
                scaling: m.scaling,
                nets: m
                    .members()
                    .map(|n| {
                        if n.sizes.len() == 3 {
                            Net::OneHidden(OneHidden::new(n, m.regressor.lags.output))
                        } else {
                            Net::Deep(n.clone())
                        }
                    })
                    .collect(),
                bounds: m.free_run_bounds(),
                uses: uses(o),
                seed: m.scaling.apply(&[0.0])[0],
            })
            .collect();
        let lags = cfg.lags;
        let window = lags.input + lags.delay;
        let n_exo = cfg.n_signals();
        let phase = Phase {
            stepped: 0,
            features: cfg
                .features
                .iter()
                .map(|f| {
                    f.operator(ts * s as f64)
                        .map(|op| (f.input(), op))
                        .ok_or_else(|| NarxError::Damaged {
                            path: path.to_path_buf(),
                            why: format!("feature {f:?} has the wrong number of parameters"),
                        })
                })
                .collect::<Result<_, _>>()?,
            u: vec![vec![0.0; window]; n_exo],
            y: outputs
                .iter()
                .map(|o| vec![vec![0.0; lags.output]; o.nets.len()])
                .collect(),
            alive: outputs.iter().map(|o| vec![true; o.nets.len()]).collect(),
        };
        let work = outputs
            .iter()
            .flat_map(|o| o.nets.iter())
            .map(|n| match n {
                Net::OneHidden(h) => Some(h.workspace()),
                Net::Deep(_) => None,
            })
            .collect();
        let width = lags.width(n_exo);
        let acts = self
            .outputs
            .iter()
            .flat_map(|o| o.members())
            .map(Mlp::acts_len)
            .max()
            .unwrap_or(0);
        let most = outputs.iter().map(|o| o.nets.len()).max().unwrap_or(0);
        let no = outputs.len();
        Ok(NarxState {
            shared: Arc::new(Shared {
                inputs: cfg.inputs.len(),
                outputs,
                input_scaling: self.input_scaling.clone(),
                decimation: s,
                start: lags.start(),
                combine: cfg.robust.combine,
                window,
            }),
            phases: vec![phase; s],
            k: 0,
            base,
            g: vec![0.0; no],
            committees,
            scratch: Scratch {
                work,
                x: vec![0.0; width],
                acts: vec![0.0; acts],
                values: Vec::with_capacity(most),
            },
        })
    }
}

impl NarxState {
    pub fn inputs(&self) -> usize {
        self.shared.inputs
    }

    pub fn outputs(&self) -> usize {
        self.shared.outputs.len()
    }

    /// Samples from rest over which no output answers the input: the networks' seed (their
    /// first regressors are not full yet), unless a grey-box base answers beside them.
    pub fn seeded(&self) -> usize {
        if self.base.is_some() {
            0
        } else {
            self.shared.start * self.shared.decimation
        }
    }

    /// One sample: the outputs `y` for the inputs `u`. An output whose every network left
    /// its range (diverged) is NaN, or the grey-box base's alone when the networks only model
    /// its residual.
    pub fn step(&mut self, u: &[f64], y: &mut [f64]) {
        if let Some(b) = self.base.as_mut() {
            b.step(u, &mut self.g);
            for (o, c) in self.committees.iter_mut().enumerate() {
                self.g[o] = c.step(o, u, self.g[o]);
            }
        }
        let s = self.shared.decimation;
        advance(
            &self.shared,
            &mut self.phases[self.k % s],
            &mut self.scratch,
            u,
            &self.g,
            y,
            None,
        );
        self.k += 1;
    }

    /// Output `o` after `delay` more samples with the inputs `u` held, on a copy: the
    /// compensator's trial of an input. Without a base, and when the delay is whole phases,
    /// only the current phase and output run (the other phases do not reach output `o` then).
    pub fn ahead(&self, u: &[f64], delay: usize, o: usize) -> f64 {
        let s = self.shared.decimation;
        let mut y = vec![0.0; self.outputs()];
        if self.base.is_some() || !delay.is_multiple_of(s) {
            let mut c = self.clone();
            for _ in 0..=delay {
                c.step(u, &mut y);
            }
            return y[o];
        }
        let mut ph = self.phases[self.k % s].clone();
        let mut scratch = self.scratch.clone();
        for _ in 0..=delay / s {
            advance(
                &self.shared,
                &mut ph,
                &mut scratch,
                u,
                &self.g,
                &mut y,
                Some(o),
            );
        }
        y[o]
    }
}

/// Buffers of one step.
#[derive(Clone)]
struct Scratch {
    /// One per network of every output, in order (`None` for a deep network).
    work: Vec<Option<OneHiddenWork>>,
    x: Vec<f64>,
    acts: Vec<f64>,
    values: Vec<f64>,
}

/// One sample of one phase: the outputs `y` for the inputs `u` and the base's outputs `g`
/// (every output, or only output `only`: the others are then left behind).
fn advance(
    sh: &Shared,
    ph: &mut Phase,
    scratch: &mut Scratch,
    u: &[f64],
    g: &[f64],
    y: &mut [f64],
    only: Option<usize>,
) {
    // the exogenous signals: the inputs, then the features, standardised
    let ni = u.len();
    for (i, w) in ph.u.iter_mut().enumerate() {
        let v = if i < ni {
            u[i]
        } else {
            let (j, op) = &mut ph.features[i - ni];
            op.step(u[*j])
        };
        push(w, sh.input_scaling[i].apply_one(v));
    }
    for (o, os) in sh.outputs.iter().enumerate() {
        if only.is_some_and(|w| w != o) {
            continue;
        }
        let z = if ph.stepped < sh.start {
            for w in ph.y[o].iter_mut() {
                push(w, os.seed);
            }
            os.seed
        } else if os.uses == BaseUse::Base {
            f64::NAN
        } else {
            let reg = &os.regressor;
            let (ny, sc) = (reg.lags.output, reg.scale());
            scratch.values.clear();
            for (m, net) in os.nets.iter().enumerate() {
                if !ph.alive[o][m] {
                    continue;
                }
                let yw = &ph.y[o][m];
                let out = match net {
                    Net::OneHidden(h) => {
                        let w = scratch.work[os.work + m]
                            .as_mut()
                            .expect("a workspace per packed network");
                        reg.fill_inputs(&ph.u, sh.window - 1, &mut w.x);
                        reg.fill_outputs(yw, ny, &mut w.x);
                        h.output(w)
                    }
                    Net::Deep(mlp) => {
                        reg.fill_outputs(yw, ny, &mut scratch.x);
                        reg.fill_inputs(&ph.u, sh.window - 1, &mut scratch.x);
                        mlp.forward(&scratch.x, &mut scratch.acts);
                        mlp.output(&scratch.acts)[0]
                    }
                };
                let v = reg.base(yw, ny) + sc * out;
                if v >= os.bounds.0 && v <= os.bounds.1 {
                    push(&mut ph.y[o][m], v);
                    scratch.values.push(v);
                } else {
                    ph.alive[o][m] = false;
                }
            }
            if scratch.values.is_empty() {
                f64::NAN
            } else {
                sh.combine.apply(&mut scratch.values)
            }
        };
        y[o] = match os.uses {
            BaseUse::Network => os.scaling.invert(z),
            BaseUse::Base => g[o],
            BaseUse::BaseAndNetwork if z.is_nan() => g[o],
            BaseUse::BaseAndNetwork => os.scaling.invert(z) + g[o],
        };
    }
    ph.stepped += 1;
}

/// Shift a window by one and put `v` last.
#[inline]
fn push(w: &mut [f64], v: f64) {
    if let Some(last) = w.len().checked_sub(1) {
        w.copy_within(1.., 0);
        w[last] = v;
    }
}
