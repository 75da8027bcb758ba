//! Explicit flags for the conditions the shipped closed form cannot fully resolve, and its
//! documented error bound. Meant for the `curve` JSON and the index: never silent.

use coupler_kinematics::{Circuit, CouplerPoint, FourBar, Linkage};
use coupler_kinematics::{CrankAngle, Pose, ToggleGaps};
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
    /// [`FlagTolerances::toggle_sin_mu`]. Positions stay finite and on their circuit;
    /// velocities grow like `1/sin μ` (infinite at the toggle itself) and, except at a
    /// change point's fold, so does the position error bound (see
    /// [`CurveFlags::error_bound_at`]).
    NearToggle,
    /// The linkage does not assemble at some sampled angles (the input is not a crank):
    /// those samples are missing (`None`/`NaN` in a [`Curve`](coupler_kinematics::Curve)), never guessed.
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
    /// `sin μ` below which `near_toggle` is raised (default 1e-3: velocities are then
    /// amplified a thousandfold, and away from a change point's fold the position error
    /// bound grows too).
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
    /// (`coupler-atlas bench stability` prints the largest measured error / bound).
    pub const BOUND_CONSTANT: f64 = 8.0;

    /// The documented error bound of the shipped closed form ([`Pose::solve`]) at one
    /// crank angle, in crank lengths:
    ///
    /// `|M − M_exact| ≤ K·ε·S + K·(1 + (|u| + |v|)/A)·δh`, `S = 1 + max(A, B, C) + |u| + |v|`,
    ///
    /// `δh = min(ε·C·(c²·√(Q/P) + s²·√(P/Q))/d, (√(ε·4C·c²·Q) + √(ε·4C·s²·P))/(2d))`,
    ///
    /// with `s, c = sin, cos(θ/2)`, `P = (A+B)² − d²`, `Q = d² − (A−B)²` (the thin factors)
    /// and `K` = [`CurveFlags::BOUND_CONSTANT`], ε = 2⁻⁵².
    ///
    /// Why this shape: the shipped form is backward stable except for the rounding of the
    /// half-angle terms `4C·c²` and `4C·s²` that enter P and Q; the half-chord
    /// `h = √(P·Q)/(2d)` turns a relative error ε in them into the first-order `δh` above,
    /// which grows near a toggle (P or Q → 0) and is capped by the square-root form at the
    /// toggle itself. At a change point's fold the small factor's half-angle term vanishes
    /// with it, so the bound stays at `K·ε·S`: no loss at change points. The coupler
    /// direction's error `δh/A` is carried to M by the lever arm `A + |u| + |v|`.
    pub fn error_bound_at(
        linkage: &FourBar,
        gaps: &ToggleGaps,
        point: CouplerPoint,
        angle: &CrankAngle,
    ) -> f64 {
        let (a, b, c) = (linkage.coupler, linkage.rocker, linkage.ground);
        let eps = f64::EPSILON;
        let s = 1.0 + a.max(b).max(c) + point.u.abs() + point.v.abs();
        let (sh2, ch2) = (
            angle.sin_half * angle.sin_half,
            angle.cos_half * angle.cos_half,
        );
        let p = (gaps.outer + 4.0 * c * ch2).max(0.0);
        let q = (gaps.inner + 4.0 * c * sh2).max(0.0);
        let d = ((c - 1.0) * (c - 1.0) + 4.0 * c * sh2).sqrt();
        let ratio = |x: f64, y: f64| {
            if y > 0.0 {
                (x / y).sqrt()
            } else {
                f64::INFINITY
            }
        };
        let term = |w: f64, r: f64| if w == 0.0 { 0.0 } else { w * r };
        let first = eps * c * (term(ch2, ratio(q, p)) + term(sh2, ratio(p, q))) / d;
        let cap = ((eps * 4.0 * c * ch2 * q).sqrt() + (eps * 4.0 * c * sh2 * p).sqrt()) / (2.0 * d);
        let dh = first.min(cap);
        let _ = b;
        CurveFlags::BOUND_CONSTANT * (eps * s + (1.0 + (point.u.abs() + point.v.abs()) / a) * dh)
    }

    /// Assesses a curve of `linkage`, `circuit`, `point` sampled at `degrees`.
    ///
    /// ```
    /// use coupler_kinematics::{FourBar, Circuit, CouplerPoint};
    /// use coupler_features::{CurveFlags, CurveFlag, FlagTolerances};
    /// let l = FourBar::new(3.0, 2.0, 2.0).unwrap(); // s + l = p + q: a change point
    /// let every_10_deg: Vec<f64> = (0..36).map(|k| 10.0 * k as f64).collect();
    /// let f = CurveFlags::assess(&l, Circuit::Open, CouplerPoint::new(1.0, 1.0),
    ///     &every_10_deg, &FlagTolerances::DEFAULT);
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
        let mut flags = CurveFlags::static_flags(linkage, point, tol);
        let mut min_sin = 1.0f64;
        let mut bound = 0.0f64;
        let gaps = ToggleGaps::of(linkage);
        let mut missing = false;
        for &deg in degrees {
            let t = CrankAngle::from_degrees(deg);
            match Pose::solve(linkage, circuit, &t) {
                Some(pose) => {
                    min_sin = min_sin.min(libm::sin(pose.transmission));
                    bound = bound.max(CurveFlags::error_bound_at(linkage, &gaps, point, &t));
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

    /// The flags that depend only on the linkage and the point, not on sampling:
    /// `change_point`, `near_change_point`, `extreme_ratio`, `far_point` (unsorted).
    pub fn static_flags(
        linkage: &FourBar,
        point: CouplerPoint,
        tol: &FlagTolerances,
    ) -> Vec<CurveFlag> {
        let mut flags = Vec::new();
        let mut links = [1.0, linkage.coupler, linkage.rocker, linkage.ground];
        links.sort_by(f64::total_cmp);
        let gap = ((links[0] + links[3]) - (links[1] + links[2])).abs() / links[3];
        if linkage.class().is_change_point() {
            flags.push(CurveFlag::ChangePoint);
        } else if gap < tol.change_point_gap {
            flags.push(CurveFlag::NearChangePoint);
        }
        CurveFlags::push_size_flags(&mut flags, links[0], links[3], point, tol);
        flags
    }

    /// `extreme_ratio` and `far_point`, from the shortest and longest links of any
    /// mechanism (four-bar or geared five-bar).
    pub(crate) fn push_size_flags(
        flags: &mut Vec<CurveFlag>,
        shortest: f64,
        longest: f64,
        point: CouplerPoint,
        tol: &FlagTolerances,
    ) {
        if longest / shortest > tol.extreme_ratio {
            flags.push(CurveFlag::ExtremeRatio);
        }
        if point.u.abs().max(point.v.abs()) > tol.far_point * longest {
            flags.push(CurveFlag::FarPoint);
        }
    }

    /// Adds `near_toggle` from the transmission angle's extremes (`[min, max]`, radians)
    /// to `flags`, sorted and unique.
    pub(crate) fn with_toggle_flag(
        mut flags: Vec<CurveFlag>,
        transmission: [f64; 2],
        tol: &FlagTolerances,
    ) -> Vec<CurveFlag> {
        let min_sin = libm::sin(transmission[0]).min(libm::sin(transmission[1]));
        if min_sin < tol.toggle_sin_mu {
            flags.push(CurveFlag::NearToggle);
        }
        flags.sort();
        flags.dedup();
        flags
    }

    /// The flags of a curve of a linkage whose crank turns fully (the atlas's
    /// crank-rockers), without sampling: the static flags, and `near_toggle` from the
    /// transmission angle's exact extremes (`transmission` = `[min, max]` in radians, from
    /// [`coupler_kinematics::transmission_range`]). Sorted and unique, as in [`CurveFlags::assess`].
    pub fn for_full_turn(
        linkage: &FourBar,
        point: CouplerPoint,
        transmission: [f64; 2],
        tol: &FlagTolerances,
    ) -> Vec<CurveFlag> {
        CurveFlags::with_toggle_flag(
            CurveFlags::static_flags(linkage, point, tol),
            transmission,
            tol,
        )
    }

    /// The flags' names, for printing.
    pub fn names(&self) -> Vec<&'static str> {
        self.flags.iter().map(|f| f.name()).collect()
    }
}

/// The flags of a curve of an atlas mechanism whose input turns fully, without sampling
/// ([`CurveFlags::for_full_turn`] for a four-bar): what the index records as `flags`.
/// `transmission` is `[min, max]` over the turn, radians.
pub fn curve_flags(
    linkage: &Linkage,
    point: CouplerPoint,
    transmission: [f64; 2],
    tol: &FlagTolerances,
) -> Vec<CurveFlag> {
    match linkage {
        Linkage::FourBar(l) => CurveFlags::for_full_turn(l, point, transmission, tol),
        Linkage::GearedFiveBar(l) => CurveFlags::for_full_turn_geared(l, point, transmission, tol),
    }
}
