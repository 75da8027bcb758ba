//! `coupler-atlas search INDEX [filters] [--sort] [--limit] [--format table|json|csv]`

use super::UsageError;
use anyhow::Result;
use coupler_atlas::{
    ArcRow, Circuit, CouplerPoint, CrankTable, DashPattern, FeatureTolerances, FourBar, GearRatio,
    GearedFiveBar, Linkage, LinkageClass, Mechanism, SegmentRow, minus_sign, pseudo_arcs,
    straight_segments, transmission_margin, window_transmission,
};
use coupler_atlas::{DEFAULT_RADIUS_TOL_PCT, Hit, Query, SearchTable, SortKey, SpanFilter};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The index to search: an atlas folder or its index.json.
    index: PathBuf,
    /// A straight segment of at least SPAN crank degrees, straightness ε_S at most TOL %.
    #[arg(long, value_name = "SPAN[:TOL]")]
    straight: Option<SpanFilter>,
    /// A pseudo-arc of at least SPAN crank degrees, radial deviation at most TOL %.
    #[arg(long, value_name = "SPAN[:TOL]")]
    arc: Option<SpanFilter>,
    /// Two straight segments, or two arcs of equal radius (--radius-tol) and the same
    /// concave side (each passing --straight / --arc when given).
    #[arg(long)]
    double_dwell: bool,
    /// Relative tolerance on the radii of a double dwell's two arcs, percent.
    #[arg(long, default_value_t = DEFAULT_RADIUS_TOL_PCT)]
    radius_tol: f64,
    /// Transmission angle within [DEG, 180 − DEG] over the whole revolution (0 ≤ DEG ≤ 90).
    #[arg(long, value_name = "DEG", value_parser = parse_min_transmission)]
    min_transmission: Option<f64>,
    /// The matching straight segments and arcs keep the transmission angle within
    /// [DEG, 180 − DEG] over their own window (0 ≤ DEG ≤ 90); alone, asks for such a
    /// segment or arc.
    #[arg(long, value_name = "DEG", value_parser = parse_min_transmission)]
    window_transmission: Option<f64>,
    /// Barker class, e.g. GCRR.
    #[arg(long)]
    class: Option<String>,
    /// The linkage: a four-bar's A,B,C (coupler, rocker, ground), or a geared five-bar's
    /// L1,L3,L4,L5,RATIO,PHASE (RATIO as p or p/q, PHASE in degrees).
    #[arg(
        long,
        value_name = "A,B,C|L1,L3,L4,L5,RATIO,PHASE",
        allow_hyphen_values = true
    )]
    linkage: Option<String>,
    /// Circuit: open or crossed.
    #[arg(long, value_parser = ["open", "crossed"])]
    circuit: Option<String>,
    /// Symmetric curves only.
    #[arg(long)]
    symmetric: bool,
    /// Also list curves of coupler points at a pin (the crank pin's circle, the rocker
    /// pin's arc), left out by default.
    #[arg(long)]
    include_trivial: bool,
    /// Arcs of radius from MIN to MAX (crank units); implies an arc.
    #[arg(long, value_name = "MIN:MAX", value_parser = parse_range)]
    radius: Option<[f64; 2]>,
    /// Arcs turning at least DEG about their centre; implies an arc.
    #[arg(long, value_name = "DEG", value_parser = parse_nonnegative)]
    min_turn: Option<f64>,
    /// Straight segments with velocity variation ε_V at most PCT %; implies a segment.
    #[arg(long, value_name = "PCT", value_parser = parse_nonnegative)]
    max_ev: Option<f64>,
    /// Order: id, straight, straightness, arc, deviation, transmission (whole turn),
    /// window-transmission (over a matching feature's window), turn, radius, velocity.
    #[arg(long, default_value = "id")]
    sort: SortKey,
    /// At most N hits (0: all).
    #[arg(long, default_value_t = 20)]
    limit: usize,
    /// Output format.
    #[arg(long, default_value = "table", value_parser = ["table", "json", "csv"])]
    format: String,
    /// Do not read or write the search cache (INDEX.search).
    #[arg(long)]
    no_cache: bool,
}

fn parse_nonnegative(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        _ => Err(format!("expected a finite number ≥ 0, got `{s}`")),
    }
}

fn parse_range(s: &str) -> Result<[f64; 2], String> {
    let (a, b) = s
        .split_once(':')
        .ok_or_else(|| format!("expected MIN:MAX, got `{s}`"))?;
    let (a, b) = (parse_nonnegative(a)?, parse_nonnegative(b)?);
    if a <= b {
        Ok([a, b])
    } else {
        Err(format!("MIN must not exceed MAX, got `{s}`"))
    }
}

fn parse_min_transmission(s: &str) -> Result<f64, String> {
    let x: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("expected degrees, got `{s}`"))?;
    if x.is_finite() && (0.0..=90.0).contains(&x) {
        Ok(x)
    } else {
        Err(format!(
            "must be from 0 to 90 degrees (the band is [DEG, 180 − DEG]), got {s}"
        ))
    }
}

/// `index` opened for searching (its columns mapped, or its cache, or the index parsed:
/// `coupler_atlas::load`): a usage error when the index cannot be read or is not an index
/// (a page set is refused here: `dwell` needs an index).
pub(super) fn load(index: &Path, use_cache: bool) -> Result<coupler_atlas::Loaded> {
    let index = match resolve(index)? {
        Searched::Index(p) => p,
        Searched::PageSet(p) => {
            return Err(UsageError(format!(
                "{}: a page set's measures (curves.json) have no feature windows; give an atlas's index.json (or its folder)",
                p.display()
            ))
            .into());
        }
    };
    open(&index, use_cache)
}

/// The index at `index` opened for searching (see [`load`]).
fn open(index: &Path, use_cache: bool) -> Result<coupler_atlas::Loaded> {
    coupler_atlas::load(index, use_cache).map_err(|e| {
        let mut m = e.to_string().trim_end().to_string();
        if m.contains("not a coupler-atlas index") {
            // Name the file to search where there is one beside it.
            let hint = ["index.json", "curves.json"]
                .iter()
                .map(|n| index.with_file_name(n))
                .find(|p| p.is_file() && *p != index);
            m += &match hint {
                Some(p) => format!(" (search {} or its folder)", p.display()),
                None => " (search reads an atlas's index.json, a page set's curves.json, or the folder holding either)".into(),
            };
        }
        UsageError(m).into()
    })
}

/// The curve `id` of `index` as a table of one row (empty if the index has no such
/// curve), read through the columns or the cache like a search.
pub(super) fn load_curve(index: &Path, id: u64) -> Result<SearchTable> {
    let mut loaded = load(index, true)?;
    let table = loaded.find(id).map_err(|e| UsageError(e.to_string()))?;
    note_columns(&loaded);
    Ok(table)
}

/// Says on stderr why a columns file beside the index was not used (the answer then
/// comes from the cache or the index).
fn note_columns(loaded: &coupler_atlas::Loaded) {
    if let Some(n) = loaded.note() {
        eprintln!(
            "note: {n}; answered from the {} instead",
            loaded.source().name()
        );
    }
}

/// What `search` reads: an atlas's index, or a page set's `curves.json`.
enum Searched {
    Index(PathBuf),
    PageSet(PathBuf),
}

/// A page set's `curves.json` is read whole: at most this many bytes (a page set is a
/// list of named curves, kilobytes each).
const MAX_PAGE_SET_BYTES: u64 = 64 << 20;

/// An atlas folder stands for its `index.json` (or, for a page set's folder, its
/// `curves.json`); a page set's `curves.json` is searched as such; the atlas's other JSON
/// files are refused with a hint naming the index (they would read as an empty index).
fn resolve(path: &Path) -> Result<Searched, UsageError> {
    if path.is_dir() {
        let (index, curves) = (path.join("index.json"), path.join("curves.json"));
        return if index.is_file() {
            Ok(Searched::Index(index))
        } else if curves.is_file() {
            Ok(Searched::PageSet(curves))
        } else {
            Err(UsageError(format!(
                "{}: an atlas folder holds index.json, and this one has none (nor a page set's curves.json: was it generated with `generate`?)",
                path.display()
            )))
        };
    }
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    let sibling = path.with_file_name("index.json");
    match name {
        "manifest.json" => Err(UsageError(format!(
            "{}: this is the atlas's manifest (file list and checksums), not its index: search {} (or the folder)",
            path.display(),
            if sibling.is_file() || !path.with_file_name("curves.json").is_file() {
                sibling.display().to_string()
            } else {
                path.with_file_name("curves.json").display().to_string()
            }
        ))),
        "curves.json" => Ok(Searched::PageSet(path.to_path_buf())),
        _ => {
            // A page set's measures under another name are still a page set.
            use std::io::Read;
            let mut head = String::new();
            if let Ok(f) = std::fs::File::open(path) {
                let _ = f.take(4096).read_to_string(&mut head);
            }
            if coupler_atlas::is_page_set(&head) {
                Ok(Searched::PageSet(path.to_path_buf()))
            } else {
                Ok(Searched::Index(path.to_path_buf()))
            }
        }
    }
}

/// The search table of a page set's `curves.json`, its straight runs re-measured at the
/// query's `--straight` tolerance when it is not one of the three the file holds.
fn load_page_set(path: &Path, q: &Query) -> Result<SearchTable> {
    let size = std::fs::metadata(path)
        .map_err(|e| UsageError(format!("{}: {e}", path.display())))?
        .len();
    if size > MAX_PAGE_SET_BYTES {
        return Err(UsageError(format!(
            "{}: {size} bytes is more than a page set's curves.json holds (at most {MAX_PAGE_SET_BYTES})",
            path.display()
        ))
        .into());
    }
    let text = std::fs::read_to_string(path)
        .map_err(|e| UsageError(format!("{}: {e}", path.display())))?;
    let tol = q
        .straight
        .map(|f| f.max_error_pct)
        .filter(|t| t.is_finite());
    SearchTable::from_page_set(&text, tol)
        .map_err(|e| UsageError(format!("{}: {e}", path.display())).into())
}

/// A feature as JSON with `"index"`: its 1-based position in the curve's list (what
/// `dwell --arc K` / `--line K` takes).
fn numbered<T: serde::Serialize>(x: &T, index: usize) -> serde_json::Value {
    let mut v = serde_json::json!({ "index": index });
    if let (Some(o), serde_json::Value::Object(f)) = (
        v.as_object_mut(),
        serde_json::to_value(x).unwrap_or_default(),
    ) {
        o.extend(f);
    }
    v
}

/// `A,B,C` (a four-bar) or `L1,L3,L4,L5,RATIO,PHASE` (a geared five-bar).
fn parse_linkage(s: &str) -> Result<Linkage, UsageError> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let lengths = |xs: &[&str]| -> Result<Vec<f64>, UsageError> {
        xs.iter()
            .map(|x| super::parse_length(x))
            .collect::<Result<_, _>>()
            .map_err(|e| UsageError(format!("--linkage: {e}")))
    };
    match parts.as_slice() {
        [_, _, _] => {
            let l = lengths(&parts)?;
            FourBar::new(l[0], l[1], l[2])
                .map(Linkage::FourBar)
                .map_err(|e| UsageError(format!("--linkage: {e}")))
        }
        [_, _, _, _, ratio, phase] => {
            let l = lengths(&parts[..4])?;
            let ratio: GearRatio = ratio
                .parse()
                .map_err(|e| UsageError(format!("--linkage: {e}")))?;
            let phase = super::parse_number(phase)
                .map_err(|e| UsageError(format!("--linkage: phase: {e}")))?;
            GearedFiveBar::new(l[0], l[1], l[2], l[3], ratio, phase)
                .map(Linkage::GearedFiveBar)
                .map_err(|e| UsageError(format!("--linkage: {e}")))
        }
        _ => Err(UsageError(format!(
            "--linkage expects A,B,C (a four-bar) or L1,L3,L4,L5,RATIO,PHASE (a geared five-bar), got `{s}`"
        ))),
    }
}

/// How the linkage is printed in the table and CSV: a four-bar's three lengths, or a
/// geared five-bar's six dimensions (an atlas holds one mechanism: the table's first
/// row decides).
#[derive(Clone, Copy, PartialEq, Eq)]
enum LinkageColumns {
    FourBar,
    Geared,
}

impl LinkageColumns {
    fn of(table: &SearchTable) -> LinkageColumns {
        match table.rows.first().map(|r| &r.linkage) {
            Some(Linkage::GearedFiveBar(_)) => LinkageColumns::Geared,
            _ => LinkageColumns::FourBar,
        }
    }

    /// The CSV header's linkage columns.
    fn csv_header(self) -> &'static str {
        match self {
            LinkageColumns::FourBar => "coupler,rocker,ground",
            LinkageColumns::Geared => "l1,l3,l4,l5,ratio,phase",
        }
    }

    /// A row's linkage cells for the CSV (empty cells for a linkage of the other kind).
    fn csv_cells(self, l: &Linkage) -> String {
        match (self, l) {
            (LinkageColumns::FourBar, Linkage::FourBar(l)) => {
                format!("{},{},{}", l.coupler, l.rocker, l.ground)
            }
            (LinkageColumns::Geared, Linkage::GearedFiveBar(g)) => format!(
                "{},{},{},{},{},{}",
                g.l1, g.l3, g.l4, g.l5, g.ratio, g.phase
            ),
            (LinkageColumns::FourBar, _) => ",,".into(),
            (LinkageColumns::Geared, _) => ",,,,,".into(),
        }
    }
}

pub fn run(args: Args) -> Result<ExitCode> {
    let stdout = std::io::stdout();
    let mut w = std::io::BufWriter::new(stdout.lock());
    run_to(args, &mut w, true)?;
    Ok(ExitCode::SUCCESS)
}

/// What a search found: the matching curves and the curves searched.
pub struct Found {
    /// Curves that match the query (all of them, not only the `--limit` shown).
    pub total: usize,
    /// Curves in the index searched.
    pub curves: usize,
}

/// The query `args` describe (the index aside).
pub fn query_of(args: &Args) -> Result<Query> {
    let class = match &args.class {
        None => None,
        Some(c) => Some(
            LinkageClass::ALL
                .iter()
                .copied()
                .find(|k| k.code().eq_ignore_ascii_case(c))
                .ok_or_else(|| UsageError(format!("unknown class `{c}`")))?,
        ),
    };
    Ok(Query {
        straight: args.straight,
        arc: args.arc,
        double_dwell: args.double_dwell,
        radius_tol_pct: args.radius_tol,
        min_transmission_deg: args.min_transmission,
        min_window_transmission_deg: args.window_transmission,
        class,
        linkage: args.linkage.as_deref().map(parse_linkage).transpose()?,
        circuit: args
            .circuit
            .as_deref()
            .map(|c| c.parse::<Circuit>())
            .transpose()
            .map_err(UsageError)?,
        symmetric: args.symmetric,
        include_trivial: args.include_trivial,
        radius: args.radius,
        min_turn_deg: args.min_turn,
        max_velocity_variation_pct: args.max_ev,
        sort: args.sort,
        limit: args.limit,
    })
}

/// [`run`], writing the results to `w`, and the closing summary line to stderr only with
/// `summary` (`bench search` runs queries without it).
pub fn run_to(args: Args, w: &mut dyn Write, summary: bool) -> Result<Found> {
    let query = query_of(&args)?;
    let t0 = Instant::now();
    let searched = resolve(&args.index)?;
    let (mut loaded, extracted) = match &searched {
        Searched::Index(index) => (open(index, !args.no_cache)?, extraction_tolerances(index)),
        Searched::PageSet(curves) => {
            if query.arc.is_some() || query.double_dwell {
                eprintln!(
                    "note: a page set's curves are measured by their straight runs only: --arc and --double-dwell match none"
                );
            }
            (
                coupler_atlas::Loaded::from_table(load_page_set(curves, &query)?),
                None,
            )
        }
    };
    let t1 = Instant::now();
    let curves = loaded.curves();
    let tight = extracted.and_then(|t| tighter(&query, &t));
    // Only the curves the query can show are read out of the index's columns (or
    // table): the query's best `--limit`, or every candidate of a refinement.
    let select = |loaded: &mut coupler_atlas::Loaded, q: &Query| {
        loaded.select(q).map_err(|e| UsageError(e.to_string()))
    };
    let (selected, mut total) = select(
        &mut loaded,
        &tight.map_or(query.clone(), |_| candidates(&query)),
    )?;
    note_columns(&loaded);
    let source = match searched {
        Searched::Index(_) => loaded.source().name(),
        Searched::PageSet(_) => "curves.json",
    };
    let refined;
    let table = match tight {
        Some(t) => {
            // Only an index has extraction tolerances, so only an index is refined.
            let dash = match &searched {
                Searched::Index(index) => extraction_dash(index),
                Searched::PageSet(_) => DashPattern::default(),
            };
            let (r, n) = refine(&selected, &query, &t, &dash)?;
            eprintln!(
                "refined: the query is tighter than the index's extraction tolerance (straight {} %, arc {} %), so its {n} candidate curve(s) were re-measured at straight {} %, arc {} % in {:.3} s",
                extracted.map_or(f64::NAN, |e| e.straight_pct),
                extracted.map_or(f64::NAN, |e| e.arc_pct),
                t.straight_pct,
                t.arc_pct,
                t1.elapsed().as_secs_f64()
            );
            refined = r;
            &refined
        }
        None => &selected,
    };
    if let Some(e) = extracted {
        for (flag, f, stored) in [
            ("--straight", query.straight, e.straight_pct),
            ("--arc", query.arc, e.arc_pct),
        ] {
            if let Some(f) = f.filter(|f| f.max_error_pct > stored && f.max_error_pct.is_finite()) {
                eprintln!(
                    "note: {flag} tolerance {} % is looser than the index's extraction tolerance {stored} %: its features are the maximal windows within {stored} %, so a longer window within {} % is not found; generate with a looser [features] tolerance for that",
                    f.max_error_pct, f.max_error_pct
                );
            }
        }
    }
    let (hits, matched) = table.search_counted(&query);
    if tight.is_some() {
        // The re-measured candidates are all there: they count themselves.
        total = matched;
    }
    let t2 = Instant::now();
    let mut w = w;
    match args.format.as_str() {
        "json" => write_json(&mut w, table, &hits, total, curves)?,
        "csv" => write_csv(&mut w, table, &hits)?,
        _ => write_table(&mut w, table, &hits)?,
    }
    w.flush()?;
    if !summary {
        return Ok(Found { total, curves });
    }
    // Memory (Linux): the peak resident set counts the mapped files' pages the scan
    // touched (the page cache's, shared) with the process's own memory.
    let memory = match status_kb(["VmHWM:", "RssAnon:", "RssFile:"]) {
        Some([peak, own, mapped]) => format!(
            "; memory: peak resident {:.0} MB (now: own {:.1} MB, mapped files {:.0} MB)",
            peak as f64 / 1024.0,
            own as f64 / 1024.0,
            mapped as f64 / 1024.0
        ),
        None => String::new(),
    };
    eprintln!(
        "{} of {total} matching curve(s) shown (of {} curves){}; load {:.3} s (from {source}), search {:.3} s{memory}",
        hits.len(),
        curves,
        if hits.len() < total {
            "; --limit 0 shows all"
        } else {
            ""
        },
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64()
    );
    if let (0, Some(Linkage::GearedFiveBar(g))) = (total, &query.linkage) {
        // A geared atlas lists each curve once: a phase 360°/q from a listed one is that
        // phase's curves again (docs/spec-format.md, "Geared five-bar atlases").
        let apart = 360.0 / g.ratio.den() as f64;
        if g.ratio.den() > 1 {
            eprintln!(
                "note: --linkage: λ = {} at φ = {}° traces the same curves as every phase {}° apart ({}° …); a geared atlas lists them once, under the first such phase of its spec",
                minus_sign(g.ratio.to_string()),
                minus_sign(g.phase.to_string()),
                apart,
                g.phase.rem_euclid(apart)
            );
        }
    }
    Ok(Found { total, curves })
}

/// Fields of `/proc/self/status` in kB (e.g. `RssAnon:`), in the order asked; `None`
/// where there is no such file (not Linux) or a field is missing.
pub fn status_kb<const N: usize>(fields: [&str; N]) -> Option<[u64; N]> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let mut out = [0u64; N];
    for (o, name) in out.iter_mut().zip(fields) {
        let line = status.lines().find(|l| l.starts_with(name))?;
        *o = line[name.len()..].split_whitespace().next()?.parse().ok()?;
    }
    Some(out)
}

/// One matching feature of a hit, as the table and CSV print it.
struct FeatureCells {
    /// `line#K` or `arc#K`.
    name: String,
    start_deg: f64,
    span_deg: f64,
    /// ε_S or the radial deviation, percent.
    error_pct: f64,
    radius: Option<f64>,
    turn_deg: Option<f64>,
    velocity_variation_pct: Option<f64>,
    /// Transmission `[min, max]` over its window, degrees (NaN: unknown).
    transmission_deg: [f64; 2],
}

fn feature_cells(table: &SearchTable, h: &Hit) -> Vec<FeatureCells> {
    let r = &table.rows[h.row];
    let mut out: Vec<FeatureCells> = h
        .straight
        .iter()
        .map(|&k| {
            let s = &table.segments[k];
            FeatureCells {
                name: format!("line#{}", k - r.seg_start as usize + 1),
                start_deg: s.start_deg,
                span_deg: s.span_deg,
                error_pct: s.straightness_pct,
                radius: None,
                turn_deg: None,
                velocity_variation_pct: Some(s.velocity_variation_pct),
                transmission_deg: s.transmission_deg,
            }
        })
        .collect();
    out.extend(h.arcs.iter().map(|&k| {
        let a = &table.arcs[k];
        FeatureCells {
            name: format!("arc#{}", k - r.arc_start as usize + 1),
            start_deg: a.start_deg,
            span_deg: a.span_deg,
            error_pct: a.deviation_pct,
            radius: Some(a.radius),
            turn_deg: Some(a.turn_deg),
            velocity_variation_pct: None,
            transmission_deg: a.transmission_deg,
        }
    }));
    out
}

/// The page's number (the digits before the extension) and the centre of the curve's box.
fn page_spot(table: &SearchTable, r: &coupler_atlas::CurveRow) -> Option<(String, [f64; 2])> {
    let file = table.pages.get(r.page as usize)?;
    let stem = file.rsplit_once('.').map_or(file.as_str(), |(a, _)| a);
    let digits: String = stem
        .chars()
        .rev()
        .take_while(|c| c.is_ascii_digit())
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect();
    let page = digits
        .trim_start_matches('0')
        .parse::<u64>()
        .map_or_else(|_| file.clone(), |n| n.to_string());
    let b = r.page_bbox;
    Some((page, [0.5 * (b[0] + b[2]), 0.5 * (b[1] + b[3])]))
}

/// Fixed columns, ≤ 120 characters: one line per matching feature (the curve's columns on
/// its first), page number and the centre of the curve's box on it in pixels. A
/// four-bar's A, B, C are columns; a geared five-bar's six dimensions would not fit, so
/// its rows are grouped under a `# L1 … L3 … λ … φ …` line wherever the linkage changes.
/// Negative numbers carry a real minus sign (U+2212), as on the pages; the CSV and JSON
/// keep the hyphen-minus, for programs.
/// `μ±` is the whole turn's transmission margin `min(μmin, 180 − μmax)` (the largest DEG
/// that `--min-transmission` accepts), `μwin` the same over the feature's window.
fn write_table(w: &mut impl Write, table: &SearchTable, hits: &[Hit]) -> Result<()> {
    let columns = LinkageColumns::of(table);
    let abc = |[a, b, c]: [&str; 3]| match columns {
        LinkageColumns::FourBar => format!(" {a:>5} {b:>5} {c:>5}"),
        LinkageColumns::Geared => String::new(),
    };
    writeln!(
        w,
        "{:>7}{} {:>6} {:>6} {:>4} {:>5}  {:<6} {:>6} {:>6} {:>6} {:>7} {:>4} {:>5} {:>5} {:>4} spot px",
        "id",
        abc(["A", "B", "C"]),
        "u",
        "v",
        "circ",
        "μ±",
        "feat",
        "start",
        "span",
        "err%",
        "R",
        "turn",
        "εV%",
        "μwin",
        "page",
    )?;
    let opt = |x: Option<f64>, p: usize| x.map_or(String::from("-"), |x| format!("{x:.p$}"));
    let mut last: Option<Linkage> = None;
    for h in hits {
        let r = &table.rows[h.row];
        if columns == LinkageColumns::Geared && last != Some(r.linkage) {
            match &r.linkage {
                Linkage::GearedFiveBar(g) => writeln!(
                    w,
                    "# L1 {}  L3 {}  L4 {}  L5 {}  λ {}  φ {}°  (class {})",
                    g.l1,
                    g.l3,
                    g.l4,
                    g.l5,
                    minus_sign(g.ratio.to_string()),
                    minus_sign(g.phase.to_string()),
                    r.class.code()
                )?,
                l => writeln!(w, "# {l}")?,
            }
            last = Some(r.linkage);
        }
        let cells = feature_cells(table, h);
        let (page, spot) = match page_spot(table, r) {
            Some((p, c)) => (p, format!("{:.0},{:.0}", c[0], c[1])),
            None => ("-".into(), "-".into()),
        };
        let circ = if r.circuit == Circuit::Open {
            "open"
        } else {
            "crsd"
        };
        let lengths = match (columns, &r.linkage) {
            (LinkageColumns::FourBar, Linkage::FourBar(l)) => {
                [l.coupler, l.rocker, l.ground].map(|x| x.to_string())
            }
            _ => ["-", "-", "-"].map(String::from),
        };
        let head = format!(
            "{:>7}{} {:>6} {:>6} {:>4} {:>5}",
            r.id,
            abc([&lengths[0], &lengths[1], &lengths[2]]),
            minus_sign(r.point[0].to_string()),
            minus_sign(r.point[1].to_string()),
            circ,
            dash_if_nan(transmission_margin(r.transmission_deg))
        );
        if cells.is_empty() {
            writeln!(
                w,
                "{head}  {:<6} {:>6} {:>6} {:>6} {:>7} {:>4} {:>5} {:>5} {page:>4} {spot}",
                "-", "-", "-", "-", "-", "-", "-", "-"
            )?;
        }
        for (n, c) in cells.iter().enumerate() {
            let lead = if n == 0 {
                head.clone()
            } else {
                " ".repeat(head.chars().count())
            };
            let margin = transmission_margin(c.transmission_deg);
            writeln!(
                w,
                "{lead}  {:<6} {:>6.1} {:>6.1} {:>6.3} {:>7} {:>4} {:>5} {:>5} {page:>4} {spot}",
                c.name,
                c.start_deg,
                c.span_deg,
                c.error_pct,
                opt(c.radius, 3),
                c.turn_deg
                    .map_or(String::from("-"), |x| minus_sign(format!("{x:.0}"))),
                opt(c.velocity_variation_pct.filter(|x| !x.is_nan()), 1),
                dash_if_nan(margin),
            )?;
        }
    }
    Ok(())
}

/// `x` to one decimal, or `-` when unknown (NaN: a page set's curves have no
/// transmission range).
fn dash_if_nan(x: f64) -> String {
    if x.is_nan() {
        "-".into()
    } else {
        format!("{x:.1}")
    }
}

/// One line per matching feature (a curve without one: a line with empty feature
/// columns); RFC 4180 (no field needs quoting but the page file, which is quoted).
fn write_csv(w: &mut impl Write, table: &SearchTable, hits: &[Hit]) -> Result<()> {
    let columns = LinkageColumns::of(table);
    writeln!(
        w,
        "id,{},u,v,circuit,class,transmission_min_deg,transmission_max_deg,feature,start_deg,span_deg,error_pct,radius,turn_deg,velocity_variation_pct,window_transmission_min_deg,window_transmission_max_deg,page,page_x_px,page_y_px",
        columns.csv_header()
    )?;
    let opt = |x: Option<f64>| x.map_or(String::new(), |x| x.to_string());
    for h in hits {
        let r = &table.rows[h.row];
        let head = format!(
            "{},{},{},{},{},{},{},{}",
            r.id,
            columns.csv_cells(&r.linkage),
            r.point[0],
            r.point[1],
            r.circuit.name(),
            r.class.code(),
            r.transmission_deg[0],
            r.transmission_deg[1]
        );
        let page = match table.pages.get(r.page as usize) {
            Some(f) => {
                let b = r.page_bbox;
                format!(
                    "\"{}\",{},{}",
                    f.replace('"', "\"\""),
                    0.5 * (b[0] + b[2]),
                    0.5 * (b[1] + b[3])
                )
            }
            None => ",,".into(),
        };
        let cells = feature_cells(table, h);
        if cells.is_empty() {
            writeln!(w, "{head},,,,,,,,,,{page}")?;
        }
        for c in &cells {
            let [lo, hi] = c.transmission_deg.map(|x| x.is_finite().then_some(x));
            writeln!(
                w,
                "{head},{},{},{},{},{},{},{},{},{},{page}",
                c.name,
                c.start_deg,
                c.span_deg,
                c.error_pct,
                opt(c.radius),
                opt(c.turn_deg),
                opt(c.velocity_variation_pct),
                opt(lo),
                opt(hi)
            )?;
        }
    }
    Ok(())
}

/// `{"total", "shown", "curves", "hits": [...]}`: `total` curves matched, the first
/// `shown` of them (by the sort) are in `hits`.
fn write_json(
    w: &mut impl Write,
    table: &SearchTable,
    hits: &[Hit],
    total: usize,
    curves: usize,
) -> Result<()> {
    writeln!(
        w,
        "{{\"total\":{total},\"shown\":{},\"curves\":{curves},\"hits\":[",
        hits.len()
    )?;
    for (n, h) in hits.iter().enumerate() {
        let r = &table.rows[h.row];
        let mut o = serde_json::json!({
            "id": r.id,
            // As in index.json: a four-bar's {coupler, rocker, ground}, a geared
            // five-bar's {l1, l3, l4, l5, ratio, phase}.
            "linkage": r.linkage,
            "point": {"u": r.point[0], "v": r.point[1]},
            "circuit": r.circuit,
            "class": r.class,
            "transmission_deg": r.transmission_deg,
            "straight_segments": h.straight.iter().map(|&k| numbered(&table.segments[k], k - r.seg_start as usize + 1)).collect::<Vec<_>>(),
            "pseudo_arcs": h.arcs.iter().map(|&k| numbered(&table.arcs[k], k - r.arc_start as usize + 1)).collect::<Vec<_>>(),
        });
        if r.page != u32::MAX {
            o["page"] =
                serde_json::json!({"file": table.pages[r.page as usize], "bbox_px": r.page_bbox});
        }
        let sep = if n + 1 < hits.len() { "," } else { "" };
        writeln!(w, "{}{sep}", serde_json::to_string(&o)?)?;
    }
    writeln!(w, "]}}")?;
    Ok(())
}

/// The index header's `spec.features` (how its features were extracted), or `None` if
/// the header does not say (features off, or not readable).
fn extraction_settings(index: &Path) -> Option<serde_json::Value> {
    use std::io::BufRead;
    let file = std::fs::File::open(index).ok()?;
    let mut lines = std::io::BufReader::new(file).lines();
    lines.next()?.ok()?;
    let spec = lines.next()?.ok()?;
    let spec = spec.trim_end().strip_suffix(',').unwrap_or(spec.trim_end());
    let v: serde_json::Value = serde_json::from_str(&format!("{{{spec}}}")).ok()?;
    let f = v.get("spec")?.get("features")?;
    if f.get("enabled").and_then(|e| e.as_bool()) == Some(false) {
        return None;
    }
    Some(f.clone())
}

/// The dash pattern the index's features were counted in (`spec.features.dash_deg`, the
/// pages' pattern), the default where the header does not say.
fn extraction_dash(index: &Path) -> DashPattern {
    let step = extraction_settings(index).and_then(|f| f.get("dash_deg")?.as_f64());
    DashPattern {
        step_deg: step.unwrap_or(DashPattern::default().step_deg),
        ..DashPattern::default()
    }
}

/// The feature tolerances the index was extracted with (its header's `spec.features`),
/// or `None` if the header does not say (features off, or not readable).
fn extraction_tolerances(index: &Path) -> Option<FeatureTolerances> {
    let f = extraction_settings(index)?;
    let num = |k: &str| f.get(k).and_then(|x| x.as_f64());
    Some(FeatureTolerances {
        step_deg: num("step_deg")?,
        straight_pct: num("straight_pct")?,
        straight_min_span_deg: num("straight_min_span_deg")?,
        arc_pct: num("arc_pct")?,
        arc_min_span_deg: num("arc_min_span_deg")?,
        arc_min_turn_deg: num("arc_min_turn_deg")?,
        cusp_speed_ratio: num("cusp_speed_ratio")?,
        symmetry_tol: num("symmetry_tol")?,
    })
}

/// Whether the query tightens the straight and the arc tolerance below `t`'s extraction
/// (`t` being what [`tighter`] returned).
fn remeasured(t: &FeatureTolerances, q: &Query) -> (bool, bool) {
    (
        q.straight
            .is_some_and(|f| f.max_error_pct <= t.straight_pct),
        q.arc.is_some_and(|f| f.max_error_pct <= t.arc_pct),
    )
}

/// The tolerances to re-measure at when the query's `--straight` or `--arc` TOL is
/// tighter than the extraction's, else `None`.
fn tighter(q: &Query, e: &FeatureTolerances) -> Option<FeatureTolerances> {
    let straight = q
        .straight
        .map_or(e.straight_pct, |f| f.max_error_pct.min(e.straight_pct));
    let arc = q.arc.map_or(e.arc_pct, |f| f.max_error_pct.min(e.arc_pct));
    (straight < e.straight_pct || arc < e.arc_pct).then_some(FeatureTolerances {
        straight_pct: straight,
        arc_pct: arc,
        ..*e
    })
}

/// The candidates of a refinement of `q`: every filter but the features' errors and
/// measures (which change when re-measured), all of them, in id order.
fn candidates(q: &Query) -> Query {
    let relax = |f: Option<SpanFilter>| {
        f.map(|f| SpanFilter {
            max_error_pct: f64::INFINITY,
            ..f
        })
    };
    Query {
        straight: relax(q.straight),
        arc: relax(q.arc),
        double_dwell: false,
        radius: None,
        min_turn_deg: None,
        max_velocity_variation_pct: None,
        sort: SortKey::Id,
        limit: 0,
        ..q.clone()
    }
}

/// Exact answers below the extraction tolerance without regenerating. A window within a
/// tighter tolerance is also within the extraction's, so (the listed windows being
/// maximal, `docs/features.md`) it shares a step with a listed window at least as long:
/// only curves with a listed segment (arc) of at least the query's span can match. Those
/// candidates are re-measured at the tighter tolerances (the same extraction `generate`
/// runs, so the answer equals that of an atlas generated at them) into a table of their
/// own, which the query then runs on. Returns that table and the number of candidates.
fn refine(
    table: &SearchTable,
    q: &Query,
    t: &FeatureTolerances,
    dash: &DashPattern,
) -> Result<(SearchTable, usize)> {
    let rows: Vec<usize> = table.search(&candidates(q)).iter().map(|h| h.row).collect();
    let redo = remeasured(t, q);
    // Only what the query tightens is re-measured; the rest is the index's own (the same
    // extraction at the same tolerance). The curve is sampled as `generate` samples it
    // for features: over the mechanism's period (a geared five-bar of gear ratio p/q
    // turns its input q times) at the index's feature step.
    let measure = |i: usize| -> Result<(Vec<SegmentRow>, Vec<ArcRow>)> {
        let r = &table.rows[i];
        let crank = CrankTable::over(t.step_deg, r.linkage.period_deg()).ok_or_else(|| {
            anyhow::anyhow!(
                "curve {}: the index's feature step {} is not valid over the period {}°",
                r.id,
                t.step_deg,
                r.linkage.period_deg()
            )
        })?;
        let curve = r
            .linkage
            .pose_table(r.circuit, &crank)
            .trace(CouplerPoint::new(r.point[0], r.point[1]));
        let window = |start: f64, span: f64| {
            window_transmission(&r.linkage, r.circuit, start, span, t.step_deg)
                .unwrap_or([f64::NAN; 2])
        };
        let segments = if redo.0 {
            straight_segments(&curve, t, dash)
                .iter()
                .map(|s| SegmentRow::of(s, window(s.start_deg, s.span_deg)))
                .collect()
        } else {
            table.segments_of(r).to_vec()
        };
        let arcs = if redo.1 {
            pseudo_arcs(&curve, t, dash)
                .iter()
                .map(|a| ArcRow::of(a, window(a.start_deg, a.span_deg)))
                .collect()
        } else {
            table.arcs_of(r).to_vec()
        };
        Ok((segments, arcs))
    };
    // In parallel, in order: one chunk of rows per thread.
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let chunk = rows.len().div_ceil(threads).max(1);
    let measured: Vec<(Vec<SegmentRow>, Vec<ArcRow>)> = std::thread::scope(|s| {
        let handles: Vec<_> = rows
            .chunks(chunk)
            .map(|c| s.spawn(|| c.iter().map(|&i| measure(i)).collect::<Result<Vec<_>>>()))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect::<Result<Vec<Vec<_>>>>()
    })?
    .into_iter()
    .flatten()
    .collect();
    let mut out = SearchTable {
        pages: table.pages.clone(),
        ..SearchTable::default()
    };
    for (&i, (segments, arcs)) in rows.iter().zip(measured) {
        let mut r = table.rows[i];
        r.seg_start = out.segments.len() as u32;
        r.seg_count = segments.len() as u32;
        r.arc_start = out.arcs.len() as u32;
        r.arc_count = arcs.len() as u32;
        out.segments.extend(segments);
        out.arcs.extend(arcs);
        out.rows.push(r);
    }
    Ok((out, rows.len()))
}
