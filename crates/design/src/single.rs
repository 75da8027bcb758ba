//! The single-dwell six-bar on a pseudo-arc (Norton §3.9, Example 3-13): link 5 of the
//! arc's radius R hangs from the coupler point M, its far end D sits at the arc's centre
//! while M runs along the arc, and the output rocker 6 (pivot O6) is pinned to D.
//!
//! Two ways to place O6, reported alike:
//! - **Norton's construction**: D the arc's centre; the bisector of the arc's chord through
//!   D; E the farthest point along that line that link 5's end reaches while M goes round
//!   (the compass traced along the curve with its lead on the line); O6 on the
//!   perpendicular bisector of DE where O6D and O6E subtend the swing. Because D swings on
//!   link 6's arc and not along DE, the output's swing differs a little from the
//!   subtended angle: O6 is then moved along the same bisector until the simulated swing
//!   is the one asked for (the uncorrected swing is reported).
//! - **Optimised**: O6 anywhere round D (every 5°, then refined); for each direction link 6
//!   is sized so the simulated swing is the one asked for; the admissible design with the
//!   least jitter wins.
//!
//! Either way the swing is honoured within [`SWING_ACCURACY_DEG`](crate::SWING_ACCURACY_DEG)
//! or the request is refused with the largest swing the method allows and why.

use crate::design::{Build, Quick, Span, quick};
use crate::motion::{Driver, Motion};
use crate::stage::{Stage, branch_of};
use crate::{DwellDesign, DwellError, DwellKind, Inadmissible, Limits, Method};
use coupler_features::{CircleFitOptions, CrankWindow, fit_circle};

/// The coupler point's positions and velocities at a window's angles (curve frame).
pub(crate) struct WindowPoints {
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub vx: Vec<f64>,
    pub vy: Vec<f64>,
}

impl WindowPoints {
    pub fn sample(driver: &Driver, w: &CrankWindow) -> Result<WindowPoints, DwellError> {
        let mut p = WindowPoints {
            x: Vec::new(),
            y: Vec::new(),
            vx: Vec::new(),
            vy: Vec::new(),
        };
        for t in w.angles() {
            let s = driver.state(t).ok_or(DwellError::NotAssembled(t))?;
            p.x.push(s.m[0]);
            p.y.push(s.m[1]);
            p.vx.push(s.velocity[0]);
            p.vy.push(s.velocity[1]);
        }
        Ok(p)
    }

    pub fn points(&self) -> Vec<[f64; 2]> {
        self.x.iter().zip(&self.y).map(|(&x, &y)| [x, y]).collect()
    }
}

/// The geometric circle of a window: (centre, radius, largest radial deviation).
pub(crate) fn arc_of(
    driver: &Driver,
    w: &CrankWindow,
) -> Result<([f64; 2], f64, f64, WindowPoints), DwellError> {
    let p = WindowPoints::sample(driver, w)?;
    let c = fit_circle(&p.x, &p.y, None, &CircleFitOptions::DEFAULT)
        .ok_or(DwellError::NoArc(w.start_deg, w.end_deg))?;
    let dev = c.max_deviation(&p.x, &p.y);
    Ok((c.center, c.radius, dev, p))
}

/// How far along the admissibility checks a failure got (to report the closest miss).
pub(crate) fn stage_of(i: &Inadmissible) -> u8 {
    match i {
        Inadmissible::Assembly { .. } => 0,
        Inadmissible::Transmission { .. } => 1,
        Inadmissible::FullTurn { .. } => 2,
        Inadmissible::LinkRatio { .. } => 3,
        Inadmissible::NoSwing { .. } => 4,
        Inadmissible::Jitter { .. } => 5,
    }
}

/// Keeps the failure that got furthest (of two jitter failures, the smaller relative
/// jitter: the best the method gets).
pub(crate) fn closer(best: &mut Option<Inadmissible>, e: Inadmissible) {
    let better = match (best.as_ref(), &e) {
        (None, _) => true,
        (
            Some(Inadmissible::Jitter {
                jitter_deg: j0,
                swing_deg: s0,
                ..
            }),
            Inadmissible::Jitter {
                jitter_deg: j1,
                swing_deg: s1,
                ..
            },
        ) => j1 / s1 < j0 / s0,
        (Some(b), e) => stage_of(e) > stage_of(b),
    };
    if better {
        *best = Some(e);
    }
}

/// A one-parameter family of candidate stages (a line of O6 positions), scanned and solved
/// for the swing.
struct Family<'a> {
    motion: &'a Motion,
    windows: &'a [Span],
    limits: &'a Limits,
    /// Why the family stops at its ends (the optimiser's link 6 is kept within the link
    /// ratio bound), if it is a contract bound.
    edge: Option<Inadmissible>,
}

/// The outcome of solving one family for a swing.
#[derive(Default)]
struct Solved {
    /// Designs at the swing asked for: (parameter, stage, quick).
    hits: Vec<(f64, Stage, Quick)>,
    /// The largest admissible swing seen, its stage, and why the next parameter failed.
    largest: Option<(f64, Option<Inadmissible>)>,
    /// The smallest admissible swing seen.
    smallest: Option<f64>,
    /// The furthest-reaching failure.
    closest: Option<Inadmissible>,
}

impl Family<'_> {
    /// Scans `params` (in order), then bisects every bracket of the swing `target` between
    /// consecutive admissible parameters.
    fn solve(
        &self,
        params: &[f64],
        stage: &dyn Fn(f64) -> Option<Stage>,
        target: f64,
        out: &mut Solved,
    ) {
        let eval = |x: f64| -> Option<Result<(Stage, Quick), Inadmissible>> {
            let s = stage(x)?;
            Some(quick(&s, self.motion, self.windows, self.limits).map(|q| (s, q)))
        };
        let results: Vec<Option<Result<(Stage, Quick), Inadmissible>>> =
            params.iter().map(|&x| eval(x)).collect();
        // The whole contract (jitter included) at each parameter: the swings a refusal
        // names come only from designs that pass it, so every hint is one we honour.
        let full: Vec<Option<Result<f64, Inadmissible>>> = results
            .iter()
            .map(|r| {
                r.as_ref().map(|r| match r {
                    Ok((_, q)) => q.check_jitter(self.limits).map(|()| q.swing),
                    Err(e) => Err(*e),
                })
            })
            .collect();
        for (i, r) in full.iter().enumerate() {
            match r {
                Some(Ok(sw)) => {
                    let sw = *sw;
                    out.smallest = Some(out.smallest.map_or(sw, |s: f64| s.min(sw)));
                    if out.largest.as_ref().is_none_or(|l| sw > l.0) {
                        // Why the neighbours fail: a larger swing lies that way.
                        // Prefer a neighbour known to swing more (it failed on jitter),
                        // then one whose swing is unknown (it failed earlier), the
                        // furthest check first; a jitter failure swinging less is not
                        // "beyond" this swing.
                        let why = [i.checked_sub(1), Some(i + 1)]
                            .into_iter()
                            .flatten()
                            .filter_map(|j| match (full.get(j), results.get(j)) {
                                (Some(Some(Err(e))), Some(Some(Ok((_, q))))) => {
                                    (q.swing > sw).then_some((2, *e))
                                }
                                (Some(Some(Err(e))), _) => Some((1, *e)),
                                _ => None,
                            })
                            .max_by_key(|(rank, e)| (*rank, stage_of(e)))
                            .map(|(_, e)| e)
                            // At the end of the family: the family's own bound.
                            .or(if i == 0 || i + 1 == params.len() {
                                self.edge
                            } else {
                                None
                            });
                        out.largest = Some((sw, why));
                    }
                }
                Some(Err(e)) => closer(&mut out.closest, *e),
                None => {}
            }
        }
        // A scan point at the swing (e.g. the largest a refusal named) is a hit itself.
        for (i, r) in results.iter().enumerate() {
            if let (Some(Ok((s, q))), Some(Some(Ok(_)))) = (r, full.get(i)) {
                if (q.swing - target).abs() <= 0.01 {
                    out.hits.push((params[i], *s, q.clone()));
                }
            }
        }
        for i in 0..params.len().saturating_sub(1) {
            let (Some(Ok((_, q0))), Some(Ok((_, q1)))) = (&results[i], &results[i + 1]) else {
                continue;
            };
            let (f0, f1) = (q0.swing - target, q1.swing - target);
            if f0 * f1 > 0.0 {
                continue;
            }
            let (mut a, mut b, mut fa) = (params[i], params[i + 1], f0);
            let mut hit = None;
            for _ in 0..60 {
                let mid = 0.5 * (a + b);
                match eval(mid) {
                    Some(Ok((s, q))) => {
                        let f = q.swing - target;
                        if f.abs() <= 1e-6 {
                            hit = Some((mid, s, q));
                            break;
                        }
                        if f * fa > 0.0 {
                            a = mid;
                            fa = f;
                        } else {
                            b = mid;
                        }
                        hit = Some((mid, s, q));
                    }
                    _ => break,
                }
            }
            if let Some(h) = hit {
                if (h.2.swing - target).abs() <= 0.01 {
                    match h.2.check_jitter(self.limits) {
                        Ok(()) => out.hits.push(h),
                        Err(e) => closer(&mut out.closest, e),
                    }
                }
            }
        }
    }
}

/// The refusal when no candidate has the swing asked for.
fn refusal(solved: Solved, asked: f64, what: &'static str) -> DwellError {
    match solved.largest {
        Some((largest, why)) if largest < asked => DwellError::SwingTooLarge {
            asked_deg: asked,
            largest_deg: largest,
            what,
            why: why
                .or(solved.closest)
                .unwrap_or(Inadmissible::NoSwing { swing_deg: largest }),
        },
        Some((largest, _)) => DwellError::SwingOutOfRange {
            asked_deg: asked,
            smallest_deg: solved.smallest.unwrap_or(largest),
            largest_deg: largest,
        },
        None => DwellError::Inadmissible {
            what,
            why: solved
                .closest
                .unwrap_or(Inadmissible::NoSwing { swing_deg: 0.0 }),
        },
    }
}

/// Designs the single dwell on the pseudo-arc of `window` with an output swing (the
/// output's whole range over the revolution) of `swing_deg`, by `method`
/// ([`Method::Norton`] or [`Method::Optimise`]), checked against `limits`.
pub fn single_dwell(
    driver: &Driver,
    window: &CrankWindow,
    swing_deg: f64,
    method: Method,
    limits: &Limits,
) -> Result<DwellDesign, DwellError> {
    crate::check_step(limits.step_deg)?;
    let motion = Motion::sample(driver, limits.step_deg)?;
    let (c, r5, _, pts) = arc_of(driver, window)?;
    let excursion = motion
        .m
        .iter()
        .map(|m| ((m[0] - c[0]).hypot(m[1] - c[1]) - r5).abs())
        .fold(0.0, f64::max);
    if excursion <= 1e-9 * r5 {
        return Err(DwellError::NoMotion);
    }
    let span: Span = (window.start_deg.rem_euclid(360.0), window.span_deg());
    let windows = [span];
    let idx = motion.window_indices(span.0, span.1);
    let m0 = motion.m[idx[idx.len() / 2]];
    let family = Family {
        motion: &motion,
        windows: &windows,
        limits,
        edge: (method == Method::Optimise).then_some(Inadmissible::LinkRatio {
            ratio: limits.max_link_ratio,
            limit: limits.max_link_ratio,
            slot: false,
        }),
    };
    let rocker = |o6: [f64; 2], l6: f64| {
        let branch = branch_of(m0, c, o6);
        (branch != 0.0).then_some(Stage::Rocker {
            link5: r5,
            link6: l6,
            pivot: o6,
            branch,
        })
    };
    let mut solved = Solved::default();
    let mut notes = Vec::new();
    let what: &'static str;
    match method {
        Method::Norton => {
            what = "arc with Norton's construction";
            // The bisector of the arc's chord, through D = c.
            let (a, b) = (
                [pts.x[0], pts.y[0]],
                [pts.x[pts.x.len() - 1], pts.y[pts.y.len() - 1]],
            );
            let q = [b[0] - a[0], b[1] - a[1]];
            let ql = q[0].hypot(q[1]);
            let n = [-q[1] / ql, q[0] / ql];
            // Link 5's far end kept on the line c + t·n: t = n·w ± √((n·w)² − |w|² + R²),
            // w = M − c; the root near 0 at mid-dwell, followed all round.
            let nn = motion.m.len() - 1;
            let k0 = idx[idx.len() / 2];
            let root = |k: usize, sigma: f64| -> Result<f64, DwellError> {
                let m = motion.m[k];
                let w = [m[0] - c[0], m[1] - c[1]];
                let nw = n[0] * w[0] + n[1] * w[1];
                let disc = nw * nw - (w[0] * w[0] + w[1] * w[1]) + r5 * r5;
                if disc < 0.0 {
                    return Err(DwellError::NortonNoE {
                        theta_deg: motion.theta[k],
                        link5: r5,
                    });
                }
                Ok(nw + sigma * disc.sqrt())
            };
            let sigma = if root(k0, 1.0)?.abs() <= root(k0, -1.0)?.abs() {
                1.0
            } else {
                -1.0
            };
            let mut t_ext = 0.0_f64;
            for j in 0..nn {
                let t = root((k0 + j) % nn, sigma)?;
                if t.abs() > t_ext.abs() {
                    t_ext = t;
                }
            }
            let de = t_ext.abs();
            if de <= 1e-9 * r5 {
                return Err(DwellError::NoMotion);
            }
            let e = [c[0] + t_ext * n[0], c[1] + t_ext * n[1]];
            let mid = [0.5 * (c[0] + e[0]), 0.5 * (c[1] + e[1])];
            let perp = [-n[1], n[0]];
            let o6_at = |side: f64, beta: f64| {
                let (s, co) = coupler_kinematics::sincos_deg(0.5 * beta);
                let t = side * 0.5 * de * co / s;
                ([mid[0] + t * perp[0], mid[1] + t * perp[1]], 0.5 * de / s)
            };
            notes.push(format!(
                "Norton: D = ({:.4}, {:.4}) the arc's centre, link 5 = R = {r5:.4}; E = ({:.4}, {:.4}), the farthest link 5's end gets along the bisector of the arc's chord; |DE| = {de:.4}",
                c[0], c[1], e[0], e[1]
            ));
            let betas: Vec<f64> = (1..180).map(|k| k as f64).collect();
            for side in [1.0, -1.0] {
                let stage = |beta: f64| {
                    let (o6, l6) = o6_at(side, beta);
                    rocker(o6, l6)
                };
                let before = solved.hits.len();
                family.solve(&betas, &stage, swing_deg, &mut solved);
                for h in &mut solved.hits[before..] {
                    h.0 *= side; // remember the side in the parameter's sign
                }
                // Norton's own O6 (subtending exactly the swing), for the record.
                if let Some(s) = stage(swing_deg) {
                    match quick(&s, &motion, &windows, limits) {
                        Ok(q) => notes.push(format!(
                            "Norton's O6 on the {} side of DE, subtending exactly {swing_deg}°, swings {:.3}°",
                            if side > 0.0 { "left" } else { "right" },
                            q.swing
                        )),
                        Err(e) => notes.push(format!(
                            "Norton's O6 on the {} side of DE, subtending exactly {swing_deg}°: {e}",
                            if side > 0.0 { "left" } else { "right" }
                        )),
                    }
                }
            }
            if let Some(best) = least_jitter(&solved.hits) {
                let beta = best.0.abs();
                notes.push(format!(
                    "O6 moved along the bisector of DE ({} side) to subtend {beta:.3}°, where the simulated swing is {:.3}°",
                    if best.0 > 0.0 { "left" } else { "right" },
                    best.2.swing
                ));
            }
        }
        _ => {
            what = "arc with O6 anywhere round D";
            let lo = r5 / limits.max_link_ratio;
            let hi = r5 * limits.max_link_ratio;
            let grid: Vec<f64> = (0..=60)
                .map(|k| lo * (hi / lo).powf(k as f64 / 60.0))
                .collect();
            let direction_stage = |phi: f64| {
                move |l6: f64| {
                    let (s, co) = coupler_kinematics::sincos_deg(phi);
                    rocker([c[0] + l6 * co, c[1] + l6 * s], l6)
                }
            };
            let mut per_dir: Vec<(f64, f64)> = Vec::new(); // (phi, least jitter)
            for j in 0..72 {
                let phi = j as f64 * 5.0;
                let before = solved.hits.len();
                family.solve(&grid, &direction_stage(phi), swing_deg, &mut solved);
                for h in &mut solved.hits[before..] {
                    h.0 = phi;
                }
                if let Some(b) = least_jitter(&solved.hits[before..]) {
                    per_dir.push((phi, b.2.worst_jitter()));
                }
            }
            // Refine the best direction (golden section on the least jitter).
            if let Some(&(phi0, _)) = per_dir.iter().min_by(|a, b| a.1.total_cmp(&b.1)) {
                let jitter_at = |phi: f64| -> Option<f64> {
                    let mut s = Solved::default();
                    family.solve(&grid, &direction_stage(phi), swing_deg, &mut s);
                    least_jitter(&s.hits).map(|h| -h.2.worst_jitter())
                };
                let (mut a, mut b) = (phi0 - 5.0, phi0 + 5.0);
                let g = 0.5 * (5f64.sqrt() - 1.0);
                for _ in 0..24 {
                    let (x1, x2) = (b - g * (b - a), a + g * (b - a));
                    match (jitter_at(x1), jitter_at(x2)) {
                        (Some(f1), Some(f2)) if f1 > f2 => b = x2,
                        (Some(_), Some(_)) => a = x1,
                        _ => break,
                    }
                }
                let phi = 0.5 * (a + b);
                let mut s = Solved::default();
                family.solve(&grid, &direction_stage(phi), swing_deg, &mut s);
                for mut h in s.hits {
                    h.0 = phi;
                    solved.hits.push(h);
                }
            }
            if let Some(best) = least_jitter(&solved.hits) {
                notes.push(format!(
                    "O6 searched all round D every 5° (refined to {:.2}° from D), link 6 sized for the swing; least jitter",
                    best.0.rem_euclid(360.0)
                ));
            }
        }
    }
    let Some(best) = least_jitter(&solved.hits) else {
        return Err(refusal(solved, swing_deg, what));
    };
    let stage = best.1;
    Build {
        kind: DwellKind::Single,
        method,
        driver,
        motion: &motion,
        stage,
        windows: windows.to_vec(),
        dwell_points: vec![c],
        limits: *limits,
        notes,
    }
    .finish()
    .map_err(|why| DwellError::Inadmissible { what, why })
}

fn least_jitter(hits: &[(f64, Stage, Quick)]) -> Option<&(f64, Stage, Quick)> {
    hits.iter()
        .min_by(|a, b| a.2.worst_jitter().total_cmp(&b.2.worst_jitter()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::{Circuit, CouplerPoint, FourBar};

    fn driver(a: f64, b: f64, c: f64, u: f64, v: f64) -> Driver {
        Driver::original(
            FourBar::new(a, b, c).unwrap(),
            Circuit::Open,
            CouplerPoint::new(u, v),
        )
    }

    /// Both methods honour a reachable swing within 0.5° (to 0.01° in fact) and refuse an
    /// unreachable one, naming the largest swing and why.
    #[test]
    fn swing_honoured_or_refused() {
        let d = driver(2.0, 2.0, 2.5, 2.5, 1.0);
        let w = CrankWindow::new(150.0, 280.0, 1.0).unwrap();
        for method in [Method::Norton, Method::Optimise] {
            for swing in [20.0, 45.0] {
                let x = single_dwell(&d, &w, swing, method, &Limits::DEFAULT).unwrap();
                assert!(
                    (x.swing_deg - swing).abs() <= 0.01,
                    "{method:?} {swing}: {}",
                    x.swing_deg
                );
            }
            match single_dwell(&d, &w, 170.0, method, &Limits::DEFAULT).unwrap_err() {
                DwellError::SwingTooLarge { largest_deg, .. } => assert!(largest_deg < 170.0),
                e => panic!("{method:?}: {e}"),
            }
        }
    }

    /// Jitter follows the arc's deviation: nested windows about one pseudo-arc give a
    /// smaller jitter at the same swing.
    #[test]
    fn jitter_shrinks_with_deviation() {
        let d = driver(2.0, 2.0, 2.5, 2.5, 1.0);
        let mut last: Option<f64> = None;
        for half in [60.0, 45.0, 30.0, 20.0] {
            let w = CrankWindow::new(215.0 - half, 215.0 + half, 1.0).unwrap();
            let x = single_dwell(&d, &w, 40.0, Method::Optimise, &Limits::DEFAULT).unwrap();
            let j = x.dwells[0].jitter_deg;
            if let Some(j0) = last {
                assert!(j < j0, "±{half}°: jitter {j} (was {j0})");
            }
            last = Some(j);
        }
    }

    /// The exact arc (the rocker pin) leaves no motion to drive.
    #[test]
    fn exact_arc_has_no_motion() {
        let d = driver(3.0, 2.5, 3.5, 3.0, 0.0);
        let w = CrankWindow::new(100.0, 160.0, 1.0).unwrap();
        assert_eq!(
            single_dwell(&d, &w, 40.0, Method::Norton, &Limits::DEFAULT).unwrap_err(),
            DwellError::NoMotion
        );
    }
}
