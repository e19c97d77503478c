//! The plant zoo: reproducible, every member re-runs with `simulate`, members do not depend on
//! the zoo's size, bad input refused with nothing half written, and `zoo score` on a small zoo
//! (the CI's zoo; the 200-record run is a bench: `benches/zoo.sh`).

mod common;

use common::{hystbench, s, stderr};
use hystbench::zoo::{self, Class, ZooIndex};
use std::path::Path;

/// `simulate` with member `m`'s plant and scenario files of zoo `dir` writes (to `out`) its
/// record again, byte for byte.
fn reruns(dir: &Path, m: &zoo::IndexEntry, out: &Path) {
    let o = hystbench(&[
        "simulate",
        "--plant",
        s(&dir.join(&m.plant)),
        "--scenario",
        s(&dir.join(&m.scenario)),
        "--out",
        s(out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(out).unwrap(),
        std::fs::read(dir.join(&m.record)).unwrap(),
        "member {}",
        m.index
    );
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for sub in ["plants", "scenarios", "records"] {
        let mut names: Vec<_> = std::fs::read_dir(dir.join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        names.sort();
        for p in names {
            out.push((
                p.strip_prefix(dir).unwrap().display().to_string(),
                std::fs::read(&p).unwrap(),
            ));
        }
    }
    out.push((
        "zoo.json".into(),
        std::fs::read(dir.join("zoo.json")).unwrap(),
    ));
    out
}

#[test]
fn a_zoo_is_reproducible_and_each_member_reruns_with_simulate() {
    let t = tempfile::tempdir().unwrap();
    let (a, b) = (t.path().join("a"), t.path().join("b"));
    let short = "1dof-short,1dof-tiny,2dof-short";
    for d in [&a, &b] {
        let o = hystbench(&[
            "zoo",
            "--count",
            "6",
            "--seed",
            "7",
            "--classes",
            short,
            "--out",
            s(d),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    assert!(files(&a) == files(&b), "two zoos of one seed differ");
    let index = ZooIndex::read(&a).unwrap();
    assert_eq!(index.members.len(), 6);
    // a member is the same in a smaller zoo of its seed
    let c = t.path().join("c");
    let o = hystbench(&[
        "zoo",
        "--count",
        "2",
        "--seed",
        "7",
        "--classes",
        short,
        "--out",
        s(&c),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let first = &index.members[1].record;
    assert_eq!(
        std::fs::read(a.join(first)).unwrap(),
        std::fs::read(c.join(first)).unwrap()
    );
    // ... and its plant and scenario files give its record again
    reruns(&a, &index.members[3], &t.path().join("again.csv"));
    // another seed, another zoo
    let d = t.path().join("d");
    assert!(hystbench(&[
        "zoo",
        "--count",
        "2",
        "--seed",
        "8",
        "--classes",
        short,
        "--out",
        s(&d)
    ])
    .status
    .success());
    assert_ne!(files(&c), files(&d));
}

#[test]
fn the_draws_cover_the_documented_classes_and_ranges() {
    let mut seen = std::collections::BTreeSet::new();
    for i in 0..300 {
        let m = zoo::member(3, i);
        seen.insert(m.class);
        let sc = &m.scenario;
        assert!(
            (1e-4..1e-2).contains(&sc.sampling_period_s),
            "{}",
            sc.sampling_period_s
        );
        assert!((300..=200_000).contains(&sc.samples), "{}", sc.samples);
        assert_eq!(m.plant.inputs.len(), m.class.axes());
        assert!(m.noise_share.iter().all(|v| (5e-4..2e-2).contains(v)));
        // every member checks as a plant and a scenario
        let p = Path::new("m.json");
        m.plant.check(p).unwrap();
        sc.check(p).unwrap();
    }
    assert_eq!(seen.len(), Class::ALL.len(), "{seen:?}");
}

#[test]
fn bad_input_is_refused_and_nothing_is_half_written() {
    let t = tempfile::tempdir().unwrap();
    let z = t.path().join("z");
    let o = hystbench(&["zoo", "--count", "0", "--out", s(&z)]);
    assert!(
        !o.status.success() && stderr(&o).contains("--count"),
        "{}",
        stderr(&o)
    );
    assert!(!z.exists());
    // a folder of the user's is never replaced, even with --force
    let mine = t.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("notes.txt"), "keep").unwrap();
    let o = hystbench(&["zoo", "--count", "1", "--out", s(&mine), "--force"]);
    assert!(stderr(&o).contains("not a zoo folder"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(mine.join("notes.txt")).unwrap(),
        "keep"
    );
    // an existing zoo needs --force
    let args = [
        "zoo",
        "--count",
        "1",
        "--classes",
        "1dof-tiny",
        "--out",
        s(&z),
    ];
    assert!(hystbench(&args).status.success());
    let o = hystbench(&args);
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    let mut forced = args.to_vec();
    forced.push("--force");
    assert!(hystbench(&forced).status.success());
    // a folder that cannot be made
    let under_file = t.path().join("notes").join("z");
    std::fs::write(t.path().join("notes"), "a file").unwrap();
    let o = hystbench(&["zoo", "--count", "1", "--out", s(&under_file)]);
    assert!(!o.status.success(), "made a zoo under a file");
    let leftovers: Vec<_> = std::fs::read_dir(t.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| n.contains("partial"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    // an unknown class
    let o = hystbench(&["zoo", "--classes", "3dof", "--out", s(&z)]);
    assert!(stderr(&o).contains("1dof-long"), "{}", stderr(&o));
    // score: no zoo, a damaged record
    let o = hystbench(&["zoo", "score", s(&mine)]);
    assert!(stderr(&o).contains("not a zoo folder"), "{}", stderr(&o));
    let index = ZooIndex::read(&z).unwrap();
    let rec = z.join(&index.members[0].record);
    let text = std::fs::read_to_string(&rec).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    lines[5] = lines[5].replacen(',', ",oops", 1);
    std::fs::write(&rec, lines.join("\n") + "\n").unwrap();
    let o = hystbench(&["zoo", "score", s(&z)]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains(&index.members[0].record) && e.contains("line 6"),
        "{e}"
    );
    assert!(
        !z.join("score").exists(),
        "a score folder was written for a damaged zoo"
    );
}

/// The CI's zoo: a few short records, scored; the default identifier never diverges where the
/// linear baseline does not, and its test R^2 is reported beside the baseline's.
#[test]
fn a_small_zoo_is_scored_against_the_linear_baseline() {
    let t = tempfile::tempdir().unwrap();
    let z = t.path().join("z");
    let o = hystbench(&[
        "zoo",
        "--count",
        "4",
        "--seed",
        "2",
        "--classes",
        "1dof-short,1dof-tiny",
        "--out",
        s(&z),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = hystbench(&["zoo", "score", s(&z), "--json", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let records = v["records"].as_array().unwrap();
    assert_eq!(records.len(), 4);
    let mut outputs = 0;
    for r in records {
        for out in r["outputs"].as_array().unwrap() {
            outputs += 1;
            assert!(
                out["arx_r2"].is_number() || out["arx_diverged"] == true,
                "{out}"
            );
            if out["arx_diverged"] == false {
                assert!(
                    out["diverged"] == false,
                    "diverged where the ARX did not: {out}"
                );
            }
        }
    }
    // a count summed over the classes
    let over_classes = |key: &str| -> u64 {
        v["classes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c[key].as_u64().unwrap())
            .sum()
    };
    assert_eq!(over_classes("outputs"), outputs);
    let csv = std::fs::read_to_string(z.join("score/results.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + outputs as usize);
    assert!(csv.lines().next().unwrap().contains(",outside_share,"));
    let report = std::fs::read_to_string(z.join("score/report.md")).unwrap();
    assert!(report.contains("| 1dof-") && report.contains("(r2.png)"));
    // each record says how much of its test half leaves the training region, and each class
    // counts the records that leave it on at least 10 % of their samples
    assert!(report.contains("| class | records | leaving | below the floor |"));
    let leaving = records
        .iter()
        .filter(|r| {
            let share = r["outside"].as_f64().unwrap();
            assert!((0.0..=1.0).contains(&share), "{r}");
            share >= 0.1
        })
        .count() as u64;
    assert_eq!(over_classes("leaving"), leaving);
    // the share is what `identify` warns of on the same split (first half trains, second tests)
    let widest = records
        .iter()
        .max_by(|a, b| {
            a["outside"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["outside"].as_f64().unwrap())
        })
        .unwrap();
    let rec = z.join(format!(
        "records/{:04}.csv",
        widest["index"].as_u64().unwrap()
    ));
    let o = hystbench(&[
        "identify",
        "--data",
        s(&rec),
        "--out",
        s(&t.path().join("m.json")),
        "--json",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let id: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let warned = id["extrapolation"].as_array().map_or(0.0, |a| {
        a.iter()
            .map(|e| e["share"].as_f64().unwrap())
            .fold(0.0, f64::max)
    });
    assert_eq!(widest["outside"].as_f64().unwrap(), warned, "{widest}");
    let png = std::fs::read(z.join("score/r2.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG"), "r2.png is a PNG");
    // every output with a band reports its coverage and its width
    for r in v["records"].as_array().unwrap() {
        for o in r["outputs"].as_array().unwrap() {
            if let Some(c) = o["coverage"].as_f64() {
                assert!((0.0..=1.0).contains(&c), "{o}");
                let w = o["band_width"]
                    .as_f64()
                    .expect("a width beside the coverage");
                assert!(w.is_finite() && w > 0.0, "{o}");
            }
        }
    }
    // in two parts (two processes, as a cluster's array job), merged: the same scores but the
    // times; an incomplete set of parts is refused
    let parts: Vec<_> = ["1/2", "2/2"]
        .iter()
        .map(|k| {
            std::process::Command::new(env!("CARGO_BIN_EXE_hystbench"))
                .args(["zoo", "score", s(&z), "--quiet", "--shard", k])
                .output()
                .unwrap()
        })
        .collect();
    for o in &parts {
        assert!(o.status.success(), "{}", stderr(o));
    }
    std::fs::rename(z.join("score/part-2-of-2.json"), t.path().join("p2.json")).unwrap();
    let o = hystbench(&["zoo", "score", s(&z), "--merge"]);
    assert!(
        !o.status.success() && stderr(&o).contains("2/2 missing"),
        "{}",
        stderr(&o)
    );
    std::fs::rename(t.path().join("p2.json"), z.join("score/part-2-of-2.json")).unwrap();
    let o = hystbench(&["zoo", "score", s(&z), "--merge", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let merged: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    fn timeless(v: &serde_json::Value) -> serde_json::Value {
        match v {
            serde_json::Value::Object(m) => m
                .iter()
                .filter(|(k, _)| !k.contains("seconds"))
                .map(|(k, x)| (k.clone(), timeless(x)))
                .collect::<serde_json::Map<_, _>>()
                .into(),
            serde_json::Value::Array(a) => a.iter().map(timeless).collect(),
            x => x.clone(),
        }
    }
    assert_eq!(timeless(&merged), timeless(&v));
    // one record at a time (each fit with every thread): the same scores as side by side
    let o = hystbench(&[
        "zoo",
        "score",
        s(&z),
        "--one-at-a-time",
        "--json",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let alone: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(timeless(&alone), timeless(&v));
    // fitted again on the noiseless training halves: the same scores beside those of the
    // fits without noise, two columns more, and the table of why records miss the floor
    let o = hystbench(&[
        "zoo",
        "score",
        s(&z),
        "--noiseless-training",
        "--json",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut again: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for r in again["records"].as_array_mut().unwrap() {
        for out in r["outputs"].as_array_mut().unwrap() {
            let n = out
                .as_object_mut()
                .unwrap()
                .remove("noiseless_training")
                .unwrap();
            // a fit to the noiseless training half fits it
            let train = n["r2_train"].as_f64().unwrap();
            assert!(train > 0.99, "{n}");
            assert!(n["r2"].is_number(), "{n}");
        }
    }
    for c in again["classes"].as_array_mut().unwrap() {
        assert!(c.as_object_mut().unwrap().remove("misses").is_some(), "{c}");
    }
    assert_eq!(timeless(&again), timeless(&v));
    let csv = std::fs::read_to_string(z.join("score/results.csv")).unwrap();
    assert!(csv
        .lines()
        .next()
        .unwrap()
        .ends_with(",noiseless_training_r2_train,noiseless_training_r2_clean"));
    let report = std::fs::read_to_string(z.join("score/report.md")).unwrap();
    assert!(
        report.contains("Why the records below the floor miss it"),
        "{report}"
    );
}

/// `zoo loop`: on a small development zoo (seed 7, long and short 1-DoF members, first 3,000
/// samples), the diagnosis names the hidden effect in the cases where refitting with it cuts
/// the error 3x or more, and names nothing on the complete models.
#[test]
fn the_loop_over_a_small_zoo_names_the_hidden_effects() {
    let t = tempfile::tempdir().unwrap();
    let z = t.path().join("z");
    let o = hystbench(&[
        "zoo",
        "--count",
        "8",
        "--seed",
        "7",
        "--classes",
        "1dof-short,1dof-long",
        "--out",
        s(&z),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = hystbench(&["zoo", "loop", s(&z), "--max-samples", "10"]);
    assert!(!o.status.success() && stderr(&o).contains("--max-samples 10"));
    let o = hystbench(&["zoo", "loop", s(t.path()), "--quiet"]);
    assert!(!o.status.success() && stderr(&o).contains("not a zoo folder"));
    let o = hystbench(&[
        "zoo",
        "loop",
        s(&z),
        "--max-samples",
        "3000",
        "--json",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (mut decisive, mut right) = (0, 0);
    for e in v["effects"].as_array().unwrap() {
        decisive += e["decisive"].as_u64().unwrap();
        right += e["decisive_right"].as_u64().unwrap();
    }
    println!(
        "decisive {decisive}, named right {right}, {}",
        v["false_alarms"]
    );
    assert!(decisive >= 5, "{v}");
    assert!(right + 1 >= decisive, "{right} of {decisive}: {v}");
    assert!(v["complete"].as_u64().unwrap() >= 5, "{v}");
    assert_eq!(v["false_alarms"].as_u64(), Some(0), "{v}");
    let csv = std::fs::read_to_string(z.join("loop/results.csv")).unwrap();
    assert!(csv.starts_with("index,class,samples,effects"));
    let report = std::fs::read_to_string(z.join("loop/report.md")).unwrap();
    assert!(report.contains("| hysteresis |"), "{report}");
}

/// `--extra drift,saturation` adds the effects sized by each output's range, from a stream of
/// their own: without them every member is the default zoo's; with them the records change.
/// The 8 members of seed 3 with `extra` drawn on top, in `dir/zoo`.
fn extra_zoo(dir: &Path, extra: &str) -> (std::path::PathBuf, ZooIndex) {
    let out = dir.join("zoo");
    let o = hystbench(&[
        "zoo",
        "--count",
        "8",
        "--seed",
        "3",
        "--extra",
        extra,
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let index = ZooIndex::read(&out).unwrap();
    (out, index)
}

#[test]
fn extra_effects_are_drawn_on_top_of_the_default_zoo() {
    use hystbench::plant::PlantSpec;
    let dir = tempfile::tempdir().unwrap();
    let (out, index) = extra_zoo(dir.path(), "drift,saturation");
    assert_eq!(index.extra.len(), 2);
    let mut drawn = 0;
    for e in &index.members {
        let mut p = PlantSpec::read(&out.join(&e.plant)).unwrap();
        let default = zoo::member(3, e.index).plant;
        for o in p.outputs.iter_mut() {
            let before = o.effects.len();
            o.effects.retain(|x| {
                x.effect() != hystbench::effect::drift::NAME
                    && x.effect() != hystbench::effect::saturation::NAME
            });
            drawn += before - o.effects.len();
        }
        assert_eq!(p.outputs, default.outputs, "member {}", e.index);
    }
    assert!(drawn > 0, "no extra effect drawn on 8 members");
    let o = hystbench(&[
        "zoo",
        "--count",
        "2",
        "--extra",
        "creep",
        "--out",
        s(&dir.path().join("z2")),
    ]);
    assert!(
        !o.status.success() && stderr(&o).contains("drift, saturation"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.path().join("z2").exists());
}

/// `--realization 1` draws the same plants and protocols with other records (each scenario's
/// seed one further on), and `simulate` with a member's files gives its record again.
#[test]
fn a_realization_keeps_the_plants_and_draws_other_records() {
    let dir = tempfile::tempdir().unwrap();
    let zoo_of = |name: &str, realization: &str| {
        let out = dir.path().join(name);
        let o = hystbench(&[
            "zoo",
            "--count",
            "4",
            "--seed",
            "3",
            "--realization",
            realization,
            "--out",
            s(&out),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        (out.clone(), ZooIndex::read(&out).unwrap())
    };
    let (z0, i0) = zoo_of("z0", "0");
    let (z1, i1) = zoo_of("z1", "1");
    assert_eq!((i0.realization, i1.realization), (0, 1));
    for (a, b) in i0.members.iter().zip(&i1.members) {
        assert_eq!(
            std::fs::read(z0.join(&a.plant)).unwrap(),
            std::fs::read(z1.join(&b.plant)).unwrap()
        );
        let (s0, s1) = (
            hystbench::scenario::ScenarioSpec::read(&z0.join(&a.scenario)).unwrap(),
            hystbench::scenario::ScenarioSpec::read(&z1.join(&b.scenario)).unwrap(),
        );
        assert_eq!(s1.seed, s0.seed + 1);
        assert_eq!(
            s1.inputs, s0.inputs,
            "member {}: the protocol changed",
            a.index
        );
        assert_ne!(
            std::fs::read(z0.join(&a.record)).unwrap(),
            std::fs::read(z1.join(&b.record)).unwrap(),
            "member {}: the same record",
            a.index
        );
        reruns(&z1, b, &dir.path().join(format!("again{}.csv", b.index)));
    }
    // the zoo as drawn writes no `realization`: an older zoo reads the same
    let text = std::fs::read_to_string(z0.join("zoo.json")).unwrap();
    assert!(!text.contains("realization"));
}

/// `--extra` effects are drawn in chain order, each once, whatever order they are typed in:
/// saturation's limits are sized on the output that hysteresis's envelopes made, and the same
/// set gives the same bytes.
#[test]
fn extra_effects_are_drawn_in_chain_order_whatever_the_order_typed() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (za, ia) = extra_zoo(a.path(), "saturation,hysteresis,saturation");
    let (zb, ib) = extra_zoo(b.path(), "hysteresis,saturation");
    let names: Vec<&str> = ia.extra.iter().map(|e| e.as_str()).collect();
    assert_eq!(names, ["hysteresis", "saturation"]);
    assert_eq!(ia.extra, ib.extra);
    assert!(
        files(&za) == files(&zb),
        "the same set typed in another order drew other bytes"
    );
}

/// `--extra dynamics` puts a second mode and a hold on top of an output's mode (or a mode with
/// both on an output without one); the rest of every member is the default zoo's.
#[test]
fn extra_dynamics_draws_a_second_mode_and_a_hold() {
    use hystbench::effect::dynamics::{DynamicsSpec, NAME as DYNAMICS};
    use hystbench::plant::PlantSpec;
    let dir = tempfile::tempdir().unwrap();
    let (out, index) = extra_zoo(dir.path(), "dynamics");
    let (mut on_top, mut new) = (0, 0);
    for e in &index.members {
        let mut p = PlantSpec::read(&out.join(&e.plant)).unwrap();
        let default = zoo::member(3, e.index).plant;
        for (o, d) in p.outputs.iter_mut().zip(&default.outputs) {
            let dyn_of = |fx: &[Box<dyn hystbench::effect::spec::EffectSpec>]| {
                fx.iter()
                    .find(|x| x.effect() == DYNAMICS)
                    .and_then(|x| x.as_any().downcast_ref::<DynamicsSpec>().copied())
            };
            let (now, before) = (dyn_of(&o.effects), dyn_of(&d.effects));
            if now == before {
                continue;
            }
            let now = now.expect("dynamics drawn");
            let m2 = now.second_mode.expect("a second mode");
            assert!(
                m2.natural_frequency_hz > now.natural_frequency_hz,
                "{now:?}"
            );
            assert!(
                m2.natural_frequency_hz <= 0.25 / e.sampling_period_s + 1e-9,
                "{now:?}"
            );
            assert!((0.0..=1.0).contains(&now.first_order_hold), "{now:?}");
            match before {
                Some(b) => {
                    on_top += 1;
                    assert_eq!(
                        (b.natural_frequency_hz, b.damping_ratio, b.dc_gain),
                        (now.natural_frequency_hz, now.damping_ratio, now.dc_gain)
                    );
                }
                None => new += 1,
            }
            o.effects.retain(|x| x.effect() != DYNAMICS);
        }
        let mut rest = default.outputs.clone();
        for (o, r) in p.outputs.iter().zip(rest.iter_mut()) {
            if o.effects.len() < r.effects.len() {
                r.effects.retain(|x| x.effect() != DYNAMICS);
            }
        }
        assert_eq!(p.outputs, rest, "member {}", e.index);
    }
    assert!(on_top + new > 0, "no second mode drawn on 8 members");
}

/// `--extra hysteresis` puts tanh envelopes (Al Janaideh's generalised plays) on Prandtl-Ishlinskii
/// paths in place of their dead zones, leaving Bouc-Wen loops and gains and the rest of every
/// member as the default zoo's.
#[test]
fn extra_hysteresis_draws_generalised_plays_on_prandtl_ishlinskii_paths() {
    use hystbench::effect::hysteresis::HysteresisSpec;
    use hystbench::plant::PlantSpec;
    let dir = tempfile::tempdir().unwrap();
    let (out, index) = extra_zoo(dir.path(), "hysteresis");
    let mut generalised = 0;
    for e in &index.members {
        let p = PlantSpec::read(&out.join(&e.plant)).unwrap();
        let rec = hystbench::data::read_csv(&out.join(&e.record)).unwrap();
        let mut default = zoo::member(3, e.index).plant;
        for (o, d) in p.outputs.iter().zip(default.outputs.iter_mut()) {
            // an output drawn gets envelopes on every Prandtl-Ishlinskii path
            let (mut pi_paths, mut enveloped) = (0, 0);
            for (path, dp) in o.paths.iter().zip(d.paths.iter_mut()) {
                for (x, dx) in path.effects.iter().zip(dp.effects.iter_mut()) {
                    let (Some(HysteresisSpec::PrandtlIshlinskii(now)), Some(before)) = (
                        x.as_any().downcast_ref::<HysteresisSpec>(),
                        dx.as_any().downcast_ref::<HysteresisSpec>(),
                    ) else {
                        continue;
                    };
                    pi_paths += 1;
                    let Some(env) = &now.envelopes else {
                        continue;
                    };
                    enveloped += 1;
                    // sized by the path's input peak U: U / L in 0.4-1.6, the descending level
                    // 0.75-1.33 times the ascending one, skews within 0.4
                    let col = rec.names.iter().position(|n| *n == path.input).unwrap();
                    let peak = hystbench::metrics::max_abs(&rec.columns[col]);
                    let (up, down) = (env.ascending, env.descending);
                    let tol = 1e-9;
                    assert!(
                        (0.4 - tol..=1.6 + tol).contains(&(peak / up.a0)),
                        "{env:?} {peak}"
                    );
                    assert!(
                        (0.75 - tol..=1.33 + tol).contains(&(down.a0 / up.a0)),
                        "{env:?}"
                    );
                    assert!(up.a2.abs() <= 0.4 && down.a2.abs() <= 0.4, "{env:?}");
                    let HysteresisSpec::PrandtlIshlinskii(b) = before else {
                        panic!("envelopes drawn on {before:?}");
                    };
                    assert_eq!(
                        (
                            &now.thresholds,
                            &now.weights,
                            now.linear_weight,
                            &now.dead_zones
                        ),
                        (&b.thresholds, &b.weights, b.linear_weight, &None)
                    );
                    for g in [env.ascending, env.descending] {
                        assert!(g.at(0.0).abs() < 1e-9, "{g:?}");
                        let slope = (g.at(1e-6) - g.at(-1e-6)) / 2e-6;
                        assert!((slope - 1.0).abs() < 1e-6, "{g:?}");
                    }
                    generalised += 1;
                    *dx = x.clone();
                }
            }
            assert!(
                enveloped == 0 || enveloped == pi_paths,
                "member {}",
                e.index
            );
        }
        assert_eq!(p.outputs, default.outputs, "member {}", e.index);
    }
    assert!(generalised > 0, "no generalised plays drawn on 8 members");
}

/// A network chosen over its grey-box base whose ensemble mostly diverges on the test record
/// (inputs in combinations the training half never visited) gives way to the base: the free
/// run is scored, not left to the few members that held (zoo seed 37 member 45 with
/// `--extra dynamics`, y2: -1.11 from three members that held, 0.61 from the base; the ARX
/// 0.62).
#[test]
fn a_mostly_diverging_network_gives_way_to_its_base() {
    let dir = tempfile::tempdir().unwrap();
    let z = dir.path().join("zoo");
    let o = hystbench(&[
        "zoo",
        "--count",
        "11",
        "--seed",
        "37",
        "--classes",
        "2dof-short",
        "--extra",
        "dynamics",
        "--out",
        s(&z),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = dir.path().join("m.json");
    let rec = z.join("records").join("0045.csv");
    let o = hystbench(&["identify", "--data", s(&rec), "--out", s(&m), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let y2 = &v["outputs"]["y2"];
    let r2 = y2["r2_fr_test"].as_f64().unwrap_or(f64::NAN);
    assert!(r2 > 0.5, "{y2}");
}
