//! Levenberg–Marquardt for fits with a few global parameters and, optionally, one local
//! parameter per point (the crank angle at which the curve passes each target point).
//! The normal equations have an arrow structure, solved by eliminating the locals (the
//! Schur complement): O(n·G²) per iteration for n points and G globals, not O((n+G)³).
//! Residuals are complex (2-D); Marquardt's scaling by the diagonal makes the step
//! independent of each parameter's units (Moré, "The Levenberg–Marquardt algorithm:
//! implementation and theory", 1978). Deterministic: sequential sums in a fixed order.

use crate::geom::C64;
use nalgebra::{DMatrix, DVector};

/// Residuals and Jacobian at a parameter vector.
pub(crate) struct Eval {
    /// `r_j`, one per point.
    pub r: Vec<C64>,
    /// `∂r_j/∂g_p` row-major, `n × G` (empty when only the cost was asked for).
    pub jg: Vec<C64>,
    /// `∂r_j/∂l_j` (empty when there are no locals or only the cost was asked for).
    pub jl: Vec<C64>,
}

impl Eval {
    pub fn cost(&self) -> f64 {
        self.r.iter().map(|r| r.norm_sqr()).sum()
    }
}

/// What [`solve`] found.
#[derive(Clone, Debug)]
pub(crate) struct LmResult {
    pub global: Vec<f64>,
    pub local: Vec<f64>,
    pub iterations: usize,
}

/// Options.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LmOptions {
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction of it.
    pub relative_decrease: f64,
    /// Stop when the cost falls below this (absolute).
    pub cost_floor: f64,
    /// Largest change of a local parameter in one step.
    pub max_local_step: f64,
}

impl LmOptions {
    pub const DEFAULT: LmOptions = LmOptions {
        max_iterations: 100,
        relative_decrease: 1e-12,
        cost_floor: 0.0,
        max_local_step: 20.0,
    };
}

#[inline]
fn dot(a: C64, b: C64) -> f64 {
    a.re * b.re + a.im * b.im
}

/// Minimises `Σ |r_j|²` from `(global, local)`. `eval(g, l, jacobian)` returns the
/// residuals (and the Jacobian when asked), or `None` where the model is undefined (a
/// step there is rejected). `local` is empty for a fit without locals; otherwise it has
/// one entry per residual. `None` if the start itself is undefined.
pub(crate) fn solve<F>(
    global: Vec<f64>,
    local: Vec<f64>,
    mut eval: F,
    options: &LmOptions,
) -> Option<LmResult>
where
    F: FnMut(&[f64], &[f64], bool) -> Option<Eval>,
{
    let ng = global.len();
    let has_locals = !local.is_empty();
    let (mut g, mut l) = (global, local);
    let mut e = eval(&g, &l, true)?;
    let mut cost = e.cost();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    while iterations < options.max_iterations && cost > options.cost_floor {
        iterations += 1;
        let n = e.r.len();
        let mut hgg = DMatrix::<f64>::zeros(ng, ng);
        let mut grad_g = DVector::<f64>::zeros(ng);
        let mut hgl = vec![0.0; if has_locals { n * ng } else { 0 }];
        let mut hll = vec![0.0; if has_locals { n } else { 0 }];
        let mut grad_l = vec![0.0; if has_locals { n } else { 0 }];
        for j in 0..n {
            let row = &e.jg[j * ng..(j + 1) * ng];
            for p in 0..ng {
                grad_g[p] += dot(row[p], e.r[j]);
                for q in p..ng {
                    hgg[(p, q)] += dot(row[p], row[q]);
                }
            }
            if has_locals {
                let jl = e.jl[j];
                for p in 0..ng {
                    hgl[j * ng + p] = dot(row[p], jl);
                }
                hll[j] = jl.norm_sqr();
                grad_l[j] = dot(jl, e.r[j]);
            }
        }
        for p in 0..ng {
            for q in 0..p {
                hgg[(p, q)] = hgg[(q, p)];
            }
        }
        let mean_hll = if has_locals {
            hll.iter().sum::<f64>() / n as f64
        } else {
            0.0
        };
        let mut accepted = false;
        for _ in 0..12 {
            let mut s = hgg.clone();
            let mut rhs = -grad_g.clone();
            for p in 0..ng {
                s[(p, p)] += lambda * hgg[(p, p)].max(1e-300);
            }
            let damped: Vec<f64> = hll
                .iter()
                .map(|&h| h + lambda * h.max(1e-9 * mean_hll).max(1e-300))
                .collect();
            if has_locals {
                for j in 0..n {
                    let row = &hgl[j * ng..(j + 1) * ng];
                    let inv = 1.0 / damped[j];
                    for p in 0..ng {
                        rhs[p] += row[p] * grad_l[j] * inv;
                        for q in 0..ng {
                            s[(p, q)] -= row[p] * row[q] * inv;
                        }
                    }
                }
            }
            let Some(dg) = s
                .clone()
                .cholesky()
                .map(|c| c.solve(&rhs))
                .or_else(|| s.lu().solve(&rhs))
            else {
                lambda *= 10.0;
                continue;
            };
            let g_new: Vec<f64> = g.iter().zip(dg.iter()).map(|(a, b)| a + b).collect();
            let l_new: Vec<f64> = if has_locals {
                (0..n)
                    .map(|j| {
                        let row = &hgl[j * ng..(j + 1) * ng];
                        let mut t = grad_l[j];
                        for p in 0..ng {
                            t += row[p] * dg[p];
                        }
                        let step =
                            (-t / damped[j]).clamp(-options.max_local_step, options.max_local_step);
                        l[j] + step
                    })
                    .collect()
            } else {
                Vec::new()
            };
            let trial = g_new.iter().chain(l_new.iter()).all(|x| x.is_finite())
                && dg.iter().all(|x| x.is_finite());
            let new_cost = if trial {
                eval(&g_new, &l_new, false).map(|t| t.cost())
            } else {
                None
            };
            match new_cost {
                Some(c) if c.is_finite() && c <= cost => {
                    let decrease = cost - c;
                    g = g_new;
                    l = l_new;
                    lambda = (lambda / 3.0).max(1e-15);
                    accepted = true;
                    if decrease <= options.relative_decrease * cost {
                        return finish(g, l, eval, iterations);
                    }
                    break;
                }
                _ => lambda *= 4.0,
            }
        }
        if !accepted {
            break;
        }
        e = eval(&g, &l, true)?;
        cost = e.cost();
    }
    finish(g, l, eval, iterations)
}

fn finish<F>(g: Vec<f64>, l: Vec<f64>, mut eval: F, iterations: usize) -> Option<LmResult>
where
    F: FnMut(&[f64], &[f64], bool) -> Option<Eval>,
{
    eval(&g, &l, false)?;
    Some(LmResult {
        global: g,
        local: l,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fit a circle's centre and radius to points on it, each point with its own angle
    /// (a local): r_j = c + R·e^{iφ_j} − p_j.
    #[test]
    fn circle_with_local_angles() {
        let (c0, r0) = (C64::new(1.0, -2.0), 3.0);
        let phis: Vec<f64> = (0..20).map(|k| 0.1 + 0.25 * k as f64).collect();
        let pts: Vec<C64> = phis
            .iter()
            .map(|&p| c0 + super::super::geom::cis(p) * r0)
            .collect();
        let eval = |g: &[f64], l: &[f64], jac: bool| {
            let c = C64::new(g[0], g[1]);
            let mut e = Eval {
                r: Vec::new(),
                jg: Vec::new(),
                jl: Vec::new(),
            };
            for (j, p) in pts.iter().enumerate() {
                let u = super::super::geom::cis(l[j]);
                e.r.push(c + u * g[2] - p);
                if jac {
                    e.jg.extend([C64::new(1.0, 0.0), C64::new(0.0, 1.0), u]);
                    e.jl.push(C64::new(0.0, 1.0) * u * g[2]);
                }
            }
            Some(e)
        };
        let start_l: Vec<f64> = phis.iter().map(|p| p + 0.2).collect();
        let res = solve(vec![0.5, -1.0, 2.0], start_l, eval, &LmOptions::DEFAULT).unwrap();
        let c = C64::new(res.global[0], res.global[1]);
        let cost: f64 = pts
            .iter()
            .zip(&res.local)
            .map(|(p, &l)| (c + super::super::geom::cis(l) * res.global[2] - p).norm_sqr())
            .sum();
        assert!(cost < 1e-24, "{res:?}");
        assert!((res.global[2] - r0).abs() < 1e-12);
    }
}
