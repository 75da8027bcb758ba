//! Curve labels at their own coupler points.
//!
//! Every curve of an atlas page is labelled at its θ = 0 dot (its coupler point, where the
//! linkage is drawn). A label box may sit in any direction around its dot, a little way
//! off, but never where another curve's dot would be as near to it as its own (a reader
//! pairs a label with the nearest dot), never over another label, and preferably where it
//! covers the least ink. Labels are placed greedily, the most crowded dots first. When a
//! page is too dense for full `(u, v)` labels, every curve gets a short number instead
//! and the page carries a key (number → (u, v)).

use crate::font;
use crate::page::{Occupancy, PagePoint, rects_overlap};

/// Distance from point `p` to the rectangle `r` (0 inside).
pub fn rect_distance(r: [f64; 4], p: PagePoint) -> f64 {
    let dx = (r[0] - p[0]).max(0.0).max(p[0] - r[2]);
    let dy = (r[1] - p[1]).max(0.0).max(p[1] - r[3]);
    libm::hypot(dx, dy)
}

/// Distance from point `p` to the segment `a`–`b`.
fn point_segment_distance(p: PagePoint, a: PagePoint, b: PagePoint) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    libm::hypot(p[0] - a[0] - t * dx, p[1] - a[1] - t * dy)
}

/// Distance from the rectangle `r` to the segment `a`–`b` (0 when they meet).
pub(crate) fn rect_segment_distance(r: [f64; 4], a: PagePoint, b: PagePoint) -> f64 {
    if crate::page::clip_segment(a, b, r).is_some() || rect_distance(r, a) == 0.0 {
        return 0.0;
    }
    let corners = [[r[0], r[1]], [r[2], r[1]], [r[2], r[3]], [r[0], r[3]]];
    corners
        .iter()
        .map(|c| point_segment_distance(*c, a, b))
        .fold(rect_distance(r, a).min(rect_distance(r, b)), f64::min)
}

/// The ink of a page as stroked segments (a point is a segment of length 0; a disc is a
/// point with its radius as half width), for keeping text clear of it.
#[derive(Clone, Debug, Default)]
pub(crate) struct InkSegments {
    segs: Vec<(PagePoint, PagePoint, f64)>,
}

impl InkSegments {
    /// A stroke from `a` to `b`, `width` wide.
    pub(crate) fn segment(&mut self, a: PagePoint, b: PagePoint, width: f64) {
        self.segs.push((a, b, 0.5 * width));
    }

    /// A polyline `width` wide.
    pub(crate) fn polyline(&mut self, pts: &[PagePoint], width: f64) {
        for w in pts.windows(2) {
            self.segment(w[0], w[1], width);
        }
    }

    /// A disc (or ring) of radius `r` about `c`.
    pub(crate) fn disc(&mut self, c: PagePoint, r: f64) {
        self.segs.push((c, c, r));
    }

    /// A rectangle's outline, `width` wide.
    pub(crate) fn rect(&mut self, r: [f64; 4], width: f64) {
        let q = [[r[0], r[1]], [r[2], r[1]], [r[2], r[3]], [r[0], r[3]]];
        for k in 0..4 {
            self.segment(q[k], q[(k + 1) % 4], width);
        }
    }

    /// The gap between the rectangle `r` and the nearest ink's edge (negative: ink in
    /// it), or `limit` if nothing is nearer.
    pub(crate) fn gap(&self, r: [f64; 4], limit: f64) -> f64 {
        let mut best = limit;
        for &(a, b, hw) in &self.segs {
            // Cheap reject: the segment's box is farther than the best gap so far.
            let reach = best + hw;
            if a[0].min(b[0]) > r[2] + reach
                || a[0].max(b[0]) < r[0] - reach
                || a[1].min(b[1]) > r[3] + reach
                || a[1].max(b[1]) < r[1] - reach
            {
                continue;
            }
            best = best.min(rect_segment_distance(r, a, b) - hw);
        }
        best
    }
}

/// The rule every label keeps: its own dot is nearer to its box than any other dot, by a
/// clear margin (another dot at least `1.5·d + 2` pt away when its own is `d` pt away).
pub fn own_dot_is_nearest(r: [f64; 4], own: usize, dots: &[PagePoint]) -> bool {
    let d = rect_distance(r, dots[own]);
    dots.iter()
        .enumerate()
        .filter(|(i, _)| *i != own)
        .all(|(_, q)| rect_distance(r, *q) >= 1.5 * d + 2.0)
}

/// How the labels of a page came out.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct LabelPlacement {
    /// Each label's box (points), and the text to print in it (baseline at box top +
    /// ascent + pad).
    pub boxes: Vec<[f64; 4]>,
    /// The texts placed (full labels, or numbers when `keyed`).
    pub texts: Vec<String>,
    /// Whether the page uses numbers and a key.
    pub keyed: bool,
    /// Labels that could not keep the rule (placed at their least bad spot): none on a
    /// well-formed page.
    pub failed: usize,
}

/// Padding between a label's text and its box edge, points.
pub(crate) const LABEL_PAD: f64 = 0.8;

/// Gaps tried between a dot and the near side of its label box, points (nearest first).
const LABEL_GAPS: [f64; 9] = [1.5, 3.0, 5.0, 8.0, 12.0, 16.0, 22.0, 30.0, 40.0];

/// Directions tried around a dot (evenly spaced).
const LABEL_DIRECTIONS: usize = 24;

/// Places labels for `dots` (the θ = 0 dots, page points): `full[i]` if every label fits
/// by the rule, else `numbers[i]` for all. `taken` are boxes labels must not cover (pivot
/// names, the inset, the key), `frame` the area they must stay in, `occ` the ink.
pub(crate) fn place_labels(
    dots: &[PagePoint],
    full: &[String],
    numbers: &[String],
    size: f64,
    occ: &Occupancy,
    taken: &[[f64; 4]],
    frame: [f64; 4],
) -> LabelPlacement {
    let first = place_all(dots, full, size, occ, taken, frame);
    if first.1 == 0 {
        return LabelPlacement {
            boxes: first.0,
            texts: full.to_vec(),
            keyed: false,
            failed: 0,
        };
    }
    let second = place_all(dots, numbers, size, occ, taken, frame);
    LabelPlacement {
        boxes: second.0,
        texts: numbers.to_vec(),
        keyed: true,
        failed: second.1,
    }
}

/// Greedy placement of `texts` at `dots`, the most crowded first: (boxes, failures).
fn place_all(
    dots: &[PagePoint],
    texts: &[String],
    size: f64,
    occ: &Occupancy,
    taken: &[[f64; 4]],
    frame: [f64; 4],
) -> (Vec<[f64; 4]>, usize) {
    let n = dots.len();
    let asc = font::ascent(size);
    let desc = font::descent(size);
    // Crowdedness: distance to the nearest other dot.
    let nearest = |i: usize| {
        dots.iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, q)| libm::hypot(q[0] - dots[i][0], q[1] - dots[i][1]))
            .fold(f64::INFINITY, f64::min)
    };
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| nearest(a).total_cmp(&nearest(b)).then(a.cmp(&b)));
    let mut boxes = vec![[0.0; 4]; n];
    let mut placed: Vec<[f64; 4]> = taken.to_vec();
    let mut failed = 0;
    for i in order {
        let tw = font::text_width(size, &texts[i]);
        let (hw, hh) = (0.5 * tw + LABEL_PAD, 0.5 * (asc + desc) + LABEL_PAD);
        let p = dots[i];
        let mut best: Option<(f64, [f64; 4])> = None;
        let mut fallback: Option<(f64, [f64; 4])> = None;
        for (gi, c, r) in candidates(p, hw, hh, &LABEL_GAPS, frame) {
            // Every cost below is at least the gap's (gaps come nearest first): once a
            // box that keeps the rule costs no more than that, no later box can win.
            if best.is_some_and(|b| b.0 <= gi as f64 * 3.0) {
                break;
            }
            // Prefer little ink, then a leader over little ink, then a small gap, then
            // labels right of or above their dot (the way one reads). The leader's
            // cost is added only where the box could still win.
            let base =
                CURVE_LABEL.label(occ, r) + gi as f64 * 3.0 + if c < -0.1 { 1.0 } else { 0.0 };
            // Once a box keeps the rule, only a cheaper one matters (the fallback is
            // no longer looked at): skip the rule and clash tests for the others.
            if best.is_some_and(|b| base >= b.0) {
                continue;
            }
            let clash = placed.iter().any(|q| rects_overlap(*q, grow(r, 0.5)));
            let rule = own_dot_is_nearest(r, i, dots);
            let with_leader =
                |base: f64| base + CURVE_LABEL.leader(occ, p, r, LEADER_MIN_GAP, LEADER_START);
            if rule && !clash {
                if best.is_none_or(|b| base < b.0) {
                    let cost = with_leader(base);
                    if best.is_none_or(|b| cost < b.0) {
                        best = Some((cost, r));
                    }
                }
            } else if best.is_none() {
                let penalty = if rule { 0.0 } else { 1e6 } + if clash { 1e7 } else { 0.0 };
                if fallback.is_none_or(|b| base + penalty < b.0) {
                    let cost = with_leader(base + penalty);
                    if fallback.is_none_or(|b| cost < b.0) {
                        fallback = Some((cost, r));
                    }
                }
            }
        }
        let r = match (best, fallback) {
            (Some((_, r)), _) => r,
            (None, Some((_, r))) => {
                failed += 1;
                r
            }
            (None, None) => {
                failed += 1;
                [p[0], p[1] - 2.0 * hh, p[0] + 2.0 * hw, p[1]]
            }
        };
        boxes[i] = r;
        placed.push(r);
    }
    (boxes, failed)
}

/// Candidate boxes of half size `hw` × `hh` around `p`: for each gap (nearest first)
/// and each of [`LABEL_DIRECTIONS`] directions, the box whose near side is `gap` from `p`
/// along the direction, if it lies in `frame`: (gap index, direction's cosine, box).
fn candidates(
    p: PagePoint,
    hw: f64,
    hh: f64,
    gaps: &[f64],
    frame: [f64; 4],
) -> impl Iterator<Item = (usize, f64, [f64; 4])> + '_ {
    let dirs = directions();
    let corner = hw.hypot(hh);
    gaps.iter().enumerate().flat_map(move |(gi, &gap)| {
        dirs.iter().filter_map(move |&(s, c)| {
            // Centre so that the box's near side is `gap` from the point along (c, s).
            let t = gap + (hw * c.abs()).max(hh * s.abs()).min(corner);
            let ctr = [p[0] + c * t, p[1] + s * t];
            let r = [ctr[0] - hw, ctr[1] - hh, ctr[0] + hw, ctr[1] + hh];
            let inside =
                r[0] >= frame[0] && r[1] >= frame[1] && r[2] <= frame[2] && r[3] <= frame[3];
            inside.then_some((gi, c, r))
        })
    })
}

/// The (sine, cosine) of each of the [`LABEL_DIRECTIONS`] directions, computed once.
fn directions() -> &'static [(f64, f64); LABEL_DIRECTIONS] {
    static DIRS: std::sync::OnceLock<[(f64, f64); LABEL_DIRECTIONS]> = std::sync::OnceLock::new();
    DIRS.get_or_init(|| {
        std::array::from_fn(|k| {
            let phi = std::f64::consts::TAU * k as f64 / LABEL_DIRECTIONS as f64;
            (libm::sin(phi), libm::cos(phi))
        })
    })
}

/// Labels farther than this from their dot (points) get a leader.
pub(crate) const LEADER_MIN_GAP: f64 = 7.0;

/// Where a curve label's leader starts, points from the dot's centre.
pub(crate) const LEADER_START: f64 = 2.9;

/// How a label's costs are weighed (ink counted in occupancy marks: about 2 per cell a
/// dash crosses). Against these, each step out to the next gap costs 3.
#[derive(Clone, Copy, Debug)]
struct Weights {
    /// Per mark of ink under the label.
    ink: f64,
    /// Once, for a label touching any ink at all.
    touch: f64,
    /// Per mark of ink under its leader.
    leader_ink: f64,
    /// Once, for a leader crossing any ink at all (what a reader notices).
    leader_crossing: f64,
}

/// Curve labels: ink under the label weighs most (a halo erases what it covers); a
/// leader across a curve costs about as much as a label touching one, so that on the
/// default atlas fewer leaders cross curves (14 % of them, from 27 %) while no more
/// labels touch a dash (2.5 %).
const CURVE_LABEL: Weights = Weights {
    ink: 4.0,
    touch: 12.0,
    leader_ink: 2.0,
    leader_crossing: 10.0,
};

/// Feature labels: they are not bound to a dot, so they can go further out to find a
/// clear place; their leaders are gray hairlines.
const MARK_LABEL: Weights = Weights {
    ink: 4.0,
    touch: 24.0,
    leader_ink: 1.0,
    leader_crossing: 6.0,
};

impl Weights {
    /// Cost of the ink under a label box `r`.
    fn label(&self, occ: &Occupancy, r: [f64; 4]) -> f64 {
        let ink = occ.cost(r).unwrap_or(1_000_000) as f64;
        ink * self.ink + if ink > 0.0 { self.touch } else { 0.0 }
    }

    /// Cost of the leader from `p` to the box `r` (0 when it needs none). Never
    /// negative, so a search may skip it for a box whose other costs already lose.
    fn leader(&self, occ: &Occupancy, p: PagePoint, r: [f64; 4], gap: f64, start: f64) -> f64 {
        leader(p, r, gap, start).map_or(0.0, |(a, b)| {
            // Skip the first 1.5 pt: the cell of the point itself.
            let len = libm::hypot(b[0] - a[0], b[1] - a[1]);
            let k = (1.5 / len).min(1.0);
            let a = [a[0] + k * (b[0] - a[0]), a[1] + k * (b[1] - a[1])];
            let under = occ.segment_cost(a, b) as f64;
            under * self.leader_ink
                + if under > 0.0 {
                    self.leader_crossing
                } else {
                    0.0
                }
        })
    }
}

/// The leader a label box `r` needs back to its point `p` (from just outside `p` to the
/// box's nearest point), if it is farther than `min_gap`: (start, end).
pub(crate) fn leader(
    p: PagePoint,
    r: [f64; 4],
    min_gap: f64,
    start: f64,
) -> Option<(PagePoint, PagePoint)> {
    let near = [p[0].clamp(r[0], r[2]), p[1].clamp(r[1], r[3])];
    let gap = libm::hypot(near[0] - p[0], near[1] - p[1]);
    (gap > min_gap).then(|| {
        let u = [(near[0] - p[0]) / gap, (near[1] - p[1]) / gap];
        ([p[0] + u[0] * start, p[1] + u[1] * start], near)
    })
}

/// Gaps tried between a feature mark's middle and its label, points (nearest first).
const MARK_GAPS: [f64; 12] = [
    1.5, 3.0, 5.0, 8.0, 12.0, 16.0, 22.0, 30.0, 40.0, 55.0, 70.0, 90.0,
];

/// Feature marks' labels farther than this from their mark's middle get a leader.
pub(crate) const MARK_LEADER_MIN_GAP: f64 = 4.0;

/// Where a feature label's leader starts, points from the curve (the band's edge).
pub(crate) const MARK_LEADER_START: f64 = 2.6;

/// How far a feature label keeps from every θ = 0 dot, points.
const MARK_DOT_CLEAR: f64 = 5.0;

/// Places the labels of feature marks (a curve's straight segment or pseudo-arc) by the
/// same search as the curve labels: around each mark's middle `anchors[i]`, the box
/// covering the least ink (then with the least ink under its leader, then nearest),
/// never over a placed label (`taken`, which grows with each one placed), and at least
/// [`MARK_DOT_CLEAR`] from every θ = 0 dot so that it is not read as a curve's label. `None`
/// where no such place is in the frame.
pub(crate) fn place_marks(
    anchors: &[PagePoint],
    texts: &[String],
    size: f64,
    occ: &Occupancy,
    taken: &mut Vec<[f64; 4]>,
    dots: &[PagePoint],
    frame: [f64; 4],
) -> Vec<Option<[f64; 4]>> {
    let (asc, desc) = (font::ascent(size), font::descent(size));
    anchors
        .iter()
        .zip(texts)
        .map(|(&p, text)| {
            let (hw, hh) = (0.5 * font::text_width(size, text), 0.5 * (asc + desc));
            let mut best: Option<(f64, [f64; 4])> = None;
            for (gi, _, r) in candidates(p, hw, hh, &MARK_GAPS, frame) {
                // Every cost is at least the gap's (gaps come nearest first): once the
                // best costs no more than that, no later box can win.
                if best.is_some_and(|b| b.0 <= gi as f64 * 3.0) {
                    break;
                }
                // The text's ink reaches a little past its box: count the ink 1 pt round.
                // The cheap test first: a box that cannot win needs no clash tests.
                let g = grow(r, 1.0);
                let base = MARK_LABEL.label(occ, g) + gi as f64 * 3.0;
                if best.is_some_and(|b| base >= b.0) {
                    continue;
                }
                if taken.iter().any(|q| rects_overlap(*q, grow(r, 0.5)))
                    || dots.iter().any(|d| near_dot(r, *d))
                {
                    continue;
                }
                let cost = base
                    + MARK_LABEL.leader(occ, p, g, MARK_LEADER_MIN_GAP - 1.0, MARK_LEADER_START);
                if best.is_none_or(|b| cost < b.0) {
                    best = Some((cost, r));
                }
            }
            let r = best.map(|b| b.1);
            taken.extend(r);
            r
        })
        .collect()
}

/// Whether the box `r` is nearer than [`MARK_DOT_CLEAR`] to the dot `d`: the distance
/// is at least each of its components, so only a dot within that of the box in both
/// directions needs it measured.
fn near_dot(r: [f64; 4], d: PagePoint) -> bool {
    let dx = (r[0] - d[0]).max(0.0).max(d[0] - r[2]);
    let dy = (r[1] - d[1]).max(0.0).max(d[1] - r[3]);
    dx < MARK_DOT_CLEAR && dy < MARK_DOT_CLEAR && rect_distance(r, d) < MARK_DOT_CLEAR
}

pub(crate) fn grow(r: [f64; 4], d: f64) -> [f64; 4] {
    [r[0] - d, r[1] - d, r[2] + d, r[3] + d]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The search before the early outs (every candidate weighed): greedy placement of `texts` at `dots`, the most crowded first: (boxes, failures).
    fn place_all_reference(
        dots: &[PagePoint],
        texts: &[String],
        size: f64,
        occ: &Occupancy,
        taken: &[[f64; 4]],
        frame: [f64; 4],
    ) -> (Vec<[f64; 4]>, usize) {
        let n = dots.len();
        let asc = font::ascent(size);
        let desc = font::descent(size);
        // Crowdedness: distance to the nearest other dot.
        let nearest = |i: usize| {
            dots.iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, q)| libm::hypot(q[0] - dots[i][0], q[1] - dots[i][1]))
                .fold(f64::INFINITY, f64::min)
        };
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| nearest(a).total_cmp(&nearest(b)).then(a.cmp(&b)));
        let mut boxes = vec![[0.0; 4]; n];
        let mut placed: Vec<[f64; 4]> = taken.to_vec();
        let mut failed = 0;
        for i in order {
            let tw = font::text_width(size, &texts[i]);
            let (hw, hh) = (0.5 * tw + LABEL_PAD, 0.5 * (asc + desc) + LABEL_PAD);
            let p = dots[i];
            let mut best: Option<(f64, [f64; 4])> = None;
            let mut fallback: Option<(f64, [f64; 4])> = None;
            for (gi, c, r) in candidates(p, hw, hh, &LABEL_GAPS, frame) {
                let clash = placed.iter().any(|q| rects_overlap(*q, grow(r, 0.5)));
                // Prefer little ink, then a leader over little ink, then a small gap, then
                // labels right of or above their dot (the way one reads). The leader's
                // cost is added only where the box could still win.
                let base =
                    CURVE_LABEL.label(occ, r) + gi as f64 * 3.0 + if c < -0.1 { 1.0 } else { 0.0 };
                let rule = own_dot_is_nearest(r, i, dots);
                let with_leader =
                    |base: f64| base + CURVE_LABEL.leader(occ, p, r, LEADER_MIN_GAP, LEADER_START);
                if rule && !clash {
                    if best.is_none_or(|b| base < b.0) {
                        let cost = with_leader(base);
                        if best.is_none_or(|b| cost < b.0) {
                            best = Some((cost, r));
                        }
                    }
                } else if best.is_none() {
                    let penalty = if rule { 0.0 } else { 1e6 } + if clash { 1e7 } else { 0.0 };
                    if fallback.is_none_or(|b| base + penalty < b.0) {
                        let cost = with_leader(base + penalty);
                        if fallback.is_none_or(|b| cost < b.0) {
                            fallback = Some((cost, r));
                        }
                    }
                }
            }
            let r = match (best, fallback) {
                (Some((_, r)), _) => r,
                (None, Some((_, r))) => {
                    failed += 1;
                    r
                }
                (None, None) => {
                    failed += 1;
                    [p[0], p[1] - 2.0 * hh, p[0] + 2.0 * hw, p[1]]
                }
            };
            boxes[i] = r;
            placed.push(r);
        }
        (boxes, failed)
    }

    fn place_marks_reference(
        anchors: &[PagePoint],
        texts: &[String],
        size: f64,
        occ: &Occupancy,
        taken: &mut Vec<[f64; 4]>,
        dots: &[PagePoint],
        frame: [f64; 4],
    ) -> Vec<Option<[f64; 4]>> {
        let (asc, desc) = (font::ascent(size), font::descent(size));
        anchors
            .iter()
            .zip(texts)
            .map(|(&p, text)| {
                let (hw, hh) = (0.5 * font::text_width(size, text), 0.5 * (asc + desc));
                let mut best: Option<(f64, [f64; 4])> = None;
                for (gi, _, r) in candidates(p, hw, hh, &MARK_GAPS, frame) {
                    if taken.iter().any(|q| rects_overlap(*q, grow(r, 0.5)))
                        || dots.iter().any(|d| rect_distance(r, *d) < MARK_DOT_CLEAR)
                    {
                        continue;
                    }
                    // The text's ink reaches a little past its box: count the ink 1 pt round.
                    let g = grow(r, 1.0);
                    let base = MARK_LABEL.label(occ, g) + gi as f64 * 3.0;
                    if best.is_some_and(|b| base >= b.0) {
                        continue;
                    }
                    let cost = base
                        + MARK_LABEL.leader(
                            occ,
                            p,
                            g,
                            MARK_LEADER_MIN_GAP - 1.0,
                            MARK_LEADER_START,
                        );
                    if best.is_none_or(|b| cost < b.0) {
                        best = Some((cost, r));
                    }
                }
                let r = best.map(|b| b.1);
                taken.extend(r);
                r
            })
            .collect()
    }

    #[test]
    fn distance_to_a_box() {
        let r = [0.0, 0.0, 10.0, 5.0];
        assert_eq!(rect_distance(r, [5.0, 2.0]), 0.0);
        assert_eq!(rect_distance(r, [13.0, 2.0]), 3.0);
        assert_eq!(rect_distance(r, [13.0, 9.0]), 5.0);
        // A segment crossing the box, one beside it, one past a corner.
        assert_eq!(rect_segment_distance(r, [-5.0, 2.0], [20.0, 2.0]), 0.0);
        assert_eq!(rect_segment_distance(r, [13.0, -5.0], [13.0, 50.0]), 3.0);
        let d = rect_segment_distance(r, [11.0, 8.0], [14.0, 5.0]);
        assert!((d - 8.0f64.sqrt()).abs() < 1e-12, "{d}");
    }

    #[test]
    fn a_row_of_close_dots_gets_labels_by_the_rule() {
        let dots: Vec<PagePoint> = (0..10).map(|i| [100.0 + 30.0 * i as f64, 200.0]).collect();
        let full: Vec<String> = (0..10).map(|i| format!("({i}.25, -1.5)")).collect();
        let nums: Vec<String> = (1..=10).map(|i| i.to_string()).collect();
        let frame = [0.0, 0.0, 600.0, 400.0];
        let mut occ = Occupancy::new(frame, 3.0);
        occ.build();
        let p = place_labels(&dots, &full, &nums, 7.5, &occ, &[], frame);
        assert_eq!(p.failed, 0);
        for (i, a) in p.boxes.iter().enumerate() {
            assert!(own_dot_is_nearest(*a, i, &dots));
            for b in &p.boxes[i + 1..] {
                assert!(!rects_overlap(*a, *b));
            }
        }
    }

    /// Pseudo-random pages (a linear congruential generator: the same every run) with
    /// crowded dots, ink strokes and boxes already taken.
    fn random_pages() -> impl Iterator<Item = (Occupancy, Vec<PagePoint>, Vec<[f64; 4]>)> {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let frame = [0.0, 0.0, 400.0, 300.0];
        (0..60).map(move |page| {
            let mut occ = Occupancy::new(frame, 3.0);
            let strokes = 20 + page % 7 * 30;
            for _ in 0..strokes {
                let a = [400.0 * next(), 300.0 * next()];
                let b = [a[0] + 80.0 * (next() - 0.5), a[1] + 80.0 * (next() - 0.5)];
                occ.mark_segment(a, b, 1 + (next() * 3.0) as u32);
            }
            occ.build();
            // Some pages crowd their dots into a corner, where the rule bites.
            let spread = if page % 3 == 0 { 60.0 } else { 350.0 };
            let n = 3 + page % 11;
            let dots: Vec<PagePoint> = (0..n)
                .map(|_| [20.0 + spread * next(), 20.0 + spread * 0.7 * next()])
                .collect();
            let mut taken: Vec<[f64; 4]> = (0..page % 4)
                .map(|_| {
                    let (x, y) = (380.0 * next(), 280.0 * next());
                    [x, y, x + 20.0, y + 8.0]
                })
                .collect();
            // And a few leave no room but a strip along the left edge.
            if page % 10 == 9 {
                taken.push([60.0, 0.0, 400.0, 300.0]);
            }
            (occ, dots, taken)
        })
    }

    #[test]
    fn early_outs_place_every_label_where_the_full_search_does() {
        let frame = [0.0, 0.0, 400.0, 300.0];
        let (mut keyed, mut failed, mut marks_placed, mut marks_none) = (0, 0, 0, 0);
        for (occ, dots, taken) in random_pages() {
            let full: Vec<String> = (0..dots.len())
                .map(|i| format!("({i}.25, -1.{i})"))
                .collect();
            let nums: Vec<String> = (1..=dots.len()).map(|i| i.to_string()).collect();
            for texts in [&full, &nums] {
                let new = place_all(&dots, texts, 7.5, &occ, &taken, frame);
                let old = place_all_reference(&dots, texts, 7.5, &occ, &taken, frame);
                assert_eq!(new, old);
                failed += usize::from(new.1 > 0);
            }
            keyed += usize::from(place_labels(&dots, &full, &nums, 7.5, &occ, &taken, frame).keyed);
            // Feature labels around points along the page, with the curve labels taken.
            let anchors: Vec<PagePoint> = dots
                .iter()
                .flat_map(|d| [[d[0] + 12.0, d[1] + 5.0], [d[0] - 9.0, d[1] + 14.0]])
                .collect();
            let texts: Vec<String> = (0..anchors.len())
                .map(|i| format!("S {}°", 40 + i))
                .collect();
            let mut t_new = taken.clone();
            let mut t_old = taken.clone();
            let new = place_marks(&anchors, &texts, 6.0, &occ, &mut t_new, &dots, frame);
            let old = place_marks_reference(&anchors, &texts, 6.0, &occ, &mut t_old, &dots, frame);
            assert_eq!(new, old);
            assert_eq!(t_new, t_old);
            marks_placed += new.iter().filter(|b| b.is_some()).count();
            marks_none += new.iter().filter(|b| b.is_none()).count();
        }
        // The pages reach every branch: keyed pages, failures, marks placed and not.
        assert!(
            keyed > 0 && failed > 0 && marks_placed > 0 && marks_none > 0,
            "keyed {keyed}, failed {failed}, marks placed {marks_placed}, unplaced {marks_none}"
        );
    }
}
