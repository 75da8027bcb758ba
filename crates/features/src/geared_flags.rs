//! The curve flags and error bound of a geared five-bar's curves (the five-bar's
//! counterparts of [`CurveFlags::assess`] and [`CurveFlags::for_full_turn`]): the same
//! flags with the same meaning, Ting's Class III in place of Barker's change points.

use crate::flags::{CurveFlag, CurveFlags, FlagTolerances};
use coupler_kinematics::{
    Circuit, CouplerPoint, GearedFiveBar, GearedGaps, GearedPose, MARGIN_TOL, Rotatability,
    TingClass,
};

impl CurveFlags {
    /// Assesses a curve of the geared five-bar `linkage`, `circuit`, `point` sampled at
    /// the input angles `degrees`: `change_point` for Ting's Class III (decided exactly)
    /// whose gears bring the path to the flat configuration (the margin touches zero),
    /// `near_change_point` within [`FlagTolerances::change_point_gap`] of it
    /// (`|L(1) + L(2) + L(5) − L(3) − L(4)| / L(5)`, lengths sorted), `near_toggle`,
    /// `not_assembled`, `far_point`, `extreme_ratio` as for a four-bar; the error bound is
    /// [`GearedFiveBar::error_bound_at`]'s largest over the samples.
    pub fn assess_geared(
        linkage: &GearedFiveBar,
        circuit: Circuit,
        point: CouplerPoint,
        degrees: &[f64],
        tol: &FlagTolerances,
    ) -> CurveFlags {
        let mut flags = CurveFlags::static_flags_geared(linkage, point, tol);
        let gaps = GearedGaps::of(linkage);
        let (mut min_sin, mut bound, mut missing) = (1.0f64, 0.0f64, false);
        for &deg in degrees {
            let angle = linkage.angle_at(deg);
            match GearedPose::solve_with(linkage, &gaps, circuit, &angle) {
                Some(pose) => {
                    min_sin = min_sin.min(libm::sin(pose.transmission));
                    if let Some(b) = linkage.error_bound_at(&gaps, &angle, point) {
                        bound = bound.max(b);
                    }
                }
                None => missing = true,
            }
        }
        if min_sin < tol.toggle_sin_mu {
            flags.push(CurveFlag::NearToggle);
        }
        if missing {
            flags.push(CurveFlag::NotAssembled);
        }
        flags.sort();
        flags.dedup();
        CurveFlags {
            flags,
            error_bound: bound,
            min_sin_transmission: min_sin,
        }
    }

    /// The flags of a geared five-bar that depend only on the linkage and the point
    /// (unsorted): see [`CurveFlags::assess_geared`].
    pub fn static_flags_geared(
        linkage: &GearedFiveBar,
        point: CouplerPoint,
        tol: &FlagTolerances,
    ) -> Vec<CurveFlag> {
        let mut flags = Vec::new();
        let mut l = linkage.lengths();
        l.sort_by(f64::total_cmp);
        let gap = ((l[0] + l[1] + l[4]) - (l[2] + l[3])).abs() / l[4];
        if linkage.ting_class() == TingClass::III {
            // The chain can fold flat, but the gears decide whether the path gets there:
            // flagged when the dyad's margin touches zero (or the input rocks), not for
            // a Class III chain whose gears keep it clear.
            if linkage.rotatability(MARGIN_TOL) != Rotatability::Full {
                flags.push(CurveFlag::ChangePoint);
            }
        } else if gap < tol.change_point_gap {
            flags.push(CurveFlag::NearChangePoint);
        }
        CurveFlags::push_size_flags(&mut flags, l[0], l[4], point, tol);
        flags
    }

    /// The flags of a geared five-bar whose input turns fully, from `transmission`
    /// (`[min, max]` of μ over the period, radians), without sampling.
    pub fn for_full_turn_geared(
        linkage: &GearedFiveBar,
        point: CouplerPoint,
        transmission: [f64; 2],
        tol: &FlagTolerances,
    ) -> Vec<CurveFlag> {
        CurveFlags::with_toggle_flag(
            CurveFlags::static_flags_geared(linkage, point, tol),
            transmission,
            tol,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::GearRatio;

    #[test]
    fn class_three_is_a_change_point_and_rocking_is_not_assembled() {
        let tol = FlagTolerances::DEFAULT;
        let p = CouplerPoint::new(1.0, 0.5);
        let degrees: Vec<f64> = (0..360).map(f64::from).collect();
        // Sorted 1, 1, 2.1, 2.4, 2.5: 1 + 1 + 2.5 = 2.1 + 2.4.
        let g =
            GearedFiveBar::new(2.5, 2.1, 2.4, 1.0, GearRatio::integer(-1).unwrap(), 180.0).unwrap();
        let f = CurveFlags::assess_geared(&g, Circuit::Open, p, &degrees, &tol);
        assert!(f.flags.contains(&CurveFlag::ChangePoint), "{f:?}");
        assert!(f.flags.contains(&CurveFlag::NearToggle), "{f:?}");
        assert!(f.error_bound > 0.0 && f.error_bound < 1e-12, "{f:?}");
        let rocks =
            GearedFiveBar::new(2.5, 2.0, 2.0, 1.0, GearRatio::integer(1).unwrap(), 180.0).unwrap();
        let f = CurveFlags::assess_geared(&rocks, Circuit::Open, p, &degrees, &tol);
        assert!(f.flags.contains(&CurveFlag::NotAssembled), "{f:?}");
        let fine =
            GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::integer(2).unwrap(), 0.0).unwrap();
        let f = CurveFlags::assess_geared(&fine, Circuit::Open, p, &degrees, &tol);
        assert!(f.flags.is_empty(), "{f:?}");
    }
}
