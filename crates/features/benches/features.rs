//! Feature extraction per curve, by part: `cargo bench -p coupler-features --bench features`.
//!
//! The workload is the 1768 curves of `tests/features.rs` (`feature_cost_per_curve`): four
//! linkages × both circuits × a 17 × 13 grid of coupler points, at the default tolerances.
//! Each pass extracts every feature of every curve through `FeatureExtractor`, then runs
//! each part over every curve; the report gives, per curve, the median over the passes of
//! the wall time and of the thread's CPU time (Linux: `/proc/thread-self/schedstat`; absent
//! elsewhere), in total, for each part, and for the rest (total − Σ parts of the same pass,
//! so a change of the machine's speed between passes cancels), and a fingerprint of every
//! result (a hash of their full-precision `Debug` text, from an untimed first pass) so that
//! two builds can be checked to give identical features. Arguments: `--passes N` (default 15).

use coupler_features::{
    FeatureExtractor, FeatureTolerances, crunodes, cusps, pseudo_arcs, straight_segments, symmetry,
};
use coupler_kinematics::{Circuit, CouplerPoint, CrankTable, DashPattern, FourBar, Mechanism};
use std::hash::{Hash, Hasher};
use std::time::Instant;

/// On-CPU time of this thread, seconds (Linux), else `None`.
fn thread_cpu() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = s.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

const LINKAGES: [(f64, f64, f64); 4] = [
    (2.5, 2.5, 2.0),
    (3.0, 2.5, 3.5),
    (3.0, 3.0, 2.5),
    (4.0, 3.0, 5.0),
];

fn points() -> impl Iterator<Item = CouplerPoint> {
    (-4..=12)
        .flat_map(|iu| (-6..=6).map(move |iv| CouplerPoint::new(iu as f64 * 0.5, iv as f64 * 0.5)))
}

const PARTS: [&str; 7] = [
    "straight",
    "arcs",
    "crunodes",
    "cusps",
    "symmetry",
    "cognates",
    "poses+trace",
];

fn main() {
    let mut passes = 15usize;
    let args: Vec<String> = std::env::args().collect();
    if let Some(k) = args.iter().position(|a| a == "--passes") {
        passes = args
            .get(k + 1)
            .and_then(|s| s.parse().ok())
            .expect("--passes N");
    }
    let tol = FeatureTolerances::DEFAULT;
    let dash = DashPattern::default();
    let table = CrankTable::new(tol.step_deg).expect("crank table");

    // The work of the parts: every curve traced once, with its mechanism.
    let mut work = Vec::new();
    for (a, b, c) in LINKAGES {
        let l = FourBar::new(a, b, c).expect("linkage");
        for circuit in [Circuit::Open, Circuit::Crossed] {
            let poses = l.pose_table(circuit, &table);
            for p in points() {
                work.push((l, circuit, p, poses.trace(p)));
            }
        }
    }

    // Each pass times the whole extraction, then each part run over all the curves in one
    // block (wall and CPU): the total and the parts of one pass see the machine at the same
    // speed, so the rest (total − Σ parts, per pass) is what the extractor spends outside
    // the parts. The fingerprint of every result is taken first, in an untimed pass.
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    let mut curves = 0usize;
    for (a, b, c) in LINKAGES {
        let l = FourBar::new(a, b, c).expect("linkage");
        for circuit in [Circuit::Open, Circuit::Crossed] {
            let mut x = FeatureExtractor::new(&l, circuit, &tol, &dash).expect("extractor");
            for p in points() {
                format!("{:?}", x.extract(p)).hash(&mut hasher);
                curves += 1;
            }
        }
    }
    let (mut wall, mut cpu) = (Vec::new(), Vec::new());
    let mut parts: Vec<(Vec<f64>, Vec<f64>)> = vec![(Vec::new(), Vec::new()); PARTS.len()];
    let (mut rest_wall, mut rest_cpu) = (Vec::new(), Vec::new());
    for _ in 0..passes {
        let (t, c) = (Instant::now(), thread_cpu());
        for (a, b, c) in LINKAGES {
            let l = FourBar::new(a, b, c).expect("linkage");
            for circuit in [Circuit::Open, Circuit::Crossed] {
                let mut x = FeatureExtractor::new(&l, circuit, &tol, &dash).expect("extractor");
                for p in points() {
                    drop(std::hint::black_box(x.extract(p)));
                }
            }
        }
        let total_wall = t.elapsed().as_secs_f64();
        let total_cpu = c.zip(thread_cpu()).map(|(c0, c1)| c1 - c0);
        let (mut sum_wall, mut sum_cpu) = (0.0, 0.0);
        for (k, (w, c)) in parts.iter_mut().enumerate() {
            let (clock, c0) = (Instant::now(), thread_cpu());
            for (l, circuit, p, curve) in &work {
                let (l, circuit, p) = (l, *circuit, *p);
                match k {
                    0 => drop(std::hint::black_box(straight_segments(curve, &tol, &dash))),
                    1 => drop(std::hint::black_box(pseudo_arcs(curve, &tol, &dash))),
                    2 => drop(std::hint::black_box(crunodes(l, circuit, p, curve, &tol))),
                    3 => drop(std::hint::black_box(cusps(l, circuit, p, curve, &tol))),
                    4 => drop(std::hint::black_box(symmetry(l, circuit, p, curve, &tol))),
                    5 => drop(std::hint::black_box(l.cognates(circuit, p))),
                    _ => {
                        let poses = l.pose_table(circuit, &table);
                        drop(std::hint::black_box(poses.trace(p)));
                    }
                }
            }
            let dt = clock.elapsed().as_secs_f64();
            w.push(dt);
            sum_wall += dt;
            if let (Some(c0), Some(c1)) = (c0, thread_cpu()) {
                c.push(c1 - c0);
                sum_cpu += c1 - c0;
            }
        }
        wall.push(total_wall);
        rest_wall.push(total_wall - sum_wall);
        if let Some(tc) = total_cpu {
            cpu.push(tc);
            rest_cpu.push(tc - sum_cpu);
        }
    }
    let per = |v: &mut Vec<f64>| median(v) / curves as f64 * 1e6;
    let cpu_text = |v: &mut Vec<f64>| {
        if v.is_empty() {
            "n/a".to_string()
        } else {
            format!("{:.1} µs", per(v))
        }
    };
    println!(
        "features per curve ({curves} curves, {passes} passes, one thread): {:.1} µs wall, {} CPU (medians)",
        per(&mut wall),
        cpu_text(&mut cpu)
    );
    println!("fingerprint of the features: {:016x}", hasher.finish());
    println!(
        "  rest (total − Σ parts, per pass; the parts build a pose table per curve, the extractor one per linkage): {:.1} µs wall, {} CPU per curve (medians)",
        per(&mut rest_wall),
        cpu_text(&mut rest_cpu)
    );
    for (name, (w, c)) in PARTS.iter().zip(parts.iter_mut()) {
        let cpu = if c.is_empty() {
            "n/a".to_string()
        } else {
            format!("{:7.1}", per(c))
        };
        println!(
            "  {name:>9}: {:7.1} µs wall, {cpu} µs CPU per curve (medians)",
            per(w)
        );
    }
}
