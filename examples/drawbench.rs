//! Times the phases of one 300 dpi tabloid page: `cargo run --release --example drawbench`.
use coupler_atlas::layout::{LinkagePage, PageSetup, Primitive, compute_page, layout_page};
use coupler_atlas::render::{RasterPage, draw};
use coupler_atlas::{Circuit, CouplerPoint, FourBar};
use std::time::Instant;

fn main() {
    let grid: Vec<CouplerPoint> = (-1..=3)
        .flat_map(|i| (-1..=2).map(move |j| CouplerPoint::new(i as f64, j as f64)))
        .collect();
    let page = LinkagePage {
        linkage: FourBar::new(3.0, 2.0, 3.0).unwrap(),
        circuit: Circuit::Open,
        points: grid[6..16].to_vec(),
        grid,
        page_number: 3,
        page_count: 12,
        features: Vec::new(),
    };
    let setup = PageSetup::default();
    let n = 20;
    let t = Instant::now();
    let mut geo = None;
    for _ in 0..n {
        geo = Some(compute_page(&page, &setup).unwrap());
    }
    let geo = geo.unwrap();
    println!(
        "compute {:.2} ms",
        t.elapsed().as_secs_f64() * 1e3 / n as f64
    );
    let t = Instant::now();
    let mut lay = None;
    for _ in 0..n {
        lay = Some(layout_page(&page, &geo, &setup));
    }
    let lay = lay.unwrap();
    println!(
        "layout {:.2} ms",
        t.elapsed().as_secs_f64() * 1e3 / n as f64
    );
    let (w, h) = setup.size_px();
    let mut r = RasterPage::new(w, h, setup.dpi).unwrap();
    let time = |name: &str, r: &mut RasterPage, f: &dyn Fn(&mut RasterPage)| {
        let t = Instant::now();
        for _ in 0..n {
            r.clear();
            f(r);
        }
        println!(
            "{name} {:.2} ms",
            t.elapsed().as_secs_f64() * 1e3 / n as f64
        );
    };
    time("clear only", &mut r, &|_| {});
    time("draw all", &mut r, &|r| draw(&lay.display, r));
    let mut only_text = lay.display.clone();
    only_text
        .items
        .retain(|i| matches!(i, Primitive::Text { .. }));
    time("draw text only", &mut r, &|r| draw(&only_text, r));
    let mut only_curves = lay.display.clone();
    only_curves
        .items
        .retain(|i| matches!(i, Primitive::Polylines { .. }));
    time("draw dash sets only", &mut r, &|r| draw(&only_curves, r));
    let mut only = lay.display.clone();
    only.items
        .retain(|i| matches!(i, Primitive::Polyline { .. }));
    time("draw single polylines only", &mut r, &|r| draw(&only, r));
    let mut only = lay.display.clone();
    only.items.retain(|i| matches!(i, Primitive::Circle { .. }));
    time("draw circles only", &mut r, &|r| draw(&only, r));
    let mut only = lay.display.clone();
    only.items
        .retain(|i| matches!(i, Primitive::Polygon { .. }));
    time("draw polygons only", &mut r, &|r| draw(&only, r));
    let mut costs: Vec<(f64, usize, f64)> = Vec::new();
    for (i, item) in lay.display.items.iter().enumerate() {
        if let Primitive::Polyline { points, width } = item {
            let mut one = lay.display.clone();
            one.items = vec![item.clone()];
            let t = Instant::now();
            for _ in 0..n {
                draw(&one, &mut r);
            }
            let _ = points;
            costs.push((t.elapsed().as_secs_f64() * 1e3 / n as f64, i, *width));
        }
    }
    costs.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (ms, i, w) in costs.iter().take(6) {
        if let Primitive::Polyline { points, .. } = &lay.display.items[*i] {
            println!(
                "polyline {i}: {ms:.3} ms, {} points, width {w}, first {:?}",
                points.len(),
                points[0]
            );
        }
    }
    println!(
        "{} single polylines, total {:.2} ms",
        costs.len(),
        costs.iter().map(|c| c.0).sum::<f64>()
    );
    let mut bytes = Vec::new();
    let t = Instant::now();
    for _ in 0..n {
        bytes.clear();
        r.clear();
        draw(&lay.display, &mut r);
        r.finish_png(&mut bytes).unwrap();
    }
    println!(
        "clear+draw+encode {:.2} ms ({} bytes)",
        t.elapsed().as_secs_f64() * 1e3 / n as f64,
        bytes.len()
    );
}
