//! The embedded page font: DejaVu Sans 2.37 (Bitstream Vera licence, see
//! `assets/fonts/LICENSE-DejaVu.txt`), compiled into the binary so that pages never
//! depend on fonts installed on the machine (no fontconfig).
//!
//! Text sizes are em sizes in page points. Measuring is pure (font tables only), so the
//! layout can place labels without a renderer.

use ab_glyph::{Font, FontRef, GlyphId, OutlineCurve, PxScale};
use std::cell::RefCell;
use std::sync::OnceLock;

/// The font file, shipped in the repository.
pub static FONT_BYTES: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

/// The family name, for SVG metadata.
pub const FONT_FAMILY: &str = "DejaVu Sans";

/// The embedded font, parsed (a few table look-ups; cheap).
pub fn embedded_font() -> FontRef<'static> {
    FontRef::try_from_slice(FONT_BYTES).expect("embedded DejaVu Sans parses")
}

/// ab_glyph's [`PxScale`] (ascent − descent height) for an em size `em` (any unit).
pub fn px_scale(font: &FontRef<'_>, em: f32) -> PxScale {
    let upem = font.units_per_em().unwrap_or(2048.0);
    PxScale::from(em * font.height_unscaled() / upem)
}

/// One glyph placed on a line of text: its id and pen x offset (em-relative units times
/// size, i.e. in the same unit as the size).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacedGlyph {
    /// Glyph id.
    pub id: GlyphId,
    /// Pen position along the baseline, from the text's start.
    pub x: f64,
}

/// Lays out one line of text at em size `size` (advances and kerning), returning the
/// glyphs and the total advance width. Same unit in and out (points on a page).
pub fn shape_line(font: &FontRef<'_>, size: f64, text: &str) -> (Vec<PlacedGlyph>, f64) {
    let upem = f64::from(font.units_per_em().unwrap_or(2048.0));
    let k = size / upem;
    let mut out = Vec::with_capacity(text.len());
    let mut x = 0.0;
    let mut prev: Option<GlyphId> = None;
    for ch in text.chars() {
        let id = font.glyph_id(ch);
        if let Some(p) = prev {
            x += f64::from(font.kern_unscaled(p, id)) * k;
        }
        out.push(PlacedGlyph { id, x });
        x += f64::from(font.h_advance_unscaled(id)) * k;
        prev = Some(id);
    }
    (out, x)
}

/// [`shape_line`] with the embedded font, each ASCII character's glyph id and advance
/// and each ASCII pair's kerning looked up once and kept (a few table searches per
/// character and pair otherwise): the same values, so the same glyphs and positions to
/// the bit. Other characters are looked up each time.
pub struct Shaper {
    font: FontRef<'static>,
    upem: f64,
    /// Per ASCII character: its glyph id and unscaled advance.
    ascii: Vec<(GlyphId, f32)>,
    /// Per ASCII pair `(a, b)` at `128·a + b`: the unscaled kerning, NaN until looked up.
    kern: Vec<f32>,
}

impl Default for Shaper {
    fn default() -> Self {
        Shaper::new()
    }
}

impl Shaper {
    /// A shaper of the embedded font.
    pub fn new() -> Shaper {
        let font = embedded_font();
        let ascii = (0..128u8)
            .map(|c| {
                let id = font.glyph_id(char::from(c));
                (id, font.h_advance_unscaled(id))
            })
            .collect();
        Shaper {
            upem: f64::from(font.units_per_em().unwrap_or(2048.0)),
            font,
            ascii,
            kern: vec![f32::NAN; 128 * 128],
        }
    }

    /// The embedded font.
    pub fn font(&self) -> &FontRef<'static> {
        &self.font
    }

    /// [`shape_line`]`(font, size, text)` of the embedded font.
    pub fn shape_line(&mut self, size: f64, text: &str) -> (Vec<PlacedGlyph>, f64) {
        let mut out = Vec::with_capacity(text.len());
        let x = self.shape_into(size, text, |g| out.push(g));
        (out, x)
    }

    /// [`Shaper::shape_line`]'s width alone, no glyphs kept.
    pub fn width(&mut self, size: f64, text: &str) -> f64 {
        self.shape_into(size, text, |_| {})
    }

    /// Shapes `text`, each glyph to `glyph` in turn; the width.
    #[inline]
    fn shape_into(&mut self, size: f64, text: &str, mut glyph: impl FnMut(PlacedGlyph)) -> f64 {
        let k = size / self.upem;
        let mut x = 0.0;
        // The previous glyph, and its ASCII code if it has one.
        let mut prev: Option<(GlyphId, Option<usize>)> = None;
        for ch in text.chars() {
            let code = ch.is_ascii().then_some(ch as usize);
            let (id, advance) = match code {
                Some(c) => self.ascii[c],
                None => {
                    let id = self.font.glyph_id(ch);
                    (id, self.font.h_advance_unscaled(id))
                }
            };
            if let Some((p, pc)) = prev {
                let kern = match (pc, code) {
                    (Some(a), Some(b)) => {
                        let kept = &mut self.kern[128 * a + b];
                        if kept.is_nan() {
                            *kept = self.font.kern_unscaled(p, id);
                        }
                        *kept
                    }
                    _ => self.font.kern_unscaled(p, id),
                };
                x += f64::from(kern) * k;
            }
            glyph(PlacedGlyph { id, x });
            x += f64::from(advance) * k;
            prev = Some((id, code));
        }
        x
    }
}

thread_local! {
    /// This thread's shaper for [`text_width`]: the font parsed once, its ASCII glyphs
    /// and kerning looked up once ([`Shaper`]), not per call.
    static MEASURE: RefCell<Shaper> = RefCell::new(Shaper::new());
}

/// The embedded font's units per em, ascender and descender (unscaled), read once.
fn vertical_metrics() -> (f64, f32, f32) {
    static METRICS: OnceLock<(f64, f32, f32)> = OnceLock::new();
    *METRICS.get_or_init(|| {
        let f = embedded_font();
        (
            f64::from(f.units_per_em().unwrap_or(2048.0)),
            f.ascent_unscaled(),
            f.descent_unscaled(),
        )
    })
}

/// Advance width of `text` at em size `size`: [`shape_line`]'s with the embedded font,
/// the same value to the bit.
pub fn text_width(size: f64, text: &str) -> f64 {
    MEASURE.with(|s| s.borrow_mut().width(size, text))
}

/// Ascender height above the baseline at em size `size` (for boxes around text).
pub fn ascent(size: f64) -> f64 {
    let (upem, ascent, _) = vertical_metrics();
    f64::from(ascent) * size / upem
}

/// Descender depth below the baseline at em size `size` (positive).
pub fn descent(size: f64) -> f64 {
    let (upem, _, descent) = vertical_metrics();
    -f64::from(descent) * size / upem
}

/// One contour command of a glyph outline, in page units, y down.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OutlineCmd {
    /// Start a contour.
    MoveTo([f64; 2]),
    /// Straight line.
    LineTo([f64; 2]),
    /// Quadratic Bézier (control, end).
    QuadTo([f64; 2], [f64; 2]),
    /// Cubic Bézier (control 1, control 2, end).
    CubicTo([f64; 2], [f64; 2], [f64; 2]),
    /// Close the contour.
    Close,
}

/// Outline of `text` at em size `size` with its baseline start at `origin` (page units,
/// y down), for vector output. Contours are closed when a curve does not start where the
/// previous one ended.
pub fn text_outline(size: f64, origin: [f64; 2], text: &str) -> Vec<OutlineCmd> {
    let font = embedded_font();
    let upem = f64::from(font.units_per_em().unwrap_or(2048.0));
    let k = size / upem;
    let (glyphs, _) = shape_line(&font, size, text);
    let mut cmds = Vec::new();
    for g in glyphs {
        let Some(outline) = font.outline(g.id) else {
            continue;
        };
        let map = |p: ab_glyph::Point| {
            [
                origin[0] + g.x + f64::from(p.x) * k,
                origin[1] - f64::from(p.y) * k,
            ]
        };
        let mut last: Option<ab_glyph::Point> = None;
        let mut open = false;
        for c in &outline.curves {
            let (start, end) = match *c {
                OutlineCurve::Line(a, b) => (a, b),
                OutlineCurve::Quad(a, _, b) => (a, b),
                OutlineCurve::Cubic(a, _, _, b) => (a, b),
            };
            if last != Some(start) {
                if open {
                    cmds.push(OutlineCmd::Close);
                }
                cmds.push(OutlineCmd::MoveTo(map(start)));
                open = true;
            }
            cmds.push(match *c {
                OutlineCurve::Line(_, b) => OutlineCmd::LineTo(map(b)),
                OutlineCurve::Quad(_, q, b) => OutlineCmd::QuadTo(map(q), map(b)),
                OutlineCurve::Cubic(_, q, r, b) => OutlineCmd::CubicTo(map(q), map(r), map(b)),
            });
            last = Some(end);
        }
        if open {
            cmds.push(OutlineCmd::Close);
        }
    }
    cmds
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widths_scale_linearly_and_kern() {
        let w10 = text_width(10.0, "A = 3.5");
        let w20 = text_width(20.0, "A = 3.5");
        assert!(w10 > 20.0 && w10 < 50.0, "{w10}");
        assert!((w20 - 2.0 * w10).abs() < 1e-9);
        assert!(ascent(10.0) > 7.0 && descent(10.0) > 1.0);
        assert!(!text_outline(10.0, [0.0, 0.0], "θ (u, v)").is_empty());
    }

    /// The shaper's glyphs and positions are `shape_line`'s, bit for bit: every ASCII
    /// pair (kerned or not), at several sizes, and strings with characters beyond ASCII.
    #[test]
    fn the_shaper_shapes_as_shape_line() {
        let font = embedded_font();
        let mut shaper = Shaper::new();
        let bits = |(g, w): (Vec<PlacedGlyph>, f64)| {
            let g: Vec<(u16, u64)> = g.iter().map(|p| (p.id.0, p.x.to_bits())).collect();
            (g, w.to_bits())
        };
        let mut texts: Vec<String> = Vec::new();
        for a in 0..128u8 {
            let row: String = (0..128u8)
                .flat_map(|b| [char::from(a), char::from(b)])
                .collect();
            texts.push(row);
        }
        texts.extend(
            [
                "AV To (0.25, −1.5)",
                "θ = 0°, λ = 3/2",
                "S 23°",
                "",
                "Wa.",
                "éAVé",
            ]
            .map(String::from),
        );
        for size in [8.0, 7.0 * 300.0 / 72.0, 11.3] {
            for t in &texts {
                assert_eq!(
                    bits(shaper.shape_line(size, t)),
                    bits(shape_line(&font, size, t)),
                    "{t:?} at {size}"
                );
            }
        }
        // Kerning is there to keep: some ASCII pairs kern.
        assert!(shaper.kern.iter().any(|&k| k != 0.0 && !k.is_nan()));
    }

    /// `text_width`, `ascent` and `descent` (their font and tables kept) measure as the
    /// font parsed for each call does, to the bit; on other threads too.
    #[test]
    fn measures_kept_are_measures_made_each_time() {
        let mut texts: Vec<String> = (0..128u8)
            .map(|a| {
                (0..128u8)
                    .flat_map(|b| [char::from(a), char::from(b)])
                    .collect()
            })
            .collect();
        texts.extend(
            [
                "AV To (0.25, −1.5)",
                "θ = 0°",
                "S 23°",
                "",
                "Wa.",
                "éAVé",
                "1",
                "(2, 3)",
            ]
            .map(String::from),
        );
        let check = |texts: &[String]| {
            for size in [8.0, 7.0, 6.0, 7.0 * 300.0 / 72.0, 11.3] {
                let f = embedded_font();
                let upem = f64::from(f.units_per_em().unwrap_or(2048.0));
                assert_eq!(
                    ascent(size).to_bits(),
                    (f64::from(f.ascent_unscaled()) * size / upem).to_bits()
                );
                assert_eq!(
                    descent(size).to_bits(),
                    (-f64::from(f.descent_unscaled()) * size / upem).to_bits()
                );
                for t in texts {
                    // Twice: the second time from the kept kerning.
                    for _ in 0..2 {
                        assert_eq!(
                            text_width(size, t).to_bits(),
                            shape_line(&f, size, t).1.to_bits(),
                            "{t:?} at {size}"
                        );
                    }
                }
            }
        };
        check(&texts);
        std::thread::scope(|s| {
            s.spawn(|| check(&texts[60..]));
        });
    }
}
