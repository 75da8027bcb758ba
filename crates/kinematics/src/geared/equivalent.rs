//! Two constructions: the geared five-bar that traces a four-bar's coupler curve (Norton
//! §3.7, "geared fivebar cognates of the fourbar"), and the geared five-bar whose dyad
//! joint runs on an exact straight line (λ = −1, φ = 180°; Norton §3.8).

use super::linkage::{GearRatio, GearedError, GearedFiveBar};
use crate::{Circuit, CouplerPoint, FourBar};
use nalgebra::Point2;

/// Why a four-bar has no (non-degenerate) geared five-bar equivalent.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EquivalentError {
    /// The coupler point is the crank pin (u, v) = (0, 0) or the rocker pin (A, 0): one of
    /// the five-bar's cranks would have zero length.
    #[error(
        "coupler point ({u}, {v}) is the crank pin or the rocker pin: the geared five-bar equivalent has a zero-length crank"
    )]
    Degenerate {
        /// u.
        u: f64,
        /// v.
        v: f64,
    },
    /// The five-bar's lengths are not valid (non-finite input).
    #[error(transparent)]
    Linkage(#[from] GearedError),
}

/// The geared five-bar that traces the same coupler curve as a four-bar, placed in the
/// four-bar's frame (see [`geared_equivalent`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GearedEquivalent {
    /// The five-bar in its own units (input crank 1). Its ground pivots are the four-bar's
    /// O2 and O4.
    pub linkage: GearedFiveBar,
    /// The length of the five-bar's input crank in the four-bar's units, `s = √(u² + v²)`:
    /// a five-bar position `x` is the four-bar position `s·x` (same origin, same axes).
    pub scale: f64,
    /// The tracing point in the five-bar's frame: the dyad joint, `(L3, 0)`.
    pub point: CouplerPoint,
    /// `arg(u + i·v)` in degrees: the five-bar's input angle is the four-bar coupler's
    /// angle (direction of Pb − Pa) plus this.
    pub input_offset_deg: f64,
}

impl GearedEquivalent {
    /// A five-bar position in the four-bar's frame.
    pub fn to_four_bar_frame(&self, p: Point2<f64>) -> Point2<f64> {
        Point2::from(p.coords * self.scale)
    }

    /// The five-bar's input angle (degrees) and circuit in the four-bar configuration with
    /// crank pin `pa` and rocker pin `pb` (four-bar frame): `θ2' = arg(Pb − Pa) +
    /// input_offset_deg`, and the circuit is open iff the four-bar's crank and rocker turn
    /// counter-clockwise from one to the other, `(Pa − O2) × (Pb − O4) > 0` (the five-bar's
    /// dyad triangle has the sides `Pa − O2` and `Pb − O4`; it is flat, a toggle of the
    /// five-bar, where they are parallel).
    pub fn input_at(&self, four_bar: &FourBar, pa: Point2<f64>, pb: Point2<f64>) -> (f64, Circuit) {
        let k = pb - pa;
        let deg = libm::atan2(k.y, k.x).to_degrees() + self.input_offset_deg;
        let rho = pb - Point2::new(four_bar.ground, 0.0);
        let cross = pa.x * rho.y - pa.y * rho.x;
        let circuit = if cross >= 0.0 {
            Circuit::Open
        } else {
            Circuit::Crossed
        };
        (deg.rem_euclid(360.0), circuit)
    }
}

/// The geared five-bar equivalent of a four-bar (crank 1, coupler A, rocker B, ground C)
/// and coupler point (u, v): Norton's "geared fivebar cognate of the fourbar" (*Design of
/// Machinery* §3.7, after Chebyshev; Hartenberg & Denavit ch. 6, Cayley's diagram).
///
/// Construction, in complex numbers in the four-bar's frame: crank `c = Pa − O2`,
/// coupler `k = Pb − Pa`, rocker `ρ = Pb − O4`, `r = (u + i·v)/A`, so `M = Pa + r·k`.
/// Complete the two parallelograms on the coupler triangle's sides PaM and PbM:
/// `A1 = O2 + r·k` and `B2 = O4 + (r − 1)·k`. Then `M = A1 + c = B2 + ρ`: the five-bar
/// with ground pivots **O2 and O4**, cranks `O2A1 = r·k` and `O4B2 = (r − 1)·k` (both
/// parallel to coupler sides, so both turn with the coupler: **λ = +1**, an idler or chain
/// pair; **φ = arg(r − 1) − arg(r)**), and dyad links `A1M ∥ crank` (length 1) and
/// `B2M ∥ rocker` (length B) traces M at its dyad joint. Normalised to input crank 1 by
/// `s = |r|·A = √(u² + v²)`: `L1 = C/s`, `L5 = √((u − A)² + v²)/s`, `L3 = 1/s`, `L4 = B/s`.
///
/// Every configuration of either is a configuration of the other (the map is a bijection:
/// from the five-bar, `Pa = O2 + (M − A1)`, `Pb = O4 + (M − B2)`), so the five-bar's whole
/// curve, both circuits over every input angle where it assembles, is the four-bar's whole
/// curve, every branch and both circuits ([`crate::trace_full`]). The five-bar's
/// input turns with the four-bar's **coupler**, so it turns fully exactly when the
/// four-bar's coupler turns fully relative to the ground: Barker's GCCC and GRCR (e.g.
/// Chebyshev's straight-line linkage). In a crank-rocker and in every triple-rocker (RRR)
/// the coupler rocks, and so does the five-bar's input: its toggles are the four-bar
/// positions where crank and rocker are parallel (the coupler stands still there); see
/// docs/geared-fivebar.md. [`GearedEquivalent::input_at`] maps a four-bar configuration to
/// the five-bar's input angle and circuit.
///
/// ```
/// use coupler_kinematics::{FourBar, CouplerPoint, GearRatio, geared_equivalent};
/// let watt = FourBar::new(1.0, 1.0, 5f64.sqrt()).unwrap();
/// let eq = geared_equivalent(&watt, CouplerPoint::new(0.5, 0.0)).unwrap();
/// assert_eq!(eq.linkage.ratio, GearRatio::integer(1).unwrap());
/// assert_eq!(eq.linkage.phase, 180.0);
/// assert_eq!((eq.scale, eq.linkage.l3, eq.linkage.l4, eq.linkage.l5), (0.5, 2.0, 2.0, 1.0));
/// ```
pub fn geared_equivalent(
    four_bar: &FourBar,
    point: CouplerPoint,
) -> Result<GearedEquivalent, EquivalentError> {
    let (a, b, c) = (four_bar.coupler, four_bar.rocker, four_bar.ground);
    let (u, v) = (point.u, point.v);
    let s = u.hypot(v);
    let t = (u - a).hypot(v);
    if !(s > 0.0 && t > 0.0) {
        return Err(EquivalentError::Degenerate { u, v });
    }
    // φ = arg((u − A) + iv) − arg(u + iv) = arg(((u − A) + iv)·(u − iv)).
    let (re, im) = ((u - a) * u + v * v, v * u - (u - a) * v);
    let phase = if im == 0.0 {
        if re > 0.0 { 0.0 } else { 180.0 }
    } else {
        libm::atan2(im, re).to_degrees()
    };
    let offset = if v == 0.0 {
        if u > 0.0 { 0.0 } else { 180.0 }
    } else {
        libm::atan2(v, u).to_degrees()
    };
    let linkage = GearedFiveBar::new(c / s, 1.0 / s, b / s, t / s, GearRatio::integer(1)?, phase)?;
    Ok(GearedEquivalent {
        linkage,
        scale: s,
        point: CouplerPoint::new(linkage.l3, 0.0),
        input_offset_deg: offset,
    })
}

impl GearedFiveBar {
    /// The exact straight-line geared five-bar (Norton §3.8: gear ratio −1, phase 180°):
    /// `L5 = 1` (equal cranks), `L4 = L3` (equal dyad links), λ = −1, φ = 180°, on ground
    /// `l1`. Then `θ5 = 180° − θ2` puts the second crank's pin at
    /// `Pd = (L1 − cos θ2, sin θ2)`, the mirror image of `Pa` in the line `x = L1/2`; the
    /// dyad is isosceles, so its joint P lies on the perpendicular bisector of PaPd, which
    /// is that line, at every input angle and on either circuit:
    /// `P = (L1/2, sin θ2 ± √(L3² − (L1/2 − cos θ2)²))`. The condition (equal cranks and
    /// equal dyad links with these gears) is the one the symmetry needs; we know of no other.
    ///
    /// The input turns fully, never meeting a toggle, iff `L1 > 2` and `L3 > L1/2 + 1`
    /// (`d = |L1 − 2·cos θ2|` must stay in `(0, 2·L3)`; for `L1 ≤ 2`, Pa = Pd where
    /// `cos θ2 = L1/2` and the joint is undetermined there); the stroke of P then follows
    /// from the formula above.
    ///
    /// ```
    /// use coupler_kinematics::{Circuit, GearedFiveBar};
    /// let g = GearedFiveBar::straight_line(3.0, 3.0).unwrap();
    /// let c = g.trace(Circuit::Open, g.joint_point(), 1.0).unwrap();
    /// assert!(c.x.iter().all(|&x| (x - 1.5).abs() < 1e-15));
    /// ```
    pub fn straight_line(l1: f64, l3: f64) -> Result<GearedFiveBar, GearedError> {
        GearedFiveBar::new(l1, l3, l3, 1.0, GearRatio::integer(-1)?, 180.0)
    }

    /// The dyad joint P as a coupler point of L3: `(u, v) = (L3, 0)`.
    pub fn joint_point(&self) -> CouplerPoint {
        CouplerPoint::new(self.l3, 0.0)
    }
}
