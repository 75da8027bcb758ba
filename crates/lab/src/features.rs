//! Minimal feature measures used to chart how feature accuracy depends on sampling
//! density: Norton's straightness ε_S and a geometric circle fit. (The atlas's own
//! feature extraction lives elsewhere; these are kept small and independent.)

use nalgebra::{Matrix3, Point2, Vector3};

/// Norton's structural error in straightness along the x direction (docs/conventions.md §5, §8):
/// `ε_S = (max y − min y)/(max x − min x)` over the samples. `None` for fewer than two
/// samples or zero extent.
pub fn straightness_along_x(points: &[Point2<f64>]) -> Option<f64> {
    if points.len() < 2 {
        return None;
    }
    let (mut x0, mut x1, mut y0, mut y1) =
        (f64::INFINITY, -f64::INFINITY, f64::INFINITY, -f64::INFINITY);
    for p in points {
        x0 = x0.min(p.x);
        x1 = x1.max(p.x);
        y0 = y0.min(p.y);
        y1 = y1.max(p.y);
    }
    (x1 > x0).then(|| (y1 - y0) / (x1 - x0))
}

/// A circle fitted to points: centre, radius and the quality
/// `max |dist(M, centre) − R| / R` (docs/conventions.md §5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CircleFit {
    /// Centre.
    pub centre: Point2<f64>,
    /// Radius.
    pub radius: f64,
    /// Largest relative radial deviation of the points.
    pub deviation: f64,
}

/// Geometric circle fit: Gauss–Newton on `Σ (|p − c| − R)²`, started from Kåsa's algebraic
/// fit (`x² + y² + Dx + Ey + F = 0` by least squares), which alone is biased on short arcs.
/// `None` for fewer than 3 points or a degenerate (collinear) set.
pub fn fit_circle(points: &[Point2<f64>]) -> Option<CircleFit> {
    if points.len() < 3 {
        return None;
    }
    // Kåsa: normal equations for (D, E, F), centred for conditioning.
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.x / n, b + p.y / n));
    let mut m = Matrix3::zeros();
    let mut r = Vector3::zeros();
    for p in points {
        let (x, y) = (p.x - mx, p.y - my);
        let row = Vector3::new(x, y, 1.0);
        m += row * row.transpose();
        r -= row * (x * x + y * y);
    }
    let sol = m.lu().solve(&r)?;
    let (mut cx, mut cy) = (-0.5 * sol[0], -0.5 * sol[1]);
    let mut rad = (cx * cx + cy * cy - sol[2]).sqrt();
    if !rad.is_finite() {
        return None;
    }
    for _ in 0..50 {
        let mut jtj = Matrix3::zeros();
        let mut jtr = Vector3::zeros();
        for p in points {
            let (dx, dy) = (p.x - mx - cx, p.y - my - cy);
            let dist = dx.hypot(dy);
            if dist == 0.0 {
                return None;
            }
            let j = Vector3::new(-dx / dist, -dy / dist, -1.0);
            let res = dist - rad;
            jtj += j * j.transpose();
            jtr += j * res;
        }
        let step = jtj.lu().solve(&(-jtr))?;
        cx += step[0];
        cy += step[1];
        rad += step[2];
        if step.norm() <= 1e-15 * (1.0 + rad) {
            break;
        }
    }
    let centre = Point2::new(cx + mx, cy + my);
    let deviation = points
        .iter()
        .map(|p| ((p - centre).norm() - rad).abs() / rad)
        .fold(0.0, f64::max);
    Some(CircleFit {
        centre,
        radius: rad,
        deviation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn circle_fit_recovers_a_short_arc() {
        let pts: Vec<_> = (0..20)
            .map(|k| {
                let t = 0.3 + 0.01 * k as f64;
                Point2::new(2.0 + 5.0 * libm::cos(t), -1.0 + 5.0 * libm::sin(t))
            })
            .collect();
        let f = fit_circle(&pts).unwrap();
        assert!((f.radius - 5.0).abs() < 1e-9, "{f:?}");
        assert!((f.centre - Point2::new(2.0, -1.0)).norm() < 1e-9);
        assert!(f.deviation < 1e-12);
    }

    #[test]
    fn straightness_of_a_line_is_zero() {
        let pts: Vec<_> = (0..5).map(|k| Point2::new(k as f64, 3.0)).collect();
        assert_eq!(straightness_along_x(&pts), Some(0.0));
    }
}
