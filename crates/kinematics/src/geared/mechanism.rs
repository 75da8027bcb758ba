//! The geared five-bar as a [`Mechanism`]: what the atlas pipeline (the `curve` command,
//! curve flags, pages, the index) asks of it.
//!
//! The input crank is the four-bar's crank (pivot O2, length 1, angle θ2 = the table's
//! angle) and the coupler point rides on L3 as it rides on the four-bar's coupler, so one
//! pose per input angle serves every coupler point of a grid ([`PoseTable`]).

use super::angle::GearAngle;
use super::linkage::{GearedFiveBar, TingClass};
use super::margin::{MARGIN_TOL, Rotatability, golden_min};
use super::pose::{GearedCore, GearedGaps, GearedPose};
use crate::curve::{CrankTable, PoseTable};
use crate::frame::{CouplerFrame, Drawing, Joint};
use crate::linkage::Circuit;
use crate::mechanism::{LinkageClass, Mechanism};
use crate::pose::CrankAngle;
use nalgebra::{Point2, Vector2};

/// The step (degrees of input) at which [`Mechanism::transmission_range`] samples μ over
/// the period before refining each sampled extremum by golden-section search.
pub const TRANSMISSION_STEP_DEG: f64 = 1.0;

impl GearedFiveBar {
    /// The frame of L3 at `angle` ([`Mechanism::frame`]) with the linkage's constants
    /// computed once (`GearedGaps::of(self)`), for many angles.
    pub fn frame_with(
        &self,
        gaps: &GearedGaps,
        circuit: Circuit,
        angle: &CrankAngle,
    ) -> Option<CouplerFrame> {
        let a = GearAngle::from_input(self.ratio, self.phase, *angle);
        let c = GearedCore::solve(self, gaps, circuit, &a)?;
        Some(CouplerFrame {
            origin: Point2::new(angle.cos, angle.sin),
            origin_velocity: Vector2::new(-angle.sin, angle.cos),
            direction: Vector2::new(c.e_x, c.e_y),
            omega: c.omega,
        })
    }

    /// The pose at `angle` (a [`CrankAngle`] of the input) on `circuit`.
    pub fn pose_at_angle(&self, circuit: Circuit, angle: &CrankAngle) -> Option<GearedPose> {
        GearedPose::solve(
            self,
            circuit,
            &GearAngle::from_input(self.ratio, self.phase, *angle),
        )
    }

    /// The radii of the two gears' pitch circles, `(r2, r5)` about O2 and O5, for drawing:
    /// for an external pair (λ < 0) meshing directly, `r2 + r5 = L1` and `r2/r5 = |λ|`;
    /// for λ > 0 (an internal pair, an idler or a chain: Norton's FIVEBAR leaves it to the
    /// designer) the same radii are drawn, with the pair's sense shown by λ's sign in the
    /// header. The pitch circles are the gears' size only; the kinematics use λ alone.
    pub fn pitch_radii(&self) -> (f64, f64) {
        let k = self.ratio.value().abs();
        (self.l1 * k / (1.0 + k), self.l1 / (1.0 + k))
    }
}

/// Text with a leading hyphen-minus replaced by a real minus sign (U+2212), for what a
/// reader sees (page headers, the `search` and `match` tables); parsers accept both.
/// Machine-readable output (JSON, CSV) keeps the hyphen-minus.
pub fn minus_sign(text: String) -> String {
    match text.strip_prefix('-') {
        Some(rest) => format!("\u{2212}{rest}"),
        None => text,
    }
}

impl Mechanism for GearedFiveBar {
    type Constants = GearedGaps;

    fn constants(&self) -> GearedGaps {
        GearedGaps::of(self)
    }

    #[inline]
    fn frame_with(
        &self,
        gaps: &GearedGaps,
        circuit: Circuit,
        angle: &CrankAngle,
    ) -> Option<CouplerFrame> {
        GearedFiveBar::frame_with(self, gaps, circuit, angle)
    }

    fn pose_table(&self, circuit: Circuit, table: &CrankTable) -> PoseTable {
        let gaps = GearedGaps::of(self);
        PoseTable::from_frames(table, |angle| self.frame_with(&gaps, circuit, angle))
    }

    fn transmission(&self, circuit: Circuit, angle: &CrankAngle) -> Option<f64> {
        self.pose_at_angle(circuit, angle).map(|p| p.transmission)
    }

    /// μ over one period, sampled every [`TRANSMISSION_STEP_DEG`] of input and each
    /// sampled extremum refined by golden-section search (μ is smooth where the dyad
    /// assembles): a numerical range, not a closed form as the four-bar's. `None` unless
    /// the input turns fully ([`GearedFiveBar::rotatability`] is `Full`). μ does not
    /// depend on the circuit (it is the angle of the triangle L3, L4, d).
    fn transmission_range(&self, circuit: Circuit) -> Option<[f64; 2]> {
        if self.rotatability(MARGIN_TOL) != Rotatability::Full {
            return None;
        }
        let gaps = GearedGaps::of(self);
        let mu = |deg: f64| {
            GearedPose::solve_with(self, &gaps, circuit, &self.angle_at(deg))
                .map_or(f64::NAN, |p| p.transmission)
        };
        let period = self.period_deg();
        let n = (period / TRANSMISSION_STEP_DEG).ceil() as usize;
        let h = period / n as f64;
        let m: Vec<f64> = (0..n).map(|k| mu(k as f64 * h)).collect();
        if m.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let (mut lo, mut hi) = (f64::INFINITY, -f64::INFINITY);
        for k in 0..n {
            let (prev, next) = (m[(k + n - 1) % n], m[(k + 1) % n]);
            let (a, b) = ((k as f64 - 1.0) * h, (k as f64 + 1.0) * h);
            if m[k] <= prev && m[k] <= next {
                lo = lo.min(m[k]).min(golden_min(mu, a, b).1);
            }
            if m[k] >= prev && m[k] >= next {
                hi = hi.max(m[k]).max(-golden_min(|t| -mu(t), a, b).1);
            }
        }
        Some([lo, hi])
    }

    fn class(&self) -> LinkageClass {
        LinkageClass::Ting(self.ting_class())
    }

    fn period_deg(&self) -> f64 {
        self.ratio.period_deg()
    }

    fn class_description(&self) -> String {
        let what = match self.rotatability(MARGIN_TOL) {
            Rotatability::Full => "turns fully",
            Rotatability::Touches => "turns through a toggle",
            Rotatability::Limited => "rocks",
        };
        let class = self.ting_class();
        let change = if class == TingClass::III {
            ", change points"
        } else {
            ""
        };
        // The transmission-angle range is not repeated here: pages and the contents
        // print it in their own field (with the warning under 30°).
        format!(
            "Ting {} ({what}{change}), λ = {}, φ = {}°",
            class.code(),
            minus_sign(self.ratio.to_string()),
            minus_sign(self.phase.to_string())
        )
    }

    /// The lengths; the gears (λ as a fraction, φ) are in [`Mechanism::class_description`].
    fn dimensions(&self) -> Vec<(&'static str, f64)> {
        vec![
            ("L1", self.l1),
            ("L3", self.l3),
            ("L4", self.l4),
            ("L5", self.l5),
        ]
    }

    fn coupler_length(&self) -> f64 {
        self.l3
    }

    fn coupler_name(&self) -> &'static str {
        "L3"
    }

    /// No: the dyad joint P hangs from the moving pin Pd.
    fn far_pin_on_ground_arc(&self) -> bool {
        false
    }

    fn convention(&self) -> &'static str {
        "input crank = 1, point on L3, θ5 = λ·θ2 + φ"
    }

    /// O2 and O5 (ground), then Pa, Pd and the dyad joint P; links input crank O2–Pa,
    /// L3 Pa–P, L4 Pd–P, second crank O5–Pd; paths: the two crank circles, then the two
    /// gears' pitch circles ([`GearedFiveBar::pitch_radii`]).
    fn drawing(&self, circuit: Circuit, angle: &CrankAngle) -> Drawing {
        let ground = |name, x| Joint {
            name,
            position: Point2::new(x, 0.0),
            ground: true,
        };
        let mut joints = vec![ground("O2", 0.0), ground("O5", self.l1)];
        let mut links = Vec::new();
        let pose = self.pose_at_angle(circuit, angle);
        if let Some(p) = &pose {
            for (name, position) in [("Pa", p.input_pin), ("Pd", p.second_pin), ("P", p.joint)] {
                joints.push(Joint {
                    name,
                    position,
                    ground: false,
                });
            }
            links = vec![[0, 2], [2, 4], [3, 4], [1, 3]];
        }
        let (r2, r5) = self.pitch_radii();
        Drawing {
            joints,
            links,
            paths: vec![
                (Point2::origin(), 1.0),
                (self.o5(), self.l5),
                (Point2::origin(), r2),
                (self.o5(), r5),
            ],
            coupler: pose.map(|p| CouplerFrame {
                origin: p.input_pin,
                origin_velocity: p.input_pin_velocity,
                direction: p.link3_dir,
                omega: p.omega3,
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geared::GearRatio;
    use crate::linkage::CouplerPoint;

    fn g(n: i64, d: i64, phase: f64) -> GearedFiveBar {
        GearedFiveBar::new(2.3, 2.9, 3.4, 1.7, GearRatio::new(n, d).unwrap(), phase).unwrap()
    }

    /// The trait's frame, its pose table and the five-bar's own pose agree to the bit.
    #[test]
    fn frame_pose_and_table_agree() {
        let p = CouplerPoint::new(1.25, -0.5);
        for l in [g(-1, 2, 15.0), g(2, 1, 0.0), g(-2, 1, 90.0)] {
            let table = CrankTable::over(5.0, l.period_deg()).unwrap();
            for circuit in [Circuit::Open, Circuit::Crossed] {
                let poses = Mechanism::pose_table(&l, circuit, &table);
                assert_eq!(poses.len(), (l.period_deg() / 5.0) as usize);
                for (k, angle) in table.angles().iter().enumerate() {
                    let pose = l.pose_at(circuit, angle.degrees);
                    assert_eq!(pose.is_some(), poses.valid[k]);
                    let Some(pose) = pose else { continue };
                    let f = l.frame(circuit, angle).unwrap();
                    assert_eq!(f.point(p), pose.point(p));
                    assert_eq!(Some(f.velocity(p)), pose.velocity(p));
                    assert_eq!(l.transmission(circuit, angle), Some(pose.transmission));
                }
            }
        }
    }

    #[test]
    fn transmission_range_brackets_every_sample() {
        // Class I with the cranks shortest: turns fully with any gears.
        let l =
            GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::new(-1, 2).unwrap(), 30.0).unwrap();
        let [lo, hi] = l.transmission_range(Circuit::Open).unwrap();
        let table = CrankTable::over(0.1, l.period_deg()).unwrap();
        let (mut slo, mut shi) = (f64::INFINITY, -f64::INFINITY);
        for a in table.angles() {
            let mu = l.transmission(Circuit::Open, a).unwrap();
            assert!(lo - 1e-12 <= mu && mu <= hi + 1e-12, "{} {mu}", a.degrees);
            (slo, shi) = (slo.min(mu), shi.max(mu));
        }
        // Refined extremes are no further out than a 0.1° sampling can miss.
        assert!(slo - lo < 1e-5 && hi - shi < 1e-5, "{lo} {slo} {hi} {shi}");
        // A linkage that rocks has no range.
        let rocks =
            GearedFiveBar::new(2.5, 2.0, 2.0, 1.0, GearRatio::integer(1).unwrap(), 180.0).unwrap();
        assert_eq!(rocks.transmission_range(Circuit::Open), None);
    }

    #[test]
    fn drawing_closes_the_loop_and_pitch_circles_mesh() {
        let l = g(-2, 1, 0.0);
        let d = l.drawing(Circuit::Open, &CrankAngle::from_degrees(40.0));
        assert_eq!(d.joints.len(), 5);
        let len = |[a, b]: [usize; 2]| (d.joints[a].position - d.joints[b].position).norm();
        for (link, want) in d.links.iter().zip([1.0, 2.9, 3.4, 1.7]) {
            assert!((len(*link) - want).abs() < 1e-14);
        }
        let (r2, r5) = l.pitch_radii();
        assert!((r2 + r5 - 2.3).abs() < 1e-15 && (r2 / r5 - 2.0).abs() < 1e-15);
        assert_eq!(l.class().code(), "II");
        assert!(
            l.class_description().starts_with("Ting II"),
            "{}",
            l.class_description()
        );
        // A real minus sign for λ and φ, not a hyphen.
        let half =
            GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::new(-1, 2).unwrap(), -30.0).unwrap();
        assert!(
            half.class_description()
                .ends_with("λ = \u{2212}1/2, φ = \u{2212}30°"),
            "{}",
            half.class_description()
        );
    }
}
