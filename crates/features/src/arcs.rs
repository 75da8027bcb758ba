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
use crate::maximal::Candidates;
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

/// The filter of every window at once ([`Filter`]), all flags set: the tests'
/// reference for the greedy choice's lazy use of it.
#[cfg(test)]
fn filter_windows(c: &Samples, tol: f64, min_steps: usize, cand: &mut Candidates) {
    let mut circles = Vec::new();
    let filter = Filter::new(c, tol, min_steps, &mut circles);
    for l in min_steps.max(1)..c.n {
        filter.starts(l, 0, cand.row_mut(l));
    }
}

/// The O(1) filter of every window of a closed curve of `n` samples, for every start at
/// once (structure of arrays, so the compiler vectorises it): Kåsa's sums of the window
/// `[i, i + l]` about its first sample ([`KasaSums`]: running fit sums, so that a small
/// window far from the origin keeps its digits), grown by one sample per round of `l`;
/// from them its circle, and whether that circle holds the window's first, middle and
/// last samples within the tolerance (0.1 % slack on it, and more than the rounding of a
/// circle fitted from sums), and whether the point runs one way round that circle's
/// centre at those three samples, all branch-free.
/// Windows whose samples are (nearly) collinear pass, and so do windows more than 1000
/// of their radii from the origin: the exact test decides those.
///
/// **How close the two circles are.** The exact test fits [`kasa_circle`] directly (the
/// samples' mean, then sums about it); the filter solves the same centred normal
/// equations from its running sums. Both differ from the circle through the samples only
/// by rounding, `κ·O(m·ε)·R` with `κ` the condition number of the 2 × 2 scatter matrix,
/// plus, for the direct fit, the rounding of its mean, `O(ε·|x̄|)`, which it then treats
/// as exact (its split normal equations take `Σ(x − x̄) = 0`), amplified by `κ`: the
/// direct fit, not the running sums, loses digits far from the origin (the tests:
/// `running_sums_are_the_more_exact_far_from_the_origin`). Hence the limit of 1000 radii.
/// Within it, `running_sums_circle_matches_the_direct_fit` measures the two on hard
/// cases (circles, wobbles near the tolerance, a 1000:1 ellipse's nearly straight sides,
/// four-bar curves, all also moved up to 10⁹ from the origin): centres within 6·10⁻¹²·R
/// where the filter trusts its centre, radii within 1.2·10⁻⁶ (half the radial slack is
/// asserted), and `filter_passes_every_qualifying_window` checks every window of them.
///
/// **Why the winding filter never rejects a qualifying window.** The exact test takes the
/// winding about the direct fit's centre `c`, the filter about its own `c'`. The filter
/// trusts its centre only where `κ ≤ 10⁴` (`det > 10⁻⁴·scale²`; the exact test decides
/// the rest) and the window is within 1000 radii of the origin, so `|c − c'| < 10⁻⁹·R`
/// there, and it rejects a window only when two of the three samples have cross products
/// `(M − c')×V` of opposite signs, each larger in size than `10⁻⁶·2R·|V|`: moving the
/// centre by less than that cannot change either sign (`|δ×V| ≤ |δ|·|V|`), so the window
/// does not run one way round `c` either.
///
/// **Four lanes where the processor has them.** On x86-64 with AVX2 (checked at run
/// time) the same code is compiled for AVX2 and run instead: the compiler packs four
/// windows per instruction instead of two. Rust never fuses a multiply and an add without
/// being asked, and every lane does the same IEEE-754 operations in the same order, so
/// every window passes or fails exactly as on the baseline path (the features bench's
/// fingerprint is the same either way).
///
/// **In two passes, the second only where it is read.** The first pass
/// ([`Filter::new`]) grows every start's sums through every length and keeps every
/// window's circle; the second ([`Filter::starts`]) tests the windows of one length from
/// a run of starts, and the greedy choice runs it as it reaches each length, only on the
/// starts whose window shares no step with a window already chosen
/// ([`Candidates::pick_filtering`]): the others it would skip unread. Each pass does,
/// window for window, the operations it did when both ran on every window, so every
/// window tested passes or fails as before and the same windows are chosen.
struct Filter<'a> {
    c: &'a Samples,
    min_steps: usize,
    /// The circles by length from `min_steps`, then by start (`n` a length): centre
    /// about the first sample, radius², and the scatter matrix's determinant and trace.
    ca: &'a [f64],
    cb: &'a [f64],
    cr2: &'a [f64],
    cdet: &'a [f64],
    cscale: &'a [f64],
    /// |V|², taken twice round like the samples.
    speed2: Vec<f64>,
    /// |M|² of each start: a window more than 1000 radii from the origin is not filtered
    /// (the direct fit the exact test uses loses digits there: see above).
    far2: Vec<f64>,
    lo_f: f64,
    hi_f: f64,
}

impl<'a> Filter<'a> {
    /// The first pass, its circles kept in `buf` (grown as needed; entries not read
    /// before they are written, so not cleared).
    fn new(c: &'a Samples, tol: f64, min_steps: usize, buf: &'a mut Vec<f64>) -> Filter<'a> {
        let n = c.n;
        let min_steps = min_steps.max(1);
        let rows = n.saturating_sub(min_steps);
        if buf.len() < 5 * rows * n {
            buf.resize(5 * rows * n, 0.0);
        }
        let (ca, rest) = buf.split_at_mut(rows * n);
        let (cb, rest) = rest.split_at_mut(rows * n);
        let (cr2, rest) = rest.split_at_mut(rows * n);
        let (cdet, rest) = rest.split_at_mut(rows * n);
        let cscale = &mut rest[..rows * n];
        circles(c, min_steps, ca, cb, cr2, cdet, cscale);
        let speed2: Vec<f64> =
            c.vx.iter()
                .zip(&c.vy)
                .map(|(ux, uy)| ux * ux + uy * uy)
                .collect();
        let far2: Vec<f64> = c.x[..n]
            .iter()
            .zip(&c.y[..n])
            .map(|(x, y)| x * x + y * y)
            .collect();
        Filter {
            c,
            min_steps,
            ca,
            cb,
            cr2,
            cdet,
            cscale,
            speed2,
            far2,
            lo_f: (1.0 - 1.001 * tol - 1e-9).max(0.0).powi(2),
            hi_f: (1.0 + 1.001 * tol + 1e-9).powi(2),
        }
    }

    /// The second pass on the windows of `l` steps from starts `lo, lo + 1, …`
    /// (`l < n`, `lo + pass.len() ≤ n`): whether each passes. Windows shorter than
    /// `min_steps` are left as they are (not passing: the flags start `false`).
    fn starts(&self, l: usize, lo: usize, pass: &mut [bool]) {
        if l < self.min_steps {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if crate::has_avx2() {
            // SAFETY: `starts_avx2` needs AVX2, which the processor was just found to
            // have; it has no other requirement (the safe `starts_body` compiled for AVX2).
            #[allow(unsafe_code)]
            unsafe {
                starts_avx2(self, l, lo, pass)
            };
            return;
        }
        starts_body(self, l, lo, pass)
    }
}

/// The first pass ([`Filter::new`]): Kåsa's running sums of every start's windows grown
/// one sample per length, and from `min_steps` on their circles, into `out` (centre x,
/// y, radius², determinant, trace; by length from `min_steps`, then by start). (Five
/// slices as five arguments: the compiler then knows they do not overlap.)
fn circles(
    c: &Samples,
    min_steps: usize,
    ca: &mut [f64],
    cb: &mut [f64],
    cr2: &mut [f64],
    cdet: &mut [f64],
    cscale: &mut [f64],
) {
    #[cfg(target_arch = "x86_64")]
    if crate::has_avx2() {
        // SAFETY: `circles_avx2` needs AVX2, which the processor was just found to have;
        // it has no other requirement (it is the safe `circles_body` compiled for AVX2).
        #[allow(unsafe_code)]
        unsafe {
            circles_avx2(c, min_steps, ca, cb, cr2, cdet, cscale)
        };
        return;
    }
    circles_body(c, min_steps, ca, cb, cr2, cdet, cscale)
}

/// [`circles_body`] compiled for AVX2 (called only where the processor has it).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn circles_avx2(
    c: &Samples,
    min_steps: usize,
    ca: &mut [f64],
    cb: &mut [f64],
    cr2: &mut [f64],
    cdet: &mut [f64],
    cscale: &mut [f64],
) {
    circles_body(c, min_steps, ca, cb, cr2, cdet, cscale)
}

/// [`Filter::starts`]'s body compiled for AVX2 (called only where the processor has it).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn starts_avx2(f: &Filter<'_>, l: usize, lo: usize, pass: &mut [bool]) {
    starts_body(f, l, lo, pass)
}

/// The first pass itself ([`circles`]); inlined into each of its two callers so that
/// each is compiled for its own instruction set.
#[inline(always)]
fn circles_body(
    c: &Samples,
    min_steps: usize,
    ca: &mut [f64],
    cb: &mut [f64],
    cr2: &mut [f64],
    cdet: &mut [f64],
    cscale: &mut [f64],
) {
    let n = c.n;
    let (x2, y2) = (&c.x, &c.y);
    let (x0, y0) = (&x2[..n], &y2[..n]);
    let mut sx = vec![0.0; n];
    let mut sy = vec![0.0; n];
    let mut sxx = vec![0.0; n];
    let mut sxy = vec![0.0; n];
    let mut syy = vec![0.0; n];
    let mut szx = vec![0.0; n];
    let mut szy = vec![0.0; n];
    for l in 1..n {
        let (xl, yl) = (&x2[l..l + n], &y2[l..l + n]);
        if l < min_steps {
            for i in 0..n {
                let mut s = KasaSums {
                    sx: sx[i],
                    sy: sy[i],
                    sxx: sxx[i],
                    sxy: sxy[i],
                    syy: syy[i],
                    szx: szx[i],
                    szy: szy[i],
                };
                s.add(xl[i] - x0[i], yl[i] - y0[i]);
                (sx[i], sy[i], sxx[i], sxy[i], syy[i]) = (s.sx, s.sy, s.sxx, s.sxy, s.syy);
                (szx[i], szy[i]) = (s.szx, s.szy);
            }
            continue;
        }
        let m = (l + 1) as f64;
        let inv_m = 1.0 / m;
        let row = (l - min_steps) * n..(l - min_steps + 1) * n;
        let (ca, cb, cr2) = (
            &mut ca[row.clone()],
            &mut cb[row.clone()],
            &mut cr2[row.clone()],
        );
        let (cdet, cscale) = (&mut cdet[row.clone()], &mut cscale[row]);
        for i in 0..n {
            let mut s = KasaSums {
                sx: sx[i],
                sy: sy[i],
                sxx: sxx[i],
                sxy: sxy[i],
                syy: syy[i],
                szx: szx[i],
                szy: szy[i],
            };
            s.add(xl[i] - x0[i], yl[i] - y0[i]);
            (sx[i], sy[i], sxx[i], sxy[i], syy[i]) = (s.sx, s.sy, s.sxx, s.sxy, s.syy);
            (szx[i], szy[i]) = (s.szx, s.szy);
            let k = s.circle(inv_m);
            (ca[i], cb[i], cr2[i]) = (k.a, k.b, k.r2);
            (cdet[i], cscale[i]) = (k.det, k.scale);
        }
    }
}

/// The second pass itself ([`Filter::starts`]): the radial test and the winding at the
/// window's first, middle and last samples, `(round & !(trusted & reverses)) | !fitted`,
/// branch-free; inlined into each of its two callers.
#[inline(always)]
fn starts_body(f: &Filter<'_>, l: usize, lo: usize, pass: &mut [bool]) {
    let c = f.c;
    let (n, m) = (c.n, pass.len());
    let (x2, y2) = (&c.x, &c.y);
    let (vx2, vy2) = (&c.vx, &c.vy);
    let at = |k: usize| k + lo..k + lo + m;
    let h = l / 2;
    let (x0, y0) = (&x2[at(0)], &y2[at(0)]);
    let (xh, yh) = (&x2[at(h)], &y2[at(h)]);
    let (xl, yl) = (&x2[at(l)], &y2[at(l)]);
    let (ux0, uy0) = (&vx2[at(0)], &vy2[at(0)]);
    let (uxh, uyh) = (&vx2[at(h)], &vy2[at(h)]);
    let (uxl, uyl) = (&vx2[at(l)], &vy2[at(l)]);
    let sp = &f.speed2;
    let (v0, vh, vl) = (&sp[at(0)], &sp[at(h)], &sp[at(l)]);
    let far2 = &f.far2[lo..lo + m];
    let row = (l - f.min_steps) * n + lo..(l - f.min_steps) * n + lo + m;
    let (ca, cb, cr2) = (&f.ca[row.clone()], &f.cb[row.clone()], &f.cr2[row.clone()]);
    let (cdet, cscale) = (&f.cdet[row.clone()], &f.cscale[row]);
    let (lo_f, hi_f) = (f.lo_f, f.hi_f);
    // (One pass doing the sums and these tests, or the winding only where it decides,
    // measured 5–10 % slower for the arcs: each pass's chain of dependent operations is
    // shorter, so more starts are in flight at once.)
    for i in 0..m {
        let (a, b, r2, det, scale) = (ca[i], cb[i], cr2[i], cdet[i], cscale[i]);
        let (lo, hi) = (r2 * lo_f, r2 * hi_f);
        // The first sample is the origin; then the middle and the last.
        let d0 = a * a + b * b;
        let (hx, hy) = (xh[i] - x0[i] - a, yh[i] - y0[i] - b);
        let dh = hx * hx + hy * hy;
        let (ex, ey) = (xl[i] - x0[i] - a, yl[i] - y0[i] - b);
        let de = ex * ex + ey * ey;
        // Conditions as lane masks (all ones or zero), combined as such and made a
        // flag once: the compiler keeps them in the vector lanes.
        let round = mask(lo <= d0)
            & mask(d0 <= hi)
            & mask(lo <= dh)
            & mask(dh <= hi)
            & mask(lo <= de)
            & mask(de <= hi);
        let fitted = mask(det > 1e-9 * scale * scale) & mask(r2 > 0.0) & mask(far2[i] <= 1e6 * r2);
        let trusted = mask(det > 1e-4 * scale * scale);
        // Winding at the three samples: (M − c) × V, and (its margin)² over |V|².
        let w0 = -a * uy0[i] + b * ux0[i];
        let wh = hx * uyh[i] - hy * uxh[i];
        let we = ex * uyl[i] - ey * uxl[i];
        let margin = 4e-12 * r2;
        let (p0, ph, pe) = (
            mask(w0 * w0 > margin * v0[i]),
            mask(wh * wh > margin * vh[i]),
            mask(we * we > margin * vl[i]),
        );
        let (s0, sh, se) = (mask(w0 > 0.0), mask(wh > 0.0), mask(we > 0.0));
        let reverses = (p0 & ph & (s0 ^ sh)) | (p0 & pe & (s0 ^ se)) | (ph & pe & (sh ^ se));
        pass[i] = ((round & !(trusted & reverses)) | !fitted) != 0;
    }
}

thread_local! {
    /// Each thread's buffer for the filter's circles ([`Filter::new`]), kept from
    /// curve to curve: about 200 kB at 72 samples, written, not cleared, per curve.
    static CIRCLES: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Kåsa's sums of a window about its first sample (which is the origin of `x`, `y`),
/// grown one sample at a time: the filter's running fit sums ([`Filter`]).
#[derive(Clone, Copy, Debug, Default)]
struct KasaSums {
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
    szx: f64,
    szy: f64,
}

/// The filter's circle of a window: centre `(a, b)` about the window's first sample,
/// radius², and the centred scatter matrix's determinant and trace (how well the circle
/// is determined).
#[derive(Clone, Copy, Debug)]
struct FilterCircle {
    a: f64,
    b: f64,
    r2: f64,
    det: f64,
    scale: f64,
}

impl KasaSums {
    /// Adds the sample at `(x, y)` from the window's first sample.
    #[inline(always)]
    fn add(&mut self, x: f64, y: f64) {
        let (xx, xy, yy) = (x * x, x * y, y * y);
        let z = xx + yy;
        self.sx += x;
        self.sy += y;
        self.sxx += xx;
        self.sxy += xy;
        self.syy += yy;
        self.szx += z * x;
        self.szy += z * y;
    }

    /// Kåsa's circle of the `m = 1 / inv_m` samples summed: the centred normal equations
    /// ([`kasa_circle`]'s) with the centred sums taken from these, solved in closed form.
    /// Meaningless (infinite or NaN) where `det` is 0; the caller tests `det` first.
    #[inline(always)]
    fn circle(&self, inv_m: f64) -> FilterCircle {
        let (mx, my) = (self.sx * inv_m, self.sy * inv_m);
        let sz = self.sxx + self.syy;
        let cxx = self.sxx - self.sx * mx;
        let cxy = self.sxy - self.sx * my;
        let cyy = self.syy - self.sy * my;
        let czx = self.szx - sz * mx;
        let czy = self.szy - sz * my;
        let det = cxx * cyy - cxy * cxy;
        let scale = cxx + cyy;
        let inv_det = 1.0 / det;
        let d = -(czx * cyy - czy * cxy) * inv_det;
        let e = -(cxx * czy - cxy * czx) * inv_det;
        let f = -(sz + d * self.sx + e * self.sy) * inv_m;
        let (a, b) = (-0.5 * d, -0.5 * e);
        let r2 = a * a + b * b - f;
        FilterCircle {
            a,
            b,
            r2,
            det,
            scale,
        }
    }
}

/// A condition as a lane mask: all ones if it holds, else zero.
#[inline(always)]
fn mask(c: bool) -> u64 {
    u64::from(c).wrapping_neg()
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
    // The filter's circles, in this thread's buffer (kept from curve to curve).
    let mut buf = CIRCLES.with(|b| b.take());
    let filter = Filter::new(c, limit, min_steps, &mut buf);
    // The exact test's answers, kept for the windows chosen (the same answers again).
    let mut found: Vec<(usize, usize, Circle, f64, f64)> = Vec::new();
    let chosen = cand.pick_filtering(
        &mut |l, lo, pass| filter.starts(l, lo, pass),
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
    drop(filter);
    CIRCLES.with(|b| b.replace(buf));
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

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::{Circuit, CouplerPoint, CrankTable, FourBar, Mechanism};

    /// A closed curve of 72 samples (5° of crank) from positions and velocities at θ.
    fn closed(f: impl Fn(f64) -> [f64; 4]) -> Curve {
        let mut c = Curve::default();
        for k in 0..72 {
            let [x, y, vx, vy] = f((5.0 * k as f64).to_radians());
            c.x.push(x);
            c.y.push(y);
            c.vx.push(vx);
            c.vy.push(vy);
        }
        c
    }

    /// Curves where running sums are hardest to trust: far from the origin (up to 1e8
    /// radii), tiny and huge, nearly straight windows (radius of curvature 10⁶ times the
    /// width), deviations near the arc tolerance, and four-bar curves moved far away.
    fn hard_curves() -> Vec<(String, Curve)> {
        let mut out = Vec::new();
        for (off, r) in [(0.0, 1.0), (1e6, 1.0), (1e8, 1.0), (3.0, 1e-6), (-2e9, 1e3)] {
            out.push((
                format!("circle r={r} at {off}"),
                closed(|t| {
                    let (s, c) = (libm::sin(t), libm::cos(t));
                    [off + r * c, -off + r * s, -r * s, r * c]
                }),
            ));
            // A three-lobed wobble of 0.45 % (arcs just inside 0.5 %) and of 0.6 %.
            for w in [0.0045, 0.006] {
                out.push((
                    format!("wobble {w} r={r} at {off}"),
                    closed(|t| {
                        let (s, c) = (libm::sin(t), libm::cos(t));
                        let (s3, c3) = (libm::sin(3.0 * t), libm::cos(3.0 * t));
                        let rho = r * (1.0 + w * c3);
                        let drho = -3.0 * r * w * s3;
                        [
                            off + rho * c,
                            off + rho * s,
                            drho * c - rho * s,
                            drho * s + rho * c,
                        ]
                    }),
                ));
            }
            // A flat ellipse: windows along its sides are nearly straight.
            out.push((
                format!("ellipse 1000:1 r={r} at {off}"),
                closed(|t| {
                    let (s, c) = (libm::sin(t), libm::cos(t));
                    [off + 1000.0 * r * c, off + r * s, -1000.0 * r * s, r * c]
                }),
            ));
        }
        let table = CrankTable::new(5.0).unwrap();
        for (a, b, c) in [(2.5, 2.5, 2.0), (3.0, 2.5, 3.5), (4.0, 3.0, 5.0)] {
            let l = FourBar::new(a, b, c).unwrap();
            let poses = l.pose_table(Circuit::Open, &table);
            for (u, v) in [
                (1.0, 0.0),
                (2.5, 0.0),
                (1.25, 2.5),
                (-1.0, 1.5),
                (3.0, -2.0),
            ] {
                let curve = poses.trace(CouplerPoint::new(u, v));
                for off in [0.0, 1e5, 1e7] {
                    let mut moved = curve.clone();
                    moved.x.iter_mut().for_each(|x| *x += off);
                    moved.y.iter_mut().for_each(|y| *y -= off);
                    out.push((format!("four-bar {a},{b},{c} ({u},{v}) at {off}"), moved));
                }
            }
        }
        out
    }

    /// The filter's running sums, grown one sample at a time about the window's first
    /// sample, give the circle the direct fit ([`kasa_circle`], two passes about the
    /// samples' mean) gives, to within what the filter's soundness argument allows, on
    /// every window of the hard curves that the filter decides (fitted, and within 1000
    /// radii of the origin): radii within 2.5·10⁻⁶ (half the radial test's slack of 10⁻³ of the 0.5 % tolerance; the
    /// worst, 1.1·10⁻⁶, on nearly straight windows of a 1000:1 ellipse 10⁸ from the origin),
    /// and where it trusts its centre for the winding (`det > 10⁻⁴·scale²`) centres
    /// within 10⁻⁹ of the radius. Farther out the direct fit itself loses digits (its
    /// centring leaves `Σ(x − x̄)` at a few ulps of `|x̄|`, which its split normal
    /// equations take as 0): on a unit circle 10⁶ from the origin it is 10⁻⁷ off the
    /// circle through the samples, which the running sums give to 10⁻¹⁵.
    #[test]
    fn running_sums_circle_matches_the_direct_fit() {
        let (mut worst_c, mut worst_r, mut compared, mut far) = (0.0f64, 0.0f64, 0, 0);
        for (name, c) in hard_curves() {
            let n = c.len();
            let s = Samples::new(&c);
            for i in 0..n {
                let mut sums = KasaSums::default();
                for l in 1..n {
                    sums.add(s.x[i + l] - s.x[i], s.y[i + l] - s.y[i]);
                    if l < 6 {
                        continue;
                    }
                    let f = sums.circle(1.0 / (l + 1) as f64);
                    if !(f.det > 1e-9 * f.scale * f.scale && f.r2 > 0.0) {
                        continue;
                    }
                    if s.x[i] * s.x[i] + s.y[i] * s.y[i] > 1e6 * f.r2 {
                        far += 1;
                        continue;
                    }
                    let k = kasa_circle(&s.x[i..=i + l], &s.y[i..=i + l]).unwrap();
                    compared += 1;
                    let dr = (f.r2.sqrt() - k.radius).abs() / k.radius;
                    worst_r = worst_r.max(dr);
                    assert!(dr < 2.5e-6, "{name}, window {i}+{l}: radius off by {dr:e}");
                    if f.det > 1e-4 * f.scale * f.scale {
                        // The direct fit's centre about the same first sample.
                        let (ka, kb) = (k.center[0] - s.x[i], k.center[1] - s.y[i]);
                        let dc = (f.a - ka).hypot(f.b - kb) / k.radius;
                        worst_c = worst_c.max(dc);
                        assert!(dc < 1e-9, "{name}, window {i}+{l}: centre off by {dc:e} R");
                    }
                }
            }
        }
        assert!(compared > 100_000 && far > 10_000, "{compared} {far}");
        eprintln!("{compared} windows: centres within {worst_c:e} R, radii within {worst_r:e}");
    }

    /// The hard case behind the 1000-radii limit: the direct fit of three samples of a
    /// unit circle 10⁶ from the origin is 10⁻⁷ away from their circumcircle (computed
    /// exactly, by hand, from the same three `f64` samples), the running sums are not.
    #[test]
    fn running_sums_are_the_more_exact_far_from_the_origin() {
        let c = closed(|t| {
            let (s, c) = (libm::sin(t), libm::cos(t));
            [1e6 + c, -1e6 + s, -s, c]
        });
        let s = Samples::new(&c);
        let mut sums = KasaSums::default();
        for k in 1..3 {
            sums.add(s.x[k] - s.x[0], s.y[k] - s.y[0]);
        }
        let f = sums.circle(1.0 / 3.0);
        // The circumcentre of the three samples about the first, from their exact
        // differences (exact by Sterbenz's lemma) in 128-bit-free form: the samples
        // differ by less than 0.2, so the few roundings below are ≈ 1e-17 of it.
        let (bx, by) = (s.x[1] - s.x[0], s.y[1] - s.y[0]);
        let (cx, cy) = (s.x[2] - s.x[0], s.y[2] - s.y[0]);
        let d = 2.0 * (bx * cy - by * cx);
        let ux = (cy * (bx * bx + by * by) - by * (cx * cx + cy * cy)) / d;
        let uy = (bx * (cx * cx + cy * cy) - cx * (bx * bx + by * by)) / d;
        assert!(
            (f.a - ux).hypot(f.b - uy) < 1e-12,
            "{} {} {ux} {uy}",
            f.a,
            f.b
        );
        let k = kasa_circle(&s.x[..3], &s.y[..3]).unwrap();
        let (ka, kb) = (k.center[0] - s.x[0], k.center[1] - s.y[0]);
        assert!((ka - ux).hypot(kb - uy) > 1e-8, "{ka} {kb} {ux} {uy}");
    }

    /// The greedy choice filtering each length as it reaches it, only on the windows it
    /// reads, chooses the windows (and errors) it chooses with every window filtered
    /// first, on the hard curves (one buffer of circles for all, as a thread's is); and
    /// it filters fewer windows, so the comparison is not of two runs of one thing.
    #[test]
    fn filtering_as_chosen_chooses_the_same_windows() {
        let tol = FeatureTolerances::DEFAULT;
        let limit = tol.arc_pct / 100.0;
        let min_turn = tol.arc_min_turn_deg.to_radians();
        let min_steps = 6;
        let (mut chosen, mut filtered, mut all) = (0, 0, 0);
        let mut buf = Vec::new();
        for (name, c) in hard_curves() {
            let n = c.len();
            let s = Samples::new(&c);
            let exact = |i: usize, j: usize| {
                qualifying(&s, i, j, limit, min_turn).map(|(k, _, dev)| dev / k.radius)
            };
            let travel = |i: usize, j: usize| (j - i) as f64;
            let mut every = Candidates::new(n, true);
            filter_windows(&s, limit, min_steps, &mut every);
            let want = every.pick(travel, 1.0, min_steps as f64, usize::MAX, exact);
            let filter = Filter::new(&s, limit, min_steps, &mut buf);
            let mut lazy = Candidates::new(n, true);
            let got = lazy.pick_filtering(
                &mut |l, lo, pass| {
                    if l >= min_steps {
                        filtered += pass.len();
                    }
                    filter.starts(l, lo, pass)
                },
                travel,
                1.0,
                min_steps as f64,
                usize::MAX,
                exact,
            );
            assert_eq!(got, want, "{name}");
            chosen += want.len();
            all += n * (n - min_steps);
        }
        assert!(chosen > 100, "{chosen}");
        assert!(filtered < all, "{filtered} of {all}");
        eprintln!("{chosen} windows chosen; {filtered} of {all} windows filtered");
    }

    /// The filter never rejects a window the exact test accepts (the contract's
    /// qualifying windows), on the hard curves: every window of every start and length.
    #[test]
    fn filter_passes_every_qualifying_window() {
        let tol = FeatureTolerances::DEFAULT;
        let limit = tol.arc_pct / 100.0;
        let min_turn = tol.arc_min_turn_deg.to_radians();
        let min_steps = 6;
        let mut qualifying_windows = 0;
        for (name, c) in hard_curves() {
            let n = c.len();
            let s = Samples::new(&c);
            let mut cand = Candidates::new(n, true);
            filter_windows(&s, limit, min_steps, &mut cand);
            for i in 0..n {
                for l in min_steps..n {
                    if qualifying(&s, i, i + l, limit, min_turn).is_some() {
                        qualifying_windows += 1;
                        assert!(cand.passes(i, l), "{name}: window {i}+{l} rejected");
                    }
                }
            }
        }
        assert!(qualifying_windows > 10_000, "{qualifying_windows}");
    }
}
