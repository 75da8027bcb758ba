//! The search cache: a [`SearchTable`] saved beside its index as `INDEX.search`, so that
//! later searches skip parsing the index. It is never trusted: it is used only if it
//! verifies completely, and otherwise rebuilt from the index (and rewritten); a cache
//! that cannot be written is simply not kept.
//!
//! ## File format (version 2, little-endian)
//!
//! A generic container of fixed-width columns, so that any set of columns can be wrapped
//! and each column can be memory-mapped (it starts on a 64-byte boundary) once the header
//! has been checked:
//!
//! | bytes | field |
//! |---|---|
//! | 0–15 | magic `CPLATLAS-SEARCH\n` |
//! | 16–19 | container format (2) |
//! | 20–23 | table version ([`crate::TABLE_VERSION`]: the column set) |
//! | 24–27 | number of sections `n` (at most 64) |
//! | 28–31 | 0 |
//! | 32–39 | the index's length in bytes |
//! | 40–55 | the index's XXH3-128 (of its whole content) |
//! | 56–63 | payload offset: `128 + 32·n` rounded up to 64 |
//! | 64–71 | payload length: the file's length minus the payload offset |
//! | 72–87 | XXH3-128 of the payload |
//! | 88–95 | XXH3-64 of bytes 0–87 and the section table |
//! | 96–127 | 0 |
//! | 128… | section table: per section a tag (8 bytes, ASCII, NUL-padded), element size (u32), 0 (u32), offset from the start of the file (u64, a multiple of 64), element count (u64) |
//! | payload | the sections in table order, each padded with zeros to 64 bytes |
//!
//! Reading checks, before allocating anything from the file's numbers: the length, magic,
//! versions, section count, the payload offset and length, the header's hash, every
//! section's size (element size × count, overflow-checked), alignment, order and extent
//! inside the file; then the index key (the index's length and content hash: an index
//! replaced by another of the same size and time is never answered from the old cache);
//! then the payload's hash. Only then are the columns decoded, and every cross-reference
//! (a row's segments, arcs, page) is checked against the columns' lengths.

use crate::SearchTable;
use crate::key::{IndexKey, write_beside};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Where a [`SearchTable`] came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableSource {
    /// Read from the cache beside the index.
    Cache,
    /// Parsed from the index itself.
    Index,
    /// Mapped from the index's columns file (`index.columns`).
    Columns,
}

impl TableSource {
    /// `"cache"` or `"index"`.
    pub fn name(self) -> &'static str {
        match self {
            TableSource::Cache => "cache",
            TableSource::Index => "index",
            TableSource::Columns => "columns",
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

/// Why a cache was not used (it is then rebuilt).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("search cache not used: {0}")]
pub struct CacheError(pub String);

fn bad(m: impl Into<String>) -> CacheError {
    CacheError(m.into())
}

/// The container's magic bytes.
pub const CACHE_MAGIC: [u8; 16] = *b"CPLATLAS-SEARCH\n";
/// The container's format version.
pub const CACHE_FORMAT: u32 = 2;
const HEADER: usize = 128;
const ENTRY: usize = 32;
const MAX_SECTIONS: usize = 64;
const ALIGN: u64 = 64;
/// Largest element (bytes) a section may declare.
const MAX_ELEMENT: u32 = 1 << 16;

fn align(x: u64) -> u64 {
    x.div_ceil(ALIGN) * ALIGN
}

/// One column to write: a tag (at most 8 ASCII bytes), its element size, and its bytes
/// (a whole number of elements).
pub struct Column {
    /// Tag, e.g. `row.id`.
    pub tag: &'static str,
    /// Bytes per element.
    pub element: u32,
    /// The elements, little-endian, back to back.
    pub data: Vec<u8>,
}

/// One column as read (a slice of the file's bytes).
#[derive(Clone, Copy, Debug)]
pub struct Section<'a> {
    /// Tag.
    pub tag: [u8; 8],
    /// Bytes per element.
    pub element: u32,
    /// Elements.
    pub count: u64,
    /// The bytes (`element × count`).
    pub data: &'a [u8],
}

fn tag_bytes(tag: &str) -> [u8; 8] {
    let mut t = [0u8; 8];
    for (d, s) in t.iter_mut().zip(tag.bytes()) {
        *d = s;
    }
    t
}

/// Writes a container of `columns` for the index `key` and table version `table`.
pub fn write_container(
    w: &mut impl Write,
    key: IndexKey,
    table: u32,
    columns: &[Column],
) -> std::io::Result<()> {
    assert!(columns.len() <= MAX_SECTIONS, "too many cache columns");
    let n = columns.len();
    let payload_offset = align((HEADER + ENTRY * n) as u64);
    let mut table_bytes = Vec::with_capacity(ENTRY * n);
    let mut offset = payload_offset;
    let mut payload_hash = xxhash_rust::xxh3::Xxh3::new();
    for c in columns {
        let count = c.data.len() as u64 / u64::from(c.element.max(1));
        table_bytes.extend_from_slice(&tag_bytes(c.tag));
        table_bytes.extend_from_slice(&c.element.to_le_bytes());
        table_bytes.extend_from_slice(&0u32.to_le_bytes());
        table_bytes.extend_from_slice(&offset.to_le_bytes());
        table_bytes.extend_from_slice(&count.to_le_bytes());
        let padded = align(c.data.len() as u64);
        payload_hash.update(&c.data);
        payload_hash.update(&vec![0u8; (padded - c.data.len() as u64) as usize]);
        offset += padded;
    }
    let mut h = [0u8; HEADER];
    h[0..16].copy_from_slice(&CACHE_MAGIC);
    h[16..20].copy_from_slice(&CACHE_FORMAT.to_le_bytes());
    h[20..24].copy_from_slice(&table.to_le_bytes());
    h[24..28].copy_from_slice(&(n as u32).to_le_bytes());
    h[32..40].copy_from_slice(&key.bytes.to_le_bytes());
    h[40..56].copy_from_slice(&key.hash.to_le_bytes());
    h[56..64].copy_from_slice(&payload_offset.to_le_bytes());
    h[64..72].copy_from_slice(&(offset - payload_offset).to_le_bytes());
    h[72..88].copy_from_slice(&payload_hash.digest128().to_le_bytes());
    let mut hh = xxhash_rust::xxh3::Xxh3::new();
    hh.update(&h[..88]);
    hh.update(&table_bytes);
    h[88..96].copy_from_slice(&hh.digest().to_le_bytes());
    w.write_all(&h)?;
    w.write_all(&table_bytes)?;
    w.write_all(&vec![
        0u8;
        (payload_offset as usize) - HEADER - table_bytes.len()
    ])?;
    for c in columns {
        w.write_all(&c.data)?;
        let pad = align(c.data.len() as u64) - c.data.len() as u64;
        w.write_all(&vec![0u8; pad as usize])?;
    }
    Ok(())
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap_or([0; 4]))
}
fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap_or([0; 8]))
}
fn u128_at(b: &[u8], at: usize) -> u128 {
    u128::from_le_bytes(b[at..at + 16].try_into().unwrap_or([0; 16]))
}

/// Checks a container (everything listed in the module's documentation) and returns its
/// table version and sections, or why it is not usable. Allocates nothing but the list
/// of at most 64 sections.
pub fn read_container(b: &[u8], key: IndexKey) -> Result<(u32, Vec<Section<'_>>), CacheError> {
    if b.len() < HEADER {
        return Err(bad("shorter than its header"));
    }
    if b[0..16] != CACHE_MAGIC {
        return Err(bad("not a search cache"));
    }
    if u32_at(b, 16) != CACHE_FORMAT {
        return Err(bad(format!("container format {}", u32_at(b, 16))));
    }
    let table = u32_at(b, 20);
    let n = u32_at(b, 24) as usize;
    if n > MAX_SECTIONS {
        return Err(bad("too many sections"));
    }
    let payload_offset = u64_at(b, 56);
    if payload_offset != align((HEADER + ENTRY * n) as u64) || payload_offset > b.len() as u64 {
        return Err(bad("payload offset"));
    }
    if u64_at(b, 64) != b.len() as u64 - payload_offset {
        return Err(bad("length (cut or grown)"));
    }
    let entries = &b[HEADER..HEADER + ENTRY * n];
    let mut hh = xxhash_rust::xxh3::Xxh3::new();
    hh.update(&b[..88]);
    hh.update(entries);
    if hh.digest() != u64_at(b, 88) {
        return Err(bad("header checksum"));
    }
    if (IndexKey {
        bytes: u64_at(b, 32),
        hash: u128_at(b, 40),
    }) != key
    {
        return Err(bad("made from another index (content hash differs)"));
    }
    let mut sections = Vec::with_capacity(n);
    let mut next = payload_offset;
    for e in entries.chunks_exact(ENTRY) {
        let mut tag = [0u8; 8];
        tag.copy_from_slice(&e[0..8]);
        let element = u32_at(e, 8);
        let (offset, count) = (u64_at(e, 16), u64_at(e, 24));
        if element == 0 || element > MAX_ELEMENT || u32_at(e, 12) != 0 {
            return Err(bad("section element size"));
        }
        let len = count
            .checked_mul(u64::from(element))
            .filter(|&l| l <= b.len() as u64)
            .ok_or_else(|| bad("section size"))?;
        let end = offset
            .checked_add(len)
            .filter(|&e| e <= b.len() as u64)
            .ok_or_else(|| bad("section extent"))?;
        if offset != next {
            return Err(bad("section offset"));
        }
        next = align(end);
        sections.push(Section {
            tag,
            element,
            count,
            data: &b[offset as usize..end as usize],
        });
    }
    if next != b.len() as u64 {
        return Err(bad("sections do not end the file"));
    }
    if xxhash_rust::xxh3::xxh3_128(&b[payload_offset as usize..]) != u128_at(b, 72) {
        return Err(bad("payload checksum"));
    }
    Ok((table, sections))
}

/// The cache file of `index`: `INDEX.search`.
pub fn cache_path(index: &Path) -> PathBuf {
    let mut cache = index.as_os_str().to_owned();
    cache.push(".search");
    PathBuf::from(cache)
}

/// Opens `path` if it is a regular file (not a device, pipe or folder, whatever a link
/// points at).
pub(crate) fn open_file(path: &Path) -> std::io::Result<std::fs::File> {
    let f = std::fs::File::open(path)?;
    if !f.metadata()?.is_file() {
        return Err(std::io::Error::other("not a regular file"));
    }
    Ok(f)
}

/// The cache of `index` if it is there and verifies for `key`.
fn read_cache(cache: &Path, key: IndexKey) -> Result<SearchTable, CacheError> {
    let f = open_file(cache).map_err(|e| bad(e.to_string()))?;
    let len = f.metadata().map_err(|e| bad(e.to_string()))?.len();
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(len as usize)
        .map_err(|_| bad("too large to read"))?;
    f.take(len)
        .read_to_end(&mut bytes)
        .map_err(|e| bad(e.to_string()))?;
    SearchTable::from_cache_bytes(&bytes, key)
}

/// Writes the cache beside the index (best effort).
fn write_cache(cache: &Path, table: &SearchTable, key: IndexKey) {
    write_beside(cache, |w| table.write_cache(w, key));
}

/// A reader that hashes what passes through it.
struct Hashing<R> {
    inner: R,
    hasher: xxhash_rust::xxh3::Xxh3,
    bytes: u64,
}

impl<R: Read> Read for Hashing<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.hasher.update(&buf[..n]);
        self.bytes += n as u64;
        Ok(n)
    }
}

/// Loads the search table of `index`: from its cache if the cache verifies for the
/// index's current content, else by parsing the index (and writing the cache, best
/// effort) when `use_cache`; without `use_cache` the cache is neither read nor written.
/// The index's content key comes from its stamp when it has one (`crate::stamp`), so a
/// cached load does not hash the index.
pub fn load_table(index: &Path, use_cache: bool) -> Result<(SearchTable, TableSource), LoadError> {
    load_table_keyed(index, use_cache, None)
}

/// [`load_table`], the index's content key already known (or not: `None`).
pub(crate) fn load_table_keyed(
    index: &Path,
    use_cache: bool,
    key: Option<IndexKey>,
) -> Result<(SearchTable, TableSource), LoadError> {
    let read_err = |source| LoadError::Read {
        path: index.to_path_buf(),
        source,
    };
    let cache = cache_path(index);
    // The stamp of an index hashed here is written only once the file has proved to be
    // an index (its cache verified, or it parsed).
    let mut pending = None;
    if use_cache {
        let key = match key {
            Some(k) => k,
            None => {
                let file = open_file(index).map_err(read_err)?;
                let (k, p) = crate::stamp::index_key(&file, index).map_err(read_err)?;
                pending = p.map(|p| (file, p));
                k
            }
        };
        if let Ok(t) = read_cache(&cache, key) {
            if let Some((file, p)) = pending {
                p.write(&file);
            }
            return Ok((t, TableSource::Cache));
        }
    }
    // Streamed line by line: memory holds the table and one batch of lines, not the
    // whole index (2 GB for a million curves with features). Hashed as it is parsed, so
    // the cache is keyed by exactly the content it was made from.
    let mut reader = Hashing {
        inner: open_file(index).map_err(read_err)?,
        hasher: xxhash_rust::xxh3::Xxh3::new(),
        bytes: 0,
    };
    let table =
        SearchTable::from_index_reader(std::io::BufReader::with_capacity(1 << 20, &mut reader))
            .map_err(|source| LoadError::Invalid {
                path: index.to_path_buf(),
                source,
            })?;
    if use_cache {
        let key = IndexKey {
            bytes: reader.bytes,
            hash: reader.hasher.digest128(),
        };
        write_cache(&cache, &table, key);
        if let Some((file, p)) = pending {
            p.write(&file);
        }
    }
    Ok((table, TableSource::Index))
}
