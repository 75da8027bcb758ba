//! `coupler-atlas bench core|pages|search`: benchmarks of the product that print a
//! markdown report (machine, date, load, medians) for `docs/benchmarks.md`, each
//! end-to-end figure beside its floor measured in the same run (the work it cannot avoid:
//! the computation alone, or reading the bytes it reads) and the ratio. Speed targets live
//! here, not in timed tests. The position-method benchmarks and charts are the lab's
//! (`cargo run --release -p coupler-lab -- methods|stability|classics|adaptive`).

use anyhow::Result;
use coupler_atlas::generate::{self, machine, median, thread_cpu_seconds};
use coupler_atlas::{Circuit, CrankTable, Curve, FourBar, PoseTable, Spec};
use std::hint::black_box;
use std::process::ExitCode;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    which: Which,
}

#[derive(clap::Subcommand, Debug)]
enum Which {
    /// Kinematic core: cost per coupler-curve sample (one core, 50-point grid, 720
    /// samples per curve) and wall time of `generate` on the default spec, index only.
    Core {
        /// Repetitions of each measurement (the median is reported).
        #[arg(long, default_value_t = 15)]
        reps: usize,
        /// Repetitions of the whole-atlas run.
        #[arg(long, default_value_t = 5)]
        atlas_reps: usize,
    },
    /// Pages: `generate` of the default atlas with pages (300 dpi tabloid grayscale PNG),
    /// wall time and the per-page split into compute, layout, draw, encode, write.
    Pages {
        /// Worker threads.
        #[arg(long, default_value_t = 2)]
        jobs: usize,
        /// Repetitions (the median wall time is reported, the split from the last).
        #[arg(long, default_value_t = 1)]
        reps: usize,
        /// Output folder (kept, so its size can be measured); default: a temporary one,
        /// removed afterwards.
        #[arg(long)]
        out: Option<std::path::PathBuf>,
    },
    /// Search: each query run in this process as `search` runs it (`--limit 10`, results
    /// discarded), wall and CPU time (all threads, to the nanosecond), beside its I/O floor measured in the
    /// same rounds: reading the whole `index.columns` a cached query maps (a query maps
    /// only the columns it tests, so the floor is an upper one and the ratio a lower one).
    /// With `--first`, also the first search of the index (hashed whole, as after
    /// `generate` or a copy) beside reading the whole `index.json`.
    Search {
        /// Atlas folder (or its index.json).
        index: std::path::PathBuf,
        /// A query as `search` takes it, in one argument (`--query "--arc 30 --sort
        /// arc"`); repeatable. Default: five queries from selective to broad.
        #[arg(long = "query", allow_hyphen_values = true)]
        queries: Vec<String>,
        /// Rounds (each times every query and floor once; medians are reported).
        #[arg(long, default_value_t = 5)]
        reps: usize,
        /// Also time the first search: removes the index's stamp (`index.json.stamp`, the
        /// key the first search writes) before each such run.
        #[arg(long)]
        first: bool,
    },
}

pub fn run(args: Args) -> Result<ExitCode> {
    match args.which {
        Which::Core { reps, atlas_reps } => core(reps.max(1), atlas_reps.max(1)),
        Which::Pages { jobs, reps, out } => pages(jobs.max(1), reps.max(1), out),
        Which::Search {
            index,
            queries,
            reps,
            first,
        } => search(&index, queries, reps.max(1), first),
    }
}

/// CPU time (user + system) of the threads of this process that are alive, seconds, to
/// the nanosecond (Linux: the sum of `/proc/self/task/*/schedstat`); `None` elsewhere.
/// Threads that ended are not counted: for work whose threads live on (the global worker
/// pool `search` uses).
fn live_threads_cpu_seconds() -> Option<f64> {
    let mut ns = 0u64;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        // A thread that ends while the list is read has no file any more: skip it.
        let Ok(s) = std::fs::read_to_string(task.ok()?.path().join("schedstat")) else {
            continue;
        };
        ns += s.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(ns as f64 * 1e-9)
}

/// CPU time (user + system) of this process since it started, threads that ended
/// included, seconds, in the kernel's clock ticks (Linux: `/proc/self/stat`, 10 ms):
/// for work that starts and ends its own threads (`generate`'s pool and writer).
fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// Wall and CPU seconds of `f` (CPU by `clock`), and its value.
fn timed<T>(clock: fn() -> Option<f64>, f: impl FnOnce() -> T) -> (f64, f64, T) {
    let (t, c) = (Instant::now(), clock());
    let v = f();
    let wall = t.elapsed().as_secs_f64();
    let cpu = match (c, clock()) {
        (Some(a), Some(b)) => b - a,
        _ => f64::NAN,
    };
    (wall, cpu, v)
}

/// The load average over the last minute, as `uptime` prints it.
fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|l| l.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "?".into())
}

/// Reads all of `path` through one 1 MiB buffer (the bytes from the page cache when they
/// are there): the I/O floor of work that reads or maps that file.
fn read_through(path: &std::path::Path) -> std::io::Result<u64> {
    use std::io::Read;
    let mut f = std::fs::File::open(path)?;
    let mut buf = vec![0u8; 1 << 20];
    let mut total = 0u64;
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            return Ok(total);
        }
        total += n as u64;
        black_box(&buf[..n]);
    }
}

/// `search`'s arguments from one query string.
#[derive(clap::Parser)]
struct SearchLine {
    #[command(flatten)]
    args: super::search::Args,
}

fn search(
    index: &std::path::Path,
    queries: Vec<String>,
    reps: usize,
    first: bool,
) -> Result<ExitCode> {
    use clap::Parser as _;
    let queries = if queries.is_empty() {
        [
            "--linkage 2.5,2.5,2",
            "--straight 120:0.5",
            "--arc 60:0.5 --min-transmission 40 --sort deviation",
            "--double-dwell --arc 40 --class GCRR",
            "--arc 30 --sort arc",
        ]
        .map(String::from)
        .to_vec()
    } else {
        queries
    };
    let dir = if index.is_dir() {
        index.to_path_buf()
    } else {
        index
            .parent()
            .map(std::path::Path::to_path_buf)
            .unwrap_or_default()
    };
    let (json, columns) = (dir.join("index.json"), dir.join("index.columns"));
    let parse = |q: &str| -> Result<super::search::Args> {
        let words = q.split_whitespace().map(str::to_string);
        let argv = ["search".to_string(), dir.display().to_string()]
            .into_iter()
            .chain(words)
            .chain(["--limit".into(), "10".into()]);
        Ok(SearchLine::try_parse_from(argv)?.args)
    };
    // Check every query parses before timing anything.
    for q in &queries {
        parse(q)?;
    }
    let load_before = load();
    let run = |q: &str| -> Result<super::search::Found> {
        super::search::run_to(parse(q)?, &mut std::io::sink(), false)
    };
    // Rounds: the floor, then every query, then (with --first) the first search and its
    // floor; so a change in the machine's load falls on all of them alike.
    let mut floor = (Vec::new(), Vec::new());
    let mut rows: Vec<(Vec<f64>, Vec<f64>, usize, usize)> =
        vec![(Vec::new(), Vec::new(), 0, 0); queries.len()];
    let mut first_rows = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut bytes = (0u64, 0u64);
    for _ in 0..reps {
        let (w, c, n) = timed(live_threads_cpu_seconds, || read_through(&columns));
        bytes.0 = n?;
        floor.0.push(w);
        floor.1.push(c);
        for (q, row) in queries.iter().zip(rows.iter_mut()) {
            let (w, c, found) = timed(live_threads_cpu_seconds, || run(q));
            let found = found?;
            row.0.push(w);
            row.1.push(c);
            (row.2, row.3) = (found.total, found.curves);
        }
        if first {
            let stamp = coupler_atlas::stamp_path(&json);
            match std::fs::remove_file(&stamp) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(anyhow::anyhow!("{}: {e}", stamp.display()));
                }
                _ => {}
            }
            let (w, c, found) = timed(
                live_threads_cpu_seconds,
                || run(&queries[queries.len() - 1]),
            );
            found?;
            first_rows.0.push(w);
            first_rows.1.push(c);
            let (w, c, n) = timed(live_threads_cpu_seconds, || read_through(&json));
            bytes.1 = n?;
            first_rows.2.push(w);
            first_rows.3.push(c);
        }
    }
    outln!(
        "## Search\n\nMachine: {}; load average {load_before} before, {} after; `{}`, {} rounds, medians\n",
        machine(),
        load(),
        dir.display(),
        reps
    )?;
    let (fw, fc) = (median(floor.0), median(floor.1));
    outln!(
        "Floor (cached): reading all of `index.columns` ({:.0} MB) from the page cache: {fw:.3} s wall, {fc:.3} s CPU.\n",
        bytes.0 as f64 / 1e6
    )?;
    outln!(
        "| query (`--limit 10`) | matches | wall | CPU | CPU / floor | target |\n|---|---|---|---|---|---|"
    )?;
    for (q, (w, c, total, curves)) in queries.iter().zip(rows) {
        let cpu = median(c);
        outln!(
            "| `{q}` | {total} of {curves} | {:.3} s | {cpu:.3} s | {:.2} | ≤ 0.1 s |",
            median(w),
            cpu / fc
        )?;
    }
    if first {
        let (w, c) = (median(first_rows.0), median(first_rows.1));
        let (jw, jc) = (median(first_rows.2), median(first_rows.3));
        outln!(
            "| first search (no stamp: `index.json` hashed whole), `{}` | | {w:.3} s | {c:.3} s | {:.2} of reading `index.json` ({:.0} MB: {jw:.3} s wall, {jc:.3} s CPU) | ≤ 1 s |",
            queries[queries.len() - 1],
            c / jc,
            bytes.1 as f64 / 1e6
        )?;
    }
    Ok(ExitCode::SUCCESS)
}

fn core(reps: usize, atlas_reps: usize) -> Result<ExitCode> {
    outln!(
        "## Kinematic core\n\nMachine: {}; load average {}\n",
        machine(),
        load()
    )?;
    let linkage = FourBar::new(2.5, 3.0, 3.5)?;
    let table = CrankTable::new(0.5).expect("valid step");
    let spec = Spec::default_atlas();
    let points = spec.points.points(linkage.coupler);
    let grid: Vec<_> = points.iter().cycle().take(50).copied().collect();
    let samples = (grid.len() * table.len()) as f64;
    let mut curves: Vec<Curve> = vec![Curve::default(); grid.len()];
    let (mut total, mut poses_only) = (Vec::new(), Vec::new());
    for _ in 0..reps {
        let t = Instant::now();
        for _ in 0..20 {
            let poses = PoseTable::new(black_box(&linkage), Circuit::Open, &table);
            for (p, c) in grid.iter().zip(curves.iter_mut()) {
                poses.trace_into(*p, c);
            }
            black_box(&curves);
        }
        total.push(t.elapsed().as_secs_f64() / 20.0);
        let t = Instant::now();
        for _ in 0..20 {
            black_box(PoseTable::new(black_box(&linkage), Circuit::Open, &table));
        }
        poses_only.push(t.elapsed().as_secs_f64() / 20.0);
    }
    let per_sample = median(total) / samples * 1e9;
    let pose = median(poses_only) / table.len() as f64 * 1e9;
    // The same work timed by the thread's CPU time, in rounds of at least 0.5 s of CPU,
    // two ways: every curve kept (50 curves, 1.15 MB of output: bound by memory
    // bandwidth), and streamed through one buffer that is consumed before the next point
    // is traced, which is how `generate` uses the tracer (output stays in cache).
    let cpu = |keep_all: bool, curves: &mut Vec<Curve>| -> Vec<f64> {
        let mut rounds = Vec::new();
        for _ in 0..5 {
            let (start, mut n) = (thread_cpu_seconds().unwrap_or(0.0), 0u64);
            let mut now = start;
            while now - start < 0.5 {
                let poses = PoseTable::new(black_box(&linkage), Circuit::Open, &table);
                for (i, p) in grid.iter().enumerate() {
                    let c = &mut curves[if keep_all { i } else { 0 }];
                    poses.trace_into(*p, c);
                    black_box(&*c);
                }
                n += 1;
                if n % 16 == 0 {
                    now = thread_cpu_seconds().unwrap_or(start + 1.0);
                }
            }
            rounds.push((now - start) / (n as f64 * samples) * 1e9);
        }
        rounds
    };
    let has_cpu_clock = thread_cpu_seconds().is_some();
    let (cpu_kept, cpu_streamed) = if has_cpu_clock {
        (
            median(cpu(true, &mut curves)),
            median(cpu(false, &mut curves)),
        )
    } else {
        (f64::NAN, f64::NAN)
    };
    outln!("| measure | median | target |\n|---|---|---|")?;
    if has_cpu_clock {
        outln!(
            "| cost per sample (position + velocity), 50 points × {} samples, 1 core, thread CPU time, curves streamed through one buffer (as `generate` uses them) | {cpu_streamed:.2} ns | ≤ 2 ns |",
            table.len()
        )?;
        outln!(
            "| the same with all 50 curves kept in memory (1.15 MB written per grid: memory-bandwidth bound) | {cpu_kept:.2} ns | |"
        )?;
    }
    outln!(
        "| all 50 curves kept, wall time (inflated when the machine is shared) | {per_sample:.2} ns | |"
    )?;
    outln!(
        "| of which the shared pose, per crank angle (amortised over 50 points: {:.2} ns/sample) | {pose:.1} ns | |",
        pose / 50.0
    )?;

    // `generate` index only, one and two threads, alternately (so load changes fall on
    // both), beside its floor measured in the same rounds: the same curves and features
    // computed in one thread with nothing formatted or written (`compute_group` over every
    // group, what the workers call).
    let job1 = generate::Job::new(spec.clone(), "built-in", "unused", 1);
    let tables = coupler_atlas::AngleTables::new(spec.sampling.crank_step_deg).expect("valid step");
    let features = spec.features.enabled.then_some(&spec.features.tolerances);
    let dash = spec.sampling.dash_pattern();
    let mut runs: [(Vec<f64>, Vec<f64>); 3] = Default::default();
    for _ in 0..atlas_reps {
        let (w, c, n) = timed(process_cpu_seconds, || -> Result<usize> {
            let mut n = 0;
            for g in job1.groups() {
                n += black_box(generate::compute_group(&tables, &g, features, &dash)?).len();
            }
            Ok(n)
        });
        n?;
        runs[0].0.push(w);
        runs[0].1.push(c);
        for jobs in [1usize, 2] {
            let dir =
                std::env::temp_dir().join(format!("coupler-atlas-bench-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            let job = generate::Job::new(spec.clone(), "built-in", &dir, jobs);
            let (w, c, report) = timed(process_cpu_seconds, || {
                generate::run(
                    &job,
                    &generate::NoPages,
                    &|_| {},
                    &std::sync::atomic::AtomicBool::new(false),
                )
            });
            black_box(report?);
            let _ = std::fs::remove_dir_all(&dir);
            runs[jobs].0.push(w);
            runs[jobs].1.push(c);
        }
    }
    let [(fw, fc), (w1, c1), (w2, c2)] = runs.map(|(w, c)| (median(w), median(c)));
    outln!(
        "\n`generate` on the default spec ({} curves), index only, {atlas_reps} alternating rounds, medians; the floor is the same curves and features computed in one thread with nothing formatted or written. CPU is the process's, all threads, in 10 ms ticks.\n",
        job1.curves()
    )?;
    outln!("| run | wall | CPU | CPU / floor | target |\n|---|---|---|---|---|")?;
    outln!("| floor: compute only, 1 thread | {fw:.3} s | {fc:.3} s | 1 | |")?;
    outln!(
        "| `generate --no-pages -j 1` | {w1:.3} s | {c1:.3} s | {:.2} | |",
        c1 / fc
    )?;
    outln!(
        "| `generate --no-pages -j 2` | {w2:.3} s | {c2:.3} s | {:.2} | |",
        c2 / fc
    )?;
    outln!(
        "| parallel efficiency, wall: (−j 1) / (2 × −j 2) | {:.0} % | | | ≥ 90 % (needs a quiet machine: compare the load above) |",
        100.0 * w1 / (2.0 * w2)
    )?;
    outln!("\nLoad average after: {}", load())?;
    Ok(ExitCode::SUCCESS)
}

fn pages(jobs: usize, reps: usize, out: Option<std::path::PathBuf>) -> Result<ExitCode> {
    use coupler_atlas::generate::{PageOptions, PageRenderer};
    outln!("## Pages\n\nMachine: {}\n", machine())?;
    let spec = Spec::default_atlas();
    let keep = out.is_some();
    let dir = out.unwrap_or_else(|| {
        std::env::temp_dir().join(format!("coupler-atlas-bench-pages-{}", std::process::id()))
    });
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..reps {
        let _ = std::fs::remove_dir_all(&dir);
        let job = generate::Job::new(spec.clone(), "built-in", &dir, jobs);
        let renderer = PageRenderer::new(PageOptions::from_spec(&job.spec)?);
        let interrupt = std::sync::atomic::AtomicBool::new(false);
        let t = Instant::now();
        generate::run(&job, &renderer, &|_| {}, &interrupt)?;
        let wall = t.elapsed().as_secs_f64();
        times.push(wall);
        last = Some((renderer.timings.seconds(), job.curves(), wall));
    }
    let bytes: u64 = std::fs::read_dir(dir.join("pages"))?
        .filter_map(|e| e.ok()?.metadata().ok())
        .map(|m| m.len())
        .sum();
    if !keep {
        let _ = std::fs::remove_dir_all(&dir);
    }
    let ((mut secs, pages), curves, wall) = last.expect("at least one run");
    // Writing (atomic rename, hashing, chunk records, index) is done by `generate`, not the
    // renderer: count it as the rest of the workers' time.
    secs[4] = (wall * jobs as f64 - secs[..4].iter().sum::<f64>()).max(0.0);
    let per = |s: f64| s / pages.max(1) as f64 * 1e3;
    let busy: f64 = secs.iter().sum();
    outln!("| measure | value | target |\n|---|---|---|")?;
    outln!(
        "| `generate` default spec with pages ({curves} curves, {pages} pages, 300 dpi tabloid 8-bit gray PNG), {jobs} threads, wall | {:.2} s | ≤ 15 s |",
        median(times)
    )?;
    outln!("| pages written | {:.0} MB | |", bytes as f64 / 1e6)?;
    let names = [
        "compute (dash sampling)",
        "layout",
        "draw (rasterise)",
        "encode (PNG)",
        "write + index (the rest of the workers' time)",
    ];
    for (name, s) in names.iter().zip(secs) {
        outln!(
            "| per page: {name} | {:.2} ms ({:.0} %) | |",
            per(s),
            100.0 * s / busy.max(1e-12)
        )?;
    }
    outln!("| per page: total (one worker) | {:.2} ms | |", per(busy))?;
    Ok(ExitCode::SUCCESS)
}
