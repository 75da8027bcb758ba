//! # coupler-specs
//!
//! Atlas specs: TOML files that say which linkages, coupler points, circuits, sampling
//! and pages make an atlas (`docs/spec-format.md`), or list named curves for a full-curve
//! page set; and target files for shape search (CSV or JSON lists of points). Parsing validates everything before any work starts; every error names the
//! file, the line, the column and the key.

mod count;
mod curves;
mod features;
mod geared;
mod ranges;
mod settings;
mod spec;
mod target_file;

pub use count::CrankRockers;
pub use curves::CurveList;
pub use features::FeatureSettings;
pub use geared::{GearedEnumeration, GearedRanges, REPEATED_PHASE, same_curves};
pub use ranges::{DecimalRange, LinkageRanges};
pub use settings::{PageSettings, Sampling};
pub use spec::{
    AtlasLinkages, AtlasSpec, DEFAULT_SPEC_SOURCE, DEFAULT_SPEC_TEXT, Enumeration, MAX_NAME_LEN,
    MAX_RANGE_VALUES, PointGrid, Spec, SpecError,
};
pub use target_file::{TargetFile, TargetFileError};
