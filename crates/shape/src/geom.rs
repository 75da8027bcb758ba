//! Plane geometry for shape search, on points as complex numbers `x + i·y`: arc-length
//! resampling, centroids, the size of a target, and the complex least-squares similarity.
//! Pure and deterministic: square roots (correctly rounded) and the crate's `libm`-based
//! transcendentals only, never the platform's `hypot` or `atan2`.

use nalgebra::Complex;

/// A point (or vector) of the plane as a complex number `x + i·y`.
pub type C64 = Complex<f64>;

/// `|z|` by a correctly rounded square root (not the platform's `hypot`).
#[inline]
pub fn abs(z: C64) -> f64 {
    (z.re * z.re + z.im * z.im).sqrt()
}

/// The argument of `z` in radians, `(−π, π]`, from `libm`.
#[inline]
pub fn arg(z: C64) -> f64 {
    libm::atan2(z.im, z.re)
}

/// `e^{iφ}` for `φ` in radians, from `libm`.
#[inline]
pub fn cis(phi: f64) -> C64 {
    C64::new(libm::cos(phi), libm::sin(phi))
}

/// `e^{iφ}` for `φ` in degrees, exact at multiples of 90° ([`coupler_kinematics::sincos_deg`]).
#[inline]
pub fn cis_deg(deg: f64) -> C64 {
    let (s, c) = coupler_kinematics::sincos_deg(deg);
    C64::new(c, s)
}

/// The cumulative arc length of a polyline: `out[0] = 0`, `out[k] = out[k−1] + |z_k − z_{k−1}|`;
/// for a closed polyline one more entry holds the length back to the first point.
pub fn cumulative_length(z: &[C64], closed: bool) -> Vec<f64> {
    let mut out = Vec::with_capacity(z.len() + 1);
    cumulative_length_into(z, closed, &mut out);
    out
}

/// [`cumulative_length`] into `out` (its earlier contents replaced): the steps' lengths
/// first (independent of each other: the compiler vectorises them), then their running
/// sum, in order (the same additions).
fn cumulative_length_into(z: &[C64], closed: bool, out: &mut Vec<f64>) {
    let n = z.len();
    out.clear();
    out.push(0.0);
    out.extend(z.iter().skip(1).zip(z).map(|(&b, &a)| abs(b - a)));
    if closed && n > 0 {
        out.push(abs(z[0] - z[n - 1]));
    }
    let mut s = 0.0;
    for v in &mut out[1..] {
        s += *v;
        *v = s;
    }
}

/// The point at arc length `s` along a polyline with cumulative lengths `cum` (from
/// [`cumulative_length`]), by linear interpolation; `hint` is a segment index to start the
/// search from (returned updated, so that increasing `s` costs O(1) amortised). For a
/// closed polyline `cum` has one more entry than `z` and the last segment returns to z₀.
/// ([`resample`] does the same in its own loop; this is its reference in the tests.)
#[cfg(test)]
pub fn point_at(z: &[C64], cum: &[f64], s: f64, hint: &mut usize) -> C64 {
    let segs = cum.len() - 1;
    let mut k = (*hint).min(segs.saturating_sub(1));
    while k + 1 < segs && cum[k + 1] < s {
        k += 1;
    }
    while k > 0 && cum[k] > s {
        k -= 1;
    }
    *hint = k;
    let a = z[k];
    let b = z[(k + 1) % z.len()];
    let len = cum[k + 1] - cum[k];
    if len <= 0.0 {
        return a;
    }
    let t = ((s - cum[k]) / len).clamp(0.0, 1.0);
    a + (b - a) * t
}

/// `m` points evenly spaced in arc length along a polyline. Closed: `s_j = j·L/m`,
/// `j = 0 .. m−1` (the last point is not a repeat of the first); open: `s_j = j·L/(m−1)`,
/// both ends included. `None` for fewer than two points, `m < 2`, or zero length.
pub fn resample(z: &[C64], closed: bool, m: usize) -> Option<Vec<C64>> {
    let mut out = Vec::with_capacity(m);
    resample_into(z, closed, m, &mut Vec::new(), &mut out).then_some(out)
}

/// [`resample`] into `out` (its earlier contents replaced), with `cum` as room for the
/// cumulative lengths: false (and `out` unspecified) where `resample` gives `None`.
pub(crate) fn resample_into(
    z: &[C64],
    closed: bool,
    m: usize,
    cum: &mut Vec<f64>,
    out: &mut Vec<C64>,
) -> bool {
    if z.len() < 2 || m < 2 {
        return false;
    }
    cumulative_length_into(z, closed, cum);
    let Some(&total) = cum.last() else {
        return false;
    };
    if !(total > 0.0 && total.is_finite()) {
        return false;
    }
    let denom = if closed { m as f64 } else { (m - 1) as f64 };
    // [`point_at`] at `s_j = total · (j / denom)`, its search and interpolation in one loop
    // (the same operations): `k` is its hint, never past the last segment (`segs − 1`).
    let (n, segs) = (z.len(), cum.len() - 1);
    let mut k = 0;
    // `j` as a float counted up by ones: exact (j < 2⁵³), the same as `j as f64`.
    let mut jf = 0.0;
    out.clear();
    out.reserve(m);
    for _ in 0..m {
        let s = total * (jf / denom);
        jf += 1.0;
        while k + 1 < segs && cum[k + 1] < s {
            k += 1;
        }
        while k > 0 && cum[k] > s {
            k -= 1;
        }
        let a = z[k];
        let len = cum[k + 1] - cum[k];
        out.push(if len <= 0.0 {
            a
        } else {
            let b = z[if k + 1 < n { k + 1 } else { (k + 1) % n }];
            let t = ((s - cum[k]) / len).clamp(0.0, 1.0);
            a + (b - a) * t
        });
    }
    true
}

/// The mean of the points.
pub fn mean(z: &[C64]) -> C64 {
    let mut s = C64::new(0.0, 0.0);
    for &p in z {
        s += p;
    }
    s / z.len().max(1) as f64
}

/// The diameter of a point set: the largest distance between two of its points (on the
/// convex hull, by Andrew's monotone chain; O(n log n + h²)). Invariant under rotation and
/// translation, proportional to scale, and nearly independent of how densely a path is
/// sampled: this is the **size** of a target that fit errors are quoted against.
pub fn diameter(z: &[C64]) -> f64 {
    let hull = convex_hull(z);
    let mut best = 0.0f64;
    for i in 0..hull.len() {
        for j in i + 1..hull.len() {
            best = best.max(abs(hull[i] - hull[j]));
        }
    }
    best
}

/// The convex hull (Andrew's monotone chain), counter-clockwise, without repeats.
fn convex_hull(z: &[C64]) -> Vec<C64> {
    let mut p: Vec<C64> = z.to_vec();
    p.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross =
        |o: C64, a: C64, b: C64| (a.re - o.re) * (b.im - o.im) - (a.im - o.im) * (b.re - o.re);
    let mut hull: Vec<C64> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &C64>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// The similarity `w ≈ a·z + b` (complex `a` = scale·e^{i·rotation}, `b` = translation)
/// that minimises `Σ |a·z_k + b − w_k|²`: with centroids `z̄`, `w̄`,
/// `a = Σ conj(z_k − z̄)(w_k − w̄) / Σ |z_k − z̄|²`, `b = w̄ − a·z̄` (the complex form of
/// Procrustes analysis; Dryden & Mardia, *Statistical Shape Analysis*, §4.1). Returns
/// `(a, b, residual sum of squares)`; `None` when the `z` are all one point.
pub fn fit_similarity(z: &[C64], w: &[C64]) -> Option<(C64, C64, f64)> {
    let (zm, wm) = (mean(z), mean(w));
    let mut num = C64::new(0.0, 0.0);
    let mut den = 0.0;
    let mut ww = 0.0;
    for (&p, &q) in z.iter().zip(w) {
        let (p, q) = (p - zm, q - wm);
        num += p.conj() * q;
        den += p.norm_sqr();
        ww += q.norm_sqr();
    }
    if den <= 0.0 {
        return None;
    }
    let a = num / den;
    let rss = (ww - num.norm_sqr() / den).max(0.0);
    Some((a, wm - a * zm, rss))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resample_is_point_at_by_point_at() {
        // `resample`'s one loop against `point_at` called at each arc length, bit for bit,
        // on open and closed random polylines (some with repeated points: zero-length steps).
        let mut rng = crate::cases::SplitMix64(23);
        for n in [2, 3, 7, 40, 720] {
            let mut z: Vec<C64> = (0..n)
                .map(|_| C64::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0)))
                .collect();
            if n > 3 {
                z[2] = z[1];
            }
            for closed in [false, true] {
                for m in [2, 5, 256, 1000] {
                    let got = resample(&z, closed, m).unwrap();
                    let cum = cumulative_length(&z, closed);
                    let total = *cum.last().unwrap();
                    let denom = if closed { m as f64 } else { (m - 1) as f64 };
                    let mut hint = 0;
                    let want: Vec<C64> = (0..m)
                        .map(|j| point_at(&z, &cum, total * (j as f64 / denom), &mut hint))
                        .collect();
                    let bits = |v: &[C64]| -> Vec<(u64, u64)> {
                        v.iter().map(|c| (c.re.to_bits(), c.im.to_bits())).collect()
                    };
                    assert_eq!(bits(&got), bits(&want), "{n} points, closed {closed}, {m}");
                }
            }
        }
    }

    #[test]
    fn resample_square() {
        let sq = [
            C64::new(0.0, 0.0),
            C64::new(1.0, 0.0),
            C64::new(1.0, 1.0),
            C64::new(0.0, 1.0),
        ];
        let r = resample(&sq, true, 8).unwrap();
        assert_eq!(r[1], C64::new(0.5, 0.0));
        assert_eq!(r[4], C64::new(1.0, 1.0));
        assert_eq!(r[7], C64::new(0.0, 0.5));
        let open = resample(&sq, false, 7).unwrap();
        assert_eq!(open[0], sq[0]);
        assert_eq!(open[6], sq[3]);
        assert_eq!(open[3], C64::new(1.0, 0.5));
        assert!(resample(&sq[..1], true, 8).is_none());
        assert!(resample(&[sq[0], sq[0]], false, 8).is_none());
    }

    #[test]
    fn diameter_and_similarity() {
        let pts: Vec<C64> = (0..50).map(|k| cis_deg(k as f64 * 7.2) * 2.0).collect();
        assert!((diameter(&pts) - 4.0).abs() < 1e-12);
        let a = C64::new(0.3, -1.7);
        let b = C64::new(5.0, 2.0);
        let w: Vec<C64> = pts.iter().map(|&z| a * z + b).collect();
        let (fa, fb, rss) = fit_similarity(&pts, &w).unwrap();
        assert!((fa - a).norm_sqr() < 1e-26 && (fb - b).norm_sqr() < 1e-24 && rss < 1e-20);
    }
}
