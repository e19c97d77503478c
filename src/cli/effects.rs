//! `hystbench effects`: the effect library's registry, as every command reads it.

use hystbench::effect::{effects, Slot};
use serde_json::json;

/// List the effects of the library: their names (for `fit --effects`, `identify --features`,
/// plant files), where they act, their grey-box operators and NARX features.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

fn place(slot: Slot) -> &'static str {
    match slot {
        Slot::PathTerm => "path term",
        Slot::Filter => "path or output filter",
        Slot::OutputFilter => "output filter",
        Slot::OutputTerm => "output term (of time)",
        Slot::Sensor => "sensor (after the offset)",
        Slot::None => "structure",
    }
}

/// The `fit --effects` help: every effect and its operators.
pub fn fit_help() -> String {
    let items: Vec<String> = effects()
        .iter()
        .map(|e| {
            let v = e.variants();
            if v.len() > 1 {
                let names: Vec<&str> = v[1..].iter().map(|x| x.name).collect();
                format!(
                    "{} (or one of its operators: {})",
                    e.name(),
                    names.join(", ")
                )
            } else {
                e.name().to_string()
            }
        })
        .collect();
    format!(
        "Effects: {}; `none` for a linear static model (`hystbench effects` says what each one is).\nThe fit uses the whole record (your choice of data) unless --train-fraction F is given.\nExample: hystbench fit --data d.csv --effects hysteresis,creep,dynamics --out model.json",
        items.join(", ")
    )
}

/// Run `effects`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let list = effects();
    if a.json {
        let v: Vec<_> = list
            .iter()
            .map(|e| {
                json!({
                    "name": e.name().as_str(),
                    "summary": e.summary(),
                    "acts_as": place(e.slot()),
                    "operators": e.variants().iter().map(|v| v.name).collect::<Vec<_>>(),
                    "narx_features": e.feature_kinds().iter().map(|k| k.name).collect::<Vec<_>>(),
                })
            })
            .collect();
        super::print(&serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    let mut text = format!(
        "{:<12} {:<22} {:<42} {:<12} {}\n",
        "effect", "acts as", "fit operators", "NARX", "what it is"
    );
    for e in &list {
        let ops: Vec<&str> = e.variants().iter().map(|v| v.name).collect();
        let feats: Vec<&str> = e.feature_kinds().iter().map(|k| k.name).collect();
        text += &format!(
            "{:<12} {:<22} {:<42} {:<12} {}\n",
            e.name().as_str(),
            place(e.slot()),
            if ops.is_empty() {
                "-".to_string()
            } else {
                ops.join(", ")
            },
            if feats.is_empty() {
                "-".to_string()
            } else {
                feats.join(", ")
            },
            e.summary()
        );
    }
    super::print(&text);
    Ok(())
}
