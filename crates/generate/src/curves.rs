//! `generate` for a full-curve page set (a spec of `[[curve]]` entries, e.g.
//! `atlas-spec/classics.toml`): each named curve traced in full across its toggles,
//! measured, and drawn on a page of its own; then `curves.json` (the measures and where
//! each curve is drawn) and `manifest.json`.
//!
//! The same guarantees as the grid pipeline: the output folder is refused if it holds
//! files this program did not write; every file is written under a temporary name and
//! renamed into place, so a run stopped at any point leaves only complete files; output is
//! byte-identical for any number of threads. A set is small (one page per curve), so it
//! is recomputed whole on every run rather than resumed.

use crate::error::io_err;
use crate::files::{PAGES_DIR, write_manifest};
use crate::run::{prepare, verifies_complete, write_rendered};
use crate::state::{Identity, Names, PageFlags, prune, remove_atlas, write_identity};
use crate::{
    FileEntry, GenerateError, PageFailure, PageOptions, PageRenderer, Rendered, write_atomically,
};
use coupler_features::{ClassicCurve, NamedCurve, StraightMeasure};
use coupler_index::PageRef;
use coupler_kinematics::{CouplerPoint, InputRange, Linkage, LinkageClass, Mechanism};
use coupler_layout::ClassicPage;
use coupler_specs::{CurveList, Sampling};
use rayon::prelude::*;
use serde::Serialize;
use std::path::PathBuf;

/// Schema version of `curves.json` (documented in `docs/index-schema.md`).
pub const CURVES_SCHEMA_VERSION: u32 = 1;

/// A full-curve page-set job.
#[derive(Clone, Debug)]
pub struct CurveJob {
    /// The parsed set.
    pub list: CurveList,
    /// Where the spec came from.
    pub source: String,
    /// Output folder.
    pub out: PathBuf,
    /// Worker threads (at least 1).
    pub jobs: usize,
    /// Write into a folder that holds files this program did not write.
    pub force: bool,
}

/// What a run wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct CurveRunReport {
    /// Curves measured.
    pub curves: usize,
    /// Pages written (0 with no pages).
    pub pages: usize,
    /// `curves.json`.
    pub record_path: PathBuf,
    /// The set was complete: every file verified, nothing written.
    pub verified: bool,
    /// Files an earlier run wrote that this set no longer has (e.g. pages of curves no
    /// longer listed), removed.
    pub removed_files: usize,
}

/// Files of a page set in its folder, in the order an earlier set is taken out.
const ROOT_FILES: [&str; 2] = ["manifest.json", "curves.json"];

/// One curve's record in `curves.json`.
#[derive(Clone, Debug, Serialize)]
pub struct CurveRecord {
    /// Position in the spec, from 0.
    pub id: usize,
    /// Name.
    pub name: String,
    /// Dimensions (input = 1): a four-bar's `{coupler, rocker, ground}`, a geared
    /// five-bar's `{l1, l3, l4, l5, ratio, phase}` (as in index.json).
    pub linkage: Linkage,
    /// Coupler point.
    pub point: CouplerPoint,
    /// Barker's class of a four-bar, Ting's of a geared five-bar.
    pub class: LinkageClass,
    /// `"full"`, `"open"` or `"crossed"`.
    pub trace: String,
    /// The input's range: a full turn, or rocking intervals between toggles.
    pub input: InputRange,
    /// Number of branches traced.
    pub branches: usize,
    /// Samples per branch (at `sampling.crank_step_deg`, plus the toggles).
    pub samples: Vec<usize>,
    /// Largest distance between a branch's first and last sample (0 when every branch
    /// closes exactly).
    pub closure: f64,
    /// The longest straight run at ε_S ≤ 1 %, 0.1 %, 0.01 % (`null` where none).
    pub straight: Vec<Option<StraightMeasure>>,
    /// Page file and the curve's box on it, in pixels (absent without pages).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub page: Option<PageRef>,
}

#[derive(Serialize)]
struct CurvesFile<'a> {
    schema_version: u32,
    kind: &'static str,
    generator: String,
    atlas: Atlas<'a>,
    sampling: &'a Sampling,
    curves: &'a [CurveRecord],
}

#[derive(Serialize)]
struct Atlas<'a> {
    name: &'a str,
    title: &'a str,
    source: &'a str,
}

fn record(id: usize, c: &NamedCurve, m: &ClassicCurve) -> CurveRecord {
    let closure = m
        .branches
        .iter()
        .filter_map(|b| Some((b.samples.first()?.point - b.samples.last()?.point).norm()))
        .fold(0.0, f64::max);
    CurveRecord {
        id,
        name: c.name.clone(),
        linkage: c.linkage,
        point: c.point,
        class: c.linkage.class(),
        trace: c.trace.name().into(),
        input: m.range.clone(),
        branches: m.branches.len(),
        samples: m.branches.iter().map(|b| b.samples.len()).collect(),
        closure,
        straight: m.straight.clone(),
        page: None,
    }
}

/// The key written in the manifest: program version, spec and page settings.
fn run_key(job: &CurveJob, pages: Option<&PageOptions>) -> String {
    let text = format!(
        "coupler-atlas {} curves\n{}\n{:?}",
        env!("CARGO_PKG_VERSION"),
        list_key_text(&job.list),
        pages
    );
    format!("{:032x}", xxhash_rust::xxh3::xxh3_128(text.as_bytes()))
}

/// The page set as the run key hashes it: `Debug` of the list as versions before geared
/// five-bar entries printed it (a four-bar's linkage as `FourBar { … }`, not wrapped in a
/// `Linkage`), so their complete page sets are not redone; a geared entry prints its
/// `Linkage`.
fn list_key_text(list: &CurveList) -> String {
    #[derive(Debug)]
    #[allow(dead_code)]
    struct CurveList<'a> {
        name: &'a String,
        title: &'a String,
        sampling: &'a Sampling,
        pages: &'a coupler_specs::PageSettings,
        curves: Vec<NamedCurve<'a>>,
    }
    #[derive(Debug)]
    #[allow(dead_code)]
    struct NamedCurve<'a> {
        name: &'a String,
        linkage: &'a dyn std::fmt::Debug,
        point: &'a CouplerPoint,
        trace: &'a coupler_features::TraceMode,
    }
    let shadow = CurveList {
        name: &list.name,
        title: &list.title,
        sampling: &list.sampling,
        pages: &list.pages,
        curves: list
            .curves
            .iter()
            .map(|c| NamedCurve {
                name: &c.name,
                linkage: match &c.linkage {
                    Linkage::FourBar(l) => l,
                    l => l,
                },
                point: &c.point,
                trace: &c.trace,
            })
            .collect(),
    };
    format!("{shadow:?}")
}

/// Runs the job: traces and measures every curve (in parallel), renders its page when
/// `pages` is given, then writes the pages, `curves.json` and `manifest.json` (each
/// atomically, so a run stopped at any point leaves only complete files). `progress` is
/// called once per finished curve.
///
/// A page that cannot be made or written does not stop the run: every other page is
/// written, then the run ends with [`GenerateError::PagesFailed`] naming every failed
/// page, and writes no `curves.json` or manifest (the set is incomplete).
pub fn run(
    job: &CurveJob,
    pages: Option<&PageRenderer>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<CurveRunReport, GenerateError> {
    let key = run_key(job, pages.map(|r| &r.opts));
    let mut id = Identity::new("page set", &job.list.name, &job.source, &key);
    id.pages = pages.map(|r| PageFlags::of(&r.opts));
    let stem = pages
        .map(|r| r.opts.stem.clone())
        .unwrap_or_else(|| job.list.name.clone());
    let names = Names {
        root: &ROOT_FILES,
        stem: &stem,
    };
    let prep = prepare(&job.out, job.force, &id, &names)?;
    let record_path = job.out.join("curves.json");
    if !prep.replaced && verifies_complete(&job.out, &key, "curves.json") {
        // A complete set of these settings: verified, nothing rewritten.
        let m = crate::files::read_manifest(&job.out);
        let n_pages = m
            .map(|m| {
                let mut pages: Vec<&str> = m
                    .files
                    .iter()
                    .filter_map(|f| f.name.strip_prefix("pages/"))
                    .filter_map(|n| n.rsplit_once('.').map(|(stem, _)| stem))
                    .collect();
                pages.sort_unstable();
                pages.dedup();
                pages.len()
            })
            .unwrap_or(0);
        return Ok(CurveRunReport {
            curves: job.list.curves.len(),
            pages: n_pages,
            record_path,
            verified: true,
            removed_files: 0,
        });
    }
    if prep.replaced {
        remove_atlas(&job.out, &prep.ledger, &ROOT_FILES)?;
    }
    write_identity(&job.out, &id)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(job.jobs.max(1))
        .build()
        .map_err(|e| GenerateError::Io {
            path: job.out.clone(),
            source: std::io::Error::other(e),
        })?;
    let step = job.list.sampling.crank_step_deg;
    let count = job.list.curves.len();
    let done: Vec<(CurveRecord, Rendered)> = pool.install(|| {
        job.list
            .curves
            .par_iter()
            .enumerate()
            .map(|(i, c)| {
                let measured = ClassicCurve::compute(c, step);
                let mut rec = record(i, c, &measured);
                let mut files: Rendered = Vec::new();
                if let Some(renderer) = pages {
                    let page = ClassicPage {
                        curve: c.clone(),
                        measured,
                        page_number: i + 1,
                        page_count: count,
                        step_deg: step,
                    };
                    match renderer.classic_page(&page) {
                        Ok((artifacts, place)) => {
                            rec.page = place;
                            files.extend(artifacts.into_iter().map(Ok));
                        }
                        Err(f) => files.push(Err(f)),
                    }
                }
                progress(1);
                (rec, files)
            })
            .collect()
    });
    let mut records = Vec::with_capacity(count);
    let mut entries: Vec<FileEntry> = Vec::new();
    let mut failed: Vec<PageFailure> = Vec::new();
    let mut n_pages = 0;
    if pages.is_some() {
        let pages_dir = job.out.join(PAGES_DIR);
        std::fs::create_dir_all(&pages_dir).map_err(io_err(&pages_dir))?;
    }
    for (rec, rendered) in done {
        if !rendered.is_empty() {
            n_pages += 1;
        }
        let (files, page_failed) = write_rendered(&job.out, rendered, &prep.ledger);
        entries.extend(files);
        failed.extend(page_failed);
        records.push(rec);
    }
    if !failed.is_empty() {
        return Err(GenerateError::PagesFailed {
            failed,
            dir: job.out.clone(),
        });
    }
    let doc = CurvesFile {
        schema_version: CURVES_SCHEMA_VERSION,
        kind: "full-curve page set",
        generator: format!("coupler-atlas {}", env!("CARGO_PKG_VERSION")),
        atlas: Atlas {
            name: &job.list.name,
            title: &job.list.title,
            source: &job.source,
        },
        sampling: &job.list.sampling,
        curves: &records,
    };
    crate::files::sync_files(&job.out, entries.iter().map(|f| f.name.as_str()))?;
    prep.ledger.add(ROOT_FILES)?;
    write_atomically(&record_path, |w| {
        serde_json::to_writer_pretty(&mut *w, &doc)?;
        std::io::Write::write_all(w, b"\n")
    })?;
    entries.push(FileEntry::of_file(&job.out, "curves.json").map_err(io_err(&record_path))?);
    write_manifest(&job.out, &key, entries.clone())?;
    let mut keep: Vec<String> = entries.into_iter().map(|f| f.name).collect();
    keep.push("manifest.json".into());
    let removed_files = prune(&job.out, &prep.ledger, &keep)?;
    Ok(CurveRunReport {
        curves: records.len(),
        pages: n_pages,
        record_path,
        verified: false,
        removed_files,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The run keys of the shipped page set and of the quick atlas (default page
    /// settings) are those earlier versions wrote into `manifest.json`: a key that changes
    /// needlessly makes a run redo a complete atlas.
    #[test]
    fn run_keys_are_stable() {
        let text = include_str!("../../../atlas-spec/classics.toml");
        let list = CurveList::parse(text, "classics").unwrap();
        let opts = PageOptions::from_settings(&list.name, &list.sampling, &list.pages).unwrap();
        let job = CurveJob {
            list,
            source: "classics".into(),
            out: PathBuf::from("unused"),
            jobs: 1,
            force: false,
        };
        assert_eq!(
            run_key(&job, Some(&opts)),
            // Changed deliberately when the Evans crank-rocker joined the set (issue 12):
            // a different set of curves must redo the atlas; and again when the page
            // set's default orientation became `auto` (issue 16): its pages changed.
            "6a0a93a51d038642ca8a699dd2865361"
        );
        let spec =
            coupler_specs::Spec::parse(include_str!("../../../atlas-spec/quick.toml"), "quick")
                .unwrap();
        let mut opts = PageOptions::from_spec(&spec).unwrap();
        // As `generate atlas-spec/quick.toml --format png,svg` writes it.
        opts.formats = vec![
            coupler_render::PageFormat::Png,
            coupler_render::PageFormat::Svg,
        ];
        let job = crate::Job::new(spec, "quick", "unused", 1);
        assert_eq!(
            crate::run_key(&job, &crate::PageRenderer::new(opts)),
            "ab1f908ebfd263eff5c718a1fa27eb15"
        );
    }
}
