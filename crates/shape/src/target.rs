//! A target path: the ordered points a designer wants a coupler point to follow.

use crate::geom::{C64, diameter};

/// How the points of a target are timed.
#[derive(Clone, Debug, PartialEq)]
pub enum Timing {
    /// Only the path counts: any crank motion that passes the points in order.
    Untimed,
    /// Each point has an input (crank) angle in degrees. The crank reaches point `k` at
    /// `θ_k = θ₀ + σ·(t_k − t₀)`: the offset `θ₀` and the sense `σ = ±1` are free (a motor
    /// turns either way), the travel between points is as given. The angles must be
    /// strictly monotone and span at most the mechanism's period (360° for a four-bar,
    /// `360°·q` for a geared five-bar of gear ratio p/q); a closed target's less than it,
    /// the crank closing the loop over the rest of the period.
    Angles(Vec<f64>),
    /// The points are equally spaced in time, so in crank angle: `θ_k = θ₀ + ω·k` with
    /// a common step `ω` (degrees, either sign). For a closed target the points divide the
    /// curve's period (`|ω| = P/n`: 360°/n on a four-bar, 720°/n on a geared five-bar of
    /// ratio p/2); for an open one `ω` is fitted.
    EqualSteps,
}

impl Timing {
    /// True unless [`Timing::Untimed`].
    pub fn is_timed(&self) -> bool {
        !matches!(self, Timing::Untimed)
    }
}

/// Why a target is unusable. Point indices count from 0.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TargetError {
    /// Too few points to define a shape.
    #[error(
        "{} target needs at least {min} points, got {found}{}",
        if *closed { "a closed" } else { "an open" },
        if *dropped_repeat { " (its last point repeats the first, so it is not counted)" } else { "" }
    )]
    TooFewPoints {
        /// The minimum for this kind of target.
        min: usize,
        /// Points given (after dropping a closed target's repeated first point).
        found: usize,
        /// Whether the target is closed.
        closed: bool,
        /// Whether a closing repeat of the first point was dropped.
        dropped_repeat: bool,
    },
    /// A coordinate or angle is NaN or infinite.
    #[error("point {index}: {field} is not a finite number")]
    NotFinite {
        /// The point.
        index: usize,
        /// `x`, `y` or `angle`.
        field: &'static str,
    },
    /// Every point is the same (the target has no size).
    #[error("all {points} points coincide: the target has no size, so no shape to match")]
    NoSize {
        /// Points given.
        points: usize,
    },
    /// A closed target whose points all lie on one line: a loop with no width.
    #[error(
        "the closed target's points all lie on one line (they stray at most {width:e} from it, over a size of {size:e}): a loop must enclose some area; if the path is a straight run, match it as an open path (--open)"
    )]
    Flat {
        /// The largest distance of a point from the points' line.
        width: f64,
        /// The target's size.
        size: f64,
    },
    /// Timing by angles with a count that differs from the points'.
    #[error("{angles} angles for {points} points")]
    AngleCount {
        /// Angles given.
        angles: usize,
        /// Points given.
        points: usize,
    },
    /// Angles that do not move one way.
    #[error("angles must be strictly monotone: {detail}")]
    BadAngles {
        /// What is wrong, naming the point.
        detail: String,
    },
    /// Angles that span more than the longest period a curve can have.
    #[error(
        "angles span {span}°, but the longest period of the curves is {period}° of input{}: {}",
        if *period == 360.0 { " (one turn)" } else { "" },
        if *closed {
            "a closed target's angles must span less than a period, the crank closing the loop over the rest of it"
        } else {
            "an open path's angles can span at most one period"
        }
    )]
    AngleSpan {
        /// The span of the angles, degrees.
        span: f64,
        /// The longest period allowed, degrees of input.
        period: f64,
        /// Whether the target is closed.
        closed: bool,
    },
}

/// The largest distance of a point of `z` from the line through their centroid along
/// their principal axis (the least-squares line).
fn line_width(z: &[C64]) -> f64 {
    let n = z.len() as f64;
    let m = z.iter().sum::<C64>() / n;
    // Σ (z − m)² (complex square): its argument is twice the principal axis's angle.
    let s: C64 = z.iter().map(|p| (p - m) * (p - m)).sum();
    let axis = if s.norm() > 0.0 {
        (s / s.norm()).sqrt()
    } else {
        C64::new(1.0, 0.0)
    };
    z.iter()
        .map(|p| ((p - m) * axis.conj()).im.abs())
        .fold(0.0, f64::max)
}

/// An ordered list of points in the user's units, open or closed, optionally timed.
///
/// A closed target is a loop: its last point joins its first (do not repeat the first
/// point at the end; [`Target::new`] drops such a repeat). Its **size** is its diameter,
/// the largest distance between two of its points ([`Target::size`]): fit errors are
/// quoted in user units and as a percentage of it.
///
/// ```
/// use coupler_shape::{Target, Timing};
/// let pts = vec![[0.0, 0.0], [3.0, 0.0], [3.0, 4.0], [0.0, 4.0]];
/// let t = Target::new(pts, false, Timing::Untimed).unwrap();
/// assert_eq!(t.size(), 5.0);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Target {
    points: Vec<[f64; 2]>,
    closed: bool,
    timing: Timing,
    size: f64,
}

impl Target {
    /// The smallest number of points of an open target.
    pub const MIN_OPEN: usize = 4;
    /// The smallest number of points of a closed target.
    pub const MIN_CLOSED: usize = 6;

    /// Validates a target: finite coordinates, enough points (at least
    /// [`Target::MIN_OPEN`] open, [`Target::MIN_CLOSED`] closed), a non-zero size, and
    /// for timing by angles one angle per point, strictly monotone, spanning at most 360°
    /// (less than 360° when closed). A closed target whose last point repeats its first
    /// (and, when timed by angles, whose last angle is a full turn from its first) loses
    /// that repeat. For curves of a longer period (a geared five-bar atlas), see
    /// [`Target::with_period`].
    pub fn new(points: Vec<[f64; 2]>, closed: bool, timing: Timing) -> Result<Target, TargetError> {
        Target::with_period(points, closed, timing, 360.0)
    }

    /// [`Target::new`] for curves whose period is at most `period_deg` of input (the
    /// longest of an atlas's mechanisms: 720° on a geared five-bar atlas with λ = −1/2):
    /// angles may span up to it (a closed target's less). Each curve then takes the
    /// timing only if it fits its own period ([`Target::fits_period`]).
    pub fn with_period(
        mut points: Vec<[f64; 2]>,
        closed: bool,
        mut timing: Timing,
        period_deg: f64,
    ) -> Result<Target, TargetError> {
        for (index, p) in points.iter().enumerate() {
            for (field, v) in [("x", p[0]), ("y", p[1])] {
                if !v.is_finite() {
                    return Err(TargetError::NotFinite { index, field });
                }
            }
        }
        if let Timing::Angles(a) = &timing {
            if a.len() != points.len() {
                return Err(TargetError::AngleCount {
                    angles: a.len(),
                    points: points.len(),
                });
            }
            if let Some(index) = a.iter().position(|v| !v.is_finite()) {
                return Err(TargetError::NotFinite {
                    index,
                    field: "angle",
                });
            }
        }
        if points.len() > 1 && points.iter().all(|p| *p == points[0]) {
            return Err(TargetError::NoSize {
                points: points.len(),
            });
        }
        let dropped_repeat = closed && points.len() > 1 && points.first() == points.last();
        if dropped_repeat {
            points.pop();
            if let Timing::Angles(a) = &mut timing {
                a.pop();
            }
        }
        let min = if closed {
            Target::MIN_CLOSED
        } else {
            Target::MIN_OPEN
        };
        if points.len() < min {
            return Err(TargetError::TooFewPoints {
                min,
                found: points.len(),
                closed,
                dropped_repeat,
            });
        }
        if let Timing::Angles(a) = &timing {
            check_angles(a, closed, period_deg)?;
        }
        let z: Vec<C64> = points.iter().map(|p| C64::new(p[0], p[1])).collect();
        let size = diameter(&z);
        if !(size > 0.0 && size.is_finite()) {
            return Err(TargetError::NoSize {
                points: points.len(),
            });
        }
        if closed {
            let width = line_width(&z);
            if width <= 1e-9 * size {
                return Err(TargetError::Flat { width, size });
            }
        }
        Ok(Target {
            points,
            closed,
            timing,
            size,
        })
    }

    /// The points, in order.
    pub fn points(&self) -> &[[f64; 2]] {
        &self.points
    }

    /// The points as complex numbers.
    pub fn complex_points(&self) -> Vec<C64> {
        self.points.iter().map(|p| C64::new(p[0], p[1])).collect()
    }

    /// Whether the path is a loop.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The timing.
    pub fn timing(&self) -> &Timing {
        &self.timing
    }

    /// The number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Never true for a valid target.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// At most `max` of the points, evenly by index (always the first; for an open target
    /// also the last), for quick fits while ranking. Timed targets are returned whole.
    pub fn thinned(&self, max: usize) -> Target {
        let n = self.points.len();
        if self.timing.is_timed() || n <= max || max < 2 {
            return self.clone();
        }
        let last = if self.closed { n } else { n - 1 };
        let keep = if self.closed { max } else { max - 1 };
        let mut idx: Vec<usize> = (0..keep).map(|j| j * last / keep).collect();
        if !self.closed {
            idx.push(n - 1);
        }
        idx.dedup();
        Target {
            points: idx.iter().map(|&i| self.points[i]).collect(),
            closed: self.closed,
            timing: Timing::Untimed,
            size: self.size,
        }
    }

    /// The diameter: the largest distance between two points, in user units.
    pub fn size(&self) -> f64 {
        self.size
    }

    /// The span of the angles, degrees, when timed by angles.
    pub fn angle_span(&self) -> Option<f64> {
        match &self.timing {
            Timing::Angles(a) => Some((a[a.len() - 1] - a[0]).abs()),
            _ => None,
        }
    }

    /// Whether a curve of period `period_deg` can carry the target's timing: always unless
    /// timed by angles, which must span at most the period (a closed target: less).
    pub fn fits_period(&self, period_deg: f64) -> bool {
        self.angle_span()
            .is_none_or(|s| s < period_deg || (!self.closed && s == period_deg))
    }
}

fn check_angles(a: &[f64], closed: bool, period: f64) -> Result<(), TargetError> {
    let rising = a[1] > a[0];
    for k in 1..a.len() {
        let step = a[k] - a[k - 1];
        if step == 0.0 || (step > 0.0) != rising {
            return Err(TargetError::BadAngles {
                detail: format!(
                    "point {k} ({}°) does not continue the motion from point {} ({}°)",
                    a[k],
                    k - 1,
                    a[k - 1]
                ),
            });
        }
    }
    let span = (a[a.len() - 1] - a[0]).abs();
    if span > period || (closed && span >= period) {
        return Err(TargetError::AngleSpan {
            span,
            period,
            closed,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation() {
        let sq = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert!(Target::new(sq.clone(), false, Timing::Untimed).is_ok());
        assert_eq!(
            Target::new(sq.clone(), true, Timing::Untimed),
            Err(TargetError::TooFewPoints {
                min: 6,
                found: 4,
                closed: true,
                dropped_repeat: false
            })
        );
        // A closing repeat is dropped before counting, and the message says so.
        let mut rep = sq.clone();
        rep.push(sq[0]);
        let e = Target::new(rep, true, Timing::Untimed).unwrap_err();
        assert!(e.to_string().contains("repeats the first"), "{e}");
        let mut bad = sq.clone();
        bad[2][1] = f64::NAN;
        assert_eq!(
            Target::new(bad, false, Timing::Untimed),
            Err(TargetError::NotFinite {
                index: 2,
                field: "y"
            })
        );
        assert_eq!(
            Target::new(vec![[1.0, 1.0]; 5], false, Timing::Untimed),
            Err(TargetError::NoSize { points: 5 })
        );
        // Equal points are reported as such, not as too few once the repeat is dropped.
        assert_eq!(
            Target::new(vec![[1.0, 1.0]; 5], true, Timing::Untimed),
            Err(TargetError::NoSize { points: 5 })
        );
        // Collinear: an open straight run is a target; a closed one has no width.
        let line: Vec<[f64; 2]> = (0..8).map(|k| [0.1 * k as f64, 0.3 * k as f64]).collect();
        assert!(Target::new(line.clone(), false, Timing::Untimed).is_ok());
        let e = Target::new(line, true, Timing::Untimed).unwrap_err();
        assert!(matches!(e, TargetError::Flat { .. }), "{e}");
        let t = Target::new(sq.clone(), false, Timing::Angles(vec![0.0, 10.0, 20.0])).unwrap_err();
        assert!(matches!(t, TargetError::AngleCount { .. }));
        let t = Target::new(
            sq.clone(),
            false,
            Timing::Angles(vec![0.0, 10.0, 5.0, 30.0]),
        )
        .unwrap_err();
        assert!(t.to_string().contains("point 2"), "{t}");
        let t = Target::new(
            sq.clone(),
            false,
            Timing::Angles(vec![0.0, 100.0, 200.0, 400.0]),
        )
        .unwrap_err();
        assert!(t.to_string().contains("400"), "{t}");
        // Over a longer period (a geared five-bar atlas's 720°): the same angles pass, and
        // a closed loop may cover up to the period.
        let a = vec![0.0, 100.0, 200.0, 400.0];
        let t = Target::with_period(sq.clone(), false, Timing::Angles(a), 720.0).unwrap();
        assert_eq!(t.angle_span(), Some(400.0));
        assert!(t.fits_period(720.0) && !t.fits_period(360.0));
        let loop6: Vec<[f64; 2]> = (0..6)
            .map(|k| {
                let (s, c) = coupler_kinematics::sincos_deg(60.0 * k as f64);
                [c, s]
            })
            .collect();
        let steps = |last: f64| Timing::Angles(vec![0.0, 120.0, 240.0, 360.0, 480.0, last]);
        let t = Target::with_period(loop6.clone(), true, steps(600.0), 720.0).unwrap();
        assert!(t.fits_period(720.0) && !t.fits_period(360.0));
        let t = Target::with_period(loop6.clone(), true, steps(720.0), 720.0);
        assert!(
            matches!(t, Err(TargetError::AngleSpan { closed: true, .. })),
            "{t:?}"
        );
        let t = Target::with_period(loop6, false, steps(720.0), 720.0).unwrap();
        assert!(t.fits_period(720.0) && !t.fits_period(719.0));
        // A closed loop given with its first point repeated at the end.
        let mut hexagon: Vec<[f64; 2]> = (0..6)
            .map(|k| {
                let (s, c) = coupler_kinematics::sincos_deg(60.0 * k as f64);
                [c, s]
            })
            .collect();
        hexagon.push(hexagon[0]);
        let t = Target::new(hexagon, true, Timing::Untimed).unwrap();
        assert_eq!(t.len(), 6);
        assert!((t.size() - 2.0).abs() < 1e-15);
    }
}
