//! Write the synthetic `seed_1dof` (three plants) and `seed_2dof` records as CSV, for the CLI and
//! the Keras peer: `cargo run --release --example narx_records -- OUT_DIR [SEED]`.

use hystbench::data::write_csv_atomic;
use hystbench::narx::synthetic::{seed_1dof, seed_2dof, Plant1};
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let dir = PathBuf::from(args.get(1).map_or("narx_records", |s| s.as_str()));
    let seed: u64 = args.get(2).map_or(Ok(1), |s| s.parse())?;
    std::fs::create_dir_all(&dir)?;
    for p in Plant1::ALL {
        let rec = seed_1dof(p, 50_000, seed);
        let (names, cols) = rec.to_columns();
        let path = dir.join(format!("{}_1dof.csv", p.name()));
        write_csv_atomic(&path, &names, &cols, true)?;
        println!("{}", path.display());
    }
    let rec = seed_2dof(seed);
    let (names, cols) = rec.to_columns();
    let path = dir.join("piezo_2dof.csv");
    write_csv_atomic(&path, &names, &cols, true)?;
    println!("{}", path.display());
    Ok(())
}
