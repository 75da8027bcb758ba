//! `coupler-atlas dwell (--coupler A --rocker B --ground C --point U,V | --index INDEX
//! --curve ID) [--window S:E [--window2 S:E] | --arc K… | --line K K2] [--kind …]
//! [--method norton|optimise] [--swing DEG] [--cognate K] [limits] [--card FILE]
//! [--export FILE] [--crank-length L] [--format table|json]`

use super::{UsageError, parse_length, parse_number, parse_point};
use anyhow::{Context, Result};
use coupler_atlas::design::{
    DoubleArcOptions, DoubleDwellSearch, Driver, Export, ExportFormat, Limits, Method,
    best_double_dwell, double_dwell_arcs, double_dwell_lines, single_dwell,
};
use coupler_atlas::{Circuit, CouplerPoint, CrankWindow, FourBar};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Coupler length A (crank = 1). Not with --index.
    #[arg(long, value_parser = parse_length, allow_hyphen_values = true)]
    coupler: Option<f64>,
    /// Rocker length B.
    #[arg(long, value_parser = parse_length, allow_hyphen_values = true)]
    rocker: Option<f64>,
    /// Ground length C.
    #[arg(long, value_parser = parse_length, allow_hyphen_values = true)]
    ground: Option<f64>,
    /// Coupler point U,V in the coupler frame (crank units).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    point: Option<CouplerPoint>,
    /// Circuit (assembly).
    #[arg(long, default_value = "open", value_parser = ["open", "crossed"])]
    circuit: String,
    /// Design on this Roberts–Chebyshev cognate, numbered as `cognates` lists them (0 the
    /// linkage itself; the crank-rocker cognate is 2). The curve, its windows and its
    /// crank angles are the same; the four-bar that drives the dyad is the cognate.
    #[arg(long, default_value_t = 0)]
    cognate: usize,
    /// The (first) dwell window START:END, crank degrees: the pseudo-arc or straight
    /// segment. For double dwells, leave out both windows to have the best pair found.
    #[arg(long, allow_hyphen_values = true)]
    window: Option<String>,
    /// Take the linkage, point, circuit and windows from this index (with --curve and
    /// --arc/--line): e.g. `--index atlas/index.json --curve 1234 --arc 2`; or only the
    /// curve, with --window/--window2 and --kind.
    #[arg(long)]
    index: Option<PathBuf>,
    /// Curve id in --index.
    #[arg(long)]
    curve: Option<u64>,
    /// Use the curve's K-th pseudo-arc (1-based) as the (first) window; give it twice for
    /// a double dwell on two arcs.
    #[arg(long, value_name = "K")]
    arc: Vec<usize>,
    /// Use the curve's K-th straight segment; give it twice for a double dwell on two lines.
    #[arg(long, value_name = "K")]
    line: Vec<usize>,
    /// The second window, for a double dwell.
    #[arg(long, allow_hyphen_values = true)]
    window2: Option<String>,
    /// single (one pseudo-arc), double-arcs (two equal arcs), double-lines (two straight
    /// segments), double (without windows: the best of both found on the curve).
    #[arg(long, default_value = "single", value_parser = ["single", "double-lines", "double-arcs", "double"])]
    kind: String,
    /// Single dwell: how O6 is placed: norton (Norton's construction, O6 on the
    /// perpendicular bisector of DE) or optimise (O6 anywhere, least jitter).
    #[arg(long, default_value = "norton", value_parser = ["norton", "optimise", "optimize"])]
    method: String,
    /// Output swing, degrees: of a single dwell the output's whole range (default 40); of
    /// a double dwell the turn between the dwells (default: free). Honoured within 0.5°,
    /// or refused with the range this curve allows.
    #[arg(long, value_parser = parse_number)]
    swing: Option<f64>,
    /// Lower limit of the links 5–6 transmission angle all round, degrees (the angle at D
    /// stays within [limit, 180° − limit]).
    #[arg(long, default_value_t = coupler_atlas::design::DEFAULT_MIN_TRANSMISSION_DEG, value_parser = parse_number)]
    min_transmission: f64,
    /// Refuse a design whose worse dwell jitters more than this percentage of its swing
    /// (between the dwells for a double dwell).
    #[arg(long, default_value_t = coupler_atlas::design::DEFAULT_MAX_JITTER_PCT, value_parser = parse_number)]
    max_jitter_pct: f64,
    /// Refuse a design whose link 5 and link 6 differ more than this ratio (a slot: the
    /// block's farthest over its closest distance from O6).
    #[arg(long, default_value_t = coupler_atlas::design::DEFAULT_MAX_LINK_RATIO, value_parser = parse_number)]
    max_link_ratio: f64,
    /// The felt dwell: the crank range in which the output stays within ± this of its
    /// dwell position, degrees.
    #[arg(long, default_value_t = coupler_atlas::design::DEFAULT_DWELL_TOL_DEG, value_parser = parse_number)]
    dwell_tol: f64,
    /// double-arcs: largest difference of the two arcs' radii, percent of the larger.
    #[arg(long, default_value_t = coupler_atlas::design::DEFAULT_DOUBLE_ARC_RADIUS_TOL_PCT, value_parser = parse_number)]
    radius_tol: f64,
    /// Simulation step, crank degrees (divides 360).
    #[arg(long, default_value = "1", value_parser = parse_number)]
    step: f64,
    /// Draw the design card (the six-bar at θ = 0, the curve with its dwells, ψ(θ) and the
    /// figures) to FILE.png, FILE.svg or FILE.pdf.
    #[arg(long, value_name = "FILE")]
    card: Option<PathBuf>,
    /// The same as --card (kept for old scripts; the extension decides the format).
    #[arg(long, value_name = "FILE", hide = true)]
    png: Option<PathBuf>,
    /// Resolution of a PNG card, dots per inch.
    #[arg(long, default_value_t = 150)]
    dpi: u32,
    /// Write the six-bar at θ = 0 (pivots, joints, link lengths) and its coupler curve
    /// to FILE.json, FILE.csv or FILE.dxf (ASCII DXF R12, for CAD), in user units.
    #[arg(long, value_name = "FILE")]
    export: Option<PathBuf>,
    /// The crank's length in user units for --export (scales everything).
    #[arg(long, default_value = "1", value_parser = parse_length)]
    crank_length: f64,
    /// Name of the user units for --export.
    #[arg(long, default_value = "crank")]
    units: String,
    /// Output format.
    #[arg(long, default_value = "table", value_parser = ["table", "json"])]
    format: String,
}

/// A dwell window (a four-bar's: at most one turn).
fn window(s: &str, step: f64) -> Result<CrankWindow, UsageError> {
    s.parse::<CrankWindow>()
        .and_then(|w| w.with_step(step))
        .and_then(|w| w.within_period(360.0).map(|()| w))
        .map_err(|e| UsageError(e.to_string()))
}

/// What to design: the curve, windows and kind, from the flags (directly, or from a
/// curve of an index and its features).
struct Plan {
    linkage: FourBar,
    circuit: Circuit,
    point: CouplerPoint,
    window1: Option<String>,
    window2: Option<String>,
    kind: String,
}

fn plan(args: &Args) -> Result<Plan> {
    if let Some(index) = &args.index {
        let id = args
            .curve
            .ok_or_else(|| UsageError("--index needs --curve ID".into()))?;
        let table = super::search::load_curve(index, id)?;
        let row = table
            .rows
            .iter()
            .find(|r| r.id == id)
            .ok_or_else(|| UsageError(format!("no curve {id} in {}", index.display())))?;
        let l = *row.linkage.four_bar().ok_or_else(|| {
            UsageError(format!(
                "curve {id} is of a geared five-bar ({}): dwell designs four-bar dwell linkages only",
                row.linkage
            ))
        })?;
        let p = CouplerPoint::new(row.point[0], row.point[1]);
        let pick = |what: &str,
                    ks: &[usize],
                    spans: Vec<(f64, f64)>|
         -> Result<Vec<(f64, f64)>, UsageError> {
            ks.iter()
                .map(|&k| {
                    k.checked_sub(1)
                        .and_then(|k| spans.get(k))
                        .copied()
                        .ok_or_else(|| {
                            UsageError(format!(
                                "curve {id} has {} {what}(s); {k} is not one",
                                spans.len()
                            ))
                        })
                })
                .collect()
        };
        if args.arc.is_empty()
            && args.line.is_empty()
            && (args.window.is_some() || args.kind.starts_with("double"))
        {
            return Ok(Plan {
                linkage: l,
                circuit: row.circuit,
                point: p,
                window1: args.window.clone(),
                window2: args.window2.clone(),
                kind: args.kind.clone(),
            });
        }
        let (spans, kind) = match (args.arc.len(), args.line.len()) {
            (n @ 1..=2, 0) => (
                pick(
                    "pseudo-arc",
                    &args.arc,
                    table
                        .arcs_of(row)
                        .iter()
                        .map(|a| (a.start_deg, a.span_deg))
                        .collect(),
                )?,
                if n == 1 { "single" } else { "double-arcs" },
            ),
            (0, 2) => (
                pick(
                    "straight segment",
                    &args.line,
                    table
                        .segments_of(row)
                        .iter()
                        .map(|a| (a.start_deg, a.span_deg))
                        .collect(),
                )?,
                "double-lines",
            ),
            _ => {
                return Err(UsageError(
                    "with --index, give --arc K (single), --arc K --arc K2 (double), --line K --line K2, or --window S:E [--window2 S:E] with --kind".into(),
                )
                .into());
            }
        };
        let w = |(s, n): (f64, f64)| format!("{s}:{}", s + n);
        return Ok(Plan {
            linkage: l,
            circuit: row.circuit,
            point: p,
            window1: Some(w(spans[0])),
            window2: spans.get(1).map(|&x| w(x)),
            kind: kind.to_string(),
        });
    }
    let need = |name: &str| {
        UsageError(format!(
            "--{name} is required (or use --index with --curve)"
        ))
    };
    let l = FourBar::new(
        args.coupler.ok_or_else(|| need("coupler"))?,
        args.rocker.ok_or_else(|| need("rocker"))?,
        args.ground.ok_or_else(|| need("ground"))?,
    )
    .map_err(|e| UsageError(e.to_string()))?;
    let circuit: Circuit = args.circuit.parse().map_err(UsageError)?;
    let p = args.point.ok_or_else(|| need("point"))?;
    if args.window.is_none() && !args.kind.starts_with("double") {
        return Err(need("window").into());
    }
    Ok(Plan {
        linkage: l,
        circuit,
        point: p,
        window1: args.window.clone(),
        window2: args.window2.clone(),
        kind: args.kind.clone(),
    })
}

/// An output file and its format, checked before any work.
enum Output {
    Card(PathBuf, coupler_atlas::render::PageFormat),
    Export(PathBuf, ExportFormat),
}

fn check_folder(path: &Path, flag: &str) -> Result<(), UsageError> {
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(UsageError(format!(
            "{flag} {}: the folder {} does not exist",
            path.display(),
            parent.display()
        )));
    }
    if path.is_dir() {
        return Err(UsageError(format!(
            "{flag} {}: is a folder, not a file",
            path.display()
        )));
    }
    Ok(())
}

fn outputs(args: &Args) -> Result<Vec<Output>, UsageError> {
    let mut v = Vec::new();
    if args.card.is_some() && args.png.is_some() {
        return Err(UsageError(
            "give --card or --png (its old name), not both".into(),
        ));
    }
    if let Some(path) = args.card.as_ref().or(args.png.as_ref()) {
        let flag = if args.card.is_some() {
            "--card"
        } else {
            "--png"
        };
        check_folder(path, flag)?;
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_string();
        let format: coupler_atlas::render::PageFormat = ext.parse().map_err(|e| {
            UsageError(format!(
                "{flag} {}: {e}; the extension names the format",
                path.display()
            ))
        })?;
        v.push(Output::Card(path.clone(), format));
    }
    if let Some(path) = &args.export {
        check_folder(path, "--export")?;
        let format = ExportFormat::from_path(path).ok_or_else(|| {
            UsageError(format!(
                "--export {}: unknown format; the extension names it: .json, .csv or .dxf",
                path.display()
            ))
        })?;
        v.push(Output::Export(path.clone(), format));
    }
    if !(coupler_atlas::layout::DPI_RANGE.contains(&args.dpi)) {
        return Err(UsageError(format!(
            "--dpi must be in {}..={}, got {}",
            coupler_atlas::layout::DPI_RANGE.start(),
            coupler_atlas::layout::DPI_RANGE.end(),
            args.dpi
        )));
    }
    Ok(v)
}

/// Renders a display list (a card or chart) in a format.
pub(super) fn render(
    display: &coupler_atlas::layout::DisplayList,
    format: coupler_atlas::render::PageFormat,
    dpi: u32,
) -> Result<Vec<u8>> {
    use coupler_atlas::render::{PageFormat, RasterPage, SvgPage, draw};
    Ok(match format {
        PageFormat::Png => {
            let k = dpi as f64 / coupler_atlas::layout::PT_PER_INCH;
            let (w, h) = (
                (display.width * k).round() as u32,
                (display.height * k).round() as u32,
            );
            let mut page = RasterPage::new(w, h, dpi as f64).context("empty page")?;
            draw(display, &mut page);
            let mut bytes = Vec::new();
            page.finish_png(&mut bytes)?;
            bytes
        }
        PageFormat::Svg => {
            let mut svg = SvgPage::new(display.width, display.height);
            draw(display, &mut svg);
            svg.finish().into_bytes()
        }
        PageFormat::Pdf => {
            let mut pdf = coupler_atlas::render::PdfPage::new(display.width, display.height);
            draw(display, &mut pdf);
            coupler_atlas::render::write_pdf(&[pdf.finish(Vec::new())], &[], &[], "design card")?
        }
    })
}

pub fn run(args: Args) -> Result<ExitCode> {
    let p = plan(&args)?;
    let step = args.step;
    if !(step > 0.0 && step <= 10.0 && coupler_atlas::divides_turn(step)) {
        return Err(UsageError(format!(
            "--step must divide 360 and be in (0, 10] degrees, got {step}"
        ))
        .into());
    }
    coupler_atlas::samples_per_turn(args.step).map_err(|m| UsageError(format!("--step: {m}")))?;
    if let Some(swing) = args.swing {
        if !(swing > 0.0 && swing < 180.0) {
            return Err(
                UsageError(format!("--swing must be in (0, 180) degrees, got {swing}")).into(),
            );
        }
    }
    let checks = [
        ("--min-transmission", args.min_transmission, 0.0, 90.0),
        ("--max-jitter-pct", args.max_jitter_pct, 0.0, 1000.0),
        ("--dwell-tol", args.dwell_tol, 0.0, 90.0),
    ];
    for (name, x, lo, hi) in checks {
        if !(x >= lo && x < hi) {
            return Err(UsageError(format!("{name} must be in [{lo}, {hi}), got {x}")).into());
        }
    }
    if !(args.max_link_ratio >= 1.0 && args.max_link_ratio.is_finite()) {
        return Err(UsageError(format!(
            "--max-link-ratio must be ≥ 1, got {}",
            args.max_link_ratio
        ))
        .into());
    }
    let files = outputs(&args)?;
    let driver = Driver::cognate(p.linkage, p.circuit, p.point, args.cognate)
        .map_err(|e| UsageError(e.to_string()))?;
    let limits = Limits {
        step_deg: step,
        min_transmission_deg: args.min_transmission,
        max_jitter_pct: args.max_jitter_pct,
        max_link_ratio: args.max_link_ratio,
        dwell_tol_deg: args.dwell_tol,
    };
    let kind = p.kind.as_str();
    let first = || -> Result<CrankWindow, UsageError> {
        let s = p
            .window1
            .as_deref()
            .ok_or_else(|| UsageError(format!("--kind {kind} needs --window")))?;
        window(s, step)
    };
    let second = || -> Result<CrankWindow, UsageError> {
        let s = p
            .window2
            .as_deref()
            .ok_or_else(|| UsageError(format!("--kind {kind} needs --window2")))?;
        window(s, step)
    };
    let arc_opts = DoubleArcOptions {
        swing_deg: args.swing,
        radius_tol_pct: args.radius_tol,
    };
    let method = match args.method.as_str() {
        "norton" => Method::Norton,
        _ => Method::Optimise,
    };
    let find = p.window1.is_none() && p.window2.is_none();
    let d = match kind {
        "single" => single_dwell(
            &driver,
            &first()?,
            args.swing.unwrap_or(40.0),
            method,
            &limits,
        ),
        _ if find => {
            let mut search = DoubleDwellSearch::default();
            match kind {
                "double-arcs" => search.line_candidates = 0,
                "double-lines" => search.arc_candidates = 0,
                _ => {}
            }
            best_double_dwell(&driver, &search, &arc_opts, &limits)
        }
        "double-lines" => double_dwell_lines(&driver, &first()?, &second()?, args.swing, &limits),
        "double-arcs" => double_dwell_arcs(&driver, &first()?, &second()?, &arc_opts, &limits),
        _ => {
            return Err(UsageError(
                "--kind double finds its windows: leave out --window and --window2 (or name the kind: double-arcs, double-lines)".into(),
            )
            .into());
        }
    }
    .map_err(|e| UsageError(e.to_string()))?;
    // Every file is made in memory and written whole before anything is printed: an
    // I/O error names its file, and no half-written file is left under its name.
    let mut export_at_one = None;
    for f in &files {
        let (path, bytes) = match f {
            Output::Card(path, format) => {
                let e = match &export_at_one {
                    Some(e) => e,
                    None => export_at_one.insert(
                        Export::new(&d, &driver, 1.0, "crank")
                            .context("the design does not assemble at θ = 0")?,
                    ),
                };
                (
                    path,
                    render(&coupler_atlas::layout::dwell_card(&d, e), *format, args.dpi)?,
                )
            }
            Output::Export(path, format) => {
                let scale = args.crank_length / driver.crank();
                let e = Export::new(&d, &driver, scale, &args.units)
                    .context("the design does not assemble at θ = 0")?;
                (path, e.write(*format).into_bytes())
            }
        };
        coupler_atlas::generate::write_atomically(path, |w| w.write_all(&bytes))
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    let stdout = std::io::stdout();
    let mut w = std::io::BufWriter::new(stdout.lock());
    if args.format == "json" {
        serde_json::to_writer(&mut w, &d)?;
        writeln!(w)?;
    } else {
        for line in d.report_lines(args.swing) {
            writeln!(w, "{line}")?;
        }
    }
    w.flush()?;
    Ok(ExitCode::SUCCESS)
}
