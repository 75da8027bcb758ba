//! `coupler-atlas dwell --coupler A --rocker B --ground C --point U,V --window S:E
//! [--window2 S:E] [--kind single|double-lines|double-arcs] [--swing DEG] [--png FILE]`

use super::{UsageError, parse_length, parse_number, parse_point};
use anyhow::{Context, Result};
use coupler_atlas::{
    ArcPairSearch, DoubleArcOptions, DwellMechanism, best_double_dwell_arcs, double_dwell_arcs,
    double_dwell_lines, single_dwell,
};
use coupler_atlas::{Circuit, CouplerPoint, CrankAngle, CrankWindow, FourBar, Pose};
use plotters::prelude::*;
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
    /// The (first) dwell window START:END, crank degrees: the pseudo-arc or straight
    /// segment. For double-arcs, leave out both windows to have the best pair of arc
    /// windows found on the curve.
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
    /// single (one pseudo-arc), double-lines (two straight segments), double-arcs (two equal arcs).
    #[arg(long, default_value = "single", value_parser = ["single", "double-lines", "double-arcs"])]
    kind: String,
    /// Output swing, degrees: of a single dwell (default 40); for double-arcs, the swing
    /// between the two dwells (default: free, chosen for the least jitter relative to the
    /// swing; if no admissible design has the swing asked for, the nearest one is taken).
    #[arg(long, value_parser = parse_number)]
    swing: Option<f64>,
    /// double-arcs: lower limit of the links 5–6 transmission angle over the whole
    /// revolution, degrees (the angle at D stays within [limit, 180° − limit]).
    #[arg(long, default_value_t = coupler_atlas::DEFAULT_MIN_TRANSMISSION_DEG, value_parser = parse_number)]
    min_transmission: f64,
    /// double-arcs: largest difference of the two arcs' radii, percent of the larger.
    #[arg(long, default_value_t = coupler_atlas::DEFAULT_DOUBLE_ARC_RADIUS_TOL_PCT, value_parser = parse_number)]
    radius_tol: f64,
    /// double-arcs: refuse a design whose worse dwell jitters more than this percentage
    /// of the swing between the dwells.
    #[arg(long, default_value_t = 100.0 * coupler_atlas::DEFAULT_MAX_RELATIVE_JITTER, value_parser = parse_number)]
    max_jitter_pct: f64,
    /// Simulation step, crank degrees.
    #[arg(long, default_value = "1", value_parser = parse_number)]
    step: f64,
    /// Draw the design and its output-angle plot to this PNG.
    #[arg(long)]
    png: Option<PathBuf>,
    /// Output format.
    #[arg(long, default_value = "table", value_parser = ["table", "json"])]
    format: String,
}

fn window(s: &str, step: f64) -> Result<CrankWindow, UsageError> {
    s.parse::<CrankWindow>()
        .and_then(|w| w.with_step(step))
        .map_err(|e| UsageError(e.to_string()))
}

/// Resolves the linkage, point, circuit, windows and kind from the flags (directly, or
/// from a curve of an index and its features).
#[allow(clippy::type_complexity)]
fn plan(
    args: &Args,
) -> Result<(
    FourBar,
    Circuit,
    CouplerPoint,
    Option<String>,
    Option<String>,
    String,
)> {
    if let Some(index) = &args.index {
        let id = args
            .curve
            .ok_or_else(|| UsageError("--index needs --curve ID".into()))?;
        let (table, _) = super::search::load(index, true)?;
        let row = table
            .rows
            .iter()
            .find(|r| r.id == id)
            .ok_or_else(|| UsageError(format!("no curve {id} in {}", index.display())))?;
        let l = FourBar::new(row.linkage[0], row.linkage[1], row.linkage[2])
            .map_err(|e| UsageError(e.to_string()))?;
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
            && (args.window.is_some() || args.kind == "double-arcs")
        {
            // The curve from the index, the windows as given (or, for double-arcs, found).
            return Ok((
                l,
                row.circuit,
                p,
                args.window.clone(),
                args.window2.clone(),
                args.kind.clone(),
            ));
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
        return Ok((
            l,
            row.circuit,
            p,
            Some(w(spans[0])),
            spans.get(1).map(|&x| w(x)),
            kind.to_string(),
        ));
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
    if args.window.is_none() && args.kind != "double-arcs" {
        return Err(need("window").into());
    }
    Ok((
        l,
        circuit,
        p,
        args.window.clone(),
        args.window2.clone(),
        args.kind.clone(),
    ))
}

pub fn run(args: Args) -> Result<ExitCode> {
    let (l, circuit, p, window1, window2, kind) = plan(&args)?;
    if !(args.step > 0.0 && args.step <= 10.0) {
        return Err(UsageError(format!(
            "--step must be in (0, 10] degrees, got {}",
            args.step
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
    if !(args.min_transmission >= 0.0 && args.min_transmission < 90.0) {
        return Err(UsageError(format!(
            "--min-transmission must be in [0, 90) degrees, got {}",
            args.min_transmission
        ))
        .into());
    }
    let first = || -> Result<CrankWindow, UsageError> {
        let s = window1
            .as_deref()
            .ok_or_else(|| UsageError(format!("--kind {kind} needs --window")))?;
        window(s, args.step)
    };
    let second = || -> Result<CrankWindow, UsageError> {
        let s = window2
            .as_deref()
            .ok_or_else(|| UsageError(format!("--kind {kind} needs --window2")))?;
        window(s, args.step)
    };
    let arc_opts = DoubleArcOptions {
        step_deg: args.step,
        min_transmission_deg: args.min_transmission,
        swing_deg: args.swing,
        radius_tol_pct: args.radius_tol,
        max_relative_jitter: args.max_jitter_pct / 100.0,
    };
    let d = match kind.as_str() {
        "single" => single_dwell(
            &l,
            circuit,
            p,
            &first()?,
            args.swing.unwrap_or(40.0),
            args.step,
        ),
        "double-lines" => double_dwell_lines(&l, circuit, p, &first()?, &second()?, args.step),
        _ if window1.is_none() && window2.is_none() => {
            best_double_dwell_arcs(&l, circuit, p, &ArcPairSearch::default(), &arc_opts)
        }
        _ => double_dwell_arcs(&l, circuit, p, &first()?, &second()?, &arc_opts),
    }
    .map_err(|e| UsageError(e.to_string()))?;
    let stdout = std::io::stdout();
    let mut w = std::io::BufWriter::new(stdout.lock());
    if args.format == "json" {
        serde_json::to_writer(&mut w, &d)?;
        writeln!(w)?;
    } else {
        writeln!(
            w,
            "{:?} dwell on {l} ({circuit}), point ({}, {})",
            d.kind, p.u, p.v
        )?;
        writeln!(
            w,
            "link 5 {:.4}, output pivot O6 ({:.4}, {:.4}), link 6 {:.4}",
            d.link5, d.output_pivot[0], d.output_pivot[1], d.link6
        )?;
        write!(w, "output swing {:.3}°", d.swing_deg)?;
        if let Some(s) = d.dwell_swing_deg {
            write!(w, ", between the dwells {s:.3}°")?;
            if let (Some(want), "double-arcs") = (args.swing, kind.as_str()) {
                if (s - want).abs() > 1.0 {
                    write!(w, " (asked for {want}°: no admissible design has it)")?;
                }
            }
        }
        writeln!(w)?;
        for (k, x) in d.dwells.iter().enumerate() {
            let [a, b] = x.output_transmission_range_deg;
            writeln!(
                w,
                "dwell {}: θ {}°+{}° ({} dashes of 10°), output {:.3}°, jitter {:.4}°, links 5–6 transmission {a:.1}°–{b:.1}°",
                k + 1,
                x.start_deg,
                x.span_deg,
                (x.span_deg / 10.0 + 1e-9).floor(),
                x.output_deg,
                x.jitter_deg
            )?;
        }
        let [a, b] = d.output_transmission_range_deg;
        let [c, e] = d.fourbar_transmission_range_deg;
        writeln!(
            w,
            "transmission angles: links 5–6 {a:.2}°–{b:.2}°, four-bar {c:.2}°–{e:.2}°"
        )?;
    }
    w.flush()?;
    if let Some(path) = &args.png {
        draw(&d, path).with_context(|| format!("cannot draw {}", path.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Left: the design (curve, dwell circles/pivots, the linkage at the first dwell); right:
/// output angle against crank angle, dwells shaded. No text (plotters here has no font).
fn draw(d: &DwellMechanism, path: &Path) -> Result<()> {
    let root = BitMapBackend::new(path, (1400, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(700);
    let l = &d.linkage;
    let pose_at = |t: f64| Pose::solve(l, d.circuit, &CrankAngle::from_degrees(t));
    let curve: Vec<(f64, f64)> = (0..=360)
        .filter_map(|k| pose_at(k as f64).map(|p| p.point(d.point)))
        .map(|m| (m.x, m.y))
        .collect();
    let mut pts: Vec<(f64, f64)> = curve.clone();
    pts.extend([
        (0.0, 0.0),
        (l.ground, 0.0),
        (d.output_pivot[0], d.output_pivot[1]),
    ]);
    pts.extend(d.dwell_points.iter().map(|c| (c[0], c[1])));
    let (x0, x1) = pts
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let (y0, y1) = pts
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    let half = 0.55 * (x1 - x0).max(y1 - y0);
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let mut chart = ChartBuilder::on(&left.margin(20, 20, 20, 20))
        .build_cartesian_2d(cx - half..cx + half, cy - half..cy + half)?;
    chart.draw_series(LineSeries::new(curve, BLACK.stroke_width(2)))?;
    for c in &d.dwell_points {
        let circle: Vec<(f64, f64)> = (0..=180)
            .map(|k| {
                let (s, co) = coupler_atlas::sincos_deg(k as f64 * 2.0);
                (c[0] + d.link5 * co, c[1] + d.link5 * s)
            })
            .collect();
        if d.link5 > 0.0 {
            chart.draw_series(LineSeries::new(circle, BLUE.mix(0.5)))?;
        }
        chart.draw_series(std::iter::once(Circle::new((c[0], c[1]), 5, BLUE.filled())))?;
    }
    if let Some(first) = d.dwells.first() {
        if let Some(pose) = pose_at(first.start_deg + 0.5 * first.span_deg) {
            let m = pose.point(d.point);
            let (pa, pb) = (pose.crank_pin, pose.rocker_pin);
            let links = [
                vec![(0.0, 0.0), (pa.x, pa.y)],
                vec![(pa.x, pa.y), (pb.x, pb.y), (m.x, m.y), (pa.x, pa.y)],
                vec![(l.ground, 0.0), (pb.x, pb.y)],
            ];
            for link in links {
                chart.draw_series(LineSeries::new(link, RED.stroke_width(3)))?;
            }
            let c = d.dwell_points[0];
            chart.draw_series(LineSeries::new(
                vec![
                    (m.x, m.y),
                    (c[0], c[1]),
                    (d.output_pivot[0], d.output_pivot[1]),
                ],
                GREEN.stroke_width(3),
            ))?;
        }
    }
    for p in [
        (0.0, 0.0),
        (l.ground, 0.0),
        (d.output_pivot[0], d.output_pivot[1]),
    ] {
        chart.draw_series(std::iter::once(TriangleMarker::new(p, 9, BLACK.filled())))?;
    }
    // Output angle plot.
    let t0 = d.theta_deg[0];
    let (o0, o1) = d
        .output_deg
        .iter()
        .fold((f64::MAX, f64::MIN), |a, &o| (a.0.min(o), a.1.max(o)));
    let pad = 0.05 * (o1 - o0).max(1e-6);
    let mut plot = ChartBuilder::on(&right.margin(30, 30, 30, 30))
        .build_cartesian_2d(t0..t0 + 360.0, o0 - pad..o1 + pad)?;
    for x in &d.dwells {
        let s = t0 + (x.start_deg - t0).rem_euclid(360.0);
        for (a, b) in [
            (s, (s + x.span_deg).min(t0 + 360.0)),
            (t0, s + x.span_deg - 360.0),
        ] {
            if b > a {
                plot.draw_series(std::iter::once(Rectangle::new(
                    [(a, o0 - pad), (b, o1 + pad)],
                    BLUE.mix(0.15).filled(),
                )))?;
            }
        }
    }
    plot.draw_series(LineSeries::new(
        vec![
            (t0, o0 - pad),
            (t0 + 360.0, o0 - pad),
            (t0 + 360.0, o1 + pad),
            (t0, o1 + pad),
            (t0, o0 - pad),
        ],
        BLACK,
    ))?;
    plot.draw_series(LineSeries::new(
        d.theta_deg
            .iter()
            .copied()
            .zip(d.output_deg.iter().copied()),
        BLACK.stroke_width(2),
    ))?;
    root.present()?;
    Ok(())
}
