//! Full-curve page sets: the usual `[atlas]`, `[sampling]` and `[pages]` sections of a
//! spec with a list of `[[curve]]` entries (name, lengths, coupler point, trace) instead
//! of the `[linkages]`/`[points]` grid (`atlas-spec/classics.toml`).

use crate::{AtlasSpec, PageSettings, Sampling, SpecError};
use coupler_features::NamedCurve;

/// A parsed full-curve page set: the `[atlas]`, `[sampling]` and `[pages]` sections of a
/// spec with a list of `[[curve]]` entries instead of the grid. Parsed by
/// [`AtlasSpec::parse`] (errors are located like every spec error).
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
    /// let text = include_str!("../../../atlas-spec/classics.toml");
    /// let list = coupler_spec::CurveList::parse(text, "classics.toml").unwrap();
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

#[cfg(test)]
mod tests {
    use super::*;
    use coupler_features::ClassicCurve;

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
        assert!(parse(include_str!("../../../atlas-spec/quick.toml")).is_err());
        let e = crate::Spec::parse(BASE, "t.toml").unwrap_err();
        assert!(e.message.contains("[[curve]]"), "{e}");
    }

    /// The shipped page set's measures: Hoeken's straight run at 1 % spans θ = 180° on
    /// the open circuit (docs/conventions.md §7), and every classic has one at each tolerance,
    /// longer at looser tolerances.
    #[test]
    fn classics_measure_their_straight_runs() {
        let list =
            CurveList::parse(include_str!("../../../atlas-spec/classics.toml"), "c").unwrap();
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
                // The straight part spans θ = 180° on the open circuit (docs/conventions.md §7).
                let s = m.straight[0].unwrap();
                let b = &m.branches[s.branch];
                assert_eq!(
                    b.samples[s.samples[0]].circuit,
                    coupler_kinematics::Circuit::Open
                );
                assert!(s.input_deg[0] < 180.0 && 180.0 < s.input_deg[1], "{s:?}");
            }
        }
    }
}
