//! The shape sidecar (`shapes.bin`): every curve's shape code for `match` (format and
//! method: `coupler_shape::encode_sidecar`, `docs/shape-search.md`). Each unit's records
//! are coded by the worker that computes the unit ([`unit_records`]) and appended in atlas
//! order as the atlas is assembled (`assembly.rs`); the file is listed in the manifest.

use crate::{GenerateError, Group, Job};
use coupler_shape::{AtlasCurve, CouplerCurve, RecordKind, ShapeCode, encode_record};

/// Every curve of `job`'s atlas in id order, as shape search sees it.
pub fn atlas_curves(job: &Job) -> Vec<AtlasCurve> {
    let mut curves = Vec::new();
    for g in job.groups() {
        curves.extend(g.points.iter().enumerate().map(|(k, &point)| AtlasCurve {
            id: g.first_id + k as u64,
            curve: CouplerCurve::new(g.linkage, g.circuit, point),
        }));
    }
    curves
}

/// The sidecar's record kind of `job`'s atlas (its first mechanism's), or `None` for an
/// atlas without curves (which has no sidecar).
pub(crate) fn record_kind(job: &Job) -> Option<RecordKind> {
    job.units().next().map(|g| RecordKind::of(&g.linkage))
}

/// The sidecar records of unit `g`'s curves, in id order, for an atlas of record kind
/// `kind`: an error if `g` is of another mechanism (one sidecar holds one kind).
pub(crate) fn unit_records(
    job: &Job,
    g: &Group,
    kind: RecordKind,
) -> Result<Vec<u8>, GenerateError> {
    if RecordKind::of(&g.linkage) != kind {
        return Err(GenerateError::Io {
            path: job.out.join(coupler_shape::SHAPES_FILE),
            source: std::io::Error::other("an atlas mixes four-bars with other mechanisms"),
        });
    }
    let mut out = Vec::with_capacity(g.points.len() * kind.record_bytes());
    // The unit's curves share its linkage's poses: solved once for all of them.
    let codes = ShapeCode::of_points(&g.linkage, g.circuit, &g.points);
    for (&point, code) in g.points.iter().zip(&codes) {
        let c = CouplerCurve::new(g.linkage, g.circuit, point);
        encode_record(&mut out, &c, code.as_ref());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_shape::{encode_sidecar, sidecar_header_for};

    /// The sidecar header and every unit's records in atlas order are the bytes of the
    /// whole atlas encoded at once.
    #[test]
    fn unit_records_make_the_whole_encoding() {
        for job in crate::job::quick_jobs() {
            let name = job.source.as_str();
            let kind = record_kind(&job).unwrap();
            let mut streamed = sidecar_header_for(kind, job.curves()).to_vec();
            for g in job.units() {
                streamed.extend(unit_records(&job, &g, kind).unwrap());
            }
            let whole: Vec<(CouplerCurve, Option<ShapeCode>)> = atlas_curves(&job)
                .iter()
                .map(|c| (c.curve, ShapeCode::of_curve(&c.curve)))
                .collect();
            assert_eq!(streamed, encode_sidecar(&whole), "{name}");
        }
    }
}
