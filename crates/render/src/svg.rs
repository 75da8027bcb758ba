//! Vector backend: SVG of the display list. Dashes are exact polylines in page points;
//! text is drawn as the embedded font's glyph outlines (no font needed to view it).

use super::{Canvas, anchored_x, num};
use coupler_layout::{self as font, Anchor, PagePoint};
use std::fmt::Write;

/// An SVG document being built (page points as user units; the size in `pt`).
pub struct SvgPage {
    body: String,
    width: f64,
    height: f64,
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
        }
    }

    /// The finished document.
    pub fn finish(self) -> String {
        let (w, h) = (num(self.width), num(self.height));
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}pt\" height=\"{h}pt\" viewBox=\"0 0 {w} {h}\">\n<rect width=\"{w}\" height=\"{h}\" fill=\"#fff\"/>\n<g stroke-linecap=\"round\" stroke-linejoin=\"round\">\n{}</g>\n</svg>\n",
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
        if points.is_empty() {
            return;
        }
        let mut d = Self::path_d(points);
        if points.len() == 1 {
            d.push_str("h0");
        }
        let _ = writeln!(
            self.body,
            "<path d=\"{d}\" fill=\"none\" stroke=\"#000\" stroke-width=\"{}\"/>",
            num(width)
        );
    }

    fn stroke_polylines(&mut self, lines: &[Vec<PagePoint>], width: f64) {
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
                "<path d=\"{d}\" fill=\"none\" stroke=\"#000\" stroke-width=\"{}\"/>",
                num(width)
            );
        }
    }

    fn stroke_rect(&mut self, rect: [f64; 4], width: f64) {
        let [x0, y0, x1, y1] = rect;
        let _ = writeln!(
            self.body,
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#000\" stroke-width=\"{}\" stroke-linejoin=\"miter\"/>",
            num(x0),
            num(y0),
            num(x1 - x0),
            num(y1 - y0),
            num(width)
        );
    }

    fn fill_polygon(&mut self, points: &[PagePoint]) {
        if points.len() < 3 {
            return;
        }
        let _ = writeln!(
            self.body,
            "<path d=\"{}Z\" fill=\"#000\"/>",
            Self::path_d(points)
        );
    }

    fn circle(&mut self, center: PagePoint, radius: f64, width: Option<f64>) {
        let (cx, cy, r) = (num(center[0]), num(center[1]), num(radius));
        match width {
            None => {
                let _ = writeln!(
                    self.body,
                    "<circle cx=\"{cx}\" cy=\"{cy}\" r=\"{r}\" fill=\"#000\"/>"
                );
            }
            Some(w) => {
                let _ = writeln!(
                    self.body,
                    "<circle cx=\"{cx}\" cy=\"{cy}\" r=\"{r}\" fill=\"none\" stroke=\"#000\" stroke-width=\"{}\"/>",
                    num(w)
                );
            }
        }
    }

    fn text(&mut self, pos: PagePoint, size: f64, anchor: Anchor, text: &str) {
        if text.is_empty() {
            return;
        }
        let width = font::text_width(size, text);
        let x = anchored_x(pos[0], width, anchor);
        let mut d = String::new();
        for c in font::text_outline(size, [x, pos[1]], text) {
            let _ = match c {
                font::OutlineCmd::MoveTo(p) => write!(d, "M{} {}", num(p[0]), num(p[1])),
                font::OutlineCmd::LineTo(p) => write!(d, "L{} {}", num(p[0]), num(p[1])),
                font::OutlineCmd::QuadTo(q, p) => {
                    write!(
                        d,
                        "Q{} {} {} {}",
                        num(q[0]),
                        num(q[1]),
                        num(p[0]),
                        num(p[1])
                    )
                }
                font::OutlineCmd::CubicTo(q, r, p) => write!(
                    d,
                    "C{} {} {} {} {} {}",
                    num(q[0]),
                    num(q[1]),
                    num(r[0]),
                    num(r[1]),
                    num(p[0]),
                    num(p[1])
                ),
                font::OutlineCmd::Close => write!(d, "Z"),
            };
        }
        let _ = writeln!(
            self.body,
            "<path d=\"{d}\" fill=\"#000\"><title>{}</title></path>",
            xml_escape(text)
        );
    }
}
