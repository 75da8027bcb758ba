//! Batch behaviour through the real binary: a page that fails is recorded and the run
//! goes on, then exits non-zero naming every failed page (and a chunk with a failed page
//! is not recorded as complete, so the same command redoes it); a closed stdout pipe ends
//! every printing command quietly with status 0.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_coupler-atlas");

fn tmp(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("coupler-atlas-batch-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn spec(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("atlas-spec")
        .join(name)
        .display()
        .to_string()
}

fn generate(spec: &str, out: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(BIN)
        .args(["generate", spec, "--out"])
        .arg(out)
        .args(["--quiet", "--yes"])
        .args(extra)
        .output()
        .unwrap()
}

fn pages_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir.join("pages"))
        .map(|d| {
            d.filter_map(|e| e.ok())
                .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| !n.starts_with('.'))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// Two pages of the quick atlas cannot be written (a folder stands where each file
/// goes): the run writes every other page, then exits 1 naming both; no index is
/// claimed. Once the obstacles are gone, the same command redoes only what is missing
/// and the atlas is byte-identical to a clean run.
#[test]
fn failed_pages_are_reported_and_the_run_goes_on() {
    let out = tmp("fail");
    let blocked = ["quick-0003.png", "quick-0010.png"];
    for b in blocked {
        std::fs::create_dir_all(out.join("pages").join(b)).unwrap();
    }
    // The folder holds the obstacles only (pages/): new to this program, so --force.
    let o = generate(&spec("quick.toml"), &out, &["--force", "--jobs", "2"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    for b in blocked {
        assert!(err.contains(&format!("pages/{b}")), "{b} not named: {err}");
    }
    assert!(err.contains("2 pages failed"), "{err}");
    // Every other page was written.
    let written = pages_in(&out);
    let contents = written.iter().filter(|n| n.contains("-contents-")).count();
    assert!(contents >= 1, "the contents is written: {written:?}");
    assert_eq!(
        written.len() - contents,
        12 - 2,
        "10 atlas pages and the contents: {written:?}"
    );
    for b in blocked {
        assert!(!written.contains(&b.to_string()));
    }
    assert!(
        !out.join("index.json").exists(),
        "an incomplete atlas has no index"
    );
    assert!(!out.join("manifest.json").exists());

    // Remove the obstacles: the same command completes the atlas, redoing only the
    // chunks that were not complete.
    for b in blocked {
        std::fs::remove_dir(out.join("pages").join(b)).unwrap();
    }
    let o = generate(&spec("quick.toml"), &out, &["--force", "--jobs", "2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let clean = tmp("clean");
    let o = generate(&spec("quick.toml"), &clean, &["--jobs", "1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["index.json", "manifest.json"] {
        assert!(
            std::fs::read(out.join(f)).unwrap() == std::fs::read(clean.join(f)).unwrap(),
            "{f} differs from a clean run"
        );
    }
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_dir_all(&clean);
}

/// The same for a full-curve page set: the failed page is named, the others written,
/// and no `curves.json` claims a complete set.
#[test]
fn failed_page_of_a_page_set_is_reported() {
    let out = tmp("set");
    std::fs::create_dir_all(out.join("pages/classics-0002.png")).unwrap();
    let o = generate(&spec("classics.toml"), &out, &["--force", "--dpi", "36"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("pages/classics-0002.png"), "{err}");
    // Every curve of the set but the blocked one has its page.
    let curves = std::fs::read_to_string(spec("classics.toml"))
        .unwrap()
        .lines()
        .filter(|l| l.trim() == "[[curve]]")
        .count();
    assert_eq!(pages_in(&out).len(), curves - 1, "{:?}", pages_in(&out));
    assert!(!out.join("curves.json").exists());
    let _ = std::fs::remove_dir_all(&out);
}

/// Runs `args` with stdout a pipe that is closed before (or while) the program writes:
/// it must end quietly with status 0, as `grep` does.
fn closed_pipe(args: &[&str]) {
    let mut child = Command::new(BIN)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Read one byte (the program has started writing), then close our end.
    let mut stdout = child.stdout.take().unwrap();
    let mut byte = [0u8; 1];
    let _ = stdout.read(&mut byte);
    drop(stdout);
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{args:?}: {err}");
    // Quietly: no error, no panic (a command's usual summary on stderr may remain).
    assert!(
        !err.contains("error") && !err.contains("panicked") && !err.contains("Broken pipe"),
        "{args:?}: {err}"
    );
}

#[test]
fn closed_pipe_ends_quietly() {
    // Large outputs (far beyond a pipe's buffer), so the write after the close fails.
    let four_bar = [
        "--coupler",
        "2.5",
        "--rocker",
        "3",
        "--ground",
        "3.5",
        "--point",
        "1.25,-0.5",
    ];
    for format in ["json", "csv", "table"] {
        let mut a = vec!["curve"];
        a.extend(four_bar);
        a.extend(["--step", "0.002", "--format", format]);
        closed_pipe(&a);
    }
    let mut a = vec!["curve"];
    a.extend([
        "--coupler",
        "1",
        "--rocker",
        "1",
        "--ground",
        "2.23606797749979",
        "--point",
        "0.5,0",
        "--trace",
        "full",
        "--step",
        "0.002",
    ]);
    closed_pipe(&a);
    let mut a = vec!["curve"];
    a.extend(four_bar);
    a.extend(["--step", "0.002", "--window", "170:190"]);
    closed_pipe(&a);
    // Small outputs: the pipe may still be open when they are written; either way, 0.
    let mut a = vec!["cognates"];
    a.extend(four_bar);
    closed_pipe(&a);
    closed_pipe(&["generate", "--dry-run"]);
    let dir = tmp("pipe");
    let o = generate(&spec("quick.toml"), &dir, &["--no-pages"]);
    assert!(o.status.success());
    let index = dir.join("index.json");
    closed_pipe(&["search", index.to_str().unwrap(), "--limit", "0"]);
    closed_pipe(&[
        "search",
        index.to_str().unwrap(),
        "--limit",
        "0",
        "--format",
        "json",
    ]);
    closed_pipe(&[
        "dwell",
        "--coupler",
        "2.5",
        "--rocker",
        "3.5",
        "--ground",
        "3.5",
        "--point",
        "3.125,1.25",
        "--window",
        "295:435",
        "--swing",
        "9",
        "--method",
        "optimise",
        "--format",
        "json",
    ]);
    let _ = std::fs::remove_dir_all(&dir);
}
