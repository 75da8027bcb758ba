//! Features miss nothing: on every curve of `atlas-spec/quick.toml` and
//! `atlas-spec/hartenberg-denavit.toml`, an exhaustive search over every window of the
//! feature samples finds no qualifying straight or arc window longer than, or disjoint
//! from, the ones the index lists; on the classics, no qualifying straight run longer than
//! the one reported, at 1 %, 0.1 % and 0.01 % (`docs/features.md`, "Maximal windows: the
//! contract").
//!
//! The oracle is coded here independently of the library: its own sampling (one pose per
//! angle), its own line fit (the closed-form eigenvector of the scatter matrix, not an
//! angle from `atan2`), its own Kåsa circle (the uncentred 3 × 3 normal equations by
//! Gaussian elimination, not the centred 2 × 2 solve), and a plain loop over every window.
//! Windows within 1e-9 (relative) of a threshold are not counted either way: the two codes
//! round differently.

use coupler_atlas::generate::Job;
use coupler_atlas::{
    AtlasSpec, Circuit, ClassicCurve, CouplerPoint, CrankAngle, DashPattern, FeatureExtractor,
    FeatureTolerances, Linkage, Mechanism, STRAIGHTNESS_TOLERANCES,
};

/// Relative margin around every threshold.
const MARGIN: f64 = 1e-9;

struct Samples {
    x: Vec<f64>,
    y: Vec<f64>,
    vx: Vec<f64>,
    vy: Vec<f64>,
}

fn sample(l: &Linkage, circuit: Circuit, p: CouplerPoint, step: f64) -> Samples {
    let n = (360.0 / step).round() as usize;
    let mut s = Samples {
        x: vec![],
        y: vec![],
        vx: vec![],
        vy: vec![],
    };
    for k in 0..n {
        let f = l
            .frame(circuit, &CrankAngle::from_degrees(k as f64 * step))
            .expect("a crank-rocker assembles everywhere");
        let (m, v) = (f.point(p), f.velocity(p));
        s.x.push(m.x);
        s.y.push(m.y);
        s.vx.push(v.x);
        s.vy.push(v.y);
    }
    s
}

/// The unit major axis of the scatter matrix [[a, b], [b, c]].
fn major_axis(a: f64, b: f64, c: f64) -> [f64; 2] {
    let lmax = 0.5 * (a + c) + (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (u, w) = ([b, lmax - a], [lmax - c, b]);
    let v = if u[0].hypot(u[1]) >= w[0].hypot(w[1]) {
        u
    } else {
        w
    };
    let r = v[0].hypot(v[1]);
    if r == 0.0 {
        [1.0, 0.0]
    } else {
        [v[0] / r, v[1] / r]
    }
}

/// ε_S of the window `[i, i + w]` of `s` (indices modulo its length) and whether it
/// moves one way along the fitted line: by velocities (closed curves) or by steps
/// (branches).
fn straightness(s: &Samples, i: usize, w: usize, by_velocity: bool) -> Option<(f64, bool)> {
    let n = s.x.len();
    let idx = (i..=i + w).map(|k| k % n);
    let m = (w + 1) as f64;
    let gx = idx.clone().map(|k| s.x[k]).sum::<f64>() / m;
    let gy = idx.clone().map(|k| s.y[k]).sum::<f64>() / m;
    let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
    for k in idx.clone() {
        let (dx, dy) = (s.x[k] - gx, s.y[k] - gy);
        a += dx * dx;
        b += dx * dy;
        c += dy * dy;
    }
    let mut d = major_axis(a, b, c);
    let forward = if by_velocity {
        idx.clone()
            .map(|k| s.vx[k] * d[0] + s.vy[k] * d[1])
            .sum::<f64>()
    } else {
        let (p, q) = (i % n, (i + w) % n);
        (s.x[q] - s.x[p]) * d[0] + (s.y[q] - s.y[p]) * d[1]
    };
    if forward < 0.0 {
        d = [-d[0], -d[1]];
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let mut one_way = true;
    let mut prev: Option<usize> = None;
    for k in idx {
        let (cx, cy) = (
            (s.x[k] - gx) * d[0] + (s.y[k] - gy) * d[1],
            (s.y[k] - gy) * d[0] - (s.x[k] - gx) * d[1],
        );
        (x0, x1, y0, y1) = (x0.min(cx), x1.max(cx), y0.min(cy), y1.max(cy));
        if by_velocity {
            one_way &= s.vx[k] * d[0] + s.vy[k] * d[1] > 0.0;
        } else if let Some(q) = prev {
            let step = [s.x[k] - s.x[q], s.y[k] - s.y[q]];
            one_way &= step == [0.0, 0.0] || step[0] * d[0] + step[1] * d[1] > 0.0;
        }
        prev = Some(k);
    }
    let extent = x1 - x0;
    (extent > 0.0).then(|| ((y1 - y0) / extent, one_way))
}

/// Kåsa's circle of the points (least squares on `x² + y² + D·x + E·y + F`), by the
/// uncentred normal equations about the first point, Gaussian elimination with pivoting.
fn kasa(s: &Samples, idx: &[usize]) -> Option<([f64; 2], f64)> {
    let (ox, oy) = (s.x[idx[0]], s.y[idx[0]]);
    let mut a = [[0.0f64; 4]; 3];
    for &k in idx {
        let (x, y) = (s.x[k] - ox, s.y[k] - oy);
        let row = [x, y, 1.0];
        let z = x * x + y * y;
        for r in 0..3 {
            for c in 0..3 {
                a[r][c] += row[r] * row[c];
            }
            a[r][3] -= row[r] * z;
        }
    }
    for col in 0..3 {
        let p = (col..3)
            .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
            .unwrap();
        a.swap(col, p);
        if a[col][col] == 0.0 {
            return None;
        }
        let pivot = a[col];
        for row in a.iter_mut().skip(col + 1) {
            let f = row[col] / pivot[col];
            for (x, p) in row.iter_mut().zip(pivot).skip(col) {
                *x -= f * p;
            }
        }
    }
    let mut sol = [0.0; 3];
    for r in (0..3).rev() {
        let mut v = a[r][3];
        for c in r + 1..3 {
            v -= a[r][c] * sol[c];
        }
        sol[r] = v / a[r][r];
    }
    let (cx, cy) = (-sol[0] / 2.0, -sol[1] / 2.0);
    let r2 = cx * cx + cy * cy - sol[2];
    (r2 > 0.0 && r2.is_finite()).then(|| ([cx + ox, cy + oy], r2.sqrt()))
}

/// How well a window is an arc: `(largest |‖M − c‖ − R| / R, least (M − c) × V / (|M − c|
/// |V|) times the winding sign, turn in degrees)`.
fn arc_measure(s: &Samples, idx: &[usize]) -> Option<(f64, f64, f64)> {
    let (c, r) = kasa(s, idx)?;
    let dev = idx
        .iter()
        .map(|&k| ((s.x[k] - c[0]).hypot(s.y[k] - c[1]) - r).abs() / r)
        .fold(0.0, f64::max);
    let cross: Vec<f64> = idx
        .iter()
        .map(|&k| {
            let (dx, dy) = (s.x[k] - c[0], s.y[k] - c[1]);
            (dx * s.vy[k] - dy * s.vx[k]) / (dx.hypot(dy) * s.vx[k].hypot(s.vy[k]))
        })
        .collect();
    let sign = if cross[0] >= 0.0 { 1.0 } else { -1.0 };
    let winding = cross.iter().map(|x| sign * x).fold(f64::MAX, f64::min);
    let turn: f64 = idx
        .windows(2)
        .map(|w| {
            let a = [s.x[w[0]] - c[0], s.y[w[0]] - c[1]];
            let b = [s.x[w[1]] - c[0], s.y[w[1]] - c[1]];
            sign * (a[0] * b[1] - a[1] * b[0]).atan2(a[0] * b[0] + a[1] * b[1])
        })
        .sum();
    Some((dev, winding, turn.to_degrees()))
}

/// Do windows `(start, steps)` on a closed curve of `n` samples share a step?
fn share_a_step(n: usize, a: (usize, usize), b: (usize, usize)) -> bool {
    (0..a.1).any(|k| {
        let e = (a.0 + k) % n;
        (e + n - b.0) % n < b.1
    })
}

struct Tally {
    curves: usize,
    straight: usize,
    arcs: usize,
    failures: Vec<String>,
    /// Curves with a missed straight window, with a missed arc window.
    missed: [usize; 2],
}

/// Checks one curve; `tol` the spec's feature tolerances.
fn check_curve(
    l: &Linkage,
    circuit: Circuit,
    p: CouplerPoint,
    tol: &FeatureTolerances,
    t: &mut Tally,
) {
    let f = FeatureExtractor::new(l, circuit, tol, &DashPattern::default())
        .unwrap()
        .extract(p);
    let s = sample(l, circuit, p, tol.step_deg);
    let n = s.x.len();
    let steps = |deg: f64| (deg / tol.step_deg).round() as usize;
    let lines: Vec<(usize, usize)> = f
        .straight_segments
        .iter()
        .map(|w| (steps(w.start_deg), steps(w.span_deg)))
        .collect();
    let arcs: Vec<(usize, usize)> = f
        .pseudo_arcs
        .iter()
        .map(|w| (steps(w.start_deg), steps(w.span_deg)))
        .collect();
    let min_line = (tol.straight_min_span_deg / tol.step_deg - 1e-9).ceil() as usize;
    let min_arc = (tol.arc_min_span_deg / tol.step_deg - 1e-9).ceil() as usize;
    let (st, at) = (tol.straight_pct / 100.0, tol.arc_pct / 100.0);
    let name = format!("{l} {circuit} ({}, {})", p.u, p.v);
    let mut missed = [false; 2];
    // Listed windows qualify.
    for &(i, w) in &lines {
        let ok = w >= min_line
            && straightness(&s, i, w, true).is_some_and(|(e, one)| one && e <= st * (1.0 + MARGIN));
        if !ok {
            t.failures
                .push(format!("{name}: listed line {i}+{w} does not qualify"));
        }
    }
    for &(i, w) in &arcs {
        let idx: Vec<usize> = (i..=i + w).map(|k| k % n).collect();
        let ok = w >= min_arc
            && arc_measure(&s, &idx).is_some_and(|(d, wd, turn)| {
                d <= at * (1.0 + MARGIN) && wd > -MARGIN && turn >= tol.arc_min_turn_deg - 1e-6
            });
        if !ok {
            t.failures
                .push(format!("{name}: listed arc {i}+{w} does not qualify"));
        }
    }
    // Every window that clearly qualifies shares a step with a listed window at least as long.
    for i in 0..n {
        for w in min_line.min(min_arc)..n {
            let idx: Vec<usize> = (i..=i + w).map(|k| k % n).collect();
            let covered = |list: &[(usize, usize)]| {
                list.iter()
                    .any(|&(a, b)| b >= w && share_a_step(n, (i, w), (a, b)))
            };
            if w >= min_line && !covered(&lines) {
                if let Some((e, true)) = straightness(&s, i, w, true) {
                    if e <= st * (1.0 - MARGIN) {
                        missed[0] = true;
                        t.failures.push(format!(
                            "{name}: straight window {}°+{}° (ε_S {:.4} %) is longer than or disjoint from the listed {lines:?}",
                            i as f64 * tol.step_deg,
                            w as f64 * tol.step_deg,
                            e * 100.0
                        ));
                    }
                }
            }
            if w >= min_arc && !covered(&arcs) {
                if let Some((d, wd, turn)) = arc_measure(&s, &idx) {
                    if d <= at * (1.0 - MARGIN)
                        && wd > MARGIN
                        && turn >= tol.arc_min_turn_deg + 1e-6
                    {
                        missed[1] = true;
                        t.failures.push(format!(
                            "{name}: arc window {}°+{}° (deviation {:.4} %, turn {turn:.1}°) is longer than or disjoint from the listed {arcs:?}",
                            i as f64 * tol.step_deg,
                            w as f64 * tol.step_deg,
                            d * 100.0
                        ));
                    }
                }
            }
        }
    }
    t.curves += 1;
    t.missed[0] += missed[0] as usize;
    t.missed[1] += missed[1] as usize;
    t.straight += lines.len();
    t.arcs += arcs.len();
}

fn check_atlas(file: &str) -> Tally {
    let text = std::fs::read_to_string(format!("{}/atlas-spec/{file}", env!("CARGO_MANIFEST_DIR")))
        .unwrap();
    let AtlasSpec::Grid(spec) = AtlasSpec::parse(&text, file).unwrap() else {
        panic!("{file} is a grid spec");
    };
    let tol = spec.features.tolerances;
    let job = Job::new(*spec, file, "unused", 1);
    let mut t = Tally {
        curves: 0,
        straight: 0,
        arcs: 0,
        failures: vec![],
        missed: [0, 0],
    };
    for g in job.groups() {
        for &p in &g.points {
            check_curve(&g.linkage, g.circuit, p, &tol, &mut t);
        }
    }
    t
}

fn report(file: &str, t: &Tally) {
    println!(
        "{file}: {} curves, {} straight segments, {} arcs, {} failures; curves with a missed straight window: {}, with a missed arc: {}",
        t.curves,
        t.straight,
        t.arcs,
        t.failures.len(),
        t.missed[0],
        t.missed[1]
    );
    assert!(
        t.failures.is_empty(),
        "{file}: {} failures, e.g.\n{}",
        t.failures.len(),
        t.failures
            .iter()
            .take(12)
            .cloned()
            .collect::<Vec<_>>()
            .join("\n")
    );
}

#[test]
fn quick_atlas_windows_are_maximal() {
    let t = check_atlas("quick.toml");
    assert_eq!(t.curves, 72);
    report("quick.toml", &t);
}

#[test]
fn hartenberg_denavit_windows_are_maximal() {
    let t = check_atlas("hartenberg-denavit.toml");
    assert_eq!(t.curves, 90);
    report("hartenberg-denavit.toml", &t);
}

/// The classics' straight runs (positions only, longest by input travel): no run of any
/// branch that moves one way along its line within the tolerance travels farther than the
/// reported one (or as far with a smaller ε_S).
#[test]
fn classic_runs_are_the_longest() {
    let text = std::fs::read_to_string(format!(
        "{}/atlas-spec/classics.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    let AtlasSpec::Curves(list) = AtlasSpec::parse(&text, "classics.toml").unwrap() else {
        panic!("classics.toml is a page set");
    };
    let mut failures = vec![];
    let mut checked = 0;
    for c in &list.curves {
        let t0 = std::time::Instant::now();
        let m = ClassicCurve::compute(c, list.sampling.crank_step_deg);
        println!(
            "{}: computed in {:.2} s",
            c.name,
            t0.elapsed().as_secs_f64()
        );
        for (ti, &tol) in STRAIGHTNESS_TOLERANCES.iter().enumerate() {
            let reported = m.straight[ti];
            let best = reported.map_or(0.0, |r| r.input_span_deg);
            if let Some(r) = reported {
                let b = &m.branches[r.branch];
                let s = Samples {
                    x: b.samples.iter().map(|q| q.point.x).collect(),
                    y: b.samples.iter().map(|q| q.point.y).collect(),
                    vx: vec![],
                    vy: vec![],
                };
                let ok = straightness(&s, r.samples[0], r.samples[1] - 1, false)
                    .is_some_and(|(e, one)| one && e <= tol * (1.0 + MARGIN));
                if !ok {
                    failures.push(format!(
                        "{} at {tol}: the reported run does not qualify",
                        c.name
                    ));
                }
            }
            for b in &m.branches {
                let s = Samples {
                    x: b.samples.iter().map(|q| q.point.x).collect(),
                    y: b.samples.iter().map(|q| q.point.y).collect(),
                    vx: vec![],
                    vy: vec![],
                };
                let deg: Vec<f64> = b.samples.iter().map(|q| q.degrees).collect();
                let n = deg.len();
                for i in 0..n {
                    let mut travel = 0.0;
                    let mut cone = Cone {
                        first: None,
                        lo: 0.0,
                        hi: 0.0,
                    };
                    let mut sums = RunSums {
                        m: 1.0,
                        ..RunSums::default()
                    };
                    for j in i + 1..n {
                        travel += (deg[j] - deg[j - 1]).abs();
                        let (x, y) = (s.x[j] - s.x[i], s.y[j] - s.y[i]);
                        sums.m += 1.0;
                        sums.sx += x;
                        sums.sy += y;
                        sums.sxx += x * x;
                        sums.sxy += x * y;
                        sums.syy += y * y;
                        sums.polyline += (s.x[j] - s.x[j - 1]).hypot(s.y[j] - s.y[j - 1]);
                        if !cone.fits([s.x[j] - s.x[j - 1], s.y[j] - s.y[j - 1]]) {
                            break;
                        }
                        if j < i + 2 || travel <= best * (1.0 + 1e-12) {
                            continue;
                        }
                        if let Some((e, true)) = run_straightness(&s, i, j, tol, &sums) {
                            if e <= tol * (1.0 - MARGIN) {
                                failures.push(format!(
                                    "{} at ε_S ≤ {tol}: run {:.2}°..{:.2}° travels {travel:.2}° at ε_S {e:.3e}, longer than the reported {best:.2}°",
                                    c.name, deg[i], deg[j]
                                ));
                            }
                        }
                    }
                }
            }
            checked += 1;
        }
    }
    println!(
        "classics: {checked} curve × tolerance cells, {} failures",
        failures.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Sums of a run grown from its first sample (about that sample), for its fitted line.
#[derive(Default)]
struct RunSums {
    m: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
    polyline: f64,
}

/// [`straightness`] of the run `[i, j]` of a branch, by steps, giving up (`None`) as soon
/// as the spread across the fitted line exceeds `tol` times the length of the polyline
/// through the run (which bounds its extent along any line): such a run cannot qualify.
/// `sums` are the run's sums about sample `i`.
fn run_straightness(
    s: &Samples,
    i: usize,
    j: usize,
    tol: f64,
    sums: &RunSums,
) -> Option<(f64, bool)> {
    let (gx, gy) = (sums.sx / sums.m, sums.sy / sums.m);
    let d = major_axis(
        sums.sxx - sums.m * gx * gx,
        sums.sxy - sums.m * gx * gy,
        sums.syy - sums.m * gy * gy,
    );
    let (gx, gy) = (gx + s.x[i], gy + s.y[i]);
    let (mut y0, mut y1) = (f64::MAX, f64::MIN);
    // Ends first, then inwards: the spread of a bent run shows early. (A 1e-6 allowance:
    // this line is the same as `straightness`'s only up to rounding.)
    for q in 0..=(j - i) {
        let k = if q % 2 == 0 { i + q / 2 } else { j - q / 2 };
        let cy = (s.y[k] - gy) * d[0] - (s.x[k] - gx) * d[1];
        (y0, y1) = (y0.min(cy), y1.max(cy));
        if y1 - y0 > tol * sums.polyline * (1.0 + 1e-6) {
            return None;
        }
    }
    straightness(s, i, j - i, false)
}

/// The nonzero steps of a run, as angles from the run's first nonzero step: they lie in
/// an open half-plane (a run moving one way along any line needs that) iff their range is
/// below π. Once that fails, every longer run from the same start fails too.
struct Cone {
    first: Option<f64>,
    lo: f64,
    hi: f64,
}

impl Cone {
    fn fits(&mut self, v: [f64; 2]) -> bool {
        if v == [0.0, 0.0] {
            return self.hi - self.lo < std::f64::consts::PI;
        }
        let a = v[1].atan2(v[0]);
        let f = *self.first.get_or_insert(a);
        let mut d = a - f;
        while d > std::f64::consts::PI {
            d -= std::f64::consts::TAU;
        }
        while d <= -std::f64::consts::PI {
            d += std::f64::consts::TAU;
        }
        self.lo = self.lo.min(d);
        self.hi = self.hi.max(d);
        self.hi - self.lo < std::f64::consts::PI
    }
}
