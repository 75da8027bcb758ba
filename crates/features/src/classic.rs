//! Named full curves (the `[[curve]]` entries of a page set such as
//! `atlas-spec/classics.toml`): the classic straight-line linkages, mostly not
//! crank-rockers, traced in full across toggles and measured by their longest straight
//! runs, for either mechanism (a four-bar, or a geared five-bar over its period). Pure.

use crate::run::longest_straight_run;
use coupler_kinematics::{
    Branch, Circuit, CouplerPoint, FullCurve, InputRange, Linkage, trace_full,
};
use serde::Serialize;

/// How a curve of an explicit spec is traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceMode {
    /// One circuit over a full turn of the input (`"open"` or `"crossed"`).
    Circuit(Circuit),
    /// Every branch, across toggles (`"full"`; [`coupler_kinematics::trace_full`]).
    Full,
}

impl TraceMode {
    /// As written in a spec: `"full"`, `"open"` or `"crossed"`.
    pub fn name(self) -> &'static str {
        match self {
            TraceMode::Full => "full",
            TraceMode::Circuit(c) => c.name(),
        }
    }
}

/// One named curve.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedCurve {
    /// Name (e.g. `"Watt"`).
    pub name: String,
    /// The linkage (input = 1): a four-bar or a geared five-bar.
    pub linkage: Linkage,
    /// The coupler point.
    pub point: CouplerPoint,
    /// How it is traced.
    pub trace: TraceMode,
}

/// Tolerances on ε_S at which each curve's straight run is measured (1 %, 0.1 %,
/// 0.01 %): the pages print all three, the middle one is drawn.
pub const STRAIGHTNESS_TOLERANCES: [f64; 3] = [1e-2, 1e-3, 1e-4];

/// The longest straight run of a full curve at one tolerance.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StraightMeasure {
    /// The ε_S bound it was found under (a fraction, not %).
    pub tolerance: f64,
    /// Index of the branch it lies on.
    pub branch: usize,
    /// Index of its first sample in the branch, and the number of samples.
    pub samples: [usize; 2],
    /// Input angle at its ends, degrees (in the order of motion).
    pub input_deg: [f64; 2],
    /// Input travel over it, degrees (summed along the branch: a run through a toggle
    /// counts the travel out and back).
    pub input_span_deg: f64,
    /// Δx along the fitted line, in units of the input link.
    pub extent: f64,
    /// ε_S over the run (a fraction).
    pub straightness: f64,
    /// Its end points.
    pub ends: [[f64; 2]; 2],
}

/// A named curve traced in full and measured.
#[derive(Clone, Debug, PartialEq)]
pub struct ClassicCurve {
    /// Where the input can go (toggles).
    pub range: InputRange,
    /// The branches drawn (every branch for `full`; for one circuit, its samples).
    pub branches: Vec<Branch>,
    /// The longest straight run at each of [`STRAIGHTNESS_TOLERANCES`] (`None` where no
    /// run of three samples qualifies).
    pub straight: Vec<Option<StraightMeasure>>,
}

impl ClassicCurve {
    /// Traces `c` at input steps of `step_deg` across its toggles
    /// ([`coupler_kinematics::trace_full`]) and measures its longest straight run at each
    /// tolerance: the run of consecutive samples on one branch that moves one way along
    /// its total-least-squares line with ε_S ≤ the tolerance (Norton §3.8) and travels
    /// the farthest in input angle, over every run of every branch
    /// ([`crate::longest_straight_run`]; ties: the smaller ε_S, then the earlier branch).
    ///
    /// A geared five-bar is traced by [`coupler_kinematics::GearedFiveBar::trace_full`]
    /// (the same branches and toggles, over its period).
    pub fn compute(c: &NamedCurve, step_deg: f64) -> ClassicCurve {
        let full: FullCurve = match &c.linkage {
            Linkage::FourBar(l) => trace_full(l, c.point, step_deg),
            Linkage::GearedFiveBar(g) => g.trace_full(c.point, step_deg),
        };
        let branches: Vec<Branch> = match c.trace {
            TraceMode::Full => full.branches,
            TraceMode::Circuit(circ) => full
                .branches
                .into_iter()
                .filter(|b| b.samples.first().is_some_and(|s| s.circuit == circ))
                .collect(),
        };
        let mut curve = ClassicCurve {
            range: full.range,
            branches,
            straight: Vec::new(),
        };
        curve.straight = STRAIGHTNESS_TOLERANCES
            .iter()
            .map(|&t| curve.straight_at(t))
            .collect();
        curve
    }

    /// The longest straight run at ε_S ≤ `tolerance` (a fraction), over every run of
    /// every branch, as [`ClassicCurve::compute`] measures it at its three tolerances
    /// (`search` on a page set asks for others). `None` where no run of three samples
    /// qualifies.
    pub fn straight_at(&self, tolerance: f64) -> Option<StraightMeasure> {
        let t = tolerance;
        let mut best: Option<StraightMeasure> = None;
        for (bi, b) in self.branches.iter().enumerate() {
            let pts = b.points();
            let input: Vec<f64> = b.samples.iter().map(|s| s.degrees).collect();
            let Some(run) = longest_straight_run(&pts, &input, t) else {
                continue;
            };
            let seg = &b.samples[run.start..run.start + run.len];
            let span: f64 = seg
                .windows(2)
                .map(|w| (w[1].degrees - w[0].degrees).abs())
                .sum();
            let better = best.is_none_or(|m| {
                span > m.input_span_deg
                    || (span == m.input_span_deg && run.straightness < m.straightness)
            });
            if better {
                let (first, last) = (seg[0], seg[seg.len() - 1]);
                best = Some(StraightMeasure {
                    tolerance: t,
                    branch: bi,
                    samples: [run.start, run.len],
                    input_deg: [first.degrees, last.degrees],
                    input_span_deg: span,
                    extent: run.extent,
                    straightness: run.straightness,
                    ends: [[first.point.x, first.point.y], [last.point.x, last.point.y]],
                });
            }
        }
        best
    }

    /// The input's range in words: "full turn", or the rocking intervals in degrees.
    pub fn range_text(&self) -> String {
        match &self.range {
            InputRange::Full => "full turn".to_string(),
            InputRange::Never => "never assembles".to_string(),
            InputRange::Rocks { intervals } => intervals
                .iter()
                .map(|(lo, hi)| format!("[{:.2}°, {:.2}°]", lo.degrees, hi.degrees))
                .collect::<Vec<_>>()
                .join(", "),
        }
    }
}
