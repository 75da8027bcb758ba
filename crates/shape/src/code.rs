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

use crate::geom::{C64, abs, arg, cis, cis_deg, resample};
use crate::kin::CouplerCurve;

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
        let z = curve.sample(TRACE)?;
        let r = resample(&z, true, SAMPLES)?;
        let n = normalized(&fourier(&r))?;
        Some(quantize(&canonical(&n)?[0]))
    }
}

/// `Z_k`, `k = −H..H`, of points evenly spaced in the parameter (a DFT; the transcendentals
/// from exact degree reduction, so deterministic).
pub(crate) fn fourier(z: &[C64]) -> Vec<C64> {
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
    let h = HARMONICS as f64;
    let (z1, zm1) = (z[HARMONICS + 1], z[HARMONICS - 1]);
    if abs(z1) == 0.0 && abs(zm1) == 0.0 {
        return None;
    }
    let beta = 0.5 * (arg(zm1) - arg(z1));
    let alpha = -arg(z1) - beta;
    let make = |b: f64, a: f64| -> Vec<C64> {
        (0..z.len())
            .map(|i| z[i] * cis(a + (i as f64 - h) * b))
            .collect()
    };
    let pi = std::f64::consts::PI;
    Some([make(beta, alpha), make(beta + pi, alpha - pi)])
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
    use coupler_kinematics::{Circuit, CouplerPoint, FourBar};

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
