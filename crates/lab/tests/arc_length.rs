//! The index's arc length against an independent double-double reference
//! ([`coupler_lab::arc_length_dd`]: chord polygons of double-double positions,
//! extrapolated and refined), on every curve of the H&D and quick atlases that has a cusp
//! or passes through a pin, and on a geared five-bar's curves.

use coupler_features::{FeatureExtractor, FeatureTolerances};
use coupler_generate::Job;
use coupler_kinematics::{ArcLength, Circuit, CouplerPoint, DashPattern, Linkage, Mechanism};
use coupler_lab::{arc_length_dd, coupler_point_dd, geared_point_dd};
use coupler_specs::Spec;

/// The relative accuracy the index's `length` promises (issue 11, docs/index-schema.md).
const PROMISED: f64 = 1e-9;

fn reference(l: &Linkage, circuit: Circuit, p: CouplerPoint) -> f64 {
    let position = |t: f64| match l {
        Linkage::FourBar(f) => coupler_point_dd(f, circuit, p, t),
        Linkage::GearedFiveBar(g) => geared_point_dd(g, circuit, p, t),
    };
    arc_length_dd(&position, l.period_deg(), 1e-13).unwrap().0
}

#[test]
fn lengths_of_curves_with_cusps_match_a_double_double_reference() {
    let mut checked = 0;
    let mut cusps = 0;
    let mut worst: f64 = 0.0;
    // What the index held before: the trapezoid sum of the speed at the atlas's 1° step.
    let mut trapezoid_worst: f64 = 0.0;
    for (text, name) in [
        (
            include_str!("../../../atlas-spec/hartenberg-denavit.toml"),
            "hd",
        ),
        (include_str!("../../../atlas-spec/quick.toml"), "quick"),
    ] {
        let job = Job::new(Spec::parse(text, name).unwrap(), name, "unused", 1);
        for g in job.groups() {
            let mut features = FeatureExtractor::new(
                &g.linkage,
                g.circuit,
                &FeatureTolerances::DEFAULT,
                &DashPattern::default(),
            )
            .unwrap();
            let mut arc = ArcLength::new(&g.linkage, g.circuit).unwrap();
            for &p in &g.points {
                let f = features.extract(p);
                // Cusps (speed ≤ 1 % of the mean) and pins (the rocker pin stops twice).
                if f.double_points.cusps.is_empty() && f.trivial.is_none() {
                    continue;
                }
                cusps += f.double_points.cusps.len();
                let s = arc.length(p).unwrap();
                let r = reference(&g.linkage, g.circuit, p);
                let err = ((s - r) / r).abs();
                worst = worst.max(err);
                assert!(
                    err <= PROMISED,
                    "{name} {} {:?} ({}, {}): length {s} vs reference {r}: {err:e}",
                    g.linkage,
                    g.circuit,
                    p.u,
                    p.v
                );
                let step = job.spec.sampling.crank_step_deg;
                let table = coupler_kinematics::CrankTable::new(step).unwrap();
                let c = g.linkage.pose_table(g.circuit, &table).trace(p);
                let trapezoid: f64 =
                    (0..c.len()).map(|k| c.vx[k].hypot(c.vy[k])).sum::<f64>() * step.to_radians();
                trapezoid_worst = trapezoid_worst.max(((trapezoid - r) / r).abs());
                checked += 1;
            }
        }
    }
    eprintln!(
        "{checked} curves ({cusps} cusps): worst relative error {worst:e} (the trapezoid sum on the samples: {trapezoid_worst:e})"
    );
    assert!(
        checked >= 20 && cusps >= 15,
        "{checked} curves, {cusps} cusps"
    );
}

#[test]
fn geared_five_bar_lengths_match_the_reference() {
    // The first mechanisms of the geared quick atlas (a period of 720°), every point.
    let text = include_str!("../../../atlas-spec/geared-quick.toml");
    let job = Job::new(Spec::parse(text, "gq").unwrap(), "gq", "unused", 1);
    let mut checked = 0;
    for g in job.groups().take(2) {
        let mut arc = ArcLength::new(&g.linkage, g.circuit).unwrap();
        for &p in &g.points {
            let s = arc.length(p).unwrap();
            let r = reference(&g.linkage, g.circuit, p);
            assert!(
                ((s - r) / r).abs() <= PROMISED,
                "{} {:?} {p:?}: {s} vs {r}",
                g.linkage,
                g.circuit
            );
            checked += 1;
        }
    }
    assert!(checked >= 2);
}
