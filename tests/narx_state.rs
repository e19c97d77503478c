//! A NARX model stepped one sample at a time (what the compensator inverts) gives the same bits
//! as its free run over the whole record, for every shape a fitted model takes: feature
//! signals of each kind, a decimated model, deeper networks, ensembles and a grey-box base.

use hystbench::data::IoRecord;
use hystbench::effect::feature::FeatureSpec;
use hystbench::effect::{creep, dynamics, hysteresis, viscous};
use hystbench::narx::synthetic::{seed_1dof, seed_2dof, Plant1};
use hystbench::narx::{FittedNarx, Mode, NarxConfig};
use std::path::Path;

fn quick(rec: &IoRecord) -> NarxConfig {
    let mut c = NarxConfig::new(rec.input_names(), rec.output_names());
    c.robust.restarts = Some(2);
    c.robust.sim_steps = 100;
    c.epochs = 30;
    c.seed = 1;
    c
}

/// Step the model over the record's inputs from rest; compare with its free run of the
/// record without outputs (seeded at rest too).
fn assert_stepped_is_free_run(m: &FittedNarx, rec: &IoRecord, what: &str) {
    let mut bare = rec.clone();
    bare.outputs.clear();
    let preds = m.predict(&bare, Mode::FreeRun).expect("free run");
    for p in &preds {
        // a member that diverges is left out of the whole free run, but out of a stepped run
        // only from where it diverges: the comparison needs runs where none does
        assert!(
            p.diverged_at.is_none() && p.diverged_members.is_empty(),
            "{what}: output {} diverged ({:?}, members {:?}): choose other settings",
            p.name,
            p.diverged_at,
            p.diverged_members
        );
    }
    let mut s = m.state(rec.ts, Path::new("model.json")).expect("state");
    assert_eq!(s.inputs(), rec.inputs.len());
    assert_eq!(s.outputs(), preds.len());
    let mut y = vec![0.0; s.outputs()];
    let mut u = vec![0.0; s.inputs()];
    for k in 0..rec.len() {
        for (j, x) in rec.inputs.iter().enumerate() {
            u[j] = x.values[k];
        }
        s.step(&u, &mut y);
        for (o, p) in preds.iter().enumerate() {
            assert_eq!(
                y[o].to_bits(),
                p.values[k].to_bits(),
                "{what}: output {o} at sample {k}: stepped {} free run {}",
                y[o],
                p.values[k]
            );
        }
    }
}

#[test]
fn stepped_with_every_feature_kind_decimated_and_deep() {
    let rec = seed_1dof(Plant1::BoucWenCreep, 3000, 3);
    let ts = rec.ts;
    for (layers, decimation, ensemble) in [(1, 1, 1), (1, 2, 2), (2, 1, 3)] {
        let mut c = quick(&rec);
        c.layers = layers;
        c.decimation = decimation;
        c.robust.try_decimation = false;
        c.robust.try_greybox = false;
        c.robust.ensemble = Some(ensemble);
        c.robust.restarts = Some(ensemble.max(2));
        c.features = vec![
            FeatureSpec::new(&hysteresis::PLAY, 0, vec![2.0]),
            FeatureSpec::new(&creep::FIRST_ORDER, 0, vec![50.0 * ts]),
            FeatureSpec::new(&dynamics::RESONATOR, 0, vec![400.0, 0.1]),
            FeatureSpec::new(&viscous::RATE, 0, vec![]),
        ];
        let m = c.fit(&rec).expect("fit");
        assert_stepped_is_free_run(
            &m,
            &rec,
            &format!("layers {layers}, decimation {decimation}, ensemble {ensemble}"),
        );
    }
}

#[test]
fn stepped_with_a_grey_box_base_on_the_2dof_record() {
    let rec = seed_2dof(1);
    let m = quick(&rec).fit(&rec).expect("fit");
    assert!(
        m.base.as_ref().is_some_and(|b| b.active()),
        "the default protocol keeps a grey-box base on this record"
    );
    assert_stepped_is_free_run(&m, &rec, "2-DoF default protocol");
}
