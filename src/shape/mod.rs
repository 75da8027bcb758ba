//! Shape search: find the atlas curves that look like a target path, then fit one exactly.
//! Pure: no I/O, no threads; see `docs/shape-search.md`.

pub mod geom;
pub mod parse;
mod target;

pub use target::{Target, TargetError, Timing};
mod kin;
mod lm;

pub use kin::{CouplerCurve, PointAt, PointSensitivity};
mod fit;
pub mod smooth;
mod traced;

pub use fit::{CurveFit, FitOptions, fit_curve};
