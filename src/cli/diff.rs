//! `coupler-atlas diff A.png B.png [--out DIFF.png] [--threshold T] [--tolerance L]`
//!
//! Compares decoded pixels, prints a score (fraction of differing pixels), writes a diff
//! image when asked, and exits 1 when the score is over the threshold (2 for unreadable
//! or mismatched inputs).

use super::UsageError;
use anyhow::Result;
use coupler_atlas::render as diff;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// First image (e.g. the expected page).
    a: PathBuf,
    /// Second image (e.g. the page just generated).
    b: PathBuf,
    /// Write a diff image here (first image faded, differing pixels red).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Largest score (fraction of differing pixels, 0–1) that still passes.
    #[arg(long, default_value_t = 0.0)]
    threshold: f64,
    /// Per-pixel tolerance in levels (0–255): smaller channel differences are ignored.
    #[arg(long, default_value_t = 0)]
    tolerance: u8,
}

pub fn run(args: Args) -> Result<ExitCode> {
    if !(args.threshold.is_finite() && (0.0..=1.0).contains(&args.threshold)) {
        return Err(UsageError(format!(
            "--threshold must be in [0, 1], got {}",
            args.threshold
        ))
        .into());
    }
    let d = diff::diff_files(&args.a, &args.b, args.tolerance).map_err(|e| match e {
        diff::DiffError::Write { .. } => anyhow::Error::from(e),
        other => UsageError(other.to_string()).into(),
    })?;
    outln!("{}", d.summary())?;
    if let Some(out) = &args.out {
        d.write_image(out)?;
        outln!("diff image: {}", out.display())?;
    }
    if d.score() > args.threshold {
        eprintln!(
            "images differ: score {:.6} > threshold {}",
            d.score(),
            args.threshold
        );
        Ok(ExitCode::from(1))
    } else {
        Ok(ExitCode::SUCCESS)
    }
}
