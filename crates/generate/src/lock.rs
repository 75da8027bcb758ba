//! The output folder's lock: an advisory lock (`flock`) on `.coupler-atlas/lock`, held
//! for the whole run and released by the operating system when the process ends, however
//! it ends (exit, Ctrl-C, SIGKILL, a crash). A second run into the same folder finds it
//! held and refuses, naming the first (process id, start time, command), which the
//! holder writes into the file. The file itself stays (removing a lock file while
//! another process waits on it would let two runs in).

use crate::GenerateError;
use crate::error::io_err;
use crate::files::STATE_DIR;
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

/// A held lock on an output folder (released when dropped or when the process ends).
#[derive(Debug)]
pub struct FolderLock {
    _file: Option<File>,
}

/// "pid 123, started 2026-05-02 10:11:12 UTC, command: coupler-atlas generate …".
fn holder_text() -> String {
    let command: Vec<String> = std::env::args().collect();
    format!(
        "pid {}, started {}, command: {}",
        std::process::id(),
        utc_now(),
        command.join(" ")
    )
}

/// The current time as `YYYY-MM-DD HH:MM:SS UTC`.
fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0);
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02} UTC",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

impl FolderLock {
    /// Takes the lock of output folder `out` (whose `.coupler-atlas/` exists), or says
    /// who holds it. On a read-only folder the lock is taken on a read-only handle (and
    /// nothing is recorded in it); where the file system has no locks, the run goes on
    /// unlocked.
    pub fn acquire(out: &Path) -> Result<FolderLock, GenerateError> {
        let path = out.join(STATE_DIR).join("lock");
        let (mut file, writable) = match OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
        {
            Ok(f) => (f, true),
            Err(e) => match File::open(&path) {
                Ok(f) => (f, false),
                // A read-only folder without a lock file (made by an earlier version):
                // nothing can be written into it, so there is nothing to protect.
                Err(_) if read_only(&e) => return Ok(FolderLock { _file: None }),
                Err(_) => return Err(io_err(&path)(e)),
            },
        };
        check_not_a_link(&path, &file)?;
        match try_lock(&file) {
            Ok(true) => {}
            Ok(false) => {
                let mut text = String::new();
                let _ = (&file).take(4096).read_to_string(&mut text);
                let holder = text.trim();
                return Err(GenerateError::Busy {
                    dir: out.to_path_buf(),
                    holder: if holder.is_empty() {
                        "its details are not recorded yet".into()
                    } else {
                        holder.to_string()
                    },
                });
            }
            // No locks on this file system (some network file systems): go on.
            Err(_) => return Ok(FolderLock { _file: Some(file) }),
        }
        if writable {
            let text = holder_text();
            let _ = file
                .set_len(0)
                .and_then(|_| file.rewind())
                .and_then(|_| file.write_all(format!("{text}\n").as_bytes()));
        }
        Ok(FolderLock { _file: Some(file) })
    }
}

/// Takes an exclusive `flock` on `file` without waiting: `Ok(false)` if another process
/// holds it.
#[cfg(unix)]
fn try_lock(file: &File) -> std::io::Result<bool> {
    use rustix::fs::{FlockOperation, flock};
    match flock(file, FlockOperation::NonBlockingLockExclusive) {
        Ok(()) => Ok(true),
        Err(e) if e == rustix::io::Errno::WOULDBLOCK => Ok(false),
        Err(e) => Err(e.into()),
    }
}

/// Elsewhere the run goes on unlocked.
#[cfg(not(unix))]
fn try_lock(_: &File) -> std::io::Result<bool> {
    Err(std::io::Error::other("no advisory locks here"))
}

/// Whether an error says the folder cannot be written (permissions, a read-only mount).
fn read_only(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::{PermissionDenied, ReadOnlyFilesystem};
    matches!(e.kind(), PermissionDenied | ReadOnlyFilesystem)
}

/// Refuses a lock file that is a symbolic link (writing the holder into it would write
/// through the link) or that was swapped for another file while it was opened.
fn check_not_a_link(path: &Path, file: &File) -> Result<(), GenerateError> {
    let link = std::fs::symlink_metadata(path).map_err(io_err(path))?;
    let bad = || GenerateError::NotAFolder {
        path: PathBuf::from(path),
    };
    if !link.is_file() {
        return Err(bad());
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let opened = file.metadata().map_err(io_err(path))?;
        if (opened.dev(), opened.ino()) != (link.dev(), link.ino()) {
            return Err(bad());
        }
    }
    #[cfg(not(unix))]
    let _ = file;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_is_refused_naming_the_first() {
        let dir = std::env::temp_dir().join(format!("coupler-lock-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join(STATE_DIR)).unwrap();
        let first = FolderLock::acquire(&dir).unwrap();
        let e = FolderLock::acquire(&dir).unwrap_err().to_string();
        assert!(
            e.contains(&format!("pid {}", std::process::id())) && e.contains("UTC"),
            "{e}"
        );
        drop(first);
        let _again = FolderLock::acquire(&dir).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn dates_are_civil() {
        let t = utc_now();
        assert!(
            t.starts_with("20") && t.ends_with(" UTC") && t.len() == 23,
            "{t}"
        );
    }
}
