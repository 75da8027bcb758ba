//! The JSON index of an atlas: one record per curve with its measures, written with a
//! stable key order and number format, never NaN or infinity. Schema: `docs/index-schema.md`.

use coupler_kinematics::{Circuit, CouplerPoint, Linkage, LinkageClass};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::{self, Write};

/// The index format's version. Readers refuse other versions.
pub const SCHEMA_VERSION: u32 = 1;

/// Where a curve is drawn: its page file (relative to the atlas folder) and its bounding
/// box on that page in pixels `[x_min, y_min, x_max, y_max]` (origin top-left); its θ = 0
/// dot and its label's box on the page (atlas pages).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PageRef {
    /// Page file, e.g. `pages/hrones-nelson-0001.png`.
    pub file: String,
    /// Bounding box in page pixels.
    pub bbox_px: [f64; 4],
    /// The page's number in the atlas (as printed on it; in the atlas PDF it follows the
    /// contents pages).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub number: Option<u64>,
    /// The θ = 0 dot (the coupler point where the linkage is drawn) in page pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dot_px: Option<[f64; 2]>,
    /// The label's box in page pixels (rounded outwards, like `bbox_px`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label_bbox_px: Option<[f64; 4]>,
    /// The label as printed: `(u, v)`, or the curve's number in the page's key.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
    /// Drawn as a gray ghost: the curve of a pin (the crank circle or the rocker arc).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub ghost: bool,
    /// The page's orientation, `portrait` or `landscape` (pages choose their own under
    /// `orientation = "auto"`); the pixel boxes are in that page's frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orientation: Option<String>,
}

impl PageRef {
    /// A reference with only the file and the box.
    pub fn new(file: String, bbox_px: [f64; 4]) -> PageRef {
        PageRef {
            file,
            bbox_px,
            number: None,
            dot_px: None,
            label_bbox_px: None,
            label: None,
            ghost: false,
            orientation: None,
        }
    }
}

/// One curve of the atlas.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IndexCurve {
    /// Position in atlas order (linkage, circuit, coupler point), from 0.
    pub id: u64,
    /// The mechanism (a four-bar: `{coupler, rocker, ground}`, crank = 1).
    pub linkage: Linkage,
    /// The coupler point (u, v), absolute (crank units).
    pub point: CouplerPoint,
    /// The circuit.
    pub circuit: Circuit,
    /// Its class (Barker's for a four-bar).
    pub class: LinkageClass,
    /// `[x_min, y_min, x_max, y_max]` of the sampled curve, crank units.
    pub bbox: [f64; 4],
    /// `[min, max]` transmission angle over the revolution, degrees.
    pub transmission_deg: [f64; 2],
    /// `[min, max]` speed |dM/dθ| of the coupler point (unit crank speed; crank units per radian).
    pub speed: [f64; 2],
    /// Curve length ∮|V|dθ, crank units.
    pub length: f64,
    /// Conditions the numerics cannot fully resolve (`near_change_point`, `near_toggle`,
    /// `far_point`, `extreme_ratio`; see `docs/methods.md`); omitted when there are none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub flags: Vec<coupler_features::CurveFlag>,
    /// The page that draws it, when pages were rendered.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub page: Option<PageRef>,
    /// Its features (`docs/features.md`), unless the spec turns them off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub features: Option<coupler_features::CurveFeatures>,
}

/// Counts over the whole atlas.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IndexSummary {
    /// (A, B, C) combinations the spec's ranges touch.
    pub combinations: u64,
    /// Strict crank-rockers among them (the atlas's linkages).
    pub linkages: u64,
    /// Combinations skipped, by Barker class.
    pub skipped: BTreeMap<String, u64>,
    /// Curves in the index.
    pub curves: u64,
    /// Pages (0 when pages were not rendered).
    pub pages: u64,
}

/// An index as read back.
#[derive(Clone, Debug, Deserialize)]
pub struct Index {
    /// Must equal [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// Program and version that wrote it.
    pub generator: String,
    /// The spec, echoed.
    pub spec: serde_json::Value,
    /// Counts.
    pub summary: IndexSummary,
    /// The curves, by id.
    pub curves: Vec<IndexCurve>,
}

/// Why an index could not be read.
#[derive(Debug, thiserror::Error)]
pub enum IndexError {
    /// Not JSON, truncated, or not of this schema.
    #[error("not a valid coupler-atlas index: {0}")]
    Malformed(#[from] serde_json::Error),
    /// Another schema version.
    #[error(
        "index schema version {found} is not supported (this program reads version {SCHEMA_VERSION}); regenerate the index"
    )]
    Version {
        /// The version found.
        found: u64,
    },
}

impl Index {
    /// Reads an index, checking the schema version first so that an index of another
    /// version gets a clear error rather than a missing-field one.
    pub fn from_slice(bytes: &[u8]) -> Result<Index, IndexError> {
        #[derive(Deserialize)]
        struct Head {
            schema_version: serde_json::Value,
        }
        let head: Head = serde_json::from_slice(bytes)?;
        match head.schema_version.as_u64() {
            Some(v) if v == SCHEMA_VERSION as u64 => Ok(serde_json::from_slice(bytes)?),
            Some(v) => Err(IndexError::Version { found: v }),
            None => Err(IndexError::Malformed(serde::de::Error::custom(
                "schema_version is not an integer",
            ))),
        }
    }
}

/// Writes an index: a header object, then the curves one per line (so that the file
/// diffs and greps line by line), keys in declaration order, numbers in shortest
/// round-trip form. Non-finite numbers are an internal error, never written.
pub fn write_index<W: Write, S: Serialize>(
    mut w: W,
    spec: &S,
    summary: &IndexSummary,
    curves: &[IndexCurve],
) -> io::Result<()> {
    write_index_header(&mut w, spec, summary)?;
    for (i, c) in curves.iter().enumerate() {
        write_curve_line(&mut w, i == 0, &curve_line(c)?)?;
    }
    write_index_footer(&mut w)
}

/// The index's opening: everything before the first curve.
pub fn write_index_header<W: Write, S: Serialize>(
    mut w: W,
    spec: &S,
    summary: &IndexSummary,
) -> io::Result<()> {
    write!(w, "{{\"schema_version\":{SCHEMA_VERSION},\"generator\":")?;
    serde_json::to_writer(
        &mut w,
        &format!("coupler-atlas {}", env!("CARGO_PKG_VERSION")),
    )?;
    w.write_all(b",\n\"spec\":")?;
    serde_json::to_writer(&mut w, spec)?;
    w.write_all(b",\n\"summary\":")?;
    serde_json::to_writer(&mut w, summary)?;
    w.write_all(b",\n\"curves\":[")?;
    Ok(())
}

/// One curve's line of the index (no separators). Refuses non-finite measures: serde_json
/// writes NaN and infinities as `null`, which would make the index unreadable.
pub fn curve_line(c: &IndexCurve) -> io::Result<String> {
    let text = serde_json::to_string(c)?;
    if text.contains("null") {
        return Err(io::Error::other(format!(
            "internal error: curve {} has a non-finite measure",
            c.id
        )));
    }
    Ok(text)
}

/// Writes a curve line with its separator (`first` for the first curve of the index).
pub fn write_curve_line<W: Write>(mut w: W, first: bool, line: &str) -> io::Result<()> {
    w.write_all(if first { b"\n" } else { b",\n" })?;
    w.write_all(line.as_bytes())
}

/// The index's closing.
pub fn write_index_footer<W: Write>(mut w: W) -> io::Result<()> {
    w.write_all(b"\n]}\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::{Class, FourBar};

    fn curve(id: u64) -> IndexCurve {
        IndexCurve {
            id,
            linkage: Linkage::FourBar(FourBar::new(2.5, 3.0, 3.5).unwrap()),
            point: CouplerPoint::new(1.25, -0.5),
            circuit: Circuit::Open,
            class: Class::Gcrr.into(),
            bbox: [-1.0, -2.0, 3.0, 4.0],
            transmission_deg: [40.0, 120.5],
            speed: [0.1, 2.0],
            length: 10.0,
            flags: Vec::new(),
            page: None,
            features: None,
        }
    }

    fn summary() -> IndexSummary {
        IndexSummary {
            combinations: 1,
            linkages: 1,
            skipped: BTreeMap::new(),
            curves: 2,
            pages: 0,
        }
    }

    #[test]
    fn round_trip_and_stable_text() {
        let mut out = Vec::new();
        write_index(
            &mut out,
            &serde_json::json!({"name": "t"}),
            &summary(),
            &[curve(0), curve(1)],
        )
        .unwrap();
        let text = String::from_utf8(out.clone()).unwrap();
        assert!(text.starts_with("{\"schema_version\":1,\"generator\":\"coupler-atlas "));
        assert!(text.contains("\n{\"id\":1,\"linkage\":{\"coupler\":2.5,\"rocker\":3.0,\"ground\":3.5},\"point\":{\"u\":1.25,\"v\":-0.5},\"circuit\":\"open\",\"class\":\"GCRR\""));
        let back = Index::from_slice(&out).unwrap();
        assert_eq!(back.curves, vec![curve(0), curve(1)]);
    }

    #[test]
    fn floats_read_back_to_the_bit() {
        // serde_json's default float parser may be off by an ulp; the index needs the
        // `float_roundtrip` feature so that search compares the values generate measured.
        let mut c = curve(0);
        let mut x = 0.1f64;
        for k in 0..2000 {
            x = (x * 1.618_033_988_749_895 + 0.377) % 97.0 + 1e-9 * k as f64;
            c.length = x / 3.0;
            c.bbox = [x.sqrt(), -x / 7.0, x * 1e-300, x * 1e300];
            let mut out = Vec::new();
            write_index(&mut out, &1, &summary(), std::slice::from_ref(&c)).unwrap();
            let back = Index::from_slice(&out).unwrap();
            assert_eq!(back.curves[0].length.to_bits(), c.length.to_bits());
            for (a, b) in back.curves[0].bbox.iter().zip(c.bbox) {
                assert_eq!(a.to_bits(), b.to_bits());
            }
        }
    }

    #[test]
    fn refuses_non_finite_and_other_versions() {
        let mut c = curve(0);
        c.length = f64::NAN;
        assert!(write_index(Vec::new(), &1, &summary(), &[c]).is_err());
        let err = Index::from_slice(br#"{"schema_version":99}"#).unwrap_err();
        assert!(matches!(err, IndexError::Version { found: 99 }), "{err}");
        assert!(Index::from_slice(b"{\"schema_version\":1,\"curv").is_err());
    }
}
