//! Shape search side by side with the `four-bar` crate's atlas fetch (Chang, Chang & Lee,
//! IFToMM WC 2023: normalised elliptic Fourier descriptors, 20 harmonics, nearest by L1
//! distance), on the same targets (`coupler_shape::cases`, the retrieval tests' cases).
//!
//! Bench-only: the crate is an optional dependency of the lab, built only with
//!
//!     cargo bench -p coupler-lab --features four-bar --bench fourbar
//!
//! (`CASES=N` for the first N cases of each kind, default 60; `HALF=closed` or `HALF=open`
//! for one kind only). One run, one thread each:
//!
//! - **ours**: `find_matches` on the default atlas (shape codes for loops, the per-linkage
//!   scan for open paths, then exact fits);
//! - **four-bar fetch, our atlas**: its descriptor and distance over the same curves (each
//!   traced at 720 crank samples), the top 5 by distance;
//! - **four-bar atlas**: `FbAtlas::make` (its own random linkages, as many as our atlas has
//!   curves, seeded), `fetch(target, is_open, 5)`: the linkages placed in the target's frame.
//!
//! Found = the bar: the source in the top 5, or a curve in the top 5 whose fit is at
//! least as close as the source's exact fit. Our atlas's candidates are fitted exactly
//! (`fit_curve`); the four-bar atlas's placed linkages are scored as they come back (RMS
//! distance from the target points to the linkage's curve, traced at 3,600 samples),
//! which is what its fetch offers before its own optimiser runs.

use coupler_shape::cases::{Case, found, retrieval_cases};
use coupler_shape::{AtlasCurve, FitOptions, MatchOptions, ShapeCode, find_matches, fit_curve};
use coupler_specs::Spec;
use four_bar::atlas::{Cfg, FbAtlas};
use four_bar::efd::Efd2;
use four_bar::mh::random::SeedOpt;
use std::time::Instant;

const HARMONICS: usize = 20;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        f64::NAN
    } else {
        v[v.len() / 2]
    }
}

/// RMS distance from `pts` to the polyline `curve` (closed).
fn rms_to_curve(pts: &[[f64; 2]], curve: &[[f64; 2]]) -> f64 {
    let d2 = |p: [f64; 2]| -> f64 {
        let mut best = f64::INFINITY;
        for k in 0..curve.len() {
            let a = curve[k];
            let b = curve[(k + 1) % curve.len()];
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let l2 = dx * dx + dy * dy;
            let t = if l2 > 0.0 {
                (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (x, y) = (a[0] + t * dx - p[0], a[1] + t * dy - p[1]);
            best = best.min(x * x + y * y);
        }
        best
    };
    (pts.iter().map(|&p| d2(p)).sum::<f64>() / pts.len() as f64).sqrt()
}

struct Tally {
    name: &'static str,
    found: usize,
    source_top5: usize,
    times: Vec<f64>,
}

impl Tally {
    fn new(name: &'static str) -> Tally {
        Tally {
            name,
            found: 0,
            source_top5: 0,
            times: Vec::new(),
        }
    }
    fn print(&self, n: usize) {
        println!(
            "  {:<32} found {:>3}/{n} ({:>5.1} %)  source in top 5 {:>3}/{n}  median query {:>8.2} ms",
            self.name,
            self.found,
            100.0 * self.found as f64 / n as f64,
            self.source_top5,
            1e3 * median(self.times.clone())
        );
    }
}

fn main() {
    let count: usize = std::env::var("CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(60);
    let job = coupler_generate::Job::new(Spec::default_atlas(), "bench", "/nonexistent", 1);
    let curves: Vec<AtlasCurve> = coupler_generate::atlas_curves(&job);
    let t0 = Instant::now();
    let codes: Vec<ShapeCode> = curves
        .iter()
        .map(|c| ShapeCode::of_curve(&c.curve).expect("a code"))
        .collect();
    let ours_build = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let fb_codes: Vec<Efd2> = curves
        .iter()
        .map(|c| {
            let pts: Vec<[f64; 2]> = (0..720)
                .map(|k| {
                    let m = c.curve.at(0.5 * k as f64).expect("assembles").m;
                    [m.re, m.im]
                })
                .collect();
            Efd2::from_curve_harmonic(pts, false, HARMONICS)
        })
        .collect();
    let fb_codes_build = t0.elapsed().as_secs_f64();
    println!(
        "default atlas: {} curves; our codes {:.2} s, four-bar descriptors of the same curves {:.2} s (one thread)",
        curves.len(),
        ours_build,
        fb_codes_build
    );
    // HALF=closed or HALF=open runs one half only.
    let half = std::env::var("HALF").unwrap_or_default();
    for closed in [true, false] {
        if (half == "closed" && !closed) || (half == "open" && closed) {
            continue;
        }
        let t0 = Instant::now();
        let fb_atlas = FbAtlas::make(
            Cfg::new()
                .is_open(!closed)
                .size(curves.len())
                .seed(SeedOpt::U64(1)),
        );
        let fb_build = t0.elapsed().as_secs_f64();
        let cases: Vec<Case> =
            retrieval_cases(&curves, closed, if closed { 2024 } else { 77 }, count);
        let n = cases.len();
        let (mut ours, mut fetch_ours, mut fetch_own) = (
            Tally::new("ours (match)"),
            Tally::new("four-bar fetch, our atlas"),
            Tally::new("four-bar atlas (its own)"),
        );
        for case in &cases {
            let t = &case.target;
            let pts = t.points().to_vec();
            let src = &curves[case.source];
            let own =
                fit_curve(t, &src.curve, &FitOptions::DEFAULT).map_or(f64::INFINITY, |f| f.rms);
            // Ours.
            let t0 = Instant::now();
            let m = find_matches(t, &curves, &codes, &MatchOptions::DEFAULT).expect("a search");
            ours.times.push(t0.elapsed().as_secs_f64());
            ours.found += usize::from(found(&m, src.id, own));
            ours.source_top5 += usize::from(m.iter().any(|x| x.id == src.id));
            // Its descriptor and distance over our curves.
            let t0 = Instant::now();
            let q = Efd2::from_curve_harmonic(pts.clone(), !closed, HARMONICS);
            let mut d: Vec<(f64, usize)> = fb_codes
                .iter()
                .enumerate()
                .map(|(i, c)| (q.err(c), i))
                .collect();
            d.sort_by(|a, b| a.0.total_cmp(&b.0));
            d.truncate(5);
            fetch_ours.times.push(t0.elapsed().as_secs_f64());
            let close = d.iter().any(|&(_, i)| {
                i == case.source
                    || fit_curve(t, &curves[i].curve, &FitOptions::DEFAULT)
                        .is_some_and(|f| f.rms <= own)
            });
            fetch_ours.found += usize::from(close);
            fetch_ours.source_top5 += usize::from(d.iter().any(|&(_, i)| i == case.source));
            // Its own atlas.
            let t0 = Instant::now();
            let fetched = fb_atlas.fetch(&pts, !closed, 5);
            fetch_own.times.push(t0.elapsed().as_secs_f64());
            let close = fetched.iter().any(|(_, fb)| {
                let c = fb.curve(3600);
                c.len() > 2 && rms_to_curve(&pts, &c) <= own
            });
            fetch_own.found += usize::from(close);
        }
        println!(
            "{} targets ({n} cases, 1 % noise; four-bar atlas of {} linkages made in {:.1} s):",
            if closed {
                "closed"
            } else {
                "open (90°–270° windows)"
            },
            fb_atlas.len(),
            fb_build
        );
        ours.print(n);
        fetch_ours.print(n);
        fetch_own.print(n);
    }
}
