//! `[geared]`: the linkages of a geared five-bar atlas (`atlas-spec/geared-fivebar.toml`,
//! docs/spec-format.md): ranges of L1, L3, L4, L5 (input crank = 1), a list of gear
//! ratios and a range of phases. The atlas holds the combinations whose input turns
//! fully ([`Rotatability::Full`], as the four-bar atlas holds crank-rockers); the others
//! are counted by Ting class.

use crate::ranges::DecimalRange;
use coupler_kinematics::{GearRatio, GearedFiveBar, Linkage, MARGIN_TOL, Rotatability};
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
    /// what the input does (`"II rocks"`, `"III touches a toggle"`). Made on first use,
    /// then shared (by clones of the ranges too).
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
        let phases = f(&self.phases);
        for &ratio in &self.ratios {
            for &phase in &phases {
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

#[cfg(test)]
mod tests {
    use crate::Spec;

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
