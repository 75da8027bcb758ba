//! # coupler-kinematics
//!
//! The pure kinematic core of coupler-atlas: exact decimals and Barker classes, the
//! four-bar's closed-form pose, coupler curves sampled by crank angle (one pose per angle
//! shared by every coupler point), full curves across toggles, Roberts–Chebyshev
//! cognates, and the dash intervals of the atlas's pages. No I/O, no global state.
//!
//! Conventions (a contract, see `docs/conventions.md`): crank = 1, coupler `A`, rocker
//! `B`, ground `C`; O2 = (0, 0), O4 = (C, 0); θ counter-clockwise from +x; coupler point
//! `M = Pa + u·e + v·J·e`.
//!
//! What the rest of the pipeline needs from a mechanism is the [`Mechanism`] trait;
//! [`FourBar`] implements it, and [`Linkage`] is the closed set of mechanisms an atlas
//! holds (the identity written in its index).

mod cognates;
mod curve;
mod dash;
mod dd;
mod exact;
mod frame;
mod geared;
mod length;
mod linkage;
mod mechanism;
mod pose;
mod tables;
mod trace;

pub use cognates::{Cognate, CognateError, cognates};
pub use curve::{
    CrankTable, Curve, CurveSummary, MAX_SAMPLES_PER_TURN, PoseTable, samples_per_turn,
    transmission_range,
};
pub use dash::{
    DEFAULT_CHORD_TOLERANCE, DEFAULT_DASH_FRACTION, DEFAULT_DASH_STEP_DEG, Dash, DashError,
    DashPattern, DashedCurve, MAX_SUBDIVISION_DEPTH, dash_curve, dash_curves, dash_leg,
    dash_leg_from, distance_to_segment,
};
pub use dd::Dd;
pub use exact::{Decimal, DecimalError, divides_turn};
pub use frame::{CouplerFrame, Drawing, Joint};
pub use geared::{
    AssemblyMargin, EquivalentError, GearAngle, GearRatio, GearTable, GearedEquivalent,
    GearedError, GearedFiveBar, GearedGaps, GearedPose, MARGIN_STEP_DEG, MARGIN_TOL, MAX_GEAR_TERM,
    Rotatability, TRANSMISSION_STEP_DEG, TingClass, geared_equivalent, minus_sign,
};
pub use length::{ARC_LENGTH_PANELS_PER_TURN, ARC_LENGTH_TOL, ArcLength};
pub use linkage::{Circuit, Class, CouplerPoint, FourBar, LinkageError};
pub use mechanism::{
    Linkage, LinkageClass, LinkageConstants, Mechanism, SymmetryAxis, SymmetryReason,
};
pub use pose::{
    CrankAngle, POINT_LANES, PointLanes, Pose, TOGGLE_ULPS, ToggleGaps, kahan_double_area,
    sincos_deg,
};
pub use tables::{AngleTables, MAX_SHARED_TABLES};
pub use trace::{
    Branch, FullCurve, InputRange, Toggle, ToggleKind, TraceSample, circle_intersections,
    input_range, trace_full,
};
