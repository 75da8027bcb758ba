//! The settings a spec shares with both kinds of atlas: `[sampling]` (the crank step
//! and the one dash angle) and `[pages]` (paper, orientation, resolution, curves per page).

use coupler_kinematics::{DEFAULT_DASH_FRACTION, DEFAULT_DASH_STEP_DEG, DashPattern};
use coupler_layout::{Orientation, PaperSize};
use serde::Serialize;

/// Sampling of the crank revolution.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Sampling {
    /// Crank step for the index's measures, degrees (divides 360).
    pub crank_step_deg: f64,
    /// Crank angle per dash, degrees (divides 360; [`DEFAULT_DASH_STEP_DEG`] by default,
    /// 5 as in 1951): the dashes the pages draw and the index counts.
    pub dash_deg: f64,
}

impl Sampling {
    /// The defaults: 1° steps, [`DEFAULT_DASH_STEP_DEG`] per dash.
    pub const DEFAULT: Sampling = Sampling {
        crank_step_deg: 1.0,
        dash_deg: DEFAULT_DASH_STEP_DEG,
    };

    /// The dash pattern of the pages and of the index's dash counts: one dash per
    /// `dash_deg`, [`DEFAULT_DASH_FRACTION`] of it drawn.
    pub fn dash_pattern(&self) -> DashPattern {
        DashPattern {
            step_deg: self.dash_deg,
            fraction: DEFAULT_DASH_FRACTION,
        }
    }
}

/// Page settings.
#[derive(Clone, PartialEq, Serialize)]
pub struct PageSettings {
    /// Curves per page.
    pub curves_per_page: u32,
    /// Paper (written by name: `tabloid`, `letter`, `a4`, `a3`).
    #[serde(serialize_with = "by_name")]
    pub size: PaperSize,
    /// Portrait or landscape (written by name).
    #[serde(serialize_with = "by_name")]
    pub orientation: Orientation,
    /// Raster resolution, dots per inch (in [`coupler_layout::DPI_RANGE`]).
    pub dpi: u32,
}

/// Paper and orientation by name (`size: "tabloid"`), as the manifest's run key of a
/// page set has printed them (it hashes the page set's `Debug` text): a run resumed over
/// an older run's output keeps its key.
impl std::fmt::Debug for PageSettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PageSettings")
            .field("curves_per_page", &self.curves_per_page)
            .field("size", &self.size.name())
            .field("orientation", &self.orientation.name())
            .field("dpi", &self.dpi)
            .finish()
    }
}

fn by_name<T: std::fmt::Display, S: serde::Serializer>(x: &T, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(x)
}
