//! Maximal qualifying windows: the one search behind straight segments, pseudo-arcs and
//! the classics' straight runs (`docs/features.md`, "Maximal windows: the contract").
//!
//! A *window* `[i, j]` is a run of consecutive samples (on a periodic track `j` may pass
//! `n`; it never spans the whole turn). Its *travel* is the crank (or input) angle it
//! covers. A feature says which windows *qualify* (exactly, in O(w)) and gives a cheap
//! necessary condition (a *filter*, O(1) per window from sliding fit sums). The windows
//! reported are chosen greedily: the longest qualifying window first (ties: the smaller
//! error, then the earlier start), then the longest qualifying window that shares no step
//! with any chosen one, and so on (windows may share an end sample). So every qualifying
//! window shares at least one step with a reported window at least as long as itself: no
//! qualifying window is longer than, or disjoint from, the reported ones.
//!
//! Every window is considered, not only those a one-sample-at-a-time growth reaches (the
//! error of a window is not monotone in its length). The filter rejects most windows in
//! O(1); the exact test runs on the rest, longest first, and skips windows that overlap
//! a window already chosen. Cost: O(n²) filter evaluations plus O(w) per window tested
//! exactly (measured in `docs/benchmarks.md`, "Features"). A filter may also be run as
//! the choice reaches each length, on the windows it will read only
//! ([`Candidates::pick_filtering`]: the pseudo-arcs' second pass).

/// A chosen window: first and last sample (`end` may pass `n` on a periodic track) and
/// its error (what ties are broken by).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Window {
    pub start: usize,
    pub end: usize,
    pub error: f64,
}

/// Which windows passed the O(1) filter: `pass[l·n + i]` for the window of `l` steps
/// starting at sample `i` (by length, then start: the greedy choice scans one length at a
/// time).
pub(crate) struct Candidates {
    n: usize,
    periodic: bool,
    pass: Vec<bool>,
}

impl Candidates {
    /// No window passes yet. A periodic track of `n` samples has windows of up to `n − 1`
    /// steps from every start; an open one of up to `n − 1 − i` steps from start `i`.
    pub fn new(n: usize, periodic: bool) -> Candidates {
        Candidates {
            n,
            periodic,
            pass: vec![false; n * n],
        }
    }

    /// Longest window from start `i`, in steps.
    pub fn max_steps(&self, i: usize) -> usize {
        if self.periodic {
            self.n.saturating_sub(1)
        } else {
            self.n.saturating_sub(1 + i)
        }
    }

    /// Marks the window of `l` steps from `i` as passing the filter.
    #[cfg(test)]
    pub fn set(&mut self, i: usize, l: usize) {
        self.pass[l * self.n + i] = true;
    }

    /// Whether the window of `l` steps from `i` passed the filter.
    #[cfg(test)]
    pub fn passes(&self, i: usize, l: usize) -> bool {
        self.pass[l * self.n + i]
    }

    /// Whether each window of `l` steps passes, by start (`n` entries; windows longer
    /// than [`Candidates::max_steps`] are never tested, whatever their entry says).
    #[inline]
    pub fn row_mut(&mut self, l: usize) -> &mut [bool] {
        &mut self.pass[l * self.n..(l + 1) * self.n]
    }

    /// The greedy choice above. `travel(i, j)` is the window's travel and `h_max` the
    /// largest travel of one step (so a window of `l` steps travels at most `l·h_max`);
    /// windows travelling less than `min_travel` never qualify; at most `max_picks`
    /// windows are chosen. `exact(i, j)` is the window's error if it qualifies.
    /// Returns the chosen windows by start.
    pub fn pick(
        &self,
        travel: impl Fn(usize, usize) -> f64,
        h_max: f64,
        min_travel: f64,
        max_picks: usize,
        exact: impl FnMut(usize, usize) -> Option<f64>,
    ) -> Vec<Window> {
        self.choose(
            Rows::Filled(&self.pass),
            travel,
            h_max,
            min_travel,
            max_picks,
            exact,
        )
    }

    /// [`Candidates::pick`] with each length's filter run as the greedy choice reaches
    /// it, and only on the windows it then reads: `fill(l, lo, flags)` sets the flags of
    /// the windows of `l` steps from starts `lo, lo + 1, …` (one call per run of starts
    /// whose window shares no step with a window chosen so far). The windows it skips
    /// are those the choice would skip unread, so the same windows are chosen as by
    /// `pick` after the filter has set every window's flag.
    pub fn pick_filtering(
        &mut self,
        fill: &mut dyn FnMut(usize, usize, &mut [bool]),
        travel: impl Fn(usize, usize) -> f64,
        h_max: f64,
        min_travel: f64,
        max_picks: usize,
        exact: impl FnMut(usize, usize) -> Option<f64>,
    ) -> Vec<Window> {
        let mut pass = std::mem::take(&mut self.pass);
        let picked = self.choose(
            Rows::Lazy(&mut pass, fill),
            travel,
            h_max,
            min_travel,
            max_picks,
            exact,
        );
        self.pass = pass;
        picked
    }

    /// The greedy choice of [`Candidates::pick`], its rows of flags as `rows` gives them.
    fn choose(
        &self,
        mut rows: Rows<'_>,
        travel: impl Fn(usize, usize) -> f64,
        h_max: f64,
        min_travel: f64,
        max_picks: usize,
        mut exact: impl FnMut(usize, usize) -> Option<f64>,
    ) -> Vec<Window> {
        let n = self.n;
        let edges = if self.periodic {
            n
        } else {
            n.saturating_sub(1)
        };
        let mut picked: Vec<Window> = Vec::new();
        if n < 3 || max_picks == 0 {
            return picked;
        }
        // used[k]: step k (samples k, k+1) belongs to a chosen window; `count` is the
        // prefix count over the steps taken twice round (periodic windows wrap).
        let mut used = vec![false; edges];
        let mut count = vec![0u32; 2 * edges + 1];
        let overlaps = |count: &[u32], i: usize, j: usize| count[j] > count[i];
        // Qualifying windows not yet chosen: (travel, error, start, end).
        let mut pending: Vec<(f64, f64, usize, usize)> = Vec::new();
        let finalize = |pending: &mut Vec<(f64, f64, usize, usize)>,
                        picked: &mut Vec<Window>,
                        used: &mut Vec<bool>,
                        count: &mut Vec<u32>,
                        bound: f64| {
            if pending.is_empty() {
                // (Most lengths: nothing to choose.)
                return;
            }
            // Windows travelling more than `bound` cannot be beaten or tied by a window
            // still to be tested: choose among them, longest first.
            pending.sort_by(|a, b| {
                b.0.total_cmp(&a.0)
                    .then(a.1.total_cmp(&b.1))
                    .then(a.2.cmp(&b.2))
            });
            let ready = pending.iter().take_while(|w| w.0 > bound).count();
            for &(_, error, i, j) in &pending[..ready] {
                if picked.len() >= max_picks || overlaps(count, i, j) {
                    continue;
                }
                picked.push(Window {
                    start: i,
                    end: j,
                    error,
                });
                // (`i < edges` and `j < 2·edges`: no modulo, whose division was most of
                // this loop's time.)
                for k in i..j {
                    used[if k < edges { k } else { k - edges }] = true;
                }
                let mut run = 0;
                for (c, &u) in count[1..].iter_mut().zip(used.iter().chain(used.iter())) {
                    run += u32::from(u);
                    *c = run;
                }
            }
            pending.drain(..ready);
        };
        let longest = (0..n).map(|i| self.max_steps(i)).max().unwrap_or(0);
        for l in (2..=longest).rev() {
            finalize(
                &mut pending,
                &mut picked,
                &mut used,
                &mut count,
                l as f64 * h_max,
            );
            if picked.len() >= max_picks {
                break;
            }
            let row: &[bool] = match &mut rows {
                Rows::Filled(pass) => &pass[l * n..(l + 1) * n],
                Rows::Lazy(pass, fill) => {
                    let row = &mut pass[l * n..(l + 1) * n];
                    // The starts whose window may be read below: not past the track's
                    // end, sharing no step with a chosen window (`overlaps`).
                    let starts = if self.periodic {
                        n
                    } else {
                        n.saturating_sub(l)
                    };
                    if count[count.len() - 1] == 0 {
                        // (Nothing chosen yet: every start.)
                        fill(l, 0, &mut row[..starts]);
                    } else {
                        let mut i = 0;
                        while i < starts {
                            while i < starts && overlaps(&count, i, i + l) {
                                i += 1;
                            }
                            let lo = i;
                            while i < starts && !overlaps(&count, i, i + l) {
                                i += 1;
                            }
                            if lo < i {
                                fill(l, lo, &mut row[lo..i]);
                            }
                        }
                    }
                    row
                }
            };
            for i in set_bits(row) {
                if l > self.max_steps(i) {
                    continue;
                }
                let j = i + l;
                if overlaps(&count, i, j) {
                    continue;
                }
                let t = travel(i, j);
                if t < min_travel {
                    continue;
                }
                if let Some(e) = exact(i, j) {
                    pending.push((t, e, i, j));
                }
            }
        }
        finalize(
            &mut pending,
            &mut picked,
            &mut used,
            &mut count,
            f64::NEG_INFINITY,
        );
        picked.sort_by_key(|w| w.start);
        picked
    }
}

/// Where [`Candidates::choose`] reads each length's flags from: all set beforehand, or
/// set as it reaches each length (every flag starts `false`), by `fill`.
enum Rows<'a> {
    Filled(&'a [bool]),
    Lazy(&'a mut [bool], &'a mut dyn FnMut(usize, usize, &mut [bool])),
}

/// The positions of the `true` entries of `flags`, ascending. Read 64 flags at a time
/// into a mask without a branch per flag, then one step per `true` flag: the passing
/// windows of a row follow no pattern a branch predictor learns, and a branch per flag
/// cost more than the scan itself (measured in `docs/benchmarks.md`).
#[inline]
pub(crate) fn set_bits(flags: &[bool]) -> impl Iterator<Item = usize> + '_ {
    flags.chunks(64).enumerate().flat_map(|(w, chunk)| {
        // Eight flags (bytes 0 or 1) at a time: the product gathers byte k's low bit into
        // bit 56 + k (no carries: every partial product lands in its own bit).
        let mut mask = 0u64;
        for (q, eight) in chunk.chunks(8).enumerate() {
            // A full eight as one 8-byte load (copying the bytes into an array first made
            // the load wait for eight byte stores: a store-forwarding stall per word).
            let bytes = match <&[bool; 8]>::try_from(eight) {
                Ok(full) => full.map(u8::from),
                Err(_) => {
                    let mut bytes = [0u8; 8];
                    for (b, &f) in bytes.iter_mut().zip(eight) {
                        *b = u8::from(f);
                    }
                    bytes
                }
            };
            let packed = u64::from_le_bytes(bytes).wrapping_mul(0x0102_0408_1020_4080) >> 56;
            mask |= packed << (8 * q);
        }
        std::iter::from_fn(move || {
            (mask != 0).then(|| {
                let k = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                64 * w + k
            })
        })
    })
}

/// Tracks whether a growing set of directions lies in an open half-plane (a point moving
/// one way along some line has all its velocities, or all its steps, there). The first
/// direction added is the reference; the others are kept as angles from it in (−π, π];
/// the set fits in an open half-plane iff their range is below π. Once it fails, every
/// larger set fails too. (The straight filter makes this test lane by lane,
/// `straight::grow`; this form is its one-start reference in the tests.)
#[derive(Clone, Copy, Debug)]
#[cfg(test)]
pub(crate) struct HalfPlane {
    reference: Option<f64>,
    lo: f64,
    hi: f64,
}

#[cfg(test)]
impl HalfPlane {
    pub fn new() -> HalfPlane {
        HalfPlane {
            reference: None,
            lo: 0.0,
            hi: 0.0,
        }
    }

    /// Adds a direction given by its angle (radians, from `atan2`). Returns whether the
    /// set still fits in an open half-plane.
    #[inline]
    pub fn add(&mut self, angle: f64) -> bool {
        match self.reference {
            None => {
                self.reference = Some(angle);
                true
            }
            Some(r) => {
                let d = wrap_pi(angle - r);
                self.lo = self.lo.min(d);
                self.hi = self.hi.max(d);
                self.hi - self.lo < std::f64::consts::PI
            }
        }
    }
}

/// An angle wrapped into (−π, π].
#[cfg(test)]
#[inline]
pub(crate) fn wrap_pi(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if a > PI {
        a - TAU
    } else if a <= -PI {
        a + TAU
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Windows qualify when they lie inside [2, 9] or [12, 15] of an open track of 20
    /// samples: the greedy choice takes both, longest first; a second pick inside a
    /// chosen window is refused.
    #[test]
    fn greedy_longest_first_without_overlap() {
        let mut c = Candidates::new(20, false);
        for i in 0..20 {
            for l in 2..=c.max_steps(i) {
                c.set(i, l);
            }
        }
        let ok = |i: usize, j: usize| (2..=9).contains(&i) && j <= 9 || i >= 12 && j <= 15;
        let w = c.pick(
            |i, j| (j - i) as f64,
            1.0,
            0.0,
            10,
            |i, j| ok(i, j).then_some(0.0),
        );
        let got: Vec<(usize, usize)> = w.iter().map(|w| (w.start, w.end)).collect();
        assert_eq!(got, vec![(2, 9), (12, 15)]);
        // Ties go to the smaller error, then the earlier start; overlapping ties lose,
        // windows sharing an end sample do not overlap.
        let w = c.pick(
            |i, j| (j - i) as f64,
            1.0,
            0.0,
            10,
            |i, j| (j - i == 4 && i < 6).then_some(if i == 1 { 0.1 } else { 0.2 }),
        );
        let got: Vec<(usize, usize)> = w.iter().map(|w| (w.start, w.end)).collect();
        assert_eq!(got, vec![(1, 5), (5, 9)]);
    }

    /// On a periodic track a window may wrap past the last sample.
    #[test]
    fn periodic_windows_wrap() {
        let mut c = Candidates::new(10, true);
        for i in 0..10 {
            for l in 2..=c.max_steps(i) {
                c.set(i, l);
            }
        }
        // Qualifies when it stays within samples 8, 9, 0, 1, 2 (unwrapped 8..=12).
        let w = c.pick(
            |i, j| (j - i) as f64,
            1.0,
            0.0,
            10,
            |i, j| (i >= 8 && j <= 12).then_some(0.0),
        );
        assert_eq!((w[0].start, w[0].end), (8, 12));
        assert_eq!(w.len(), 1);
    }

    /// Unequal steps: the longest window by travel wins, even with fewer samples.
    #[test]
    fn longest_by_travel() {
        let travel = [0.0, 1.0, 2.0, 3.0, 10.0, 11.0, 12.0];
        let mut c = Candidates::new(7, false);
        for i in 0..7 {
            for l in 2..=c.max_steps(i) {
                c.set(i, l);
            }
        }
        let w = c.pick(
            |i, j| travel[j] - travel[i],
            7.0,
            0.0,
            1,
            |i, j| ((i == 0 && j == 3) || (i == 2 && j == 4)).then_some(0.0),
        );
        assert_eq!((w[0].start, w[0].end), (2, 4));
    }

    #[test]
    fn set_bits_lists_the_true_flags() {
        for n in [0, 1, 7, 8, 9, 63, 64, 65, 72, 130] {
            let flags: Vec<bool> = (0..n).map(|k| (k * 7 + k / 3) % 5 < 2).collect();
            let want: Vec<usize> = (0..n).filter(|&k| flags[k]).collect();
            assert_eq!(set_bits(&flags).collect::<Vec<_>>(), want, "{n}");
        }
        assert_eq!(set_bits(&[true; 70]).count(), 70);
        // Every pattern of eight flags.
        for m in 0..256usize {
            let flags: Vec<bool> = (0..8).map(|k| m >> k & 1 == 1).collect();
            let want: Vec<usize> = (0..8).filter(|&k| flags[k]).collect();
            assert_eq!(set_bits(&flags).collect::<Vec<_>>(), want, "{m:08b}");
        }
    }

    #[test]
    fn half_plane() {
        let mut h = HalfPlane::new();
        assert!(h.add(3.0));
        assert!(h.add(3.0 + 1.5));
        assert!(h.add(3.0 - 1.5));
        assert!(!h.add(3.0 + 1.7));
        let mut h = HalfPlane::new();
        assert!(h.add(-3.1));
        assert!(h.add(3.1)); // 0.08 rad apart across ±π
    }
}
