//! The geared five-bar's kinematics against independent formulations: a double-double
//! reference, loop closure, finite differences; near Class III change points (lengths
//! moved by ±1e-6, 1e-9, 1e-12 across one); property tests that like nearly equal
//! lengths; exact class decisions on half-unit grids; the geared five-bar equivalent of a
//! four-bar tracing its whole coupler curve; the exact straight line.

use coupler_atlas::{
    Circuit, CouplerPoint, FourBar, GearAngle, GearRatio, GearTable, GearedEquivalent,
    GearedFiveBar, GearedGaps, GearedPose, MARGIN_STEP_DEG, MARGIN_TOL, Rotatability, TingClass,
    geared_equivalent,
};
use coupler_atlas::{circle_intersections, trace_full};
use coupler_lab::{geared_point_dd, joints_dd};
use nalgebra::Point2;
use proptest::prelude::*;

fn ratio(n: i64, d: i64) -> GearRatio {
    GearRatio::new(n, d).unwrap()
}

fn five(l1: f64, l3: f64, l4: f64, l5: f64, n: i64, d: i64, phase: f64) -> GearedFiveBar {
    GearedFiveBar::new(l1, l3, l4, l5, ratio(n, d), phase).unwrap()
}

/// Largest distance between the core's coupler point and the double-double reference
/// over `angles`, both circuits; the largest ratio of that error to
/// [`GearedFiveBar::error_bound_at`]; and how many samples assembled. Where exactly one of
/// them assembles, the margin must be within rounding of zero (a toggle).
fn against_reference(
    g: &GearedFiveBar,
    points: &[CouplerPoint],
    angles: impl Iterator<Item = f64> + Clone,
) -> (f64, f64, usize) {
    let gaps = GearedGaps::of(g);
    let (mut worst, mut ratio, mut n) = (0.0f64, 0.0f64, 0);
    for circuit in [Circuit::Open, Circuit::Crossed] {
        for deg in angles.clone() {
            let angle = GearAngle::new(g.ratio, g.phase, deg);
            let pose = GearedPose::solve_with(g, &gaps, circuit, &angle);
            let reference = joints_dd(g, circuit, deg);
            let (Some(pose), Some(_)) = (pose, reference) else {
                // Only within rounding of a toggle may one of them assemble and not the other.
                let margin = g.margin_at(&gaps, deg);
                assert!(
                    pose.is_none() == reference.is_none() || margin.abs() < 1e-12,
                    "{g} {circuit} θ={deg}: core {} reference {}, margin {margin:e}",
                    pose.is_some(),
                    reference.is_some()
                );
                continue;
            };
            n += 1;
            for &p in points {
                let m = pose.point(p);
                let (rx, ry) = geared_point_dd(g, circuit, p, deg).expect("assembles");
                let err = (m.x - rx.to_f64()).abs().max((m.y - ry.to_f64()).abs());
                let bound = g.error_bound_at(&gaps, &angle, p).expect("assembles");
                worst = worst.max(err);
                ratio = ratio.max(err / bound);
            }
        }
    }
    (worst, ratio, n)
}

// ---------------------------------------------------------------------------------------
// Accuracy

/// Geared five-bars over lengths in 0.5 … 4 and every gear ratio the atlas issue names
/// (−1, −2, +2, −1/2) and a few more, phases on and off the quadrants: every kind, those
/// that turn fully and those that rock between toggles.
fn spread() -> Vec<GearedFiveBar> {
    let mut v = Vec::new();
    let lengths = [
        (2.0, 2.5, 3.0, 1.0),
        (3.0, 3.5, 2.5, 1.5),
        (1.5, 3.0, 3.0, 0.5),
        (3.0, 3.0, 3.0, 1.0),
        (2.5, 3.5, 2.0, 0.75),
        (4.0, 2.5, 3.5, 2.0),
        (1.0, 2.0, 2.5, 1.5),
    ];
    for (n, d) in [(-1, 1), (-2, 1), (2, 1), (-1, 2), (1, 1), (3, 2), (-2, 3)] {
        for phase in [0.0, 90.0, 180.0, 37.5] {
            for (l1, l3, l4, l5) in lengths {
                v.push(five(l1, l3, l4, l5, n, d, phase));
            }
        }
    }
    v
}

/// "Ordinary": the input turns fully and the dyad stays clear of toggles and of Pa = Pd
/// by half a crank length (margin ≥ 0.5), as the four-bar atlas's crank-rockers do. (Near
/// Pa = Pd with L3 = L4 the joint's direction is set by the short vector Pd − Pa, whose
/// rounding it amplifies by L3/d: the problem's conditioning, which the error bound
/// covers.)
fn ordinary() -> Vec<GearedFiveBar> {
    spread()
        .into_iter()
        .filter(|g| g.assembly_margin(MARGIN_STEP_DEG).min >= 0.5)
        .collect()
}

fn grid_points(g: &GearedFiveBar) -> [CouplerPoint; 4] {
    [
        CouplerPoint::new(0.5 * g.l3, 0.5 * g.l3),
        g.joint_point(),
        CouplerPoint::new(-0.25 * g.l3, -g.l3),
        CouplerPoint::new(1.5 * g.l3, g.l3),
    ]
}

#[test]
fn positions_agree_with_double_double_on_ordinary_linkages() {
    let linkages = ordinary();
    assert!(linkages.len() >= 40, "{} ordinary linkages", linkages.len());
    let mut worst = 0.0f64;
    let mut samples = 0;
    for g in linkages {
        let period = g.period_deg();
        let angles = (0..(period / 2.5) as usize).map(|k| k as f64 * 2.5 + 0.3);
        let (w, _, n) = against_reference(&g, &grid_points(&g), angles);
        assert_eq!(
            n,
            2 * (period / 2.5) as usize,
            "{g}: every sample assembles"
        );
        worst = worst.max(w);
        samples += n;
    }
    assert!(samples > 20_000, "only {samples} samples");
    eprintln!("ordinary linkages: worst position error {worst:.2e} over {samples} samples");
    assert!(worst <= 1e-14, "worst position error {worst:e} crank units");
}

/// Every linkage of the spread, including those that rock between toggles and pass
/// near Pa = Pd, sampled on a grid and densely (10⁻¹ … 10⁻¹²°) around the angle of
/// smallest margin: the error never exceeds the documented bound.
#[test]
fn positions_within_the_error_bound_everywhere() {
    let mut ratio = 0.0f64;
    for g in spread() {
        let at = g.assembly_margin(MARGIN_STEP_DEG).at_degrees;
        let angles = (0..(g.period_deg() / 2.5) as usize)
            .map(|k| k as f64 * 2.5 + 0.3)
            .chain((1..=12).flat_map(move |k| [at - 10f64.powi(-k), at + 10f64.powi(-k)]));
        let (_, r, _) = against_reference(&g, &grid_points(&g), angles);
        ratio = ratio.max(r);
    }
    eprintln!("largest error / bound: {ratio:.3}");
    assert!(ratio <= 1.0, "error exceeds its bound by {ratio}");
}

#[test]
fn loop_closes_and_circuit_sign_holds() {
    let ordinary = ordinary();
    for g in spread() {
        let gaps = GearedGaps::of(&g);
        let table = GearTable::for_linkage(&g, 5.0).unwrap();
        for a in table.angles() {
            for circuit in [Circuit::Open, Circuit::Crossed] {
                let Some(p) = GearedPose::solve(&g, circuit, a) else {
                    continue;
                };
                // 1e-14 on ordinary linkages; elsewhere within the joint's error bound
                // (twice: both ends of a link), which grows near toggles and Pa = Pd.
                let tol = if ordinary.contains(&g) {
                    1e-14
                } else {
                    2.0 * g.error_bound_at(&gaps, a, g.joint_point()).unwrap()
                };
                let residual = p.loop_residual(&g);
                assert!(residual < tol, "{g}: residual {residual:e} > {tol:e}");
                assert!(((p.joint - p.input_pin).norm() - g.l3).abs() < tol);
                assert!(((p.joint - p.second_pin).norm() - g.l4).abs() < tol);
                assert!(((p.second_pin - g.o5()).norm() - g.l5).abs() < 1e-15);
                let (w, r) = (p.second_pin - p.input_pin, p.joint - p.input_pin);
                let cross = w.x * r.y - w.y * r.x;
                if p.is_finite() {
                    assert_eq!(
                        cross.signum(),
                        circuit.sign(),
                        "{g} {circuit} θ={}",
                        a.input.degrees
                    );
                }
                // Transmission angle: the law of cosines at P.
                let d2 = w.norm_squared();
                let cos_mu = (g.l3 * g.l3 + g.l4 * g.l4 - d2) / (2.0 * g.l3 * g.l4);
                assert!((p.transmission.cos() - cos_mu).abs() < 1e-12);
            }
        }
    }
}

/// Mirror identity (as for the four-bar): reflecting the linkage in the ground line maps
/// the open curve of (u, v) at θ2 with phase φ onto the crossed curve of (u, −v) at −θ2
/// with phase −φ (θ5 = λ·θ2 + φ turns into −θ5).
#[test]
fn mirror_identity_holds_to_the_bit() {
    for g in spread().into_iter().step_by(5) {
        let m = GearedFiveBar {
            phase: -g.phase,
            ..g
        };
        for (u, v) in [(1.0, 0.7), (-0.5, -1.3), (g.l3, 0.0)] {
            for k in 0..(g.period_deg() / 10.0) as usize {
                let deg = k as f64 * 10.0 + 3.5;
                let open =
                    GearedPose::solve(&g, Circuit::Open, &GearAngle::new(g.ratio, g.phase, deg));
                let crossed = GearedPose::solve(
                    &m,
                    Circuit::Crossed,
                    &GearAngle::new(m.ratio, m.phase, -deg),
                );
                assert_eq!(open.is_some(), crossed.is_some(), "{g} θ={deg}");
                let (Some(open), Some(crossed)) = (open, crossed) else {
                    continue;
                };
                let a = open.point(CouplerPoint::new(u, v));
                let b = crossed.point(CouplerPoint::new(u, -v));
                assert_eq!((a.x, a.y), (b.x, -b.y), "{g} ({u},{v}) θ={deg}");
            }
        }
    }
}

#[test]
fn velocities_agree_with_finite_differences() {
    // Central differences of the double-double positions, step h = 2⁻¹⁷° so that θ ± h
    // are exact floats (a rounded step would cost ~1e-9 relative), truncation error
    // ~h²·|M'''|/6; away from toggles, where the velocity is unbounded.
    let mut worst = 0.0f64;
    for g in ordinary().into_iter().step_by(3) {
        let p = CouplerPoint::new(1.3, -0.4);
        for circuit in [Circuit::Open, Circuit::Crossed] {
            for k in 0..(g.period_deg() / 7.0) as usize {
                let deg = k as f64 * 7.0 + 0.5;
                let Some(pose) =
                    GearedPose::solve(&g, circuit, &GearAngle::new(g.ratio, g.phase, deg))
                else {
                    continue;
                };
                if pose.transmission.sin() < 0.05 {
                    continue; // near a toggle
                }
                let h = 2f64.powi(-17);
                let m = |t: f64| geared_point_dd(&g, circuit, p, t);
                let (Some(a), Some(b)) = (m(deg - h), m(deg + h)) else {
                    continue;
                };
                let fd = nalgebra::Vector2::new((b.0 - a.0).to_f64(), (b.1 - a.1).to_f64())
                    / (2.0 * h.to_radians());
                let v = pose.velocity(p).expect("finite away from toggles");
                worst = worst.max((fd - v).norm() / (1.0 + v.norm()));
            }
        }
    }
    eprintln!("velocities: worst relative difference from finite differences {worst:.2e}");
    assert!(worst < 1e-12, "worst relative velocity error {worst:e}");
}

// ---------------------------------------------------------------------------------------
// Near the edge: Class III change points

/// Class III linkages whose gear path passes through the flat configuration, and a length
/// that moves them across it: `(linkage at the change point, which length, angle of the
/// flat configuration)`.
fn change_points() -> Vec<(GearedFiveBar, &'static str, f64)> {
    vec![
        // Sorted 1, 1, 2.1, 2.4, 2.5: 1 + 1 + 2.5 = 2.1 + 2.4; λ = −1, φ = 180°: at
        // θ2 = 180° Pa = (−1, 0), Pd = (3.5, 0), d = 4.5 = L3 + L4 (dyad stretched out).
        (five(2.5, 2.1, 2.4, 1.0, -1, 1, 180.0), "L4", 180.0),
        // λ = 2, φ = 0: θ2 = 180° gives θ5 = 360°, the same flat configuration.
        (five(2.5, 2.1, 2.4, 1.0, 2, 1, 0.0), "L4", 180.0),
        // Folded: sorted 0.5, 1, 2, 3, 3.5: 0.5 + 1 + 3.5 = 2 + 3. λ = −1/2, φ = 180°: at
        // θ2 = 0 (and 720°) θ5 = 180°, Pa = (1, 0), Pd = (2.5, 0), d = 1.5 = L3 − L4
        // (dyad folded onto itself).
        (five(3.0, 3.5, 2.0, 0.5, -1, 2, 180.0), "L3", 0.0),
    ]
}

fn moved(g: &GearedFiveBar, which: &str, by: f64) -> GearedFiveBar {
    let mut m = *g;
    match which {
        "L3" => m.l3 += by,
        "L4" => m.l4 += by,
        _ => unreachable!(),
    }
    m
}

#[test]
fn change_point_fixtures_are_class_three_and_flat_on_the_path() {
    for (g, _, flat) in change_points() {
        assert_eq!(g.ting_class(), TingClass::III, "{g}");
        let m = g.margin_at(&GearedGaps::of(&g), flat);
        assert!(m.abs() < 1e-15, "{g}: margin {m:e} at {flat}");
    }
}

/// Lengths moved by ±1e-6, 1e-9, 1e-12 across a Class III change point: no NaN, the
/// circuit sign never jumps, positions within 1e-14 of double-double (dense around the
/// flat configuration), and on the side where the gap opens the dyad assembles at every
/// angle.
#[test]
fn stable_across_class_three_change_points() {
    for (g0, which, flat) in change_points() {
        for gap in [1e-6, 1e-9, 1e-12, 0.0, -1e-12, -1e-9, -1e-6] {
            let g = moved(&g0, which, gap);
            let points = [
                g.joint_point(),
                CouplerPoint::new(1.5, 1.0),
                CouplerPoint::new(-1.0, -2.0),
            ];
            let period = g.period_deg();
            let angles = (0..period as usize)
                .map(|k| k as f64)
                .chain((-1000..=1000).map(move |k| flat + k as f64 * 1e-3))
                .chain((-30..=30).map(move |k| flat + k as f64 * 1e-9));
            let (worst, _, n) = against_reference(&g, &points, angles.clone());
            eprintln!("change point {which} moved by {gap:+e}: worst {worst:.2e} ({n} poses)");
            assert!(worst <= 1e-14, "{g} (gap {gap:e}): worst {worst:e}");
            assert!(n > 0);
            let class = g.ting_class();
            for circuit in [Circuit::Open, Circuit::Crossed] {
                let mut assembled = 0;
                let mut total = 0;
                for deg in angles.clone() {
                    total += 1;
                    let a = GearAngle::new(g.ratio, g.phase, deg);
                    let Some(p) = GearedPose::solve(&g, circuit, &a) else {
                        continue;
                    };
                    assembled += 1;
                    assert!(p.joint.x.is_finite() && p.joint.y.is_finite());
                    assert!(!p.transmission.is_nan());
                    assert!(
                        p.velocity(CouplerPoint::new(1.0, 1.0))
                            .is_none_or(|v| v.x.is_finite() && v.y.is_finite())
                    );
                    // No circuit jump: the joint is on the requested side of Pa→Pd, or on
                    // the line (a toggle) — never on the other side.
                    let (w, r) = (p.second_pin - p.input_pin, p.joint - p.input_pin);
                    let cross = w.x * r.y - w.y * r.x;
                    assert!(
                        cross * circuit.sign() >= -1e-15,
                        "{g} {circuit} θ={deg}: joint on the wrong side ({cross:e})"
                    );
                }
                // Class I side of the change point: a strict double crank, every angle.
                if class == TingClass::I {
                    assert_eq!(assembled, total, "{g} {circuit}");
                }
            }
        }
    }
}

/// The change-point test can fail: the textbook alternative, Kahan's area of the
/// triangle (L3, L4, d) from a *rounded* d = |Pd − Pa| (cancellation-free for the
/// triangle, but d's last-bit error is amplified near the flat configuration), misses by
/// ~1e-11 at a gap of 1e-12 where the shipped half-angle thin factors stay at 1e-15.
#[test]
fn thin_factors_from_a_rounded_d_fail_near_a_change_point() {
    for (gap, naive_at_least) in [(1e-6, 1e-13), (1e-9, 1e-12), (1e-12, 1e-12)] {
        let g = five(2.5, 2.1, 2.4 + gap, 1.0, -1, 1, 180.0);
        let (mut naive, mut shipped) = (0.0f64, 0.0f64);
        for circuit in [Circuit::Open, Circuit::Crossed] {
            for k in -1000..=1000 {
                let deg = 180.0 + k as f64 * 1e-3;
                let a = GearAngle::new(g.ratio, g.phase, deg);
                let pa = Point2::new(a.input.cos, a.input.sin);
                let pd = g.o5() + nalgebra::Vector2::new(a.second.cos, a.second.sin) * g.l5;
                let w = pd - pa;
                let d2 = w.norm_squared();
                let area4 = 2.0 * coupler_atlas::kahan_double_area(g.l3, g.l4, d2.sqrt()).unwrap();
                let along = 0.5 + 0.5 * (g.l3 - g.l4) * (g.l3 + g.l4) / d2;
                let across = circuit.sign() * 0.5 * area4 / d2;
                let joint = pa + w * along + nalgebra::Vector2::new(-w.y, w.x) * across;
                let (rx, ry) = geared_point_dd(&g, circuit, g.joint_point(), deg).unwrap();
                let err = |m: Point2<f64>| (m.x - rx.to_f64()).abs().max((m.y - ry.to_f64()).abs());
                naive = naive.max(err(joint));
                shipped = shipped.max(err(GearedPose::solve(&g, circuit, &a).unwrap().joint));
            }
        }
        eprintln!("gap {gap:e}: Kahan on a rounded d {naive:.2e}, shipped {shipped:.2e}");
        assert!(naive >= naive_at_least, "gap {gap:e}: {naive:e}");
        assert!(shipped <= 1e-14, "gap {gap:e}: {shipped:e}");
    }
}

// ---------------------------------------------------------------------------------------
// Properties

/// Lengths that like to be nearly equal (and Class III-adjacent): a base length, then
/// others either independent or within 10^-k of a sum or difference that makes a gap zero.
fn nearly_equal_linkage() -> impl Strategy<Value = GearedFiveBar> {
    (
        0.3f64..4.0,
        0.3f64..4.0,
        0.3f64..4.0,
        prop_oneof![Just(0.0), (1u32..15).prop_map(|k| 10f64.powi(-(k as i32)))],
        any::<bool>(),
        prop_oneof![
            Just((-1i64, 1i64)),
            Just((-2, 1)),
            Just((2, 1)),
            Just((-1, 2)),
            Just((1, 1)),
            Just((3, 2))
        ],
        prop_oneof![Just(None), Just(Some(90.0)), (0.0f64..360.0).prop_map(Some)],
    )
        .prop_map(|(l1, l5, l3, eps, sign, (n, d), phase)| {
            // No phase given: the one that takes the gear path through the flat
            // configuration θ2 = 180°, θ5 = 0.
            let phase = phase.unwrap_or((-180.0 * n as f64 / d as f64).rem_euclid(360.0));
            // L4 within eps of closing a collinear configuration: L3 + L4 = L1 + L5 + 1.
            let flat = (l1 + l5 + 1.0 - l3).abs().max(0.05);
            let l4 = flat + if sign { eps } else { -eps };
            GearedFiveBar::new(
                l1,
                l3,
                l4.max(0.05),
                l5,
                GearRatio::new(n, d).unwrap(),
                phase,
            )
            .unwrap()
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 120, timeout: 30_000, ..ProptestConfig::default() })]

    /// Wherever the core assembles, it agrees with double-double within its error bound
    /// (toggles included); it never returns NaN.
    #[test]
    fn agrees_with_double_double_near_flat(g in nearly_equal_linkage(), u in -2.0f64..2.0, v in -2.0f64..2.0) {
        let points = [CouplerPoint::new(u, v), g.joint_point()];
        let angles = (0..(g.period_deg() / 3.0) as usize).map(|k| k as f64 * 3.0)
            .chain((-50..=50).map(|k| 180.0 + k as f64 * 1e-4));
        let (_, ratio, _) = against_reference(&g, &points, angles);
        prop_assert!(ratio <= 1.0, "{} ({u}, {v}): error / bound {ratio}", g);
    }

    /// A geared five-bar whose margin stays positive assembles at every sampled angle, on
    /// both circuits, and its traced curve has no null.
    #[test]
    fn full_rotation_means_no_nulls(g in nearly_equal_linkage()) {
        if g.rotatability(MARGIN_TOL) == Rotatability::Full {
            for circuit in [Circuit::Open, Circuit::Crossed] {
                let c = g.trace(circuit, g.joint_point(), 1.0).unwrap();
                prop_assert!((0..c.len()).all(|k| c.is_valid(k) && c.vx[k].is_finite()), "{}", g);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Exact class decisions on half-unit grids

#[test]
fn ting_class_exact_on_a_half_unit_grid() {
    // Every combination of L1, L3, L4, L5 in 0.5 … 4 (steps of 0.5): the class agrees
    // with integer arithmetic on the doubled lengths (exact), including every equality.
    let vals: Vec<i64> = (1..=8).collect(); // doubled lengths
    let mut equal = 0;
    for &a in &vals {
        for &b in &vals {
            for &c in &vals {
                for &e in &vals {
                    let mut l = [a, 2, b, c, e];
                    l.sort();
                    let expect = match (l[0] + l[1] + l[4]).cmp(&(l[2] + l[3])) {
                        std::cmp::Ordering::Less => TingClass::I,
                        std::cmp::Ordering::Greater => TingClass::II,
                        std::cmp::Ordering::Equal => TingClass::III,
                    };
                    equal += usize::from(expect == TingClass::III);
                    let h = |x: i64| x as f64 * 0.5;
                    let g = five(h(a), h(b), h(c), h(e), -1, 1, 0.0);
                    assert_eq!(g.ting_class(), expect, "{g}");
                }
            }
        }
    }
    assert!(equal > 100, "{equal} change points on the grid");
    // On a decimal grid of tenths the f64 sums are coin-flips; the class is not.
    let g = five(0.4, 0.1, 1.1, 0.2, 1, 1, 0.0);
    assert_ne!(0.1 + 0.2 + 1.1, 0.4 + 1.0);
    assert_eq!(g.ting_class(), TingClass::III);
}

/// Where [`GearedFiveBar::turns_for_any_gearing`] says so (exactly), the numeric margin
/// agrees for several gears; where Class I does not put the cranks shortest, some gearing
/// fails.
#[test]
fn any_gearing_decision_agrees_with_the_margin_on_a_grid() {
    let vals = [0.5, 1.0, 1.5, 2.0, 3.0, 4.0];
    let gears = [
        (1, 1, 0.0),
        (-1, 1, 180.0),
        (2, 1, 90.0),
        (-1, 2, 45.0),
        (1, 1, 180.0),
    ];
    let mut checked = 0;
    for &l1 in &vals {
        for &l3 in &vals {
            for &l4 in &vals {
                for &l5 in &vals {
                    let g = five(l1, l3, l4, l5, 1, 1, 0.0);
                    if g.turns_for_any_gearing() {
                        checked += 1;
                        for (n, d, phase) in gears {
                            let h = GearedFiveBar {
                                ratio: ratio(n, d),
                                phase,
                                ..g
                            };
                            assert_eq!(h.rotatability(MARGIN_TOL), Rotatability::Full, "{h}");
                        }
                    }
                }
            }
        }
    }
    assert!(checked > 20, "{checked}");
}

// ---------------------------------------------------------------------------------------
// The geared five-bar equivalent of a four-bar

/// A named four-bar (crank 1, coupler A, rocker B, ground C) and coupler point.
fn case(name: &str, a: f64, b: f64, c: f64, u: f64, v: f64) -> (&str, FourBar, CouplerPoint) {
    (
        name,
        FourBar::new(a, b, c).unwrap(),
        CouplerPoint::new(u, v),
    )
}

/// Residual of `m` (four-bar frame) from the four-bar's coupler curve, by inverse
/// kinematics, in crank units: solve one pin from M and check the other. Pa on the unit
/// circle with |M − Pa| = |r|·A gives Pb = Pa + (M − Pa)/r, which must lie on
/// circle(O4, B); or Pb on circle(O4, B) with |M − Pb| = |r − 1|·A gives
/// Pa = Pb − (M − Pb)/(r − 1), which must lie on the unit circle (r = (u + iv)/A). The
/// smaller miss over all candidates: each way is ill-conditioned only where its circles
/// are tangent, and the two are not tangent together.
fn off_four_bar(l: &FourBar, p: CouplerPoint, m: Point2<f64>) -> f64 {
    type C = nalgebra::Complex<f64>;
    let r = C::new(p.u, p.v) / l.coupler;
    let o4 = Point2::new(l.ground, 0.0);
    let mc = C::new(m.x, m.y);
    let via_pa = circle_intersections(Point2::origin(), 1.0, m, (r * l.coupler).norm())
        .into_iter()
        .map(|pa| {
            let pa = C::new(pa.x, pa.y);
            let pb = pa + (mc - pa) / r;
            ((pb - C::new(l.ground, 0.0)).norm() - l.rocker).abs()
        });
    let via_pb = circle_intersections(o4, l.rocker, m, ((r - 1.0) * l.coupler).norm())
        .into_iter()
        .map(|pb| {
            let pb = C::new(pb.x, pb.y);
            let pa = pb - (mc - pb) / (r - 1.0);
            (pa.norm() - 1.0).abs()
        });
    via_pa.chain(via_pb).fold(f64::INFINITY, f64::min)
}

/// Residual of `m` (four-bar frame) from the five-bar's curve, by inverse kinematics
/// without the five-bar's solver, in four-bar units: with M' = M/scale, A1 on the unit
/// circle at distance L3 from M' fixes θ2, the gears fix θ5 and B2, which must be at
/// distance L4 from M'; or B2 on circle(O5, L5) at distance L4 fixes θ5, the gears θ2
/// (λ = 1 here) and A1, which must be at distance L3. The smaller miss, as above.
fn off_five_bar(eq: &GearedEquivalent, m: Point2<f64>) -> f64 {
    let g = &eq.linkage;
    assert_eq!(g.ratio.value(), 1.0);
    let mm = Point2::from(m.coords / eq.scale);
    let pin = |deg: f64, len: f64, at: Point2<f64>| {
        let t = deg.to_radians();
        at + nalgebra::Vector2::new(t.cos(), t.sin()) * len
    };
    let via_a1 = circle_intersections(Point2::origin(), 1.0, mm, g.l3)
        .into_iter()
        .map(|a1| {
            let t5 = libm::atan2(a1.y, a1.x).to_degrees() + g.phase;
            ((pin(t5, g.l5, g.o5()) - mm).norm() - g.l4).abs()
        });
    let via_b2 = circle_intersections(g.o5(), g.l5, mm, g.l4)
        .into_iter()
        .map(|b2| {
            let t2 = libm::atan2(b2.y, b2.x - g.l1).to_degrees() - g.phase;
            ((pin(t2, 1.0, Point2::origin()) - mm).norm() - g.l3).abs()
        });
    via_a1.chain(via_b2).fold(f64::INFINITY, f64::min) * eq.scale
}

/// Checks that the four-bar's full trace and the equivalent five-bar's curve (both
/// circuits) lie on each other to 1e-12 of the curve's size, prints the figures, and
/// returns the equivalent.
fn check_equivalence(name: &str, l: &FourBar, p: CouplerPoint, step: f64) -> GearedEquivalent {
    let eq = geared_equivalent(l, p).unwrap();
    let full = trace_full(l, p, step);
    let pts: Vec<Point2<f64>> = full.branches.iter().flat_map(|b| b.points()).collect();
    assert!(!pts.is_empty());
    let (mut lo, mut hi) = (pts[0], pts[0]);
    for q in &pts {
        lo = Point2::new(lo.x.min(q.x), lo.y.min(q.y));
        hi = Point2::new(hi.x.max(q.x), hi.y.max(q.y));
    }
    let size = (hi - lo).norm();
    let four_on_five = pts
        .iter()
        .map(|&q| off_five_bar(&eq, q))
        .fold(0.0, f64::max)
        / size;
    let mut five_on_four = 0.0f64;
    let mut five_samples = 0;
    for circuit in [Circuit::Open, Circuit::Crossed] {
        let c = eq.linkage.trace(circuit, eq.point, step).unwrap();
        for k in 0..c.len() {
            if c.is_valid(k) {
                five_samples += 1;
                let q = eq.to_four_bar_frame(Point2::new(c.x[k], c.y[k]));
                five_on_four = five_on_four.max(off_four_bar(l, p, q) / size);
            }
        }
    }
    eprintln!(
        "{name}: four-bar on five-bar {four_on_five:.1e}, five-bar on four-bar {five_on_four:.1e} \
         ({five_samples} five-bar samples), {:?}",
        eq.linkage.rotatability(MARGIN_TOL)
    );
    assert!(
        four_on_five <= 1e-12,
        "{name}: four-bar off the five-bar by {four_on_five:e}"
    );
    assert!(
        five_on_four <= 1e-12,
        "{name}: five-bar off the four-bar by {five_on_four:e}"
    );
    assert!(five_samples > 100, "{name}");
    eq
}

/// Triple rockers (Watt, Roberts, and one of each other RRR kind): every point of the
/// four-bar's full trace (both branches joined at the toggles, `trace_full`) lies on the
/// five-bar's curve and every sample of the five-bar (both circuits, every input angle
/// where it assembles) lies on the four-bar's curve, to 1e-12 of the curve's size.
///
/// And the five-bar's input does NOT turn fully: it turns with the four-bar's coupler,
/// which rocks in every triple rocker (Barker's RRR), so the five-bar rocks between
/// toggles too, and traces the whole curve as the four-bar does, changing circuit there.
#[test]
fn equivalent_traces_the_whole_curve_of_triple_rockers() {
    let cases = [
        case("Watt", 1.0, 1.0, 5f64.sqrt(), 0.5, 0.0),
        case("Roberts", 0.8, 1.0, 1.6, 0.4, -0.916515138991168),
        case("RRR1", 1.2, 1.4, 1.8, 0.7, 0.9),
        case("RRR2", 0.3, 0.4, 0.5, 0.1, -0.2),
        case("RRR3", 1.8, 1.2, 1.4, -0.5, 0.6),
        case("RRR4", 1.2, 1.8, 1.4, 2.0, 0.3),
    ];
    for (name, l, p) in cases {
        assert!(
            !l.class().is_grashof() && !l.class().is_change_point(),
            "{name}"
        );
        let eq = check_equivalence(name, &l, p, 0.25);
        assert_eq!(
            eq.linkage.rotatability(MARGIN_TOL),
            Rotatability::Limited,
            "{name}"
        );
    }
}

/// The five-bar's input turns fully exactly where the four-bar's coupler does: Barker's
/// GRCR (Chebyshev's straight-line linkage) and GCCC (a drag link). There the five-bar
/// needs no circuit change: each of its circuits traces one branch of the four-bar.
#[test]
fn equivalent_turns_fully_where_the_coupler_does() {
    let cases = [
        case("Chebyshev (GRCR)", 0.4, 1.0, 0.8, 0.2, 0.0),
        case("GRCR", 0.5, 1.6, 1.3, 0.8, -0.4),
        case("drag link (GCCC)", 2.5, 2.5, 0.5, 1.0, 1.5),
        case("Hoeken (GCRR)", 2.5, 2.5, 2.0, 5.0, 0.0),
    ];
    for (name, l, p) in cases {
        let eq = check_equivalence(name, &l, p, 0.25);
        let coupler_turns = matches!(l.class().code(), "GRCR" | "GCCC");
        let expect = if coupler_turns {
            Rotatability::Full
        } else {
            Rotatability::Limited
        };
        assert_eq!(eq.linkage.rotatability(MARGIN_TOL), expect, "{name}");
    }
}

/// Configuration by configuration: at every sample of the four-bar's full trace, the
/// five-bar at the input angle and circuit [`GearedEquivalent::input_at`] names puts its
/// joint on the four-bar's coupler point (away from the five-bar's own toggles, where the
/// circuit is a coin-flip and both circuits meet).
#[test]
fn equivalent_follows_the_four_bar_configuration_by_configuration() {
    for (l, p) in [
        (
            FourBar::new(1.0, 1.0, 5f64.sqrt()).unwrap(),
            CouplerPoint::new(0.5, 0.0),
        ),
        (
            FourBar::new(1.2, 1.4, 1.8).unwrap(),
            CouplerPoint::new(0.7, 0.9),
        ),
        (
            FourBar::new(3.0, 2.5, 3.5).unwrap(),
            CouplerPoint::new(1.5, -2.0),
        ),
    ] {
        let eq = geared_equivalent(&l, p).unwrap();
        let g = eq.linkage;
        let mut worst = 0.0f64;
        let mut n = 0;
        for b in trace_full(&l, p, 1.0).branches {
            for s in b.samples {
                let t = coupler_atlas::CrankAngle::from_degrees(s.degrees);
                let pose = coupler_atlas::Pose::solve(&l, s.circuit, &t).unwrap();
                let (deg, circuit) = eq.input_at(&l, pose.crank_pin, pose.rocker_pin);
                let five = GearedPose::solve(&g, circuit, &GearAngle::new(g.ratio, g.phase, deg));
                let Some(five) = five else {
                    panic!("{l}: five-bar does not assemble at {deg} {circuit}");
                };
                // Away from either mechanism's toggles, where both are ill-conditioned.
                if five.transmission.sin() < 1e-2 || pose.transmission.sin() < 1e-2 {
                    continue;
                }
                n += 1;
                // The input angle is read off the four-bar's coupler (an atan2 and a sum
                // of degrees, ~1e-16 rad); where the coupler turns slowly the five-bar's
                // point moves fast per radian of input, so scale by its speed.
                let m = eq.to_four_bar_frame(five.joint);
                let speed = five.velocity(eq.point).unwrap().norm() * eq.scale;
                worst = worst.max((m - s.point).norm() / (1.0 + speed));
            }
        }
        assert!(n > 200, "{n}");
        assert!(worst < 1e-14, "{l}: {worst:e}");
    }
}

/// Watt's linkage: the coupler swings ±atan 2 = ±63.43° about the ground line (its
/// extremes are the mid-stroke positions, where crank and rocker are antiparallel), so
/// the equivalent five-bar (L1 = 2√5, cranks 1 and 1, dyad 2 and 2, λ = 1, φ = 180°)
/// assembles exactly for cos θ2 ≥ 1/√5.
#[test]
fn watt_equivalent_rocks_through_the_coupler_swing() {
    let l = FourBar::new(1.0, 1.0, 5f64.sqrt()).unwrap();
    let eq = geared_equivalent(&l, CouplerPoint::new(0.5, 0.0)).unwrap();
    let g = eq.linkage;
    assert!((g.l1 - 2.0 * 5f64.sqrt()).abs() < 1e-15);
    let gaps = GearedGaps::of(&g);
    let limit = 2f64.atan().to_degrees();
    for k in 0..3600 {
        let deg = k as f64 * 0.1;
        let inside = deg.to_radians().cos() >= 1.0 / 5f64.sqrt();
        let m = g.margin_at(&gaps, deg);
        if (deg - limit).abs() > 1e-6 && (deg - (360.0 - limit)).abs() > 1e-6 {
            assert_eq!(m >= 0.0, inside, "θ2 = {deg}: margin {m:e}");
        }
    }
    // Its input range, toggle to toggle.
    let r = g.input_intervals(1.0);
    assert_eq!(r.len(), 1);
    assert!(
        (r[0].0 - (360.0 - limit)).abs() < 1e-9 && (r[0].1 - (360.0 + limit)).abs() < 1e-9,
        "{r:?}"
    );
    // The four-bar's coupler angle over its full trace spans the same ±63.43°.
    let mut lo: f64 = 0.0;
    let mut hi: f64 = 0.0;
    for b in trace_full(&l, CouplerPoint::new(0.5, 0.0), 0.01).branches {
        for s in b.samples {
            let t = coupler_atlas::CrankAngle::from_degrees(s.degrees);
            let pose = coupler_atlas::Pose::solve(&l, s.circuit, &t).unwrap();
            let e = pose.coupler_dir;
            let deg = libm::atan2(e.y, e.x).to_degrees();
            (lo, hi) = (lo.min(deg), hi.max(deg));
        }
    }
    assert!(
        (hi - limit).abs() < 1e-6 && (lo + limit).abs() < 1e-6,
        "{lo} {hi}"
    );
}

// ---------------------------------------------------------------------------------------
// The exact straight line (λ = −1, φ = 180°)

#[test]
fn straight_line_at_rounding_level() {
    for (l1, l3) in [(3.0, 3.0), (2.5, 2.3), (4.0, 3.1), (2.1, 2.1), (3.0, 7.0)] {
        let g = GearedFiveBar::straight_line(l1, l3).unwrap();
        assert_eq!(g.rotatability(MARGIN_TOL), Rotatability::Full, "{g}");
        let scale = l1 + l3 + 1.0;
        for circuit in [Circuit::Open, Circuit::Crossed] {
            let c = g.trace(circuit, g.joint_point(), 0.1).unwrap();
            let (mut ymin, mut ymax) = (f64::INFINITY, f64::NEG_INFINITY);
            let (mut xmin, mut xmax) = (f64::INFINITY, f64::NEG_INFINITY);
            for k in 0..c.len() {
                assert!(c.is_valid(k));
                (xmin, xmax) = (xmin.min(c.x[k]), xmax.max(c.x[k]));
                // Straightness ε_S = (max Cy − min Cy)/Δx with the line x = L1/2: every
                // deviation at the level of rounding (a few ulps of the linkage's size).
                assert!(
                    (c.x[k] - 0.5 * l1).abs() <= 4.0 * f64::EPSILON * scale,
                    "{g} {circuit}: x = {} at θ2 = {}",
                    c.x[k],
                    k as f64 * 0.1
                );
                assert!(c.vx[k].abs() <= 8.0 * f64::EPSILON * scale * (1.0 + c.vy[k].abs()));
                (ymin, ymax) = (ymin.min(c.y[k]), ymax.max(c.y[k]));
            }
            let eps_s = (xmax - xmin) / (ymax - ymin);
            eprintln!(
                "{g} {circuit}: stroke {:.4}, ε_S = {eps_s:.1e}",
                ymax - ymin
            );
            assert!(eps_s <= 2e-15, "{g}: ε_S {eps_s:e}");
            // The stroke: y = sin θ2 ± √(L3² − (L1/2 − cos θ2)²).
            let stroke = |t: f64| {
                let (s, co) = (t.to_radians().sin(), t.to_radians().cos());
                s + circuit.sign() * (l3 * l3 - (0.5 * l1 - co).powi(2)).sqrt()
            };
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for k in 0..36000 {
                let y = stroke(k as f64 * 0.01);
                (lo, hi) = (lo.min(y), hi.max(y));
            }
            assert!((ymin - lo).abs() < 1e-5 && (ymax - hi).abs() < 1e-5, "{g}");
        }
    }
    // Not a straight line without the symmetry: L5 ≠ 1 or L3 ≠ L4.
    for g in [
        five(3.0, 3.0, 3.0, 1.1, -1, 1, 180.0),
        five(3.0, 3.0, 3.1, 1.0, -1, 1, 180.0),
        five(3.0, 3.0, 3.0, 1.0, -1, 1, 170.0),
    ] {
        let c = g.trace(Circuit::Open, g.joint_point(), 1.0).unwrap();
        let spread = c.x.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b))
            - c.x.iter().fold(f64::INFINITY, |a, &b| a.min(b));
        assert!(spread > 1e-3, "{g}: {spread}");
    }
}
