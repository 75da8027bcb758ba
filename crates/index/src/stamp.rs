//! The index's content key without reading the index: a small stamp beside it
//! (`INDEX.stamp`) that remembers which file (device, inode, size, modification and
//! change times) had which content hash when it was last hashed whole. A search whose
//! index still has that identity takes the key from the stamp; any other index (changed,
//! replaced, copied, touched) is hashed whole again, and the stamp rewritten.
//!
//! What it trusts, and why that is enough: the change time (`ctime`) cannot be set by a
//! user (every write, rename onto the name, `chmod` or `touch` sets it to the clock), so
//! an index whose device, inode, size, mtime and ctime all equal the stamp's has not been
//! written since it was hashed — unless the write came within the file system's timestamp
//! resolution of the hash (a few milliseconds on Linux), which is why a stamp is written
//! only for an index unchanged for [`SETTLED`] (until then every search hashes it: the
//! "racy" case git's index knows too), or unless someone who can set the clock or write
//! the disk's blocks directly forged it (they can as well rewrite the index and its
//! columns). The stamp is checksummed (a damaged one is ignored and rewritten) and written
//! under a new exclusive temporary name, then renamed, like the search cache.

use crate::key::IndexKey;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

/// How long an index must have been unchanged before its stamp is written.
pub const SETTLED: Duration = Duration::from_secs(2);

const MAGIC: [u8; 16] = *b"CPLATLAS-STAMP1\n";
const LEN: usize = 96;

/// The stamp file of `index`: `INDEX.stamp`.
pub fn stamp_path(index: &Path) -> PathBuf {
    let mut p = index.as_os_str().to_owned();
    p.push(".stamp");
    PathBuf::from(p)
}

/// A file's identity as `fstat` gives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Identity([u64; 7]);

impl Identity {
    #[cfg(unix)]
    fn of(m: &std::fs::Metadata) -> Option<Identity> {
        use std::os::unix::fs::MetadataExt;
        Some(Identity([
            m.dev(),
            m.ino(),
            m.len(),
            m.mtime() as u64,
            m.mtime_nsec() as u64,
            m.ctime() as u64,
            m.ctime_nsec() as u64,
        ]))
    }

    /// Without an inode and a change time the identity is too weak: never stamped.
    #[cfg(not(unix))]
    fn of(_: &std::fs::Metadata) -> Option<Identity> {
        None
    }

    fn encode(&self, key: IndexKey) -> [u8; LEN] {
        let mut b = [0u8; LEN];
        b[0..16].copy_from_slice(&MAGIC);
        for (k, f) in self.0.iter().enumerate() {
            b[16 + 8 * k..24 + 8 * k].copy_from_slice(&f.to_le_bytes());
        }
        b[72..88].copy_from_slice(&key.hash.to_le_bytes());
        let sum = xxhash_rust::xxh3::xxh3_64(&b[..88]);
        b[88..96].copy_from_slice(&sum.to_le_bytes());
        b
    }
}

/// The key a stamp holds for a file of identity `id`, if the stamp is intact and is this
/// file's.
fn read_stamp(path: &Path, id: Identity) -> Option<IndexKey> {
    let f = std::fs::File::open(path).ok()?;
    if !f.metadata().ok()?.is_file() {
        return None;
    }
    let mut b = Vec::with_capacity(LEN + 1);
    f.take(LEN as u64 + 1).read_to_end(&mut b).ok()?;
    if b.len() != LEN || b[0..16] != MAGIC {
        return None;
    }
    let sum = u64::from_le_bytes(b[88..96].try_into().ok()?);
    if xxhash_rust::xxh3::xxh3_64(&b[..88]) != sum {
        return None;
    }
    let stamped: Vec<u64> = b[16..72]
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
        .collect();
    if stamped[..] != id.0[..] {
        return None;
    }
    Some(IndexKey {
        bytes: id.0[2],
        hash: u128::from_le_bytes(b[72..88].try_into().ok()?),
    })
}

/// Writes the stamp (best effort: a folder that cannot be written keeps none).
fn write_stamp(path: &Path, id: Identity, key: IndexKey) {
    crate::key::write_beside(path, |w| w.write_all(&id.encode(key)));
}

/// Whether the file was last modified and changed at least [`SETTLED`] ago.
fn settled(id: &Identity) -> bool {
    let at = |secs: u64, nanos: u64| {
        SystemTime::UNIX_EPOCH
            .checked_add(Duration::new(secs, nanos.min(999_999_999) as u32))
            .is_some_and(|t| {
                SystemTime::now()
                    .duration_since(t)
                    .is_ok_and(|age| age >= SETTLED)
            })
    };
    at(id.0[3], id.0[4]) && at(id.0[5], id.0[6])
}

/// A stamp not yet written: the identity `index` had when it was hashed whole. Written
/// by [`PendingStamp::write`] only once the caller has found the file to be an index (a
/// file refused as not an index gets no stamp beside it).
#[must_use]
pub struct PendingStamp {
    stamp: PathBuf,
    id: Identity,
    key: IndexKey,
}

impl PendingStamp {
    /// Writes the stamp if `file` is still the file that was hashed (size and times
    /// unchanged) and has settled; best effort.
    pub fn write(self, file: &std::fs::File) {
        let now = file.metadata().ok().and_then(|m| Identity::of(&m));
        if now == Some(self.id) && self.key.bytes == self.id.0[2] && settled(&self.id) {
            write_stamp(&self.stamp, self.id, self.key);
        }
    }
}

/// The content key of the open index `file` (at `index`): from its stamp if the stamp is
/// this file's, else by hashing the file whole, with the stamp to write
/// ([`PendingStamp::write`]) once the caller has accepted the file as an index. Any file
/// an atlas's manifest lists by size and XXH3-128 can be keyed the same way (`match`
/// verifies `shapes.bin` with it, its stamp `shapes.bin.stamp`).
pub fn index_key(
    file: &std::fs::File,
    index: &Path,
) -> std::io::Result<(IndexKey, Option<PendingStamp>)> {
    let meta = file.metadata()?;
    let id = Identity::of(&meta);
    let stamp = stamp_path(index);
    if let Some(key) = id.and_then(|id| read_stamp(&stamp, id)) {
        return Ok((key, None));
    }
    let key = IndexKey::of_file(file)?;
    Ok((key, id.map(|id| PendingStamp { stamp, id, key })))
}
