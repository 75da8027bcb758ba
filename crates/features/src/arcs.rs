//! Pseudo-arcs (docs/conventions.md §5): portions of the curve that stay close to a circle.

use super::fit::{Circle, CircleFitOptions, fit_circle, kasa_circle};
use super::{FeatureTolerances, PseudoArc, Side, dash_count, grow_windows, pick_disjoint};
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

/// The angle (radians) a window that runs one way round `center` with `sign` turns: the
/// sum of its polar angle's increments over eight sub-windows (each well under half a
/// turn), each taken in the direction of travel; never negative.
fn turn(c: &Curve, i: usize, j: usize, center: [f64; 2], sign: f64) -> f64 {
    let n = c.len();
    let polar = |k: usize| libm::atan2(c.y[k % n] - center[1], c.x[k % n] - center[0]);
    let pieces = 8.min(j - i).max(1);
    let mut total = 0.0;
    let mut prev = polar(i);
    for q in 1..=pieces {
        let k = i + (j - i) * q / pieces;
        let a = polar(k);
        let d = sign * (a - prev);
        // wrap into (−π, π]
        let d = d - std::f64::consts::TAU
            * ((d + std::f64::consts::PI) / std::f64::consts::TAU).floor();
        total += d;
        prev = a;
    }
    total.max(0.0)
}

/// The pseudo-arcs of a closed curve sampled every `tol.step_deg` from θ = 0: maximal
/// windows (two-pointer growth tested with the algebraic Kåsa circle, O(w) per test)
/// whose radial deviation is at most `arc_pct` of the radius, that run one way round
/// the centre, span at least `arc_min_span_deg` and turn at least `arc_min_turn_deg`.
/// The reported circle is the geometric fit ([`fit_circle`], started from Kåsa's), or
/// Kåsa's own if that has the smaller largest deviation, so `deviation_pct ≤ arc_pct`.
pub fn pseudo_arcs(c: &Curve, tol: &FeatureTolerances, dash: &DashPattern) -> Vec<PseudoArc> {
    let n = c.len();
    if n < 4 {
        return Vec::new();
    }
    let limit = tol.arc_pct / 100.0;
    let (mut xs, mut ys) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let test = |i: usize, j: usize, xs: &mut Vec<f64>, ys: &mut Vec<f64>| -> Option<Circle> {
        gather(c, i, j, xs, ys)?;
        let k = kasa_circle(xs, ys)?;
        // |d − R| ≤ tol·R  ⟺  (R(1 − tol))² ≤ d² ≤ (R(1 + tol))²: no square roots.
        let (lo, hi) = (
            (k.radius * (1.0 - limit)).powi(2),
            (k.radius * (1.0 + limit)).powi(2),
        );
        let within = xs.iter().zip(ys.iter()).all(|(&x, &y)| {
            let d2 = (x - k.center[0]).powi(2) + (y - k.center[1]).powi(2);
            (lo..=hi).contains(&d2)
        });
        (within && winding(c, i, j, k.center) != 0.0).then_some(k)
    };
    let best = grow_windows(n, 3, |i, j| test(i, j, &mut xs, &mut ys).is_some());
    let min_edges = (tol.arc_min_span_deg / tol.step_deg - 1e-9).ceil() as usize;
    // Candidates, scored by Kåsa's deviation; a start whose window ends inside the
    // previous start's is a sub-window of it and skipped.
    let mut candidates = Vec::new();
    for (i, &j) in best.iter().enumerate() {
        if j < i + min_edges.max(2) || (i > 0 && best[i - 1] >= j) {
            continue;
        }
        let Some(k) = test(i, j, &mut xs, &mut ys) else {
            continue;
        };
        let sign = winding(c, i, j, k.center);
        if turn(c, i, j, k.center, sign).to_degrees() < tol.arc_min_turn_deg {
            continue;
        }
        candidates.push((i, j, k.max_deviation(&xs, &ys) / k.radius));
    }
    pick_disjoint(n, candidates)
        .into_iter()
        .filter_map(|(i, j)| {
            let k = test(i, j, &mut xs, &mut ys)?;
            let circle = match fit_circle(&xs, &ys, Some(k), &CircleFitOptions::DEFAULT) {
                Some(g)
                    if g.max_deviation(&xs, &ys) / g.radius
                        < k.max_deviation(&xs, &ys) / k.radius =>
                {
                    g
                }
                _ => k,
            };
            let sign = winding(c, i, j, circle.center);
            let turned = turn(c, i, j, circle.center, sign);
            if sign == 0.0 || turned.to_degrees() < tol.arc_min_turn_deg {
                return None;
            }
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
