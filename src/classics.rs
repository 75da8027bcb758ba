//! Explicit-curve specs (`atlas-spec/classics.toml`): the usual `[atlas]` and
//! `[sampling]` sections with a list of `[[curve]]` entries (name, lengths, coupler point,
//! trace) instead of the `[linkages]`/`[points]` grid. Used for the classic straight-line
//! linkages, which are mostly not crank-rockers and are traced in full across toggles.
//! Pure: parses text.

use crate::linkage::{Circuit, CouplerPoint, FourBar};
use crate::methods::longest_straight_run;
use crate::spec::{AtlasSpec, PageSettings, Sampling, SpecError};
use crate::trace::{Branch, InputRange, trace_full};
use serde::Serialize;

/// How a curve of an explicit spec is traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceMode {
    /// One circuit over a full turn of the input (`"open"` or `"crossed"`).
    Circuit(Circuit),
    /// Every branch, across toggles (`"full"`; [`crate::trace::trace_full`]).
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
    /// The linkage (input = 1).
    pub linkage: FourBar,
    /// The coupler point.
    pub point: CouplerPoint,
    /// How it is traced.
    pub trace: TraceMode,
}

/// A parsed full-curve page set: the `[atlas]`, `[sampling]` and `[pages]` sections of a
/// spec with a list of `[[curve]]` entries instead of the grid. Parsed by
/// [`crate::spec::AtlasSpec::parse`] (errors are located like every spec error).
#[derive(Clone, Debug, PartialEq)]
pub struct CurveList {
    /// `[atlas] name`.
    pub name: String,
    /// `[atlas] title` (the name if absent).
    pub title: String,
    /// `[sampling]`: the input step of the traced samples behind the measures, and the
    /// input angle per dash on the pages.
    pub sampling: Sampling,
    /// `[pages]` (one curve per page).
    pub pages: PageSettings,
    /// The curves, in file order.
    pub curves: Vec<NamedCurve>,
}

impl CurveList {
    /// Parses and validates a full-curve page set.
    ///
    /// ```
    /// let text = include_str!("../atlas-spec/classics.toml");
    /// let list = coupler_atlas::classics::CurveList::parse(text, "classics.toml").unwrap();
    /// assert_eq!(list.curves.len(), 5);
    /// ```
    pub fn parse(text: &str, source_name: &str) -> Result<CurveList, SpecError> {
        match AtlasSpec::parse(text, source_name)? {
            AtlasSpec::Curves(list) => Ok(list),
            AtlasSpec::Grid(_) => Err(SpecError {
                source_name: source_name.to_string(),
                line: 1,
                column: 1,
                key: Some("curve".into()),
                message: "this spec is a grid ([linkages] and [points]); a list of [[curve]] entries is needed here".into(),
                snippet: None,
            }),
        }
    }
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
    /// ([`crate::trace::trace_full`]) and measures its longest straight run at each
    /// tolerance: the longest run of consecutive samples on one branch that moves one
    /// way along its total-least-squares line with ε_S ≤ the tolerance (Norton §3.8),
    /// the longest by input travel across branches.
    pub fn compute(c: &NamedCurve, step_deg: f64) -> ClassicCurve {
        let full = trace_full(&c.linkage, c.point, step_deg);
        let branches: Vec<Branch> = match c.trace {
            TraceMode::Full => full.branches,
            TraceMode::Circuit(circ) => full
                .branches
                .into_iter()
                .filter(|b| b.samples.first().is_some_and(|s| s.circuit == circ))
                .collect(),
        };
        let straight = STRAIGHTNESS_TOLERANCES
            .iter()
            .map(|&t| {
                let mut best: Option<StraightMeasure> = None;
                for (bi, b) in branches.iter().enumerate() {
                    let pts = b.points();
                    let Some(run) = longest_straight_run(&pts, t) else {
                        continue;
                    };
                    let seg = &b.samples[run.start..run.start + run.len];
                    let span: f64 = seg
                        .windows(2)
                        .map(|w| (w[1].degrees - w[0].degrees).abs())
                        .sum();
                    if best.is_none_or(|m| span > m.input_span_deg) {
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
            })
            .collect();
        ClassicCurve {
            range: full.range,
            branches,
            straight,
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<CurveList, SpecError> {
        CurveList::parse(text, "t.toml")
    }

    const BASE: &str = "[atlas]\nname = \"x\"\n[[curve]]\nname = \"a\"\ncoupler = 1.0\nrocker = 1.0\nground = 1.5\nu = 0.0\nv = 0.0\n";

    #[test]
    fn rejects_bad_entries_with_their_line_and_key() {
        assert!(parse(BASE).is_ok());
        let e = parse(&BASE.replace("coupler = 1.0", "coupler = -1.0")).unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (5, Some("curve.coupler")),
            "{e}"
        );
        let e = parse(&format!("{BASE}trace = \"sideways\"\n")).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("curve.trace"), "{e}");
        let e = parse(&format!("{BASE}colour = 3\n")).unwrap_err();
        assert!(e.message.contains("unknown field"), "{e}");
        assert!(parse("[atlas]\nname = \"x\"\ncurve = []\n").is_err());
        let e = parse(&format!("{BASE}[[curve]]\nname = \"a\"\ncoupler = 1.0\nrocker = 1.0\nground = 1.5\nu = 0.0\nv = 0.0\n")).unwrap_err();
        assert!(e.message.contains("earlier"), "{e}");
        // A triple rocker cannot be traced on one circuit over a full turn.
        let e = parse(&format!("{BASE}trace = \"open\"\n")).unwrap_err();
        assert!(e.message.contains("cannot turn fully"), "{e}");
        let e = parse(&format!("[pages]\ncurves_per_page = 4\n{BASE}")).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("pages.curves_per_page"), "{e}");
        // Grid and list together.
        let e = parse(&format!("{BASE}[linkages]\ncoupler = {{ start = 1, end = 1, step = 1 }}\nrocker = {{ start = 1, end = 1, step = 1 }}\nground = {{ start = 1, end = 1, step = 1 }}\n")).unwrap_err();
        assert!(e.message.contains("not both"), "{e}");
        // A grid spec is not a curve list, and a curve list is not a grid spec.
        assert!(parse(include_str!("../atlas-spec/quick.toml")).is_err());
        let e = crate::Spec::parse(BASE, "t.toml").unwrap_err();
        assert!(e.message.contains("[[curve]]"), "{e}");
    }

    /// The shipped page set's measures: Hoeken's straight run at 1 % spans θ = 180° on
    /// the open circuit (domain.md §7), and every classic has one at each tolerance,
    /// longer at looser tolerances.
    #[test]
    fn classics_measure_their_straight_runs() {
        let list = CurveList::parse(include_str!("../atlas-spec/classics.toml"), "c").unwrap();
        for c in &list.curves {
            let m = ClassicCurve::compute(c, list.sampling.crank_step_deg);
            let spans: Vec<f64> = m
                .straight
                .iter()
                .map(|s| s.expect("a straight run").input_span_deg)
                .collect();
            assert!(
                spans[0] > spans[1] && spans[1] > spans[2],
                "{}: {spans:?}",
                c.name
            );
            for s in m.straight.iter().flatten() {
                assert!(s.straightness <= s.tolerance, "{}", c.name);
            }
            if c.name == "Hoeken" {
                // The straight part spans θ = 180° on the open circuit (domain.md §7).
                let s = m.straight[0].unwrap();
                let b = &m.branches[s.branch];
                assert_eq!(b.samples[s.samples[0]].circuit, crate::Circuit::Open);
                assert!(s.input_deg[0] < 180.0 && 180.0 < s.input_deg[1], "{s:?}");
            }
        }
    }
}
