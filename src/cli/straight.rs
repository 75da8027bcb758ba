//! `coupler-atlas straight --frame P [--step DEG] [--format table|json]` and
//! `coupler-atlas straight --chart FILE [--from P0] [--to P1] [--by DP]`: the symmetric
//! Evans straight-line linkage for a frame ratio (from its design condition), its
//! Chebyshev form and measured straightness; the family chart over the frame ratio.

use super::{UsageError, parse_length, parse_number};
use anyhow::{Context, Result};
use coupler_atlas::design::{StraightDesign, evans, evans_coupler, family};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Frame ratio p = frame / crank (> 1 for a crank-rocker).
    #[arg(long, value_parser = parse_length)]
    frame: Option<f64>,
    /// Window sampling step of the straightness measures, crank degrees.
    #[arg(long, default_value = "0.5", value_parser = parse_length)]
    step: f64,
    /// Draw the family chart (straight span and ε_V against the frame ratio) to
    /// FILE.png, FILE.svg or FILE.pdf.
    #[arg(long, value_name = "FILE")]
    chart: Option<PathBuf>,
    /// Family chart: first frame ratio.
    #[arg(long, default_value = "1.25", value_parser = parse_number)]
    from: f64,
    /// Family chart: last frame ratio.
    #[arg(long, default_value = "6", value_parser = parse_number)]
    to: f64,
    /// Family chart: frame ratio step.
    #[arg(long, default_value = "0.0625", value_parser = parse_length)]
    by: f64,
    /// Resolution of a PNG chart, dots per inch.
    #[arg(long, default_value_t = 150)]
    dpi: u32,
    /// Output format.
    #[arg(long, default_value = "table", value_parser = ["table", "json"])]
    format: String,
}

fn report(d: &StraightDesign, w: &mut impl Write) -> std::io::Result<()> {
    writeln!(
        w,
        "Evans straight-line linkage (symmetric form) for frame p = {}: crank 1, coupler = rocker = a = ½(p + 1)^(3/2) = {:.6}, ground {}, point (2a, 0) = ({:.6}, 0), open circuit",
        d.frame, d.coupler, d.frame, d.point.u
    )?;
    writeln!(
        w,
        "the line: y = {:.6} (through M at θ = 180°, ({}, {:.6})), parallel to the frame; curvature there {:.2e} (the design condition makes it 0)",
        d.symmetric_point[1], d.frame, d.symmetric_point[1], d.curvature
    )?;
    writeln!(
        w,
        "straight spans (windows centred on θ = 180°, ε_S against the frame direction, sampled every window step):"
    )?;
    writeln!(
        w,
        "{:>8} {:>12} {:>10} {:>12} {:>10}   Chebyshev: {:>12} {:>10}",
        "ε_S ≤", "crank span", "stroke Δx", "ε_S", "ε_V", "input span", "ε_V"
    )?;
    for s in &d.spans {
        let cheb = match (
            s.chebyshev_input_span_deg,
            s.chebyshev_velocity_variation_pct,
        ) {
            (Some(a), Some(v)) => format!("{:>22.3}° {:>9.4}%", a, v),
            _ => format!("{:>34}", "its input reverses within"),
        };
        writeln!(
            w,
            "{:>7}% {:>11.3}° {:>10.5} {:>11}% {:>9.4}%   {cheb}",
            s.tolerance_pct,
            s.crank_span_deg,
            s.extent,
            format!("{:.4}", s.straightness_pct),
            s.velocity_variation_pct,
        )?;
    }
    let c = &d.chebyshev;
    writeln!(
        w,
        "Chebyshev form (the cognate through O2, halved: same line, half size): rockers {:.6}, coupler {}, ground {}, point at the coupler's middle; driven by a rocker (it only rocks); in units of its input rocker: coupler {:.6}, rocker 1, ground {:.6}, point ({:.6}, 0)",
        c.rockers, c.coupler, c.frame, c.normalized[0], c.normalized[2], c.normalized[3]
    )
}

pub fn run(args: Args) -> Result<ExitCode> {
    if args.frame.is_none() && args.chart.is_none() {
        return Err(
            UsageError("give --frame P (a design) or --chart FILE (the family)".into()).into(),
        );
    }
    if !(args.step > 0.0 && args.step <= 10.0) {
        return Err(UsageError(format!("--step must be in (0, 10], got {}", args.step)).into());
    }
    let chart = match &args.chart {
        Some(path) => {
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
            let format: coupler_atlas::render::PageFormat = ext.parse().map_err(|e| {
                UsageError(format!(
                    "--chart {}: {e}; the extension names the format",
                    path.display()
                ))
            })?;
            let parent = path
                .parent()
                .filter(|p| !p.as_os_str().is_empty())
                .unwrap_or(std::path::Path::new("."));
            if !parent.is_dir() {
                return Err(UsageError(format!(
                    "--chart {}: the folder {} does not exist",
                    path.display(),
                    parent.display()
                ))
                .into());
            }
            if !(args.from > 1.0 && args.to > args.from) {
                return Err(UsageError(format!(
                    "--from must be > 1 (a crank-rocker needs frame > crank) and --to > --from, got {} and {}",
                    args.from, args.to
                ))
                .into());
            }
            Some((path.clone(), format))
        }
        None => None,
    };
    let design = match args.frame {
        Some(p) => Some(evans(p, args.step).ok_or_else(|| {
            UsageError(format!(
                "frame {p}: the Evans linkage needs a frame ratio > 1 (crank the shortest link), got {p}; a = {:.4}",
                evans_coupler(p)
            ))
        })?),
        None => None,
    };
    if let Some((path, format)) = &chart {
        let n = ((args.to - args.from) / args.by).round() as usize;
        let frames: Vec<f64> = (0..=n).map(|k| args.from + k as f64 * args.by).collect();
        let fam = family(&frames, args.step);
        let display = coupler_atlas::layout::straight_family_chart(&fam);
        let bytes = super::dwell::render(&display, *format, args.dpi)?;
        coupler_atlas::generate::write_atomically(path, |w| w.write_all(&bytes))
            .with_context(|| format!("cannot write {}", path.display()))?;
        if design.is_none() {
            eprintln!(
                "family chart of {} frame ratios ({}–{}) written to {}",
                fam.len(),
                args.from,
                args.to,
                path.display()
            );
        }
    }
    if let Some(d) = design {
        let stdout = std::io::stdout();
        let mut w = std::io::BufWriter::new(stdout.lock());
        if args.format == "json" {
            serde_json::to_writer(&mut w, &d)?;
            writeln!(w)?;
        } else {
            report(&d, &mut w)?;
        }
        w.flush()?;
    }
    Ok(ExitCode::SUCCESS)
}
