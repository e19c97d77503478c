//! Lab records as they come: comment lines, a trailing separator, `;` or tab separators, units
//! in the header and decimal commas read into the same numbers as the plain CSV, through the
//! one reading path; what was accepted is said (`Record::format`), and a command prints it.

use hystbench::data::parse_csv;
use std::path::Path;

const PLAIN: &str = "t,u,y\n0,0,0\n0.001,1.5,-0.25\n0.002,3,-0.5\n0.003,2.25,1e-3\n";

fn read(text: &str) -> hystbench::data::Record {
    parse_csv(Path::new("lab.csv"), text).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

#[test]
fn every_tolerated_format_reads_into_the_plain_numbers() {
    let plain = read(PLAIN);
    assert!(plain.format.notes(&plain.names).is_empty());
    let variants = [
        (
            "comments",
            "# logged 2026-11-25 by the stage controller\n# gain 1.0\nt,u,y\n0,0,0\n# a note in the middle\n0.001,1.5,-0.25\n0.002,3,-0.5\n0.003,2.25,1e-3\n",
            "comment line",
        ),
        (
            "trailing separator",
            "t,u,y,\n0,0,0,\n0.001,1.5,-0.25,\n0.002,3,-0.5,\n0.003,2.25,1e-3,\n",
            "trailing separator",
        ),
        (
            "semicolons and decimal commas",
            "t;u;y\n0;0;0\n0,001;1,5;-0,25\n0,002;3;-0,5\n0,003;2,25;1e-3\n",
            "decimal commas",
        ),
        (
            "tabs",
            "t\tu\ty\n0\t0\t0\n0.001\t1.5\t-0.25\n0.002\t3\t-0.5\n0.003\t2.25\t1e-3\n",
            "tab-separated",
        ),
        (
            "units",
            "t (s),u [V],y [um]\n0,0,0\n0.001,1.5,-0.25\n0.002,3,-0.5\n0.003,2.25,1e-3\n",
            "units",
        ),
        (
            "all at once",
            "\u{feff}# exported\nt [s];u (V);y [um];\n0;0;0;\n0,001;1,5;-0,25;\n0,002;3;-0,5;\n0,003;2,25;1e-3;\n",
            "`;`-separated",
        ),
    ];
    for (what, text, said) in variants {
        let r = read(text);
        assert_eq!(r.names, plain.names, "{what}");
        assert_eq!(r.columns, plain.columns, "{what}");
        let notes = r.format.notes(&r.names).join("; ");
        assert!(notes.contains(said), "{what}: {notes}");
    }
    let r = read("t (s),u [V],y [um]\n0,0,0\n");
    assert_eq!(
        r.format.units,
        vec![Some("s".into()), Some("V".into()), Some("um".into())]
    );
}

#[test]
fn what_is_still_refused_says_the_line() {
    // a ragged row stays an error with its line, comments counted in the line numbers
    let e = parse_csv(Path::new("lab.csv"), "# c\nt,u,y\n0,0,0\n1,2\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 4"), "{e}");
    // a decimal comma in a comma-separated file is a column too many, not a number
    let e = parse_csv(Path::new("lab.csv"), "t,u,y\n0,0,0,5\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 2"), "{e}");
    // the header's own line, after comments
    let e = parse_csv(Path::new("lab.csv"), "# c\n# d\nt,u,u\n0,0,0\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 3") && e.contains("twice"), "{e}");
    // only comments: empty
    assert!(parse_csv(Path::new("lab.csv"), "# nothing\n# here\n").is_err());
}

/// A command says what it read: `;`, decimal commas, units (standard error; the JSON on
/// standard out stays clean).
#[test]
fn a_command_says_how_it_read_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("lab.csv");
    let mut text = String::from("# logged by the stage\nt [s];u [V];y [um]\n");
    for k in 0..2000 {
        let t = k as f64 * 1e-4;
        let u = 10.0 * (2.0 * std::f64::consts::PI * 5.0 * t).sin();
        let y = 0.8 * u + 0.1 * u.abs();
        text += &format!("{};{};{}\n", t, u, y).replace('.', ",");
    }
    std::fs::write(&data, text).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_hystbench"))
        .args(["compare", "--model"])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/prandtl_ishlinskii_piezo.json"))
        .arg("--data")
        .arg(&data)
        .arg("--json")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("`;`-separated") && err.contains("decimal commas") && err.contains("y [um]"),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("clean JSON on stdout");
    assert!(v.is_object());
}
