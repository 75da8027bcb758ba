//! Errors of a method against the double-double reference.

use super::PositionMethod;
use crate::reference::coupler_point_dd;
use coupler_kinematics::{Circuit, CouplerPoint, FourBar};
use nalgebra::Point2;

/// `36·n` crank angles `θ_k = k·10°/n` over a full turn: `n` samples per 10° dash.
///
/// ```
/// let a = coupler_lab::uniform_angles(4, 10.0);
/// assert_eq!((a.len(), a[1], a[143]), (144, 2.5, 357.5));
/// ```
pub fn uniform_angles(samples_per_dash: usize, dash_deg: f64) -> Vec<f64> {
    let n = samples_per_dash.max(1);
    let total = (360.0 / dash_deg).round() as usize * n;
    (0..total).map(|k| k as f64 * dash_deg / n as f64).collect()
}

/// What a method got right and wrong over one curve, against
/// [`coupler_point_dd`](crate::coupler_point_dd).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Measurement {
    /// Number of angles.
    pub samples: usize,
    /// Largest distance |M − M_ref| over the angles where both assemble (circuit jumps
    /// included), in crank lengths; NaN positions are counted in `nans`, not here.
    pub max_error: f64,
    /// Positions with a NaN coordinate, returned without a `None`.
    pub nans: usize,
    /// Angles where the reference assembles but the method said it does not.
    pub missing: usize,
    /// Angles where the method gave a position but the reference does not assemble.
    pub spurious: usize,
    /// Angles where the position is on the other circuit: farther than
    /// [`Measurement::JUMP_THRESHOLD`] from the reference and at least ten times closer to
    /// the other circuit's reference.
    pub circuit_jumps: usize,
    /// The method's own count of iterations that did not converge.
    pub non_converged: usize,
}

impl Measurement {
    /// An error above this (crank lengths, relative to the curve's scale) may be a circuit
    /// jump; below it, it is just error.
    pub const JUMP_THRESHOLD: f64 = 1e-6;

    /// True when nothing went wrong but accuracy: no NaN, nothing missing or spurious, no
    /// jump, every iteration converged.
    pub fn is_clean(&self) -> bool {
        self.nans == 0
            && self.missing == 0
            && self.spurious == 0
            && self.circuit_jumps == 0
            && self.non_converged == 0
    }
}

fn dist(p: Point2<f64>, r: (coupler_kinematics::Dd, coupler_kinematics::Dd)) -> f64 {
    // (p − r) in double-double, then rounded: exact enough to measure 1e-17 errors.
    let dx = (coupler_kinematics::Dd::from_f64(p.x) - r.0).to_f64();
    let dy = (coupler_kinematics::Dd::from_f64(p.y) - r.1).to_f64();
    dx.hypot(dy)
}

/// Runs `method` over `degrees` and measures it against the reference.
pub fn measure(
    method: &dyn PositionMethod,
    linkage: &FourBar,
    circuit: Circuit,
    point: CouplerPoint,
    degrees: &[f64],
) -> Measurement {
    let trace = method.trace(linkage, circuit, point, degrees);
    let mut m = Measurement {
        samples: degrees.len(),
        non_converged: trace.non_converged,
        ..Measurement::default()
    };
    let scale = 1.0
        + linkage.coupler.max(linkage.rocker).max(linkage.ground)
        + point.u.abs()
        + point.v.abs();
    for (&deg, got) in degrees.iter().zip(&trace.points) {
        let reference = coupler_point_dd(linkage, circuit, point, deg);
        match (got, reference) {
            (None, None) => {}
            (None, Some(_)) => m.missing += 1,
            (Some(p), _) if !(p.x.is_finite() && p.y.is_finite()) => m.nans += 1,
            (Some(_), None) => m.spurious += 1,
            (Some(p), Some(r)) => {
                let err = dist(*p, r);
                m.max_error = m.max_error.max(err);
                if err > Measurement::JUMP_THRESHOLD * scale
                    && let Some(o) = coupler_point_dd(linkage, circuit.other(), point, deg)
                    && dist(*p, o) * 10.0 < err
                {
                    m.circuit_jumps += 1;
                }
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use super::*;

    #[test]
    fn every_method_is_accurate_on_an_ordinary_crank_rocker() {
        let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
        let p = CouplerPoint::new(1.2, -0.7);
        let angles = uniform_angles(20, 10.0);
        for circuit in [Circuit::Open, Circuit::Crossed] {
            for method in all_methods() {
                let m = measure(method.as_ref(), &l, circuit, p, &angles);
                assert!(m.is_clean(), "{} {circuit:?}: {m:?}", method.name());
                let bound = if method.name() == "rk4" { 1e-6 } else { 1e-13 };
                assert!(m.max_error < bound, "{} {circuit:?}: {m:?}", method.name());
            }
        }
    }

    #[test]
    fn shipped_closed_form_to_a_few_ulps() {
        let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
        let angles = uniform_angles(10, 10.0);
        for circuit in [Circuit::Open, Circuit::Crossed] {
            let m = measure(
                &ClosedForm,
                &l,
                circuit,
                CouplerPoint::new(1.2, -0.7),
                &angles,
            );
            assert!(m.is_clean() && m.max_error < 2e-15, "{m:?}");
        }
    }
}
