//! The lab's binary, run as a user runs it.

use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_coupler-lab"))
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .args(args)
        .output()
        .expect("the lab runs")
}

#[test]
fn bench_stability_passes_and_classics_measure() {
    let out = run(&["stability"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let t = String::from_utf8_lossy(&out.stdout);
    assert!(t.contains("no NaN, no circuit jump"), "{t}");
    let out = run(&["classics"]);
    assert!(out.status.success());
    let t = String::from_utf8_lossy(&out.stdout);
    for name in ["Hoeken", "Chebyshev", "Watt", "Roberts", "Evans"] {
        assert!(t.contains(&format!("| {name} |")), "{t}");
    }
}
