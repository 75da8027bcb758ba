//! Pages as a reader uses them (issue 16): every page of the default atlas holds one
//! linkage and one row of its grid, and every label sits at its own θ = 0 dot (nearer to
//! it than to any other dot) without overlapping another label; classic branches start
//! their dash pattern where they start; the atlas PDF carries real, extractable text.

use coupler_atlas::generate::{Job, PageOptions, PageSource};
use coupler_atlas::layout::{
    Anchor, ClassicGeometry, ClassicPage, LinkagePage, PageGeometry, PageLayout, PageSetup, ascent,
    compute_classic, descent, layout_page, rect_distance, text_width,
};
use coupler_atlas::spec::{DEFAULT_SPEC_TEXT, Spec};
use coupler_atlas::{ClassicCurve, CrankAngle, CurveList, Mechanism};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// One page of the default atlas, laid out as `generate` lays it out: the page jobs of
/// [`PageSource`] (the run's curves, features, shared angle tables and page numbers).
struct AtlasPage {
    page: LinkagePage,
    geo: PageGeometry,
    lay: PageLayout,
}

/// The default atlas, every page laid out once and shared by the tests that read it.
struct DefaultAtlas {
    spec: Spec,
    setup: PageSetup,
    /// Pages the job plans.
    planned: u64,
    /// In page order.
    pages: Vec<AtlasPage>,
}

fn default_atlas() -> &'static DefaultAtlas {
    static ATLAS: OnceLock<DefaultAtlas> = OnceLock::new();
    ATLAS.get_or_init(|| {
        let spec = Spec::parse(DEFAULT_SPEC_TEXT, "default").unwrap();
        let setup = PageOptions::from_spec(&spec).unwrap().setup;
        let job = Job::new(spec.clone(), "default", "unused", 2);
        let source = PageSource::new(&job, setup.curves_per_page).unwrap();
        let groups: Vec<_> = job.groups().collect();
        let pages = groups
            .par_iter()
            .flat_map_iter(|g| {
                let features = source.features(g).unwrap();
                source
                    .pages(g, &features)
                    .map(|pj| {
                        let page = pj.page();
                        let geo = pj.geometry(&page, &setup).unwrap();
                        let lay = layout_page(&page, &geo, &setup);
                        AtlasPage { page, geo, lay }
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        DefaultAtlas {
            planned: job.pages(),
            spec,
            setup,
            pages,
        }
    })
}

/// The pages of `atlas-spec/classics.toml` with their geometry, and the page options.
fn classic_pages() -> (Vec<(ClassicPage, ClassicGeometry)>, PageOptions) {
    let text = std::fs::read_to_string(root().join("atlas-spec/classics.toml")).unwrap();
    let list = CurveList::parse(&text, "classics.toml").unwrap();
    let opts = PageOptions::from_settings(&list.name, &list.sampling, &list.pages).unwrap();
    let n = list.curves.len();
    let pages = list
        .curves
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let page = ClassicPage {
                curve: c.clone(),
                measured: ClassicCurve::compute(c, list.sampling.crank_step_deg),
                page_number: i + 1,
                page_count: n,
                step_deg: list.sampling.crank_step_deg,
            };
            let geo = compute_classic(&page, &opts.setup).unwrap();
            (page, geo)
        })
        .collect();
    (pages, opts)
}

/// A fresh, empty folder for this test process under the system's temp folder.
fn fresh_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("coupler-atlas-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `generate SPEC --out OUT --format pdf --quiet EXTRA…` run from the repository's root;
/// the atlas PDF it wrote, `OUT/pages/NAME.pdf`.
fn generate_pdf(spec: &Path, out: &Path, name: &str, extra: &[&str]) -> Vec<u8> {
    let o = Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
        .arg("generate")
        .arg(spec)
        .arg("--out")
        .arg(out)
        .args(["--format", "pdf", "--quiet"])
        .args(extra)
        .current_dir(root())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let pdf = std::fs::read(out.join(format!("pages/{name}.pdf"))).unwrap();
    assert!(pdf.starts_with(b"%PDF-"));
    pdf
}

/// The box `[x0, y0, x1, y1]` (points) of a line of text at `pos` (its baseline).
fn text_box(pos: [f64; 2], size: f64, anchor: Anchor, text: &str) -> [f64; 4] {
    let w = text_width(size, text);
    let x0 = match anchor {
        Anchor::Start => pos[0],
        Anchor::Middle => pos[0] - 0.5 * w,
        Anchor::End => pos[0] - w,
    };
    [x0, pos[1] - ascent(size), x0 + w, pos[1] + descent(size)]
}

fn overlap(a: [f64; 4], b: [f64; 4]) -> bool {
    a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]
}

/// Fraction of a segment's length inside the rectangle `r` is > 0 (sampled every
/// 0.25 pt).
fn segment_enters(r: [f64; 4], p: [f64; 2], q: [f64; 2]) -> bool {
    let n = ((q[0] - p[0]).hypot(q[1] - p[1]) / 0.25).ceil().max(1.0) as usize;
    (0..=n).any(|k| {
        let t = k as f64 / n as f64;
        let x = p[0] + t * (q[0] - p[0]);
        let y = p[1] + t * (q[1] - p[1]);
        x > r[0] && x < r[2] && y > r[1] && y < r[3]
    })
}

/// Over every curve of the default atlas, laid out exactly as `generate` lays it out
/// (features and all): each page is one linkage and one full row of its grid; each
/// label's nearest θ = 0 dot is its own; no two labels overlap; labels stay in the
/// frame; the dot is where the drawn linkage carries the coupler point at θ = 0; and
/// labels keep clear of the other curves' dashes: at most 3 % of the labels touch a
/// dash of another curve (2.5 % at this commit; those sit on a white halo).
#[test]
fn every_default_page_is_one_family_with_labels_at_their_own_dots() {
    let atlas = default_atlas();
    let row_len = atlas.spec.points.u.len() as usize;
    assert_eq!(
        atlas.setup.curves_per_page, row_len,
        "curves per page follows the row"
    );
    // (labels, labels on another curve's dashes, problems)
    let results: Vec<(usize, usize, Vec<String>)> = atlas
        .pages
        .par_iter()
        .map(|AtlasPage { page, geo, lay }| {
            let mut bad = Vec::new();
            let (mut labels, mut on_ink) = (0, 0);
            let f0 = page
                .linkage
                .drawing(page.circuit, &CrankAngle::from_degrees(0.0));
            let frame0 = f0.coupler.expect("a four-bar has a coupler");
            let number = page.page_number;
            let pts = &page.points;
            let v0 = pts[0].v;
            if pts.len() != row_len || pts.iter().any(|p| p.v != v0) {
                bad.push(format!("page {number}: not one full grid row"));
            }
            // The page's own frame (portrait or landscape, as it chose).
            let frame = geo.frame;
            if lay.label_failures > 0 {
                bad.push(format!(
                    "page {number}: {} labels off the rule",
                    lay.label_failures
                ));
            }
            let s = lay.scale_pt_per_unit;
            let m0 = frame0.point(lay.curves[0].point);
            for (i, c) in lay.curves.iter().enumerate() {
                labels += 1;
                let own = rect_distance(c.label_pt, c.dot_pt);
                // The dot is the coupler point at θ = 0 (relative to curve 0's dot).
                let m = frame0.point(c.point);
                let want = [
                    lay.curves[0].dot_pt[0] + s * (m.x - m0.x),
                    lay.curves[0].dot_pt[1] - s * (m.y - m0.y),
                ];
                if (want[0] - c.dot_pt[0]).hypot(want[1] - c.dot_pt[1]) > 1e-6 {
                    bad.push(format!(
                        "page {number}: dot of {} not at its point",
                        c.label
                    ));
                }
                let mut touches = false;
                for (j, o) in lay.curves.iter().enumerate() {
                    if j == i {
                        continue;
                    }
                    if rect_distance(c.label_pt, o.dot_pt) <= own {
                        bad.push(format!(
                            "page {number}: label {} is as near to the dot of {:?} as to its own",
                            c.label, o.point
                        ));
                    }
                    if j > i && overlap(c.label_pt, o.label_pt) {
                        bad.push(format!(
                            "page {number}: labels {} and {} overlap",
                            c.label, o.label
                        ));
                    }
                    if !o.ghost && overlap(c.label_pt, o.bbox_pt) {
                        let t = &geo.transform;
                        touches |= geo.curves[j].dashes.iter().any(|d| {
                            d.points.windows(2).any(|w| {
                                segment_enters(
                                    c.label_pt,
                                    t.map(w[0].x, w[0].y),
                                    t.map(w[1].x, w[1].y),
                                )
                            })
                        });
                    }
                }
                on_ink += usize::from(touches);
                let r = c.label_pt;
                if !(r[0] >= frame[0] && r[1] >= frame[1] && r[2] <= frame[2] && r[3] <= frame[3]) {
                    bad.push(format!(
                        "page {number}: label {} outside the frame",
                        c.label
                    ));
                }
            }
            (labels, on_ink, bad)
        })
        .collect();
    let pages = atlas.pages.len();
    let labels: usize = results.iter().map(|r| r.0).sum();
    let on_ink: usize = results.iter().map(|r| r.1).sum();
    let bad: Vec<&String> = results.iter().flat_map(|r| &r.2).collect();
    assert_eq!(pages as u64, atlas.planned);
    let numbers: Vec<usize> = atlas.pages.iter().map(|p| p.page.page_number).collect();
    assert!(
        numbers.iter().enumerate().all(|(i, &n)| n == i + 1),
        "pages numbered 1, 2, … in order"
    );
    assert!(
        pages >= 700 && labels >= 7000,
        "{pages} pages, {labels} labels"
    );
    assert!(
        bad.is_empty(),
        "{} problems, first: {:?}",
        bad.len(),
        &bad[..bad.len().min(10)]
    );
    eprintln!("{on_ink} of {labels} labels touch another curve's dashes");
    assert!(
        on_ink * 100 <= 3 * labels,
        "{on_ink} of {labels} labels lie on another curve's dashes"
    );
}

/// The default atlas keeps the 1951 scale and holds Hoeken's straight-line family
/// (A = B = 2.5, C = 2, point u = 2A, v = 0).
#[test]
fn default_atlas_has_the_1951_scale_and_hoekens_point() {
    let spec = Spec::parse(DEFAULT_SPEC_TEXT, "default").unwrap();
    let job = Job::new(spec, "default", "unused", 1);
    assert!(job.curves() >= 7000 && job.pages() >= 700);
    let hoeken = job
        .groups()
        .find(|g| {
            let d = g.linkage.dimensions();
            d[0].1 == 2.5 && d[1].1 == 2.5 && d[2].1 == 2.0
        })
        .expect("Hoeken's linkage is a crank-rocker of the grid");
    assert!(
        hoeken
            .points
            .iter()
            .any(|p| (p.u - 5.0).abs() < 1e-12 && p.v == 0.0),
        "u = 2A, v = 0 is in the grid"
    );
}

/// Each classic branch's dash pattern starts where the branch starts (θ = 0 for a crank,
/// the lower toggle for a rocking input): its first dash begins at the branch's first
/// sample, so the start dot sits on a dash.
#[test]
fn classic_branches_start_their_dashes_at_the_branch_start() {
    let (pages, _) = classic_pages();
    assert!(!pages.is_empty());
    for (page, geo) in &pages {
        let c = &page.curve;
        let mut seen = Vec::new();
        for leg in &geo.legs {
            if seen.contains(&leg.branch) {
                continue;
            }
            seen.push(leg.branch);
            let branch = &page.measured.branches[leg.branch];
            let s0 = branch.samples.first().unwrap();
            let d0 = leg.dashes.first().unwrap();
            assert!(
                (d0.theta_start - s0.degrees).abs() < 1e-9,
                "{}: branch {} starts at {}°, its first dash at {}°",
                c.name,
                leg.branch,
                s0.degrees,
                d0.theta_start
            );
            let p0 = d0.points[0];
            assert!(
                (p0 - s0.point).norm() < 1e-9,
                "{}: the first dash starts at the start dot",
                c.name
            );
        }
    }
}

/// Distance from the rectangle `r` to the segment `a`–`b` (0 when they meet).
fn rect_segment_distance(r: [f64; 4], a: [f64; 2], b: [f64; 2]) -> f64 {
    let inside = |p: [f64; 2]| p[0] >= r[0] && p[0] <= r[2] && p[1] >= r[1] && p[1] <= r[3];
    if inside(a) || inside(b) {
        return 0.0;
    }
    let corners = [[r[0], r[1]], [r[2], r[1]], [r[2], r[3]], [r[0], r[3]]];
    let cross = |o: [f64; 2], p: [f64; 2], q: [f64; 2]| {
        (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0])
    };
    for k in 0..4 {
        let (c, d) = (corners[k], corners[(k + 1) % 4]);
        let (d1, d2) = (cross(a, b, c), cross(a, b, d));
        let (d3, d4) = (cross(c, d, a), cross(c, d, b));
        if d1 * d2 <= 0.0 && d3 * d4 <= 0.0 && (d1 != d2 || d3 != d4) {
            return 0.0;
        }
    }
    let point_segment = |p: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let l2 = dx * dx + dy * dy;
        let t = if l2 > 0.0 {
            (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
    };
    let mut d = rect_distance(r, a).min(rect_distance(r, b));
    for c in corners {
        d = d.min(point_segment(c, a, b));
    }
    d
}

/// Every classic page's bracket labels (`εₛ ≤ …: n°, k dashes`) keep clear of all ink:
/// at least 1 pt from the curve's dashes, the ghost linkage, the input's path, the
/// brackets, markers and frames (measured from the stroke's edge), and they overlap no
/// other text.
#[test]
fn classic_bracket_labels_touch_no_ink() {
    use coupler_atlas::layout::{Ink, Primitive, layout_classic};
    let (pages, opts) = classic_pages();
    let mut bad = Vec::new();
    let mut labels = 0;
    for (page, geo) in &pages {
        let c = &page.curve;
        let lay = layout_classic(page, geo, &opts.setup);
        // Ink as segments with their half widths; text as boxes.
        let mut ink: Vec<([f64; 2], [f64; 2], f64)> = Vec::new();
        let mut texts: Vec<([f64; 4], String, bool)> = Vec::new();
        let mut paper = false;
        for item in &lay.display.items {
            match item {
                Primitive::Ink(k) => paper = *k == Ink::Paper,
                _ if paper => {}
                Primitive::Polyline { points, width } => {
                    for w in points.windows(2) {
                        ink.push((w[0], w[1], 0.5 * width));
                    }
                }
                Primitive::Polylines { lines, width } => {
                    for l in lines {
                        for w in l.windows(2) {
                            ink.push((w[0], w[1], 0.5 * width));
                        }
                    }
                }
                Primitive::Rect { rect: r, width } => {
                    let q = [[r[0], r[1]], [r[2], r[1]], [r[2], r[3]], [r[0], r[3]]];
                    for k in 0..4 {
                        ink.push((q[k], q[(k + 1) % 4], 0.5 * width));
                    }
                }
                Primitive::Polygon { points } => {
                    for k in 0..points.len() {
                        ink.push((points[k], points[(k + 1) % points.len()], 0.0));
                    }
                }
                Primitive::Circle {
                    center,
                    radius,
                    width,
                } => {
                    let r = radius + width.map_or(0.0, |w| 0.5 * w);
                    ink.push((*center, *center, r));
                }
                Primitive::Text {
                    pos,
                    size,
                    anchor,
                    text,
                    halo,
                } => {
                    let r = text_box(*pos, *size, *anchor, text);
                    let bracket =
                        *halo > 0.0 && text.starts_with("εₛ ≤") && text.contains("dashes");
                    texts.push((r, text.clone(), bracket));
                }
            }
        }
        for (r, label, _) in texts.iter().filter(|t| t.2) {
            labels += 1;
            let gap = ink
                .iter()
                .map(|(a, b, hw)| rect_segment_distance(*r, *a, *b) - hw)
                .fold(f64::INFINITY, f64::min);
            if gap < 1.0 {
                bad.push(format!("{}: \"{label}\" is {gap:.2} pt from ink", c.name));
            }
            for (q, other, _) in &texts {
                if other != label && overlap(*r, *q) {
                    bad.push(format!("{}: \"{label}\" overlaps \"{other}\"", c.name));
                }
            }
        }
    }
    assert!(labels >= 12, "{labels} bracket labels");
    assert!(bad.is_empty(), "{} problems: {bad:#?}", bad.len());
}

// ---- the atlas PDF: parse what we wrote ------------------------------------------------

fn find(hay: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    hay[from..]
        .windows(needle.len())
        .position(|w| w == needle)
        .map(|p| p + from)
}

/// The body of object `id` (from `id 0 obj` to `endobj`).
fn object(pdf: &[u8], id: u32) -> &[u8] {
    let head = format!("\n{id} 0 obj");
    let start = find(pdf, head.as_bytes(), 0).unwrap_or_else(|| panic!("object {id}")) + 1;
    let end = find(pdf, b"endobj", start).unwrap();
    &pdf[start..end]
}

/// The first `N 0 R` after `key` in `dict`.
fn reference(dict: &[u8], key: &str) -> u32 {
    let at = find(dict, key.as_bytes(), 0).unwrap_or_else(|| panic!("{key}")) + key.len();
    let digits: String = dict[at..]
        .iter()
        .skip_while(|b| b.is_ascii_whitespace() || **b == b'[')
        .take_while(|b| b.is_ascii_digit())
        .map(|&b| char::from(b))
        .collect();
    digits
        .parse()
        .unwrap_or_else(|_| panic!("no reference after {key}"))
}

/// The bytes of the stream of an object, inflated when it says FlateDecode.
fn stream(obj: &[u8]) -> Vec<u8> {
    let s = find(obj, b"stream\n", 0).unwrap() + 7;
    let e = find(obj, b"\nendstream", s).unwrap();
    let raw = &obj[s..e];
    if find(obj, b"/FlateDecode", 0).is_some_and(|p| p < s) {
        miniz_oxide::inflate::decompress_to_vec_zlib(raw).unwrap()
    } else {
        raw.to_vec()
    }
}

/// The object ids of the document's pages, in order (one flat page tree).
fn kids(pdf: &[u8]) -> Vec<u32> {
    let pages_at = find(pdf, b"/Type /Pages", 0).unwrap();
    let kids_at = find(pdf, b"/Kids [", pages_at).unwrap() + 7;
    let kids_end = find(pdf, b"]", kids_at).unwrap();
    std::str::from_utf8(&pdf[kids_at..kids_end])
        .unwrap()
        .split_whitespace()
        .collect::<Vec<_>>()
        .chunks(3)
        .map(|c| c[0].parse().unwrap())
        .collect()
}

fn page_count(pdf: &[u8]) -> usize {
    kids(pdf).len()
}

/// The text shown on a page: every string in its content stream, decoded with the font's
/// ToUnicode map (2-byte codes), one shown string per line.
fn page_text(pdf: &[u8], page_index: usize) -> String {
    let kids = kids(pdf);
    let page = object(pdf, kids[page_index]);
    let content = stream(object(pdf, reference(page, "/Contents")));
    // The ToUnicode CMap of the one font.
    let type0_at = find(pdf, b"/Subtype /Type0", 0).unwrap();
    let tu_at = find(pdf, b"/ToUnicode", type0_at).unwrap();
    let cmap = stream(object(pdf, reference(&pdf[tu_at..], "/ToUnicode")));
    let cmap = String::from_utf8_lossy(&cmap).to_string();
    let mut map = std::collections::HashMap::new();
    for line in cmap.lines() {
        let parts: Vec<&str> = line.split_whitespace().collect();
        if parts.len() == 2 && parts[0].starts_with('<') && parts[1].starts_with('<') {
            let code = u16::from_str_radix(parts[0].trim_matches(['<', '>']), 16).unwrap();
            let uni = u32::from_str_radix(parts[1].trim_matches(['<', '>']), 16).unwrap();
            map.insert(code, char::from_u32(uni).unwrap());
        }
    }
    // Literal strings inside TJ arrays.
    let mut out = String::new();
    let mut i = 0;
    let c = &content;
    while i < c.len() {
        if c[i] == b'(' {
            let mut bytes = Vec::new();
            i += 1;
            let mut depth = 0;
            while i < c.len() {
                match c[i] {
                    b'\\' => {
                        i += 1;
                        match c[i] {
                            b'n' => bytes.push(b'\n'),
                            b'r' => bytes.push(b'\r'),
                            b't' => bytes.push(b'\t'),
                            b'b' => bytes.push(8),
                            b'f' => bytes.push(12),
                            b'0'..=b'7' => {
                                let mut v = 0u32;
                                let mut k = 0;
                                while k < 3 && i < c.len() && (b'0'..=b'7').contains(&c[i]) {
                                    v = v * 8 + u32::from(c[i] - b'0');
                                    i += 1;
                                    k += 1;
                                }
                                bytes.push(v as u8);
                                continue;
                            }
                            x => bytes.push(x),
                        }
                    }
                    b'(' => {
                        depth += 1;
                        bytes.push(b'(');
                    }
                    b')' if depth > 0 => {
                        depth -= 1;
                        bytes.push(b')');
                    }
                    b')' => break,
                    x => bytes.push(x),
                }
                i += 1;
            }
            for pair in bytes.chunks(2) {
                if pair.len() == 2 {
                    let code = u16::from_be_bytes([pair[0], pair[1]]);
                    out.push(*map.get(&code).unwrap_or(&'\u{fffd}'));
                }
            }
        } else if c[i..].starts_with(b"TJ") {
            out.push('\n');
        }
        i += 1;
    }
    out
}

/// `generate --format pdf` writes one PDF of the whole atlas: the contents first, then
/// the pages, with real text: the header of the first atlas page ("A = …") can be read
/// back through the font's ToUnicode map; the contents link to the pages and the outline
/// has an entry per linkage.
#[test]
fn the_atlas_pdf_has_extractable_text_links_and_an_outline() {
    let dir = fresh_dir("pdf");
    let quick = Path::new("atlas-spec/quick.toml");
    let pdf = generate_pdf(quick, &dir.join("all"), "quick", &[]);
    // Byte-deterministic for any --jobs.
    assert!(
        generate_pdf(quick, &dir.join("one"), "quick", &["--jobs", "1"]) == pdf,
        "the PDF differs between --jobs 1 and all cores"
    );
    // quick.toml: 6 linkages × 2 circuits, one page each, after the contents pages.
    let count = page_count(&pdf);
    let contents = (0..count)
        .take_while(|&i| page_text(&pdf, i).contains("Contents: quick"))
        .count();
    assert!(contents >= 1, "the PDF opens with the contents");
    assert_eq!(count, contents + 12, "contents and 12 atlas pages");
    let first = page_text(&pdf, contents);
    assert!(
        first.contains("A = 2.5"),
        "the first atlas page reads: {first}"
    );
    assert!(
        first.contains("page 1 of 12"),
        "the first atlas page reads: {first}"
    );
    assert!(!first.contains("Contents"), "{first}");
    let last = page_text(&pdf, count - 1);
    assert!(
        last.contains("page 12 of 12"),
        "the last page reads: {last}"
    );
    assert!(find(&pdf, b"/Subtype /Link", 0).is_some());
    assert!(find(&pdf, b"/Outlines", 0).is_some());
    assert!(find(&pdf, b"/PageLabels", 0).is_some());
    // The index points at the PDF and at each curve's page.
    let index = std::fs::read_to_string(dir.join("all/index.json")).unwrap();
    assert!(index.contains("\"file\":\"pages/quick.pdf\""));
    assert!(index.contains("\"dot_px\":"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The `/MediaBox [0 0 W H]` of a page object, points.
fn media_box(page: &[u8]) -> [f64; 4] {
    let at = find(page, b"/MediaBox [", 0).expect("every page has its own MediaBox") + 11;
    let end = find(page, b"]", at).unwrap();
    let v: Vec<f64> = std::str::from_utf8(&page[at..end])
        .unwrap()
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    [v[0], v[1], v[2], v[3]]
}

/// Every `N 0 R` that a `/D [` or `/Dest [` array names first: the pages that links and
/// outline entries go to, in file order.
fn destinations(pdf: &[u8], key: &[u8]) -> Vec<u32> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(at) = find(pdf, key, from) {
        let rest = &pdf[at + key.len()..];
        let n: String = rest
            .iter()
            .take_while(|b| b.is_ascii_digit())
            .map(|&b| char::from(b))
            .collect();
        out.push(n.parse().unwrap());
        from = at + key.len();
    }
    out
}

/// A tabloid atlas whose pages choose their orientation (`auto`): in the one PDF each
/// page has the MediaBox of the orientation the index records for it (landscape pages
/// 1224 × 792 pt, portrait 792 × 1224, the contents portrait), its header names its page
/// number, the contents link to every atlas page and only to atlas pages, and the
/// outline has the contents and one entry per linkage, each going to its first page.
#[test]
fn the_atlas_pdf_turns_each_page_as_the_index_says_and_links_every_page() {
    let dir = fresh_dir("pdfo");
    // Two linkages whose families are long and flat (landscape) or tall (portrait).
    let spec = dir.join("mixed.toml");
    std::fs::write(
        &spec,
        "[atlas]\nname = \"mixed\"\n\n[linkages]\n\
         coupler = { start = 2.0, end = 2.5, step = 0.5 }\n\
         rocker = { start = 1.5, end = 2.0, step = 0.5 }\n\
         ground = { start = 2.0, end = 3.0, step = 1.0 }\ncircuits = [\"open\"]\n\n\
         [points]\nu = { start = -0.25, end = 2.0, step = 0.25, relative = true }\n\
         v = { start = -1.0, end = 1.0, step = 0.5, relative = true }\n\n\
         [sampling]\ncrank_step_deg = 2.0\ndash_deg = 10.0\n\n\
         [pages]\nsize = \"tabloid\"\norientation = \"auto\"\ndpi = 72\n",
    )
    .unwrap();
    let out = dir.join("out");
    let pdf = generate_pdf(&spec, &out, "mixed", &[]);
    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("index.json")).unwrap()).unwrap();
    // Each page's orientation and linkage, from the index.
    let mut pages = std::collections::BTreeMap::new();
    for c in index["curves"].as_array().unwrap() {
        let n = c["page"]["number"].as_u64().unwrap() as usize;
        let o = c["page"]["orientation"].as_str().unwrap().to_string();
        let l = c["linkage"].to_string();
        let prev = pages.insert(n, (o.clone(), l.clone()));
        assert!(
            prev.is_none_or(|p| p == (o, l)),
            "page {n}: one orientation, one linkage"
        );
    }
    let n_pages = pages.len();
    let kids = kids(&pdf);
    let contents = kids.len() - n_pages;
    assert!(
        contents >= 1,
        "{} PDF pages for {n_pages} atlas pages",
        kids.len()
    );
    let landscape = pages.values().filter(|p| p.0 == "landscape").count();
    assert!(
        landscape > 0 && landscape < n_pages,
        "the test needs both orientations: {landscape} of {n_pages} landscape"
    );
    for (i, &kid) in kids.iter().enumerate() {
        let b = media_box(object(&pdf, kid));
        let (w, h) = (b[2] - b[0], b[3] - b[1]);
        if i < contents {
            assert_eq!(
                (w, h),
                (792.0, 1224.0),
                "contents page {} is portrait",
                i + 1
            );
            continue;
        }
        let n = i - contents + 1;
        let want = if pages[&n].0 == "landscape" {
            (1224.0, 792.0)
        } else {
            (792.0, 1224.0)
        };
        assert_eq!(
            (w, h),
            want,
            "atlas page {n} is {} in the index",
            pages[&n].0
        );
        let text = page_text(&pdf, i);
        assert!(
            text.contains(&format!("page {n} of {n_pages}")),
            "PDF page {} is atlas page {n}: {text}",
            i + 1
        );
    }
    // The contents' links go to atlas pages, and every atlas page has one.
    let links = destinations(&pdf, b"/D [");
    let atlas: std::collections::BTreeSet<u32> = kids[contents..].iter().copied().collect();
    assert!(links.iter().all(|d| atlas.contains(d)), "links: {links:?}");
    let linked: std::collections::BTreeSet<u32> = links.iter().copied().collect();
    assert_eq!(
        linked, atlas,
        "every atlas page is linked from the contents"
    );
    // The outline: the contents, then one entry per linkage at its first page, holding
    // an entry per page of that linkage, in order.
    let catalog_at = find(&pdf, b"/Type /Catalog", 0).unwrap();
    let root_entry = object(&pdf, reference(&pdf[catalog_at..], "/Outlines"));
    let dest = |id: u32| reference(object(&pdf, id), "/Dest [");
    let title = |id: u32| {
        let o = object(&pdf, id);
        let at = find(o, b"/Title (", 0).unwrap() + 8;
        String::from_utf8_lossy(&o[at..find(o, b")", at).unwrap()]).to_string()
    };
    let chain = |parent: &[u8]| {
        let mut ids = Vec::new();
        let mut next = find(parent, b"/First", 0).map(|_| reference(parent, "/First"));
        while let Some(id) = next {
            ids.push(id);
            let o = object(&pdf, id);
            next = find(o, b"/Next", 0).map(|_| reference(o, "/Next"));
        }
        ids
    };
    let top = chain(root_entry);
    assert_eq!(title(top[0]), "Contents");
    assert_eq!(dest(top[0]), kids[0]);
    let mut by_linkage: Vec<(String, Vec<usize>)> = Vec::new();
    for (&n, (_, l)) in &pages {
        match by_linkage.last_mut() {
            Some((last, ns)) if last == l => ns.push(n),
            _ => by_linkage.push((l.clone(), vec![n])),
        }
    }
    assert_eq!(
        top.len(),
        1 + by_linkage.len(),
        "one outline entry per linkage"
    );
    for (&entry, (_, ns)) in top[1..].iter().zip(&by_linkage) {
        assert!(title(entry).starts_with("A = "), "{}", title(entry));
        assert_eq!(dest(entry), kids[contents + ns[0] - 1], "{}", title(entry));
        let children: Vec<u32> = chain(object(&pdf, entry)).into_iter().map(dest).collect();
        let want: Vec<u32> = ns.iter().map(|n| kids[contents + n - 1]).collect();
        assert_eq!(children, want, "the pages under {}", title(entry));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// ---- feature marks on atlas pages ------------------------------------------------------

/// Whether segments `a`–`b` and `c`–`d` cross (or touch).
fn segments_cross(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let cross = |o: [f64; 2], p: [f64; 2], q: [f64; 2]| {
        (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0])
    };
    let (d1, d2) = (cross(a, b, c), cross(a, b, d));
    let (d3, d4) = (cross(c, d, a), cross(c, d, b));
    d1 * d2 <= 0.0 && d3 * d4 <= 0.0 && (d1 != 0.0 || d2 != 0.0 || d3 != 0.0 || d4 != 0.0)
}

/// Whether `text` is an atlas page's feature label (`S 45°`, `A 110°`).
fn is_feature_label(text: &str) -> bool {
    let mut c = text.chars();
    matches!(c.next(), Some('S' | 'A'))
        && c.next() == Some(' ')
        && text.ends_with('°')
        && text[2..text.len() - '°'.len_utf8()]
            .chars()
            .all(|ch| ch.is_ascii_digit())
}

/// The feature marks of the default atlas read as marks on a curve, not as more curves:
/// every curve's longest straight segment and pseudo-arc (from the index) gets its span
/// label (`S n°`, `A n°`), and those labels are placed like the curve labels, clear of
/// the curves' dashes: at most 2 % of them touch a dash (any curve's; 40 % did when they
/// were set beside their brackets, and 12 % of the brackets had no label). The leaders
/// from curve labels to their dots are measured too: at most 18 % of them cross another
/// curve's dashes (27 % before the leaders' ink was weighed).
#[test]
fn atlas_feature_labels_keep_clear_of_the_curves() {
    use coupler_atlas::layout::Primitive;
    // (features, feature labels, labels on dashes, leaders, leaders crossing)
    let results: Vec<[usize; 5]> = default_atlas()
        .pages
        .par_iter()
        .map(|AtlasPage { page, geo, lay }| {
            let fs = &page.features;
            let mut n = [0usize; 5];
            let t = &geo.transform;
            let dashes: Vec<Vec<([f64; 2], [f64; 2])>> = geo
                .curves
                .iter()
                .map(|c| {
                    c.dashes
                        .iter()
                        .flat_map(|d| {
                            d.points
                                .windows(2)
                                .map(|w| (t.map(w[0].x, w[0].y), t.map(w[1].x, w[1].y)))
                        })
                        .collect()
                })
                .collect();
            for (c, f) in lay.curves.iter().zip(fs) {
                if let (false, Some(f)) = (c.ghost, f) {
                    n[0] += usize::from(!f.straight_segments.is_empty());
                    n[0] += usize::from(!f.pseudo_arcs.is_empty());
                }
            }
            for item in &lay.display.items {
                let Primitive::Text {
                    pos,
                    size,
                    anchor,
                    text,
                    ..
                } = item
                else {
                    continue;
                };
                if !is_feature_label(text) {
                    continue;
                }
                n[1] += 1;
                let r = text_box(*pos, *size, *anchor, text);
                let on = dashes.iter().flatten().any(|(a, b)| {
                    let (a, b) = (*a, *b);
                    a[0].min(b[0]) <= r[2] + 1.0
                        && a[0].max(b[0]) >= r[0] - 1.0
                        && a[1].min(b[1]) <= r[3] + 1.0
                        && a[1].max(b[1]) >= r[1] - 1.0
                        && rect_segment_distance(r, a, b) < 0.7
                });
                n[2] += usize::from(on);
            }
            for (i, c) in lay.curves.iter().enumerate() {
                let r = c.label_pt;
                let d = c.dot_pt;
                let near = [d[0].clamp(r[0], r[2]), d[1].clamp(r[1], r[3])];
                if (near[0] - d[0]).hypot(near[1] - d[1]) <= 7.0 {
                    continue;
                }
                n[3] += 1;
                let crosses = dashes.iter().enumerate().any(|(j, segs)| {
                    j != i && segs.iter().any(|(a, b)| segments_cross(d, near, *a, *b))
                });
                n[4] += usize::from(crosses);
            }
            n
        })
        .collect();
    let s = |k: usize| results.iter().map(|r| r[k]).sum::<usize>();
    let (features, labels, on_ink, leaders, crossing) = (s(0), s(1), s(2), s(3), s(4));
    eprintln!(
        "{features} features, {labels} feature labels, {on_ink} on a dash; {leaders} leaders, {crossing} crossing another curve"
    );
    assert!(features > 1000, "{features} features");
    assert_eq!(
        labels, features,
        "every feature mark carries its span label"
    );
    assert!(
        on_ink * 50 <= labels,
        "{on_ink} of {labels} feature labels lie on a curve's dashes"
    );
    assert!(
        crossing * 100 <= 18 * leaders,
        "{crossing} of {leaders} leaders cross another curve's dashes"
    );
}
