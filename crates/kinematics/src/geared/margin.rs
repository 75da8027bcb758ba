//! Whether a geared five-bar's input turns fully: the dyad's assembly margin over the
//! period.

use super::angle::GearAngle;
use super::linkage::GearedFiveBar;
use super::pose::{GearedGaps, factors};

/// The default sampling step of [`GearedFiveBar::assembly_margin`] (degrees of input)
/// before each local minimum is refined.
pub const MARGIN_STEP_DEG: f64 = 0.5;

/// The default tolerance of [`GearedFiveBar::rotatability`], relative to the longest link:
/// a margin within it is a touch (a toggle or change point on the path), not a clearance.
pub const MARGIN_TOL: f64 = 1e-9;

/// The smallest assembly margin of the dyad over one period of the input.
///
/// At input angle θ2 the dyad closes iff `|L3 − L4| ≤ d ≤ L3 + L4`. The margin is the
/// distance to the nearer bound, `m(θ2) = min(L3 + L4 − d, d − |L3 − L4|)`, computed from
/// the thin factors without cancellation (`P/(L3 + L4 + d)` and `Q/(d + |L3 − L4|)`):
/// positive where it assembles strictly, zero at a toggle, negative where it cannot close.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AssemblyMargin {
    /// The minimum of m over the period (length units).
    pub min: f64,
    /// The input angle θ2 (degrees, in [0, period)) where it is reached.
    pub at_degrees: f64,
}

/// What a geared five-bar's input can do with its gears (λ, φ).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rotatability {
    /// The input turns fully and never meets a toggle (margin > tolerance).
    Full,
    /// The input turns fully but the path touches a toggle (margin within tolerance of
    /// zero): a change point or a grazing toggle, where the circuits meet.
    Touches,
    /// There are input angles where the dyad cannot close: the input rocks between toggles.
    Limited,
}

impl GearedFiveBar {
    /// The dyad's margin at one input angle (see [`AssemblyMargin`]).
    pub fn margin_at(&self, gaps: &GearedGaps, theta2: f64) -> f64 {
        let a = GearAngle::new(self.ratio, self.phase, theta2);
        let f = factors(self, gaps, &a);
        let d = f.wx.hypot(f.wy);
        let outer = f.p / (self.l3 + self.l4 + d);
        let spread = (self.l3 - self.l4).abs();
        let inner = if d + spread > 0.0 {
            f.q / (d + spread)
        } else {
            0.0
        };
        outer.min(inner)
    }

    /// The margin at `n ≥ 3` evenly spaced input angles `k·h` over one period, `h` at most
    /// `step_deg` ([`MARGIN_STEP_DEG`] if that is not a positive number).
    fn sampled_margins(&self, step_deg: f64) -> (GearedGaps, f64, Vec<f64>) {
        let gaps = GearedGaps::of(self);
        let period = self.period_deg();
        let step = if step_deg.is_finite() && step_deg > 0.0 {
            step_deg.min(period)
        } else {
            MARGIN_STEP_DEG
        };
        let n = ((period / step).ceil() as usize).max(3);
        let h = period / n as f64;
        let m = (0..n)
            .map(|k| self.margin_at(&gaps, k as f64 * h))
            .collect();
        (gaps, h, m)
    }

    /// The minimum of the assembly margin over one period (`360°·q` of input), found by
    /// sampling every `step_deg` and refining each sampled local minimum by golden-section
    /// search to ~1e-10°. A numerical check: a dip narrower than the step between two
    /// samples that both clear it can be missed (the margin is Lipschitz with constant
    /// `1 + |λ|·L5`, so a sampled minimum above `(1 + |λ|·L5)·step·π/360` cannot hide a
    /// toggle). `step_deg` must be positive ([`MARGIN_STEP_DEG`] is the default).
    ///
    /// ```
    /// use coupler_kinematics::{GearRatio, GearedFiveBar};
    /// // λ = −1, φ = 180°, L5 = 1, L3 = L4 = 3.5 on L1 = 3: d = |3 − 2 cos θ2| ∈ [1, 5],
    /// // so the margin is min(7 − d, d − 0), smallest (1) at θ2 = 0.
    /// let g = GearedFiveBar::new(3.0, 3.5, 3.5, 1.0, GearRatio::integer(-1).unwrap(), 180.0).unwrap();
    /// let m = g.assembly_margin(0.5);
    /// assert!((m.min - 1.0).abs() < 1e-12);
    /// assert!(m.at_degrees.min(360.0 - m.at_degrees) < 1e-6);
    /// ```
    pub fn assembly_margin(&self, step_deg: f64) -> AssemblyMargin {
        let (gaps, h, m) = self.sampled_margins(step_deg);
        let (n, period) = (m.len(), self.period_deg());
        let mut best = AssemblyMargin {
            min: f64::INFINITY,
            at_degrees: 0.0,
        };
        for k in 0..n {
            let (prev, next) = (m[(k + n - 1) % n], m[(k + 1) % n]);
            if m[k] <= prev && m[k] <= next {
                let (t, v) = golden_min(
                    |t| self.margin_at(&gaps, t),
                    (k as f64 - 1.0) * h,
                    (k as f64 + 1.0) * h,
                );
                let v = v.min(m[k]);
                if v < best.min {
                    let t = if v == m[k] { k as f64 * h } else { t };
                    best = AssemblyMargin {
                        min: v,
                        at_degrees: t.rem_euclid(period),
                    };
                }
            }
        }
        best
    }

    /// Whether the input turns fully with these gears, from [`Self::assembly_margin`] at
    /// [`MARGIN_STEP_DEG`] and the tolerance `tol` relative to the longest link
    /// ([`MARGIN_TOL`] is the default). For linkages where
    /// [`GearedFiveBar::turns_for_any_gearing`] holds, this is [`Rotatability::Full`]
    /// whatever the gears.
    pub fn rotatability(&self, tol: f64) -> Rotatability {
        let scale = self.lengths().into_iter().fold(0.0, f64::max);
        let m = self.assembly_margin(MARGIN_STEP_DEG).min;
        if m > tol * scale {
            Rotatability::Full
        } else if m >= -tol * scale {
            Rotatability::Touches
        } else {
            Rotatability::Limited
        }
    }
}

impl GearedFiveBar {
    /// The input ranges where the dyad assembles, as `(start, end)` degrees with
    /// `0 ≤ start < period` and `start < end ≤ start + period` (an interval that runs
    /// through 0° keeps going past the period), each end a toggle refined by bisection on
    /// the margin to ~1e-12°. Empty if the dyad never closes; one interval `(0, period)`
    /// if it always does. Found by sampling the margin every `step_deg` (a range narrower
    /// than a step can be missed, as in [`Self::assembly_margin`]). At an end both circuits
    /// meet: tracing a rocking input's whole curve goes out on one circuit and back on the
    /// other, as the four-bar's full trace does.
    ///
    /// ```
    /// use coupler_kinematics::{GearRatio, GearedFiveBar};
    /// // λ = 1, φ = 180°: d = |L1 − 2·e^{iθ2}| ≤ L3 + L4 = 4 iff cos θ2 ≥ (L1² − 12)/(4·L1).
    /// let g = GearedFiveBar::new(2.5, 2.0, 2.0, 1.0, GearRatio::integer(1).unwrap(), 180.0).unwrap();
    /// let r = g.input_intervals(1.0);
    /// let t = (-5.75f64 / 10.0).acos().to_degrees();
    /// assert_eq!(r.len(), 1);
    /// assert!((r[0].0 - (360.0 - t)).abs() < 1e-9 && (r[0].1 - (360.0 + t)).abs() < 1e-9);
    /// ```
    pub fn input_intervals(&self, step_deg: f64) -> Vec<(f64, f64)> {
        let (gaps, h, m) = self.sampled_margins(step_deg);
        let (n, period) = (m.len(), self.period_deg());
        let ok: Vec<bool> = m.iter().map(|&x| x >= 0.0).collect();
        if ok.iter().all(|&b| b) {
            return vec![(0.0, period)];
        }
        // The toggle between samples k and k + 1 (one assembles, the other not).
        let edge = |k: usize| {
            let (mut a, mut b) = (k as f64 * h, (k + 1) as f64 * h);
            let inside_a = ok[k];
            for _ in 0..60 {
                let mid = 0.5 * (a + b);
                if (self.margin_at(&gaps, mid) >= 0.0) == inside_a {
                    a = mid;
                } else {
                    b = mid;
                }
            }
            if inside_a { a } else { b }
        };
        let mut intervals = Vec::new();
        // Start at a sample that does not assemble and walk once around the period.
        let first_out = ok.iter().position(|&b| !b).unwrap_or(0);
        let mut start = None;
        for j in 0..n {
            let k = (first_out + j) % n;

            let next = (k + 1) % n;
            match (ok[k], ok[next]) {
                (false, true) => start = Some(edge(k)),
                (true, false) => {
                    if let Some(s) = start.take() {
                        let s = s.rem_euclid(period);
                        let mut e = edge(k);
                        while e <= s {
                            e += period;
                        }
                        intervals.push((s, e));
                    }
                }
                _ => {}
            }
        }
        intervals.sort_by(|a, b| a.0.total_cmp(&b.0));
        intervals
    }
}

/// Golden-section search for the minimum of `f` on `[a, b]`, to ~1e-10 of the bracket
/// (the margin is continuous; where it has a kink, the bracket still shrinks onto it).
pub(crate) fn golden_min(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> (f64, f64) {
    const R: f64 = 0.618_033_988_749_894_8;
    let (mut c, mut d) = (b - R * (b - a), a + R * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..60 {
        if fc < fd {
            b = d;
            (d, fd) = (c, fc);
            c = b - R * (b - a);
            fc = f(c);
        } else {
            a = c;
            (c, fc) = (d, fd);
            d = a + R * (b - a);
            fd = f(d);
        }
    }
    if fc < fd { (c, fc) } else { (d, fd) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geared::GearRatio;
    use crate::geared::GearedGaps;

    #[test]
    fn any_gearing_linkages_turn_fully_with_any_gears() {
        for (n, d) in [(1, 1), (-1, 1), (2, 1), (-2, 1), (-1, 2), (3, 2)] {
            for phase in [0.0, 45.0, 180.0, 271.0] {
                let g =
                    GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::new(n, d).unwrap(), phase)
                        .unwrap();
                assert!(g.turns_for_any_gearing());
                assert_eq!(g.rotatability(MARGIN_TOL), Rotatability::Full, "{g}");
            }
        }
    }

    #[test]
    fn gears_decide_class_two() {
        // Class II (sorted 1, 1, 2, 2, 2.5: 4.5 > 4). With λ = 1, φ = 0 the cranks stay
        // parallel: d = |(L1 + (L5 − 1)·e^{iθ})| = 2.5 exactly, inside [0, 4].
        let l = |n, phase| {
            GearedFiveBar::new(2.5, 2.0, 2.0, 1.0, GearRatio::integer(n).unwrap(), phase).unwrap()
        };
        assert_eq!(l(1, 0.0).ting_class(), crate::geared::TingClass::II);
        let m = l(1, 0.0).assembly_margin(MARGIN_STEP_DEG);
        assert!((m.min - 1.5).abs() < 1e-14, "{m:?}");
        assert_eq!(l(1, 0.0).rotatability(MARGIN_TOL), Rotatability::Full);
        // λ = 1, φ = 180°: d = |L1 − 2·e^{iθ}| reaches 4.5 > 4 at θ2 = 180°.
        let m = l(1, 180.0).assembly_margin(MARGIN_STEP_DEG);
        assert!((m.min + 0.5).abs() < 1e-12 && (m.at_degrees - 180.0).abs() < 1e-6);
        assert_eq!(l(1, 180.0).rotatability(MARGIN_TOL), Rotatability::Limited);
    }

    #[test]
    fn intervals_of_a_linkage_that_rocks_twice_per_period() {
        // λ = 2, φ = 180°, L1 = 2.5, L5 = 1: w = L1 − e^{2iθ2} − e^{iθ2} reaches
        // |w|² = (L1 + L5)² + 1 = 13.25 at θ2 = 90° and 270°, beyond (L3 + L4)² = 11.56;
        // elsewhere |w| ≥ 0.5 > |L3 − L4|: two ranges per period, each toggle to toggle.
        let g =
            GearedFiveBar::new(2.5, 1.6, 1.8, 1.0, GearRatio::integer(2).unwrap(), 180.0).unwrap();
        let gaps = GearedGaps::of(&g);
        let r = g.input_intervals(0.5);
        assert!(!r.is_empty());
        for &(s, e) in &r {
            assert!((0.0..360.0).contains(&s) && e > s && e <= s + 360.0);
            for k in 1..100 {
                let t = s + (e - s) * k as f64 / 100.0;
                assert!(g.margin_at(&gaps, t) >= 0.0, "{t}");
            }
            for t in [s, e] {
                assert!(g.margin_at(&gaps, t).abs() < 1e-12, "{t}");
            }
        }
        assert_eq!(r.len(), 2, "{r:?}");
        // Mirror-symmetric about 180° and 360° (the ground line): one range through 180°,
        // one through 0°, which wraps past the period.
        assert!((r[0].0 + r[0].1 - 360.0).abs() < 1e-9, "{r:?}");
        assert!((r[1].0 + r[1].1 - 720.0).abs() < 1e-9, "{r:?}");
        assert!(r[0].0 > 90.0 && r[0].1 < 270.0 && r[1].0 > 270.0 && r[1].1 < 450.0);
        let full =
            GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::integer(2).unwrap(), 0.0).unwrap();
        assert_eq!(full.input_intervals(0.5), vec![(0.0, 360.0)]);
    }

    #[test]
    fn class_three_through_its_change_point_touches() {
        // Sorted 1, 1, 2.1, 2.4, 2.5: 1 + 1 + 2.5 = 2.1 + 2.4. λ = −1, φ = 180°: at
        // θ2 = 180° the chain lies flat with d = L1 + 1 + L5 = 4.5 = L3 + L4 (and d ≥ 0.5 >
        // |L3 − L4| elsewhere).
        let g =
            GearedFiveBar::new(2.5, 2.1, 2.4, 1.0, GearRatio::integer(-1).unwrap(), 180.0).unwrap();
        assert_eq!(g.ting_class(), crate::geared::TingClass::III);
        let m = g.assembly_margin(MARGIN_STEP_DEG);
        assert!(
            m.min.abs() < 1e-15 && (m.at_degrees - 180.0).abs() < 1e-6,
            "{m:?}"
        );
        assert_eq!(g.rotatability(MARGIN_TOL), Rotatability::Touches);
    }
}
