//! `coupler-atlas cognates --coupler A --rocker B --ground C --point U,V [--circuit] [--format]`

use super::{LinkageArgs, UsageError};
use anyhow::Result;
use coupler_atlas::cognates;
use std::io::Write;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    linkage: LinkageArgs,
    /// Output format.
    #[arg(long, default_value = "table", value_parser = ["table", "json"])]
    format: String,
    /// Instead of the four-bar cognates, the geared five-bar that traces the same coupler
    /// curve (Norton §3.7: gear ratio +1, ground pivots O2 and O4; docs/geared-fivebar.md §8).
    #[arg(long)]
    geared_fivebar: bool,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let (linkage, circuit, point) = args.linkage.resolve()?;
    if args.geared_fivebar {
        return geared(&linkage, point, &args.format);
    }
    let three = cognates(&linkage, circuit, point).map_err(|e| UsageError(e.to_string()))?;
    let names = ["original", "cognate 1", "cognate 2"];
    let stdout = std::io::stdout();
    let mut w = std::io::BufWriter::new(stdout.lock());
    if args.format == "json" {
        let list: Vec<serde_json::Value> = three
            .iter()
            .zip(names)
            .map(|(c, name)| {
                let mut v = serde_json::to_value(c).expect("cognate serialises");
                v["name"] = name.into();
                if let Some((l, p)) = c.normalized() {
                    v["normalized"] = serde_json::json!({
                        "crank": 1.0, "coupler": l.coupler, "rocker": l.rocker, "ground": l.ground,
                        "point": {"u": p.u, "v": p.v},
                    });
                }
                v
            })
            .collect();
        let crank_rockers: Vec<&str> = three
            .iter()
            .zip(names)
            .filter(|(c, _)| c.crank_rocker)
            .map(|(_, n)| n)
            .collect();
        serde_json::to_writer_pretty(
            &mut w,
            &serde_json::json!({
                "third_pivot": three[1].pivots[1],
                "linkages": list,
                "crank_rockers": crank_rockers,
            }),
        )?;
        writeln!(w)?;
    } else {
        writeln!(
            w,
            "Roberts–Chebyshev cognates of {linkage} ({circuit}), point ({}, {})",
            point.u, point.v
        )?;
        writeln!(
            w,
            "{:<10} {:>22} {:>22} {:>8} {:>8} {:>8} {:>8} {:>20} {:>8} {:>5}  input follows",
            "",
            "crank pivot",
            "rocker pivot",
            "crank",
            "coupler",
            "rocker",
            "ground",
            "point (u, v)",
            "circuit",
            "class"
        )?;
        for (c, name) in three.iter().zip(names) {
            let p = |q: [f64; 2]| format!("({:.4}, {:.4})", q[0], q[1]);
            writeln!(
                w,
                "{name:<10} {:>22} {:>22} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>20} {:>8} {:>5}  {}{}",
                p(c.pivots[0]),
                p(c.pivots[1]),
                c.crank,
                c.coupler,
                c.rocker,
                c.ground,
                format!("({:.4}, {:.4})", c.point.u, c.point.v),
                c.circuit.name(),
                c.class,
                c.input_follows,
                if c.crank_rocker {
                    "  [crank-rocker]"
                } else {
                    ""
                }
            )?;
        }
    }
    w.flush()?;
    Ok(ExitCode::SUCCESS)
}

/// `cognates --geared-fivebar`: the geared five-bar equivalent of the four-bar.
fn geared(
    linkage: &coupler_atlas::FourBar,
    point: coupler_atlas::CouplerPoint,
    format: &str,
) -> Result<ExitCode> {
    use coupler_atlas::{InputRange, MARGIN_TOL, Rotatability, geared_equivalent};
    let eq = geared_equivalent(linkage, point).map_err(|e| UsageError(e.to_string()))?;
    let g = eq.linkage;
    let rot = match g.rotatability(MARGIN_TOL) {
        Rotatability::Full => "full",
        Rotatability::Touches => "touches_toggle",
        Rotatability::Limited => "rocks",
    };
    let range = g.input_range();
    let stdout = std::io::stdout();
    let mut w = std::io::BufWriter::new(stdout.lock());
    if format == "json" {
        serde_json::to_writer_pretty(
            &mut w,
            &serde_json::json!({
                "four_bar": {"crank": 1.0, "coupler": linkage.coupler, "rocker": linkage.rocker, "ground": linkage.ground,
                             "point": {"u": point.u, "v": point.v}, "class": linkage.class().code()},
                "geared_fivebar": g,
                "class": g.ting_class().code(),
                "scale": eq.scale,
                "point": {"u": eq.point.u, "v": eq.point.v},
                "input_offset_deg": eq.input_offset_deg,
                "rotatability": rot,
                "input_range": range,
            }),
        )?;
        writeln!(w)?;
    } else {
        writeln!(
            w,
            "Geared five-bar equivalent of {linkage} ({}), point ({}, {}) (Norton §3.7)",
            linkage.class(),
            point.u,
            point.v
        )?;
        writeln!(
            w,
            "  in its own units (input crank = 1): {g}; {}",
            g.ting_class()
        )?;
        writeln!(
            w,
            "  scale {:.6}: a five-bar length x is x·{:.6} in the four-bar's units; same O2, O4 = O5",
            eq.scale, eq.scale
        )?;
        writeln!(
            w,
            "  traces the four-bar's coupler point at its dyad joint (u, v) = ({}, 0); input angle = coupler angle + {:.6}°",
            eq.point.u, eq.input_offset_deg
        )?;
        let what = match &range {
            InputRange::Full => "its input turns fully".to_string(),
            InputRange::Never => "it cannot be assembled".to_string(),
            InputRange::Rocks { intervals } => format!(
                "its input rocks between toggles ({} range(s)), as the four-bar's coupler does",
                intervals.len()
            ),
        };
        writeln!(w, "  {what} (rotatability: {rot})")?;
        writeln!(
            w,
            "  curve: coupler-atlas curve --mechanism geared-fivebar --l1 {} --l3 {} --l4 {} --l5 {} --ratio {} --phase {} --point {},0 --trace full",
            g.l1, g.l3, g.l4, g.l5, g.ratio, g.phase, g.l3
        )?;
    }
    w.flush()?;
    Ok(ExitCode::SUCCESS)
}
