//! The job: a validated spec with what it enumerates, split into groups (one linkage in
//! one circuit with all its coupler points, sharing one pose table), and the pure
//! computation of a group's index records.

use crate::GenerateError;
use coupler_features::{FeatureExtractor, FeatureTolerances, FlagTolerances, curve_flags};
use coupler_index::{IndexCurve, IndexSummary};
use coupler_kinematics::{
    Circuit, CouplerPoint, CrankTable, CurveSummary, DashPattern, Linkage, Mechanism,
};
use coupler_specs::{Enumeration, Spec};
use std::fmt::Write as _;
use std::path::PathBuf;

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

/// A finished output file: its name relative to the atlas folder, and its bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct Artifact {
    /// E.g. `pages/hrones-nelson-0001.png`.
    pub name: String,
    /// The complete file.
    pub bytes: Vec<u8>,
}

/// A page that could not be made or written: its file (relative to the atlas folder)
/// and why. A run records it and goes on with the other pages.
#[derive(Clone, Debug, PartialEq)]
pub struct PageFailure {
    /// E.g. `pages/hrones-nelson-0003.png`.
    pub page: String,
    /// What went wrong.
    pub message: String,
}

/// What a renderer makes of one group or of the atlas: each page's files, or why a page
/// failed (the others are still made).
pub type Rendered = Vec<Result<Artifact, PageFailure>>;

/// Renders pages: the hook between the curve pipeline and page output. It is called on
/// worker threads, one group at a time, and returns finished files; the pipeline writes
/// them (atomically) and drops them, so memory stays bounded. A page that fails is
/// returned as a [`PageFailure`] in its place, and the other pages go on.
pub trait Renderer: Sync {
    /// The pages of one group; may record each curve's place (`curves[i].page`).
    fn render_group(&self, job: &Job, group: &Group, curves: &mut [IndexCurve]) -> Rendered;
    /// Files made once per atlas after all groups (e.g. a contents page).
    fn render_atlas(&self, job: &Job) -> Rendered;
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
    fn render_group(&self, _: &Job, _: &Group, _: &mut [IndexCurve]) -> Rendered {
        Vec::new()
    }
    fn render_atlas(&self, _: &Job) -> Rendered {
        Vec::new()
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
    /// The mechanism.
    pub linkage: Linkage,
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
            let points = self.spec.points.points(l.coupler_length());
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
        if let Some(g) = &s.geared {
            // A geared five-bar atlas (crates/specs/src/geared.rs).
            let _ = writeln!(
                t,
                "combinations: {} (L1: {} values, L3: {}, L4: {}, L5: {}, ratios: {}, phases: {})",
                s.combinations(),
                g.l1.len(),
                g.l3.len(),
                g.l4.len(),
                g.l5.len(),
                g.ratios.len(),
                g.phases.len()
            );
            let _ = writeln!(
                t,
                "linkages:     {} geared five-bars whose input turns fully",
                self.enumeration.linkages.len()
            );
        } else {
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
        }
        let skipped: u64 = self.enumeration.skipped.values().sum();
        let detail: Vec<String> = self
            .enumeration
            .skipped
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        let _ = writeln!(
            t,
            "skipped:      {skipped} {}{}",
            if s.geared.is_some() {
                "whose input does not turn fully"
            } else {
                "not strict crank-rockers"
            },
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
            "samples:      {} per curve (every {}°){}",
            (360.0 / s.sampling.crank_step_deg).round(),
            s.sampling.crank_step_deg,
            if s.geared.is_some() {
                " per turn of input; a gear ratio p/q takes q turns"
            } else {
                ""
            }
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
/// when `features` is given, their dashes counted in `dash` (the pages' pattern).
pub fn compute_group(
    table: &CrankTable,
    group: &Group,
    features: Option<&FeatureTolerances>,
    dash: &DashPattern,
) -> Result<Vec<IndexCurve>, GenerateError> {
    let mut extractor =
        features.and_then(|t| FeatureExtractor::new(&group.linkage, group.circuit, t, dash));
    // A mechanism whose period is longer than a turn (a geared five-bar of gear ratio
    // p/q) is sampled over its whole period at the same step.
    let own_table;
    let table = if group.linkage.period_deg() == 360.0 {
        table
    } else {
        own_table = CrankTable::over(table.step(), group.linkage.period_deg())
            .ok_or(GenerateError::BadStep(table.step()))?;
        &own_table
    };
    let poses = group.linkage.pose_table(group.circuit, table);
    if !poses.all_valid() {
        return Err(GenerateError::NotAssembled {
            linkage: group.linkage,
            circuit: group.circuit,
        });
    }
    let range = group.linkage.transmission_range(group.circuit);
    let [tmin, tmax] = range.ok_or(GenerateError::NotAssembled {
        linkage: group.linkage,
        circuit: group.circuit,
    })?;
    let transmission_deg = [tmin.to_degrees(), tmax.to_degrees()];
    let class = group.linkage.class();
    let flag_tol = FlagTolerances::DEFAULT;
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
            linkage: group.linkage,
            point,
            circuit: group.circuit,
            class,
            bbox: summary.bbox,
            transmission_deg,
            speed: summary.speed,
            length: summary.length,
            flags: curve_flags(&group.linkage, point, [tmin, tmax], &flag_tol),
            page: None,
            features: extractor.as_mut().map(|x| x.extract(point)),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_cover_ids_and_pages_in_order() {
        let spec = Spec::parse(include_str!("../../../atlas-spec/quick.toml"), "quick").unwrap();
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
        let l = coupler_kinematics::FourBar::new(3.0, 3.0, 3.0)
            .unwrap()
            .into();
        let g = Group {
            linkage: l,
            circuit: Circuit::Open,
            points: vec![CouplerPoint::new(0.0, 0.0), CouplerPoint::new(3.0, 0.0)],
            first_id: 5,
            first_page: 1,
        };
        let c = compute_group(&table, &g, None, &DashPattern::default()).unwrap();
        assert_eq!(c[0].id, 5);
        // Point (0, 0) is the crank pin: the unit circle.
        assert!((c[0].length - std::f64::consts::TAU).abs() < 1e-12);
        // Point (A, 0) is the rocker pin: an arc of radius B about O4, inside x ∈ [0, 6].
        assert!(c[1].bbox[0] >= 0.0 - 1e-12 && c[1].bbox[2] <= 6.0 + 1e-12);
        let [lo, hi] = c[0].transmission_deg;
        assert!(0.0 < lo && lo < hi && hi < 180.0);
    }
}
