//! Cost per coupler sample of the geared five-bar against the four-bar, in one run:
//! `cargo run --release --example geared_bench [ROUNDS]`.
//!
//! Both trace a 50-point coupler grid at 0.5° of input through one buffer (as `generate`
//! uses curves), the pose table built once per linkage and amortised over the grid, as
//! `coupler-atlas bench core` measures the four-bar. The rounds alternate four-bar and
//! five-bar so that both see the same load; each figure is the median over the rounds of
//! the thread's CPU time (wall time beside it). The five-bar's gear table (θ5 and the
//! half-angles, which depend only on the gears and the step) is shared by every linkage
//! with those gears, like the four-bar's crank table, and is timed separately: `generate`
//! shares it through `AngleTables` (timed so, lookup included), against the per-linkage
//! `Mechanism::pose_table` that forms the gear angles for each linkage.

use coupler_atlas::{
    AngleTables, Circuit, CouplerPoint, CrankTable, Curve, FourBar, GearRatio, GearTable,
    GearedFiveBar, Linkage, Mechanism, PoseTable,
};
use coupler_generate::{median, thread_cpu_seconds as cpu_seconds};
use std::hint::black_box;
use std::time::Instant;

/// Runs `work` (which traces `samples` samples) for at least 0.5 s of CPU; returns
/// (CPU ns per sample, wall ns per sample).
fn round(samples: usize, mut work: impl FnMut()) -> (f64, f64) {
    let (cpu0, wall0) = (cpu_seconds().unwrap_or(0.0), Instant::now());
    let mut n = 0u64;
    loop {
        work();
        n += 1;
        let wall = wall0.elapsed().as_secs_f64();
        if n % 8 == 0 && (cpu_seconds().unwrap_or(0.0) - cpu0 >= 0.5 || wall > 5.0) {
            let cpu = cpu_seconds().unwrap_or(f64::NAN) - cpu0;
            let per = 1e9 / (n as f64 * samples as f64);
            return (cpu * per, wall * per);
        }
    }
}

fn main() {
    let rounds: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(7);
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "Geared five-bar against four-bar, {} rounds; load average {}",
        rounds,
        load.split_whitespace().next().unwrap_or("?")
    );
    // The same grid shape as `bench core`: 50 points over a coupler-sized box.
    let grid = |len: f64| -> Vec<CouplerPoint> {
        (0..50)
            .map(|k| {
                CouplerPoint::new(
                    len * (k % 10) as f64 / 4.5 - 0.5 * len,
                    len * (k / 10) as f64 / 2.0 - len,
                )
            })
            .collect()
    };
    let four = FourBar::new(2.5, 3.0, 3.5).unwrap();
    let crank = CrankTable::new(0.5).unwrap();
    let four_points = grid(four.coupler);
    let cases: Vec<(&str, GearedFiveBar)> = vec![
        (
            "λ = −2, φ = 90° (720 samples)",
            GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::integer(-2).unwrap(), 90.0).unwrap(),
        ),
        (
            "λ = −1/2, φ = 0 (1440 samples: two input turns)",
            GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::new(-1, 2).unwrap(), 0.0).unwrap(),
        ),
    ];
    let mut buf = Curve::default();
    let four_samples = four_points.len() * crank.len();
    let mut four_cpu = Vec::new();
    let mut four_wall = Vec::new();
    let mut five = vec![(Vec::new(), Vec::new()); cases.len()];
    // Per linkage: `Mechanism::pose_table` on a crank table over the period, the gear
    // angles formed for each linkage rather than shared (what `generate` ran before it
    // shared them through `AngleTables`).
    let mut generic = vec![(Vec::new(), Vec::new()); cases.len()];
    let crank_tables: Vec<CrankTable> = cases
        .iter()
        .map(|(_, g)| CrankTable::over(0.5, Mechanism::period_deg(g)).unwrap())
        .collect();
    let tables: Vec<GearTable> = cases
        .iter()
        .map(|(_, g)| GearTable::for_linkage(g, 0.5).unwrap())
        .collect();
    // The pipeline's path (`generate`, pages): the run's shared tables.
    let shared = AngleTables::new(0.5).unwrap();
    for _ in 0..rounds {
        let (c, w) = round(four_samples, || {
            let poses = PoseTable::new(black_box(&four), Circuit::Open, &crank);
            for p in &four_points {
                poses.trace_into(*p, &mut buf);
                black_box(&buf);
            }
        });
        four_cpu.push(c);
        four_wall.push(w);
        for (i, (_, g)) in cases.iter().enumerate() {
            let points = grid(g.l3);
            let samples = points.len() * tables[i].len();
            let linkage = Linkage::from(*g);
            let (c, w) = round(samples, || {
                let poses = shared.pose_table(black_box(&linkage), Circuit::Open);
                for p in &points {
                    poses.trace_into(*p, &mut buf);
                    black_box(&buf);
                }
            });
            five[i].0.push(c);
            five[i].1.push(w);
            let (c, w) = round(samples, || {
                let poses = Mechanism::pose_table(black_box(g), Circuit::Open, &crank_tables[i]);
                for p in &points {
                    poses.trace_into(*p, &mut buf);
                    black_box(&buf);
                }
            });
            generic[i].0.push(c);
            generic[i].1.push(w);
        }
    }
    let f = median(four_cpu.clone());
    println!(
        "\n| curve (50 points, 0.5° of input, one core) | CPU ns/sample (median) | wall ns/sample | vs four-bar |"
    );
    println!("|---|---|---|---|");
    println!(
        "| four-bar A=2.5 B=3 C=3.5 (`bench core`'s linkage) | {f:.2} | {:.2} | 1.00 |",
        median(four_wall)
    );
    for (i, (name, _)) in cases.iter().enumerate() {
        let c = median(five[i].0.clone());
        println!(
            "| geared five-bar L1=3 L3=L4=3 L5=1, {name}, shared gear table (`AngleTables`, as `generate` runs it) | {c:.2} | {:.2} | {:.2} |",
            median(five[i].1.clone()),
            c / f
        );
        let c = median(generic[i].0.clone());
        println!(
            "| … the same through `Mechanism::pose_table` (gear angles per linkage) | {c:.2} | {:.2} | {:.2} |",
            median(generic[i].1.clone()),
            c / f
        );
    }
    // The shared tables, per input angle.
    let t = Instant::now();
    let reps = 200;
    for _ in 0..reps {
        black_box(GearTable::for_linkage(black_box(&cases[0].1), 0.5));
    }
    let gear = t.elapsed().as_secs_f64() / (reps * 720) as f64 * 1e9;
    let t = Instant::now();
    for _ in 0..reps {
        black_box(CrankTable::new(black_box(0.5)));
    }
    let crank_ns = t.elapsed().as_secs_f64() / (reps * 720) as f64 * 1e9;
    let t = Instant::now();
    for _ in 0..reps {
        black_box(cases[0].1.gear_pose_table(Circuit::Open, &tables[0]));
    }
    let pose5 = t.elapsed().as_secs_f64() / (reps * 720) as f64 * 1e9;
    let t = Instant::now();
    for _ in 0..reps {
        black_box(PoseTable::new(&four, Circuit::Open, &crank));
    }
    let pose4 = t.elapsed().as_secs_f64() / (reps * 720) as f64 * 1e9;
    println!(
        "\nper input angle (wall): pose four-bar {pose4:.1} ns, five-bar {pose5:.1} ns; shared tables: crank {crank_ns:.1} ns, gears {gear:.1} ns"
    );
}
