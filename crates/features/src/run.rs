//! The longest straight run of an open sequence of samples (one branch of a full curve):
//! Norton's ε_S against the total-least-squares line, grown sample by sample. The classic
//! straight-line pages measure their runs with it (see [`crate::ClassicCurve`]).

use nalgebra::Point2;

/// A straight run found on a sampled polyline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StraightRun {
    /// Index of the first sample.
    pub start: usize,
    /// Number of samples.
    pub len: usize,
    /// ε_S over the run, the line fitted by total least squares (principal axis).
    pub straightness: f64,
    /// Extent Δx along the line.
    pub extent: f64,
}

/// Norton's ε_S with the line fitted by total least squares (the principal axis of the
/// points): Cx along it, Cy across; `ε_S = (max Cy − min Cy)/(max Cx − min Cx)`. Also
/// returns Δx and whether Cx moves one way (monotone) along the samples.
pub fn straightness_fitted(points: &[Point2<f64>]) -> Option<(f64, f64, bool)> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.x / n, b + p.y / n));
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in points {
        let (x, y) = (p.x - mx, p.y - my);
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
    }
    let phi = 0.5 * libm::atan2(2.0 * sxy, sxx - syy);
    let (s, c) = (libm::sin(phi), libm::cos(phi));
    let (mut x0, mut x1, mut y0, mut y1) =
        (f64::INFINITY, -f64::INFINITY, f64::INFINITY, -f64::INFINITY);
    let mut dir = 0.0f64;
    let mut monotone = true;
    let mut prev: Option<f64> = None;
    for p in points {
        let (x, y) = (p.x - mx, p.y - my);
        let (cx, cy) = (c * x + s * y, -s * x + c * y);
        if let Some(q) = prev {
            let d = cx - q;
            if dir == 0.0 {
                dir = d.signum();
            } else if d * dir < 0.0 {
                monotone = false;
            }
        }
        prev = Some(cx);
        x0 = x0.min(cx);
        x1 = x1.max(cx);
        y0 = y0.min(cy);
        y1 = y1.max(cy);
    }
    (x1 > x0).then(|| ((y1 - y0) / (x1 - x0), x1 - x0, monotone))
}

/// The longest run of consecutive samples (at least 3) that moves one way along its
/// fitted line with `ε_S ≤ tolerance`; ties go to the smaller ε_S. For a closed branch
/// pass the samples once (a run does not wrap).
pub fn longest_straight_run(points: &[Point2<f64>], tolerance: f64) -> Option<StraightRun> {
    let mut best: Option<StraightRun> = None;
    for start in 0..points.len() {
        let mut len = 3;
        let mut last: Option<StraightRun> = None;
        while start + len <= points.len() {
            match straightness_fitted(&points[start..start + len]) {
                Some((eps, extent, true)) if eps <= tolerance => {
                    last = Some(StraightRun {
                        start,
                        len,
                        straightness: eps,
                        extent,
                    });
                    len += 1;
                }
                _ => break,
            }
        }
        if let Some(run) = last {
            let better = match best {
                None => true,
                Some(b) => {
                    run.len > b.len || (run.len == b.len && run.straightness < b.straightness)
                }
            };
            if better {
                best = Some(run);
            }
        }
    }
    best
}
