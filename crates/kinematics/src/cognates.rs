//! Roberts–Chebyshev cognates: the three four-bars that trace one coupler curve
//! (Hartenberg & Denavit, *Kinematic Synthesis of Linkages*, §6.4; Norton §3.7; docs/conventions.md §5).
//!
//! In complex numbers (original's frame), with crank `c = Pa − O2`, coupler `k = Pb − Pa`,
//! rocker `ρ = Pb − O4`, and `r = (u + i·v)/A` so that `M = Pa + r·k`, Cayley's diagram
//! gives the third pivot `O_C = r·C` and
//! - cognate 1 (pivots O2, O_C): links `O2→A1 = r·k`, `A1→C1 = r·c`, `O_C→C1 = r·ρ`,
//!   with `M = A1 + c`: its input turns with the original **coupler**;
//! - cognate 2 (pivots O_C, O4): links `O_C→C2 = (1 − r)·c`, `C2→B2 = (r − 1)·ρ`,
//!   `O4→B2 = (r − 1)·k`, with `M = C2 + r·ρ`: its input turns with the original
//!   **crank**, at the same angle in its own frame. Scaled to crank 1 it is (A ↔ B
//!   swapped) `coupler B, rocker A, ground C`: a crank-rocker iff the original is one.

use crate::linkage::{Circuit, CouplerPoint, FourBar};
use crate::pose::{CrankAngle, Pose};
use nalgebra::Complex;
use serde::{Deserialize, Serialize};

type C64 = Complex<f64>;

/// One of the three linkages that trace a coupler curve, in the original's frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Cognate {
    /// Ground pivots: its input (crank) pivot, then its rocker pivot, in the original's
    /// frame.
    pub pivots: [[f64; 2]; 2],
    /// Length of the link at `pivots[0]` (original's units).
    pub crank: f64,
    /// Coupler length.
    pub coupler: f64,
    /// Length of the link at `pivots[1]`.
    pub rocker: f64,
    /// Ground length `|pivots[1] − pivots[0]|`.
    pub ground: f64,
    /// The tracing point in its own coupler frame (docs/conventions.md §1: origin at its crank pin,
    /// +u towards its rocker pin), original's units.
    pub point: CouplerPoint,
    /// Its assembly in its own frame (docs/conventions.md §1), at the original's θ = 0. A crank
    /// input keeps it all the way round; a rocker input (cognate 1 of a crank-rocker, a
    /// Grashof double-rocker) flips it at each toggle of the input, where it reverses.
    pub circuit: Circuit,
    /// Its Barker class (input = the link at `pivots[0]`).
    pub class: String,
    /// Whether it is a crank-rocker (GCRR).
    pub crank_rocker: bool,
    /// Which of the original's links its input link turns with: `"crank"` or `"coupler"`
    /// (the original itself: `"crank"`).
    pub input_follows: String,
}

/// Why cognates cannot be formed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CognateError {
    /// The coupler point lies on the coupler line at Pa or Pb (r = 0 or r = 1): a
    /// cognate degenerates to a zero-length link.
    #[error("coupler point ({u}, {v}) is the crank pin or the rocker pin: its cognates degenerate")]
    Degenerate {
        /// u.
        u: f64,
        /// v.
        v: f64,
    },
    /// The original cannot be assembled at θ = 0 nor 90° (needed to pick the circuits).
    #[error("the linkage does not assemble")]
    NotAssembled,
}

impl Cognate {
    /// The linkage scaled to crank 1 in its own frame, and the point in crank units.
    pub fn normalized(&self) -> Option<(FourBar, CouplerPoint)> {
        let s = self.crank;
        let l = FourBar::new(self.coupler / s, self.rocker / s, self.ground / s).ok()?;
        Some((l, CouplerPoint::new(self.point.u / s, self.point.v / s)))
    }

    /// The tracing point, in the original's frame, when its input link is at `deg`
    /// degrees in its own frame (from `pivots[0]` towards `pivots[1]`).
    pub fn point_at(&self, deg: f64) -> Option<[f64; 2]> {
        let (l, p) = self.normalized()?;
        let pose = Pose::solve(&l, self.circuit, &CrankAngle::from_degrees(deg))?;
        let m = pose.point(p);
        let o = C64::new(self.pivots[0][0], self.pivots[0][1]);
        let axis = C64::new(self.pivots[1][0], self.pivots[1][1]) - o;
        let frame = axis / axis.norm() * self.crank;
        let z = o + frame * C64::new(m.x, m.y);
        Some([z.re, z.im])
    }
}

fn pt(z: C64) -> [f64; 2] {
    [z.re, z.im]
}

/// Builds a cognate from its pivots, input pin, rocker pin and tracing point (all in the
/// original's frame, at one pose).
fn make(pivots: [C64; 2], pin_a: C64, pin_b: C64, m: C64, follows: &str) -> Cognate {
    let crank = (pin_a - pivots[0]).norm();
    let coupler = (pin_b - pin_a).norm();
    let rocker = (pin_b - pivots[1]).norm();
    let ground = (pivots[1] - pivots[0]).norm();
    let e = (pin_b - pin_a) / coupler;
    let local = (m - pin_a) / e; // (u + i·v) in its coupler frame
    let w = pivots[1] - pin_a;
    let cross = w.re * (pin_b - pin_a).im - w.im * (pin_b - pin_a).re;
    let circuit = if cross >= 0.0 {
        Circuit::Open
    } else {
        Circuit::Crossed
    };
    let class = FourBar::new(coupler / crank, rocker / crank, ground / crank)
        .map(|l| l.class())
        .ok();
    Cognate {
        pivots: [pt(pivots[0]), pt(pivots[1])],
        crank,
        coupler,
        rocker,
        ground,
        point: CouplerPoint::new(local.re, local.im),
        circuit,
        class: class.map(|c| c.code().to_string()).unwrap_or_default(),
        crank_rocker: class.is_some_and(|c| c == crate::linkage::Class::Gcrr),
        input_follows: follows.to_string(),
    }
}

/// The three linkages that trace the coupler curve of `point` on `linkage` in `circuit`:
/// the original, cognate 1 (pivots O2, O_C) and cognate 2 (pivots O_C, O4); see the
/// module doc. Circuits are read off one pose (θ = 0, else 90°) of the original; a
/// crank-rocker keeps its circuit, and so do its cognates.
///
/// ```
/// use coupler_kinematics::{FourBar, Circuit, CouplerPoint, cognates};
/// let hoeken = FourBar::new(2.5, 2.5, 2.0).unwrap();
/// let [_, c1, c2] = cognates(&hoeken, Circuit::Open, CouplerPoint::new(5.0, 0.0)).unwrap();
/// assert!(c2.crank_rocker && !c1.crank_rocker);
/// // Chebyshev's straight-line linkage is the Hoeken's cognate: rockers 2.5, coupler 1, ground 2 (× 2).
/// assert!((c1.crank - 5.0).abs() < 1e-12 && (c1.rocker - 5.0).abs() < 1e-12 && (c1.coupler - 2.0).abs() < 1e-12);
/// ```
pub fn cognates(
    linkage: &FourBar,
    circuit: Circuit,
    point: CouplerPoint,
) -> Result<[Cognate; 3], CognateError> {
    let a_len = linkage.coupler;
    let r = C64::new(point.u, point.v) / a_len;
    if r.norm() == 0.0 || (r - 1.0).norm() == 0.0 {
        return Err(CognateError::Degenerate {
            u: point.u,
            v: point.v,
        });
    }
    let pose = [0.0, 90.0, 45.0]
        .iter()
        .find_map(|&d| {
            Pose::solve(linkage, circuit, &CrankAngle::from_degrees(d)).filter(|p| p.is_finite())
        })
        .ok_or(CognateError::NotAssembled)?;
    let o2 = C64::new(0.0, 0.0);
    let o4 = C64::new(linkage.ground, 0.0);
    let pa = C64::new(pose.crank_pin.x, pose.crank_pin.y);
    let pb = C64::new(pose.rocker_pin.x, pose.rocker_pin.y);
    let (c, k, rho) = (pa - o2, pb - pa, pb - o4);
    let m = pa + r * k;
    let oc = r * linkage.ground;
    let original = make([o2, o4], pa, pb, m, "crank");
    let a1 = o2 + r * k;
    let c1 = a1 + r * c;
    let first = make([o2, oc], a1, c1, m, "coupler");
    let c2 = oc + (C64::new(1.0, 0.0) - r) * c;
    let b2 = o4 + (r - 1.0) * k;
    let second = make([oc, o4], c2, b2, m, "crank");
    let _ = rho;
    Ok([original, first, second])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::curve::{CrankTable, PoseTable};

    /// The three traces agree to 1e-12: cognate 2 at the same crank angle, cognate 1 at
    /// the original's coupler angle (in its own frame).
    #[test]
    fn cognates_trace_the_same_curve() {
        let cases = [
            (2.5, 2.5, 2.0, 5.0, 0.0, Circuit::Open),
            (3.0, 2.5, 3.5, 1.5, 1.0, Circuit::Open),
            (3.0, 2.5, 3.5, 1.5, -2.0, Circuit::Crossed),
            (4.0, 3.0, 5.0, -1.0, 0.5, Circuit::Crossed),
            (2.0, 3.5, 4.0, 2.5, 2.5, Circuit::Open),
        ];
        for (a, b, cc, u, v, circuit) in cases {
            let l = FourBar::new(a, b, cc).unwrap();
            let p = CouplerPoint::new(u, v);
            let [orig, c1, c2] = cognates(&l, circuit, p).unwrap();
            assert_eq!(orig.circuit, circuit);
            assert!(c2.crank_rocker && !c1.crank_rocker, "{a} {b} {cc}");
            let table = CrankTable::new(3.0).unwrap();
            let curve = PoseTable::new(&l, circuit, &table).trace(p);
            for (k, angle) in table.angles().iter().enumerate() {
                let m = [curve.x[k], curve.y[k]];
                let o = orig.point_at(angle.degrees).unwrap();
                let q2 = c2.point_at(angle.degrees).unwrap();
                let pose = Pose::solve(&l, circuit, angle).unwrap();
                let phi3 = libm::atan2(pose.coupler_dir.y, pose.coupler_dir.x).to_degrees();
                // Cognate 1's input is at a toggle (an extreme of its swing) where the
                // original's coupler stands still (ω3 = 0); there the point depends on the
                // input angle like a square root and an ulp of angle costs ~1e-8, so
                // cognate 1 is compared away from those angles.
                // Its assembly in the sense of docs/conventions.md §1 flips at each toggle of its
                // input (a Grashof double-rocker swings between two toggles), so read it
                // off the Cayley construction at this angle.
                let (pa, pb) = (
                    C64::new(pose.crank_pin.x, pose.crank_pin.y),
                    C64::new(pose.rocker_pin.x, pose.rocker_pin.y),
                );
                let r = C64::new(u, v) / a;
                let a1 = r * (pb - pa);
                let cc1 = a1 + r * pa;
                let (w, e) = (r * cc - a1, cc1 - a1);
                let branch = if w.re * e.im - w.im * e.re >= 0.0 {
                    Circuit::Open
                } else {
                    Circuit::Crossed
                };
                let c1 = Cognate {
                    circuit: branch,
                    ..c1.clone()
                };
                let q1 = if pose.coupler_omega.abs() > 0.05 {
                    c1.point_at(phi3).unwrap()
                } else {
                    m
                };
                for q in [o, q1, q2] {
                    let err = (q[0] - m[0]).hypot(q[1] - m[1]);
                    assert!(
                        err < 1e-12,
                        "{a} {b} {cc} ({u},{v}) θ={}: {err:e}",
                        angle.degrees
                    );
                }
            }
        }
    }

    #[test]
    fn degenerate_points() {
        let l = FourBar::new(3.0, 2.5, 3.5).unwrap();
        assert!(cognates(&l, Circuit::Open, CouplerPoint::new(0.0, 0.0)).is_err());
        assert!(cognates(&l, Circuit::Open, CouplerPoint::new(3.0, 0.0)).is_err());
    }
}
