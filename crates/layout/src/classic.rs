//! Pages of a full-curve page set (`atlas-spec/classics.toml`): one named four-bar per
//! page, its complete coupler curve traced across toggles, dashed by input angle.
//!
//! The page follows the atlas page (same frame, fonts, dashes, scale rule and footer) with
//! what a linkage that is not a crank-rocker needs: every branch of the curve, each leg of
//! a rocking input dashed in the order the point moves (one dash per `Δ` of input, as on
//! the atlas pages, so counting dashes still reads input time); the toggles, where the
//! input stops and reverses and the linkage changes circuit, as small squares; the input's
//! path (crank circle, or the arc between its toggles); the linkage drawn mid-way along its
//! straight run, with the coupler triangle to M; the longest straight run at ε_S ≤ 0.1 %
//! bracketed; and the measured straightness at 1 %, 0.1 % and 0.01 % in a box.

use crate::atlas::fmt_sig;
use crate::atlas::{CurvePlacement, Inset, PageLayout, place_inset};
use crate::font;
use crate::labels::InkSegments;
use crate::page::{
    Anchor, CurveStyle, DisplayList, Ink, LayoutError, Occupancy, Orientation, PagePoint,
    PageSetup, Primitive, WorldToPage, draw_dashes, draw_links_width, fit_into, fmt_num,
    footer_settings, frame_for, pivot_labels, rects_overlap, start_marker, style, union,
};
use coupler_features::{
    ClassicCurve, CrankWindow, LineDirection, NamedCurve, STRAIGHTNESS_TOLERANCES, StraightMeasure,
    WindowMeasures,
};
use coupler_kinematics::{
    Circuit, CrankAngle, Dash, InputRange, Linkage, Mechanism, Pose, dash_curve, dash_leg_from,
};
use nalgebra::Vector2;

/// Inches per input unit offered for the page scale: the atlas's list, continued for the
/// small linkages of this set (Chebyshev's spans 1.3 units).
const NICE_INCHES_PER_UNIT: [f64; 37] = [
    0.1, 0.125, 0.15, 0.175, 0.2, 0.225, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.6, 0.7, 0.75, 0.8, 0.9,
    1.0, 1.1, 1.2, 1.25, 1.4, 1.5, 1.75, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0,
    20.0, 25.0,
];

/// Index of the tolerance in [`STRAIGHTNESS_TOLERANCES`] whose run is
/// bracketed on the page and at whose middle the linkage is drawn (0.1 %).
pub const BRACKETED_TOLERANCE: usize = 1;

/// What one page of a full-curve page set shows.
#[derive(Clone, Debug, PartialEq)]
pub struct ClassicPage {
    /// The named curve.
    pub curve: NamedCurve,
    /// Its full trace and measures.
    pub measured: ClassicCurve,
    /// Page number (1-based) and pages in the set.
    pub page_number: usize,
    /// Pages in the set.
    pub page_count: usize,
    /// `[sampling] crank_step_deg` the measures were taken at (printed with them).
    pub step_deg: f64,
}

/// One leg of a branch: the input moving one way on one circuit, cut into dashes.
#[derive(Clone, Debug, PartialEq)]
pub struct Leg {
    /// The branch it belongs to.
    pub branch: usize,
    /// The circuit.
    pub circuit: Circuit,
    /// Dashes in the order of travel.
    pub dashes: Vec<Dash>,
}

/// A classic page computed for a setup.
#[derive(Clone, Debug, PartialEq)]
pub struct ClassicGeometry {
    /// The legs, branch by branch, in the order of motion.
    pub legs: Vec<Leg>,
    /// Page transform.
    pub transform: WorldToPage,
    /// Plot frame in points.
    pub frame: [f64; 4],
    /// Input angle (degrees) and circuit at which the linkage is drawn.
    pub drawn: (f64, Circuit),
    /// Where the linkage is drawn small, when at the curve's scale it would take most of
    /// the sheet (`None`: with the curve).
    pub inset: Option<Inset>,
    /// The page's orientation (chosen here when the setup's is `auto`).
    pub orientation: Orientation,
}

/// The pose the linkage is drawn in: the middle sample of the bracketed straight run (the
/// position the linkage is used in), else the first sample of the first branch.
fn drawn_state(page: &ClassicPage) -> Option<(f64, Circuit)> {
    let m = &page.measured;
    let pick = |branch: usize, k: usize| {
        m.branches
            .get(branch)
            .and_then(|b| b.samples.get(k))
            .filter(|s| !s.toggle)
            .map(|s| (s.degrees, s.circuit))
    };
    m.straight
        .get(BRACKETED_TOLERANCE)
        .copied()
        .flatten()
        .and_then(|s| pick(s.branch, s.samples[0] + s.samples[1] / 2))
        .or_else(|| pick(0, 1))
}

/// The coupler point where the linkage is drawn (the four-bar's by its [`Pose`], as the
/// pages always drew it; a geared five-bar's by its frame); `None` where it does not
/// assemble.
fn drawn_point(page: &ClassicPage, drawn: (f64, Circuit)) -> Option<nalgebra::Point2<f64>> {
    let angle = CrankAngle::from_degrees(drawn.0);
    let p = page.curve.point;
    match &page.curve.linkage {
        Linkage::FourBar(l) => Pose::solve(l, drawn.1, &angle).map(|pose| pose.point(p)),
        Linkage::GearedFiveBar(g) => g.frame(drawn.1, &angle).map(|f| f.point(p)),
    }
}

/// Computes the page: the extent of every branch, the linkage and the input's path at the
/// largest round scale that fits, then each leg dashed to the page's chord tolerance.
pub fn compute_classic(
    page: &ClassicPage,
    setup: &PageSetup,
) -> Result<ClassicGeometry, LayoutError> {
    setup.validate()?;
    let l = page.curve.linkage;
    let p = page.curve.point;
    let drawn = drawn_state(page).unwrap_or((0.0, Circuit::Open));
    // The ground pivots, the input's path (its circle, or the arcs it rocks over), the
    // branches, the linkage's joints where it is drawn.
    let drawing = l.drawing(drawn.1, &CrankAngle::from_degrees(drawn.0));
    let mut world = [0.0, 0.0, 0.0, 0.0];
    for j in drawing.joints.iter().filter(|j| j.ground) {
        world = union(
            world,
            [j.position.x, j.position.y, j.position.x, j.position.y],
        );
    }
    let mut curve_world = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];
    let mut samples = Vec::new();
    let mirror = mirror_branch(page);
    for (i, (a0, a1)) in input_arcs(&page.measured.range).into_iter().enumerate() {
        if Some(i) == mirror {
            continue;
        }
        for q in arc_points(a0, a1) {
            world = union(world, [q.0, q.1, q.0, q.1]);
        }
    }
    for b in page
        .measured
        .branches
        .iter()
        .enumerate()
        .filter(|(i, _)| Some(*i) != mirror)
        .map(|(_, b)| b)
    {
        for s in &b.samples {
            curve_world = union(curve_world, [s.point.x, s.point.y, s.point.x, s.point.y]);
            samples.push((s.point.x, s.point.y));
        }
    }
    if let Some(m) = drawn_point(page, drawn) {
        let moving = drawing.joints.iter().filter(|j| !j.ground);
        for q in moving.map(|j| j.position).chain([m]) {
            world = union(world, [q.x, q.y, q.x, q.y]);
        }
    }
    if !curve_world[0].is_finite() {
        curve_world = world;
    }
    // Each orientation the page may take (both under `auto`): the largest scale wins,
    // portrait on a tie.
    let mut best: Option<(WorldToPage, Option<Inset>, [f64; 4], Orientation)> = None;
    for &o in setup.size.orientation.candidates() {
        let frame = frame_for(setup, o);
        let inner = crate::page::inset_rect(frame, style::FRAME_PAD);
        let all = union(world, curve_world);
        let t_all = fit_into(all, inner, &NICE_INCHES_PER_UNIT);
        let t_cur = fit_into(curve_world, inner, &NICE_INCHES_PER_UNIT);
        let (t, inset) = if t_all.scale >= 0.8 * t_cur.scale {
            (t_all, None)
        } else {
            place_inset(
                curve_world,
                all,
                &samples,
                inner,
                &NICE_INCHES_PER_UNIT,
                "the linkage and its curve, input 1 = 0.000 in",
            )
        };
        if best.as_ref().is_none_or(|b| t.scale > b.0.scale) {
            best = Some((t, inset, frame, o));
        }
    }
    let (transform, inset, frame, orientation) = best.expect("at least one orientation");
    let tol = setup.chord_tolerance_px / setup.px_per_pt() / transform.scale;
    let mut legs = Vec::new();
    match &page.measured.range {
        InputRange::Never => {}
        InputRange::Full => {
            for (bi, b) in page.measured.branches.iter().enumerate() {
                let circuit = b
                    .samples
                    .first()
                    .map(|s| s.circuit)
                    .unwrap_or(Circuit::Open);
                let c = dash_curve(&l, circuit, p, &setup.dash, tol)?;
                legs.push(Leg {
                    branch: bi,
                    circuit,
                    dashes: c.dashes,
                });
            }
        }
        InputRange::Rocks { intervals } => {
            let mirror = mirror_branch(page);
            for (bi, (lo, hi)) in intervals.iter().enumerate() {
                if Some(bi) == mirror {
                    continue;
                }
                // Dashes counted by input travel from the branch's start (its lower
                // toggle), out on the open circuit and back on the crossed one.
                let span = hi.degrees - lo.degrees;
                for (circuit, from, to, travel0) in [
                    (Circuit::Open, lo.degrees, hi.degrees, 0.0),
                    (Circuit::Crossed, hi.degrees, lo.degrees, span),
                ] {
                    let dashes =
                        dash_leg_from(&l, circuit, p, &setup.dash, tol, from, to, travel0)?;
                    legs.push(Leg {
                        branch: bi,
                        circuit,
                        dashes,
                    });
                }
            }
        }
    }
    Ok(ClassicGeometry {
        legs,
        transform,
        frame,
        drawn,
        inset,
        orientation,
    })
}

/// The branch of a rocking input that is the mirror assembly of the drawn one: when the
/// input rocks in two intervals that are mirror images in the ground line (the linkage
/// reflected: its curve is this curve reflected), the one without the bracketed straight
/// run. It is not drawn (the page says so).
///
/// Only a four-bar's: a geared five-bar's mirror image is another linkage (its phase
/// negated), so its intervals are two assemblies of this one and both are drawn.
pub fn mirror_branch(page: &ClassicPage) -> Option<usize> {
    let InputRange::Rocks { intervals } = &page.measured.range else {
        return None;
    };
    page.curve.linkage.four_bar()?;
    if intervals.len() != 2 {
        return None;
    }
    let norm = |d: f64| (d % 360.0 + 360.0) % 360.0;
    let (a, b) = (intervals[0], intervals[1]);
    let close = |x: f64, y: f64| {
        let d = norm(x - y);
        d.min(360.0 - d) < 1e-6
    };
    let mirrored = close(a.0.degrees, -b.1.degrees) && close(a.1.degrees, -b.0.degrees);
    if !mirrored {
        return None;
    }
    let kept = page
        .measured
        .straight
        .get(BRACKETED_TOLERANCE)
        .copied()
        .flatten()
        .map(|s| s.branch)
        .unwrap_or(0);
    Some(1 - kept.min(1))
}

/// The input's path as angle intervals (degrees): the full circle for a crank, else each
/// rocking interval between its toggles.
fn input_arcs(range: &InputRange) -> Vec<(f64, f64)> {
    match range {
        InputRange::Rocks { intervals } => intervals
            .iter()
            .map(|(lo, hi)| (lo.degrees, hi.degrees))
            .collect(),
        _ => vec![(0.0, 360.0)],
    }
}

/// Points of the unit circle about O2 from `a0` to `a1` degrees, at most 3° apart.
fn arc_points(a0: f64, a1: f64) -> Vec<(f64, f64)> {
    let n = ((a1 - a0) / 3.0).ceil().max(2.0) as usize;
    (0..=n)
        .map(|k| {
            let (s, c) = coupler_kinematics::sincos_deg(a0 + (a1 - a0) * k as f64 / n as f64);
            (c, s)
        })
        .collect()
}

/// In words, how the input moves and which kind of linkage this is (a four-bar's Barker
/// class and Grashof family; a geared five-bar's Ting class and gears).
fn kind_text(page: &ClassicPage) -> String {
    let family = match &page.curve.linkage {
        Linkage::FourBar(l) => {
            let class = l.class();
            let family = if class.is_grashof() {
                "Grashof"
            } else if class.is_change_point() {
                "change point"
            } else {
                "non-Grashof"
            };
            format!("class {} ({family})", class.code())
        }
        Linkage::GearedFiveBar(g) => format!(
            "geared five-bar, Ting class {}, λ = {}, φ = {}°",
            g.ting_class().code(),
            minus_sign(g.ratio.to_string()),
            minus_sign(fmt_sig(g.phase))
        ),
    };
    let input = match &page.measured.range {
        InputRange::Full => "the input turns fully (a crank)".to_string(),
        InputRange::Never => "it never assembles".to_string(),
        InputRange::Rocks { .. } => format!(
            "the input rocks in {} between its toggles",
            page.measured.range_text()
        ),
    };
    format!("{family}: {input}")
}

/// Text with a leading hyphen-minus as a real minus sign (U+2212).
fn minus_sign(text: String) -> String {
    match text.strip_prefix('-') {
        Some(rest) => format!("\u{2212}{rest}"),
        None => text,
    }
}

/// ε_V over a straight run (percent), measured on its circuit over its input window with
/// the fitted line (`WindowMeasures`); `None` for a run through a toggle (two circuits).
pub fn run_velocity_variation(page: &ClassicPage, s: &StraightMeasure) -> Option<f64> {
    let b = page.measured.branches.get(s.branch)?;
    let samples = b.samples.get(s.samples[0]..s.samples[0] + s.samples[1])?;
    let circuit = samples.first()?.circuit;
    if samples.iter().any(|q| q.circuit != circuit || q.toggle) {
        return None;
    }
    let (a, e) = (
        s.input_deg[0].min(s.input_deg[1]),
        s.input_deg[0].max(s.input_deg[1]),
    );
    let window = CrankWindow::new(a, e, page.step_deg.min(e - a)).ok()?;
    WindowMeasures::measure(
        &page.curve.linkage,
        circuit,
        page.curve.point,
        &window,
        LineDirection::Fitted,
    )
    .ok()?
    .velocity_variation_pct
}

/// A tolerance as printed: `1 %`, `0.1 %`, `0.01 %`.
fn tol_text(tolerance: f64) -> String {
    format!("{} %", fmt_sig(tolerance * 100.0))
}

fn straight_text(
    page: &ClassicPage,
    s: &Option<StraightMeasure>,
    tolerance: f64,
    dash: f64,
) -> String {
    let tol = tol_text(tolerance);
    match s {
        Some(s) => {
            let ev = match run_velocity_variation(page, s) {
                Some(v) => format!("εᵥ = {} %", fmt_sig(v)),
                None => "εᵥ: through a toggle".into(),
            };
            format!(
                "εₛ ≤ {tol}:  {}° of input ({} dashes),  Δx = {},  εₛ = {} %,  {ev}",
                fmt_sig(s.input_span_deg),
                fmt_sig(s.input_span_deg / dash),
                fmt_sig(s.extent),
                fmt_sig(s.straightness * 100.0)
            )
        }
        None => format!("εₛ ≤ {tol}:  no run of three samples"),
    }
}

/// The line saying that a mirror assembly is not drawn (none if there is none).
fn mirror_note(page: &ClassicPage, mirror: Option<usize>) -> Option<String> {
    let m = mirror?;
    match &page.measured.range {
        InputRange::Rocks { intervals } => intervals.get(m).map(|(lo, hi)| {
            format!(
                "Not drawn: the mirror assembly (input {}° to {}°), which traces this curve reflected in the ground line.",
                fmt_sig(lo.degrees),
                fmt_sig(hi.degrees)
            )
        }),
        _ => None,
    }
}

/// Ink of the ghost linkage and the input's path.
const GHOST: Ink = Ink::Gray(110);

/// Lays out a classic page from its geometry. The placement's box covers every branch.
pub fn layout_classic(
    page: &ClassicPage,
    geometry: &ClassicGeometry,
    setup: &PageSetup,
) -> PageLayout {
    let setup = &setup.oriented(geometry.orientation);
    let (w, h) = setup.size_pt();
    let mut dl = DisplayList::new(w, h);
    let t = geometry.transform;
    let frame = geometry.frame;
    let l = page.curve.linkage;
    let p = page.curve.point;
    let step = setup.dash.step_deg;

    // Header.
    crate::page::header(
        &mut dl,
        setup,
        format!(
            "{}    {}   M = ({}, {})",
            page.curve.name,
            l.dimensions()
                .iter()
                .map(|(name, x)| format!("{name} = {}", fmt_sig(*x)))
                .collect::<Vec<_>>()
                .join("   "),
            fmt_sig(p.u),
            fmt_sig(p.v)
        ),
        format!("{};  input = 1", kind_text(page)),
        [page.page_number, page.page_count],
    );
    dl.rect(frame, style::FRAME);
    let mut occ = Occupancy::new(frame, 3.0);

    // The input's path and the linkage, first and as a thin gray ghost, so that the
    // curve is drawn over them; in an inset (with the curve, small) when at the curve's
    // scale they would take most of the sheet.
    let main_t = t;
    let t = match &geometry.inset {
        None => t,
        Some(inset) => {
            let r = inset.rect;
            dl.rect(r, style::THIN);
            dl.text(
                [r[0] + 5.0, r[1] + 4.0 + font::ascent(style::SMALL_SIZE)],
                style::SMALL_SIZE,
                Anchor::Start,
                format!(
                    "the linkage and its curve, input 1 = {} in",
                    fmt_num(
                        (inset.transform.scale / crate::page::PT_PER_INCH * 1000.0).round()
                            / 1000.0
                    )
                ),
            );
            let lt = inset.transform;
            let mirror = mirror_branch(page);
            let lines: Vec<Vec<PagePoint>> = page
                .measured
                .branches
                .iter()
                .enumerate()
                .filter(|(i, _)| Some(*i) != mirror)
                .map(|(_, b)| {
                    b.samples
                        .iter()
                        .map(|s| lt.map(s.point.x, s.point.y))
                        .collect()
                })
                .collect();
            dl.items
                .push(crate::page::Primitive::Polylines { lines, width: 0.5 });
            lt
        }
    };
    dl.ink(GHOST);
    let mirror = mirror_branch(page);
    for (a0, a1) in input_arcs(&page.measured.range)
        .into_iter()
        .enumerate()
        .filter(|(i, _)| Some(*i) != mirror)
        .map(|(_, a)| a)
    {
        let arc: Vec<PagePoint> = arc_points(a0, a1)
            .into_iter()
            .map(|(x, y)| t.map(x, y))
            .collect();
        dl.line(arc, style::THIN);
    }
    let mut segments = Vec::new();
    let mut pins = Vec::new();
    if let Some(mq) = drawn_point(page, geometry.drawn) {
        let drawing = l.drawing(
            geometry.drawn.1,
            &CrankAngle::from_degrees(geometry.drawn.0),
        );
        pins = draw_links_width(&mut dl, &t, &drawing, &mut segments, 0.7);
        // The coupler body's ends: the input's pin and the far end of its link (a
        // four-bar's rocker pin, a geared five-bar's dyad joint).
        let pin = |name: &str| pins.iter().find(|q| q.1 == name).map(|q| q.0);
        let ends = [pin("Pa"), pin("Pb").or_else(|| pin("P"))];
        let mp = t.map(mq.x, mq.y);
        for a in ends.into_iter().flatten() {
            if libm::hypot(mp[0] - a[0], mp[1] - a[1]) > 2.0 * style::PIN_RADIUS {
                dl.line(vec![a, mp], style::THIN);
                segments.push((a, mp));
            }
        }
        dl.circle(mp, style::GRID_RADIUS + 0.5, Some(style::THIN + 0.3));
        pins.push((mp, "M"));
    }
    dl.ink(Ink::Black);
    let t = main_t;

    // Curve: every leg drawn (but a mirror assembly's); the first dash of each branch
    // bold, a heavier dash every 90° of input travel.
    let mut bbox = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];
    let mut centroid = [0.0, 0.0, 0.0];
    let mut branch_started = Vec::new();
    let mut start_dot: PagePoint = [0.0, 0.0];
    let mut markers = Vec::new();
    for leg in &geometry.legs {
        let pts: Vec<Vec<PagePoint>> = leg
            .dashes
            .iter()
            .map(|d| d.points.iter().map(|q| t.map(q.x, q.y)).collect())
            .collect();
        for d in &pts {
            for s in d.windows(2) {
                occ.mark_segment(s[0], s[1], 1);
            }
            for q in d {
                centroid = [centroid[0] + q[0], centroid[1] + q[1], centroid[2] + 1.0];
            }
        }
        let first = !branch_started.contains(&leg.branch);
        let bold = (first && !leg.dashes.is_empty()).then_some(0);
        bbox = union(
            bbox,
            draw_dashes(
                &mut dl,
                &t,
                &leg.dashes,
                pts,
                bold,
                &CurveStyle::BLACK,
                step,
                0,
            ),
        );
        if let (true, Some(d0)) = (first, leg.dashes.first()) {
            branch_started.push(leg.branch);
            // The dot at the branch's start (θ = 0, or the lower toggle, where its first
            // dash now starts), the arrowhead at the end of its first dash.
            let start = page.measured.branches[leg.branch]
                .samples
                .first()
                .map(|s| s.point)
                .unwrap_or(d0.points[0]);
            let end = d0.points[d0.points.len() - 1];
            let dir = travel_direction(page, leg.circuit, d0);
            if start_dot == [0.0, 0.0] {
                start_dot = t.map(start.x, start.y);
            }
            markers.push((start, end, dir));
        }
    }
    // Toggles: small open squares where the input reverses (a rocking branch starts and
    // ends at the same toggle: its closing sample stands for both).
    for (bi, b) in page.measured.branches.iter().enumerate() {
        if Some(bi) == mirror {
            continue;
        }
        for s in b.samples.iter().filter(|s| s.toggle).skip(1) {
            let q = t.map(s.point.x, s.point.y);
            let r = 2.6;
            dl.rect([q[0] - r, q[1] - r, q[0] + r, q[1] + r], style::THIN + 0.2);
            occ.mark_point(q, 2);
        }
    }
    for (a, b) in &segments {
        occ.mark_segment(*a, *b, 2);
    }
    // The inset box is taken: neither the measures nor a bracket label may cover it.
    let mut taken: Vec<[f64; 4]> = geometry.inset.iter().map(|i| i.rect).collect();
    dl.ink(GHOST);
    taken.extend(pivot_labels(&mut dl, pins));
    dl.ink(Ink::Black);
    occ.build();

    // Nested brackets: the 0.01 % run nearest the curve, then 0.1 %, then 1 %. Every
    // bracket is drawn before any label is placed, so that no label is set where a later
    // bracket runs.
    let centroid = if centroid[2] > 0.0 {
        [centroid[0] / centroid[2], centroid[1] / centroid[2]]
    } else {
        [0.5 * (frame[0] + frame[2]), 0.5 * (frame[1] + frame[3])]
    };
    let mut brackets = Vec::new();
    for (i, s) in page.measured.straight.iter().enumerate().rev() {
        let Some(mut s) = *s else { continue };
        if mirror == Some(s.branch) {
            // Its mirror image lies on the drawn branch.
            s.ends = s.ends.map(|[x, y]| [x, -y]);
        }
        let depth = (page.measured.straight.len() - 1 - i) as f64;
        let off = 6.0 + 11.0 * depth;
        let text = format!(
            "εₛ ≤ {}: {}°, {} dashes",
            tol_text(s.tolerance),
            fmt_sig(s.input_span_deg),
            fmt_sig(s.input_span_deg / step)
        );
        brackets.push((bracket(&mut dl, &t, &s, centroid, off), text));
    }

    // Markers: each branch's start dot and arrowhead, above the curve.
    for (start, end, dir) in markers {
        bbox = union(bbox, start_marker(&mut dl, &t, start, end, dir));
    }

    // The bracket labels, clear of all the ink and text drawn so far.
    let (mut ink, texts) = ink_and_text(&dl.items);
    taken.extend(texts);
    for (b, text) in brackets {
        let r = bracket_label(&mut dl, &b, text, &mut ink, &taken, frame);
        taken.push(r);
    }

    // The measures, in the frame corner with the least ink.
    let lines: Vec<String> = std::iter::once(format!(
        "Longest straight run (moving one way along its fitted line; {}° input steps):",
        fmt_num(page.step_deg)
    ))
    .chain(
        page.measured
            .straight
            .iter()
            .zip(STRAIGHTNESS_TOLERANCES)
            .map(|(s, tol)| straight_text(page, s, tol, step)),
    )
    .chain(mirror_note(page, mirror))
    .collect();
    let size = style::SMALL_SIZE + 0.5;
    let row = size + 3.5;
    let bw = lines
        .iter()
        .map(|s| font::text_width(size, s))
        .fold(0.0, f64::max)
        + 12.0;
    let bh = row * lines.len() as f64 + 8.0;
    let inset = 6.0;
    let corners = [
        [frame[0] + inset, frame[1] + inset],
        [frame[2] - inset - bw, frame[1] + inset],
        [frame[0] + inset, frame[3] - inset - bh],
        [frame[2] - inset - bw, frame[3] - inset - bh],
    ];
    let best = corners
        .iter()
        .map(|c| [c[0], c[1], c[0] + bw, c[1] + bh])
        .min_by_key(|r| {
            occ.cost(*r).unwrap_or(u64::MAX / 2)
                + 1_000_000 * taken.iter().filter(|q| rects_overlap(**q, *r)).count() as u64
        })
        .unwrap_or([frame[0], frame[1], frame[0] + bw, frame[1] + bh]);
    dl.rect(best, style::THIN);
    for (i, s) in lines.into_iter().enumerate() {
        dl.text(
            [best[0] + 6.0, best[1] + 4.0 + row * (i as f64 + 1.0) - 3.0],
            size,
            Anchor::Start,
            s,
        );
    }

    let rocks = matches!(page.measured.range, InputRange::Rocks { .. });
    legend(&mut dl, geometry, setup, rocks);
    PageLayout {
        display: dl,
        curves: vec![CurvePlacement {
            point: p,
            bbox_pt: bbox,
            label_pt: best,
            dot_pt: start_dot,
            label: page.curve.name.clone(),
            ghost: false,
        }],
        scale_pt_per_unit: t.scale,
        keyed: false,
        label_failures: 0,
    }
}

/// Direction of travel (world, unit) at the end of dash `d` on `circuit`: the velocity for
/// the way the input moves on this leg, else the chord.
fn travel_direction(page: &ClassicPage, circuit: Circuit, d: &Dash) -> Vector2<f64> {
    let sign = if d.theta_end >= d.theta_start {
        1.0
    } else {
        -1.0
    };
    let angle = CrankAngle::from_degrees(d.theta_end);
    let p = page.curve.point;
    let v = match &page.curve.linkage {
        Linkage::FourBar(l) => Pose::solve(l, circuit, &angle).map(|pose| pose.velocity(p)),
        Linkage::GearedFiveBar(g) => g.frame(circuit, &angle).map(|f| f.velocity(p)),
    }
    .map(|v| v * sign)
    .filter(|v| v.norm() > 1e-12 && v.iter().all(|x| x.is_finite()));
    let chord = d.points[d.points.len() - 1] - d.points[0];
    match v {
        Some(v) => v / v.norm(),
        None if chord.norm() > 0.0 => chord / chord.norm(),
        None => Vector2::zeros(),
    }
}

/// A bracket drawn beside a straight run: its middle on the bracket line, its outward
/// normal and direction along it (unit), and its length (points).
struct Bracket {
    mid: PagePoint,
    ends: [PagePoint; 2],
    n: PagePoint,
    u: PagePoint,
    len: f64,
}

/// A bracket beside the straight run, `off` pt out on the side away from the curve's
/// centroid, with ticks at its ends.
fn bracket(
    dl: &mut DisplayList,
    t: &WorldToPage,
    s: &StraightMeasure,
    centroid: PagePoint,
    off: f64,
) -> Bracket {
    let a = t.map(s.ends[0][0], s.ends[0][1]);
    let b = t.map(s.ends[1][0], s.ends[1][1]);
    let len = libm::hypot(b[0] - a[0], b[1] - a[1]).max(1e-9);
    let u = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
    let mut n = [-u[1], u[0]];
    let mid = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
    if n[0] * (centroid[0] - mid[0]) + n[1] * (centroid[1] - mid[1]) > 0.0 {
        n = [-n[0], -n[1]];
    }
    let at = |p: PagePoint, d: f64| [p[0] + n[0] * d, p[1] + n[1] * d];
    dl.line(vec![at(a, off), at(a, off + 6.0)], 0.6);
    dl.line(vec![at(b, off), at(b, off + 6.0)], 0.6);
    dl.line(vec![at(a, off + 4.0), at(b, off + 4.0)], 0.6);
    Bracket {
        mid: at(mid, off + 4.0),
        ends: [at(a, off + 4.0), at(b, off + 4.0)],
        n,
        u,
        len,
    }
}

/// The ink of `items` as strokes (what is drawn in paper is skipped), and the boxes of
/// their texts.
fn ink_and_text(items: &[Primitive]) -> (InkSegments, Vec<[f64; 4]>) {
    let mut ink = InkSegments::default();
    let mut texts = Vec::new();
    let mut paper = false;
    for item in items {
        match item {
            Primitive::Ink(k) => paper = *k == Ink::Paper,
            _ if paper => {}
            Primitive::Polyline { points, width } => ink.polyline(points, *width),
            Primitive::Polylines { lines, width } => {
                for l in lines {
                    ink.polyline(l, *width);
                }
            }
            Primitive::Rect { rect, width } => ink.rect(*rect, *width),
            Primitive::Polygon { points } => {
                let n = points.len();
                for k in 0..n {
                    ink.segment(points[k], points[(k + 1) % n], 0.0);
                }
            }
            Primitive::Circle {
                center,
                radius,
                width,
            } => ink.disc(*center, radius + width.map_or(0.0, |w| 0.5 * w)),
            Primitive::Text {
                pos,
                size,
                anchor,
                text,
                ..
            } => {
                let w = font::text_width(*size, text);
                let x0 = match anchor {
                    Anchor::Start => pos[0],
                    Anchor::Middle => pos[0] - 0.5 * w,
                    Anchor::End => pos[0] - w,
                };
                texts.push([
                    x0,
                    pos[1] - font::ascent(*size),
                    x0 + w,
                    pos[1] + font::descent(*size),
                ]);
            }
        }
    }
    (ink, texts)
}

/// Clear space kept between a bracket label and any ink, points.
const BRACKET_LABEL_CLEAR: f64 = 2.0;

/// Places and draws a bracket's label: beside the bracket's middle on its outer side if
/// that is clear of all ink (by [`BRACKET_LABEL_CLEAR`]) and of other text, else the
/// nearest clear place out from or along the bracket, with a hairline leader back to the
/// bracket. Returns the label's box; its leader joins `ink`.
fn bracket_label(
    dl: &mut DisplayList,
    b: &Bracket,
    text: String,
    ink: &mut InkSegments,
    taken: &[[f64; 4]],
    frame: [f64; 4],
) -> [f64; 4] {
    let size = style::LABEL_SIZE;
    let tw = font::text_width(size, &text);
    let (asc, desc) = (font::ascent(size), font::descent(size));
    // The box whose side towards the bracket (which lies towards −n) touches `at`.
    let place = |at: PagePoint, n: PagePoint| {
        let x0 = if n[0] > 0.35 {
            at[0]
        } else if n[0] < -0.35 {
            at[0] - tw
        } else {
            at[0] - 0.5 * tw
        };
        let y0 = if n[1] > 0.0 {
            at[1]
        } else {
            at[1] - asc - desc
        };
        [x0, y0, x0 + tw, y0 + asc + desc]
    };
    // The leader from the bracket line (its point nearest the box's centre) to the box,
    // stopping short of it; none when the box is beside the bracket.
    let leader = |r: [f64; 4]| -> Option<(PagePoint, PagePoint)> {
        let c = [0.5 * (r[0] + r[2]), 0.5 * (r[1] + r[3])];
        let [e0, e1] = b.ends;
        let (dx, dy) = (e1[0] - e0[0], e1[1] - e0[1]);
        let l2 = (dx * dx + dy * dy).max(1e-12);
        let s = (((c[0] - e0[0]) * dx + (c[1] - e0[1]) * dy) / l2).clamp(0.0, 1.0);
        let from = [e0[0] + s * dx, e0[1] + s * dy];
        let near = [from[0].clamp(r[0], r[2]), from[1].clamp(r[1], r[3])];
        let d = libm::hypot(near[0] - from[0], near[1] - from[1]);
        (d > 10.0).then(|| {
            let k = (d - 1.5 - BRACKET_LABEL_CLEAR) / d;
            (
                from,
                [
                    from[0] + k * (near[0] - from[0]),
                    from[1] + k * (near[1] - from[1]),
                ],
            )
        })
    };
    let inner = crate::page::inset_rect(frame, 3.0);
    // Out from the bracket, along it, and (at a cost) across the curve on the other
    // side: nearest first.
    let mut candidates = Vec::new();
    for (side, cost) in [(1.0, 0.0), (-1.0, 40.0)] {
        let n = [side * b.n[0], side * b.n[1]];
        for d in [
            6.0, 10.0, 15.0, 21.0, 28.0, 36.0, 46.0, 58.0, 72.0, 90.0, 110.0, 135.0, 165.0,
        ] {
            if side < 0.0 && d < 21.0 {
                continue; // the curve and the inner brackets are there
            }
            for s in [0.0, -0.25, 0.25, -0.5, 0.5, -0.75, 0.75, -1.0, 1.0] {
                let along = s * b.len;
                let at = [
                    b.mid[0] + n[0] * d + b.u[0] * along,
                    b.mid[1] + n[1] * d + b.u[1] * along,
                ];
                candidates.push((cost + d + 0.5 * along.abs(), place(at, n)));
            }
        }
    }
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0));
    let free = |r: [f64; 4]| {
        r[0] >= inner[0]
            && r[1] >= inner[1]
            && r[2] <= inner[2]
            && r[3] <= inner[3]
            && !taken
                .iter()
                .any(|q| rects_overlap(*q, crate::labels::grow(r, 1.0)))
            && leader(r).is_none_or(|(p, q)| {
                !taken
                    .iter()
                    .any(|t| crate::labels::rect_segment_distance(*t, p, q) < 1.0)
            })
    };
    let r = candidates
        .iter()
        .find(|(_, r)| free(*r) && ink.gap(*r, BRACKET_LABEL_CLEAR) >= BRACKET_LABEL_CLEAR)
        .or_else(|| {
            // Nowhere clear: the free place with the most room.
            candidates
                .iter()
                .filter(|(_, r)| free(*r))
                .max_by(|x, y| ink.gap(x.1, 20.0).total_cmp(&ink.gap(y.1, 20.0)))
        })
        .map_or_else(|| place(b.mid, b.n), |c| c.1);
    if let Some((p, q)) = leader(r) {
        dl.line(vec![p, q], style::THIN);
        ink.segment(p, q, style::THIN);
    }
    dl.text_halo([r[0], r[1] + asc], size, Anchor::Start, text, 1.2);
    r
}

/// Legend and footer of a classic page.
fn legend(dl: &mut DisplayList, geometry: &ClassicGeometry, setup: &PageSetup, rocks: bool) {
    let m = setup.margin_pt;
    let ts = style::SMALL_SIZE;
    let y = crate::page::dash_legend(
        dl,
        setup,
        "one dash = {step}° of input ({drawn}° drawn), counted from the start of a branch (θ = 0 for a crank, the lower toggle for a rocking input: the dot); bold: its first dash, heavier: every 90°",
    );
    let y2 = y + 14.0;
    let (deg, circuit) = geometry.drawn;
    let drawn = format!(
        "linkage (gray) at θ = {}° ({} circuit), mid-way along the 0.1 % run; brackets: the longest runs at εₛ ≤ 1 %, 0.1 %, 0.01 %",
        fmt_sig(deg),
        circuit.name()
    );
    let text = if rocks {
        let r = 2.6;
        dl.rect(
            [m + 8.0 - r, y2 - r, m + 8.0 + r, y2 + r],
            style::THIN + 0.2,
        );
        format!("toggle: the input stops and reverses, the linkage changes circuit;  {drawn}")
    } else {
        drawn
    };
    dl.text([m + 3.0 * 12.0 + 4.0, y2 + 2.5], ts, Anchor::Start, text);
    crate::page::scale_bar(
        dl,
        m,
        y2 + 14.0,
        geometry.transform.scale,
        "input link 1 = {} in on this page",
    );

    crate::page::footer(
        dl,
        setup,
        footer_settings(setup).replacen("of crank", "of input", 1),
    );
}
