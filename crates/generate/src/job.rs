//! The job: a validated spec with what it enumerates, split into groups (one linkage in
//! one circuit with all its coupler points, sharing one pose table), and the pure
//! computation of a group's index records.

use crate::GenerateError;
use coupler_features::{FeatureExtractor, FeatureTolerances, FlagTolerances, curve_flags};
use coupler_index::{IndexCurve, IndexSummary};
use coupler_kinematics::{
    AngleTables, ArcLength, Circuit, CouplerPoint, CurveSummary, DashPattern, Linkage, Mechanism,
};
use coupler_specs::Spec;
use std::path::PathBuf;

/// A validated generate job: the spec, what it enumerates (counted, never held), and
/// where output goes.
#[derive(Clone, Debug)]
pub struct Job {
    /// The spec.
    pub spec: Spec,
    /// Where the spec came from (for messages).
    pub source: String,
    /// The spec's TOML text, when known: recorded in the output folder, so that `merge`
    /// takes the spec from the shards.
    pub spec_text: Option<String>,
    /// Number of strict crank-rockers (counted arithmetically: [`Spec::count_linkages`]).
    pub linkages: u64,
    /// Output folder.
    pub out: PathBuf,
    /// Worker threads.
    pub jobs: usize,
    /// Which slice of the chunks to compute.
    pub shard: Shard,
    /// Write into a folder that holds files this program did not write.
    pub force: bool,
    skipped: std::sync::OnceLock<std::collections::BTreeMap<String, u64>>,
}

/// At most this many coupler points in one unit of work: a linkage's grid larger than
/// this (possible only without pages: a page draws its linkage's whole grid) is cut into
/// units of this many points, so memory stays bounded whatever the grid.
pub const UNIT_POINTS: u64 = 1024;

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
    /// [`Renderer::render_group`] with the group's pages drawn as tasks of the calling
    /// worker's rayon pool, so that a worker with nothing else to do draws some: the same
    /// files in the same order. The run asks it for its last few units, where a worker
    /// that finds no unit left would otherwise wait for the other's last group. The
    /// default draws them as `render_group` does.
    fn render_group_shared(&self, job: &Job, group: &Group, curves: &mut [IndexCurve]) -> Rendered {
        self.render_group(job, group, curves)
    }
    /// Files made once per atlas after all groups (e.g. a contents page).
    fn render_atlas(&self, job: &Job) -> Rendered;
    /// The same files as [`Renderer::render_atlas`], made while the groups are: `Some`
    /// when they depend on the job alone (not on the groups' output) and are drawn on the
    /// calling thread. A whole run calls it on a worker as its first task, so that they
    /// are drawn beside the groups' pages rather than after the last one, with one core
    /// idle; `None` (the default): the run calls [`Renderer::render_atlas`] at its end.
    fn render_atlas_alongside(&self, _job: &Job) -> Option<Rendered> {
        None
    }
    /// Number of pages it makes for `job` (0 for none), for the summary.
    fn pages(&self, job: &Job) -> u64;
    /// Everything about it that changes output bytes (formats, resolution…): part of the
    /// key that decides whether a chunk record from an earlier run can be reused.
    fn settings(&self) -> String;
    /// Its page options, if it renders pages (recorded in the output folder so that
    /// `merge` rebuilds the same renderer, and used for the plan's estimates).
    fn page_options(&self) -> Option<&crate::PageOptions> {
        None
    }
    /// Its clocks, if it keeps any: the run adds its own work on each group to them
    /// (curves and index, file writing), so that a benchmark can split a worker's time.
    fn timings(&self) -> Option<&crate::PageTimings> {
        None
    }
    /// The names of the files [`Renderer::render_group`] will return for `group`, when
    /// known in advance: the run records them (durably) once per chunk before rendering,
    /// rather than once per group. `None`: recorded as they come (correct, slower).
    fn group_files(&self, _job: &Job, _group: &Group) -> Option<Vec<String>> {
        None
    }
}

/// No pages: index only.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoPages;

impl Renderer for NoPages {
    fn group_files(&self, _: &Job, _: &Group) -> Option<Vec<String>> {
        Some(Vec::new())
    }
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
    /// Its coupler points, in atlas order: the linkage's whole grid, or for a grid of
    /// more than [`UNIT_POINTS`] points (index only) one slice of it.
    pub points: Vec<CouplerPoint>,
    /// Id of its first curve.
    pub first_id: u64,
    /// Number of its first page (from 1).
    pub first_page: u64,
}

impl Job {
    /// A job for `spec` writing into `out` with `jobs` threads (at least 1). Counts the
    /// linkages arithmetically; enumerates nothing.
    pub fn new(spec: Spec, source: impl Into<String>, out: impl Into<PathBuf>, jobs: usize) -> Job {
        Job {
            linkages: spec.count_linkages(),
            spec,
            source: source.into(),
            spec_text: None,
            out: out.into(),
            jobs: jobs.max(1),
            shard: Shard::ALL,
            force: false,
            skipped: Default::default(),
        }
    }

    /// Coupler points per unit of work: the whole grid, or [`UNIT_POINTS`] for a larger
    /// grid (a multiple of the curves per page).
    pub fn unit_points(&self) -> u64 {
        let n = self.spec.points.len();
        if n <= UNIT_POINTS {
            n.max(1)
        } else {
            let per = u64::from(self.spec.pages.curves_per_page.max(1));
            (UNIT_POINTS / per).max(1) * per
        }
    }

    /// Units of work per (linkage, circuit).
    fn units_per_group(&self) -> u64 {
        self.spec.points.len().div_ceil(self.unit_points()).max(1)
    }

    /// Number of units of work.
    pub fn unit_count(&self) -> u64 {
        self.linkages
            .saturating_mul(self.spec.circuits.len() as u64)
            .saturating_mul(self.units_per_group())
    }

    /// Number of chunks ([`crate::CHUNK_GROUPS`] units each).
    pub fn chunk_count(&self) -> u64 {
        self.unit_count().div_ceil(crate::CHUNK_GROUPS as u64)
    }

    /// The units of work in atlas order (linkage: A, then B, then C ascending; circuit;
    /// points), made one at a time: for an ordinary grid each unit is a whole group (one
    /// linkage in one circuit with all its coupler points); a grid of more than
    /// [`UNIT_POINTS`] points is cut into slices.
    pub fn units(&self) -> impl Iterator<Item = Group> + '_ {
        let circuits = self.spec.circuits.clone();
        let (n, per_unit) = (self.spec.points.len(), self.unit_points());
        let per_page = u64::from(self.spec.pages.curves_per_page.max(1));
        let pages_per_group = n.div_ceil(per_page);
        self.spec
            .atlas_linkages()
            .enumerate()
            .flat_map(move |(li, l)| {
                let circuits = circuits.clone();
                circuits
                    .into_iter()
                    .enumerate()
                    .flat_map(move |(ci, circuit)| {
                        let g = li as u64 * self.spec.circuits.len() as u64 + ci as u64;
                        (0..n.div_ceil(per_unit).max(1)).map(move |u| {
                            let first = u * per_unit;
                            Group {
                                linkage: l,
                                circuit,
                                points: self.spec.points.points_in(
                                    l.coupler_length(),
                                    first,
                                    per_unit,
                                ),
                                first_id: g * n + first,
                                first_page: g * pages_per_group + first / per_page + 1,
                            }
                        })
                    })
            })
    }

    /// The groups in atlas order (one per linkage and circuit, each with its whole
    /// grid), made one at a time.
    pub fn groups(&self) -> impl Iterator<Item = Group> + '_ {
        let per_page = u64::from(self.spec.pages.curves_per_page.max(1));
        let n = self.spec.points.len();
        let pages_per_group = n.div_ceil(per_page);
        let circuits = self.spec.circuits.clone();
        self.spec
            .atlas_linkages()
            .enumerate()
            .flat_map(move |(li, l)| {
                let points = self.spec.points.points(l.coupler_length());
                circuits
                    .clone()
                    .into_iter()
                    .enumerate()
                    .map(move |(ci, circuit)| {
                        let g = li as u64 * self.spec.circuits.len() as u64 + ci as u64;
                        Group {
                            linkage: l,
                            circuit,
                            points: points.clone(),
                            first_id: g * n,
                            first_page: g * pages_per_group + 1,
                        }
                    })
            })
    }

    /// Number of curves (saturating: see [`crate::Plan`] for exact counts of any size).
    pub fn curves(&self) -> u64 {
        self.linkages
            .saturating_mul(self.spec.circuits.len() as u64)
            .saturating_mul(self.spec.points.len())
    }

    /// Number of pages (each group starts a new page; saturating).
    pub fn pages(&self) -> u64 {
        let per_page = self.spec.pages.curves_per_page as u64;
        self.linkages
            .saturating_mul(self.spec.circuits.len() as u64)
            .saturating_mul(self.spec.points.len().div_ceil(per_page))
    }

    /// Combinations that are not strict crank-rockers, by class (counted arithmetically
    /// once, on first use).
    pub fn skipped(&self) -> &std::collections::BTreeMap<String, u64> {
        self.skipped.get_or_init(|| self.spec.skipped())
    }

    /// The counts written into the index.
    pub fn summary(&self, pages: u64) -> IndexSummary {
        IndexSummary {
            combinations: self.spec.combinations(),
            linkages: self.linkages,
            skipped: self.skipped().clone(),
            curves: self.curves(),
            pages,
        }
    }
}

/// Computes the index records of one group (pure: no I/O), with each curve's features
/// when `features` is given, their dashes counted in `dash` (the pages' pattern).
/// `tables` (one per run, shared by its threads) holds the input angles: a mechanism
/// whose period is longer than a turn (a geared five-bar of gear ratio p/q) is sampled
/// over its whole period at the same step.
pub fn compute_group(
    tables: &AngleTables,
    group: &Group,
    features: Option<&FeatureTolerances>,
    dash: &DashPattern,
) -> Result<Vec<IndexCurve>, GenerateError> {
    let mut extractor = features.and_then(|t| {
        FeatureExtractor::with_tables(&group.linkage, group.circuit, t, dash, tables)
    });
    let poses = tables.pose_table(&group.linkage, group.circuit);
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
    let not_assembled = || GenerateError::NotAssembled {
        linkage: group.linkage,
        circuit: group.circuit,
    };
    // Lengths exact to 1e-11 relative (adaptive quadrature of the speed; the samples'
    // trapezoid sum is off by up to 1e-5 on curves with cusps).
    let mut arc = ArcLength::new(&group.linkage, group.circuit).ok_or_else(not_assembled)?;
    let flag_tol = FlagTolerances::DEFAULT;
    let mut curve = Default::default();
    let mut out = Vec::with_capacity(group.points.len());
    for (k, &point) in group.points.iter().enumerate() {
        poses.trace_into(point, &mut curve);
        let summary = CurveSummary::of(&curve).ok_or_else(not_assembled)?;
        out.push(IndexCurve {
            id: group.first_id + k as u64,
            linkage: group.linkage,
            point,
            circuit: group.circuit,
            class,
            bbox: summary.bbox,
            transmission_deg,
            speed: summary.speed,
            length: arc.length(point).ok_or_else(not_assembled)?,
            flags: curve_flags(&group.linkage, point, [tmin, tmax], &flag_tol),
            page: None,
            features: extractor.as_mut().map(|x| x.extract(point)),
        });
    }
    Ok(out)
}

/// The built-in quick specs, a four-bar one and a geared five-bar one, as one-thread jobs
/// writing nowhere: for tests that run every kind of atlas through one piece of the run.
#[cfg(test)]
pub(crate) fn quick_jobs() -> Vec<Job> {
    [
        (include_str!("../../../atlas-spec/quick.toml"), "quick"),
        (
            include_str!("../../../atlas-spec/geared-quick.toml"),
            "geared-quick",
        ),
    ]
    .into_iter()
    .map(|(text, name)| {
        let spec = coupler_specs::Spec::parse(text, name).expect("a built-in spec");
        Job::new(spec, name, std::env::temp_dir(), 1)
    })
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_cover_ids_and_pages_in_order() {
        let spec = Spec::parse(include_str!("../../../atlas-spec/quick.toml"), "quick").unwrap();
        let job = Job::new(spec, "quick", "unused", 1);
        let groups: Vec<Group> = job.groups().collect();
        assert_eq!(job.units().collect::<Vec<_>>(), groups);
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
        let table = AngleTables::new(1.0).unwrap();
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
