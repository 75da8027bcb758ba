//! Full-curve page sets: the usual `[atlas]`, `[sampling]` and `[pages]` sections of a
//! spec with a list of `[[curve]]` entries (name, lengths, coupler point, trace) instead
//! of the `[linkages]`/`[points]` grid (`atlas-spec/classics.toml`).

use crate::settings::{PageSettings, Sampling};
use coupler_features::NamedCurve;

/// A parsed full-curve page set: the `[atlas]`, `[sampling]` and `[pages]` sections of a
/// spec with a list of `[[curve]]` entries instead of the grid. Parsed by
/// [`crate::AtlasSpec::parse`] (errors are located like every spec error).
#[derive(Clone, Debug, PartialEq)]
pub struct CurveList {
    /// `[atlas] name`.
    pub name: String,
    /// `[atlas] title` (the name if absent).
    pub title: String,
    /// `[sampling]`: the input step of the traced samples behind the measures, and the
    /// input angle per dash on the pages.
    pub sampling: Sampling,
    /// `[pages]` (one curve per page).
    pub pages: PageSettings,
    /// The curves, in file order.
    pub curves: Vec<NamedCurve>,
}
