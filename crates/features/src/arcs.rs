//! Pseudo-arcs (docs/conventions.md §5): portions of the curve that stay close to a circle.
//!
//! **The contract.** The circle of a window is Kåsa's algebraic circle of its samples
//! ([`kasa_circle`]: closed form, so a window's fit is exact and costs O(1) from sliding
//! sums; on arcs within a fraction of a percent of a circle it agrees with the geometric
//! fit to first order, since `‖M−c‖² − R² = (‖M−c‖ − R)(‖M−c‖ + R)` and the second factor
//! varies by twice the tolerance). A window **qualifies** when, with that circle (c, R):
//! every sample is within `arc_pct` % of R of it (`|‖M−c‖ − R| ≤ tol·R`); the point runs
//! one way round c (every `(M − c) × V` of one strict sign); it turns at least
//! `arc_min_turn_deg` about c (the sum of the polar angle's steps between consecutive
//! samples); and it spans at least `arc_min_span_deg`. The error breaking ties is Kåsa's
//! largest relative deviation. The pseudo-arcs are the maximal qualifying windows
//! ([`crate::maximal`]).

use super::fit::{Circle, CircleFitOptions, fit_circle, kasa_circle};
use super::{FeatureTolerances, PseudoArc, Side, dash_count};
use crate::maximal::{Candidates, set_bits};
use coupler_kinematics::{Curve, DashPattern};

/// The samples of a closed curve taken twice round (so that a window passing the last
/// sample is one slice), and which of them are valid.
struct Samples {
    n: usize,
    x: Vec<f64>,
    y: Vec<f64>,
    vx: Vec<f64>,
    vy: Vec<f64>,
    /// `invalid[k]`: invalid samples (position or velocity not finite) before `k`.
    invalid: Vec<u32>,
}

impl Samples {
    fn new(c: &Curve) -> Samples {
        let n = c.len();
        let twice = |v: &[f64]| v.iter().chain(v).copied().collect::<Vec<f64>>();
        let mut invalid = vec![0u32; 2 * n + 1];
        for k in 0..2 * n {
            let q = if k < n { k } else { k - n };
            let ok = c.is_valid(q) && c.vx[q].is_finite() && c.vy[q].is_finite();
            invalid[k + 1] = invalid[k] + u32::from(!ok);
        }
        Samples {
            n,
            x: twice(&c.x),
            y: twice(&c.y),
            vx: twice(&c.vx),
            vy: twice(&c.vy),
            invalid,
        }
    }

    /// The positions of window `[i, j]` (`j < 2n`), or `None` if a sample is invalid.
    #[inline]
    fn window(&self, i: usize, j: usize) -> Option<(&[f64], &[f64])> {
        (self.invalid[j + 1] == self.invalid[i]).then(|| (&self.x[i..=j], &self.y[i..=j]))
    }
}

/// The sign (+1 / −1) with which the window runs round `center` if it runs one way
/// (every `(M − c) × V` of that sign), else 0.
fn winding(c: &Samples, i: usize, j: usize, center: [f64; 2]) -> f64 {
    let (mut pos, mut neg) = (true, true);
    for k in i..=j {
        let cross = (c.x[k] - center[0]) * c.vy[k] - (c.y[k] - center[1]) * c.vx[k];
        pos &= cross > 0.0;
        neg &= cross < 0.0;
    }
    if pos {
        1.0
    } else if neg {
        -1.0
    } else {
        0.0
    }
}

/// The angle (radians) a window turns about `center` in the direction `sign`: the sum of
/// the polar angle's steps between consecutive samples (each in (−π, π]), times `sign`.
/// With `stop_at`, the sum stops once it reaches that angle (enough to pass a test).
fn turn(c: &Samples, i: usize, j: usize, center: [f64; 2], sign: f64, stop_at: f64) -> f64 {
    let r = |k: usize| [c.x[k] - center[0], c.y[k] - center[1]];
    let mut total = 0.0;
    let mut a = r(i);
    for k in i + 1..=j {
        let b = r(k);
        let step = libm::atan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1]);
        total += sign * step;
        if total >= stop_at {
            break;
        }
        a = b;
    }
    total
}

/// The O(1) filter of every window of a closed curve of `n` samples, for every start at
/// once (structure of arrays, so the compiler vectorises it): Kåsa's sums of the window
/// `[i, i + l]` about its first sample (so that a small window far from the origin keeps
/// its digits), grown by one sample per round of `l`; from them its circle, and whether
/// that circle holds the window's first, middle and last samples within the tolerance
/// (0.1 % slack on it, and more than the rounding of a circle fitted from sums), and
/// whether the point runs one way round that circle's centre at those three samples.
/// Windows whose samples are (nearly) collinear pass: the exact test decides.
///
/// **Why the winding filter never rejects a qualifying window.** The exact test takes the
/// winding about [`kasa_circle`]'s centre `c`, the filter about its own centre `c'`, the
/// same centred normal equations solved from sums accumulated in another order: they
/// differ only by rounding, `|c − c'| ≤ κ·O(m·ε)·R` with `κ` the condition number of the
/// 2 × 2 scatter matrix. The filter trusts its centre only where `κ ≤ 10⁴` (`det >
/// 10⁻⁴·scale²`; the exact test decides the rest), so `|c − c'| < 10⁻⁹·R` there, and it
/// rejects a window only when two of the three samples have cross products
/// `(M − c')×V` of opposite signs, each larger in size than `10⁻⁶·2R·|V|`: moving the centre
/// by less than that cannot change either sign (`|δ×V| ≤ |δ|·|V|`), so the window does
/// not run one way round `c` either.
///
/// **Four lanes where the processor has them.** On x86-64 with AVX2 (checked at run
/// time) the same code is compiled for AVX2 and run instead: the compiler packs four
/// windows per instruction instead of two. Rust never fuses a multiply and an add without
/// being asked, and every lane does the same IEEE-754 operations in the same order, so
/// every window passes or fails exactly as on the baseline path (the features bench's
/// fingerprint is the same either way).
fn filter_windows(c: &Samples, tol: f64, min_steps: usize, cand: &mut Candidates) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: `filter_avx2` needs AVX2, which the processor was just found to have;
        // it has no other requirement (it is the safe `filter_body` compiled for AVX2).
        #[allow(unsafe_code)]
        unsafe {
            filter_avx2(c, tol, min_steps, cand)
        };
        return;
    }
    filter_body(c, tol, min_steps, cand)
}

/// [`filter_body`] compiled for AVX2 (called only where the processor has it).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn filter_avx2(c: &Samples, tol: f64, min_steps: usize, cand: &mut Candidates) {
    filter_body(c, tol, min_steps, cand)
}

/// The filter itself ([`filter_windows`]); inlined into each of its two callers so that
/// each is compiled for its own instruction set.
#[inline(always)]
fn filter_body(c: &Samples, tol: f64, min_steps: usize, cand: &mut Candidates) {
    let n = c.n;
    let (x2, y2) = (&c.x, &c.y);
    let (vx2, vy2) = (&c.vx, &c.vy);
    let (x0, y0) = (&x2[..n], &y2[..n]);
    let mut sx = vec![0.0; n];
    let mut sy = vec![0.0; n];
    let mut sxx = vec![0.0; n];
    let mut sxy = vec![0.0; n];
    let mut syy = vec![0.0; n];
    let mut szx = vec![0.0; n];
    let mut szy = vec![0.0; n];
    // Per start of the current length: the filter's circle (centre about the first
    // sample, radius²) and whether the winding decides.
    let (mut ca, mut cb, mut cr2) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut wind = vec![false; n];
    // |V|², taken twice round like the samples.
    let speed2: Vec<f64> = vx2
        .iter()
        .zip(vy2)
        .map(|(ux, uy)| ux * ux + uy * uy)
        .collect();
    let lo_f = (1.0 - 1.001 * tol - 1e-9).max(0.0).powi(2);
    let hi_f = (1.0 + 1.001 * tol + 1e-9).powi(2);
    for l in 1..n {
        let (xl, yl) = (&x2[l..l + n], &y2[l..l + n]);
        for i in 0..n {
            let (x, y) = (xl[i] - x0[i], yl[i] - y0[i]);
            let (xx, xy, yy) = (x * x, x * y, y * y);
            let z = xx + yy;
            sx[i] += x;
            sy[i] += y;
            sxx[i] += xx;
            sxy[i] += xy;
            syy[i] += yy;
            szx[i] += z * x;
            szy[i] += z * y;
        }
        if l < min_steps {
            continue;
        }
        let m = (l + 1) as f64;
        let inv_m = 1.0 / m;
        let h = l / 2;
        let (xh, yh) = (&x2[h..h + n], &y2[h..h + n]);
        let (ux0, uy0) = (&vx2[..n], &vy2[..n]);
        let (uxh, uyh) = (&vx2[h..h + n], &vy2[h..h + n]);
        let (uxl, uyl) = (&vx2[l..l + n], &vy2[l..l + n]);
        let (v0, vh, vl) = (&speed2[..n], &speed2[h..h + n], &speed2[l..l + n]);
        let pass = cand.row_mut(l);
        // First the circles and the radial test, for every start (vectorised); then the
        // winding, only where it decides (a fitted, trusted circle that holds the three
        // samples: about one window in seven). The same arithmetic as one pass, so the
        // same windows pass: `(round & !(trusted & reverses)) | !fitted`.
        for i in 0..n {
            let (mx, my) = (sx[i] * inv_m, sy[i] * inv_m);
            let sz = sxx[i] + syy[i];
            let cxx = sxx[i] - sx[i] * mx;
            let cxy = sxy[i] - sx[i] * my;
            let cyy = syy[i] - sy[i] * my;
            let czx = szx[i] - sz * mx;
            let czy = szy[i] - sz * my;
            let det = cxx * cyy - cxy * cxy;
            let scale = cxx + cyy;
            let inv_det = 1.0 / det;
            let d = -(czx * cyy - czy * cxy) * inv_det;
            let e = -(cxx * czy - cxy * czx) * inv_det;
            let f = -(sz + d * sx[i] + e * sy[i]) * inv_m;
            let (a, b) = (-0.5 * d, -0.5 * e);
            let r2 = a * a + b * b - f;
            let (lo, hi) = (r2 * lo_f, r2 * hi_f);
            // The first sample is the origin; then the middle and the last.
            let d0 = a * a + b * b;
            let (hx, hy) = (xh[i] - x0[i] - a, yh[i] - y0[i] - b);
            let dh = hx * hx + hy * hy;
            let (ex, ey) = (xl[i] - x0[i] - a, yl[i] - y0[i] - b);
            let de = ex * ex + ey * ey;
            let round = (lo <= d0) & (d0 <= hi) & (lo <= dh) & (dh <= hi) & (lo <= de) & (de <= hi);
            let fitted = (det > 1e-9 * scale * scale) & (r2 > 0.0);
            let trusted = det > 1e-4 * scale * scale;
            pass[i] = round | !fitted;
            wind[i] = round & fitted & trusted;
            ca[i] = a;
            cb[i] = b;
            cr2[i] = r2;
        }
        for i in set_bits(&wind) {
            let (a, b, r2) = (ca[i], cb[i], cr2[i]);
            let (hx, hy) = (xh[i] - x0[i] - a, yh[i] - y0[i] - b);
            let (ex, ey) = (xl[i] - x0[i] - a, yl[i] - y0[i] - b);
            // Winding at the three samples: (M − c) × V, and (its margin)² over |V|².
            let w0 = -a * uy0[i] + b * ux0[i];
            let wh = hx * uyh[i] - hy * uxh[i];
            let we = ex * uyl[i] - ey * uxl[i];
            let margin = 4e-12 * r2;
            let (p0, ph, pe) = (
                w0 * w0 > margin * v0[i],
                wh * wh > margin * vh[i],
                we * we > margin * vl[i],
            );
            let (s0, sh, se) = (w0 > 0.0, wh > 0.0, we > 0.0);
            let reverses = (p0 & ph & (s0 != sh)) | (p0 & pe & (s0 != se)) | (ph & pe & (sh != se));
            pass[i] = !reverses;
        }
    }
}

/// A window's circle if the window qualifies (the contract above): Kåsa's circle, the
/// winding sign, and Kåsa's largest deviation (absolute: divide by the radius). The conditions are tested
/// cheapest and most often failing first (the radial test on squared distances, the
/// winding, the exact deviation, the turn); all must hold, so the order changes nothing
/// but the cost.
fn qualifying(
    c: &Samples,
    i: usize,
    j: usize,
    limit: f64,
    min_turn: f64,
) -> Option<(Circle, f64, f64)> {
    let (xs, ys) = c.window(i, j)?;
    let k = kasa_circle(xs, ys)?;
    // |‖M − c‖ − R| ≤ limit·R ⟺ (R(1 − limit))² ≤ ‖M − c‖² ≤ (R(1 + limit))²: a cheap
    // test first (ends first, where a window usually fails), the exact maximum after.
    let (lo, hi) = (
        (k.radius * (1.0 - limit)).max(0.0).powi(2),
        (k.radius * (1.0 + limit)).powi(2),
    );
    let m = xs.len();
    let order = [0, m - 1, m / 2].into_iter().chain(1..m - 1);
    for q in order {
        let d2 = (xs[q] - k.center[0]).powi(2) + (ys[q] - k.center[1]).powi(2);
        if !(lo * (1.0 - 1e-12) <= d2 && d2 <= hi * (1.0 + 1e-12)) {
            return None;
        }
    }
    let sign = winding(c, i, j, k.center);
    if sign == 0.0 {
        return None;
    }
    let dev = k.max_deviation(xs, ys);
    if dev.is_nan() || dev > limit * k.radius {
        return None;
    }
    if turn(c, i, j, k.center, sign, min_turn) < min_turn {
        return None;
    }
    Some((k, sign, dev))
}

/// The pseudo-arcs of a closed curve sampled every `tol.step_deg` from θ = 0: the maximal
/// qualifying windows (module documentation). The reported circle is the geometric one
/// ([`fit_circle`], least squares on distances, started from Kåsa's) when it deviates less
/// than Kåsa's and also runs one way round its centre turning at least
/// `arc_min_turn_deg`; otherwise Kåsa's. So `deviation_pct ≤ arc_pct` always holds.
pub fn pseudo_arcs(c: &Curve, tol: &FeatureTolerances, dash: &DashPattern) -> Vec<PseudoArc> {
    let n = c.len();
    if n < 4 {
        return Vec::new();
    }
    let limit = tol.arc_pct / 100.0;
    let min_turn = tol.arc_min_turn_deg.to_radians();
    let min_steps = (tol.arc_min_span_deg / tol.step_deg - 1e-9).ceil().max(2.0) as usize;
    let samples = Samples::new(c);
    let c = &samples;
    let mut cand = Candidates::new(n, true);
    filter_windows(c, limit, min_steps, &mut cand);
    // The exact test's answers, kept for the windows chosen (the same answers again).
    let mut found: Vec<(usize, usize, Circle, f64, f64)> = Vec::new();
    let chosen = cand.pick(
        |i, j| (j - i) as f64,
        1.0,
        min_steps as f64,
        usize::MAX,
        |i, j| {
            let (k, sign, dev) = qualifying(c, i, j, limit, min_turn)?;
            found.push((i, j, k, sign, dev));
            Some(dev / k.radius)
        },
    );
    chosen
        .into_iter()
        .filter_map(|w| {
            let (i, j) = (w.start, w.end);
            let &(_, _, k, k_sign, k_dev) = found.iter().find(|f| (f.0, f.1) == (i, j))?;
            let (xs, ys) = c.window(i, j)?;
            let geometric = fit_circle(xs, ys, Some(k), &CircleFitOptions::DEFAULT)
                .map(|g| (g, g.max_deviation(xs, ys)))
                .filter(|&(g, g_dev)| g_dev / g.radius < k_dev / k.radius)
                .and_then(|(g, g_dev)| {
                    let sign = winding(c, i, j, g.center);
                    if sign == 0.0 {
                        return None;
                    }
                    let turned = turn(c, i, j, g.center, sign, f64::INFINITY);
                    (turned >= min_turn).then_some((g, sign, g_dev, turned))
                });
            let (circle, sign, dev, turned) = match geometric {
                Some(g) => g,
                None => (
                    k,
                    k_sign,
                    k_dev,
                    turn(c, i, j, k.center, k_sign, f64::INFINITY),
                ),
            };
            let span = (j - i) as f64 * tol.step_deg;
            Some(PseudoArc {
                start_deg: i as f64 * tol.step_deg,
                span_deg: span,
                dashes: dash_count(span, dash),
                center: circle.center,
                radius: circle.radius,
                deviation_pct: dev / circle.radius * 100.0,
                turn_deg: turned.to_degrees(),
                // (M − c) × V > 0: counter-clockwise about c, so c is on the left.
                concave: if sign > 0.0 { Side::Left } else { Side::Right },
                // Filled by the extractor, which knows the mechanism.
                transmission_deg: None,
            })
        })
        .collect()
}
