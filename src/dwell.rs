//! Dwell mechanisms built from coupler curves (Norton, *Design of Machinery*, §3.9;
//! domain.md §6): a six-bar whose output link stands (nearly) still while the coupler
//! point runs along a pseudo-arc (single dwell), or along either of two straight
//! segments or two equal arcs (double dwell).
//!
//! Single dwell: link 5 of length R (the arc's radius) hangs from the coupler point M;
//! its far end D is also on output link 6 (pivot O6, length L6). While M runs on the
//! arc, D sits at the arc's centre c, so link 6 stands still. O6 is placed so that link 6
//! is perpendicular, at the dwell, to the direction in which M pulls D when it leaves the
//! arc (towards the curve's farthest point from c), and L6 is sized so the output swings
//! by the requested angle. The dwell's **jitter** is the output's motion during the
//! dwell window: it follows the arc's radial deviation (≈ deviation·R / L6).
//!
//! Double dwell from two straight segments: a slotted output link pivoted where the two
//! lines meet; a slider at M runs in the slot, so the output angle is the direction of
//! M from the pivot, which stands still while M runs along either line. From two arcs of
//! equal radius: link 5 as above, D dwells at either centre; O6 is on the perpendicular
//! bisector of the two centres.

use crate::linkage::{Circuit, CouplerPoint, FourBar};
use crate::pose::{CrankAngle, Pose};
use crate::window::{CrankWindow, LineDirection, WindowMeasures, WindowSamples};
use serde::Serialize;

/// Why a dwell mechanism cannot be designed or simulated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DwellError {
    /// The window could not be measured.
    #[error(transparent)]
    Window(#[from] crate::window::WindowError),
    /// The window's points are not on a finite circle.
    #[error("the window {0}°–{1}° is not an arc (no finite circle fits it)")]
    NoArc(f64, f64),
    /// The two lines are (nearly) parallel: no pivot where they meet.
    #[error("the two straight segments are parallel: no pivot for the slotted link")]
    Parallel,
    /// The four-bar does not assemble somewhere in the revolution.
    #[error("the four-bar does not assemble at θ = {0}°")]
    NotAssembled(f64),
    /// Links 5 and 6 cannot reach each other somewhere in the revolution.
    #[error("links 5 and 6 do not assemble at θ = {0}° (try a smaller swing)")]
    Dyad(f64),
    /// The coupler point never leaves the arc: nothing to drive the output.
    #[error("the coupler point never leaves the arc: the output would not move")]
    NoMotion,
}

/// Which dwell mechanism.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DwellKind {
    /// Six-bar with link 5 on a pseudo-arc.
    Single,
    /// Slotted output link pivoted where two straight segments' lines meet.
    DoubleLines,
    /// Six-bar with link 5 on two arcs of equal radius.
    DoubleArcs,
}

/// A dwell window and how still the output stays in it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Dwell {
    /// First crank angle, degrees.
    pub start_deg: f64,
    /// Crank duration, degrees.
    pub span_deg: f64,
    /// Mean output angle during it, degrees.
    pub output_deg: f64,
    /// Output motion during it (max − min), degrees.
    pub jitter_deg: f64,
}

/// A designed and simulated dwell mechanism.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DwellMechanism {
    /// Which kind.
    pub kind: DwellKind,
    /// The four-bar.
    pub linkage: FourBar,
    /// Its circuit.
    pub circuit: Circuit,
    /// The coupler point.
    pub point: CouplerPoint,
    /// Link 5's length (0 for the slotted link).
    pub link5: f64,
    /// Output pivot O6.
    pub output_pivot: [f64; 2],
    /// Link 6's length at the dwell (for the slotted link: distance to M at the first dwell).
    pub link6: f64,
    /// Where D dwells (arc centres), or the slot pivot.
    pub dwell_points: Vec<[f64; 2]>,
    /// Crank angles of the simulation, degrees.
    pub theta_deg: Vec<f64>,
    /// Output angle at each, degrees (unwrapped, continuous).
    pub output_deg: Vec<f64>,
    /// Transmission angle between links 5 and 6 at D, degrees (90 for the slotted link).
    pub output_transmission_deg: Vec<f64>,
    /// The four-bar's transmission angle, degrees.
    pub fourbar_transmission_deg: Vec<f64>,
    /// The dwells.
    pub dwells: Vec<Dwell>,
    /// Output swing over the revolution (max − min), degrees.
    pub swing_deg: f64,
    /// `[min, max]` of the output transmission angle, degrees.
    pub output_transmission_range_deg: [f64; 2],
    /// `[min, max]` of the four-bar's transmission angle, degrees.
    pub fourbar_transmission_range_deg: [f64; 2],
}

struct Revolution {
    theta: Vec<f64>,
    m: Vec<[f64; 2]>,
    mu: Vec<f64>,
}

fn revolution(
    l: &FourBar,
    circuit: Circuit,
    p: CouplerPoint,
    start: f64,
    step: f64,
) -> Result<Revolution, DwellError> {
    let n = (360.0 / step).round() as usize;
    let mut r = Revolution {
        theta: Vec::with_capacity(n + 1),
        m: Vec::with_capacity(n + 1),
        mu: Vec::with_capacity(n + 1),
    };
    for k in 0..=n {
        let t = start + k as f64 * 360.0 / n as f64;
        let pose = Pose::solve(l, circuit, &CrankAngle::from_degrees(t))
            .ok_or(DwellError::NotAssembled(t))?;
        let m = pose.point(p);
        r.theta.push(t);
        r.m.push([m.x, m.y]);
        r.mu.push(pose.transmission.to_degrees());
    }
    Ok(r)
}

/// Intersection of circle(m, r5) and circle(o6, l6) nearest to `prev`.
fn dyad(m: [f64; 2], r5: f64, o6: [f64; 2], l6: f64, prev: [f64; 2]) -> Option<[f64; 2]> {
    let (dx, dy) = (o6[0] - m[0], o6[1] - m[1]);
    let d = dx.hypot(dy);
    let a = crate::pose::kahan_double_area(r5, l6, d)? / d; // height of D above line M→O6
    let foot = (r5 * r5 - l6 * l6 + d * d) / (2.0 * d);
    let (ux, uy) = (dx / d, dy / d);
    let base = [m[0] + foot * ux, m[1] + foot * uy];
    let c1 = [base[0] - a * uy, base[1] + a * ux];
    let c2 = [base[0] + a * uy, base[1] - a * ux];
    let dist = |c: [f64; 2]| (c[0] - prev[0]).hypot(c[1] - prev[1]);
    Some(if dist(c1) <= dist(c2) { c1 } else { c2 })
}

fn unwrap_deg(prev: f64, a: f64) -> f64 {
    prev + (a - prev + 180.0).rem_euclid(360.0) - 180.0
}

fn range(v: impl Iterator<Item = f64>) -> [f64; 2] {
    v.fold([f64::INFINITY, f64::NEG_INFINITY], |[a, b], x| {
        [a.min(x), b.max(x)]
    })
}

/// Simulates a link-5/link-6 dyad over a revolution starting at `start` (where D is at
/// `d0`), returning (output angles, transmission angles at D).
fn simulate_dyad(
    rev: &Revolution,
    r5: f64,
    o6: [f64; 2],
    l6: f64,
    d0: [f64; 2],
) -> Result<(Vec<f64>, Vec<f64>), DwellError> {
    let mut d = d0;
    let mut out = Vec::with_capacity(rev.m.len());
    let mut mu = Vec::with_capacity(rev.m.len());
    let mut prev_angle = libm::atan2(d0[1] - o6[1], d0[0] - o6[0]).to_degrees();
    for (k, &m) in rev.m.iter().enumerate() {
        d = dyad(m, r5, o6, l6, d).ok_or(DwellError::Dyad(rev.theta[k]))?;
        let a = unwrap_deg(
            prev_angle,
            libm::atan2(d[1] - o6[1], d[0] - o6[0]).to_degrees(),
        );
        prev_angle = a;
        out.push(a);
        let (p, q) = ([m[0] - d[0], m[1] - d[1]], [o6[0] - d[0], o6[1] - d[1]]);
        let cos = (p[0] * q[0] + p[1] * q[1]) / (r5 * l6);
        mu.push(libm::acos(cos.clamp(-1.0, 1.0)).to_degrees());
    }
    Ok((out, mu))
}

fn dwell_of(rev: &Revolution, out: &[f64], start: f64, span: f64) -> Dwell {
    let inside: Vec<f64> = rev
        .theta
        .iter()
        .zip(out)
        .filter(|(t, _)| {
            let rel = (*t - start).rem_euclid(360.0);
            rel <= span + 1e-9
        })
        .map(|(_, &o)| o)
        .collect();
    // Relative to one sample of the window, wrapped into (−180°, 180°]: the simulated
    // revolution may start inside the window, and an output that turns fully adds 360°
    // on the way round; neither is motion during the dwell.
    let reference = inside.first().copied().unwrap_or(0.0);
    let rel: Vec<f64> = inside
        .iter()
        .map(|&o| unwrap_deg(0.0, o - reference))
        .collect();
    let [lo, hi] = range(rel.iter().copied());
    Dwell {
        start_deg: start,
        span_deg: span,
        output_deg: reference + rel.iter().sum::<f64>() / rel.len().max(1) as f64,
        jitter_deg: hi - lo,
    }
}

/// Designs and simulates the single-dwell six-bar on the pseudo-arc of `window` (domain.md
/// §6), with an output swing of about `swing_deg`, simulated every `step_deg`.
pub fn single_dwell(
    l: &FourBar,
    circuit: Circuit,
    p: CouplerPoint,
    window: &CrankWindow,
    swing_deg: f64,
    step_deg: f64,
) -> Result<DwellMechanism, DwellError> {
    let w = WindowMeasures::measure(l, circuit, p, window, LineDirection::Fitted)?;
    let (Some(c), Some(r5)) = (w.arc_center, w.arc_radius) else {
        return Err(DwellError::NoArc(window.start_deg, window.end_deg));
    };
    let mid = 0.5 * (window.start_deg + window.end_deg);
    let rev = revolution(l, circuit, p, mid, step_deg)?;
    // The farthest the coupler point gets from the centre: it pulls D that way.
    let (far, far_d) = rev
        .m
        .iter()
        .map(|m| (*m, (m[0] - c[0]).hypot(m[1] - c[1])))
        .fold(([0.0, 0.0], 0.0), |a, b| if b.1 > a.1 { b } else { a });
    let excursion = far_d - r5;
    if excursion <= 1e-9 * r5 {
        return Err(DwellError::NoMotion);
    }
    let u = [(far[0] - c[0]) / far_d, (far[1] - c[1]) / far_d];
    let n = [-u[1], u[0]];
    let target = swing_deg.to_radians();
    let mut l6 = (excursion / target).max(0.05 * r5);
    let mut best = None;
    for _ in 0..12 {
        let o6 = [c[0] + l6 * n[0], c[1] + l6 * n[1]];
        match simulate_dyad(&rev, r5, o6, l6, c) {
            Ok((out, mu)) => {
                let [lo, hi] = range(out.iter().copied());
                let swing = (hi - lo).to_radians();
                best = Some((o6, l6, out, mu));
                if (swing - target).abs() <= 0.01 * target || swing <= 0.0 {
                    break;
                }
                l6 *= (swing / target).clamp(0.25, 4.0);
            }
            Err(e) => {
                if best.is_some() {
                    break;
                }
                // Too short to reach: lengthen link 6.
                l6 *= 2.0;
                if l6 > 1e6 * r5 {
                    return Err(e);
                }
            }
        }
    }
    let Some((o6, l6, out, mu)) = best else {
        return Err(DwellError::Dyad(mid));
    };
    let dwell = dwell_of(
        &rev,
        &out,
        window.start_deg.rem_euclid(360.0),
        window.span_deg(),
    );
    Ok(finish(
        DwellKind::Single,
        l,
        circuit,
        p,
        r5,
        o6,
        l6,
        vec![c],
        rev,
        out,
        mu,
        vec![dwell],
    ))
}

#[allow(clippy::too_many_arguments)]
fn finish(
    kind: DwellKind,
    l: &FourBar,
    circuit: Circuit,
    p: CouplerPoint,
    r5: f64,
    o6: [f64; 2],
    l6: f64,
    dwell_points: Vec<[f64; 2]>,
    rev: Revolution,
    out: Vec<f64>,
    mu: Vec<f64>,
    dwells: Vec<Dwell>,
) -> DwellMechanism {
    let [lo, hi] = range(out.iter().copied());
    DwellMechanism {
        kind,
        linkage: *l,
        circuit,
        point: p,
        link5: r5,
        output_pivot: o6,
        link6: l6,
        dwell_points,
        output_transmission_range_deg: range(mu.iter().copied()),
        fourbar_transmission_range_deg: range(rev.mu.iter().copied()),
        theta_deg: rev.theta,
        output_deg: out,
        output_transmission_deg: mu,
        fourbar_transmission_deg: rev.mu,
        dwells,
        swing_deg: hi - lo,
    }
}

/// The double dwell with a slotted output link pivoted where the lines of two straight
/// windows meet.
pub fn double_dwell_lines(
    l: &FourBar,
    circuit: Circuit,
    p: CouplerPoint,
    w1: &CrankWindow,
    w2: &CrankWindow,
    step_deg: f64,
) -> Result<DwellMechanism, DwellError> {
    let line = |w: &CrankWindow| -> Result<([f64; 2], [f64; 2]), DwellError> {
        let s = WindowSamples::sample(l, circuit, p, w)?;
        let m = crate::window::LineMeasures::of(&s.x, &s.y, &s.vx, &s.vy, LineDirection::Fitted);
        Ok((m.centroid, m.direction))
    };
    let ((g1, d1), (g2, d2)) = (line(w1)?, line(w2)?);
    let den = d1[0] * d2[1] - d1[1] * d2[0];
    if den.abs() < 1e-6 {
        return Err(DwellError::Parallel);
    }
    let t = ((g2[0] - g1[0]) * d2[1] - (g2[1] - g1[1]) * d2[0]) / den;
    let o6 = [g1[0] + t * d1[0], g1[1] + t * d1[1]];
    let rev = revolution(l, circuit, p, w1.start_deg, step_deg)?;
    let mut prev = libm::atan2(rev.m[0][1] - o6[1], rev.m[0][0] - o6[0]).to_degrees();
    let out: Vec<f64> = rev
        .m
        .iter()
        .map(|m| {
            prev = unwrap_deg(prev, libm::atan2(m[1] - o6[1], m[0] - o6[0]).to_degrees());
            prev
        })
        .collect();
    let mu = vec![90.0; out.len()];
    let dwells = vec![
        dwell_of(&rev, &out, w1.start_deg.rem_euclid(360.0), w1.span_deg()),
        dwell_of(&rev, &out, w2.start_deg.rem_euclid(360.0), w2.span_deg()),
    ];
    let l6 = (rev.m[0][0] - o6[0]).hypot(rev.m[0][1] - o6[1]);
    Ok(finish(
        DwellKind::DoubleLines,
        l,
        circuit,
        p,
        0.0,
        o6,
        l6,
        vec![o6],
        rev,
        out,
        mu,
        dwells,
    ))
}

/// The double dwell on two arcs of (nearly) equal radius: link 5 of the mean radius, D
/// dwelling at either centre, O6 on their perpendicular bisector (tried at ½, 1, 2, 4, 8,
/// 16 × the centres' separation from their midpoint, either side; of the designs that
/// assemble all the way round, the one whose worse dwell jitters least is kept).
pub fn double_dwell_arcs(
    l: &FourBar,
    circuit: Circuit,
    p: CouplerPoint,
    w1: &CrankWindow,
    w2: &CrankWindow,
    step_deg: f64,
) -> Result<DwellMechanism, DwellError> {
    let arc = |w: &CrankWindow| -> Result<([f64; 2], f64), DwellError> {
        let m = WindowMeasures::measure(l, circuit, p, w, LineDirection::Fitted)?;
        match (m.arc_center, m.arc_radius) {
            (Some(c), Some(r)) => Ok((c, r)),
            _ => Err(DwellError::NoArc(w.start_deg, w.end_deg)),
        }
    };
    let ((c1, r1), (c2, r2)) = (arc(w1)?, arc(w2)?);
    let r5 = 0.5 * (r1 + r2);
    let mid = [(c1[0] + c2[0]) / 2.0, (c1[1] + c2[1]) / 2.0];
    let sep = (c2[0] - c1[0]).hypot(c2[1] - c1[1]);
    if sep <= 1e-9 * r5 {
        return Err(DwellError::NoMotion);
    }
    let n = [-(c2[1] - c1[1]) / sep, (c2[0] - c1[0]) / sep];
    let start = 0.5 * (w1.start_deg + w1.end_deg);
    let rev = revolution(l, circuit, p, start, step_deg)?;
    // O6 on the bisector, at h = k·sep from the midpoint on either side: keep the design
    // that assembles all the way round with the best worst-case transmission angle.
    /// (O6, L6, output angles, transmission angles, worse dwell jitter)
    type Candidate = ([f64; 2], f64, Vec<f64>, Vec<f64>, f64);
    let mut best: Option<Candidate> = None;
    let mut last_err = DwellError::Dyad(start);
    for k in [1.0, 0.5, 2.0, 4.0, 8.0, 16.0] {
        for side in [1.0, -1.0] {
            let o6 = [
                mid[0] + side * k * sep * n[0],
                mid[1] + side * k * sep * n[1],
            ];
            let l6 = (c1[0] - o6[0]).hypot(c1[1] - o6[1]);
            match simulate_dyad(&rev, r5, o6, l6, c1) {
                Ok((out, mu)) => {
                    // Score: the worse of the two dwells' jitter (D must settle at both
                    // centres on the branch the mechanism runs on).
                    let jitter = |w: &CrankWindow| {
                        dwell_of(&rev, &out, w.start_deg.rem_euclid(360.0), w.span_deg()).jitter_deg
                    };
                    let score = jitter(w1).max(jitter(w2));
                    if best.as_ref().is_none_or(|b| score < b.4) {
                        best = Some((o6, l6, out, mu, score));
                    }
                }
                Err(e) => last_err = e,
            }
        }
    }
    let (o6, l6, out, mu, _) = best.ok_or(last_err)?;
    let dwells = vec![
        dwell_of(&rev, &out, w1.start_deg.rem_euclid(360.0), w1.span_deg()),
        dwell_of(&rev, &out, w2.start_deg.rem_euclid(360.0), w2.span_deg()),
    ];
    Ok(finish(
        DwellKind::DoubleArcs,
        l,
        circuit,
        p,
        r5,
        o6,
        l6,
        vec![c1, c2],
        rev,
        out,
        mu,
        dwells,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Jitter follows the arc's deviation: nested windows about one pseudo-arc, wider
    /// windows deviating more, give a larger jitter at the same swing.
    #[test]
    fn jitter_shrinks_with_deviation() {
        let l = FourBar::new(3.0, 2.5, 3.5).unwrap();
        let p = CouplerPoint::new(3.0, 0.4); // near the rocker pin: nearly circular swings
        let mut last: Option<(f64, f64)> = None;
        for half in [60.0, 45.0, 30.0, 20.0, 10.0] {
            let w = CrankWindow::new(130.0 - half, 130.0 + half, 1.0).unwrap();
            let dev = WindowMeasures::measure(&l, Circuit::Open, p, &w, LineDirection::Fitted)
                .unwrap()
                .arc_deviation_pct
                .unwrap();
            let d = single_dwell(&l, Circuit::Open, p, &w, 40.0, 1.0).unwrap();
            let jitter = d.dwells[0].jitter_deg;
            if let Some((dev0, jit0)) = last {
                assert!(
                    dev < dev0 && jitter < jit0,
                    "half {half}: dev {dev} (was {dev0}), jitter {jitter} (was {jit0})"
                );
            }
            last = Some((dev, jitter));
        }
    }

    /// The exact arc (rocker pin) leaves no motion to drive.
    #[test]
    fn exact_arc_has_no_motion() {
        let l = FourBar::new(3.0, 2.5, 3.5).unwrap();
        let w = CrankWindow::new(100.0, 160.0, 1.0).unwrap();
        assert_eq!(
            single_dwell(
                &l,
                Circuit::Open,
                CouplerPoint::new(3.0, 0.0),
                &w,
                40.0,
                1.0
            )
            .unwrap_err(),
            DwellError::NoMotion
        );
    }

    /// Hoeken-like straight segment and the slotted double dwell: the output stands nearly
    /// still on both lines.
    #[test]
    fn double_dwell_from_lines() {
        let l = FourBar::new(2.5, 2.5, 2.0).unwrap();
        let p = CouplerPoint::new(5.0, 0.0);
        let w1 = CrankWindow::new(150.0, 210.0, 1.0).unwrap();
        let w2 = CrankWindow::new(300.0, 330.0, 1.0).unwrap();
        let d = double_dwell_lines(&l, Circuit::Open, p, &w1, &w2, 1.0).unwrap();
        assert!(d.dwells[0].jitter_deg < 1.0, "{:?}", d.dwells);
        assert!(d.swing_deg > 5.0);
    }
}
