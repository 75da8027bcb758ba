//! Exact decimal numbers for the decisions that must not be float coin-flips.
//!
//! Grashof's test `s + l ⋚ p + q` lands exactly on equality on the half-unit (and
//! decimal) grids atlases are made of. Link lengths enter the program as decimal text
//! (a spec file, a flag); [`Decimal`] keeps them exactly, and an `f64` is read back as the
//! shortest decimal that round-trips to it (which is the decimal the user wrote, for any
//! input of at most 15 significant digits).

use std::cmp::Ordering;
use std::fmt;

/// An exact decimal `mantissa · 10^exponent`, normalised so the mantissa has no trailing
/// zeros (zero is `0 · 10^0`).
///
/// ```
/// use coupler_kinematics::Decimal;
/// let a: Decimal = "0.1".parse().unwrap();
/// let b: Decimal = "0.5".parse().unwrap();
/// let c: Decimal = "0.3".parse().unwrap();
/// // 0.1 + 0.5 = 0.3 + 0.3 exactly, although not in f64.
/// assert_eq!(Decimal::compare_sums(&[a, b], &[c, c]), Some(std::cmp::Ordering::Equal));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Decimal {
    mantissa: i128,
    exponent: i32,
}

/// Why a text is not a decimal number.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecimalError {
    /// Empty, or characters that are not part of a decimal number.
    #[error("`{0}` is not a decimal number")]
    Syntax(String),
    /// More digits or a larger exponent than can be held exactly.
    #[error("`{0}` has more digits than can be held exactly (at most 30 significant digits)")]
    TooLong(String),
    /// `inf`, `nan` or an `f64` that is not finite.
    #[error("`{0}` is not a finite number")]
    NotFinite(String),
}

const MAX_DIGITS: usize = 30;

impl Decimal {
    /// Zero.
    pub const ZERO: Decimal = Decimal {
        mantissa: 0,
        exponent: 0,
    };

    /// `mantissa · 10^exponent`, normalised.
    pub fn new(mantissa: i128, exponent: i32) -> Decimal {
        let mut d = Decimal { mantissa, exponent };
        d.normalise();
        d
    }

    fn normalise(&mut self) {
        if self.mantissa == 0 {
            self.exponent = 0;
            return;
        }
        while self.mantissa % 10 == 0 {
            self.mantissa /= 10;
            self.exponent += 1;
        }
    }

    /// The shortest decimal that rounds to `x` (Rust's `Display` of `f64`).
    ///
    /// Errors for NaN and infinities.
    pub fn from_f64(x: f64) -> Result<Decimal, DecimalError> {
        if !x.is_finite() {
            return Err(DecimalError::NotFinite(x.to_string()));
        }
        // `{:e}` prints the shortest round-trip digits in scientific form.
        format!("{x:e}").parse()
    }

    /// The nearest `f64`.
    pub fn to_f64(self) -> f64 {
        // Formatting then parsing gives the correctly rounded value.
        format!("{}e{}", self.mantissa, self.exponent)
            .parse()
            .unwrap_or(f64::NAN)
    }

    /// The mantissa (no trailing zeros).
    pub fn mantissa(self) -> i128 {
        self.mantissa
    }

    /// The decimal exponent.
    pub fn exponent(self) -> i32 {
        self.exponent
    }

    /// Sign of the number.
    pub fn signum(self) -> i32 {
        self.mantissa.signum() as i32
    }

    /// Both numbers as mantissas over the common exponent `min(e1, e2)`, or `None` if that
    /// overflows.
    fn align(self, other: Decimal) -> Option<(i128, i128, i32)> {
        let e = self.exponent.min(other.exponent);
        let a = scale(self.mantissa, self.exponent - e)?;
        let b = scale(other.mantissa, other.exponent - e)?;
        Some((a, b, e))
    }

    /// `self + other`, or `None` on overflow.
    pub fn checked_add(self, other: Decimal) -> Option<Decimal> {
        let (a, b, e) = self.align(other)?;
        Some(Decimal::new(a.checked_add(b)?, e))
    }

    /// `self − other`, or `None` on overflow.
    pub fn checked_sub(self, other: Decimal) -> Option<Decimal> {
        self.checked_add(Decimal::new(other.mantissa.checked_neg()?, other.exponent))
    }

    /// `self · k`, or `None` on overflow.
    pub fn checked_mul_int(self, k: i128) -> Option<Decimal> {
        Some(Decimal::new(self.mantissa.checked_mul(k)?, self.exponent))
    }

    /// Exact comparison of `Σ lhs` with `Σ rhs`; `None` only if the exact sums overflow
    /// (numbers more than ~30 orders of magnitude apart).
    pub fn compare_sums(lhs: &[Decimal], rhs: &[Decimal]) -> Option<Ordering> {
        let mut diff = Decimal::ZERO;
        for &x in lhs {
            diff = diff.checked_add(x)?;
        }
        for &x in rhs {
            diff = diff.checked_sub(x)?;
        }
        Some(diff.mantissa.cmp(&0))
    }

    /// The number of integer steps `k ≥ 0` with `start + k·step ≤ end` (exactly), or `None`
    /// when `step ≤ 0` or on overflow.
    pub fn steps_in_range(start: Decimal, end: Decimal, step: Decimal) -> Option<u64> {
        if step.mantissa <= 0 {
            return None;
        }
        let span = end.checked_sub(start)?;
        if span.mantissa < 0 {
            return Some(0);
        }
        let (s, t, _) = span.align(step)?;
        u64::try_from(s / t + 1).ok()
    }
}

/// Whether `degrees` is a positive divisor of a full turn: `0 < degrees ≤ 360` and
/// `360 / degrees` a whole number, decided exactly on the shortest decimal that rounds to
/// `degrees` (so `7.5` and `0.1` divide 360, `7` does not). The one check behind every
/// "divides 360" setting: crank steps, dash angles, feature steps.
///
/// ```
/// use coupler_kinematics::divides_turn;
/// assert!(divides_turn(10.0) && divides_turn(7.5) && divides_turn(0.1) && divides_turn(360.0));
/// assert!(!divides_turn(7.0) && !divides_turn(0.0) && !divides_turn(720.0) && !divides_turn(f64::NAN));
/// ```
pub fn divides_turn(degrees: f64) -> bool {
    let Ok(d) = Decimal::from_f64(degrees) else {
        return false;
    };
    let full = Decimal::new(360, 0);
    d.signum() > 0
        && d <= full
        && Decimal::steps_in_range(Decimal::ZERO, full, d)
            .map(|n| d.checked_mul_int(n as i128 - 1) == Some(full))
            .unwrap_or(false)
}

fn scale(m: i128, by: i32) -> Option<i128> {
    let mut m = m;
    for _ in 0..by {
        m = m.checked_mul(10)?;
    }
    Some(m)
}

impl PartialOrd for Decimal {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Decimal {
    fn cmp(&self, other: &Self) -> Ordering {
        match self.align(*other) {
            Some((a, b, _)) => a.cmp(&b),
            // Too far apart to align: magnitudes decide (signs first).
            None => self
                .to_f64()
                .partial_cmp(&other.to_f64())
                .unwrap_or(Ordering::Equal),
        }
    }
}

impl std::str::FromStr for Decimal {
    type Err = DecimalError;

    /// Parses `[+-]digits[.digits][(e|E)[+-]digits]`.
    fn from_str(text: &str) -> Result<Decimal, DecimalError> {
        let s = text.trim();
        let bad = || DecimalError::Syntax(text.to_string());
        let lower = s.to_ascii_lowercase();
        if matches!(
            lower.trim_start_matches(['+', '-']),
            "inf" | "infinity" | "nan"
        ) {
            return Err(DecimalError::NotFinite(text.to_string()));
        }
        let (body, exp) = match s.find(['e', 'E']) {
            Some(i) => (&s[..i], s[i + 1..].parse::<i32>().map_err(|_| bad())?),
            None => (s, 0),
        };
        let (negative, body) = match body.as_bytes().first() {
            Some(b'-') => (true, &body[1..]),
            Some(b'+') => (false, &body[1..]),
            _ => (false, body),
        };
        let (int, frac) = match body.find('.') {
            Some(i) => (&body[..i], &body[i + 1..]),
            None => (body, ""),
        };
        if int.is_empty() && frac.is_empty() {
            return Err(bad());
        }
        if !int.bytes().chain(frac.bytes()).all(|b| b.is_ascii_digit()) {
            return Err(bad());
        }
        let digits = format!("{int}{frac}");
        let digits = digits.trim_start_matches('0');
        let trimmed = digits.trim_end_matches('0');
        if trimmed.len() > MAX_DIGITS {
            return Err(DecimalError::TooLong(text.to_string()));
        }
        let zeros = (digits.len() - trimmed.len()) as i64;
        let exponent = exp as i64 - frac.len() as i64 + zeros;
        let exponent = i32::try_from(exponent).map_err(|_| DecimalError::TooLong(text.into()))?;
        if exponent.abs() > 400 {
            return Err(DecimalError::TooLong(text.to_string()));
        }
        let mut mantissa: i128 = if trimmed.is_empty() {
            0
        } else {
            trimmed.parse().map_err(|_| bad())?
        };
        if negative {
            mantissa = -mantissa;
        }
        Ok(Decimal::new(mantissa, exponent))
    }
}

impl fmt::Display for Decimal {
    /// Plain notation (`2.5`, `0.001`, `300`) for exponents in −20..=20, else `me±k`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let neg = self.mantissa < 0;
        let digits = self.mantissa.unsigned_abs().to_string();
        let e = self.exponent;
        let sign = if neg { "-" } else { "" };
        if !(-20..=20).contains(&e) {
            return write!(f, "{sign}{digits}e{e}");
        }
        if e >= 0 {
            write!(f, "{sign}{digits}{}", "0".repeat(e as usize))
        } else {
            let k = (-e) as usize;
            if digits.len() > k {
                let (i, fr) = digits.split_at(digits.len() - k);
                write!(f, "{sign}{i}.{fr}")
            } else {
                write!(f, "{sign}0.{}{digits}", "0".repeat(k - digits.len()))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn d(s: &str) -> Decimal {
        s.parse().unwrap()
    }

    #[test]
    fn parses_and_prints() {
        for (text, shown) in [
            ("2.5", "2.5"),
            ("+3", "3"),
            ("-0.125", "-0.125"),
            ("1e-3", "0.001"),
            ("1.50", "1.5"),
            ("300", "300"),
            ("0", "0"),
            ("-0.0", "0"),
            (".5", "0.5"),
            ("5.", "5"),
            ("1e30", "1e30"),
        ] {
            assert_eq!(d(text).to_string(), shown, "{text}");
        }
        for bad in ["", ".", "-", "1.2.3", "abc", "1e", "0x10", "1_0"] {
            assert!(
                matches!(bad.parse::<Decimal>(), Err(DecimalError::Syntax(_))),
                "{bad}"
            );
        }
        for bad in ["inf", "-inf", "NaN", "infinity"] {
            assert!(
                matches!(bad.parse::<Decimal>(), Err(DecimalError::NotFinite(_))),
                "{bad}"
            );
        }
    }

    #[test]
    fn f64_round_trip_is_the_typed_decimal() {
        for text in ["0.1", "0.3", "2.975", "3.9625", "1e-3", "1000", "4.5"] {
            let x: f64 = text.parse().unwrap();
            assert_eq!(Decimal::from_f64(x).unwrap(), d(text));
            assert_eq!(d(text).to_f64(), x);
        }
        assert!(Decimal::from_f64(f64::NAN).is_err());
    }

    #[test]
    fn exact_sums_where_f64_fails() {
        let (a, b, c) = (0.1_f64, 0.2_f64, 0.3_f64);
        assert_ne!(a + b, c, "f64 says 0.1 + 0.2 != 0.3");
        assert_eq!(
            Decimal::compare_sums(&[d("0.1"), d("0.2")], &[d("0.3")]),
            Some(Ordering::Equal)
        );
        assert_eq!(
            Decimal::compare_sums(&[d("1"), d("5")], &[d("3"), d("3.0000000000001")]),
            Some(Ordering::Less)
        );
    }

    #[test]
    fn ranges_count_exactly() {
        assert_eq!(
            Decimal::steps_in_range(d("1.5"), d("4.5"), d("0.5")),
            Some(7)
        );
        assert_eq!(Decimal::steps_in_range(d("0"), d("1"), d("0.1")), Some(11));
        assert_eq!(
            Decimal::steps_in_range(d("0"), d("0.95"), d("0.1")),
            Some(10)
        );
        assert_eq!(Decimal::steps_in_range(d("2"), d("1"), d("0.1")), Some(0));
        assert_eq!(Decimal::steps_in_range(d("0"), d("1"), d("0")), None);
    }
}
