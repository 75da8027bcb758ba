//! What `curve --trace circuit` writes, for any mechanism (the four-bar in `curve`, the
//! geared five-bar in `geared`): the samples, the flags and the window's measures, as
//! JSON, CSV or a table.

use anyhow::Result;
use coupler_atlas::WindowMeasures;
use serde::Serialize;
use std::io::Write;
use std::process::ExitCode;

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
