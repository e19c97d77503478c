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
    // the columns as wide as their widest cell
    let dash = |v: Vec<&str>| {
        if v.is_empty() {
            "-".to_string()
        } else {
            v.join(", ")
        }
    };
    let mut rows = vec![[
        "effect".to_string(),
        "acts as".to_string(),
        "fit operators".to_string(),
        "NARX".to_string(),
        "what it is".to_string(),
    ]];
    for e in &list {
        rows.push([
            e.name().as_str().to_string(),
            place(e.slot()).to_string(),
            dash(e.variants().iter().map(|v| v.name).collect()),
            dash(e.feature_kinds().iter().map(|k| k.name).collect()),
            e.summary().to_string(),
        ]);
    }
    let width = |c: usize| rows.iter().map(|r| r[c].chars().count()).max().unwrap_or(0);
    let w = [width(0), width(1), width(2), width(3)];
    let mut text = String::new();
    for r in &rows {
        text += &format!(
            "{:<w0$} {:<w1$} {:<w2$} {:<w3$} {}\n",
            r[0],
            r[1],
            r[2],
            r[3],
            r[4],
            w0 = w[0],
            w1 = w[1],
            w2 = w[2],
            w3 = w[3]
        );
    }
    super::print(&text);
    Ok(())
}
