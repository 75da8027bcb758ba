//! Closed-form position and velocity of a geared five-bar at one input angle, and the
//! table of poses that serves a whole coupler-point grid.

use super::angle::{GearAngle, GearTable, add2, two_sum};
use super::linkage::GearedFiveBar;
use crate::{Circuit, CouplerPoint, Curve, PoseTable, TOGGLE_ULPS};
use nalgebra::{Point2, Vector2};

/// The constants of a geared five-bar's thin factors, computed once per linkage with
/// error-free sums and products and rounded once (the five-bar's
/// [`crate::ToggleGaps`]).
///
/// The chain folds flat at four *collinear configurations*, θ2* ∈ {0°, 180°} and
/// θ5* ∈ {0°, 180°}, where `d = |Pd − Pa|` is `|D*|` with `D* = L1 + L5·cos θ5* − cos θ2*`.
/// For each, the gaps `outer = (L3+L4)² − D*²` (how far the dyad is from stretching out
/// straight there) and `inner = D*² − (L3−L4)²` (from folding onto itself). Ting's
/// Class III linkages are exactly those where one of them is zero for the configuration
/// whose lengths sort as in his inequality; any 3–2 split of the five lengths with equal
/// sums makes a gap zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GearedGaps {
    /// `D*` per configuration, index `2·[θ2* = 180°] + [θ5* = 180°]`.
    pub d_star: [f64; 4],
    /// `(L3+L4)² − D*²`.
    pub outer: [f64; 4],
    /// `(L3+L4)² + D*²` (the size of its terms, for the rounding tolerance).
    pub outer_scale: [f64; 4],
    /// `D*² − (L3−L4)²`.
    pub inner: [f64; 4],
    /// `D*² + (L3−L4)²`.
    pub inner_scale: [f64; 4],
}

impl GearedGaps {
    /// The gaps of `linkage`.
    pub fn of(linkage: &GearedFiveBar) -> GearedGaps {
        let (l1, l3, l4, l5) = (linkage.l1, linkage.l3, linkage.l4, linkage.l5);
        let sum34 = two_sum(l3, l4);
        let diff34 = two_sum(l3, -l4);
        let neg = |(h, l): (f64, f64)| (-h, -l);
        let mut g = GearedGaps {
            d_star: [0.0; 4],
            outer: [0.0; 4],
            outer_scale: [0.0; 4],
            inner: [0.0; 4],
            inner_scale: [0.0; 4],
        };
        for i in 0..4 {
            let c2 = if i & 2 == 0 { 1.0 } else { -1.0 };
            let c5 = if i & 1 == 0 { 1.0 } else { -1.0 };
            // D* = L1 + c5·L5 − c2, exactly as a two-part sum.
            let d = add2(two_sum(l1, c5 * l5), (-c2, 0.0));
            let df = d.0 + d.1;
            // X² − Y² = (X − Y)(X + Y), each factor exact to ~1e-32 before one rounding.
            let diff_of_squares = |x: (f64, f64), y: (f64, f64)| {
                let a = add2(x, neg(y));
                let b = add2(x, y);
                (a.0 + a.1) * (b.0 + b.1)
            };
            let (s, t) = (sum34.0 + sum34.1, diff34.0 + diff34.1);
            g.d_star[i] = df;
            g.outer[i] = diff_of_squares(sum34, d);
            g.outer_scale[i] = s * s + df * df;
            g.inner[i] = diff_of_squares(d, diff34);
            g.inner_scale[i] = df * df + t * t;
        }
        g
    }
}

/// A thin factor negative by no more than rounding (relative to the size of its terms) is
/// a flat triangle, 0; more negative, no triangle.
#[inline]
fn flat(x: f64, scale: f64) -> Option<f64> {
    match x {
        x if x >= 0.0 => Some(x),
        x if x >= -TOGGLE_ULPS * f64::EPSILON * scale => Some(0.0),
        _ => None,
    }
}

/// The raw thin factors at one angle, before the flat/none decision, and the vector w.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Factors {
    /// `P = (L3+L4)² − d²` and the size of its terms.
    pub p: f64,
    pub p_scale: f64,
    /// `Q = d² − (L3−L4)²` and the size of its terms.
    pub q: f64,
    pub q_scale: f64,
    /// `w = Pd − Pa`.
    pub wx: f64,
    pub wy: f64,
    /// Sizes of the rounding errors of P and Q (the magnitudes of what was summed, the gap
    /// counted as it is, not as the size of its terms: it is rounded once) and of w's
    /// components.
    pub p_err: f64,
    pub q_err: f64,
    pub w_err: f64,
}

/// `d² = D*² + 4·T` around the nearest collinear configuration, with
/// `T = ∓L1·L5·{sin², cos²}(θ5/2) ± L1·{sin², cos²}(θ2/2) ± L5·{sin², cos²}(ψ/2)`: from
/// `|a + b + c|² = (Σσ|·|)² + 2Σ(x·y − σxσy|x||y|)` with `a = Pd − O5`, `b = O5 − O2`,
/// `c = O2 − Pa`, each pair term `2|x||y|(cos α ∓ 1) = ∓4|x||y|·{sin², cos²}(α/2)`.
#[inline]
pub(crate) fn factors(l: &GearedFiveBar, gaps: &GearedGaps, a: &GearAngle) -> Factors {
    let (t2, t5) = (&a.input, &a.second);
    let near2_pi = t2.cos < 0.0;
    let near5_pi = t5.cos < 0.0;
    let i = 2 * usize::from(near2_pi) + usize::from(near5_pi);
    let (s2, c2) = (t2.sin_half * t2.sin_half, t2.cos_half * t2.cos_half);
    let (s5, c5) = (t5.sin_half * t5.sin_half, t5.cos_half * t5.cos_half);
    let (sp, cp) = (
        a.rel_sin_half * a.rel_sin_half,
        a.rel_cos_half * a.rel_cos_half,
    );
    // Pair (a, b): 2·L1·L5·(cos θ5 − cos θ5*).
    let ab = if near5_pi {
        l1l5(l) * c5
    } else {
        -l1l5(l) * s5
    };
    // Pair (b, c): 2·L1·(cos θ2* − cos θ2).
    let bc = if near2_pi { -l.l1 * c2 } else { l.l1 * s2 };
    // Pair (a, c): 2·L5·(cos ψ* − cos ψ), ψ* = θ5* − θ2*.
    let ac = if near2_pi == near5_pi {
        l.l5 * sp
    } else {
        -l.l5 * cp
    };
    let t = 4.0 * ((ab + bc) + ac);
    let t_abs = 4.0 * (ab.abs() + bc.abs() + ac.abs());
    // w.x = L1 + L5·cos θ5 − cos θ2 = D* + L5·(cos θ5 − cos θ5*) − (cos θ2 − cos θ2*).
    let dx5 = if near5_pi {
        2.0 * l.l5 * c5
    } else {
        -2.0 * l.l5 * s5
    };
    let dx2 = if near2_pi { 2.0 * c2 } else { -2.0 * s2 };
    let p = gaps.outer[i] - t;
    let q = gaps.inner[i] + t;
    Factors {
        p_err: gaps.outer[i].abs() + t_abs + p.abs(),
        q_err: gaps.inner[i].abs() + t_abs + q.abs(),
        w_err: gaps.d_star[i].abs() + dx5.abs() + dx2.abs() + (l.l5 * t5.sin).abs() + t2.sin.abs(),
        p,
        p_scale: gaps.outer_scale[i] + t_abs,
        q,
        q_scale: gaps.inner_scale[i] + t_abs,
        wx: (gaps.d_star[i] + dx5) - dx2,
        wy: l.l5 * t5.sin - t2.sin,
    }
}

#[inline]
fn l1l5(l: &GearedFiveBar) -> f64 {
    l.l1 * l.l5
}

/// What every coupler point needs from a pose (the hot path of
/// [`GearedFiveBar::gear_pose_table`]). Same equations as [`GearedPose::solve`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct GearedCore {
    /// Unit direction e3 of L3 (Pa → P).
    pub e_x: f64,
    pub e_y: f64,
    /// ω3 (infinite at a toggle).
    pub omega: f64,
    /// The joint P.
    pub p_x: f64,
    pub p_y: f64,
    /// Pd.
    pub pd_x: f64,
    pub pd_y: f64,
    /// 4·Area of the triangle (L3, L4, d) = √(P·Q).
    pub area4: f64,
    /// `(P − Q)/2 = L3² + L4² − d²`.
    pub cos_term: f64,
    /// Relative velocity Vd − Va.
    pub dv_x: f64,
    pub dv_y: f64,
}

impl GearedCore {
    #[inline]
    pub(crate) fn solve(
        l: &GearedFiveBar,
        gaps: &GearedGaps,
        circuit: Circuit,
        a: &GearAngle,
    ) -> Option<GearedCore> {
        let f = factors(l, gaps, a);
        let d2 = f.wx * f.wx + f.wy * f.wy;
        if d2.is_nan() || d2 < f64::MIN_POSITIVE {
            return None;
        }
        let p = flat(f.p, f.p_scale)?;
        let q = flat(f.q, f.q_scale)?;
        let area4 = (p * q).sqrt();
        let inv_d2 = 1.0 / d2;
        let sigma = circuit.sign();
        // P − Pa = (a/d)·w + σ(h/d)·J·w, a/d = ½ + (L3² − L4²)/(2d²), h/d = area4/(2d²).
        let along = 0.5 + 0.5 * ((l.l3 - l.l4) * (l.l3 + l.l4)) * inv_d2;
        let across = sigma * 0.5 * area4 * inv_d2;
        let (cx, cy) = (f.wx * along - f.wy * across, f.wy * along + f.wx * across);
        let (t2, t5) = (&a.input, &a.second);
        let (p_x, p_y) = (t2.cos + cx, t2.sin + cy);
        let (pd_x, pd_y) = (l.l1 + l.l5 * t5.cos, l.l5 * t5.sin);
        // Va = J·Pa, Vd = λ·J·(Pd − O5); ω3 = 2·((Vd − Va)·(P − Pd)) / (σ·area4).
        let lambda = l.ratio.value();
        let dv_x = -lambda * l.l5 * t5.sin + t2.sin;
        let dv_y = lambda * l.l5 * t5.cos - t2.cos;
        let num = dv_x * (p_x - pd_x) + dv_y * (p_y - pd_y);
        let omega = if area4 > 0.0 {
            2.0 * num / (sigma * area4)
        } else {
            f64::INFINITY
        };
        let inv3 = 1.0 / l.l3;
        Some(GearedCore {
            e_x: cx * inv3,
            e_y: cy * inv3,
            omega,
            p_x,
            p_y,
            pd_x,
            pd_y,
            area4,
            cos_term: 0.5 * (p - q),
            dv_x,
            dv_y,
        })
    }
}

/// A geared five-bar's pose at one input angle: everything that depends only on the
/// linkage, the circuit and θ2, shared by every coupler point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GearedPose {
    /// The input crank's pin Pa = (cos θ2, sin θ2).
    pub input_pin: Point2<f64>,
    /// The second crank's pin Pd = O5 + L5·(cos θ5, sin θ5).
    pub second_pin: Point2<f64>,
    /// The dyad's joint P.
    pub joint: Point2<f64>,
    /// Unit vector e3 along L3, Pa → P.
    pub link3_dir: Vector2<f64>,
    /// Unit vector e4 along L4, Pd → P.
    pub link4_dir: Vector2<f64>,
    /// dPa/dθ2 = J·Pa.
    pub input_pin_velocity: Vector2<f64>,
    /// dPd/dθ2 = λ·J·(Pd − O5).
    pub second_pin_velocity: Vector2<f64>,
    /// ω3 = dφ3/dθ2 (infinite at a toggle).
    pub omega3: f64,
    /// ω4 = dφ4/dθ2 (infinite at a toggle).
    pub omega4: f64,
    /// Transmission angle μ at the joint P, between L3 and L4, radians in [0, π].
    pub transmission: f64,
}

impl GearedPose {
    /// Solves the dyad in closed form. With `w = Pd − Pa`, `d = |w|`, the joint is
    /// `P = Pa + (a/d)·w + σ·(h/d)·J·w`, `a/d = ½ + (L3² − L4²)/(2d²)`, `h = 2·Area/d` of
    /// the triangle (L3, L4, d), σ = +1 open, −1 crossed (domain conventions, as for the
    /// four-bar's [`crate::Pose::solve`] with O4 replaced by Pd).
    ///
    /// The area comes from Kahan's thin factors `16·Area² = P·Q`, `P = (L3+L4)² − d²`,
    /// `Q = d² − (L3−L4)²` (Kahan, "Miscalculating Area and Angles of a Needle-like
    /// Triangle"), and neither is formed by subtracting a rounded `d²`: around the
    /// nearest collinear configuration (θ2*, θ5*) ∈ {0°, 180°}² (derived in
    /// docs/geared-fivebar.md),
    /// `d² = D*² + 4·(∓L1·L5·s5 ± L1·s2 ± L5·sψ)` with `s` the squared sine or cosine of
    /// the half-angle deviations, so `P = [(L3+L4)² − D*²] − 4(…)` and
    /// `Q = [D*² − (L3−L4)²] + 4(…)`, the brackets exact per linkage ([`GearedGaps`]).
    /// Near a configuration where the chain folds flat every term is small and
    /// computed to a few ulps, so a Class III change point costs no digits (as the
    /// four-bar's change points do not). Likewise `w.x = D* + L5·(cos θ5 − cos θ5*) −
    /// (cos θ2 − cos θ2*)` from the half-angles.
    ///
    /// Velocities (unit input speed, θ2 in radians) differentiate the loop
    /// `Pa + L3·e3 = Pd + L4·e4`: with `Δ = Vd − Va`, `Va = J·Pa`, `Vd = λ·J·(Pd − O5)`,
    /// `ω3 = (Δ·e4)/(L3·(e3 × e4))`, `ω4 = (Δ·e3)/(L4·(e3 × e4))`, and
    /// `e3 × e4 = σ·h·d/(L3·L4)`. Transmission angle at P:
    /// `μ = atan2(√(P·Q), (P − Q)/2)` (`(P − Q)/2 = L3² + L4² − d²`: stable at 0° and 180°).
    ///
    /// `angle` must be made with the linkage's gears ([`GearedFiveBar::angle_at`]).
    ///
    /// Degenerate cases, part of the contract: `None` where the dyad cannot close (`P` or
    /// `Q` negative beyond [`TOGGLE_ULPS`] ulps of their terms) or where Pa = Pd (d = 0).
    /// At a toggle (h = 0, including a change point) both circuits meet; the pose is
    /// returned with infinite `omega3`/`omega4` and [`GearedPose::velocity`] is `None`.
    ///
    /// ```
    /// use coupler_kinematics::{Circuit, GearAngle, GearRatio, GearedFiveBar, GearedPose};
    /// let g = GearedFiveBar::new(2.0, 2.5, 2.5, 1.0, GearRatio::integer(-1).unwrap(), 180.0).unwrap();
    /// let a = GearAngle::new(g.ratio, g.phase, 30.0);
    /// let p = GearedPose::solve(&g, Circuit::Open, &a).unwrap();
    /// assert!(((p.joint - p.input_pin).norm() - 2.5).abs() < 1e-15);
    /// assert!(((p.joint - p.second_pin).norm() - 2.5).abs() < 1e-15);
    /// // λ = −1, φ = 180°, L5 = 1, L3 = L4: the joint runs on the line x = L1/2.
    /// assert!((p.joint.x - 1.0).abs() < 1e-15);
    /// ```
    pub fn solve(linkage: &GearedFiveBar, circuit: Circuit, angle: &GearAngle) -> Option<Self> {
        GearedPose::solve_with(linkage, &GearedGaps::of(linkage), circuit, angle)
    }

    /// [`GearedPose::solve`] with the linkage's constants computed once.
    pub fn solve_with(
        linkage: &GearedFiveBar,
        gaps: &GearedGaps,
        circuit: Circuit,
        angle: &GearAngle,
    ) -> Option<GearedPose> {
        let c = GearedCore::solve(linkage, gaps, circuit, angle)?;
        let (t2, t5) = (&angle.input, &angle.second);
        let e3 = Vector2::new(c.e_x, c.e_y);
        let e4 = Vector2::new(c.p_x - c.pd_x, c.p_y - c.pd_y) / linkage.l4;
        let va = Vector2::new(-t2.sin, t2.cos);
        let lambda = linkage.ratio.value();
        let vd = Vector2::new(-t5.sin, t5.cos) * (lambda * linkage.l5);
        // ω4 = 2·(Δ·(P − Pa)) / (σ·area4).
        let omega4 = if c.area4 > 0.0 {
            let num = c.dv_x * (c.p_x - t2.cos) + c.dv_y * (c.p_y - t2.sin);
            2.0 * num / (circuit.sign() * c.area4)
        } else {
            f64::INFINITY
        };
        Some(GearedPose {
            input_pin: Point2::new(t2.cos, t2.sin),
            second_pin: Point2::new(c.pd_x, c.pd_y),
            joint: Point2::new(c.p_x, c.p_y),
            link3_dir: e3,
            link4_dir: e4,
            input_pin_velocity: va,
            second_pin_velocity: vd,
            omega3: c.omega,
            omega4,
            transmission: libm::atan2(c.area4, c.cos_term),
        })
    }

    /// The coupler point M = Pa + u·e3 + v·J·e3.
    #[inline]
    pub fn point(&self, p: CouplerPoint) -> Point2<f64> {
        let e = self.link3_dir;
        Point2::new(
            self.input_pin.x + p.u * e.x - p.v * e.y,
            self.input_pin.y + p.u * e.y + p.v * e.x,
        )
    }

    /// The coupler point's velocity for unit input speed,
    /// `V_M = Va + ω3·J·(M − Pa)`; `None` at a toggle (where it is unbounded).
    #[inline]
    pub fn velocity(&self, p: CouplerPoint) -> Option<Vector2<f64>> {
        if !self.omega3.is_finite() {
            return None;
        }
        let e = self.link3_dir;
        let w = self.omega3;
        Some(Vector2::new(
            self.input_pin_velocity.x + w * (-p.u * e.y - p.v * e.x),
            self.input_pin_velocity.y + w * (p.u * e.x - p.v * e.y),
        ))
    }

    /// The loop-closure residual |Pa + L3·e3 − Pd − L4·e4| (a few ulps).
    pub fn loop_residual(&self, linkage: &GearedFiveBar) -> f64 {
        let lhs = self.input_pin + self.link3_dir * linkage.l3;
        let rhs = self.second_pin + self.link4_dir * linkage.l4;
        (lhs - rhs).norm()
    }

    /// True when every field is finite (false at a toggle).
    pub fn is_finite(&self) -> bool {
        self.joint.coords.iter().all(|x| x.is_finite())
            && self.omega3.is_finite()
            && self.omega4.is_finite()
    }
}

impl GearedFiveBar {
    /// The crank angles at input angle `theta2` (degrees) for this linkage's gears.
    pub fn angle_at(&self, theta2: f64) -> GearAngle {
        GearAngle::new(self.ratio, self.phase, theta2)
    }

    /// The pose at input angle `theta2` (degrees) on `circuit` ([`GearedPose::solve`]).
    pub fn pose_at(&self, circuit: Circuit, theta2: f64) -> Option<GearedPose> {
        GearedPose::solve(self, circuit, &self.angle_at(theta2))
    }

    /// The poses at every angle of `table` on `circuit`, as a [`PoseTable`] (input pin,
    /// L3's direction, ω3), the same columns the four-bar's table has: the input crank is
    /// the four-bar's crank (pivot O2, length 1) and the coupler point rides on L3 as on
    /// the four-bar's coupler, so [`PoseTable::trace_into`] traces any coupler point of the
    /// grid with the same loop. Angles where the dyad cannot close are marked invalid
    /// (NaN in the columns, `null` when printed); at a toggle ω3 is infinite and so the
    /// velocity is not finite. `table` must have been made for this linkage's gears
    /// (panics otherwise: a programming error, not an input error).
    pub fn gear_pose_table(&self, circuit: Circuit, table: &GearTable) -> PoseTable {
        assert!(
            table.ratio() == self.ratio && table.phase() == self.phase,
            "gear table for λ = {}, φ = {} used with a linkage of λ = {}, φ = {}",
            table.ratio(),
            table.phase(),
            self.ratio,
            self.phase
        );
        let n = table.len();
        let mut t = PoseTable {
            pa_x: Vec::with_capacity(n),
            pa_y: Vec::with_capacity(n),
            e_x: Vec::with_capacity(n),
            e_y: Vec::with_capacity(n),
            omega: Vec::with_capacity(n),
            valid: Vec::with_capacity(n),
        };
        let gaps = GearedGaps::of(self);
        for a in table.angles() {
            let core = GearedCore::solve(self, &gaps, circuit, a);
            t.pa_x.push(a.input.cos);
            t.pa_y.push(a.input.sin);
            t.valid.push(core.is_some());
            let (e_x, e_y, omega) =
                core.map_or((f64::NAN, f64::NAN, f64::NAN), |c| (c.e_x, c.e_y, c.omega));
            t.e_x.push(e_x);
            t.e_y.push(e_y);
            t.omega.push(omega);
        }
        t
    }

    /// A bound on the rounding error of the coupler point `point` computed by
    /// [`GearedPose::solve`] at `angle` (either circuit), in units of the input crank, or
    /// `None` where the dyad does not assemble. It grows only near a toggle and where Pa
    /// nears Pd, as the problem's own conditioning does:
    ///
    /// `K·ε·S + K·(1 + (|u| + |v|)/L3)·(δh + (|a| + h)·δw/d + ε·(d + |L3² − L4²|/d))`,
    ///
    /// with `S = 1 + L1 + L3 + L4 + L5 + |u| + |v|`, `a` and `h` the chord's foot and
    /// half-chord, `δP`, `δQ`, `δw` the rounding sizes of the thin factors and of w (`ε`
    /// times the magnitudes summed), the half-chord's error
    /// `δh = min(δP·√(Q/P) + δQ·√(P/Q), 2(√(δP·Q) + √(δQ·P)))/(4d)` (the linearised
    /// error, and the bound `|√(x+δ) − √x| ≤ √δ` at the toggle itself), and `K = 8`. Near a
    /// change point the gaps and the terms are all small, so the bound stays at `K·ε·S`.
    pub fn error_bound_at(
        &self,
        gaps: &GearedGaps,
        angle: &GearAngle,
        point: CouplerPoint,
    ) -> Option<f64> {
        const K: f64 = 8.0;
        let eps = f64::EPSILON;
        let f = factors(self, gaps, angle);
        let d2 = f.wx * f.wx + f.wy * f.wy;
        if d2.is_nan() || d2 < f64::MIN_POSITIVE {
            return None;
        }
        let d = d2.sqrt();
        let p = flat(f.p, f.p_scale)?;
        let q = flat(f.q, f.q_scale)?;
        let (dp, dq) = (2.0 * eps * f.p_err, 2.0 * eps * f.q_err);
        let sqrt_form = 2.0 * ((dp * q).sqrt() + (dq * p).sqrt());
        let linear = if p > 0.0 && q > 0.0 {
            dp * (q / p).sqrt() + dq * (p / q).sqrt()
        } else {
            f64::INFINITY
        };
        let dh = linear.min(sqrt_form) / (4.0 * d);
        let h = 0.5 * (p * q).sqrt() / d;
        let spread = (self.l3 - self.l4) * (self.l3 + self.l4);
        let a = 0.5 * (d2 + spread) / d;
        let dw = 2.0 * eps * f.w_err;
        let (u, v) = (point.u.abs(), point.v.abs());
        let s = 1.0 + self.l1 + self.l3 + self.l4 + self.l5 + u + v;
        let joint = dh + (a.abs() + h) * dw / d + eps * (d + spread.abs() / d);
        Some(K * eps * s + K * (1.0 + (u + v) / self.l3) * joint)
    }

    /// The coupler curve of `point` on `circuit` over one period, sampled every `step_deg`
    /// of input (a [`GearTable`] and [`GearedFiveBar::gear_pose_table`] in one call). `None`
    /// for a step that is not in (0, 360].
    pub fn trace(&self, circuit: Circuit, point: CouplerPoint, step_deg: f64) -> Option<Curve> {
        let table = GearTable::for_linkage(self, step_deg)?;
        Some(self.gear_pose_table(circuit, &table).trace(point))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geared::GearRatio;

    fn linkage(l1: f64, l3: f64, l4: f64, l5: f64, n: i64, d: i64, phase: f64) -> GearedFiveBar {
        GearedFiveBar::new(l1, l3, l4, l5, GearRatio::new(n, d).unwrap(), phase).unwrap()
    }

    #[test]
    fn factors_agree_with_direct_formula() {
        let l = linkage(2.3, 2.9, 3.4, 1.7, -3, 2, 41.0);
        let gaps = GearedGaps::of(&l);
        for k in 0..720 {
            let a = GearAngle::new(l.ratio, l.phase, k as f64 * 1.0 + 0.3);
            let f = factors(&l, &gaps, &a);
            let wx = l.l1 + l.l5 * a.second.cos - a.input.cos;
            let wy = l.l5 * a.second.sin - a.input.sin;
            let d2 = wx * wx + wy * wy;
            let p = (l.l3 + l.l4).powi(2) - d2;
            let q = d2 - (l.l3 - l.l4).powi(2);
            assert!(
                (f.wx - wx).abs() < 1e-14 && (f.wy - wy).abs() < 1e-15,
                "{k}"
            );
            assert!((f.p - p).abs() < 1e-13 && (f.q - q).abs() < 1e-13, "{k}");
        }
    }

    #[test]
    fn velocities_match_finite_differences() {
        let p = CouplerPoint::new(1.2, -0.7);
        for l in [
            linkage(2.3, 2.9, 3.4, 1.7, -3, 2, 41.0),
            linkage(1.5, 2.5, 2.0, 0.8, 2, 1, 0.0),
            linkage(2.0, 3.0, 3.0, 1.0, -1, 1, 180.0),
        ] {
            for circuit in [Circuit::Open, Circuit::Crossed] {
                for k in 0..72 {
                    let t = k as f64 * 10.0 + 3.0;
                    let h = 1e-4;
                    let at = |deg: f64| {
                        GearedPose::solve(&l, circuit, &GearAngle::new(l.ratio, l.phase, deg))
                    };
                    let (Some(a), Some(b), Some(c)) = (at(t - h), at(t), at(t + h)) else {
                        continue;
                    };
                    let fd = (c.point(p) - a.point(p)) / (2.0 * h.to_radians());
                    let v = b.velocity(p).unwrap();
                    assert!(
                        (fd - v).norm() < 1e-6 * (1.0 + v.norm()),
                        "{l} {circuit} {t}: {fd} vs {v}"
                    );
                    let phi = |e: Vector2<f64>| libm::atan2(e.y, e.x);
                    let fd4 = (phi(c.link4_dir) - phi(a.link4_dir)) / (2.0 * h.to_radians());
                    assert!((fd4 - b.omega4).abs() < 1e-6 * (1.0 + b.omega4.abs()));
                    let fdd = (c.second_pin - a.second_pin) / (2.0 * h.to_radians());
                    assert!((fdd - b.second_pin_velocity).norm() < 1e-7);
                }
            }
        }
    }

    #[test]
    fn table_matches_single_pose() {
        let l = linkage(2.3, 2.9, 3.4, 1.7, -1, 2, 15.0);
        let table = GearTable::for_linkage(&l, 5.0).unwrap();
        let poses = l.gear_pose_table(Circuit::Crossed, &table);
        let p = CouplerPoint::new(1.5, 2.0);
        let c = poses.trace(p);
        assert_eq!(c.len(), 144);
        let mut valid = 0;
        for (k, a) in table.angles().iter().enumerate() {
            match GearedPose::solve(&l, Circuit::Crossed, a) {
                Some(pose) => {
                    valid += 1;
                    let m = pose.point(p);
                    assert!((c.x[k] - m.x).abs() < 1e-15 && (c.y[k] - m.y).abs() < 1e-15);
                    let v = pose.velocity(p).unwrap();
                    assert!((c.vx[k] - v.x).abs() < 1e-13 && (c.vy[k] - v.y).abs() < 1e-13);
                }
                None => assert!(!c.is_valid(k) && !poses.valid[k]),
            }
        }
        assert!(valid > 0);
    }
}
