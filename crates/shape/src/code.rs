//! Shape codes of closed curves: normalised elliptic Fourier descriptors (Kuhl &
//! Giardina, "Elliptic Fourier features of a closed contour", Computer Graphics and Image
//! Processing 18, 1982), in the complex form: the curve `z(s)`, parametrised by arc length
//! `s ∈ [0, 2π)`, has coefficients `Z_k = (1/2π)∮ z(s) e^{−iks} ds`. Dropping `Z_0`
//! removes translation; dividing by `(Σ_{k≠0} |Z_k|²)^{1/2}` removes scale; rotating by
//! `α` multiplies every `Z_k` by `e^{iα}` and moving the start by `β` multiplies `Z_k` by
//! `e^{ikβ}`, so choosing `α`, `β` to make `Z_1` and `Z_{−1}` real and positive (the first
//! harmonic ellipse's major axis on +x, the start at its end) removes both, up to the
//! pair `(α + π, β + π)` (Kuhl & Giardina's 180° ambiguity), which the query side tries.
//! The `four-bar` crate's atlas uses the same descriptors (Chang, Chang & Lee, IFToMM WC
//! 2023).

use crate::geom::{C64, abs, arg, cis, cis_deg, resample, resample_into};
use crate::kin::{CouplerCurve, sample_poses, trace_points};
use coupler_kinematics::{Circuit, CouplerPoint, Linkage, PoseTable};
use std::sync::OnceLock;

/// Harmonics kept, `k = −H..H` without 0.
pub const HARMONICS: usize = 6;
/// Values in a code: real and imaginary parts of `Z_k`, `k = −6..−1, 1..6`.
pub const CODE_LEN: usize = 4 * HARMONICS;
/// Bytes of a code: `CODE_LEN` little-endian `i16`, each coefficient × 32767.
pub const CODE_BYTES: usize = 2 * CODE_LEN;
/// Arc-length samples the coefficients are computed from.
const SAMPLES: usize = 256;
/// Crank samples of the trace the arc length is measured on.
const TRACE: usize = 720;

/// The shape code of one closed curve: [`CODE_LEN`] quantised coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ShapeCode(pub [i16; CODE_LEN]);

impl ShapeCode {
    /// Stands for "no code" (a curve that cannot be described): every value at the top
    /// of the range, which no normalised code can be (their values have unit norm).
    /// [`ClosedQuery::distance`] to it is infinite.
    pub const ABSENT: ShapeCode = ShapeCode([i16::MAX; CODE_LEN]);

    /// The code's bytes (little-endian), [`CODE_BYTES`] of them: the same on every machine.
    pub fn to_bytes(&self) -> [u8; CODE_BYTES] {
        let mut out = [0u8; CODE_BYTES];
        for (i, v) in self.0.iter().enumerate() {
            out[2 * i..2 * i + 2].copy_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Reads [`ShapeCode::to_bytes`]; `None` for a slice of another length.
    pub fn from_bytes(bytes: &[u8]) -> Option<ShapeCode> {
        if bytes.len() != CODE_BYTES {
            return None;
        }
        let mut v = [0i16; CODE_LEN];
        for (i, x) in v.iter_mut().enumerate() {
            *x = i16::from_le_bytes([bytes[2 * i], bytes[2 * i + 1]]);
        }
        Some(ShapeCode(v))
    }

    /// The coefficients as numbers.
    pub fn values(&self) -> [f64; CODE_LEN] {
        let mut out = [0.0; CODE_LEN];
        for (o, v) in out.iter_mut().zip(self.0.iter()) {
            *o = *v as f64 / 32767.0;
        }
        out
    }

    /// The code of an atlas curve, from its exact trace; `None` if it does not assemble
    /// all round or has no length.
    pub fn of_curve(curve: &CouplerCurve) -> Option<ShapeCode> {
        let poses = sample_poses(&curve.linkage, curve.circuit, TRACE)?;
        Coder::default().code(&poses, curve.point)
    }

    /// The codes of the curves of `points` on `circuit` of `linkage`, in order: each the
    /// [`ShapeCode::of_curve`] of its curve, the same values, with the poses (a function
    /// of the linkage alone) solved once for all of them.
    pub fn of_points(
        linkage: &Linkage,
        circuit: Circuit,
        points: &[CouplerPoint],
    ) -> Vec<Option<ShapeCode>> {
        let Some(poses) = sample_poses(linkage, circuit, TRACE) else {
            return vec![None; points.len()];
        };
        let mut coder = Coder::default();
        points.iter().map(|&p| coder.code(&poses, p)).collect()
    }
}

/// Room for the steps of a code, kept from one curve to the next.
#[derive(Default)]
struct Coder {
    points: Vec<C64>,
    cum: Vec<f64>,
    even: Vec<C64>,
}

impl Coder {
    /// The code of `point`'s curve traced at `poses` (from [`sample_poses`] with `TRACE`
    /// angles): the steps of [`ShapeCode::of_curve`].
    fn code(&mut self, poses: &PoseTable, point: CouplerPoint) -> Option<ShapeCode> {
        trace_points(poses, point, &mut self.points);
        if !resample_into(&self.points, true, SAMPLES, &mut self.cum, &mut self.even) {
            return None;
        }
        let n = normalized(&fourier_terms(&self.even))?;
        Some(quantize(&canonical_first(&n)?))
    }
}

/// Harmonics `k = −H..H`, zero included.
const TERMS: usize = 2 * HARMONICS + 1;
/// [`TERMS`] rounded up to a whole number of four-lane vectors: the lanes of the DFT's
/// sums (the last ones unused).
const LANES: usize = TERMS.div_ceil(4) * 4;

/// The DFT's factors for `m` points: row `j` holds `e^{−2πi·kj/m}`, `k = −H..H`, as the
/// `m` roots of unity `cis_deg(360°·i/m)`, `i = (−kj) mod m`, real and imaginary parts
/// apart (the lanes past [`TERMS`] 0).
struct Factors {
    re: Vec<[f64; LANES]>,
    im: Vec<[f64; LANES]>,
}

impl Factors {
    fn new(m: usize) -> Factors {
        let roots: Vec<C64> = (0..m)
            .map(|j| cis_deg(360.0 * j as f64 / m as f64))
            .collect();
        let mut re = vec![[0.0; LANES]; m];
        let mut im = vec![[0.0; LANES]; m];
        for j in 0..m {
            for (t, k) in (-(HARMONICS as i64)..=(HARMONICS as i64)).enumerate() {
                let r = roots[(-k * j as i64).rem_euclid(m as i64) as usize];
                re[j][t] = r.re;
                im[j][t] = r.im;
            }
        }
        Factors { re, im }
    }
}

/// `Z_k`, `k = −H..H`, of points evenly spaced in the parameter (a DFT; the transcendentals
/// from exact degree reduction, so deterministic).
pub(crate) fn fourier(z: &[C64]) -> Vec<C64> {
    fourier_terms(z).to_vec()
}

/// [`fourier`] as an array: each `Z_k` the sum over `j` in order of `z_j` times its
/// factor, divided by `m`. Every harmonic's sum is taken side by side in a lane of its
/// own, each in the order and with the operations of a sum of complex products (the same
/// values as one harmonic at a time); the factors of [`SAMPLES`] points made once.
fn fourier_terms(z: &[C64]) -> [C64; TERMS] {
    static SAMPLED: OnceLock<Factors> = OnceLock::new();
    let m = z.len();
    let made;
    let f = if m == SAMPLES {
        SAMPLED.get_or_init(|| Factors::new(SAMPLES))
    } else {
        made = Factors::new(m);
        &made
    };
    let (re, im) = fourier_sums(z, f);
    std::array::from_fn(|t| C64::new(re[t], im[t]) / m as f64)
}

/// The DFT's sums, [`fourier_sums_body`]: on x86-64 with AVX2 (checked at run time) the
/// same code compiled for AVX2 (four lanes a vector), the same operations in the same
/// order, so the same values bit for bit.
fn fourier_sums(z: &[C64], f: &Factors) -> ([f64; LANES], [f64; LANES]) {
    #[cfg(target_arch = "x86_64")]
    if crate::has_avx2() {
        // SAFETY: `fourier_sums_avx2` needs AVX2, which the processor was just found to
        // have; it has no other requirement (the safe body compiled for AVX2).
        #[allow(unsafe_code)]
        return unsafe { fourier_sums_avx2(z, f) };
    }
    fourier_sums_body(z, f)
}

/// [`fourier_sums_body`] compiled for AVX2 (called only where the processor has it).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn fourier_sums_avx2(z: &[C64], f: &Factors) -> ([f64; LANES], [f64; LANES]) {
    fourier_sums_body(z, f)
}

/// `Σ_j z_j·w_jk` for every lane `k`, in order of `j`: real parts, imaginary parts.
#[inline(always)]
fn fourier_sums_body(z: &[C64], f: &Factors) -> ([f64; LANES], [f64; LANES]) {
    let mut re = [0.0; LANES];
    let mut im = [0.0; LANES];
    for ((p, wr), wi) in z.iter().zip(&f.re).zip(&f.im) {
        for t in 0..LANES {
            // `s += p · w` of complex numbers: (a·c − b·d) + i(a·d + b·c).
            re[t] += p.re * wr[t] - p.im * wi[t];
            im[t] += p.re * wi[t] + p.im * wr[t];
        }
    }
    (re, im)
}

/// Drops `Z_0` and scales to unit norm; `None` for a curve with no extent.
pub(crate) fn normalized(z: &[C64]) -> Option<Vec<C64>> {
    let mut v = z.to_vec();
    v[HARMONICS] = C64::new(0.0, 0.0);
    let n = v.iter().map(|c| c.norm_sqr()).sum::<f64>().sqrt();
    (n > 0.0 && n.is_finite()).then(|| v.iter().map(|c| c / n).collect())
}

/// The two Kuhl–Giardina normalisations: `Z_k · e^{i(α + kβ)}` with `Z_1`, `Z_{−1}` real
/// positive, and the same with `(α + π, β + π)`.
pub(crate) fn canonical(z: &[C64]) -> Option<[Vec<C64>; 2]> {
    let (beta, alpha) = start_and_turn(z)?;
    let pi = std::f64::consts::PI;
    Some([turned(z, beta, alpha), turned(z, beta + pi, alpha - pi)])
}

/// The first of [`canonical`]'s two normalisations alone (the same values).
fn canonical_first(z: &[C64]) -> Option<Vec<C64>> {
    let (beta, alpha) = start_and_turn(z)?;
    Some(turned(z, beta, alpha))
}

/// `(β, α)` of [`canonical`]'s first normalisation; `None` if `Z_1 = Z_{−1} = 0`.
fn start_and_turn(z: &[C64]) -> Option<(f64, f64)> {
    let (z1, zm1) = (z[HARMONICS + 1], z[HARMONICS - 1]);
    if abs(z1) == 0.0 && abs(zm1) == 0.0 {
        return None;
    }
    let beta = 0.5 * (arg(zm1) - arg(z1));
    let alpha = -arg(z1) - beta;
    Some((beta, alpha))
}

/// `Z_k · e^{i(a + kb)}`.
fn turned(z: &[C64], b: f64, a: f64) -> Vec<C64> {
    let h = HARMONICS as f64;
    (0..z.len())
        .map(|i| z[i] * cis(a + (i as f64 - h) * b))
        .collect()
}

/// Packs `Z_k`, `k ≠ 0`, as (re, im) pairs in order of `k`.
pub(crate) fn flatten(z: &[C64]) -> [f64; CODE_LEN] {
    let mut out = [0.0; CODE_LEN];
    let mut i = 0;
    for (k, c) in z.iter().enumerate() {
        if k == HARMONICS {
            continue;
        }
        out[i] = c.re;
        out[i + 1] = c.im;
        i += 2;
    }
    out
}

fn quantize(z: &[C64]) -> ShapeCode {
    let f = flatten(z);
    let mut v = [0i16; CODE_LEN];
    for (o, x) in v.iter_mut().zip(f.iter()) {
        *o = (x.clamp(-1.0, 1.0) * 32767.0).round() as i16;
    }
    ShapeCode(v)
}

/// The query side of a closed target: its normalised coefficients for every variant the
/// search allows (the order reversed: the crank driven the other way; reflected, if
/// allowed), each with both Kuhl–Giardina solutions, and for several smoothings of the
/// points (see the `smooth` module): the coarse distance to a code is the least over them.
#[derive(Clone, Debug)]
pub struct ClosedQuery {
    pub(crate) vectors: Vec<[f64; CODE_LEN]>,
    /// How many of `vectors` (the first ones) describe the unreflected target.
    plain: usize,
}

/// Divisors of the point count that set the smoothing terms of a closed query: one term
/// per 5, 8 and 12 points (fewer terms average more noise, more keep sharp turns; the
/// coarse distance takes the best).
const SMOOTHINGS: [usize; 3] = [5, 8, 12];

impl ClosedQuery {
    /// The query vectors of a closed target's points; `None` if none can be formed.
    pub fn new(points: &[C64], allow_mirror: bool) -> Option<ClosedQuery> {
        use rayon::prelude::*;
        // Every (order, smoothing), described in parallel on the calling thread's rayon
        // pool (a least-squares smoothing each: most of a closed query's work before the
        // fits), unreflected and, if allowed, reflected; kept in the order (reflection,
        // order, smoothing), so the vectors are the same on any number of threads. The
        // reflected target's smoothed points are the unreflected ones' mirror images
        // (the smoothing commutes with the reflection: the same chord and arc lengths,
        // conjugate coefficients), made from them rather than smoothed again.
        let describe = |r: &[C64]| -> Vec<[f64; CODE_LEN]> {
            let Some(n) = normalized(&fourier(r)) else {
                return Vec::new();
            };
            canonical(&n).map_or_else(Vec::new, |c| c.iter().map(|x| flatten(x)).collect())
        };
        let smoothed = |mir: bool, rev: bool, d: usize| -> Option<(Vec<C64>, bool)> {
            let mut v: Vec<C64> = points
                .iter()
                .map(|&z| if mir { z.conj() } else { z })
                .collect();
            if rev {
                v.reverse();
            }
            let terms = (v.len() / d).clamp(2, 24);
            match super::smooth::smooth_resample(&v, true, terms, SAMPLES) {
                Some(r) => Some((r.0, true)),
                None => resample(&v, true, SAMPLES).map(|r| (r, false)),
            }
        };
        let mut jobs = Vec::new();
        for rev in [false, true] {
            for d in SMOOTHINGS {
                jobs.push((rev, d));
            }
        }
        let parts: Vec<[Vec<[f64; CODE_LEN]>; 2]> = jobs
            .into_par_iter()
            .map(|(rev, d)| {
                let plain = smoothed(false, rev, d);
                let reflected = if !allow_mirror {
                    Vec::new()
                } else {
                    match &plain {
                        Some((r, true)) => {
                            describe(&r.iter().map(|z| z.conj()).collect::<Vec<_>>())
                        }
                        _ => smoothed(true, rev, d).map_or_else(Vec::new, |r| describe(&r.0)),
                    }
                };
                [plain.map_or_else(Vec::new, |r| describe(&r.0)), reflected]
            })
            .collect();
        // The unreflected jobs' vectors first: both orders, every smoothing.
        let (plain, reflected): (Vec<_>, Vec<_>) = parts.into_iter().map(|[p, r]| (p, r)).unzip();
        let mut vectors = plain.concat();
        let plain = vectors.len();
        vectors.extend(reflected.into_iter().flatten());
        (!vectors.is_empty()).then_some(ClosedQuery { vectors, plain })
    }

    /// The coarse distance to a code: the least squared Euclidean distance over the query
    /// vectors.
    pub fn distance(&self, code: &ShapeCode) -> f64 {
        self.distance_over(&self.vectors, code)
    }

    /// The coarse distance to a code of the target unreflected (`mirrored` false: the
    /// same value, bit for bit, as a query without reflection gives) or reflected
    /// (infinite when the query does not allow reflection).
    pub fn distance_of(&self, code: &ShapeCode, mirrored: bool) -> f64 {
        let (plain, reflected) = self.vectors.split_at(self.plain);
        self.distance_over(if mirrored { reflected } else { plain }, code)
    }

    /// Whether the query describes the reflected target too.
    pub fn allows_mirror(&self) -> bool {
        self.plain < self.vectors.len()
    }

    fn distance_over(&self, vectors: &[[f64; CODE_LEN]], code: &ShapeCode) -> f64 {
        if *code == ShapeCode::ABSENT {
            return f64::INFINITY;
        }
        let c = code.values();
        vectors
            .iter()
            .map(|q| {
                q.iter()
                    .zip(c.iter())
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
            })
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::{FourBar, GearRatio, GearedFiveBar};

    /// The DFT one harmonic at a time, as a sum of complex products with a root of unity
    /// looked up per term: the definition [`fourier`] keeps, bit for bit.
    fn fourier_by_harmonic(z: &[C64]) -> Vec<C64> {
        let m = z.len() as i64;
        let roots: Vec<C64> = (0..m)
            .map(|j| cis_deg(360.0 * j as f64 / m as f64))
            .collect();
        (-(HARMONICS as i64)..=(HARMONICS as i64))
            .map(|k| {
                let mut s = C64::new(0.0, 0.0);
                for (j, &p) in z.iter().enumerate() {
                    s += p * roots[(-k * j as i64).rem_euclid(m) as usize];
                }
                s / m as f64
            })
            .collect()
    }

    /// The harmonics' sums side by side (with the run-time choice of instruction set, and
    /// the plain body alone) are the sums one harmonic at a time, bit for bit, for the
    /// sampled count of points (factors made once) and others (made per call).
    #[test]
    fn fourier_is_the_sum_by_harmonic() {
        let mut rng = crate::cases::SplitMix64(5);
        let bits = |v: &[C64]| -> Vec<(u64, u64)> {
            v.iter().map(|c| (c.re.to_bits(), c.im.to_bits())).collect()
        };
        for m in [SAMPLES, SAMPLES, 72, 100, 257, 3] {
            let z: Vec<C64> = (0..m)
                .map(|_| C64::new(rng.normal(), rng.range(-5.0, 5.0)))
                .collect();
            let want = bits(&fourier_by_harmonic(&z));
            assert_eq!(bits(&fourier(&z)), want, "{m} points");
            let f = Factors::new(m);
            let (re, im) = fourier_sums_body(&z, &f);
            let plain: Vec<C64> = (0..TERMS)
                .map(|t| C64::new(re[t], im[t]) / m as f64)
                .collect();
            assert_eq!(bits(&plain), want, "{m} points, plain body");
        }
    }

    /// A curve's code step by step from the crate's public pieces, the DFT one harmonic at
    /// a time: the definition of [`ShapeCode::of_curve`].
    fn code_by_steps(c: &CouplerCurve) -> Option<ShapeCode> {
        let z = c.sample(TRACE)?;
        let r = resample(&z, true, SAMPLES)?;
        let n = normalized(&fourier_by_harmonic(&r))?;
        Some(quantize(&canonical(&n)?[0]))
    }

    /// A unit's codes made together ([`ShapeCode::of_points`], the poses solved once) are
    /// each curve's own [`ShapeCode::of_curve`] and its code step by step (the same
    /// values), for a four-bar on either circuit and for
    /// geared five-bars (one of a 720° period), and `None` alike for a linkage that does
    /// not assemble all round and for a point with no extent.
    #[test]
    fn codes_of_a_unit_are_each_curves_code() {
        let mut rng = crate::cases::SplitMix64(11);
        let mut points: Vec<CouplerPoint> = (0..12)
            .map(|_| CouplerPoint::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0)))
            .collect();
        points.push(CouplerPoint::new(0.0, 0.0));
        let linkages: Vec<Linkage> = vec![
            FourBar::new(3.0, 2.5, 3.5).unwrap().into(),
            FourBar::new(2.37, 3.1, 3.4).unwrap().into(),
            // A rocker input: does not assemble all round.
            FourBar::new(1.0, 3.0, 3.5).unwrap().into(),
            GearedFiveBar::new(3.0, 3.2, 3.5, 1.2, GearRatio::integer(-2).unwrap(), 40.0)
                .unwrap()
                .into(),
            GearedFiveBar::new(3.0, 3.2, 3.5, 1.2, GearRatio::new(-1, 2).unwrap(), -70.0)
                .unwrap()
                .into(),
        ];
        let mut absent = 0;
        for linkage in &linkages {
            for circuit in [Circuit::Open, Circuit::Crossed] {
                let together = ShapeCode::of_points(linkage, circuit, &points);
                assert_eq!(together.len(), points.len());
                for (&point, code) in points.iter().zip(&together) {
                    let c = CouplerCurve::new(*linkage, circuit, point);
                    let alone = ShapeCode::of_curve(&c);
                    assert_eq!(*code, alone, "{linkage:?} {circuit:?} {point:?}");
                    assert_eq!(
                        alone,
                        code_by_steps(&c),
                        "{linkage:?} {circuit:?} {point:?}"
                    );
                    absent += code.is_none() as usize;
                }
            }
        }
        // Both kinds of `None` were met, and not only them.
        assert!(absent > points.len(), "{absent}");
        assert!(absent < linkages.len() * 2 * points.len() / 2, "{absent}");
    }

    /// A mirror query's reflected vectors (made from the unreflected smoothing, reflected)
    /// are, to rounding, those of the reflected points described alone, and its
    /// unreflected ones are those of the query without reflection, bit for bit.
    #[test]
    fn reflected_description_is_the_reflected_points_description() {
        let mut rng = crate::cases::SplitMix64(17);
        let c = CouplerCurve {
            linkage: FourBar::new(3.0, 2.5, 3.5).unwrap().into(),
            circuit: Circuit::Open,
            point: CouplerPoint::new(1.5, 1.0),
        };
        let z = c.sample(72).unwrap();
        for noise in [0.0, 0.01, 0.03] {
            let pts: Vec<C64> = z
                .iter()
                .map(|&p| 20.0 * p + C64::new(rng.normal(), rng.normal()) * noise * 20.0)
                .collect();
            let both = ClosedQuery::new(&pts, true).unwrap();
            let plain = ClosedQuery::new(&pts, false).unwrap();
            let conj: Vec<C64> = pts.iter().map(|p| p.conj()).collect();
            let alone = ClosedQuery::new(&conj, false).unwrap();
            assert_eq!(both.plain, plain.vectors.len());
            let bits = |v: &[[f64; CODE_LEN]]| -> Vec<u64> {
                v.iter().flatten().map(|x| x.to_bits()).collect()
            };
            assert_eq!(bits(&both.vectors[..both.plain]), bits(&plain.vectors));
            let reflected = &both.vectors[both.plain..];
            assert_eq!(reflected.len(), alone.vectors.len());
            for (a, b) in reflected
                .iter()
                .flatten()
                .zip(alone.vectors.iter().flatten())
            {
                assert!((a - b).abs() < 1e-9, "noise {noise}: {a} against {b}");
            }
        }
    }

    #[test]
    fn invariant_to_similarity_start_and_bytes_round_trip() {
        let c = CouplerCurve {
            linkage: FourBar::new(3.0, 2.5, 3.5).unwrap().into(),
            circuit: Circuit::Open,
            point: CouplerPoint::new(1.5, 1.0),
        };
        let code = ShapeCode::of_curve(&c).unwrap();
        assert_eq!(ShapeCode::from_bytes(&code.to_bytes()), Some(code));
        // The same curve moved, turned, scaled and started elsewhere, as a dense target.
        let z = c.sample(720).unwrap();
        let a = C64::new(-2.0, 7.0);
        let pts: Vec<C64> = (0..720)
            .map(|k| a * z[(k + 137) % 720] + C64::new(50.0, -3.0))
            .collect();
        let q = ClosedQuery::new(&pts, false).unwrap();
        let d = q.distance(&code);
        assert!(d < 1e-4, "{d}");
        // Another curve is farther.
        let other = CouplerCurve {
            point: CouplerPoint::new(0.5, -1.0),
            ..c
        };
        assert!(q.distance(&ShapeCode::of_curve(&other).unwrap()) > 100.0 * d);
    }
}
