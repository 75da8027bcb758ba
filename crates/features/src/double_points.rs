//! Double points (docs/conventions.md §5): crunodes (self-crossings) and cusps (speed zero).

use super::{Crunode, Cusp, FeatureTolerances};
use coupler_kinematics::{Circuit, CouplerPoint, CrankAngle, Curve, Mechanism};

/// Position and velocity (per radian) of the coupler point at θ degrees (`k`: the
/// mechanism's [`Mechanism::constants`]).
pub(crate) fn at<M: Mechanism>(
    l: &M,
    k: &M::Constants,
    circuit: Circuit,
    p: CouplerPoint,
    deg: f64,
) -> Option<([f64; 2], [f64; 2])> {
    let pose = l.frame_with(k, circuit, &CrankAngle::from_degrees(deg))?;
    let (m, v) = (pose.point(p), pose.velocity(p));
    (m.x.is_finite() && v.x.is_finite() && v.y.is_finite()).then_some(([m.x, m.y], [v.x, v.y]))
}

/// `deg` reduced to `[0, period)` (the mechanism's period: 360° for a four-bar).
fn wrap(deg: f64, period: f64) -> f64 {
    let r = deg.rem_euclid(period);
    if r >= period { 0.0 } else { r }
}

/// Where segments `p0→p1` and `q0→q1` cross: parameters `(t, s)` in [0, 1].
fn segment_cross(p0: [f64; 2], p1: [f64; 2], q0: [f64; 2], q1: [f64; 2]) -> Option<(f64, f64)> {
    let r = [p1[0] - p0[0], p1[1] - p0[1]];
    let s = [q1[0] - q0[0], q1[1] - q0[1]];
    let den = r[0] * s[1] - r[1] * s[0];
    if den == 0.0 {
        return None;
    }
    let w = [q0[0] - p0[0], q0[1] - p0[1]];
    let t = (w[0] * s[1] - w[1] * s[0]) / den;
    let u = (w[0] * r[1] - w[1] * r[0]) / den;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some((t, u))
}

/// The bounding boxes of a closed polyline's segments (segment `k` from sample `k` to
/// `k + 1`), one array per side, and those of blocks of [`SegmentBoxes::BLOCK`] segments
/// (the union of their boxes).
struct SegmentBoxes {
    x0: Vec<f64>,
    y0: Vec<f64>,
    x1: Vec<f64>,
    y1: Vec<f64>,
    /// Per block: `[x0, y0, x1, y1]`.
    blocks: Vec<[f64; 4]>,
}

impl SegmentBoxes {
    /// Segments per block.
    const BLOCK: usize = 8;

    /// The boxes of the `n` segments of the finite samples `pt(0..=n)`.
    fn new(n: usize, pt: impl Fn(usize) -> [f64; 2]) -> SegmentBoxes {
        // (One loop with `min` and `max` inlined: through a function pointer, one call
        // per side and segment, they cost more than the boxes' test.)
        let (mut x0, mut y0, mut x1, mut y1) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        for k in 0..n {
            let (p, q) = (pt(k), pt(k + 1));
            x0.push(p[0].min(q[0]));
            y0.push(p[1].min(q[1]));
            x1.push(p[0].max(q[0]));
            y1.push(p[1].max(q[1]));
        }
        let blocks = (0..n.div_ceil(Self::BLOCK))
            .map(|q| {
                let r = q * Self::BLOCK..((q + 1) * Self::BLOCK).min(n);
                let mut u = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];
                for k in r {
                    u = [
                        u[0].min(x0[k]),
                        u[1].min(y0[k]),
                        u[2].max(x1[k]),
                        u[3].max(y1[k]),
                    ];
                }
                u
            })
            .collect();
        SegmentBoxes {
            x0,
            y0,
            x1,
            y1,
            blocks,
        }
    }

    /// The segments `b` of `range` whose boxes meet segment `a`'s (edges touching
    /// count), in order, into `out` (cleared first). A box that misses a block's misses
    /// each of its segments', so their boxes are not tested: a curve's segments far
    /// along it mostly lie away from segment `a`, and a block's segments lie together.
    fn meeting(&self, a: usize, range: std::ops::Range<usize>, out: &mut Vec<usize>) {
        out.clear();
        let (ax0, ay0, ax1, ay1) = (self.x0[a], self.y0[a], self.x1[a], self.y1[a]);
        let misses = |bx0: f64, by0: f64, bx1: f64, by1: f64| {
            (ax1 < bx0) | (bx1 < ax0) | (ay1 < by0) | (by1 < ay0)
        };
        if range.is_empty() {
            return;
        }
        for q in range.start / Self::BLOCK..range.end.div_ceil(Self::BLOCK) {
            let [ux0, uy0, ux1, uy1] = self.blocks[q];
            if misses(ux0, uy0, ux1, uy1) {
                continue;
            }
            let lo = (q * Self::BLOCK).max(range.start);
            let hi = ((q + 1) * Self::BLOCK).min(range.end);
            for b in lo..hi {
                if !misses(self.x0[b], self.y0[b], self.x1[b], self.y1[b]) {
                    out.push(b);
                }
            }
        }
    }
}

/// The crunodes of a closed curve: crossings of the sampled polyline (segment pairs
/// pruned by bounding box), each refined by Newton's method on `M(θ1) = M(θ2)` with the
/// closed-form pose (Jacobian `[V(θ1), −V(θ2)]`) to ~1e-13, then de-duplicated. A
/// crossing that the polyline misses (two branches touching within the sampling's chord
/// error) is missed; a tangency (Jacobian singular) is dropped.
pub fn crunodes<M: Mechanism>(
    l: &M,
    circuit: Circuit,
    p: CouplerPoint,
    c: &Curve,
    tol: &FeatureTolerances,
) -> Vec<Crunode> {
    let n = c.len();
    if n < 4 || (0..n).any(|k| !c.is_valid(k)) {
        return Vec::new();
    }
    // `k ≤ n` (a segment's end): wrapped without a division.
    let pt = |k: usize| {
        let k = if k < n { k } else { k - n };
        [c.x[k], c.y[k]]
    };
    let boxes = SegmentBoxes::new(n, pt);
    // The later segments whose boxes meet segment a's, in order.
    let mut meets: Vec<usize> = Vec::new();
    let consts = l.constants();
    let size = (c.x.iter().cloned().fold(f64::MIN, f64::max)
        - c.x.iter().cloned().fold(f64::MAX, f64::min))
    .hypot(
        c.y.iter().cloned().fold(f64::MIN, f64::max) - c.y.iter().cloned().fold(f64::MAX, f64::min),
    );
    let mut out: Vec<Crunode> = Vec::new();
    for a in 0..n {
        let last = if a == 0 { n - 1 } else { n };
        let from = (a + 2).min(last);
        boxes.meeting(a, from..last, &mut meets);
        for &b in &meets {
            let Some((t, s)) = segment_cross(pt(a), pt(a + 1), pt(b), pt(b + 1)) else {
                continue;
            };
            let mut t1 = (a as f64 + t) * tol.step_deg;
            let mut t2 = (b as f64 + s) * tol.step_deg;
            let mut converged = false;
            for _ in 0..30 {
                let (Some((m1, v1)), Some((m2, v2))) = (
                    at(l, &consts, circuit, p, t1),
                    at(l, &consts, circuit, p, t2),
                ) else {
                    break;
                };
                let f = [m1[0] - m2[0], m1[1] - m2[1]];
                if f[0].hypot(f[1]) <= 1e-13 * size.max(1.0) {
                    converged = true;
                    break;
                }
                // [v1, −v2]·(d1, d2) = −f, in radians.
                let det = v1[0] * (-v2[1]) - (-v2[0]) * v1[1];
                if det.abs() < 1e-300 {
                    break;
                }
                let d1 = (-f[0] * (-v2[1]) - (-v2[0]) * (-f[1])) / det;
                let d2 = (v1[0] * (-f[1]) - (-f[0]) * v1[1]) / det;
                let max_step = 2.0 * tol.step_deg.to_radians();
                let scale = (max_step / d1.abs().max(d2.abs())).min(1.0);
                t1 += (d1 * scale).to_degrees();
                t2 += (d2 * scale).to_degrees();
            }
            let period = l.period_deg();
            let (t1, t2) = (wrap(t1, period), wrap(t2, period));
            let gap = (t1 - t2).abs().min(period - (t1 - t2).abs());
            if !converged || gap < 1e-6 {
                continue;
            }
            let (Some((m, v1)), Some((_, v2))) = (
                at(l, &consts, circuit, p, t1),
                at(l, &consts, circuit, p, t2),
            ) else {
                continue;
            };
            // A true crossing has distinct tangents; a curve that retraces itself (the
            // rocker pin's arc, run forth and back) meets itself with parallel ones.
            let sin = (v1[0] * v2[1] - v1[1] * v2[0]) / (v1[0].hypot(v1[1]) * v2[0].hypot(v2[1]));
            if sin.abs().is_nan() || sin.abs() <= 1e-6 {
                continue;
            }
            if out
                .iter()
                .any(|q| (q.position[0] - m[0]).hypot(q.position[1] - m[1]) < 1e-9 * size.max(1.0))
            {
                continue;
            }
            out.push(Crunode {
                position: m,
                angles_deg: [t1.min(t2), t1.max(t2)],
            });
        }
    }
    out.sort_by(|a, b| a.angles_deg[0].total_cmp(&b.angles_deg[0]));
    out
}

/// The cusps of a closed curve: local minima of the sampled speed, refined by
/// golden-section search on |V(θ)| over the two neighbouring steps, kept when the minimum
/// is at most `cusp_speed_ratio` × the mean sampled speed.
pub fn cusps<M: Mechanism>(
    l: &M,
    circuit: Circuit,
    p: CouplerPoint,
    c: &Curve,
    tol: &FeatureTolerances,
) -> Vec<Cusp> {
    let n = c.len();
    if n < 3 || (0..n).any(|k| !c.is_valid(k)) {
        return Vec::new();
    }
    if surely_no_slow_sample(c, 10.0 * tol.cusp_speed_ratio) {
        return Vec::new();
    }
    let speed: Vec<f64> = (0..n).map(|k| c.vx[k].hypot(c.vy[k])).collect();
    let mean = speed.iter().sum::<f64>() / n as f64;
    if !(mean > 0.0 && mean.is_finite()) {
        return Vec::new();
    }
    let consts = l.constants();
    let sp = |deg: f64| {
        at(l, &consts, circuit, p, deg)
            .map(|(_, v)| v[0].hypot(v[1]))
            .unwrap_or(f64::INFINITY)
    };
    let mut out = Vec::new();
    for k in 0..n {
        let (prev, next) = (speed[(k + n - 1) % n], speed[(k + 1) % n]);
        if !(speed[k] <= prev && speed[k] < next && speed[k] <= 10.0 * tol.cusp_speed_ratio * mean)
        {
            continue;
        }
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let (mut a, mut b) = (
            (k as f64 - 1.0) * tol.step_deg,
            (k as f64 + 1.0) * tol.step_deg,
        );
        let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
        let (mut f1, mut f2) = (sp(x1), sp(x2));
        for _ in 0..60 {
            if f1 < f2 {
                b = x2;
                x2 = x1;
                f2 = f1;
                x1 = b - g * (b - a);
                f1 = sp(x1);
            } else {
                a = x1;
                x1 = x2;
                f1 = f2;
                x2 = a + g * (b - a);
                f2 = sp(x2);
            }
        }
        let t = 0.5 * (a + b);
        let Some((m, v)) = at(l, &consts, circuit, p, t) else {
            continue;
        };
        let ratio = v[0].hypot(v[1]) / mean;
        if ratio <= tol.cusp_speed_ratio {
            out.push(Cusp {
                position: m,
                angle_deg: wrap(t, l.period_deg()),
                speed_ratio: ratio,
            });
        }
    }
    out
}

/// Whether no sampled speed `|V_k|` (as `hypot` gives it) is at most `fraction` × their
/// mean, decided without `hypot`: a curve with no cusp (nearly every curve) then needs
/// no `hypot` at all, and what [`cusps`] reports does not change. The speeds are taken
/// as `sqrt(vx² + vy²)`, within 3 ulp of `hypot`'s where the squares neither overflow
/// nor fall below 1e-290 (otherwise this answers `false` and the exact test runs); their
/// mean, summed in the same order, is then within about `n·2⁻⁵²` of the mean of `hypot`'s
/// (below 10⁻¹¹ for a million samples), so a speed above `fraction × mean` by more than
/// 10⁻⁹ of it is above it in `hypot`'s speeds too. `sqrt` needs no overflow guard here:
/// the guarded case answers `false`.
fn surely_no_slow_sample(c: &Curve, fraction: f64) -> bool {
    let n = c.len();
    let mut speed = Vec::with_capacity(n);
    for k in 0..n {
        let s2 = c.vx[k] * c.vx[k] + c.vy[k] * c.vy[k];
        if !(s2.is_finite() && s2 > 1e-290) {
            return false;
        }
        speed.push(s2.sqrt());
    }
    let mean = speed.iter().sum::<f64>() / n as f64;
    let limit = fraction * mean * (1.0 + 1e-9);
    limit.is_finite() && speed.iter().all(|&v| v > limit)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The segments whose boxes meet, found block by block, are those found testing
    /// every later segment's box: closed random walks (steps of every size, so blocks
    /// both tight and wide), axis-aligned and touching boxes, every range the crunode
    /// search asks for and some more.
    #[test]
    fn segments_met_by_blocks_are_those_met_one_by_one() {
        let mut seed = 0x243f_6a88_85a3_08d3u64;
        let mut rand = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut found = 0usize;
        for (trial, n) in [4usize, 5, 15, 16, 17, 33, 100, 181, 360, 720]
            .iter()
            .cycle()
            .take(40)
            .enumerate()
        {
            let step = [0.01, 0.2, 1.0, 5.0][trial % 4];
            let mut pts: Vec<[f64; 2]> = vec![[0.0, 0.0]];
            for k in 1..*n {
                let p = pts[k - 1];
                pts.push(if trial % 5 == 0 && k % 3 == 0 {
                    // Axis-aligned steps on a lattice: edges that touch exactly.
                    [(p[0] + 1.0).round(), p[1]]
                } else {
                    [p[0] + step * (rand() - 0.5), p[1] + step * (rand() - 0.5)]
                });
            }
            let n = *n;
            let pt = |k: usize| pts[if k < n { k } else { k - n }];
            let boxes = SegmentBoxes::new(n, pt);
            let mut got = Vec::new();
            for a in 0..n {
                let last = if a == 0 { n - 1 } else { n };
                for from in [(a + 2).min(last), 0, a, last] {
                    boxes.meeting(a, from..last, &mut got);
                    let want: Vec<usize> = (from..last)
                        .filter(|&b| {
                            let (p, q) = (pt(a), pt(a + 1));
                            let (r, s) = (pt(b), pt(b + 1));
                            !((p[0].max(q[0]) < r[0].min(s[0]))
                                | (r[0].max(s[0]) < p[0].min(q[0]))
                                | (p[1].max(q[1]) < r[1].min(s[1]))
                                | (r[1].max(s[1]) < p[1].min(q[1])))
                        })
                        .collect();
                    assert_eq!(got, want, "n {n}, a {a}, from {from}");
                    found += want.len();
                }
            }
        }
        assert!(found > 10_000, "{found}");
    }
}
