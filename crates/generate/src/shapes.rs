//! The shape sidecar (`shapes.bin`): every curve's shape code for `match`, computed in
//! parallel when the atlas is assembled and listed in the manifest (format and method:
//! `coupler_shape::encode_sidecar`, `docs/shape-search.md`).

use crate::files::{FileEntry, write_atomically};
use crate::{GenerateError, Job};
use coupler_shape::{CouplerCurve, SHAPES_FILE, ShapeCode, encode_sidecar};
use rayon::prelude::*;
use std::io::Write as _;

/// Computes the codes of every curve of `job` on `job.jobs` threads and writes the
/// sidecar into `job.out`; `None` (nothing written) for an atlas of mechanisms other than
/// four-bars.
pub(crate) fn write_shapes(job: &Job) -> Result<Option<FileEntry>, GenerateError> {
    let mut curves: Vec<CouplerCurve> = Vec::new();
    for g in job.groups() {
        let Some(linkage) = g.linkage.four_bar() else {
            return Ok(None);
        };
        curves.extend(g.points.iter().map(|&point| CouplerCurve {
            linkage: *linkage,
            circuit: g.circuit,
            point,
        }));
    }
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
            .map(|c| (*c, ShapeCode::of_curve(c)))
            .collect()
    });
    let bytes = encode_sidecar(&coded);
    let path = job.out.join(SHAPES_FILE);
    write_atomically(&path, |w| w.write_all(&bytes))?;
    Ok(Some(FileEntry::of(SHAPES_FILE, &bytes)))
}
