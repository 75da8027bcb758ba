//! `coupler-atlas curve --mechanism geared-fivebar`, run as a user runs it: the JSON
//! contract (the library's numbers, nulls where the dyad cannot close, flags and error
//! bound), the full trace across toggles, the exact straight line, and clear errors.

use coupler_atlas::{Circuit, CouplerPoint, GearRatio, GearedFiveBar};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn json(out: &Output) -> serde_json::Value {
    assert_ok(out);
    serde_json::from_slice(&out.stdout).expect("valid JSON")
}

/// Asserts the run succeeded, its stderr in the message.
fn assert_ok(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The repository's atlas spec `name` (e.g. `geared-quick.toml`).
fn spec(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("atlas-spec")
        .join(name)
}

/// A fresh (emptied) temporary folder for this test process.
fn fresh_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// `generate SPEC --out OUT --quiet EXTRA…`, which must succeed.
fn generate(spec: &Path, out: &Path, extra: &[&str]) {
    let mut args = vec![
        "generate",
        spec.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ];
    args.extend_from_slice(extra);
    assert_ok(&run(&args));
}

fn geared(lengths: [&str; 4], ratio: &str, phase: &str, rest: &[&str]) -> Output {
    let mut args = vec![
        "curve",
        "--mechanism",
        "geared-fivebar",
        "--l1",
        lengths[0],
        "--l3",
        lengths[1],
        "--l4",
        lengths[2],
        "--l5",
        lengths[3],
        "--ratio",
        ratio,
        "--phase",
        phase,
    ];
    args.extend_from_slice(rest);
    run(&args)
}

#[test]
fn curve_json_is_the_librarys_over_the_period() {
    let out = geared(
        ["3", "3", "3", "1"],
        "-1/2",
        "30",
        &["--point", "1,1", "--step", "5", "--circuit", "crossed"],
    );
    let j = json(&out);
    assert_eq!(j["mechanism"], "geared-fivebar");
    assert_eq!(j["linkage"]["ratio"], "-1/2");
    assert_eq!(j["linkage"]["l5"], 1.0);
    assert_eq!(j["class"], "I");
    assert_eq!(j["rotatability"], "full");
    assert_eq!(j["period_deg"], 720.0);
    assert_eq!(j["circuit"], "crossed");
    assert_eq!(j["flags"], serde_json::json!([]));
    let bound = j["error_bound"].as_f64().unwrap();
    assert!(bound > 0.0 && bound < 1e-12, "{bound}");
    let samples = j["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 144, "two input turns at 5°");
    let g = GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::new(-1, 2).unwrap(), 30.0).unwrap();
    let p = CouplerPoint::new(1.0, 1.0);
    for (k, s) in samples.iter().enumerate() {
        let theta = 5.0 * k as f64;
        assert_eq!(s["theta_deg"].as_f64().unwrap(), theta);
        let pose = g.pose_at(Circuit::Crossed, theta).unwrap();
        let (m, v) = (pose.point(p), pose.velocity(p).unwrap());
        // The printed numbers are the library's, to the bit.
        assert_eq!(s["x"].as_f64().unwrap(), m.x);
        assert_eq!(s["y"].as_f64().unwrap(), m.y);
        assert_eq!(s["vx"].as_f64().unwrap(), v.x);
        assert_eq!(s["vy"].as_f64().unwrap(), v.y);
        let t5 = s["theta5_deg"].as_f64().unwrap();
        assert!(((-0.5 * theta + 30.0).rem_euclid(360.0) - t5).abs() < 1e-12);
    }
    // CSV and table carry the same samples.
    let csv = geared(
        ["3", "3", "3", "1"],
        "-1/2",
        "30",
        &["--point", "1,1", "--step", "5", "--format", "csv"],
    );
    assert!(csv.status.success());
    assert_eq!(String::from_utf8_lossy(&csv.stdout).lines().count(), 145);
}

#[test]
fn rocking_input_prints_nulls_and_traces_fully_across_toggles() {
    // λ = 1, φ = 180°: the dyad cannot close around θ2 = 180° (docs/geared-fivebar.md).
    let args = ["2.5", "2", "2", "1"];
    let j = json(&geared(
        args,
        "1",
        "180",
        &["--point", "1,0.5", "--step", "2"],
    ));
    assert_eq!(j["rotatability"], "rocks");
    let samples = j["samples"].as_array().unwrap();
    let nulls = samples.iter().filter(|s| s["x"].is_null()).count();
    assert!(nulls > 0 && nulls < samples.len(), "{nulls}");
    for s in samples.iter().filter(|s| s["x"].is_null()) {
        for key in ["y", "vx", "vy", "transmission_deg"] {
            assert!(s[key].is_null(), "{s}");
        }
    }
    let flags = j["flags"].as_array().unwrap();
    assert!(flags.contains(&"not_assembled".into()), "{flags:?}");

    let full = json(&geared(
        args,
        "1",
        "180",
        &["--point", "1,0.5", "--step", "2", "--trace", "full"],
    ));
    assert_eq!(full["trace"], "full");
    assert_eq!(full["mechanism"], "geared-fivebar");
    assert_eq!(full["input_range"]["kind"], "rocks");
    let branches = full["branches"].as_array().unwrap();
    assert_eq!(branches.len(), 1);
    let s = branches[0]["samples"].as_array().unwrap();
    let (first, last) = (&s[0], &s[s.len() - 1]);
    assert_eq!(first["toggle"], true);
    assert_eq!((&first["x"], &first["y"]), (&last["x"], &last["y"]));
    assert!(s.iter().all(|x| x["x"].is_f64() && x["y"].is_f64()));
    // Out on one circuit, back on the other, without a jump.
    let xy = |v: &serde_json::Value| (v["x"].as_f64().unwrap(), v["y"].as_f64().unwrap());
    for w in s.windows(2) {
        let ((x0, y0), (x1, y1)) = (xy(&w[0]), xy(&w[1]));
        assert!((x1 - x0).hypot(y1 - y0) < 0.2, "{} {}", w[0], w[1]);
    }
    assert!(s.iter().any(|x| x["circuit"] == "open"));
    assert!(s.iter().any(|x| x["circuit"] == "crossed"));
}

#[test]
fn straight_line_classic_is_straight_to_rounding() {
    // λ = −1, φ = 180°, L5 = 1, L3 = L4: the joint (u, v) = (L3, 0) runs on x = L1/2.
    let j = json(&geared(
        ["3", "3", "3", "1"],
        "-1",
        "180",
        &["--point", "3,0", "--step", "0.5"],
    ));
    let samples = j["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 720);
    let worst = samples
        .iter()
        .map(|s| (s["x"].as_f64().unwrap() - 1.5).abs())
        .fold(0.0, f64::max);
    assert!(worst <= 4.0 * f64::EPSILON * 3.0, "{worst:e}");
}

#[test]
fn bad_geared_input_is_refused_clearly() {
    let err = |out: Output, want: &str| {
        assert_eq!(
            out.status.code(),
            Some(2),
            "{}",
            String::from_utf8_lossy(&out.stdout)
        );
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(e.contains(want), "{e}");
    };
    err(
        run(&[
            "curve",
            "--mechanism",
            "geared-fivebar",
            "--l1",
            "3",
            "--l3",
            "3",
            "--l4",
            "3",
            "--l5",
            "1",
            "--point",
            "1,1",
        ]),
        "--ratio is missing",
    );
    err(
        geared(["3", "3", "3", "1"], "1.5", "0", &["--point", "1,1"]),
        "is not a gear ratio",
    );
    err(
        geared(["3", "3", "3", "1"], "0", "0", &["--point", "1,1"]),
        "must not be 0",
    );
    err(
        geared(["3", "-3", "3", "1"], "1", "0", &["--point", "1,1"]),
        "a length must be > 0",
    );
    err(
        geared(
            ["3", "3", "3", "1"],
            "1",
            "0",
            &["--point", "1,1", "--step", "0"],
        ),
        "--step must be > 0",
    );
    err(
        geared(
            ["3", "3", "3", "1"],
            "1",
            "0",
            &["--point", "1,1", "--coupler", "2"],
        ),
        "name a four-bar",
    );
    err(
        run(&["curve", "--l1", "3", "--point", "1,1"]),
        "add --mechanism geared-fivebar",
    );
    err(
        run(&["curve", "--coupler", "2", "--rocker", "2", "--point", "1,1"]),
        "--ground is missing",
    );
}

#[test]
fn geared_atlas_generates_pages_and_an_index_that_search_reads() {
    let spec = spec("geared-quick.toml");
    let dirs: Vec<_> = ["j1", "j2"]
        .iter()
        .map(|j| fresh_dir(&format!("geared-atlas-{j}")))
        .collect();
    for (dir, jobs) in dirs.iter().zip(["1", "2"]) {
        generate(&spec, dir, &["--jobs", jobs]);
    }
    let bytes = std::fs::read(dirs[0].join("index.json")).unwrap();
    assert!(
        bytes == std::fs::read(dirs[1].join("index.json")).unwrap(),
        "index.json differs between --jobs 1 and --jobs 2"
    );
    for k in 1..=8 {
        let name = format!("pages/geared-quick-{k:04}.png");
        assert!(
            std::fs::read(dirs[0].join(&name)).unwrap()
                == std::fs::read(dirs[1].join(&name)).unwrap(),
            "{name} differs between --jobs 1 and --jobs 2"
        );
    }
    let index: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
    assert_eq!(index["spec"]["linkages"]["mechanism"], "geared-fivebar");
    assert_eq!(index["summary"]["linkages"], 8);
    let curves = index["curves"].as_array().unwrap();
    assert_eq!(curves.len(), 16);
    for c in curves {
        assert_eq!(c["class"], "I");
        assert!(c["features"].is_object() && c["page"].is_object());
        // The index's measures are the library's curve over the whole period (one turn
        // of a λ = −1/2 curve would be about half its length): the trapezoid length at
        // 0.1° agrees with the index's from 2° samples (1.2e-5 relative at worst here,
        // on λ = −2's quicker loops).
        let l = &c["linkage"];
        let g = GearedFiveBar::new(
            l["l1"].as_f64().unwrap(),
            l["l3"].as_f64().unwrap(),
            l["l4"].as_f64().unwrap(),
            l["l5"].as_f64().unwrap(),
            l["ratio"].as_str().unwrap().parse().unwrap(),
            l["phase"].as_f64().unwrap(),
        )
        .unwrap();
        let p = CouplerPoint::new(
            c["point"]["u"].as_f64().unwrap(),
            c["point"]["v"].as_f64().unwrap(),
        );
        let fine = g.trace(Circuit::Open, p, 0.1).unwrap();
        let speed: f64 = (0..fine.len()).map(|k| fine.vx[k].hypot(fine.vy[k])).sum();
        let length = speed * 0.1f64.to_radians();
        let got = c["length"].as_f64().unwrap();
        assert!((got - length).abs() < 1e-4 * length, "{got} vs {length}");
    }
    // λ = −1/2 curves run two input turns.
    let half: Vec<_> = curves
        .iter()
        .filter(|c| c["linkage"]["ratio"] == "-1/2")
        .collect();
    assert_eq!(half.len(), 4);
    // search reads the index by features and class.
    let out = run(&[
        "search",
        dirs[0].join("index.json").to_str().unwrap(),
        "--class",
        "I",
        "--limit",
        "0",
        "--format",
        "json",
    ]);
    let found = json(&out);
    assert_eq!(found["total"], 16);
    let hits = found["hits"].as_array().unwrap();
    assert_eq!(hits.len(), 16);
    // Each hit carries its linkage's six dimensions, as the index records them.
    for h in hits {
        let c = curves.iter().find(|c| c["id"] == h["id"]).unwrap();
        assert_eq!(h["linkage"], c["linkage"], "curve {}", h["id"]);
    }
    // --linkage L1,L3,L4,L5,RATIO,PHASE finds that linkage's curves (and only them);
    // the CSV and the table print the dimensions.
    let out = run(&[
        "search",
        dirs[0].to_str().unwrap(),
        "--linkage",
        "3,3,3,1,-1/2,90",
        "--format",
        "csv",
    ]);
    assert_ok(&out);
    let csv = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(
        lines[0].starts_with("id,l1,l3,l4,l5,ratio,phase,u,v,"),
        "{}",
        lines[0]
    );
    assert_eq!(lines.len(), 3, "{csv}");
    for l in &lines[1..] {
        assert!(l.contains(",3,3,3,1,-1/2,90,"), "{l}");
    }
    let out = run(&["search", dirs[0].to_str().unwrap(), "--limit", "0"]);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(
        table.contains("# L1 3  L3 3  L4 3  L5 1  λ \u{2212}1/2  φ 90°  (class I)"),
        "{table}"
    );
    assert!(table.lines().all(|l| l.chars().count() <= 120), "{table}");
    // λ = −1/2 at φ = 270° is φ = 90° one input turn later: the atlas lists it once, and a
    // search for the repeat says where to look.
    let out = run(&[
        "search",
        dirs[0].to_str().unwrap(),
        "--linkage",
        "3,3,3,1,-1/2,270",
    ]);
    assert!(
        String::from_utf8_lossy(&out.stderr)
            .contains("traces the same curves as every phase 180° apart (90° …)"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A four-bar's A,B,C matches no geared row.
    let out = run(&[
        "search",
        dirs[0].to_str().unwrap(),
        "--linkage",
        "3,3,3",
        "--format",
        "json",
    ]);
    assert_eq!(json(&out)["total"], 0);
    // match works on the five-bar atlas: see `match_finds_a_geared_curve_and_places_it`.
    // dwell designs four-bar dwell linkages: a five-bar curve is refused, naming it.
    let out = run(&[
        "dwell",
        "--index",
        dirs[0].to_str().unwrap(),
        "--curve",
        "0",
        "--arc",
        "1",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("curve 0 is of a geared five-bar (L1=3 L3=3 L4=3 L5=1 ratio=-1 phase=0): dwell designs four-bar dwell linkages only"),
        "{err}"
    );
    for dir in &dirs {
        let _ = std::fs::remove_dir_all(dir);
    }
}

#[test]
fn cognates_geared_fivebar_gives_the_librarys_equivalent() {
    // A triple rocker (1 + 3.5 > 2 + 2): its equivalent's input rocks with the coupler.
    let out = run(&[
        "cognates",
        "--coupler",
        "2",
        "--rocker",
        "2",
        "--ground",
        "3.5",
        "--point",
        "1,0.5",
        "--geared-fivebar",
        "--format",
        "json",
    ]);
    let j = json(&out);
    let l = coupler_atlas::FourBar::new(2.0, 2.0, 3.5).unwrap();
    let eq = coupler_atlas::geared_equivalent(&l, CouplerPoint::new(1.0, 0.5)).unwrap();
    assert_eq!(
        j["geared_fivebar"],
        serde_json::to_value(eq.linkage).unwrap()
    );
    assert_eq!(j["scale"].as_f64().unwrap(), eq.scale);
    assert_eq!(j["geared_fivebar"]["ratio"], "1");
    assert_eq!(j["rotatability"], "rocks");
    assert_eq!(j["input_range"]["kind"], "rocks");
    assert_eq!(j["four_bar"]["class"], l.class().code());
    // The crank and rocker pins themselves have no equivalent (a zero-length crank).
    let bad = run(&[
        "cognates",
        "--coupler",
        "2",
        "--rocker",
        "2",
        "--ground",
        "3.5",
        "--point",
        "0,0",
        "--geared-fivebar",
    ]);
    assert_eq!(bad.status.code(), Some(2));
}

#[test]
fn straight_line_page_set_measures_its_line_at_rounding_level() {
    let dir = fresh_dir("geared-straight");
    generate(&spec("geared-straight-line.toml"), &dir, &["--dpi", "72"]);
    assert!(dir.join("pages/geared-straight-line-0001.png").exists());
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("index.json")).unwrap()).unwrap();
    let joint = index["curves"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["point"]["u"] == 3.0 && c["point"]["v"] == 0.0)
        .expect("the dyad joint's curve");
    // Its box is the line x = L1/2 = 1.5, a few ulps wide (at most 4 ulps of L3 = 3).
    let b = joint["bbox"].as_array().unwrap();
    let (x0, x1) = (b[0].as_f64().unwrap(), b[2].as_f64().unwrap());
    let tol = 4.0 * f64::EPSILON * 3.0;
    assert!(
        (x0 - 1.5).abs() <= tol && (x1 - 1.5).abs() <= tol,
        "{x0} {x1}"
    );
    // And the index's straight-segment measure finds it straight at rounding level.
    let segs = joint["features"]["straight_segments"].as_array().unwrap();
    assert!(!segs.is_empty());
    for s in segs {
        assert!(s["straightness_pct"].as_f64().unwrap() < 1e-12, "{s}");
    }
    // The joint is not a trivial pin (its curve is no arc about a ground pivot, as a
    // four-bar's rocker pin's is), so search shows it without --include-trivial.
    assert!(joint["features"]["trivial"].is_null(), "{joint}");
    let found = json(&run(&[
        "search",
        dir.to_str().unwrap(),
        "--straight",
        "90:0.01",
        "--format",
        "json",
    ]));
    assert_eq!(found["total"], 1, "{found}");
    assert_eq!(found["hits"][0]["id"], joint["id"]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A query tighter than the index's extraction tolerance re-measures the candidate
/// curves of a geared five-bar atlas through the mechanism (over its period: λ = −1/2
/// turns the input twice), and the answer equals that of the atlas generated at the
/// tighter tolerance: `geared-quick.toml` at the default 0.5 % against a copy at 0.2 %.
#[test]
fn geared_tighter_tolerance_equals_regenerating() {
    let dir = fresh_dir("geared-refine");
    std::fs::create_dir_all(&dir).unwrap();
    let quick_spec = spec("geared-quick.toml");
    let quick = std::fs::read_to_string(&quick_spec).unwrap();
    let tight = dir.join("tight.toml");
    std::fs::write(
        &tight,
        format!("{quick}\n[features]\nstraight_pct = 0.2\narc_pct = 0.2\n"),
    )
    .unwrap();
    let index_only = |spec: &Path, out: &str| {
        let out = dir.join(out);
        generate(spec, &out, &["--no-pages"]);
        out
    };
    let loose = index_only(&quick_spec, "loose");
    let tight = index_only(&tight, "tight");
    let search = |atlas: &std::path::Path, q: &[&str]| -> (serde_json::Value, String) {
        let mut args = vec!["search", atlas.to_str().unwrap()];
        args.extend_from_slice(q);
        args.extend_from_slice(&["--format", "json", "--limit", "0", "--include-trivial"]);
        let out = run(&args);
        (
            json(&out),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let mut found = 0;
    let mut half_turns = 0;
    for q in [
        &["--straight", "30:0.2"][..],
        &["--arc", "40:0.2", "--sort", "arc"],
        &["--arc", "30:0.1", "--sort", "deviation"],
        &["--straight", "30:0.15", "--arc", "30:0.2"],
    ] {
        let (a, note) = search(&loose, q);
        let (b, _) = search(&tight, q);
        assert!(note.contains("refined"), "{q:?}: {note}");
        assert_eq!(a, b, "{q:?}");
        found += a["total"].as_u64().unwrap();
        // Features past the first turn of a λ = −1/2 curve are found.
        for h in a["hits"].as_array().unwrap() {
            for f in h["pseudo_arcs"]
                .as_array()
                .unwrap()
                .iter()
                .chain(h["straight_segments"].as_array().unwrap())
            {
                half_turns += (f["start_deg"].as_f64().unwrap() >= 360.0) as usize;
            }
        }
    }
    assert!(found > 0, "the queries must find something");
    assert!(half_turns > 0, "a feature in the second input turn");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `curve --window` on a geared five-bar: the library's window measures through the
/// mechanism, to the bit (JSON), anywhere in the period (a λ = −1/2 window in the second
/// input turn differs from the same angles a turn earlier); the exact straight line's
/// window is straight at rounding level; a window that meets a dead input is refused.
#[test]
fn window_measures_are_the_librarys_for_the_geared_five_bar() {
    use coupler_atlas::{CrankWindow, LineDirection, WindowMeasures};
    let g = GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::new(-1, 2).unwrap(), 30.0).unwrap();
    let p = CouplerPoint::new(1.0, 1.0);
    let measured = |window: &str, line: &str| {
        let out = geared(
            ["3", "3", "3", "1"],
            "-1/2",
            "30",
            &["--point", "1,1", "--window", window, "--window-line", line],
        );
        json(&out)["window"].clone()
    };
    let library = |a: f64, b: f64, line: LineDirection| {
        let w = CrankWindow::new(a, b, 1.0).unwrap();
        let m = WindowMeasures::measure(&g, Circuit::Open, p, &w, line).unwrap();
        serde_json::to_value(&m).unwrap()
    };
    let second = measured("500:600", "fitted");
    assert_eq!(second, library(500.0, 600.0, LineDirection::Fitted));
    assert_ne!(second, library(140.0, 240.0, LineDirection::Fitted));
    assert_eq!(
        measured("10:60", "ground"),
        library(10.0, 60.0, LineDirection::Given(0.0))
    );
    // A window over the whole 720° period of λ = −1/2 (one turn is half the curve); a
    // four-bar's window still spans at most one turn, and a five-bar's its period.
    let whole = measured("0:720", "fitted");
    assert_eq!(whole, library(0.0, 720.0, LineDirection::Fitted));
    assert_eq!(whole["end_deg"], 720.0);
    let out = geared(
        ["3", "3", "3", "1"],
        "-1/2",
        "30",
        &["--point", "1,1", "--window", "0:721"],
    );
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("crank window 0:721 spans more than the mechanism's period of 720° of input"),
        "{err}"
    );
    let out = run(&[
        "curve",
        "--coupler",
        "3",
        "--rocker",
        "2.5",
        "--ground",
        "3",
        "--point",
        "1,1",
        "--window",
        "0:400",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("period of 360°"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The straight line: the joint (L3, 0) of λ = −1, φ = 180°.
    let out = geared(
        ["3", "3", "3", "1"],
        "-1",
        "180",
        &["--point", "3,0", "--window", "20:80", "--format", "table"],
    );
    assert_ok(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    let line = text.lines().find(|l| l.starts_with("# window ")).unwrap();
    let eps: f64 = line
        .split("ε_S ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    assert!(eps < 1e-12, "{line}");
    // A rocking input (the dyad cannot close everywhere) is refused by the window.
    let out = geared(
        ["2", "1", "1", "1.5"],
        "2",
        "0",
        &["--point", "1,1", "--window", "0:359"],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("does not assemble at θ ="),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The points of a geared five-bar's coupler curve at `angles` (input degrees), placed in
/// a user's frame by `z ↦ a·z + b` (reflected first when `mirror`).
fn user_points(
    g: &GearedFiveBar,
    point: CouplerPoint,
    angles: &[f64],
    mirror: bool,
) -> Vec<[f64; 2]> {
    let (a, b) = ((3.0, 4.0), (100.0, -20.0)); // scale 5, rotation 53.13°
    angles
        .iter()
        .map(|&t| {
            let m = g.pose_at(Circuit::Open, t).unwrap().point(point);
            let (x, y) = (m.x, if mirror { -m.y } else { m.y });
            [a.0 * x - a.1 * y + b.0, a.0 * y + a.1 * x + b.1]
        })
        .collect()
}

/// `match` on a geared five-bar atlas (issue 14): a closed target and an open window
/// drawn from an atlas curve of period 720° (λ = −1/2) are found exactly, the hit
/// reports the five-bar's dimensions and gears and its pivots in the user's frame; a
/// reflected target is reported as the mirror five-bar (other circuit, v and φ negated),
/// and that reported linkage, driven at the reported input angles, passes through the
/// target; `--refine` moves L1, L3, L4, L5, φ and the point off the grid to the exact
/// linkage. Before this, match refused a five-bar atlas.
#[test]
fn match_finds_a_geared_curve_and_places_it() {
    let dir = fresh_dir("geared-match");
    generate(&spec("geared-quick.toml"), &dir, &["--no-pages"]);
    let atlas = dir.to_str().unwrap();
    let half = GearRatio::new(-1, 2).unwrap();
    let src = GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, half, 90.0).unwrap();
    let p = CouplerPoint::new(1.5, 1.5);
    let write = |name: &str, pts: &[[f64; 2]]| {
        let f = dir.join(name);
        let text: String = pts.iter().map(|q| format!("{},{}\n", q[0], q[1])).collect();
        std::fs::write(&f, text).unwrap();
        f.to_str().unwrap().to_string()
    };
    let find = |file: &str, extra: &[&str]| -> serde_json::Value {
        let mut args = vec![
            "match", file, "--atlas", atlas, "--top", "1", "--format", "json",
        ];
        args.extend_from_slice(extra);
        json(&run(&args))["matches"][0].clone()
    };
    // Closed: the whole 720° period; open: 160° of input past the first turn.
    let closed: Vec<f64> = (0..120).map(|k| 6.0 * k as f64).collect();
    let open: Vec<f64> = (0..41).map(|k| 400.0 + 4.0 * k as f64).collect();
    for (name, angles, flag) in [("closed", &closed, "--closed"), ("open", &open, "--open")] {
        let file = write(&format!("{name}.csv"), &user_points(&src, p, angles, false));
        let best = find(&file, &[flag]);
        assert_eq!(best["curve"]["linkage"]["ratio"], "-1/2", "{name}: {best}");
        assert_eq!(best["curve"]["linkage"]["phase"], 90.0, "{name}: {best}");
        assert_eq!(best["curve"]["point"]["u"], 1.5, "{name}: {best}");
        assert!(
            best["error"]["rms_pct"].as_f64().unwrap() < 1e-6,
            "{name}: {best}"
        );
        let pl = &best["placement"];
        assert!((pl["scale"].as_f64().unwrap() - 5.0).abs() < 1e-6, "{pl}");
        assert!((pl["l1"].as_f64().unwrap() - 15.0).abs() < 1e-5, "{pl}");
        assert!((pl["o5"][0].as_f64().unwrap() - 109.0).abs() < 1e-5, "{pl}");
        assert!((pl["o5"][1].as_f64().unwrap() + 8.0).abs() < 1e-5, "{pl}");
        assert_eq!(pl["ratio"], "-1/2");
        if name == "open" {
            // The window starts at 400° of input: 40° into the second turn, which a
            // crank angle taken modulo 360° would confuse with the first.
            let c0 = pl["crank_deg"][0].as_f64().unwrap();
            assert!(
                (c0 - 40.0).abs() < 1e-3 || (c0 + 320.0).abs() < 1e-3,
                "{c0}"
            );
        }
    }
    // Reflected: reported as the mirror five-bar, which traces the target as placed.
    let pts = user_points(&src, p, &closed, true);
    let file = write("mirrored.csv", &pts);
    let best = find(&file, &["--closed", "--mirror"]);
    assert!(best["error"]["rms_pct"].as_f64().unwrap() < 1e-6, "{best}");
    let pl = &best["placement"];
    assert_eq!(pl["mirrored"], true);
    assert_eq!(pl["circuit"], "crossed");
    assert_eq!(pl["phase_deg"], -90.0);
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    let scale = f(&pl["scale"]);
    let reported = GearedFiveBar::new(
        f(&pl["l1"]) / scale,
        f(&pl["l3"]) / scale,
        f(&pl["l4"]) / scale,
        f(&pl["l5"]) / scale,
        pl["ratio"].as_str().unwrap().parse().unwrap(),
        f(&pl["phase_deg"]),
    )
    .unwrap();
    let q = CouplerPoint::new(f(&pl["point"][0]) / scale, f(&pl["point"][1]) / scale);
    let (o2, o5) = (&pl["o2"], &pl["o5"]);
    let (dx, dy) = (f(&o5[0]) - f(&o2[0]), f(&o5[1]) - f(&o2[1]));
    let (cx, sx) = (dx / reported.l1, dy / reported.l1);
    let first = f(&pl["crank_deg"][0]);
    for (k, target) in pts.iter().enumerate().step_by(7) {
        // Clockwise in the user's frame: the mirror's input runs backwards.
        let m = reported
            .pose_at(Circuit::Crossed, first - 6.0 * k as f64)
            .unwrap()
            .point(q);
        let z = [
            f(&o2[0]) + cx * m.x - sx * m.y,
            f(&o2[1]) + sx * m.x + cx * m.y,
        ];
        let d = (z[0] - target[0]).hypot(z[1] - target[1]);
        assert!(d < 1e-8, "point {k}: {z:?} vs {target:?}");
    }
    // --refine: an off-grid five-bar of the same gears is recovered exactly.
    let truth = GearedFiveBar::new(3.05, 3.1, 2.95, 1.0, half, 95.0).unwrap();
    let file = write(
        "off-grid.csv",
        &user_points(&truth, CouplerPoint::new(1.4, 1.55), &closed, false),
    );
    let best = find(&file, &["--closed", "--refine"]);
    let r = &best["refined"];
    assert!(r["error"]["rms_pct"].as_f64().unwrap() < 1e-6, "{best}");
    let l = &r["curve"]["linkage"];
    for (key, want) in [
        ("l1", 3.05),
        ("l3", 3.1),
        ("l4", 2.95),
        ("l5", 1.0),
        ("phase", 95.0),
    ] {
        assert!((f(&l[key]) - want).abs() < 1e-6, "{key}: {r}");
    }
    assert_eq!(r["class"], "I");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `match --timed` with a closed target on a geared five-bar of period 720° (λ = −1/2,
/// issue 14): the timing spans the whole period. A loop timed by angles over two input
/// turns finds its source exactly at crank rate 1 (the angles' offset is free), equal
/// steps divide the curve's own period (6° a point for 120 points on a 720° curve), the
/// same loop with the wrong timing (half the travel) fits nothing, and angles spanning
/// more than the atlas's longest period are refused naming the target, the span and the
/// period. Before, any closed target timed over 360° or more was refused.
#[test]
fn match_timed_closed_target_spans_the_geared_period() {
    let dir = fresh_dir("geared-timed");
    generate(&spec("geared-quick.toml"), &dir, &["--no-pages"]);
    let atlas = dir.to_str().unwrap();
    let half = GearRatio::new(-1, 2).unwrap();
    let src = GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, half, 90.0).unwrap();
    let p = CouplerPoint::new(1.5, 1.5);
    let angles: Vec<f64> = (0..120).map(|k| 6.0 * k as f64).collect();
    let pts = user_points(&src, p, &angles, false);
    // Points with a timing column `t_k = 30° + step·k`, or none (equal steps).
    let write = |name: &str, step: Option<f64>| {
        let f = dir.join(name);
        let text: String = pts
            .iter()
            .enumerate()
            .map(|(k, q)| match step {
                Some(s) => format!("{},{},{}\n", q[0], q[1], 30.0 + s * k as f64),
                None => format!("{},{}\n", q[0], q[1]),
            })
            .collect();
        std::fs::write(&f, text).unwrap();
        f.to_str().unwrap().to_string()
    };
    let find = |file: &str| -> serde_json::Value {
        json(&run(&[
            "match", file, "--atlas", atlas, "--closed", "--timed", "--top", "3", "--format",
            "json",
        ]))["matches"]
            .clone()
    };
    for (name, step, rate) in [("angles", Some(6.0), 1.0), ("steps", None, 6.0)] {
        let file = write(&format!("{name}.csv"), step);
        let best = find(&file)[0].clone();
        assert_eq!(best["curve"]["linkage"]["ratio"], "-1/2", "{name}: {best}");
        assert_eq!(best["curve"]["linkage"]["phase"], 90.0, "{name}: {best}");
        assert_eq!(best["curve"]["point"]["u"], 1.5, "{name}: {best}");
        assert!(
            best["error"]["rms_pct"].as_f64().unwrap() < 1e-6,
            "{name}: {best}"
        );
        assert!(
            (best["timing_rate"].as_f64().unwrap() - rate).abs() < 1e-9,
            "{name}: {best}"
        );
        // The crank runs the whole period: from the first point to the last, 714°.
        let c = &best["placement"]["crank_deg"];
        let travel = c[1].as_f64().unwrap() - c[0].as_f64().unwrap();
        assert!((travel - 714.0).abs() < 1e-6, "{name}: {c}");
    }
    // Timed at 3° a point (357° in all), the loop is not that curve's timing: nothing
    // in the atlas fits it closely.
    let file = write("wrong.csv", Some(3.0));
    for m in find(&file).as_array().unwrap() {
        assert!(m["error"]["rms_pct"].as_f64().unwrap() > 1.0, "{m}");
    }
    // More than the longest period: refused, naming the target, its span and the period.
    let f = dir.join("too-long.csv");
    let mut text = std::fs::read_to_string(write("angles.csv", Some(6.0))).unwrap();
    text.push_str("100,-15,750\n");
    std::fs::write(&f, text).unwrap();
    let out = run(&[
        "match",
        f.to_str().unwrap(),
        "--atlas",
        atlas,
        "--closed",
        "--timed",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("too-long.csv")
            && err.contains(
                "angles span 720°, but the longest period of the curves is 720° of input"
            ),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A `[[curve]]` page set of geared five-bars (`atlas-spec/geared-classics.toml`, issue
/// 14): each entry is traced over its period (λ = −1/2: 720° of input) or across its
/// toggles, `curves.json` records the five-bar's dimensions and Ting class, the exact
/// straight line's run is straight at rounding level, `search` reads the set, and an entry
/// missing its gear ratio is refused naming it. Before, `[[curve]]` entries were
/// four-bars only.
#[test]
fn geared_curve_page_set_traces_and_measures_each_entry() {
    use coupler_atlas::{ClassicCurve, CurveList, InputRange, Linkage};
    let spec = spec("geared-classics.toml");
    let list = CurveList::parse(&std::fs::read_to_string(&spec).unwrap(), "g").unwrap();
    assert!(
        list.curves
            .iter()
            .all(|c| matches!(c.linkage, Linkage::GearedFiveBar(_)))
    );
    let dir = fresh_dir("geared-classics");
    generate(&spec, &dir, &["--dpi", "72"]);
    for k in 1..=3 {
        assert!(
            dir.join(format!("pages/geared-classics-{k:04}.png"))
                .exists()
        );
    }
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("curves.json")).unwrap()).unwrap();
    let curves = v["curves"].as_array().unwrap();
    assert_eq!(curves.len(), 3);
    let step = list.sampling.crank_step_deg;
    for (c, named) in curves.iter().zip(&list.curves) {
        assert_eq!(c["linkage"], serde_json::to_value(named.linkage).unwrap());
        assert!(c["linkage"]["l1"].is_number() && c["linkage"]["ratio"].is_string());
        // The library's measure of the entry, as recorded.
        let m = ClassicCurve::compute(named, step);
        assert_eq!(c["branches"], m.branches.len());
        assert_eq!(c["closure"], 0.0, "{}", named.name);
    }
    // The straight line: Ting class I, a crank; its run straight to rounding.
    assert_eq!(curves[0]["class"], "I");
    assert_eq!(curves[0]["input"]["kind"], "full");
    let run0 = &curves[0]["straight"][2];
    assert!(run0["straightness"].as_f64().unwrap() < 1e-14, "{run0}");
    assert!(run0["input_span_deg"].as_f64().unwrap() > 150.0, "{run0}");
    // λ = −1/2: one branch over two turns (720° at 0.5°, closing on its first sample).
    assert_eq!(curves[1]["samples"][0], 1441);
    // The rocking input: Ting class II, rocking between two toggles, one branch out and
    // back.
    assert_eq!(curves[2]["class"], "II");
    assert!(matches!(
        ClassicCurve::compute(&list.curves[2], step).range,
        InputRange::Rocks { .. }
    ));
    // search reads the set: the straight line's 150° run at 0.01 %.
    let o = run(&[
        "search",
        dir.to_str().unwrap(),
        "--straight",
        "150:0.01",
        "--format",
        "json",
    ]);
    let found = json(&o);
    assert_eq!(found["total"], 1, "{found}");
    assert_eq!(found["hits"][0]["id"], 0);
    assert_eq!(found["hits"][0]["linkage"]["ratio"], "-1");
    // An entry without its gear ratio is refused, naming it and the key.
    let text = std::fs::read_to_string(&spec)
        .unwrap()
        .replace("ratio = \"-1/2\"\n", "");
    let bad = dir.join("no-ratio.toml");
    std::fs::write(&bad, text).unwrap();
    let o = run(&[
        "generate",
        bad.to_str().unwrap(),
        "--out",
        dir.join("x").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("`Two-turn loop` has no `ratio`"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
