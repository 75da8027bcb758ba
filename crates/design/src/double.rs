//! Double dwells (Norton §3.9, docs/conventions.md §6): link 5 on two pseudo-arcs of equal
//! radius, or a block in a slotted output link pivoted where two straight segments meet;
//! and the search for either on a whole curve.

use crate::design::{Build, Quick, Span, quick};
use crate::motion::{Driver, Motion};
use crate::single::{WindowPoints, arc_of, closer};
use crate::stage::Stage;
use crate::{DwellDesign, DwellError, DwellKind, Inadmissible, Limits, Method};
use coupler_features::{CrankWindow, LineDirection, LineMeasures};

/// Default tolerance on the two arcs' radii of [`double_dwell_arcs`], percent of the larger.
pub const DEFAULT_DOUBLE_ARC_RADIUS_TOL_PCT: f64 = 10.0;

/// Two arcs whose centres are at most this many times their largest radial deviation
/// apart make one dwell, not two ([`NoDoubleDwell::SameCentre`]): the relative jitter
/// of a double dwell is at least about deviation spread / separation (see
/// [`double_dwell_arcs`]).
pub const CENTRE_SEPARATION_FACTOR: f64 = 4.0;

/// With the swing left free, designs swinging less than this between the dwells rank
/// after all that swing more (a swing of a fraction of a degree is no use, however
/// small its relative jitter), degrees.
pub const MIN_FREE_SWING_DEG: f64 = 5.0;

/// How close the swing between the dwells must come to a swing asked for (degrees, and a
/// fraction of it; the larger applies) before jitter decides.
pub const SWING_TOLERANCE: (f64, f64) = (0.01, 0.005);

/// Options of [`double_dwell_arcs`] (the contract's limits are a [`Limits`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubleArcOptions {
    /// Requested output swing between the two dwells (the angle D1–O6–D2), degrees;
    /// `None` leaves it free.
    pub swing_deg: Option<f64>,
    /// Largest difference of the two arcs' radii, percent of the larger.
    pub radius_tol_pct: f64,
}

impl DoubleArcOptions {
    /// Swing free, radius tolerance [`DEFAULT_DOUBLE_ARC_RADIUS_TOL_PCT`].
    pub const DEFAULT: DoubleArcOptions = DoubleArcOptions {
        swing_deg: None,
        radius_tol_pct: DEFAULT_DOUBLE_ARC_RADIUS_TOL_PCT,
    };
}

impl Default for DoubleArcOptions {
    fn default() -> Self {
        DoubleArcOptions::DEFAULT
    }
}

/// Why two arcs admit no double-dwell six-bar (see [`double_dwell_arcs`]). When several
/// reasons apply to different pivots, the one of the pivot that came closest is given
/// (in this order: assembly, branches, transmission, full turn).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum NoDoubleDwell {
    /// The two arcs' radii differ by more than [`DoubleArcOptions::radius_tol_pct`].
    #[error("the arcs' radii {r1:.4} and {r2:.4} differ by more than {tol_pct}%")]
    RadiiDiffer {
        /// Radius of the first arc.
        r1: f64,
        /// Radius of the second.
        r2: f64,
        /// The tolerance, percent of the larger radius.
        tol_pct: f64,
    },
    /// The two arcs' centres are closer than [`CENTRE_SEPARATION_FACTOR`] × the arcs'
    /// largest radial deviation: the two dwell positions would be lost in the jitter
    /// (typically one arc split in two).
    #[error(
        "the arcs' centres are {separation:.3e} apart, not more than {CENTRE_SEPARATION_FACTOR} × their radial deviation {deviation:.3e}: one dwell, not two"
    )]
    SameCentre {
        /// |c2 − c1|.
        separation: f64,
        /// The larger of the arcs' largest radial deviations from their circles.
        deviation: f64,
    },
    /// For every output pivot on the bisector, links 5 and 6 fail to assemble (or pass a
    /// toggle) somewhere in the revolution.
    #[error(
        "links 5 and 6 fail to assemble (or toggle) somewhere in the revolution for every output pivot on the centres' bisector"
    )]
    Assembly,
    /// Wherever links 5 and 6 assemble all the way round, the two centres lie on opposite
    /// branches of the dyad: D would settle at the mirror image of the second centre, so
    /// there is no second dwell.
    #[error(
        "wherever links 5 and 6 assemble all the way round, the two centres are on opposite branches of the dyad (no second dwell)"
    )]
    Branches,
    /// On a common branch, the links 5–6 transmission angle falls below the limit for
    /// every pivot.
    #[error(
        "the links 5–6 transmission angle falls to {best_deg:.1}° at best, below the limit {limit_deg}° (lower --min-transmission)"
    )]
    Transmission {
        /// The limit asked for, degrees.
        limit_deg: f64,
        /// The best minimum transmission angle found on a common branch, degrees.
        best_deg: f64,
    },
    /// The best admissible design's worse dwell jitters more than
    /// [`crate::Limits::max_jitter_pct`] of its swing between the dwells.
    #[error(
        "the best design's worse dwell jitters {jitter_deg:.3}° on a {swing_deg:.3}° swing ({:.1} % > {:.1} %): the arcs deviate too much for their centres' separation",
        100.0 * jitter_deg / swing_deg,
        100.0 * max_relative
    )]
    Jitter {
        /// The worse dwell's jitter, degrees.
        jitter_deg: f64,
        /// The swing between the dwells, degrees.
        swing_deg: f64,
        /// The limit (a fraction).
        max_relative: f64,
    },
    /// Every admissible output link turns fully round instead of oscillating.
    #[error("every admissible output link turns fully round instead of oscillating")]
    FullTurn,
    /// Every design that passes the other checks has links 5 and 6 too unequal.
    #[error(
        "every design that passes the other checks has links 5 and 6 differing more than {limit} : 1 (best {best:.1} : 1, --max-link-ratio)"
    )]
    LinkRatio {
        /// The bound.
        limit: f64,
        /// The least ratio found.
        best: f64,
    },
    /// [`best_double_dwell`] found no pair of pseudo-arc windows on the curve that
    /// admits a design.
    #[error(
        "no pair of pseudo-arc windows on this curve ({pairs} candidate pairs tried) admits a double dwell"
    )]
    NoPair {
        /// How many candidate pairs were designed.
        pairs: usize,
    },
}

/// The two arcs, as the design sees them.
struct ArcPair {
    /// Free-fit centres c1, c2.
    c: [[f64; 2]; 2],
    /// Free-fit radii r1, r2.
    r: [f64; 2],
    /// The coupler point's samples on each arc.
    pts: [Vec<[f64; 2]>; 2],
}

/// The dwell points for one link-5 length and the bisector they define.
struct Bisector {
    /// Dwell points D1, D2: the arcs' best centres for radius R.
    d: [[f64; 2]; 2],
    /// Their midpoint.
    mid: [f64; 2],
    /// Unit normal of D1→D2 (the bisector's direction).
    n: [f64; 2],
    /// Half their separation.
    h: f64,
}

/// The centre of the circle of given radius `r` nearest (least squares of the radial
/// distances, `min Σ (|M − c| − r)²`) to the points, by Gauss–Newton from the free fit's
/// centre `c0` (radius `r0`) moved by `r0 − r` towards the points:
/// `Δc = (Σ u·uᵀ)⁻¹ · Σ u·(|M − c| − r)`, u the unit vectors from c to the points.
/// Returns `c0` moved when the normal matrix is singular.
fn centre_for_radius(pts: &[[f64; 2]], c0: [f64; 2], r0: f64, r: f64) -> [f64; 2] {
    let (mut ux, mut uy) = (0.0, 0.0);
    for m in pts {
        let (dx, dy) = (m[0] - c0[0], m[1] - c0[1]);
        let d = dx.hypot(dy);
        ux += dx / d;
        uy += dy / d;
    }
    let norm = ux.hypot(uy);
    let mut c = [c0[0] + (r0 - r) * ux / norm, c0[1] + (r0 - r) * uy / norm];
    for _ in 0..20 {
        let (mut a, mut b, mut d, mut gx, mut gy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for m in pts {
            let (dx, dy) = (m[0] - c[0], m[1] - c[1]);
            let dist = dx.hypot(dy);
            let (ux, uy) = (dx / dist, dy / dist);
            let f = dist - r;
            a += ux * ux;
            b += ux * uy;
            d += uy * uy;
            gx += ux * f;
            gy += uy * f;
        }
        let det = a * d - b * b;
        if det.abs() <= 1e-300 || det.is_nan() {
            break;
        }
        let step = [(d * gx - b * gy) / det, (a * gy - b * gx) / det];
        c = [c[0] + step[0], c[1] + step[1]];
        if step[0].hypot(step[1]) <= 1e-14 * r {
            break;
        }
    }
    c
}

impl ArcPair {
    /// The dwell points for link 5 = `r5` and their bisector.
    fn at_radius(&self, r5: f64) -> Bisector {
        let d = [0, 1].map(|i| centre_for_radius(&self.pts[i], self.c[i], self.r[i], r5));
        let sep = (d[1][0] - d[0][0]).hypot(d[1][1] - d[0][1]);
        Bisector {
            d,
            mid: [(d[0][0] + d[1][0]) / 2.0, (d[0][1] + d[1][1]) / 2.0],
            n: [-(d[1][1] - d[0][1]) / sep, (d[1][0] - d[0][0]) / sep],
            h: 0.5 * sep,
        }
    }
}

impl Bisector {
    /// The output pivot and link 6 for a swing β between the dwells, on `side` (±1) of
    /// the line D1D2: `O6 = mid + side·h·cot(β/2)·n`, `L6 = h / sin(β/2)`.
    fn pivot(&self, side: f64, beta_deg: f64) -> ([f64; 2], f64) {
        let (s, c) = coupler_kinematics::sincos_deg(0.5 * beta_deg);
        let t = side * self.h * c / s;
        (
            [self.mid[0] + t * self.n[0], self.mid[1] + t * self.n[1]],
            self.h / s,
        )
    }
}

/// One evaluated double-arc design.
struct ArcDesign {
    dwell_points: [[f64; 2]; 2],
    beta: f64,
    side: f64,
    r5: f64,
    stage: Stage,
    q: Quick,
    /// Smaller is better, compared lexicographically (see [`design_score`]).
    score: (u8, f64),
}

/// What became of one candidate pivot, in the order the checks are made.
enum Verdict {
    Assembly,
    Branches,
    Transmission(f64),
    FullTurn,
    LinkRatio(f64),
    Admissible(Box<ArcDesign>),
}

impl Verdict {
    fn stage(&self) -> u8 {
        match self {
            Verdict::Assembly => 0,
            Verdict::Branches => 1,
            Verdict::Transmission(_) => 2,
            Verdict::FullTurn => 3,
            Verdict::LinkRatio(_) => 4,
            Verdict::Admissible(_) => 5,
        }
    }
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// How a double-arc design ranks (lower first), from the swing between its dwells and its
/// worse dwell jitter (degrees). Free swing: the jitter relative to the swing, designs
/// swinging less than [`MIN_FREE_SWING_DEG`] last. Swing asked for: within
/// [`SWING_TOLERANCE`] of it, the worse jitter; else (a second tier) the swing's miss.
fn design_score(asked: Option<f64>, swing: f64, worst: f64) -> (u8, f64) {
    match asked {
        None => (
            u8::from(swing < MIN_FREE_SWING_DEG),
            worst / swing.max(1e-12),
        ),
        Some(want) => {
            let miss = (swing - want).abs();
            if miss <= SWING_TOLERANCE.0.max(SWING_TOLERANCE.1 * want) {
                (0, worst)
            } else {
                (1, miss)
            }
        }
    }
}

/// Checks and simulates the design with swing `beta` on `side` and link 5 = `r5`.
fn evaluate(
    motion: &Motion,
    pair: &ArcPair,
    windows: &[Span],
    (side, beta, r5): (f64, f64, f64),
    opts: &DoubleArcOptions,
    limits: &Limits,
) -> Verdict {
    let bis = pair.at_radius(r5);
    if bis.h.is_nan() || bis.h <= 0.0 {
        return Verdict::Assembly;
    }
    let (o6, l6) = bis.pivot(side, beta);
    // Assembly first (cheap): cos μ = (R² + L6² − |M − O6|²) / (2·R·L6) within [−1, 1].
    for m in &motion.m {
        let d2 = (m[0] - o6[0]).powi(2) + (m[1] - o6[1]).powi(2);
        let cos = (r5 * r5 + l6 * l6 - d2) / (2.0 * r5 * l6);
        if cos.abs() >= 1.0 || !cos.is_finite() {
            return Verdict::Assembly;
        }
    }
    // Branches: D = c_i solves the dyad for M on arc i; its branch is the sign of
    // (O6 − M) × (c_i − M). Both arcs, every sample, must agree.
    let sign = |m: &[f64; 2], c: [f64; 2]| {
        cross([o6[0] - m[0], o6[1] - m[1]], [c[0] - m[0], c[1] - m[1]]).signum()
    };
    let s = sign(&pair.pts[0][0], bis.d[0]);
    let same = (0..2).all(|i| pair.pts[i].iter().all(|m| sign(m, bis.d[i]) == s));
    if !same {
        return Verdict::Branches;
    }
    let stage = Stage::Rocker {
        link5: r5,
        link6: l6,
        pivot: o6,
        branch: s,
    };
    let q = match quick(&stage, motion, windows, limits) {
        Ok(q) => q,
        Err(Inadmissible::Transmission { min_deg, .. }) => return Verdict::Transmission(min_deg),
        Err(Inadmissible::FullTurn { .. }) => return Verdict::FullTurn,
        Err(Inadmissible::LinkRatio { ratio, .. }) => return Verdict::LinkRatio(ratio),
        Err(_) => return Verdict::Assembly,
    };
    let score = design_score(opts.swing_deg, q.judged_swing(), q.worst_jitter());
    Verdict::Admissible(Box::new(ArcDesign {
        dwell_points: bis.d,
        beta,
        side,
        r5,
        stage,
        q,
        score,
    }))
}

/// The double dwell on two pseudo-arcs of (nearly) equal radius (docs/conventions.md §6, Norton
/// §3.9).
///
/// **Mechanism.** Link 5 (length R) hangs from the coupler point M; its far end D is
/// pinned to output link 6 (pivot O6, length L6). D dwells at D1 while M runs on arc 1
/// and at D2 while M runs on arc 2, D_i the arc's best centre for radius R (least squares
/// of the radial distances, refitted from the arc's free circle c_i, r_i: for a short arc
/// the radius is poorly determined, and refitting absorbs the difference r_i − R into
/// the centre instead of leaving it as an offset that the turning link 5 turns into
/// jitter). `|O6 − D1| = |O6 − D2| = L6` puts O6 on the perpendicular bisector of D1D2.
/// With h = |D2 − D1|/2, n the unit normal of D1→D2 and β the output swing between the
/// dwells (the angle D1–O6–D2):
/// `O6 = (D1 + D2)/2 ± h·cot(β/2)·n`, `L6 = h / sin(β/2)`.
///
/// **Admissible designs.** At every crank step the dyad must assemble with its
/// transmission angle μ at D, `cos μ = (R² + L6² − |M − O6|²)/(2·R·L6)`, within
/// `[limit, 180° − limit]` ([`crate::Limits::min_transmission_deg`]). Then M, D, O6
/// are never collinear, so the dyad keeps one branch, the sign of (O6 − M) × (D − M),
/// all the way round (it is simulated on that fixed branch); D reaches D1 and D2 only if
/// both lie on it: the sign of (O6 − M) × (D_i − M) must be the same for every sample M
/// of both arcs (for fixed M it is the sign of a function linear in O6, so the admissible
/// pivots on the bisector form intervals). The output must also oscillate.
///
/// **Jitter.** To first order, with δ(M) = |M − D_i| − R the radial error of M from the
/// dwell circle, D leaves D_i along link 6's circle by δ / sin μ, so the output moves by
/// `δ(M) / (L6 · sin μ(M))` radians: the dwell's jitter is at most `2·e_i / (L6 · s_i)`,
/// e_i = max |δ| over the arc (≤ the arc's free-fit deviation + |r_i − R|, the free
/// centre being one candidate) and s_i the sine of the worst folded transmission angle
/// during the dwell. Since L6 = h / sin(β/2), the relative jitter (jitter / swing) is
/// about `δ-spread / (2h · sin μ) · sin(β/2)/(β/2)`: the arcs' radial spread over the
/// centres' separation, over sin μ; no choice of pivot beats that by more than 2/π.
///
/// **Objective.** Over the swing β (both sides of D1D2) and R ∈ [min(r1, r2),
/// max(r1, r2)], among admissible designs (simulated: the jitters are measured, not
/// predicted): with no swing asked for, minimise the worse dwell's jitter *relative to
/// the swing between the dwells* (jitter / swing, which does not reward a vanishing
/// swing), designs swinging less than [`MIN_FREE_SWING_DEG`] ranking last; with `swing_deg`, minimise the worse dwell's jitter among designs whose
/// measured swing between the dwells is within [`SWING_TOLERANCE`] of it. Search: a grid (β every 0.5°, 5 radii, both sides), each candidate checked
/// as above and simulated, then a pattern search on (β, R) about the best one. With a
/// swing asked for, a best design more than [`SWING_ACCURACY_DEG`](crate::SWING_ACCURACY_DEG)
/// from it is refused with the range of admissible swings
/// ([`DwellError::SwingOutOfRange`]). The best design must then pass the whole contract
/// ([`crate::Limits`]: link ratio, jitter within `max_jitter_pct` of the swing between
/// the dwells).
///
/// **Which arc pairs work.** With φ_i the direction of M − D_i (link 5 at dwell i)
/// measured from D1→D2 and α that of O6 − D1, the branches are the signs of
/// sin(α − φ1) and sin(α + φ2). Arcs that are mirror images across the centres'
/// bisector (φ2 = 180° − φ1: the equal arcs of a symmetric coupler curve) are always on
/// opposite branches, whatever O6 ([`NoDoubleDwell::Branches`]); the ideal pair has
/// φ2 = −φ1 (mirror images across the line of centres), where μ = 90° at both dwells
/// is possible. The concave side of the arcs does not decide it.
///
/// Errors: [`DwellError::NoDoubleDwell`] with the reason when no admissible design
/// exists; window and assembly errors of the four-bar as for the other designs.
pub fn double_dwell_arcs(
    driver: &Driver,
    w1: &CrankWindow,
    w2: &CrankWindow,
    opts: &DoubleArcOptions,
    limits: &Limits,
) -> Result<DwellDesign, DwellError> {
    crate::check_step(limits.step_deg)?;
    let (c1, r1, e1, p1) = arc_of(driver, w1)?;
    let (c2, r2, e2, p2) = arc_of(driver, w2)?;
    if (r1 - r2).abs() > opts.radius_tol_pct / 100.0 * r1.max(r2) {
        return Err(DwellError::NoDoubleDwell(NoDoubleDwell::RadiiDiffer {
            r1,
            r2,
            tol_pct: opts.radius_tol_pct,
        }));
    }
    let sep = (c2[0] - c1[0]).hypot(c2[1] - c1[1]);
    let deviation = e1.max(e2);
    if sep <= CENTRE_SEPARATION_FACTOR * deviation || sep <= 1e-9 * r1.max(r2) {
        return Err(DwellError::NoDoubleDwell(NoDoubleDwell::SameCentre {
            separation: sep,
            deviation,
        }));
    }
    let pair = ArcPair {
        c: [c1, c2],
        r: [r1, r2],
        pts: [p1.points(), p2.points()],
    };
    let motion = Motion::sample(driver, limits.step_deg)?;
    let windows = [
        (w1.start_deg.rem_euclid(360.0), w1.span_deg()),
        (w2.start_deg.rem_euclid(360.0), w2.span_deg()),
    ];
    let (design, seen) = search_arc_design(&motion, &pair, &windows, opts, limits)?;
    if let Some(want) = opts.swing_deg {
        let got = design.q.judged_swing();
        if (got - want).abs() > crate::SWING_ACCURACY_DEG {
            return Err(DwellError::SwingOutOfRange {
                asked_deg: want,
                smallest_deg: seen[0],
                largest_deg: seen[1],
            });
        }
    }
    let notes = vec![format!(
        "D1, D2 the arcs' best centres for link 5 = {:.4}; O6 on their perpendicular bisector ({} side), subtending {:.3}°",
        design.r5,
        if design.side > 0.0 { "left" } else { "right" },
        design.beta
    )];
    Build {
        kind: DwellKind::DoubleArcs,
        method: Method::Bisector,
        driver,
        motion: &motion,
        stage: design.stage,
        windows: windows.to_vec(),
        dwell_points: design.dwell_points.to_vec(),
        limits: *limits,
        notes,
    }
    .finish()
    .map_err(|why| match why {
        Inadmissible::Jitter {
            jitter_deg,
            swing_deg,
            limit_pct,
        } => DwellError::NoDoubleDwell(NoDoubleDwell::Jitter {
            jitter_deg,
            swing_deg,
            max_relative: limit_pct / 100.0,
        }),
        why => DwellError::Inadmissible {
            what: "these two arcs",
            why,
        },
    })
}

/// The search of [`double_dwell_arcs`]: grid, then pattern search. Also returns the range
/// of swings between the dwells over the admissible candidates seen.
fn search_arc_design(
    motion: &Motion,
    pair: &ArcPair,
    windows: &[Span],
    opts: &DoubleArcOptions,
    limits: &Limits,
) -> Result<(ArcDesign, [f64; 2]), DwellError> {
    let (rmin, rmax) = (pair.r[0].min(pair.r[1]), pair.r[0].max(pair.r[1]));
    let radii: Vec<f64> = (0..5)
        .map(|k| rmin + (rmax - rmin) * k as f64 / 4.0)
        .collect();
    let betas: Vec<f64> = (1..360).map(|k| k as f64 * 0.5).collect();
    // The closest a failing candidate came, for the error.
    let mut stage = 0_u8;
    let mut best_mu = 0.0_f64;
    let mut best_ratio = f64::INFINITY;
    let mut seen = [f64::INFINITY, f64::NEG_INFINITY];
    let mut best: Option<ArcDesign> = None;
    let mut consider = |v: Verdict, best: &mut Option<ArcDesign>, seen: &mut [f64; 2]| {
        stage = stage.max(v.stage());
        match v {
            Verdict::Transmission(m) => best_mu = best_mu.max(m),
            Verdict::LinkRatio(r) => best_ratio = best_ratio.min(r),
            Verdict::Admissible(d) => {
                // The range a refusal names counts only designs that pass the whole
                // contract (jitter included), so every swing it names is one we give.
                if d.q.check_jitter(limits).is_ok() {
                    let sw = d.q.judged_swing();
                    seen[0] = seen[0].min(sw);
                    seen[1] = seen[1].max(sw);
                }
                if best.as_ref().is_none_or(|b| d.score < b.score) {
                    *best = Some(*d);
                }
            }
            _ => {}
        }
    };
    for &beta in &betas {
        for side in [1.0, -1.0] {
            for &r5 in &radii {
                let v = evaluate(motion, pair, windows, (side, beta, r5), opts, limits);
                consider(v, &mut best, &mut seen);
            }
        }
    }
    let Some(mut cur) = best.take() else {
        return Err(DwellError::NoDoubleDwell(match stage {
            0 => NoDoubleDwell::Assembly,
            1 => NoDoubleDwell::Branches,
            2 => NoDoubleDwell::Transmission {
                limit_deg: limits.min_transmission_deg,
                best_deg: best_mu,
            },
            3 => NoDoubleDwell::FullTurn,
            _ => NoDoubleDwell::LinkRatio {
                limit: limits.max_link_ratio,
                best: best_ratio,
            },
        }));
    };
    // Pattern search about the best grid point.
    let (mut db, mut dr) = (0.25, (rmax - rmin) / 8.0);
    for _ in 0..40 {
        let mut moved = false;
        for (x, y) in [(db, 0.0), (-db, 0.0), (0.0, dr), (0.0, -dr)] {
            if x == 0.0 && y == 0.0 {
                continue;
            }
            let (beta, r5) = (cur.beta + x, cur.r5 + y);
            if !(beta > 0.0 && beta < 180.0 && r5 >= rmin && r5 <= rmax) {
                continue;
            }
            if let Verdict::Admissible(d) =
                evaluate(motion, pair, windows, (cur.side, beta, r5), opts, limits)
            {
                if d.q.check_jitter(limits).is_ok() {
                    let sw = d.q.judged_swing();
                    seen[0] = seen[0].min(sw);
                    seen[1] = seen[1].max(sw);
                }
                if d.score < cur.score {
                    cur = *d;
                    moved = true;
                }
            }
        }
        if !moved {
            db *= 0.5;
            dr *= 0.5;
            if db < 1e-3 && dr < 1e-6 * rmax {
                break;
            }
        }
    }
    Ok((cur, seen))
}

/// A straight segment's fitted line: (centroid, unit direction).
fn line_of(driver: &Driver, w: &CrankWindow) -> Result<([f64; 2], [f64; 2]), DwellError> {
    let p = WindowPoints::sample(driver, w)?;
    let m = LineMeasures::of(&p.x, &p.y, &p.vx, &p.vy, LineDirection::Fitted);
    Ok((m.centroid, m.direction))
}

/// The double dwell with a slotted output link pivoted where the fitted lines of two
/// straight windows meet (Norton Example 3-14): a block pinned to the coupler at M slides
/// in the slot, so the output angle is the direction of M from O6, which stands (nearly)
/// still while M runs along either line. Its swing between the dwells is fixed by the
/// lines: a swing asked for that differs by more than
/// [`SWING_ACCURACY_DEG`](crate::SWING_ACCURACY_DEG) is refused
/// ([`DwellError::SwingFixed`]). The design must pass the contract ([`Limits`]): the
/// block never reaches O6, the output oscillates, the block's farthest distance from O6
/// is at most `max_link_ratio` × its closest, and the worse dwell jitters at most
/// `max_jitter_pct` of the swing between the dwells. The block transmits its force
/// square to the slot, so the links 5–6 transmission angle is 90° by construction: no
/// limit applies to it, and it is not reported as a range.
pub fn double_dwell_lines(
    driver: &Driver,
    w1: &CrankWindow,
    w2: &CrankWindow,
    swing_deg: Option<f64>,
    limits: &Limits,
) -> Result<DwellDesign, DwellError> {
    crate::check_step(limits.step_deg)?;
    let ((g1, d1), (g2, d2)) = (line_of(driver, w1)?, line_of(driver, w2)?);
    let den = d1[0] * d2[1] - d1[1] * d2[0];
    if den.abs() < 1e-6 {
        return Err(DwellError::Parallel);
    }
    let t = ((g2[0] - g1[0]) * d2[1] - (g2[1] - g1[1]) * d2[0]) / den;
    let o6 = [g1[0] + t * d1[0], g1[1] + t * d1[1]];
    let motion = Motion::sample(driver, limits.step_deg)?;
    let windows = vec![
        (w1.start_deg.rem_euclid(360.0), w1.span_deg()),
        (w2.start_deg.rem_euclid(360.0), w2.span_deg()),
    ];
    let stage = Stage::Slot { pivot: o6 };
    let what = "these two straight segments";
    if let Some(want) = swing_deg {
        let q = quick(&stage, &motion, &windows, limits)
            .map_err(|why| DwellError::Inadmissible { what, why })?;
        let got = q.judged_swing();
        if (got - want).abs() > crate::SWING_ACCURACY_DEG {
            return Err(DwellError::SwingFixed {
                asked_deg: want,
                fixed_deg: got,
            });
        }
    }
    Build {
        kind: DwellKind::DoubleLines,
        method: Method::LinesMeet,
        driver,
        motion: &motion,
        stage,
        windows,
        dwell_points: vec![o6],
        limits: *limits,
        notes: vec![format!(
            "O6 = ({:.4}, {:.4}), where the two segments' fitted lines meet",
            o6[0], o6[1]
        )],
    }
    .finish()
    .map_err(|why| DwellError::Inadmissible { what, why })
}

/// How [`best_double_dwell`] looks for windows on a curve.
#[derive(Clone, Debug, PartialEq)]
pub struct DoubleDwellSearch {
    /// Arc window lengths tried, crank degrees.
    pub arc_spans_deg: Vec<f64>,
    /// Straight window lengths tried, crank degrees.
    pub line_spans_deg: Vec<f64>,
    /// Window starts every this many crank degrees.
    pub start_step_deg: f64,
    /// Largest radial deviation of an arc window from its circle, percent of the radius.
    pub max_arc_deviation_pct: f64,
    /// Largest straightness error ε_S of a line window, percent.
    pub max_straightness_pct: f64,
    /// How many of the best-ranked arc pairs are designed.
    pub arc_candidates: usize,
    /// How many of the best-ranked line pairs are designed.
    pub line_candidates: usize,
}

impl Default for DoubleDwellSearch {
    /// Arc windows of 30°–90°, line windows of 30°–120°, starting every 5°; arcs within
    /// 0.2 %, lines within ε_S 0.5 %; 24 arc pairs and 60 line pairs designed.
    fn default() -> Self {
        DoubleDwellSearch {
            arc_spans_deg: vec![30.0, 45.0, 60.0, 90.0],
            line_spans_deg: vec![30.0, 45.0, 60.0, 90.0, 120.0],
            start_step_deg: 5.0,
            max_arc_deviation_pct: 0.2,
            max_straightness_pct: 0.5,
            arc_candidates: 24,
            line_candidates: 60,
        }
    }
}

/// Whether windows a and b (start, span) are disjoint going round the crank.
fn disjoint(a: &CrankWindow, b: &CrankWindow) -> bool {
    let gap_ab = (b.start_deg - a.end_deg).rem_euclid(360.0);
    let gap_ba = (a.start_deg - b.end_deg).rem_euclid(360.0);
    gap_ab + gap_ba + a.span_deg() + b.span_deg() <= 360.0 + 1e-9
}

/// Finds the best double dwell on one coupler curve, windows chosen here: pairs of
/// pseudo-arc windows (designed with [`double_dwell_arcs`]) and pairs of straight windows
/// (designed with [`double_dwell_lines`]), every design checked against the whole
/// contract. The admissible design whose shorter felt dwell is longest wins (ties: the
/// smaller jitter relative to the swing); with `opts.swing_deg`, only designs within
/// [`SWING_ACCURACY_DEG`](crate::SWING_ACCURACY_DEG) of it count.
///
/// Candidates: every window of the search's spans starting every `start_step_deg`.
/// Arc windows whose circle deviates at most `max_arc_deviation_pct`; pairs that do not
/// overlap, with radii within `opts.radius_tol_pct`, centres further apart than
/// [`CENTRE_SEPARATION_FACTOR`] × the deviation, and link-5 directions at mid-window
/// (φ_i, from c_i to M, measured from c1→c2) with cos(φ1 + φ2) > 0 (mirror pairs, which
/// never admit a design, have φ1 + φ2 = 180°); ranked by the shorter window, then by the
/// centres' separation over the larger deviation. Line windows with ε_S at most
/// `max_straightness_pct` that move one way; pairs that do not overlap, at 10°–170° to
/// each other, ranked by the shorter window.
pub fn best_double_dwell(
    driver: &Driver,
    search: &DoubleDwellSearch,
    opts: &DoubleArcOptions,
    limits: &Limits,
) -> Result<DwellDesign, DwellError> {
    crate::check_step(limits.step_deg)?;
    struct ArcCandidate {
        window: CrankWindow,
        c: [f64; 2],
        r: f64,
        e: f64,
        mid: [f64; 2],
    }
    struct LineCandidate {
        window: CrankWindow,
        d: [f64; 2],
    }
    let starts = (360.0 / search.start_step_deg).round() as usize;
    let mut arcs = Vec::new();
    let mut lines = Vec::new();
    for k in 0..starts {
        let start = k as f64 * search.start_step_deg;
        for &span in &search.arc_spans_deg {
            let w = CrankWindow::new(start, start + span, limits.step_deg)?;
            let Ok((c, r, e, _)) = arc_of(driver, &w) else {
                continue;
            };
            if e / r * 100.0 > search.max_arc_deviation_pct {
                continue;
            }
            let Some(s) = driver.state(start + span / 2.0) else {
                continue;
            };
            arcs.push(ArcCandidate {
                window: w,
                c,
                r,
                e,
                mid: s.m,
            });
        }
        for &span in &search.line_spans_deg {
            let w = CrankWindow::new(start, start + span, limits.step_deg)?;
            let Ok(p) = WindowPoints::sample(driver, &w) else {
                continue;
            };
            let m = LineMeasures::of(&p.x, &p.y, &p.vx, &p.vy, LineDirection::Fitted);
            match m.straightness_pct() {
                Some(s) if s <= search.max_straightness_pct && m.monotone => {}
                _ => continue,
            }
            lines.push(LineCandidate {
                window: w,
                d: m.direction,
            });
        }
    }
    // Arc pairs.
    let mut arc_pairs: Vec<(f64, f64, usize, usize)> = Vec::new();
    for (i, a) in arcs.iter().enumerate() {
        for (j, b) in arcs.iter().enumerate() {
            if i == j || a.window.start_deg > b.window.start_deg || !disjoint(&a.window, &b.window)
            {
                continue;
            }
            if (a.r - b.r).abs() > opts.radius_tol_pct / 100.0 * a.r.max(b.r) {
                continue;
            }
            let sep = (b.c[0] - a.c[0]).hypot(b.c[1] - a.c[1]);
            let e = a.e.max(b.e);
            if sep <= CENTRE_SEPARATION_FACTOR * e || sep == 0.0 {
                continue;
            }
            let u = [(b.c[0] - a.c[0]) / sep, (b.c[1] - a.c[1]) / sep];
            let phi = |m: [f64; 2], c: [f64; 2]| {
                let v = [m[0] - c[0], m[1] - c[1]];
                libm::atan2(u[0] * v[1] - u[1] * v[0], u[0] * v[0] + u[1] * v[1])
            };
            if libm::cos(phi(a.mid, a.c) + phi(b.mid, b.c)) <= 0.0 {
                continue;
            }
            let shorter = a.window.span_deg().min(b.window.span_deg());
            arc_pairs.push((shorter, sep / e.max(f64::MIN_POSITIVE), i, j));
        }
    }
    arc_pairs.sort_by(|x, y| y.0.total_cmp(&x.0).then(y.1.total_cmp(&x.1)));
    // Line pairs.
    let mut line_pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (i, a) in lines.iter().enumerate() {
        for (j, b) in lines.iter().enumerate() {
            if i == j || a.window.start_deg > b.window.start_deg || !disjoint(&a.window, &b.window)
            {
                continue;
            }
            let sin = (a.d[0] * b.d[1] - a.d[1] * b.d[0]).abs();
            if sin < libm::sin(10f64.to_radians()) {
                continue;
            }
            line_pairs.push((a.window.span_deg().min(b.window.span_deg()), i, j));
        }
    }
    line_pairs.sort_by(|x, y| y.0.total_cmp(&x.0));
    let key = |d: &DwellDesign| {
        (
            -d.shortest_felt_deg(),
            d.worst_jitter_deg() / d.judged_swing_deg().max(1e-12),
        )
    };
    let accept = |d: &DwellDesign| {
        opts.swing_deg
            .is_none_or(|w| (d.judged_swing_deg() - w).abs() <= crate::SWING_ACCURACY_DEG)
    };
    let mut best: Option<DwellDesign> = None;
    let mut closest: Option<Inadmissible> = None;
    let mut other: Option<String> = None;
    let mut consider = |r: Result<DwellDesign, DwellError>, best: &mut Option<DwellDesign>| match r
    {
        Ok(d) if accept(&d) => {
            if best
                .as_ref()
                .is_none_or(|b| key(&d).partial_cmp(&key(b)) == Some(std::cmp::Ordering::Less))
            {
                *best = Some(d);
            }
        }
        Ok(d) => {
            other.get_or_insert(format!(
                "a design swings {:.2}°, not the {}° asked for",
                d.judged_swing_deg(),
                opts.swing_deg.unwrap_or(0.0)
            ));
        }
        Err(DwellError::Inadmissible { why, .. }) => closer(&mut closest, why),
        Err(e) => {
            other.get_or_insert(e.to_string());
        }
    };
    let arc_tried = arc_pairs.len().min(search.arc_candidates);
    for &(_, _, i, j) in &arc_pairs[..arc_tried] {
        let r = double_dwell_arcs(driver, &arcs[i].window, &arcs[j].window, opts, limits);
        consider(r, &mut best);
    }
    let line_tried = line_pairs.len().min(search.line_candidates);
    for &(_, i, j) in &line_pairs[..line_tried] {
        let r = double_dwell_lines(
            driver,
            &lines[i].window,
            &lines[j].window,
            opts.swing_deg,
            limits,
        );
        consider(r, &mut best);
    }
    best.ok_or_else(|| DwellError::NothingFound {
        arc_pairs: arc_tried,
        line_pairs: line_tried,
        closest: closest
            .map(|c| c.to_string())
            .or(other)
            .unwrap_or_else(|| "no candidate pair on this curve".into()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::{Circuit, CouplerPoint, CrankAngle, FourBar, Pose};

    fn driver(a: f64, b: f64, c: f64, u: f64, v: f64) -> Driver {
        Driver::original(
            FourBar::new(a, b, c).unwrap(),
            Circuit::Open,
            CouplerPoint::new(u, v),
        )
    }

    fn w(s: f64, e: f64) -> CrankWindow {
        CrankWindow::new(s, e, 1.0).unwrap()
    }

    /// The slotted double dwell on two straight segments (default atlas, A = 1.5, B = C = 3,
    /// point (2.25, 0), its index's two segments): the output stands nearly still on both
    /// lines; the block passes 1/24 of its reach from O6, so the default link ratio refuses
    /// it, a looser one designs it and warns (dψ/dθ 5.5, d²ψ/dθ² 24.5 there).
    #[test]
    fn double_dwell_from_lines() {
        let d = driver(1.5, 3.0, 3.0, 2.25, 0.0);
        let (w1, w2) = (w(105.0, 175.0), w(240.0, 285.0));
        assert!(matches!(
            double_dwell_lines(&d, &w1, &w2, None, &Limits::DEFAULT),
            Err(DwellError::Inadmissible {
                why: Inadmissible::LinkRatio { slot: true, .. },
                ..
            })
        ));
        let loose = Limits {
            max_link_ratio: 40.0,
            ..Limits::DEFAULT
        };
        let x = double_dwell_lines(&d, &w1, &w2, None, &loose).unwrap();
        assert!(x.worst_jitter_deg() < 0.5, "{:?}", x.dwells);
        assert!((x.peak_acceleration.value - 24.47).abs() < 0.01);
        assert!(
            x.warnings.iter().any(|w| w.contains("from O6")),
            "{:?}",
            x.warnings
        );
    }

    /// A slotted link whose pivot the curve winds round turns fully: refused (default atlas,
    /// A = B = 3.5, C = 4, point (5.25, 3.5), its index's two segments).
    #[test]
    fn lines_round_the_pivot_are_refused() {
        let d = driver(3.5, 3.5, 4.0, 5.25, 3.5);
        let e = double_dwell_lines(
            &d,
            &w(90.0, 235.0),
            &w(240.0, 285.0),
            None,
            &Limits::DEFAULT,
        )
        .unwrap_err();
        assert!(
            matches!(
                e,
                DwellError::Inadmissible {
                    why: Inadmissible::FullTurn { .. },
                    ..
                }
            ),
            "{e}"
        );
    }

    /// The mirror-image arcs of a symmetric curve (A = B = C = 1.5, point (1.5, −1.5)) are on
    /// opposite branches whatever the pivot; two windows of one exact circle are one dwell.
    #[test]
    fn double_arcs_mirror_pair_has_no_design() {
        let d = driver(1.5, 1.5, 1.5, 1.5, -1.5);
        for limit in [30.0, 0.0] {
            let limits = Limits {
                min_transmission_deg: limit,
                ..Limits::DEFAULT
            };
            assert_eq!(
                double_dwell_arcs(
                    &d,
                    &w(65.0, 130.0),
                    &w(230.0, 295.0),
                    &DoubleArcOptions::DEFAULT,
                    &limits
                )
                .unwrap_err(),
                DwellError::NoDoubleDwell(NoDoubleDwell::Branches)
            );
        }
        let d = driver(3.0, 2.5, 3.5, 3.0, 0.0);
        assert!(matches!(
            double_dwell_arcs(
                &d,
                &w(100.0, 160.0),
                &w(200.0, 260.0),
                &DoubleArcOptions::DEFAULT,
                &Limits::DEFAULT
            ),
            Err(DwellError::NoDoubleDwell(NoDoubleDwell::SameCentre { .. }))
        ));
    }

    /// Real atlas pairs that admit a design: (A, B, C), point, the two windows.
    type Case = ((f64, f64, f64), (f64, f64), (f64, f64), (f64, f64));
    const ADMISSIBLE: [Case; 3] = [
        ((3.0, 3.5, 2.5), (1.5, -3.0), (195.0, 225.0), (355.0, 385.0)),
        ((2.0, 3.0, 3.0), (2.0, 1.0), (170.0, 200.0), (355.0, 385.0)),
        (
            (1.5, 2.5, 2.5),
            (1.875, -0.75),
            (160.0, 190.0),
            (355.0, 385.0),
        ),
    ];

    /// On real atlas pairs: the links 5–6 transmission angle stays within [30°, 150°]
    /// all the way round, the dyad never changes branch and both dwell points are on it,
    /// and D stays at link 5's length from M.
    #[test]
    fn double_arcs_design_is_admissible() {
        for ((a, b, c), (u, v), (s1, e1), (s2, e2)) in ADMISSIBLE {
            let dr = driver(a, b, c, u, v);
            let ws = [w(s1, e1), w(s2, e2)];
            let d = double_dwell_arcs(
                &dr,
                &ws[0],
                &ws[1],
                &DoubleArcOptions::DEFAULT,
                &Limits::DEFAULT,
            )
            .unwrap();
            let mu = d.output_transmission_deg.as_ref().unwrap();
            let folded = mu
                .iter()
                .map(|m| m.min(180.0 - m))
                .fold(f64::INFINITY, f64::min);
            assert!(folded >= 30.0 - 1e-9, "{a} {b} {c}: μ {folded}");
            let Stage::Rocker {
                link5,
                link6,
                pivot: o6,
                branch,
            } = d.stage
            else {
                panic!("not a rocker")
            };
            let l = FourBar::new(a, b, c).unwrap();
            for (&t, &o) in d.theta_deg.iter().zip(&d.output_deg) {
                let m = Pose::solve(&l, Circuit::Open, &CrankAngle::from_degrees(t))
                    .unwrap()
                    .point(CouplerPoint::new(u, v));
                let (so, co) = coupler_kinematics::sincos_deg(o);
                let dd = [o6[0] + link6 * co, o6[1] + link6 * so];
                assert!(((m.x - dd[0]).hypot(m.y - dd[1]) - link5).abs() < 1e-9 * link5);
                assert_eq!(crate::stage::branch_of([m.x, m.y], dd, o6), branch);
                for (i, wi) in ws.iter().enumerate() {
                    if (t - wi.start_deg).rem_euclid(360.0) <= wi.span_deg() + 1e-9 {
                        assert_eq!(
                            crate::stage::branch_of([m.x, m.y], d.dwells[i].point, o6),
                            branch,
                            "θ {t}: dwell point {i}"
                        );
                    }
                }
            }
        }
    }

    /// Jitter follows the arcs' deviation: nested windows about one curve's two arcs give a
    /// smaller worse-dwell jitter each time.
    #[test]
    fn double_arcs_jitter_shrinks_with_deviation() {
        let dr = driver(3.0, 3.5, 2.5, 1.5, -3.0);
        let mut last: Option<f64> = None;
        for h in [15.0, 12.0, 9.0, 6.0, 4.0] {
            let d = double_dwell_arcs(
                &dr,
                &w(210.0 - h, 210.0 + h),
                &w(370.0 - h, 370.0 + h),
                &DoubleArcOptions::DEFAULT,
                &Limits::DEFAULT,
            )
            .unwrap();
            let jitter = d.worst_jitter_deg();
            if let Some(j0) = last {
                assert!(jitter < j0, "±{h}°: jitter {jitter} (was {j0})");
            }
            last = Some(jitter);
        }
    }

    /// A jittery pair is refused; allowed more jitter, it designs.
    #[test]
    fn double_arcs_refuses_a_jittery_design() {
        let dr = driver(3.0, 3.0, 1.5, 4.5, 1.5);
        let (w1, w2) = (w(65.0, 295.0), w(315.0, 405.0));
        let err = double_dwell_arcs(&dr, &w1, &w2, &DoubleArcOptions::DEFAULT, &Limits::DEFAULT)
            .unwrap_err();
        assert!(
            matches!(err, DwellError::NoDoubleDwell(NoDoubleDwell::Jitter { jitter_deg, swing_deg, .. }) if jitter_deg > 0.1 * swing_deg),
            "{err}"
        );
        let loose = Limits {
            max_jitter_pct: 100.0,
            ..Limits::DEFAULT
        };
        assert!(double_dwell_arcs(&dr, &w1, &w2, &DoubleArcOptions::DEFAULT, &loose).is_ok());
    }

    /// A swing asked for is honoured within 0.5° when admissible, refused with the range
    /// of admissible swings when not.
    #[test]
    fn double_arcs_honours_or_refuses_a_swing() {
        let dr = driver(3.0, 3.5, 2.5, 1.5, -3.0);
        let (w1, w2) = (w(195.0, 225.0), w(355.0, 385.0));
        let free =
            double_dwell_arcs(&dr, &w1, &w2, &DoubleArcOptions::DEFAULT, &Limits::DEFAULT).unwrap();
        let want = 0.5 * free.dwell_swing_deg.unwrap();
        let opts = DoubleArcOptions {
            swing_deg: Some(want),
            ..DoubleArcOptions::DEFAULT
        };
        let d = double_dwell_arcs(&dr, &w1, &w2, &opts, &Limits::DEFAULT).unwrap();
        let got = d.dwell_swing_deg.unwrap();
        assert!(
            (got - want).abs() <= crate::SWING_ACCURACY_DEG,
            "asked {want}, got {got}"
        );
        let opts = DoubleArcOptions {
            swing_deg: Some(179.0),
            ..DoubleArcOptions::DEFAULT
        };
        assert!(matches!(
            double_dwell_arcs(&dr, &w1, &w2, &opts, &Limits::DEFAULT),
            Err(DwellError::SwingOutOfRange { .. })
        ));
    }

    /// The finder: on A = 3, B = 3.5, C = 2.5, point (1.5, −3) it finds an admissible
    /// double dwell; on the symmetric curve (mirror pairs only) nothing.
    #[test]
    fn finds_double_dwells() {
        let d = best_double_dwell(
            &driver(3.0, 3.5, 2.5, 1.5, -3.0),
            &DoubleDwellSearch::default(),
            &DoubleArcOptions::DEFAULT,
            &Limits::DEFAULT,
        )
        .unwrap();
        assert!(d.worst_jitter_deg() <= 0.1 * d.judged_swing_deg());
        assert!(d.shortest_felt_deg() >= 20.0, "{}", d.shortest_felt_deg());
        assert!(matches!(
            best_double_dwell(
                &driver(1.5, 1.5, 1.5, 1.5, -1.5),
                &DoubleDwellSearch::default(),
                &DoubleArcOptions::DEFAULT,
                &Limits::DEFAULT
            ),
            Err(DwellError::NothingFound { .. })
        ));
    }
}
