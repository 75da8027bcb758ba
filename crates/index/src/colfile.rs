//! The search columns of an index (`index.columns`, beside `index.json`), written by
//! `generate` as it writes the index ([`ColumnsWriter`]) and searched in place through a
//! read-only memory map ([`ColumnTable`]): no parse, no copy, and memory that does not
//! grow with the index (the pages a search touches are the page cache's).
//!
//! ## File format (version 1, little-endian)
//!
//! The rows are cut into **groups** of [`GROUP_ROWS`] curves; each group holds its rows'
//! 26 columns (the search cache's, [`crate::TABLE_VERSION`]) and those rows' straight
//! segments and arcs, each column in its own **chunk** starting on a 64-byte boundary,
//! padded with zeros. Every chunk has its own XXH3-64 in the directory, so a search
//! checks exactly the chunks it reads, once each, and a writer holds one group at a time.
//!
//! | bytes | field |
//! |---|---|
//! | 0–15 | magic `CPLATLAS-COLUMN\n` |
//! | 16–19 | format (1) |
//! | 20–23 | table version |
//! | 24–63 | 0 |
//! | 64… | the groups' chunks, then the page names' two chunks (offsets: `u64` × (pages + 1); text) |
//! | directory | per group 48 bytes (rows `u32`, 0 `u32`, first row, first segment, segments, first arc, arcs: `u64` each) and 26 × 24 bytes (chunk offset, length, XXH3-64: `u64` each); then the page chunks' 2 × 24 bytes |
//! | last 128 | trailer: magic `CPLATLAS-COLEND\n`; format, table version, groups, columns (`u32` each); rows, segments, arcs, pages, directory offset, directory length, directory XXH3-64, index length (`u64` each); the index's XXH3-128; group rows (`u64`); XXH3-64 of the trailer's first 120 bytes |
//!
//! ## What is checked, and when
//!
//! Opening checks, before anything is read from the columns: the file's length against
//! the trailer, the trailer's and the directory's checksums, every chunk's extent
//! (inside the file, aligned, in order, of the length its element size and count say) and
//! every count (groups cover the rows, segments and arcs in sequence), and that the
//! index's content key in the trailer is the index's (see [`crate::stamp`] for how the key
//! is known without hashing the index on every search). A chunk's checksum is checked
//! the first time it is read. Each value is checked where it is used: a row's flags
//! before it is tested; for a row they do not reject, its segment and arc ranges and the
//! linkage or transmission it is tested on; every value of a row that is shown (finite,
//! its segments and arcs inside its group, its page inside the page names), including
//! fields no filter read. So any damage is found before a value of the damaged chunk is
//! used, and [`ColumnTable::select`] then
//! returns an error: the caller rebuilds from the index (the file is not trusted again).
//! What the checksums do not defend against: someone who writes the folder can write
//! another file with valid checksums (XXH3 is not a signature), as they can rewrite the
//! index itself; and a file cut short in place *while a search maps it* stops that search
//! (`SIGBUS`; see `coupler-mapped`) — the program itself only ever replaces the file by
//! renaming a complete new one over it.

use crate::key::IndexKey;
use crate::schema::IndexCurve;
use crate::search::{
    ArcRow, CurveRow, Features, Matched, Query, RowFlags, SearchTable, SegmentRow, order,
};
use coupler_features::Side;
use coupler_kinematics::{Circuit, FourBar, GearRatio, GearedFiveBar, Linkage, LinkageClass};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU8, Ordering};

/// The columns file of an atlas: `index.columns`, beside `index.json`.
pub const COLUMNS_FILE: &str = "index.columns";
/// The columns file's format version.
pub const COLUMNS_FORMAT: u32 = 1;
/// Rows per group.
pub const GROUP_ROWS: usize = 8192;

const MAGIC: [u8; 16] = *b"CPLATLAS-COLUMN\n";
const END: [u8; 16] = *b"CPLATLAS-COLEND\n";
const HEAD: usize = 64;
const TRAILER: usize = 128;
const ALIGN: u64 = 64;
const GROUP_HEAD: usize = 48;
const CHUNK_ENTRY: usize = 24;

/// The columns: (tag, bytes per element). Rows first (0–10), then one column per field
/// of the segments (11–17) and of the arcs (18–25), so that a query reads (and checks)
/// only the fields it tests: an arc filter reads the arcs' spans and deviations, 16
/// bytes an arc, not all 73. One encoding for both the columns file and the search
/// cache (`columns.rs`): a new field is a new column here, in [`push_row`] and
/// [`row_at`] (or [`push_segment`]/[`segment_at`], [`push_arc`]/[`arc_at`], and
/// `Query::reads_features`), and a new [`crate::TABLE_VERSION`]; both files then carry it.
pub(crate) const COLS: [(&str, usize); 26] = [
    ("row.id", 8),
    ("row.link", 24),
    ("row.pt", 16),
    ("row.tr", 16),
    ("row.pbox", 32),
    ("row.page", 4),
    ("row.segs", 8),
    ("row.arcs", 8),
    ("row.dbl", 8),
    ("row.flag", 5),
    ("row.gear", 24),
    ("seg.st", 8),
    ("seg.span", 8),
    ("seg.es", 8),
    ("seg.ev", 8),
    ("seg.len", 8),
    ("seg.dir", 8),
    ("seg.tr", 16),
    ("arc.st", 8),
    ("arc.span", 8),
    ("arc.r", 8),
    ("arc.dev", 8),
    ("arc.ctr", 16),
    ("arc.turn", 8),
    ("arc.side", 1),
    ("arc.tr", 16),
];
pub(crate) const NCOLS: usize = COLS.len();
/// A geared five-bar's L5, φ and λ (zero for a four-bar): see [`linkage_cells`].
pub(crate) const GEAR: usize = 10;
/// The segments' columns: start, span, ε_S, ε_V, length, direction (`f64` each), and the
/// transmission angle range over the segment's window (two `f64`, NaN where unknown).
pub(crate) const SEG_START: usize = 11;
pub(crate) const SEG_SPAN: usize = 12;
pub(crate) const SEG_ES: usize = 13;
pub(crate) const SEG_EV: usize = 14;
pub(crate) const SEG_LEN: usize = 15;
pub(crate) const SEG_DIR: usize = 16;
pub(crate) const SEG_TR: usize = 17;
/// The arcs' columns: start, span, radius, deviation (`f64` each), centre (two `f64`),
/// turn (`f64`), concave side (a byte: 1 right), transmission range (two `f64`).
pub(crate) const ARC_START: usize = 18;
pub(crate) const ARC_SPAN: usize = 19;
pub(crate) const ARC_R: usize = 20;
pub(crate) const ARC_DEV: usize = 21;
pub(crate) const ARC_CTR: usize = 22;
pub(crate) const ARC_TURN: usize = 23;
pub(crate) const SIDE: usize = 24;
pub(crate) const ARC_TR: usize = 25;

/// What a column's elements are: rows, segments or arcs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Row,
    Seg,
    Arc,
}

/// The kind of column `c`.
pub(crate) fn kind(c: usize) -> Kind {
    if c < SEG_START {
        Kind::Row
    } else if c < ARC_START {
        Kind::Seg
    } else {
        Kind::Arc
    }
}

const GROUP_ENTRY: usize = GROUP_HEAD + NCOLS * CHUNK_ENTRY;

/// The columns file of `index`: `index.columns` for `…/index.json`, else `INDEX.columns`.
pub fn columns_path(index: &Path) -> PathBuf {
    if index.file_name().is_some_and(|n| n == "index.json") {
        return index.with_file_name(COLUMNS_FILE);
    }
    let mut p = index.as_os_str().to_owned();
    p.push(".columns");
    PathBuf::from(p)
}

/// Why a columns file is not used (the index is then searched without it).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("search columns not used: {0}")]
pub struct ColumnsError(pub String);

fn bad(m: impl Into<String>) -> ColumnsError {
    ColumnsError(m.into())
}

fn align(x: u64) -> u64 {
    x.div_ceil(ALIGN) * ALIGN
}

fn f64s(out: &mut Vec<u8>, xs: &[f64]) {
    for x in xs {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

fn u32s(out: &mut Vec<u8>, xs: &[u32]) {
    for x in xs {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

#[inline]
fn u32_at(b: &[u8], at: usize) -> u32 {
    b.get(at..at + 4)
        .and_then(|s| s.try_into().ok())
        .map_or(0, u32::from_le_bytes)
}

#[inline]
fn u64_at(b: &[u8], at: usize) -> u64 {
    b.get(at..at + 8)
        .and_then(|s| s.try_into().ok())
        .map_or(0, u64::from_le_bytes)
}

#[inline]
fn f64_at(b: &[u8], at: usize) -> f64 {
    b.get(at..at + 8)
        .and_then(|s| s.try_into().ok())
        .map_or(f64::NAN, f64::from_le_bytes)
}

/// A row's linkage as the columns `row.link` (three lengths: a four-bar's A, B, C, a
/// geared five-bar's L1, L3, L4) and `row.gear` (a geared five-bar's L5 and φ as `f64`,
/// λ = p/q as `i32` p and q; all zero for a four-bar).
pub(crate) fn linkage_cells(l: &Linkage) -> ([f64; 3], [u8; 24]) {
    let mut gear = [0u8; 24];
    match l {
        Linkage::FourBar(l) => ([l.coupler, l.rocker, l.ground], gear),
        Linkage::GearedFiveBar(g) => {
            gear[0..8].copy_from_slice(&g.l5.to_le_bytes());
            gear[8..16].copy_from_slice(&g.phase.to_le_bytes());
            // Terms are at most MAX_GEAR_TERM (1000) in lowest terms: they fit an i32.
            gear[16..20].copy_from_slice(&(g.ratio.num() as i32).to_le_bytes());
            gear[20..24].copy_from_slice(&(g.ratio.den() as i32).to_le_bytes());
            ([g.l1, g.l3, g.l4], gear)
        }
    }
}

/// The linkage of [`linkage_cells`]' columns, or `None` unless they hold a valid one
/// (a valid ratio in lowest terms, positive finite lengths, a finite phase).
pub(crate) fn linkage_of_cells(link: [f64; 3], gear: &[u8]) -> Option<Linkage> {
    if gear.len() != 24 {
        return None;
    }
    let f = |a: usize| f64::from_le_bytes(gear[a..a + 8].try_into().unwrap_or([0; 8]));
    let i = |a: usize| i32::from_le_bytes(gear[a..a + 4].try_into().unwrap_or([0; 4]));
    let [a, b, c] = link;
    if gear.iter().all(|&x| x == 0) {
        return FourBar::new(a, b, c).ok().map(Linkage::FourBar);
    }
    let (num, den) = (i64::from(i(16)), i64::from(i(20)));
    let ratio = GearRatio::new(num, den).ok()?;
    if (ratio.num(), ratio.den()) != (num, den) {
        return None;
    }
    GearedFiveBar::new(a, b, c, f(0), ratio, f(8))
        .ok()
        .map(Linkage::GearedFiveBar)
}

/// Appends one row to the row columns.
pub(crate) fn push_row(cols: &mut [Vec<u8>], r: &CurveRow) {
    cols[0].extend_from_slice(&r.id.to_le_bytes());
    let (link, gear) = linkage_cells(&r.linkage);
    f64s(&mut cols[1], &link);
    cols[GEAR].extend_from_slice(&gear);
    f64s(&mut cols[2], &r.point);
    f64s(&mut cols[3], &r.transmission_deg);
    f64s(&mut cols[4], &r.page_bbox);
    u32s(&mut cols[5], &[r.page]);
    u32s(&mut cols[6], &[r.seg_start, r.seg_count]);
    u32s(&mut cols[7], &[r.arc_start, r.arc_count]);
    u32s(&mut cols[8], &[r.crunodes, r.cusps]);
    let class = LinkageClass::ALL
        .iter()
        .position(|&c| c == r.class)
        .unwrap_or(0) as u8;
    cols[9].extend_from_slice(&[
        (r.circuit == Circuit::Crossed) as u8,
        class,
        r.symmetric as u8,
        r.has_features as u8,
        r.trivial as u8,
    ]);
}

/// Appends one segment to its columns.
pub(crate) fn push_segment(cols: &mut [Vec<u8>], s: &SegmentRow) {
    f64s(&mut cols[SEG_START], &[s.start_deg]);
    f64s(&mut cols[SEG_SPAN], &[s.span_deg]);
    f64s(&mut cols[SEG_ES], &[s.straightness_pct]);
    f64s(&mut cols[SEG_EV], &[s.velocity_variation_pct]);
    f64s(&mut cols[SEG_LEN], &[s.length]);
    f64s(&mut cols[SEG_DIR], &[s.direction_deg]);
    f64s(&mut cols[SEG_TR], &s.transmission_deg);
}

/// Appends one arc to its columns.
pub(crate) fn push_arc(cols: &mut [Vec<u8>], a: &ArcRow) {
    f64s(&mut cols[ARC_START], &[a.start_deg]);
    f64s(&mut cols[ARC_SPAN], &[a.span_deg]);
    f64s(&mut cols[ARC_R], &[a.radius]);
    f64s(&mut cols[ARC_DEV], &[a.deviation_pct]);
    f64s(&mut cols[ARC_CTR], &a.center);
    f64s(&mut cols[ARC_TURN], &[a.turn_deg]);
    cols[SIDE].push((a.concave == Side::Right) as u8);
    f64s(&mut cols[ARC_TR], &a.transmission_deg);
}

/// The linkage of a row whose linkage columns a scan did not read (its query does not
/// test it): never shown, the selected rows are read whole.
const UNREAD_LINKAGE: Linkage = Linkage::FourBar(FourBar {
    coupler: 1.0,
    rocker: 1.0,
    ground: 1.0,
});

/// Row `i` of the row columns, checked: flags and class valid, a valid linkage (see
/// [`linkage_of_cells`]), values finite, its segments inside `segs` and arcs inside
/// `arcs` (global ranges), its page below `pages` (or none).
/// A column given as an empty slice was not read (a scan reads only what its query
/// needs): its fields are left at zero (the page at none, the linkage at
/// [`UNREAD_LINKAGE`]) and not checked; the id, the segment and arc ranges and the flags
/// are always needed.
pub(crate) fn row_at(
    cols: &[&[u8]],
    i: usize,
    segs: std::ops::Range<u64>,
    arcs: std::ops::Range<u64>,
    pages: u64,
) -> Result<CurveRow, String> {
    let read = |c: usize| !cols[c].is_empty();
    if !(read(0) && read(6) && read(7) && read(9)) || read(1) != read(GEAR) {
        return Err("the row's id, ranges and flags (and its linkage whole) were not read".into());
    }
    #[inline(always)]
    fn cell(cols: &[&[u8]], c: usize, i: usize, k: usize) -> f64 {
        if cols[c].is_empty() {
            0.0
        } else {
            f64_at(cols[c], (i * (COLS[c].1 / 8) + k) * 8)
        }
    }
    let f = |c: usize, k: usize| cell(cols, c, i, k);
    let linkage = if read(1) {
        linkage_of_cells(
            [f(1, 0), f(1, 1), f(1, 2)],
            cols[GEAR].get(i * 24..i * 24 + 24).unwrap_or(&[]),
        )
        .ok_or_else(|| format!("row {i}: not a valid linkage"))?
    } else {
        UNREAD_LINKAGE
    };
    let point = [f(2, 0), f(2, 1)];
    let transmission_deg = [f(3, 0), f(3, 1)];
    let page_bbox = [f(4, 0), f(4, 1), f(4, 2), f(4, 3)];
    let finite = |xs: &[f64]| xs.iter().all(|x| x.is_finite());
    if !(finite(&point) && finite(&transmission_deg) && finite(&page_bbox)) {
        return Err(format!("row {i}: a value is not finite"));
    }
    #[inline(always)]
    fn cell_u32(cols: &[&[u8]], c: usize, i: usize, k: usize) -> u32 {
        if !cols[c].is_empty() {
            u32_at(cols[c], (i * (COLS[c].1 / 4) + k) * 4)
        } else if c == 5 {
            u32::MAX
        } else {
            0
        }
    }
    let u = |c: usize, k: usize| cell_u32(cols, c, i, k);
    let (page, seg_start, seg_count, arc_start, arc_count, crunodes, cusps) = (
        u(5, 0),
        u(6, 0),
        u(6, 1),
        u(7, 0),
        u(7, 1),
        u(8, 0),
        u(8, 1),
    );
    let fl = cols[9].get(i * 5..i * 5 + 5).ok_or("row flags")?;
    if !inside(seg_start, seg_count, &segs)
        || !inside(arc_start, arc_count, &arcs)
        || (page != u32::MAX && u64::from(page) >= pages)
    {
        return Err(format!("row {i} refers outside the table"));
    }
    let fl = flags_at(fl, i)?;
    Ok(CurveRow {
        id: u64_at(cols[0], i * 8),
        linkage,
        point,
        circuit: fl.circuit,
        class: fl.class,
        transmission_deg,
        page,
        page_bbox,
        seg_start,
        seg_count,
        arc_start,
        arc_count,
        symmetric: fl.symmetric,
        crunodes,
        cusps,
        has_features: fl.has_features,
        trivial: fl.trivial,
    })
}

/// Whether `count` elements from `start` lie inside `r` (and below 2^32).
#[inline]
fn inside(start: u32, count: u32, r: &std::ops::Range<u64>) -> bool {
    let (s, e) = (u64::from(start), u64::from(start) + u64::from(count));
    r.start <= s && e <= r.end && e <= u64::from(u32::MAX)
}

/// The flags of row `i` from its five bytes of `row.flag` (crossed, class, symmetric,
/// features, trivial), checked: each yes/no byte 0 or 1, the class one of
/// [`LinkageClass::ALL`].
#[inline]
pub(crate) fn flags_at(fl: &[u8], i: usize) -> Result<RowFlags, String> {
    let &[crossed, class, symmetric, features, trivial] = fl else {
        return Err(format!("row {i}: flags"));
    };
    if crossed > 1 || symmetric > 1 || features > 1 || trivial > 1 {
        return Err(format!("row {i} refers outside the table"));
    }
    Ok(RowFlags {
        class: *LinkageClass::ALL
            .get(class as usize)
            .ok_or_else(|| format!("row {i}: class"))?,
        circuit: if crossed == 1 {
            Circuit::Crossed
        } else {
            Circuit::Open
        },
        symmetric: symmetric == 1,
        has_features: features == 1,
        trivial: trivial == 1,
    })
}

/// The byte offset of `f64` number `j` of element `k` of `n` numbers each (saturating:
/// a position past any column reads NaN).
fn at(k: usize, n: usize, j: usize) -> usize {
    k.saturating_mul(n).saturating_add(j).saturating_mul(8)
}

/// Segment `k` of the segment columns (NaN outside them, and in every field whose
/// column was not read, given as an empty slice: it then passes no filter).
pub(crate) fn segment_at(cols: &[&[u8]], k: usize) -> SegmentRow {
    let v = |c: usize| f64_at(cols[c], at(k, 1, 0));
    let tr = |j: usize| f64_at(cols[SEG_TR], at(k, 2, j));
    SegmentRow {
        start_deg: v(SEG_START),
        span_deg: v(SEG_SPAN),
        straightness_pct: v(SEG_ES),
        velocity_variation_pct: v(SEG_EV),
        length: v(SEG_LEN),
        direction_deg: v(SEG_DIR),
        transmission_deg: [tr(0), tr(1)],
    }
}

/// Arc `k` of the arc columns (NaN outside them and where not read; the side left).
pub(crate) fn arc_at(cols: &[&[u8]], k: usize) -> ArcRow {
    let v = |c: usize| f64_at(cols[c], at(k, 1, 0));
    let two = |c: usize, j: usize| f64_at(cols[c], at(k, 2, j));
    ArcRow {
        start_deg: v(ARC_START),
        span_deg: v(ARC_SPAN),
        radius: v(ARC_R),
        deviation_pct: v(ARC_DEV),
        center: [two(ARC_CTR, 0), two(ARC_CTR, 1)],
        concave: if cols[SIDE].get(k) == Some(&1) {
            Side::Right
        } else {
            Side::Left
        },
        turn_deg: v(ARC_TURN),
        transmission_deg: [two(ARC_TR, 0), two(ARC_TR, 1)],
    }
}

/// Whether a segment's values are valid: finite, its window's transmission finite or
/// NaN (unknown), never ±∞.
pub(crate) fn segment_is_valid(s: &SegmentRow) -> bool {
    [
        s.start_deg,
        s.span_deg,
        s.straightness_pct,
        s.velocity_variation_pct,
        s.length,
        s.direction_deg,
    ]
    .iter()
    .all(|x| x.is_finite())
        && s.transmission_deg.iter().all(|x| !x.is_infinite())
}

/// Whether an arc's values are valid (as [`segment_is_valid`]).
pub(crate) fn arc_is_valid(a: &ArcRow) -> bool {
    [
        a.start_deg,
        a.span_deg,
        a.radius,
        a.deviation_pct,
        a.center[0],
        a.center[1],
        a.turn_deg,
    ]
    .iter()
    .all(|x| x.is_finite())
        && a.transmission_deg.iter().all(|x| !x.is_infinite())
}

/// Writes the columns file of an index, one curve at a time, in index order: holds one
/// group of rows in memory. Give it the curves (or their index lines) as the index is
/// written, then [`ColumnsWriter::finish`] with the finished index's key.
pub struct ColumnsWriter<W: Write> {
    w: W,
    at: u64,
    bufs: Vec<Vec<u8>>,
    group_rows: u32,
    first_row: u64,
    first_seg: u64,
    first_arc: u64,
    rows: u64,
    segs: u64,
    arcs: u64,
    pages: Vec<String>,
    page_ix: std::collections::HashMap<String, u32>,
    directory: Vec<u8>,
    groups: u32,
    lines: Vec<String>,
}

impl<W: Write> ColumnsWriter<W> {
    /// Starts a columns file on `w` (writes its header).
    pub fn new(mut w: W) -> std::io::Result<ColumnsWriter<W>> {
        let mut head = [0u8; HEAD];
        head[0..16].copy_from_slice(&MAGIC);
        head[16..20].copy_from_slice(&COLUMNS_FORMAT.to_le_bytes());
        head[20..24].copy_from_slice(&crate::TABLE_VERSION.to_le_bytes());
        w.write_all(&head)?;
        Ok(ColumnsWriter {
            w,
            at: HEAD as u64,
            bufs: vec![Vec::new(); NCOLS],
            group_rows: 0,
            first_row: 0,
            first_seg: 0,
            first_arc: 0,
            rows: 0,
            segs: 0,
            arcs: 0,
            pages: Vec::new(),
            page_ix: Default::default(),
            directory: Vec::new(),
            groups: 0,
            lines: Vec::new(),
        })
    }

    /// The writer the columns go to (for example to make what was written so far
    /// durable while the rest is still to come).
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.w
    }

    /// Adds the next curve (after the lines given to [`ColumnsWriter::push_line`]).
    pub fn push(&mut self, c: &IndexCurve) -> std::io::Result<()> {
        if !self.lines.is_empty() {
            self.parse_lines()?;
        }
        self.push_curve(c)
    }

    fn push_curve(&mut self, c: &IndexCurve) -> std::io::Result<()> {
        let too_many =
            || std::io::Error::other("more features than the search columns hold (2^32)");
        let page = match &c.page {
            Some(p) => match self.page_ix.get(&p.file) {
                Some(&i) => i,
                None => {
                    let i = u32::try_from(self.pages.len()).map_err(|_| too_many())?;
                    self.page_ix.insert(p.file.clone(), i);
                    self.pages.push(p.file.clone());
                    i
                }
            },
            None => u32::MAX,
        };
        let (mut row, segments, arcs) = crate::search::decompose(c);
        row.page = page;
        row.seg_start = u32::try_from(self.segs).map_err(|_| too_many())?;
        row.arc_start = u32::try_from(self.arcs).map_err(|_| too_many())?;
        if self.segs + segments.len() as u64 > u64::from(u32::MAX)
            || self.arcs + arcs.len() as u64 > u64::from(u32::MAX)
        {
            return Err(too_many());
        }
        push_row(&mut self.bufs, &row);
        for s in &segments {
            push_segment(&mut self.bufs, s);
        }
        for a in &arcs {
            push_arc(&mut self.bufs, a);
        }
        self.rows += 1;
        self.segs += segments.len() as u64;
        self.arcs += arcs.len() as u64;
        self.group_rows += 1;
        if self.group_rows as usize == GROUP_ROWS {
            self.end_group()?;
        }
        Ok(())
    }

    /// Adds the next curve from its index line (as `write_curve_line` takes it, with or
    /// without the trailing comma). Lines are parsed in batches, in parallel.
    pub fn push_line(&mut self, line: &str) -> std::io::Result<()> {
        self.lines.push(line.to_string());
        if self.lines.len() >= 1024 {
            self.parse_lines()?;
        }
        Ok(())
    }

    fn parse_lines(&mut self) -> std::io::Result<()> {
        use rayon::prelude::*;
        let lines = std::mem::take(&mut self.lines);
        let curves: Vec<IndexCurve> = lines
            .par_iter()
            .map(|l| {
                let l = l.trim_end();
                serde_json::from_str(l.strip_suffix(',').unwrap_or(l))
                    .map_err(std::io::Error::other)
            })
            .collect::<std::io::Result<_>>()?;
        for c in &curves {
            self.push_curve(c)?;
        }
        Ok(())
    }

    fn chunk(&mut self, data: &[u8]) -> std::io::Result<()> {
        let padded = align(data.len() as u64);
        self.w.write_all(data)?;
        self.w
            .write_all(&vec![0u8; (padded - data.len() as u64) as usize])?;
        for x in [self.at, data.len() as u64, xxhash_rust::xxh3::xxh3_64(data)] {
            self.directory.extend_from_slice(&x.to_le_bytes());
        }
        self.at += padded;
        Ok(())
    }

    fn end_group(&mut self) -> std::io::Result<()> {
        if self.group_rows == 0 {
            return Ok(());
        }
        let nsegs = self.segs - self.first_seg;
        let narcs = self.arcs - self.first_arc;
        self.directory
            .extend_from_slice(&self.group_rows.to_le_bytes());
        self.directory.extend_from_slice(&0u32.to_le_bytes());
        for x in [self.first_row, self.first_seg, nsegs, self.first_arc, narcs] {
            self.directory.extend_from_slice(&x.to_le_bytes());
        }
        let bufs = std::mem::take(&mut self.bufs);
        for b in &bufs {
            self.chunk(b)?;
        }
        self.bufs = bufs
            .into_iter()
            .map(|mut b| {
                b.clear();
                b
            })
            .collect();
        self.groups += 1;
        self.first_row = self.rows;
        self.first_seg = self.segs;
        self.first_arc = self.arcs;
        self.group_rows = 0;
        Ok(())
    }

    /// Ends the file for the index whose content key is `index` (its length and
    /// XXH3-128, as the manifest records them) and returns the writer.
    pub fn finish(mut self, index: IndexKey) -> std::io::Result<W> {
        self.parse_lines()?;
        self.end_group()?;
        let mut off = Vec::with_capacity(8 * (self.pages.len() + 1));
        let mut text = Vec::new();
        off.extend_from_slice(&0u64.to_le_bytes());
        for p in &self.pages {
            text.extend_from_slice(p.as_bytes());
            off.extend_from_slice(&(text.len() as u64).to_le_bytes());
        }
        self.chunk(&off)?;
        self.chunk(&text)?;
        let dir_at = self.at;
        self.w.write_all(&self.directory)?;
        let mut t = [0u8; TRAILER];
        t[0..16].copy_from_slice(&END);
        t[16..20].copy_from_slice(&COLUMNS_FORMAT.to_le_bytes());
        t[20..24].copy_from_slice(&crate::TABLE_VERSION.to_le_bytes());
        t[24..28].copy_from_slice(&self.groups.to_le_bytes());
        t[28..32].copy_from_slice(&(NCOLS as u32).to_le_bytes());
        let fields = [
            self.rows,
            self.segs,
            self.arcs,
            self.pages.len() as u64,
            dir_at,
            self.directory.len() as u64,
            xxhash_rust::xxh3::xxh3_64(&self.directory),
            index.bytes,
        ];
        for (k, x) in fields.iter().enumerate() {
            t[32 + 8 * k..40 + 8 * k].copy_from_slice(&x.to_le_bytes());
        }
        t[96..112].copy_from_slice(&index.hash.to_le_bytes());
        t[112..120].copy_from_slice(&(GROUP_ROWS as u64).to_le_bytes());
        let sum = xxhash_rust::xxh3::xxh3_64(&t[..120]);
        t[120..128].copy_from_slice(&sum.to_le_bytes());
        self.w.write_all(&t)?;
        self.w.flush()?;
        Ok(self.w)
    }
}

/// One chunk as the directory describes it (checked against the file at opening).
#[derive(Clone, Copy, Debug)]
struct Chunk {
    at: usize,
    len: usize,
    hash: u64,
}

#[derive(Clone, Debug)]
struct Group {
    rows: usize,
    first_row: usize,
    segs: std::ops::Range<u64>,
    arcs: std::ops::Range<u64>,
    chunks: [Chunk; NCOLS],
}

/// The bytes of a columns file: mapped, or (tests) owned.
enum Bytes {
    Mapped(coupler_mapped::Mapped),
    Owned(Vec<u8>),
}

impl std::ops::Deref for Bytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        match self {
            Bytes::Mapped(m) => m,
            Bytes::Owned(v) => v,
        }
    }
}

/// A columns file opened for searching: its directory checked, its chunks checked as
/// they are first read (see the module's documentation).
pub struct ColumnTable {
    bytes: Bytes,
    groups: Vec<Group>,
    rows: u64,
    pages: u64,
    page_chunks: [Chunk; 2],
    /// Per chunk (groups' then the pages'): 0 not checked yet, 1 good, 2 damaged.
    checked: Vec<AtomicU8>,
}

impl std::fmt::Debug for ColumnTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ColumnTable")
            .field("rows", &self.rows)
            .field("groups", &self.groups.len())
            .finish()
    }
}

/// One group's chunks as read for a query (those not needed are empty).
struct View<'a> {
    cols: [&'a [u8]; NCOLS],
    group: &'a Group,
    pages: u64,
}

impl View<'_> {
    /// Row `i`'s segments and arcs (global ranges), checked as [`row_at`] checks them.
    #[inline]
    fn ranges(
        &self,
        i: usize,
    ) -> Result<(std::ops::Range<usize>, std::ops::Range<usize>), ColumnsError> {
        let (s, sc) = (u32_at(self.cols[6], i * 8), u32_at(self.cols[6], i * 8 + 4));
        let (a, ac) = (u32_at(self.cols[7], i * 8), u32_at(self.cols[7], i * 8 + 4));
        if !(inside(s, sc, &self.group.segs) && inside(a, ac, &self.group.arcs)) {
            return Err(bad(format!("row {i} refers outside the table")));
        }
        let (s, a) = (s as usize, a as usize);
        Ok((s..s + sc as usize, a..a + ac as usize))
    }

    /// Row `i`'s linkage, checked as [`row_at`] checks it.
    #[inline]
    fn linkage(&self, i: usize) -> Result<Linkage, ColumnsError> {
        let cell = |k: usize| f64_at(self.cols[1], i * 24 + k * 8);
        linkage_of_cells(
            [cell(0), cell(1), cell(2)],
            self.cols[GEAR].get(i * 24..i * 24 + 24).unwrap_or(&[]),
        )
        .ok_or_else(|| bad(format!("row {i}: not a valid linkage")))
    }

    /// Row `i`'s transmission range, checked finite as [`row_at`] checks it.
    #[inline]
    fn transmission(&self, i: usize) -> Result<[f64; 2], ColumnsError> {
        let range = [
            f64_at(self.cols[3], i * 16),
            f64_at(self.cols[3], i * 16 + 8),
        ];
        if range.iter().all(|x| x.is_finite()) {
            Ok(range)
        } else {
            Err(bad(format!("row {i}: a value is not finite")))
        }
    }

    fn row(&self, i: usize) -> Result<CurveRow, ColumnsError> {
        row_at(
            &self.cols,
            i,
            self.group.segs.clone(),
            self.group.arcs.clone(),
            self.pages,
        )
        .map_err(ColumnsError)
    }
}

/// The fields of segments and arcs are read straight from the mapped bytes (a chunk
/// starts on a 64-byte boundary, so each `f64` is one aligned load): nothing is copied
/// or decoded ahead, and a field no filter tests is never touched.
impl View<'_> {
    /// Element `k` (a global segment or arc index, by the kind of column `c`) as an
    /// index into the group's chunk of column `c`.
    #[inline]
    fn local(&self, c: usize, k: usize) -> usize {
        let start = match kind(c) {
            Kind::Seg => self.group.segs.start,
            _ => self.group.arcs.start,
        };
        k.wrapping_sub(start as usize)
    }

    /// Value `j` of `width` of element `k` (global) of column `c` (NaN where not read
    /// or outside).
    #[inline]
    fn val(&self, c: usize, k: usize, width: usize, j: usize) -> f64 {
        let col = self.cols[c];
        match self.local(c, k).checked_mul(width).map(|x| x + j) {
            Some(x) if x < col.len() / 8 => {
                let at = x * 8;
                f64::from_le_bytes(col[at..at + 8].try_into().unwrap_or([0xff; 8]))
            }
            _ => f64::NAN,
        }
    }

    /// The one value of element `k` (global) of column `c`.
    #[inline]
    fn one(&self, c: usize, k: usize) -> f64 {
        self.val(c, k, 1, 0)
    }

    /// The two values of element `k` (global) of the two-wide column `c`.
    #[inline]
    fn two(&self, c: usize, k: usize) -> [f64; 2] {
        [self.val(c, k, 2, 0), self.val(c, k, 2, 1)]
    }
}

impl Features for View<'_> {
    fn segment(&self, k: usize) -> SegmentRow {
        segment_at(&self.cols, self.local(SEG_START, k))
    }
    fn arc(&self, k: usize) -> ArcRow {
        arc_at(&self.cols, self.local(ARC_START, k))
    }
    fn seg_span(&self, k: usize) -> f64 {
        self.one(SEG_SPAN, k)
    }
    fn seg_straightness(&self, k: usize) -> f64 {
        self.one(SEG_ES, k)
    }
    fn seg_velocity(&self, k: usize) -> f64 {
        self.one(SEG_EV, k)
    }
    fn seg_transmission(&self, k: usize) -> [f64; 2] {
        self.two(SEG_TR, k)
    }
    fn arc_span(&self, k: usize) -> f64 {
        self.one(ARC_SPAN, k)
    }
    fn arc_deviation(&self, k: usize) -> f64 {
        self.one(ARC_DEV, k)
    }
    fn arc_radius(&self, k: usize) -> f64 {
        self.one(ARC_R, k)
    }
    fn arc_turn(&self, k: usize) -> f64 {
        self.one(ARC_TURN, k)
    }
    fn arc_concave(&self, k: usize) -> Side {
        if self.cols[SIDE].get(self.local(SIDE, k)) == Some(&1) {
            Side::Right
        } else {
            Side::Left
        }
    }
    fn arc_transmission(&self, k: usize) -> [f64; 2] {
        self.two(ARC_TR, k)
    }
}

/// The columns a scan for `q` reads for every row: the id, the segment and arc ranges
/// and the flags always; the linkage and the transmission range if the query tests or
/// sorts on them (`Query::reads_row`); and of the segments and arcs only the fields it
/// tests or sorts on (`Query::reads_features`). The other fields are read for the
/// selected rows only.
fn columns_read(q: &Query) -> Vec<usize> {
    let mut need: Vec<usize> = vec![0, 6, 7, 9];
    let (linkage, transmission) = q.reads_row();
    if linkage {
        need.extend([1, GEAR]);
    }
    if transmission {
        need.push(3);
    }
    let f = q.reads_features();
    for (read, c) in [
        (f.seg_span, SEG_SPAN),
        (f.seg_straightness, SEG_ES),
        (f.seg_velocity, SEG_EV),
        (f.seg_transmission, SEG_TR),
        (f.arc_span, ARC_SPAN),
        (f.arc_deviation, ARC_DEV),
        (f.arc_radius, ARC_R),
        (f.arc_turn, ARC_TURN),
        (f.arc_side, SIDE),
        (f.arc_transmission, ARC_TR),
    ] {
        if read {
            need.push(c);
        }
    }
    need
}

impl ColumnTable {
    /// Opens the columns file at `path` (mapped) for the index of key `index`.
    pub fn open(path: &Path, index: IndexKey) -> Result<ColumnTable, ColumnsError> {
        let f = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
        if !f.metadata().is_ok_and(|m| m.is_file()) {
            return Err(bad("not a regular file"));
        }
        let m = coupler_mapped::Mapped::of_file(&f).map_err(|e| bad(e.to_string()))?;
        ColumnTable::from_bytes(Bytes::Mapped(m), index)
    }

    /// A columns file held in memory (tests, tools).
    pub fn from_vec(bytes: Vec<u8>, index: IndexKey) -> Result<ColumnTable, ColumnsError> {
        ColumnTable::from_bytes(Bytes::Owned(bytes), index)
    }

    fn from_bytes(bytes: Bytes, index: IndexKey) -> Result<ColumnTable, ColumnsError> {
        let b: &[u8] = &bytes;
        if b.len() < HEAD + TRAILER {
            return Err(bad("shorter than its header and trailer"));
        }
        if b[0..16] != MAGIC {
            return Err(bad("not a columns file"));
        }
        if u32_at(b, 16) != COLUMNS_FORMAT || u32_at(b, 20) != crate::TABLE_VERSION {
            return Err(bad(format!(
                "format {} table {} (this version reads {COLUMNS_FORMAT}, {})",
                u32_at(b, 16),
                u32_at(b, 20),
                crate::TABLE_VERSION
            )));
        }
        let t = &b[b.len() - TRAILER..];
        if t[0..16] != END || xxhash_rust::xxh3::xxh3_64(&t[..120]) != u64_at(t, 120) {
            return Err(bad("trailer (cut, grown or damaged)"));
        }
        if u32_at(t, 16) != COLUMNS_FORMAT
            || u32_at(t, 20) != crate::TABLE_VERSION
            || u32_at(t, 28) as usize != NCOLS
            || u64_at(t, 112) != GROUP_ROWS as u64
        {
            return Err(bad("trailer versions"));
        }
        let key = IndexKey {
            bytes: u64_at(t, 88),
            hash: u128::from_le_bytes(t[96..112].try_into().unwrap_or([0; 16])),
        };
        if key != index {
            return Err(bad(
                "made for another index (its content hash differs: stale or foreign)",
            ));
        }
        let ngroups = u32_at(t, 24) as u64;
        let (rows, nsegs, narcs, pages) =
            (u64_at(t, 32), u64_at(t, 40), u64_at(t, 48), u64_at(t, 56));
        let (dir_at, dir_len) = (u64_at(t, 64), u64_at(t, 72));
        let body_end = (b.len() - TRAILER) as u64;
        if ngroups
            .checked_mul(GROUP_ENTRY as u64)
            .and_then(|l| l.checked_add(2 * CHUNK_ENTRY as u64))
            != Some(dir_len)
            || dir_at.checked_add(dir_len) != Some(body_end)
            || ngroups
                .checked_mul(GROUP_ROWS as u64)
                .is_none_or(|cap| cap < rows)
        {
            return Err(bad("directory extent"));
        }
        let dir = &b[dir_at as usize..body_end as usize];
        if xxhash_rust::xxh3::xxh3_64(dir) != u64_at(t, 80) {
            return Err(bad("directory checksum"));
        }
        let mut next = HEAD as u64;
        let mut chunk = |e: &[u8], element: u64, count: u64| -> Result<Chunk, ColumnsError> {
            let (at, len, hash) = (u64_at(e, 0), u64_at(e, 8), u64_at(e, 16));
            let end = at.checked_add(len).ok_or_else(|| bad("chunk extent"))?;
            if at != next || end > dir_at || count.checked_mul(element) != Some(len) {
                return Err(bad("chunk extent"));
            }
            next = align(end);
            Ok(Chunk {
                at: at as usize,
                len: len as usize,
                hash,
            })
        };
        let mut groups = Vec::with_capacity(ngroups as usize);
        let (mut row, mut seg, mut arc) = (0u64, 0u64, 0u64);
        for g in dir[..ngroups as usize * GROUP_ENTRY].chunks_exact(GROUP_ENTRY) {
            let n = u64::from(u32_at(g, 0));
            let (first_row, first_seg, gsegs, first_arc, garcs) = (
                u64_at(g, 8),
                u64_at(g, 16),
                u64_at(g, 24),
                u64_at(g, 32),
                u64_at(g, 40),
            );
            let full = groups.len() as u64 + 1 < ngroups;
            if n == 0
                || n > GROUP_ROWS as u64
                || (full && n != GROUP_ROWS as u64)
                || u32_at(g, 4) != 0
                || first_row != row
                || first_seg != seg
                || first_arc != arc
                || gsegs > nsegs - seg.min(nsegs)
                || garcs > narcs - arc.min(narcs)
            {
                return Err(bad("group counts"));
            }
            let mut chunks = [Chunk {
                at: 0,
                len: 0,
                hash: 0,
            }; NCOLS];
            for (c, (_, element)) in COLS.iter().enumerate() {
                let count = match kind(c) {
                    Kind::Seg => gsegs,
                    Kind::Arc => garcs,
                    Kind::Row => n,
                };
                let e = &g[GROUP_HEAD + c * CHUNK_ENTRY..GROUP_HEAD + (c + 1) * CHUNK_ENTRY];
                chunks[c] = chunk(e, *element as u64, count)?;
            }
            groups.push(Group {
                rows: n as usize,
                first_row: first_row as usize,
                segs: first_seg..first_seg + gsegs,
                arcs: first_arc..first_arc + garcs,
                chunks,
            });
            row += n;
            seg += gsegs;
            arc += garcs;
        }
        if row != rows || seg != nsegs || arc != narcs {
            return Err(bad("groups do not cover the rows"));
        }
        let pe = &dir[ngroups as usize * GROUP_ENTRY..];
        let off = chunk(
            &pe[..CHUNK_ENTRY],
            8,
            pages.checked_add(1).ok_or_else(|| bad("pages"))?,
        )?;
        let text_len = u64_at(&pe[CHUNK_ENTRY..], 8);
        let text = chunk(&pe[CHUNK_ENTRY..], 1, text_len)?;
        if align((text.at + text.len) as u64) != dir_at {
            return Err(bad("chunks do not end at the directory"));
        }
        let nchunks = groups.len() * NCOLS + 2;
        Ok(ColumnTable {
            bytes,
            groups,
            rows,
            pages,
            page_chunks: [off, text],
            checked: (0..nchunks).map(|_| AtomicU8::new(0)).collect(),
        })
    }

    /// Number of curves.
    pub fn len(&self) -> usize {
        self.rows as usize
    }

    /// Whether there are no curves.
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    /// The file extents (offset, length in bytes) of the chunks read so far, in file
    /// order: every byte a search read from the file (each chunk is checked, whole, on
    /// its first read, and nothing outside a checked chunk is read besides the header,
    /// the directory and the trailer, which opening reads). What `bench search` reads as
    /// a query's own I/O floor.
    pub fn extents_read(&self) -> Vec<(u64, u64)> {
        let chunks = self
            .groups
            .iter()
            .flat_map(|g| g.chunks.iter())
            .chain(self.page_chunks.iter());
        chunks
            .zip(&self.checked)
            .filter(|(_, c)| c.load(Ordering::Relaxed) != 0)
            .map(|(k, _)| (k.at as u64, k.len as u64))
            .collect()
    }

    /// Chunk `c` (number `n` among all chunks), its checksum checked on first use.
    fn bytes_of(&self, c: Chunk, n: usize) -> Result<&[u8], ColumnsError> {
        let data = &self.bytes[c.at..c.at + c.len];
        match self.checked[n].load(Ordering::Relaxed) {
            1 => Ok(data),
            2 => Err(bad("a chunk's checksum")),
            _ => {
                let ok = xxhash_rust::xxh3::xxh3_64(data) == c.hash;
                self.checked[n].store(if ok { 1 } else { 2 }, Ordering::Relaxed);
                if ok {
                    Ok(data)
                } else {
                    Err(bad(format!("checksum of chunk {n}")))
                }
            }
        }
    }

    fn view(&self, g: usize, need: &[usize]) -> Result<View<'_>, ColumnsError> {
        let group = &self.groups[g];
        let mut cols: [&[u8]; NCOLS] = [&[]; NCOLS];
        for &c in need {
            cols[c] = self.bytes_of(group.chunks[c], g * NCOLS + c)?;
        }
        Ok(View {
            cols,
            group,
            pages: self.pages,
        })
    }

    fn page_name(&self, p: u32) -> Result<String, ColumnsError> {
        let n = self.groups.len() * NCOLS;
        let off = self.bytes_of(self.page_chunks[0], n)?;
        let text = self.bytes_of(self.page_chunks[1], n + 1)?;
        let (a, b) = (u64_at(off, p as usize * 8), u64_at(off, p as usize * 8 + 8));
        if a > b || b > text.len() as u64 {
            return Err(bad("page offsets"));
        }
        std::str::from_utf8(&text[a as usize..b as usize])
            .map(str::to_string)
            .map_err(|_| bad("page name"))
    }

    /// The curves that pass `q`, sorted and limited as [`SearchTable::search`] would
    /// (only the `q.limit` best are kept while scanning, so memory does not grow with the
    /// index), as a table of their own (index order, all their segments and arcs), and how
    /// many curves passed. `q` run on that table gives the same hits as on the whole index.
    pub fn select(&self, q: &Query) -> Result<(SearchTable, usize), ColumnsError> {
        use rayon::prelude::*;
        let need = columns_read(q);
        let (linkage, transmission) = q.reads_row();
        // The scan reads the rows' columns it needs (each checked as `row_at` checks
        // it) without building a `CurveRow`.
        let per_group: Vec<(Vec<Keyed>, usize)> = (0..self.groups.len())
            .into_par_iter()
            .map(|g| {
                let v = self.view(g, &need)?;
                let mut best = Best::new(q.limit);
                let mut m = Matched::default();
                let (ids, flags) = (v.cols[0], v.cols[9]);
                for i in 0..v.group.rows {
                    // `Query::eval`, in parts: the flags first (a row they reject is not
                    // read further: each column's checks run on the rows tested), the
                    // linkage and transmission only for a query that reads them (the
                    // row then read and checked whole), then the segments and arcs.
                    let fl = flags_at(flags.get(i * 5..i * 5 + 5).unwrap_or(&[]), i)
                        .map_err(ColumnsError)?;
                    if !q.passes_flags(fl) {
                        continue;
                    }
                    if linkage && !q.passes_linkage(&v.linkage(i)?) {
                        continue;
                    }
                    let transmission = if transmission {
                        let range = v.transmission(i)?;
                        if !q.passes_transmission(range) {
                            continue;
                        }
                        range
                    } else {
                        [f64::NAN; 2]
                    };
                    let (segs, arcs) = v.ranges(i)?;
                    if q.eval_features(&v, segs, arcs, &mut m) {
                        let id = u64_at(ids, i * 8);
                        let key = q.sort_key_of(&v, id, transmission, &m.straight, &m.arcs);
                        best.push((key, id, v.group.first_row + i));
                    }
                }
                Ok(best.finish())
            })
            .collect::<Result<_, ColumnsError>>()?;
        let total = per_group.iter().map(|g| g.1).sum();
        let mut best = Best::new(q.limit);
        for (hits, _) in per_group {
            for h in hits {
                best.push(h);
            }
        }
        let mut rows: Vec<usize> = best.finish().0.into_iter().map(|(_, _, row)| row).collect();
        rows.sort_unstable();
        Ok((self.subset(&rows)?, total))
    }

    /// The curve of id `id` as a table of one row (with its segments and arcs), if any.
    pub fn find(&self, id: u64) -> Result<Option<SearchTable>, ColumnsError> {
        for g in 0..self.groups.len() {
            let v = self.view(g, &[0])?;
            if let Some(i) = (0..v.group.rows).find(|&i| u64_at(v.cols[0], i * 8) == id) {
                return self.subset(&[v.group.first_row + i]).map(Some);
            }
        }
        Ok(None)
    }

    /// Rows `rows` (ascending, global) as a table of their own.
    fn subset(&self, rows: &[usize]) -> Result<SearchTable, ColumnsError> {
        let all: Vec<usize> = (0..NCOLS).collect();
        let mut out = SearchTable::default();
        let mut pages: std::collections::HashMap<u32, u32> = Default::default();
        let mut g = 0;
        for &row in rows {
            while g < self.groups.len() && self.groups[g].first_row + self.groups[g].rows <= row {
                g += 1;
            }
            if g == self.groups.len() || row < self.groups[g].first_row {
                return Err(bad(format!("row {row} is in no group")));
            }
            let v = self.view(g, &all)?;
            let mut r = v.row(row - v.group.first_row)?;
            let segs: Vec<SegmentRow> = (r.seg_start as usize
                ..(r.seg_start + r.seg_count) as usize)
                .map(|k| v.segment(k))
                .collect();
            let arcs: Vec<ArcRow> = (r.arc_start as usize..(r.arc_start + r.arc_count) as usize)
                .map(|k| v.arc(k))
                .collect();
            // The values of a row that is used are checked as the cache's are (a scan
            // reads only the fields it tests, and trusts an untested field to be finite).
            let sides = (r.arc_start as usize..(r.arc_start + r.arc_count) as usize)
                .all(|k| v.cols[SIDE].get(v.local(SIDE, k)).is_some_and(|&b| b <= 1));
            if !(segs.iter().all(segment_is_valid) && arcs.iter().all(arc_is_valid) && sides) {
                return Err(bad(format!(
                    "row {row}: a segment or arc value is not valid"
                )));
            }
            if r.page != u32::MAX {
                r.page = match pages.get(&r.page) {
                    Some(&p) => p,
                    None => {
                        out.pages.push(self.page_name(r.page)?);
                        let p = (out.pages.len() - 1) as u32;
                        pages.insert(r.page, p);
                        p
                    }
                };
            }
            r.seg_start = out.segments.len() as u32;
            r.arc_start = out.arcs.len() as u32;
            out.segments.extend(segs);
            out.arcs.extend(arcs);
            out.rows.push(r);
        }
        Ok(out)
    }
}

/// A hit's sort key, curve id and row (global).
type Keyed = (f64, u64, usize);

/// The best `limit` hits seen (all of them for 0) and how many were seen: kept by
/// selecting the best half whenever twice the limit has gathered.
struct Best {
    limit: usize,
    hits: Vec<Keyed>,
    seen: usize,
    /// The worst of the `limit` best once that many were kept: a hit that sorts after it
    /// can never be among the best (curve ids are unique, so no two hits tie), and is counted
    /// only, not kept (a broad query then keeps few of its million hits).
    cutoff: Option<Keyed>,
}

impl Best {
    fn new(limit: usize) -> Best {
        Best {
            limit,
            hits: Vec::new(),
            seen: 0,
            cutoff: None,
        }
    }

    fn push(&mut self, h: Keyed) {
        self.seen += 1;
        if self
            .cutoff
            .is_some_and(|c| order(&h, &c) == std::cmp::Ordering::Greater)
        {
            return;
        }
        self.hits.push(h);
        if self.limit > 0 && self.hits.len() >= 2 * self.limit.max(512) {
            self.trim();
        }
    }

    fn trim(&mut self) {
        if self.limit > 0 && self.hits.len() > self.limit {
            self.hits.select_nth_unstable_by(self.limit - 1, order);
            self.hits.truncate(self.limit);
            // After the selection, element `limit − 1` is the worst kept.
            self.cutoff = Some(self.hits[self.limit - 1]);
        }
    }

    fn finish(mut self) -> (Vec<Keyed>, usize) {
        self.trim();
        (self.hits, self.seen)
    }
}
