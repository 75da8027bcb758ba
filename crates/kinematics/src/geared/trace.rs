//! The complete coupler curve of a geared five-bar driven by its input across toggles
//! (the five-bar's counterpart of [`crate::trace_full`]): the same [`FullCurve`], so the
//! `curve --trace full` output and everything reading it serve both mechanisms.

use super::linkage::GearedFiveBar;
use super::margin::MARGIN_STEP_DEG;
use super::pose::{GearedGaps, GearedPose, factors};
use crate::linkage::{Circuit, CouplerPoint};
use crate::trace::{
    Branch, FullCurve, InputRange, Toggle, ToggleKind, TraceSample, grid_inside, toggle_sample,
};
use nalgebra::Vector2;

impl GearedFiveBar {
    /// Where the input can go, over one period ([`GearedFiveBar::input_intervals`] at
    /// [`MARGIN_STEP_DEG`]): `Full` if the dyad closes at every sampled input angle, each
    /// toggle otherwise, with the kind of flat triangle there (`Extended`: L3 and L4 in
    /// line, `P = 0`; `Folded`: `Q = 0`). A range narrower than the step can be missed.
    pub fn input_range(&self) -> InputRange {
        let intervals = self.input_intervals(MARGIN_STEP_DEG);
        if intervals.is_empty() {
            return InputRange::Never;
        }
        if intervals == [(0.0, self.period_deg())] {
            return InputRange::Full;
        }
        let gaps = GearedGaps::of(self);
        let toggle = |degrees: f64| {
            let f = factors(self, &gaps, &self.angle_at(degrees));
            let kind = if f.p.abs() / f.p_scale <= f.q.abs() / f.q_scale {
                ToggleKind::Extended
            } else {
                ToggleKind::Folded
            };
            Toggle { degrees, kind }
        };
        InputRange::Rocks {
            intervals: intervals
                .into_iter()
                .map(|(lo, hi)| (toggle(lo), toggle(hi)))
                .collect(),
        }
    }

    fn trace_sample(
        &self,
        gaps: &GearedGaps,
        circuit: Circuit,
        p: CouplerPoint,
        deg: f64,
        toggle: bool,
    ) -> Option<TraceSample> {
        let angle = self.angle_at(deg);
        let pose = GearedPose::solve_with(self, gaps, circuit, &angle)?;
        if toggle {
            // The flat pose, shared by both circuits (the margin at the refined angle is
            // ≥ 0 but may be a few ulps above zero).
            let other = GearedPose::solve_with(self, gaps, circuit.other(), &angle)?;
            return Some(toggle_sample(
                deg,
                circuit,
                p,
                pose.input_pin,
                [pose.link3_dir, other.link3_dir],
                pose.transmission,
            ));
        }
        Some(TraceSample {
            degrees: deg,
            circuit,
            point: pose.point(p),
            velocity: pose
                .velocity(p)
                .unwrap_or(Vector2::new(f64::INFINITY, f64::INFINITY)),
            transmission: pose.transmission,
            toggle,
        })
    }

    /// The complete coupler curve of `point`, sampling the input at the multiples of
    /// `step_deg` inside its range ([`GearedFiveBar::input_range`]) plus every toggle. An
    /// input that turns fully gives one closed branch per circuit over one period
    /// (`0 ≤ θ2 < 360°·q`, closed by repeating θ2 = 0 as θ2 = period); a rocking input
    /// gives, per interval, the branch from the lower toggle to the upper one on the open
    /// circuit and back on the crossed one, closing exactly (first and last samples
    /// equal). Where an ordinary sample meets a toggle (a Class III change point on the
    /// path) its velocity is infinite (printed as null). `step_deg` must be positive and
    /// finite (else no branch).
    ///
    /// ```
    /// use coupler_kinematics::{CouplerPoint, GearRatio, GearedFiveBar, InputRange};
    /// let g = GearedFiveBar::new(2.5, 2.0, 2.0, 1.0, GearRatio::integer(1).unwrap(), 180.0).unwrap();
    /// let full = g.trace_full(CouplerPoint::new(1.0, 0.5), 1.0);
    /// assert!(matches!(full.range, InputRange::Rocks { .. }));
    /// let b = &full.branches[0];
    /// assert_eq!(b.samples.first().unwrap().point, b.samples.last().unwrap().point);
    /// ```
    pub fn trace_full(&self, p: CouplerPoint, step_deg: f64) -> FullCurve {
        let range = self.input_range();
        let gaps = GearedGaps::of(self);
        let mut branches = Vec::new();
        if !(step_deg.is_finite() && step_deg > 0.0) {
            return FullCurve { range, branches };
        }
        let sample = |c, d, toggle| self.trace_sample(&gaps, c, p, d, toggle);
        match &range {
            InputRange::Never => {}
            InputRange::Full => {
                let period = self.period_deg();
                for c in [Circuit::Open, Circuit::Crossed] {
                    let mut angles = vec![0.0];
                    angles.extend(grid_inside(0.0, period, step_deg));
                    angles.push(period);
                    let samples = angles.iter().filter_map(|&d| sample(c, d, false)).collect();
                    branches.push(Branch { samples });
                }
            }
            InputRange::Rocks { intervals } => {
                let (open, crossed) = (Circuit::Open, Circuit::Crossed);
                for (lo, hi) in intervals {
                    let inside = grid_inside(lo.degrees, hi.degrees, step_deg);
                    let mut samples = Vec::with_capacity(2 * inside.len() + 3);
                    samples.extend(sample(crossed, lo.degrees, true));
                    samples.extend(inside.iter().filter_map(|&d| sample(open, d, false)));
                    samples.extend(sample(open, hi.degrees, true));
                    samples.extend(
                        inside
                            .iter()
                            .rev()
                            .filter_map(|&d| sample(crossed, d, false)),
                    );
                    samples.extend(sample(crossed, lo.degrees, true));
                    branches.push(Branch { samples });
                }
            }
        }
        FullCurve { range, branches }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geared::GearRatio;

    #[test]
    fn rocking_branches_close_and_stay_on_the_linkage() {
        // λ = 2, φ = 180°: two ranges per period (margin.rs works the numbers).
        let g =
            GearedFiveBar::new(2.5, 1.6, 1.8, 1.0, GearRatio::integer(2).unwrap(), 180.0).unwrap();
        let p = CouplerPoint::new(0.8, 0.6);
        let full = g.trace_full(p, 2.0);
        let InputRange::Rocks { intervals } = &full.range else {
            panic!("{:?}", full.range)
        };
        assert_eq!(intervals.len(), 2);
        assert_eq!(full.branches.len(), 2);
        for b in &full.branches {
            let (first, last) = (b.samples[0], *b.samples.last().unwrap());
            assert!(first.toggle && last.toggle);
            assert_eq!(first.point, last.point);
            // Consecutive samples are close: no jump between circuits.
            for w in b.samples.windows(2) {
                assert!((w[1].point - w[0].point).norm() < 0.25, "{w:?}");
            }
            // Out on the open circuit, back on the crossed one.
            assert!(b.samples.iter().any(|s| s.circuit == Circuit::Open));
            assert!(b.samples.iter().any(|s| s.circuit == Circuit::Crossed));
        }
    }

    #[test]
    fn full_turn_gives_a_branch_per_circuit_over_the_period() {
        let g =
            GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::new(-1, 2).unwrap(), 0.0).unwrap();
        let full = g.trace_full(CouplerPoint::new(1.0, 1.0), 10.0);
        assert_eq!(full.range, InputRange::Full);
        assert_eq!(full.branches.len(), 2);
        for b in &full.branches {
            assert_eq!(b.samples.len(), 73); // 0°, 10°, …, 720°
            let (first, last) = (b.samples[0].point, b.samples[72].point);
            assert!((first - last).norm() < 1e-14);
        }
        let never =
            GearedFiveBar::new(10.0, 1.0, 1.0, 1.0, GearRatio::integer(1).unwrap(), 0.0).unwrap();
        assert_eq!(
            never.trace_full(CouplerPoint::new(1.0, 0.0), 1.0).range,
            InputRange::Never
        );
    }
}
