//! `generate`: the atlas job. Enumerates linkages × circuits × coupler points from a
//! spec, computes every curve in parallel (rayon), renders pages through a [`Renderer`],
//! and writes the index and a manifest.
//!
//! Output is deterministic (same spec ⇒ same bytes, whatever the thread count), and a run
//! survives being killed: work is cut into fixed **chunks** of [`CHUNK_GROUPS`] groups in
//! atlas order. Every file is written under a temporary name and renamed when complete;
//! when a chunk's pages are in place, a chunk record (its index lines and its files'
//! sizes and hashes) is written the same way under `DIR/.coupler-atlas/chunks/`. A run
//! skips every chunk whose record is present and whose files verify, so running the same
//! command again resumes. The index is then streamed from the chunk records, so memory
//! stays bounded whatever the atlas size. A shard (`K/N`) computes chunks `c` with
//! `c mod N = K − 1`; [`merge`] gathers shard folders and assembles exactly what one run
//! writes.

use crate::curve::{CrankTable, CurveSummary, PoseTable, transmission_range};
use crate::features::{FeatureExtractor, FeatureTolerances};
use crate::index::{
    IndexCurve, IndexSummary, LinkageLengths, curve_line, write_curve_line, write_index_footer,
    write_index_header,
};
use crate::linkage::{Circuit, CouplerPoint, FourBar};
use crate::spec::{Enumeration, Spec};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::io::{BufRead, Write as _};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

pub mod curves;

/// A validated generate job: the spec, what it enumerates, and where output goes.
#[derive(Clone, Debug)]
pub struct Job {
    /// The spec.
    pub spec: Spec,
    /// Where the spec came from (for messages).
    pub source: String,
    /// Its linkages and skipped combinations.
    pub enumeration: Enumeration,
    /// Output folder.
    pub out: PathBuf,
    /// Worker threads.
    pub jobs: usize,
    /// Which slice of the chunks to compute.
    pub shard: Shard,
    /// Write into a folder that holds files this program did not write.
    pub force: bool,
}

/// A deterministic slice of the work: chunks `c` with `c mod count = index − 1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// 1-based.
    pub index: u32,
    /// Number of shards.
    pub count: u32,
}

impl Shard {
    /// The whole job.
    pub const ALL: Shard = Shard { index: 1, count: 1 };

    /// Whether chunk `c` is this shard's.
    pub fn owns(&self, chunk: usize) -> bool {
        chunk as u64 % self.count as u64 == (self.index - 1) as u64
    }
}

impl std::str::FromStr for Shard {
    type Err = String;
    /// `K/N` with `1 ≤ K ≤ N`.
    fn from_str(s: &str) -> Result<Shard, String> {
        let bad = || format!("`{s}` is not a shard: expected K/N with 1 ≤ K ≤ N, e.g. 2/8");
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (k, n): (u32, u32) = (
            k.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if n == 0 || k == 0 || k > n {
            return Err(bad());
        }
        Ok(Shard { index: k, count: n })
    }
}

/// Groups per chunk: the unit of resumption and sharding. Fixed, so chunk boundaries do
/// not depend on the machine.
pub const CHUNK_GROUPS: usize = 32;

/// The folder (inside the output folder) that holds chunk records.
pub const STATE_DIR: &str = ".coupler-atlas";

/// A finished output file: its name relative to the atlas folder, and its bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct Artifact {
    /// E.g. `pages/hrones-nelson-0001.png`.
    pub name: String,
    /// The complete file.
    pub bytes: Vec<u8>,
}

/// Renders pages: the hook between the curve pipeline and page output. It is called on
/// worker threads, one group at a time, and returns finished files; the pipeline writes
/// them (atomically) and drops them, so memory stays bounded.
pub trait Renderer: Sync {
    /// The pages of one group; may record each curve's place (`curves[i].page`).
    fn render_group(
        &self,
        job: &Job,
        group: &Group,
        curves: &mut [IndexCurve],
    ) -> Result<Vec<Artifact>, GenerateError>;
    /// Files made once per atlas after all groups (e.g. a contents page).
    fn render_atlas(&self, job: &Job) -> Result<Vec<Artifact>, GenerateError>;
    /// Number of pages it makes for `job` (0 for none), for the summary.
    fn pages(&self, job: &Job) -> u64;
    /// Everything about it that changes output bytes (formats, resolution…): part of the
    /// key that decides whether a chunk record from an earlier run can be reused.
    fn settings(&self) -> String;
}

/// No pages: index only.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoPages;

impl Renderer for NoPages {
    fn render_group(
        &self,
        _: &Job,
        _: &Group,
        _: &mut [IndexCurve],
    ) -> Result<Vec<Artifact>, GenerateError> {
        Ok(Vec::new())
    }
    fn render_atlas(&self, _: &Job) -> Result<Vec<Artifact>, GenerateError> {
        Ok(Vec::new())
    }
    fn pages(&self, _: &Job) -> u64 {
        0
    }
    fn settings(&self) -> String {
        "no pages".into()
    }
}

/// One unit of parallel work: a linkage in one circuit with all its coupler points. It
/// shares one pose table (one pose per crank angle) across all its points.
#[derive(Clone, Debug, PartialEq)]
pub struct Group {
    /// The linkage.
    pub linkage: FourBar,
    /// The circuit.
    pub circuit: Circuit,
    /// Its coupler points, in atlas order.
    pub points: Vec<CouplerPoint>,
    /// Id of its first curve.
    pub first_id: u64,
    /// Number of its first page (from 1).
    pub first_page: u64,
}

impl Job {
    /// A job for `spec` writing into `out` with `jobs` threads (at least 1).
    pub fn new(spec: Spec, source: impl Into<String>, out: impl Into<PathBuf>, jobs: usize) -> Job {
        let enumeration = spec.enumerate();
        Job {
            spec,
            source: source.into(),
            enumeration,
            out: out.into(),
            jobs: jobs.max(1),
            shard: Shard::ALL,
            force: false,
        }
    }

    /// The groups in atlas order: linkage (A, then B, then C ascending), circuit, points.
    pub fn groups(&self) -> Vec<Group> {
        let per_page = self.spec.pages.curves_per_page as u64;
        let mut groups = Vec::new();
        let (mut id, mut page) = (0u64, 1u64);
        for l in &self.enumeration.linkages {
            let points = self.spec.points.points(l.coupler);
            for &circuit in &self.spec.circuits {
                let n = points.len() as u64;
                groups.push(Group {
                    linkage: *l,
                    circuit,
                    points: points.clone(),
                    first_id: id,
                    first_page: page,
                });
                id += n;
                page += n.div_ceil(per_page);
            }
        }
        groups
    }

    /// Number of curves.
    pub fn curves(&self) -> u64 {
        self.enumeration.linkages.len() as u64
            * self.spec.circuits.len() as u64
            * self.spec.points.len()
    }

    /// Number of pages (each group starts a new page).
    pub fn pages(&self) -> u64 {
        let per_page = self.spec.pages.curves_per_page as u64;
        self.enumeration.linkages.len() as u64
            * self.spec.circuits.len() as u64
            * self.spec.points.len().div_ceil(per_page)
    }

    /// The counts written into the index.
    pub fn summary(&self, pages: u64) -> IndexSummary {
        IndexSummary {
            combinations: self.spec.combinations(),
            linkages: self.enumeration.linkages.len() as u64,
            skipped: self.enumeration.skipped.clone(),
            curves: self.curves(),
            pages,
        }
    }

    /// A human-readable plan (what `--dry-run` prints).
    pub fn describe(&self) -> String {
        let s = &self.spec;
        let mut t = String::new();
        let _ = writeln!(t, "spec:         {} ({})", s.name, self.source);
        let _ = writeln!(
            t,
            "combinations: {} (A: {} values, B: {}, C: {})",
            s.combinations(),
            s.linkages.coupler.len(),
            s.linkages.rocker.len(),
            s.linkages.ground.len()
        );
        let _ = writeln!(
            t,
            "linkages:     {} strict crank-rockers",
            self.enumeration.linkages.len()
        );
        let skipped: u64 = self.enumeration.skipped.values().sum();
        let detail: Vec<String> = self
            .enumeration
            .skipped
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        let _ = writeln!(
            t,
            "skipped:      {skipped} not strict crank-rockers{}",
            if detail.is_empty() {
                String::new()
            } else {
                format!(" ({})", detail.join(", "))
            }
        );
        let _ = writeln!(
            t,
            "points:       {} per linkage ({} u × {} v)",
            s.points.len(),
            s.points.u.len(),
            s.points.v.len()
        );
        let _ = writeln!(
            t,
            "circuits:     {}",
            s.circuits
                .iter()
                .map(|c| c.name())
                .collect::<Vec<_>>()
                .join(", ")
        );
        let _ = writeln!(t, "curves:       {}", self.curves());
        let _ = writeln!(
            t,
            "samples:      {} per curve (every {}°)",
            (360.0 / s.sampling.crank_step_deg).round(),
            s.sampling.crank_step_deg
        );
        let _ = writeln!(
            t,
            "pages:        {} ({} curves per page, {} {}, {} dpi)",
            self.pages(),
            s.pages.curves_per_page,
            s.pages.size,
            s.pages.orientation,
            s.pages.dpi
        );
        let _ = write!(t, "output:       {}", self.out.display());
        t
    }
}

/// Computes the index records of one group (pure: no I/O), with each curve's features
/// when `features` is given.
pub fn compute_group(
    table: &CrankTable,
    group: &Group,
    features: Option<&FeatureTolerances>,
) -> Result<Vec<IndexCurve>, GenerateError> {
    let mut extractor =
        features.and_then(|t| FeatureExtractor::new(&group.linkage, group.circuit, t));
    let poses = PoseTable::new(&group.linkage, group.circuit, table);
    if !poses.all_valid() {
        return Err(GenerateError::NotAssembled {
            linkage: group.linkage,
            circuit: group.circuit,
        });
    }
    let [tmin, tmax] = transmission_range(&group.linkage).ok_or(GenerateError::NotAssembled {
        linkage: group.linkage,
        circuit: group.circuit,
    })?;
    let transmission_deg = [tmin.to_degrees(), tmax.to_degrees()];
    let class = group.linkage.class();
    let flag_tol = crate::methods::FlagTolerances::DEFAULT;
    let mut curve = Default::default();
    let mut out = Vec::with_capacity(group.points.len());
    for (k, &point) in group.points.iter().enumerate() {
        poses.trace_into(point, &mut curve);
        let summary =
            CurveSummary::of(&curve, table.step()).ok_or(GenerateError::NotAssembled {
                linkage: group.linkage,
                circuit: group.circuit,
            })?;
        out.push(IndexCurve {
            id: group.first_id + k as u64,
            linkage: LinkageLengths::from(&group.linkage),
            point,
            circuit: group.circuit,
            class,
            bbox: summary.bbox,
            transmission_deg,
            speed: summary.speed,
            length: summary.length,
            flags: crate::methods::CurveFlags::for_full_turn(
                &group.linkage,
                point,
                [tmin, tmax],
                &flag_tol,
            ),
            page: None,
            features: extractor.as_mut().map(|x| x.extract(point)),
        });
    }
    Ok(out)
}

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

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// A file or folder could not be written or read.
    #[error("cannot write {}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// A crank-rocker that did not assemble at some angle: an internal invariant failed.
    #[error("internal error: linkage {linkage} ({circuit}) did not assemble over a full turn")]
    NotAssembled {
        /// The linkage.
        linkage: FourBar,
        /// The circuit.
        circuit: Circuit,
    },
    /// The crank step is not usable.
    #[error("crank step {0}° is not usable")]
    BadStep(f64),
    /// The output folder holds files this program did not write.
    #[error("{} holds files that coupler-atlas did not write (e.g. {}); choose an empty or new folder, or pass --force to write beside them (nothing of theirs is deleted)", dir.display(), example)]
    ForeignFolder {
        /// The folder.
        dir: PathBuf,
        /// One foreign entry.
        example: String,
    },
    /// Stopped by the user (SIGINT) between groups.
    #[error("interrupted: {done} of {total} chunks are complete in {}; run the same command again to resume", dir.display())]
    Interrupted {
        /// Complete chunks.
        done: usize,
        /// All chunks of this run.
        total: usize,
        /// The output folder.
        dir: PathBuf,
    },
    /// Shard folders that do not make one atlas.
    #[error("cannot merge: {0}")]
    Merge(String),
    /// Page rendering failed.
    #[error("rendering {what}: {message}")]
    Render {
        /// The page or file.
        what: String,
        /// What went wrong.
        message: String,
    },
}

impl GenerateError {
    /// True for errors in what the user gave (exit code 2), as opposed to failures while
    /// working.
    pub fn is_user_error(&self) -> bool {
        matches!(
            self,
            GenerateError::ForeignFolder { .. } | GenerateError::Merge(_)
        )
    }
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> GenerateError + '_ {
    move |source| GenerateError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// One file recorded in a chunk record or the manifest.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileEntry {
    /// Name relative to the atlas folder.
    pub name: String,
    /// Size in bytes.
    pub bytes: u64,
    /// XXH3-128 of the content, hex.
    pub xxh3: String,
}

impl FileEntry {
    fn of(name: &str, bytes: &[u8]) -> FileEntry {
        FileEntry {
            name: name.to_string(),
            bytes: bytes.len() as u64,
            xxh3: format!("{:032x}", xxhash_rust::xxh3::xxh3_128(bytes)),
        }
    }

    /// The entry of file `name` in `dir`, hashed in blocks (memory stays small whatever
    /// the file's size).
    pub fn of_file(dir: &Path, name: &str) -> std::io::Result<FileEntry> {
        use std::io::Read;
        let mut file = std::fs::File::open(dir.join(name))?;
        let mut hasher = xxhash_rust::xxh3::Xxh3::new();
        let mut buf = vec![0u8; 1 << 20];
        let mut bytes = 0u64;
        loop {
            let n = file.read(&mut buf)?;
            if n == 0 {
                break;
            }
            hasher.update(&buf[..n]);
            bytes += n as u64;
        }
        Ok(FileEntry {
            name: name.to_string(),
            bytes,
            xxh3: format!("{:032x}", hasher.digest128()),
        })
    }

    /// Whether the file is in `dir` with this size and hash.
    pub fn verify(&self, dir: &Path) -> bool {
        match std::fs::metadata(dir.join(&self.name)) {
            Ok(m) if m.len() == self.bytes => {
                FileEntry::of_file(dir, &self.name).is_ok_and(|e| e == *self)
            }
            _ => false,
        }
    }
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

/// Checks that `dir` is new, empty, or this program's output (unless `force`).
pub fn check_out_dir(dir: &Path, force: bool) -> Result<(), GenerateError> {
    if force || !dir.exists() {
        return Ok(());
    }
    let mut entries = std::fs::read_dir(dir).map_err(io_err(dir))?;
    let names: Vec<String> = entries
        .by_ref()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    if names.is_empty() || names.iter().any(|n| n == STATE_DIR) {
        return Ok(());
    }
    let mut names = names;
    names.sort();
    Err(GenerateError::ForeignFolder {
        dir: dir.to_path_buf(),
        example: names[0].clone(),
    })
}

/// A group's index records and the files it wrote.
type GroupOutput = (Vec<IndexCurve>, Vec<FileEntry>);

/// Runs the job (its shard of it): computes the chunks not already complete, on
/// `job.jobs` threads, writing pages as they finish; for a whole job (shard 1/1) then
/// assembles `index.json` and `manifest.json`. `progress` is called with the number of
/// curves finished, from any thread; `interrupt` is polled before each group.
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
                    let mut curves = compute_group(&table, g, features)?;
                    let artifacts = renderer.render_group(job, g, &mut curves)?;
                    let mut files = Vec::with_capacity(artifacts.len());
                    for a in artifacts {
                        files.push(write_artifact(&job.out, &a)?);
                    }
                    progress(curves.len() as u64);
                    Ok((curves, files))
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

fn write_artifact(dir: &Path, a: &Artifact) -> Result<FileEntry, GenerateError> {
    let path = dir.join(&a.name);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(io_err(parent))?;
    }
    write_atomically(&path, |w| w.write_all(&a.bytes))?;
    Ok(FileEntry::of(&a.name, &a.bytes))
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
    for a in renderer.render_atlas(job)? {
        files.push(write_artifact(&job.out, &a)?);
    }
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
    write_manifest(&job.out, key, files)?;
    Ok(index_path)
}

/// Writes `manifest.json` in `dir`: the run key and every file (sorted by name) with its
/// size and XXH3-128 hash.
fn write_manifest(dir: &Path, key: &str, mut files: Vec<FileEntry>) -> Result<(), GenerateError> {
    files.sort_by(|a, b| a.name.cmp(&b.name));
    write_atomically(&dir.join("manifest.json"), |w| {
        write!(
            w,
            "{{\"schema_version\":1,\"run_key\":\"{key}\",\"files\":["
        )?;
        for (i, f) in files.iter().enumerate() {
            w.write_all(if i == 0 { b"\n" } else { b",\n" })?;
            serde_json::to_writer(&mut *w, f)?;
        }
        w.write_all(b"\n]}\n")
    })
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

/// Removes temporary files a killed run of this program left (`.NAME.tmp-PID`, as
/// [`write_atomically`] names them) from the output folder, its `pages/` and its chunk
/// records. Nothing else is touched.
fn remove_stale_temporaries(out: &Path) {
    for dir in [
        out.to_path_buf(),
        out.join("pages"),
        out.join(STATE_DIR).join("chunks"),
    ] {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let ours = name.starts_with('.')
                && name.rsplit_once(".tmp-").is_some_and(|(_, pid)| {
                    !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit())
                });
            if ours && e.file_type().is_ok_and(|t| t.is_file()) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// Writes a file under a temporary name in the same folder and renames it into place
/// when complete, so no partial file ever stands under the final name.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), GenerateError> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(file);
        write(&mut w)?;
        w.flush()?;
        drop(w.into_inner().map_err(|e| e.into_error())?);
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io_err(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_cover_ids_and_pages_in_order() {
        let spec = Spec::parse(include_str!("../../atlas-spec/quick.toml"), "quick").unwrap();
        let job = Job::new(spec, "quick", "unused", 1);
        let groups = job.groups();
        let mut id = 0;
        for g in &groups {
            assert_eq!(g.first_id, id);
            id += g.points.len() as u64;
        }
        assert_eq!(id, job.curves());
        let last = groups.last().unwrap();
        assert_eq!(
            last.first_page - 1 + (last.points.len() as u64).div_ceil(6),
            job.pages()
        );
    }

    #[test]
    fn group_measures_are_finite_and_plausible() {
        let table = CrankTable::new(1.0).unwrap();
        let l = FourBar::new(3.0, 3.0, 3.0).unwrap();
        let g = Group {
            linkage: l,
            circuit: Circuit::Open,
            points: vec![CouplerPoint::new(0.0, 0.0), CouplerPoint::new(3.0, 0.0)],
            first_id: 5,
            first_page: 1,
        };
        let c = compute_group(&table, &g, None).unwrap();
        assert_eq!(c[0].id, 5);
        // Point (0, 0) is the crank pin: the unit circle.
        assert!((c[0].length - std::f64::consts::TAU).abs() < 1e-12);
        // Point (A, 0) is the rocker pin: an arc of radius B about O4, inside x ∈ [0, 6].
        assert!(c[1].bbox[0] >= 0.0 - 1e-12 && c[1].bbox[2] <= 6.0 + 1e-12);
        let [lo, hi] = c[0].transmission_deg;
        assert!(0.0 < lo && lo < hi && hi < 180.0);
    }
}
