//! The linkage lattice of an atlas, for the coarse-to-fine open search
//! (`docs/shape-search.md`, "The lattice search").
//!
//! Each linkage (a run of curves sharing a linkage and circuit, [`linkage_groups`]) gets
//! lattice coordinates: per dimension of its mechanism (a four-bar's A, B, C; a geared
//! five-bar's L1, L3, L4, L5, gear ratio and phase) the rank of its value among the
//! distinct values that dimension takes in the atlas. So a regular atlas (the dense one:
//! A, B, C from 1.5 to 6 in steps of 0.125) is its own lattice, and any other atlas gets
//! one too (irregular steps become unit steps of rank). Two linkages are neighbours within
//! `r` when they share the circuit and no rank differs by more than `r`.
//!
//! [`linkage_groups`]: crate::open::linkage_groups

use crate::kin::AtlasCurve;
use coupler_kinematics::{Circuit, Linkage};
use std::collections::HashMap;
use std::ops::Range;

/// Most dimensions of a mechanism (a geared five-bar's six).
const DIMS: usize = 6;

fn values(l: &Linkage) -> [f64; DIMS] {
    match l {
        Linkage::FourBar(f) => [f.coupler, f.rocker, f.ground, 0.0, 0.0, 0.0],
        Linkage::GearedFiveBar(g) => [g.l1, g.l3, g.l4, g.l5, g.ratio.value(), g.phase],
    }
}

type Key = (Circuit, [u32; DIMS]);

/// The lattice coordinates of an atlas's linkages.
#[derive(Clone, Debug)]
pub struct LinkageLattice {
    /// Per linkage (in atlas order): its circuit and ranks.
    keys: Vec<Key>,
    /// The dimensions that take more than one value.
    live: Vec<usize>,
    /// Linkages by key (several, should an atlas list one linkage in separate runs).
    at: HashMap<Key, Vec<usize>>,
}

impl LinkageLattice {
    /// The lattice of the linkages `groups` (runs of `curves` as [`linkage_groups`] cuts
    /// them; an empty run is kept as a linkage of its own that no other neighbours).
    ///
    /// [`linkage_groups`]: crate::open::linkage_groups
    pub fn new(curves: &[AtlasCurve], groups: &[Range<usize>]) -> LinkageLattice {
        let vals: Vec<Option<(Circuit, [f64; DIMS])>> = groups
            .iter()
            .map(|g| {
                curves
                    .get(g.start)
                    .filter(|_| !g.is_empty())
                    .map(|c| (c.curve.circuit, values(&c.curve.linkage)))
            })
            .collect();
        let mut axes: Vec<Vec<f64>> = vec![Vec::new(); DIMS];
        for (_, v) in vals.iter().flatten() {
            for (axis, x) in axes.iter_mut().zip(v) {
                axis.push(*x);
            }
        }
        for axis in &mut axes {
            axis.sort_by(f64::total_cmp);
            axis.dedup_by(|a, b| a.total_cmp(b).is_eq());
        }
        let live = (0..DIMS).filter(|&d| axes[d].len() > 1).collect();
        let mut keys = Vec::with_capacity(groups.len());
        let mut at: HashMap<Key, Vec<usize>> = HashMap::new();
        for (i, v) in vals.iter().enumerate() {
            let key = match v {
                Some((circuit, v)) => {
                    let mut r = [0u32; DIMS];
                    for d in 0..DIMS {
                        r[d] = axes[d]
                            .binary_search_by(|x| x.total_cmp(&v[d]))
                            .expect("every value is on its axis")
                            as u32;
                    }
                    at.entry((*circuit, r)).or_default().push(i);
                    (*circuit, r)
                }
                // Not on the lattice: a rank no linkage has, so it neighbours none.
                None => (Circuit::Open, [u32::MAX; DIMS]),
            };
            keys.push(key);
        }
        LinkageLattice { keys, live, at }
    }

    /// Number of linkages.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// The sub-lattice: one linkage per cell of `cell` lattice steps a side (per circuit),
    /// the one nearest the cell's centre (ties: the first in atlas order). Ascending.
    pub fn sample(&self, cell: usize) -> Vec<usize> {
        let cell = cell.max(1) as u32;
        let mut best: HashMap<Key, (u32, usize)> = HashMap::new();
        for (i, (circuit, r)) in self.keys.iter().enumerate() {
            if r[0] == u32::MAX {
                continue;
            }
            let mut c = [0u32; DIMS];
            let mut off = 0u32;
            for &d in &self.live {
                c[d] = r[d] / cell;
                off += (2 * (r[d] % cell)).abs_diff(cell - 1);
            }
            best.entry((*circuit, c))
                .and_modify(|b| {
                    if off < b.0 {
                        *b = (off, i);
                    }
                })
                .or_insert((off, i));
        }
        let mut out: Vec<usize> = best.into_values().map(|b| b.1).collect();
        out.sort_unstable();
        out
    }

    /// The linkages within `radius` lattice steps of linkage `i` (the same circuit, no
    /// rank more than `radius` away), `i` itself excluded. Ascending.
    pub fn neighbours(&self, i: usize, radius: usize) -> Vec<usize> {
        let (circuit, r) = self.keys[i];
        if r[0] == u32::MAX {
            return Vec::new();
        }
        let radius = radius as i64;
        let n = self.live.len();
        let mut off = vec![-radius; n];
        let mut out = Vec::new();
        loop {
            let mut k = r;
            let mut ok = true;
            for (j, &d) in self.live.iter().enumerate() {
                let x = i64::from(r[d]) + off[j];
                if x < 0 || x >= i64::from(u32::MAX) {
                    ok = false;
                    break;
                }
                k[d] = x as u32;
            }
            if ok {
                if let Some(v) = self.at.get(&(circuit, k)) {
                    out.extend(v.iter().filter(|&&j| j != i));
                }
            }
            // The next offset (an odometer over [−radius, radius]^n).
            let mut j = 0;
            while j < n && off[j] == radius {
                off[j] = -radius;
                j += 1;
            }
            if j == n {
                break;
            }
            off[j] += 1;
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::LinkageLattice;
    use crate::kin::{AtlasCurve, CouplerCurve};
    use crate::open::linkage_groups;
    use coupler_kinematics::{Circuit, CouplerPoint, FourBar};

    /// A synthetic lattice atlas: A, B, C each `n` values (steps of 0.25 from 1.5) on
    /// both circuits, two coupler points a linkage, in the generator's order.
    fn lattice_atlas(n: usize) -> Vec<AtlasCurve> {
        let mut curves = Vec::new();
        let x = |k: usize| 1.5 + 0.25 * k as f64;
        for a in 0..n {
            for b in 0..n {
                for c in 0..n {
                    for circuit in [Circuit::Open, Circuit::Crossed] {
                        for u in [0.5, 1.0] {
                            curves.push(AtlasCurve {
                                id: curves.len() as u64,
                                curve: CouplerCurve::new(
                                    FourBar::new(x(a), x(b), x(c)).unwrap(),
                                    circuit,
                                    CouplerPoint::new(u, 0.5),
                                ),
                            });
                        }
                    }
                }
            }
        }
        curves
    }

    /// A linkage's ranks (A, B, C) and circuit, from its lengths.
    fn ranks(curves: &[AtlasCurve], g: &std::ops::Range<usize>) -> ([i64; 3], Circuit) {
        let c = &curves[g.start].curve;
        let f = c.linkage.four_bar().unwrap();
        let r = |x: f64| ((x - 1.5) / 0.25).round() as i64;
        ([r(f.coupler), r(f.rocker), r(f.ground)], c.circuit)
    }

    /// The sub-lattice holds one linkage per cell and circuit, the one nearest the
    /// cell's centre (ties: the first in atlas order), the same each time it is made.
    #[test]
    fn the_sub_lattice_is_one_linkage_per_cell_nearest_its_centre() {
        let curves = lattice_atlas(5);
        let groups = linkage_groups(&curves);
        assert_eq!(groups.len(), 250);
        let lattice = LinkageLattice::new(&curves, &groups);
        assert_eq!(lattice.len(), 250);
        for (cell, per_axis, offset) in [(1, 5, 0), (2, 3, 0), (3, 2, 1), (4, 2, 1), (5, 1, 2)] {
            let s = lattice.sample(cell);
            assert_eq!(s, lattice.sample(cell));
            assert_eq!(
                s.len(),
                2 * per_axis * per_axis * per_axis,
                "cell {cell}: {} linkages",
                s.len()
            );
            let mut cells = std::collections::HashSet::new();
            for &i in &s {
                let (r, circuit) = ranks(&curves, &groups[i]);
                assert!(cells.insert((r.map(|x| x / cell as i64), circuit)));
                // In a full cell the centre's (or the first of the nearest); the last,
                // cut short by the lattice's end, has its own.
                for x in r {
                    let k = x % cell as i64;
                    let full = x - k + cell as i64 <= 5;
                    assert!(!full || k == offset, "cell {cell}: ranks {r:?}");
                }
            }
        }
    }

    /// The neighbours within `radius` are exactly the linkages of the same circuit no
    /// rank of which is more than `radius` away (the linkage itself excluded), and the
    /// sub-lattice's neighbourhoods of radius `cell / 2` cover the whole lattice.
    #[test]
    fn neighbours_are_the_lattice_cube_around_a_linkage() {
        let curves = lattice_atlas(5);
        let groups = linkage_groups(&curves);
        let lattice = LinkageLattice::new(&curves, &groups);
        for radius in [1, 2] {
            for i in 0..groups.len() {
                let (r, circuit) = ranks(&curves, &groups[i]);
                let want: Vec<usize> = (0..groups.len())
                    .filter(|&j| {
                        let (q, c) = ranks(&curves, &groups[j]);
                        j != i
                            && c == circuit
                            && (0..3).all(|d| (q[d] - r[d]).abs() <= radius as i64)
                    })
                    .collect();
                assert_eq!(
                    lattice.neighbours(i, radius),
                    want,
                    "linkage {i} radius {radius}"
                );
            }
        }
        // An interior linkage has 26 neighbours within one step, a corner 7.
        let interior = (0..groups.len())
            .find(|&i| ranks(&curves, &groups[i]).0 == [2, 2, 2])
            .unwrap();
        assert_eq!(lattice.neighbours(interior, 1).len(), 26);
        assert_eq!(lattice.neighbours(0, 1).len(), 7);
        for cell in [2, 3, 4, 5] {
            let mut covered = vec![false; groups.len()];
            for i in lattice.sample(cell) {
                covered[i] = true;
                for j in lattice.neighbours(i, cell / 2) {
                    covered[j] = true;
                }
            }
            assert!(covered.iter().all(|&c| c), "cell {cell}");
        }
    }
}
