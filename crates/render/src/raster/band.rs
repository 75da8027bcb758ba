//! Drawing a page band by band: the display list is planned once (which primitives,
//! and which pieces of each stroke, reach each band of [`BAND_ROWS`] rows), then
//! replayed band after band, each primitive drawing only the band's rows, and each band
//! is PNG-encoded (and cleared) as soon as it is drawn, while its rows are in cache.
//! Drawn whole, every curve swept the 16.8 MB page from top to bottom, one cache miss per
//! row it crossed, and the encoder read the page once more.
//!
//! The pixels are those of the page drawn whole, byte for byte:
//! - every primitive's pixels in a row depend only on that row (the stroke scan
//!   converter, rings, rectangles, glyph and halo tiles), and a pixel sees the
//!   primitives in display order in both ways;
//! - a stroke's ink in a row is the maximum over its segments that reach the row, so
//!   stroking only the pieces that reach a band (in pieces of [`PIECE`] segments that
//!   share their end points) gives the band's rows of the whole stroke;
//! - polygons are scan-converted once, before the first band: a gray or paper polygon's
//!   coverage as [`RasterPage::scratch_cover`] always made it, a black polygon's by the
//!   very tiny-skia call the whole page makes (the same mask, the same path), on the page
//!   while it is blank, whose coverage is then blended as tiny-skia blends it;
//! - the gray layer is composited where the page drawn whole composites it: the plan
//!   follows the ink and layer level through the list and puts a composite step into
//!   every band whose layer may hold gray at each of those points.

use super::{Cover, HaloKey, RasterPage, axis_rect};
use crate::Canvas;
use coupler_layout::{DisplayList, Ink, PagePoint, Primitive};

/// Rows per band.
pub(crate) const BAND_ROWS: usize = 64;

/// Segments per piece of a stroke.
const PIECE: usize = 16;

/// One step of a band.
#[derive(Clone, Copy, Debug)]
enum Step {
    /// Draw display item `.0` (its rows in the band).
    Item(u32),
    /// Stroke piece `.1` of display item `.0`; consecutive pieces of one item are one
    /// stroke.
    Piece(u32, u32),
    /// Composite polygon coverage `.1` of display item `.0`.
    Cover(u32, u32),
    /// Composite the gray layer.
    Flush,
    /// Draw text item `.0` from its placement `.1` ([`Bands::labels`]).
    Text(u32, u32),
}

/// The band plan of a page, kept from page to page (its vectors keep their memory).
#[derive(Default)]
pub(crate) struct Bands {
    steps: Vec<Vec<Step>>,
    /// Bands whose gray layer may hold gray (since their last composite step).
    pending: Vec<bool>,
    /// `[line, first point, last point]` of each stroke piece.
    pieces: Vec<[u32; 3]>,
    covers: Vec<Cover>,
    /// The ink of each display item.
    inks: Vec<Ink>,
    placed: Vec<(i64, i64, HaloKey)>,
    /// The labels' placed tiles (page x, page y, key), made once by the plan and drawn
    /// from in every band a label reaches: `labels[l]` is label `l`'s halo tiles and
    /// glyph tiles, ranges of `tiles`.
    tiles: Vec<(i64, i64, HaloKey)>,
    labels: Vec<[(usize, usize); 2]>,
}

/// Whether every number of the display list is finite and of a sane size (the plan's
/// row extents assume it; anything else is drawn whole).
fn plannable(display: &DisplayList) -> bool {
    let ok = |v: f64| v.is_finite() && v.abs() < 1e7;
    let pts = |ps: &[PagePoint]| ps.iter().all(|p| ok(p[0]) && ok(p[1]));
    display.items.iter().all(|item| match item {
        Primitive::Polyline { points, width } => pts(points) && ok(*width),
        Primitive::Polylines { lines, width } => lines.iter().all(|l| pts(l)) && ok(*width),
        Primitive::Rect { rect, width } => rect.iter().all(|&v| ok(v)) && ok(*width),
        Primitive::Polygon { points } => pts(points),
        Primitive::Circle {
            center,
            radius,
            width,
        } => pts(&[*center]) && ok(*radius) && width.is_none_or(ok),
        Primitive::Text {
            pos, size, halo, ..
        } => pts(&[*pos]) && ok(*size) && ok(*halo),
        Primitive::Ink(_) => true,
    })
}

impl RasterPage {
    /// Draws `display` (a blank page first) band by band and encodes it as the fast PNG
    /// ([`RasterPage::take_png`]'s bytes for the page drawn whole), leaving the page
    /// blank. `None` when the page cannot be drawn in bands (a number out of range): the
    /// caller draws it whole.
    pub(super) fn render_bands(
        &mut self,
        display: &DisplayList,
        encode: &mut std::time::Duration,
    ) -> Option<std::io::Result<Vec<u8>>> {
        if !plannable(display) {
            return None;
        }
        self.clear();
        let mut bands = std::mem::take(&mut self.bands);
        bands.plan(self, display);
        let (w, h, dpi) = (self.width(), self.height(), self.dpi);
        let capacity = if self.last_png == 0 {
            1 << 19
        } else {
            self.last_png + self.last_png / 8 + 4096
        };
        let mut png = match super::FastPng::begin(w, h, dpi, capacity) {
            Ok(p) => p,
            Err(e) => return Some(Err(e)),
        };
        let (h, stride) = (h as usize, w as usize);
        // The band's buffer: blank, the band's rows and the row above it. The last page's
        // left it blank (the encoder clears each row as it reads it), so it is zeroed only
        // when its size changes.
        let len = (BAND_ROWS + 1) * stride;
        if self.band_buf.len() != len {
            self.band_buf.clear();
            self.band_buf.resize(len, 0);
        }
        self.banded = true;
        for (b, steps) in bands.steps.iter().enumerate() {
            let (y0, y1) = (b * BAND_ROWS, ((b + 1) * BAND_ROWS).min(h));
            if y0 > 0 {
                // The last row of the band before (encoded, not yet cleared: the
                // encoder reads it above this band's first row) moves to the buffer's
                // first row; the rest of the buffer is blank (the encoder cleared it).
                // Its ink is in its marked blocks: only those are zeroed.
                let last = y0 - 1 - self.first;
                if last > 0 {
                    self.band_buf
                        .copy_within(last * stride..(last + 1) * stride, 0);
                    self.dirty.clear_row(
                        y0 - 1,
                        &mut self.band_buf[last * stride..(last + 1) * stride],
                    );
                }
                self.first = y0 - 1;
            }
            self.rows = (y0, y1);
            self.replay(&bands, steps, display);
            self.flush_gray();
            let t = std::time::Instant::now();
            png.rows(&mut self.band_buf, self.first, &self.dirty, y1, true);
            *encode += t.elapsed();
        }
        let t = std::time::Instant::now();
        let bytes = png.finish(&mut self.band_buf, self.first, &self.dirty, true);
        *encode += t.elapsed();
        self.banded = false;
        self.first = 0;
        self.rows = (0, h);
        self.bands = bands;
        self.dirty.reset();
        self.ink = Ink::Black;
        self.trim_tiles();
        if let Ok(b) = &bytes {
            self.last_png = b.len();
        }
        Some(bytes)
    }

    /// Draws one band's steps (the rows `self.rows`).
    fn replay(&mut self, bands: &Bands, steps: &[Step], display: &DisplayList) {
        let mut e = 0;
        while e < steps.len() {
            match steps[e] {
                Step::Flush => self.flush_gray(),
                Step::Text(i, l) => {
                    // The label as `Canvas::text` draws it, from the plan's placement.
                    self.ink = bands.inks[i as usize];
                    let [halo, glyphs] = bands.labels[l as usize];
                    if let Primitive::Text { halo: h, .. } = &display.items[i as usize]
                        && *h > 0.0
                    {
                        self.draw_halo(&bands.tiles[halo.0..halo.1]);
                    }
                    self.draw_glyphs(&bands.tiles[glyphs.0..glyphs.1]);
                }
                Step::Cover(i, c) => {
                    self.ink = bands.inks[i as usize];
                    self.apply_cover(&bands.covers[c as usize], self.ink);
                }
                Step::Item(i) => {
                    self.ink = bands.inks[i as usize];
                    match &display.items[i as usize] {
                        Primitive::Rect { rect, width } => self.stroke_rect(*rect, *width),
                        Primitive::Polygon { points } => self.fill_polygon(points),
                        Primitive::Circle {
                            center,
                            radius,
                            width,
                        } => self.circle(*center, *radius, *width),
                        Primitive::Text {
                            pos,
                            size,
                            anchor,
                            text,
                            halo,
                        } => self.text(*pos, *size, *anchor, text, *halo),
                        Primitive::Polyline { .. }
                        | Primitive::Polylines { .. }
                        | Primitive::Ink(_) => {}
                    }
                }
                Step::Piece(i, _) => {
                    let end = steps[e..]
                        .iter()
                        .position(|s| !matches!(s, Step::Piece(j, _) if *j == i))
                        .map_or(steps.len(), |n| e + n);
                    self.ink = bands.inks[i as usize];
                    let (lines, width) = match &display.items[i as usize] {
                        Primitive::Polyline { points, width } => {
                            (std::slice::from_ref(points), *width)
                        }
                        Primitive::Polylines { lines, width } => (lines.as_slice(), *width),
                        _ => (&[][..], 0.0),
                    };
                    let pieces = steps[e..end].iter().filter_map(|s| match *s {
                        Step::Piece(_, p) => {
                            let [l, a, b] = bands.pieces[p as usize];
                            Some(&lines[l as usize][a as usize..=b as usize])
                        }
                        _ => None,
                    });
                    self.stroke_paths(pieces, width);
                    e = end;
                    continue;
                }
            }
            e += 1;
        }
    }

    /// A black polygon's coverage as tiny-skia fills it on this (blank) page, read off
    /// the page's box of the path and erased there again.
    fn blank_cover(&mut self, path: &tiny_skia::Path) -> Option<Cover> {
        let [x0, y0, x1, y1] = self.path_box(path)?;
        self.mask.fill_path(
            path,
            tiny_skia::FillRule::Winding,
            true,
            tiny_skia::Transform::identity(),
        );
        let (x0, y0, x1, y1) = (x0 as usize, y0 as usize, x1 as usize, y1 as usize);
        let stride = self.width() as usize;
        let data = self.mask.data_mut();
        let mut cov = Vec::with_capacity((x1 - x0) * (y1 - y0));
        for j in y0..y1 {
            let row = &mut data[j * stride + x0..j * stride + x1];
            cov.extend_from_slice(row);
            row.fill(0);
        }
        Some(Cover {
            x0,
            y0,
            w: x1 - x0,
            cov,
        })
    }
}

/// Rows `[lo, hi)` of a page of `h` rows within `m` pixels of `[y0, y1]`.
fn rows_within(y0: f64, y1: f64, m: f64, h: usize) -> (usize, usize) {
    let lo = (y0.min(y1) - m).floor().clamp(0.0, h as f64) as usize;
    let hi = (y0.max(y1) + m).ceil().clamp(0.0, h as f64) as usize;
    (lo, hi)
}

impl Bands {
    /// Plans `display` on `page` (blank; its polygons are scan-converted here).
    fn plan(&mut self, page: &mut RasterPage, display: &DisplayList) {
        let h = page.height() as usize;
        let n = h.div_ceil(BAND_ROWS);
        self.steps.truncate(n);
        for s in &mut self.steps {
            s.clear();
        }
        self.steps.resize_with(n, Vec::new);
        self.pending.clear();
        self.pending.resize(n, false);
        self.pieces.clear();
        self.covers.clear();
        self.inks.clear();
        self.tiles.clear();
        self.labels.clear();
        let k = page.px_per_pt;
        let mut ink = Ink::Black;
        // The gray layer's level as the page drawn whole would have it.
        let mut level = page.gray.level;
        for (i, item) in display.items.iter().enumerate() {
            self.inks.push(ink);
            let i = i as u32;
            match item {
                Primitive::Ink(x) => ink = *x,
                Primitive::Polyline { points, width } => {
                    self.strokes(
                        page,
                        i,
                        std::slice::from_ref(points),
                        *width,
                        ink,
                        &mut level,
                    );
                }
                Primitive::Polylines { lines, width } => {
                    self.strokes(page, i, lines, *width, ink, &mut level);
                }
                Primitive::Rect { rect, width } => {
                    let sides = page.rect_sides(*rect, *width);
                    if ink == Ink::Paper && sides.iter().any(|s| page.rect_on_page(*s).is_some()) {
                        self.flush();
                    }
                    let (lo, hi) = sides.iter().fold((f64::MAX, f64::MIN), |(lo, hi), s| {
                        (lo.min(s[1]).min(s[3]), hi.max(s[1]).max(s[3]))
                    });
                    self.add(rows_within(lo, hi, 2.0, h), Step::Item(i), false);
                }
                Primitive::Polygon { points } => {
                    if points.len() < 3 {
                        continue;
                    }
                    if let Some(r) = axis_rect(points) {
                        let r = r.map(|v| v * k);
                        if ink == Ink::Paper && page.rect_on_page(r).is_some() {
                            self.flush();
                        }
                        self.add(rows_within(r[1], r[3], 2.0, h), Step::Item(i), false);
                        continue;
                    }
                    let Some(path) = page.polygon_path(points) else {
                        continue;
                    };
                    self.target(ink, &mut level);
                    let cover = match ink {
                        Ink::Black => page.blank_cover(&path),
                        _ => page.scratch_cover(&path),
                    };
                    if let Some(c) = cover {
                        let rows = (c.y0, c.y0 + c.cov.len() / c.w.max(1));
                        let step = Step::Cover(i, self.covers.len() as u32);
                        self.covers.push(c);
                        self.add(rows, step, matches!(ink, Ink::Gray(_)));
                    }
                }
                Primitive::Circle {
                    center,
                    radius,
                    width,
                } => {
                    self.target(ink, &mut level);
                    let m = (radius.abs() + width.map_or(0.0, |w| 0.5 * w.abs())) * k + 3.0;
                    let y = center[1] * k;
                    self.add(
                        rows_within(y, y, m, h),
                        Step::Item(i),
                        matches!(ink, Ink::Gray(_)),
                    );
                }
                Primitive::Text {
                    pos,
                    size,
                    anchor,
                    text,
                    halo,
                } => {
                    let (mut lo, mut hi) = (i64::MAX, i64::MIN);
                    let mut placed = std::mem::take(&mut self.placed);
                    let mut ranges = [(0, 0); 2];
                    for (m, halo) in [(*halo > 0.0).then_some(*halo), None]
                        .into_iter()
                        .enumerate()
                    {
                        if halo.is_none() {
                            page.place_label(*pos, *size, *anchor, text, None, &mut placed);
                        } else {
                            page.place_label(*pos, *size, *anchor, text, halo, &mut placed);
                            if !placed.is_empty() {
                                // The halo composites the gray layer first.
                                self.flush();
                            }
                        }
                        for (_, ty, key) in &placed {
                            if let Some(Some(tile)) = page.halos.get(key) {
                                lo = lo.min(*ty);
                                hi = hi.max(ty + tile.h as i64);
                            }
                        }
                        // Kept for the bands (the tiles stay cached while the page is
                        // drawn: the cache is trimmed between pages only).
                        ranges[m] = (self.tiles.len(), self.tiles.len() + placed.len());
                        self.tiles.extend_from_slice(&placed);
                    }
                    self.placed = placed;
                    if lo < hi {
                        let rows = (
                            (lo - 1).clamp(0, h as i64) as usize,
                            (hi + 1).clamp(0, h as i64) as usize,
                        );
                        let step = Step::Text(i, self.labels.len() as u32);
                        self.labels.push(ranges);
                        self.add(rows, step, false);
                    }
                }
            }
        }
    }

    /// A stroke (one or more polylines) of item `i`: its pieces in the bands they reach.
    fn strokes(
        &mut self,
        page: &RasterPage,
        i: u32,
        lines: &[Vec<PagePoint>],
        width: f64,
        ink: Ink,
        level: &mut u8,
    ) {
        self.target(ink, level);
        let r = (0.5 * width * page.px_per_pt) as f32;
        if !r.is_finite() {
            return;
        }
        let (m, h) = (f64::from(r.abs()) + 3.0, page.height() as usize);
        let gray = matches!(ink, Ink::Gray(_));
        for (l, points) in lines.iter().enumerate() {
            let last = points.len().saturating_sub(1);
            let mut a = 0;
            while a < points.len() {
                let b = (a + PIECE).min(last);
                let (lo, hi) = points[a..=b]
                    .iter()
                    .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
                        let y = f64::from(page.px(*p).1);
                        (lo.min(y), hi.max(y))
                    });
                let step = Step::Piece(i, self.pieces.len() as u32);
                self.pieces.push([l as u32, a as u32, b as u32]);
                self.add(rows_within(lo, hi, m, h), step, gray);
                if b == last {
                    break;
                }
                a = b;
            }
        }
    }

    /// What the page drawn whole does to the gray layer before drawing in `ink` through
    /// the scan converter or a polygon fill: a gray of another level composites the
    /// layer (and becomes its level), paper composites it.
    fn target(&mut self, ink: Ink, level: &mut u8) {
        match ink {
            Ink::Gray(l) => {
                if *level != l {
                    self.flush();
                    *level = l;
                }
            }
            Ink::Paper => self.flush(),
            Ink::Black => {}
        }
    }

    /// A composite step in every band whose layer may hold gray.
    fn flush(&mut self) {
        for (steps, pending) in self.steps.iter_mut().zip(&mut self.pending) {
            if *pending {
                steps.push(Step::Flush);
                *pending = false;
            }
        }
    }

    /// `step` in every band of rows `[lo, hi)`; `gray`: it puts gray in the layer.
    fn add(&mut self, (lo, hi): (usize, usize), step: Step, gray: bool) {
        if lo >= hi {
            return;
        }
        for b in lo / BAND_ROWS..=(hi - 1) / BAND_ROWS {
            self.steps[b].push(step);
            if gray {
                self.pending[b] = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::raster::lerp_white;
    use crate::{Canvas, PngCompression, RasterPage, draw};
    use coupler_layout::{Anchor, DisplayList, Ink, PagePoint, Primitive};

    /// tiny-skia's blend, on a blank pixel, gives the coverage itself.
    #[test]
    fn lerp_white_on_blank_is_the_coverage() {
        for c in 0..=255u8 {
            assert_eq!(lerp_white(0, c), c);
            assert_eq!(lerp_white(c, 0), c);
        }
    }

    /// A black polygon filled by tiny-skia over ink is the polygon filled on a blank
    /// page, blended with `lerp_white`.
    #[test]
    fn a_black_polygon_blends_as_tiny_skia_fills_it() {
        let (w, h) = (120u32, 90u32);
        let mut page = RasterPage::new(w, h, 72.0).unwrap();
        // Ink of every level under the polygon.
        for j in 0..h {
            page.set_ink(Ink::Gray((j * 255 / h) as u8));
            page.fill_rect_px(0.0, f64::from(j), f64::from(w), f64::from(j) + 1.0);
        }
        let under = page.ink().to_vec();
        page.set_ink(Ink::Black);
        let tri: [PagePoint; 3] = [[10.3, 4.7], [113.9, 40.2], [30.1, 87.6]];
        page.fill_polygon(&tri);
        let want = page.ink().to_vec();
        let mut blank = RasterPage::new(w, h, 72.0).unwrap();
        let path = blank.polygon_path(&tri).unwrap();
        let cover = blank.blank_cover(&path).unwrap();
        assert!(blank.ink().iter().all(|&x| x == 0), "left blank");
        let mut got = under.clone();
        let mut partial = 0;
        for (j, row) in cover.cov.chunks(cover.w).enumerate() {
            for (i, &c) in row.iter().enumerate() {
                let at = (cover.y0 + j) * w as usize + cover.x0 + i;
                got[at] = lerp_white(got[at], c);
                partial += usize::from(c != 0 && c != 255);
            }
        }
        assert!(partial > 100, "{partial} edge pixels");
        assert_eq!(got, want);
    }

    /// Every kind of primitive, across band edges, in black, grays and paper, and gray
    /// levels that change in other bands than the ones they draw in.
    fn every_kind(w: f64, h: f64) -> DisplayList {
        let mut dl = DisplayList::new(w, h);
        let push = |dl: &mut DisplayList, p| dl.items.push(p);
        // Dashes of a wave crossing every band, in gray.
        let wave: Vec<PagePoint> = (0..400)
            .map(|i| {
                let t = f64::from(i) / 399.0;
                [5.0 + t * (w - 10.0), h * (0.5 + 0.45 * (t * 11.0).sin())]
            })
            .collect();
        push(&mut dl, Primitive::Ink(Ink::Gray(150)));
        push(
            &mut dl,
            Primitive::Polylines {
                lines: wave
                    .chunks(9)
                    .step_by(2)
                    .map(<[PagePoint]>::to_vec)
                    .collect(),
                width: 1.1,
            },
        );
        // A gray stroke near the top, another gray's stroke far below (the layer is
        // composited there), the first gray again over the first stroke.
        push(
            &mut dl,
            Primitive::Polyline {
                points: vec![[10.0, 6.0], [w - 10.0, 9.0]],
                width: 2.0,
            },
        );
        push(&mut dl, Primitive::Ink(Ink::Gray(80)));
        push(
            &mut dl,
            Primitive::Polyline {
                points: vec![[10.0, h - 6.0], [w - 10.0, h - 9.0]],
                width: 2.0,
            },
        );
        push(&mut dl, Primitive::Ink(Ink::Gray(150)));
        push(
            &mut dl,
            Primitive::Polyline {
                points: vec![[w - 10.0, 6.0], [10.0, 9.5]],
                width: 2.0,
            },
        );
        // One long black polyline down the page, a dot, a stroke in paper.
        push(&mut dl, Primitive::Ink(Ink::Black));
        push(
            &mut dl,
            Primitive::Polyline {
                points: (0..60)
                    .map(|i| [8.0 + f64::from(i) * 0.3 * w / 60.0, f64::from(i) * h / 59.0])
                    .collect(),
                width: 0.5,
            },
        );
        push(
            &mut dl,
            Primitive::Polyline {
                points: vec![[0.6 * w, 0.31 * h]],
                width: 3.0,
            },
        );
        push(
            &mut dl,
            Primitive::Rect {
                rect: [12.0, 12.0, w - 12.0, h - 12.0],
                width: 0.6,
            },
        );
        push(&mut dl, Primitive::Ink(Ink::Paper));
        push(
            &mut dl,
            Primitive::Polyline {
                points: vec![[0.2 * w, 0.1 * h], [0.3 * w, 0.9 * h]],
                width: 1.5,
            },
        );
        // Triangles across band edges: black, gray, paper; a paper panel.
        push(&mut dl, Primitive::Ink(Ink::Black));
        push(
            &mut dl,
            Primitive::Polygon {
                points: vec![
                    [0.4 * w, 0.2 * h],
                    [0.55 * w, 0.26 * h],
                    [0.43 * w, 0.5 * h],
                ],
            },
        );
        push(&mut dl, Primitive::Ink(Ink::Gray(100)));
        push(
            &mut dl,
            Primitive::Polygon {
                points: vec![[0.6 * w, 0.4 * h], [0.8 * w, 0.45 * h], [0.62 * w, 0.7 * h]],
            },
        );
        push(
            &mut dl,
            Primitive::Circle {
                center: [0.5 * w, 0.5 * h],
                radius: 0.3 * h,
                width: Some(0.8),
            },
        );
        push(&mut dl, Primitive::Ink(Ink::Paper));
        push(
            &mut dl,
            Primitive::Polygon {
                points: vec![[0.7 * w, 0.1 * h], [0.9 * w, 0.15 * h], [0.75 * w, 0.3 * h]],
            },
        );
        push(
            &mut dl,
            Primitive::Polygon {
                points: vec![
                    [0.1 * w, 0.6 * h],
                    [0.3 * w, 0.6 * h],
                    [0.3 * w, 0.75 * h],
                    [0.1 * w, 0.75 * h],
                ],
            },
        );
        push(&mut dl, Primitive::Ink(Ink::Black));
        push(
            &mut dl,
            Primitive::Circle {
                center: [0.35 * w, 0.33 * h],
                radius: 2.5,
                width: None,
            },
        );
        // Labels with halos over the gray, across band edges; gray text; a tall size.
        for (k, y) in [0.33, 0.5, 0.66].into_iter().enumerate() {
            push(
                &mut dl,
                Primitive::Text {
                    pos: [0.2 * w, y * h],
                    size: 7.0 + 5.0 * k as f64,
                    anchor: [Anchor::Start, Anchor::Middle, Anchor::End][k],
                    text: "(1.875, −1.25) θ 35° Ag".into(),
                    halo: 1.6,
                },
            );
        }
        push(&mut dl, Primitive::Ink(Ink::Gray(120)));
        push(
            &mut dl,
            Primitive::Text {
                pos: [0.5 * w, 0.8 * h],
                size: 9.0,
                anchor: Anchor::Start,
                text: "row v = 1.5 (0.5 L3)".into(),
                halo: 0.0,
            },
        );
        // Gray strokes after the halos, and a last gray stroke left in the layer.
        push(
            &mut dl,
            Primitive::Polylines {
                lines: wave
                    .chunks(7)
                    .skip(1)
                    .step_by(3)
                    .map(<[PagePoint]>::to_vec)
                    .collect(),
                width: 0.7,
            },
        );
        dl
    }

    /// Drawn band by band, a page is byte for byte the page drawn whole, at DPIs that
    /// put the band edges everywhere, on a fresh buffer and on one reused page after
    /// page; the buffer is left blank.
    #[test]
    fn pages_drawn_in_bands_are_the_pages_drawn_whole() {
        let (wpt, hpt) = (300.0, 200.0);
        let dl = every_kind(wpt, hpt);
        for dpi in [72.0, 150.0, 217.0, 300.0] {
            let k = dpi / 72.0;
            let (w, h) = ((wpt * k) as u32, (hpt * k) as u32);
            let mut whole = RasterPage::new(w, h, dpi).unwrap();
            draw(&dl, &mut whole);
            let want = whole.take_png(PngCompression::Fast).unwrap();
            let mut banded = RasterPage::new(w, h, dpi).unwrap();
            for round in 0..2 {
                let (got, _) = banded.render_png(&dl, PngCompression::Fast).unwrap();
                assert!(got == want, "dpi {dpi}, round {round}: bytes differ");
                assert!(banded.ink().iter().all(|&x| x == 0), "left blank");
                // The next page's bands are drawn into it without zeroing it first.
                assert!(banded.band_buf.iter().all(|&x| x == 0), "band buffer blank");
            }
            // Best compression: drawn whole, the same bytes as before.
            draw(&dl, &mut whole);
            let best = whole.take_png(PngCompression::Best).unwrap();
            let (got, _) = banded.render_png(&dl, PngCompression::Best).unwrap();
            assert!(got == best, "dpi {dpi}: best differs");
        }
    }
}
