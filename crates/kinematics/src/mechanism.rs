//! What the atlas pipeline (the job, features, page layout, index) needs from a
//! mechanism, and nothing more: [`Mechanism`]. [`FourBar`] implements it; [`Linkage`] is
//! the closed set of mechanisms an atlas holds (what its index records), dispatching to
//! each.
//!
//! Every mechanism of the atlas is driven by one input crank of unit length pivoted at
//! O2 = (0, 0), turning counter-clockwise by θ (`docs/conventions.md`), and carries its
//! coupler points on a body whose frame has its origin at the input crank's pin
//! Pa = (cos θ, sin θ): a coupler point (u, v) is `M = Pa + u·e + v·J·e` with `e` the
//! body's unit direction ([`CouplerFrame`]). That holds for the four-bar (the coupler
//! from Pa to the rocker pin) and for the geared five-bar (the link from Pa to the dyad
//! joint), and it is what lets one pose per input angle serve every coupler point of a
//! grid ([`PoseTable`]): the hot path.
//!
//! A second mechanism plugs in here: implement [`Mechanism`] for it (in a file of its
//! own beside `linkage.rs`), add it as a variant of [`Linkage`] and [`LinkageClass`], and
//! the compiler lists every `match` in the layers above that must say what it does (the
//! spec's enumeration, the index's record, the search row, the curve flags).

use crate::cognates::{Cognate, cognates};
use crate::curve::{CrankTable, PoseTable, transmission_range};
use crate::frame::{CouplerFrame, Drawing, Joint};
use crate::geared::{GearedFiveBar, GearedGaps, TingClass};
use crate::linkage::{Circuit, Class, CouplerPoint, FourBar};
use crate::pose::{CrankAngle, Pose, PoseCore, ToggleGaps};
use nalgebra::Point2;
use serde::{Deserialize, Serialize};
use std::fmt;

/// What the atlas pipeline needs from a mechanism: its coupler curves by input angle,
/// their velocities, its class and transmission angle, its drawing, its identity.
///
/// The contract: [`Mechanism::frame`] and [`Mechanism::pose_table`] agree to the bit
/// (the table is the frames of its angles, stored as columns); `None` (a NaN row in the
/// table) where the mechanism cannot be assembled, never a guess.
pub trait Mechanism: Clone + fmt::Debug + fmt::Display + Send + Sync {
    /// What [`Mechanism::frame_with`] needs of the mechanism that no angle changes (a
    /// four-bar's [`ToggleGaps`]): computed once by [`Mechanism::constants`] for many
    /// angles.
    type Constants: Clone + fmt::Debug + Send + Sync;

    /// The mechanism's [`Mechanism::Constants`].
    fn constants(&self) -> Self::Constants;

    /// [`Mechanism::frame`] with `constants` (this mechanism's [`Mechanism::constants`])
    /// given, not computed again: the same frame to the bit.
    fn frame_with(
        &self,
        constants: &Self::Constants,
        circuit: Circuit,
        angle: &CrankAngle,
    ) -> Option<CouplerFrame>;

    /// The coupler body's frame at input angle `angle` on `circuit`, or `None` where the
    /// mechanism cannot be assembled there.
    #[inline]
    fn frame(&self, circuit: Circuit, angle: &CrankAngle) -> Option<CouplerFrame> {
        self.frame_with(&self.constants(), circuit, angle)
    }

    /// The frames at every angle of `table` as columns, shared by every coupler point
    /// (one pose per angle serves the whole grid). The default solves
    /// [`Mechanism::frame`] per angle; a mechanism may solve faster (the four-bar does).
    fn pose_table(&self, circuit: Circuit, table: &CrankTable) -> PoseTable {
        let k = self.constants();
        PoseTable::from_frames(table, |angle| self.frame_with(&k, circuit, angle))
    }

    /// The transmission angle (radians, in [0, π]) at `angle` on `circuit`, or `None`
    /// where the mechanism cannot be assembled.
    fn transmission(&self, circuit: Circuit, angle: &CrankAngle) -> Option<f64>;

    /// `[min, max]` of the transmission angle over a full turn of the input (radians),
    /// or `None` unless the mechanism assembles all the way round.
    fn transmission_range(&self, circuit: Circuit) -> Option<[f64; 2]>;

    /// Its class (Barker's for a four-bar, Ting's for a geared five-bar).
    fn class(&self) -> LinkageClass;

    /// Degrees of input after which the mechanism is back where it started: 360 for a
    /// four-bar, `360·q` for a geared five-bar of gear ratio p/q. A whole coupler curve is
    /// sampled over `[0, period)` ([`CrankTable::over`]).
    fn period_deg(&self) -> f64 {
        360.0
    }

    /// The class with a word on what it means for the input, for page headers, e.g.
    /// `"GCRR (crank-rocker)"`.
    fn class_description(&self) -> String;

    /// Its dimensions as printed on a page: name and value, e.g. `[("A", 2.5), …]`.
    fn dimensions(&self) -> Vec<(&'static str, f64)>;

    /// The length of the coupler body's link from Pa along `e` (the coupler A of a
    /// four-bar): pages draw the coupler plate over it.
    fn coupler_length(&self) -> f64;

    /// That link's name as [`Mechanism::dimensions`] prints it ("A" for a four-bar, "L3"
    /// for a geared five-bar): pages give grid rows in units of it.
    fn coupler_name(&self) -> &'static str {
        "A"
    }

    /// Whether the pin at the far end of that link, the point `(coupler_length, 0)`,
    /// moves on a circle about a ground pivot (a four-bar's rocker pin: its curve is a
    /// trivial arc). A geared five-bar's dyad joint does not: the second crank's pin it
    /// hangs from moves (its curve is §9's exact straight line for λ = −1, φ = 180°).
    fn far_pin_on_ground_arc(&self) -> bool;

    /// The naming convention of its links, for page headers, e.g.
    /// `"crank = 1, coupler A, rocker B, ground C"`.
    fn convention(&self) -> &'static str;

    /// The mechanism drawn at `angle` on `circuit`.
    fn drawing(&self, circuit: Circuit, angle: &CrankAngle) -> Drawing;

    /// Other mechanisms tracing the same coupler curve of `point` (the Roberts–Chebyshev
    /// cognates of a four-bar, as [`cognates`] gives them, without the linkage itself);
    /// none by default.
    fn cognates(&self, _circuit: Circuit, _point: CouplerPoint) -> Vec<Cognate> {
        Vec::new()
    }

    /// An axis of mirror symmetry of the coupler curve of `point` where theory gives it
    /// exactly: a point on the axis and its direction (radians). `None` when theory says
    /// nothing (the curve may still be symmetric: features then test reflections).
    fn symmetry_axis(&self, _circuit: Circuit, _point: CouplerPoint) -> Option<SymmetryAxis> {
        None
    }
}

/// An axis of mirror symmetry given by theory ([`Mechanism::symmetry_axis`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SymmetryAxis {
    /// A point on the axis.
    pub point: Point2<f64>,
    /// Its direction, radians.
    pub direction: f64,
    /// Which theorem gives it.
    pub reason: SymmetryReason,
}

/// Why a four-bar's coupler curve is symmetric (docs/conventions.md §5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SymmetryReason {
    /// The crank pin: a circle about O2 (every line through O2 is an axis; the ground
    /// line is reported).
    CrankPin,
    /// The rocker pin: an arc of the circle about O4 swept between the rocker's two
    /// extreme positions; the axis through O4 bisects them.
    RockerPin,
    /// A = B and M on the circle about Pb through Pa ((u − A)² + v² = A²): the axis
    /// through O4 turned by γ/2 from the ground line, γ the coupler's angle from Pb→Pa
    /// to Pb→M (Hartenberg & Denavit §6).
    EqualRockerCircle,
}

impl Mechanism for FourBar {
    type Constants = ToggleGaps;

    fn constants(&self) -> ToggleGaps {
        ToggleGaps::of(self)
    }

    #[inline]
    fn frame_with(
        &self,
        gaps: &ToggleGaps,
        circuit: Circuit,
        angle: &CrankAngle,
    ) -> Option<CouplerFrame> {
        let core = PoseCore::solve(self, gaps, circuit, angle)?;
        Some(core.frame(angle))
    }

    fn pose_table(&self, circuit: Circuit, table: &CrankTable) -> PoseTable {
        PoseTable::new(self, circuit, table)
    }

    fn transmission(&self, circuit: Circuit, angle: &CrankAngle) -> Option<f64> {
        Pose::solve(self, circuit, angle).map(|p| p.transmission)
    }

    fn transmission_range(&self, _circuit: Circuit) -> Option<[f64; 2]> {
        transmission_range(self)
    }

    fn class(&self) -> LinkageClass {
        LinkageClass::Barker(FourBar::class(self))
    }

    fn class_description(&self) -> String {
        format!(
            "{} ({})",
            FourBar::class(self).code(),
            if self.is_crank_rocker() {
                "crank-rocker"
            } else {
                "not a crank-rocker"
            }
        )
    }

    fn dimensions(&self) -> Vec<(&'static str, f64)> {
        vec![("A", self.coupler), ("B", self.rocker), ("C", self.ground)]
    }

    fn coupler_length(&self) -> f64 {
        self.coupler
    }

    fn far_pin_on_ground_arc(&self) -> bool {
        true
    }

    fn convention(&self) -> &'static str {
        "crank = 1, coupler A, rocker B, ground C"
    }

    /// O2 and O4 (ground), then Pa and Pb; links crank O2–Pa, coupler Pa–Pb, rocker
    /// O4–Pb; the crank circle.
    fn drawing(&self, circuit: Circuit, angle: &CrankAngle) -> Drawing {
        let ground = |name, x| Joint {
            name,
            position: Point2::new(x, 0.0),
            ground: true,
        };
        let mut joints = vec![ground("O2", 0.0), ground("O4", self.ground)];
        let mut links = Vec::new();
        let pose = Pose::solve(self, circuit, angle);
        if let Some(p) = &pose {
            joints.push(Joint {
                name: "Pa",
                position: p.crank_pin,
                ground: false,
            });
            joints.push(Joint {
                name: "Pb",
                position: p.rocker_pin,
                ground: false,
            });
            links = vec![[0, 2], [2, 3], [1, 3]];
        }
        Drawing {
            joints,
            links,
            paths: vec![(Point2::origin(), 1.0)],
            coupler: pose.map(|p| p.frame()),
        }
    }

    fn cognates(&self, circuit: Circuit, point: CouplerPoint) -> Vec<Cognate> {
        cognates(self, circuit, point)
            .map(|[_, a, b]| vec![a, b])
            .unwrap_or_default()
    }

    /// The three symmetric families of [`SymmetryReason`], recognised to 1e-12 (relative
    /// to the links). Positions at θ = 0 fix the signs (which side of the ground the
    /// rocker swings on, the coupler's sense of turning), so both circuits are covered.
    fn symmetry_axis(&self, circuit: Circuit, point: CouplerPoint) -> Option<SymmetryAxis> {
        let (a, b, c) = (self.coupler, self.rocker, self.ground);
        let scale = 1.0f64.max(a).max(b).max(c);
        let eps = 1e-12 * scale;
        let o4 = Point2::new(c, 0.0);
        if point.u.abs() <= eps && point.v.abs() <= eps {
            return Some(SymmetryAxis {
                point: Point2::origin(),
                direction: 0.0,
                reason: SymmetryReason::CrankPin,
            });
        }
        if !self.is_crank_rocker() {
            return None;
        }
        let frame = self.frame(circuit, &CrankAngle::from_degrees(0.0))?;
        if (point.u - a).abs() <= eps && point.v.abs() <= eps {
            // Extremes of the rocker: crank and coupler in line, |O2 Pb| = A ± 1; the
            // angle at O4 between O4→O2 and O4→Pb by the law of cosines.
            let alpha = |d: f64| {
                ((b * b + c * c - d * d) / (2.0 * b * c))
                    .clamp(-1.0, 1.0)
                    .acos()
            };
            let mid = 0.5 * (alpha(a + 1.0) + alpha(a - 1.0));
            let above = frame.point(CouplerPoint::new(a, 0.0)).y > 0.0;
            let direction = if above {
                std::f64::consts::PI - mid
            } else {
                std::f64::consts::PI + mid
            };
            return Some(SymmetryAxis {
                point: o4,
                direction,
                reason: SymmetryReason::RockerPin,
            });
        }
        let on_circle = ((point.u - a).powi(2) + point.v.powi(2) - a * a).abs() <= eps * scale;
        if (a - b).abs() <= eps && on_circle {
            let pa = frame.point(CouplerPoint::new(0.0, 0.0));
            let pb = frame.point(CouplerPoint::new(a, 0.0));
            let m = frame.point(point);
            let (s, t) = (pa - pb, m - pb);
            let gamma = libm::atan2(s.x * t.y - s.y * t.x, s.x * t.x + s.y * t.y);
            return Some(SymmetryAxis {
                point: o4,
                direction: 0.5 * gamma,
                reason: SymmetryReason::EqualRockerCircle,
            });
        }
        None
    }
}

/// The mechanisms an atlas holds: what a group of curves is drawn from and what the
/// index records as a curve's `linkage`. Serialised without a tag, as the mechanism's own
/// fields (a four-bar is `{"coupler": A, "rocker": B, "ground": C}`), so adding a
/// mechanism with other fields leaves existing indexes as they are.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Linkage {
    /// A four-bar (crank = 1, coupler A, rocker B, ground C).
    FourBar(FourBar),
    /// A geared five-bar (input crank 1, ground L1, dyad L3 and L4, second crank L5,
    /// gear ratio λ and phase φ): `{"l1", "l3", "l4", "l5", "ratio", "phase"}`.
    GearedFiveBar(GearedFiveBar),
}

impl From<GearedFiveBar> for Linkage {
    fn from(l: GearedFiveBar) -> Linkage {
        Linkage::GearedFiveBar(l)
    }
}

impl From<FourBar> for Linkage {
    fn from(l: FourBar) -> Linkage {
        Linkage::FourBar(l)
    }
}

impl Linkage {
    /// The four-bar, if it is one.
    pub fn four_bar(&self) -> Option<&FourBar> {
        match self {
            Linkage::FourBar(l) => Some(l),
            Linkage::GearedFiveBar(_) => None,
        }
    }

    /// The geared five-bar, if it is one.
    pub fn geared_five_bar(&self) -> Option<&GearedFiveBar> {
        match self {
            Linkage::GearedFiveBar(l) => Some(l),
            Linkage::FourBar(_) => None,
        }
    }
}

impl fmt::Display for Linkage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Linkage::FourBar(l) => l.fmt(f),
            Linkage::GearedFiveBar(l) => l.fmt(f),
        }
    }
}

/// A [`Linkage`]'s [`Mechanism::Constants`]: its variant's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LinkageConstants {
    /// A four-bar's toggle gaps.
    FourBar(ToggleGaps),
    /// A geared five-bar's gaps.
    GearedFiveBar(GearedGaps),
}

impl Mechanism for Linkage {
    type Constants = LinkageConstants;

    fn constants(&self) -> LinkageConstants {
        match self {
            Linkage::FourBar(l) => LinkageConstants::FourBar(l.constants()),
            Linkage::GearedFiveBar(l) => LinkageConstants::GearedFiveBar(l.constants()),
        }
    }

    /// Constants of the other variant (not this linkage's) are not used: the frame is
    /// then solved with the linkage's own.
    #[inline]
    fn frame_with(
        &self,
        constants: &LinkageConstants,
        circuit: Circuit,
        angle: &CrankAngle,
    ) -> Option<CouplerFrame> {
        match (self, constants) {
            (Linkage::FourBar(l), LinkageConstants::FourBar(c)) => l.frame_with(c, circuit, angle),
            (Linkage::GearedFiveBar(l), LinkageConstants::GearedFiveBar(c)) => {
                Mechanism::frame_with(l, c, circuit, angle)
            }
            (Linkage::FourBar(l), _) => l.frame(circuit, angle),
            (Linkage::GearedFiveBar(l), _) => l.frame(circuit, angle),
        }
    }

    fn pose_table(&self, circuit: Circuit, table: &CrankTable) -> PoseTable {
        match self {
            Linkage::FourBar(l) => l.pose_table(circuit, table),
            Linkage::GearedFiveBar(l) => l.pose_table(circuit, table),
        }
    }

    fn transmission(&self, circuit: Circuit, angle: &CrankAngle) -> Option<f64> {
        match self {
            Linkage::FourBar(l) => l.transmission(circuit, angle),
            Linkage::GearedFiveBar(l) => l.transmission(circuit, angle),
        }
    }

    fn transmission_range(&self, circuit: Circuit) -> Option<[f64; 2]> {
        match self {
            Linkage::FourBar(l) => l.transmission_range(circuit),
            Linkage::GearedFiveBar(l) => l.transmission_range(circuit),
        }
    }

    fn class(&self) -> LinkageClass {
        match self {
            Linkage::FourBar(l) => Mechanism::class(l),
            Linkage::GearedFiveBar(l) => Mechanism::class(l),
        }
    }

    fn period_deg(&self) -> f64 {
        match self {
            Linkage::FourBar(l) => l.period_deg(),
            Linkage::GearedFiveBar(l) => Mechanism::period_deg(l),
        }
    }

    fn class_description(&self) -> String {
        match self {
            Linkage::FourBar(l) => l.class_description(),
            Linkage::GearedFiveBar(l) => l.class_description(),
        }
    }

    fn dimensions(&self) -> Vec<(&'static str, f64)> {
        match self {
            Linkage::FourBar(l) => l.dimensions(),
            Linkage::GearedFiveBar(l) => l.dimensions(),
        }
    }

    fn coupler_length(&self) -> f64 {
        match self {
            Linkage::FourBar(l) => l.coupler_length(),
            Linkage::GearedFiveBar(l) => l.coupler_length(),
        }
    }

    fn coupler_name(&self) -> &'static str {
        match self {
            Linkage::FourBar(l) => l.coupler_name(),
            Linkage::GearedFiveBar(l) => l.coupler_name(),
        }
    }

    fn far_pin_on_ground_arc(&self) -> bool {
        match self {
            Linkage::FourBar(l) => l.far_pin_on_ground_arc(),
            Linkage::GearedFiveBar(l) => l.far_pin_on_ground_arc(),
        }
    }

    fn convention(&self) -> &'static str {
        match self {
            Linkage::FourBar(l) => l.convention(),
            Linkage::GearedFiveBar(l) => l.convention(),
        }
    }

    fn drawing(&self, circuit: Circuit, angle: &CrankAngle) -> Drawing {
        match self {
            Linkage::FourBar(l) => l.drawing(circuit, angle),
            Linkage::GearedFiveBar(l) => l.drawing(circuit, angle),
        }
    }

    fn cognates(&self, circuit: Circuit, point: CouplerPoint) -> Vec<Cognate> {
        match self {
            Linkage::FourBar(l) => l.cognates(circuit, point),
            Linkage::GearedFiveBar(l) => l.cognates(circuit, point),
        }
    }

    fn symmetry_axis(&self, circuit: Circuit, point: CouplerPoint) -> Option<SymmetryAxis> {
        match self {
            Linkage::FourBar(l) => l.symmetry_axis(circuit, point),
            Linkage::GearedFiveBar(l) => l.symmetry_axis(circuit, point),
        }
    }
}

/// The class of a mechanism: Barker's for a four-bar, Ting's for a geared five-bar.
/// Serialised as its code (`"GCRR"`, `"II"`), without a tag.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(untagged)]
pub enum LinkageClass {
    /// Barker's class of a four-bar.
    Barker(Class),
    /// Ting's rotatability class of a geared five-bar (`"I"`, `"II"`, `"III"`).
    Ting(TingClass),
}

impl LinkageClass {
    /// Every class, in a fixed order (the search cache stores a class as its position):
    /// Barker's fourteen, then Ting's three (appended, so the four-bar positions keep
    /// their numbers).
    pub const ALL: [LinkageClass; 17] = {
        let mut all = [LinkageClass::Barker(Class::Gccc); 17];
        let mut k = 0;
        while k < 14 {
            all[k] = LinkageClass::Barker(Class::ALL[k]);
            k += 1;
        }
        all[14] = LinkageClass::Ting(TingClass::I);
        all[15] = LinkageClass::Ting(TingClass::II);
        all[16] = LinkageClass::Ting(TingClass::III);
        all
    };

    /// Its code, e.g. `"GCRR"`.
    pub fn code(self) -> &'static str {
        match self {
            LinkageClass::Barker(c) => c.code(),
            LinkageClass::Ting(c) => c.code(),
        }
    }
}

impl From<Class> for LinkageClass {
    fn from(c: Class) -> LinkageClass {
        LinkageClass::Barker(c)
    }
}

impl fmt::Display for LinkageClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.code())
    }
}

impl std::str::FromStr for LinkageClass {
    type Err = String;
    fn from_str(s: &str) -> Result<LinkageClass, String> {
        match s.trim() {
            "I" => Ok(LinkageClass::Ting(TingClass::I)),
            "II" => Ok(LinkageClass::Ting(TingClass::II)),
            "III" => Ok(LinkageClass::Ting(TingClass::III)),
            _ => s.parse::<Class>().map(LinkageClass::Barker),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The frame, the pose and the pose table agree to the bit.
    #[test]
    fn frame_pose_and_table_agree() {
        let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
        let p = CouplerPoint::new(1.25, -0.5);
        let table = CrankTable::new(7.5).unwrap();
        for circuit in [Circuit::Open, Circuit::Crossed] {
            let poses = Mechanism::pose_table(&l, circuit, &table);
            let generic = PoseTable::from_frames(&table, |a| l.frame(circuit, a));
            // The table's columns are the frames' (its tracing loop groups the sums its
            // own way, so its samples may differ from `point` in the last bit).
            assert_eq!(poses.trace(p), generic.trace(p));
            for angle in table.angles() {
                let f = l.frame(circuit, angle).unwrap();
                let pose = Pose::solve(&l, circuit, angle).unwrap();
                assert_eq!(f, pose.frame());
                assert_eq!(f.point(p), pose.point(p));
                assert_eq!(f.velocity(p), pose.velocity(p));
            }
        }
    }

    /// Frames solved with the constants computed once are the frames solved alone (each
    /// computing its own), to the bit, `None` where they are: four-bars (a change point
    /// and a non-Grashof one among them, so angles at and past toggles), geared five-bars,
    /// and a `Linkage` given its own constants or the other variant's.
    #[test]
    fn frames_with_constants_computed_once_are_each_solved_alone() {
        use crate::geared::GearRatio;
        let geared = |n, d, phase| {
            Linkage::from(
                GearedFiveBar::new(2.3, 2.9, 3.4, 1.7, GearRatio::new(n, d).unwrap(), phase)
                    .unwrap(),
            )
        };
        let linkages = [
            Linkage::from(FourBar::new(2.5, 3.0, 3.5).unwrap()),
            Linkage::from(FourBar::new(2.0, 2.0, 1.0).unwrap()),
            Linkage::from(FourBar::new(1.5, 2.5, 3.0).unwrap()),
            Linkage::from(FourBar::new(0.7, 1.9, 2.2).unwrap()),
            Linkage::from(FourBar::new(3.0, 1.2, 2.6).unwrap()),
            geared(-1, 2, 15.0),
            geared(2, 1, 0.0),
            geared(-2, 1, 90.0),
        ];
        let other = [linkages[7].constants(), linkages[0].constants()];
        let (mut solved, mut none) = (0, 0);
        for l in &linkages {
            let own = l.constants();
            let wrong = match l {
                Linkage::FourBar(_) => &other[0],
                Linkage::GearedFiveBar(_) => &other[1],
            };
            let table = CrankTable::over(0.25, l.period_deg()).unwrap();
            for circuit in [Circuit::Open, Circuit::Crossed] {
                for angle in table.angles() {
                    let alone = match l {
                        Linkage::FourBar(b) => {
                            Pose::solve(b, circuit, angle).map(|pose| pose.frame())
                        }
                        Linkage::GearedFiveBar(g) => {
                            g.frame_with(&GearedGaps::of(g), circuit, angle)
                        }
                    };
                    let text = format!("{alone:?}");
                    assert_eq!(format!("{:?}", l.frame(circuit, angle)), text);
                    assert_eq!(format!("{:?}", l.frame_with(&own, circuit, angle)), text);
                    assert_eq!(format!("{:?}", l.frame_with(wrong, circuit, angle)), text);
                    let inner = match l {
                        Linkage::FourBar(b) => b.frame_with(&b.constants(), circuit, angle),
                        Linkage::GearedFiveBar(g) => {
                            Mechanism::frame_with(g, &g.constants(), circuit, angle)
                        }
                    };
                    assert_eq!(format!("{inner:?}"), text);
                    if alone.is_some() {
                        solved += 1;
                    } else {
                        none += 1;
                    }
                }
            }
        }
        assert!(solved > 5_000 && none > 500, "{solved} {none}");
    }

    #[test]
    fn linkage_serialises_as_the_four_bar() {
        let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
        assert_eq!(
            serde_json::to_string(&Linkage::from(l)).unwrap(),
            serde_json::to_string(&l).unwrap()
        );
    }
}
