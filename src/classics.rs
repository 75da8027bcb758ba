//! Explicit-curve specs (`atlas-spec/classics.toml`): the usual `[atlas]` and
//! `[sampling]` sections with a list of `[[curve]]` entries (name, lengths, coupler point,
//! trace) instead of the `[linkages]`/`[points]` grid. Used for the classic straight-line
//! linkages, which are mostly not crank-rockers and are traced in full across toggles.
//! Pure: parses text.

use crate::linkage::{Circuit, CouplerPoint, FourBar};
use serde::Deserialize;

/// How a curve of an explicit spec is traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceMode {
    /// One circuit over a full turn of the input (`"open"` or `"crossed"`).
    Circuit(Circuit),
    /// Every branch, across toggles (`"full"`; [`crate::trace::trace_full`]).
    Full,
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

/// A parsed explicit-curve spec.
#[derive(Clone, Debug, PartialEq)]
pub struct CurveList {
    /// `[atlas] name`.
    pub name: String,
    /// `[atlas] title` (the name if absent).
    pub title: String,
    /// `[sampling] crank_step_deg` (default 1).
    pub crank_step_deg: f64,
    /// The curves, in file order.
    pub curves: Vec<NamedCurve>,
}

/// An error in an explicit-curve spec.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{source_name}: {message}")]
pub struct CurveListError {
    /// The file.
    pub source_name: String,
    /// What is wrong (with the curve's name or index).
    pub message: String,
}

#[derive(Deserialize)]
struct Raw {
    atlas: RawAtlas,
    #[serde(default)]
    sampling: Option<RawSampling>,
    #[serde(default)]
    pages: Option<toml::Value>,
    curve: Vec<RawCurve>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAtlas {
    name: String,
    #[serde(default)]
    title: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSampling {
    #[serde(default)]
    crank_step_deg: Option<f64>,
    #[serde(default)]
    dash_deg: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCurve {
    name: String,
    coupler: f64,
    rocker: f64,
    ground: f64,
    u: f64,
    v: f64,
    #[serde(default)]
    trace: Option<String>,
}

impl CurveList {
    /// Parses and validates an explicit-curve spec.
    ///
    /// ```
    /// let text = include_str!("../atlas-spec/classics.toml");
    /// let list = coupler_atlas::classics::CurveList::parse(text, "classics.toml").unwrap();
    /// assert_eq!(list.curves.len(), 5);
    /// ```
    pub fn parse(text: &str, source_name: &str) -> Result<CurveList, CurveListError> {
        let err = |message: String| CurveListError {
            source_name: source_name.to_string(),
            message,
        };
        let raw: Raw = toml::from_str(text).map_err(|e| err(e.to_string()))?;
        let _ = raw.pages;
        let step = raw
            .sampling
            .as_ref()
            .and_then(|s| s.crank_step_deg)
            .unwrap_or(1.0);
        let _ = raw.sampling.as_ref().and_then(|s| s.dash_deg);
        if !(step.is_finite() && step > 0.0 && step <= 360.0) {
            return Err(err(format!(
                "sampling.crank_step_deg must be in (0, 360], got {step}"
            )));
        }
        if raw.curve.is_empty() {
            return Err(err("no [[curve]] entries".into()));
        }
        let mut curves = Vec::new();
        for (i, c) in raw.curve.iter().enumerate() {
            let at = |m: String| err(format!("curve {} (`{}`): {m}", i + 1, c.name));
            let linkage =
                FourBar::new(c.coupler, c.rocker, c.ground).map_err(|e| at(e.to_string()))?;
            if !(c.u.is_finite() && c.v.is_finite()) {
                return Err(at("u and v must be finite".into()));
            }
            let trace = match c.trace.as_deref().unwrap_or("full") {
                "full" => TraceMode::Full,
                other => TraceMode::Circuit(other.parse().map_err(|_| {
                    at(format!(
                        "trace must be `full`, `open` or `crossed`, got `{other}`"
                    ))
                })?),
            };
            if curves.iter().any(|n: &NamedCurve| n.name == c.name) {
                return Err(at("name used twice".into()));
            }
            curves.push(NamedCurve {
                name: c.name.clone(),
                linkage,
                point: CouplerPoint::new(c.u, c.v),
                trace,
            });
        }
        Ok(CurveList {
            title: raw.atlas.title.unwrap_or_else(|| raw.atlas.name.clone()),
            name: raw.atlas.name,
            crank_step_deg: step,
            curves,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_entries() {
        let base = "[atlas]\nname = \"x\"\n[[curve]]\nname = \"a\"\ncoupler = 1.0\nrocker = 1.0\nground = 1.0\nu = 0.0\nv = 0.0\n";
        assert!(CurveList::parse(base, "t").is_ok());
        assert!(CurveList::parse(&base.replace("coupler = 1.0", "coupler = -1.0"), "t").is_err());
        assert!(CurveList::parse(&format!("{base}trace = \"sideways\"\n"), "t").is_err());
        assert!(CurveList::parse(&format!("{base}colour = 3\n"), "t").is_err());
        assert!(CurveList::parse("[atlas]\nname = \"x\"\ncurve = []\n", "t").is_err());
    }
}
