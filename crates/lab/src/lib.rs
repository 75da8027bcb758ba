//! # coupler-lab
//!
//! The benchmark lab, apart from the product: position methods for the four-bar side by
//! side behind one interface ([`PositionMethod`]), so that their cost and their errors
//! can be measured against the double-double reference ([`coupler_point_dd`]); adaptive
//! sampling; the stability sweep. Its binary (`cargo run --release -p coupler-lab --
//! methods|stability|classics|adaptive`) charts them for `docs/methods.md`. The product
//! (`coupler-atlas`) never depends on this crate, except its tests (reference checks).
//!
//! - [`ClosedForm`]: the method the atlas ships ([`Pose::solve`]: the chord's foot and a
//!   half-chord from Kahan's thin factors, formed from the exact inputs and the half-angle).
//! - [`KahanOnD`]: the first shipped version, Kahan's area from a rounded `d`.
//! - [`NaiveClosedForm`]: the same geometry with the textbook `h = √(A² − a²)`, which
//!   cancels catastrophically near toggles (a "what goes wrong" baseline).
//! - [`Newton`]: Newton–Raphson on the loop-closure equations in the coupler and rocker
//!   angles, continued from the previous crank step (what general mechanism solvers do),
//!   with or without a first-order predictor.
//! - [`Rk4`]: classical Runge–Kutta integration of the velocity ODE `dφ/dθ = ω(φ, θ)`,
//!   with or without re-projection onto the constraint after each step.
//! - [`Freudenstein`]: Norton's half-angle form, `θ3 = 2·atan((−E ± √(E² − 4DF))/(2D))`.
//!
//! Every method takes the crank's sine and cosine from [`CrankAngle::from_degrees`], so
//! the differences measured are the methods', not the trigonometry's.
//!
//! [`Pose::solve`]: coupler_kinematics::Pose::solve
//! [`CrankAngle::from_degrees`]: coupler_kinematics::CrankAngle::from_degrees

mod adaptive;
mod closed;
mod features;
mod freudenstein;
mod geared_reference;
mod length;
mod measure;
mod newton;
mod reference;
mod rk4;
mod sweep;

pub use adaptive::{
    AdaptiveSampling, CHECK_FRACTIONS, chord_error, uniform_closed, uniform_density_for,
};
pub use closed::{ClosedForm, KahanOnD, NaiveClosedForm};

pub use features::{CircleFit, fit_circle, straightness_along_x};
pub use freudenstein::Freudenstein;
pub use geared_reference::{geared_point_dd, joints_dd, second_crank_degrees_dd, sincos_deg_dd2};
pub use length::{PositionDd, arc_length_dd};
pub use measure::{Measurement, measure, uniform_angles};
pub use newton::Newton;
pub use reference::{coupler_point_dd, sincos_deg_dd};
pub use rk4::Rk4;
pub use sweep::{SweepCase, SweepRow, angle_for_d, run_case, sweep_cases};

use coupler_kinematics::{Circuit, CouplerPoint, FourBar};
use nalgebra::Point2;

/// The positions one method gives for one coupler point over a sequence of crank angles,
/// with what it reports about itself.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MethodTrace {
    /// One entry per angle: `None` where the method says the linkage does not assemble;
    /// `Some` with NaN coordinates where it produced a NaN without saying so.
    pub points: Vec<Option<Point2<f64>>>,
    /// Number of angles where an iteration stopped without meeting its tolerance.
    pub non_converged: usize,
    /// Work done, in the method's own unit (Newton iterations, ODE right-hand sides);
    /// 0 for the closed forms.
    pub work: usize,
}

/// A way of finding the coupler point's position at a sequence of crank angles.
pub trait PositionMethod: Sync {
    /// A short stable name, e.g. `"closed-form"` (used in tables and charts).
    fn name(&self) -> &'static str;

    /// The coupler point of `linkage` on `circuit` at each angle of `degrees`, in the
    /// order given. Continuation methods (Newton, RK4) carry their state from one angle
    /// to the next and are started from an assembled pose at the first angle.
    fn trace(
        &self,
        linkage: &FourBar,
        circuit: Circuit,
        point: CouplerPoint,
        degrees: &[f64],
    ) -> MethodTrace;
}

/// Every method compared in `coupler-lab methods`, the shipped one first.
pub fn all_methods() -> Vec<Box<dyn PositionMethod>> {
    vec![
        Box::new(ClosedForm),
        Box::new(KahanOnD),
        Box::new(NaiveClosedForm),
        Box::new(Freudenstein),
        Box::new(Newton::default()),
        Box::new(Rk4::plain()),
        Box::new(Rk4::projected()),
        Box::new(Newton {
            predictor: true,
            ..Newton::default()
        }),
    ]
}

/// The coupler point `M = Pa + u·e + v·J·e` for a coupler direction `e = (cos φ3, sin φ3)`.
#[inline]
pub(crate) fn coupler_point(pa: Point2<f64>, e: (f64, f64), p: CouplerPoint) -> Point2<f64> {
    Point2::new(pa.x + p.u * e.0 - p.v * e.1, pa.y + p.u * e.1 + p.v * e.0)
}
