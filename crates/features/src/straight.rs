//! Straight segments (Norton §3.8; docs/conventions.md §5).

use super::fit::LineSums;
use super::{FeatureTolerances, StraightSegment, dash_count, grow_windows, pick_disjoint};
use coupler_kinematics::{Curve, DashPattern};

/// The line measures of the periodic window `[i, j]` of a curve (see
/// [`crate::WindowMeasures`]): fitted line, then one pass for Cx, Cy and Vx.
#[derive(Clone, Copy, Debug)]
pub(crate) struct WindowLine {
    pub d: [f64; 2],
    pub extent: f64,
    pub width: f64,
    pub vx_range: f64,
    pub mean_vx: f64,
    pub monotone: bool,
}

pub(crate) fn window_line(c: &Curve, i: usize, j: usize) -> Option<WindowLine> {
    let n = c.len();
    let mut sums = LineSums::new([c.x[i % n], c.y[i % n]]);
    for k in i..=j {
        let k = if k < n { k } else { k - n }; // k < 2n: no division
        if !(c.is_valid(k) && c.vx[k].is_finite() && c.vy[k].is_finite()) {
            return None;
        }
        sums.add(c.x[k], c.y[k]);
    }
    let (g, mut d) = sums.line()?;
    let (mut cx0, mut cx1, mut cy0, mut cy1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let (mut v0, mut v1, mut vs) = (f64::MAX, f64::MIN, 0.0);
    for k in i..=j {
        let k = if k < n { k } else { k - n };
        let (px, py) = (c.x[k] - g[0], c.y[k] - g[1]);
        let cx = px * d[0] + py * d[1];
        let cy = py * d[0] - px * d[1];
        let vx = c.vx[k] * d[0] + c.vy[k] * d[1];
        cx0 = cx0.min(cx);
        cx1 = cx1.max(cx);
        cy0 = cy0.min(cy);
        cy1 = cy1.max(cy);
        v0 = v0.min(vx);
        v1 = v1.max(vx);
        vs += vx;
    }
    let m = (j + 1 - i) as f64;
    let mut mean = vs / m;
    let monotone = if mean < 0.0 {
        d = [-d[0], -d[1]];
        mean = -mean;
        v1 < 0.0
    } else {
        v0 > 0.0
    };
    Some(WindowLine {
        d,
        extent: cx1 - cx0,
        width: cy1 - cy0,
        vx_range: v1 - v0,
        mean_vx: mean,
        monotone,
    })
}

/// The straight segments of a closed curve sampled every `tol.step_deg` from θ = 0:
/// maximal windows (grown by a two-pointer sweep, then chosen longest first without
/// overlap) with ε_S ≤ `straight_pct`, moving one way along the line (every Vx > 0) and
/// spanning at least `straight_min_span_deg`. Windows never include an invalid sample.
pub fn straight_segments(
    c: &Curve,
    tol: &FeatureTolerances,
    dash: &DashPattern,
) -> Vec<StraightSegment> {
    let n = c.len();
    if n < 4 {
        return Vec::new();
    }
    let limit = tol.straight_pct / 100.0;
    let ok = |w: &WindowLine| w.monotone && w.extent > 0.0 && w.width <= limit * w.extent;
    let best = grow_windows(n, 3, |i, j| window_line(c, i, j).is_some_and(|w| ok(&w)));
    let min_edges = (tol.straight_min_span_deg / tol.step_deg - 1e-9).ceil() as usize;
    // A start whose window ends inside the previous start's is a sub-window: skipped.
    // Equally long sliding windows all stay, so the straightest of them wins.
    let candidates: Vec<(usize, usize, f64)> = best
        .iter()
        .enumerate()
        .filter(|&(i, &j)| j >= i + min_edges.max(2) && (i == 0 || best[i - 1] < j))
        .filter_map(|(i, &j)| {
            let w = window_line(c, i, j).filter(ok)?;
            Some((i, j, w.width / w.extent))
        })
        .collect();
    pick_disjoint(n, candidates)
        .into_iter()
        .filter_map(|(i, j)| {
            let w = window_line(c, i, j)?;
            let (a, b) = (i % n, j % n);
            let seg = StraightSegment {
                start_deg: i as f64 * tol.step_deg,
                span_deg: (j - i) as f64 * tol.step_deg,
                dashes: dash_count((j - i) as f64 * tol.step_deg, dash),
                length: w.extent,
                straightness_pct: w.width / w.extent * 100.0,
                velocity_variation_pct: w.vx_range / w.mean_vx * 100.0,
                direction_deg: crate::angle_deg(w.d),
                endpoints: [[c.x[a], c.y[a]], [c.x[b], c.y[b]]],
            };
            [
                seg.length,
                seg.straightness_pct,
                seg.velocity_variation_pct,
                seg.direction_deg,
            ]
            .iter()
            .all(|x| x.is_finite())
            .then_some(seg)
        })
        .collect()
}
