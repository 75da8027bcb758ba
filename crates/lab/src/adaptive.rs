//! Adaptive sampling of a coupler curve: model no more than the scene needs. The crank
//! interval is bisected where the drawn chord strays from the curve by more than a
//! tolerance (for pages: a fraction of a pixel; for the index: the feature tolerance),
//! and left coarse where it does not.

use coupler_kinematics::{Circuit, CouplerPoint, FourBar};
use coupler_kinematics::{CrankAngle, Pose, ToggleGaps};
use nalgebra::{Point2, Vector2};

/// Settings for [`AdaptiveSampling::angles`], with one named default
/// ([`AdaptiveSampling::DEFAULT`]) apart from the tolerance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveSampling {
    /// Largest allowed distance between the curve and its chord (curve units: crank
    /// lengths). Pages: e.g. 0.1 px divided by the page's pixels per crank length.
    pub tolerance: f64,
    /// Every multiple of this angle (degrees) is a sample: the dash boundaries, so that
    /// dashes start and end on samples (default 10°, one dash).
    pub base_step_deg: f64,
    /// Also bisect where the tangent turns by more than this between the ends (degrees,
    /// default 30°): guards against a chord whose midpoint happens to lie on the curve.
    pub max_turn_deg: f64,
    /// Never bisect below this step (degrees, default 1e-6°).
    pub min_step_deg: f64,
}

impl AdaptiveSampling {
    /// Defaults with tolerance 1e-3 crank lengths.
    pub const DEFAULT: AdaptiveSampling = AdaptiveSampling {
        tolerance: 1e-3,
        base_step_deg: 10.0,
        max_turn_deg: 30.0,
        min_step_deg: 1e-6,
    };

    /// For a page: chord error below `fraction` of a pixel when the curve is drawn at
    /// `pixels_per_unit` pixels per crank length (e.g. 0.1 px at 150 px per unit:
    /// tolerance 6.7e-4).
    ///
    /// ```
    /// let s = coupler_lab::AdaptiveSampling::for_page(150.0, 0.1);
    /// assert!((s.tolerance - 0.1 / 150.0).abs() < 1e-18);
    /// ```
    pub fn for_page(pixels_per_unit: f64, fraction: f64) -> AdaptiveSampling {
        AdaptiveSampling::with_tolerance(fraction / pixels_per_unit)
    }

    /// The defaults with another tolerance.
    pub fn with_tolerance(tolerance: f64) -> AdaptiveSampling {
        AdaptiveSampling {
            tolerance,
            ..AdaptiveSampling::DEFAULT
        }
    }

    /// Crank angles (degrees, ascending, in `[0, 360]`, both ends included so the
    /// polyline closes) such that every chord between consecutive samples stays within
    /// `tolerance` of the curve at its midpoint angle and turns by at most
    /// `max_turn_deg` (an interval whose midpoint strays by `dev` is split into
    /// `⌈√(dev/tol)⌉` equal parts, as chord error falls like the step squared). Also
    /// returns the number of poses evaluated (samples plus rejected midpoints), the honest
    /// measure of cost. Intervals where the linkage does not
    /// assemble are not refined.
    ///
    /// ```
    /// use coupler_kinematics::{FourBar, Circuit, CouplerPoint};
    /// use coupler_lab::AdaptiveSampling;
    /// let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
    /// let (angles, _) = AdaptiveSampling::with_tolerance(1e-4).angles(&l, Circuit::Open, CouplerPoint::new(1.0, 0.5));
    /// assert!(angles.len() > 37 && angles.len() < 3600);
    /// ```
    pub fn angles(&self, l: &FourBar, circuit: Circuit, p: CouplerPoint) -> (Vec<f64>, usize) {
        let gaps = ToggleGaps::of(l);
        let eval = |deg: f64| -> Option<(Point2<f64>, Vector2<f64>)> {
            Pose::solve_with(l, &gaps, circuit, &CrankAngle::from_degrees(deg))
                .map(|pose| (pose.point(p), pose.velocity(p)))
        };
        let n = (360.0 / self.base_step_deg).round().max(1.0) as usize;
        let base: Vec<f64> = (0..=n).map(|k| k as f64 * 360.0 / n as f64).collect();
        let mut out = vec![base[0]];
        let mut evals = base.len();
        let cos_turn = libm::cos(self.max_turn_deg.to_radians());
        for w in base.windows(2) {
            // Depth-first bisection with an explicit stack, emitting samples in order.
            let mut stack = vec![(w[0], w[1], eval(w[0]), eval(w[1]))];
            while let Some((a, b, ea, eb)) = stack.pop() {
                let split = match (ea, eb) {
                    (Some((pa, va)), Some((pb, vb))) if b - a > self.min_step_deg => {
                        let mid = 0.5 * (a + b);
                        evals += 1;
                        match eval(mid) {
                            Some((pm, _)) => {
                                let chord = pb - pa;
                                let len2 = chord.norm_squared();
                                let dev = if len2 > 0.0 {
                                    let t = ((pm - pa).dot(&chord) / len2).clamp(0.0, 1.0);
                                    (pm - (pa + chord * t)).norm()
                                } else {
                                    (pm - pa).norm()
                                };
                                let (na, nb) = (va.norm(), vb.norm());
                                let measurable =
                                    na > 0.0 && nb > 0.0 && na.is_finite() && nb.is_finite();
                                let turn_ok = !measurable || va.dot(&vb) >= cos_turn * na * nb;
                                // Chord error falls like step²: split into as many equal
                                // parts as that predicts (2 … 16), not blindly in two.
                                let parts = if dev > self.tolerance {
                                    libm::ceil(libm::sqrt(dev / self.tolerance)).clamp(2.0, 16.0)
                                        as usize
                                } else {
                                    2
                                };
                                (dev > self.tolerance || !turn_ok).then_some(parts)
                            }
                            None => None,
                        }
                    }
                    _ => None,
                };
                match split {
                    Some(parts) => {
                        // Push the rightmost part first so the left is processed first.
                        let cut = |i: usize| {
                            if i == parts {
                                b
                            } else {
                                a + (b - a) * i as f64 / parts as f64
                            }
                        };
                        let mut right = (b, eb);
                        for i in (0..parts).rev() {
                            let t = cut(i);
                            let et = if i == 0 {
                                ea
                            } else {
                                evals += 1;
                                eval(t)
                            };
                            stack.push((t, right.0, et, right.1));
                            right = (t, et);
                        }
                    }
                    None => out.push(b),
                }
            }
        }
        (out, evals)
    }
}

/// Where [`chord_error`] looks inside each interval: the quarters and midpoint, and points
/// clustered geometrically towards both ends, where a fold sampled exactly (θ = 0 or 180°
/// of a linkage near a change point) makes the curve race away from the sample.
pub const CHECK_FRACTIONS: [f64; 11] = [
    1e-4, 1e-3, 1e-2, 0.1, 0.25, 0.5, 0.75, 0.9, 0.99, 0.999, 0.9999,
];

/// The largest distance between the curve (the shipped closed form, at the
/// [`CHECK_FRACTIONS`] of each interval) and the chord drawn between consecutive samples
/// of `degrees`: the error of the curve as drawn by a polyline. Intervals that do not
/// assemble are skipped. A feature narrower than the check spacing in the middle of an
/// interval can still be missed (a measurement, not a proof).
pub fn chord_error(l: &FourBar, circuit: Circuit, p: CouplerPoint, degrees: &[f64]) -> f64 {
    let gaps = ToggleGaps::of(l);
    let at = |deg: f64| {
        Pose::solve_with(l, &gaps, circuit, &CrankAngle::from_degrees(deg))
            .map(|pose| pose.point(p))
    };
    let pts: Vec<Option<Point2<f64>>> = degrees.iter().map(|&d| at(d)).collect();
    let mut worst = 0.0f64;
    for k in 0..degrees.len().saturating_sub(1) {
        let (Some(a), Some(b)) = (pts[k], pts[k + 1]) else {
            continue;
        };
        let chord = b - a;
        let len2 = chord.norm_squared();
        for f in CHECK_FRACTIONS {
            let Some(m) = at(degrees[k] + f * (degrees[k + 1] - degrees[k])) else {
                continue;
            };
            let t = if len2 > 0.0 {
                ((m - a).dot(&chord) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            worst = worst.max((m - (a + chord * t)).norm());
        }
    }
    worst
}

/// `36·n + 1` angles `k·10°/n`, k = 0 … 36n (360° included, closing the polyline).
pub fn uniform_closed(samples_per_dash: usize) -> Vec<f64> {
    let n = samples_per_dash.max(1);
    (0..=36 * n).map(|k| k as f64 * 10.0 / n as f64).collect()
}

/// The fewest samples per 10° dash for which uniform sampling has chord error at most
/// `target` (searched up to `max_per_dash`; `None` if even that is not enough).
pub fn uniform_density_for(
    l: &FourBar,
    circuit: Circuit,
    p: CouplerPoint,
    target: f64,
    max_per_dash: usize,
) -> Option<usize> {
    let ok = |n: usize| chord_error(l, circuit, p, &uniform_closed(n)) <= target;
    let mut hi = 1;
    while !ok(hi) {
        if hi >= max_per_dash {
            return None;
        }
        hi = (hi * 2).min(max_per_dash);
    }
    let mut lo = hi / 2; // fails (or 0)
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if ok(mid) { hi = mid } else { lo = mid }
    }
    Some(hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adaptive_meets_its_tolerance_with_fewer_samples() {
        let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
        let p = CouplerPoint::new(1.2, -0.7);
        for tol in [1e-3, 1e-5] {
            let (angles, _) = AdaptiveSampling::with_tolerance(tol).angles(&l, Circuit::Open, p);
            assert!(angles.windows(2).all(|w| w[0] < w[1]));
            assert_eq!((angles[0], *angles.last().unwrap()), (0.0, 360.0));
            for k in 0..=36 {
                assert!(
                    angles.contains(&(k as f64 * 10.0)),
                    "dash boundary {k} missing"
                );
            }
            let err = chord_error(&l, Circuit::Open, p, &angles);
            assert!(err <= 2.0 * tol, "tol {tol}: chord error {err}");
            // On a smooth ordinary curve adaptive is no worse than uniform at equal
            // tolerance (the dash boundaries and whole parts cost a little)...
            let n = uniform_density_for(&l, Circuit::Open, p, tol, 4096).unwrap();
            assert!(
                angles.len() as f64 <= 1.1 * (36 * n + 1) as f64,
                "adaptive {} vs uniform {}",
                angles.len(),
                36 * n + 1
            );
        }
        // ... and far better near a change point, where the point races through the fold.
        let l = FourBar::new(3.0, 2.0, 2.0 + 1e-6).unwrap();
        let p = CouplerPoint::new(1.0, 1.0);
        let (angles, _) = AdaptiveSampling::with_tolerance(1e-4).angles(&l, Circuit::Open, p);
        assert!(chord_error(&l, Circuit::Open, p, &angles) <= 2e-4);
        let n = uniform_density_for(&l, Circuit::Open, p, 1e-4, 1 << 16).unwrap();
        assert!(
            angles.len() * 10 < 36 * n,
            "adaptive {} vs uniform {}",
            angles.len(),
            36 * n + 1
        );
    }
}
