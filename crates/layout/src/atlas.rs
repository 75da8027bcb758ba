//! Atlas pages (after Hrones & Nelson, 1951): one linkage and one family of its coupler
//! points (a row of its grid) per page, every curve dashed at one shared scale.
//!
//! What a page shows, in drawing order: the header (A, B, C, class, circuit, row, the
//! transmission-angle range with a warning under 30°); the linkage at θ = 0 in the
//! curves' frame, or small in an inset where drawing it at the curves' scale would push
//! the curves together; the curves of the crank and rocker pins ghosted in gray; the
//! other curves alternating black-thin and gray-wide so that crossing curves can be
//! followed, each with a heavier dash every 90° of crank; the longest straight segment
//! and pseudo-arc of each curve bracketed with their crank spans; the labels at their
//! θ = 0 dots with paper halos (numbers and a key where the page is too dense); and last,
//! above everything, the markers (θ = 0 dot and arrowhead, cusps, crunodes).

use crate::font;
use crate::labels::{
    LABEL_PAD, LEADER_MIN_GAP, LEADER_START, MARK_LEADER_MIN_GAP, MARK_LEADER_START, leader,
    place_labels, place_marks,
};
use crate::page::{
    Anchor, CurveStyle, DisplayList, Ink, LayoutError, Occupancy, Orientation, PT_PER_INCH,
    PagePoint, PageSetup, Primitive, WorldToPage, clip_segment, draw_dashes, draw_links, fit_into,
    fmt_num, footer, footer_settings, frame_for, header, inset_rect, nice_inches_per_unit,
    pivot_labels, scale_bar, start_marker, style, union,
};
use coupler_features::CurveFeatures;
use coupler_kinematics::{
    AngleTables, Circuit, CouplerPoint, CrankAngle, CrankTable, Curve, DashedCurve, Drawing,
    Linkage, Mechanism, PoseTable, dash_curves,
};

/// Crank angle (degrees) at which the linkage is drawn: θ = 0, so every coupler point of
/// the page sits on the start (θ = 0 dot) of its own curve.
pub const DRAWN_CRANK_ANGLE_DEG: f64 = 0.0;

/// Transmission angle below which the header carries a warning, degrees.
pub const MU_WARNING_DEG: f64 = 30.0;

const EMPTY: [f64; 4] = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];

/// What one linkage page shows.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkagePage<M: Mechanism = Linkage> {
    /// The mechanism.
    pub linkage: M,
    /// Its circuit.
    pub circuit: Circuit,
    /// Coupler points whose curves are on this page (in order).
    pub points: Vec<CouplerPoint>,
    /// The linkage's whole grid of coupler points (drawn as small circles).
    pub grid: Vec<CouplerPoint>,
    /// Page number in the atlas (1-based).
    pub page_number: usize,
    /// Pages in the atlas.
    pub page_count: usize,
    /// The features of each point's curve (same order as `points`; shorter or `None`
    /// where not measured): marked on the page.
    pub features: Vec<Option<CurveFeatures>>,
}

/// Whether coupler point `p` of a coupler of length `a` is a pin: the crank pin Pa
/// (u = v = 0) or the rocker pin Pb (u = A, v = 0). Their curves only repeat the crank
/// circle and the rocker arc, so pages ghost them (the index flags them `trivial`).
pub fn is_pin_point(a: f64, p: CouplerPoint) -> bool {
    let tol = 1e-12 * a.abs().max(1.0);
    p.v.abs() <= tol && (p.u.abs() <= tol || (p.u - a).abs() <= tol)
}

/// The linkage drawn small in a corner box of the frame, where at the curves' scale it
/// would push them together.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inset {
    /// The box, points.
    pub rect: [f64; 4],
    /// The linkage's transform inside it.
    pub transform: WorldToPage,
}

/// Curves of a page computed for a given setup: the dash polylines, and the world
/// (curve-unit) window and scale they are drawn at.
#[derive(Clone, Debug, PartialEq)]
pub struct PageGeometry {
    /// Dashed curves, one per point of the page, same order.
    pub curves: Vec<DashedCurve>,
    /// Page transform: page = (origin.x + s·x, origin.y − s·y) for curve coordinates.
    pub transform: WorldToPage,
    /// The frame (plot area) in points: `[x0, y0, x1, y1]`.
    pub frame: [f64; 4],
    /// Where the linkage is drawn small (`None`: in the curves' frame, at their scale).
    pub inset: Option<Inset>,
    /// The page's orientation (chosen here when the setup's is `auto`).
    pub orientation: Orientation,
}

/// The mechanism at the drawn angle (crank-rockers assemble everywhere).
fn drawn<M: Mechanism>(page: &LinkagePage<M>) -> Drawing {
    page.linkage.drawing(
        page.circuit,
        &CrankAngle::from_degrees(DRAWN_CRANK_ANGLE_DEG),
    )
}

/// World bounding box of the linkage as drawn: the crank paths, the ground pivots, and,
/// at the drawn angle, the moving joints and this page's coupler points.
fn linkage_bbox<M: Mechanism>(page: &LinkagePage<M>) -> [f64; 4] {
    let drawing = drawn(page);
    let mut b = EMPTY;
    for (c, r) in &drawing.paths {
        b = union(b, [c.x - r, c.y - r, c.x + r, c.y + r]);
    }
    for j in &drawing.joints {
        b = union(b, [j.position.x, j.position.y, j.position.x, j.position.y]);
    }
    if let Some(f) = drawing.coupler {
        for q in &page.points {
            let m = f.point(*q);
            b = union(b, [m.x, m.y, m.x, m.y]);
        }
    }
    b
}

/// Linkage drawn at the curves' scale if that keeps at least this share of the scale the
/// curves alone would get; else it goes into an inset.
const LINKAGE_SCALE_SHARE: f64 = 0.8;

/// Computes the page's curves: estimates their extent from a 2° trace (one pose table
/// shared by every point), picks the largest round scale at which all curves fit in the
/// frame (with the linkage, when that costs under 20 % of the scale; else the linkage
/// goes into an inset in the frame corner the curves leave free), then dashes every curve
/// with a chord tolerance of `setup.chord_tolerance_px` pixels at that scale.
pub fn compute_page<M: Mechanism>(
    page: &LinkagePage<M>,
    setup: &PageSetup,
) -> Result<PageGeometry, LayoutError> {
    // A mechanism whose period is longer than a turn (a geared five-bar of gear ratio
    // p/q) is traced over its whole period.
    let table = CrankTable::over(EXTENT_STEP_DEG, page.linkage.period_deg()).expect("valid step");
    let poses = page.linkage.pose_table(page.circuit, &table);
    compute_page_from(page, setup, &poses)
}

/// Input step of the trace that estimates a page's extent, degrees.
pub const EXTENT_STEP_DEG: f64 = 2.0;

/// [`compute_page`] with the extent trace's poses from a run's shared `tables`
/// ([`AngleTables::pose_table_at`] at [`EXTENT_STEP_DEG`]: the crank table, and a geared
/// five-bar's gear table, built once for the run, not per page). The same page to the
/// bit.
pub fn compute_page_with_tables(
    page: &LinkagePage<Linkage>,
    setup: &PageSetup,
    tables: &AngleTables,
) -> Result<PageGeometry, LayoutError> {
    let poses = tables.pose_table_at(&page.linkage, page.circuit, EXTENT_STEP_DEG);
    compute_page_from(page, setup, &poses)
}

fn compute_page_from<M: Mechanism>(
    page: &LinkagePage<M>,
    setup: &PageSetup,
    poses: &PoseTable,
) -> Result<PageGeometry, LayoutError> {
    setup.validate()?;
    let mut world = EMPTY;
    let mut samples: Vec<(f64, f64)> = Vec::new();
    let mut curve = Curve::default();
    for p in &page.points {
        poses.trace_into(*p, &mut curve);
        for k in 0..curve.len() {
            if curve.is_valid(k) {
                world = union(world, [curve.x[k], curve.y[k], curve.x[k], curve.y[k]]);
                samples.push((curve.x[k], curve.y[k]));
            }
        }
    }
    let link = linkage_bbox(page);
    if !world[0].is_finite() {
        world = link;
    }
    let nice = nice_inches_per_unit();
    // Each orientation the page may take (both under `auto`): the largest scale wins,
    // portrait on a tie.
    let mut best: Option<(WorldToPage, Option<Inset>, [f64; 4], Orientation)> = None;
    for &o in setup.size.orientation.candidates() {
        let frame = frame_for(setup, o);
        let (t, inset) = fit_page(world, link, &samples, frame, &nice);
        if best.as_ref().is_none_or(|b| t.scale > b.0.scale) {
            best = Some((t, inset, frame, o));
        }
    }
    let (transform, inset, frame, orientation) = best.expect("at least one orientation");
    let scale = transform.scale;
    let tol_world = setup.chord_tolerance_px / setup.px_per_pt() / scale;
    // Every curve of the page dashed with the frames of the angles solved once.
    let curves = dash_curves(
        &page.linkage,
        page.circuit,
        &page.points,
        &setup.dash,
        tol_world,
    )?;
    Ok(PageGeometry {
        curves,
        transform,
        frame,
        inset,
        orientation,
    })
}

/// The curves' transform in `frame`: at the largest round scale at which the curves and
/// the linkage fit, or, when the linkage would cost more than 20 % of the curves' own
/// scale, the curves alone with the linkage in an inset.
fn fit_page(
    world: [f64; 4],
    link: [f64; 4],
    samples: &[(f64, f64)],
    frame: [f64; 4],
    nice: &[f64],
) -> (WorldToPage, Option<Inset>) {
    let inner = inset_rect(frame, style::FRAME_PAD);
    let t_all = fit_into(union(world, link), inner, nice);
    let t_cur = fit_into(world, inner, nice);
    if t_all.scale >= LINKAGE_SCALE_SHARE * t_cur.scale {
        (t_all, None)
    } else {
        place_inset(world, link, samples, inner, nice, INSET_CAPTION_SAMPLE)
    }
}

/// Caption height inside an inset, points.
const INSET_CAPTION: f64 = 11.0;

/// The inset's caption with the longest numbers it prints, for its width.
const INSET_CAPTION_SAMPLE: &str = "linkage at θ = 0, crank 1 = 0.000 in (curves: 0.000 in)";

/// The curves' transform and the inset: the inset box (about a third of the frame's
/// width) goes into the corner where the curves, fitted to the whole frame, leave it
/// empty; if every corner has curves, the curves are refitted above or below a band for
/// it.
pub(crate) fn place_inset(
    world: [f64; 4],
    link: [f64; 4],
    samples: &[(f64, f64)],
    inner: [f64; 4],
    nice: &[f64],
    caption: &str,
) -> (WorldToPage, Option<Inset>) {
    let (fw, fh) = (inner[2] - inner[0], inner[3] - inner[1]);
    let (lw, lh) = ((link[2] - link[0]).max(1e-9), (link[3] - link[1]).max(1e-9));
    let pad = 10.0;
    let s = ((0.36 * fw - 2.0 * pad) / lw).min((0.24 * fh - 2.0 * pad - INSET_CAPTION) / lh);
    // At least as wide as its caption (a tall linkage makes a narrow box).
    let caption_w = font::text_width(style::SMALL_SIZE, caption) + 12.0;
    let (bw, bh) = (
        (lw * s + 2.0 * pad).max(caption_w),
        lh * s + 2.0 * pad + INSET_CAPTION,
    );
    let corner = |k: usize, area: [f64; 4]| -> [f64; 4] {
        let x0 = if k % 2 == 0 { area[0] } else { area[2] - bw };
        let y0 = if k < 2 { area[1] } else { area[3] - bh };
        [x0, y0, x0 + bw, y0 + bh]
    };
    let inside = |t: &WorldToPage, r: [f64; 4]| {
        let r = [r[0] - 6.0, r[1] - 6.0, r[2] + 6.0, r[3] + 6.0];
        samples
            .iter()
            .filter(|(x, y)| {
                let p = t.map(*x, *y);
                p[0] >= r[0] && p[0] <= r[2] && p[1] >= r[1] && p[1] <= r[3]
            })
            .count()
    };
    let t = fit_into(world, inner, nice);
    let free = (0..4)
        .map(|k| (inside(&t, corner(k, inner)), k))
        .min()
        .filter(|(n, _)| *n == 0);
    let (t, rect) = match free {
        Some((_, k)) => (t, corner(k, inner)),
        None => {
            // A band at the top or bottom for the inset; the curves fill the rest.
            let top = [inner[0], inner[1] + bh + 6.0, inner[2], inner[3]];
            let bottom = [inner[0], inner[1], inner[2], inner[3] - bh - 6.0];
            let (tt, tb) = (fit_into(world, top, nice), fit_into(world, bottom, nice));
            let (t, band_top) = if tt.scale >= tb.scale {
                (tt, true)
            } else {
                (tb, false)
            };
            let ks = if band_top { [0, 1] } else { [2, 3] };
            let k = ks
                .into_iter()
                .min_by_key(|k| inside(&t, corner(*k, inner)))
                .unwrap_or(ks[0]);
            (t, corner(k, inner))
        }
    };
    let box_inner = [
        rect[0] + pad,
        rect[1] + pad + INSET_CAPTION,
        rect[2] - pad,
        rect[3] - pad,
    ];
    let lt = fit_into(link, box_inner, &[]);
    (
        t,
        Some(Inset {
            rect,
            transform: lt,
        }),
    )
}

/// Where one curve ended up on its page.
#[derive(Clone, Debug, PartialEq)]
pub struct CurvePlacement {
    /// The coupler point.
    pub point: CouplerPoint,
    /// Bounding box of the drawn curve (dash ink), `[x0, y0, x1, y1]` in points.
    pub bbox_pt: [f64; 4],
    /// Bounding box of its label, points.
    pub label_pt: [f64; 4],
    /// Its θ = 0 dot (the coupler point at θ = 0), points.
    pub dot_pt: PagePoint,
    /// The label printed: `(u, v)`, or its number in the page's key.
    pub label: String,
    /// Drawn as a ghost (a pin's curve: the crank circle or the rocker arc).
    pub ghost: bool,
}

fn to_px(v: f64, dpi: f64) -> f64 {
    v * dpi / PT_PER_INCH
}

impl CurvePlacement {
    /// The curve's bounding box in device pixels at `dpi`, rounded outwards:
    /// `[x0, y0, x1, y1]` with `x1`, `y1` exclusive.
    pub fn bbox_px(&self, dpi: f64) -> [u32; 4] {
        round_out(self.bbox_pt, dpi)
    }

    /// The label's box in device pixels at `dpi`, rounded outwards.
    pub fn label_bbox_px(&self, dpi: f64) -> [u32; 4] {
        round_out(self.label_pt, dpi)
    }

    /// The θ = 0 dot in device pixels at `dpi` (not rounded; 0.01 px).
    pub fn dot_px(&self, dpi: f64) -> [f64; 2] {
        self.dot_pt.map(|v| (to_px(v, dpi) * 100.0).round() / 100.0)
    }
}

fn round_out(b: [f64; 4], dpi: f64) -> [u32; 4] {
    let k = dpi / PT_PER_INCH;
    [
        (b[0] * k).floor().max(0.0) as u32,
        (b[1] * k).floor().max(0.0) as u32,
        (b[2] * k).ceil().max(0.0) as u32,
        (b[3] * k).ceil().max(0.0) as u32,
    ]
}

/// A laid-out page: the display list, and where each curve is.
#[derive(Clone, Debug, PartialEq)]
pub struct PageLayout {
    /// What to draw.
    pub display: DisplayList,
    /// One entry per curve, in the page's point order.
    pub curves: Vec<CurvePlacement>,
    /// Points per crank unit.
    pub scale_pt_per_unit: f64,
    /// Whether the labels are numbers with a key.
    pub keyed: bool,
    /// Labels that could not be placed by the rule (0 on every page of the shipped
    /// atlases; tested).
    pub label_failures: usize,
}

/// A number for reading: at most 4 significant digits (trailing zeros dropped) and a
/// real minus sign, e.g. `−0.375`, `1.125`, `0.0001036`, `12.35`.
pub fn fmt_sig(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return if x.is_finite() {
            "0".into()
        } else {
            format!("{x}")
        };
    }
    let mag = libm::floor(libm::log10(x.abs())) as i32;
    let decimals = (3 - mag).max(0) as usize;
    let mut s = format!("{:.*}", decimals, x);
    if s.contains('.') {
        s = s.trim_end_matches('0').trim_end_matches('.').to_string();
    }
    if s == "-0" {
        return "0".into();
    }
    s.replace('-', "−")
}

/// The curve styles, alternating along the row so that neighbours differ: black and
/// thin, then gray and wider (a crossing is read as a thin line over a wide gray one).
const CURVE_STYLES: [CurveStyle; 2] = [
    CurveStyle::BLACK,
    CurveStyle {
        ink: Ink::Gray(150),
        width: 1.25,
        heavy: 2.3,
        bold: 2.3,
    },
];

/// The pins' curves: light gray, thin, no heavy dashes.
const GHOST_STYLE: CurveStyle = CurveStyle {
    ink: Ink::Gray(80),
    width: 0.5,
    heavy: 0.5,
    bold: 0.9,
};

/// Ink of the linkage's context (crank circle, plate, grid) and of the feature brackets.
const CONTEXT_INK: Ink = Ink::Gray(150);

/// The page's header lines: the linkage's dimensions, then class, circuit, row and the
/// transmission-angle range (with a warning sign under [`MU_WARNING_DEG`]).
fn header_lines<M: Mechanism>(page: &LinkagePage<M>) -> (String, String) {
    let l = &page.linkage;
    let title = l
        .dimensions()
        .iter()
        .map(|(name, x)| format!("{name} = {}", fmt_sig(*x)))
        .collect::<Vec<_>>()
        .join("   ");
    let a = l.coupler_length();
    let row = match page.points.first() {
        Some(p0) if page.points.iter().all(|p| p.v == p0.v) => {
            format!(
                "   row v = {} ({} {})",
                fmt_sig(p0.v),
                fmt_sig(p0.v / a),
                l.coupler_name()
            )
        }
        _ => String::new(),
    };
    let mu = match l.transmission_range(page.circuit) {
        Some([lo, hi]) => {
            let (lo, hi) = (lo.to_degrees(), hi.to_degrees());
            let warn = if lo < MU_WARNING_DEG {
                format!("  ⚠ under {}°", fmt_num(MU_WARNING_DEG))
            } else {
                String::new()
            };
            format!("   transmission angle μ {:.1}°–{:.1}°{warn}", lo, hi)
        }
        None => String::new(),
    };
    let subtitle = format!(
        "class {}   {} circuit{row}{mu}",
        l.class_description(),
        page.circuit.name()
    );
    (title, subtitle)
}

/// Draws the linkage at θ = 0 with `t`: the crank circle, the coupler plate and grid
/// (gray context, clipped to `clip`), the links and pins; returns the link segments and
/// the pins with their names.
fn draw_linkage<M: Mechanism>(
    dl: &mut DisplayList,
    page: &LinkagePage<M>,
    t: &WorldToPage,
    clip: [f64; 4],
    segments: &mut Vec<(PagePoint, PagePoint)>,
    grid_dots: &mut Vec<PagePoint>,
) -> Vec<(PagePoint, &'static str)> {
    let drawing = drawn(page);
    let Some(pose) = drawing.coupler else {
        return Vec::new();
    };
    let l = &page.linkage;
    dl.ink(CONTEXT_INK);
    for (c, r) in &drawing.paths {
        let circle: Vec<PagePoint> = (0..=120)
            .map(|k| {
                let (s, co) = coupler_kinematics::sincos_deg(3.0 * k as f64);
                t.map(c.x + r * co, c.y + r * s)
            })
            .collect();
        dl.line(circle, style::THIN);
    }
    if !page.grid.is_empty() {
        let (mut u0, mut v0, mut u1, mut v1) = (0.0f64, 0.0f64, l.coupler_length(), 0.0f64);
        for q in &page.grid {
            (u0, v0, u1, v1) = (u0.min(q.u), v0.min(q.v), u1.max(q.u), v1.max(q.v));
        }
        let plate: Vec<PagePoint> = [(u0, v0), (u1, v0), (u1, v1), (u0, v1), (u0, v0)]
            .iter()
            .map(|&(u, v)| {
                let m = pose.point(CouplerPoint::new(u, v));
                t.map(m.x, m.y)
            })
            .collect();
        for w in plate.windows(2) {
            if let Some((a, b)) = clip_segment(w[0], w[1], clip) {
                dl.line(vec![a, b], style::THIN);
            }
        }
        for q in &page.grid {
            let mq = pose.point(*q);
            let p = t.map(mq.x, mq.y);
            let r = style::GRID_RADIUS;
            if p[0] - r >= clip[0]
                && p[0] + r <= clip[2]
                && p[1] - r >= clip[1]
                && p[1] + r <= clip[3]
            {
                dl.circle(p, r, Some(style::THIN));
                grid_dots.push(p);
            }
        }
    }
    dl.ink(Ink::Black);
    draw_links(dl, t, &drawing, segments)
}

/// Ink of the feature marks' bands: a light gray, well under the curves' inks.
const MARK_BAND_INK: Ink = Ink::Gray(48);

/// Width of a feature mark's band, points: a highlighter stroke over the curve.
const MARK_BAND_WIDTH: f64 = 5.0;

/// Half length and width of the ticks across the curve at a feature mark's ends, points.
const MARK_TICK_HALF: f64 = 4.2;
const MARK_TICK_WIDTH: f64 = 0.6;

/// A feature of one curve marked on the page: the stretch of the curve it covers (page
/// points, in order) and its label.
struct FeatureMark {
    pts: Vec<PagePoint>,
    text: String,
}

/// `pts` without `d` points of length at each end (a round-capped band of width 2·d
/// then ends where the polyline did); `pts` itself when it is too short.
fn trim_ends(pts: &[PagePoint], d: f64) -> Vec<PagePoint> {
    fn cut(pts: &[PagePoint], d: f64) -> Option<Vec<PagePoint>> {
        let mut left = d;
        for (i, w) in pts.windows(2).enumerate() {
            let l = libm::hypot(w[1][0] - w[0][0], w[1][1] - w[0][1]);
            if l > left {
                let t = left / l;
                let mut out = vec![[
                    w[0][0] + t * (w[1][0] - w[0][0]),
                    w[0][1] + t * (w[1][1] - w[0][1]),
                ]];
                out.extend_from_slice(&pts[i + 1..]);
                return Some(out);
            }
            left -= l;
        }
        None
    }
    let length: f64 = pts
        .windows(2)
        .map(|w| libm::hypot(w[1][0] - w[0][0], w[1][1] - w[0][1]))
        .sum();
    if length <= 4.0 * d {
        return pts.to_vec();
    }
    let mut front = cut(pts, d).unwrap_or_else(|| pts.to_vec());
    front.reverse();
    let mut both = cut(&front, d).unwrap_or(front);
    both.reverse();
    both
}

/// A tick across the curve at `pts[i]` (perpendicular to the polyline there).
fn end_tick(pts: &[PagePoint], i: usize) -> Option<Vec<PagePoint>> {
    let n = pts.len();
    let a = pts[i.saturating_sub(1)];
    let b = pts[(i + 1).min(n - 1)];
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len = libm::hypot(dx, dy);
    (len > 1e-9).then(|| {
        let nv = [-dy / len * MARK_TICK_HALF, dx / len * MARK_TICK_HALF];
        let p = pts[i];
        vec![[p[0] - nv[0], p[1] - nv[1]], [p[0] + nv[0], p[1] + nv[1]]]
    })
}

/// The curve of `point` on the page from `start_deg` over `span_deg`, every 2°.
fn stretch<M: Mechanism>(
    page: &LinkagePage<M>,
    t: &WorldToPage,
    point: CouplerPoint,
    start_deg: f64,
    span_deg: f64,
) -> Vec<PagePoint> {
    let n = (span_deg / 2.0).ceil().max(1.0) as usize;
    let constants = page.linkage.constants();
    (0..=n)
        .filter_map(|k| {
            let th = start_deg + span_deg * k as f64 / n as f64;
            let f =
                page.linkage
                    .frame_with(&constants, page.circuit, &CrankAngle::from_degrees(th))?;
            let m = f.point(point);
            Some(t.map(m.x, m.y))
        })
        .collect()
}

/// Lays out a linkage page from its computed geometry.
pub fn layout_page<M: Mechanism>(
    page: &LinkagePage<M>,
    geometry: &PageGeometry,
    setup: &PageSetup,
) -> PageLayout {
    let setup = &setup.oriented(geometry.orientation);
    let (w, h) = setup.size_pt();
    let mut dl = DisplayList::new(w, h);
    let t = geometry.transform;
    let frame = geometry.frame;
    let a_len = page.linkage.coupler_length();
    let (title, subtitle) = header_lines(page);
    header(
        &mut dl,
        setup,
        title,
        subtitle,
        [page.page_number, page.page_count],
    );
    dl.rect(frame, style::FRAME);

    let mut occ = Occupancy::new(frame, 3.0);
    let mut late_ink: Vec<(PagePoint, PagePoint)> = Vec::new();
    let mut taken: Vec<[f64; 4]> = Vec::new();

    // The linkage: in the frame, or small in the inset.
    let mut segments: Vec<(PagePoint, PagePoint)> = Vec::new();
    let mut grid_dots: Vec<PagePoint> = Vec::new();
    let pins = match &geometry.inset {
        None => {
            let first = dl.items.len();
            let pins = draw_linkage(&mut dl, page, &t, frame, &mut segments, &mut grid_dots);
            // The linkage's context (crank circle, plate outline, grid): ink that
            // feature labels keep clear of (curve labels weigh the links and grid dots).
            for item in &dl.items[first..] {
                match item {
                    Primitive::Polyline { points, .. } => {
                        late_ink.extend(points.windows(2).map(|w| (w[0], w[1])));
                    }
                    Primitive::Circle { center, .. } => late_ink.push((*center, *center)),
                    _ => {}
                }
            }
            pins
        }
        Some(inset) => {
            let r = inset.rect;
            dl.ink(Ink::Paper);
            dl.items.push(Primitive::Polygon {
                points: vec![[r[0], r[1]], [r[2], r[1]], [r[2], r[3]], [r[0], r[3]]],
            });
            dl.ink(Ink::Black);
            dl.rect(r, style::THIN);
            dl.text(
                [r[0] + 5.0, r[1] + 4.0 + font::ascent(style::SMALL_SIZE)],
                style::SMALL_SIZE,
                Anchor::Start,
                format!(
                    "linkage at θ = 0, crank 1 = {} in (curves: {} in)",
                    fmt_num((inset.transform.scale / PT_PER_INCH * 1000.0).round() / 1000.0),
                    fmt_num((t.scale / PT_PER_INCH * 1000.0).round() / 1000.0)
                ),
            );
            let mut inset_segments = Vec::new();
            let mut inset_dots = Vec::new();
            let pins = draw_linkage(
                &mut dl,
                page,
                &inset.transform,
                r,
                &mut inset_segments,
                &mut inset_dots,
            );
            // This page's points, filled, in the inset.
            if let Some(f) = drawn(page).coupler {
                for q in &page.points {
                    let m = f.point(*q);
                    dl.circle(inset.transform.map(m.x, m.y), style::GRID_RADIUS, None);
                }
            }
            taken.extend(pivot_labels(&mut dl, pins));
            taken.push(r);
            Vec::new()
        }
    };

    let ghost: Vec<bool> = page
        .points
        .iter()
        .map(|p| is_pin_point(a_len, *p))
        .collect();

    // Feature marks: each curve's longest straight segment and pseudo-arc, a light band
    // over the curve (under its dashes) between two ticks across it at the window's ends.
    let mut marks: Vec<FeatureMark> = Vec::new();
    for (i, p) in page.points.iter().enumerate() {
        let Some(Some(f)) = page.features.get(i) else {
            continue;
        };
        if ghost[i] {
            continue;
        }
        let longest_s = f
            .straight_segments
            .iter()
            .max_by(|a, b| a.span_deg.total_cmp(&b.span_deg))
            .map(|s| ('S', s.start_deg, s.span_deg));
        let longest_a = f
            .pseudo_arcs
            .iter()
            .max_by(|a, b| a.span_deg.total_cmp(&b.span_deg))
            .map(|a| ('A', a.start_deg, a.span_deg));
        for (kind, start, span) in longest_s.into_iter().chain(longest_a) {
            let pts = stretch(page, &t, *p, start, span);
            if pts.len() >= 2 {
                marks.push(FeatureMark {
                    pts,
                    text: format!("{kind} {}°", fmt_num(span.round())),
                });
            }
        }
    }
    if !marks.is_empty() {
        // One path of bands and one of ticks: a renderer fills each set at once.
        dl.ink(MARK_BAND_INK);
        dl.items.push(Primitive::Polylines {
            lines: marks
                .iter()
                .map(|m| trim_ends(&m.pts, 0.5 * MARK_BAND_WIDTH))
                .collect(),
            width: MARK_BAND_WIDTH,
        });
        dl.ink(Ink::Black);
        let ticks: Vec<Vec<PagePoint>> = marks
            .iter()
            .flat_map(|m| [end_tick(&m.pts, 0), end_tick(&m.pts, m.pts.len() - 1)])
            .flatten()
            .collect();
        for tick in &ticks {
            occ.mark_segment(tick[0], tick[1], 1);
        }
        for m in &marks {
            late_ink.extend(m.pts.windows(2).map(|w| (w[0], w[1])));
        }
        dl.items.push(Primitive::Polylines {
            lines: ticks,
            width: MARK_TICK_WIDTH,
        });
    }

    // Curves: the pins' ghosts first, then the others, alternating styles.
    let mut placements = Vec::with_capacity(geometry.curves.len());
    let mut page_curves: Vec<Vec<Vec<PagePoint>>> = Vec::with_capacity(geometry.curves.len());
    for c in &geometry.curves {
        let dashes: Vec<Vec<PagePoint>> = c
            .dashes
            .iter()
            .map(|d| d.points.iter().map(|p| t.map(p.x, p.y)).collect())
            .collect();
        for d in &dashes {
            for s in d.windows(2) {
                occ.mark_segment(s[0], s[1], 1);
            }
        }
        page_curves.push(dashes);
    }
    let step = setup.dash.step_deg;
    let mut bboxes = vec![EMPTY; geometry.curves.len()];
    for pass_ghost in [true, false] {
        let mut visible = 0usize;
        for (i, (c, dashes)) in geometry.curves.iter().zip(&mut page_curves).enumerate() {
            if !ghost[i] {
                visible += 1;
            }
            if ghost[i] != pass_ghost {
                continue;
            }
            let st = if ghost[i] {
                GHOST_STYLE
            } else {
                CURVE_STYLES[(visible - 1) % CURVE_STYLES.len()]
            };
            // (Each curve is drawn once, in one of the two passes: its page points are
            // moved into the display list.)
            let dashes = std::mem::take(dashes);
            bboxes[i] = draw_dashes(&mut dl, &t, &c.dashes, dashes, Some(0), &st, step, 0);
        }
    }

    // Markers' places, for the label rule and costs.
    let dots: Vec<PagePoint> = geometry
        .curves
        .iter()
        .map(|c| t.map(c.start.x, c.start.y))
        .collect();
    for d in &dots {
        occ.mark_point(*d, 40);
    }
    for (a, b) in &segments {
        occ.mark_segment(*a, *b, 4);
    }
    for g in &grid_dots {
        occ.mark_point(*g, 2);
    }
    taken.extend(pivot_labels(&mut dl, pins));

    // The key, where labels become numbers, sits in the legend area (outside the frame).
    occ.build();
    let full: Vec<String> = page
        .points
        .iter()
        .map(|p| format!("({}, {})", fmt_sig(p.u), fmt_sig(p.v)))
        .collect();
    let numbers: Vec<String> = (1..=page.points.len()).map(|k| k.to_string()).collect();
    let labels = place_labels(
        &dots,
        &full,
        &numbers,
        style::LABEL_SIZE,
        &occ,
        &taken,
        frame,
    );
    let asc = font::ascent(style::LABEL_SIZE);
    for (i, (r, text)) in labels.boxes.iter().zip(&labels.texts).enumerate() {
        dl.ink(if ghost[i] {
            GHOST_STYLE.ink
        } else {
            Ink::Black
        });
        // A label set off from its dot (to keep clear of other curves) gets a hairline
        // leader from just outside the dot to the box.
        if let Some((a, b)) = leader(dots[i], *r, LEADER_MIN_GAP, LEADER_START) {
            late_ink.push((a, b));
            dl.line(vec![a, b], style::THIN);
        }
        dl.text_halo(
            [r[0] + LABEL_PAD, r[1] + LABEL_PAD + asc],
            style::LABEL_SIZE,
            Anchor::Start,
            text.clone(),
            1.6,
        );
        taken.push(*r);
    }
    dl.ink(Ink::Black);
    // Feature labels (`S n°`, `A n°`): placed like the curve labels, around the
    // middle of their mark, clear of ink where the page allows, with a leader to the
    // band when set off.
    let bs = style::SMALL_SIZE - 1.0;
    let anchors: Vec<PagePoint> = marks.iter().map(|m| m.pts[m.pts.len() / 2]).collect();
    let texts: Vec<String> = marks.iter().map(|m| m.text.clone()).collect();
    // Feature labels also keep clear of the context lines, the bands and the curve
    // labels' leaders.
    for (a, b) in &late_ink {
        occ.mark_segment(*a, *b, 1);
    }
    occ.build();
    let boxes = place_marks(&anchors, &texts, bs, &occ, &mut taken, &dots, frame);
    dl.ink(CONTEXT_INK);
    for ((p, text), r) in anchors.iter().zip(texts).zip(boxes) {
        let Some(r) = r else { continue };
        if let Some((a, b)) = leader(*p, r, MARK_LEADER_MIN_GAP, MARK_LEADER_START) {
            dl.line(vec![a, b], style::THIN);
        }
        // A halo only where there is ink to clear (nearly every feature label finds
        // a clear place, and a halo costs more to draw than its text).
        let at = [r[0], r[1] + font::ascent(bs)];
        if occ.cost(crate::labels::grow(r, 1.0)) == Some(0) {
            dl.text(at, bs, Anchor::Start, text);
        } else {
            dl.text_halo(at, bs, Anchor::Start, text, 1.0);
        }
    }
    dl.ink(Ink::Black);

    // Markers, last: θ = 0 dots and arrowheads, cusps, crunodes.
    for (i, c) in geometry.curves.iter().enumerate() {
        dl.ink(if ghost[i] {
            GHOST_STYLE.ink
        } else {
            Ink::Black
        });
        let d0 = &c.dashes[0];
        bboxes[i] = union(
            bboxes[i],
            start_marker(
                &mut dl,
                &t,
                c.start,
                d0.points[d0.points.len() - 1],
                c.start_direction,
            ),
        );
        if let Some(Some(f)) = page.features.get(i) {
            for cusp in &f.double_points.cusps {
                let q = t.map(cusp.position[0], cusp.position[1]);
                let r = 2.6;
                dl.line(vec![[q[0] - r, q[1] - r], [q[0] + r, q[1] + r]], 0.7);
                dl.line(vec![[q[0] - r, q[1] + r], [q[0] + r, q[1] - r]], 0.7);
            }
            for cr in &f.double_points.crunodes {
                let q = t.map(cr.position[0], cr.position[1]);
                dl.circle(q, 3.0, Some(0.6));
            }
        }
    }
    dl.ink(Ink::Black);
    for (i, p) in page.points.iter().enumerate() {
        placements.push(CurvePlacement {
            point: *p,
            bbox_pt: bboxes[i],
            label_pt: labels.boxes[i],
            dot_pt: dots[i],
            label: labels.texts[i].clone(),
            ghost: ghost[i],
        });
    }

    legend(
        &mut dl,
        page,
        geometry,
        setup,
        labels.keyed.then_some(&full),
    );
    PageLayout {
        display: dl,
        curves: placements,
        scale_pt_per_unit: t.scale,
        keyed: labels.keyed,
        label_failures: labels.failed,
    }
}

/// Legend, key and footer: dash meaning, marks, crank sense, circuit, scale bar; the key
/// (number → (u, v)) at the right when the labels are numbers; generation settings.
fn legend<M: Mechanism>(
    dl: &mut DisplayList,
    page: &LinkagePage<M>,
    geometry: &PageGeometry,
    setup: &PageSetup,
    key: Option<&Vec<String>>,
) {
    let (w, h) = setup.size_pt();
    let m = setup.margin_pt;
    let ts = style::SMALL_SIZE;
    let y = crate::page::dash_legend(
        dl,
        setup,
        "one dash = {step}° of crank ({drawn}° drawn), a heavier dash every 90°; dot and bold dash: θ = 0; arrowhead: direction of travel",
    );
    // Marks: a cusp cross, a crunode ring, a bracket.
    let y2 = y + 13.0;
    let x = m + 2.0;
    let r = 2.6;
    dl.line(vec![[x, y2 - r], [x + 2.0 * r, y2 + r]], 0.7);
    dl.line(vec![[x, y2 + r], [x + 2.0 * r, y2 - r]], 0.7);
    dl.circle([x + 14.0, y2], 3.0, Some(0.6));
    // A feature mark: a band over a stretch of dashes, between ticks across it.
    let (b0, b1) = (x + 24.0, x + 52.0);
    let half = 0.5 * MARK_BAND_WIDTH;
    dl.ink(MARK_BAND_INK);
    dl.line(vec![[b0 + half, y2], [b1 - half, y2]], MARK_BAND_WIDTH);
    dl.ink(Ink::Black);
    for bx in [b0, b1] {
        dl.line(
            vec![[bx, y2 - MARK_TICK_HALF], [bx, y2 + MARK_TICK_HALF]],
            MARK_TICK_WIDTH,
        );
    }
    let mut d0 = b0 + 2.0;
    while d0 < b1 - 2.0 {
        dl.line(
            vec![[d0, y2], [(d0 + 3.6).min(b1 - 2.0), y2]],
            style::DASH_WIDTH,
        );
        d0 += 6.0;
    }
    dl.ink(CONTEXT_INK);
    dl.line(vec![[x + 58.0, y2 + 0.5], [x + 62.0, y2 - 2.5]], 1.25);
    dl.ink(Ink::Black);
    dl.text(
        [x + 70.0, y2 + 2.5],
        ts,
        Anchor::Start,
        "cusp, crunode;  band between ticks: longest straight segment S / pseudo-arc A, n° of crank;  gray: every other curve, pins' curves",
    );
    let y3 = y2 + 13.0;
    dl.text(
        [m + 2.0, y3 + 2.5],
        ts,
        Anchor::Start,
        format!(
            "crank turns counter-clockwise, θ from O2→{};  {} circuit;  linkage drawn at θ = 0°",
            // The second ground pivot: O4 of a four-bar, O5 of a geared five-bar.
            drawn(page).joints.get(1).map_or("O4", |j| j.name),
            page.circuit.name()
        ),
    );
    let sx = m
        + 2.0
        + font::text_width(
            ts,
            "crank turns counter-clockwise, θ from O2→O4;  crossed circuit;  linkage drawn at θ = 0°",
        )
        + 16.0;
    scale_bar(
        dl,
        sx,
        y3 + 2.0,
        geometry.transform.scale,
        "crank 1 = {} in",
    );
    if let Some(key) = key {
        // Two columns of (number, (u, v)) at the right of the legend area.
        let rows = key.len().div_ceil(2).max(1);
        let row = ((h - m - 10.0 - (y - 8.0)) / rows as f64).min(9.0);
        let col = 92.0;
        let x0 = w - m - 2.0 * col;
        dl.text([x0 - 4.0, y + 1.0], ts, Anchor::End, "key:");
        for (i, s) in key.iter().enumerate() {
            let (c, r) = (i / rows, i % rows);
            let xx = x0 + c as f64 * col;
            let yy = y + 1.0 + r as f64 * row;
            dl.text([xx + 10.0, yy], ts, Anchor::End, format!("{}", i + 1));
            dl.text([xx + 14.0, yy], ts, Anchor::Start, s.clone());
        }
    }
    footer(dl, setup, footer_settings(setup));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::page::rects_overlap;
    use coupler_kinematics::{FourBar, Pose};

    fn page() -> LinkagePage<FourBar> {
        let grid: Vec<CouplerPoint> = (0..4)
            .flat_map(|i| (0..3).map(move |j| CouplerPoint::new(i as f64, j as f64 - 1.0)))
            .collect();
        LinkagePage {
            linkage: FourBar::new(3.0, 2.0, 3.0).unwrap(),
            circuit: Circuit::Open,
            points: grid[..10].to_vec(),
            grid,
            page_number: 1,
            page_count: 2,
            features: Vec::new(),
        }
    }

    #[test]
    fn the_header_gives_the_transmission_angle_once() {
        use coupler_kinematics::{GearRatio, GearedFiveBar};
        let count = |s: &str| s.matches('μ').count();
        let (_, sub) = header_lines(&page());
        assert_eq!(count(&sub), 1, "{sub}");
        let geared = LinkagePage {
            linkage: GearedFiveBar::new(2.3, 2.9, 3.4, 1.7, GearRatio::new(-1, 2).unwrap(), 30.0)
                .unwrap(),
            circuit: Circuit::Open,
            points: vec![CouplerPoint::new(1.0, 0.5)],
            grid: vec![CouplerPoint::new(1.0, 0.5)],
            page_number: 1,
            page_count: 1,
            features: Vec::new(),
        };
        let (_, sub) = header_lines(&geared);
        assert_eq!(count(&sub), 1, "{sub}");
        assert!(sub.contains("Ting"), "{sub}");
        // The row is given in units of the five-bar's coupler link L3, not a four-bar's A.
        assert!(sub.contains("row v = 0.5 ("), "{sub}");
        assert!(sub.contains(" L3)") && !sub.contains(" A)"), "{sub}");
    }

    #[test]
    fn everything_inside_the_frame_and_labels_disjoint() {
        let setup = PageSetup::default();
        let pg = page();
        let geo = compute_page(&pg, &setup).unwrap();
        let lay = layout_page(&pg, &geo, &setup);
        assert_eq!(lay.curves.len(), 10);
        let f = geo.frame;
        for c in &lay.curves {
            let b = c.bbox_pt;
            assert!(
                b[0] >= f[0] && b[1] >= f[1] && b[2] <= f[2] && b[3] <= f[3],
                "{b:?} outside {f:?}"
            );
            let px = c.bbox_px(setup.dpi);
            assert!(px[2] <= 3300 && px[3] <= 5100 && px[0] < px[2]);
        }
        for (i, a) in lay.curves.iter().enumerate() {
            for b in &lay.curves[i + 1..] {
                assert!(!rects_overlap(a.label_pt, b.label_pt), "{a:?} {b:?}");
            }
        }
        // Scale is a round number of inches per crank unit.
        let s_in = lay.scale_pt_per_unit / PT_PER_INCH;
        assert!(nice_inches_per_unit().contains(&s_in), "{s_in}");
    }

    #[test]
    fn far_points_are_fitted_not_cut() {
        let mut pg = page();
        pg.points = vec![
            CouplerPoint::new(20.0, 15.0),
            CouplerPoint::new(-10.0, -12.0),
        ];
        let setup = PageSetup::default();
        let geo = compute_page(&pg, &setup).unwrap();
        let lay = layout_page(&pg, &geo, &setup);
        for c in &lay.curves {
            let b = c.bbox_pt;
            let f = geo.frame;
            assert!(b[0] >= f[0] && b[1] >= f[1] && b[2] <= f[2] && b[3] <= f[3]);
        }
    }

    /// Under `auto` a page of wide curves turns landscape, at a larger scale than
    /// portrait gives it, and everything stays in its own frame; a fixed orientation is
    /// kept.
    #[test]
    fn auto_orientation_takes_the_larger_scale() {
        use crate::page::{Orientation, PageSize, PaperSize};
        // Hoeken's straight-line point: a long flat curve.
        let mut pg = page();
        pg.linkage = FourBar::new(2.5, 2.5, 2.0).unwrap();
        pg.points = vec![CouplerPoint::new(5.0, 0.0)];
        let fixed = |o| PageSetup {
            size: PageSize {
                paper: PaperSize::Tabloid,
                orientation: o,
            },
            ..PageSetup::default()
        };
        let portrait = compute_page(&pg, &fixed(Orientation::Portrait)).unwrap();
        let landscape = compute_page(&pg, &fixed(Orientation::Landscape)).unwrap();
        assert_eq!(portrait.orientation, Orientation::Portrait);
        assert!(landscape.transform.scale > portrait.transform.scale);
        let setup = fixed(Orientation::Auto);
        let auto = compute_page(&pg, &setup).unwrap();
        assert_eq!(auto.orientation, Orientation::Landscape);
        assert_eq!(auto.transform, landscape.transform);
        let lay = layout_page(&pg, &auto, &setup);
        assert_eq!((lay.display.width, lay.display.height), (1224.0, 792.0));
        assert_eq!(lay.display.size_px(300.0), (5100, 3300));
        let f = auto.frame;
        assert!(f[2] > 1100.0, "{f:?}");
        for c in &lay.curves {
            let b = c.bbox_pt;
            assert!(b[0] >= f[0] && b[1] >= f[1] && b[2] <= f[2] && b[3] <= f[3]);
        }
    }

    #[test]
    fn a_dash_shrunk_at_a_cusp_stays_a_countable_dot() {
        let setup = PageSetup::default();
        let mut pg = page();
        pg.points.truncate(1);
        let mut geo = compute_page(&pg, &setup).unwrap();
        // Collapse dash 7 to a point, as at a cusp where the speed vanishes.
        let d = &mut geo.curves[0].dashes[7];
        let p = d.points[0];
        d.points = vec![p, p];
        let lay = layout_page(&pg, &geo, &setup);
        let at = geo.transform.map(p.x, p.y);
        let dots = lay
            .display
            .items
            .iter()
            .filter(|i| matches!(i, Primitive::Circle { center, width: None, radius } if *center == at && *radius >= 0.5))
            .count();
        assert_eq!(
            dots, 1,
            "the collapsed dash must be drawn as one filled dot"
        );
        // The other 35 dashes are strokes: 1 bold θ = 0 dash + 34 in the curve's set.
        let regular: usize = lay
            .display
            .items
            .iter()
            .map(|i| match i {
                Primitive::Polylines { lines, .. } => lines.len(),
                _ => 0,
            })
            .sum();
        assert_eq!(regular, 34);
    }

    /// The coupler point that sits on the instant centre at θ0 has a cusp there (its
    /// velocity vanishes). Its page still shows all 36 dashes, each a stroke or a dot.
    #[test]
    fn real_cusp_keeps_every_dash() {
        let l = FourBar::new(3.0, 2.0, 3.0).unwrap();
        let theta0 = 33.0; // the middle of dash 3 (30°–36°)
        let pose = Pose::solve(&l, Circuit::Open, &CrankAngle::from_degrees(theta0)).unwrap();
        // Instant centre: O2 + s·Pa = O4 + t·e4 (lines O2Pa and O4Pb).
        let (a, e4) = (pose.crank_pin.coords, pose.rocker_dir);
        let det = a.x * (-e4.y) - a.y * (-e4.x);
        let s_ = (l.ground * (-e4.y)) / det;
        let ic = a * s_;
        let d = ic - pose.crank_pin.coords;
        let e = pose.coupler_dir;
        let p = CouplerPoint::new(d.dot(&e), -d.x * e.y + d.y * e.x);
        assert!(
            pose.velocity(p).norm() < 1e-9,
            "not a cusp: {}",
            pose.velocity(p).norm()
        );
        let mut pg = page();
        pg.points = vec![p];
        let setup = PageSetup::default();
        let geo = compute_page(&pg, &setup).unwrap();
        let cusp = &geo.curves[0].dashes[3];
        assert!(cusp.length() < 0.2 * geo.curves[0].dashes[20].length());
        let lay = layout_page(&pg, &geo, &setup);
        let strokes: usize = lay
            .display
            .items
            .iter()
            .map(|i| match i {
                Primitive::Polylines { lines, .. } => lines.len(),
                _ => 0,
            })
            .sum();
        let dots = lay
            .display
            .items
            .iter()
            .filter(|i| matches!(i, Primitive::Circle { width: None, radius, .. } if *radius <= style::DOT_RADIUS.max(0.5 * style::DASH_WIDTH)))
            .count();
        // 1 bold θ = 0 dash + the others as strokes or dots.
        assert_eq!(1 + strokes + dots, 36, "strokes {strokes}, dots {dots}");
    }
}
