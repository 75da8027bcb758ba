//! `coupler-atlas generate [SPEC] [--out DIR] [--jobs N] [--dry-run] [--shard K/N] …` and
//! `coupler-atlas merge [--spec SPEC] --out DIR SHARD_DIR…`

use super::UsageError;
use anyhow::{Context, Result};
use coupler_atlas::CurveList;
use coupler_atlas::generate::{
    self, GenerateError, Identity, Job, Limits, NoPages, Plan, Renderer, Shard, read_identity,
};
use coupler_atlas::generate::{CurveJob, run_curve_set};
use coupler_atlas::generate::{PageOptions, PageRenderer};
use coupler_atlas::render::{PageFormat, PngCompression};
use coupler_atlas::{AtlasSpec, DEFAULT_SPEC_SOURCE, DEFAULT_SPEC_TEXT, Spec};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// At most this many worker threads (more only adds memory and contention).
const MAX_JOBS: usize = 512;

/// A spec file larger than this is not a spec (and /dev/zero is never read whole).
const MAX_SPEC_BYTES: u64 = 16 << 20;

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
    /// Page formats, comma-separated: png, svg (one file per page), pdf (one PDF of the
    /// whole atlas, contents first); default: png. With --dry-run, `json` prints the plan
    /// as JSON.
    #[arg(long, value_delimiter = ',', default_value = "png")]
    format: Vec<String>,
    /// Raster resolution of pages, dots per inch (default: the spec's).
    #[arg(long)]
    dpi: Option<f64>,
    /// Page size: tabloid, letter, a4, a3, optionally -landscape or -auto (each page chooses; default: the spec's).
    #[arg(long)]
    page_size: Option<String>,
    /// PNG compression: fast (the default: pages are encoded as fast as they are drawn)
    /// or best (smaller files for archiving, several times slower; the same pixels).
    #[arg(long, value_parser = parse_png_compression)]
    png_compression: Option<PngCompression>,
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
    /// Run even if the plan is over a limit: 5,000,000 curves, 20,000 page files, or
    /// about 20 GB on disk (see --dry-run).
    #[arg(long)]
    yes: bool,
    /// Do not show a progress bar.
    #[arg(long, short = 'q')]
    quiet: bool,
}

#[derive(clap::Args, Debug)]
pub struct MergeArgs {
    /// Check that the shards were made from this spec (the spec and settings are taken
    /// from the shards themselves).
    #[arg(long)]
    spec: Option<PathBuf>,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Check that the shards were made without pages.
    #[arg(long)]
    no_pages: bool,
    /// Check that the shards' pages are in these formats.
    #[arg(long, value_delimiter = ',')]
    format: Option<Vec<String>>,
    /// Check that the shards' pages have this resolution.
    #[arg(long)]
    dpi: Option<f64>,
    /// Check that the shards' pages have this size.
    #[arg(long)]
    page_size: Option<String>,
    /// Check that the shards' PNG pages have this compression (fast or best).
    #[arg(long, value_parser = parse_png_compression)]
    png_compression: Option<PngCompression>,
    /// Write into a folder that holds files coupler-atlas did not write (none of them is
    /// touched).
    #[arg(long)]
    force: bool,
    /// Shard output folders (from `generate --shard K/N`), in any order.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
}

fn parse_shard(s: &str) -> Result<Shard, String> {
    s.parse()
}

fn parse_png_compression(s: &str) -> Result<PngCompression, String> {
    s.parse()
}

/// Reads a spec file: at most 16 MiB (a device or a pipe that never ends is refused
/// after that much), UTF-8.
fn read_spec_file(path: &std::path::Path) -> Result<String> {
    use std::io::Read;
    let cannot = |e: String| UsageError(format!("cannot read spec {}: {e}", path.display()));
    let file = std::fs::File::open(path).map_err(|e| cannot(e.to_string()))?;
    if file.metadata().is_ok_and(|m| m.is_dir()) {
        return Err(cannot("Is a directory (os error 21)".into()).into());
    }
    let mut bytes = Vec::new();
    file.take(MAX_SPEC_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| cannot(e.to_string()))?;
    if bytes.len() as u64 > MAX_SPEC_BYTES {
        return Err(cannot(format!(
            "it is larger than {} MiB, which is not an atlas spec",
            MAX_SPEC_BYTES >> 20
        ))
        .into());
    }
    String::from_utf8(bytes).map_err(|_| cannot("stream did not contain valid UTF-8".into()).into())
}

/// The spec's text and where it came from (the built-in default when no path is given).
fn read_spec(spec: &Option<PathBuf>) -> Result<(String, String)> {
    Ok(match spec {
        None => (
            DEFAULT_SPEC_TEXT.to_string(),
            DEFAULT_SPEC_SOURCE.to_string(),
        ),
        Some(path) => (read_spec_file(path)?, path.display().to_string()),
    })
}

fn plan_grid(
    spec: Spec,
    source: String,
    text: String,
    args: &JobArgs,
    jobs: usize,
) -> Result<(Job, Box<dyn Renderer>)> {
    let out = out_dir(args, &spec.name)?;
    let mut job = Job::new(spec, source, out, jobs);
    job.force = args.force;
    job.spec_text = Some(text);
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
    // `json` selects the dry run's output format, not a page format.
    for f in args.format.iter().filter(|f| f.as_str() != "json") {
        let f: PageFormat = f
            .parse()
            .map_err(|e| UsageError(format!("--format: {e}")))?;
        if !formats.contains(&f) {
            formats.push(f);
        }
    }
    if formats.is_empty() {
        formats.push(PageFormat::Png);
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
    if let Some(c) = args.png_compression {
        opts.png_compression = c;
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

/// Installs the handler that turns SIGINT, SIGTERM and SIGHUP into a clean stop (the
/// work in progress finishes, nothing is left half-written); a second signal stops at
/// once, which is safe too.
fn stop_flag() -> Arc<AtomicBool> {
    let interrupt = Arc::new(AtomicBool::new(false));
    let flag = interrupt.clone();
    // If a handler cannot be installed (e.g. one already is), a signal just kills the
    // run, which is safe too: every file is renamed into place only when complete.
    let _ = ctrlc::set_handler(move || {
        if flag.swap(true, std::sync::atomic::Ordering::SeqCst) {
            std::process::exit(130);
        }
        eprintln!("\nstopping after the work in progress (signal again to stop at once)…");
    });
    interrupt
}

pub fn run(args: Args) -> Result<ExitCode> {
    let jobs = match args.jobs {
        Some(n) if !(1..=MAX_JOBS).contains(&n) => {
            return Err(UsageError(format!(
                "--jobs must be at least 1 and at most {MAX_JOBS}, got {n}"
            ))
            .into());
        }
        Some(n) => n,
        None => std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1),
    };
    let (text, source) = read_spec(&args.spec)?;
    let (mut job, renderer) = match AtlasSpec::parse(&text, &source)? {
        AtlasSpec::Grid(spec) => plan_grid(*spec, source, text, &args.job, jobs)?,
        AtlasSpec::Curves(list) => return run_curves(list, source, &args, jobs),
    };
    if let Some(shard) = args.shard {
        job.shard = shard;
    }
    let plan = Plan::new(&job, renderer.as_ref(), Limits::DEFAULT);
    if args.dry_run {
        if args.job.format.iter().any(|f| f == "json") {
            outln!("{}", serde_json::to_string_pretty(&plan)?)?;
        } else {
            outln!("{}", plan.describe())?;
        }
        return Ok(ExitCode::SUCCESS);
    }
    if let Some(r) = plan.refused.first() {
        return Err(UsageError(format!("{}: {r}", job.source)).into());
    }
    if let (Some(m), false) = (plan.confirmation(), args.yes) {
        return Err(UsageError(m).into());
    }
    let interrupt = stop_flag();
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
    if report.verified {
        eprintln!(
            "{}: complete and verified ({} curves, {} pages; every file has its recorded size and hash), nothing rewritten, in {:.2} s; index: {}",
            job.spec.name,
            s.curves,
            s.pages,
            start.elapsed().as_secs_f64(),
            job.out.join("index.json").display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    let mut notes = String::new();
    if report.reused_chunks > 0 {
        notes.push_str(&format!(
            ", {} of {} chunks reused from an earlier run",
            report.reused_chunks, report.total_chunks
        ));
    }
    if report.replaced {
        notes.push_str(", replacing the atlas made with other settings");
    }
    if report.removed_files > 0 {
        notes.push_str(&format!(
            ", {} file(s) of an earlier run removed",
            report.removed_files
        ));
    }
    match &report.index_path {
        Some(index) => eprintln!(
            "{}: {} curves of {} linkages ({} combinations, {} skipped as {}), {} pages, in {:.2} s{notes}; index: {}",
            job.spec.name,
            s.curves,
            s.linkages,
            s.combinations,
            skipped,
            if job.spec.geared.is_some() {
                "their input does not turn fully or their phase repeats another's curves"
            } else {
                "not strict crank-rockers"
            },
            s.pages,
            start.elapsed().as_secs_f64(),
            index.display()
        ),
        None => eprintln!(
            "{}: shard {}/{} complete in {} ({:.2} s{notes}); combine the shards with: coupler-atlas merge --out DIR SHARD_DIR…",
            job.spec.name,
            job.shard.index,
            job.shard.count,
            job.out.display(),
            start.elapsed().as_secs_f64()
        ),
    }
    Ok(ExitCode::SUCCESS)
}

/// The job recorded in shard folders: their spec and page settings, which must agree
/// (the folders that disagree are named).
fn job_from_shards(args: &MergeArgs) -> Result<(Job, Box<dyn Renderer>)> {
    let mut first: Option<(&PathBuf, Identity)> = None;
    for d in &args.shards {
        let id = read_identity(d)
            .map_err(|e| UsageError(format!("shard folder {}: {e}", d.display())))?
            .ok_or_else(|| {
                UsageError(format!(
                    "{} is not a shard folder of this version of coupler-atlas (it has no .coupler-atlas/atlas.json recording its spec); run `generate --shard K/N --out {}` to make it",
                    d.display(),
                    d.display()
                ))
            })?;
        match &first {
            None => first = Some((d, id)),
            Some((d0, id0)) => {
                if id.run_key != id0.run_key {
                    let what = if id.spec_toml != id0.spec_toml || id.name != id0.name {
                        format!(
                            "{} (atlas `{}`) and {} (atlas `{}`)",
                            id0.source, id0.name, id.source, id.name
                        )
                    } else if id.pages != id0.pages {
                        format!(
                            "the same spec with other page settings ({} vs {})",
                            describe_pages(&id0.pages),
                            describe_pages(&id.pages)
                        )
                    } else {
                        format!("{} and {}", id0.generator, id.generator)
                    };
                    return Err(UsageError(format!(
                        "the shards do not make one atlas: {} and {} were made from {what}",
                        d0.display(),
                        d.display()
                    ))
                    .into());
                }
            }
        }
    }
    let (d0, id) = first.ok_or_else(|| UsageError("no shard folders given".into()))?;
    let text = id.spec_toml.clone().ok_or_else(|| {
        UsageError(format!(
            "{} does not record its spec's text; pass --spec SPEC",
            d0.display()
        ))
    })?;
    let spec = Spec::parse(&text, &id.source)?;
    let job_args =
        JobArgs {
            out: Some(args.out.clone()),
            no_pages: id.pages.is_none(),
            format: id
                .pages
                .as_ref()
                .map(|p| p.formats.clone())
                .unwrap_or_else(|| vec!["png".into()]),
            dpi: id.pages.as_ref().map(|p| p.dpi),
            page_size: id.pages.as_ref().map(|p| p.page_size.clone()),
            png_compression: match &id.pages {
                Some(p) => Some(p.png_compression.parse().map_err(|e: String| {
                    UsageError(format!("shard folder {}: {e}", d0.display()))
                })?),
                None => None,
            },
            force: args.force,
        };
    let (job, renderer) = plan_grid(spec, id.source.clone(), text, &job_args, 1)?;
    // What the flags given to merge say must hold.
    if let Some(path) = &args.spec {
        let (text, source) = read_spec(&Some(path.clone()))?;
        let given = Spec::parse(&text, &source)?;
        if given != job.spec {
            return Err(UsageError(format!(
                "the shards were made from {} (atlas `{}`), not from --spec {} (atlas `{}`)",
                id.source, id.name, source, given.name
            ))
            .into());
        }
    }
    let mut wrong = Vec::new();
    if args.no_pages && id.pages.is_some() {
        wrong.push(format!(
            "--no-pages, but the shards have pages ({})",
            describe_pages(&id.pages)
        ));
    }
    if let (Some(f), Some(p)) = (&args.format, &id.pages) {
        if f != &p.formats {
            wrong.push(format!(
                "--format {}, but the shards' pages are {}",
                f.join(","),
                p.formats.join(",")
            ));
        }
    }
    if let (Some(d), Some(p)) = (args.dpi, &id.pages) {
        if d != p.dpi {
            wrong.push(format!(
                "--dpi {d}, but the shards' pages are {} dpi",
                p.dpi
            ));
        }
    }
    if let (Some(s), Some(p)) = (&args.page_size, &id.pages) {
        if s.parse::<coupler_atlas::layout::PageSize>()
            .map(|x| x.to_string())
            .ok()
            .as_deref()
            != Some(p.page_size.as_str())
        {
            wrong.push(format!(
                "--page-size {s}, but the shards' pages are {}",
                p.page_size
            ));
        }
    }
    if let (Some(c), Some(p)) = (args.png_compression, &id.pages) {
        if c.name() != p.png_compression {
            wrong.push(format!(
                "--png-compression {}, but the shards' pages are {}",
                c.name(),
                p.png_compression
            ));
        }
    }
    if (args.format.is_some()
        || args.dpi.is_some()
        || args.page_size.is_some()
        || args.png_compression.is_some())
        && id.pages.is_none()
    {
        wrong.push("page flags, but the shards were made without pages".into());
    }
    if !wrong.is_empty() {
        return Err(UsageError(format!("merge was given {}", wrong.join("; "))).into());
    }
    Ok((job, renderer))
}

fn describe_pages(p: &Option<coupler_atlas::generate::PageFlags>) -> String {
    match p {
        None => "no pages".into(),
        Some(p) => format!(
            "{} at {} dpi, {}, {} PNG compression",
            p.formats.join(","),
            p.dpi,
            p.page_size,
            p.png_compression
        ),
    }
}

pub fn merge(args: MergeArgs) -> Result<ExitCode> {
    for d in &args.shards {
        if !d.is_dir() {
            return Err(UsageError(format!(
                "shard folder {} does not exist or is not a folder",
                d.display()
            ))
            .into());
        }
    }
    let (job, renderer) = job_from_shards(&args)?;
    let interrupt = stop_flag();
    let index = match generate::merge(&job, renderer.as_ref(), &args.shards, &interrupt) {
        Ok(i) => i,
        Err(e @ GenerateError::Interrupted { .. }) => {
            eprintln!(
                "merge stopped: {} is incomplete (no temporary file is left); run the same command again to finish",
                e_dir(&e)
            );
            return Ok(ExitCode::from(130));
        }
        Err(e) => {
            return Err(classify(e)).with_context(|| format!("merging into {}", job.out.display()));
        }
    };
    eprintln!(
        "{}: merged {} shard folder(s); index: {}",
        job.spec.name,
        args.shards.len(),
        index.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn e_dir(e: &GenerateError) -> String {
    match e {
        GenerateError::Interrupted { dir, .. } => dir.display().to_string(),
        _ => String::new(),
    }
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
            use coupler_atlas::Mechanism as _;
            let mut dims: Vec<String> = c
                .linkage
                .dimensions()
                .iter()
                .map(|(n, x)| format!("{n} = {x}"))
                .collect();
            if let coupler_atlas::Linkage::GearedFiveBar(g) = &c.linkage {
                dims.push(format!("λ = {}", g.ratio));
                dims.push(format!("φ = {}°", g.phase));
            }
            outln!(
                "curve {}: {} ({}, point ({}, {}), class {}, trace {})",
                i + 1,
                c.name,
                dims.join(", "),
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
    // No SIGINT handler here: a page set takes well under a second, and a signal leaves
    // only complete files (every file is renamed into place when written).
    let renderer = pages.map(PageRenderer::new);
    let result = run_curve_set(&job, renderer.as_ref(), &|n| bar.inc(n));
    bar.finish_and_clear();
    let report = result
        .map_err(classify)
        .with_context(|| format!("generating {} into {}", job.list.name, job.out.display()))?;
    let removed = if report.removed_files > 0 {
        format!(
            ", {} file(s) of an earlier run removed",
            report.removed_files
        )
    } else {
        String::new()
    };
    eprintln!(
        "{}: {} curves traced in full, {} pages, {} in {:.2} s{removed}; measures: {}",
        job.list.name,
        report.curves,
        report.pages,
        if report.verified {
            "complete and verified (nothing rewritten)"
        } else {
            "written"
        },
        start.elapsed().as_secs_f64(),
        report.record_path.display()
    );
    Ok(ExitCode::SUCCESS)
}
