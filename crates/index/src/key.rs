//! What identifies an index's content ([`IndexKey`]), and how the files kept beside an
//! index (the search cache, the stamp) are written: below both the cache and the stamp.

use std::io::{Read, Write};
use std::path::Path;

/// What identifies an index's content: its length and XXH3-128.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IndexKey {
    /// Length in bytes.
    pub bytes: u64,
    /// XXH3-128 of the whole content.
    pub hash: u128,
}

impl IndexKey {
    /// The key of everything `r` yields (read in 1 MiB blocks).
    pub fn of_reader(mut r: impl Read) -> std::io::Result<IndexKey> {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        let mut buf = vec![0u8; 1 << 20];
        let mut bytes = 0u64;
        loop {
            let n = match r.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            h.update(&buf[..n]);
            bytes += n as u64;
        }
        Ok(IndexKey {
            bytes,
            hash: h.digest128(),
        })
    }
}

/// Writes `path` under a new temporary name beside it, created exclusively
/// (unpredictable, so a planted file or link is never opened), then renamed into place.
/// Best effort: on any error nothing is left behind.
pub(crate) fn write_beside(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) {
    use std::hash::{BuildHasher, Hasher};
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u128(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos()),
    );
    let tmp = path.with_file_name(format!(
        ".{name}.tmp-{}-{:016x}",
        std::process::id(),
        h.finish()
    ));
    let Ok(file) = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
    else {
        return;
    };
    let mut w = std::io::BufWriter::new(file);
    let ok = write(&mut w).is_ok() && w.flush().is_ok();
    drop(w);
    if !(ok && std::fs::rename(&tmp, path).is_ok()) {
        let _ = std::fs::remove_file(&tmp);
    }
}
