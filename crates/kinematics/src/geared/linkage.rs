//! The geared five-bar linkage: its lengths, gear ratio and phase, and Ting's class.

use crate::Decimal;
use serde::{Deserialize, Serialize};
use std::cmp::Ordering;
use std::fmt;

/// The largest numerator or denominator a [`GearRatio`] may have. Gear trains have small
/// tooth-count ratios; the bound keeps the period (`360° · denominator`) and the exact
/// products `numerator · θ2` of [`crate::GearAngle`] in range.
pub const MAX_GEAR_TERM: i64 = 1000;

/// Why a set of lengths, a gear ratio or a phase is not a geared five-bar.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GearedError {
    /// A length is zero, negative, NaN or infinite.
    #[error("{link} length must be a finite number > 0, got {value}")]
    BadLength {
        /// `L1` (ground), `L3`, `L4` or `L5`.
        link: &'static str,
        /// The value given.
        value: f64,
    },
    /// The gear ratio is zero: the second crank would not turn (the linkage is a four-bar).
    #[error("gear ratio must not be 0 (the second crank would stand still: use a four-bar)")]
    ZeroRatio,
    /// The gear ratio's denominator is zero.
    #[error("gear ratio {num}/0 has a zero denominator")]
    ZeroDenominator {
        /// The numerator given.
        num: i64,
    },
    /// Numerator or denominator (in lowest terms) beyond [`MAX_GEAR_TERM`].
    #[error(
        "gear ratio {num}/{den} is too fine: numerator and denominator must be at most {MAX_GEAR_TERM} in lowest terms"
    )]
    RatioTooFine {
        /// Numerator in lowest terms.
        num: i64,
        /// Denominator in lowest terms.
        den: i64,
    },
    /// A gear ratio text that is not `p` or `p/q` with integers p, q.
    #[error(
        "`{0}` is not a gear ratio (expected an integer `p` or a fraction `p/q`, e.g. `-1`, `2`, `-1/2`)"
    )]
    BadRatioText(String),
    /// The phase is NaN or infinite.
    #[error("phase must be a finite number of degrees, got {0}")]
    BadPhase(f64),
}

/// The gear ratio λ = θ̇5 / θ̇2 = `num / den` of a geared five-bar, a rational number in
/// lowest terms with `den > 0`. Negative for an external gear pair (the cranks turn in
/// opposite directions), positive for an internal pair or a pair coupled through an idler
/// or a chain (Norton, *Design of Machinery*, §2 "Geared fivebar linkages").
///
/// Stored as integers so that the second crank's angle `θ5 = λ·θ2 + φ` can be formed
/// exactly and the period ([`GearRatio::period_deg`]) is exact.
///
/// ```
/// use coupler_kinematics::GearRatio;
/// let r: GearRatio = "-2/4".parse().unwrap();
/// assert_eq!((r.num(), r.den()), (-1, 2));
/// assert_eq!(r.to_string(), "-1/2");
/// assert_eq!(r.period_deg(), 720.0);
/// assert!("0".parse::<GearRatio>().is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct GearRatio {
    num: i64,
    den: i64,
}

fn gcd(a: i64, b: i64) -> i64 {
    let (mut a, mut b) = (a.abs(), b.abs());
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

impl GearRatio {
    /// λ = `num / den`, reduced to lowest terms with a positive denominator. Errors for
    /// `num = 0`, `den = 0`, or terms beyond [`MAX_GEAR_TERM`] in lowest terms.
    pub fn new(num: i64, den: i64) -> Result<GearRatio, GearedError> {
        if den == 0 {
            return Err(GearedError::ZeroDenominator { num });
        }
        if num == 0 {
            return Err(GearedError::ZeroRatio);
        }
        let g = gcd(num, den);
        let sign = if den < 0 { -1 } else { 1 };
        let (num, den) = (sign * (num / g), sign * (den / g));
        if num.abs() > MAX_GEAR_TERM || den > MAX_GEAR_TERM {
            return Err(GearedError::RatioTooFine { num, den });
        }
        Ok(GearRatio { num, den })
    }

    /// An integer ratio λ = `n`.
    pub fn integer(n: i64) -> Result<GearRatio, GearedError> {
        GearRatio::new(n, 1)
    }

    /// The numerator (sign of λ).
    pub fn num(self) -> i64 {
        self.num
    }

    /// The denominator (> 0).
    pub fn den(self) -> i64 {
        self.den
    }

    /// λ as a float (for display and tests; the kinematics use `num` and `den`).
    pub fn value(self) -> f64 {
        self.num as f64 / self.den as f64
    }

    /// The period of the mechanism in degrees of input: `360° · den`. After it both cranks
    /// are back where they started (θ2 has turned `den` times, θ5 `num` times); no shorter
    /// input turn does that, since `num/den` is in lowest terms.
    pub fn period_deg(self) -> f64 {
        360.0 * self.den as f64
    }
}

impl fmt::Display for GearRatio {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.den == 1 {
            write!(f, "{}", self.num)
        } else {
            write!(f, "{}/{}", self.num, self.den)
        }
    }
}

impl std::str::FromStr for GearRatio {
    type Err = GearedError;

    /// `p` or `p/q` (integers, optional sign; `−` U+2212 is accepted as a minus).
    fn from_str(text: &str) -> Result<GearRatio, GearedError> {
        let bad = || GearedError::BadRatioText(text.to_string());
        let s = text.trim().replace('\u{2212}', "-");
        let int = |t: &str| t.trim().parse::<i64>().map_err(|_| bad());
        let (num, den) = match s.split_once('/') {
            Some((p, q)) => (int(p)?, int(q)?),
            None => (int(&s)?, 1),
        };
        GearRatio::new(num, den)
    }
}

impl TryFrom<String> for GearRatio {
    type Error = GearedError;
    fn try_from(s: String) -> Result<GearRatio, GearedError> {
        s.parse()
    }
}

impl From<GearRatio> for String {
    fn from(r: GearRatio) -> String {
        r.to_string()
    }
}

/// A geared five-bar linkage in Norton's numbering (*Design of Machinery*, §2 "Geared
/// fivebar linkages", and his program FIVEBAR), in units of the input crank:
///
/// - ground `L1` from O2 = (0, 0) to O5 = (L1, 0);
/// - input crank `L2 = 1` at O2, pin `Pa = (cos θ2, sin θ2)`;
/// - second crank `L5` at O5, pin `Pd = O5 + L5·(cos θ5, sin θ5)`, driven through the
///   gears: **θ5 = λ·θ2 + φ** (λ the [`GearRatio`], φ the phase in degrees);
/// - the dyad: link `L3` from Pa and link `L4` from Pd, meeting at the joint P.
///
/// Circuits as for the four-bar ([`crate::Circuit`]): **open** when P lies left of the
/// directed line Pa→Pd, `(Pd − Pa) × (P − Pa) > 0`; **crossed** when right. The coupler
/// point is carried by `L3`: `M = Pa + u·e + v·J·e`, `e = (P − Pa)/L3`, J the +90°
/// rotation ([`crate::CouplerPoint`]); the joint P itself is `(u, v) = (L3, 0)`.
///
/// ```
/// use coupler_kinematics::{GearedFiveBar, GearRatio, TingClass};
/// let g = GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::integer(-1).unwrap(), 0.0).unwrap();
/// assert_eq!(g.ting_class(), TingClass::I); // sorted 1, 1, 3, 3, 3: 1 + 1 + 3 < 3 + 3
/// assert!(g.turns_for_any_gearing()); // the two shortest are the cranks
/// assert_eq!(g.period_deg(), 360.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GearedFiveBar {
    /// Ground L1 (O2 to O5).
    pub l1: f64,
    /// Dyad link L3, from the input crank's pin Pa to the joint P (carries the coupler point).
    pub l3: f64,
    /// Dyad link L4, from the second crank's pin Pd to the joint P.
    pub l4: f64,
    /// Second crank L5 (at O5).
    pub l5: f64,
    /// Gear ratio λ.
    pub ratio: GearRatio,
    /// Phase φ in degrees: θ5 = λ·θ2 + φ.
    pub phase: f64,
}

/// Ting's rotatability class of the five-bar chain (K.-L. Ting, "Five-bar Grashof
/// criteria", ASME J. Mech. Trans. Automation Design 108, 1986; Norton §2): with the
/// five lengths sorted `L(1) ≤ L(2) ≤ L(3) ≤ L(4) ≤ L(5)` (whatever links they are),
/// compare `L(1) + L(2) + L(5)` with `L(3) + L(4)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum TingClass {
    /// `L(1) + L(2) + L(5) < L(3) + L(4)`: the two shortest links turn fully relative to
    /// every other link (the five-bar "Grashof" case).
    I,
    /// `L(1) + L(2) + L(5) > L(3) + L(4)`: no link turns fully for every position of the
    /// other input; a geared five-bar may still turn fully, depending on λ and φ.
    II,
    /// Equality: the chain can fold flat (change points), where both circuits meet.
    III,
}

impl TingClass {
    /// `"I"`, `"II"` or `"III"`.
    pub fn code(self) -> &'static str {
        match self {
            TingClass::I => "I",
            TingClass::II => "II",
            TingClass::III => "III",
        }
    }
}

impl fmt::Display for TingClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Class {}", self.code())
    }
}

impl GearedFiveBar {
    /// A geared five-bar with input crank 1. Errors unless every length is finite and
    /// positive and the phase is finite (the ratio is valid by construction).
    pub fn new(
        l1: f64,
        l3: f64,
        l4: f64,
        l5: f64,
        ratio: GearRatio,
        phase: f64,
    ) -> Result<GearedFiveBar, GearedError> {
        for (link, value) in [("L1", l1), ("L3", l3), ("L4", l4), ("L5", l5)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(GearedError::BadLength { link, value });
            }
        }
        if !phase.is_finite() {
            return Err(GearedError::BadPhase(phase));
        }
        Ok(GearedFiveBar {
            l1,
            l3,
            l4,
            l5,
            ratio,
            phase,
        })
    }

    /// The five lengths in Norton's order `[L1, L2, L3, L4, L5]` (L2 = 1).
    pub fn lengths(&self) -> [f64; 5] {
        [self.l1, 1.0, self.l3, self.l4, self.l5]
    }

    /// The second crank's pivot O5 = (L1, 0).
    pub fn o5(&self) -> nalgebra::Point2<f64> {
        nalgebra::Point2::new(self.l1, 0.0)
    }

    /// The mechanism's period in degrees of input, `360° · q` for λ = p/q in lowest
    /// terms ([`GearRatio::period_deg`]): a curve is sampled over θ2 ∈ [0, 360°·q).
    pub fn period_deg(&self) -> f64 {
        self.ratio.period_deg()
    }

    /// The lengths as exact decimals (each `f64` read as the shortest decimal that rounds
    /// to it, as [`crate::FourBar::exact_lengths`] does), in the order of [`Self::lengths`].
    pub fn exact_lengths(&self) -> [Decimal; 5] {
        self.lengths()
            .map(|x| Decimal::from_f64(x).unwrap_or(Decimal::ZERO))
    }

    /// `L(1) + L(2) + L(5)` against `L(3) + L(4)` with the lengths sorted, exactly.
    fn ting_ordering(&self) -> Ordering {
        let mut l = self.exact_lengths();
        l.sort();
        Decimal::compare_sums(&[l[0], l[1], l[4]], &[l[2], l[3]]).unwrap_or_else(|| {
            let f = |x: Decimal| x.to_f64();
            (f(l[0]) + f(l[1]) + f(l[4]))
                .partial_cmp(&(f(l[2]) + f(l[3])))
                .unwrap_or(Ordering::Greater)
        })
    }

    /// Ting's class ([`TingClass`]), decided with exact decimal arithmetic (like
    /// [`crate::FourBar::class`]), so that an equality on a decimal grid is never a float
    /// coin-flip. The ordering is by length, whatever link each is: Ting's
    /// `l_max + l_min1 + l_min2 ⋚ m + n` (his abstract states Class I with `≤`; the equality
    /// is Norton's Class III, the change-point case, as here).
    pub fn ting_class(&self) -> TingClass {
        match self.ting_ordering() {
            Ordering::Less => TingClass::I,
            Ordering::Greater => TingClass::II,
            Ordering::Equal => TingClass::III,
        }
    }

    /// Whether the input turns fully for **every** gear ratio and phase, without ever
    /// meeting a toggle: Ting's double-crank case, Class I with the two shortest links
    /// among the ground and the two cranks (L1, L2, L5). Decided exactly.
    ///
    /// Why: the dyad closes iff `|L3 − L4| ≤ d ≤ L3 + L4`, `d = |Pd − Pa|`. Over all
    /// (θ2, θ5) the largest d is `L1 + 1 + L5` and the smallest is
    /// `max(0, L1 − 1 − L5, L5 − 1 − L1, 1 − L1 − L5)`; with the two shortest links among
    /// L1, L2, L5, Class I's strict inequality gives `L1 + 1 + L5 < L3 + L4` and
    /// `|L3 − L4| <` the smallest d (docs/geared-fivebar.md, "Rotatability", works the
    /// cases). So the dyad closes strictly at every (θ2, θ5), whatever the gears make of them.
    /// Otherwise whether a given (λ, φ) turns fully is a property of the gears too: see
    /// [`GearedFiveBar::rotatability`].
    pub fn turns_for_any_gearing(&self) -> bool {
        if self.ting_class() != TingClass::I {
            return false;
        }
        let [l1, l2, l3, l4, l5] = self.exact_lengths();
        let mut cranks = [l1, l2, l5];
        cranks.sort();
        // The second shortest of {L1, L2, L5} is no longer than the shorter dyad link.
        cranks[1] <= l3.min(l4)
    }
}

impl fmt::Display for GearedFiveBar {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "L1={} L3={} L4={} L5={} ratio={} phase={}",
            self.l1, self.l3, self.l4, self.l5, self.ratio, self.phase
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn g(l1: f64, l3: f64, l4: f64, l5: f64) -> GearedFiveBar {
        GearedFiveBar::new(l1, l3, l4, l5, GearRatio::integer(-1).unwrap(), 0.0).unwrap()
    }

    #[test]
    fn ratio_reduces_and_rejects() {
        let r = GearRatio::new(4, -6).unwrap();
        assert_eq!((r.num(), r.den()), (-2, 3));
        assert_eq!(r.period_deg(), 1080.0);
        assert_eq!(GearRatio::new(0, 3), Err(GearedError::ZeroRatio));
        assert_eq!(
            GearRatio::new(3, 0),
            Err(GearedError::ZeroDenominator { num: 3 })
        );
        assert!(matches!(
            GearRatio::new(1, 1001),
            Err(GearedError::RatioTooFine { .. })
        ));
        assert_eq!(GearRatio::new(2000, 1000).unwrap().to_string(), "2");
        for (text, shown) in [("-1", "-1"), ("\u{2212}1/2", "-1/2"), (" 2 / 1 ", "2")] {
            assert_eq!(text.parse::<GearRatio>().unwrap().to_string(), shown);
        }
        for bad in ["", "x", "1/", "1.5", "1/2/3"] {
            assert!(
                matches!(bad.parse::<GearRatio>(), Err(GearedError::BadRatioText(_))),
                "{bad}"
            );
        }
        let json = serde_json::to_string(&GearRatio::new(-1, 2).unwrap()).unwrap();
        assert_eq!(json, "\"-1/2\"");
        assert!(serde_json::from_str::<GearRatio>("\"0\"").is_err());
    }

    #[test]
    fn rejects_bad_lengths_and_phase() {
        let r = GearRatio::integer(2).unwrap();
        assert!(matches!(
            GearedFiveBar::new(0.0, 1.0, 1.0, 1.0, r, 0.0),
            Err(GearedError::BadLength { link: "L1", .. })
        ));
        assert!(GearedFiveBar::new(1.0, -1.0, 1.0, 1.0, r, 0.0).is_err());
        assert!(GearedFiveBar::new(1.0, 1.0, f64::NAN, 1.0, r, 0.0).is_err());
        assert!(GearedFiveBar::new(1.0, 1.0, 1.0, f64::INFINITY, r, 0.0).is_err());
        assert!(matches!(
            GearedFiveBar::new(1.0, 1.0, 1.0, 1.0, r, f64::NAN),
            Err(GearedError::BadPhase(_))
        ));
    }

    #[test]
    fn ting_classes() {
        assert_eq!(g(3.0, 3.0, 3.0, 1.0).ting_class(), TingClass::I);
        assert_eq!(g(2.0, 3.0, 3.0, 1.5).ting_class(), TingClass::II); // 1 + 1.5 + 3 > 2 + 3
        assert_eq!(g(4.0, 1.0, 1.0, 1.0).ting_class(), TingClass::II);
        // 1 + 1 + 2 = 2 + 2.
        assert_eq!(g(2.0, 2.0, 2.0, 1.0).ting_class(), TingClass::III);
        // Sorted 0.1, 0.2, 0.4, 1, 1.1: 0.1 + 0.2 + 1.1 = 0.4 + 1 exactly, though not in f64.
        assert_ne!(0.1 + 0.2 + 1.1, 0.4 + 1.0);
        let l =
            GearedFiveBar::new(0.4, 0.1, 1.1, 0.2, GearRatio::integer(1).unwrap(), 0.0).unwrap();
        assert_eq!(l.ting_class(), TingClass::III);
    }

    #[test]
    fn any_gearing_needs_class_one_and_short_cranks() {
        // Cranks 1 and 1 shortest, Class I.
        assert!(g(3.0, 3.0, 3.0, 1.0).turns_for_any_gearing());
        // Ground and input crank shortest (sorted 1, 1, 3, 3, 3.5: 5.5 < 6).
        assert!(g(1.0, 3.0, 3.0, 3.5).turns_for_any_gearing());
        // Class I (0.5 + 1 + 3 < 2.5 + 3) but the shortest are L3 and L2: depends on the gears.
        assert!(!g(3.0, 0.5, 3.0, 2.5).turns_for_any_gearing());
        // Class II.
        assert!(!g(2.0, 3.0, 3.0, 1.5).turns_for_any_gearing());
        // Class III.
        assert!(!g(2.0, 2.0, 2.0, 1.0).turns_for_any_gearing());
    }
}
