//! A candidate curve traced densely by crank angle, with its arc length: the bridge
//! between a shape (arc length) and the kinematics (crank angle).

use crate::geom::{C64, abs};
use crate::kin::CouplerCurve;

/// A closed coupler curve sampled at equal crank steps over the mechanism's period, with
/// the cumulative arc length of the polyline through the samples.
#[derive(Clone, Debug)]
pub(crate) struct Traced {
    /// Samples at θ_k = k·P/n, P the period.
    pub z: Vec<C64>,
    /// Cumulative length: `cum[k]` at sample k, `cum[n]` = the whole loop.
    pub cum: Vec<f64>,
    /// Crank step, degrees.
    pub step: f64,
    /// The mechanism's period P, degrees of input (360 for a four-bar).
    pub period: f64,
}

impl Traced {
    /// Traces `curve` at `n` crank samples per turn (`n·P/360` over its period P);
    /// `None` unless it assembles all round with a positive length.
    pub fn new(curve: &CouplerCurve, n: usize) -> Option<Traced> {
        let period = curve.period_deg();
        let n = n * (period / 360.0).round().max(1.0) as usize;
        let z = curve.sample(n)?;
        let mut cum = Vec::with_capacity(n + 1);
        let mut s = 0.0;
        cum.push(0.0);
        for k in 0..n {
            s += abs(z[(k + 1) % n] - z[k]);
            cum.push(s);
        }
        (s > 0.0 && s.is_finite()).then_some(Traced {
            z,
            cum,
            step: period / n as f64,
            period,
        })
    }

    /// The loop's length.
    pub fn length(&self) -> f64 {
        self.cum[self.z.len()]
    }

    /// The crank angle (degrees, unwrapped: may exceed the period or be negative) at which
    /// the polyline reaches arc length `s` (any real; taken modulo the length, whole loops
    /// adding the period).
    pub fn theta_at(&self, s: f64) -> f64 {
        let len = self.length();
        let turns = (s / len).floor();
        let r = s - turns * len;
        let n = self.z.len();
        // Binary search for the segment.
        let k = match self.cum[..=n].binary_search_by(|c| c.total_cmp(&r)) {
            Ok(k) => k.min(n - 1),
            Err(k) => k.saturating_sub(1).min(n - 1),
        };
        let seg = self.cum[k + 1] - self.cum[k];
        let t = if seg > 0.0 {
            ((r - self.cum[k]) / seg).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (turns * self.period) + (k as f64 + t) * self.step
    }

    /// The point at arc length `s` (modulo the length).
    pub fn point_at(&self, s: f64) -> C64 {
        let len = self.length();
        let r = s - (s / len).floor() * len;
        let n = self.z.len();
        let k = match self.cum[..=n].binary_search_by(|c| c.total_cmp(&r)) {
            Ok(k) => k.min(n - 1),
            Err(k) => k.saturating_sub(1).min(n - 1),
        };
        let seg = self.cum[k + 1] - self.cum[k];
        let t = if seg > 0.0 {
            ((r - self.cum[k]) / seg).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (a, b) = (self.z[k], self.z[(k + 1) % n]);
        a + (b - a) * t
    }

    /// `m` points evenly spaced in arc length round the loop, from arc length 0.
    pub fn resample_closed(&self, m: usize) -> Vec<C64> {
        let len = self.length();
        (0..m)
            .map(|j| self.point_at(len * j as f64 / m as f64))
            .collect()
    }

    /// The point at crank angle `deg` by linear interpolation between samples.
    pub fn point_at_theta(&self, deg: f64) -> C64 {
        let n = self.z.len();
        let x = deg.rem_euclid(self.period) / self.step;
        let k = (x.floor() as usize).min(n - 1);
        let t = x - k as f64;
        let (a, b) = (self.z[k], self.z[(k + 1) % n]);
        a + (b - a) * t
    }
}
