//! The output stage of a dwell six-bar, links 5 and 6, simulated over a revolution of
//! the driving four-bar (Norton §3.9, docs/conventions.md §6).

use crate::motion::Motion;
use serde::Serialize;

/// Links 5 and 6.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "kebab-case")]
pub enum Stage {
    /// A binary link 5 (length `link5`) from the coupler point M to D, and the output
    /// rocker 6 (length `link6`) from the ground pivot O6 to D. `branch` (±1) is the
    /// assembly of the dyad M–D–O6: the sign of (O6 − M) × (D − M), +1 when D is left of
    /// the directed line M → O6. A dyad that never folds flat keeps its branch all round.
    Rocker {
        /// Link 5, M to D.
        link5: f64,
        /// Link 6, O6 to D.
        link6: f64,
        /// Output pivot O6.
        pivot: [f64; 2],
        /// +1: D left of M → O6; −1: right.
        branch: f64,
    },
    /// A block (link 5) pinned to the coupler at M, sliding in a slotted output link 6
    /// pivoted at O6 (Norton Fig. 3-32): the output angle is the direction of M from O6.
    Slot {
        /// Output pivot O6.
        pivot: [f64; 2],
    },
}

/// What stopped a simulation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoAssembly {
    /// Crank angle, degrees.
    pub theta_deg: f64,
    /// |M − O6| there.
    pub distance: f64,
}

/// The output over a revolution: angle ψ of link 6 (direction O6 → D, or O6 → M for the
/// slot; unwrapped, continuous from θ = 0), its derivatives for unit crank speed
/// (dψ/dθ in rad/rad, d²ψ/dθ² in rad/rad²), the links 5–6 transmission angle at D
/// (degrees; `None` for the slot, whose block takes the force square to the slot: 90° by
/// construction) and D itself.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputMotion {
    /// ψ, degrees.
    pub psi: Vec<f64>,
    /// dψ/dθ.
    pub dpsi: Vec<f64>,
    /// d²ψ/dθ².
    pub ddpsi: Vec<f64>,
    /// Links 5–6 transmission angle μ at D, degrees in [0°, 180°].
    pub mu: Option<Vec<f64>>,
    /// D (for the slot: M, where the block is).
    pub d: Vec<[f64; 2]>,
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

fn unwrap_deg(prev: f64, a: f64) -> f64 {
    prev + (a - prev + 180.0).rem_euclid(360.0) - 180.0
}

/// The dyad's D for M, on `branch`: `D = M + f·u + s·h·J·u`, u the unit vector M → O6,
/// `f = (R² − L6² + d²)/(2d)` the foot and `h` the height of the triangle (R, L6, d) over
/// it (Kahan's area, stable when thin). `None` where the dyad does not assemble.
pub fn dyad_point(
    m: [f64; 2],
    link5: f64,
    pivot: [f64; 2],
    link6: f64,
    branch: f64,
) -> Option<[f64; 2]> {
    let (dx, dy) = (pivot[0] - m[0], pivot[1] - m[1]);
    let d = dx.hypot(dy);
    if d == 0.0 {
        return None;
    }
    let h = coupler_kinematics::kahan_double_area(link5, link6, d)? / d;
    let foot = (link5 * link5 - link6 * link6 + d * d) / (2.0 * d);
    let (ux, uy) = (dx / d, dy / d);
    Some([
        m[0] + foot * ux - branch * h * uy,
        m[1] + foot * uy + branch * h * ux,
    ])
}

impl Stage {
    /// The output pivot O6.
    pub fn pivot(&self) -> [f64; 2] {
        match *self {
            Stage::Rocker { pivot, .. } | Stage::Slot { pivot } => pivot,
        }
    }

    /// Simulates the stage over the motion's samples.
    ///
    /// Rocker: D on the fixed branch; with `e5 = (D − M)/R`, `e6 = (D − O6)/L6`, the loop
    /// `M + R·e5 = O6 + L6·e6` differentiated once and twice, dotted with e6 and e5:
    /// `ω5 = −(M'·e6)/(R·(e5 × e6))`, `ψ' = (M'·e5)/(L6·(e6 × e5))`,
    /// `ψ'' = [M''·e5 − R·ω5² + L6·ψ'²·(e5·e6)] / (L6·(e6 × e5))`;
    /// `cos μ = (R² + L6² − |M − O6|²)/(2·R·L6)`.
    /// Slot: with `r = M − O6`, `ψ' = (r × M')/|r|²`,
    /// `ψ'' = (r × M'')/|r|² − 2·(r·M')·(r × M')/|r|⁴`.
    pub fn simulate(&self, motion: &Motion) -> Result<OutputMotion, NoAssembly> {
        let n = motion.m.len();
        let mut out = OutputMotion {
            psi: Vec::with_capacity(n),
            dpsi: Vec::with_capacity(n),
            ddpsi: Vec::with_capacity(n),
            mu: None,
            d: Vec::with_capacity(n),
        };
        let mut mus = Vec::with_capacity(n);
        let mut prev: Option<f64> = None;
        for k in 0..n {
            let (m, v, a) = (motion.m[k], motion.v[k], motion.a[k]);
            let o6 = self.pivot();
            let fail = || NoAssembly {
                theta_deg: motion.theta[k],
                distance: (m[0] - o6[0]).hypot(m[1] - o6[1]),
            };
            let (raw, dpsi, ddpsi, d) = match *self {
                Stage::Rocker {
                    link5,
                    link6,
                    pivot,
                    branch,
                } => {
                    let d = dyad_point(m, link5, pivot, link6, branch).ok_or_else(fail)?;
                    let e5 = [(d[0] - m[0]) / link5, (d[1] - m[1]) / link5];
                    let e6 = [(d[0] - pivot[0]) / link6, (d[1] - pivot[1]) / link6];
                    let c56 = cross(e5, e6);
                    let w5 = -dot(v, e6) / (link5 * c56);
                    let dpsi = dot(v, e5) / (link6 * -c56);
                    let ddpsi = (dot(a, e5) - link5 * w5 * w5 + link6 * dpsi * dpsi * dot(e5, e6))
                        / (link6 * -c56);
                    let dist2 = (m[0] - pivot[0]).powi(2) + (m[1] - pivot[1]).powi(2);
                    let cos = (link5 * link5 + link6 * link6 - dist2) / (2.0 * link5 * link6);
                    mus.push(libm::acos(cos.clamp(-1.0, 1.0)).to_degrees());
                    let raw = libm::atan2(e6[1], e6[0]).to_degrees();
                    (raw, dpsi, ddpsi, d)
                }
                Stage::Slot { pivot } => {
                    let r = [m[0] - pivot[0], m[1] - pivot[1]];
                    let r2 = dot(r, r);
                    if r2 == 0.0 {
                        return Err(fail());
                    }
                    let dpsi = cross(r, v) / r2;
                    let ddpsi = cross(r, a) / r2 - 2.0 * dot(r, v) * cross(r, v) / (r2 * r2);
                    (libm::atan2(r[1], r[0]).to_degrees(), dpsi, ddpsi, m)
                }
            };
            let psi = prev.map_or(raw, |p| unwrap_deg(p, raw));
            prev = Some(psi);
            out.psi.push(psi);
            out.dpsi.push(dpsi);
            out.ddpsi.push(ddpsi);
            out.d.push(d);
        }
        if matches!(self, Stage::Rocker { .. }) {
            out.mu = Some(mus);
        }
        Ok(out)
    }

    /// The state of the stage alone at one coupler-point state (used to refine peaks
    /// between samples): (ψ unwrapped near `near`, dψ/dθ, d²ψ/dθ²).
    pub fn at(&self, m: [f64; 2], v: [f64; 2], a: [f64; 2]) -> Option<(f64, f64, f64)> {
        let motion = Motion {
            theta: vec![0.0],
            m: vec![m],
            v: vec![v],
            a: vec![a],
            mu4: vec![0.0],
        };
        let o = self.simulate(&motion).ok()?;
        Some((o.psi[0], o.dpsi[0], o.ddpsi[0]))
    }
}

/// The branch a rocker stage needs for D to be at `d` when the coupler point is at `m`:
/// the sign of (O6 − M) × (D − M) (0 when collinear).
pub fn branch_of(m: [f64; 2], d: [f64; 2], pivot: [f64; 2]) -> f64 {
    let c = cross(
        [pivot[0] - m[0], pivot[1] - m[1]],
        [d[0] - m[0], d[1] - m[1]],
    );
    if c > 0.0 {
        1.0
    } else if c < 0.0 {
        -1.0
    } else {
        0.0
    }
}
