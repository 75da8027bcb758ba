//! Levenberg–Marquardt for fits with a few global parameters and, optionally, one local
//! parameter per point (the crank angle at which the curve passes each target point).
//! The normal equations have an arrow structure, solved by eliminating the locals (the
//! Schur complement): O(n·G²) per iteration for n points and G globals, not O((n+G)³).
//! Residuals are complex (2-D); Marquardt's scaling by the diagonal makes the step
//! independent of each parameter's units (Moré, "The Levenberg–Marquardt algorithm:
//! implementation and theory", 1978). The damping follows the gain ratio of each accepted
//! step (Nielsen, "Damping parameter in Marquardt's method", IMM-REP-1999-05): it is held
//! where the linear model predicts the decrease fairly, so few trials are rejected.
//! Deterministic: sequential sums in a fixed order.

use crate::geom::C64;
use nalgebra::{DMatrix, DVector, Matrix4, Vector4};

/// Residuals and Jacobian at a parameter vector.
#[derive(Clone, Debug, Default)]
pub(crate) struct Eval {
    /// `r_j`, one per point.
    pub r: Vec<C64>,
    /// `∂r_j/∂g_p` row-major, `n × G` (empty when only the cost was asked for, or when
    /// the rows are given by `sim`).
    pub jg: Vec<C64>,
    /// `∂r_j/∂l_j` (empty when there are no locals or only the cost was asked for).
    pub jl: Vec<C64>,
    /// The rows of a similarity fit `r_j = a·m_j + b − p_j` over `g = (a, b)` (four
    /// globals), given by their `m_j` instead of in `jg`: row `j` is
    /// [`similarity_row`]`(m_j)`, the same values (empty when `jg` holds the rows).
    pub sim: Vec<C64>,
    /// [`Eval::cost`] as the evaluation summed it ([`RunningCost::sum`]: the same sum in
    /// the same order), if it did.
    pub summed: Option<f64>,
}

/// The Jacobian row `∂r/∂(Re a, Im a, Re b, Im b)` of a residual `a·m + b − p`:
/// `[m, i·m, 1, i]`.
#[inline(always)]
pub(crate) fn similarity_row(m: C64) -> [C64; 4] {
    [
        m,
        C64::new(0.0, 1.0) * m,
        C64::new(1.0, 0.0),
        C64::new(0.0, 1.0),
    ]
}

impl Eval {
    /// `Σ_j |r_j|²`, in point order.
    pub fn cost(&self) -> f64 {
        match self.summed {
            Some(c) if !self.r.is_empty() => c,
            _ => self.r.iter().map(|r| r.norm_sqr()).sum(),
        }
    }

    /// Empty, its vectors' room kept (for the next evaluation into it).
    pub fn clear(&mut self) {
        self.r.clear();
        self.jg.clear();
        self.jl.clear();
        self.sim.clear();
        self.summed = None;
    }
}

/// What [`solve`] asks of one evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Ask {
    /// Also the Jacobian.
    pub jacobian: bool,
    /// A trial step whose cost exceeds this is rejected whatever else it holds: the
    /// evaluation may give up (return `None`) as soon as the cost of the points so far,
    /// `Σ |r_j|²` summed in point order, exceeds it. That partial sum never decreases as
    /// points are added (each term is ≥ 0 and rounding is monotone), so a trial that
    /// gives up would have been rejected anyway, and the iterations are the same, bit for
    /// bit: only the rest of a rejected trial's points go unevaluated. `+∞` for an
    /// evaluation that must be whole.
    pub reject_above: f64,
}

impl Ask {
    /// The whole evaluation, with the Jacobian or without.
    pub const fn whole(jacobian: bool) -> Ask {
        Ask {
            jacobian,
            reject_above: f64::INFINITY,
        }
    }
}

/// Keeps the running cost of an evaluation point by point, in the order of
/// [`Eval::cost`], for [`Ask::reject_above`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct RunningCost {
    sum: f64,
    limit: f64,
}

impl RunningCost {
    pub fn new(ask: Ask) -> RunningCost {
        RunningCost {
            sum: 0.0,
            limit: ask.reject_above,
        }
    }

    /// The cost so far: `Σ |r_j|²` of the points added, in their order (the same value as
    /// [`Eval::cost`] of those residuals, which sums from `−0`: the terms are `≥ +0`, so
    /// the first sum is the same).
    pub fn sum(&self) -> f64 {
        self.sum
    }

    /// Adds a point's residual; `false` once the cost so far exceeds the limit (the trial
    /// is rejected: the evaluation may stop).
    #[inline]
    pub fn add(&mut self, r: C64) -> bool {
        self.sum += r.norm_sqr();
        self.sum.partial_cmp(&self.limit) != Some(std::cmp::Ordering::Greater)
    }
}

/// What [`solve`] found.
#[derive(Clone, Debug)]
pub(crate) struct LmResult {
    pub global: Vec<f64>,
    pub local: Vec<f64>,
    pub iterations: usize,
    /// The evaluation at `(global, local)` (with [`LmOptions::reuse_trial`]; else `None`).
    pub last: Option<Eval>,
    /// The damping the next iteration would start from.
    pub lambda: f64,
    /// The factor the damping grows by at the next rejected trial.
    pub nu: f64,
    /// Stopped by [`LmOptions::max_iterations`] alone (every other stop is final): with
    /// `last`, [`resume_into`] continues it.
    pub capped: bool,
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
    /// Evaluate each trial step with its Jacobian and, when the step is accepted, keep
    /// that evaluation for the next iteration instead of evaluating the same point again.
    /// Only for an `eval` whose residuals do not depend on whether the Jacobian was asked
    /// for (then the iterations are the same, bit for bit, at one evaluation fewer per
    /// accepted step); an `eval` that computes its residuals another way with the
    /// Jacobian (as the refinement's sensitivities do) must leave it off.
    pub reuse_trial: bool,
}

impl LmOptions {
    pub const DEFAULT: LmOptions = LmOptions {
        max_iterations: 100,
        relative_decrease: 1e-12,
        cost_floor: 0.0,
        max_local_step: 20.0,
        reuse_trial: false,
    };
}

#[inline]
fn dot(a: C64, b: C64) -> f64 {
    a.re * b.re + a.im * b.im
}

/// Minimises `Σ |r_j|²` from `(global, local)`. `eval(g, l, ask)` returns the
/// residuals (and the Jacobian when `ask.jacobian`), or `None` where the model is
/// undefined (a step there is rejected) or, for a trial step, once its cost exceeds
/// `ask.reject_above` ([`Ask`]). `local` is empty for a fit without locals; otherwise it has
/// one entry per residual. `None` if the start itself is undefined.
pub(crate) fn solve<F>(
    global: Vec<f64>,
    local: Vec<f64>,
    eval: F,
    options: &LmOptions,
) -> Option<LmResult>
where
    F: FnMut(&[f64], &[f64], Ask) -> Option<Eval>,
{
    solve_from(global, local, None, eval, options)
}

/// [`solve`] given the start's evaluation with its Jacobian, `first` (what
/// `eval(&global, &local, Ask::whole(true))` returns; evaluated when `None`).
pub(crate) fn solve_from<F>(
    global: Vec<f64>,
    local: Vec<f64>,
    first: Option<Eval>,
    mut eval: F,
    options: &LmOptions,
) -> Option<LmResult>
where
    F: FnMut(&[f64], &[f64], Ask) -> Option<Eval>,
{
    let into = |g: &[f64], l: &[f64], ask: Ask, out: &mut Eval| -> Option<()> {
        *out = eval(g, l, ask)?;
        Some(())
    };
    solve_into(global, local, first, into, options)
}

/// [`solve_from`] with an `eval` that writes each evaluation into a buffer it is given
/// (`eval(g, l, ask, out)`: `Some(())` with `out` holding what [`solve`]'s `eval` would
/// return, `None` where that is `None`, `out` then left in any state), so that the
/// evaluations reuse two buffers (the current point's and the trial's) instead of
/// allocating their vectors each time. The same iterations, bit for bit.
pub(crate) fn solve_into<F>(
    global: Vec<f64>,
    local: Vec<f64>,
    first: Option<Eval>,
    mut eval: F,
    options: &LmOptions,
) -> Option<LmResult>
where
    F: FnMut(&[f64], &[f64], Ask, &mut Eval) -> Option<()>,
{
    let e = match first {
        Some(e) => e,
        None => {
            let mut e = Eval::default();
            eval(&global, &local, Ask::whole(true), &mut e)?;
            e
        }
    };
    iterate(global, local, e, (1e-3, 2.0), 0, eval, options)
}

/// Continues a fit that [`solve_into`] (or this) stopped at its iteration cap
/// ([`LmResult::capped`], with its evaluation `last`: [`LmOptions::reuse_trial`]) up to
/// `options.max_iterations` in all, with the same `eval` and otherwise the same options:
/// the same iterations, bit for bit, as one run with the larger cap. An iteration reads
/// only the point, its evaluation, the damping and the count (every buffer is written
/// before it is read), which the result holds. A result not capped is returned as it is:
/// a larger cap stops where it stopped.
pub(crate) fn resume_into<F>(from: LmResult, eval: F, options: &LmOptions) -> Option<LmResult>
where
    F: FnMut(&[f64], &[f64], Ask, &mut Eval) -> Option<()>,
{
    match from {
        LmResult {
            global,
            local,
            iterations,
            last: Some(e),
            lambda,
            nu,
            capped: true,
        } => iterate(global, local, e, (lambda, nu), iterations, eval, options),
        done => Some(done),
    }
}

/// The iterations of [`solve_into`] from the point `(global, local)`, its evaluation `e`,
/// the damping `lambda` and the iterations done so far.
///
/// **Compiled for AVX2 where the processor has it** (checked at run time), as the
/// curve's point lanes are: the iterations (with `eval` where it inlines) in 256-bit
/// registers. The same operations in the same order (never fused: AVX2 does not enable
/// FMA, and no sum is reassociated), so the same values bit for bit.
fn iterate<F>(
    global: Vec<f64>,
    local: Vec<f64>,
    e: Eval,
    damping: (f64, f64),
    iterations: usize,
    eval: F,
    options: &LmOptions,
) -> Option<LmResult>
where
    F: FnMut(&[f64], &[f64], Ask, &mut Eval) -> Option<()>,
{
    #[cfg(target_arch = "x86_64")]
    if crate::has_avx2() {
        // SAFETY: `iterate_avx2` needs AVX2, which the processor was just found to have;
        // it has no other requirement (the safe body compiled for AVX2).
        #[allow(unsafe_code)]
        return unsafe { iterate_avx2(global, local, e, damping, iterations, eval, options) };
    }
    iterate_body(global, local, e, damping, iterations, eval, options)
}

/// [`iterate_body`] compiled for AVX2 (called only where the processor has it).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn iterate_avx2<F>(
    global: Vec<f64>,
    local: Vec<f64>,
    e: Eval,
    damping: (f64, f64),
    iterations: usize,
    eval: F,
    options: &LmOptions,
) -> Option<LmResult>
where
    F: FnMut(&[f64], &[f64], Ask, &mut Eval) -> Option<()>,
{
    iterate_body(global, local, e, damping, iterations, eval, options)
}

/// [`iterate`] itself, inlined into each of its two paths.
#[inline(always)]
fn iterate_body<F>(
    global: Vec<f64>,
    local: Vec<f64>,
    mut e: Eval,
    (mut lambda, mut nu): (f64, f64),
    mut iterations: usize,
    mut eval: F,
    options: &LmOptions,
) -> Option<LmResult>
where
    F: FnMut(&[f64], &[f64], Ask, &mut Eval) -> Option<()>,
{
    let ng = global.len();
    let has_locals = !local.is_empty();
    let (mut g, mut l) = (global, local);
    // The trial's buffer: an accepted trial's evaluation is swapped into `e`.
    let mut trial = Eval::default();
    let mut cost = e.cost();
    // The normal equations in flat row-major buffers, made once: `hgg` (G × G), `grad_g`,
    // and per point `hgl` (n × G), `hll`, `grad_l`; each damping's Schur complement `s`
    // and right-hand side `rhs`. Every entry is summed in the same order as the textbook
    // loops over (point, row, column), so the steps are the same bit for bit.
    let mut hgg = vec![0.0; ng * ng];
    let mut grad_g = vec![0.0; ng];
    let mut hgl: Vec<f64> = Vec::new();
    let mut hll: Vec<f64> = Vec::new();
    let mut grad_l: Vec<f64> = Vec::new();
    let mut damped: Vec<f64> = Vec::new();
    let mut s = vec![0.0; ng * ng];
    let mut rhs = vec![0.0; ng];
    let mut g_new = vec![0.0; ng];
    let mut dg = vec![0.0; ng];
    let mut l_new: Vec<f64> = Vec::new();
    while iterations < options.max_iterations && cost > options.cost_floor {
        iterations += 1;
        let n = e.r.len();
        hgg.fill(0.0);
        grad_g.fill(0.0);
        let nl = if has_locals { n } else { 0 };
        // Every point's entries are written (`point_locals`: assigned, not summed) before
        // they are read, so the buffers are sized, not cleared: after the first iteration
        // (the same points) this is no work.
        hgl.resize(nl * ng, 0.0);
        hll.resize(nl, 0.0);
        grad_l.resize(nl, 0.0);
        let normal = Normal {
            hgg: &mut hgg,
            grad_g: &mut grad_g,
            hgl: &mut hgl,
            hll: &mut hll,
            grad_l: &mut grad_l,
        };
        match ng {
            // A finite cost: every residual finite (the similarity rows' `m` are).
            4 if !e.sim.is_empty() && cost.is_finite() => normal.sum_similarity(&e, has_locals),
            4 if !e.sim.is_empty() => {
                normal.sum_rows::<4>(e.sim.iter().map(|&m| similarity_row(m)), &e, has_locals)
            }
            4 => normal.sum_fixed::<4>(&e, has_locals),
            _ => normal.sum(ng, &e, has_locals),
        }
        let mean_hll = if has_locals {
            hll.iter().sum::<f64>() / n as f64
        } else {
            0.0
        };
        let mut accepted = false;
        // The accepted trial's evaluation is in `trial` (with `reuse_trial`).
        let mut kept = false;
        for _ in 0..12 {
            s.copy_from_slice(&hgg);
            for (r, gg) in rhs.iter_mut().zip(&grad_g) {
                *r = -gg;
            }
            for p in 0..ng {
                s[p * ng + p] += lambda * hgg[p * ng + p].max(1e-300);
            }
            damped.clear();
            damped.extend(
                hll.iter()
                    .map(|&h| h + lambda * h.max(1e-9 * mean_hll).max(1e-300)),
            );
            if has_locals {
                match ng {
                    4 => schur_fixed::<4>(&mut s, &mut rhs, &hgl, &grad_l, &damped),
                    _ => schur(ng, &mut s, &mut rhs, &hgl, &grad_l, &damped),
                }
            }
            if !solve_small(&s, &rhs, &mut dg) {
                lambda *= 10.0;
                continue;
            }
            for ((x, a), b) in g_new.iter_mut().zip(&g).zip(dg.iter()) {
                *x = a + b;
            }
            // Whether the new locals are all finite, where their loop found it.
            let mut locals_finite = None;
            if has_locals {
                let max = options.max_local_step;
                // `l_j − (grad_l_j + h_j·dg)/d_j`, the product summed in order; four globals
                // unrolled (the same sums).
                let local = |j: usize, t: f64| l[j] + (-t / damped[j]).clamp(-max, max);
                if let Ok(d) = <[f64; 4]>::try_from(dg.as_slice()) {
                    // Written in place, every entry (a loop here, not `extend`'s call, so
                    // that it is compiled with the iterations); the point's values zipped
                    // in step (no index, so no bounds test).
                    l_new.resize(n, 0.0);
                    let rows = hgl.chunks_exact(4).zip(grad_l.iter().zip(&damped));
                    let mut finite = true;
                    for ((x, &lj), (row, (&gl, &dj))) in l_new.iter_mut().zip(&l).zip(rows) {
                        let t = gl + row[0] * d[0] + row[1] * d[1] + row[2] * d[2] + row[3] * d[3];
                        *x = lj + (-t / dj).clamp(-max, max);
                        finite &= x.is_finite();
                    }
                    locals_finite = Some(finite);
                } else {
                    l_new.clear();
                    l_new.extend((0..n).map(|j| {
                        let row = &hgl[j * ng..(j + 1) * ng];
                        let mut t = grad_l[j];
                        for p in 0..ng {
                            t += row[p] * dg[p];
                        }
                        local(j, t)
                    }));
                }
            } else {
                l_new.clear();
            }
            let finite = g_new.iter().all(|x| x.is_finite())
                && locals_finite.unwrap_or_else(|| l_new.iter().all(|x| x.is_finite()))
                && dg.iter().all(|x| x.is_finite());
            let evaluated = finite
                && eval(
                    &g_new,
                    &l_new,
                    Ask {
                        jacobian: options.reuse_trial,
                        reject_above: cost,
                    },
                    &mut trial,
                )
                .is_some();
            let new_cost = evaluated.then(|| trial.cost());
            match new_cost {
                Some(c) if c.is_finite() && c <= cost => {
                    let decrease = cost - c;
                    // The decrease the linear model predicts for the step `h = (dg, dl)`:
                    // `−h·grad + λ·hᵀDh` (the model `|r + J·h|²` with `(H + λD)·h = −grad`;
                    // only an accepted step's is needed).
                    let mut predicted = 0.0;
                    for p in 0..ng {
                        predicted += -dg[p] * grad_g[p]
                            + lambda * hgg[p * ng + p].max(1e-300) * dg[p] * dg[p];
                    }
                    if has_locals {
                        // The points' values zipped in step (no index, so no bounds test).
                        let points = l_new
                            .iter()
                            .zip(&l)
                            .zip(grad_l.iter().zip(&damped).zip(&hll));
                        for ((&ln, &lj), ((&gl, &dj), &hj)) in points.take(n) {
                            let dl = ln - lj;
                            predicted += -dl * gl + (dj - hj) * dl * dl;
                        }
                    }
                    std::mem::swap(&mut g, &mut g_new);
                    std::mem::swap(&mut l, &mut l_new);
                    // Nielsen's rule: the damping follows the gain ratio `ρ` (actual over
                    // predicted decrease), falling by at most 3 at `ρ = 1`.
                    let rho = if predicted > 0.0 {
                        decrease / predicted
                    } else {
                        0.0
                    };
                    let t = 2.0 * rho - 1.0;
                    lambda = (lambda * (1.0 - t * t * t).max(1.0 / 3.0)).max(1e-15);
                    nu = 2.0;
                    accepted = true;
                    if decrease <= options.relative_decrease * cost {
                        return finish(
                            g,
                            l,
                            eval,
                            iterations,
                            options.reuse_trial.then_some(trial),
                            (lambda, nu, false),
                        );
                    }
                    // With `reuse_trial`, the residuals and Jacobian at the accepted
                    // point: what `eval(&g, &l, Ask::whole(true))` gives.
                    kept = options.reuse_trial;
                    break;
                }
                _ => {
                    lambda *= nu;
                    nu *= 2.0;
                }
            }
        }
        if !accepted {
            let last = options.reuse_trial.then_some(e);
            return finish(g, l, eval, iterations, last, (lambda, nu, false));
        }
        if kept {
            std::mem::swap(&mut e, &mut trial);
        } else {
            eval(&g, &l, Ask::whole(true), &mut e)?;
        }
        cost = e.cost();
    }
    // The loop's own test stopped it: capped unless the cost reached its floor.
    let capped = cost > options.cost_floor;
    let last = options.reuse_trial.then_some(e);
    finish(g, l, eval, iterations, last, (lambda, nu, capped))
}

/// The normal equations' buffers (see [`solve_from`]), to be summed from an evaluation.
struct Normal<'a> {
    hgg: &'a mut [f64],
    grad_g: &'a mut [f64],
    hgl: &'a mut [f64],
    hll: &'a mut [f64],
    grad_l: &'a mut [f64],
}

impl Normal<'_> {
    /// `hgg = Σ_j row_jᵀ·row_j`, `grad_g = Σ_j row_jᵀ·r_j` (points in order; the upper
    /// triangle computed, then copied down) and per point `hgl`, `hll`, `grad_l`, from
    /// zeroed buffers.
    #[inline(always)]
    fn sum(self, ng: usize, e: &Eval, has_locals: bool) {
        let Normal {
            hgg,
            grad_g,
            hgl,
            hll,
            grad_l,
        } = self;
        for j in 0..e.r.len() {
            let row = &e.jg[j * ng..(j + 1) * ng];
            let rj = e.r[j];
            for p in 0..ng {
                grad_g[p] += dot(row[p], rj);
                let h = &mut hgg[p * ng..(p + 1) * ng];
                for q in p..ng {
                    h[q] += dot(row[p], row[q]);
                }
            }
            if has_locals {
                point_locals(
                    row,
                    e.jl[j],
                    rj,
                    &mut hgl[j * ng..(j + 1) * ng],
                    &mut hll[j],
                    &mut grad_l[j],
                );
            }
        }
        for p in 0..ng {
            for q in 0..p {
                hgg[p * ng + q] = hgg[q * ng + p];
            }
        }
    }

    /// [`Normal::sum`] for `G` globals known at compile time (the untimed fit's four): the
    /// sums held in registers instead of memory, each summed in the same order from the
    /// same zero, so the same bits.
    #[inline(always)]
    fn sum_fixed<const G: usize>(self, e: &Eval, has_locals: bool) {
        let rows =
            e.jg.chunks_exact(G)
                .map(|row| <[C64; G]>::try_from(row).expect("rows of G"));
        self.sum_rows::<G>(rows, e, has_locals);
    }

    /// [`Normal::sum_fixed`] with the rows given one by one (from `jg`, or made from
    /// `sim` in registers: the same values, so the same sums).
    #[inline(always)]
    fn sum_rows<const G: usize>(
        self,
        rows: impl Iterator<Item = [C64; G]>,
        e: &Eval,
        has_locals: bool,
    ) {
        let Normal {
            hgg,
            grad_g,
            hgl,
            hll,
            grad_l,
        } = self;
        let mut m = [[0.0; G]; G];
        let mut gr = [0.0; G];
        let mut points = 0;
        for (j, (row, &rj)) in rows.zip(&e.r).enumerate() {
            points += 1;
            let row = &row;
            for p in 0..G {
                gr[p] += dot(row[p], rj);
                for q in p..G {
                    m[p][q] += dot(row[p], row[q]);
                }
            }
            if has_locals {
                point_locals(
                    row,
                    e.jl[j],
                    rj,
                    &mut hgl[j * G..(j + 1) * G],
                    &mut hll[j],
                    &mut grad_l[j],
                );
            }
        }
        // Every point's locals written (the buffers are not cleared between iterations).
        assert!(!has_locals || points == e.r.len(), "a row per point");
        for p in 0..G {
            for q in 0..G {
                hgg[p * G + q] = if q < p { m[q][p] } else { m[p][q] };
            }
            grad_g[p] = gr[p];
        }
    }

    /// [`Normal::sum_rows`] of the similarity rows `[m, i·m, 1, i]` ([`similarity_row`]) of
    /// `e.sim`, the same values bit for bit when every `m_j` and residual is finite, with
    /// the rows' constant entries summed as what they are. Each product with a row entry
    /// `1 = (1, 0)` or `i = (0, 1)` is a component of the other factor plus a zero (`1·x =
    /// x` exactly; `0·y` is a zero for a finite `y`), and `i·m = (0·m.re − m.im, 0·m.im +
    /// m.re)` is `(−m.im, m.re)` but for the signs of zeros; a zero's sign changes neither
    /// a sum with a nonzero term nor a sum that starts from `+0` (the accumulators never
    /// become `−0`: in round to nearest, `x + y = −0` only when both are `−0`). So, points
    /// in order from `+0`:
    ///
    /// - `hgg[0][0] = Σ |m|²`, and `hgg[1][1]` the same terms (`(−m.im)² + m.re²` is
    ///   `m.re² + m.im²`: a sum of two terms commutes);
    /// - `hgg[0][1] = Σ m·(i·m)` (each term `±0` unless it overflows), kept as a sum;
    /// - `hgg[0][2] = hgg[1][3] = Σ m.re`, `hgg[0][3] = Σ m.im`, and `hgg[1][2] = Σ −m.im`,
    ///   which is `0 − Σ m.im` (rounding to nearest is symmetric; `0 −` makes a zero `+0`);
    /// - `hgg[2][2] = hgg[3][3] = Σ 1 = n`, `hgg[2][3] = +0`;
    /// - `grad_g = (Σ m·r, Σ (i·m)·r, Σ r.re, Σ r.im)`.
    ///
    /// The per-point entries (`hgl`, stored, not summed) are made from the rows as
    /// [`Normal::sum_rows`] makes them. Tested against it (`similarity_sums_by_structure`).
    #[inline(always)]
    fn sum_similarity(self, e: &Eval, has_locals: bool) {
        let Normal {
            hgg,
            grad_g,
            hgl,
            hll,
            grad_l,
        } = self;
        let (mut mm, mut mim, mut sre, mut sim) = (0.0, 0.0, 0.0, 0.0);
        let mut gr = [0.0; 4];
        let mut points = 0;
        let mut add = |m: C64, rj: C64| {
            points += 1;
            let im = C64::new(-m.im, m.re);
            mm += dot(m, m);
            mim += dot(m, im);
            sre += m.re;
            sim += m.im;
            gr[0] += dot(m, rj);
            gr[1] += dot(im, rj);
            gr[2] += rj.re;
            gr[3] += rj.im;
        };
        if has_locals {
            // Each point's own entries zipped in step with it (no index, so no bounds test).
            let own = hgl
                .chunks_exact_mut(4)
                .zip(hll.iter_mut().zip(grad_l.iter_mut()));
            for (((&m, &rj), &jl), (h, (hl, gl))) in e.sim.iter().zip(&e.r).zip(&e.jl).zip(own) {
                add(m, rj);
                point_locals(&similarity_row(m), jl, rj, h, hl, gl);
            }
        } else {
            for (&m, &rj) in e.sim.iter().zip(&e.r) {
                add(m, rj);
            }
        }
        assert!(!has_locals || points == e.r.len(), "a row per point");
        // `Σ 1` over the points: exact (a count far below 2⁵³).
        let ones = points as f64;
        let up = [
            [mm, mim, sre, sim],
            [0.0, mm, 0.0 - sim, sre],
            [0.0, 0.0, ones, 0.0],
            [0.0, 0.0, 0.0, ones],
        ];
        for p in 0..4 {
            for q in 0..4 {
                hgg[p * 4 + q] = if q < p { up[q][p] } else { up[p][q] };
            }
            grad_g[p] = gr[p];
        }
    }
}

/// Point `j`'s entries of the normal equations that involve its local: `h = rowᵀ·jl`
/// (row `j` of `hgl`), `hll = |jl|²` and `grad_l = jl·r_j` (its entries of those).
#[inline(always)]
fn point_locals(row: &[C64], jl: C64, rj: C64, h: &mut [f64], hll: &mut f64, grad_l: &mut f64) {
    for (h, &x) in h.iter_mut().zip(row) {
        *h = dot(x, jl);
    }
    *hll = jl.norm_sqr();
    *grad_l = dot(jl, rj);
}

/// Solves `s·x = rhs` (`s` row-major, symmetric) into `x`: by Cholesky, or by LU where
/// Cholesky fails; `false` if neither gives a solution. Four unknowns (the untimed fit's
/// globals) on the stack, others on the heap: nalgebra runs the same generic algorithm
/// on either, so the same bits (tested).
#[inline(always)]
fn solve_small(s: &[f64], rhs: &[f64], x: &mut [f64]) -> bool {
    if rhs.len() == 4 {
        let sm = Matrix4::<f64>::from_row_slice(s);
        let rv = Vector4::<f64>::from_column_slice(rhs);
        let v = sm
            .cholesky()
            .map(|c| c.solve(&rv))
            .or_else(|| sm.lu().solve(&rv));
        return put(x, v.as_ref().map(|v| v.iter()));
    }
    solve_dynamic(s, rhs, x)
}

/// Copies a solution into `x`; `false` if there is none.
fn put<'a>(x: &mut [f64], v: Option<impl IntoIterator<Item = &'a f64>>) -> bool {
    let Some(v) = v else { return false };
    for (x, v) in x.iter_mut().zip(v) {
        *x = *v;
    }
    true
}

/// [`solve_small`] on the heap, for any size.
fn solve_dynamic(s: &[f64], rhs: &[f64], x: &mut [f64]) -> bool {
    let n = rhs.len();
    let sm = DMatrix::<f64>::from_row_slice(n, n, s);
    let rv = DVector::<f64>::from_column_slice(rhs);
    let v = sm
        .clone()
        .cholesky()
        .map(|c| c.solve(&rv))
        .or_else(|| sm.lu().solve(&rv));
    put(x, v.as_ref().map(|v| v.iter()))
}

/// Eliminates the locals: `s −= Σ_j h_j·h_jᵀ/d_j` and `rhs += Σ_j h_j·g_j/d_j` (`h_j` row
/// `j` of `hgl`, `g_j = grad_l[j]`, `d_j = damped[j]`), points in order. `s` is symmetric
/// and stays so: only its upper triangle is computed (`h_p·h_q` and `h_q·h_p` are the same
/// product), then copied down.
#[inline(always)]
fn schur(ng: usize, s: &mut [f64], rhs: &mut [f64], hgl: &[f64], grad_l: &[f64], damped: &[f64]) {
    for (j, row) in hgl.chunks_exact(ng).enumerate() {
        let inv = 1.0 / damped[j];
        let gl = grad_l[j];
        for p in 0..ng {
            rhs[p] += row[p] * gl * inv;
            let rp = row[p];
            let sp = &mut s[p * ng..(p + 1) * ng];
            for q in p..ng {
                sp[q] -= rp * row[q] * inv;
            }
        }
    }
    for p in 0..ng {
        for q in 0..p {
            s[p * ng + q] = s[q * ng + p];
        }
    }
}

/// [`schur`] for `G` globals known at compile time (the untimed fit's four), held in
/// registers: the same sums in the same order.
#[inline(always)]
fn schur_fixed<const G: usize>(
    s: &mut [f64],
    rhs: &mut [f64],
    hgl: &[f64],
    grad_l: &[f64],
    damped: &[f64],
) {
    let mut m = [[0.0; G]; G];
    let mut r = [0.0; G];
    for p in 0..G {
        m[p].copy_from_slice(&s[p * G..(p + 1) * G]);
        r[p] = rhs[p];
    }
    // The points' values zipped in step (no index, so no bounds test).
    for (row, (&gl, &dj)) in hgl.chunks_exact(G).zip(grad_l.iter().zip(damped)) {
        let row: &[f64; G] = row.try_into().expect("rows of G");
        let inv = 1.0 / dj;
        for p in 0..G {
            r[p] += row[p] * gl * inv;
            for q in p..G {
                m[p][q] -= row[p] * row[q] * inv;
            }
        }
    }
    for p in 0..G {
        for q in 0..G {
            s[p * G + q] = if q < p { m[q][p] } else { m[p][q] };
        }
        rhs[p] = r[p];
    }
}

/// The result at `(g, l)`. Every exit of [`solve`] stands on a point that was evaluated
/// (the start, or an accepted step): given that evaluation, `last` (a pure `eval`,
/// [`LmOptions::reuse_trial`]), it is not evaluated again; otherwise it is, as a last check
/// that the model is defined there.
fn finish<F>(
    g: Vec<f64>,
    l: Vec<f64>,
    mut eval: F,
    iterations: usize,
    last: Option<Eval>,
    (lambda, nu, capped): (f64, f64, bool),
) -> Option<LmResult>
where
    F: FnMut(&[f64], &[f64], Ask, &mut Eval) -> Option<()>,
{
    if last.is_none() {
        eval(&g, &l, Ask::whole(false), &mut Eval::default())?;
    }
    Some(LmResult {
        global: g,
        local: l,
        iterations,
        last,
        lambda,
        nu,
        capped,
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
        let eval = |g: &[f64], l: &[f64], ask: Ask| {
            let c = C64::new(g[0], g[1]);
            let mut e = Eval::default();
            for (j, p) in pts.iter().enumerate() {
                let u = super::super::geom::cis(l[j]);
                e.r.push(c + u * g[2] - p);
                if ask.jacobian {
                    e.jg.extend([C64::new(1.0, 0.0), C64::new(0.0, 1.0), u]);
                    e.jl.push(C64::new(0.0, 1.0) * u * g[2]);
                }
            }
            Some(e)
        };
        let start_l: Vec<f64> = phis.iter().map(|p| p + 0.2).collect();
        let res = solve(
            vec![0.5, -1.0, 2.0],
            start_l.clone(),
            eval,
            &LmOptions::DEFAULT,
        )
        .unwrap();
        // Keeping the accepted trial's evaluation (a pure `eval`) takes the same steps,
        // bit for bit, at fewer evaluations.
        let count = std::cell::Cell::new(0usize);
        let counted = |g: &[f64], l: &[f64], ask: Ask| {
            count.set(count.get() + 1);
            eval(g, l, ask)
        };
        let reused = LmOptions {
            reuse_trial: true,
            ..LmOptions::DEFAULT
        };
        let again = solve(vec![0.5, -1.0, 2.0], start_l.clone(), counted, &reused).unwrap();
        let with_reuse = count.replace(0);
        solve(vec![0.5, -1.0, 2.0], start_l, counted, &LmOptions::DEFAULT).unwrap();
        let without = count.get();
        assert_eq!((&again.global, &again.local), (&res.global, &res.local));
        assert_eq!(again.iterations, res.iterations);
        assert!(
            with_reuse + res.iterations <= without,
            "{with_reuse} {without} {}",
            res.iterations
        );
        let c = C64::new(res.global[0], res.global[1]);
        let cost: f64 = pts
            .iter()
            .zip(&res.local)
            .map(|(p, &l)| (c + super::super::geom::cis(l) * res.global[2] - p).norm_sqr())
            .sum();
        assert!(cost < 1e-24, "{res:?}");
        assert!((res.global[2] - r0).abs() < 1e-12);
    }

    /// The normal equations of a similarity fit summed from `sim` (rows made in registers)
    /// are those the generic loops sum from the rows `[m, i·m, 1, i]` stored in `jg` (as
    /// the untimed fit stored them before), bit for bit.
    #[test]
    fn similarity_rows_sum_as_stored_rows() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for case in 0..200 {
            let n = 1 + case % 70;
            let mut stored = Eval::default();
            let mut given = Eval::default();
            for j in 0..n {
                // Some exact zeros among the values, as in fits that start on the curve.
                let zero = |x: f64| if (case + j) % 7 == 0 { 0.0 } else { x };
                let m = C64::new(zero(next()) * 10.0, next() * 10.0);
                let r = C64::new(next(), zero(next()));
                let jl = C64::new(next() * 3.0, zero(next()) * 3.0);
                stored.r.push(r);
                stored.jl.push(jl);
                stored.jg.extend_from_slice(&[
                    m,
                    C64::new(0.0, 1.0) * m,
                    C64::new(1.0, 0.0),
                    C64::new(0.0, 1.0),
                ]);
                given.r.push(r);
                given.jl.push(jl);
                given.sim.push(m);
            }
            let sums = |e: &Eval| {
                let (mut hgg, mut grad_g) = (vec![0.0; 16], vec![0.0; 4]);
                let (mut hgl, mut hll, mut grad_l) = (vec![0.0; 4 * n], vec![0.0; n], vec![0.0; n]);
                let normal = Normal {
                    hgg: &mut hgg,
                    grad_g: &mut grad_g,
                    hgl: &mut hgl,
                    hll: &mut hll,
                    grad_l: &mut grad_l,
                };
                if e.sim.is_empty() {
                    normal.sum(4, e, true);
                } else {
                    normal.sum_rows::<4>(e.sim.iter().map(|&m| similarity_row(m)), e, true);
                }
                [hgg, grad_g, hgl, hll, grad_l]
                    .iter()
                    .flatten()
                    .map(|x| x.to_bits())
                    .collect::<Vec<u64>>()
            };
            assert_eq!(sums(&given), sums(&stored), "case {case}");
        }
    }

    /// The similarity rows' sums by their structure (`Normal::sum_similarity`) are those
    /// of the rows made in registers, bit for bit: values of every sign and size, exact
    /// zeros of either sign among `m`, the residuals and the angles' derivatives, and
    /// points with `m = 0`.
    #[test]
    fn similarity_sums_by_structure() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for case in 0..400 {
            let n = 1 + case % 70;
            let mut e = Eval::default();
            for _ in 0..n {
                let mut value = || {
                    let bits = next();
                    let x = (bits >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
                    match bits % 11 {
                        0 => 0.0,
                        1 => -0.0,
                        2 => x * 1e6,
                        3 => x * 1e-6,
                        _ => x * 10.0,
                    }
                };
                let m = C64::new(value(), value());
                let r = C64::new(value(), value());
                let jl = C64::new(value(), value());
                e.sim.push(m);
                e.r.push(r);
                e.jl.push(jl);
            }
            for has_locals in [true, false] {
                let sums = |structure: bool| {
                    let (mut hgg, mut grad_g) = (vec![0.0; 16], vec![0.0; 4]);
                    let (mut hgl, mut hll, mut grad_l) =
                        (vec![0.0; 4 * n], vec![0.0; n], vec![0.0; n]);
                    let normal = Normal {
                        hgg: &mut hgg,
                        grad_g: &mut grad_g,
                        hgl: &mut hgl,
                        hll: &mut hll,
                        grad_l: &mut grad_l,
                    };
                    if structure {
                        normal.sum_similarity(&e, has_locals);
                    } else {
                        let rows = e.sim.iter().map(|&m| similarity_row(m));
                        normal.sum_rows::<4>(rows, &e, has_locals);
                    }
                    [hgg, grad_g, hgl, hll, grad_l]
                        .iter()
                        .flatten()
                        .map(|x| x.to_bits())
                        .collect::<Vec<u64>>()
                };
                assert_eq!(sums(true), sums(false), "case {case}");
            }
        }
    }

    /// The 4 × 4 solve on the stack is the heap one, bit for bit: positive definite
    /// systems (Cholesky), indefinite ones (Cholesky fails, LU solves) and singular ones
    /// (neither).
    #[test]
    fn small_solve_on_the_stack_is_the_heap_solve() {
        let mut state = 0x853c_49e6_748f_ea9bu64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut failed = 0;
        for case in 0..3000 {
            let a: Vec<f64> = (0..16).map(|_| next()).collect();
            let mut s = vec![0.0; 16];
            for p in 0..4 {
                for q in 0..4 {
                    s[p * 4 + q] = match case % 3 {
                        // AᵀA + small diagonal: positive definite.
                        0 => (0..4).map(|k| a[k * 4 + p] * a[k * 4 + q]).sum::<f64>(),
                        // Symmetric, usually indefinite.
                        1 => a[p * 4 + q] + a[q * 4 + p],
                        // Rank one: singular.
                        _ => a[p] * a[q],
                    };
                }
            }
            let rhs: Vec<f64> = (0..4).map(|_| next()).collect();
            let (mut x, mut y) = (vec![7.0; 4], vec![7.0; 4]);
            let (ok_x, ok_y) = (
                solve_small(&s, &rhs, &mut x),
                solve_dynamic(&s, &rhs, &mut y),
            );
            assert_eq!(ok_x, ok_y, "case {case}");
            failed += usize::from(!ok_x);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&x), bits(&y), "case {case}");
        }
        assert!(failed > 0, "no singular system was refused");
    }

    /// An evaluation that gives up on a trial once its running cost exceeds
    /// [`Ask::reject_above`] leaves every iteration the same, bit for bit (the same
    /// result, iterations and last evaluation), and evaluates fewer points: here a
    /// far start, where many trial steps are rejected.
    #[test]
    fn giving_up_on_rejected_trials_changes_nothing() {
        let (c0, r0) = (C64::new(1.0, -2.0), 3.0);
        let phis: Vec<f64> = (0..30).map(|k| 0.1 + 0.2 * k as f64).collect();
        let pts: Vec<C64> = phis
            .iter()
            .map(|&p| c0 + super::super::geom::cis(p) * r0 + C64::new(0.01 * (p * 7.0).sin(), 0.0))
            .collect();
        let points = std::cell::Cell::new(0usize);
        let gave_up = std::cell::Cell::new(0usize);
        let eval = |bounded: bool| {
            let (pts, points, gave_up) = (&pts, &points, &gave_up);
            move |g: &[f64], l: &[f64], ask: Ask| {
                let c = C64::new(g[0], g[1]);
                let mut e = Eval::default();
                let mut cost = RunningCost::new(if bounded {
                    ask
                } else {
                    Ask::whole(ask.jacobian)
                });
                for (j, p) in pts.iter().enumerate() {
                    points.set(points.get() + 1);
                    let u = super::super::geom::cis(l[j]);
                    let r = c + u * g[2] - p;
                    if !cost.add(r) {
                        gave_up.set(gave_up.get() + 1);
                        return None;
                    }
                    e.r.push(r);
                    if ask.jacobian {
                        e.jg.extend([C64::new(1.0, 0.0), C64::new(0.0, 1.0), u]);
                        e.jl.push(C64::new(0.0, 1.0) * u * g[2]);
                    }
                }
                Some(e)
            }
        };
        let options = LmOptions {
            reuse_trial: true,
            ..LmOptions::DEFAULT
        };
        let start_l: Vec<f64> = phis.iter().map(|p| p - 1.5).collect();
        let whole = solve(vec![-2.0, 1.0, 6.0], start_l.clone(), eval(false), &options).unwrap();
        let (whole_points, whole_gave_up) = (points.replace(0), gave_up.replace(0));
        let bounded = solve(vec![-2.0, 1.0, 6.0], start_l, eval(true), &options).unwrap();
        assert_eq!(whole_gave_up, 0);
        assert!(
            gave_up.get() > 0,
            "no trial was rejected: the test tests nothing"
        );
        assert!(
            points.get() < whole_points,
            "{} {whole_points} {} {}",
            points.get(),
            gave_up.get(),
            whole.iterations
        );
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&bounded.global), bits(&whole.global));
        assert_eq!(bits(&bounded.local), bits(&whole.local));
        assert_eq!(bounded.iterations, whole.iterations);
        let last = |r: &LmResult| r.last.as_ref().unwrap().r.clone();
        assert_eq!(last(&bounded), last(&whole));
        assert!(whole.iterations > 3);
    }
}
