//! Why a run fails.

use coupler_kinematics::{Circuit, Linkage};
use std::path::{Path, PathBuf};

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
        linkage: Linkage,
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
    /// The output folder (or its `.coupler-atlas/` record) was removed while the run was
    /// writing it.
    #[error("{} was removed while this run was writing it (its `.coupler-atlas/chunks/` is gone), so the run stopped: nothing more is written there. Run the same command again to start afresh; if some of the atlas's files are still there, they can no longer be told from the user's: remove the folder first", dir.display())]
    FolderRemoved {
        /// The output folder.
        dir: PathBuf,
    },
    /// Shard folders that do not make one atlas.
    #[error("cannot merge: {0}")]
    Merge(String),
    /// A `pages/` or `.coupler-atlas/` that is not a real folder (e.g. a symbolic link).
    #[error("{} is not a folder (a symbolic link or a file); coupler-atlas writes and cleans up only inside the output folder: replace it with a folder, or choose another --out", path.display())]
    NotAFolder {
        /// The path.
        path: PathBuf,
    },
    /// Another run is writing into the output folder (it holds the folder's lock).
    #[error("{} is in use by another coupler-atlas run ({holder}); wait for it to finish, or stop it, then run again", dir.display())]
    Busy {
        /// The folder.
        dir: PathBuf,
        /// Who holds the lock: process id, start time and command, as it recorded them.
        holder: String,
    },
    /// A file this atlas would write is already there and this program did not write it.
    #[error("{} exists and was not written by coupler-atlas, so it is left alone: move it away or choose another --out ({more})", path.display())]
    UserFile {
        /// The file.
        path: PathBuf,
        /// How many such files there are.
        more: String,
    },
    /// The output folder holds another atlas.
    #[error("{} holds the atlas `{existing}` ({source_name}); writing `{new}` there would replace it: choose another --out, or delete that atlas first", dir.display())]
    OtherAtlas {
        /// The folder.
        dir: PathBuf,
        /// The atlas in it.
        existing: String,
        /// Where that atlas's spec came from.
        source_name: String,
        /// The atlas of this run.
        new: String,
    },
    /// The plan is over a limit that no flag lifts.
    #[error("{0}")]
    Plan(String),
    /// Pages could not be made or written; every other page was (no index or manifest
    /// is written for an incomplete atlas). The same command again redoes what is missing.
    #[error("{} failed (every other page is written; once the cause is fixed, run the same command again to redo only what is missing):{}", pages(failed.len()), failed.iter().map(|f| format!("\n  {}: {}", f.page, f.message)).collect::<String>())]
    PagesFailed {
        /// Every failed page.
        failed: Vec<crate::PageFailure>,
        /// The output folder.
        dir: PathBuf,
    },
}

impl GenerateError {
    /// True for errors in what the user gave (exit code 2), as opposed to failures while
    /// working.
    pub fn is_user_error(&self) -> bool {
        matches!(
            self,
            GenerateError::ForeignFolder { .. }
                | GenerateError::Merge(_)
                | GenerateError::NotAFolder { .. }
                | GenerateError::UserFile { .. }
                | GenerateError::OtherAtlas { .. }
                | GenerateError::Plan(_)
        )
    }
}

pub(crate) fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> GenerateError + '_ {
    move |source| GenerateError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// "1 page" or "N pages".
fn pages(n: usize) -> String {
    if n == 1 {
        "1 page".into()
    } else {
        format!("{n} pages")
    }
}
