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
use crate::maximal::{Candidates, HalfPlane, Window};
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

    /// The direction (angle) whose half-plane test applies at step `l` of a window from
    /// `i`: the velocity at sample `i + l`, or the step from sample `i + l − 1` to `i + l`
    /// (`None` for a step of zero length, which moves along no line and is ignored).
    fn direction(&self, angles: &[Option<f64>], i: usize, l: usize) -> Option<f64> {
        match self.velocity {
            Some(_) => angles[self.at(i + l)],
            None => angles[self.at(i + l - 1)],
        }
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
            let (a, b) = ((k - 1) % n, k % n);
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
        let diameter = (x1 - x0).hypot(y1 - y0);
        let far = 1.01 * tol * diameter;
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
                    None => continue, // a zero or infinite velocity never moves one way
                }
            }
            for l in 1..=cand.max_steps(i) {
                let k = self.at(i + l);
                let (x, y) = (self.x[k], self.y[k]);
                if !(x.is_finite() && y.is_finite()) {
                    break;
                }
                sums.add(x, y);
                match self.direction(&angles, i, l) {
                    // No extension moves one way either.
                    Some(a) if !half.add(a) => break,
                    Some(_) => {}
                    None if self.velocity.is_some() => break,
                    None => {}
                }
                // (1 % slack on the bounds, and more than the rounding of the sums: a
                // filter must never reject a qualifying window.)
                if sums.spread_exceeds(far) {
                    break;
                }
                let near = 1.01 * tol * (chord[i + l] - chord[i]);
                if l >= 2 && travel(i, i + l) >= min_travel && !sums.spread_exceeds(near) {
                    cand.set(i, l);
                }
            }
        }
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
