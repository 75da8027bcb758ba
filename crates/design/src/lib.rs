//! # coupler-design
//!
//! Mechanisms designed from coupler curves, pure (no I/O, no global state):
//!
//! - **dwell six-bars** (Norton, *Design of Machinery*, §3.9; docs/conventions.md §6): a
//!   single dwell on a pseudo-arc by Norton's construction or an optimiser
//!   ([`single_dwell`]), a double dwell on two arcs ([`double_dwell_arcs`]) or two straight
//!   segments ([`double_dwell_lines`]), and the search for a double dwell on a whole curve
//!   ([`best_double_dwell`]). Every design is simulated and passes one admissibility
//!   contract ([`Limits`]) or is refused with a typed reason ([`DwellError`],
//!   [`Inadmissible`]); it is measured as its user feels it ([`DwellDesign`]: the felt
//!   dwell, output velocity and acceleration, closest approach to O6, warnings);
//! - its **exports** for CAD and spreadsheets ([`Export`]: JSON, CSV, DXF);
//! - **straight-line four-bars**: the symmetric Evans linkage from its design condition
//!   and its Chebyshev form ([`evans`], [`StraightDesign`]).

mod design;
mod double;
mod error;
mod export;
mod motion;
mod report;
mod single;
mod stage;
mod straight;

pub use design::{
    ACCELERATION_WARNING_FACTOR, DEFAULT_DWELL_TOL_DEG, DEFAULT_MAX_JITTER_PCT,
    DEFAULT_MAX_LINK_RATIO, DEFAULT_MIN_TRANSMISSION_DEG, DEFAULT_STEP_DEG, DriverReport, Dwell,
    DwellDesign, DwellKind, FeltDwell, Limits, Method, Peak, SWING_ACCURACY_DEG,
    TRANSMISSION_WARNING_DEG,
};
pub use double::{
    CENTRE_SEPARATION_FACTOR, DEFAULT_DOUBLE_ARC_RADIUS_TOL_PCT, DoubleArcOptions,
    DoubleDwellSearch, MIN_FREE_SWING_DEG, NoDoubleDwell, SWING_TOLERANCE, best_double_dwell,
    double_dwell_arcs, double_dwell_lines,
};
pub use error::{DwellError, Inadmissible};
pub use export::{Export, ExportFormat, Joint, Link};
pub use motion::{Driver, DriverState, Motion, Placement};
pub use report::fmt_deg;
pub use single::single_dwell;
pub use stage::{OutputMotion, Stage, dyad_point};
pub use straight::{
    ChebyshevForm, FamilyPoint, SPAN_TOLERANCES_PCT, StraightDesign, StraightSpan, evans,
    evans_coupler, evans_with, family,
};

/// Checks a simulation step: it must divide 360° and lie in (0°, 10°].
pub(crate) fn check_step(step: f64) -> Result<(), DwellError> {
    if step > 0.0 && step <= 10.0 && coupler_kinematics::divides_turn(step) {
        Ok(())
    } else {
        Err(DwellError::BadStep(step))
    }
}
