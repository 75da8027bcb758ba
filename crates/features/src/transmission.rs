//! The transmission angle over a feature's window: what the mechanism's force
//! transmission is while the coupler point runs along a straight segment or a pseudo-arc
//! (a designer's question before the whole turn's range: a dwell or a straight-line
//! stroke is used over its window only).

use coupler_kinematics::{Circuit, CrankAngle, Mechanism};
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// `[min, max]` of the transmission angle μ (degrees) over the input window
/// `[start_deg, start_deg + span_deg]` on `circuit`, or `None` where the mechanism does
/// not assemble somewhere in it.
///
/// μ is evaluated at both ends of the window, at every multiple of 180° of input inside
/// it, and every `step_deg` between; each sampled interior extremum (a sample above or
/// below both neighbours) is then refined by golden-section search between its
/// neighbours. For a four-bar this is exact: μ depends on the input only through
/// `d² = 1 + C² − 2C·cos θ`, monotonic between multiples of 180°, so its extremes over any
/// window lie at the window's ends or at θ ≡ 0, 180° (all sampled exactly; no sampled
/// extremum lies elsewhere). For another mechanism (the geared five-bar) it is as good as
/// the step and the refinement (the same method as its whole-turn range).
///
/// ```
/// use coupler_features::window_transmission;
/// use coupler_kinematics::{Circuit, FourBar, Mechanism};
/// let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
/// let whole = l.transmission_range(Circuit::Open).unwrap().map(f64::to_degrees);
/// // A window across θ = 0 reaches the turn's smallest μ; one from 30° to 150° does not.
/// let [lo, _] = window_transmission(&l, Circuit::Open, 330.0, 60.0, 5.0).unwrap();
/// assert_eq!(lo, whole[0]);
/// let [lo, hi] = window_transmission(&l, Circuit::Open, 30.0, 120.0, 5.0).unwrap();
/// assert!(lo > whole[0] && hi < whole[1]);
/// ```
pub fn window_transmission<M: Mechanism>(
    mechanism: &M,
    circuit: Circuit,
    start_deg: f64,
    span_deg: f64,
    step_deg: f64,
) -> Option<[f64; 2]> {
    TransmissionMemo::default().window(mechanism, circuit, start_deg, span_deg, step_deg)
}

/// μ of one mechanism and circuit at the input angles already asked for, and the refined
/// extremes of the brackets already searched, so that the windows of every coupler point
/// of a linkage (an [`crate::FeatureExtractor`]'s) evaluate each input angle once. μ
/// depends on the input angle only, not on the coupler point, and is a pure function of
/// it: a remembered value is the one recomputing would give, to the bit.
#[derive(Clone, Debug, Default)]
pub(crate) struct TransmissionMemo {
    /// μ (radians) by the input angle's bits.
    mu: HashMap<u64, Option<f64>, BitsHash>,
    /// The refined extreme's μ by its bracket's bits and direction.
    peak: HashMap<(u64, u64, bool), Option<f64>, BitsHash>,
}

/// The memo's hasher: its keys are angles' bits, chosen by the program, not by an
/// adversary, so a multiply per word, the high half folded onto the low, does (the
/// default SipHash cost more than the rest of the lookup). Which hasher a map uses
/// changes only where entries sit, never what a lookup returns.
type BitsHash = BuildHasherDefault<WordHasher>;

/// A word-at-a-time multiplicative hash ([`BitsHash`]).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct WordHasher(u64);

impl Hasher for WordHasher {
    fn finish(&self) -> u64 {
        // A product's low bits depend only on its factors' low bits, which are zero for
        // most angles (35.0 has 45 trailing zero bits); the table indexes by the low bits.
        self.0 ^ (self.0 >> 32)
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(5) ^ word).wrapping_mul(0x517c_c1b7_2722_0a95);
    }

    fn write_u8(&mut self, b: u8) {
        self.write_u64(u64::from(b));
    }
}

impl TransmissionMemo {
    /// [`window_transmission`], remembering μ for the next window of the same mechanism
    /// and circuit (the caller keeps those fixed).
    pub(crate) fn window<M: Mechanism>(
        &mut self,
        mechanism: &M,
        circuit: Circuit,
        start_deg: f64,
        span_deg: f64,
        step_deg: f64,
    ) -> Option<[f64; 2]> {
        if !(start_deg.is_finite() && span_deg.is_finite() && span_deg >= 0.0 && step_deg > 0.0) {
            return None;
        }
        let end = start_deg + span_deg;
        // The sample angles: the ends, the multiples of 180° inside, and every step between.
        let mut at: Vec<f64> = vec![start_deg, end];
        let mut k = (start_deg / 180.0).floor() + 1.0;
        while k * 180.0 < end {
            at.push(k * 180.0);
            k += 1.0;
        }
        let n = (span_deg / step_deg).ceil() as usize;
        at.extend((1..n).map(|i| start_deg + i as f64 * step_deg));
        at.sort_by(f64::total_cmp);
        at.dedup();
        let mu = |deg: f64| mechanism.transmission(circuit, &CrankAngle::from_degrees(deg));
        let values: Vec<f64> = at
            .iter()
            .map(|&t| *self.mu.entry(t.to_bits()).or_insert_with(|| mu(t)))
            .collect::<Option<_>>()?;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &v in &values {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        for i in 1..at.len().saturating_sub(1) {
            let (a, v, b) = (values[i - 1], values[i], values[i + 1]);
            let on_half_turn = (at[i] / 180.0).fract() == 0.0;
            if on_half_turn || !((v > a && v > b) || (v < a && v < b)) {
                continue;
            }
            let up = v > a;
            let key = (at[i - 1].to_bits(), at[i + 1].to_bits(), up);
            let peak = *self.peak.entry(key).or_insert_with(|| {
                let sign = if up { 1.0 } else { -1.0 };
                mu(golden(
                    |t| sign * mu(t).unwrap_or(f64::NAN),
                    at[i - 1],
                    at[i + 1],
                ))
            });
            if let Some(y) = peak {
                lo = lo.min(y);
                hi = hi.max(y);
            }
        }
        Some([lo.to_degrees(), hi.to_degrees()])
    }
}

/// The maximiser of a unimodal `f` on `[a, b]`, by golden-section search to 1e-10°.
fn golden(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    const R: f64 = 0.618_033_988_749_894_8;
    let (mut c, mut d) = (b - R * (b - a), a + R * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    while b - a > 1e-10 {
        if fc > fd {
            b = d;
            (d, fd) = (c, fc);
            c = b - R * (b - a);
            fc = f(c);
        } else {
            a = c;
            (c, fc) = (d, fd);
            d = a + R * (b - a);
            fd = f(d);
        }
    }
    0.5 * (a + b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_kinematics::FourBar;

    #[test]
    fn four_bar_window_extremes_equal_a_dense_scan() {
        let l = FourBar::new(2.5, 3.0, 3.5).unwrap();
        for (start, span) in [(0.0, 30.0), (350.0, 40.0), (100.0, 170.0), (200.0, 300.0)] {
            let [lo, hi] = window_transmission(&l, Circuit::Crossed, start, span, 5.0).unwrap();
            let (mut dlo, mut dhi) = (f64::INFINITY, f64::NEG_INFINITY);
            for k in 0..=20_000 {
                let t = start + span * k as f64 / 20_000.0;
                let m = l
                    .transmission(Circuit::Crossed, &CrankAngle::from_degrees(t))
                    .unwrap()
                    .to_degrees();
                dlo = dlo.min(m);
                dhi = dhi.max(m);
            }
            // The scan's samples are inside the window: never beyond the exact extremes.
            assert!(lo <= dlo + 1e-12 && hi >= dhi - 1e-12, "{start} {span}");
            assert!(
                dlo - lo < 1e-6 && hi - dhi < 1e-6,
                "{start} {span}: {lo} {dlo} {hi} {dhi}"
            );
        }
    }

    #[test]
    fn whole_turn_window_is_the_whole_range() {
        let l = FourBar::new(3.0, 2.0, 3.5).unwrap();
        let whole = l.transmission_range(Circuit::Open).unwrap();
        let w = window_transmission(&l, Circuit::Open, 17.0, 360.0, 5.0).unwrap();
        assert_eq!(w, whole.map(f64::to_degrees));
    }
}
