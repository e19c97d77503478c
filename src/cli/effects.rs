//! `hystbench effects`: the effect library's registry, as every command reads it.

use hystbench::effect::{effects, Effect, Slot};
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
    super::print(&table(&list));
    Ok(())
}

/// The text table of `list`: one row per effect, each column but the last as wide as its
/// widest cell.
fn table(list: &[&'static dyn Effect]) -> String {
    let dash = |v: Vec<&str>| {
        if v.is_empty() {
            "-".to_string()
        } else {
            v.join(", ")
        }
    };
    let mut rows =
        vec![["effect", "acts as", "fit operators", "NARX", "what it is"].map(String::from)];
    for e in list {
        rows.push([
            e.name().as_str().to_string(),
            place(e.slot()).to_string(),
            dash(e.variants().iter().map(|v| v.name).collect()),
            dash(e.feature_kinds().iter().map(|k| k.name).collect()),
            e.summary().to_string(),
        ]);
    }
    let widths: Vec<usize> = (0..4)
        .map(|c| rows.iter().map(|r| r[c].chars().count()).max().unwrap_or(0))
        .collect();
    let mut text = String::new();
    for r in &rows {
        for (cell, w) in r.iter().zip(&widths) {
            text += &format!("{cell:<w$} ");
        }
        text += &r[4];
        text.push('\n');
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every row's summary starts at the header's "what it is", whatever the cells' widths
    /// (`sensor (after the offset)` was wider than its fixed column).
    #[test]
    fn the_summaries_line_up_under_their_header() {
        let text = table(&effects());
        let at = |line: &str, what: &str| line.find(what).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let col = at(lines[0], "what it is");
        for (line, e) in lines[1..].iter().zip(effects()) {
            assert_eq!(at(line, e.summary()), col, "{line}");
        }
    }
}
