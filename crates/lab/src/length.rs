//! An independent reference for a coupler curve's arc length: positions only, in
//! double-double, and no velocity or quadrature rule of the product's. The curve is cut
//! into chords, and each piece of input `[a, b]` is measured by its chord polygons of 1,
//! 2 and 4 chords, extrapolated (a chord of a smooth arc of width `h` is short by
//! `c₃h³ + c₅h⁵ + …`, so Richardson's `L₂ + (L₂ − L₁)/3` removes the `h³` term and a
//! second step the `h⁵`). A piece whose two extrapolations differ by more than its share
//! of the tolerance, or whose chords (with the chords just before and after it) turn by
//! more than 30° from one to the next, is halved. The turning test is what catches a cusp
//! or a reversal close to a piece's end, whose tip every chord polygon of the piece
//! misses alike (so the extrapolations agree and are wrong); its piece is halved until
//! it is tiny, as it must be.
//!
//! Not on any hot path (each position costs double-double Taylor series): it exists to
//! check [`coupler_kinematics::ArcLength`].

use coupler_kinematics::Dd;

/// A position of the curve at input angle θ (degrees), or `None` where it does not
/// assemble.
pub type PositionDd<'a> = dyn Fn(f64) -> Option<(Dd, Dd)> + 'a;

/// The reference length of the closed curve `position` over `[0, period_deg)`, with
/// extrapolations agreeing to `rel_tol` (relative, summed over the pieces), and the
/// number of positions evaluated. `None` if the curve fails to assemble somewhere.
pub fn arc_length_dd(position: &PositionDd, period_deg: f64, rel_tol: f64) -> Option<(f64, usize)> {
    let pieces = (period_deg / 1.0).round() as usize;
    let w = period_deg / pieces as f64;
    let mut evals = 0;
    let mut at = |t: f64| {
        evals += 1;
        position(t)
    };
    // A first estimate of the length (the 1° chord polygon) scales the tolerance.
    let pts: Vec<(Dd, Dd)> = (0..=pieces)
        .map(|k| at(k as f64 * w))
        .collect::<Option<_>>()?;
    let rough: f64 = pts.windows(2).map(|p| chord(p[0], p[1])).sum();
    let share = rel_tol * rough / pieces as f64;
    let mut total = 0.0;
    for k in 0..pieces {
        let (a, b) = (k as f64 * w, (k + 1) as f64 * w);
        let m = at(0.5 * (a + b))?;
        let around = [at(a - 0.25 * w)?, at(b + 0.25 * w)?];
        total += piece(&mut at, a, b, [pts[k], m, pts[k + 1]], around, share / w, 0)?;
    }
    Some((total, evals))
}

/// Whether the polyline through `pts` turns by less than 30° at every vertex (a chord of
/// zero length turns nowhere).
fn gentle(pts: &[(Dd, Dd)]) -> bool {
    let d: Vec<(f64, f64)> = pts
        .windows(2)
        .map(|p| ((p[1].0 - p[0].0).to_f64(), (p[1].1 - p[0].1).to_f64()))
        .collect();
    d.windows(2).all(|v| {
        let (n0, n1) = (v[0].0.hypot(v[0].1), v[1].0.hypot(v[1].1));
        n0 == 0.0 || n1 == 0.0 || v[0].0 * v[1].0 + v[0].1 * v[1].1 > 0.866 * n0 * n1
    })
}

/// `|q − p|`, the differences formed in double-double.
fn chord(p: (Dd, Dd), q: (Dd, Dd)) -> f64 {
    let (dx, dy) = ((q.0 - p.0).to_f64(), (q.1 - p.1).to_f64());
    dx.hypot(dy)
}

/// The length over `[a, b]` whose ends and middle are `p`, `around` a point before `a`
/// and one after `b`; `density` is the tolerance per degree.
fn piece(
    at: &mut impl FnMut(f64) -> Option<(Dd, Dd)>,
    a: f64,
    b: f64,
    p: [(Dd, Dd); 3],
    around: [(Dd, Dd); 2],
    density: f64,
    depth: u32,
) -> Option<f64> {
    let m = 0.5 * (a + b);
    let (q1, q3) = (at(0.5 * (a + m))?, at(0.5 * (m + b))?);
    let l1 = chord(p[0], p[2]);
    let l2 = chord(p[0], p[1]) + chord(p[1], p[2]);
    let l4 = chord(p[0], q1) + chord(q1, p[1]) + chord(p[1], q3) + chord(q3, p[2]);
    let r1 = l2 + (l2 - l1) / 3.0;
    let r2 = l4 + (l4 - l2) / 3.0;
    let smooth = gentle(&[around[0], p[0], q1, p[1], q3, p[2], around[1]]);
    if (smooth && (r2 - r1).abs() <= density * (b - a)) || depth >= 40 {
        return Some(r2 + (r2 - r1) / 15.0);
    }
    Some(
        piece(
            at,
            a,
            m,
            [p[0], q1, p[1]],
            [around[0], q3],
            density,
            depth + 1,
        )? + piece(
            at,
            m,
            b,
            [p[1], q3, p[2]],
            [q1, around[1]],
            density,
            depth + 1,
        )?,
    )
}
