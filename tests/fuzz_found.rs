//! Every input the fuzzer found (`fuzz/found/TARGET/`: panics, hangs, aborts) runs through
//! its target again, now without a panic.

#[path = "../fuzz/targets.rs"]
mod targets;

use std::path::Path;

#[test]
fn found_inputs_are_read_without_a_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/found");
    let mut replayed = 0;
    for t in targets::TARGETS {
        let Ok(dir) = std::fs::read_dir(root.join(t)) else {
            continue;
        };
        let mut paths: Vec<_> = dir.filter_map(|e| e.ok().map(|e| e.path())).collect();
        paths.sort();
        for p in paths {
            if p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with('.'))
            {
                continue;
            }
            let data = std::fs::read(&p).unwrap();
            let r = std::panic::catch_unwind(|| targets::run(t, &data));
            assert!(r.is_ok(), "{t}: {} panics", p.display());
            replayed += 1;
        }
    }
    println!("{replayed} found inputs replayed");
}
