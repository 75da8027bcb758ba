//! `coupler-atlas match` run the way a user runs it: on the quick atlas, with targets made
//! from its own curves moved into a user frame; the shape sidecar `generate` writes; bad
//! atlases and targets refused clearly.

use coupler_atlas::shape::{C64, CouplerCurve, SHAPES_FILE, decode_sidecar};
use coupler_atlas::{Circuit, CouplerPoint, FourBar};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("coupler-atlas-match-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The quick atlas (72 curves) generated into `dir` without pages (with pages when asked).
fn quick_atlas(dir: &Path, pages: bool) {
    let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("atlas-spec/quick.toml");
    let mut args = vec![
        "generate",
        spec.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
        "--quiet",
    ];
    if !pages {
        args.push("--no-pages");
    }
    let out = run(&args);
    assert!(out.status.success(), "{}", text(&out.stderr));
}

/// A curve of the quick atlas: A = 3, B = 2.5, C = 3, point (1.5, 1.5) (u = 0.5 A,
/// v = 0.5 A), open circuit.
fn quick_curve() -> CouplerCurve {
    CouplerCurve::new(
        FourBar::new(3.0, 2.5, 3.0).unwrap(),
        Circuit::Open,
        CouplerPoint::new(1.5, 1.5),
    )
}

/// Points of `c` at `angles` (degrees), moved into a user frame by `p = a·M + b`.
fn user_points(c: &CouplerCurve, angles: &[f64], a: C64, b: C64) -> Vec<[f64; 2]> {
    angles
        .iter()
        .map(|&t| {
            let z = a * c.at(t).unwrap().m + b;
            [z.re, z.im]
        })
        .collect()
}

fn write_csv(path: &Path, pts: &[[f64; 2]]) {
    let mut s = String::from("x,y\n");
    for p in pts {
        s.push_str(&format!("{},{}\n", p[0], p[1]));
    }
    std::fs::write(path, s).unwrap();
}

/// `generate` writes the sidecar, lists it in the manifest, and it holds every curve of
/// the index in order; the index itself does not mention it.
#[test]
fn generate_writes_the_shape_sidecar() {
    let dir = tmp("sidecar");
    quick_atlas(&dir, false);
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    let entry = manifest["files"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["name"] == SHAPES_FILE)
        .expect("shapes.bin in the manifest");
    let bytes = std::fs::read(dir.join(SHAPES_FILE)).unwrap();
    assert_eq!(entry["bytes"].as_u64(), Some(bytes.len() as u64));
    let atlas = decode_sidecar(&bytes).unwrap();
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("index.json")).unwrap()).unwrap();
    let curves = index["curves"].as_array().unwrap();
    assert_eq!(atlas.curves.len(), curves.len());
    for (s, c) in atlas.curves.iter().zip(curves) {
        assert_eq!(s.id, c["id"].as_u64().unwrap());
        assert_eq!(
            s.curve.linkage.four_bar().unwrap().coupler,
            c["linkage"]["coupler"].as_f64().unwrap()
        );
        assert_eq!(s.curve.point.v, c["point"]["v"].as_f64().unwrap());
        assert_eq!(
            c["circuit"].as_str().unwrap(),
            match s.curve.circuit {
                Circuit::Open => "open",
                Circuit::Crossed => "crossed",
            }
        );
    }
    assert!(atlas.has_code.iter().all(|&h| h));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A closed target and an open window made from atlas curves under a similarity: the
/// source is the first match with an error at rounding level, its page and spot are
/// given, the placement is in the user's frame, and the overlay is a PNG of the size
/// promised. A reflected target is found only with --mirror, as the mirror four-bar.
#[test]
fn match_finds_the_source_and_places_it() {
    let dir = tmp("find");
    quick_atlas(&dir, true);
    let atlas = dir.to_str().unwrap();
    let src = quick_curve();
    let (a, b) = (C64::new(3.0, 4.0), C64::new(100.0, -20.0)); // scale 5, rotation 53.13°
    let closed: Vec<f64> = (0..60).map(|k| 7.0 + 6.0 * k as f64).collect();
    let open: Vec<f64> = (0..40).map(|k| 30.0 + 4.0 * k as f64).collect();
    for (name, angles, flag) in [("closed", &closed, "--closed"), ("open", &open, "--open")] {
        let file = dir.join(format!("{name}.csv"));
        write_csv(&file, &user_points(&src, angles, a, b));
        let png = dir.join(format!("{name}.png"));
        let out = run(&[
            "match",
            file.to_str().unwrap(),
            "--atlas",
            atlas,
            flag,
            "--top",
            "3",
            "--format",
            "json",
            "--png",
            png.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{name}: {}", text(&out.stderr));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let best = &v["matches"][0];
        let id = best["id"].as_u64().unwrap();
        assert_eq!(best["curve"]["linkage"]["coupler"], 3.0, "{name}: {best}");
        assert_eq!(best["curve"]["linkage"]["rocker"], 2.5, "{name}: {best}");
        assert_eq!(best["curve"]["point"]["u"], 1.5, "{name}: {best}");
        assert_eq!(best["curve"]["point"]["v"], 1.5, "{name}: {best}");
        assert_eq!(best["curve"]["circuit"], "open", "{name}: {best}");
        assert!(
            best["error"]["rms_pct"].as_f64().unwrap() < 1e-4,
            "{name}: {best}"
        );
        let p = &best["placement"];
        assert!((p["scale"].as_f64().unwrap() - 5.0).abs() < 1e-6, "{p}");
        assert!((p["o2"][0].as_f64().unwrap() - 100.0).abs() < 1e-5, "{p}");
        assert!((p["rotation_deg"].as_f64().unwrap() - 53.130102354).abs() < 1e-5);
        assert!((p["ground"].as_f64().unwrap() - 15.0).abs() < 1e-5);
        if name == "open" {
            let c = p["crank_deg"].as_array().unwrap();
            let (c0, c1) = (c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
            // The window's crank interval, 30° → 186° (crank angles in the user's frame
            // count from the ground line O2→O4, so a similarity leaves them as they are).
            let turn = |x: f64| (x - 30.0).rem_euclid(360.0);
            assert!(turn(c0) < 1e-3 || turn(c0) > 360.0 - 1e-3, "{c0}");
            assert!((c1 - c0 - 156.0).abs() < 1e-3, "{c0} {c1}");
        }
        let page = best["page"]["file"].as_str().unwrap();
        assert!(dir.join(page).exists(), "{page}");
        // Every hit's page reference is its index record's, whole (the lookup bisects
        // the index by id rather than reading it through).
        let index: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("index.json")).unwrap()).unwrap();
        for m in v["matches"].as_array().unwrap() {
            let c = &index["curves"][m["id"].as_u64().unwrap() as usize];
            assert_eq!(c["id"], m["id"]);
            assert!(c["page"].is_object(), "{c}");
            assert_eq!(m["page"], c["page"], "{name}: curve {}", m["id"]);
        }
        let img = image::open(&png).unwrap();
        assert_eq!((img.width(), img.height()), (1200, 1050));
        let _ = id;
    }
    // Reflected: without --mirror the source is not found exactly; with it, it is, as
    // the mirror four-bar (the other circuit, v negated).
    let file = dir.join("mirrored.csv");
    let pts: Vec<[f64; 2]> = user_points(&src, &closed, a, b)
        .into_iter()
        .map(|p| [p[0], -p[1]])
        .collect();
    write_csv(&file, &pts);
    let hits = |extra: &[&str]| -> Vec<serde_json::Value> {
        let mut args = vec!["match", file.to_str().unwrap(), "--atlas", atlas];
        args.extend_from_slice(&["--closed", "--format", "json"]);
        args.extend_from_slice(extra);
        let out = run(&args);
        assert!(out.status.success(), "{}", text(&out.stderr));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["matches"].as_array().unwrap().clone()
    };
    let plain = hits(&[])[0].clone();
    let with_mirror = hits(&["--mirror"]);
    // This atlas also holds the mirror four-bar's own curve (the crossed circuit, v
    // negated), fitted exactly without reflection: the two exact hits differ only by
    // rounding (RMS about 1e-15), so either may come first. Both are the same four-bar
    // in the user's frame, and the reflected source must be among the exact hits.
    let exact: Vec<&serde_json::Value> = with_mirror
        .iter()
        .filter(|m| m["error"]["rms_pct"].as_f64().unwrap() < 1e-4)
        .collect();
    assert!(
        exact.first().is_some_and(|m| m["rank"] == 1),
        "{with_mirror:?}"
    );
    for m in &exact {
        assert_eq!(m["placement"]["circuit"], "crossed", "{m}");
        let v = m["placement"]["point"][1].as_f64().unwrap();
        assert!((v + 7.5).abs() < 1e-6, "{m}");
    }
    let mirrored = exact
        .iter()
        .find(|m| m["placement"]["mirrored"] == true)
        .unwrap_or_else(|| panic!("the reflected source is not found: {with_mirror:?}"));
    assert_eq!(mirrored["curve"]["circuit"], "open", "{mirrored}");
    assert_eq!(mirrored["curve"]["point"]["v"], 1.5, "{mirrored}");
    assert!(
        plain["error"]["rms_pct"].as_f64().unwrap() > 1e-2
            || plain["placement"]["mirrored"] == false,
        "{plain}"
    );
    // The table prints negative numbers with a real minus sign (U+2212), as `search`
    // does: the mirror's coupler point in the user's frame has v = -7.5.
    let out = run(&[
        "match",
        file.to_str().unwrap(),
        "--atlas",
        atlas,
        "--closed",
        "--mirror",
        "--top",
        "1",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    assert!(table.contains("(u, v) = (7.5, \u{2212}7.5)"), "{table}");
    assert!(table.contains("rotation \u{2212}53.1301°"), "{table}");
    for hyphen in [
        "(-", " -0", " -1", " -2", " -3", " -4", " -5", " -6", " -7", " -8", " -9",
    ] {
        assert!(
            !table.contains(hyphen),
            "hyphen for minus `{hyphen}`: {table}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Bad atlases and targets: exit code 2, a message naming the file and the problem.
#[test]
fn match_refuses_bad_input_clearly() {
    let dir = tmp("bad");
    quick_atlas(&dir, false);
    let atlas = dir.to_str().unwrap();
    let target = dir.join("t.csv");
    std::fs::write(&target, "0,0\n1,0\n2,1\n3,3\n4,6\n").unwrap();
    let t = target.to_str().unwrap();
    let fails = |args: &[&str], needle: &str| {
        let out = run(args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            text(&out.stderr)
        );
        let err = text(&out.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
    };
    // Not an atlas folder.
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    fails(
        &["match", t, "--atlas", empty.to_str().unwrap()],
        "is not an atlas folder",
    );
    // A target file that is not points.
    let junk = dir.join("junk.csv");
    std::fs::write(&junk, "0,0\n1,one\n").unwrap();
    fails(
        &["match", junk.to_str().unwrap(), "--atlas", atlas],
        "junk.csv: line 2: y: `one` is not a number",
    );
    // Too few points for a closed target.
    fails(
        &["match", t, "--atlas", atlas, "--closed"],
        "at least 6 points",
    );
    // Angles spanning more than a crank turn, on a four-bar atlas.
    let long = dir.join("long.csv");
    let pts: String = (0..40)
        .map(|k| {
            let (a, r) = (f64::from(k) * 10.0, 1.0 + f64::from(k) * 0.01);
            let (x, y) = (r * a.to_radians().cos(), r * a.to_radians().sin());
            format!("{x},{y},{a}\n")
        })
        .collect();
    std::fs::write(&long, pts).unwrap();
    fails(
        &[
            "match",
            long.to_str().unwrap(),
            "--atlas",
            atlas,
            "--closed",
            "--timed",
        ],
        "angles span 390°, but the longest period of the curves is 360° of input",
    );
    // A sidecar replaced by a link to the same bytes: refused, and the message says so
    // (not that the bytes changed).
    let side = dir.join(SHAPES_FILE);
    let moved = dir.join("shapes-elsewhere.bin");
    std::fs::rename(&side, &moved).unwrap();
    std::os::unix::fs::symlink(&moved, &side).unwrap();
    fails(
        &["match", t, "--atlas", atlas],
        "shapes.bin is a link or not a regular file",
    );
    std::fs::remove_file(&side).unwrap();
    std::fs::rename(&moved, &side).unwrap();
    // A sidecar changed after it was written.
    let mut bytes = std::fs::read(&side).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&side, &bytes).unwrap();
    fails(
        &["match", t, "--atlas", atlas],
        "does not match the manifest",
    );
    // An atlas without a sidecar (an older version's).
    std::fs::remove_file(&side).unwrap();
    let m = dir.join("manifest.json");
    let s = std::fs::read_to_string(&m).unwrap();
    let kept: Vec<&str> = s.lines().filter(|l| !l.contains(SHAPES_FILE)).collect();
    std::fs::write(&m, kept.join("\n").replace(",\n]}", "\n]}")).unwrap();
    fails(&["match", t, "--atlas", atlas], "has no shape codes");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `match` reads the sidecar mapped and in place, its content key remembered in a stamp
/// beside it (`shapes.bin.stamp`) once the file has settled, as the search columns'
/// index key is: the same hits with and without the stamp, and a sidecar changed after
/// the stamp was written (same size, one code byte) is still refused.
#[test]
fn sidecar_stamp_keeps_the_check() {
    let dir = tmp("stamp");
    quick_atlas(&dir, false);
    let atlas = dir.to_str().unwrap();
    let src = quick_curve();
    let angles: Vec<f64> = (0..36).map(|k| 5.0 + 10.0 * k as f64).collect();
    let target = dir.join("t.csv");
    write_csv(
        &target,
        &user_points(&src, &angles, C64::new(0.0, 2.0), C64::new(5.0, 5.0)),
    );
    let t = target.to_str().unwrap();
    let hits = || {
        let out = run(&["match", t, "--atlas", atlas, "--closed", "--top", "4"]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        text(&out.stdout)
    };
    let side = dir.join(SHAPES_FILE);
    let stamp = dir.join(format!("{SHAPES_FILE}.stamp"));
    // A stamp is written only for a file unchanged for 2 s (`coupler_index::SETTLED`).
    let age = std::fs::metadata(&side).unwrap().modified().unwrap();
    let wait = coupler_atlas::SETTLED + std::time::Duration::from_millis(200);
    if let Some(left) = wait.checked_sub(age.elapsed().unwrap_or_default()) {
        std::thread::sleep(left);
    }
    let hashed = hits();
    assert!(
        stamp.is_file(),
        "the stamp is written once the file is accepted"
    );
    let stamp_bytes = std::fs::read(&stamp).unwrap();
    assert_eq!(hits(), hashed, "the same hits with the key from the stamp");
    assert_eq!(
        std::fs::read(&stamp).unwrap(),
        stamp_bytes,
        "the stamp is reused"
    );
    // One byte of the first record's code changed in place, size unchanged.
    let mut bytes = std::fs::read(&side).unwrap();
    let at = coupler_atlas::shape::HEADER_BYTES + 50;
    bytes[at] ^= 0x10;
    std::fs::write(&side, &bytes).unwrap();
    let out = run(&["match", t, "--atlas", atlas, "--closed"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("does not match the manifest"),
        "{}",
        text(&out.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The number after `before` in `text` (up to the next space), or a failure naming it.
fn number_after(text: &str, before: &str) -> usize {
    let at = text
        .find(before)
        .unwrap_or_else(|| panic!("no `{before}` in: {text}"));
    let rest = &text[at + before.len()..];
    rest[..rest.find(' ').unwrap_or(rest.len())]
        .parse()
        .unwrap_or_else(|_| panic!("no number after `{before}` in: {text}"))
}

/// The closing `searched …` line says what was searched: every curve of the atlas, or,
/// when the lattice search or the screen of `--linkages` picked the linkages, the curves
/// of the linkages scanned, of how many. An open target on an atlas of 3,952 linkages
/// (more than the lattice search's 2,000), two coupler points each: the line counts the
/// curves of the linkages the note says were scanned (twice as many), not the atlas's;
/// with `--full-scan` every curve; on the quick atlas with `--linkages 2`, the screen's
/// linkages' curves.
#[test]
fn match_says_which_curves_it_searched() {
    let dir = tmp("searched");
    std::fs::create_dir_all(&dir).unwrap();
    let spec = dir.join("lattice.toml");
    std::fs::write(
        &spec,
        r#"[atlas]
name = "lattice"
title = "More linkages than the lattice search's threshold"

[linkages]
coupler = { start = 1.5, end = 6.0, step = 0.25 }
rocker  = { start = 1.5, end = 6.0, step = 0.25 }
ground  = { start = 1.5, end = 6.0, step = 0.25 }
circuits = ["open"]

[points]
u = { start = 0.5, end = 0.5, step = 0.5, relative = true }
v = { start = -0.5, end = 0.5, step = 1.0, relative = true }

[sampling]
crank_step_deg = 2.0
dash_deg = 10.0
"#,
    )
    .unwrap();
    let atlas = dir.join("atlas");
    let out = run(&[
        "generate",
        spec.to_str().unwrap(),
        "--out",
        atlas.to_str().unwrap(),
        "--no-pages",
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let (linkages, curves) = (3952, 7904);
    let file = dir.join("open.csv");
    let angles: Vec<f64> = (0..40).map(|k| 30.0 + 4.0 * k as f64).collect();
    let pts = user_points(
        &quick_curve(),
        &angles,
        C64::new(3.0, 4.0),
        C64::new(100.0, -20.0),
    );
    write_csv(&file, &pts);
    let (t, a) = (file.to_str().unwrap(), atlas.to_str().unwrap());
    let out = run(&["match", t, "--atlas", a, "--open", "--top", "1"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let err = text(&out.stderr);
    let scanned = number_after(&err, "note: lattice search: ");
    assert!(
        err.contains(&format!(
            "note: lattice search: {scanned} of the atlas's {linkages} linkages scanned"
        )),
        "{err}"
    );
    assert!(scanned < linkages, "{err}");
    let searched = number_after(&err, "\nsearched ");
    assert_eq!(searched, 2 * scanned, "{err}");
    assert!(
        err.contains(&format!(
            "\nsearched {searched} of the atlas's {curves} curves (lattice search: {scanned} of its {linkages} linkages) in "
        )),
        "{err}"
    );
    let out = run(&[
        "match",
        t,
        "--atlas",
        a,
        "--open",
        "--top",
        "1",
        "--full-scan",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let err = text(&out.stderr);
    assert!(!err.contains("note:"), "{err}");
    assert!(
        err.starts_with(&format!("searched {curves} curves in ")),
        "{err}"
    );
    // The screen of `--linkages` on the quick atlas (12 linkages of 6 curves).
    let quick = dir.join("quick");
    quick_atlas(&quick, false);
    let q = quick.to_str().unwrap();
    let out = run(&["match", t, "--atlas", q, "--open", "--linkages", "2"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let err = text(&out.stderr);
    assert!(
        err.contains(
            "\nsearched 12 of the atlas's 72 curves (coarse screen: 2 of its 12 linkages) in "
        ),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
