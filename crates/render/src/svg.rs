//! Vector backend: SVG of the display list. Dashes are exact polylines in page points;
//! text is real `<text>` (searchable, selectable) in the embedded font, a subset of which
//! is carried in the file (`@font-face` with a data URL), so it looks the same without
//! the font installed.

use super::{Canvas, anchored_x, num};
use crate::svg_font::FONT_CSS_FAMILY;
use coupler_layout::{self as font, Anchor, Ink, PagePoint};
use std::fmt::Write;

/// An SVG document being built (page points as user units; the size in `pt`).
pub struct SvgPage {
    body: String,
    width: f64,
    height: f64,
    /// The current ink as an SVG colour.
    color: String,
    /// Characters used by the text (for the embedded font subset).
    glyphs: std::collections::BTreeSet<char>,
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

impl SvgPage {
    /// An empty page of `width × height` points.
    pub fn new(width: f64, height: f64) -> SvgPage {
        SvgPage {
            body: String::with_capacity(1 << 16),
            width,
            height,
            color: "#000".into(),
            glyphs: Default::default(),
        }
    }

    /// The finished document.
    pub fn finish(self) -> String {
        let (w, h) = (num(self.width), num(self.height));
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}pt\" height=\"{h}pt\" viewBox=\"0 0 {w} {h}\">\n<rect width=\"{w}\" height=\"{h}\" fill=\"#fff\"/>\n{}<g stroke-linecap=\"round\" stroke-linejoin=\"round\" font-family=\"{FONT_CSS_FAMILY}, 'DejaVu Sans', sans-serif\">\n{}</g>\n</svg>\n",
            crate::svg_font::font_face_style(&self.glyphs),
            self.body
        )
    }

    fn path_d(points: &[PagePoint]) -> String {
        let mut d = String::with_capacity(points.len() * 14);
        for (i, p) in points.iter().enumerate() {
            let _ = write!(
                d,
                "{}{} {}",
                if i == 0 { "M" } else { "L" },
                num(p[0]),
                num(p[1])
            );
        }
        d
    }
}

impl Canvas for SvgPage {
    fn stroke_polyline(&mut self, points: &[PagePoint], width: f64) {
        let c = self.color.clone();
        if points.is_empty() {
            return;
        }
        let mut d = Self::path_d(points);
        if points.len() == 1 {
            d.push_str("h0");
        }
        let _ = writeln!(
            self.body,
            "<path d=\"{d}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"{}\"/>",
            num(width)
        );
    }

    fn stroke_polylines(&mut self, lines: &[Vec<PagePoint>], width: f64) {
        let c = self.color.clone();
        let d: String = lines
            .iter()
            .filter(|l| !l.is_empty())
            .map(|l| {
                if l.len() == 1 {
                    Self::path_d(l) + "h0"
                } else {
                    Self::path_d(l)
                }
            })
            .collect();
        if !d.is_empty() {
            let _ = writeln!(
                self.body,
                "<path d=\"{d}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"{}\"/>",
                num(width)
            );
        }
    }

    fn stroke_rect(&mut self, rect: [f64; 4], width: f64) {
        let c = self.color.clone();
        let [x0, y0, x1, y1] = rect;
        let _ = writeln!(
            self.body,
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"{}\" stroke-linejoin=\"miter\"/>",
            num(x0),
            num(y0),
            num(x1 - x0),
            num(y1 - y0),
            num(width)
        );
    }

    fn fill_polygon(&mut self, points: &[PagePoint]) {
        let c = self.color.clone();
        if points.len() < 3 {
            return;
        }
        let _ = writeln!(
            self.body,
            "<path d=\"{}Z\" fill=\"{c}\"/>",
            Self::path_d(points)
        );
    }

    fn circle(&mut self, center: PagePoint, radius: f64, width: Option<f64>) {
        let c = self.color.clone();
        let (cx, cy, r) = (num(center[0]), num(center[1]), num(radius));
        match width {
            None => {
                let _ = writeln!(
                    self.body,
                    "<circle cx=\"{cx}\" cy=\"{cy}\" r=\"{r}\" fill=\"{c}\"/>"
                );
            }
            Some(w) => {
                let _ = writeln!(
                    self.body,
                    "<circle cx=\"{cx}\" cy=\"{cy}\" r=\"{r}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"{}\"/>",
                    num(w)
                );
            }
        }
    }

    fn set_ink(&mut self, ink: Ink) {
        self.color = match ink {
            Ink::Black => "#000".into(),
            ink => format!("#{0:02x}{0:02x}{0:02x}", ink.gray()),
        };
    }

    fn text(&mut self, pos: PagePoint, size: f64, anchor: Anchor, text: &str, halo: f64) {
        if text.is_empty() {
            return;
        }
        // Real text (searchable, selectable) in the embedded font, each glyph placed
        // where the layout measured it (advances and kerning), so it looks the same in
        // every viewer.
        let f = font::embedded_font();
        let (glyphs, width) = font::shape_line(&f, size, text);
        let x = anchored_x(pos[0], width, anchor);
        self.glyphs.extend(text.chars());
        let xs: Vec<String> = glyphs.iter().map(|g| num(x + g.x)).collect();
        let halo = if halo > 0.0 {
            format!(
                " stroke=\"#fff\" stroke-width=\"{}\" stroke-linejoin=\"round\" paint-order=\"stroke\"",
                num(2.0 * halo)
            )
        } else {
            String::new()
        };
        let _ = writeln!(
            self.body,
            "<text x=\"{}\" y=\"{}\" font-size=\"{}\" fill=\"{}\"{halo}>{}</text>",
            xs.join(" "),
            num(pos[1]),
            num(size),
            self.color,
            xml_escape(text)
        );
    }
}
