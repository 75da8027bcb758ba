//! A [`SearchTable`] as the search cache's columns (see [`crate::cache`] for the
//! container and its checks): one fixed-width column per field, so that each can be
//! memory-mapped. To add a field: add a column in [`SearchTable::columns`], read it in
//! [`SearchTable::from_cache_bytes`] (checking it), and bump [`TABLE_VERSION`]; an old
//! cache is then rebuilt.

use crate::cache::{Column, IndexKey, Section, write_container};
use crate::search::{ArcRow, CurveRow, SearchTable, SegmentRow};
use crate::{CacheError, read_container};
use coupler_features::Side;
use coupler_kinematics::{Circuit, FourBar, GearRatio, GearedFiveBar, Linkage, LinkageClass};

/// Version of the column set (the cache's table version): 2 added arcs' turn and the
/// rows' `trivial` flag; 3 the rows' `row.gear` (a geared five-bar's L5, φ and λ).
pub const TABLE_VERSION: u32 = 3;

/// A row's linkage as the columns `row.link` (three lengths: a four-bar's A, B, C, a
/// geared five-bar's L1, L3, L4) and `row.gear` (a geared five-bar's L5 and φ as `f64`,
/// λ = p/q as `i32` p and q; all zero for a four-bar).
fn linkage_cells(l: &Linkage) -> ([f64; 3], [u8; 24]) {
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
fn linkage_of_cells(link: [f64; 3], gear: &[u8]) -> Option<Linkage> {
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

/// Reads element `i` of a column of `N` little-endian `f64` per element.
fn f64_row<const N: usize>(s: &Section, i: usize) -> [f64; N] {
    let mut out = [0.0; N];
    let at = i * 8 * N;
    for (k, x) in out.iter_mut().enumerate() {
        let b = &s.data[at + 8 * k..at + 8 * k + 8];
        *x = f64::from_le_bytes(b.try_into().unwrap_or([0; 8]));
    }
    out
}

fn u32_row<const N: usize>(s: &Section, i: usize) -> [u32; N] {
    let mut out = [0u32; N];
    let at = i * 4 * N;
    for (k, x) in out.iter_mut().enumerate() {
        let b = &s.data[at + 4 * k..at + 4 * k + 4];
        *x = u32::from_le_bytes(b.try_into().unwrap_or([0; 4]));
    }
    out
}

fn bad(m: impl Into<String>) -> CacheError {
    CacheError(m.into())
}

impl SearchTable {
    /// The table's columns.
    fn columns(&self) -> Vec<Column> {
        let n = self.rows.len();
        let mut id = Vec::with_capacity(8 * n);
        let mut gear = Vec::with_capacity(24 * n);
        let (mut link, mut point, mut trans, mut pbox) = (
            Vec::with_capacity(24 * n),
            Vec::with_capacity(16 * n),
            Vec::with_capacity(16 * n),
            Vec::with_capacity(32 * n),
        );
        let (mut page, mut segs, mut arcs, mut dbl, mut flags) = (
            Vec::with_capacity(4 * n),
            Vec::with_capacity(8 * n),
            Vec::with_capacity(8 * n),
            Vec::with_capacity(8 * n),
            Vec::with_capacity(5 * n),
        );
        for r in &self.rows {
            id.extend_from_slice(&r.id.to_le_bytes());
            let (lengths, gears) = linkage_cells(&r.linkage);
            f64s(&mut link, &lengths);
            gear.extend_from_slice(&gears);
            f64s(&mut point, &r.point);
            f64s(&mut trans, &r.transmission_deg);
            f64s(&mut pbox, &r.page_bbox);
            u32s(&mut page, &[r.page]);
            u32s(&mut segs, &[r.seg_start, r.seg_count]);
            u32s(&mut arcs, &[r.arc_start, r.arc_count]);
            u32s(&mut dbl, &[r.crunodes, r.cusps]);
            let class = LinkageClass::ALL
                .iter()
                .position(|&c| c == r.class)
                .unwrap_or(0) as u8;
            flags.extend_from_slice(&[
                (r.circuit == Circuit::Crossed) as u8,
                class,
                r.symmetric as u8,
                r.has_features as u8,
                r.trivial as u8,
            ]);
        }
        let mut seg = Vec::with_capacity(48 * self.segments.len());
        for s in &self.segments {
            f64s(
                &mut seg,
                &[
                    s.start_deg,
                    s.span_deg,
                    s.straightness_pct,
                    s.velocity_variation_pct,
                    s.length,
                    s.direction_deg,
                ],
            );
        }
        let mut arc = Vec::with_capacity(56 * self.arcs.len());
        let mut side = Vec::with_capacity(self.arcs.len());
        for a in &self.arcs {
            f64s(
                &mut arc,
                &[
                    a.start_deg,
                    a.span_deg,
                    a.radius,
                    a.deviation_pct,
                    a.center[0],
                    a.center[1],
                    a.turn_deg,
                ],
            );
            side.push((a.concave == Side::Right) as u8);
        }
        let mut off = Vec::with_capacity(8 * (self.pages.len() + 1));
        let mut text = Vec::new();
        off.extend_from_slice(&0u64.to_le_bytes());
        for p in &self.pages {
            text.extend_from_slice(p.as_bytes());
            off.extend_from_slice(&(text.len() as u64).to_le_bytes());
        }
        let col = |tag, element, data| Column { tag, element, data };
        vec![
            col("row.id", 8, id),
            col("row.link", 24, link),
            col("row.gear", 24, gear),
            col("row.pt", 16, point),
            col("row.tr", 16, trans),
            col("row.pbox", 32, pbox),
            col("row.page", 4, page),
            col("row.segs", 8, segs),
            col("row.arcs", 8, arcs),
            col("row.dbl", 8, dbl),
            col("row.flag", 5, flags),
            col("seg", 48, seg),
            col("arc", 56, arc),
            col("arc.side", 1, side),
            col("page.off", 8, off),
            col("page.txt", 1, text),
        ]
    }

    /// Writes the table as a search cache for the index with key `key`.
    pub fn write_cache(&self, w: &mut impl std::io::Write, key: IndexKey) -> std::io::Result<()> {
        write_container(w, key, TABLE_VERSION, &self.columns())
    }

    /// The table as a search cache for the index with key `key` (in memory).
    pub fn to_cache_bytes(&self, key: IndexKey) -> Vec<u8> {
        let mut out = Vec::new();
        let _ = self.write_cache(&mut out, key);
        out
    }

    /// Reads a cache written by [`SearchTable::write_cache`] if it verifies (container,
    /// index key, checksums) and every value and cross-reference in it is valid: any
    /// bytes give either this or an error, never a panic or an allocation beyond what the
    /// file's own size supports.
    pub fn from_cache_bytes(b: &[u8], key: IndexKey) -> Result<SearchTable, CacheError> {
        let (version, sections) = read_container(b, key)?;
        if version != TABLE_VERSION {
            return Err(bad(format!("table version {version}")));
        }
        let find = |tag: &str, element: u32| -> Result<Section<'_>, CacheError> {
            let t = {
                let mut t = [0u8; 8];
                for (d, s) in t.iter_mut().zip(tag.bytes()) {
                    *d = s;
                }
                t
            };
            sections
                .iter()
                .find(|s| s.tag == t)
                .copied()
                .filter(|s| s.element == element)
                .ok_or_else(|| bad(format!("column {tag}")))
        };
        let id = find("row.id", 8)?;
        let n = id.count as usize;
        let rows_of = |tag: &str, element: u32| -> Result<Section<'_>, CacheError> {
            let s = find(tag, element)?;
            (s.count as usize == n)
                .then_some(s)
                .ok_or_else(|| bad(format!("column {tag} length")))
        };
        let gear = rows_of("row.gear", 24)?;
        let (link, point, trans, pbox) = (
            rows_of("row.link", 24)?,
            rows_of("row.pt", 16)?,
            rows_of("row.tr", 16)?,
            rows_of("row.pbox", 32)?,
        );
        let (page, segs, arcs, dbl, flags) = (
            rows_of("row.page", 4)?,
            rows_of("row.segs", 8)?,
            rows_of("row.arcs", 8)?,
            rows_of("row.dbl", 8)?,
            rows_of("row.flag", 5)?,
        );
        let (seg, arc, side) = (find("seg", 48)?, find("arc", 56)?, find("arc.side", 1)?);
        if side.count != arc.count {
            return Err(bad("column arc.side length"));
        }
        let (off, text) = (find("page.off", 8)?, find("page.txt", 1)?);
        if off.count == 0 {
            return Err(bad("column page.off"));
        }
        let finite = |xs: &[f64]| xs.iter().all(|x| x.is_finite());
        let mut t = SearchTable::default();
        // Page names: offsets rise from 0 to the text's end, each name UTF-8.
        let npages = off.count as usize - 1;
        t.pages.reserve_exact(npages);
        let mut last = 0u64;
        for i in 0..=npages {
            let at = i * 8;
            let o = u64::from_le_bytes(off.data[at..at + 8].try_into().unwrap_or([0; 8]));
            if (i == 0 && o != 0) || o < last || o > text.count {
                return Err(bad("page offsets"));
            }
            if i > 0 {
                let name = std::str::from_utf8(&text.data[last as usize..o as usize])
                    .map_err(|_| bad("page name"))?;
                t.pages.push(name.to_string());
            }
            last = o;
        }
        if last != text.count {
            return Err(bad("page text length"));
        }
        let (nsegs, narcs) = (seg.count, arc.count);
        t.rows.reserve_exact(n);
        for i in 0..n {
            let rid = u64::from_le_bytes(id.data[i * 8..i * 8 + 8].try_into().unwrap_or([0; 8]));
            let (l, p, tr, pb) = (
                f64_row::<3>(&link, i),
                f64_row::<2>(&point, i),
                f64_row::<2>(&trans, i),
                f64_row::<4>(&pbox, i),
            );
            if !(finite(&l) && finite(&p) && finite(&tr) && finite(&pb)) {
                return Err(bad("a value is not finite"));
            }
            let linkage = linkage_of_cells(l, &gear.data[i * 24..i * 24 + 24])
                .ok_or_else(|| bad(format!("row {i}: not a valid linkage")))?;
            let [pg] = u32_row::<1>(&page, i);
            let [seg_start, seg_count] = u32_row::<2>(&segs, i);
            let [arc_start, arc_count] = u32_row::<2>(&arcs, i);
            let [crunodes, cusps] = u32_row::<2>(&dbl, i);
            let f = &flags.data[i * 5..i * 5 + 5];
            if u64::from(seg_start) + u64::from(seg_count) > nsegs
                || u64::from(arc_start) + u64::from(arc_count) > narcs
                || (pg != u32::MAX && pg as usize >= npages)
                || f[0] > 1
                || f[2] > 1
                || f[3] > 1
                || f[4] > 1
            {
                return Err(bad(format!("row {i} refers outside the table")));
            }
            t.rows.push(CurveRow {
                id: rid,
                linkage,
                point: p,
                transmission_deg: tr,
                page_bbox: pb,
                page: pg,
                seg_start,
                seg_count,
                arc_start,
                arc_count,
                crunodes,
                cusps,
                circuit: if f[0] == 1 {
                    Circuit::Crossed
                } else {
                    Circuit::Open
                },
                class: *LinkageClass::ALL
                    .get(f[1] as usize)
                    .ok_or_else(|| bad("class"))?,
                symmetric: f[2] == 1,
                has_features: f[3] == 1,
                trivial: f[4] == 1,
            });
        }
        t.segments.reserve_exact(nsegs as usize);
        for i in 0..nsegs as usize {
            let v = f64_row::<6>(&seg, i);
            if !finite(&v) {
                return Err(bad("a segment value is not finite"));
            }
            t.segments.push(SegmentRow {
                start_deg: v[0],
                span_deg: v[1],
                straightness_pct: v[2],
                velocity_variation_pct: v[3],
                length: v[4],
                direction_deg: v[5],
            });
        }
        t.arcs.reserve_exact(narcs as usize);
        for i in 0..narcs as usize {
            let v = f64_row::<7>(&arc, i);
            let s = side.data[i];
            if !finite(&v) || s > 1 {
                return Err(bad("an arc value is not valid"));
            }
            t.arcs.push(ArcRow {
                start_deg: v[0],
                span_deg: v[1],
                radius: v[2],
                deviation_pct: v[3],
                center: [v[4], v[5]],
                concave: if s == 1 { Side::Right } else { Side::Left },
                turn_deg: v[6],
            });
        }
        Ok(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::IndexKey;

    fn row(id: u64, linkage: Linkage) -> CurveRow {
        CurveRow {
            id,
            linkage,
            point: [0.5, -0.25],
            circuit: Circuit::Open,
            class: LinkageClass::ALL[14],
            transmission_deg: [40.0, 120.0],
            page: u32::MAX,
            page_bbox: [0.0; 4],
            seg_start: 0,
            seg_count: 0,
            arc_start: 0,
            arc_count: 0,
            symmetric: false,
            crunodes: 0,
            cusps: 0,
            has_features: false,
            trivial: false,
        }
    }

    #[test]
    fn rows_of_both_mechanisms_round_trip() {
        let ratio = GearRatio::new(-1, 2).unwrap();
        let t = SearchTable {
            rows: vec![
                row(0, FourBar::new(2.5, 3.0, 3.5).unwrap().into()),
                row(
                    1,
                    GearedFiveBar::new(3.0, 2.0, 4.0, 0.5, ratio, 270.0)
                        .unwrap()
                        .into(),
                ),
            ],
            ..SearchTable::default()
        };
        let key = IndexKey { bytes: 1, hash: 2 };
        assert_eq!(
            SearchTable::from_cache_bytes(&t.to_cache_bytes(key), key).unwrap(),
            t
        );
    }

    #[test]
    fn gear_cells_are_checked() {
        let g =
            GearedFiveBar::new(3.0, 2.0, 4.0, 0.5, GearRatio::integer(2).unwrap(), 90.0).unwrap();
        let (link, gear) = linkage_cells(&Linkage::GearedFiveBar(g));
        assert_eq!(linkage_of_cells(link, &gear), Some(g.into()));
        // A ratio not in lowest terms, a zero denominator, a NaN phase: refused.
        for (at, bytes) in [
            (16, 4i32.to_le_bytes().to_vec()),
            (20, 0i32.to_le_bytes().to_vec()),
            (8, f64::NAN.to_le_bytes().to_vec()),
        ] {
            let mut bad = gear;
            bad[at..at + bytes.len()].copy_from_slice(&bytes);
            if at == 16 {
                bad[20..24].copy_from_slice(&2i32.to_le_bytes());
            }
            assert_eq!(linkage_of_cells(link, &bad), None, "{at}");
        }
        // A four-bar with a non-positive length: refused.
        assert_eq!(linkage_of_cells([2.0, 0.0, 3.0], &[0; 24]), None);
    }
}
