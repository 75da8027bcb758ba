//! Ranked matches of a target against a set of atlas curves: coarse retrieval, then the
//! exact fit of the best candidates, ranked by the exact RMS error.

use crate::code::{ClosedQuery, ShapeCode};
use crate::fit::{
    CurveFit, FitOptions, RobustKept, Start, UntimedFit, continue_untimed, fit_closed_both,
    fit_timed, fit_timed_from, fit_untimed, fit_untimed_kept, fit_with, robust_kept,
};
use crate::kin::{AtlasCurve, CouplerCurve};
use crate::open::{
    LatticeReport, LatticeSearch, LinkageScreen, OpenQuery, Stage1, keep_each_reflection,
    linkage_groups, open_candidates, open_stage1, open_stage1_lattice, open_stage2,
};
use crate::placement::Placement;
use crate::sidecar::{SidecarError, SidecarView};
use crate::target::Target;
use crate::traced::Traced;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::Arc;

/// Settings of a search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatchOptions {
    /// Allow reflected matches (by the mirror identity, another real four-bar).
    pub allow_mirror: bool,
    /// Matches returned.
    pub top: usize,
    /// Candidates from the coarse stage that get the exact fit (quick fits on at most 40
    /// points; the best `4·top` then fitted on every point). With `allow_mirror`, this
    /// many of each reflection.
    pub candidates: usize,
    /// The same for an open target (its candidates come from the per-linkage scan, whose
    /// misfit ranks less sharply than the closed codes' distance, and are cheap to fit:
    /// they start from the scan's crank angles). With `allow_mirror`, this many of each
    /// reflection.
    pub open_candidates: usize,
    /// Most linkages an open target's scan covers: an atlas of more linkages is first
    /// screened ([`LinkageScreen`]) and only the most promising this many are scanned.
    /// The default, `usize::MAX`, scans every linkage: the screen is an estimate that
    /// misses the source's linkage part of the time (`docs/shape-search.md`), so it is
    /// opt-in.
    pub open_linkages: usize,
    /// An open target's lattice search (coarse to fine over the atlas's linkage lattice,
    /// [`LatticeSearch`]) on an atlas of more than `open_lattice.above` linkages, unless
    /// a screen applies (`open_linkages`). `above: usize::MAX` scans every linkage.
    pub open_lattice: LatticeSearch,
    /// The exact fit's settings (its `allow_mirror` is overridden by this one's).
    pub fit: FitOptions,
}

impl MatchOptions {
    /// Mirror allowed, top 5, 64 candidates fitted exactly (1,024 for an open target),
    /// no screen; an open target's linkages all scanned on an atlas of at most 2,000 of
    /// them, searched coarse to fine over the linkage lattice on a larger one
    /// ([`LatticeSearch::DEFAULT`]).
    pub const DEFAULT: MatchOptions = MatchOptions {
        allow_mirror: true,
        top: 5,
        candidates: 64,
        open_candidates: 1024,
        open_linkages: usize::MAX,
        open_lattice: LatticeSearch::DEFAULT,
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
    /// A record of the shape sidecar read during the search does not decode.
    #[error(transparent)]
    Sidecar(#[from] SidecarError),
}

/// A curve the coarse stage proposes for the exact fit: the curve, its coarse distance
/// (lower is closer; comparable within one search only), whether it is proposed for the
/// reflected target and, for an open target, where the exact fit starts (the reflection
/// and the crank angle of every target point, from the per-linkage scan).
#[derive(Clone, Debug)]
pub struct Candidate {
    /// The atlas curve.
    pub curve: AtlasCurve,
    /// The coarse distance.
    pub coarse: f64,
    /// Whether the candidate is proposed for the reflected target (an open candidate's
    /// start is reflected; a closed one's coarse distance is to the reflected target's
    /// description).
    reflected: bool,
    start: Option<Start>,
}

/// The coarse stage over `curves` (with their shape codes, in the same order; open targets
/// do not use the codes and accept an empty slice): at most `options.candidates`
/// candidates, best first (ties by id).
///
/// - **Closed** target: the shape-code distance ([`ClosedQuery::distance`]) of every curve.
/// - **Open** target: a scan per linkage (runs of `curves` that share a linkage and
///   circuit, as an atlas lists them): the coupler point enters the curve linearly, so
///   one least-squares problem per crank-window hypothesis answers for every coupler point
///   of the linkage (`docs/shape-search.md`, "Open targets"); an atlas of more than
///   `options.open_linkages` linkages is screened first ([`open_linkages`]), else one of
///   more than `options.open_lattice.above` is searched coarse to fine over its linkage
///   lattice ([`open_lattice_scan`]).
///
/// To use several threads: for a closed target, split `curves`, call this on each part in
/// parallel and hand all the candidates to [`rank_candidates`]; for an open one, score the
/// linkages in parallel in [`open_linkages`]'s closure, share its linkages out to
/// [`open_scan`] in parallel, and finish with [`open_finish`].
pub fn coarse_candidates(
    target: &Target,
    curves: &[AtlasCurve],
    codes: &[ShapeCode],
    options: &MatchOptions,
) -> Result<Vec<Candidate>, MatchError> {
    let keep = options.kept(target);
    if target.is_closed() {
        if codes.len() != curves.len() {
            return Err(MatchError::CodeCount {
                codes: codes.len(),
                curves: curves.len(),
            });
        }
        let q = ClosedQuery::new(&target.complex_points(), options.allow_mirror)
            .ok_or(MatchError::Undescribable)?;
        closed_stage(
            &q,
            target,
            0..curves.len(),
            keep,
            |i| Ok(Some(codes[i])),
            |i| Ok(curves[i]),
            |i| curves[i].id,
        )
    } else {
        let groups = linkage_groups(curves);
        if let Some((scan, _)) = open_lattice_scan(target, curves, &groups, options)? {
            return open_finish(target, curves, vec![scan], options);
        }
        let q = OpenQuery::new(target, options.allow_mirror).ok_or(MatchError::Undescribable)?;
        let groups = open_linkages(target, groups, options, |screen, groups| {
            groups
                .iter()
                .map(|g| screen.score(&curves[g.clone()]))
                .collect()
        });
        Ok(open_candidates(&q, curves, &groups, keep)
            .into_iter()
            .map(|c| Candidate {
                curve: c.curve,
                coarse: c.misfit,
                reflected: c.start.mirrored,
                start: Some(c.start),
            })
            .collect())
    }
}

/// The coarse stage of a **closed** target over the curves `ids` of a sidecar read in
/// place ([`SidecarView`]): the same candidates as [`coarse_candidates`] gives on those
/// curves decoded ([`crate::decode_sidecar`]), without decoding them: every code is read
/// where it lies, and only the best `options.candidates` records (by distance, ties by
/// id; of each reflection, with reflection allowed) are decoded. `query` is the target's description
/// (`ClosedQuery::new(&target.complex_points(), options.allow_mirror)`), made once for
/// all parts: to use several threads, call this on parts of `0..view.len()` in parallel
/// and hand all the candidates to [`rank_candidates`]. An error if a record read does not
/// decode.
pub fn closed_candidates_in(
    query: &ClosedQuery,
    target: &Target,
    view: &SidecarView<'_>,
    ids: Range<usize>,
    options: &MatchOptions,
) -> Result<Vec<Candidate>, MatchError> {
    let ids = ids.start.min(view.len())..ids.end.min(view.len());
    // Ids are record positions.
    closed_stage(
        query,
        target,
        ids,
        options.kept(target),
        |i| Ok(view.code(i)?),
        |i| Ok(view.curve(i)?),
        |i| i as u64,
    )
}

/// The closed coarse stage over the curves `ids`, however they are held: `code(i)` gives
/// curve `i`'s shape code (`None`: it has none), `curve(i)` the curve (called only for
/// the kept candidates, and for every curve when the target is timed: its period), and
/// `id(i)` its id. The best `keep` by distance, ties by id, best first; with reflection
/// allowed, the best `keep` of each reflection (by the distance to the target's
/// unreflected or reflected description: the unreflected ones are those of the query
/// without reflection, bit for bit). A curve whose period is shorter than the target's
/// timed angles cannot carry it and is left out.
fn closed_stage(
    query: &ClosedQuery,
    target: &Target,
    ids: Range<usize>,
    keep: usize,
    code: impl Fn(usize) -> Result<Option<ShapeCode>, MatchError>,
    curve: impl Fn(usize) -> Result<AtlasCurve, MatchError>,
    id: impl Fn(usize) -> u64,
) -> Result<Vec<Candidate>, MatchError> {
    let timed = target.angle_span().is_some();
    let mirror = query.allows_mirror();
    // Per reflection.
    let mut scored: [Vec<(f64, u64, usize)>; 2] = [Vec::new(), Vec::new()];
    for i in ids {
        let code = code(i)?.unwrap_or(ShapeCode::ABSENT);
        let d = [
            query.distance_of(&code, false),
            if mirror {
                query.distance_of(&code, true)
            } else {
                f64::INFINITY
            },
        ];
        if !d.iter().any(|d| d.is_finite()) {
            continue;
        }
        if timed && !target.fits_period(curve(i)?.curve.period_deg()) {
            continue;
        }
        for (m, d) in d.into_iter().enumerate() {
            if d.is_finite() {
                scored[m].push((d, id(i), i));
            }
        }
    }
    let by = |a: &(f64, u64, usize), b: &(f64, u64, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
    let mut out = Vec::new();
    for (m, mut scored) in scored.into_iter().enumerate() {
        if scored.len() > keep {
            scored.select_nth_unstable_by(keep, by);
            scored.truncate(keep);
        }
        scored.sort_by(by);
        for (d, _, i) in scored {
            out.push(Candidate {
                curve: curve(i)?,
                coarse: d,
                reflected: m == 1,
                start: None,
            });
        }
    }
    Ok(out)
}

/// Points of the target used to rank the candidates (the final fits use them all).
const RANK_POINTS: usize = 40;
/// Iterations of each ranking fit of a closed target.
const RANK_ITERATIONS: usize = 30;
/// Iterations of each quick fit of an open target (from its scan start; a finalist's
/// continues to the final cap). 15 ranks the 200 open retrieval cases as 30 did, with
/// the same misses (`docs/shape-search.md`, "Eighteenth part").
pub(crate) const RANK_ITERATIONS_OPEN: usize = 15;
/// An open target's candidates (best by coarse distance) that also get the exact fit's
/// own robust start.
const ROBUST_OPEN: usize = 64;
/// Iterations of an untimed open candidate's robust start's two finishes while ranking
/// (a finalist's continue to the final cap: the same fit as one run). They ran to the
/// final cap before (`docs/benchmarks.md`, "Open queries: the exact stage's work cut").
const ROBUST_RANK_ITERATIONS: usize = 4;

/// Ranked matches of `target` among `curves` (with their shape codes, in the same order;
/// an open target needs none): the coarse stage ([`coarse_candidates`]), then the exact
/// fit of the candidates ([`rank_candidates`]); the best `options.top` by RMS error,
/// ties broken by coarse distance then id. Deterministic: the same inputs give the same
/// matches, bit for bit, on any number of threads. The coarse stage is sequential (an
/// open target's lattice search runs on the calling thread's rayon pool); the exact fits run on the
/// calling thread's rayon pool ([`rank_candidates`]).
pub fn find_matches(
    target: &Target,
    curves: &[AtlasCurve],
    codes: &[ShapeCode],
    options: &MatchOptions,
) -> Result<Vec<Match>, MatchError> {
    let c = coarse_candidates(target, curves, codes, options)?;
    Ok(rank_candidates(target, c, options))
}

/// Stage 1 of an open target's coarse stage over one part of the atlas ([`open_scan`]).
#[derive(Clone, Debug)]
pub struct OpenScan(Vec<Stage1>);

/// The linkages an open target's scan covers, as [`coarse_candidates`] picks them, of
/// the atlas's `groups`, every run of its curves sharing a linkage and circuit
/// (`linkage_groups(curves)`, [`linkage_groups`]): all of them when there are at most
/// `options.open_linkages`; else those with the best [`LinkageScreen::score`]s. `score`
/// scores the runs (callers may compute them in parallel; [`LinkageScreen::score`] of
/// each is what it must return). In atlas order.
pub fn open_linkages(
    target: &Target,
    groups: Vec<Range<usize>>,
    options: &MatchOptions,
    score: impl Fn(&LinkageScreen, &[Range<usize>]) -> Vec<f64>,
) -> Vec<Range<usize>> {
    match LinkageScreen::new(target, options.allow_mirror) {
        Some(screen) if groups.len() > options.open_linkages => {
            let scores = score(&screen, &groups);
            select_linkages(&groups, &scores, options.open_linkages)
        }
        _ => groups,
    }
}

/// Stage 1 of an open target by the lattice search ([`LatticeSearch`]), when it applies:
/// an open target, an atlas of more than `options.open_lattice.above` linkages and no
/// screen (not more than `options.open_linkages` linkages); `None` otherwise (scan the
/// linkages of [`open_linkages`]). `groups` are the atlas's linkages,
/// `linkage_groups(curves)` ([`linkage_groups`]; cut once, they serve [`open_linkages`]
/// too). Complete it with [`open_finish`]. Its linkages are scanned in parallel on the
/// calling thread's rayon pool; the result is the same on any number of threads.
pub fn open_lattice_scan(
    target: &Target,
    curves: &[AtlasCurve],
    groups: &[Range<usize>],
    options: &MatchOptions,
) -> Result<Option<(OpenScan, LatticeReport)>, MatchError> {
    if target.is_closed() {
        return Ok(None);
    }
    if groups.len() <= options.open_lattice.above || groups.len() > options.open_linkages {
        return Ok(None);
    }
    let q = OpenQuery::new(target, options.allow_mirror).ok_or(MatchError::Undescribable)?;
    let (stage1, report) = open_stage1_lattice(
        &q,
        curves,
        groups,
        &options.open_lattice,
        options.kept(target),
    );
    Ok(Some((OpenScan(stage1), report)))
}

/// The `keep` groups of least score (ties by position), in their original order.
fn select_linkages(groups: &[Range<usize>], scores: &[f64], keep: usize) -> Vec<Range<usize>> {
    let mut order: Vec<usize> = (0..groups.len()).collect();
    order.sort_by(|&a, &b| scores[a].total_cmp(&scores[b]).then(a.cmp(&b)));
    order.truncate(keep);
    order.sort_unstable();
    order.into_iter().map(|i| groups[i].clone()).collect()
}

/// Stage 1 of the coarse stage of an **open** target over some of its linkages (`groups`,
/// ranges of `curves`, e.g. a share of [`open_linkages`]), to run shares in parallel;
/// [`open_finish`] completes it. The result does not depend on how the linkages are
/// shared out.
pub fn open_scan(
    target: &Target,
    curves: &[AtlasCurve],
    groups: &[Range<usize>],
    options: &MatchOptions,
) -> Result<OpenScan, MatchError> {
    let q = OpenQuery::new(target, options.allow_mirror).ok_or(MatchError::Undescribable)?;
    Ok(OpenScan(open_stage1(
        &q,
        curves,
        groups,
        options.kept(target),
    )))
}

/// Stage 2 of an open target's coarse stage, from the [`open_scan`]s of parts of
/// `curves`: the same candidates as [`coarse_candidates`] on the whole of `curves`.
pub fn open_finish(
    target: &Target,
    curves: &[AtlasCurve],
    scans: Vec<OpenScan>,
    options: &MatchOptions,
) -> Result<Vec<Candidate>, MatchError> {
    let q = OpenQuery::new(target, options.allow_mirror).ok_or(MatchError::Undescribable)?;
    let all: Vec<Stage1> = scans.into_iter().flat_map(|s| s.0).collect();
    Ok(open_stage2(&q, curves, all, options.kept(target))
        .into_iter()
        .map(|c| Candidate {
            curve: c.curve,
            coarse: c.misfit,
            reflected: c.start.mirrored,
            start: Some(c.start),
        })
        .collect())
}

impl MatchOptions {
    /// Candidates that get the exact fit for `target`.
    fn kept(&self, target: &Target) -> usize {
        if target.is_closed() {
            self.candidates
        } else {
            self.open_candidates
        }
        .max(self.top)
    }
}

/// The exact stage of [`find_matches`]: the best `options.candidates` of `candidates`
/// (by coarse distance, then id; duplicates of one curve dropped) each get a quick fit,
/// the best `4·top` (at least `top + 8`) the full fit on every point, and the best `options.top` by RMS error
/// are returned, each curve once. The candidates are counted per reflection (an open
/// one's start, a closed one's coarse description): with `allow_mirror`, the unreflected
/// ones get the same quick fits, robust starts and final fits as without it (fitted
/// without reflection), and as many reflected ones theirs (fitted with reflection
/// allowed), so allowing reflection never makes a rank's error worse. A closed target's
/// curve that is a candidate of both reflections is fitted both ways at once, with the
/// same fits bit for bit (the work both fits share done once). The candidates are fitted in parallel on the calling thread's rayon pool
/// (run it inside `ThreadPool::install` to choose the threads); the result is the same,
/// bit for bit, on any number of threads.
pub fn rank_candidates(
    target: &Target,
    mut candidates: Vec<Candidate>,
    options: &MatchOptions,
) -> Vec<Match> {
    candidates.sort_by(|a, b| {
        a.coarse
            .total_cmp(&b.coarse)
            .then(a.curve.id.cmp(&b.curve.id))
            .then(a.reflected.cmp(&b.reflected))
    });
    candidates.dedup_by(|a, b| a.curve.id == b.curve.id && a.reflected == b.reflected);
    keep_each_reflection(&mut candidates, options.kept(target), |c| c.reflected);
    // Each candidate's place among those of its reflection: the robust starts go to the
    // best of each.
    let place: Vec<usize> = {
        let mut count = [0usize; 2];
        candidates
            .iter()
            .map(|c| {
                let k = &mut count[usize::from(c.reflected)];
                *k += 1;
                *k - 1
            })
            .collect()
    };
    let fit_options = FitOptions {
        allow_mirror: options.allow_mirror,
        ..options.fit
    };
    // An unreflected candidate is fitted without reflection, as a query without
    // `allow_mirror` fits it: with reflection allowed, it gets the very same fits (a
    // reflected one is fitted with reflection allowed, both ways).
    let plain_options = FitOptions {
        allow_mirror: false,
        ..options.fit
    };
    let options_of = |c: &Candidate| {
        if !c.reflected {
            plain_options
        } else {
            fit_options
        }
    };
    let quick_of = |c: &Candidate| FitOptions {
        max_iterations: match c.start {
            Some(_) => RANK_ITERATIONS_OPEN,
            None => RANK_ITERATIONS,
        },
        ..options_of(c)
    };
    let p = target.complex_points();
    // Every candidate gets a quick fit: closed targets on at most RANK_POINTS of the
    // target's points, open ones from their start on every point (the starts are per
    // point); the best few get the full fit. Candidates are fitted in parallel (on the
    // calling thread's rayon pool); each fit is sequential and the lists keep the
    // candidates' order, so the result does not depend on the threads.
    let thin = target.thinned(RANK_POINTS);
    // A candidate's dense trace, made once: the quick fit, the robust start and the final
    // fit all scan it. A closed target's curve that is a candidate of both reflections
    // shares one trace (the same bits).
    let traced_of =
        |c: &Candidate| Traced::new(&c.curve.curve, fit_options.trace_samples).map(Arc::new);
    // A closed target's curve in both reflections' lists is fitted both ways at once
    // (`fit_closed_both`: the same fits, bit for bit, as fitting each candidate alone,
    // with the unreflected starts' work done once): `partner[i]` is the reflected
    // candidate of unreflected candidate `i`'s curve, if any.
    let partner = closed_partners(&candidates.iter().collect::<Vec<_>>());
    // An open target's best few candidates by coarse distance also get the exact fit's own
    // robust start (its window scan of the traced curve): the scan's start can sit in the
    // basin of a neighbouring window. A timed target's is fitted in full (its fit is timed
    // after the finishes); an untimed one's two finishes stop at ROBUST_RANK_ITERATIONS
    // and are kept, and only a finalist's are continued to the final cap (the same fit as
    // one run).
    enum Robust {
        Done(CurveFit),
        Kept(RobustKept),
    }
    struct Ranked {
        traced: Option<Option<Arc<Traced>>>,
        robust: Option<Robust>,
        quick: Option<f64>,
        // An open candidate's quick fit from its scan start, kept for its final fit to
        // continue (`continue_untimed`: the same fit as one run to the final cap).
        scan: Option<UntimedFit>,
    }
    let quick_one = |i: usize| -> Ranked {
        let c = &candidates[i];
        let mut traced = None;
        let robust = match &c.start {
            Some(_) if place[i] < ROBUST_OPEN => {
                let t = traced.insert(traced_of(c));
                t.as_ref().and_then(|t| {
                    let (curve, options) = (&c.curve.curve, &options_of(c));
                    if target.timing().is_timed() {
                        fit_with(target, curve, t, options).map(Robust::Done)
                    } else {
                        let cap = ROBUST_RANK_ITERATIONS;
                        Some(Robust::Kept(robust_kept(target, curve, t, options, cap)))
                    }
                })
            }
            _ => None,
        };
        let robust_rms = match &robust {
            Some(Robust::Done(f)) => Some(f.rms),
            Some(Robust::Kept(k)) => k.rms(),
            None => None,
        };
        let mut scan = None;
        let f = match &c.start {
            // A timed target's candidate is ranked by a timed fit: the untimed fit's error
            // is a lower bound of it that can tie many curves (every rocker pin traces a
            // circle's arc, which fits any other). Its final fit runs the untimed fit in
            // one go (the same fit as the quick one continued).
            Some(s) if target.timing().is_timed() => {
                fit_timed_from(target, &c.curve.curve, s, &quick_of(c)).map(|f| f.rms)
            }
            Some(s) => scan
                .insert(fit_untimed_kept(&p, &c.curve.curve, s, &quick_of(c)))
                .as_ref()
                .and_then(|k| k.fit.as_ref().map(|f| f.rms)),
            None => traced
                .insert(traced_of(c))
                .as_ref()
                .and_then(|t| fit_with(&thin, &c.curve.curve, t, &quick_of(c)))
                .map(|f| f.rms),
        };
        let quick = match (f, robust_rms) {
            (Some(f), Some(r)) => Some(f.min(r)),
            (Some(f), None) => Some(f),
            (None, Some(r)) => Some(r),
            (None, None) => None,
        };
        Ranked {
            traced,
            robust,
            quick,
            scan: scan.flatten(),
        }
    };
    // The units of work: a candidate alone, or a closed curve's two candidates together.
    let units = work_units(&partner);
    let mut ranked: Vec<Option<Ranked>> = (0..candidates.len()).map(|_| None).collect();
    let done: Vec<Vec<(usize, Ranked)>> = units
        .par_iter()
        .map(|&(i, j)| match j {
            None => vec![(i, quick_one(i))],
            Some(j) => {
                let c = &candidates[i];
                let t = traced_of(c);
                let [f, g] = t.as_ref().map_or([None, None], |t| {
                    fit_closed_both(&thin, &c.curve.curve, t, &quick_of(c))
                });
                let r = |f: Option<CurveFit>| Ranked {
                    traced: Some(t.clone()),
                    robust: None,
                    quick: f.map(|f| f.rms),
                    scan: None,
                };
                vec![(i, r(f)), (j, r(g))]
            }
        })
        .collect();
    for (i, r) in done.into_iter().flatten() {
        ranked[i] = Some(r);
    }
    let mut ranked: Vec<Ranked> = ranked
        .into_iter()
        .map(|r| r.expect("every candidate is in one unit"))
        .collect();
    let mut quick: Vec<(f64, usize)> = ranked
        .iter()
        .enumerate()
        .filter_map(|(i, r)| Some((r.quick?, i)))
        .collect();
    quick.sort_by(|a, b| {
        a.0.total_cmp(&b.0)
            .then(candidates[a.1].coarse.total_cmp(&candidates[b.1].coarse))
            .then(candidates[a.1].curve.id.cmp(&candidates[b.1].curve.id))
    });
    // The best of each reflection reach the final fits.
    keep_each_reflection(
        &mut quick,
        (4 * options.top).max(options.top + 8),
        |&(_, i)| candidates[i].reflected,
    );
    // The final fits, each candidate with its own (moved out) ranking state. Every open
    // candidate that reaches them also gets the robust start, so a reported curve's fit is
    // the better of the two basins (a curve's fit from the scan's start alone can stop in
    // a neighbouring window's, a hair or more above its best).
    let finalists: Vec<(usize, Ranked)> = quick
        .iter()
        .map(|&(_, i)| {
            let r = Ranked {
                traced: ranked[i].traced.take(),
                robust: ranked[i].robust.take(),
                quick: ranked[i].quick,
                scan: ranked[i].scan.take(),
            };
            (i, r)
        })
        .collect();
    drop(ranked);
    let size = target.size();
    let match_of = |c: &Candidate, fit: CurveFit| Match {
        id: c.curve.id,
        curve: c.curve.curve,
        coarse: c.coarse,
        placement: Placement::of(&c.curve.curve, &fit),
        rms_pct: 100.0 * fit.rms / size,
        max_pct: 100.0 * fit.max / size,
        fit,
    };
    let final_one = |i: usize, mut r: Ranked| -> Option<Match> {
        let c = &candidates[i];
        let curve = &c.curve.curve;
        let traced = |r: &mut Ranked| -> Option<Arc<Traced>> {
            r.traced.take().unwrap_or_else(|| traced_of(c))
        };
        let fit_options = options_of(c);
        let fit = match &c.start {
            Some(s) => {
                let mut t = None;
                let robust = match r.robust.take() {
                    Some(Robust::Done(f)) => Some(f),
                    Some(Robust::Kept(k)) => k.finish(target, curve, &fit_options),
                    None => t
                        .insert(traced(&mut r))
                        .as_ref()
                        .and_then(|t| fit_with(target, curve, t, &fit_options)),
                };
                // The quick fit continued to the final cap: the same fit as one run.
                let untimed = match r.scan.take() {
                    Some(kept) => continue_untimed(&p, curve, s, kept, &fit_options),
                    None => fit_untimed(&p, curve, s, &fit_options),
                };
                let from_scan = untimed.and_then(|untimed| {
                    if target.timing().is_timed() {
                        let t = match t.take() {
                            Some(t) => t,
                            None => traced(&mut r),
                        }?;
                        fit_timed(target, curve, &t, Some(&untimed), &fit_options)
                    } else {
                        Some(untimed)
                    }
                });
                match (from_scan, robust) {
                    (Some(a), Some(b)) => {
                        if b.rms < a.rms {
                            b
                        } else {
                            a
                        }
                    }
                    (a, b) => a.or(b)?,
                }
            }
            None => {
                let t = traced(&mut r)?;
                fit_with(target, curve, &t, &fit_options)?
            }
        };
        Some(match_of(c, fit))
    };
    // A closed curve among both reflections' finalists is fitted both ways at once, as in
    // the quick fits.
    let final_partner = closed_partners(
        &finalists
            .iter()
            .map(|(i, _)| &candidates[*i])
            .collect::<Vec<_>>(),
    );
    let mut slots: Vec<Option<(usize, Ranked)>> = finalists.into_iter().map(Some).collect();
    type Job = (usize, (usize, Ranked), Option<(usize, (usize, Ranked))>);
    let jobs: Vec<Job> = work_units(&final_partner)
        .into_iter()
        .map(|(k, m)| {
            let first = slots[k].take().expect("each finalist in one unit");
            let second = m.map(|m| (m, slots[m].take().expect("each finalist in one unit")));
            (k, first, second)
        })
        .collect();
    let done: Vec<Vec<(usize, Option<Match>)>> = jobs
        .into_par_iter()
        .map(|(k, (i, mut r), second)| match second {
            None => vec![(k, final_one(i, r))],
            Some((m, (j, _))) => {
                let c = &candidates[i];
                let t = r.traced.take().unwrap_or_else(|| traced_of(c));
                let [f, g] = t.as_ref().map_or([None, None], |t| {
                    fit_closed_both(target, &c.curve.curve, t, &options_of(c))
                });
                vec![
                    (k, f.map(|f| match_of(c, f))),
                    (m, g.map(|g| match_of(&candidates[j], g))),
                ]
            }
        })
        .collect();
    let mut placed: Vec<Option<Match>> = (0..slots.len()).map(|_| None).collect();
    for (k, m) in done.into_iter().flatten() {
        placed[k] = m;
    }
    let mut matches: Vec<Match> = placed.into_iter().flatten().collect();
    matches.sort_by(|a, b| {
        a.fit
            .rms
            .total_cmp(&b.fit.rms)
            .then(a.coarse.total_cmp(&b.coarse))
            .then(a.id.cmp(&b.id))
    });
    // A curve fitted from both reflections' starts is reported once, at its best.
    let mut seen = std::collections::HashSet::new();
    matches.retain(|m| seen.insert(m.id));
    matches.truncate(options.top);
    matches
}

/// For each of `items`, the position of the reflected **closed** candidate of the same
/// curve when the item is an unreflected closed candidate and there is one (an open
/// candidate's fits start from its own scan: it is never paired).
/// Each item is paired at most once (a curve listed twice in one reflection, which a
/// caller may hand over, pairs its first entries).
fn closed_partners(items: &[&Candidate]) -> Vec<Option<usize>> {
    let mut reflected = std::collections::HashMap::new();
    for (k, c) in items.iter().enumerate() {
        if c.start.is_none() && c.reflected {
            reflected.entry(c.curve.id).or_insert(k);
        }
    }
    items
        .iter()
        .map(|c| {
            (c.start.is_none() && !c.reflected)
                .then(|| reflected.remove(&c.curve.id))
                .flatten()
        })
        .collect()
}

/// The units of work over items with their [`closed_partners`]: each item alone, or an
/// unreflected item with its partner; in the items' order (of the first of each unit).
fn work_units(partner: &[Option<usize>]) -> Vec<(usize, Option<usize>)> {
    let mut paired = vec![false; partner.len()];
    for &j in partner.iter().flatten() {
        paired[j] = true;
    }
    (0..partner.len())
        .filter(|&i| !paired[i])
        .map(|i| (i, partner[i]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cases::{SplitMix64, make_target};
    use crate::sidecar::{HEADER_BYTES, RECORD_BYTES, decode_sidecar, encode_sidecar};
    use coupler_kinematics::{Circuit, CouplerPoint, FourBar};

    /// A small atlas: four linkages, twelve points each, one curve without a code.
    fn sidecar() -> Vec<u8> {
        let mut curves = Vec::new();
        for (a, b, c) in [
            (2.0, 2.5, 3.0),
            (2.5, 3.0, 3.5),
            (3.0, 3.5, 3.0),
            (2.5, 2.5, 2.0),
        ] {
            let l = FourBar::new(a, b, c).unwrap();
            for k in 0..12 {
                let p = CouplerPoint::new(0.5 * (k % 4) as f64, -1.0 + 0.75 * (k / 4) as f64);
                let curve = CouplerCurve::new(l, Circuit::Open, p);
                let code = (curves.len() != 17).then(|| ShapeCode::of_curve(&curve).unwrap());
                curves.push((curve, code));
            }
        }
        encode_sidecar(&curves)
    }

    /// The exact stage gives the same matches, bit for bit, on one thread and on three,
    /// for closed and open targets (the candidates are fitted in parallel).
    #[test]
    fn rank_candidates_does_not_depend_on_threads() {
        let atlas = decode_sidecar(&sidecar()).unwrap();
        let options = MatchOptions {
            candidates: 12,
            open_candidates: 24,
            top: 3,
            ..MatchOptions::DEFAULT
        };
        let mut rng = SplitMix64(11);
        for (source, closed, span) in [(5, true, 360.0), (30, false, 160.0)] {
            let t = make_target(
                &mut rng,
                &atlas.curves[source].curve,
                closed,
                20.0,
                span,
                40,
                false,
                0.01,
            )
            .unwrap();
            let on = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| find_matches(&t, &atlas.curves, &atlas.codes, &options).unwrap())
            };
            let one = on(1);
            assert_eq!(one.len(), 3);
            assert_eq!(on(3), one, "source {source}");
        }
    }

    /// A curve listed twice in each reflection's candidates (at two coarse distances, as a
    /// caller may hand them over) is paired once: each entry is fitted, none twice, and
    /// the search does not fail.
    #[test]
    fn a_curve_listed_twice_is_paired_once() {
        let atlas = decode_sidecar(&sidecar()).unwrap();
        let options = MatchOptions {
            candidates: 12,
            top: 3,
            ..MatchOptions::DEFAULT
        };
        let mut rng = SplitMix64(19);
        let t = make_target(
            &mut rng,
            &atlas.curves[7].curve,
            true,
            20.0,
            360.0,
            40,
            false,
            0.01,
        )
        .unwrap();
        let mut c = coarse_candidates(&t, &atlas.curves, &atlas.codes, &options).unwrap();
        // A curve in both lists, its unreflected and its reflected entry listed again.
        let both = |k: &usize| {
            let (id, r) = (c[*k].curve.id, c[*k].reflected);
            !r && c.iter().any(|o| o.reflected && o.curve.id == id)
        };
        let plain = (0..c.len()).find(both).expect("a curve in both lists");
        let mirrored = (0..c.len())
            .find(|&k| c[k].reflected && c[k].curve.id == c[plain].curve.id)
            .unwrap();
        // Listed last (not next to the first entry, which the exact stage's dedup drops).
        let last = c.iter().map(|c| c.coarse).fold(f64::MIN, f64::max);
        for k in [plain, mirrored] {
            let mut again = c[k].clone();
            again.coarse = last + 1.0;
            c.push(again);
        }
        // One more candidate a reflection than the coarse stage gave: the copies are kept.
        let options = MatchOptions {
            candidates: 13,
            ..options
        };
        let m = rank_candidates(&t, c, &options);
        assert_eq!(m.len(), 3);
    }

    /// A closed query with reflection allowed proposes every candidate of the same query
    /// without it, with the same coarse distance bit for bit (issue 13: the reflected
    /// variants shared one budget and one distance with the unreflected ones), and at most
    /// as many reflected ones on top.
    #[test]
    fn reflection_only_adds_closed_candidates() {
        let atlas = decode_sidecar(&sidecar()).unwrap();
        let mut rng = SplitMix64(13);
        for source in [2, 11, 25, 40] {
            let t = make_target(
                &mut rng,
                &atlas.curves[source].curve,
                true,
                30.0,
                360.0,
                48,
                false,
                0.01,
            )
            .unwrap();
            let with = |allow_mirror: bool| {
                let options = MatchOptions {
                    allow_mirror,
                    candidates: 6,
                    top: 3,
                    ..MatchOptions::DEFAULT
                };
                coarse_candidates(&t, &atlas.curves, &atlas.codes, &options).unwrap()
            };
            let bits = |c: &Candidate| (c.curve.id, c.coarse.to_bits());
            let plain: Vec<_> = with(false).iter().map(bits).collect();
            let both: Vec<_> = with(true).iter().map(bits).collect();
            assert_eq!(plain.len(), 6);
            for c in &plain {
                assert!(both.contains(c), "source {source}: {c:?} not kept");
            }
            assert!(both.len() <= 2 * plain.len(), "source {source}");
        }
    }

    /// The closed coarse stage read in place, in uneven parts, proposes exactly the
    /// candidates of the stage over the decoded atlas, and the ranked matches are the
    /// same, bit for bit; a damaged record is an error when the search reads it, as the
    /// whole decode's.
    #[test]
    fn in_place_closed_stage_equals_decoded() {
        let bytes = sidecar();
        let atlas = decode_sidecar(&bytes).unwrap();
        let view = SidecarView::new(&bytes).unwrap();
        assert_eq!(view.len(), 48);
        for i in [0, 17, 47] {
            assert_eq!(view.curve(i).unwrap(), atlas.curves[i]);
            assert_eq!(view.code(i).unwrap().is_some(), atlas.has_code[i]);
        }
        let options = MatchOptions {
            candidates: 6,
            top: 3,
            ..MatchOptions::DEFAULT
        };
        let key = |c: &[Candidate]| -> Vec<(u64, f64, bool)> {
            let mut v: Vec<(u64, f64, bool)> = c
                .iter()
                .map(|c| (c.curve.id, c.coarse, c.reflected))
                .collect();
            v.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)).then(a.2.cmp(&b.2)));
            v.truncate(options.candidates);
            v
        };
        let mut rng = SplitMix64(5);
        for source in [3, 20, 41] {
            let t = make_target(
                &mut rng,
                &atlas.curves[source].curve,
                true,
                40.0,
                360.0,
                48,
                source == 20,
                0.005,
            )
            .unwrap();
            let whole = coarse_candidates(&t, &atlas.curves, &atlas.codes, &options).unwrap();
            let q = ClosedQuery::new(&t.complex_points(), options.allow_mirror).unwrap();
            let parts: Vec<Candidate> = [0..7, 7..30, 30..48]
                .into_iter()
                .flat_map(|ids| closed_candidates_in(&q, &t, &view, ids, &options).unwrap())
                .collect();
            assert_eq!(key(&parts), key(&whole), "source {source}");
            assert!(
                parts.iter().all(|c| c.curve.id != 17),
                "no code: never proposed"
            );
            assert_eq!(
                rank_candidates(&t, parts, &options),
                rank_candidates(&t, whole, &options),
                "source {source}"
            );
        }
        // A damaged code flag is found by the scan (every code is read) ...
        let t = make_target(
            &mut rng,
            &atlas.curves[9].curve,
            true,
            0.0,
            360.0,
            40,
            false,
            0.0,
        )
        .unwrap();
        let q = ClosedQuery::new(&t.complex_points(), true).unwrap();
        let mut bad = bytes.clone();
        bad[HEADER_BYTES + 30 * RECORD_BYTES + 41] = 2;
        let view = SidecarView::new(&bad).unwrap();
        assert!(decode_sidecar(&bad).is_err());
        assert!(matches!(
            closed_candidates_in(&q, &t, &view, 0..48, &options),
            Err(MatchError::Sidecar(SidecarError::Record { id: 30, .. }))
        ));
        // ... and a damaged linkage when its record is proposed (the source's own, here).
        let best = closed_candidates_in(&q, &t, &SidecarView::new(&bytes).unwrap(), 0..48, &options)
            .unwrap()[0]
            .curve
            .id as usize;
        let mut bad = bytes.clone();
        bad[HEADER_BYTES + best * RECORD_BYTES..][..8].copy_from_slice(&(-1.0f64).to_le_bytes());
        assert!(decode_sidecar(&bad).is_err());
        assert!(matches!(
            closed_candidates_in(&q, &t, &SidecarView::new(&bad).unwrap(), 0..48, &options),
            Err(MatchError::Sidecar(SidecarError::Record { id, .. })) if id == best as u64
        ));
    }
}
