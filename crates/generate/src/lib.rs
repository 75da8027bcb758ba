//! # coupler-generate
//!
//! The atlas job: enumerates linkages × circuits × coupler points from a spec, computes
//! every curve in parallel (rayon), renders pages through one trait ([`Renderer`]), and
//! writes the index and a manifest; full-curve page sets likewise.
//!
//! Output is deterministic (same spec ⇒ same bytes, whatever the thread count), and a run
//! survives being killed: work is cut into fixed **chunks** of [`CHUNK_GROUPS`] groups in
//! atlas order. Every file is written under a temporary name and renamed when complete;
//! when a chunk's pages are in place, a chunk record (its index lines and its files'
//! sizes and hashes) is written the same way under `DIR/.coupler-atlas/chunks/`. A run
//! skips every chunk whose record is present and whose files verify, so running the same
//! command again resumes. The index (with its search columns and shape sidecar) is
//! written as the chunks come, one chunk at a time, so memory stays bounded whatever the
//! atlas size. A shard (`K/N`) computes chunks `c` with
//! `c mod N = K − 1`; [`merge`] gathers shard folders and assembles exactly what one run
//! writes.

mod assembly;
mod chunk;
mod curves;
mod error;
mod files;
mod job;
mod lock;
mod measure;
mod pages;
mod plan;
mod run;
mod shapes;
mod state;

pub use chunk::{CHUNK_FORMAT, CHUNK_GROUPS};
pub use curves::{
    CURVES_SCHEMA_VERSION, CurveJob, CurveRecord, CurveRunReport, run as run_curve_set,
};
pub use error::GenerateError;
pub use files::{FileEntry, PAGES_DIR, STATE_DIR, check_name, check_out_dir, write_atomically};
pub use job::{
    Artifact, Group, Job, NoPages, PageFailure, Rendered, Renderer, Shard, UNIT_POINTS,
    compute_group,
};
pub use lock::FolderLock;
pub use measure::{machine, median, thread_cpu_seconds};
pub use pages::{
    BufferPool, PageError, PageJob, PageOptions, PageRenderer, PageSource, PageTimings,
    RenderedPage, render_classic, render_contents, render_page,
};
pub use plan::{DiskEstimate, Limits, MAX_CURVES, Plan, human_bytes};
pub use run::{RunReport, merge, run, run_key};
pub use shapes::atlas_curves;
pub use state::{Identity, PageFlags, read_identity};
