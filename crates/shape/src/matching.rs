//! Ranked matches of a target against a set of atlas curves: coarse retrieval, then the
//! exact fit of the best candidates, ranked by the exact RMS error.

use crate::code::{ClosedQuery, ShapeCode};
use crate::fit::{CurveFit, FitOptions, fit_with, scan_open};
use crate::kin::CouplerCurve;
use crate::placement::Placement;
use crate::target::Target;
use crate::traced::Traced;

/// A curve a search can return: its id (in the atlas) and what traces it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasCurve {
    /// Id in the atlas (index order).
    pub id: u64,
    /// Linkage, circuit and coupler point.
    pub curve: CouplerCurve,
}

/// Settings of a search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatchOptions {
    /// Allow reflected matches (by the mirror identity, another real four-bar).
    pub allow_mirror: bool,
    /// Matches returned.
    pub top: usize,
    /// Candidates from the coarse stage that get the exact fit.
    pub candidates: usize,
    /// The exact fit's settings (its `allow_mirror` is overridden by this one's).
    pub fit: FitOptions,
}

impl MatchOptions {
    /// Mirror allowed, top 5, 64 candidates fitted exactly.
    pub const DEFAULT: MatchOptions = MatchOptions {
        allow_mirror: true,
        top: 5,
        candidates: 64,
        fit: FitOptions::DEFAULT,
    };
}

impl Default for MatchOptions {
    fn default() -> Self {
        MatchOptions::DEFAULT
    }
}

/// One ranked match.
#[derive(Clone, Debug, PartialEq)]
pub struct Match {
    /// The atlas curve.
    pub id: u64,
    /// What traces it (atlas frame, crank units).
    pub curve: CouplerCurve,
    /// The coarse stage's distance (lower is closer; comparable within one search only).
    pub coarse: f64,
    /// The exact fit.
    pub fit: CurveFit,
    /// The linkage in the user's frame.
    pub placement: Placement,
    /// RMS distance as a percentage of the target's size.
    pub rms_pct: f64,
    /// Largest distance as a percentage of the target's size.
    pub max_pct: f64,
}

/// Why a search could not run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MatchError {
    /// Codes and curves of different counts.
    #[error("{codes} shape codes for {curves} curves")]
    CodeCount {
        /// Codes given.
        codes: usize,
        /// Curves given.
        curves: usize,
    },
    /// The target's shape could not be described (e.g. every point on a line through
    /// its own reversal).
    #[error("the target's shape cannot be described")]
    Undescribable,
}

/// The coarse distance of every curve to `target`, in the curves' order: for a closed
/// target the shape-code distance ([`ClosedQuery::distance`]); for an open one the
/// misfit of the best window of the re-traced curve ([`scan_open`], a descriptor-free
/// stage, see `docs/shape-search.md` for why). `f64::INFINITY` for a curve that cannot be
/// compared.
pub fn coarse_distances(
    target: &Target,
    curves: &[AtlasCurve],
    codes: &[ShapeCode],
    options: &MatchOptions,
) -> Result<Vec<f64>, MatchError> {
    if target.is_closed() {
        if codes.len() != curves.len() {
            return Err(MatchError::CodeCount {
                codes: codes.len(),
                curves: curves.len(),
            });
        }
        let q = ClosedQuery::new(&target.complex_points(), options.allow_mirror)
            .ok_or(MatchError::Undescribable)?;
        Ok(codes.iter().map(|c| q.distance(c)).collect())
    } else {
        let p = target.complex_points();
        Ok(curves
            .iter()
            .map(|c| {
                Traced::new(&c.curve, OPEN_SCAN_TRACE)
                    .and_then(|t| {
                        scan_open(&p, &t, options.allow_mirror)
                            .first()
                            .map(|s| s.score)
                    })
                    .unwrap_or(f64::INFINITY)
            })
            .collect())
    }
}

/// Points of the target used to rank the candidates (the final fits use them all).
const RANK_POINTS: usize = 40;
/// Iterations of each ranking fit.
const RANK_ITERATIONS: usize = 30;

/// Crank samples of the trace an open target's coarse scan uses.
const OPEN_SCAN_TRACE: usize = 360;

/// Ranked matches of `target` among `curves` (with their shape codes, in the same order):
/// the `options.candidates` curves nearest by [`coarse_distances`] get the exact fit
/// ([`super::fit_curve`]), and the best `options.top` by RMS error are returned, ties
/// broken by coarse distance then id. Deterministic: the same inputs give the same
/// matches, bit for bit. Sequential; a caller may split `curves` into chunks, run
/// [`coarse_distances`] on each in parallel and call [`rank_candidates`].
pub fn find_matches(
    target: &Target,
    curves: &[AtlasCurve],
    codes: &[ShapeCode],
    options: &MatchOptions,
) -> Result<Vec<Match>, MatchError> {
    let d = coarse_distances(target, curves, codes, options)?;
    Ok(rank_candidates(target, curves, &d, options))
}

/// The exact stage of [`find_matches`], given every curve's coarse distance.
pub fn rank_candidates(
    target: &Target,
    curves: &[AtlasCurve],
    coarse: &[f64],
    options: &MatchOptions,
) -> Vec<Match> {
    let mut order: Vec<usize> = (0..curves.len().min(coarse.len()))
        .filter(|&i| coarse[i].is_finite())
        .collect();
    order.sort_by(|&a, &b| {
        coarse[a]
            .total_cmp(&coarse[b])
            .then(curves[a].id.cmp(&curves[b].id))
    });
    order.truncate(options.candidates.max(options.top));
    let fit_options = FitOptions {
        allow_mirror: options.allow_mirror,
        ..options.fit
    };
    // Every candidate gets a quick fit on at most RANK_POINTS of the target's points;
    // the best few get the full fit on every point.
    let thin = target.thinned(RANK_POINTS);
    let quick_options = FitOptions {
        max_iterations: RANK_ITERATIONS,
        ..fit_options
    };
    let mut quick: Vec<(f64, usize)> = order
        .iter()
        .filter_map(|&i| {
            let c = &curves[i];
            let traced = Traced::new(&c.curve, fit_options.trace_samples)?;
            fit_with(&thin, &c.curve, &traced, &quick_options).map(|f| (f.rms, i))
        })
        .collect();
    quick.sort_by(|a, b| {
        a.0.total_cmp(&b.0)
            .then(coarse[a.1].total_cmp(&coarse[b.1]))
            .then(curves[a.1].id.cmp(&curves[b.1].id))
    });
    quick.truncate((2 * options.top).max(options.top + 4));
    let size = target.size();
    let mut matches: Vec<Match> = quick
        .iter()
        .filter_map(|&(_, i)| {
            let c = &curves[i];
            let traced = Traced::new(&c.curve, fit_options.trace_samples)?;
            let fit = fit_with(target, &c.curve, &traced, &fit_options)?;
            Some(Match {
                id: c.id,
                curve: c.curve,
                coarse: coarse[i],
                placement: Placement::of(&c.curve, &fit),
                rms_pct: 100.0 * fit.rms / size,
                max_pct: 100.0 * fit.max / size,
                fit,
            })
        })
        .collect();
    matches.sort_by(|a, b| {
        a.fit
            .rms
            .total_cmp(&b.fit.rms)
            .then(a.coarse.total_cmp(&b.coarse))
            .then(a.id.cmp(&b.id))
    });
    matches.truncate(options.top);
    matches
}
