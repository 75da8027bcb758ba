//! A designed dwell six-bar, measured as its user feels it, and the one admissibility
//! contract every kind of dwell design must pass (docs/features.md, "dwell").

use crate::Inadmissible;
use crate::motion::{Driver, Motion};
use crate::stage::{OutputMotion, Stage};
use coupler_kinematics::{Circuit, CouplerPoint, FourBar};
use serde::Serialize;

/// Default lower limit of the links 5–6 transmission angle, degrees.
pub const DEFAULT_MIN_TRANSMISSION_DEG: f64 = 30.0;
/// Default largest jitter of a dwell, percent of the swing.
pub const DEFAULT_MAX_JITTER_PCT: f64 = 10.0;
/// Default largest ratio of links 5 and 6 (for the slot: of the block's farthest and
/// closest distance from O6).
pub const DEFAULT_MAX_LINK_RATIO: f64 = 10.0;
/// Default band of the felt dwell: the output within ± this of its dwell position, degrees.
pub const DEFAULT_DWELL_TOL_DEG: f64 = 0.1;
/// Default simulation step, crank degrees.
pub const DEFAULT_STEP_DEG: f64 = 1.0;
/// A swing asked for is honoured within this many degrees.
pub const SWING_ACCURACY_DEG: f64 = 0.5;
/// Peak output acceleration above this many times a cam's cycloidal rise of the same swing
/// over the same crank angle draws a warning.
pub const ACCELERATION_WARNING_FACTOR: f64 = 3.0;
/// Designers want transmission angles within [this, 180° − this] (Norton §3.3).
pub const TRANSMISSION_WARNING_DEG: f64 = 40.0;

/// The admissibility contract's limits, and the felt dwell's band.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Limits {
    /// Simulation step, crank degrees (divides 360).
    pub step_deg: f64,
    /// Links 5–6 transmission angle, folded into [0°, 90°], at least this all round.
    pub min_transmission_deg: f64,
    /// The worse dwell's jitter at most this percentage of the swing.
    pub max_jitter_pct: f64,
    /// The longer of links 5 and 6 at most this many times the shorter (slot: farthest over
    /// closest distance of the block from O6).
    pub max_link_ratio: f64,
    /// The felt dwell: the output within ± this of its dwell position, degrees.
    pub dwell_tol_deg: f64,
}

impl Limits {
    /// The defaults.
    pub const DEFAULT: Limits = Limits {
        step_deg: DEFAULT_STEP_DEG,
        min_transmission_deg: DEFAULT_MIN_TRANSMISSION_DEG,
        max_jitter_pct: DEFAULT_MAX_JITTER_PCT,
        max_link_ratio: DEFAULT_MAX_LINK_RATIO,
        dwell_tol_deg: DEFAULT_DWELL_TOL_DEG,
    };
}

impl Default for Limits {
    fn default() -> Self {
        Limits::DEFAULT
    }
}

/// `x ≤ limit`, false when either is NaN (so a NaN figure always fails a check).
fn at_most(x: f64, limit: f64) -> bool {
    x <= limit
}

/// Which dwell mechanism.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DwellKind {
    /// Six-bar with link 5 on a pseudo-arc.
    Single,
    /// Six-bar with link 5 on two arcs of equal radius.
    DoubleArcs,
    /// Slotted output link pivoted where two straight segments' lines meet.
    DoubleLines,
}

impl DwellKind {
    /// In words.
    pub fn describe(self) -> &'static str {
        match self {
            DwellKind::Single => "single dwell (link 5 on a pseudo-arc)",
            DwellKind::DoubleArcs => "double dwell (link 5 on two pseudo-arcs of equal radius)",
            DwellKind::DoubleLines => {
                "double dwell (block in a slotted link pivoted where two straight segments meet)"
            }
        }
    }
}

/// How O6 was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Norton's construction (Example 3-13): O6 on the perpendicular bisector of DE.
    Norton,
    /// O6 anywhere: the least jitter at the swing asked for.
    Optimise,
    /// Double arcs: O6 on the perpendicular bisector of the two dwell points.
    Bisector,
    /// Double lines: O6 where the lines meet.
    LinesMeet,
}

impl Method {
    /// In words.
    pub fn describe(self) -> &'static str {
        match self {
            Method::Norton => {
                "Norton's construction (O6 on the perpendicular bisector of DE, Example 3-13)"
            }
            Method::Optimise => "optimised (O6 anywhere: least jitter at the swing asked for)",
            Method::Bisector => "O6 on the perpendicular bisector of the two dwell points",
            Method::LinesMeet => "O6 where the two lines meet (Norton Example 3-14)",
        }
    }
}

/// A value and the crank angle where it occurs.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Peak {
    /// The value.
    pub value: f64,
    /// Crank angle, degrees.
    pub theta_deg: f64,
}

/// The dwell as a user feels it: the longest run of the simulation's samples, overlapping
/// the window, over which the output stays within ± `tol` of one position.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FeltDwell {
    /// The band, degrees (± this).
    pub tol_deg: f64,
    /// First crank angle of the run, degrees.
    pub start_deg: f64,
    /// Its crank span, degrees (samples − 1 steps).
    pub span_deg: f64,
    /// The dwell position: the middle of the output's range over the run, degrees.
    pub position_deg: f64,
}

/// One dwell: its window, how still the output stays in it, and the felt dwell.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Dwell {
    /// Window start, crank degrees (in [0°, 360°)).
    pub start_deg: f64,
    /// Window span, crank degrees.
    pub span_deg: f64,
    /// Where the dwell point is (D at the arc's centre; the slot's pivot for lines).
    pub point: [f64; 2],
    /// Mean output angle over the window's samples, degrees.
    pub output_deg: f64,
    /// Output motion during the window (max − min over its samples), degrees.
    pub jitter_deg: f64,
    /// The felt dwell.
    pub felt: FeltDwell,
    /// `[min, max]` of the links 5–6 transmission angle during the window (`None`: slot).
    pub transmission_range_deg: Option<[f64; 2]>,
}

/// The four-bar that drives the design, as built.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DriverReport {
    /// The atlas's linkage (crank = 1) whose curve is used.
    pub curve_linkage: FourBar,
    /// Its circuit.
    pub curve_circuit: Circuit,
    /// Its coupler point.
    pub curve_point: CouplerPoint,
    /// 0: the linkage itself; 1 or 2: that cognate drives the design.
    pub cognate: usize,
    /// The driving four-bar's ground pivots (crank's, rocker's) in the curve's frame.
    pub pivots: [[f64; 2]; 2],
    /// Its links `[crank, coupler, rocker, ground]` in the curve's units.
    pub links: [f64; 4],
    /// Its coupler point in its own coupler frame, curve units.
    pub point: [f64; 2],
    /// Its circuit.
    pub circuit: Circuit,
    /// Normalised to crank 1: `[coupler, rocker, ground]`.
    pub normalized: [f64; 3],
}

/// A designed and simulated dwell six-bar that passed the admissibility contract.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DwellDesign {
    /// Which kind.
    pub kind: DwellKind,
    /// How O6 was found.
    pub method: Method,
    /// The driving four-bar.
    pub driver: DriverReport,
    /// Links 5 and 6.
    pub stage: Stage,
    /// The dwells.
    pub dwells: Vec<Dwell>,
    /// The limits it was checked against.
    pub limits: Limits,
    /// Crank angles of the simulation, degrees (0 to 360).
    pub theta_deg: Vec<f64>,
    /// Output angle ψ (direction of link 6), degrees, unwrapped.
    pub output_deg: Vec<f64>,
    /// dψ/dθ (rad/rad, unit crank speed).
    pub output_velocity: Vec<f64>,
    /// d²ψ/dθ² (rad/rad²).
    pub output_acceleration: Vec<f64>,
    /// Links 5–6 transmission angle at each step, degrees (`None`: slot).
    pub output_transmission_deg: Option<Vec<f64>>,
    /// The four-bar's transmission angle at each step, degrees.
    pub fourbar_transmission_deg: Vec<f64>,
    /// `[min, max]` of the output angle, degrees.
    pub output_range_deg: [f64; 2],
    /// max − min of the output angle over the revolution, degrees.
    pub swing_deg: f64,
    /// For a double dwell: the turn between the dwells' mean outputs, degrees.
    pub dwell_swing_deg: Option<f64>,
    /// Largest |dψ/dθ| (refined between samples).
    pub peak_velocity: Peak,
    /// Largest |d²ψ/dθ²| (refined between samples).
    pub peak_acceleration: Peak,
    /// Closest approach of the coupler point M to O6 (refined), curve units.
    pub closest_approach: Peak,
    /// Farthest distance of M from O6 (refined), curve units.
    pub farthest_reach: Peak,
    /// Link ratio checked by the contract (≥ 1).
    pub link_ratio: f64,
    /// `[min, max]` of the links 5–6 transmission angle (`None`: slot).
    pub output_transmission_range_deg: Option<[f64; 2]>,
    /// `[min, max]` of the four-bar's transmission angle.
    pub fourbar_transmission_range_deg: [f64; 2],
    /// Warnings where Norton (or a designer) would warn.
    pub warnings: Vec<String>,
    /// How the design was reached (e.g. Norton's uncorrected O6 and its swing).
    pub notes: Vec<String>,
}

pub(crate) fn range(v: impl Iterator<Item = f64>) -> [f64; 2] {
    v.fold([f64::INFINITY, f64::NEG_INFINITY], |[a, b], x| {
        [a.min(x), b.max(x)]
    })
}

pub(crate) fn unwrap_deg(prev: f64, a: f64) -> f64 {
    prev + (a - prev + 180.0).rem_euclid(360.0) - 180.0
}

/// A window as (start in [0, 360), span).
pub(crate) type Span = (f64, f64);

/// What the cheap checks of a candidate give (no felt dwell, nothing refined).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Quick {
    pub out: OutputMotion,
    pub swing: f64,
    pub dwell_swing: Option<f64>,
    pub jitters: Vec<f64>,
    pub means: Vec<f64>,
    pub min_mu: f64,
}

impl Quick {
    /// The swing the jitter is judged against: between the dwells for a double dwell, the
    /// whole output range for a single one.
    pub fn judged_swing(&self) -> f64 {
        self.dwell_swing.unwrap_or(self.swing)
    }

    /// The worse dwell's jitter.
    pub fn worst_jitter(&self) -> f64 {
        self.jitters.iter().copied().fold(0.0, f64::max)
    }

    /// The jitter check of the contract.
    pub fn check_jitter(&self, limits: &Limits) -> Result<(), Inadmissible> {
        let (j, s) = (self.worst_jitter(), self.judged_swing());
        if !at_most(j, limits.max_jitter_pct / 100.0 * s) {
            return Err(Inadmissible::Jitter {
                jitter_deg: j,
                swing_deg: s,
                limit_pct: limits.max_jitter_pct,
            });
        }
        Ok(())
    }
}

/// Jitter (max − min) and mean of the output over a window's samples, relative to its first
/// sample and wrapped (an output that turns fully adds 360° on the way round: no motion).
fn window_stats(psi: &[f64], idx: &[usize]) -> (f64, f64) {
    let Some(&first) = idx.first() else {
        return (0.0, 0.0);
    };
    let reference = psi[first];
    let rel: Vec<f64> = idx
        .iter()
        .map(|&k| unwrap_deg(0.0, psi[k] - reference))
        .collect();
    let [lo, hi] = range(rel.iter().copied());
    (
        hi - lo,
        reference + rel.iter().sum::<f64>() / rel.len() as f64,
    )
}

/// The contract's checks but jitter, in order (assembly, transmission, full turn, link
/// ratio, some swing), and the cheap measures.
pub(crate) fn quick(
    stage: &Stage,
    motion: &Motion,
    windows: &[Span],
    limits: &Limits,
) -> Result<Quick, Inadmissible> {
    let out = stage.simulate(motion).map_err(|e| Inadmissible::Assembly {
        theta_deg: e.theta_deg,
        distance: e.distance,
    })?;
    let mut min_mu = 90.0_f64;
    if let Some(mu) = &out.mu {
        let mut at = 0.0;
        for (k, &m) in mu.iter().enumerate() {
            let f = m.min(180.0 - m);
            if f < min_mu {
                min_mu = f;
                at = motion.theta[k];
            }
        }
        if min_mu < limits.min_transmission_deg || min_mu <= 0.0 {
            return Err(Inadmissible::Transmission {
                min_deg: min_mu,
                theta_deg: at,
                limit_deg: limits.min_transmission_deg,
            });
        }
    }
    let turn = out.psi[out.psi.len() - 1] - out.psi[0];
    if turn.abs() > 180.0 {
        return Err(Inadmissible::FullTurn { turn_deg: turn });
    }
    let ratio = link_ratio(stage, motion);
    if !at_most(ratio, limits.max_link_ratio) {
        return Err(Inadmissible::LinkRatio {
            ratio,
            limit: limits.max_link_ratio,
            slot: matches!(stage, Stage::Slot { .. }),
        });
    }
    let [lo, hi] = range(out.psi.iter().copied());
    let swing = hi - lo;
    if at_most(swing, 1e-9) || swing.is_nan() {
        return Err(Inadmissible::NoSwing { swing_deg: swing });
    }
    let (mut jitters, mut means) = (Vec::new(), Vec::new());
    for &(s, span) in windows {
        let (j, m) = window_stats(&out.psi, &motion.window_indices(s, span));
        jitters.push(j);
        means.push(m);
    }
    let dwell_swing = (windows.len() == 2).then(|| unwrap_deg(0.0, means[1] - means[0]).abs());
    Ok(Quick {
        out,
        swing,
        dwell_swing,
        jitters,
        means,
        min_mu,
    })
}

/// The sampled link ratio (the slot's is refined in the report).
fn link_ratio(stage: &Stage, motion: &Motion) -> f64 {
    match *stage {
        Stage::Rocker { link5, link6, .. } => link5.max(link6) / link5.min(link6),
        Stage::Slot { pivot } => {
            let [lo, hi] = range(
                motion
                    .m
                    .iter()
                    .map(|m| (m[0] - pivot[0]).hypot(m[1] - pivot[1])),
            );
            hi / lo
        }
    }
}

/// Golden-section search for the maximum of `f` on `[a, b]`.
fn golden_max(mut a: f64, mut b: f64, f: impl Fn(f64) -> Option<f64>) -> Option<(f64, f64)> {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c)?, f(d)?);
    for _ in 0..80 {
        if (b - a).abs() < 1e-11 {
            break;
        }
        if fc > fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c)?;
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d)?;
        }
    }
    Some(if fc > fd { (c, fc) } else { (d, fd) })
}

/// Refines the maximum of `f(θ)` over the samples `values` (f's value at each sample):
/// golden-section search over the two steps around the largest sample. Keeps the sample
/// when the refinement fails or does not improve it.
pub(crate) fn refine_max(
    theta: &[f64],
    values: &[f64],
    step: f64,
    f: impl Fn(f64) -> Option<f64>,
) -> Peak {
    let (k, &v) =
        values.iter().enumerate().fold(
            (0, &f64::NEG_INFINITY),
            |a, b| if b.1 > a.1 { b } else { a },
        );
    let t = theta[k];
    match golden_max(t - step, t + step, &f) {
        Some((tt, vv)) if vv >= v => Peak {
            value: vv,
            theta_deg: tt.rem_euclid(360.0),
        },
        _ => Peak {
            value: v,
            theta_deg: t,
        },
    }
}

/// The felt dwell of a window: the longest run of consecutive samples (going round) that
/// overlaps the window and over which max ψ − min ψ ≤ 2·tol.
fn felt_dwell(theta: &[f64], psi: &[f64], window: &[usize], tol: f64, step: f64) -> FeltDwell {
    let n = psi.len() - 1; // the last sample repeats the first
    let inside: std::collections::HashSet<usize> = window.iter().copied().collect();
    let mut best: Option<(usize, usize, f64, f64)> = None; // (start, len, lo, hi)
    for i in 0..n {
        let (mut lo, mut hi) = (0.0_f64, 0.0_f64);
        let mut len = 0;
        let mut hits = false;
        while len < n {
            let k = (i + len) % n;
            let r = unwrap_deg(0.0, psi[k] - psi[i]);
            let (l2, h2) = (lo.min(r), hi.max(r));
            if h2 - l2 > 2.0 * tol {
                break;
            }
            lo = l2;
            hi = h2;
            hits |= inside.contains(&k);
            len += 1;
        }
        if hits && best.is_none_or(|b| len > b.1) {
            best = Some((i, len, psi[i] + lo, psi[i] + hi));
        }
    }
    match best {
        Some((i, len, lo, hi)) => FeltDwell {
            tol_deg: tol,
            start_deg: theta[i],
            span_deg: (len - 1) as f64 * step,
            position_deg: 0.5 * (lo + hi),
        },
        None => FeltDwell {
            tol_deg: tol,
            start_deg: theta[window.first().copied().unwrap_or(0)],
            span_deg: 0.0,
            position_deg: f64::NAN,
        },
    }
}

/// Everything a design is built from.
pub(crate) struct Build<'a> {
    pub kind: DwellKind,
    pub method: Method,
    pub driver: &'a Driver,
    pub motion: &'a Motion,
    pub stage: Stage,
    pub windows: Vec<Span>,
    pub dwell_points: Vec<[f64; 2]>,
    pub limits: Limits,
    pub notes: Vec<String>,
}

impl Build<'_> {
    /// Checks the whole contract and measures the design.
    pub fn finish(self) -> Result<DwellDesign, Inadmissible> {
        let Build {
            kind,
            method,
            driver,
            motion,
            stage,
            windows,
            dwell_points,
            limits,
            notes,
        } = self;
        let q = quick(&stage, motion, &windows, &limits)?;
        q.check_jitter(&limits)?;
        let step = motion.step();
        let out = &q.out;
        let dwells: Vec<Dwell> = windows
            .iter()
            .enumerate()
            .map(|(i, &(s, span))| {
                let idx = motion.window_indices(s, span);
                Dwell {
                    start_deg: s,
                    span_deg: span,
                    point: dwell_points[i.min(dwell_points.len() - 1)],
                    output_deg: q.means[i],
                    jitter_deg: q.jitters[i],
                    felt: felt_dwell(&motion.theta, &out.psi, &idx, limits.dwell_tol_deg, step),
                    transmission_range_deg: out
                        .mu
                        .as_ref()
                        .map(|mu| range(idx.iter().map(|&k| mu[k]))),
                }
            })
            .collect();
        // Refined peaks: the driver's exact state between samples.
        let at = |t: f64| {
            let s = driver.state(t)?;
            stage.at(s.m, s.velocity, s.acceleration)
        };
        let vel: Vec<f64> = out.dpsi.iter().map(|x| x.abs()).collect();
        let acc: Vec<f64> = out.ddpsi.iter().map(|x| x.abs()).collect();
        let peak_velocity = refine_max(&motion.theta, &vel, step, |t| at(t).map(|x| x.1.abs()));
        let peak_acceleration = refine_max(&motion.theta, &acc, step, |t| at(t).map(|x| x.2.abs()));
        let o6 = stage.pivot();
        let dist = |t: f64| {
            driver
                .state(t)
                .map(|s| (s.m[0] - o6[0]).hypot(s.m[1] - o6[1]))
        };
        let d: Vec<f64> = motion
            .m
            .iter()
            .map(|m| (m[0] - o6[0]).hypot(m[1] - o6[1]))
            .collect();
        let neg: Vec<f64> = d.iter().map(|x| -x).collect();
        let closest = refine_max(&motion.theta, &neg, step, |t| dist(t).map(|x| -x));
        let closest_approach = Peak {
            value: -closest.value,
            theta_deg: closest.theta_deg,
        };
        let farthest_reach = refine_max(&motion.theta, &d, step, dist);
        let link_ratio = match stage {
            Stage::Rocker { link5, link6, .. } => link5.max(link6) / link5.min(link6),
            Stage::Slot { .. } => farthest_reach.value / closest_approach.value,
        };
        if !at_most(link_ratio, limits.max_link_ratio) {
            return Err(Inadmissible::LinkRatio {
                ratio: link_ratio,
                limit: limits.max_link_ratio,
                slot: matches!(stage, Stage::Slot { .. }),
            });
        }
        let l = &driver.linkage;
        let links = driver.links();
        let mut design = DwellDesign {
            kind,
            method,
            driver: DriverReport {
                curve_linkage: *l,
                curve_circuit: driver.circuit,
                curve_point: driver.point,
                cognate: driver.cognate,
                pivots: driver.pivots(),
                links,
                point: [
                    driver.point.u * driver.crank(),
                    driver.point.v * driver.crank(),
                ],
                circuit: driver.circuit,
                normalized: [l.coupler, l.rocker, l.ground],
            },
            stage,
            dwells,
            limits,
            theta_deg: motion.theta.clone(),
            output_range_deg: range(out.psi.iter().copied()),
            swing_deg: q.swing,
            dwell_swing_deg: q.dwell_swing,
            output_velocity: out.dpsi.clone(),
            output_acceleration: out.ddpsi.clone(),
            output_transmission_range_deg: out.mu.as_ref().map(|m| range(m.iter().copied())),
            output_transmission_deg: out.mu.clone(),
            output_deg: out.psi.clone(),
            fourbar_transmission_range_deg: range(motion.mu4.iter().copied()),
            fourbar_transmission_deg: motion.mu4.clone(),
            peak_velocity,
            peak_acceleration,
            closest_approach,
            farthest_reach,
            link_ratio,
            warnings: Vec::new(),
            notes,
        };
        design.warnings = warnings(&design);
        Ok(design)
    }
}

/// Where Norton (or a designer) would warn.
fn warnings(d: &DwellDesign) -> Vec<String> {
    let mut w = Vec::new();
    // Acceleration against a cam's cycloidal rise of the same swing over the shortest
    // stretch of motion: peak ψ'' = 2π·S/β² (S, β in radians).
    let swing = d.dwell_swing_deg.unwrap_or(d.swing_deg).to_radians();
    let dwell_total: f64 = d.dwells.iter().map(|x| x.span_deg).sum();
    let beta = match d.dwells.len() {
        1 => 0.5 * (360.0 - dwell_total),
        _ => {
            let (a, b) = (&d.dwells[0], &d.dwells[1]);
            let g1 = (b.start_deg - (a.start_deg + a.span_deg)).rem_euclid(360.0);
            let g2 = (a.start_deg - (b.start_deg + b.span_deg)).rem_euclid(360.0);
            g1.min(g2)
        }
    }
    .max(1.0)
    .to_radians();
    let cycloidal = 2.0 * std::f64::consts::PI * swing / (beta * beta);
    let acc = d.peak_acceleration.value;
    let versus = format!(
        "{:.1} × a cam's cycloidal rise of the same swing over {:.0}° of crank",
        acc / cycloidal,
        beta.to_degrees()
    );
    match d.stage {
        Stage::Slot { .. } if d.closest_approach.value < 0.25 * d.farthest_reach.value => {
            w.push(format!(
                "the block passes {:.4} from O6 at θ = {:.1}° ({:.1} % of its farthest reach): there dψ/dθ peaks at {:.2} rad/rad and |d²ψ/dθ²| at {acc:.2} rad/rad² ({versus}); Norton §3.9 warns of high output acceleration when the block is near O6",
                d.closest_approach.value,
                d.closest_approach.theta_deg,
                100.0 * d.closest_approach.value / d.farthest_reach.value,
                d.peak_velocity.value
            ));
        }
        _ if acc > ACCELERATION_WARNING_FACTOR * cycloidal => {
            w.push(format!(
                "high output acceleration: |d²ψ/dθ²| reaches {acc:.2} rad/rad² at θ = {:.1}° ({versus})",
                d.peak_acceleration.theta_deg
            ));
        }
        _ => {}
    }
    for (k, x) in d.dwells.iter().enumerate() {
        if x.felt.span_deg < 0.5 * x.span_deg {
            w.push(format!(
                "dwell {}: the output stays within ±{}° for only {:.0}° of the {:.0}° window (jitter {:.3}°): the dwell a user feels is the shorter one",
                k + 1,
                x.felt.tol_deg,
                x.felt.span_deg,
                x.span_deg,
                x.jitter_deg
            ));
        }
    }
    let [lo, hi] = d.fourbar_transmission_range_deg;
    if lo < TRANSMISSION_WARNING_DEG || hi > 180.0 - TRANSMISSION_WARNING_DEG {
        w.push(format!(
            "the four-bar's transmission angle ranges {lo:.1}°–{hi:.1}°, outside the {TRANSMISSION_WARNING_DEG}°–{}° designers aim for",
            180.0 - TRANSMISSION_WARNING_DEG
        ));
    }
    if let Some([lo, hi]) = d.output_transmission_range_deg {
        let folded = lo.min(180.0 - hi);
        if folded < TRANSMISSION_WARNING_DEG {
            w.push(format!(
                "the links 5–6 transmission angle ranges {lo:.1}°–{hi:.1}° (within the limit {}°, but outside the {TRANSMISSION_WARNING_DEG}°–{}° designers aim for)",
                d.limits.min_transmission_deg,
                180.0 - TRANSMISSION_WARNING_DEG
            ));
        }
    }
    w
}

impl DwellDesign {
    /// The swing the design is judged by: between the dwells for a double dwell, the
    /// output's whole range for a single one.
    pub fn judged_swing_deg(&self) -> f64 {
        self.dwell_swing_deg.unwrap_or(self.swing_deg)
    }

    /// The worse dwell's jitter, degrees.
    pub fn worst_jitter_deg(&self) -> f64 {
        self.dwells.iter().map(|x| x.jitter_deg).fold(0.0, f64::max)
    }

    /// The shorter felt dwell, crank degrees.
    pub fn shortest_felt_deg(&self) -> f64 {
        self.dwells
            .iter()
            .map(|x| x.felt.span_deg)
            .fold(f64::INFINITY, f64::min)
    }

    /// The dyad branch in words.
    pub fn branch_text(&self) -> String {
        match self.stage {
            Stage::Rocker { branch, .. } => format!(
                "D {} of the line M → O6 ({:+}) all round (the other branch is another mechanism)",
                if branch > 0.0 { "left" } else { "right" },
                branch as i32
            ),
            Stage::Slot { .. } => {
                "the block on the slot, on one side of O6 all round (it never passes over O6)"
                    .to_string()
            }
        }
    }
}
