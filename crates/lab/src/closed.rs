//! The closed forms: the shipped one (Kahan half-chord) and the naive textbook one.

use super::{MethodTrace, PositionMethod, coupler_point};
use coupler_kinematics::{Circuit, CouplerPoint, FourBar};
use coupler_kinematics::{CrankAngle, Pose, ToggleGaps};
use nalgebra::Point2;

/// The shipped closed form, [`Pose::solve`] at each angle (docs/conventions.md §3, docs/accuracy.md):
/// foot `a = (A² − B² + d²)/(2d)`, half-chord `h = √(P·Q)/(2d)` with Kahan's thin factors
/// `P = (A+B)² − d²`, `Q = d² − (A−B)²` formed from the exact inputs and the crank
/// half-angle. Independent per angle: no state, no iteration, no drift.
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
        let gaps = ToggleGaps::of(l);
        let points = degrees
            .iter()
            .map(|&deg| {
                Pose::solve_with(l, &gaps, circuit, &CrankAngle::from_degrees(deg))
                    .map(|pose| pose.point(p))
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

/// The closed form as first shipped: Kahan's area of the triangle (A, B, d) from a
/// *rounded* `d = |O4 − Pa|`, then `h = 2·Area/d`. Kahan's formula is exact for the sides
/// it is given, but `d` carries the rounding of cos θ, and near a toggle the half-chord's
/// sensitivity `∂h/∂d ~ d/h` amplifies that last bit: the error grows like `ε/h` near a
/// change point (2e-12 at a gap of 1e-7; 8e-12 at 1e-9). The shipped [`ClosedForm`] forms
/// the thin factors from the exact inputs and the half-angle instead (docs/accuracy.md).
#[derive(Clone, Copy, Debug, Default)]
pub struct KahanOnD;

impl PositionMethod for KahanOnD {
    fn name(&self) -> &'static str {
        "kahan-on-d"
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
                if d == 0.0 {
                    return None;
                }
                let h = coupler_kinematics::kahan_double_area(a, b, d)? / d;
                let foot = ((a - b) * (a + b) + d2) / (2.0 * d);
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
