//! Norton's half-angle (Freudenstein) form for the coupler angle.

use super::{MethodTrace, PositionMethod, coupler_point};
use coupler_kinematics::CrankAngle;
use coupler_kinematics::{Circuit, CouplerPoint, FourBar};
use nalgebra::Point2;

/// The coupler angle θ3 by the tangent half-angle substitution on Freudenstein's
/// equation, as printed in Norton, *Design of Machinery*, eqs. 4.11–4.13, with Norton's
/// links a = crank = 1, b = coupler A, c = rocker B, d = ground C:
///
/// `K1 = d/a`, `K4 = d/b`, `K5 = (c² − d² − a² − b²)/(2ab)`,
/// `D = cos θ2 − K1 + K4·cos θ2 + K5`, `E = −2 sin θ2`,
/// `F = K1 + (K4 − 1)·cos θ2 + K5`,
/// `θ3 = 2·atan2(−E ± √(E² − 4DF), 2D)`,
///
/// the `−` root for this crate's [`Circuit::Open`] and the `+` root for
/// [`Circuit::Crossed`] (checked in the tests against the reference). The
/// discriminant `E² − 4DF` is `4·(d² − K²)`-like and cancels near a toggle as the naive
/// `√(A² − a²)` does; a slightly negative discriminant is reported as not assembled.
#[derive(Clone, Copy, Debug, Default)]
pub struct Freudenstein;

impl PositionMethod for Freudenstein {
    fn name(&self) -> &'static str {
        "freudenstein"
    }

    fn trace(
        &self,
        l: &FourBar,
        circuit: Circuit,
        p: CouplerPoint,
        degrees: &[f64],
    ) -> MethodTrace {
        let (a, b, c, d) = (1.0, l.coupler, l.rocker, l.ground);
        let k1 = d / a;
        let k4 = d / b;
        let k5 = (c * c - d * d - a * a - b * b) / (2.0 * a * b);
        let sign = match circuit {
            Circuit::Open => -1.0,
            Circuit::Crossed => 1.0,
        };
        let points = degrees
            .iter()
            .map(|&deg| {
                let t = CrankAngle::from_degrees(deg);
                let dd = t.cos - k1 + k4 * t.cos + k5;
                let e = -2.0 * t.sin;
                let f = k1 + (k4 - 1.0) * t.cos + k5;
                let disc = e * e - 4.0 * dd * f;
                if disc < 0.0 {
                    return None;
                }
                let theta3 = 2.0 * libm::atan2(-e + sign * disc.sqrt(), 2.0 * dd);
                let dir = (libm::cos(theta3), libm::sin(theta3));
                Some(coupler_point(Point2::new(t.cos, t.sin), dir, p))
            })
            .collect();
        MethodTrace {
            points,
            ..MethodTrace::default()
        }
    }
}
