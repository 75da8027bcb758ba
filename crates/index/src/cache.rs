//! The search cache: a [`SearchTable`] saved beside its index as `INDEX.search`, keyed by
//! the index's length and modification time, so that later searches skip parsing the
//! index. Best effort: a cache that is missing, stale or unreadable is rebuilt from the
//! index (and rewritten); a cache that cannot be written is simply not kept.

use crate::SearchTable;
use std::path::{Path, PathBuf};

/// Where a [`SearchTable`] came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableSource {
    /// Read from the cache beside the index.
    Cache,
    /// Parsed from the index itself.
    Index,
}

impl TableSource {
    /// `"cache"` or `"index"`.
    pub fn name(self) -> &'static str {
        match self {
            TableSource::Cache => "cache",
            TableSource::Index => "index",
        }
    }
}

/// Why an index could not be loaded for searching.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The index file could not be read.
    #[error("cannot read index {}: {source}", path.display())]
    Read {
        /// The index.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The index is not a valid index.
    #[error("{}: {source}", path.display())]
    Invalid {
        /// The index.
        path: PathBuf,
        /// What is wrong.
        #[source]
        source: crate::SearchError,
    },
}

/// The cache file of `index`: `INDEX.search`.
pub fn cache_path(index: &Path) -> PathBuf {
    let mut cache = index.as_os_str().to_owned();
    cache.push(".search");
    PathBuf::from(cache)
}

fn cache_key(path: &Path) -> Result<[u64; 2], LoadError> {
    let meta = std::fs::metadata(path).map_err(|source| LoadError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let mtime = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0);
    Ok([meta.len(), mtime])
}

/// Loads the search table of `index`: from its cache if the cache matches the index,
/// else by parsing the index (and writing the cache, best effort) when `use_cache`;
/// without `use_cache` the cache is neither read nor written.
pub fn load_table(index: &Path, use_cache: bool) -> Result<(SearchTable, TableSource), LoadError> {
    let key = cache_key(index)?;
    let cache = cache_path(index);
    if use_cache {
        if let Ok(bytes) = std::fs::read(&cache) {
            if let Ok(t) = SearchTable::from_bytes(&bytes, key) {
                return Ok((t, TableSource::Cache));
            }
        }
    }
    // Streamed line by line: memory holds the table and one batch of lines, not the
    // whole index (2 GB for a million curves with features).
    let file = std::fs::File::open(index).map_err(|source| LoadError::Read {
        path: index.to_path_buf(),
        source,
    })?;
    let table = SearchTable::from_index_reader(std::io::BufReader::with_capacity(1 << 20, file))
        .map_err(|source| LoadError::Invalid {
            path: index.to_path_buf(),
            source,
        })?;
    if use_cache {
        let tmp = cache.with_extension("search.tmp");
        if std::fs::write(&tmp, table.to_bytes(key)).is_ok() {
            let _ = std::fs::rename(&tmp, &cache);
        }
    }
    Ok((table, TableSource::Index))
}
