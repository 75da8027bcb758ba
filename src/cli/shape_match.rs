//! `coupler-atlas match TARGET [--atlas DIR] [--open|--closed] [--timed] [--mirror]
//! [--top K] [--candidates N] [--linkages N] [--full-scan] [--refine] [--png FILE] [--svg FILE]
//! [--format table|json] [--jobs N]`:
//! which atlas curves look like the target path, each with its fit, placement and error
//! (`docs/shape-search.md`).

use super::UsageError;
use anyhow::{Context, Result};
use coupler_atlas::generate::FileEntry;
use coupler_atlas::render::{RasterPage, SvgPage, draw};
use coupler_atlas::shape::{
    AtlasCurve, Candidate, ClosedQuery, CouplerCurve, CurveFit, LatticeSearch, MAX_PROPORTION,
    Match, MatchError, MatchOptions, OVERLAY_SIZE_PT, OpenScan, OverlayText, Placement, Refined,
    SHAPES_FILE, SidecarView, Target, Timing, closed_candidates_in, open_finish, open_lattice_scan,
    open_linkages, open_scan, rank_candidates, refine,
};
use coupler_atlas::{Circuit, IndexCurve, Linkage, TargetFile, minus_sign};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use serde_json::{Value, json};
use std::io::BufRead as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The target path: CSV (`x,y` or `x,y,angle` per line) or JSON (`[[x, y], …]` or
    /// `{"points": …, "closed": …, "angles_deg": …}`); `-` reads CSV from stdin.
    target: PathBuf,
    /// The atlas folder (written by `generate`; it must hold shapes.bin).
    #[arg(long, default_value = "output/hrones-nelson")]
    atlas: PathBuf,
    /// The target is an open path, matched to a stretch of a curve (default unless the
    /// file says `"closed": true` or repeats its first point at the end).
    #[arg(long, conflicts_with = "closed")]
    open: bool,
    /// The target is a closed loop, matched to a whole curve.
    #[arg(long)]
    closed: bool,
    /// Respect timing: each point's input angle (third column / `angles_deg`), or equal
    /// crank steps between points if the file gives no angles.
    #[arg(long)]
    timed: bool,
    /// Allow reflected matches (a mirrored curve is traced by another real linkage,
    /// which is what is reported: the other circuit, v negated, and for a geared
    /// five-bar the phase negated).
    #[arg(long)]
    mirror: bool,
    /// Matches to report.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=100))]
    top: u32,
    /// Candidates from the coarse stage that get an exact fit (default: 64 for a closed
    /// target, 1,024 for an open one; with --mirror: that many of each reflection).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    candidates: Option<u32>,
    /// Screen an open target's linkages and scan only the best N by a coarse score
    /// (default: no screen; see --full-scan for what is scanned). The
    /// screen is an estimate: on the dense atlas the source's linkage is among its best
    /// N only part of the time (docs/shape-search.md), so a screened answer is a sample
    /// of the atlas, not a full search.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    linkages: Option<u32>,
    /// Scan every linkage for an open target (with progress on stderr for a large
    /// atlas). By default only an atlas of at most 2,000 linkages is scanned whole; a
    /// larger one is searched coarse to fine over its linkage lattice (a sub-lattice, then
    /// the neighbours of the best linkages; docs/shape-search.md, "The lattice search").
    #[arg(long)]
    full_scan: bool,
    /// Refine each match off the atlas grid (Levenberg–Marquardt over the linkage's
    /// dimensions: a four-bar's A, B, C, a geared five-bar's L1, L3, L4, L5 and phase φ
    /// with its gear ratio held; the coupler point and the transform).
    #[arg(long)]
    refine: bool,
    /// Write the overlay of the best match (refined if --refine) as PNG.
    #[arg(long, value_name = "FILE")]
    png: Option<PathBuf>,
    /// Write the overlay of the best match (refined if --refine) as SVG.
    #[arg(long, value_name = "FILE")]
    svg: Option<PathBuf>,
    /// Output format.
    #[arg(long, default_value = "table", value_parser = ["table", "json"])]
    format: String,
    /// Worker threads (default: all cores).
    #[arg(long, short = 'j')]
    jobs: Option<usize>,
}

/// Reads the target file into a validated target. Timed angles are checked against
/// the atlas's periods once it is loaded ([`check_timing`]).
fn read_target(args: &Args) -> Result<Target> {
    let name = args.target.display().to_string();
    let text = if name == "-" {
        std::io::read_to_string(std::io::stdin()).context("reading the target from stdin")?
    } else {
        std::fs::read_to_string(&args.target)
            .map_err(|e| UsageError(format!("cannot read target {name}: {e}")))?
    };
    let file =
        TargetFile::parse(&text, &name).map_err(|e| UsageError(format!("target {name}: {e}")))?;
    let repeats = file.points.len() > 1 && file.points.first() == file.points.last();
    let closed = if args.closed {
        true
    } else if args.open {
        false
    } else {
        file.closed.unwrap_or(repeats)
    };
    if !args.open && !args.closed && file.closed.is_none() && !repeats {
        // A loop whose last point stops short of the first looks closed; say how it is read.
        let p = &file.points;
        let d = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
        let steps: f64 = p.windows(2).map(|w| d(w[0], w[1])).sum();
        if p.len() > 2 && d(p[0], p[p.len() - 1]) <= 3.0 * steps / (p.len() - 1) as f64 {
            eprintln!(
                "note: {name} is matched as an open path (its ends are close: pass --closed if it is a loop)"
            );
        }
    }
    let timing = if !args.timed {
        Timing::Untimed
    } else if let Some(a) = file.angles_deg.clone() {
        Timing::Angles(a)
    } else {
        Timing::EqualSteps
    };
    Target::with_period(file.points, closed, timing, f64::INFINITY)
        .map_err(|e| UsageError(format!("target {name}: {e}")).into())
}

/// Refuses a target timed by angles that no curve of the atlas can carry: its angles
/// span at least the longest period of the atlas's curves (more, for an open target).
/// The period is 360° on a four-bar atlas and `360°·q` for a geared five-bar of gear
/// ratio p/q (720° for λ = −1/2), so a closed loop timed over two input turns is matched
/// on the curves that close after two turns.
fn check_timing(target: &Target, atlas: &Shapes, name: &str, dir: &Path) -> Result<()> {
    let Some(span) = target.angle_span() else {
        return Ok(());
    };
    let view = atlas.view();
    if view.is_empty() {
        return Ok(());
    }
    // Only a target timed by angles needs the periods. A four-bar curve's period is one
    // crank turn, whatever its record; a geared atlas's periods (360°·q by its gears)
    // need every record decoded.
    let longest = match view.kind() {
        coupler_atlas::shape::RecordKind::FourBar => 360.0,
        coupler_atlas::shape::RecordKind::GearedFiveBar => atlas
            .curves(&view)?
            .iter()
            .map(|c| c.curve.period_deg())
            .fold(0.0, f64::max),
    };
    if target.fits_period(longest) {
        return Ok(());
    }
    let e = coupler_atlas::shape::TargetError::AngleSpan {
        span,
        period: longest,
        closed: target.is_closed(),
    };
    Err(UsageError(format!("target {name} on atlas {}: {e}", dir.display())).into())
}

/// An atlas's shape sidecar, verified against the manifest and mapped read-only: its
/// records are read in place ([`SidecarView`]), decoded only where the search needs them.
pub(super) struct Shapes {
    bytes: coupler_mapped::Mapped,
    path: PathBuf,
}

impl Shapes {
    /// The records (the header was checked when the file was loaded).
    pub(super) fn view(&self) -> SidecarView<'_> {
        SidecarView::new(&self.bytes).expect("checked by load_shapes")
    }

    /// Every curve decoded (in parallel parts, in place), for an open target's scan.
    fn curves(&self, view: &SidecarView<'_>) -> Result<Vec<AtlasCurve>> {
        const PART: usize = 1 << 14;
        if view.is_empty() {
            return Ok(Vec::new());
        }
        let first = view.curve(0).map_err(|e| self.bad(e))?;
        let mut out = vec![first; view.len()];
        out.par_chunks_mut(PART)
            .enumerate()
            .try_for_each(|(k, part)| {
                let decoded = view.curves(k * PART..k * PART + part.len())?;
                part.copy_from_slice(&decoded);
                Ok(())
            })
            .map_err(|e: coupler_atlas::shape::SidecarError| self.bad(e))?;
        Ok(out)
    }

    fn bad(&self, e: impl std::fmt::Display) -> anyhow::Error {
        UsageError(format!("{}: {e}", self.path.display())).into()
    }
}

/// Reads the atlas's shape sidecar, checked against the manifest: its size and XXH3-128
/// must be the manifest's. The content key comes from the sidecar's stamp
/// (`shapes.bin.stamp`) when the file is the one last hashed (same device, inode, size,
/// modification and change times), as the search columns' index key does
/// (`coupler_index::index_key`); else the file is hashed whole, and the stamp written once
/// the file is accepted. The file is then mapped, not read: a query reads the records in
/// place.
pub(super) fn load_shapes(dir: &Path) -> Result<Shapes> {
    let manifest_path = dir.join("manifest.json");
    let text = std::fs::read_to_string(&manifest_path).map_err(|e| {
        UsageError(format!(
            "{} is not an atlas folder ({}: {e}); make one with `coupler-atlas generate`",
            dir.display(),
            manifest_path.display()
        ))
    })?;
    #[derive(serde::Deserialize)]
    struct Manifest {
        files: Vec<FileEntry>,
    }
    let manifest: Manifest = serde_json::from_str(&text)
        .map_err(|e| UsageError(format!("{}: not a manifest: {e}", manifest_path.display())))?;
    let entry = manifest
        .files
        .iter()
        .find(|f| f.name == SHAPES_FILE)
        .ok_or_else(|| UsageError(no_sidecar(dir)))?;
    let path = dir.join(SHAPES_FILE);
    if !path.is_file() {
        return Err(UsageError(format!(
            "{} is missing: the atlas's manifest lists it, so the file was removed after the atlas was written; run `coupler-atlas generate` again for the atlas (with the spec it was made from) to write it",
            path.display()
        ))
        .into());
    }
    let changed = || -> anyhow::Error {
        UsageError(format!(
            "{} does not match the manifest (size or hash differs): the atlas was changed after it was written; run `coupler-atlas generate` again for it",
            path.display()
        ))
        .into()
    };
    let read_err = |e: std::io::Error| -> anyhow::Error {
        UsageError(format!("{}: {e}", path.display())).into()
    };
    // A regular file only (not a link), checked on what was opened.
    if !std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file()) {
        return Err(UsageError(format!(
            "{} is a link or not a regular file: the shape sidecar is read only as the regular file `coupler-atlas generate` wrote; copy the file in place of the link, or run `coupler-atlas generate` again for the atlas",
            path.display()
        ))
        .into());
    }
    let file = std::fs::File::open(&path).map_err(read_err)?;
    if !file.metadata().map_err(read_err)?.is_file() {
        return Err(changed());
    }
    let (key, pending) = coupler_atlas::index_key(&file, &path).map_err(read_err)?;
    if key.bytes != entry.bytes || format!("{:032x}", key.hash) != entry.xxh3 {
        return Err(changed());
    }
    let bytes = coupler_mapped::Mapped::of_file(&file).map_err(read_err)?;
    if bytes.len() as u64 != key.bytes {
        return Err(changed());
    }
    SidecarView::new(&bytes).map_err(|e| UsageError(format!("{}: {e}", path.display())))?;
    // The file is the manifest's sidecar: remember its key.
    if let Some(p) = pending {
        p.write(&file);
    }
    Ok(Shapes { bytes, path })
}

/// Why an atlas whose manifest lists no shape sidecar cannot be searched, and what to do
/// (an atlas lacks them when it was written before shape search existed, or, for a
/// geared five-bar atlas, before its curves had shape codes), naming its spec from the
/// head of its index.
fn no_sidecar(dir: &Path) -> String {
    let mut head = String::new();
    if let Ok(f) = std::fs::File::open(dir.join("index.json")) {
        let _ = std::io::Read::read_to_string(&mut std::io::Read::take(f, 4096), &mut head);
    }
    let name = head
        .split_once("\"spec\":{\"name\":\"")
        .and_then(|(_, r)| r.split_once('"'))
        .map(|(n, _)| n.to_string());
    let spec = match name {
        Some(n) => format!("the spec of atlas `{n}`"),
        None => "the spec it was made from".into(),
    };
    let older = match atlas_mechanism(dir).as_deref() {
        Some("geared-fivebar") => "without shape codes for geared five-bars",
        _ => "without shape search",
    };
    format!(
        "the atlas in {} has no shape codes: its manifest lists no {SHAPES_FILE}, which `match` searches (a version of coupler-atlas {older} wrote it); write it again with `coupler-atlas generate SPEC --out {}` ({spec}), which adds {SHAPES_FILE}",
        dir.display(),
        dir.display()
    )
}

/// The mechanism of the atlas in `dir` as its index header names it
/// (`spec.linkages.mechanism`; a four-bar atlas's header may not name it), or `None` if
/// the header cannot be read.
fn atlas_mechanism(dir: &Path) -> Option<String> {
    let file = std::fs::File::open(dir.join("index.json")).ok()?;
    let mut lines = std::io::BufReader::new(file).lines();
    lines.next()?.ok()?;
    let spec = lines.next()?.ok()?;
    let spec = spec.trim_end().strip_suffix(',').unwrap_or(spec.trim_end());
    let v: serde_json::Value = serde_json::from_str(&format!("{{{spec}}}")).ok()?;
    let linkages = v.get("spec")?.get("linkages")?;
    Some(
        linkages
            .get("mechanism")
            .and_then(|m| m.as_str())
            .unwrap_or("four-bar")
            .to_string(),
    )
}

/// Linkages from which an open target's scan shows progress on stderr (the dense atlas
/// has 31,018; the default one 175).
const PROGRESS_LINKAGES: usize = 2_000;

/// What an open target's coarse stage scanned when it was not the whole atlas (the
/// lattice search, or the screen of `--linkages`): for the closing `searched …` line.
struct Scanned {
    /// Curves scanned.
    curves: usize,
    /// Linkages scanned.
    linkages: usize,
    /// Linkages of the atlas.
    of: usize,
    /// How they were picked.
    how: &'static str,
}

/// The coarse stage on the pool's threads: open targets' linkages screened (an atlas of
/// many linkages) and scanned in shares, then finished on the whole (the same candidates
/// however they are shared out); closed targets' codes in parts, in parallel. With what
/// was scanned if not every curve.
fn coarse(
    target: &Target,
    atlas: &Shapes,
    options: &MatchOptions,
) -> Result<(Vec<Candidate>, Option<Scanned>)> {
    let view = atlas.view();
    if target.is_closed() {
        let q = ClosedQuery::new(&target.complex_points(), options.allow_mirror)
            .ok_or(MatchError::Undescribable)?;
        // Parts of the atlas in parallel; their candidates together hold the best of all
        // (the same candidates however the atlas is cut). At most 2^15 curves a part, and
        // at least two parts a thread, so that a small atlas's codes are shared out too.
        let part = view
            .len()
            .div_ceil(2 * rayon::current_num_threads())
            .clamp(1024, 1 << 15);
        let parts: Vec<Vec<Candidate>> = (0..view.len().div_ceil(part))
            .into_par_iter()
            .map(|k| {
                let ids = k * part..((k + 1) * part).min(view.len());
                closed_candidates_in(&q, target, &view, ids, options)
            })
            .collect::<Result<_, _>>()?;
        return Ok((parts.concat(), None));
    }
    let curves = &atlas.curves(&view)?;
    let groups = coupler_atlas::shape::linkage_groups(curves);
    if let Some((scan, report)) = open_lattice_scan(target, curves, &groups, options)? {
        eprintln!(
            "note: lattice search: {} of the atlas's {} linkages scanned (a sub-lattice, then {} rounds of the best linkages' neighbours); a full scan may find closer curves: --full-scan scans every linkage",
            report.scanned, report.linkages, report.rounds
        );
        let scanned = Scanned {
            curves: report.curves,
            linkages: report.scanned,
            of: report.linkages,
            how: "lattice search",
        };
        return Ok((
            open_finish(target, curves, vec![scan], options)?,
            Some(scanned),
        ));
    }
    let all = groups.len();
    let groups = open_linkages(target, groups, options, |screen, groups| {
        groups
            .par_iter()
            .map(|g| screen.score(&curves[g.clone()]))
            .collect()
    });
    let total: usize = groups.iter().map(|g| g.len()).sum();
    let scanned = (groups.len() < all).then(|| {
        eprintln!(
            "note: {} of the atlas's {all} linkages scanned, picked by a coarse screen: the answer is a sample of the atlas, not a full search (without --linkages every linkage is scanned)",
            groups.len()
        );
        Scanned {
            curves: total,
            linkages: groups.len(),
            of: all,
            how: "coarse screen",
        }
    });
    let bar = if groups.len() >= PROGRESS_LINKAGES {
        let bar =
            ProgressBar::with_draw_target(Some(groups.len() as u64), ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} linkages scanned (eta {eta})",
            )
            .expect("valid template"),
        );
        bar
    } else {
        ProgressBar::hidden()
    };
    // Shares of about equal curve counts, several per thread.
    let parts = if bar.is_hidden() { 8 } else { 32 } * rayon::current_num_threads();
    let want = total.div_ceil(parts).max(1);
    let mut shares: Vec<Vec<std::ops::Range<usize>>> = vec![Vec::new()];
    let mut size = 0;
    for g in groups {
        if size >= want {
            shares.push(Vec::new());
            size = 0;
        }
        size += g.len();
        shares.last_mut().expect("one share").push(g);
    }
    let scans: Vec<OpenScan> = shares
        .par_iter()
        .map(|share| {
            let scan = open_scan(target, curves, share, options);
            bar.inc(share.len() as u64);
            scan
        })
        .collect::<Result<_, _>>()?;
    bar.finish_and_clear();
    Ok((open_finish(target, curves, scans, options)?, scanned))
}

/// Where each hit is drawn (page file and box), from the index, without reading it
/// whole: its curve lines are in id order (`docs/index-schema.md`), so each hit's line is
/// found by bisection over byte offsets (a few dozen short reads, however large the
/// index), and only that line is parsed. An index whose lines are not in id order is
/// streamed instead. Missing pages (an atlas made with `--no-pages`) give `None`.
fn page_refs(dir: &Path, ids: &[u64]) -> Result<Vec<Option<coupler_atlas::PageRef>>> {
    let path = dir.join("index.json");
    let open = || {
        std::fs::File::open(&path)
            .map_err(|e| UsageError(format!("cannot read {}: {e}", path.display())))
    };
    let file = open()?;
    let len = file
        .metadata()
        .with_context(|| format!("reading {}", path.display()))?
        .len();
    let mut lines = IndexLines {
        r: std::io::BufReader::with_capacity(16 << 10, file),
        buf: Vec::new(),
    };
    let mut found: std::collections::HashMap<u64, Option<coupler_atlas::PageRef>> =
        std::collections::HashMap::new();
    for &id in ids {
        if found.contains_key(&id) {
            continue;
        }
        match lines
            .bisect(id, len)
            .with_context(|| format!("reading {}", path.display()))?
        {
            Some(line) => {
                let c: IndexCurve = serde_json::from_str(line)
                    .with_context(|| format!("{}: curve {id}", path.display()))?;
                found.insert(id, c.page);
            }
            None => return stream_page_refs(&path, open()?, ids),
        }
    }
    Ok(ids
        .iter()
        .map(|id| found.get(id).cloned().flatten())
        .collect())
}

/// Curve lines of an index read at byte offsets.
struct IndexLines {
    r: std::io::BufReader<std::fs::File>,
    buf: Vec<u8>,
}

impl IndexLines {
    /// The id of the first curve line that starts at or after `pos` (`u64::MAX` if none),
    /// and where that line starts; its text is left in `self.buf`.
    fn next_curve(&mut self, pos: u64) -> std::io::Result<(u64, u64)> {
        use std::io::{Seek, SeekFrom};
        let mut at = pos;
        self.r.seek(SeekFrom::Start(pos))?;
        if pos > 0 {
            // Back up one byte: a line starts at `pos` if the byte before it ends a line.
            self.r.seek(SeekFrom::Start(pos - 1))?;
            at = pos - 1;
            let n = coupler_atlas::read_line_bounded(
                &mut self.r,
                &mut self.buf,
                coupler_atlas::MAX_INDEX_LINE,
            )?;
            at += n as u64;
        }
        loop {
            let n = coupler_atlas::read_line_bounded(
                &mut self.r,
                &mut self.buf,
                coupler_atlas::MAX_INDEX_LINE,
            )?;
            if n == 0 {
                return Ok((u64::MAX, at));
            }
            if let Some(id) = curve_id(&self.buf) {
                return Ok((id, at));
            }
            at += n as u64;
        }
    }

    /// The text of curve `id`'s line, by bisection over the file's `len` bytes; `None`
    /// if there is no such line where id order puts it.
    fn bisect(&mut self, id: u64, len: u64) -> std::io::Result<Option<&str>> {
        // The least offset whose next curve line has an id >= `id`.
        let (mut lo, mut hi) = (0u64, len);
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            let (found, start) = self.next_curve(mid)?;
            if found < id {
                lo = start.max(mid) + 1;
            } else {
                hi = mid;
            }
        }
        let (found, _) = self.next_curve(lo)?;
        if found != id {
            return Ok(None);
        }
        let line = std::str::from_utf8(&self.buf).map_err(|e| {
            std::io::Error::new(std::io::ErrorKind::InvalidData, format!("curve {id}: {e}"))
        })?;
        Ok(Some(line.trim_end().trim_end_matches(',')))
    }
}

/// The id of an index curve line (`{"id":N,…`).
fn curve_id(line: &[u8]) -> Option<u64> {
    let rest = line.strip_prefix(b"{\"id\":")?;
    let digits = rest.iter().take_while(|c| c.is_ascii_digit()).count();
    std::str::from_utf8(&rest[..digits]).ok()?.parse().ok()
}

/// [`page_refs`] by streaming every curve line of the index (its lines not in id order).
fn stream_page_refs(
    path: &Path,
    file: std::fs::File,
    ids: &[u64],
) -> Result<Vec<Option<coupler_atlas::PageRef>>> {
    let mut want: Vec<u64> = ids.to_vec();
    want.sort_unstable();
    want.dedup();
    let mut found: std::collections::HashMap<u64, Option<coupler_atlas::PageRef>> =
        std::collections::HashMap::new();
    for line in std::io::BufReader::new(file).lines() {
        let line = line.with_context(|| format!("reading {}", path.display()))?;
        let Some(id) = curve_id(line.as_bytes()) else {
            continue;
        };
        if want.binary_search(&id).is_err() {
            continue;
        }
        let json = line.trim_end().trim_end_matches(',');
        let c: IndexCurve = serde_json::from_str(json)
            .with_context(|| format!("{}: curve {id}", path.display()))?;
        found.insert(id, c.page);
        if found.len() == want.len() {
            break;
        }
    }
    Ok(ids
        .iter()
        .map(|id| found.get(id).cloned().flatten())
        .collect())
}

fn circuit_name(c: Circuit) -> &'static str {
    match c {
        Circuit::Open => "open",
        Circuit::Crossed => "crossed",
    }
}

fn g(x: f64) -> String {
    // Six significant digits, no trailing zeros, a real minus sign (U+2212: table text).
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    if x.abs() < 1e-4 {
        return format!("{x:.5e}");
    }
    let digits = (5 - x.abs().log10().floor() as i32).clamp(0, 12) as usize;
    let s = format!("{x:.digits$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" { "0".into() } else { minus_sign(s) }
}

/// Five significant digits; scientific below 1e-3 (for the picture's heading).
fn short(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        format!("{x}")
    } else if x.abs() < 1e-3 {
        format!("{x:.2e}")
    } else {
        let digits = (4 - x.abs().log10().floor() as i32).clamp(0, 12) as usize;
        let s = format!("{x:.digits$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        if s == "-0" { "0".into() } else { s }
    }
}

/// The placement as JSON: a four-bar's pivots O2, O4 and lengths crank, coupler, rocker,
/// ground; a geared five-bar's pivots O2, O5, lengths L1 … L5 (L2 the input crank) and
/// its gears (ratio λ, phase φ in degrees, the mirror's for a reflected match), all in
/// user units and the user's frame.
fn placement_json(p: &Placement) -> Value {
    let mut v = json!({
        "mirrored": p.mirrored,
        "scale": p.scale,
        "rotation_deg": p.rotation_deg,
        "o2": p.o2,
    });
    v[pivot_name(&p.linkage).to_lowercase()] = json!(p.pivot);
    for (name, x) in p.lengths() {
        v[name.to_lowercase()] = json!(x);
    }
    if let Linkage::GearedFiveBar(l) = &p.linkage {
        v["ratio"] = json!(l.ratio);
        v["phase_deg"] = json!(l.phase);
    }
    v["point"] = json!(p.point);
    v["circuit"] = json!(circuit_name(p.circuit));
    v["crank_deg"] = json!(crank_interval(p));
    v
}

/// `"O4"` (a four-bar's rocker pivot) or `"O5"` (a geared five-bar's second crank's).
fn pivot_name(l: &Linkage) -> &'static str {
    match l {
        Linkage::FourBar(_) => "O4",
        Linkage::GearedFiveBar(_) => "O5",
    }
}

/// The curve as JSON; its linkage as in index.json (a four-bar's
/// `{coupler, rocker, ground}`, a geared five-bar's `{l1, l3, l4, l5, ratio, phase}`).
fn curve_json(c: &CouplerCurve) -> Value {
    json!({
        "linkage": c.linkage,
        "point": {"u": c.point.u, "v": c.point.v},
        "circuit": circuit_name(c.circuit),
    })
}

/// The linkage's dimensions in crank units with `num` formatting the numbers: a
/// four-bar's `A=… B=… C=…`, a geared five-bar's `L1=… L3=… L4=… L5=… λ=… φ=…°`.
fn linkage_text(l: &Linkage, num: fn(f64) -> String) -> String {
    match l {
        Linkage::FourBar(l) => format!(
            "A={} B={} C={}",
            num(l.coupler),
            num(l.rocker),
            num(l.ground)
        ),
        Linkage::GearedFiveBar(l) => format!(
            "L1={} L3={} L4={} L5={} λ={} φ={}°",
            num(l.l1),
            num(l.l3),
            num(l.l4),
            num(l.l5),
            minus_sign(l.ratio.to_string()),
            minus_sign(num(l.phase))
        ),
    }
}

fn error_json(fit: &CurveFit, size: f64) -> Value {
    json!({
        "rms": fit.rms, "max": fit.max,
        "rms_pct": 100.0 * fit.rms / size, "max_pct": 100.0 * fit.max / size,
    })
}

/// The crank angles at the first and last point as reported: the first in (−P/2, P/2]
/// (P the mechanism's period: 360° for a four-bar, 720° for a geared five-bar of ratio
/// p/2, where θ and θ + 360° are different points), the last the first plus the signed
/// travel.
fn crank_interval(p: &Placement) -> [f64; 2] {
    use coupler_atlas::Mechanism as _;
    let period = p.linkage.period_deg();
    let [a, b] = p.crank_deg;
    let mut first = a.rem_euclid(period);
    if first > 0.5 * period {
        first -= period;
    }
    [first, first + (b - a)]
}

/// The lines of one placement in the table.
fn placement_lines(p: &Placement, closed: bool, timed_rate: Option<f64>) -> Vec<String> {
    let crank = crank_interval(p);
    let mut v = vec![
        format!(
            "transform: scale {} per crank length, rotation {}°, O2 at ({}, {}){}",
            g(p.scale),
            g(p.rotation_deg),
            g(p.o2[0]),
            g(p.o2[1]),
            match (p.mirrored, &p.linkage) {
                (false, _) => "",
                (true, Linkage::FourBar(_)) => ", reflected (reported as the mirror four-bar)",
                (true, Linkage::GearedFiveBar(_)) =>
                    ", reflected (reported as the mirror five-bar: phase negated)",
            }
        ),
        format!(
            "{} in your frame: O2 ({}, {}), {} ({}, {}); {}{}; coupler point (u, v) = ({}, {}), {} circuit",
            match p.linkage {
                Linkage::FourBar(_) => "four-bar",
                Linkage::GearedFiveBar(_) => "geared five-bar",
            },
            g(p.o2[0]),
            g(p.o2[1]),
            pivot_name(&p.linkage),
            g(p.pivot[0]),
            g(p.pivot[1]),
            p.lengths()
                .iter()
                .map(|(n, x)| format!("{n} {}", g(*x)))
                .collect::<Vec<_>>()
                .join(", "),
            match &p.linkage {
                Linkage::FourBar(_) => String::new(),
                Linkage::GearedFiveBar(l) => format!(
                    "; gears λ = {}, φ = {}°",
                    minus_sign(l.ratio.to_string()),
                    minus_sign(g(l.phase))
                ),
            },
            g(p.point[0]),
            g(p.point[1]),
            circuit_name(p.circuit)
        ),
    ];
    let travel = crank[1] - crank[0];
    v.push(if closed {
        format!(
            "crank: {}° at the first point, {} {}",
            g(crank[0]),
            {
                use coupler_atlas::Mechanism as _;
                match p.linkage.period_deg() {
                    360.0 => "a full turn".to_string(),
                    x => format!("a full period of {}°", g(x)),
                }
            },
            if travel >= 0.0 {
                "counter-clockwise"
            } else {
                "clockwise"
            }
        )
    } else {
        format!(
            "crank interval: {}° → {}° (travel {}°, {})",
            g(crank[0]),
            g(crank[1]),
            g(travel),
            if travel >= 0.0 {
                "counter-clockwise"
            } else {
                "clockwise"
            }
        )
    });
    if let Some(r) = timed_rate {
        v.push(format!(
            "timing: crank rate {} (per unit of the target's timing)",
            g(r)
        ));
    }
    v
}

fn warnings(r: &Refined) -> Vec<String> {
    let mut w: Vec<String> = Vec::new();
    let geared = matches!(r.curve.linkage, Linkage::GearedFiveBar(_));
    if r.input_does_not_turn {
        w.push(
            if geared {
                "the input no longer turns fully: the dyad does not close all round"
            } else {
                "no longer a crank-rocker: the crank does not turn fully"
            }
            .into(),
        );
    }
    if r.crossed_change_point {
        w.push(
            if geared {
                "crossed a change point (Ting class changed, or Class III)"
            } else {
                "crossed a change point (Grashof type changed)"
            }
            .into(),
        );
    }
    if r.proportion > MAX_PROPORTION {
        w.push(format!(
            "ran off the atlas's proportions: longest length {}× the shortest link \
             (above {}×): a degenerate limit, not a buildable fit",
            g(r.proportion),
            g(MAX_PROPORTION)
        ));
    }
    w
}

pub fn run(args: Args) -> Result<ExitCode> {
    let t0 = Instant::now();
    let target = read_target(&args)?;
    if let Some(j) = args.jobs {
        if j == 0 {
            return Err(UsageError("--jobs must be at least 1".into()).into());
        }
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.jobs.unwrap_or(0))
        .build()
        .context("starting worker threads")?;
    let atlas = load_shapes(&args.atlas)?;
    check_timing(
        &target,
        &atlas,
        &args.target.display().to_string(),
        &args.atlas,
    )?;
    let t_load = t0.elapsed();
    let options = MatchOptions {
        allow_mirror: args.mirror,
        top: args.top as usize,
        candidates: args
            .candidates
            .map_or(MatchOptions::DEFAULT.candidates, |c| c as usize),
        open_candidates: args
            .candidates
            .map_or(MatchOptions::DEFAULT.open_candidates, |c| c as usize),
        open_linkages: args
            .linkages
            .map_or(MatchOptions::DEFAULT.open_linkages, |n| n as usize),
        open_lattice: if args.full_scan {
            LatticeSearch::FULL
        } else {
            MatchOptions::DEFAULT.open_lattice
        },
        ..MatchOptions::DEFAULT
    };
    let size = target.size();
    type Found = (Vec<Match>, Vec<Option<Refined>>, Option<Scanned>);
    let (matches, refined, scanned): Found = pool.install(|| {
        let (c, scanned) = coarse(&target, &atlas, &options).map_err(|e| match e.downcast() {
            Ok(MatchError::Sidecar(e)) => atlas.bad(e),
            Ok(e) => UsageError(format!("target {}: {e}", args.target.display())).into(),
            Err(e) => e,
        })?;
        let m = rank_candidates(&target, c, &options);
        let r = if args.refine {
            m.par_iter()
                .map(|m| refine(&target, m, &options.fit))
                .collect()
        } else {
            vec![None; m.len()]
        };
        Ok::<_, anyhow::Error>((m, r, scanned))
    })?;
    let t_search = t0.elapsed();
    let ids: Vec<u64> = matches.iter().map(|m| m.id).collect();
    let pages = page_refs(&args.atlas, &ids)?;
    let elapsed = t0.elapsed();

    if let Some(best) = matches.first() {
        let (curve, fit, label) = match refined.first().cloned().flatten() {
            Some(r) => (r.curve, r.fit, format!("refined from curve {}", best.id)),
            None => (best.curve, best.fit.clone(), format!("curve {}", best.id)),
        };
        let text = OverlayText {
            title: format!(
                "{}: {} {}, point ({}, {}), {} circuit",
                args.target.display(),
                label,
                linkage_text(&curve.linkage, short),
                short(curve.point.u),
                short(curve.point.v),
                circuit_name(curve.circuit)
            ),
            detail: format!(
                "{} target, {} points, size {}: RMS error {} ({} %), max {} ({} %){}",
                if target.is_closed() { "closed" } else { "open" },
                target.len(),
                short(size),
                short(fit.rms),
                short(100.0 * fit.rms / size),
                short(fit.max),
                short(100.0 * fit.max / size),
                if fit.mirrored { "; reflected" } else { "" }
            ),
        };
        for (path, svg) in [(&args.png, false), (&args.svg, true)] {
            let Some(path) = path else { continue };
            write_overlay(path, svg, &target, &curve, &fit, &text)?;
        }
    }

    if args.format == "json" {
        let hits: Vec<Value> = matches
            .iter()
            .zip(&refined)
            .zip(&pages)
            .enumerate()
            .map(|(k, ((m, r), page))| {
                let mut v = json!({
                    "rank": k + 1,
                    "id": m.id,
                    "page": page,
                    "curve": curve_json(&m.curve),
                    "transform": {"a": m.fit.a, "b": m.fit.b, "scale": m.placement.scale,
                        "rotation_deg": m.placement.rotation_deg, "mirrored": m.fit.mirrored},
                    "placement": placement_json(&m.placement),
                    "crank_deg": crank_interval(&m.placement),
                    "timing_rate": m.fit.timing_rate,
                    "error": error_json(&m.fit, size),
                });
                if let Some(r) = r {
                    v["refined"] = json!({
                        "curve": curve_json(&r.curve),
                        "class": r.class.code(),
                        "placement": placement_json(&r.placement),
                        "error": error_json(&r.fit, size),
                        "warnings": warnings(r),
                        "proportion": r.proportion,
                        "iterations": r.iterations,
                    });
                }
                v
            })
            .collect();
        let out = json!({
            "target": {"file": args.target.display().to_string(), "points": target.len(),
                "closed": target.is_closed(), "timed": target.timing().is_timed(), "size": size},
            "atlas": {"dir": args.atlas.display().to_string(), "curves": atlas.view().len()},
            "matches": hits,
            "seconds": {"load": t_load.as_secs_f64(), "search": (t_search - t_load).as_secs_f64(), "total": elapsed.as_secs_f64()},
        });
        outln!("{}", serde_json::to_string_pretty(&out)?)?;
        return Ok(ExitCode::SUCCESS);
    }

    outln!(
        "target {}: {} {}, {} points, size {} (its diameter); atlas {}: {} curves",
        args.target.display(),
        if target.is_closed() { "closed" } else { "open" },
        if target.timing().is_timed() {
            "timed"
        } else {
            "untimed"
        },
        target.len(),
        g(size),
        args.atlas.display(),
        atlas.view().len()
    )?;
    for (k, ((m, r), page)) in matches.iter().zip(&refined).zip(&pages).enumerate() {
        let c = &m.curve;
        outln!()?;
        outln!(
            "#{} curve {}: {}, point ({}, {}), {} circuit{}",
            k + 1,
            m.id,
            linkage_text(&c.linkage, g),
            g(c.point.u),
            g(c.point.v),
            circuit_name(c.circuit),
            match page {
                Some(p) => format!(
                    "; {} at [{}, {}, {}, {}] px",
                    p.file, p.bbox_px[0], p.bbox_px[1], p.bbox_px[2], p.bbox_px[3]
                ),
                None => String::new(),
            }
        )?;
        outln!(
            "   error: RMS {} ({} %), max {} ({} %)",
            g(m.fit.rms),
            g(m.rms_pct),
            g(m.fit.max),
            g(m.max_pct)
        )?;
        for l in placement_lines(&m.placement, target.is_closed(), m.fit.timing_rate) {
            outln!("   {l}")?;
        }
        if let Some(r) = r {
            outln!(
                "   refined: {}, point ({}, {}), class {}: RMS {} ({} %), max {} ({} %){}",
                linkage_text(&r.curve.linkage, g),
                g(r.curve.point.u),
                g(r.curve.point.v),
                r.class.code(),
                g(r.fit.rms),
                g(r.rms_pct),
                g(r.fit.max),
                g(r.max_pct),
                warnings(r)
                    .iter()
                    .map(|w| format!("; WARNING: {w}"))
                    .collect::<String>()
            )?;
            for l in placement_lines(&r.placement, target.is_closed(), r.fit.timing_rate) {
                outln!("      {l}")?;
            }
        }
    }
    if matches.is_empty() {
        outln!("no match: no curve of the atlas could be fitted to the target")?;
    }
    // The curves searched: every curve of the atlas, or those of the linkages scanned.
    let searched = match scanned {
        None => format!("{} curves", atlas.view().len()),
        Some(s) => format!(
            "{} of the atlas's {} curves ({}: {} of its {} linkages)",
            s.curves,
            atlas.view().len(),
            s.how,
            s.linkages,
            s.of
        ),
    };
    eprintln!(
        "searched {searched} in {:.3} s (load {:.3} s, search {:.3} s)",
        elapsed.as_secs_f64(),
        t_load.as_secs_f64(),
        (t_search - t_load).as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}

fn write_overlay(
    path: &Path,
    svg: bool,
    target: &Target,
    curve: &CouplerCurve,
    fit: &CurveFit,
    text: &OverlayText,
) -> Result<()> {
    let d = coupler_atlas::shape::overlay(target, curve, fit, text)
        .context("the matched curve cannot be drawn")?;
    let bytes = if svg {
        let mut page = SvgPage::new(OVERLAY_SIZE_PT[0], OVERLAY_SIZE_PT[1]);
        draw(&d, &mut page);
        page.finish().into_bytes()
    } else {
        let dpi = 150.0;
        let px = |pt: f64| (pt * dpi / 72.0).round() as u32;
        let mut page = RasterPage::new(px(OVERLAY_SIZE_PT[0]), px(OVERLAY_SIZE_PT[1]), dpi)
            .context("overlay size")?;
        draw(&d, &mut page);
        let mut v = Vec::new();
        page.finish_png(&mut v)
            .context("encoding the overlay PNG")?;
        v
    };
    let tmp: PathBuf = {
        let mut s = path.as_os_str().to_owned();
        s.push(format!(".tmp-{}", std::process::id()));
        s.into()
    };
    std::fs::write(&tmp, &bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
