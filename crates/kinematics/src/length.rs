//! Arc length of a coupler curve, exact to a relative tolerance: adaptive Gauss–Kronrod
//! quadrature of the analytic speed `|V(θ)|` over the mechanism's period.
//!
//! The trapezoid rule on evenly spaced samples converges geometrically for a smooth
//! periodic integrand, but `|V|` is not smooth where the speed vanishes (a cusp: `|V|`
//! has a kink there) or nearly vanishes (a near-cusp: a sharp, narrow dip), and there it
//! converges only like `h²`: a 1° step leaves errors of 1e-5 relative on such curves.
//!
//! Here the period is cut into panels and each is integrated by the 15-point
//! Gauss–Kronrod rule, its 7-point Gauss sub-rule giving the error estimate
//! `|K15 − G7|` (Piessens et al., QUADPACK, 1983). The poses at the panels' nodes are
//! solved once per mechanism and circuit and shared by every coupler point (as
//! [`PoseTable`] shares the samples'), so a smooth curve costs one pass over 24 × 15 node
//! speeds. A panel whose estimate exceeds its share of the tolerance is bisected, with
//! poses solved on demand for that point only, until every piece meets its share: only
//! the few panels holding a cusp or near-cusp are refined, and those converge because
//! the kink's error falls fourfold with each halving of the piece that holds it.

use crate::curve::{CrankTable, Curve, PoseTable};
use crate::linkage::{Circuit, CouplerPoint};
use crate::mechanism::Mechanism;
use crate::pose::CrankAngle;

/// The relative tolerance [`ArcLength`] is asked for by default: the sum of the
/// pieces' `|K15 − G7|` estimates is at most this fraction of the length. The estimate
/// bounds the 15-point rule's error from above: with a wide margin on a smooth piece
/// (where the true error is many orders smaller), by a small factor on a piece holding a
/// kink (a cusp), which is where the remaining error is.
pub const ARC_LENGTH_TOL: f64 = 1e-10;

/// Panels per 360° of input, each integrated by the 15-point rule before any refinement.
pub const ARC_LENGTH_PANELS_PER_TURN: usize = 36;

/// Bisections of one panel at most (a piece of 15° / 2^40 ≈ 1.4e-11°): beyond it a
/// piece is accepted as it is (never reached on atlas curves; a guard for degenerate
/// input).
const MAX_DEPTH: u32 = 40;

/// Kronrod nodes on [−1, 1] (the positive half; 0 last), QUADPACK's `qk15`.
const XGK: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
/// Kronrod weights of [`XGK`].
const WGK: [f64; 8] = [
    0.022_935_322_010_529_22,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_2,
    0.140_653_259_715_525_9,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_727_8,
];
/// Gauss weights of the 7-point rule, whose nodes are `XGK[1]`, `XGK[3]`, `XGK[5]`, `XGK[7]`.
const WG: [f64; 4] = [
    0.129_484_966_168_869_7,
    0.279_705_391_489_276_7,
    0.381_830_050_505_118_9,
    0.417_959_183_673_469_4,
];

/// The 15 node offsets of a panel, in units of its half-width, in ascending order.
fn nodes() -> [f64; 15] {
    let mut x = [0.0; 15];
    for k in 0..7 {
        x[k] = -XGK[k];
        x[14 - k] = XGK[k];
    }
    x
}

/// `(K15, G7)` of 15 values at [`nodes`] on a panel of half-width `half` (any unit).
fn rules(s: &[f64], half: f64) -> (f64, f64) {
    let mut k = WGK[7] * s[7];
    let mut g = WG[3] * s[7];
    for j in 0..7 {
        let pair = s[j] + s[14 - j];
        k += WGK[j] * pair;
        if j % 2 == 1 {
            g += WG[j / 2] * pair;
        }
    }
    (k * half, g * half)
}

/// Arc lengths `∮|V| dθ` (θ in radians, unit input speed) of the coupler curves of one
/// mechanism and circuit, over the mechanism's whole period
/// ([`Mechanism::period_deg`]), to a relative tolerance ([`ARC_LENGTH_TOL`] by default).
///
/// ```
/// use coupler_kinematics::{ArcLength, Circuit, CouplerPoint, FourBar};
/// let l = FourBar::new(3.0, 3.0, 3.0).unwrap();
/// let mut arc = ArcLength::new(&l, Circuit::Open).unwrap();
/// // The crank pin runs round the unit circle.
/// let s = arc.length(CouplerPoint::new(0.0, 0.0)).unwrap();
/// assert!((s - std::f64::consts::TAU).abs() < 1e-13);
/// ```
#[derive(Clone, Debug)]
pub struct ArcLength<M: Mechanism> {
    mechanism: M,
    /// The mechanism's [`Mechanism::constants`].
    constants: M::Constants,
    circuit: Circuit,
    /// Panel width, degrees.
    width_deg: f64,
    panels: usize,
    /// Poses at the 15 nodes of every panel, panel after panel.
    poses: PoseTable,
    /// The speeds of one point at those nodes (scratch).
    curve: Curve,
    tol: f64,
    /// Poses solved on demand while refining, for the last point measured.
    refined_poses: usize,
}

impl<M: Mechanism> ArcLength<M> {
    /// `None` unless the mechanism assembles at every node of the first pass (a curve
    /// whose input does not turn all the way round has no closed length).
    pub fn new(mechanism: &M, circuit: Circuit) -> Option<ArcLength<M>> {
        ArcLength::with_tolerance(mechanism, circuit, ARC_LENGTH_TOL)
    }

    /// With another relative tolerance (> 0).
    pub fn with_tolerance(mechanism: &M, circuit: Circuit, tol: f64) -> Option<ArcLength<M>> {
        if !(tol.is_finite() && tol > 0.0) {
            return None;
        }
        let period = mechanism.period_deg();
        let panels = ((period / 360.0).round() as usize).max(1) * ARC_LENGTH_PANELS_PER_TURN;
        let width_deg = period / panels as f64;
        let x = nodes();
        let angles = (0..panels)
            .flat_map(|p| {
                let mid = (p as f64 + 0.5) * width_deg;
                x.iter()
                    .map(move |&t| CrankAngle::from_degrees(mid + 0.5 * width_deg * t))
            })
            .collect();
        let poses = mechanism.pose_table(circuit, &CrankTable::from_angles(angles));
        poses.all_valid().then(|| ArcLength {
            mechanism: mechanism.clone(),
            constants: mechanism.constants(),
            circuit,
            width_deg,
            panels,
            poses,
            curve: Curve::default(),
            tol,
            refined_poses: 0,
        })
    }

    /// The length of the curve of `point`; `None` if the mechanism fails to assemble at
    /// an angle a refinement needs, or the speed is not finite.
    pub fn length(&mut self, point: CouplerPoint) -> Option<f64> {
        self.refined_poses = 0;
        self.poses.trace_into(point, &mut self.curve);
        let c = &self.curve;
        let speed: Vec<f64> = (0..c.len()).map(|k| c.vx[k].hypot(c.vy[k])).collect();
        let half = 0.5 * self.width_deg.to_radians();
        let panels: Vec<(f64, f64)> = speed.chunks_exact(15).map(|s| rules(s, half)).collect();
        let first: f64 = panels.iter().map(|p| p.0).sum();
        if !first.is_finite() {
            return None;
        }
        // Each panel's share of the tolerance: its width's fraction of the period.
        let share = self.tol * first / self.panels as f64;
        let mut total = 0.0;
        for (p, &(k, g)) in panels.iter().enumerate() {
            if (k - g).abs() <= share {
                total += k;
            } else {
                let a = p as f64 * self.width_deg;
                total += self.refine(point, a, a + self.width_deg, (k, g), share, 0)?;
            }
        }
        total.is_finite().then_some(total)
    }

    /// Poses solved on demand by the last [`ArcLength::length`] (0 when no panel needed
    /// refining): its cost beyond the shared pass.
    pub fn refined_poses(&self) -> usize {
        self.refined_poses
    }

    /// The integral over `[a, b]` degrees (whose rules gave `kg`), bisecting until each
    /// piece's estimate is within its share `share · (b − a) / width`.
    fn refine(
        &mut self,
        point: CouplerPoint,
        a: f64,
        b: f64,
        kg: (f64, f64),
        share: f64,
        depth: u32,
    ) -> Option<f64> {
        let allowed = share * (b - a) / self.width_deg;
        if (kg.0 - kg.1).abs() <= allowed || depth >= MAX_DEPTH {
            return Some(kg.0);
        }
        let m = 0.5 * (a + b);
        let left = self.panel(point, a, m)?;
        let right = self.panel(point, m, b)?;
        Some(
            self.refine(point, a, m, left, share, depth + 1)?
                + self.refine(point, m, b, right, share, depth + 1)?,
        )
    }

    /// `(K15, G7)` over `[a, b]` degrees, solving the 15 poses.
    fn panel(&mut self, point: CouplerPoint, a: f64, b: f64) -> Option<(f64, f64)> {
        let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
        let mut s = [0.0; 15];
        for (sk, t) in s.iter_mut().zip(nodes()) {
            let angle = CrankAngle::from_degrees(mid + half * t);
            let v = self
                .mechanism
                .frame_with(&self.constants, self.circuit, &angle)?
                .velocity(point);
            *sk = v.x.hypot(v.y);
        }
        self.refined_poses += 15;
        s.iter()
            .all(|x| x.is_finite())
            .then(|| rules(&s, half.to_radians()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linkage::FourBar;

    #[test]
    fn rules_integrate_polynomials_exactly() {
        // K15 is exact to degree 22, G7 to degree 13: ∫_{−1}^{1} x^n = 2/(n + 1) for even n.
        let x = nodes();
        for n in [0, 2, 4, 12, 22] {
            let s: Vec<f64> = x.iter().map(|t| t.powi(n)).collect();
            let (k, g) = rules(&s, 1.0);
            let exact = 2.0 / (n as f64 + 1.0);
            assert!((k - exact).abs() < 1e-15, "K15 x^{n}: {k} vs {exact}");
            if n <= 12 {
                assert!((g - exact).abs() < 1e-15, "G7 x^{n}: {g} vs {exact}");
            }
        }
        // Odd powers vanish by symmetry of the nodes.
        let s: Vec<f64> = x.iter().map(|t| t.powi(7)).collect();
        assert!(rules(&s, 1.0).0.abs() < 1e-16);
    }

    #[test]
    fn rocker_pin_sweeps_twice_its_swing() {
        // The rocker pin (u = A, v = 0) moves on the circle of radius B about O4 between
        // the rocker's two extremes and back: its length is 2·B·swing. The extremes are
        // where crank and coupler line up, O2–Pb = A + 1 (extended) and A − 1 (folded),
        // and the law of cosines in O2, O4, Pb gives the rocker's angle there. Its speed
        // vanishes at both: two kinks of |V|, the hard case of a cusp.
        for (a, b, c) in [(3.0, 3.0, 3.0), (2.5, 2.0, 2.5), (4.0, 2.0, 4.5)] {
            let l = FourBar::new(a, b, c).unwrap();
            let angle_at_o4 = |r: f64| ((b * b + c * c - r * r) / (2.0 * b * c)).acos();
            let swing = (angle_at_o4(a + 1.0) - angle_at_o4(a - 1.0)).abs();
            let exact = 2.0 * b * swing;
            for circuit in [Circuit::Open, Circuit::Crossed] {
                let mut arc = ArcLength::new(&l, circuit).unwrap();
                let s = arc.length(CouplerPoint::new(a, 0.0)).unwrap();
                // Within the tolerance asked for (the sum of the pieces' estimates).
                assert!(
                    ((s - exact) / exact).abs() < ARC_LENGTH_TOL,
                    "{a} {b} {c} {circuit:?}: {s} vs {exact}"
                );
                assert!(arc.refined_poses() > 0, "the kinks are refined");
            }
        }
    }

    #[test]
    fn smooth_curve_needs_no_refinement() {
        let l = FourBar::new(3.0, 3.0, 3.0).unwrap();
        let mut arc = ArcLength::new(&l, Circuit::Open).unwrap();
        let s = arc.length(CouplerPoint::new(0.0, 0.0)).unwrap();
        assert!((s - std::f64::consts::TAU).abs() < 1e-13);
        assert_eq!(arc.refined_poses(), 0);
    }
}
