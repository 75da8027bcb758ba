//! Renders one sample page: `cargo run --release --example page -- OUT.png [DPI]`.
use coupler_atlas::layout::{LinkagePage, PageSetup, compute_page, layout_page};
use coupler_atlas::render::{RasterPage, SvgPage, draw};
use coupler_atlas::{Circuit, CouplerPoint, FourBar};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(2).map(String::as_str) == Some("crop") {
        let n: Vec<u32> = args[3..7].iter().map(|s| s.parse().unwrap()).collect();
        let im = image::open(&args[1]).unwrap().to_luma8();
        let c = image::imageops::crop_imm(&im, n[0], n[1], n[2], n[3]).to_image();
        c.save(&args[7]).unwrap();
        return;
    }
    let out = args.get(1).cloned().unwrap_or_else(|| "page.png".into());
    let dpi: f64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(100.0);
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
    let setup = PageSetup {
        dpi,
        spec_name: "sample".into(),
        settings: "Δ = 10°, f = 0.6".into(),
        ..PageSetup::default()
    };
    let geo = compute_page(&page, &setup).unwrap();
    let lay = layout_page(&page, &geo, &setup);
    let (w, h) = setup.size_px();
    let mut r = RasterPage::new(w, h, dpi).unwrap();
    draw(&lay.display, &mut r);
    r.finish_png(std::fs::File::create(&out).unwrap()).unwrap();
    let mut s = SvgPage::new(lay.display.width, lay.display.height);
    draw(&lay.display, &mut s);
    std::fs::write(format!("{out}.svg"), s.finish()).unwrap();
}

/// `cargo run --example page -- IN.png crop x y w h OUT.png` crops (for looking at detail).
#[allow(dead_code)]
fn crop() {}
