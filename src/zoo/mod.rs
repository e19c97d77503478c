//! # The plant zoo: plants we did not write, to develop and judge against
//!
//! `make` draws `count` random plants from the effect library over wide, documented physical
//! ranges (each effect's `draw`: [`crate::effect::hysteresis::draw`],
//! [`crate::effect::creep::draw`], [`crate::effect::dynamics::draw`]), an excitation for each
//! input ([`draw`]), simulates a record of each and writes the three files, so that any member
//! can be re-run with `hystbench simulate`. Member `i` of seed `s` is the same whatever the
//! zoo's size. [`score`] runs the default identifier and a linear ARX baseline on every record
//! and reports the distribution of the free-run test R^2 per class.
//!
//! A zoo folder:
//!
//! ```text
//! DIR/zoo.json                 the index: seed, count, and per member its class and files
//! DIR/plants/0000.json         plant files
//! DIR/scenarios/0000.json      scenario files (noise set from the noiseless record's range)
//! DIR/records/0000.csv         the records (with `simulate`'s sidecar 0000.json)
//! DIR/score/                   what `zoo score` writes
//! ```

pub mod draw;
pub mod hidden;
pub mod score;

pub use draw::{member, Class, Member};
pub use hidden::{score_loop, LoopOptions, LoopScore};
pub use score::{
    score, score_members, Miss, NoiselessTraining, RecordScore, Schedule, ScoreOptions, ZooScore,
};

use crate::data::{format_csv, JsonFileError};
use crate::plant::PlantError;
use crate::scenario::{NoiseLevel, ScenarioError};
use crate::simulator::{simulate_scenario, SimulateError};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The index file's `format` field.
pub const FORMAT: &str = "hystbench-zoo";
/// The index file version this code writes and reads.
pub const VERSION: u32 = 1;
/// The index file's name in a zoo folder.
pub const INDEX: &str = "zoo.json";

/// The most members of one zoo.
pub const MAX_MEMBERS: usize = 100_000;

/// What can go wrong making or scoring a zoo.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ZooError {
    #[error("--count must be at least 1 (got 0)")]
    NoMembers,
    #[error("--count {count}: at most {MAX_MEMBERS} members in one zoo; make several zoos with different --seed")]
    TooMany { count: usize },
    #[error("--extra {effect}: the zoo draws only effects sized by an output's range, or drawn on a path's operator, on top of its plants ({allowed})")]
    Extra { effect: String, allowed: String },
    #[error("{dir}: exists and is not a zoo folder (no {INDEX}); choose another folder")]
    NotAZoo { dir: PathBuf },
    #[error("{dir}: exists; pass --force to replace this zoo")]
    Exists { dir: PathBuf },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    File(#[from] JsonFileError),
    #[error("{path}: not a zoo index: {why}")]
    NotAnIndex { path: PathBuf, why: String },
    #[error("{dir}: the zoo has no members")]
    Empty { dir: PathBuf },
    #[error("member {index}: {source}")]
    Plant { index: usize, source: PlantError },
    #[error("member {index}: {source}")]
    Scenario { index: usize, source: ScenarioError },
    #[error("member {index}: {source}")]
    Simulate { index: usize, source: SimulateError },
    #[error("{0}")]
    Data(#[from] crate::data::DataError),
    #[error("{path}: {source}")]
    Narx {
        path: PathBuf,
        source: crate::narx::NarxError,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> ZooError + '_ {
    move |source| ZooError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The index of a zoo folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZooIndex {
    pub format: String,
    pub version: u32,
    pub seed: u64,
    /// Effects drawn on top of the default zoo (`zoo --extra`), sized by each output's range
    /// (hysteresis: by each path's input peak).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extra: Vec<crate::effect::EffectName>,
    /// The records' realization (`zoo --realization`): 0, the zoo as drawn; r, the same plants
    /// and protocols with every scenario's seed r further on.
    #[serde(default, skip_serializing_if = "crate::data::is_default")]
    pub realization: u64,
    pub members: Vec<IndexEntry>,
}

/// One member in the index (paths relative to the zoo folder).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IndexEntry {
    pub index: usize,
    pub class: Class,
    pub samples: usize,
    pub sampling_period_s: f64,
    pub record: String,
    pub plant: String,
    pub scenario: String,
}

impl ZooIndex {
    /// Reads the index of zoo folder `dir`.
    pub fn read(dir: &Path) -> Result<ZooIndex, ZooError> {
        let path = dir.join(INDEX);
        if !path.exists() {
            return Err(ZooError::NotAZoo {
                dir: dir.to_path_buf(),
            });
        }
        let text = crate::data::read_json_text(&path)?;
        let header = crate::data::FileHeader::read(&path, &text)?;
        if header.format_str() != Some(FORMAT) {
            return Err(ZooError::NotAnIndex {
                path,
                why: format!("`format` is not \"{FORMAT}\""),
            });
        }
        let index: ZooIndex = crate::data::parse_json_file(&path, &text)?;
        if index.version != VERSION {
            return Err(ZooError::NotAnIndex {
                path,
                why: format!(
                    "version {} is not supported; this hystbench reads version {VERSION}",
                    index.version
                ),
            });
        }
        if index.members.is_empty() {
            return Err(ZooError::Empty {
                dir: dir.to_path_buf(),
            });
        }
        Ok(index)
    }
}

/// The files of one member, in memory.
struct MemberFiles {
    entry: IndexEntry,
    plant: String,
    scenario: String,
    record: String,
    sidecar: String,
}

/// Draws member `index` and simulates its record: once without noise to measure each output's
/// range, then with the noise the member draws (a share of that range) written into its
/// scenario, so that `simulate` with the written files gives the same record. Realization
/// `realization` moves the scenario's seed that far (new noise, new draws of the random
/// excitations) and leaves the plant and the protocol as drawn.
fn make_member(
    seed: u64,
    index: usize,
    extra: &[crate::effect::EffectName],
    realization: u64,
) -> Result<MemberFiles, ZooError> {
    let mut m = member(seed, index);
    if !extra.is_empty() {
        draw_extra(&mut m, seed, index, extra)?;
    }
    if realization > 0 {
        m.scenario.seed = m.scenario.seed.wrapping_add(realization);
        m.scenario.description += &format!(" Realization {realization}.");
    }
    let name = format!("{index:04}");
    let plant_path = PathBuf::from(format!("plants/{name}.json"));
    let scen_path = PathBuf::from(format!("scenarios/{name}.json"));
    let plant = m
        .plant
        .check(&plant_path)
        .map_err(|source| ZooError::Plant { index, source })?;
    let run = |spec: &crate::scenario::ScenarioSpec| -> Result<_, ZooError> {
        let scenario = spec
            .check(&scen_path)
            .map_err(|source| ZooError::Scenario { index, source })?;
        simulate_scenario(&plant, &scenario, None)
            .map_err(|source| ZooError::Simulate { index, source })
    };
    let clean = run(&m.scenario)?;
    let noise: Vec<f64> = clean
        .record
        .outputs
        .iter()
        .zip(&m.noise_share)
        .map(|(o, share)| share * crate::metrics::ptp(&o.values).max(f64::MIN_POSITIVE))
        .collect();
    m.scenario.noise_std = NoiseLevel::PerOutput(noise);
    let sim = run(&m.scenario)?;
    let (names, cols) = sim.record.to_columns();
    let record_path = format!("records/{name}.csv");
    let record = format_csv(Path::new(&record_path), &names, &cols)?;
    let json = |v: &dyn erased_serde::Serialize| -> String {
        serde_json::to_string_pretty(v).expect("specs serialise") + "\n"
    };
    Ok(MemberFiles {
        entry: IndexEntry {
            index,
            class: m.class,
            samples: m.scenario.samples,
            sampling_period_s: m.scenario.sampling_period_s,
            record: record_path,
            plant: plant_path.display().to_string(),
            scenario: scen_path.display().to_string(),
        },
        plant: json(&m.plant),
        scenario: json(&m.scenario),
        record,
        sidecar: json(&sim.provenance),
    })
}

/// Draws the `extra` effects on member `m`'s outputs (each output gets each with probability
/// 1/2, from its own stream so that the rest of the member is the default zoo's): each effect
/// sizes itself on the output's noiseless signal without it ([`crate::effect::Effect::draw_on_output`]).
fn draw_extra(
    m: &mut Member,
    seed: u64,
    index: usize,
    extra: &[crate::effect::EffectName],
) -> Result<(), ZooError> {
    let mut dice = crate::effect::draw::Dice::new(seed ^ 0x5eed_e47a, index as u64);
    let scen_path = PathBuf::from(format!("scenarios/{index:04}.json"));
    let scenario = m
        .scenario
        .check(&scen_path)
        .map_err(|source| ZooError::Scenario { index, source })?;
    let mut drawn: Vec<(String, String)> = Vec::new();
    for &name in extra {
        let Some(effect) = crate::effect::registry::effect(name) else {
            continue;
        };
        let plant_path = PathBuf::from(format!("plants/{index:04}.json"));
        let plant = m
            .plant
            .check(&plant_path)
            .map_err(|source| ZooError::Plant { index, source })?;
        let clean = simulate_scenario(&plant, &scenario, None)
            .map_err(|source| ZooError::Simulate { index, source })?;
        let inputs = &m.plant.inputs;
        for (o, out) in m.plant.outputs.iter_mut().enumerate() {
            if !dice.chance(0.5) {
                continue;
            }
            if effect.draws_onto_paths() {
                // on every path of the output that has the effect, driven by its input
                for path in out.paths.iter_mut() {
                    let Some(j) = inputs.iter().position(|i| *i == path.input) else {
                        continue;
                    };
                    let u = &clean.record.inputs[j].values;
                    for spec in path.effects.iter_mut().filter(|s| s.effect() == name) {
                        if let Some(new) = effect.draw_onto_path(spec.as_ref(), u, &mut dice) {
                            *spec = new;
                            drawn.push((
                                out.name.clone(),
                                format!("{name} on the path of {}", path.input),
                            ));
                        }
                    }
                }
                continue;
            }
            let y = &clean.record.outputs[o].values;
            let ts = clean.record.ts;
            if let Some(at) = out.effects.iter().position(|s| s.effect() == name) {
                // drawn on top of what the output has (a second mode on its mode)
                if let Some(spec) = effect.draw_onto(out.effects[at].as_ref(), y, ts, &mut dice) {
                    out.effects[at] = spec;
                    drawn.push((out.name.clone(), format!("{name} on top")));
                }
            } else if let Some(spec) = effect.draw_on_output(y, ts, &mut dice) {
                out.effects.push(spec);
                // in registry (chain) order
                out.effects.sort_by_key(|s| s.effect());
                drawn.push((out.name.clone(), name.to_string()));
            }
        }
    }
    let drawn: Vec<String> = drawn.iter().map(|(o, e)| format!("{o}: {e}")).collect();
    m.plant.description += &format!(
        " Extra effects drawn: {}.",
        if drawn.is_empty() {
            "none".to_string()
        } else {
            drawn.join(", ")
        }
    );
    Ok(())
}

/// The indices of the first `count` members of seed `seed` whose class is one of `classes`
/// (every class when empty).
pub fn member_indices(seed: u64, count: usize, classes: &[Class]) -> Vec<usize> {
    (0..)
        .filter(|&i| classes.is_empty() || classes.contains(&draw::class_of(seed, i)))
        .take(count)
        .collect()
}

/// Makes a zoo of `count` members of seed `seed` in `dir` (only members of `classes` when it is
/// not empty; each keeps its index, so member i is the same in every zoo of its seed). The
/// folder is written whole or not at all (built beside it, then moved in place); an existing
/// zoo is replaced only with `force`, and a folder that is not a zoo never. `progress` hears
/// each member as it is done (in any order).
/// The `extra` effects are drawn in chain order, each once, whatever order they come in.
/// Realization `realization` > 0 draws the same plants and protocols with other records
/// ([`ZooIndex::realization`]): a paired comparison of two identifiers on several
/// realizations tells a change from the spread of the records.
#[allow(clippy::too_many_arguments)]
pub fn make(
    dir: &Path,
    count: usize,
    seed: u64,
    classes: &[Class],
    extra: &[crate::effect::EffectName],
    realization: u64,
    force: bool,
    progress: &(dyn Fn(&IndexEntry) + Sync),
) -> Result<ZooIndex, ZooError> {
    if count == 0 {
        return Err(ZooError::NoMembers);
    }
    if count > MAX_MEMBERS {
        return Err(ZooError::TooMany { count });
    }
    let drawable = |e: &dyn crate::effect::Effect| {
        let probe: Vec<f64> = (0..100).map(|k| (0.1 * k as f64).sin()).collect();
        e.draws_onto_paths()
            || e.draw_on_output(&probe, 1e-3, &mut crate::effect::draw::Dice::new(0, 0))
                .is_some()
    };
    for name in extra {
        if !crate::effect::registry::effect(*name).is_some_and(drawable) {
            let allowed: Vec<String> = crate::effect::effects()
                .into_iter()
                .filter(|e| drawable(*e))
                .map(|e| e.name().to_string())
                .collect();
            return Err(ZooError::Extra {
                effect: name.to_string(),
                allowed: allowed.join(", "),
            });
        }
    }
    // drawn in chain order, each once, whatever order they were typed in: an effect later in
    // the chain (saturation's limits) is sized on what the earlier ones (hysteresis's
    // envelopes) made of the output, and the same set draws the same plants
    let mut extra = extra.to_vec();
    extra.sort();
    extra.dedup();
    let extra = &extra[..];
    let replace = check_target(dir, force)?;
    let files: Vec<MemberFiles> = member_indices(seed, count, classes)
        .into_par_iter()
        .map(|i| {
            let f = make_member(seed, i, extra, realization)?;
            progress(&f.entry);
            Ok(f)
        })
        .collect::<Result<_, ZooError>>()?;
    let index = ZooIndex {
        format: FORMAT.into(),
        version: VERSION,
        seed,
        extra: extra.to_vec(),
        realization,
        members: files.iter().map(|f| f.entry.clone()).collect(),
    };
    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let tmp = parent.join(format!(
        ".{}.partial-{}",
        dir.file_name()
            .map_or("zoo".into(), |n| n.to_string_lossy()),
        std::process::id()
    ));
    let written = write_folder(&tmp, &index, &files);
    if let Err(e) = written {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    if replace {
        std::fs::remove_dir_all(dir).map_err(io(dir))?;
    }
    std::fs::rename(&tmp, dir).map_err(io(dir))?;
    Ok(index)
}

/// Whether `dir` may be written: absent or empty (false), an existing zoo with `force` (true:
/// replace it); else an error.
fn check_target(dir: &Path, force: bool) -> Result<bool, ZooError> {
    if !dir.exists() {
        return Ok(false);
    }
    let empty = std::fs::read_dir(dir).map_err(io(dir))?.next().is_none();
    if empty {
        std::fs::remove_dir(dir).map_err(io(dir))?;
        return Ok(false);
    }
    if !dir.join(INDEX).exists() {
        return Err(ZooError::NotAZoo {
            dir: dir.to_path_buf(),
        });
    }
    if !force {
        return Err(ZooError::Exists {
            dir: dir.to_path_buf(),
        });
    }
    Ok(true)
}

fn write_folder(tmp: &Path, index: &ZooIndex, files: &[MemberFiles]) -> Result<(), ZooError> {
    for sub in ["plants", "scenarios", "records"] {
        let d = tmp.join(sub);
        std::fs::create_dir_all(&d).map_err(io(&d))?;
    }
    let write = |rel: &str, text: &str| -> Result<(), ZooError> {
        let p = tmp.join(rel);
        std::fs::write(&p, text).map_err(io(&p))
    };
    for f in files {
        write(&f.entry.plant, &f.plant)?;
        write(&f.entry.scenario, &f.scenario)?;
        write(&f.entry.record, &f.record)?;
        write(&f.entry.record.replace(".csv", ".json"), &f.sidecar)?;
    }
    let text = serde_json::to_string_pretty(index).expect("the index serialises") + "\n";
    write(INDEX, &text)
}

/// The member's outputs without measurement noise (its plant and scenario re-run).
pub(crate) fn noiseless(dir: &Path, e: &IndexEntry) -> Result<Vec<Vec<f64>>, ZooError> {
    let index = e.index;
    let plant_path = dir.join(&e.plant);
    let scen_path = dir.join(&e.scenario);
    let plant = crate::plant::PlantSpec::read(&plant_path)
        .and_then(|p| p.check(&plant_path))
        .map_err(|source| ZooError::Plant { index, source })?;
    let mut spec = crate::scenario::ScenarioSpec::read(&scen_path)
        .map_err(|source| ZooError::Scenario { index, source })?;
    spec.noise_std = crate::scenario::NoiseLevel::All(0.0);
    let scenario = spec
        .check(&scen_path)
        .map_err(|source| ZooError::Scenario { index, source })?;
    let sim = crate::simulator::simulate_scenario(&plant, &scenario, None)
        .map_err(|source| ZooError::Simulate { index, source })?;
    Ok(sim.record.outputs.into_iter().map(|s| s.values).collect())
}

/// The median (upper for an even count) of the values, `None` when there are none.
pub(crate) fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| v[v.len() / 2])
}

/// `k (p %)` of `n` for the reports (`-` when `n` is 0).
pub(crate) fn share(k: usize, n: usize) -> String {
    if n == 0 {
        "-".into()
    } else {
        format!("{k} ({:.0} %)", 100.0 * k as f64 / n as f64)
    }
}
