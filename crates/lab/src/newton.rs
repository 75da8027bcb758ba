//! Newton–Raphson on the loop-closure equations, continued along the crank.

use super::{MethodTrace, PositionMethod, coupler_point};
use coupler_kinematics::{Circuit, CouplerPoint, FourBar};
use coupler_kinematics::{CrankAngle, Pose};
use nalgebra::Point2;

/// The loop closure `Pa + A·e3(φ3) − O4 − B·e4(φ4) = 0` as two equations in the coupler
/// angle φ3 and the rocker angle φ4 at a fixed crank angle:
///
/// `f1 = cos θ + A cos φ3 − B cos φ4 − C`, `f2 = sin θ + A sin φ3 − B sin φ4`,
/// Jacobian `[[−A sin φ3, B sin φ4], [A cos φ3, −B cos φ4]]`, determinant
/// `A·B·sin(φ3 − φ4)`, zero at a toggle.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LoopClosure {
    a: f64,
    b: f64,
    c: f64,
}

/// Outcome of Newton's iteration at one crank angle.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NewtonOutcome {
    pub phi: [f64; 2],
    pub iterations: usize,
    pub converged: bool,
}

impl LoopClosure {
    pub(crate) fn new(l: &FourBar) -> LoopClosure {
        LoopClosure {
            a: l.coupler,
            b: l.rocker,
            c: l.ground,
        }
    }

    /// The angular velocities `(ω3, ω4) = dφ/dθ` at `(θ, φ)`, from differentiating the loop
    /// closure: `ω3 = −(Va·e4)/(A·(e3 × e4))`, `ω4 = −(Va·e3)/(B·(e3 × e4))`.
    pub(crate) fn omega(&self, t: &CrankAngle, phi: [f64; 2]) -> [f64; 2] {
        let (s3, c3) = (libm::sin(phi[0]), libm::cos(phi[0]));
        let (s4, c4) = (libm::sin(phi[1]), libm::cos(phi[1]));
        let cross = c3 * s4 - s3 * c4;
        let (vax, vay) = (-t.sin, t.cos);
        [
            -(vax * c4 + vay * s4) / (self.a * cross),
            -(vax * c3 + vay * s3) / (self.b * cross),
        ]
    }

    /// The residual `(f1, f2)`.
    pub(crate) fn residual(&self, t: &CrankAngle, phi: [f64; 2]) -> [f64; 2] {
        [
            t.cos + self.a * libm::cos(phi[0]) - self.b * libm::cos(phi[1]) - self.c,
            t.sin + self.a * libm::sin(phi[0]) - self.b * libm::sin(phi[1]),
        ]
    }

    /// Newton's iteration from `phi` at crank angle `t`: stops when the correction is below
    /// `tol` (radians), after at most `max_iter` steps, or at a singular Jacobian.
    pub(crate) fn solve(
        &self,
        t: &CrankAngle,
        mut phi: [f64; 2],
        tol: f64,
        max_iter: usize,
    ) -> NewtonOutcome {
        for it in 1..=max_iter {
            let f = self.residual(t, phi);
            let (s3, c3) = (libm::sin(phi[0]), libm::cos(phi[0]));
            let (s4, c4) = (libm::sin(phi[1]), libm::cos(phi[1]));
            let (j11, j12, j21, j22) = (-self.a * s3, self.b * s4, self.a * c3, -self.b * c4);
            let det = j11 * j22 - j12 * j21;
            if det == 0.0 || !det.is_finite() {
                return NewtonOutcome {
                    phi,
                    iterations: it,
                    converged: false,
                };
            }
            let d3 = (j22 * f[0] - j12 * f[1]) / det;
            let d4 = (-j21 * f[0] + j11 * f[1]) / det;
            phi = [phi[0] - d3, phi[1] - d4];
            let step = d3.abs().max(d4.abs());
            if !step.is_finite() {
                return NewtonOutcome {
                    phi,
                    iterations: it,
                    converged: false,
                };
            }
            if step <= tol {
                return NewtonOutcome {
                    phi,
                    iterations: it,
                    converged: true,
                };
            }
        }
        NewtonOutcome {
            phi,
            iterations: max_iter,
            converged: false,
        }
    }
}

/// Coupler and rocker angles `(φ3, φ4)` of an assembled pose.
pub(crate) fn pose_angles(pose: &Pose) -> [f64; 2] {
    [
        libm::atan2(pose.coupler_dir.y, pose.coupler_dir.x),
        libm::atan2(pose.rocker_dir.y, pose.rocker_dir.x),
    ]
}

/// Newton–Raphson on `LoopClosure`, each crank step started from the previous step's
/// solution (zeroth-order continuation) or, with `predictor`, from the previous solution
/// advanced along its velocity (`φ + ω·Δθ`, first-order continuation), the first from the
/// closed-form assembly (a solver is handed an assembled mechanism). This is what general
/// mechanism solvers do.
///
/// Its failure modes are the subject of the stability sweep: near a toggle the Jacobian
/// is singular and the iteration stalls (reported in [`MethodTrace::non_converged`]);
/// with coarse crank steps it may converge onto the other circuit (a circuit jump, which
/// it cannot see). Positions are returned even when not converged, as solvers do.
#[derive(Clone, Copy, Debug)]
pub struct Newton {
    /// Stop when the angle correction is at most this (radians).
    pub tolerance: f64,
    /// Give up after this many iterations per crank angle.
    pub max_iterations: usize,
    /// Start each step from the first-order prediction `φ + ω·Δθ` instead of `φ`.
    pub predictor: bool,
}

impl Newton {
    /// The default tolerance: corrections below 1e-14 rad (full f64 precision, a couple of
    /// ulps of an angle near π).
    pub const DEFAULT_TOLERANCE: f64 = 1e-14;
}

impl Default for Newton {
    fn default() -> Newton {
        Newton {
            tolerance: Newton::DEFAULT_TOLERANCE,
            max_iterations: 30,
            predictor: false,
        }
    }
}

impl PositionMethod for Newton {
    fn name(&self) -> &'static str {
        if self.predictor {
            "newton-predictor"
        } else {
            "newton"
        }
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
        let mut state: Option<[f64; 2]> = None;
        let mut prev_deg = 0.0;
        for &deg in degrees {
            let t = CrankAngle::from_degrees(deg);
            let start = match state {
                Some(phi) if self.predictor => {
                    let w = loop_eq.omega(&CrankAngle::from_degrees(prev_deg), phi);
                    let h = (deg - prev_deg).to_radians();
                    let next = [phi[0] + w[0] * h, phi[1] + w[1] * h];
                    if next.iter().all(|x| x.is_finite()) {
                        next
                    } else {
                        phi
                    }
                }
                Some(phi) => phi,
                None => match Pose::solve(l, circuit, &t) {
                    Some(pose) => pose_angles(&pose),
                    None => {
                        out.points.push(None);
                        continue;
                    }
                },
            };
            let r = loop_eq.solve(&t, start, self.tolerance, self.max_iterations);
            out.work += r.iterations;
            if !r.converged {
                out.non_converged += 1;
            }
            state = Some(r.phi);
            prev_deg = deg;
            let e = (libm::cos(r.phi[0]), libm::sin(r.phi[0]));
            out.points
                .push(Some(coupler_point(Point2::new(t.cos, t.sin), e, p)));
        }
        out
    }
}
