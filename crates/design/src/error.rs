//! Why a dwell six-bar cannot be designed: typed, with the figures a designer needs to
//! decide what to change.

use serde::Serialize;

/// Why a design fails the admissibility contract ([`crate::Limits`]), checked in this
/// order on the simulated revolution.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, thiserror::Error)]
#[serde(tag = "check", rename_all = "kebab-case")]
pub enum Inadmissible {
    /// Links 5 and 6 cannot reach each other (or, for the slot, M passes through O6).
    #[error(
        "links 5 and 6 do not assemble at θ = {theta_deg}° (the coupler point is {distance:.4} from O6)"
    )]
    Assembly {
        /// Crank angle, degrees.
        theta_deg: f64,
        /// |M − O6| there.
        distance: f64,
    },
    /// The links 5–6 transmission angle (folded into [0°, 90°]) falls below the limit.
    #[error(
        "the links 5–6 transmission angle falls to {min_deg:.1}° at θ = {theta_deg}° (limit {limit_deg}°, --min-transmission)"
    )]
    Transmission {
        /// Least folded transmission angle, degrees.
        min_deg: f64,
        /// Where, crank degrees.
        theta_deg: f64,
        /// The limit, degrees.
        limit_deg: f64,
    },
    /// The output turns fully round instead of oscillating.
    #[error(
        "the output turns {turn_deg:.0}° in one revolution instead of oscillating (the coupler curve winds round O6)"
    )]
    FullTurn {
        /// Net turn over one revolution, degrees.
        turn_deg: f64,
    },
    /// Link 5 and link 6 (for the slot: the block's farthest and closest distance from O6)
    /// differ by more than the bound.
    #[error(
        "{what} ({ratio:.1} : 1, bound {limit} : 1, --max-link-ratio)",
        what = if *slot { "the block comes much closer to O6 than it goes from it" } else { "links 5 and 6 differ too much in length" }
    )]
    LinkRatio {
        /// The ratio (≥ 1).
        ratio: f64,
        /// The bound.
        limit: f64,
        /// Whether it is the slot's reach ratio.
        slot: bool,
    },
    /// The worse dwell's jitter exceeds the allowed fraction of the swing.
    #[error(
        "the dwell jitters {jitter_deg:.3}° on a {swing_deg:.3}° swing ({:.1} % > {limit_pct} %, --max-jitter-pct)",
        100.0 * jitter_deg / swing_deg
    )]
    Jitter {
        /// Worse dwell's jitter, degrees.
        jitter_deg: f64,
        /// The swing it is compared with, degrees.
        swing_deg: f64,
        /// The limit, percent.
        limit_pct: f64,
    },
    /// The output does not move.
    #[error("the output does not move (swing {swing_deg:.2e}°)")]
    NoSwing {
        /// The swing, degrees.
        swing_deg: f64,
    },
}

/// Why a dwell mechanism cannot be designed or simulated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DwellError {
    /// The window could not be measured.
    #[error(transparent)]
    Window(#[from] coupler_features::WindowError),
    /// The window's points are not on a finite circle.
    #[error("the window {0}°–{1}° is not an arc (no finite circle fits it)")]
    NoArc(f64, f64),
    /// The two lines are (nearly) parallel: no pivot where they meet.
    #[error("the two straight segments are parallel: no pivot for the slotted link")]
    Parallel,
    /// The four-bar does not assemble somewhere in the revolution.
    #[error("the four-bar does not assemble at θ = {0}°")]
    NotAssembled(f64),
    /// The coupler point never leaves the arc: nothing to drive the output.
    #[error("the coupler point never leaves the arc: the output would not move")]
    NoMotion,
    /// The step does not divide the turn.
    #[error("the simulation step must divide 360° and be in (0°, 10°], got {0}")]
    BadStep(f64),
    /// Norton's construction does not apply to this arc.
    #[error(
        "Norton's construction does not apply: at θ = {theta_deg}° the coupler point is farther than link 5 ({link5:.4}) from the bisector of the arc's chord, so link 5's end cannot stay on it and there is no point E (try --method optimise)"
    )]
    NortonNoE {
        /// Where, crank degrees.
        theta_deg: f64,
        /// Link 5.
        link5: f64,
    },
    /// The swing asked for is beyond every admissible design of this method.
    #[error(
        "no admissible design swings {asked_deg}°: the largest this {what} allows is {largest_deg:.2}°; beyond it {why}"
    )]
    SwingTooLarge {
        /// The swing asked for, degrees.
        asked_deg: f64,
        /// The largest admissible swing found, degrees.
        largest_deg: f64,
        /// What was searched ("arc with Norton's construction", …).
        what: &'static str,
        /// Why larger swings fail.
        why: Inadmissible,
    },
    /// The swing asked for is outside the admissible designs' swings.
    #[error(
        "no admissible design swings {asked_deg}°: the admissible designs found swing {smallest_deg:.2}°–{largest_deg:.2}° (a single dwell: the output's whole range; a double dwell: the turn between the dwells)"
    )]
    SwingOutOfRange {
        /// The swing asked for, degrees.
        asked_deg: f64,
        /// Smallest admissible swing found, degrees.
        smallest_deg: f64,
        /// Largest admissible swing found, degrees.
        largest_deg: f64,
    },
    /// A slotted link's swing is fixed by the two lines.
    #[error(
        "a slotted link pivoted where the lines meet swings {fixed_deg:.2}° between the dwells (the angle between the lines); {asked_deg}° cannot be chosen"
    )]
    SwingFixed {
        /// The swing asked for, degrees.
        asked_deg: f64,
        /// The geometry's swing, degrees.
        fixed_deg: f64,
    },
    /// No admissible design at all; the reason of the candidate that came closest.
    #[error("no admissible design on {what}: {why}")]
    Inadmissible {
        /// What was designed ("this arc", "these two lines", …).
        what: &'static str,
        /// The failed check.
        why: Inadmissible,
    },
    /// Two arcs admit no double-dwell six-bar, and why.
    #[error("no double dwell on two arcs: {0}")]
    NoDoubleDwell(crate::NoDoubleDwell),
    /// The automatic search found no admissible double dwell.
    #[error(
        "no admissible double dwell on this curve: {arc_pairs} pairs of pseudo-arcs and {line_pairs} pairs of straight segments were designed, none passes (closest: {closest})"
    )]
    NothingFound {
        /// Arc pairs designed.
        arc_pairs: usize,
        /// Line pairs designed.
        line_pairs: usize,
        /// The reason of the candidate that came closest.
        closest: String,
    },
    /// `--cognate K` with K not 0, 1 or 2.
    #[error("there is no cognate {0}: `cognates` lists the original (0) and cognates 1 and 2")]
    NoSuchCognate(usize),
    /// The cognate cannot be formed.
    #[error("cognates: {0}")]
    Cognate(String),
    /// The cognate is not a crank-rocker.
    #[error(
        "cognate {k} is a {class}, not a crank-rocker: its input link only rocks between toggles, so a motor at its ground pivot cannot drive it round the whole curve (use the original or the crank-rocker cognate)"
    )]
    CognateNotCrank {
        /// Which cognate.
        k: usize,
        /// Its Barker class.
        class: String,
    },
}
