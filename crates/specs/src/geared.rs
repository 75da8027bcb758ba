//! `[geared]`: the linkages of a geared five-bar atlas (`atlas-spec/geared-fivebar.toml`,
//! docs/spec-format.md): ranges of L1, L3, L4, L5 (input crank = 1), a list of gear
//! ratios and a range of phases. The atlas holds the combinations whose input turns
//! fully ([`Rotatability::Full`], as the four-bar atlas holds crank-rockers); the others
//! are counted by Ting class.

use crate::ranges::DecimalRange;
use coupler_kinematics::{Decimal, GearRatio, GearedFiveBar, Linkage, MARGIN_TOL, Rotatability};
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::{Arc, OnceLock};

/// The linkage ranges of a geared five-bar atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct GearedRanges {
    /// Ground L1 (O2 to O5).
    pub l1: DecimalRange,
    /// Dyad link L3 from the input crank's pin (carries the coupler points).
    pub l3: DecimalRange,
    /// Dyad link L4 from the second crank's pin.
    pub l4: DecimalRange,
    /// Second crank L5.
    pub l5: DecimalRange,
    /// Gear ratios λ, in the spec's order.
    pub ratios: Vec<GearRatio>,
    /// Phases φ in degrees (θ5 = λ·θ2 + φ).
    pub phases: DecimalRange,
    /// The enumeration, made on first use (deciding rotatability samples each
    /// combination's period) and shared by clones.
    pub(crate) enumerated: Enumerated,
}

/// A geared grid's enumeration ([`GearedRanges::enumeration`]), made once: the count,
/// the skipped classes and the job's linkages all read it. A cache, not part of the
/// value: every two compare equal.
#[derive(Clone, Default)]
pub(crate) struct Enumerated(Arc<OnceLock<GearedEnumeration>>);

/// The fully turning linkages in atlas order, and the others counted by class.
pub type GearedEnumeration = (Vec<Linkage>, BTreeMap<String, u64>);

impl PartialEq for Enumerated {
    fn eq(&self, _: &Enumerated) -> bool {
        true
    }
}

impl std::fmt::Debug for Enumerated {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.get().is_some() {
            "enumerated"
        } else {
            "not enumerated yet"
        })
    }
}

/// As the index echoes it: `{"mechanism": "geared-fivebar", "l1": {…}, …}`.
impl Serialize for GearedRanges {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut st = s.serialize_struct("GearedRanges", 7)?;
        st.serialize_field("mechanism", "geared-fivebar")?;
        st.serialize_field("l1", &self.l1)?;
        st.serialize_field("l3", &self.l3)?;
        st.serialize_field("l4", &self.l4)?;
        st.serialize_field("l5", &self.l5)?;
        st.serialize_field("ratios", &self.ratios)?;
        st.serialize_field("phases", &self.phases)?;
        st.end()
    }
}

impl GearedRanges {
    /// Number of (L1, L3, L4, L5, λ, φ) combinations.
    pub fn combinations(&self) -> u64 {
        self.l1.len()
            * self.l3.len()
            * self.l4.len()
            * self.l5.len()
            * self.ratios.len() as u64
            * self.phases.len()
    }

    /// Every combination in atlas order (λ outermost in the spec's order, then φ, L1,
    /// L3, L4, L5 ascending) whose input turns fully and clears every toggle
    /// ([`GearedFiveBar::rotatability`] is `Full`); the others counted by Ting class and
    /// what the input does (`"II rocks"`, `"III touches a toggle"`). A phase that gives
    /// the same curves as an earlier phase of the list for that ratio (360°/q apart for
    /// λ = p/q, [`same_curves`]) is left out, counted as [`REPEATED_PHASE`]. Made on
    /// first use, then shared (by clones of the ranges too).
    pub fn enumeration(&self) -> &GearedEnumeration {
        self.enumerated.0.get_or_init(|| self.enumerate())
    }

    /// [`GearedRanges::enumeration`], made afresh.
    fn enumerate(&self) -> GearedEnumeration {
        let mut linkages = Vec::new();
        let mut skipped: BTreeMap<String, u64> = BTreeMap::new();
        let f =
            |r: &DecimalRange| -> Vec<f64> { r.values().into_iter().map(|x| x.to_f64()).collect() };
        let (l1s, l3s, l4s, l5s) = (f(&self.l1), f(&self.l3), f(&self.l4), f(&self.l5));
        let phases = self.phases.values();
        let per_phase = l1s.len() * l3s.len() * l4s.len() * l5s.len();
        for &ratio in &self.ratios {
            for (i, &exact) in phases.iter().enumerate() {
                if phases[..i].iter().any(|&b| same_curves(ratio, exact, b)) {
                    *skipped.entry(REPEATED_PHASE.to_string()).or_default() += per_phase as u64;
                    continue;
                }
                let phase = exact.to_f64();
                for &l1 in &l1s {
                    for &l3 in &l3s {
                        for &l4 in &l4s {
                            for &l5 in &l5s {
                                let Ok(g) = GearedFiveBar::new(l1, l3, l4, l5, ratio, phase) else {
                                    continue;
                                };
                                let what = match g.rotatability(MARGIN_TOL) {
                                    Rotatability::Full => {
                                        linkages.push(Linkage::GearedFiveBar(g));
                                        continue;
                                    }
                                    Rotatability::Touches => "touches a toggle",
                                    Rotatability::Limited => "rocks",
                                };
                                let key = format!("{} {what}", g.ting_class().code());
                                *skipped.entry(key).or_default() += 1;
                            }
                        }
                    }
                }
            }
        }
        (linkages, skipped)
    }
}

/// The key of [`GearedRanges::enumeration`]'s skipped counts for combinations whose
/// phase repeats an earlier phase's curves ([`same_curves`]).
pub const REPEATED_PHASE: &str = "repeated phase";

/// Whether the phases `a` and `b` (degrees) give a geared five-bar of gear ratio λ = p/q
/// the same curves. One more input turn (θ2 + 360°) brings the input pin back and turns
/// the second crank by λ·360° = 360°·p/q, so the linkage of phase φ passes, a turn later,
/// through every configuration of the linkage of phase φ + 360°·p/q (mod 360°): the same
/// mechanism, started a whole number of input turns apart, tracing the same curve (the
/// same dashes, as a turn is a whole number of them) from another start. As p and q are
/// coprime, the phases so related are exactly those 360°/q apart: for an integer ratio
/// every phase is its own; for λ = −1/2, φ and φ + 180°. Exact (decimal): q·(a − b) is a
/// whole multiple of 360°. Nothing else makes two phases equal: at θ2 = 0 the second
/// crank's angle, θ5 = φ, tells them apart.
pub fn same_curves(ratio: GearRatio, a: Decimal, b: Decimal) -> bool {
    let Some(d) = a
        .checked_sub(b)
        .and_then(|d| d.checked_mul_int(i128::from(ratio.den())))
    else {
        return false;
    };
    // Normalised: a negative exponent is a fraction (no whole multiple of 360).
    if d.exponent() < 0 {
        return false;
    }
    let mut r = d.mantissa().rem_euclid(360);
    for _ in 0..d.exponent() {
        r = r * 10 % 360;
    }
    r == 0
}

#[cfg(test)]
mod tests {
    use super::same_curves;
    use crate::Spec;
    use coupler_kinematics::{Circuit, CouplerPoint, Decimal, GearRatio, GearedFiveBar};

    fn dec(x: &str) -> Decimal {
        x.parse().unwrap()
    }

    /// Phases 360°/q apart trace the same curve (every sample of one is a sample of the
    /// other one input turn later, within 1e-13); others do not; the test of the identity
    /// is exact in decimals.
    #[test]
    fn phases_360_over_q_apart_trace_the_same_curves() {
        let half = GearRatio::new(-1, 2).unwrap();
        let whole = GearRatio::new(-2, 1).unwrap();
        let two_thirds = GearRatio::new(2, 3).unwrap();
        assert!(same_curves(half, dec("180"), dec("0")));
        assert!(same_curves(half, dec("270"), dec("90")));
        assert!(same_curves(half, dec("-157.5"), dec("22.5")));
        assert!(!same_curves(half, dec("90"), dec("0")));
        assert!(!same_curves(half, dec("180.1"), dec("0")));
        assert!(!same_curves(whole, dec("180"), dec("0")));
        assert!(same_curves(whole, dec("360"), dec("0")));
        assert!(same_curves(two_thirds, dec("240"), dec("0")));
        assert!(!same_curves(two_thirds, dec("180"), dec("0")));
        // The curves themselves: λ = −1/2, φ = 30° at θ2 + 360° is φ = 210° at θ2.
        let p = CouplerPoint::new(1.5, 0.7);
        let a = GearedFiveBar::new(3.0, 3.0, 2.5, 1.0, half, 30.0).unwrap();
        let b = GearedFiveBar::new(3.0, 3.0, 2.5, 1.0, half, 210.0).unwrap();
        let c = GearedFiveBar::new(3.0, 3.0, 2.5, 1.0, half, 120.0).unwrap();
        let mut apart = 0.0_f64;
        for k in 0..720 {
            let t = k as f64;
            let m = a.pose_at(Circuit::Open, t + 360.0).unwrap().point(p);
            let n = b.pose_at(Circuit::Open, t).unwrap().point(p);
            assert!((m - n).norm() < 1e-13, "θ2 = {t}: {m} vs {n}");
            let o = c.pose_at(Circuit::Open, t).unwrap().point(p);
            apart = apart.max((o - n).norm());
        }
        assert!(apart > 0.1, "{apart}");
    }

    /// The geared atlas's λ = −1/2 phases 180° and 270° repeat 0° and 90°: left out,
    /// counted, and the atlas holds no two combinations with the same curves.
    #[test]
    fn repeated_phases_are_left_out_of_the_atlas() {
        let text = include_str!("../../../atlas-spec/geared-fivebar.toml");
        let spec = Spec::parse(text, "geared-fivebar").unwrap();
        let g = spec.geared.as_ref().unwrap();
        let (linkages, skipped) = g.enumeration();
        assert_eq!(skipped[super::REPEATED_PHASE], 2 * 81);
        let mut seen = std::collections::BTreeSet::new();
        for l in linkages {
            let coupler_kinematics::Linkage::GearedFiveBar(f) = l else {
                panic!("{l:?}")
            };
            let r = f.ratio;
            // The phase reduced modulo 360°/q names the curve set.
            let key = (
                [f.l1, f.l3, f.l4, f.l5].map(f64::to_bits),
                r.num(),
                r.den(),
                (f.phase.rem_euclid(360.0 / r.den() as f64)).to_bits(),
            );
            assert!(seen.insert(key), "{l:?} repeats another's curves");
        }
        for l in linkages {
            if let coupler_kinematics::Linkage::GearedFiveBar(f) = l {
                assert!(f.ratio.den() == 1 || f.phase < 180.0, "{l:?}");
            }
        }
    }

    /// The count, the skipped classes and the linkages read one enumeration, shared by
    /// clones of the spec (a job holds a clone), and equal to a fresh one.
    #[test]
    fn a_geared_grid_is_enumerated_once() {
        let text = include_str!("../../../atlas-spec/geared-quick.toml");
        let spec = Spec::parse(text, "geared-quick").unwrap();
        let g = spec.geared.as_ref().unwrap();
        assert_eq!(format!("{:?}", g.enumerated), "not enumerated yet");
        let copy = spec.clone();
        assert_eq!(spec.count_linkages(), 8);
        let shared = copy.geared.as_ref().unwrap();
        assert_eq!(format!("{:?}", shared.enumerated), "enumerated");
        assert!(std::ptr::eq(g.enumeration(), shared.enumeration()));
        assert_eq!(*g.enumeration(), g.enumerate());
        assert_eq!(copy.skipped(), g.enumerate().1);
        assert_eq!(copy.atlas_linkages().collect::<Vec<_>>(), g.enumerate().0);
        // A cache, not part of the value.
        assert_eq!(Spec::parse(text, "geared-quick").unwrap(), spec);
    }
}
