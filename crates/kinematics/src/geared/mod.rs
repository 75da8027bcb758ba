//! The geared five-bar linkage (Norton, *Design of Machinery*, §2 "Geared fivebar
//! linkages", §3.7, §3.8, and his program FIVEBAR): kinematics beside the four-bar's, with
//! the same conventions and the same care at toggles. Pure: no I/O, no global state.
//!
//! - [`GearedFiveBar`], [`GearRatio`]: the linkage (ground L1, input crank 1, second crank
//!   L5 geared to it by θ5 = λ·θ2 + φ, dyad L3, L4), validated; Ting's class
//!   ([`TingClass`]) decided exactly; the period `360°·q` for λ = p/q.
//! - [`GearAngle`], [`GearTable`]: both crank angles, formed exactly, over a period.
//! - [`GearedPose`]: closed-form position (cancellation-free half-chord), velocity,
//!   transmission angle; [`GearedFiveBar::gear_pose_table`] for a coupler-point grid.
//! - [`AssemblyMargin`], [`Rotatability`]: does the input turn fully with these gears.
//! - [`geared_equivalent`]: the geared five-bar that traces a four-bar's coupler curve;
//!   [`GearedFiveBar::straight_line`]: the exact straight-line geared five-bar.
//!
//! The equations, their sources and derivations are in `docs/geared-fivebar.md`.

mod angle;
mod equivalent;
mod linkage;
mod margin;
mod mechanism;
mod pose;
mod trace;

pub use angle::{GearAngle, GearTable};
pub use equivalent::{EquivalentError, GearedEquivalent, geared_equivalent};
pub use linkage::{GearRatio, GearedError, GearedFiveBar, MAX_GEAR_TERM, TingClass};
pub use margin::{AssemblyMargin, MARGIN_STEP_DEG, MARGIN_TOL, Rotatability};
pub use mechanism::{TRANSMISSION_STEP_DEG, minus_sign};
pub use pose::{GearedGaps, GearedPose};
