//! The real binary at the edges: `curve --trace full` on the classic linkages, flags in the
//! curve JSON, and `bench stability` / `bench classics` as a user runs them.

use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("runs")
}

fn json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON")
}

#[test]
fn curve_trace_full_closes_for_watt_and_chebyshev() {
    for (a, b, c, p, branches) in [
        ("1", "1", "2.23606797749979", "0.5,0", 1),
        ("0.4", "1", "0.8", "0.2,0", 2),
    ] {
        let v = json(&run(&[
            "curve",
            "--coupler",
            a,
            "--rocker",
            b,
            "--ground",
            c,
            "--point",
            p,
            "--trace",
            "full",
            "--step",
            "2",
        ]));
        assert_eq!(v["trace"], "full");
        assert_eq!(v["input_range"]["kind"], "rocks");
        let bs = v["branches"].as_array().unwrap();
        assert_eq!(bs.len(), branches);
        for br in bs {
            let s = br["samples"].as_array().unwrap();
            let (first, last) = (&s[0], &s[s.len() - 1]);
            let d = (first["x"].as_f64().unwrap() - last["x"].as_f64().unwrap())
                .hypot(first["y"].as_f64().unwrap() - last["y"].as_f64().unwrap());
            assert!(d <= 1e-12, "branch does not close: {d}");
            assert_eq!(first["toggle"], true);
            assert!(first["vx"].is_null(), "velocity is infinite at a toggle");
            assert!(
                s.iter().any(|x| x["circuit"] == "open")
                    && s.iter().any(|x| x["circuit"] == "crossed")
            );
        }
    }
}

#[test]
fn curve_json_carries_flags() {
    let v = json(&run(&[
        "curve",
        "--coupler",
        "3",
        "--rocker",
        "2",
        "--ground",
        "2",
        "--point",
        "1,1",
        "--step",
        "10",
    ]));
    assert_eq!(
        v["flags"],
        serde_json::json!(["change_point", "near_toggle"])
    );
    assert!(v["error_bound"].as_f64().unwrap() < 1e-13);
    let v = json(&run(&[
        "curve",
        "--coupler",
        "2.5",
        "--rocker",
        "3",
        "--ground",
        "3.5",
        "--point",
        "1,1",
        "--step",
        "10",
    ]));
    assert_eq!(v["flags"], serde_json::json!([]));
}
