//! `examples/simulate_and_fit.rs` runs the whole loop from Rust (simulate -> identify -> fit ->
//! diagnose -> improve); here it runs in CI and its findings are checked.

#[path = "../examples/simulate_and_fit.rs"]
mod example;

#[test]
fn the_library_runs_the_whole_loop() {
    let found = example::run().expect("the example runs");
    let r2 = found.narx_r2.expect("the NARX free run does not diverge");
    assert!(r2 > 0.99, "NARX free-run test R^2 {r2}");
    assert_eq!(found.missing, Some(hystbench::effect::creep::NAME));
    let (first, last) = (found.ladder[0], *found.ladder.last().unwrap());
    assert!(
        found.ladder.len() >= 2 && last < first / 3.0,
        "{:?}",
        found.ladder
    );
}
