//! Mirror symmetry of a coupler curve (docs/conventions.md §5).

use super::double_points::at;
use super::{FeatureTolerances, Symmetry};
use coupler_kinematics::{Circuit, CouplerPoint, Curve, Mechanism};

/// Finds an axis of mirror symmetry of a closed curve, if any.
///
/// Where theory gives the axis ([`Mechanism::symmetry_axis`]: the crank pin's circle, the
/// rocker pin's arc, and A = B with M on the circle about Pb through Pa, docs/conventions.md
/// §5), that exact axis is reported, with its reflection error measured as below. Other
/// curves: an axis of symmetry passes through the curve's arc-length centroid G and is a
/// principal axis of its arc-length second moment (both are geometric: they do not depend
/// on the parametrisation). So each of the two principal axes is tried: every sample is
/// reflected in it; a coarse test (the nearest sample within ~a chord length) rejects most
/// curves cheaply; then each reflected point is projected onto the curve by Gauss–Newton
/// on θ with the closed-form pose, and the axis is accepted when the largest distance is
/// at most `symmetry_tol` × the curve's size (bounding-box diagonal).
pub fn symmetry<M: Mechanism>(
    l: &M,
    circuit: Circuit,
    p: CouplerPoint,
    c: &Curve,
    tol: &FeatureTolerances,
) -> Option<Symmetry> {
    let n = c.len();
    if n < 8 || (0..n).any(|k| !c.is_valid(k) || !c.vx[k].is_finite()) {
        return None;
    }
    let (x0, x1) =
        c.x.iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    let (y0, y1) =
        c.y.iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &y| (a.min(y), b.max(y)));
    let size = (x1 - x0).hypot(y1 - y0);
    let mirror = |g: [f64; 2], phi: f64| Mirror {
        g,
        d: [libm::cos(phi), libm::sin(phi)],
    };
    let found = |g: [f64; 2], phi: f64, error: f64| {
        let deg = phi.to_degrees().rem_euclid(180.0);
        Symmetry {
            point: g,
            direction_deg: if deg >= 180.0 { 0.0 } else { deg },
            error,
        }
    };
    if let Some(axis) = l.symmetry_axis(circuit, p) {
        let g = [axis.point.x, axis.point.y];
        let m = mirror(g, axis.direction);
        let error = m.error(l, circuit, p, c, tol, size, f64::INFINITY);
        // Theory and measurement agree to rounding (tests/features.rs); a disagreement
        // would be a defect, so the general test below decides then.
        if error <= tol.symmetry_tol {
            return Some(found(g, axis.direction, error));
        }
    }
    let w: Vec<f64> = (0..n).map(|k| c.vx[k].hypot(c.vy[k])).collect();
    let wsum: f64 = w.iter().sum();
    if wsum.is_nan() || wsum <= 0.0 {
        return None;
    }
    let gx = (0..n).map(|k| w[k] * c.x[k]).sum::<f64>() / wsum;
    let gy = (0..n).map(|k| w[k] * c.y[k]).sum::<f64>() / wsum;
    let (mut ixx, mut ixy, mut iyy) = (0.0, 0.0, 0.0);
    for (k, &wk) in w.iter().enumerate() {
        let (dx, dy) = (c.x[k] - gx, c.y[k] - gy);
        ixx += wk * dx * dx;
        ixy += wk * dx * dy;
        iyy += wk * dy * dy;
    }
    let chords: Vec<f64> = (0..n)
        .map(|k| (c.x[(k + 1) % n] - c.x[k]).hypot(c.y[(k + 1) % n] - c.y[k]))
        .collect();
    let phi0 = 0.5 * libm::atan2(2.0 * ixy, ixx - iyy);
    for phi in [phi0, phi0 + std::f64::consts::FRAC_PI_2] {
        let m = mirror([gx, gy], phi);
        // Coarse: each reflected sample has a sample within about a chord length (squared
        // distances; samples visited in a stride so a miss shows early).
        // The mirror partner of M_k moves at M_k's speed, so the local chord bounds the gap.
        // Each search starts where the last partner found suggests (a reflection runs the
        // curve backwards: sample k + s near q − s) and goes outwards, so a partner is
        // usually found in a few steps; every sample is still looked at before one is
        // declared missing, so the answer is that of a plain scan.
        let mut last: Option<(usize, usize)> = None;
        let coarse = (0..n).map(|i| (i * 37) % n).all(|k| {
            let thr = 0.75 * chords[k].max(chords[(k + n - 1) % n]) + 1e-9 * size;
            let thr2 = thr * thr;
            let r = m.reflect(c.x[k], c.y[k]);
            let start = last.map_or(0, |(k0, q0)| (q0 + k0 + n - k) % n);
            let partner = (0..n).map(|t| (start + outward(t, n)) % n).find(|&q| {
                let (dx, dy) = (c.x[q] - r[0], c.y[q] - r[1]);
                dx * dx + dy * dy <= thr2
            });
            if let Some(q) = partner {
                last = Some((k, q));
            }
            partner.is_some()
        });
        if !coarse {
            continue;
        }
        let worst = m.error(l, circuit, p, c, tol, size, tol.symmetry_tol);
        if worst <= tol.symmetry_tol {
            return Some(found([gx, gy], phi, worst));
        }
    }
    None
}

/// The `t`-th offset of a search outwards from a start, modulo `n`: 0, +1, −1, +2, −2, …
/// (`t < n`: each residue once).
fn outward(t: usize, n: usize) -> usize {
    if t % 2 == 1 {
        t.div_ceil(2)
    } else {
        (n - t / 2) % n
    }
}

/// Reflection in the line through `g` along the unit vector `d`.
struct Mirror {
    g: [f64; 2],
    d: [f64; 2],
}

impl Mirror {
    fn reflect(&self, x: f64, y: f64) -> [f64; 2] {
        let (g, d) = (self.g, self.d);
        let (dx, dy) = (x - g[0], y - g[1]);
        let t = dx * d[0] + dy * d[1];
        [g[0] + 2.0 * t * d[0] - dx, g[1] + 2.0 * t * d[1] - dy]
    }

    /// The largest distance from a reflected sample to the curve, relative to `size`:
    /// each reflected sample is projected onto the curve by Gauss–Newton on θ with the
    /// closed-form pose, from the nearest sample. Stops early once above `stop_above`.
    #[allow(clippy::too_many_arguments)]
    fn error<M: Mechanism>(
        &self,
        l: &M,
        circuit: Circuit,
        p: CouplerPoint,
        c: &Curve,
        tol: &FeatureTolerances,
        size: f64,
        stop_above: f64,
    ) -> f64 {
        let n = c.len();
        let consts = l.constants();
        let mut worst: f64 = 0.0;
        for k in 0..n {
            let r = self.reflect(c.x[k], c.y[k]);
            let near = (0..n)
                .min_by(|&a, &b| {
                    let da = (c.x[a] - r[0]).powi(2) + (c.y[a] - r[1]).powi(2);
                    let db = (c.x[b] - r[0]).powi(2) + (c.y[b] - r[1]).powi(2);
                    da.total_cmp(&db)
                })
                .unwrap_or(0);
            let mut t = near as f64 * tol.step_deg;
            let mut dist = f64::MAX;
            for _ in 0..40 {
                let Some((m, v)) = at(l, &consts, circuit, p, t) else {
                    break;
                };
                let e = [m[0] - r[0], m[1] - r[1]];
                dist = e[0].hypot(e[1]);
                let vv = v[0] * v[0] + v[1] * v[1];
                if dist <= 1e-3 * tol.symmetry_tol * size || vv == 0.0 {
                    break;
                }
                let dt = -(e[0] * v[0] + e[1] * v[1]) / vv;
                let dt = dt.clamp(-tol.step_deg.to_radians(), tol.step_deg.to_radians());
                if dt.abs() < 1e-16 {
                    break;
                }
                t += dt.to_degrees();
            }
            worst = worst.max(dist / size);
            if worst > stop_above {
                break;
            }
        }
        worst
    }
}

#[cfg(test)]
mod tests {
    use super::outward;

    #[test]
    fn outward_offsets_visit_every_sample_once() {
        for n in 1..40 {
            let mut seen: Vec<usize> = (0..n).map(|t| outward(t, n)).collect();
            assert_eq!(&seen[..n.min(3)], &[0, 1, n.saturating_sub(1)][..n.min(3)]);
            seen.sort();
            assert_eq!(seen, (0..n).collect::<Vec<_>>(), "{n}");
        }
    }
}
