//! The shape sidecar of an atlas (`shapes.bin`, beside `index.json`): every curve's
//! linkage, circuit, coupler point and [`ShapeCode`], in atlas order, so that a shape
//! search loads one small binary file instead of parsing the index. Pure: bytes in,
//! bytes out (the caller reads and writes the file, and checks it against the manifest).
//!
//! Layout (all little-endian), `docs/shape-search.md` "The sidecar":
//!
//! | bytes | what |
//! |---|---|
//! | 8 | magic `CASHAPE\0` |
//! | 4 | format version (1) |
//! | 4 | harmonics of the codes ([`HARMONICS`]) |
//! | 4 | bytes per record ([`RECORD_BYTES`], [`GEARED_RECORD_BYTES`]) |
//! | 4 | mechanism of the records: 0 four-bar, 1 geared five-bar ([`RecordKind`]) |
//! | 8 | curves `n` |
//! | `n` × [`RECORD_BYTES`] | records, curve `id` = position |
//!
//! A four-bar record: coupler, rocker, ground, u, v (`f64` each, crank units, exactly as
//! the index states them), the circuit (`u8`: 0 open, 1 crossed), a flag (`u8`: 1 if the
//! code is present), then the code ([`CODE_BYTES`]; zeros when absent: a curve that does
//! not assemble all round or has no length). A geared five-bar record: L1, L3, L4, L5,
//! the phase φ (degrees), u, v (`f64` each), the gear ratio's numerator and denominator
//! (`i64` each, lowest terms), then circuit, flag and code as above. A four-bar atlas's
//! file is the same bytes as before geared records existed (the mechanism word was a
//! reserved zero).

use crate::code::{CODE_BYTES, HARMONICS, ShapeCode};
use crate::kin::AtlasCurve;
use crate::kin::CouplerCurve;
use coupler_kinematics::{Circuit, CouplerPoint, FourBar, GearRatio, GearedFiveBar, Linkage};

/// The sidecar's file name in an atlas folder.
pub const SHAPES_FILE: &str = "shapes.bin";
/// Format version.
pub const SIDECAR_VERSION: u32 = 1;
/// Bytes of one four-bar curve's record.
pub const RECORD_BYTES: usize = 5 * 8 + 2 + CODE_BYTES;
/// Bytes of one geared five-bar curve's record.
pub const GEARED_RECORD_BYTES: usize = 9 * 8 + 2 + CODE_BYTES;

/// Which mechanism a sidecar's records describe (one per file: an atlas holds one).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordKind {
    /// Four-bar records ([`RECORD_BYTES`]).
    FourBar,
    /// Geared five-bar records ([`GEARED_RECORD_BYTES`]).
    GearedFiveBar,
}

impl RecordKind {
    /// The kind of records for curves of `linkage`'s mechanism.
    pub fn of(linkage: &Linkage) -> RecordKind {
        match linkage {
            Linkage::FourBar(_) => RecordKind::FourBar,
            Linkage::GearedFiveBar(_) => RecordKind::GearedFiveBar,
        }
    }

    /// Bytes per record.
    pub fn record_bytes(self) -> usize {
        match self {
            RecordKind::FourBar => RECORD_BYTES,
            RecordKind::GearedFiveBar => GEARED_RECORD_BYTES,
        }
    }

    fn word(self) -> u32 {
        match self {
            RecordKind::FourBar => 0,
            RecordKind::GearedFiveBar => 1,
        }
    }
}
const MAGIC: &[u8; 8] = b"CASHAPE\0";
/// Bytes of the header before the records.
pub const HEADER_BYTES: usize = 32;

/// Why sidecar bytes could not be read.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SidecarError {
    /// Not a shape sidecar, or cut short.
    #[error("not a coupler-atlas shape file ({0})")]
    Malformed(String),
    /// Another format version or code length.
    #[error(
        "shape file version {version} with {harmonics} harmonics is not supported (this program reads version {SIDECAR_VERSION}, {HARMONICS} harmonics); regenerate the atlas"
    )]
    Version {
        /// Version found.
        version: u32,
        /// Harmonics found.
        harmonics: u32,
    },
    /// A record that does not describe a linkage.
    #[error("shape file record {id}: {message}")]
    Record {
        /// Curve id.
        id: u64,
        /// What is wrong.
        message: String,
    },
}

/// The sidecar's bytes for `curves` (ids must be `0..n` in order, all of one mechanism:
/// the first curve's) with their codes.
pub fn encode_sidecar(curves: &[(CouplerCurve, Option<ShapeCode>)]) -> Vec<u8> {
    let kind = curves
        .first()
        .map_or(RecordKind::FourBar, |c| RecordKind::of(&c.0.linkage));
    let mut out = Vec::with_capacity(HEADER_BYTES + curves.len() * kind.record_bytes());
    out.extend_from_slice(&sidecar_header_for(kind, curves.len() as u64));
    for (c, code) in curves {
        encode_record(&mut out, c, code.as_ref());
    }
    out
}

/// The sidecar's header for `n` four-bar curves: with [`encode_record`] for each curve
/// in id order after it, the bytes of [`encode_sidecar`], written without holding every
/// curve (`generate` streams them).
pub fn sidecar_header(n: u64) -> [u8; HEADER_BYTES] {
    sidecar_header_for(RecordKind::FourBar, n)
}

/// [`sidecar_header`] for `n` curves of the mechanism `kind`.
pub fn sidecar_header_for(kind: RecordKind, n: u64) -> [u8; HEADER_BYTES] {
    let mut out = [0u8; HEADER_BYTES];
    out[..8].copy_from_slice(MAGIC);
    out[8..12].copy_from_slice(&SIDECAR_VERSION.to_le_bytes());
    out[12..16].copy_from_slice(&(HARMONICS as u32).to_le_bytes());
    out[16..20].copy_from_slice(&(kind.record_bytes() as u32).to_le_bytes());
    out[20..24].copy_from_slice(&kind.word().to_le_bytes());
    out[24..32].copy_from_slice(&n.to_le_bytes());
    out
}

/// Appends one curve's record to `out` ([`RECORD_BYTES`] bytes for a four-bar,
/// [`GEARED_RECORD_BYTES`] for a geared five-bar).
pub fn encode_record(out: &mut Vec<u8>, c: &CouplerCurve, code: Option<&ShapeCode>) {
    let (u, v) = (c.point.u, c.point.v);
    match &c.linkage {
        Linkage::FourBar(l) => {
            for x in [l.coupler, l.rocker, l.ground, u, v] {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
        Linkage::GearedFiveBar(l) => {
            for x in [l.l1, l.l3, l.l4, l.l5, l.phase, u, v] {
                out.extend_from_slice(&x.to_le_bytes());
            }
            for k in [l.ratio.num(), l.ratio.den()] {
                out.extend_from_slice(&k.to_le_bytes());
            }
        }
    }
    out.push(match c.circuit {
        Circuit::Open => 0,
        Circuit::Crossed => 1,
    });
    match code {
        Some(code) => {
            out.push(1);
            out.extend_from_slice(&code.to_bytes());
        }
        None => {
            out.push(0);
            out.extend_from_slice(&[0u8; CODE_BYTES]);
        }
    }
}

/// Curves and codes read from a sidecar.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeAtlas {
    /// Every curve, by id.
    pub curves: Vec<AtlasCurve>,
    /// The code of each (a curve without one gets a code no target is near: it is never a
    /// closed-target candidate, but open targets still scan it).
    pub codes: Vec<ShapeCode>,
    /// Whether each curve has a real code.
    pub has_code: Vec<bool>,
}

/// Reads [`encode_sidecar`]'s bytes whole: every record decoded and checked
/// ([`SidecarView::decode_all`]).
pub fn decode_sidecar(bytes: &[u8]) -> Result<ShapeAtlas, SidecarError> {
    SidecarView::new(bytes)?.decode_all()
}

/// A sidecar's bytes read in place: the header is checked when the view is made, each
/// record when it is read ([`SidecarView::curve`], [`SidecarView::code`]), by the same
/// decoder [`decode_sidecar`] runs on every record. A search reads the codes of every
/// curve (48 bytes a record, no allocation) and decodes only the records it proposes,
/// so a query on a mapped file costs neither a copy of it nor a decoded atlas in memory.
/// The file's integrity is the caller's check (the manifest's hash, `match`'s loader);
/// a record that does not decode is an error when it is read, never a wrong value.
#[derive(Clone, Copy, Debug)]
pub struct SidecarView<'a> {
    body: &'a [u8],
    kind: RecordKind,
    record: usize,
    n: usize,
}

impl<'a> SidecarView<'a> {
    /// The view of a sidecar's bytes: magic, version, harmonics, record size and count
    /// checked against the length.
    pub fn new(bytes: &'a [u8]) -> Result<SidecarView<'a>, SidecarError> {
        let bad = |m: &str| SidecarError::Malformed(m.to_string());
        if bytes.len() < HEADER_BYTES || &bytes[..8] != MAGIC {
            return Err(bad("no CASHAPE header"));
        }
        let u32_at = |k: usize| u32::from_le_bytes(bytes[k..k + 4].try_into().expect("4 bytes"));
        let (version, harmonics, record) = (u32_at(8), u32_at(12), u32_at(16) as usize);
        let kind = match u32_at(20) {
            0 => RecordKind::FourBar,
            1 => RecordKind::GearedFiveBar,
            _ => return Err(SidecarError::Version { version, harmonics }),
        };
        if version != SIDECAR_VERSION
            || harmonics as usize != HARMONICS
            || record != kind.record_bytes()
        {
            return Err(SidecarError::Version { version, harmonics });
        }
        let n = u64::from_le_bytes(bytes[24..32].try_into().expect("8 bytes"));
        let body = &bytes[HEADER_BYTES..];
        if (body.len() as u64) != n.saturating_mul(record as u64) {
            return Err(bad(&format!(
                "{} bytes of records for {n} curves of {record} bytes",
                body.len()
            )));
        }
        Ok(SidecarView {
            body,
            kind,
            record,
            n: n as usize,
        })
    }

    /// Curves in the sidecar.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether it holds no curve.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The mechanism of its records.
    pub fn kind(&self) -> RecordKind {
        self.kind
    }

    /// The bytes of record `id` (`id < len()`).
    fn bytes_of(&self, id: usize) -> &'a [u8] {
        &self.body[id * self.record..(id + 1) * self.record]
    }

    /// Where the circuit byte is in a record (the code flag follows, then the code).
    fn tail(&self) -> usize {
        match self.kind {
            RecordKind::FourBar => 40,
            RecordKind::GearedFiveBar => 72,
        }
    }

    /// Curve `id`'s shape code, `None` if it has none (its flag byte 0); an error for a
    /// flag byte other than 0 or 1, or an id past the end.
    pub fn code(&self, id: usize) -> Result<Option<ShapeCode>, SidecarError> {
        let r = self.record_at(id)?;
        let tail = self.tail();
        match r[tail + 1] {
            0 => Ok(None),
            1 => Ok(Some(
                ShapeCode::from_bytes(&r[tail + 2..]).expect("CODE_BYTES"),
            )),
            x => Err(SidecarError::Record {
                id: id as u64,
                message: format!("code flag byte {x}"),
            }),
        }
    }

    /// Curve `id`, its record decoded and checked (linkage, coupler point, circuit and
    /// code flag).
    pub fn curve(&self, id: usize) -> Result<AtlasCurve, SidecarError> {
        Ok(self.decode(id)?.0)
    }

    fn record_at(&self, id: usize) -> Result<&'a [u8], SidecarError> {
        if id >= self.n {
            return Err(SidecarError::Record {
                id: id as u64,
                message: format!("no such record (the file holds {})", self.n),
            });
        }
        Ok(self.bytes_of(id))
    }

    /// Record `id` decoded: the curve, its code ([`ShapeCode::ABSENT`] if none) and
    /// whether it has one.
    fn decode(&self, id: usize) -> Result<(AtlasCurve, ShapeCode, bool), SidecarError> {
        let r = self.record_at(id)?;
        let id = id as u64;
        let f = |k: usize| f64::from_le_bytes(r[8 * k..8 * k + 8].try_into().expect("8 bytes"));
        let at = |message: String| SidecarError::Record { id, message };
        let (linkage, (u, v)): (Linkage, _) = match self.kind {
            RecordKind::FourBar => (
                FourBar::new(f(0), f(1), f(2))
                    .map_err(|e| at(e.to_string()))?
                    .into(),
                (f(3), f(4)),
            ),
            RecordKind::GearedFiveBar => {
                let i = |k: usize| i64::from_le_bytes(r[8 * k..8 * k + 8].try_into().expect("8"));
                let ratio = GearRatio::new(i(7), i(8)).map_err(|e| at(e.to_string()))?;
                (
                    GearedFiveBar::new(f(0), f(1), f(2), f(3), ratio, f(4))
                        .map_err(|e| at(e.to_string()))?
                        .into(),
                    (f(5), f(6)),
                )
            }
        };
        if !u.is_finite() || !v.is_finite() {
            return Err(at("coupler point is not finite".into()));
        }
        let tail = self.tail();
        let circuit = match r[tail] {
            0 => Circuit::Open,
            1 => Circuit::Crossed,
            x => return Err(at(format!("circuit byte {x}"))),
        };
        let code = self.code(id as usize)?;
        Ok((
            AtlasCurve {
                id,
                curve: CouplerCurve {
                    linkage,
                    circuit,
                    point: CouplerPoint::new(u, v),
                },
            },
            code.unwrap_or(ShapeCode::ABSENT),
            code.is_some(),
        ))
    }

    /// The curves `ids` (a range of ids), each record decoded and checked, without their
    /// codes (an open target's scan needs none): to decode a large atlas in parallel
    /// parts.
    pub fn curves(&self, ids: std::ops::Range<usize>) -> Result<Vec<AtlasCurve>, SidecarError> {
        ids.map(|id| self.curve(id)).collect()
    }

    /// Every record decoded and checked, as [`decode_sidecar`] returns them.
    pub fn decode_all(&self) -> Result<ShapeAtlas, SidecarError> {
        let mut out = ShapeAtlas {
            curves: Vec::with_capacity(self.n),
            codes: Vec::with_capacity(self.n),
            has_code: Vec::with_capacity(self.n),
        };
        for id in 0..self.n {
            let (curve, code, has) = self.decode(id)?;
            out.curves.push(curve);
            out.codes.push(code);
            out.has_code.push(has);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_damage() {
        let c = CouplerCurve::new(
            FourBar::new(2.5, 3.0, 3.5).unwrap(),
            Circuit::Crossed,
            CouplerPoint::new(1.25, -0.625),
        );
        let code = ShapeCode::of_curve(&c).unwrap();
        let bytes = encode_sidecar(&[(c, Some(code)), (c, None)]);
        assert_eq!(bytes.len(), HEADER_BYTES + 2 * RECORD_BYTES);
        let a = decode_sidecar(&bytes).unwrap();
        assert_eq!(a.curves[0].curve, c);
        assert_eq!(a.curves[1].id, 1);
        assert_eq!(a.codes[0], code);
        assert_eq!(a.has_code, vec![true, false]);
        assert!(matches!(
            decode_sidecar(&bytes[..bytes.len() - 1]),
            Err(SidecarError::Malformed(_))
        ));
        let mut v = bytes.clone();
        v[8] = 2;
        assert!(matches!(
            decode_sidecar(&v),
            Err(SidecarError::Version { version: 2, .. })
        ));
        let mut v = bytes;
        v[HEADER_BYTES + 40] = 7;
        assert!(matches!(
            decode_sidecar(&v),
            Err(SidecarError::Record { id: 0, .. })
        ));
    }

    /// A geared five-bar's record keeps its dimensions, gears, circuit and point, the
    /// header says so, and a four-bar reader's record size is not accepted for it.
    #[test]
    fn geared_round_trip() {
        let l =
            GearedFiveBar::new(3.0, 3.2, 3.5, 1.2, GearRatio::new(-1, 2).unwrap(), -70.0).unwrap();
        let c = CouplerCurve::new(l, Circuit::Crossed, CouplerPoint::new(1.25, -0.625));
        let code = ShapeCode::of_curve(&c).unwrap();
        let bytes = encode_sidecar(&[(c, Some(code)), (c, None)]);
        assert_eq!(bytes.len(), HEADER_BYTES + 2 * GEARED_RECORD_BYTES);
        assert_eq!(bytes[20], 1);
        let a = decode_sidecar(&bytes).unwrap();
        assert_eq!(a.curves[0].curve, c);
        assert_eq!(a.codes[0], code);
        assert_eq!(a.has_code, vec![true, false]);
        let mut v = bytes.clone();
        v[20] = 0; // claims four-bar records of the geared size
        assert!(matches!(
            decode_sidecar(&v),
            Err(SidecarError::Version { .. })
        ));
        let mut v = bytes;
        v[HEADER_BYTES + 7 * 8..HEADER_BYTES + 8 * 8].fill(0); // ratio numerator 0
        assert!(matches!(
            decode_sidecar(&v),
            Err(SidecarError::Record { id: 0, .. })
        ));
    }
}
