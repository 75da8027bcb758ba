//! `coupler-lab`: the benchmark lab's command line (`cargo run --release -p coupler-lab --
//! methods|stability|classics|adaptive`). The position methods charted (accuracy against
//! speed, feature accuracy against sampling density), the stability sweep table, the
//! classic straight-line linkages' measured straightness, and adaptive sampling. Results
//! go to `docs/methods/` (see `docs/methods.md`). Not part of the product: the
//! `coupler-atlas` binary never depends on it.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use coupler_generate::{machine, median};
use coupler_kinematics::{Circuit, CouplerPoint, FourBar};
use coupler_lab::{
    ClosedForm, Measurement, PositionMethod, all_methods, coupler_point_dd, fit_circle, measure,
    run_case, straightness_along_x, sweep_cases, uniform_angles,
};
use nalgebra::Point2;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// The coupler-atlas benchmark lab: position methods, stability, classics, adaptive sampling.
#[derive(Parser, Debug)]
#[command(name = "coupler-lab", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    which: Which,
}

#[derive(Subcommand, Debug)]
enum Which {
    /// Position methods charted: time per curve against max error, and feature accuracy
    /// against samples per dash (PNG charts, CSV tables, markdown; docs/methods.md).
    Methods {
        /// Output folder.
        #[arg(long, default_value = "docs/methods")]
        out: PathBuf,
        /// Repetitions of each timing (the median is reported).
        #[arg(long, default_value_t = 15)]
        reps: usize,
    },
    /// Stability sweep: every method near change points, toggles, extreme ratios and far
    /// coupler points, as a markdown table (also written to `<out>/stability.md`).
    Stability {
        /// Output folder for stability.md (none: print only).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Adaptive sampling against uniform sampling at equal chord-error tolerance.
    Adaptive {
        /// Output folder for adaptive.md (none: print only).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Repetitions of each timing (the median is reported).
        #[arg(long, default_value_t = 5)]
        reps: usize,
    },
    /// Measured straightness of the classic straight-line linkages (full curves).
    Classics {
        /// The explicit-curve spec.
        #[arg(long, default_value = "atlas-spec/classics.toml")]
        spec: PathBuf,
        /// Output folder for classics.md (none: print only).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Cost of the index's exact arc length per curve (adaptive Gauss–Kronrod) against the
    /// trapezoid sum on the samples it replaced, over every curve of an atlas spec.
    Arclength {
        /// The atlas spec.
        #[arg(long, default_value = "atlas-spec/hrones-nelson.toml")]
        spec: PathBuf,
        /// Repetitions of each timing (the median is reported).
        #[arg(long, default_value_t = 5)]
        reps: usize,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.which {
        Which::Methods { out, reps } => methods(&out, reps.max(1)),
        Which::Stability { out } => stability(out.as_deref()),
        Which::Adaptive { out, reps } => adaptive(out.as_deref(), reps.max(1)),
        Which::Classics { spec, out } => classics(&spec, out.as_deref()),
        Which::Arclength { spec, reps } => arclength(&spec, reps.max(1)),
    };
    match result {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::from(1)
        }
    }
}

/// Sampling densities charted: samples per 10° dash.
pub const DENSITIES: [usize; 10] = [1, 2, 3, 5, 10, 20, 30, 50, 100, 200];

const FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

fn register_font() {
    // Registering twice is harmless (the first stays).
    let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
}

/// Median seconds per call of `f`, over `reps` timed batches of at least 2 ms.
fn time_per_call(reps: usize, mut f: impl FnMut()) -> f64 {
    let mut batch = 1usize;
    loop {
        let t = Instant::now();
        for _ in 0..batch {
            f();
        }
        if t.elapsed().as_secs_f64() > 2e-3 || batch > 1 << 20 {
            break;
        }
        batch *= 2;
    }
    let times: Vec<f64> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..batch {
                f();
            }
            t.elapsed().as_secs_f64() / batch as f64
        })
        .collect();
    median(times)
}

/// The largest distance between the true curve (double-double, at the midpoint angle of
/// each interval) and the chord drawn between consecutive samples: the error of the
/// curve *as drawn* by a polyline.
fn chord_error(
    l: &FourBar,
    c: Circuit,
    p: CouplerPoint,
    degrees: &[f64],
    pts: &[Option<Point2<f64>>],
) -> f64 {
    let n = degrees.len();
    let mut worst = 0.0f64;
    for k in 0..n {
        let (a, b) = (pts[k], pts[(k + 1) % n]);
        let (Some(a), Some(b)) = (a, b) else { continue };
        let mid = if k + 1 < n {
            0.5 * (degrees[k] + degrees[k + 1])
        } else {
            0.5 * (degrees[k] + 360.0)
        };
        let Some((x, y)) = coupler_point_dd(l, c, p, mid) else {
            continue;
        };
        let m = Point2::new(x.to_f64(), y.to_f64());
        // distance from m to segment ab
        let ab = b - a;
        let t = if ab.norm_squared() > 0.0 {
            ((m - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        worst = worst.max((m - (a + ab * t)).norm());
    }
    worst
}

struct SpeedRow {
    method: &'static str,
    case: &'static str,
    density: usize,
    seconds: f64,
    m: Measurement,
    chord: f64,
}

/// `methods`: both charts, their CSV tables and a markdown summary under `out`.
pub fn methods(out: &Path, reps: usize) -> Result<ExitCode> {
    register_font();
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let machine = machine();
    let methods = all_methods();
    let cases: [(&'static str, FourBar, Circuit, CouplerPoint); 2] = [
        (
            "ordinary",
            FourBar::new(2.5, 3.0, 3.5)?,
            Circuit::Open,
            CouplerPoint::new(1.2, -0.7),
        ),
        (
            "near change point (gap 1e-6)",
            FourBar::new(3.0, 2.0, 2.0 + 1e-6)?,
            Circuit::Open,
            CouplerPoint::new(1.0, 1.0),
        ),
    ];
    let mut rows = Vec::new();
    for (case, l, c, p) in &cases {
        for &n in &DENSITIES {
            let degrees = uniform_angles(n, 10.0);
            for method in &methods {
                let seconds = time_per_call(reps, || {
                    black_box(method.trace(black_box(l), *c, *p, black_box(&degrees)));
                });
                let m = measure(method.as_ref(), l, *c, *p, &degrees);
                let chord = if method.name() == ClosedForm.name() {
                    chord_error(
                        l,
                        *c,
                        *p,
                        &degrees,
                        &method.trace(l, *c, *p, &degrees).points,
                    )
                } else {
                    f64::NAN
                };
                rows.push(SpeedRow {
                    method: method.name(),
                    case,
                    density: n,
                    seconds,
                    m,
                    chord,
                });
            }
        }
    }
    // CSV.
    let mut csv = format!(
        "# coupler-lab methods; {machine}\ncase,method,samples_per_dash,samples,seconds_per_curve,max_error,nans,missing,spurious,circuit_jumps,non_converged,chord_error\n"
    );
    for r in &rows {
        writeln!(
            csv,
            "{},{},{},{},{:.4e},{:.3e},{},{},{},{},{},{}",
            r.case,
            r.method,
            r.density,
            r.m.samples,
            r.seconds,
            r.m.max_error,
            r.m.nans,
            r.m.missing,
            r.m.spurious,
            r.m.circuit_jumps,
            r.m.non_converged,
            if r.chord.is_nan() {
                String::new()
            } else {
                format!("{:.3e}", r.chord)
            }
        )?;
    }
    std::fs::write(out.join("accuracy-speed.csv"), &csv)?;
    for (i, (case, ..)) in cases.iter().enumerate() {
        let file = out.join(format!(
            "accuracy-speed-{}.png",
            ["ordinary", "near-change-point"][i]
        ));
        speed_chart(&file, case, &rows, &methods)?;
    }
    // Feature accuracy.
    let feats = feature_rows();
    let mut fcsv = format!("# coupler-lab methods (features); {machine}\n");
    feature_table(&mut fcsv, &feats.series, false)?;
    std::fs::write(out.join("features.csv"), &fcsv)?;
    feature_chart(&out.join("features.png"), &feats)?;
    // Markdown summary.
    let mut md = format!(
        "## Methods: accuracy against speed\n\nMachine: {machine}\n\nCommand: `cargo run --release -p coupler-lab -- methods --out {}`\n\n",
        out.display()
    );
    for (case, ..) in &cases {
        writeln!(
            md,
            "### {case}\n\n| method | samples/dash | µs per curve | max error | NaN | jumps | not converged |\n|---|---|---|---|---|---|---|"
        )?;
        for r in rows
            .iter()
            .filter(|r| r.case == *case && [1, 10, 100].contains(&r.density))
        {
            writeln!(
                md,
                "| {} | {} | {:.1} | {:.1e} | {} | {} | {} |",
                r.method,
                r.density,
                r.seconds * 1e6,
                r.m.max_error,
                r.m.nans,
                r.m.circuit_jumps,
                r.m.non_converged
            )?;
        }
        md.push('\n');
    }
    writeln!(
        md,
        "### Closed form drawn as a polyline: chord error (crank lengths)\n\n| samples/dash | ordinary | near change point |\n|---|---|---|"
    )?;
    for &n in &DENSITIES {
        let get = |case: &str| {
            rows.iter()
                .find(|r| r.case == case && r.density == n && r.method == ClosedForm.name())
                .map(|r| r.chord)
                .unwrap_or(f64::NAN)
        };
        writeln!(
            md,
            "| {n} | {:.1e} | {:.1e} |",
            get(cases[0].0),
            get(cases[1].0)
        )?;
    }
    writeln!(
        md,
        "\n### Feature accuracy against samples per dash (relative error against the converged value: 100,000 samples/dash for ε_S, 10,000 for the arc)\n"
    )?;
    feature_table(&mut md, &feats.series, true)?;
    writeln!(md, "\n{}", feats.notes)?;
    std::fs::write(out.join("methods.md"), &md)?;
    print!("{md}");
    eprintln!(
        "wrote {}/accuracy-speed-*.png, accuracy-speed.csv, features.png, features.csv, methods.md",
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn palette(i: usize) -> RGBColor {
    const C: [RGBColor; 8] = [
        RGBColor(0, 0, 0),
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
    ];
    C[i % C.len()]
}

const FLOOR: f64 = 1e-17;

fn speed_chart(
    file: &Path,
    case: &str,
    rows: &[SpeedRow],
    methods: &[Box<dyn PositionMethod>],
) -> Result<()> {
    let rows: Vec<&SpeedRow> = rows.iter().filter(|r| r.case == case).collect();
    let tmin = rows
        .iter()
        .map(|r| r.seconds * 1e6)
        .fold(f64::INFINITY, f64::min)
        / 2.0;
    let tmax = rows.iter().map(|r| r.seconds * 1e6).fold(0.0, f64::max) * 2.0;
    let root = BitMapBackend::new(file, (1000, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "Position methods, {case}: time per curve vs max error (1…200 samples per 10° dash)"
            ),
            ("sans-serif", 20),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((tmin..tmax).log_scale(), (FLOOR..10.0f64).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("time per curve (µs, one core)")
        .y_desc("max position error (crank lengths; 1e-17 = exact)")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style(("sans-serif", 14))
        .draw()?;
    for (i, m) in methods.iter().enumerate() {
        let color = palette(i);
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.method == m.name())
            .map(|r| (r.seconds * 1e6, r.m.max_error.max(FLOOR)))
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
            .label(m.name())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
        // Mark runs that were not clean (NaN, jumps, non-convergence) with a cross.
        chart.draw_series(
            rows.iter()
                .filter(|r| r.method == m.name() && !r.m.is_clean())
                .map(|r| {
                    Cross::new(
                        (r.seconds * 1e6, r.m.max_error.max(FLOOR)),
                        7,
                        color.stroke_width(2),
                    )
                }),
        )?;
    }
    let chord: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r.method == ClosedForm.name())
        .map(|r| (r.seconds * 1e6, r.chord.max(FLOOR)))
        .collect();
    let grey = RGBColor(120, 120, 120);
    chart
        .draw_series(DashedLineSeries::new(chord, 6, 4, grey.stroke_width(2)))?
        .label("closed-form drawn as polyline (chord error)")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey.stroke_width(2)));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()?;
    root.present()?;
    Ok(())
}

/// The feature-accuracy table, one row per density of [`FEATURE_DENSITIES`]: CSV
/// (`samples_per_dash,NAME…`, values to 4 digits) or Markdown (values to 2 digits).
fn feature_table(
    out: &mut String,
    series: &[(String, Vec<f64>)],
    markdown: bool,
) -> std::fmt::Result {
    let (open, sep, close) = if markdown {
        ("| ", " | ", " |")
    } else {
        ("", ",", "")
    };
    write!(
        out,
        "{open}samples{}dash",
        if markdown { "/" } else { "_per_" }
    )?;
    for (name, _) in series {
        write!(out, "{sep}{name}")?;
    }
    writeln!(out, "{close}")?;
    if markdown {
        writeln!(out, "|---|{}", "---|".repeat(series.len()))?;
    }
    for (i, &n) in FEATURE_DENSITIES.iter().enumerate() {
        write!(out, "{open}{n}")?;
        for (_, vals) in series {
            if markdown {
                write!(out, "{sep}{:.1e}", vals[i])?;
            } else {
                write!(out, "{sep}{:.3e}", vals[i])?;
            }
        }
        writeln!(out, "{close}")?;
    }
    Ok(())
}

/// Densities for the feature chart.
pub const FEATURE_DENSITIES: [usize; 9] = [1, 2, 3, 5, 10, 20, 30, 50, 100];

struct FeatureRows {
    series: Vec<(String, Vec<f64>)>,
    notes: String,
}

fn curve_points(l: &FourBar, c: Circuit, p: CouplerPoint, degrees: &[f64]) -> Vec<Point2<f64>> {
    ClosedForm
        .trace(l, c, p, degrees)
        .points
        .into_iter()
        .flatten()
        .collect()
}

/// Samples of a window `[lo, hi]` (degrees) on the uniform grid of `n` per 10°, both ends
/// included (as Norton samples his windows).
fn window_angles(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let step = 10.0 / n as f64;
    let mut v: Vec<f64> = vec![lo];
    let mut k = (lo / step).floor() as i64 + 1;
    while (k as f64) * step < hi {
        let t = k as f64 * step;
        if t > lo {
            v.push(t);
        }
        k += 1;
    }
    v.push(hi);
    v
}

fn feature_rows() -> FeatureRows {
    let mut series = Vec::new();
    let mut notes = String::new();
    // Norton Table 3-1 rows: ε_S of Hoeken-type linkages.
    for (label, c, a, beta) in [
        ("ε_S Hoeken 20°", 2.975, 3.9625, 20.0),
        ("ε_S Hoeken 120°", 2.625, 3.4375, 120.0),
        ("ε_S Hoeken steadiest 120°", 1.825, 2.2375, 120.0),
    ] {
        let l = FourBar::new(a, a, c).expect("valid");
        let p = CouplerPoint::new(2.0 * a, 0.0);
        let eps = |n: usize| {
            straightness_along_x(&curve_points(
                &l,
                Circuit::Open,
                p,
                &window_angles(180.0 - beta / 2.0, 180.0 + beta / 2.0, n),
            ))
            .unwrap_or(f64::NAN)
        };
        let truth = eps(100_000);
        let norton = eps(5); // every 2°, as Norton samples
        writeln!(notes, "- {label}: ε_S = {:.4e} % at 2° (Norton's sampling), {:.6e} % converged (100,000 samples/dash).", norton * 100.0, truth * 100.0).ok();
        series.push((
            label.to_string(),
            FEATURE_DENSITIES
                .iter()
                .map(|&n| ((eps(n) - truth) / truth).abs())
                .collect(),
        ));
    }
    // A pseudo-arc: the best 60° window of the Hoeken curve's far side, found at fine
    // sampling, then fitted at each density.
    let l = FourBar::new(2.5, 3.0, 3.5).expect("valid");
    let p = CouplerPoint::new(1.2, -0.7);
    let fit = |lo: f64, n: usize| {
        fit_circle(&curve_points(
            &l,
            Circuit::Open,
            p,
            &window_angles(lo, lo + 60.0, n),
        ))
    };
    let best = (0..36)
        .map(|k| k as f64 * 10.0)
        .filter_map(|lo| fit(lo, 20).map(|f| (lo, f.deviation)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|x| x.0)
        .unwrap_or(0.0);
    let truth = fit(best, 10_000).expect("fits");
    writeln!(notes, "- pseudo-arc: A=2.5 B=3 C=3.5, (u, v) = (1.2, −0.7), open, θ ∈ [{best}°, {}°] (the roundest 60° window): R = {:.6}, deviation {:.3e} (converged).", best + 60.0, truth.radius, truth.deviation).ok();
    series.push((
        "arc radius".into(),
        FEATURE_DENSITIES
            .iter()
            .map(|&n| {
                fit(best, n)
                    .map(|f| ((f.radius - truth.radius) / truth.radius).abs())
                    .unwrap_or(f64::NAN)
            })
            .collect(),
    ));
    series.push((
        "arc deviation".into(),
        FEATURE_DENSITIES
            .iter()
            .map(|&n| {
                fit(best, n)
                    .map(|f| ((f.deviation - truth.deviation) / truth.deviation).abs())
                    .unwrap_or(f64::NAN)
            })
            .collect(),
    ));
    // A real arc: the rocker pin (u, v) = (A, 0) moves on the circle of radius B about O4.
    let rocker_fit = |n: usize| {
        fit_circle(&curve_points(
            &l,
            Circuit::Open,
            CouplerPoint::new(2.5, 0.0),
            &window_angles(0.0, 60.0, n),
        ))
    };
    series.push((
        "rocker-pin circle radius".into(),
        FEATURE_DENSITIES
            .iter()
            .map(|&n| {
                rocker_fit(n)
                    .map(|f| ((f.radius - 3.0) / 3.0).abs())
                    .unwrap_or(f64::NAN)
            })
            .collect(),
    ));
    writeln!(notes, "- rocker-pin circle: the rocker pin (u, v) = (A, 0) over θ ∈ [0°, 60°] lies on a true circle of radius B = 3 about O4: its fitted radius is exact at any density (a check of the fit).").ok();
    FeatureRows { series, notes }
}

fn feature_chart(file: &Path, f: &FeatureRows) -> Result<()> {
    let root = BitMapBackend::new(file, (1000, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Feature accuracy against samples per 10° dash (relative error vs converged)",
            ("sans-serif", 20),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((0.8..130.0f64).log_scale(), (1e-16..10.0f64).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("samples per 10° dash")
        .y_desc("relative error of the feature")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style(("sans-serif", 14))
        .draw()?;
    for (i, (name, vals)) in f.series.iter().enumerate() {
        let color = palette(i + 1);
        let pts: Vec<(f64, f64)> = FEATURE_DENSITIES
            .iter()
            .zip(vals)
            .filter(|(_, v)| v.is_finite())
            .map(|(&n, &v)| (n as f64, v.max(1e-16)))
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
            .label(name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()?;
    root.present()?;
    Ok(())
}

fn cell(m: &Measurement) -> String {
    let mut s = format!("{:.0e}", m.max_error);
    if m.max_error == 0.0 {
        s = "0".into();
    }
    let mut extra = Vec::new();
    if m.nans > 0 {
        extra.push(format!("{} NaN", m.nans));
    }
    if m.circuit_jumps > 0 {
        extra.push(format!("{} jump", m.circuit_jumps));
    }
    if m.non_converged > 0 {
        extra.push(format!("{} nc", m.non_converged));
    }
    if m.missing > 0 {
        extra.push(format!("{} miss", m.missing));
    }
    if m.spurious > 0 {
        extra.push(format!("{} spur", m.spurious));
    }
    if !extra.is_empty() {
        s = format!("{s} ({})", extra.join(", "));
    }
    s
}

/// `stability`: the sweep table (markdown) on stdout, and in `out/stability.md`.
pub fn stability(out: Option<&Path>) -> Result<ExitCode> {
    let methods = all_methods();
    let machine = machine();
    let mut md = format!(
        "## Stability sweep\n\nMachine: {machine}\n\nCommand: `cargo run --release -p coupler-lab -- stability`\n\n\
         Each cell: max position error against the double-double reference (crank lengths), then what went wrong: \
         `NaN` positions returned without a `None`, circuit `jump`s (closer to the other circuit), iterations not converged (`nc`), \
         samples `miss`ing (reference assembles, method says no) or `spur`ious (method gives a position where nothing assembles). \
         `bound` is the shipped closed form's documented error bound (`CurveFlags::error_bound_at`), `flags` the flags the shipped path raises.\n\n"
    );
    write!(md, "| case | samples |")?;
    for m in &methods {
        write!(md, " {} |", m.name())?;
    }
    md.push_str(" bound | flags |\n|---|---|");
    for _ in &methods {
        md.push_str("---|");
    }
    md.push_str("---|---|\n");
    let mut group = "";
    let mut worst_ratio = 0.0f64;
    let mut shipped_clean = true;
    for case in sweep_cases() {
        let row = run_case(case, &methods);
        if row.case.group != group {
            group = row.case.group;
            writeln!(md, "| **{group}** |{}", " |".repeat(methods.len() + 3))?;
        }
        write!(md, "| {} | {} |", row.case.label, row.case.degrees.len())?;
        for (_, m) in &row.results {
            write!(md, " {} |", cell(m))?;
        }
        let shipped = &row.results[0].1;
        shipped_clean &= shipped.is_clean();
        if row.flags.error_bound > 0.0 {
            worst_ratio = worst_ratio.max(shipped.max_error / row.flags.error_bound);
        }
        writeln!(
            md,
            " {:.0e} | {} |",
            row.flags.error_bound,
            row.flags.names().join(", ")
        )?;
    }
    writeln!(
        md,
        "\nShipped closed form: {} ; largest measured error / documented bound = {:.3}.",
        if shipped_clean {
            "no NaN, no circuit jump, nothing missing or spurious in any case"
        } else {
            "NOT CLEAN in some case (see table)"
        },
        worst_ratio
    )?;
    print!("{md}");
    if let Some(out) = out {
        std::fs::create_dir_all(out)?;
        std::fs::write(out.join("stability.md"), &md)?;
        eprintln!("wrote {}", out.join("stability.md").display());
    }
    Ok(if shipped_clean && worst_ratio <= 1.0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// `classics`: the measured straightness of each curve of an explicit-curve spec
/// (default `atlas-spec/classics.toml`) over its useful range: the longest run of samples
/// (on any branch of the full curve) moving one way with ε_S below each tolerance.
pub fn classics(spec: &Path, out: Option<&Path>) -> Result<ExitCode> {
    use coupler_features::{ClassicCurve, STRAIGHTNESS_TOLERANCES};
    use coupler_kinematics::{Linkage, Mechanism as _};
    use coupler_specs::CurveList;
    let text =
        std::fs::read_to_string(spec).with_context(|| format!("reading {}", spec.display()))?;
    let list =
        CurveList::parse(&text, &spec.display().to_string()).map_err(|e| anyhow::anyhow!(e))?;
    let step = list.sampling.crank_step_deg;
    let mut md = format!(
        "## {}: measured straightness\n\nCommand: `cargo run --release -p coupler-lab -- classics --spec {}` ({}° input steps, full curves across toggles).\n\n\
         For each tolerance, the longest run of consecutive samples on any branch that moves one way along its fitted line \
         (total least squares) with ε_S = (max Cy − min Cy)/Δx below it (Norton §3.8): its input span (degrees of input travel), \
         Δx (units of the input link) and ε_S.\n\n\
         | linkage | class | input range | branches |",
        list.title,
        spec.display(),
        step
    );
    for t in STRAIGHTNESS_TOLERANCES {
        write!(md, " ε_S ≤ {}%: span, Δx, ε_S |", t * 100.0)?;
    }
    md.push_str("\n|---|---|---|---|");
    for _ in STRAIGHTNESS_TOLERANCES {
        md.push_str("---|");
    }
    md.push('\n');
    let mut panels: Vec<Panel> = Vec::new();
    for c in &list.curves {
        let m = ClassicCurve::compute(c, step);
        write!(
            md,
            "| {} | {} | {} | {} |",
            c.name,
            c.linkage.class(),
            m.range_text(),
            m.branches.len()
        )?;
        let straight = match m.straight[1] {
            Some(s) => m.branches[s.branch].samples[s.samples[0]..s.samples[0] + s.samples[1]]
                .iter()
                .map(|p| (p.point.x, p.point.y))
                .collect(),
            None => Vec::new(),
        };
        panels.push(Panel {
            title: format!("{} ({})", c.name, c.linkage.class()),
            branches: m
                .branches
                .iter()
                .map(|b| b.samples.iter().map(|s| (s.point.x, s.point.y)).collect())
                .collect(),
            straight,
            pivots: vec![
                (0.0, 0.0),
                (
                    match &c.linkage {
                        Linkage::FourBar(l) => l.ground,
                        Linkage::GearedFiveBar(g) => g.l1,
                    },
                    0.0,
                ),
            ],
        });
        for s in &m.straight {
            match s {
                Some(s) => write!(
                    md,
                    " {:.1}°, {:.3}, {:.2e}% |",
                    s.input_span_deg,
                    s.extent,
                    s.straightness * 100.0
                )?,
                None => write!(md, " — |")?,
            }
        }
        md.push('\n');
    }
    print!("{md}");
    if let Some(out) = out {
        std::fs::create_dir_all(out)?;
        std::fs::write(out.join("classics.md"), &md)?;
        register_font();
        classics_figure(&out.join("classics.png"), &panels)?;
        eprintln!(
            "wrote {} and classics.png",
            out.join("classics.md").display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

struct Panel {
    title: String,
    branches: Vec<Vec<(f64, f64)>>,
    straight: Vec<(f64, f64)>,
    pivots: Vec<(f64, f64)>,
}

/// One panel per classic: every branch of the full curve (black), the longest run with
/// ε_S ≤ 0.1 % (red), the ground pivots (dots); equal scales on both axes.
fn classics_figure(file: &Path, panels: &[Panel]) -> Result<()> {
    let cols = 3;
    let rows = panels.len().div_ceil(cols);
    let root = BitMapBackend::new(file, (1200, 420 * rows as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let areas = root.split_evenly((rows, cols));
    for (panel, area) in panels.iter().zip(areas) {
        let all = panel.branches.iter().flatten().chain(panel.pivots.iter());
        let (mut x0, mut x1, mut y0, mut y1) =
            (f64::INFINITY, -f64::INFINITY, f64::INFINITY, -f64::INFINITY);
        for &(x, y) in all {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        let (w, h) = (x1 - x0, y1 - y0);
        let half = 0.55 * w.max(h * 380.0 / 330.0).max(1e-9);
        let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        let mut chart = ChartBuilder::on(&area)
            .caption(&panel.title, ("sans-serif", 18))
            .margin(8)
            .x_label_area_size(25)
            .y_label_area_size(35)
            .build_cartesian_2d(
                cx - half..cx + half,
                cy - half * 330.0 / 380.0..cy + half * 330.0 / 380.0,
            )?;
        chart
            .configure_mesh()
            .disable_mesh()
            .label_style(("sans-serif", 11))
            .draw()?;
        for b in &panel.branches {
            chart.draw_series(LineSeries::new(b.clone(), BLACK.stroke_width(1)))?;
        }
        chart.draw_series(LineSeries::new(
            panel.straight.clone(),
            RGBColor(214, 39, 40).stroke_width(4),
        ))?;
        chart.draw_series(
            panel
                .pivots
                .iter()
                .map(|&p| Circle::new(p, 4, BLUE.filled())),
        )?;
    }
    root.present()?;
    Ok(())
}

/// `adaptive`: adaptive sampling against fixed uniform sampling at equal quality
/// (the same chord-error tolerance), for page and index tolerances.
pub fn adaptive(out: Option<&Path>, reps: usize) -> Result<ExitCode> {
    use coupler_lab::{AdaptiveSampling, chord_error, uniform_closed, uniform_density_for};
    let machine = machine();
    let mut cases: Vec<(String, FourBar, Circuit, CouplerPoint)> = vec![
        (
            "ordinary A=2.5 B=3 C=3.5 (1.2, −0.7)".into(),
            FourBar::new(2.5, 3.0, 3.5)?,
            Circuit::Open,
            CouplerPoint::new(1.2, -0.7),
        ),
        (
            "Hoeken (5, 0)".into(),
            FourBar::new(2.5, 2.5, 2.0)?,
            Circuit::Open,
            CouplerPoint::new(5.0, 0.0),
        ),
        (
            "gap 1e-3 from a change point".into(),
            FourBar::new(3.0, 2.0, 2.0 + 1e-3)?,
            Circuit::Open,
            CouplerPoint::new(1.0, 1.0),
        ),
        (
            "gap 1e-6 from a change point".into(),
            FourBar::new(3.0, 2.0, 2.0 + 1e-6)?,
            Circuit::Open,
            CouplerPoint::new(1.0, 1.0),
        ),
    ];
    // A small atlas: the quick spec's grid (6 linkages × 6 points × 2 circuits).
    let mut grid = Vec::new();
    for a in [2.5, 3.0, 3.5] {
        for b in [2.5, 3.0] {
            let l = FourBar::new(a, b, 3.0)?;
            for u in [0.0, 0.5, 1.0] {
                for v in [-0.5, 0.5] {
                    for c in [Circuit::Open, Circuit::Crossed] {
                        grid.push((l, c, CouplerPoint::new(u * a, v * a)));
                    }
                }
            }
        }
    }
    let tolerances = [("page (1e-3)", 1e-3), ("index (1e-6)", 1e-6)];
    let mut md = format!(
        "## Adaptive sampling against uniform sampling at equal quality\n\nMachine: {machine}\n\nCommand: `cargo run --release -p coupler-lab -- adaptive`\n\n\
         Quality = the chord error of the polyline (largest distance between the curve and the chord between consecutive samples, \
         checked at 11 fractions of every interval, clustered towards its ends: `CHECK_FRACTIONS`), in crank lengths. Page tolerance 1e-3 ≈ 0.15 px at 150 px per crank length \
         (a Hrones–Nelson cell at 300 dpi); index tolerance 1e-6 (features to ~1e-6 relative). Uniform = the fewest samples per 10° dash \
         meeting the same tolerance. Adaptive keeps every dash boundary as a sample; *evals* counts every pose it computed (samples + rejected midpoints).\n\n\
         | curve | tolerance | adaptive samples | evals | achieved | uniform samples (per dash) | achieved | samples saved | time adaptive / uniform |\n|---|---|---|---|---|---|---|---|---|\n"
    );
    let time = |f: &mut dyn FnMut()| time_per_call(reps, f);
    let row = |name: &str,
               l: &FourBar,
               c: Circuit,
               p: CouplerPoint,
               tname: &str,
               tol: f64,
               md: &mut String|
     -> Result<(usize, usize)> {
        let sampler = AdaptiveSampling::with_tolerance(tol);
        let (angles, evals) = sampler.angles(l, c, p);
        let err_a = chord_error(l, c, p, &angles);
        let n = uniform_density_for(l, c, p, tol, 1 << 17).unwrap_or(1 << 17);
        let uni = uniform_closed(n);
        let err_u = chord_error(l, c, p, &uni);
        let ta = time(&mut || {
            let (a, _) = sampler.angles(black_box(l), c, p);
            black_box(ClosedForm.trace(l, c, p, &a));
        });
        let tu = time(&mut || {
            black_box(ClosedForm.trace(black_box(l), c, p, black_box(&uni)));
        });
        if !name.is_empty() {
            writeln!(
                md,
                "| {name} | {tname} | {} | {evals} | {err_a:.1e} | {} ({n}) | {err_u:.1e} | {:.1}× | {:.2} |",
                angles.len(),
                uni.len(),
                uni.len() as f64 / angles.len() as f64,
                ta / tu
            )?;
        }
        Ok((angles.len(), uni.len()))
    };
    for (tname, tol) in tolerances {
        for (name, l, c, p) in cases.iter_mut() {
            row(name, l, *c, *p, tname, tol, &mut md)?;
        }
        let (mut sa, mut su) = (0usize, 0usize);
        for (l, c, p) in &grid {
            let sampler = AdaptiveSampling::with_tolerance(tol);
            let (angles, _) = sampler.angles(l, *c, *p);
            sa += angles.len();
            su += 36 * uniform_density_for(l, *c, *p, tol, 1 << 17).unwrap_or(1 << 17) + 1;
        }
        writeln!(
            md,
            "| quick atlas, 72 curves, each uniform at its own best density | {tname} | {sa} | | ≤ tol | {su} | ≤ tol | {:.1}× | |",
            su as f64 / sa as f64
        )?;
        // One density for the whole atlas (as a page generator would choose it).
        let worst_n = grid
            .iter()
            .map(|(l, c, p)| uniform_density_for(l, *c, *p, tol, 1 << 17).unwrap_or(1 << 17))
            .max()
            .unwrap_or(1);
        let su_one = grid.len() * (36 * worst_n + 1);
        writeln!(
            md,
            "| quick atlas, 72 curves, one density for all ({worst_n}/dash) | {tname} | {sa} | | ≤ tol | {su_one} | ≤ tol | {:.1}× | |",
            su_one as f64 / sa as f64
        )?;
    }
    print!("{md}");
    if let Some(out) = out {
        std::fs::create_dir_all(out)?;
        std::fs::write(out.join("adaptive.md"), &md)?;
        eprintln!("wrote {}", out.join("adaptive.md").display());
    }
    Ok(ExitCode::SUCCESS)
}

/// `arclength`: per curve, the exact length's cost (the shared node poses, per group,
/// included) against the trapezoid sum on the samples, medians of `reps` passes over the
/// whole atlas on one thread; and how many curves needed refining.
fn arclength(spec: &Path, reps: usize) -> Result<ExitCode> {
    use coupler_kinematics::{ArcLength, CrankTable, Mechanism};
    let text = std::fs::read_to_string(spec).with_context(|| format!("{}", spec.display()))?;
    let name = spec.file_stem().and_then(|s| s.to_str()).unwrap_or("spec");
    let s = coupler_specs::Spec::parse(&text, name).map_err(|e| anyhow::anyhow!("{e}"))?;
    let table = CrankTable::new(s.sampling.crank_step_deg).context("sampling step")?;
    let job = coupler_generate::Job::new(s, name, "unused", 1);
    let groups: Vec<_> = job.groups().collect();
    let curves: usize = groups.iter().map(|g| g.points.len()).sum();
    let (mut exact_t, mut trap_t) = (Vec::new(), Vec::new());
    let (mut refined, mut poses, mut worst) = (0usize, 0usize, 0f64);
    for rep in 0..reps {
        let t0 = Instant::now();
        let mut sums = Vec::with_capacity(curves);
        for g in &groups {
            let mut arc = ArcLength::new(&g.linkage, g.circuit).context("assembles")?;
            for &p in &g.points {
                sums.push(black_box(arc.length(p).context("length")?));
                if rep == 0 && arc.refined_poses() > 0 {
                    refined += 1;
                    poses += arc.refined_poses();
                }
            }
        }
        exact_t.push(t0.elapsed().as_secs_f64());
        let t1 = Instant::now();
        let mut k = 0;
        for g in &groups {
            let t = g.linkage.pose_table(g.circuit, &table);
            let mut c = Default::default();
            for &p in &g.points {
                t.trace_into(p, &mut c);
                let c: &coupler_kinematics::Curve = &c;
                let l = (0..c.len()).map(|i| c.vx[i].hypot(c.vy[i])).sum::<f64>()
                    * table.step().to_radians();
                if rep == 0 {
                    worst = worst.max(((black_box(l) - sums[k]) / sums[k]).abs());
                }
                k += 1;
            }
        }
        trap_t.push(t1.elapsed().as_secs_f64());
    }
    let us = |v: &Vec<f64>| median(v.clone()) * 1e6 / curves as f64;
    println!("machine: {}", machine());
    println!(
        "{curves} curves of {}: exact length {:.2} µs per curve, trapezoid on the {}° samples {:.2} µs per curve (medians of {reps}, one thread)",
        spec.display(),
        us(&exact_t),
        table.step(),
        us(&trap_t)
    );
    println!(
        "{refined} curves refined ({poses} extra poses, {:.0} per refined curve); largest trapezoid error against the exact length {worst:.2e} relative",
        poses as f64 / refined.max(1) as f64
    );
    Ok(ExitCode::SUCCESS)
}
