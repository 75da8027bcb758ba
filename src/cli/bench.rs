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
    /// wall and CPU time, beside its output floor measured in the same rounds (each page's
    /// ink written once, its file's bytes written once and the PNG's CRC-32s computed, one
    /// thread), the ratio, and the per-page split into compute, layout, draw, encode, write.
    Pages {
        /// Worker threads.
        #[arg(long, default_value_t = 2)]
        jobs: usize,
        /// Rounds (each runs `generate` and then the floor of the pages it wrote; medians
        /// are reported, the split from the last round).
        #[arg(long, default_value_t = 3)]
        reps: usize,
        /// Output folder (kept, so its size can be measured); default: a temporary one,
        /// removed afterwards.
        #[arg(long)]
        out: Option<std::path::PathBuf>,
    },
    /// Search: each query run in this process as `search` runs it (`--limit 10`, results
    /// discarded), wall and CPU time (all threads, to the nanosecond), beside two I/O
    /// floors measured in the same rounds: reading the whole `index.columns`, and reading
    /// only the bytes of it the query reads (the chunks it checks); and its peak memory:
    /// own (`RssAnon`) and mapped files' pages (`RssFile`), sampled every millisecond.
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

/// Reads the extents `(offset, length)` of `path` through one 1 MiB buffer: the I/O
/// floor of a search that reads exactly those bytes of the mapped file.
fn read_extents(path: &std::path::Path, extents: &[(u64, u64)]) -> std::io::Result<u64> {
    use std::os::unix::fs::FileExt;
    let f = std::fs::File::open(path)?;
    let mut buf = vec![0u8; 1 << 20];
    let mut total = 0u64;
    for &(at, len) in extents {
        let mut done = 0u64;
        while done < len {
            let n = ((len - done) as usize).min(buf.len());
            f.read_exact_at(&mut buf[..n], at + done)?;
            black_box(&buf[..n]);
            done += n as u64;
        }
        total += len;
    }
    Ok(total)
}

/// This process's resident memory now, kB: (own: `RssAnon`, mapped files: `RssFile`),
/// from `/proc/self/status` (Linux; `None` elsewhere).
fn rss_now() -> Option<(u64, u64)> {
    super::search::status_kb(["RssAnon:", "RssFile:"]).map(|[a, f]| (a, f))
}

/// Resident memory while some work ran, kB: own (`RssAnon`) before it and at its peak,
/// and the peak of mapped files' pages (`RssFile`: the page cache's, shared, including
/// the program's own text).
#[derive(Clone, Copy, Debug, Default)]
struct Rss {
    anon_before: u64,
    anon_peak: u64,
    file_peak: u64,
}

/// Runs `f` while a thread samples [`rss_now`] every millisecond (and once before and
/// after), and returns its value and the peaks. The sampling thread ends before this
/// returns, so a CPU clock of the live threads read around this call does not count it.
fn with_peak_rss<T: Send>(f: impl FnOnce() -> T + Send) -> (T, Rss) {
    use std::sync::atomic::{AtomicBool, Ordering};
    let (anon, file) = rss_now().unwrap_or((0, 0));
    let stop = AtomicBool::new(false);
    let (v, peak) = std::thread::scope(|s| {
        let sampler = s.spawn(|| {
            let mut peak = (anon, file);
            loop {
                if let Some((a, f)) = rss_now() {
                    peak = (peak.0.max(a), peak.1.max(f));
                }
                if stop.load(Ordering::Relaxed) {
                    return peak;
                }
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        });
        let v = f();
        stop.store(true, Ordering::Relaxed);
        (v, sampler.join().unwrap_or((anon, file)))
    });
    (
        v,
        Rss {
            anon_before: anon,
            anon_peak: peak.0,
            file_peak: peak.1,
        },
    )
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
    // The bytes each query reads of `index.columns` (every chunk it checks): found by
    // running it once before the rounds (which also warms the page cache).
    let mut needs = Vec::with_capacity(queries.len());
    for q in &queries {
        let args = parse(q)?;
        let query = super::search::query_of(&args)?;
        let mut loaded = coupler_atlas::load(&json, true)?;
        loaded.select(&query)?;
        needs.push(loaded.extents_read().unwrap_or_default());
    }
    let load_before = load();
    let run = |q: &str| -> Result<super::search::Found> {
        super::search::run_to(parse(q)?, &mut std::io::sink(), false)
    };
    // Rounds: the floor, then every query and the floor of the bytes it reads, then
    // (with --first) the first search and its floor; so a change in the machine's load
    // falls on all of them alike.
    let mut floor = (Vec::new(), Vec::new());
    #[derive(Clone, Default)]
    struct Row {
        wall: Vec<f64>,
        cpu: Vec<f64>,
        own_wall: Vec<f64>,
        own_cpu: Vec<f64>,
        own_bytes: u64,
        rss: Vec<Rss>,
        total: usize,
        curves: usize,
    }
    let mut rows: Vec<Row> = vec![Row::default(); queries.len()];
    let mut first_rows = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut bytes = (0u64, 0u64);
    for _ in 0..reps {
        let (w, c, n) = timed(live_threads_cpu_seconds, || read_through(&columns));
        bytes.0 = n?;
        floor.0.push(w);
        floor.1.push(c);
        for ((q, row), need) in queries.iter().zip(rows.iter_mut()).zip(&needs) {
            let (w, c, (found, rss)) = timed(live_threads_cpu_seconds, || with_peak_rss(|| run(q)));
            let found = found?;
            row.wall.push(w);
            row.cpu.push(c);
            row.rss.push(rss);
            (row.total, row.curves) = (found.total, found.curves);
            let (w, c, n) = timed(live_threads_cpu_seconds, || read_extents(&columns, need));
            row.own_bytes = n?;
            row.own_wall.push(w);
            row.own_cpu.push(c);
        }
        if first {
            let stamp = coupler_atlas::stamp_path(&json);
            match std::fs::remove_file(&stamp) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(anyhow::anyhow!("{}: {e}", stamp.display()));
                }
                _ => {}
            }
            let (w, c, (found, rss)) = timed(live_threads_cpu_seconds, || {
                with_peak_rss(|| run(&queries[queries.len() - 1]))
            });
            found?;
            first_rows.0.push(w);
            first_rows.1.push(c);
            first_rows.4.push(rss);
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
        "Floor (cached), all columns: reading all of `index.columns` ({:.0} MB) from the page cache: {fw:.3} s wall, {fc:.3} s CPU. Own floor: reading the bytes of `index.columns` the query reads (the chunks it checks), the same way.\n",
        bytes.0 as f64 / 1e6
    )?;
    // Memory, MB: own (RssAnon) peak during the query and its rise over the value
    // before it, mapped files' pages (RssFile) peak; medians over the rounds.
    let mb = |kb: u64| kb as f64 / 1024.0;
    let memory = |rss: &[Rss]| {
        let own = median(rss.iter().map(|r| mb(r.anon_peak)).collect());
        let rise = median(
            rss.iter()
                .map(|r| mb(r.anon_peak.saturating_sub(r.anon_before)))
                .collect(),
        );
        let mapped = median(rss.iter().map(|r| mb(r.file_peak)).collect());
        format!("{own:.1} MB (+{rise:.1}) | {mapped:.0} MB")
    };
    outln!(
        "| query (`--limit 10`) | matches | wall | CPU | reads | own floor: wall, CPU | CPU / all-columns floor | CPU / own floor | own memory peak (rise) | mapped peak | target |\n|---|---|---|---|---|---|---|---|---|---|---|"
    )?;
    for (q, row) in queries.iter().zip(rows) {
        let cpu = median(row.cpu.clone());
        let (ow, oc) = (median(row.own_wall.clone()), median(row.own_cpu.clone()));
        outln!(
            "| `{q}` | {} of {} | {:.3} s | {cpu:.3} s | {:.0} MB | {ow:.3} s, {oc:.3} s | {:.2} | {:.2} | {} | ≤ 0.1 s, ≤ 100 MB own |",
            row.total,
            row.curves,
            median(row.wall.clone()),
            row.own_bytes as f64 / 1e6,
            cpu / fc,
            cpu / oc,
            memory(&row.rss)
        )?;
    }
    if first {
        let (w, c) = (median(first_rows.0), median(first_rows.1));
        let (jw, jc) = (median(first_rows.2), median(first_rows.3));
        outln!(
            "| first search (no stamp: `index.json` hashed whole), `{}` | | {w:.3} s | {c:.3} s | {:.0} MB (`index.json`) | {jw:.3} s, {jc:.3} s | | {:.2} | {} | ≤ 1 s, ≤ 100 MB own |",
            queries[queries.len() - 1],
            bytes.1 as f64 / 1e6,
            c / jc,
            memory(&first_rows.4)
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
    let load_before = load();
    let spec = Spec::default_atlas();
    let keep = out.is_some();
    let dir = out.unwrap_or_else(|| {
        std::env::temp_dir().join(format!("coupler-atlas-bench-pages-{}", std::process::id()))
    });
    // Alternating rounds: `generate` with pages, then the output floor of the pages that
    // run wrote (each page read back and decoded untimed, its floor timed alone); so a
    // change in the machine's load falls on both alike.
    let (mut runs, mut floors) = ((Vec::new(), Vec::new()), (Vec::new(), Vec::new()));
    let mut dense = (Vec::new(), Vec::new());
    let mut last = None;
    let mut written = PagesWritten::default();
    for round in 0..reps {
        let _ = std::fs::remove_dir_all(&dir);
        let job = generate::Job::new(spec.clone(), "built-in", &dir, jobs);
        let renderer = PageRenderer::new(PageOptions::from_spec(&job.spec)?);
        let interrupt = std::sync::atomic::AtomicBool::new(false);
        let (wall, cpu, report) = timed(process_cpu_seconds, || {
            generate::run(&job, &renderer, &|_| {}, &interrupt)
        });
        black_box(report?);
        runs.0.push(wall);
        runs.1.push(cpu);
        written = floor_of_pages(&dir.join("pages"))?;
        if written.mismatched > 0 {
            anyhow::bail!(
                "{}: {} PNG chunks whose CRC-32 does not match their bytes",
                dir.display(),
                written.mismatched
            );
        }
        floors.0.push(written.wall);
        floors.1.push(written.cpu);
        dense.0.push(written.wall + written.dense_wall);
        dense.1.push(written.cpu + written.dense_cpu);
        last = Some((renderer.timings.seconds(), job.curves(), wall, cpu));
        if !keep || round + 1 < reps {
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    let ((secs, pages), curves, wall, cpu_last) = last.expect("at least one run");
    let (rw, rc) = (median(runs.0), median(runs.1));
    let (fw, fc) = (median(floors.0), median(floors.1));
    let (dw, dc) = (median(dense.0), median(dense.1));
    let n = pages.max(1) as f64;
    let per = |s: f64| s / n * 1e3;
    outln!(
        "## Pages\n\nMachine: {}; load average {load_before} before, {} after; {reps} alternating rounds, medians\n",
        machine(),
        load()
    )?;
    outln!(
        "Floor per page: what any renderer writing the same PNG files must do with drawing and compression free: write the page's ink once (its {:.0} non-paper coverage bytes per page on average, packed, one copy), write the file's bytes once ({:.0} KB per page on average, one copy) and compute the CRC-32 the PNG format stores for every chunk (checked against the file's). One thread, CPU to the nanosecond; each page's floor is run {FLOOR_REPS} times and averaged. It leaves out the deflate, the filter, the Adler-32, drawing and layout, so it is a lower bound and the ratio an upper one; clearing is not in it because this renderer clears and encodes only the blocks it drew (the dense row below adds the issue's clear + one pass over every pixel). The `generate` CPU is the whole process's (all threads, the index too), in 10 ms ticks.\n",
        written.ink as f64 / n,
        written.bytes as f64 / n / 1e3
    )?;
    outln!("| run | wall | CPU | CPU / floor | target |\n|---|---|---|---|---|")?;
    outln!(
        "| floor: ink + file bytes + CRC-32, 1 thread, all {pages} pages | {fw:.3} s | {fc:.3} s | 1 | |"
    )?;
    outln!(
        "| `generate` default spec with pages ({curves} curves, {pages} pages, 300 dpi tabloid 8-bit gray PNG), {jobs} threads | {rw:.2} s | {rc:.2} s | {:.1} | ≤ 4 s wall |",
        rc / fc
    )?;
    outln!(
        "| per page: floor | {:.3} ms | {:.3} ms | 1 | |",
        per(fw),
        per(fc)
    )?;
    outln!(
        "| per page: `generate` (wall × {jobs} threads / pages; CPU / pages) | {:.2} ms | {:.2} ms | {:.1} | ≤ 10 ms |",
        per(rw * jobs as f64),
        per(rc),
        rc / fc
    )?;
    outln!(
        "| per page: the issue's dense floor (the floor + clearing the whole raster + one CRC-32 pass over all its final pixels; a bound only for a renderer that clears and encodes the whole page) | {:.3} ms | {:.3} ms | {:.1} of `generate`'s CPU / this | |",
        per(dw),
        per(dc),
        rc / dc
    )?;
    outln!(
        "| pages written | {:.0} MB | | | |",
        written.bytes as f64 / 1e6
    )?;
    // The workers' clocks: the renderer's phases, and `generate`'s own work on each
    // group (its curves, features and index lines; writing its files). The rest of the
    // workers' wall time is spent outside them: waiting (for the other worker at the end
    // of each chunk, for the chunk writer's fsyncs, for the CPU under load) and the
    // serial parts (start, the contents pages, the index's end).
    let [compute, layout, draw, encode, write, index] = secs;
    let timed = [compute, layout, draw, encode, index, write];
    let rest = (wall * jobs as f64 - timed.iter().sum::<f64>()).max(0.0);
    let busy = wall * jobs as f64;
    outln!(
        "\nThe split of the last round's workers' wall time ({jobs} workers × the run's wall; the renderer's and the run's own clocks):\n\n| per page | wall | share |\n|---|---|---|"
    )?;
    let names = [
        "compute (dash sampling)",
        "layout",
        "draw (rasterise)",
        "encode (PNG)",
        "index (the group's curves, features, index lines, shape records)",
        "write (the page files: create, write, hash, rename)",
        "outside the clocks (waiting for the other worker, the chunk writer or the CPU; start, contents pages, end)",
    ];
    for (name, s) in names.iter().zip(timed.iter().copied().chain([rest])) {
        outln!(
            "| {name} | {:.2} ms | {:.0} % |",
            per(s),
            100.0 * s / busy.max(1e-12)
        )?;
    }
    outln!(
        "| of all the rows above: not on a CPU (workers' wall − the process's CPU) | {:.2} ms | {:.0} % |",
        per((busy - cpu_last).max(0.0)),
        100.0 * (busy - cpu_last).max(0.0) / busy.max(1e-12)
    )?;
    outln!("| total ({jobs} workers × wall) | {:.2} ms | |", per(busy))?;
    Ok(ExitCode::SUCCESS)
}

/// How many times each page's floor is run in one timed block (the mean is taken).
const FLOOR_REPS: u32 = 4;

/// The floors of every PNG in a pages folder, summed.
#[derive(Debug, Default)]
struct PagesWritten {
    /// Wall and CPU seconds of the floors (reading and decoding not counted).
    wall: f64,
    cpu: f64,
    /// Bytes of all the PNG files, and non-paper pixels of all the pages.
    bytes: u64,
    ink: u64,
    /// Chunks whose stored CRC-32 is not the one computed (0 for sound files).
    mismatched: usize,
    /// Wall and CPU seconds of the dense floor's extra work ([`PageFloor::dense`]).
    dense_wall: f64,
    dense_cpu: f64,
}

/// Reads each PNG in `pages` back (untimed) and times its [`PageFloor`].
fn floor_of_pages(pages: &std::path::Path) -> Result<PagesWritten> {
    let mut files: Vec<_> = std::fs::read_dir(pages)?
        .map(|e| e.map(|e| e.path()))
        .collect::<std::io::Result<_>>()?;
    files.retain(|p| p.extension().is_some_and(|e| e == "png"));
    files.sort();
    let mut sum = PagesWritten::default();
    let (mut ink_out, mut png_out, mut raster) = (Vec::new(), Vec::new(), Vec::new());
    for path in files {
        let bytes = std::fs::read(&path)?;
        let floor =
            PageFloor::new(bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        // Buffers sized once, outside the timing: the floor writes, it does not allocate.
        ink_out.reserve(floor.ink.len());
        png_out.reserve(floor.png.len());
        raster.reserve(floor.gray.len());
        let (wall, cpu, bad) = timed(thread_cpu_seconds, || {
            (0..FLOOR_REPS)
                .map(|_| floor.run(&mut ink_out, &mut png_out))
                .sum::<usize>()
        });
        sum.wall += wall / f64::from(FLOOR_REPS);
        sum.cpu += cpu / f64::from(FLOOR_REPS);
        sum.bytes += floor.png.len() as u64;
        sum.ink += floor.ink.len() as u64;
        sum.mismatched += bad / FLOOR_REPS as usize;
        let (wall, cpu, _) = timed(thread_cpu_seconds, || {
            for _ in 0..FLOOR_REPS {
                black_box(floor.dense(&mut raster));
            }
        });
        sum.dense_wall += wall / f64::from(FLOOR_REPS);
        sum.dense_cpu += cpu / f64::from(FLOOR_REPS);
    }
    Ok(sum)
}

/// The output floor of one PNG page: the work any renderer that writes these exact bytes
/// must do, however fast it draws and compresses. It must produce every non-paper pixel's
/// final coverage at least once (here: those bytes written once, packed, by one copy —
/// the cheapest way to write that many bytes), write every byte of the file at least once
/// (one copy of the file), and compute the CRC-32 the PNG format stores after every chunk
/// (over the chunk's type and data, as `crc32fast` does it). Clearing the raster is not
/// in it: a renderer that visits only the blocks it drew into (as this one does) clears
/// no more than its ink. Nor is the deflate, the filter, the Adler-32 or the layout: all
/// are real work the floor leaves out, so it is a lower bound and the ratio an upper one.
struct PageFloor {
    /// The file.
    png: Vec<u8>,
    /// The page's non-paper pixels as ink coverage (255 − gray), row-major, packed.
    ink: Vec<u8>,
    /// Each chunk's CRC-covered bytes (type and data) and its stored CRC-32.
    chunks: Vec<(std::ops::Range<usize>, u32)>,
    /// The page's final gray levels, row-major (for [`PageFloor::dense`]).
    gray: Vec<u8>,
}

impl PageFloor {
    /// The floor of the 8-bit grayscale PNG `png` (decoded here, untimed).
    fn new(png: Vec<u8>) -> Result<PageFloor> {
        let mut reader = png::Decoder::new(std::io::Cursor::new(&png[..])).read_info()?;
        let info = reader.info();
        if (info.color_type, info.bit_depth) != (png::ColorType::Grayscale, png::BitDepth::Eight) {
            anyhow::bail!("not an 8-bit grayscale PNG");
        }
        let mut gray = vec![0; reader.output_buffer_size().unwrap_or(0)];
        let frame = reader.next_frame(&mut gray)?;
        gray.truncate(frame.buffer_size());
        let ink: Vec<u8> = gray
            .iter()
            .filter(|&&g| g != 255)
            .map(|&g| 255 - g)
            .collect();
        let mut chunks = Vec::new();
        let mut at = 8;
        while at + 12 <= png.len() {
            let len = u32::from_be_bytes(png[at..at + 4].try_into()?) as usize;
            let end = at + 8 + len;
            let stored = png
                .get(end..end + 4)
                .ok_or_else(|| anyhow::anyhow!("chunk at byte {at} runs past the end"))?;
            chunks.push((at + 4..end, u32::from_be_bytes(stored.try_into()?)));
            at = end + 4;
        }
        Ok(PageFloor {
            png,
            ink,
            chunks,
            gray,
        })
    }

    /// The extra work of the dense floor, for a renderer that keeps the whole page
    /// in one raster and encodes all of it (as this one did before it visited only drawn
    /// blocks): clear every pixel of the raster once (`raster`, reused, its memory already
    /// there) and read every final pixel once (one CRC-32 pass over them, the cheapest
    /// pass an encoder's filter and deflate could make). Not a lower bound on a renderer
    /// that clears and encodes only what it drew, as this one does.
    fn dense(&self, raster: &mut Vec<u8>) -> u32 {
        raster.clear();
        raster.resize(self.gray.len(), 0);
        black_box(&*raster);
        crc32fast::hash(black_box(&self.gray))
    }

    /// Does the floor's work once into `ink_out` and `png_out` (buffers reused from page
    /// to page); the number of chunks whose CRC-32 is not the stored one.
    fn run(&self, ink_out: &mut Vec<u8>, png_out: &mut Vec<u8>) -> usize {
        ink_out.clear();
        ink_out.extend_from_slice(black_box(&self.ink));
        black_box(&*ink_out);
        png_out.clear();
        png_out.extend_from_slice(black_box(&self.png));
        let file = black_box(&*png_out);
        self.chunks
            .iter()
            .filter(|(range, stored)| crc32fast::hash(&file[range.clone()]) != *stored)
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_atlas::render::{PngCompression, RasterPage};

    /// A small drawn page as `generate` encodes it, and its ink coverage.
    fn page() -> (Vec<u8>, Vec<u8>) {
        let mut page = RasterPage::new(64, 48, 72.0).expect("a page");
        page.fill_rect_px(3.0, 4.0, 20.5, 9.25);
        page.fill_rect_px(30.0, 20.0, 31.0, 47.0);
        let ink = page.ink().to_vec();
        (page.take_png(PngCompression::Fast).expect("encoded"), ink)
    }

    #[test]
    fn the_page_floor_writes_the_ink_and_the_file_and_checks_every_crc() {
        let (png, ink) = page();
        let floor = PageFloor::new(png.clone()).expect("a floor");
        let inked: Vec<u8> = ink.iter().copied().filter(|&c| c != 0).collect();
        assert!(!inked.is_empty());
        assert_eq!(floor.ink, inked, "the non-paper pixels, packed");
        // IHDR, pHYs, IDAT…, IEND: every chunk's CRC is computed and matches.
        assert!(floor.chunks.len() >= 3, "{:?}", floor.chunks);
        let (mut ink_out, mut png_out) = (Vec::new(), Vec::new());
        assert_eq!(floor.run(&mut ink_out, &mut png_out), 0);
        assert_eq!((ink_out, &png_out), (inked, &png));
        // A flipped bit in the last chunk before IEND is found: the CRCs are computed.
        let mut bad = png.clone();
        let idat = floor.chunks[floor.chunks.len() - 2].0.clone();
        bad[idat.end - 1] ^= 1;
        let bad = PageFloor {
            png: bad,
            ink: floor.ink.clone(),
            chunks: floor.chunks.clone(),
            gray: floor.gray.clone(),
        };
        assert_eq!(bad.run(&mut Vec::new(), &mut Vec::new()), 1);
        // The dense floor clears a whole raster and reads every pixel.
        let mut raster = vec![7u8; 5];
        let crc = floor.dense(&mut raster);
        assert_eq!(raster, vec![0u8; 64 * 48]);
        assert_eq!(
            crc,
            crc32fast::hash(&ink.iter().map(|c| 255 - c).collect::<Vec<_>>())
        );
    }

    #[test]
    fn the_floor_of_a_pages_folder_sums_its_pngs() {
        let dir = std::env::temp_dir().join(format!("coupler-atlas-floor-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("a folder");
        let (png, ink) = page();
        std::fs::write(dir.join("p-0001.png"), &png).expect("written");
        std::fs::write(dir.join("p-0002.png"), &png).expect("written");
        std::fs::write(dir.join("notes.txt"), "not a page").expect("written");
        let sum = floor_of_pages(&dir);
        let _ = std::fs::remove_dir_all(&dir);
        let sum = sum.expect("floors");
        assert_eq!(sum.bytes, 2 * png.len() as u64);
        assert_eq!(sum.ink, 2 * ink.iter().filter(|&&c| c != 0).count() as u64);
        assert_eq!(sum.mismatched, 0);
        assert!(sum.wall > 0.0 && sum.cpu >= 0.0, "{sum:?}");
        assert!(sum.dense_wall > 0.0 && sum.dense_cpu >= 0.0, "{sum:?}");
    }
}
