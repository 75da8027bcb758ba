//! `coupler-atlas generate [SPEC] [--out DIR] [--jobs N] [--dry-run] [--shard K/N] …` and
//! `coupler-atlas merge [--spec SPEC] --out DIR SHARD_DIR…`

use super::UsageError;
use anyhow::{Context, Result};
use coupler_atlas::CurveList;
use coupler_atlas::generate::{self, GenerateError, Job, NoPages, Renderer, Shard};
use coupler_atlas::generate::{CurveJob, run_curve_set};
use coupler_atlas::generate::{PageOptions, PageRenderer};
use coupler_atlas::render::PageFormat;
use coupler_atlas::{AtlasSpec, DEFAULT_SPEC_SOURCE, DEFAULT_SPEC_TEXT, Spec};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// Over this many curves, `generate` asks for `--yes` (a typo in a step is the usual cause).
const CONFIRM_OVER: u64 = 5_000_000;

/// What makes the output: the spec and the rendering flags. `merge` takes the same, and
/// refuses shards made with anything else.
#[derive(clap::Args, Debug)]
pub struct JobArgs {
    /// Output folder. Default: output/<atlas name>.
    #[arg(long)]
    out: Option<PathBuf>,
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
    /// Write into a folder that holds files coupler-atlas did not write (none of them is deleted).
    #[arg(long)]
    force: bool,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Atlas spec (TOML). Default: the built-in atlas-spec/hrones-nelson.toml.
    spec: Option<PathBuf>,
    #[command(flatten)]
    job: JobArgs,
    /// Worker threads (default: all cores).
    #[arg(long, short = 'j')]
    jobs: Option<usize>,
    /// Print the plan (linkages, curves, pages) and do no work.
    #[arg(long)]
    dry_run: bool,
    /// Compute only shard K of N (chunks c with c mod N = K − 1); combine with `merge`.
    #[arg(long, value_parser = parse_shard)]
    shard: Option<Shard>,
    /// Run even if the spec enumerates more than 5,000,000 curves.
    #[arg(long)]
    yes: bool,
    /// Do not show a progress bar.
    #[arg(long, short = 'q')]
    quiet: bool,
}

#[derive(clap::Args, Debug)]
pub struct MergeArgs {
    /// The atlas spec the shards were made from (default: the built-in one).
    #[arg(long)]
    spec: Option<PathBuf>,
    #[command(flatten)]
    job: JobArgs,
    /// Shard output folders (from `generate --shard K/N`), in any order.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
}

fn parse_shard(s: &str) -> Result<Shard, String> {
    s.parse()
}

/// The spec's text and where it came from (the built-in default when no path is given).
fn read_spec(spec: &Option<PathBuf>) -> Result<(String, String)> {
    Ok(match spec {
        None => (
            DEFAULT_SPEC_TEXT.to_string(),
            DEFAULT_SPEC_SOURCE.to_string(),
        ),
        Some(path) => (
            std::fs::read_to_string(path)
                .map_err(|e| UsageError(format!("cannot read spec {}: {e}", path.display())))?,
            path.display().to_string(),
        ),
    })
}

/// The validated job and its renderer, from the flags.
fn plan(spec: &Option<PathBuf>, args: &JobArgs, jobs: usize) -> Result<(Job, Box<dyn Renderer>)> {
    let (text, source) = read_spec(spec)?;
    let spec = Spec::parse(&text, &source)?;
    plan_grid(spec, source, args, jobs)
}

fn plan_grid(
    spec: Spec,
    source: String,
    args: &JobArgs,
    jobs: usize,
) -> Result<(Job, Box<dyn Renderer>)> {
    let out = out_dir(args, &spec.name)?;
    let mut job = Job::new(spec, source, out, jobs);
    job.force = args.force;
    let renderer: Box<dyn Renderer> = if args.no_pages {
        Box::new(NoPages)
    } else {
        Box::new(page_renderer(&job.spec, args)?)
    };
    Ok((job, renderer))
}

/// A progress bar of `total` curves on stderr (hidden with `--quiet`).
fn progress_bar(quiet: bool, total: u64) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} curves ({per_sec}, eta {eta})",
        )
        .expect("valid template"),
    );
    bar
}

/// `--out`, or `output/<atlas name>`; refused if it exists and is not a folder.
fn out_dir(args: &JobArgs, name: &str) -> Result<PathBuf> {
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("output").join(name));
    if out.exists() && !out.is_dir() {
        return Err(UsageError(format!(
            "--out {} exists and is not a folder",
            out.display()
        ))
        .into());
    }
    Ok(out)
}

/// The page renderer from the spec's `[pages]` and the page flags.
fn page_renderer(spec: &Spec, args: &JobArgs) -> Result<PageRenderer> {
    let opts =
        PageOptions::from_spec(spec).map_err(|e| UsageError(format!("page settings: {e}")))?;
    Ok(PageRenderer::new(page_options(opts, args)?))
}

/// Page options with the page flags applied.
fn page_options(mut opts: PageOptions, args: &JobArgs) -> Result<PageOptions> {
    let mut formats = Vec::new();
    for f in &args.format {
        let f: PageFormat = f
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
    Ok(opts)
}

/// Maps library errors in the user's input to exit code 2.
fn classify(e: GenerateError) -> anyhow::Error {
    if e.is_user_error() {
        UsageError(e.to_string()).into()
    } else {
        e.into()
    }
}

pub fn run(args: Args) -> Result<ExitCode> {
    let jobs = match args.jobs {
        Some(0) => return Err(UsageError("--jobs must be at least 1".into()).into()),
        Some(n) => n,
        None => std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1),
    };
    let (text, source) = read_spec(&args.spec)?;
    let (mut job, renderer) = match AtlasSpec::parse(&text, &source)? {
        AtlasSpec::Grid(spec) => plan_grid(*spec, source, &args.job, jobs)?,
        AtlasSpec::Curves(list) => return run_curves(list, source, &args, jobs),
    };
    if let Some(shard) = args.shard {
        job.shard = shard;
    }
    if args.dry_run {
        outln!("{}", job.describe())?;
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
    let interrupt = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupt.clone();
        // If a handler cannot be installed (e.g. one already is), SIGINT just kills the
        // run, which is safe too: every file is renamed into place only when complete.
        let _ = ctrlc::set_handler(move || {
            if flag.swap(true, std::sync::atomic::Ordering::SeqCst) {
                std::process::exit(130);
            }
            eprintln!(
                "\nstopping after the groups in progress (press Ctrl-C again to stop at once)…"
            );
        });
    }
    let total = job.curves();
    let bar = progress_bar(args.quiet, total);
    let start = Instant::now();
    let result = generate::run(&job, renderer.as_ref(), &|n| bar.inc(n), &interrupt);
    bar.finish_and_clear();
    let report = match result {
        Ok(r) => r,
        Err(e @ GenerateError::Interrupted { .. }) => {
            eprintln!("{e}");
            return Ok(ExitCode::from(130));
        }
        Err(e) => {
            return Err(classify(e)).with_context(|| {
                format!("generating {} into {}", job.spec.name, job.out.display())
            });
        }
    };
    let s = &report.summary;
    let skipped: u64 = s.skipped.values().sum();
    let reused = if report.reused_chunks > 0 {
        format!(
            ", {} of {} chunks reused from an earlier run",
            report.reused_chunks, report.total_chunks
        )
    } else {
        String::new()
    };
    match &report.index_path {
        Some(index) => eprintln!(
            "{}: {} curves of {} linkages ({} combinations, {} skipped as {}), {} pages, in {:.2} s{reused}; index: {}",
            job.spec.name,
            s.curves,
            s.linkages,
            s.combinations,
            skipped,
            if job.spec.geared.is_some() {
                "their input does not turn fully"
            } else {
                "not strict crank-rockers"
            },
            s.pages,
            start.elapsed().as_secs_f64(),
            index.display()
        ),
        None => eprintln!(
            "{}: shard {}/{} complete in {} ({:.2} s{reused}); combine the shards with: coupler-atlas merge [--spec SPEC] --out DIR SHARD_DIR…",
            job.spec.name,
            job.shard.index,
            job.shard.count,
            job.out.display(),
            start.elapsed().as_secs_f64()
        ),
    }
    Ok(ExitCode::SUCCESS)
}

pub fn merge(args: MergeArgs) -> Result<ExitCode> {
    let (job, renderer) = plan(&args.spec, &args.job, 1)?;
    for d in &args.shards {
        if !d.is_dir() {
            return Err(UsageError(format!(
                "shard folder {} does not exist or is not a folder",
                d.display()
            ))
            .into());
        }
    }
    let index = generate::merge(&job, renderer.as_ref(), &args.shards)
        .map_err(classify)
        .with_context(|| format!("merging into {}", job.out.display()))?;
    eprintln!(
        "{}: merged {} shard folder(s); index: {}",
        job.spec.name,
        args.shards.len(),
        index.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `generate` for a full-curve page set (`[[curve]]` entries): one page per curve.
fn run_curves(list: CurveList, source: String, args: &Args, jobs: usize) -> Result<ExitCode> {
    if args.shard.is_some() {
        return Err(UsageError(format!(
            "--shard: {source} is a full-curve page set ({} curve(s)), which is not sharded",
            list.curves.len()
        ))
        .into());
    }
    let out = out_dir(&args.job, &list.name)?;
    let pages = if args.job.no_pages {
        None
    } else {
        let opts = PageOptions::from_settings(&list.name, &list.sampling, &list.pages)
            .map_err(|e| UsageError(format!("page settings: {e}")))?;
        Some(page_options(opts, &args.job)?)
    };
    if args.dry_run {
        outln!("spec:     {} ({source}), a full-curve page set", list.name)?;
        for (i, c) in list.curves.iter().enumerate() {
            outln!(
                "curve {}: {} (A = {}, B = {}, C = {}, point ({}, {}), class {}, trace {})",
                i + 1,
                c.name,
                c.linkage.coupler,
                c.linkage.rocker,
                c.linkage.ground,
                c.point.u,
                c.point.v,
                c.linkage.class().code(),
                c.trace.name()
            )?;
        }
        outln!(
            "samples:  every {}° of input, plus the toggles",
            list.sampling.crank_step_deg
        )?;
        outln!(
            "pages:    {}",
            if pages.is_some() {
                list.curves.len()
            } else {
                0
            }
        )?;
        outln!("output:   {}", out.display())?;
        return Ok(ExitCode::SUCCESS);
    }
    let job = CurveJob {
        list,
        source,
        out,
        jobs,
        force: args.job.force,
    };
    let bar = progress_bar(args.quiet, job.list.curves.len() as u64);
    let start = Instant::now();
    // No SIGINT handler here: a page set takes well under a second, and Ctrl-C leaves
    // only complete files (every file is renamed into place when written).
    let renderer = pages.map(PageRenderer::new);
    let result = run_curve_set(&job, renderer.as_ref(), &|n| bar.inc(n));
    bar.finish_and_clear();
    let report = result
        .map_err(classify)
        .with_context(|| format!("generating {} into {}", job.list.name, job.out.display()))?;
    eprintln!(
        "{}: {} curves traced in full, {} pages, in {:.2} s; measures: {}",
        job.list.name,
        report.curves,
        report.pages,
        start.elapsed().as_secs_f64(),
        report.record_path.display()
    );
    Ok(ExitCode::SUCCESS)
}
