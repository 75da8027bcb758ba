//! The shape sidecar (`shapes.bin`): every curve's shape code for `match`, computed in
//! parallel when the atlas is assembled and listed in the manifest (format and method:
//! `coupler_shape::encode_sidecar`, `docs/shape-search.md`).

use crate::files::{FileEntry, write_atomically};
use crate::{GenerateError, Job};
use coupler_shape::{AtlasCurve, CouplerCurve, SHAPES_FILE, ShapeCode, encode_sidecar};
use rayon::prelude::*;
use std::io::Write as _;

/// Every curve of `job`'s atlas in id order, as shape search sees it (`None` for an
/// atlas of mechanisms other than four-bars, which has no shape codes).
pub fn atlas_curves(job: &Job) -> Option<Vec<AtlasCurve>> {
    let mut curves = Vec::new();
    for g in job.groups() {
        let linkage = g.linkage.four_bar()?;
        curves.extend(g.points.iter().enumerate().map(|(k, &point)| AtlasCurve {
            id: g.first_id + k as u64,
            curve: CouplerCurve {
                linkage: *linkage,
                circuit: g.circuit,
                point,
            },
        }));
    }
    Some(curves)
}

/// Computes the codes of every curve of `job` on `job.jobs` threads and writes the
/// sidecar into `job.out`; `None` (nothing written) for an atlas of mechanisms other than
/// four-bars.
pub(crate) fn write_shapes(job: &Job) -> Result<Option<FileEntry>, GenerateError> {
    let Some(curves) = atlas_curves(job) else {
        return Ok(None);
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(job.jobs)
        .build()
        .map_err(|e| GenerateError::Io {
            path: job.out.clone(),
            source: std::io::Error::other(e),
        })?;
    let coded: Vec<(CouplerCurve, Option<ShapeCode>)> = pool.install(|| {
        curves
            .par_iter()
            .map(|c| (c.curve, ShapeCode::of_curve(&c.curve)))
            .collect()
    });
    let bytes = encode_sidecar(&coded);
    let path = job.out.join(SHAPES_FILE);
    write_atomically(&path, |w| w.write_all(&bytes))?;
    Ok(Some(FileEntry::of(SHAPES_FILE, &bytes)))
}
