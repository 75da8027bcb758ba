//! `generate`: the atlas job. Enumerates linkages × circuits × coupler points from a
//! spec, computes every curve in parallel (rayon), and writes the index. Output is
//! deterministic: work is split into groups in atlas order and results are collected in
//! that order, whatever the thread count.

use crate::curve::{CrankTable, CurveSummary, PoseTable, transmission_range};
use crate::index::{IndexCurve, IndexSummary, LinkageLengths, PageRef, write_index};
use crate::layout::ContentsEntry;
use crate::linkage::{Circuit, CouplerPoint, FourBar};
use crate::render::pages::{
    BufferPool, PageError, PageOptions, PageTimings, render_contents, render_linkage_pages,
};
use crate::spec::{Enumeration, Spec};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

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
    /// Page rendering into `out/pages/` (`None`: index only).
    pub pages: Option<PageOptions>,
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

/// What a run did.
#[derive(Clone, Debug, PartialEq)]
pub struct RunReport {
    /// Counts, as written in the index.
    pub summary: IndexSummary,
    /// The index file written.
    pub index_path: PathBuf,
    /// Seconds spent per page phase `[compute, layout, draw, encode, write]` summed over
    /// workers, and pages rendered (contents excluded), when pages were rendered.
    pub page_seconds: Option<([f64; 5], u64)>,
}

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// A file or folder could not be written.
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
    /// A page could not be rendered or written.
    #[error(transparent)]
    Page(#[from] PageError),
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
            pages: None,
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

/// Computes the index records of one group (pure: no I/O).
pub fn compute_group(table: &CrankTable, group: &Group) -> Result<Vec<IndexCurve>, GenerateError> {
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
            class: group.linkage.class(),
            bbox: summary.bbox,
            transmission_deg,
            speed: summary.speed,
            length: summary.length,
            page: None,
        });
    }
    Ok(out)
}

/// Runs the job: computes every group on `job.jobs` threads, then writes
/// `out/index.json` atomically (temporary name, then rename). `progress` is called with
/// the number of curves finished after each group, from any worker thread.
pub fn run(job: &Job, progress: &(dyn Fn(u64) + Sync)) -> Result<RunReport, GenerateError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| GenerateError::Io { path, source }
    };
    std::fs::create_dir_all(&job.out).map_err(io(&job.out))?;
    let table = CrankTable::new(job.spec.sampling.crank_step_deg)
        .ok_or(GenerateError::BadStep(job.spec.sampling.crank_step_deg))?;
    let groups = job.groups();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(job.jobs)
        .build()
        .map_err(|e| GenerateError::Io {
            path: job.out.clone(),
            source: std::io::Error::other(e),
        })?;
    let pages_dir = job.out.join("pages");
    if job.pages.is_some() {
        std::fs::create_dir_all(&pages_dir).map_err(io(&pages_dir))?;
    }
    let buffers = BufferPool::new();
    let timings = PageTimings::default();
    let page_count = job.pages();
    let results: Result<Vec<Vec<IndexCurve>>, GenerateError> = pool.install(|| {
        groups
            .par_iter()
            .map(|g| {
                let mut curves = compute_group(&table, g)?;
                if let Some(opts) = &job.pages {
                    let placed = render_linkage_pages(
                        opts,
                        &pages_dir,
                        &buffers,
                        &timings,
                        g.linkage,
                        g.circuit,
                        &g.points,
                        g.first_page,
                        page_count,
                    )?;
                    for (c, p) in curves.iter_mut().zip(placed) {
                        c.page = Some(PageRef {
                            file: p.file,
                            bbox_px: p.bbox_px.map(f64::from),
                        });
                    }
                }
                progress(curves.len() as u64);
                Ok(curves)
            })
            .collect()
    });
    let curves: Vec<IndexCurve> = results?.into_iter().flatten().collect();
    let mut page_seconds = None;
    if let Some(opts) = &job.pages {
        let per = opts.setup.curves_per_page.max(1) as u64;
        let entries: Vec<ContentsEntry> = groups
            .iter()
            .map(|g| ContentsEntry {
                linkage: g.linkage,
                circuit: g.circuit,
                curves: g.points.len(),
                first_page: g.first_page as usize,
                last_page: (g.first_page + (g.points.len() as u64).div_ceil(per)).saturating_sub(1)
                    as usize,
            })
            .collect();
        render_contents(opts, &pages_dir, &buffers, &entries)?;
        page_seconds = Some(timings.seconds());
    }
    let summary = job.summary(if job.pages.is_some() { page_count } else { 0 });
    let index_path = job.out.join("index.json");
    write_atomically(&index_path, |w| {
        write_index(w, &job.spec, &summary, &curves)
    })?;
    Ok(RunReport {
        summary,
        index_path,
        page_seconds,
    })
}

/// Writes a file under a temporary name in the same folder and renames it into place
/// when complete, so no partial file ever stands under the final name.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), GenerateError> {
    let err = |source| GenerateError::Io {
        path: path.to_path_buf(),
        source,
    };
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(file);
        write(&mut w)?;
        w.flush()?;
        w.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_cover_ids_and_pages_in_order() {
        let spec = Spec::parse(include_str!("../atlas-spec/quick.toml"), "quick").unwrap();
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
        let c = compute_group(&table, &g).unwrap();
        assert_eq!(c[0].id, 5);
        // Point (0, 0) is the crank pin: the unit circle.
        assert!((c[0].length - std::f64::consts::TAU).abs() < 1e-12);
        // Point (A, 0) is the rocker pin: an arc of radius B about O4, inside x ∈ [0, 6].
        assert!(c[1].bbox[0] >= 0.0 - 1e-12 && c[1].bbox[2] <= 6.0 + 1e-12);
        let [lo, hi] = c[0].transmission_deg;
        assert!(0.0 < lo && lo < hi && hi < 180.0);
    }
}
