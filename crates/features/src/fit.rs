//! Least-squares fits of a line and a circle to sampled points, shared by the window
//! measures ([`crate::WindowMeasures`]) and feature extraction.

use nalgebra::Vector3;

/// Running sums for an orthogonal (total) least-squares line fit, kept about a fixed
/// reference point so that adding and removing samples does not lose digits.
///
/// The fitted line passes through the centroid `G` with direction `d = (cos φ, sin φ)`,
/// `φ = ½·atan2(2·Sxy, Sxx − Syy)` (the major axis of the scatter matrix: Pearson 1901).
/// For points all on one spot (`Sxx = Syy = Sxy = 0`) the direction is `φ = 0`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LineSums {
    origin: [f64; 2],
    n: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
}

impl LineSums {
    /// Empty sums about `origin` (pick a point near the data, e.g. the curve's centroid).
    pub fn new(origin: [f64; 2]) -> LineSums {
        LineSums {
            origin,
            ..LineSums::default()
        }
    }

    /// Adds the point (x, y).
    #[inline]
    pub fn add(&mut self, x: f64, y: f64) {
        let (x, y) = (x - self.origin[0], y - self.origin[1]);
        self.n += 1.0;
        self.sx += x;
        self.sy += y;
        self.sxx += x * x;
        self.sxy += x * y;
        self.syy += y * y;
    }

    /// Removes the point (x, y) (which must have been added).
    #[inline]
    pub fn remove(&mut self, x: f64, y: f64) {
        let (x, y) = (x - self.origin[0], y - self.origin[1]);
        self.n -= 1.0;
        self.sx -= x;
        self.sy -= y;
        self.sxx -= x * x;
        self.sxy -= x * y;
        self.syy -= y * y;
    }

    /// The number of points.
    pub fn count(&self) -> usize {
        self.n as usize
    }

    /// The centroid and the unit direction of the fitted line. `None` if empty.
    pub fn line(&self) -> Option<([f64; 2], [f64; 2])> {
        if self.n < 1.0 {
            return None;
        }
        let (mx, my) = (self.sx / self.n, self.sy / self.n);
        let cxx = self.sxx - self.n * mx * mx;
        let cxy = self.sxy - self.n * mx * my;
        let cyy = self.syy - self.n * my * my;
        let phi = 0.5 * libm::atan2(2.0 * cxy, cxx - cyy);
        Some((
            [mx + self.origin[0], my + self.origin[1]],
            [libm::cos(phi), libm::sin(phi)],
        ))
    }
}

/// The angle of a vector in degrees, in (−180, 180] (so −0 and the −x axis give 180).
pub fn angle_deg(d: [f64; 2]) -> f64 {
    let a = libm::atan2(d[1], d[0]).to_degrees();
    if a <= -180.0 { a + 360.0 } else { a }
}

/// `‖(dx, dy)‖` as `sqrt(dx² + dy²)`, without `hypot`'s guard against overflow and
/// underflow (and its extra-precise rounding), which costs several times the `sqrt`.
/// Safe for what it measures here: distances of a window's samples from a circle's
/// centre, within a few radii of it. **Overflow:** a square overflows only for a
/// distance beyond 1e154, and the Kåsa circle every arc and fit starts from
/// ([`kasa_circle`], the filter's sums) already squares distances of the same size
/// (`z = x² + y²` about the window's mean), so such a window fails there first, as it
/// did with `hypot`. **Underflow:** a square that underflows is that of a distance below
/// 1e-154, which then moves a deviation or a residual by less than that; a distance of
/// exactly 0 is skipped where it is divided by. **Rounding:** at most about 1.5 ulp
/// against `hypot`'s 1, a change of ≈ 1e-16 of the radius in a deviation, against
/// tolerances of 1e-3 of it and more: results can differ from `hypot`'s in the last
/// digits, never beyond the documented tolerances.
#[inline]
pub(crate) fn dist(dx: f64, dy: f64) -> f64 {
    (dx * dx + dy * dy).sqrt()
}

/// A circle: centre and radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle {
    /// Centre.
    pub center: [f64; 2],
    /// Radius (> 0).
    pub radius: f64,
}

impl Circle {
    /// Largest radial deviation `max |‖p − c‖ − R|` over the points (distances by
    /// `sqrt(dx² + dy²)`: see `dist`).
    pub fn max_deviation(&self, xs: &[f64], ys: &[f64]) -> f64 {
        xs.iter()
            .zip(ys)
            .map(|(&x, &y)| (dist(x - self.center[0], y - self.center[1]) - self.radius).abs())
            .fold(0.0, f64::max)
    }

    /// True when centre and radius are finite and the radius positive.
    pub fn is_finite(&self) -> bool {
        self.center[0].is_finite()
            && self.center[1].is_finite()
            && self.radius.is_finite()
            && self.radius > 0.0
    }
}

/// Tolerances of the circle fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CircleFitOptions {
    /// Iteration cap of the Levenberg–Marquardt refinement.
    pub max_iterations: usize,
    /// Stop when the step in (a, b, R) is below this times the radius (or the cost stops
    /// decreasing by more than 1e-12 of itself).
    pub relative_step: f64,
    /// Reject a circle whose radius exceeds this many times the points' spread (the points
    /// are then on a line, not an arc).
    pub max_radius_ratio: f64,
}

impl CircleFitOptions {
    /// The default: 50 iterations, relative step 1e-12, radius at most 1e6 × spread.
    pub const DEFAULT: CircleFitOptions = CircleFitOptions {
        max_iterations: 50,
        relative_step: 1e-12,
        max_radius_ratio: 1e6,
    };
}

impl Default for CircleFitOptions {
    fn default() -> Self {
        CircleFitOptions::DEFAULT
    }
}

/// The algebraic circle of Kåsa (1976): minimise `Σ (x² + y² + D·x + E·y + F)²`, a linear
/// least-squares problem, solved in coordinates centred on the points' mean. Biased
/// towards small radii on short arcs, so it only starts [`fit_circle`]. `None` for fewer
/// than three points or collinear points.
pub fn kasa_circle(xs: &[f64], ys: &[f64]) -> Option<Circle> {
    let n = xs.len();
    if n < 3 || ys.len() != n {
        return None;
    }
    let mx = xs.iter().sum::<f64>() / n as f64;
    let my = ys.iter().sum::<f64>() / n as f64;
    // Centred, Σx = Σy = 0, so the normal equations split: F = −Σz/n and
    // [Sxx Sxy; Sxy Syy]·(D, E) = −(Szx, Szy), with z = x² + y².
    let (mut sxx, mut sxy, mut syy, mut szx, mut szy, mut sz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let mut spread: f64 = 0.0;
    for (&x, &y) in xs.iter().zip(ys) {
        let (x, y) = (x - mx, y - my);
        spread = spread.max(x.abs()).max(y.abs());
        let z = x * x + y * y;
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        szx += z * x;
        szy += z * y;
        sz += z;
    }
    let det = sxx * syy - sxy * sxy;
    if spread == 0.0 || det == 0.0 {
        return None;
    }
    let d = -(szx * syy - szy * sxy) / det;
    let e = -(sxx * szy - sxy * szx) / det;
    let f = -sz / n as f64;
    let (a, b) = (-d / 2.0, -e / 2.0);
    let r2 = a * a + b * b - f;
    let c = Circle {
        center: [a + mx, b + my],
        radius: r2.max(0.0).sqrt(),
    };
    (c.is_finite() && c.radius < 1e12 * spread).then_some(c)
}

/// The geometric circle: minimise `Σ (‖p_k − c‖ − R)²` by Levenberg–Marquardt on
/// `(c_x, c_y, R)`, started from `start` (or from [`kasa_circle`]). Chernov, *Circular and
/// Linear Regression* (2010), ch. 4. Returns `None` for fewer than three points,
/// (nearly) collinear points (radius beyond `max_radius_ratio` × spread) or a failed start.
pub fn fit_circle(
    xs: &[f64],
    ys: &[f64],
    start: Option<Circle>,
    options: &CircleFitOptions,
) -> Option<Circle> {
    let n = xs.len();
    if n < 3 || ys.len() != n {
        return None;
    }
    let start = match start {
        Some(c) if c.is_finite() => c,
        _ => kasa_circle(xs, ys)?,
    };
    let spread = {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for (&x, &y) in xs.iter().zip(ys) {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        (x1 - x0).max(y1 - y0)
    };
    // The cost `Σ (‖p − c‖ − R)²` at `c`, and the normal equations' sums there
    // (`JᵀJ`: a00 a01 a02 a11 a12 a22, `Jᵀr`: g0 g1 g2), in one pass: a trial circle's
    // cost decides whether it is accepted, and its sums are the next iteration's, so each
    // iteration reads the points once. Each sum adds the same terms in the same order as
    // a pass of its own would.
    let eval = |c: &Circle| -> (f64, [f64; 9]) {
        let mut cost = 0.0;
        let (mut a00, mut a01, mut a02, mut a11, mut a12, mut a22) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut g0, mut g1, mut g2) = (0.0, 0.0, 0.0);
        for (&x, &y) in xs.iter().zip(ys) {
            let (dx, dy) = (x - c.center[0], y - c.center[1]);
            let d = dist(dx, dy);
            let r = d - c.radius;
            cost += r * r;
            if d == 0.0 {
                continue;
            }
            let (j0, j1) = (-dx / d, -dy / d); // j2 = −1
            a00 += j0 * j0;
            a01 += j0 * j1;
            a02 -= j0;
            a11 += j1 * j1;
            a12 -= j1;
            a22 += 1.0;
            g0 += j0 * r;
            g1 += j1 * r;
            g2 -= r;
        }
        (cost, [a00, a01, a02, a11, a12, a22, g0, g1, g2])
    };
    let mut c = start;
    let (mut f, mut sums) = eval(&c);
    let mut lambda = 1e-3;
    for _ in 0..options.max_iterations {
        let [a00, a01, a02, a11, a12, a22, g0, g1, g2] = sums;
        let jtj = [[a00, a01, a02], [a01, a11, a12], [a02, a12, a22]];
        let minus_jtr = [-g0, -g1, -g2];
        let mut accepted = false;
        for _ in 0..8 {
            let mut a = jtj;
            for (i, row) in a.iter_mut().enumerate() {
                row[i] *= 1.0 + lambda;
            }
            let Some(step) = solve3(a, minus_jtr) else {
                lambda *= 10.0;
                continue;
            };
            let step = Vector3::new(step[0], step[1], step[2]);
            let trial = Circle {
                center: [c.center[0] + step[0], c.center[1] + step[1]],
                radius: c.radius + step[2],
            };
            let (ft, trial_sums) = eval(&trial);
            if trial.radius > 0.0 && ft.is_finite() && ft <= f {
                // Converged: a tiny step, or no real decrease of the cost.
                let done = step.norm() <= options.relative_step * trial.radius.max(spread)
                    || f - ft <= 1e-12 * f;
                c = trial;
                f = ft;
                sums = trial_sums;
                lambda = (lambda * 0.1).max(1e-12);
                accepted = true;
                if done {
                    return finish(c, spread, options);
                }
                break;
            }
            lambda *= 10.0;
        }
        if !accepted {
            break;
        }
    }
    finish(c, spread, options)
}

/// `a·x = b` for a 3 × 3 `a` (rows), by LU with partial pivoting: the operations of
/// nalgebra's `a.lu().solve(&b)` (0.35: `LU::new`, `gauss_step(_swap)`, the two
/// triangular solves), written out for three rows, so every result is the same to the
/// bit (the test `solve3_is_nalgebras_lu_to_the_bit`), without the generic matrix code's
/// cost (it was ≈ 2.5 % of feature extraction, inside [`fit_circle`]). The pivot of a
/// column is its first entry of largest absolute value at or below the diagonal; a column
/// whose pivot is 0 is skipped; `None` where a diagonal entry of `U` is 0.
// Index loops, in nalgebra's order: the iterator forms measured 27 % more instructions in
// the fit (cachegrind).
#[allow(clippy::needless_range_loop)]
fn solve3(mut a: [[f64; 3]; 3], mut b: [f64; 3]) -> Option<[f64; 3]> {
    let mut swaps = [None; 3];
    for i in 0..3 {
        let (mut piv, mut max) = (i, a[i][i].abs());
        for (r, row) in a.iter().enumerate().skip(i + 1) {
            let v = row[i].abs();
            if v > max {
                max = v;
                piv = r;
            }
        }
        let diag = a[piv][i];
        if diag == 0.0 {
            continue;
        }
        if piv != i {
            swaps[i] = Some(piv);
            a.swap(i, piv);
        }
        let inv_diag = 1.0 / diag;
        for r in i + 1..3 {
            a[r][i] *= inv_diag;
        }
        for k in i + 1..3 {
            let p = a[i][k];
            for r in i + 1..3 {
                a[r][k] += -p * a[r][i];
            }
        }
    }
    for (i, s) in swaps.iter().enumerate() {
        if let Some(piv) = *s {
            b.swap(i, piv);
        }
    }
    // L (unit diagonal), then U.
    for i in 0..2 {
        let coeff = b[i];
        for r in i + 1..3 {
            b[r] += -coeff * a[r][i];
        }
    }
    for i in (0..3).rev() {
        let diag = a[i][i];
        if diag == 0.0 {
            return None;
        }
        let coeff = b[i] / diag;
        b[i] = coeff;
        for r in 0..i {
            b[r] += -coeff * a[r][i];
        }
    }
    Some(b)
}

fn finish(c: Circle, spread: f64, options: &CircleFitOptions) -> Option<Circle> {
    (c.is_finite() && c.radius <= options.max_radius_ratio * spread.max(f64::MIN_POSITIVE))
        .then_some(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn circle_through_exact_points() {
        let (cx, cy, r) = (1.5, -2.0, 3.25);
        let (xs, ys): (Vec<f64>, Vec<f64>) = (0..20)
            .map(|k| {
                let t = 0.05 * k as f64;
                (cx + r * libm::cos(t), cy + r * libm::sin(t))
            })
            .unzip();
        let c = fit_circle(&xs, &ys, None, &CircleFitOptions::DEFAULT).unwrap();
        assert!((c.center[0] - cx).abs() < 1e-10 && (c.center[1] - cy).abs() < 1e-10);
        assert!((c.radius - r).abs() < 1e-10);
        assert!(
            fit_circle(
                &[0.0, 1.0, 2.0],
                &[0.0, 1.0, 2.0],
                None,
                &CircleFitOptions::DEFAULT
            )
            .is_none()
        );
    }

    /// [`solve3`] gives nalgebra's `lu().solve()` to the bit: random systems (entries of
    /// mixed signs and sizes 10⁻³⁰⁰…10³⁰⁰, so that every pivot order occurs), damped
    /// normal equations like the fit's, ties between pivots, zero columns and rows,
    /// singular matrices, and NaN and infinite entries.
    #[test]
    #[allow(clippy::needless_range_loop)]
    fn solve3_is_nalgebras_lu_to_the_bit() {
        use nalgebra::Matrix3;
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            2.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MIN_POSITIVE,
            1e300,
        ];
        let mut value = |kind: u64| -> f64 {
            let r = next();
            match kind {
                0 => special[(r % special.len() as u64) as usize],
                1 => (r % 5) as f64 - 2.0,
                2 => {
                    let m = (r >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                    m * 10f64.powi((r % 601) as i32 - 300)
                }
                _ => (r >> 11) as f64 / (1u64 << 53) as f64 - 0.5,
            }
        };
        let (mut compared, mut solved) = (0, 0);
        for case in 0..200_000u64 {
            let kind = case % 4;
            let mut a = [[0.0; 3]; 3];
            for row in a.iter_mut() {
                for v in row.iter_mut() {
                    *v = value(kind);
                }
            }
            if case % 3 == 0 {
                // Symmetric and damped, like the fit's normal equations.
                for i in 0..3 {
                    for k in 0..i {
                        a[i][k] = a[k][i];
                    }
                    a[i][i] = a[i][i].abs() * (1.0 + 1e-3);
                }
            }
            let b = [value(kind), value(kind), value(kind)];
            let m = Matrix3::from_fn(|i, k| a[i][k]);
            let want = m.lu().solve(&Vector3::new(b[0], b[1], b[2]));
            let got = solve3(a, b);
            compared += 1;
            match (want, got) {
                (None, None) => {}
                (Some(w), Some(g)) => {
                    solved += 1;
                    for i in 0..3 {
                        assert!(
                            w[i].to_bits() == g[i].to_bits() || (w[i].is_nan() && g[i].is_nan()),
                            "case {case}: {a:?} {b:?}: {w:?} against {g:?}"
                        );
                    }
                }
                (w, g) => panic!("case {case}: {a:?} {b:?}: {w:?} against {g:?}"),
            }
        }
        assert!(solved > compared / 2, "{solved} of {compared}");
    }

    #[test]
    fn line_sums_add_remove() {
        let mut s = LineSums::new([10.0, 10.0]);
        for k in 0..10 {
            s.add(k as f64, 2.0 * k as f64 + 1.0);
        }
        s.add(100.0, -50.0);
        s.remove(100.0, -50.0);
        let (g, d) = s.line().unwrap();
        assert!((g[0] - 4.5).abs() < 1e-12 && (g[1] - 10.0).abs() < 1e-12);
        assert!((d[1] / d[0] - 2.0).abs() < 1e-12);
    }
}
