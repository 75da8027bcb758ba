//! # coupler-atlas
//!
//! A Hrones–Nelson style atlas of four-bar coupler curves: enumerate crank-rocker
//! linkages and coupler points from an atlas spec, compute every coupler curve, render
//! printable pages, index the curves with measured features, and search them.
//!
//! This crate is the `coupler-atlas` command line and a thin facade over the layers it is
//! built from (as lyon's meta-crate is), so that one `use coupler_atlas::…` reaches them
//! all. Each layer is a crate of its own, and Cargo enforces that imports only run down:
//!
//! - [`kinematics`] (pure): exact decimals, [`FourBar`] and Barker's classes, [`Pose`],
//!   [`PoseTable`] and [`Curve`], full curves across toggles, cognates, dash intervals;
//! - [`features`] (pure): straight segments, pseudo-arcs, double points, symmetry, crank
//!   windows, curve flags, the classics' straight runs;
//! - [`design`] (pure): dwell six-bars (Norton's construction, an optimiser, double
//!   dwells, one admissibility contract), their exports (JSON, CSV, DXF), straight-line
//!   four-bars (Evans, Chebyshev) — not re-exported flat: `coupler_atlas::design::…`;
//! - [`layout`] (pure): paper, display lists, labels, text metrics, the pages;
//! - [`render`]: PNG, SVG and PDF of a display list, page diffs;
//! - [`index`]: the JSON index, search and its cache;
//! - [`spec`]: atlas specs (TOML);
//! - [`generate`]: the job (chunks, resume, shards, merge, page rendering).
//!
//! Conventions (a contract, see `docs/conventions.md`): crank = 1, coupler `A`, rocker
//! `B`, ground `C`; O2 = (0, 0), O4 = (C, 0); θ counter-clockwise from +x; coupler point
//! `M = Pa + u·e + v·J·e`.
//!
//! The items of the pure layers and of the index and spec are also re-exported here,
//! flat.

pub use coupler_design as design;
pub use coupler_features as features;
pub use coupler_generate as generate;
pub use coupler_index as index;
pub use coupler_kinematics as kinematics;
pub use coupler_layout as layout;
pub use coupler_render as render;
pub use coupler_specs as spec;

pub use coupler_features::*;
pub use coupler_index::*;
pub use coupler_kinematics::*;
pub use coupler_specs::*;
