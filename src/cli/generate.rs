//! `coupler-atlas generate [SPEC] --out DIR [--jobs N] [--dry-run]`

use super::UsageError;
use anyhow::{Context, Result};
use coupler_atlas::{DEFAULT_SPEC_SOURCE, DEFAULT_SPEC_TEXT, Spec, generate};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Over this many curves, `generate` asks for `--yes` (a typo in a step is the usual cause).
const CONFIRM_OVER: u64 = 5_000_000;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Atlas spec (TOML). Default: the built-in atlas-spec/hrones-nelson.toml.
    spec: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "output")]
    out: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long, short = 'j')]
    jobs: Option<usize>,
    /// Print the plan (linkages, curves, pages) and do no work.
    #[arg(long)]
    dry_run: bool,
    /// Index only: do not render pages.
    #[arg(long)]
    no_pages: bool,
    /// Page formats, comma-separated: png, svg (default: png).
    #[arg(long, value_delimiter = ',', default_value = "png")]
    format: Vec<String>,
    /// Raster resolution of pages, dots per inch (default: the spec's).
    #[arg(long)]
    dpi: Option<f64>,
    /// Page size: tabloid, letter, a4, a3, optionally -landscape (default: the spec's).
    #[arg(long)]
    page_size: Option<String>,
    /// Run even if the spec enumerates more than 5,000,000 curves.
    #[arg(long)]
    yes: bool,
    /// Do not show a progress bar.
    #[arg(long, short = 'q')]
    quiet: bool,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let (text, source) = match &args.spec {
        None => (
            DEFAULT_SPEC_TEXT.to_string(),
            DEFAULT_SPEC_SOURCE.to_string(),
        ),
        Some(path) => (
            std::fs::read_to_string(path)
                .map_err(|e| UsageError(format!("cannot read spec {}: {e}", path.display())))?,
            path.display().to_string(),
        ),
    };
    let spec = Spec::parse(&text, &source)?;
    let jobs = match args.jobs {
        Some(0) => return Err(UsageError("--jobs must be at least 1".into()).into()),
        Some(n) => n,
        None => std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1),
    };
    if args.out.exists() && !args.out.is_dir() {
        return Err(UsageError(format!(
            "--out {} exists and is not a folder",
            args.out.display()
        ))
        .into());
    }
    let mut job = generate::Job::new(spec, source, args.out.clone(), jobs);
    if !args.no_pages {
        let mut opts = coupler_atlas::render::pages::PageOptions::from_spec(&job.spec)
            .map_err(|e| UsageError(format!("page settings: {e}")))?;
        let mut formats = Vec::new();
        for f in &args.format {
            let f: coupler_atlas::render::PageFormat = f
                .parse()
                .map_err(|e| UsageError(format!("--format: {e}")))?;
            if !formats.contains(&f) {
                formats.push(f);
            }
        }
        opts.formats = formats;
        if let Some(dpi) = args.dpi {
            opts.setup.dpi = dpi;
        }
        if let Some(size) = &args.page_size {
            opts.setup.size = size
                .parse()
                .map_err(|e| UsageError(format!("--page-size: {e}")))?;
        }
        opts.setup
            .validate()
            .map_err(|e| UsageError(format!("page settings: {e}")))?;
        job.pages = Some(opts);
    }
    if args.dry_run {
        println!("{}", job.describe());
        return Ok(ExitCode::SUCCESS);
    }
    if job.curves() > CONFIRM_OVER && !args.yes {
        return Err(UsageError(format!(
            "{} enumerates {} curves ({} linkages × {} points × {} circuit(s)), more than {CONFIRM_OVER}; check the ranges with --dry-run, or pass --yes to run it",
            job.source,
            job.curves(),
            job.enumeration.linkages.len(),
            job.spec.points.len(),
            job.spec.circuits.len()
        ))
        .into());
    }
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        let bar = ProgressBar::with_draw_target(Some(job.curves()), ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} curves ({per_sec}, eta {eta})",
            )
            .expect("valid template"),
        );
        bar
    };
    let start = Instant::now();
    let report = generate::run(&job, &|n| bar.inc(n))
        .with_context(|| format!("generating {}", job.spec.name))?;
    bar.finish_and_clear();
    let s = &report.summary;
    let skipped: u64 = s.skipped.values().sum();
    eprintln!(
        "{}: {} curves of {} linkages ({} combinations, {} skipped as not strict crank-rockers) in {:.2} s; index: {}",
        job.spec.name,
        s.curves,
        s.linkages,
        s.combinations,
        skipped,
        start.elapsed().as_secs_f64(),
        report.index_path.display()
    );
    Ok(ExitCode::SUCCESS)
}
