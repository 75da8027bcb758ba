//! The longest straight run of an open sequence of samples (one branch of a full curve):
//! the straight segments' contract and search ([`crate::straight`]) on positions only, the
//! run moving one way along its fitted line step by step, longest by input travel. The
//! classic straight-line pages measure their runs with it (see [`crate::ClassicCurve`]).

use crate::straight::Track;
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

fn columns(points: &[Point2<f64>]) -> (Vec<f64>, Vec<f64>) {
    points.iter().map(|p| (p.x, p.y)).unzip()
}

/// Norton's ε_S with the line fitted by total least squares (the principal axis of the
/// points, [`crate::LineSums`]): Cx along it, Cy across; `ε_S = (max Cy − min Cy)/(max Cx
/// − min Cx)`. Also returns Δx and whether the points move one way along the line (every
/// step that moves at all has ΔCx > 0, the line oriented from the first point towards the
/// last). `None` for fewer than three points or Δx = 0.
pub fn straightness_fitted(points: &[Point2<f64>]) -> Option<(f64, f64, bool)> {
    if points.len() < 3 {
        return None;
    }
    let (x, y) = columns(points);
    let track = Track {
        x: &x,
        y: &y,
        periodic: false,
        velocity: None,
    };
    let f = track.measure(0, points.len() - 1)?;
    (f.extent > 0.0).then(|| (f.width / f.extent, f.extent, f.monotone))
}

/// The longest run of consecutive samples (at least 3) that moves one way along its
/// fitted line with `ε_S ≤ tolerance`, longest by input travel (`input_deg[k]` is the
/// input angle of sample k; the travel of a run sums |Δ input| over its steps); ties go to
/// the smaller ε_S, then the earlier start. Every run is considered (ε_S is not monotone
/// in a run's length), so no qualifying run is longer. For a closed branch pass the
/// samples once (a run does not wrap).
pub fn longest_straight_run(
    points: &[Point2<f64>],
    input_deg: &[f64],
    tolerance: f64,
) -> Option<StraightRun> {
    if points.len() < 3 || input_deg.len() != points.len() {
        return None;
    }
    let (x, y) = columns(points);
    let mut travel = vec![0.0; points.len()];
    let mut h_max: f64 = 0.0;
    for k in 1..points.len() {
        let h = (input_deg[k] - input_deg[k - 1]).abs();
        h_max = h_max.max(h);
        travel[k] = travel[k - 1] + h;
    }
    let track = Track {
        x: &x,
        y: &y,
        periodic: false,
        velocity: None,
    };
    let w = track
        .maximal(tolerance, |i, j| travel[j] - travel[i], h_max, 0.0, 1)
        .into_iter()
        .next()?;
    let f = track.measure(w.start, w.end)?;
    Some(StraightRun {
        start: w.start,
        len: w.end - w.start + 1,
        straightness: w.error,
        extent: f.extent,
    })
}
