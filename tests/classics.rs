//! The classics page set as a user makes it: `generate atlas-spec/classics.toml` draws
//! one page per classic straight-line linkage, traced in full across its toggles, and
//! writes `curves.json` with the measured straightness and where each curve is drawn.

use coupler_atlas::{ClassicCurve, CurveList};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "coupler-atlas-classics-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("runs")
}

fn generate(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "generate",
        "atlas-spec/classics.toml",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--dpi",
        "60",
    ];
    args.extend_from_slice(extra);
    run(&args)
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v = Vec::new();
    for sub in ["", "pages"] {
        for e in std::fs::read_dir(dir.join(sub)).unwrap() {
            let e = e.unwrap();
            if e.file_type().unwrap().is_file() {
                let name = format!("{sub}/{}", e.file_name().to_string_lossy());
                v.push((name, std::fs::read(e.path()).unwrap()));
            }
        }
    }
    v.sort();
    v
}

/// One page per classic; `curves.json` carries for each the measures the library
/// computes (not figures copied here), closed branches, and a page reference whose box
/// lies on the page; the manifest lists every file with its hash; any thread count gives
/// the same bytes.
#[test]
fn classics_pages_and_measures() {
    let out = tmp("set");
    let o = generate(&out, &["--jobs", "2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let list = CurveList::parse(
        &std::fs::read_to_string(root().join("atlas-spec/classics.toml")).unwrap(),
        "classics.toml",
    )
    .unwrap();
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("curves.json")).unwrap()).unwrap();
    assert_eq!(doc["schema_version"], 1);
    let curves = doc["curves"].as_array().unwrap();
    assert_eq!(curves.len(), list.curves.len());
    for (rec, c) in curves.iter().zip(&list.curves) {
        assert_eq!(rec["name"], c.name.as_str());
        let m = ClassicCurve::compute(c, list.sampling.crank_step_deg);
        assert!(rec["closure"].as_f64().unwrap() <= 1e-12, "{}", c.name);
        for (got, want) in rec["straight"].as_array().unwrap().iter().zip(&m.straight) {
            let want = want.expect("every classic has a straight run");
            assert_eq!(got["input_span_deg"].as_f64(), Some(want.input_span_deg));
            assert_eq!(got["straightness"].as_f64(), Some(want.straightness));
            assert!(want.straightness <= want.tolerance);
        }
        let page = rec["page"]["file"].as_str().unwrap();
        let png = std::fs::read(out.join(page)).expect("page file");
        let decoder = png::Decoder::new(std::io::Cursor::new(png));
        let info = decoder.read_info().unwrap().info().clone();
        let b: Vec<f64> = rec["page"]["bbox_px"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert!(
            b[0] < b[2] && b[1] < b[3] && b[2] <= info.width as f64 && b[3] <= info.height as f64
        );
    }
    // Watt's curve is one branch, out on the open circuit and back on the crossed;
    // Chebyshev's two; Hoeken and Evans (cranks) are drawn on their open circuits only.
    let branches: Vec<u64> = curves
        .iter()
        .map(|c| c["branches"].as_u64().unwrap())
        .collect();
    assert_eq!(branches, [1, 2, 1, 1, 1, 1]);
    assert_eq!(curves[2]["input"]["kind"], "rocks");
    // Evans from its design condition (frame 3, a = 4) is a crank-rocker whose line is
    // straight to 0.1 % over more than 100° of crank (Hoeken's proportions give 38.5°).
    assert_eq!(curves[5]["name"], "Evans");
    assert_eq!(curves[5]["input"]["kind"], "full");
    assert!(curves[5]["straight"][1]["input_span_deg"].as_f64().unwrap() > 100.0);

    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    let listed: Vec<&str> = manifest["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    assert_eq!(listed.len(), list.curves.len() + 1);
    assert!(listed.contains(&"curves.json") && listed.contains(&"pages/classics-0003.png"));

    search_page_set(&out, &list);

    let again = tmp("set-j1");
    let o = generate(&again, &["--jobs", "1"]);
    assert!(o.status.success());
    assert_eq!(
        files(&out),
        files(&again),
        "bytes differ between --jobs 2 and 1"
    );
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_dir_all(&again);
}

/// `search` reads the page set (its folder or its `curves.json`): a curve matches
/// `--straight SPAN:TOL` when its longest straight run within TOL spans SPAN, at the three
/// stored tolerances and at any other (re-measured); the manifest is refused with a hint
/// naming `curves.json`.
fn search_page_set(out: &Path, list: &CurveList) {
    let search = |target: &Path, filter: &str| -> serde_json::Value {
        let o = run(&[
            "search",
            target.to_str().unwrap(),
            "--straight",
            filter,
            "--limit",
            "0",
            "--format",
            "json",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let step = list.sampling.crank_step_deg;
    let measured: Vec<ClassicCurve> = list
        .curves
        .iter()
        .map(|c| ClassicCurve::compute(c, step))
        .collect();
    for (span, tol) in [(200.0, 1.0), (100.0, 0.1), (150.0, 0.5), (60.0, 0.02)] {
        let filter = format!("{span}:{tol}");
        for target in [out.to_path_buf(), out.join("curves.json")] {
            let v = search(&target, &filter);
            let ids: Vec<u64> = v["hits"]
                .as_array()
                .unwrap()
                .iter()
                .map(|h| h["id"].as_u64().unwrap())
                .collect();
            let want: Vec<u64> = (0..measured.len() as u64)
                .filter(|&k| {
                    measured[k as usize]
                        .straight_at(tol / 100.0)
                        .is_some_and(|r| r.input_span_deg >= span)
                })
                .collect();
            assert_eq!(ids, want, "--straight {filter} on {}", target.display());
            assert_eq!(v["total"].as_u64(), Some(want.len() as u64));
        }
    }
    // Hoeken (id 0) at 1 %: its longest run, found by the exact search.
    let v = search(out, "200:1");
    assert_eq!(v["hits"][0]["id"], 0);
    let o = run(&["search", out.join("manifest.json").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("curves.json"), "{err}");
}

/// `--shard` does not apply to a page set: refused, nothing written; `--dry-run` lists
/// the curves and pages and writes nothing.
#[test]
fn page_set_refuses_shards_and_dry_run_writes_nothing() {
    let out = tmp("refuse");
    let o = generate(&out, &["--shard", "1/2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not sharded"));
    assert!(!out.exists());
    let o = generate(&out, &["--dry-run"]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("curve 5: Evans grasshopper")
            && text.contains("curve 6: Evans")
            && text.contains("pages:    6"),
        "{text}"
    );
    assert!(!out.exists());
}
