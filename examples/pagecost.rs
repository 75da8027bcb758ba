//! Where a raster page's CPU goes, by primitive kind, on pages of the default atlas:
//! `cargo run --release --example pagecost -- [EVERY] [REPS] [OUT]`.
//!
//! Lays out every EVERY-th page of the built-in atlas (default 5: 175 of 875 pages) once,
//! then draws and encodes them REPS times (default 3) on one reused buffer, one thread,
//! and prints the median per-page time of each phase and primitive kind. A digest of all
//! PNG bytes shows whether a change kept the pages byte-identical; with OUT, the pages are
//! also written there (`page-NNNN.png`) for `cmp`.
use coupler_atlas::Spec;
use coupler_atlas::generate::{
    Job, PageOptions, PageSource, PageTimings, median, thread_cpu_seconds,
};
use coupler_atlas::layout::{Anchor, DisplayList, Ink, PagePoint};
use coupler_atlas::render::{Canvas, PngCompression, RasterPage, draw};
use std::time::Instant;

const KINDS: [&str; 10] = [
    "dash sets",
    "polylines",
    "rects",
    "polygons",
    "circles",
    "text",
    "text + halo",
    "clear",
    "encode",
    "gray flush",
];

/// Times every call by kind.
struct Timed<'a> {
    page: &'a mut RasterPage,
    ns: [f64; KINDS.len()],
}

impl Timed<'_> {
    fn time(&mut self, k: usize, f: impl FnOnce(&mut RasterPage)) {
        let t = Instant::now();
        f(self.page);
        self.ns[k] += t.elapsed().as_nanos() as f64;
    }
}

impl Canvas for Timed<'_> {
    fn stroke_polyline(&mut self, points: &[PagePoint], width: f64) {
        self.time(1, |p| p.stroke_polyline(points, width));
    }
    fn stroke_polylines(&mut self, lines: &[Vec<PagePoint>], width: f64) {
        self.time(0, |p| p.stroke_polylines(lines, width));
    }
    fn stroke_rect(&mut self, rect: [f64; 4], width: f64) {
        self.time(2, |p| p.stroke_rect(rect, width));
    }
    fn fill_polygon(&mut self, points: &[PagePoint]) {
        self.time(3, |p| p.fill_polygon(points));
    }
    fn circle(&mut self, center: PagePoint, radius: f64, width: Option<f64>) {
        self.time(4, |p| p.circle(center, radius, width));
    }
    fn text(&mut self, pos: PagePoint, size: f64, anchor: Anchor, text: &str, halo: f64) {
        let k = if halo > 0.0 { 6 } else { 5 };
        if halo > 0.0 {
            // The gray layer is composited before a halo: timed on its own.
            self.time(9, |p| {
                p.ink();
            });
        }
        self.time(k, |p| p.text(pos, size, anchor, text, halo));
    }
    fn set_ink(&mut self, ink: Ink) {
        self.page.set_ink(ink);
    }
}

/// `PAGECOST_BANDS=1`: the same pages drawn whole then encoded (`draw` + `take_png`)
/// and drawn and encoded band by band (`render_png`), passes alternated REPS times in
/// this one thread: CPU per page of each pass, the median of each and of the pair
/// ratios, and both digests (which must agree).
fn bands_ab(pages: &[(u64, DisplayList)], buf: &mut RasterPage, dpi: f64, reps: usize) {
    let n = pages.len() as f64;
    let (mut whole, mut banded, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
    let mut digests = [0u64; 2];
    for rep in 0..reps {
        let mut pair = [0.0; 2];
        let only = std::env::var("PAGECOST_BANDS").unwrap_or_default();
        for (mode, cpu) in pair.iter_mut().enumerate() {
            if (only == "whole" && mode == 1) || (only == "bands" && mode == 0) {
                continue;
            }
            let mut digest = 0xcbf2_9ce4_8422_2325u64;
            let c0 = thread_cpu_seconds().unwrap_or(0.0);
            for (_, display) in pages {
                let (pw, ph) = display.size_px(dpi);
                if (buf.width(), buf.height()) != (pw, ph) && !buf.reshape(pw, ph) {
                    *buf = RasterPage::new(pw, ph, dpi).expect("page");
                }
                let bytes = if mode == 0 {
                    buf.clear();
                    draw(display, buf);
                    buf.take_png(PngCompression::Fast).expect("encodes")
                } else {
                    buf.render_png(display, PngCompression::Fast)
                        .expect("encodes")
                        .0
                };
                for b in &bytes {
                    digest = (digest ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3);
                }
            }
            *cpu = (thread_cpu_seconds().unwrap_or(0.0) - c0) * 1e3 / n;
            digests[mode] = digest;
        }
        println!(
            "pass {rep}: whole {:.2} ms, bands {:.2} ms CPU per page",
            pair[0], pair[1]
        );
        whole.push(pair[0]);
        banded.push(pair[1]);
        ratio.push(pair[1] / pair[0]);
    }
    println!(
        "median CPU per page: whole {:.2} ms, bands {:.2} ms, ratio {:.3}; digests {:016x} {:016x}{}",
        median(whole),
        median(banded),
        median(ratio),
        digests[0],
        digests[1],
        if digests[0] == digests[1] {
            ""
        } else {
            " DIFFER"
        }
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let every: usize = args.get(1).map_or(5, |s| s.parse().expect("EVERY"));
    let reps: usize = args.get(2).map_or(3, |s| s.parse().expect("REPS"));
    let out = args.get(3).map(std::path::PathBuf::from);
    let spec = Spec::default_atlas();
    let opts = PageOptions::from_spec(&spec).expect("page options");
    let job = Job::new(spec, "default", "unused", 1);
    let source = PageSource::new(&job, opts.setup.curves_per_page).expect("page source");
    let timings = PageTimings::default();
    let t = Instant::now();
    let mut pages: Vec<(u64, DisplayList)> = Vec::new();
    for g in job.groups() {
        let feats = source.features(&g).expect("curves");
        for pj in source.pages(&g, &feats) {
            if (pj.number - 1) % every as u64 != 0 {
                continue;
            }
            let layout = pj.layout(&opts.setup, &timings).expect("layout");
            pages.push((pj.number, layout.display));
        }
    }
    let ([compute, layout, ..], _) = timings.seconds();
    let n = pages.len() as f64;
    println!(
        "{} pages laid out in {:.1} s (per page: compute {:.2} ms, layout {:.2} ms)",
        pages.len(),
        t.elapsed().as_secs_f64(),
        compute * 1e3 / n,
        layout * 1e3 / n
    );
    let (w, h) = opts.setup.size_px();
    let mut buf = RasterPage::new(w, h, opts.setup.dpi).expect("page");
    if std::env::var_os("PAGECOST_BANDS").is_some() {
        bands_ab(&pages, &mut buf, opts.setup.dpi, reps);
        return;
    }
    let mut runs: Vec<[f64; KINDS.len()]> = Vec::new();
    let mut totals = Vec::new();
    let mut cpu = Vec::new();
    let mut digest = 0xcbf2_9ce4_8422_2325u64;
    let mut bytes_total = 0usize;
    if let Some(o) = &out {
        std::fs::create_dir_all(o).expect("out folder");
    }
    for rep in 0..reps {
        let mut ns = [0.0; KINDS.len()];
        let t0 = Instant::now();
        let c0 = thread_cpu_seconds().unwrap_or(0.0);
        for (number, display) in &pages {
            let t = Instant::now();
            // Each page at its own size (portrait or landscape): the buffer is turned.
            let (pw, ph) = display.size_px(opts.setup.dpi);
            if (buf.width(), buf.height()) != (pw, ph) {
                if !buf.reshape(pw, ph) {
                    buf = RasterPage::new(pw, ph, opts.setup.dpi).expect("page");
                }
            } else {
                buf.clear();
            }
            ns[7] += t.elapsed().as_nanos() as f64;
            let mut timed = Timed {
                page: &mut buf,
                ns: [0.0; KINDS.len()],
            };
            draw(display, &mut timed);
            for (a, b) in ns.iter_mut().zip(timed.ns) {
                *a += b;
            }
            let t = Instant::now();
            let bytes = buf.take_png(PngCompression::Fast).expect("encodes");
            ns[8] += t.elapsed().as_nanos() as f64;
            if rep == 0 {
                bytes_total += bytes.len();
                for b in &bytes {
                    digest = (digest ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3);
                }
                if let Some(o) = &out {
                    std::fs::write(o.join(format!("page-{number:04}.png")), &bytes)
                        .expect("writes");
                }
            }
        }
        totals.push(t0.elapsed().as_secs_f64() * 1e3 / n);
        cpu.push((thread_cpu_seconds().unwrap_or(0.0) - c0) * 1e3 / n);
        runs.push(ns);
    }
    if std::env::var_os("PAGE_WIDTHS").is_some() {
        // Stroke widths over the pages: segments and items per width.
        let mut by: std::collections::BTreeMap<String, (usize, usize)> = Default::default();
        for (_, display) in &pages {
            let mut ink = Ink::Black;
            for item in &display.items {
                let (n, w) = match item {
                    coupler_atlas::layout::Primitive::Ink(k) => {
                        ink = *k;
                        continue;
                    }
                    coupler_atlas::layout::Primitive::Polyline { points, width } => {
                        (points.len().saturating_sub(1), *width)
                    }
                    coupler_atlas::layout::Primitive::Polylines { lines, width } => (
                        lines.iter().map(|l| l.len().saturating_sub(1)).sum(),
                        *width,
                    ),
                    _ => continue,
                };
                let e = by.entry(format!("{w:5.2} {ink:?}")).or_default();
                e.0 += n;
                e.1 += 1;
            }
        }
        for (k, (segs, items)) in by {
            println!("width {k}: {segs} segments in {items} items");
        }
    }
    if let Ok(k) = std::env::var("PAGE_DUMP") {
        let k: u64 = k.parse().expect("PAGE_DUMP");
        for (number, display) in &pages {
            if *number == k {
                for (i, item) in display.items.iter().enumerate() {
                    let d = format!("{item:?}");
                    println!("#{i:4} {}", &d[..d.len().min(110)]);
                }
            }
        }
    }
    if let Ok(k) = std::env::var("PAGE_ITEMS") {
        let (_, display) = &pages[k.parse::<usize>().expect("PAGE_ITEMS")];
        let mut costs = Vec::new();
        buf.clear();
        for (i, item) in display.items.iter().enumerate() {
            let mut one = DisplayList::new(display.width, display.height);
            one.items.push(item.clone());
            let mut best = f64::MAX;
            for _ in 0..5 {
                let t = Instant::now();
                draw(&one, &mut buf);
                best = best.min(t.elapsed().as_secs_f64() * 1e3);
            }
            costs.push((best, i));
        }
        costs.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (ms, i) in costs.iter().take(25) {
            let ink = display.items[..*i]
                .iter()
                .rev()
                .find_map(|p| match p {
                    coupler_atlas::layout::Primitive::Ink(k) => Some(*k),
                    _ => None,
                })
                .unwrap_or(Ink::Black);
            let d = format!("{ink:?} {:?}", display.items[*i]);
            println!("{ms:7.3} ms  #{i:4} {}", &d[..d.len().min(150)]);
        }
    }
    println!(
        "digest {digest:016x}, {:.0} KB per page",
        bytes_total as f64 / n / 1e3
    );
    println!(
        "per page (median of {reps}): {:.2} ms wall, {:.2} ms CPU; by kind (wall):",
        median(totals.clone()),
        median(cpu.clone())
    );
    for (k, name) in KINDS.iter().enumerate() {
        let v: Vec<f64> = runs.iter().map(|r| r[k] * 1e-6 / n).collect();
        println!("  {name:12} {:6.2} ms", median(v));
    }
}
