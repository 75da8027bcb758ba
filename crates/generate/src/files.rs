//! The files of an atlas folder: every file written under a temporary name and renamed
//! into place when complete, recorded with its size and XXH3-128 hash (chunk records and
//! the manifest), checked on reuse; the folder refused if it holds files this program did
//! not write; temporaries a killed run left behind removed.

use crate::error::io_err;
use crate::{Artifact, GenerateError};
use serde::{Deserialize, Serialize};
use std::io::Write as _;
use std::path::Path;

/// The folder (inside the output folder) that holds chunk records.
pub const STATE_DIR: &str = ".coupler-atlas";

/// One file recorded in a chunk record or the manifest.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileEntry {
    /// Name relative to the atlas folder.
    pub name: String,
    /// Size in bytes.
    pub bytes: u64,
    /// XXH3-128 of the content, hex.
    pub xxh3: String,
}

impl FileEntry {
    pub(crate) fn of(name: &str, bytes: &[u8]) -> FileEntry {
        FileEntry {
            name: name.to_string(),
            bytes: bytes.len() as u64,
            xxh3: format!("{:032x}", xxhash_rust::xxh3::xxh3_128(bytes)),
        }
    }

    /// The entry of file `name` in `dir`, hashed in blocks (memory stays small whatever
    /// the file's size).
    pub fn of_file(dir: &Path, name: &str) -> std::io::Result<FileEntry> {
        use std::io::Read;
        let mut file = std::fs::File::open(dir.join(name))?;
        let mut hasher = xxhash_rust::xxh3::Xxh3::new();
        let mut buf = vec![0u8; 1 << 20];
        let mut bytes = 0u64;
        loop {
            let n = file.read(&mut buf)?;
            if n == 0 {
                break;
            }
            hasher.update(&buf[..n]);
            bytes += n as u64;
        }
        Ok(FileEntry {
            name: name.to_string(),
            bytes,
            xxh3: format!("{:032x}", hasher.digest128()),
        })
    }

    /// Whether the file is in `dir` with this size and hash.
    pub fn verify(&self, dir: &Path) -> bool {
        match std::fs::metadata(dir.join(&self.name)) {
            Ok(m) if m.len() == self.bytes => {
                FileEntry::of_file(dir, &self.name).is_ok_and(|e| e == *self)
            }
            _ => false,
        }
    }
}

/// Checks that `dir` is new, empty, or this program's output (unless `force`).
pub fn check_out_dir(dir: &Path, force: bool) -> Result<(), GenerateError> {
    if force || !dir.exists() {
        return Ok(());
    }
    let mut entries = std::fs::read_dir(dir).map_err(io_err(dir))?;
    let names: Vec<String> = entries
        .by_ref()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    if names.is_empty() || names.iter().any(|n| n == STATE_DIR) {
        return Ok(());
    }
    let mut names = names;
    names.sort();
    Err(GenerateError::ForeignFolder {
        dir: dir.to_path_buf(),
        example: names[0].clone(),
    })
}

pub(crate) fn write_artifact(dir: &Path, a: &Artifact) -> Result<FileEntry, GenerateError> {
    let path = dir.join(&a.name);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(io_err(parent))?;
    }
    write_atomically(&path, |w| w.write_all(&a.bytes))?;
    Ok(FileEntry::of(&a.name, &a.bytes))
}

/// Writes `manifest.json` in `dir`: the run key and every file (sorted by name) with its
/// size and XXH3-128 hash.
pub(crate) fn write_manifest(
    dir: &Path,
    key: &str,
    mut files: Vec<FileEntry>,
) -> Result<(), GenerateError> {
    files.sort_by(|a, b| a.name.cmp(&b.name));
    write_atomically(&dir.join("manifest.json"), |w| {
        write!(
            w,
            "{{\"schema_version\":1,\"run_key\":\"{key}\",\"files\":["
        )?;
        for (i, f) in files.iter().enumerate() {
            w.write_all(if i == 0 { b"\n" } else { b",\n" })?;
            serde_json::to_writer(&mut *w, f)?;
        }
        w.write_all(b"\n]}\n")
    })
}

/// Removes temporary files a killed run of this program left (`.NAME.tmp-PID`, as
/// [`write_atomically`] names them) from the output folder, its `pages/` and its chunk
/// records. Nothing else is touched.
pub(crate) fn remove_stale_temporaries(out: &Path) {
    for dir in [
        out.to_path_buf(),
        out.join("pages"),
        out.join(STATE_DIR).join("chunks"),
    ] {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let ours = name.starts_with('.')
                && name.rsplit_once(".tmp-").is_some_and(|(_, pid)| {
                    !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit())
                });
            if ours && e.file_type().is_ok_and(|t| t.is_file()) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// Writes a file under a temporary name in the same folder and renames it into place
/// when complete, so no partial file ever stands under the final name.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), GenerateError> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(file);
        write(&mut w)?;
        w.flush()?;
        drop(w.into_inner().map_err(|e| e.into_error())?);
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io_err(path))
}
