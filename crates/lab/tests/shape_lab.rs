#![allow(dead_code)]
//! Shape-search lab: retrieval rates of candidate descriptors on the default atlas.
//! Measurement only (ignored): `cargo test --release -p coupler-lab --test shape_lab -- --ignored --nocapture`.

use coupler_generate::Job;
use coupler_kinematics::{Circuit, CouplerPoint, CrankAngle, CrankTable, FourBar, Pose, PoseTable};
// The cases' generator is shared with `tests/shape.rs` (`coupler_shape::cases`).
use coupler_shape::cases::{SplitMix64 as Rng, crank_angles, place_points};
use coupler_shape::{C64, cis, resample};
use coupler_specs::Spec;

fn abs(z: C64) -> f64 {
    z.norm()
}

fn arg(z: C64) -> f64 {
    z.im.atan2(z.re)
}

fn mean(z: &[C64]) -> C64 {
    z.iter().sum::<C64>() / z.len() as f64
}
use std::time::Instant;

#[derive(Clone, Copy, Debug)]
struct AtlasCurve {
    linkage: FourBar,
    circuit: Circuit,
    point: CouplerPoint,
}

fn atlas(spec: &Spec) -> Vec<AtlasCurve> {
    let job = Job::new(spec.clone(), "lab", "/nonexistent", 1);
    coupler_generate::atlas_curves(&job)
        .into_iter()
        .map(|c| AtlasCurve {
            linkage: *c.curve.linkage.four_bar().expect("a four-bar atlas"),
            circuit: c.curve.circuit,
            point: c.curve.point,
        })
        .collect()
}

fn trace(c: &AtlasCurve, table: &CrankTable) -> Vec<C64> {
    let poses = PoseTable::new(&c.linkage, c.circuit, table);
    let t = poses.trace(c.point);
    (0..t.len()).map(|k| C64::new(t.x[k], t.y[k])).collect()
}

struct Case {
    source: usize,
    points: Vec<C64>,
    closed: bool,
    span: f64,
    start: f64,
    mirrored: bool,
}

fn make_case(rng: &mut Rng, curves: &[AtlasCurve], closed: bool, noise: f64) -> Case {
    let source = (rng.next_u64() % curves.len() as u64) as usize;
    let c = curves[source];
    let start = rng.range(0.0, 360.0);
    let span = if closed {
        360.0
    } else {
        rng.range(90.0, 270.0)
    };
    let n = 30 + (rng.next_u64() % 120) as usize;
    let angles = crank_angles(rng, closed, start, span, n);
    let pts: Vec<C64> = angles
        .iter()
        .map(|&d| {
            let p = Pose::solve(&c.linkage, c.circuit, &CrankAngle::from_degrees(d)).unwrap();
            let m = p.point(c.point);
            C64::new(m.x, m.y)
        })
        .collect();
    let mirrored = rng.uniform() < 0.5;
    let w = place_points(rng, &pts, mirrored, noise);
    Case {
        source,
        points: w,
        closed,
        span,
        start,
        mirrored,
    }
}

/// Complex Fourier coefficients Z_k, k = −h..h, of m points equally spaced in the
/// parameter (z_j at s = 2πj/m): Z_k = (1/m) Σ z_j e^{−iksj}.
fn fourier(z: &[C64], h: usize) -> Vec<C64> {
    let m = z.len();
    let mut out = Vec::with_capacity(2 * h + 1);
    for k in -(h as i64)..=(h as i64) {
        let mut s = C64::new(0.0, 0.0);
        for (j, &p) in z.iter().enumerate() {
            let deg = -360.0 * ((k * j as i64).rem_euclid(m as i64)) as f64 / m as f64;
            s += p * coupler_shape::cis_deg(deg);
        }
        out.push(s / m as f64);
    }
    out
}

/// Unit-norm coefficients without Z_0.
fn normalized(z: &[C64]) -> Vec<C64> {
    let h = (z.len() - 1) / 2;
    let mut v: Vec<C64> = z.to_vec();
    v[h] = C64::new(0.0, 0.0);
    let n = v.iter().map(|c| c.norm_sqr()).sum::<f64>().sqrt();
    v.iter().map(|c| c / n).collect()
}

/// Kuhl–Giardina style normalisation: rotate and shift the start so that Z_1 and Z_−1
/// are real positive (two solutions, β and β + π).
fn efd_normalize(z: &[C64]) -> [Vec<C64>; 2] {
    let h = (z.len() - 1) / 2;
    let (z1, zm1) = (z[h + 1], z[h - 1]);
    let beta = 0.5 * (arg(zm1) - arg(z1));
    let alpha = -arg(z1) - beta;
    let make = |b: f64, a: f64| -> Vec<C64> {
        (0..z.len())
            .map(|i| {
                let k = i as f64 - h as f64;
                z[i] * cis(a + k * b)
            })
            .collect()
    };
    [
        make(beta, alpha),
        make(beta + std::f64::consts::PI, alpha - std::f64::consts::PI),
    ]
}

fn dist2(a: &[C64], b: &[C64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).norm_sqr()).sum()
}

/// Aligned distance: min over rotation and start shift (β on a grid of `nb`) of
/// |Z − e^{iα+ikβ} W|², both unit norm. `tw[j][i]` = e^{i(i−h)β_j}.
fn aligned(z: &[C64], w: &[C64], tw: &[Vec<C64>]) -> f64 {
    let prod: Vec<C64> = z.iter().zip(w).map(|(a, b)| a.conj() * b).collect();
    let mut best = 0.0f64;
    for t in tw {
        let mut s = C64::new(0.0, 0.0);
        for (p, e) in prod.iter().zip(t) {
            s += p * e;
        }
        best = best.max(s.norm_sqr());
    }
    2.0 - 2.0 * best.sqrt()
}

fn twiddles(h: usize, nb: usize) -> Vec<Vec<C64>> {
    (0..nb)
        .map(|j| {
            let beta = std::f64::consts::TAU * j as f64 / nb as f64;
            (0..2 * h + 1)
                .map(|i| cis((i as f64 - h as f64) * beta))
                .collect()
        })
        .collect()
}

fn rank_of(scores: &[f64], source: usize) -> usize {
    let s = scores[source];
    scores.iter().filter(|&&x| x < s).count()
}

fn report(name: &str, ranks: &[usize]) {
    let n = ranks.len() as f64;
    let at = |k: usize| 100.0 * ranks.iter().filter(|&&r| r < k).count() as f64 / n;
    println!(
        "{name:<40} @1 {:5.1}  @5 {:5.1}  @20 {:5.1}  @100 {:5.1}  @300 {:5.1}  @1000 {:5.1}",
        at(1),
        at(5),
        at(20),
        at(100),
        at(300),
        at(1000)
    );
}

fn variants(points: &[C64]) -> Vec<Vec<C64>> {
    let rev: Vec<C64> = points.iter().rev().copied().collect();
    let mir: Vec<C64> = points.iter().map(|z| z.conj()).collect();
    let mr: Vec<C64> = rev.iter().map(|z| z.conj()).collect();
    vec![points.to_vec(), rev, mir, mr]
}

fn target_coeffs(v: &[C64], m: usize, h: usize, cap: usize, div: usize) -> Vec<C64> {
    let r = if cap > 0 {
        let terms = (v.len() / div).clamp(2, cap);
        match coupler_shape::smooth_resample(v, true, terms, m) {
            Some(r) => r.0,
            None => {
                println!("smoothing failed n={} terms={terms}", v.len());
                resample(v, true, m).unwrap()
            }
        }
    } else {
        resample(v, true, m).unwrap()
    };
    normalized(&fourier(&r, h))
}

#[test]
#[ignore]
fn closed_descriptors() {
    let spec = Spec::default_atlas();
    let curves = atlas(&spec);
    let table = CrankTable::new(0.5).unwrap();
    let m = 256;
    let traced: Vec<Vec<C64>> = curves
        .iter()
        .map(|c| resample(&trace(c, &table), true, m).unwrap())
        .collect();
    for h in [6usize] {
        let coeffs: Vec<Vec<C64>> = traced.iter().map(|z| normalized(&fourier(z, h))).collect();
        let efd: Vec<[Vec<C64>; 2]> = coeffs.iter().map(|z| efd_normalize(z)).collect();
        let mags: Vec<Vec<f64>> = coeffs
            .iter()
            .map(|z| z.iter().map(|c| abs(*c)).collect())
            .collect();
        for (noise, cap) in [(0.01, 24)] {
            let mut rng = Rng(42);
            let (mut r_efd, mut r_mag) = (vec![], vec![]);
            for _ in 0..200 {
                let case = make_case(&mut rng, &curves, true, noise);
                let divs: Vec<usize> = std::env::var("DIVS")
                    .map(|x| x.split(',').map(|d| d.parse().unwrap()).collect())
                    .unwrap_or(vec![8]);
                let qs: Vec<Vec<C64>> = variants(&case.points)
                    .iter()
                    .flat_map(|v| {
                        divs.iter()
                            .map(|&d| target_coeffs(v, m, h, cap, d))
                            .collect::<Vec<_>>()
                    })
                    .collect();
                let q_efd: Vec<[Vec<C64>; 2]> = qs.iter().map(|z| efd_normalize(z)).collect();
                let q_mag: Vec<Vec<f64>> = qs
                    .iter()
                    .map(|z| z.iter().map(|c| abs(*c)).collect())
                    .collect();
                let s_efd: Vec<f64> = efd
                    .iter()
                    .map(|e| {
                        q_efd
                            .iter()
                            .flat_map(|q| q.iter().map(|qq| dist2(qq, &e[0])))
                            .fold(f64::INFINITY, f64::min)
                    })
                    .collect();
                let s_mag: Vec<f64> = mags
                    .iter()
                    .map(|e| {
                        q_mag
                            .iter()
                            .map(|q| q.iter().zip(e).map(|(a, b)| (a - b) * (a - b)).sum::<f64>())
                            .fold(f64::INFINITY, f64::min)
                    })
                    .collect();
                r_efd.push(rank_of(&s_efd, case.source));
                if rank_of(&s_efd, case.source) >= 20 && std::env::var("MISS").is_ok() {
                    let c = curves[case.source];
                    println!(
                        "  miss rank {} n {} {} ({}, {}) {:?}",
                        rank_of(&s_efd, case.source),
                        case.points.len(),
                        c.linkage,
                        c.point.u / c.linkage.coupler,
                        c.point.v / c.linkage.coupler,
                        c.circuit
                    );
                }
                r_mag.push(rank_of(&s_mag, case.source));
            }
            let tag = format!("h {h} noise {noise} smooth cap {cap}");
            report(&format!("{tag} EFD"), &r_efd);
            report(&format!("{tag} mag"), &r_mag);
        }
    }
}

/// Discrete orthonormal polynomials of degree 1..=p on m equally spaced points
/// (Gram–Schmidt on 1, t, t², … with the plain sum as inner product).
fn legendre_basis(m: usize, p: usize) -> Vec<Vec<f64>> {
    let t: Vec<f64> = (0..m)
        .map(|j| 2.0 * j as f64 / (m - 1) as f64 - 1.0)
        .collect();
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for deg in 0..=p {
        let mut v: Vec<f64> = t.iter().map(|&x| x.powi(deg as i32)).collect();
        for _ in 0..2 {
            for b in &basis {
                let d: f64 = v.iter().zip(b).map(|(a, c)| a * c).sum();
                for (x, y) in v.iter_mut().zip(b) {
                    *x -= d * y;
                }
            }
        }
        let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        basis.push(v.iter().map(|x| x / n).collect());
    }
    basis.remove(0);
    basis
}

fn coeffs(w: &[C64], basis: &[Vec<f64>]) -> Vec<C64> {
    let c: Vec<C64> = basis
        .iter()
        .map(|b| {
            let mut s = C64::new(0.0, 0.0);
            for (x, &y) in b.iter().zip(w) {
                s += y * *x;
            }
            s
        })
        .collect();
    let n = c.iter().map(|x| x.norm_sqr()).sum::<f64>().sqrt();
    c.iter().map(|x| x / n).collect()
}

/// The window of the closed arc-length-resampled curve `zc` from fraction `s0` of its
/// length over fraction `f`, at m points (linear interpolation, periodic).
fn window(zc: &[C64], s0: f64, f: f64, m: usize) -> Vec<C64> {
    let n = zc.len() as f64;
    (0..m)
        .map(|j| {
            let s = (s0 + f * j as f64 / (m - 1) as f64) * n;
            let k = s.floor();
            let t = s - k;
            let a = zc[(k as usize) % zc.len()];
            let b = zc[(k as usize + 1) % zc.len()];
            a + (b - a) * t
        })
        .collect()
}

fn q8(c: &[C64]) -> Vec<C64> {
    c.iter()
        .map(|x| {
            C64::new(
                (x.re * 127.0).round() / 127.0,
                (x.im * 127.0).round() / 127.0,
            )
        })
        .collect()
}

fn bank_windows(lengths: &[f64], density: f64) -> Vec<(f64, f64)> {
    let mut w = Vec::new();
    for &f in lengths {
        let starts = ((density / f).ceil() as usize).max(1);
        for j in 0..starts {
            w.push((j as f64 / starts as f64, f));
        }
    }
    w
}

#[test]
#[ignore]
fn open_window_bank() {
    let spec = Spec::default_atlas();
    let curves = atlas(&spec);
    let table = CrankTable::new(0.5).unwrap();
    let big = 256;
    let m = 24;
    let t0 = Instant::now();
    let zcs: Vec<Vec<C64>> = curves
        .iter()
        .map(|c| resample(&trace(c, &table), true, big).unwrap())
        .collect();
    println!("traced + resampled {:.2?}", t0.elapsed());
    let mut rng = Rng(7);
    let noise: f64 = std::env::var("NOISE")
        .ok()
        .and_then(|x| x.parse().ok())
        .unwrap_or(0.01);
    let smooth = std::env::var("NOSMOOTH").is_err();
    let only: Option<usize> = std::env::var("ONLY").ok().and_then(|x| x.parse().ok());
    let cases: Vec<Case> = (0..200)
        .map(|_| make_case(&mut rng, &curves, false, noise))
        .collect();
    // Arc fraction the cases cover (how long are 90–270° crank windows in arc length?).
    let mut fr: Vec<f64> = cases
        .iter()
        .map(|c| {
            let cur = &curves[c.source];
            let tab = CrankTable::new(0.5).unwrap();
            let z = trace(cur, &tab);
            let cum = coupler_shape::cumulative_length(&z, true);
            let l = *cum.last().unwrap();
            let a = ((c.start.rem_euclid(360.0)) / 0.5) as usize;
            let b = a + (c.span / 0.5) as usize;
            let len = |k: usize| cum[k % 720] + l * (k / 720) as f64;
            (len(b) - len(a)) / l
        })
        .collect();
    fr.sort_by(f64::total_cmp);
    println!(
        "arc fraction of the windows: min {:.3} p5 {:.3} p50 {:.3} p95 {:.3} max {:.3}",
        fr[0], fr[10], fr[100], fr[190], fr[199]
    );
    let configs: Vec<(&str, Vec<f64>, f64, usize)> = vec![
        (
            "7 lengths x1.5, density 1, p3",
            vec![0.06, 0.09, 0.135, 0.2, 0.3, 0.45, 0.68, 0.95],
            1.0,
            3,
        ),
        (
            "7 lengths x1.5, density 2, p3",
            vec![0.06, 0.09, 0.135, 0.2, 0.3, 0.45, 0.68, 0.95],
            2.0,
            3,
        ),
        (
            "7 lengths x1.5, density 4, p3",
            vec![0.06, 0.09, 0.135, 0.2, 0.3, 0.45, 0.68, 0.95],
            4.0,
            3,
        ),
        (
            "7 lengths x1.5, density 2, p5",
            vec![0.06, 0.09, 0.135, 0.2, 0.3, 0.45, 0.68, 0.95],
            2.0,
            5,
        ),
        (
            "11 lengths x1.3, density 2, p3",
            vec![
                0.05, 0.065, 0.085, 0.11, 0.14, 0.18, 0.24, 0.31, 0.4, 0.52, 0.68, 0.88,
            ],
            2.0,
            3,
        ),
        (
            "11 lengths x1.3, density 4, p4",
            vec![
                0.05, 0.065, 0.085, 0.11, 0.14, 0.18, 0.24, 0.31, 0.4, 0.52, 0.68, 0.88,
            ],
            4.0,
            4,
        ),
    ];
    for (ci, (name, lengths, density, p)) in configs.into_iter().enumerate() {
        if only.is_some_and(|o| o != ci) {
            continue;
        }
        let basis = legendre_basis(m, p);
        let wins = bank_windows(&lengths, density);
        let t0 = Instant::now();
        let bank: Vec<Vec<Vec<C64>>> = zcs
            .iter()
            .map(|zc| {
                wins.iter()
                    .map(|&(s0, f)| q8(&coeffs(&window(zc, s0, f, m), &basis)))
                    .collect()
            })
            .collect();
        let build = t0.elapsed();
        let mut ranks = vec![];
        let t0 = Instant::now();
        for case in &cases {
            let qs: Vec<Vec<C64>> = variants(&case.points)
                .iter()
                .flat_map(|v| {
                    [5usize, 8, 12]
                        .iter()
                        .map(|&d| {
                            let terms = (v.len() / d).clamp(2, 24);
                            let r = if smooth {
                                coupler_shape::smooth_resample(v, false, terms, m)
                                    .map(|r| r.0)
                                    .unwrap_or_else(|| resample(v, false, m).unwrap())
                            } else {
                                resample(v, false, m).unwrap()
                            };
                            coeffs(&r, &basis)
                        })
                        .collect::<Vec<_>>()
                })
                .collect();
            let scores: Vec<f64> = bank
                .iter()
                .map(|ws| {
                    let mut best = 0.0f64;
                    for w in ws {
                        for q in &qs {
                            let mut s = C64::new(0.0, 0.0);
                            for (a, b) in q.iter().zip(w) {
                                s += a.conj() * b;
                            }
                            best = best.max(s.norm_sqr());
                        }
                    }
                    1.0 - best
                })
                .collect();
            ranks.push(rank_of(&scores, case.source));
        }
        report(
            &format!("{name} ({} windows, {} B)", wins.len(), wins.len() * 2 * p),
            &ranks,
        );
        println!("   build {:.2?}, 200 queries {:.2?}", build, t0.elapsed());
    }
}

#[test]
#[ignore]
fn bank_debug() {
    let spec = Spec::default_atlas();
    let curves = atlas(&spec);
    let table = CrankTable::new(0.5).unwrap();
    let m = 24;
    let zcs: Vec<Vec<C64>> = curves
        .iter()
        .map(|c| resample(&trace(c, &table), true, 256).unwrap())
        .collect();
    let basis = legendre_basis(m, 3);
    let lengths = vec![0.06, 0.09, 0.135, 0.2, 0.3, 0.45, 0.68, 0.95];
    let wins = bank_windows(&lengths, 4.0);
    let src = 1234;
    for (s0, f) in [(0.3, 0.3), (0.31, 0.3), (0.33, 0.33), (0.5, 0.5)] {
        let q = coeffs(&window(&zcs[src], s0, f, m), &basis);
        let mut scores: Vec<(f64, usize)> = zcs
            .iter()
            .enumerate()
            .map(|(i, zc)| {
                let best = wins
                    .iter()
                    .map(|&(a, b)| {
                        let w = coeffs(&window(zc, a, b, m), &basis);
                        let mut s = C64::new(0.0, 0.0);
                        for (x, y) in q.iter().zip(&w) {
                            s += x.conj() * y;
                        }
                        s.norm_sqr()
                    })
                    .fold(0.0, f64::max);
                (1.0 - best, i)
            })
            .collect();
        let srcs = scores[src].0;
        scores.sort_by(|a, b| a.0.total_cmp(&b.0));
        let rank = scores.iter().position(|x| x.1 == src).unwrap();
        println!(
            "window ({s0},{f}): source misfit {srcs:e}, rank {rank}, best {:?}",
            &scores[..3]
        );
    }
}

/// How many atlas curves fit an open noisy target at least as well as its source (exact
/// fit of every curve): the oracle behind "the source or a curve at least as close".
#[test]
#[ignore]
fn open_oracle() {
    use coupler_shape::{CouplerCurve, FitOptions, Target, Timing, fit_curve};
    use rayon::prelude::*;
    let spec = Spec::default_atlas();
    let curves = atlas(&spec);
    let noise: f64 = std::env::var("NOISE")
        .ok()
        .and_then(|x| x.parse().ok())
        .unwrap_or(0.01);
    let count: usize = std::env::var("COUNT")
        .ok()
        .and_then(|x| x.parse().ok())
        .unwrap_or(10);
    let closed = std::env::var("CLOSED").is_ok();
    let mut rng = Rng(7);
    for _ in 0..count {
        let case = make_case(&mut rng, &curves, closed, noise);
        let pts: Vec<[f64; 2]> = case.points.iter().map(|z| [z.re, z.im]).collect();
        let target = Target::new(pts, closed, Timing::Untimed).unwrap();
        let t0 = Instant::now();
        let fits: Vec<f64> = curves
            .par_iter()
            .map(|c| {
                let cc = CouplerCurve {
                    linkage: c.linkage.into(),
                    circuit: c.circuit,
                    point: c.point,
                };
                fit_curve(&target, &cc, &FitOptions::DEFAULT).map_or(f64::INFINITY, |f| f.rms)
            })
            .collect();
        let src = fits[case.source];
        let better = fits.iter().filter(|&&x| x <= src).count();
        let mut sorted = fits.clone();
        sorted.sort_by(f64::total_cmp);
        println!(
            "span {:5.1} n {:3} source rms {:.3}% of size; curves at least as close {better:5}; best {:.3}% 5th {:.3}%  ({:.1?})",
            case.span,
            case.points.len(),
            100.0 * src / target.size(),
            100.0 * sorted[0] / target.size(),
            100.0 * sorted[4] / target.size(),
            t0.elapsed()
        );
    }
}

/// Level-1 open scan: best misfit of an m-point target over windows of a 256-point
/// arc-length loop (lengths ratio `ratio` from 0.04, centres clamp(k/f, lo, hi)).
fn quick_scan(
    zc: &[C64],
    vars: &[Vec<C64>],
    m: usize,
    ratio: f64,
    k: f64,
    lo: usize,
    hi: usize,
) -> f64 {
    let big = zc.len();
    let mut best = f64::INFINITY;
    let mut f: f64 = 0.04;
    let mut w = vec![C64::new(0.0, 0.0); m];
    while f <= 1.0 + 1e-9 {
        let count = ((k / f).ceil() as usize).clamp(lo, hi);
        for i in 0..count {
            let s0 = i as f64 / count as f64;
            let mut mean = C64::new(0.0, 0.0);
            for (j, wj) in w.iter_mut().enumerate() {
                let s = (s0 + f * j as f64 / (m - 1) as f64) * big as f64;
                let kk = s as usize;
                let u = s - kk as f64;
                let (a, b) = (zc[kk % big], zc[(kk + 1) % big]);
                *wj = a + (b - a) * u;
                mean += *wj;
            }
            mean /= m as f64;
            let mut n2 = 0.0;
            for wj in w.iter_mut() {
                *wj -= mean;
                n2 += wj.norm_sqr();
            }
            for v in vars {
                let mut s = C64::new(0.0, 0.0);
                for (a, b) in w.iter().zip(v) {
                    s += a.conj() * b;
                }
                let mis = 1.0 - s.norm_sqr() / n2;
                if mis < best {
                    best = mis;
                }
            }
        }
        f *= ratio;
    }
    best
}

#[test]
#[ignore]
fn open_quick_scan() {
    let spec = Spec::default_atlas();
    let curves = atlas(&spec);
    let table = CrankTable::new(1.0).unwrap();
    let zcs: Vec<Vec<C64>> = curves
        .iter()
        .map(|c| resample(&trace(c, &table), true, 256).unwrap())
        .collect();
    let mut rng = Rng(7);
    let cases: Vec<Case> = (0..200)
        .map(|_| make_case(&mut rng, &curves, false, 0.01))
        .collect();
    for (m, ratio, k, lo, hi) in [
        (8, 1.4, 4.0, 8, 48),
        (12, 1.3, 5.0, 10, 64),
        (16, 1.25, 8.0, 12, 128),
    ] {
        let mut ranks = vec![];
        let t0 = Instant::now();
        for case in &cases {
            let vars: Vec<Vec<C64>> = variants(&case.points)
                .iter()
                .filter_map(|v| {
                    let terms = (v.len() / 8).clamp(2, 24);
                    let r = coupler_shape::smooth_resample(v, false, terms, m)?.0;
                    let mu = mean(&r);
                    let c: Vec<C64> = r.iter().map(|z| z - mu).collect();
                    let n = c.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
                    Some(c.iter().map(|z| z / n).collect())
                })
                .collect();
            let scores: Vec<f64> = zcs
                .iter()
                .map(|zc| quick_scan(zc, &vars, m, ratio, k, lo, hi))
                .collect();
            ranks.push(rank_of(&scores, case.source));
        }
        report(
            &format!("quick m={m} ratio={ratio} k={k} [{lo},{hi}]"),
            &ranks,
        );
        println!("   {:.1?} per query", t0.elapsed() / 200);
    }
}

#[test]
#[ignore]
fn closed_timing() {
    use coupler_shape::*;
    let spec = Spec::default_atlas();
    let ac = atlas(&spec);
    let curves: Vec<AtlasCurve> = ac
        .iter()
        .enumerate()
        .map(|(i, c)| AtlasCurve {
            id: i as u64,
            curve: CouplerCurve {
                linkage: c.linkage.into(),
                circuit: c.circuit,
                point: c.point,
            },
        })
        .collect();
    let t0 = Instant::now();
    let codes: Vec<ShapeCode> = curves
        .iter()
        .map(|c| ShapeCode::of_curve(&c.curve).unwrap())
        .collect();
    println!(
        "codes: {:.2?} for {} ({:.1?} each)",
        t0.elapsed(),
        codes.len(),
        t0.elapsed() / codes.len() as u32
    );
    let mut rng = Rng(3);
    for _ in 0..5 {
        let case = make_case(&mut rng, &ac, true, 0.01);
        let pts: Vec<[f64; 2]> = case.points.iter().map(|z| [z.re, z.im]).collect();
        let t = Target::new(pts, true, Timing::Untimed).unwrap();
        let t0 = Instant::now();
        let q = ClosedQuery::new(&t.complex_points(), true).unwrap();
        let t1 = t0.elapsed();
        let d: Vec<f64> = codes.iter().map(|c| q.distance(c)).collect();
        assert_eq!(d.len(), codes.len());
        let t2 = t0.elapsed();
        let opts = MatchOptions {
            candidates: 32,
            ..MatchOptions::DEFAULT
        };
        // (The coarse stage again, through the library: the codes' distances are timed
        // above.)
        let c = coarse_candidates(&t, &curves, &codes, &opts).unwrap();
        let m = rank_candidates(&t, c, &opts);
        let t3 = t0.elapsed();
        println!(
            "n {} query {:.1?} coarse {:.1?} exact {:.1?} best {:.3}%",
            t.len(),
            t1,
            t2 - t1,
            t3 - t2,
            m[0].rms_pct
        );
    }
}

/// An open target through the whole pipeline (refined window scan of every curve), and
/// Chebyshev's straight run as an open path: time and result.
#[test]
#[ignore]
fn open_query_time() {
    use coupler_features::ClassicCurve;
    use coupler_shape::*;
    use coupler_specs::CurveList;
    let spec = Spec::default_atlas();
    let ac = atlas(&spec);
    let curves: Vec<AtlasCurve> = ac
        .iter()
        .enumerate()
        .map(|(i, c)| AtlasCurve {
            id: i as u64,
            curve: CouplerCurve {
                linkage: c.linkage.into(),
                circuit: c.circuit,
                point: c.point,
            },
        })
        .collect();
    let list = CurveList::parse(include_str!("../../../atlas-spec/classics.toml"), "c").unwrap();
    let cheb = list.curves.iter().find(|c| c.name == "Chebyshev").unwrap();
    let m = ClassicCurve::compute(cheb, 1.0);
    let run = m.straight[0].unwrap();
    let b = &m.branches[run.branch];
    let pts: Vec<[f64; 2]> = b.samples[run.samples[0]..run.samples[0] + run.samples[1]]
        .iter()
        .map(|s| [s.point.x, s.point.y])
        .collect();
    let t = Target::new(pts, false, Timing::Untimed).unwrap();
    let t0 = Instant::now();
    let found = find_matches(&t, &curves, &[], &MatchOptions::DEFAULT).unwrap();
    println!(
        "Chebyshev straight run ({} points, {:.0}° of input): {:.1?}",
        t.len(),
        run.input_span_deg,
        t0.elapsed()
    );
    for x in &found {
        println!(
            "  curve {} {} ({}, {}) rms {:.3}% crank {:?}",
            x.id,
            x.curve.linkage,
            x.curve.point.u,
            x.curve.point.v,
            x.rms_pct,
            x.placement.crank_deg
        );
    }
}
