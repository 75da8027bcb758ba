//! Ranges of exact decimals: the link-length ranges of a four-bar grid (and the geared
//! five-bar's), read by the spec parser and counted by `count`.

use coupler_kinematics::Decimal;
use serde::Serialize;

/// `start..=end` by `step`, exact decimals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DecimalRange {
    /// First value.
    pub start: Decimal,
    /// Last value (included when on the grid).
    pub end: Decimal,
    /// Step (> 0).
    pub step: Decimal,
}

impl DecimalRange {
    /// The values `start + k·step ≤ end`, exactly.
    pub fn values(&self) -> Vec<Decimal> {
        let n = Decimal::steps_in_range(self.start, self.end, self.step).unwrap_or(0);
        (0..n)
            .filter_map(|k| {
                self.start
                    .checked_add(self.step.checked_mul_int(k as i128)?)
            })
            .collect()
    }

    /// Number of values.
    pub fn len(&self) -> u64 {
        Decimal::steps_in_range(self.start, self.end, self.step).unwrap_or(0)
    }

    /// True if the range has no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl Serialize for DecimalRange {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut st = s.serialize_struct("Range", 3)?;
        st.serialize_field("start", &self.start.to_f64())?;
        st.serialize_field("end", &self.end.to_f64())?;
        st.serialize_field("step", &self.step.to_f64())?;
        st.end()
    }
}

/// Ranges of the three free link lengths.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LinkageRanges {
    /// Coupler A.
    pub coupler: DecimalRange,
    /// Rocker B.
    pub rocker: DecimalRange,
    /// Ground C.
    pub ground: DecimalRange,
}
