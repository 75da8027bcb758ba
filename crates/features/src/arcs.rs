//! Pseudo-arcs (docs/conventions.md §5): portions of the curve that stay close to a circle.
//!
//! **The contract.** The circle of a window is Kåsa's algebraic circle of its samples
//! ([`kasa_circle`]: closed form, so a window's fit is exact and costs O(1) from sliding
//! sums; on arcs within a fraction of a percent of a circle it agrees with the geometric
//! fit to first order, since `‖M−c‖² − R² = (‖M−c‖ − R)(‖M−c‖ + R)` and the second factor
//! varies by twice the tolerance). A window **qualifies** when, with that circle (c, R):
//! every sample is within `arc_pct` % of R of it (`|‖M−c‖ − R| ≤ tol·R`); the point runs
//! one way round c (every `(M − c) × V` of one strict sign); it turns at least
//! `arc_min_turn_deg` about c (the sum of the polar angle's steps between consecutive
//! samples); and it spans at least `arc_min_span_deg`. The error breaking ties is Kåsa's
//! largest relative deviation. The pseudo-arcs are the maximal qualifying windows
//! ([`crate::maximal`]).

use super::fit::{Circle, CircleFitOptions, fit_circle, kasa_circle};
use super::{FeatureTolerances, PseudoArc, Side, dash_count};
use crate::maximal::Candidates;
use coupler_kinematics::{Curve, DashPattern};

/// The samples of the periodic window `[i, j]`, or `None` if one is invalid.
fn gather(c: &Curve, i: usize, j: usize, xs: &mut Vec<f64>, ys: &mut Vec<f64>) -> Option<()> {
    let n = c.len();
    xs.clear();
    ys.clear();
    for k in i..=j {
        let k = if k < n { k } else { k - n }; // k < 2n: no division
        if !(c.is_valid(k) && c.vx[k].is_finite() && c.vy[k].is_finite()) {
            return None;
        }
        xs.push(c.x[k]);
        ys.push(c.y[k]);
    }
    Some(())
}

/// The sign (+1 / −1) with which the window runs round `center` if it runs one way
/// (every `(M − c) × V` of that sign), else 0.
fn winding(c: &Curve, i: usize, j: usize, center: [f64; 2]) -> f64 {
    let n = c.len();
    let (mut pos, mut neg) = (true, true);
    for k in i..=j {
        let k = if k < n { k } else { k - n };
        let cross = (c.x[k] - center[0]) * c.vy[k] - (c.y[k] - center[1]) * c.vx[k];
        pos &= cross > 0.0;
        neg &= cross < 0.0;
    }
    if pos {
        1.0
    } else if neg {
        -1.0
    } else {
        0.0
    }
}

/// The angle (radians) a window turns about `center` in the direction `sign`: the sum of
/// the polar angle's steps between consecutive samples (each in (−π, π]), times `sign`.
/// With `stop_at`, the sum stops once it reaches that angle (enough to pass a test).
fn turn(c: &Curve, i: usize, j: usize, center: [f64; 2], sign: f64, stop_at: f64) -> f64 {
    let n = c.len();
    let r = |k: usize| {
        let k = if k < n { k } else { k - n };
        [c.x[k] - center[0], c.y[k] - center[1]]
    };
    let mut total = 0.0;
    let mut a = r(i);
    for k in i + 1..=j {
        let b = r(k);
        let step = libm::atan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1]);
        total += sign * step;
        if total >= stop_at {
            break;
        }
        a = b;
    }
    total
}

/// The O(1) filter of every window of a closed curve of `n` samples, for every start at
/// once (structure of arrays, so the compiler vectorises it): Kåsa's sums of the window
/// `[i, i + l]` about its first sample (so that a small window far from the origin keeps
/// its digits), grown by one sample per round of `l`; from them its circle, and whether
/// that circle holds the window's first, middle and last samples within the tolerance
/// (0.1 % slack on it, and more than the rounding of a circle fitted from sums). Windows
/// whose samples are (nearly) collinear pass: the exact test decides.
fn filter_windows(c: &Curve, tol: f64, min_steps: usize, cand: &mut Candidates) {
    let n = c.len();
    let x2: Vec<f64> = c.x.iter().chain(&c.x).copied().collect();
    let y2: Vec<f64> = c.y.iter().chain(&c.y).copied().collect();
    let (x0, y0) = (&x2[..n], &y2[..n]);
    let mut sx = vec![0.0; n];
    let mut sy = vec![0.0; n];
    let mut sxx = vec![0.0; n];
    let mut sxy = vec![0.0; n];
    let mut syy = vec![0.0; n];
    let mut szx = vec![0.0; n];
    let mut szy = vec![0.0; n];
    let mut pass = vec![false; n];
    let lo_f = (1.0 - 1.001 * tol - 1e-9).max(0.0).powi(2);
    let hi_f = (1.0 + 1.001 * tol + 1e-9).powi(2);
    for l in 1..n {
        let (xl, yl) = (&x2[l..l + n], &y2[l..l + n]);
        for i in 0..n {
            let (x, y) = (xl[i] - x0[i], yl[i] - y0[i]);
            let (xx, xy, yy) = (x * x, x * y, y * y);
            let z = xx + yy;
            sx[i] += x;
            sy[i] += y;
            sxx[i] += xx;
            sxy[i] += xy;
            syy[i] += yy;
            szx[i] += z * x;
            szy[i] += z * y;
        }
        if l < min_steps {
            continue;
        }
        let m = (l + 1) as f64;
        let inv_m = 1.0 / m;
        let h = l / 2;
        let (xh, yh) = (&x2[h..h + n], &y2[h..h + n]);
        for i in 0..n {
            let (mx, my) = (sx[i] * inv_m, sy[i] * inv_m);
            let sz = sxx[i] + syy[i];
            let cxx = sxx[i] - sx[i] * mx;
            let cxy = sxy[i] - sx[i] * my;
            let cyy = syy[i] - sy[i] * my;
            let czx = szx[i] - sz * mx;
            let czy = szy[i] - sz * my;
            let det = cxx * cyy - cxy * cxy;
            let scale = cxx + cyy;
            let inv_det = 1.0 / det;
            let d = -(czx * cyy - czy * cxy) * inv_det;
            let e = -(cxx * czy - cxy * czx) * inv_det;
            let f = -(sz + d * sx[i] + e * sy[i]) * inv_m;
            let (a, b) = (-0.5 * d, -0.5 * e);
            let r2 = a * a + b * b - f;
            let (lo, hi) = (r2 * lo_f, r2 * hi_f);
            // The first sample is the origin; then the middle and the last.
            let d0 = a * a + b * b;
            let (hx, hy) = (xh[i] - x0[i] - a, yh[i] - y0[i] - b);
            let dh = hx * hx + hy * hy;
            let (ex, ey) = (xl[i] - x0[i] - a, yl[i] - y0[i] - b);
            let de = ex * ex + ey * ey;
            let round = (lo <= d0) & (d0 <= hi) & (lo <= dh) & (dh <= hi) & (lo <= de) & (de <= hi);
            let fitted = (det > 1e-9 * scale * scale) & (r2 > 0.0);
            pass[i] = round | !fitted;
        }
        for (i, &p) in pass.iter().enumerate() {
            if p {
                cand.set(i, l);
            }
        }
    }
}

/// A window's circle if the window qualifies (the contract above): Kåsa's circle, the
/// winding sign, and Kåsa's largest relative deviation.
fn qualifying(
    c: &Curve,
    i: usize,
    j: usize,
    limit: f64,
    min_turn: f64,
    xs: &mut Vec<f64>,
    ys: &mut Vec<f64>,
) -> Option<(Circle, f64, f64)> {
    gather(c, i, j, xs, ys)?;
    let k = kasa_circle(xs, ys)?;
    // |‖M − c‖ − R| ≤ limit·R ⟺ (R(1 − limit))² ≤ ‖M − c‖² ≤ (R(1 + limit))²: a cheap
    // test first (ends first, where a window usually fails), the exact maximum after.
    let (lo, hi) = (
        (k.radius * (1.0 - limit)).max(0.0).powi(2),
        (k.radius * (1.0 + limit)).powi(2),
    );
    let m = xs.len();
    let order = [0, m - 1, m / 2].into_iter().chain(1..m - 1);
    for q in order {
        let d2 = (xs[q] - k.center[0]).powi(2) + (ys[q] - k.center[1]).powi(2);
        if !(lo * (1.0 - 1e-12) <= d2 && d2 <= hi * (1.0 + 1e-12)) {
            return None;
        }
    }
    let dev = k.max_deviation(xs, ys);
    if dev.is_nan() || dev > limit * k.radius {
        return None;
    }
    let sign = winding(c, i, j, k.center);
    if sign == 0.0 || turn(c, i, j, k.center, sign, min_turn) < min_turn {
        return None;
    }
    Some((k, sign, dev / k.radius))
}

/// The pseudo-arcs of a closed curve sampled every `tol.step_deg` from θ = 0: the maximal
/// qualifying windows (module documentation). The reported circle is the geometric one
/// ([`fit_circle`], least squares on distances, started from Kåsa's) when it deviates less
/// than Kåsa's and also runs one way round its centre turning at least
/// `arc_min_turn_deg`; otherwise Kåsa's. So `deviation_pct ≤ arc_pct` always holds.
pub fn pseudo_arcs(c: &Curve, tol: &FeatureTolerances, dash: &DashPattern) -> Vec<PseudoArc> {
    let n = c.len();
    if n < 4 {
        return Vec::new();
    }
    let limit = tol.arc_pct / 100.0;
    let min_turn = tol.arc_min_turn_deg.to_radians();
    let min_steps = (tol.arc_min_span_deg / tol.step_deg - 1e-9).ceil().max(2.0) as usize;
    let mut cand = Candidates::new(n, true);
    filter_windows(c, limit, min_steps, &mut cand);
    let (mut xs, mut ys) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let chosen = cand.pick(
        |i, j| (j - i) as f64,
        1.0,
        min_steps as f64,
        usize::MAX,
        |i, j| qualifying(c, i, j, limit, min_turn, &mut xs, &mut ys).map(|q| q.2),
    );
    chosen
        .into_iter()
        .filter_map(|w| {
            let (i, j) = (w.start, w.end);
            let (k, k_sign, _) = qualifying(c, i, j, limit, min_turn, &mut xs, &mut ys)?;
            let geometric = fit_circle(&xs, &ys, Some(k), &CircleFitOptions::DEFAULT)
                .filter(|g| {
                    g.max_deviation(&xs, &ys) / g.radius < k.max_deviation(&xs, &ys) / k.radius
                })
                .and_then(|g| {
                    let sign = winding(c, i, j, g.center);
                    (sign != 0.0 && turn(c, i, j, g.center, sign, f64::INFINITY) >= min_turn)
                        .then_some((g, sign))
                });
            let (circle, sign) = geometric.unwrap_or((k, k_sign));
            let turned = turn(c, i, j, circle.center, sign, f64::INFINITY);
            let span = (j - i) as f64 * tol.step_deg;
            Some(PseudoArc {
                start_deg: i as f64 * tol.step_deg,
                span_deg: span,
                dashes: dash_count(span, dash),
                center: circle.center,
                radius: circle.radius,
                deviation_pct: circle.max_deviation(&xs, &ys) / circle.radius * 100.0,
                turn_deg: turned.to_degrees(),
                // (M − c) × V > 0: counter-clockwise about c, so c is on the left.
                concave: if sign > 0.0 { Side::Left } else { Side::Right },
            })
        })
        .collect()
}
