//! Measures of a coupler curve over a crank window: how straight, how steady, how round
//! (Norton, *Design of Machinery*, §3.8; docs/conventions.md §5).

use crate::fit::{Circle, CircleFitOptions, LineSums, angle_deg, fit_circle};
use coupler_kinematics::{Circuit, CouplerPoint, CrankAngle, Mechanism};
use serde::Serialize;

/// A crank window `[start, end]` in degrees (`end > start`; it may run past 360°, e.g.
/// `300:420`), sampled every `step` degrees with both ends included. It spans at most the
/// mechanism's period ([`Mechanism::period_deg`]: 360° for a four-bar, 720° for a geared
/// five-bar of gear ratio p/2), checked when it is sampled ([`CrankWindow::within_period`]).
///
/// The samples are `θ_k = start + k·(end − start)/n`, `k = 0..=n`, `n = ⌈(end − start)/step⌉`:
/// exactly every `step` when `step` divides the span (Norton's Table 3-1 uses 2°).
///
/// ```
/// use coupler_features::CrankWindow;
/// let w: CrankWindow = "170:190".parse().unwrap();
/// let w = w.with_step(2.0).unwrap();
/// assert_eq!(w.angles().len(), 11);
/// assert_eq!(w.angles()[10], 190.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CrankWindow {
    /// First angle, degrees.
    pub start_deg: f64,
    /// Last angle, degrees (> start).
    pub end_deg: f64,
    /// Sampling step, degrees.
    pub step_deg: f64,
}

/// The default sampling step of a window, degrees.
pub const DEFAULT_WINDOW_STEP_DEG: f64 = 1.0;

/// Why a window cannot be measured.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WindowError {
    /// Not `START:END` with finite numbers and `END > START`.
    #[error(
        "bad crank window `{0}`: expected START:END in degrees with END > START (e.g. 300:420)"
    )]
    Syntax(String),
    /// The window spans more than the mechanism's period.
    #[error(
        "crank window {start}:{end} spans more than the mechanism's period of {period}° of input"
    )]
    TooLong {
        /// Start, degrees.
        start: f64,
        /// End, degrees.
        end: f64,
        /// The period, degrees.
        period: f64,
    },
    /// The step is not a finite positive number.
    #[error("window step must be a finite number > 0, got {0}")]
    BadStep(f64),
    /// The linkage cannot be assembled somewhere in the window.
    #[error("the linkage does not assemble at θ = {0}°")]
    NotAssembled(f64),
    /// The linkage meets a toggle (infinite velocity) in the window.
    #[error("the linkage is at a toggle at θ = {0}° (infinite velocity)")]
    Toggle(f64),
}

impl CrankWindow {
    /// The window `[start, end]` sampled every `step` degrees. Its span is checked
    /// against a mechanism's period when it is sampled ([`CrankWindow::within_period`]).
    pub fn new(start_deg: f64, end_deg: f64, step_deg: f64) -> Result<CrankWindow, WindowError> {
        if !(start_deg.is_finite() && end_deg.is_finite() && end_deg > start_deg) {
            return Err(WindowError::Syntax(format!("{start_deg}:{end_deg}")));
        }
        if !(step_deg.is_finite() && step_deg > 0.0) {
            return Err(WindowError::BadStep(step_deg));
        }
        Ok(CrankWindow {
            start_deg,
            end_deg,
            step_deg,
        })
    }

    /// `Ok` unless the window spans more than `period_deg` (a mechanism's period: one
    /// window never covers a point of the curve twice).
    pub fn within_period(&self, period_deg: f64) -> Result<(), WindowError> {
        if self.span_deg() > period_deg {
            return Err(WindowError::TooLong {
                start: self.start_deg,
                end: self.end_deg,
                period: period_deg,
            });
        }
        Ok(())
    }

    /// The same window with another step.
    pub fn with_step(self, step_deg: f64) -> Result<CrankWindow, WindowError> {
        CrankWindow::new(self.start_deg, self.end_deg, step_deg)
    }

    /// The span `end − start`, degrees.
    pub fn span_deg(&self) -> f64 {
        self.end_deg - self.start_deg
    }

    /// The sample angles, both ends included.
    pub fn angles(&self) -> Vec<f64> {
        let span = self.span_deg();
        let n = ((span / self.step_deg) - 1e-9).ceil().max(1.0) as usize;
        let h = span / n as f64;
        (0..=n)
            .map(|k| {
                if k == n {
                    self.end_deg
                } else {
                    self.start_deg + k as f64 * h
                }
            })
            .collect()
    }
}

impl std::str::FromStr for CrankWindow {
    type Err = WindowError;
    /// Parses `START:END` (degrees) with the default step [`DEFAULT_WINDOW_STEP_DEG`].
    fn from_str(s: &str) -> Result<CrankWindow, WindowError> {
        let bad = || WindowError::Syntax(s.to_string());
        let (a, b) = s.split_once(':').ok_or_else(bad)?;
        let a: f64 = a.trim().parse().map_err(|_| bad())?;
        let b: f64 = b.trim().parse().map_err(|_| bad())?;
        CrankWindow::new(a, b, DEFAULT_WINDOW_STEP_DEG).map_err(|e| match e {
            WindowError::Syntax(_) => bad(),
            e => e,
        })
    }
}

/// Which line the straightness is measured against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LineDirection {
    /// The orthogonal least-squares line of the samples (the default).
    Fitted,
    /// A given direction (degrees from +x), through the samples' centroid. Norton's
    /// Table 3-1 measures Hoeken linkages against the ground direction (`Given(0.0)`).
    Given(f64),
}

/// Positions and velocities of a coupler point at the angles of a [`CrankWindow`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WindowSamples {
    /// Crank angles, degrees.
    pub theta: Vec<f64>,
    /// x of M.
    pub x: Vec<f64>,
    /// y of M.
    pub y: Vec<f64>,
    /// dx/dθ (θ in radians, unit crank speed).
    pub vx: Vec<f64>,
    /// dy/dθ.
    pub vy: Vec<f64>,
}

impl WindowSamples {
    /// Solves the pose at every angle of the window. Errors where the window spans more
    /// than the mechanism's period, or the linkage does not assemble or sits at a toggle.
    pub fn sample<M: Mechanism>(
        linkage: &M,
        circuit: Circuit,
        point: CouplerPoint,
        window: &CrankWindow,
    ) -> Result<WindowSamples, WindowError> {
        window.within_period(linkage.period_deg())?;
        let mut s = WindowSamples::default();
        let k = linkage.constants();
        for t in window.angles() {
            let pose = linkage
                .frame_with(&k, circuit, &CrankAngle::from_degrees(t))
                .ok_or(WindowError::NotAssembled(t))?;
            let (m, v) = (pose.point(point), pose.velocity(point));
            if !(v.x.is_finite() && v.y.is_finite()) {
                return Err(WindowError::Toggle(t));
            }
            s.theta.push(t);
            s.x.push(m.x);
            s.y.push(m.y);
            s.vx.push(v.x);
            s.vy.push(v.y);
        }
        Ok(s)
    }
}

/// Straightness, steadiness and roundness of a coupler curve over a crank window
/// (docs/conventions.md §5, Norton §3.8).
///
/// With the line through the samples' centroid G along the unit `d` (oriented so that the
/// mean velocity along it is ≥ 0, i.e. the direction of travel) and `n = J·d`:
/// `Cx = (M − G)·d`, `Cy = (M − G)·n`, `Vx = V·d`;
/// - `extent` Δx = max Cx − min Cx;
/// - `straightness_pct` ε_S = (max Cy − min Cy)/Δx · 100;
/// - `velocity_variation_pct` ε_V = (max Vx − min Vx)/mean Vx · 100 (mean over the samples);
/// - `mean_speed` = mean of |V| over the samples (unit crank speed, length per radian);
/// - the geometric circle of the samples ([`fit_circle`]): `arc_center`, `arc_radius`,
///   `arc_deviation_pct` = max |‖M − c‖ − R| / R · 100.
///
/// Degenerate cases: `straightness_pct` is `None` if Δx = 0, `velocity_variation_pct` is
/// `None` if mean Vx = 0, and the arc fields are `None` when the samples are (nearly)
/// collinear (no finite circle). Every number present is finite.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WindowMeasures {
    /// Window start, degrees.
    pub start_deg: f64,
    /// Window end, degrees.
    pub end_deg: f64,
    /// Sampling step, degrees.
    pub step_deg: f64,
    /// Number of samples.
    pub samples: usize,
    /// Direction of the line (direction of travel), degrees in (−180, 180].
    pub direction_deg: f64,
    /// `"fitted"` or `"given"`.
    pub line: &'static str,
    /// Δx, extent along the line.
    pub extent: f64,
    /// ε_S, percent.
    pub straightness_pct: Option<f64>,
    /// ε_V, percent.
    pub velocity_variation_pct: Option<f64>,
    /// Whether the point moves one way along the line (every Vx > 0).
    pub monotone: bool,
    /// Mean |V| over the samples.
    pub mean_speed: f64,
    /// Centre of the best geometric circle.
    pub arc_center: Option<[f64; 2]>,
    /// Its radius.
    pub arc_radius: Option<f64>,
    /// Largest radial deviation / R, percent.
    pub arc_deviation_pct: Option<f64>,
}

impl WindowMeasures {
    /// Measures a linkage's coupler curve over `window`.
    ///
    /// ```
    /// use coupler_kinematics::{FourBar, Circuit, CouplerPoint};
    /// use coupler_features::{CrankWindow, LineDirection, WindowMeasures};
    /// let l = FourBar::new(3.0, 2.0, 3.5).unwrap();
    /// let w = CrankWindow::new(0.0, 90.0, 2.0).unwrap();
    /// let m = WindowMeasures::measure(&l, Circuit::Open, CouplerPoint::new(0.0, 0.0), &w, LineDirection::Fitted).unwrap();
    /// assert!((m.arc_radius.unwrap() - 1.0).abs() < 1e-9); // the crank pin moves on the unit circle
    /// ```
    pub fn measure<M: Mechanism>(
        linkage: &M,
        circuit: Circuit,
        point: CouplerPoint,
        window: &CrankWindow,
        direction: LineDirection,
    ) -> Result<WindowMeasures, WindowError> {
        let s = WindowSamples::sample(linkage, circuit, point, window)?;
        Ok(WindowMeasures::of_samples(&s, window, direction))
    }

    /// Measures already-sampled positions and velocities (see [`WindowSamples`]).
    pub fn of_samples(
        s: &WindowSamples,
        window: &CrankWindow,
        direction: LineDirection,
    ) -> WindowMeasures {
        let n = s.x.len();
        let line = LineMeasures::of(&s.x, &s.y, &s.vx, &s.vy, direction);
        let mean_speed =
            s.vx.iter()
                .zip(&s.vy)
                .map(|(a, b)| a.hypot(*b))
                .sum::<f64>()
                / n.max(1) as f64;
        let arc = fit_circle(&s.x, &s.y, None, &CircleFitOptions::DEFAULT);
        WindowMeasures {
            start_deg: window.start_deg,
            end_deg: window.end_deg,
            step_deg: window.step_deg,
            samples: n,
            direction_deg: line.direction_deg,
            line: match direction {
                LineDirection::Fitted => "fitted",
                LineDirection::Given(_) => "given",
            },
            extent: line.extent,
            straightness_pct: line.straightness_pct(),
            velocity_variation_pct: line.velocity_variation_pct(),
            monotone: line.monotone,
            mean_speed,
            arc_center: arc.map(|c| c.center),
            arc_radius: arc.map(|c| c.radius),
            arc_deviation_pct: arc.map(|c| arc_deviation_pct(&c, &s.x, &s.y)),
        }
    }
}

/// `max |‖M − c‖ − R| / R · 100` over the points.
pub fn arc_deviation_pct(c: &Circle, xs: &[f64], ys: &[f64]) -> f64 {
    c.max_deviation(xs, ys) / c.radius * 100.0
}

/// The line measures of a set of samples (see [`WindowMeasures`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineMeasures {
    /// Centroid of the samples.
    pub centroid: [f64; 2],
    /// Unit direction of travel along the line.
    pub direction: [f64; 2],
    /// Its angle, degrees.
    pub direction_deg: f64,
    /// Δx.
    pub extent: f64,
    /// max Cy − min Cy.
    pub width: f64,
    /// min Cx, max Cx (the segment's ends along the line, from the centroid).
    pub cx_range: [f64; 2],
    /// max Vx − min Vx.
    pub vx_range: f64,
    /// Mean Vx (≥ 0).
    pub mean_vx: f64,
    /// Every Vx > 0.
    pub monotone: bool,
}

impl LineMeasures {
    /// Measures positions `(xs, ys)` and velocities `(vxs, vys)` against a line.
    pub fn of(
        xs: &[f64],
        ys: &[f64],
        vxs: &[f64],
        vys: &[f64],
        direction: LineDirection,
    ) -> LineMeasures {
        let mut sums = LineSums::new([
            xs.first().copied().unwrap_or(0.0),
            ys.first().copied().unwrap_or(0.0),
        ]);
        for (&x, &y) in xs.iter().zip(ys) {
            sums.add(x, y);
        }
        let (g, d) = sums.line().unwrap_or(([0.0, 0.0], [1.0, 0.0]));
        let d = match direction {
            LineDirection::Fitted => d,
            LineDirection::Given(deg) => {
                let (s, c) = coupler_kinematics::sincos_deg(deg);
                [c, s]
            }
        };
        LineMeasures::against(xs, ys, vxs, vys, g, d)
    }

    /// Measures against the line through `g` along the unit `d` (re-oriented along travel).
    pub fn against(
        xs: &[f64],
        ys: &[f64],
        vxs: &[f64],
        vys: &[f64],
        g: [f64; 2],
        d: [f64; 2],
    ) -> LineMeasures {
        let n = xs.len().max(1) as f64;
        let mean_v: f64 = vxs
            .iter()
            .zip(vys)
            .map(|(a, b)| a * d[0] + b * d[1])
            .sum::<f64>()
            / n;
        let d = if mean_v < 0.0 { [-d[0], -d[1]] } else { d };
        let nrm = [-d[1], d[0]];
        let (mut cx0, mut cx1, mut cy0, mut cy1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        let (mut v0, mut v1, mut vs) = (f64::MAX, f64::MIN, 0.0);
        for k in 0..xs.len() {
            let (px, py) = (xs[k] - g[0], ys[k] - g[1]);
            let cx = px * d[0] + py * d[1];
            let cy = px * nrm[0] + py * nrm[1];
            let vx = vxs[k] * d[0] + vys[k] * d[1];
            cx0 = cx0.min(cx);
            cx1 = cx1.max(cx);
            cy0 = cy0.min(cy);
            cy1 = cy1.max(cy);
            v0 = v0.min(vx);
            v1 = v1.max(vx);
            vs += vx;
        }
        LineMeasures {
            centroid: g,
            direction: d,
            direction_deg: angle_deg(d),
            extent: cx1 - cx0,
            width: cy1 - cy0,
            cx_range: [cx0, cx1],
            vx_range: v1 - v0,
            mean_vx: vs / n,
            monotone: v0 > 0.0,
        }
    }

    /// ε_S in percent, `None` if the extent is zero.
    pub fn straightness_pct(&self) -> Option<f64> {
        let e = self.width / self.extent * 100.0;
        (self.extent > 0.0 && e.is_finite()).then_some(e)
    }

    /// ε_V in percent, `None` if the mean velocity along the line is zero.
    pub fn velocity_variation_pct(&self) -> Option<f64> {
        let e = self.vx_range / self.mean_vx * 100.0;
        (self.mean_vx > 0.0 && e.is_finite()).then_some(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::FourBar;

    /// Rounds to `sig` significant digits.
    fn sig(x: f64, digits: i32) -> f64 {
        let p = 10f64.powi(digits - 1 - x.abs().log10().floor() as i32);
        (x * p).round() / p
    }

    /// Norton, *Design of Machinery*, Table 3-1 (docs/conventions.md §8): Hoeken linkages, point
    /// (2A, 0), open, window 180 ± Δβ/2 every 2°, line = ground direction.
    #[test]
    fn norton_table_3_1() {
        // (C, A=B, Δβ, Δx, ε_S %, ε_V %, significant digits printed for ε_S and ε_V).
        let rows = [
            (2.975, 3.9625, 20.0, 0.6013, 0.0000104, 0.3775, 3, 4),
            (2.625, 3.4375, 120.0, 3.2380, 0.01031, 14.684, 4, 5),
            (1.825, 2.2375, 120.0, 2.5999, 0.7521, 1.8845, 4, 5),
        ];
        for (c, a, beta, dx, es, ev, sig_s, sig_v) in rows {
            let l = FourBar::new(a, a, c).unwrap();
            let w = CrankWindow::new(180.0 - beta / 2.0, 180.0 + beta / 2.0, 2.0).unwrap();
            let p = CouplerPoint::new(2.0 * a, 0.0);
            let m = WindowMeasures::measure(&l, Circuit::Open, p, &w, LineDirection::Given(0.0))
                .unwrap();
            // Δx printed with 4 decimals.
            assert_eq!(
                (m.extent * 1e4).round() / 1e4,
                dx,
                "Δx row C={c}: {}",
                m.extent
            );
            let got_es = m.straightness_pct.unwrap();
            let got_ev = m.velocity_variation_pct.unwrap();
            assert_eq!(sig(got_es, sig_s), es, "ε_S row C={c}: {got_es}");
            assert_eq!(sig(got_ev, sig_v), ev, "ε_V row C={c}: {got_ev}");
            assert!(m.monotone);
        }
    }

    #[test]
    fn rocker_pin_moves_on_circle_about_o4() {
        for (a, b, c) in [(3.0, 2.0, 3.5), (2.5, 2.5, 2.0), (4.0, 3.0, 5.5)] {
            let l = FourBar::new(a, b, c).unwrap();
            for circuit in [Circuit::Open, Circuit::Crossed] {
                let w = CrankWindow::new(300.0, 420.0, 5.0).unwrap();
                let m = WindowMeasures::measure(
                    &l,
                    circuit,
                    CouplerPoint::new(a, 0.0),
                    &w,
                    LineDirection::Fitted,
                )
                .unwrap();
                let cen = m.arc_center.unwrap();
                assert!((cen[0] - c).abs() < 1e-9 && cen[1].abs() < 1e-9, "{cen:?}");
                assert!((m.arc_radius.unwrap() - b).abs() < 1e-9);
                assert!(m.arc_deviation_pct.unwrap() < 1e-9);
            }
        }
    }

    #[test]
    fn crank_pin_is_unit_circle() {
        let l = FourBar::new(3.0, 2.5, 3.5).unwrap();
        let w = CrankWindow::new(10.0, 370.0, 10.0).unwrap();
        let m = WindowMeasures::measure(
            &l,
            Circuit::Crossed,
            CouplerPoint::new(0.0, 0.0),
            &w,
            LineDirection::Fitted,
        )
        .unwrap();
        let cen = m.arc_center.unwrap();
        assert!(cen[0].abs() < 1e-12 && cen[1].abs() < 1e-12);
        assert!((m.arc_radius.unwrap() - 1.0).abs() < 1e-12);
        assert!((m.mean_speed - 1.0).abs() < 1e-14);
    }

    #[test]
    fn window_parsing_and_wrap() {
        let w: CrankWindow = "300:420".parse().unwrap();
        let a = w.with_step(30.0).unwrap().angles();
        assert_eq!(a, vec![300.0, 330.0, 360.0, 390.0, 420.0]);
        assert!("420:300".parse::<CrankWindow>().is_err());
        // Longer than a turn parses; a four-bar's period refuses it, a 720° one does not.
        let long: CrankWindow = "0:400".parse().unwrap();
        assert!(matches!(
            long.within_period(360.0),
            Err(WindowError::TooLong { period: 360.0, .. })
        ));
        assert!(long.within_period(720.0).is_ok());
        let l = coupler_kinematics::FourBar::new(3.0, 2.5, 3.0).unwrap();
        assert!(matches!(
            WindowSamples::sample(&l, Circuit::Open, CouplerPoint::new(1.0, 1.0), &long),
            Err(WindowError::TooLong { .. })
        ));
        assert!("abc".parse::<CrankWindow>().is_err());
        let odd = CrankWindow::new(0.0, 10.0, 3.0).unwrap().angles();
        assert_eq!(odd.len(), 5);
        assert_eq!(*odd.last().unwrap(), 10.0);
    }
}
