//! Which parts of a page buffer may hold ink, so that clearing, compositing and encoding
//! visit only those (a tabloid page at 300 dpi is 16.8 MB, most of it paper).
//!
//! The buffer is cut into bands of [`BAND`] rows and column blocks of [`BLOCK`] pixels; a
//! band's blocks are bits in a few `u64` words. Marks are conservative (a pixel outside
//! every marked block is known to be 0) and widened by one pixel on every side, because
//! anti-aliasing reaches into the pixels an edge crosses.

/// Rows per band.
pub(crate) const BAND: usize = 8;
/// Pixels per column block.
pub(crate) const BLOCK: usize = 16;

/// Marked blocks of a `width × height` buffer.
#[derive(Clone, Debug)]
pub(crate) struct Dirty {
    width: usize,
    height: usize,
    /// `u64` words per band.
    words: usize,
    bits: Vec<u64>,
}

impl Dirty {
    /// Nothing marked.
    pub(crate) fn new(width: usize, height: usize) -> Dirty {
        let words = width.div_ceil(BLOCK).div_ceil(64).max(1);
        Dirty {
            width,
            height,
            words,
            bits: vec![0; height.div_ceil(BAND) * words],
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

    /// Sets blocks `b0..b1` of band `k`.
    fn set(&mut self, k: usize, b0: usize, b1: usize) {
        let band = &mut self.bits[k * self.words..(k + 1) * self.words];
        for (i, w) in band.iter_mut().enumerate() {
            let (lo, hi) = (b0.saturating_sub(64 * i), b1.saturating_sub(64 * i).min(64));
            if lo < hi {
                *w |= bit_range(lo, hi);
            }
        }
    }

    /// Marks the columns `[x0, x1)` of band `k`.
    fn set_px(&mut self, k: usize, x0: usize, x1: usize) {
        if x1 > x0 {
            self.set(k, x0 / BLOCK, (x1 - 1) / BLOCK + 1);
        }
    }

    /// Marks the pixel box `[x0, x1) × [y0, y1)` (clamped to the buffer).
    pub(crate) fn mark_px(&mut self, x0: usize, y0: usize, x1: usize, y1: usize) {
        let (x1, y1) = (x1.min(self.width), y1.min(self.height));
        if x1 <= x0 || y1 <= y0 {
            return;
        }
        for k in y0 / BAND..=(y1 - 1) / BAND {
            self.set_px(k, x0, x1);
        }
    }

    /// Marks the whole buffer.
    pub(crate) fn mark_all(&mut self) {
        self.mark_px(0, 0, self.width, self.height);
    }

    /// Nothing marked.
    pub(crate) fn reset(&mut self) {
        self.bits.fill(0);
    }

    /// Whether anything is marked.
    #[cfg(test)]
    pub(crate) fn any(&self) -> bool {
        self.bits.iter().any(|&b| b != 0)
    }

    /// The marked column spans `[x0, x1)` of the rows `j` and `j − 1` (the union; for
    /// `j = 0` row 0 alone), adjacent blocks merged.
    pub(crate) fn row_pair_spans(&self, j: usize) -> Spans {
        let mut s = Spans::new(self.words, self.width);
        let k = j / BAND;
        s.or(&self.bits[k * self.words..(k + 1) * self.words]);
        if j > 0 && (j - 1) / BAND != k {
            let k = (j - 1) / BAND;
            s.or(&self.bits[k * self.words..(k + 1) * self.words]);
        }
        s
    }

    /// Calls `f(row, x0, x1)` for every marked span, band by band, row by row.
    pub(crate) fn for_each_span(&self, mut f: impl FnMut(usize, usize, usize)) {
        let mut spans = [(0usize, 0usize); 8 * 64];
        for (k, band) in self.bits.chunks(self.words).enumerate() {
            if band.iter().all(|&w| w == 0) {
                continue;
            }
            let mut it = Spans::new(self.words, self.width);
            it.or(band);
            let mut n = 0;
            for s in it {
                spans[n] = s;
                n += 1;
            }
            for j in k * BAND..((k + 1) * BAND).min(self.height) {
                for &(x0, x1) in &spans[..n] {
                    f(j, x0, x1);
                }
            }
        }
    }

    /// Every marked `(row, x0, x1)`, band by band, row by row.
    #[cfg(test)]
    pub(crate) fn rows(&self) -> Vec<(usize, usize, usize)> {
        let mut v = Vec::new();
        self.for_each_span(|j, a, b| v.push((j, a, b)));
        v
    }
}

/// The runs of set blocks of one band, as pixel spans `[x0, x1)`.
pub(crate) struct Spans {
    words: [u64; 8],
    n: usize,
    width: usize,
    /// Next block to look at.
    at: usize,
}

impl Spans {
    fn new(words: usize, width: usize) -> Spans {
        assert!(words <= 8, "pages up to {} px wide", 8 * 64 * BLOCK);
        Spans {
            words: [0; 8],
            n: words,
            width,
            at: 0,
        }
    }

    fn or(&mut self, band: &[u64]) {
        for (a, b) in self.words.iter_mut().zip(band) {
            *a |= *b;
        }
    }

    fn bit(&self, i: usize) -> bool {
        self.words[i / 64] >> (i % 64) & 1 == 1
    }

    /// The first set block at or after `i`, if any.
    fn next_set(&self, i: usize) -> Option<usize> {
        let mut w = i / 64;
        if w >= self.n {
            return None;
        }
        let mut m = self.words[w] & !bit_range(0, i % 64);
        loop {
            if m != 0 {
                return Some(64 * w + m.trailing_zeros() as usize);
            }
            w += 1;
            if w >= self.n {
                return None;
            }
            m = self.words[w];
        }
    }
}

impl Iterator for Spans {
    type Item = (usize, usize);
    fn next(&mut self) -> Option<(usize, usize)> {
        let s = self.next_set(self.at)?;
        let mut e = s + 1;
        while e < 64 * self.n && self.bit(e) {
            e += 1;
        }
        self.at = e;
        Some(((s * BLOCK).min(self.width), (e * BLOCK).min(self.width)))
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
        let rows = d.rows();
        // Rows 39..42 (two bands), one merged span covering 99..202.
        assert_eq!(rows.len(), 2 * BAND);
        for (j, x0, x1) in rows {
            assert!((32..48).contains(&j), "{j}");
            assert!(x0 <= 99 && x1 >= 202, "{x0} {x1}");
        }
        d.mark([-5.0, -5.0, 1e9, f32::NAN]);
        d.mark_all();
        let covered: usize = d.rows().into_iter().map(|(_, a, b)| b - a).sum();
        assert_eq!(covered, 3300 * 5100);
        d.reset();
        assert!(d.rows().is_empty());
    }

    #[test]
    fn narrow_buffers_and_spans_across_words() {
        let mut d = Dirty::new(10, 3);
        d.mark_px(9, 2, 10, 3);
        assert_eq!(d.rows(), vec![(0, 0, 10), (1, 0, 10), (2, 0, 10)]);
        let mut d = Dirty::new(3300, 20);
        d.mark_px(1000, 9, 1100, 10); // blocks 62..69: across the first word's end
        d.mark_px(3290, 17, 3300, 18);
        assert_eq!(d.row_pair_spans(8).collect::<Vec<_>>(), vec![(992, 1104)]);
        assert_eq!(
            d.row_pair_spans(16).collect::<Vec<_>>(),
            vec![(992, 1104), (3280, 3300)]
        );
        assert_eq!(d.row_pair_spans(17).collect::<Vec<_>>(), vec![(3280, 3300)]);
        assert_eq!(d.row_pair_spans(0).count(), 0);
    }
}
