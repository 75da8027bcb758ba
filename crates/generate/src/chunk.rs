//! Chunk records: the unit of resumption and sharding. A run cuts its work into fixed
//! chunks of [`CHUNK_GROUPS`] units; when a chunk's pages are written, its record
//! (`.coupler-atlas/chunks/NNNNNN.jsonl`: a header line with the files it wrote, then its
//! curve lines as in the index) is written last, so a killed run resumes at the first
//! chunk without a valid record, and [`read_chunk`] checks a record before it is used.

use crate::files::{check_name, open_regular};
use crate::{FileEntry, GenerateError, STATE_DIR, write_atomically};
use coupler_index::{MAX_INDEX_LINE, read_line_bounded};
use serde::{Deserialize, Serialize};
use std::io::{BufReader, Write as _};
use std::path::{Path, PathBuf};

/// Units per chunk: the unit of resumption and sharding. Fixed, so chunk boundaries do
/// not depend on the machine.
pub const CHUNK_GROUPS: usize = 32;

/// Version of the chunk record format: 2 added the curve lines' size and hash, and the
/// first curve id. Records of other versions are recomputed.
pub const CHUNK_FORMAT: u32 = 2;

/// Longest header line of a chunk record read back.
const MAX_HEADER_LINE: usize = 64 << 20;

/// First line of a chunk record; its curve lines follow, one per line, as in the index.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct ChunkHeader {
    format: u32,
    run_key: String,
    chunk: u64,
    pub(crate) curves: u64,
    first_id: u64,
    lines_bytes: u64,
    lines_xxh3: String,
    pub(crate) files: Vec<FileEntry>,
}

/// Why a chunk record cannot be used.
#[derive(Debug)]
pub(crate) enum ChunkProblem {
    /// No record (or not readable).
    Missing,
    /// Of another run key, chunk number or format: another spec, settings or version.
    Other,
    /// The record is damaged (what is wrong).
    Damaged(String),
    /// A file it lists is missing or changed.
    FileChanged(String),
}

impl std::fmt::Display for ChunkProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ChunkProblem::Missing => write!(f, "no record"),
            ChunkProblem::Other => write!(f, "a record of another spec, settings or version"),
            ChunkProblem::Damaged(m) => write!(f, "a damaged record ({m})"),
            ChunkProblem::FileChanged(n) => write!(f, "its file {n} is missing or changed"),
        }
    }
}

pub(crate) fn chunk_path(dir: &Path, chunk: u64) -> PathBuf {
    dir.join(STATE_DIR)
        .join("chunks")
        .join(format!("{chunk:06}.jsonl"))
}

/// Receives the curve lines of a chunk record as they are read.
type LineSink<'a> = &'a mut dyn FnMut(&str) -> std::io::Result<()>;

/// Reads chunk record `chunk` of `dir` and checks everything in it: format, run key and
/// chunk number; every file name a plain name inside the folder; the curve lines
/// complete, numbered from the header's first id, and equal to their recorded size and
/// hash; with `verify_files`, every file it lists present with its size and hash. Each
/// curve line is passed to `sink` as it is read (an error there stops the read), so a
/// caller that writes them must discard what it wrote unless this returns `Ok`.
pub(crate) fn read_chunk(
    dir: &Path,
    chunk: u64,
    key: &str,
    verify_files: bool,
    mut sink: Option<LineSink<'_>>,
) -> Result<ChunkHeader, ChunkProblem> {
    let path = chunk_path(dir, chunk);
    let file = open_regular(&path).map_err(|_| ChunkProblem::Missing)?;
    let mut r = BufReader::with_capacity(1 << 16, file);
    let mut line = Vec::new();
    let damaged = |m: &str| ChunkProblem::Damaged(m.to_string());
    read_line_bounded(&mut r, &mut line, MAX_HEADER_LINE)
        .map_err(|e| ChunkProblem::Damaged(e.to_string()))?;
    #[derive(Deserialize)]
    struct Version {
        format: u32,
    }
    let version: Version = serde_json::from_slice(&line).map_err(|_| damaged("header"))?;
    if version.format != CHUNK_FORMAT {
        return Err(ChunkProblem::Other);
    }
    let header: ChunkHeader = serde_json::from_slice(&line).map_err(|_| damaged("header"))?;
    if header.run_key != key || header.chunk != chunk {
        return Err(ChunkProblem::Other);
    }
    for f in &header.files {
        check_name(&f.name).map_err(|m| ChunkProblem::Damaged(format!("it lists {m}")))?;
    }
    let mut hasher = xxhash_rust::xxh3::Xxh3::new();
    let (mut bytes, mut count) = (0u64, 0u64);
    loop {
        let n = read_line_bounded(&mut r, &mut line, MAX_INDEX_LINE)
            .map_err(|e| ChunkProblem::Damaged(e.to_string()))?;
        if n == 0 {
            break;
        }
        hasher.update(&line);
        bytes += n as u64;
        if count >= header.curves || bytes > header.lines_bytes {
            return Err(damaged("more curve lines than recorded"));
        }
        let text = std::str::from_utf8(&line).map_err(|_| damaged("a curve line is not UTF-8"))?;
        let text = text
            .strip_suffix('\n')
            .ok_or_else(|| damaged("the last curve line is cut"))?;
        let id = header.first_id + count;
        let numbered = text
            .strip_prefix("{\"id\":")
            .and_then(|t| t.strip_prefix(id.to_string().as_str()))
            .is_some_and(|t| t.starts_with(','));
        if !numbered || !text.ends_with('}') {
            return Err(ChunkProblem::Damaged(format!(
                "curve line {} is not the record of curve {id}",
                count + 1
            )));
        }
        if let Some(s) = sink.as_mut() {
            s(text).map_err(|e| ChunkProblem::Damaged(e.to_string()))?;
        }
        count += 1;
    }
    if count != header.curves
        || bytes != header.lines_bytes
        || format!("{:032x}", hasher.digest128()) != header.lines_xxh3
    {
        return Err(damaged(
            "its curve lines do not match their recorded size and hash",
        ));
    }
    if verify_files {
        if let Some(f) = header.files.iter().find(|f| !f.verify(dir)) {
            return Err(ChunkProblem::FileChanged(f.name.clone()));
        }
    }
    Ok(header)
}

/// Writes the record of chunk `chunk` of `dir`: its header (the run key, the curves' count,
/// first id, size and hash of `lines`, the files it lists), then `lines` (curve lines, each
/// ending in a newline, in id order). The caller makes the files it lists durable first.
pub(crate) fn write_record(
    dir: &Path,
    key: &str,
    chunk: u64,
    curves: u64,
    first_id: u64,
    lines: &str,
    files: &[FileEntry],
) -> Result<(), GenerateError> {
    let header = ChunkHeader {
        format: CHUNK_FORMAT,
        run_key: key.to_string(),
        chunk,
        curves,
        first_id,
        lines_bytes: lines.len() as u64,
        lines_xxh3: format!("{:032x}", xxhash_rust::xxh3::xxh3_128(lines.as_bytes())),
        files: files.to_vec(),
    };
    write_atomically(&chunk_path(dir, chunk), |w| {
        serde_json::to_writer(&mut *w, &header)?;
        w.write_all(b"\n")?;
        w.write_all(lines.as_bytes())
    })
}
