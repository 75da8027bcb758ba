//! Searching an index by features: composable filters over a compact columnar table.
//!
//! The JSON index of a large atlas is big (≈2 KB per curve with features), and parsing
//! it takes seconds per million curves. So `generate` writes the same rows as columns
//! beside the index (`index.columns`, `colfile.rs`), which `search` scans in place
//! through a memory map ([`crate::ColumnTable`]); an index without them is read once
//! into a [`SearchTable`] (one fixed-size row per curve plus flat arrays of segments and
//! arcs), saved as a binary cache next to the index (`INDEX.search`, keyed by the index's
//! length and content hash, checksummed: see `cache.rs`). Either way a query is a linear
//! scan with cheap tests ([`Query`]'s `matches`, one code for both). The filtered
//! quantities are kept as `f64`, so a result satisfies its filters exactly as the index's
//! own numbers do.

use crate::schema::{IndexCurve, PageRef, SCHEMA_VERSION};
use coupler_features::{
    CurveFeatures, PseudoArc, Side, StraightSegment, Trivial, window_transmission,
};
use coupler_kinematics::{Circuit, Linkage, LinkageClass};
use serde::Serialize;

/// One straight segment, as searched.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SegmentRow {
    /// Start, degrees.
    pub start_deg: f64,
    /// Span, degrees.
    pub span_deg: f64,
    /// ε_S, percent.
    pub straightness_pct: f64,
    /// ε_V, percent.
    pub velocity_variation_pct: f64,
    /// Length along the line.
    pub length: f64,
    /// Direction of travel, degrees.
    pub direction_deg: f64,
    /// Transmission angle `[min, max]` over its window, degrees (NaN: unknown).
    pub transmission_deg: [f64; 2],
}

/// One pseudo-arc, as searched.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ArcRow {
    /// Start, degrees.
    pub start_deg: f64,
    /// Span, degrees.
    pub span_deg: f64,
    /// Radius.
    pub radius: f64,
    /// Radial deviation, percent.
    pub deviation_pct: f64,
    /// Centre.
    pub center: [f64; 2],
    /// Concave side.
    pub concave: Side,
    /// Turn about the centre, degrees.
    pub turn_deg: f64,
    /// Transmission angle `[min, max]` over its window, degrees (NaN: unknown).
    pub transmission_deg: [f64; 2],
}

impl SegmentRow {
    /// The row of an extracted segment, with the transmission over its window.
    pub fn of(s: &StraightSegment, transmission_deg: [f64; 2]) -> SegmentRow {
        SegmentRow {
            start_deg: s.start_deg,
            span_deg: s.span_deg,
            straightness_pct: s.straightness_pct,
            velocity_variation_pct: s.velocity_variation_pct,
            length: s.length,
            direction_deg: s.direction_deg,
            transmission_deg,
        }
    }
}

impl ArcRow {
    /// The row of an extracted pseudo-arc, with the transmission over its window.
    pub fn of(a: &PseudoArc, transmission_deg: [f64; 2]) -> ArcRow {
        ArcRow {
            start_deg: a.start_deg,
            span_deg: a.span_deg,
            radius: a.radius,
            deviation_pct: a.deviation_pct,
            center: a.center,
            concave: a.concave,
            turn_deg: a.turn_deg,
            transmission_deg,
        }
    }
}

/// How far a transmission range `[min, max]` (degrees) stays from 0° and 180°:
/// `min(min, 180 − max)`, the largest `DEG` for which it lies within `[DEG, 180 − DEG]`
/// (NaN when unknown).
pub fn transmission_margin(range: [f64; 2]) -> f64 {
    range[0].min(180.0 - range[1])
}

/// One curve, as searched.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveRow {
    /// Curve id.
    pub id: u64,
    /// The linkage: a four-bar's (A, B, C), a geared five-bar's (L1, L3, L4, L5, λ, φ).
    pub linkage: Linkage,
    /// Coupler point (u, v).
    pub point: [f64; 2],
    /// Circuit.
    pub circuit: Circuit,
    /// Class (Barker's for a four-bar).
    pub class: LinkageClass,
    /// Transmission angle range, degrees.
    pub transmission_deg: [f64; 2],
    /// Index into [`SearchTable::pages`], or `u32::MAX`.
    pub page: u32,
    /// Page bounding box, pixels.
    pub page_bbox: [f64; 4],
    /// First segment in [`SearchTable::segments`].
    pub seg_start: u32,
    /// Number of segments.
    pub seg_count: u32,
    /// First arc in [`SearchTable::arcs`].
    pub arc_start: u32,
    /// Number of arcs.
    pub arc_count: u32,
    /// Whether the curve has an axis of symmetry.
    pub symmetric: bool,
    /// Number of crunodes.
    pub crunodes: u32,
    /// Number of cusps.
    pub cusps: u32,
    /// Whether the index carried features for it.
    pub has_features: bool,
    /// The coupler point is a pin ([`Trivial`]): decided from the point, so indexes
    /// written before the index's `trivial` key existed are searched the same way.
    pub trivial: bool,
}

/// The searchable form of an index.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SearchTable {
    /// One row per curve, in index order.
    pub rows: Vec<CurveRow>,
    /// All straight segments, by curve.
    pub segments: Vec<SegmentRow>,
    /// All pseudo-arcs, by curve.
    pub arcs: Vec<ArcRow>,
    /// Page file names.
    pub pages: Vec<String>,
}

/// Why an index or its cache could not be read.
#[derive(Debug, thiserror::Error)]
pub enum SearchError {
    /// A curve line of the index is not valid.
    #[error("index line {line}: {message}")]
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Not an index of this schema.
    #[error("not a coupler-atlas index of schema version {SCHEMA_VERSION}: {0}")]
    Header(String),
    /// The cache is truncated or of another version (it is rebuilt).
    #[error("search cache is not valid")]
    Cache,
}

/// A curve's row (its page, first segment and first arc left at 0 for the caller to
/// set), segments and arcs.
pub(crate) fn decompose(c: &IndexCurve) -> (CurveRow, Vec<SegmentRow>, Vec<ArcRow>) {
    let empty = CurveFeatures {
        straight_segments: Vec::new(),
        pseudo_arcs: Vec::new(),
        double_points: Default::default(),
        symmetry: None,
        cognates: Vec::new(),
        trivial: None,
    };
    let f = c.features.as_ref().unwrap_or(&empty);
    // Indexes written before features carried their window's transmission: computed
    // here (once: the cache and the columns keep it), at the default feature step (exact
    // for a four-bar at any step).
    let window = |given: Option<[f64; 2]>, start: f64, span: f64| {
        given
            .or_else(|| window_transmission(&c.linkage, c.circuit, start, span, 5.0))
            .unwrap_or([f64::NAN; 2])
    };
    let row = CurveRow {
        id: c.id,
        linkage: c.linkage,
        point: [c.point.u, c.point.v],
        circuit: c.circuit,
        class: c.class,
        transmission_deg: c.transmission_deg,
        page: 0,
        page_bbox: c.page.as_ref().map(|p| p.bbox_px).unwrap_or([0.0; 4]),
        seg_start: 0,
        seg_count: f.straight_segments.len() as u32,
        arc_start: 0,
        arc_count: f.pseudo_arcs.len() as u32,
        symmetric: f.symmetry.is_some(),
        crunodes: f.double_points.crunodes.len() as u32,
        cusps: f.double_points.cusps.len() as u32,
        has_features: c.features.is_some(),
        trivial: Trivial::of_linkage(c.point, &c.linkage).is_some(),
    };
    let segments = f
        .straight_segments
        .iter()
        .map(|s| SegmentRow::of(s, window(s.transmission_deg, s.start_deg, s.span_deg)))
        .collect();
    let arcs = f
        .pseudo_arcs
        .iter()
        .map(|a| ArcRow::of(a, window(a.transmission_deg, a.start_deg, a.span_deg)))
        .collect();
    (row, segments, arcs)
}

/// Where a query reads segments and arcs: a [`SearchTable`]'s arrays, or the chunks of
/// a columns file (indices are the table's, global).
pub(crate) trait Features {
    /// Segment `k`.
    fn segment(&self, k: usize) -> SegmentRow;
    /// Arc `k`.
    fn arc(&self, k: usize) -> ArcRow;
    // One field of a segment or an arc: what a query reads (a scan of the columns then
    // reads one value, not the whole feature).
    /// Span of segment `k`.
    fn seg_span(&self, k: usize) -> f64 {
        self.segment(k).span_deg
    }
    /// ε_S of segment `k`.
    fn seg_straightness(&self, k: usize) -> f64 {
        self.segment(k).straightness_pct
    }
    /// ε_V of segment `k`.
    fn seg_velocity(&self, k: usize) -> f64 {
        self.segment(k).velocity_variation_pct
    }
    /// Transmission range over segment `k`'s window.
    fn seg_transmission(&self, k: usize) -> [f64; 2] {
        self.segment(k).transmission_deg
    }
    /// Span of arc `k`.
    fn arc_span(&self, k: usize) -> f64 {
        self.arc(k).span_deg
    }
    /// Deviation of arc `k`.
    fn arc_deviation(&self, k: usize) -> f64 {
        self.arc(k).deviation_pct
    }
    /// Radius of arc `k`.
    fn arc_radius(&self, k: usize) -> f64 {
        self.arc(k).radius
    }
    /// Turn of arc `k`.
    fn arc_turn(&self, k: usize) -> f64 {
        self.arc(k).turn_deg
    }
    /// Concave side of arc `k`.
    fn arc_concave(&self, k: usize) -> Side {
        self.arc(k).concave
    }
    /// Transmission range over arc `k`'s window.
    fn arc_transmission(&self, k: usize) -> [f64; 2] {
        self.arc(k).transmission_deg
    }
}

impl Features for SearchTable {
    fn segment(&self, k: usize) -> SegmentRow {
        self.segments[k]
    }
    fn arc(&self, k: usize) -> ArcRow {
        self.arcs[k]
    }
}

/// The order of hits: by sort key, then by id.
pub(crate) fn order<T>(a: &(f64, u64, T), b: &(f64, u64, T)) -> std::cmp::Ordering {
    a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
}

impl SearchTable {
    /// Adds one curve.
    pub fn push(&mut self, c: &IndexCurve) {
        let (mut row, segments, arcs) = decompose(c);
        row.page = match &c.page {
            Some(PageRef { file, .. }) => match self.pages.iter().rposition(|p| p == file) {
                Some(i) => i as u32,
                None => {
                    self.pages.push(file.clone());
                    (self.pages.len() - 1) as u32
                }
            },
            None => u32::MAX,
        };
        row.seg_start = self.segments.len() as u32;
        row.arc_start = self.arcs.len() as u32;
        self.segments.extend(segments);
        self.arcs.extend(arcs);
        self.rows.push(row);
    }

    /// Rows `rows` of the table (in that order) as a table of their own, each with all
    /// its segments and arcs and its page.
    pub fn subset(&self, rows: &[usize]) -> SearchTable {
        let mut out = SearchTable::default();
        for &i in rows {
            let mut r = self.rows[i];
            let segments = self.segments_of(&r);
            let arcs = self.arcs_of(&r);
            r.seg_start = out.segments.len() as u32;
            r.arc_start = out.arcs.len() as u32;
            out.segments.extend_from_slice(segments);
            out.arcs.extend_from_slice(arcs);
            if let Some(p) = self.pages.get(r.page as usize) {
                r.page = match out.pages.iter().rposition(|q| q == p) {
                    Some(k) => k as u32,
                    None => {
                        out.pages.push(p.clone());
                        (out.pages.len() - 1) as u32
                    }
                };
            }
            out.rows.push(r);
        }
        out
    }

    /// Reads the curves of an index written by [`crate::write_index`] (a header,
    /// then one curve per line), parsing the curve lines in parallel.
    pub fn from_index_text(text: &str) -> Result<SearchTable, SearchError> {
        SearchTable::from_index_reader(text.as_bytes())
    }

    /// Like [`SearchTable::from_index_text`], streaming: lines are read and parsed in
    /// batches (in parallel), so memory holds one batch of text and records at a time
    /// besides the table.
    pub fn from_index_reader<R: std::io::BufRead>(
        mut reader: R,
    ) -> Result<SearchTable, SearchError> {
        use crate::lines::{MAX_INDEX_LINE, read_line_bounded};
        use rayon::prelude::*;
        let mut buf = Vec::new();
        let mut line_no = 1;
        // Lines are read with a bound on their length: a file without newlines (a
        // gigabyte of anything) is refused after 16 MiB, never read whole.
        let mut next_line = |reader: &mut R,
                             line_no: usize|
         -> Result<Option<String>, SearchError> {
            match read_line_bounded(reader, &mut buf, MAX_INDEX_LINE) {
                Ok(0) => Ok(None),
                Ok(_) => Ok(Some(String::from_utf8_lossy(&buf).into_owned())),
                Err(e) if e.kind() == std::io::ErrorKind::InvalidData => Err(SearchError::Line {
                    line: line_no,
                    message: format!(
                        "the line is longer than {} MiB: this is not a coupler-atlas index",
                        MAX_INDEX_LINE >> 20
                    ),
                }),
                Err(e) => Err(SearchError::Header(e.to_string())),
            }
        };
        let first = next_line(&mut reader, 1)?.unwrap_or_default();
        // An index's header names its generator second; other files of an atlas
        // (`manifest.json`) share the first key only.
        if !first.starts_with(&format!(
            "{{\"schema_version\":{SCHEMA_VERSION},\"generator\":"
        )) {
            return Err(SearchError::Header(first.chars().take(60).collect()));
        }
        let mut t = SearchTable::default();
        let mut batch: Vec<(usize, String)> = Vec::with_capacity(1 << 14);
        let mut done = false;
        let mut closed = false;
        while !done {
            batch.clear();
            // A batch holds at most 16,384 lines and about 64 MiB.
            let mut batch_bytes = 0;
            while batch.len() < 1 << 14 && batch_bytes < 64 << 20 {
                let Some(l) = next_line(&mut reader, line_no + 1)? else {
                    done = true;
                    break;
                };
                line_no += 1;
                batch_bytes += l.len();
                if l.starts_with("{\"id\":") {
                    batch.push((line_no, l));
                } else if !l.trim().is_empty() {
                    // The index closes with `]}`; anything after the curves but that
                    // means the file was cut short or altered.
                    closed = l.trim() == "]}";
                }
            }
            let parsed: Result<Vec<IndexCurve>, SearchError> = batch
                .par_iter()
                .map(|(n, l)| {
                    let l = l.trim_end();
                    serde_json::from_str(l.strip_suffix(',').unwrap_or(l)).map_err(|e| {
                        SearchError::Line {
                            line: *n,
                            message: e.to_string(),
                        }
                    })
                })
                .collect();
            for c in &parsed? {
                t.push(c);
            }
        }
        if !closed {
            return Err(SearchError::Line {
                line: line_no,
                message: "the index ends without its closing `]}`: it is truncated".into(),
            });
        }
        Ok(t)
    }

    /// The segments of a row.
    pub fn segments_of(&self, r: &CurveRow) -> &[SegmentRow] {
        &self.segments[r.seg_start as usize..(r.seg_start + r.seg_count) as usize]
    }

    /// The arcs of a row.
    pub fn arcs_of(&self, r: &CurveRow) -> &[ArcRow] {
        &self.arcs[r.arc_start as usize..(r.arc_start + r.arc_count) as usize]
    }

    /// Runs a query: every row that passes all filters, sorted and limited. Sort keys
    /// are computed once per hit; with a limit, only the best `limit` hits are sorted
    /// (partial selection), so a query that matches most of a million curves stays fast.
    pub fn search(&self, q: &Query) -> Vec<Hit> {
        self.search_counted(q).0
    }

    /// [`SearchTable::search`], with the number of curves that matched before the limit.
    pub fn search_counted(&self, q: &Query) -> (Vec<Hit>, usize) {
        let mut keyed: Vec<(f64, u64, Hit)> = self
            .rows
            .iter()
            .enumerate()
            .filter_map(|(i, r)| {
                q.matches(self, i, r)
                    .map(|h| (q.sort_key(self, r, &h), r.id, h))
            })
            .collect();
        let total = keyed.len();
        if q.limit > 0 && keyed.len() > q.limit {
            keyed.select_nth_unstable_by(q.limit - 1, order);
            keyed.truncate(q.limit);
        }
        keyed.sort_by(order);
        (keyed.into_iter().map(|(_, _, h)| h).collect(), total)
    }
}

/// How hits are ordered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SortKey {
    /// By curve id (atlas order).
    #[default]
    Id,
    /// Longest matching straight segment first.
    Straight,
    /// Straightest matching segment first.
    Straightness,
    /// Longest matching arc first.
    Arc,
    /// Smallest matching arc deviation first.
    Deviation,
    /// Transmission angle farthest from 0° and 180° over the whole turn first (largest
    /// [`transmission_margin`]).
    Transmission,
    /// Transmission angle farthest from 0° and 180° over a matching feature's window first.
    WindowTransmission,
    /// Largest matching arc turn first.
    Turn,
    /// Smallest matching arc radius first.
    Radius,
    /// Smallest matching segment ε_V first.
    Velocity,
}

impl std::str::FromStr for SortKey {
    type Err = String;
    fn from_str(s: &str) -> Result<SortKey, String> {
        Ok(match s {
            "id" => SortKey::Id,
            "straight" => SortKey::Straight,
            "straightness" => SortKey::Straightness,
            "arc" => SortKey::Arc,
            "deviation" => SortKey::Deviation,
            "transmission" => SortKey::Transmission,
            "window-transmission" => SortKey::WindowTransmission,
            "turn" => SortKey::Turn,
            "radius" => SortKey::Radius,
            "velocity" => SortKey::Velocity,
            _ => {
                return Err(format!(
                    "unknown sort key `{s}` (expected id, straight, straightness, arc, deviation, transmission, window-transmission, turn, radius, velocity)"
                ));
            }
        })
    }
}

/// A feature filter: span at least `min_span_deg`, error at most `max_error_pct`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpanFilter {
    /// Smallest span, crank degrees.
    pub min_span_deg: f64,
    /// Largest error (ε_S for segments, radial deviation for arcs), percent.
    pub max_error_pct: f64,
}

impl std::str::FromStr for SpanFilter {
    type Err = String;
    /// `SPAN` or `SPAN:TOL` (degrees, percent).
    fn from_str(s: &str) -> Result<SpanFilter, String> {
        let num = |t: &str| -> Result<f64, String> {
            let x: f64 = t
                .trim()
                .parse()
                .map_err(|_| format!("expected SPAN[:TOL] (degrees[:percent]), got `{s}`"))?;
            if x.is_finite() && x >= 0.0 {
                Ok(x)
            } else {
                Err(format!("SPAN and TOL must be finite and ≥ 0, got `{s}`"))
            }
        };
        let (span, tol) = match s.split_once(':') {
            Some((a, b)) => (num(a)?, num(b)?),
            None => (num(s)?, f64::INFINITY),
        };
        Ok(SpanFilter {
            min_span_deg: span,
            max_error_pct: tol,
        })
    }
}

/// A search query: every filter given must hold.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Query {
    /// Some straight segment passes.
    pub straight: Option<SpanFilter>,
    /// Some pseudo-arc passes.
    pub arc: Option<SpanFilter>,
    /// Two straight segments (passing `straight`, if given), or two arcs (passing `arc`,
    /// if given) of equal radius (within `radius_tol_pct`) and the same concave side.
    pub double_dwell: bool,
    /// Relative radius tolerance of the two arcs of a double dwell, percent.
    pub radius_tol_pct: f64,
    /// Transmission angle within [DEG, 180 − DEG] over the whole revolution.
    pub min_transmission_deg: Option<f64>,
    /// Matching segments and arcs have their transmission angle within [DEG, 180 − DEG]
    /// over their own window; alone, asks for such a segment or arc.
    pub min_window_transmission_deg: Option<f64>,
    /// Class (Barker's for a four-bar).
    pub class: Option<LinkageClass>,
    /// The linkage: lengths (and a geared five-bar's phase) matched to 1e-9, its gear
    /// ratio exactly; a four-bar never matches a geared five-bar.
    pub linkage: Option<Linkage>,
    /// Circuit.
    pub circuit: Option<Circuit>,
    /// Symmetric curves only.
    pub symmetric: bool,
    /// Keep curves of coupler points at a pin ([`CurveRow::trivial`]); left out by default.
    pub include_trivial: bool,
    /// Matching arcs have a radius in `[min, max]`.
    pub radius: Option<[f64; 2]>,
    /// Matching arcs turn at least this many degrees about their centre.
    pub min_turn_deg: Option<f64>,
    /// Matching straight segments have ε_V at most this, percent.
    pub max_velocity_variation_pct: Option<f64>,
    /// Order.
    pub sort: SortKey,
    /// At most this many hits (0: all).
    pub limit: usize,
}

/// Default relative radius tolerance of a double dwell's two arcs, percent.
pub const DEFAULT_RADIUS_TOL_PCT: f64 = 2.0;

/// Whether two linkages are the same mechanism with lengths (and phase) within 1e-9
/// and the same gear ratio.
fn same_linkage(a: &Linkage, b: &Linkage) -> bool {
    let near = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(p, q)| (p - q).abs() <= 1e-9);
    match (a, b) {
        (Linkage::FourBar(a), Linkage::FourBar(b)) => near(
            &[a.coupler, a.rocker, a.ground],
            &[b.coupler, b.rocker, b.ground],
        ),
        (Linkage::GearedFiveBar(a), Linkage::GearedFiveBar(b)) => {
            a.ratio == b.ratio
                && near(
                    &[a.l1, a.l3, a.l4, a.l5, a.phase],
                    &[b.l1, b.l3, b.l4, b.l5, b.phase],
                )
        }
        _ => false,
    }
}

/// A search result: the row and the features that matched.
#[derive(Clone, Debug, PartialEq)]
pub struct Hit {
    /// Row index in the table.
    pub row: usize,
    /// Indices (into [`SearchTable::segments`]) of the matching straight segments.
    pub straight: Vec<usize>,
    /// Indices (into [`SearchTable::arcs`]) of the matching arcs.
    pub arcs: Vec<usize>,
}

impl Query {
    /// Whether the query reads segments and arcs: (straight, arc).
    pub(crate) fn wants(&self) -> (bool, bool) {
        let want_straight = self.straight.is_some() || self.max_velocity_variation_pct.is_some();
        let want_arc = self.arc.is_some() || self.radius.is_some() || self.min_turn_deg.is_some();
        // The window's transmission reads both (alone it asks for a segment or an arc).
        let window = self.min_window_transmission_deg.is_some();
        (
            want_straight || self.double_dwell || window,
            want_arc || self.double_dwell || window,
        )
    }

    /// Which row fields beyond the id, the segment and arc ranges and the flags (class,
    /// circuit, symmetric, features, trivial) [`Query::matches`] and [`Query::sort_key`]
    /// read: (linkage, transmission range). A search of the columns file reads only
    /// those columns for every row, so a filter on another row field must be added here.
    pub(crate) fn reads_row(&self) -> (bool, bool) {
        (
            self.linkage.is_some(),
            self.min_transmission_deg.is_some() || self.sort == SortKey::Transmission,
        )
    }

    /// Which fields of the segments and arcs [`Query::eval`] and [`Query::sort_key_of`]
    /// read. A search of the columns file reads only those columns, so a test or sort on
    /// another feature field must be added here.
    pub(crate) fn reads_features(&self) -> FeatureReads {
        let (straight, arc) = self.wants();
        let window = self.min_window_transmission_deg.is_some();
        let sort = |k: SortKey| self.sort == k;
        // A filter without a tolerance (`--arc 40`: TOL is ∞) tests the span only (every
        // stored error is finite: checked where a row is used).
        let tested = |f: SpanFilter| f.max_error_pct != f64::INFINITY;
        FeatureReads {
            seg_span: straight && (self.straight.is_some() || sort(SortKey::Straight)),
            seg_straightness: straight
                && (self.straight.is_some_and(tested) || sort(SortKey::Straightness)),
            seg_velocity: straight
                && (self.max_velocity_variation_pct.is_some() || sort(SortKey::Velocity)),
            seg_transmission: straight && (window || sort(SortKey::WindowTransmission)),
            arc_span: arc && (self.arc.is_some() || sort(SortKey::Arc)),
            arc_deviation: arc && (self.arc.is_some_and(tested) || sort(SortKey::Deviation)),
            arc_radius: arc
                && (self.radius.is_some() || self.double_dwell || sort(SortKey::Radius)),
            arc_turn: arc && (self.min_turn_deg.is_some() || sort(SortKey::Turn)),
            arc_side: arc && self.double_dwell,
            arc_transmission: arc && (window || sort(SortKey::WindowTransmission)),
        }
    }

    /// The sort key of hit `h` of row `r` (smaller first).
    pub(crate) fn sort_key(&self, t: &impl Features, r: &CurveRow, h: &Hit) -> f64 {
        self.sort_key_of(t, r.id, r.transmission_deg, &h.straight, &h.arcs)
    }

    /// The sort key of the row of id `id` and transmission range `transmission` (read
    /// only for a sort on it: [`Query::reads_row`]) whose matching segments and arcs are
    /// `straight` and `arcs`.
    pub(crate) fn sort_key_of(
        &self,
        t: &impl Features,
        id: u64,
        transmission: [f64; 2],
        straight: &[usize],
        arcs: &[usize],
    ) -> f64 {
        // Generic, not `dyn`: the sort key is computed for every hit of a scan.
        fn min(xs: &[usize], f: impl Fn(usize) -> f64) -> f64 {
            xs.iter().fold(f64::INFINITY, |m, &k| m.min(f(k)))
        }
        fn max(xs: &[usize], f: impl Fn(usize) -> f64) -> f64 {
            xs.iter().fold(0.0, |m: f64, &k| m.max(f(k)))
        }
        match self.sort {
            SortKey::Id => id as f64,
            SortKey::Straight => -max(straight, |k| t.seg_span(k)),
            SortKey::Arc => -max(arcs, |k| t.arc_span(k)),
            SortKey::Deviation => min(arcs, |k| t.arc_deviation(k)),
            SortKey::Straightness => min(straight, |k| t.seg_straightness(k)),
            SortKey::Transmission => -transmission_margin(transmission),
            SortKey::WindowTransmission => -straight
                .iter()
                .map(|&k| transmission_margin(t.seg_transmission(k)))
                .chain(
                    arcs.iter()
                        .map(|&k| transmission_margin(t.arc_transmission(k))),
                )
                .fold(f64::NEG_INFINITY, f64::max),
            SortKey::Turn => -max(arcs, |k| t.arc_turn(k)),
            SortKey::Radius => min(arcs, |k| t.arc_radius(k)),
            SortKey::Velocity => min(straight, |k| t.seg_velocity(k)),
        }
    }

    /// Hit of row `r` (number `i`), if it passes. Row fields read here beyond those
    /// [`Query::reads_row`] names must be added there.
    pub(crate) fn matches(&self, t: &impl Features, i: usize, r: &CurveRow) -> Option<Hit> {
        let mut m = Matched::default();
        if !self.eval(t, r, &mut m) {
            return None;
        }
        Some(Hit {
            row: i,
            straight: m.straight,
            arcs: m.arcs,
        })
    }

    /// Whether a row with flags `f` may pass: the tests of [`Query::eval`] on the class,
    /// circuit, symmetry, trivial point and features (the scan of a columns file runs
    /// this on a row's flag bytes alone, before it reads the rest of the row).
    pub(crate) fn passes_flags(&self, f: RowFlags) -> bool {
        let (want_straight, want_arc) = self.wants();
        self.class.is_none_or(|c| f.class == c)
            && self.circuit.is_none_or(|c| f.circuit == c)
            && (f.symmetric || !self.symmetric)
            && (!f.trivial || self.include_trivial)
            && (f.has_features || !(want_straight || want_arc))
    }

    /// Whether row `r` passes, its matching segments and arcs (as [`Hit`] gives them)
    /// left in `m` (whose lists are reused from row to row: a scan allocates nothing per
    /// row). The one test behind [`Query::matches`] and the columns' scan. Row fields
    /// read here beyond those [`Query::reads_row`] names, and feature fields beyond those
    /// [`Query::reads_features`] names, must be added there.
    pub(crate) fn eval(&self, t: &impl Features, r: &CurveRow, m: &mut Matched) -> bool {
        m.straight.clear();
        m.arcs.clear();
        if !(self.passes_flags(RowFlags::of(r)) && self.passes_row(r)) {
            return false;
        }
        let segs = r.seg_start as usize..(r.seg_start + r.seg_count) as usize;
        let arcs = r.arc_start as usize..(r.arc_start + r.arc_count) as usize;
        self.eval_features(t, segs, arcs, m)
    }

    /// The part of [`Query::eval`] after the row tests, for a row whose segments are
    /// `segs` and arcs `arcs`: whether it passes, its matching segments and arcs left in
    /// `m`.
    pub(crate) fn eval_features(
        &self,
        t: &impl Features,
        segs: std::ops::Range<usize>,
        arcs: std::ops::Range<usize>,
        m: &mut Matched,
    ) -> bool {
        m.straight.clear();
        m.arcs.clear();
        let (straight, arc) = self.collects();
        if straight {
            for k in segs {
                if self.segment_passes(t, k) {
                    m.straight.push(k);
                }
            }
        }
        if arc {
            for k in arcs {
                if self.arc_passes(t, k) {
                    m.arcs.push(k);
                }
            }
        }
        self.decide(t, m)
    }

    /// Which of a row's features [`Query::eval`] tests and collects: (straight segments,
    /// arcs). Within what [`Query::wants`] reads.
    pub(crate) fn collects(&self) -> (bool, bool) {
        let want_straight = self.straight.is_some() || self.max_velocity_variation_pct.is_some();
        let want_arc = self.arc.is_some() || self.radius.is_some() || self.min_turn_deg.is_some();
        let want_any = self.min_window_transmission_deg.is_some()
            && !(want_straight || want_arc || self.double_dwell);
        (
            want_straight || self.double_dwell || want_any,
            want_arc || self.double_dwell || want_any,
        )
    }

    /// The tests of [`Query::eval`] on the row's linkage and transmission range (the
    /// fields [`Query::reads_row`] names).
    pub(crate) fn passes_row(&self, r: &CurveRow) -> bool {
        self.passes_linkage(&r.linkage) && self.passes_transmission(r.transmission_deg)
    }

    /// The test of [`Query::eval`] on the row's linkage.
    #[inline]
    pub(crate) fn passes_linkage(&self, linkage: &Linkage) -> bool {
        self.linkage
            .as_ref()
            .is_none_or(|l| same_linkage(linkage, l))
    }

    /// The test of [`Query::eval`] on the row's transmission range.
    #[inline]
    pub(crate) fn passes_transmission(&self, range: [f64; 2]) -> bool {
        self.min_transmission_deg
            .is_none_or(|mt| !(range[0] < mt || range[1] > 180.0 - mt))
    }

    /// Whether straight segment `k` passes the segment filters (each field is read only
    /// if a filter tests it: `reads_features`). NaN (unknown) never passes.
    #[inline]
    pub(crate) fn segment_passes(&self, t: &impl Features, k: usize) -> bool {
        self.straight.is_none_or(|f| {
            t.seg_span(k) >= f.min_span_deg
                && (f.max_error_pct == f64::INFINITY || t.seg_straightness(k) <= f.max_error_pct)
        }) && self
            .min_window_transmission_deg
            .is_none_or(|mw| transmission_margin(t.seg_transmission(k)) >= mw)
            && self
                .max_velocity_variation_pct
                .is_none_or(|mv| t.seg_velocity(k) <= mv)
    }

    /// Whether arc `k` passes the arc filters (as [`Query::segment_passes`]).
    #[inline]
    pub(crate) fn arc_passes(&self, t: &impl Features, k: usize) -> bool {
        self.arc.is_none_or(|f| {
            t.arc_span(k) >= f.min_span_deg
                && (f.max_error_pct == f64::INFINITY || t.arc_deviation(k) <= f.max_error_pct)
        }) && self
            .min_window_transmission_deg
            .is_none_or(|mw| transmission_margin(t.arc_transmission(k)) >= mw)
            && self.radius.is_none_or(|[lo, hi]| {
                let radius = t.arc_radius(k);
                lo <= radius && radius <= hi
            })
            && self.min_turn_deg.is_none_or(|mt| t.arc_turn(k) >= mt)
    }

    /// The end of [`Query::eval`] for a row that passed the row tests and whose passing
    /// segments and arcs are in `m` (those of them the query wants): whether it passes,
    /// with what it shows left in `m`.
    fn decide(&self, t: &impl Features, m: &mut Matched) -> bool {
        // Arc and segment measures filter the arcs or segments; given alone, they ask for one.
        let want_straight = self.straight.is_some() || self.max_velocity_variation_pct.is_some();
        let want_arc = self.arc.is_some() || self.radius.is_some() || self.min_turn_deg.is_some();
        // The window's transmission alone asks for a segment or an arc.
        let want_any = self.min_window_transmission_deg.is_some()
            && !(want_straight || want_arc || self.double_dwell);
        if want_straight && m.straight.is_empty() {
            return false;
        }
        if want_arc && m.arcs.is_empty() {
            return false;
        }
        if want_any && m.straight.is_empty() && m.arcs.is_empty() {
            return false;
        }
        if self.double_dwell {
            let two_lines = m.straight.len() >= 2;
            // Two lines with --arc given: the arcs that passed --arc are shown, and the
            // equal pair is not needed (not looked for).
            if !(two_lines && want_arc) {
                let arcs = &m.arcs;
                // The first equal pair (p before q, both in order); each arc's radius
                // and side are read once per p, not once per pair.
                let pair = arcs.iter().enumerate().find_map(|(x, &p)| {
                    let (a, side) = (t.arc_radius(p), t.arc_concave(p));
                    arcs[x + 1..].iter().find_map(|&q| {
                        let b = t.arc_radius(q);
                        let equal = (a - b).abs() <= self.radius_tol_pct / 100.0 * a.max(b);
                        (equal && side == t.arc_concave(q)).then_some([p, q])
                    })
                });
                match (two_lines, pair) {
                    // Else the equal pair is shown (none with two lines: no arc).
                    (true, pair) | (false, pair @ Some(_)) => {
                        m.arcs.clear();
                        m.arcs.extend(pair.into_iter().flatten());
                    }
                    (false, None) => return false,
                }
            }
        }
        true
    }
}

/// A row's flags: what [`Query::passes_flags`] tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct RowFlags {
    pub class: LinkageClass,
    pub circuit: Circuit,
    pub symmetric: bool,
    pub has_features: bool,
    pub trivial: bool,
}

impl RowFlags {
    /// The flags of row `r`.
    pub(crate) fn of(r: &CurveRow) -> RowFlags {
        RowFlags {
            class: r.class,
            circuit: r.circuit,
            symmetric: r.symmetric,
            has_features: r.has_features,
            trivial: r.trivial,
        }
    }
}

/// Which fields of the segments and arcs a query reads ([`Query::reads_features`]);
/// none unless the query reads segments (or arcs) at all ([`Query::wants`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct FeatureReads {
    pub seg_span: bool,
    pub seg_straightness: bool,
    pub seg_velocity: bool,
    pub seg_transmission: bool,
    pub arc_span: bool,
    pub arc_deviation: bool,
    pub arc_radius: bool,
    pub arc_turn: bool,
    pub arc_side: bool,
    pub arc_transmission: bool,
}

/// The matching segments and arcs of a row ([`Query::eval`]), as indices into the
/// table's (or the columns') segments and arcs.
#[derive(Clone, Debug, Default)]
pub(crate) struct Matched {
    /// Matching straight segments.
    pub straight: Vec<usize>,
    /// Matching arcs.
    pub arcs: Vec<usize>,
}
