//! The coverage of one gray level, kept until it is composited into the page.
//!
//! Strokes of one gray merge into one coverage (so that crossing curves of one gray do not
//! darken where they cross), which is composited into the page when the level changes,
//! before paper is drawn and when the page is read. The layer is sparse: 64 × 64 tiles,
//! made where gray is drawn and reused page after page, with the span of every tile row
//! that holds coverage, so a layer costs memory and compositing time only where there is
//! gray (a page-sized layer was 16.8 MB per worker at 300 dpi).

use crate::dirty::Dirty;

/// Tile side, pixels.
const TILE: usize = 64;

/// No tile.
const NONE: u32 = u32::MAX;

/// One tile: its number in the page's tile grid, its coverage and each row's span
/// `[lo, hi)` (empty when `lo ≥ hi`).
struct Tile {
    at: u32,
    cov: Box<[u8]>,
    span: [(u8, u8); TILE],
}

/// A sparse coverage layer of one gray level over a `width × height` page.
pub(crate) struct GrayLayer {
    pub(crate) level: u8,
    width: usize,
    height: usize,
    cols: usize,
    /// Per tile of the page: its index in `tiles`, or [`NONE`].
    slot: Vec<u32>,
    /// Tiles made so far; the first `used` hold coverage.
    tiles: Vec<Tile>,
    used: usize,
}

impl GrayLayer {
    /// An empty layer over a `width × height` page.
    pub(crate) fn new(width: usize, height: usize) -> GrayLayer {
        let cols = width.div_ceil(TILE);
        GrayLayer {
            level: 0,
            width,
            height,
            cols,
            slot: vec![NONE; cols * height.div_ceil(TILE)],
            tiles: Vec::new(),
            used: 0,
        }
    }

    /// Whether any coverage waits to be composited.
    pub(crate) fn any(&self) -> bool {
        self.used > 0
    }

    /// Merges coverage `cov` into row `j`, columns `x0..x0 + cov.len()` ("source over":
    /// `l ← l + (255 − l)·c`, rounded), and clears `cov`.
    pub(crate) fn add_span(&mut self, j: usize, x0: usize, cov: &mut [u8]) {
        let x1 = (x0 + cov.len()).min(self.width);
        if j >= self.height || x0 >= x1 {
            cov.fill(0);
            return;
        }
        let (ty, r) = (j / TILE, j % TILE);
        let mut x = x0;
        while x < x1 {
            let tx = x / TILE;
            let end = ((tx + 1) * TILE).min(x1);
            let at = ty * self.cols + tx;
            let k = match self.slot[at] {
                NONE => {
                    if self.used == self.tiles.len() {
                        self.tiles.push(Tile {
                            at: at as u32,
                            cov: vec![0; TILE * TILE].into_boxed_slice(),
                            span: [(u8::MAX, 0); TILE],
                        });
                    }
                    self.tiles[self.used].at = at as u32;
                    self.slot[at] = self.used as u32;
                    self.used += 1;
                    self.used - 1
                }
                k => k as usize,
            };
            let tile = &mut self.tiles[k];
            let (lo, hi) = (x - tx * TILE, end - tx * TILE);
            let row = &mut tile.cov[r * TILE + lo..r * TILE + hi];
            for (l, c) in row.iter_mut().zip(&cov[x - x0..end - x0]) {
                let (ll, cc) = (u32::from(*l), u32::from(*c));
                *l = (ll + ((255 - ll) * cc + 127) / 255) as u8;
            }
            let s = &mut tile.span[r];
            *s = (s.0.min(lo as u8), s.1.max(hi as u8));
            x = end;
        }
        cov.fill(0);
    }

    /// Composites the layer into `page` (row-major ink, the layer's width, from page row
    /// `first` on) with the layer's gray, marks what it inked in `dirty` and empties the
    /// layer.
    pub(crate) fn flush(
        &mut self,
        page: &mut [u8],
        first: usize,
        dirty: &mut Dirty,
        overprint: impl Fn(u8, u8, u32) -> u8,
    ) {
        if self.used == 0 {
            return;
        }
        let g = u32::from(self.level);
        for tile in &mut self.tiles[..self.used] {
            let at = tile.at as usize;
            let (ty, tx) = (at / self.cols, at % self.cols);
            for (r, s) in tile.span.iter_mut().enumerate() {
                if s.0 >= s.1 {
                    continue;
                }
                let (lo, hi) = (usize::from(s.0), usize::from(s.1));
                let (j, x) = (ty * TILE + r, tx * TILE);
                let at = (j - first) * self.width + x;
                let dst = &mut page[at + lo..at + hi];
                let src = &mut tile.cov[r * TILE + lo..r * TILE + hi];
                for (d, c) in dst.iter_mut().zip(src.iter()) {
                    *d = overprint(*d, *c, g);
                }
                src.fill(0);
                dirty.mark_px(x + lo, j, x + hi, j + 1);
                *s = (u8::MAX, 0);
            }
            self.slot[at] = NONE;
        }
        self.used = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spans_merge_across_tiles_and_flush_once() {
        let (w, h) = (300, 200);
        let mut layer = GrayLayer::new(w, h);
        layer.level = 255;
        let mut cov = vec![200u8; 150];
        layer.add_span(70, 40, &mut cov);
        assert!(cov.iter().all(|&c| c == 0), "cleared");
        let mut cov = vec![200u8; 10];
        layer.add_span(70, 100, &mut cov);
        assert!(layer.any());
        let mut page = vec![0u8; w * h];
        let mut dirty = Dirty::new(w, h);
        let op = |d: u8, c: u8, g: u32| {
            let (d, c) = (u32::from(d), u32::from(c));
            (d + ((255 - d) * c * g + 32_512) / 65_025) as u8
        };
        layer.flush(&mut page, 0, &mut dirty, op);
        assert!(!layer.any());
        // 200 over 200: 200 + 55·200/255 = 243.
        assert_eq!(page[70 * w + 105], 243);
        assert_eq!(page[70 * w + 40], 200);
        assert_eq!(page[70 * w + 189], 200);
        assert_eq!(page[70 * w + 190], 0);
        assert_eq!(page.iter().filter(|&&v| v != 0).count(), 150);
        // Flushed again: nothing more.
        layer.flush(&mut page, 0, &mut dirty, op);
        assert_eq!(page[70 * w + 105], 243);
        assert!(dirty.row_pair_spans(70).any(|(a, b)| a <= 40 && 189 < b));
        // Off the page: ignored.
        layer.add_span(500, 0, &mut [9u8; 10]);
        layer.add_span(10, 295, &mut [9u8; 10]);
        layer.flush(&mut page, 0, &mut dirty, op);
        assert_eq!(page[10 * w + 299], 9);
    }
}
