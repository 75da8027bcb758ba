//! What an atlas folder records about itself, in `.coupler-atlas/`:
//!
//! - `atlas.json`, the atlas's identity: its name, kind, spec (the TOML text), page
//!   settings and run key, and for a shard which one it is. `merge` takes the spec and
//!   settings from here; a run finds here whether the folder holds this atlas, the same
//!   atlas made with other settings (which it replaces as a whole), or another atlas
//!   (which it refuses to touch).
//! - `files`, the ledger: the name of every file a run of this program wrote (or was
//!   about to write) in the folder, one per line, appended and made durable before the
//!   file itself is written. A file that is not in the ledger is the user's: it is never
//!   overwritten or deleted, and a run that would write it refuses to start. After a
//!   complete run, files in the ledger that the new manifest does not list (pages of an
//!   earlier, larger atlas) are removed.

use crate::error::io_err;
use crate::files::{PAGES_DIR, STATE_DIR, check_name, read_small, sync_dir, write_atomically};
use crate::{GenerateError, PageOptions};
use serde::{Deserialize, Serialize};
use std::collections::HashSet;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Version of `atlas.json`.
const IDENTITY_FORMAT: u32 = 1;

/// The page settings a run used, as `generate`'s flags give them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PageFlags {
    /// Formats (`png`, `svg`, `pdf`), in order.
    pub formats: Vec<String>,
    /// Resolution, dots per inch.
    pub dpi: f64,
    /// Paper and orientation, e.g. `tabloid` or `a4-landscape`.
    pub page_size: String,
    /// PNG compression, `fast` or `best` (recorded only when not `fast`, the default).
    #[serde(default = "fast", skip_serializing_if = "is_fast")]
    pub png_compression: String,
}

fn fast() -> String {
    coupler_render::PngCompression::Fast.name().into()
}

fn is_fast(s: &String) -> bool {
    *s == fast()
}

impl PageFlags {
    /// The flags of a renderer's options.
    pub fn of(opts: &PageOptions) -> PageFlags {
        PageFlags {
            formats: opts
                .formats
                .iter()
                .map(|f| f.extension().to_string())
                .collect(),
            dpi: opts.setup.dpi,
            page_size: opts.setup.size.to_string(),
            png_compression: opts.png_compression.name().into(),
        }
    }
}

/// `.coupler-atlas/atlas.json`: which atlas a folder holds and how it was made.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Identity {
    /// Version of this record.
    pub format: u32,
    /// `grid` or `page set`.
    pub kind: String,
    /// The atlas's name.
    pub name: String,
    /// Where its spec came from.
    pub source: String,
    /// The run key (program version, spec and settings).
    pub run_key: String,
    /// Program and version.
    pub generator: String,
    /// The spec's TOML text, when known (what `merge` rebuilds the job from).
    #[serde(default)]
    pub spec_toml: Option<String>,
    /// Page settings (`None`: no pages).
    #[serde(default)]
    pub pages: Option<PageFlags>,
    /// `K/N` for a shard of several.
    #[serde(default)]
    pub shard: Option<String>,
}

impl Identity {
    /// A new record for the current program.
    pub fn new(kind: &str, name: &str, source: &str, run_key: &str) -> Identity {
        Identity {
            format: IDENTITY_FORMAT,
            kind: kind.into(),
            name: name.into(),
            source: source.into(),
            run_key: run_key.into(),
            generator: format!("coupler-atlas {}", env!("CARGO_PKG_VERSION")),
            spec_toml: None,
            pages: None,
            shard: None,
        }
    }

    /// Whether `self` (a folder's record) is the same atlas as `other`, made with the same
    /// settings.
    pub fn same_run(&self, other: &Identity) -> bool {
        self.run_key == other.run_key
    }

    /// Whether it is the same atlas (name and kind), whatever its settings.
    pub fn same_atlas(&self, other: &Identity) -> bool {
        self.name == other.name && self.kind == other.kind
    }
}

fn identity_path(dir: &Path) -> PathBuf {
    dir.join(STATE_DIR).join("atlas.json")
}

/// Reads a folder's `atlas.json`: `Ok(None)` when there is none, `Err` (why) when it is
/// damaged.
pub fn read_identity(dir: &Path) -> Result<Option<Identity>, String> {
    let path = identity_path(dir);
    if std::fs::symlink_metadata(&path).is_err() {
        return Ok(None);
    }
    let bytes = read_small(&path, 64 << 20).map_err(|e| format!("{}: {e}", path.display()))?;
    let id: Identity =
        serde_json::from_slice(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    if id.format != IDENTITY_FORMAT {
        return Err(format!(
            "{}: format {} is not supported (this program reads {IDENTITY_FORMAT})",
            path.display(),
            id.format
        ));
    }
    Ok(Some(id))
}

/// Writes `atlas.json` unless it already says exactly this (a complete atlas on a
/// read-only disk is verified without writing).
pub(crate) fn write_identity(dir: &Path, id: &Identity) -> Result<(), GenerateError> {
    if read_identity(dir).ok().flatten().as_ref() == Some(id) {
        return Ok(());
    }
    let path = identity_path(dir);
    write_atomically(&path, |w| {
        serde_json::to_writer_pretty(&mut *w, id)?;
        w.write_all(b"\n")
    })
}

/// The ledger of files this program wrote in a folder (`.coupler-atlas/files`).
#[derive(Debug)]
pub(crate) struct Ledger {
    path: PathBuf,
    inner: Mutex<LedgerInner>,
    /// A folder made by an earlier version (state folder, no ledger): every file at one of
    /// this atlas's names counts as its own, as those versions assumed.
    legacy: bool,
}

#[derive(Debug)]
struct LedgerInner {
    names: HashSet<String>,
    file: Option<std::fs::File>,
}

/// Longest ledger line read (names are at most 206 bytes).
const MAX_LEDGER_LINE: usize = 4096;

impl Ledger {
    /// Reads the ledger of `out` (empty when there is none). Lines that are not plain
    /// names (damage) are ignored: those files then count as the user's, the safe side.
    /// `had_state`: the folder had a state folder before this run (without a ledger, it
    /// was made by an earlier version).
    pub(crate) fn read(out: &Path, had_state: bool) -> Ledger {
        let path = out.join(STATE_DIR).join("files");
        let mut names = HashSet::new();
        let exists = std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file());
        if let Ok(f) = crate::files::open_regular(&path) {
            let mut r = std::io::BufReader::new(f);
            let mut line = Vec::new();
            loop {
                line.clear();
                match coupler_index::read_line_bounded(&mut r, &mut line, MAX_LEDGER_LINE) {
                    Ok(0) => break,
                    Ok(_) => {
                        if let Ok(s) = std::str::from_utf8(&line) {
                            let s = s.trim_end_matches('\n');
                            if check_name(s).is_ok() {
                                names.insert(s.to_string());
                            }
                        }
                    }
                    Err(_) => break,
                }
            }
        }
        let legacy = !exists && had_state;
        Ledger {
            path,
            inner: Mutex::new(LedgerInner { names, file: None }),
            legacy,
        }
    }

    /// Whether this program wrote `name` here.
    pub(crate) fn owns(&self, name: &str) -> bool {
        self.legacy
            || self
                .inner
                .lock()
                .map(|i| i.names.contains(name))
                .unwrap_or(false)
    }

    /// Records `names` (those not yet recorded), durably, before they are written.
    pub(crate) fn add<'a>(
        &self,
        names: impl IntoIterator<Item = &'a str>,
    ) -> Result<(), GenerateError> {
        let mut inner = self
            .inner
            .lock()
            .map_err(|_| io_err(&self.path)(std::io::Error::other("ledger lock poisoned")))?;
        let new: Vec<&str> = names
            .into_iter()
            .filter(|n| !inner.names.contains(*n))
            .collect();
        if new.is_empty() {
            return Ok(());
        }
        let mut text = String::new();
        for n in &new {
            text.push_str(n);
            text.push('\n');
        }
        if inner.file.is_none() {
            let f = std::fs::OpenOptions::new()
                .append(true)
                .create(true)
                .open(&self.path)
                .map_err(io_err(&self.path))?;
            inner.file = Some(f);
        }
        if let Some(f) = inner.file.as_mut() {
            f.write_all(text.as_bytes())
                .and_then(|_| f.sync_data())
                .map_err(io_err(&self.path))?;
        }
        for n in new {
            inner.names.insert(n.to_string());
        }
        Ok(())
    }

    /// Every recorded name.
    pub(crate) fn names(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .inner
            .lock()
            .map(|i| i.names.iter().cloned().collect())
            .unwrap_or_default();
        v.sort();
        v
    }

    /// Replaces the ledger by exactly `names`.
    pub(crate) fn rewrite(&self, names: &[String]) -> Result<(), GenerateError> {
        let mut inner = self
            .inner
            .lock()
            .map_err(|_| io_err(&self.path)(std::io::Error::other("ledger lock poisoned")))?;
        let mut sorted = names.to_vec();
        sorted.sort();
        sorted.dedup();
        let current: HashSet<String> = sorted.iter().cloned().collect();
        if current == inner.names && self.path.exists() {
            return Ok(());
        }
        inner.file = None;
        write_atomically(&self.path, |w| {
            for n in &sorted {
                w.write_all(n.as_bytes())?;
                w.write_all(b"\n")?;
            }
            Ok(())
        })?;
        inner.names = current;
        Ok(())
    }
}

/// Which names an atlas writes: its root files and pages named `STEM-NNNN.EXT` or
/// `STEM-contents-N.EXT` (any page format).
pub(crate) struct Names<'a> {
    /// Files in the atlas folder itself.
    pub root: &'a [&'a str],
    /// The page files' stem.
    pub stem: &'a str,
}

impl Names<'_> {
    /// Whether the atlas may write `name` (relative to the folder).
    pub(crate) fn has(&self, name: &str) -> bool {
        match name.split_once('/') {
            None => self.root.contains(&name),
            Some((dir, file)) => {
                dir == PAGES_DIR
                    && file
                        .strip_prefix(self.stem)
                        .and_then(|r| r.strip_prefix('-'))
                        .and_then(|r| r.rsplit_once('.'))
                        .is_some_and(|(num, ext)| {
                            let num = num.strip_prefix("contents-").unwrap_or(num);
                            !num.is_empty()
                                && num.bytes().all(|b| b.is_ascii_digit())
                                && matches!(ext, "png" | "svg" | "pdf")
                        })
            }
        }
    }
}

/// Refuses to start if a file this atlas would write is already in `out` and the ledger
/// does not say this program wrote it (the user's `index.json`, their pages…).
pub(crate) fn check_user_files(
    out: &Path,
    ledger: &Ledger,
    names: &Names,
) -> Result<(), GenerateError> {
    let mut found: Vec<String> = Vec::new();
    for (dir, prefix) in [(out.to_path_buf(), ""), (out.join(PAGES_DIR), "pages/")] {
        if !std::fs::symlink_metadata(&dir).is_ok_and(|m| m.is_dir()) {
            continue;
        }
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            // A folder where a page goes cannot be overwritten (that page then fails,
            // named, and the run goes on): only files and links are at risk.
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                continue;
            }
            let name = format!("{prefix}{}", e.file_name().to_string_lossy());
            if names.has(&name) && !ledger.owns(&name) {
                found.push(name);
            }
        }
    }
    found.sort();
    match found.first() {
        None => Ok(()),
        Some(first) => Err(GenerateError::UserFile {
            path: out.join(first),
            more: if found.len() == 1 {
                "the only such file".into()
            } else {
                format!("and {} more like it", found.len() - 1)
            },
        }),
    }
}

/// Removes `name` (a recorded, plain name) from `out` if it is a file or a link; a
/// folder in its place is left alone.
fn remove_owned(out: &Path, name: &str) -> Result<bool, GenerateError> {
    if check_name(name).is_err() {
        return Ok(false);
    }
    let path = out.join(name);
    match std::fs::symlink_metadata(&path) {
        Ok(m) if !m.is_dir() => {
            std::fs::remove_file(&path).map_err(io_err(&path))?;
            Ok(true)
        }
        _ => Ok(false),
    }
}

/// Takes an earlier atlas out of `out` as a whole, so that a reader never finds its
/// manifest or index beside pages of other settings: first the manifest, then the index
/// (`root` files, in order), then the chunk records, then every other file the ledger
/// lists. Each step is made durable before the next.
pub(crate) fn remove_atlas(
    out: &Path,
    ledger: &Ledger,
    root: &[&str],
) -> Result<(), GenerateError> {
    for name in root {
        if ledger.owns(name) && remove_owned(out, name)? {
            sync_dir(out).map_err(io_err(out))?;
        }
    }
    let chunks = out.join(STATE_DIR).join("chunks");
    if let Ok(entries) = std::fs::read_dir(&chunks) {
        for e in entries.flatten() {
            if e.file_type().is_ok_and(|t| t.is_file())
                && e.file_name().to_string_lossy().ends_with(".jsonl")
            {
                std::fs::remove_file(e.path()).map_err(io_err(&e.path()))?;
            }
        }
        sync_dir(&chunks).map_err(io_err(&chunks))?;
    }
    for name in ledger.names() {
        remove_owned(out, &name)?;
    }
    if out.join(PAGES_DIR).is_dir() {
        sync_dir(&out.join(PAGES_DIR)).map_err(io_err(out))?;
    }
    ledger.rewrite(&[])
}

/// After a complete run: removes every file the ledger lists that `keep` does not (what
/// earlier runs wrote and this atlas no longer has), then records exactly `keep`.
pub(crate) fn prune(out: &Path, ledger: &Ledger, keep: &[String]) -> Result<usize, GenerateError> {
    let keep_set: HashSet<&str> = keep.iter().map(String::as_str).collect();
    let mut removed = 0;
    for name in ledger.names() {
        if !keep_set.contains(name.as_str()) && remove_owned(out, &name)? {
            removed += 1;
        }
    }
    if removed > 0 && out.join(PAGES_DIR).is_dir() {
        sync_dir(&out.join(PAGES_DIR)).map_err(io_err(out))?;
    }
    ledger.rewrite(keep)?;
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_of_an_atlas() {
        let n = Names {
            root: &["index.json", "manifest.json"],
            stem: "quick",
        };
        for yes in [
            "index.json",
            "pages/quick-0001.png",
            "pages/quick-12.svg",
            "pages/quick-contents-1.pdf",
        ] {
            assert!(n.has(yes), "{yes}");
        }
        for no in [
            "notes.txt",
            "pages/quick-notes.png",
            "pages/quicker-0001.png",
            "pages/quick-0001.txt",
            "pages/hd-0001.png",
            "pages/quick-.png",
        ] {
            assert!(!n.has(no), "{no}");
        }
    }

    #[test]
    fn ledger_records_durably_and_reads_back() {
        let dir = std::env::temp_dir().join(format!("coupler-ledger-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join(STATE_DIR)).unwrap();
        let l = Ledger::read(&dir, false);
        assert!(!l.owns("index.json"));
        l.add(["index.json", "pages/a-0001.png"]).unwrap();
        l.add(["index.json"]).unwrap();
        // A damaged line (a path out of the folder) is ignored.
        std::fs::OpenOptions::new()
            .append(true)
            .open(dir.join(STATE_DIR).join("files"))
            .unwrap()
            .write_all(b"../../etc/passwd\n")
            .unwrap();
        let back = Ledger::read(&dir, true);
        assert!(back.owns("index.json") && back.owns("pages/a-0001.png"));
        assert!(!back.owns("../../etc/passwd"));
        assert_eq!(back.names().len(), 2);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
