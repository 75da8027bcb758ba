//! A [`SearchTable`] as the search cache's columns (see [`crate::cache`] for the
//! container and its checks): one fixed-width column per field, encoded as in the
//! columns file (`colfile.rs`: one encoding for both). To add a field: add a column
//! there, and bump [`TABLE_VERSION`]; an old cache is then rebuilt.

use crate::cache::{Column, Section, write_container};
use crate::colfile::{
    COLS, Kind, NCOLS, SIDE, arc_at, arc_is_valid, kind, push_arc, push_row, push_segment, row_at,
    segment_at, segment_is_valid,
};
use crate::key::IndexKey;
use crate::search::SearchTable;
use crate::{CacheError, read_container};

/// Version of the column set (the cache's and the columns file's table version): 2
/// added arcs' turn and the rows' `trivial` flag; 3 the rows' `row.gear` (a geared
/// five-bar's L5, φ and λ); 4 the transmission over each segment's and arc's window
/// (`seg.tr`, `arc.tr`; NaN where unknown); 5 one column per field of the segments and
/// arcs (a query reads only the fields it tests).
pub const TABLE_VERSION: u32 = 5;

fn bad(m: impl Into<String>) -> CacheError {
    CacheError(m.into())
}

impl SearchTable {
    /// The table's columns.
    fn columns(&self) -> Vec<Column> {
        let mut cols: Vec<Vec<u8>> = COLS
            .iter()
            .enumerate()
            .map(|(c, (_, element))| {
                let n = match kind(c) {
                    Kind::Seg => self.segments.len(),
                    Kind::Arc => self.arcs.len(),
                    Kind::Row => self.rows.len(),
                };
                Vec::with_capacity(element * n)
            })
            .collect();
        for r in &self.rows {
            push_row(&mut cols, r);
        }
        for s in &self.segments {
            push_segment(&mut cols, s);
        }
        for a in &self.arcs {
            push_arc(&mut cols, a);
        }
        let mut off = Vec::with_capacity(8 * (self.pages.len() + 1));
        let mut text = Vec::new();
        off.extend_from_slice(&0u64.to_le_bytes());
        for p in &self.pages {
            text.extend_from_slice(p.as_bytes());
            off.extend_from_slice(&(text.len() as u64).to_le_bytes());
        }
        let mut out: Vec<Column> = COLS
            .iter()
            .zip(cols)
            .map(|((tag, element), data)| Column {
                tag,
                element: *element as u32,
                data,
            })
            .collect();
        out.push(Column {
            tag: "page.off",
            element: 8,
            data: off,
        });
        out.push(Column {
            tag: "page.txt",
            element: 1,
            data: text,
        });
        out
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
        let n = find(COLS[0].0, COLS[0].1 as u32)?.count as usize;
        let mut cols: Vec<Section<'_>> = Vec::with_capacity(NCOLS);
        for (c, (tag, element)) in COLS.iter().enumerate() {
            let s = find(tag, *element as u32)?;
            if kind(c) == Kind::Row && s.count as usize != n {
                return Err(bad(format!("column {tag} length")));
            }
            cols.push(s);
        }
        // Every segment column holds as many segments as the first, every arc column as
        // many arcs.
        let first = |k: Kind| {
            (0..NCOLS)
                .find(|&c| kind(c) == k)
                .map_or(0, |c| cols[c].count)
        };
        let (nsegs, narcs) = (first(Kind::Seg), first(Kind::Arc));
        if (0..NCOLS).any(|c| match kind(c) {
            Kind::Seg => cols[c].count != nsegs,
            Kind::Arc => cols[c].count != narcs,
            Kind::Row => false,
        }) {
            return Err(bad("a segment or arc column's length"));
        }
        let (off, text) = (find("page.off", 8)?, find("page.txt", 1)?);
        if off.count == 0 {
            return Err(bad("column page.off"));
        }
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
        let data: Vec<&[u8]> = cols.iter().map(|s| s.data).collect();
        t.rows.reserve_exact(n);
        for i in 0..n {
            let r = row_at(&data, i, 0..nsegs, 0..narcs, npages as u64).map_err(CacheError)?;
            t.rows.push(r);
        }
        t.segments.reserve_exact(nsegs as usize);
        for k in 0..nsegs as usize {
            let s = segment_at(&data, k);
            if !segment_is_valid(&s) {
                return Err(bad("a segment value is not finite"));
            }
            t.segments.push(s);
        }
        t.arcs.reserve_exact(narcs as usize);
        for k in 0..narcs as usize {
            let a = arc_at(&data, k);
            if !arc_is_valid(&a) || data[SIDE][k] > 1 {
                return Err(bad("an arc value is not valid"));
            }
            t.arcs.push(a);
        }
        Ok(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::IndexKey;
    use crate::colfile::{linkage_cells, linkage_of_cells};
    use crate::search::CurveRow;
    use coupler_kinematics::{Circuit, FourBar, GearRatio, GearedFiveBar, Linkage, LinkageClass};

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
