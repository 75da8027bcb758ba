//! The input-angle tables of a run over many linkages, built once and shared:
//! [`AngleTables`]. A four-bar's pose table needs the crank table (the input angles and
//! their sines and cosines); a geared five-bar's also needs the second crank's angle at
//! each input angle ([`GearTable`]), which depends only on the gears (λ, φ) and the step,
//! not on the lengths: one table serves every linkage with those gears.

use crate::curve::{CrankTable, PoseTable};
use crate::geared::{GearRatio, GearTable};
use crate::linkage::Circuit;
use crate::mechanism::{Linkage, Mechanism};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};

/// At most this many gear tables are kept; a run with more gears than that builds the
/// others per linkage (as [`Mechanism::pose_table`] does), so memory stays bounded
/// whatever the spec (a table is under 100 bytes per angle of its period).
pub const MAX_SHARED_TABLES: usize = 64;

/// The crank table at one step and, built on first use and shared between threads, the
/// gear table of each (λ, φ). Its pose tables are
/// [`Mechanism::pose_table`]'s over the mechanism's period to the bit (tested).
///
/// ```
/// use coupler_kinematics::{AngleTables, Circuit, CrankTable, GearRatio, GearedFiveBar, Linkage, Mechanism};
/// let tables = AngleTables::new(2.0).unwrap();
/// let g = GearedFiveBar::new(3.0, 3.0, 3.0, 1.0, GearRatio::new(-1, 2).unwrap(), 90.0).unwrap();
/// let poses = tables.pose_table(&Linkage::from(g), Circuit::Open);
/// assert_eq!(poses.len(), 360); // two input turns at 2°
/// let own = g.pose_table(Circuit::Open, &CrankTable::over(2.0, 720.0).unwrap());
/// assert_eq!(poses.e_x, own.e_x);
/// ```
#[derive(Debug)]
pub struct AngleTables {
    crank: CrankTable,
    shared: Mutex<Shared>,
}

#[derive(Debug, Default)]
struct Shared {
    /// Gear tables by (λ, φ's bits, the step's bits).
    gears: HashMap<(GearRatio, u64, u64), Arc<GearTable>>,
    /// Crank tables at steps other than the run's, by the step's bits.
    cranks: HashMap<u64, Arc<CrankTable>>,
}

impl AngleTables {
    /// The tables at `step_deg` degrees of input. `None` unless the step is valid for a
    /// crank table ([`CrankTable::new`]).
    pub fn new(step_deg: f64) -> Option<AngleTables> {
        Some(AngleTables {
            crank: CrankTable::new(step_deg)?,
            shared: Mutex::default(),
        })
    }

    /// The step, degrees.
    pub fn step(&self) -> f64 {
        self.crank.step()
    }

    /// The crank table over one turn.
    pub fn crank(&self) -> &CrankTable {
        &self.crank
    }

    /// The gear table of λ = `ratio`, φ = `phase` at this step (built on first use).
    pub fn gears(&self, ratio: GearRatio, phase: f64) -> Option<Arc<GearTable>> {
        self.gears_at(ratio, phase, self.step())
    }

    /// The gear table of λ = `ratio`, φ = `phase` at `step_deg` (built on first use).
    pub fn gears_at(&self, ratio: GearRatio, phase: f64, step_deg: f64) -> Option<Arc<GearTable>> {
        let key = (ratio, phase.to_bits(), step_deg.to_bits());
        if let Some(t) = self.lock().gears.get(&key) {
            return Some(t.clone());
        }
        // Built outside the lock: another thread may build the same table meanwhile
        // (the same bits); the first one stored is kept.
        let t = Arc::new(GearTable::new(ratio, phase, step_deg)?);
        let mut shared = self.lock();
        if let Some(kept) = shared.gears.get(&key) {
            return Some(kept.clone());
        }
        if shared.gears.len() < MAX_SHARED_TABLES {
            shared.gears.insert(key, t.clone());
        }
        Some(t)
    }

    /// The poses of `linkage` on `circuit` at every angle of its period: exactly
    /// `linkage.pose_table(circuit, &CrankTable::over(step, period))`, a geared five-bar's
    /// from the shared gear table. An invalid period or phase (which a validated linkage
    /// never has) gives the per-linkage table's answer.
    pub fn pose_table(&self, linkage: &Linkage, circuit: Circuit) -> PoseTable {
        match linkage {
            Linkage::FourBar(l) => l.pose_table(circuit, &self.crank),
            Linkage::GearedFiveBar(g) => match self.gears(g.ratio, g.phase) {
                Some(gears) => g.gear_pose_table(circuit, &gears),
                None => match CrankTable::over(self.step(), g.period_deg()) {
                    Some(t) => g.pose_table(circuit, &t),
                    None => PoseTable::from_frames(&self.crank, |_| None),
                },
            },
        }
    }

    /// The crank table over one turn at `step_deg` (this run's, or another built on first
    /// use and kept, up to [`MAX_SHARED_TABLES`]).
    fn crank_at(&self, step_deg: f64) -> Option<Arc<CrankTable>> {
        let key = step_deg.to_bits();
        if let Some(t) = self.lock().cranks.get(&key) {
            return Some(t.clone());
        }
        let t = Arc::new(CrankTable::new(step_deg)?);
        let mut shared = self.lock();
        if let Some(kept) = shared.cranks.get(&key) {
            return Some(kept.clone());
        }
        if shared.cranks.len() < MAX_SHARED_TABLES {
            shared.cranks.insert(key, t.clone());
        }
        Some(t)
    }

    /// [`AngleTables::pose_table`] at another step: exactly
    /// `linkage.pose_table(circuit, &CrankTable::over(step_deg, period))`, from a crank
    /// table and gear tables at that step shared like this run's (the features' 5°
    /// samples, the pages' 2° extents). A step no crank table takes gives the
    /// per-linkage table's answer.
    pub fn pose_table_at(&self, linkage: &Linkage, circuit: Circuit, step_deg: f64) -> PoseTable {
        if step_deg.to_bits() == self.step().to_bits() {
            return self.pose_table(linkage, circuit);
        }
        let own = || match CrankTable::over(step_deg, linkage.period_deg()) {
            Some(t) => linkage.pose_table(circuit, &t),
            None => PoseTable::from_frames(&self.crank, |_| None),
        };
        match linkage {
            Linkage::FourBar(l) => match self.crank_at(step_deg) {
                Some(t) => l.pose_table(circuit, &t),
                None => own(),
            },
            Linkage::GearedFiveBar(g) => match self.gears_at(g.ratio, g.phase, step_deg) {
                Some(gears) => g.gear_pose_table(circuit, &gears),
                None => own(),
            },
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Shared> {
        // The map only ever holds complete tables: a panic elsewhere leaves it usable.
        self.shared.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FourBar, GearedFiveBar};

    fn bits(t: &PoseTable) -> Vec<[u64; 5]> {
        (0..t.len())
            .map(|k| [t.pa_x[k], t.pa_y[k], t.e_x[k], t.e_y[k], t.omega[k]].map(f64::to_bits))
            .collect()
    }

    #[test]
    fn shared_tables_give_the_mechanisms_own_poses_to_the_bit() {
        let tables = AngleTables::new(1.5).unwrap();
        let mut linkages: Vec<Linkage> = vec![FourBar::new(2.5, 3.0, 3.5).unwrap().into()];
        for (n, d) in [(-1, 1), (-2, 1), (2, 1), (-1, 2), (3, 4)] {
            for phase in [0.0, 90.0, 137.5] {
                for (l1, l3, l4, l5) in [(3.0, 3.0, 3.0, 1.0), (2.0, 1.0, 1.0, 1.5)] {
                    let ratio = GearRatio::new(n, d).unwrap();
                    linkages.push(
                        GearedFiveBar::new(l1, l3, l4, l5, ratio, phase)
                            .unwrap()
                            .into(),
                    );
                }
            }
        }
        // Twice over: the second pass reads the stored tables.
        for _ in 0..2 {
            for l in &linkages {
                for circuit in [Circuit::Open, Circuit::Crossed] {
                    let own =
                        l.pose_table(circuit, &CrankTable::over(1.5, l.period_deg()).unwrap());
                    let shared = tables.pose_table(l, circuit);
                    assert_eq!(bits(&shared), bits(&own), "{l} {circuit}");
                    assert_eq!(shared.valid, own.valid, "{l} {circuit}");
                }
            }
        }
        assert_eq!(tables.lock().gears.len(), 15);
        // At other steps (the features' 5°, the pages' 2°), likewise to the bit.
        for step in [5.0, 2.0] {
            for l in &linkages {
                for circuit in [Circuit::Open, Circuit::Crossed] {
                    let own =
                        l.pose_table(circuit, &CrankTable::over(step, l.period_deg()).unwrap());
                    let shared = tables.pose_table_at(l, circuit, step);
                    assert_eq!(bits(&shared), bits(&own), "{l} {circuit} at {step}°");
                    assert_eq!(shared.valid, own.valid, "{l} {circuit} at {step}°");
                }
            }
        }
        assert_eq!(tables.lock().gears.len(), 45);
        assert_eq!(tables.lock().cranks.len(), 2);
    }

    #[test]
    fn stored_tables_are_bounded() {
        let tables = AngleTables::new(10.0).unwrap();
        for k in 0..2 * MAX_SHARED_TABLES {
            assert!(
                tables
                    .gears(GearRatio::integer(-1).unwrap(), k as f64)
                    .is_some()
            );
        }
        assert_eq!(tables.lock().gears.len(), MAX_SHARED_TABLES);
    }
}
