//! The coupler point and its derivatives, for fitting: position `M(θ)`, velocity
//! `dM/dθ`, and the sensitivities `∂M/∂(A, B, C, u, v)` of the closed-form pose.

use crate::geom::C64;
use coupler_kinematics::{Circuit, CouplerPoint, CrankAngle, FourBar, Pose, ToggleGaps};

/// A curve a search can return: its id (in the atlas) and what traces it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasCurve {
    /// Id in the atlas (index order).
    pub id: u64,
    /// Linkage, circuit and coupler point.
    pub curve: CouplerCurve,
}

/// A coupler point on one circuit of a linkage: the curve a candidate traces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CouplerCurve {
    /// The linkage (crank = 1).
    pub linkage: FourBar,
    /// The circuit.
    pub circuit: Circuit,
    /// The coupler point (crank units).
    pub point: CouplerPoint,
}

/// The coupler point at one crank angle, with derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointAt {
    /// `M(θ)`.
    pub m: C64,
    /// `dM/dθ` per **degree** of crank.
    pub dm_dtheta: C64,
}

/// [`PointAt`] plus `∂M/∂A`, `∂M/∂B`, `∂M/∂C`, `∂M/∂u`, `∂M/∂v` (θ held).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointSensitivity {
    /// Position and velocity.
    pub at: PointAt,
    /// `∂M/∂(A, B, C, u, v)`.
    pub d: [C64; 5],
}

const RAD_PER_DEG: f64 = std::f64::consts::PI / 180.0;

impl CouplerCurve {
    /// The position and velocity at `deg`; `None` where the linkage does not assemble or
    /// is at a toggle (infinite velocity).
    pub fn at(&self, deg: f64) -> Option<PointAt> {
        self.at_with(&ToggleGaps::of(&self.linkage), deg)
    }

    /// [`CouplerCurve::at`] with the linkage's constants computed once
    /// (`ToggleGaps::of(&self.linkage)`), for many angles.
    pub fn at_with(&self, gaps: &ToggleGaps, deg: f64) -> Option<PointAt> {
        let pose = Pose::solve_with(
            &self.linkage,
            gaps,
            self.circuit,
            &CrankAngle::from_degrees(deg),
        )?;
        if !pose.is_finite() {
            return None;
        }
        let m = pose.point(self.point);
        let v = pose.velocity(self.point);
        Some(PointAt {
            m: C64::new(m.x, m.y),
            dm_dtheta: C64::new(v.x, v.y) * RAD_PER_DEG,
        })
    }

    /// [`CouplerCurve::at`] with the sensitivities to the linkage's dimensions and the
    /// coupler point. The rocker pin Pb satisfies `|Pb − Pa|² = A²` and `|Pb − O4|² = B²`
    /// with `O4 = (C, 0)`; differentiating, with `q = Pb − Pa`, `w = Pb − O4`:
    /// `q·dPb = A·dA` and `w·dPb = B·dB + w_x·dC`, a 2 × 2 system (singular only at a
    /// toggle, where `q ∥ w`). Then `e = q/A`, `de = dPb/A − q·dA/A²`, and
    /// `dM = u·de + v·J·de`; `∂M/∂u = e`, `∂M/∂v = J·e`.
    pub fn sensitivity(&self, deg: f64) -> Option<PointSensitivity> {
        self.sensitivity_with(&ToggleGaps::of(&self.linkage), deg)
    }

    /// [`CouplerCurve::sensitivity`] with the linkage's constants computed once.
    pub fn sensitivity_with(&self, gaps: &ToggleGaps, deg: f64) -> Option<PointSensitivity> {
        let pose = Pose::solve_with(
            &self.linkage,
            gaps,
            self.circuit,
            &CrankAngle::from_degrees(deg),
        )?;
        if !pose.is_finite() {
            return None;
        }
        let (a_len, b_len, c_len) = (
            self.linkage.coupler,
            self.linkage.rocker,
            self.linkage.ground,
        );
        let pa = C64::new(pose.crank_pin.x, pose.crank_pin.y);
        let pb = C64::new(pose.rocker_pin.x, pose.rocker_pin.y);
        let q = pb - pa;
        let w = pb - C64::new(c_len, 0.0);
        let det = q.re * w.im - q.im * w.re;
        if det == 0.0 {
            return None;
        }
        // Solve [q_x q_y; w_x w_y]·d = (r1, r2).
        let solve = |r1: f64, r2: f64| {
            C64::new((r1 * w.im - q.im * r2) / det, (q.re * r2 - w.re * r1) / det)
        };
        let e = C64::new(pose.coupler_dir.x, pose.coupler_dir.y);
        let (u, v) = (self.point.u, self.point.v);
        let j = C64::new(0.0, 1.0);
        let dm_from = |dpb: C64, da: f64| {
            let de = dpb / a_len - q * (da / (a_len * a_len));
            de * u + j * de * v
        };
        let d_a = dm_from(solve(a_len, 0.0), 1.0);
        let d_b = dm_from(solve(0.0, b_len), 0.0);
        let d_c = dm_from(solve(0.0, w.re), 0.0);
        let m = pose.point(self.point);
        let vel = pose.velocity(self.point);
        Some(PointSensitivity {
            at: PointAt {
                m: C64::new(m.x, m.y),
                dm_dtheta: C64::new(vel.x, vel.y) * RAD_PER_DEG,
            },
            d: [d_a, d_b, d_c, e, j * e],
        })
    }

    /// The curve sampled at `n` crank angles `k·360°/n`, `k = 0..n`; `None` unless it
    /// assembles at all of them.
    pub fn sample(&self, n: usize) -> Option<Vec<C64>> {
        let table = coupler_kinematics::CrankTable::new(360.0 / n as f64)?;
        let poses = coupler_kinematics::PoseTable::new(&self.linkage, self.circuit, &table);
        if !poses.all_valid() {
            return None;
        }
        let c = poses.trace(self.point);
        Some((0..c.len()).map(|k| C64::new(c.x[k], c.y[k])).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensitivities_match_finite_differences() {
        let base = CouplerCurve {
            linkage: FourBar::new(2.37, 3.1, 3.4).unwrap(),
            circuit: Circuit::Open,
            point: CouplerPoint::new(1.3, -0.8),
        };
        for circuit in [Circuit::Open, Circuit::Crossed] {
            let c = CouplerCurve { circuit, ..base };
            for k in 0..12 {
                let deg = 13.0 + 30.0 * k as f64;
                let s = c.sensitivity(deg).unwrap();
                let h = 1e-6;
                let moved = |i: usize, sign: f64| {
                    let mut d = [
                        c.linkage.coupler,
                        c.linkage.rocker,
                        c.linkage.ground,
                        c.point.u,
                        c.point.v,
                    ];
                    d[i] += sign * h;
                    CouplerCurve {
                        linkage: FourBar::new(d[0], d[1], d[2]).unwrap(),
                        circuit,
                        point: CouplerPoint::new(d[3], d[4]),
                    }
                    .at(deg)
                    .unwrap()
                    .m
                };
                for i in 0..5 {
                    let fd = (moved(i, 1.0) - moved(i, -1.0)) / (2.0 * h);
                    assert!(
                        (fd - s.d[i]).norm() < 1e-7,
                        "{circuit} {deg} {i}: {fd} {}",
                        s.d[i]
                    );
                }
                let fd = (c.at(deg + 1e-5).unwrap().m - c.at(deg - 1e-5).unwrap().m) / 2e-5;
                assert!((fd - s.at.dm_dtheta).norm() < 1e-7);
            }
        }
    }
}
