//! Raster backend: anti-aliased ink coverage (strokes by [`crate::capsule`], polygons by
//! tiny-skia, glyphs by ab_glyph), grayscale PNG output.

use super::{Canvas, anchored_x};
use crate::capsule::{Capsules, Target};
use crate::dirty::Dirty;
use crate::layer::GrayLayer;
use crate::pixel::{div255, narrow, overprint, widen};
use crate::rowdeflate::RowDeflate;
use ab_glyph::{
    Font, FontRef, Glyph, GlyphId, Outline, OutlineCurve, OutlinedGlyph, ScaleFont, point,
};
use coupler_layout::{self as font, Anchor, DisplayList, Ink, PT_PER_INCH, PagePoint, Shaper};
use std::collections::HashMap;
use std::io::Write;
use tiny_skia::{FillRule, Mask, PathBuilder, Transform};
use wide::{u8x16, u16x8};

mod band;

/// A page being drawn: an 8-bit ink-coverage buffer (0 = paper, 255 = full ink) at a
/// given DPI. Ink of gray level `g` with coverage `c` overprints in integers
/// (`ink ← ink + (255 − ink)·c·g`, see `overprint`), paper erases. Black is composited
/// as it is drawn; the strokes and polygons of one gray merge in a sparse layer
/// (`GrayLayer`) composited when the gray changes, before paper and when the page is
/// read. One buffer per worker, cleared and reused for every page, keeps memory bounded
/// (tabloid at 300 dpi: 16.8 MB).
pub struct RasterPage {
    mask: Mask,
    px_per_pt: f64,
    dpi: f64,
    font: FontRef<'static>,
    /// The labels' shaping, its look-ups kept from page to page.
    shaper: Shaper,
    ink: Ink,
    /// Gray waiting to be composited.
    gray: GrayLayer,
    /// Where the page may hold ink: clearing and encoding visit only these blocks.
    dirty: Dirty,
    /// The stroke scan converter's scratch.
    capsules: Capsules,
    /// Glyphs and glyph halos made so far (`None`: a glyph without outline).
    halos: HashMap<HaloKey, Option<HaloTile>, KeyHash>,
    halo_scratch: HaloScratch,
    /// Glyph outlines read from the font so far, by glyph id (the font never changes).
    outlines: HashMap<u16, Option<Outline>, KeyHash>,
    /// Size of the last PNG encoded, to size the next one's buffer.
    last_png: usize,
    /// Rows `[lo, hi)` drawn into: the whole page, but while it is drawn band by band
    /// ([`RasterPage::render_png`]), when every primitive draws only the band's rows.
    rows: (usize, usize),
    /// The band plan's scratch, kept from page to page.
    bands: band::Bands,
    /// While a page is drawn band by band: the band's buffer, `BAND_ROWS + 1` rows
    /// whose first is page row `first` (the row above the band, which the encoder
    /// reads), reused band after band so that it stays in cache. The page's own buffer
    /// then stays blank.
    band_buf: Vec<u8>,
    first: usize,
    banded: bool,
}

/// The pixels drawn into: the page's buffer, or the band's while a page is drawn band
/// by band.
#[inline]
fn pixels<'a>(mask: &'a mut Mask, band: &'a mut [u8], banded: bool) -> &'a mut [u8] {
    if banded { band } else { mask.data_mut() }
}

/// How hard to compress PNG pages.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PngCompression {
    /// fdeflate's PNG-tuned fast mode with the Up filter (the default: pages are
    /// written as fast as they are drawn).
    #[default]
    Fast,
    /// zlib's best level with adaptive filtering: smaller files for archiving, at
    /// several times the encoding time. Same pixels.
    Best,
}

impl std::str::FromStr for PngCompression {
    type Err = String;
    fn from_str(s: &str) -> Result<PngCompression, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "fast" => Ok(PngCompression::Fast),
            "best" => Ok(PngCompression::Best),
            _ => Err(format!(
                "unknown PNG compression {s:?} (expected fast or best)"
            )),
        }
    }
}

impl PngCompression {
    /// `"fast"` or `"best"`.
    pub fn name(self) -> &'static str {
        match self {
            PngCompression::Fast => "fast",
            PngCompression::Best => "best",
        }
    }
}

impl RasterPage {
    /// A blank page of `width_px × height_px` at `dpi`. `None` for a zero size.
    pub fn new(width_px: u32, height_px: u32, dpi: f64) -> Option<RasterPage> {
        Some(RasterPage {
            mask: Mask::new(width_px, height_px)?,
            px_per_pt: dpi / PT_PER_INCH,
            dpi,
            font: font::embedded_font(),
            shaper: Shaper::new(),
            ink: Ink::Black,
            gray: GrayLayer::new(width_px as usize, height_px as usize),
            dirty: Dirty::new(width_px as usize, height_px as usize),
            capsules: Capsules::default(),
            halos: HashMap::default(),
            halo_scratch: HaloScratch::default(),
            outlines: HashMap::default(),
            last_png: 0,
            rows: (0, height_px as usize),
            bands: band::Bands::default(),
            band_buf: Vec::new(),
            first: 0,
            banded: false,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.mask.width()
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.mask.height()
    }

    /// Resolution.
    pub fn dpi(&self) -> f64 {
        self.dpi
    }

    /// Erases all ink (and sets the ink back to black). Only the blocks that were drawn
    /// into are visited.
    pub fn clear(&mut self) {
        self.flush_gray();
        let stride = self.mask.width() as usize;
        let data = self.mask.data_mut();
        self.dirty
            .for_each_span(|j, x0, x1| data[j * stride + x0..j * stride + x1].fill(0));
        self.dirty.reset();
        self.ink = Ink::Black;
        self.trim_tiles();
    }

    /// Empties the glyph and halo cache when it is full (between pages only: a label's
    /// tiles must stay while it is drawn).
    fn trim_tiles(&mut self) {
        if self.halos.len() >= MAX_HALO_TILES {
            self.halos.clear();
        }
    }

    /// Erases all ink and turns the page to `width_px × height_px` when that is as many
    /// pixels as now (a portrait page's buffer for a landscape page), keeping its memory;
    /// `false` (the page only erased) for another size.
    pub fn reshape(&mut self, width_px: u32, height_px: u32) -> bool {
        self.clear();
        let n = u64::from(width_px) * u64::from(height_px);
        let Some(size) = tiny_skia::IntSize::from_wh(width_px, height_px) else {
            return false;
        };
        if n != u64::from(self.width()) * u64::from(self.height()) {
            return false;
        }
        // Cleared: every byte is 0, so the same bytes serve any shape.
        let turn = |m: &mut Mask| {
            if let Some(empty) = Mask::new(1, 1) {
                let data = std::mem::replace(m, empty).take();
                if let Some(turned) = Mask::from_vec(data, size) {
                    *m = turned;
                }
            }
        };
        turn(&mut self.mask);
        self.dirty = Dirty::new(width_px as usize, height_px as usize);
        self.gray = GrayLayer::new(width_px as usize, height_px as usize);
        self.rows = (0, height_px as usize);
        self.width() == width_px && self.height() == height_px
    }

    /// The ink coverage, row-major (gray composited in).
    pub fn ink(&mut self) -> &[u8] {
        self.flush_gray();
        self.mask.data()
    }

    /// Composites the waiting gray into the page.
    fn flush_gray(&mut self) {
        if self.gray.any() {
            let data = pixels(&mut self.mask, &mut self.band_buf, self.banded);
            self.gray.flush(data, self.first);
        }
    }

    /// Writes the page as an 8-bit grayscale PNG (paper white, ink black), fast
    /// compression. The page is left as drawn.
    pub fn finish_png(&mut self, out: impl Write) -> Result<(), png::EncodingError> {
        self.finish_png_with(PngCompression::Fast, out)
    }

    /// Writes the page as an 8-bit grayscale PNG with the given compression. The fast
    /// encoder inverts ink to gray inside its Up filter and visits only the drawn blocks
    /// (elsewhere both rows are paper and the filtered bytes are 0).
    pub fn finish_png_with(
        &mut self,
        compression: PngCompression,
        out: impl Write,
    ) -> Result<(), png::EncodingError> {
        let mut out = out;
        match compression {
            PngCompression::Fast => {
                let bytes = self.encode_fast(false)?;
                out.write_all(&bytes)?;
                Ok(())
            }
            PngCompression::Best => {
                self.flush_gray();
                let mut gray = self.mask.data().to_vec();
                invert(&mut gray);
                encode_png_best(&gray, self.width(), self.height(), self.dpi, out)
            }
        }
    }

    /// The page as an 8-bit grayscale PNG (the same bytes as [`RasterPage::finish_png_with`]),
    /// and the page cleared for the next one: the fast encoder erases each row once it
    /// has been read, while it is in cache, instead of in a pass of its own.
    pub fn take_png(&mut self, compression: PngCompression) -> Result<Vec<u8>, png::EncodingError> {
        let bytes = match compression {
            PngCompression::Fast => self.encode_fast(true)?,
            PngCompression::Best => {
                let mut v = Vec::with_capacity(self.last_png);
                self.finish_png_with(compression, &mut v)?;
                self.clear();
                v
            }
        };
        self.last_png = bytes.len();
        Ok(bytes)
    }

    /// Draws `display` on the page, blank first, and encodes it: the bytes of [`draw`]
    /// then [`RasterPage::take_png`], and the page is left blank. The fast PNG is drawn
    /// and encoded band by band, each band encoded while its rows are in cache (the
    /// pixels are the same, see `raster/band.rs`). Gives the PNG and the time spent
    /// encoding (the rest is drawing).
    ///
    /// [`draw`]: crate::draw
    pub fn render_png(
        &mut self,
        display: &DisplayList,
        compression: PngCompression,
    ) -> Result<(Vec<u8>, std::time::Duration), png::EncodingError> {
        let mut encode = std::time::Duration::ZERO;
        if compression == PngCompression::Fast
            && let Some(bytes) = self.render_bands(display, &mut encode)
        {
            return Ok((bytes?, encode));
        }
        self.clear();
        crate::draw(display, self);
        let t = std::time::Instant::now();
        let bytes = self.take_png(compression)?;
        Ok((bytes, t.elapsed()))
    }

    /// The fast PNG of the page in one buffer sized from the last page's; with `clear`,
    /// the page is left blank (and the ink black).
    fn encode_fast(&mut self, clear: bool) -> std::io::Result<Vec<u8>> {
        self.flush_gray();
        let (w, h, dpi) = (self.width(), self.height(), self.dpi);
        let capacity = if self.last_png == 0 {
            1 << 19
        } else {
            self.last_png + self.last_png / 8 + 4096
        };
        let data = self.mask.data_mut();
        let bytes = write_png_fast(data, w, h, dpi, &self.dirty, clear, capacity)?;
        if clear {
            self.dirty.reset();
            self.ink = Ink::Black;
            self.trim_tiles();
        }
        self.last_png = bytes.len();
        Ok(bytes)
    }

    /// The page as 8-bit gray levels (255 = paper), a new buffer.
    pub fn to_gray(&mut self) -> Vec<u8> {
        let mut v = self.ink().to_vec();
        invert(&mut v);
        v
    }

    fn px(&self, p: PagePoint) -> (f32, f32) {
        (
            (p[0] * self.px_per_pt) as f32,
            (p[1] * self.px_per_pt) as f32,
        )
    }

    /// Fills an axis-aligned rectangle given in pixels with exact area coverage (each
    /// pixel gets the fraction of its area inside), composited as ink. A fast path for
    /// frames and bands, which a general anti-aliasing scan handles row by row.
    pub fn fill_rect_px(&mut self, x0: f64, y0: f64, x1: f64, y1: f64) {
        let Some([x0, y0, x1, y1]) = self.rect_on_page([x0, y0, x1, y1]) else {
            return;
        };
        let stride = self.width() as usize;
        let cover = |lo: f64, hi: f64, i: usize| -> f64 {
            let (a, b) = (i as f64, i as f64 + 1.0);
            (hi.min(b) - lo.max(a)).max(0.0)
        };
        let (i0, i1) = (x0.floor() as usize, (x1.ceil() as usize).min(stride));
        let (j0, j1) = (
            y0.floor() as usize,
            (y1.ceil() as usize).min(self.height() as usize),
        );
        let ink_of = self.ink;
        if ink_of == Ink::Paper {
            self.flush_gray();
        }
        // Only the rows being drawn (the band's, when drawn in bands).
        let (j0, j1) = (j0.max(self.rows.0), j1.min(self.rows.1));
        if j1 <= j0 {
            return;
        }
        if ink_of != Ink::Paper {
            self.dirty.mark_px(i0, j0, i1, j1);
        }
        let columns: Vec<f64> = (i0..i1).map(|i| cover(x0, x1, i)).collect();
        let first = self.first;
        let data = pixels(&mut self.mask, &mut self.band_buf, self.banded);
        if ink_of != Ink::Paper {
            let rows = &mut data[(j0 - first) * stride..(j1 - first) * stride];
            fill_rect_rows(
                rows,
                stride,
                i0,
                &columns,
                |j| cover(y0, y1, j0 + j),
                ink_of,
            );
            return;
        }
        for j in j0..j1 {
            let cy = cover(y0, y1, j);
            let row = &mut data[(j - first) * stride..(j - first + 1) * stride];
            // Paper changes only pixels with ink: the marked blocks.
            for (a, b) in self.dirty.row_pair_spans(j) {
                let (a, b) = (a.max(i0), b.min(i1));
                if a < b {
                    rect_span(&mut row[a..b], &columns[a - i0..b - i0], cy, ink_of);
                }
            }
        }
    }

    /// The four sides of a stroked rectangle (page points) as pixel rectangles: exact
    /// mitred corners.
    fn rect_sides(&self, rect: [f64; 4], width: f64) -> [[f64; 4]; 4] {
        let k = self.px_per_pt;
        let [x0, y0, x1, y1] = rect.map(|v| v * k);
        let h = 0.5 * width * k;
        [
            [x0 - h, y0 - h, x1 + h, y0 + h],
            [x0 - h, y1 - h, x1 + h, y1 + h],
            [x0 - h, y0 + h, x0 + h, y1 - h],
            [x1 - h, y0 + h, x1 + h, y1 - h],
        ]
    }

    /// A polygon (at least 3 points, page points) as a closed pixel path.
    fn polygon_path(&self, points: &[PagePoint]) -> Option<tiny_skia::Path> {
        let mut pb = PathBuilder::new();
        let (x, y) = self.px(*points.first()?);
        pb.move_to(x, y);
        for p in &points[1..] {
            let (x, y) = self.px(*p);
            pb.line_to(x, y);
        }
        pb.close();
        pb.finish()
    }

    /// A pixel rectangle clipped to the page, `None` when nothing of it is on the page.
    fn rect_on_page(&self, r: [f64; 4]) -> Option<[f64; 4]> {
        let (w, h) = (self.width() as f64, self.height() as f64);
        let (x0, x1) = (r[0].clamp(0.0, w), r[2].clamp(0.0, w));
        let (y0, y1) = (r[1].clamp(0.0, h), r[3].clamp(0.0, h));
        (x0 < x1 && y0 < y1).then_some([x0, y0, x1, y1])
    }

    /// Fills `path` in the current ink.
    fn fill(&mut self, path: &tiny_skia::Path) {
        match self.ink {
            // All-black ink composites straight into the page's coverage.
            Ink::Black => {
                self.mask
                    .fill_path(path, FillRule::Winding, true, Transform::identity());
                let b = path.bounds();
                self.dirty.mark([b.left(), b.top(), b.right(), b.bottom()]);
            }
            Ink::Gray(level) => {
                if self.gray.level != level {
                    self.flush_gray();
                    self.gray.level = level;
                }
                self.fill_with(path, self.ink);
            }
            Ink::Paper => {
                self.flush_gray();
                self.fill_with(path, Ink::Paper);
            }
        }
    }

    /// Readies the gray layer for drawing in `ink`: a gray other than the layer's
    /// composites the layer first and becomes its level; paper composites it (paper
    /// erases what is below, the layer's gray included); black draws on the page as is.
    fn prepare_ink(&mut self, ink: Ink) {
        match ink {
            Ink::Gray(level) => {
                if self.gray.level != level {
                    self.flush_gray();
                    self.gray.level = level;
                }
            }
            Ink::Paper => self.flush_gray(),
            Ink::Black => {}
        }
    }

    /// The page as a target of the stroke scan converter, in the current ink: gray
    /// into the layer (composited first if it holds another gray), paper once the
    /// layer is composited.
    fn target(&mut self) -> (&mut Capsules, Target<'_>) {
        self.prepare_ink(self.ink);
        let (width, height) = (self.width() as usize, self.height() as usize);
        let layer = matches!(self.ink, Ink::Gray(_)).then_some(&mut self.gray);
        (
            &mut self.capsules,
            Target {
                data: pixels(&mut self.mask, &mut self.band_buf, self.banded),
                first: self.first,
                width,
                height,
                ink: self.ink,
                rows: self.rows,
                dirty: &mut self.dirty,
                layer,
            },
        )
    }

    /// Fills `path` in a gray or in paper: its coverage is rasterised into a scratch
    /// mask over its box, then composited (a gray overprints, paper erases).
    fn fill_with(&mut self, path: &tiny_skia::Path, ink: Ink) {
        if let Some(cover) = self.scratch_cover(path) {
            self.apply_cover(&cover, ink);
        }
    }

    /// The coverage of `path` rasterised into a scratch mask over its box (widened by a
    /// pixel, clipped to the page), the path moved by whole pixels: the coverage of a
    /// gray or paper polygon.
    fn scratch_cover(&self, path: &tiny_skia::Path) -> Option<Cover> {
        let [x0, y0, x1, y1] = self.path_box(path)?;
        let mut scratch = Mask::new((x1 - x0) as u32, (y1 - y0) as u32)?;
        scratch.fill_path(
            path,
            FillRule::Winding,
            true,
            Transform::from_translate(-(x0 as f32), -(y0 as f32)),
        );
        Some(Cover {
            x0: x0 as usize,
            y0: y0 as usize,
            w: (x1 - x0) as usize,
            cov: scratch.take(),
        })
    }

    /// The pixel box of `path`, widened by a pixel and clipped to the page: `None`
    /// when empty.
    fn path_box(&self, path: &tiny_skia::Path) -> Option<[i64; 4]> {
        let b = path.bounds();
        let (w, h) = (i64::from(self.width()), i64::from(self.height()));
        let x0 = (b.left().floor() as i64 - 1).clamp(0, w);
        let y0 = (b.top().floor() as i64 - 1).clamp(0, h);
        let x1 = (b.right().ceil() as i64 + 1).clamp(0, w);
        let y1 = (b.bottom().ceil() as i64 + 1).clamp(0, h);
        (x0 < x1 && y0 < y1).then_some([x0, y0, x1, y1])
    }

    /// Composites a coverage in `ink`, only in the rows being drawn: black as
    /// tiny-skia's mask fill blends it ([`lerp_white`]), a gray merged into the gray
    /// layer, paper erasing.
    fn apply_cover(&mut self, cover: &Cover, ink: Ink) {
        self.prepare_ink(ink);
        let (sw, stride) = (cover.w, self.width() as usize);
        let h = cover.cov.len() / sw.max(1);
        let j0 = cover.y0.max(self.rows.0);
        let j1 = (cover.y0 + h).min(self.rows.1);
        if j1 <= j0 {
            return;
        }
        if ink != Ink::Paper {
            self.dirty.mark_px(cover.x0, j0, cover.x0 + sw, j1);
        }
        let rows = cover.cov[(j0 - cover.y0) * sw..(j1 - cover.y0) * sw].chunks(sw);
        if let Ink::Gray(_) = ink {
            // Merged with the other strokes of this gray.
            let mut row = std::mem::take(&mut self.halo_scratch.merged);
            for (j, src) in (j0..).zip(rows) {
                row.clear();
                row.extend_from_slice(src);
                self.gray.add_span(j, cover.x0, &mut row);
            }
            self.halo_scratch.merged = row;
            return;
        }
        let first = self.first;
        let data = pixels(&mut self.mask, &mut self.band_buf, self.banded);
        for (j, src) in (j0..).zip(rows) {
            let start = (j - first) * stride + cover.x0;
            for (px, &c) in data[start..start + sw].iter_mut().zip(src) {
                if c != 0 {
                    *px = match ink {
                        Ink::Black => lerp_white(*px, c),
                        ink => composite(*px, c, ink),
                    };
                }
            }
        }
    }
}

/// A polygon's coverage over a box of the page: `w` pixels wide from `(x0, y0)`, row-major.
pub(crate) struct Cover {
    x0: usize,
    y0: usize,
    w: usize,
    cov: Vec<u8>,
}

/// tiny-skia's blend of white with coverage `c` over a mask pixel `d` (its low-precision
/// pipeline: `lerp(d, 255, c)` with `div255(v) = (v + 255) >> 8`). On a blank pixel it
/// gives `c` itself, so a black polygon filled on a blank page and blended later with
/// this gives the page tiny-skia would have made (tested).
#[inline]
fn lerp_white(d: u8, c: u8) -> u8 {
    let (d, c) = (u32::from(d), u32::from(c));
    ((d * (255 - c) + 255 * c + 255) >> 8) as u8
}

/// A rectangle's pixels on one row: `px[i]` covered `columns[i] · cy` in `ink`.
#[inline]
fn rect_span(px: &mut [u8], columns: &[f64], cy: f64, ink: Ink) {
    for (px, cx) in px.iter_mut().zip(columns) {
        let c = cx * cy;
        if ink == Ink::Black {
            let ink = f64::from(*px);
            *px = (ink + (255.0 - ink) * c + 0.5).min(255.0) as u8;
        } else {
            *px = composite(*px, (c * 255.0 + 0.5).min(255.0) as u8, ink);
        }
    }
}

/// Widest rectangle (pixels) whose rows [`fill_rect_rows`] remembers.
const RECT_MEMO: usize = 16;

/// A rectangle's rows `rows` (`stride` pixels each), columns `i0..i0 + columns.len()`,
/// each row `j` covered `cy(j)` in `ink` ([`rect_span`]; not paper). A row is a pure
/// function of its pixels before and its `cy`, so a row that holds the bytes the row
/// before held and has the same `cy` (a tall, narrow rectangle's rows over blank or
/// evenly inked paper: the frame's sides) takes the row before's result, not its
/// arithmetic again.
fn fill_rect_rows(
    rows: &mut [u8],
    stride: usize,
    i0: usize,
    columns: &[f64],
    cy: impl Fn(usize) -> f64,
    ink: Ink,
) {
    let n = columns.len();
    let i1 = i0 + n;
    // The row before: its `cy` (bits), its pixels before and after.
    let mut memo: Option<(u64, [u8; RECT_MEMO], [u8; RECT_MEMO])> = None;
    for (j, row) in rows.chunks_exact_mut(stride).enumerate() {
        let cy = cy(j);
        let px = &mut row[i0..i1];
        if n > RECT_MEMO {
            rect_span(px, columns, cy, ink);
            continue;
        }
        if let Some((bits, before, after)) = &memo {
            if *bits == cy.to_bits() && px[..] == before[..n] {
                px.copy_from_slice(&after[..n]);
                continue;
            }
        }
        let mut before = [0; RECT_MEMO];
        before[..n].copy_from_slice(px);
        rect_span(px, columns, cy, ink);
        let mut after = [0; RECT_MEMO];
        after[..n].copy_from_slice(px);
        memo = Some((cy.to_bits(), before, after));
    }
}

/// Composites coverage `c` (0..=255) of `ink` over the page's ink `dst` (0 paper, 255
/// black), in integers (deterministic): black and grays overprint (`dst + (255 − dst)·c·g`,
/// never lighter), paper erases (`dst·(1 − c)`).
fn composite(dst: u8, c: u8, ink: Ink) -> u8 {
    match ink {
        Ink::Paper => {
            let (d, c) = (u32::from(dst), u32::from(c));
            (d - (d * c + 127) / 255) as u8
        }
        ink => overprint(dst, c, u32::from(ink.level())),
    }
}

/// [`composite`] over a row: `dst[i] ← composite(dst[i], cov[i], ink)`, the ink chosen
/// once, not per pixel, so that each loop vectorises. Paper and black (whose
/// `(255·x + 32512) / 65025` is `(x + 127) / 255`: `255·(x + 127) + 127` leaves less
/// than 65025 over the quotient's multiple) fit 16-bit lanes; so do grays, their
/// quotient split in two ([`crate::layer::overprint_span`]).
fn composite_row(dst: &mut [u8], cov: &[u8], ink: Ink) {
    match ink {
        Ink::Paper => {
            for (d, &c) in dst.iter_mut().zip(cov) {
                let x = u16::from(*d) * u16::from(c) + 127;
                *d -= (x / 255) as u8;
            }
        }
        Ink::Black => {
            for (d, &c) in dst.iter_mut().zip(cov) {
                let x = u16::from(!*d) * u16::from(c) + 127;
                *d += (x / 255) as u8;
            }
        }
        ink => crate::layer::overprint_span(dst, cov, ink.level()),
    }
}

/// [`composite_row`] of rows of whole groups of [`LANES`] pixels, a group at a time in
/// 16-bit lanes (the same integer arithmetic: exact).
#[inline]
fn composite_groups(dst: &mut [u8], cov: &[u8], ink: Ink) {
    debug_assert!(dst.len() == cov.len() && dst.len() % LANES == 0);
    let groups = dst.chunks_exact_mut(LANES).zip(cov.chunks_exact(LANES));
    let (full, half) = (u16x8::splat(255), u16x8::splat(127));
    match ink {
        Ink::Paper => {
            for (d8, c8) in groups {
                let d = widen(d8);
                narrow(d - div255(d * widen(c8) + half), d8);
            }
        }
        Ink::Black => {
            for (d8, c8) in groups {
                if u64::from_ne_bytes(d8.try_into().unwrap_or([1; LANES])) == 0 {
                    // Paper under all eight (a glyph's, where its halo erased the page):
                    // `(255·c + 127) / 255` is `c`.
                    d8.copy_from_slice(c8);
                    continue;
                }
                let d = widen(d8);
                narrow(d + div255((full - d) * widen(c8) + half), d8);
            }
        }
        ink => crate::layer::overprint_span(dst, cov, ink.level()),
    }
}

/// `x ← 255 − x` over a buffer (vectorises).
fn invert(data: &mut [u8]) {
    for x in data.iter_mut() {
        *x = !*x;
    }
}

/// Encodes 8-bit gray (or ink, inverted on the way out when `ink` is true) as a PNG with
/// the resolution in a `pHYs` chunk (pixels per metre). Fast deflate and the Up filter:
/// deterministic bytes for a given `fdeflate` version.
pub fn encode_png(
    data: &[u8],
    width: u32,
    height: u32,
    dpi: f64,
    ink: bool,
    out: impl Write,
) -> Result<(), png::EncodingError> {
    encode_png_with(data, width, height, dpi, ink, PngCompression::Fast, out)
}

/// [`encode_png`] with a choice of compression.
pub fn encode_png_with(
    data: &[u8],
    width: u32,
    height: u32,
    dpi: f64,
    ink: bool,
    compression: PngCompression,
    out: impl Write,
) -> Result<(), png::EncodingError> {
    let mut v = data.to_vec();
    match compression {
        PngCompression::Fast => {
            let mut all = Dirty::new(width as usize, height as usize);
            all.mark_all();
            if !ink {
                // Gray in: the same encoder on the ink it shows.
                invert(&mut v);
            }
            let capacity = v.len() / 4;
            let bytes = write_png_fast(&mut v, width, height, dpi, &all, false, capacity)?;
            let mut out = out;
            out.write_all(&bytes)?;
            Ok(())
        }
        PngCompression::Best => {
            if ink {
                invert(&mut v);
            }
            encode_png_best(&v, width, height, dpi, out)
        }
    }
}

/// Pixels per metre for a resolution in dots per inch.
fn ppm(dpi: f64) -> u32 {
    (dpi / 0.0254).round() as u32
}

/// PNG of ink coverage `ink` (0 = paper), written as gray (255 = paper) with the Up
/// filter and fdeflate's PNG-tuned fast mode, the inversion folded into the filter:
/// filtered = gray(row) − gray(row above) = ink(row above) − ink(row). Outside the blocks
/// `dirty` marks (in this row or the one above) both rows are paper and the filtered bytes
/// are 0, so only the filtered row's 8-byte words that meet a marked block are computed,
/// by [`RowDeflate::up_row`] as it codes them: a row with no marked block is a blank
/// row, written as a precomputed bit string (runs of them one after the other), and the
/// zeros between an inked row's words only lengthen a run. The bytes are those of
/// `fdeflate` on the whole filtered rows. With `clear`, each row's marked blocks are
/// zeroed once the row below has been filtered (the buffer ends blank).
/// The file is built in one buffer of `capacity` bytes to start with.
fn write_png_fast(
    ink: &mut [u8],
    width: u32,
    height: u32,
    dpi: f64,
    dirty: &Dirty,
    clear: bool,
    capacity: usize,
) -> std::io::Result<Vec<u8>> {
    assert_eq!(ink.len(), width as usize * height as usize, "buffer size");
    let mut png = FastPng::begin(width, height, dpi, capacity)?;
    png.rows(ink, 0, dirty, height as usize, clear);
    png.finish(ink, 0, dirty, clear)
}

/// The most buffers [`reuse_png_buffer`] keeps on a thread, and the least capacity
/// it keeps (a page's PNG at 300 dpi is hundreds of KiB).
const SPARE_MAX: usize = 16;
const SPARE_LEAST: usize = 1 << 16;

thread_local! {
    /// Buffers of files already written, for the thread's next pages' PNGs: their
    /// bytes are written over, not zeroed again, and their pages stay mapped.
    static SPARE: std::cell::RefCell<Vec<Vec<u8>>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Gives the buffer of a file that has been written (a PNG this crate made, or any
/// other bytes) back for the next fast PNG made on this thread, which writes its
/// file over the buffer's bytes instead of a new buffer's zeros. At most a few are
/// kept per thread (the others are dropped), so a page's buffer is reused when the
/// thread that draws pages writes their files. The PNG's bytes do not depend on it.
pub fn reuse_png_buffer(buf: Vec<u8>) {
    if buf.capacity() < SPARE_LEAST {
        return;
    }
    SPARE.with_borrow_mut(|v| {
        if v.len() < SPARE_MAX {
            v.push(buf);
        }
    });
}

/// [`write_png_fast`] row by row: the rows of a page drawn band by band are encoded as
/// each band is done ([`FastPng::rows`]), while they are in cache.
pub(crate) struct FastPng {
    z: RowDeflate,
    /// Where the IDAT chunk starts (its length is patched in at the end).
    idat: usize,
    /// The first row, filtered (filter byte first); the others are filtered by
    /// [`RowDeflate::up_row`] as they are coded.
    row: Vec<u8>,
    /// Blank rows (no marked block in the row or the one above: filtered bytes all 0)
    /// waiting to be written as one run.
    blank: usize,
    /// The next row to encode.
    next: usize,
    width: usize,
    height: usize,
}

impl FastPng {
    /// The PNG's header chunks and the start of its IDAT, in a buffer of `capacity` bytes
    /// to start with.
    pub(crate) fn begin(
        width: u32,
        height: u32,
        dpi: f64,
        capacity: usize,
    ) -> std::io::Result<FastPng> {
        let mut out = Vec::with_capacity(64);
        out.extend_from_slice(&[0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a]);
        let mut ihdr = Vec::with_capacity(13);
        ihdr.extend_from_slice(&width.to_be_bytes());
        ihdr.extend_from_slice(&height.to_be_bytes());
        ihdr.extend_from_slice(&[8, 0, 0, 0, 0]); // 8-bit grayscale, deflate, no interlace
        write_chunk(&mut out, b"IHDR", &ihdr)?;
        let mut phys = Vec::with_capacity(9);
        phys.extend_from_slice(&ppm(dpi).to_be_bytes());
        phys.extend_from_slice(&ppm(dpi).to_be_bytes());
        phys.push(1); // metre
        write_chunk(&mut out, b"pHYs", &phys)?;
        // The IDAT chunk: its length is patched in once the stream is written.
        let idat = out.len();
        out.extend_from_slice(&[0, 0, 0, 0]);
        out.extend_from_slice(b"IDAT");
        let w = width as usize;
        let mut row = vec![0u8; w + 1];
        row[0] = 2; // Up
        // The file is written over a buffer given back after an earlier page's file
        // ([`reuse_png_buffer`]), whatever it holds, or into a new one.
        let mut buf = SPARE
            .with_borrow_mut(Vec::pop)
            .unwrap_or_else(|| Vec::with_capacity(capacity.max(out.len())));
        let head = out.len();
        if buf.len() < head {
            buf.resize(head, 0);
        }
        buf[..head].copy_from_slice(&out);
        Ok(FastPng {
            z: RowDeflate::at(buf, head),
            idat,
            row,
            blank: 0,
            next: 0,
            width: w,
            height: height as usize,
        })
    }

    /// Encodes the rows up to `upto` (exclusive) of the page, which must be drawn up to
    /// there; `ink` holds the page's rows from row `first` on (the row above the next
    /// row to encode, if any, included). With `clear`, the marked blocks of each row but
    /// the last encoded are zeroed once the row below has been filtered.
    pub(crate) fn rows(
        &mut self,
        ink: &mut [u8],
        first: usize,
        dirty: &Dirty,
        upto: usize,
        clear: bool,
    ) {
        let (w, upto) = (self.width, upto.min(self.height));
        if self.next == 0 && upto > 0 {
            // The first row: the row above is 0 (PNG), so filtered = gray.
            for (o, i) in self.row[1..].iter_mut().zip(&ink[..w]) {
                *o = !*i;
            }
            self.z.row(&self.row, std::iter::once((0, w + 1)));
            self.row[1..].fill(0);
            self.next = 1;
        }
        for j in self.next.max(1)..upto {
            if dirty.row_pair_blank(j) {
                self.blank += 1;
                continue;
            }
            self.z.blank_rows(w + 1, 2, self.blank);
            self.blank = 0;
            let (above, this) = ink[(j - 1 - first) * w..(j + 1 - first) * w].split_at_mut(w);
            // Only the words meeting the marked blocks are filtered, in the encoder, which
            // clears the row above as it reads it (its ink is in its marked blocks).
            self.z.up_row(above, this, dirty.row_pair_words(j), clear);
        }
        self.next = self.next.max(upto);
    }

    /// The finished PNG, once every row is encoded; with `clear`, the last row's marked
    /// blocks are zeroed too (the page is left blank).
    pub(crate) fn finish(
        mut self,
        ink: &mut [u8],
        first: usize,
        dirty: &Dirty,
        clear: bool,
    ) -> std::io::Result<Vec<u8>> {
        let (w, h) = (self.width, self.height);
        debug_assert_eq!(self.next, h, "every row encoded");
        self.z.blank_rows(w + 1, 2, self.blank);
        if clear && h > 0 {
            dirty.clear_row(h - 1, &mut ink[(h - 1 - first) * w..(h - first) * w]);
        }
        let idat = self.idat;
        let mut out = self.z.finish();
        let len = u32::try_from(out.len() - idat - 8).map_err(std::io::Error::other)?;
        out[idat..idat + 4].copy_from_slice(&len.to_be_bytes());
        let crc = crc32fast::hash(&out[idat + 4..]);
        out.extend_from_slice(&crc.to_be_bytes());
        write_chunk(&mut out, b"IEND", &[])?;
        Ok(out)
    }
}

/// One PNG chunk: length, type, data, CRC-32 of type and data.
fn write_chunk(out: &mut impl Write, kind: &[u8; 4], data: &[u8]) -> std::io::Result<()> {
    let len = u32::try_from(data.len()).map_err(std::io::Error::other)?;
    out.write_all(&len.to_be_bytes())?;
    out.write_all(kind)?;
    out.write_all(data)?;
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    out.write_all(&crc.finalize().to_be_bytes())
}

/// 8-bit gray as a PNG at the `png` crate's highest compression with adaptive filtering
/// (`--png-compression best`).
fn encode_png_best(
    gray: &[u8],
    width: u32,
    height: u32,
    dpi: f64,
    out: impl Write,
) -> Result<(), png::EncodingError> {
    let mut enc = png::Encoder::new(out, width, height);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::High);
    enc.set_filter(png::Filter::Adaptive);
    enc.set_pixel_dims(Some(png::PixelDimensions {
        xppu: ppm(dpi),
        yppu: ppm(dpi),
        unit: png::Unit::Meter,
    }));
    let mut w = enc.write_header()?;
    w.write_image_data(gray)?;
    w.finish()
}

impl RasterPage {
    /// Strokes polylines as one stroke (round caps and joins; a single point is a dot).
    fn stroke_paths<'a>(&mut self, lines: impl Iterator<Item = &'a [PagePoint]>, width: f64) {
        for points in lines.filter(|l| !l.is_empty()) {
            let mut last = self.px(points[0]);
            if points.len() == 1 {
                self.capsules.push([last.0, last.1], [last.0, last.1]);
            }
            for p in &points[1..] {
                let (x, y) = self.px(*p);
                self.capsules.push([last.0, last.1], [x, y]);
                last = (x, y);
            }
        }
        let r = (0.5 * width * self.px_per_pt) as f32;
        let (capsules, mut target) = self.target();
        capsules.stroke(r, &mut target);
    }

    /// The tiles of a label's glyphs (`halo: None`) or of their halos (`Some(halo)`,
    /// points): `(page x, page y, key)` of each tile's top left corner, into `placed`
    /// (emptied first); each tile is made if not cached. The one placement both the
    /// drawing and the band plan use.
    fn place_label(
        &mut self,
        pos: PagePoint,
        size: f64,
        anchor: Anchor,
        text: &str,
        halo: Option<f64>,
        placed: &mut Vec<(i64, i64, HaloKey)>,
    ) {
        placed.clear();
        let k = self.px_per_pt;
        // Glyphs are shaped at their pixel size, halos at their point size (as drawn
        // since the halos were introduced: both kept as they are, byte for byte).
        let (origin, em, r, glyphs) = match halo {
            Some(halo) => {
                let (glyphs, advance) = self.shaper.shape_line(size, text);
                let x = anchored_x(pos[0], advance, anchor);
                let r = (halo * k) as f32;
                if r.is_nan() || r <= 0.0 {
                    // No halo (and `r == 0` keys are the glyphs' own coverage).
                    return;
                }
                ((x, k), (size * k) as f32, r, glyphs)
            }
            None => {
                let size_px = size * k;
                let (glyphs, advance) = self.shaper.shape_line(size_px, text);
                let x0 = anchored_x(pos[0] * k, advance, anchor);
                ((x0, 1.0), size_px as f32, 0.0, glyphs)
            }
        };
        for g in &glyphs {
            let (gx, gy) = match halo {
                Some(_) => (((origin.0 + g.x) * k) as f32, (pos[1] * k) as f32),
                None => ((origin.0 + g.x) as f32, (pos[1] * k) as f32),
            };
            if !(gx.is_finite() && gy.is_finite()) || gx.abs() > 1e7 || gy.abs() > 1e7 {
                continue;
            }
            // The nearest quarter pixel (`(4·g).round()`, then its whole pixel and
            // quarters), in integers.
            let (qx, qy) = (round_half_away(gx * 4.0), round_half_away(gy * 4.0));
            let (ix, iy) = (qx.div_euclid(4), qy.div_euclid(4));
            let key = HaloKey {
                glyph: g.id.0,
                em: em.to_bits(),
                r: r.to_bits(),
                sub: [qx.rem_euclid(4) as u8, qy.rem_euclid(4) as u8],
            };
            let Some((x0, y0)) = self.halo_tile(key) else {
                continue;
            };
            placed.push((ix + x0, iy + y0, key));
        }
    }

    /// The paper halo of `text`: its glyph outlines stroked `halo` points wide on each
    /// side, in paper. Each glyph's halo is made once per size and quarter-pixel
    /// position ([`HaloKey`]) and kept; a label's glyph halos are merged (their union)
    /// and composited at once.
    fn halo(&mut self, pos: PagePoint, size: f64, anchor: Anchor, text: &str, halo: f64) {
        // The glyphs' tiles: (page x, page y, key).
        let mut placed = std::mem::take(&mut self.halo_scratch.placed);
        self.place_label(pos, size, anchor, text, Some(halo), &mut placed);
        self.draw_halo(&placed);
        self.halo_scratch.placed = placed;
    }

    /// Draws a label's halo from its placed halo tiles ([`RasterPage::place_label`]).
    fn draw_halo(&mut self, placed: &[(i64, i64, HaloKey)]) {
        let (mut bx0, mut by0, mut bx1, mut by1) = (i64::MAX, i64::MAX, i64::MIN, i64::MIN);
        for (tx, ty, key) in placed {
            let Some(Some(tile)) = self.halos.get(key) else {
                continue;
            };
            bx0 = bx0.min(*tx);
            by0 = by0.min(*ty);
            bx1 = bx1.max(tx + tile.w as i64);
            by1 = by1.max(ty + tile.h as i64);
        }
        if placed.is_empty() {
            return;
        }
        // The union of the glyphs' halos over the label's box, clipped to the page (and
        // to the rows being drawn), in paper over everything drawn so far.
        self.flush_gray();
        let (pw, ph) = (i64::from(self.width()), i64::from(self.height()));
        let (cx0, cx1) = (bx0.max(0), bx1.min(pw));
        let cy0 = by0.max(0).max(self.rows.0 as i64);
        let cy1 = by1.min(ph).min(self.rows.1 as i64);
        if cx0 < cx1 && cy0 < cy1 {
            // The merged rows `bw` apart, with room for a tile's padding past the box (a
            // tile's row of `stride < w + LANES` pixels from at most `bw − w` on), so
            // that each tile's padded rows are merged in whole groups of `LANES` (a zero
            // changes no maximum).
            let bw = (bx1 - bx0) as usize + LANES;
            let merged = &mut self.halo_scratch.merged;
            merged.clear();
            merged.resize(bw * (by1 - by0) as usize, 0);
            for (tx, ty, key) in placed {
                let Some(Some(tile)) = self.halos.get(key) else {
                    continue;
                };
                let s = tile.stride;
                let start = (ty - by0) as usize * bw + (tx - bx0) as usize;
                for (j, row) in tile.cov.chunks_exact(s).enumerate() {
                    let m = &mut merged[start + j * bw..start + j * bw + s];
                    for (m8, c8) in m.chunks_exact_mut(LANES).zip(row.chunks_exact(LANES)) {
                        let v = |b: &[u8]| {
                            let mut a = [0u8; 16];
                            a[..LANES].copy_from_slice(b);
                            u8x16::new(a)
                        };
                        let x = v(m8).max(v(c8)).to_array();
                        m8.copy_from_slice(&x[..LANES]);
                    }
                }
            }
            let stride = pw as usize;
            let first = self.first;
            let data = pixels(&mut self.mask, &mut self.band_buf, self.banded);
            for y in cy0..cy1 {
                let src = (y - by0) as usize * bw + (cx0 - bx0) as usize;
                let dst = (y as usize - first) * stride + cx0 as usize;
                let n = (cx1 - cx0) as usize;
                composite_row(&mut data[dst..dst + n], &merged[src..src + n], Ink::Paper);
            }
        }
    }

    /// Makes the tile of `key` if it is not cached yet: the coverage of a glyph when
    /// `key.r == 0`, else the glyph's halo `key.r` pixels wide on each side (see
    /// [`HaloKey`]). A glyph without outline is cached as `None`. The one place that
    /// fills the cache; it is emptied between pages when full ([`RasterPage::trim_tiles`]),
    /// never while a label is placed (its tiles are looked up after all are made).
    ///
    /// Gives the tile's corner (`None` for a glyph without outline).
    fn halo_tile(&mut self, key: HaloKey) -> Option<(i64, i64)> {
        if let Some(tile) = self.halos.get(&key) {
            return tile.as_ref().map(|t| (t.x0, t.y0));
        }
        let font = &self.font;
        let outline = self
            .outlines
            .entry(key.glyph)
            .or_insert_with(|| font.outline(GlyphId(key.glyph)))
            .clone();
        let em = f32::from_bits(key.em);
        let sub = [f32::from(key.sub[0]) / 4.0, f32::from(key.sub[1]) / 4.0];
        let tile = outline.map(|outline| {
            if key.r == 0 {
                HaloTile::glyph(font, GlyphId(key.glyph), em, sub, outline)
            } else {
                let upem = font.units_per_em().unwrap_or(2048.0);
                let r = f32::from_bits(key.r);
                HaloTile::make(&outline, em / upem, r, sub, &mut self.capsules)
            }
        });
        let corner = tile.as_ref().map(|t| (t.x0, t.y0));
        self.halos.insert(key, tile);
        corner
    }
}

/// `x.round()` (half away from zero) as an integer, for `|x| < 2^31` (no call to the
/// library's `roundf`): the truncation `t` and the exact remainder `x − t`.
#[inline]
fn round_half_away(x: f32) -> i64 {
    let t = x as i32;
    let f = x - t as f32;
    i64::from(t) + i64::from(f >= 0.5) - i64::from(f <= -0.5)
}

/// Glyphs and glyph halos kept from page to page at most (a few kilobytes each); the
/// cache is emptied between pages when full.
const MAX_HALO_TILES: usize = 4096;

/// The glyph and halo caches' hasher: a multiply-rotate of the key's few integers (the
/// standard SipHash was 1.4 % of a page's CPU, looking tiles up glyph after glyph). The
/// keys are the program's own, not an adversary's; only lookups use it (no order).
#[derive(Clone, Copy, Default)]
struct KeyHash;

impl std::hash::BuildHasher for KeyHash {
    type Hasher = KeyHasher;
    fn build_hasher(&self) -> KeyHasher {
        KeyHasher(0)
    }
}

struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    #[inline]
    fn write_u8(&mut self, v: u8) {
        self.write_u64(u64::from(v));
    }
    #[inline]
    fn write_u16(&mut self, v: u16) {
        self.write_u64(u64::from(v));
    }
    #[inline]
    fn write_u32(&mut self, v: u32) {
        self.write_u64(u64::from(v));
    }
    #[inline]
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    #[inline]
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
    #[inline]
    fn finish(&self) -> u64 {
        // The high bits are the mixed ones; the table indexes with the low bits.
        self.0.rotate_left(26)
    }
}

/// A glyph's halo: its glyph id, em size and halo half width in pixels (bits of the
/// f32s), and the glyph origin's quarter-pixel offset from a whole pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct HaloKey {
    glyph: u16,
    em: u32,
    r: u32,
    sub: [u8; 2],
}

/// The coverage of a glyph's halo, its top left corner relative to the whole pixel of
/// the glyph's origin.
struct HaloTile {
    x0: i64,
    y0: i64,
    w: usize,
    h: usize,
    /// The rows' distance in `cov`: `w`, or for a glyph's own coverage `w` rounded up
    /// to whole groups of [`LANES`], the columns past `w` zero ([`RasterPage::draw_glyphs`]).
    stride: usize,
    cov: Vec<u8>,
}

/// A glyph's coverage rows are composited in groups of this many pixels.
const LANES: usize = 8;

/// Scratch of the halos.
#[derive(Default)]
struct HaloScratch {
    placed: Vec<(i64, i64, HaloKey)>,
    merged: Vec<u8>,
}

impl HaloTile {
    /// The outline (font units, y up) scaled by `scale` to pixels (y down), its origin
    /// at `sub` in the tile's first pixel's frame, stroked `r` pixels on each side.
    fn make(
        outline: &Outline,
        scale: f32,
        r: f32,
        sub: [f32; 2],
        capsules: &mut Capsules,
    ) -> HaloTile {
        // ab_glyph gives the box as (x_min, y_max), (x_max, y_min): take both ends.
        let b = outline.bounds;
        let (top, bottom) = (b.min.y.max(b.max.y), b.min.y.min(b.max.y));
        let pad = r + 2.0;
        let x0 = (sub[0] + b.min.x.min(b.max.x) * scale - pad).floor();
        let y0 = (sub[1] - top * scale - pad).floor();
        let x1 = (sub[0] + b.min.x.max(b.max.x) * scale + pad).ceil();
        let y1 = (sub[1] - bottom * scale + pad).ceil();
        let (w, h) = ((x1 - x0).max(0.0) as usize, (y1 - y0).max(0.0) as usize);
        let p = |q: ab_glyph::Point| [sub[0] + q.x * scale - x0, sub[1] - q.y * scale - y0];
        let mut flat = Flattener::default();
        let mut last: Option<ab_glyph::Point> = None;
        for c in &outline.curves {
            let start = match *c {
                OutlineCurve::Line(a, _)
                | OutlineCurve::Quad(a, _, _)
                | OutlineCurve::Cubic(a, ..) => a,
            };
            if last != Some(start) {
                flat.close(capsules);
                flat.move_to(p(start), capsules);
            }
            match *c {
                OutlineCurve::Line(_, e) => {
                    flat.line_to(p(e), capsules);
                    last = Some(e);
                }
                OutlineCurve::Quad(_, q, e) => {
                    flat.quad_to(p(q), p(e), capsules);
                    last = Some(e);
                }
                OutlineCurve::Cubic(_, q, r, e) => {
                    flat.cubic_to(p(q), p(r), p(e), capsules);
                    last = Some(e);
                }
            }
        }
        flat.close(capsules);
        let mut cov = vec![0u8; w * h];
        let mut dirty = Dirty::new(w.max(1), h.max(1));
        // Black on a blank tile: the coverage itself.
        capsules.stroke(
            r,
            &mut Target {
                data: &mut cov,
                width: w,
                height: h,
                ink: Ink::Black,
                rows: (0, h),
                first: 0,
                dirty: &mut dirty,
                layer: None,
            },
        );
        // Rows padded with zeros to whole groups of `LANES` ([`RasterPage::draw_halo`]).
        let stride = w.next_multiple_of(LANES);
        let cov = if stride == w {
            cov
        } else {
            let mut padded = vec![0u8; stride * h];
            for (to, from) in padded.chunks_exact_mut(stride).zip(cov.chunks_exact(w)) {
                to[..w].copy_from_slice(from);
            }
            padded
        };
        HaloTile {
            x0: x0 as i64,
            y0: y0 as i64,
            w,
            h,
            stride,
            cov,
        }
    }

    /// The coverage of glyph `id` at em size `em` pixels, its origin at `sub` in the
    /// first pixel's frame, as ab_glyph draws it.
    fn glyph(
        font: &FontRef<'static>,
        id: GlyphId,
        em: f32,
        sub: [f32; 2],
        outline: Outline,
    ) -> HaloTile {
        let glyph = Glyph {
            id,
            scale: font::px_scale(font, em),
            position: point(sub[0], sub[1]),
        };
        let scale_factor = font.as_scaled(glyph.scale).scale_factor();
        let outlined = OutlinedGlyph::new(glyph, outline, scale_factor);
        let b = outlined.px_bounds();
        let (x0, y0) = (b.min.x as i64, b.min.y as i64);
        let w = (b.max.x as i64 - x0).max(0) as usize;
        let h = (b.max.y as i64 - y0).max(0) as usize;
        // Rows padded with zeros to whole groups of `LANES`.
        let stride = w.next_multiple_of(LANES);
        let mut cov = vec![0u8; stride * h];
        outlined.draw(|gx, gy, c| {
            let (x, y) = (gx as usize, gy as usize);
            if x < w && y < h {
                cov[y * stride + x] = (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
            }
        });
        HaloTile {
            x0,
            y0,
            w,
            h,
            stride,
            cov,
        }
    }
}

/// Outline curves as line segments within [`FLATNESS`] pixels of them.
#[derive(Default)]
struct Flattener {
    start: [f32; 2],
    at: [f32; 2],
    open: bool,
}

/// How far a flattened outline may stray from the curve, in pixels.
const FLATNESS: f32 = 0.1;

impl Flattener {
    fn move_to(&mut self, a: [f32; 2], _: &mut Capsules) {
        (self.start, self.at, self.open) = (a, a, true);
    }

    fn line_to(&mut self, a: [f32; 2], out: &mut Capsules) {
        out.push(self.at, a);
        self.at = a;
    }

    /// A quadratic is within `|p0 − 2p1 + p2| / (8n²)` of its `n` chords.
    fn quad_to(&mut self, q: [f32; 2], a: [f32; 2], out: &mut Capsules) {
        let p0 = self.at;
        let dd = (p0[0] - 2.0 * q[0] + a[0]).hypot(p0[1] - 2.0 * q[1] + a[1]);
        let n = ((dd / (8.0 * FLATNESS)).sqrt().ceil() as usize).clamp(1, 64);
        for i in 1..=n {
            let t = i as f32 / n as f32;
            let u = 1.0 - t;
            let b = [
                u * u * p0[0] + 2.0 * u * t * q[0] + t * t * a[0],
                u * u * p0[1] + 2.0 * u * t * q[1] + t * t * a[1],
            ];
            self.line_to(if i == n { a } else { b }, out);
        }
    }

    /// A cubic is within `3·max|second differences| / (4n²)` of its `n` chords.
    fn cubic_to(&mut self, q: [f32; 2], r: [f32; 2], a: [f32; 2], out: &mut Capsules) {
        let p0 = self.at;
        let d1 = (p0[0] - 2.0 * q[0] + r[0]).hypot(p0[1] - 2.0 * q[1] + r[1]);
        let d2 = (q[0] - 2.0 * r[0] + a[0]).hypot(q[1] - 2.0 * r[1] + a[1]);
        let n = ((0.75 * d1.max(d2) / FLATNESS).sqrt().ceil() as usize).clamp(1, 64);
        for i in 1..=n {
            let t = i as f32 / n as f32;
            let u = 1.0 - t;
            let (b0, b1, b2, b3) = (u * u * u, 3.0 * u * u * t, 3.0 * u * t * t, t * t * t);
            let b = [
                b0 * p0[0] + b1 * q[0] + b2 * r[0] + b3 * a[0],
                b0 * p0[1] + b1 * q[1] + b2 * r[1] + b3 * a[1],
            ];
            self.line_to(if i == n { a } else { b }, out);
        }
    }

    fn close(&mut self, out: &mut Capsules) {
        if self.open && self.at != self.start {
            self.line_to(self.start, out);
        }
        self.open = false;
    }
}

/// `[x0, y0, x1, y1]` when the polygon is an axis-aligned rectangle (four corners, in
/// either turning order, from any corner).
fn axis_rect(points: &[PagePoint]) -> Option<[f64; 4]> {
    let [a, b, c, d] = points else {
        return None;
    };
    let horizontal_first = a[1] == b[1] && b[0] == c[0] && c[1] == d[1] && d[0] == a[0];
    let vertical_first = a[0] == b[0] && b[1] == c[1] && c[0] == d[0] && d[1] == a[1];
    (horizontal_first || vertical_first).then(|| {
        [
            a[0].min(c[0]),
            a[1].min(c[1]),
            a[0].max(c[0]),
            a[1].max(c[1]),
        ]
    })
}

impl Canvas for RasterPage {
    fn stroke_polyline(&mut self, points: &[PagePoint], width: f64) {
        self.stroke_paths(std::iter::once(points), width);
    }

    fn stroke_polylines(&mut self, lines: &[Vec<PagePoint>], width: f64) {
        self.stroke_paths(lines.iter().map(Vec::as_slice), width);
    }

    fn stroke_rect(&mut self, rect: [f64; 4], width: f64) {
        for [x0, y0, x1, y1] in self.rect_sides(rect, width) {
            self.fill_rect_px(x0, y0, x1, y1);
        }
    }

    fn fill_polygon(&mut self, points: &[PagePoint]) {
        if points.len() < 3 {
            return;
        }
        if let Some([x0, y0, x1, y1]) = axis_rect(points) {
            // A box (a paper panel, a band): exact area coverage, no scan conversion.
            let k = self.px_per_pt;
            self.fill_rect_px(x0 * k, y0 * k, x1 * k, y1 * k);
            return;
        }
        if let Some(path) = self.polygon_path(points) {
            self.fill(&path);
        }
    }

    fn circle(&mut self, center: PagePoint, radius: f64, width: Option<f64>) {
        let (x, y) = self.px(center);
        let r = (radius * self.px_per_pt) as f32;
        match width {
            // A disc: a dot of radius r.
            None => {
                self.capsules.push([x, y], [x, y]);
                let (capsules, mut target) = self.target();
                capsules.stroke(r, &mut target);
            }
            Some(w) => {
                let h = (0.5 * w * self.px_per_pt) as f32;
                let (capsules, mut target) = self.target();
                capsules.ring([x, y], r, h, &mut target);
            }
        }
    }

    fn set_ink(&mut self, ink: Ink) {
        self.ink = ink;
    }

    fn text(&mut self, pos: PagePoint, size: f64, anchor: Anchor, text: &str, halo: f64) {
        if halo > 0.0 {
            // The glyph outlines stroked in paper, under the glyphs.
            self.halo(pos, size, anchor, text, halo);
        }
        let mut placed = std::mem::take(&mut self.halo_scratch.placed);
        self.place_label(pos, size, anchor, text, None, &mut placed);
        self.draw_glyphs(&placed);
        self.halo_scratch.placed = placed;
    }
}

impl RasterPage {
    /// Draws a label's glyphs in the current ink from their placed tiles
    /// ([`RasterPage::place_label`]).
    fn draw_glyphs(&mut self, placed: &[(i64, i64, HaloKey)]) {
        let ink = self.ink;
        let (w, h) = (i64::from(self.width()), i64::from(self.height()));
        let (r0, r1) = (self.rows.0 as i64, (self.rows.1 as i64).min(h));
        for (tx, ty, key) in placed {
            // The glyph's coverage at its quarter-pixel position, made once and kept.
            let Some(Some(tile)) = self.halos.get(key) else {
                continue;
            };
            let (tx, ty) = (*tx, *ty);
            let (cx0, cy0) = (tx.max(0), ty.max(r0));
            let (cx1, cy1) = ((tx + tile.w as i64).min(w), (ty + tile.h as i64).min(r1));
            if cx0 >= cx1 || cy0 >= cy1 {
                continue;
            }
            if ink != Ink::Paper {
                self.dirty
                    .mark_px(cx0 as usize, cy0 as usize, cx1 as usize, cy1 as usize);
            }
            let first = self.first as i64;
            let data = pixels(&mut self.mask, &mut self.band_buf, self.banded);
            let n = (cx1 - cx0) as usize;
            let (stride, rows) = (tile.stride, (cy1 - cy0) as usize);
            let dst0 = ((cy0 - first) * w + cx0) as usize;
            let src0 = (cy0 - ty) as usize * stride + (cx0 - tx) as usize;
            // An unclipped row is composited with its padding, whole groups of `LANES`
            // (coverage 0 leaves a pixel as it is in every ink: the same bytes), where
            // the last row's groups stay in the buffer.
            let whole =
                cx0 == tx && n == tile.w && dst0 + (rows - 1) * w as usize + stride <= data.len();
            if whole {
                let src = tile.cov[src0..src0 + rows * stride].chunks_exact(stride);
                for (j, cov) in src.enumerate() {
                    let dst = dst0 + j * w as usize;
                    composite_groups(&mut data[dst..dst + stride], cov, ink);
                }
                continue;
            }
            for y in cy0..cy1 {
                let src = (y - ty) as usize * stride + (cx0 - tx) as usize;
                let dst = ((y - first) * w + cx0) as usize;
                composite_row(&mut data[dst..dst + n], &tile.cov[src..src + n], ink);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::draw;
    use coupler_layout::{DisplayList, Primitive};

    /// A rectangle's rows filled with the row before's result where it applies are the
    /// rows each blended on its own: tall and wide rectangles with fractional edges (a
    /// first and last row of their own `cy`) over rows that repeat, in runs, and change,
    /// in black and grays.
    #[test]
    fn rect_rows_remembered_are_each_blended() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            seed = crate::xorshift(seed);
            seed
        };
        let stride = 40;
        let mut remembered = 0;
        for case in 0..400 {
            let n = 1 + (next() % 20) as usize;
            let i0 = (next() % (stride - n) as u64) as usize;
            let rows = 1 + (next() % 30) as usize;
            // Rows in runs of equal bytes: a few values, repeated.
            let mut page = vec![0u8; rows * stride];
            let mut fill = 0u8;
            for row in page.chunks_exact_mut(stride) {
                if next() % 4 == 0 {
                    fill = [0, 0, 255, 90, 200][(next() % 5) as usize];
                }
                row.fill(fill);
                if next() % 6 == 0 {
                    row[i0 + (next() as usize % n)] = next() as u8;
                }
            }
            let (x0, x1) = (
                0.3 * (next() % 4) as f64,
                n as f64 - 0.25 * (next() % 4) as f64,
            );
            let columns: Vec<f64> = (0..n)
                .map(|i| (x1.min(i as f64 + 1.0) - x0.max(i as f64)).max(0.0))
                .collect();
            let (y0, y1) = (
                0.4 * (next() % 3) as f64,
                rows as f64 - 0.3 * (next() % 3) as f64,
            );
            let cy = |j: usize| (y1.min(j as f64 + 1.0) - y0.max(j as f64)).max(0.0);
            let ink = [Ink::Black, Ink::Gray(150), Ink::Gray(80)][case % 3];
            let mut reference = page.clone();
            for (j, row) in reference.chunks_exact_mut(stride).enumerate() {
                rect_span(&mut row[i0..i0 + n], &columns, cy(j), ink);
            }
            fill_rect_rows(&mut page, stride, i0, &columns, cy, ink);
            assert_eq!(page, reference, "case {case}");
            remembered += usize::from(rows > 2 && n <= RECT_MEMO);
        }
        assert!(remembered > 100);
    }

    /// A page with every kind of primitive in black, grays and paper.
    fn sample() -> DisplayList {
        let mut dl = DisplayList::new(300.0, 200.0);
        let wave: Vec<PagePoint> = (0..200)
            .map(|i| {
                [
                    10.0 + i as f64 * 1.4,
                    100.0 + 60.0 * (i as f64 * 0.07).sin(),
                ]
            })
            .collect();
        dl.items.push(Primitive::Ink(Ink::Gray(150)));
        dl.items.push(Primitive::Polylines {
            lines: wave.chunks(7).map(<[PagePoint]>::to_vec).collect(),
            width: 1.25,
        });
        dl.items.push(Primitive::Ink(Ink::Black));
        dl.items.push(Primitive::Polyline {
            points: vec![[5.0, 5.0], [295.0, 195.0]],
            width: 0.75,
        });
        dl.items.push(Primitive::Rect {
            rect: [20.0, 20.0, 280.0, 180.0],
            width: 0.6,
        });
        dl.items.push(Primitive::Ink(Ink::Gray(80)));
        dl.items.push(Primitive::Circle {
            center: [150.0, 100.0],
            radius: 40.0,
            width: Some(0.4),
        });
        dl.items.push(Primitive::Polygon {
            points: vec![[200.0, 40.0], [230.0, 45.0], [210.0, 70.0]],
        });
        dl.items.push(Primitive::Ink(Ink::Black));
        dl.items.push(Primitive::Text {
            pos: [120.0, 105.0],
            size: 9.0,
            anchor: coupler_layout::Anchor::Start,
            text: "(1.875, −1.25)".into(),
            halo: 1.6,
        });
        // Alone in the bottom margin: marked by nothing else.
        dl.items.push(Primitive::Text {
            pos: [25.0, 195.0],
            size: 7.0,
            anchor: coupler_layout::Anchor::Start,
            text: "A 120°".into(),
            halo: 0.0,
        });
        dl.items.push(Primitive::Ink(Ink::Gray(150)));
        dl.items.push(Primitive::Polygon {
            points: vec![[250.0, 185.0], [270.0, 186.0], [262.0, 198.0]],
        });
        dl
    }

    fn decode(bytes: &[u8]) -> Vec<u8> {
        let mut r = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        buf
    }

    #[test]
    fn only_drawn_blocks_are_encoded_and_cleared_and_nothing_is_lost() {
        let dl = sample();
        for dpi in [72.0, 150.0, 300.0] {
            let k = dpi / 72.0;
            let (w, h) = ((300.0 * k) as u32, (200.0 * k) as u32);
            let mut page = RasterPage::new(w, h, dpi).unwrap();
            for round in 0..2 {
                draw(&dl, &mut page);
                let gray = page.to_gray();
                // The block-skipping encoder, the whole-buffer encoder and the best one
                // all give the drawn pixels.
                let mut fast = Vec::new();
                page.finish_png(&mut fast).unwrap();
                assert_eq!(decode(&fast), gray, "dpi {dpi} round {round}");
                let mut full = Vec::new();
                encode_png(&gray, w, h, dpi, false, &mut full).unwrap();
                assert_eq!(decode(&full), gray);
                let mut best = Vec::new();
                page.finish_png_with(PngCompression::Best, &mut best)
                    .unwrap();
                assert_eq!(decode(&best), gray);
                assert!(best.len() < fast.len(), "{} {}", best.len(), fast.len());
                // Clearing only the drawn blocks leaves no ink anywhere.
                page.clear();
                assert!(page.ink().iter().all(|&x| x == 0), "dpi {dpi}");
            }
            // The same page drawn on a fresh buffer is the same.
            let mut fresh = RasterPage::new(w, h, dpi).unwrap();
            draw(&dl, &mut fresh);
            draw(&dl, &mut page);
            assert_eq!(fresh.ink(), page.ink());
        }
    }

    /// The scan converter and the gray layer compiled for AVX2, BMI1 and BMI2 (where the
    /// processor has them) draw a page of every kind of primitive as their baseline
    /// instruction set's code does, byte for byte: the ink, and the PNG.
    #[test]
    fn both_instruction_sets_draw_the_same_page() {
        let dl = sample();
        for dpi in [72.0, 150.0, 300.0, 600.0] {
            let k = dpi / 72.0;
            let (w, h) = ((300.0 * k) as u32, (200.0 * k) as u32);
            let [(fast_ink, fast_png), (base_ink, base_png)] = [false, true].map(|baseline| {
                crate::cpu::baseline_only(baseline, || {
                    let mut page = RasterPage::new(w, h, dpi).unwrap();
                    draw(&dl, &mut page);
                    let ink = page.ink().to_vec();
                    let mut png = Vec::new();
                    page.finish_png(&mut png).unwrap();
                    (ink, png)
                })
            });
            assert!(fast_ink.iter().any(|&v| v != 0), "dpi {dpi}");
            assert!(fast_ink == base_ink, "dpi {dpi}");
            assert!(fast_png == base_png, "dpi {dpi}");
        }
    }

    /// The image data of a PNG: its IDAT chunks' bytes, in order.
    fn idat(png: &[u8]) -> Vec<u8> {
        let (mut at, mut data) = (8, Vec::new());
        while at + 8 <= png.len() {
            let len = u32::from_be_bytes(png[at..at + 4].try_into().unwrap()) as usize;
            if &png[at + 4..at + 8] == b"IDAT" {
                data.extend_from_slice(&png[at + 8..at + 8 + len]);
            }
            at += 12 + len;
        }
        data
    }

    /// The fast PNG is the one written before blank rows became precomputed runs: its
    /// image data is `fdeflate`'s stream of the whole Up-filtered rows, byte for byte (so
    /// pages kept as regression images do not change), and it decodes to the drawn pixels.
    /// Pages: the sample (blank rows above, between and below ink), the same with one
    /// dot in the last row, and a blank page.
    #[test]
    fn the_fast_png_is_fdeflates_stream_of_the_up_filtered_rows() {
        for (dpi, kind) in [(72.0, 0), (300.0, 0), (150.0, 1), (72.0, 2)] {
            let k = dpi / 72.0;
            let (w, h) = ((300.0 * k) as u32, (200.0 * k) as u32);
            let mut page = RasterPage::new(w, h, dpi).unwrap();
            if kind < 2 {
                draw(&sample(), &mut page);
            }
            if kind == 1 {
                page.fill_rect_px(
                    f64::from(w) - 3.0,
                    f64::from(h) - 1.0,
                    f64::from(w),
                    f64::from(h),
                );
            }
            let gray = page.to_gray();
            let png = page.take_png(PngCompression::Fast).unwrap();
            let want = reference_stream(&gray, w as usize, h as usize);
            assert!(idat(&png) == want, "dpi {dpi}, page {kind}: streams differ");
            assert_eq!(decode(&png), gray, "dpi {dpi}, page {kind}");
            assert!(page.ink().iter().all(|&x| x == 0), "left blank");
        }
    }

    /// A page's fast PNG written over a buffer given back ([`reuse_png_buffer`]) is the
    /// one written into a new buffer, whatever the old buffer holds and however long it
    /// is (shorter than the PNG's header, than the PNG, or longer), drawn whole or band
    /// by band; the buffer is taken (the thread keeps no other).
    #[test]
    fn a_reused_buffer_makes_the_same_png() {
        let (w, h, dpi) = (1250u32, 833u32, 300.0);
        let mut page = RasterPage::new(w, h, dpi).unwrap();
        draw(&sample(), &mut page);
        let want = page.take_png(PngCompression::Fast).unwrap();
        assert!(want.len() > 1000, "a page with ink");
        let dl = sample();
        for len in [
            0,
            10,
            57,
            want.len() / 2,
            want.len() - 1,
            want.len() + 999,
            3 * want.len(),
        ] {
            for banded in [false, true] {
                let mut old = Vec::with_capacity(SPARE_LEAST);
                old.resize(len, 0xa5);
                reuse_png_buffer(old);
                assert_eq!(SPARE.with_borrow(Vec::len), 1, "kept");
                let got = if banded {
                    page.render_png(&dl, PngCompression::Fast).unwrap().0
                } else {
                    draw(&dl, &mut page);
                    page.take_png(PngCompression::Fast).unwrap()
                };
                assert!(
                    got == want,
                    "over {len} bytes (banded: {banded}): PNGs differ"
                );
                assert_eq!(SPARE.with_borrow(Vec::len), 0, "taken");
            }
        }
        // Small buffers are not kept.
        reuse_png_buffer(vec![1; 100]);
        assert_eq!(SPARE.with_borrow(Vec::len), 0, "a small buffer kept");
    }

    /// fdeflate's zlib stream of a `w × h` gray image, every row filtered Up: what the
    /// fast PNG's stream must equal byte for byte.
    fn reference_stream(gray: &[u8], w: usize, h: usize) -> Vec<u8> {
        let mut z = fdeflate::Compressor::new(Vec::new()).unwrap();
        let mut row = vec![2u8; w + 1];
        for j in 0..h {
            for x in 0..w {
                let above = if j == 0 { 0 } else { gray[(j - 1) * w + x] };
                row[1 + x] = gray[j * w + x].wrapping_sub(above);
            }
            z.write_data(&row).unwrap();
        }
        z.finish().unwrap()
    }

    /// The row compositor is the pixel one, for every ink level, coverage and ink under.
    #[test]
    fn composite_groups_is_composite_per_pixel() {
        // Every level under every coverage, then levels of which about half are 0
        // (groups of paper, and groups mixing paper and ink), under every coverage.
        let mut s = 1u64;
        let mixed = (0..256 * 256).map(|_| {
            s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            if s >> 63 == 0 { 0 } else { (s >> 40) as u8 }
        });
        let unders: [Vec<u8>; 2] = [
            (0..=255u8).flat_map(|d| [d; 256]).collect(),
            mixed.collect(),
        ];
        let cov: Vec<u8> = (0..256 * 256)
            .map(|i| (i as u8).wrapping_mul(151))
            .collect();
        for under in unders {
            let inks = (0..=255u8).map(Ink::Gray).chain([Ink::Black, Ink::Paper]);
            for ink in inks {
                let mut got = under.clone();
                for (a, b) in [(0, 8), (8, 304), (304, 65_536)] {
                    composite_groups(&mut got[a..b], &cov[a..b], ink);
                }
                for i in 0..under.len() {
                    assert_eq!(got[i], composite(under[i], cov[i], ink), "{ink:?} at {i}");
                }
            }
        }
    }

    #[test]
    fn composite_row_is_composite_per_pixel() {
        let under: Vec<u8> = (0..=255u8).flat_map(|d| [d; 256]).collect();
        let cov: Vec<u8> = (0..256 * 256).map(|i| i as u8).collect();
        let inks = (0..=255u8).map(Ink::Gray).chain([Ink::Black, Ink::Paper]);
        for ink in inks {
            let mut got = under.clone();
            // Odd lengths and offsets too: the vector loops' remainders.
            for (a, b) in [(0, 7), (7, 300), (300, 65_536)] {
                composite_row(&mut got[a..b], &cov[a..b], ink);
            }
            for i in 0..under.len() {
                assert_eq!(got[i], composite(under[i], cov[i], ink), "{ink:?} at {i}");
            }
        }
    }

    /// Marks exactly on the ink (no widening) with ink in the bytes after the last whole
    /// 8-byte word of a row, then rows marked elsewhere only: each row's filtered words
    /// and tail are its own (nothing left from an earlier row), byte for byte `fdeflate`'s
    /// stream of the whole filtered rows, for several widths (tails of 0 to 7 bytes).
    #[test]
    fn rows_after_ink_in_the_row_tail_are_their_own() {
        for w in 13usize..=21 {
            let h = 6;
            let mut ink = vec![0u8; w * h];
            let mut dirty = Dirty::new(w, h);
            // Row 0: ink at the right edge; rows 2 and 4: ink at the left only.
            ink[w - 2] = 200;
            dirty.mark_px(w - 3, 0, w, 1);
            ink[2 * w + 3] = 50;
            ink[4 * w + 9] = 7;
            dirty.mark_px(0, 2, 8, 3);
            dirty.mark_px(8, 4, 16.min(w), 5);
            let gray: Vec<u8> = ink.iter().map(|&x| !x).collect();
            let png = write_png_fast(&mut ink, w as u32, h as u32, 72.0, &dirty, true, 64).unwrap();
            assert_eq!(decode(&png), gray, "width {w}");
            assert!(
                idat(&png) == reference_stream(&gray, w, h),
                "width {w}: streams differ"
            );
            assert!(ink.iter().all(|&x| x == 0), "width {w}: left blank");
        }
    }

    /// A page wider than 8192 px (a landscape tabloid at the highest DPI a spec may ask,
    /// 1200, is 20,400 px): drawn, encoded and decoded back to what was drawn, the page
    /// left blank. The block marks used to stop at 8192 px (`--dpi 1200` panicked).
    #[test]
    fn pages_wider_than_8192_px_encode() {
        let (w, h) = (20_400u32, 24u32);
        let mut page = RasterPage::new(w, h, 1200.0).unwrap();
        let mut dl = DisplayList::new(f64::from(w) * 0.06, f64::from(h) * 0.06);
        dl.items.push(Primitive::Polyline {
            points: vec![[1.0, 0.5], [1210.0, 1.0]],
            width: 0.3,
        });
        draw(&dl, &mut page);
        let gray = page.to_gray();
        let (wu, hu) = (w as usize, h as usize);
        let inked = |x0: usize, x1: usize| {
            (0..hu).any(|j| gray[j * wu + x0..j * wu + x1].iter().any(|&g| g < 255))
        };
        assert!(
            inked(9_000, 9_100) && inked(20_000, 20_100),
            "ink past 8192 px"
        );
        let png = page.take_png(PngCompression::Fast).unwrap();
        assert_eq!(decode(&png), gray);
        assert!(page.ink().iter().all(|&x| x == 0), "left blank");
    }

    /// A buffer turned from portrait to landscape (and back) draws a page exactly as a
    /// fresh buffer of that shape does, with no ink left from the other shape.
    #[test]
    fn a_reshaped_buffer_draws_like_a_fresh_one() {
        let wide = sample();
        let mut tall = DisplayList::new(200.0, 300.0);
        tall.items = wide.items.clone();
        let (w, h) = (300u32, 200u32);
        let mut page = RasterPage::new(h, w, 72.0).unwrap();
        draw(&tall, &mut page);
        for (dl, (pw, ph)) in [(&wide, (w, h)), (&tall, (h, w)), (&wide, (w, h))] {
            assert!(page.reshape(pw, ph));
            assert_eq!((page.width(), page.height()), (pw, ph));
            assert!(page.ink().iter().all(|&x| x == 0));
            draw(dl, &mut page);
            let mut fresh = RasterPage::new(pw, ph, 72.0).unwrap();
            draw(dl, &mut fresh);
            assert_eq!(fresh.ink(), page.ink());
            let (mut a, mut b) = (Vec::new(), Vec::new());
            page.finish_png(&mut a).unwrap();
            fresh.finish_png(&mut b).unwrap();
            assert_eq!(a, b);
        }
        // Another pixel count: only cleared.
        assert!(!page.reshape(100, 100));
        assert_eq!((page.width(), page.height()), (w, h));
        assert!(page.ink().iter().all(|&x| x == 0));
    }

    #[test]
    fn png_compression_parses() {
        assert_eq!("Best".parse(), Ok(PngCompression::Best));
        assert_eq!("fast".parse(), Ok(PngCompression::Fast));
        assert!("max".parse::<PngCompression>().is_err());
    }
}

#[cfg(test)]
mod halo_tests {
    use super::*;

    /// A label drawn when the glyph and halo cache is one tile short of full is the
    /// label drawn on a fresh page: the cache used to be emptied while a label's halo
    /// was placed, which dropped the halos of the glyphs placed before.
    #[test]
    fn a_full_tile_cache_does_not_drop_a_labels_halos() {
        let (w, h) = (400u32, 80u32);
        let text = "(−1.875, 2.5) S 35°";
        let label = |page: &mut RasterPage| {
            page.fill_rect_px(0.0, 0.0, f64::from(w), f64::from(h));
            page.text([8.0, 12.0], 9.0, Anchor::Start, text, 1.6);
            page.to_gray()
        };
        let want = label(&mut RasterPage::new(w, h, 300.0).unwrap());
        let mut page = RasterPage::new(w, h, 300.0).unwrap();
        for g in 0..MAX_HALO_TILES - 1 {
            let key = HaloKey {
                glyph: 60_000,
                em: g as u32,
                r: 1,
                sub: [0, 0],
            };
            page.halos.insert(key, None);
        }
        assert_eq!(label(&mut page), want);
        // Emptied between pages.
        page.clear();
        assert!(page.halos.is_empty());
    }

    /// A glyph's quarter-pixel position in integers is the float one: every quarter
    /// and eighth of a pixel near 0 and near the bounds, their neighbours, and a
    /// sweep of odd values.
    #[test]
    fn quarter_pixels_in_integers_are_the_float_ones() {
        let mut xs = Vec::new();
        for k in -4000i32..=4000 {
            for base in [0.0f32, 1.0e6, -1.0e6, 9.99e6, -9.99e6] {
                let x = base + k as f32 / 8.0;
                xs.extend([x, x.next_up(), x.next_down()]);
            }
        }
        let mut v = 0.123f32;
        for _ in 0..200_000 {
            v = (v * 1.618_034 + 0.377).rem_euclid(2.0e7) - 1.0e7;
            xs.push(v);
        }
        xs.extend([1.0e7, -1.0e7, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, -0.0]);
        for g in xs.into_iter().filter(|g| g.abs() <= 1e7) {
            let q = (g * 4.0).round();
            let i = (q / 4.0).floor();
            let (qi, ii) = (
                round_half_away(g * 4.0),
                round_half_away(g * 4.0).div_euclid(4),
            );
            assert_eq!(qi as f32, q, "{g}");
            assert_eq!(ii as f32, i, "{g}");
            assert_eq!(qi.rem_euclid(4) as u8, (q - 4.0 * i) as u8, "{g}");
        }
    }

    /// A label's halo, made from cached glyph halos at quarter-pixel positions, is the
    /// text's outline stroked in paper at its exact position, but for the quarter-pixel
    /// shift of its edge.
    #[test]
    fn a_halo_is_the_outline_stroked_in_paper() {
        let (w, h) = (500u32, 120u32);
        for (size, halo, x, y) in [
            (9.0, 1.6, 10.0, 20.0),
            (6.0, 1.0, 10.3, 14.71),
            (7.5, 1.6, 3.1, 22.2),
        ] {
            let text = "(−1.875, 2.5) S 35°";
            let mut page = RasterPage::new(w, h, 300.0).unwrap();
            page.fill_rect_px(0.0, 0.0, w as f64, h as f64);
            page.halo([x, y], size, Anchor::Start, text, halo);
            // The reference: the whole outline flattened and stroked at once.
            let mut reference = RasterPage::new(w, h, 300.0).unwrap();
            reference.fill_rect_px(0.0, 0.0, w as f64, h as f64);
            let k = 300.0 / 72.0;
            let p = |q: [f64; 2]| [(q[0] * k) as f32, (q[1] * k) as f32];
            let mut flat = Flattener::default();
            let c = &mut reference.capsules;
            for cmd in font::text_outline(size, [x, y], text) {
                match cmd {
                    coupler_layout::OutlineCmd::MoveTo(a) => flat.move_to(p(a), c),
                    coupler_layout::OutlineCmd::LineTo(a) => flat.line_to(p(a), c),
                    coupler_layout::OutlineCmd::QuadTo(q, a) => flat.quad_to(p(q), p(a), c),
                    coupler_layout::OutlineCmd::CubicTo(q, r, a) => {
                        flat.cubic_to(p(q), p(r), p(a), c)
                    }
                    coupler_layout::OutlineCmd::Close => flat.close(c),
                }
            }
            reference.ink = Ink::Paper;
            let (capsules, mut target) = reference.target();
            capsules.stroke((halo * k) as f32, &mut target);
            let (a, b) = (page.ink().to_vec(), reference.ink().to_vec());
            let erased = |v: &[u8]| v.iter().filter(|&&x| x < 128).count();
            let (ea, eb) = (erased(&a), erased(&b));
            assert!(eb > 5000, "{eb}");
            assert!(ea.abs_diff(eb) * 50 < eb, "{size}: {ea} against {eb}");
            // A quarter-pixel shift moves an anti-aliased edge by at most a third of
            // the full range.
            let worst = a.iter().zip(&b).map(|(p, q)| p.abs_diff(*q)).max();
            assert!(worst.unwrap_or(0) <= 96, "{size}: {worst:?}");
        }
    }
}
