//! PNG size and encoding time, fast against best compression, on pages already written:
//! `cargo run --release --example png_size -- DIR/pages [N]` (the first N pages, default 40).
use coupler_atlas::render::{PngCompression, encode_png_with};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = args.get(1).expect("usage: png_size DIR/pages [N]");
    let n: usize = args.get(2).map_or(40, |s| s.parse().expect("N"));
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .expect("pages folder")
        .filter_map(|e| Some(e.ok()?.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    files.sort();
    files.truncate(n);
    let mut totals = [(0usize, 0f64); 2];
    for f in &files {
        let img = image::open(f).expect("a page").to_luma8();
        let (w, h) = img.dimensions();
        for (k, c) in [PngCompression::Fast, PngCompression::Best]
            .into_iter()
            .enumerate()
        {
            let mut out = Vec::new();
            let t = Instant::now();
            encode_png_with(img.as_raw(), w, h, 300.0, false, c, &mut out).expect("encodes");
            totals[k].1 += t.elapsed().as_secs_f64();
            totals[k].0 += out.len();
        }
    }
    let n = files.len().max(1) as f64;
    for (name, (bytes, secs)) in ["fast", "best"].iter().zip(totals) {
        println!(
            "{name}: {:.0} KB per page, {:.1} ms per page to encode",
            bytes as f64 / n / 1e3,
            secs / n * 1e3
        );
    }
}
