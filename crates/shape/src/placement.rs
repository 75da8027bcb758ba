//! A fitted curve's linkage placed in the user's frame.

use crate::fit::CurveFit;
use crate::geom::{C64, abs, arg};
use crate::kin::CouplerCurve;
use coupler_kinematics::Circuit;

/// The four-bar that traces a fitted target, in the user's frame and units.
///
/// The fit maps the atlas frame to the user's by `p = a·M + b` (or `a·conj(M) + b` for a
/// reflected match). A reflected curve is traced by a real four-bar (the mirror identity,
/// domain conventions §1): reflecting the whole linkage in its ground line maps the
/// curve of point `(u, v)` on one circuit at crank angle `θ` onto the curve of `(u, −v)`
/// on the other circuit at `−θ`. So a reflected match reports that four-bar: the other
/// circuit, `v` negated, crank angles negated (the crank then turns clockwise in the
/// user's frame as the target is followed). Angles here are in the user's frame,
/// counter-clockwise from the ground line O2→O4.
#[derive(Clone, Debug, PartialEq)]
pub struct Placement {
    /// Whether the atlas curve was reflected to match.
    pub mirrored: bool,
    /// User units per crank length.
    pub scale: f64,
    /// Direction of the ground line O2→O4 in the user's frame, degrees, `(−180, 180]`.
    pub rotation_deg: f64,
    /// Crank pivot O2.
    pub o2: [f64; 2],
    /// Rocker pivot O4.
    pub o4: [f64; 2],
    /// Crank length (= `scale`).
    pub crank: f64,
    /// Coupler length.
    pub coupler: f64,
    /// Rocker length.
    pub rocker: f64,
    /// Ground length |O2O4|.
    pub ground: f64,
    /// The coupler point `(u, v)` in the coupler frame of this four-bar (origin at the
    /// crank pin, +u towards the rocker pin, +v 90° counter-clockwise in the user's
    /// frame), user units.
    pub point: [f64; 2],
    /// The circuit of this four-bar in the user's frame.
    pub circuit: Circuit,
    /// Crank angle at the first and last target point, in order of motion (user frame,
    /// degrees; the difference is the signed travel: positive counter-clockwise). For a
    /// closed untimed target the crank makes a full turn from the first.
    pub crank_deg: [f64; 2],
}

impl Placement {
    /// The placement of `fit` of `curve`.
    pub fn of(curve: &CouplerCurve, fit: &CurveFit) -> Placement {
        let a = C64::new(fit.a[0], fit.a[1]);
        let b = C64::new(fit.b[0], fit.b[1]);
        let (a_user, sign) = (a, if fit.mirrored { -1.0 } else { 1.0 });
        let scale = abs(a_user);
        let l = &curve.linkage;
        let o4 = a_user * l.ground + b;
        let first = fit.theta_deg.first().copied().unwrap_or(0.0);
        let last = fit.theta_deg.last().copied().unwrap_or(0.0);
        Placement {
            mirrored: fit.mirrored,
            scale,
            rotation_deg: arg(a_user).to_degrees(),
            o2: [b.re, b.im],
            o4: [o4.re, o4.im],
            crank: scale,
            coupler: scale * l.coupler,
            rocker: scale * l.rocker,
            ground: scale * l.ground,
            point: [scale * curve.point.u, sign * scale * curve.point.v],
            circuit: if fit.mirrored {
                curve.circuit.other()
            } else {
                curve.circuit
            },
            crank_deg: [sign * first, sign * last],
        }
    }

    /// The coupler point's position in the user's frame at crank angle `deg` (user frame),
    /// from this placement alone: a check that the report is self-contained.
    pub fn point_at(&self, deg: f64) -> Option<[f64; 2]> {
        let l = coupler_kinematics::FourBar::new(
            self.coupler / self.crank,
            self.rocker / self.crank,
            self.ground / self.crank,
        )
        .ok()?;
        let pose = coupler_kinematics::Pose::solve(
            &l,
            self.circuit,
            &coupler_kinematics::CrankAngle::from_degrees(deg),
        )?;
        let m = pose.point(coupler_kinematics::CouplerPoint::new(
            self.point[0] / self.crank,
            self.point[1] / self.crank,
        ));
        let frame =
            C64::new(self.o4[0] - self.o2[0], self.o4[1] - self.o2[1]) / self.ground * self.crank;
        let z = C64::new(self.o2[0], self.o2[1]) + frame * C64::new(m.x, m.y);
        Some([z.re, z.im])
    }
}
