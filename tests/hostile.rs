//! Issue 17's adversarial cases, each through the command line: a damaged chunk record
//! (edited value, cut line) is recomputed rather than served, also through `merge`; a
//! record naming a file outside the folder is refused; planted symbolic links are never
//! followed; a second run into a locked folder refuses, naming the first; a huge spec
//! answers `--dry-run` at once; `--force` never overwrites the user's files; a settings
//! change replaces the old atlas as a whole, even when interrupted. Every test here
//! fails on the code before issue 17 (see docs/scale.md, "Verified, locked, bounded").

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn ok_spec() -> PathBuf {
    root().join("tests/bad-input/ok.toml")
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "coupler-atlas-hostile-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn generate(spec: &Path, out: &Path, extra: &[&str]) -> Output {
    bin()
        .arg("generate")
        .arg(spec)
        .arg("--out")
        .arg(out)
        .arg("--quiet")
        .args(extra)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn assert_ok(o: &Output) {
    assert!(o.status.success(), "{}", stderr(o));
}

fn chunk0(dir: &Path) -> PathBuf {
    dir.join(".coupler-atlas/chunks/000000.jsonl")
}

/// XXH3-128 of a file, as the manifest writes it.
fn xxh3(path: &Path) -> String {
    format!(
        "{:032x}",
        xxhash_rust::xxh3::xxh3_128(&std::fs::read(path).unwrap())
    )
}

/// If `dir` has a manifest, every file it lists has its recorded size and hash (what a
/// reader of the folder relies on at any moment).
fn manifest_consistent(dir: &Path) -> Result<(), String> {
    let Ok(text) = std::fs::read_to_string(dir.join("manifest.json")) else {
        return Ok(());
    };
    let m: serde_json::Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    for f in m["files"].as_array().unwrap() {
        let name = f["name"].as_str().unwrap();
        let path = dir.join(name);
        let bytes = std::fs::metadata(&path).map(|m| m.len()).ok();
        if bytes != f["bytes"].as_u64() || xxh3(&path) != f["xxh3"].as_str().unwrap() {
            return Err(format!("{name} is not the file the manifest lists"));
        }
    }
    Ok(())
}

/// A chunk record whose curve lines are damaged (a value edited, or the record cut
/// mid-line) is recomputed: the index is exactly the clean run's.
#[test]
fn damaged_chunk_lines_are_recomputed_not_served() {
    let clean = tmp("chunk-clean");
    assert_ok(&generate(&ok_spec(), &clean, &["--no-pages"]));
    let want = std::fs::read(clean.join("index.json")).unwrap();
    let record = std::fs::read_to_string(chunk0(&clean)).unwrap();
    let edited = record.replacen("\"ground\":3.0}", "\"ground\":3.5}", 1);
    assert_ne!(edited, record);
    let cut = &record[..record.len() - 40];
    for (what, damaged) in [("edited", edited.as_str()), ("cut", cut)] {
        let dir = tmp(&format!("chunk-{what}"));
        assert_ok(&generate(&ok_spec(), &dir, &["--no-pages"]));
        // As a run killed before it assembled the index would leave it.
        std::fs::remove_file(dir.join("index.json")).unwrap();
        std::fs::remove_file(dir.join("manifest.json")).unwrap();
        std::fs::write(chunk0(&dir), damaged).unwrap();
        let o = generate(&ok_spec(), &dir, &["--no-pages"]);
        assert_ok(&o);
        assert!(
            std::fs::read(dir.join("index.json")).unwrap() == want,
            "{what}: the damaged record was served"
        );
        assert_eq!(std::fs::read_to_string(chunk0(&dir)).unwrap(), record);
        let _ = std::fs::remove_dir_all(&dir);
    }
    let _ = std::fs::remove_dir_all(&clean);
}

/// Two shard folders of `ok.toml` (its one chunk is in shard 1/2) below `base`.
fn shards(base: &Path, extra: &[&str]) -> [PathBuf; 2] {
    let s = [base.join("s1"), base.join("s2")];
    for (k, d) in s.iter().enumerate() {
        let shard = format!("{}/2", k + 1);
        let mut args = vec!["--shard", shard.as_str()];
        args.extend_from_slice(extra);
        assert_ok(&generate(&ok_spec(), d, &args));
    }
    s
}

fn merge(out: &Path, shards: &[PathBuf], extra: &[&str]) -> Output {
    bin()
        .arg("merge")
        .arg("--spec")
        .arg(ok_spec())
        .arg("--out")
        .arg(out)
        .args(extra)
        .args(shards)
        .output()
        .unwrap()
}

/// `merge` never serves a shard's damaged curve lines.
#[test]
fn merge_refuses_damaged_chunk_lines() {
    let base = tmp("merge-damaged");
    let single = base.join("single");
    assert_ok(&generate(&ok_spec(), &single, &["--no-pages"]));
    let s = shards(&base, &["--no-pages"]);
    let record = std::fs::read_to_string(chunk0(&s[0])).unwrap();
    let edited = record.replacen("\"ground\":3.0}", "\"ground\":3.5}", 1);
    assert_ne!(edited, record);
    std::fs::write(chunk0(&s[0]), edited).unwrap();
    let out = base.join("merged");
    let o = merge(&out, &s, &["--no-pages"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("damaged"), "{}", stderr(&o));
    assert!(!out.join("index.json").exists());
    // Redone, the shard merges into exactly the single run's index.
    std::fs::write(chunk0(&s[0]), &record).unwrap();
    assert_ok(&merge(&out, &s, &["--no-pages"]));
    assert_eq!(
        std::fs::read(out.join("index.json")).unwrap(),
        std::fs::read(single.join("index.json")).unwrap()
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// A shard's chunk record naming `../planted.png` (a file that is there, with the
/// recorded hash) is refused: nothing is written outside `--out`.
#[test]
fn merge_never_writes_outside_out() {
    let base = tmp("merge-escape");
    let s = shards(&base.join("shards"), &[]);
    let page = "pages/bad-0001.png";
    std::fs::copy(s[0].join(page), base.join("shards/planted.png")).unwrap();
    let record = std::fs::read_to_string(chunk0(&s[0])).unwrap();
    let hostile = record.replacen(
        &format!("\"name\":\"{page}\""),
        "\"name\":\"../planted.png\"",
        1,
    );
    assert_ne!(hostile, record);
    std::fs::write(chunk0(&s[0]), hostile).unwrap();
    let out = base.join("out/merged");
    let o = merge(&out, &s, &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("../planted.png") && stderr(&o).contains("not a plain file name"),
        "{}",
        stderr(&o)
    );
    assert!(
        !base.join("out/planted.png").exists(),
        "merge wrote outside --out"
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// A symbolic link planted where the search cache's temporary file used to be named,
/// and a `pages/` that is a link to another folder holding what looks like a
/// temporary file: neither is followed, nothing outside the folder changes.
#[test]
fn planted_symlinks_are_not_followed() {
    let base = tmp("symlinks");
    let atlas = base.join("atlas");
    assert_ok(&generate(&ok_spec(), &atlas, &[]));
    let victim = base.join("victim.txt");
    std::fs::write(&victim, b"the user's file").unwrap();
    std::os::unix::fs::symlink(&victim, atlas.join("index.json.search.tmp")).unwrap();
    // Without its columns file (an atlas of an older version), search writes the cache.
    std::fs::remove_file(atlas.join("index.columns")).unwrap();
    let o = bin()
        .arg("search")
        .arg(atlas.join("index.json"))
        .args(["--limit", "1"])
        .output()
        .unwrap();
    assert_ok(&o);
    assert_eq!(std::fs::read(&victim).unwrap(), b"the user's file");
    assert!(atlas.join("index.json.search").is_file());

    // pages/ → a folder outside, holding a file named like a dead run's temporary.
    let elsewhere = base.join("elsewhere");
    std::fs::create_dir_all(&elsewhere).unwrap();
    let theirs = elsewhere.join(".draft.tmp-999999");
    std::fs::write(&theirs, b"keep").unwrap();
    std::fs::remove_dir_all(atlas.join("pages")).unwrap();
    std::os::unix::fs::symlink(&elsewhere, atlas.join("pages")).unwrap();
    let o = generate(&ok_spec(), &atlas, &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("is not a folder"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&theirs).unwrap(), b"keep");
    assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 1);
    let _ = std::fs::remove_dir_all(&base);
}

/// Starts `generate tests/fixtures/kill.toml --no-pages --jobs 1` into `out` (63 chunks,
/// long enough to race) and returns once its first chunk is recorded.
fn start_kill_atlas(out: &Path) -> std::process::Child {
    let child = bin()
        .arg("generate")
        .arg(root().join("tests/fixtures/kill.toml"))
        .arg("--out")
        .arg(out)
        .args(["--quiet", "--no-pages", "--jobs", "1"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !chunk0(out).exists() {
        assert!(start.elapsed() < Duration::from_secs(120), "no progress");
        std::thread::sleep(Duration::from_millis(5));
    }
    child
}

/// A second run into a folder a run is writing refuses at once, naming the first (its
/// process id); the first finishes unharmed; the lock goes with the process.
#[test]
fn a_second_run_into_a_busy_folder_refuses_naming_the_first() {
    let spec = root().join("tests/fixtures/kill.toml");
    let out = tmp("busy");
    let mut first = start_kill_atlas(&out);
    let second = generate(&spec, &out, &["--no-pages"]);
    let still_running = first.try_wait().unwrap().is_none();
    // Exit 1: nothing is wrong with the input, the folder is busy now.
    assert_eq!(second.status.code(), Some(1), "{}", stderr(&second));
    assert!(
        stderr(&second).contains("in use by another coupler-atlas run")
            && stderr(&second).contains(&format!("pid {}", first.id())),
        "{}",
        stderr(&second)
    );
    assert!(
        still_running,
        "the first run ended before the test could race it"
    );
    // A crash releases the lock: after SIGKILL, a run (here the last shard only, to
    // stay short) gets in.
    first.kill().unwrap();
    first.wait().unwrap();
    let o = generate(&spec, &out, &["--no-pages", "--shard", "63/63"]);
    assert_ok(&o);
    let _ = std::fs::remove_dir_all(&out);
}

/// The output folder removed while a run writes it (an `rm -rf` of the wrong folder): the
/// run stops at its next chunk with an error naming the folder (no panic, no folder made
/// again, no computing on with every write failing), and the same command then starts
/// afresh instead of taking what is left for the user's files.
#[test]
fn a_folder_removed_mid_run_stops_the_run_and_the_rerun_starts_afresh() {
    let spec = root().join("tests/fixtures/kill.toml");
    let out = tmp("removed");
    let child = start_kill_atlas(&out);
    // A file the run creates at that moment can make one pass fail (not empty).
    let start = Instant::now();
    while out.exists() {
        let _ = std::fs::remove_dir_all(&out);
        assert!(start.elapsed() < Duration::from_secs(10), "cannot remove");
    }
    let o = wait_at_most(child, Duration::from_secs(60));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains(&format!(
            "{} was removed while this run was writing it",
            out.display()
        )),
        "{e}"
    );
    assert!(!out.exists(), "the run made the removed folder again");
    // Only the last shard, to stay short: the folder is new again, nothing is refused.
    assert_ok(&generate(&spec, &out, &["--no-pages", "--shard", "63/63"]));
    let _ = std::fs::remove_dir_all(&out);
}

/// Start-up removes the temporaries of runs that are no longer running and leaves those of
/// a live process (here the test itself) alone; a file that only looks like one is not
/// touched either.
#[test]
fn start_up_removes_only_dead_runs_temporaries() {
    let dir = tmp("stale");
    assert_ok(&generate(&ok_spec(), &dir, &["--no-pages"]));
    let dead = [
        dir.join(".index.json.tmp-999999999-deadbeef"),
        dir.join(".coupler-atlas/chunks/.000000.jsonl.tmp-999999998-cafe"),
    ];
    let live = dir.join(format!(".index.json.tmp-{}-feed", std::process::id()));
    let lookalike = dir.join("notes.tmp-999999999-x");
    for f in dead.iter().chain([&live, &lookalike]) {
        std::fs::write(f, b"partial").unwrap();
    }
    std::fs::remove_file(dir.join("manifest.json")).unwrap();
    assert_ok(&generate(&ok_spec(), &dir, &["--no-pages", "--force"]));
    for f in &dead {
        assert!(!f.exists(), "{} (of a dead run) was left", f.display());
    }
    assert_eq!(std::fs::read(&live).unwrap(), b"partial");
    assert_eq!(std::fs::read(&lookalike).unwrap(), b"partial");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Waits for `child` at most `limit`; kills it and fails if it is still running.
fn wait_at_most(mut child: std::process::Child, limit: Duration) -> Output {
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().unwrap()
}

/// `--dry-run` of specs whose ranges multiply to 300³ and 100000³ combinations answers
/// at once (counted, not enumerated), with exact counts; the run itself needs `--yes`.
#[test]
fn huge_specs_are_planned_at_once() {
    let dir = tmp("huge");
    std::fs::create_dir_all(&dir).unwrap();
    for (n, linkages) in [(300, "13365599"), (100_000, "499985000199999")] {
        let spec = dir.join(format!("huge-{n}.toml"));
        std::fs::write(
            &spec,
            format!(
                "[atlas]\nname = \"huge\"\n\n[linkages]\n\
                 coupler = {{ start = 1.0, end = {n}.0, step = 1.0 }}\n\
                 rocker = {{ start = 1.0, end = {n}.0, step = 1.0 }}\n\
                 ground = {{ start = 1.0, end = {n}.0, step = 1.0 }}\n\n[points]\n\
                 u = {{ start = 0.0, end = 1.0, step = 0.5, relative = true }}\n\
                 v = {{ start = 0.0, end = 1.0, step = 0.5, relative = true }}\n"
            ),
        )
        .unwrap();
        let out = dir.join("out");
        let child = bin()
            .arg("generate")
            .arg(&spec)
            .arg("--out")
            .arg(&out)
            .arg("--dry-run")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Generous for a loaded machine: the count takes milliseconds.
        let o = wait_at_most(child, Duration::from_secs(20));
        assert_ok(&o);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(
            text.contains(&format!("linkages:     {linkages} strict crank-rockers")),
            "{text}"
        );
        assert!(text.contains("needs --yes"), "{text}");
        let child = bin()
            .arg("generate")
            .arg(&spec)
            .arg("--out")
            .arg(&out)
            .args(["--dry-run", "--format", "json"])
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        let o = wait_at_most(child, Duration::from_secs(20));
        let plan: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(plan["linkages"].to_string(), linkages);
        let child = bin()
            .arg("generate")
            .arg(&spec)
            .arg("--out")
            .arg(&out)
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let o = wait_at_most(child, Duration::from_secs(20));
        assert_eq!(o.status.code(), Some(2));
        assert!(stderr(&o).contains("--yes"), "{}", stderr(&o));
        assert!(!out.exists(), "a refused plan wrote into its folder");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// More curves than an index can number exactly (2^53) is refused even with `--yes`,
/// before anything is written; `--dry-run` says so.
#[test]
fn more_curves_than_ids_can_number_are_refused_even_with_yes() {
    let dir = tmp("2pow53");
    std::fs::create_dir_all(&dir).unwrap();
    let spec = dir.join("huge.toml");
    std::fs::write(
        &spec,
        "[atlas]\nname = \"huge\"\n\n[linkages]\n\
         coupler = { start = 1.0, end = 100000.0, step = 1.0 }\n\
         rocker = { start = 1.0, end = 100000.0, step = 1.0 }\n\
         ground = { start = 1.0, end = 100000.0, step = 1.0 }\n\n[points]\n\
         u = { start = 0.0, end = 1.0, step = 0.1, relative = true }\n\
         v = { start = 0.0, end = 1.0, step = 0.1, relative = true }\n",
    )
    .unwrap();
    let out = dir.join("out");
    let o = generate(&spec, &out, &["--dry-run", "--no-pages"]);
    assert_ok(&o);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("refused:      60498185024199879 curves is more than the 9007199254740992"),
        "{text}"
    );
    let o = generate(&spec, &out, &["--no-pages", "--yes"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("an index can number exactly"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists(), "a refused plan wrote into its folder");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The limits on page files (20,000) and on the estimated disk (20 GB) need `--yes` as the
/// curve limit does: `dense.toml` with pages (186,108 page files, about 76 GB) is over
/// both and refused without it; index only it is under all three.
#[test]
fn page_and_disk_limits_need_yes() {
    let dense = root().join("atlas-spec/dense.toml");
    let out = tmp("dense-limits");
    let o = generate(&dense, &out, &["--dry-run"]);
    assert_ok(&o);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("over limit:   186108 page files, more than 20000")
            && text.contains("GB on disk, more than 20.0 GB: needs --yes"),
        "{text}"
    );
    let o = generate(&dense, &out, &["--dry-run", "--no-pages"]);
    assert_ok(&o);
    assert!(!String::from_utf8_lossy(&o.stdout).contains("over limit"));
    let child = bin()
        .arg("generate")
        .arg(&dense)
        .arg("--out")
        .arg(&out)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let o = wait_at_most(child, Duration::from_secs(20));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--yes"), "{}", stderr(&o));
    assert!(!out.exists(), "a refused plan wrote into its folder");
}

/// `--force` adds an atlas beside the user's files but never overwrites one that is
/// where the atlas writes (their `index.json`, `manifest.json`, a page): it refuses,
/// naming it, and every file of theirs is intact.
#[test]
fn force_never_overwrites_the_users_files() {
    let dir = tmp("force");
    std::fs::create_dir_all(dir.join("pages")).unwrap();
    let theirs = [
        ("index.json", "my index"),
        ("manifest.json", "my manifest"),
        ("pages/bad-0001.png", "my page"),
        ("notes.txt", "my notes"),
    ];
    for (name, text) in theirs {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let o = generate(&ok_spec(), &dir, &["--force"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("was not written by coupler-atlas"),
        "{}",
        stderr(&o)
    );
    for (name, text) in theirs {
        assert_eq!(
            std::fs::read_to_string(dir.join(name)).unwrap(),
            text,
            "{name}"
        );
    }
    // Beside unrelated files, --force writes the atlas and leaves them alone.
    for (name, _) in &theirs[..3] {
        std::fs::remove_file(dir.join(name)).unwrap();
    }
    assert_ok(&generate(&ok_spec(), &dir, &["--force"]));
    assert_eq!(
        std::fs::read_to_string(dir.join("notes.txt")).unwrap(),
        "my notes"
    );
    manifest_consistent(&dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// The sidecars the atlas writes beside its index (`shapes.bin`, `index.columns`) are
/// the user's when the atlas did not write them: `--force` refuses, each file intact.
#[test]
fn force_never_overwrites_the_users_sidecars() {
    for name in ["shapes.bin", "index.columns"] {
        let dir = tmp(&format!("force-{name}"));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(name), "my file").unwrap();
        let o = generate(&ok_spec(), &dir, &["--no-pages", "--force"]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("was not written by coupler-atlas"),
            "{name}: {}",
            stderr(&o)
        );
        assert_eq!(
            std::fs::read_to_string(dir.join(name)).unwrap(),
            "my file",
            "{name}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// Page files (relative names) below `dir/pages`.
fn pages(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir.join("pages"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A rerun with other settings replaces the atlas as a whole: killed mid-way, the
/// folder's manifest (if any) never lists a file it does not match; finished, the
/// folder is exactly a clean run's (no page of the old settings left behind).
#[test]
fn a_settings_change_replaces_the_atlas_as_a_whole() {
    let spec = root().join("tests/fixtures/pages.toml");
    let (dir, clean) = (tmp("settings"), tmp("settings-clean"));
    assert_ok(&generate(&spec, &dir, &["--format", "png,svg"]));
    let old_key = {
        let r = std::fs::read_to_string(chunk0(&dir)).unwrap();
        let h: serde_json::Value = serde_json::from_str(r.lines().next().unwrap()).unwrap();
        h["run_key"].as_str().unwrap().to_string()
    };
    let mut child = bin()
        .arg("generate")
        .arg(&spec)
        .arg("--out")
        .arg(&dir)
        .args(["--quiet", "--dpi", "40", "--jobs", "1"])
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Killed once the new settings' first chunk is recorded.
    let start = Instant::now();
    loop {
        let key = std::fs::read_to_string(chunk0(&dir)).ok().and_then(|r| {
            let h: serde_json::Value = serde_json::from_str(r.lines().next()?).ok()?;
            Some(h["run_key"].as_str()?.to_string())
        });
        // (A run that already ended, finished or failed, is checked as it left the
        // folder.)
        if key.is_some_and(|k| k != old_key) || child.try_wait().unwrap().is_some() {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "no progress");
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    manifest_consistent(&dir).unwrap();
    assert_ok(&generate(&spec, &dir, &["--dpi", "40"]));
    assert_ok(&generate(&spec, &clean, &["--dpi", "40"]));
    assert_eq!(
        pages(&dir),
        pages(&clean),
        "pages of the old settings left behind"
    );
    for f in ["index.json", "manifest.json"] {
        assert!(
            std::fs::read(dir.join(f)).unwrap() == std::fs::read(clean.join(f)).unwrap(),
            "{f}"
        );
    }
    manifest_consistent(&dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&clean);
}

/// Every file below `dir` but the lock, with its inode and modification time.
fn stamps(dir: &Path) -> Vec<(PathBuf, u64, std::time::SystemTime)> {
    use std::os::unix::fs::MetadataExt;
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let (p, m) = (e.path(), e.metadata().unwrap());
            if p.ends_with(".coupler-atlas/lock") {
                continue;
            }
            if m.is_dir() {
                todo.push(p.clone());
            }
            out.push((p, m.ino(), m.modified().unwrap()));
        }
    }
    out.sort();
    out
}

/// A complete atlas is verified (every file against its recorded hash) without writing
/// anything, so it can be checked on a full or read-only disk; a damaged page is found
/// and only it is redone.
#[test]
fn a_complete_atlas_verifies_without_writing() {
    let dir = tmp("verify");
    assert_ok(&generate(&ok_spec(), &dir, &[]));
    let before = stamps(&dir);
    std::thread::sleep(Duration::from_millis(20));
    let o = generate(&ok_spec(), &dir, &[]);
    assert_ok(&o);
    assert!(
        stderr(&o).contains("complete and verified"),
        "{}",
        stderr(&o)
    );
    assert_eq!(
        stamps(&dir),
        before,
        "a verifying run wrote into the folder"
    );
    // A damaged page: detected, redone, the atlas again exactly as before.
    let page = dir.join("pages/bad-0002.png");
    let good = std::fs::read(&page).unwrap();
    let mut bad = good.clone();
    bad[100] ^= 0xff;
    std::fs::write(&page, &bad).unwrap();
    assert_ok(&generate(&ok_spec(), &dir, &[]));
    assert!(std::fs::read(&page).unwrap() == good);
    manifest_consistent(&dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// SIGTERM (what `kill`, a batch system or a container stop sends) and SIGHUP (the
/// terminal closed) stop like Ctrl-C: the work in progress finishes, the run says how to
/// resume, exit code 130.
#[test]
fn sigterm_and_sighup_stop_cleanly_like_sigint() {
    for signal in ["TERM", "HUP"] {
        let out = tmp(&format!("sig{signal}"));
        let child = start_kill_atlas(&out);
        let status = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        let o = child.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(130), "{signal}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("run the same command again to resume"),
            "{signal}: {}",
            stderr(&o)
        );
        assert!(!out.join("index.json").exists());
        let _ = std::fs::remove_dir_all(&out);
    }
}

/// A folder holding another atlas (another name) is refused, naming both atlases, and
/// nothing in it changes.
#[test]
fn another_atlas_in_the_folder_is_refused() {
    let dir = tmp("other-atlas");
    assert_ok(&generate(&ok_spec(), &dir, &["--no-pages"]));
    let before = stamps(&dir);
    let index = std::fs::read(dir.join("index.json")).unwrap();
    let quick = root().join("atlas-spec/quick.toml");
    for extra in [&["--no-pages"][..], &["--no-pages", "--force"][..]] {
        let o = generate(&quick, &dir, extra);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains("holds the atlas `bad`") && e.contains("`quick`"),
            "{e}"
        );
    }
    assert_eq!(std::fs::read(dir.join("index.json")).unwrap(), index);
    assert_eq!(stamps(&dir), before);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `merge` takes the spec and page settings from the shards (no `--spec`: not the
/// built-in atlas), and refuses shards made with other settings, naming both folders.
#[test]
fn merge_takes_the_spec_from_the_shards() {
    let base = tmp("merge-spec");
    let single = base.join("single");
    assert_ok(&generate(&ok_spec(), &single, &["--no-pages"]));
    let s = shards(&base, &["--no-pages"]);
    let out = base.join("merged");
    let o = bin()
        .arg("merge")
        .arg("--out")
        .arg(&out)
        .args(&s)
        .output()
        .unwrap();
    assert_ok(&o);
    assert_eq!(
        std::fs::read(out.join("index.json")).unwrap(),
        std::fs::read(single.join("index.json")).unwrap()
    );
    // Shard 2/2 made again with pages: the shards disagree.
    let other = base.join("s2-pages");
    assert_ok(&generate(&ok_spec(), &other, &["--shard", "2/2"]));
    let o = bin()
        .arg("merge")
        .arg("--out")
        .arg(base.join("merged-2"))
        .arg(&s[0])
        .arg(&other)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("do not make one atlas")
            && e.contains(&s[0].display().to_string())
            && e.contains(&other.display().to_string()),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&base);
}
