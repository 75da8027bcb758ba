//! `coupler-atlas curve … --trace full`: the complete coupler curve of any four-bar, driven
//! by its input across toggles (see `coupler_atlas::trace`).

use anyhow::Result;
use coupler_atlas::{CouplerPoint, FourBar};
use coupler_atlas::{FullCurve, InputRange, trace_full};
use serde::Serialize;
use std::io::Write;
use std::process::ExitCode;

#[derive(Serialize)]
struct Sample {
    theta_deg: f64,
    circuit: &'static str,
    x: f64,
    y: f64,
    vx: Option<f64>,
    vy: Option<f64>,
    transmission_deg: f64,
    toggle: bool,
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// Writes the full curve in `format` (`json`, `csv` or `table`).
pub fn run(linkage: &FourBar, p: CouplerPoint, step: f64, format: &str) -> Result<ExitCode> {
    let full = trace_full(linkage, p, step);
    let head = format!(
        "{{\"linkage\":{{\"coupler\":{},\"rocker\":{},\"ground\":{}}}",
        serde_json::to_string(&linkage.coupler)?,
        serde_json::to_string(&linkage.rocker)?,
        serde_json::to_string(&linkage.ground)?
    );
    let title = format!("{linkage} class {}", linkage.class());
    write(&full, &head, linkage.class().code(), &title, p, format)
}

/// Writes a full curve of any mechanism: `head` opens the JSON object with the
/// mechanism's identity (`{"linkage":{…}`), `title` starts the table's first line.
pub fn write(
    full: &FullCurve,
    head: &str,
    class: &str,
    title: &str,
    p: CouplerPoint,
    format: &str,
) -> Result<ExitCode> {
    let branches: Vec<Vec<Sample>> = full
        .branches
        .iter()
        .map(|b| {
            b.samples
                .iter()
                .map(|s| {
                    let fin = s.velocity.x.is_finite() && s.velocity.y.is_finite() && !s.toggle;
                    Sample {
                        theta_deg: s.degrees,
                        circuit: s.circuit.name(),
                        x: s.point.x,
                        y: s.point.y,
                        vx: if fin { finite(s.velocity.x) } else { None },
                        vy: if fin { finite(s.velocity.y) } else { None },
                        transmission_deg: s.transmission.to_degrees(),
                        toggle: s.toggle,
                    }
                })
                .collect()
        })
        .collect();
    let stdout = std::io::stdout();
    let mut w = std::io::BufWriter::new(stdout.lock());
    match format {
        "json" => {
            write!(w, "{head},\"point\":")?;
            serde_json::to_writer(&mut w, &p)?;
            write!(
                w,
                ",\"trace\":\"full\",\"class\":\"{class}\",\"input_range\":"
            )?;
            serde_json::to_writer(&mut w, &full.range)?;
            write!(w, ",\"branches\":[")?;
            for (i, b) in branches.iter().enumerate() {
                if i > 0 {
                    write!(w, ",")?;
                }
                write!(w, "\n{{\"samples\":[")?;
                for (j, s) in b.iter().enumerate() {
                    w.write_all(if j == 0 { b"\n" } else { b",\n" })?;
                    serde_json::to_writer(&mut w, s)?;
                }
                write!(w, "\n]}}")?;
            }
            writeln!(w, "\n]}}")?;
        }
        "csv" => {
            writeln!(
                w,
                "branch,theta_deg,circuit,x,y,vx,vy,transmission_deg,toggle"
            )?;
            let f = |x: Option<f64>| x.map(|x| x.to_string()).unwrap_or_default();
            for (i, b) in branches.iter().enumerate() {
                for s in b {
                    writeln!(
                        w,
                        "{i},{},{},{},{},{},{},{},{}",
                        s.theta_deg,
                        s.circuit,
                        s.x,
                        s.y,
                        f(s.vx),
                        f(s.vy),
                        s.transmission_deg,
                        s.toggle
                    )?;
                }
            }
        }
        _ => {
            let range = match &full.range {
                InputRange::Full => "input turns fully".to_string(),
                InputRange::Never => "cannot be assembled at any input angle".to_string(),
                InputRange::Rocks { intervals } => intervals
                    .iter()
                    .map(|(lo, hi)| format!("[{:.6}°, {:.6}°]", lo.degrees, hi.degrees))
                    .collect::<Vec<_>>()
                    .join(" and "),
            };
            writeln!(w, "# {title} point ({}, {}); input: {range}", p.u, p.v)?;
            for (i, b) in branches.iter().enumerate() {
                writeln!(w, "# branch {i}: {} samples", b.len())?;
                writeln!(
                    w,
                    "{:>12} {:>8} {:>12} {:>12} {:>9} toggle",
                    "theta°", "circuit", "x", "y", "mu°"
                )?;
                for s in b {
                    writeln!(
                        w,
                        "{:>12.6} {:>8} {:>12.6} {:>12.6} {:>9.2} {}",
                        s.theta_deg,
                        s.circuit,
                        s.x,
                        s.y,
                        s.transmission_deg,
                        if s.toggle { "*" } else { "" }
                    )?;
                }
            }
        }
    }
    w.flush()?;
    Ok(if full.branches.is_empty() {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
