//! Subcommands, one file each. `main` maps errors to `error: …` on stderr and an exit
//! code: 0 success, 1 failure while working, 2 bad usage or input (clap uses 2 too).

/// Writes a line to stdout (as `println!`), returning the I/O error instead of
/// panicking: a closed pipe (`coupler-atlas … | head -1`) goes up to [`main`], which ends
/// quietly with status 0.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*)
    }};
}

mod bench;
mod cognates;
mod curve;
mod curve_full;
mod curve_output;
mod diff;
mod dwell;
mod geared;
mod generate;
mod search;
mod shape_match;
mod straight;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Build, render, index and search a Hrones–Nelson style atlas of four-bar coupler curves.
#[derive(Parser, Debug)]
#[command(name = "coupler-atlas", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Generate an atlas (index and pages) from a spec; the built-in Hrones–Nelson atlas by default.
    Generate(generate::Args),
    /// Combine the output folders of `generate --shard K/N` runs into one atlas.
    Merge(generate::MergeArgs),
    /// Sample the coupler curve of any single four-bar (or geared five-bar:
    /// `--mechanism geared-fivebar`).
    Curve(curve::Args),
    /// The three four-bars (Roberts–Chebyshev cognates) that trace one coupler curve.
    Cognates(cognates::Args),
    /// Design a dwell six-bar from a pseudo-arc (or a double dwell from two straight
    /// segments or two equal arcs): honoured or refused, simulated, a design card, CAD export.
    Dwell(Box<dwell::Args>),
    /// Design a straight-line four-bar for a frame ratio (the symmetric Evans linkage from
    /// its design condition, and its Chebyshev form), or chart the family.
    Straight(straight::Args),
    /// Search an atlas index by features (straight segments, arcs, dwells, transmission).
    Search(search::Args),
    /// Which atlas curves look like a target path (CSV/JSON points): ranked fits with the
    /// linkage placed in your frame, optional refinement off the grid and an overlay picture.
    Match(shape_match::Args),
    /// Benchmarks (results go to docs/benchmarks.md).
    Bench(bench::Args),
    /// Compare two page images pixel by pixel (score, diff image, exit 1 over threshold).
    Diff(diff::Args),
}

/// An error that is the user's input (exit code 2), as opposed to a failure while working.
#[derive(Debug)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Generate(args) => generate::run(args),
        Command::Merge(args) => generate::merge(args),
        Command::Curve(args) => curve::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Search(args) => search::run(args),
        Command::Match(args) => shape_match::run(args),
        Command::Cognates(args) => cognates::run(args),
        Command::Dwell(args) => dwell::run(*args),
        Command::Straight(args) => straight::run(args),
        Command::Diff(args) => diff::run(args),
    };
    match result {
        Ok(code) => code,
        // The reader of our output went away (`… | head -1`): nothing is wrong, and
        // nothing more can be said on stdout. End quietly, as `grep` does.
        Err(err) if is_broken_pipe(&err) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            if err
                .chain()
                .any(|e| e.is::<UsageError>() || e.is::<coupler_atlas::SpecError>())
            {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

/// Whether the error is a write to a closed pipe.
fn is_broken_pipe(err: &anyhow::Error) -> bool {
    use std::io::ErrorKind::BrokenPipe;
    err.chain().any(|e| {
        e.downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == BrokenPipe)
            || e.downcast_ref::<serde_json::Error>()
                .is_some_and(|e| e.io_error_kind() == Some(BrokenPipe))
    })
}

/// Parses a length flag exactly (rejects NaN, infinities, text), as an f64.
pub fn parse_number(s: &str) -> Result<f64, String> {
    let d: coupler_atlas::Decimal = s
        .parse()
        .map_err(|e: coupler_atlas::DecimalError| e.to_string())?;
    Ok(d.to_f64())
}

/// The flags that name one four-bar, a coupler point and a circuit (`curve`, `cognates`).
#[derive(clap::Args, Debug)]
pub struct LinkageArgs {
    /// Coupler length A (crank = 1). Required for a four-bar.
    #[arg(long, value_parser = parse_length, allow_hyphen_values = true)]
    coupler: Option<f64>,
    /// Rocker length B. Required for a four-bar.
    #[arg(long, value_parser = parse_length, allow_hyphen_values = true)]
    rocker: Option<f64>,
    /// Ground length C. Required for a four-bar.
    #[arg(long, value_parser = parse_length, allow_hyphen_values = true)]
    ground: Option<f64>,
    /// Coupler point U,V in the coupler frame (crank units), e.g. `--point 1.5,-0.5`.
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    point: coupler_atlas::CouplerPoint,
    /// Circuit (assembly) of the linkage.
    #[arg(long, default_value = "open", value_parser = ["open", "crossed"])]
    circuit: String,
}

impl LinkageArgs {
    /// The validated linkage, circuit and point.
    pub fn resolve(
        &self,
    ) -> Result<
        (
            coupler_atlas::FourBar,
            coupler_atlas::Circuit,
            coupler_atlas::CouplerPoint,
        ),
        UsageError,
    > {
        let need = |x: Option<f64>, flag: &str| {
            x.ok_or_else(|| {
                UsageError(format!(
                    "the four-bar needs --coupler, --rocker and --ground: {flag} is missing"
                ))
            })
        };
        let linkage = coupler_atlas::FourBar::new(
            need(self.coupler, "--coupler")?,
            need(self.rocker, "--rocker")?,
            need(self.ground, "--ground")?,
        )
        .map_err(|e| UsageError(e.to_string()))?;
        let (circuit, point) = self.circuit_and_point()?;
        Ok((linkage, circuit, point))
    }

    /// The circuit and the coupler point alone (any mechanism).
    pub fn circuit_and_point(
        &self,
    ) -> Result<(coupler_atlas::Circuit, coupler_atlas::CouplerPoint), UsageError> {
        let circuit = self.circuit.parse().map_err(UsageError)?;
        Ok((circuit, self.point))
    }

    /// Whether any of the four-bar's length flags was given.
    pub fn has_four_bar_lengths(&self) -> bool {
        self.coupler.is_some() || self.rocker.is_some() || self.ground.is_some()
    }
}

/// Parses a coupler point `U,V` (exact decimals).
pub fn parse_point(s: &str) -> Result<coupler_atlas::CouplerPoint, String> {
    let (u, v) = s
        .split_once(',')
        .ok_or_else(|| format!("expected U,V (two numbers separated by a comma), got `{s}`"))?;
    Ok(coupler_atlas::CouplerPoint::new(
        parse_number(u.trim())?,
        parse_number(v.trim())?,
    ))
}

/// Parses a positive length flag.
pub fn parse_length(s: &str) -> Result<f64, String> {
    let x = parse_number(s)?;
    if x > 0.0 {
        Ok(x)
    } else {
        Err(format!("a length must be > 0, got {s}"))
    }
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;

    #[test]
    fn command_line_definition_is_consistent() {
        Cli::command().debug_assert();
    }
}
