//! The atlas-level files of a whole run, built as the chunks come, in chunk order: the
//! index (`index.json`, hashed as it is written), the search columns (`index.columns`,
//! format: `coupler_index::ColumnsWriter`) and the shape sidecar (`shapes.bin`). A chunk
//! computed by this run is added from what its workers made (its index lines, its
//! curves, its sidecar records): nothing is read back or parsed again. A chunk found
//! complete (a resumed run, a merge) is read from its record, its lines checked against
//! the record's hash and parsed in parallel for the columns, its sidecar records coded
//! again. The three files stay under temporary names until [`Assembled::commit`] puts
//! them in place; dropped before (an error, an interrupted run, a failed page), they are
//! removed.

use crate::chunk::{CHUNK_GROUPS, read_chunk};
use crate::error::io_err;
use crate::files::{FileEntry, Temporary, sync_dir};
use crate::shapes::{record_kind, unit_records};
use crate::{GenerateError, Group, Job};
use coupler_index::{
    COLUMNS_FILE, ColumnsWriter, IndexCurve, IndexKey, write_curve_line, write_index_footer,
    write_index_header,
};
use coupler_shape::{RecordKind, SHAPES_FILE, sidecar_header_for};
use rayon::prelude::*;
use std::io::Write;

/// The index, columns and sidecar being written.
pub(crate) struct Assembly {
    index: Temporary,
    columns: ColumnsWriter<Temporary>,
    shapes: Option<(Temporary, RecordKind)>,
    /// Curves added so far.
    curves: u64,
    /// Curves of the whole atlas.
    total: u64,
}

/// What a chunk computed by this run gives the assembly.
pub(crate) struct ChunkParts<'a> {
    /// Its index lines, each ending in a newline, in id order.
    pub lines: &'a str,
    /// Its curves, as the lines record them.
    pub curves: &'a [IndexCurve],
    /// Its curves' sidecar records (see [`unit_records`]), in id order.
    pub shapes: &'a [u8],
}

impl Assembly {
    /// Starts the three files of `job`'s atlas in `job.out` (under temporary names).
    pub(crate) fn start(
        job: &Job,
        summary: &coupler_index::IndexSummary,
    ) -> Result<Assembly, GenerateError> {
        let index_path = job.out.join("index.json");
        let mut index = Temporary::create(&index_path).map_err(io_err(&index_path))?;
        write_index_header(&mut index, &job.spec, summary).map_err(io_err(&index_path))?;
        let columns_path = job.out.join(COLUMNS_FILE);
        let columns = Temporary::create(&columns_path)
            .and_then(ColumnsWriter::new)
            .map_err(io_err(&columns_path))?;
        let total = job.curves();
        let shapes = match record_kind(job) {
            Some(kind) => {
                let path = job.out.join(SHAPES_FILE);
                let mut t = Temporary::create(&path).map_err(io_err(&path))?;
                t.write_all(&sidecar_header_for(kind, total))
                    .map_err(io_err(&path))?;
                Some((t, kind))
            }
            None => None,
        };
        Ok(Assembly {
            index,
            columns,
            shapes,
            curves: 0,
            total,
        })
    }

    /// The sidecar's record kind (`None` for an atlas without curves).
    pub(crate) fn record_kind(&self) -> Option<RecordKind> {
        self.shapes.as_ref().map(|(_, k)| *k)
    }

    /// Adds the next chunk, computed by this run.
    pub(crate) fn push(&mut self, chunk: ChunkParts<'_>) -> Result<(), GenerateError> {
        let index_path = self.index.path().to_path_buf();
        for line in chunk.lines.lines() {
            write_curve_line(&mut self.index, self.curves == 0, line)
                .map_err(io_err(&index_path))?;
            self.curves += 1;
        }
        let columns_path = self.index.path().with_file_name(COLUMNS_FILE);
        for c in chunk.curves {
            self.columns.push(c).map_err(io_err(&columns_path))?;
        }
        self.push_shapes(chunk.shapes)
    }

    /// Makes what was assembled so far durable (on the record writer's thread, while the
    /// workers compute the next chunk), so that after the last chunk the closing fsyncs
    /// ([`Assembly::finish`]) have only the last chunk's bytes to write: they are on the
    /// run's critical path, alone, while every core but one is idle. Nothing to do once
    /// every curve is in: the closing fsyncs (run side by side) write the rest.
    pub(crate) fn sync_written(&mut self) -> Result<(), GenerateError> {
        if self.curves == self.total {
            return Ok(());
        }
        let files = [Some(&mut self.index), Some(self.columns.get_mut())]
            .into_iter()
            .chain([self.shapes.as_mut().map(|(t, _)| t)]);
        for t in files.flatten() {
            let path = t.path().to_path_buf();
            t.sync_written().map_err(io_err(&path))?;
        }
        Ok(())
    }

    fn push_shapes(&mut self, records: &[u8]) -> Result<(), GenerateError> {
        if let Some((t, _)) = self.shapes.as_mut() {
            t.write_all(records).map_err(io_err(t.path()))?;
        }
        Ok(())
    }

    /// Adds chunk `c` of `job` from its record in `job.out` (run key `key`), whose units
    /// are `units`: the lines as the record holds them (checked against its hash; a record
    /// that changed since it was checked stops the assembly), parsed on `pool` for the
    /// columns; the sidecar records coded on `pool`.
    pub(crate) fn push_record(
        &mut self,
        job: &Job,
        c: u64,
        key: &str,
        units: &[Group],
        pool: &rayon::ThreadPool,
    ) -> Result<(), GenerateError> {
        let index_path = self.index.path().to_path_buf();
        pool.install(|| {
            let (index, columns, curves) = (&mut self.index, &mut self.columns, &mut self.curves);
            let mut sink = |line: &str| {
                write_curve_line(&mut *index, *curves == 0, line)?;
                *curves += 1;
                columns.push_line(line)
            };
            read_chunk(&job.out, c, key, false, Some(&mut sink)).map_err(|p| {
                io_err(&index_path)(std::io::Error::other(format!(
                    "chunk {c} changed while assembling: {p}"
                )))
            })
        })?;
        if let Some(kind) = self.record_kind() {
            let records: Vec<Vec<u8>> = pool.install(|| {
                units
                    .par_iter()
                    .map(|g| unit_records(job, g, kind))
                    .collect::<Result<_, _>>()
            })?;
            for r in &records {
                self.push_shapes(r)?;
            }
        }
        Ok(())
    }

    /// The assembly of every chunk of `job` from the records in `job.out` (a merge).
    pub(crate) fn of_records(
        job: &Job,
        summary: &coupler_index::IndexSummary,
        key: &str,
    ) -> Result<Assembly, GenerateError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(job.jobs)
            .build()
            .map_err(|e| io_err(&job.out)(std::io::Error::other(e)))?;
        let mut asm = Assembly::start(job, summary)?;
        let mut units = job.units();
        for c in 0..job.chunk_count() {
            let chunk: Vec<Group> = units.by_ref().take(CHUNK_GROUPS).collect();
            asm.push_record(job, c, key, &chunk, &pool)?;
        }
        Ok(asm)
    }

    /// Ends the three files and makes them durable (still under temporary names): the
    /// index's footer, the columns' directory and trailer (with the index's size and
    /// hash), the sidecar checked to hold every curve.
    pub(crate) fn finish(mut self) -> Result<Assembled, GenerateError> {
        let index_path = self.index.path().to_path_buf();
        if self.curves != self.total {
            return Err(io_err(&index_path)(std::io::Error::other(format!(
                "{} curves assembled for an atlas of {}",
                self.curves, self.total
            ))));
        }
        write_index_footer(&mut self.index).map_err(io_err(&index_path))?;
        let index_entry = self.index.entry("index.json");
        let key = IndexKey {
            bytes: index_entry.bytes,
            hash: self.index.digest(),
        };
        let columns_path = index_path.with_file_name(COLUMNS_FILE);
        let columns = self.columns.finish(key).map_err(io_err(&columns_path))?;
        let columns_entry = columns.entry(COLUMNS_FILE);
        let mut files = vec![(self.index, index_entry), (columns, columns_entry)];
        if let Some((t, kind)) = self.shapes {
            let expected = sidecar_header_for(kind, self.total).len() as u64
                + self.total * kind.record_bytes() as u64;
            let e = t.entry(SHAPES_FILE);
            if e.bytes != expected {
                return Err(io_err(t.path())(std::io::Error::other(format!(
                    "{} bytes of shape records for an atlas of {} curves ({expected} expected)",
                    e.bytes, self.total
                ))));
            }
            files.push((t, e));
        }
        // The three fsyncs at once: the file system can commit them together.
        std::thread::scope(|s| {
            let closing: Vec<_> = files
                .iter_mut()
                .map(|(t, _)| {
                    s.spawn(move || {
                        let path = t.path().to_path_buf();
                        t.close(true).map_err(io_err(&path))
                    })
                })
                .collect();
            closing
                .into_iter()
                .try_for_each(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
        })?;
        Ok(Assembled { files })
    }
}

/// The index, columns and sidecar, complete and durable under temporary names.
pub(crate) struct Assembled {
    files: Vec<(Temporary, FileEntry)>,
}

impl Assembled {
    /// The files' entries (names, sizes and hashes), as [`Assembled::commit`] returns them.
    pub(crate) fn entries(&self) -> Vec<FileEntry> {
        self.files.iter().map(|(_, e)| e.clone()).collect()
    }

    /// Renames the files into place (durably: one fsync of the folder for all three)
    /// and returns their entries.
    pub(crate) fn commit(self, out: &std::path::Path) -> Result<Vec<FileEntry>, GenerateError> {
        let mut entries = Vec::with_capacity(self.files.len());
        for (t, e) in self.files {
            let path = t.path().to_path_buf();
            t.commit(false).map_err(io_err(&path))?;
            entries.push(e);
        }
        sync_dir(out).map_err(io_err(out))?;
        Ok(entries)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compute_group;
    use coupler_index::curve_line;
    use coupler_kinematics::AngleTables;

    /// The columns a run builds from the curves it computed are the bytes of the columns
    /// built from those curves' index lines (as a resumed run or a merge builds them from
    /// the records), also when the two are mixed chunk by chunk: a run that reuses some
    /// chunks writes what a fresh run writes.
    #[test]
    fn columns_from_curves_equal_columns_from_their_lines() {
        for job in crate::job::quick_jobs() {
            let name = job.source.as_str();
            let table = AngleTables::new(job.spec.sampling.crank_step_deg).unwrap();
            let dash = job.spec.sampling.dash_pattern();
            let tolerances = &job.spec.features.tolerances;
            let units: Vec<Vec<IndexCurve>> = job
                .units()
                .map(|g| compute_group(&table, &g, Some(tolerances), &dash).unwrap())
                .collect();
            assert!(units.iter().flatten().any(|c| {
                c.features
                    .as_ref()
                    .is_some_and(|f| !f.pseudo_arcs.is_empty() && !f.straight_segments.is_empty())
            }));
            let key = IndexKey { bytes: 1, hash: 2 };
            let build = |lines_of: &dyn Fn(usize) -> bool| {
                let mut w = ColumnsWriter::new(Vec::new()).unwrap();
                for (k, unit) in units.iter().enumerate() {
                    for c in unit {
                        if lines_of(k) {
                            w.push_line(&curve_line(c).unwrap()).unwrap();
                        } else {
                            w.push(c).unwrap();
                        }
                    }
                }
                w.finish(key).unwrap()
            };
            let from_lines = build(&|_| true);
            assert_eq!(build(&|_| false), from_lines, "{name}: all from curves");
            assert_eq!(build(&|k| k % 2 == 0), from_lines, "{name}: mixed");
        }
    }
}
