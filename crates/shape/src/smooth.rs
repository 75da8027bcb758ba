//! A smooth curve through noisy target points, for describing a target's shape: a
//! least-squares fit in a smooth basis (a truncated Fourier series for a closed target,
//! Chebyshev polynomials for an open one) over a parameter that starts as the cumulative
//! chord length and is then replaced by the fitted curve's own arc length (twice). The
//! arc-length parametrisation of a noisy polyline is badly distorted (points 1 % of the
//! size off a path sampled every 3 % of it stretch the local length by half), and
//! arc-length descriptors inherit the distortion; the smooth fit removes most of it.

use crate::geom::{C64, cis_deg, cumulative_length};
use nalgebra::{DMatrix, DVector};

/// Basis functions at parameter `t ∈ [0, 1]`: for a closed curve `e^{2πikt}`,
/// `k = −h..h` (complex coefficients); for an open one Chebyshev `T_0..T_h(2t − 1)`.
fn basis(closed: bool, h: usize, t: f64, out: &mut Vec<C64>) {
    out.clear();
    if closed {
        // e^{2πikt} for k = −h..h by repeated multiplication from e^{±2πit} (one sine and
        // cosine per point; the error grows by an ulp or so per step, far below the noise
        // this fit averages).
        // The powers `e^k`, k = 0..h, made in place at the end of `out`, then their
        // conjugates in front (the same values as building them apart).
        let e = cis_deg(360.0 * t.rem_euclid(1.0));
        out.resize(2 * h + 1, C64::new(1.0, 0.0));
        let (down, up) = out.split_at_mut(h);
        for k in 1..=h {
            up[k] = up[k - 1] * e;
        }
        for (d, u) in down.iter_mut().zip(up[1..].iter().rev()) {
            *d = u.conj();
        }
    } else {
        let x = 2.0 * t - 1.0;
        let (mut a, mut b) = (1.0, x);
        out.push(C64::new(1.0, 0.0));
        if h >= 1 {
            out.push(C64::new(x, 0.0));
        }
        for _ in 2..=h {
            let c = 2.0 * x * b - a;
            out.push(C64::new(c, 0.0));
            a = b;
            b = c;
        }
    }
}

/// Coefficients minimising `Σ |Σ_k c_k φ_k(t_j) − z_j|²` (complex least squares through
/// the real normal equations of the stacked real and imaginary parts; small and well
/// conditioned for these bases). `None` if singular.
fn fit(z: &[C64], t: &[f64], closed: bool, h: usize) -> Option<Vec<C64>> {
    let nb = if closed { 2 * h + 1 } else { h + 1 };
    let n2 = 2 * nb;
    // Unknowns: re and im of each c_k. Residual re/im of Σ c_k φ_k − z. The normal
    // equations' upper triangle is summed row-major in `upper` (each entry over the points
    // in order, the same terms as summing into the matrix), the rows' two columns held
    // apart (`r0`, `r1`) so the inner sums run in vector registers.
    let mut upper = vec![0.0f64; n2 * n2];
    let mut atb = DVector::<f64>::zeros(n2);
    let mut phi = Vec::with_capacity(nb);
    let mut r0 = vec![0.0f64; n2];
    let mut r1 = vec![0.0f64; n2];
    for (&zj, &tj) in z.iter().zip(t) {
        basis(closed, h, tj, &mut phi);
        // (c.re + i c.im)(φ.re + i φ.im): real part = c.re φ.re − c.im φ.im,
        // imaginary part = c.re φ.im + c.im φ.re.
        for (k, f) in phi.iter().enumerate() {
            (r0[2 * k], r1[2 * k]) = (f.re, f.im);
            (r0[2 * k + 1], r1[2 * k + 1]) = (-f.im, f.re);
        }
        for p in 0..n2 {
            let (a0, a1) = (r0[p], r1[p]);
            atb[p] += a0 * zj.re + a1 * zj.im;
            let row = &mut upper[p * n2 + p..(p + 1) * n2];
            for ((u, &b0), &b1) in row.iter_mut().zip(&r0[p..]).zip(&r1[p..]) {
                *u += a0 * b0 + a1 * b1;
            }
        }
    }
    let ata = DMatrix::<f64>::from_fn(n2, n2, |p, q| {
        if q >= p {
            upper[p * n2 + q]
        } else {
            upper[q * n2 + p]
        }
    });
    solve_penalized(ata, &atb, z.len(), closed, h)
}

/// The coefficients from the normal equations `ata`, `atb` of `points` points (both
/// halves of `ata` filled), with a light roughness penalty on the diagonal, growing as the
/// fourth power of the frequency (degree): it keeps the fit well posed where the
/// parameters leave gaps. `None` if singular.
fn solve_penalized(
    mut ata: DMatrix<f64>,
    atb: &DVector<f64>,
    points: usize,
    closed: bool,
    h: usize,
) -> Option<Vec<C64>> {
    let nb = if closed { 2 * h + 1 } else { h + 1 };
    let scale = points as f64;
    for k in 0..nb {
        let freq = if closed {
            k as f64 - h as f64
        } else {
            k as f64
        };
        let w = 1e-6 * scale * (freq * freq / (h * h).max(1) as f64).powi(2);
        ata[(2 * k, 2 * k)] += w;
        ata[(2 * k + 1, 2 * k + 1)] += w;
    }
    let x = ata.cholesky()?.solve(atb);
    Some((0..nb).map(|k| C64::new(x[2 * k], x[2 * k + 1])).collect())
}

fn eval(c: &[C64], closed: bool, t: f64, phi: &mut Vec<C64>) -> C64 {
    let h = if closed {
        (c.len() - 1) / 2
    } else {
        c.len() - 1
    };
    basis(closed, h, t, phi);
    let mut s = C64::new(0.0, 0.0);
    for (a, b) in c.iter().zip(phi.iter()) {
        s += a * b;
    }
    s
}

/// The number of basis terms used for `n` points: enough for the sharp turns of coupler
/// curves, few enough to average the noise (about one term per 4 points), at most
/// `max_h`.
pub fn default_terms(n: usize, max_h: usize) -> usize {
    (n / 8).clamp(2, max_h)
}

/// Fits a smooth curve to `z` (ordered; closed or open) with `h` harmonics or polynomial
/// degree `h`, re-parametrised by arc length, and returns `m` points of it evenly spaced
/// in arc length (closed: not repeating the first; open: both ends), together with the
/// arc-length fraction at which each input point's parameter lands. `None` when the fit
/// fails or the curve has no length.
pub fn smooth_resample(
    z: &[C64],
    closed: bool,
    h: usize,
    m: usize,
) -> Option<(Vec<C64>, Vec<f64>)> {
    let n = z.len();
    let cum = cumulative_length(z, closed);
    let total = *cum.last()?;
    if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let mut t: Vec<f64> = cum[..n].iter().map(|c| c / total).collect();
    let dense = 1024;
    let mut phi = Vec::new();
    let mut coeffs = fit(z, &t, closed, h)?;
    for _ in 0..2 {
        // Arc length of the fitted curve as a function of its parameter.
        let denom = if closed { dense } else { dense - 1 } as f64;
        let pts: Vec<C64> = (0..dense)
            .map(|j| eval(&coeffs, closed, j as f64 / denom, &mut phi))
            .collect();
        let arc = cumulative_length(&pts, closed);
        let len = *arc.last()?;
        if !(len > 0.0 && len.is_finite()) {
            return None;
        }
        let map = |x: f64| -> f64 {
            let y = x * denom;
            let k = (y.floor() as usize).min(arc.len() - 2);
            let u = y - k as f64;
            (arc[k] + (arc[k + 1] - arc[k]) * u) / len
        };
        for tj in &mut t {
            *tj = map(*tj);
        }
        coeffs = fit(z, &t, closed, h)?;
    }
    // Resample the final fit evenly in its own arc length.
    let denom = if closed { dense } else { dense - 1 } as f64;
    let pts: Vec<C64> = (0..dense)
        .map(|j| eval(&coeffs, closed, j as f64 / denom, &mut phi))
        .collect();
    let out = super::geom::resample(&pts, closed, m)?;
    let arc = cumulative_length(&pts, closed);
    let len = *arc.last()?;
    let frac = t
        .iter()
        .map(|&x| {
            let y = x * denom;
            let k = (y.floor() as usize).min(arc.len() - 2);
            let u = y - k as f64;
            (arc[k] + (arc[k + 1] - arc[k]) * u) / len
        })
        .collect();
    Some((out, frac))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The basis and the normal equations as first written (a power table apart, the
    /// sums into the matrix entry by entry).
    fn reference_fit(z: &[C64], t: &[f64], closed: bool, h: usize) -> Option<Vec<C64>> {
        let basis = |t: f64| -> Vec<C64> {
            let mut out = Vec::new();
            if closed {
                let e = cis_deg(360.0 * t.rem_euclid(1.0));
                let mut up = vec![C64::new(1.0, 0.0); h + 1];
                for k in 1..=h {
                    up[k] = up[k - 1] * e;
                }
                for k in (1..=h).rev() {
                    out.push(up[k].conj());
                }
                out.extend_from_slice(&up);
            } else {
                super::basis(false, h, t, &mut out);
            }
            out
        };
        let nb = if closed { 2 * h + 1 } else { h + 1 };
        let mut ata = DMatrix::<f64>::zeros(2 * nb, 2 * nb);
        let mut atb = DVector::<f64>::zeros(2 * nb);
        let mut rows = vec![[0.0f64; 2]; 2 * nb];
        for (&zj, &tj) in z.iter().zip(t) {
            for (k, f) in basis(tj).iter().enumerate() {
                rows[2 * k] = [f.re, f.im];
                rows[2 * k + 1] = [-f.im, f.re];
            }
            for p in 0..2 * nb {
                atb[p] += rows[p][0] * zj.re + rows[p][1] * zj.im;
                for q in p..2 * nb {
                    ata[(p, q)] += rows[p][0] * rows[q][0] + rows[p][1] * rows[q][1];
                }
            }
        }
        for p in 0..2 * nb {
            for q in 0..p {
                ata[(p, q)] = ata[(q, p)];
            }
        }
        // The penalty and the solve are the fit's own (not changed since first written).
        solve_penalized(ata, &atb, z.len(), closed, h)
    }

    /// The fit gives the reference's coefficients bit for bit, closed and open, for
    /// several point counts and numbers of terms.
    #[test]
    fn fit_sums_as_first_written() {
        let mut rng = crate::cases::SplitMix64(3);
        for (n, h) in [(72, 14), (72, 9), (40, 2), (17, 24), (200, 24)] {
            let z: Vec<C64> = (0..n)
                .map(|_| C64::new(rng.normal(), rng.normal()))
                .collect();
            let mut t: Vec<f64> = (0..n).map(|_| rng.uniform()).collect();
            t.sort_by(f64::total_cmp);
            for closed in [true, false] {
                let bits = |c: Option<Vec<C64>>| -> Option<Vec<(u64, u64)>> {
                    c.map(|c| c.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect())
                };
                assert_eq!(
                    bits(fit(&z, &t, closed, h)),
                    bits(reference_fit(&z, &t, closed, h)),
                    "{n} points, {h} terms, closed {closed}"
                );
                assert!(fit(&z, &t, closed, h).is_some());
            }
        }
    }
}
