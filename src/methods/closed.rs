//! The closed forms: the shipped one (Kahan half-chord) and the naive textbook one.

use super::{MethodTrace, PositionMethod, coupler_point};
use crate::linkage::{Circuit, CouplerPoint, FourBar};
use crate::pose::{CrankAngle, Pose};
use nalgebra::Point2;

/// The shipped closed form, [`Pose::solve`] at each angle (domain.md §3): foot
/// `a = (A² − B² + d²)/(2d)`, half-chord `h = 2·Area(A, B, d)/d` with Kahan's
/// cancellation-free area. Independent per angle: no state, no iteration, no drift.
#[derive(Clone, Copy, Debug, Default)]
pub struct ClosedForm;

impl PositionMethod for ClosedForm {
    fn name(&self) -> &'static str {
        "closed-form"
    }

    fn trace(
        &self,
        l: &FourBar,
        circuit: Circuit,
        p: CouplerPoint,
        degrees: &[f64],
    ) -> MethodTrace {
        let points = degrees
            .iter()
            .map(|&deg| {
                Pose::solve(l, circuit, &CrankAngle::from_degrees(deg)).map(|pose| pose.point(p))
            })
            .collect();
        MethodTrace {
            points,
            ..MethodTrace::default()
        }
    }
}

/// The textbook closed form with `h = √(A² − a²)` in plain f64: the same geometry as
/// [`ClosedForm`], but `A² − a²` is a difference of nearly equal numbers near a toggle,
/// so it loses digits there (error ~ ε·A²/h instead of ~ ε·A), and where rounding makes it
/// slightly negative the square root returns NaN, which this method passes on silently,
/// as naive code does. A baseline showing what goes wrong; never used on a real path.
#[derive(Clone, Copy, Debug, Default)]
pub struct NaiveClosedForm;

impl PositionMethod for NaiveClosedForm {
    fn name(&self) -> &'static str {
        "naive-sqrt"
    }

    fn trace(
        &self,
        l: &FourBar,
        circuit: Circuit,
        p: CouplerPoint,
        degrees: &[f64],
    ) -> MethodTrace {
        let (a, b, c) = (l.coupler, l.rocker, l.ground);
        let sigma = circuit.sign();
        let points = degrees
            .iter()
            .map(|&deg| {
                let t = CrankAngle::from_degrees(deg);
                let (wx, wy) = (c - t.cos, -t.sin);
                let d2 = wx * wx + wy * wy;
                let d = d2.sqrt();
                if d > a + b || d < (a - b).abs() {
                    return None; // plainly outside: the naive code checks this much
                }
                let foot = (a * a - b * b + d2) / (2.0 * d);
                let h = (a * a - foot * foot).sqrt(); // NaN when rounding makes it < 0
                let ex = (foot * wx - sigma * h * wy) / (d * a);
                let ey = (foot * wy + sigma * h * wx) / (d * a);
                Some(coupler_point(Point2::new(t.cos, t.sin), (ex, ey), p))
            })
            .collect();
        MethodTrace {
            points,
            ..MethodTrace::default()
        }
    }
}

/// A closed form that keeps its digits at a change point: the same geometry as
/// [`ClosedForm`], but the triangle's area and `d²` come from the half-angle factorisation
///
/// `P = (A + B)² − d² = (A + B − C − 1)(A + B + C + 1) + 4C·cos²(θ/2)`,
/// `Q = d² − (A − B)² = (C − 1 − (A − B))(C − 1 + (A − B)) + 4C·sin²(θ/2)`,
/// `h·d = 2·Area = ½·√(P·Q)`, `d² = (C − 1)² + 4C·sin²(θ/2)` (or `(C + 1)² − 4C·cos²(θ/2)`
/// near θ = 180°),
///
/// using `d² = 1 + C² − 2C·cos θ`, `1 − cos θ = 2 sin²(θ/2)` and `1 + cos θ = 2 cos²(θ/2)`.
/// At a change point the links fold flat at θ = 0 or 180°, where the small factor
/// (`C − 1 − |A − B|` or `A + B − C − 1`) is a difference of the exact inputs (exact by
/// Sterbenz's lemma when they are close) and the half-angle term is tiny, so neither
/// loses digits: the rounding of cos θ, which costs [`ClosedForm`] `ε/h` near the fold,
/// no longer enters. At toggles away from θ = 0, 180° it is no better (nor worse): the
/// rounding of cos(θ/2) is then the conditioning of the problem in f64.
#[derive(Clone, Copy, Debug, Default)]
pub struct FactoredClosedForm;

impl FactoredClosedForm {
    /// Coupler direction `e3` at one angle, or `None` where the linkage does not assemble.
    pub fn coupler_dir(l: &FourBar, circuit: Circuit, deg: f64) -> Option<(f64, f64)> {
        let (a, b, c) = (l.coupler, l.rocker, l.ground);
        let t = CrankAngle::from_degrees(deg);
        let (sh, ch) = crate::pose::sincos_deg(0.5 * deg);
        let (s2, c2) = (4.0 * c * sh * sh, 4.0 * c * ch * ch);
        let p = ((a + b) - c - 1.0) * ((a + b) + c + 1.0) + c2;
        let q = ((c - 1.0) - (a - b)) * ((c - 1.0) + (a - b)) + s2;
        if p < 0.0 || q < 0.0 {
            return None;
        }
        let d2 = if t.cos >= 0.0 {
            (c - 1.0) * (c - 1.0) + s2
        } else {
            (c + 1.0) * (c + 1.0) - c2
        };
        let d = d2.sqrt();
        if d == 0.0 {
            return None;
        }
        let hd = 0.5 * p.sqrt() * q.sqrt(); // h·d
        let (wx, wy) = (c - t.cos, -t.sin);
        // foot·d = (A² − B² + d²)/2
        let foot_d = 0.5 * ((a - b) * (a + b) + d2);
        let sigma = circuit.sign();
        let ex = (foot_d * wx - sigma * hd * wy) / (d2 * a);
        let ey = (foot_d * wy + sigma * hd * wx) / (d2 * a);
        Some((ex, ey))
    }
}

impl PositionMethod for FactoredClosedForm {
    fn name(&self) -> &'static str {
        "closed-form-factored"
    }

    fn trace(
        &self,
        l: &FourBar,
        circuit: Circuit,
        p: CouplerPoint,
        degrees: &[f64],
    ) -> MethodTrace {
        let points = degrees
            .iter()
            .map(|&deg| {
                let t = CrankAngle::from_degrees(deg);
                FactoredClosedForm::coupler_dir(l, circuit, deg)
                    .map(|e| coupler_point(Point2::new(t.cos, t.sin), e, p))
            })
            .collect();
        MethodTrace {
            points,
            ..MethodTrace::default()
        }
    }
}
