//! The four-bar that drives a dwell six-bar, and the motion of its coupler point M over a
//! revolution: position, velocity and acceleration for unit crank speed (θ in radians),
//! analytic, in the frame of the curve as the atlas gives it (docs/conventions.md §1, §3).
//!
//! The driving four-bar is the atlas's linkage itself or one of its Roberts–Chebyshev
//! cognates (as `cognates` lists them): every cognate traces the same curve with the same
//! timing, so a dwell dyad hung from M behaves the same whichever of them drives it; what
//! changes is the four-bar (its pivots, links and transmission angles).

use crate::DwellError;
use coupler_kinematics::{Circuit, CouplerPoint, CrankAngle, FourBar, Pose, cognates};
use serde::Serialize;

/// A similarity of the plane, `z ↦ origin + rot·z` in complex numbers (`rot = s·e^{iα}`):
/// how a cognate's own frame (crank pivot at its origin, ground along +x, crank = 1) sits
/// in the original's frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Placement {
    /// Image of the own frame's origin.
    pub origin: [f64; 2],
    /// `s·(cos α, sin α)`: scale (the crank's length in the original's units) and rotation.
    pub rot: [f64; 2],
}

impl Placement {
    /// The identity.
    pub const IDENTITY: Placement = Placement {
        origin: [0.0, 0.0],
        rot: [1.0, 0.0],
    };

    /// Maps a point.
    pub fn point(&self, p: [f64; 2]) -> [f64; 2] {
        let v = self.vector(p);
        [self.origin[0] + v[0], self.origin[1] + v[1]]
    }

    /// Maps a vector (no translation).
    pub fn vector(&self, p: [f64; 2]) -> [f64; 2] {
        if *self == Placement::IDENTITY {
            return p;
        }
        let [c, s] = self.rot;
        [c * p[0] - s * p[1], s * p[0] + c * p[1]]
    }

    /// The scale (length of the image of a unit vector).
    pub fn scale(&self) -> f64 {
        self.rot[0].hypot(self.rot[1])
    }
}

/// The four-bar driving a dwell six-bar: a crank-rocker with its circuit and coupler
/// point, placed in the curve's frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Driver {
    /// The four-bar in its own frame (crank = 1).
    pub linkage: FourBar,
    /// Its circuit.
    pub circuit: Circuit,
    /// The coupler point in its own coupler frame (crank units).
    pub point: CouplerPoint,
    /// Where its frame sits in the curve's frame.
    pub placement: Placement,
    /// 0 for the atlas's linkage itself, 1 or 2 for a cognate (as `cognates` numbers them).
    pub cognate: usize,
}

/// The state of the driving four-bar at one crank angle, in the curve's frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriverState {
    /// Crank pin.
    pub crank_pin: [f64; 2],
    /// Rocker pin.
    pub rocker_pin: [f64; 2],
    /// Coupler point M.
    pub m: [f64; 2],
    /// dM/dθ.
    pub velocity: [f64; 2],
    /// d²M/dθ².
    pub acceleration: [f64; 2],
    /// The four-bar's transmission angle, degrees.
    pub transmission_deg: f64,
}

impl Driver {
    /// The atlas's linkage itself.
    pub fn original(linkage: FourBar, circuit: Circuit, point: CouplerPoint) -> Driver {
        Driver {
            linkage,
            circuit,
            point,
            placement: Placement::IDENTITY,
            cognate: 0,
        }
    }

    /// Cognate `k` (0 = the linkage itself, 1 and 2 as [`coupler_kinematics::cognates`]
    /// and the `cognates` command list them). A cognate that is not a crank-rocker is
    /// refused: its input only rocks between toggles, so no motor at its ground pivot drives
    /// it round the whole curve ([`DwellError::CognateNotCrank`]).
    pub fn cognate(
        linkage: FourBar,
        circuit: Circuit,
        point: CouplerPoint,
        k: usize,
    ) -> Result<Driver, DwellError> {
        if k == 0 {
            return Ok(Driver::original(linkage, circuit, point));
        }
        if k > 2 {
            return Err(DwellError::NoSuchCognate(k));
        }
        let three =
            cognates(&linkage, circuit, point).map_err(|e| DwellError::Cognate(e.to_string()))?;
        let c = &three[k];
        if !c.crank_rocker {
            return Err(DwellError::CognateNotCrank {
                k,
                class: c.class.clone(),
            });
        }
        let (l, p) = c
            .normalized()
            .ok_or_else(|| DwellError::Cognate(format!("cognate {k} cannot be normalised")))?;
        let axis = [
            c.pivots[1][0] - c.pivots[0][0],
            c.pivots[1][1] - c.pivots[0][1],
        ];
        let len = axis[0].hypot(axis[1]);
        Ok(Driver {
            linkage: l,
            circuit: c.circuit,
            point: p,
            placement: Placement {
                origin: c.pivots[0],
                rot: [axis[0] / len * c.crank, axis[1] / len * c.crank],
            },
            cognate: k,
        })
    }

    /// The crank's length in the curve's units (1 for the linkage itself).
    pub fn crank(&self) -> f64 {
        self.placement.scale()
    }

    /// The ground pivots (crank's, rocker's) in the curve's frame.
    pub fn pivots(&self) -> [[f64; 2]; 2] {
        [
            self.placement.point([0.0, 0.0]),
            self.placement.point([self.linkage.ground, 0.0]),
        ]
    }

    /// Link lengths `[crank, coupler, rocker, ground]` in the curve's units.
    pub fn links(&self) -> [f64; 4] {
        let s = self.crank();
        [
            s,
            s * self.linkage.coupler,
            s * self.linkage.rocker,
            s * self.linkage.ground,
        ]
    }

    /// The state at crank angle `theta_deg` (the crank's angle in its own frame; for a
    /// cognate that turns with the original's crank it is the original's θ), or `None`
    /// where the four-bar does not assemble or sits at a toggle.
    ///
    /// Acceleration for unit crank speed, from the loop `Pa + A·e3 = O4 + B·e4`
    /// differentiated twice (`Pa'' = −Pa`):
    /// `α3 = [Pa·e4 + A·ω3²·(e3·e4) − B·ω4²] / (A·(e3 × e4))`, and with `r = M − Pa`,
    /// `M'' = −Pa + α3·J·r − ω3²·r`.
    pub fn state(&self, theta_deg: f64) -> Option<DriverState> {
        let l = &self.linkage;
        let pose = Pose::solve(l, self.circuit, &CrankAngle::from_degrees(theta_deg))?;
        if !(pose.coupler_omega.is_finite() && pose.rocker_omega.is_finite()) {
            return None;
        }
        let m = pose.point(self.point);
        let v = pose.velocity(self.point);
        let (pa, e3, e4) = (pose.crank_pin, pose.coupler_dir, pose.rocker_dir);
        let (w3, w4) = (pose.coupler_omega, pose.rocker_omega);
        let cross34 = e3.x * e4.y - e3.y * e4.x;
        let alpha3 =
            (pa.x * e4.x + pa.y * e4.y + l.coupler * w3 * w3 * (e3.x * e4.x + e3.y * e4.y)
                - l.rocker * w4 * w4)
                / (l.coupler * cross34);
        let r = [m.x - pa.x, m.y - pa.y];
        let a = [
            -pa.x - alpha3 * r[1] - w3 * w3 * r[0],
            -pa.y + alpha3 * r[0] - w3 * w3 * r[1],
        ];
        let p = &self.placement;
        Some(DriverState {
            crank_pin: p.point([pa.x, pa.y]),
            rocker_pin: p.point([pose.rocker_pin.x, pose.rocker_pin.y]),
            m: p.point([m.x, m.y]),
            velocity: p.vector([v.x, v.y]),
            acceleration: p.vector(a),
            transmission_deg: pose.transmission.to_degrees(),
        })
    }
}

/// The coupler point's motion over one revolution, sampled every `step` degrees from
/// θ = 0 to θ = 360° (both ends: the last sample repeats the first pose).
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    /// Crank angles, degrees.
    pub theta: Vec<f64>,
    /// M.
    pub m: Vec<[f64; 2]>,
    /// dM/dθ.
    pub v: Vec<[f64; 2]>,
    /// d²M/dθ².
    pub a: Vec<[f64; 2]>,
    /// The four-bar's transmission angle, degrees.
    pub mu4: Vec<f64>,
}

impl Motion {
    /// Samples the driver every `step_deg` (which must divide 360).
    pub fn sample(driver: &Driver, step_deg: f64) -> Result<Motion, DwellError> {
        let n = (360.0 / step_deg).round() as usize;
        let mut r = Motion {
            theta: Vec::with_capacity(n + 1),
            m: Vec::with_capacity(n + 1),
            v: Vec::with_capacity(n + 1),
            a: Vec::with_capacity(n + 1),
            mu4: Vec::with_capacity(n + 1),
        };
        for k in 0..=n {
            let t = k as f64 * 360.0 / n as f64;
            let s = driver.state(t).ok_or(DwellError::NotAssembled(t))?;
            r.theta.push(t);
            r.m.push(s.m);
            r.v.push(s.velocity);
            r.a.push(s.acceleration);
            r.mu4.push(s.transmission_deg);
        }
        Ok(r)
    }

    /// The crank step, degrees.
    pub fn step(&self) -> f64 {
        360.0 / (self.theta.len() - 1) as f64
    }

    /// Indices of the samples inside a crank window `[start, start + span]` (taken modulo
    /// 360°), in crank order from the window's start; the sample at 360° is the one at 0°
    /// and is left out.
    pub fn window_indices(&self, start_deg: f64, span_deg: f64) -> Vec<usize> {
        let n = self.theta.len() - 1;
        let step = self.step();
        let s = start_deg.rem_euclid(360.0);
        let first = (s / step - 1e-9).ceil() as usize;
        let mut out = Vec::new();
        let mut k = first;
        loop {
            let t = k as f64 * step;
            if t - s > span_deg + 1e-9 {
                break;
            }
            out.push(k % n);
            k += 1;
            if out.len() > n {
                break;
            }
        }
        out
    }
}
