//! Refinement: from a match, Levenberg–Marquardt over the linkage's continuous dimensions
//! (A, B, C), the coupler point (u, v), the similarity transform and the crank angles
//! (per point when untimed; offset and rate when timed). The result is an exact four-bar
//! no longer tied to the atlas grid.

use crate::fit::{CurveFit, FitOptions};
use crate::geom::{C64, abs};
use crate::kin::CouplerCurve;
use crate::lm::{Eval, LmOptions, solve};
use crate::matching::Match;
use crate::placement::Placement;
use crate::target::{Target, Timing};
use coupler_kinematics::{Class, CouplerPoint, FourBar};

/// A refined four-bar and its fit.
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
    /// Barker class of the refined linkage.
    pub class: Class,
    /// It is no longer a crank-rocker: the crank does not turn fully (for a closed target
    /// the curve is then not traced by a crank turn; for an open one, check that the fitted
    /// crank interval is within the crank's range).
    pub not_crank_rocker: bool,
    /// The refinement moved across a change point (`s + l = p + q`): the start and the
    /// result differ in Grashof type, or the result is a change-point linkage.
    pub crossed_change_point: bool,
    /// LM iterations used.
    pub iterations: usize,
}

/// Refines `start` (a match of `target`) by Levenberg–Marquardt; `None` if the start
/// cannot be evaluated. Deterministic.
pub fn refine(target: &Target, start: &Match, options: &FitOptions) -> Option<Refined> {
    let p = target.complex_points();
    let mir = start.fit.mirrored;
    let c0 = start.curve;
    let l0 = c0.linkage;
    let mut g = vec![
        l0.coupler,
        l0.rocker,
        l0.ground,
        c0.point.u,
        c0.point.v,
        start.fit.a[0],
        start.fit.a[1],
        start.fit.b[0],
        start.fit.b[1],
    ];
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
    let make = |g: &[f64]| -> Option<CouplerCurve> {
        Some(CouplerCurve {
            linkage: FourBar::new(g[0], g[1], g[2]).ok()?,
            circuit: c0.circuit,
            point: CouplerPoint::new(g[3], g[4]),
        })
    };
    let tilde = |z: C64| if mir { z.conj() } else { z };
    let theta_of = |g: &[f64], l: &[f64], k: usize| -> f64 {
        if timed {
            let s = if free_step { g[10] } else { rate };
            g[9] + s * offsets[k]
        } else {
            l[k]
        }
    };
    let eval = |g: &[f64], l: &[f64], jac: bool| -> Option<Eval> {
        let curve = make(g)?;
        let gaps = coupler_kinematics::ToggleGaps::of(&curve.linkage);
        let (a, b) = (C64::new(g[5], g[6]), C64::new(g[7], g[8]));
        let mut e = Eval {
            r: Vec::with_capacity(p.len()),
            jg: Vec::new(),
            jl: Vec::new(),
        };
        for (k, &pk) in p.iter().enumerate() {
            let t = theta_of(g, l, k);
            if !jac {
                let m = tilde(curve.at_with(&gaps, t)?.m);
                e.r.push(a * m + b - pk);
                continue;
            }
            let s = curve.sensitivity_with(&gaps, t)?;
            let m = tilde(s.at.m);
            e.r.push(a * m + b - pk);
            for d in s.d {
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
    let (a, b) = (C64::new(g[5], g[6]), C64::new(g[7], g[8]));
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
        timing_rate: timed.then(|| if free_step { g[10] } else { rate }),
    };
    let class = curve.linkage.class();
    let start_class = l0.class();
    let size = target.size();
    Some(Refined {
        placement: Placement::of(&curve, &fit),
        rms_pct: 100.0 * rms / size,
        max_pct: 100.0 * max / size,
        not_crank_rocker: class != Class::Gcrr,
        crossed_change_point: class.is_change_point()
            || class.is_grashof() != start_class.is_grashof(),
        class,
        curve,
        fit,
        iterations: res.iterations,
    })
}

/// Iteration cap of the refinement (an open window constrains the linkage less than a
/// whole curve, and its valley is long: hundreds of steps are common).
pub const REFINE_ITERATIONS: usize = 5000;
