//! Closed-form position and velocity of the four-bar at one crank angle.

use crate::frame::CouplerFrame;
use crate::linkage::{Circuit, CouplerPoint, FourBar};
use nalgebra::{Point2, Vector2};

/// A crank angle θ in degrees, with its sine and cosine (crank pin Pa = (cos θ, sin θ)).
///
/// The sine and cosine come from the pure-Rust `libm` after an exact reduction of the
/// degrees to `[−45°, 45°]`, so they are the same bits on every platform, and exact at
/// multiples of 90° (sin 180° = 0, not 1.2e-16).
///
/// ```
/// use coupler_kinematics::CrankAngle;
/// let t = CrankAngle::from_degrees(180.0);
/// assert_eq!((t.cos, t.sin), (-1.0, 0.0));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrankAngle {
    /// θ in degrees, as given.
    pub degrees: f64,
    /// cos θ.
    pub cos: f64,
    /// sin θ.
    pub sin: f64,
    /// sin(θ/2): with it, `C − cos θ = (C − 1) + 2·sin²(θ/2)` loses no digits near θ = 0.
    pub sin_half: f64,
    /// cos(θ/2): `1 + cos θ = 2·cos²(θ/2)` loses no digits near θ = 180°.
    pub cos_half: f64,
}

impl CrankAngle {
    /// The angle θ (degrees, any finite value).
    pub fn from_degrees(degrees: f64) -> CrankAngle {
        let (sin, cos) = sincos_deg(degrees);
        let (sin_half, cos_half) = sincos_deg(0.5 * degrees);
        CrankAngle {
            degrees,
            cos,
            sin,
            sin_half,
            cos_half,
        }
    }

    /// The crank pin Pa = (cos θ, sin θ).
    pub fn crank_pin(&self) -> Point2<f64> {
        Point2::new(self.cos, self.sin)
    }

    /// The crank pin's velocity dPa/dθ = (−sin θ, cos θ) (unit crank speed).
    pub fn crank_pin_velocity(&self) -> Vector2<f64> {
        Vector2::new(-self.sin, self.cos)
    }
}

/// `(sin, cos)` of an angle in degrees. The degrees are folded exactly (each subtraction
/// is exact by Sterbenz's lemma) onto `[0°, 45°]` by the symmetries `θ ↔ −θ`,
/// `θ ↔ 360° − θ`, `θ ↔ 180° − θ`, `θ ↔ 90° − θ`, then rounded once to radians. So the
/// result is deterministic across platforms (libm), exact at multiples of 90°, and has the
/// symmetries exactly (`sin(180° − θ) = sin θ` to the bit), which symmetric curves rely on.
pub fn sincos_deg(degrees: f64) -> (f64, f64) {
    let negative = degrees < 0.0;
    let mut r = turn_remainder(degrees.abs());
    let mut sin_sign = if negative { -1.0 } else { 1.0 };
    let mut cos_sign = 1.0;
    if r > 180.0 {
        r = 360.0 - r;
        sin_sign = -sin_sign;
    }
    if r > 90.0 {
        r = 180.0 - r;
        cos_sign = -1.0;
    }
    let swap = r > 45.0;
    if swap {
        r = 90.0 - r;
    }
    let x = r * (std::f64::consts::PI / 180.0);
    let (s, c) = if r == 0.0 {
        (0.0, 1.0)
    } else {
        libm_sin_cos(x)
    };
    let (s, c) = if swap { (c, s) } else { (s, c) };
    // `+ 0.0` turns a −0 into +0 so that sin 180° prints as 0.
    (sin_sign * s + 0.0, cos_sign * c + 0.0)
}

/// `x % 360.0` for `x ≥ 0` (or NaN), the same bits: the remainder is exact, so any exact
/// way to it gives the same value. Below 720° one subtraction is exact (Sterbenz's lemma:
/// `360 ≤ x ≤ 2·360`); further out, and for infinities and NaN, the library's `fmod`,
/// which is a loop of exact steps and costs tens of nanoseconds: the fits evaluate crank
/// angles by the million, almost all within a turn or two.
#[inline]
fn turn_remainder(x: f64) -> f64 {
    if x < 360.0 {
        x
    } else if x < 720.0 {
        x - 360.0
    } else {
        x % 360.0
    }
}

/// FreeBSD's `__kernel_sin(x, 0, 0)` for `2⁻²⁶ ≤ x ≤ π/4`, given `z = x²` and `w = z²`
/// (the notice is at [`libm_sin_cos`]): the expressions of `libm`'s `k_sin.rs`, inlined
/// so that the scalar path and the lanes of [`Pose::finite_points_with`] compute them
/// alike.
#[inline(always)]
#[allow(clippy::excessive_precision)] // libm's literals, digit for digit
fn kernel_sin(x: f64, z: f64, w: f64) -> f64 {
    const S1: f64 = -1.666_666_666_666_663_243_48e-1;
    const S2: f64 = 8.333_333_333_322_489_461_24e-3;
    const S3: f64 = -1.984_126_982_985_794_931_34e-4;
    const S4: f64 = 2.755_731_370_707_006_767_89e-6;
    const S5: f64 = -2.505_076_025_340_686_341_95e-8;
    const S6: f64 = 1.589_690_995_211_550_102_21e-10;
    let r = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    let v = z * x;
    x + v * (S1 + z * r)
}

/// FreeBSD's `__kernel_cos(x, 0)` for `2⁻²⁷·√2 ≤ x ≤ π/4`, given `z = x²` and `w = z²`
/// (the notice is at [`libm_sin_cos`]): the expressions of `libm`'s `k_cos.rs`.
#[inline(always)]
#[allow(clippy::excessive_precision)] // libm's literals, digit for digit
fn kernel_cos(x: f64, z: f64, w: f64) -> f64 {
    const C1: f64 = 4.166_666_666_666_660_190_37e-2;
    const C2: f64 = -1.388_888_888_887_410_957_49e-3;
    const C3: f64 = 2.480_158_728_947_672_941_78e-5;
    const C4: f64 = -2.755_731_435_139_066_330_35e-7;
    const C5: f64 = 2.087_572_321_298_174_827_90e-9;
    const C6: f64 = -1.135_964_755_778_819_482_65e-11;
    let r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let hw = 1.0 - hz;
    hw + (((1.0 - hw) - hz) + (z * r - x * 0.0))
}

/// `(libm::sin(x), libm::cos(x))`, the same bits, for the folded angles of
/// [`sincos_deg`] (`0 < x ≤ π/4`) with `libm`'s own kernels written out here, so that
/// they inline and the sine and cosine of a crank angle and of its half (four kernels)
/// overlap instead of running as four calls: they are a fifth of a shape fit's time.
/// Anything else (not reached from `sincos_deg`; NaN) goes to `libm` itself. A test
/// compares both with `libm` over millions of arguments.
///
/// The kernels and their coefficients are FreeBSD's `__kernel_sin` and `__kernel_cos`
/// (`k_sin.c`, `k_cos.c`, as the `libm` crate has them in `k_sin.rs`, `k_cos.rs`), under
/// this notice:
///
/// > Copyright (C) 1993 by Sun Microsystems, Inc. All rights reserved.
/// > Developed at SunPro, a Sun Microsystems, Inc. business. Permission to use, copy,
/// > modify, and distribute this software is freely granted, provided that this notice
/// > is preserved.
#[inline(always)]
fn libm_sin_cos(x: f64) -> (f64, f64) {
    // The high word of |x|, as libm tests it.
    let ix = (x.to_bits() >> 32) as u32 & 0x7fff_ffff;
    if !(x > 0.0 && ix <= 0x3fe9_21fb) {
        return (libm::sin(x), libm::cos(x));
    }
    let z = x * x;
    let w = z * z;
    // sin: x itself below 2⁻²⁶, else __kernel_sin(x, 0, 0).
    let sin = if ix < 0x3e50_0000 {
        x
    } else {
        kernel_sin(x, z, w)
    };
    // cos: 1 below 2⁻²⁷·√2, else __kernel_cos(x, 0).
    let cos = if ix < 0x3e46_a09e {
        1.0
    } else {
        kernel_cos(x, z, w)
    };
    (sin, cos)
}

/// How many crank angles [`Pose::finite_points_with`] evaluates at once.
pub const POINT_LANES: usize = 4;

/// [`sincos_deg`] for `|degrees| < 720` (the caller's test), without branches: every
/// fold and kernel computed and selected, the same operations in the same order, so the
/// same bits (a test compares them), and lanes of these run side by side.
#[inline(always)]
fn sincos_deg_select(degrees: f64) -> (f64, f64) {
    let a = degrees.abs();
    let r = if a < 360.0 { a } else { a - 360.0 };
    sincos_turn_select(r, degrees < 0.0)
}

/// [`sincos_deg_select`] for a half angle, `|degrees| < 360` (half of a lane's
/// `|θ| < 720°`), where its first fold, `a < 360`, always keeps `a`: the same operations
/// otherwise, so the same bits (a test compares them).
#[inline(always)]
fn sincos_half_deg_select(degrees: f64) -> (f64, f64) {
    sincos_turn_select(degrees.abs(), degrees < 0.0)
}

/// The sine and cosine of `±r` degrees for `r` in `[0°, 360°)` (`−` if `negative`), as
/// [`sincos_deg`] folds and evaluates them. Each fold `r ↦ K − r` (`K` = 360°, 180°,
/// 90°) is taken where `r > K/2`, which is where `K − r < r`: below `K/2` the rounded
/// `K − r` is at least `K/2 ≥ r`, above it the difference is exact (Sterbenz's lemma) and
/// below `K/2 < r`; so each fold is a minimum (one instruction in lanes) and its test the
/// same comparison. The signs are `sincos_deg`'s `±1` factors as flips of the sign bit
/// (a product by `−1` is exact: the same bits for the finite values here).
#[inline(always)]
fn sincos_turn_select(r: f64, negative: bool) -> (f64, f64) {
    let t = 360.0 - r;
    let over_half = t < r;
    let r = if over_half { t } else { r };
    let t = 180.0 - r;
    let over_quarter = t < r;
    let r = if over_quarter { t } else { r };
    let t = 90.0 - r;
    let swap = t < r;
    let r = if swap { t } else { r };
    let x = r * (std::f64::consts::PI / 180.0);
    // libm's tiny branches (`x` itself below 2⁻²⁶, 1 below 2⁻²⁷·√2) need no selection
    // here: there the kernels round to those very values. The sine's correction is about
    // `x³/6`, under `x·2⁻⁵⁴`, less than half an ulp of `x` (or 0 once `x³` underflows);
    // the cosine's `½x²` is under `2⁻⁵⁴`, half an ulp below 1, and so is every step from
    // 1 (a test compares every fold and both thresholds with `sincos_deg`). At `x = 0`
    // both give (0, 1).
    let z = x * x;
    let w = z * z;
    let s = kernel_sin(x, z, w);
    // `x` is finite and `≥ 0` here, where libm's `− x·0.0` changes no bit.
    let c = kernel_cos_finite(z, w);
    let (s, c) = if swap { (c, s) } else { (s, c) };
    // `+ 0.0` turns a −0 into +0, as `sincos_deg` does.
    (
        flip_sign(s, negative != over_half) + 0.0,
        flip_sign(c, over_quarter) + 0.0,
    )
}

/// `x` with its sign bit flipped where `flip`: `−x`, as `−1.0·x` gives it.
#[inline(always)]
fn flip_sign(x: f64, flip: bool) -> f64 {
    f64::from_bits(x.to_bits() ^ (u64::from(flip) << 63))
}

/// [`kernel_cos`] for a finite `x ≥ 0` (given `z = x²`, `w = z²`), where `x·0.0 = +0`
/// and `y − (+0) = y` for every `y` (also `±0`): the same bits without that term.
#[inline(always)]
#[allow(clippy::excessive_precision)] // libm's literals, digit for digit
fn kernel_cos_finite(z: f64, w: f64) -> f64 {
    const C1: f64 = 4.166_666_666_666_660_190_37e-2;
    const C2: f64 = -1.388_888_888_887_410_957_49e-3;
    const C3: f64 = 2.480_158_728_947_672_941_78e-5;
    const C4: f64 = -2.755_731_435_139_066_330_35e-7;
    const C5: f64 = 2.087_572_321_298_174_827_90e-9;
    const C6: f64 = -1.135_964_755_778_819_482_65e-11;
    let r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let hw = 1.0 - hz;
    hw + (((1.0 - hw) - hz) + z * r)
}

/// One four-bar coupler point (a linkage, its circuit and the point) with every constant
/// of [`Pose::finite_points_with`]'s lanes computed once, for evaluating the point at many
/// crank angles ([`PointLanes::at`]): a shape fit evaluates the same point at every
/// target point's angle, iteration after iteration. The constants are the very
/// subexpressions the lanes formed each time (`4·C`, `(C − 1)²`, `(A − B)(A + B)`, `1/A`,
/// `A·B`, …, each evaluated as the lanes' expressions group them), so the values are the
/// same, bit for bit (tested).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLanes {
    linkage: FourBar,
    gaps: ToggleGaps,
    circuit: Circuit,
    point: CouplerPoint,
    /// `C`, `C − 1`, `(C − 1)·(C − 1)`, `4·C`.
    c_len: f64,
    c_m1: f64,
    c_m1_sq: f64,
    c4: f64,
    /// `(A − B)·(A + B)`.
    ab_sq: f64,
    /// `σ·0.5` and `σ`.
    half_sign: f64,
    sign: f64,
    /// `1/A`, `A·B`, `B`.
    inv_a: f64,
    a_b: f64,
    b_len: f64,
    /// `u`, `v`, `−u`.
    u: f64,
    v: f64,
    neg_u: f64,
}

impl PointLanes {
    /// The constants of `point` on `circuit` of `linkage` (with its [`ToggleGaps`]).
    pub fn new(
        linkage: &FourBar,
        gaps: &ToggleGaps,
        circuit: Circuit,
        point: CouplerPoint,
    ) -> PointLanes {
        let (a_len, b_len, c_len) = (linkage.coupler, linkage.rocker, linkage.ground);
        let sign = circuit.sign();
        PointLanes {
            linkage: *linkage,
            gaps: *gaps,
            circuit,
            point,
            c_len,
            c_m1: c_len - 1.0,
            c_m1_sq: (c_len - 1.0) * (c_len - 1.0),
            c4: 4.0 * c_len,
            ab_sq: (a_len - b_len) * (a_len + b_len),
            half_sign: sign * 0.5,
            sign,
            inv_a: 1.0 / a_len,
            a_b: a_len * b_len,
            b_len,
            u: point.u,
            v: point.v,
            neg_u: -point.u,
        }
    }

    /// The coupler point and its velocity at [`POINT_LANES`] crank angles:
    /// [`Pose::finite_points_with`] of this linkage, circuit and point, bit for bit.
    #[inline(always)]
    pub fn at(
        &self,
        degrees: &[f64; POINT_LANES],
    ) -> [Option<(Point2<f64>, Vector2<f64>)>; POINT_LANES] {
        self.lanes::<false>(degrees)
    }

    /// [`PointLanes::at`], `None` also where the point or its velocity is not finite
    /// (what a fit asks: tested in the lanes, side by side).
    #[inline(always)]
    pub fn at_finite(
        &self,
        degrees: &[f64; POINT_LANES],
    ) -> [Option<(Point2<f64>, Vector2<f64>)>; POINT_LANES] {
        self.lanes::<true>(degrees)
    }

    /// [`PointLanes::at`], or with `FINITE` [`PointLanes::at_finite`].
    #[inline(always)]
    fn lanes<const FINITE: bool>(
        &self,
        degrees: &[f64; POINT_LANES],
    ) -> [Option<(Point2<f64>, Vector2<f64>)>; POINT_LANES] {
        const L: usize = POINT_LANES;
        let k = self;
        let gaps = &k.gaps;
        let mut out = [[0.0f64; 4]; L];
        let mut ok = [false; L];
        for i in 0..L {
            let deg = degrees[i];
            let (sin, cos) = sincos_deg_select(deg);
            let (sin_half, cos_half) = sincos_half_deg_select(0.5 * deg);
            // PoseCore::solve.
            let sh2 = sin_half * sin_half;
            let ch2 = cos_half * cos_half;
            let (wx, wy) = (k.c_m1 + 2.0 * sh2, -sin);
            let d2 = k.c_m1_sq + k.c4 * sh2;
            let px = gaps.outer + k.c4 * ch2;
            let p_tol = -TOGGLE_ULPS * f64::EPSILON * (gaps.outer_scale + k.c4 * ch2);
            let qx = gaps.inner + k.c4 * sh2;
            let q_tol = -TOGGLE_ULPS * f64::EPSILON * (gaps.inner_scale + k.c4 * sh2);
            // `flat_or_none`: a factor below 0 by no more than its tolerance is 0 (written
            // as a maximum, the same values: a −0 is kept). The tolerances are ≤ 0 (the
            // scales are sums of squares), so `px ≥ 0` passes `px ≥ p_tol` too.
            let p = if px < 0.0 { 0.0 } else { px };
            let q = if qx < 0.0 { 0.0 } else { qx };
            let assembles = (px >= p_tol) & (qx >= q_tol);
            let area4 = (p * q).sqrt();
            let inv_d2 = 1.0 / d2;
            let along = 0.5 * (k.ab_sq + d2) * inv_d2;
            let half_area = k.half_sign * area4;
            let across = half_area * inv_d2;
            let (cx, cy) = (wx * along - wy * across, wy * along + wx * across);
            let pb_x = cos + cx;
            let pb_y = sin + cy;
            let va_dot = -sin * (pb_x - k.c_len) + cos * pb_y;
            let omega = -2.0 * va_dot / (k.sign * area4);
            let (e_x, e_y) = (cx * k.inv_a, cy * k.inv_a);
            // finite_frame_with.
            let cross34 = half_area / k.a_b;
            let rocker_omega = -(-sin * e_x + cos * e_y) / (k.b_len * cross34);
            // CouplerFrame::point and ::velocity.
            let o = [
                cos + k.u * e_x - k.v * e_y,
                sin + k.u * e_y + k.v * e_x,
                -sin + omega * (k.neg_u * e_y - k.v * e_x),
                cos + omega * (k.u * e_x - k.v * e_y),
            ];
            // Every value finite (`is_finite` of each): `x·0` is ±0 for a finite `x` and
            // NaN for an infinite or NaN one, so their sum is ±0 exactly when all are
            // finite (one comparison for the lot).
            let mut zero = (pb_x * 0.0 + pb_y * 0.0) + (omega * 0.0 + rocker_omega * 0.0);
            if FINITE {
                zero += (o[0] * 0.0 + o[1] * 0.0) + (o[2] * 0.0 + o[3] * 0.0);
            }
            ok[i] = (deg.abs() < 720.0) & (d2 != 0.0) & assembles & (zero == 0.0);
            out[i] = o;
        }
        let mut got = [None; L];
        for i in 0..L {
            if ok[i] {
                let o = out[i];
                got[i] = Some((Point2::new(o[0], o[1]), Vector2::new(o[2], o[3])));
            }
        }
        if !degrees.iter().all(|d| d.abs() < 720.0) {
            self.far_lanes(degrees, &mut got);
            if FINITE {
                for lane in &mut got {
                    *lane = lane.filter(|(m, v)| {
                        m.x.is_finite() && m.y.is_finite() && v.x.is_finite() && v.y.is_finite()
                    });
                }
            }
        }
        got
    }

    /// The lanes outside `|θ| < 720°` (or NaN), by the scalar path.
    #[cold]
    #[inline(never)]
    fn far_lanes(
        &self,
        degrees: &[f64; POINT_LANES],
        got: &mut [Option<(Point2<f64>, Vector2<f64>)>; POINT_LANES],
    ) {
        for (d, lane) in degrees.iter().zip(got.iter_mut()) {
            let near = d.abs() < 720.0;
            if !near {
                let angle = CrankAngle::from_degrees(*d);
                *lane = Pose::finite_frame_with(&self.linkage, &self.gaps, self.circuit, &angle)
                    .map(|f| (f.point(self.point), f.velocity(self.point)));
            }
        }
    }
}

impl Pose {
    /// The coupler point and its velocity (unit crank speed) at [`POINT_LANES`] crank
    /// angles at once: lane `i` is, bit for bit,
    /// `Pose::finite_frame_with(linkage, gaps, circuit, &CrankAngle::from_degrees(degrees[i]))
    /// .map(|f| (f.point(point), f.velocity(point)))`. The lanes run the same operations
    /// without branches (each test a selection), so the compiler can run them side by
    /// side; a lane outside `|θ| < 720°` (or NaN) takes the scalar path. For many angles
    /// of one point, [`PointLanes`] computes the linkage's constants once.
    #[inline]
    pub fn finite_points_with(
        linkage: &FourBar,
        gaps: &ToggleGaps,
        circuit: Circuit,
        point: CouplerPoint,
        degrees: &[f64; POINT_LANES],
    ) -> [Option<(Point2<f64>, Vector2<f64>)>; POINT_LANES] {
        PointLanes::new(linkage, gaps, circuit, point).at(degrees)
    }
}

/// How far (in ulps of the longest side) the triangle inequality may fail by rounding
/// and still count as a flat triangle (a toggle).
pub const TOGGLE_ULPS: f64 = 4.0;

/// Twice the area of the triangle with sides `a`, `b`, `c` (times two: `2·Area`), by
/// Kahan's formula for needle-like triangles ("Miscalculating Area and Angles of a
/// Needle-like Triangle", 2014): sort `x ≥ y ≥ z`, then
/// `4·Area = √((x+(y+z))(z−(x−y))(z+(x−y))(x+(y−z)))`, with the parentheses as written.
/// Accurate to a few ulps even for triangles that are nearly flat, where Heron's formula
/// or `√(A² − a²)` lose all their digits.
///
/// Returns `None` when the sides violate the triangle inequality by more than
/// [`TOGGLE_ULPS`] ulps of the longest side (no triangle; the linkage cannot be
/// assembled), and `Some(0.0)` for a triangle flat to within that (a toggle): the
/// distance `d` carries a rounding error of about an ulp, so a linkage that just reaches
/// a toggle must not be declared unassemblable by it.
pub fn kahan_double_area(a: f64, b: f64, c: f64) -> Option<f64> {
    let (mut x, mut y, mut z) = (a, b, c);
    if x < y {
        std::mem::swap(&mut x, &mut y);
    }
    if y < z {
        std::mem::swap(&mut y, &mut z);
    }
    if x < y {
        std::mem::swap(&mut x, &mut y);
    }
    let mut gap = z - (x - y);
    if gap.is_nan() {
        return None;
    }
    if gap < 0.0 {
        // Within rounding of flat (a few ulps of the longest side): a toggle, not a
        // failure to assemble. Further out: no triangle.
        if gap >= -TOGGLE_ULPS * f64::EPSILON * x {
            gap = 0.0;
        } else {
            return None;
        }
    }
    let p = (x + (y + z)) * gap * (z + (x - y)) * (x + (y - z));
    Some(0.5 * p.sqrt())
}

/// The two Grashof gaps of a linkage, the constants of [`Pose::solve`]'s thin factors:
/// `outer = (A+B)² − (C+1)²` (how far the coupler and rocker are from folding out
/// straight at θ = 180°) and `inner = (C−1)² − (A−B)²` (from folding onto each other at
/// θ = 0), each computed with error-free products and sums and rounded once. Both are
/// positive for a strict crank-rocker and zero at a change point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToggleGaps {
    /// `(A+B)² − (C+1)²`.
    pub outer: f64,
    /// Sum of the magnitudes of its terms (for the rounding tolerance).
    pub outer_scale: f64,
    /// `(C−1)² − (A−B)²`.
    pub inner: f64,
    /// Sum of the magnitudes of its terms.
    pub inner_scale: f64,
}

impl ToggleGaps {
    /// The gaps of `linkage`.
    pub fn of(linkage: &FourBar) -> ToggleGaps {
        use crate::dd::Dd;
        let (a, b, c) = (
            Dd::from_f64(linkage.coupler),
            Dd::from_f64(linkage.rocker),
            Dd::from_f64(linkage.ground),
        );
        let one = Dd::from_f64(1.0);
        let sq = |x: Dd| x * x;
        let (ab_sum, ab_diff, c_plus, c_minus) = (a + b, a - b, c + one, c - one);
        ToggleGaps {
            outer: (sq(ab_sum) - sq(c_plus)).to_f64(),
            outer_scale: sq(ab_sum).to_f64() + sq(c_plus).to_f64(),
            inner: (sq(c_minus) - sq(ab_diff)).to_f64(),
            inner_scale: sq(c_minus).to_f64() + sq(ab_diff).to_f64(),
        }
    }
}

/// A thin factor that is negative by no more than rounding (relative to the size of its
/// terms) is a flat triangle, 0; more negative, no triangle.
#[inline]
fn flat_or_none(x: f64, scale: f64) -> Option<f64> {
    if x >= 0.0 {
        Some(x)
    } else if x >= -TOGGLE_ULPS * f64::EPSILON * scale {
        Some(0.0)
    } else {
        None
    }
}

/// What every coupler point needs from a pose, and nothing more: the hot path of
/// [`crate::PoseTable`]. Same equations as [`Pose::solve`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PoseCore {
    /// Unit coupler direction e3.
    pub e_x: f64,
    pub e_y: f64,
    /// Coupler angular velocity ω3.
    pub omega: f64,
    /// Rocker pin.
    pub pb_x: f64,
    pub pb_y: f64,
    /// 4·Area of the triangle (A, B, d) = √(P·Q).
    pub area4: f64,
    /// d².
    pub d2: f64,
}

impl PoseCore {
    #[inline]
    pub(crate) fn solve(
        linkage: &FourBar,
        gaps: &ToggleGaps,
        circuit: Circuit,
        angle: &CrankAngle,
    ) -> Option<PoseCore> {
        let (a_len, b_len, c_len) = (linkage.coupler, linkage.rocker, linkage.ground);
        let sh2 = angle.sin_half * angle.sin_half;
        let ch2 = angle.cos_half * angle.cos_half;
        let (wx, wy) = ((c_len - 1.0) + 2.0 * sh2, -angle.sin);
        let d2 = (c_len - 1.0) * (c_len - 1.0) + 4.0 * c_len * sh2;
        if d2 == 0.0 {
            return None;
        }
        let p = flat_or_none(
            gaps.outer + 4.0 * c_len * ch2,
            gaps.outer_scale + 4.0 * c_len * ch2,
        )?;
        let q = flat_or_none(
            gaps.inner + 4.0 * c_len * sh2,
            gaps.inner_scale + 4.0 * c_len * sh2,
        )?;
        let area4 = (p * q).sqrt();
        let inv_d2 = 1.0 / d2;
        // Pb − Pa = (a/d)·w + σ(h/d)·J·w with a/d = (A² − B² + d²)/(2d²), h/d = area4/(2d²).
        let along = 0.5 * ((a_len - b_len) * (a_len + b_len) + d2) * inv_d2;
        let across = circuit.sign() * 0.5 * area4 * inv_d2;
        let (cx, cy) = (wx * along - wy * across, wy * along + wx * across);
        let pb_x = angle.cos + cx;
        let pb_y = angle.sin + cy;
        let inv_a = 1.0 / a_len;
        // ω3 = −(Va·e4)/(A·(e3 × e4)) = −(Va·(Pb − O4)) / (σ·h·d) = −2·(Va·(Pb − O4)) / (σ·area4).
        let va_dot = -angle.sin * (pb_x - c_len) + angle.cos * pb_y;
        let omega = -2.0 * va_dot / (circuit.sign() * area4);
        Some(PoseCore {
            e_x: cx * inv_a,
            e_y: cy * inv_a,
            omega,
            pb_x,
            pb_y,
            area4,
            d2,
        })
    }

    /// The coupler frame: origin Pa = (cos θ, sin θ), direction e3, angular velocity ω3.
    #[inline]
    pub(crate) fn frame(&self, angle: &CrankAngle) -> CouplerFrame {
        CouplerFrame {
            origin: Point2::new(angle.cos, angle.sin),
            origin_velocity: Vector2::new(-angle.sin, angle.cos),
            direction: Vector2::new(self.e_x, self.e_y),
            omega: self.omega,
        }
    }
}

/// The linkage's pose at one crank angle: everything that depends only on (A, B, C, θ)
/// and the circuit, shared by every coupler point (docs/conventions.md §3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Crank pin Pa.
    pub crank_pin: Point2<f64>,
    /// Rocker pin Pb.
    pub rocker_pin: Point2<f64>,
    /// Unit vector e3 along the coupler, Pa → Pb.
    pub coupler_dir: Vector2<f64>,
    /// Unit vector e4 along the rocker, O4 → Pb.
    pub rocker_dir: Vector2<f64>,
    /// Velocity of Pa for unit crank speed.
    pub crank_pin_velocity: Vector2<f64>,
    /// Coupler angular velocity ω3 = dφ3/dθ (infinite only at a toggle).
    pub coupler_omega: f64,
    /// Rocker angular velocity ω4 = dφ4/dθ.
    pub rocker_omega: f64,
    /// Transmission angle μ in radians, in [0, π].
    pub transmission: f64,
}

impl Pose {
    /// Solves the loop closure in closed form (docs/conventions.md §3):
    /// `w = O4 − Pa`, `d = |w|`, foot `a = (A² − B² + d²)/(2d)`, half-chord `h = 2·Area/d`,
    /// and `Pb = Pa + (a/d)·w + σ·(h/d)·J·w` (σ = +1 open, −1 crossed).
    ///
    /// The area is Kahan's factorisation of the triangle (A, B, d) (Kahan, "Miscalculating
    /// Area and Angles of a Needle-like Triangle"): `16·Area² = P·Q` with the two thin
    /// factors `P = (A+B)² − d²` and `Q = d² − (A−B)²`. Forming `d` first and subtracting
    /// would cost all the digits of a toggle's small gap, so both are taken from the exact
    /// inputs with the crank half-angle instead:
    /// `P = [(A+B)² − (C+1)²] + 4C·cos²(θ/2)`, `Q = [(C−1)² − (A−B)²] + 4C·sin²(θ/2)`,
    /// the brackets evaluated once with error-free products. For a crank-rocker both
    /// brackets are positive (strict Grashof), so nothing cancels anywhere: positions are
    /// good to a few ulps even within 1e-9 of a change point. Likewise
    /// `w = ((C − 1) + 2·sin²(θ/2), −sin θ)` and `d² = (C−1)² + 4C·sin²(θ/2)`.
    ///
    /// Velocities (unit crank speed) differentiate `Pa + A·e3 = O4 + B·e4`:
    /// `ω3 = −(Va·e4) / (A·(e3 × e4))`, `ω4 = −(Va·e3) / (B·(e3 × e4))`, with
    /// `e3 × e4 = σ·h·d/(A·B)` from the same area. Transmission angle
    /// `μ = atan2(√(P·Q), A² + B² − d²)` (tan μ = 4·Area/(A² + B² − d²); stable at 0° and
    /// 180°, unlike `acos`).
    ///
    /// Degenerate cases, part of the contract: returns `None` where the linkage cannot be
    /// assembled (`P` or `Q` negative beyond rounding, see [`TOGGLE_ULPS`]) or where Pa
    /// lies on O4 (d = 0). At a toggle (h = 0, including a change point) both circuits
    /// meet; the pose is returned with infinite `coupler_omega`/`rocker_omega`.
    ///
    /// ```
    /// use coupler_kinematics::{FourBar, Circuit, CrankAngle, Pose};
    /// let l = FourBar::new(3.0, 3.0, 3.0).unwrap();
    /// let p = Pose::solve(&l, Circuit::Open, &CrankAngle::from_degrees(90.0)).unwrap();
    /// assert!(p.rocker_pin.y > 0.0); // open puts Pb above the ground line here
    /// assert!(((p.rocker_pin - p.crank_pin).norm() - 3.0).abs() < 1e-15);
    /// ```
    pub fn solve(linkage: &FourBar, circuit: Circuit, angle: &CrankAngle) -> Option<Pose> {
        Pose::solve_with(linkage, &ToggleGaps::of(linkage), circuit, angle)
    }

    /// [`Pose::solve`] with the linkage's constants computed once (see [`ToggleGaps`]).
    pub fn solve_with(
        linkage: &FourBar,
        gaps: &ToggleGaps,
        circuit: Circuit,
        angle: &CrankAngle,
    ) -> Option<Pose> {
        let core = PoseCore::solve(linkage, gaps, circuit, angle)?;
        let (a_len, b_len) = (linkage.coupler, linkage.rocker);
        let e4 = Vector2::new(core.pb_x - linkage.ground, core.pb_y) / b_len;
        let e3 = Vector2::new(core.e_x, core.e_y);
        let va = Vector2::new(-angle.sin, angle.cos);
        // ω4 = −(Va·e3) / (B·(e3 × e4)) with e3 × e4 = σ·h·d/(A·B) = σ·area4/(2AB).
        let cross34 = circuit.sign() * 0.5 * core.area4 / (a_len * b_len);
        let rocker_omega = -va.dot(&e3) / (b_len * cross34);
        let transmission = libm::atan2(core.area4, a_len * a_len + b_len * b_len - core.d2);
        Some(Pose {
            crank_pin: Point2::new(angle.cos, angle.sin),
            rocker_pin: Point2::new(core.pb_x, core.pb_y),
            coupler_dir: e3,
            rocker_dir: e4,
            crank_pin_velocity: va,
            coupler_omega: core.omega,
            rocker_omega,
            transmission,
        })
    }

    /// The coupler's frame of [`Pose::solve_with`]'s pose where that pose is finite
    /// ([`Pose::is_finite`]), else `None`: the same values, bit for bit, as
    /// `Pose::solve_with(..).filter(Pose::is_finite).map(|p| p.frame())`, without what a
    /// coupler point does not need (the rocker's direction and the transmission angle,
    /// whose `atan2` costs as much as the rest of the pose). For evaluating a coupler
    /// point and its velocity at many angles, as the shape fits do.
    #[inline]
    pub fn finite_frame_with(
        linkage: &FourBar,
        gaps: &ToggleGaps,
        circuit: Circuit,
        angle: &CrankAngle,
    ) -> Option<CouplerFrame> {
        let core = PoseCore::solve(linkage, gaps, circuit, angle)?;
        let (a_len, b_len) = (linkage.coupler, linkage.rocker);
        // ω4 exactly as `solve_with` forms it: only its finiteness is asked.
        let e3 = Vector2::new(core.e_x, core.e_y);
        let va = Vector2::new(-angle.sin, angle.cos);
        let cross34 = circuit.sign() * 0.5 * core.area4 / (a_len * b_len);
        let rocker_omega = -va.dot(&e3) / (b_len * cross34);
        let finite = core.pb_x.is_finite()
            && core.pb_y.is_finite()
            && core.omega.is_finite()
            && rocker_omega.is_finite();
        finite.then(|| core.frame(angle))
    }

    /// The coupler's frame: origin Pa, direction e3, angular velocity ω3.
    #[inline]
    pub fn frame(&self) -> CouplerFrame {
        CouplerFrame {
            origin: self.crank_pin,
            origin_velocity: self.crank_pin_velocity,
            direction: self.coupler_dir,
            omega: self.coupler_omega,
        }
    }

    /// The coupler point M = Pa + u·e3 + v·J·e3 ([`CouplerFrame::point`]).
    #[inline]
    pub fn point(&self, p: CouplerPoint) -> Point2<f64> {
        self.frame().point(p)
    }

    /// The coupler point's velocity for unit crank speed:
    /// `V_M = V_Pa + ω3·J·(M − Pa) = V_Pa + ω3·(u·J·e3 − v·e3)` ([`CouplerFrame::velocity`]).
    #[inline]
    pub fn velocity(&self, p: CouplerPoint) -> Vector2<f64> {
        self.frame().velocity(p)
    }

    /// The loop-closure residual |Pa + A·e3 − O4 − B·e4| (should be a few ulps).
    pub fn loop_residual(&self, linkage: &FourBar) -> f64 {
        let o4 = Point2::new(linkage.ground, 0.0);
        let lhs = self.crank_pin + self.coupler_dir * linkage.coupler;
        let rhs = o4 + self.rocker_dir * linkage.rocker;
        (lhs - rhs).norm()
    }

    /// True when every field is finite (false at a toggle, where velocities blow up).
    pub fn is_finite(&self) -> bool {
        self.rocker_pin.coords.iter().all(|x| x.is_finite())
            && self.coupler_omega.is_finite()
            && self.rocker_omega.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sincos_exact_at_quadrants_and_symmetric() {
        assert_eq!(sincos_deg(0.0), (0.0, 1.0));
        assert_eq!(sincos_deg(90.0), (1.0, 0.0));
        assert_eq!(sincos_deg(180.0), (0.0, -1.0));
        assert_eq!(sincos_deg(270.0), (-1.0, 0.0));
        assert_eq!(sincos_deg(360.0), (0.0, 1.0));
        assert_eq!(sincos_deg(-90.0), (-1.0, 0.0));
        for k in 0..720 {
            let t = k as f64 * 0.5;
            let (s, c) = sincos_deg(t);
            let (s2, c2) = sincos_deg(-t);
            assert_eq!((s, c), (-s2, c2), "odd/even at {t}");
            let (s3, c3) = sincos_deg(360.0 - t);
            assert_eq!((s, c), (-s3, c3), "reflection at {t}");
        }
    }

    /// The written-out kernels are `libm`'s sine and cosine, bit for bit: on a fine grid
    /// of degrees as `sincos_deg` folds them, on random arguments over `(0, π/4]`, and at
    /// the thresholds where `libm` returns `x` or 1.
    #[test]
    fn written_out_kernels_are_libm() {
        let check = |x: f64| {
            let (s, c) = libm_sin_cos(x);
            assert_eq!(s.to_bits(), libm::sin(x).to_bits(), "sin {x:e}");
            assert_eq!(c.to_bits(), libm::cos(x).to_bits(), "cos {x:e}");
        };
        for k in 1..=450_000u32 {
            check(k as f64 * 1e-4 * (std::f64::consts::PI / 180.0));
        }
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..2_000_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            check(u * std::f64::consts::FRAC_PI_4);
            check(u * 1e-7);
        }
        for hi in [0x3e50_0000u64, 0x3e46_a09e, 0x3fe9_21fb, 0x3fe9_21fc] {
            for lo in [0u64, 1, 0x8000_0000, 0xffff_ffff] {
                let x = f64::from_bits((hi << 32) | lo);
                check(x);
                check(x.next_down());
            }
        }
        for x in [
            5e-324,
            f64::MIN_POSITIVE,
            1e-300,
            1e-20,
            std::f64::consts::FRAC_PI_4,
        ] {
            check(x);
        }
        let (s, c) = libm_sin_cos(f64::NAN);
        assert!(s.is_nan() && c.is_nan());
    }

    /// The branch-free sine and cosine of the lanes are [`sincos_deg`]'s, bit for bit, below
    /// 720° (every fold, the kernels' tiny branches, zeros and multiples of 45°), and so
    /// are the half angle's below 360°.
    #[test]
    fn selected_sincos_is_sincos_deg() {
        let check = |d: f64| {
            let (s, c) = sincos_deg(d);
            let (s2, c2) = sincos_deg_select(d);
            assert_eq!(
                (s.to_bits(), c.to_bits()),
                (s2.to_bits(), c2.to_bits()),
                "{d:e}"
            );
            if d.abs() < 360.0 {
                let (s3, c3) = sincos_half_deg_select(d);
                assert_eq!(
                    (s.to_bits(), c.to_bits()),
                    (s3.to_bits(), c3.to_bits()),
                    "half {d:e}"
                );
            }
        };
        for k in -7_200_000i32..7_200_000 {
            check(k as f64 * 1e-4);
        }
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..2_000_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            check(1440.0 * u - 720.0);
            check(u * 1e-5);
        }
        for d in [
            0.0f64,
            -0.0,
            5e-324,
            1e-300,
            1e-9,
            45.0,
            90.0,
            180.0,
            359.999_999_999_999_94,
        ] {
            for x in [d, -d, d.next_up(), d.next_down(), 360.0 + d, 360.0 - d] {
                check(x);
            }
        }
        for hi in [0x3e50_0000u64, 0x3e46_a09e] {
            for lo in [0u64, 1, 0xffff_ffff] {
                let r = f64::from_bits((hi << 32) | lo) / (std::f64::consts::PI / 180.0);
                for x in [r, r.next_up(), r.next_down(), 90.0 - r, 180.0 + r] {
                    check(x);
                }
            }
        }
        // Small folded angles on a log scale, from subnormal to past libm's tiny branches
        // (2⁻²⁷·√2 and 2⁻²⁶ radians), about each multiple of 90°.
        for k in 0..400_000 {
            let r = 2f64.powf(-1070.0 + 1050.0 * k as f64 / 400_000.0);
            for x in [r, 90.0 - r, 90.0 + r, 180.0 - r, 180.0 + r, 360.0 - r, -r] {
                check(x);
            }
        }
    }

    /// Every lane of [`Pose::finite_points_with`], and of one [`PointLanes`] made once and
    /// evaluated at every angle, is the scalar path's point and velocity, bit for bit, and
    /// `None` where it is: both circuits, several coupler points (on the coupler's line,
    /// off it either side, at its pins), across toggles and unassembled angles (a
    /// non-Grashof linkage), beyond 720° and NaN.
    #[test]
    fn lanes_are_the_scalar_points() {
        let mut lanes = 0;
        let mut none = 0;
        for (a, b, c) in [
            (2.37, 3.1, 3.4),
            (3.0, 3.0, 3.0),
            (1.2, 1.5, 1.1),
            (2.0, 2.5, 3.5),
            (4.5, 3.0, 3.5),
        ] {
            let l = FourBar::new(a, b, c).unwrap();
            let g = ToggleGaps::of(&l);
            for circuit in [Circuit::Open, Circuit::Crossed] {
                for (u, v) in [
                    (1.3, -0.8),
                    (0.0, 0.0),
                    (a, 0.0),
                    (-0.7, 2.25),
                    (1.125, -2.25),
                ] {
                    let point = CouplerPoint::new(u, v);
                    let prepared = PointLanes::new(&l, &g, circuit, point);
                    let mut degs: Vec<f64> = (-3000..3000).map(|k| k as f64 * 0.37).collect();
                    degs.extend([0.0, 180.0, -180.0, 720.0, -720.0, 1e6, f64::NAN, 5e-324]);
                    degs.extend([-0.0, 359.999_999_999_999_94, 719.999_999_999_999_9, 90.0]);
                    for chunk in degs.chunks_exact(POINT_LANES) {
                        let d: [f64; POINT_LANES] = chunk.try_into().unwrap();
                        let got = Pose::finite_points_with(&l, &g, circuit, point, &d);
                        let again = prepared.at(&d);
                        let finite = prepared.at_finite(&d);
                        for (i, (lane, other)) in got.iter().zip(&again).enumerate() {
                            let angle = CrankAngle::from_degrees(d[i]);
                            let want = Pose::finite_frame_with(&l, &g, circuit, &angle)
                                .map(|f| (f.point(point), f.velocity(point)));
                            let bits = |x: Option<(Point2<f64>, Vector2<f64>)>| {
                                x.map(|(m, v)| [m.x, m.y, v.x, v.y].map(f64::to_bits))
                            };
                            assert_eq!(bits(*lane), bits(want), "{l} {circuit} {}", d[i]);
                            assert_eq!(bits(*other), bits(want), "{l} {circuit} {}", d[i]);
                            let want_finite = want.filter(|(m, v)| {
                                [m.x, m.y, v.x, v.y].iter().all(|x| x.is_finite())
                            });
                            assert_eq!(bits(finite[i]), bits(want_finite), "{l} {circuit}");
                            lanes += 1;
                            none += usize::from(want.is_none());
                        }
                    }
                }
            }
        }
        assert!(none > 5000 && lanes - none > 100_000, "{none} of {lanes}");
    }

    /// The fast reduction is `%` to the bit, at the edges and far out.
    #[test]
    fn turn_remainder_is_the_remainder() {
        let mut xs = vec![
            0.0,
            f64::MIN_POSITIVE,
            5e-324,
            1e-300,
            359.0,
            360.0,
            720.0,
            1080.0,
            1e6 + 0.125,
            2f64.powi(52) + 1.0,
            1e300,
            f64::MAX,
        ];
        for edge in [360.0f64, 720.0, 1080.0] {
            let mut x = edge;
            for _ in 0..4 {
                x = x.next_down();
                xs.push(x);
            }
            let mut x = edge;
            for _ in 0..4 {
                x = x.next_up();
                xs.push(x);
            }
        }
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..20_000 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            xs.push(u * 1500.0);
            xs.push(u * 360.0 * 4.0f64.powi((state % 12) as i32));
        }
        for x in xs {
            assert_eq!(turn_remainder(x).to_bits(), (x % 360.0).to_bits(), "{x:e}");
        }
        assert!(turn_remainder(f64::INFINITY).is_nan());
        assert!(turn_remainder(f64::NAN).is_nan());
    }

    /// The lean frame is the full pose's frame, bit for bit, where that pose is finite,
    /// and `None` where it is not: at a change point (toggles: infinite velocities) and
    /// where the linkage does not assemble.
    #[test]
    fn finite_frame_is_the_poses_frame() {
        let linkages = [
            FourBar::new(2.5, 3.0, 3.5).unwrap(),
            FourBar::new(3.0, 3.0, 3.0).unwrap(),
            FourBar::new(2.0, 2.0, 1.0).unwrap(), // change point: toggles at 0°
            FourBar::new(1.0, 3.0, 4.5).unwrap(), // does not assemble everywhere
            FourBar::new(4.0, 2.5, 2.5).unwrap(),
        ];
        let mut none = 0;
        for l in &linkages {
            let gaps = ToggleGaps::of(l);
            for circuit in [Circuit::Open, Circuit::Crossed] {
                for k in -800..800 {
                    let deg = k as f64 * 0.9 + if k % 3 == 0 { 0.0 } else { 1.0 / 7.0 };
                    let angle = CrankAngle::from_degrees(deg);
                    let full = Pose::solve_with(l, &gaps, circuit, &angle)
                        .filter(Pose::is_finite)
                        .map(|p| p.frame());
                    let lean = Pose::finite_frame_with(l, &gaps, circuit, &angle);
                    none += usize::from(full.is_none());
                    let bits = |f: Option<CouplerFrame>| {
                        f.map(|f| {
                            [
                                f.origin.x,
                                f.origin.y,
                                f.origin_velocity.x,
                                f.origin_velocity.y,
                                f.direction.x,
                                f.direction.y,
                                f.omega,
                            ]
                            .map(f64::to_bits)
                        })
                    };
                    assert_eq!(bits(lean), bits(full), "{l} {circuit} {deg}");
                }
            }
        }
        assert!(none > 100, "no pose was left out: {none}");
    }

    #[test]
    fn kahan_area() {
        assert_eq!(kahan_double_area(3.0, 4.0, 5.0), Some(12.0));
        assert_eq!(kahan_double_area(1.0, 2.0, 3.0), Some(0.0));
        assert_eq!(kahan_double_area(1.0, 2.0, 3.5), None);
        assert_eq!(
            kahan_double_area(1.0, 2.0, 3.0 + 2.0 * f64::EPSILON),
            Some(0.0)
        );
        assert_eq!(kahan_double_area(1.0, 2.0, 3.0 + 1e-12), None);
        assert_eq!(kahan_double_area(1.0, 2.0, f64::NAN), None);
    }

    #[test]
    fn velocities_match_finite_differences() {
        let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
        let p = CouplerPoint::new(1.2, -0.7);
        for circuit in [Circuit::Open, Circuit::Crossed] {
            for k in 0..36 {
                let t = k as f64 * 10.0 + 3.0;
                let hdeg = 1e-4;
                let at =
                    |deg: f64| Pose::solve(&l, circuit, &CrankAngle::from_degrees(deg)).unwrap();
                let (m1, m2) = (at(t - hdeg).point(p), at(t + hdeg).point(p));
                let fd = (m2 - m1) / (2.0 * hdeg.to_radians());
                let v = at(t).velocity(p);
                assert!(
                    (fd - v).norm() < 1e-6 * (1.0 + v.norm()),
                    "{circuit} {t}: {fd} vs {v}"
                );
                let e4 = |deg: f64| at(deg).rocker_dir;
                let phi = |e: Vector2<f64>| libm::atan2(e.y, e.x);
                let fd4 = (phi(e4(t + hdeg)) - phi(e4(t - hdeg))) / (2.0 * hdeg.to_radians());
                assert!((fd4 - at(t).rocker_omega).abs() < 1e-6, "ω4 {circuit} {t}");
            }
        }
    }
}
