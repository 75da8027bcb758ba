//! The coupler point and its derivatives, for fitting: position `M(θ)`, velocity
//! `dM/dθ`, and the sensitivities `∂M/∂(dimensions, u, v)` of the closed-form pose, for
//! either mechanism of an atlas ([`Linkage`]): the mechanism-generic seam of shape search
//! (how a hit becomes a linkage, how its curve is regenerated).

use crate::geom::C64;
use coupler_kinematics::{
    Circuit, CouplerPoint, CrankAngle, CrankTable, FourBar, GearedFiveBar, GearedGaps, Linkage,
    Mechanism, POINT_LANES, PointLanes, Pose, PoseTable, ToggleGaps,
};
use std::cell::RefCell;
use std::rc::Rc;

/// A curve a search can return: its id (in the atlas) and what traces it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasCurve {
    /// Id in the atlas (index order).
    pub id: u64,
    /// Linkage, circuit and coupler point.
    pub curve: CouplerCurve,
}

/// A coupler point on one circuit of a linkage (a four-bar or a geared five-bar, input
/// crank = 1): the curve a candidate traces, over the mechanism's period of input
/// ([`CouplerCurve::period_deg`]: 360° for a four-bar, `360°·q` for a geared five-bar of
/// gear ratio p/q).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CouplerCurve {
    /// The linkage (input crank = 1).
    pub linkage: Linkage,
    /// The circuit.
    pub circuit: Circuit,
    /// The coupler point (crank units), on the coupler of a four-bar or on L3 of a geared
    /// five-bar.
    pub point: CouplerPoint,
}

/// A curve's linkage constants computed once, for evaluating it at many angles
/// ([`CouplerCurve::gaps`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CurveGaps {
    /// A four-bar's.
    FourBar(ToggleGaps),
    /// A geared five-bar's.
    Geared(GearedGaps),
}

/// A curve made ready for [`CurveLanes::at`], its points [`POINT_LANES`] angles at a time
/// ([`CouplerCurve::lanes`]): a four-bar's linkage constants computed once
/// ([`PointLanes`]), for a fit that evaluates the same curve at many angles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CurveLanes {
    /// A four-bar's coupler point, its lanes side by side.
    FourBar(PointLanes),
    /// Another mechanism's curve, one angle at a time ([`CouplerCurve::at_with`]).
    Other(CouplerCurve, CurveGaps),
}

impl CurveLanes {
    /// [`CouplerCurve::at_lanes_with`] of the curve, the same values bit for bit.
    #[inline(always)]
    pub fn at(&self, degrees: &[f64; POINT_LANES]) -> [Option<PointAt>; POINT_LANES] {
        match self {
            CurveLanes::FourBar(k) => point_lanes(k, degrees),
            CurveLanes::Other(curve, gaps) => degrees.map(|d| curve.at_with(gaps, d)),
        }
    }
}

impl CurveLanes {
    /// [`CurveLanes::at`] with a four-bar's lanes inlined into the caller, the same values
    /// bit for bit: for a caller compiled for AVX2 itself (Levenberg–Marquardt's
    /// iterations, `lm::iterate`), where the call per group and its result's copy go (on
    /// the baseline path the lanes are compiled for the baseline, as [`CurveLanes::at`]'s
    /// are there).
    #[inline(always)]
    pub fn at_inlined(&self, degrees: &[f64; POINT_LANES]) -> [Option<PointAt>; POINT_LANES] {
        match self {
            CurveLanes::FourBar(k) => point_lanes_body(k, degrees),
            CurveLanes::Other(curve, gaps) => degrees.map(|d| curve.at_with(gaps, d)),
        }
    }
}

/// A four-bar's lanes as [`PointAt`]s: `None` also where a value is not finite. A
/// function of its own: the lanes vectorize well alone, and worse inlined into a fit
/// compiled for the baseline (the untimed fit's iterations, compiled for AVX2 themselves,
/// inline them instead: [`CurveLanes::at_inlined`]).
///
/// **Four lanes in one vector where the processor has them**: on x86-64 with AVX2
/// (checked at run time) the same code compiled for AVX2 runs instead (the four lanes in
/// one register where the baseline code takes two): the same operations in the same
/// order (never fused: AVX2 does not enable FMA), so the same values bit for bit (test
/// `point_lanes_are_the_same_on_every_path`).
#[inline(never)]
fn point_lanes(k: &PointLanes, degrees: &[f64; POINT_LANES]) -> [Option<PointAt>; POINT_LANES] {
    #[cfg(target_arch = "x86_64")]
    if crate::has_avx2() {
        // SAFETY: `point_lanes_avx2` needs AVX2, which the processor was just found to
        // have; it has no other requirement (the safe body compiled for AVX2).
        #[allow(unsafe_code)]
        return unsafe { point_lanes_avx2(k, degrees) };
    }
    point_lanes_body(k, degrees)
}

/// [`point_lanes_body`] compiled for AVX2 (called only where the processor has it).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn point_lanes_avx2(
    k: &PointLanes,
    degrees: &[f64; POINT_LANES],
) -> [Option<PointAt>; POINT_LANES] {
    point_lanes_body(k, degrees)
}

/// [`point_lanes`] itself, inlined into each of its two paths.
#[inline(always)]
fn point_lanes_body(
    k: &PointLanes,
    degrees: &[f64; POINT_LANES],
) -> [Option<PointAt>; POINT_LANES] {
    let lanes = k.at_finite(degrees);
    // Lane by lane in place (`from_fn`: inlined, where `map` over the lanes was a call per
    // group).
    std::array::from_fn(|i| {
        let (m, v) = lanes[i]?;
        Some(PointAt {
            m: C64::new(m.x, m.y),
            dm_dtheta: C64::new(v.x, v.y) * RAD_PER_DEG,
        })
    })
}

/// The coupler point at one crank angle, with derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointAt {
    /// `M(θ)`.
    pub m: C64,
    /// `dM/dθ` per **degree** of crank.
    pub dm_dtheta: C64,
}

/// [`PointAt`] plus `∂M/∂p` for each of the curve's parameters `p`
/// ([`CouplerCurve::params`]), θ held.
#[derive(Clone, Debug, PartialEq)]
pub struct PointSensitivity {
    /// Position and velocity.
    pub at: PointAt,
    /// `∂M/∂p`, in the order of [`CouplerCurve::params`].
    pub d: Vec<C64>,
}

const RAD_PER_DEG: f64 = std::f64::consts::PI / 180.0;

impl CouplerCurve {
    /// The curve of `point` on `circuit` of `linkage`.
    pub fn new(linkage: impl Into<Linkage>, circuit: Circuit, point: CouplerPoint) -> Self {
        CouplerCurve {
            linkage: linkage.into(),
            circuit,
            point,
        }
    }

    /// Degrees of input after which the curve closes ([`Mechanism::period_deg`]).
    pub fn period_deg(&self) -> f64 {
        self.linkage.period_deg()
    }

    /// The linkage's constants, for [`CouplerCurve::at_with`].
    pub fn gaps(&self) -> CurveGaps {
        match &self.linkage {
            Linkage::FourBar(l) => CurveGaps::FourBar(ToggleGaps::of(l)),
            Linkage::GearedFiveBar(l) => CurveGaps::Geared(GearedGaps::of(l)),
        }
    }

    /// The position and velocity at `deg`; `None` where the linkage does not assemble or
    /// is at a toggle (infinite velocity).
    pub fn at(&self, deg: f64) -> Option<PointAt> {
        self.at_with(&self.gaps(), deg)
    }

    /// [`CouplerCurve::at`] with the linkage's constants computed once
    /// ([`CouplerCurve::gaps`]), for many angles. `None` also if `gaps` are another
    /// mechanism's.
    pub fn at_with(&self, gaps: &CurveGaps, deg: f64) -> Option<PointAt> {
        let angle = CrankAngle::from_degrees(deg);
        let (m, v) = match (&self.linkage, gaps) {
            (Linkage::FourBar(l), CurveGaps::FourBar(g)) => {
                let frame = Pose::finite_frame_with(l, g, self.circuit, &angle)?;
                (frame.point(self.point), frame.velocity(self.point))
            }
            (Linkage::GearedFiveBar(l), CurveGaps::Geared(g)) => {
                let frame = l.frame_with(g, self.circuit, &angle)?;
                if !frame.omega.is_finite() {
                    return None;
                }
                (frame.point(self.point), frame.velocity(self.point))
            }
            _ => return None,
        };
        if !(m.x.is_finite() && m.y.is_finite() && v.x.is_finite() && v.y.is_finite()) {
            return None;
        }
        Some(PointAt {
            m: C64::new(m.x, m.y),
            dm_dtheta: C64::new(v.x, v.y) * RAD_PER_DEG,
        })
    }

    /// [`CouplerCurve::at_with`] at [`POINT_LANES`] angles at once, the same values bit
    /// for bit; a four-bar's lanes run side by side ([`Pose::finite_points_with`]; for
    /// many groups of angles, [`CouplerCurve::lanes`] prepares the curve once).
    pub fn at_lanes_with(
        &self,
        gaps: &CurveGaps,
        degrees: &[f64; POINT_LANES],
    ) -> [Option<PointAt>; POINT_LANES] {
        self.lanes_with(gaps).at(degrees)
    }

    /// The curve made ready for evaluating [`POINT_LANES`] angles at a time
    /// ([`CurveLanes::at`]: [`CouplerCurve::at_lanes_with`]'s values, bit for bit).
    pub fn lanes(&self) -> CurveLanes {
        self.lanes_with(&self.gaps())
    }

    /// [`CouplerCurve::lanes`] with the linkage's constants computed once (`gaps`).
    #[inline]
    pub fn lanes_with(&self, gaps: &CurveGaps) -> CurveLanes {
        match (&self.linkage, gaps) {
            (Linkage::FourBar(l), CurveGaps::FourBar(g)) => {
                CurveLanes::FourBar(PointLanes::new(l, g, self.circuit, self.point))
            }
            _ => CurveLanes::Other(*self, *gaps),
        }
    }

    /// [`CouplerCurve::at_with`] at each of `degrees`, [`POINT_LANES`] at a time (the same
    /// values); `None` if any is.
    pub fn points_with(&self, gaps: &CurveGaps, degrees: &[f64]) -> Option<Vec<PointAt>> {
        let mut out = Vec::with_capacity(degrees.len());
        let prepared = self.lanes_with(gaps);
        for chunk in degrees.chunks(POINT_LANES) {
            let lanes = std::array::from_fn(|i| chunk[i.min(chunk.len() - 1)]);
            let got = prepared.at(&lanes);
            for x in &got[..chunk.len()] {
                out.push((*x)?);
            }
        }
        Some(out)
    }

    /// The curve's continuous parameters, as refinement moves them: a four-bar's
    /// `[A, B, C, u, v]`; a geared five-bar's `[L1, L3, L4, L5, φ (degrees), u, v]` (its
    /// gear ratio λ is discrete: it sets the period and the curve's family, and is held).
    pub fn params(&self) -> Vec<f64> {
        let (u, v) = (self.point.u, self.point.v);
        match &self.linkage {
            Linkage::FourBar(l) => vec![l.coupler, l.rocker, l.ground, u, v],
            Linkage::GearedFiveBar(l) => vec![l.l1, l.l3, l.l4, l.l5, l.phase, u, v],
        }
    }

    /// The names of [`CouplerCurve::params`].
    pub fn param_names(&self) -> &'static [&'static str] {
        match &self.linkage {
            Linkage::FourBar(_) => &["A", "B", "C", "u", "v"],
            Linkage::GearedFiveBar(_) => &["L1", "L3", "L4", "L5", "φ", "u", "v"],
        }
    }

    /// The same mechanism (circuit, and gear ratio of a geared five-bar) with parameters
    /// `p` in the order of [`CouplerCurve::params`]; `None` unless they make a linkage
    /// (lengths finite and positive, point finite).
    pub fn with_params(&self, p: &[f64]) -> Option<CouplerCurve> {
        let (linkage, point): (Linkage, _) = match &self.linkage {
            Linkage::FourBar(_) if p.len() == 5 => (
                FourBar::new(p[0], p[1], p[2]).ok()?.into(),
                CouplerPoint::new(p[3], p[4]),
            ),
            Linkage::GearedFiveBar(l) if p.len() == 7 => (
                GearedFiveBar::new(p[0], p[1], p[2], p[3], l.ratio, p[4])
                    .ok()?
                    .into(),
                CouplerPoint::new(p[5], p[6]),
            ),
            _ => return None,
        };
        (point.u.is_finite() && point.v.is_finite()).then_some(CouplerCurve {
            linkage,
            circuit: self.circuit,
            point,
        })
    }

    /// The mirror image's linkage: reflecting the whole linkage in its ground line maps
    /// this curve onto the curve of `(u, −v)` on the other circuit, the input angle
    /// negated (domain conventions §1, the mirror identity); for a geared five-bar the
    /// second crank's angle is negated too, `−θ5 = λ·(−θ2) − φ`, so the phase becomes
    /// `−φ`. So `self.mirrored().at(−θ)` is the conjugate of `self.at(θ)` (velocities
    /// per degree of the mirror's own input).
    pub fn mirrored(&self) -> CouplerCurve {
        let linkage = match self.linkage {
            Linkage::FourBar(l) => Linkage::FourBar(l),
            Linkage::GearedFiveBar(l) => Linkage::GearedFiveBar(GearedFiveBar {
                phase: if l.phase == 0.0 { 0.0 } else { -l.phase },
                ..l
            }),
        };
        CouplerCurve {
            linkage,
            circuit: self.circuit.other(),
            point: CouplerPoint::new(self.point.u, -self.point.v),
        }
    }

    /// [`CouplerCurve::at`] with the sensitivities to the curve's parameters
    /// ([`CouplerCurve::params`]).
    ///
    /// Four-bar, in closed form: the rocker pin Pb satisfies `|Pb − Pa|² = A²` and
    /// `|Pb − O4|² = B²` with `O4 = (C, 0)`; differentiating, with `q = Pb − Pa`,
    /// `w = Pb − O4`: `q·dPb = A·dA` and `w·dPb = B·dB + w_x·dC`, a 2 × 2 system (singular
    /// only at a toggle, where `q ∥ w`). Then `e = q/A`, `de = dPb/A − q·dA/A²`, and
    /// `dM = u·de + v·J·de`; `∂M/∂u = e`, `∂M/∂v = J·e`.
    ///
    /// Geared five-bar: `∂M/∂u = e3`, `∂M/∂v = J·e3` exactly; the dimensions' by central
    /// differences of the closed-form pose (step `1e-6·max(1, |p|)`; error about 1e-9
    /// relative, ample for a Gauss–Newton step). `None` if a moved linkage does not
    /// assemble at `deg`.
    pub fn sensitivity(&self, deg: f64) -> Option<PointSensitivity> {
        self.sensitivity_with(&self.gaps(), deg)
    }

    /// [`CouplerCurve::sensitivity`] with the linkage's constants computed once.
    pub fn sensitivity_with(&self, gaps: &CurveGaps, deg: f64) -> Option<PointSensitivity> {
        let at = self.at_with(gaps, deg)?;
        let l = match (&self.linkage, gaps) {
            (Linkage::FourBar(l), CurveGaps::FourBar(g)) => (l, g),
            (Linkage::GearedFiveBar(_), CurveGaps::Geared(_)) => {
                return self.geared_sensitivity(at, deg);
            }
            _ => return None,
        };
        let (linkage, gaps) = l;
        let pose = Pose::solve_with(linkage, gaps, self.circuit, &CrankAngle::from_degrees(deg))?;
        let (a_len, b_len, c_len) = (linkage.coupler, linkage.rocker, linkage.ground);
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
        Some(PointSensitivity {
            at,
            d: vec![d_a, d_b, d_c, e, j * e],
        })
    }

    /// The geared five-bar's sensitivities (see [`CouplerCurve::sensitivity`]).
    fn geared_sensitivity(&self, at: PointAt, deg: f64) -> Option<PointSensitivity> {
        let p = self.params();
        let dims = p.len() - 2;
        let mut d = Vec::with_capacity(p.len());
        for i in 0..dims {
            let h = 1e-6 * p[i].abs().max(1.0);
            let moved = |sign: f64| {
                let mut q = p.clone();
                q[i] += sign * h;
                self.with_params(&q)?.at(deg).map(|x| x.m)
            };
            d.push((moved(1.0)? - moved(-1.0)?) / (2.0 * h));
        }
        // ∂M/∂u = e, ∂M/∂v = J·e: the unit direction of L3 from the point (0, 0) and (1, 0).
        let origin = CouplerCurve {
            point: CouplerPoint::new(0.0, 0.0),
            ..*self
        };
        let unit = CouplerCurve {
            point: CouplerPoint::new(1.0, 0.0),
            ..*self
        };
        let e = unit.at(deg)?.m - origin.at(deg)?.m;
        d.push(e);
        d.push(C64::new(0.0, 1.0) * e);
        Some(PointSensitivity { at, d })
    }

    /// The curve sampled at `n` input angles `k·P/n`, `k = 0..n`, over its period `P`
    /// ([`CouplerCurve::period_deg`]); `None` unless it assembles at all of them.
    pub fn sample(&self, n: usize) -> Option<Vec<C64>> {
        let poses = sample_poses(&self.linkage, self.circuit, n)?;
        let mut z = Vec::new();
        trace_points(&poses, self.point, &mut z);
        Some(z)
    }
}

/// The poses [`CouplerCurve::sample`] traces: `linkage` on `circuit` at `n` input angles
/// `k·P/n` over its period `P`; `None` unless it assembles at all of them. They depend on
/// the linkage alone, so the curves of every coupler point of it share them.
pub(crate) fn sample_poses(linkage: &Linkage, circuit: Circuit, n: usize) -> Option<PoseTable> {
    let period = linkage.period_deg();
    let table = crank_table(period / n as f64, period)?;
    let poses = linkage.pose_table(circuit, &table);
    poses.all_valid().then_some(poses)
}

/// The points of `point`'s curve at the angles of `poses` (the trace's positions), into
/// `z` (its earlier contents replaced).
pub(crate) fn trace_points(poses: &PoseTable, point: CouplerPoint, z: &mut Vec<C64>) {
    z.clear();
    z.extend(poses.positions(point).map(|(x, y)| C64::new(x, y)));
}

/// `CrankTable::over(step, period)`, the table of the last `(step, period)` asked on this
/// thread kept for the next ask: a query traces every candidate at the same angles
/// (each table's sines and cosines cost as much as the poses). The table is a function
/// of its arguments alone, so the same values.
fn crank_table(step: f64, period: f64) -> Option<Rc<CrankTable>> {
    thread_local! {
        static LAST: RefCell<Option<(u64, u64, Rc<CrankTable>)>> = const { RefCell::new(None) };
    }
    let key = (step.to_bits(), period.to_bits());
    LAST.with(|last| {
        let mut last = last.borrow_mut();
        if let Some((s, p, table)) = last.as_ref() {
            if (*s, *p) == key {
                return Some(Rc::clone(table));
            }
        }
        let table = Rc::new(CrankTable::over(step, period)?);
        *last = Some((key.0, key.1, Rc::clone(&table)));
        Some(table)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::GearRatio;

    fn geared(ratio: GearRatio, phase: f64) -> CouplerCurve {
        CouplerCurve::new(
            GearedFiveBar::new(3.0, 3.2, 3.5, 1.2, ratio, phase).unwrap(),
            Circuit::Open,
            CouplerPoint::new(1.3, -0.8),
        )
    }

    /// Every parameter's sensitivity against central differences of the curve moved
    /// through [`CouplerCurve::with_params`] (an independent path for the four-bar's
    /// closed form; for the five-bar, a check of the step and of u, v).
    #[test]
    fn sensitivities_match_finite_differences() {
        let four = CouplerCurve::new(
            FourBar::new(2.37, 3.1, 3.4).unwrap(),
            Circuit::Open,
            CouplerPoint::new(1.3, -0.8),
        );
        let half = GearRatio::new(-1, 2).unwrap();
        for base in [
            four,
            geared(GearRatio::integer(-2).unwrap(), 40.0),
            geared(half, -70.0),
        ] {
            for circuit in [Circuit::Open, Circuit::Crossed] {
                let c = CouplerCurve { circuit, ..base };
                for k in 0..12 {
                    let deg = 13.0 + c.period_deg() / 12.0 * k as f64;
                    let s = c.sensitivity(deg).unwrap();
                    let p = c.params();
                    assert_eq!(s.d.len(), p.len());
                    for i in 0..p.len() {
                        let h = 1e-5;
                        let moved = |sign: f64| {
                            let mut q = p.clone();
                            q[i] += sign * h;
                            c.with_params(&q).unwrap().at(deg).unwrap().m
                        };
                        let fd = (moved(1.0) - moved(-1.0)) / (2.0 * h);
                        assert!(
                            (fd - s.d[i]).norm() < 1e-6 * (1.0 + fd.norm()),
                            "{} {circuit} {deg} {}: {fd} {}",
                            c.linkage,
                            c.param_names()[i],
                            s.d[i]
                        );
                    }
                    let fd = (c.at(deg + 1e-5).unwrap().m - c.at(deg - 1e-5).unwrap().m) / 2e-5;
                    assert!((fd - s.at.dm_dtheta).norm() < 1e-7 * (1.0 + fd.norm()));
                }
            }
        }
    }

    /// The mirror identity for both mechanisms: the mirror linkage at −θ traces the
    /// conjugate point (a five-bar's phase negated), over a whole period.
    #[test]
    fn mirrored_linkage_traces_the_reflected_curve() {
        let four = CouplerCurve::new(
            FourBar::new(2.37, 3.1, 3.4).unwrap(),
            Circuit::Crossed,
            CouplerPoint::new(1.3, -0.8),
        );
        let half = GearRatio::new(-1, 2).unwrap();
        for c in [
            four,
            geared(GearRatio::integer(2).unwrap(), 35.0),
            geared(half, -70.0),
        ] {
            let m = c.mirrored();
            let mut seen = 0;
            for k in 0..97 {
                let deg = c.period_deg() * k as f64 / 97.0;
                let (Some(a), Some(b)) = (c.at(deg), m.at(-deg)) else {
                    assert_eq!(c.at(deg).is_some(), m.at(-deg).is_some(), "{deg}");
                    continue;
                };
                seen += 1;
                assert!((a.m.conj() - b.m).norm() < 1e-12, "{} {deg}", c.linkage);
                assert!((a.dm_dtheta.conj() + b.dm_dtheta).norm() < 1e-12);
            }
            assert!(seen > 40, "{}: {seen}", c.linkage);
        }
    }

    /// A four-bar's lanes on the processor's fastest path ([`point_lanes`]: AVX2 where
    /// the processor has it) are the baseline path's, bit for bit (every value, and
    /// `None` at the same lanes), over random four-bars (some that do not turn fully, so
    /// lanes past a toggle occur), coupler points, both circuits and angles of either
    /// sign up to two turns.
    #[test]
    fn point_lanes_are_the_same_on_every_path() {
        let mut rng = crate::cases::SplitMix64(19);
        let bits = |x: &[Option<PointAt>; POINT_LANES]| {
            x.map(|p| p.map(|p| [p.m.re, p.m.im, p.dm_dtheta.re, p.dm_dtheta.im].map(f64::to_bits)))
        };
        let (mut some, mut none) = (0, 0);
        for _ in 0..200 {
            let (a, b, c) = (
                rng.range(0.5, 5.0),
                rng.range(0.5, 5.0),
                rng.range(0.5, 5.0),
            );
            let Ok(l) = FourBar::new(a, b, c) else {
                continue;
            };
            let point = CouplerPoint::new(rng.range(-4.0, 4.0), rng.range(-4.0, 4.0));
            for circuit in [Circuit::Open, Circuit::Crossed] {
                let curve = CouplerCurve::new(l, circuit, point);
                let CurveLanes::FourBar(k) = curve.lanes() else {
                    panic!("a four-bar's lanes");
                };
                for _ in 0..8 {
                    let degrees: [f64; POINT_LANES] =
                        std::array::from_fn(|_| rng.range(-720.0, 720.0));
                    let fast = point_lanes(&k, &degrees);
                    let base = point_lanes_body(&k, &degrees);
                    assert_eq!(bits(&fast), bits(&base), "{l} {circuit} {degrees:?}");
                    for x in &base {
                        if x.is_some() {
                            some += 1;
                        } else {
                            none += 1;
                        }
                    }
                }
            }
        }
        // Not vacuous: both kinds of lanes occur, many times.
        assert!(some > 1000 && none > 100, "{some} {none}");
    }

    /// A ratio of −1/2 closes after 720° of input, and `sample` covers it.
    #[test]
    fn samples_cover_the_period() {
        let c = geared(GearRatio::new(-1, 2).unwrap(), -70.0);
        assert_eq!(c.period_deg(), 720.0);
        let z = c.sample(720).unwrap();
        assert_eq!(z.len(), 720);
        assert!((z[1] - c.at(1.0).unwrap().m).norm() < 1e-12);
        assert!((z[500] - c.at(500.0).unwrap().m).norm() < 1e-12);
        assert!((z[500] - c.at(140.0).unwrap().m).norm() > 1e-3);
    }
}
