//! The exact fit of a target to one coupler curve: the similarity transform (with or
//! without reflection) and the crank angle at which the curve passes each target point,
//! by Levenberg–Marquardt on the closed-form kinematics, from a global initial guess
//! (cyclic correlation for closed targets, a window scan for open ones, a phase scan for
//! timed ones).
//!
//! The model: target point `p_k ≈ a·M̃(θ_k) + b` with `a` complex (scale and rotation),
//! `b` complex (translation), and `M̃ = M` or, for a reflected match, `M̃ = conj(M)`
//! (the curve mirrored in the atlas frame's x-axis, the ground line). Untimed: every `θ_k`
//! is free, so at the optimum each residual is perpendicular to the curve and `|r_k|` is
//! the distance from `p_k` to the curve near its match. Timed: `θ_k = θ₀ + σ·(t_k − t₀)`
//! or `θ₀ + ω·k`.

use crate::geom::{C64, abs, fit_similarity, mean};
use crate::kin::{CouplerCurve, CurveLanes, PointAt};
use crate::lm::{Ask, Eval, LmOptions, LmResult, RunningCost, resume_into, solve_into};
use crate::target::{Target, Timing};
use crate::traced::Traced;
use coupler_kinematics::POINT_LANES;
use rayon::prelude::*;

/// How a target's points sit on a curve: what the fit found.
#[derive(Clone, Debug, PartialEq)]
pub struct CurveFit {
    /// The curve is reflected (the target matches the mirror image; see
    /// [`super::Placement`] for the four-bar that traces it unreflected).
    pub mirrored: bool,
    /// `a` of `p ≈ a·M̃(θ) + b`: `|a|` is the scale (user units per crank length), `arg a`
    /// the rotation.
    pub a: [f64; 2],
    /// `b`: where the crank pivot O2 lands in the user's frame.
    pub b: [f64; 2],
    /// The crank angle (degrees, atlas frame, unwrapped so consecutive points differ by
    /// less than a turn) at which the curve passes each target point.
    pub theta_deg: Vec<f64>,
    /// Root-mean-square distance from the target points to their matched curve points,
    /// user units.
    pub rms: f64,
    /// Largest such distance, user units.
    pub max: f64,
    /// For a timed target, the rate `s` of `θ_k = θ_0 + s·o_k`, where `o_k = t_k − t_0`
    /// for angles (so `s = ±1`, the sense the crank turns) and `o_k = k` for equal steps
    /// (so `s` is the crank step between points, degrees, signed); `None` when untimed.
    pub timing_rate: Option<f64>,
}

/// Settings of the exact fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Allow reflected matches.
    pub allow_mirror: bool,
    /// Crank samples of the dense trace used by the initial scans.
    pub trace_samples: usize,
    /// Iteration cap of Levenberg–Marquardt.
    pub max_iterations: usize,
}

impl FitOptions {
    /// Reflection allowed, 720 samples (0.5°), 100 iterations.
    pub const DEFAULT: FitOptions = FitOptions {
        allow_mirror: true,
        trace_samples: 720,
        max_iterations: 100,
    };
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions::DEFAULT
    }
}

/// A starting point: reflection and one crank angle per target point.
#[derive(Clone, Debug)]
pub(crate) struct Start {
    pub mirrored: bool,
    pub theta: Vec<f64>,
    /// The scan's normalised misfit (lower is better), for ordering starts.
    pub score: f64,
}

#[inline]
fn tilde(mirrored: bool, z: C64) -> C64 {
    if mirrored { z.conj() } else { z }
}

/// Arc-length fraction of each point along the target polyline (0 at the first point;
/// for a closed target the loop's length is 1, for an open one the path's).
fn arc_fractions(p: &[C64], closed: bool) -> Vec<f64> {
    let cum = super::geom::cumulative_length(p, closed);
    let total = *cum.last().unwrap_or(&1.0);
    cum[..p.len()].iter().map(|c| c / total).collect()
}

/// Centres a vector and scales it to unit norm; `None` if it is a single point.
fn unit(mut w: Vec<C64>) -> Option<Vec<C64>> {
    let m = mean(&w);
    let mut n2 = 0.0;
    for z in &mut w {
        *z -= m;
        n2 += z.norm_sqr();
    }
    if n2 <= 0.0 {
        return None;
    }
    let s = 1.0 / n2.sqrt();
    for z in &mut w {
        *z *= s;
    }
    Some(w)
}

/// The target variants the scans try: (reversed, mirrored), each resampled by `resample`.
fn variants(allow_mirror: bool) -> Vec<(bool, bool)> {
    let mut v = vec![(false, false), (true, false)];
    if allow_mirror {
        v.extend([(false, true), (true, true)]);
    }
    v
}

/// The resampled target `t` in each variant the scans try ([`variants`]), centred and
/// scaled to unit norm, with its (reversed, mirrored) flags; a reversed one is turned so
/// that its first point stays first when `keep_first`. Variants that cannot be scaled
/// (a single point) are left out.
fn target_variants(t: &[C64], allow_mirror: bool, keep_first: bool) -> Vec<(bool, bool, Vec<C64>)> {
    variants(allow_mirror)
        .into_iter()
        .filter_map(|(rev, mir)| {
            let mut v: Vec<C64> = t.iter().map(|&z| tilde(mir, z)).collect();
            if rev {
                v.reverse();
                if keep_first {
                    v.rotate_right(1);
                }
            }
            unit(v).map(|v| (rev, mir, v))
        })
        .collect()
}

/// Closed target: cyclic correlation of the arc-length resampled target against the
/// resampled curve, every shift and every variant; the best shift per variant becomes a
/// start.
pub(crate) fn scan_closed(p: &[C64], traced: &Traced, allow_mirror: bool) -> Vec<Start> {
    const M: usize = 128;
    let Some(t) = super::geom::resample(p, true, M) else {
        return Vec::new();
    };
    let Some(c) = unit(traced.resample_closed(M)) else {
        return Vec::new();
    };
    let tau = arc_fractions(p, true);
    let len = traced.length();
    // Reversed closed targets keep their first point first.
    let vars = target_variants(&t, allow_mirror, true);
    // The curve twice round, so that every shift is one slice.
    let cc: Vec<C64> = c.iter().chain(&c).map(|z| z.conj()).collect();
    let best_shifts = match vars.as_slice() {
        [v0, v1, v2, v3] => best_shifts::<4>(&cc, [&v0.2, &v1.2, &v2.2, &v3.2]).to_vec(),
        [v0, v1] => best_shifts::<2>(&cc, [&v0.2, &v1.2]).to_vec(),
        vs => vs
            .iter()
            .map(|v| best_shifts::<1>(&cc, [&v.2])[0])
            .collect(),
    };
    let mut starts = Vec::new();
    for ((rev, mir, _), best) in vars.into_iter().zip(best_shifts) {
        let s0 = len * best.1 as f64 / M as f64;
        let theta = tau
            .iter()
            .map(|&f| {
                let along = if rev { -f } else { f };
                traced.theta_at(s0 + along * len)
            })
            .collect();
        starts.push(Start {
            mirrored: mir,
            theta: unwrap_sequence(theta, traced.period),
            score: 1.0 - best.0,
        });
    }
    starts.sort_by(|a, b| a.score.total_cmp(&b.score));
    starts
}

/// For each of `L` resampled targets `v`, the cyclic shift `k` of the curve (`cc`: its
/// `M` conjugated points twice round) with the largest `|Σ_j conj(c[j + k])·v[j]|²`, and
/// that value (the first such `k` on a tie). The `L` sums run side by side (one pass over
/// the curve for all of them); each is summed over `j` in order, as one target's alone.
/// The real and imaginary parts are held apart (the targets' lane by lane, so the `L` sums
/// run in vector registers, and no bounds are checked in the loop); each term and sum is
/// the complex product's and sum's, operation for operation (`Complex`'s `*` and `+=`),
/// so the same bits as summing `C64`s (tested against that).
#[inline]
fn best_shifts<const L: usize>(cc: &[C64], vs: [&[C64]; L]) -> [(f64, usize); L] {
    let m = cc.len() / 2;
    let vs = vs.map(|v| &v[..m]);
    // Target point `j` of every variant: (re of each, im of each).
    let vt: Vec<([f64; L], [f64; L])> = (0..m)
        .map(|j| {
            (
                std::array::from_fn(|l| vs[l][j].re),
                std::array::from_fn(|l| vs[l][j].im),
            )
        })
        .collect();
    let (cr, ci): (Vec<f64>, Vec<f64>) = cc[..2 * m].iter().map(|z| (z.re, z.im)).unzip();
    let mut best = [(-1.0, 0usize); L];
    for k in 0..m {
        let (wr, wi) = (&cr[k..k + m], &ci[k..k + m]);
        let mut sr = [0.0f64; L];
        let mut si = [0.0f64; L];
        for ((&a, &b), (xr, xi)) in wr.iter().zip(wi).zip(&vt) {
            for l in 0..L {
                // `(a + ib)·(xr + i·xi)`: `Complex`'s product, then its `+=`.
                sr[l] += a * xr[l] - b * xi[l];
                si[l] += a * xi[l] + b * xr[l];
            }
        }
        for l in 0..L {
            let q = C64::new(sr[l], si[l]).norm_sqr();
            if q > best[l].0 {
                best[l] = (q, k);
            }
        }
    }
    best
}

/// Open target: scan windows of the curve for the best similarity fit of the resampled
/// target. Windows are placed by their centre `c` and length `f` (fractions of the loop's
/// arc length): lengths on a geometric grid (ratio [`OPEN_LENGTH_RATIO`]) from 2 % to the
/// whole loop, centres every `f/3` ([`OPEN_CENTRES`]). Along each length's centres, every local minimum of
/// the misfit is refined by a parabola through it and its neighbours; the best distinct
/// ones (per reflection and direction) are polished by a pattern search on `(c, ln f)`.
///
/// **Compiled for AVX2 where the processor has it** (checked at run time), as the
/// curve's point lanes are: the same operations in the same order (never fused), so the
/// same starts bit for bit.
pub(crate) fn scan_open(p: &[C64], traced: &Traced, allow_mirror: bool) -> Vec<Start> {
    #[cfg(target_arch = "x86_64")]
    if crate::has_avx2() {
        // SAFETY: `scan_open_avx2` needs AVX2, which the processor was just found to have;
        // it has no other requirement (the safe body compiled for AVX2).
        #[allow(unsafe_code)]
        return unsafe { scan_open_avx2(p, traced, allow_mirror) };
    }
    scan_open_body(p, traced, allow_mirror)
}

/// [`scan_open_body`] compiled for AVX2 (called only where the processor has it).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn scan_open_avx2(p: &[C64], traced: &Traced, allow_mirror: bool) -> Vec<Start> {
    scan_open_body(p, traced, allow_mirror)
}

/// Points of the open scan's windows and of its resampled target.
const OPEN_SCAN_POINTS: usize = 24;

/// A target variant's points as the two lane pairs of the open scan's misfit (see
/// [`scan_open_body`]).
type ScanLanes = ([[f64; 2]; OPEN_SCAN_POINTS], [[f64; 2]; OPEN_SCAN_POINTS]);

/// [`scan_open`] itself, inlined into each of its two paths (its closures with it).
#[inline(always)]
fn scan_open_body(p: &[C64], traced: &Traced, allow_mirror: bool) -> Vec<Start> {
    const M: usize = OPEN_SCAN_POINTS;
    const POLISHED: usize = 10;
    const BIG: usize = 512;
    let Some(t) = super::geom::resample(p, false, M) else {
        return Vec::new();
    };
    let len = traced.length();
    // The loop's points, the first repeated at the end: sample `k + 1` of sample `k ≤ 511`
    // is `ring[k + 1]` (the `(k + 1) mod 512`-th), with no remainder and no bounds test.
    let mut ring = [C64::new(0.0, 0.0); BIG + 1];
    for (r, z) in ring.iter_mut().zip(traced.resample_closed(BIG)) {
        *r = z;
    }
    ring[BIG] = ring[0];
    // A window's point offsets from its first point, `f·j/(M − 1)` (the same product and
    // quotient as in the window's sum), made once per length.
    let offsets = {
        #[inline(always)]
        |f: f64| -> [f64; M] { std::array::from_fn(|j| f * j as f64 / (M - 1) as f64) }
    };
    // The window of first point `s0 = c − f/2` (centre `c`, length `f`, its offsets `off`),
    // centred and scaled to unit norm ([`unit`]'s values, bit for bit) into `w`; `false` if
    // it is a single point. A point's position `s ∈ [0, 512]` (or NaN) splits into its
    // sample `k = ⌊s⌋` (at most 511; 0 for NaN: what the unsigned cast gave) and fraction.
    // (`k` as the saturating cast `s as i32` clamped to `0..=511` gave, without the cast:
    // `max` takes 0 for NaN; `+ 0.0` makes a `−0` the cast's `+0`; the whole number
    // `kf < 2⁵²` is the low bits of `kf + 2⁵²`, and the mask tells the compiler `k ≤ 511`.)
    const WHOLE: f64 = 4_503_599_627_370_496.0;
    let window = {
        #[inline(always)]
        |s0: f64, off: &[f64; M], w: &mut [C64; M]| -> bool {
            // A point's sample and fraction from its position `s`.
            let split = |s: f64| -> (usize, f64) {
                let kf = s.max(0.0).min((BIG - 1) as f64).trunc() + 0.0;
                (((kf + WHOLE).to_bits() & (BIG as u64 - 1)) as usize, s - kf)
            };
            // The samples and fractions first, a pass of their own (in vectors): where
            // every `x = s0 + o` lies in (−1, 2), [`frac`]'s cases as selects, its values;
            // else [`frac`] itself.
            let (mut ks, mut us) = ([0usize; M], [0.0f64; M]);
            let mut inside = true;
            for ((k, u), &o) in ks.iter_mut().zip(us.iter_mut()).zip(off) {
                let x = s0 + o;
                inside &= (x > -1.0) & (x < 2.0);
                let r = if x >= 1.0 {
                    x - 1.0
                } else if x < 0.0 {
                    x + 1.0
                } else {
                    x
                };
                (*k, *u) = split(r * BIG as f64);
            }
            if !inside {
                for ((k, u), &o) in ks.iter_mut().zip(us.iter_mut()).zip(off) {
                    (*k, *u) = split(frac(s0 + o) * BIG as f64);
                }
            }
            for ((z, &k), &u) in w.iter_mut().zip(&ks).zip(&us) {
                let (a, b) = (ring[k], ring[k + 1]);
                *z = a + (b - a) * u;
            }
            unit_in_place(w)
        }
    };
    let vars = target_variants(&t, allow_mirror, false);
    // Each variant's points (`M` of them) as the two lane pairs of `conj(w)·v =
    // w.re·[v.re, v.im] + w.im·[v.im, −v.re]`: the complex product's own products and sums
    // (`(−w.im)·v.im` and `w.im·(−v.re)` are exact negations of `w.im·v.im` and
    // `w.im·v.re`), so the misfit is the same, bit for bit, in two lanes side by side.
    type Lanes = ScanLanes;
    let lanes: Vec<Lanes> = vars
        .iter()
        .map(|(_, _, v)| {
            (
                std::array::from_fn(|j| [v[j].re, v[j].im]),
                std::array::from_fn(|j| [v[j].im, -v[j].re]),
            )
        })
        .collect();
    // `1 − |Σ conj(w_j)·v_j|²`, summed in order.
    let score = {
        #[inline(always)]
        |w: &[C64; M], v: &Lanes| -> f64 {
            let mut s = [0.0f64; 2];
            for ((a, b), c) in w.iter().zip(&v.0).zip(&v.1) {
                s[0] += a.re * b[0] + a.im * c[0];
                s[1] += a.re * b[1] + a.im * c[1];
            }
            1.0 - (s[0] * s[0] + s[1] * s[1])
        }
    };
    let score_at = {
        #[inline(always)]
        |c: f64, f: f64, v: &Lanes| -> Option<f64> {
            let mut w = [C64::new(0.0, 0.0); M];
            window(c - 0.5 * f, &offsets(f), &mut w).then(|| score(&w, v))
        }
    };
    // Refined local minima along the centres of each length: (misfit, variant, c, f).
    let mut minima: Vec<(f64, usize, f64, f64)> = Vec::new();
    // One length's windows (`None`: a single point), made in place, and each variant's
    // misfits along them.
    let mut wins: Vec<[C64; M]> = Vec::new();
    let mut whole: Vec<bool> = Vec::new();
    let mut ms: Vec<Vec<f64>> = vec![Vec::new(); lanes.len()];
    // The variants' lanes side by side (two or four variants: four or eight lanes), so
    // that one pass over a window sums every variant's misfit, each in its own lanes.
    let (side2, side4) = match lanes.len() {
        2 => (Some(side_by_side::<4>(&lanes)), None),
        4 => (None, Some(side_by_side::<8>(&lanes))),
        _ => (None, None),
    };
    let mut f: f64 = 0.02;
    while f <= 1.0 + 1e-9 {
        let count = ((OPEN_CENTRES / f).ceil() as usize).clamp(
            (2.0 * OPEN_CENTRES) as usize,
            (32.0 * OPEN_CENTRES) as usize,
        );
        let h = 1.0 / count as f64;
        let off = offsets(f);
        wins.resize(count, [C64::new(0.0, 0.0); M]);
        // (A plain loop: an adapter's closure would be compiled apart, without AVX2.)
        whole.clear();
        for (i, w) in wins.iter_mut().enumerate() {
            whole.push(window(i as f64 * h - 0.5 * f, &off, w));
        }
        if let Some(side) = &side2 {
            side_misfits(&wins, &whole, side, &mut ms);
        } else if let Some(side) = &side4 {
            side_misfits(&wins, &whole, side, &mut ms);
        } else {
            for (m, v) in ms.iter_mut().zip(&lanes) {
                m.clear();
                m.extend(wins.iter().zip(&whole).map(
                    #[inline(always)]
                    |(w, &ok)| {
                        if ok { score(w, v) } else { f64::INFINITY }
                    },
                ));
            }
        }
        for (vi, (v, m)) in lanes.iter().zip(&ms).enumerate() {
            for i in 0..count {
                let (l, r) = (m[(i + count - 1) % count], m[(i + 1) % count]);
                if !(m[i] <= l && m[i] < r && m[i].is_finite()) {
                    continue;
                }
                let curvature = l - 2.0 * m[i] + r;
                let shift = if curvature > 0.0 {
                    (0.5 * (l - r) / curvature).clamp(-0.5, 0.5)
                } else {
                    0.0
                };
                let c = (i as f64 + shift) * h;
                let refined = score_at(c, f, v).unwrap_or(f64::INFINITY);
                let (best, c) = if refined < m[i] {
                    (refined, c)
                } else {
                    (m[i], i as f64 * h)
                };
                minima.push((best, vi, c, f));
            }
        }
        f *= OPEN_LENGTH_RATIO;
    }
    minima.sort_by(|a, b| {
        a.0.total_cmp(&b.0)
            .then(a.1.cmp(&b.1))
            .then(a.2.total_cmp(&b.2))
            .then(a.3.total_cmp(&b.3))
    });
    let mut picked: Vec<(f64, usize, f64, f64)> = Vec::new();
    for &g in &minima {
        if picked.len() >= POLISHED {
            break;
        }
        let distinct = picked.iter().all(|q| {
            q.1 != g.1 || {
                let dc = (q.2 - g.2).rem_euclid(1.0);
                let dc = dc.min(1.0 - dc);
                dc > 0.25 * q.3.min(g.3) || (q.3 / g.3).ln().abs() > 2.5 * OPEN_LENGTH_RATIO.ln()
            }
        });
        if distinct {
            picked.push(g);
        }
    }
    let tau = arc_fractions(p, false);
    let mut out = Vec::new();
    for (m, vi, c, f) in picked {
        let (rev, mir, _) = &vars[vi];
        let v = &lanes[vi];
        let (mut m, mut c, mut f) = (m, c, f);
        // Pattern search on (c, ln f). A trial often lands on a point tried before, bit
        // for bit (a step back after a move: `(c + dc) − dc` is `c` whenever the sum was
        // exact): its misfit, a function of `(c, f)` alone, is taken from the last
        // `RECENT` trials instead of being made again, the same value. A length's offsets
        // are kept while the length stays (the trials along `c`).
        const RECENT: usize = 8;
        let mut recent = [(u64::MAX, u64::MAX, None::<f64>); RECENT];
        let mut next = 0;
        let mut kept = (f.to_bits(), offsets(f));
        let mut dc = f / 12.0;
        let mut dl = OPEN_LENGTH_RATIO.ln() / 2.0;
        for _ in 0..60 {
            let mut moved = false;
            for (a, b) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)] {
                let (c1, f1) = (c + a * dc, f * libm::exp(b * dl));
                if !(f1 > 0.0 && f1 <= 1.0) {
                    continue;
                }
                let key = (c1.to_bits(), f1.to_bits());
                let tried = recent.iter().find(|r| (r.0, r.1) == key).map(|r| r.2);
                let got = tried.unwrap_or_else(
                    #[inline(always)]
                    || {
                        if kept.0 != key.1 {
                            kept = (key.1, offsets(f1));
                        }
                        let mut w = [C64::new(0.0, 0.0); M];
                        let m1 = window(c1 - 0.5 * f1, &kept.1, &mut w).then(|| score(&w, v));
                        recent[next] = (key.0, key.1, m1);
                        next = (next + 1) % RECENT;
                        m1
                    },
                );
                if let Some(m1) = got {
                    if m1 < m {
                        (m, c, f) = (m1, c1, f1);
                        moved = true;
                    }
                }
            }
            if !moved {
                dc /= 2.0;
                dl /= 2.0;
                if dc < OPEN_PATTERN_STOP * f {
                    break;
                }
            }
        }
        let s0 = c - 0.5 * f;
        let theta = tau
            .iter()
            .map(|&x| {
                let along = if *rev { 1.0 - x } else { x };
                traced.theta_at((s0 + along * f) * len)
            })
            .collect();
        out.push(Start {
            mirrored: *mir,
            theta: unwrap_sequence(theta, traced.period),
            score: m,
        });
    }
    out.sort_by(|a, b| a.score.total_cmp(&b.score));
    out
}

/// The open scan's variants' lanes side by side: point `j`'s `(b, c)` with variant
/// `v`'s pair of [`ScanLanes`] at lanes `2v` and `2v + 1` (`W/2` variants).
fn side_by_side<const W: usize>(lanes: &[ScanLanes]) -> [([f64; W], [f64; W]); OPEN_SCAN_POINTS] {
    std::array::from_fn(|j| {
        (
            std::array::from_fn(|k| lanes[k / 2].0[j][k % 2]),
            std::array::from_fn(|k| lanes[k / 2].1[j][k % 2]),
        )
    })
}

/// Each variant's misfit `1 − |Σ conj(w_j)·v_j|²` along one length's windows into `ms`
/// (`+∞` where the window is a single point), the `W/2` variants' sums side by side
/// ([`side_by_side`]): each lane's products and sums are those of the scan's
/// one-variant `score`, in the same order, so the same values bit for bit.
#[inline(always)]
fn side_misfits<const W: usize>(
    wins: &[[C64; OPEN_SCAN_POINTS]],
    whole: &[bool],
    side: &[([f64; W], [f64; W]); OPEN_SCAN_POINTS],
    ms: &mut [Vec<f64>],
) {
    for m in ms.iter_mut() {
        m.clear();
    }
    for (w, &ok) in wins.iter().zip(whole) {
        if !ok {
            for m in ms.iter_mut() {
                m.push(f64::INFINITY);
            }
            continue;
        }
        let mut s = [0.0f64; W];
        for (a, (b, c)) in w.iter().zip(side) {
            for k in 0..W {
                s[k] += a.re * b[k] + a.im * c[k];
            }
        }
        for (v, m) in ms.iter_mut().enumerate() {
            let (x, y) = (s[2 * v], s[2 * v + 1]);
            m.push(1.0 - (x * x + y * y));
        }
    }
}

/// `x.rem_euclid(1.0)` without the floating-point remainder's call for `x` in
/// `(−1, 2)`, where the open scan's window positions lie: there the remainder is `x`,
/// `x − 1` (exact, Sterbenz's lemma, as the remainder is) or `x + 1` (the sum
/// `rem_euclid` itself rounds), so the same bits.
#[inline(always)]
fn frac(x: f64) -> f64 {
    if (0.0..1.0).contains(&x) {
        x
    } else if (1.0..2.0).contains(&x) {
        x - 1.0
    } else if x > -1.0 && x < 0.0 {
        x + 1.0
    } else {
        x.rem_euclid(1.0)
    }
}

/// [`unit`] in place, on a fixed number of points: the same operations in the same order
/// (the mean summed in order, then the centred norm), so the same bits; `false` (and `w`
/// left centred) if it is a single point.
#[inline(always)]
fn unit_in_place<const N: usize>(w: &mut [C64; N]) -> bool {
    let m = mean(w);
    let mut n2 = 0.0;
    for z in w.iter_mut() {
        *z -= m;
        n2 += z.norm_sqr();
    }
    if n2 <= 0.0 {
        return false;
    }
    let s = 1.0 / n2.sqrt();
    for z in w.iter_mut() {
        *z *= s;
    }
    true
}

/// Centres of the open scan's windows per window length along the loop (every
/// `f/OPEN_CENTRES` for windows of length `f`, from `2·OPEN_CENTRES` to
/// `32·OPEN_CENTRES` of them a length). Every third of the length: the local minima
/// are refined by a parabola and the best polished by the pattern search, and the fits
/// that start from them refine them again (every sixth before: twice the windows;
/// every half length missed a reflected exact window; `docs/benchmarks.md`, "Open
/// queries: the exact stage's work cut").
const OPEN_CENTRES: f64 = 3.0;

/// The open scan's pattern search stops when its step along the loop falls below this
/// share of the window's length (10⁻⁵ before: the fits refine the window anyway; 10⁻²
/// with centres every third of the length left a reflected exact window's fit at
/// 0.047 %, test `mirror_finds_the_reflected_exact_open_source`).
const OPEN_PATTERN_STOP: f64 = 1e-3;

/// Ratio between consecutive window lengths of the open scan.
const OPEN_LENGTH_RATIO: f64 = 1.2;

/// Makes consecutive angles differ by less than half the mechanism's period (adding whole
/// periods: 360° for a four-bar, 720° for a geared five-bar of ratio p/2, where θ and
/// θ + 360° are different points of the curve).
fn unwrap_sequence(mut t: Vec<f64>, period: f64) -> Vec<f64> {
    for k in 1..t.len() {
        let d = t[k] - t[k - 1];
        t[k] -= period * (d / period).round();
    }
    t
}

/// The untimed fit's residuals `a·M̃(θ_k) + b − p_k` into `e` and, with the Jacobian
/// asked, their derivatives (the similarity rows by `m`, `lm::similarity_row`, and the
/// angles' `a·dM̃/dθ`), from the curve's points [`POINT_LANES`] at a time: `group(k)`
/// gives points `k..k + POINT_LANES` (those past the end unread), asked in order, so a
/// trial rejected part-way ([`Ask::reject_above`]) evaluates no more groups. `None` where
/// a point is `None` or the trial is given up (`e` then holds part of it).
#[inline(always)]
fn untimed_residuals(
    p: &[C64],
    mir: bool,
    a: C64,
    b: C64,
    ask: Ask,
    e: &mut Eval,
    mut group: impl FnMut(usize) -> [Option<PointAt>; POINT_LANES],
) -> Option<()> {
    let jac = ask.jacobian;
    e.clear();
    // Room for every point (after a buffer's first evaluation, no work).
    e.r.reserve(p.len());
    if jac {
        e.sim.reserve(p.len());
        e.jl.reserve(p.len());
    }
    let mut cost = RunningCost::new(ask);
    let full = p.chunks_exact(POINT_LANES);
    let rest = full.remainder();
    // Whole groups with their length known (the lanes' loop unrolled), then the rest.
    for (c, chunk) in full.enumerate() {
        let chunk: &[C64; POINT_LANES] = chunk.try_into().expect("a whole group");
        let points = group(c * POINT_LANES);
        whole_group_residuals(chunk, &points, mir, a, b, jac, &mut cost, e)?;
    }
    if !rest.is_empty() {
        let points = group(p.len() - rest.len());
        group_residuals(rest, &points, mir, a, b, jac, &mut cost, e)?;
    }
    e.summed = Some(cost.sum());
    Some(())
}

/// [`group_residuals`] of a whole group, its lanes side by side (the real and imaginary
/// parts in arrays of their own, so that they vectorize): each lane's operations are those
/// of [`group_residuals`] (`tilde`, the complex product and sums written out as
/// `num_complex` computes them), in the same order, so the same values bit for bit. Every
/// lane is evaluated before the cost is kept, point by point as there: a trial given up
/// evaluates at most the rest of its group more, and returns `None` as there.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn whole_group_residuals(
    chunk: &[C64; POINT_LANES],
    points: &[Option<PointAt>; POINT_LANES],
    mir: bool,
    a: C64,
    b: C64,
    jac: bool,
    cost: &mut RunningCost,
    e: &mut Eval,
) -> Option<()> {
    const L: usize = POINT_LANES;
    let (mut mre, mut mim, mut dre, mut dim) = ([0.0; L], [0.0; L], [0.0; L], [0.0; L]);
    for i in 0..L {
        let at = points[i]?;
        mre[i] = at.m.re;
        mim[i] = at.m.im;
        dre[i] = at.dm_dtheta.re;
        dim[i] = at.dm_dtheta.im;
    }
    if mir {
        // `tilde`: the conjugate (an exact negation).
        for i in 0..L {
            mim[i] = -mim[i];
            dim[i] = -dim[i];
        }
    }
    // `a·m̃ + b − p`: `(a.re·m.re − a.im·m.im, a.re·m.im + a.im·m.re)`, then the sums.
    let (mut rre, mut rim) = ([0.0; L], [0.0; L]);
    for i in 0..L {
        rre[i] = (a.re * mre[i] - a.im * mim[i]) + b.re - chunk[i].re;
        rim[i] = (a.re * mim[i] + a.im * mre[i]) + b.im - chunk[i].im;
    }
    for i in 0..L {
        if !cost.add(C64::new(rre[i], rim[i])) {
            return None;
        }
    }
    e.r.extend_from_slice(&std::array::from_fn::<C64, L, _>(|i| {
        C64::new(rre[i], rim[i])
    }));
    if jac {
        // The rows `[m, i·m, 1, i]` (`lm::similarity_row`), given by `m`; `a·dM̃/dθ`.
        let (mut jre, mut jim) = ([0.0; L], [0.0; L]);
        for i in 0..L {
            jre[i] = a.re * dre[i] - a.im * dim[i];
            jim[i] = a.re * dim[i] + a.im * dre[i];
        }
        e.sim
            .extend_from_slice(&std::array::from_fn::<C64, L, _>(|i| {
                C64::new(mre[i], mim[i])
            }));
        e.jl.extend_from_slice(&std::array::from_fn::<C64, L, _>(|i| {
            C64::new(jre[i], jim[i])
        }));
    }
    Some(())
}

/// One group's part of [`untimed_residuals`]: its points' residuals (and with `jac` the
/// similarity rows' `m` and the angles' derivatives) appended to `e` together, the cost
/// kept point by point; `None` where a point is `None` or the trial is given up.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn group_residuals(
    chunk: &[C64],
    points: &[Option<PointAt>; POINT_LANES],
    mir: bool,
    a: C64,
    b: C64,
    jac: bool,
    cost: &mut RunningCost,
    e: &mut Eval,
) -> Option<()> {
    let zero = C64::new(0.0, 0.0);
    let (mut r, mut m, mut jl) = (
        [zero; POINT_LANES],
        [zero; POINT_LANES],
        [zero; POINT_LANES],
    );
    for (i, (&pk, at)) in chunk.iter().zip(points).enumerate() {
        let at = (*at)?;
        m[i] = tilde(mir, at.m);
        r[i] = a * m[i] + b - pk;
        if !cost.add(r[i]) {
            return None;
        }
        if jac {
            jl[i] = a * tilde(mir, at.dm_dtheta);
        }
    }
    let n = chunk.len();
    e.r.extend_from_slice(&r[..n]);
    if jac {
        // The rows `[m, i·m, 1, i]` (`lm::similarity_row`), given by `m`.
        e.sim.extend_from_slice(&m[..n]);
        e.jl.extend_from_slice(&jl[..n]);
    }
    Some(())
}

/// Least-squares untimed fit from a start: LM on (a, b) and every θ_k.
pub(crate) fn fit_untimed(
    p: &[C64],
    curve: &CouplerCurve,
    start: &Start,
    options: &FitOptions,
) -> Option<CurveFit> {
    fit_untimed_kept(p, curve, start, options)?.fit
}

/// An untimed fit with what a larger iteration cap needs to continue it
/// ([`continue_untimed`]).
pub(crate) struct UntimedFit {
    /// What [`fit_untimed`] returns.
    pub fit: Option<CurveFit>,
    /// Levenberg–Marquardt's result (with its evaluation, its damping and whether the
    /// cap stopped it).
    lm: LmResult,
    mirrored: bool,
    /// The cap it ran under.
    cap: usize,
}

/// [`fit_untimed`], keeping Levenberg–Marquardt's state (`None` where [`fit_untimed`]'s
/// fit has no start: the start's points or its similarity undefined).
pub(crate) fn fit_untimed_kept(
    p: &[C64],
    curve: &CouplerCurve,
    start: &Start,
    options: &FitOptions,
) -> Option<UntimedFit> {
    let mir = start.mirrored;
    let gaps = curve.gaps();
    let lanes = curve.lanes_with(&gaps);
    // The start's points serve both its similarity and LM's first evaluation.
    let at0: Vec<PointAt> = curve.points_with(&gaps, &start.theta)?;
    let m0: Vec<C64> = at0.iter().map(|x| tilde(mir, x.m)).collect();
    let (a, b, _) = fit_similarity(&m0, p)?;
    let g0 = vec![a.re, a.im, b.re, b.im];
    let mut first = Eval::default();
    untimed_residuals(
        p,
        mir,
        C64::new(g0[0], g0[1]),
        C64::new(g0[2], g0[3]),
        Ask::whole(true),
        &mut first,
        |k| std::array::from_fn(|i| at0.get(k + i).copied()),
    )?;
    let lm = untimed_lm(options);
    let res = solve_into(
        g0,
        start.theta.clone(),
        Some(first),
        untimed_eval(p, mir, &lanes),
        &lm,
    )?;
    Some(UntimedFit {
        fit: untimed_report(p, curve, mir, &res),
        lm: res,
        mirrored: mir,
        cap: options.max_iterations,
    })
}

/// `fit_untimed(p, curve, start, options)` given `kept`, the same start's
/// [`fit_untimed_kept`] under a cap no larger than `options.max_iterations` (the options
/// otherwise alike: an untimed fit reads only the cap): the same fit, bit for bit, for the
/// iterations `kept` ran are the first ones of the longer run. If its cap stopped it,
/// Levenberg–Marquardt continues from its state ([`resume_into`]); if anything else did,
/// the longer run stops there too, and `kept`'s fit is the answer. A larger `kept` cap
/// fits afresh.
pub(crate) fn continue_untimed(
    p: &[C64],
    curve: &CouplerCurve,
    start: &Start,
    kept: UntimedFit,
    options: &FitOptions,
) -> Option<CurveFit> {
    if kept.cap > options.max_iterations {
        return fit_untimed(p, curve, start, options);
    }
    if !kept.lm.capped {
        return kept.fit;
    }
    let lanes = curve.lanes_with(&curve.gaps());
    let mir = kept.mirrored;
    let res = resume_into(kept.lm, untimed_eval(p, mir, &lanes), &untimed_lm(options))?;
    untimed_report(p, curve, mir, &res)
}

/// Levenberg–Marquardt's options for an untimed fit.
fn untimed_lm(options: &FitOptions) -> LmOptions {
    LmOptions {
        max_iterations: options.max_iterations,
        reuse_trial: true,
        ..LmOptions::DEFAULT
    }
}

/// The untimed fit's evaluation at `(a, b) = g` and the angles `l`: the points a lane
/// group at a time (`POINT_LANES` angles side by side), so a trial given up part-way has
/// evaluated at most a group's worth more.
fn untimed_eval<'a>(
    p: &'a [C64],
    mir: bool,
    lanes: &'a CurveLanes,
) -> impl FnMut(&[f64], &[f64], Ask, &mut Eval) -> Option<()> + 'a {
    // Inlined into Levenberg–Marquardt's iterations (compiled for AVX2 where the processor
    // has it, `lm::iterate`).
    #[inline(always)]
    move |g: &[f64], l: &[f64], ask: Ask, e: &mut Eval| -> Option<()> {
        let (a, b) = (C64::new(g[0], g[1]), C64::new(g[2], g[3]));
        let last = l.len() - 1;
        untimed_residuals(
            p,
            mir,
            a,
            b,
            ask,
            e,
            #[inline(always)]
            |k| {
                // A whole group's angles as they lie; the last group's repeat its last.
                // The lanes inlined here (with the closure), so compiled with the
                // iterations for AVX2.
                let degrees = match l.get(k..k + POINT_LANES) {
                    Some(d) => d.try_into().expect("a whole group"),
                    None => std::array::from_fn(|i| l[(k + i).min(last)]),
                };
                lanes.at_inlined(&degrees)
            },
        )
    }
}

/// The untimed fit's report from Levenberg–Marquardt's result.
fn untimed_report(p: &[C64], curve: &CouplerCurve, mir: bool, res: &LmResult) -> Option<CurveFit> {
    let theta = unwrap_sequence(res.local.clone(), curve.period_deg());
    // The residuals at the result, where the unwrapped angles are the ones LM evaluated.
    let known = res
        .last
        .as_ref()
        .map(|e| (res.local.as_slice(), e.r.as_slice()));
    finish_fit(p, curve, mir, &res.global, theta, None, known)
}

/// The fit's report at `g` and the angles `theta`. Given `known = (angles, residuals)` of an
/// evaluation at `g`, a point whose angle is bit for bit the evaluated one takes its
/// residual from there (the same value the curve would give again).
fn finish_fit(
    p: &[C64],
    curve: &CouplerCurve,
    mirrored: bool,
    g: &[f64],
    theta: Vec<f64>,
    step: Option<f64>,
    known: Option<(&[f64], &[C64])>,
) -> Option<CurveFit> {
    let (a, b) = (C64::new(g[0], g[1]), C64::new(g[2], g[3]));
    let gaps = curve.gaps();
    let mut sum = 0.0;
    let mut max = 0.0f64;
    for (k, &pk) in p.iter().enumerate() {
        let d = match known {
            Some((l, r)) if l.get(k).map(|x| x.to_bits()) == Some(theta[k].to_bits()) => abs(r[k]),
            _ => abs(a * tilde(mirrored, curve.at_with(&gaps, theta[k])?.m) + b - pk),
        };
        sum += d * d;
        max = max.max(d);
    }
    let rms = (sum / p.len() as f64).sqrt();
    (rms.is_finite() && abs(a) > 0.0).then_some(CurveFit {
        mirrored,
        a: [a.re, a.im],
        b: [b.re, b.im],
        theta_deg: theta,
        rms,
        max,
        timing_rate: step,
    })
}

/// The crank angles of a timed target relative to its first point, before the sense and
/// offset: for angles `t_k − t₀`; for equal steps `k` (times the step).
fn timed_offsets(target: &Target) -> Vec<f64> {
    match target.timing() {
        Timing::Angles(t) => t.iter().map(|x| x - t[0]).collect(),
        _ => (0..target.len()).map(|k| k as f64).collect(),
    }
}

/// Timed fit: `θ_k = θ₀ + s·o_k` with `o_k` from [`timed_offsets`] and the step `s`
/// fixed (±1 for angles, ±P/n for a closed target of equal steps, P the mechanism's period) or fitted (an open
/// target of equal steps). Starts: every θ₀ on a 2° grid for each sense and reflection
/// (Procrustes on the dense trace), and, when `hint` is given (an untimed fit), the
/// regression of its angles on the offsets.
pub(crate) fn fit_timed(
    target: &Target,
    curve: &CouplerCurve,
    traced: &Traced,
    hint: Option<&CurveFit>,
    options: &FitOptions,
) -> Option<CurveFit> {
    let (p, o, (free_step, unit_step)) = timed_problem(target, curve)?;
    // Candidate (mirrored, θ₀, step) starts.
    let mut starts: Vec<(f64, bool, f64, f64)> = Vec::new();
    let mirrors: &[bool] = if options.allow_mirror {
        &[false, true]
    } else {
        &[false]
    };
    if !free_step {
        for &mir in mirrors {
            for sense in [1.0, -1.0] {
                let step = sense * unit_step;
                let mut best = (f64::INFINITY, 0.0);
                for i in 0..(curve.period_deg() / 2.0).round() as usize {
                    let t0 = 2.0 * i as f64;
                    let m: Vec<C64> = o
                        .iter()
                        .map(|&x| tilde(mir, traced.point_at_theta(t0 + step * x)))
                        .collect();
                    if let Some((_, _, rss)) = fit_similarity(&m, &p) {
                        if rss < best.0 {
                            best = (rss, t0);
                        }
                    }
                }
                starts.push((best.0, mir, best.1, step));
            }
        }
    }
    if let Some(h) = hint.filter(|h| options.allow_mirror || !h.mirrored) {
        if let Some((t0, step)) = timed_line(&o, &h.theta_deg, free_step, unit_step) {
            starts.push((f64::INFINITY, h.mirrored, t0, step));
        }
    }
    let mut best: Option<CurveFit> = None;
    starts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let keep = if free_step { 1 } else { 2 };
    for &(_, mir, t0, step) in starts.iter().take(keep + usize::from(hint.is_some())) {
        if let Some(f) = timed_lm(&p, &o, curve, mir, t0, step, free_step, options) {
            if best.as_ref().is_none_or(|b| f.rms < b.rms) {
                best = Some(f);
            }
        }
    }
    best
}

/// The target's points, their timing offsets and the step: the data of a timed fit.
type TimedProblem = (Vec<C64>, Vec<f64>, (bool, f64));

/// A timed fit's problem: the target's points, their timing offsets
/// ([`timed_offsets`]) and the step ([`timed_step`]); `None` when the target's timing
/// does not fit the curve's period.
fn timed_problem(target: &Target, curve: &CouplerCurve) -> Option<TimedProblem> {
    if !target.fits_period(curve.period_deg()) {
        return None;
    }
    Some((
        target.complex_points(),
        timed_offsets(target),
        timed_step(target, curve),
    ))
}

/// Whether a timed target's step is fitted (an open target of equal steps), and its
/// magnitude when it is not (1 for angles, `P/n` for a closed target of equal steps).
fn timed_step(target: &Target, curve: &CouplerCurve) -> (bool, f64) {
    let free_step = matches!(target.timing(), Timing::EqualSteps) && !target.is_closed();
    let unit_step = match target.timing() {
        Timing::Angles(_) => 1.0,
        _ if target.is_closed() => curve.period_deg() / target.len() as f64,
        _ => 0.0,
    };
    (free_step, unit_step)
}

/// The regression `θ_k ≈ θ₀ + s·o_k` of angles `theta` on the offsets `o` (`s` fixed in
/// magnitude unless `free_step`): `(θ₀, s)`, or `None` when the step comes out zero.
fn timed_line(o: &[f64], theta: &[f64], free_step: bool, unit_step: f64) -> Option<(f64, f64)> {
    let n = o.len();
    let (om, tm) = (
        o.iter().sum::<f64>() / n as f64,
        theta.iter().sum::<f64>() / n as f64,
    );
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (x, y) in o.iter().zip(theta) {
        sxy += (x - om) * (y - tm);
        sxx += (x - om) * (x - om);
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let step = if free_step {
        slope
    } else {
        unit_step * slope.signum()
    };
    (step != 0.0).then_some((tm - step * om, step))
}

/// A timed fit from one start's angles alone (an open candidate's scan start, whose angles
/// a timed query lays out by the target's timing): the timed Levenberg–Marquardt from the
/// regression of its angles on the offsets ([`fit_timed`]'s hinted start), without the
/// scan of the dense trace. `None` when the target's timing does not fit the curve's
/// period or the start gives no step.
pub(crate) fn fit_timed_from(
    target: &Target,
    curve: &CouplerCurve,
    start: &Start,
    options: &FitOptions,
) -> Option<CurveFit> {
    let (p, o, (free_step, unit_step)) = timed_problem(target, curve)?;
    let (t0, step) = timed_line(&o, &start.theta, free_step, unit_step)?;
    timed_lm(&p, &o, curve, start.mirrored, t0, step, free_step, options)
}

#[allow(clippy::too_many_arguments)]
fn timed_lm(
    p: &[C64],
    o: &[f64],
    curve: &CouplerCurve,
    mir: bool,
    t0: f64,
    step: f64,
    free_step: bool,
    options: &FitOptions,
) -> Option<CurveFit> {
    let gaps = curve.gaps();
    let m0: Vec<C64> = o
        .iter()
        .map(|&x| curve.at_with(&gaps, t0 + step * x).map(|a| tilde(mir, a.m)))
        .collect::<Option<_>>()?;
    let (a, b, _) = fit_similarity(&m0, p)?;
    let lanes = curve.lanes_with(&gaps);
    let eval = |g: &[f64], _: &[f64], ask: Ask, e: &mut Eval| -> Option<()> {
        let (a, b) = (C64::new(g[0], g[1]), C64::new(g[2], g[3]));
        let (t0, s) = (g[4], if free_step { g[5] } else { step });
        e.clear();
        e.r.reserve(p.len());
        if ask.jacobian {
            e.jg.reserve(p.len() * if free_step { 6 } else { 5 });
        }
        let mut cost = RunningCost::new(ask);
        // The points a lane group at a time, as in the untimed fit.
        let mut group = [None; POINT_LANES];
        let last = o.len().saturating_sub(1);
        for (k, &pk) in p.iter().enumerate() {
            let lane = k % POINT_LANES;
            if lane == 0 {
                let degrees = std::array::from_fn(|i| t0 + s * o[(k + i).min(last)]);
                group = lanes.at(&degrees);
            }
            let at = group[lane]?;
            let m = tilde(mir, at.m);
            let r = a * m + b - pk;
            if !cost.add(r) {
                return None;
            }
            e.r.push(r);
            if ask.jacobian {
                let dv = a * tilde(mir, at.dm_dtheta);
                e.jg.extend([
                    m,
                    C64::new(0.0, 1.0) * m,
                    C64::new(1.0, 0.0),
                    C64::new(0.0, 1.0),
                    dv,
                ]);
                if free_step {
                    e.jg.push(dv * o[k]);
                }
            }
        }
        e.summed = Some(cost.sum());
        Some(())
    };
    let mut g = vec![a.re, a.im, b.re, b.im, t0];
    if free_step {
        g.push(step);
    }
    let lm = LmOptions {
        max_iterations: options.max_iterations,
        reuse_trial: true,
        ..LmOptions::DEFAULT
    };
    let res = solve_into(g, Vec::new(), None, eval, &lm)?;
    let s = if free_step { res.global[5] } else { step };
    let theta = o.iter().map(|&x| res.global[4] + s * x).collect();
    finish_fit(p, curve, mir, &res.global, theta, Some(s), None)
}

/// Fits `target` to `curve`: the global scans, then Levenberg–Marquardt from the best
/// starts (two per fit), keeping the lowest RMS error. Timed targets are fitted untimed
/// first (to find the shape's placement), then with their timing. `None` if the curve
/// does not assemble all round.
pub fn fit_curve(target: &Target, curve: &CouplerCurve, options: &FitOptions) -> Option<CurveFit> {
    let traced = Traced::new(curve, options.trace_samples)?;
    fit_with(target, curve, &traced, options)
}

/// Iterations each start gets before the best two are fitted to convergence.
const RACE_ITERATIONS: usize = 4;

pub(crate) fn fit_with(
    target: &Target,
    curve: &CouplerCurve,
    traced: &Traced,
    options: &FitOptions,
) -> Option<CurveFit> {
    let (p, raced) = race(target, curve, traced, options);
    let finish = |f: Option<&CurveFit>| fit_untimed(&p, curve, &finish_start(f?), options);
    let (first, second) = rayon::join(|| finish(raced.first()), || finish(raced.get(1)));
    let mut best: Option<CurveFit> = None;
    for f in [first, second].into_iter().flatten() {
        if best.as_ref().is_none_or(|b| f.rms < b.rms) {
            best = Some(f);
        }
    }
    if target.timing().is_timed() {
        return fit_timed(target, curve, traced, best.as_ref(), options);
    }
    best
}

/// [`fit_with`]'s scan and race: the target's points and the starts' raced fits, best
/// first.
fn race(
    target: &Target,
    curve: &CouplerCurve,
    traced: &Traced,
    options: &FitOptions,
) -> (Vec<C64>, Vec<CurveFit>) {
    let p = target.complex_points();
    let starts = if target.is_closed() {
        scan_closed(&p, traced, options.allow_mirror)
    } else {
        scan_open(&p, traced, options.allow_mirror)
    };
    // Race the starts: a few iterations each, then the two best to convergence.
    let quick = FitOptions {
        max_iterations: RACE_ITERATIONS,
        ..*options
    };
    // The starts' fits are independent: they run on the calling thread's rayon pool
    // (finer work than one candidate's whole fit, so the last candidates of a search
    // share the threads), and are taken in the starts' order, so the result is the same
    // on any number of threads.
    let mut raced: Vec<CurveFit> = starts
        .par_iter()
        .filter_map(|s| fit_untimed(&p, curve, s, &quick))
        .collect();
    raced.sort_by(|a, b| a.rms.total_cmp(&b.rms));
    (p, raced)
}

/// The start a raced fit is finished from: its angles.
fn finish_start(f: &CurveFit) -> Start {
    Start {
        mirrored: f.mirrored,
        theta: f.theta_deg.clone(),
        score: 0.0,
    }
}

/// An untimed target's [`fit_with`] with its finishes stopped at a smaller cap and
/// kept ([`robust_kept`]): what an open candidate's ranking reads, and what its final
/// fit continues ([`RobustKept::finish`]: [`fit_with`]'s fit, bit for bit).
pub(crate) struct RobustKept {
    /// The (up to two) finishes, in [`fit_with`]'s order, each from its start.
    finishes: Vec<(Start, UntimedFit)>,
}

impl RobustKept {
    /// The RMS error of the better capped finish (as [`fit_with`] chooses: the first on
    /// a tie); `None` if neither has a fit.
    pub(crate) fn rms(&self) -> Option<f64> {
        let mut best: Option<f64> = None;
        for f in self.finishes.iter().filter_map(|(_, k)| k.fit.as_ref()) {
            if best.is_none_or(|b| f.rms < b) {
                best = Some(f.rms);
            }
        }
        best
    }

    /// Both finishes continued to `options`' cap ([`continue_untimed`]) and the better
    /// taken: [`fit_with`]'s fit with those options, bit for bit (`options` as the
    /// ones [`robust_kept`] ran under, but for the cap).
    pub(crate) fn finish(
        self,
        target: &Target,
        curve: &CouplerCurve,
        options: &FitOptions,
    ) -> Option<CurveFit> {
        let p = target.complex_points();
        let mut best: Option<CurveFit> = None;
        for (start, kept) in self.finishes {
            if let Some(f) = continue_untimed(&p, curve, &start, kept, options) {
                if best.as_ref().is_none_or(|b| f.rms < b.rms) {
                    best = Some(f);
                }
            }
        }
        best
    }
}

/// [`fit_with`] for an **untimed** target (a timed one's fit is timed after the
/// finishes: call [`fit_with`]), its two finishes stopped at `cap` iterations (at most
/// `options.max_iterations`) and kept, so that a candidate is ranked by a shorter fit
/// and only a finalist's is continued to the full cap.
pub(crate) fn robust_kept(
    target: &Target,
    curve: &CouplerCurve,
    traced: &Traced,
    options: &FitOptions,
    cap: usize,
) -> RobustKept {
    let (p, raced) = race(target, curve, traced, options);
    let capped = FitOptions {
        max_iterations: cap.min(options.max_iterations),
        ..*options
    };
    let finish = |f: Option<&CurveFit>| {
        let start = finish_start(f?);
        let kept = fit_untimed_kept(&p, curve, &start, &capped)?;
        Some((start, kept))
    };
    let (first, second) = rayon::join(|| finish(raced.first()), || finish(raced.get(1)));
    RobustKept {
        finishes: [first, second].into_iter().flatten().collect(),
    }
}

/// A **closed** target fitted to one curve both ways: `[fit_with` without reflection,
/// `fit_with` with reflection allowed`]` (`options.allow_mirror` is ignored), the same
/// results bit for bit as the two calls, for a curve that is a candidate of both
/// reflections. The work both calls would do alike is done once:
///
/// - the scan: the starts of the scan with reflection allowed are those of the scan
///   without it (the same values: each variant's shifts are summed alone, in order) plus
///   the reflected ones, and both are sorted stably by score, so the unreflected ones
///   come in the same order;
/// - the race: an unreflected start's race is the same fit in both calls (the same start
///   and iterations; an untimed fit does not read `allow_mirror`);
/// - the finishes: each call finishes its two best raced fits, in its own order (a stable
///   sort by RMS of the fits in the starts' order); a raced fit both calls finish is
///   finished once.
pub(crate) fn fit_closed_both(
    target: &Target,
    curve: &CouplerCurve,
    traced: &Traced,
    options: &FitOptions,
) -> [Option<CurveFit>; 2] {
    let p = target.complex_points();
    let starts = scan_closed(&p, traced, true);
    let quick = FitOptions {
        max_iterations: RACE_ITERATIONS,
        ..*options
    };
    // Every start raced once, on the pool, in the starts' order (as `fit_with`).
    let raced: Vec<Option<CurveFit>> = starts
        .par_iter()
        .map(|s| fit_untimed(&p, curve, s, &quick))
        .collect();
    // Each call's two best raced fits: `fit_with`'s list (the raced fits that exist, in
    // the starts' order, sorted stably by RMS) as indices into `raced`.
    let best_two = |mirror: bool| -> Vec<usize> {
        let mut order: Vec<usize> = (0..starts.len())
            .filter(|&i| raced[i].is_some() && (mirror || !starts[i].mirrored))
            .collect();
        order.sort_by(|&a, &b| {
            let rms = |i: usize| raced[i].as_ref().map_or(f64::NAN, |f| f.rms);
            rms(a).total_cmp(&rms(b))
        });
        order.truncate(2);
        order
    };
    let lists = [best_two(false), best_two(true)];
    let mut needed: Vec<usize> = lists.iter().flatten().copied().collect();
    needed.sort_unstable();
    needed.dedup();
    let finished: Vec<(usize, Option<CurveFit>)> = needed
        .par_iter()
        .map(|&i| {
            let f = raced[i].as_ref().and_then(|f| {
                let start = Start {
                    mirrored: f.mirrored,
                    theta: f.theta_deg.clone(),
                    score: 0.0,
                };
                fit_untimed(&p, curve, &start, options)
            });
            (i, f)
        })
        .collect();
    let finish_of = |i: usize| -> Option<&CurveFit> {
        finished
            .iter()
            .find(|(j, _)| *j == i)
            .and_then(|(_, f)| f.as_ref())
    };
    [false, true].map(|mirror| {
        let mut best: Option<&CurveFit> = None;
        for f in lists[usize::from(mirror)]
            .iter()
            .filter_map(|&i| finish_of(i))
        {
            if best.is_none_or(|b| f.rms < b.rms) {
                best = Some(f);
            }
        }
        let best = best.cloned();
        if target.timing().is_timed() {
            let options = FitOptions {
                allow_mirror: mirror,
                ..*options
            };
            return fit_timed(target, curve, traced, best.as_ref(), &options);
        }
        best
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::{Circuit, CouplerPoint, FourBar};

    fn curve() -> CouplerCurve {
        CouplerCurve {
            linkage: FourBar::new(2.5, 3.0, 3.5).unwrap().into(),
            circuit: Circuit::Open,
            point: CouplerPoint::new(1.25, 1.0),
        }
    }

    /// [`curve`] and two curves of other shapes (one of them on the crossed circuit).
    fn three_curves() -> [CouplerCurve; 3] {
        [
            curve(),
            CouplerCurve {
                linkage: FourBar::new(2.0, 2.5, 2.0).unwrap().into(),
                circuit: Circuit::Open,
                point: CouplerPoint::new(3.0, 0.0),
            },
            CouplerCurve {
                linkage: FourBar::new(4.5, 3.0, 3.5).unwrap().into(),
                circuit: Circuit::Crossed,
                point: CouplerPoint::new(1.125, -2.25),
            },
        ]
    }

    /// Points of `c` at the angles, placed by `p = a·M̃ + b`.
    fn placed(c: &CouplerCurve, angles: &[f64], a: C64, b: C64, mirrored: bool) -> Vec<[f64; 2]> {
        angles
            .iter()
            .map(|&t| {
                let z = a * tilde(mirrored, c.at(t).unwrap().m) + b;
                [z.re, z.im]
            })
            .collect()
    }

    /// `frac` is `rem_euclid(1.0)` bit for bit: edges, neighbours of the edges and random
    /// values in and around its fast range.
    #[test]
    fn frac_is_rem_euclid() {
        let mut xs = vec![-3.0, -2.0, -1.0, -0.5, -0.0, 0.0, 0.5, 1.0, 1.5, 2.0, 3.0];
        for &e in &[-2.0f64, -1.0, 0.0, 1.0, 2.0] {
            let mut lo = e;
            let mut hi = e;
            for _ in 0..4 {
                lo = lo.next_down();
                hi = hi.next_up();
                xs.extend([lo, hi]);
            }
        }
        xs.extend([f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e-300, -1e-300]);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..2_000_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            xs.push((state >> 11) as f64 / (1u64 << 53) as f64 * 6.0 - 3.0);
        }
        for x in xs {
            assert_eq!(frac(x).to_bits(), x.rem_euclid(1.0).to_bits(), "{x:e}");
        }
    }

    /// `fit_closed_both` gives the fits of `fit_with` without and with reflection, bit
    /// for bit: closed targets from curves of several shapes, unreflected and reflected,
    /// noisy and exact, untimed and timed by equal steps, with the ranking's iteration cap
    /// and the final one.
    #[test]
    fn fit_closed_both_is_two_fits() {
        let mut rng = crate::cases::SplitMix64(31);
        let curves = three_curves();
        let bits = |f: &Option<CurveFit>| format!("{f:?}");
        let mut reflected_best = 0;
        for (ci, c) in curves.iter().enumerate() {
            for (mirrored, noise, timed) in [
                (false, 0.01, false),
                (true, 0.01, false),
                (false, 0.0, false),
                (true, 0.02, true),
            ] {
                let t =
                    crate::cases::make_target(&mut rng, c, true, 10.0, 360.0, 48, mirrored, noise)
                        .unwrap();
                let t = if timed {
                    Target::new(t.points().to_vec(), true, Timing::EqualSteps).unwrap()
                } else {
                    t
                };
                let traced = Traced::new(c, 720).unwrap();
                for iterations in [30, 100] {
                    let options = FitOptions {
                        max_iterations: iterations,
                        ..FitOptions::DEFAULT
                    };
                    let alone = |allow_mirror: bool| {
                        let o = FitOptions {
                            allow_mirror,
                            ..options
                        };
                        fit_with(&t, c, &traced, &o)
                    };
                    let [plain, both] = fit_closed_both(&t, c, &traced, &options);
                    let what = format!("curve {ci}, {mirrored} {noise} {timed}, {iterations}");
                    assert_eq!(bits(&plain), bits(&alone(false)), "{what}");
                    assert_eq!(bits(&both), bits(&alone(true)), "{what}");
                    assert!(plain.is_some(), "{what}");
                    reflected_best += usize::from(both.is_some_and(|f| f.mirrored));
                }
            }
        }
        // Both kinds of answer are compared: some fits with reflection allowed are
        // reflected.
        assert!(reflected_best > 0);
    }

    /// An untimed fit continued from a smaller iteration cap (`continue_untimed`) is the
    /// fit of one run to the larger cap, bit for bit: open targets of several curves,
    /// spans, noise and reflections, every start of their window scan, caps from 0 to
    /// 30 continued to 100, some stopped by the cap and some converged before it; a
    /// larger kept cap than the final one fits afresh.
    #[test]
    fn continued_fit_is_one_fit() {
        let mut rng = crate::cases::SplitMix64(57);
        let curves = three_curves();
        let bits = |f: &Option<CurveFit>| format!("{f:?}");
        let (mut capped, mut stopped) = (0, 0);
        for (ci, c) in curves.iter().enumerate() {
            for (span, mirrored, noise) in [
                (120.0, false, 0.01),
                (240.0, true, 0.0),
                (90.0, false, 0.03),
            ] {
                let t =
                    crate::cases::make_target(&mut rng, c, false, 40.0, span, 40, mirrored, noise)
                        .unwrap();
                let p = t.complex_points();
                let traced = Traced::new(c, 720).unwrap();
                for (si, start) in scan_open(&p, &traced, true).iter().enumerate() {
                    let cap = |max_iterations: usize| FitOptions {
                        max_iterations,
                        ..FitOptions::DEFAULT
                    };
                    let one = fit_untimed(&p, c, start, &cap(100));
                    for k in [0, 1, 4, 30] {
                        let what = format!("curve {ci}, span {span}, start {si}, cap {k}");
                        let Some(kept) = fit_untimed_kept(&p, c, start, &cap(k)) else {
                            assert!(one.is_none(), "{what}");
                            continue;
                        };
                        assert_eq!(bits(&kept.fit), bits(&fit_untimed(&p, c, start, &cap(k))));
                        if kept.lm.capped {
                            capped += 1;
                        } else {
                            stopped += 1;
                        }
                        let continued = continue_untimed(&p, c, start, kept, &cap(100));
                        assert_eq!(bits(&continued), bits(&one), "{what}");
                    }
                    let kept = fit_untimed_kept(&p, c, start, &cap(30)).unwrap();
                    let shorter = continue_untimed(&p, c, start, kept, &cap(8));
                    assert_eq!(bits(&shorter), bits(&fit_untimed(&p, c, start, &cap(8))));
                }
            }
        }
        // Both ways of continuing are compared.
        assert!(
            capped > 0 && stopped > 0,
            "{capped} capped, {stopped} stopped"
        );
    }

    /// An untimed open target's robust start stopped at a smaller cap and continued
    /// ([`robust_kept`], [`RobustKept::finish`]) is [`fit_with`]'s fit, bit for bit, and
    /// its ranking error is the better capped finish's: several curves, spans, noise and
    /// reflections, caps from 0 to the final one.
    #[test]
    fn robust_kept_finishes_as_fit_with() {
        let mut rng = crate::cases::SplitMix64(59);
        let bits = |f: &Option<CurveFit>| format!("{f:?}");
        let mut fits = 0;
        for c in &three_curves() {
            for (span, mirrored, noise, allow_mirror) in [
                (120.0, false, 0.01, false),
                (240.0, true, 0.0, true),
                (90.0, false, 0.03, true),
            ] {
                let t =
                    crate::cases::make_target(&mut rng, c, false, 40.0, span, 40, mirrored, noise)
                        .unwrap();
                let traced = Traced::new(c, 720).unwrap();
                let options = FitOptions {
                    allow_mirror,
                    ..FitOptions::DEFAULT
                };
                let whole = fit_with(&t, c, &traced, &options);
                for cap in [0, 1, 8, 100] {
                    let kept = robust_kept(&t, c, &traced, &options, cap);
                    let (p, raced) = race(&t, c, &traced, &options);
                    let capped = FitOptions {
                        max_iterations: cap,
                        ..options
                    };
                    let least = raced
                        .iter()
                        .take(2)
                        .filter_map(|f| fit_untimed(&p, c, &finish_start(f), &capped))
                        .map(|f| f.rms)
                        .reduce(|a, b| if b < a { b } else { a });
                    assert_eq!(kept.rms().map(f64::to_bits), least.map(f64::to_bits));
                    let finished = kept.finish(&t, c, &options);
                    assert_eq!(bits(&finished), bits(&whole), "span {span}, cap {cap}");
                    fits += usize::from(finished.is_some());
                }
            }
        }
        // Not vacuous: the fits exist.
        assert!(fits >= 30, "{fits}");
    }

    /// The open window scan on the processor's fastest path ([`scan_open`]: compiled for
    /// AVX2 where it has it) gives the baseline body's starts, bit for bit: three curves,
    /// open targets with and without reflection (two and four variants side by side).
    #[test]
    fn scan_open_is_the_same_on_every_path() {
        let mut rng = crate::cases::SplitMix64(83);
        let bits = |v: &[Start]| -> Vec<(bool, u64, Vec<u64>)> {
            v.iter()
                .map(|s| {
                    let theta = s.theta.iter().map(|t| t.to_bits()).collect();
                    (s.mirrored, s.score.to_bits(), theta)
                })
                .collect()
        };
        let mut starts = 0;
        for c in &three_curves() {
            let traced = Traced::new(c, 720).unwrap();
            for (span, mirrored, noise) in [
                (60.0, false, 0.0),
                (200.0, true, 0.02),
                (350.0, false, 0.01),
            ] {
                let t =
                    crate::cases::make_target(&mut rng, c, false, 30.0, span, 48, mirrored, noise)
                        .unwrap();
                let p = t.complex_points();
                for allow_mirror in [false, true] {
                    let fast = scan_open(&p, &traced, allow_mirror);
                    let base = scan_open_body(&p, &traced, allow_mirror);
                    assert_eq!(
                        bits(&fast),
                        bits(&base),
                        "span {span}, mirror {allow_mirror}"
                    );
                    starts += fast.len();
                }
            }
        }
        // Not vacuous: the scans found starts.
        assert!(starts >= 18, "{starts}");
    }

    /// `best_shifts` in split form gives the shifts and values of the sums of `C64`
    /// products, bit for bit, for one, two and four targets.
    #[test]
    fn best_shifts_sums_as_complex() {
        fn reference<const L: usize>(cc: &[C64], vs: [&[C64]; L]) -> [(f64, usize); L] {
            let m = cc.len() / 2;
            let mut best = [(-1.0, 0usize); L];
            for k in 0..m {
                let w = &cc[k..k + m];
                let mut s = [C64::new(0.0, 0.0); L];
                for (j, &cj) in w.iter().enumerate() {
                    for l in 0..L {
                        s[l] += cj * vs[l][j];
                    }
                }
                for l in 0..L {
                    let q = s[l].norm_sqr();
                    if q > best[l].0 {
                        best[l] = (q, k);
                    }
                }
            }
            best
        }
        let mut rng = crate::cases::SplitMix64(7);
        let mut point = || C64::new(rng.normal(), rng.normal());
        for m in [1, 5, 128] {
            let c: Vec<C64> = (0..m).map(|_| point()).collect();
            let cc: Vec<C64> = c.iter().chain(&c).map(|z| z.conj()).collect();
            let v: Vec<Vec<C64>> = (0..4).map(|_| (0..m).map(|_| point()).collect()).collect();
            let bits = |r: &[(f64, usize)]| -> Vec<(u64, usize)> {
                r.iter().map(|&(q, k)| (q.to_bits(), k)).collect()
            };
            let four = [&v[0][..], &v[1], &v[2], &v[3]];
            assert_eq!(bits(&best_shifts(&cc, four)), bits(&reference(&cc, four)));
            let two = [&v[0][..], &v[1]];
            assert_eq!(bits(&best_shifts(&cc, two)), bits(&reference(&cc, two)));
            let one = [&v[2][..]];
            assert_eq!(bits(&best_shifts(&cc, one)), bits(&reference(&cc, one)));
        }
    }

    #[test]
    fn exact_targets_fit_to_rounding() {
        let c = curve();
        let (a, b) = (C64::new(3.0, -4.0), C64::new(10.0, 20.0));
        for (closed, timing, mirrored) in [
            (true, Timing::Untimed, false),
            (true, Timing::Untimed, true),
            (false, Timing::Untimed, false),
            (false, Timing::Untimed, true),
            (true, Timing::EqualSteps, false),
            (false, Timing::EqualSteps, true),
        ] {
            let angles: Vec<f64> = if closed {
                (0..40).map(|k| 33.0 + 9.0 * k as f64).collect()
            } else {
                (0..30).map(|k| 100.0 + 5.0 * k as f64).collect()
            };
            let pts = placed(&c, &angles, a, b, mirrored);
            let t = Target::new(pts, closed, timing.clone()).unwrap();
            let f = fit_curve(&t, &c, &FitOptions::DEFAULT).unwrap();
            assert!(
                f.rms < 1e-9 * t.size(),
                "{closed} {timing:?} {mirrored}: {f:?}"
            );
            assert_eq!(f.mirrored, mirrored);
        }
        // Timing by angles, crank turning the other way.
        let angles: Vec<f64> = (0..25).map(|k| 300.0 - 7.0 * k as f64).collect();
        let given: Vec<f64> = (0..25).map(|k| 7.0 * k as f64).collect();
        let t = Target::new(
            placed(&c, &angles, a, b, false),
            false,
            Timing::Angles(given),
        )
        .unwrap();
        let f = fit_curve(&t, &c, &FitOptions::DEFAULT).unwrap();
        assert!(f.rms < 1e-9 * t.size(), "{f:?}");
        assert_eq!(f.timing_rate, Some(-1.0));
    }
}
