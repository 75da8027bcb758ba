//! Numerical integration of the velocity equations in the crank angle.

use super::newton::{LoopClosure, pose_angles};
use super::{MethodTrace, PositionMethod, coupler_point};
use coupler_kinematics::{Circuit, CouplerPoint, FourBar};
use coupler_kinematics::{CrankAngle, Pose};
use nalgebra::Point2;

/// Classical fourth-order Runge–Kutta on the velocity ODE of the loop closure, in θ
/// (radians), state `(φ3, φ4)`:
///
/// `dφ3/dθ = −(Va·e4)/(A·(e3 × e4))`, `dφ4/dθ = −(Va·e3)/(B·(e3 × e4))`,
/// `Va = (−sin θ, cos θ)` (differentiating `Pa + A·e3 = O4 + B·e4`; docs/conventions.md §3).
///
/// One RK4 step per interval between consecutive requested angles, started from the
/// closed-form assembly at the first angle. Without projection the local error
/// `O(Δθ⁵)` accumulates as drift off the constraint (the links change length); with
/// projection each step ends with Newton's iteration on the loop closure at the new
/// angle (a predictor–corrector), and a projection that does not converge is reported.
/// The right-hand side is infinite at a toggle (e3 × e4 = 0): the integration cannot pass
/// one.
#[derive(Clone, Copy, Debug)]
pub struct Rk4 {
    /// Re-project onto the constraint after each step.
    pub project: bool,
}

impl Rk4 {
    /// RK4 without projection (drifts).
    pub fn plain() -> Rk4 {
        Rk4 { project: false }
    }

    /// RK4 with Newton re-projection after each step.
    pub fn projected() -> Rk4 {
        Rk4 { project: true }
    }
}

fn rhs(l: &FourBar, deg: f64, phi: [f64; 2]) -> [f64; 2] {
    let t = CrankAngle::from_degrees(deg);
    let (s3, c3) = (libm::sin(phi[0]), libm::cos(phi[0]));
    let (s4, c4) = (libm::sin(phi[1]), libm::cos(phi[1]));
    let cross = c3 * s4 - s3 * c4;
    let (vax, vay) = (-t.sin, t.cos);
    [
        -(vax * c4 + vay * s4) / (l.coupler * cross),
        -(vax * c3 + vay * s3) / (l.rocker * cross),
    ]
}

impl PositionMethod for Rk4 {
    fn name(&self) -> &'static str {
        if self.project { "rk4-projected" } else { "rk4" }
    }

    fn trace(
        &self,
        l: &FourBar,
        circuit: Circuit,
        p: CouplerPoint,
        degrees: &[f64],
    ) -> MethodTrace {
        let loop_eq = LoopClosure::new(l);
        let mut out = MethodTrace::default();
        let mut state: Option<([f64; 2], f64)> = None;
        for &deg in degrees {
            let t = CrankAngle::from_degrees(deg);
            let phi = match state {
                None => match Pose::solve(l, circuit, &t) {
                    Some(pose) => pose_angles(&pose),
                    None => {
                        out.points.push(None);
                        continue;
                    }
                },
                Some((phi, prev)) => {
                    let hd = deg - prev; // degrees
                    let h = hd.to_radians();
                    let add = |y: [f64; 2], k: [f64; 2], s: f64| [y[0] + s * k[0], y[1] + s * k[1]];
                    let k1 = rhs(l, prev, phi);
                    let k2 = rhs(l, prev + 0.5 * hd, add(phi, k1, 0.5 * h));
                    let k3 = rhs(l, prev + 0.5 * hd, add(phi, k2, 0.5 * h));
                    let k4 = rhs(l, deg, add(phi, k3, h));
                    out.work += 4;
                    let mut next = [
                        phi[0] + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
                        phi[1] + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
                    ];
                    if self.project {
                        let r = loop_eq.solve(&t, next, super::Newton::DEFAULT_TOLERANCE, 30);
                        out.work += r.iterations;
                        if !r.converged {
                            out.non_converged += 1;
                        }
                        next = r.phi;
                    }
                    next
                }
            };
            state = Some((phi, deg));
            let e = (libm::cos(phi[0]), libm::sin(phi[0]));
            out.points
                .push(Some(coupler_point(Point2::new(t.cos, t.sin), e, p)));
        }
        out
    }
}
