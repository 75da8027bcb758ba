//! Vector backend: a one-page PDF (1.4) of the display list, written by hand (no
//! dependency; behind the `pdf` cargo feature). Dashes are exact polylines in page
//! points; text is filled glyph outlines of the embedded font, so no font is embedded or
//! needed. The content stream is uncompressed (a page is a few hundred KB).

use super::{Canvas, anchored_x, num};
use coupler_layout::{self as font, Anchor, PagePoint};
use std::fmt::Write;

/// Bézier constant for a quarter circle: 4/3·(√2 − 1).
const KAPPA: f64 = 0.552_284_749_830_793_4;

/// A PDF page being built. Page points map to PDF user space through a y-flip
/// (`1 0 0 −1 0 H cm`), so the display list's y-down coordinates are used as they are.
pub struct PdfPage {
    ops: String,
    width: f64,
    height: f64,
}

impl PdfPage {
    /// An empty page of `width × height` points.
    pub fn new(width: f64, height: f64) -> PdfPage {
        let mut ops = String::with_capacity(1 << 16);
        let _ = writeln!(ops, "1 0 0 -1 0 {} cm 0 g 0 G", num(height));
        PdfPage { ops, width, height }
    }

    /// A cubic Bézier segment to `p` with control points `a`, `b`.
    fn curve_to(&mut self, a: PagePoint, b: PagePoint, p: PagePoint) {
        let _ = write!(
            self.ops,
            "{} {} {} {} {} {} c ",
            num(a[0]),
            num(a[1]),
            num(b[0]),
            num(b[1]),
            num(p[0]),
            num(p[1])
        );
    }

    fn path(&mut self, points: &[PagePoint]) {
        for (i, p) in points.iter().enumerate() {
            let _ = write!(
                self.ops,
                "{} {} {} ",
                num(p[0]),
                num(p[1]),
                if i == 0 { "m" } else { "l" }
            );
        }
    }

    /// The finished PDF file.
    pub fn finish(self) -> Vec<u8> {
        let mut out: Vec<u8> = Vec::with_capacity(self.ops.len() + 1024);
        let mut offsets = Vec::new();
        out.extend_from_slice(b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n");
        let objects = [
            "<< /Type /Catalog /Pages 2 0 R >>".to_string(),
            "<< /Type /Pages /Kids [3 0 R] /Count 1 >>".to_string(),
            format!(
                "<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {} {}] /Resources << >> /Contents 4 0 R >>",
                num(self.width),
                num(self.height)
            ),
        ];
        for (i, body) in objects.iter().enumerate() {
            offsets.push(out.len());
            out.extend_from_slice(format!("{} 0 obj\n{body}\nendobj\n", i + 1).as_bytes());
        }
        offsets.push(out.len());
        out.extend_from_slice(
            format!("4 0 obj\n<< /Length {} >>\nstream\n", self.ops.len()).as_bytes(),
        );
        out.extend_from_slice(self.ops.as_bytes());
        out.extend_from_slice(b"\nendstream\nendobj\n");
        let xref = out.len();
        out.extend_from_slice(b"xref\n0 5\n0000000000 65535 f \n");
        for o in offsets {
            out.extend_from_slice(format!("{o:010} 00000 n \n").as_bytes());
        }
        out.extend_from_slice(
            format!("trailer\n<< /Size 5 /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n").as_bytes(),
        );
        out
    }
}

impl Canvas for PdfPage {
    fn stroke_polyline(&mut self, points: &[PagePoint], width: f64) {
        self.stroke_polylines(&[points.to_vec()], width);
    }

    fn stroke_polylines(&mut self, lines: &[Vec<PagePoint>], width: f64) {
        let _ = write!(self.ops, "{} w 1 J 1 j ", num(width));
        let mut any = false;
        for l in lines.iter().filter(|l| !l.is_empty()) {
            self.path(l);
            if l.len() == 1 {
                // A dot: a zero-length segment, drawn by the round cap.
                let _ = write!(self.ops, "{} {} l ", num(l[0][0]), num(l[0][1]));
            }
            any = true;
        }
        if any {
            self.ops.push_str("S\n");
        }
    }

    fn stroke_rect(&mut self, rect: [f64; 4], width: f64) {
        let [x0, y0, x1, y1] = rect;
        let _ = writeln!(
            self.ops,
            "{} w 0 J 0 j {} {} {} {} re S",
            num(width),
            num(x0),
            num(y0),
            num(x1 - x0),
            num(y1 - y0)
        );
    }

    fn fill_polygon(&mut self, points: &[PagePoint]) {
        if points.len() < 3 {
            return;
        }
        self.path(points);
        self.ops.push_str("h f\n");
    }

    fn circle(&mut self, c: PagePoint, r: f64, width: Option<f64>) {
        let k = KAPPA * r;
        let (x, y) = (c[0], c[1]);
        let _ = write!(self.ops, "{} {} m ", num(x + r), num(y));
        let quads = [
            ([x + r, y + k], [x + k, y + r], [x, y + r]),
            ([x - k, y + r], [x - r, y + k], [x - r, y]),
            ([x - r, y - k], [x - k, y - r], [x, y - r]),
            ([x + k, y - r], [x + r, y - k], [x + r, y]),
        ];
        for (a, b, e) in quads {
            self.curve_to(a, b, e);
        }
        match width {
            None => self.ops.push_str("h f\n"),
            Some(w) => {
                let _ = writeln!(self.ops, "h {} w S", num(w));
            }
        }
    }

    fn text(&mut self, pos: PagePoint, size: f64, anchor: Anchor, text: &str) {
        if text.is_empty() {
            return;
        }
        let x = anchored_x(pos[0], font::text_width(size, text), anchor);
        let mut cur = [0.0, 0.0];
        for c in font::text_outline(size, [x, pos[1]], text) {
            match c {
                font::OutlineCmd::MoveTo(p) => {
                    let _ = write!(self.ops, "{} {} m ", num(p[0]), num(p[1]));
                    cur = p;
                }
                font::OutlineCmd::LineTo(p) => {
                    let _ = write!(self.ops, "{} {} l ", num(p[0]), num(p[1]));
                    cur = p;
                }
                font::OutlineCmd::QuadTo(q, p) => {
                    // Quadratic → cubic: c1 = p0 + ⅔(q − p0), c2 = p + ⅔(q − p).
                    let c1 = [
                        cur[0] + 2.0 / 3.0 * (q[0] - cur[0]),
                        cur[1] + 2.0 / 3.0 * (q[1] - cur[1]),
                    ];
                    let c2 = [
                        p[0] + 2.0 / 3.0 * (q[0] - p[0]),
                        p[1] + 2.0 / 3.0 * (q[1] - p[1]),
                    ];
                    self.curve_to(c1, c2, p);
                    cur = p;
                }
                font::OutlineCmd::CubicTo(a, b, p) => {
                    self.curve_to(a, b, p);
                    cur = p;
                }
                font::OutlineCmd::Close => self.ops.push_str("h "),
            }
        }
        self.ops.push_str("f\n");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xref_offsets_point_at_objects() {
        let mut p = PdfPage::new(100.0, 50.0);
        p.stroke_polyline(&[[1.0, 2.0], [3.0, 4.0]], 0.5);
        p.text([5.0, 20.0], 10.0, Anchor::Start, "(1, 2)");
        let pdf = p.finish();
        let find = |needle: &[u8]| {
            pdf.windows(needle.len())
                .rposition(|w| w == needle)
                .unwrap()
        };
        let tail = std::str::from_utf8(&pdf[find(b"startxref\n") + 10..]).unwrap();
        let start: usize = tail.lines().next().unwrap().parse().unwrap();
        let xref = std::str::from_utf8(&pdf[start..]).unwrap();
        assert!(xref.starts_with("xref\n0 5\n"));
        for (i, line) in xref.lines().skip(3).take(4).enumerate() {
            let off: usize = line[..10].parse().unwrap();
            assert!(
                pdf[off..].starts_with(format!("{} 0 obj", i + 1).as_bytes()),
                "object {}",
                i + 1
            );
        }
        assert!(find(b"1 2 m 3 4 l S") > 0);
    }
}
