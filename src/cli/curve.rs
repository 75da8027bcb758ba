//! `coupler-atlas curve --coupler A --rocker B --ground C --point U,V [--circuit] [--step] [--format]`
//! (and `--mechanism geared-fivebar`: src/cli/geared.rs)

use super::curve_output::{CurveOutput, Sample, finite};
use super::{LinkageArgs, UsageError, parse_number};
use anyhow::Result;
use coupler_atlas::{CrankTable, LineDirection, Mechanism, Pose, WindowMeasures};
use serde::Serialize;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The mechanism: `four-bar` (--coupler, --rocker, --ground) or `geared-fivebar`
    /// (--l1, --l3, --l4, --l5, --ratio, --phase; sampled over its period, 360°·q of
    /// input for a gear ratio p/q).
    #[arg(long, default_value = "four-bar", value_parser = ["four-bar", "geared-fivebar"])]
    mechanism: String,
    #[command(flatten)]
    linkage: LinkageArgs,
    #[command(flatten)]
    geared: super::geared::GearedArgs,
    /// Crank step in degrees; samples at 0, step, 2·step, … below 360.
    #[arg(long, default_value = "1", value_parser = parse_number, allow_hyphen_values = true)]
    step: f64,
    /// Output format.
    #[arg(long, default_value = "json", value_parser = ["json", "csv", "table"])]
    format: String,
    /// Measure a crank window START:END in degrees (may pass 360, e.g. 300:420; it spans at
    /// most the mechanism's period: 360°, or 720° for a geared five-bar of ratio p/2), sampled
    /// every --step with both ends: adds a `"window"` object (straightness, velocity
    /// variation, best circle) to the JSON. See docs/features.md.
    #[arg(long, allow_hyphen_values = true)]
    window: Option<String>,
    /// The window's line: `fitted` (orthogonal least squares), `ground` (the +x axis, as
    /// Norton's Table 3-1), or a direction in degrees.
    #[arg(long, default_value = "fitted", allow_hyphen_values = true)]
    window_line: String,
    /// `circuit`: one circuit, θ over a full turn (null where it does not assemble);
    /// `full`: the complete coupler curve of any four-bar, driven across its toggles
    /// (every branch, changing circuit at each toggle; `--circuit` is ignored).
    #[arg(long, default_value = "circuit", value_parser = ["circuit", "full"])]
    trace: String,
}

#[derive(Serialize)]
struct Linkage {
    coupler: f64,
    rocker: f64,
    ground: f64,
}

/// The crank window's measures asked for by `--window` (sampled every `--step`) on
/// `--window-line`, for any mechanism; `None` without `--window`.
fn window<M: Mechanism>(
    args: &Args,
    linkage: &M,
    circuit: coupler_atlas::Circuit,
    p: coupler_atlas::CouplerPoint,
) -> Result<Option<WindowMeasures>, UsageError> {
    let Some(text) = &args.window else {
        return Ok(None);
    };
    let w = text
        .parse::<coupler_atlas::CrankWindow>()
        .and_then(|w| w.with_step(args.step))
        .map_err(|e| UsageError(e.to_string()))?;
    let line = match args.window_line.as_str() {
        "fitted" => LineDirection::Fitted,
        "ground" => LineDirection::Given(0.0),
        d => LineDirection::Given(parse_number(d).map_err(|e| {
            UsageError(format!(
                "--window-line must be `fitted`, `ground` or degrees: {e}"
            ))
        })?),
    };
    WindowMeasures::measure(linkage, circuit, p, &w, line)
        .map(Some)
        .map_err(|e| UsageError(e.to_string()))
}

pub fn run(args: Args) -> Result<ExitCode> {
    if args.mechanism == "geared-fivebar" {
        return run_geared(&args);
    }
    if args.geared.any() {
        return Err(UsageError(
            "--l1, --l3, --l4, --l5 and --ratio name a geared five-bar: add --mechanism geared-fivebar"
                .into(),
        )
        .into());
    }
    let (linkage, circuit, point) = args.linkage.resolve()?;
    if let Err(m) = coupler_atlas::samples_per_turn(args.step) {
        return Err(UsageError(if args.step > 0.0 && args.step <= 360.0 {
            format!("--step: {m}")
        } else {
            format!(
                "--step must be > 0 and at most 360 degrees, got {}",
                args.step
            )
        })
        .into());
    }
    let table = CrankTable::new(args.step)
        .ok_or_else(|| UsageError(format!("--step {} is not usable", args.step)))?;
    let p = point;
    let window = window(&args, &linkage, circuit, p)?;
    if args.trace == "full" {
        return super::curve_full::run(&linkage, p, table.step(), &args.format);
    }
    let flags = coupler_atlas::CurveFlags::assess(
        &linkage,
        circuit,
        p,
        &table.angles().iter().map(|a| a.degrees).collect::<Vec<_>>(),
        &coupler_atlas::FlagTolerances::DEFAULT,
    );
    let samples: Vec<Sample> = table
        .angles()
        .iter()
        .map(|angle| match Pose::solve(&linkage, circuit, angle) {
            Some(pose) => {
                let m = pose.point(p);
                let v = pose.velocity(p);
                let fin = v.x.is_finite() && v.y.is_finite();
                Sample {
                    theta_deg: angle.degrees,
                    theta5_deg: None,
                    x: finite(m.x),
                    y: finite(m.y),
                    vx: if fin { Some(v.x) } else { None },
                    vy: if fin { Some(v.y) } else { None },
                    transmission_deg: finite(pose.transmission.to_degrees()),
                }
            }
            None => Sample {
                theta_deg: angle.degrees,
                theta5_deg: None,
                x: None,
                y: None,
                vx: None,
                vy: None,
                transmission_deg: None,
            },
        })
        .collect();
    let head = format!(
        "{{\"linkage\":{}",
        serde_json::to_string(&Linkage {
            coupler: linkage.coupler,
            rocker: linkage.rocker,
            ground: linkage.ground,
        })?
    );
    CurveOutput {
        head,
        extra: String::new(),
        title: format!("{} class {}", linkage, linkage.class()),
        class: linkage.class().code(),
        circuit,
        point: p,
        samples,
        flags,
        window,
    }
    .write(&args.format)
}

/// `curve --mechanism geared-fivebar`.
fn run_geared(args: &Args) -> Result<ExitCode> {
    if args.linkage.has_four_bar_lengths() {
        return Err(UsageError(
            "--coupler, --rocker and --ground name a four-bar: a geared five-bar takes --l1, --l3, --l4, --l5, --ratio and --phase".into(),
        )
        .into());
    }
    let linkage = args.geared.resolve()?;
    let (circuit, p) = args.linkage.circuit_and_point()?;
    if !(args.step.is_finite() && args.step > 0.0 && args.step <= 360.0) {
        return Err(UsageError(format!(
            "--step must be > 0 and at most 360 degrees, got {}",
            args.step
        ))
        .into());
    }
    let window = window(args, &linkage, circuit, p)?;
    if args.trace == "full" {
        let full = linkage.trace_full(p, args.step);
        let head = super::geared::json_head(&linkage)?;
        let title = format!("geared five-bar {linkage} ({})", linkage.ting_class());
        let class = linkage.ting_class().code();
        return super::curve_full::write(&full, &head, class, &title, p, &args.format);
    }
    super::geared::output(&linkage, circuit, p, args.step, window)?.write(&args.format)
}
