//! The stability sweep: cases chosen where position methods fail (change points,
//! toggles, transmission angles near 0° and 180°, extreme ratios, far coupler points),
//! each method measured against the reference. Pure: the CLI prints the table.

use super::{Measurement, PositionMethod, measure, uniform_angles};
use coupler_features::{CurveFlags, FlagTolerances};
use coupler_kinematics::{Circuit, CouplerPoint, FourBar};

/// One case of the sweep: a linkage, circuit, coupler point and a sequence of angles.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepCase {
    /// Family, e.g. `"change point (μ→0°)"`.
    pub group: &'static str,
    /// The case within the family, e.g. `"gap 1e-9"`.
    pub label: String,
    /// The linkage.
    pub linkage: FourBar,
    /// The circuit.
    pub circuit: Circuit,
    /// The coupler point.
    pub point: CouplerPoint,
    /// Crank angles in degrees, in tracing order.
    pub degrees: Vec<f64>,
}

/// The input angle θ (degrees, in [0°, 180°]) at which `d = |O4 − Pa|` equals `target`:
/// `cos θ = (1 + C² − target²)/(2C)`, or `None` if no angle has that d.
pub fn angle_for_d(ground: f64, target: f64) -> Option<f64> {
    let c = (1.0 + ground * ground - target * target) / (2.0 * ground);
    (-1.0..=1.0)
        .contains(&c)
        .then(|| libm::acos(c).to_degrees())
}

/// The sweep's cases, in table order.
pub fn sweep_cases() -> Vec<SweepCase> {
    let mut cases = Vec::new();
    let gaps = [1e-1, 1e-3, 1e-6, 1e-9, 1e-12, 1e-15];
    let p = CouplerPoint::new(1.0, 1.0);
    let dense = uniform_angles(10, 10.0); // 1° steps, through 0° and 180°
    // Change point at θ = 0, transmission μ → 0°: C = |A − B| + 1 + gap (A = 3, B = 2).
    for &g in &gaps {
        cases.push(SweepCase {
            group: "μ→0° (change point at θ=0)",
            label: format!("C = 2 + {g:e}"),
            linkage: FourBar::new(3.0, 2.0, 2.0 + g).expect("valid"),
            circuit: Circuit::Open,
            point: p,
            degrees: dense.clone(),
        });
    }
    // Change point at θ = 180°, transmission μ → 180°: C = A + B − 1 − gap.
    for &g in &gaps {
        cases.push(SweepCase {
            group: "μ→180° (change point at θ=180°)",
            label: format!("C = 4 − {g:e}"),
            linkage: FourBar::new(3.0, 2.0, 4.0 - g).expect("valid"),
            circuit: Circuit::Crossed,
            point: p,
            degrees: dense.clone(),
        });
    }
    // Exactly on the change point.
    cases.push(SweepCase {
        group: "change point exactly",
        label: "A=3 B=2 C=2".into(),
        linkage: FourBar::new(3.0, 2.0, 2.0).expect("valid"),
        circuit: Circuit::Open,
        point: p,
        degrees: dense.clone(),
    });
    // Crank angles around the fold of a near-change-point linkage (C = 2 + 1e-9): θ from
    // −1° to +1° through 0 with geometric steps ±10^−k, k = 0..15.
    let mut around: Vec<f64> = (0..=15).map(|k| -libm::pow(10.0, -(k as f64))).collect();
    around.push(0.0);
    around.extend((0..=15).rev().map(|k| libm::pow(10.0, -(k as f64))));
    for &g in &[1e-6, 1e-9, 1e-12] {
        cases.push(SweepCase {
            group: "crank angles around a fold (θ = 0 ± 10^−k)",
            label: format!("C = 2 + {g:e}"),
            linkage: FourBar::new(3.0, 2.0, 2.0 + g).expect("valid"),
            circuit: Circuit::Open,
            point: p,
            degrees: around.clone(),
        });
    }
    // Approaching a toggle of a triple rocker (A = 2, B = 1.5, C = 3: d ≤ A + B = 3.5 at
    // θ_t): 1° steps from 30° up to θ_t − δ.
    let rocker = FourBar::new(2.0, 1.5, 3.0).expect("valid");
    let theta_t = angle_for_d(3.0, 3.5).expect("toggle exists");
    for &delta in &[1e-1, 1e-3, 1e-6, 1e-9, 1e-12, 0.0] {
        let end = theta_t - delta;
        let mut degrees: Vec<f64> = (30..).map(|k| k as f64).take_while(|&t| t < end).collect();
        degrees.push(end);
        cases.push(SweepCase {
            group: "toggle of a triple rocker",
            label: if delta == 0.0 {
                "θ = θ_t".into()
            } else {
                format!("θ_t − {delta:e}")
            },
            linkage: rocker,
            circuit: Circuit::Open,
            point: p,
            degrees,
        });
    }
    // Around the toggle: θ_t − 10^−k … θ_t … θ_t + 10^−k (beyond it nothing assembles).
    let mut around_t: Vec<f64> = (1..=12)
        .map(|k| theta_t - libm::pow(10.0, -(k as f64)))
        .collect();
    around_t.push(theta_t);
    around_t.extend(
        (1..=12)
            .rev()
            .map(|k| theta_t + libm::pow(10.0, -(k as f64))),
    );
    cases.push(SweepCase {
        group: "toggle of a triple rocker",
        label: "θ_t ± 10^−k, k = 1…12".into(),
        linkage: rocker,
        circuit: Circuit::Open,
        point: p,
        degrees: around_t,
    });
    // Extreme ratios.
    for (a, b, c) in [
        (1e3, 1e3, 1e3),
        (1e3, 1e3 - 0.5, 1e3),
        (1e-3, 1e3, 1e3),
        (1e3, 1e-3, 1e3),
        (1e3, 1e3, 1e-3),
        (1e-3, 1e-3, 1.0),
    ] {
        cases.push(SweepCase {
            group: "extreme ratios",
            label: format!("A={a:e} B={b:e} C={c:e}"),
            linkage: FourBar::new(a, b, c).expect("valid"),
            circuit: Circuit::Open,
            point: CouplerPoint::new(0.5 * a, 0.5 * a),
            degrees: dense.clone(),
        });
    }
    // Far coupler points on an ordinary crank-rocker.
    for r in [1e1, 1e2, 1e3] {
        for (u, v) in [(r, 0.0), (0.0, r), (-r, r)] {
            cases.push(SweepCase {
                group: "far coupler point",
                label: format!("u={u:e} v={v:e}"),
                linkage: FourBar::new(2.5, 3.0, 3.5).expect("valid"),
                circuit: Circuit::Crossed,
                point: CouplerPoint::new(u, v),
                degrees: dense.clone(),
            });
        }
    }
    cases
}

/// A case's result: one measurement per method (in the order given), the shipped flags.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepRow {
    /// The case.
    pub case: SweepCase,
    /// `(method name, measurement)`.
    pub results: Vec<(&'static str, Measurement)>,
    /// Flags and error bound of the shipped closed form.
    pub flags: CurveFlags,
}

/// Runs every method on one case.
pub fn run_case(case: SweepCase, methods: &[Box<dyn PositionMethod>]) -> SweepRow {
    let results = methods
        .iter()
        .map(|m| {
            (
                m.name(),
                measure(
                    m.as_ref(),
                    &case.linkage,
                    case.circuit,
                    case.point,
                    &case.degrees,
                ),
            )
        })
        .collect();
    let flags = CurveFlags::assess(
        &case.linkage,
        case.circuit,
        case.point,
        &case.degrees,
        &FlagTolerances::DEFAULT,
    );
    SweepRow {
        case,
        results,
        flags,
    }
}
