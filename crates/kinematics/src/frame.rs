//! The geometry a mechanism hands to the rest of the pipeline: the frame of the body
//! that carries the coupler points ([`CouplerFrame`]), and the mechanism drawn at one
//! input angle ([`Drawing`]). Plain data: the [`crate::Mechanism`] trait produces them.

use crate::linkage::CouplerPoint;
use nalgebra::{Point2, Vector2};

/// The frame of the body that carries the coupler points, at one input angle: origin
/// at the input crank's pin Pa, unit direction `e`, and the body's angular velocity
/// `ω = dφ/dθ` (θ in radians, unit input speed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CouplerFrame {
    /// The origin, the input crank's pin Pa.
    pub origin: Point2<f64>,
    /// Its velocity dPa/dθ.
    pub origin_velocity: Vector2<f64>,
    /// Unit direction `e` of the body.
    pub direction: Vector2<f64>,
    /// Angular velocity of the body, dφ/dθ (infinite at a toggle).
    pub omega: f64,
}

impl CouplerFrame {
    /// The coupler point `M = Pa + u·e + v·J·e`.
    #[inline]
    pub fn point(&self, p: CouplerPoint) -> Point2<f64> {
        let e = self.direction;
        Point2::new(
            self.origin.x + p.u * e.x - p.v * e.y,
            self.origin.y + p.u * e.y + p.v * e.x,
        )
    }

    /// The coupler point's velocity for unit input speed:
    /// `V_M = V_Pa + ω·J·(M − Pa) = V_Pa + ω·(u·J·e − v·e)`.
    #[inline]
    pub fn velocity(&self, p: CouplerPoint) -> Vector2<f64> {
        let e = self.direction;
        let w = self.omega;
        Vector2::new(
            self.origin_velocity.x + w * (-p.u * e.y - p.v * e.x),
            self.origin_velocity.y + w * (p.u * e.x - p.v * e.y),
        )
    }
}

/// A named joint of a mechanism's drawing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Joint {
    /// Its name on the page, e.g. `"O2"`, `"Pa"`.
    pub name: &'static str,
    /// Where it is, in crank units.
    pub position: Point2<f64>,
    /// A ground pivot (drawn with the ground symbol).
    pub ground: bool,
}

/// A mechanism drawn at one input angle, as geometry for the page layout: its joints,
/// the links between them, and the circles its crank pins move on.
#[derive(Clone, Debug, PartialEq)]
pub struct Drawing {
    /// Joints in drawing order: the ground pivots first, then the moving joints (only
    /// the ground pivots where the mechanism cannot be assembled).
    pub joints: Vec<Joint>,
    /// Links as pairs of indices into `joints`, in drawing order.
    pub links: Vec<[usize; 2]>,
    /// Circles the crank pins move on: `(centre, radius)`.
    pub paths: Vec<(Point2<f64>, f64)>,
    /// The coupler body's frame at this angle; `None` where the mechanism cannot be
    /// assembled.
    pub coupler: Option<CouplerFrame>,
}
