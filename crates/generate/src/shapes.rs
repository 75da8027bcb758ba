//! The shape sidecar (`shapes.bin`): every curve's shape code for `match`, computed in
//! parallel when the atlas is assembled and listed in the manifest (format and method:
//! `coupler_shape::encode_sidecar`, `docs/shape-search.md`).

use crate::files::{FileEntry, write_atomically};
use crate::{GenerateError, Job};
use coupler_shape::{
    AtlasCurve, CouplerCurve, RecordKind, SHAPES_FILE, ShapeCode, encode_record, sidecar_header_for,
};
use rayon::prelude::*;
use std::io::Write;

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

/// Curves coded and written per batch: memory stays at a batch's curves and records
/// (about 140 bytes each) whatever the atlas's size.
const BATCH: usize = 16_384;

/// Computes the codes of every curve of `job` on `job.jobs` threads and writes the
/// sidecar into `job.out`, streaming the groups in batches of [`BATCH`] curves (four-bar
/// or geared five-bar records, as the atlas's mechanism is); `None` (nothing written) for
/// an atlas without curves.
pub(crate) fn write_shapes(job: &Job) -> Result<Option<FileEntry>, GenerateError> {
    write_shapes_in_batches(job, BATCH)
}

fn write_shapes_in_batches(
    job: &Job,
    batch_size: usize,
) -> Result<Option<FileEntry>, GenerateError> {
    let mut groups = job.groups().peekable();
    let Some(kind) = groups.peek().map(|g| RecordKind::of(&g.linkage)) else {
        return Ok(None);
    };
    let io = |e: std::io::Error| GenerateError::Io {
        path: job.out.clone(),
        source: e,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(job.jobs)
        .build()
        .map_err(|e| io(std::io::Error::other(e)))?;
    let total = job.curves();
    let path = job.out.join(SHAPES_FILE);
    write_atomically(&path, |w| {
        w.write_all(&sidecar_header_for(kind, total))?;
        let mut written = 0u64;
        let mut batch: Vec<CouplerCurve> = Vec::with_capacity(batch_size);
        let mut records = Vec::with_capacity(batch_size * kind.record_bytes());
        let mut flush = |batch: &mut Vec<CouplerCurve>, w: &mut dyn Write| {
            let codes: Vec<Option<ShapeCode>> =
                pool.install(|| batch.par_iter().map(ShapeCode::of_curve).collect());
            records.clear();
            for (c, code) in batch.iter().zip(&codes) {
                encode_record(&mut records, c, code.as_ref());
            }
            written += batch.len() as u64;
            batch.clear();
            w.write_all(&records)
        };
        for g in groups {
            if RecordKind::of(&g.linkage) != kind {
                return Err(std::io::Error::other(
                    "an atlas mixes four-bars with other mechanisms",
                ));
            }
            for &point in &g.points {
                batch.push(CouplerCurve::new(g.linkage, g.circuit, point));
                if batch.len() == batch_size {
                    flush(&mut batch, w)?;
                }
            }
        }
        flush(&mut batch, w)?;
        if written != total {
            return Err(std::io::Error::other(format!(
                "{written} curves coded for an atlas of {total}"
            )));
        }
        Ok(())
    })?;
    FileEntry::of_file(&job.out, SHAPES_FILE)
        .map(Some)
        .map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_shape::encode_sidecar;
    use coupler_specs::Spec;

    /// Streamed in batches that split groups (5 curves, groups of 12), the sidecar is the
    /// bytes of the whole atlas encoded at once, and its entry hashes those bytes.
    #[test]
    fn streamed_sidecar_equals_the_whole_encoding() {
        let spec = Spec::parse(include_str!("../../../atlas-spec/quick.toml"), "quick").unwrap();
        let dir = std::env::temp_dir().join(format!("coupler-atlas-shapes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let job = Job::new(spec, "quick", &dir, 2);
        let entry = write_shapes_in_batches(&job, 5).unwrap().unwrap();
        let written = std::fs::read(dir.join(SHAPES_FILE)).unwrap();
        let whole: Vec<(CouplerCurve, Option<ShapeCode>)> = atlas_curves(&job)
            .iter()
            .map(|c| (c.curve, ShapeCode::of_curve(&c.curve)))
            .collect();
        assert_eq!(written, encode_sidecar(&whole));
        assert_eq!(entry, FileEntry::of(SHAPES_FILE, &written));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
