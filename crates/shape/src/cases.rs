//! Seeded retrieval cases: targets made from atlas curves the way the retrieval
//! bar describes them (random crank window and sampling, random similarity transform,
//! optional reflection, noise of a given fraction of the target's size). One generator
//! for the retrieval tests, the shape lab's measurements and the benchmark against other
//! shape searches, so that they all measure the same cases (`docs/shape-search.md`).

use crate::geom::{C64, cis, diameter};
use crate::kin::{AtlasCurve, CouplerCurve};
use crate::matching::Match;
use crate::target::{Target, Timing};

/// SplitMix64 (Steele, Lea & Flood 2014): seeded, platform-independent random numbers.
#[derive(Clone, Debug)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`, 53 bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[a, b)`.
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }

    /// Standard normal (Box–Muller, `libm`, so the same on every machine).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * libm::log(u1)).sqrt() * libm::cos(std::f64::consts::TAU * u2)
    }
}

/// The crank angles (degrees, ascending) of `n` target points: a full turn from `start`
/// in equal steps when `closed`; otherwise over `start ..= start + span`, in equal steps
/// or (with even odds) at random between the two ends.
pub fn crank_angles(
    rng: &mut SplitMix64,
    closed: bool,
    start: f64,
    span: f64,
    n: usize,
) -> Vec<f64> {
    let even = rng.uniform() < 0.5;
    let mut angles: Vec<f64> = (0..n)
        .map(|j| {
            if closed {
                start + 360.0 * j as f64 / n as f64
            } else if even || j == 0 || j + 1 == n {
                start + span * j as f64 / (n - 1) as f64
            } else {
                start + span * rng.uniform()
            }
        })
        .collect();
    angles.sort_by(f64::total_cmp);
    angles
}

/// Curve points moved by a random similarity (rotation uniform, scale log-uniform over
/// 0.1–100, translation uniform over ±100), reflected first when `mirrored`, then
/// displaced by isotropic Gaussian noise of RMS length `noise` × the moved points' size
/// (their diameter).
pub fn place_points(rng: &mut SplitMix64, points: &[C64], mirrored: bool, noise: f64) -> Vec<C64> {
    let a = cis(rng.range(0.0, std::f64::consts::TAU)) * 10f64.powf(rng.range(-1.0, 2.0));
    let b = C64::new(rng.range(-100.0, 100.0), rng.range(-100.0, 100.0));
    let mut w: Vec<C64> = points
        .iter()
        .map(|&m| a * if mirrored { m.conj() } else { m } + b)
        .collect();
    let size = diameter(&w);
    for p in &mut w {
        *p += C64::new(rng.normal(), rng.normal()) * (noise * size / std::f64::consts::SQRT_2);
    }
    w
}

/// A target made from curve `c`: `n` points at crank angles from `start` over `span`
/// (a full turn when closed; [`crank_angles`]), moved by a random similarity (reflected
/// when `mirrored`) with noise of RMS length `noise` × the target's size
/// ([`place_points`]); untimed. `None` if the curve does not assemble at those angles.
#[allow(clippy::too_many_arguments)]
pub fn make_target(
    rng: &mut SplitMix64,
    c: &CouplerCurve,
    closed: bool,
    start: f64,
    span: f64,
    n: usize,
    mirrored: bool,
    noise: f64,
) -> Option<Target> {
    let m: Vec<C64> = crank_angles(rng, closed, start, span, n)
        .iter()
        .map(|&t| c.at(t).map(|p| p.m))
        .collect::<Option<_>>()?;
    let pts = place_points(rng, &m, mirrored, noise)
        .iter()
        .map(|z| [z.re, z.im])
        .collect();
    Target::new(pts, closed, Timing::Untimed).ok()
}

/// One retrieval case: the index of the source curve in the atlas list, the target made
/// from it, and the crank window it covers (start and span, degrees).
#[derive(Clone, Debug)]
pub struct Case {
    /// Index of the source in the curves the cases were drawn from.
    pub source: usize,
    /// The target.
    pub target: Target,
    /// First crank angle (degrees).
    pub start: f64,
    /// Crank span (degrees; 360 when closed).
    pub span: f64,
}

/// The retrieval cases, seeded: `count` targets from random `curves`, each with a
/// random start, half of them reflected, 1 % noise. Closed: the full turn, 30–149 points.
/// Open: a window of 90°–270° of crank, 20–100 points. (The retrieval tests use seeds
/// 2024 closed and 77 open.)
pub fn retrieval_cases(curves: &[AtlasCurve], closed: bool, seed: u64, count: usize) -> Vec<Case> {
    seeded_cases(
        curves,
        closed,
        seed,
        count,
        |rng, c, start, span, n, mirrored| {
            make_target(rng, c, closed, start, span, n, mirrored, 0.01)
        },
    )
}

/// Open retrieval cases timed by their crank angles (`Timing::Angles`), seeded: as
/// [`retrieval_cases`] makes its open ones (a window of 90°–270°, 20–100 points at even
/// or random angles, half reflected, 1 % noise), each point with the crank angle it was
/// traced at.
pub fn timed_open_cases(curves: &[AtlasCurve], seed: u64, count: usize) -> Vec<Case> {
    seeded_cases(
        curves,
        false,
        seed,
        count,
        |rng, c, start, span, n, mirrored| {
            let angles = crank_angles(rng, false, start, span, n);
            let m: Vec<C64> = angles
                .iter()
                .map(|&t| c.at(t).map(|p| p.m))
                .collect::<Option<_>>()?;
            let pts = place_points(rng, &m, mirrored, 0.01)
                .iter()
                .map(|z| [z.re, z.im])
                .collect();
            Target::new(pts, false, Timing::Angles(angles)).ok()
        },
    )
}

/// `count` cases drawn with `seed`: each a random source of `curves`, start, span and
/// number of points (closed: the full turn, 30–149 points; open: 90°–270°, 20–100
/// points) and reflection (even odds), handed to `make` for its target (a case is drawn
/// again when `make` gives none).
fn seeded_cases(
    curves: &[AtlasCurve],
    closed: bool,
    seed: u64,
    count: usize,
    mut make: impl FnMut(&mut SplitMix64, &CouplerCurve, f64, f64, usize, bool) -> Option<Target>,
) -> Vec<Case> {
    let mut rng = SplitMix64(seed);
    let mut out = Vec::with_capacity(count);
    while out.len() < count && !curves.is_empty() {
        let source = (rng.next_u64() % curves.len() as u64) as usize;
        let start = rng.range(0.0, 360.0);
        let (span, n) = if closed {
            (360.0, 30 + (rng.next_u64() % 120) as usize)
        } else {
            let span = rng.range(90.0, 270.0);
            (span, 20 + (rng.next_u64() % 81) as usize)
        };
        let mirrored = rng.uniform() < 0.5;
        if let Some(target) = make(&mut rng, &curves[source].curve, start, span, n, mirrored) {
            out.push(Case {
                source,
                target,
                start,
                span,
            });
        }
    }
    out
}

/// Success as the issue defines it: the source among `matches`, or a match at least as
/// close as the source's own exact fit (`source_rms`, user units).
pub fn found(matches: &[Match], source: u64, source_rms: f64) -> bool {
    matches
        .iter()
        .any(|m| m.id == source || m.fit.rms <= source_rms)
}
