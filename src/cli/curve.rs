//! `coupler-atlas curve --coupler A --rocker B --ground C --point U,V [--circuit] [--step] [--format]`
//! (and `--mechanism geared-fivebar`: src/cli/geared.rs)

use super::{LinkageArgs, UsageError, parse_number};
use anyhow::Result;
use coupler_atlas::{CrankTable, LineDirection, Mechanism, Pose, WindowMeasures};
use serde::Serialize;
use std::io::Write;
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
    /// Measure a crank window START:END in degrees (may pass 360, e.g. 300:420), sampled
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

/// One sample of the `curve` JSON contract. `None` fields print as `null`: where the
/// mechanism cannot be assembled (all but the angles), or at a toggle (velocities,
/// infinite there). `theta5_deg`, the second crank's angle, is a geared five-bar's only.
#[derive(Serialize)]
pub(super) struct Sample {
    pub theta_deg: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub theta5_deg: Option<f64>,
    pub x: Option<f64>,
    pub y: Option<f64>,
    pub vx: Option<f64>,
    pub vy: Option<f64>,
    pub transmission_deg: Option<f64>,
}

#[derive(Serialize)]
struct Linkage {
    coupler: f64,
    rocker: f64,
    ground: f64,
}

pub(super) fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// What `curve --trace circuit` writes, for any mechanism: the samples of one circuit,
/// the flags, and the crank window's measures if one was asked for. The mechanism's own
/// parts are given as text: the JSON before `"point"` and after `"class"`, the table's
/// title.
pub(super) struct CurveOutput<'a> {
    /// `{"linkage":{…}` (a four-bar) or `{"mechanism":"geared-fivebar","linkage":{…}`.
    pub head: String,
    /// JSON fields after `"class"`, each with its leading comma (may be empty).
    pub extra: String,
    /// The table's title before ` circuit …`.
    pub title: String,
    /// The class code.
    pub class: &'a str,
    pub circuit: coupler_atlas::Circuit,
    pub point: coupler_atlas::CouplerPoint,
    pub samples: Vec<Sample>,
    pub flags: coupler_atlas::CurveFlags,
    pub window: Option<WindowMeasures>,
}

impl CurveOutput<'_> {
    /// Writes it to stdout in `format` (`json`, `csv` or `table`).
    pub fn write(&self, format: &str) -> Result<ExitCode> {
        let stdout = std::io::stdout();
        let mut w = std::io::BufWriter::new(stdout.lock());
        let (p, circuit, window) = (self.point, self.circuit, &self.window);
        // A geared five-bar's samples carry the second crank's angle: a column of its own.
        let second = self.samples.iter().any(|s| s.theta5_deg.is_some());
        match format {
            "json" => {
                write!(w, "{},\"point\":", self.head)?;
                serde_json::to_writer(&mut w, &p)?;
                write!(
                    w,
                    ",\"circuit\":\"{}\",\"class\":\"{}\"{},\"samples\":[",
                    circuit.name(),
                    self.class,
                    self.extra
                )?;
                for (i, s) in self.samples.iter().enumerate() {
                    w.write_all(if i == 0 { b"\n" } else { b",\n" })?;
                    serde_json::to_writer(&mut w, s)?;
                }
                write!(w, "\n],\"flags\":")?;
                serde_json::to_writer(&mut w, &self.flags.flags)?;
                write!(w, ",\"error_bound\":{:e}", self.flags.error_bound)?;
                if let Some(m) = window {
                    write!(w, ",\"window\":")?;
                    serde_json::to_writer(&mut w, m)?;
                }
                writeln!(w, "}}")?;
            }
            "csv" => {
                let theta5 = if second { "theta5_deg," } else { "" };
                writeln!(w, "theta_deg,{theta5}x,y,vx,vy,transmission_deg")?;
                let f = |x: Option<f64>| x.map(|x| x.to_string()).unwrap_or_default();
                for s in &self.samples {
                    let theta5 = match s.theta5_deg {
                        Some(t) => format!("{t},"),
                        None => String::new(),
                    };
                    writeln!(
                        w,
                        "{},{theta5}{},{},{},{},{}",
                        s.theta_deg,
                        f(s.x),
                        f(s.y),
                        f(s.vx),
                        f(s.vy),
                        f(s.transmission_deg)
                    )?;
                }
                if let Some(m) = window {
                    // A second block after an empty line: the window's measures.
                    let o = |x: Option<f64>| x.map(|x| x.to_string()).unwrap_or_default();
                    let c = m.arc_center;
                    writeln!(w)?;
                    writeln!(
                        w,
                        "window_start_deg,window_end_deg,step_deg,samples,line,direction_deg,extent,straightness_pct,velocity_variation_pct,monotone,mean_speed,arc_center_x,arc_center_y,arc_radius,arc_deviation_pct"
                    )?;
                    writeln!(
                        w,
                        "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                        m.start_deg,
                        m.end_deg,
                        m.step_deg,
                        m.samples,
                        m.line,
                        m.direction_deg,
                        m.extent,
                        o(m.straightness_pct),
                        o(m.velocity_variation_pct),
                        m.monotone,
                        m.mean_speed,
                        o(c.map(|c| c[0])),
                        o(c.map(|c| c[1])),
                        o(m.arc_radius),
                        o(m.arc_deviation_pct)
                    )?;
                }
            }
            _ => {
                writeln!(
                    w,
                    "# {} circuit {} point ({}, {})",
                    self.title, circuit, p.u, p.v
                )?;
                let theta5 = |x: String| {
                    if second {
                        format!(" {x:>9}")
                    } else {
                        String::new()
                    }
                };
                writeln!(
                    w,
                    "{:>9}{} {:>12} {:>12} {:>12} {:>12} {:>9}",
                    "theta°",
                    theta5("theta5°".into()),
                    "x",
                    "y",
                    "vx",
                    "vy",
                    "mu°"
                )?;
                let f = |x: Option<f64>, prec: usize| {
                    x.map(|x| format!("{x:.prec$}"))
                        .unwrap_or_else(|| "-".into())
                };
                for s in &self.samples {
                    writeln!(
                        w,
                        "{:>9}{} {:>12} {:>12} {:>12} {:>12} {:>9}",
                        s.theta_deg,
                        theta5(f(s.theta5_deg, 4)),
                        f(s.x, 6),
                        f(s.y, 6),
                        f(s.vx, 6),
                        f(s.vy, 6),
                        f(s.transmission_deg, 2)
                    )?;
                }
                if let Some(m) = window {
                    let pct = |x: Option<f64>| match x {
                        None => "-".to_string(),
                        Some(x) if x != 0.0 && x.abs() < 0.01 => format!("{x:.4e} %"),
                        Some(x) => format!("{x:.4} %"),
                    };
                    writeln!(
                        w,
                        "# window {}°..{}° every {}° ({} samples), {} line at {:.4}°: Δx {:.6}, ε_S {}, ε_V {}, {}, mean speed {:.6}",
                        m.start_deg,
                        m.end_deg,
                        m.step_deg,
                        m.samples,
                        m.line,
                        m.direction_deg,
                        m.extent,
                        pct(m.straightness_pct),
                        pct(m.velocity_variation_pct),
                        if m.monotone {
                            "moves one way along it"
                        } else {
                            "does not move one way along it"
                        },
                        m.mean_speed
                    )?;
                    match (m.arc_center, m.arc_radius) {
                        (Some(c), Some(r)) => writeln!(
                            w,
                            "# window circle: centre ({:.6}, {:.6}), radius {r:.6}, deviation {}",
                            c[0],
                            c[1],
                            pct(m.arc_deviation_pct)
                        )?,
                        _ => writeln!(w, "# window circle: none (the samples are collinear)")?,
                    }
                }
            }
        }
        w.flush()?;
        Ok(ExitCode::SUCCESS)
    }
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
