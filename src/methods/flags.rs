//! Explicit flags for the conditions the shipped closed form cannot fully resolve, and its
//! documented error bound. Meant for the `curve` JSON and the index: never silent.

use crate::linkage::{Circuit, CouplerPoint, FourBar};
use crate::pose::{CrankAngle, Pose};
use serde::{Deserialize, Serialize};

/// One condition worth telling a user about a sampled curve. Serialised in snake case
/// (`"change_point"`, `"near_toggle"`, …); a curve's flags are sorted and unique.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CurveFlag {
    /// `s + l = p + q` exactly (Barker's S classes, decided exactly): the links fold flat
    /// at a change point, where both circuits meet and the motion may switch circuit.
    /// The tracer never switches there by itself: it stays on the requested circuit.
    ChangePoint,
    /// Not a change point, but within [`FlagTolerances::change_point_gap`] of one
    /// (`|s + l − p − q| / l`): the linkage nearly folds flat; see `near_toggle`.
    NearChangePoint,
    /// Some sample lies at or near a toggle: the transmission angle's sine falls below
    /// [`FlagTolerances::toggle_sin_mu`]. Positions stay finite and on their circuit, but
    /// their error bound grows like `1/sin μ` (and velocities like `1/sin μ`, infinite at
    /// the toggle itself).
    NearToggle,
    /// The linkage does not assemble at some sampled angles (the input is not a crank):
    /// those samples are missing (`None`/`NaN` in a [`Curve`](crate::Curve)), never guessed.
    NotAssembled,
    /// The coupler point is far from the coupler (`max(|u|, |v|)` above
    /// [`FlagTolerances::far_point`] times the longest link): the absolute error grows
    /// with the distance, relative error does not.
    FarPoint,
    /// Link ratios beyond [`FlagTolerances::extreme_ratio`] (longest / shortest, crank = 1
    /// included).
    ExtremeRatio,
}

impl CurveFlag {
    /// The snake-case name used in JSON.
    pub fn name(self) -> &'static str {
        match self {
            CurveFlag::ChangePoint => "change_point",
            CurveFlag::NearChangePoint => "near_change_point",
            CurveFlag::NearToggle => "near_toggle",
            CurveFlag::NotAssembled => "not_assembled",
            CurveFlag::FarPoint => "far_point",
            CurveFlag::ExtremeRatio => "extreme_ratio",
        }
    }
}

/// Thresholds for the flags, with one named default ([`FlagTolerances::DEFAULT`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlagTolerances {
    /// Relative Grashof gap below which `near_change_point` is raised (default 1e-6).
    pub change_point_gap: f64,
    /// `sin μ` below which `near_toggle` is raised (default 1e-3: the error bound is then
    /// above ~1e-12 of the curve's scale).
    pub toggle_sin_mu: f64,
    /// `max(|u|, |v|) / longest link` above which `far_point` is raised (default 100).
    pub far_point: f64,
    /// Longest / shortest link above which `extreme_ratio` is raised (default 1e3).
    pub extreme_ratio: f64,
}

impl FlagTolerances {
    /// The defaults.
    pub const DEFAULT: FlagTolerances = FlagTolerances {
        change_point_gap: 1e-6,
        toggle_sin_mu: 1e-3,
        far_point: 100.0,
        extreme_ratio: 1e3,
    };
}

impl Default for FlagTolerances {
    fn default() -> Self {
        FlagTolerances::DEFAULT
    }
}

/// The flags of one sampled curve and the shipped closed form's error bound for it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CurveFlags {
    /// Sorted, unique.
    pub flags: Vec<CurveFlag>,
    /// Bound on the position error of [`Pose::solve`]`.point(p)` over the samples, in crank
    /// lengths (see [`CurveFlags::error_bound_at`]).
    pub error_bound: f64,
    /// Smallest `sin μ` over the assembled samples (1 if none).
    pub min_sin_transmission: f64,
}

impl CurveFlags {
    /// The constant `K` of the error bound, set from the stability sweep
    /// (`coupler-atlas bench stability`) with a margin: no case measured needs more than
    /// a quarter of it.
    pub const BOUND_CONSTANT: f64 = 16.0;

    /// The documented error bound of the shipped closed form at one pose:
    ///
    /// `|M − M_exact| ≤ K·ε·S·(1 + L/(d·sin μ))`, `S = 1 + max(A, B, C) + |u| + |v|`,
    /// `L = max(A, B, C)`, ε = 2⁻⁵², `K` = [`CurveFlags::BOUND_CONSTANT`].
    ///
    /// Why this shape: the closed form is backward stable in (cos θ, sin θ, d) (Kahan's area
    /// is accurate to a few ulps for any triangle), so its error is the conditioning of the
    /// half-chord h with respect to d: `∂h/∂d ~ L/h` and `h·d = A·B·sin μ`, which gives the
    /// `1/sin μ` growth near a toggle; the coupler point's lever arm gives `S`.
    pub fn error_bound_at(linkage: &FourBar, point: CouplerPoint, d: f64, sin_mu: f64) -> f64 {
        let l = linkage.coupler.max(linkage.rocker).max(linkage.ground);
        let s = 1.0 + l + point.u.abs() + point.v.abs();
        let cond = if sin_mu > 0.0 && d > 0.0 {
            1.0 + l / (d * sin_mu)
        } else {
            f64::INFINITY
        };
        // The half-chord error can never exceed √(ε·L·…) however thin the triangle.
        let cap = (f64::EPSILON * l).sqrt() * s / f64::EPSILON;
        CurveFlags::BOUND_CONSTANT * f64::EPSILON * (s * cond).min(cap)
    }

    /// Assesses a curve of `linkage`, `circuit`, `point` sampled at `degrees`.
    ///
    /// ```
    /// use coupler_atlas::{FourBar, Circuit, CouplerPoint};
    /// use coupler_atlas::methods::{CurveFlags, CurveFlag, FlagTolerances, uniform_angles};
    /// let l = FourBar::new(3.0, 2.0, 2.0).unwrap(); // s + l = p + q: a change point
    /// let f = CurveFlags::assess(&l, Circuit::Open, CouplerPoint::new(1.0, 1.0),
    ///     &uniform_angles(1, 10.0), &FlagTolerances::DEFAULT);
    /// assert!(f.flags.contains(&CurveFlag::ChangePoint));
    /// assert!(f.flags.contains(&CurveFlag::NearToggle));
    /// ```
    pub fn assess(
        linkage: &FourBar,
        circuit: Circuit,
        point: CouplerPoint,
        degrees: &[f64],
        tol: &FlagTolerances,
    ) -> CurveFlags {
        let mut flags = Vec::new();
        let class = linkage.class();
        let mut links = [1.0, linkage.coupler, linkage.rocker, linkage.ground];
        links.sort_by(f64::total_cmp);
        let gap = ((links[0] + links[3]) - (links[1] + links[2])).abs() / links[3];
        if class.is_change_point() {
            flags.push(CurveFlag::ChangePoint);
        } else if gap < tol.change_point_gap {
            flags.push(CurveFlag::NearChangePoint);
        }
        if links[3] / links[0] > tol.extreme_ratio {
            flags.push(CurveFlag::ExtremeRatio);
        }
        if point.u.abs().max(point.v.abs()) > tol.far_point * links[3] {
            flags.push(CurveFlag::FarPoint);
        }
        let mut min_sin = 1.0f64;
        let mut bound = 0.0f64;
        let mut missing = false;
        for &deg in degrees {
            let t = CrankAngle::from_degrees(deg);
            match Pose::solve(linkage, circuit, &t) {
                Some(pose) => {
                    let sin_mu = libm::sin(pose.transmission);
                    let d = (pose.crank_pin - nalgebra::Point2::new(linkage.ground, 0.0)).norm();
                    min_sin = min_sin.min(sin_mu);
                    bound = bound.max(CurveFlags::error_bound_at(linkage, point, d, sin_mu));
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

    /// The flags' names, for printing.
    pub fn names(&self) -> Vec<&'static str> {
        self.flags.iter().map(|f| f.name()).collect()
    }
}
