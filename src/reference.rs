//! A high-precision reference for tests and benchmarks: double-double arithmetic
//! (~32 significant digits; Dekker 1971, Knuth TAOCP 4.2.3, Hida–Li–Bailey's QD) and the
//! four-bar's position computed with it by an *independent* formulation: the half-chord
//! from `√(A² − a²)` (which cancels catastrophically in f64 near toggles, harmlessly in
//! double-double), and the crank's sine and cosine from Taylor series, not libm.
//!
//! Not on any hot path: it exists to measure the error of the methods that are.

use crate::linkage::{Circuit, CouplerPoint, FourBar};
use std::ops::{Add, Div, Mul, Neg, Sub};

/// A double-double number `hi + lo` with `|lo| ≤ ulp(hi)/2`.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
pub struct Dd {
    /// The leading part.
    pub hi: f64,
    /// The trailing part.
    pub lo: f64,
}

#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

#[inline]
fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

#[inline]
fn split(a: f64) -> (f64, f64) {
    const SPLITTER: f64 = 134_217_729.0; // 2^27 + 1
    let t = SPLITTER * a;
    let hi = t - (t - a);
    (hi, a - hi)
}

#[inline]
fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    (p, ((ah * bh - p) + ah * bl + al * bh) + al * bl)
}

impl Dd {
    /// An exact `f64`.
    pub const fn from_f64(x: f64) -> Dd {
        Dd { hi: x, lo: 0.0 }
    }

    /// The nearest `f64`.
    pub fn to_f64(self) -> f64 {
        self.hi + self.lo
    }

    /// Square root (one Newton step on the f64 root; Karp's trick).
    pub fn sqrt(self) -> Dd {
        if self.hi <= 0.0 {
            return Dd::from_f64(if self.hi == 0.0 { 0.0 } else { f64::NAN });
        }
        let x = 1.0 / self.hi.sqrt();
        let ax = self.hi * x;
        let diff = self - Dd::from_f64(ax) * Dd::from_f64(ax);
        Dd::from_f64(ax) + Dd::from_f64(diff.hi * (x * 0.5))
    }

    /// π in double-double.
    pub const PI: Dd = Dd {
        hi: std::f64::consts::PI,
        lo: 1.224_646_799_147_353_2e-16,
    };

    /// |x|.
    pub fn abs(self) -> Dd {
        if self.hi < 0.0 { -self } else { self }
    }
}

impl Add for Dd {
    type Output = Dd;
    fn add(self, b: Dd) -> Dd {
        let (s1, s2) = two_sum(self.hi, b.hi);
        let (t1, t2) = two_sum(self.lo, b.lo);
        let (s1, s2) = quick_two_sum(s1, s2 + t1);
        let (hi, lo) = quick_two_sum(s1, s2 + t2);
        Dd { hi, lo }
    }
}

impl Neg for Dd {
    type Output = Dd;
    fn neg(self) -> Dd {
        Dd {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Sub for Dd {
    type Output = Dd;
    fn sub(self, b: Dd) -> Dd {
        self + (-b)
    }
}

impl Mul for Dd {
    type Output = Dd;
    fn mul(self, b: Dd) -> Dd {
        let (p1, p2) = two_prod(self.hi, b.hi);
        let p2 = p2 + (self.hi * b.lo + self.lo * b.hi);
        let (hi, lo) = quick_two_sum(p1, p2);
        Dd { hi, lo }
    }
}

impl Div for Dd {
    type Output = Dd;
    fn div(self, b: Dd) -> Dd {
        let q1 = self.hi / b.hi;
        let r = self - b * Dd::from_f64(q1);
        let q2 = r.hi / b.hi;
        let r = r - b * Dd::from_f64(q2);
        let q3 = r.hi / b.hi;
        let (hi, lo) = quick_two_sum(q1, q2);
        Dd { hi, lo } + Dd::from_f64(q3)
    }
}

/// `(sin, cos)` of an angle in degrees, in double-double, by exact folding onto [0°, 45°]
/// and Taylor series.
pub fn sincos_deg_dd(degrees: f64) -> (Dd, Dd) {
    let negative = degrees < 0.0;
    let mut r = degrees.abs() % 360.0;
    let mut ss = if negative { -1.0 } else { 1.0 };
    let mut cs = 1.0;
    if r > 180.0 {
        r = 360.0 - r;
        ss = -ss;
    }
    if r > 90.0 {
        r = 180.0 - r;
        cs = -1.0;
    }
    let swap = r > 45.0;
    if swap {
        r = 90.0 - r;
    }
    let x = Dd::from_f64(r) * Dd::PI / Dd::from_f64(180.0);
    let x2 = x * x;
    // sin: x − x³/3! + …; cos: 1 − x²/2! + …
    let (mut s, mut c) = (x, Dd::from_f64(1.0));
    let (mut ts, mut tc) = (x, Dd::from_f64(1.0));
    for k in 1..40 {
        let k = k as f64;
        ts = -(ts * x2) / Dd::from_f64((2.0 * k) * (2.0 * k + 1.0));
        tc = -(tc * x2) / Dd::from_f64((2.0 * k - 1.0) * (2.0 * k));
        s = s + ts;
        c = c + tc;
        if ts.hi.abs() < 1e-40 && tc.hi.abs() < 1e-40 {
            break;
        }
    }
    let (s, c) = if swap { (c, s) } else { (s, c) };
    let sgn = |v: Dd, k: f64| if k < 0.0 { -v } else { v };
    (sgn(s, ss), sgn(c, cs))
}

/// The coupler point M at crank angle θ (degrees) in double-double, or `None` where the
/// linkage cannot be assembled. Lengths are taken as the exact `f64` values given.
pub fn coupler_point_dd(
    linkage: &FourBar,
    circuit: Circuit,
    point: CouplerPoint,
    degrees: f64,
) -> Option<(Dd, Dd)> {
    let a = Dd::from_f64(linkage.coupler);
    let b = Dd::from_f64(linkage.rocker);
    let c = Dd::from_f64(linkage.ground);
    let (s, co) = sincos_deg_dd(degrees);
    let wx = c - co;
    let wy = -s;
    let d2 = wx * wx + wy * wy;
    let d = d2.sqrt();
    if d.hi == 0.0 {
        return None;
    }
    let two = Dd::from_f64(2.0);
    let foot = (a * a - b * b + d2) / (two * d);
    let h2 = a * a - foot * foot;
    if h2.hi < 0.0 {
        return None;
    }
    let h = h2.sqrt();
    let sigma = Dd::from_f64(circuit.sign());
    // Pb − Pa = (foot/d)·w + σ(h/d)·J·w, J·w = (−wy, wx); e = (Pb − Pa)/A.
    let ex = (foot * wx - sigma * h * wy) / (d * a);
    let ey = (foot * wy + sigma * h * wx) / (d * a);
    let u = Dd::from_f64(point.u);
    let v = Dd::from_f64(point.v);
    Some((co + u * ex - v * ey, s + u * ey + v * ex))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dd_arithmetic() {
        let third = Dd::from_f64(1.0) / Dd::from_f64(3.0);
        let back = third * Dd::from_f64(3.0) - Dd::from_f64(1.0);
        assert!(back.to_f64().abs() < 1e-31);
        let r2 = Dd::from_f64(2.0).sqrt();
        assert!((r2 * r2 - Dd::from_f64(2.0)).to_f64().abs() < 1e-31);
    }

    #[test]
    fn dd_trig() {
        let (s, c) = sincos_deg_dd(30.0);
        assert!((s - Dd::from_f64(0.5)).to_f64().abs() < 1e-31);
        let (s, c2) = sincos_deg_dd(37.0);
        assert!((s * s + c2 * c2 - Dd::from_f64(1.0)).to_f64().abs() < 1e-31);
        let sqrt3_2 = Dd::from_f64(3.0).sqrt() / Dd::from_f64(2.0);
        assert!((c - sqrt3_2).to_f64().abs() < 1e-31);
        let (s, c) = sincos_deg_dd(-225.0);
        let r = Dd::from_f64(0.5).sqrt();
        assert!((s - r).to_f64().abs() < 1e-31 && (c + r).to_f64().abs() < 1e-31);
    }
}
