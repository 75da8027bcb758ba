//! Counting a grid spec's linkages by Barker class without enumerating them, and
//! streaming its strict crank-rockers in atlas order without holding them.
//!
//! A spec's link lengths are three decimal ranges `A × B × C` (crank = 1), up to
//! 100,000 values each: up to 10^15 combinations, far too many to classify one by one
//! before a run starts (a `--dry-run` must answer at once). The class of `(1, A, B, C)`
//! is decided exactly ([`FourBar::class`]), and for fixed `A` and `B` it is piecewise
//! constant in `C`: it can only change where `C` meets one of `1, A, B` (the sorted
//! order changes) or where Grashof's sum `s + l − p − q` is zero, i.e. at
//! `x1 + x2 − x3`, `x1 + x3 − x2` or `x2 + x3 − x1` (`x1 ≤ x2 ≤ x3` the sorted
//! `1, A, B`). For fixed `A`, these breakpoints are linear in `B` and keep their order
//! between the few values of `B` where two of them meet (`B = 1`, `B = A`, and where
//! `x1 + x3 = 2·x2`). So the count of each class is, for each `A`, a handful of sums over
//! a range of `B` of "lattice values of `C` between two linear functions of `B`": sums of
//! `⌊(s·j + t)/m⌋`, which have a closed form ([`floor_sum`]). Work is `O(|A| · log)`
//! whatever the sizes of `B` and `C`.
//!
//! Every value is an integer on the lattice `10^E` common to the three ranges (a spec
//! value has at most 15 significant digits, so the `f64` each value becomes reads back as
//! the same decimal, and the counts agree with [`FourBar::class`] exactly; tested against
//! enumeration).

use crate::ranges::{DecimalRange, LinkageRanges};
use coupler_kinematics::{Class, Decimal, FourBar, Linkage};
use std::cmp::Ordering;
use std::collections::BTreeMap;

/// A range on the integer lattice: `start + k·step` for `k` in `0..n` (`step > 0`).
#[derive(Clone, Copy, Debug)]
struct Lattice {
    start: i128,
    step: i128,
    n: i128,
}

impl Lattice {
    fn value(&self, k: i128) -> i128 {
        self.start + k * self.step
    }
    fn last(&self) -> i128 {
        self.value(self.n - 1)
    }
}

/// The three link ranges and the crank on one integer lattice.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LinkLattice {
    one: i128,
    exponent: i32,
    a: Lattice,
    b: Lattice,
    c: Lattice,
}

/// `m · 10^(from − to)` for `from ≥ to`, or `None` on overflow.
fn rescale(m: i128, from: i32, to: i32) -> Option<i128> {
    let mut x = m;
    for _ in 0..(from - to) {
        x = x.checked_mul(10)?;
    }
    Some(x)
}

impl LinkLattice {
    /// The ranges on their common lattice; `None` if a range is empty or the integers
    /// do not fit (not for a validated spec).
    pub(crate) fn of(l: &LinkageRanges) -> Option<LinkLattice> {
        let ranges = [l.coupler, l.rocker, l.ground];
        let exponent = ranges
            .iter()
            .flat_map(|r| [r.start.exponent(), r.step.exponent()])
            .chain([0])
            .min()?;
        let lat = |r: &DecimalRange| -> Option<Lattice> {
            let n = i128::from(r.len());
            (n > 0).then_some(())?;
            Some(Lattice {
                start: rescale(r.start.mantissa(), r.start.exponent(), exponent)?,
                step: rescale(r.step.mantissa(), r.step.exponent(), exponent)?,
                n,
            })
        };
        let out = LinkLattice {
            one: rescale(1, 0, exponent)?,
            exponent,
            a: lat(&l.coupler)?,
            b: lat(&l.rocker)?,
            c: lat(&l.ground)?,
        };
        // Keep every intermediate (sums of three values, times 4, times a count) far
        // inside i128.
        let big = [out.one, out.a.last(), out.b.last(), out.c.last()]
            .into_iter()
            .max()?;
        (big < 1_000_000_000_000_000_000_000_000 && out.a.step > 0 && out.b.step > 0).then_some(out)
    }

    fn length(&self, x: i128) -> f64 {
        Decimal::new(x, self.exponent).to_f64()
    }
}

/// Barker's class of `(crank, coupler, rocker, ground)`, exactly as
/// [`FourBar::class`] decides it, on integers.
pub(crate) fn class_of(crank: i128, coupler: i128, rocker: i128, ground: i128) -> Class {
    let links = [ground, crank, coupler, rocker];
    let mut sorted = links;
    sorted.sort_unstable();
    let [s, p, q, l] = sorted;
    let which = |x: i128| links.iter().position(|&y| y == x).unwrap_or(0);
    match (s + l).cmp(&(p + q)) {
        Ordering::Less => [Class::Gccc, Class::Gcrr, Class::Grcr, Class::Grrc][which(s)],
        Ordering::Greater => [Class::Rrr1, Class::Rrr2, Class::Rrr3, Class::Rrr4][which(l)],
        Ordering::Equal => {
            if s == l {
                Class::S3x
            } else if s == p || q == l {
                Class::S2x
            } else {
                [Class::Sccc, Class::Scrr, Class::Srcr, Class::Srrc][which(s)]
            }
        }
    }
}

/// `Σ_{i=0}^{n−1} ⌊(a·i + b)/m⌋` for `n ≥ 0`, `m > 0`, `a ≥ 0` and any `b` (the classic
/// Euclid-like reduction, `O(log m)`).
fn floor_sum(n: i128, m: i128, a: i128, b: i128) -> i128 {
    if n <= 0 {
        return 0;
    }
    let (mut n, mut m, mut a) = (n, m, a);
    let mut ans = n * b.div_euclid(m);
    let mut b = b.rem_euclid(m);
    loop {
        if a >= m {
            ans += n * (n - 1) / 2 * (a / m);
            a %= m;
        }
        if b >= m {
            ans += n * (b / m);
            b %= m;
        }
        let y_max = a * n + b;
        if y_max < m {
            break;
        }
        n = y_max / m;
        b = y_max % m;
        std::mem::swap(&mut m, &mut a);
    }
    ans
}

/// `⌈x / y⌉` for `y > 0`.
fn ceil_div(x: i128, y: i128) -> i128 {
    -((-x).div_euclid(y))
}

/// `Σ_{j=j0}^{j1} clamp(⌊(s·j + t)/m⌋, lo, hi)` (`m > 0`, `lo ≤ hi`; 0 when `j0 > j1`).
fn clamped_floor_sum(j0: i128, j1: i128, s: i128, t: i128, m: i128, lo: i128, hi: i128) -> i128 {
    if j0 > j1 {
        return 0;
    }
    let n = j1 - j0 + 1;
    if s == 0 {
        return n * t.div_euclid(m).clamp(lo, hi);
    }
    // Make the slope positive (j → −j) and start at i = 0.
    let (s, j0) = if s < 0 { (-s, -j1) } else { (s, j0) };
    let t = t + s * j0;
    // ⌊(s·i + t)/m⌋ is non-decreasing in i: below lo before i_lo, at least hi from i_hi.
    let i_lo = ceil_div(lo * m - t, s).clamp(0, n);
    let i_hi = ceil_div(hi * m - t, s).clamp(i_lo, n);
    lo * i_lo + floor_sum(i_hi - i_lo, m, s, t + s * i_lo) + hi * (n - i_hi)
}

/// A breakpoint in `C`, linear in `B`: `cb·B + k`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Lin {
    cb: i128,
    k: i128,
}

impl Lin {
    fn at(self, b: i128) -> i128 {
        self.cb * b + self.k
    }
    fn plus(self, o: Lin) -> Lin {
        Lin {
            cb: self.cb + o.cb,
            k: self.k + o.k,
        }
    }
    fn minus(self, o: Lin) -> Lin {
        Lin {
            cb: self.cb - o.cb,
            k: self.k - o.k,
        }
    }
}

impl LinkLattice {
    /// `Σ_{j=j0}^{j1} #{k : c_k < f(b_j)}` (`strict`) or `#{k : c_k ≤ f(b_j)}`.
    fn sum_below(&self, j0: i128, j1: i128, f: Lin, strict: bool) -> i128 {
        let (b, c) = (self.b, self.c);
        // c0 + k·dc < x  ⟺  k < (x − c0)/dc  ⟺  k ≤ ⌈(x − c0)/dc⌉ − 1: count ⌈(x − c0)/dc⌉
        // = ⌊(x − c0 + dc − 1)/dc⌋; for ≤, ⌊(x − c0)/dc⌋ + 1 = ⌊(x − c0 + dc)/dc⌋.
        let extra = if strict { c.step - 1 } else { c.step };
        let s = f.cb * b.step;
        let t = f.cb * b.start + f.k - c.start + extra;
        clamped_floor_sum(j0, j1, s, t, c.step, 0, c.n)
    }

    /// Adds the count of every class over `a × {b_j : j0 ≤ j ≤ j1} × C` to `out`, for a
    /// range of `j` in which the breakpoints keep a strict order (else it splits).
    fn add_range(&self, a: i128, j0: i128, j1: i128, out: &mut [i128; 14]) {
        if j0 > j1 {
            return;
        }
        let one = self.one;
        let bj0 = self.b.value(j0);
        let mut xs = [
            Lin { cb: 0, k: one },
            Lin { cb: 0, k: a },
            Lin { cb: 1, k: 0 },
        ];
        xs.sort_by_key(|x| x.at(bj0));
        let [x1, x2, x3] = xs;
        let mut f = vec![
            x1.plus(x2).minus(x3),
            x1,
            x2,
            x3,
            x1.plus(x3).minus(x2),
            x2.plus(x3).minus(x1),
        ];
        if j0 == j1 {
            f.sort_by_key(|g| g.at(bj0));
            f.dedup_by_key(|g| g.at(bj0));
        } else {
            f.sort_by_key(|g| (g.at(bj0), g.cb));
            f.dedup();
            let bj1 = self.b.value(j1);
            let strict = f
                .windows(2)
                .all(|w| w[0].at(bj0) < w[1].at(bj0) && w[0].at(bj1) < w[1].at(bj1));
            if !strict {
                // Two breakpoints meet inside: cannot happen between the cut points, but
                // splitting keeps the count exact whatever happens.
                let mid = j0 + (j1 - j0) / 2;
                self.add_range(a, j0, mid, out);
                self.add_range(a, mid + 1, j1, out);
                return;
            }
        }
        let n = j1 - j0 + 1;
        // Pieces of the C axis at bj0 (doubled, so that midpoints are integers): below the
        // first breakpoint, each breakpoint, between two, above the last.
        let class2 = |c2: i128| class_of(2 * one, 2 * a, 2 * bj0, c2) as usize;
        let first = f[0];
        out[class2(2 * first.at(bj0) - 1)] += self.sum_below(j0, j1, first, true);
        for (i, &g) in f.iter().enumerate() {
            let at_most = self.sum_below(j0, j1, g, false);
            out[class2(2 * g.at(bj0))] += at_most - self.sum_below(j0, j1, g, true);
            let (above, upto) = match f.get(i + 1) {
                Some(&h) => (
                    class2(g.at(bj0) + h.at(bj0)),
                    self.sum_below(j0, j1, h, true),
                ),
                None => (class2(2 * g.at(bj0) + 1), n * self.c.n),
            };
            out[above] += upto - at_most;
        }
    }

    /// Counts of each class (indexed by `Class as usize`).
    fn count(&self) -> [i128; 14] {
        let mut out = [0i128; 14];
        let (one, b) = (self.one, self.b);
        for i in 0..self.a.n {
            let a = self.a.value(i);
            let (lo, hi) = (one.min(a), one.max(a));
            // Doubled values of B where two breakpoints meet.
            let critical = [
                2 * one,
                2 * a,
                2 * (2 * lo - hi),
                one + a,
                2 * (2 * hi - lo),
            ];
            let mut cuts = vec![0, b.n];
            for v in critical {
                // First j with 2·b_j ≥ v; if 2·b_j = v there, j is a range of its own.
                let j = ceil_div(v - 2 * b.start, 2 * b.step);
                cuts.push(j.clamp(0, b.n));
                if (0..b.n).contains(&j) && 2 * b.value(j) == v {
                    cuts.push(j + 1);
                }
            }
            cuts.sort_unstable();
            cuts.dedup();
            for w in cuts.windows(2) {
                self.add_range(a, w[0], w[1] - 1, &mut out);
            }
        }
        out
    }
}

impl LinkLattice {
    /// The strict crank-rockers: `|A − B| + 1 < C < A + B − 1`, which needs A > 1 and
    /// B > 1; for each A, two sums over B (below A and from A on), four closed forms.
    fn count_crank_rockers(&self) -> i128 {
        let (one, b) = (self.one, self.b);
        let first_above = |x: i128| ((x - b.start).div_euclid(b.step) + 1).clamp(0, b.n);
        let first_at_least = |x: i128| ceil_div(x - b.start, b.step).clamp(0, b.n);
        let j_one = first_above(one);
        let mut total = 0;
        for i in 0..self.a.n {
            let a = self.a.value(i);
            if a <= one {
                continue;
            }
            let j_a = first_at_least(a).max(j_one);
            let hi = Lin { cb: 1, k: a - one };
            // B < A: C > A − B + 1; B ≥ A: C > B − A + 1.
            let (lo_below, lo_above) = (Lin { cb: -1, k: a + one }, Lin { cb: 1, k: one - a });
            total += self.sum_below(j_one, j_a - 1, hi, true)
                - self.sum_below(j_one, j_a - 1, lo_below, false);
            total += self.sum_below(j_a, b.n - 1, hi, true)
                - self.sum_below(j_a, b.n - 1, lo_above, false);
        }
        total
    }
}

/// The number of strict crank-rockers (`GCRR`) in the ranges, counted arithmetically.
pub(crate) fn count_crank_rockers(l: &LinkageRanges) -> u64 {
    LinkLattice::of(l)
        .map(|g| g.count_crank_rockers() as u64)
        .unwrap_or(0)
}

/// The combinations in the ranges by Barker class code, counted arithmetically (classes
/// with none are left out).
pub(crate) fn count_by_class(l: &LinkageRanges) -> BTreeMap<&'static str, u64> {
    let counts = LinkLattice::of(l).map(|g| g.count()).unwrap_or([0; 14]);
    Class::ALL
        .iter()
        .zip(counts)
        .filter(|(_, n)| *n > 0)
        .map(|(&c, n)| (c.code(), n as u64))
        .collect()
}

/// The strict crank-rockers of a spec in atlas order (A, then B, then C ascending),
/// produced one at a time: memory stays constant whatever the ranges. For each (A, B)
/// only the values of C with `|A − B| + 1 < C < A + B − 1` are visited, and only the B
/// for which that interval meets the range of C.
#[derive(Clone, Debug)]
pub struct CrankRockers {
    lat: Option<LinkLattice>,
    /// The current A and B indices, the next C index and the end of C's run.
    i: i128,
    j: i128,
    j_end: i128,
    k: i128,
    k_end: i128,
    /// The values as `f64` (at most 100,000 per range).
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
}

impl CrankRockers {
    pub(crate) fn new(l: &LinkageRanges) -> CrankRockers {
        let lat = LinkLattice::of(l);
        let values = |r: Option<Lattice>| -> Vec<f64> {
            match (lat, r) {
                (Some(g), Some(r)) => (0..r.n).map(|k| g.length(r.value(k))).collect(),
                _ => Vec::new(),
            }
        };
        let mut it = CrankRockers {
            lat,
            i: -1,
            j: 0,
            j_end: 0,
            k: 0,
            k_end: 0,
            a: values(lat.map(|g| g.a)),
            b: values(lat.map(|g| g.b)),
            c: values(lat.map(|g| g.c)),
        };
        it.next_a();
        it
    }

    /// Moves to the next A with its window of B (`j..j_end`); false at the end.
    fn next_a(&mut self) -> bool {
        let Some(g) = self.lat else { return false };
        self.i += 1;
        if self.i >= g.a.n {
            return false;
        }
        let a = g.a.value(self.i);
        let (c_lo, c_hi) = (g.c.start, g.c.last());
        // Some C with |A − B| + 1 < C < A + B − 1 needs B > c_lo + 1 − A and
        // |A − B| < c_hi − 1.
        let b_min = (c_lo + g.one - a).max(a - (c_hi - g.one));
        let b_max = a + (c_hi - g.one);
        // j with b_j > b_min and b_j < b_max.
        self.j = ((b_min - g.b.start).div_euclid(g.b.step) + 1).clamp(0, g.b.n);
        self.j_end = ceil_div(b_max - g.b.start, g.b.step).clamp(self.j, g.b.n);
        self.k = 0;
        self.k_end = 0;
        true
    }

    /// Sets the run of C for the current (A, B): `k..k_end`.
    fn set_c_run(&mut self, g: &LinkLattice) {
        let (a, b, c) = (g.a.value(self.i), g.b.value(self.j), g.c);
        let (lo, hi) = ((a - b).abs() + g.one, a + b - g.one);
        // First k with c_k > lo; first k with c_k ≥ hi.
        self.k = ((lo - c.start).div_euclid(c.step) + 1).clamp(0, c.n);
        self.k_end = ceil_div(hi - c.start, c.step).clamp(self.k, c.n);
    }
}

impl Iterator for CrankRockers {
    type Item = Linkage;

    fn next(&mut self) -> Option<Linkage> {
        let g = self.lat?;
        loop {
            if self.i >= g.a.n {
                return None;
            }
            if self.k < self.k_end {
                let (i, j, k) = (self.i as usize, self.j as usize, self.k as usize);
                self.k += 1;
                if self.k == self.k_end {
                    self.j += 1;
                }
                let l = FourBar::new(self.a[i], self.b[j], self.c[k]).ok()?;
                return Some(Linkage::FourBar(l));
            }
            if self.j < self.j_end && self.k == self.k_end {
                self.set_c_run(&g);
                if self.k == self.k_end {
                    self.j += 1;
                }
                continue;
            }
            if !self.next_a() {
                return None;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Spec;

    fn ranges(a: (&str, &str, &str), b: (&str, &str, &str), c: (&str, &str, &str)) -> Spec {
        let text = format!(
            "[atlas]\nname = \"t\"\n[linkages]\ncoupler = {{ start = {}, end = {}, step = {} }}\nrocker = {{ start = {}, end = {}, step = {} }}\nground = {{ start = {}, end = {}, step = {} }}\n[points]\nu = {{ start = 0, end = 0, step = 1 }}\nv = {{ start = 0, end = 0, step = 1 }}\n",
            a.0, a.1, a.2, b.0, b.1, b.2, c.0, c.1, c.2
        );
        Spec::parse(&text, "t.toml").unwrap()
    }

    fn brute(spec: &Spec) -> (BTreeMap<&'static str, u64>, Vec<Linkage>) {
        let mut classes = BTreeMap::new();
        let mut linkages = Vec::new();
        for a in spec.linkages.coupler.values() {
            for b in spec.linkages.rocker.values() {
                for c in spec.linkages.ground.values() {
                    let l = FourBar::new(a.to_f64(), b.to_f64(), c.to_f64()).unwrap();
                    *classes.entry(l.class().code()).or_default() += 1;
                    if l.class() == Class::Gcrr {
                        linkages.push(Linkage::FourBar(l));
                    }
                }
            }
        }
        (classes, linkages)
    }

    #[test]
    fn floor_sums_match_loops() {
        let mut seed = 0x1234_5678_9abc_def0u64;
        let mut rnd = |m: i128| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % m as u64) as i128
        };
        for _ in 0..2000 {
            let (j0, len) = (rnd(40) - 20, rnd(30) - 2);
            let (s, t, m) = (rnd(41) - 20, rnd(401) - 200, rnd(17) + 1);
            let (lo, hi) = (rnd(5) - 2, rnd(12));
            let want: i128 = (j0..=j0 + len)
                .map(|j| (s * j + t).div_euclid(m).clamp(lo, hi.max(lo)))
                .sum();
            assert_eq!(
                clamped_floor_sum(j0, j0 + len, s, t, m, lo, hi.max(lo)),
                want,
                "j {j0}+{len} s {s} t {t} m {m} [{lo}, {hi}]"
            );
        }
    }

    #[test]
    fn integer_classes_match_the_four_bar() {
        let vals = [0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.5, 5.0];
        for a in vals {
            for b in vals {
                for c in vals {
                    let l = FourBar::new(a, b, c).unwrap();
                    let i = |x: f64| (x * 2.0) as i128;
                    assert_eq!(class_of(2, i(a), i(b), i(c)), l.class(), "{a} {b} {c}");
                }
            }
        }
    }

    /// Arithmetic counts and the streamed crank-rockers equal a brute-force enumeration,
    /// on grids that meet every breakpoint (half units through 1 = crank), decimal steps
    /// and ranges that start below the crank.
    #[test]
    fn counts_and_stream_match_enumeration() {
        let cases = [
            (
                ("1.5", "4.5", "0.5"),
                ("1.5", "4.5", "0.5"),
                ("1.5", "4.5", "0.5"),
            ),
            (
                ("0.5", "5", "0.5"),
                ("0.5", "5", "0.5"),
                ("0.5", "9", "0.5"),
            ),
            (
                ("0.3", "3.3", "0.3"),
                ("0.1", "4.1", "0.2"),
                ("0.7", "6.2", "0.1"),
            ),
            (("1", "3", "0.25"), ("2", "2", "1"), ("0.25", "7", "0.125")),
            (("2.5", "2.5", "1"), ("0.35", "6", "0.45"), ("1", "1", "1")),
            (
                ("0.1", "9.9", "0.7"),
                ("0.2", "9.8", "0.6"),
                ("0.05", "12", "0.35"),
            ),
            (("3", "30", "3"), ("1.5", "40", "1.5"), ("1", "50", "0.5")),
        ];
        for (a, b, c) in cases {
            let spec = ranges(a, b, c);
            let (classes, linkages) = brute(&spec);
            assert_eq!(count_by_class(&spec.linkages), classes, "{a:?} {b:?} {c:?}");
            assert_eq!(
                count_crank_rockers(&spec.linkages),
                linkages.len() as u64,
                "{a:?} {b:?} {c:?}"
            );
            let streamed: Vec<Linkage> = CrankRockers::new(&spec.linkages).collect();
            assert_eq!(streamed, linkages, "{a:?} {b:?} {c:?}");
        }
    }

    /// Random small grids (starts, steps and lengths drawn from quarter and tenth units,
    /// so that breakpoints are often met exactly): counts and stream equal enumeration.
    #[test]
    fn random_grids_match_enumeration() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = |m: u64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed % m
        };
        for _ in 0..150 {
            let mut r = || {
                let unit = [0.25, 0.1, 0.5, 0.05][rnd(4) as usize];
                let start = (rnd(16) + 1) as f64 * unit;
                let step = (rnd(6) + 1) as f64 * unit;
                let n = rnd(14);
                let s = |x: f64| format!("{}", (x * 1e6).round() / 1e6);
                (s(start), s(start + n as f64 * step), s(step))
            };
            let (a, b, c) = (r(), r(), r());
            let spec = ranges((&a.0, &a.1, &a.2), (&b.0, &b.1, &b.2), (&c.0, &c.1, &c.2));
            let (classes, linkages) = brute(&spec);
            assert_eq!(count_by_class(&spec.linkages), classes, "{a:?} {b:?} {c:?}");
            let streamed: Vec<Linkage> = CrankRockers::new(&spec.linkages).collect();
            assert_eq!(streamed, linkages, "{a:?} {b:?} {c:?}");
            assert_eq!(count_crank_rockers(&spec.linkages), linkages.len() as u64);
            let g = LinkLattice::of(&spec.linkages).unwrap();
            assert_eq!(g.count()[Class::Gcrr as usize], linkages.len() as i128);
        }
    }

    /// 100,000 values per range (10^15 combinations): counted in well under a second,
    /// and the stream starts at once.
    #[test]
    fn huge_ranges_count_at_once() {
        let spec = ranges(
            ("1", "100000.99", "1"),
            ("1", "100000.99", "1"),
            ("1", "100000.99", "1"),
        );
        let t = std::time::Instant::now();
        let n = count_crank_rockers(&spec.linkages);
        assert!(n > 0 && n < 1_000_000_000_000_000, "{n}");
        let first: Vec<Linkage> = CrankRockers::new(&spec.linkages).take(3).collect();
        assert_eq!(first.len(), 3);
        // Generous for a loaded CI machine; typically a few tens of milliseconds.
        assert!(t.elapsed().as_secs_f64() < 5.0, "{:?}", t.elapsed());
        eprintln!(
            "crank-rockers of 10^15 combinations counted in {:?}",
            t.elapsed()
        );
        let t = std::time::Instant::now();
        let all: u64 = count_by_class(&spec.linkages).values().sum();
        assert_eq!(all, 1_000_000_000_000_000);
        eprintln!(
            "every class of 10^15 combinations counted in {:?}",
            t.elapsed()
        );
        // Integer ranges: for A, B ≥ 2, the C strictly inside (|A−B|+1, A+B−1) are
        // 2·min(A,B) − 3 integers, clipped to C ≤ 100,000.
        let small = ranges(("1", "60", "1"), ("1", "60", "1"), ("1", "60", "1"));
        let (_, l) = brute(&small);
        assert_eq!(count_crank_rockers(&small.linkages), l.len() as u64);
    }
}
