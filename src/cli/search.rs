//! `coupler-atlas search INDEX [filters] [--sort] [--limit] [--format table|json]`

use super::UsageError;
use anyhow::Result;
use coupler_atlas::{Circuit, LinkageClass};
use coupler_atlas::{DEFAULT_RADIUS_TOL_PCT, Query, SearchTable, SortKey, SpanFilter};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The index to search (index.json of a generated atlas).
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
    /// Barker class, e.g. GCRR.
    #[arg(long)]
    class: Option<String>,
    /// The linkage A,B,C (coupler, rocker, ground).
    #[arg(long, value_name = "A,B,C")]
    linkage: Option<String>,
    /// Circuit: open or crossed.
    #[arg(long, value_parser = ["open", "crossed"])]
    circuit: Option<String>,
    /// Symmetric curves only.
    #[arg(long)]
    symmetric: bool,
    /// Order: id, straight, straightness, arc, deviation, transmission.
    #[arg(long, default_value = "id")]
    sort: SortKey,
    /// At most N hits (0: all).
    #[arg(long, default_value_t = 20)]
    limit: usize,
    /// Output format.
    #[arg(long, default_value = "table", value_parser = ["table", "json"])]
    format: String,
    /// Do not read or write the search cache (INDEX.search).
    #[arg(long)]
    no_cache: bool,
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

/// The search table of `index` (from its cache when it matches): a usage error when the
/// index cannot be read or is not an index.
pub(super) fn load(index: &Path, use_cache: bool) -> Result<(SearchTable, &'static str)> {
    let (table, source) =
        coupler_atlas::load_table(index, use_cache).map_err(|e| UsageError(e.to_string()))?;
    Ok((table, source.name()))
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

fn parse_linkage(s: &str) -> Result<[f64; 3], UsageError> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| super::parse_length(x.trim()))
        .collect::<Result<_, _>>()
        .map_err(|e| UsageError(format!("--linkage: {e}")))?;
    <[f64; 3]>::try_from(v).map_err(|_| UsageError(format!("--linkage expects A,B,C, got `{s}`")))
}

pub fn run(args: Args) -> Result<ExitCode> {
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
    let query = Query {
        straight: args.straight,
        arc: args.arc,
        double_dwell: args.double_dwell,
        radius_tol_pct: args.radius_tol,
        min_transmission_deg: args.min_transmission,
        class,
        linkage: args.linkage.as_deref().map(parse_linkage).transpose()?,
        circuit: args
            .circuit
            .as_deref()
            .map(|c| c.parse::<Circuit>())
            .transpose()
            .map_err(UsageError)?,
        symmetric: args.symmetric,
        sort: args.sort,
        limit: args.limit,
    };
    let t0 = Instant::now();
    let (table, source) = load(&args.index, !args.no_cache)?;
    let t1 = Instant::now();
    let hits = table.search(&query);
    let t2 = Instant::now();
    let stdout = std::io::stdout();
    let mut w = std::io::BufWriter::new(stdout.lock());
    if args.format == "json" {
        writeln!(w, "[")?;
        for (n, h) in hits.iter().enumerate() {
            let r = &table.rows[h.row];
            let mut o = serde_json::json!({
                "id": r.id,
                // A geared five-bar's row has no (A, B, C): its linkage is in index.json
                // under the same id.
                "linkage": if r.linkage[0].is_nan() { serde_json::Value::Null } else { serde_json::json!({"coupler": r.linkage[0], "rocker": r.linkage[1], "ground": r.linkage[2]}) },
                "point": {"u": r.point[0], "v": r.point[1]},
                "circuit": r.circuit,
                "class": r.class,
                "transmission_deg": r.transmission_deg,
                "straight_segments": h.straight.iter().map(|&k| numbered(&table.segments[k], k - r.seg_start as usize + 1)).collect::<Vec<_>>(),
                "pseudo_arcs": h.arcs.iter().map(|&k| numbered(&table.arcs[k], k - r.arc_start as usize + 1)).collect::<Vec<_>>(),
            });
            if r.page != u32::MAX {
                o["page"] = serde_json::json!({"file": table.pages[r.page as usize], "bbox_px": r.page_bbox});
            }
            let sep = if n + 1 < hits.len() { "," } else { "" };
            writeln!(w, "{}{sep}", serde_json::to_string(&o)?)?;
        }
        writeln!(w, "]")?;
    } else {
        writeln!(
            w,
            "{:>8} {:>6} {:>6} {:>6} {:>7} {:>7} {:>7} {:>9}  matches / page",
            "id", "A", "B", "C", "u", "v", "circuit", "mu min"
        )?;
        for h in &hits {
            let r = &table.rows[h.row];
            let mut m: Vec<String> = h
                .straight
                .iter()
                .map(|&k| {
                    let s = &table.segments[k];
                    format!(
                        "line#{} {}°+{}° ε_S {:.3}%",
                        k - r.seg_start as usize + 1,
                        s.start_deg,
                        s.span_deg,
                        s.straightness_pct
                    )
                })
                .collect();
            m.extend(h.arcs.iter().map(|&k| {
                let a = &table.arcs[k];
                format!(
                    "arc#{} {}°+{}° R {:.3} dev {:.3}%",
                    k - r.arc_start as usize + 1,
                    a.start_deg,
                    a.span_deg,
                    a.radius,
                    a.deviation_pct
                )
            }));
            if r.page != u32::MAX {
                let b = r.page_bbox;
                m.push(format!(
                    "page {} at ({:.0},{:.0})-({:.0},{:.0}) px",
                    table.pages[r.page as usize], b[0], b[1], b[2], b[3]
                ));
            }
            writeln!(
                w,
                "{:>8} {:>6} {:>6} {:>6} {:>7} {:>7} {:>7} {:>9.2}  {}",
                r.id,
                r.linkage[0],
                r.linkage[1],
                r.linkage[2],
                r.point[0],
                r.point[1],
                r.circuit.name(),
                r.transmission_deg[0],
                m.join("; ")
            )?;
        }
    }
    w.flush()?;
    eprintln!(
        "{} hit(s) of {} curves; load {:.3} s (from {source}), search {:.3} s",
        hits.len(),
        table.rows.len(),
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}
