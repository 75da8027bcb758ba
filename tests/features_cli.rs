//! The feature commands as a user runs them: `curve --window`, `search`, `cognates`, `dwell`.

use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
}

fn run_json(args: &[&str]) -> serde_json::Value {
    let out = bin().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Norton Table 3-1 (docs/conventions.md §8) through the command line, to the printed digits.
#[test]
fn curve_window_reproduces_norton() {
    let rows = [
        (
            "2.975",
            "3.9625",
            "7.925",
            "170:190",
            "0.6013",
            "0.0000104",
            "0.3775",
        ),
        (
            "2.625", "3.4375", "6.875", "120:240", "3.2380", "0.01031", "14.684",
        ),
        (
            "1.825", "2.2375", "4.475", "120:240", "2.5999", "0.7521", "1.8845",
        ),
    ];
    for (c, a, u, window, dx, es, ev) in rows {
        let point = format!("{u},0");
        let j = run_json(&[
            "curve",
            "--coupler",
            a,
            "--rocker",
            a,
            "--ground",
            c,
            "--point",
            &point,
            "--step",
            "2",
            "--window",
            window,
            "--window-line",
            "ground",
        ]);
        let w = &j["window"];
        let digits = |printed: &str| {
            printed
                .trim_start_matches(['0', '.'])
                .chars()
                .filter(char::is_ascii_digit)
                .count() as i32
        };
        let round_sig = |x: f64, sig: i32| {
            let p = 10f64.powi(sig - 1 - x.abs().log10().floor() as i32);
            (x * p).round() / p
        };
        let extent = w["extent"].as_f64().unwrap();
        assert_eq!(format!("{extent:.4}"), dx, "{c}");
        let got = w["straightness_pct"].as_f64().unwrap();
        assert_eq!(
            round_sig(got, digits(es)),
            es.parse::<f64>().unwrap(),
            "{c}: {got}"
        );
        let got = w["velocity_variation_pct"].as_f64().unwrap();
        assert_eq!(
            round_sig(got, digits(ev)),
            ev.parse::<f64>().unwrap(),
            "{c}: {got}"
        );
    }
}

/// The rocker pin's window arc is the rocker circle; a bad window is a usage error.
#[test]
fn curve_window_arc_and_errors() {
    let j = run_json(&[
        "curve",
        "--coupler",
        "3",
        "--rocker",
        "2.5",
        "--ground",
        "3.5",
        "--point",
        "3,0",
        "--window",
        "300:420",
    ]);
    let w = &j["window"];
    assert!((w["arc_radius"].as_f64().unwrap() - 2.5).abs() < 1e-9);
    assert!((w["arc_center"][0].as_f64().unwrap() - 3.5).abs() < 1e-9);
    let out = bin()
        .args([
            "curve",
            "--coupler",
            "3",
            "--rocker",
            "2.5",
            "--ground",
            "3.5",
            "--point",
            "3,0",
            "--window",
            "90:10",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("START:END"));
}

/// `cognates --format json`: the three linkages' pivots, lengths, points and circuits
/// (as printed) trace the same curve; cognate 2 (input turning with the crank) at the
/// same crank angle, to 1e-12. (Cognate 1 is checked in the library's unit test.)
#[test]
fn cognates_json_contract() {
    use coupler_atlas::{Circuit, CouplerPoint, CrankAngle, FourBar, Pose};
    let j = run_json(&[
        "cognates",
        "--coupler",
        "3",
        "--rocker",
        "2.5",
        "--ground",
        "3.5",
        "--point",
        "1.5,1",
        "--format",
        "json",
    ]);
    let ls = j["linkages"].as_array().unwrap();
    assert_eq!(ls.len(), 3);
    assert_eq!(
        j["crank_rockers"],
        serde_json::json!(["original", "cognate 2"])
    );
    let trace = |l: &serde_json::Value, deg: f64| -> [f64; 2] {
        let f = |k: &str| l[k].as_f64().unwrap();
        let s = f("crank");
        let four = FourBar::new(f("coupler") / s, f("rocker") / s, f("ground") / s).unwrap();
        let p = CouplerPoint::new(
            l["point"]["u"].as_f64().unwrap() / s,
            l["point"]["v"].as_f64().unwrap() / s,
        );
        let circuit: Circuit = l["circuit"].as_str().unwrap().parse().unwrap();
        let m = Pose::solve(&four, circuit, &CrankAngle::from_degrees(deg))
            .unwrap()
            .point(p);
        let piv = |i: usize, k: usize| l["pivots"][i][k].as_f64().unwrap();
        let (ax, ay) = (piv(1, 0) - piv(0, 0), piv(1, 1) - piv(0, 1));
        let n = ax.hypot(ay);
        let (c, sn) = (ax / n * s, ay / n * s);
        [
            piv(0, 0) + c * m.x - sn * m.y,
            piv(0, 1) + sn * m.x + c * m.y,
        ]
    };
    for k in 0..72 {
        let deg = k as f64 * 5.0;
        let (a, b) = (trace(&ls[0], deg), trace(&ls[2], deg));
        assert!(
            (a[0] - b[0]).hypot(a[1] - b[1]) < 1e-12,
            "θ = {deg}: {a:?} vs {b:?}"
        );
    }
    assert_eq!(ls[0]["pivots"], serde_json::json!([[0.0, 0.0], [3.5, 0.0]]));
    assert_eq!(ls[1]["pivots"][0], serde_json::json!([0.0, 0.0]));
}

/// `dwell`: JSON report and a design card (`--png`, the card's old name); a narrower window
/// (smaller deviation) jitters less at the same swing.
#[test]
fn dwell_reports_and_draws() {
    let dir = std::env::temp_dir().join(format!("coupler-atlas-dwell-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("dwell.png");
    let base = [
        "dwell",
        "--coupler",
        "3",
        "--rocker",
        "2.5",
        "--ground",
        "3.5",
        "--point",
        "3,0.4",
        "--swing",
        "20",
        "--format",
        "json",
    ];
    let wide = run_json(
        &[
            &base[..],
            &["--window", "100:160", "--png", png.to_str().unwrap()],
        ]
        .concat(),
    );
    let narrow = run_json(&[&base[..], &["--window", "110:150"]].concat());
    let jitter = |j: &serde_json::Value| j["dwells"][0]["jitter_deg"].as_f64().unwrap();
    assert!(jitter(&narrow) < jitter(&wide));
    assert!((wide["swing_deg"].as_f64().unwrap() - 20.0).abs() <= 0.5);
    assert_eq!(wide["theta_deg"].as_array().unwrap().len(), 361);
    let img = image::open(&png).unwrap();
    // A landscape 11 × 8.5 in card at the default 150 dpi.
    assert_eq!((img.width(), img.height()), (1650, 1275));
    let _ = std::fs::remove_dir_all(&dir);
    // Hoeken's straight run and a second, short run are no double dwell: the slot's
    // output wanders half its swing during the second (once printed with exit 0).
    let out = bin()
        .args([
            "dwell",
            "--coupler",
            "2.5",
            "--rocker",
            "2.5",
            "--ground",
            "2",
            "--point",
            "5,0",
            "--kind",
            "double-lines",
            "--window",
            "150:210",
            "--window2",
            "300:330",
            "--max-link-ratio",
            "40",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--max-jitter-pct"));
}

/// `dwell --kind double-arcs`: a usable design on two 30° arcs of atlas curve 2723
/// (A = 3, B = 3.5, C = 2.5, point (1.5, −3)), and a typed refusal on the mirror-image
/// arcs of the symmetric atlas curve 5 (A = B = C = 1.5, point (1.5, −1.5)).
#[test]
fn dwell_double_arcs_designs_or_refuses() {
    let d = run_json(&[
        "dwell",
        "--coupler",
        "3",
        "--rocker",
        "3.5",
        "--ground",
        "2.5",
        "--point",
        "1.5,-3",
        "--kind",
        "double-arcs",
        "--window",
        "195:225",
        "--window2",
        "355:385",
        "--format",
        "json",
    ]);
    let swing = d["dwell_swing_deg"].as_f64().unwrap();
    assert!(swing > 30.0, "swing {swing}");
    for x in d["dwells"].as_array().unwrap() {
        assert!(x["jitter_deg"].as_f64().unwrap() < 0.1, "{x}");
    }
    let mu = d["output_transmission_deg"].as_array().unwrap();
    assert!(mu.iter().all(|m| {
        let m = m.as_f64().unwrap();
        (30.0 - 1e-9..=150.0 + 1e-9).contains(&m)
    }));
    let out = bin()
        .args([
            "dwell",
            "--coupler",
            "1.5",
            "--rocker",
            "1.5",
            "--ground",
            "1.5",
            "--point",
            "1.5,-1.5",
            "--kind",
            "double-arcs",
            "--window",
            "65:130",
            "--window2",
            "230:295",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("opposite branches"), "{err}");
}

/// `curve --window` shows its measures in every format (they were dropped silently from
/// `table` and `csv`): the same ε_S, ε_V and radius as the JSON.
#[test]
fn curve_window_measures_in_every_format() {
    let args = [
        "curve",
        "--coupler",
        "3",
        "--rocker",
        "2.5",
        "--ground",
        "3.5",
        "--point",
        "3,0",
        "--window",
        "300:420",
    ];
    let j = run_json(&args);
    let w = &j["window"];
    let run = |format: &str| {
        let out = bin()
            .args(args)
            .args(["--format", format])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    };
    let csv = run("csv");
    let block: Vec<&str> = csv
        .split("\n\n")
        .nth(1)
        .expect("a window block")
        .lines()
        .collect();
    let keys: Vec<&str> = block[0].split(',').collect();
    let values: Vec<&str> = block[1].split(',').collect();
    let get = |k: &str| values[keys.iter().position(|&x| x == k).unwrap()];
    assert_eq!(
        get("arc_radius").parse::<f64>().unwrap(),
        w["arc_radius"].as_f64().unwrap()
    );
    assert_eq!(
        get("extent").parse::<f64>().unwrap(),
        w["extent"].as_f64().unwrap()
    );
    assert_eq!(get("window_start_deg"), "300");
    let table = run("table");
    let r = w["arc_radius"].as_f64().unwrap();
    assert!(table.contains("# window 300°..420°"), "{table}");
    assert!(table.contains(&format!("radius {r:.6}")), "{table}");
}
