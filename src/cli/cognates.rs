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
}

pub fn run(args: Args) -> Result<ExitCode> {
    let (linkage, circuit, point) = args.linkage.resolve()?;
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
