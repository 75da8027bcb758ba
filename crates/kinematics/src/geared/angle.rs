//! The two crank angles of a geared five-bar, θ2 and θ5 = λ·θ2 + φ, with their sines and
//! cosines formed from the exact angle in degrees; and a table of them over the period.

use super::linkage::{GearRatio, GearedFiveBar};
use crate::{CrankAngle, sincos_deg};

/// `a + b` as an unevaluated sum `(s, e)`, `s = fl(a + b)`, exactly (Knuth's TwoSum).
#[inline]
pub(crate) fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `a · b` as an unevaluated sum `(p, e)`, exactly (the fused multiply-add is correctly
/// rounded, so `e = a·b − p` is exact; IEEE 754, the same bits on every platform).
#[inline]
pub(crate) fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

/// The sum of two unevaluated sums, renormalised (error ~1e-32 relative).
#[inline]
pub(crate) fn add2((ah, al): (f64, f64), (bh, bl): (f64, f64)) -> (f64, f64) {
    let (s, e) = two_sum(ah, bh);
    two_sum(s, e + (al + bl))
}

/// `num/den · θ2 + φ` degrees as an unevaluated sum `(hi, lo)`: the product is exact, the
/// division by the (small, integer) denominator and the phase add ~1e-32 relative.
fn geared_degrees(num: i64, den: i64, theta2: f64, phase: f64) -> (f64, f64) {
    let (p, e) = two_prod(num as f64, theta2);
    let (p, e) = if den == 1 {
        (p, e)
    } else {
        let q = den as f64;
        let q1 = p / q;
        // (p + e) − q1·q, exactly enough: q1·q via two_prod.
        let (m, me) = two_prod(q1, q);
        let r = ((p - m) - me) + e;
        two_sum(q1, r / q)
    };
    add2((p, e), (phase, 0.0))
}

/// `(sin, cos)` of the angle `hi + lo` degrees (an unevaluated sum). With `lo = 0` this is
/// exactly [`sincos_deg`]; otherwise the sum is folded onto `[0°, 45°]` by the same
/// symmetries, each step an exact subtraction (Sterbenz) in two parts, and rounded once to
/// radians at the end. So an angle whose exact value is a multiple of 90° gives exact
/// zeros and ones, and `θ5 = 180° − θ2` gives `sin θ5 = sin θ2` to the bit even when
/// `180 − θ2` is not a float.
pub(crate) fn sincos_deg2(hi: f64, lo: f64) -> (f64, f64) {
    if lo == 0.0 {
        return sincos_deg(hi);
    }
    let negative = hi < 0.0;
    let (mut h, mut l) = if negative { (-hi, -lo) } else { (hi, lo) };
    let mut sin_sign = if negative { -1.0 } else { 1.0 };
    let mut cos_sign = 1.0;
    // Reduce modulo 360: `%` is exact; then bring h + l back into [0, 360].
    (h, l) = two_sum(h % 360.0, l);
    if h < 0.0 {
        (h, l) = add2((h, l), (360.0, 0.0));
    } else if h >= 360.0 {
        (h, l) = two_sum(h - 360.0, l);
    }
    let above = |h: f64, l: f64, x: f64| h > x || (h == x && l > 0.0);
    if above(h, l, 180.0) {
        (h, l) = two_sum(360.0 - h, -l);
        sin_sign = -sin_sign;
    }
    if above(h, l, 90.0) {
        (h, l) = two_sum(180.0 - h, -l);
        cos_sign = -1.0;
    }
    let swap = above(h, l, 45.0);
    if swap {
        (h, l) = two_sum(90.0 - h, -l);
    }
    const K: f64 = std::f64::consts::PI / 180.0;
    let (s, c) = if h == 0.0 && l == 0.0 {
        (0.0, 1.0)
    } else {
        let x = h * K + l * K;
        (libm::sin(x), libm::cos(x))
    };
    let (s, c) = if swap { (c, s) } else { (s, c) };
    (sin_sign * s + 0.0, cos_sign * c + 0.0)
}

/// `hi + lo` degrees reduced to `[0, 360)` and rounded to a float.
fn reduced_degrees(hi: f64, lo: f64) -> f64 {
    let (h, l) = two_sum(hi % 360.0, lo);
    let r = h + l;
    if r < 0.0 {
        (r + 360.0) % 360.0
    } else if r >= 360.0 {
        r - 360.0
    } else {
        r
    }
}

/// An angle given as an unevaluated sum of degrees, as a [`CrankAngle`] (sine, cosine and
/// half-angle sine and cosine), `degrees` reduced to `[0, 360)`.
fn crank_angle2(hi: f64, lo: f64) -> CrankAngle {
    let (sin, cos) = sincos_deg2(hi, lo);
    let (sin_half, cos_half) = sincos_deg2(0.5 * hi, 0.5 * lo);
    CrankAngle {
        degrees: reduced_degrees(hi, lo),
        cos,
        sin,
        sin_half,
        cos_half,
    }
}

/// The crank angles of a geared five-bar at one input angle: θ2, the second crank's
/// `θ5 = λ·θ2 + φ`, and the half-angle of their difference `ψ = θ5 − θ2`, each with its
/// sine and cosine. Depends only on the gears (λ, φ) and θ2, so one table of them serves
/// every linkage with those gears ([`GearTable`]).
///
/// θ5 and ψ are formed exactly from the rational λ = p/q: `p·θ2` is an exact product,
/// the division by q and the phase are carried in two parts (~1e-32 relative), and the
/// sum is folded onto [0°, 45°] exactly before one rounding to radians. So θ5 is as
/// accurate as θ2 itself however many turns the input has made (θ2 up to 360°·q), and
/// exact multiples of 90° give exact sines and cosines. The half-angles give the
/// cancellation-free thin factors of [`crate::GearedPose::solve`].
///
/// ```
/// use coupler_kinematics::{GearAngle, GearRatio};
/// // λ = −1, φ = 180°: θ5 = 180° − θ2, the mirror image of the input crank.
/// let a = GearAngle::new(GearRatio::integer(-1).unwrap(), 180.0, 0.1);
/// assert_eq!(a.second.sin, a.input.sin);
/// assert_eq!(a.second.cos, -a.input.cos);
/// // λ = 1/3 at θ2 = 810°: θ5 = 270° exactly.
/// let b = GearAngle::new(GearRatio::new(1, 3).unwrap(), 0.0, 810.0);
/// assert_eq!((b.second.sin, b.second.cos), (-1.0, 0.0));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GearAngle {
    /// θ2 (degrees as given), the input crank.
    pub input: CrankAngle,
    /// θ5 = λ·θ2 + φ (`degrees` reduced to [0, 360)), the second crank.
    pub second: CrankAngle,
    /// sin(ψ/2), ψ = θ5 − θ2.
    pub rel_sin_half: f64,
    /// cos(ψ/2).
    pub rel_cos_half: f64,
}

impl GearAngle {
    /// The angles at input angle `theta2` (degrees, any finite value) for gear ratio
    /// `ratio` and phase `phase` (degrees).
    pub fn new(ratio: GearRatio, phase: f64, theta2: f64) -> GearAngle {
        GearAngle::from_input(ratio, phase, CrankAngle::from_degrees(theta2))
    }

    /// The angles at the input angle `input` (as [`CrankAngle::from_degrees`] makes it,
    /// kept as it is: the input crank's pin is exactly `input`'s cosine and sine).
    pub fn from_input(ratio: GearRatio, phase: f64, input: CrankAngle) -> GearAngle {
        let theta2 = input.degrees;
        let (h5, l5) = geared_degrees(ratio.num(), ratio.den(), theta2, phase);
        let (hp, lp) = geared_degrees(ratio.num() - ratio.den(), ratio.den(), theta2, phase);
        let (rel_sin_half, rel_cos_half) = sincos_deg2(0.5 * hp, 0.5 * lp);
        GearAngle {
            input,
            second: crank_angle2(h5, l5),
            rel_sin_half,
            rel_cos_half,
        }
    }
}

/// Evenly spaced input angles over one period of the gears, `θ2_k = k·step` for
/// `k = 0 .. n`, `n = ⌈period/step⌉` (all below the period `360°·q` for λ = p/q), with
/// the [`GearAngle`] at each. Shared by every linkage with the same gears and step.
///
/// Dashes keep their meaning: one dash per `step` (or per Δ) **of input**, so a curve of
/// λ = p/q has `36·q` dashes at 10°, and a dash's length is still the point's mean speed
/// per unit input angle.
///
/// ```
/// use coupler_kinematics::{GearTable, GearRatio};
/// let t = GearTable::new(GearRatio::new(-1, 2).unwrap(), 0.0, 10.0).unwrap();
/// assert_eq!(t.len(), 72); // 0°, 10°, …, 710°: two input turns
/// assert_eq!(t.angles()[71].second.degrees, 5.0); // −355° ≡ 5°
/// ```
#[derive(Clone, Debug)]
pub struct GearTable {
    ratio: GearRatio,
    phase: f64,
    step: f64,
    angles: Vec<GearAngle>,
}

impl GearTable {
    /// Angles `0, step, 2·step, …` below the period. `None` unless `0 < step ≤ 360` and
    /// both `step` and `phase` are finite.
    pub fn new(ratio: GearRatio, phase: f64, step_deg: f64) -> Option<GearTable> {
        if !(step_deg.is_finite() && step_deg > 0.0 && step_deg <= 360.0 && phase.is_finite()) {
            return None;
        }
        let period = ratio.period_deg();
        let n = (period / step_deg).ceil() as usize;
        let angles = (0..n)
            .map(|k| k as f64 * step_deg)
            .filter(|&t| t < period)
            .map(|t| GearAngle::new(ratio, phase, t))
            .collect();
        Some(GearTable {
            ratio,
            phase,
            step: step_deg,
            angles,
        })
    }

    /// The table for the gears of `linkage`.
    pub fn for_linkage(linkage: &GearedFiveBar, step_deg: f64) -> Option<GearTable> {
        GearTable::new(linkage.ratio, linkage.phase, step_deg)
    }

    /// The gear ratio.
    pub fn ratio(&self) -> GearRatio {
        self.ratio
    }

    /// The phase (degrees).
    pub fn phase(&self) -> f64 {
        self.phase
    }

    /// The step in degrees of input.
    pub fn step(&self) -> f64 {
        self.step
    }

    /// Number of angles.
    pub fn len(&self) -> usize {
        self.angles.len()
    }

    /// True if there are no angles (never, for a valid step).
    pub fn is_empty(&self) -> bool {
        self.angles.is_empty()
    }

    /// The angles.
    pub fn angles(&self) -> &[GearAngle] {
        &self.angles
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Dd;

    /// (sin, cos) of `num/den·θ + φ` degrees in double-double by Taylor series after an
    /// independent reduction (rational arithmetic on the exact float θ), for comparison.
    fn reference(num: i64, den: i64, theta: f64, phase: f64) -> (f64, f64) {
        let d = |x: f64| Dd::from_f64(x);
        let deg = d(num as f64) * d(theta) / d(den as f64) + d(phase);
        // Reduce by whole turns in double-double.
        let turns = (deg.to_f64() / 360.0).floor();
        let r = deg - d(turns) * d(360.0);
        let x = r * Dd::PI / d(180.0);
        let (mut s, mut c, mut ts, mut tc) = (x, d(1.0), x, d(1.0));
        for k in 1..60 {
            let k = k as f64;
            ts = -(ts * x * x) / d((2.0 * k) * (2.0 * k + 1.0));
            tc = -(tc * x * x) / d((2.0 * k - 1.0) * (2.0 * k));
            s = s + ts;
            c = c + tc;
        }
        (s.to_f64(), c.to_f64())
    }

    #[test]
    fn geared_angles_match_double_double() {
        let mut worst = 0.0f64;
        for (num, den) in [
            (1, 1),
            (-1, 1),
            (2, 1),
            (-2, 1),
            (-1, 2),
            (1, 3),
            (-5, 7),
            (7, 3),
        ] {
            for phase in [0.0, 180.0, 37.25, -90.0, 1e-3] {
                for k in 0..400 {
                    let theta = k as f64 * 0.9 * den as f64 + 0.1;
                    let (s, c) = sincos_deg2(
                        geared_degrees(num, den, theta, phase).0,
                        geared_degrees(num, den, theta, phase).1,
                    );
                    let (rs, rc) = reference(num, den, theta, phase);
                    worst = worst.max((s - rs).abs()).max((c - rc).abs());
                }
            }
        }
        assert!(worst < 2.5e-16, "worst error {worst:e}");
    }

    #[test]
    fn exact_multiples_and_symmetries() {
        let r = |n, d| GearRatio::new(n, d).unwrap();
        // θ5 = 2·45° + 0 = 90°; θ5 = −3·30° = −90°; 1/3 · 270° + 180° = 270°.
        assert_eq!(
            GearAngle::new(r(2, 1), 0.0, 45.0).second.sin,
            1.0,
            "sin 90°"
        );
        let a = GearAngle::new(r(-3, 1), 0.0, 30.0).second;
        assert_eq!((a.sin, a.cos, a.degrees), (-1.0, 0.0, 270.0));
        let a = GearAngle::new(r(1, 3), 180.0, 270.0).second;
        assert_eq!((a.sin, a.cos), (-1.0, 0.0));
        // The mirror gearing λ = −1, φ = 180° is exact at every sampled angle.
        for k in 0..3600 {
            let t = k as f64 * 0.1;
            let a = GearAngle::new(r(-1, 1), 180.0, t);
            assert_eq!(a.second.sin, a.input.sin, "{t}");
            assert_eq!(a.second.cos, -a.input.cos, "{t}");
        }
        // With λ = 1 and φ = 0 the cranks are parallel and ψ = 0.
        let a = GearAngle::new(r(1, 1), 0.0, 123.4);
        assert_eq!((a.rel_sin_half, a.rel_cos_half), (0.0, 1.0));
        assert_eq!((a.second.sin, a.second.cos), (a.input.sin, a.input.cos));
    }

    #[test]
    fn table_covers_the_period() {
        let t = GearTable::new(GearRatio::new(2, 3).unwrap(), 0.0, 10.0).unwrap();
        assert_eq!(t.len(), 108);
        assert!(GearTable::new(GearRatio::integer(1).unwrap(), 0.0, 0.0).is_none());
        assert!(GearTable::new(GearRatio::integer(1).unwrap(), f64::NAN, 1.0).is_none());
        assert_eq!(
            GearTable::new(GearRatio::integer(-2).unwrap(), 0.0, 7.0)
                .unwrap()
                .len(),
            52
        );
    }
}
