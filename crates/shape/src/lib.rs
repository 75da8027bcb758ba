//! # coupler-shape
//!
//! Shape search: find the atlas curves that look like a target path, then fit one
//! exactly. Pure: no I/O, no threads; the method and the matching contract are in
//! `docs/shape-search.md`.
//!
//! - [`Target`]: the user's points (open or closed, optionally timed).
//! - [`ShapeCode`]: the compact shape code of a closed atlas curve (normalised elliptic
//!   Fourier descriptors, [`CODE_BYTES`] bytes).
//! - [`find_matches`]: coarse retrieval, then the exact fit ([`fit_curve`]) of the best
//!   candidates, ranked by RMS error, each with its [`Placement`] in the user's frame.
//! - [`refine`]: Levenberg–Marquardt over the linkage's dimensions, the coupler point, the
//!   transform and the crank angles, off the atlas grid.

pub mod cases;
mod code;
mod fit;
mod geom;
mod kin;
mod lattice;
mod lm;
mod matching;
mod open;
mod overlay;
mod placement;
mod refine;
mod sidecar;
mod smooth;
mod target;
mod traced;

pub use code::{CODE_BYTES, CODE_LEN, ClosedQuery, HARMONICS, ShapeCode};
pub use fit::{CurveFit, FitOptions, fit_curve};
pub use geom::{C64, cis, cis_deg, cumulative_length, diameter, fit_similarity, resample};
pub use kin::{AtlasCurve, CouplerCurve, CurveGaps, CurveLanes, PointAt, PointSensitivity};
pub use lattice::LinkageLattice;
pub use matching::{
    Candidate, Match, MatchError, MatchOptions, OpenScan, closed_candidates_in, coarse_candidates,
    find_matches, open_finish, open_lattice_scan, open_linkages, open_scan, rank_candidates,
};
pub use open::{LatticeReport, LatticeSearch, LinkageScreen, linkage_groups};
pub use overlay::{OVERLAY_SIZE_PT, OverlayText, overlay};
pub use placement::Placement;
pub use refine::{MAX_PROPORTION, Refined, proportion, refine};
pub use sidecar::{
    GEARED_RECORD_BYTES, HEADER_BYTES, RECORD_BYTES, RecordKind, SHAPES_FILE, SIDECAR_VERSION,
    ShapeAtlas, SidecarError, SidecarView, decode_sidecar, encode_record, encode_sidecar,
    sidecar_header, sidecar_header_for,
};
pub use smooth::{default_terms, smooth_resample};
pub use target::{Target, TargetError, Timing};

/// Whether the processor has AVX2, the one run-time check every AVX2 path of the crate
/// dispatches on (the standard library caches the answer after the first call). Each
/// such path is a safe body compiled a second time for AVX2, the same IEEE-754
/// operations in the same order, so the results are the same, bit for bit, either way.
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}
