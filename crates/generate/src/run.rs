//! Running a job: work cut into fixed chunks of units in atlas order; each chunk's pages
//! written as they finish and its record (index lines with their hash, files with sizes
//! and hashes) written last, so a killed run resumes where it stopped; a shard computes
//! its share of the chunks; [`merge`] gathers shard folders. The index, its search columns
//! and the shape sidecar are built as the chunks come (`assembly.rs`: a computed chunk
//! from memory, a chunk found complete from its record, verified as it is read); the
//! manifest is written last. The chunk records themselves (their format, reading and
//! checking) are `chunk.rs`.

use crate::assembly::{Assembly, ChunkParts};
use crate::chunk::{self, CHUNK_GROUPS, ChunkProblem, chunk_path, read_chunk};
use crate::error::io_err;
use crate::files::{
    PAGES_DIR, Staged, check_out_dir, check_subfolders, hash_reader, manifest_file, open_regular,
    read_manifest, remove_stale_temporaries, stage_artifact, sync_files, sync_folders,
    write_artifact, write_file,
};
use crate::lock::FolderLock;
use crate::plan::{Limits, Plan};
use crate::state::{
    Identity, Ledger, Names, PageFlags, check_user_files, prune, read_identity, remove_atlas,
    write_identity,
};
use crate::{
    FileEntry, GenerateError, Group, Job, PageFailure, PageTimings, Rendered, Renderer, STATE_DIR,
    compute_group, write_atomically,
};
use coupler_index::{IndexCurve, IndexSummary, curve_line};
use coupler_kinematics::AngleTables;
use std::collections::VecDeque;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

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
    /// The atlas was complete: every file verified, nothing written.
    pub verified: bool,
    /// An atlas of the same name made with other settings was removed first.
    pub replaced: bool,
    /// Files an earlier run wrote that this atlas no longer has, removed at the end.
    pub removed_files: usize,
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

/// Whether the folder a run is writing is still there (its `.coupler-atlas/chunks/`, which
/// [`prepare`] made): one `stat`, checked before each chunk so that a run whose folder was
/// removed stops at once instead of computing on with every write failing.
fn still_there(out: &Path) -> Result<(), GenerateError> {
    match std::fs::symlink_metadata(out.join(STATE_DIR).join("chunks")) {
        Ok(m) if m.is_dir() => Ok(()),
        _ => Err(GenerateError::FolderRemoved {
            dir: out.to_path_buf(),
        }),
    }
}

/// `e`, or [`GenerateError::FolderRemoved`] if it came from the folder being removed.
fn or_removed(out: &Path, e: GenerateError) -> GenerateError {
    match e {
        GenerateError::Io { .. } | GenerateError::PagesFailed { .. } => {
            still_there(out).err().unwrap_or(e)
        }
        e => e,
    }
}

/// A computed chunk, ready to be recorded: its curve lines (each ending in a newline, in
/// id order), how many, the first id, and the files its pages are in; for a whole run,
/// also its curves and their shape records (for the assembly).
struct ChunkLines {
    chunk: u64,
    lines: String,
    curves: u64,
    first_id: u64,
    files: Vec<FileEntry>,
    records: Vec<IndexCurve>,
    shapes: Vec<u8>,
}

/// What the record writer is given, in chunk order.
enum Finished {
    /// A chunk computed by this run: its record is written (and it is assembled).
    Computed(ChunkLines),
    /// A chunk found complete (its record verified), and its units: assembled from the
    /// record.
    Reused(u64, Vec<Group>),
    /// A chunk not recorded (a page failed): the atlas is not assembled.
    Failed,
}

/// The index lines of `curves`, each ending in a newline (formatted by the worker that
/// computed them, so that the run's serial part stays small).
fn format_lines(curves: &[IndexCurve]) -> std::io::Result<String> {
    let mut lines = String::new();
    for c in curves {
        lines.push_str(&curve_line(c)?);
        lines.push('\n');
    }
    Ok(lines)
}

/// Makes files `names` of `dir` durable ahead of their chunk's record, which syncs them
/// again ([`sync_files`], where an error counts): here an error is left to that sync, and
/// a file that is not there is neither made nor waited for. (A name may be a full path,
/// as a staged file's temporary one is: `dir` is then not used.)
fn sync_early(dir: &Path, names: &[String]) {
    for n in names {
        if let Ok(f) = std::fs::File::open(dir.join(n)) {
            let _ = f.sync_all();
        }
    }
}

/// Writes the record of a computed chunk (durably: after the files it lists are made
/// durable).
fn write_chunk(dir: &Path, key: &str, c: &ChunkLines) -> Result<(), GenerateError> {
    sync_files(dir, c.files.iter().map(|f| f.name.as_str()))?;
    chunk::write_record(dir, key, c.chunk, c.curves, c.first_id, &c.lines, &c.files)
}
/// A group's index lines (see [`format_lines`]), their count and first id, the files it
/// wrote, and the pages that failed; for a whole run, its curves and their shape records.
struct GroupOutput {
    lines: String,
    curves: u64,
    first_id: Option<u64>,
    files: Vec<FileEntry>,
    failed: Vec<PageFailure>,
    records: Vec<IndexCurve>,
    shapes: Vec<u8>,
}

/// How many chunks may be computing beyond the one whose outputs are awaited: one, so a
/// worker that finds no unit left in a chunk starts the next chunk's units.
const AHEAD: usize = 1;

/// The run's last units, per worker, whose pages are drawn as tasks any worker may take
/// ([`Renderer::render_group_shared`]): once no unit is left to start, a free worker draws
/// some of the pages of those still running instead of waiting for them (a unit is a
/// group of several pages; at the run's end one worker would otherwise wait up to a whole
/// group for the other). Earlier units are drawn by the worker that took them, each page
/// in its cache.
const SHARED_TAIL_UNITS: u64 = 4;

/// Whether unit `k` of chunk `c` is among the run's last units ([`SHARED_TAIL_UNITS`] per
/// worker, counted back from the last unit of `last_chunk`, the last chunk the run
/// computes, in a job of `units` units): none with one worker.
fn in_shared_tail(c: u64, k: usize, last_chunk: u64, units: u64, workers: usize) -> bool {
    if workers < 2 {
        return false;
    }
    let last = ((last_chunk + 1) * CHUNK_GROUPS as u64).min(units);
    let unit = c * CHUNK_GROUPS as u64 + k as u64;
    unit < last && last - unit <= SHARED_TAIL_UNITS * workers as u64
}

/// One unit's output, by chunk and place in it (a panic carried as its payload).
type UnitResult = (
    u64,
    usize,
    std::thread::Result<Result<GroupOutput, GenerateError>>,
);

/// A chunk taken into the run, finished (handed to the record writer) in chunk order.
enum Admitted {
    /// Another shard's chunk.
    Skipped,
    /// Found complete by an earlier run (its record verified): its files and units.
    Reused(u64, Vec<FileEntry>, Vec<Group>),
    /// Being computed: each unit's output as it comes, and how many are still missing.
    Computing {
        chunk: u64,
        outputs: Vec<Option<Result<GroupOutput, GenerateError>>>,
        missing: usize,
    },
}

impl Admitted {
    fn computing(&self) -> bool {
        matches!(self, Admitted::Computing { .. })
    }
}

/// What the chunks finished so far amount to.
#[derive(Default)]
struct Done {
    computed: usize,
    reused: usize,
    failed: Vec<PageFailure>,
    /// The files of every chunk found complete or computed (for the manifest), in chunk
    /// order; `None` for a chunk not recorded.
    chunk_files: Vec<Option<Vec<FileEntry>>>,
}

/// Finishes the first chunk of `queue`: waits for its units' outputs (keeping those of
/// later chunks that come meanwhile), then hands the chunk to the record writer. A unit's
/// error is returned when its chunk is finished, so the chunks before it are recorded as
/// they would be one at a time. `Ok(false)`: the writer stopped (on an error it reports).
fn finish_front(
    queue: &mut VecDeque<Admitted>,
    done: &mut Done,
    whole: bool,
    outputs: &std::sync::mpsc::Receiver<UnitResult>,
    records: &std::sync::mpsc::SyncSender<Finished>,
    stop: &AtomicBool,
) -> Result<bool, GenerateError> {
    while matches!(queue.front(), Some(Admitted::Computing { missing, .. }) if *missing > 0) {
        let Ok((c, k, out)) = outputs.recv() else {
            unreachable!("the run holds a sender of the units' outputs")
        };
        let out = out.unwrap_or_else(|panic| {
            stop.store(true, Ordering::Relaxed);
            std::panic::resume_unwind(panic)
        });
        let slot = queue.iter_mut().find_map(|a| match a {
            Admitted::Computing {
                chunk,
                outputs,
                missing,
            } if *chunk == c => Some((outputs, missing)),
            _ => None,
        });
        let Some((slots, missing)) = slot else {
            unreachable!("an output of chunk {c}, which is not being computed")
        };
        slots[k] = Some(out);
        *missing -= 1;
    }
    let Some(front) = queue.pop_front() else {
        return Ok(true);
    };
    let (c, outputs) = match front {
        Admitted::Skipped => {
            if whole {
                done.chunk_files.push(None);
            }
            return Ok(true);
        }
        Admitted::Reused(c, files, units) => {
            done.reused += 1;
            if whole {
                done.chunk_files.push(Some(files));
                return Ok(records.send(Finished::Reused(c, units)).is_ok());
            }
            return Ok(true);
        }
        Admitted::Computing { chunk, outputs, .. } => (chunk, outputs),
    };
    let results: Vec<GroupOutput> = outputs
        .into_iter()
        .map(|o| o.expect("every unit's output came"))
        .collect::<Result<_, _>>()
        .map_err(|e| match e {
            // The chunks done are those handed to the writer before this one.
            GenerateError::Interrupted { total, dir, .. } => GenerateError::Interrupted {
                done: done.reused + done.computed,
                total,
                dir,
            },
            e => e,
        })?;
    let chunk_failed: Vec<PageFailure> = results
        .iter()
        .flat_map(|r| r.failed.iter().cloned())
        .collect();
    if !chunk_failed.is_empty() {
        // Not recorded as complete: the same command redoes this chunk.
        done.failed.extend(chunk_failed);
        if whole {
            done.chunk_files.push(None);
            return Ok(records.send(Finished::Failed).is_ok());
        }
        return Ok(true);
    }
    let mut lines = String::with_capacity(results.iter().map(|r| r.lines.len()).sum());
    let mut shapes = Vec::with_capacity(results.iter().map(|r| r.shapes.len()).sum());
    for r in &results {
        lines.push_str(&r.lines);
        shapes.extend_from_slice(&r.shapes);
    }
    let mut record = ChunkLines {
        chunk: c,
        lines,
        curves: results.iter().map(|r| r.curves).sum(),
        first_id: results.iter().find_map(|r| r.first_id).unwrap_or(0),
        files: Vec::new(),
        records: Vec::new(),
        shapes,
    };
    for r in results {
        record.files.extend(r.files);
        record.records.extend(r.records);
    }
    if whole {
        done.chunk_files.push(Some(record.files.clone()));
    }
    if records.send(Finished::Computed(record)).is_err() {
        // The writer stopped on an error: it is reported by the caller.
        return Ok(false);
    }
    done.computed += 1;
    Ok(true)
}

/// Writes what a renderer made: the names recorded in the ledger first (durably), then
/// each file atomically; a page that failed, or a file that could not be written,
/// becomes a [`PageFailure`] and the others go on.
pub(crate) fn write_rendered(
    dir: &Path,
    rendered: Rendered,
    ledger: &Ledger,
) -> (Vec<FileEntry>, Vec<PageFailure>) {
    let (mut files, mut failed) = (Vec::new(), Vec::new());
    let names: Vec<&str> = rendered
        .iter()
        .filter_map(|r| r.as_ref().ok().map(|a| a.name.as_str()))
        .collect();
    if let Err(e) = ledger.add(names) {
        let message = error_chain(&e);
        for r in rendered {
            failed.push(match r {
                Ok(a) => PageFailure {
                    page: a.name,
                    message: message.clone(),
                },
                Err(f) => f,
            });
        }
        return (files, failed);
    }
    for r in rendered {
        match r.and_then(|a| {
            let written = write_artifact(dir, &a).map_err(|e| PageFailure {
                page: a.name.clone(),
                message: error_chain(&e),
            });
            // The file's buffer, for this thread's next page (not zeroed again).
            coupler_render::reuse_png_buffer(a.bytes);
            written
        }) {
            Ok(f) => files.push(f),
            Err(f) => failed.push(f),
        }
    }
    (files, failed)
}

/// What a renderer made, written under temporary names (or why a file was not).
type StagedFiles = Vec<Result<Staged, PageFailure>>;

/// Writes what a renderer made under temporary names ([`stage_artifact`]), to be put in
/// place by [`write_staged`]; a file that could not be written becomes a failure.
fn stage_rendered(dir: &Path, rendered: Rendered) -> StagedFiles {
    rendered
        .into_iter()
        .map(|r| {
            r.and_then(|a| {
                stage_artifact(dir, &a).map_err(|e| PageFailure {
                    page: a.name.clone(),
                    message: error_chain(&e),
                })
            })
        })
        .collect()
}

/// [`write_rendered`] for files already written under temporary names: their names
/// recorded in the ledger first (durably), then each put in place.
fn write_staged(staged: StagedFiles, ledger: &Ledger) -> (Vec<FileEntry>, Vec<PageFailure>) {
    let (mut files, mut failed) = (Vec::new(), Vec::new());
    let names: Vec<&str> = staged
        .iter()
        .filter_map(|r| r.as_ref().ok().map(Staged::name))
        .collect();
    if let Err(e) = ledger.add(names) {
        let message = error_chain(&e);
        for r in staged {
            failed.push(match r {
                Ok(s) => PageFailure {
                    page: s.name().to_string(),
                    message: message.clone(),
                },
                Err(f) => f,
            });
        }
        return (files, failed);
    }
    for r in staged {
        match r.and_then(|s| {
            let page = s.name().to_string();
            s.commit().map_err(|e| PageFailure {
                page,
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

/// An output folder prepared for a run: locked, its leftovers of dead runs removed, its
/// ledger read, and checked to hold nothing of the user's where this atlas writes.
pub(crate) struct Prepared {
    _lock: FolderLock,
    pub ledger: Ledger,
    /// The folder held the same atlas made with other settings.
    pub replaced: bool,
}

/// Prepares `out` for writing the atlas `id` (whose files are `names`): refuses a folder
/// holding files this program did not write (unless `force`), a `pages/` that is a link,
/// another atlas, and any file of the user's where this atlas writes; takes the folder's
/// lock; removes temporaries of dead runs. Writes nothing into a folder that already is
/// this atlas's (a complete atlas verifies on a read-only disk).
pub(crate) fn prepare(
    out: &Path,
    force: bool,
    id: &Identity,
    names: &Names,
) -> Result<Prepared, GenerateError> {
    check_out_dir(out, force)?;
    check_subfolders(out)?;
    let had_state = out.join(STATE_DIR).is_dir();
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    let chunks = out.join(STATE_DIR).join("chunks");
    std::fs::create_dir_all(&chunks).map_err(io_err(&chunks))?;
    let lock = FolderLock::acquire(out)?;
    remove_stale_temporaries(out);
    let ledger = Ledger::read(out, had_state);
    let replaced = match read_identity(out).ok().flatten() {
        Some(prev) if !prev.same_run(id) => {
            if !prev.same_atlas(id) {
                return Err(GenerateError::OtherAtlas {
                    dir: out.to_path_buf(),
                    existing: prev.name,
                    source_name: prev.source,
                    new: id.name.clone(),
                });
            }
            true
        }
        _ => false,
    };
    check_user_files(out, &ledger, names)?;
    Ok(Prepared {
        _lock: lock,
        ledger,
        replaced,
    })
}

/// Whether `out` holds a complete atlas of run key `key`: its manifest is of this key and
/// every file it lists (the index among them) has its recorded size and hash.
pub(crate) fn verifies_complete(out: &Path, key: &str, index_name: &str) -> bool {
    match read_manifest(out) {
        Some(m) => {
            m.run_key == key
                && m.files.iter().any(|f| f.name == index_name)
                && m.files.iter().all(|f| f.verify(out))
        }
        None => false,
    }
}

/// The identity `job` records in its folder.
fn identity(job: &Job, renderer: &dyn Renderer, key: &str) -> Identity {
    let mut id = Identity::new("grid", &job.spec.name, &job.source, key);
    id.spec_toml = job.spec_text.clone();
    id.pages = renderer.page_options().map(PageFlags::of);
    id.shard = (job.shard.count > 1).then(|| format!("{}/{}", job.shard.index, job.shard.count));
    id
}

/// The stem of the page files (the spec's name unless the renderer says otherwise).
fn stem(job: &Job, renderer: &dyn Renderer) -> String {
    renderer
        .page_options()
        .map(|o| o.stem.clone())
        .unwrap_or_else(|| job.spec.name.clone())
}

const ROOT_FILES: [&str; 4] = [
    "manifest.json",
    "index.json",
    coupler_index::COLUMNS_FILE,
    coupler_shape::SHAPES_FILE,
];

/// Runs the job (its shard of it): computes the chunks not already complete, on
/// `job.jobs` threads, writing pages as they finish; for a whole job (shard 1/1) then
/// assembles `index.json` and `manifest.json`. `progress` is called with the number of
/// curves finished, from any thread; `interrupt` is polled before each group.
///
/// The output folder is locked for the run; a folder holding a complete atlas of this
/// spec and settings is verified without writing anything; one holding the same atlas
/// made with other settings is replaced as a whole; files the user put where the atlas
/// writes are never touched (the run refuses to start).
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
    let plan = Plan::new(job, renderer, Limits::DEFAULT);
    if let Some(r) = plan.refused.first() {
        return Err(GenerateError::Plan(r.clone()));
    }
    let table = AngleTables::new(job.spec.sampling.crank_step_deg)
        .ok_or(GenerateError::BadStep(job.spec.sampling.crank_step_deg))?;
    let key = run_key(job, renderer);
    let id = identity(job, renderer, &key);
    let stem = stem(job, renderer);
    let names = Names {
        root: &ROOT_FILES,
        stem: &stem,
    };
    let prep = prepare(&job.out, job.force, &id, &names)?;
    let total = job.chunk_count();
    let whole = job.shard.count == 1;
    if whole && !prep.replaced && verifies_complete(&job.out, &key, "index.json") {
        return Ok(RunReport {
            summary: job.summary(renderer.pages(job)),
            index_path: Some(job.out.join("index.json")),
            computed_chunks: 0,
            reused_chunks: total as usize,
            total_chunks: total as usize,
            verified: true,
            replaced: false,
            removed_files: 0,
        });
    }
    if prep.replaced {
        remove_atlas(&job.out, &prep.ledger, &ROOT_FILES)?;
    }
    write_identity(&job.out, &id)?;
    if renderer.page_options().is_some() {
        let pages = job.out.join(PAGES_DIR);
        std::fs::create_dir_all(&pages).map_err(io_err(&pages))?;
    }
    let dash = job.spec.sampling.dash_pattern();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(job.jobs)
        .build()
        .map_err(|e| GenerateError::Io {
            path: job.out.clone(),
            source: std::io::Error::other(e),
        })?;
    let mine = (0..total).filter(|&c| job.shard.owns(c as usize)).count();
    let features = job
        .spec
        .features
        .enabled
        .then_some(&job.spec.features.tolerances);
    let summary = job.summary(renderer.pages(job));
    // For a whole run, the index, columns and sidecar are built as the chunks come.
    let assembly = if whole {
        Some(Assembly::start(job, &summary)?)
    } else {
        None
    };
    let shape_kind = assembly.as_ref().and_then(Assembly::record_kind);
    // A whole run's atlas files, when the renderer makes them alongside the groups: made
    // by the pool's first task (see below) and written under temporary names, kept here
    // and put in place at the end as before (the ledger records their names after the
    // chunks', in the same order for any number of workers).
    let alongside: Mutex<Option<StagedFiles>> = Mutex::new(None);
    // The chunks' units are computed in atlas order by all workers, a chunk's first units
    // while the last of the one before are still running (see `finish_front`); a computed
    // chunk's record is written (its pages made durable, the record written and made
    // durable) and the chunk added to the assembly on a thread of its own while the next
    // chunks are computed. At most one chunk waits for it.
    let (computed, reused, failed, chunk_files, assembly) = std::thread::scope(|scope| {
        let (records, pending) = std::sync::mpsc::sync_channel::<Finished>(1);
        let (record_key, pool) = (key.as_str(), &pool);
        let writer = scope.spawn(move || -> Result<Option<Assembly>, GenerateError> {
            let mut assembly = assembly;
            for f in pending {
                match f {
                    Finished::Computed(c) => {
                        // The record (written and made durable) and the assembly's part
                        // side by side: neither needs the other, and after the last chunk
                        // both are on the run's critical path.
                        std::thread::scope(|s| -> Result<(), GenerateError> {
                            let record = s.spawn(|| write_chunk(&job.out, record_key, &c));
                            let assembled = match assembly.as_mut() {
                                Some(a) => a
                                    .push(ChunkParts {
                                        lines: &c.lines,
                                        curves: &c.records,
                                        shapes: &c.shapes,
                                    })
                                    .and_then(|()| a.sync_written()),
                                None => Ok(()),
                            };
                            let recorded = record
                                .join()
                                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
                            recorded.and(assembled)
                        })?;
                    }
                    Finished::Reused(c, units) => {
                        if let Some(a) = assembly.as_mut() {
                            a.push_record(job, c, record_key, &units, pool)?;
                        }
                    }
                    Finished::Failed => assembly = None,
                }
            }
            Ok(assembly)
        });
        let mut done = Done::default();
        let mut units = job.units();
        // The units are computed as tasks on the pool, in atlas order (first in, first
        // out), and their outputs gathered here by chunk: while the last units of one chunk
        // are still being computed, a free worker already starts the next chunk's, so no
        // worker waits at a chunk's end (at most `AHEAD` chunks beyond the one awaited).
        let (unit_done, unit_outputs) = std::sync::mpsc::channel::<UnitResult>();
        let stop = AtomicBool::new(false);
        // Each unit's files are made durable as soon as it has written them, on a thread
        // of their own (an fsync waits for the disk, not for a core): the chunk record's
        // own sync (`write_chunk`) then finds them written back, so that after the last
        // unit its chunk's sync is not all left on the run's critical path.
        let (early_sync, to_sync) = std::sync::mpsc::channel::<Vec<String>>();
        scope.spawn(move || {
            for names in to_sync {
                sync_early(&job.out, &names);
            }
        });
        // The last chunk this run computes (for the shared tail).
        let last_chunk = (0..total)
            .rev()
            .find(|&c| job.shard.owns(c as usize))
            .unwrap_or(0);
        let unit = |c: u64, k: usize, g: &Group| -> Result<GroupOutput, GenerateError> {
            if interrupt.load(Ordering::Relaxed) {
                // How many chunks are done is filled in by `finish_front`.
                return Err(GenerateError::Interrupted {
                    done: 0,
                    total: mine,
                    dir: job.out.clone(),
                });
            }
            let clocks = renderer.timings();
            let t = Instant::now();
            let mut curves = compute_group(&table, g, features, &dash)?;
            let index_time = t.elapsed();
            let rendered = if in_shared_tail(c, k, last_chunk, job.unit_count(), job.jobs) {
                renderer.render_group_shared(job, g, &mut curves)
            } else {
                renderer.render_group(job, g, &mut curves)
            };
            let t = Instant::now();
            let (files, failed) = write_rendered(&job.out, rendered, &prep.ledger);
            if !files.is_empty() {
                let _ = early_sync.send(files.iter().map(|f| f.name.clone()).collect());
            }
            let t = match clocks {
                Some(k) => PageTimings::add(&k.write, t),
                None => t,
            };
            let lines = format_lines(&curves).map_err(io_err(&chunk_path(&job.out, c)))?;
            let shapes = match shape_kind {
                Some(kind) => crate::shapes::unit_records(job, g, kind)?,
                None => Vec::new(),
            };
            if let Some(k) = clocks {
                let ns = (index_time + t.elapsed()).as_nanos() as u64;
                k.index.fetch_add(ns, Ordering::Relaxed);
            }
            progress(curves.len() as u64);
            Ok(GroupOutput {
                lines,
                curves: curves.len() as u64,
                first_id: curves.first().map(|c| c.id),
                files,
                failed,
                records: if whole { curves } else { Vec::new() },
                shapes,
            })
        };
        let result = pool.in_place_scope_fifo(|scope| -> Result<(), GenerateError> {
            if whole {
                // The atlas files that depend on the job alone (the contents pages) are
                // the first task: drawn by one worker while the other starts on the
                // groups, not after the last group with one worker idle.
                let (alongside, early_sync) = (&alongside, &early_sync);
                scope.spawn_fifo(move |_| {
                    let made = renderer
                        .render_atlas_alongside(job)
                        .map(|r| stage_rendered(&job.out, r));
                    // Their bytes made durable now, on the syncing thread, not all left to
                    // the closing sync after the last group (where both cores wait on it).
                    if let Some(staged) = &made {
                        let paths: Vec<String> = staged
                            .iter()
                            .filter_map(|s| s.as_ref().ok())
                            .map(|s| s.staged_path().to_string_lossy().into_owned())
                            .collect();
                        if !paths.is_empty() {
                            let _ = early_sync.send(paths);
                        }
                    }
                    *alongside.lock().unwrap_or_else(PoisonError::into_inner) = made;
                });
            }
            let mut queue: VecDeque<Admitted> = VecDeque::new();
            let finish =
                |queue: &mut VecDeque<Admitted>, done: &mut Done| -> Result<bool, GenerateError> {
                    finish_front(queue, done, whole, &unit_outputs, &records, &stop)
                };
            let run = (|| -> Result<(), GenerateError> {
                for c in 0..total {
                    let chunk: Vec<Group> = units.by_ref().take(CHUNK_GROUPS).collect();
                    if !job.shard.owns(c as usize) {
                        queue.push_back(Admitted::Skipped);
                        continue;
                    }
                    while queue.iter().filter(|a| a.computing()).count() > AHEAD {
                        if !finish(&mut queue, &mut done)? {
                            return Ok(());
                        }
                    }
                    if interrupt.load(Ordering::Relaxed) {
                        // The chunks already taken in are finished first (their units not
                        // started stop at once: a unit's `Interrupted` ends the run).
                        while !queue.is_empty() {
                            if !finish(&mut queue, &mut done)? {
                                return Ok(());
                            }
                        }
                        return Err(GenerateError::Interrupted {
                            done: done.reused + done.computed,
                            total: mine,
                            dir: job.out.clone(),
                        });
                    }
                    still_there(&job.out)?;
                    if let Ok(header) = read_chunk(&job.out, c, &key, true, None) {
                        progress(header.curves);
                        queue.push_back(Admitted::Reused(c, header.files, chunk));
                        continue;
                    }
                    // The names this chunk will write, recorded (durably) before any is
                    // written.
                    let known: Option<Vec<String>> = chunk
                        .iter()
                        .map(|g| renderer.group_files(job, g))
                        .collect::<Option<Vec<Vec<String>>>>()
                        .map(|v| v.concat());
                    if let Some(names) = &known {
                        prep.ledger.add(names.iter().map(String::as_str))?;
                    }
                    queue.push_back(Admitted::Computing {
                        chunk: c,
                        outputs: (0..chunk.len()).map(|_| None).collect(),
                        missing: chunk.len(),
                    });
                    for (k, g) in chunk.into_iter().enumerate() {
                        let (unit, stop, sender) = (&unit, &stop, unit_done.clone());
                        scope.spawn_fifo(move |_| {
                            if stop.load(Ordering::Relaxed) {
                                return;
                            }
                            // A panic is carried to the thread gathering the outputs
                            // (which would otherwise wait for this unit forever).
                            let out =
                                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                                    unit(c, k, &g)
                                }));
                            let _ = sender.send((c, k, out));
                        });
                    }
                }
                while !queue.is_empty() {
                    if !finish(&mut queue, &mut done)? {
                        return Ok(());
                    }
                }
                Ok(())
            })();
            // Units not started yet are skipped (the run stops); those running finish.
            stop.store(true, Ordering::Relaxed);
            run
        });
        let (computed, reused, failed, chunk_files) =
            (done.computed, done.reused, done.failed, done.chunk_files);
        drop(records);
        drop(early_sync);
        let written = writer
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        match (result, written) {
            (_, Err(e)) => Err(or_removed(&job.out, e)),
            (r, Ok(assembly)) => r.map(|()| (computed, reused, failed, chunk_files, assembly)),
        }
    })?;
    still_there(&job.out)?;
    let alongside = alongside
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner);
    let mut failed = failed;
    if !failed.is_empty() {
        if whole {
            // The atlas-level pages (contents) do not depend on the failed ones.
            let (_, atlas_failed) = match alongside {
                Some(staged) => write_staged(staged, &prep.ledger),
                None => write_rendered(&job.out, renderer.render_atlas(job), &prep.ledger),
            };
            failed.extend(atlas_failed);
        }
        return Err(GenerateError::PagesFailed {
            failed,
            dir: job.out.clone(),
        });
    }
    let (index_path, removed_files) = match assembly {
        Some(a) => {
            let (p, removed) =
                assemble(job, renderer, &key, chunk_files, &prep.ledger, a, alongside)?;
            (Some(p), removed)
        }
        None => (None, 0),
    };
    Ok(RunReport {
        summary,
        index_path,
        computed_chunks: computed,
        reused_chunks: reused,
        total_chunks: total as usize,
        verified: false,
        replaced: prep.replaced,
        removed_files,
    })
}

/// Puts the atlas-level files into `job.out`: the atlas pages, then the index, columns
/// and sidecar of `assembly` (every chunk added), then `manifest.json`; then removes files
/// of earlier runs this atlas no longer has. `known` holds the files of the chunks already
/// verified (the others are verified here); `made`, the atlas files if the run made them
/// already ([`Renderer::render_atlas_alongside`]). Returns the index's path and how many
/// old files were removed.
fn assemble(
    job: &Job,
    renderer: &dyn Renderer,
    key: &str,
    known: Vec<Option<Vec<FileEntry>>>,
    ledger: &Ledger,
    assembly: Assembly,
    made: Option<StagedFiles>,
) -> Result<(PathBuf, usize), GenerateError> {
    let total = job.chunk_count();
    let mut files: Vec<FileEntry> = Vec::new();
    for c in 0..total {
        match known.get(c as usize) {
            Some(Some(f)) => files.extend(f.iter().cloned()),
            _ => {
                let header = read_chunk(&job.out, c, key, true, None).map_err(|p| {
                    GenerateError::Merge(format!(
                        "chunk {c} of {total} is not complete in {} ({p}); run the same command again to complete it",
                        job.out.display()
                    ))
                })?;
                files.extend(header.files);
            }
        }
    }
    // Side by side, as none needs another and all must be done before anything is put in
    // place: the index's, columns' and sidecar's closing fsyncs; the ledger's record of the
    // root files and, after them (the order they had when recorded apart), of the atlas
    // files made alongside; and those files made durable under their temporary names
    // (their bytes were synced early, so this is quick). After the renames only their
    // folder then needs a sync, not each file again (whose renamed inode would cost a
    // journal commit of its own, two at a time).
    let staged_names: Vec<&str> = made
        .iter()
        .flatten()
        .filter_map(|s| s.as_ref().ok().map(Staged::name))
        .collect();
    let (assembled, recorded, staged_synced) = std::thread::scope(|s| {
        let record = s.spawn(|| ledger.add(ROOT_FILES.into_iter().chain(staged_names)));
        let staged = made.as_ref().map(|staged| {
            s.spawn(|| {
                use rayon::prelude::*;
                staged
                    .par_iter()
                    .filter_map(|s| s.as_ref().ok())
                    .try_for_each(Staged::sync)
            })
        });
        let assembled = assembly.finish();
        let recorded = record
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        let staged_synced = staged.map(|h| {
            h.join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
        });
        (assembled, recorded, staged_synced)
    });
    let assembled = assembled?;
    recorded?;
    let staged_durable = match staged_synced {
        Some(synced) => {
            synced?;
            true
        }
        None => false,
    };
    // (Made alongside, their names are recorded already: the ledger is not synced again.)
    let (atlas_files, failed) = match made {
        Some(staged) => write_staged(staged, ledger),
        None => write_rendered(&job.out, renderer.render_atlas(job), ledger),
    };
    if !failed.is_empty() {
        return Err(GenerateError::PagesFailed {
            failed,
            dir: job.out.clone(),
        });
    }
    let atlas_names: Vec<String> = atlas_files.iter().map(|f| f.name.clone()).collect();
    files.extend(atlas_files);
    files.extend(assembled.entries());
    // Side by side: the atlas files made durable in place (their folder synced, or each
    // file and its folder), the index's files renamed into place (durably), and the
    // manifest written and made durable under its temporary name; the manifest is put in
    // place after all of them.
    let (committed, manifest, placed) = std::thread::scope(|s| {
        let manifest = s.spawn(|| manifest_file(&job.out, key, files.clone()));
        let placed = s.spawn(|| {
            let names = atlas_names.iter().map(String::as_str);
            if staged_durable {
                sync_folders(&job.out, names)
            } else {
                sync_files(&job.out, names)
            }
        });
        let committed = assembled.commit(&job.out);
        let manifest = manifest
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        let placed = placed
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (committed, manifest, placed)
    });
    placed?;
    committed?;
    let manifest_path = job.out.join("manifest.json");
    manifest?.commit(true).map_err(io_err(&manifest_path))?;
    let mut keep: Vec<String> = files.into_iter().map(|f| f.name).collect();
    keep.push("manifest.json".into());
    let removed = prune(&job.out, ledger, &keep)?;
    Ok((job.out.join("index.json"), removed))
}

/// Copies file `f` of shard folder `src` into `out` (atomically), checking its size and
/// hash as it is copied: nothing that differs from the record is ever put in place.
fn copy_verified(src: &Path, out: &Path, f: &FileEntry) -> Result<(), GenerateError> {
    let from = src.join(&f.name);
    let file = open_regular(&from).map_err(io_err(&from))?;
    let to = out.join(&f.name);
    write_file(&to, false, |w| {
        let mut tee = Tee {
            inner: file,
            out: w,
            error: None,
        };
        let (bytes, hash) = hash_reader(&mut tee)?;
        if let Some(e) = tee.error {
            return Err(e);
        }
        if bytes != f.bytes || hash != f.xxh3 {
            return Err(std::io::Error::other(format!(
                "{} does not match its record (size or hash)",
                from.display()
            )));
        }
        Ok(())
    })
}

/// A reader that writes what it reads to `out`.
struct Tee<'a, R, W> {
    inner: R,
    out: &'a mut W,
    error: Option<std::io::Error>,
}

impl<R: std::io::Read, W: std::io::Write> std::io::Read for Tee<'_, R, W> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if let Err(e) = self.out.write_all(&buf[..n]) {
            self.error = Some(e);
            return Ok(0);
        }
        Ok(n)
    }
}

/// Merges shard folders into `job.out` (which may be one of them): checks that every
/// shard was made from this job's spec and settings (naming any that was not), copies
/// every chunk record and its files (verified by hash) into `job.out`, then assembles the
/// index and manifest exactly as a single run writes them. Refuses if any chunk is
/// missing, naming the shard that should hold it. `interrupt` is polled between files:
/// a stopped merge leaves no temporary file.
pub fn merge(
    job: &Job,
    renderer: &dyn Renderer,
    shards: &[PathBuf],
    interrupt: &AtomicBool,
) -> Result<PathBuf, GenerateError> {
    let key = run_key(job, renderer);
    let total = job.chunk_count();
    // Which shard each folder is (K, N), from its record.
    let mut which: Vec<Option<(u64, u64)>> = Vec::new();
    for d in shards {
        let id = read_identity(d)
            .map_err(GenerateError::Merge)?
            .ok_or_else(|| {
                GenerateError::Merge(format!(
                    "{} has no record of its spec and settings (.coupler-atlas/atlas.json): it is not a shard folder of this version of coupler-atlas",
                    d.display()
                ))
            })?;
        if id.run_key != key {
            return Err(GenerateError::Merge(format!(
                "{} was made from {} (atlas `{}`) with other settings than this merge's {} (atlas `{}`)",
                d.display(),
                id.source,
                id.name,
                job.source,
                job.spec.name
            )));
        }
        which.push(id.shard.as_deref().and_then(|s| {
            let (k, n) = s.split_once('/')?;
            Some((k.parse().ok()?, n.parse().ok()?))
        }));
    }
    let mut id = identity(job, renderer, &key);
    id.shard = None;
    let stem = stem(job, renderer);
    let names = Names {
        root: &ROOT_FILES,
        stem: &stem,
    };
    let prep = prepare(&job.out, job.force, &id, &names)?;
    if prep.replaced {
        remove_atlas(&job.out, &prep.ledger, &ROOT_FILES)?;
    }
    // Find every chunk before writing anything.
    let mut sources: Vec<Option<&PathBuf>> = Vec::with_capacity(total as usize);
    for c in 0..total {
        if read_chunk(&job.out, c, &key, true, None).is_ok() {
            sources.push(None);
            continue;
        }
        let mut problems = Vec::new();
        let mut found = None;
        for d in shards {
            match read_chunk(d, c, &key, true, None) {
                Ok(_) => {
                    found = Some(d);
                    break;
                }
                Err(ChunkProblem::Damaged(m)) => {
                    return Err(GenerateError::Merge(format!(
                        "chunk {c} in {} is damaged ({m}); run that shard again to redo it",
                        d.display()
                    )));
                }
                Err(p) => problems.push((d, p)),
            }
        }
        let Some(src) = found else {
            let owner = which.iter().flatten().next().map(|&(_, n)| (c % n + 1, n));
            let hint = match owner {
                Some((k, n)) => match which.iter().position(|w| *w == Some((k, n))) {
                    Some(i) => format!(
                        "it belongs to shard {k}/{n}, whose folder {} has {}: run that shard again to finish it",
                        shards[i].display(),
                        problems
                            .iter()
                            .find(|(d, _)| *d == &shards[i])
                            .map(|(_, p)| p.to_string())
                            .unwrap_or_else(|| "no record".into())
                    ),
                    None => format!(
                        "it belongs to shard {k}/{n} (chunks c with c mod {n} = {}), whose folder is not among those given",
                        k - 1
                    ),
                },
                None => "check that every shard finished".into(),
            };
            return Err(GenerateError::Merge(format!(
                "chunk {c} of {total} is in none of the shard folders: {hint}"
            )));
        };
        sources.push(Some(src));
    }
    write_identity(&job.out, &id)?;
    let pages = job.out.join(PAGES_DIR);
    if renderer.page_options().is_some() {
        std::fs::create_dir_all(&pages).map_err(io_err(&pages))?;
    }
    let stopped = || GenerateError::Interrupted {
        done: 0,
        total: total as usize,
        dir: job.out.clone(),
    };
    let mut chunk_files: Vec<Option<Vec<FileEntry>>> = Vec::with_capacity(total as usize);
    for (c, src) in sources.into_iter().enumerate() {
        let c = c as u64;
        let Some(src) = src else {
            chunk_files.push(None);
            continue;
        };
        if interrupt.load(Ordering::Relaxed) {
            return Err(stopped());
        }
        still_there(&job.out)?;
        let header = read_chunk(src, c, &key, false, None).map_err(|p| {
            GenerateError::Merge(format!(
                "chunk {c} changed in {} while merging ({p})",
                src.display()
            ))
        })?;
        prep.ledger
            .add(header.files.iter().map(|f| f.name.as_str()))?;
        for f in &header.files {
            if interrupt.load(Ordering::Relaxed) {
                return Err(stopped());
            }
            copy_verified(src, &job.out, f)?;
        }
        sync_files(&job.out, header.files.iter().map(|f| f.name.as_str()))?;
        let from = chunk_path(src, c);
        let record = open_regular(&from).map_err(io_err(&from))?;
        write_atomically(&chunk_path(&job.out, c), |w| {
            std::io::copy(&mut BufReader::new(record), w).map(|_| ())
        })?;
        // Checked again where it now is (lines and files).
        let header = read_chunk(&job.out, c, &key, true, None).map_err(|p| {
            GenerateError::Merge(format!(
                "chunk {c} of {} did not verify once copied ({p})",
                src.display()
            ))
        })?;
        chunk_files.push(Some(header.files));
    }
    if interrupt.load(Ordering::Relaxed) {
        return Err(stopped());
    }
    let assembly = Assembly::of_records(job, &job.summary(renderer.pages(job)), &key)?;
    assemble(
        job,
        renderer,
        &key,
        chunk_files,
        &prep.ledger,
        assembly,
        None,
    )
    .map(|(p, _)| p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Artifact;
    use std::sync::atomic::AtomicUsize;

    /// Index only, and one atlas file (`atlas.txt`): made alongside the groups or, with
    /// `alongside` false, at the end; counts the calls of each.
    #[derive(Default)]
    struct AtlasFile {
        alongside: bool,
        made_alongside: AtomicUsize,
        made_at_end: AtomicUsize,
    }

    impl AtlasFile {
        fn made(&self, job: &Job) -> Rendered {
            vec![Ok(Artifact {
                name: "atlas.txt".into(),
                bytes: format!("{} groups\n", job.groups().count()).into_bytes(),
            })]
        }
    }

    impl Renderer for AtlasFile {
        fn group_files(&self, _: &Job, _: &Group) -> Option<Vec<String>> {
            Some(Vec::new())
        }
        fn render_group(&self, _: &Job, _: &Group, _: &mut [IndexCurve]) -> Rendered {
            Vec::new()
        }
        fn render_atlas(&self, job: &Job) -> Rendered {
            self.made_at_end.fetch_add(1, Ordering::Relaxed);
            self.made(job)
        }
        fn render_atlas_alongside(&self, job: &Job) -> Option<Rendered> {
            if !self.alongside {
                return None;
            }
            self.made_alongside.fetch_add(1, Ordering::Relaxed);
            Some(self.made(job))
        }
        fn pages(&self, _: &Job) -> u64 {
            0
        }
        fn settings(&self) -> String {
            "atlas file".into()
        }
    }

    /// A unit's files made durable early stay as they were written, and a name with no
    /// file behind it (or a folder) is passed over: nothing is made, nothing fails.
    #[test]
    fn syncing_early_changes_no_file_and_makes_none() {
        let dir = std::env::temp_dir().join(format!("coupler-sync-early-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join(PAGES_DIR)).unwrap();
        std::fs::write(dir.join("pages/a.png"), b"page a").unwrap();
        std::fs::write(dir.join("b.txt"), b"").unwrap();
        let names: Vec<String> = ["pages/a.png", "pages/missing.png", "b.txt", "pages", "x/y"]
            .map(String::from)
            .into();
        sync_early(&dir, &names);
        assert_eq!(std::fs::read(dir.join("pages/a.png")).unwrap(), b"page a");
        assert_eq!(std::fs::read(dir.join("b.txt")).unwrap(), b"");
        assert!(!dir.join("pages/missing.png").exists());
        assert!(!dir.join("x").exists());
        let mut left: Vec<String> = std::fs::read_dir(dir.join(PAGES_DIR))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["a.png"]);
        // A staged file synced early by its temporary name's full path (as the contents
        // are) is put in place as it was written, and no temporary is left.
        let staged = crate::files::stage_artifact(
            &dir,
            &Artifact {
                name: "pages/c.png".into(),
                bytes: b"page c".to_vec(),
            },
        )
        .unwrap();
        let path = staged.staged_path().to_string_lossy().into_owned();
        assert!(Path::new(&path).is_absolute());
        assert_eq!(std::fs::read(&path).unwrap(), b"page c");
        assert!(!dir.join("pages/c.png").exists());
        sync_early(Path::new("/nonexistent"), &[path]);
        staged.sync().unwrap();
        staged.commit().unwrap();
        assert_eq!(std::fs::read(dir.join("pages/c.png")).unwrap(), b"page c");
        let mut left: Vec<String> = std::fs::read_dir(dir.join(PAGES_DIR))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["a.png", "c.png"]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Atlas files made alongside the groups are made once, not again at the end, and
    /// written as those made at the end are: the same bytes, in the manifest, and recorded
    /// in the ledger last (after the chunks' names and the root files'), so that the
    /// ledger, too, is the same for any number of workers and either way of making them.
    #[test]
    fn atlas_files_made_alongside_are_written_as_at_the_end() {
        for base in crate::job::quick_jobs() {
            let mut want: Option<(Vec<u8>, String)> = None;
            for (jobs, alongside) in [(1, false), (1, true), (2, true), (3, true)] {
                let out = std::env::temp_dir().join(format!(
                    "coupler-alongside-{}-{}-{jobs}-{alongside}",
                    base.spec.name,
                    std::process::id()
                ));
                let _ = std::fs::remove_dir_all(&out);
                let mut job = base.clone();
                job.out = out.clone();
                job.jobs = jobs;
                let r = AtlasFile {
                    alongside,
                    ..AtlasFile::default()
                };
                run(&job, &r, &|_| {}, &AtomicBool::new(false)).unwrap();
                let made = (
                    r.made_alongside.load(Ordering::Relaxed),
                    r.made_at_end.load(Ordering::Relaxed),
                );
                assert_eq!(made, if alongside { (1, 0) } else { (0, 1) });
                let bytes = std::fs::read(out.join("atlas.txt")).unwrap();
                assert_eq!(
                    bytes,
                    format!("{} groups\n", job.groups().count()).as_bytes()
                );
                let manifest = read_manifest(&out).unwrap();
                assert!(manifest.files.iter().any(|f| f.name == "atlas.txt"));
                let temporaries: Vec<_> = std::fs::read_dir(&out)
                    .unwrap()
                    .map(|e| e.unwrap().file_name())
                    .filter(|n| n.to_string_lossy().contains(".tmp-"))
                    .collect();
                assert!(temporaries.is_empty(), "{temporaries:?}");
                let ledger = std::fs::read_to_string(out.join(STATE_DIR).join("files")).unwrap();
                assert_eq!(ledger.lines().last(), Some("atlas.txt"), "{ledger}");
                let got = (bytes, ledger);
                match &want {
                    None => want = Some(got),
                    Some(w) => assert!(*w == got, "{jobs} workers, alongside {alongside}"),
                }
                let _ = std::fs::remove_dir_all(&out);
            }
        }
    }

    /// The shared tail is the run's last units, four per worker, counted back from the
    /// last unit of the last chunk it computes (a short last chunk included), and none
    /// with one worker.
    #[test]
    fn the_shared_tail_is_the_last_units_of_the_last_chunk_computed() {
        let g = CHUNK_GROUPS as u64;
        let tail = |last_chunk: u64, units: u64, workers: usize| -> Vec<u64> {
            (0..units.div_ceil(g))
                .flat_map(|c| (0..CHUNK_GROUPS).map(move |k| (c, k)))
                .filter(|&(c, k)| in_shared_tail(c, k, last_chunk, units, workers))
                .map(|(c, k)| c * g + k as u64)
                .collect()
        };
        assert_eq!(tail(5, 175, 2), (167..175).collect::<Vec<_>>());
        assert_eq!(tail(5, 175, 3), (163..175).collect::<Vec<_>>());
        assert_eq!(tail(5, 161, 2), (153..161).collect::<Vec<_>>());
        assert_eq!(tail(0, 3, 2), (0..3).collect::<Vec<_>>());
        // A shard whose last chunk is not the job's: its own last chunk's last units.
        assert_eq!(tail(3, 175, 2), (120..128).collect::<Vec<_>>());
        assert!(tail(5, 175, 1).is_empty());
    }

    fn output(lines: &str, first_id: u64) -> GroupOutput {
        GroupOutput {
            lines: lines.to_string(),
            curves: lines.lines().count() as u64,
            first_id: Some(first_id),
            files: Vec::new(),
            failed: Vec::new(),
            records: Vec::new(),
            shapes: lines.as_bytes().to_vec(),
        }
    }

    /// The units of two chunks computing at once finish in any order; the chunks are
    /// still handed to the record writer in chunk order, each with its units' lines and
    /// shape records in unit order, and a unit's error is returned only when its own
    /// chunk is finished (after the chunks before it are recorded), an interruption
    /// with the count of the chunks recorded.
    #[test]
    fn chunks_are_finished_in_order_whatever_order_their_units_come_in() {
        let (send, outputs) = std::sync::mpsc::channel::<UnitResult>();
        let (records, written) = std::sync::mpsc::sync_channel::<Finished>(8);
        let stop = AtomicBool::new(false);
        let computing = |chunk: u64, units: usize| Admitted::Computing {
            chunk,
            outputs: (0..units).map(|_| None).collect(),
            missing: units,
        };
        let mut queue: VecDeque<Admitted> = VecDeque::new();
        queue.push_back(computing(0, 3));
        queue.push_back(Admitted::Skipped);
        queue.push_back(computing(2, 2));
        queue.push_back(computing(3, 1));
        // Chunk 2's units first, chunk 0's backwards; chunk 3 fails.
        for (c, k, lines, id) in [
            (2, 1, "d\n", 4),
            (0, 2, "c\n", 3),
            (2, 0, "x\ny\n", 2),
            (0, 0, "a\n", 1),
            (0, 1, "b\n", 2),
        ] {
            send.send((c, k, Ok(Ok(output(lines, id))))).unwrap();
        }
        let interrupted = GenerateError::Interrupted {
            done: 0,
            total: 4,
            dir: PathBuf::from("out"),
        };
        send.send((3, 0, Ok(Err(interrupted)))).unwrap();
        let mut done = Done::default();
        for _ in 0..3 {
            assert!(finish_front(&mut queue, &mut done, true, &outputs, &records, &stop).unwrap());
        }
        let err = finish_front(&mut queue, &mut done, true, &outputs, &records, &stop);
        // Interrupted, with the chunks recorded before it counted.
        assert!(
            matches!(
                err,
                Err(GenerateError::Interrupted {
                    done: 2,
                    total: 4,
                    ..
                })
            ),
            "{err:?}"
        );
        assert_eq!((done.computed, done.reused), (2, 0));
        assert_eq!(done.chunk_files.len(), 3);
        assert!(done.chunk_files[1].is_none());
        let got: Vec<(u64, String, u64, u64, Vec<u8>)> = written
            .try_iter()
            .map(|f| match f {
                Finished::Computed(c) => (c.chunk, c.lines, c.curves, c.first_id, c.shapes),
                _ => panic!("only computed chunks"),
            })
            .collect();
        assert_eq!(
            got,
            vec![
                (0, "a\nb\nc\n".to_string(), 3, 1, b"a\nb\nc\n".to_vec()),
                (2, "x\ny\nd\n".to_string(), 3, 2, b"x\ny\nd\n".to_vec()),
            ]
        );
    }
}
