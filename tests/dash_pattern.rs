//! One dash pattern for pages and index alike: `[sampling] dash_deg` sets the dashes drawn
//! on the pages and the `dashes` counted in the index's features; `[features] dash_deg`
//! (a second setting of the same thing, which let the two disagree) is refused with a
//! message that says where the setting lives.

use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
}

fn tmp(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("coupler-atlas-dash-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `atlas-spec/quick.toml` with its `dash_deg = 10.0` line replaced by `dash`, plus `extra`.
fn quick_spec(dir: &Path, dash: &str, extra: &str) -> PathBuf {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("atlas-spec/quick.toml"),
    )
    .unwrap();
    assert!(text.contains("dash_deg = 10.0\n"));
    let text = text.replace("dash_deg = 10.0\n", &format!("{dash}\n")) + extra;
    let path = dir.join("spec.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn index_counts_dashes_at_the_sampling_dash_angle() {
    let dir = tmp("five");
    let spec = quick_spec(&dir, "dash_deg = 5.0", "");
    let out = dir.join("atlas");
    let o = bin()
        .args(["generate", spec.to_str().unwrap(), "--out"])
        .arg(&out)
        .args(["--no-pages", "--quiet"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("index.json")).unwrap()).unwrap();
    assert_eq!(index["spec"]["sampling"]["dash_deg"], 5.0);
    let mut checked = 0;
    for c in index["curves"].as_array().unwrap() {
        let f = &c["features"];
        for key in ["straight_segments", "pseudo_arcs"] {
            for s in f[key].as_array().unwrap() {
                let span = s["span_deg"].as_f64().unwrap();
                let want = (span / 5.0 + 1e-9).floor() as u64;
                assert_eq!(
                    s["dashes"].as_u64().unwrap(),
                    want,
                    "curve {} {key} spanning {span}°: dashes must count 5° dashes, as the pages draw them",
                    c["id"]
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 10, "only {checked} features checked");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn features_dash_deg_is_refused_with_where_the_setting_lives() {
    let dir = tmp("dup");
    let spec = quick_spec(&dir, "dash_deg = 10.0", "\n[features]\ndash_deg = 5.0\n");
    let o = bin()
        .args(["generate", spec.to_str().unwrap(), "--dry-run"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    // Located: file, line and column of the key, and the key's name.
    let line = std::fs::read_to_string(&spec)
        .unwrap()
        .lines()
        .position(|l| l.starts_with("dash_deg = 5.0"))
        .unwrap()
        + 1;
    assert!(
        err.contains(&format!("spec.toml:{line}:1: key `features.dash_deg`")),
        "{err}"
    );
    assert!(err.contains("[sampling] dash_deg"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
