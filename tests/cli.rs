//! The real binary, run the way a user runs it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("the binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn spec(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("atlas-spec")
        .join(name)
        .display()
        .to_string()
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("coupler-atlas-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn generate_is_byte_identical_for_any_jobs() {
    let (a, b) = (tmp("j1"), tmp("j2"));
    for (dir, jobs) in [(&a, "1"), (&b, "2")] {
        let out = run(&[
            "generate",
            &spec("quick.toml"),
            "--out",
            dir.to_str().unwrap(),
            "--jobs",
            jobs,
            "--quiet",
            "--no-pages",
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
    }
    let ia = std::fs::read(a.join("index.json")).unwrap();
    let ib = std::fs::read(b.join("index.json")).unwrap();
    assert!(!ia.is_empty());
    assert!(ia == ib, "index.json differs between --jobs 1 and --jobs 2");
    let index: serde_json::Value = serde_json::from_slice(&ia).unwrap();
    assert_eq!(index["schema_version"], 1);
    assert_eq!(index["summary"]["curves"], 72);
    let curves = index["curves"].as_array().unwrap();
    assert_eq!(curves.len(), 72);
    for (i, c) in curves.iter().enumerate() {
        assert_eq!(c["id"], i as u64);
        assert_eq!(c["class"], "GCRR");
    }
    // No NaN or infinity anywhere (JSON cannot hold them; serde_json would write null).
    assert!(!text(&ia).contains("null") && !text(&ia).contains("NaN"));
    let _ = std::fs::remove_dir_all(&a);
    let _ = std::fs::remove_dir_all(&b);
}

#[test]
fn generate_counts_skipped_linkages() {
    let dir = tmp("hd");
    let out = run(&[
        "generate",
        &spec("hartenberg-denavit.toml"),
        "--out",
        dir.to_str().unwrap(),
        "--quiet",
        "--no-pages",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("index.json")).unwrap()).unwrap();
    let s = &index["summary"];
    assert_eq!(s["combinations"], 36);
    assert_eq!(s["linkages"], 10);
    let skipped: u64 = s["skipped"]
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(skipped, 26);
    assert!(
        text(&out.stderr).contains("26 skipped"),
        "{}",
        text(&out.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn dry_run_prints_the_plan_and_writes_nothing() {
    let dir = tmp("dry");
    let out = run(&["generate", "--dry-run", "--out", dir.to_str().unwrap()]);
    assert!(out.status.success());
    let t = text(&out.stdout);
    assert!(t.contains("linkages:     175 strict crank-rockers"), "{t}");
    // 50 coupler points (10 along the coupler, u up to 2A, × 5 rows) per linkage, one
    // row per page.
    assert!(t.contains("curves:       8750"), "{t}");
    assert!(t.contains("pages:        875"), "{t}");
    assert!(!dir.exists());
}

#[test]
fn bad_spec_is_refused_with_file_line_and_key() {
    let dir = tmp("bad");
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    let good = std::fs::read_to_string(spec("quick.toml")).unwrap();
    std::fs::write(
        &bad,
        good.replace(
            "rocker  = { start = 2.5, end = 3.0, step = 0.5 }",
            "rocker  = { start = 2.5, end = 3.0, step = -0.5 }",
        ),
    )
    .unwrap();
    let out = run(&[
        "generate",
        bad.to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let e = text(&out.stderr);
    assert!(
        e.contains("bad.toml:")
            && e.contains("linkages.rocker.step")
            && e.contains("step must be > 0"),
        "{e}"
    );
    assert!(
        !dir.join("out").exists(),
        "nothing is written for a bad spec"
    );
    let missing = run(&["generate", dir.join("nope.toml").to_str().unwrap()]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(
        text(&missing.stderr).contains("nope.toml"),
        "{}",
        text(&missing.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn curve_json_contract() {
    let out = run(&[
        "curve",
        "--coupler",
        "2.5",
        "--rocker",
        "2.5",
        "--ground",
        "2",
        "--point",
        "5,0",
        "--step",
        "10",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        v["linkage"],
        serde_json::json!({"coupler": 2.5, "rocker": 2.5, "ground": 2.0})
    );
    assert_eq!(v["point"], serde_json::json!({"u": 5.0, "v": 0.0}));
    assert_eq!(v["circuit"], "open");
    assert_eq!(v["class"], "GCRR");
    let samples = v["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 36);
    // Key order is part of the contract (serde_json::Value sorts keys, so read the text).
    let raw = text(&out.stdout);
    assert!(raw.starts_with("{\"linkage\":{\"coupler\":2.5,\"rocker\":2.5,\"ground\":2.0},\"point\":{\"u\":5.0,\"v\":0.0},\"circuit\":\"open\",\"class\":\"GCRR\",\"samples\":["), "{raw}");
    assert!(raw.contains("\n{\"theta_deg\":0.0,\"x\":"), "{raw}");
    let first = raw.lines().nth(1).unwrap();
    let order: Vec<usize> = [
        "theta_deg",
        "\"x\"",
        "\"y\"",
        "\"vx\"",
        "\"vy\"",
        "transmission_deg",
    ]
    .iter()
    .map(|k| first.find(k).unwrap())
    .collect();
    assert!(order.windows(2).all(|w| w[0] < w[1]), "{first}");
    for (k, s) in samples.iter().enumerate() {
        assert_eq!(s["theta_deg"].as_f64().unwrap(), 10.0 * k as f64);
        assert!(s["x"].is_f64() && s["vx"].is_f64() && s["transmission_deg"].is_f64());
    }
    // Hoeken: the straight part is centred on θ = 180°, where the curve crosses x = C = 2.
    let mid = &samples[18];
    assert!((mid["x"].as_f64().unwrap() - 2.0).abs() < 1e-12, "{mid}");
}

#[test]
fn curve_keeps_unassemblable_samples_as_nulls() {
    // Non-Grashof (RRR1): the crank cannot turn fully.
    let out = run(&[
        "curve",
        "--coupler",
        "1.2",
        "--rocker",
        "1.4",
        "--ground",
        "1.8",
        "--point",
        "1,-1",
        "--step",
        "5",
    ]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["class"], "RRR1");
    let samples = v["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 72, "every crank angle keeps its sample");
    let nulls = samples.iter().filter(|s| s["x"].is_null()).count();
    assert!(nulls > 0 && nulls < 72);
    for s in samples.iter().filter(|s| s["x"].is_null()) {
        for k in ["y", "vx", "vy", "transmission_deg"] {
            assert!(s[k].is_null());
        }
    }
    // Exact change point: positions everywhere, velocities null only at the fold (θ = 180°).
    let out = run(&[
        "curve",
        "--coupler",
        "3",
        "--rocker",
        "3",
        "--ground",
        "5",
        "--point",
        "1,0.5",
        "--step",
        "30",
        "--format",
        "csv",
    ]);
    assert!(out.status.success());
    let t = text(&out.stdout);
    let lines: Vec<&str> = t.lines().collect();
    assert_eq!(lines[0], "theta_deg,x,y,vx,vy,transmission_deg");
    assert_eq!(lines.len(), 13);
    assert!(lines[7].starts_with("180,0,0.5,,,180"), "{}", lines[7]);
    assert!(!t.contains("NaN") && !t.contains("inf"));
}

#[test]
fn curve_rejects_bad_numbers_clearly() {
    for (args, needle) in [
        (
            vec![
                "--coupler",
                "nan",
                "--rocker",
                "1",
                "--ground",
                "1",
                "--point",
                "0,0",
            ],
            "not a finite number",
        ),
        (
            vec![
                "--coupler",
                "-2",
                "--rocker",
                "1",
                "--ground",
                "1",
                "--point",
                "0,0",
            ],
            "must be > 0",
        ),
        (
            vec![
                "--coupler",
                "2",
                "--rocker",
                "1",
                "--ground",
                "1",
                "--point",
                "0",
            ],
            "expected U,V",
        ),
        (
            vec![
                "--coupler",
                "2",
                "--rocker",
                "1",
                "--ground",
                "1",
                "--point",
                "0,0",
                "--step",
                "0",
            ],
            "--step",
        ),
    ] {
        let out = run(&[vec!["curve"], args].concat());
        assert_eq!(out.status.code(), Some(2), "{needle}");
        assert!(text(&out.stderr).contains(needle), "{}", text(&out.stderr));
    }
}

#[test]
fn default_atlas_generates_completely() {
    let dir = tmp("default");
    let out = run(&[
        "generate",
        "--out",
        dir.to_str().unwrap(),
        "--quiet",
        "--no-pages",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("index.json")).unwrap()).unwrap();
    assert_eq!(index["summary"]["curves"], 8750);
    assert_eq!(index["curves"].as_array().unwrap().len(), 8750);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn index_flags_what_the_numerics_cannot_resolve() {
    let dir = tmp("flags");
    std::fs::create_dir_all(&dir).unwrap();
    // A = B = 3, C = 5 − 1e-7: a crank-rocker a hair from the change point 1 + 5 = 3 + 3,
    // folding almost flat at θ = 180°.
    let spec = dir.join("near.toml");
    std::fs::write(
        &spec,
        "[atlas]\nname = \"near\"\n[linkages]\ncoupler = { start = 3, end = 3, step = 1 }\nrocker = { start = 3, end = 3, step = 1 }\nground = { start = 4.9999999, end = 4.9999999, step = 1 }\n[points]\nu = { start = 0, end = 1, step = 1, relative = true }\nv = { start = 0, end = 0, step = 1 }\n",
    )
    .unwrap();
    let out = run(&[
        "generate",
        spec.to_str().unwrap(),
        "--out",
        dir.join("near").to_str().unwrap(),
        "--quiet",
        "--no-pages",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("near/index.json")).unwrap()).unwrap();
    for c in index["curves"].as_array().unwrap() {
        assert_eq!(
            c["flags"],
            serde_json::json!(["near_change_point", "near_toggle"]),
            "{c}"
        );
    }
    // The default atlas's half-unit crank-rockers are all well away from such conditions.
    let plain = run(&[
        "generate",
        "--out",
        dir.join("plain").to_str().unwrap(),
        "--quiet",
        "--no-pages",
    ]);
    assert!(plain.status.success());
    let text_index =
        String::from_utf8(std::fs::read(dir.join("plain/index.json")).unwrap()).unwrap();
    assert!(!text_index.contains("\"flags\""));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn png_compression_best_writes_smaller_pages_with_the_same_pixels() {
    let (fast, best) = (tmp("png-fast"), tmp("png-best"));
    for (dir, level) in [(&fast, "fast"), (&best, "best")] {
        let out = run(&[
            "generate",
            &spec("quick.toml"),
            "--out",
            dir.to_str().unwrap(),
            "--png-compression",
            level,
            "--quiet",
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
    }
    let mut names: Vec<_> = std::fs::read_dir(fast.join("pages"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert!(names.len() > 3, "{names:?}");
    let (mut fast_bytes, mut best_bytes) = (0, 0);
    for n in &names {
        let (a, b) = (fast.join("pages").join(n), best.join("pages").join(n));
        let (sa, sb) = (
            std::fs::metadata(&a).unwrap().len(),
            std::fs::metadata(&b).unwrap().len(),
        );
        assert_ne!(
            std::fs::read(&a).unwrap(),
            std::fs::read(&b).unwrap(),
            "{n:?}"
        );
        let (ia, ib) = (image::open(&a).unwrap(), image::open(&b).unwrap());
        assert_eq!(ia.color(), image::ColorType::L8, "{n:?}");
        assert_eq!(ia.to_luma8(), ib.to_luma8(), "{n:?}: same pixels");
        fast_bytes += sa;
        best_bytes += sb;
    }
    assert!(
        best_bytes * 10 < fast_bytes * 9,
        "best {best_bytes} B is not clearly smaller than fast {fast_bytes} B"
    );
    // The choice is recorded: a rerun with the other one replaces the atlas.
    let again = run(&[
        "generate",
        &spec("quick.toml"),
        "--out",
        best.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(again.status.success(), "{}", text(&again.stderr));
    for n in &names {
        let (a, b) = (fast.join("pages").join(n), best.join("pages").join(n));
        assert_eq!(
            std::fs::read(&a).unwrap(),
            std::fs::read(&b).unwrap(),
            "{n:?}"
        );
    }
    let _ = std::fs::remove_dir_all(&fast);
    let _ = std::fs::remove_dir_all(&best);
}
