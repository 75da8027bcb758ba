//! Coupler curves: sampled positions and velocities of coupler points over a crank turn.

use crate::frame::CouplerFrame;
use crate::linkage::{Circuit, CouplerPoint, FourBar};
use crate::pose::{CrankAngle, Pose, PoseCore, ToggleGaps};

/// Evenly spaced crank angles `θ_k = k·step` for `k = 0 .. n`, `n = ⌈360/step⌉` (all
/// below 360°), with their sines and cosines. Shared by every linkage sampled at that step.
///
/// ```
/// use coupler_kinematics::CrankTable;
/// let t = CrankTable::new(10.0).unwrap();
/// assert_eq!(t.len(), 36);
/// assert_eq!(t.angles()[35].degrees, 350.0);
/// ```
#[derive(Clone, Debug)]
pub struct CrankTable {
    step: f64,
    angles: Vec<CrankAngle>,
}

/// At most this many samples per crank turn (a step of at least 0.00036°): a guard
/// against typos like `--step 1e-9`, which would ask for gigabytes.
pub const MAX_SAMPLES_PER_TURN: u64 = 1_000_000;

/// The number of samples `0, step, 2·step, …` below 360° when `0 < step ≤ 360` is finite
/// and the count is at most [`MAX_SAMPLES_PER_TURN`]; `Err` says why not (for messages).
///
/// ```
/// use coupler_kinematics::samples_per_turn;
/// assert_eq!(samples_per_turn(7.0), Ok(52));
/// assert!(samples_per_turn(1e-9).unwrap_err().contains("more than the 1000000 allowed"));
/// ```
pub fn samples_per_turn(step_deg: f64) -> Result<u64, String> {
    if !(step_deg.is_finite() && step_deg > 0.0 && step_deg <= 360.0) {
        return Err(format!(
            "must be > 0 and at most 360 degrees, got {step_deg}"
        ));
    }
    let n = (360.0 / step_deg).ceil();
    if n > MAX_SAMPLES_PER_TURN as f64 {
        return Err(format!(
            "a step of {step_deg}° gives {n:.0} samples per turn, more than the {MAX_SAMPLES_PER_TURN} allowed (use a step of at least {}°)",
            360.0 / MAX_SAMPLES_PER_TURN as f64
        ));
    }
    let n = n as u64;
    // The last k·step may round to 360 exactly: it is not below 360.
    Ok(if (n - 1) as f64 * step_deg < 360.0 {
        n
    } else {
        n - 1
    })
}

impl CrankTable {
    /// Angles `0, step, 2·step, …` below 360°. `None` unless `0 < step ≤ 360` is finite
    /// and gives at most [`MAX_SAMPLES_PER_TURN`] samples ([`samples_per_turn`]).
    pub fn new(step_deg: f64) -> Option<CrankTable> {
        samples_per_turn(step_deg).ok()?;
        let n = (360.0 / step_deg).ceil() as usize;
        let angles = (0..n)
            .map(|k| k as f64 * step_deg)
            .filter(|&t| t < 360.0)
            .map(CrankAngle::from_degrees)
            .collect();
        Some(CrankTable {
            step: step_deg,
            angles,
        })
    }

    /// Angles `0, step, 2·step, …` below `period_deg` (a mechanism's period, e.g. `720`
    /// for a geared five-bar of gear ratio p/2: [`crate::Mechanism::period_deg`]).
    /// `None` unless `0 < step ≤ 360` and `period_deg` is a positive multiple of 360 (at
    /// most 360 000: a thousand turns). `over(step, 360.0)` is [`CrankTable::new`].
    ///
    /// ```
    /// use coupler_kinematics::CrankTable;
    /// let t = CrankTable::over(10.0, 720.0).unwrap();
    /// assert_eq!(t.len(), 72);
    /// assert_eq!(t.angles()[71].degrees, 710.0);
    /// ```
    pub fn over(step_deg: f64, period_deg: f64) -> Option<CrankTable> {
        let turns = period_deg / 360.0;
        if !(step_deg.is_finite()
            && step_deg > 0.0
            && step_deg <= 360.0
            && (1.0..=1000.0).contains(&turns)
            && turns.fract() == 0.0)
        {
            return None;
        }
        let n = (period_deg / step_deg).ceil() as usize;
        let angles = (0..n)
            .map(|k| k as f64 * step_deg)
            .filter(|&t| t < period_deg)
            .map(CrankAngle::from_degrees)
            .collect();
        Some(CrankTable {
            step: step_deg,
            angles,
        })
    }

    /// A table of arbitrary angles (the quadrature nodes of [`crate::ArcLength`]): its
    /// step is NaN, it has none.
    pub(crate) fn from_angles(angles: Vec<CrankAngle>) -> CrankTable {
        CrankTable {
            step: f64::NAN,
            angles,
        }
    }

    /// The step in degrees.
    pub fn step(&self) -> f64 {
        self.step
    }

    /// Number of angles.
    pub fn len(&self) -> usize {
        self.angles.len()
    }

    /// True if there are no angles (never, for a valid step).
    pub fn is_empty(&self) -> bool {
        self.angles.is_empty()
    }

    /// The angles.
    pub fn angles(&self) -> &[CrankAngle] {
        &self.angles
    }
}

/// The poses of one linkage and circuit at every angle of a [`CrankTable`], stored as
/// columns (structure of arrays) so that tracing many coupler points streams through
/// memory with one fused, branch-free loop. A pose that cannot be assembled is marked
/// invalid (its columns hold NaN).
#[derive(Clone, Debug)]
pub struct PoseTable {
    /// Crank pin x = cos θ.
    pub pa_x: Vec<f64>,
    /// Crank pin y = sin θ.
    pub pa_y: Vec<f64>,
    /// Coupler direction e3, x.
    pub e_x: Vec<f64>,
    /// Coupler direction e3, y.
    pub e_y: Vec<f64>,
    /// ω3, the coupler's angular velocity for unit crank speed.
    pub omega: Vec<f64>,
    /// Whether the linkage assembles at that angle.
    pub valid: Vec<bool>,
}

impl PoseTable {
    fn with_capacity(n: usize) -> PoseTable {
        PoseTable {
            pa_x: Vec::with_capacity(n),
            pa_y: Vec::with_capacity(n),
            e_x: Vec::with_capacity(n),
            e_y: Vec::with_capacity(n),
            omega: Vec::with_capacity(n),
            valid: Vec::with_capacity(n),
        }
    }

    /// Solves the pose once per angle (the equations of [`Pose::solve`]).
    pub fn new(linkage: &FourBar, circuit: Circuit, table: &CrankTable) -> PoseTable {
        let mut t = PoseTable::with_capacity(table.len());
        let gaps = ToggleGaps::of(linkage);
        for angle in table.angles() {
            let core = PoseCore::solve(linkage, &gaps, circuit, angle);
            t.pa_x.push(angle.cos);
            t.pa_y.push(angle.sin);
            t.valid.push(core.is_some());
            let c = core.unwrap_or(PoseCore {
                e_x: f64::NAN,
                e_y: f64::NAN,
                omega: f64::NAN,
                pb_x: f64::NAN,
                pb_y: f64::NAN,
                area4: f64::NAN,
                d2: f64::NAN,
            });
            t.e_x.push(c.e_x);
            t.e_y.push(c.e_y);
            t.omega.push(c.omega);
        }
        t
    }

    /// The frames `frame(angle)` at every angle of `table` (`None`: not assembled there),
    /// for any [`crate::Mechanism`]. The frame's origin must be the input crank's pin
    /// `(cos θ, sin θ)` (so its velocity is `J·Pa`, as [`PoseTable::trace_into`] assumes).
    pub fn from_frames(
        table: &CrankTable,
        mut frame: impl FnMut(&CrankAngle) -> Option<CouplerFrame>,
    ) -> PoseTable {
        let mut t = PoseTable::with_capacity(table.len());
        for angle in table.angles() {
            let f = frame(angle);
            debug_assert!(f.is_none_or(|f| f.origin.x == angle.cos && f.origin.y == angle.sin));
            t.pa_x.push(angle.cos);
            t.pa_y.push(angle.sin);
            t.valid.push(f.is_some());
            let (e, omega) = f.map_or(([f64::NAN; 2], f64::NAN), |f| {
                ([f.direction.x, f.direction.y], f.omega)
            });
            t.e_x.push(e[0]);
            t.e_y.push(e[1]);
            t.omega.push(omega);
        }
        t
    }

    /// Number of angles.
    pub fn len(&self) -> usize {
        self.valid.len()
    }

    /// True if empty.
    pub fn is_empty(&self) -> bool {
        self.valid.is_empty()
    }

    /// True when the linkage assembles at every angle.
    pub fn all_valid(&self) -> bool {
        self.valid.iter().all(|&v| v)
    }

    /// Traces one coupler point into `out` (resized to the table's length): with
    /// `d = M − Pa = u·e + v·J·e`, the position is `M = Pa + d` and the velocity
    /// `V = J·Pa + ω·J·d` (dPa/dθ = J·Pa; the coupler turns at ω). One branch-free loop of
    /// 12 flops over five columns, which the compiler vectorises. Invalid angles come out
    /// as NaN; see [`Curve::is_valid`].
    pub fn trace_into(&self, p: CouplerPoint, out: &mut Curve) {
        let n = self.len();
        out.x.resize(n, 0.0);
        out.y.resize(n, 0.0);
        out.vx.resize(n, 0.0);
        out.vy.resize(n, 0.0);
        let (u, v) = (p.u, p.v);
        let (pa_x, pa_y, e_x, e_y, om) = (
            &self.pa_x[..n],
            &self.pa_y[..n],
            &self.e_x[..n],
            &self.e_y[..n],
            &self.omega[..n],
        );
        let (x, y, vx, vy) = (
            &mut out.x[..n],
            &mut out.y[..n],
            &mut out.vx[..n],
            &mut out.vy[..n],
        );
        for k in 0..n {
            let dx = u * e_x[k] - v * e_y[k];
            let dy = u * e_y[k] + v * e_x[k];
            x[k] = pa_x[k] + dx;
            y[k] = pa_y[k] + dy;
            vx[k] = -pa_y[k] - om[k] * dy;
            vy[k] = pa_x[k] + om[k] * dx;
        }
    }

    /// The positions alone of [`PoseTable::trace_into`]'s trace, angle by angle: `(x, y)`
    /// of `M = Pa + d`, the same operations, so the same values (for a use that needs no
    /// velocity).
    pub fn positions(&self, p: CouplerPoint) -> impl Iterator<Item = (f64, f64)> + '_ {
        let n = self.len();
        let (u, v) = (p.u, p.v);
        let (pa_x, pa_y, e_x, e_y) = (
            &self.pa_x[..n],
            &self.pa_y[..n],
            &self.e_x[..n],
            &self.e_y[..n],
        );
        (0..n).map(move |k| {
            let dx = u * e_x[k] - v * e_y[k];
            let dy = u * e_y[k] + v * e_x[k];
            (pa_x[k] + dx, pa_y[k] + dy)
        })
    }

    /// Traces one coupler point into a new [`Curve`].
    pub fn trace(&self, p: CouplerPoint) -> Curve {
        let mut c = Curve::default();
        self.trace_into(p, &mut c);
        c
    }
}

/// The range `[min, max]` of the transmission angle over a full crank turn, radians, or
/// `None` unless the linkage assembles at θ = 0 and θ = 180°. μ depends only on
/// `d² = 1 + C² − 2C·cos θ`, which is monotonic on [0°, 180°], so for a crank that turns
/// fully the extremes fall exactly at θ = 0 and 180° (Norton §2.2; docs/conventions.md §3): exact,
/// not limited by sampling. Both circuits share it.
pub fn transmission_range(linkage: &FourBar) -> Option<[f64; 2]> {
    let at = |deg: f64| {
        Pose::solve(linkage, Circuit::Open, &CrankAngle::from_degrees(deg)).map(|p| p.transmission)
    };
    let (a, b) = (at(0.0)?, at(180.0)?);
    Some([a.min(b), a.max(b)])
}

/// One sampled coupler curve: position `(x, y)` and velocity `(vx, vy)` for unit crank
/// speed at each angle of its [`CrankTable`]. NaN where the linkage does not assemble.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Curve {
    /// x of M.
    pub x: Vec<f64>,
    /// y of M.
    pub y: Vec<f64>,
    /// dx/dθ.
    pub vx: Vec<f64>,
    /// dy/dθ.
    pub vy: Vec<f64>,
}

impl Curve {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// True if there are no samples.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Whether sample `k` is a real position (finite).
    pub fn is_valid(&self, k: usize) -> bool {
        self.x[k].is_finite() && self.y[k].is_finite()
    }
}

/// Summary measures of a closed, fully assembled curve sampled evenly in θ. Its length
/// is not one of them: the trapezoid rule on the samples is off by up to 1e-5 relative
/// on curves with cusps; [`crate::ArcLength`] gives it exactly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveSummary {
    /// `[x_min, y_min, x_max, y_max]` of the samples.
    pub bbox: [f64; 4],
    /// Smallest and largest sampled speed |V| (unit crank speed).
    pub speed: [f64; 2],
}

impl CurveSummary {
    /// Measures a curve; `None` if any sample is invalid or the curve is empty.
    pub fn of(curve: &Curve) -> Option<CurveSummary> {
        if curve.is_empty() {
            return None;
        }
        let mut bbox = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];
        let mut speed = [f64::INFINITY, -f64::INFINITY];
        for k in 0..curve.len() {
            let (x, y) = (curve.x[k], curve.y[k]);
            let s = (curve.vx[k] * curve.vx[k] + curve.vy[k] * curve.vy[k]).sqrt();
            if !(x.is_finite() && y.is_finite() && s.is_finite()) {
                return None;
            }
            bbox = [
                bbox[0].min(x),
                bbox[1].min(y),
                bbox[2].max(x),
                bbox[3].max(y),
            ];
            speed = [speed[0].min(s), speed[1].max(s)];
        }
        Some(CurveSummary { bbox, speed })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_matches_single_pose() {
        let l = FourBar::new(3.0, 2.5, 3.5).unwrap();
        let table = CrankTable::new(7.5).unwrap();
        let poses = PoseTable::new(&l, Circuit::Crossed, &table);
        let p = CouplerPoint::new(1.5, 2.0);
        let c = poses.trace(p);
        assert_eq!(c.len(), 48);
        for (k, angle) in table.angles().iter().enumerate() {
            let pose = Pose::solve(&l, Circuit::Crossed, angle).unwrap();
            let m = pose.point(p);
            let v = pose.velocity(p);
            assert!((c.x[k] - m.x).abs() < 1e-15 && (c.y[k] - m.y).abs() < 1e-15);
            assert!((c.vx[k] - v.x).abs() < 1e-14 && (c.vy[k] - v.y).abs() < 1e-14);
        }
    }

    /// The positions alone are the trace's, bit for bit, on either mechanism's table.
    #[test]
    fn positions_are_the_traces() {
        let four = FourBar::new(3.0, 2.5, 3.5).unwrap();
        let geared = crate::GearedFiveBar::new(
            3.0,
            3.2,
            3.5,
            1.2,
            crate::GearRatio::integer(-2).unwrap(),
            40.0,
        )
        .unwrap();
        let table = CrankTable::new(7.5).unwrap();
        for poses in [
            PoseTable::new(&four, Circuit::Crossed, &table),
            crate::Mechanism::pose_table(&geared, Circuit::Open, &table),
        ] {
            for p in [CouplerPoint::new(1.5, 2.0), CouplerPoint::new(-0.3, 0.7)] {
                let c = poses.trace(p);
                let got: Vec<(u64, u64)> = poses
                    .positions(p)
                    .map(|(x, y)| (x.to_bits(), y.to_bits()))
                    .collect();
                let want: Vec<(u64, u64)> = (0..c.len())
                    .map(|k| (c.x[k].to_bits(), c.y[k].to_bits()))
                    .collect();
                assert_eq!(got, want);
            }
        }
    }

    #[test]
    fn summary_of_unit_circle() {
        let l = FourBar::new(3.0, 3.0, 3.0).unwrap();
        let table = CrankTable::new(1.0).unwrap();
        let poses = PoseTable::new(&l, Circuit::Open, &table);
        let s = CurveSummary::of(&poses.trace(CouplerPoint::new(0.0, 0.0))).unwrap();
        assert!((s.speed[0] - 1.0).abs() < 1e-15 && (s.speed[1] - 1.0).abs() < 1e-15);
        assert!((s.bbox[0] + 1.0).abs() < 1e-15 && (s.bbox[3] - 1.0).abs() < 1e-15);
    }

    #[test]
    fn transmission_extremes_are_at_0_and_180() {
        let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
        let [lo, hi] = transmission_range(&l).unwrap();
        let table = CrankTable::new(0.25).unwrap();
        for angle in table.angles() {
            let mu = Pose::solve(&l, Circuit::Crossed, angle)
                .unwrap()
                .transmission;
            assert!(
                lo - 1e-15 <= mu && mu <= hi + 1e-15,
                "{} {mu}",
                angle.degrees
            );
        }
        // Law of cosines at θ = 0 (d = C − 1) and θ = 180° (d = C + 1).
        let mu = |d: f64| ((2.5f64 * 2.5 + 9.0 - d * d) / (2.0 * 2.5 * 3.0)).acos();
        // cos μ falls as d grows, so μ is smallest at θ = 0 (d = C − 1).
        assert!(
            (lo - mu(2.5)).abs() < 1e-14 && (hi - mu(4.5)).abs() < 1e-14,
            "{lo} {hi}"
        );
    }

    #[test]
    fn step_must_be_positive() {
        assert!(CrankTable::new(0.0).is_none());
        assert!(CrankTable::new(-1.0).is_none());
        assert!(CrankTable::new(f64::NAN).is_none());
        assert_eq!(CrankTable::new(360.0).unwrap().len(), 1);
        assert_eq!(CrankTable::new(7.0).unwrap().len(), 52); // 0..357
    }
}
