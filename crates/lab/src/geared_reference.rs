//! A double-double reference for the geared five-bar, for tests and benchmarks (the
//! five-bar's counterpart of [`crate::coupler_point_dd`]): an *independent* formulation of the
//! position, with the naive half-chord `√(L3² − a²)` from a `d` formed directly from the
//! pins (harmless in ~32 digits), the second crank's angle `θ5 = p·θ2/q + φ` reduced by
//! whole turns in double-double, and sines and cosines from Taylor series, not libm and
//! not the core's exact folding.
//!
//! Not on any hot path: it exists to measure the error of the methods that are.

use coupler_kinematics::Dd;
use coupler_kinematics::{Circuit, CouplerPoint, GearedFiveBar};

/// `(sin, cos)` of `deg` degrees (double-double), reduced by whole turns to
/// `[−180°, 180°]`, then Taylor series.
pub fn sincos_deg_dd2(deg: Dd) -> (Dd, Dd) {
    let d = Dd::from_f64;
    let turns = (deg.to_f64() / 360.0).round();
    let r = deg - d(turns) * d(360.0);
    let x = r * Dd::PI / d(180.0);
    let x2 = x * x;
    let (mut s, mut c, mut ts, mut tc) = (x, d(1.0), x, d(1.0));
    for k in 1..40 {
        let k = k as f64;
        ts = -(ts * x2) / d((2.0 * k) * (2.0 * k + 1.0));
        tc = -(tc * x2) / d((2.0 * k - 1.0) * (2.0 * k));
        s = s + ts;
        c = c + tc;
        if ts.hi.abs() < 1e-40 && tc.hi.abs() < 1e-40 {
            break;
        }
    }
    (s, c)
}

/// θ5 = p·θ2/q + φ in degrees, double-double.
pub fn second_crank_degrees_dd(linkage: &GearedFiveBar, theta2: f64) -> Dd {
    let d = Dd::from_f64;
    let r = linkage.ratio;
    d(r.num() as f64) * d(theta2) / d(r.den() as f64) + d(linkage.phase)
}

/// The pins and joint at input angle `theta2` (degrees) in double-double: `(Pa, Pd, P)`
/// as `(x, y)` pairs, or `None` where the dyad cannot close or Pa = Pd. Lengths are the
/// exact `f64` values given.
pub fn joints_dd(linkage: &GearedFiveBar, circuit: Circuit, theta2: f64) -> Option<[(Dd, Dd); 3]> {
    let d = Dd::from_f64;
    let (l1, l3, l4, l5) = (d(linkage.l1), d(linkage.l3), d(linkage.l4), d(linkage.l5));
    let (s2, c2) = sincos_deg_dd2(d(theta2));
    let (s5, c5) = sincos_deg_dd2(second_crank_degrees_dd(linkage, theta2));
    let (pdx, pdy) = (l1 + l5 * c5, l5 * s5);
    let (wx, wy) = (pdx - c2, pdy - s2);
    let d2 = wx * wx + wy * wy;
    if d2.hi == 0.0 {
        return None;
    }
    let dist = d2.sqrt();
    let foot = (l3 * l3 - l4 * l4 + d2) / (d(2.0) * dist);
    let h2 = l3 * l3 - foot * foot;
    if h2.hi < 0.0 {
        return None;
    }
    let h = h2.sqrt();
    let sigma = d(circuit.sign());
    let px = c2 + (foot * wx - sigma * h * wy) / dist;
    let py = s2 + (foot * wy + sigma * h * wx) / dist;
    Some([(c2, s2), (pdx, pdy), (px, py)])
}

/// The coupler point M = Pa + u·e + v·J·e, e = (P − Pa)/L3, at input angle `theta2`
/// (degrees) in double-double, or `None` where the dyad cannot close.
pub fn geared_point_dd(
    linkage: &GearedFiveBar,
    circuit: Circuit,
    point: CouplerPoint,
    theta2: f64,
) -> Option<(Dd, Dd)> {
    let [(pax, pay), _, (px, py)] = joints_dd(linkage, circuit, theta2)?;
    let l3 = Dd::from_f64(linkage.l3);
    let (ex, ey) = ((px - pax) / l3, (py - pay) / l3);
    let (u, v) = (Dd::from_f64(point.u), Dd::from_f64(point.v));
    Some((pax + u * ex - v * ey, pay + u * ey + v * ex))
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::GearRatio;

    #[test]
    fn closes_the_loop_in_double_double() {
        let g =
            GearedFiveBar::new(2.3, 2.9, 3.4, 1.7, GearRatio::new(-3, 2).unwrap(), 41.0).unwrap();
        let mut n = 0;
        for k in 0..720 {
            let Some([pa, pd, p]) = joints_dd(&g, Circuit::Open, k as f64) else {
                continue;
            };
            n += 1;
            let len = |a: (Dd, Dd), b: (Dd, Dd)| {
                let (x, y) = (a.0 - b.0, a.1 - b.1);
                (x * x + y * y).sqrt()
            };
            assert!((len(p, pa) - Dd::from_f64(2.9)).to_f64().abs() < 1e-28);
            assert!((len(p, pd) - Dd::from_f64(3.4)).to_f64().abs() < 1e-28);
        }
        assert!(n > 100);
    }
}
