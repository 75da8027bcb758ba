//! The overlay picture of a match: the target's points, the matched coupler curve dashed
//! by crank angle (one dash per 10° of crank, as on the atlas pages), a whisker from each
//! target point to the curve point it was matched to (the error, drawn to scale), and the
//! linkage drawn in place at the first target point, in the user's frame. Pure: a display
//! list for `coupler-render` (PNG or SVG).

use crate::fit::CurveFit;
use crate::geom::C64;
use crate::kin::CouplerCurve;
use crate::target::Target;
use coupler_kinematics::{CouplerPoint, CrankAngle, DashPattern, Mechanism};
use coupler_layout::{Anchor, DisplayList, PagePoint, Primitive};

/// What to say about the match in the picture's heading.
#[derive(Clone, Debug, PartialEq)]
pub struct OverlayText {
    /// First line (what was matched).
    pub title: String,
    /// Second line (the error, the placement).
    pub detail: String,
}

/// Page size of the overlay, points (8 × 7 in).
pub const OVERLAY_SIZE_PT: [f64; 2] = [576.0, 504.0];

/// The overlay of `fit` (a fit of `curve` to `target`) as a display list of
/// [`OVERLAY_SIZE_PT`]; `None` if the curve cannot be traced.
pub fn overlay(
    target: &Target,
    curve: &CouplerCurve,
    fit: &CurveFit,
    text: &OverlayText,
) -> Option<DisplayList> {
    let a = C64::new(fit.a[0], fit.a[1]);
    let b = C64::new(fit.b[0], fit.b[1]);
    // Atlas frame → user frame.
    let user = |z: C64| a * if fit.mirrored { z.conj() } else { z } + b;
    let dash = DashPattern::default();
    // The curve at 0.5° steps, user frame; dashes of `fraction · step` every `step`.
    let sub = 20usize;
    let per = dash.step_deg / sub as f64;
    let n = (curve.period_deg() / per).round() as usize;
    let mut samples = Vec::with_capacity(n + 1);
    for k in 0..=n {
        samples.push(user(curve.at(k as f64 * per)?.m));
    }
    let drawn = ((dash.fraction * sub as f64).round() as usize).max(1);
    let matched: Vec<C64> = fit
        .theta_deg
        .iter()
        .map(|&t| curve.at(t).map(|p| user(p.m)))
        .collect::<Option<_>>()?;
    let pts: Vec<C64> = target.complex_points();
    let first = *fit.theta_deg.first()?;
    let drawing = curve
        .linkage
        .drawing(curve.circuit, &CrankAngle::from_degrees(first));
    let frame = drawing.coupler?;
    let c2 = |p: nalgebra::Point2<f64>| C64::new(p.x, p.y);
    let joints: Vec<(C64, bool)> = drawing
        .joints
        .iter()
        .map(|j| (user(c2(j.position)), j.ground))
        .collect();
    // The coupler body: from the input crank's pin along its link (to the rocker pin of a
    // four-bar, to the dyad joint of a five-bar), and the coupler point on it.
    let pa = user(c2(frame.origin));
    let pb = user(c2(
        frame.point(CouplerPoint::new(curve.linkage.coupler_length(), 0.0))
    ));
    let m = user(c2(frame.point(curve.point)));

    // World box of everything drawn, then a uniform scale into the plot area (y up).
    let [w, h] = OVERLAY_SIZE_PT;
    let (left, right, top, bottom) = (36.0, w - 36.0, 84.0, h - 48.0);
    let linkage: Vec<C64> = joints.iter().map(|j| j.0).chain([m]).collect();
    let all = samples.iter().chain(&pts).chain(linkage.iter());
    let (mut x0, mut y0, mut x1, mut y1) = (
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    );
    for z in all {
        x0 = x0.min(z.re);
        x1 = x1.max(z.re);
        y0 = y0.min(z.im);
        y1 = y1.max(z.im);
    }
    let span = (x1 - x0).max(y1 - y0);
    if !(span > 0.0 && span.is_finite()) {
        return None;
    }
    let s = ((right - left) / (x1 - x0).max(1e-12 * span))
        .min((bottom - top) / (y1 - y0).max(1e-12 * span));
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let (px, py) = (0.5 * (left + right), 0.5 * (top + bottom));
    let page = |z: C64| -> PagePoint { [px + s * (z.re - cx), py - s * (z.im - cy)] };

    let mut d = DisplayList::new(w, h);
    // Heading.
    d.items.push(Primitive::Text {
        pos: [36.0, 34.0],
        size: 10.5,
        anchor: Anchor::Start,
        text: text.title.clone(),
        halo: 0.0,
    });
    d.items.push(Primitive::Text {
        pos: [36.0, 52.0],
        size: 9.5,
        anchor: Anchor::Start,
        text: text.detail.clone(),
        halo: 0.0,
    });
    // The curve, dashed by crank angle.
    let mut dashes = Vec::new();
    for k in 0..(n / sub) {
        let from = k * sub;
        dashes.push((from..=from + drawn).map(|j| page(samples[j])).collect());
    }
    d.items.push(Primitive::Polylines {
        lines: dashes,
        width: 1.0,
    });
    // The linkage in place at the first target point: its links, the coupler triangle to
    // the coupler point, ground pivots and moving joints.
    d.items.push(Primitive::Polylines {
        lines: drawing
            .links
            .iter()
            .map(|&[i, j]| vec![page(joints[i].0), page(joints[j].0)])
            .collect(),
        width: 2.0,
    });
    d.items.push(Primitive::Polyline {
        points: vec![page(pa), page(m), page(pb)],
        width: 1.2,
    });
    for p in joints.iter().filter(|j| j.1).map(|j| j.0) {
        let [x, y] = page(p);
        d.items.push(Primitive::Polygon {
            points: vec![[x, y], [x - 6.0, y + 10.0], [x + 6.0, y + 10.0]],
        });
        d.items.push(Primitive::Polyline {
            points: vec![[x - 9.0, y + 10.0], [x + 9.0, y + 10.0]],
            width: 1.0,
        });
    }
    for p in joints.iter().filter(|j| !j.1).map(|j| j.0) {
        d.items.push(Primitive::Circle {
            center: page(p),
            radius: 2.5,
            width: Some(1.0),
        });
    }
    d.items.push(Primitive::Circle {
        center: page(m),
        radius: 2.0,
        width: None,
    });
    // Target points (rings) and the error whiskers to their matched curve points.
    let whiskers: Vec<Vec<PagePoint>> = pts
        .iter()
        .zip(&matched)
        .map(|(p, q)| vec![page(*p), page(*q)])
        .collect();
    d.items.push(Primitive::Polylines {
        lines: whiskers,
        width: 0.6,
    });
    for p in &pts {
        d.items.push(Primitive::Circle {
            center: page(*p),
            radius: 2.2,
            width: Some(0.6),
        });
    }
    // Legend and scale.
    let bar = nice_length(0.25 * (right - left) / s);
    let y = h - 30.0;
    d.items.push(Primitive::Polyline {
        points: vec![[w - 36.0 - s * bar, y], [w - 36.0, y]],
        width: 1.5,
    });
    d.items.push(Primitive::Text {
        pos: [w - 36.0 - 0.5 * s * bar, y - 5.0],
        size: 8.5,
        anchor: Anchor::Middle,
        text: format!("{} user units", fmt_short(bar)),
        halo: 0.0,
    });
    d.items.push(Primitive::Text {
        pos: [36.0, h - 12.0],
        size: 8.0,
        anchor: Anchor::Start,
        text: "rings: target points · ticks: error to the matched point · dashes: the curve, one per 10° of crank · bold: the linkage at the first point".into(),
        halo: 0.0,
    });
    Some(d)
}

/// 1, 2 or 5 × a power of ten, at most `x`.
fn nice_length(x: f64) -> f64 {
    let p = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|k| k * p)
        .find(|&v| v <= x)
        .unwrap_or(p)
}

fn fmt_short(x: f64) -> String {
    let s = format!("{x:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_lengths() {
        assert_eq!(nice_length(7.3), 5.0);
        assert_eq!(nice_length(0.031), 0.02);
        assert_eq!(nice_length(100.0), 100.0);
        assert_eq!(fmt_short(0.5), "0.5");
        assert_eq!(fmt_short(20.0), "20");
    }
}
