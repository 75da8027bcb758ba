//! # coupler-index
//!
//! The JSON index of an atlas: one record per curve with its measures and features,
//! written with a stable key order and number format (schema: `docs/index-schema.md`),
//! read back, and searched: composable filters over a compact columnar table, saved as a
//! cache beside the index.

mod cache;
mod columns;
mod lines;
mod page_set;
mod schema;
mod search;

pub use cache::{
    CACHE_FORMAT, CACHE_MAGIC, CacheError, Column, IndexKey, LoadError, Section, TableSource,
    cache_path, load_table, read_container, write_container,
};
pub use columns::TABLE_VERSION;
pub use lines::{MAX_INDEX_LINE, read_line_bounded};
pub use page_set::{PAGE_SET_KIND, is_page_set};
pub use schema::{
    Index, IndexCurve, IndexError, IndexSummary, PageRef, SCHEMA_VERSION, curve_line,
    write_curve_line, write_index, write_index_footer, write_index_header,
};
pub use search::{
    ArcRow, CurveRow, DEFAULT_RADIUS_TOL_PCT, Hit, Query, SearchError, SearchTable, SegmentRow,
    SortKey, SpanFilter, transmission_margin,
};
