//! Mirror symmetry of a coupler curve (docs/conventions.md §5).

use super::double_points::at;
use super::{FeatureTolerances, Symmetry};
use coupler_kinematics::{Circuit, CouplerPoint, Curve, Mechanism};

/// Finds an axis of mirror symmetry of a closed curve, if any.
///
/// An axis of symmetry passes through the curve's arc-length centroid G and is a principal
/// axis of its arc-length second moment (both are geometric: they do not depend on the
/// parametrisation). So each of the two principal axes is tried: every sample is reflected
/// in it; a coarse test (the nearest sample within ~a chord length) rejects most curves
/// cheaply; then each reflected point is projected onto the curve by Gauss–Newton on θ
/// with the closed-form pose, and the axis is accepted when the largest distance is at
/// most `symmetry_tol` × the curve's size (bounding-box diagonal). A circle (isotropic
/// moment) reports one of its axes. This finds the symmetric curves of docs/conventions.md §5
/// (A = B, M on the circle about Pb through Pa, axis through O4) and any other.
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
    let (x0, x1) =
        c.x.iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    let (y0, y1) =
        c.y.iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &y| (a.min(y), b.max(y)));
    let size = (x1 - x0).hypot(y1 - y0);
    let chords: Vec<f64> = (0..n)
        .map(|k| (c.x[(k + 1) % n] - c.x[k]).hypot(c.y[(k + 1) % n] - c.y[k]))
        .collect();
    let phi0 = 0.5 * libm::atan2(2.0 * ixy, ixx - iyy);
    for phi in [phi0, phi0 + std::f64::consts::FRAC_PI_2] {
        let d = [libm::cos(phi), libm::sin(phi)];
        let reflect = |x: f64, y: f64| {
            let (dx, dy) = (x - gx, y - gy);
            let t = dx * d[0] + dy * d[1];
            [gx + 2.0 * t * d[0] - dx, gy + 2.0 * t * d[1] - dy]
        };
        // Coarse: each reflected sample has a sample within about a chord length (squared
        // distances; samples visited in a stride so a miss shows early).
        // The mirror partner of M_k moves at M_k's speed, so the local chord bounds the gap.
        let coarse = (0..n).map(|i| (i * 37) % n).all(|k| {
            let thr = 0.75 * chords[k].max(chords[(k + n - 1) % n]) + 1e-9 * size;
            let thr2 = thr * thr;
            let r = reflect(c.x[k], c.y[k]);
            (0..n).any(|m| {
                let (dx, dy) = (c.x[m] - r[0], c.y[m] - r[1]);
                dx * dx + dy * dy <= thr2
            })
        });
        if !coarse {
            continue;
        }
        let nearest: Vec<usize> = (0..n)
            .map(|k| {
                let r = reflect(c.x[k], c.y[k]);
                (0..n)
                    .min_by(|&a, &b| {
                        let da = (c.x[a] - r[0]).powi(2) + (c.y[a] - r[1]).powi(2);
                        let db = (c.x[b] - r[0]).powi(2) + (c.y[b] - r[1]).powi(2);
                        da.total_cmp(&db)
                    })
                    .unwrap_or(0)
            })
            .collect();
        // Fine: project each reflected sample onto the curve.
        let mut worst: f64 = 0.0;
        for (k, &near) in nearest.iter().enumerate() {
            let r = reflect(c.x[k], c.y[k]);
            let mut t = near as f64 * tol.step_deg;
            let mut dist = f64::MAX;
            for _ in 0..40 {
                let Some((m, v)) = at(l, circuit, p, t) else {
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
            if worst > tol.symmetry_tol {
                break;
            }
        }
        if worst <= tol.symmetry_tol {
            let deg = phi.to_degrees().rem_euclid(180.0);
            return Some(Symmetry {
                point: [gx, gy],
                direction_deg: if deg >= 180.0 { 0.0 } else { deg },
                error: worst,
            });
        }
    }
    None
}
