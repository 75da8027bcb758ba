//! A run's size before it starts: linkages, curves, pages and an estimate of the disk it
//! takes, all counted arithmetically (a spec of 10^15 combinations answers at once), the
//! limits over which a run needs confirmation (`--yes`), and those no flag lifts.

use crate::{Job, Renderer, UNIT_POINTS};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// Over these, `generate` asks for `--yes` (a typo in a step is the usual cause).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Limits {
    /// Curves.
    pub curves: u64,
    /// Page files.
    pub page_files: u64,
    /// Estimated bytes written.
    pub bytes: u64,
}

impl Limits {
    /// The documented limits (`docs/scale.md`): 5,000,000 curves, 20,000 page files,
    /// 20 GB.
    pub const DEFAULT: Limits = Limits {
        curves: 5_000_000,
        page_files: 20_000,
        bytes: 20_000_000_000,
    };
}

/// Ids must stay exact in any JSON reader (doubles): at most 2^53 curves.
pub const MAX_CURVES: u128 = 1 << 53;

/// Estimated bytes written, by kind.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DiskEstimate {
    /// `index.json`.
    pub index: u128,
    /// Chunk records (the index's lines again, kept for resuming).
    pub chunk_records: u128,
    /// Page files.
    pub pages: u128,
    /// All of it.
    pub total: u128,
}

/// A run's plan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Plan {
    /// The atlas's name.
    pub name: String,
    /// Where the spec came from.
    pub source: String,
    /// (A, B, C) combinations in the ranges.
    pub combinations: u64,
    /// Values of A, B and C (all 0 for a geared grid: see `ranges`).
    pub range_values: [u64; 3],
    /// The ranges in words: "A: 10 values, B: 10, C: 7", or a geared grid's
    /// "L1: …, L3: …, L4: …, L5: …, ratios: …, phases: …".
    pub ranges: String,
    /// The mechanism: "four-bar" or "geared-fivebar".
    pub mechanism: String,
    /// The atlas's linkages among them (strict crank-rockers, or geared five-bars whose
    /// input turns fully).
    pub linkages: u64,
    /// The others, by Barker class (`None` when not counted: more than
    /// [`Plan::CLASS_COUNT_LIMIT`] values of A).
    pub skipped_by_class: Option<BTreeMap<String, u64>>,
    /// Combinations skipped.
    pub skipped: u64,
    /// Coupler points per linkage.
    pub points: u64,
    /// Points along u and v.
    pub grid: [u64; 2],
    /// Circuits.
    pub circuits: Vec<String>,
    /// Curves.
    pub curves: u128,
    /// Samples per curve.
    pub samples_per_curve: u64,
    /// Crank step, degrees.
    pub crank_step_deg: f64,
    /// Pages (0 without pages).
    pub pages: u128,
    /// Page files (pages × formats).
    pub page_files: u128,
    /// Page settings, as text (`None` without pages).
    pub page_settings: Option<String>,
    /// Estimated disk use.
    pub bytes: DiskEstimate,
    /// Chunks of work.
    pub chunks: u64,
    /// The output folder.
    pub output: String,
    /// The limits over which `--yes` is needed.
    pub limits: Limits,
    /// The limits this plan is over (each a sentence).
    pub over_limits: Vec<String>,
    /// Why this plan cannot run at all, whatever the flags.
    pub refused: Vec<String>,
}

/// Bytes per curve of the index with features and pages (measured: the default atlas's
/// index is 13.5 MB for 7,000 curves), and without features.
const INDEX_BYTES_WITH_FEATURES: u128 = 2000;
const INDEX_BYTES_PLAIN: u128 = 450;

impl Plan {
    /// Above this many values of A, the skipped combinations are not broken down by class
    /// in a dry run (the count takes about 10 µs per value of A).
    pub const CLASS_COUNT_LIMIT: u64 = 10_000;

    /// The plan of `job` with `renderer`, against `limits`.
    pub fn new(job: &Job, renderer: &dyn Renderer, limits: Limits) -> Plan {
        let s = &job.spec;
        let circuits = s.circuits.len() as u128;
        let points = s.points.len();
        let curves = u128::from(job.linkages) * circuits * u128::from(points);
        let options = renderer.page_options();
        let per_page = u128::from(s.pages.curves_per_page.max(1));
        let pages = match options {
            Some(_) => u128::from(job.linkages) * circuits * u128::from(points).div_ceil(per_page),
            None => 0,
        };
        let formats = options.map(|o| o.formats.len() as u128).unwrap_or(0);
        let page_files = pages * formats;
        let per_curve = if s.features.enabled {
            INDEX_BYTES_WITH_FEATURES
        } else {
            INDEX_BYTES_PLAIN
        };
        let page_bytes: u128 = options
            .map(|o| {
                let (w, h) = o.setup.size_px();
                let px = u128::from(w) * u128::from(h);
                o.formats
                    .iter()
                    .map(|f| match f.extension() {
                        // Measured: 385 KB for a 300 dpi tabloid page of 10 curves
                        // (16.8 Mpx), about 1 byte per 44 pixels.
                        "png" => px / 44,
                        // Vector pages: about 60 KB per curve drawn.
                        _ => 60_000 * per_page,
                    })
                    .sum()
            })
            .unwrap_or(0);
        let index = curves * per_curve;
        let bytes = DiskEstimate {
            index,
            chunk_records: index,
            pages: pages * page_bytes,
            total: 2 * index + pages * page_bytes,
        };
        let skipped_by_class =
            (s.linkages.coupler.len() <= Plan::CLASS_COUNT_LIMIT).then(|| job.skipped().clone());
        let mut plan = Plan {
            name: s.name.clone(),
            source: job.source.clone(),
            combinations: s.combinations(),
            range_values: [
                s.linkages.coupler.len(),
                s.linkages.rocker.len(),
                s.linkages.ground.len(),
            ],
            ranges: match &s.geared {
                Some(g) => format!(
                    "L1: {} values, L3: {}, L4: {}, L5: {}, ratios: {}, phases: {}",
                    g.l1.len(),
                    g.l3.len(),
                    g.l4.len(),
                    g.l5.len(),
                    g.ratios.len(),
                    g.phases.len()
                ),
                None => format!(
                    "A: {} values, B: {}, C: {}",
                    s.linkages.coupler.len(),
                    s.linkages.rocker.len(),
                    s.linkages.ground.len()
                ),
            },
            mechanism: if s.geared.is_some() {
                "geared-fivebar"
            } else {
                "four-bar"
            }
            .to_string(),
            linkages: job.linkages,
            skipped: s.combinations().saturating_sub(job.linkages),
            skipped_by_class,
            points,
            grid: [s.points.u.len(), s.points.v.len()],
            circuits: s.circuits.iter().map(|c| c.name().to_string()).collect(),
            curves,
            samples_per_curve: coupler_kinematics::samples_per_turn(s.sampling.crank_step_deg)
                .unwrap_or(0),
            crank_step_deg: s.sampling.crank_step_deg,
            pages,
            page_files,
            page_settings: options.map(|o| {
                format!(
                    "{} curves per page, {}, {} dpi, {}",
                    s.pages.curves_per_page,
                    o.setup.size,
                    o.setup.dpi,
                    o.formats
                        .iter()
                        .map(|f| f.extension())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }),
            bytes,
            chunks: job.chunk_count(),
            output: job.out.display().to_string(),
            limits,
            over_limits: Vec::new(),
            refused: Vec::new(),
        };
        if curves > u128::from(limits.curves) {
            plan.over_limits.push(format!(
                "{curves} curves ({} linkages × {points} points × {circuits} circuit(s)), more than {}",
                job.linkages, limits.curves
            ));
        }
        if page_files > u128::from(limits.page_files) {
            plan.over_limits.push(format!(
                "{page_files} page files, more than {} (--no-pages writes none)",
                limits.page_files
            ));
        }
        if bytes.total > u128::from(limits.bytes) {
            plan.over_limits.push(format!(
                "about {} on disk, more than {}",
                human_bytes(bytes.total),
                human_bytes(u128::from(limits.bytes))
            ));
        }
        if curves > MAX_CURVES {
            plan.refused.push(format!(
                "{curves} curves is more than the {MAX_CURVES} an index can number exactly"
            ));
        }
        if options.is_some() && points > UNIT_POINTS {
            plan.refused.push(format!(
                "each page draws its linkage's whole grid of coupler points, and {points} points per linkage is more than the {UNIT_POINTS} a page can show: use --no-pages, or a coarser [points] grid"
            ));
        }
        plan
    }

    /// The plan as text (what `--dry-run` prints).
    pub fn describe(&self) -> String {
        let mut t = String::new();
        let _ = writeln!(t, "spec:         {} ({})", self.name, self.source);
        let geared = self.mechanism == "geared-fivebar";
        let _ = writeln!(t, "combinations: {} ({})", self.combinations, self.ranges);
        let _ = writeln!(
            t,
            "linkages:     {} {}",
            self.linkages,
            if geared {
                "geared five-bars whose input turns fully"
            } else {
                "strict crank-rockers"
            }
        );
        let detail = match &self.skipped_by_class {
            Some(m) if !m.is_empty() => format!(
                " ({})",
                m.iter()
                    .map(|(k, v)| format!("{k} {v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Some(_) => String::new(),
            None => format!(
                " (not broken down by class for more than {} values of A)",
                Plan::CLASS_COUNT_LIMIT
            ),
        };
        let _ = writeln!(
            t,
            "skipped:      {} {}{detail}",
            self.skipped,
            if geared {
                "whose input does not turn fully, or whose phase repeats another's curves (360°/q apart for λ = p/q)"
            } else {
                "not strict crank-rockers"
            }
        );
        let _ = writeln!(
            t,
            "points:       {} per linkage ({} u × {} v)",
            self.points, self.grid[0], self.grid[1]
        );
        let _ = writeln!(t, "circuits:     {}", self.circuits.join(", "));
        let _ = writeln!(t, "curves:       {}", self.curves);
        let _ = writeln!(
            t,
            "samples:      {} per curve (every {}°){}",
            self.samples_per_curve,
            self.crank_step_deg,
            if geared {
                " per turn of input; a gear ratio p/q takes q turns"
            } else {
                ""
            }
        );
        match &self.page_settings {
            Some(p) => {
                let _ = writeln!(t, "pages:        {} ({p})", self.pages);
            }
            None => {
                let _ = writeln!(t, "pages:        0 (--no-pages)");
            }
        }
        let _ = writeln!(
            t,
            "disk:         about {} (index {}, chunk records {}, pages {})",
            human_bytes(self.bytes.total),
            human_bytes(self.bytes.index),
            human_bytes(self.bytes.chunk_records),
            human_bytes(self.bytes.pages)
        );
        let _ = writeln!(t, "chunks:       {}", self.chunks);
        let _ = write!(t, "output:       {}", self.output);
        for r in &self.refused {
            let _ = write!(t, "\nrefused:      {r}");
        }
        for o in &self.over_limits {
            let _ = write!(t, "\nover limit:   {o}: needs --yes");
        }
        t
    }

    /// Why this plan needs `--yes` (empty if it does not), as one sentence.
    pub fn confirmation(&self) -> Option<String> {
        (!self.over_limits.is_empty()).then(|| {
            format!(
                "{} enumerates {}; check the ranges with --dry-run, or pass --yes to run it",
                self.source,
                self.over_limits.join("; ")
            )
        })
    }
}

/// `1.2 GB`, `350 MB`, `12 kB`, `800 B` (decimal units).
pub fn human_bytes(b: u128) -> String {
    let units = [
        ("EB", 1e18),
        ("PB", 1e15),
        ("TB", 1e12),
        ("GB", 1e9),
        ("MB", 1e6),
        ("kB", 1e3),
    ];
    let x = b as f64;
    for (name, size) in units {
        if x >= size {
            return format!("{:.1} {name}", x / size);
        }
    }
    format!("{b} B")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_read_as_people_write_them() {
        assert_eq!(human_bytes(800), "800 B");
        assert_eq!(human_bytes(13_519_413), "13.5 MB");
        assert_eq!(human_bytes(49_000_000_000), "49.0 GB");
    }
}
