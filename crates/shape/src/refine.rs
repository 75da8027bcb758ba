//! Refinement: from a match, Levenberg–Marquardt over the linkage's continuous dimensions
//! (a four-bar's A, B, C; a geared five-bar's L1, L3, L4, L5 and phase φ, its gear ratio
//! held), the coupler point (u, v), the similarity transform and the crank angles (per
//! point when untimed; offset and rate when timed). The result is an exact linkage no
//! longer tied to the atlas grid.

use crate::fit::{CurveFit, FitOptions};
use crate::geom::{C64, abs};
use crate::kin::CouplerCurve;
use crate::lm::{Ask, Eval, LmOptions, RunningCost, solve};
use crate::matching::Match;
use crate::placement::Placement;
use crate::target::{Target, Timing};
use coupler_kinematics::{
    Class, Linkage, LinkageClass, MARGIN_TOL, Mechanism, Rotatability, TingClass,
};

/// A refined linkage and its fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Refined {
    /// The refined linkage, circuit and coupler point (atlas frame, crank units).
    pub curve: CouplerCurve,
    /// Its fit to the target.
    pub fit: CurveFit,
    /// The linkage in the user's frame.
    pub placement: Placement,
    /// RMS distance, % of the target's size.
    pub rms_pct: f64,
    /// Largest distance, % of the target's size.
    pub max_pct: f64,
    /// Class of the refined linkage (Barker's for a four-bar, Ting's for a geared
    /// five-bar).
    pub class: LinkageClass,
    /// The input crank no longer turns fully: a four-bar that is no longer a
    /// crank-rocker, a geared five-bar whose dyad does not close all round (for a closed
    /// target the curve is then not traced by turning the input; for an open one, check
    /// that the fitted crank interval is within the input's range).
    pub input_does_not_turn: bool,
    /// The refinement moved across a change point: a four-bar's Grashof type changed
    /// (`s + l = p + q` crossed) or the result is a change-point linkage; a geared
    /// five-bar's Ting class changed between I and II (through Class III) or the result
    /// is Class III.
    pub crossed_change_point: bool,
    /// The refined linkage's proportions: its longest length (a link, or the coupler
    /// point's distance from the crank pin) over its shortest link. The atlas grids stay
    /// below about 10; above [`MAX_PROPORTION`] the refinement has run off toward a
    /// degenerate limit (e.g. links a million times the crank, whose coupler point moves
    /// on a near-circle): a fit, but not a mechanism one would build.
    pub proportion: f64,
    /// LM iterations used.
    pub iterations: usize,
}

/// Proportion (longest length over shortest link, see [`Refined::proportion`]) above
/// which a refined linkage is flagged as run off.
pub const MAX_PROPORTION: f64 = 100.0;

/// A curve's proportion: its longest length (link, or the coupler point's distance from
/// the crank pin, the point in crank units) over its shortest link.
pub fn proportion(curve: &CouplerCurve) -> f64 {
    let lengths: Vec<f64> = match &curve.linkage {
        Linkage::FourBar(l) => vec![1.0, l.coupler, l.rocker, l.ground],
        Linkage::GearedFiveBar(l) => l.lengths().to_vec(),
    };
    let point = curve.point.u.hypot(curve.point.v);
    let longest = lengths.iter().copied().fold(point, f64::max);
    let shortest = lengths.iter().copied().fold(f64::INFINITY, f64::min);
    longest / shortest
}

/// Refines `start` (a match of `target`) by Levenberg–Marquardt; `None` if the start
/// cannot be evaluated. Deterministic.
pub fn refine(target: &Target, start: &Match, options: &FitOptions) -> Option<Refined> {
    let p = target.complex_points();
    let mir = start.fit.mirrored;
    let c0 = start.curve;
    // The curve's parameters (dimensions, u, v), then a, b, then the timing's.
    let mut g = c0.params();
    let nd = g.len();
    g.extend([
        start.fit.a[0],
        start.fit.a[1],
        start.fit.b[0],
        start.fit.b[1],
    ]);
    let timed = target.timing().is_timed();
    let offsets: Vec<f64> = match target.timing() {
        Timing::Angles(t) => t.iter().map(|x| x - t[0]).collect(),
        _ => (0..p.len()).map(|k| k as f64).collect(),
    };
    let free_step = matches!(target.timing(), Timing::EqualSteps) && !target.is_closed();
    let rate = start.fit.timing_rate.unwrap_or(1.0);
    let locals = if timed {
        g.push(start.fit.theta_deg[0]);
        if free_step {
            g.push(rate);
        }
        Vec::new()
    } else {
        start.fit.theta_deg.clone()
    };
    let make = |g: &[f64]| -> Option<CouplerCurve> { c0.with_params(&g[..nd]) };
    let tilde = |z: C64| if mir { z.conj() } else { z };
    let theta_of = |g: &[f64], l: &[f64], k: usize| -> f64 {
        if timed {
            let s = if free_step { g[nd + 5] } else { rate };
            g[nd + 4] + s * offsets[k]
        } else {
            l[k]
        }
    };
    let eval = |g: &[f64], l: &[f64], ask: Ask| -> Option<Eval> {
        let jac = ask.jacobian;
        let mut cost = RunningCost::new(ask);
        let curve = make(g)?;
        let gaps = curve.gaps();
        let (a, b) = (C64::new(g[nd], g[nd + 1]), C64::new(g[nd + 2], g[nd + 3]));
        let mut e = Eval {
            r: Vec::with_capacity(p.len()),
            ..Eval::default()
        };
        for (k, &pk) in p.iter().enumerate() {
            let t = theta_of(g, l, k);
            if !jac {
                let m = tilde(curve.at_with(&gaps, t)?.m);
                let r = a * m + b - pk;
                if !cost.add(r) {
                    return None;
                }
                e.r.push(r);
                continue;
            }
            let s = curve.sensitivity_with(&gaps, t)?;
            let m = tilde(s.at.m);
            let r = a * m + b - pk;
            if !cost.add(r) {
                return None;
            }
            e.r.push(r);
            for &d in &s.d {
                e.jg.push(a * tilde(d));
            }
            e.jg.extend([
                m,
                C64::new(0.0, 1.0) * m,
                C64::new(1.0, 0.0),
                C64::new(0.0, 1.0),
            ]);
            let dv = a * tilde(s.at.dm_dtheta);
            if timed {
                e.jg.push(dv);
                if free_step {
                    e.jg.push(dv * offsets[k]);
                }
            } else {
                e.jl.push(dv);
            }
        }
        Some(e)
    };
    let lm = LmOptions {
        max_iterations: options.max_iterations.max(REFINE_ITERATIONS),
        relative_decrease: 1e-15,
        ..LmOptions::DEFAULT
    };
    let res = solve(g, locals, eval, &lm)?;
    let g = res.global;
    let curve = make(&g)?;
    let theta: Vec<f64> = (0..p.len()).map(|k| theta_of(&g, &res.local, k)).collect();
    let (a, b) = (C64::new(g[nd], g[nd + 1]), C64::new(g[nd + 2], g[nd + 3]));
    let mut sum = 0.0;
    let mut max = 0.0f64;
    for (k, &pk) in p.iter().enumerate() {
        let d = abs(a * tilde(curve.at(theta[k])?.m) + b - pk);
        sum += d * d;
        max = max.max(d);
    }
    let rms = (sum / p.len() as f64).sqrt();
    let fit = CurveFit {
        mirrored: mir,
        a: [a.re, a.im],
        b: [b.re, b.im],
        theta_deg: theta,
        rms,
        max,
        timing_rate: timed.then(|| if free_step { g[nd + 5] } else { rate }),
    };
    let class = curve.linkage.class();
    let (input_does_not_turn, crossed_change_point) = match (&curve.linkage, &c0.linkage) {
        (Linkage::FourBar(l), Linkage::FourBar(l0)) => {
            let (class, start_class) = (l.class(), l0.class());
            (
                class != Class::Gcrr,
                class.is_change_point() || class.is_grashof() != start_class.is_grashof(),
            )
        }
        (Linkage::GearedFiveBar(l), Linkage::GearedFiveBar(l0)) => {
            let (class, start_class) = (l.ting_class(), l0.ting_class());
            (
                l.rotatability(MARGIN_TOL) != Rotatability::Full,
                class == TingClass::III || class != start_class,
            )
        }
        _ => return None,
    };
    let size = target.size();
    Some(Refined {
        placement: Placement::of(&curve, &fit),
        rms_pct: 100.0 * rms / size,
        max_pct: 100.0 * max / size,
        input_does_not_turn,
        crossed_change_point,
        class,
        proportion: proportion(&curve),
        curve,
        fit,
        iterations: res.iterations,
    })
}

/// Iteration cap of the refinement (an open window constrains the linkage less than a
/// whole curve, and its valley is long: hundreds of steps are common).
pub const REFINE_ITERATIONS: usize = 5000;

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::{Circuit, CouplerPoint, FourBar};

    fn four_bar(a: f64, b: f64, c: f64, u: f64, v: f64) -> CouplerCurve {
        CouplerCurve::new(
            FourBar::new(a, b, c).unwrap(),
            Circuit::Open,
            CouplerPoint::new(u, v),
        )
    }

    #[test]
    fn proportion_flags_run_off_linkages() {
        // An atlas-like crank-rocker is well inside the bound.
        let p = proportion(&four_bar(3.0, 3.5, 4.0, 1.5, 0.5));
        assert!((p - 4.0).abs() < 1e-12, "{p}");
        assert!(p < MAX_PROPORTION);
        // Links a million times the crank: flagged.
        assert!(proportion(&four_bar(1e6, 1e6, 1e6, 0.0, 1.0)) > MAX_PROPORTION);
        // A coupler point far off the coupler: flagged too.
        assert!(proportion(&four_bar(3.0, 3.5, 4.0, 500.0, 0.0)) > MAX_PROPORTION);
    }
}
