//! The four-bar linkage, its circuits and Barker's classification.

use crate::exact::Decimal;
use serde::{Deserialize, Serialize};
use std::cmp::Ordering;
use std::fmt;

/// A planar four-bar in Hrones & Nelson's units: crank = 1, coupler `A`, rocker `B`,
/// ground `C`.
///
/// Ground pivots: crank pivot O2 = (0, 0), rocker pivot O4 = (C, 0) (docs/conventions.md §1).
///
/// ```
/// use coupler_kinematics::{FourBar, Class};
/// let hoeken = FourBar::new(2.5, 2.5, 2.0).unwrap();
/// assert_eq!(hoeken.class(), Class::Gcrr);
/// assert!(hoeken.is_crank_rocker());
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FourBar {
    /// Coupler length A (crank pin to rocker pin).
    pub coupler: f64,
    /// Rocker length B.
    pub rocker: f64,
    /// Ground length C (O2 to O4).
    pub ground: f64,
}

/// Why a set of lengths is not a four-bar.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LinkageError {
    /// A length is zero, negative, NaN or infinite.
    #[error("{link} length must be a finite number > 0, got {value}")]
    BadLength {
        /// `coupler`, `rocker` or `ground`.
        link: &'static str,
        /// The value given.
        value: f64,
    },
}

impl FourBar {
    /// A four-bar with crank 1. Errors unless every length is finite and positive.
    pub fn new(coupler: f64, rocker: f64, ground: f64) -> Result<FourBar, LinkageError> {
        for (link, value) in [("coupler", coupler), ("rocker", rocker), ("ground", ground)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(LinkageError::BadLength { link, value });
            }
        }
        Ok(FourBar {
            coupler,
            rocker,
            ground,
        })
    }

    /// The lengths as exact decimals (each `f64` read as the shortest decimal that rounds
    /// to it): crank, coupler, rocker, ground.
    pub fn exact_lengths(&self) -> [Decimal; 4] {
        let d = |x: f64| Decimal::from_f64(x).unwrap_or(Decimal::ZERO);
        [
            Decimal::new(1, 0),
            d(self.coupler),
            d(self.rocker),
            d(self.ground),
        ]
    }

    /// Barker's class (Norton, *Design of Machinery*, Table 2-4), decided with exact
    /// decimal arithmetic so that `s + l = p + q` on a decimal grid is never a float
    /// coin-flip. Input = crank, output = rocker.
    ///
    /// Far from the Grashof equality it is decided on the `f64` lengths themselves, with
    /// the same result: the exact decimals sort as the `f64`s do (the shortest decimal
    /// that rounds to `x` increases with `x`, and equal decimals are equal `f64`s), and
    /// each decimal is within half an ulp of its `f64` (2⁻⁵³ of it), so `s + l − p − q`
    /// computed in `f64` is within `3·2⁻⁵³·(s + l + p + q)` of the exact difference: when
    /// it is larger than `10⁻¹²·(s + l + p + q)` in size, its sign is the exact one.
    /// Nearer the equality the exact decimals decide (as they always did).
    pub fn class(&self) -> Class {
        let floats = [self.ground, 1.0, self.coupler, self.rocker];
        if floats.iter().all(|x| x.is_finite() && *x > 0.0) {
            let mut sorted = floats;
            sorted.sort_by(f64::total_cmp);
            let (s, p, q, l) = (sorted[0], sorted[1], sorted[2], sorted[3]);
            let diff = (s + l) - (p + q);
            if diff.abs() > 1e-12 * (s + l + p + q) {
                let which = |x: f64| floats.iter().position(|&y| y == x).unwrap_or(0);
                return if diff < 0.0 {
                    [Class::Gccc, Class::Gcrr, Class::Grcr, Class::Grrc][which(s)]
                } else {
                    [Class::Rrr1, Class::Rrr2, Class::Rrr3, Class::Rrr4][which(l)]
                };
            }
        }
        self.class_exact()
    }

    /// [`FourBar::class`] decided on the exact decimals alone.
    fn class_exact(&self) -> Class {
        let [crank, coupler, rocker, ground] = self.exact_lengths();
        // Barker's link order: L1 ground, L2 input, L3 coupler, L4 output.
        let links = [ground, crank, coupler, rocker];
        let mut sorted = links;
        sorted.sort();
        let (s, p, q, l) = (sorted[0], sorted[1], sorted[2], sorted[3]);
        let grashof = Decimal::compare_sums(&[s, l], &[p, q]).unwrap_or_else(|| {
            let f = |x: Decimal| x.to_f64();
            (f(s) + f(l))
                .partial_cmp(&(f(p) + f(q)))
                .unwrap_or(Ordering::Greater)
        });
        let which = |x: Decimal| links.iter().position(|&y| y == x).unwrap_or(0);
        match grashof {
            Ordering::Less => [Class::Gccc, Class::Gcrr, Class::Grcr, Class::Grrc][which(s)],
            Ordering::Greater => [Class::Rrr1, Class::Rrr2, Class::Rrr3, Class::Rrr4][which(l)],
            Ordering::Equal => {
                if s == l {
                    Class::S3x
                } else if s == p || q == l {
                    // s + l = p + q with a tie at either end forces two equal pairs.
                    Class::S2x
                } else {
                    [Class::Sccc, Class::Scrr, Class::Srcr, Class::Srrc][which(s)]
                }
            }
        }
    }

    /// A strict crank-rocker (`GCRR`): `|A − B| + 1 < C < A + B − 1` (docs/conventions.md §2), so the
    /// crank turns fully and never meets a toggle. Decided exactly.
    pub fn is_crank_rocker(&self) -> bool {
        self.class() == Class::Gcrr
    }
}

impl fmt::Display for FourBar {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "A={} B={} C={}", self.coupler, self.rocker, self.ground)
    }
}

/// Barker's 14 classes of four-bar (Norton, Table 2-4). Letters: input, coupler, output;
/// `G` Grashof, `S` special (change-point) case, `R` non-Grashof.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum Class {
    Gccc,
    Gcrr,
    Grcr,
    Grrc,
    Rrr1,
    Rrr2,
    Rrr3,
    Rrr4,
    Sccc,
    Scrr,
    Srcr,
    Srrc,
    S2x,
    S3x,
}

impl Class {
    /// Barker's code, e.g. `"GCRR"`.
    pub fn code(self) -> &'static str {
        match self {
            Class::Gccc => "GCCC",
            Class::Gcrr => "GCRR",
            Class::Grcr => "GRCR",
            Class::Grrc => "GRRC",
            Class::Rrr1 => "RRR1",
            Class::Rrr2 => "RRR2",
            Class::Rrr3 => "RRR3",
            Class::Rrr4 => "RRR4",
            Class::Sccc => "SCCC",
            Class::Scrr => "SCRR",
            Class::Srcr => "SRCR",
            Class::Srrc => "SRRC",
            Class::S2x => "S2X",
            Class::S3x => "S3X",
        }
    }

    /// All classes, in Barker's order.
    pub const ALL: [Class; 14] = [
        Class::Gccc,
        Class::Gcrr,
        Class::Grcr,
        Class::Grrc,
        Class::Rrr1,
        Class::Rrr2,
        Class::Rrr3,
        Class::Rrr4,
        Class::Sccc,
        Class::Scrr,
        Class::Srcr,
        Class::Srrc,
        Class::S2x,
        Class::S3x,
    ];

    /// Grashof (`s + l < p + q`).
    pub fn is_grashof(self) -> bool {
        self.code().starts_with('G')
    }

    /// Special case (`s + l = p + q`): the links can fold flat at a change point.
    pub fn is_change_point(self) -> bool {
        self.code().starts_with('S')
    }
}

impl std::str::FromStr for Class {
    type Err = String;
    fn from_str(s: &str) -> Result<Class, String> {
        Class::ALL
            .into_iter()
            .find(|c| c.code().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                format!(
                    "unknown class `{s}` (expected one of {})",
                    Class::ALL.map(|c| c.code()).join(", ")
                )
            })
    }
}

impl fmt::Display for Class {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.code())
    }
}

/// The assembly (branch) of the linkage (docs/conventions.md §1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Circuit {
    /// `(O4 − Pa) × (Pb − Pa) > 0`: the rocker pin left of the directed line Pa→O4.
    Open,
    /// The same cross product `< 0`.
    Crossed,
}

impl Circuit {
    /// `+1` for open, `−1` for crossed: the sign σ of the half-chord.
    pub fn sign(self) -> f64 {
        match self {
            Circuit::Open => 1.0,
            Circuit::Crossed => -1.0,
        }
    }

    /// `"open"` or `"crossed"`.
    pub fn name(self) -> &'static str {
        match self {
            Circuit::Open => "open",
            Circuit::Crossed => "crossed",
        }
    }

    /// The other circuit.
    pub fn other(self) -> Circuit {
        match self {
            Circuit::Open => Circuit::Crossed,
            Circuit::Crossed => Circuit::Open,
        }
    }
}

impl std::str::FromStr for Circuit {
    type Err = String;
    fn from_str(s: &str) -> Result<Circuit, String> {
        match s {
            "open" => Ok(Circuit::Open),
            "crossed" => Ok(Circuit::Crossed),
            _ => Err(format!(
                "unknown circuit `{s}` (expected `open` or `crossed`)"
            )),
        }
    }
}

impl fmt::Display for Circuit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A coupler point M given in the frame carried by the coupler: origin at the crank pin
/// Pa, `+u` towards the rocker pin Pb, `+v` rotated 90° counter-clockwise from `+u`.
/// With `e = (Pb − Pa)/A` and `J` the +90° rotation, `M = Pa + u·e + v·J·e`
/// (docs/conventions.md §1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CouplerPoint {
    /// Along the coupler, from the crank pin.
    pub u: f64,
    /// Across the coupler, to the left of Pa→Pb.
    pub v: f64,
}

impl CouplerPoint {
    /// The point (u, v).
    pub fn new(u: f64, v: f64) -> CouplerPoint {
        CouplerPoint { u, v }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn class(a: f64, b: f64, c: f64) -> Class {
        FourBar::new(a, b, c).unwrap().class()
    }

    /// Deciding on the `f64` lengths away from the Grashof equality gives the class the
    /// exact decimals give: on a decimal grid (where equalities are exact and sums of
    /// decimals round), on lengths a rounding away from an equality, and on generic
    /// lengths such as a cognate's.
    #[test]
    fn class_by_floats_is_the_exact_class() {
        let mut lengths: Vec<f64> = (1..=40).map(|k| k as f64 * 0.1).collect();
        lengths.extend([0.3 + 0.6, 0.1 + 0.2, 1.0 + 1e-15, 3.0 - 4e-16, 2.0 + 2e-12]);
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..20 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            lengths.push(0.05 + (seed >> 11) as f64 / (1u64 << 53) as f64 * 4.0);
        }
        let mut change_points = 0;
        for &a in &lengths {
            for &b in &lengths {
                for &c in &lengths {
                    let l = FourBar::new(a, b, c).unwrap();
                    let exact = l.class_exact();
                    assert_eq!(l.class(), exact, "{a} {b} {c}");
                    change_points += usize::from(exact.is_change_point());
                }
            }
        }
        // The grid holds equalities, which the exact decimals decide.
        assert!(change_points > 100, "{change_points}");
    }

    #[test]
    fn barker_classes() {
        assert_eq!(class(3.0, 3.0, 3.0), Class::Gcrr);
        assert_eq!(class(2.5, 2.5, 2.0), Class::Gcrr); // Hoeken
        assert_eq!(class(3.0, 3.0, 0.5), Class::Gccc); // ground shortest
        assert_eq!(class(0.5, 3.0, 3.0), Class::Grcr); // coupler shortest
        assert_eq!(class(3.0, 0.5, 3.0), Class::Grrc); // rocker shortest
        assert_eq!(class(3.0, 3.0, 5.0), Class::Scrr); // 1 + 5 = 3 + 3
        assert_eq!(class(1.0, 1.0, 1.0), Class::S3x);
        assert_eq!(class(1.0, 2.0, 2.0), Class::S2x); // kite 1,1,2,2
        assert_eq!(class(2.0, 1.0, 2.0), Class::S2x); // parallelogram
        assert_eq!(class(1.2, 1.4, 1.8), Class::Rrr1); // l = ground, 1 + 1.8 > 1.2 + 1.4
        assert_eq!(class(0.3, 0.4, 0.5), Class::Rrr2); // l = crank
        assert_eq!(class(1.8, 1.2, 1.4), Class::Rrr3);
        assert_eq!(class(1.2, 1.8, 1.4), Class::Rrr4);
        assert_eq!(class(2.5, 2.5, 2.0).code(), "GCRR");
        // Chebyshev: ground 2, rockers 2.5, coupler 1 (driving a rocker: our crank is a
        // rocker of length 1 scaled).
        assert!(class(0.4, 1.0, 0.8).is_grashof());
    }

    #[test]
    fn decimal_change_points_are_exact() {
        // 1 + 0.3 = 0.6 + 0.7 exactly; in f64, 1 + 0.3 = 1.3 and 0.6 + 0.7 = 1.2999999999999998.
        assert_ne!(1.0 + 0.3, 0.6 + 0.7);
        assert!(class(0.6, 0.7, 0.3).is_change_point());
    }

    #[test]
    fn crank_rocker_matches_domain_inequality_on_a_grid() {
        let vals: Vec<f64> = (1..=12).map(|k| k as f64 * 0.5).collect();
        for &a in &vals {
            for &b in &vals {
                for &c in &vals {
                    let expect = (a - b).abs() + 1.0 < c && c < a + b - 1.0;
                    assert_eq!(class(a, b, c) == Class::Gcrr, expect, "{a} {b} {c}");
                }
            }
        }
    }

    #[test]
    fn rejects_bad_lengths() {
        assert!(FourBar::new(0.0, 1.0, 1.0).is_err());
        assert!(FourBar::new(1.0, -1.0, 1.0).is_err());
        assert!(FourBar::new(1.0, 1.0, f64::NAN).is_err());
        assert!(FourBar::new(1.0, f64::INFINITY, 1.0).is_err());
    }
}
