//! Straight segments (Norton §3.8; docs/conventions.md §5) and the classics' straight
//! runs: one contract, one search ([`crate::maximal`]).
//!
//! **The fitted line** of a window is the orthogonal (total) least-squares line of its
//! samples, all weighted equally: through their centroid G, along the major axis of their
//! scatter matrix ([`LineSums::line`]). With `d` its unit direction oriented along the
//! motion and `n = J·d`: `Cx = (M − G)·d`, `Cy = (M − G)·n`; `Δx = max Cx − min Cx`;
//! **ε_S = (max Cy − min Cy)/Δx**, the peak-to-peak spread across the line over the
//! extent along it.
//!
//! A window *moves one way along its line* when (on a closed curve, with velocities)
//! every sampled velocity has `Vx = V·d > 0`, `d` oriented so that the mean Vx is ≥ 0;
//! or (on a branch of a full curve, positions only) every step between consecutive
//! samples that moves at all has `ΔCx > 0`, `d` oriented from the first sample towards
//! the last.

use crate::fit::LineSums;
use crate::maximal::{Candidates, Window};
use crate::{FeatureTolerances, StraightSegment, dash_count};
use coupler_kinematics::{Curve, DashPattern};

/// The line measures of a window ([`Track::measure`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct LineFit {
    /// Unit direction of travel along the fitted line.
    pub d: [f64; 2],
    /// Δx.
    pub extent: f64,
    /// max Cy − min Cy.
    pub width: f64,
    /// Moves one way along the line.
    pub monotone: bool,
    /// max Vx − min Vx and mean Vx (0 without velocities).
    pub vx_range: f64,
    pub mean_vx: f64,
}

/// Sliding sums of a window grown one sample at a time, about the window's first sample
/// (so that the sums of a small window far from the origin keep their digits), and the
/// O(1) filter of a straight window: across its fitted line the samples have mean 0 and
/// mean square `λ_min/m` (λ_min the scatter matrix's smaller eigenvalue), so their
/// peak-to-peak spread is at least `2·√(λ_min/m)` (Bhatia–Davis), while the extent is at
/// most the length of the polyline through them. A window with `2·√(λ_min/m) > tol · length`
/// cannot qualify. The spread across any other line is at least as large, so no window
/// containing it qualifies either once `2·√(λ_min/m)` exceeds `tol` times the diameter of
/// all the samples.
///
/// The filter ([`Track::filter`]) grows many windows' sums at once, lane by lane
/// ([`grow`]); this one-window form is its reference in the tests.
#[cfg(test)]
#[derive(Clone, Copy, Debug, Default)]
struct Sliding {
    origin: [f64; 2],
    m: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
}

#[cfg(test)]
impl Sliding {
    fn new(x: f64, y: f64) -> Sliding {
        let mut s = Sliding {
            origin: [x, y],
            ..Sliding::default()
        };
        s.add(x, y);
        s
    }

    #[inline]
    fn add(&mut self, x: f64, y: f64) {
        let (x, y) = (x - self.origin[0], y - self.origin[1]);
        self.m += 1.0;
        self.sx += x;
        self.sy += y;
        self.sxx += x * x;
        self.sxy += x * y;
        self.syy += y * y;
    }

    /// Whether the squared spread across the fitted line is surely above `lim²`: its lower
    /// bound `4·λ_min/m` exceeds `lim²` plus a rounding allowance. Computed without a
    /// division or a root, on the scatter matrix times `m` (`C' = m·C`, no division by
    /// `m`), and with `λ_min ≥ det C / tr C` (as `λ_max ≤ tr C`): so the test is
    /// `4·det C' > (lim²·m² + a)·tr C'` with the allowance `a = 10⁻¹³·tr C'` (that is
    /// `10⁻¹³·tr C/m` on the squared spread, at least the `10⁻¹³·λ_max/m` it covers). The
    /// bound is weaker than `4·λ_min/m` by the factor `λ_max/tr C`, which is within
    /// rounding of 1 for the nearly straight windows the test is about; a window it lets
    /// through goes to the exact test, so what is reported does not change.
    #[inline]
    fn spread_exceeds(&self, lim: f64) -> bool {
        let m = self.m;
        let cxx = m * self.sxx - self.sx * self.sx;
        let cxy = m * self.sxy - self.sx * self.sy;
        let cyy = m * self.syy - self.sy * self.sy;
        let tr = cxx + cyy;
        let det = cxx * cyy - cxy * cxy;
        tr > 0.0 && 4.0 * det > (lim * lim * m * m + 1e-13 * tr) * tr
    }
}

/// Starts filtered together ([`Track::filter`]).
const BLOCK: usize = 32;

/// The state of [`BLOCK`] starts whose windows grow together: `Sliding`'s sums and
/// the half-plane's bounds (`HalfPlane`) by lane, and whether each start still grows.
#[derive(Clone, Copy)]
struct Lanes {
    x0: [f64; BLOCK],
    y0: [f64; BLOCK],
    c0: [f64; BLOCK],
    max_l: [f64; BLOCK],
    reference: [f64; BLOCK],
    alive: [u64; BLOCK],
    sx: [f64; BLOCK],
    sy: [f64; BLOCK],
    sxx: [f64; BLOCK],
    sxy: [f64; BLOCK],
    syy: [f64; BLOCK],
    lo: [f64; BLOCK],
    hi: [f64; BLOCK],
    /// All ones where a direction that is not known ends the window (velocities).
    strict: u64,
}

impl Default for Lanes {
    fn default() -> Lanes {
        let z = [0.0; BLOCK];
        Lanes {
            x0: z,
            y0: z,
            c0: z,
            max_l: z,
            reference: [f64::NAN; BLOCK],
            alive: [0; BLOCK],
            sx: z,
            sy: z,
            sxx: z,
            sxy: z,
            syy: z,
            lo: z,
            hi: z,
            strict: 0,
        }
    }
}

/// The samples at step `l` of the [`BLOCK`] starts' windows.
struct Inputs<'a> {
    x: &'a [f64; BLOCK],
    y: &'a [f64; BLOCK],
    finite: &'a [u64; BLOCK],
    dir: &'a [f64; BLOCK],
    chord: &'a [f64; BLOCK],
}

/// Grows the windows of the [`BLOCK`] starts by one sample (to `l` steps): a lane whose
/// window fails the half-plane test or the far bound, meets a sample that is not finite or
/// passes its start's last window stops growing. `pass` gets the growing lanes whose
/// window passes the near bound. Returns whether any lane still grows. Branch-free per
/// lane: the same operations, in the same order, as
/// `Sliding::add`, `Sliding::spread_exceeds` and `HalfPlane::add` (with
/// `wrap_pi` as two selects; a NaN direction leaves the bounds as
/// they are, as an ignored step does).
#[inline(always)]
#[allow(clippy::needless_range_loop)] // one lane index into a dozen arrays
fn grow(st: &mut Lanes, l: usize, far: f64, tol: f64, at: Inputs, pass: &mut [u64; BLOCK]) -> u64 {
    use std::f64::consts::{PI, TAU};
    let m = (l + 1) as f64;
    let lf = l as f64;
    let mut any = 0;
    for q in 0..BLOCK {
        let (x, y) = (at.x[q] - st.x0[q], at.y[q] - st.y0[q]);
        let sx = st.sx[q] + x;
        let sy = st.sy[q] + y;
        let sxx = st.sxx[q] + x * x;
        let sxy = st.sxy[q] + x * y;
        let syy = st.syy[q] + y * y;
        (st.sx[q], st.sy[q], st.sxx[q], st.sxy[q], st.syy[q]) = (sx, sy, sxx, sxy, syy);
        let cxx = m * sxx - sx * sx;
        let cxy = m * sxy - sx * sy;
        let cyy = m * syy - sy * sy;
        let tr = cxx + cyy;
        let det = cxx * cyy - cxy * cxy;
        let far_out = mask(tr > 0.0) & mask(4.0 * det > (far * far * m * m + 1e-13 * tr) * tr);
        let a = at.dir[q];
        let d = a - st.reference[q];
        let d = if d > PI {
            d - TAU
        } else if d <= -PI {
            d + TAU
        } else {
            d
        };
        let known = mask(!d.is_nan());
        let lo = if d < st.lo[q] { d } else { st.lo[q] };
        let hi = if d > st.hi[q] { d } else { st.hi[q] };
        (st.lo[q], st.hi[q]) = (lo, hi);
        let half = mask(hi - lo < PI) & (known | !st.strict);
        let alive = st.alive[q] & at.finite[q] & mask(lf <= st.max_l[q]) & half & !far_out;
        st.alive[q] = alive;
        let near = 1.01 * tol * (at.chord[q] - st.c0[q]);
        let near_out = mask(tr > 0.0) & mask(4.0 * det > (near * near * m * m + 1e-13 * tr) * tr);
        pass[q] = alive & !near_out;
        any |= alive;
    }
    any
}

/// The first `len` entries of `v` repeated (none if `v` is empty): what `cycle().take(len)`
/// gives, copied a turn at a time (the iterator's per-entry branch cost more than the
/// filter's setup does otherwise).
fn cycled(v: &[f64], len: usize) -> Vec<f64> {
    let mut out = Vec::with_capacity(len);
    while out.len() < len && !v.is_empty() {
        let k = (len - out.len()).min(v.len());
        out.extend_from_slice(&v[..k]);
    }
    out
}

/// A condition as a lane mask: all ones if it holds, else zero.
#[inline(always)]
fn mask(c: bool) -> u64 {
    u64::from(c).wrapping_neg()
}

/// The samples a straight search runs over.
pub(crate) struct Track<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
    /// Closed curve: windows may wrap past the last sample.
    pub periodic: bool,
    /// Velocities at the samples (closed curves), or `None`: monotone by the steps
    /// between positions (branches of full curves).
    pub velocity: Option<(&'a [f64], &'a [f64])>,
}

impl Track<'_> {
    fn len(&self) -> usize {
        self.x.len()
    }

    #[inline]
    fn at(&self, k: usize) -> usize {
        let n = self.len();
        if k < n { k } else { k - n }
    }

    /// The line measures of window `[i, j]` (the contract above), or `None` if a sample
    /// is not finite.
    pub fn measure(&self, i: usize, j: usize) -> Option<LineFit> {
        let mut sums = LineSums::new([self.x[self.at(i)], self.y[self.at(i)]]);
        for k in i..=j {
            let k = self.at(k);
            if !(self.x[k].is_finite() && self.y[k].is_finite()) {
                return None;
            }
            if let Some((vx, vy)) = self.velocity {
                if !(vx[k].is_finite() && vy[k].is_finite()) {
                    return None;
                }
            }
            sums.add(self.x[k], self.y[k]);
        }
        let (g, mut d) = sums.line()?;
        let orient = match self.velocity {
            Some((vx, vy)) => (i..=j)
                .map(|k| vx[self.at(k)] * d[0] + vy[self.at(k)] * d[1])
                .sum(),
            None => {
                let (a, b) = (self.at(i), self.at(j));
                (self.x[b] - self.x[a]) * d[0] + (self.y[b] - self.y[a]) * d[1]
            }
        };
        if orient < 0.0 {
            d = [-d[0], -d[1]];
        }
        let (mut cx0, mut cx1, mut cy0, mut cy1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        let (mut v0, mut v1, mut vs) = (f64::MAX, f64::MIN, 0.0);
        let mut monotone = true;
        let mut prev: Option<[f64; 2]> = None;
        for k in i..=j {
            let k = self.at(k);
            let (px, py) = (self.x[k] - g[0], self.y[k] - g[1]);
            let cx = px * d[0] + py * d[1];
            let cy = py * d[0] - px * d[1];
            cx0 = cx0.min(cx);
            cx1 = cx1.max(cx);
            cy0 = cy0.min(cy);
            cy1 = cy1.max(cy);
            match self.velocity {
                Some((vx, vy)) => {
                    let v = vx[k] * d[0] + vy[k] * d[1];
                    v0 = v0.min(v);
                    v1 = v1.max(v);
                    vs += v;
                }
                None => {
                    let p = [self.x[k], self.y[k]];
                    if let Some(q) = prev {
                        let step = [p[0] - q[0], p[1] - q[1]];
                        if step != [0.0, 0.0] {
                            monotone &= step[0] * d[0] + step[1] * d[1] > 0.0;
                        }
                    }
                    prev = Some(p);
                }
            }
        }
        let (vx_range, mean_vx) = match self.velocity {
            Some(_) => {
                monotone = v0 > 0.0;
                (v1 - v0, vs / (j + 1 - i) as f64)
            }
            None => (0.0, 0.0),
        };
        Some(LineFit {
            d,
            extent: cx1 - cx0,
            width: cy1 - cy0,
            monotone,
            vx_range,
            mean_vx,
        })
    }

    /// The filter of the windows of every start and length (`Sliding`, and the
    /// half-plane test of the directions): marks in `cand` the windows that may qualify.
    /// A start's windows grow one sample at a time until one fails the half-plane test or
    /// the far bound (no longer window can qualify then) or meets a sample that is not
    /// finite. Vectorised across starts: [`BLOCK`] starts at a time grow together, each
    /// lane keeping whether its start is still growing as a lane mask, until none is.
    /// Every lane does the same IEEE-754 operations in the same order as the one-start
    /// loop it replaces, so the same windows pass.
    ///
    /// **Four lanes where the processor has them.** On x86-64 with AVX2 (checked at run
    /// time, once per track) the whole filter is compiled for AVX2 and run instead, the
    /// lanes' step ([`grow`]) inlined into its loop; the same operations in the same
    /// order, so the same windows pass.
    #[allow(clippy::too_many_arguments)]
    fn filter(
        &self,
        angles: &[Option<f64>],
        chord: &[f64],
        far: f64,
        tol: f64,
        travel: &impl Fn(usize, usize) -> f64,
        min_travel: f64,
        cand: &mut Candidates,
    ) {
        #[cfg(target_arch = "x86_64")]
        if crate::has_avx2() {
            // SAFETY: `filter_avx2` needs AVX2, which the processor was just found to
            // have; it has no other requirement (it is the safe `filter_body` compiled
            // for AVX2).
            #[allow(unsafe_code)]
            unsafe {
                self.filter_avx2(angles, chord, far, tol, travel, min_travel, cand)
            };
            return;
        }
        self.filter_body(angles, chord, far, tol, travel, min_travel, cand)
    }

    /// [`Track::filter_body`] compiled for AVX2 (called only where the processor has it).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    fn filter_avx2(
        &self,
        angles: &[Option<f64>],
        chord: &[f64],
        far: f64,
        tol: f64,
        travel: &impl Fn(usize, usize) -> f64,
        min_travel: f64,
        cand: &mut Candidates,
    ) {
        self.filter_body(angles, chord, far, tol, travel, min_travel, cand)
    }

    /// The filter itself ([`Track::filter`]); inlined into each of its two callers so that
    /// each is compiled for its own instruction set.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn filter_body(
        &self,
        angles: &[Option<f64>],
        chord: &[f64],
        far: f64,
        tol: f64,
        travel: &impl Fn(usize, usize) -> f64,
        min_travel: f64,
        cand: &mut Candidates,
    ) {
        let n = self.len();
        // Twice round plus a block, so that every lane reads in bounds; what a lane reads
        // past its last window is masked.
        let len = 2 * n + BLOCK;
        let (x2, y2) = (cycled(self.x, len), cycled(self.y, len));
        let finite: Vec<u64> = x2
            .iter()
            .zip(&y2)
            .map(|(x, y)| mask(x.is_finite() && y.is_finite()))
            .collect();
        // The direction tested at step `l` of a window from `i` is `dir[i + l]`: the
        // velocity at sample `i + l`, or the step from sample `i + l − 1` to `i + l`; NaN
        // where there is none (a zero or non-finite velocity ends a closed curve's window;
        // a step of zero length moves along no line and is ignored).
        let velocity = self.velocity.is_some();
        let angle = |a: &Option<f64>| a.unwrap_or(f64::NAN);
        let angles: Vec<f64> = angles.iter().map(angle).collect();
        let dir: Vec<f64> = if velocity {
            cycled(&angles, len)
        } else {
            let mut dir = Vec::with_capacity(len);
            dir.push(angles.last().copied().unwrap_or(f64::NAN));
            dir.extend_from_slice(&cycled(&angles, len - 1));
            dir
        };
        // The half-plane's reference of a start: its velocity's direction, or the first
        // step direction there is from it on (the first direction the one-start loop adds).
        let mut next = vec![f64::NAN; len + 1];
        for k in (0..len).rev() {
            next[k] = if dir[k].is_nan() { next[k + 1] } else { dir[k] };
        }
        let mut chord2 = chord.to_vec();
        chord2.resize(len, 0.0);
        let last = (n - 1) as f64;
        for b0 in (0..n).step_by(BLOCK) {
            let w = BLOCK.min(n - b0);
            let mut st = Lanes {
                strict: mask(velocity),
                ..Lanes::default()
            };
            for q in 0..BLOCK {
                let i = b0 + q;
                st.x0[q] = x2[i];
                st.y0[q] = y2[i];
                st.c0[q] = chord2[i];
                st.max_l[q] = if self.periodic { last } else { last - i as f64 };
                if q < w {
                    let (r, ok) = if velocity {
                        (dir[i], !dir[i].is_nan())
                    } else {
                        (next[i + 1], true)
                    };
                    st.reference[q] = r;
                    st.alive[q] = finite[i] & mask(ok);
                }
            }
            let mut pass = [0u64; BLOCK];
            for l in 1..n {
                let r = b0 + l..b0 + l + BLOCK;
                let any = grow(
                    &mut st,
                    l,
                    far,
                    tol,
                    Inputs {
                        x: x2[r.clone()].try_into().expect("block"),
                        y: y2[r.clone()].try_into().expect("block"),
                        finite: finite[r.clone()].try_into().expect("block"),
                        dir: dir[r.clone()].try_into().expect("block"),
                        chord: chord2[r].try_into().expect("block"),
                    },
                    &mut pass,
                );
                if any == 0 {
                    break;
                }
                if l >= 2 {
                    let row = &mut cand.row_mut(l)[b0..b0 + w];
                    for (q, flag) in row.iter_mut().enumerate() {
                        *flag = pass[q] != 0 && travel(b0 + q, b0 + q + l) >= min_travel;
                    }
                }
            }
        }
    }

    /// The filter's inputs: each sample's direction (one `atan2`; `None` where the
    /// direction is zero or not finite), the polyline's length as prefix sums over two
    /// turns, and the bound `far` on a qualifying window's spread (1.01 `tol` times the
    /// diameter of all finite samples).
    fn filter_inputs(&self, tol: f64) -> (Vec<Option<f64>>, Vec<f64>, f64) {
        let n = self.len();
        // Directions whose half-plane test is exact and cheap: one atan2 per sample.
        let angles: Vec<Option<f64>> = (0..n)
            .map(|k| {
                let v = match self.velocity {
                    Some((vx, vy)) => [vx[k], vy[k]],
                    None => {
                        let q = if k + 1 < n {
                            k + 1
                        } else if self.periodic {
                            0
                        } else {
                            k
                        };
                        [self.x[q] - self.x[k], self.y[q] - self.y[k]]
                    }
                };
                let zero = v == [0.0, 0.0];
                (!zero && v[0].is_finite() && v[1].is_finite()).then(|| libm::atan2(v[1], v[0]))
            })
            .collect();
        // Polyline length, prefix sums over two turns. `sqrt(dx² + dy²)`, not `hypot`:
        // the length only bounds the filter below (1 % slack), and `hypot`'s guard
        // against overflow and underflow of the squares is not needed: the samples are
        // finite coupler positions (|x|, |y| far below 1e150, so dx² cannot overflow), and
        // a step below 1e-154, whose square underflows, is shorter than the slack by
        // hundreds of orders of magnitude. Non-finite samples never reach the bound (their
        // windows are cut first). The `sqrt` form may differ from `hypot` in the last
        // bit, which the slack absorbs; no reported number uses it.
        let mut chord = vec![0.0; 2 * n];
        for k in 1..2 * n {
            let b = if k < n { k } else { k - n };
            let a = if b > 0 { b - 1 } else { n - 1 };
            let (dx, dy) = (self.x[b] - self.x[a], self.y[b] - self.y[a]);
            chord[k] = chord[k - 1] + (dx * dx + dy * dy).sqrt();
        }
        // Any window's extent is at most the diameter of all samples: a window whose
        // spread already exceeds `tol` times that cannot qualify, nor can any window
        // containing it (its spread across any line is at least as large).
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for (&x, &y) in self.x.iter().zip(self.y) {
            if x.is_finite() && y.is_finite() {
                (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
            }
        }
        (angles, chord, 1.01 * tol * (x1 - x0).hypot(y1 - y0))
    }

    /// The maximal windows with `ε_S ≤ tol` that move one way along their line, travel at
    /// least `min_travel` (`travel(i, j)`, at most `h_max` per step), at most `max_picks`
    /// of them ([`crate::maximal`]). Error: ε_S.
    pub fn maximal(
        &self,
        tol: f64,
        travel: impl Fn(usize, usize) -> f64,
        h_max: f64,
        min_travel: f64,
        max_picks: usize,
    ) -> Vec<Window> {
        let n = self.len();
        if n < 3 {
            return Vec::new();
        }
        let (angles, chord, far) = self.filter_inputs(tol);
        let mut cand = Candidates::new(n, self.periodic);
        self.filter(&angles, &chord, far, tol, &travel, min_travel, &mut cand);
        cand.pick(travel, h_max, min_travel, max_picks, |i, j| {
            let f = self.measure(i, j)?;
            (f.monotone && f.extent > 0.0 && f.width <= tol * f.extent).then(|| f.width / f.extent)
        })
    }
}

/// The straight segments of a closed curve sampled every `tol.step_deg` from θ = 0: the
/// maximal windows (`docs/features.md`, "Maximal windows: the contract") with
/// ε_S ≤ `straight_pct`, moving one way along their fitted line (every Vx > 0) and
/// spanning at least `straight_min_span_deg`. Windows never include an invalid sample.
pub fn straight_segments(
    c: &Curve,
    tol: &FeatureTolerances,
    dash: &DashPattern,
) -> Vec<StraightSegment> {
    let n = c.len();
    if n < 4 {
        return Vec::new();
    }
    let track = Track {
        x: &c.x,
        y: &c.y,
        periodic: true,
        velocity: Some((&c.vx, &c.vy)),
    };
    let min_steps = (tol.straight_min_span_deg / tol.step_deg - 1e-9)
        .ceil()
        .max(2.0);
    track
        .maximal(
            tol.straight_pct / 100.0,
            |i, j| (j - i) as f64,
            1.0,
            min_steps,
            usize::MAX,
        )
        .into_iter()
        .filter_map(|w| {
            let (i, j) = (w.start, w.end);
            let l = track.measure(i, j)?;
            let (a, b) = (i % n, j % n);
            let span = (j - i) as f64 * tol.step_deg;
            let seg = StraightSegment {
                start_deg: i as f64 * tol.step_deg,
                span_deg: span,
                dashes: dash_count(span, dash),
                length: l.extent,
                straightness_pct: l.width / l.extent * 100.0,
                velocity_variation_pct: l.vx_range / l.mean_vx * 100.0,
                direction_deg: crate::angle_deg(l.d),
                endpoints: [[c.x[a], c.y[a]], [c.x[b], c.y[b]]],
                // Filled by the extractor, which knows the mechanism.
                transmission_deg: None,
            };
            [
                seg.length,
                seg.straightness_pct,
                seg.velocity_variation_pct,
                seg.direction_deg,
            ]
            .iter()
            .all(|x| x.is_finite())
            .then_some(seg)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::maximal::HalfPlane;
    use coupler_kinematics::{Circuit, CouplerPoint, CrankTable, FourBar, Mechanism};

    impl Track<'_> {
        /// The one-start filter the lanes replace: each start's windows grown one sample
        /// at a time, with `Sliding` and `HalfPlane`, until one cannot qualify.
        fn filter_one_by_one(
            &self,
            angles: &[Option<f64>],
            chord: &[f64],
            far: f64,
            tol: f64,
            travel: impl Fn(usize, usize) -> f64,
            min_travel: f64,
        ) -> Candidates {
            let n = self.len();
            let mut cand = Candidates::new(n, self.periodic);
            for i in 0..n {
                let (x0, y0) = (self.x[i], self.y[i]);
                if !(x0.is_finite() && y0.is_finite()) {
                    continue;
                }
                let mut sums = Sliding::new(x0, y0);
                let mut half = HalfPlane::new();
                if self.velocity.is_some() {
                    match angles[i] {
                        Some(a) => {
                            half.add(a);
                        }
                        None => continue,
                    }
                }
                for l in 1..=cand.max_steps(i) {
                    let k = self.at(i + l);
                    let (x, y) = (self.x[k], self.y[k]);
                    if !(x.is_finite() && y.is_finite()) {
                        break;
                    }
                    sums.add(x, y);
                    let direction = match self.velocity {
                        Some(_) => angles[self.at(i + l)],
                        None => angles[self.at(i + l - 1)],
                    };
                    match direction {
                        Some(a) if !half.add(a) => break,
                        Some(_) => {}
                        None if self.velocity.is_some() => break,
                        None => {}
                    }
                    if sums.spread_exceeds(far) {
                        break;
                    }
                    let near = 1.01 * tol * (chord[i + l] - chord[i]);
                    if l >= 2 && travel(i, i + l) >= min_travel && !sums.spread_exceeds(near) {
                        cand.set(i, l);
                    }
                }
            }
            cand
        }
    }

    /// A zigzag between two parallel lines `2h` apart, one unit along them per step:
    /// its samples sit at the two extremes across the line, so the filter's lower bound
    /// on the spread is tight, and the windows of about `2h/tol` steps are right at the
    /// tolerance. Velocities along the lines.
    fn zigzag(n: usize, h: f64, turn: f64) -> Curve {
        let mut c = Curve::default();
        let (s, co) = (libm::sin(turn), libm::cos(turn));
        for k in 0..n {
            let (u, v) = (k as f64, if k % 2 == 0 { h } else { -h });
            c.x.push(3.0 + u * co - v * s);
            c.y.push(-1.0 + u * s + v * co);
            c.vx.push(co);
            c.vy.push(s);
        }
        c
    }

    /// Closed curves with straight stretches (four-bar curves, among them near-straight
    /// ones, a flat ellipse, zigzags at the tolerance), some with a cusp (zero velocity),
    /// repeated samples (steps of zero length) or a sample that is not finite.
    fn curves() -> Vec<(String, Curve)> {
        let mut out = Vec::new();
        let table = CrankTable::new(4.0).unwrap();
        for (a, b, c) in [
            (2.5, 2.5, 2.0),
            (3.0, 2.5, 3.5),
            (2.0, 2.5, 2.0),
            (4.0, 3.0, 5.0),
        ] {
            let l = FourBar::new(a, b, c).unwrap();
            let poses = l.pose_table(Circuit::Open, &table);
            for (u, v) in [(1.0, 0.0), (2.5, 0.0), (1.25, 2.5), (-1.0, 1.5), (5.0, 0.0)] {
                out.push((
                    format!("four-bar {a},{b},{c} ({u},{v})"),
                    poses.trace(CouplerPoint::new(u, v)),
                ));
            }
        }
        let mut ellipse = Curve::default();
        for k in 0..90 {
            let t = (4.0 * k as f64).to_radians();
            let (s, c) = (libm::sin(t), libm::cos(t));
            ellipse.x.push(40.0 * c);
            ellipse.y.push(s);
            ellipse.vx.push(-40.0 * s);
            ellipse.vy.push(c);
        }
        out.push(("ellipse 40:1".into(), ellipse));
        for (h, turn) in [(0.05, 0.0), (0.05, 0.7), (0.0301, 2.0), (0.1, -1.0)] {
            out.push((format!("zigzag h={h} turn {turn}"), zigzag(60, h, turn)));
        }
        // Defects: a cusp (zero velocity), a repeated sample, a sample that is not finite.
        let mut z = zigzag(60, 0.05, 0.3);
        (z.vx[17], z.vy[17]) = (0.0, 0.0);
        (z.x[31], z.y[31]) = (z.x[30], z.y[30]);
        z.x[45] = f64::NAN;
        out.push(("zigzag with defects".into(), z));
        out
    }

    /// The tracks of the curves: closed with velocities (straight segments), and open
    /// without (the classics' branches: positions only), whole and cut short.
    fn tracks(c: &Curve) -> Vec<(&'static str, Track<'_>)> {
        let n = c.len();
        vec![
            (
                "closed",
                Track {
                    x: &c.x,
                    y: &c.y,
                    periodic: true,
                    velocity: Some((&c.vx, &c.vy)),
                },
            ),
            (
                "open",
                Track {
                    x: &c.x,
                    y: &c.y,
                    periodic: false,
                    velocity: None,
                },
            ),
            (
                "open, cut",
                Track {
                    x: &c.x[n / 3..],
                    y: &c.y[n / 3..],
                    periodic: false,
                    velocity: None,
                },
            ),
        ]
    }

    /// Every window of every start and length that the exact test accepts (finite,
    /// moving one way along its line, ε_S ≤ tol, at least 2 steps) passes the filter,
    /// and the filter passes exactly the windows the one-start loop it replaces passes.
    /// The zigzags put windows right at the tolerance where the filter's bound is tight:
    /// with the near bound's slack cut from 1.01 to 0.9, windows of the zigzags that
    /// qualify are rejected.
    #[test]
    fn filter_passes_every_qualifying_window() {
        let (mut qualifying, mut passing) = (0, 0);
        for (name, c) in curves() {
            for (kind, t) in tracks(&c) {
                let n = t.len();
                for tol in [0.002, 0.01, 0.05] {
                    let (angles, chord, far) = t.filter_inputs(tol);
                    let travel = |i: usize, j: usize| (j - i) as f64;
                    let mut cand = Candidates::new(n, t.periodic);
                    t.filter(&angles, &chord, far, tol, &travel, 2.0, &mut cand);
                    let one = t.filter_one_by_one(&angles, &chord, far, tol, travel, 2.0);
                    for i in 0..n {
                        for l in 2..=cand.max_steps(i) {
                            let what = format!("{name}, {kind}, tol {tol}: window {i}+{l}");
                            assert_eq!(cand.passes(i, l), one.passes(i, l), "{what}");
                            passing += usize::from(cand.passes(i, l));
                            let exact = t.measure(i, i + l).filter(|f| {
                                f.monotone && f.extent > 0.0 && f.width <= tol * f.extent
                            });
                            if exact.is_some() {
                                qualifying += 1;
                                assert!(cand.passes(i, l), "{what} qualifies but is rejected");
                            }
                        }
                    }
                }
            }
        }
        assert!(qualifying > 1000, "{qualifying} qualifying windows");
        assert!(passing > qualifying, "{passing} passing windows");
    }
}
