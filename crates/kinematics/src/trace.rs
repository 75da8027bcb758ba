//! Driving any four-bar: the input's limits (toggle angles) and the complete coupler curve,
//! traced across toggles by changing circuit there (docs/conventions.md §7). Pure: no I/O.
//!
//! The input link (length 1, pivot O2) turns fully only for cranks. Otherwise it rocks
//! between toggles, where the coupler and rocker fold flat (`d = A + B`, extended, or
//! `d = |A − B|`, folded) and both circuits meet; the motion continues on the other circuit
//! back to the other limit. One pass out on one circuit and back on the other is a closed
//! branch of the coupler curve.

use crate::linkage::{Circuit, CouplerPoint, FourBar};
use crate::pose::{CrankAngle, Pose, TOGGLE_ULPS, ToggleGaps};
use nalgebra::{Point2, Vector2};
use serde::Serialize;

/// Which thin factor vanishes at a toggle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ToggleKind {
    /// `d = A + B`: coupler and rocker extended in line (`P = (A+B)² − d² = 0`).
    Extended,
    /// `d = |A − B|`: coupler and rocker folded over each other (`Q = d² − (A−B)² = 0`).
    Folded,
}

/// A toggle of the input: its angle (degrees) and kind.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Toggle {
    /// Input angle θ in degrees.
    pub degrees: f64,
    /// Which factor vanishes.
    pub kind: ToggleKind,
}

/// Where the input can go.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum InputRange {
    /// The input turns fully (a crank): every θ assembles.
    Full,
    /// The input rocks within each interval `[lo, hi]` (degrees, `lo < hi`, `lo` may be
    /// negative), bounded by toggles. A Grashof linkage whose input is not the shortest
    /// link has two, one per branch; a non-Grashof linkage has one.
    Rocks {
        /// `(lower toggle, upper toggle)` per interval.
        intervals: Vec<(Toggle, Toggle)>,
    },
    /// The linkage cannot be assembled at any input angle.
    Never,
}

/// The thin factors `P = (A+B)² − d²` and `Q = d² − (A−B)²` at θ, unrounded to zero,
/// formed as in [`Pose::solve`] from the exact gaps and the half-angle.
fn factors(l: &FourBar, gaps: &ToggleGaps, t: &CrankAngle) -> (f64, f64, f64, f64) {
    let c = l.ground;
    let (sh2, ch2) = (t.sin_half * t.sin_half, t.cos_half * t.cos_half);
    (
        gaps.outer + 4.0 * c * ch2,
        gaps.outer_scale + 4.0 * c * ch2,
        gaps.inner + 4.0 * c * sh2,
        gaps.inner_scale + 4.0 * c * sh2,
    )
}

/// Next float away from `x` in direction `dir` (±1).
fn next_float(x: f64, dir: f64) -> f64 {
    if x == 0.0 {
        return dir * f64::from_bits(1);
    }
    let bits = x.to_bits();
    let up = (dir > 0.0) == (x > 0.0);
    f64::from_bits(if up { bits + 1 } else { bits - 1 })
}

/// Refines an estimated toggle angle to the float nearest it at which the vanishing
/// factor, as [`Pose::solve`] computes it, lies in `[−tol, 0]`: the pose there is exactly
/// flat (h = 0), so both circuits give the same position. Where one ulp of θ moves the
/// factor by more than that window, it returns the last angle that still assembles (the
/// circuits then differ by h ~ √ε; [`trace_full`] uses the flat pose there).
/// `outward` (±1) is the direction in θ leaving the assembled interval.
fn refine_toggle(
    l: &FourBar,
    gaps: &ToggleGaps,
    estimate: f64,
    kind: ToggleKind,
    outward: f64,
) -> f64 {
    let value = |deg: f64| {
        let (p, ps, q, qs) = factors(l, gaps, &CrankAngle::from_degrees(deg));
        let (x, scale) = match kind {
            ToggleKind::Extended => (p, ps),
            ToggleKind::Folded => (q, qs),
        };
        (x, TOGGLE_ULPS * f64::EPSILON * scale)
    };
    let ok = |deg: f64| {
        let (x, tol) = value(deg);
        (-tol..=0.0).contains(&x)
    };
    if ok(estimate) {
        return estimate;
    }
    // Walk in the direction that brings the factor towards [−tol, 0].
    let (x0, _) = value(estimate);
    let dir = if x0 > 0.0 { outward } else { -outward };
    let mut deg = estimate;
    for _ in 0..4096 {
        deg = next_float(deg, dir);
        if ok(deg) {
            return deg;
        }
        let (x, _) = value(deg);
        if (x > 0.0) != (x0 > 0.0) {
            break; // stepped over the window: keep the last flat-or-inside angle below
        }
    }
    // The factor jumps over the window (steep): take the last angle that still assembles,
    // the one before the step out if we started inside, the current one if we came in.
    if x0 > 0.0 { next_float(deg, -dir) } else { deg }
}

/// The input's range: toggle angles from `d = A + B` or `d = |A − B|`, i.e.
/// `sin²(θ/2) = −[(C−1)² − (A−B)²]/(4C)` (folded) and
/// `cos²(θ/2) = −[(A+B)² − (C+1)²]/(4C)` (extended), using
/// `d² = (C−1)² + 4C·sin²(θ/2) = (C+1)² − 4C·cos²(θ/2)`; the brackets are the exact
/// [`ToggleGaps`]. Each toggle is then refined to the float where the shipped closed form
/// sees an exactly flat triangle.
///
/// ```
/// use coupler_kinematics::{FourBar, input_range, InputRange};
/// // A crank-rocker turns fully; Watt's linkage (a triple rocker) rocks.
/// assert_eq!(input_range(&FourBar::new(2.5, 3.0, 3.5).unwrap()), InputRange::Full);
/// let watt = FourBar::new(1.0, 1.0, 5f64.sqrt()).unwrap();
/// assert!(matches!(input_range(&watt), InputRange::Rocks { ref intervals } if intervals.len() == 1));
/// ```
pub fn input_range(l: &FourBar) -> InputRange {
    let gaps = ToggleGaps::of(l);
    let c = l.ground;
    let s2_lo = (-gaps.inner / (4.0 * c)).max(0.0); // sin²(θ/2) ≥ this
    let s2_hi = (1.0 + gaps.outer / (4.0 * c)).min(1.0); // sin²(θ/2) ≤ this
    if s2_lo > s2_hi {
        return InputRange::Never;
    }
    let folded = s2_lo > 0.0;
    let extended = s2_hi < 1.0;
    // θ = 2·asin(√s²) = 2·acos(√c²): whichever of s², c² is smaller keeps its digits.
    let angle = |s2: f64, c2: f64| {
        if s2 <= c2 {
            2.0 * libm::asin(s2.sqrt()).to_degrees()
        } else {
            2.0 * libm::acos(c2.sqrt()).to_degrees()
        }
    };
    let t_fold = angle(s2_lo, (1.0 + gaps.inner / (4.0 * c)).max(0.0));
    let t_ext = angle(s2_hi, (-gaps.outer / (4.0 * c)).max(0.0)).clamp(t_fold, 180.0);
    let fold = |deg: f64, outward: f64| Toggle {
        degrees: refine_toggle(l, &gaps, deg, ToggleKind::Folded, outward),
        kind: ToggleKind::Folded,
    };
    let ext = |deg: f64, outward: f64| Toggle {
        degrees: refine_toggle(l, &gaps, deg, ToggleKind::Extended, outward),
        kind: ToggleKind::Extended,
    };
    match (folded, extended) {
        (false, false) => InputRange::Full,
        (false, true) => InputRange::Rocks {
            intervals: vec![(ext(-t_ext, -1.0), ext(t_ext, 1.0))],
        },
        (true, false) => InputRange::Rocks {
            intervals: vec![(fold(t_fold, -1.0), fold(360.0 - t_fold, 1.0))],
        },
        (true, true) => InputRange::Rocks {
            intervals: vec![
                (fold(t_fold, -1.0), ext(t_ext, 1.0)),
                (ext(360.0 - t_ext, -1.0), fold(360.0 - t_fold, 1.0)),
            ],
        },
    }
}

/// One sample of a traced branch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceSample {
    /// Input angle θ (degrees).
    pub degrees: f64,
    /// The circuit the linkage is on (at a toggle: the one it arrives on).
    pub circuit: Circuit,
    /// The coupler point.
    pub point: Point2<f64>,
    /// Its velocity for unit input speed (infinite at a toggle: not finite there).
    pub velocity: Vector2<f64>,
    /// Transmission angle μ (radians).
    pub transmission: f64,
    /// True at a toggle (where the circuit changes).
    pub toggle: bool,
}

/// A closed branch of the coupler curve: the samples in the order the linkage moves
/// through them; the last sample repeats the first (same angle and position), so the
/// polyline closes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Branch {
    /// Samples in order of motion.
    pub samples: Vec<TraceSample>,
}

impl Branch {
    /// The positions.
    pub fn points(&self) -> Vec<Point2<f64>> {
        self.samples.iter().map(|s| s.point).collect()
    }
}

/// The complete coupler curve of a four-bar driven by its input: every branch.
#[derive(Clone, Debug, PartialEq)]
pub struct FullCurve {
    /// The input's range.
    pub range: InputRange,
    /// The branches: for a crank, one per circuit; for a rocking input, one per
    /// interval, out on the open circuit and back on the crossed one.
    pub branches: Vec<Branch>,
}

fn sample(
    l: &FourBar,
    gaps: &ToggleGaps,
    c: Circuit,
    p: CouplerPoint,
    deg: f64,
    toggle: bool,
) -> Option<TraceSample> {
    let angle = CrankAngle::from_degrees(deg);
    let pose = Pose::solve_with(l, gaps, c, &angle)?;
    if toggle {
        let other = Pose::solve_with(l, gaps, c.other(), &angle)?;
        return Some(toggle_sample(
            deg,
            c,
            p,
            pose.crank_pin,
            [pose.coupler_dir, other.coupler_dir],
            pose.transmission,
        ));
    }
    Some(TraceSample {
        degrees: deg,
        circuit: c,
        point: pose.point(p),
        velocity: pose.velocity(p),
        transmission: pose.transmission,
        toggle,
    })
}

/// The sample at a toggle: the flat pose, the same for both circuits. Where the refined
/// angle could not make the thin factor exactly zero (it changes by more than its rounding
/// window per ulp of θ), the circuits differ by h ~ √ε there; the coupler direction is
/// then taken along the chord's foot, e = (e_this + e_other)/|…| (the directions of the
/// body carrying the point on the two circuits), which is the flat pose to that same √ε.
/// Shared by the four-bar's and the geared five-bar's full traces.
pub(crate) fn toggle_sample(
    deg: f64,
    circuit: Circuit,
    p: CouplerPoint,
    pa: Point2<f64>,
    [e_this, e_other]: [Vector2<f64>; 2],
    transmission: f64,
) -> TraceSample {
    let sum = e_this + e_other;
    let e = if sum.norm() > 0.0 {
        sum / sum.norm()
    } else {
        e_this
    };
    let point = Point2::new(pa.x + p.u * e.x - p.v * e.y, pa.y + p.u * e.y + p.v * e.x);
    let flat = if transmission > std::f64::consts::FRAC_PI_2 {
        std::f64::consts::PI
    } else {
        0.0
    };
    TraceSample {
        degrees: deg,
        circuit,
        point,
        velocity: Vector2::new(f64::INFINITY, f64::INFINITY),
        transmission: flat,
        toggle: true,
    }
}

/// Grid angles `k·step` strictly inside `(lo, hi)`, ascending.
pub(crate) fn grid_inside(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let mut k = (lo / step).floor() as i64 + 1;
    let mut v = Vec::new();
    while (k as f64) * step < hi {
        let t = k as f64 * step;
        if t > lo {
            v.push(t);
        }
        k += 1;
    }
    v
}

/// Traces the complete coupler curve of `point`, sampling the input at the multiples of
/// `step_deg` (degrees) inside its range plus every toggle. A crank gives one closed
/// branch per circuit (0 ≤ θ < 360, closed by repeating θ = 0); a rocking input gives,
/// per interval, the branch from the lower toggle to the upper one on the open circuit and
/// back on the crossed one: at each toggle the pose is exactly flat, so the change of
/// circuit is continuous and the branch closes exactly (first and last samples equal).
/// `step_deg` must be positive and finite (else no branch).
///
/// ```
/// use coupler_kinematics::{FourBar, CouplerPoint, trace_full};
/// let watt = FourBar::new(1.0, 1.0, 5f64.sqrt()).unwrap();
/// let full = trace_full(&watt, CouplerPoint::new(0.5, 0.0), 1.0);
/// let b = &full.branches[0];
/// assert_eq!(b.samples.first().unwrap().point, b.samples.last().unwrap().point);
/// ```
pub fn trace_full(l: &FourBar, p: CouplerPoint, step_deg: f64) -> FullCurve {
    let range = input_range(l);
    let gaps = ToggleGaps::of(l);
    let mut branches = Vec::new();
    if !(step_deg.is_finite() && step_deg > 0.0) {
        return FullCurve { range, branches };
    }
    match &range {
        InputRange::Never => {}
        InputRange::Full => {
            for c in [Circuit::Open, Circuit::Crossed] {
                let mut angles = vec![0.0];
                angles.extend(grid_inside(0.0, 360.0, step_deg));
                angles.push(360.0);
                let samples = angles
                    .iter()
                    .filter_map(|&d| sample(l, &gaps, c, p, d, false))
                    .collect();
                branches.push(Branch { samples });
            }
        }
        InputRange::Rocks { intervals } => {
            for (lo, hi) in intervals {
                let inside = grid_inside(lo.degrees, hi.degrees, step_deg);
                let mut samples = Vec::with_capacity(2 * inside.len() + 3);
                let open = Circuit::Open;
                let crossed = Circuit::Crossed;
                samples.extend(sample(l, &gaps, crossed, p, lo.degrees, true));
                samples.extend(
                    inside
                        .iter()
                        .filter_map(|&d| sample(l, &gaps, open, p, d, false)),
                );
                samples.extend(sample(l, &gaps, open, p, hi.degrees, true));
                samples.extend(
                    inside
                        .iter()
                        .rev()
                        .filter_map(|&d| sample(l, &gaps, crossed, p, d, false)),
                );
                samples.extend(sample(l, &gaps, crossed, p, lo.degrees, true));
                branches.push(Branch { samples });
            }
        }
    }
    FullCurve { range, branches }
}

/// Intersections of circle(c1, r1) and circle(c2, r2) (0, 1 or 2 points); for tests of
/// curve membership by inverse kinematics.
pub fn circle_intersections(
    c1: Point2<f64>,
    r1: f64,
    c2: Point2<f64>,
    r2: f64,
) -> Vec<Point2<f64>> {
    let w = c2 - c1;
    let d = w.norm();
    if d == 0.0 {
        return Vec::new();
    }
    let Some(area2) = crate::pose::kahan_double_area(r1, r2, d) else {
        return Vec::new();
    };
    let h = area2 / d;
    let a = ((r1 - r2) * (r1 + r2) + d * d) / (2.0 * d);
    let base = c1 + w * (a / d);
    let jw = Vector2::new(-w.y, w.x) * (h / d);
    vec![base + jw, base - jw]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn watt() -> FourBar {
        FourBar::new(1.0, 1.0, 5f64.sqrt()).unwrap()
    }

    /// Chebyshev (docs/conventions.md §7): ground 2, rockers 2.5, coupler 1, point at the coupler's
    /// midpoint; in crank units (input rocker = 1): A = 0.4, B = 1, C = 0.8, (u, v) = (0.2, 0).
    fn chebyshev() -> (FourBar, CouplerPoint) {
        (
            FourBar::new(0.4, 1.0, 0.8).unwrap(),
            CouplerPoint::new(0.2, 0.0),
        )
    }

    fn assert_closes_and_is_continuous(
        full: &FullCurve,
        l: &FourBar,
        p: CouplerPoint,
        max_chord: f64,
    ) {
        assert!(!full.branches.is_empty());
        let gaps = ToggleGaps::of(l);
        for b in &full.branches {
            let (first, last) = (b.samples.first().unwrap(), b.samples.last().unwrap());
            assert!(
                (first.point - last.point).norm() <= 1e-12,
                "branch does not close"
            );
            for w in b.samples.windows(2) {
                let gap = (w[1].point - w[0].point).norm();
                assert!(
                    gap < max_chord,
                    "jump of {gap} between {:?} and {:?}",
                    w[0],
                    w[1]
                );
            }
            for s in b.samples.iter().filter(|s| s.toggle) {
                // Both circuits meet at the toggle, to the last bit.
                let t = CrankAngle::from_degrees(s.degrees);
                let o = Pose::solve_with(l, &gaps, Circuit::Open, &t)
                    .unwrap()
                    .point(p);
                let c = Pose::solve_with(l, &gaps, Circuit::Crossed, &t)
                    .unwrap()
                    .point(p);
                assert!(
                    (o - c).norm() <= 1e-12,
                    "circuits differ by {} at toggle {}",
                    (o - c).norm(),
                    s.degrees
                );
            }
        }
    }

    #[test]
    fn watt_rocks_between_two_extended_toggles_and_closes() {
        let l = watt();
        let InputRange::Rocks { intervals } = input_range(&l) else {
            panic!("Watt rocks")
        };
        assert_eq!(intervals.len(), 1);
        let (lo, hi) = intervals[0];
        assert_eq!(
            (lo.kind, hi.kind),
            (ToggleKind::Extended, ToggleKind::Extended)
        );
        // d = A + B = 2 at cos θ = (1 + 5 − 4)/(2√5).
        let expect = libm::acos(2.0 / (2.0 * 5f64.sqrt())).to_degrees();
        assert!(
            (hi.degrees - expect).abs() < 1e-12 && (lo.degrees + expect).abs() < 1e-12,
            "{hi:?} {expect}"
        );
        let p = CouplerPoint::new(0.5, 0.0);
        let full = trace_full(&l, p, 1.0);
        assert_eq!(full.branches.len(), 1);
        assert_closes_and_is_continuous(&full, &l, p, 0.2);
    }

    #[test]
    fn chebyshev_has_two_branches_each_closed() {
        let (l, p) = chebyshev();
        let InputRange::Rocks { intervals } = input_range(&l) else {
            panic!("Chebyshev rocks")
        };
        assert_eq!(intervals.len(), 2);
        // cos θ = (1 + C² − d²)/(2C): d = 0.6 → 36.87°, d = 1.4 → 101.54°.
        assert!((intervals[0].0.degrees - libm::acos(0.8).to_degrees()).abs() < 1e-12);
        assert!((intervals[0].1.degrees - libm::acos(-0.2).to_degrees()).abs() < 1e-12);
        let full = trace_full(&l, p, 0.5);
        assert_eq!(full.branches.len(), 2);
        assert_closes_and_is_continuous(&full, &l, p, 0.2);
    }

    /// Chebyshev and Hoeken are cognates (docs/conventions.md §7): by Roberts–Chebyshev, Hoeken's
    /// (crank 1, ground 2, coupler = rocker = 2.5, M at 5 along the coupler) has third
    /// pivot O_C = C·(u + iv)/A = (4, 0), and its cognate on O2 and O_C is a Chebyshev
    /// linkage twice the size (ground 4, rockers 5, coupler 2, M at the midpoint). So the
    /// Chebyshev frame (input rocker = 1) is placed by scaling by 5 with its input pivot at
    /// O2. Then every point of one curve lies on the other (checked by inverse kinematics:
    /// exact membership, not distance to a sampled polyline).
    #[test]
    fn chebyshev_and_hoeken_trace_the_same_curve() {
        let hoeken = FourBar::new(2.5, 2.5, 2.0).unwrap();
        let hp = CouplerPoint::new(5.0, 0.0);
        let (cheb, cp) = chebyshev();
        let place = |m: Point2<f64>| Point2::from(5.0 * m.coords);
        // On Chebyshev's curve (in Hoeken's frame): R1 on circle(O2, 5), R2 = 2M − R1
        // on circle(O_C, 5), |R1 − R2| = 2.
        let on_chebyshev = |m: Point2<f64>| {
            circle_intersections(m, 1.0, Point2::origin(), 5.0)
                .into_iter()
                .map(|r1| {
                    let r2 = Point2::from(2.0 * m.coords - r1.coords);
                    ((r2 - Point2::new(4.0, 0.0)).norm() - 5.0).abs()
                })
                .fold(f64::INFINITY, f64::min)
        };
        // On Hoeken's curve: Pa on the unit circle with |M − Pa| = 5, Pb = (M + Pa)/2 on
        // circle(O4, 2.5).
        let on_hoeken = |m: Point2<f64>| {
            circle_intersections(Point2::origin(), 1.0, m, 5.0)
                .into_iter()
                .map(|pa| {
                    let pb = Point2::from(0.5 * (m.coords + pa.coords));
                    ((pb - Point2::new(2.0, 0.0)).norm() - 2.5).abs()
                })
                .fold(f64::INFINITY, f64::min)
        };
        let mut worst = 0.0f64;
        for c in [Circuit::Open, Circuit::Crossed] {
            for k in 0..360 {
                let t = CrankAngle::from_degrees(k as f64 + 0.25);
                let m = Pose::solve(&hoeken, c, &t).unwrap().point(hp);
                worst = worst.max(on_chebyshev(m));
            }
        }
        for b in trace_full(&cheb, cp, 0.25).branches {
            for s in b.samples {
                worst = worst.max(on_hoeken(place(s.point)));
            }
        }
        assert!(worst < 1e-12, "cognates differ by {worst:e}");
    }

    #[test]
    fn crank_rocker_is_full_with_one_branch_per_circuit() {
        let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
        let p = CouplerPoint::new(1.0, 0.5);
        let full = trace_full(&l, p, 10.0);
        assert_eq!(full.range, InputRange::Full);
        assert_eq!(full.branches.len(), 2);
        for b in &full.branches {
            assert_eq!(b.samples.len(), 37);
            assert_eq!(b.samples[0].point, b.samples[36].point);
        }
    }

    #[test]
    fn a_linkage_that_never_assembles_has_no_branch() {
        let l = FourBar::new(0.1, 0.1, 5.0).unwrap();
        assert_eq!(input_range(&l), InputRange::Never);
        assert!(
            trace_full(&l, CouplerPoint::new(0.0, 0.0), 1.0)
                .branches
                .is_empty()
        );
    }

    #[test]
    fn folded_only_range_goes_through_180() {
        // Q-toggle only: |A − B| > |C − 1| and A + B ≥ C + 1: A = 3, B = 1, C = 2.5.
        let l = FourBar::new(3.0, 1.0, 2.5).unwrap();
        let InputRange::Rocks { intervals } = input_range(&l) else {
            panic!()
        };
        assert_eq!(intervals.len(), 1);
        let (lo, hi) = intervals[0];
        assert_eq!((lo.kind, hi.kind), (ToggleKind::Folded, ToggleKind::Folded));
        assert!(lo.degrees < 180.0 && hi.degrees > 180.0);
        let p = CouplerPoint::new(1.0, 1.0);
        assert_closes_and_is_continuous(&trace_full(&l, p, 1.0), &l, p, 0.5);
    }
}
