//! The contents pages: every linkage of the atlas with its pages.

use crate::atlas::{MU_WARNING_DEG, fmt_sig, is_pin_point};
use crate::page::{
    Anchor, DisplayList, Ink, PagePoint, PageSetup, Primitive, fit_into, footer_settings,
    inset_rect, style,
};
use coupler_kinematics::{Circuit, CouplerPoint, CrankTable, Curve, Linkage, Mechanism};

/// One line of the contents: a linkage and its pages.
#[derive(Clone, Debug, PartialEq)]
pub struct ContentsEntry {
    /// The mechanism.
    pub linkage: Linkage,
    /// Its circuit.
    pub circuit: Circuit,
    /// Number of coupler points (curves).
    pub curves: usize,
    /// First page (1-based, inclusive).
    pub first_page: usize,
    /// Last page (inclusive).
    pub last_page: usize,
    /// The coupler points of each of its pages, in page order (for the thumbnails; may
    /// be empty).
    pub pages: Vec<Vec<CouplerPoint>>,
}

/// A contents page: what to draw, and its links (a box on the page and the atlas page
/// number it goes to).
#[derive(Clone, Debug, PartialEq)]
pub struct ContentsPage {
    /// What to draw.
    pub display: DisplayList,
    /// Link areas (points) and their atlas page numbers (1-based).
    pub links: Vec<([f64; 4], usize)>,
}

/// Row height of the contents, points.
const ROW: f64 = 60.0;
/// Width of the text column.
const TEXT_COL: f64 = 170.0;

/// Lays out the contents: one row per linkage, its dimensions, class, transmission-angle
/// range and pages beside a thumbnail of each page's curves (with its number), in as many
/// pages as needed (at least one). Each thumbnail links to its page.
pub fn layout_contents(entries: &[ContentsEntry], setup: &PageSetup) -> Vec<ContentsPage> {
    let (w, h) = setup.size_pt();
    let m = setup.margin_pt;
    let top = m + 44.0;
    let rows = (((h - m - 20.0) - top) / ROW).floor().max(1.0) as usize;
    let n_pages = entries.len().div_ceil(rows).max(1);
    let mut pages = Vec::with_capacity(n_pages);
    for pi in 0..n_pages {
        let mut dl = DisplayList::new(w, h);
        let mut links = Vec::new();
        dl.text(
            [m, m + style::TITLE_SIZE],
            style::TITLE_SIZE,
            Anchor::Start,
            format!("Contents: {}", setup.spec_name),
        );
        dl.text(
            [w - m, m + style::TITLE_SIZE],
            style::TEXT_SIZE,
            Anchor::End,
            format!("contents page {} of {}", pi + 1, n_pages),
        );
        dl.text(
            [m, m + style::TITLE_SIZE + 15.0],
            style::SMALL_SIZE,
            Anchor::Start,
            "each linkage (crank = 1) with its pages: a thumbnail of each page's curves, its page number below; μ: transmission angle over the turn (⚠ under 30°)",
        );
        for (r, e) in entries.iter().skip(pi * rows).take(rows).enumerate() {
            let y = top + r as f64 * ROW;
            if r > 0 {
                dl.ink(Ink::Gray(60));
                dl.line(vec![[m, y - 3.0], [w - m, y - 3.0]], 0.3);
                dl.ink(Ink::Black);
            }
            let dims = e
                .linkage
                .dimensions()
                .iter()
                .map(|(n, v)| format!("{n} = {}", fmt_sig(*v)))
                .collect::<Vec<_>>()
                .join("   ");
            dl.text([m, y + 11.0], style::TEXT_SIZE, Anchor::Start, dims);
            dl.text(
                [m, y + 22.0],
                style::SMALL_SIZE,
                Anchor::Start,
                format!("{}, {}", e.linkage.class_description(), e.circuit.name()),
            );
            if let Some([lo, hi]) = e.linkage.transmission_range(e.circuit) {
                let (lo, hi) = (lo.to_degrees(), hi.to_degrees());
                let warn = if lo < MU_WARNING_DEG { "  ⚠" } else { "" };
                dl.text(
                    [m, y + 32.0],
                    style::SMALL_SIZE,
                    Anchor::Start,
                    format!("μ {lo:.1}°–{hi:.1}°{warn}"),
                );
            }
            let pages_text = if e.first_page == e.last_page {
                format!("page {}", e.first_page)
            } else {
                format!("pages {}–{}", e.first_page, e.last_page)
            };
            dl.text([m, y + 42.0], style::SMALL_SIZE, Anchor::Start, pages_text);
            links.push(([m, y, m + TEXT_COL - 8.0, y + ROW - 6.0], e.first_page));
            // Thumbnails.
            let n = e.pages.len().max(1);
            let avail = w - 2.0 * m - TEXT_COL;
            let bw = (avail / n as f64 - 6.0).min(100.0);
            let bh = ROW - 16.0;
            let table = CrankTable::over(5.0, e.linkage.period_deg()).expect("valid step");
            let poses = e.linkage.pose_table(e.circuit, &table);
            let a = e.linkage.coupler_length();
            let mut curve = Curve::default();
            for (k, pts) in e.pages.iter().enumerate() {
                let x0 = m + TEXT_COL + k as f64 * (bw + 6.0);
                let rect = [x0, y, x0 + bw, y + bh];
                let mut lines: Vec<Vec<(f64, f64)>> = Vec::new();
                let mut bb = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];
                for q in pts.iter().filter(|q| !is_pin_point(a, **q)) {
                    poses.trace_into(*q, &mut curve);
                    let mut line = Vec::with_capacity(curve.len() + 1);
                    for i in 0..curve.len() {
                        if curve.is_valid(i) {
                            line.push((curve.x[i], curve.y[i]));
                            bb = [
                                bb[0].min(curve.x[i]),
                                bb[1].min(curve.y[i]),
                                bb[2].max(curve.x[i]),
                                bb[3].max(curve.y[i]),
                            ];
                        }
                    }
                    if let Some(&first) = line.first() {
                        line.push(first);
                    }
                    lines.push(line);
                }
                dl.ink(Ink::Gray(90));
                dl.rect(rect, 0.3);
                dl.ink(Ink::Black);
                if bb[0].is_finite() {
                    let t = fit_into(bb, inset_rect(rect, 2.0), &[]);
                    let polylines: Vec<Vec<PagePoint>> = lines
                        .iter()
                        .map(|l| l.iter().map(|(x, y)| t.map(*x, *y)).collect())
                        .collect();
                    dl.items.push(Primitive::Polylines {
                        lines: polylines,
                        width: 0.3,
                    });
                }
                let number = e.first_page + k;
                dl.text(
                    [x0 + 0.5 * bw, y + bh + 8.0],
                    style::SMALL_SIZE,
                    Anchor::Middle,
                    number.to_string(),
                );
                links.push(([x0, y, x0 + bw, y + bh + 9.0], number));
            }
        }
        dl.text([w - m, h - m], 6.0, Anchor::End, footer_settings(setup));
        pages.push(ContentsPage { display: dl, links });
    }
    pages
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::FourBar;

    #[test]
    fn contents_paginates() {
        let e = ContentsEntry {
            linkage: FourBar::new(3.0, 2.0, 3.0).unwrap().into(),
            circuit: Circuit::Open,
            curves: 40,
            first_page: 1,
            last_page: 4,
            pages: Vec::new(),
        };
        let many = vec![e; 1000];
        let pages = layout_contents(&many, &PageSetup::default());
        assert!(pages.len() >= 2);
        assert!(!layout_contents(&[], &PageSetup::default()).is_empty());
    }
}
