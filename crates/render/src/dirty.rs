//! Which parts of a page buffer may hold ink, so that clearing, compositing and encoding
//! visit only those (a tabloid page at 300 dpi is 16.8 MB, most of it paper).
//!
//! The buffer is cut into bands of [`BAND`] rows and at most 64 column blocks; a band's
//! blocks are the bits of one `u64`. Marks are conservative boxes (a pixel outside every
//! marked block is known to be 0); a mark is widened by one pixel on every side because
//! anti-aliasing reaches into the pixels a box's edges cross.

/// Rows per band.
pub(crate) const BAND: usize = 16;

/// Marked blocks of a `width × height` buffer.
#[derive(Clone, Debug)]
pub(crate) struct Dirty {
    width: usize,
    height: usize,
    /// Block width in pixels (a multiple of 8, so that blocks are whole `u64` words).
    block: usize,
    bands: Vec<u64>,
}

impl Dirty {
    /// Nothing marked.
    pub(crate) fn new(width: usize, height: usize) -> Dirty {
        let block = width.div_ceil(64).div_ceil(8).max(1) * 8;
        Dirty {
            width,
            height,
            block,
            bands: vec![0; height.div_ceil(BAND)],
        }
    }

    /// Marks the pixels a box `[x0, y0, x1, y1]` (pixel coordinates, any order of
    /// magnitude, NaN-safe) touches, widened by one pixel.
    pub(crate) fn mark(&mut self, b: [f32; 4]) {
        let cx = |v: f32| (v.max(0.0) as usize).min(self.width);
        let cy = |v: f32| (v.max(0.0) as usize).min(self.height);
        let (x0, x1) = (cx(b[0].floor() - 1.0), cx(b[2].ceil() + 1.0));
        let (y0, y1) = (cy(b[1].floor() - 1.0), cy(b[3].ceil() + 1.0));
        self.mark_px(x0, y0, x1, y1);
    }

    /// Marks the pixels within `r` of the segment `a`–`b` (pixel coordinates), band by
    /// band, so that a long slanted line marks a thin staircase, not its bounding box.
    pub(crate) fn mark_segment(&mut self, a: [f32; 2], b: [f32; 2], r: f32) {
        // Widen by a pixel: anti-aliasing touches every pixel the outline enters.
        let r = r.max(0.0) + 1.0;
        let (lo, hi) = (a[1].min(b[1]) - r, a[1].max(b[1]) + r);
        if !(lo.is_finite() && hi.is_finite() && a[0].is_finite() && b[0].is_finite()) {
            self.mark([a[0].min(b[0]) - r, lo, a[0].max(b[0]) + r, hi]);
            return;
        }
        let cy = |v: f32| (v.max(0.0) as usize).min(self.height);
        let (y0, y1) = (cy(lo.floor()), cy(hi.ceil()));
        if y1 <= y0 {
            return;
        }
        let dy = b[1] - a[1];
        for k in y0 / BAND..=(y1 - 1) / BAND {
            // The part of the segment within r of the band's rows.
            let (band_lo, band_hi) = ((k * BAND) as f32 - r, ((k + 1) * BAND) as f32 + r);
            let (t0, t1) = if dy.abs() < 1e-3 {
                (0.0, 1.0)
            } else {
                let (ta, tb) = ((band_lo - a[1]) / dy, (band_hi - a[1]) / dy);
                (ta.min(tb).max(0.0), ta.max(tb).min(1.0))
            };
            if t0 > t1 {
                continue;
            }
            let xa = a[0] + t0 * (b[0] - a[0]);
            let xb = a[0] + t1 * (b[0] - a[0]);
            let cx = |v: f32| (v.max(0.0) as usize).min(self.width);
            let (x0, x1) = (cx((xa.min(xb) - r).floor()), cx((xa.max(xb) + r).ceil()));
            if x1 > x0 {
                let bits = bit_range(x0 / self.block, (x1 - 1) / self.block + 1);
                self.bands[k] |= bits;
            }
        }
    }

    /// Marks the pixel box `[x0, x1) × [y0, y1)` (clamped to the buffer).
    pub(crate) fn mark_px(&mut self, x0: usize, y0: usize, x1: usize, y1: usize) {
        let (x1, y1) = (x1.min(self.width), y1.min(self.height));
        if x1 <= x0 || y1 <= y0 {
            return;
        }
        let (b0, b1) = (x0 / self.block, (x1 - 1) / self.block);
        let bits = bit_range(b0, b1 + 1);
        for band in &mut self.bands[y0 / BAND..=(y1 - 1) / BAND] {
            *band |= bits;
        }
    }

    /// Marks everything `other` marks (same size).
    pub(crate) fn include(&mut self, other: &Dirty) {
        for (a, b) in self.bands.iter_mut().zip(&other.bands) {
            *a |= *b;
        }
    }

    /// Marks the whole buffer.
    pub(crate) fn mark_all(&mut self) {
        self.mark_px(0, 0, self.width, self.height);
    }

    /// Nothing marked.
    pub(crate) fn reset(&mut self) {
        self.bands.fill(0);
    }

    /// Whether anything is marked.
    pub(crate) fn any(&self) -> bool {
        self.bands.iter().any(|&b| b != 0)
    }

    /// The band's marked blocks as bits (bit i: block i).
    pub(crate) fn band_bits(&self, band: usize) -> u64 {
        self.bands.get(band).copied().unwrap_or(0)
    }

    /// The marked column spans `[x0, x1)` of `bits` (runs of adjacent blocks merged).
    pub(crate) fn spans(&self, bits: u64) -> impl Iterator<Item = (usize, usize)> + '_ {
        let mut m = bits;
        std::iter::from_fn(move || {
            if m == 0 {
                return None;
            }
            let s = m.trailing_zeros() as usize;
            let len = (!(m >> s)).trailing_zeros() as usize;
            m &= !bit_range(s, s + len);
            let x0 = s * self.block;
            let x1 = ((s + len) * self.block).min(self.width);
            Some((x0, x1))
        })
    }

    /// Every marked `(row, x0, x1)`, band by band, row by row.
    pub(crate) fn rows(&self) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
        self.bands
            .iter()
            .enumerate()
            .filter(|(_, b)| **b != 0)
            .flat_map(move |(k, &bits)| {
                let rows = k * BAND..((k + 1) * BAND).min(self.height);
                rows.flat_map(move |j| self.spans(bits).map(move |(x0, x1)| (j, x0, x1)))
            })
    }
}

/// Bits `lo..hi` set (`hi ≤ 64`).
fn bit_range(lo: usize, hi: usize) -> u64 {
    let upto = |n: usize| if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
    upto(hi) & !upto(lo)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marks_cover_their_boxes_and_spans_merge() {
        let mut d = Dirty::new(3300, 5100);
        assert!(!d.any());
        d.mark([100.2, 40.0, 130.9, 41.0]);
        d.mark([131.0, 40.0, 200.0, 41.0]);
        let rows: Vec<_> = d.rows().collect();
        // One band, one merged span covering 99..202.
        assert_eq!(rows.len(), BAND);
        for (j, x0, x1) in rows {
            assert!((32..48).contains(&j), "{j}");
            assert!(x0 <= 99 && x1 >= 202, "{x0} {x1}");
        }
        d.mark([-5.0, -5.0, 1e9, f32::NAN]);
        d.mark_all();
        let covered: usize = d.rows().map(|(_, a, b)| b - a).sum();
        assert_eq!(covered, 3300 * 5100);
        d.reset();
        assert_eq!(d.rows().count(), 0);
    }

    #[test]
    fn a_slanted_segment_marks_a_staircase() {
        let mut d = Dirty::new(3300, 5100);
        d.mark_segment([0.0, 0.0], [3000.0, 3000.0], 2.0);
        let covered: usize = d.rows().map(|(_, a, b)| b - a).sum();
        // Its bounding box is 9 M pixels; the staircase a few % of that.
        assert!(covered < 600_000, "{covered}");
        // Every pixel within 2 px of the line is marked.
        for i in 0..3000 {
            for dx in -3i32..=3 {
                let (x, y) = ((i as i32 + dx).clamp(0, 3299) as usize, i);
                let band = d.band_bits(y / BAND);
                assert!(d.spans(band).any(|(a, b)| a <= x && x < b), "{x} {y}");
            }
        }
    }

    #[test]
    fn narrow_buffers_have_eight_pixel_blocks() {
        let mut d = Dirty::new(10, 3);
        d.mark_px(9, 2, 10, 3);
        assert_eq!(
            d.rows().collect::<Vec<_>>(),
            vec![(0, 8, 10), (1, 8, 10), (2, 8, 10)]
        );
    }
}
