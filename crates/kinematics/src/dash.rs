//! Dashes by crank angle (docs/conventions.md §4): the atlas's clock.
//!
//! Dash `k` spans the crank interval `θ ∈ [k·Δ, k·Δ + f·Δ]` (Δ the dash step, `f` the
//! drawn fraction, the rest a gap), so counting dashes along a stretch of curve reads its
//! crank duration, and a dash's length is the coupler point's mean speed over it times
//! `f·Δ`. Each interval becomes a polyline in curve units by sampling the coupler point
//! with its frame ([`Mechanism::frame`], the closed form for a four-bar) adaptively: an interval is split until every chord lies within a
//! tolerance of the curve (chosen by the page so that it is well under a pixel).
//!
//! Pure: no I/O, no global state. A renderer only strokes what comes out of here.

use crate::exact::divides_turn;
use crate::frame::CouplerFrame;
use crate::linkage::{Circuit, CouplerPoint};
use crate::mechanism::Mechanism;
use crate::pose::CrankAngle;
use nalgebra::{Point2, Vector2};
use std::cell::RefCell;

/// Default dash step Δ in crank degrees (Hartenberg & Denavit's redrawn atlas): the one
/// default of `[sampling] dash_deg`, by which pages draw and the index counts dashes.
pub const DEFAULT_DASH_STEP_DEG: f64 = 10.0;
/// Default drawn fraction `f` of each step.
pub const DEFAULT_DASH_FRACTION: f64 = 0.6;
/// Default chord tolerance in curve (crank) units when no page scale is known.
pub const DEFAULT_CHORD_TOLERANCE: f64 = 1e-3;
/// Deepest bisection of a dash interval (2¹⁴ pieces at most: a guard, never reached on an
/// assembled crank-rocker at any sane tolerance).
pub const MAX_SUBDIVISION_DEPTH: u32 = 14;

/// The dash pattern: one dash per `step_deg` of crank, of which `fraction` is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DashPattern {
    /// Δ in degrees; must divide 360 into a whole number of dashes.
    pub step_deg: f64,
    /// Drawn fraction `f`, in (0, 1).
    pub fraction: f64,
}

impl Default for DashPattern {
    fn default() -> Self {
        DashPattern {
            step_deg: DEFAULT_DASH_STEP_DEG,
            fraction: DEFAULT_DASH_FRACTION,
        }
    }
}

/// Why a curve could not be dashed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DashError {
    /// Δ is not a positive divisor of 360° or `f` is not in (0, 1).
    #[error(
        "dash pattern step {step_deg}° fraction {fraction}: the step must divide 360° and 0 < fraction < 1"
    )]
    BadPattern {
        /// Δ given.
        step_deg: f64,
        /// `f` given.
        fraction: f64,
    },
    /// The tolerance is not a finite positive number.
    #[error("chord tolerance must be finite and > 0, got {0}")]
    BadTolerance(f64),
    /// The mechanism cannot be assembled at this crank angle (not a crank-rocker).
    #[error("linkage {linkage} ({circuit}) does not assemble at θ = {theta_deg}°")]
    NotAssembled {
        /// The mechanism (its `Debug` text).
        linkage: String,
        /// The circuit.
        circuit: Circuit,
        /// The crank angle in degrees.
        theta_deg: f64,
    },
}

impl DashPattern {
    /// A validated pattern.
    pub fn new(step_deg: f64, fraction: f64) -> Result<DashPattern, DashError> {
        let p = DashPattern { step_deg, fraction };
        p.validate()?;
        Ok(p)
    }

    /// Checks that Δ divides 360 ([`divides_turn`]: `0 < Δ ≤ 360`, `360/Δ` a whole
    /// number, exactly) and `0 < f < 1`.
    pub fn validate(&self) -> Result<(), DashError> {
        let ok = divides_turn(self.step_deg) && self.fraction > 0.0 && self.fraction < 1.0;
        if ok {
            Ok(())
        } else {
            Err(DashError::BadPattern {
                step_deg: self.step_deg,
                fraction: self.fraction,
            })
        }
    }

    /// Number of dashes in a full crank turn, `360/Δ`.
    pub fn count(&self) -> usize {
        (360.0 / self.step_deg).round() as usize
    }

    /// Crank interval of dash `k` in degrees: `[k·Δ, k·Δ + f·Δ]`.
    pub fn interval(&self, k: usize) -> (f64, f64) {
        let start = k as f64 * self.step_deg;
        (start, start + self.fraction * self.step_deg)
    }
}

/// One dash: a crank interval and the polyline the coupler point traces over it.
#[derive(Clone, Debug, PartialEq)]
pub struct Dash {
    /// Dash number `k` (0 starts at θ = 0; on a rocking input's leg, the `k` of the
    /// interval `[kΔ, kΔ + fΔ]` it lies in, which may be negative there: see [`dash_leg`]).
    pub index: i64,
    /// First crank angle, degrees.
    pub theta_start: f64,
    /// Last crank angle, degrees.
    pub theta_end: f64,
    /// Points of M, in curve units, in the order of travel (θ increasing, except on the
    /// return leg of a rocking input: [`dash_leg`]). At least two.
    pub points: Vec<Point2<f64>>,
}

impl Dash {
    /// Crank span in degrees (`f·Δ`, less for a dash cut by a toggle).
    pub fn span_deg(&self) -> f64 {
        (self.theta_end - self.theta_start).abs()
    }

    /// Polyline length in curve units (a lower bound of the arc length, within the chord
    /// tolerance per piece).
    pub fn length(&self) -> f64 {
        self.points.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
    }

    /// The point of the polyline halfway along its length (where a shrunk dash is drawn
    /// as a dot).
    pub fn midpoint(&self) -> Point2<f64> {
        let half = 0.5 * self.length();
        let mut run = 0.0;
        for w in self.points.windows(2) {
            let l = (w[1] - w[0]).norm();
            if run + l >= half && l > 0.0 {
                let t = (half - run) / l;
                return w[0] + (w[1] - w[0]) * t;
            }
            run += l;
        }
        self.points[self.points.len() / 2]
    }
}

/// A coupler curve cut into dashes, plus what is needed to show where θ = 0 is and which
/// way the point travels.
#[derive(Clone, Debug, PartialEq)]
pub struct DashedCurve {
    /// The pattern used.
    pub pattern: DashPattern,
    /// Dashes in crank order; `dashes[0]` starts at θ = 0.
    pub dashes: Vec<Dash>,
    /// M at θ = 0.
    pub start: Point2<f64>,
    /// Direction of travel at the end of dash 0 (unit vector; the chord direction of dash
    /// 0 if the point is at rest there, e.g. a cusp; zero if both vanish).
    pub start_direction: Vector2<f64>,
    /// `[x_min, y_min, x_max, y_max]` of all dash points (curve units).
    pub bbox: [f64; 4],
}

impl DashedCurve {
    /// Total number of polyline points (a measure of the sampling cost).
    pub fn point_count(&self) -> usize {
        self.dashes.iter().map(|d| d.points.len()).sum()
    }
}

/// Distance from `p` to the segment `a`–`b`.
pub fn distance_to_segment(p: Point2<f64>, a: Point2<f64>, b: Point2<f64>) -> f64 {
    let ab = b - a;
    let l2 = ab.norm_squared();
    if l2 == 0.0 {
        return (p - a).norm();
    }
    let t = ((p - a).dot(&ab) / l2).clamp(0.0, 1.0);
    (p - (a + ab * t)).norm()
}

/// Samples coupler point M over crank angles, bisecting in a parameter σ with
/// θ = `warp(σ)` (the identity for a crank; near a toggle a square map that makes the
/// curve regular in σ: [`dash_leg`]).
struct Sampler<'a, M: Mechanism> {
    linkage: &'a M,
    /// The linkage's [`Mechanism::constants`].
    constants: M::Constants,
    circuit: Circuit,
    point: CouplerPoint,
    warp: &'a dyn Fn(f64) -> f64,
    /// The frames of the angles already solved, shared by the curves of several points
    /// ([`dash_curves`]; the identity warp only), or `None`.
    frames: Option<&'a RefCell<FrameCache>>,
}

/// Bisection nodes of a dash interval whose frames [`FrameCache`] keeps: node 1 is the
/// interval's midpoint, nodes `2n` and `2n + 1` the midpoints of node `n`'s halves, so
/// nodes below 128 are the midpoints down to depth 6 (deeper ones are solved each time).
const CACHED_NODES: usize = 128;

/// Slots of one dash in [`FrameCache`]: slot 0 its start, slots `1..CACHED_NODES` the
/// bisection nodes, the last its end.
const DASH_SLOTS: usize = CACHED_NODES + 1;

/// The frames [`dash_curve`] solves for one mechanism and dash pattern, by dash and
/// bisection node. Every point's sampler visits the same crank angles (the dash ends and
/// the midpoints of the same halvings, the same `f64`s whatever the point), only more or
/// fewer of them, and a frame depends on the angle alone: a frame solved for one point
/// is the frame every other point would solve there, to the bit.
#[derive(Default)]
struct FrameCache {
    /// Per slot, 1 + the frame's index in `frames`, or 0 when not solved yet.
    slot: Vec<u32>,
    frames: Vec<CouplerFrame>,
}

impl FrameCache {
    fn new(dashes: usize) -> FrameCache {
        FrameCache {
            slot: vec![0; dashes * DASH_SLOTS],
            frames: Vec::new(),
        }
    }

    fn get(&self, slot: usize) -> Option<CouplerFrame> {
        let i = *self.slot.get(slot)? as usize;
        (i > 0).then(|| self.frames[i - 1])
    }

    fn put(&mut self, slot: usize, f: CouplerFrame) {
        if let Some(s) = self.slot.get_mut(slot) {
            self.frames.push(f);
            *s = self.frames.len() as u32;
        }
    }
}

impl<M: Mechanism> Sampler<'_, M> {
    fn pose(&self, deg: f64) -> Result<CouplerFrame, DashError> {
        self.linkage
            .frame_with(
                &self.constants,
                self.circuit,
                &CrankAngle::from_degrees(deg),
            )
            .ok_or_else(|| DashError::NotAssembled {
                linkage: format!("{:?}", self.linkage),
                circuit: self.circuit,
                theta_deg: deg,
            })
    }

    fn at(&self, deg: f64) -> Result<Point2<f64>, DashError> {
        Ok(self.pose(deg)?.point(self.point))
    }

    /// [`Sampler::at`] the angle of cache slot `slot` (`None`: not kept), from the cache
    /// when it holds that frame.
    fn at_slot(&self, slot: Option<usize>, deg: f64) -> Result<Point2<f64>, DashError> {
        let (Some(cache), Some(slot)) = (self.frames, slot) else {
            return self.at(deg);
        };
        let cached = cache.borrow().get(slot);
        let f = match cached {
            Some(f) => f,
            None => {
                let f = self.pose(deg)?;
                cache.borrow_mut().put(slot, f);
                f
            }
        };
        Ok(f.point(self.point))
    }

    /// Appends the points after `p0` on `[t0, t1]` (excluding `p0`, including `p1`),
    /// bisecting while the mid-sample (or the quarter samples) strays from the chord by
    /// more than `tol`. Checking the quarter points as well as the midpoint catches an
    /// inflection whose midpoint happens to lie on the chord.
    ///
    /// `node` is the interval's bisection node in the dash whose cache slots start at
    /// `base` ([`CACHED_NODES`]; `None` without a cache): the midpoint is that node, the
    /// quarter points its children's.
    #[allow(clippy::too_many_arguments)]
    fn refine(
        &self,
        t0: f64,
        p0: Point2<f64>,
        t1: f64,
        p1: Point2<f64>,
        tol: f64,
        depth: u32,
        node: Option<(usize, usize)>,
        out: &mut Vec<Point2<f64>>,
    ) -> Result<(), DashError> {
        // The cache slot of node `n` (its children `2n`, `2n + 1`), if kept.
        let slot = |n: usize| node.and_then(|(base, _)| (n < CACHED_NODES).then_some(base + n));
        let child = |c: usize| node.map(|(base, n)| (base, 2 * n + c));
        let n = node.map_or(0, |(_, n)| n);
        let tm = 0.5 * (t0 + t1);
        let pm = self.at_slot(slot(n), (self.warp)(tm))?;
        let mut err = distance_to_segment(pm, p0, p1);
        if err <= tol && depth < 2 {
            // Cheap extra check on coarse pieces: the quarter points.
            let q1 = self.at_slot(slot(2 * n), (self.warp)(0.5 * (t0 + tm)))?;
            let q3 = self.at_slot(slot(2 * n + 1), (self.warp)(0.5 * (tm + t1)))?;
            err = err
                .max(distance_to_segment(q1, p0, p1))
                .max(distance_to_segment(q3, p0, p1));
        }
        if err <= tol || depth >= MAX_SUBDIVISION_DEPTH {
            out.push(p1);
            return Ok(());
        }
        self.refine(t0, p0, tm, pm, tol, depth + 1, child(0), out)?;
        self.refine(tm, pm, t1, p1, tol, depth + 1, child(1), out)
    }
}

/// Cuts the coupler curve of `point` on `linkage` (`circuit`) into dashes of `pattern`
/// over the mechanism's period ([`Mechanism::period_deg`]), each sampled so that every chord stays within `tolerance` (curve units) of the true
/// curve at the samples tested (midpoints, and quarter points on the coarsest pieces).
///
/// Errors if the pattern or tolerance is invalid, or if the linkage does not assemble
/// anywhere on a dash (only crank-rockers turn fully).
///
/// ```
/// use coupler_kinematics::{FourBar, Circuit, CouplerPoint, DashPattern, dash_curve};
/// let l = FourBar::new(3.0, 2.0, 3.0).unwrap();
/// let c = dash_curve(&l, Circuit::Open, CouplerPoint::new(1.0, 1.0), &DashPattern::default(), 1e-3).unwrap();
/// assert_eq!(c.dashes.len(), 36);
/// assert!((c.dashes[5].span_deg() - 6.0).abs() < 1e-12);
/// ```
pub fn dash_curve<M: Mechanism>(
    linkage: &M,
    circuit: Circuit,
    point: CouplerPoint,
    pattern: &DashPattern,
    tolerance: f64,
) -> Result<DashedCurve, DashError> {
    dash_curve_with(linkage, circuit, point, pattern, tolerance, None)
}

/// [`dash_curve`] of each of `points` on one mechanism, in order: the same curves to the
/// bit (and the first point's error, if any), for less work. The curves visit the same
/// crank angles, so each angle's frame is solved once for all of them (up to a depth of
/// bisection; the few deeper pieces are solved per point).
pub fn dash_curves<M: Mechanism>(
    linkage: &M,
    circuit: Circuit,
    points: &[CouplerPoint],
    pattern: &DashPattern,
    tolerance: f64,
) -> Result<Vec<DashedCurve>, DashError> {
    let turns = (linkage.period_deg() / 360.0).round().max(1.0) as usize;
    let dashes = if pattern.validate().is_ok() {
        pattern.count() * turns
    } else {
        0
    };
    let cache = RefCell::new(FrameCache::new(dashes));
    points
        .iter()
        .map(|&p| dash_curve_with(linkage, circuit, p, pattern, tolerance, Some(&cache)))
        .collect()
}

fn dash_curve_with<M: Mechanism>(
    linkage: &M,
    circuit: Circuit,
    point: CouplerPoint,
    pattern: &DashPattern,
    tolerance: f64,
    frames: Option<&RefCell<FrameCache>>,
) -> Result<DashedCurve, DashError> {
    pattern.validate()?;
    if !(tolerance.is_finite() && tolerance > 0.0) {
        return Err(DashError::BadTolerance(tolerance));
    }
    let s = Sampler {
        linkage,
        constants: linkage.constants(),
        circuit,
        point,
        warp: &|t| t,
        frames,
    };
    // Over the mechanism's whole period: one turn for a four-bar, q turns for a geared
    // five-bar of gear ratio p/q (one dash per Δ of input all the way).
    let turns = (linkage.period_deg() / 360.0).round().max(1.0) as usize;
    let count = pattern.count() * turns;
    let mut dashes = Vec::with_capacity(count);
    let mut bbox = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];
    // Each dash's samples are gathered in one buffer for the whole curve, then copied
    // into a list of their exact length (one allocation a dash, none grown sample by
    // sample).
    let mut samples = Vec::new();
    for k in 0..count {
        let (t0, t1) = pattern.interval(k);
        let base = k * DASH_SLOTS;
        let p0 = s.at_slot(Some(base), t0)?;
        let p1 = s.at_slot(Some(base + CACHED_NODES), t1)?;
        samples.clear();
        samples.push(p0);
        s.refine(t0, p0, t1, p1, tolerance, 0, Some((base, 1)), &mut samples)?;
        let points = samples.clone();
        for p in &points {
            bbox = [
                bbox[0].min(p.x),
                bbox[1].min(p.y),
                bbox[2].max(p.x),
                bbox[3].max(p.y),
            ];
        }
        dashes.push(Dash {
            index: k as i64,
            theta_start: t0,
            theta_end: t1,
            points,
        });
    }
    let first = &dashes[0];
    let end_pose = s.pose(first.theta_end)?;
    let v = end_pose.velocity(point);
    let chord = first.points[first.points.len() - 1] - first.points[0];
    let start_direction = if v.norm() > 1e-12 && v.iter().all(|x| x.is_finite()) {
        v / v.norm()
    } else if chord.norm() > 0.0 {
        chord / chord.norm()
    } else {
        Vector2::zeros()
    };
    Ok(DashedCurve {
        pattern: *pattern,
        start: first.points[0],
        start_direction,
        dashes,
        bbox,
    })
}

/// The dashes of one leg of a complete coupler curve ([`crate::trace::trace_full`]): the
/// input moving from `from_deg` to `to_deg` (either way) on `circuit`, as a rocking input
/// does between its toggles. Dash `k` is the part of `θ ∈ [kΔ, kΔ + fΔ]` inside the leg,
/// the same intervals of the input as a crank's dashes, so one dash still reads `Δ` of
/// input time; a dash cut by a toggle is shorter (a piece under 1 % of `fΔ` is dropped).
/// Dashes come in the order of travel, each polyline in that order too. Near a toggle the
/// curve's speed in θ grows without bound (a square-root branch point); the bisection
/// follows it there to the chord tolerance.
///
/// Errors as [`dash_curve`]; also if the linkage does not assemble inside the leg (the
/// ends must be within the input's range: use the toggle angles `trace_full` reports).
pub fn dash_leg<M: Mechanism>(
    linkage: &M,
    circuit: Circuit,
    point: CouplerPoint,
    pattern: &DashPattern,
    tolerance: f64,
    from_deg: f64,
    to_deg: f64,
) -> Result<Vec<Dash>, DashError> {
    dash_leg_intervals(
        linkage, circuit, point, pattern, tolerance, from_deg, to_deg, None,
    )
}

/// The dashes of one leg as [`dash_leg`] gives them, but counted from the start of a
/// branch's travel instead of from θ = 0: the input has already travelled `travel0_deg`
/// when the leg starts at `from_deg`, and dash `k` covers travel `[kΔ, kΔ + fΔ]` (so a
/// branch that starts at a toggle starts with a whole dash there, and the pattern runs on
/// unbroken across the toggle where the leg turns back). `Dash::index` is `k`.
#[allow(clippy::too_many_arguments)]
pub fn dash_leg_from<M: Mechanism>(
    linkage: &M,
    circuit: Circuit,
    point: CouplerPoint,
    pattern: &DashPattern,
    tolerance: f64,
    from_deg: f64,
    to_deg: f64,
    travel0_deg: f64,
) -> Result<Vec<Dash>, DashError> {
    dash_leg_intervals(
        linkage,
        circuit,
        point,
        pattern,
        tolerance,
        from_deg,
        to_deg,
        Some(travel0_deg),
    )
}

#[allow(clippy::too_many_arguments)]
fn dash_leg_intervals<M: Mechanism>(
    linkage: &M,
    circuit: Circuit,
    point: CouplerPoint,
    pattern: &DashPattern,
    tolerance: f64,
    from_deg: f64,
    to_deg: f64,
    travel0: Option<f64>,
) -> Result<Vec<Dash>, DashError> {
    pattern.validate()?;
    if !(tolerance.is_finite() && tolerance > 0.0) {
        return Err(DashError::BadTolerance(tolerance));
    }
    let (lo, hi) = (from_deg.min(to_deg), from_deg.max(to_deg));
    let step = pattern.step_deg;
    let drawn = pattern.fraction * step;
    let mut dashes = Vec::new();
    // Dash k as an input interval [a, b] (ascending): by θ from 0, or by travel from the
    // leg's start.
    let sign = if to_deg >= from_deg { 1.0 } else { -1.0 };
    let (first, last) = match travel0 {
        None => ((lo / step).floor() as i64, (hi / step).floor() as i64),
        Some(t0) => (
            (t0 / step).floor() as i64,
            ((t0 + (hi - lo)) / step).floor() as i64,
        ),
    };
    for k in first..=last {
        let (a, b) = match travel0 {
            None => (k as f64 * step, k as f64 * step + drawn),
            Some(t0) => {
                let s0 = from_deg + sign * (k as f64 * step - t0);
                let s1 = from_deg + sign * (k as f64 * step + drawn - t0);
                (s0.min(s1), s0.max(s1))
            }
        };
        let (a, b) = (a.max(lo), b.min(hi));
        if b - a < 0.01 * drawn {
            continue;
        }
        // Bisect in σ ∈ [0, 1] with θ = a + (b − a)·w(σ): w(σ) = σ in the open; a square
        // at an end that is a leg end (a toggle), where M(θ) has a square-root branch
        // point but M(θ(σ)) is regular, so the midpoint test bounds the chord error there
        // as it does elsewhere: w = σ² at `lo`, 1 − (1 − σ)² at `hi`, the smooth step
        // (1 − cos πσ)/2 when the dash touches both.
        let (at_lo, at_hi) = (a == lo, b == hi);
        let warp = move |x: f64| -> f64 {
            let w = match (at_lo, at_hi) {
                (false, false) => x,
                (true, false) => x * x,
                (false, true) => 1.0 - (1.0 - x) * (1.0 - x),
                (true, true) => 0.5 * (1.0 - libm::cos(std::f64::consts::PI * x)),
            };
            if x >= 1.0 { b } else { a + (b - a) * w }
        };
        let s = Sampler {
            linkage,
            constants: linkage.constants(),
            circuit,
            point,
            warp: &warp,
            frames: None,
        };
        let (p_a, p_b) = (s.at(a)?, s.at(b)?);
        let (t0, t1, p0, p1, s0, s1) = if to_deg >= from_deg {
            (a, b, p_a, p_b, 0.0, 1.0)
        } else {
            (b, a, p_b, p_a, 1.0, 0.0)
        };
        let mut points = vec![p0];
        s.refine(s0, p0, s1, p1, tolerance, 0, None, &mut points)?;
        dashes.push(Dash {
            index: k,
            theta_start: t0,
            theta_end: t1,
            points,
        });
    }
    if to_deg < from_deg && travel0.is_none() {
        dashes.reverse();
    }
    Ok(dashes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FourBar, Pose};

    fn distance_to_polyline(p: Point2<f64>, pts: &[Point2<f64>]) -> f64 {
        pts.windows(2)
            .map(|w| distance_to_segment(p, w[0], w[1]))
            .fold(f64::INFINITY, f64::min)
    }

    fn crank_rocker() -> FourBar {
        FourBar::new(3.0, 2.0, 3.0).unwrap()
    }

    #[test]
    fn dash_span_is_fraction_of_step_and_count_is_360_over_step() {
        for (step, f) in [(10.0, 0.6), (5.0, 0.5), (15.0, 0.75), (360.0, 0.5)] {
            let pat = DashPattern::new(step, f).unwrap();
            let c = dash_curve(
                &crank_rocker(),
                Circuit::Open,
                CouplerPoint::new(1.5, 1.0),
                &pat,
                1e-3,
            )
            .unwrap();
            assert_eq!(c.dashes.len(), (360.0 / step) as usize);
            for (k, d) in c.dashes.iter().enumerate() {
                assert_eq!(d.index, k as i64);
                assert!(
                    (d.span_deg() - step * f).abs() < 1e-12,
                    "span {}",
                    d.span_deg()
                );
                assert!((d.theta_start - k as f64 * step).abs() < 1e-12);
                assert!(d.points.len() >= 2);
            }
        }
    }

    #[test]
    fn bad_patterns_rejected() {
        assert!(DashPattern::new(7.0, 0.5).is_err()); // 360/7 not whole
        assert!(DashPattern::new(10.0, 1.0).is_err());
        assert!(DashPattern::new(10.0, 0.0).is_err());
        assert!(DashPattern::new(0.0, 0.5).is_err());
        assert!(DashPattern::new(f64::NAN, 0.5).is_err());
        let l = crank_rocker();
        let p = CouplerPoint::new(0.0, 0.0);
        assert!(dash_curve(&l, Circuit::Open, p, &DashPattern::default(), 0.0).is_err());
    }

    #[test]
    fn not_assembled_is_an_error() {
        // Not a crank-rocker: at θ = 0, d = 1 < B − A, so the linkage cannot assemble.
        let l2 = FourBar::new(0.4, 2.5, 2.0).unwrap();
        let p = CouplerPoint::new(0.5, 0.0);
        let r = dash_curve(&l2, Circuit::Open, p, &DashPattern::default(), 1e-3);
        assert!(matches!(r, Err(DashError::NotAssembled { .. })), "{r:?}");
    }

    /// Every dense sample of the true curve lies within the tolerance of the polyline
    /// (not only the samples the refinement tested).
    #[test]
    fn chord_error_bound_holds() {
        let cases = [
            (
                FourBar::new(3.0, 2.0, 3.0).unwrap(),
                CouplerPoint::new(1.5, 1.0),
            ),
            (
                FourBar::new(2.5, 2.5, 2.0).unwrap(),
                CouplerPoint::new(5.0, 0.0),
            ), // Hoeken
            (
                FourBar::new(4.0, 3.0, 4.0).unwrap(),
                CouplerPoint::new(-2.0, 3.0),
            ),
            (
                FourBar::new(2.0, 2.0, 1.5).unwrap(),
                CouplerPoint::new(3.0, -1.0),
            ),
        ];
        for tol in [1e-2, 1e-3, 1e-4] {
            for (l, p) in cases {
                for circuit in [Circuit::Open, Circuit::Crossed] {
                    let c = dash_curve(&l, circuit, p, &DashPattern::default(), tol).unwrap();
                    for d in &c.dashes {
                        let n = 400;
                        for i in 0..=n {
                            let t = d.theta_start + d.span_deg() * i as f64 / n as f64;
                            let m = Pose::solve(&l, circuit, &CrankAngle::from_degrees(t))
                                .unwrap()
                                .point(p);
                            let dist = distance_to_polyline(m, &d.points);
                            assert!(
                                dist <= tol * 1.01,
                                "{l:?} {p:?} {circuit} θ={t}: {dist:e} > {tol:e}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn sampling_is_frugal() {
        // At a tolerance of a tenth of a 300-dpi pixel on a 1-inch crank, a smooth curve
        // needs only a handful of points per dash.
        let tol = 0.1 / 300.0;
        let c = dash_curve(
            &crank_rocker(),
            Circuit::Open,
            CouplerPoint::new(1.5, 1.0),
            &DashPattern::default(),
            tol,
        )
        .unwrap();
        assert!(c.point_count() < 36 * 20, "{} points", c.point_count());
    }

    #[test]
    fn start_direction_follows_travel() {
        // Crank pin itself (u = v = 0): moves counter-clockwise on the unit circle; at θ = 6°
        // the velocity is (−sin 6°, cos 6°).
        let c = dash_curve(
            &crank_rocker(),
            Circuit::Open,
            CouplerPoint::new(0.0, 0.0),
            &DashPattern::default(),
            1e-4,
        )
        .unwrap();
        assert!((c.start - Point2::new(1.0, 0.0)).norm() < 1e-15);
        let (s, co) = crate::pose::sincos_deg(6.0);
        assert!((c.start_direction - Vector2::new(-s, co)).norm() < 1e-12);
        // Dash length ≈ arc of 6° on a unit circle.
        assert!((c.dashes[0].length() - 6f64.to_radians()).abs() < 1e-4);
    }

    /// Toggle angles of a rocking input's first interval (from the full trace).
    fn toggles(l: &FourBar) -> (f64, f64) {
        match crate::trace::input_range(l) {
            crate::trace::InputRange::Rocks { intervals } => {
                (intervals[0].0.degrees, intervals[0].1.degrees)
            }
            r => panic!("not a rocking input: {r:?}"),
        }
    }

    /// The classic rockers of `atlas-spec/classics.toml` (Watt, Roberts, Evans).
    fn rockers() -> [(FourBar, CouplerPoint); 3] {
        [
            (
                FourBar::new(1.0, 1.0, 5f64.sqrt()).unwrap(),
                CouplerPoint::new(0.5, 0.0),
            ),
            (
                FourBar::new(0.8, 1.0, 1.6).unwrap(),
                CouplerPoint::new(0.4, -0.916515138991168),
            ),
            (
                FourBar::new(1.0, 4.0, 17f64.sqrt()).unwrap(),
                CouplerPoint::new(-1.0, 0.0),
            ),
        ]
    }

    /// A leg's dashes are the pattern's intervals cut to the leg, in the order of travel;
    /// the return leg on the same circuit is the same polylines reversed, exactly.
    #[test]
    fn leg_dashes_follow_the_input_both_ways() {
        let pat = DashPattern::default();
        for (l, p) in rockers() {
            let (lo, hi) = toggles(&l);
            let out = dash_leg(&l, Circuit::Open, p, &pat, 1e-4, lo, hi).unwrap();
            let back = dash_leg(&l, Circuit::Open, p, &pat, 1e-4, hi, lo).unwrap();
            // Every interval [kΔ, kΔ + fΔ] meeting (lo, hi) by more than 1 % of fΔ.
            let expected = (((lo / 10.0).floor() as i64)..=((hi / 10.0).floor() as i64))
                .filter(|&k| {
                    let (a, b) = ((k as f64 * 10.0).max(lo), (k as f64 * 10.0 + 6.0).min(hi));
                    b - a >= 0.06
                })
                .count();
            assert_eq!(out.len(), expected, "{l:?}");
            for w in out.windows(2) {
                assert!(w[0].theta_end < w[1].theta_start && w[0].index + 1 == w[1].index);
            }
            for d in &out {
                let k = d.index as f64;
                assert!(
                    d.theta_start >= (10.0 * k).max(lo) && d.theta_end <= (10.0 * k + 6.0).min(hi)
                );
                assert!(d.span_deg() <= 6.0 + 1e-12 && d.points.len() >= 2);
            }
            assert_eq!(back.len(), out.len());
            for (b, o) in back.iter().zip(out.iter().rev()) {
                assert_eq!(b.index, o.index);
                assert_eq!((b.theta_start, b.theta_end), (o.theta_end, o.theta_start));
                let mut rev = o.points.clone();
                rev.reverse();
                assert_eq!(b.points, rev);
            }
            // Outside the input's range the linkage does not assemble: an error.
            assert!(dash_leg(&l, Circuit::Open, p, &pat, 1e-4, lo, hi + 5.0).is_err());
        }
    }

    /// The chord bound holds up to the toggles, where the point's speed in θ is
    /// unbounded (dense samples of the true curve within the tolerance of the polyline).
    /// Frozen failure: bisecting in θ itself (no square warp at the toggles), Roberts'
    /// crossed leg at 1e-4 left a sample 1.013e-4 from its polyline at θ = 84.2502°.
    #[test]
    fn leg_chord_error_bound_holds_at_toggles() {
        let pat = DashPattern::new(10.0, 0.6).unwrap();
        for (l, p) in rockers() {
            let (lo, hi) = toggles(&l);
            for circuit in [Circuit::Open, Circuit::Crossed] {
                for tol in [1e-3, 1e-4] {
                    let dashes = dash_leg(&l, circuit, p, &pat, tol, lo, hi).unwrap();
                    for d in [&dashes[0], &dashes[dashes.len() - 1]] {
                        let n = 400;
                        for i in 0..=n {
                            let t =
                                d.theta_start + (d.theta_end - d.theta_start) * i as f64 / n as f64;
                            let Some(pose) = Pose::solve(&l, circuit, &CrankAngle::from_degrees(t))
                            else {
                                continue; // the last ulps before a toggle may not assemble
                            };
                            let m = pose.point(p);
                            let dist = distance_to_polyline(m, &d.points);
                            assert!(
                                dist <= tol * 1.01,
                                "{l:?} {circuit} θ={t}: {dist:e} > {tol:e}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// A curve's dashes, their samples gathered in one buffer and copied out, are each
    /// dash sampled on its own into a fresh list (as every dash was before): the same
    /// points to the bit, on four-bars and a geared five-bar, both circuits, tolerances
    /// from coarse (a few samples a dash) to fine (bisected deep), alone and together.
    #[test]
    fn dashes_gathered_in_one_buffer_are_each_sampled_alone() {
        use crate::geared::{GearRatio, GearedFiveBar};
        use crate::mechanism::Linkage;
        let linkages = [
            Linkage::FourBar(FourBar::new(3.0, 2.0, 3.0).unwrap()),
            Linkage::FourBar(FourBar::new(2.5, 3.5, 3.0).unwrap()),
            Linkage::GearedFiveBar(
                GearedFiveBar::new(2.5, 2.2, 2.4, 0.8, GearRatio::new(3, 2).unwrap(), 30.0)
                    .unwrap(),
            ),
        ];
        let pat = DashPattern::default();
        let (mut dashes, mut longest) = (0, 0);
        for l in &linkages {
            for circuit in [Circuit::Open, Circuit::Crossed] {
                for tol in [3e-2, 1e-3, 1e-6] {
                    let points = [
                        CouplerPoint::new(1.5, 1.0),
                        CouplerPoint::new(-0.5, 2.0),
                        CouplerPoint::new(2.5, -1.5),
                    ];
                    let Ok(together) = dash_curves(l, circuit, &points, &pat, tol) else {
                        continue;
                    };
                    for (c, &point) in together.iter().zip(&points) {
                        let s = Sampler {
                            linkage: l,
                            constants: l.constants(),
                            circuit,
                            point,
                            warp: &|t| t,
                            frames: None,
                        };
                        let alone = dash_curve(l, circuit, point, &pat, tol).unwrap();
                        assert_eq!(format!("{c:?}"), format!("{alone:?}"));
                        for d in &c.dashes {
                            let (t0, t1) = (d.theta_start, d.theta_end);
                            let (p0, p1) = (s.at(t0).unwrap(), s.at(t1).unwrap());
                            let mut own = vec![p0];
                            s.refine(t0, p0, t1, p1, tol, 0, None, &mut own).unwrap();
                            assert_eq!(format!("{:?}", d.points), format!("{own:?}"));
                            dashes += 1;
                            longest = longest.max(own.len());
                        }
                    }
                }
            }
        }
        assert!(
            dashes > 1000 && longest > 65,
            "{dashes} dashes, {longest} samples"
        );
    }

    /// `dash_curves` gives each point's `dash_curve`, bit for bit (the `Debug` text of
    /// every `f64`, sign of zero included), on four-bars and geared five-bars (a period of
    /// two turns among them), points near and far, tolerances that bisect past the
    /// cached depth; and the first point's error where one does not assemble.
    #[test]
    fn curves_dashed_together_are_each_dashed_alone() {
        use crate::geared::{GearRatio, GearedFiveBar};
        use crate::mechanism::Linkage;
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut unit = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let linkages = [
            Linkage::FourBar(FourBar::new(3.0, 2.0, 3.0).unwrap()),
            Linkage::FourBar(FourBar::new(2.5, 3.5, 3.0).unwrap()),
            Linkage::FourBar(FourBar::new(4.0, 2.5, 4.5).unwrap()),
            Linkage::GearedFiveBar(
                GearedFiveBar::new(2.0, 2.5, 2.5, 1.0, GearRatio::integer(-1).unwrap(), 180.0)
                    .unwrap(),
            ),
            Linkage::GearedFiveBar(
                GearedFiveBar::new(2.5, 2.2, 2.4, 0.8, GearRatio::new(3, 2).unwrap(), 30.0)
                    .unwrap(),
            ),
        ];
        let (mut ok, mut deep) = (0, 0);
        for l in &linkages {
            for circuit in [Circuit::Open, Circuit::Crossed] {
                for tol in [3e-2, 1e-3, 2e-5, 1e-7] {
                    let points: Vec<CouplerPoint> = (0..6)
                        .map(|_| CouplerPoint::new(6.0 * unit() - 3.0, 6.0 * unit() - 3.0))
                        .collect();
                    let pat = DashPattern::default();
                    let together = dash_curves(l, circuit, &points, &pat, tol);
                    let alone: Result<Vec<_>, _> = points
                        .iter()
                        .map(|&p| dash_curve(l, circuit, p, &pat, tol))
                        .collect();
                    assert_eq!(format!("{together:?}"), format!("{alone:?}"));
                    if let Ok(curves) = &alone {
                        ok += 1;
                        // More than 2⁶ pieces in a dash: bisected past the cached nodes.
                        deep += usize::from(
                            curves
                                .iter()
                                .any(|c| c.dashes.iter().any(|d| d.points.len() > 65)),
                        );
                    }
                }
            }
        }
        assert!(ok >= 16 && deep >= 4, "{ok} sets dashed, {deep} deep");
        // No points, and a bad pattern or tolerance: as each alone.
        let l = &linkages[0];
        assert!(
            matches!(dash_curves(l, Circuit::Open, &[], &DashPattern::default(), 1e-3), Ok(v) if v.is_empty())
        );
        let p = [CouplerPoint::new(1.0, 1.0)];
        let bad = DashPattern {
            step_deg: 7.0,
            fraction: 0.5,
        };
        assert_eq!(
            dash_curves(l, Circuit::Open, &p, &bad, 1e-3).unwrap_err(),
            dash_curve(l, Circuit::Open, p[0], &bad, 1e-3).unwrap_err()
        );
        assert_eq!(
            dash_curves(l, Circuit::Open, &p, &DashPattern::default(), 0.0).unwrap_err(),
            DashError::BadTolerance(0.0)
        );
    }
}
