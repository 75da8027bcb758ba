//! The search columns (`index.columns`, format: `coupler_index::ColumnsWriter`): written
//! right after the index from the same verified chunk records, parsed in parallel on the
//! job's threads, one group of rows in memory at a time; listed in the manifest with the
//! other files. `search` maps it instead of parsing the index.

use crate::files::{FileEntry, write_atomically};
use crate::{GenerateError, Job};
use coupler_index::{COLUMNS_FILE, ColumnsWriter, IndexKey};
use std::io::Write;

/// A writer that hashes (XXH3-128) and counts what passes through it.
struct Hashing<W> {
    inner: W,
    hasher: xxhash_rust::xxh3::Xxh3,
    bytes: u64,
}

impl<W: Write> Write for Hashing<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.hasher.update(&buf[..n]);
        self.bytes += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// Writes `index.columns` into `job.out` for the index just written (`index`, its entry)
/// from the run's verified chunk records, and returns its entry. `read_chunk(c, sink)`
/// passes chunk `c`'s curve lines to `sink` in order (the caller owns the record format),
/// or says why it cannot.
pub(crate) fn write_columns(
    job: &Job,
    index: &FileEntry,
    read_chunk: impl Fn(u64, &mut dyn FnMut(&str) -> std::io::Result<()>) -> Result<(), String> + Sync,
) -> Result<FileEntry, GenerateError> {
    let path = job.out.join(COLUMNS_FILE);
    let io = |source| GenerateError::Io {
        path: path.clone(),
        source,
    };
    let index_key = IndexKey {
        bytes: index.bytes,
        hash: u128::from_str_radix(&index.xxh3, 16).map_err(|e| io(std::io::Error::other(e)))?,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(job.jobs)
        .build()
        .map_err(|e| io(std::io::Error::other(e)))?;
    let mut entry = None;
    pool.install(|| {
        write_atomically(&path, |w| {
            let mut cols = ColumnsWriter::new(Hashing {
                inner: w,
                hasher: xxhash_rust::xxh3::Xxh3::new(),
                bytes: 0,
            })?;
            for c in 0..job.chunk_count() {
                let mut sink = |line: &str| cols.push_line(line);
                read_chunk(c, &mut sink).map_err(|p| {
                    std::io::Error::other(format!(
                        "chunk {c} changed while writing the search columns: {p}"
                    ))
                })?;
            }
            let h = cols.finish(index_key)?;
            entry = Some(FileEntry {
                name: COLUMNS_FILE.to_string(),
                bytes: h.bytes,
                xxh3: format!("{:032x}", h.hasher.digest128()),
            });
            Ok(())
        })
    })?;
    entry.ok_or_else(|| io(std::io::Error::other("the search columns were not written")))
}
