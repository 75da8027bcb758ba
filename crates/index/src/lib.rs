//! # coupler-index
//!
//! The JSON index of an atlas: one record per curve with its measures and features,
//! written with a stable key order and number format (schema: `docs/index-schema.md`),
//! read back, and searched: composable filters over compact columns, written beside the
//! index by `generate` (`index.columns`, mapped by [`load`]) or, for an index without
//! them, saved as a cache beside it on its first search.

mod cache;
mod colfile;
mod columns;
mod key;
mod lines;
mod load;
mod page_set;
mod schema;
mod search;
mod stamp;

pub use cache::{
    CACHE_FORMAT, CACHE_MAGIC, CacheError, Column, LoadError, Section, TableSource, cache_path,
    load_table, read_container, write_container,
};
pub use colfile::{
    COLUMNS_FILE, COLUMNS_FORMAT, ColumnTable, ColumnsError, ColumnsWriter, GROUP_ROWS,
    columns_path,
};
pub use columns::TABLE_VERSION;
pub use key::IndexKey;
pub use lines::{MAX_INDEX_LINE, read_line_bounded};
pub use load::{Loaded, load};
pub use page_set::{PAGE_SET_KIND, is_page_set};
pub use schema::{
    Index, IndexCurve, IndexError, IndexSummary, PageRef, SCHEMA_VERSION, curve_line,
    write_curve_line, write_index, write_index_footer, write_index_header,
};
pub use search::{
    ArcRow, CurveRow, DEFAULT_RADIUS_TOL_PCT, Hit, Query, SearchError, SearchTable, SegmentRow,
    SortKey, SpanFilter, transmission_margin,
};
pub use stamp::{PendingStamp, SETTLED, index_key, stamp_path};
