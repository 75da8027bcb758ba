//! A high-precision reference for tests and benchmarks: the four-bar's position computed
//! in double-double ([`Dd`]) by an *independent* formulation: the half-chord from
//! `√(A² − a²)` (which cancels catastrophically in f64 near toggles, harmlessly in
//! double-double), and the crank's sine and cosine from Taylor series, not libm.
//!
//! Not on any hot path: it exists to measure the error of the methods that are.

use coupler_kinematics::{Circuit, CouplerPoint, Dd, FourBar};

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

    #[test]
    fn sincos_deg_agrees_with_double_double() {
        for k in 0..720 {
            let t = k as f64 * 0.5;
            let (s, c) = coupler_kinematics::sincos_deg(t);
            let (es, ec) = sincos_deg_dd(t);
            let err = (s - es.to_f64()).abs().max((c - ec.to_f64()).abs());
            assert!(err < 2e-16, "{t}: error {err:e} against double-double");
        }
    }
}
