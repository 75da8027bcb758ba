//! The coverage of one gray level, kept until it is composited into the page.
//!
//! Strokes of one gray merge into one coverage (so that crossing curves of one gray do not
//! darken where they cross), which is composited into the page when the level changes,
//! before paper is drawn and when the page is read. The layer is sparse: 64 × 64 tiles,
//! made where gray is drawn and reused page after page, with the span of every tile row
//! that holds coverage, so a layer costs memory and compositing time only where there is
//! gray (a page-sized layer was 16.8 MB per worker at 300 dpi).

use crate::dirty::BLOCK;
use crate::pixel::{div255, narrow, overprint, widen};
use wide::u16x8;

/// Tile side, pixels.
const TILE: usize = 64;

/// No tile.
const NONE: u32 = u32::MAX;

// A tile's row is a byte of a word of a row's block map ([`GrayLayer::add_blocks`]).
const _: () = assert!(TILE == 8 * BLOCK);

/// One tile: its number in the page's tile grid, its coverage and each row's span
/// `[lo, hi)` (empty when `lo ≥ hi`), and which rows hold a span (bit `r` for row `r`).
struct Tile {
    at: u32,
    cov: Box<[u8; TILE * TILE]>,
    span: [(u8, u8); TILE],
    rows: u64,
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
    /// `l ← l + (255 − l)·c`, rounded, [`merge`]), and clears `cov`. The caller marks
    /// those pixels in the page's dirty map ([`GrayLayer::flush`] does not).
    #[inline]
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
                NONE => self.new_tile(at),
                k => k as usize,
            };
            let tile = &mut self.tiles[k];
            let (lo, hi) = (x - tx * TILE, end - tx * TILE);
            let row = &mut tile.cov[r * TILE + lo..r * TILE + hi];
            merge(row, &mut cov[x - x0..end - x0]);
            let s = &mut tile.span[r];
            *s = (s.0.min(lo as u8), s.1.max(hi as u8));
            tile.rows |= 1 << r;
            x = end;
        }
        cov[x1 - x0..].fill(0);
    }

    /// Merges the coverage of row buffer `row` (row `j` of the page, from its column 0)
    /// over the blocks of [`BLOCK`] pixels set in `bits`, word `w` of the row's block map
    /// (block `b` is bit `b % 64` of word `b / 64`), and clears them in `row`: the same
    /// layer as [`GrayLayer::add_span`] of each run of set blocks, a tile's blocks at
    /// once (a tile's row is 8 blocks, a byte of the word) from its first set block to
    /// its last. The blocks between two runs of one tile are merged too: `row` holds 0
    /// beside its set blocks (the caller's promise), which leaves the layer as it is
    /// (`l + (127 / 255)` is `l`), and the tile row's span is the runs' hull either way.
    /// Into a tile row without a span (all 0) the tile's 64 pixels of `row` are copied
    /// whole, a merge over 0 being the coverage itself. `X16` (only in code
    /// compiled for AVX2, run where the processor has it): merged sixteen pixels at a
    /// time ([`merge_x16`]).
    #[inline(always)]
    pub(crate) fn add_blocks<const X16: bool>(
        &mut self,
        j: usize,
        w: usize,
        mut bits: u64,
        row: &mut [u8],
    ) {
        let width = self.width.min(row.len());
        if j >= self.height {
            return clear_blocks(w, bits, row);
        }
        let (ty, r) = (j / TILE, j % TILE);
        // The page's tile of the word's first byte.
        let first = ty * self.cols + 8 * w;
        while bits != 0 {
            let t = bits.trailing_zeros() as usize / 8;
            let mut byte = (bits >> (8 * t)) as u8;
            bits &= !(0xff << (8 * t));
            let x = (8 * w + t) * TILE;
            let mut hi = BLOCK * (8 - byte.leading_zeros() as usize);
            if x + TILE > width {
                // The blocks past the layer: not merged, cleared.
                let keep = width.div_ceil(BLOCK).saturating_sub(x / BLOCK);
                let past = if keep < 8 {
                    byte & !((1 << keep) - 1)
                } else {
                    0
                };
                clear_blocks(w, u64::from(past) << (8 * t), row);
                byte &= !past;
                if byte == 0 {
                    continue;
                }
                // A block across the layer's edge: its pixels past it cleared.
                hi = BLOCK * (8 - byte.leading_zeros() as usize);
                let end = (x + hi).min(row.len());
                if end > width {
                    row[width..end].fill(0);
                }
                hi = hi.min(width - x);
            }
            let lo = BLOCK * byte.trailing_zeros() as usize;
            let at = first + t;
            let k = match self.slot[at] {
                NONE => self.new_tile(at),
                k => k as usize,
            };
            let tile = &mut self.tiles[k];
            let s = &mut tile.span[r];
            if s.1 == 0
                && let Some(c) = row.get_mut(x..x + TILE)
            {
                // A tile row without a span holds no coverage, and the row buffer holds
                // none beside the set blocks (the caller's promise; past the layer's
                // width cleared above): merged over 0, the tile's 64 pixels of the row
                // are themselves, copied whole.
                let l: &mut [u8; TILE] = (&mut tile.cov[r * TILE..][..TILE])
                    .try_into()
                    .expect("a tile row");
                let c: &mut [u8; TILE] = c.try_into().expect("a tile row");
                *l = *c;
                *c = [0; TILE];
                *s = (lo as u8, hi as u8);
                tile.rows |= 1 << r;
                continue;
            }
            let (l, c) = (
                &mut tile.cov[r * TILE..][..TILE][lo..hi],
                &mut row[x..][lo..hi],
            );
            if hi <= usize::from(s.0) || usize::from(s.1) <= lo {
                // Pixels beside the tile row's span (or a row without one) hold no
                // coverage: merged over 0, the coverage is itself.
                take(l, c);
            } else if X16 {
                // SAFETY: `merge_x16` needs AVX2; `X16` is true only in the scan
                // converter's twins compiled for AVX2, BMI1 and BMI2, which run only
                // where the processor was found to have them (`Capsules::stroke`,
                // `Capsules::ring`).
                #[cfg(target_arch = "x86_64")]
                #[allow(unsafe_code)]
                unsafe {
                    merge_x16(l, c)
                };
                #[cfg(not(target_arch = "x86_64"))]
                merge(l, c);
            } else {
                merge(l, c);
            }
            *s = (s.0.min(lo as u8), s.1.max(hi as u8));
            tile.rows |= 1 << r;
        }
    }

    /// A tile for the page's tile `at`, which has none: the index of a spare one or of a
    /// new one.
    #[cold]
    #[inline(never)]
    fn new_tile(&mut self, at: usize) -> usize {
        if self.used == self.tiles.len() {
            self.tiles.push(Tile {
                at: at as u32,
                cov: Box::new([0; TILE * TILE]),
                span: [(u8::MAX, 0); TILE],
                rows: 0,
            });
        }
        self.tiles[self.used].at = at as u32;
        self.slot[at] = self.used as u32;
        self.used += 1;
        self.used - 1
    }

    /// Composites the layer into `page` (row-major ink, the layer's width, from page row
    /// `first` on) with the layer's gray ([`overprint`], [`overprint_span`]) and empties
    /// the layer. Marks nothing: the pixels were marked in the page's dirty map when
    /// they were added ([`GrayLayer::add_span`]), and the map is not reset while the
    /// layer holds coverage.
    ///
    /// Compiled for AVX2, BMI1 and BMI2 too and run so where the processor has them
    /// (as [`crate::capsule::Capsules::stroke`]; the same bytes).
    pub(crate) fn flush(&mut self, page: &mut [u8], first: usize) {
        if self.used == 0 {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::x86_fast() {
            // SAFETY: `flush_fast` needs AVX2, BMI1 and BMI2, which the processor was
            // just found to have; it has no other requirement (it is the safe
            // `flush_body` compiled for them).
            #[allow(unsafe_code)]
            unsafe {
                self.flush_fast(page, first)
            };
            return;
        }
        self.flush_body::<false>(page, first)
    }

    /// [`GrayLayer::flush_body`] compiled for AVX2, BMI1 and BMI2 (called only where
    /// the processor has them).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1,bmi2")]
    fn flush_fast(&mut self, page: &mut [u8], first: usize) {
        self.flush_body::<true>(page, first)
    }

    /// [`GrayLayer::flush`] itself; inlined into each of its two callers so that each
    /// is compiled for its own instruction set; `X16` (only in [`GrayLayer::flush_fast`]):
    /// sixteen pixels at a time ([`overprint_x16`]).
    #[inline(always)]
    fn flush_body<const X16: bool>(&mut self, page: &mut [u8], first: usize) {
        let g = self.level;
        for tile in &mut self.tiles[..self.used] {
            let at = tile.at as usize;
            let (ty, tx) = (at / self.cols, at % self.cols);
            let mut rows = std::mem::take(&mut tile.rows);
            while rows != 0 {
                let r = rows.trailing_zeros() as usize;
                rows &= rows - 1;
                let s = std::mem::replace(&mut tile.span[r], (u8::MAX, 0));
                let (lo, hi) = (usize::from(s.0), usize::from(s.1));
                let (j, x) = (ty * TILE + r, tx * TILE);
                let at = (j - first) * self.width + x;
                let dst = &mut page[at + lo..at + hi];
                let src = &mut tile.cov[r * TILE..(r + 1) * TILE];
                #[cfg(target_arch = "x86_64")]
                if X16 {
                    // SAFETY: `overprint_x16` needs AVX2; `X16` is true only in
                    // `flush_fast`, compiled for AVX2, BMI1 and BMI2 and run only where
                    // the processor was found to have them (`GrayLayer::flush`).
                    #[allow(unsafe_code)]
                    unsafe {
                        overprint_x16(dst, &src[lo..hi], g)
                    };
                } else {
                    overprint_span(dst, &src[lo..hi], g);
                }
                #[cfg(not(target_arch = "x86_64"))]
                overprint_span(dst, &src[lo..hi], g);
                // The row's coverage outside its span is 0 already.
                src.fill(0);
            }
            self.slot[at] = NONE;
        }
        self.used = 0;
    }
}

/// Clears the blocks of `row` set in `bits`, word `w` of a row's block map (as far as
/// `row` reaches).
#[cold]
fn clear_blocks(w: usize, mut bits: u64, row: &mut [u8]) {
    while bits != 0 {
        let x = BLOCK * (64 * w + bits.trailing_zeros() as usize);
        bits &= bits - 1;
        let n = row.len();
        row[x.min(n)..(x + BLOCK).min(n)].fill(0);
    }
}

/// Sixteen bytes in AVX2's 16-bit lanes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn widen16(b: &[u8; 16]) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    let v = u128::from_le_bytes(*b);
    _mm256_cvtepu8_epi16(_mm_set_epi64x((v >> 64) as i64, v as i64))
}

/// [`widen16`]'s inverse: sixteen 16-bit lanes, each at most 255, as bytes (a
/// saturating pack per 128-bit half, the halves' low words brought together).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn narrow16(v: std::arch::x86_64::__m256i) -> [u8; 16] {
    use std::arch::x86_64::*;
    let p = _mm256_permute4x64_epi64::<0b1000>(_mm256_packus_epi16(v, _mm256_setzero_si256()));
    let p = _mm256_castsi256_si128(p);
    let (lo, hi) = (
        _mm_cvtsi128_si64(p) as u64,
        _mm_extract_epi64::<1>(p) as u64,
    );
    (u128::from(lo) | u128::from(hi) << 64).to_le_bytes()
}

/// [`div255`] in sixteen lanes: `x / 255` for every 16-bit `x`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn div255_16(x: std::arch::x86_64::__m256i) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    _mm256_srli_epi16::<7>(_mm256_mulhi_epu16(x, _mm256_set1_epi16(0x8081_u16 as i16)))
}

/// [`overprint_span`] sixteen pixels at a time in AVX2's 16-bit lanes (the same integer
/// arithmetic, exact: the same bytes), the last fewer than sixteen by
/// [`overprint_span`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn overprint_x16(dst: &mut [u8], cov: &[u8], g: u8) {
    use std::arch::x86_64::*;
    let n = dst.len().min(cov.len());
    let lanes = n - n % 16;
    let (full, half) = (_mm256_set1_epi16(255), _mm256_set1_epi16(127));
    let gl = _mm256_set1_epi16(i16::from(g));
    let (add, sub, mul) = (_mm256_add_epi16, _mm256_sub_epi16, _mm256_mullo_epi16);
    for (d16, c16) in dst[..lanes]
        .chunks_exact_mut(16)
        .zip(cov[..lanes].chunks_exact(16))
    {
        let d16: &mut [u8; 16] = d16.try_into().expect("16 pixels");
        let c16: &[u8; 16] = c16.try_into().expect("16 pixels");
        let b = mul(widen16(c16), gl);
        *d16 = if u128::from_le_bytes(*d16) == 0 {
            // Paper under all sixteen: `⌊(b + 127) / 255⌋` (see `overprint_span`).
            narrow16(div255_16(add(b, half)))
        } else {
            let d = widen16(d16);
            let a = sub(full, d);
            let h = div255_16(b);
            let l = sub(b, mul(h, full));
            let z = add(add(mul(a, h), half), div255_16(add(mul(a, l), half)));
            narrow16(add(d, div255_16(z)))
        };
    }
    overprint_span(&mut dst[lanes..n], &cov[lanes..n], g);
}

/// [`merge`] sixteen pixels at a time in AVX2's 16-bit lanes (the same integer
/// arithmetic, exact: the same bytes), the last fewer than sixteen by [`merge`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn merge_x16(l: &mut [u8], c: &mut [u8]) {
    use std::arch::x86_64::*;
    let n = l.len().min(c.len());
    let lanes = n - n % 16;
    let (full, half) = (_mm256_set1_epi16(255), _mm256_set1_epi16(127));
    let magic = _mm256_set1_epi16(0x8081_u16 as i16);
    let wide = |b: &[u8; 16]| {
        let v = u128::from_le_bytes(*b);
        _mm256_cvtepu8_epi16(_mm_set_epi64x((v >> 64) as i64, v as i64))
    };
    for (l16, c16) in l[..lanes]
        .chunks_exact_mut(16)
        .zip(c[..lanes].chunks_exact_mut(16))
    {
        let l16: &mut [u8; 16] = l16.try_into().expect("16 pixels");
        let c16: &mut [u8; 16] = c16.try_into().expect("16 pixels");
        let (a, b) = (wide(l16), wide(c16));
        let x = _mm256_add_epi16(_mm256_mullo_epi16(_mm256_sub_epi16(full, a), b), half);
        // `x / 255` ([`div255`]), then `a +` it: each lane at most 255.
        let q = _mm256_srli_epi16::<7>(_mm256_mulhi_epu16(x, magic));
        let v = _mm256_add_epi16(a, q);
        // Packed to bytes per 128-bit half, the halves' low words brought together.
        let p = _mm256_permute4x64_epi64::<0b1000>(_mm256_packus_epi16(v, _mm256_setzero_si256()));
        let p = _mm256_castsi256_si128(p);
        let (lo, hi) = (
            _mm_cvtsi128_si64(p) as u64,
            _mm_extract_epi64::<1>(p) as u64,
        );
        *l16 = (u128::from(lo) | u128::from(hi) << 64).to_le_bytes();
        *c16 = [0; 16];
    }
    merge(&mut l[lanes..n], &mut c[lanes..n]);
}

/// [`merge`] over a layer that holds no coverage there (`l` all 0): `l ← c`, as
/// `0 + ((255 − 0)·c + 127) / 255` is `c` for every `c` (`255·c + 127 < 255·(c + 1)`),
/// sixteen pixels at a time; and clears `c`.
#[inline(always)]
fn take(l: &mut [u8], c: &mut [u8]) {
    let n = l.len().min(c.len());
    let (l, c) = (&mut l[..n], &mut c[..n]);
    let mut ls = l.chunks_exact_mut(16);
    let mut cs = c.chunks_exact_mut(16);
    for (l16, c16) in (&mut ls).zip(&mut cs) {
        let c16: &mut [u8; 16] = c16.try_into().expect("16 pixels");
        l16.copy_from_slice(c16);
        *c16 = [0; 16];
    }
    let (l, c) = (ls.into_remainder(), cs.into_remainder());
    let eight = l.len() - l.len() % 8;
    if eight == 8 {
        let c8: &mut [u8; 8] = (&mut c[..8]).try_into().expect("8 pixels");
        l[..8].copy_from_slice(c8);
        *c8 = [0; 8];
    }
    for (l, c) in l[eight..].iter_mut().zip(&mut c[eight..]) {
        *l = std::mem::take(c);
    }
}

/// `l ← l + ((255 − l)·c + 127) / 255` over `l` with `c` (the layer's "source over"),
/// eight pixels at a time in 16-bit lanes (`(255 − l)·c + 127 ≤ 65152`, and [`div255`]
/// is `x / 255` for every 16-bit `x`), and clears `c`.
#[inline]
fn merge(l: &mut [u8], c: &mut [u8]) {
    let n = l.len().min(c.len());
    let lanes = n - n % 8;
    let (full, half) = (u16x8::splat(255), u16x8::splat(127));
    let (l8s, c8s) = (
        l[..lanes].chunks_exact_mut(8),
        c[..lanes].chunks_exact_mut(8),
    );
    for (l8, c8) in l8s.zip(c8s) {
        let (a, b) = (widen(l8), widen(c8));
        narrow(a + div255((full - a) * b + half), l8);
        c8.fill(0);
    }
    for (l, c) in l[lanes..n].iter_mut().zip(&mut c[lanes..n]) {
        let (ll, cc) = (u32::from(*l), u32::from(*c));
        *l = (ll + ((255 - ll) * cc + 127) / 255) as u8;
        *c = 0;
    }
}

/// [`overprint`] of coverage `cov` in gray `g` over `dst`, eight pixels at a time in
/// 16-bit lanes. With `a = 255 − d`, `b = c·g` (at most 65025) split as `b = 255·h + l`
/// (`h = b / 255`, `l < 255`), `⌊(a·b + 32512) / 65025⌋` is `⌊z / 255⌋` with
/// `z = ⌊(a·b + 32512) / 255⌋` (a floor of a floor), and as `a·b + 32512` is
/// `255·(a·h + 127) + a·l + 127`, `z = a·h + 127 + ⌊(a·l + 127) / 255⌋`: every term
/// below 2^16 (`a·l + 127 ≤ 64897`, `z ≤ 65152`), each quotient a [`div255`]. Eight
/// pixels of paper (`d = 0`) take `⌊(b + 127) / 255⌋`, the same. Exact; tested for
/// every `d`, `c`, `g`.
#[inline]
pub(crate) fn overprint_span(dst: &mut [u8], cov: &[u8], g: u8) {
    let n = dst.len().min(cov.len());
    let lanes = n - n % 8;
    let (full, gl, half) = (
        u16x8::splat(255),
        u16x8::splat(u16::from(g)),
        u16x8::splat(127),
    );
    for (d8, c8) in dst[..lanes]
        .chunks_exact_mut(8)
        .zip(cov[..lanes].chunks_exact(8))
    {
        let c = widen(c8);
        let b = c * gl;
        if u64::from_ne_bytes(d8.try_into().unwrap_or([1; 8])) == 0 {
            // Paper under all eight (d = 0, a = 255): z = 255·h + 127 + l, so the
            // level is h + ⌊(l + 127) / 255⌋ = ⌊(b + 127) / 255⌋.
            narrow(div255(b + half), d8);
            continue;
        }
        let d = widen(d8);
        let a = full - d;
        let h = div255(b);
        let l = b - h * full;
        let z = a * h + half + div255(a * l + half);
        // At most 255.
        narrow(d + div255(z), d8);
    }
    let g = u32::from(g);
    for (d, &c) in dst[lanes..n].iter_mut().zip(&cov[lanes..n]) {
        *d = overprint(*d, c, g);
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
        layer.flush(&mut page, 0);
        assert!(!layer.any());
        // 200 over 200: 200 + 55·200/255 = 243.
        assert_eq!(page[70 * w + 105], 243);
        assert_eq!(page[70 * w + 40], 200);
        assert_eq!(page[70 * w + 189], 200);
        assert_eq!(page[70 * w + 190], 0);
        assert_eq!(page.iter().filter(|&&v| v != 0).count(), 150);
        // Flushed again: nothing more.
        layer.flush(&mut page, 0);
        assert_eq!(page[70 * w + 105], 243);
        // Off the page: ignored.
        layer.add_span(500, 0, &mut [9u8; 10]);
        layer.add_span(10, 295, &mut [9u8; 10]);
        layer.flush(&mut page, 0);
        assert_eq!(page[10 * w + 299], 9);
    }

    /// The layer in lanes is the layer pixel by pixel: random spans of random gray
    /// coverage (every length, across tiles, on the page's last, partial tile) merged
    /// and composited in random grays over a random page, flushed now and then, against
    /// a page-sized reference layer merged and composited pixel by pixel.
    #[test]
    fn the_layer_is_its_pixel_by_pixel_reference() {
        let (w, h) = (203, 150);
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rand = |n: usize| {
            seed = crate::xorshift(seed);
            (seed >> 33) as usize % n
        };
        let mut page: Vec<u8> = (0..w * h).map(|_| rand(256) as u8).collect();
        let mut want = page.clone();
        let mut layer = GrayLayer::new(w, h);
        let mut reference = vec![0u8; w * h];
        for round in 0..60 {
            layer.level = rand(256) as u8;
            for _ in 0..40 {
                let (j, x0, len) = (rand(h), rand(w), 1 + rand(150));
                let mut cov: Vec<u8> = (0..len).map(|_| rand(256) as u8).collect();
                for (i, &c) in cov.iter().enumerate() {
                    if x0 + i < w {
                        let l = &mut reference[j * w + x0 + i];
                        let (ll, cc) = (u32::from(*l), u32::from(c));
                        *l = (ll + ((255 - ll) * cc + 127) / 255) as u8;
                    }
                }
                layer.add_span(j, x0, &mut cov);
            }
            layer.flush(&mut page, 0);
            let g = u32::from(layer.level);
            for (d, l) in want.iter_mut().zip(reference.iter_mut()) {
                *d = overprint(*d, *l, g);
                *l = 0;
            }
            assert!(page == want, "round {round}");
        }
    }

    /// [`GrayLayer::add_blocks`] is [`GrayLayer::add_span`] of each run of set blocks
    /// (split at words, as the scan converter's row flush made them): random blocks of
    /// random coverage (0 in the blocks not set) on rows of a page wider than a word of
    /// the block map, its last tile partial, in random grays, flushed now and then over
    /// a random page; the same tile rows' spans, the same pages, the row buffer cleared.
    /// Also a row buffer wider than the layer (its blocks past the layer cleared). Where
    /// the processor has AVX2, every other round merges sixteen pixels at a time.
    #[test]
    fn blocks_merge_as_their_runs() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rand = || {
            seed = crate::xorshift(seed);
            seed
        };
        for (w, h, extra) in [(1100usize, 150usize, 0usize), (203, 70, 0), (1100, 70, 29)] {
            let words = w.div_ceil(BLOCK).div_ceil(64);
            let mut page: Vec<u8> = (0..w * h).map(|_| rand() as u8).collect();
            let mut want = page.clone();
            let (mut got, mut reference) = (GrayLayer::new(w, h), GrayLayer::new(w, h));
            let mut row = vec![0u8; w + extra];
            for round in 0..40 {
                let level = rand() as u8;
                (got.level, reference.level) = (level, level);
                for _ in 0..30 {
                    let j = rand() as usize % h;
                    let mut map = vec![0u64; words];
                    for m in &mut map {
                        // Sparse, dense or full words.
                        *m = match rand() % 3 {
                            0 => rand() & rand() & rand(),
                            1 => rand(),
                            _ => u64::MAX,
                        };
                    }
                    let blocks = row.len().div_ceil(BLOCK);
                    if let Some(last) = map.last_mut() {
                        let keep = blocks - 64 * (words - 1);
                        if keep < 64 {
                            *last &= (1u64 << keep) - 1;
                        }
                    }
                    let fill = |row: &mut Vec<u8>, rand: &mut dyn FnMut() -> u64| {
                        row.iter_mut().for_each(|c| *c = 0);
                        for (i, c) in row.iter_mut().enumerate() {
                            let b = i / BLOCK;
                            if map[b / 64] >> (b % 64) & 1 == 1 {
                                *c = rand() as u8;
                            }
                        }
                    };
                    fill(&mut row, &mut rand);
                    let mut copy = row.clone();
                    for (wi, &m) in map.iter().enumerate() {
                        if crate::cpu::x86_fast() && round % 2 == 1 {
                            // Sixteen pixels at a time (the scan converter's AVX2 twins).
                            got.add_blocks::<true>(j, wi, m, &mut row);
                        } else {
                            got.add_blocks::<false>(j, wi, m, &mut row);
                        }
                        let mut bits = m;
                        while bits != 0 {
                            let s = bits.trailing_zeros() as usize;
                            let n = (!(bits >> s)).trailing_zeros() as usize;
                            bits &= bits.wrapping_add(1 << s);
                            let x0 = BLOCK * (64 * wi + s);
                            let x1 = (BLOCK * (64 * wi + s + n)).min(copy.len());
                            reference.add_span(j, x0, &mut copy[x0..x1]);
                        }
                    }
                    assert!(row.iter().all(|&c| c == 0), "cleared, round {round}");
                    for (at, &k) in got.slot.iter().enumerate() {
                        let kr = reference.slot[at];
                        assert_eq!(k == NONE, kr == NONE, "tile {at}");
                        if k != NONE {
                            let (a, b) = (&got.tiles[k as usize], &reference.tiles[kr as usize]);
                            assert_eq!(a.rows, b.rows, "tile {at}");
                            assert_eq!(a.span, b.span, "tile {at}");
                        }
                    }
                }
                got.flush(&mut page, 0);
                reference.flush(&mut want, 0);
                assert!(page == want, "{w} round {round}");
            }
        }
    }

    /// [`take`] is [`merge`] over a layer of 0: every coverage (a span of all 256),
    /// spans of every length 0–40 (the ways of sixteen, eight and one pixel).
    #[test]
    fn taken_coverage_is_merged_over_nothing() {
        for n in (0..=40).chain([256]) {
            let cov: Vec<u8> = (0..n).map(|i| (i * 97 + n) as u8).collect();
            let (mut want, mut want_cov) = (vec![0u8; n], cov.clone());
            merge(&mut want, &mut want_cov);
            let (mut got, mut got_cov) = (vec![0u8; n], cov.clone());
            take(&mut got, &mut got_cov);
            assert_eq!(got, want, "{n} pixels");
            assert_eq!(got, cov, "{n} pixels");
            assert!(got_cov.iter().all(|&c| c == 0), "{n} pixels cleared");
        }
    }

    /// [`merge`] and [`overprint_span`] (and where the processor has AVX2 [`merge_x16`]
    /// and [`overprint_x16`]) are their pixel-by-pixel formulas for every level under, every coverage and every
    /// gray (tails of 0–7 pixels too; the first
    /// 256 pixels, paper under, take [`overprint_span`]'s way for eight of paper).
    #[test]
    fn lanes_are_the_formulas_for_every_value() {
        let under: Vec<u8> = (0..65536 + 5).map(|i| (i >> 8) as u8).collect();
        let cov: Vec<u8> = (0..65536 + 5).map(|i| i as u8).collect();
        let (mut got, mut cleared) = (under.clone(), cov.clone());
        merge(&mut got, &mut cleared);
        assert!(cleared.iter().all(|&c| c == 0), "cleared");
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::x86_fast() {
            // Sixteen at a time, from every offset (tails of 0–15 pixels).
            for skip in 0..16 {
                let (mut sixteen, mut cleared) = (under[skip..].to_vec(), cov[skip..].to_vec());
                // SAFETY: the processor has AVX2 (`x86_fast`).
                #[allow(unsafe_code)]
                unsafe {
                    merge_x16(&mut sixteen, &mut cleared)
                };
                assert!(sixteen == got[skip..], "sixteen at a time from {skip}");
                assert!(cleared.iter().all(|&c| c == 0), "cleared");
            }
        }
        for (i, (&l, &c)) in under.iter().zip(&cov).enumerate() {
            let (ll, cc) = (u32::from(l), u32::from(c));
            assert_eq!(
                u32::from(got[i]),
                ll + ((255 - ll) * cc + 127) / 255,
                "{l} {c}"
            );
        }
        for g in 0..=255u8 {
            let mut got = under.clone();
            overprint_span(&mut got, &cov, g);
            for (i, (&d, &c)) in under.iter().zip(&cov).enumerate() {
                assert_eq!(got[i], overprint(d, c, u32::from(g)), "{d} {c} {g}");
            }
            #[cfg(target_arch = "x86_64")]
            if crate::cpu::x86_fast() {
                // Sixteen at a time, from an offset that changes with the gray.
                let skip = usize::from(g % 16);
                let mut sixteen = under[skip..].to_vec();
                // SAFETY: the processor has AVX2 (`x86_fast`).
                #[allow(unsafe_code)]
                unsafe {
                    overprint_x16(&mut sixteen, &cov[skip..], g)
                };
                assert!(sixteen == got[skip..], "sixteen at a time, gray {g}");
            }
        }
    }
}
