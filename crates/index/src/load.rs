//! Loading an index for searching: its columns file mapped when it has one that is this
//! index's and intact, else its search cache, else the index itself (parsed, and the
//! cache written). See [`load`].

use crate::cache::{LoadError, TableSource, load_table_keyed, open_file};
use crate::colfile::{ColumnTable, columns_path};
use crate::key::IndexKey;
use crate::{Query, SearchTable};
use std::path::{Path, PathBuf};

enum Source {
    Columns(ColumnTable),
    Table(SearchTable),
}

/// An index ready to answer queries: see [`load`].
pub struct Loaded {
    source: Source,
    from: TableSource,
    note: Option<String>,
    index: PathBuf,
    use_cache: bool,
    key: Option<IndexKey>,
}

/// Opens `index` for searching. With `use_cache`: its columns file (`index.columns`,
/// written by `generate`) if it is there, made for this index's content and intact
/// (checked as `crate::colfile` describes; the index's key comes from its stamp, so a
/// search does not hash the index); else the search cache (`INDEX.search`) if it
/// verifies; else the index, parsed (and the cache written). Without `use_cache` the index
/// is parsed and nothing beside it is read or written.
pub fn load(index: &Path, use_cache: bool) -> Result<Loaded, LoadError> {
    let read_err = |source| LoadError::Read {
        path: index.to_path_buf(),
        source,
    };
    let mut loaded = Loaded {
        source: Source::Table(SearchTable::default()),
        from: TableSource::Index,
        note: None,
        index: index.to_path_buf(),
        use_cache,
        key: None,
    };
    if use_cache {
        let file = open_file(index).map_err(read_err)?;
        let (key, pending) = crate::stamp::index_key(&file, index).map_err(read_err)?;
        loaded.key = Some(key);
        let columns = columns_path(index);
        if columns.exists() {
            match ColumnTable::open(&columns, key) {
                Ok(t) => {
                    loaded.source = Source::Columns(t);
                    loaded.from = TableSource::Columns;
                    // Columns made for this content: the file is an index; stamp it.
                    if let Some(p) = pending {
                        p.write(&file);
                    }
                    return Ok(loaded);
                }
                Err(e) => loaded.note = Some(format!("{}: {e}", columns.display())),
            }
        }
        loaded.rebuild()?;
        // Only a file accepted as an index (its cache verified, or it parsed) is stamped.
        if let Some(p) = pending {
            p.write(&file);
        }
        return Ok(loaded);
    }
    loaded.rebuild()?;
    Ok(loaded)
}

impl Loaded {
    /// A table already in memory (a page set's, or one built by the caller) as a
    /// [`Loaded`] that answers from it.
    pub fn from_table(table: SearchTable) -> Loaded {
        Loaded {
            source: Source::Table(table),
            from: TableSource::Index,
            note: None,
            index: PathBuf::new(),
            use_cache: false,
            key: None,
        }
    }

    /// Loads from the cache or the index (the columns not being usable).
    fn rebuild(&mut self) -> Result<(), LoadError> {
        let (t, from) = load_table_keyed(&self.index, self.use_cache, self.key)?;
        self.source = Source::Table(t);
        self.from = from;
        Ok(())
    }

    /// Number of curves.
    pub fn curves(&self) -> usize {
        match &self.source {
            Source::Columns(c) => c.len(),
            Source::Table(t) => t.rows.len(),
        }
    }

    /// Where the answers come from (so far).
    pub fn source(&self) -> TableSource {
        self.from
    }

    /// Why the columns file beside the index was not used, if it was there and was not.
    pub fn note(&self) -> Option<&str> {
        self.note.as_deref()
    }

    /// The extents (offset, length) of `index.columns` read so far, when the answers come
    /// from it (see `ColumnTable::extents_read`).
    pub fn extents_read(&self) -> Option<Vec<(u64, u64)>> {
        match &self.source {
            Source::Columns(c) => Some(c.extents_read()),
            Source::Table(_) => None,
        }
    }

    /// The curves that pass `q` (the best `q.limit` by its sort), as a table of their own
    /// on which `q` gives the same hits as on the whole index, and how many curves passed.
    /// Columns found damaged while reading are given up (see [`Loaded::note`]) and the
    /// answer comes from the cache or the index.
    pub fn select(&mut self, q: &Query) -> Result<(SearchTable, usize), LoadError> {
        if let Source::Columns(c) = &self.source {
            match c.select(q) {
                Ok(r) => return Ok(r),
                Err(e) => {
                    self.note = Some(format!("{}: {e}", columns_path(&self.index).display()));
                    self.rebuild()?;
                }
            }
        }
        let Source::Table(t) = &self.source else {
            unreachable!("rebuilt as a table")
        };
        let (hits, total) = t.search_counted(q);
        let mut rows: Vec<usize> = hits.iter().map(|h| h.row).collect();
        rows.sort_unstable();
        Ok((t.subset(&rows), total))
    }

    /// The curve of id `id` as a table of one row (empty if there is none).
    pub fn find(&mut self, id: u64) -> Result<SearchTable, LoadError> {
        if let Source::Columns(c) = &self.source {
            match c.find(id) {
                Ok(t) => return Ok(t.unwrap_or_default()),
                Err(e) => {
                    self.note = Some(format!("{}: {e}", columns_path(&self.index).display()));
                    self.rebuild()?;
                }
            }
        }
        let Source::Table(t) = &self.source else {
            unreachable!("rebuilt as a table")
        };
        let rows: Vec<usize> = t.rows.iter().position(|r| r.id == id).into_iter().collect();
        Ok(t.subset(&rows))
    }
}
