//! A scan converter for the strokes a page is made of: thin round-capped, round-joined
//! polylines (dashes, links, brackets), dots, rings and text halos.
//!
//! A round-capped, round-joined stroke of half width `r` along a polyline is the union
//! of the capsules (segments thickened by `r`) of its segments, so a pixel's coverage is
//! a function of its centre's distance `d` to the nearest segment: the length of
//! `[d − ½, d + ½] ∩ [−r, r]` (the pixel as a unit box across the stroke's edge). That is
//! exact for an edge along a row or a column, within a few levels for any other, keeps
//! the stroke's ink (its integral across the stroke is the width) and handles strokes
//! thinner than a pixel. The union is the nearest distance, so overlapping segments,
//! joins and crossing dashes of one stroke are never inked twice, as with a non-zero fill
//! of the stroke's outline.
//!
//! Rows are swept once per stroke; a segment makes its coverage of up to [`RING`] rows
//! at a time, from the first row it reaches, into that many one-row buffers (maximum
//! over segments), and a row is composited into the page at once when every segment
//! that reaches it has been made there, only over the spans the segments reach: no
//! page-sized layer, no outline, no supersampling. Everything is in f32 arithmetic that
//! depends only on the input (no threads, no platform-dependent functions: `sqrt` is
//! exact), so pages are byte-deterministic.

use crate::dirty::{BLOCK, Dirty};
use crate::layer::GrayLayer;
use crate::pixel::{div255, narrow, widen};
use coupler_layout::Ink;
use wide::{f32x4, i16x8, i32x8, u8x16, u16x8};

/// One segment of a stroke, in pixels, with the rows it may reach.
#[derive(Clone, Copy, Debug)]
struct Seg {
    a: [f32; 2],
    d: [f32; 2],
    /// `1 / |d|²`, or 0 for a point (or a segment whose `|d|²` is subnormal).
    inv: f32,
    /// `|d|` (as the body's interval needs it, row after row).
    l: f32,
    /// First row reached and one past the last.
    rows: (u32, u32),
    /// How a row's coverage is made ([`Seg::prepare`]): in [`Mode::Lanes`] every pixel
    /// the segment may reach is measured; in [`Mode::Exact`] the reach is the row's exact
    /// interval, the pixels within `r − ½` are filled (255) and only the edges are
    /// measured. The bytes are the same either way; only the work differs.
    mode: Mode,
    /// `1 / d.y`, or 0 when the segment is (nearly) along a row (for [`Mode::Lanes`]).
    rdy: f32,
}

/// See [`Seg::mode`].
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    Lanes,
    /// A wide stroke's segment ([`Mode::Exact`] in two halves: every segment of a row
    /// fills its interior, then the edges are measured but where they lie in pixels
    /// covered whole already, which stay as they are: 255 is the most coverage).
    Wide,
    Exact,
}

/// Page coordinates below which a pixel's centre is placed to a few ten-thousandths of a
/// pixel (an f32's ulp is below 1/2000 px there), far within the `½/255` of coverage that
/// rounding to a level forgives: the ways of [`Seg::mode`] give the same bytes. Beyond
/// (pages wider than 8192 px), the one way rows were always made.
const MODEST: f32 = 8192.0;

/// Thin strokes (half width in pixels) are measured in lanes; wider ones fill their
/// interiors, wider than [`LANES_MAX_R`]` − ½` pixels each side of the segment.
const LANES_MAX_R: f32 = 3.0;

impl Seg {
    /// Decides [`Seg::mode`] for half width `r`: a thin stroke's segment ([`LANES_MAX_R`])
    /// is measured in lanes over a conservative span (the pixels whose centre lies within
    /// the x-range of its part within `reach` of the row, widened by `reach` and an
    /// eighth of a pixel each side). The bytes are those of the exact interval with its
    /// interior filled:
    ///
    /// - the pixels beyond the exact interval are at least `reach` from the segment (up to
    ///   the rounding of the interval, a few ulps of a page coordinate), where
    ///   [`coverage`] is below a thousandth and rounds to level 0; so are those beyond
    ///   the span, by more than an eighth of a pixel (far beyond that rounding);
    /// - an interior pixel's centre is within `r − ½` of the segment (up to that rounding),
    ///   so the pixel lies across the stroke whole: [`coverage`] is `(d + ½) − (d − ½)`,
    ///   or `1 − δ` with `δ` far below the `½/255` that rounding to level 255 forgives.
    ///
    /// Both need the coordinates below [`MODEST`]; beyond, rows are made the exact way.
    /// Tested against it pixel for pixel: `rows_made_every_way_are_the_same_bytes`.
    fn prepare(&mut self, r: f32) {
        let [ax, ay] = self.a;
        let (bx, by) = (ax + self.d[0], ay + self.d[1]);
        let modest = ax.abs().max(ay.abs()).max(bx.abs()).max(by.abs()) < MODEST;
        self.rdy = if self.d[1].abs() > 1e-6 {
            1.0 / self.d[1]
        } else {
            0.0
        };
        self.mode = match (modest, r <= LANES_MAX_R) {
            (true, true) => Mode::Lanes,
            (true, false) => Mode::Wide,
            (false, _) => Mode::Exact,
        };
    }

    /// Whether the row's pixels within the segment's conservative span ([`Seg::reach_x`],
    /// a pixel more each side) are all covered whole already (or there are none): how
    /// [`Mode::Wide`] rows were made before [`measure_edges`] (the tests' reference).
    #[cfg(test)]
    fn covered(&self, cy: f32, reach: f32, row: &[u8]) -> bool {
        let Some((lo, hi)) = self.reach_x(cy, reach) else {
            return true;
        };
        let w = row.len() as f32;
        let x0 = floor(lo - 0.5).clamp(0.0, w) as usize;
        let x1 = (floor(hi - 0.5) + 2.0).clamp(0.0, w) as usize;
        let span = &row[x0..x1.max(x0)];
        let mut words = span.chunks_exact(8);
        words.all(|c| c == [255; 8]) && words.remainder().iter().all(|&v| v == 255)
    }

    /// The x-range `[lo, hi]` holding every point of the capsule of half width `reach`
    /// on the row line `y = cy`, or `None` when the segment stays farther than `reach`
    /// from the line: the x-range of the segment's part within `reach` of it, widened
    /// by `reach`.
    #[inline(always)]
    fn reach_x(&self, cy: f32, reach: f32) -> Option<(f32, f32)> {
        let (t0, t1) = if self.rdy != 0.0 {
            let u0 = (cy - reach - self.a[1]) * self.rdy;
            let u1 = (cy + reach - self.a[1]) * self.rdy;
            (u0.min(u1).max(0.0), u0.max(u1).min(1.0))
        } else {
            (0.0, 1.0)
        };
        if t0 > t1 {
            return None;
        }
        let (xa, xb) = (self.a[0] + t0 * self.d[0], self.a[0] + t1 * self.d[0]);
        Some((xa.min(xb) - reach, xa.max(xb) + reach))
    }
}

/// A page's ink buffer, seen by the scan converter.
pub(crate) struct Target<'a> {
    pub(crate) data: &'a mut [u8],
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) ink: Ink,
    /// Only rows `[rows.0, rows.1)` are drawn into (the whole height but while a page
    /// is drawn band by band): a row's pixels do not depend on the others.
    pub(crate) rows: (usize, usize),
    /// The page row `data` starts at (0 but for a band's buffer).
    pub(crate) first: usize,
    pub(crate) dirty: &'a mut Dirty,
    /// Where gray goes instead of the page, until it is composited.
    pub(crate) layer: Option<&'a mut GrayLayer>,
}

/// A segment's intervals on a row: where the row line lies within `r + ½` (its reach)
/// and within `r − ½` (its interior) of the segment ([`intervals`]).
type Intervals = [Option<(f32, f32)>; 2];

/// Rows of coverage a stroke gathers at once: a segment's rows are made [`RING`] at a
/// time (its state kept across them), into the row buffers of rows `j .. j + RING`,
/// row `j` in buffer `j % RING`; row `j` is composited once every segment that reaches
/// it has been made there.
const RING: usize = 32;

/// Scratch of the scan converter, reused from stroke to stroke ([`RING`] rows of the
/// page's width: about a hundred kilobytes for a tabloid page at 300 dpi).
#[derive(Default)]
pub(crate) struct Capsules {
    segs: Vec<Seg>,
    order: Vec<u32>,
    /// The active segments of the tests' reference row loop.
    #[cfg(test)]
    active: Vec<u32>,
    /// [`RING`] row buffers, row `j`'s at `j % RING`.
    slots: [Slot; RING],
    /// A row's spans, for the reference row loop of the tests.
    #[cfg(test)]
    spans: Vec<(u32, u32)>,
    /// The segments due on the row being made.
    due: Vec<u32>,
}

/// A row buffer of [`Capsules`], and what goes with it.
#[derive(Default)]
struct Slot {
    /// The row's coverage, `width` pixels (all 0 between rows).
    row: Vec<u8>,
    /// The blocks it holds coverage in.
    notes: Notes,
    /// The row's edges left to measure in [`Mode::Wide`]: `(segment, from, to)`.
    edges: Vec<(u32, u32, u32)>,
    /// The segments whose next rows start at its row (made up to [`RING`] rows
    /// before).
    wake: Vec<u32>,
}

/// The blocks ([`BLOCK`] pixels, the dirty map's) of a row buffer that hold the row's
/// spans: block `b` is bit `b % 64` of word `b / 64`; words `[lo, hi)` may hold bits
/// (see [`Notes::note`]).
#[derive(Default)]
struct Notes {
    blocks: Vec<u64>,
    lo: usize,
    hi: usize,
}

impl Notes {
    /// Notes that the row buffer holds coverage in pixels `[x0, x1)` (`x0 < x1`, within
    /// the row): their blocks are composited by [`Capsules::flush_row`].
    #[inline(always)]
    fn note(&mut self, (x0, x1): (u32, u32)) {
        let (b0, b1) = (x0 as usize / BLOCK, (x1 as usize - 1) / BLOCK);
        let (w0, w1) = (b0 / 64, b1 / 64);
        self.lo = self.lo.min(w0);
        self.hi = self.hi.max(w1 + 1);
        let blocks = &mut self.blocks;
        if w0 == w1 {
            blocks[w0] |= (u64::MAX << (b0 % 64)) & (u64::MAX >> (63 - b1 % 64));
        } else {
            blocks[w0] |= u64::MAX << (b0 % 64);
            blocks[w0 + 1..w1].fill(u64::MAX);
            blocks[w1] |= u64::MAX >> (63 - b1 % 64);
        }
    }
}

/// `x.floor()` without a call into libm (which the baseline x86-64 target makes of it),
/// the same value for every `x` but the sign of a zero result (`−0.5` gives `−1`, `−0.0`
/// gives `+0.0`), which every caller turns into an integer or compares.
#[inline(always)]
fn floor(x: f32) -> f32 {
    // Below 2^23 an f32 may have a fraction and fits an i32; beyond (and NaN), libm.
    if x.abs() < 8_388_608.0 {
        let t = x as i32 as f32;
        if t > x { t - 1.0 } else { t }
    } else {
        x.floor()
    }
}

/// `x.ceil()`, as [`floor`].
#[inline(always)]
fn ceil(x: f32) -> f32 {
    if x.abs() < 8_388_608.0 {
        let t = x as i32 as f32;
        if t < x { t + 1.0 } else { t }
    } else {
        x.ceil()
    }
}

/// The rows a target may be drawn into, `[c0, c1)` within the page, as f32.
fn clip_rows(t: &Target) -> (f32, f32) {
    let c1 = t.rows.1.min(t.height);
    (t.rows.0.min(c1) as f32, c1 as f32)
}

/// Coverage (0..=255) of a pixel whose centre is `d` from the middle of a stroke of half
/// width `r`.
#[inline(always)]
fn coverage(d: f32, r: f32) -> u8 {
    let c = ((d + 0.5).min(r) - (d - 0.5).max(-r)).clamp(0.0, 1.0);
    (c * 255.0 + 0.5) as u8
}

impl Capsules {
    /// Adds the segment `a`–`b` (pixels; `a == b` is a dot) to the stroke being built.
    pub(crate) fn push(&mut self, a: [f32; 2], b: [f32; 2]) {
        let d = [b[0] - a[0], b[1] - a[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        self.segs.push(Seg {
            a,
            d,
            // A subnormal `|d|²` (a segment shorter than 10⁻¹⁹ px) would make `inv`
            // infinite, and `0 · ∞` a NaN that [`Edge::measure`]'s finite lanes do not
            // expect: such a segment is its dot.
            inv: if len2 >= f32::MIN_POSITIVE {
                1.0 / len2
            } else {
                0.0
            },
            l: len2.sqrt(),
            rows: (0, 0),
            mode: Mode::Exact,
            rdy: 0.0,
        });
    }

    /// Strokes the segments added so far with half width `r` (pixels) in the target's
    /// ink, and forgets them. Marks what was inked in the target's `dirty` (not for
    /// paper, which only erases).
    ///
    /// On x86-64 with AVX2, BMI1 and BMI2 (checked at run time, [`x86_fast`](crate::cpu::x86_fast)) the same
    /// code compiled for them runs instead ([`Capsules::stroke_fast`]): the same IEEE
    /// f32 and integer operations in the same order (no fused multiply-add), so the
    /// same bytes, in fewer instructions.
    pub(crate) fn stroke(&mut self, r: f32, t: &mut Target) {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::x86_fast() {
            // SAFETY: `stroke_fast` needs AVX2, BMI1 and BMI2, which the processor was
            // just found to have; it has no other requirement (it is the safe
            // `stroke_body` compiled for them).
            #[allow(unsafe_code)]
            unsafe {
                self.stroke_fast(r, t)
            };
            return;
        }
        self.stroke_body::<false>(r, t)
    }

    /// [`Capsules::stroke_body`] compiled for AVX2, BMI1 and BMI2 (called only where
    /// the processor has them).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1,bmi2")]
    fn stroke_fast(&mut self, r: f32, t: &mut Target) {
        self.stroke_body::<true>(r, t)
    }

    /// The stroke itself ([`Capsules::stroke`]); inlined into each of its two callers
    /// so that each is compiled for its own instruction set. `X8` (only in
    /// [`Capsules::stroke_fast`], where the processor has AVX2): the pixels of a segment
    /// within [`MODEST`] coordinates measured eight at a time ([`Edge::measure_x8`]).
    #[inline(always)]
    fn stroke_body<const X8: bool>(&mut self, r: f32, t: &mut Target) {
        let mut segs = std::mem::take(&mut self.segs);
        let reach = r.max(0.0) + 0.5;
        if !(reach.is_finite() && reach > 0.5) || t.width == 0 || t.height == 0 {
            segs.clear();
            self.segs = segs;
            return;
        }
        let (c0, c1) = clip_rows(t);
        self.order.clear();
        for (k, s) in segs.iter_mut().enumerate() {
            let (y0, y1) = (s.a[1].min(s.a[1] + s.d[1]), s.a[1].max(s.a[1] + s.d[1]));
            // Rows whose centre j + ½ lies within `reach` of the segment's rows.
            let lo = floor(y0 - reach - 0.5).clamp(c0, c1);
            let hi = ceil(y1 + reach + 0.5).clamp(c0, c1);
            if lo.is_nan() || hi.is_nan() || lo >= hi || !(s.a[0] + s.d[0]).is_finite() {
                continue; // off the page, or not a number
            }
            s.rows = (lo as u32, hi as u32);
            s.prepare(r);
            self.order.push(k as u32);
        }
        self.order
            .sort_unstable_by_key(|&k| segs[k as usize].rows.0);
        self.fit(t.width);
        let mut next = 0;
        let mut j = 0u32;
        // Rows `[j, until)` may hold coverage; `pending` segments wait in `wake`.
        let (mut until, mut pending) = (0u32, 0usize);
        loop {
            if j >= until && pending == 0 {
                // Every row buffer composited: on to the next segment's first row.
                let Some(&k) = self.order.get(next) else {
                    break;
                };
                j = j.max(segs[k as usize].rows.0);
            }
            let at = j as usize % RING;
            std::mem::swap(&mut self.due, &mut self.slots[at].wake);
            pending -= self.due.len();
            while next < self.order.len() && segs[self.order[next] as usize].rows.0 <= j {
                self.due.push(self.order[next]);
                next += 1;
            }
            for i in 0..self.due.len() {
                let k = self.due[i];
                let s = &segs[k as usize];
                // Its rows from this one, up to RING of them.
                let end = j.saturating_add(RING as u32).min(s.rows.1);
                self.run::<X8>(s, k, j, end, r, reach);
                until = until.max(end);
                if end < s.rows.1 {
                    // Its next rows, once this row buffer is free (`end − j ≤ RING`).
                    self.slots[end as usize % RING].wake.push(k);
                    pending += 1;
                }
            }
            self.due.clear();
            let slot = &mut self.slots[at];
            if !slot.edges.is_empty() {
                measure_edges::<X8>(&segs, &slot.edges, j as f32 + 0.5, r, &mut slot.row);
                slot.edges.clear();
            }
            self.flush_row::<X8>(j as usize, t);
            j += 1;
        }
        segs.clear();
        self.segs = segs;
    }

    /// A thin segment's coverage of row `row` (centre `cy`) within its conservative span
    /// `[x0, x1)` measured into the row's buffer, and the inked span noted.
    #[inline(always)]
    fn measure_row<const X8: bool>(
        &mut self,
        s: &Seg,
        row: usize,
        cy: f32,
        r: f32,
        x0: u32,
        x1: u32,
    ) {
        let (x0, x1) = (x0 as usize, x1 as usize);
        if x0 < x1 {
            let slot = &mut self.slots[row % RING];
            let edge = Edge::new(s, cy, r);
            if let Some(span) = edge.measure_finite::<X8>(&mut slot.row, x0, x1) {
                slot.notes.note(span);
            }
        }
    }

    /// Makes segment `s`'s (`k`'s) coverage of rows `[j, end)` (`end − j ≤ RING`) in
    /// their row buffers and notes their spans; in [`Mode::Wide`] leaves their edges in
    /// `edges` (see [`seg_row_fill`]).
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // a row's lane of four rows' spans
    fn run<const X8: bool>(&mut self, s: &Seg, k: u32, j: u32, end: u32, r: f32, reach: f32) {
        let w = self.slots[0].row.len() as f32;
        match s.mode {
            #[cfg(target_arch = "x86_64")]
            Mode::Lanes if X8 && w < 4_194_304.0 => {
                // The segment's conservative spans eight rows at a time.
                for i in (j..end).step_by(8) {
                    let cy8 = [0, 1, 2, 3, 4, 5, 6, 7].map(|m| (i + m) as f32 + 0.5);
                    // SAFETY: `lanes_spans8` needs AVX2; `X8` is true only in the
                    // stroke's twin compiled for AVX2, BMI1 and BMI2, which runs only
                    // where the processor was found to have them (`Capsules::stroke`).
                    #[allow(unsafe_code)]
                    let [x0, x1] = unsafe { lanes_spans8(s, cy8, reach, w) };
                    for m in 0..(end - i).min(8) as usize {
                        self.measure_row::<X8>(s, i as usize + m, cy8[m], r, x0[m], x1[m]);
                    }
                }
            }
            Mode::Lanes => {
                // The segment's conservative spans four rows at a time.
                for i in (j..end).step_by(4) {
                    let cy4 = [0, 1, 2, 3].map(|m| (i + m) as f32 + 0.5);
                    let [x0, x1] = lanes_spans4(s, cy4, reach, w);
                    for m in 0..(end - i).min(4) as usize {
                        self.measure_row::<X8>(s, i as usize + m, cy4[m], r, x0[m], x1[m]);
                    }
                }
            }
            #[cfg(target_arch = "x86_64")]
            Mode::Wide if X8 && w < 4_194_304.0 => {
                // The segment's pixel spans eight rows at a time (the spans' order does
                // not matter).
                for i in (j..end).step_by(8) {
                    let cy8 = [0, 1, 2, 3, 4, 5, 6, 7].map(|m| (i + m) as f32 + 0.5);
                    // SAFETY: `wide_spans8` needs AVX2; `X8` is true only in the stroke's
                    // twin compiled for AVX2, BMI1 and BMI2, which runs only where the
                    // processor was found to have them (`Capsules::stroke`).
                    #[allow(unsafe_code)]
                    let spans = unsafe { wide_spans8(s, cy8, reach, r - 0.5, w) };
                    for m in 0..(end - i).min(8) as usize {
                        let at = (i as usize + m) % RING;
                        let Slot {
                            row, notes, edges, ..
                        } = &mut self.slots[at];
                        let row_spans = [0, 1, 2, 3].map(|b| spans[b][m] as usize);
                        if let Some(span) = seg_row_fill(k, row_spans, row, edges) {
                            notes.note(span);
                        }
                    }
                }
            }
            Mode::Wide => {
                // The segment's pixel spans four rows at a time (the spans' order does
                // not matter).
                for i in (j..end).step_by(4) {
                    let cy4 = [0, 1, 2, 3].map(|m| (i + m) as f32 + 0.5);
                    let spans = wide_spans4(s, cy4, reach, r - 0.5, w);
                    for m in 0..(end - i).min(4) as usize {
                        let at = (i as usize + m) % RING;
                        let Slot {
                            row, notes, edges, ..
                        } = &mut self.slots[at];
                        let row_spans = [0, 1, 2, 3].map(|b| spans[b][m] as usize);
                        if let Some(span) = seg_row_fill(k, row_spans, row, edges) {
                            notes.note(span);
                        }
                    }
                }
            }
            Mode::Exact => {
                for i in j..end {
                    let at = i as usize % RING;
                    let slot = &mut self.slots[at];
                    if let Some(span) = seg_row(s, i as f32 + 0.5, r, reach, &mut slot.row) {
                        slot.notes.note(span);
                    }
                }
            }
        }
    }

    /// Sizes the row buffers and their block maps for rows of `width` pixels (all 0
    /// between rows, so resized in place).
    fn fit(&mut self, width: usize) {
        if self.slots[0].row.len() != width || self.slots[0].notes.blocks.is_empty() {
            let words = width.div_ceil(BLOCK).div_ceil(64).max(1);
            for Slot { row, notes, .. } in &mut self.slots {
                row.resize(width, 0);
                notes.blocks.resize(words, 0);
                (notes.lo, notes.hi) = (words, 0);
            }
        }
    }

    /// Composites row `j`'s buffer's noted blocks into row `j` and clears them: each run
    /// of adjacent blocks within a word of the block map at once, in the order of the
    /// row (a pixel of a noted block that no span reached has coverage 0, which leaves
    /// the page as it is; a run across words is composited in two pieces, split at a
    /// multiple of 512 pixels, which changes no pixel's arithmetic), and marks the
    /// blocks in the target's `dirty` (not for paper): the blocks the spans touch, as
    /// marking each span would. Into the gray layer, a tile's noted blocks at once
    /// ([`GrayLayer::add_blocks`], sixteen pixels at a time with `X8`). Inlined into the
    /// stroke's and the ring's two
    /// instruction sets' code ([`Capsules::stroke`]).
    #[inline(always)]
    fn flush_row<const X8: bool>(&mut self, j: usize, t: &mut Target) {
        let Slot {
            row: cov, notes, ..
        } = &mut self.slots[j % RING];
        if notes.lo >= notes.hi {
            return;
        }
        let (wlo, whi) = (notes.lo, notes.hi);
        (notes.lo, notes.hi) = (notes.blocks.len(), 0);
        let blocks = &mut notes.blocks[wlo..whi];
        if t.ink != Ink::Paper {
            t.dirty.mark_blocks(j, wlo, blocks);
        }
        if let Some(layer) = t.layer.as_deref_mut() {
            for (w, bits) in (wlo..).zip(blocks) {
                layer.add_blocks::<X8>(j, w, std::mem::take(bits), cov);
            }
            return;
        }
        let row = &mut t.data[(j - t.first) * t.width..(j - t.first + 1) * t.width];
        let (width, ink) = (t.width, t.ink);
        for (w, bits) in (wlo..).zip(blocks) {
            let mut bits = std::mem::take(bits);
            while bits != 0 {
                let s = bits.trailing_zeros() as usize;
                let n = (!(bits >> s)).trailing_zeros() as usize;
                // The lowest run of ones cleared.
                bits &= bits.wrapping_add(1 << s);
                let (x0, x1) = (BLOCK * (64 * w + s), (BLOCK * (64 * w + s + n)).min(width));
                composite_span(&mut row[x0..x1], &mut cov[x0..x1], ink);
            }
        }
    }

    /// Strokes the circle of radius `radius` about `c` (pixels) with half width `r`: a
    /// ring, the distance to the circle being `| |p − c| − radius |`.
    /// As [`Capsules::stroke`], compiled for AVX2, BMI1 and BMI2 where the processor
    /// has them ([`Capsules::ring_fast`]).
    pub(crate) fn ring(&mut self, c: [f32; 2], radius: f32, r: f32, t: &mut Target) {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::x86_fast() {
            // SAFETY: `ring_fast` needs AVX2, BMI1 and BMI2, which the processor was just
            // found to have; it has no other requirement (it is the safe `ring_with`
            // compiled for them).
            #[allow(unsafe_code)]
            unsafe {
                self.ring_fast(c, radius, r, t)
            };
            return;
        }
        self.ring_with::<false>(c, radius, r, t, ring_span);
    }

    /// [`Capsules::ring`] compiled for AVX2, BMI1 and BMI2 (called only where the
    /// processor has them).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1,bmi2")]
    fn ring_fast(&mut self, c: [f32; 2], radius: f32, r: f32, t: &mut Target) {
        self.ring_with::<true>(c, radius, r, t, ring_span);
    }

    /// [`Capsules::ring`] with the pixels of an arc's span measured by `span`
    /// ([`ring_span`], or pixel by pixel in the tests' reference); `X8` only in
    /// [`Capsules::ring_fast`] (an arc's span measured eight pixels at a time,
    /// [`ring_span_x8`], in place of `span`; a gray ring's rows merged into the layer
    /// sixteen pixels at a time, [`GrayLayer::add_blocks`]).
    #[inline(always)]
    fn ring_with<const X8: bool>(
        &mut self,
        c: [f32; 2],
        radius: f32,
        r: f32,
        t: &mut Target,
        span: fn(&mut [u8], usize, usize, Ring),
    ) {
        let reach = r.max(0.0) + 0.5;
        let outer = radius.abs() + reach;
        if !(outer.is_finite() && reach > 0.5 && c[0].is_finite() && c[1].is_finite()) {
            return;
        }
        let w = t.width as f32;
        let (c0, c1) = clip_rows(t);
        self.fit(t.width);
        let lo = floor(c[1] - outer - 0.5).clamp(c0, c1) as usize;
        let hi = ceil(c[1] + outer + 0.5).clamp(c0, c1) as usize;
        let inner = (radius.abs() - reach).max(0.0);
        for j in lo..hi {
            let dy = j as f32 + 0.5 - c[1];
            let xo = (outer * outer - dy * dy).max(0.0).sqrt();
            let xi = (inner * inner - dy * dy).max(0.0).sqrt();
            let ring = Ring {
                cx: c[0],
                dy,
                radius,
                r,
            };
            // The two arcs of the ring on this row: [c − xo, c − xi] and [c + xi, c + xo].
            for (a, b) in [(c[0] - xo, c[0] - xi), (c[0] + xi, c[0] + xo)] {
                let x0 = floor(a - 1.0).clamp(0.0, w) as usize;
                let x1 = ceil(b + 1.0).clamp(0.0, w) as usize;
                if x0 >= x1 {
                    continue;
                }
                let at = j % RING;
                let slot = &mut self.slots[at];
                #[cfg(target_arch = "x86_64")]
                if X8 {
                    // SAFETY: `ring_span_x8` needs AVX2; `X8` is true only in the ring's
                    // twin compiled for AVX2, BMI1 and BMI2, which runs only where the
                    // processor was found to have them (`Capsules::ring`).
                    #[allow(unsafe_code)]
                    unsafe {
                        ring_span_x8(&mut slot.row, x0, x1, ring)
                    };
                } else {
                    span(&mut slot.row, x0, x1, ring);
                }
                #[cfg(not(target_arch = "x86_64"))]
                span(&mut slot.row, x0, x1, ring);
                slot.notes.note((x0 as u32, x1 as u32));
            }
            self.flush_row::<X8>(j, t);
        }
    }
}

/// A ring on a row: its centre's x, the row centre's height above its centre, its
/// radius and half width (pixels).
#[derive(Clone, Copy)]
struct Ring {
    cx: f32,
    dy: f32,
    radius: f32,
    r: f32,
}

impl Ring {
    /// Pixel `x`'s coverage (the reference [`ring_span`] follows in lanes).
    #[inline(always)]
    fn pixel(self, x: usize) -> u8 {
        let dx = x as f32 + 0.5 - self.cx;
        let d = ((dx * dx + self.dy * self.dy).sqrt() - self.radius).abs();
        coverage(d, self.r)
    }
}

/// Pixels `[x0, x1)` of `row` ← the maximum of theirs and ring `g`'s coverage, four at a
/// time: per lane the f32 operations of [`Ring::pixel`] in its order (IEEE operations,
/// the same bits; `min`, `max` and the clamp as `f32`'s, NaN included, and the level's
/// truncation `as u8`'s: a level in `[½, 255.5]`, or 0 for NaN), so the bytes are the
/// pixel by pixel ones. A pixel's index is exact in an f32 below 2^24 (beyond, pixel by
/// pixel).
#[inline]
fn ring_span(row: &mut [u8], x0: usize, x1: usize, g: Ring) {
    let n = if x1 <= 1 << 24 { x1 - x0 } else { 0 };
    let lanes = n - n % 4;
    let half = f32x4::splat(0.5);
    let (cx, dy2) = (f32x4::splat(g.cx), f32x4::splat(g.dy * g.dy));
    let (radius, r) = (f32x4::splat(g.radius), f32x4::splat(g.r));
    let mut x = f32x4::splat(x0 as f32) + f32x4::new([0.0, 1.0, 2.0, 3.0]);
    let four = f32x4::splat(4.0);
    for px4 in row[x0..x0 + lanes].chunks_exact_mut(4) {
        let dx = x + half - cx;
        x += four;
        let d = ((dx * dx + dy2).sqrt() - radius).abs();
        let c = clamp01((d + half).min(r) - (d - half).max(-r));
        let v = (c * f32x4::splat(255.0) + half).trunc_int().to_array();
        // The four levels (each in 0..=255: the saturating packs keep them) as bytes,
        // their maxima with the row's in byte lanes.
        let b = i32x8::new([v[0], v[1], v[2], v[3], 0, 0, 0, 0]);
        let b = u8x16::narrow_i16x8(i16x8::from_i32x8_saturate(b), i16x8::ZERO);
        let mut p = [0u8; 16];
        p[..4].copy_from_slice(px4);
        px4.copy_from_slice(&u8x16::new(p).max(b).to_array()[..4]);
    }
    for (i, px) in row[x0 + lanes..x1].iter_mut().enumerate() {
        *px = (*px).max(g.pixel(x0 + lanes + i));
    }
}

/// [`ring_span`] eight pixels at a time in AVX's 256-bit lanes (from
/// [`Capsules::ring_fast`] only): per lane the same f32 operations in the same order
/// (`vsqrtps`, `vminps`/`vmaxps` with the operands of `min`/`max`, the truncation
/// `vcvttps2dq`; no fused multiply-add), so the same levels bit for bit. `min` and
/// `max` are f32's for every value here: their first operand, `d ± ½`, is never NaN
/// (`d` is the absolute difference of a square root of a sum of squares of finite
/// values, `+∞` at most, and a finite radius), and when it were, `vminps`/`vmaxps`
/// give the second operand, as f32's do. The clamp to `[0, 1]` has no NaN case: `c`
/// is a finite `min` less a `max` that is finite or `+∞`. The levels (0..=255) are
/// packed to bytes and their maxima with the row's taken eight at a time; the last
/// pixels of a span (fewer than eight) take the first lanes' bytes. Beyond 2^24
/// pixels, pixel by pixel, as [`ring_span`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn ring_span_x8(row: &mut [u8], x0: usize, x1: usize, g: Ring) {
    use std::arch::x86_64::*;
    if x1 > 1 << 24 {
        ring_span(row, x0, x1, g);
        return;
    }
    let half = _mm256_set1_ps(0.5);
    let (cx, dy2) = (_mm256_set1_ps(g.cx), _mm256_set1_ps(g.dy * g.dy));
    let radius = _mm256_set1_ps(g.radius);
    let (r, neg_r) = (_mm256_set1_ps(g.r), _mm256_set1_ps(-g.r));
    let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
    let full = _mm256_set1_ps(255.0);
    // The sign bit, for `abs`.
    let sign = _mm256_set1_ps(-0.0);
    // Eight pixels' levels' `as u8` as eight bytes of a word (first pixel lowest), from
    // their indices as f32.
    let levels = |x: __m256| {
        let dx = _mm256_sub_ps(_mm256_add_ps(x, half), cx);
        let d = _mm256_sub_ps(
            _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), dy2)),
            radius,
        );
        let d = _mm256_andnot_ps(sign, d);
        let c = _mm256_sub_ps(
            _mm256_min_ps(_mm256_add_ps(d, half), r),
            _mm256_max_ps(_mm256_sub_ps(d, half), neg_r),
        );
        let c = _mm256_min_ps(_mm256_max_ps(c, zero), one);
        let v = _mm256_cvttps_epi32(_mm256_add_ps(_mm256_mul_ps(c, full), half));
        let w = _mm_packs_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
        _mm_cvtsi128_si64(_mm_packus_epi16(w, _mm_setzero_si128())) as u64
    };
    // Pixel indices x0 + k (k < 8) to begin with, eight more each time; below 2^24
    // exact, as `(x0 + k) as f32`.
    let mut x = _mm256_add_ps(
        _mm256_set1_ps(x0 as f32),
        _mm256_setr_ps(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0),
    );
    let eight = _mm256_set1_ps(8.0);
    let span = &mut row[x0..x1];
    let whole = span.len() - span.len() % 8;
    let (body, tail) = span.split_at_mut(whole);
    for px8 in body.chunks_exact_mut(8) {
        let v = levels(x);
        x = _mm256_add_ps(x, eight);
        let px8: &mut [u8; 8] = px8.try_into().expect("8 pixels");
        let b = u64::from_le_bytes(*px8);
        let m = _mm_max_epu8(_mm_cvtsi64_si128(b as i64), _mm_cvtsi64_si128(v as i64));
        *px8 = (_mm_cvtsi128_si64(m) as u64).to_le_bytes();
    }
    if !tail.is_empty() {
        let v = levels(x);
        for (px, v) in tail.iter_mut().zip(v.to_le_bytes()) {
            *px = (*px).max(v);
        }
    }
}

/// The `x` interval where the row line `y = cy` lies within `rho` of segment `s` (the
/// capsule is convex: the hull of the intervals of its two end discs and its body): the
/// reference [`intervals`] follows, lane by lane.
#[cfg(test)]
fn interval(s: &Seg, cy: f32, rho: f32) -> Option<(f32, f32)> {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    let mut add = |a: f32, b: f32| {
        if a <= b {
            lo = lo.min(a);
            hi = hi.max(b);
        }
    };
    let ey = cy - s.a[1];
    let [dx, dy] = s.d;
    for (x, y) in [(s.a[0], ey), (s.a[0] + dx, ey - dy)] {
        let q = rho * rho - y * y;
        if q >= 0.0 {
            let h = q.sqrt();
            add(x - h, x + h);
        }
    }
    if s.inv > 0.0 {
        // Body: 0 ≤ t ≤ 1 and |perpendicular distance| ≤ rho, with u = x − ax:
        // t·L² = u·dx + ey·dy, perp·L = ey·dx − u·dy.
        let l = s.l;
        let (mut u0, mut u1) = (f32::NEG_INFINITY, f32::INFINITY);
        let mut within = |k: f32, c0: f32, c1: f32| {
            // c0 ≤ u·k ≤ c1
            if k != 0.0 {
                let (a, b) = (c0 / k, c1 / k);
                u0 = u0.max(a.min(b));
                u1 = u1.min(a.max(b));
            } else if !(c0 <= 0.0 && 0.0 <= c1) {
                u1 = f32::NEG_INFINITY;
            }
        };
        within(dx, -ey * dy, l * l - ey * dy);
        within(-dy, -rho * l - ey * dx, rho * l - ey * dx);
        add(s.a[0] + u0, s.a[0] + u1);
    }
    (lo <= hi).then_some((lo, hi))
}

/// The `x` intervals where the row line `y = cy` lies within `reach` and within `inner`
/// of segment `s`, at once: per distance the f32 operations of `interval` (the tests'
/// reference) in its order (the end discs' square roots and the body's divisions four
/// at a time, IEEE operations with the same bits; the body's first bound, which does not
/// depend on the distance, once), so the intervals are `interval`'s.
#[inline]
fn intervals(s: &Seg, cy: f32, reach: f32, inner: f32) -> Intervals {
    let ey = cy - s.a[1];
    let [dx, dy] = s.d;
    let ends = [(s.a[0], ey), (s.a[0] + dx, ey - dy)];
    let q = [
        reach * reach - ends[0].1 * ends[0].1,
        reach * reach - ends[1].1 * ends[1].1,
        inner * inner - ends[0].1 * ends[0].1,
        inner * inner - ends[1].1 * ends[1].1,
    ];
    // The lanes of a negative q are not used.
    let h = f32x4::new(q).sqrt().to_array();
    let body = s.inv > 0.0;
    let l = s.l;
    // The body's bounds on u = x − ax (see `interval`): along the segment, for both.
    let (mut u0, mut u1) = (f32::NEG_INFINITY, f32::INFINITY);
    let c = [
        -reach * l - ey * dx,
        reach * l - ey * dx,
        -inner * l - ey * dx,
        inner * l - ey * dx,
    ];
    let k = -dy;
    let mut v = [0.0; 4];
    if body {
        if dx != 0.0 {
            let (a, b) = ((-ey * dy) / dx, (l * l - ey * dy) / dx);
            u0 = u0.max(a.min(b));
            u1 = u1.min(a.max(b));
        } else if !(-ey * dy <= 0.0 && 0.0 <= l * l - ey * dy) {
            u1 = f32::NEG_INFINITY;
        }
        if k != 0.0 {
            v = (f32x4::new(c) / f32x4::splat(k)).to_array();
        }
    }
    let mut out = [None; 2];
    for (m, out) in out.iter_mut().enumerate() {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let mut add = |a: f32, b: f32| {
            if a <= b {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        };
        for (e, &(x, _)) in ends.iter().enumerate() {
            if q[2 * m + e] >= 0.0 {
                let h = h[2 * m + e];
                add(x - h, x + h);
            }
        }
        if body {
            // Across the segment, within the distance.
            let (mut u0, mut u1) = (u0, u1);
            if k != 0.0 {
                let (a, b) = (v[2 * m], v[2 * m + 1]);
                u0 = u0.max(a.min(b));
                u1 = u1.min(a.max(b));
            } else if !(c[2 * m] <= 0.0 && 0.0 <= c[2 * m + 1]) {
                u1 = f32::NEG_INFINITY;
            }
            add(s.a[0] + u0, s.a[0] + u1);
        }
        *out = (lo <= hi).then_some((lo, hi));
    }
    out
}

/// [`intervals`] of segment `s` on four rows at once (centres `cy`), a row a lane: per
/// lane the f32 operations of `interval` (the tests' reference) in its order, each branch
/// made in every lane and chosen by a mask. Only for segments within [`MODEST`]
/// coordinates, whose values are finite: `min` and `max` then without their NaN cases
/// (the lanes a branch does not choose, which may be NaN, are dropped). Their bounds may
/// differ from `interval`'s in the sign of a zero only, which no pixel span made of them
/// tells apart.
#[cfg(test)]
fn intervals4(s: &Seg, cy: [f32; 4], reach: f32, inner: f32) -> [Intervals; 4] {
    let mut out = [[None; 2]; 4];
    for (m, (lo, hi)) in intervals4_lanes(s, cy, reach, inner)
        .into_iter()
        .enumerate()
    {
        let (lo, hi) = (lo.to_array(), hi.to_array());
        for (j, out) in out.iter_mut().enumerate() {
            out[m] = (lo[j] <= hi[j]).then_some((lo[j], hi[j]));
        }
    }
    out
}

/// [`intervals4`] as lanes: per distance (`reach`, `inner`) the bounds `lo` and `hi` of
/// the four rows' intervals, a row a lane; a row without an interval has `lo = +∞` and
/// `hi = −∞`.
#[inline(always)]
fn intervals4_lanes(s: &Seg, cy: [f32; 4], reach: f32, inner: f32) -> [(f32x4, f32x4); 2] {
    let ax = f32x4::splat(s.a[0]);
    let ey = f32x4::new(cy) - f32x4::splat(s.a[1]);
    let dx = f32x4::splat(s.d[0]);
    let dy = f32x4::splat(s.d[1]);
    let l = f32x4::splat(s.l);
    let (ninf, inf) = (f32x4::splat(f32::NEG_INFINITY), f32x4::INFINITY);
    // Whether the segment has a body, and is along a row or a column, is the same in
    // every lane: a branch each, not a mask (a mask of all ones or none selects one
    // side whole, bit for bit).
    // The body's bounds on u = x − ax along the segment, for both distances.
    let (b0, b1) = {
        let (c0, c1) = (-ey * dy, l * l - ey * dy);
        if s.d[0] != 0.0 {
            let (a, b) = (c0 / dx, c1 / dx);
            (ninf.fast_max(a.fast_min(b)), inf.fast_min(a.fast_max(b)))
        } else {
            let within = c0.simd_le(f32x4::ZERO) & c1.simd_ge(f32x4::ZERO);
            (ninf, within.bitselect(inf, ninf))
        }
    };
    let lanes = Lanes4 {
        ax,
        ey,
        dx,
        l,
        k: -dy,
        ends: [(ax, ey), (ax + dx, ey - dy)],
        b0,
        b1,
        body: s.inv > 0.0,
        across: s.d[1] != 0.0,
    };
    [lanes.bounds(reach), lanes.bounds(inner)]
}

/// What [`intervals4_lanes`] makes the intervals of, for each distance.
struct Lanes4 {
    ax: f32x4,
    ey: f32x4,
    dx: f32x4,
    l: f32x4,
    k: f32x4,
    ends: [(f32x4, f32x4); 2],
    b0: f32x4,
    b1: f32x4,
    body: bool,
    across: bool,
}

impl Lanes4 {
    /// The bounds `lo` and `hi` of the four rows' intervals within `rho`.
    #[inline(always)]
    fn bounds(&self, rho: f32) -> (f32x4, f32x4) {
        let (ninf, inf) = (f32x4::splat(f32::NEG_INFINITY), f32x4::INFINITY);
        let end = |&(x, y): &(f32x4, f32x4)| {
            let q = f32x4::splat(rho * rho) - y * y;
            let h = q.sqrt();
            let (a, b) = (x - h, x + h);
            (q.simd_ge(f32x4::ZERO) & a.simd_le(b), a, b)
        };
        // The first end's interval, where it has one (the minimum of +∞ and a bound
        // is the bound: `minps` gives its second operand but where the first is less).
        let (ok, a, b) = end(&self.ends[0]);
        let (mut lo, mut hi) = (ok.bitselect(a, inf), ok.bitselect(b, ninf));
        let mut add = |ok: f32x4, a: f32x4, b: f32x4| {
            lo = ok.bitselect(lo.fast_min(a), lo);
            hi = ok.bitselect(hi.fast_max(b), hi);
        };
        let (ok, a, b) = end(&self.ends[1]);
        add(ok, a, b);
        if self.body {
            // Across the segment, within the distance.
            let c0 = f32x4::splat(-rho) * self.l - self.ey * self.dx;
            let c1 = f32x4::splat(rho) * self.l - self.ey * self.dx;
            let (u0, u1) = if self.across {
                let (a, b) = (c0 / self.k, c1 / self.k);
                (
                    self.b0.fast_max(a.fast_min(b)),
                    self.b1.fast_min(a.fast_max(b)),
                )
            } else {
                let within = c0.simd_le(f32x4::ZERO) & c1.simd_ge(f32x4::ZERO);
                (self.b0, within.bitselect(self.b1, ninf))
            };
            let (a, b) = (self.ax + u0, self.ax + u1);
            add(a.simd_le(b), a, b);
        }
        (lo, hi)
    }
}

/// The pixel spans of wide segment `s` ([`Mode::Wide`], within [`MODEST`]
/// coordinates) on four rows at once (centres `cy`), a row a lane, on a row of `w`
/// pixels: `[x0, x1, j0, j1]`, the pixels whose centre lies in its reach (`[x0, x1)`,
/// none when `x0 ≥ x1`) and in its interior (`[j0, j1)` before [`seg_row_fill`]
/// clamps it to the reach), as [`pixel_spans`] makes them of each row's [`intervals`]
/// (of the reach twice when the interior has none: it then gives an empty interior
/// all the same). Each bound is clamped to `[−1, w + 1]` before it is made a whole
/// number, which changes no span clamped to `[0, w]` after, and keeps every lane
/// finite (`±∞` where a row has no interval) and below 2^23 for the lanes' truncation.
#[inline(always)]
fn wide_spans4(s: &Seg, cy: [f32; 4], reach: f32, inner: f32, w: f32) -> [[u32; 4]; 4] {
    let [(lo, hi), (ilo, ihi)] = intervals4_lanes(s, cy, reach, inner);
    let half = f32x4::splat(0.5);
    if w < 4_194_304.0 {
        let (below, above) = (f32x4::splat(-1.0), f32x4::splat(w + 1.0));
        let clamp = |x: f32x4| x.fast_max(below).fast_min(above);
        let floor = |x: f32x4| {
            let t = x.fast_trunc_int().round_float();
            t - (t.simd_gt(x) & f32x4::ONE)
        };
        let (zero, wl) = (f32x4::ZERO, f32x4::splat(w));
        let fit = |p: f32x4| {
            let p = p.fast_max(zero).fast_min(wl).fast_trunc_int();
            p.to_array().map(|p| p as u32)
        };
        // ceil(x) is −floor(−x).
        [
            fit(-floor(-clamp(lo - half))),
            fit(floor(clamp(hi - half)) + f32x4::ONE),
            fit(-floor(-clamp(ilo - half))),
            fit(floor(clamp(ihi - half)) + f32x4::ONE),
        ]
    } else {
        let v = [lo, hi, ilo, ihi].map(|v| v.to_array());
        let mut out = [[0; 4]; 4];
        for m in 0..4 {
            let p = pixel_spans([v[0][m], v[1][m], v[2][m], v[3][m]], [0.5; 4], w);
            for (o, p) in out.iter_mut().zip(p) {
                o[m] = p as u32;
            }
        }
        out
    }
}

/// [`wide_spans4`] on eight rows at once, in AVX's 256-bit lanes (rows of fewer than
/// 2^22 pixels): per lane the f32 operations of [`intervals4_lanes`] and of
/// [`wide_spans4`]'s bounds in their order, with the operands of `wide`'s `fast_max`,
/// `fast_min`, `bitselect` (and, and-not, or) and negation (the sign bit flipped), and
/// its truncations (`vcvttps2dq`) and conversions: the same bits, so the same spans.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn wide_spans8(s: &Seg, cy: [f32; 8], reach: f32, inner: f32, w: f32) -> [[u32; 8]; 4] {
    use std::arch::x86_64::*;
    let splat = _mm256_set1_ps;
    let (add, sub, mul, div) = (_mm256_add_ps, _mm256_sub_ps, _mm256_mul_ps, _mm256_div_ps);
    let (max, min) = (_mm256_max_ps, _mm256_min_ps);
    let neg = |x: __m256| _mm256_xor_ps(x, splat(-0.0));
    // `mask.bitselect(t, f)`: `(t & mask) | (f & !mask)`.
    let select = |mask: __m256, t: __m256, f: __m256| {
        _mm256_or_ps(_mm256_and_ps(t, mask), _mm256_andnot_ps(mask, f))
    };
    let le = |a: __m256, b: __m256| _mm256_cmp_ps::<_CMP_LE_OQ>(a, b);
    let ge = |a: __m256, b: __m256| _mm256_cmp_ps::<_CMP_GE_OQ>(a, b);
    let (zero, one) = (_mm256_setzero_ps(), splat(1.0));
    let (ninf, inf) = (splat(f32::NEG_INFINITY), splat(f32::INFINITY));
    let cy = _mm256_setr_ps(cy[0], cy[1], cy[2], cy[3], cy[4], cy[5], cy[6], cy[7]);
    let ax = splat(s.a[0]);
    let ey = sub(cy, splat(s.a[1]));
    let dx = splat(s.d[0]);
    let dy = splat(s.d[1]);
    let l = splat(s.l);
    // The body's bounds on u = x − ax along the segment ([`intervals4_lanes`]).
    let (b0, b1) = {
        let (c0, c1) = (mul(neg(ey), dy), sub(mul(l, l), mul(ey, dy)));
        if s.d[0] != 0.0 {
            let (a, b) = (div(c0, dx), div(c1, dx));
            (max(ninf, min(a, b)), min(inf, max(a, b)))
        } else {
            let within = _mm256_and_ps(le(c0, zero), ge(c1, zero));
            (ninf, select(within, inf, ninf))
        }
    };
    let k = neg(dy);
    let ends = [(ax, ey), (add(ax, dx), sub(ey, dy))];
    let (body, across) = (s.inv > 0.0, s.d[1] != 0.0);
    // [`Lanes4::bounds`].
    let bounds = |rho: f32| {
        let end = |(x, y): (__m256, __m256)| {
            let q = sub(splat(rho * rho), mul(y, y));
            let h = _mm256_sqrt_ps(q);
            let (a, b) = (sub(x, h), add(x, h));
            (_mm256_and_ps(ge(q, zero), le(a, b)), a, b)
        };
        let (ok, a, b) = end(ends[0]);
        let (mut lo, mut hi) = (select(ok, a, inf), select(ok, b, ninf));
        let mut put = |ok: __m256, a: __m256, b: __m256| {
            lo = select(ok, min(lo, a), lo);
            hi = select(ok, max(hi, b), hi);
        };
        let (ok, a, b) = end(ends[1]);
        put(ok, a, b);
        if body {
            let c0 = sub(mul(splat(-rho), l), mul(ey, dx));
            let c1 = sub(mul(splat(rho), l), mul(ey, dx));
            let (u0, u1) = if across {
                let (a, b) = (div(c0, k), div(c1, k));
                (max(b0, min(a, b)), min(b1, max(a, b)))
            } else {
                let within = _mm256_and_ps(le(c0, zero), ge(c1, zero));
                (b0, select(within, b1, ninf))
            };
            let (a, b) = (add(ax, u0), add(ax, u1));
            put(le(a, b), a, b);
        }
        (lo, hi)
    };
    let ((lo, hi), (ilo, ihi)) = (bounds(reach), bounds(inner));
    // [`wide_spans4`]'s bounds.
    let half = splat(0.5);
    let (below, above) = (splat(-1.0), splat(w + 1.0));
    let clamp = |x: __m256| min(max(x, below), above);
    let floor = |x: __m256| {
        let t = _mm256_cvtepi32_ps(_mm256_cvttps_epi32(x));
        sub(t, _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(t, x), one))
    };
    let wl = splat(w);
    let fit = |p: __m256| {
        let p = _mm256_cvttps_epi32(min(max(p, zero), wl));
        // SAFETY: eight `i32` lanes as eight `u32`s: the same size, every bit pattern
        // a value (the lanes are in [0, w]).
        #[allow(unsafe_code)]
        unsafe {
            std::mem::transmute::<__m256i, [u32; 8]>(p)
        }
    };
    // ceil(x) is −floor(−x).
    [
        fit(neg(floor(neg(clamp(sub(lo, half)))))),
        fit(add(floor(clamp(sub(hi, half))), one)),
        fit(neg(floor(neg(clamp(sub(ilo, half)))))),
        fit(add(floor(clamp(sub(ihi, half))), one)),
    ]
}

/// Gathers segment `s`'s coverage of the row whose centre is at `cy` into `row`
/// (maximum), and gives the pixel span it reached: pixels within `r − ½` of the segment
/// are covered whole, only those on its edges are measured (four at a time).
#[inline(always)]
fn seg_row(s: &Seg, cy: f32, r: f32, reach: f32, row: &mut [u8]) -> Option<(u32, u32)> {
    let [outer, inner] = intervals(s, cy, reach, r - 0.5);
    let (a, b) = outer?;
    let w = row.len() as f32;
    // Pixel i's centre is i + ½.
    let x0 = ceil(a - 0.5).clamp(0.0, w) as usize;
    let x1 = (floor(b - 0.5) + 1.0).clamp(0.0, w) as usize;
    if x0 >= x1 {
        return None;
    }
    let (mut i0, mut i1) = (x1, x1);
    if let Some((a, b)) = inner.filter(|_| r > 0.5) {
        i0 = (ceil(a - 0.5).clamp(0.0, w) as usize).clamp(x0, x1);
        i1 = ((floor(b - 0.5) + 1.0).clamp(0.0, w) as usize).clamp(i0, x1);
        row[i0..i1].fill(255);
    }
    // Edges of a pixel or a few, in lanes (the spans they give are within [x0, x1)).
    let edge = Edge::new(s, cy, r);
    edge.measure::<false>(row, x0, i0);
    edge.measure::<false>(row, i1, x1);
    Some((x0 as u32, x1 as u32))
}

/// [`seg_row`] in [`Mode::Wide`], its first half: fills the pixels within `r − ½` of
/// segment `k` (`s`) and leaves its edges to measure in `edges`, once every segment of
/// the row has filled its interior ([`measure_edges`]). The bytes are [`seg_row`]'s: a
/// row's pixel is the maximum of the segments' coverage, which does not depend on their
/// order, and 255 (filled) is the most.
/// Its spans are [`wide_spans4`]'s of the row, `[x0, x1, j0, j1]`.
#[inline]
fn seg_row_fill(
    k: u32,
    [x0, x1, j0, j1]: [usize; 4],
    row: &mut [u8],
    edges: &mut Vec<(u32, u32, u32)>,
) -> Option<(u32, u32)> {
    if x0 >= x1 {
        return None;
    }
    let i0 = j0.clamp(x0, x1);
    let i1 = j1.clamp(i0, x1);
    if i0 < i1 {
        fill_255(&mut row[i0..i1]);
    }
    for (from, to) in [(x0, i0), (i1, x1)] {
        if from < to {
            edges.push((k, from as u32, to as u32));
        }
    }
    Some((x0 as u32, x1 as u32))
}

/// `span.fill(255)` without a call for a span of up to 32 pixels (a wide segment's
/// interior on a row, most often a few pixels): two stores of a fixed size that may
/// overlap, or each pixel of one of three or fewer.
#[inline(always)]
fn fill_255(span: &mut [u8]) {
    let n = span.len();
    match n {
        0 => {}
        1..=3 => {
            // Pixels 0, n / 2 and n − 1: every pixel of a span of one to three.
            span[0] = 255;
            span[n / 2] = 255;
            span[n - 1] = 255;
        }
        4..=7 => {
            span[..4].copy_from_slice(&[255; 4]);
            span[n - 4..].copy_from_slice(&[255; 4]);
        }
        8..=16 => {
            span[..8].copy_from_slice(&[255; 8]);
            span[n - 8..].copy_from_slice(&[255; 8]);
        }
        17..=32 => {
            span[..16].copy_from_slice(&[255; 16]);
            span[n - 16..].copy_from_slice(&[255; 16]);
        }
        _ => span.fill(255),
    }
}

/// Two pixel spans at once, as [`seg_row`] makes them from intervals `[a, b]` and
/// `[c, e]` (`v = [a, b, c, e]`, `o` what is taken off each bound first, ½ for the pixels
/// whose centre lies in the interval): `[ceil(a − o₀), floor(b − o₁) + 1]` and the same
/// for `[c, e]`, each bound clamped to `[0, w]`, in lanes. The same values: `ceil(x)` is
/// `−floor(−x)` exactly, and [`floor`]'s `x as i32 as f32` is the lanes' truncation and
/// conversion back, both exact below 2^23 (beyond, or for NaN, [`floor`] and [`ceil`]
/// one by one).
#[inline(always)]
fn pixel_spans(v: [f32; 4], o: [f32; 4], w: f32) -> [usize; 4] {
    let x = f32x4::new(v) - f32x4::new(o);
    let x = x ^ f32x4::new([-0.0, 0.0, -0.0, 0.0]);
    if x.abs().simd_lt(f32x4::splat(8_388_608.0)).to_bitmask() == 0b1111 {
        // Finite and below 2^23: the plain truncation is `trunc_int`'s (which differs
        // only for NaN and beyond 2^31).
        let t = x.fast_trunc_int().round_float();
        let fl = t - (t.simd_gt(x) & f32x4::ONE);
        let p = (fl ^ f32x4::new([-0.0, 0.0, -0.0, 0.0])) + f32x4::new([0.0, 1.0, 0.0, 1.0]);
        // Whole numbers, not NaN: `clamp` is max then min; then within [0, w].
        let p = p.fast_max(f32x4::ZERO).fast_min(f32x4::splat(w));
        p.fast_trunc_int().to_array().map(|p| p as usize)
    } else {
        [
            ceil(v[0] - o[0]),
            floor(v[1] - o[1]) + 1.0,
            ceil(v[2] - o[2]),
            floor(v[3] - o[3]) + 1.0,
        ]
        .map(|p| p.clamp(0.0, w) as usize)
    }
}

/// [`seg_row`] in [`Mode::Wide`], its second half: measures the edges the segments left
/// ([`seg_row_fill`]) but their ends that lie in pixels already covered whole (255, by
/// any segment's interior: the maximum is 255 whatever the edge's coverage there).
#[inline(always)]
fn measure_edges<const X8: bool>(
    segs: &[Seg],
    edges: &[(u32, u32, u32)],
    cy: f32,
    r: f32,
    row: &mut [u8],
) {
    for &(k, from, to) in edges {
        let (mut from, mut to) = (from as usize, to as usize);
        while from < to && row[from] == 255 {
            from += 1;
        }
        while from < to && row[to - 1] == 255 {
            to -= 1;
        }
        if from < to {
            Edge::new(&segs[k as usize], cy, r).measure_finite::<X8>(row, from, to);
        }
    }
}

/// [`seg_row`] in [`Mode::Lanes`]: every pixel of a conservative span measured, four at
/// a time; gives the span of the pixels it inked (the others it left as they were). A
/// stroke makes the spans four rows at a time ([`lanes_spans4`]); this row by row way is
/// the tests' reference.
#[cfg(test)]
fn seg_row_lanes(s: &Seg, cy: f32, r: f32, reach: f32, row: &mut [u8]) -> Option<(u32, u32)> {
    let (x0, x1) = lanes_span(s, cy, reach, row.len() as f32)?;
    if x0 >= x1 {
        return None;
    }
    Edge::new(s, cy, r).measure::<true>(row, x0, x1)
}

/// The conservative span `[x0, x1)` of segment `s` on the row of centre `cy` and `w`
/// pixels in [`Mode::Lanes`]: the pixels whose centre i + ½ lies within [lo − ⅛, hi + ⅛]
/// of its reach (none when the segment does not reach the row; empty when `x0 ≥ x1`).
fn lanes_span(s: &Seg, cy: f32, reach: f32, w: f32) -> Option<(usize, usize)> {
    let (lo, hi) = s.reach_x(cy, reach)?;
    let [x0, x1, _, _] = pixel_spans([lo, hi, lo, hi], [0.625, 0.375, 0.625, 0.375], w);
    Some((x0, x1))
}

/// The conservative spans of [`seg_row_lanes`] of segment `s` ([`Mode::Lanes`], within
/// [`MODEST`] coordinates) on four rows at once (centres `cy`), a row a lane, on a row
/// of `w` pixels: `[x0, x1]`, none when `x0 ≥ x1`. Per lane the f32 operations of
/// [`Seg::reach_x`] and [`pixel_spans`] in their order (IEEE operations, the same bits),
/// `min` and `max` without their NaN cases (every value is finite) and a row the segment
/// does not reach (`t0 > t1`) an empty span. Values may differ from those of the row
/// by row operations in the sign of a zero only (`t0`, `t1`), which the spans do not
/// tell apart: `ax + t·dx` is `ax` or a nonzero sum either way, or a zero that the
/// span's `− reach` turns into `−reach`. Every bound lies within `8192 + 4` pixels of 0
/// (the segment's coordinates are below [`MODEST`], its reach below 4), so below 2^23
/// for the lanes' floor; rows of 2^22 pixels or more are made one row at a time.
#[inline(always)]
fn lanes_spans4(s: &Seg, cy: [f32; 4], reach: f32, w: f32) -> [[u32; 4]; 2] {
    if w >= 4_194_304.0 {
        let mut out = [[0; 4]; 2];
        for (m, &cy) in cy.iter().enumerate() {
            if let Some((x0, x1)) = lanes_span(s, cy, reach, w) {
                (out[0][m], out[1][m]) = (x0 as u32, x1 as u32);
            }
        }
        return out;
    }
    let (zero, one) = (f32x4::ZERO, f32x4::ONE);
    let (t0, t1) = if s.rdy != 0.0 {
        let (cy, ay, rdy) = (f32x4::new(cy), f32x4::splat(s.a[1]), f32x4::splat(s.rdy));
        let reach = f32x4::splat(reach);
        let u0 = (cy - reach - ay) * rdy;
        let u1 = (cy + reach - ay) * rdy;
        (
            u0.fast_min(u1).fast_max(zero),
            u0.fast_max(u1).fast_min(one),
        )
    } else {
        (zero, one)
    };
    let (ax, dx) = (f32x4::splat(s.a[0]), f32x4::splat(s.d[0]));
    let (xa, xb) = (ax + t0 * dx, ax + t1 * dx);
    let reach = f32x4::splat(reach);
    let (lo, hi) = (xa.fast_min(xb) - reach, xa.fast_max(xb) + reach);
    let floor = |x: f32x4| {
        let t = x.fast_trunc_int().round_float();
        t - (t.simd_gt(x) & one)
    };
    let wl = f32x4::splat(w);
    let fit = |p: f32x4| p.fast_max(zero).fast_min(wl).fast_trunc_int();
    // ceil(x) is −floor(−x); the pixels whose centre lies within [lo − ⅛, hi + ⅛].
    let x0 = fit(-floor(-(lo - f32x4::splat(0.625))));
    let x1 = fit(floor(hi - f32x4::splat(0.375)) + one);
    // A row out of reach: no span.
    let out = t0.simd_gt(t1).to_bitmask();
    let (x0, x1) = (x0.to_array(), x1.to_array());
    let mut spans = [[0; 4]; 2];
    for m in 0..4 {
        if out & (1 << m) == 0 {
            (spans[0][m], spans[1][m]) = (x0[m] as u32, x1[m] as u32);
        }
    }
    spans
}

/// [`lanes_spans4`] on eight rows at once, in AVX's 256-bit lanes (rows of fewer than
/// 2^22 pixels): per lane the same f32 operations in their order, with the operands
/// of `wide`'s `fast_min`, `fast_max`, negation (the sign bit flipped) and truncations
/// (`vcvttps2dq`): the same bits, so the same spans.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn lanes_spans8(s: &Seg, cy: [f32; 8], reach: f32, w: f32) -> [[u32; 8]; 2] {
    use std::arch::x86_64::*;
    let splat = _mm256_set1_ps;
    let (add, sub, mul) = (_mm256_add_ps, _mm256_sub_ps, _mm256_mul_ps);
    let (max, min) = (_mm256_max_ps, _mm256_min_ps);
    let neg = |x: __m256| _mm256_xor_ps(x, splat(-0.0));
    let (zero, one) = (_mm256_setzero_ps(), splat(1.0));
    let (t0, t1) = if s.rdy != 0.0 {
        let cy = _mm256_setr_ps(cy[0], cy[1], cy[2], cy[3], cy[4], cy[5], cy[6], cy[7]);
        let (ay, rdy, reach) = (splat(s.a[1]), splat(s.rdy), splat(reach));
        let u0 = mul(sub(sub(cy, reach), ay), rdy);
        let u1 = mul(sub(add(cy, reach), ay), rdy);
        (max(min(u0, u1), zero), min(max(u0, u1), one))
    } else {
        (zero, one)
    };
    let (ax, dx) = (splat(s.a[0]), splat(s.d[0]));
    let (xa, xb) = (add(ax, mul(t0, dx)), add(ax, mul(t1, dx)));
    let reach = splat(reach);
    let (lo, hi) = (sub(min(xa, xb), reach), add(max(xa, xb), reach));
    let floor = |x: __m256| {
        let t = _mm256_cvtepi32_ps(_mm256_cvttps_epi32(x));
        sub(t, _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(t, x), one))
    };
    let wl = splat(w);
    let fit = |p: __m256| _mm256_cvttps_epi32(min(max(p, zero), wl));
    // ceil(x) is −floor(−x); the pixels whose centre lies within [lo − ⅛, hi + ⅛].
    let x0 = fit(neg(floor(neg(sub(lo, splat(0.625))))));
    let x1 = fit(add(floor(sub(hi, splat(0.375))), one));
    // A row out of reach (`t0 > t1`): no span (both bounds 0).
    let out = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GT_OQ>(t0, t1));
    let (x0, x1) = (_mm256_andnot_si256(out, x0), _mm256_andnot_si256(out, x1));
    // SAFETY: eight `i32` lanes as eight `u32`s: the same size, every bit pattern a
    // value (the lanes are in [0, w]).
    #[allow(unsafe_code)]
    unsafe {
        [
            std::mem::transmute::<__m256i, [u32; 8]>(x0),
            std::mem::transmute::<__m256i, [u32; 8]>(x1),
        ]
    }
}

/// Measures a segment's coverage of a row's pixels, four at a time: per lane the f32
/// operations of `Edge::pixel` (the tests' reference) in its order (IEEE operations,
/// the same bits; `min`, `max` and `clamp` as `f32`'s, NaN included), so the bytes are
/// the pixel by pixel ones.
struct Edge {
    ax: f32,
    py: f32,
    dx: f32,
    dy: f32,
    inv: f32,
    r: f32,
}

/// `x.clamp(0.0, 1.0)` in lanes, NaN kept as `f32::clamp` keeps it.
#[inline(always)]
fn clamp01(x: f32x4) -> f32x4 {
    let c = x.fast_max(f32x4::ZERO).fast_min(f32x4::ONE);
    x.is_nan().bitselect(x, c)
}

impl Edge {
    #[inline(always)]
    fn new(s: &Seg, cy: f32, r: f32) -> Edge {
        Edge {
            ax: s.a[0] - 0.5,
            py: cy - s.a[1],
            dx: s.d[0],
            dy: s.d[1],
            inv: s.inv,
            r,
        }
    }

    /// Pixel `i`'s coverage (the reference the lanes follow, in the tests).
    #[cfg(test)]
    fn pixel(&self, i: usize) -> u8 {
        let (dx, dy, py) = (self.dx, self.dy, self.py);
        let qx = i as f32 - self.ax;
        let t = ((qx * dx + py * dy) * self.inv).clamp(0.0, 1.0);
        let (ex, ey) = (qx - t * dx, py - t * dy);
        let d = (ex * ex + ey * ey).sqrt();
        coverage(d, self.r)
    }

    /// Pixels `[from, to)` of `row` ← the maximum of theirs and the segment's coverage;
    /// gives the span of the pixels the segment covers (not 0).
    ///
    /// `FINITE` for a segment within [`MODEST`] coordinates ([`Mode::Lanes`] and
    /// [`Mode::Wide`]): every value is then finite (below 2^24 · 2^15 before the clamps),
    /// no lane is NaN, and `min`, `max`, the clamps and the conversion to an integer are
    /// made without their NaN cases, the same values. Else (coordinates of any size,
    /// whose products may be infinite and NaN) as `f32`'s, NaN included.
    #[inline(always)]
    fn measure<const FINITE: bool>(
        &self,
        row: &mut [u8],
        from: usize,
        to: usize,
    ) -> Option<(u32, u32)> {
        if from >= to {
            return None;
        }
        let dx = f32x4::splat(self.dx);
        let dy = f32x4::splat(self.dy);
        let py = f32x4::splat(self.py);
        let pdy = f32x4::splat(self.py * self.dy);
        let inv = f32x4::splat(self.inv);
        let ax = f32x4::splat(self.ax);
        let r = f32x4::splat(self.r);
        let half = f32x4::splat(0.5);
        // Four pixels' levels (`c·255 + ½`) and their `as u8` as i32s, from their
        // centres less ax.
        let levels = |qx: f32x4| {
            if FINITE {
                let t = ((qx * dx + pdy) * inv)
                    .fast_max(f32x4::ZERO)
                    .fast_min(f32x4::ONE);
                let (ex, ey) = (qx - t * dx, py - t * dy);
                let d = (ex * ex + ey * ey).sqrt();
                let c = ((d + half).fast_min(r) - (d - half).fast_max(-r))
                    .fast_max(f32x4::ZERO)
                    .fast_min(f32x4::ONE);
                let level = c * f32x4::splat(255.0) + half;
                // c·255 + ½ in [½, 255.5]: its `as u8`.
                (level, level.fast_trunc_int().to_array())
            } else {
                let t = clamp01((qx * dx + pdy) * inv);
                let (ex, ey) = (qx - t * dx, py - t * dy);
                let d = (ex * ex + ey * ey).sqrt();
                let c = clamp01((d + half).min(r) - (d - half).max(-r));
                let level = c * f32x4::splat(255.0) + half;
                // `as u8` of c·255 + ½ in [½, 255.5], or 0 for NaN (trunc_int's 0).
                (level, level.trunc_int().to_array())
            }
        };
        // Pixel centres less ax: from + k (k < 4) to begin with, four more each time;
        // below 2^24 (a row's width) exact, as `(i + k) as f32`.
        let mut x = f32x4::splat(from as f32) + f32x4::new([0.0, 1.0, 2.0, 3.0]);
        let four = f32x4::splat(4.0);
        let span = &mut row[from..to];
        let whole = span.len() - span.len() % 4;
        let (body, tail) = span.split_at_mut(whole);
        let mut inked_span = InkedSpan::<4>::new(from);
        for (q, px4) in body.chunks_exact_mut(4).enumerate() {
            let (level, v) = levels(x - ax);
            x += four;
            if FINITE {
                // The four levels (each in 0..=255: the saturating packs keep them) as
                // bytes, their maxima with the row's in byte lanes.
                let b = i32x8::new([v[0], v[1], v[2], v[3], 0, 0, 0, 0]);
                let b = u8x16::narrow_i16x8(i16x8::from_i32x8_saturate(b), i16x8::ZERO);
                let mut p = [0u8; 16];
                p[..4].copy_from_slice(px4);
                px4.copy_from_slice(&u8x16::new(p).max(b).to_array()[..4]);
            } else {
                for (px, &v) in px4.iter_mut().zip(&v) {
                    *px = (*px).max(v as u8);
                }
            }
            // The lanes of level 1 or more.
            let inked = level.simd_ge(f32x4::ONE).to_bitmask();
            inked_span.note(q, inked);
        }
        if !tail.is_empty() {
            let (level, v) = levels(x - ax);
            for (px, &v) in tail.iter_mut().zip(&v) {
                *px = (*px).max(v as u8);
            }
            let inked = level.simd_ge(f32x4::ONE).to_bitmask() & ((1 << tail.len()) - 1);
            inked_span.note(whole / 4, inked);
        }
        inked_span.span()
    }

    /// [`Edge::measure`] of a segment within [`MODEST`] coordinates (`FINITE`): eight
    /// pixels at a time with `X8` (called so only where the processor has AVX2, from
    /// [`Capsules::stroke_fast`]), else four.
    #[inline(always)]
    fn measure_finite<const X8: bool>(
        &self,
        row: &mut [u8],
        from: usize,
        to: usize,
    ) -> Option<(u32, u32)> {
        #[cfg(target_arch = "x86_64")]
        if X8 {
            // SAFETY: `measure_x8` needs AVX2; `X8` is true only in the stroke's twin
            // compiled for AVX2, BMI1 and BMI2, which runs only where the processor was
            // found to have them (`Capsules::stroke`).
            #[allow(unsafe_code)]
            return unsafe { self.measure_x8(row, from, to) };
        }
        self.measure::<true>(row, from, to)
    }

    /// [`Edge::measure`]`::<true>` eight pixels at a time in AVX's 256-bit lanes: per
    /// lane the same f32 operations in the same order (`vmaxps`/`vminps` with the
    /// operands of `fast_max`/`fast_min`, `vsqrtps`, the truncation `vcvttps2dq`; no
    /// fused multiply-add), so the same levels bit for bit, and the same span. The
    /// levels (0..=255) are packed to bytes and their maxima with the row's taken eight
    /// at a time.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn measure_x8(&self, row: &mut [u8], from: usize, to: usize) -> Option<(u32, u32)> {
        use std::arch::x86_64::*;
        if from >= to {
            return None;
        }
        let dx = _mm256_set1_ps(self.dx);
        let dy = _mm256_set1_ps(self.dy);
        let py = _mm256_set1_ps(self.py);
        let pdy = _mm256_set1_ps(self.py * self.dy);
        let inv = _mm256_set1_ps(self.inv);
        let ax = _mm256_set1_ps(self.ax);
        let r = _mm256_set1_ps(self.r);
        let neg_r = _mm256_set1_ps(-self.r);
        let half = _mm256_set1_ps(0.5);
        let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
        let full = _mm256_set1_ps(255.0);
        // Eight pixels' levels (`c·255 + ½`, in [½, 255.5]) from their centres less
        // ax, and the levels' `as u8` as eight bytes of a word (first pixel lowest).
        let levels = |qx: __m256| {
            let t = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(qx, dx), pdy), inv);
            let t = _mm256_min_ps(_mm256_max_ps(t, zero), one);
            let ex = _mm256_sub_ps(qx, _mm256_mul_ps(t, dx));
            let ey = _mm256_sub_ps(py, _mm256_mul_ps(t, dy));
            let d = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(ex, ex), _mm256_mul_ps(ey, ey)));
            let c = _mm256_sub_ps(
                _mm256_min_ps(_mm256_add_ps(d, half), r),
                _mm256_max_ps(_mm256_sub_ps(d, half), neg_r),
            );
            let c = _mm256_min_ps(_mm256_max_ps(c, zero), one);
            let level = _mm256_add_ps(_mm256_mul_ps(c, full), half);
            let v = _mm256_cvttps_epi32(level);
            let w = _mm_packs_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
            let bytes = _mm_cvtsi128_si64(_mm_packus_epi16(w, _mm_setzero_si128())) as u64;
            // The lanes of level 1 or more.
            let inked = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(level, one)) as u32;
            (bytes, inked)
        };
        // The row's bytes `b` ← their maxima with `v`'s, byte by byte.
        let max8 = |b: u64, v: u64| {
            let m = _mm_max_epu8(_mm_cvtsi64_si128(b as i64), _mm_cvtsi64_si128(v as i64));
            _mm_cvtsi128_si64(m) as u64
        };
        // Pixel centres less ax: from + k (k < 8) to begin with, eight more each time;
        // below 2^24 (a row's width) exact, as `(i + k) as f32`.
        let mut x = _mm256_add_ps(
            _mm256_set1_ps(from as f32),
            _mm256_setr_ps(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0),
        );
        let eight = _mm256_set1_ps(8.0);
        let span = &mut row[from..to];
        let whole = span.len() - span.len() % 8;
        let (body, tail) = span.split_at_mut(whole);
        let mut inked_span = InkedSpan::<8>::new(from);
        for (q, px8) in body.chunks_exact_mut(8).enumerate() {
            let (v, inked) = levels(_mm256_sub_ps(x, ax));
            x = _mm256_add_ps(x, eight);
            let px8: &mut [u8; 8] = px8.try_into().expect("8 pixels");
            *px8 = max8(u64::from_le_bytes(*px8), v).to_le_bytes();
            inked_span.note(q, inked);
        }
        if !tail.is_empty() {
            let (v, inked) = levels(_mm256_sub_ps(x, ax));
            for (px, v) in tail.iter_mut().zip(v.to_le_bytes()) {
                *px = (*px).max(v);
            }
            let inked = inked & ((1 << tail.len()) - 1);
            inked_span.note(whole / 8, inked);
        }
        inked_span.span()
    }
}

/// The pixels a measured span inked (level 1 or more), kept group by group of `W`
/// lanes: the first pixel inked, and the last group that inked and its lanes (the
/// span's end made once, at the end).
struct InkedSpan<const W: usize> {
    from: usize,
    first: usize,
    at: usize,
    lanes: u32,
}

impl<const W: usize> InkedSpan<W> {
    #[inline(always)]
    fn new(from: usize) -> Self {
        Self {
            from,
            first: usize::MAX,
            at: 0,
            lanes: 0,
        }
    }

    /// Group `q` (pixels `from + W·q ..`) inked the lanes set in `inked`.
    #[inline(always)]
    fn note(&mut self, q: usize, inked: u32) {
        if inked != 0 {
            if self.first == usize::MAX {
                self.first = self.from + W * q + inked.trailing_zeros() as usize;
            }
            (self.at, self.lanes) = (q, inked);
        }
    }

    /// The first and one past the last pixel inked, `None` if none was.
    #[inline(always)]
    fn span(&self) -> Option<(u32, u32)> {
        let last = self.from + W * self.at + 32 - self.lanes.leading_zeros() as usize;
        (self.first != usize::MAX).then_some((self.first as u32, last as u32))
    }
}

/// Composites coverage `cov` of `ink` over `dst` and clears `cov`: `composite` of
/// `raster.rs` pixel by pixel, black and paper eight pixels at a time in 16-bit lanes
/// (`(255·x + 32512) / 65025` is `(x + 127) / 255` for black, see `composite_row`).
#[inline(always)]
fn composite_span(dst: &mut [u8], cov: &mut [u8], ink: Ink) {
    let n = dst.len().min(cov.len());
    let (dst, cov) = (&mut dst[..n], &mut cov[..n]);
    let lanes = match ink {
        Ink::Black | Ink::Paper => n - n % 8,
        Ink::Gray(_) => 0,
    };
    let paper = ink == Ink::Paper;
    let half = u16x8::splat(127);
    for (d8, c8) in dst[..lanes]
        .chunks_exact_mut(8)
        .zip(cov[..lanes].chunks_exact_mut(8))
    {
        let (d, c) = (widen(d8), widen(c8));
        let v = if paper {
            d - div255(d * c + half)
        } else {
            d + div255((u16x8::splat(255) - d) * c + half)
        };
        narrow(v, d8);
        c8.fill(0);
    }
    composite_pixels(&mut dst[lanes..], &mut cov[lanes..], ink);
}

/// Composites coverage `cov` of `ink` over `dst` and clears `cov`, pixel by pixel (the
/// tail of [`composite_span`], and the tests' reference).
fn composite_pixels(dst: &mut [u8], cov: &mut [u8], ink: Ink) {
    match ink {
        Ink::Paper => {
            for (d, c) in dst.iter_mut().zip(cov.iter_mut()) {
                let (dd, cc) = (u32::from(*d), u32::from(std::mem::take(c)));
                *d = (dd - (dd * cc + 127) / 255) as u8;
            }
        }
        ink => {
            let g = u32::from(ink.level());
            for (d, c) in dst.iter_mut().zip(cov.iter_mut()) {
                let (dd, cc) = (u32::from(*d), u32::from(std::mem::take(c)));
                *d = (dd + ((255 - dd) * cc * g + 32_512) / 65_025) as u8;
            }
        }
    }
    // Coverage past `dst` (none in this crate's calls) is cleared too.
    let n = dst.len().min(cov.len());
    if n < cov.len() {
        cov[n..].fill(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tests' seeded random numbers: xorshift64 (13, 7, 17) from `seed`.
    fn xorshift(mut seed: u64) -> impl FnMut() -> u64 {
        move || {
            seed = crate::xorshift(seed);
            seed
        }
    }

    /// [`xorshift`]'s numbers as f32 in [0, 1), from their top 24 bits.
    fn unit_floats(seed: u64) -> impl FnMut() -> f32 {
        let mut next = xorshift(seed);
        move || (next() >> 40) as f32 / (1u64 << 24) as f32
    }

    fn target<'a>(data: &'a mut [u8], w: usize, dirty: &'a mut Dirty, ink: Ink) -> Target<'a> {
        let h = data.len() / w;
        Target {
            data,
            width: w,
            height: h,
            ink,
            rows: (0, h),
            first: 0,
            dirty,
            layer: None,
        }
    }

    /// The inline floor and ceil give libm's values (a zero's sign aside), everywhere:
    /// around every integer, at 2^23 and beyond, for infinities and NaN.
    #[test]
    fn floor_and_ceil_match_libm() {
        let same = |a: f32, b: f32| a == b || (a.is_nan() && b.is_nan());
        let mut xs = vec![
            0.0,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_608.0,
            8_388_609.0,
            16_777_217.0,
            3e9,
            -3e9,
        ];
        for i in -3000..3000 {
            let x = i as f32 * 0.5;
            xs.extend([x, x.next_up(), x.next_down(), x * 1.37, x * 2731.7]);
        }
        let mut s = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..200_000 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            xs.push(f32::from_bits(s as u32));
        }
        for x in xs {
            assert!(same(floor(x), x.floor()), "floor {x:e}");
            assert!(same(ceil(x), x.ceil()), "ceil {x:e}");
        }
    }

    /// A segment's intervals on four rows made at once are its [`intervals`] row by row
    /// (up to the sign of a zero, which `==` does not tell apart): segments of every
    /// slope and length within [`MODEST`] coordinates, dots, segments exactly along a
    /// row or a column, rows through them, at their ends and beyond their reach. And
    /// their pixel spans made at once ([`wide_spans4`]) are those [`seg_row_fill`] made
    /// of each row's intervals before, on rows of several widths (the segments across
    /// the row's ends, and past 2^22 pixels one row at a time); where the processor has
    /// AVX2, so are those made eight rows at once ([`wide_spans8`]).
    #[test]
    fn four_rows_intervals_are_each_ones() {
        let mut rand = unit_floats(0x9e37_79b9_7f4a_7c15u64);
        let (mut found, mut spanned, mut eights) = ([0; 2], 0, 0);
        for n in 0..60_000 {
            let r = [0.2, 0.5, 1.56, 3.2, 4.1, 10.41, 40.0][n % 7];
            let mut c = Capsules::default();
            for m in 0..4 {
                let a = [
                    -40.0 + (MODEST - 30.0) * rand(),
                    -40.0 + (MODEST - 30.0) * rand(),
                ];
                let len = [0.0, 0.02, 0.7, 3.0, 9.0, 60.0][(n + m) % 6];
                let ang = rand() * std::f32::consts::TAU;
                let mut b = [a[0] + len * ang.cos(), a[1] + len * ang.sin()];
                match (n / 7 + m) % 5 {
                    0 => b[0] = a[0],
                    1 => b[1] = a[1],
                    _ => {}
                }
                c.push(a, b);
            }
            let base = c.segs[(n / 3) % 4];
            let cy = if n % 3 == 0 {
                base.a[1] + base.d[1]
            } else {
                (base.a[1] + (rand() - 0.5) * 3.0 * (r + 1.0)).floor() + 0.5
            };
            let (reach, inner) = (r + 0.5, r - 0.5);
            // Each segment on four rows from there, a row a lane (the last ones mostly
            // beyond the reach of short segments).
            let cy4 = [0.0, 1.0, 2.0, 3.0].map(|m| cy + m);
            for s in &c.segs {
                let got = intervals4(s, cy4, reach, inner);
                // Rows of several widths: the segments' spans across the edges too.
                let w = [7.0, 300.0, 2500.0, 8100.0, 5_000_000.0][n % 5];
                let spans = wide_spans4(s, cy4, reach, inner, w);
                #[cfg(target_arch = "x86_64")]
                if crate::cpu::x86_fast() && w < 4_194_304.0 {
                    // Eight rows at once (the stroke's AVX2 twin): the four rows' and the
                    // next four's spans.
                    let cy8 = [0, 1, 2, 3, 4, 5, 6, 7].map(|m| cy + m as f32);
                    #[allow(unsafe_code)]
                    // SAFETY: the processor has AVX2 (`x86_fast`).
                    let eight = unsafe { wide_spans8(s, cy8, reach, inner, w) };
                    let next =
                        wide_spans4(s, [4.0, 5.0, 6.0, 7.0].map(|m| cy + m), reach, inner, w);
                    for b in 0..4 {
                        assert_eq!(eight[b][..4], spans[b], "{s:?} cy {cy} r {r} w {w}");
                        assert_eq!(eight[b][4..], next[b], "{s:?} cy {cy} r {r} w {w}");
                    }
                    eights += 1;
                }
                for (m, (got, cy)) in got.iter().zip(cy4).enumerate() {
                    let want = intervals(s, cy, reach, inner);
                    assert!(*got == want, "{s:?} cy {cy} r {r}: {got:?} {want:?}");
                    for (f, w) in found.iter_mut().zip(want) {
                        *f += usize::from(w.is_some());
                    }
                    if r > 0.5 {
                        let got = row_spans(spans.map(|v| v[m] as usize));
                        let want = row_spans_reference(want, w);
                        assert_eq!(got, want, "{s:?} cy {cy} r {r} w {w}");
                        spanned +=
                            usize::from(want.is_some_and(|[x0, _, i0, i1]| x0 < i0 && i0 < i1));
                    }
                }
            }
        }
        assert!(found.iter().all(|&f| f > 80_000), "{found:?}");
        assert!(spanned > 10_000, "{spanned}");
        assert!(!crate::cpu::x86_fast() || eights == 192_000, "{eights}");
    }

    /// A thin segment's conservative spans made four rows at a time ([`lanes_spans4`])
    /// are those [`seg_row_lanes`] makes row by row ([`Seg::reach_x`] and
    /// [`pixel_spans`], none where the segment does not reach the row): segments of every
    /// slope and length, dots, along a row or a column and nearly, across the page's
    /// edges and at the ends of [`MODEST`] coordinates, on rows through them, at their
    /// ends and beyond their reach, rows of several widths (past 2^22 pixels one row at
    /// a time). Where the processor has AVX2, so are those made eight rows at once
    /// ([`lanes_spans8`]).
    #[test]
    fn four_rows_lane_spans_are_each_ones() {
        let mut rand = unit_floats(0x1319_8a2e_0370_7344u64);
        let (mut spanned, mut empty, mut eights) = (0, 0, 0);
        for n in 0..200_000 {
            let r = [0.2, 0.5, 0.8, 1.04, 1.56, 2.6, 3.0][n % 7];
            let a = match n % 13 {
                0 => [-3.0 - 5.0 * rand(), 8191.0 * rand()],
                1 => [MODEST - 0.01 - 3.0 * rand(), -8191.0 + 16_382.0 * rand()],
                _ => [
                    -40.0 + (MODEST - 30.0) * rand(),
                    -40.0 + (MODEST - 30.0) * rand(),
                ],
            };
            let len = [0.0, 0.02, 0.7, 3.0, 9.0, 60.0][n % 6];
            let ang = match n % 5 {
                0 => {
                    [0.0, 0.5, 1e-7, 0.499_999_9, 3.0e-7, 1.0][(rand() * 6.0) as usize % 6]
                        * std::f32::consts::PI
                }
                _ => rand() * std::f32::consts::TAU,
            };
            let mut b = [a[0] + len * ang.cos(), a[1] + len * ang.sin()];
            if n % 11 == 0 {
                b[0] = a[0];
            }
            let mut c = Capsules::default();
            c.push(a, b);
            let mut s = c.segs[0];
            s.prepare(r);
            if s.mode != Mode::Lanes {
                continue;
            }
            let reach = r + 0.5;
            let y = if n % 3 == 0 { s.a[1] + s.d[1] } else { s.a[1] };
            let cy = (y + (rand() - 0.5) * 4.0 * (r + 2.0)).floor() + 0.5;
            let cy4 = [0.0, 1.0, 2.0, 3.0].map(|m| cy + m);
            let w = [7.0, 300.0, 2500.0, 8100.0, 8192.0, 5_000_000.0][n % 6];
            let got = lanes_spans4(&s, cy4, reach, w);
            #[cfg(target_arch = "x86_64")]
            if crate::cpu::x86_fast() && w < 4_194_304.0 {
                // Eight rows at once (the stroke's AVX2 twin): the four rows' spans and
                // the next four's.
                let cy8 = [0, 1, 2, 3, 4, 5, 6, 7].map(|m| cy + m as f32);
                #[allow(unsafe_code)]
                // SAFETY: the processor has AVX2 (`x86_fast`).
                let eight = unsafe { lanes_spans8(&s, cy8, reach, w) };
                let next = lanes_spans4(&s, [4.0, 5.0, 6.0, 7.0].map(|m| cy + m), reach, w);
                for b in 0..2 {
                    assert_eq!(eight[b][..4], got[b], "{s:?} cy {cy} r {r} w {w}");
                    assert_eq!(eight[b][4..], next[b], "{s:?} cy {cy} r {r} w {w}");
                }
                eights += 1;
            }
            for (m, &cy) in cy4.iter().enumerate() {
                let want = lanes_span(&s, cy, reach, w);
                let (x0, x1) = (got[0][m] as usize, got[1][m] as usize);
                // Both the same span, or both none.
                let g = (x0 < x1).then_some((x0, x1));
                let want = want.filter(|(x0, x1)| x0 < x1);
                assert_eq!(g, want, "{s:?} cy {cy} r {r} w {w}");
                spanned += usize::from(want.is_some());
                empty += usize::from(want.is_none());
            }
        }
        assert!(spanned > 150_000 && empty > 150_000, "{spanned} {empty}");
        assert!(!crate::cpu::x86_fast() || eights > 100_000, "{eights}");
    }

    /// A row's reach and interior as [`seg_row_fill`] takes them from
    /// [`wide_spans4`]'s spans: `[x0, x1, i0, i1]`, or `None`.
    fn row_spans([x0, x1, j0, j1]: [usize; 4]) -> Option<[usize; 4]> {
        let i0 = j0.clamp(x0, x1.max(x0));
        (x0 < x1).then(|| [x0, x1, i0, j1.clamp(i0, x1)])
    }

    /// [`row_spans`] as [`seg_row_fill`] made them of a row's intervals before the
    /// spans were made four rows at a time (`r > ½`).
    fn row_spans_reference([outer, inner]: Intervals, w: f32) -> Option<[usize; 4]> {
        let (a, b) = outer?;
        let (ia, ib) = inner.unwrap_or((a, b));
        let [x0, x1, j0, j1] = pixel_spans([a, b, ia, ib], [0.5; 4], w);
        if x0 >= x1 {
            return None;
        }
        let (mut i0, mut i1) = (x1, x1);
        if inner.is_some() {
            i0 = j0.clamp(x0, x1);
            i1 = j1.clamp(i0, x1);
        }
        Some([x0, x1, i0, i1])
    }

    /// Pixel spans made in lanes are those made one bound at a time with [`ceil`],
    /// [`floor`] and `clamp`: around every half pixel, at the page's edges and far
    /// beyond, past 2^23, for infinities and NaN.
    #[test]
    fn pixel_spans_match_one_by_one() {
        let mut rand = xorshift(0x2545_f491_4f6c_dd1du64);
        let special = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            0.625,
            0.375,
            8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            3e9,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for n in 0..400_000 {
            let pick = |k: u64| -> f32 {
                match k % 4 {
                    0 => special[(k >> 8) as usize % special.len()],
                    1 => f32::from_bits((k >> 16) as u32),
                    // Near a half pixel, on and off a page 3300 px wide.
                    _ => {
                        let x = ((k >> 8) % 8000) as f32 * 0.5 - 400.0;
                        [
                            x,
                            x.next_up(),
                            x.next_down(),
                            x + (k >> 40) as f32 / 65536.0,
                        ][(k >> 4) as usize % 4]
                    }
                }
            };
            let v = [pick(rand()), pick(rand()), pick(rand()), pick(rand())];
            let o = if n % 2 == 0 {
                [0.5; 4]
            } else {
                [0.625, 0.375, 0.625, 0.375]
            };
            let w = [0.0, 1.0, 3300.0, 8192.0][n % 4];
            let want = [
                ceil(v[0] - o[0]),
                floor(v[1] - o[1]) + 1.0,
                ceil(v[2] - o[2]),
                floor(v[3] - o[3]) + 1.0,
            ]
            .map(|p| p.clamp(0.0, w) as usize);
            assert_eq!(pixel_spans(v, o, w), want, "{v:?} {o:?} {w}");
        }
    }

    /// A segment within [`MODEST`] coordinates measured in its finite lanes (four
    /// bytes' maxima at once) is byte for byte measured in the NaN-exact lanes (byte
    /// after byte), with the same span: segments of every slope and length, dots, thin
    /// and wide, rows through them and beside them, over blank rows, rows of every
    /// level and rows covered whole, every span length and position, at the row's ends.
    /// Where the processor has AVX2, so are the eight-lane measures of the stroke's
    /// twin ([`Edge::measure_x8`]).
    #[test]
    fn finite_measures_are_the_nan_exact_ones() {
        let mut rand = unit_floats(0x243f_6a88_85a3_08d3u64);
        let w = 8192;
        let unders: [Vec<u8>; 3] = [
            vec![0; w],
            (0..w).map(|i| ((i * 37) % 256) as u8).collect(),
            vec![255; w],
        ];
        let (mut inked, mut eights) = (0, 0);
        for n in 0..30_000 {
            let len = [0.0, 0.02, 0.7, 3.0, 9.0, 60.0][n % 6];
            let a = [
                -40.0 + (MODEST - 30.0) * rand(),
                -40.0 + (MODEST - 30.0) * rand(),
            ];
            let ang = rand() * std::f32::consts::TAU;
            let b = [a[0] + len * ang.cos(), a[1] + len * ang.sin()];
            let r = [0.2, 0.5, 1.56, 2.6, 3.0, 10.41][(rand() * 6.0) as usize % 6];
            let mut c = Capsules::default();
            c.push(a, b);
            let e = Edge::new(
                &c.segs[0],
                (a[1] + (rand() - 0.5) * 3.0 * (r + 1.0)).floor() + 0.5,
                r,
            );
            let from = if n % 5 == 0 {
                0
            } else {
                ((a[0] - 2.0 * r - 4.0 + 4.0 * rand()).max(0.0) as usize).min(w)
            };
            let to = if n % 7 == 0 {
                w
            } else {
                (from + (rand() * (4.0 * r + 20.0)) as usize).min(w)
            };
            for under in &unders {
                let (mut got, mut want) = (under.clone(), under.clone());
                let gs = e.measure::<true>(&mut got, from, to);
                let ws = e.measure::<false>(&mut want, from, to);
                assert!(got == want, "{a:?} {b:?} r {r} [{from}, {to})");
                assert_eq!(gs, ws, "{a:?} {b:?} r {r} [{from}, {to})");
                if crate::cpu::x86_fast() {
                    let mut eight = under.clone();
                    let es = e.measure_finite::<true>(&mut eight, from, to);
                    assert!(
                        eight == want,
                        "eight lanes: {a:?} {b:?} r {r} [{from}, {to})"
                    );
                    assert_eq!(es, ws, "eight lanes: {a:?} {b:?} r {r} [{from}, {to})");
                    eights += 1;
                }
                inked += usize::from(ws.is_some());
            }
        }
        assert!(inked > 20_000, "{inked}");
        assert!(!crate::cpu::x86_fast() || eights == 90_000, "{eights}");
    }

    /// Compositing in lanes is compositing pixel by pixel: every coverage over every
    /// ink under, in black, paper and a gray, spans of every length (tails of 0–7
    /// pixels), and the coverage is cleared; `div255` is `x / 255` for every `x`.
    #[test]
    fn spans_composited_in_lanes_are_composited_pixel_by_pixel() {
        for x in 0..=u16::MAX {
            let got = div255(u16x8::splat(x)).to_array();
            assert!(got.iter().all(|&q| q == x / 255), "{x}");
        }
        for ink in [Ink::Black, Ink::Paper, Ink::Gray(48), Ink::Gray(150)] {
            for d in 0..=255u8 {
                for len in [1, 7, 8, 13, 16, 23, 255] {
                    let under: Vec<u8> = (0..len).map(|i| d.wrapping_add(i as u8)).collect();
                    let cov0: Vec<u8> = (0..len).map(|i| (i * 37 + usize::from(d)) as u8).collect();
                    let (mut got, mut want) = (under.clone(), under.clone());
                    let (mut cg, mut cw) = (cov0.clone(), cov0.clone());
                    composite_span(&mut got, &mut cg, ink);
                    composite_pixels(&mut want, &mut cw, ink);
                    assert_eq!(got, want, "{ink:?} {d} {len}");
                    assert!(cg.iter().all(|&c| c == 0), "cleared");
                }
            }
        }
        // Every coverage over every ink, in one span.
        let under: Vec<u8> = (0..65536).map(|i| (i >> 8) as u8).collect();
        let cov0: Vec<u8> = (0..65536).map(|i| i as u8).collect();
        for ink in [Ink::Black, Ink::Paper] {
            let (mut got, mut want) = (under.clone(), under.clone());
            composite_span(&mut got, &mut cov0.clone(), ink);
            composite_pixels(&mut want, &mut cov0.clone(), ink);
            assert!(got == want, "{ink:?}");
        }
    }

    #[test]
    fn coverage_is_the_overlap_of_pixel_and_stroke() {
        assert_eq!(coverage(0.0, 1.0), 255);
        assert_eq!(coverage(1.0, 1.0), 128);
        assert_eq!(coverage(1.5, 1.0), 0);
        // Thinner than a pixel: its width, wherever the pixel holds it whole.
        assert_eq!(coverage(0.0, 0.25), 128);
        assert_eq!(coverage(0.2, 0.25), 128);
    }

    /// `fill_255` sets every pixel of its span and no other, whatever the span's length
    /// and place in the row (the lengths of each of its ways and past them).
    #[test]
    fn fill_255_fills_its_span_only() {
        for n in 0..=40 {
            for at in 0..4 {
                let mut row: Vec<u8> = (0..50).map(|i| (i * 7 % 251) as u8).collect();
                let mut want = row.clone();
                want[at..at + n].fill(255);
                fill_255(&mut row[at..at + n]);
                assert_eq!(row, want, "{n} pixels from {at}");
            }
        }
    }

    /// A horizontal stroke's ink per column is its width, and a long slanted one's ink
    /// per unit of length too; the union of overlapping segments is inked once.
    #[test]
    fn strokes_keep_their_ink_and_overlaps_are_inked_once() {
        let (w, h) = (200, 100);
        for (a, b) in [([20.0, 50.3], [180.0, 50.3]), ([20.0, 20.0], [180.0, 80.0])] {
            let mut data = vec![0u8; w * h];
            let mut dirty = Dirty::new(w, h);
            let mut c = Capsules::default();
            c.push(a, b);
            // The same segment twice and a piece of it: the same ink as once.
            c.push(a, b);
            c.push(a, [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]);
            c.stroke(1.5, &mut target(&mut data, w, &mut dirty, Ink::Black));
            let ink: f64 = data.iter().map(|&v| f64::from(v) / 255.0).sum();
            let len = ((b[0] - a[0]) as f64).hypot((b[1] - a[1]) as f64);
            let expected = 3.0 * len + std::f64::consts::PI * 1.5 * 1.5;
            assert!((ink / expected - 1.0).abs() < 0.02, "{ink} {expected}");
            // Everything inked is marked.
            for j in 0..h {
                for i in 0..w {
                    if data[j * w + i] != 0 {
                        assert!(dirty.row_pair_spans(j).any(|(x0, x1)| x0 <= i && i < x1));
                    }
                }
            }
            assert!(
                c.slots.iter().all(|s| s.row.iter().all(|&v| v == 0)),
                "row buffer left clean"
            );
        }
    }

    /// A segment too short for its `1 / |d|²` in f32 (a subnormal `|d|²`) is drawn as the
    /// dot at its start, in every mode: no pixel is left out by a NaN of `0 · ∞`.
    #[test]
    fn a_vanishing_segment_is_its_dot() {
        let (w, h) = (40, 40);
        let (a, b) = ([1e-20f32, 2e-20], [2e-20f32, 1e-20]);
        for r in [1.0f32, 2.5, 6.0] {
            let draw = |b: [f32; 2]| {
                let mut data = vec![0u8; w * h];
                let mut dirty = Dirty::new(w, h);
                let mut c = Capsules::default();
                c.push(a, b);
                c.stroke(r, &mut target(&mut data, w, &mut dirty, Ink::Black));
                data
            };
            let (seg, dot) = (draw(b), draw(a));
            assert!(dot[0] > 0, "r = {r}: the dot inks its pixel");
            assert_eq!(seg, dot, "r = {r}");
        }
    }

    /// The row coverage with whole interior spans and measured edges is the coverage of
    /// every pixel measured, for segments of every slope, length and width.
    #[test]
    fn interiors_and_edges_match_measuring_every_pixel() {
        let mut worst = 0;
        let mut rand = unit_floats(0x2545_f491_4f6c_dd1du64);
        for _ in 0..3000 {
            let a = [10.0 + 80.0 * rand(), 10.0 + 80.0 * rand()];
            let len = [0.0, 0.3, 3.0, 40.0][(rand() * 4.0) as usize % 4];
            let ang = rand() * std::f32::consts::TAU;
            let b = [a[0] + len * ang.cos(), a[1] + len * ang.sin()];
            let r = [0.2, 0.5, 0.7, 1.56, 6.7][(rand() * 5.0) as usize % 5];
            let mut c = Capsules::default();
            c.push(a, b);
            let s = c.segs[0];
            for j in 0..100 {
                let cy = j as f32 + 0.5;
                let mut row = vec![0u8; 100];
                let span = seg_row(&s, cy, r, r + 0.5, &mut row);
                for (i, &got) in row.iter().enumerate() {
                    let (qx, qy) = (i as f32 + 0.5 - a[0], cy - a[1]);
                    let t = ((qx * s.d[0] + qy * s.d[1]) * s.inv).clamp(0.0, 1.0);
                    let d = (qx - t * s.d[0]).hypot(qy - t * s.d[1]);
                    let want = coverage(d, r);
                    worst = worst.max(got.abs_diff(want));
                    if got != 0 {
                        let (x0, x1) = span.expect("a span");
                        assert!((x0 as usize..x1 as usize).contains(&i));
                    }
                    assert!(
                        want == 0 || span.is_some(),
                        "{a:?} {b:?} {r} row {j} px {i}"
                    );
                }
            }
        }
        assert!(worst <= 1, "{worst}");
    }

    /// The old row coverage, pixel by pixel: the interior always found by its interval
    /// and filled, every edge pixel measured on its own ([`Edge::pixel`]).
    fn seg_row_reference(s: &Seg, cy: f32, r: f32, row: &mut [u8]) -> Option<(u32, u32)> {
        let (a, b) = interval(s, cy, r + 0.5)?;
        let w = row.len() as f32;
        let x0 = ceil(a - 0.5).clamp(0.0, w) as usize;
        let x1 = (floor(b - 0.5) + 1.0).clamp(0.0, w) as usize;
        if x0 >= x1 {
            return None;
        }
        let (mut i0, mut i1) = (x1, x1);
        if let Some((a, b)) = interval(s, cy, r - 0.5).filter(|_| r > 0.5) {
            i0 = (ceil(a - 0.5).clamp(0.0, w) as usize).clamp(x0, x1);
            i1 = ((floor(b - 0.5) + 1.0).clamp(0.0, w) as usize).clamp(i0, x1);
            row[i0..i1].fill(255);
        }
        let e = Edge::new(s, cy, r);
        for i in (x0..i0).chain(i1..x1) {
            row[i] = row[i].max(e.pixel(i));
        }
        Some((x0 as u32, x1 as u32))
    }

    /// A row made either way ([`Mode`]: measured in lanes over a conservative span, or
    /// with the exact interval, its interior filled, its edges measured in lanes) is byte
    /// for byte the row filled and measured pixel by pixel as it always was: segments of every slope,
    /// length and width anywhere on a page 8192 px wide (where an f32 coordinate's ulp is
    /// 1/2000 px), exactly along a row or a column too, over blank rows and rows already
    /// inked; the span given holds every pixel inked. The exact way's two intervals are
    /// made at once in lanes ([`intervals`]), the reference's one by one ([`interval`]).
    #[test]
    fn rows_made_every_way_are_the_same_bytes() {
        let mut rand = unit_floats(0x9e37_79b9_7f4a_7c15u64);
        let w = 8192;
        let (mut made, mut covered) = ([0u64; 2], 0);
        let unders: [Vec<u8>; 2] = [
            vec![0; w],
            (0..w).map(|i| ((i * 37) % 7 * 40) as u8).collect(),
        ];
        for n in 0..40_000 {
            let len = [0.0, 0.02, 0.7, 3.0, 9.0, 60.0][n % 6];
            let a = [
                -40.0 + (MODEST - 30.0) * rand(),
                -40.0 + (MODEST - 30.0) * rand(),
            ];
            let ang = if n % 7 == 0 {
                // Along a row or a column, and nearly.
                [0.0, 0.5, 1e-4, 0.499_97, 3.0e-6][(rand() * 5.0) as usize % 5]
                    * std::f32::consts::PI
            } else {
                rand() * std::f32::consts::TAU
            };
            let mut b = [a[0] + len * ang.cos(), a[1] + len * ang.sin()];
            if n % 11 == 0 {
                b[0] = a[0]; // exactly along a column (the body's bound along it)
            }
            let r = [0.2, 0.5, 0.52, 0.8, 1.04, 1.56, 2.6, 3.0, 4.1, 6.7, 12.0]
                [(rand() * 11.0) as usize % 11];
            let mut c = Capsules::default();
            c.push(a, b);
            let mut s = c.segs[0];
            s.prepare(r);
            let prepared = s.mode;
            for j in 0..4 {
                let cy = (a[1] + (j as f32 - 1.5) * (r + 1.0)).floor() + 0.5;
                // A row already covered whole about the segment (by a wider stroke's
                // neighbours), and partly.
                let x = (a[0] as i64).clamp(0, w as i64) as usize;
                let mut whole = unders[1].clone();
                whole[x.saturating_sub(40)..(x + 40).min(w)].fill(255);
                let mut part = unders[1].clone();
                part[x.saturating_sub(40)..(x + 3).min(w)].fill(255);
                for under in unders.iter().chain([&whole, &part]) {
                    let mut want = under.clone();
                    let span = seg_row_reference(&s, cy, r, &mut want);
                    for mode in [Mode::Exact, Mode::Lanes, Mode::Wide] {
                        s.mode = mode;
                        let mut got = under.clone();
                        let got_span = match mode {
                            Mode::Lanes => seg_row_lanes(&s, cy, r, r + 0.5, &mut got),
                            Mode::Wide if s.covered(cy, r + 0.5, &got) => {
                                covered += 1;
                                span
                            }
                            Mode::Exact | Mode::Wide => seg_row(&s, cy, r, r + 0.5, &mut got),
                        };
                        assert!(got == want, "{a:?} {b:?} r {r} row {cy} {mode:?}");
                        if mode == Mode::Lanes {
                            let (x0, x1) = got_span.unwrap_or((0, 0));
                            let inked = (0..w).filter(|&i| got[i] != under[i]);
                            assert!(inked.clone().all(|i| x0 as usize <= i && i < x1 as usize));
                            if got_span.is_some() && under[0] == 0 {
                                assert!(got[x0 as usize] != 0 && got[x1 as usize - 1] != 0);
                            }
                        } else {
                            assert_eq!(got_span, span);
                        }
                    }
                    if span.is_some() {
                        made[usize::from(prepared == Mode::Wide)] += 1;
                    }
                    s.mode = prepared;
                }
            }
        }
        assert!(
            made.iter().all(|&m| m > 1000) && covered > 1000,
            "{made:?} {covered}"
        );
    }

    impl Capsules {
        /// [`Capsules::stroke`] as it was, segment after segment, each row's coverage
        /// made whole by each segment in turn (a [`Mode::Wide`] segment skipped where its
        /// span is covered whole already): the reference of the row loop.
        fn stroke_reference(&mut self, r: f32, t: &mut Target) {
            let mut segs = std::mem::take(&mut self.segs);
            let reach = r.max(0.0) + 0.5;
            if !(reach.is_finite() && reach > 0.5) || t.width == 0 || t.height == 0 {
                segs.clear();
                self.segs = segs;
                return;
            }
            let (c0, c1) = clip_rows(t);
            self.order.clear();
            for (k, s) in segs.iter_mut().enumerate() {
                let (y0, y1) = (s.a[1].min(s.a[1] + s.d[1]), s.a[1].max(s.a[1] + s.d[1]));
                let lo = floor(y0 - reach - 0.5).clamp(c0, c1);
                let hi = ceil(y1 + reach + 0.5).clamp(c0, c1);
                if lo.is_nan() || hi.is_nan() || lo >= hi || !(s.a[0] + s.d[0]).is_finite() {
                    continue;
                }
                s.rows = (lo as u32, hi as u32);
                s.prepare(r);
                self.order.push(k as u32);
            }
            self.order
                .sort_unstable_by_key(|&k| segs[k as usize].rows.0);
            self.fit(t.width);
            self.active.clear();
            let mut next = 0;
            let mut j = 0u32;
            while next < self.order.len() || !self.active.is_empty() {
                if self.active.is_empty() {
                    j = j.max(segs[self.order[next] as usize].rows.0);
                }
                while next < self.order.len() && segs[self.order[next] as usize].rows.0 <= j {
                    self.active.push(self.order[next]);
                    next += 1;
                }
                self.spans.clear();
                let cy = j as f32 + 0.5;
                let row = &mut self.slots[0].row;
                for &k in &self.active {
                    let s = &segs[k as usize];
                    let span = match s.mode {
                        Mode::Lanes => seg_row_lanes(s, cy, r, reach, row),
                        Mode::Wide if s.covered(cy, reach, row) => None,
                        Mode::Wide | Mode::Exact => seg_row(s, cy, r, reach, row),
                    };
                    if let Some(span) = span {
                        self.spans.push(span);
                    }
                }
                self.flush_row_reference(j as usize, t);
                self.active.retain(|&k| segs[k as usize].rows.1 > j + 1);
                j += 1;
            }
            segs.clear();
            self.segs = segs;
        }

        /// The row's spans sorted, merged and composited one after the other, pixel by
        /// pixel, each marked on its own: the reference of [`Capsules::flush_row`].
        fn flush_row_reference(&mut self, j: usize, t: &mut Target) {
            if self.spans.is_empty() {
                return;
            }
            self.spans.sort_unstable();
            let row = &mut t.data[(j - t.first) * t.width..(j - t.first + 1) * t.width];
            let mut k = 0;
            while k < self.spans.len() {
                let (x0, mut x1) = self.spans[k];
                k += 1;
                while k < self.spans.len() && self.spans[k].0 <= x1 {
                    x1 = x1.max(self.spans[k].1);
                    k += 1;
                }
                let (x0, x1) = (x0 as usize, x1 as usize);
                match t.layer.as_deref_mut() {
                    Some(layer) => layer.add_span(j, x0, &mut self.slots[0].row[x0..x1]),
                    None => {
                        composite_pixels(&mut row[x0..x1], &mut self.slots[0].row[x0..x1], t.ink)
                    }
                }
                if t.ink != Ink::Paper {
                    t.dirty.mark_px(x0, j, x1, j + 1);
                }
            }
        }
    }

    /// Whole strokes made by the row loop are byte for byte those of the reference
    /// ([`Capsules::stroke_reference`]), and mark the same blocks: polylines of many short
    /// segments (many segments on a row, overlapping: a feature mark's band, a curve),
    /// scattered segments and dots, thin ([`Mode::Lanes`]) and wide ([`Mode::Wide`]),
    /// over blank and inked pages, drawn whole and band by band (segments entering and
    /// leaving mid-band, rows clipped), one stroke after another with the same scratch,
    /// on pages narrower and wider than a word of the block map; segments of a row or a
    /// few and of many runs of [`RING`] rows, entering while others are mid-run.
    ///
    /// On the instruction set the processor allows (AVX2, BMI1 and BMI2 where it has
    /// them, [`x86_fast`](crate::cpu::x86_fast)).
    #[test]
    fn strokes_match_the_reference_row_loop() {
        crate::cpu::baseline_only(false, strokes_match_reference);
    }

    /// [`strokes_match_the_reference_row_loop`] on the baseline instruction set's path:
    /// both paths are the reference's bytes and blocks, so each other's.
    #[test]
    fn strokes_on_the_baseline_path_match_the_reference_row_loop() {
        crate::cpu::baseline_only(true, strokes_match_reference);
    }

    fn strokes_match_reference() {
        let mut rand = unit_floats(0x5851_f42d_4c95_7f2du64);
        let (mut wide, mut thin, mut crowded, mut long) = (0, 0, 0, 0);
        // One scratch for every stroke, as a page's (nothing of a stroke may be left for
        // the next: rows made ahead, segments waiting for their next rows).
        let mut c = Capsules::default();
        for n in 0..1500 {
            // Now and then a page wider than a word of the block map (512 pixels).
            let (w, h) = if n % 7 == 6 { (1100, 40) } else { (240, 160) };
            let r = [0.2, 0.5, 0.83, 1.56, 2.6, 3.0, 3.125, 4.8, 10.41, 14.0][n % 10];
            let mut pts = Vec::new();
            let count = 1 + (rand() * 90.0) as usize;
            match (n / 10) % 3 {
                0 => {
                    // A polyline of short steps, wandering (a curve, a mark's band).
                    let mut p = [w as f32 * rand(), h as f32 * rand()];
                    let mut ang = rand() * std::f32::consts::TAU;
                    for _ in 0..count {
                        let step = 0.3 + 6.0 * rand();
                        ang += (rand() - 0.5) * 0.8;
                        let q = [p[0] + step * ang.cos(), p[1] + step * ang.sin()];
                        pts.push((p, q));
                        p = q;
                    }
                }
                1 => {
                    // Scattered segments, dots and segments along rows and columns.
                    for k in 0..count {
                        let a = [
                            -20.0 + (w as f32 + 40.0) * rand(),
                            -20.0 + (h as f32 + 40.0) * rand(),
                        ];
                        let len = [0.0, 0.5, 4.0, 30.0, 200.0][k % 5] * rand();
                        let ang = match k % 4 {
                            0 => 0.0,
                            1 => std::f32::consts::FRAC_PI_2,
                            _ => rand() * std::f32::consts::TAU,
                        };
                        pts.push((a, [a[0] + len * ang.cos(), a[1] + len * ang.sin()]));
                    }
                }
                _ => {
                    // Many segments crossing one another on the same rows.
                    let y = h as f32 * rand();
                    for _ in 0..count {
                        let a = [w as f32 * rand(), y + 8.0 * (rand() - 0.5)];
                        let b = [w as f32 * rand(), y + 8.0 * (rand() - 0.5)];
                        pts.push((a, b));
                    }
                }
            }
            let under: Vec<u8> = if n % 2 == 0 {
                vec![0; w * h]
            } else {
                (0..w * h).map(|i| ((i * 37) % 11 * 25) as u8).collect()
            };
            let ink = [Ink::Black, Ink::Gray(48), Ink::Paper][n % 3];
            // Whole, or in bands of a few rows (data from the band's first row).
            let bands: Vec<(usize, usize)> = if n % 4 == 3 {
                let step = 1 + (rand() * 40.0) as usize;
                (0..h)
                    .step_by(step)
                    .map(|j| (j, (j + step).min(h)))
                    .collect()
            } else {
                vec![(0, h)]
            };
            let mut got = under.clone();
            let mut want = under.clone();
            let mut got_dirty = Dirty::new(w, h);
            let mut want_dirty = Dirty::new(w, h);
            // Gray into the gray layer (as pages draw it) or straight onto the page.
            let layered = matches!(ink, Ink::Gray(_)) && n % 2 == 1;
            let mut layers = [GrayLayer::new(w, h), GrayLayer::new(w, h)];
            for &(j0, j1) in &bands {
                for (((data, dirty), layer), reference) in [&mut got, &mut want]
                    .into_iter()
                    .zip([&mut got_dirty, &mut want_dirty])
                    .zip(&mut layers)
                    .zip([false, true])
                {
                    for &(a, b) in &pts {
                        c.push(a, b);
                    }
                    layer.level = ink.level();
                    let mut t = Target {
                        data: &mut data[j0 * w..j1 * w],
                        width: w,
                        height: h,
                        ink,
                        rows: (j0, j1),
                        first: j0,
                        dirty,
                        layer: layered.then_some(layer),
                    };
                    if reference {
                        c.stroke_reference(r, &mut t);
                    } else {
                        c.stroke(r, &mut t);
                    }
                    layer.flush(&mut data[j0 * w..j1 * w], j0);
                }
            }
            assert!(got == want, "stroke {n}: r {r}, {} segments", pts.len());
            assert_eq!(got_dirty.rows(), want_dirty.rows(), "stroke {n}");
            assert!(
                c.slots.iter().all(|s| s.row.iter().all(|&v| v == 0)),
                "row buffer left clean"
            );
            if got != under {
                if r > LANES_MAX_R {
                    wide += 1;
                } else {
                    thin += 1;
                }
                crowded += usize::from(pts.len() > 20);
                // A segment over three runs of rows or more.
                let tall = |(a, b): &([f32; 2], [f32; 2])| (a[1] - b[1]).abs() > 3.0 * RING as f32;
                long += usize::from(pts.iter().any(tall));
            }
        }
        assert!(
            wide > 300 && thin > 300 && crowded > 300 && long > 300,
            "{wide} {thin} {crowded} {long}"
        );
    }

    /// [`ring_span`] is [`Ring::pixel`] pixel by pixel: random rings (centres on and off
    /// the page, at fractions of a pixel; radii from 0, thin and wide, half widths below
    /// and above ½; a few whose pixels' squared distances are infinite) on pages of widths
    /// that are not multiples of four, drawn over each other, against the pixel by pixel
    /// reference.
    #[test]
    fn rings_in_lanes_are_their_pixels() {
        let mut seed = 0x51f1_5eed_2545_f491u64;
        let mut rand = || {
            seed = crate::xorshift(seed);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let pixels = |row: &mut [u8], x0: usize, x1: usize, g: Ring| {
            for (i, px) in row[x0..x1].iter_mut().enumerate() {
                *px = (*px).max(g.pixel(x0 + i));
            }
        };
        let mut inked = 0;
        for (w, h) in [(97usize, 61usize), (203, 150), (5, 9)] {
            let (mut got, mut want) = (vec![0u8; w * h], vec![0u8; w * h]);
            let (mut got_dirty, mut want_dirty) = (Dirty::new(w, h), Dirty::new(w, h));
            let (mut a, mut b) = (Capsules::default(), Capsules::default());
            for n in 0..400 {
                let mut c = [
                    (rand() * 1.4 - 0.2) * w as f32,
                    (rand() * 1.4 - 0.2) * h as f32,
                ];
                let mut radius = match n % 4 {
                    0 => 0.0,
                    1 => rand() * 4.0,
                    _ => rand() * w as f32,
                };
                let mut r = rand() * if n % 3 == 0 { 0.6 } else { 6.0 };
                if n % 50 == 7 {
                    // An arc across the page whose pixels' squared distances to the
                    // centre are infinite.
                    c[0] = if n % 100 == 7 { -1.9e19 } else { 1.9e19 };
                    (radius, r) = (1.9e19, 1.0e18);
                }
                let ink = if n % 5 == 0 { Ink::Paper } else { Ink::Black };
                a.ring(c, radius, r, &mut target(&mut got, w, &mut got_dirty, ink));
                b.ring_with::<false>(
                    c,
                    radius,
                    r,
                    &mut target(&mut want, w, &mut want_dirty, ink),
                    pixels,
                );
                assert!(got == want, "{w}: ring {n}: {c:?} {radius} {r}");
                assert!(
                    a.slots.iter().all(|s| s.row.iter().all(|&v| v == 0)),
                    "row buffer left clean"
                );
            }
            assert_eq!(got_dirty.rows(), want_dirty.rows());
            inked += got.iter().filter(|&&v| v != 0 && v != 255).count();
        }
        assert!(inked > 1000, "{inked}");
    }

    /// [`ring_span_x8`] is [`ring_span`]: random rings' spans of every length from 0 to
    /// 40 pixels at every offset within eight, over blank, mixed and full rows (where
    /// the processor has AVX2; [`Capsules::ring`] takes it there, which
    /// `rings_in_lanes_are_their_pixels` checks pixel by pixel too).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn ring_spans_eight_at_a_time_are_four_at_a_times() {
        if !crate::cpu::x86_fast() {
            return;
        }
        let mut seed = 0x2b99_1c0d_e51f_7a03u64;
        let mut rand = || {
            seed = crate::xorshift(seed);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut cases = 0;
        for n in 0..600 {
            let g = Ring {
                cx: rand() * 80.0 - 10.0,
                dy: rand() * 40.0 - 20.0,
                radius: if n % 5 == 0 { 0.0 } else { rand() * 30.0 },
                r: rand() * if n % 3 == 0 { 0.6 } else { 8.0 },
            };
            let under: Vec<u8> = (0..64u32)
                .map(|i| match n % 3 {
                    0 => 0,
                    1 => (i * 37 % 256) as u8,
                    _ => 255,
                })
                .collect();
            for x0 in 0..8 {
                for len in 0..=40 {
                    let (mut got, mut want) = (under.clone(), under.clone());
                    // SAFETY: the processor was just found to have AVX2.
                    #[allow(unsafe_code)]
                    unsafe {
                        ring_span_x8(&mut got, x0, x0 + len, g)
                    };
                    ring_span(&mut want, x0, x0 + len, g);
                    assert!(got == want, "{n}: {x0} {len}");
                    cases += 1;
                }
            }
        }
        assert_eq!(cases, 600 * 8 * 41);
    }

    #[test]
    fn a_ring_is_the_circle_thickened() {
        let (w, h) = (120, 120);
        let mut data = vec![0u8; w * h];
        let mut dirty = Dirty::new(w, h);
        let mut c = Capsules::default();
        c.ring(
            [60.0, 60.0],
            40.0,
            1.0,
            &mut target(&mut data, w, &mut dirty, Ink::Black),
        );
        let ink: f64 = data.iter().map(|&v| f64::from(v) / 255.0).sum();
        let expected = 2.0 * std::f64::consts::PI * 40.0 * 2.0;
        assert!((ink / expected - 1.0).abs() < 0.01, "{ink} {expected}");
        assert_eq!(data[60 * w + 60], 0);
        assert_eq!(data[59 * w + 20], 255);
    }

    #[test]
    fn paper_erases_and_off_page_strokes_are_clipped() {
        let (w, h) = (50, 40);
        let mut data = vec![255u8; w * h];
        let mut dirty = Dirty::new(w, h);
        let mut c = Capsules::default();
        c.push([-100.0, 20.0], [1000.0, 20.0]);
        c.push([f32::NAN, 3.0], [4.0, 5.0]);
        c.push([10.0, -50.0], [10.0, -40.0]);
        c.stroke(2.0, &mut target(&mut data, w, &mut dirty, Ink::Paper));
        assert_eq!(data[20 * w + 25], 0);
        assert_eq!(data[19 * w], 0);
        assert_eq!(data[10 * w + 10], 255);
        assert!(!dirty.any(), "paper marks nothing");
    }
}
