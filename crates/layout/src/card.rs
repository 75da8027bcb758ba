//! The dwell design card (`dwell --card FILE`): one landscape page (11 × 8.5 in) with the
//! six-bar drawn at θ = 0 (every link and pivot labelled), the coupler curve with its
//! dwell windows marked and the direction of travel from θ = 0, a chart of the output
//! angle ψ(θ) with labelled axes (dwell windows hatched, felt dwells bold), and the
//! design's figures in a box — the same lines `dwell` prints. A display list in page
//! points like every page, so PNG, SVG and PDF come out of the same renderers.
//!
//! Also the straight-line family chart (`straight --chart FILE`): straight span and ε_V
//! of the Evans linkages against the frame ratio.

use crate::font;
use crate::page::{Anchor, DisplayList, PagePoint, Primitive};
use coupler_design::{DwellDesign, Export, FamilyPoint, Stage};

/// Card width, points (11 in).
pub const CARD_WIDTH_PT: f64 = 792.0;
/// Card height, points (8.5 in).
pub const CARD_HEIGHT_PT: f64 = 612.0;

const TITLE: f64 = 13.0;
const TEXT: f64 = 8.0;
const SMALL: f64 = 6.6;
const LINK: f64 = 1.8;
const THIN: f64 = 0.5;
const PIN: f64 = 2.6;

fn line(dl: &mut DisplayList, points: Vec<PagePoint>, width: f64) {
    dl.items.push(Primitive::Polyline { points, width });
}

fn text(dl: &mut DisplayList, pos: PagePoint, size: f64, anchor: Anchor, s: impl Into<String>) {
    dl.items.push(Primitive::Text {
        pos,
        size,
        anchor,
        text: s.into(),
        halo: 0.0,
    });
}

fn circle(dl: &mut DisplayList, center: PagePoint, radius: f64, width: Option<f64>) {
    dl.items.push(Primitive::Circle {
        center,
        radius,
        width,
    });
}

fn rect(dl: &mut DisplayList, r: [f64; 4], width: f64) {
    dl.items.push(Primitive::Rect { rect: r, width });
}

/// A dashed polyline: dashes of `on` points with gaps of `off`, measured along it.
fn dashed(dl: &mut DisplayList, pts: &[PagePoint], width: f64, on: f64, off: f64) {
    let mut lines: Vec<Vec<PagePoint>> = Vec::new();
    let mut cur: Vec<PagePoint> = Vec::new();
    let mut s = 0.0; // position within the on+off period
    for w in pts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let mut t = 0.0;
        while t < len {
            let on_now = s < on;
            let left = if on_now { on - s } else { on + off - s };
            let step = left.min(len - t);
            let p0 = [
                a[0] + (b[0] - a[0]) * t / len,
                a[1] + (b[1] - a[1]) * t / len,
            ];
            let t1 = t + step;
            let p1 = [
                a[0] + (b[0] - a[0]) * t1 / len,
                a[1] + (b[1] - a[1]) * t1 / len,
            ];
            if on_now {
                if cur.is_empty() {
                    cur.push(p0);
                }
                cur.push(p1);
            } else if !cur.is_empty() {
                lines.push(std::mem::take(&mut cur));
            }
            s += step;
            if s >= on + off - 1e-12 {
                s = 0.0;
            }
            if s >= on && !cur.is_empty() {
                lines.push(std::mem::take(&mut cur));
            }
            t = t1;
        }
    }
    if cur.len() > 1 {
        lines.push(cur);
    }
    if !lines.is_empty() {
        dl.items.push(Primitive::Polylines { lines, width });
    }
}

/// Diagonal hatching of a rectangle, lines `gap` apart.
fn hatch(dl: &mut DisplayList, r: [f64; 4], gap: f64, width: f64) {
    let [x0, y0, x1, y1] = r;
    if x1 <= x0 || y1 <= y0 {
        return;
    }
    let mut lines = Vec::new();
    // Lines x − y = c, clipped to the rectangle.
    let mut c = x0 - y1;
    while c <= x1 - y0 {
        let mut pts = Vec::new();
        // Intersections with the four edges.
        for (x, y) in [(c + y0, y0), (c + y1, y1), (x0, x0 - c), (x1, x1 - c)] {
            if x >= x0 - 1e-9 && x <= x1 + 1e-9 && y >= y0 - 1e-9 && y <= y1 + 1e-9 {
                pts.push([x, y]);
            }
        }
        pts.sort_by(|a, b| a[0].total_cmp(&b[0]));
        pts.dedup_by(|a, b| (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9);
        if pts.len() >= 2 {
            lines.push(vec![pts[0], pts[pts.len() - 1]]);
        }
        c += gap;
    }
    if !lines.is_empty() {
        dl.items.push(Primitive::Polylines { lines, width });
    }
}

/// Splits `s` into lines no wider than `width` at em size `size`, breaking at spaces.
pub fn wrap(s: &str, size: f64, width: f64) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for word in s.split(' ') {
        let trial = if cur.is_empty() {
            word.to_string()
        } else {
            format!("{cur} {word}")
        };
        if font::text_width(size, &trial) > width && !cur.is_empty() {
            out.push(std::mem::take(&mut cur));
            cur = format!("    {word}");
        } else {
            cur = trial;
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

/// Round tick spacing for a range: 1, 2 or 5 × 10^k, about `n` ticks.
fn nice_step(span: f64, n: f64) -> f64 {
    let raw = (span / n).max(1e-12);
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let k = if f <= 1.0 {
        1.0
    } else if f <= 2.0 {
        2.0
    } else if f <= 5.0 {
        5.0
    } else {
        10.0
    };
    k * mag
}

fn fmt_tick(x: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    let s = format!("{x:.decimals$}");
    if s == "-0" { "0".into() } else { s }
}

/// A chart frame: maps data (x, y) into `area` with ticks and labels on the left and
/// bottom edges.
struct Chart {
    area: [f64; 4],
    x: [f64; 2],
    y: [f64; 2],
}

impl Chart {
    fn map(&self, x: f64, y: f64) -> PagePoint {
        let [a0, b0, a1, b1] = self.area;
        [
            a0 + (x - self.x[0]) / (self.x[1] - self.x[0]) * (a1 - a0),
            b1 - (y - self.y[0]) / (self.y[1] - self.y[0]) * (b1 - b0),
        ]
    }

    /// Frame, ticks, tick labels, axis titles.
    fn axes(
        &self,
        dl: &mut DisplayList,
        (x_step, y_step): (f64, f64),
        (x_title, y_title): (&str, &str),
        y_label: &dyn Fn(f64) -> String,
    ) {
        let [a0, b0, a1, b1] = self.area;
        rect(dl, self.area, 0.6);
        let mut k = (self.x[0] / x_step).ceil() as i64;
        while (k as f64) * x_step <= self.x[1] + 1e-9 {
            let x = k as f64 * x_step;
            let p = self.map(x, self.y[0]);
            line(dl, vec![[p[0], b1], [p[0], b1 - 3.0]], 0.5);
            line(dl, vec![[p[0], b0], [p[0], b0 + 3.0]], 0.5);
            text(
                dl,
                [p[0], b1 + 9.0],
                SMALL,
                Anchor::Middle,
                fmt_tick(x, x_step),
            );
            k += 1;
        }
        let mut k = (self.y[0] / y_step).ceil() as i64;
        while (k as f64) * y_step <= self.y[1] + 1e-9 {
            let y = k as f64 * y_step;
            let p = self.map(self.x[0], y);
            line(dl, vec![[a0, p[1]], [a0 + 3.0, p[1]]], 0.5);
            line(dl, vec![[a1, p[1]], [a1 - 3.0, p[1]]], 0.5);
            text(dl, [a0 - 3.0, p[1] + 2.3], SMALL, Anchor::End, y_label(y));
            k += 1;
        }
        text(dl, [a0, b1 + 19.0], TEXT, Anchor::Start, x_title);
        text(dl, [a0, b0 - 5.0], TEXT, Anchor::Start, y_title);
    }

    /// Clips a polyline to the area (drops points outside; curves here stay inside).
    fn polyline(&self, dl: &mut DisplayList, pts: &[(f64, f64)], width: f64) {
        let v: Vec<PagePoint> = pts.iter().map(|&(x, y)| self.map(x, y)).collect();
        line(dl, v, width);
    }
}

/// World (curve units, y up) to page.
struct World {
    scale: f64,
    origin: PagePoint,
}

impl World {
    fn fit(points: &[[f64; 2]], area: [f64; 4]) -> World {
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for p in points {
            x0 = x0.min(p[0]);
            x1 = x1.max(p[0]);
            y0 = y0.min(p[1]);
            y1 = y1.max(p[1]);
        }
        let [a0, b0, a1, b1] = area;
        let scale = ((a1 - a0) / (x1 - x0).max(1e-9)).min((b1 - b0) / (y1 - y0).max(1e-9));
        let cx = 0.5 * (x0 + x1);
        let cy = 0.5 * (y0 + y1);
        World {
            scale,
            origin: [0.5 * (a0 + a1) - scale * cx, 0.5 * (b0 + b1) + scale * cy],
        }
    }

    fn map(&self, p: [f64; 2]) -> PagePoint {
        [
            self.origin[0] + self.scale * p[0],
            self.origin[1] - self.scale * p[1],
        ]
    }
}

/// A ground pivot's symbol: a triangle under the pin and a hatched base.
fn ground(dl: &mut DisplayList, p: PagePoint) {
    let r = PIN;
    let (h, w) = (8.0, 6.0);
    line(
        dl,
        vec![
            [p[0], p[1] + r],
            [p[0] - w, p[1] + h],
            [p[0] + w, p[1] + h],
            [p[0], p[1] + r],
        ],
        0.7,
    );
    line(
        dl,
        vec![[p[0] - w - 2.0, p[1] + h], [p[0] + w + 2.0, p[1] + h]],
        0.7,
    );
    let mut lines = Vec::new();
    let mut x = p[0] - w - 2.0;
    while x < p[0] + w + 2.0 {
        lines.push(vec![[x + 2.5, p[1] + h], [x, p[1] + h + 3.0]]);
        x += 2.5;
    }
    dl.items.push(Primitive::Polylines { lines, width: 0.5 });
}

/// A link between two pins, stopping at the pin circles.
fn link(dl: &mut DisplayList, a: PagePoint, b: PagePoint, width: f64) {
    let len = (b[0] - a[0]).hypot(b[1] - a[1]);
    if len > 2.0 * PIN {
        let u = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
        line(
            dl,
            vec![
                [a[0] + u[0] * PIN, a[1] + u[1] * PIN],
                [b[0] - u[0] * PIN, b[1] - u[1] * PIN],
            ],
            width,
        );
    }
}

/// Places labels avoiding each other and the given boxes: tries eight spots round `p`.
struct Labels {
    taken: Vec<[f64; 4]>,
    area: [f64; 4],
}

impl Labels {
    fn place(&mut self, dl: &mut DisplayList, p: PagePoint, s: &str, size: f64, gap: f64) {
        let w = font::text_width(size, s);
        let (asc, desc) = (font::ascent(size), font::descent(size));
        let spots = [
            (1.0, -1.0),
            (1.0, 1.0),
            (-1.0, -1.0),
            (-1.0, 1.0),
            (0.0, -1.0),
            (0.0, 1.0),
            (1.0, 0.0),
            (-1.0, 0.0),
        ];
        let mut best = None;
        let tries = spots
            .iter()
            .map(|s| (s, gap))
            .chain(spots.iter().map(|s| (s, gap + 7.0)))
            .chain(spots.iter().map(|s| (s, gap + 16.0)));
        for (k, ((sx, sy), gap)) in tries.enumerate() {
            let x = match *sx as i32 {
                1 => p[0] + gap,
                -1 => p[0] - gap - w,
                _ => p[0] - 0.5 * w,
            };
            let y = match *sy as i32 {
                -1 => p[1] - gap - desc,
                1 => p[1] + gap + asc,
                _ => p[1] + 0.5 * (asc - desc),
            };
            let b = [x - 0.5, y - asc - 0.5, x + w + 0.5, y + desc + 0.5];
            let inside = b[0] >= self.area[0]
                && b[2] <= self.area[2]
                && b[1] >= self.area[1]
                && b[3] <= self.area[3];
            let free = !self.taken.iter().any(|t| overlap(*t, b));
            if inside && free {
                best = Some((x, y, b));
                break;
            }
            if k == 0 {
                best = Some((x, y, b));
            }
        }
        if let Some((x, y, b)) = best {
            self.taken.push(b);
            text(dl, [x, y], size, Anchor::Start, s);
        }
    }
}

impl Labels {
    /// Marks a polyline's ink as taken (small boxes along it).
    fn block(&mut self, pts: &[PagePoint], half: f64) {
        for w in pts.windows(2) {
            let (a, b) = (w[0], w[1]);
            let len = (b[0] - a[0]).hypot(b[1] - a[1]);
            let n = (len / 4.0).ceil().max(1.0) as usize;
            for k in 0..=n {
                let t = k as f64 / n as f64;
                let p = [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
                self.taken
                    .push([p[0] - half, p[1] - half, p[0] + half, p[1] + half]);
            }
        }
    }
}

fn overlap(a: [f64; 4], b: [f64; 4]) -> bool {
    a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]
}

/// The design card of a dwell design; `e` is its export at scale 1 (curve units).
pub fn dwell_card(d: &DwellDesign, e: &Export) -> DisplayList {
    let mut dl = DisplayList::new(CARD_WIDTH_PT, CARD_HEIGHT_PT);
    let m = 28.0;
    // Title.
    let dr = &d.driver;
    let title = format!(
        "{}: A = {}, B = {}, C = {} ({}), M = ({}, {}){}",
        match d.kind {
            coupler_design::DwellKind::Single => "Single-dwell six-bar",
            coupler_design::DwellKind::DoubleArcs => "Double-dwell six-bar (two arcs)",
            coupler_design::DwellKind::DoubleLines => "Double-dwell six-bar (two lines, slot)",
        },
        dr.curve_linkage.coupler,
        dr.curve_linkage.rocker,
        dr.curve_linkage.ground,
        dr.curve_circuit.name(),
        dr.curve_point.u,
        dr.curve_point.v,
        if dr.cognate > 0 {
            format!(", driven by cognate {}", dr.cognate)
        } else {
            String::new()
        }
    );
    text(&mut dl, [m, m + 6.0], TITLE, Anchor::Start, title);
    text(
        &mut dl,
        [m, m + 20.0],
        TEXT,
        Anchor::Start,
        format!(
            "{}; crank = 1, turning counter-clockwise; drawn at θ = 0",
            d.method.describe()
        ),
    );

    // Mechanism panel.
    let panel = [m, m + 34.0, 430.0, CARD_HEIGHT_PT - m];
    rect(&mut dl, panel, 0.6);
    let inner = [
        panel[0] + 22.0,
        panel[1] + 22.0,
        panel[2] - 22.0,
        panel[3] - 34.0,
    ];
    let find = |name: &str| -> [f64; 2] {
        e.pivots
            .iter()
            .chain(&e.joints)
            .find(|j| j.name == name)
            .map(|j| [j.x, j.y])
            .unwrap_or([0.0, 0.0])
    };
    let mut world_pts: Vec<[f64; 2]> = e.curve.clone();
    world_pts.extend(e.pivots.iter().chain(&e.joints).map(|j| [j.x, j.y]));
    world_pts.extend(d.dwells.iter().map(|x| x.point));
    let o6 = d.stage.pivot();
    // Link 6's path (rocker) or the slot's reach.
    let [psi0, psi1] = d.output_range_deg;
    let reach = match d.stage {
        Stage::Rocker { link6, .. } => link6,
        Stage::Slot { .. } => d.farthest_reach.value,
    };
    let arc: Vec<[f64; 2]> = (0..=60)
        .map(|k| {
            let a = (psi0 + (psi1 - psi0) * k as f64 / 60.0).to_radians();
            [o6[0] + reach * libm::cos(a), o6[1] + reach * libm::sin(a)]
        })
        .collect();
    world_pts.extend(arc.iter().copied());
    let w = World::fit(&world_pts, inner);
    let mut labels = Labels {
        taken: Vec::new(),
        area: panel,
    };
    // The coupler curve, thin; the dwell windows bold.
    let curve: Vec<PagePoint> = e.curve.iter().map(|&p| w.map(p)).collect();
    line(&mut dl, curve.clone(), THIN);
    labels.block(&curve, 1.2);
    let mut dwell_labels: Vec<(PagePoint, String)> = Vec::new();
    let n = e.curve.len() - 1;
    let step = 360.0 / n as f64;
    for (k, x) in d.dwells.iter().enumerate() {
        let first = (x.start_deg / step).ceil() as usize;
        let last = ((x.start_deg + x.span_deg) / step + 1e-9).floor() as usize;
        let pts: Vec<PagePoint> = (first..=last).map(|i| curve[i % n]).collect();
        line(&mut dl, pts.clone(), 2.4);
        let mid = pts[pts.len() / 2];
        labels.block(&pts, 2.0);
        dwell_labels.push((
            mid,
            format!(
                "dwell {} (θ {}°–{}°)",
                k + 1,
                coupler_design::fmt_deg(x.start_deg),
                coupler_design::fmt_deg(x.start_deg + x.span_deg)
            ),
        ));
        // The dwell point, and (rocker) link 5's circle about it along the window.
        let dp = w.map(x.point);
        line(
            &mut dl,
            vec![[dp[0] - 3.0, dp[1] - 3.0], [dp[0] + 3.0, dp[1] + 3.0]],
            0.7,
        );
        line(
            &mut dl,
            vec![[dp[0] - 3.0, dp[1] + 3.0], [dp[0] + 3.0, dp[1] - 3.0]],
            0.7,
        );
        if let Stage::Rocker { link5, .. } = d.stage {
            let a0 = (first..=last)
                .map(|i| {
                    let q = e.curve[i % n];
                    libm::atan2(q[1] - x.point[1], q[0] - x.point[0])
                })
                .collect::<Vec<f64>>();
            let mut lo = a0[0];
            let mut prev = a0[0];
            let mut un = vec![a0[0]];
            for &a in &a0[1..] {
                let mut b = a;
                while b - prev > std::f64::consts::PI {
                    b -= 2.0 * std::f64::consts::PI;
                }
                while prev - b > std::f64::consts::PI {
                    b += 2.0 * std::f64::consts::PI;
                }
                un.push(b);
                prev = b;
                lo = lo.min(b);
            }
            let hi = un.iter().copied().fold(f64::MIN, f64::max);
            let pad = 0.15 * (hi - lo) + 0.05;
            let circ: Vec<PagePoint> = (0..=80)
                .map(|i| {
                    let a = lo - pad + (hi - lo + 2.0 * pad) * i as f64 / 80.0;
                    w.map([
                        x.point[0] + link5 * libm::cos(a),
                        x.point[1] + link5 * libm::sin(a),
                    ])
                })
                .collect();
            dashed(&mut dl, &circ, 0.5, 2.0, 2.0);
        }
    }
    // θ = 0: a dot at M and an arrow along the direction of travel.
    let m0 = curve[0];
    circle(&mut dl, m0, 2.2, None);
    if let Some(&m1) = curve.get(3) {
        let dir = [m1[0] - m0[0], m1[1] - m0[1]];
        let len = dir[0].hypot(dir[1]);
        if len > 0.0 {
            let u = [dir[0] / len, dir[1] / len];
            let tip = [m0[0] + u[0] * 16.0, m0[1] + u[1] * 16.0];
            line(&mut dl, vec![m0, tip], 0.9);
            let base = [tip[0] - u[0] * 6.0, tip[1] - u[1] * 6.0];
            let nn = [-u[1] * 2.6, u[0] * 2.6];
            dl.items.push(Primitive::Polygon {
                points: vec![
                    tip,
                    [base[0] + nn[0], base[1] + nn[1]],
                    [base[0] - nn[0], base[1] - nn[1]],
                ],
            });
        }
    }
    // Link 6's path, dashed.
    let arc_p: Vec<PagePoint> = arc.iter().map(|&p| w.map(p)).collect();
    dashed(&mut dl, &arc_p, 0.5, 4.0, 2.5);

    // The six-bar at θ = 0.
    let (po2, po4, a, b, mm) = (
        w.map(find("O2")),
        w.map(find("O4")),
        w.map(find("A")),
        w.map(find("B")),
        w.map(find("M")),
    );
    let po6 = w.map(o6);
    link(&mut dl, po2, a, LINK);
    link(&mut dl, a, b, LINK);
    link(&mut dl, a, mm, LINK);
    link(&mut dl, b, mm, LINK);
    link(&mut dl, po4, b, LINK);
    let mut pins = vec![
        (po2, "O2", true),
        (po4, "O4", true),
        (po6, "O6", true),
        (a, "A", false),
        (b, "B", false),
        (mm, "M", false),
    ];
    // Coupler triangle lightly hatched so it reads as one link.
    dl.items.push(Primitive::Polylines {
        lines: vec![vec![a, b, mm, a]],
        width: 0.4,
    });
    let mut link_labels: Vec<(PagePoint, PagePoint, &str)> =
        vec![(po2, a, "2"), (a, b, "3"), (po4, b, "4")];
    match d.stage {
        Stage::Rocker { .. } => {
            let pd = w.map(find("D"));
            link(&mut dl, mm, pd, LINK);
            link(&mut dl, po6, pd, LINK + 0.8);
            pins.push((pd, "D", false));
            link_labels.push((mm, pd, "5"));
            link_labels.push((po6, pd, "6"));
        }
        Stage::Slot { .. } => {
            // The slotted link from O6 past M to the block's farthest reach: two rails.
            let dir = [mm[0] - po6[0], mm[1] - po6[1]];
            let len = dir[0].hypot(dir[1]).max(1e-9);
            let u = [dir[0] / len, dir[1] / len];
            let far = reach * w.scale * 1.08;
            let nrm = [-u[1] * 3.2, u[0] * 3.2];
            for s in [1.0, -1.0] {
                line(
                    &mut dl,
                    vec![
                        [
                            po6[0] + u[0] * PIN * 1.6 + s * nrm[0],
                            po6[1] + u[1] * PIN * 1.6 + s * nrm[1],
                        ],
                        [
                            po6[0] + u[0] * far + s * nrm[0],
                            po6[1] + u[1] * far + s * nrm[1],
                        ],
                    ],
                    1.2,
                );
            }
            // The block at M, square along the slot.
            let (bx, by) = ([u[0] * 5.0, u[1] * 5.0], [nrm[0] * 1.3, nrm[1] * 1.3]);
            line(
                &mut dl,
                vec![
                    [mm[0] + bx[0] + by[0], mm[1] + bx[1] + by[1]],
                    [mm[0] - bx[0] + by[0], mm[1] - bx[1] + by[1]],
                    [mm[0] - bx[0] - by[0], mm[1] - bx[1] - by[1]],
                    [mm[0] + bx[0] - by[0], mm[1] + bx[1] - by[1]],
                    [mm[0] + bx[0] + by[0], mm[1] + bx[1] + by[1]],
                ],
                1.0,
            );
            link_labels.push((mm, [mm[0] + u[0] * 12.0, mm[1] + u[1] * 12.0], "5 (block)"));
            link_labels.push((po6, [po6[0] + u[0] * far, po6[1] + u[1] * far], "6 (slot)"));
        }
    }
    for (p, q, _) in &link_labels {
        labels.block(&[*p, *q], 2.0);
    }
    for (p, _, is_ground) in &pins {
        circle(&mut dl, *p, PIN, Some(0.9));
        labels.block(&[*p, *p], PIN + 1.0);
        if *is_ground {
            ground(&mut dl, *p);
            labels
                .taken
                .push([p[0] - 9.0, p[1] + PIN, p[0] + 9.0, p[1] + 12.0]);
        }
    }
    // Scale bar: the crank's length.
    let bar = w.scale * e.crank_length / e.scale;
    let y = panel[3] - 12.0;
    line(
        &mut dl,
        vec![[panel[0] + 10.0, y], [panel[0] + 10.0 + bar, y]],
        1.0,
    );
    for x in [panel[0] + 10.0, panel[0] + 10.0 + bar] {
        line(&mut dl, vec![[x, y - 3.0], [x, y + 3.0]], 1.0);
    }
    // The legend beside the bar, wrapped inside the panel (bottom line level with the bar).
    let legend = match d.stage {
        Stage::Rocker { .. } => {
            "crank = 1;  bold: dwell windows;  ×: dwell points;  dashed: link 5's circle at the dwell, D's path;  dot and arrow: M at θ = 0, moving"
        }
        Stage::Slot { .. } => {
            "crank = 1;  bold: dwell windows (straight segments);  dashed: the slot's reach as it swings;  dot and arrow: M at θ = 0, moving"
        }
    };
    let x0 = panel[0] + 16.0 + bar;
    let legend = wrap(legend, SMALL, panel[2] - 6.0 - x0);
    let lead = SMALL * 1.3;
    let top = y + 2.5 - lead * (legend.len() - 1) as f64;
    labels
        .taken
        .push([panel[0], top - SMALL - 2.0, panel[2], panel[3]]);
    for (k, s) in legend.into_iter().enumerate() {
        text(
            &mut dl,
            [x0, top + lead * k as f64],
            SMALL,
            Anchor::Start,
            s,
        );
    }

    for (p, s, _) in &pins {
        labels.place(&mut dl, *p, s, TEXT, 3.5);
    }
    for (p, q, s) in link_labels {
        let mid = [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])];
        labels.place(&mut dl, mid, s, TEXT, 2.5);
    }
    for (p, s) in dwell_labels {
        labels.place(&mut dl, p, &s, SMALL, 4.0);
    }
    // The chart of ψ(θ).
    let chart_area = [478.0, m + 50.0, CARD_WIDTH_PT - m - 6.0, 262.0];
    let pad = 0.06 * (psi1 - psi0).max(1e-6);
    let y_step = nice_step(psi1 - psi0 + 2.0 * pad, 6.0);
    let chart = Chart {
        area: chart_area,
        x: [0.0, 360.0],
        y: [
            ((psi0 - pad) / y_step).floor() * y_step,
            ((psi1 + pad) / y_step).ceil() * y_step,
        ],
    };
    for x in &d.dwells {
        let s = x.start_deg;
        let e = s + x.span_deg;
        for (a0, a1) in [(s, e.min(360.0)), (0.0, e - 360.0)] {
            if a1 > a0 {
                let p0 = chart.map(a0, chart.y[1]);
                let p1 = chart.map(a1, chart.y[0]);
                hatch(&mut dl, [p0[0], p0[1], p1[0], p1[1]], 4.0, 0.3);
            }
        }
        // Felt dwell: a bold bar at its position.
        let f = &x.felt;
        if f.span_deg > 0.0 && f.position_deg.is_finite() {
            let y = f.position_deg;
            let (fs, fe) = (f.start_deg, f.start_deg + f.span_deg);
            for (a0, a1) in [(fs, fe.min(360.0)), (0.0, fe - 360.0)] {
                if a1 > a0 {
                    // Shift ψ by whole turns into the chart (an unwrapped ψ may sit a turn off).
                    let yy = y - 360.0 * ((y - psi0) / 360.0).floor();
                    chart.polyline(&mut dl, &[(a0, yy), (a1, yy)], 3.2);
                }
            }
        }
    }
    let pts: Vec<(f64, f64)> = d
        .theta_deg
        .iter()
        .copied()
        .zip(d.output_deg.iter().copied())
        .collect();
    chart.polyline(&mut dl, &pts, 1.1);
    chart.axes(
        &mut dl,
        (60.0, y_step),
        (
            "crank angle θ (degrees; θ = 0 as drawn)",
            "output angle ψ of link 6 (degrees)",
        ),
        &|y| fmt_tick(y, y_step),
    );
    text(
        &mut dl,
        [chart_area[2], chart_area[3] + 30.0],
        SMALL,
        Anchor::End,
        format!(
            "hatched: dwell windows; bold: felt dwell (ψ within ±{}°)",
            d.limits.dwell_tol_deg
        ),
    );

    // The figures.
    let boxr = [452.0, 300.0, CARD_WIDTH_PT - m, CARD_HEIGHT_PT - m];
    rect(&mut dl, boxr, 0.6);
    let inner_w = boxr[2] - boxr[0] - 12.0;
    let mut y = boxr[1] + 11.0;
    let size = 6.2;
    let lines = d.report_lines(None);
    'out: for l in lines.iter().skip(1) {
        for piece in wrap(l, size, inner_w) {
            if y > boxr[3] - 4.0 {
                text(&mut dl, [boxr[0] + 6.0, y], size, Anchor::Start, "…");
                break 'out;
            }
            text(&mut dl, [boxr[0] + 6.0, y], size, Anchor::Start, piece);
            y += size * 1.28;
        }
    }
    dl
}

/// The straight-line family chart: for each tolerance (1 %, 0.1 %, 0.01 %), the straight
/// span (crank degrees) and ε_V over it (percent) of the Evans linkage designed for each
/// frame ratio.
pub fn straight_family_chart(points: &[FamilyPoint]) -> DisplayList {
    let mut dl = DisplayList::new(CARD_WIDTH_PT, CARD_HEIGHT_PT);
    let m = 28.0;
    text(
        &mut dl,
        [m, m + 6.0],
        TITLE,
        Anchor::Start,
        "Evans straight-line linkages: straight span and velocity variation against the frame ratio",
    );
    text(
        &mut dl,
        [m, m + 20.0],
        TEXT,
        Anchor::Start,
        "crank 1, frame p, coupler = rocker = a = ½(p + 1)^(3/2) (zero curvature at the symmetric point), point (2a, 0); windows centred on θ = 180°",
    );
    if points.is_empty() {
        return dl;
    }
    let (p0, p1) = (
        points.first().map_or(1.0, |p| p.frame),
        points.last().map_or(2.0, |p| p.frame),
    );
    let tols = coupler_design::SPAN_TOLERANCES_PCT;
    let series = |f: &dyn Fn(&coupler_design::StraightSpan) -> f64| -> Vec<Vec<(f64, f64)>> {
        (0..tols.len())
            .map(|k| {
                points
                    .iter()
                    .filter_map(|p| {
                        p.spans
                            .get(k)
                            .and_then(|s| s.as_ref())
                            .map(|s| (p.frame, f(s)))
                    })
                    .collect()
            })
            .collect()
    };
    let spans = series(&|s| s.crank_span_deg);
    let ev = series(&|s| s.velocity_variation_pct);
    let panels = [
        (
            [70.0, 80.0, 760.0, 300.0],
            spans,
            "straight span (crank degrees) within ε_S",
            false,
        ),
        (
            [70.0, 350.0, 760.0, 560.0],
            ev,
            "ε_V over that span (percent, log scale)",
            true,
        ),
    ];
    for (area, data, title, log) in panels {
        let ys: Vec<f64> = data
            .iter()
            .flatten()
            .map(|&(_, y)| if log { y.max(1e-6).log10() } else { y })
            .collect();
        let lo = ys.iter().copied().fold(f64::MAX, f64::min);
        let hi = ys.iter().copied().fold(f64::MIN, f64::max);
        let (lo, hi) = if log {
            (lo.floor(), hi.ceil().max(lo.floor() + 1.0))
        } else {
            (0.0, hi * 1.08)
        };
        let ystep = if log { 1.0 } else { nice_step(hi - lo, 6.0) };
        let chart = Chart {
            area,
            x: [p0, p1],
            y: [lo, (hi / ystep).ceil() * ystep],
        };
        for (k, s) in data.iter().enumerate() {
            let pts: Vec<(f64, f64)> = s
                .iter()
                .map(|&(x, y)| (x, if log { y.max(1e-6).log10() } else { y }))
                .collect();
            if pts.len() < 2 {
                continue;
            }
            let v: Vec<PagePoint> = pts.iter().map(|&(x, y)| chart.map(x, y)).collect();
            match k {
                0 => line(&mut dl, v.clone(), 1.2),
                1 => dashed(&mut dl, &v, 1.2, 6.0, 3.0),
                _ => dashed(&mut dl, &v, 1.2, 1.5, 2.5),
            }
            let last = v[v.len() - 1];
            text(
                &mut dl,
                [last[0] - 2.0, last[1] - 4.0],
                SMALL,
                Anchor::End,
                format!("ε_S ≤ {} %", tols[k]),
            );
        }
        let label = |y: f64| {
            if log {
                format!("{} %", fmt_pct(10f64.powi(y.round() as i32)))
            } else {
                fmt_tick(y, ystep)
            }
        };
        chart.axes(
            &mut dl,
            (nice_step(p1 - p0, 8.0), ystep),
            ("frame ratio p (frame / crank)", title),
            &label,
        );
    }
    dl
}

fn fmt_pct(x: f64) -> String {
    let s = format!("{x:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}
