//! The study's NARX settings and records.

use super::*;

// ---------------------------------------------------------------------------------------------
// NARX

/// Every `m`-th sample.
pub fn decimate(x: &[f64], m: usize) -> Vec<f64> {
    x.iter().step_by(m.max(1)).copied().collect()
}

/// The NARX record of a displacement at constant current (decimated), with or without force.
pub fn narx_record(name: &Path, x: &[f64], current: f64, f: Option<&[f64]>, ts: f64) -> IoRecord {
    let xd = decimate(x, NARX_DECIMATION);
    let n = xd.len();
    IoRecord {
        path: name.to_path_buf(),
        ts: ts * NARX_DECIMATION as f64,
        t0: 0.0,
        time_name: "t_s".into(),
        inputs: vec![
            Signal {
                name: "x_mm".into(),
                values: xd,
            },
            Signal {
                name: "I_A".into(),
                values: vec![current; n],
            },
        ],
        outputs: f
            .map(|f| {
                vec![Signal {
                    name: "F_N".into(),
                    values: decimate(f, NARX_DECIMATION),
                }]
            })
            .unwrap_or_default(),
    }
}

/// The NARX configuration: default protocol, inputs x and I, [`NARX_LAGS`] lags,
/// [`NARX_NEURONS`] neurons, 2 restarts, 600 simulation-error steps in all, seed 1.
pub fn narx_config() -> NarxConfig {
    let mut c = NarxConfig::new(vec!["x_mm".into(), "I_A".into()], vec!["F_N".into()]);
    c.seed = NARX_SEED;
    c.lags = Lags {
        output: NARX_LAGS,
        input: NARX_LAGS,
        delay: 1,
    };
    c.neurons = NARX_NEURONS;
    // the current scales the damper's force (a product of the inputs' effects): not additive
    c.interaction = Interaction::Full;
    c.robust.restarts = Some(2);
    c.robust.sim_steps = 600;
    c
}

/// Trains the NARX on the (decimated) training records.
pub fn fit_narx(data: &MrDamperData) -> Result<FittedNarx, MrDamperError> {
    let recs: Vec<IoRecord> = data
        .train
        .iter()
        .map(|r| narx_record(&r.path, &r.x, r.current, Some(&r.f), r.ts))
        .collect();
    Ok(narx_config().fit_records(&recs)?)
}
