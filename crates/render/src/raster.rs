//! Raster backend: anti-aliased ink coverage with tiny-skia, grayscale PNG output.

use super::{Canvas, anchored_x};
use ab_glyph::{Font, FontRef, Glyph, point};
use coupler_layout::{self as font, Anchor, Ink, OutlineCmd, PT_PER_INCH, PagePoint};
use std::io::Write;
use tiny_skia::{FillRule, LineCap, LineJoin, Mask, PathBuilder, Stroke, Transform};

/// A page being drawn: an 8-bit ink-coverage buffer (0 = paper, 255 = full ink) at a
/// given DPI. All ink is black, so coverage composites exactly ("source over" in one
/// channel: `ink ← ink + (255 − ink)·coverage`). One buffer per worker, cleared and
/// reused for every page, keeps memory bounded (tabloid at 300 dpi: 16.8 MB).
pub struct RasterPage {
    mask: Mask,
    px_per_pt: f64,
    dpi: f64,
    font: FontRef<'static>,
    ink: Ink,
    /// Gray ink of one level is rasterised into its own coverage layer and composited
    /// into the page when the level changes, before paper is drawn, and when the page is
    /// read: grays overprint black in any order, so black can be drawn meanwhile. Made
    /// on the first gray.
    gray: Option<GrayLayer>,
}

/// A coverage layer for one gray level, with the pixel box drawn into since the last
/// flush.
struct GrayLayer {
    mask: Mask,
    level: u8,
    dirty: Option<[usize; 4]>,
}

impl RasterPage {
    /// A blank page of `width_px × height_px` at `dpi`. `None` for a zero size.
    pub fn new(width_px: u32, height_px: u32, dpi: f64) -> Option<RasterPage> {
        Some(RasterPage {
            mask: Mask::new(width_px, height_px)?,
            px_per_pt: dpi / PT_PER_INCH,
            dpi,
            font: font::embedded_font(),
            ink: Ink::Black,
            gray: None,
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

    /// Erases all ink (and sets the ink back to black).
    pub fn clear(&mut self) {
        self.flush_gray();
        self.mask.data_mut().fill(0);
        self.ink = Ink::Black;
    }

    /// The ink coverage, row-major (grays composited in).
    pub fn ink(&mut self) -> &[u8] {
        self.flush_gray();
        self.mask.data()
    }

    /// Composites the gray layer into the page and clears it.
    fn flush_gray(&mut self) {
        let Some(layer) = self.gray.as_mut() else {
            return;
        };
        let Some([x0, y0, x1, y1]) = layer.dirty.take() else {
            return;
        };
        let stride = self.mask.width() as usize;
        let ink = Ink::Gray(layer.level);
        let src = layer.mask.data_mut();
        let dst = self.mask.data_mut();
        for j in y0..y1 {
            let row = j * stride;
            let (d_row, s_row) = (&mut dst[row + x0..row + x1], &mut src[row + x0..row + x1]);
            // Most of the layer is empty: skip it eight bytes at a time.
            for (d8, s8) in d_row.chunks_mut(8).zip(s_row.chunks_mut(8)) {
                if s8.len() == 8 && u64::from_ne_bytes(s8[..8].try_into().unwrap_or([1; 8])) == 0 {
                    continue;
                }
                for (d, s) in d8.iter_mut().zip(s8.iter_mut()) {
                    if *s != 0 {
                        *d = composite(*d, *s, ink);
                        *s = 0;
                    }
                }
            }
        }
    }

    /// Writes the page as an 8-bit grayscale PNG (paper white, ink black). The buffer is
    /// turned into gray levels in place on the way (one pass, no copy), which finishes the
    /// page: call [`RasterPage::clear`] before drawing the next one.
    pub fn finish_png(&mut self, out: impl Write) -> Result<(), png::EncodingError> {
        self.flush_gray();
        let (w, h, dpi) = (self.width(), self.height(), self.dpi);
        let data = self.mask.data_mut();
        invert(data);
        encode_png(data, w, h, dpi, false, out)
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
        let (w, h) = (self.width() as f64, self.height() as f64);
        let (x0, x1) = (x0.clamp(0.0, w), x1.clamp(0.0, w));
        let (y0, y1) = (y0.clamp(0.0, h), y1.clamp(0.0, h));
        if x1 <= x0 || y1 <= y0 {
            return;
        }
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
        let data = self.mask.data_mut();
        for j in j0..j1 {
            let cy = cover(y0, y1, j);
            let row = &mut data[j * stride..(j + 1) * stride];
            for (i, px) in row.iter_mut().enumerate().take(i1).skip(i0) {
                let c = cover(x0, x1, i) * cy;
                if ink_of == Ink::Black {
                    let ink = f64::from(*px);
                    *px = (ink + (255.0 - ink) * c + 0.5).min(255.0) as u8;
                } else {
                    *px = composite(*px, (c * 255.0 + 0.5).min(255.0) as u8, ink_of);
                }
            }
        }
    }

    fn fill(&mut self, path: &tiny_skia::Path) {
        match self.ink {
            // All-black ink composites straight into the page's coverage.
            Ink::Black => self
                .mask
                .fill_path(path, FillRule::Winding, true, Transform::identity()),
            Ink::Gray(level) => {
                if self.gray.as_ref().is_some_and(|g| g.level != level) {
                    self.flush_gray();
                }
                let (w, h) = (self.width(), self.height());
                let layer = match &mut self.gray {
                    Some(layer) => layer,
                    None => self.gray.insert(GrayLayer {
                        mask: Mask::new(w, h).expect("same size as the page"),
                        level,
                        dirty: None,
                    }),
                };
                layer.level = level;
                layer
                    .mask
                    .fill_path(path, FillRule::Winding, true, Transform::identity());
                let b = path.bounds();
                let clampx = |v: f32| (v.max(0.0) as usize).min(w as usize);
                let clampy = |v: f32| (v.max(0.0) as usize).min(h as usize);
                let r = [
                    clampx(b.left().floor() - 1.0),
                    clampy(b.top().floor() - 1.0),
                    clampx(b.right().ceil() + 1.0),
                    clampy(b.bottom().ceil() + 1.0),
                ];
                layer.dirty = Some(match layer.dirty {
                    None => r,
                    Some(d) => [
                        d[0].min(r[0]),
                        d[1].min(r[1]),
                        d[2].max(r[2]),
                        d[3].max(r[3]),
                    ],
                });
            }
            Ink::Paper => {
                self.flush_gray();
                self.fill_with(path, Ink::Paper)
            }
        }
    }

    /// Fills `path` in a gray or in paper: its coverage is rasterised into a scratch
    /// mask over its box, then composited (a gray overprints, paper erases).
    fn fill_with(&mut self, path: &tiny_skia::Path, ink: Ink) {
        let b = path.bounds();
        let (w, h) = (i64::from(self.width()), i64::from(self.height()));
        let x0 = (b.left().floor() as i64 - 1).clamp(0, w);
        let y0 = (b.top().floor() as i64 - 1).clamp(0, h);
        let x1 = (b.right().ceil() as i64 + 1).clamp(0, w);
        let y1 = (b.bottom().ceil() as i64 + 1).clamp(0, h);
        if x1 <= x0 || y1 <= y0 {
            return;
        }
        let Some(mut scratch) = Mask::new((x1 - x0) as u32, (y1 - y0) as u32) else {
            return;
        };
        scratch.fill_path(
            path,
            FillRule::Winding,
            true,
            Transform::from_translate(-(x0 as f32), -(y0 as f32)),
        );
        let stride = self.width() as usize;
        let sw = (x1 - x0) as usize;
        let data = self.mask.data_mut();
        for (j, row) in scratch.data().chunks(sw).enumerate() {
            let start = (y0 as usize + j) * stride + x0 as usize;
            for (px, &c) in data[start..start + sw].iter_mut().zip(row) {
                if c != 0 {
                    *px = composite(*px, c, ink);
                }
            }
        }
    }
}

/// Composites coverage `c` (0..=255) of `ink` over the page's ink `dst` (0 paper, 255
/// black), in integers (deterministic): black and grays overprint (`dst + (255 − dst)·c·g`,
/// never lighter), paper erases (`dst·(1 − c)`).
fn composite(dst: u8, c: u8, ink: Ink) -> u8 {
    let (d, c) = (u32::from(dst), u32::from(c));
    match ink {
        Ink::Paper => (d - (d * c + 127) / 255) as u8,
        ink => {
            let g = u32::from(ink.level());
            (d + ((255 - d) * c * g + 32_512) / 65_025) as u8
        }
    }
}

/// `x ← 255 − x` over a buffer (vectorises).
fn invert(data: &mut [u8]) {
    for x in data.iter_mut() {
        *x = !*x;
    }
}

/// Encodes 8-bit gray (or ink, inverted on the way out when `ink` is true) as a PNG with
/// the resolution in a `pHYs` chunk (pixels per metre). Fast deflate and adaptive
/// filtering: deterministic bytes for a given `png` crate version.
pub fn encode_png(
    data: &[u8],
    width: u32,
    height: u32,
    dpi: f64,
    ink: bool,
    out: impl Write,
) -> Result<(), png::EncodingError> {
    let mut enc = png::Encoder::new(out, width, height);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    // fdeflate's PNG-tuned fast mode; the Up filter (instead of trying all five filters
    // per row) costs a fraction of the time on line art for a few % of size.
    enc.set_compression(png::Compression::Fast);
    enc.set_filter(png::Filter::Up);
    let ppm = (dpi / 0.0254).round() as u32;
    enc.set_pixel_dims(Some(png::PixelDimensions {
        xppu: ppm,
        yppu: ppm,
        unit: png::Unit::Meter,
    }));
    let mut w = enc.write_header()?;
    if ink {
        let mut sw = w.stream_writer()?;
        let mut row = vec![0u8; width as usize];
        for chunk in data.chunks(width as usize) {
            for (o, i) in row.iter_mut().zip(chunk) {
                *o = 255 - *i;
            }
            sw.write_all(&row)?;
        }
        sw.finish()?;
    } else {
        w.write_image_data(data)?;
        w.finish()?;
    }
    Ok(())
}

impl RasterPage {
    /// Strokes polylines as one path (round caps and joins; a single point is a dot).
    fn stroke_paths<'a>(&mut self, lines: impl Iterator<Item = &'a [PagePoint]>, width: f64) {
        let mut pb = PathBuilder::new();
        for points in lines.filter(|l| !l.is_empty()) {
            let (x, y) = self.px(points[0]);
            pb.move_to(x, y);
            if points.len() == 1 {
                pb.line_to(x, y);
            }
            for p in &points[1..] {
                let (x, y) = self.px(*p);
                pb.line_to(x, y);
            }
        }
        let Some(path) = pb.finish() else { return };
        let stroke = Stroke {
            width: (width * self.px_per_pt) as f32,
            line_cap: LineCap::Round,
            line_join: LineJoin::Round,
            ..Stroke::default()
        };
        if let Some(outline) = path.stroke(&stroke, 1.0) {
            self.fill(&outline);
        }
    }
}

impl Canvas for RasterPage {
    fn stroke_polyline(&mut self, points: &[PagePoint], width: f64) {
        self.stroke_paths(std::iter::once(points), width);
    }

    fn stroke_polylines(&mut self, lines: &[Vec<PagePoint>], width: f64) {
        self.stroke_paths(lines.iter().map(Vec::as_slice), width);
    }

    fn stroke_rect(&mut self, rect: [f64; 4], width: f64) {
        let k = self.px_per_pt;
        let [x0, y0, x1, y1] = rect.map(|v| v * k);
        let h = 0.5 * width * k;
        self.fill_rect_px(x0 - h, y0 - h, x1 + h, y0 + h);
        self.fill_rect_px(x0 - h, y1 - h, x1 + h, y1 + h);
        self.fill_rect_px(x0 - h, y0 + h, x0 + h, y1 - h);
        self.fill_rect_px(x1 - h, y0 + h, x1 + h, y1 - h);
    }

    fn fill_polygon(&mut self, points: &[PagePoint]) {
        if points.len() < 3 {
            return;
        }
        let mut pb = PathBuilder::new();
        let (x, y) = self.px(points[0]);
        pb.move_to(x, y);
        for p in &points[1..] {
            let (x, y) = self.px(*p);
            pb.line_to(x, y);
        }
        pb.close();
        if let Some(path) = pb.finish() {
            self.fill(&path);
        }
    }

    fn circle(&mut self, center: PagePoint, radius: f64, width: Option<f64>) {
        let (x, y) = self.px(center);
        let r = (radius * self.px_per_pt) as f32;
        let Some(path) = PathBuilder::from_circle(x, y, r) else {
            return;
        };
        match width {
            None => self.fill(&path),
            Some(w) => {
                let stroke = Stroke {
                    width: (w * self.px_per_pt) as f32,
                    ..Stroke::default()
                };
                if let Some(outline) = path.stroke(&stroke, 1.0) {
                    self.fill(&outline);
                }
            }
        }
    }

    fn set_ink(&mut self, ink: Ink) {
        self.ink = ink;
    }

    fn text(&mut self, pos: PagePoint, size: f64, anchor: Anchor, text: &str, halo: f64) {
        if halo > 0.0 {
            // The glyph outlines stroked in paper, under the glyphs.
            let x = anchored_x(pos[0], font::text_width(size, text), anchor);
            let mut pb = PathBuilder::new();
            let k = self.px_per_pt as f32;
            let p = |q: [f64; 2]| (q[0] as f32 * k, q[1] as f32 * k);
            for c in font::text_outline(size, [x, pos[1]], text) {
                match c {
                    OutlineCmd::MoveTo(a) => pb.move_to(p(a).0, p(a).1),
                    OutlineCmd::LineTo(a) => pb.line_to(p(a).0, p(a).1),
                    OutlineCmd::QuadTo(q, a) => pb.quad_to(p(q).0, p(q).1, p(a).0, p(a).1),
                    OutlineCmd::CubicTo(q, r, a) => {
                        pb.cubic_to(p(q).0, p(q).1, p(r).0, p(r).1, p(a).0, p(a).1)
                    }
                    OutlineCmd::Close => pb.close(),
                }
            }
            if let Some(path) = pb.finish() {
                let stroke = Stroke {
                    width: (2.0 * halo * self.px_per_pt) as f32,
                    line_cap: LineCap::Round,
                    line_join: LineJoin::Round,
                    ..Stroke::default()
                };
                if let Some(outline) = path.stroke(&stroke, 1.0) {
                    self.flush_gray();
                    self.fill_with(&outline, Ink::Paper);
                }
            }
        }
        let ink = self.ink;
        let size_px = size * self.px_per_pt;
        let (glyphs, advance) = font::shape_line(&self.font, size_px, text);
        let x0 = anchored_x(pos[0] * self.px_per_pt, advance, anchor);
        let y0 = pos[1] * self.px_per_pt;
        let scale = font::px_scale(&self.font, size_px as f32);
        let (w, h) = (self.mask.width() as i64, self.mask.height() as i64);
        for g in glyphs {
            let glyph = Glyph {
                id: g.id,
                scale,
                position: point((x0 + g.x) as f32, y0 as f32),
            };
            let Some(outlined) = self.font.outline_glyph(glyph) else {
                continue;
            };
            let b = outlined.px_bounds();
            let (bx, by) = (b.min.x as i64, b.min.y as i64);
            let data = self.mask.data_mut();
            outlined.draw(|gx, gy, c| {
                let (x, y) = (bx + i64::from(gx), by + i64::from(gy));
                if x >= 0 && y >= 0 && x < w && y < h {
                    let k = (y * w + x) as usize;
                    if ink == Ink::Black {
                        let d = f32::from(data[k]);
                        let v = d + (255.0 - d) * c.clamp(0.0, 1.0);
                        data[k] = (v + 0.5) as u8;
                    } else {
                        let cov = (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
                        data[k] = composite(data[k], cov, ink);
                    }
                }
            });
        }
    }
}
