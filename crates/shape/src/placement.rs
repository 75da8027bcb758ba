//! A fitted curve's linkage placed in the user's frame.

use crate::fit::CurveFit;
use crate::geom::{C64, abs, arg};
use crate::kin::CouplerCurve;
use coupler_kinematics::{Circuit, CouplerPoint, Linkage};

/// The linkage (a four-bar or a geared five-bar) that traces a fitted target, in the
/// user's frame and units.
///
/// The fit maps the atlas frame to the user's by `p = a·M + b` (or `a·conj(M) + b` for a
/// reflected match). A reflected curve is traced by a real linkage (the mirror identity,
/// domain conventions §1, [`CouplerCurve::mirrored`]): reflecting the whole linkage in its
/// ground line maps the curve of point `(u, v)` on one circuit at input angle `θ` onto the
/// curve of `(u, −v)` on the other circuit at `−θ` (for a geared five-bar with its phase
/// negated, `φ → −φ`, the gear ratio unchanged). So a reflected match reports that
/// linkage: the other circuit, `v` negated, input angles negated (the input crank then
/// turns clockwise in the user's frame as the target is followed). Angles here are in the
/// user's frame, counter-clockwise from the ground line O2→O4 (O2→O5).
#[derive(Clone, Debug, PartialEq)]
pub struct Placement {
    /// Whether the atlas curve was reflected to match.
    pub mirrored: bool,
    /// User units per crank length.
    pub scale: f64,
    /// Direction of the ground line O2→O4 (O2→O5) in the user's frame, degrees,
    /// `(−180, 180]`.
    pub rotation_deg: f64,
    /// Input crank pivot O2.
    pub o2: [f64; 2],
    /// The other ground pivot: O4 of a four-bar, O5 of a geared five-bar.
    pub pivot: [f64; 2],
    /// The linkage reported, in crank units (input crank = 1): the atlas curve's, or for a
    /// reflected match its mirror's (a five-bar's phase negated). Its lengths in user
    /// units are [`Placement::lengths`].
    pub linkage: Linkage,
    /// The coupler point `(u, v)` in the coupler frame of this linkage (origin at the
    /// input crank's pin, +u towards the rocker pin of a four-bar or the dyad joint of a
    /// five-bar, +v 90° counter-clockwise in the user's frame), user units.
    pub point: [f64; 2],
    /// The circuit of this linkage in the user's frame.
    pub circuit: Circuit,
    /// Input crank angle at the first and last target point, in order of motion (user
    /// frame, degrees; the difference is the signed travel: positive counter-clockwise).
    /// For a closed untimed target the crank makes a whole period from the first.
    pub crank_deg: [f64; 2],
}

impl Placement {
    /// The placement of `fit` of `curve`.
    pub fn of(curve: &CouplerCurve, fit: &CurveFit) -> Placement {
        let a = C64::new(fit.a[0], fit.a[1]);
        let b = C64::new(fit.b[0], fit.b[1]);
        let sign = if fit.mirrored { -1.0 } else { 1.0 };
        let reported = if fit.mirrored {
            curve.mirrored()
        } else {
            *curve
        };
        let scale = abs(a);
        let pivot = a * ground_length(&curve.linkage) + b;
        let first = fit.theta_deg.first().copied().unwrap_or(0.0);
        let last = fit.theta_deg.last().copied().unwrap_or(0.0);
        Placement {
            mirrored: fit.mirrored,
            scale,
            rotation_deg: arg(a).to_degrees(),
            o2: [b.re, b.im],
            pivot: [pivot.re, pivot.im],
            linkage: reported.linkage,
            point: [scale * reported.point.u, scale * reported.point.v],
            circuit: reported.circuit,
            crank_deg: [sign * first, sign * last],
        }
    }

    /// The linkage's lengths in user units, named as its convention names them: a
    /// four-bar's `crank, coupler, rocker, ground`; a geared five-bar's `L1 … L5` (L2 the
    /// input crank).
    pub fn lengths(&self) -> Vec<(&'static str, f64)> {
        let s = self.scale;
        match &self.linkage {
            Linkage::FourBar(l) => vec![
                ("crank", s),
                ("coupler", s * l.coupler),
                ("rocker", s * l.rocker),
                ("ground", s * l.ground),
            ],
            Linkage::GearedFiveBar(l) => vec![
                ("L1", s * l.l1),
                ("L2", s),
                ("L3", s * l.l3),
                ("L4", s * l.l4),
                ("L5", s * l.l5),
            ],
        }
    }

    /// The coupler point's position in the user's frame at input angle `deg` (user
    /// frame), from this placement alone: a check that the report is self-contained.
    pub fn point_at(&self, deg: f64) -> Option<[f64; 2]> {
        let curve = CouplerCurve {
            linkage: self.linkage,
            circuit: self.circuit,
            point: CouplerPoint::new(self.point[0] / self.scale, self.point[1] / self.scale),
        };
        let m = curve.at(deg)?.m;
        let ground = C64::new(self.pivot[0] - self.o2[0], self.pivot[1] - self.o2[1]);
        let frame = ground / abs(ground) * self.scale;
        let z = C64::new(self.o2[0], self.o2[1]) + frame * m;
        Some([z.re, z.im])
    }
}

/// |O2O4| of a four-bar, |O2O5| of a geared five-bar, crank units.
fn ground_length(l: &Linkage) -> f64 {
    match l {
        Linkage::FourBar(l) => l.ground,
        Linkage::GearedFiveBar(l) => l.l1,
    }
}
