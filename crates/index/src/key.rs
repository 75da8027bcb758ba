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

impl IndexKey {
    /// The key of the whole of `file` (its length as `fstat` gives it now), hashed in
    /// place through a read-only memory map: the same key as [`IndexKey::of_reader`]
    /// (XXH3-128 one-shot and streaming agree), without copying the file through a
    /// buffer (on a 2.5 GB index that copy was most of a first search's time). A file
    /// cut short in place while it is hashed stops the process (`SIGBUS`: see
    /// `coupler-mapped`); the program only ever replaces an index by renaming.
    pub fn of_file(file: &std::fs::File) -> std::io::Result<IndexKey> {
        let m = coupler_mapped::Mapped::of_file(file)?;
        Ok(IndexKey {
            bytes: m.len() as u64,
            hash: xxhash_rust::xxh3::xxh3_128(&m),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mapped_and_streamed_keys_agree() {
        let dir = std::env::temp_dir().join(format!("coupler-key-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // Longer than the streaming hasher's internal buffer, of no round length.
        let data: Vec<u8> = (0..3_000_017u32).map(|i| (i % 251) as u8).collect();
        for (name, bytes) in [("big", &data[..]), ("empty", &[][..])] {
            let p = dir.join(name);
            std::fs::write(&p, bytes).unwrap();
            let f = std::fs::File::open(&p).unwrap();
            assert_eq!(
                IndexKey::of_file(&f).unwrap(),
                IndexKey::of_reader(bytes).unwrap(),
                "{name}"
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
