//! Open targets: a scan per **linkage**, not per curve.
//!
//! The coupler point enters the curve linearly: `M(θ) = Pa(θ) + w·e(θ)` with `w = u + iv`
//! (`Pa` the crank pin, `e` the unit vector along the coupler). So for target points
//! `y_j` supposed to be passed at crank angles `θ_j`, the fit `y_j ≈ a·M(θ_j) + b` over a
//! similarity `(a, b)` and the coupler point `w` is the *linear* least-squares problem
//! `y_j ≈ α·Pa(θ_j) + β·e(θ_j) + γ` in three complex unknowns (`α = a`, `β = a·w`,
//! `γ = b`): for a reflected match the same with `conj(y)`. One linkage (one table of
//! `Pa` and `e`, shared by all its coupler points) answers for every coupler point at
//! once, off the grid too.
//!
//! 1. **Hypotheses** place the target's points at `θ_j = θ_s + σ·Δ·x_j`: `x_j` the
//!    point's position along the path (untimed: the target resampled evenly in arc length,
//!    `x_j = j/(M−1)`, i.e. the crank supposed to turn evenly along the path; timed:
//!    from the given angles or steps), `Δ` the crank span (on a geometric grid, or given),
//!    `σ = ±1` the sense, `θ_s` the start (a grid over the turn). Each costs one `O(M)`
//!    pass; the misfit is taken at the best coupler point clamped to the box of the atlas
//!    grid for that linkage. The best local minima over `θ_s` of every linkage go on.
//! 2. **Re-estimation** (untimed): with the fitted curve, each point's crank angle is
//!    moved to the nearest point of the curve near its current angle (kept in order), and
//!    the linear problem solved again, a few times: the crank need not turn evenly along
//!    the path. Timed targets instead polish `θ_s` (and the step, when free).
//! 3. **Grid points**: with the final angles, every coupler point of the atlas on that
//!    linkage is scored in `O(1)` from the same sums; the best few become candidates,
//!    each with a start (reflection and one crank angle per target point) for the exact fit.

use crate::fit::Start;
use crate::geom::C64;
use crate::kin::AtlasCurve;
use crate::lattice::LinkageLattice;
use crate::smooth::{default_terms, smooth_resample};
use crate::target::{Target, Timing};
use coupler_kinematics::{Circuit, CrankTable, Linkage, Mechanism};
use rayon::prelude::*;

/// Most points of an untimed query (the target's own points, thinned by index).
const QUERY_POINTS: usize = 32;
/// Most points of a timed query (the target's own points, thinned by index).
const TIMED_QUERY_POINTS: usize = 32;
/// Re-estimations of the crank angles (untimed), at most (each while the misfit falls;
/// five before, and none loses retrieval cases: `docs/benchmarks.md`, "Open queries:
/// the exact stage's work cut").
const REESTIMATIONS: usize = 1;
/// Projection steps of stage 1b (untimed), on every curve.
const PROJECTIONS: usize = 10;
/// Projection steps every window of stage 1b gets; then only the best
/// [`PROJECTION_KEEP`] of each reflection of a coupler point go on to `PROJECTIONS`.
const PROJECTION_HEAT: usize = 3;
/// Windows of each coupler point and reflection projected to the end.
const PROJECTION_KEEP: usize = 2;

/// One linkage on one circuit at 1° crank steps over its period (360° for a four-bar,
/// `360°·q` for a geared five-bar of ratio p/q): crank pin and coupler direction, each
/// 1° cell with its start values and its differences to the next (the linear
/// interpolant's slopes, computed once per linkage instead of at every lookup).
struct Table {
    cells: Vec<TableCell>,
    /// Empty, or `cells` three times over (`ring[i] = cells[i % n]`,
    /// [`Table::with_ring`]): the cell of whole degree `w` in `−n..2n` is `ring[w + n]`,
    /// found without a remainder or a wrap ([`Table::flat_at_with`] on the AVX2 path).
    ring: Vec<TableCell>,
    /// The period, degrees of input.
    period: f64,
}

/// `Pa` and `e` at the start of a 1° cell and their differences across it (in the order
/// of [`Flat`], so that [`Table::flat_at_with`] reads and writes them as they lie).
#[derive(Clone, Copy)]
#[repr(C)]
struct TableCell {
    pa: C64,
    e: C64,
    dpa: C64,
    de: C64,
}

impl Table {
    fn new(linkage: &Linkage, circuit: Circuit) -> Option<Table> {
        Cranks::default().table(linkage, circuit)
    }

    /// [`Table::new`] from the crank angles of its `period` at 1° steps.
    fn with_crank(
        linkage: &Linkage,
        circuit: Circuit,
        period: f64,
        crank: &CrankTable,
    ) -> Option<Table> {
        let t = linkage.pose_table(circuit, crank);
        if !t.all_valid() {
            return None;
        }
        let n = t.len();
        let pa = |k: usize| C64::new(t.pa_x[k % n], t.pa_y[k % n]);
        let e = |k: usize| C64::new(t.e_x[k % n], t.e_y[k % n]);
        let cells = (0..n)
            .map(|k| TableCell {
                pa: pa(k),
                dpa: pa(k + 1) - pa(k),
                e: e(k),
                de: e(k + 1) - e(k),
            })
            .collect::<Vec<_>>();
        Some(Table {
            cells,
            ring: Vec::new(),
            period,
        })
    }

    /// Lays out [`Table::ring`] (stage 1's projection reads it; a table without it
    /// finds every cell by [`cell_floor`], the same cells).
    fn with_ring(mut self) -> Table {
        let n = self.cells.len();
        let mut ring = Vec::with_capacity(3 * n);
        for _ in 0..3 {
            for c in &self.cells {
                ring.push(*c);
            }
        }
        self.ring = ring;
        self
    }

    /// `(Pa, e)` at `deg` by linear interpolation.
    #[inline(always)]
    fn at(&self, deg: f64) -> (C64, C64) {
        let (k, t) = cell(deg, self.cells.len());
        let c = &self.cells[k];
        (c.pa + c.dpa * t, c.e + c.de * t)
    }

    /// `Pa`, `e`, `dPa/dθ`, `de/dθ` at `deg` (derivatives per degree, of the
    /// interpolant) as [`Flat`]: `Pa + dPa·t` and `e + de·t` lane by lane, as
    /// `num-complex` forms them (the same values as [`Table::at`]). The cell is found by
    /// [`cell_floor`] when `FLOOR` (where the processor rounds in one instruction: the
    /// AVX2 path), else by [`cell`]: the same cell and fraction.
    #[inline(always)]
    fn flat_at_with<const FLOOR: bool>(&self, deg: f64) -> Flat {
        let (c, t) = if FLOOR {
            self.ring_at(deg)
        } else {
            let (k, t) = cell(deg, self.cells.len());
            (&self.cells[k], t)
        };
        [
            c.pa.re + c.dpa.re * t,
            c.pa.im + c.dpa.im * t,
            c.e.re + c.de.re * t,
            c.e.im + c.de.im * t,
            c.dpa.re,
            c.dpa.im,
            c.de.re,
            c.de.im,
        ]
    }
}

impl Table {
    /// The cell of `deg` and the fraction into it, as [`cell_floor`] finds them (the same
    /// cell's values, the same fraction): on x86-64 the whole degrees `w` by one
    /// truncating conversion (`i64::MIN` for NaN and values out of range) and the cell
    /// `ring[w + n]` when that is inside the ring (`w` in `−n..2n`, where the scan's and
    /// the projection's angles lie), else by [`cell_floor`].
    #[inline(always)]
    fn ring_at(&self, deg: f64) -> (&TableCell, f64) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_cvttsd_si64, _mm_set_sd};
            let whole = deg.floor();
            // SAFETY: SSE2, which these two need, is part of every x86-64 processor.
            #[allow(unsafe_code)]
            let w = unsafe { _mm_cvttsd_si64(_mm_set_sd(whole)) };
            // `w + n` below zero wraps to far above the ring's length.
            let i = w.wrapping_add(self.cells.len() as i64) as usize;
            if let Some(c) = self.ring.get(i) {
                return (c, deg - whole);
            }
        }
        let (k, t) = cell_floor(deg, self.cells.len());
        (&self.cells[k], t)
    }
}

/// The crank angles of [`Table::new`] (1° steps over a period), kept between linkages:
/// they are the same for every linkage of one period.
#[derive(Default)]
struct Cranks(Option<(f64, Option<CrankTable>)>);

impl Cranks {
    /// [`Table::new`], the crank angles made again only when the period changes.
    fn table(&mut self, linkage: &Linkage, circuit: Circuit) -> Option<Table> {
        let period = linkage.period_deg();
        if self.0.as_ref().is_none_or(|(p, _)| *p != period) {
            self.0 = Some((period, CrankTable::over(1.0, period)));
        }
        let crank = self.0.as_ref()?.1.as_ref()?;
        Table::with_crank(linkage, circuit, period, crank)
    }
}

/// A table's values at whole degrees for stage 1's kernel sums ([`Kernel::sums`]): per
/// degree `k = 0, 1, …` over one period and on past it (wrapped, so that a kernel's
/// cells `base + d` need no remainder), `Pa`, `e` and `conj(Pa)·e` as `[re, im]` pairs.
struct Grid {
    cells: Vec<[[f64; 2]; 3]>,
    /// Whole degrees in one period.
    period: usize,
}

impl Grid {
    /// Cells past the period: every kernel's reach (a span of at most a period and two
    /// cells per point).
    const EXTRA: usize = 4;

    fn new(table: &Table) -> Grid {
        let n = table.cells.len();
        let cells = (0..2 * n + Grid::EXTRA)
            .map(|k| {
                let c = &table.cells[k % n];
                let x = c.pa.conj() * c.e;
                [[c.pa.re, c.pa.im], [c.e.re, c.e.im], [x.re, x.im]]
            })
            .collect();
        Grid { cells, period: n }
    }
}

/// Stage 1's sums for every **whole-degree** start of one span and sense: a hypothesis's
/// sums are sums over the target points of table functions at `start + o_j`
/// (`o_j = σ·Δ·x_j`), a correlation of the table with a comb of the offsets. Each
/// offset's weight (1 for `S_P`, `S_e`, `S_Pe`; `y_j` for the `R` sums) is spread linearly
/// onto the two whole degrees around it, so for a whole-degree start the kernel's sum of
/// `Pa` or `e` is the sum of their linear interpolants at the points (what [`Sums::of`]
/// adds up, to rounding), and `S_Pe` is the sum of the interpolants of the tabulated
/// product `conj(Pa)·e` (within `O(1°²)` of [`Sums::of`]'s products of interpolants).
/// The kernel depends on the target and the span only (not on the linkage, nor the
/// start): its cells, at most `Δ + 2` and at most two per point, replace the points'
/// lookups and interpolations.
struct Kernel {
    /// The offset of the first cell from the start, whole degrees.
    lo: i64,
    /// Nonzero cells.
    cells: Vec<KernelCell>,
    /// Points (the sums' `m`).
    count: u32,
}

/// One nonzero cell of a [`Kernel`]: its distance from `lo`, and the factors of the
/// seven `[re, im]` pair sums of [`Kernel::sums`], each twice, flat and in the order of
/// the lanes of [`Kernel::flat_sums`]: `w` four times (for `Pa` and `e`), `Re y·w` four
/// times, `Im y·w` four times (each again for `Pa` and `e`), then `w` twice (for
/// `conj(Pa)·e`) and two zeros, so that the sums are one plain multiply-add per lane
/// and the grid cell's values are read as they lie (`Pa` and `e` side by side).
#[derive(Clone, Copy)]
#[repr(C, align(32))]
struct KernelCell {
    factors: [f64; 16],
    d: usize,
    /// `6·d`: the cell's grid values as an offset in `f64` ([`Kernel::flat_sums_avx2`]).
    off: usize,
}

impl Kernel {
    fn new(offsets: &[f64], y: &[C64]) -> Kernel {
        let n = offsets.len().min(y.len());
        let lo = offsets[..n]
            .iter()
            .map(|o| o.floor())
            .fold(f64::INFINITY, f64::min);
        let lo = if lo.is_finite() { lo as i64 } else { 0 };
        let mut dense: Vec<(f64, C64)> = Vec::new();
        for (&o, &yj) in offsets.iter().zip(y) {
            let k = o.floor();
            let t = o - k;
            let d = (k as i64 - lo) as usize;
            if dense.len() < d + 2 {
                dense.resize(d + 2, (0.0, C64::new(0.0, 0.0)));
            }
            dense[d].0 += 1.0 - t;
            dense[d].1 += yj * (1.0 - t);
            dense[d + 1].0 += t;
            dense[d + 1].1 += yj * t;
        }
        // The weights are at least 0: a cell of weight 0 has `y`-weight 0 as well.
        let cells = dense
            .into_iter()
            .enumerate()
            .filter(|(_, (w, _))| *w != 0.0)
            .map(|(d, (w, wy))| {
                let (a, b) = (wy.re, wy.im);
                KernelCell {
                    factors: [w, w, w, w, a, a, a, a, b, b, b, b, w, w, 0.0, 0.0],
                    d,
                    off: 6 * d,
                }
            })
            .collect();
        Kernel {
            lo,
            cells,
            count: n as u32,
        }
    }

    /// Cells past the start's base that [`Kernel::sums`] reads.
    fn reach(&self) -> usize {
        self.cells.last().map_or(0, |c| c.d + 1)
    }

    /// The seven pair sums of [`Kernel::sums`] (`Σ w·Pa`, `Σ w·e`, `Σ w·conj(Pa)·e`,
    /// `Σ Re(y)·Pa`, `Σ Im(y)·Pa`, `Σ Re(y)·e`, `Σ Im(y)·e`): one multiply-add per lane
    /// and cell, in cell order, sixteen lanes (two of them zero) in the order of
    /// [`KernelCell`]'s factors. Not inlined: inlined, the compiler mixed the pairs'
    /// lanes across accumulators.
    #[inline(never)]
    fn flat_sums(kernel: &[KernelCell], grid: &[[[f64; 2]; 3]]) -> [[f64; 2]; 7] {
        Kernel::flat_sums_body(kernel, grid)
    }

    /// [`Kernel::flat_sums`] in AVX2 vectors (called only where the processor has it):
    /// the same operations in the same order, lane by lane (a multiply, then an add;
    /// never fused), the sixteen lanes in three vectors of four and one of two (compiled
    /// from the plain loop, the lanes were shuffled across vectors: more instructions
    /// a cell than the baseline's pairs).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    fn flat_sums_avx2(kernel: &[KernelCell], grid: &[[[f64; 2]; 3]]) -> [[f64; 2]; 7] {
        use std::arch::x86_64::{
            _mm_add_pd, _mm_loadu_pd, _mm_mul_pd, _mm_setzero_pd, _mm_storeu_pd, _mm256_add_pd,
            _mm256_loadu_pd, _mm256_mul_pd, _mm256_setzero_pd, _mm256_storeu_pd,
        };
        let (mut l0, mut l1, mut l2) = (
            _mm256_setzero_pd(),
            _mm256_setzero_pd(),
            _mm256_setzero_pd(),
        );
        let mut l3 = _mm_setzero_pd();
        // The cells are in increasing `d` (made so by `Kernel::new`): every cell's six
        // grid values lie inside `grid` when the last one's do. Checked once here, so
        // that the loop reads by offset without a bounds test.
        let Some(last) = kernel.last() else {
            return Kernel::lanes_to_pairs([[0.0; 4]; 4]);
        };
        assert!(last.d < grid.len() && last.off == 6 * last.d);
        debug_assert!(
            kernel.iter().all(|c| c.off == 6 * c.d) && kernel.windows(2).all(|p| p[0].d < p[1].d)
        );
        let g0: *const f64 = grid.as_ptr().cast();
        // One cell's four multiply-adds, lane by lane (a multiply, then an add).
        let mut cell = |c: &KernelCell| {
            let f = &c.factors;
            // SAFETY: `c.off = 6·c.d <= last.off` with `last.d < grid.len()` (the cells
            // are made sorted with `off = 6·d` by `Kernel::new`, the only place they are
            // made; the last checked above), so `g0 + c.off` starts the six `f64` of
            // `grid[c.d]` (`Pa`, `e`, `conj(Pa)·e`), of which the first four and the last
            // two are read; `f` is sixteen, all read.
            #[allow(unsafe_code)]
            let (pe, x, f0, f1, f2, f3) = unsafe {
                let g = g0.add(c.off);
                (
                    _mm256_loadu_pd(g),
                    _mm_loadu_pd(g.add(4)),
                    _mm256_loadu_pd(f.as_ptr()),
                    _mm256_loadu_pd(f[4..].as_ptr()),
                    _mm256_loadu_pd(f[8..].as_ptr()),
                    _mm_loadu_pd(f[12..].as_ptr()),
                )
            };
            l0 = _mm256_add_pd(l0, _mm256_mul_pd(f0, pe));
            l1 = _mm256_add_pd(l1, _mm256_mul_pd(f1, pe));
            l2 = _mm256_add_pd(l2, _mm256_mul_pd(f2, pe));
            l3 = _mm_add_pd(l3, _mm_mul_pd(f3, x));
        };
        // Two cells a round (the same cells in the same order).
        let mut pairs = kernel.chunks_exact(2);
        for p in &mut pairs {
            cell(&p[0]);
            cell(&p[1]);
        }
        for c in pairs.remainder() {
            cell(c);
        }
        let mut l = [[0.0f64; 4]; 4];
        // SAFETY: each store writes four (the last two) `f64` into its own array.
        #[allow(unsafe_code)]
        unsafe {
            _mm256_storeu_pd(l[0].as_mut_ptr(), l0);
            _mm256_storeu_pd(l[1].as_mut_ptr(), l1);
            _mm256_storeu_pd(l[2].as_mut_ptr(), l2);
            _mm_storeu_pd(l[3].as_mut_ptr(), l3);
        }
        Kernel::lanes_to_pairs(l)
    }

    /// The lanes of [`Kernel::flat_sums`] as its seven pairs.
    #[inline(always)]
    fn lanes_to_pairs(l: [[f64; 4]; 4]) -> [[f64; 2]; 7] {
        let [[a, b, c, d], [e, f, g, h], [i, j, k, m], [n, o, _, _]] = l;
        [[a, b], [c, d], [n, o], [e, f], [i, j], [g, h], [k, m]]
    }

    /// The body of [`Kernel::flat_sums`].
    #[inline(always)]
    fn flat_sums_body(kernel: &[KernelCell], grid: &[[[f64; 2]; 3]]) -> [[f64; 2]; 7] {
        // Four lanes of four: `w·(Pa, e)`, `Re y·(Pa, e)`, `Im y·(Pa, e)`, `w·(conj(Pa)·e, 0)`.
        let mut l = [[0.0f64; 4]; 4];
        for c in kernel {
            let [p, e, x] = grid[c.d];
            let pe = [p[0], p[1], e[0], e[1]];
            let x0 = [x[0], x[1], 0.0, 0.0];
            let f = &c.factors;
            for i in 0..4 {
                l[0][i] += f[i] * pe[i];
                l[1][i] += f[4 + i] * pe[i];
                l[2][i] += f[8 + i] * pe[i];
                l[3][i] += f[12 + i] * x0[i];
            }
        }
        Kernel::lanes_to_pairs(l)
    }

    /// The sums at the whole-degree `start` (any integer) on `grid`; the reflection's
    /// `R` sums come from the same two products per cell as the others.
    #[inline(always)]
    fn sums<const AVX2: bool>(&self, grid: &Grid, start: i64) -> Sums {
        let base = (start + self.lo).rem_euclid(grid.period as i64) as usize;
        let cells = &grid.cells[base..];
        // `[re, im]` pairs: `Σ w·Pa`, `Σ w·e`, `Σ w·conj(Pa)·e`, and `Σ Re(y)·Pa`,
        // `Σ Im(y)·Pa`, `Σ Re(y)·e`, `Σ Im(y)·e`, from which the `R` sums are formed.
        #[cfg(target_arch = "x86_64")]
        let acc = if AVX2 {
            // SAFETY: `AVX2` is set only on the path that found the processor to have
            // AVX2 ([`linkage_stage1`]); `flat_sums_avx2` has no other requirement.
            #[allow(unsafe_code)]
            unsafe {
                Kernel::flat_sums_avx2(&self.cells, cells)
            }
        } else {
            Kernel::flat_sums(&self.cells, cells)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let acc = Kernel::flat_sums(&self.cells, cells);
        let c = |v: [f64; 2]| C64::new(v[0], v[1]);
        // `y = a + ib`: `Σ conj(P)·y = (ΣaP_re + ΣbP_im) + i(ΣbP_re − ΣaP_im)` and
        // `Σ conj(P)·conj(y) = conj(Σ P·y)`, `Σ P·y = (ΣaP_re − ΣbP_im) + i(ΣbP_re + ΣaP_im)`.
        let plain = |a: [f64; 2], b: [f64; 2]| C64::new(a[0] + b[1], b[0] - a[1]);
        let mirror = |a: [f64; 2], b: [f64; 2]| C64::new(a[0] - b[1], -(b[0] + a[1]));
        Sums {
            m: f64::from(self.count),
            sp: c(acc[0]),
            se: c(acc[1]),
            spe: c(acc[2]),
            r: [
                [plain(acc[3], acc[4]), plain(acc[5], acc[6])],
                [mirror(acc[3], acc[4]), mirror(acc[5], acc[6])],
            ],
        }
    }
}

/// The 1° cell of an input angle (any finite value) and the fraction into it: `deg`
/// modulo the table's `period` (whole degrees: 360 for a four-bar, `360·q` for a geared
/// five-bar) split into whole and fractional degrees, without a floating-point remainder
/// (the hot loops call it for every point of every hypothesis).
#[inline(always)]
fn cell(deg: f64, period: usize) -> (usize, f64) {
    if deg.is_nan() || deg.abs() >= 1e15 {
        // Not reached by the scan's angles; the general form for completeness.
        let x = deg.rem_euclid(period as f64);
        let k = (x as usize).min(period - 1);
        return (k, x - k as f64);
    }
    let mut whole = deg as i64;
    if whole as f64 > deg {
        whole -= 1;
    }
    // The scan's angles lie within a period or two of [0, period): a subtraction or an
    // addition instead of an integer division (the same cell as `rem_euclid`), chosen
    // without a branch.
    let p = period as i64;
    let k = whole + p * i64::from(whole < 0) - p * i64::from(whole >= p);
    let k = if (0..p).contains(&k) {
        k
    } else {
        whole.rem_euclid(p)
    };
    (k as usize, deg - whole as f64)
}

/// [`cell`] with the whole degrees by `floor` (one instruction where SSE4.1 is there, as
/// on the AVX2 path; a call on the baseline instruction set): the same cell and fraction,
/// as `floor` is the whole part `cell` finds.
///
/// On x86-64 the whole degrees are converted by the processor's truncating conversion,
/// which gives `i64::MIN` for NaN and for values out of range: the wrap by one period
/// then leaves the cell out of `0..period` and the general form ([`cell`]) is taken, so
/// the common case costs no test for NaN or size and no saturation.
#[inline(always)]
fn cell_floor(deg: f64, period: usize) -> (usize, f64) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_cvttsd_si64, _mm_set_sd};
        let whole = deg.floor();
        // SAFETY: SSE2, which these two need, is part of every x86-64 processor.
        #[allow(unsafe_code)]
        let w = unsafe { _mm_cvttsd_si64(_mm_set_sd(whole)) };
        let p = period as i64;
        // `w` within a period of `0..p`: the same cell as `rem_euclid` (and as the
        // general form below), chosen by conditional moves.
        let k = if w < 0 {
            w.wrapping_add(p)
        } else if w >= p {
            w - p
        } else {
            w
        };
        if (k as u64) < period as u64 {
            return (k as usize, deg - whole);
        }
        cell(deg, period)
    }
    #[cfg(not(target_arch = "x86_64"))]
    cell_floor_general(deg, period)
}

/// [`cell_floor`] in its general form (any finite value, and NaN).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
#[inline(always)]
fn cell_floor_general(deg: f64, period: usize) -> (usize, f64) {
    if deg.is_nan() || deg.abs() >= 1e15 {
        return cell(deg, period);
    }
    let whole = deg.floor();
    let w = whole as i64;
    let p = period as i64;
    let k = w + p * i64::from(w < 0) - p * i64::from(w >= p);
    let k = if (0..p).contains(&k) {
        k
    } else {
        w.rem_euclid(p)
    };
    (k as usize, deg - whole)
}

/// The sums of one hypothesis: `S_P = Σ Pa`, `S_e = Σ e`, `S_Pe = Σ conj(Pa)·e`,
/// `R_P = Σ conj(Pa)·y`, `R_e = Σ conj(e)·y` (and the same with `conj(y)`), over `M`
/// points (`Σ |Pa|² = Σ |e|² = M`). The target is centred (`Σ y = 0`) with `Σ|y|² = 1`.
#[derive(Clone, Copy, Debug)]
struct Sums {
    m: f64,
    sp: C64,
    se: C64,
    spe: C64,
    r: [[C64; 2]; 2],
}

impl Sums {
    fn of(table: &Table, theta: impl Iterator<Item = f64>, y: &[C64], mirror: bool) -> Sums {
        if mirror {
            Sums::of_with::<true>(table, theta, y)
        } else {
            Sums::of_with::<false>(table, theta, y)
        }
    }

    /// [`Sums::of`] with the reflection's sums (`MIRROR`) or without, decided at compile
    /// time (the hot loop has no branch).
    #[inline(always)]
    fn of_with<const MIRROR: bool>(
        table: &Table,
        theta: impl Iterator<Item = f64>,
        y: &[C64],
    ) -> Sums {
        Sums::accumulate::<MIRROR>(theta.map(|t| table.at(t)), y)
    }

    /// The sums over the points' `(Pa, e)` and the target's `y`.
    #[inline(always)]
    fn accumulate<const MIRROR: bool>(pe: impl Iterator<Item = (C64, C64)>, y: &[C64]) -> Sums {
        let zero = C64::new(0.0, 0.0);
        let mut s = Sums {
            m: 0.0,
            sp: zero,
            se: zero,
            spe: zero,
            r: [[zero; 2]; 2],
        };
        // The count kept as an integer: `m` is then what adding 1.0 once a point gives.
        let mut count = 0u32;
        for ((p, e), &yj) in pe.zip(y) {
            count += 1;
            s.sp += p;
            s.se += e;
            s.spe += p.conj() * e;
            s.r[0][0] += p.conj() * yj;
            s.r[0][1] += e.conj() * yj;
            if MIRROR {
                let yc = yj.conj();
                s.r[1][0] += p.conj() * yc;
                s.r[1][1] += e.conj() * yc;
            }
        }
        s.m = f64::from(count);
        s
    }

    /// The centred Gram matrix `[[g11, g12], [conj g12, g22]]`.
    fn gram(&self) -> (f64, C64, f64) {
        let g11 = self.m - self.sp.norm_sqr() / self.m;
        let g22 = self.m - self.se.norm_sqr() / self.m;
        let g12 = self.spe - self.sp.conj() * self.se / self.m;
        (g11, g12, g22)
    }

    /// The misfit `Σ|y − α·(Pa + w·e) − γ|²` at the best `α`, `γ` for a given `w`.
    fn at_point(&self, v: usize, w: C64) -> (f64, C64) {
        self.at_point_with(self.gram(), v, w)
    }

    /// [`Sums::at_point`] with the Gram matrix computed once for many points.
    #[inline]
    fn at_point_with(&self, gram: (f64, C64, f64), v: usize, w: C64) -> (f64, C64) {
        let mm = Sums::model_norm(gram, w);
        if mm <= 0.0 {
            return (1.0, C64::new(0.0, 0.0));
        }
        let my = self.r[v][0] + w.conj() * self.r[v][1];
        ((1.0 - my.norm_sqr() / mm).max(0.0), my / mm)
    }

    /// `Σ|Pa + w·e − mean|²`, the centred model's squared norm at the point `w` (the same
    /// with and without reflection).
    #[inline(always)]
    fn model_norm((g11, g12, g22): (f64, C64, f64), w: C64) -> f64 {
        g11 + 2.0 * (w * g12).re + w.norm_sqr() * g22
    }

    /// Whether the misfit at `w` ([`Sums::misfit_with`]) is surely above `bound`, decided
    /// without its division: `1 − q/mm > bound` holds when `q < (1 − bound − 10⁻⁹)·mm`
    /// (`q = |my|²`, `mm > 0`), whose rounding errors, a few units in the last place of
    /// values near 1, are far inside the margin. `false` means "not sure" (also for NaN):
    /// the caller then computes the misfit. So skipping a point on `true` changes no
    /// decision [`offer`] would make (it refuses a misfit at or above the list's last).
    #[inline(always)]
    fn surely_above(&self, mm: f64, v: usize, w: C64, bound: f64) -> bool {
        let my = self.r[v][0] + w.conj() * self.r[v][1];
        mm > 0.0 && bound < 1.0 && my.norm_sqr() < (1.0 - bound - 1e-9) * mm
    }

    /// A lower bound of the misfit ([`Sums::misfit_with`]) at **every** coupler point
    /// `w`, given the Gram matrix `gram` of these sums, for reflection `v`; minus
    /// infinity when the matrix is too close to singular for the bound to be safe.
    ///
    /// With `z = (Pa − P̄) + w·(e − ē)` the misfit at `w` is `1 − |⟨z, y⟩|²/|z|²`, and `z`
    /// lies in the plane spanned by the centred `Pa` and `e`: the least misfit over every
    /// `w` is at most `1 −` the squared norm of `y`'s projection on that plane,
    /// `1 − rᴴ·G⁻¹·r` (`G` the Gram matrix, `r = (R_P, R_e)`); as algebra on the computed
    /// sums, `|vᴴr|² ≤ (vᴴGv)·(rᴴG⁻¹r)` for `v = (1, w)` (Cauchy–Schwarz in the inner product
    /// of `G`). Rounding: with `det G ≥ 10⁻⁶·(g11 + g22)²` the condition number of `G` is
    /// at most about 4·10⁶, so each of the two computed values is within about 10⁻⁹ of
    /// its exact value on the same sums; the caller adds a margin of [`BOUND_MARGIN`].
    #[inline]
    fn least_misfit(&self, (g11, g12, g22): (f64, C64, f64), v: usize) -> f64 {
        let det = g11 * g22 - g12.norm_sqr();
        let tr = g11 + g22;
        if !(g11 > 0.0 && g22 > 0.0 && det >= 1e-6 * tr * tr) {
            return f64::NEG_INFINITY;
        }
        let [r0, r1] = self.r[v];
        let proj =
            (g22 * r0.norm_sqr() + g11 * r1.norm_sqr() - 2.0 * (r0.conj() * g12 * r1).re) / det;
        1.0 - proj
    }

    /// The misfit of [`Sums::at_point_with`] alone, given [`Sums::model_norm`] `mm`.
    #[inline(always)]
    fn misfit_with(&self, mm: f64, v: usize, w: C64) -> f64 {
        if mm <= 0.0 {
            return 1.0;
        }
        let my = self.r[v][0] + w.conj() * self.r[v][1];
        (1.0 - my.norm_sqr() / mm).max(0.0)
    }
}

/// A linkage's coupler points as columns, for [`sieve`].
struct PointColumns {
    re: Vec<f64>,
    im: Vec<f64>,
    /// `|w|²`, as [`C64::norm_sqr`] gives it.
    norm: Vec<f64>,
}

impl PointColumns {
    fn new(points: &[C64]) -> PointColumns {
        PointColumns {
            re: points.iter().map(|w| w.re).collect(),
            im: points.iter().map(|w| w.im).collect(),
            norm: points.iter().map(|w| w.norm_sqr()).collect(),
        }
    }
}

/// Bit `k % 64` of `open[k / 64][v]` set unless reflection `v` is not `live` or the
/// misfit at point `k` is surely above its bound: the test of [`Sums::surely_above`] with
/// `bar[v][k] = 1 − bound − 10⁻⁹` (each reflection its own bound), computed with the same
/// operations in the same order (so the same values, bit for bit: `(w·g12).re` and
/// `conj(w)·r` written out as `num-complex` forms them), over all points in one
/// branch-free pass; with `AVX2` four points a vector, their four tests gathered into
/// four bits by one instruction. `open` holds one word pair per 64 points.
#[inline(always)]
fn sieve<const AVX2: bool>(
    sums: &Sums,
    gram: (f64, C64, f64),
    pts: &PointColumns,
    bar: [&[f64]; 2],
    live: [bool; 2],
    open: &mut [[u64; 2]],
) {
    // Only the live reflections' tests are computed (a query without reflection has one).
    match live {
        [true, false] => sieve_with::<true, false, AVX2>(sums, gram, pts, bar, open),
        [false, true] => sieve_with::<false, true, AVX2>(sums, gram, pts, bar, open),
        [true, true] => sieve_with::<true, true, AVX2>(sums, gram, pts, bar, open),
        [false, false] => open.fill([0; 2]),
    }
}

/// The factors of [`sieve`]'s test that do not depend on the point: `g11`, `Re g12`,
/// `Im g12`, `g22`, then `Re`, `Im` of `r[v][0]` and `r[v][1]` for each reflection.
type SieveFactors = ([f64; 4], [[f64; 4]; 2]);

/// [`sieve`] for the live reflections `R0` and `R1`, known at compile time.
#[inline(always)]
fn sieve_with<const R0: bool, const R1: bool, const AVX2: bool>(
    sums: &Sums,
    (g11, g12, g22): (f64, C64, f64),
    pts: &PointColumns,
    [bar0, bar1]: [&[f64]; 2],
    open: &mut [[u64; 2]],
) {
    let n = pts.re.len();
    assert_eq!(open.len(), n.div_ceil(64));
    let (re, im, norm) = (&pts.re[..n], &pts.im[..n], &pts.norm[..n]);
    // A reflection not tested reads no bound (its slice may be empty).
    let (bar0, bar1) = (
        &bar0[..if R0 { n } else { 0 }],
        &bar1[..if R1 { n } else { 0 }],
    );
    let [[a0, b0], [a1, b1]] = sums.r;
    let factors: SieveFactors = (
        [g11, g12.re, g12.im, g22],
        [[a0.re, a0.im, b0.re, b0.im], [a1.re, a1.im, b1.re, b1.im]],
    );
    for (b, o) in open.iter_mut().enumerate() {
        let (lo, hi) = (64 * b, (64 * b + 64).min(n));
        let mut m = [0u64; 2];
        #[allow(unused_mut)]
        let mut k = lo;
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            // SAFETY: `AVX2` is set only where the processor was found to have AVX2
            // ([`linkage_stage1`], and the test that checks it); `sieve_avx2` reads
            // inside the slices it is given.
            #[allow(unsafe_code)]
            {
                k = unsafe {
                    sieve_avx2::<R0, R1>(
                        factors,
                        [&re[lo..hi], &im[lo..hi], &norm[lo..hi]],
                        [
                            &bar0[if R0 { lo..hi } else { 0..0 }],
                            &bar1[if R1 { lo..hi } else { 0..0 }],
                        ],
                        &mut m,
                    )
                } + lo;
            }
        }
        while k < hi {
            let (wr, wi) = (re[k], im[k]);
            let mm = g11 + 2.0 * (wr * g12.re - wi * g12.im) + norm[k] * g22;
            let pos = mm > 0.0;
            // `my = r[v][0] + conj(w)·r[v][1]`: `conj(w) = (wr, −wi)`.
            if R0 {
                let m0r = a0.re + (wr * b0.re - -wi * b0.im);
                let m0i = a0.im + (wr * b0.im + -wi * b0.re);
                let q0 = m0r * m0r + m0i * m0i;
                m[0] |= u64::from(!(pos & (q0 < bar0[k] * mm))) << (k - lo);
            }
            if R1 {
                let m1r = a1.re + (wr * b1.re - -wi * b1.im);
                let m1i = a1.im + (wr * b1.im + -wi * b1.re);
                let q1 = m1r * m1r + m1i * m1i;
                m[1] |= u64::from(!(pos & (q1 < bar1[k] * mm))) << (k - lo);
            }
            k += 1;
        }
        *o = m;
    }
}

/// [`sieve_with`]'s test at four points a vector (called only where the processor has
/// AVX2), each lane the same operations in the same order as the scalar form (a
/// multiply, then an add or a subtraction: never fused; `−wi` a sign flip; the ordered
/// comparisons, false for NaN): the open bits of the first points of `w` (at most 64,
/// `[re, im, |w|²]` columns) into `m`, four at a time. Returns how many points it did (a
/// multiple of four); the caller does the rest.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn sieve_avx2<const R0: bool, const R1: bool>(
    ([g11, g12r, g12i, g22], r): SieveFactors,
    [re, im, norm]: [&[f64]; 3],
    [bar0, bar1]: [&[f64]; 2],
    m: &mut [u64; 2],
) -> usize {
    use std::arch::x86_64::{
        _CMP_GT_OQ, _CMP_LT_OQ, _mm256_add_pd, _mm256_and_pd, _mm256_cmp_pd, _mm256_loadu_pd,
        _mm256_movemask_pd, _mm256_mul_pd, _mm256_set1_pd, _mm256_setzero_pd, _mm256_sub_pd,
        _mm256_xor_pd,
    };
    let n = re.len().min(im.len()).min(norm.len()).min(64);
    let n = if R0 { n.min(bar0.len()) } else { n };
    let n = if R1 { n.min(bar1.len()) } else { n };
    let (add, sub, mul, set) = (_mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd, _mm256_set1_pd);
    let (g11, g12r, g12i, g22, two) = (set(g11), set(g12r), set(g12i), set(g22), set(2.0));
    let (zero, sign) = (_mm256_setzero_pd(), set(-0.0));
    let rv = r.map(|[ar, ai, br, bi]| [set(ar), set(ai), set(br), set(bi)]);
    let mut k = 0;
    while k + 4 <= n {
        // SAFETY: `k + 4 <= n`, at most every slice's length: four `f64` in a row inside
        // each slice read (the bounds only of the reflections tested).
        #[allow(unsafe_code)]
        let (wr, wi, nm) = unsafe {
            (
                _mm256_loadu_pd(re.as_ptr().add(k)),
                _mm256_loadu_pd(im.as_ptr().add(k)),
                _mm256_loadu_pd(norm.as_ptr().add(k)),
            )
        };
        // `mm = g11 + 2·(wr·Re g12 − wi·Im g12) + |w|²·g22`, left to right.
        let mm = add(
            add(g11, mul(two, sub(mul(wr, g12r), mul(wi, g12i)))),
            mul(nm, g22),
        );
        let pos = _mm256_cmp_pd::<_CMP_GT_OQ>(mm, zero);
        let nwi = _mm256_xor_pd(wi, sign);
        for (v, bar) in [(0, bar0), (1, bar1)] {
            if (v == 0 && !R0) || (v == 1 && !R1) {
                continue;
            }
            let [ar, ai, br, bi] = rv[v];
            let mr = add(ar, sub(mul(wr, br), mul(nwi, bi)));
            let mi = add(ai, add(mul(wr, bi), mul(nwi, br)));
            let q = add(mul(mr, mr), mul(mi, mi));
            // SAFETY: as above (this reflection is tested, so `bar` has `n` values).
            #[allow(unsafe_code)]
            let b = unsafe { _mm256_loadu_pd(bar.as_ptr().add(k)) };
            let closed = _mm256_and_pd(pos, _mm256_cmp_pd::<_CMP_LT_OQ>(q, mul(b, mm)));
            let open = !_mm256_movemask_pd(closed) as u64 & 0xF;
            m[v] |= open << k;
        }
        k += 4;
    }
    k
}

/// What a hypothesis's [`Sums::least_misfit`] must exceed a point's bound by before the
/// scan skips the point: far above the rounding of both values (about 10⁻⁹).
const BOUND_MARGIN: f64 = 1e-7;

/// A stage-1 hypothesis before its angles are laid out.
#[derive(Clone, Copy, Debug)]
struct Window {
    misfit: f64,
    mirror: bool,
    start: f64,
    span: f64,
    sense: f64,
    /// `start + sense·span/2`, made once ([`Window::new`]).
    centre: f64,
}

impl Window {
    fn new(misfit: f64, mirror: bool, start: f64, span: f64, sense: f64) -> Window {
        Window {
            misfit,
            mirror,
            start,
            span,
            sense,
            centre: start + 0.5 * sense * span,
        }
    }

    /// Whether two hypotheses describe about the same window: same reflection and sense,
    /// centres closer than a quarter of the longer span (modulo the `period`), spans
    /// within a ratio of 1.44.
    fn alike(&self, o: &Window, period: f64) -> bool {
        // The cheap tests first (the same answer: every test must hold).
        if self.mirror != o.mirror || self.sense != o.sense {
            return false;
        }
        let ratio = self.span.max(o.span) / self.span.min(o.span);
        if ratio.partial_cmp(&1.44) != Some(std::cmp::Ordering::Less) {
            return false;
        }
        let d = rem_period(self.centre - o.centre, period);
        d.min(period - d) < 0.25 * self.span.max(o.span)
    }
}

/// `x.rem_euclid(period)` without the floating-point remainder's call when `|x|` is below
/// two periods, as the difference of two windows' centres is: there the remainder is
/// `x`, `x − period` or `x + period`, each exact (Sterbenz's lemma), and a negative
/// remainder gets `period` added, as `rem_euclid` adds it.
#[inline(always)]
fn rem_period(x: f64, period: f64) -> f64 {
    if (0.0..period).contains(&x) {
        x
    } else if (period..2.0 * period).contains(&x) {
        x - period
    } else if x < 0.0 && x > -period {
        x + period
    } else if x <= -period && x > -2.0 * period {
        // The remainder keeps the dividend's sign: `−0` at `x = −period`.
        let r = x + period;
        if r < 0.0 {
            r + period
        } else if r == 0.0 {
            -0.0
        } else {
            r
        }
    } else {
        x.rem_euclid(period)
    }
}

/// The least step between the starts of an untimed target's scan pass, degrees of input
/// (the step is `span/16` above it): the spans below 72° take 80 starts a sense on a 360°
/// period, every start within 2.25° of a scanned one (the 200-case open retrieval finds
/// the same sources as with 3°; `docs/shape-search.md`, section 3).
const UNTIMED_START_STEP: f64 = 4.5;

/// Distinct windows kept per coupler point from stage 1 (each is projected in stage 1b,
/// the best goes on): under the even-crank layout the source's own window often scores
/// worse than some other window of the same curve, and only the projection tells them
/// apart.
const WINDOWS: usize = 6;

/// Keeps `list` (best first) the `WINDOWS` best pairwise distinct windows offered, on a
/// linkage of the given `period`.
#[inline(always)]
fn offer(list: &mut Vec<Window>, h: Window, period: f64) {
    if !h.misfit.is_finite() || (list.len() == WINDOWS && h.misfit >= list[WINDOWS - 1].misfit) {
        return;
    }
    if let Some(i) = list.iter().position(|x| x.alike(&h, period)) {
        if h.misfit < list[i].misfit {
            list[i] = h;
        } else {
            return;
        }
        // Moved up past the worse windows before it: the order a stable sort by misfit
        // gives (the rest of the list is sorted, and those after it are worse still).
        lift(list, i);
    } else {
        list.push(h);
        let last = list.len() - 1;
        lift(list, last);
    }
    list.truncate(WINDOWS);
}

/// Moves `list[i]` to where a stable sort by misfit puts it, the rest of `list` being
/// sorted and no better than it after `i`: after every window before it that is not
/// worse ([`f64::total_cmp`]).
#[inline]
fn lift(list: &mut [Window], i: usize) {
    let m = list[i].misfit;
    let p = list[..i].partition_point(|x| x.misfit.total_cmp(&m) != std::cmp::Ordering::Greater);
    list[p..=i].rotate_right(1);
}

/// One step of [`OpenQuery::reproject`]'s dynamic programme: `least[g]` the least of
/// `cost[..=g]` (a NaN never taken, +∞ before any cost below it) and `next[g] += least[g]`.
/// The running least alone, one `min` a cell and no index: the cell it came from is found
/// again on the way back ([`first_of_least`]). The three rows of one length.
#[inline(always)]
fn add_running_least(cost: &[f64], next: &mut [f64], least: &mut [f64]) {
    let mut run = f64::INFINITY;
    // Zipped slices: no bounds test in the loop.
    for ((&c, nx), l) in cost.iter().zip(next.iter_mut()).zip(least.iter_mut()) {
        run = if c < run { c } else { run };
        *l = run;
        *nx += run;
    }
}

/// The first cell of [`add_running_least`]'s cost whose value `least[g]` is: where the
/// running least first took it (it falls only at a cost below every earlier one, so it
/// keeps its value from there to `g`; 0 where it is still +∞). The cell a running least
/// that kept its index (taking a cost only when below) would give.
#[inline(always)]
fn first_of_least(least: &[f64], mut g: usize) -> usize {
    while g > 0 && least[g - 1] == least[g] {
        g -= 1;
    }
    g
}

/// The buffers of [`OpenQuery::reproject`]'s dynamic programme, kept between calls: the
/// fitted curve on the grid (real and imaginary parts), the costs of the current and
/// next point, and for every point the running least of the previous point's costs
/// (`cells` each; the back pointers are where it falls).
#[derive(Default)]
struct Programme {
    re: Vec<f64>,
    im: Vec<f64>,
    cost: Vec<f64>,
    next: Vec<f64>,
    least: Vec<f64>,
}

/// The buffers of [`OpenQuery::project`], kept between windows: the trial angles and the
/// table's values at the current and trial angles.
#[derive(Default)]
struct Projection {
    next: Vec<f64>,
    at: Vec<Flat>,
    trial_at: Vec<Flat>,
    /// Angle vectors of former windows, handed to the next ones (stage 1 lays each
    /// window's angles out in one of these rather than in a new vector).
    spare: Vec<Vec<f64>>,
}

/// [`Table::flat_at_with`]'s values: `Pa`, `e`, `dPa/dθ`, `de/dθ`, each real then imaginary
/// (so that four points' values are read into vectors as they lie).
type Flat = [f64; 8];

/// `(Pa, e)` of a [`Flat`].
#[inline(always)]
fn pa_e(a: &Flat) -> (C64, C64) {
    (C64::new(a[0], a[1]), C64::new(a[2], a[3]))
}

/// One projection step at one point ([`OpenQuery::project_with`]): the angle `t` moved
/// along the fitted curve `α·(Pa + w·e) + γ` towards the target point `y` (conjugated
/// when `MIRROR`), by `Re((y − c)·conj(d))/|d|²` clamped to `±limit`.
#[inline(always)]
fn step_point<const MIRROR: bool>(
    (alpha, gamma, w, limit): (C64, C64, C64, f64),
    t: f64,
    a: &Flat,
    yj: C64,
) -> f64 {
    let (p, e) = pa_e(a);
    let (dp, de) = (C64::new(a[4], a[5]), C64::new(a[6], a[7]));
    let c = alpha * (p + w * e) + gamma;
    let d = alpha * (dp + w * de);
    let d2 = d.norm_sqr();
    let yj = if MIRROR { yj.conj() } else { yj };
    if d2 > 0.0 {
        t + (((yj - c) * d.conj()).re / d2).clamp(-limit, limit)
    } else {
        t
    }
}

/// [`step_point`] at four points a time in AVX2 vectors (called only where the
/// processor has it), each lane the same operations in the same order as `num-complex`
/// forms them (a multiply, then an add or a subtraction: never fused; a conjugate a
/// sign flip; the clamp's two ordered tests): the same values, bit for bit. Returns how
/// many of the first points it did (a multiple of four); the caller does the rest.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn step_avx2<const MIRROR: bool>(
    (alpha, gamma, w, limit): (C64, C64, C64, f64),
    theta: &[f64],
    at: &[Flat],
    y: &[C64],
    next: &mut [f64],
) -> usize {
    use std::arch::x86_64::{
        _CMP_GT_OQ, _CMP_LT_OQ, _mm256_add_pd, _mm256_blendv_pd, _mm256_cmp_pd, _mm256_div_pd,
        _mm256_loadu_pd, _mm256_mul_pd, _mm256_permute2f128_pd, _mm256_permute4x64_pd,
        _mm256_set1_pd, _mm256_setzero_pd, _mm256_storeu_pd, _mm256_sub_pd, _mm256_unpackhi_pd,
        _mm256_unpacklo_pd, _mm256_xor_pd,
    };
    let n = theta.len().min(at.len()).min(y.len()).min(next.len());
    let (add, sub, mul) = (_mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd);
    let (wr, wi) = (_mm256_set1_pd(w.re), _mm256_set1_pd(w.im));
    let (ar, ai) = (_mm256_set1_pd(alpha.re), _mm256_set1_pd(alpha.im));
    let (gr, gi) = (_mm256_set1_pd(gamma.re), _mm256_set1_pd(gamma.im));
    let (lim, nlim) = (_mm256_set1_pd(limit), _mm256_set1_pd(-limit));
    let (zero, sign) = (_mm256_setzero_pd(), _mm256_set1_pd(-0.0));
    let mut j = 0;
    while j + 4 <= n {
        let (a, th, yy) = (&at[j..j + 4], &theta[j..j + 4], &y[j..j + 4]);
        // SAFETY: each load reads four `f64` in a row inside its slice: half of one
        // point's `Flat`, four angles, two points' `C64` (`repr(C)`: re, im).
        #[allow(unsafe_code)]
        let (r, d, t, y01, y23) = unsafe {
            let r = |k: usize, h: usize| _mm256_loadu_pd(a[k][h..].as_ptr());
            (
                [r(0, 0), r(1, 0), r(2, 0), r(3, 0)],
                [r(0, 4), r(1, 4), r(2, 4), r(3, 4)],
                _mm256_loadu_pd(th.as_ptr()),
                _mm256_loadu_pd(yy[..2].as_ptr().cast()),
                _mm256_loadu_pd(yy[2..].as_ptr().cast()),
            )
        };
        // Four rows `(x_re, x_im, z_re, z_im)` into four columns of the points.
        let columns = |r: [_; 4]| {
            let (lo01, hi01) = (
                _mm256_unpacklo_pd(r[0], r[1]),
                _mm256_unpackhi_pd(r[0], r[1]),
            );
            let (lo23, hi23) = (
                _mm256_unpacklo_pd(r[2], r[3]),
                _mm256_unpackhi_pd(r[2], r[3]),
            );
            (
                _mm256_permute2f128_pd::<0x20>(lo01, lo23),
                _mm256_permute2f128_pd::<0x20>(hi01, hi23),
                _mm256_permute2f128_pd::<0x31>(lo01, lo23),
                _mm256_permute2f128_pd::<0x31>(hi01, hi23),
            )
        };
        let (pr, pi, er, ei) = columns(r);
        let (dpr, dpi, der, dei) = columns(d);
        // `y0 y2 y1 y3` after the unpacks, put in order.
        let yr = _mm256_permute4x64_pd::<0xD8>(_mm256_unpacklo_pd(y01, y23));
        let yi = _mm256_permute4x64_pd::<0xD8>(_mm256_unpackhi_pd(y01, y23));
        let yi = if MIRROR { _mm256_xor_pd(yi, sign) } else { yi };
        // `c = α·(Pa + w·e) + γ`.
        let (we_r, we_i) = (sub(mul(wr, er), mul(wi, ei)), add(mul(wr, ei), mul(wi, er)));
        let (qr, qi) = (add(pr, we_r), add(pi, we_i));
        let cr = add(sub(mul(ar, qr), mul(ai, qi)), gr);
        let ci = add(add(mul(ar, qi), mul(ai, qr)), gi);
        // `d = α·(Pa′ + w·e′)`, `|d|²`.
        let (wd_r, wd_i) = (
            sub(mul(wr, der), mul(wi, dei)),
            add(mul(wr, dei), mul(wi, der)),
        );
        let (sr, si) = (add(dpr, wd_r), add(dpi, wd_i));
        let (dr, di) = (sub(mul(ar, sr), mul(ai, si)), add(mul(ar, si), mul(ai, sr)));
        let d2 = add(mul(dr, dr), mul(di, di));
        // `Re((y − c)·conj(d))/|d|²`, `conj(d) = (dr, −di)`.
        let (ur, ui) = (sub(yr, cr), sub(yi, ci));
        let q = _mm256_div_pd(sub(mul(ur, dr), mul(ui, _mm256_xor_pd(di, sign))), d2);
        let q = _mm256_blendv_pd(q, nlim, _mm256_cmp_pd::<_CMP_LT_OQ>(q, nlim));
        let q = _mm256_blendv_pd(q, lim, _mm256_cmp_pd::<_CMP_GT_OQ>(q, lim));
        let moved = _mm256_blendv_pd(t, add(t, q), _mm256_cmp_pd::<_CMP_GT_OQ>(d2, zero));
        // SAFETY: four `f64` in a row inside `next[j..j + 4]`.
        #[allow(unsafe_code)]
        unsafe {
            _mm256_storeu_pd(next[j..j + 4].as_mut_ptr(), moved)
        };
        j += 4;
    }
    j
}

/// How the query's crank angles are laid out.
#[derive(Clone, Debug)]
enum Layout {
    /// Untimed: `x_j = j/(M−1)` along the smoothed path; re-estimated in stage 2.
    Untimed,
    /// Timed by angles: the span is fixed.
    Angles { span: f64 },
    /// Timed by equal steps: the span (step × (n − 1)) is free.
    Steps,
}

/// An open target prepared for the scan.
#[derive(Clone, Debug)]
pub(crate) struct OpenQuery {
    /// Query points, centred, `Σ|y|² = 1`.
    y: Vec<C64>,
    /// Their positions along the crank span, `0..=1`.
    x: Vec<f64>,
    /// Each original target point's position on the same scale (to hand starts to the
    /// exact fit).
    target_x: Vec<f64>,
    layout: Layout,
    allow_mirror: bool,
}

/// The scan's passes for one period ([`OpenQuery::passes`]), made once per query and
/// period instead of once per linkage.
struct Passes {
    /// The period they were made for, degrees of input.
    period: f64,
    list: Vec<Pass>,
}

/// One span and sense of the scan: its kernel and its whole-degree starts.
struct Pass {
    span: f64,
    sense: f64,
    kernel: Kernel,
    starts: Vec<f64>,
}

/// A stage-1 or stage-2 hypothesis on one linkage.
#[derive(Clone, Debug)]
struct Hypothesis {
    misfit: f64,
    mirror: bool,
    start: f64,
    span: f64,
    sense: f64,
    /// Per query point (after re-estimation; before it, from the layout).
    theta: Vec<f64>,
}

fn centred_unit(z: &[C64]) -> Option<Vec<C64>> {
    let m = z.iter().sum::<C64>() / z.len() as f64;
    let n2: f64 = z.iter().map(|p| (p - m).norm_sqr()).sum();
    (n2 > 0.0).then(|| {
        let s = 1.0 / n2.sqrt();
        z.iter().map(|p| (p - m) * s).collect()
    })
}

impl OpenQuery {
    pub(crate) fn new(target: &Target, allow_mirror: bool) -> Option<OpenQuery> {
        OpenQuery::with_points(target, allow_mirror, QUERY_POINTS, TIMED_QUERY_POINTS)
    }

    /// [`OpenQuery::new`] on at most `untimed` (`timed`) of the target's points.
    fn with_points(
        target: &Target,
        allow_mirror: bool,
        untimed: usize,
        timed: usize,
    ) -> Option<OpenQuery> {
        let p = target.complex_points();
        let n = p.len();
        let (pts, x, target_x, layout): (Vec<C64>, Vec<f64>, Vec<f64>, Layout) =
            match target.timing() {
                Timing::Untimed => {
                    // Positions: arc-length fractions along the smoothed path (noise would
                    // stretch the polyline's own length).
                    let (_, tau) = smooth_resample(&p, false, default_terms(n, 12).min(n / 2), 64)?;
                    let idx = thin(n, untimed);
                    (
                        idx.iter().map(|&i| p[i]).collect(),
                        idx.iter().map(|&i| tau[i]).collect(),
                        tau,
                        Layout::Untimed,
                    )
                }
                Timing::Angles(t) => {
                    let span = (t[n - 1] - t[0]).abs();
                    let tx: Vec<f64> = t.iter().map(|a| (a - t[0]).abs() / span).collect();
                    let idx = thin(n, timed);
                    (
                        idx.iter().map(|&i| p[i]).collect(),
                        idx.iter().map(|&i| tx[i]).collect(),
                        tx,
                        Layout::Angles { span },
                    )
                }
                Timing::EqualSteps => {
                    let tx: Vec<f64> = (0..n).map(|k| k as f64 / (n - 1) as f64).collect();
                    let idx = thin(n, timed);
                    (
                        idx.iter().map(|&i| p[i]).collect(),
                        idx.iter().map(|&i| tx[i]).collect(),
                        tx,
                        Layout::Steps,
                    )
                }
            };
        Some(OpenQuery {
            y: centred_unit(&pts)?,
            x,
            target_x,
            layout,
            allow_mirror,
        })
    }

    /// The crank spans tried on a linkage of the given `period` (none when the target's
    /// angles span more than it: such a linkage cannot carry the timing).
    fn spans(&self, period: f64) -> Vec<f64> {
        match self.layout {
            Layout::Angles { span } if span > period => Vec::new(),
            Layout::Angles { span } => vec![span],
            _ => {
                // 30° to a whole period, ratio 1.2.
                let mut v = Vec::new();
                let mut s: f64 = 30.0;
                while s < period {
                    v.push(s);
                    s *= 1.2;
                }
                v.push(period);
                v
            }
        }
    }

    fn thetas(&self, start: f64, span: f64, sense: f64) -> impl Iterator<Item = f64> + '_ {
        self.x.iter().map(move |&x| start + sense * span * x)
    }

    /// Stage 1 on one linkage: for every coupler point `w` of the atlas on it, the best
    /// `WINDOWS` distinct hypotheses (span, sense, start) of each reflection, best first,
    /// the unreflected list before the reflected one. Each reflection has its own lists
    /// and bounds, so the unreflected lists are the same, bit for bit, with reflection
    /// allowed or not: a reflected window never pushes an unreflected one out.
    /// (For tests and the lab: the scan of [`linkage_stage1`], on the path the query
    /// takes, AVX2 where the processor has it.)
    #[cfg(test)]
    fn scan(&self, table: &Table, points: &[C64]) -> Vec<Vec<Hypothesis>> {
        let passes = self.passes(table.period);
        #[cfg(target_arch = "x86_64")]
        if crate::has_avx2() {
            // SAFETY: `scan_avx2` needs AVX2, which the processor was just found to have;
            // it has no other requirement (the safe body compiled for AVX2).
            #[allow(unsafe_code)]
            return self.hypotheses(unsafe { self.scan_avx2(&passes, table, points) });
        }
        let windows = self.scan_with::<false>(&passes, table, points);
        self.hypotheses(windows)
    }

    /// The scan's windows as hypotheses, each with its own angles.
    #[cfg(test)]
    fn hypotheses(&self, windows: Vec<Vec<Window>>) -> Vec<Vec<Hypothesis>> {
        windows
            .iter()
            .map(|ws| ws.iter().map(|b| self.hypothesis(b, Vec::new())).collect())
            .collect()
    }

    /// [`OpenQuery::scan_with`] compiled for AVX2 (called only where the processor has
    /// it).
    #[cfg(all(test, target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    fn scan_avx2(&self, passes: &Passes, table: &Table, points: &[C64]) -> Vec<Vec<Window>> {
        self.scan_with::<true>(passes, table, points)
    }

    /// The scan's passes on a linkage of the given `period`: every span and sense with
    /// its kernel and its starts. They depend on the target and the period only, so one
    /// list serves every linkage of that period.
    fn passes(&self, period: f64) -> Passes {
        let mut list = Vec::new();
        let mut offsets = vec![0.0; self.x.len()];
        for span in self.spans(period) {
            let h = match self.layout {
                Layout::Angles { .. } => 3.0,
                _ => (span / 16.0).max(UNTIMED_START_STEP),
            };
            let (count, h) = even_starts(period, h);
            for sense in [1.0, -1.0] {
                // `θ_j = start + σ·Δ·x_j` as `thetas` gives it, the products made once.
                for (o, &x) in offsets.iter_mut().zip(&self.x) {
                    *o = sense * span * x;
                }
                // The starts are whole degrees (the nearest to every `h`-th), so that one
                // kernel serves them all.
                list.push(Pass {
                    span,
                    sense,
                    kernel: Kernel::new(&offsets, &self.y),
                    starts: (0..count).map(|i| (i as f64 * h).round()).collect(),
                });
            }
        }
        Passes { period, list }
    }

    /// [`OpenQuery::scan`], the kernel's sums by [`Kernel::flat_sums_avx2`] when `AVX2`
    /// (inlined into [`linkage_stage1`]'s AVX2 body only).
    #[inline(always)]
    fn scan_with<const AVX2: bool>(
        &self,
        passes: &Passes,
        table: &Table,
        points: &[C64],
    ) -> Vec<Vec<Window>> {
        let mirrors: &[bool] = if self.allow_mirror {
            &[false, true]
        } else {
            &[false]
        };
        let n = points.len();
        // Per reflection: each point's list, the least misfit it still takes (its last,
        // once full), the greatest of those (infinite until every list is full), and
        // `1 − worst − 10⁻⁹`, the factor of [`Sums::surely_above`]'s test.
        let n1 = if self.allow_mirror { n } else { 0 };
        // Each list made once at its greatest length (`offer` pushes before it truncates):
        // no growth while offers fill it.
        let lists = |n: usize| -> Vec<Vec<Window>> {
            (0..n).map(|_| Vec::with_capacity(WINDOWS + 1)).collect()
        };
        let mut best: [Vec<Vec<Window>>; 2] = [lists(n), lists(n1)];
        let mut worst = [vec![f64::INFINITY; n], vec![f64::INFINITY; n1]];
        let mut most = [f64::INFINITY; 2];
        let mut bar = [vec![f64::NEG_INFINITY; n], vec![f64::NEG_INFINITY; n1]];
        let period = table.period;
        let pts = PointColumns::new(points);
        let mut open = vec![[0u64; 2]; n.div_ceil(64)];
        debug_assert_eq!(passes.period, period);
        let grid = Grid::new(table);
        for pass in &passes.list {
            let (span, sense, kernel) = (pass.span, pass.sense, &pass.kernel);
            debug_assert!(kernel.reach() <= grid.cells.len() - grid.period);
            for &start in &pass.starts {
                let sums = kernel.sums::<AVX2>(&grid, start as i64);
                let gram = sums.gram();
                // A reflection whose least misfit over every coupler point is above
                // every point's bound of that reflection would be refused by every
                // list: skipped whole.
                let mut live = [false; 2];
                for &mirror in mirrors {
                    let v = usize::from(mirror);
                    // Live unless surely above (a NaN keeps it live).
                    live[v] = sums
                        .least_misfit(gram, v)
                        .partial_cmp(&(most[v] + BOUND_MARGIN))
                        != Some(std::cmp::Ordering::Greater);
                }
                if !live[0] && !live[1] {
                    continue;
                }
                // Which points each reflection may offer to, all points in one
                // branch-free pass: bit `v` of `open[k]` is clear when the misfit
                // at point `k` is surely above its bound for reflection `v` (the
                // test of [`Sums::surely_above`], the same values bit for bit).
                sieve::<AVX2>(&sums, gram, &pts, [&bar[0], &bar[1]], live, &mut open);
                // Whether a list whose bound was the greatest (`most`) took a window.
                let mut offered = [false; 2];
                // Point by point, each live reflection into its own list: the open
                // points in increasing order, each word pair's set bits. A point's
                // bound is the one the sieve tested (only its own list changes it,
                // and each list is offered at most one window a hypothesis), so the
                // sieve's answer stands: no second test.
                for (b, &o) in open.iter().enumerate() {
                    let mut bits = o[0] | o[1];
                    while bits != 0 {
                        let i = bits.trailing_zeros();
                        bits &= bits - 1;
                        let k = 64 * b + i as usize;
                        let w = points[k];
                        let mm = Sums::model_norm(gram, w);
                        for &mirror in mirrors {
                            let v = usize::from(mirror);
                            if (o[v] >> i) & 1 == 0 {
                                continue;
                            }
                            debug_assert!(!sums.surely_above(mm, v, w, worst[v][k]));
                            let m = sums.misfit_with(mm, v, w);
                            // `most` is the greatest of the bounds, which only fall: it
                            // changes only when the list that held it changes.
                            offered[v] |= worst[v][k] == most[v];
                            let list = &mut best[v][k];
                            offer(list, Window::new(m, mirror, start, span, sense), period);
                            if list.len() == WINDOWS {
                                worst[v][k] = list[WINDOWS - 1].misfit;
                                bar[v][k] = 1.0 - worst[v][k] - 1e-9;
                            }
                        }
                    }
                }
                for v in 0..2 {
                    if offered[v] {
                        most[v] = worst[v].iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    }
                }
            }
        }
        let [plain, reflected] = best;
        plain
            .into_iter()
            .zip(
                reflected
                    .into_iter()
                    .chain(std::iter::repeat_with(Vec::new)),
            )
            .map(|(mut a, b)| {
                a.extend(b);
                a
            })
            .collect()
    }

    /// The hypothesis of a scan window, its angles laid out (evenly along its span) in
    /// `theta`, whose former contents are dropped (a vector reused between windows
    /// keeps its storage: no allocation a window).
    fn hypothesis(&self, b: &Window, mut theta: Vec<f64>) -> Hypothesis {
        theta.clear();
        theta.extend(self.thetas(b.start, b.span, b.sense));
        Hypothesis {
            misfit: b.misfit,
            mirror: b.mirror,
            start: b.start,
            span: b.span,
            sense: b.sense,
            theta,
        }
    }

    /// Stage 1b for one coupler point `w` (untimed): each point's crank angle slides
    /// along the fitted curve towards where it passes nearest the point (one Gauss–Newton
    /// step of the distance along the curve's tangent, at most `span/8`), and the linear
    /// problem is solved again, while the misfit falls. The even-crank layout of stage 1
    /// puts the points where the crank would be if it turned evenly along the path; the
    /// coupler's speed along its curve is far from even, so the source's misfit there is
    /// dominated by that timing error (a slide along the curve), not by its shape. This
    /// removes most of it at `O(M)` a step, cheap enough for every curve of the atlas.
    ///
    /// At most `steps` steps; `true` when it has settled (a step no longer lowered the
    /// misfit, or there is nothing to do). A run of `a` steps resumed with `b` more takes
    /// the same steps as one run of `a + b`, bit for bit (the sums are made again from the
    /// same angles, in the same order).
    #[inline(always)]
    fn project<const AVX2: bool>(
        &self,
        table: &Table,
        w: C64,
        hyp: &mut Hypothesis,
        buf: &mut Projection,
        steps: usize,
    ) -> bool {
        if !matches!(self.layout, Layout::Untimed) || hyp.theta.is_empty() || steps == 0 {
            return true;
        }
        if hyp.mirror {
            self.project_with::<true, AVX2>(table, w, hyp, buf, steps)
        } else {
            self.project_with::<false, AVX2>(table, w, hyp, buf, steps)
        }
    }

    /// [`OpenQuery::project`] for a reflected match (`MIRROR`) or not, decided at compile
    /// time. Each step's trial angles are looked up and summed in one pass (each sum adds
    /// the points in the same order as in separate passes: the same values, bit for bit).
    #[inline(always)]
    fn project_with<const MIRROR: bool, const AVX2: bool>(
        &self,
        table: &Table,
        w: C64,
        hyp: &mut Hypothesis,
        buf: &mut Projection,
        steps: usize,
    ) -> bool {
        let v = usize::from(MIRROR);
        let mut settled = false;
        let limit = (hyp.span / 8.0).max(2.0);
        let mut theta = std::mem::take(&mut hyp.theta);
        let Projection {
            next, at, trial_at, ..
        } = buf;
        // Every one of `next` and `trial_at` is written in each step before it is read
        // (one angle and one lookup a target point, as many as `theta` has): sized only,
        // not filled (what a former window left there is never read).
        debug_assert_eq!(theta.len(), self.y.len());
        next.resize(theta.len(), 0.0);
        // The table at `theta` (each step's trial lookups become the next step's), and
        // the sums from it: every angle is looked up once ([`Table::flat_at_with`] gives the
        // same `Pa` and `e` as [`Table::at`], so the same sums as [`Sums::of`]).
        at.resize(theta.len(), [0.0; 8]);
        for (a, &t) in at.iter_mut().zip(&theta) {
            *a = table.flat_at_with::<AVX2>(t);
        }
        trial_at.resize(theta.len(), [0.0; 8]);
        let y = &self.y;
        let mut s = Sums::accumulate::<MIRROR>(at.iter().map(pa_e), y);
        let n = theta.len().min(y.len());
        for _ in 0..steps {
            let (_, alpha) = s.at_point(v, w);
            let gamma = -alpha * (s.sp + w * s.se) / s.m;
            let fit = (alpha, gamma, w, limit);
            // The first points four at a time where AVX2 runs, the rest one by one.
            #[allow(unused_mut)]
            let mut done = 0;
            #[cfg(target_arch = "x86_64")]
            if AVX2 {
                // SAFETY: `AVX2` is set only on the path that found the processor to
                // have AVX2 ([`linkage_stage1`]); `step_avx2` has no other requirement.
                #[allow(unsafe_code)]
                {
                    done = unsafe { step_avx2::<MIRROR>(fit, &theta, at, y, next) };
                }
            }
            for j in done..n {
                next[j] = step_point::<MIRROR>(fit, theta[j], &at[j], y[j]);
            }
            // The trial angles' lookups and the sums from them in one pass.
            let moved = next.iter().zip(trial_at.iter_mut()).map(|(&n, a)| {
                *a = table.flat_at_with::<AVX2>(n);
                pa_e(a)
            });
            let trial = Sums::accumulate::<MIRROR>(moved, y);
            let misfit = trial.at_point(v, w).0;
            if misfit.partial_cmp(&hyp.misfit) != Some(std::cmp::Ordering::Less) {
                settled = true;
                break;
            }
            hyp.misfit = misfit;
            s = trial;
            std::mem::swap(&mut theta, next);
            std::mem::swap(at, trial_at);
        }
        hyp.theta = theta;
        settled
    }

    /// Stage 2 for one coupler point `w`: re-estimated angles (untimed) or polished start
    /// and step (timed).
    ///
    /// **Four lanes where the processor has them**: on x86-64 with AVX2 (checked at run
    /// time) the same code compiled for AVX2 runs instead (the dynamic programme's
    /// distances four cells a vector), the same operations in the same order, so the same
    /// values bit for bit (as [`linkage_stage1`]).
    fn polish(&self, table: &Table, w: C64, hyp: &Hypothesis, dp: &mut Programme) -> Hypothesis {
        #[cfg(target_arch = "x86_64")]
        if crate::has_avx2() {
            // SAFETY: `polish_avx2` needs AVX2, which the processor was just found to
            // have; it has no other requirement (the safe body compiled for AVX2).
            #[allow(unsafe_code)]
            return unsafe { self.polish_avx2(table, w, hyp, dp) };
        }
        self.polish_body(table, w, hyp, dp)
    }

    /// [`OpenQuery::polish_body`] compiled for AVX2 (called only where the processor has
    /// it).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn polish_avx2(
        &self,
        table: &Table,
        w: C64,
        hyp: &Hypothesis,
        dp: &mut Programme,
    ) -> Hypothesis {
        self.polish_body(table, w, hyp, dp)
    }

    /// [`OpenQuery::polish`] itself, inlined into each of its two callers.
    #[inline(always)]
    fn polish_body(
        &self,
        table: &Table,
        w: C64,
        hyp: &Hypothesis,
        dp: &mut Programme,
    ) -> Hypothesis {
        let v = usize::from(hyp.mirror);
        let mut out = hyp.clone();
        match self.layout {
            Layout::Untimed => {
                let mut s = Sums::of(table, out.theta.iter().copied(), &self.y, hyp.mirror);
                for _ in 0..REESTIMATIONS {
                    let (_, alpha) = s.at_point(v, w);
                    let theta = self.reproject(table, &s, v, w, alpha, &out.theta, dp);
                    let trial = Sums::of(table, theta.iter().copied(), &self.y, hyp.mirror);
                    let misfit = trial.at_point(v, w).0;
                    if misfit.partial_cmp(&out.misfit) != Some(std::cmp::Ordering::Less) {
                        break;
                    }
                    out.theta = theta;
                    out.misfit = misfit;
                    s = trial;
                }
            }
            _ => {
                let free_span = matches!(self.layout, Layout::Steps);
                let eval = |start: f64, span: f64| -> f64 {
                    Sums::of(
                        table,
                        self.thetas(start, span, hyp.sense),
                        &self.y,
                        hyp.mirror,
                    )
                    .at_point(v, w)
                    .0
                };
                let (mut start, mut span) = (hyp.start, hyp.span);
                let mut best = eval(start, span);
                let (mut ds, mut dl) = (2.0, 0.05);
                for _ in 0..40 {
                    let mut moved = false;
                    let mut tries = vec![(start + ds, span), (start - ds, span)];
                    if free_span {
                        tries.push((start, (span * (1.0 + dl)).min(table.period)));
                        tries.push((start, span * (1.0 - dl)));
                    }
                    for (a, b) in tries {
                        let m = eval(a, b);
                        if m < best {
                            (best, start, span) = (m, a, b);
                            moved = true;
                        }
                    }
                    if !moved {
                        ds /= 2.0;
                        dl /= 2.0;
                        if ds < 0.01 {
                            break;
                        }
                    }
                }
                out.start = start;
                out.span = span;
                out.misfit = best;
                out.theta = self.thetas(start, span, hyp.sense).collect();
            }
        }
        out
    }

    /// Moves each point's angle to the nearest point of the fitted curve near it, keeping
    /// the order. `dp` holds the dynamic programme's buffers between calls.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn reproject(
        &self,
        table: &Table,
        s: &Sums,
        v: usize,
        w: C64,
        alpha: C64,
        theta: &[f64],
        dp: &mut Programme,
    ) -> Vec<f64> {
        let m = s.m;
        // γ = −α·mean(Pa + w·e) (the target is centred).
        let gamma = -alpha * (s.sp + w * s.se) / m;
        let curve = |t: f64| {
            let (p, e) = table.at(t);
            alpha * (p + w * e) + gamma
        };
        let target = |j: usize| {
            if v == 1 { self.y[j].conj() } else { self.y[j] }
        };
        let n = theta.len();
        // A grid of crank angles running with the sense of the current assignment, over
        // its window extended on both sides, at most two periods in all.
        let sense = if theta[n - 1] >= theta[0] { 1.0 } else { -1.0 };
        let span = (theta[n - 1] - theta[0]).abs();
        let ext = (0.5 * span)
            .max(30.0)
            .min(0.5 * (2.0 * table.period - span));
        let from = theta[0] - sense * ext;
        let cells = (span + 2.0 * ext).ceil() as usize + 1;
        let Programme {
            re,
            im,
            cost,
            next,
            least,
        } = dp;
        re.clear();
        im.clear();
        for g in 0..cells {
            let c = curve(from + sense * g as f64);
            re.push(c.re);
            im.push(c.im);
        }
        // `|grid[g] − y|²` as `C64::norm_sqr` of the difference gives it.
        let dist = |g: usize, y: C64| {
            let (dr, di) = (re[g] - y.re, im[g] - y.im);
            dr * dr + di * di
        };
        // cost[g]: the least Σ|y_i − c(θ_i)|² over points 0..=j with θ_j = cell g and the
        // cells not decreasing; least[j·cells + g]: the least of point j − 1's costs over
        // cells 0..=g, whose first cell is that of point j − 1 on that path.
        // (Plain loops over buffers of their length: an adapter's closure would be
        // compiled apart, for the baseline instruction set.)
        let y0 = target(0);
        cost.clear();
        cost.resize(cells, 0.0);
        for (g, c) in cost.iter_mut().enumerate() {
            *c = dist(g, y0);
        }
        next.clear();
        next.resize(cells, 0.0);
        // Every entry read below (rows 1 to n − 1) is written first: the buffer is only
        // grown, never cleared.
        if least.len() < n * cells {
            least.resize(n * cells, 0.0);
        }
        for j in 1..n {
            let yj = target(j);
            // The distances first (a pass the compiler can vectorise), then the running
            // least of the previous costs.
            for ((nx, &r), &i) in next[..cells].iter_mut().zip(&re[..cells]).zip(&im[..cells]) {
                let (dr, di) = (r - yj.re, i - yj.im);
                *nx = dr * dr + di * di;
            }
            add_running_least(
                &cost[..cells],
                &mut next[..cells],
                &mut least[j * cells..(j + 1) * cells],
            );
            std::mem::swap(cost, next);
        }
        let mut g = (0..cells)
            .min_by(|&a, &b| cost[a].total_cmp(&cost[b]))
            .unwrap_or(0);
        let mut cell = vec![0usize; n];
        for j in (0..n).rev() {
            cell[j] = g;
            if j > 0 {
                g = first_of_least(&least[j * cells..(j + 1) * cells], g);
            }
        }
        // Each angle refined by a parabola through its neighbouring cells.
        cell.iter()
            .enumerate()
            .map(|(j, &g)| {
                let t = from + sense * g as f64;
                if g == 0 || g + 1 >= cells {
                    return t;
                }
                let yj = target(j);
                let (l, m, r) = (dist(g - 1, yj), dist(g, yj), dist(g + 1, yj));
                let c = l - 2.0 * m + r;
                if c > 0.0 {
                    t + sense * (0.5 * (l - r) / c).clamp(-0.5, 0.5)
                } else {
                    t
                }
            })
            .collect()
    }

    /// The crank angle of every original target point from the query's angles.
    fn target_angles(&self, hyp: &Hypothesis) -> Vec<f64> {
        match self.layout {
            Layout::Untimed => {
                // Interpolated over the positions between the query's points.
                let (x, q) = (&self.x, &hyp.theta);
                let last = x.len() - 1;
                self.target_x
                    .iter()
                    .map(|&t| {
                        let k = x[..last].partition_point(|&a| a <= t).saturating_sub(1);
                        let d = x[k + 1] - x[k];
                        let f = if d > 0.0 {
                            ((t - x[k]) / d).clamp(0.0, 1.0)
                        } else {
                            0.0
                        };
                        q[k] + (q[k + 1] - q[k]) * f
                    })
                    .collect()
            }
            _ => self
                .target_x
                .iter()
                .map(|&x| hyp.start + hyp.sense * hyp.span * x)
                .collect(),
        }
    }
}

/// Points of the linkage screen's query.
const SCREEN_POINTS: usize = 12;

/// The linkage screen of an open target (the coarse-to-fine step before the scan, for
/// atlases of many linkages): a cheap estimate of how well the best coupler point of a
/// linkage can fit the target, to scan only the most promising linkages.
///
/// Each linkage is tried under a coarse grid of hypotheses (12 of the target's points,
/// every other span of the scan, starts every eighth of the span, both senses and, if
/// allowed, reflections). For each, the coupler point is left free: the two-term
/// least-squares fit `y ≈ α·Pa + β·e + γ` gives `w = β/α`, which is clamped to the box of
/// the linkage's coupler points in the atlas and scored there exactly
/// (`Sums::at_point`). The score is the least over the hypotheses: an estimate, not a
/// bound (the even-crank layout is not re-estimated here). Measured on the dense atlas it
/// ranks the source's linkage no better than chance, so a screened scan is a sample of
/// the atlas (`docs/shape-search.md`, "Open targets").
#[derive(Clone, Debug)]
pub struct LinkageScreen {
    query: OpenQuery,
}

impl LinkageScreen {
    /// The screen of an open target; `None` for a closed one or one that cannot be
    /// described.
    pub fn new(target: &Target, allow_mirror: bool) -> Option<LinkageScreen> {
        if target.is_closed() {
            return None;
        }
        Some(LinkageScreen {
            query: OpenQuery::with_points(target, allow_mirror, SCREEN_POINTS, SCREEN_POINTS)?,
        })
    }

    /// The score of one linkage: `group` is a run of atlas curves that share a linkage
    /// and circuit (as [`linkage_groups`] cuts them). Lower is more promising; infinite
    /// if the linkage does not assemble all round.
    pub fn score(&self, group: &[AtlasCurve]) -> f64 {
        let Some(first) = group.first() else {
            return f64::INFINITY;
        };
        let c = &first.curve;
        let Some(table) = Table::new(&c.linkage, c.circuit) else {
            return f64::INFINITY;
        };
        let (mut u0, mut u1, mut v0, mut v1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for a in group {
            let w = w_of(a);
            (u0, u1) = (u0.min(w.re), u1.max(w.re));
            (v0, v1) = (v0.min(w.im), v1.max(w.im));
        }
        let q = &self.query;
        let mirrors: &[bool] = if q.allow_mirror {
            &[false, true]
        } else {
            &[false]
        };
        let mut best = f64::INFINITY;
        let period = table.period;
        for span in q.spans(period).into_iter().step_by(2) {
            let h = match q.layout {
                Layout::Angles { .. } => 6.0,
                _ => (span / 8.0).max(5.0),
            };
            let (count, h) = even_starts(period, h);
            for sense in [1.0, -1.0] {
                for i in 0..count {
                    let s = Sums::of(
                        &table,
                        q.thetas(i as f64 * h, span, sense),
                        &q.y,
                        q.allow_mirror,
                    );
                    let (g11, g12, g22) = s.gram();
                    let det = g11 * g22 - g12.norm_sqr();
                    if det.is_nan() || det <= 0.0 {
                        continue;
                    }
                    for &mirror in mirrors {
                        let v = usize::from(mirror);
                        let [r1, r2] = s.r[v];
                        let alpha = (r1 * g22 - g12 * r2) / det;
                        let beta = (r2 * g11 - g12.conj() * r1) / det;
                        if alpha.norm_sqr() == 0.0 {
                            continue;
                        }
                        let w = beta / alpha;
                        let w = C64::new(w.re.clamp(u0, u1), w.im.clamp(v0, v1));
                        best = best.min(s.at_point_with((g11, g12, g22), v, w).0);
                    }
                }
            }
        }
        best
    }
}

/// The runs of `curves` that share a linkage and circuit (as an atlas lists them), as
/// index ranges: the units the open scan and [`LinkageScreen`] work on.
pub fn linkage_groups(curves: &[AtlasCurve]) -> Vec<std::ops::Range<usize>> {
    let mut groups = Vec::new();
    let mut i = 0;
    while i < curves.len() {
        let c = &curves[i].curve;
        let mut j = i + 1;
        while j < curves.len()
            && curves[j].curve.linkage == c.linkage
            && curves[j].curve.circuit == c.circuit
        {
            j += 1;
        }
        groups.push(i..j);
        i = j;
    }
    groups
}

/// Indices `0..n` thinned to at most `max`, evenly, keeping both ends.
fn thin(n: usize, max: usize) -> Vec<usize> {
    if n <= max {
        return (0..n).collect();
    }
    let mut idx: Vec<usize> = (0..max).map(|j| j * (n - 1) / (max - 1)).collect();
    idx.dedup();
    idx
}

/// A curve proposed by the coarse stage, with how the exact fit should start.
#[derive(Clone, Debug)]
pub(crate) struct OpenCandidate {
    pub curve: AtlasCurve,
    pub misfit: f64,
    pub start: Start,
}

/// Least number of curves kept after stage 1 (stage 2 runs on them; at least twice the
/// candidates wanted).
const STAGE2: usize = 2048;

/// Curves polished by one task of stage 2.
const STAGE2_PART: usize = 64;

fn stage2_count(keep: usize) -> usize {
    STAGE2.max(2 * keep)
}

/// One curve's best stage-1 hypothesis of one reflection: `index` into the whole atlas, `group` the index
/// of its linkage's first curve.
#[derive(Clone, Debug)]
pub(crate) struct Stage1 {
    group: usize,
    index: usize,
    hyp: Hypothesis,
}

/// The coarse stage for an open target over the linkages `groups` of `curves` (runs of
/// curves that share a linkage and circuit, [`linkage_groups`], are scanned once):
/// candidates ordered by misfit, best first.
pub(crate) fn open_candidates(
    query: &OpenQuery,
    curves: &[AtlasCurve],
    groups: &[std::ops::Range<usize>],
    keep: usize,
) -> Vec<OpenCandidate> {
    open_stage2(
        query,
        curves,
        open_stage1(query, curves, groups, keep),
        keep,
    )
}

/// Stage 1 over some linkages of the atlas (`groups`, ranges of `curves` as
/// [`linkage_groups`] cuts them): the best `stage2_count(keep)` of their curves by their
/// best hypothesis, of each reflection (a curve may be there twice, once reflected). The union of such lists over any split of the linkages holds the best
/// of them all, so [`open_stage2`] gives the same result however they are split.
pub(crate) fn open_stage1(
    query: &OpenQuery,
    curves: &[AtlasCurve],
    groups: &[std::ops::Range<usize>],
    keep: usize,
) -> Vec<Stage1> {
    let mut stage1: Vec<Stage1> = Vec::new();
    let mut scanner = Scanner::default();
    for g in groups {
        scanner.scan(query, curves, g.clone(), &mut stage1);
    }
    truncate_stage1(&mut stage1, keep);
    stage1
}

/// What scanning one linkage after another reuses: the projection's buffers, the scan's
/// passes (made again only when the period changes: geared five-bars) and the crank
/// angles of the tables.
#[derive(Default)]
struct Scanner {
    buf: Projection,
    passes: Option<Passes>,
    cranks: Cranks,
}

impl Scanner {
    /// Stage 1 with its projections on the linkage `g` (a range of `curves`): each
    /// curve's best window of each reflection, pushed onto `out`.
    fn scan(
        &mut self,
        query: &OpenQuery,
        curves: &[AtlasCurve],
        g: std::ops::Range<usize>,
        out: &mut Vec<Stage1>,
    ) {
        let (a, b) = (g.start, g.end);
        let Some(first) = curves.get(a) else {
            return;
        };
        let c = &first.curve;
        let Some(table) = self.cranks.table(&c.linkage, c.circuit) else {
            return;
        };
        let table = table.with_ring();
        let pts: Vec<C64> = (a..b.min(curves.len())).map(|k| w_of(&curves[k])).collect();
        if self
            .passes
            .as_ref()
            .is_none_or(|p| p.period != table.period)
        {
            self.passes = Some(query.passes(table.period));
        }
        let passes = self.passes.as_ref().expect("made above");
        linkage_stage1(query, passes, &table, &pts, a, &mut self.buf, out);
    }
}

/// Settings of the lattice search (`docs/shape-search.md`, "The lattice search"): an
/// open target's coarse-to-fine scan over the atlas's linkage lattice
/// ([`LinkageLattice`]) instead of a scan of every linkage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LatticeSearch {
    /// The search runs on an atlas of more than this many linkages (`usize::MAX`: never;
    /// every linkage is scanned).
    pub above: usize,
    /// The sub-lattice scanned first: one linkage per cell of this many lattice steps a
    /// side.
    pub cell: usize,
    /// The best linkages (by their best curve's stage-1 misfit) whose neighbours are
    /// scanned, round after round until the best this many have all had theirs scanned.
    pub best: usize,
    /// Neighbours: linkages within this many lattice steps in every dimension.
    pub radius: usize,
    /// Once the rounds settle, the unscanned linkages within this many steps of the best
    /// one are scanned too, and the rounds go on from them (once per linkage that is
    /// best when they settle; nothing when not more than `radius`).
    pub widen: usize,
}

impl LatticeSearch {
    /// On an atlas of more than 2,000 linkages (the dense atlas has 31,018, the default
    /// one 175): cells of 5 lattice steps, the neighbours within one step of the best 4,
    /// and once settled within two of the best (`docs/shape-search.md`, "The lattice
    /// search", for the measured recall).
    pub const DEFAULT: LatticeSearch = LatticeSearch {
        above: 2_000,
        cell: 5,
        best: 4,
        radius: 1,
        widen: 2,
    };

    /// No lattice search: every linkage scanned.
    pub const FULL: LatticeSearch = LatticeSearch {
        above: usize::MAX,
        ..LatticeSearch::DEFAULT
    };
}

/// What a lattice search scanned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LatticeReport {
    /// Linkages in the sub-lattice.
    pub sampled: usize,
    /// Linkages scanned (the sub-lattice's among them).
    pub scanned: usize,
    /// Curves of the linkages scanned.
    pub curves: usize,
    /// Linkages of the atlas.
    pub linkages: usize,
    /// Rounds of neighbours scanned after the sub-lattice (the widening ones among them).
    pub rounds: usize,
}

/// Linkages of one task of the lattice search.
const LATTICE_PART: usize = 4;

/// Stage 1 by the lattice search over the linkages `groups` of `curves`, for each
/// reflection on its own: the sub-lattice ([`LinkageLattice::sample`]) scanned, the
/// linkages ranked by their best curve's misfit of that reflection (ties by atlas
/// order), and the unscanned neighbours of the best `search.best` scanned, until each of
/// the best has had its neighbours scanned; then those within `search.widen` steps of
/// the best, and the rounds again, until they settle on a best already widened. A
/// linkage is scanned once (by [`open_stage1`]'s scan) whichever reflection asks for it,
/// but a reflection takes its own hypotheses only from the linkages its own search
/// reached: so the unreflected ones are those of the same query without reflection, bit
/// for bit, and `--mirror` only adds (as in the full scan). The linkages are scanned in parallel on the calling thread's
/// rayon pool; which are scanned depends on their scores and order only, so the result
/// is the same on any number of threads.
pub(crate) fn open_stage1_lattice(
    query: &OpenQuery,
    curves: &[AtlasCurve],
    groups: &[std::ops::Range<usize>],
    search: &LatticeSearch,
    keep: usize,
) -> (Vec<Stage1>, LatticeReport) {
    let lattice = LinkageLattice::new(curves, groups);
    let n = groups.len();
    let reflections = if query.allow_mirror { 2 } else { 1 };
    // Each linkage's scan, once made.
    let mut scans: Vec<Option<Vec<Stage1>>> = vec![None; n];
    // Per reflection: the score of each linkage it reached, and which it expanded.
    let mut score = vec![vec![None::<f64>; n]; reflections];
    let mut expanded = vec![vec![false; n]; reflections];
    let mut widened = vec![vec![false; n]; reflections];
    let mut stage1: Vec<Stage1> = Vec::new();
    let sample = lattice.sample(search.cell);
    let mut report = LatticeReport {
        sampled: sample.len(),
        scanned: 0,
        curves: 0,
        linkages: n,
        rounds: 0,
    };
    let mut todo = vec![sample; reflections];
    loop {
        let mut need: Vec<usize> = todo.concat();
        need.sort_unstable();
        need.dedup();
        need.retain(|&i| scans[i].is_none());
        let found: Vec<(usize, Vec<Stage1>)> = need
            .par_chunks(LATTICE_PART)
            .flat_map_iter(|part| {
                let mut scanner = Scanner::default();
                part.iter()
                    .map(|&i| {
                        let mut out = Vec::new();
                        scanner.scan(query, curves, groups[i].clone(), &mut out);
                        (i, out)
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        report.scanned += found.len();
        report.curves += found.iter().map(|(i, _)| groups[*i].len()).sum::<usize>();
        for (i, out) in found {
            scans[i] = Some(out);
        }
        let mut next = vec![Vec::new(); reflections];
        for m in 0..reflections {
            let mirror = m == 1;
            for &i in &todo[m] {
                let out = scans[i].as_deref().unwrap_or_default();
                let mine = out.iter().filter(|s| s.hyp.mirror == mirror);
                score[m][i] = Some(
                    mine.clone()
                        .map(|s| s.hyp.misfit)
                        .fold(f64::INFINITY, f64::min),
                );
                stage1.extend(mine.cloned());
            }
            let mut order: Vec<(f64, usize)> =
                (0..n).filter_map(|i| score[m][i].map(|s| (s, i))).collect();
            order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            for &(s, i) in order.iter().take(search.best) {
                if !expanded[m][i] && s.is_finite() {
                    expanded[m][i] = true;
                    next[m].extend(
                        lattice
                            .neighbours(i, search.radius)
                            .into_iter()
                            .filter(|&j| score[m][j].is_none()),
                    );
                }
            }
            next[m].sort_unstable();
            next[m].dedup();
            // Settled: the wider neighbourhood of the best, once per linkage.
            let settled = next[m].is_empty() && search.widen > search.radius;
            if let Some(&(_, i)) = order
                .first()
                .filter(|&&(s, i)| settled && s.is_finite() && !widened[m][i])
            {
                widened[m][i] = true;
                next[m] = lattice.neighbours(i, search.widen);
                next[m].retain(|&j| score[m][j].is_none());
            }
        }
        truncate_stage1(&mut stage1, keep);
        if next.iter().all(|t| t.is_empty()) {
            break;
        }
        report.rounds += 1;
        todo = next;
    }
    (stage1, report)
}

/// Stage 1 and its projections on one linkage (`table`, its coupler points `pts`, the
/// first of them curve `a` of the atlas): each curve's best window of each reflection,
/// pushed onto `out`.
///
/// **Four lanes where the processor has them.** On x86-64 with AVX2 (checked at run
/// time) the same code is compiled for AVX2 and run instead (the sieve's points four a
/// vector instead of two, the three-operand forms of the other arithmetic). Rust never
/// fuses a multiply and an add without being asked, and every operation is the same
/// IEEE-754 operation in the same order, so every value is the same, bit for bit, on
/// either path.
fn linkage_stage1(
    query: &OpenQuery,
    passes: &Passes,
    table: &Table,
    pts: &[C64],
    a: usize,
    buf: &mut Projection,
    out: &mut Vec<Stage1>,
) {
    #[cfg(target_arch = "x86_64")]
    if crate::has_avx2() {
        // SAFETY: `linkage_stage1_avx2` needs AVX2, which the processor was just found
        // to have; it has no other requirement (it is the safe body compiled for AVX2).
        #[allow(unsafe_code)]
        unsafe {
            linkage_stage1_avx2(query, passes, table, pts, a, buf, out)
        };
        return;
    }
    linkage_stage1_body::<false>(query, passes, table, pts, a, buf, out)
}

/// [`linkage_stage1_body`] compiled for AVX2 (called only where the processor has it).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn linkage_stage1_avx2(
    query: &OpenQuery,
    passes: &Passes,
    table: &Table,
    pts: &[C64],
    a: usize,
    buf: &mut Projection,
    out: &mut Vec<Stage1>,
) {
    linkage_stage1_body::<true>(query, passes, table, pts, a, buf, out)
}

/// [`linkage_stage1`] itself, inlined into each of its two callers so that each is
/// compiled for its own instruction set (`AVX2`: the kernel's sums by
/// [`Kernel::flat_sums_avx2`]).
#[inline(always)]
fn linkage_stage1_body<const AVX2: bool>(
    query: &OpenQuery,
    passes: &Passes,
    table: &Table,
    pts: &[C64],
    a: usize,
    buf: &mut Projection,
    out: &mut Vec<Stage1>,
) {
    let mut hs: Vec<Hypothesis> = Vec::new();
    for (k, ws) in query
        .scan_with::<AVX2>(passes, table, pts)
        .into_iter()
        .enumerate()
    {
        // Each reflection's best window after the projection: a curve goes on once
        // per reflection, so its unreflected hypothesis is the one a query without
        // reflection keeps.
        // Every window gets the first `PROJECTION_HEAT` steps; the best
        // `PROJECTION_KEEP` of each reflection (by their misfit then) the rest, those
        // that have not settled (stopped falling) yet: the same steps as in one run
        // (a run resumes from its angles and misfit, and the sums are made again from
        // the same angles; tested by `a_resumed_projection_is_one_run`).
        // (Plain loops: a closure passed to a generic adapter is compiled apart from
        // this body, for the baseline instruction set.)
        // The windows' angles laid out in vectors of former windows (returned below).
        hs.clear();
        for b in &ws {
            let theta = buf.spare.pop().unwrap_or_default();
            hs.push(query.hypothesis(b, theta));
        }
        let mut settled = Vec::with_capacity(hs.len());
        for h in hs.iter_mut() {
            settled.push(query.project::<AVX2>(table, pts[k], h, buf, PROJECTION_HEAT));
        }
        for mirror in [false, true] {
            let mut order: Vec<usize> = (0..hs.len()).filter(|&i| hs[i].mirror == mirror).collect();
            order.sort_by(|&a, &b| hs[a].misfit.total_cmp(&hs[b].misfit));
            for &i in order.iter().take(PROJECTION_KEEP).filter(|&&i| !settled[i]) {
                query.project::<AVX2>(
                    table,
                    pts[k],
                    &mut hs[i],
                    buf,
                    PROJECTIONS - PROJECTION_HEAT,
                );
            }
        }
        for mirror in [false, true] {
            let Some(h) = hs
                .iter()
                .filter(|h| h.mirror == mirror)
                .min_by(|a, b| a.misfit.total_cmp(&b.misfit))
            else {
                continue;
            };
            if h.misfit.is_finite() {
                out.push(Stage1 {
                    group: a,
                    index: a + k,
                    hyp: h.clone(),
                });
            }
        }
        buf.spare.extend(hs.drain(..).map(|h| h.theta));
    }
}

/// The best `stage2_count(keep)` of `stage1` by misfit (ties by index) **of each
/// reflection**: reflected hypotheses never take an unreflected one's place, so the
/// unreflected ones kept are those a query without reflection keeps.
fn truncate_stage1(stage1: &mut Vec<Stage1>, keep: usize) {
    stage1.sort_by(|x, y| {
        x.hyp
            .misfit
            .total_cmp(&y.hyp.misfit)
            .then(x.index.cmp(&y.index))
            .then(x.hyp.mirror.cmp(&y.hyp.mirror))
    });
    keep_each_reflection(stage1, stage2_count(keep), |s| s.hyp.mirror);
}

/// Keeps the first `n` items of each reflection (`mirror` of an item), in order.
pub(crate) fn keep_each_reflection<T>(items: &mut Vec<T>, n: usize, mirror: impl Fn(&T) -> bool) {
    let mut count = [0usize; 2];
    items.retain(|x| {
        let c = &mut count[usize::from(mirror(x))];
        *c += 1;
        *c <= n
    });
}

fn w_of(c: &AtlasCurve) -> C64 {
    C64::new(c.curve.point.u, c.curve.point.v)
}

/// Stage 2 over the best of `stage1` (from one or several parts of `curves`, the whole
/// atlas): re-estimated angles, the best `keep` of each reflection as candidates, best
/// first.
pub(crate) fn open_stage2(
    query: &OpenQuery,
    curves: &[AtlasCurve],
    mut stage1: Vec<Stage1>,
    keep: usize,
) -> Vec<OpenCandidate> {
    truncate_stage1(&mut stage1, keep);
    // Linkage by linkage (one table each), in parts on the calling thread's rayon pool:
    // each curve's polish is its own, and the parts are joined in order, so the result
    // does not depend on the threads.
    stage1.sort_by_key(|x| (x.group, x.index, x.hyp.mirror));
    let mut out: Vec<OpenCandidate> = stage1
        .par_chunks(STAGE2_PART)
        .flat_map_iter(|part| {
            let mut table: Option<(usize, Table)> = None;
            let mut cranks = Cranks::default();
            let mut dp = Programme::default();
            let mut out = Vec::with_capacity(part.len());
            for s in part {
                let Some(curve) = curves.get(s.index) else {
                    continue;
                };
                if table.as_ref().is_none_or(|t| t.0 != s.group) {
                    let c = &curve.curve;
                    table = cranks.table(&c.linkage, c.circuit).map(|t| (s.group, t));
                }
                let Some((_, t)) = &table else { continue };
                let p = query.polish(t, w_of(curve), &s.hyp, &mut dp);
                out.push(OpenCandidate {
                    curve: *curve,
                    misfit: p.misfit,
                    start: Start {
                        mirrored: p.mirror,
                        theta: query.target_angles(&p),
                        score: p.misfit,
                    },
                });
            }
            out
        })
        .collect();
    out.sort_by(|x, y| {
        x.misfit
            .total_cmp(&y.misfit)
            .then(x.curve.id.cmp(&y.curve.id))
            .then(x.start.mirrored.cmp(&y.start.mirrored))
    });
    // The best `keep` of each reflection (with reflection allowed, up to twice as many
    // candidates: those a query without it proposes, and as many reflected).
    keep_each_reflection(&mut out, keep, |c| c.start.mirrored);
    out
}

/// Starts about `h` degrees apart over a `period`: the step made to divide the period
/// evenly, and how many starts it gives (`(count, step)`).
fn even_starts(period: f64, h: f64) -> (usize, f64) {
    let count = (period / h).ceil() as usize;
    (count, period / count as f64)
}

#[cfg(test)]
mod tests {
    use super::{
        C64, Sums, TableCell, add_running_least, cell, cell_floor, cell_floor_general,
        first_of_least,
    };
    use crate::cases::SplitMix64;

    /// The scan skips a point's misfit only when it is surely above the bound: wherever
    /// `surely_above` says so, the misfit computed in full is above the bound, over
    /// random sums, points and bounds, also with the bound a hair below the misfit.
    #[test]
    fn surely_above_never_skips_a_misfit_below_the_bound() {
        let mut rng = SplitMix64(17);
        let c = |rng: &mut SplitMix64| C64::new(rng.normal(), rng.normal());
        let mut skipped = 0;
        for _ in 0..200_000 {
            let s = Sums {
                m: 32.0,
                sp: c(&mut rng),
                se: c(&mut rng),
                spe: c(&mut rng),
                r: [
                    [c(&mut rng) * 0.3, c(&mut rng) * 0.3],
                    [c(&mut rng), c(&mut rng)],
                ],
            };
            let gram = (32.0 * rng.uniform(), c(&mut rng), 32.0 * rng.uniform());
            let w = c(&mut rng) * 2.0;
            let mm = Sums::model_norm(gram, w);
            for v in 0..2 {
                let m = s.misfit_with(mm, v, w);
                assert_eq!(m, s.at_point_with(gram, v, w).0);
                for bound in [
                    rng.uniform(),
                    m - 1e-12,
                    m - 2e-9,
                    m * (1.0 - 1e-15),
                    m,
                    0.0,
                    1.0,
                ] {
                    if s.surely_above(mm, v, w, bound) {
                        skipped += 1;
                        assert!(m > bound, "{m} {bound}");
                    }
                }
            }
        }
        assert!(skipped > 10_000, "the test reaches the skip: {skipped}");
    }

    /// Random sums as a scan makes them (32 points of a table-like curve, a centred unit
    /// target), with their Gram matrix.
    fn random_sums(rng: &mut SplitMix64) -> (Sums, (f64, C64, f64)) {
        let mut c = || C64::new(rng.normal(), rng.normal());
        let (a, b, k) = (c(), c() * 0.3, c());
        let y: Vec<C64> = (0..32).map(|_| c()).collect();
        let mean = y.iter().sum::<C64>() / 32.0;
        let norm = y.iter().map(|z| (z - mean).norm_sqr()).sum::<f64>().sqrt();
        let y: Vec<C64> = y.iter().map(|z| (z - mean) / norm).collect();
        let pe = (0..32).map(|j| {
            let t = 0.05 * j as f64 + k.re;
            let p = C64::new(t.cos(), t.sin());
            let e = (a + b * C64::new((2.0 * t).cos(), (2.0 * t).sin())).unwrap_or_unit();
            (p, e)
        });
        let s = Sums::accumulate::<true>(pe, &y);
        let gram = s.gram();
        (s, gram)
    }

    trait UnitOr {
        fn unwrap_or_unit(self) -> C64;
    }

    impl UnitOr for C64 {
        fn unwrap_or_unit(self) -> C64 {
            let n = self.norm();
            if n > 0.0 {
                self / n
            } else {
                C64::new(1.0, 0.0)
            }
        }
    }

    /// The least misfit of a hypothesis is a lower bound of the misfit at every coupler
    /// point, margin included, and is reached (up to rounding) at the free optimum: over
    /// random sums and points, near and far.
    #[test]
    fn least_misfit_bounds_every_point() {
        let mut rng = SplitMix64(23);
        let mut used = 0;
        for _ in 0..20_000 {
            let (s, gram) = random_sums(&mut rng);
            for v in 0..2 {
                let lb = s.least_misfit(gram, v);
                if lb == f64::NEG_INFINITY {
                    continue;
                }
                used += 1;
                // The optimum w = β/α of the free two-term fit attains it.
                let (g11, g12, g22) = gram;
                let det = g11 * g22 - g12.norm_sqr();
                let [r1, r2] = s.r[v];
                let alpha = (r1 * g22 - g12 * r2) / det;
                let beta = (r2 * g11 - g12.conj() * r1) / det;
                let best = beta / alpha;
                let at_best = s.misfit_with(Sums::model_norm(gram, best), v, best);
                assert!((at_best - lb).abs() < 1e-9, "{at_best} {lb}");
                for scale in [1e-3, 0.1, 1.0, 10.0, 1e3] {
                    for w in [
                        best,
                        best + C64::new(rng.normal(), rng.normal()) * scale,
                        C64::new(rng.normal(), rng.normal()) * scale,
                    ] {
                        let m = s.misfit_with(Sums::model_norm(gram, w), v, w);
                        assert!(m > lb - super::BOUND_MARGIN, "{m} {lb} {w}");
                    }
                }
            }
        }
        assert!(used > 10_000, "the bound is usable: {used}");
    }

    /// The sieve leaves a point open for a reflection exactly when that reflection is
    /// live and `surely_above` does not hold, bound by bound.
    #[test]
    fn sieve_is_surely_above_point_by_point() {
        let mut rng = SplitMix64(29);
        for i in 0..2_000 {
            let (s, gram) = random_sums(&mut rng);
            // One word with a remainder, two and three words (one of them whole).
            let pts: Vec<C64> = (0..[50, 87, 128, 131][i % 4])
                .map(|_| C64::new(rng.normal(), rng.normal()) * 3.0)
                .collect();
            // Each reflection its own bounds (shifted by one point against the other's).
            let worst: Vec<Vec<f64>> = (0..2)
                .map(|v| {
                    pts.iter()
                        .enumerate()
                        .map(|(k, &w)| match (k + v) % 5 {
                            0 => f64::INFINITY,
                            1 => 1.5,
                            2 => rng.uniform(),
                            // A hair around the point's own misfit.
                            _ => {
                                let m = s.misfit_with(Sums::model_norm(gram, w), v, w);
                                m + (rng.uniform() - 0.5) * 2e-9
                            }
                        })
                        .collect()
                })
                .collect();
            let bar: Vec<Vec<f64>> = worst
                .iter()
                .map(|l| l.iter().map(|w| 1.0 - w - 1e-9).collect())
                .collect();
            let cols = super::PointColumns::new(&pts);
            for live in [[true, true], [true, false], [false, true]] {
                let mut open = vec![[0u64; 2]; pts.len().div_ceil(64)];
                super::sieve::<false>(&s, gram, &cols, [&bar[0], &bar[1]], live, &mut open);
                for (k, &w) in pts.iter().enumerate() {
                    let mm = Sums::model_norm(gram, w);
                    for (v, &l) in live.iter().enumerate() {
                        let want = l && !s.surely_above(mm, v, w, worst[v][k]);
                        assert_eq!((open[k / 64][v] >> (k % 64)) & 1 != 0, want, "{k} {v}");
                    }
                }
                // Every bit past the points is clear.
                if let Some(last) = open.last() {
                    let tail = pts.len() % 64;
                    if tail != 0 {
                        assert_eq!(last[0] >> tail, 0);
                        assert_eq!(last[1] >> tail, 0);
                    }
                }
                // The same bits in AVX2 vectors, where the processor has them.
                #[cfg(target_arch = "x86_64")]
                if crate::has_avx2() {
                    let mut fast = vec![[1u64; 2]; open.len()];
                    super::sieve::<true>(&s, gram, &cols, [&bar[0], &bar[1]], live, &mut fast);
                    assert_eq!(fast, open);
                }
            }
        }
    }

    /// The programme's running least without an index finds the cells and sums of the
    /// one with it, bit for bit.
    #[test]
    fn running_least_finds_the_indexed_cells() {
        // Rows with ties, +∞ and NaN among the costs, against the running least that
        // keeps its index (the programme as first written).
        let mut rng = SplitMix64(41);
        let values: [f64; 7] = [0.0, 1.0, 2.0, 2.0, 3.5, f64::INFINITY, f64::NAN];
        for case in 0..2000 {
            let cells = 1 + case % 37;
            let cost: Vec<f64> = (0..cells)
                .map(|_| {
                    if rng.uniform() < 0.5 {
                        values[(rng.next_u64() % values.len() as u64) as usize]
                    } else {
                        rng.range(0.0, 4.0)
                    }
                })
                .collect();
            let dist: Vec<f64> = (0..cells).map(|_| rng.uniform()).collect();
            let mut next = dist.clone();
            let mut least = vec![0.0; cells];
            add_running_least(&cost, &mut next, &mut least);
            let mut run = (f64::INFINITY, 0usize);
            for g in 0..cells {
                if cost[g] < run.0 {
                    run = (cost[g], g);
                }
                assert_eq!(least[g].to_bits(), run.0.to_bits(), "case {case} cell {g}");
                assert_eq!(
                    next[g].to_bits(),
                    (dist[g] + run.0).to_bits(),
                    "case {case} cell {g}"
                );
                assert_eq!(first_of_least(&least, g), run.1, "case {case} cell {g}");
            }
        }
    }

    /// `rem_period` is `rem_euclid`, bit for bit, near and far from the range it shortcuts.
    #[test]
    fn rem_period_is_rem_euclid() {
        let mut rng = SplitMix64(31);
        for period in [360.0, 720.0, 1080.0] {
            let mut xs: Vec<f64> = (0..20_000)
                .map(|_| (rng.uniform() - 0.5) * 6.0 * period)
                .collect();
            for k in -3..=3 {
                let b = k as f64 * period;
                xs.extend([b, b + 1e-13, b - 1e-13, -0.0, 0.0, b + 0.5, b - 0.5]);
            }
            for x in xs {
                assert_eq!(
                    super::rem_period(x, period).to_bits(),
                    x.rem_euclid(period).to_bits(),
                    "{x} {period}"
                );
            }
        }
    }

    /// `offer` keeps the windows in the order a stable sort by misfit gives, over random
    /// offers with many ties.
    #[test]
    fn offer_keeps_the_stable_sorted_order() {
        use super::{WINDOWS, Window, offer};
        let mut rng = SplitMix64(37);
        for _ in 0..2_000 {
            let mut list: Vec<Window> = Vec::new();
            let mut reference: Vec<Window> = Vec::new();
            for _ in 0..60 {
                let h = Window::new(
                    (rng.uniform() * 8.0).floor() / 8.0,
                    rng.uniform() < 0.5,
                    (rng.uniform() * 24.0).floor() * 15.0,
                    [30.0, 36.0, 60.0, 180.0][(rng.uniform() * 4.0) as usize],
                    if rng.uniform() < 0.5 { 1.0 } else { -1.0 },
                );
                offer(&mut list, h, 360.0);
                // The reference: the former form, a stable sort after each change.
                let r = &mut reference;
                if !(r.len() == WINDOWS && h.misfit >= r[WINDOWS - 1].misfit) {
                    let i = r.iter().position(|x| x.alike(&h, 360.0));
                    let changed = match i {
                        Some(i) if h.misfit < r[i].misfit => {
                            r[i] = h;
                            true
                        }
                        Some(_) => false,
                        None => {
                            r.push(h);
                            true
                        }
                    };
                    if changed {
                        r.sort_by(|a, b| a.misfit.total_cmp(&b.misfit));
                        r.truncate(WINDOWS);
                    }
                }
                let key = |l: &[Window]| -> Vec<(u64, bool, u64, u64, u64)> {
                    l.iter()
                        .map(|w| {
                            (
                                w.misfit.to_bits(),
                                w.mirror,
                                w.start.to_bits(),
                                w.span.to_bits(),
                                w.sense.to_bits(),
                            )
                        })
                        .collect()
                };
                assert_eq!(key(&list), key(r));
            }
        }
    }

    /// The cell of an angle is the one of the floating remainder's whole part, with the
    /// same fraction, inside the scan's range and far outside it.
    #[test]
    fn cell_is_the_euclidean_remainder() {
        for period in [360usize, 720, 1080] {
            let p = period as f64;
            let mut deg = -3.5 * p;
            while deg < 4.5 * p {
                let whole = deg.floor();
                let (k, t) = cell(deg, period);
                assert_eq!(
                    k,
                    (whole as i64).rem_euclid(period as i64) as usize,
                    "{deg}"
                );
                assert_eq!(t, deg - whole, "{deg}");
                assert_eq!(cell_floor(deg, period), (k, t), "{deg}");
                deg += 0.37;
            }
            assert_eq!(cell_floor(-0.0, period), (0, 0.0));
            assert_eq!(cell(-0.0, period), (0, 0.0));
            assert_eq!(cell(p, period), (0, 0.0));
            assert_eq!(cell_floor(p, period), (0, 0.0));
            assert_eq!(cell(-1e-12, period).0, period - 1);
            assert_eq!(cell_floor(-1e-12, period).0, period - 1);
            // Far values, where the conversion saturates or the wrap by one period does
            // not reach: the general form's answer.
            for deg in [
                1e14 + 0.25,
                -1e14 - 0.75,
                1e15,
                -3e15,
                9.3e18,
                -9.3e18,
                1e300,
                -1e300,
                i64::MIN as f64,
            ] {
                let (k, t) = cell_floor(deg, period);
                assert_eq!((k, t.to_bits()), {
                    let (k, t) = cell_floor_general(deg, period);
                    (k, t.to_bits())
                });
                assert_eq!((k, t.to_bits()), {
                    let (k, t) = cell(deg, period);
                    (k, t.to_bits())
                });
            }
            let (k, t) = cell_floor(f64::NAN, period);
            assert_eq!(k, cell(f64::NAN, period).0);
            assert!(t.is_nan());
        }
    }

    /// [`Table::ring_at`] gives the cell and fraction [`cell_floor`] finds, near the
    /// ring's ends and far from them.
    #[test]
    fn ring_at_is_cell_floor() {
        for period in [360usize, 720] {
            let cells: Vec<TableCell> = (0..period)
                .map(|k| {
                    let x = k as f64;
                    TableCell {
                        pa: C64::new(x, -x),
                        e: C64::new(x + 0.5, 1.0),
                        dpa: C64::new(2.0 * x, 3.0),
                        de: C64::new(-x, 0.25),
                    }
                })
                .collect();
            let table = super::Table {
                cells,
                ring: Vec::new(),
                period: period as f64,
            }
            .with_ring();
            assert_eq!(table.ring.len(), 3 * period);
            let p = period as f64;
            let mut degs = vec![
                -0.0,
                1e-300,
                -1e-12,
                p,
                -p,
                2.0 * p,
                -p - 1e-9,
                2.0 * p - 1e-9,
            ];
            degs.extend([1e15, -1e15, 1e300, -1e300, 9.3e18, -9.3e18]);
            let mut deg = -3.5 * p;
            while deg < 4.5 * p {
                degs.push(deg);
                deg += 0.37;
            }
            for deg in degs {
                let (c, t) = table.ring_at(deg);
                let (k, want) = cell_floor(deg, period);
                assert_eq!(t.to_bits(), want.to_bits(), "{deg}");
                assert_eq!(c.pa, table.cells[k].pa, "{deg}");
                assert_eq!(c.e, table.cells[k].e, "{deg}");
            }
            let (c, t) = table.ring_at(f64::NAN);
            assert_eq!(c.pa, table.cells[cell_floor(f64::NAN, period).0].pa);
            assert!(t.is_nan());
        }
    }
}

#[cfg(test)]
mod mirror {
    //! Allowing reflection only adds candidates: the unreflected ones are those of the
    //! same query without reflection, bit for bit.
    use super::*;
    use crate::cases::retrieval_cases;
    use crate::kin::CouplerCurve;
    use coupler_kinematics::{CouplerPoint, FourBar};

    /// The open circuit's curves of `l` at 8 × 5 coupler points, in steps of a quarter
    /// and half of its coupler `A`, numbered on from `out`'s.
    pub(super) fn push_grid(l: FourBar, out: &mut Vec<AtlasCurve>) {
        let a = l.coupler;
        for i in 0..8 {
            for j in 0..5 {
                let p =
                    CouplerPoint::new(a * (-0.25 + 0.25 * i as f64), a * (-1.0 + 0.5 * j as f64));
                out.push(AtlasCurve {
                    id: out.len() as u64,
                    curve: CouplerCurve::new(l, Circuit::Open, p),
                });
            }
        }
    }

    /// Four linkages, 40 coupler points each: the Chebyshev-like symmetric one (A = B),
    /// whose curves score about as well reflected, and three others.
    fn atlas() -> Vec<AtlasCurve> {
        let mut out = Vec::new();
        for (a, b, c) in [
            (2.5, 2.5, 2.0),
            (3.0, 2.5, 3.5),
            (2.0, 3.0, 3.5),
            (3.5, 4.0, 3.0),
        ] {
            push_grid(FourBar::new(a, b, c).unwrap(), &mut out);
        }
        out
    }

    fn bits(c: &OpenCandidate) -> (u64, u64, bool, Vec<u64>) {
        (
            c.curve.id,
            c.misfit.to_bits(),
            c.start.mirrored,
            c.start.theta.iter().map(|t| t.to_bits()).collect(),
        )
    }

    /// A random target of 2 to 41 points for the kernel tests: its offsets along a span
    /// of 30° to 360° in either sense (the first at 0 and the last at the span when
    /// `pinned`), and its points centred and scaled to unit size.
    fn random_kernel_target(
        rng: &mut crate::cases::SplitMix64,
        pinned: bool,
    ) -> (Vec<f64>, Vec<C64>) {
        let m = 2 + (rng.next_u64() % 40) as usize;
        let mut x: Vec<f64> = (0..m).map(|_| rng.uniform()).collect();
        x.sort_by(f64::total_cmp);
        if pinned {
            (x[0], x[m - 1]) = (0.0, 1.0);
        }
        let y: Vec<C64> = (0..m)
            .map(|_| C64::new(rng.normal(), rng.normal()))
            .collect();
        let y = centred_unit(&y).unwrap();
        let span = 30.0 + 330.0 * rng.uniform();
        let sense = if rng.uniform() < 0.5 { 1.0 } else { -1.0 };
        (x.iter().map(|&x| sense * span * x).collect(), y)
    }

    /// Stage 1's kernel sums at whole-degree starts are the sums of the linear
    /// interpolants [`Sums::of`] makes, to rounding, for `Pa`, `e` and the `R` sums of
    /// both reflections; `S_Pe` (the interpolant of the tabulated product, not the product
    /// of interpolants) within `O(1°²)`: over four linkages, random targets, spans,
    /// senses and starts (also negative and past a period).
    #[test]
    fn kernel_sums_are_the_interpolated_sums() {
        let curves = atlas();
        let mut rng = crate::cases::SplitMix64(41);
        let (mut worst, mut worst_pe, mut tried) = (0.0f64, 0.0f64, 0);
        for g in linkage_groups(&curves) {
            let c = &curves[g.start].curve;
            let table = Table::new(&c.linkage, c.circuit).unwrap();
            let grid = Grid::new(&table);
            for _ in 0..40 {
                let (offsets, y) = random_kernel_target(&mut rng, true);
                let m = y.len();
                let kernel = Kernel::new(&offsets, &y);
                assert!(kernel.reach() <= grid.cells.len() - grid.period);
                for start in (-400..800).step_by(37) {
                    let k = kernel.sums::<false>(&grid, start);
                    let want =
                        Sums::of(&table, offsets.iter().map(|&o| start as f64 + o), &y, true);
                    assert_eq!(k.m, want.m);
                    let mut d = (k.sp - want.sp).norm().max((k.se - want.se).norm());
                    for v in 0..2 {
                        for i in 0..2 {
                            d = d.max((k.r[v][i] - want.r[v][i]).norm());
                        }
                    }
                    worst = worst.max(d);
                    worst_pe = worst_pe.max((k.spe - want.spe).norm() / m as f64);
                    tried += 1;
                }
            }
        }
        assert!(tried > 5000, "{tried}");
        assert!(worst < 1e-12, "{worst}");
        // The two differ by `Σ t(1 − t)·ΔPa·conj(Δe)`-like terms: each at most a quarter
        // of the product of two 1° differences of unit vectors turning at most a few
        // times faster than the crank, so at most about 10⁻³ a point.
        assert!(worst_pe < 1e-3 && worst_pe > 0.0, "{worst_pe}");
    }

    /// [`Kernel::sums`] from flat lanes gives the sums of the loop it replaced (a
    /// multiply-add per `[re, im]` pair, the factors `[[w, w], [Re, Re], [Im, Im]]`
    /// beside each cell), bit for bit: over four linkages, random targets, spans, senses
    /// and starts.
    #[test]
    fn kernel_sums_as_first_written() {
        fn first_written(kernel: &Kernel, grid: &Grid, start: i64) -> [[f64; 2]; 7] {
            let base = (start + kernel.lo).rem_euclid(grid.period as i64) as usize;
            let cells = &grid.cells[base..];
            let mut acc = [[0.0f64; 2]; 7];
            fn mac(acc: &mut [f64; 2], f: [f64; 2], v: [f64; 2]) {
                acc[0] += f[0] * v[0];
                acc[1] += f[1] * v[1];
            }
            for c in &kernel.cells {
                let f = c.factors;
                let (w, a, b) = ([f[0], f[1]], [f[4], f[5]], [f[8], f[9]]);
                let [p, e, x] = cells[c.d];
                mac(&mut acc[0], w, p);
                mac(&mut acc[1], w, e);
                mac(&mut acc[2], w, x);
                mac(&mut acc[3], a, p);
                mac(&mut acc[4], b, p);
                mac(&mut acc[5], a, e);
                mac(&mut acc[6], b, e);
            }
            acc
        }
        let curves = atlas();
        let mut rng = crate::cases::SplitMix64(43);
        let mut tried = 0;
        for g in linkage_groups(&curves) {
            let c = &curves[g.start].curve;
            let table = Table::new(&c.linkage, c.circuit).unwrap();
            let grid = Grid::new(&table);
            for _ in 0..20 {
                let (offsets, y) = random_kernel_target(&mut rng, false);
                let kernel = Kernel::new(&offsets, &y);
                for c in &kernel.cells {
                    let f = c.factors;
                    let same =
                        |i: &[usize], j: usize| i.iter().all(|&i| f[i].to_bits() == f[j].to_bits());
                    assert!(same(&[1, 2, 3, 12, 13], 0));
                    assert!(same(&[5, 6, 7], 4));
                    assert!(same(&[9, 10, 11], 8));
                    assert_eq!([f[14], f[15]], [0.0, 0.0]);
                }
                for start in (-400..800).step_by(29) {
                    let base = (start + kernel.lo).rem_euclid(grid.period as i64) as usize;
                    let want = first_written(&kernel, &grid, start);
                    let bits = |a: [[f64; 2]; 7]| a.map(|p| p.map(f64::to_bits));
                    let flat = Kernel::flat_sums(&kernel.cells, &grid.cells[base..]);
                    assert_eq!(bits(flat), bits(want));
                    #[cfg(target_arch = "x86_64")]
                    if crate::has_avx2() {
                        // SAFETY: the processor was just found to have AVX2.
                        #[allow(unsafe_code)]
                        let flat =
                            unsafe { Kernel::flat_sums_avx2(&kernel.cells, &grid.cells[base..]) };
                        assert_eq!(bits(flat), bits(want));
                    }
                    tried += 1;
                }
            }
        }
        assert!(tried > 2000, "{tried}");
    }

    /// With reflection allowed, the unreflected candidates are exactly, in order, those
    /// proposed without it, and as many reflected ones come with them (issue 13: they
    /// shared the per-point window lists and the cuts, so reflected windows pushed the
    /// source's own out). Eight candidates kept, so the cut of stage 2 bites.
    #[test]
    fn reflection_only_adds_candidates() {
        let curves = atlas();
        let groups = linkage_groups(&curves);
        for case in retrieval_cases(&curves, false, 13, 6) {
            let plain = OpenQuery::new(&case.target, false).unwrap();
            let both = OpenQuery::new(&case.target, true).unwrap();
            let p = open_candidates(&plain, &curves, &groups, 8);
            let b = open_candidates(&both, &curves, &groups, 8);
            let unreflected: Vec<_> = b.iter().filter(|c| !c.start.mirrored).map(bits).collect();
            let ids = |v: &[(u64, u64, bool, Vec<u64>)]| v.iter().map(|c| c.0).collect::<Vec<_>>();
            let want: Vec<_> = p.iter().map(bits).collect();
            assert_eq!(ids(&unreflected), ids(&want), "source {}", case.source);
            assert!(
                unreflected == want,
                "source {}: the same curves, other bits",
                case.source
            );
            assert_eq!(b.len() - unreflected.len(), p.len());
        }
    }

    /// Stage 1 on the processor's fastest path ([`linkage_stage1`]: AVX2 where the
    /// processor has it) gives the same windows as on the baseline path, bit for bit
    /// (misfit, start, span, sense, reflection and every angle), over every linkage of
    /// the test atlas and several targets, both reflections.
    #[test]
    fn stage1_is_the_same_on_every_path() {
        let curves = atlas();
        let groups = linkage_groups(&curves);
        let key = |s: &Stage1| {
            let h = &s.hyp;
            let mut v = vec![
                s.index as u64,
                s.group as u64,
                u64::from(h.mirror),
                h.misfit.to_bits(),
                h.start.to_bits(),
                h.span.to_bits(),
                h.sense.to_bits(),
            ];
            v.extend(h.theta.iter().map(|t| t.to_bits()));
            v
        };
        let mut kept = 0;
        for case in retrieval_cases(&curves, false, 31, 4) {
            let q = OpenQuery::new(&case.target, true).unwrap();
            let (mut fast, mut base) = (Vec::new(), Vec::new());
            let (mut b1, mut b2) = (Projection::default(), Projection::default());
            for g in &groups {
                let c = &curves[g.start].curve;
                // With its ring, as the scan lays it out (the baseline path reads none).
                let Some(table) = Table::new(&c.linkage, c.circuit).map(Table::with_ring) else {
                    continue;
                };
                let pts: Vec<C64> = g.clone().map(|k| w_of(&curves[k])).collect();
                let passes = q.passes(table.period);
                linkage_stage1(&q, &passes, &table, &pts, g.start, &mut b1, &mut fast);
                linkage_stage1_body::<false>(
                    &q, &passes, &table, &pts, g.start, &mut b2, &mut base,
                );
            }
            assert_eq!(fast.len(), base.len());
            for (a, b) in fast.iter().zip(&base) {
                assert_eq!(key(a), key(b));
            }
            kept += fast.len();
        }
        // Not vacuous: every curve has a window of each reflection.
        assert!(kept >= 8 * curves.len(), "{kept} of {}", curves.len());
    }

    /// Stage 2's re-estimation on the processor's fastest path ([`OpenQuery::polish`]:
    /// AVX2 where the processor has it) gives the same hypothesis as on the baseline path,
    /// bit for bit (misfit and every angle), for every curve stage 1 keeps on the test
    /// atlas, several targets, both reflections.
    #[test]
    fn polish_is_the_same_on_every_path() {
        let curves = atlas();
        let groups = linkage_groups(&curves);
        let (mut dp1, mut dp2) = (Programme::default(), Programme::default());
        let mut moved = 0;
        let mut tried = 0;
        for case in retrieval_cases(&curves, false, 37, 3) {
            let q = OpenQuery::new(&case.target, true).unwrap();
            for s in open_stage1(&q, &curves, &groups, 64) {
                let c = &curves[s.index].curve;
                let table = Table::new(&c.linkage, c.circuit).unwrap();
                let w = w_of(&curves[s.index]);
                let fast = q.polish(&table, w, &s.hyp, &mut dp1);
                let base = q.polish_body(&table, w, &s.hyp, &mut dp2);
                assert_eq!(fast.misfit.to_bits(), base.misfit.to_bits());
                let bits = |h: &Hypothesis| h.theta.iter().map(|t| t.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&fast), bits(&base));
                moved += usize::from(bits(&fast) != bits(&s.hyp));
                tried += 1;
            }
        }
        // Not vacuous: many curves, a good part of them re-estimated (468 of 960 with the
        // 4.5° start step; 485 with 3°).
        assert!(tried > 300 && 3 * moved > tried, "{moved} of {tried} moved");
    }

    /// The staged projection's premise: `PROJECTION_HEAT` steps resumed with the rest
    /// take the same steps as one run of `PROJECTIONS`, bit for bit (misfit and every
    /// angle), for every window the scan proposes on several linkages, both reflections.
    #[test]
    fn a_resumed_projection_is_one_run() {
        let curves = atlas();
        let groups = linkage_groups(&curves);
        let mut buf = Projection::default();
        let mut windows = 0;
        let mut moved = 0;
        for case in retrieval_cases(&curves, false, 29, 3) {
            let q = OpenQuery::new(&case.target, true).unwrap();
            for g in groups.iter().step_by(7) {
                let c = &curves[g.start].curve;
                let Some(table) = Table::new(&c.linkage, c.circuit) else {
                    continue;
                };
                let pts: Vec<C64> = g.clone().map(|k| w_of(&curves[k])).collect();
                for (k, hs) in q.scan(&table, &pts).into_iter().enumerate() {
                    for h in hs {
                        let (mut one, mut staged) = (h.clone(), h.clone());
                        q.project::<false>(&table, pts[k], &mut one, &mut buf, PROJECTIONS);
                        if !q.project::<false>(
                            &table,
                            pts[k],
                            &mut staged,
                            &mut buf,
                            PROJECTION_HEAT,
                        ) {
                            q.project::<false>(
                                &table,
                                pts[k],
                                &mut staged,
                                &mut buf,
                                PROJECTIONS - PROJECTION_HEAT,
                            );
                        }
                        let angles = |h: &Hypothesis| -> Vec<u64> {
                            h.theta.iter().map(|t| t.to_bits()).collect()
                        };
                        assert_eq!(one.misfit.to_bits(), staged.misfit.to_bits());
                        assert_eq!(angles(&one), angles(&staged));
                        windows += 1;
                        moved += usize::from(angles(&one) != angles(&h));
                    }
                }
            }
        }
        // Not vacuous: many windows, and most of them moved by the projection.
        assert!(
            windows > 100 && 2 * moved > windows,
            "{windows} windows, {moved} moved"
        );
    }
}

#[cfg(test)]
mod lab {
    //! Where the open scan loses the source (ignored; run with
    //! `cargo test --release -p coupler-shape open_stages -- --ignored --nocapture`).
    use super::*;
    use crate::cases::{SplitMix64 as Rng, crank_angles};
    use crate::fit::{FitOptions, fit_untimed};
    use coupler_kinematics::FourBar;

    fn atlas() -> Vec<AtlasCurve> {
        let mut out = Vec::new();
        let vals: Vec<f64> = (0..7).map(|k| 1.5 + 0.5 * k as f64).collect();
        for &a in &vals {
            for &b in &vals {
                for &c in &vals {
                    let Ok(l) = FourBar::new(a, b, c) else {
                        continue;
                    };
                    if !l.is_crank_rocker() {
                        continue;
                    }
                    super::mirror::push_grid(l, &mut out);
                }
            }
        }
        out
    }

    #[test]
    #[ignore]
    fn open_stages() {
        let curves = atlas();
        println!("{} curves", curves.len());
        let mut rng = Rng(99);
        let mut ranks = Vec::new();
        for case in 0..60 {
            let src = (rng.next_u64() % curves.len() as u64) as usize;
            let c = curves[src].curve;
            let start = 360.0 * rng.uniform();
            let span = 90.0 + 180.0 * rng.uniform();
            let n = 20 + (rng.next_u64() % 81) as usize;
            let ang = crank_angles(&mut rng, false, start, span, n);
            let mir = rng.uniform() < 0.5;
            let mut z: Vec<C64> = ang
                .iter()
                .map(|&t| {
                    let m = c.at(t).unwrap().m;
                    if mir { m.conj() } else { m }
                })
                .collect();
            let size = crate::geom::diameter(&z);
            for p in &mut z {
                *p +=
                    C64::new(rng.normal(), rng.normal()) * (0.01 * size / std::f64::consts::SQRT_2);
            }
            let t = Target::new(
                z.iter().map(|p| [p.re, p.im]).collect(),
                false,
                Timing::Untimed,
            )
            .unwrap();
            let q = OpenQuery::new(&t, true).unwrap();
            let cands = open_candidates(&q, &curves, &linkage_groups(&curves), 100000);
            let pos = cands.iter().position(|x| x.curve.id == src as u64);
            let p = t.complex_points();
            let from_start = pos
                .and_then(|i| fit_untimed(&p, &c, &cands[i].start, &FitOptions::DEFAULT))
                .map(|f| 100.0 * f.rms / size);
            let own_fit =
                crate::fit::fit_curve(&t, &c, &FitOptions::DEFAULT).map(|f| 100.0 * f.rms / size);
            let own = own_fit.unwrap();
            let quick = FitOptions {
                max_iterations: crate::matching::RANK_ITERATIONS_OPEN,
                ..FitOptions::DEFAULT
            };
            let fits: Vec<f64> = cands
                .iter()
                .take(256)
                .map(|x| {
                    fit_untimed(&p, &x.curve.curve, &x.start, &quick)
                        .map_or(f64::INFINITY, |f| 100.0 * f.rms / size)
                })
                .collect();
            let first_ok = fits.iter().position(|&f| f <= own * 1.0000001);
            let best = fits.iter().copied().fold(f64::INFINITY, f64::min);
            println!(
                "case {case}: span {span:.0} n {n} mir {mir}: src pos {pos:?}; from start {from_start:?} own {own:.3}; first ok cand {first_ok:?} best of 256 {best:.3}",
            );
            // (coarse rank of the source, rank of the first quick fit as close as it)
            ranks.push((pos.unwrap_or(9999), first_ok.unwrap_or(9999)));
        }
        ranks.sort();
        println!("(coarse rank, first as close) per case: {ranks:?}");
    }
}

#[cfg(test)]
mod stage_times {
    //! Where an open query's time goes, stage by stage, on an atlas on disk (ignored; run
    //! with `OPEN_ATLAS=/tmp/hn OPEN_TARGET=cheb.csv cargo test --release -p coupler-shape
    //! open_stage_times -- --ignored --nocapture`). One thread; each stage's least time
    //! over the repetitions (`OPEN_REPS`, default 5), so that other work on the machine
    //! weighs little.
    use super::*;
    use crate::fit::{FitOptions, fit_untimed, fit_with};
    use std::time::Instant;

    fn least(reps: usize, f: &mut dyn FnMut()) -> f64 {
        (0..reps)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64() * 1e3
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    #[ignore]
    fn open_stage_times() {
        let dir = std::env::var("OPEN_ATLAS").expect("OPEN_ATLAS");
        let csv = std::env::var("OPEN_TARGET").expect("OPEN_TARGET");
        let reps: usize = std::env::var("OPEN_REPS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(5);
        let bytes = std::fs::read(format!("{dir}/shapes.bin")).unwrap();
        let atlas = crate::decode_sidecar(&bytes).unwrap();
        let pts: Vec<[f64; 2]> = std::fs::read_to_string(&csv)
            .unwrap()
            .lines()
            .filter_map(|l| {
                let mut it = l.split(',').map(|s| s.trim().parse::<f64>());
                Some([it.next()?.ok()?, it.next()?.ok()?])
            })
            .collect();
        let t = Target::new(pts, false, Timing::Untimed).unwrap();
        // As `match` without `--mirror` (OPEN_MIRROR=1: with it).
        let mirror = std::env::var("OPEN_MIRROR").is_ok();
        let keep = 1024;
        let curves = &atlas.curves;
        let groups = linkage_groups(curves);
        let q = OpenQuery::new(&t, mirror).unwrap();
        let tables: Vec<(Table, Vec<C64>)> = groups
            .iter()
            .map(|g| {
                let c = &curves[g.start].curve;
                let table = Table::new(&c.linkage, c.circuit).unwrap();
                (table, g.clone().map(|k| w_of(&curves[k])).collect())
            })
            .collect();
        // OPEN_STAGES=scan,one,stage1,stage2,quick,robust: only those (e.g. to count
        // instructions of one stage under callgrind).
        let stages = std::env::var("OPEN_STAGES")
            .unwrap_or_else(|_| "scan,one,stage1,stage2,quick,robust".into());
        let on = |name: &str| stages.split(',').any(|s| s == name);
        let least = |name: &str, reps: usize, f: &mut dyn FnMut()| {
            if on(name) { least(reps, f) } else { f64::NAN }
        };
        // The scan on the path the query takes ([`OpenQuery::scan`]: AVX2 where the
        // processor has it), the passes made per linkage.
        let scan = least("scan", reps, &mut || {
            for (table, pts) in &tables {
                std::hint::black_box(q.scan(table, pts));
            }
        });
        let one = least("one", reps, &mut || {
            for (table, pts) in &tables {
                std::hint::black_box(q.scan(table, &pts[..1]));
            }
        });
        let stage1 = least("stage1", reps, &mut || {
            std::hint::black_box(open_stage1(&q, curves, &groups, keep));
        });
        if !(on("stage2") || on("quick") || on("robust")) {
            println!(
                "least of {reps}: scan {scan:.1} ms (one point per linkage {one:.1} ms), stage 1 with projection {stage1:.1} ms"
            );
            return;
        }
        let s1 = open_stage1(&q, curves, &groups, keep);
        let stage2 = least("stage2", reps, &mut || {
            std::hint::black_box(open_stage2(&q, curves, s1.clone(), keep));
        });
        let cands = open_stage2(&q, curves, s1.clone(), keep);
        let p = t.complex_points();
        let full = FitOptions {
            allow_mirror: mirror,
            ..FitOptions::DEFAULT
        };
        let quick = FitOptions {
            max_iterations: crate::matching::RANK_ITERATIONS_OPEN,
            ..full
        };
        let quick_fits = least("quick", reps.min(3), &mut || {
            for c in &cands {
                std::hint::black_box(fit_untimed(&p, &c.curve.curve, &c.start, &quick));
            }
        });
        let robust = least("robust", reps.min(3), &mut || {
            for c in cands.iter().take(64) {
                let traced = crate::traced::Traced::new(&c.curve.curve, 720).unwrap();
                std::hint::black_box(fit_with(&t, &c.curve.curve, &traced, &full));
            }
        });
        println!(
            "least of {reps}: scan {scan:.1} ms (one point per linkage {one:.1} ms), stage 1 with projection {stage1:.1} ms, stage 2 {stage2:.1} ms, {} quick fits {quick_fits:.1} ms, 64 robust starts {robust:.1} ms",
            cands.len()
        );
    }
}

#[cfg(test)]
mod fingerprint {
    //! The open coarse stage's candidates, hashed bit for bit, on the first retrieval cases
    //! of an atlas on disk (ignored; a lab check that a faster scan proposes exactly the
    //! same candidates: `OPEN_ATLAS=/tmp/hn cargo test --release -p coupler-shape
    //! open_candidates_fingerprint -- --ignored --nocapture`).
    use super::*;
    use crate::cases::retrieval_cases;
    use std::hash::{Hash, Hasher};

    /// The lab tests' atlas (`OPEN_ATLAS`, a folder made by `generate`) and number of
    /// cases (`OPEN_CASES`, else `default`).
    pub(super) fn lab_atlas(default: usize) -> (crate::ShapeAtlas, usize) {
        let dir = std::env::var("OPEN_ATLAS").expect("OPEN_ATLAS");
        let count = std::env::var("OPEN_CASES")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(default);
        let bytes = std::fs::read(format!("{dir}/shapes.bin")).unwrap();
        (crate::decode_sidecar(&bytes).unwrap(), count)
    }

    #[test]
    #[ignore]
    fn open_candidates_fingerprint() {
        let (atlas, count) = lab_atlas(12);
        let curves = &atlas.curves;
        let groups = linkage_groups(curves);
        let mut all = std::collections::hash_map::DefaultHasher::new();
        for (i, case) in retrieval_cases(curves, false, 77, count).iter().enumerate() {
            for mirror in [true, false] {
                let q = OpenQuery::new(&case.target, mirror).unwrap();
                let c = open_candidates(&q, curves, &groups, 1024);
                let mut h = std::collections::hash_map::DefaultHasher::new();
                for x in &c {
                    x.curve.id.hash(&mut h);
                    x.misfit.to_bits().hash(&mut h);
                    x.start.mirrored.hash(&mut h);
                    for t in &x.start.theta {
                        t.to_bits().hash(&mut h);
                    }
                }
                let v = h.finish();
                v.hash(&mut all);
                println!("case {i} mirror {mirror}: {} candidates, {v:016x}", c.len());
            }
        }
        println!("all: {:016x}", all.finish());
    }
}

#[cfg(test)]
mod fits_fingerprint {
    //! The open exact stage's fits, hashed bit for bit (ignored; a lab check that a
    //! cheaper fit computes exactly the same values: `OPEN_ATLAS=/tmp/hn cargo test
    //! --release -p coupler-shape open_fits_fingerprint -- --ignored --nocapture`). For the
    //! first `OPEN_CASES` (default 3) open retrieval cases, both reflections: every
    //! candidate's quick fit (30 iterations from its scan start), the exact fit's robust
    //! start (window scan, race, final fits) of the best 64, and the ranked matches.
    use super::fingerprint::lab_atlas;
    use super::*;
    use crate::cases::retrieval_cases;
    use crate::fit::{CurveFit, FitOptions, fit_untimed, fit_with};
    use crate::matching::{MatchOptions, find_matches};
    use std::hash::{Hash, Hasher};

    fn hash_fit(f: &Option<CurveFit>, h: &mut impl Hasher) {
        let Some(f) = f else {
            0u8.hash(h);
            return;
        };
        f.mirrored.hash(h);
        for x in f.a.iter().chain(&f.b).chain(&f.theta_deg) {
            x.to_bits().hash(h);
        }
        f.rms.to_bits().hash(h);
        f.max.to_bits().hash(h);
    }

    #[test]
    #[ignore]
    fn open_fits_fingerprint() {
        let (atlas, count) = lab_atlas(3);
        let curves = &atlas.curves;
        let groups = linkage_groups(curves);
        let mut all = std::collections::hash_map::DefaultHasher::new();
        for (i, case) in retrieval_cases(curves, false, 77, count).iter().enumerate() {
            let t = &case.target;
            let p = t.complex_points();
            for mirror in [true, false] {
                let q = OpenQuery::new(t, mirror).unwrap();
                let c = open_candidates(&q, curves, &groups, 1024);
                let full = FitOptions {
                    allow_mirror: mirror,
                    ..FitOptions::DEFAULT
                };
                let quick = FitOptions {
                    max_iterations: crate::matching::RANK_ITERATIONS_OPEN,
                    ..full
                };
                let mut hq = std::collections::hash_map::DefaultHasher::new();
                for x in &c {
                    hash_fit(&fit_untimed(&p, &x.curve.curve, &x.start, &quick), &mut hq);
                }
                let mut hr = std::collections::hash_map::DefaultHasher::new();
                for x in c.iter().take(64) {
                    let traced = crate::traced::Traced::new(&x.curve.curve, 720);
                    let f = traced.and_then(|tr| fit_with(t, &x.curve.curve, &tr, &full));
                    hash_fit(&f, &mut hr);
                }
                let options = MatchOptions {
                    allow_mirror: mirror,
                    ..MatchOptions::DEFAULT
                };
                let mut hm = std::collections::hash_map::DefaultHasher::new();
                for m in find_matches(t, curves, &[], &options).unwrap() {
                    m.id.hash(&mut hm);
                    hash_fit(&Some(m.fit), &mut hm);
                }
                let (a, b, d) = (hq.finish(), hr.finish(), hm.finish());
                (a, b, d).hash(&mut all);
                println!(
                    "case {i} mirror {mirror}: quick {a:016x} robust {b:016x} matches {d:016x}"
                );
            }
        }
        println!("all: {:016x}", all.finish());
    }
}

#[cfg(test)]
mod window_lab {
    //! Which of a curve's stage-1 windows wins after the projection (ignored; a lab
    //! measurement: `OPEN_ATLAS=<atlas> cargo test --release -p coupler-shape
    //! window_choice -- --ignored --nocapture`).
    use super::fingerprint::lab_atlas;
    use super::*;
    use crate::cases::retrieval_cases;

    #[test]
    #[ignore]
    fn window_choice() {
        let (atlas, count) = lab_atlas(40);
        let curves = &atlas.curves;
        let groups = linkage_groups(curves);
        // Per case: (curve index, reflection, best pre misfit, chosen window's rank, its pre
        // misfit, post misfit).
        let mut src_rows = Vec::new();
        let mut top_rows = Vec::new();
        for case in retrieval_cases(curves, false, 77, count) {
            let q = OpenQuery::new(&case.target, true).unwrap();
            let mut rows = Vec::new();
            let mut buf = Projection::default();
            for g in &groups {
                let c = &curves[g.start].curve;
                let table = Table::new(&c.linkage, c.circuit).unwrap();
                let pts: Vec<C64> = g.clone().map(|k| w_of(&curves[k])).collect();
                for (k, hs) in q.scan(&table, &pts).into_iter().enumerate() {
                    let mut hs = hs;
                    let pre: Vec<f64> = hs.iter().map(|h| h.misfit).collect();
                    let mut settled = Vec::new();
                    for h in hs.iter_mut() {
                        settled.push(q.project::<false>(
                            &table,
                            pts[k],
                            h,
                            &mut buf,
                            PROJECTION_HEAT,
                        ));
                    }
                    for mirror in [false, true] {
                        let mut order: Vec<usize> =
                            (0..hs.len()).filter(|&i| hs[i].mirror == mirror).collect();
                        order.sort_by(|&a, &b| hs[a].misfit.total_cmp(&hs[b].misfit));
                        for &i in order.iter().take(PROJECTION_KEEP).filter(|&&i| !settled[i]) {
                            q.project::<false>(
                                &table,
                                pts[k],
                                &mut hs[i],
                                &mut buf,
                                PROJECTIONS - PROJECTION_HEAT,
                            );
                        }
                        let idx: Vec<usize> =
                            (0..hs.len()).filter(|&i| hs[i].mirror == mirror).collect();
                        let Some(&best) = idx
                            .iter()
                            .min_by(|&&a, &&b| hs[a].misfit.total_cmp(&hs[b].misfit))
                        else {
                            continue;
                        };
                        let rank = idx.iter().position(|&i| i == best).unwrap();
                        rows.push((
                            g.start + k,
                            mirror,
                            pre[idx[0]],
                            rank,
                            pre[best],
                            hs[best].misfit,
                        ));
                    }
                }
            }
            for mirror in [false, true] {
                let mut r: Vec<_> = rows.iter().filter(|r| r.1 == mirror).cloned().collect();
                r.sort_by(|a, b| a.5.total_cmp(&b.5).then(a.0.cmp(&b.0)));
                // The pre-projection rank of each curve by its best window.
                let mut pre_order: Vec<_> = r.iter().map(|x| (x.2, x.0)).collect();
                pre_order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                let pre_rank = |i: usize| pre_order.iter().position(|x| x.1 == i).unwrap();
                for (pos, x) in r.iter().enumerate() {
                    if x.0 == case.source {
                        src_rows.push((pos, pre_rank(x.0), x.3, x.4 / x.2, x.1));
                    }
                    if pos < 2048 && pos % 64 == 0 {
                        top_rows.push((pos, pre_rank(x.0), x.3, x.4 / x.2));
                    }
                }
            }
        }
        for r in &src_rows {
            println!(
                "source: post rank {} pre rank {} chosen window {} ratio {:.3} mirror {}",
                r.0, r.1, r.2, r.3, r.4
            );
        }
        let mut ratios: Vec<f64> = top_rows.iter().map(|r| r.3).collect();
        ratios.sort_by(f64::total_cmp);
        let q = |f: f64| ratios[((ratios.len() - 1) as f64 * f) as usize];
        let mut pre: Vec<usize> = top_rows.iter().map(|r| r.1).collect();
        pre.sort();
        let qp = |f: f64| pre[((pre.len() - 1) as f64 * f) as usize];
        let mut hist = [0usize; 12];
        for r in &top_rows {
            hist[r.2] += 1;
        }
        println!(
            "top 2048 sample ({}): ratio q50 {:.3} q90 {:.3} q99 {:.3} max {:.3}; pre rank q50 {} q90 {} q99 {} max {}; chosen window {:?}",
            top_rows.len(),
            q(0.5),
            q(0.9),
            q(0.99),
            q(1.0),
            qp(0.5),
            qp(0.9),
            qp(0.99),
            qp(1.0),
            hist
        );
        let mut sr: Vec<f64> = src_rows.iter().map(|r| r.3).collect();
        sr.sort_by(f64::total_cmp);
        let mut sp: Vec<usize> = src_rows.iter().map(|r| r.1).collect();
        sp.sort();
        println!("sources: ratios {sr:?}\npre ranks {sp:?}");
    }
}
