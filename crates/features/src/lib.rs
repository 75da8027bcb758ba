//! # coupler-features
//!
//! Features of a coupler curve (`docs/conventions.md`, "Features"): straight segments,
//! pseudo-arcs, double points, symmetry and cognates; measures over a crank window; the
//! flags for what the numerics cannot fully resolve; the longest straight runs of the
//! classic full curves (dwell six-bars designed from them are in `coupler-design`). Pure:
//! no I/O, no global state.
//!
//! Extraction works on the curve sampled every [`FeatureTolerances::step_deg`] (5° by
//! default) and refines with the closed-form pose where a sampled answer is not enough
//! (crossings, cusps, symmetry). Straight segments and pseudo-arcs are the *maximal*
//! qualifying windows of the samples: every window is considered (a cheap O(1) filter
//! from sliding fit sums, then an exact test, longest first), so no qualifying window is
//! longer than, or disjoint from, the ones reported (`docs/features.md`, "Maximal
//! windows: the contract").
//! Definitions and defaults: `docs/features.md`.

mod arcs;
mod classic;
mod double_points;
mod fit;
mod flags;
mod geared_flags;
mod maximal;
mod run;
mod straight;
mod symmetry;
mod transmission;
mod window;

pub use arcs::pseudo_arcs;
pub use classic::{ClassicCurve, NamedCurve, STRAIGHTNESS_TOLERANCES, StraightMeasure, TraceMode};
pub use double_points::{crunodes, cusps};
pub use fit::{Circle, CircleFitOptions, LineSums, angle_deg, fit_circle, kasa_circle};
pub use flags::{CurveFlag, CurveFlags, FlagTolerances, curve_flags};
pub use run::{StraightRun, longest_straight_run, straightness_fitted};
pub use straight::straight_segments;
pub use symmetry::symmetry;
pub use transmission::window_transmission;
pub use window::{
    CrankWindow, DEFAULT_WINDOW_STEP_DEG, LineDirection, LineMeasures, WindowError, WindowMeasures,
    WindowSamples, arc_deviation_pct,
};

/// Whether the processor has AVX2, the one run-time check the crate's AVX2 paths (the
/// pseudo-arcs' two filter passes, the straight segments' window filter) dispatch on;
/// the standard library caches the answer after the first call. Each such path is a
/// safe body compiled a second time for AVX2, so the results are the same either way.
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

use coupler_kinematics::{
    AngleTables, Circuit, Cognate, CouplerPoint, CrankTable, Curve, DashPattern, Linkage,
    Mechanism, PoseTable, divides_turn,
};
use serde::{Deserialize, Serialize};

/// Tolerances and settings of feature extraction, settable in a spec's `[features]` table.
/// Every field has a default ([`FeatureTolerances::DEFAULT`]). The dash angle by which
/// `dashes` are counted is not one of them: it is the pages' ([`DashPattern`], from
/// `[sampling] dash_deg`), passed beside the tolerances.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FeatureTolerances {
    /// Crank step of the samples features are found on, degrees (5, the 1951 atlas's dash
    /// spacing; 2 is finer and ~4× slower).
    pub step_deg: f64,
    /// Largest straightness error ε_S of a straight segment, percent (0.5).
    pub straight_pct: f64,
    /// Shortest straight segment, crank degrees (30).
    pub straight_min_span_deg: f64,
    /// Largest radial deviation of a pseudo-arc, percent of its radius (0.5).
    pub arc_pct: f64,
    /// Shortest pseudo-arc, crank degrees (30).
    pub arc_min_span_deg: f64,
    /// Smallest angle a pseudo-arc turns about its centre, degrees (10): flatter
    /// portions are straight segments of huge radius, not arcs.
    pub arc_min_turn_deg: f64,
    /// A cusp: the speed's local minimum is at most this fraction of the mean speed (0.01).
    pub cusp_speed_ratio: f64,
    /// A curve is symmetric when every reflected point lies this close to the curve,
    /// relative to the curve's size (bounding-box diagonal) (1e-7).
    pub symmetry_tol: f64,
}

impl FeatureTolerances {
    /// The defaults (documented in `docs/features.md`).
    pub const DEFAULT: FeatureTolerances = FeatureTolerances {
        step_deg: 5.0,
        straight_pct: 0.5,
        straight_min_span_deg: 30.0,
        arc_pct: 0.5,
        arc_min_span_deg: 30.0,
        arc_min_turn_deg: 10.0,
        cusp_speed_ratio: 0.01,
        symmetry_tol: 1e-7,
    };

    /// Checks ranges; the message names the offending field.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |name: &str, x: f64| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(format!(
                    "features.{name} must be a finite number > 0, got {x}"
                ))
            }
        };
        pos("step_deg", self.step_deg)?;
        if self.step_deg > 30.0 || !divides_turn(self.step_deg) {
            return Err(format!(
                "features.step_deg must divide 360 and be at most 30, got {}",
                self.step_deg
            ));
        }
        pos("straight_pct", self.straight_pct)?;
        pos("straight_min_span_deg", self.straight_min_span_deg)?;
        pos("arc_pct", self.arc_pct)?;
        pos("arc_min_span_deg", self.arc_min_span_deg)?;
        pos("arc_min_turn_deg", self.arc_min_turn_deg)?;
        pos("cusp_speed_ratio", self.cusp_speed_ratio)?;
        pos("symmetry_tol", self.symmetry_tol)?;
        Ok(())
    }
}

impl Default for FeatureTolerances {
    fn default() -> Self {
        FeatureTolerances::DEFAULT
    }
}

/// A portion of the curve that is nearly straight (Norton §3.8; see [`WindowMeasures`]
/// for ε_S and ε_V), maximal under [`FeatureTolerances::straight_pct`], moving one way
/// along its line.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StraightSegment {
    /// First crank angle, degrees in [0, 360).
    pub start_deg: f64,
    /// Crank duration, degrees (the segment ends at `start_deg + span_deg`, maybe past 360).
    pub span_deg: f64,
    /// Whole dashes in it: ⌊span / dash⌋, at the pages' dash angle.
    pub dashes: u32,
    /// Its length: extent Δx along the fitted line.
    pub length: f64,
    /// ε_S, percent.
    pub straightness_pct: f64,
    /// ε_V, percent.
    pub velocity_variation_pct: f64,
    /// Direction of travel along the line, degrees in (−180, 180].
    pub direction_deg: f64,
    /// Positions at its first and last crank angle.
    pub endpoints: [[f64; 2]; 2],
    /// `[min, max]` of the transmission angle over its window, degrees
    /// ([`window_transmission`]); absent in indexes written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transmission_deg: Option<[f64; 2]>,
}

/// Which side of the direction of travel the arc's centre lies on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// Centre to the left (the curve turns counter-clockwise).
    Left,
    /// Centre to the right (clockwise).
    Right,
}

/// A portion of the curve close to a circle (docs/conventions.md §5), maximal under
/// [`FeatureTolerances::arc_pct`], running one way round its centre.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PseudoArc {
    /// First crank angle, degrees in [0, 360).
    pub start_deg: f64,
    /// Crank duration, degrees.
    pub span_deg: f64,
    /// Whole dashes in it.
    pub dashes: u32,
    /// Centre of the circle.
    pub center: [f64; 2],
    /// Its radius.
    pub radius: f64,
    /// Largest radial deviation / radius, percent.
    pub deviation_pct: f64,
    /// Angle turned about the centre, degrees.
    pub turn_deg: f64,
    /// The concave side (where the centre is), relative to the direction of travel.
    pub concave: Side,
    /// `[min, max]` of the transmission angle over its window, degrees
    /// ([`window_transmission`]); absent in indexes written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transmission_deg: Option<[f64; 2]>,
}

/// A crunode: the curve crosses itself.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Crunode {
    /// Where.
    pub position: [f64; 2],
    /// The two crank angles that pass through it, degrees in [0, 360), ascending.
    pub angles_deg: [f64; 2],
}

/// A cusp (or near-cusp): the point passes (nearly) through the instant centre, its
/// speed drops (nearly) to zero.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Cusp {
    /// Where.
    pub position: [f64; 2],
    /// Crank angle, degrees in [0, 360).
    pub angle_deg: f64,
    /// The speed there / mean speed.
    pub speed_ratio: f64,
}

/// Double points of the curve.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DoublePoints {
    /// Self-crossings.
    pub crunodes: Vec<Crunode>,
    /// Cusps.
    pub cusps: Vec<Cusp>,
}

/// An axis of mirror symmetry of the curve.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Symmetry {
    /// A point of the axis: O2 or O4 where theory gives the axis, else the curve's
    /// arc-length centroid.
    pub point: [f64; 2],
    /// The axis direction, degrees in [0, 180).
    pub direction_deg: f64,
    /// Largest distance of a reflected point from the curve, relative to the curve's size.
    pub error: f64,
}

/// Everything extracted from one curve.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurveFeatures {
    /// Straight segments, by start angle.
    pub straight_segments: Vec<StraightSegment>,
    /// Pseudo-arcs, by start angle.
    pub pseudo_arcs: Vec<PseudoArc>,
    /// Crunodes and cusps.
    pub double_points: DoublePoints,
    /// The axis, if the curve is symmetric.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub symmetry: Option<Symmetry>,
    /// The two other four-bars tracing the same curve (Roberts–Chebyshev;
    /// [`Mechanism::cognates`]).
    pub cognates: Vec<Cognate>,
    /// Set when the coupler point is a pin of the mechanism, whose curve is a circle or
    /// an arc a designer gets for free ([`Trivial`]); search leaves such curves out unless
    /// asked. Absent otherwise (and in indexes written before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trivial: Option<Trivial>,
}

/// A coupler point whose curve is trivial: it coincides with a pin of the mechanism.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Trivial {
    /// The crank pin Pa (u = v = 0): the crank circle.
    CrankPin,
    /// The pin at the far end of the coupler link (u = A, v = 0: the rocker pin Pb of a
    /// four-bar): an arc about the output link's ground pivot.
    RockerPin,
}

impl Trivial {
    /// Which trivial pin of `linkage` `point` is ([`Trivial::of`]); the far pin counts
    /// only where it moves on a circle about a ground pivot
    /// ([`Mechanism::far_pin_on_ground_arc`]: a four-bar's rocker pin, not a geared
    /// five-bar's dyad joint, whose curve is no arc).
    pub fn of_linkage<M: Mechanism>(point: CouplerPoint, linkage: &M) -> Option<Trivial> {
        Trivial::of(point, linkage.coupler_length())
            .filter(|t| *t == Trivial::CrankPin || linkage.far_pin_on_ground_arc())
    }

    /// Which pin `point` is, to 1e-12 relative to the coupler link (`coupler_length`).
    pub fn of(point: CouplerPoint, coupler_length: f64) -> Option<Trivial> {
        let eps = 1e-12 * coupler_length.max(1.0);
        if point.v.abs() > eps {
            None
        } else if point.u.abs() <= eps {
            Some(Trivial::CrankPin)
        } else if (point.u - coupler_length).abs() <= eps {
            Some(Trivial::RockerPin)
        } else {
            None
        }
    }
}

/// Extracts features of every coupler point of one mechanism and circuit, sharing one
/// pose table (at [`FeatureTolerances::step_deg`]) across the points.
#[derive(Clone, Debug)]
pub struct FeatureExtractor<M: Mechanism> {
    linkage: M,
    circuit: Circuit,
    tolerances: FeatureTolerances,
    dash: DashPattern,
    poses: PoseTable,
    curve: Curve,
    /// μ at the input angles of the windows so far (the same for every coupler point).
    transmission: transmission::TransmissionMemo,
}

impl<M: Mechanism> FeatureExtractor<M> {
    /// Features counted in dashes of `dash` (the pages' pattern). `None` if the
    /// tolerances or the pattern are invalid, or the linkage does not assemble at every
    /// sampled angle (features are defined for full-revolution curves).
    pub fn new(
        linkage: &M,
        circuit: Circuit,
        tolerances: &FeatureTolerances,
        dash: &DashPattern,
    ) -> Option<FeatureExtractor<M>> {
        tolerances.validate().ok()?;
        dash.validate().ok()?;
        let table = CrankTable::over(tolerances.step_deg, linkage.period_deg())?;
        let poses = linkage.pose_table(circuit, &table);
        Self::with_poses(linkage, circuit, tolerances, dash, poses)
    }

    /// [`FeatureExtractor::new`] with the pose table given: `poses` must be
    /// `linkage.pose_table(circuit, &CrankTable::over(tolerances.step_deg, period))`
    /// (e.g. from a run's shared [`AngleTables`]: [`FeatureExtractor::with_tables`]).
    fn with_poses(
        linkage: &M,
        circuit: Circuit,
        tolerances: &FeatureTolerances,
        dash: &DashPattern,
        poses: PoseTable,
    ) -> Option<FeatureExtractor<M>> {
        poses.all_valid().then(|| FeatureExtractor {
            linkage: linkage.clone(),
            circuit,
            tolerances: *tolerances,
            dash: *dash,
            poses,
            curve: Curve::default(),
            transmission: transmission::TransmissionMemo::default(),
        })
    }

    /// The features of the curve of `point`.
    pub fn extract(&mut self, point: CouplerPoint) -> CurveFeatures {
        self.poses.trace_into(point, &mut self.curve);
        let (l, c, t, curve) = (&self.linkage, self.circuit, &self.tolerances, &self.curve);
        let cogs = l.cognates(c, point);
        let memo = &mut self.transmission;
        let mut window = |start: f64, span: f64| memo.window(l, c, start, span, t.step_deg);
        let mut segments = straight_segments(curve, t, &self.dash);
        for s in &mut segments {
            s.transmission_deg = window(s.start_deg, s.span_deg);
        }
        let mut arcs = pseudo_arcs(curve, t, &self.dash);
        for a in &mut arcs {
            a.transmission_deg = window(a.start_deg, a.span_deg);
        }
        CurveFeatures {
            straight_segments: segments,
            pseudo_arcs: arcs,
            double_points: DoublePoints {
                crunodes: crunodes(l, c, point, curve, t),
                cusps: cusps(l, c, point, curve, t),
            },
            symmetry: symmetry(l, c, point, curve, t),
            cognates: cogs,
            trivial: Trivial::of_linkage(point, l),
        }
    }
}

impl FeatureExtractor<Linkage> {
    /// [`FeatureExtractor::new`] with its pose table from a run's shared `tables`
    /// ([`AngleTables::pose_table_at`] at the features' step: the crank table, and a
    /// geared five-bar's gear table, built once for every linkage of the run, not per
    /// linkage). The same features to the bit.
    pub fn with_tables(
        linkage: &Linkage,
        circuit: Circuit,
        tolerances: &FeatureTolerances,
        dash: &DashPattern,
        tables: &AngleTables,
    ) -> Option<FeatureExtractor<Linkage>> {
        tolerances.validate().ok()?;
        dash.validate().ok()?;
        let poses = tables.pose_table_at(linkage, circuit, tolerances.step_deg);
        Self::with_poses(linkage, circuit, tolerances, dash, poses)
    }
}

/// Whole dashes of `dash` in a span: ⌊span / Δ⌋ (with a 1e-9 allowance for rounding).
pub(crate) fn dash_count(span_deg: f64, dash: &DashPattern) -> u32 {
    (span_deg / dash.step_deg + 1e-9).floor().max(0.0) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate() {
        FeatureTolerances::DEFAULT.validate().unwrap();
        let bad = FeatureTolerances {
            step_deg: 7.0,
            ..FeatureTolerances::DEFAULT
        };
        assert!(bad.validate().is_err());
    }
}
