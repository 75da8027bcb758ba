//! Nothing lost, nothing half-written: runs killed mid-way resume to the same bytes,
//! shards merge into exactly one run's output, foreign folders are refused.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("coupler-atlas-rel-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Every file below `dir` (relative path → bytes).
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(base: &Path, dir: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            // The lock records who holds it (process id, time): not output.
            if p.ends_with(".coupler-atlas/lock") {
                continue;
            }
            if p.is_dir() {
                walk(base, &p, out);
            } else {
                out.insert(
                    p.strip_prefix(base).unwrap().display().to_string(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

fn assert_same_tree(a: &Path, b: &Path) {
    let (ta, tb) = (tree(a), tree(b));
    assert_eq!(
        ta.keys().collect::<Vec<_>>(),
        tb.keys().collect::<Vec<_>>(),
        "file sets differ"
    );
    for (k, v) in &ta {
        assert!(v == &tb[k], "{k} differs");
    }
}

fn generate(spec: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    bin()
        .arg("generate")
        .arg(spec)
        .arg("--out")
        .arg(out)
        .args(["--quiet"])
        .args(extra)
        .output()
        .unwrap()
}

fn chunk_count(out: &Path) -> usize {
    std::fs::read_dir(out.join(".coupler-atlas/chunks"))
        .map(|d| {
            d.flatten()
                .filter(|e| e.file_name().to_string_lossy().ends_with(".jsonl"))
                .count()
        })
        .unwrap_or(0)
}

/// Starts a run and waits until `min_chunks` chunk records exist, then returns the child.
fn start_and_wait(spec: &Path, out: &Path, min_chunks: usize) -> std::process::Child {
    let child = bin()
        .arg("generate")
        .arg(spec)
        .arg("--out")
        .arg(out)
        .args(["--quiet", "--no-pages", "--jobs", "2"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while chunk_count(out) < min_chunks {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "run made no progress"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    child
}

#[test]
fn sigkill_mid_run_then_rerun_gives_the_same_bytes() {
    let spec = root().join("tests/fixtures/kill.toml");
    let (killed, clean) = (tmp("killed"), tmp("clean"));
    let mut child = start_and_wait(&spec, &killed, 2);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert!(
        !killed.join("index.json").exists(),
        "the run finished before it was killed: the test proved nothing"
    );
    // Nothing stands half-written under a final name: every chunk record present is complete.
    for e in std::fs::read_dir(killed.join(".coupler-atlas/chunks"))
        .unwrap()
        .flatten()
    {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.ends_with(".jsonl") {
            let text = std::fs::read_to_string(e.path()).unwrap();
            let header: serde_json::Value =
                serde_json::from_str(text.lines().next().unwrap()).unwrap();
            assert_eq!(
                text.lines().count() - 1,
                header["curves"].as_u64().unwrap() as usize,
                "{name} is incomplete"
            );
        }
    }
    let resumed = generate(&spec, &killed, &["--no-pages"]);
    assert!(
        resumed.status.success(),
        "{}",
        String::from_utf8_lossy(&resumed.stderr)
    );
    assert!(String::from_utf8_lossy(&resumed.stderr).contains("reused from an earlier run"));
    let full = generate(&spec, &clean, &["--no-pages"]);
    assert!(full.status.success());
    assert_same_tree(&killed, &clean);
    let _ = std::fs::remove_dir_all(&killed);
    let _ = std::fs::remove_dir_all(&clean);
}

#[test]
fn sigint_stops_cleanly_and_says_how_to_resume() {
    let spec = root().join("tests/fixtures/kill.toml");
    let (stopped, clean) = (tmp("sigint"), tmp("sigint-clean"));
    let child = start_and_wait(&spec, &stopped, 1);
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains("run the same command again to resume"),
        "{stderr}"
    );
    assert!(!stopped.join("index.json").exists());
    let resumed = generate(&spec, &stopped, &["--no-pages"]);
    assert!(resumed.status.success());
    assert!(generate(&spec, &clean, &["--no-pages"]).status.success());
    assert_same_tree(&stopped, &clean);
    let _ = std::fs::remove_dir_all(&stopped);
    let _ = std::fs::remove_dir_all(&clean);
}

#[test]
fn shards_merge_into_exactly_one_runs_output() {
    let spec = root().join("atlas-spec/hrones-nelson.toml");
    let (single, merged) = (tmp("single"), tmp("merged"));
    let shards: Vec<PathBuf> = (1..=3).map(|k| tmp(&format!("shard{k}"))).collect();
    assert!(generate(&spec, &single, &["--no-pages"]).status.success());
    for (k, dir) in shards.iter().enumerate() {
        let out = generate(
            &spec,
            dir,
            &["--no-pages", "--shard", &format!("{}/3", k + 1)],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(!dir.join("index.json").exists(), "a shard writes no index");
    }
    // Missing a shard: refused, naming the problem.
    let partial = bin()
        .args(["merge", "--spec"])
        .arg(&spec)
        .arg("--out")
        .arg(&merged)
        .args(["--no-pages"])
        .args(&shards[..2])
        .output()
        .unwrap();
    assert_eq!(partial.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&partial.stderr).contains("is in none of the shard folders"));
    let _ = std::fs::remove_dir_all(&merged);
    let out = bin()
        .args(["merge", "--spec"])
        .arg(&spec)
        .arg("--out")
        .arg(&merged)
        .args(["--no-pages"])
        .args(shards.iter().rev())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_same_tree(&merged, &single);
    for d in shards.iter().chain([&single, &merged]) {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn foreign_folders_are_refused_unless_forced_and_nothing_of_theirs_is_deleted() {
    let dir = tmp("foreign");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("thesis.tex"), b"mine").unwrap();
    let spec = root().join("atlas-spec/quick.toml");
    let refused = generate(&spec, &dir, &["--no-pages"]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("thesis.tex"));
    assert!(!dir.join("index.json").exists());
    let forced = generate(&spec, &dir, &["--no-pages", "--force"]);
    assert!(forced.status.success());
    assert_eq!(std::fs::read(dir.join("thesis.tex")).unwrap(), b"mine");
    assert!(dir.join("index.json").exists());
    // Our own folder is recognised on the next run without --force.
    assert!(generate(&spec, &dir, &["--no-pages"]).status.success());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A `merge` stopped mid-way, by SIGKILL (nothing can clean up then) or by SIGINT, is
/// finished by the same command: the folder is then exactly one run's output, with no
/// temporary file left (the file sets are compared). After SIGINT the merge says so and
/// leaves no temporary file even before the rerun. `many-chunks.toml` has 63 cheap
/// chunks, so the merge is stopped with most of its records still to copy.
#[test]
fn a_merge_stopped_mid_way_finishes_on_rerun() {
    let spec = root().join("tests/fixtures/many-chunks.toml");
    let base = tmp("merge-stop");
    let single = base.join("single");
    assert!(generate(&spec, &single, &["--no-pages"]).status.success());
    let shards: Vec<PathBuf> = (1..=2)
        .map(|k| {
            let dir = base.join(format!("s{k}"));
            let o = generate(&spec, &dir, &["--no-pages", "--shard", &format!("{k}/2")]);
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            dir
        })
        .collect();
    let merge = |out: &Path| {
        let mut c = bin();
        c.arg("merge").arg("--out").arg(out).args(&shards);
        c
    };
    for signal in ["KILL", "INT"] {
        let out = base.join(signal);
        let child = merge(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let start = Instant::now();
        while chunk_count(&out) < 1 {
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "merge made no progress"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        let status = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        let o = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(
            !out.join("index.json").exists() && chunk_count(&out) < 63,
            "{signal}: the merge finished before it was stopped: the test proved nothing"
        );
        if signal == "INT" {
            assert_eq!(o.status.code(), Some(130), "{stderr}");
            assert!(stderr.contains("no temporary file is left"), "{stderr}");
            let temporaries: Vec<String> = tree(&out)
                .into_keys()
                .filter(|k| k.contains(".tmp-"))
                .collect();
            assert!(temporaries.is_empty(), "left behind: {temporaries:?}");
        } else {
            assert_eq!(o.status.code(), None, "{stderr}");
        }
        let o = merge(&out).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_same_tree(&out, &single);
    }
    let _ = std::fs::remove_dir_all(&base);
}
