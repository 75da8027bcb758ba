//! Golden pages and pixel-exact primitives.
//!
//! Golden pages: `generate atlas-spec/hartenberg-denavit.toml --dpi 72` (and two pages of
//! `atlas-spec/classics.toml`) must give, page
//! for page, the same decoded pixels as the PNGs committed in `tests/golden/` (compared
//! by pixels, not bytes: PNG streams may change with the encoder version). On a mismatch
//! the test writes `target/golden-diff/NAME.diff.png` and the score, and fails.
//!
//! Re-bless after an intended change (then look at the new pages before committing):
//!
//! ```text
//! BLESS=1 cargo test --release --test golden
//! ```

#![allow(clippy::needless_range_loop)] // pixel rows and columns read best as indices

use coupler_atlas::layout::{Anchor, PagePoint};
use coupler_atlas::render as diff;
use coupler_atlas::render::{Canvas, RasterPage, SvgPage};
use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_coupler-atlas");
const GOLDEN_DPI: &str = "72";
/// Pages kept as golden images (a small set: first, middle, last, and the contents).
const GOLDEN_PAGES: [&str; 4] = [
    "hartenberg-denavit-0001.png",
    "hartenberg-denavit-0005.png",
    "hartenberg-denavit-0010.png",
    "hartenberg-denavit-0000-contents-001.png",
];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "coupler-atlas-golden-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn generate(out: &Path, extra: &[&str]) {
    generate_spec("atlas-spec/hartenberg-denavit.toml", out, extra)
}

fn generate_spec(spec: &str, out: &Path, extra: &[&str]) {
    let spec = root().join(spec);
    let mut args = vec![
        "generate".to_string(),
        spec.to_str().unwrap().into(),
        "--out".into(),
        out.to_str().unwrap().into(),
        "--quiet".into(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let o = Command::new(BIN)
        .args(&args)
        .output()
        .expect("run coupler-atlas");
    assert!(
        o.status.success(),
        "generate failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn golden_pages_match() {
    check_golden("atlas-spec/hartenberg-denavit.toml", &GOLDEN_PAGES);
}

/// The classics page set: Chebyshev (two branches of a Grashof double rocker) and Watt
/// (one branch across two toggles).
#[test]
fn golden_classic_pages_match() {
    check_golden(
        "atlas-spec/classics.toml",
        &["classics-0002.png", "classics-0003.png"],
    );
}

/// A geared five-bar page (λ = −1/2: two input turns, 72 dashes; the gears' pitch
/// circles; Ting's class, λ, φ and μ in the header).
#[test]
fn golden_geared_pages_match() {
    check_golden("atlas-spec/geared-quick.toml", &["geared-quick-0007.png"]);
}

fn check_golden(spec: &str, pages: &[&str]) {
    let out = tmp(&format!("golden-{}", spec.replace('/', "-")));
    generate_spec(spec, &out, &["--dpi", GOLDEN_DPI, "--jobs", "2"]);
    let golden = root().join("tests/golden");
    let bless = std::env::var_os("BLESS").is_some();
    let diff_dir = root().join("target/golden-diff");
    let mut failures = Vec::new();
    for &name in pages {
        let got = out.join("pages").join(name);
        let want = golden.join(name);
        if bless {
            std::fs::create_dir_all(&golden).unwrap();
            std::fs::copy(&got, &want).unwrap();
            continue;
        }
        assert!(
            want.exists(),
            "missing golden {} (run BLESS=1 cargo test --test golden)",
            want.display()
        );
        match diff::diff_files(&want, &got, 0) {
            Ok(d) if d.is_identical() => {}
            Ok(d) => {
                std::fs::create_dir_all(&diff_dir).unwrap();
                let p = diff_dir.join(name.replace(".png", ".diff.png"));
                d.write_image(&p).unwrap();
                std::fs::copy(&got, diff_dir.join(name)).unwrap();
                failures.push(format!(
                    "{name}: {} (diff image {})",
                    d.summary(),
                    p.display()
                ));
            }
            Err(e) => failures.push(format!("{name}: {e}")),
        }
    }
    let _ = std::fs::remove_dir_all(&out);
    assert!(
        failures.is_empty(),
        "golden pages differ:\n{}\nre-bless with BLESS=1 cargo test --test golden",
        failures.join("\n")
    );
}

#[test]
fn pages_are_byte_identical_for_any_jobs_and_index_points_at_them() {
    let (a, b) = (tmp("j1"), tmp("j2"));
    generate(&a, &["--dpi", "50", "--jobs", "1", "--format", "png,svg"]);
    generate(&b, &["--dpi", "50", "--jobs", "2", "--format", "png,svg"]);
    let mut names: Vec<_> = std::fs::read_dir(a.join("pages"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert_eq!(
        names.len(),
        2 * 11,
        "10 pages + 1 contents, png and svg: {names:?}"
    );
    for n in &names {
        let x = std::fs::read(a.join("pages").join(n)).unwrap();
        let y = std::fs::read(b.join("pages").join(n)).unwrap();
        assert!(x == y, "{n:?} differs between --jobs 1 and --jobs 2");
    }
    let ia = std::fs::read(a.join("index.json")).unwrap();
    assert!(
        ia == std::fs::read(b.join("index.json")).unwrap(),
        "index differs"
    );
    // Every curve points at an existing page, inside its pixels, and the box holds ink.
    let index: serde_json::Value = serde_json::from_slice(&ia).unwrap();
    assert_eq!(index["summary"]["pages"], 10);
    let curves = index["curves"].as_array().unwrap();
    assert_eq!(curves.len(), 90);
    for c in curves {
        let file = c["page"]["file"].as_str().expect("page file");
        let img = image::open(a.join(file)).unwrap().to_luma8();
        let b: Vec<u32> = c["page"]["bbox_px"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap() as u32)
            .collect();
        assert!(
            b[0] < b[2] && b[1] < b[3] && b[2] <= img.width() && b[3] <= img.height(),
            "{file} {b:?}"
        );
        let ink = (b[1]..b[3])
            .flat_map(|y| (b[0]..b[2]).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0[0] < 128)
            .count();
        assert!(ink > 0, "no ink in the box of curve {} on {file}", c["id"]);
    }
    // The PNG records its resolution: 50 dpi = 1969 pixels per metre.
    let bytes = std::fs::read(a.join("pages/hartenberg-denavit-0001.png")).unwrap();
    let dec = png::Decoder::new(std::io::Cursor::new(bytes))
        .read_info()
        .unwrap();
    let info = dec.info();
    assert_eq!(info.color_type, png::ColorType::Grayscale);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    let dims = info.pixel_dims.expect("pHYs chunk");
    assert_eq!(
        (dims.xppu, dims.yppu, dims.unit),
        (1969, 1969, png::Unit::Meter)
    );
    let _ = std::fs::remove_dir_all(&a);
    let _ = std::fs::remove_dir_all(&b);
}

#[test]
fn no_pages_writes_index_only() {
    let out = tmp("nopages");
    generate(&out, &["--no-pages"]);
    assert!(out.join("index.json").exists());
    assert!(!out.join("pages").exists());
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn bad_page_flags_are_usage_errors() {
    for (flag, value) in [("--format", "tiff"), ("--page-size", "b5"), ("--dpi", "0")] {
        let o = Command::new(BIN)
            .args([
                "generate",
                "--dry-run",
                "--out",
                "/tmp/unused-golden",
                flag,
                value,
            ])
            .output()
            .unwrap();
        assert_eq!(
            o.status.code(),
            Some(2),
            "{flag} {value}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

// ---- pixel-exact primitives ------------------------------------------------------------

/// A canvas at 72 dpi: one pixel per point, so page coordinates are pixel coordinates.
fn canvas(w: u32, h: u32) -> RasterPage {
    RasterPage::new(w, h, 72.0).unwrap()
}

fn rows(page: &mut RasterPage) -> Vec<Vec<u8>> {
    let w = page.width() as usize;
    page.ink().chunks(w).map(|r| r.to_vec()).collect()
}

#[test]
fn pixel_aligned_stroke_is_exact() {
    // A 2-px-wide horizontal line centred on the pixel boundary y = 4 covers rows 3 and
    // 4 exactly; round caps reach 1 px beyond the ends.
    let mut p = canvas(16, 8);
    p.stroke_polyline(&[[3.0, 4.0], [13.0, 4.0]], 2.0);
    let r = rows(&mut p);
    for x in 3..13 {
        assert_eq!((r[3][x], r[4][x]), (255, 255), "x = {x}");
        assert_eq!((r[2][x], r[5][x]), (0, 0), "x = {x}");
    }
    for y in 0..8 {
        assert_eq!((r[y][0], r[y][15]), (0, 0));
        // Left-right symmetry of the caps.
        for x in 0..16 {
            assert_eq!(r[y][x], r[y][15 - x], "({x}, {y})");
        }
    }
    // Total ink = area of the stadium (20 px² rectangle + π px² of caps), within AA error.
    let ink: f64 = p.ink().iter().map(|&v| f64::from(v) / 255.0).sum();
    assert!((ink - (20.0 + std::f64::consts::PI)).abs() < 0.3, "{ink}");
}

#[test]
fn half_pixel_offset_is_kept_not_snapped() {
    // Width 1 at y = 4.5 fills row 4 only; at y = 4.0 it straddles rows 3 and 4 at half
    // coverage each. An integer-pixel backend cannot tell these apart.
    let mut a = canvas(12, 8);
    a.stroke_polyline(&[[2.0, 4.5], [10.0, 4.5]], 1.0);
    let mut b = canvas(12, 8);
    b.stroke_polyline(&[[2.0, 4.0], [10.0, 4.0]], 1.0);
    let (ra, rb) = (rows(&mut a), rows(&mut b));
    for x in 3..9 {
        assert_eq!((ra[3][x], ra[4][x], ra[5][x]), (0, 255, 0), "x = {x}");
        // Half coverage each: 127.5 levels, rounded to 127 or 128 in 8 bits.
        let (u, v) = (rb[3][x], rb[4][x]);
        assert!(
            (127..=128).contains(&u) && (127..=128).contains(&v),
            "x = {x}: {u} {v}"
        );
    }
}

#[test]
fn dashes_leave_clean_gaps() {
    // Three dashes of 6 px with 4 px gaps (the 10° / 60 % pattern at 1 px per degree),
    // stroked as separate polylines, 1 px wide along the middle of row 2: gaps have no
    // ink at all (round caps reach half a pixel beyond each end), dash cores are solid,
    // nothing spills into rows 1 and 3.
    let mut p = canvas(40, 6);
    for k in 0..3 {
        let x0 = 4.0 + 10.0 * k as f64;
        p.stroke_polyline(&[[x0, 2.5], [x0 + 3.0, 2.5], [x0 + 6.0, 2.5]], 1.0);
    }
    let r = rows(&mut p);
    for k in 0..3 {
        let x0 = 4 + 10 * k;
        for x in x0..x0 + 6 {
            assert_eq!((r[1][x], r[2][x], r[3][x]), (0, 255, 0), "dash {k} x {x}");
        }
        if k < 2 {
            for x in x0 + 7..x0 + 9 {
                assert_eq!(r[2][x], 0, "gap after dash {k} at x {x}");
            }
        }
    }
    // Exactly 3 runs of ink along row 2: the dashes can be counted.
    let runs = r[2].windows(2).filter(|w| w[0] == 0 && w[1] > 0).count();
    assert_eq!(runs, 3);
}

#[test]
fn filled_disc_and_text_draw_ink() {
    let mut p = canvas(20, 20);
    p.circle([10.0, 10.0], 4.0, None);
    let r = rows(&mut p);
    assert_eq!(r[10][10], 255);
    assert_eq!(r[10][15], 0);
    let ink: f64 = p.ink().iter().map(|&v| f64::from(v) / 255.0).sum();
    assert!((ink - std::f64::consts::PI * 16.0).abs() < 0.5, "{ink}");
    let mut t = canvas(60, 16);
    t.text([2.0, 12.0], 12.0, Anchor::Start, "(1, 2)", 0.0);
    assert!(t.ink().iter().filter(|&&v| v > 128).count() > 20);
}

#[test]
fn rectangle_frame_has_exact_area_coverage() {
    // A frame [2, 2, 10, 6] with a 1-px stroke: edges on pixel centres ± 0.5 → the band
    // covers whole pixels exactly (1.5..2.5 covers half of pixel 1 and half of pixel 2).
    let mut p = canvas(12, 8);
    p.stroke_rect([2.5, 2.5, 9.5, 5.5], 1.0);
    let r = rows(&mut p);
    for x in 2..=9 {
        assert_eq!((r[2][x], r[5][x]), (255, 255), "top/bottom x = {x}");
        assert_eq!((r[1][x], r[6][x]), (0, 0), "x = {x}");
    }
    for x in 3..=8 {
        assert_eq!((r[3][x], r[4][x]), (0, 0), "interior x = {x}");
    }
    for y in 2..=5 {
        assert_eq!((r[y][2], r[y][9]), (255, 255), "sides y = {y}");
        assert_eq!((r[y][1], r[y][10]), (0, 0), "outside y = {y}");
    }
    // Interior untouched.
    assert_eq!((r[3][4], r[4][6]), (0, 0));
    // Half-pixel band: 50 % coverage, exactly (exact area, not supersampled).
    let mut q = canvas(6, 6);
    q.stroke_rect([1.0, 1.0, 5.0, 5.0], 1.0);
    let rq = rows(&mut q);
    assert_eq!(rq[0][2], 128);
    assert_eq!(rq[1][2], 128);
    assert_eq!(rq[0][0], 64); // a corner pixel: a quarter of its area
}

#[test]
fn svg_keeps_exact_coordinates() {
    let mut s = SvgPage::new(100.0, 50.0);
    let pts: [PagePoint; 3] = [[1.25, 2.5], [3.125, 4.0], [10.0, 20.0]];
    s.stroke_polyline(&pts, 0.75);
    let svg = s.finish();
    assert!(svg.contains("M1.25 2.5L3.125 4L10 20"), "{svg}");
    assert!(svg.contains("stroke-width=\"0.75\""));
    assert!(svg.contains("width=\"100pt\""));
}
