//! Which parts of a page buffer may hold ink, so that clearing, compositing and encoding
//! visit only those (a tabloid page at 300 dpi is 16.8 MB, most of it paper).
//!
//! Every row of the buffer is cut into column blocks of [`BLOCK`] pixels; a row's blocks
//! are bits in a few `u64` words. Marks are conservative (a pixel outside every marked
//! block is known to be 0); [`Dirty::mark`] widens a box by one pixel on every side,
//! because anti-aliasing reaches into the pixels an edge crosses. Marks are kept per row
//! (not per band of rows) and in blocks of 8 pixels, one deflate word: a thin slanted
//! stroke marks little more than the pixels it inks, so the encoder and the clear read
//! little more than the ink.

/// Pixels per column block.
pub(crate) const BLOCK: usize = 8;

/// Marked blocks of a `width × height` buffer.
#[derive(Clone, Debug)]
pub(crate) struct Dirty {
    width: usize,
    height: usize,
    /// `u64` words per row.
    words: usize,
    bits: Vec<u64>,
    /// The blocks of a row's last word within the width.
    tail: u64,
    /// Rows `[lo, hi)` hold every mark (empty when nothing is marked).
    lo: usize,
    hi: usize,
}

impl Dirty {
    /// Nothing marked.
    pub(crate) fn new(width: usize, height: usize) -> Dirty {
        let words = width.div_ceil(BLOCK).div_ceil(64).max(1);
        Dirty {
            width,
            height,
            words,
            bits: vec![0; height * words],
            tail: bit_range(0, width.div_ceil(BLOCK) - 64 * (words - 1)),
            lo: height,
            hi: 0,
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

    /// Marks the pixel box `[x0, x1) × [y0, y1)` (clamped to the buffer).
    #[inline]
    pub(crate) fn mark_px(&mut self, x0: usize, y0: usize, x1: usize, y1: usize) {
        let (x1, y1) = (x1.min(self.width), y1.min(self.height));
        if x1 <= x0 || y1 <= y0 {
            return;
        }
        self.lo = self.lo.min(y0);
        self.hi = self.hi.max(y1);
        let (b0, b1) = (x0 / BLOCK, (x1 - 1) / BLOCK + 1);
        let (w0, w1) = (b0 / 64, (b1 - 1) / 64);
        if w0 == w1 {
            // The box's blocks in one word of each row: that word's bits, made once.
            let m = bit_range(b0 - 64 * w0, b1 - 64 * w0);
            let rows = self.bits[y0 * self.words + w0..].iter_mut();
            for w in rows.step_by(self.words).take(y1 - y0) {
                *w |= m;
            }
            return;
        }
        for j in y0..y1 {
            let row = &mut self.bits[j * self.words..(j + 1) * self.words];
            for (i, w) in row[w0..=w1].iter_mut().enumerate() {
                let i = w0 + i;
                *w |= bit_range(b0.saturating_sub(64 * i), (b1 - 64 * i).min(64));
            }
        }
    }

    /// Marks in row `j` the blocks whose bits are set in `bits`, the row's words from
    /// word `w0` on (block `b` is bit `b % 64` of word `b / 64`, as in [`Dirty`]'s own
    /// rows; a block past the row's width is not marked).
    ///
    /// One word not the row's last (most of a stroke's rows) is marked in the caller's
    /// code; the others in a call ([`Dirty::mark_words`]).
    #[inline(always)]
    pub(crate) fn mark_blocks(&mut self, j: usize, w0: usize, bits: &[u64]) {
        if let [b] = *bits
            && j < self.height
            && w0 + 1 < self.words
        {
            self.bits[j * self.words + w0] |= b;
            if b != 0 {
                self.lo = self.lo.min(j);
                self.hi = self.hi.max(j + 1);
            }
            return;
        }
        self.mark_words(j, w0, bits);
    }

    /// [`Dirty::mark_blocks`] for any number of words.
    #[inline(never)]
    fn mark_words(&mut self, j: usize, w0: usize, bits: &[u64]) {
        if j >= self.height || w0 >= self.words {
            return;
        }
        if let [b] = *bits {
            // One word: that word alone.
            let b = if w0 + 1 == self.words {
                b & self.tail
            } else {
                b
            };
            self.bits[j * self.words + w0] |= b;
            if b != 0 {
                self.lo = self.lo.min(j);
                self.hi = self.hi.max(j + 1);
            }
            return;
        }
        let row = &mut self.bits[j * self.words + w0..(j + 1) * self.words];
        let n = bits.len().min(row.len());
        let (mut row, mut bits) = (&mut row[..n], &bits[..n]);
        let mut any = 0;
        if n == self.words - w0 {
            // The row's last word: no block past the width.
            let ((w, rest), (&b, others)) =
                (row.split_last_mut().unwrap(), bits.split_last().unwrap());
            let b = b & self.tail;
            *w |= b;
            any |= b;
            (row, bits) = (rest, others);
        }
        for (w, &b) in row.iter_mut().zip(bits) {
            *w |= b;
            any |= b;
        }
        if any != 0 {
            self.lo = self.lo.min(j);
            self.hi = self.hi.max(j + 1);
        }
    }

    /// Marks the whole buffer.
    pub(crate) fn mark_all(&mut self) {
        self.mark_px(0, 0, self.width, self.height);
    }

    /// Nothing marked.
    pub(crate) fn reset(&mut self) {
        if self.lo < self.hi {
            self.bits[self.lo * self.words..self.hi * self.words].fill(0);
        }
        (self.lo, self.hi) = (self.height, 0);
    }

    /// Whether anything is marked.
    #[cfg(test)]
    pub(crate) fn any(&self) -> bool {
        self.bits.iter().any(|&b| b != 0)
    }

    /// Row `j`'s words.
    fn row(&self, j: usize) -> &[u64] {
        &self.bits[j * self.words..(j + 1) * self.words]
    }

    /// The marked column spans `[x0, x1)` of the rows `j` and `j − 1` (the union; for
    /// `j = 0` row 0 alone), adjacent blocks merged.
    pub(crate) fn row_pair_spans(&self, j: usize) -> Spans<'_> {
        let a = self.row(j);
        Spans {
            a,
            b: if j > 0 { self.row(j - 1) } else { a },
            width: self.width,
            at: 0,
        }
    }

    /// The marked blocks of rows `j` and `j − 1` (for `j = 0`, row 0 twice): a bit per
    /// block, 64 to a word.
    pub(crate) fn row_pair_words(&self, j: usize) -> (&[u64], &[u64]) {
        let a = self.row(j);
        (a, if j > 0 { self.row(j - 1) } else { a })
    }

    /// Zeroes the marked blocks of row `j` in `row`, that row's pixels: the row is
    /// blank after (nothing is drawn outside the marks).
    pub(crate) fn clear_row(&self, j: usize, row: &mut [u8]) {
        let w = row.len().min(self.width);
        for (k, &m) in self.row(j).iter().enumerate() {
            let mut m = m;
            while m != 0 {
                let x = BLOCK * (64 * k + m.trailing_zeros() as usize);
                m &= m - 1;
                if x + BLOCK <= w {
                    row[x..x + BLOCK].copy_from_slice(&[0; BLOCK]);
                } else {
                    row[x.min(w)..w].fill(0);
                }
            }
        }
    }

    /// Whether rows `j` and `j − 1` hold no mark (for `j = 0`, row 0).
    #[inline]
    pub(crate) fn row_pair_blank(&self, j: usize) -> bool {
        if j < self.lo || j > self.hi {
            return true;
        }
        let a = self.row(j);
        let b = if j > 0 { self.row(j - 1) } else { a };
        a.iter().zip(b).all(|(x, y)| x | y == 0)
    }

    /// Calls `f(row, x0, x1)` for every marked span, row by row.
    pub(crate) fn for_each_span(&self, mut f: impl FnMut(usize, usize, usize)) {
        for j in self.lo..self.hi {
            let a = self.row(j);
            if a.iter().all(|&w| w == 0) {
                continue;
            }
            let spans = Spans {
                a,
                b: a,
                width: self.width,
                at: 0,
            };
            for (x0, x1) in spans {
                f(j, x0, x1);
            }
        }
    }

    /// Every marked `(row, x0, x1)`, row by row.
    #[cfg(test)]
    pub(crate) fn rows(&self) -> Vec<(usize, usize, usize)> {
        let mut v = Vec::new();
        self.for_each_span(|j, a, b| v.push((j, a, b)));
        v
    }
}

/// The runs of set blocks of the union of two rows' words, as pixel spans `[x0, x1)`.
pub(crate) struct Spans<'a> {
    a: &'a [u64],
    b: &'a [u64],
    width: usize,
    /// Next block to look at.
    at: usize,
}

impl Spans<'_> {
    #[inline]
    fn word(&self, i: usize) -> u64 {
        self.a[i] | self.b[i]
    }
}

impl Iterator for Spans<'_> {
    type Item = (usize, usize);
    #[inline]
    fn next(&mut self) -> Option<(usize, usize)> {
        let n = self.a.len();
        // The first set block at or after `at`.
        let mut w = self.at / 64;
        if w >= n {
            return None;
        }
        let mut m = self.word(w) & !bit_range(0, self.at % 64);
        while m == 0 {
            w += 1;
            if w >= n {
                self.at = 64 * n;
                return None;
            }
            m = self.word(w);
        }
        let s = 64 * w + m.trailing_zeros() as usize;
        // The first clear block after it.
        let mut e = s;
        loop {
            let (wi, bi) = (e / 64, e % 64);
            if wi >= n {
                break;
            }
            let ones = (self.word(wi) >> bi).trailing_ones() as usize;
            e += ones;
            if ones < 64 - bi {
                break;
            }
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

    /// A row's blocks marked from words of bits are the blocks set one by one, but those
    /// past the width: rows of widths around words of the map, bits from any word on,
    /// sparse, dense, past the width, none.
    #[test]
    fn row_blocks_are_the_blocks_one_by_one() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rand = || {
            seed = crate::xorshift(seed);
            seed
        };
        for width in [0, 1, 8, 9, 500, 512, 513, 1100, 1536, 2550] {
            let (mut got, mut want) = (Dirty::new(width, 6), Dirty::new(width, 6));
            let words = got.words;
            for _ in 0..200 {
                let j = rand() as usize % 7;
                let w0 = rand() as usize % (words + 1);
                let n = rand() as usize % (words + 2);
                let bits: Vec<u64> = (0..n)
                    .map(|_| match rand() % 4 {
                        0 => 0,
                        1 => rand() & rand(),
                        2 => rand(),
                        _ => u64::MAX,
                    })
                    .collect();
                got.mark_blocks(j, w0, &bits);
                for (i, &b) in bits.iter().enumerate() {
                    for k in 0..64 {
                        let x = BLOCK * (64 * (w0 + i) + k);
                        if b >> k & 1 == 1 && x < width && w0 < words {
                            want.mark_px(x, j, x + 1, j + 1);
                        }
                    }
                }
                assert_eq!(got.bits, want.bits, "{width}");
                assert_eq!((got.lo, got.hi), (want.lo, want.hi), "{width}");
            }
        }
    }

    /// Boxes marked at once are the boxes' blocks set one by one, row by row: boxes in
    /// one word and across words, at the buffer's edges and beyond, on widths that end
    /// mid-word and on a word's end; the rows holding marks are kept too.
    #[test]
    fn boxes_mark_their_blocks_row_by_row() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rand = |n: usize| {
            seed = crate::xorshift(seed);
            (seed >> 33) as usize % n
        };
        for &(w, h) in &[(3300, 70), (512, 9), (513, 9), (10, 4), (1100, 30)] {
            let mut got = Dirty::new(w, h);
            let mut want = Dirty::new(w, h);
            for _ in 0..400 {
                let (x0, y0) = (rand(w + 20), rand(h + 3));
                let span = if rand(3) == 0 { 40 } else { 900 };
                let (x1, y1) = (x0 + rand(span), y0 + rand(12));
                got.mark_px(x0, y0, x1, y1);
                let (x1c, y1c) = (x1.min(w), y1.min(h));
                if x0 < x1c && y0 < y1c {
                    for j in y0..y1c {
                        for b in x0 / BLOCK..=(x1c - 1) / BLOCK {
                            want.bits[j * want.words + b / 64] |= 1 << (b % 64);
                        }
                    }
                    want.lo = want.lo.min(y0);
                    want.hi = want.hi.max(y1c);
                }
                assert!(
                    got.bits == want.bits,
                    "{w} × {h}: [{x0}, {x1}) × [{y0}, {y1})"
                );
                assert_eq!((got.lo, got.hi), (want.lo, want.hi));
            }
        }
    }

    #[test]
    fn marks_cover_their_boxes_and_spans_merge() {
        let mut d = Dirty::new(3300, 5100);
        assert!(!d.any());
        d.mark([100.2, 40.0, 130.9, 41.0]);
        d.mark([131.0, 40.0, 200.0, 41.0]);
        let rows = d.rows();
        // Rows 39..42 (widened by a pixel), one merged span covering 99..202.
        assert_eq!(rows.len(), 3);
        for (j, x0, x1) in rows {
            assert!((39..42).contains(&j), "{j}");
            assert_eq!((x0, x1), (96, 208));
        }
        assert!(d.row_pair_blank(38) && !d.row_pair_blank(39) && !d.row_pair_blank(42));
        assert!(d.row_pair_blank(43) && d.row_pair_blank(0));
        d.mark([-5.0, -5.0, 1e9, f32::NAN]);
        d.mark_all();
        let covered: usize = d.rows().into_iter().map(|(_, a, b)| b - a).sum();
        assert_eq!(covered, 3300 * 5100);
        d.reset();
        assert!(d.rows().is_empty() && !d.any());
        assert!((0..5100).all(|j| d.row_pair_blank(j)));
    }

    #[test]
    fn narrow_buffers_and_spans_across_words() {
        let mut d = Dirty::new(10, 3);
        d.mark_px(9, 2, 10, 3);
        assert_eq!(d.rows(), vec![(2, 8, 10)]);
        let mut d = Dirty::new(3300, 20);
        d.mark_px(500, 9, 530, 10); // blocks 62..67: across the first word's end
        d.mark_px(3290, 17, 3300, 18);
        assert_eq!(d.row_pair_spans(9).collect::<Vec<_>>(), vec![(496, 536)]);
        assert_eq!(d.row_pair_spans(10).collect::<Vec<_>>(), vec![(496, 536)]);
        assert_eq!(d.row_pair_spans(11).count(), 0);
        assert_eq!(d.row_pair_spans(18).collect::<Vec<_>>(), vec![(3288, 3300)]);
        assert_eq!(d.row_pair_spans(0).count(), 0);
        // Wider than the old fixed limit of 8 words (a landscape tabloid at 1200 dpi).
        let mut d = Dirty::new(20_400, 2);
        d.mark_px(0, 1, 20_400, 2);
        assert_eq!(d.row_pair_spans(1).collect::<Vec<_>>(), vec![(0, 20_400)]);
    }

    /// Random boxes: the spans of every row pair are exactly the union of the marked
    /// blocks of both rows, cover every marked pixel, and reset clears all.
    #[test]
    fn spans_are_the_marked_blocks_exactly() {
        let (w, h) = (1100, 60);
        let mut d = Dirty::new(w, h);
        let mut truth = vec![false; w.div_ceil(BLOCK) * h];
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = |n: usize| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s % n as u64) as usize
        };
        for round in 0..3 {
            for _ in 0..40 {
                let (x0, y0) = (rnd(w), rnd(h));
                let (x1, y1) = (x0 + rnd(if round == 0 { 9 } else { 700 }), y0 + rnd(4));
                d.mark_px(x0, y0, x1, y1);
                let (x1, y1) = (x1.min(w), y1.min(h));
                for j in y0..y1 {
                    for x in x0..x1 {
                        truth[j * w.div_ceil(BLOCK) + x / BLOCK] = true;
                    }
                }
            }
            let cols = w.div_ceil(BLOCK);
            for j in 0..h {
                let mut want = Vec::new();
                for b in 0..cols {
                    let on = truth[j * cols + b] || (j > 0 && truth[(j - 1) * cols + b]);
                    if on {
                        match want.last_mut() {
                            Some((_, e)) if *e == (b * BLOCK).min(w) => {
                                *e = ((b + 1) * BLOCK).min(w)
                            }
                            _ => want.push((b * BLOCK, ((b + 1) * BLOCK).min(w))),
                        }
                    }
                }
                assert_eq!(d.row_pair_spans(j).collect::<Vec<_>>(), want, "row {j}");
                assert_eq!(d.row_pair_blank(j), want.is_empty(), "row {j}");
            }
            let rows = d.rows();
            for j in 0..h {
                for b in 0..cols {
                    let x = b * BLOCK;
                    let inside = rows.iter().any(|&(r, a, e)| r == j && a <= x && x < e);
                    assert_eq!(inside, truth[j * cols + b], "{j} {b}");
                }
            }
            d.reset();
            truth.fill(false);
            assert!(!d.any());
        }
    }
}
