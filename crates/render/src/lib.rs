//! # coupler-render
//!
//! Rendering: strokes what the layout gives, nothing more.
//!
//! The drawing interface ([`Canvas`]) takes f64 page points (1/72 in, y down), never
//! integer pixels, so sub-pixel geometry survives to the rasteriser (plotters' backend
//! trait rounds to whole pixels at the boundary; we don't). Two backends:
//!
//! - [`RasterPage`]: tiny-skia anti-aliased coverage into an 8-bit ink buffer (one buffer
//!   per worker, reused page after page), text rasterised with ab_glyph from the embedded
//!   font, written as 8-bit grayscale PNG with the DPI in a `pHYs` chunk ([`encode_png`]);
//! - [`SvgPage`]: the same display list as exact vector paths (text as glyph outlines, so
//!   the page looks the same without the font installed).

mod capsule;
mod cpu;
mod diff;
mod dirty;
mod layer;
mod pdf;
mod pixel;
mod raster;
mod rowdeflate;
mod svg;
mod svg_font;

pub use diff::{
    DiffError, ImageDiff, MAX_DIFF_PIXELS, MAX_DIFF_WIDTH, diff_files, diff_images, read_image,
};
pub use pdf::{Bookmark, PageLabelRange, PdfError, PdfPage, PdfPageContent, write_pdf};
pub use raster::{PngCompression, RasterPage, encode_png, encode_png_with, reuse_png_buffer};
pub use svg::SvgPage;

use coupler_layout::{Anchor, DisplayList, Ink, PagePoint, Primitive};

/// A surface that can draw the layout's primitives, in page points.
pub trait Canvas {
    /// Strokes an open polyline (round caps and joins) of `width` points.
    fn stroke_polyline(&mut self, points: &[PagePoint], width: f64);
    /// Strokes several open polylines of one width; the ink is the union of the strokes.
    fn stroke_polylines(&mut self, lines: &[Vec<PagePoint>], width: f64) {
        for l in lines {
            self.stroke_polyline(l, width);
        }
    }
    /// Outlines an axis-aligned rectangle `[x0, y0, x1, y1]` with a stroke of `width`
    /// centred on its edges, mitred corners.
    fn stroke_rect(&mut self, rect: [f64; 4], width: f64) {
        let [x0, y0, x1, y1] = rect;
        let h = 0.5 * width;
        // Four bands as filled polygons: exact mitred corners.
        for band in [
            [x0 - h, y0 - h, x1 + h, y0 + h],
            [x0 - h, y1 - h, x1 + h, y1 + h],
            [x0 - h, y0 + h, x0 + h, y1 - h],
            [x1 - h, y0 + h, x1 + h, y1 - h],
        ] {
            let [a, b, c, d] = band;
            self.fill_polygon(&[[a, b], [c, b], [c, d], [a, d]]);
        }
    }
    /// Fills a closed polygon (non-zero rule).
    fn fill_polygon(&mut self, points: &[PagePoint]);
    /// A circle outline of `width` points, or a filled disc when `width` is `None`.
    fn circle(&mut self, center: PagePoint, radius: f64, width: Option<f64>);
    /// One line of text, baseline through `pos`, em size `size` points, with a
    /// paper-white halo of `halo` points around its glyphs (0: none).
    fn text(&mut self, pos: PagePoint, size: f64, anchor: Anchor, text: &str, halo: f64);
    /// The ink of what is drawn next (black until set).
    fn set_ink(&mut self, ink: Ink);
}

/// Draws a display list on a canvas, in order.
pub fn draw(display: &DisplayList, canvas: &mut impl Canvas) {
    for item in &display.items {
        match item {
            Primitive::Polyline { points, width } => canvas.stroke_polyline(points, *width),
            Primitive::Polylines { lines, width } => canvas.stroke_polylines(lines, *width),
            Primitive::Rect { rect, width } => canvas.stroke_rect(*rect, *width),
            Primitive::Polygon { points } => canvas.fill_polygon(points),
            Primitive::Circle {
                center,
                radius,
                width,
            } => canvas.circle(*center, *radius, *width),
            Primitive::Text {
                pos,
                size,
                anchor,
                text,
                halo,
            } => canvas.text(*pos, *size, *anchor, text, *halo),
            Primitive::Ink(ink) => canvas.set_ink(*ink),
        }
    }
}

/// Output formats for pages.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PageFormat {
    /// 8-bit grayscale PNG with DPI.
    Png,
    /// SVG (vector).
    Svg,
    /// PDF (vector): one document of the whole atlas.
    Pdf,
}

impl PageFormat {
    /// File extension.
    pub fn extension(self) -> &'static str {
        match self {
            PageFormat::Png => "png",
            PageFormat::Svg => "svg",
            PageFormat::Pdf => "pdf",
        }
    }
}

/// An unknown page format name.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("unknown page format {0:?} (expected png, svg or pdf)")]
pub struct UnknownFormat(pub String);

impl std::str::FromStr for PageFormat {
    type Err = UnknownFormat;
    fn from_str(s: &str) -> Result<PageFormat, UnknownFormat> {
        match s.trim().to_ascii_lowercase().as_str() {
            "png" => Ok(PageFormat::Png),
            "svg" => Ok(PageFormat::Svg),
            "pdf" => Ok(PageFormat::Pdf),
            _ => Err(UnknownFormat(s.to_string())),
        }
    }
}

/// Text start x for an anchor, given its advance width.
pub(crate) fn anchored_x(x: f64, width: f64, anchor: Anchor) -> f64 {
    match anchor {
        Anchor::Start => x,
        Anchor::Middle => x - 0.5 * width,
        Anchor::End => x - width,
    }
}

/// A coordinate for a vector format: at most 3 decimals, no trailing zeros, never `-0`
/// (deterministic and compact).
fn num(x: f64) -> String {
    let s = format!("{x:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" || s.is_empty() {
        "0".into()
    } else {
        s.to_string()
    }
}

/// The tests' random numbers: one step of Marsaglia's xorshift64 (13, 7, 17).
#[cfg(test)]
pub(crate) fn xorshift(mut x: u64) -> u64 {
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    x
}
