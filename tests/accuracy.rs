//! Accuracy of the shipped closed form against the double-double reference (issue 2's
//! targets, checked here for issue 5): ~1e-14 on ordinary linkages, 1e-12 within 1e-6 …
//! 1e-9 of a change point, including crank angles right around the fold. Each test
//! prints its measured maximum (`cargo test --test accuracy -- --nocapture`).

use coupler_atlas::{Circuit, CouplerPoint, FourBar};
use coupler_lab::{ClosedForm, measure, uniform_angles};

/// Target on ordinary linkages, crank lengths, for |u|, |v| ≤ 3.
const ORDINARY: f64 = 1e-14;
/// Target within 1e-6 … 1e-9 of a change point.
const NEAR_CHANGE_POINT: f64 = 1e-12;

fn points() -> Vec<CouplerPoint> {
    let mut v = Vec::new();
    for u in [-3.0, -1.0, 0.0, 0.5, 1.5, 3.0] {
        for w in [-3.0, -0.5, 0.0, 1.0, 3.0] {
            v.push(CouplerPoint::new(u, w));
        }
    }
    v
}

#[test]
fn ordinary_crank_rockers_to_1e_14() {
    let angles = uniform_angles(2, 10.0); // every 5°
    let mut worst = 0.0f64;
    let mut count = 0;
    for a in [1.5, 2.0, 2.5, 3.0, 3.5, 4.5] {
        for b in [1.5, 2.0, 2.5, 3.0, 4.0] {
            for c in [1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0] {
                let l = FourBar::new(a, b, c).unwrap();
                if !l.is_crank_rocker() {
                    continue;
                }
                count += 1;
                for circuit in [Circuit::Open, Circuit::Crossed] {
                    for p in points() {
                        let m = measure(&ClosedForm, &l, circuit, p, &angles);
                        assert!(m.is_clean(), "{l} {circuit:?} {p:?}: {m:?}");
                        worst = worst.max(m.max_error);
                    }
                }
            }
        }
    }
    eprintln!(
        "ordinary crank-rockers: {count} linkages × 30 points × 2 circuits × 72 angles: max error {worst:.2e}"
    );
    assert!(count > 30);
    assert!(worst <= ORDINARY, "max error {worst:e}");
}

/// Angles dense around θ = 0 (where these linkages fold) and a 1° grid elsewhere.
fn around_fold(center: f64) -> Vec<f64> {
    let mut v: Vec<f64> = (0..360).map(|k| k as f64).collect();
    for k in 0..=15 {
        let d = libm::pow(10.0, -(k as f64));
        v.push(center - d);
        v.push(center + d);
    }
    v
}

#[test]
fn near_change_points_to_1e_12() {
    let mut worst = 0.0f64;
    for gap in [1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9, 1e-9] {
        // μ → 0° at θ = 0 (C − 1 = |A − B| + gap) and μ → 180° at θ = 180° (C + 1 = A + B − gap).
        let cases = [
            (FourBar::new(3.0, 2.0, 2.0 + gap).unwrap(), 0.0),
            (FourBar::new(2.0, 3.0, 2.0 + gap).unwrap(), 0.0),
            (FourBar::new(3.0, 2.0, 4.0 - gap).unwrap(), 180.0),
            (FourBar::new(3.0, 3.0, 5.0 - gap).unwrap(), 180.0),
        ];
        for (l, fold) in cases {
            assert!(l.is_crank_rocker(), "{l}");
            for circuit in [Circuit::Open, Circuit::Crossed] {
                for p in [
                    CouplerPoint::new(1.0, 1.0),
                    CouplerPoint::new(-2.0, 0.5),
                    CouplerPoint::new(3.0, -3.0),
                ] {
                    let m = measure(&ClosedForm, &l, circuit, p, &around_fold(fold));
                    assert!(m.is_clean(), "{l} {circuit:?} {p:?}: {m:?}");
                    worst = worst.max(m.max_error);
                }
            }
        }
    }
    eprintln!("within 1e-6 … 1e-9 of a change point, dense around the fold: max error {worst:.2e}");
    assert!(worst <= NEAR_CHANGE_POINT, "max error {worst:e}");
}

#[test]
fn exactly_at_change_points_positions_stay_accurate() {
    let mut worst = 0.0f64;
    for (l, fold) in [
        (FourBar::new(3.0, 2.0, 2.0).unwrap(), 0.0),
        (FourBar::new(3.0, 3.0, 5.0).unwrap(), 180.0),
        (FourBar::new(2.5, 2.5, 1.0).unwrap(), 0.0),
    ] {
        assert!(l.class().is_change_point(), "{l}");
        for circuit in [Circuit::Open, Circuit::Crossed] {
            let m = measure(
                &ClosedForm,
                &l,
                circuit,
                CouplerPoint::new(1.0, 1.0),
                &around_fold(fold),
            );
            assert!(m.is_clean(), "{l} {circuit:?}: {m:?}");
            worst = worst.max(m.max_error);
        }
    }
    eprintln!("exactly at change points: max error {worst:.2e}");
    assert!(worst <= NEAR_CHANGE_POINT, "max error {worst:e}");
}
