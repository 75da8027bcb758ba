//! Running a job: work cut into fixed chunks of groups in atlas order; each chunk's
//! pages written as they finish and its record (index lines, files with sizes and hashes)
//! written last, so a killed run resumes where it stopped; a shard computes its share of
//! the chunks; [`merge`] gathers shard folders; the index and manifest are assembled from
//! the chunk records.

use crate::error::io_err;
use crate::files::{remove_stale_temporaries, write_artifact, write_manifest};
use crate::{
    Artifact, FileEntry, GenerateError, Group, Job, PageFailure, Rendered, Renderer, STATE_DIR,
    check_out_dir, compute_group, write_atomically,
};
use coupler_index::{
    IndexCurve, IndexSummary, curve_line, write_curve_line, write_index_footer, write_index_header,
};
use coupler_kinematics::CrankTable;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::io::{BufRead, Write as _};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// Groups per chunk: the unit of resumption and sharding. Fixed, so chunk boundaries do
/// not depend on the machine.
pub const CHUNK_GROUPS: usize = 32;

/// What a run did.
#[derive(Clone, Debug, PartialEq)]
pub struct RunReport {
    /// Counts, as written in the index.
    pub summary: IndexSummary,
    /// The index file written (`None` for a shard of several, which writes no index).
    pub index_path: Option<PathBuf>,
    /// Chunks this run computed.
    pub computed_chunks: usize,
    /// Chunks found complete and valid from an earlier run, and skipped.
    pub reused_chunks: usize,
    /// Chunks of the whole job.
    pub total_chunks: usize,
}

/// First line of a chunk record; its curve lines follow, one per line, as in the index.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct ChunkHeader {
    run_key: String,
    chunk: usize,
    curves: usize,
    files: Vec<FileEntry>,
}

/// The key that says whether an earlier run's chunk records can be reused: the program
/// version, the spec and the renderer's settings.
pub fn run_key(job: &Job, renderer: &dyn Renderer) -> String {
    let spec = serde_json::to_string(&job.spec).unwrap_or_default();
    let text = format!(
        "coupler-atlas {}\n{CHUNK_GROUPS}\n{spec}\n{}",
        env!("CARGO_PKG_VERSION"),
        renderer.settings()
    );
    format!("{:032x}", xxhash_rust::xxh3::xxh3_128(text.as_bytes()))
}

fn chunk_path(dir: &Path, chunk: usize) -> PathBuf {
    dir.join(STATE_DIR)
        .join("chunks")
        .join(format!("{chunk:06}.jsonl"))
}

/// Reads a chunk record if it is complete, of this run key, and all its files verify.
fn read_valid_chunk(dir: &Path, chunk: usize, key: &str) -> Option<(ChunkHeader, Vec<String>)> {
    let file = std::fs::File::open(chunk_path(dir, chunk)).ok()?;
    let mut lines = std::io::BufReader::new(file).lines();
    let header: ChunkHeader = serde_json::from_str(&lines.next()?.ok()?).ok()?;
    if header.run_key != key || header.chunk != chunk {
        return None;
    }
    let curves: Vec<String> = lines.collect::<Result<_, _>>().ok()?;
    if curves.len() != header.curves || !header.files.iter().all(|f| f.verify(dir)) {
        return None;
    }
    Some((header, curves))
}

/// The curve lines of a chunk record of this run key (files not re-verified).
fn read_chunk_lines(dir: &Path, chunk: usize, key: &str) -> Option<Vec<String>> {
    let file = std::fs::File::open(chunk_path(dir, chunk)).ok()?;
    let mut lines = std::io::BufReader::new(file).lines();
    let header: ChunkHeader = serde_json::from_str(&lines.next()?.ok()?).ok()?;
    let curves: Vec<String> = lines.collect::<Result<_, _>>().ok()?;
    (header.run_key == key && header.chunk == chunk && curves.len() == header.curves)
        .then_some(curves)
}

/// A group's index records, the files it wrote, and the pages that failed.
type GroupOutput = (Vec<IndexCurve>, Vec<FileEntry>, Vec<PageFailure>);

/// Writes what a renderer made: each file atomically; a page that failed, or a file that
/// could not be written, becomes a [`PageFailure`] and the others go on.
pub(crate) fn write_rendered(dir: &Path, rendered: Rendered) -> (Vec<FileEntry>, Vec<PageFailure>) {
    let (mut files, mut failed) = (Vec::new(), Vec::new());
    for r in rendered {
        match r.and_then(|a| {
            write_artifact(dir, &a).map_err(|e| PageFailure {
                page: a.name.clone(),
                message: error_chain(&e),
            })
        }) {
            Ok(f) => files.push(f),
            Err(f) => failed.push(f),
        }
    }
    (files, failed)
}

/// An error and its causes, joined by `: `.
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut source = e.source();
    while let Some(c) = source {
        s.push_str(": ");
        s.push_str(&c.to_string());
        source = c.source();
    }
    s
}

/// Runs the job (its shard of it): computes the chunks not already complete, on
/// `job.jobs` threads, writing pages as they finish; for a whole job (shard 1/1) then
/// assembles `index.json` and `manifest.json`. `progress` is called with the number of
/// curves finished, from any thread; `interrupt` is polled before each group.
///
/// A page that fails (cannot be made or written) does not stop the run: it is recorded,
/// its chunk is not recorded as complete (so the same command redoes it), every other
/// page is written, and the run ends with [`GenerateError::PagesFailed`] naming every
/// failed page (no index or manifest is written for an incomplete atlas).
pub fn run(
    job: &Job,
    renderer: &dyn Renderer,
    progress: &(dyn Fn(u64) + Sync),
    interrupt: &AtomicBool,
) -> Result<RunReport, GenerateError> {
    check_out_dir(&job.out, job.force)?;
    let table = CrankTable::new(job.spec.sampling.crank_step_deg)
        .ok_or(GenerateError::BadStep(job.spec.sampling.crank_step_deg))?;
    std::fs::create_dir_all(&job.out).map_err(io_err(&job.out))?;
    let chunks_dir = job.out.join(STATE_DIR).join("chunks");
    std::fs::create_dir_all(&chunks_dir).map_err(io_err(&chunks_dir))?;
    remove_stale_temporaries(&job.out);
    let key = run_key(job, renderer);
    let dash = job.spec.sampling.dash_pattern();
    let groups = job.groups();
    let chunks: Vec<&[Group]> = groups.chunks(CHUNK_GROUPS).collect();
    let mine: Vec<usize> = (0..chunks.len()).filter(|&c| job.shard.owns(c)).collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(job.jobs)
        .build()
        .map_err(|e| GenerateError::Io {
            path: job.out.clone(),
            source: std::io::Error::other(e),
        })?;
    let (mut computed, mut reused) = (0, 0);
    let mut failed: Vec<PageFailure> = Vec::new();
    for (done, &c) in mine.iter().enumerate() {
        if let Some((header, _)) = read_valid_chunk(&job.out, c, &key) {
            progress(header.curves as u64);
            reused += 1;
            continue;
        }
        let results: Result<Vec<GroupOutput>, GenerateError> = pool.install(|| {
            chunks[c]
                .par_iter()
                .map(|g| {
                    if interrupt.load(Ordering::Relaxed) {
                        return Err(GenerateError::Interrupted {
                            done: reused + computed,
                            total: mine.len(),
                            dir: job.out.clone(),
                        });
                    }
                    let features = job
                        .spec
                        .features
                        .enabled
                        .then_some(&job.spec.features.tolerances);
                    let mut curves = compute_group(&table, g, features, &dash)?;
                    let rendered = renderer.render_group(job, g, &mut curves);
                    let (files, failed) = write_rendered(&job.out, rendered);
                    progress(curves.len() as u64);
                    Ok((curves, files, failed))
                })
                .collect()
        });
        let results = results.map_err(|e| match e {
            GenerateError::Interrupted { .. } => GenerateError::Interrupted {
                done,
                total: mine.len(),
                dir: job.out.clone(),
            },
            other => other,
        })?;
        let chunk_failed: Vec<PageFailure> =
            results.iter().flat_map(|r| r.2.iter().cloned()).collect();
        if !chunk_failed.is_empty() {
            // Not recorded as complete: the same command redoes this chunk.
            failed.extend(chunk_failed);
            continue;
        }
        let curves: Vec<&IndexCurve> = results.iter().flat_map(|r| &r.0).collect();
        let files: Vec<FileEntry> = results.iter().flat_map(|r| r.1.iter().cloned()).collect();
        let header = ChunkHeader {
            run_key: key.clone(),
            chunk: c,
            curves: curves.len(),
            files,
        };
        let path = chunk_path(&job.out, c);
        write_atomically(&path, |w| {
            serde_json::to_writer(&mut *w, &header)?;
            for curve in &curves {
                w.write_all(b"\n")?;
                w.write_all(curve_line(curve)?.as_bytes())?;
            }
            w.write_all(b"\n")
        })?;
        computed += 1;
    }
    if !failed.is_empty() {
        if job.shard.count == 1 {
            // The atlas-level pages (contents) do not depend on the failed ones.
            let (_, atlas_failed) = write_rendered(&job.out, renderer.render_atlas(job));
            failed.extend(atlas_failed);
        }
        return Err(GenerateError::PagesFailed {
            failed,
            dir: job.out.clone(),
        });
    }
    let summary = job.summary(renderer.pages(job));
    let index_path = if job.shard.count == 1 {
        Some(assemble(job, renderer, &key, chunks.len())?)
    } else {
        None
    };
    Ok(RunReport {
        summary,
        index_path,
        computed_chunks: computed,
        reused_chunks: reused,
        total_chunks: chunks.len(),
    })
}

/// Writes `index.json` (streamed from the chunk records, in chunk order), the
/// atlas-level files, and `manifest.json` into `job.out`. Every chunk must be present,
/// complete and valid there.
fn assemble(
    job: &Job,
    renderer: &dyn Renderer,
    key: &str,
    total: usize,
) -> Result<PathBuf, GenerateError> {
    let mut files: Vec<FileEntry> = Vec::new();
    for c in 0..total {
        let (header, _) = read_valid_chunk(&job.out, c, key).ok_or_else(|| {
            GenerateError::Merge(format!("chunk {c} of {total} is missing or incomplete in {}; rerun the same command to complete it", job.out.display()))
        })?;
        files.extend(header.files);
    }
    let (atlas_files, failed) = write_rendered(&job.out, renderer.render_atlas(job));
    if !failed.is_empty() {
        return Err(GenerateError::PagesFailed {
            failed,
            dir: job.out.clone(),
        });
    }
    files.extend(atlas_files);
    let summary = job.summary(renderer.pages(job));
    let index_path = job.out.join("index.json");
    write_atomically(&index_path, |w| {
        write_index_header(&mut *w, &job.spec, &summary)?;
        let mut first = true;
        for c in 0..total {
            // Checked (files and all) just above; the curve lines are read again here so
            // that only one chunk's lines are in memory at a time.
            let curves = read_chunk_lines(&job.out, c, key).ok_or_else(|| {
                std::io::Error::other(format!("chunk {c} changed while assembling"))
            })?;
            for line in curves {
                write_curve_line(&mut *w, first, &line)?;
                first = false;
            }
        }
        write_index_footer(&mut *w)
    })?;
    files.push(FileEntry::of_file(&job.out, "index.json").map_err(io_err(&index_path))?);
    files.extend(crate::shapes::write_shapes(job)?);
    write_manifest(&job.out, key, files)?;
    Ok(index_path)
}

/// Merges shard folders into `job.out` (which may be one of them): copies every chunk
/// record and its files (verified by hash) into `job.out`, then assembles the index and
/// manifest exactly as a single run writes them. Refuses if the shards are of another
/// spec or settings, or if any chunk is missing.
pub fn merge(
    job: &Job,
    renderer: &dyn Renderer,
    shards: &[PathBuf],
) -> Result<PathBuf, GenerateError> {
    check_out_dir(&job.out, job.force)?;
    let key = run_key(job, renderer);
    let total = job.groups().chunks(CHUNK_GROUPS).count();
    // Find every chunk before writing anything.
    let mut sources: Vec<Option<&PathBuf>> = Vec::with_capacity(total);
    for c in 0..total {
        if read_valid_chunk(&job.out, c, &key).is_some() {
            sources.push(None);
            continue;
        }
        let Some(src) = shards
            .iter()
            .find(|d| read_valid_chunk(d, c, &key).is_some())
        else {
            return Err(GenerateError::Merge(format!(
                "chunk {c} of {total} is in none of the shard folders (complete and of this spec and settings); check that every shard finished and that all were run with the same spec and flags"
            )));
        };
        sources.push(Some(src));
    }
    let chunks_dir = job.out.join(STATE_DIR).join("chunks");
    std::fs::create_dir_all(&chunks_dir).map_err(io_err(&chunks_dir))?;
    for (c, src) in sources.into_iter().enumerate() {
        let Some(src) = src else { continue };
        let (header, _) = read_valid_chunk(src, c, &key).ok_or_else(|| {
            GenerateError::Merge(format!(
                "chunk {c} changed in {} while merging",
                src.display()
            ))
        })?;
        for f in &header.files {
            let from = src.join(&f.name);
            let bytes = std::fs::read(&from).map_err(io_err(&from))?;
            write_artifact(
                &job.out,
                &Artifact {
                    name: f.name.clone(),
                    bytes,
                },
            )?;
        }
        let record = std::fs::read(chunk_path(src, c)).map_err(io_err(&chunk_path(src, c)))?;
        write_atomically(&chunk_path(&job.out, c), |w| w.write_all(&record))?;
    }
    assemble(job, renderer, &key, total)
}
