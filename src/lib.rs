//! # coupler-atlas
//!
//! A Hrones–Nelson style atlas of four-bar coupler curves: enumerate crank-rocker
//! linkages and coupler points from an atlas spec, compute every coupler curve, render
//! printable pages, index the curves with measured features, and search them.
//!
//! Conventions (a contract, see `docs/conventions.md`): crank = 1, coupler `A`, rocker
//! `B`, ground `C`; O2 = (0, 0), O4 = (C, 0); θ counter-clockwise from +x; coupler point
//! `M = Pa + u·e + v·J·e`.
//!
//! The pure core ([`FourBar`], [`Pose`], [`PoseTable`], [`Curve`]) does no I/O and holds
//! no global state; orchestration ([`generate`]) and the command line sit on top.

pub mod classics;
mod cognates;
mod curve;
mod dash;
pub mod diff;
pub mod dwell;
mod exact;
pub mod generate;
pub mod index;
pub mod layout;
mod linkage;
pub mod methods;
mod pose;
pub mod render;
mod spec;
mod window;

pub mod features;
pub mod search;
pub mod shape;

pub mod reference;
pub mod trace;

pub use cognates::{Cognate, CognateError, cognates};
pub use curve::{CrankTable, Curve, CurveSummary, PoseTable, transmission_range};
pub use dash::{
    DEFAULT_CHORD_TOLERANCE, DEFAULT_DASH_FRACTION, DEFAULT_DASH_STEP_DEG, Dash, DashError,
    DashPattern, DashedCurve, dash_curve, dash_leg, distance_to_segment,
};
pub use exact::{Decimal, DecimalError};
pub use features::{
    CurveFeatures, FeatureExtractor, FeatureTolerances, PseudoArc, Side, StraightSegment, Symmetry,
};
pub use index::{Index, IndexCurve, IndexError, IndexSummary, PageRef, SCHEMA_VERSION};
pub use linkage::{Circuit, Class, CouplerPoint, FourBar, LinkageError};
pub use pose::{CrankAngle, Pose, TOGGLE_ULPS, ToggleGaps, kahan_double_area, sincos_deg};
pub use spec::{
    AtlasSpec, DEFAULT_SPEC_SOURCE, DEFAULT_SPEC_TEXT, DecimalRange, Enumeration, LinkageRanges,
    PAGE_SIZES, PageSettings, PointGrid, Sampling, Spec, SpecError,
};
pub use window::{
    CrankWindow, DEFAULT_WINDOW_STEP_DEG, LineDirection, LineMeasures, WindowError, WindowMeasures,
    WindowSamples, arc_deviation_pct,
};
