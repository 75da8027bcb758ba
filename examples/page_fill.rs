//! How much of the frame the curves of each page use, measured from an atlas's
//! `index.json`: per page, the union of its curves' `bbox_px` as a fraction of the
//! frame's width and of its height (the frame: inside the margins, below the header and
//! above the footer, at the spec's paper and DPI, in the page's own orientation: the
//! index's `page.orientation`). Prints the medians, the pages under half the height and
//! under 60 % in either direction, and how many pages are landscape.
//!
//! `cargo run --release --example page_fill -- OUT/index.json`

use coupler_atlas::layout::{PageSetup, PageSize};
use std::collections::BTreeMap;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn main() {
    let path = std::env::args()
        .nth(1)
        .expect("usage: page_fill OUT/index.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let index: serde_json::Value = serde_json::from_str(&text).expect("index.json is JSON");
    let pages = &index["spec"]["pages"];
    let paper = pages["size"].as_str().unwrap_or("tabloid");
    let spec_orientation = pages["orientation"].as_str().unwrap_or("portrait");
    let dpi = pages["dpi"].as_f64().unwrap_or(300.0);
    // The frame of a page in its own orientation (under `auto` each page has its own).
    let frame_px = |orientation: &str| -> (f64, f64) {
        let size: PageSize = format!("{paper}-{orientation}").parse().expect("page size");
        let setup = PageSetup {
            size,
            dpi,
            ..PageSetup::default()
        };
        let k = setup.px_per_pt();
        let f = setup.frame_pt();
        ((f[2] - f[0]) * k, (f[3] - f[1]) * k)
    };
    // Per page: the union of its curves' boxes, and its frame.
    let mut boxes: BTreeMap<String, ([f64; 4], (f64, f64))> = BTreeMap::new();
    for c in index["curves"].as_array().expect("curves") {
        let Some(p) = c.get("page") else { continue };
        let file = p["file"].as_str().unwrap_or_default().to_string();
        let b: Vec<f64> = p["bbox_px"]
            .as_array()
            .expect("bbox_px")
            .iter()
            .map(|x| x.as_f64().unwrap_or(f64::NAN))
            .collect();
        // One PDF holds every page: tell pages apart by their number.
        let key = format!(
            "{file}#{}",
            p.get("number").map_or(0, |n| n.as_u64().unwrap_or(0))
        );
        let orientation = p["orientation"].as_str().unwrap_or(spec_orientation);
        let e = boxes.entry(key).or_insert((
            [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY],
            frame_px(orientation),
        ));
        e.0 = [
            e.0[0].min(b[0]),
            e.0[1].min(b[1]),
            e.0[2].max(b[2]),
            e.0[3].max(b[3]),
        ];
    }
    let landscape = index["curves"]
        .as_array()
        .expect("curves")
        .iter()
        .filter_map(|c| c.get("page"))
        .filter(|p| p["orientation"].as_str() == Some("landscape"))
        .map(|p| (p["file"].as_str(), p.get("number").and_then(|n| n.as_u64())))
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    let mut w: Vec<f64> = boxes
        .values()
        .map(|(b, (fw, _))| (b[2] - b[0]) / fw)
        .collect();
    let mut h: Vec<f64> = boxes
        .values()
        .map(|(b, (_, fh))| (b[3] - b[1]) / fh)
        .collect();
    let mut both: Vec<f64> = w.iter().zip(&h).map(|(a, b)| a.min(*b)).collect();
    let mut area: Vec<f64> = w.iter().zip(&h).map(|(a, b)| a * b).collect();
    let under_half = h.iter().filter(|x| **x < 0.5).count();
    let under_60 = both.iter().filter(|x| **x < 0.6).count();
    println!(
        "{} pages; median fraction of the frame covered by the curves: width {:.3}, height {:.3}, min(width, height) {:.3}, area {:.3}; pages under half the height: {}; pages under 60 % in width or height: {}; landscape pages: {}",
        boxes.len(),
        median(&mut w),
        median(&mut h),
        median(&mut both),
        median(&mut area),
        under_half,
        under_60,
        landscape
    );
}
