//! The files of an atlas folder: every file written under an unpredictable temporary name
//! (created exclusively, so a planted file or symbolic link is never followed), made
//! durable (fsync) and renamed into place when complete, the rename made durable too;
//! recorded with its size and XXH3-128 hash (chunk records and the manifest) and checked
//! on reuse; names read back from any record checked to be plain relative names inside
//! the folder; the folder refused if it holds files this program did not write;
//! temporaries of dead runs removed.

use crate::error::io_err;
use crate::{Artifact, GenerateError};
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// The folder (inside the output folder) that holds chunk records, the lock, the
/// record of the atlas's settings and of the files it wrote.
pub const STATE_DIR: &str = ".coupler-atlas";

/// The folder (inside the output folder) that holds pages.
pub const PAGES_DIR: &str = "pages";

/// The longest file name a record may give (bytes; file systems allow 255, and a
/// temporary name adds about 40).
const MAX_NAME_BYTES: usize = 200;

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

/// Checks that `name` (read from a record, so possibly damaged or hostile) is a plain
/// relative name inside the atlas folder: `FILE` or `pages/FILE`, where `FILE` is made
/// of ASCII letters, digits, `-`, `_` and `.`, does not start with `.`, and is at most
/// 200 bytes. So `../x`, `/etc/x`, `a/../../x`, `.`, `..`, NUL bytes, backslashes and
/// deeper paths are all refused.
pub fn check_name(name: &str) -> Result<(), String> {
    let plain = |part: &str| {
        !part.is_empty()
            && part.len() <= MAX_NAME_BYTES
            && !part.starts_with('.')
            && part
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'))
    };
    let ok = match name.split_once('/') {
        None => plain(name),
        Some((dir, file)) => dir == PAGES_DIR && plain(file),
    };
    if ok {
        Ok(())
    } else {
        Err(format!(
            "`{}` is not a plain file name inside the atlas folder",
            name.escape_debug()
        ))
    }
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
    /// the file's size). A symbolic link or anything but a regular file is an error.
    pub fn of_file(dir: &Path, name: &str) -> std::io::Result<FileEntry> {
        let file = open_regular(&dir.join(name))?;
        let (bytes, xxh3) = hash_reader(file)?;
        Ok(FileEntry {
            name: name.to_string(),
            bytes,
            xxh3,
        })
    }

    /// Whether the file is in `dir` (a regular file, not a link) with this size and
    /// hash, and its name is a plain name inside the folder.
    pub fn verify(&self, dir: &Path) -> bool {
        if check_name(&self.name).is_err() {
            return false;
        }
        match std::fs::symlink_metadata(dir.join(&self.name)) {
            Ok(m) if m.is_file() && m.len() == self.bytes => {
                FileEntry::of_file(dir, &self.name).is_ok_and(|e| e == *self)
            }
            _ => false,
        }
    }
}

/// Size and XXH3-128 (hex) of everything `r` yields, read in 1 MiB blocks (the same
/// streaming hash that keys the search cache).
pub(crate) fn hash_reader(r: impl Read) -> std::io::Result<(u64, String)> {
    let key = coupler_index::IndexKey::of_reader(r)?;
    Ok((key.bytes, format!("{:032x}", key.hash)))
}

/// Opens `path` for reading if it is a regular file (a symbolic link, a folder, a device
/// or a pipe is an error: records name regular files only).
pub(crate) fn open_regular(path: &Path) -> std::io::Result<std::fs::File> {
    let meta = std::fs::symlink_metadata(path)?;
    if !meta.is_file() {
        return Err(std::io::Error::other(format!(
            "{} is not a regular file",
            path.display()
        )));
    }
    let file = std::fs::File::open(path)?;
    // The path may have been swapped between the two calls: check what was opened.
    if !file.metadata()?.is_file() {
        return Err(std::io::Error::other(format!(
            "{} is not a regular file",
            path.display()
        )));
    }
    Ok(file)
}

/// Reads a whole small file (a manifest, a record of settings), refusing anything that
/// is not a regular file or is larger than `max` bytes, before reading it.
pub(crate) fn read_small(path: &Path, max: u64) -> std::io::Result<Vec<u8>> {
    let file = open_regular(path)?;
    let len = file.metadata()?.len();
    if len > max {
        return Err(std::io::Error::other(format!(
            "{} is {len} bytes, more than the {max} expected",
            path.display()
        )));
    }
    let mut out = Vec::with_capacity(len as usize);
    file.take(max + 1).read_to_end(&mut out)?;
    if out.len() as u64 > max {
        return Err(std::io::Error::other(format!(
            "{} grew past {max} bytes while read",
            path.display()
        )));
    }
    Ok(out)
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

/// Refuses a `pages/` or `.coupler-atlas/` (or its `chunks/`) that is not a real folder
/// inside `out` (a symbolic link would carry writes and clean-up outside the output
/// folder).
pub(crate) fn check_subfolders(out: &Path) -> Result<(), GenerateError> {
    for sub in [
        out.join(PAGES_DIR),
        out.join(STATE_DIR),
        out.join(STATE_DIR).join("chunks"),
    ] {
        match std::fs::symlink_metadata(&sub) {
            Ok(m) if !m.is_dir() => {
                return Err(GenerateError::NotAFolder { path: sub });
            }
            _ => {}
        }
    }
    Ok(())
}

/// Writes an artifact (its name checked) into `dir`, whose `pages/` folder exists:
/// atomically, but not yet durably: [`sync_files`] makes a chunk's files durable at once,
/// before the record that claims them is written.
pub(crate) fn write_artifact(dir: &Path, a: &Artifact) -> Result<FileEntry, GenerateError> {
    let path = dir.join(&a.name);
    check_name(&a.name).map_err(|m| GenerateError::Io {
        path: path.clone(),
        source: std::io::Error::other(m),
    })?;
    write_file(&path, false, |w| w.write_all(&a.bytes))?;
    Ok(FileEntry::of(&a.name, &a.bytes))
}

/// An artifact written under its temporary name beside its final path, not yet in place
/// (see [`stage_artifact`]): put in place by [`Staged::commit`], removed if dropped first.
pub(crate) struct Staged {
    entry: FileEntry,
    file: Temporary,
}

impl Staged {
    /// Its name, relative to the atlas folder.
    pub(crate) fn name(&self) -> &str {
        &self.entry.name
    }

    /// Where it is written until it is put in place (its temporary name's full path).
    pub(crate) fn staged_path(&self) -> &Path {
        self.file.temporary_path()
    }

    /// Makes it durable under its temporary name (fsync): then putting it in place needs
    /// only its folder made durable ([`sync_folders`]). Quick when it was already made
    /// durable, as the run does for the contents while the groups are computed.
    pub(crate) fn sync(&self) -> Result<(), GenerateError> {
        let path = self.staged_path();
        std::fs::File::open(path)
            .and_then(|f| f.sync_all())
            .map_err(io_err(path))
    }

    /// Renames it into place (not yet durably, as [`write_artifact`] leaves a file).
    pub(crate) fn commit(self) -> Result<FileEntry, GenerateError> {
        let path = self.file.path().to_path_buf();
        self.file.commit(false).map_err(io_err(&path))?;
        Ok(self.entry)
    }
}

/// [`write_artifact`] up to the rename: the bytes written under the file's temporary
/// name, so that they need not be held in memory until the name is recorded and the file
/// can be put in place.
pub(crate) fn stage_artifact(dir: &Path, a: &Artifact) -> Result<Staged, GenerateError> {
    let path = dir.join(&a.name);
    check_name(&a.name).map_err(|m| GenerateError::Io {
        path: path.clone(),
        source: std::io::Error::other(m),
    })?;
    let mut file = Temporary::create(&path).map_err(io_err(&path))?;
    file.buffer()
        .write_all(&a.bytes)
        .and_then(|()| file.close(false))
        .map_err(io_err(&path))?;
    Ok(Staged {
        entry: FileEntry::of(&a.name, &a.bytes),
        file,
    })
}

/// Makes files `names` of `dir` durable (fsync each, in parallel, so the file system
/// can commit them together), then the folders they are in.
pub(crate) fn sync_files<'a>(
    dir: &Path,
    names: impl IntoIterator<Item = &'a str>,
) -> Result<(), GenerateError> {
    use rayon::prelude::*;
    let names: Vec<&str> = names.into_iter().collect();
    if names.is_empty() {
        // (Nothing to sync: an index-only chunk. Returning here also keeps such a run
        // from starting rayon's global pool, two more threads, for an empty job.)
        return Ok(());
    }
    names.par_iter().try_for_each(|n| {
        let path = dir.join(n);
        std::fs::File::open(&path)
            .and_then(|f| f.sync_all())
            .map_err(io_err(&path))
    })?;
    sync_folders(dir, names)
}

/// Makes the folders of files `names` of `dir` durable (fsync of each folder once): what
/// [`sync_files`] does after the files, for files already durable under the temporary
/// names they were renamed from.
pub(crate) fn sync_folders<'a>(
    dir: &Path,
    names: impl IntoIterator<Item = &'a str>,
) -> Result<(), GenerateError> {
    let mut folders: Vec<PathBuf> = names
        .into_iter()
        .map(|n| {
            dir.join(n)
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_default()
        })
        .collect();
    folders.sort();
    folders.dedup();
    for f in folders {
        sync_dir(&f).map_err(io_err(&f))?;
    }
    Ok(())
}

/// Writes `manifest.json` in `dir`: the run key and every file (sorted by name) with its
/// size and XXH3-128 hash.
pub(crate) fn write_manifest(
    dir: &Path,
    key: &str,
    files: Vec<FileEntry>,
) -> Result<(), GenerateError> {
    let path = dir.join("manifest.json");
    manifest_file(dir, key, files)?
        .commit(true)
        .map_err(io_err(&path))
}

/// [`write_manifest`]'s file, written and made durable under its temporary name, not yet
/// in place: [`Temporary::commit`] (durable) puts it there. So it can be written while
/// the files it lists are being put in place, and renamed after them.
pub(crate) fn manifest_file(
    dir: &Path,
    key: &str,
    mut files: Vec<FileEntry>,
) -> Result<Temporary, GenerateError> {
    files.sort_by(|a, b| a.name.cmp(&b.name));
    let path = dir.join("manifest.json");
    let mut t = Temporary::create(&path).map_err(io_err(&path))?;
    let w = t.buffer();
    write!(
        w,
        "{{\"schema_version\":1,\"run_key\":\"{key}\",\"files\":["
    )
    .and_then(|()| {
        for (i, f) in files.iter().enumerate() {
            w.write_all(if i == 0 { b"\n" } else { b",\n" })?;
            serde_json::to_writer(&mut *w, f)?;
        }
        w.write_all(b"\n]}\n")
    })
    .and_then(|()| t.close(true))
    .map_err(io_err(&path))?;
    Ok(t)
}

/// The manifest as read back.
#[derive(Debug, Deserialize)]
pub(crate) struct Manifest {
    pub run_key: String,
    pub files: Vec<FileEntry>,
}

/// Reads `manifest.json` of `dir` (at most 1 GiB), or `None` if it is missing or is not
/// a manifest.
pub(crate) fn read_manifest(dir: &Path) -> Option<Manifest> {
    let bytes = read_small(&dir.join("manifest.json"), 1 << 30).ok()?;
    serde_json::from_slice(&bytes).ok()
}

/// The temporary name of a file being written as `name`: `.NAME.tmp-PID-RANDOM`. The
/// process id says whose it is (so clean-up removes only a dead run's); the random part
/// makes it unpredictable, and it is created exclusively, so nothing planted under it
/// (a file, a symbolic link) is ever opened.
fn temporary_name(name: &str) -> String {
    use std::hash::{BuildHasher, Hasher};
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    // RandomState's keys are random per process; the counter and time make each call's
    // value distinct.
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
    h.write_u128(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0),
    );
    format!(".{name}.tmp-{}-{:016x}", std::process::id(), h.finish())
}

/// Creates a new temporary file beside `path`, exclusively (never an existing file or
/// link).
pub(crate) fn create_temporary(path: &Path) -> std::io::Result<(PathBuf, std::fs::File)> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    loop {
        let tmp = path.with_file_name(temporary_name(name));
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
        {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

/// Makes a rename or removal in `dir` durable (fsync of the folder).
pub(crate) fn sync_dir(dir: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::fs::File::open(dir)?.sync_all()
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        Ok(())
    }
}

/// Writes a file under a temporary name in the same folder, makes it durable (fsync),
/// and renames it into place when complete, then makes the rename durable (fsync of the
/// folder): no partial file ever stands under the final name, even after a power cut.
/// Every file that commits work (chunk records, the index, the manifest) is written so.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), GenerateError> {
    write_file(path, true, write)
}

/// [`write_atomically`], the fsyncs only when `durable`.
pub(crate) fn write_file(
    path: &Path,
    durable: bool,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), GenerateError> {
    let mut t = Temporary::create(path).map_err(io_err(path))?;
    write(t.buffer())
        .and_then(|()| t.close(durable))
        .and_then(|()| t.commit(durable))
        .map_err(io_err(path))
}

/// A file being written under a temporary name beside its final path (created as
/// [`create_temporary`] creates it), counting and hashing (XXH3-128) what is written
/// through its [`Write`](std::io::Write); renamed into place by [`Temporary::commit`],
/// removed if dropped before (an error or an interrupted run leaves nothing behind).
pub(crate) struct Temporary {
    path: PathBuf,
    tmp: PathBuf,
    w: Option<std::io::BufWriter<std::fs::File>>,
    hasher: xxhash_rust::xxh3::Xxh3,
    bytes: u64,
    committed: bool,
}

impl Temporary {
    /// Creates the temporary file of `path`.
    pub(crate) fn create(path: &Path) -> std::io::Result<Temporary> {
        let (tmp, file) = create_temporary(path)?;
        Ok(Temporary {
            path: path.to_path_buf(),
            tmp,
            w: Some(std::io::BufWriter::with_capacity(1 << 16, file)),
            hasher: xxhash_rust::xxh3::Xxh3::new(),
            bytes: 0,
            committed: false,
        })
    }

    /// The final path.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// The temporary path (where the file is until [`Temporary::commit`]).
    pub(crate) fn temporary_path(&self) -> &Path {
        &self.tmp
    }

    /// The file's buffer, for writing what need not be counted or hashed.
    fn buffer(&mut self) -> &mut std::io::BufWriter<std::fs::File> {
        self.w.as_mut().expect("written before it is closed")
    }

    /// Size and hash of what was written through `Write`, as recorded for file `name`.
    pub(crate) fn entry(&self, name: &str) -> FileEntry {
        FileEntry {
            name: name.to_string(),
            bytes: self.bytes,
            xxh3: format!("{:032x}", self.digest()),
        }
    }

    /// XXH3-128 of what was written through `Write`.
    pub(crate) fn digest(&self) -> u128 {
        self.hasher.digest128()
    }

    /// Flushes what was written so far and waits until it is on the disk (`fdatasync`),
    /// so that the closing fsync ([`Temporary::close`]) has only the rest to write.
    pub(crate) fn sync_written(&mut self) -> std::io::Result<()> {
        let w = self.buffer();
        w.flush()?;
        w.get_ref().sync_data()
    }

    /// Ends writing: flushes, makes the content durable when `durable`, closes.
    pub(crate) fn close(&mut self, durable: bool) -> std::io::Result<()> {
        if let Some(mut w) = self.w.take() {
            w.flush()?;
            let file = w.into_inner().map_err(|e| e.into_error())?;
            if durable {
                file.sync_all()?;
            }
        }
        Ok(())
    }

    /// Closes (if not yet) and renames the file into place; with `durable`, the rename is
    /// made durable too (fsync of the folder).
    pub(crate) fn commit(mut self, durable: bool) -> std::io::Result<()> {
        self.close(durable)?;
        std::fs::rename(&self.tmp, &self.path)?;
        self.committed = true;
        if durable {
            let dir = match self.path.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            sync_dir(dir)?;
        }
        Ok(())
    }
}

impl std::io::Write for Temporary {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.buffer().write(buf)?;
        self.hasher.update(&buf[..n]);
        self.bytes += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.buffer().flush()
    }
}

impl Drop for Temporary {
    fn drop(&mut self) {
        if !self.committed {
            drop(self.w.take());
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Whether process `pid` may still be running (`/proc/PID` exists). Where `/proc` is not
/// available, every other process counts as dead: the folder's lock already keeps other
/// runs out, so only a `search` building its cache could lose its temporary (it then just
/// does not keep the cache).
fn alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    let proc = Path::new("/proc");
    proc.join("self").exists() && proc.join(pid.to_string()).exists()
}

/// The process id in a temporary name `.NAME.tmp-PID-RANDOM` (or `.NAME.tmp-PID`, as
/// earlier versions named them).
fn temporary_pid(name: &str) -> Option<u32> {
    if !name.starts_with('.') {
        return None;
    }
    let (_, tail) = name.rsplit_once(".tmp-")?;
    let (pid, rand) = match tail.split_once('-') {
        Some((p, r)) => (p, Some(r)),
        None => (tail, None),
    };
    let digits = |s: &str, hex: bool| {
        !s.is_empty()
            && s.bytes().all(|b| {
                if hex {
                    b.is_ascii_hexdigit()
                } else {
                    b.is_ascii_digit()
                }
            })
    };
    if !digits(pid, false) || rand.is_some_and(|r| !digits(r, true)) {
        return None;
    }
    pid.parse().ok()
}

/// Removes temporary files that runs of this program which are no longer running left
/// (named as [`write_atomically`] names them) from the output folder, its `pages/`, its
/// state folder and chunk records. Only regular files and links directly in those
/// folders are removed, and a `pages/` that is a link is not entered: nothing outside the
/// output folder is touched. Best effort (a read-only folder keeps them).
pub(crate) fn remove_stale_temporaries(out: &Path) {
    for dir in [
        out.to_path_buf(),
        out.join(PAGES_DIR),
        out.join(STATE_DIR),
        out.join(STATE_DIR).join("chunks"),
    ] {
        if !std::fs::symlink_metadata(&dir).is_ok_and(|m| m.is_dir()) {
            continue;
        }
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let dead = temporary_pid(&name).is_some_and(|pid| !alive(pid));
            if dead && e.file_type().is_ok_and(|t| t.is_file() || t.is_symlink()) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A staged file stands under no atlas name until it is committed, then under its own
    /// with its bytes and the entry [`write_artifact`] gives; one dropped uncommitted
    /// leaves nothing behind; a name that is not plain is refused before anything is made.
    #[test]
    fn staged_files_appear_only_when_committed() {
        let dir = std::env::temp_dir().join(format!("coupler-staged-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join(PAGES_DIR)).unwrap();
        let listing = || -> Vec<String> {
            let mut v: Vec<String> = std::fs::read_dir(dir.join(PAGES_DIR))
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            v.sort();
            v
        };
        let artifact = |name: &str, bytes: &[u8]| Artifact {
            name: name.into(),
            bytes: bytes.to_vec(),
        };
        let a = stage_artifact(&dir, &artifact("pages/a.png", b"page a")).unwrap();
        let b = stage_artifact(&dir, &artifact("pages/b.png", b"page b")).unwrap();
        assert_eq!(a.name(), "pages/a.png");
        let staged = listing();
        assert_eq!(staged.len(), 2, "{staged:?}");
        assert!(staged.iter().all(|n| n.starts_with('.')), "{staged:?}");
        assert_eq!(a.commit().unwrap(), FileEntry::of("pages/a.png", b"page a"));
        assert_eq!(std::fs::read(dir.join("pages/a.png")).unwrap(), b"page a");
        drop(b);
        assert_eq!(listing(), ["a.png"]);
        assert!(stage_artifact(&dir, &artifact("../c.png", b"c")).is_err());
        assert_eq!(listing(), ["a.png"]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn names_from_records_must_be_plain() {
        for ok in [
            "index.json",
            "manifest.json",
            "pages/hrones-nelson-0001.png",
            "pages/quick-contents-1.svg",
        ] {
            assert!(check_name(ok).is_ok(), "{ok}");
        }
        for bad in [
            "",
            "../x",
            "../../x",
            "/etc/passwd",
            "pages/../../x",
            "pages/..",
            "..",
            ".",
            "pages/",
            "pages/a/b.png",
            "other/a.png",
            "a\0b",
            "pages\\x.png",
            ".hidden",
            "pages/.index.json.tmp-1-2",
            "a b",
            &"x".repeat(201),
        ] {
            assert!(check_name(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn temporary_names_carry_the_pid_and_differ() {
        let a = temporary_name("index.json");
        let b = temporary_name("index.json");
        assert_ne!(a, b);
        assert_eq!(temporary_pid(&a), Some(std::process::id()));
        assert_eq!(temporary_pid(".index.json.tmp-123"), Some(123));
        assert_eq!(temporary_pid("index.json"), None);
        assert_eq!(temporary_pid(".x.tmp-12a"), None);
        assert_eq!(temporary_pid(".x.tmp-12-zz"), None);
    }
}
