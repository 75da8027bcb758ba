//! Atlas specs: TOML files under `atlas-spec/` that say which linkages, coupler points,
//! circuits and sampling make an atlas. Parsing validates everything before any work
//! starts; every error names the file, the line and the key.
//!
//! The format is documented in `docs/spec-format.md`.

use crate::count::{self, CrankRockers};
use crate::curves::CurveList;
use crate::features::FeatureSettings;
use crate::geared::GearedRanges;
use crate::ranges::{DecimalRange, LinkageRanges};
use crate::settings::{PageSettings, Sampling};
use coupler_features::{NamedCurve, TraceMode};
use coupler_kinematics::{
    Circuit, Class, CouplerPoint, Decimal, FourBar, GearRatio, GearedError, GearedFiveBar, Linkage,
    Mechanism, divides_turn, samples_per_turn,
};
use coupler_layout::{DPI_RANGE, Orientation, PaperSize};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::ops::Range;
use toml::Spanned;

/// The default atlas (`atlas-spec/hrones-nelson.toml`), embedded in the binary so that
/// `coupler-atlas generate` works anywhere.
pub const DEFAULT_SPEC_TEXT: &str = include_str!("../../../atlas-spec/hrones-nelson.toml");
/// The name under which the embedded default spec is reported.
pub const DEFAULT_SPEC_SOURCE: &str = "atlas-spec/hrones-nelson.toml (built in)";

/// An error in a spec, located in its source.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{source_name}:{line}:{column}: {}{message}{}", key.as_ref().map(|k| format!("key `{k}`: ")).unwrap_or_default(), snippet.as_ref().map(|s| format!("\n  | {s}")).unwrap_or_default())]
pub struct SpecError {
    /// The spec's file (or `builtin` name).
    pub source_name: String,
    /// 1-based line.
    pub line: usize,
    /// 1-based column.
    pub column: usize,
    /// The dotted key the error is about, where known.
    pub key: Option<String>,
    /// What is wrong.
    pub message: String,
    /// The offending source line.
    pub snippet: Option<String>,
}

/// A validated atlas spec.
#[derive(Clone, Debug, PartialEq)]
pub struct Spec {
    /// Short name (used in page headers and file names).
    pub name: String,
    /// Title printed on the contents page.
    pub title: String,
    /// Ranges of the coupler A, rocker B and ground C (crank = 1) of a four-bar atlas;
    /// empty ranges in a geared five-bar atlas (see `geared`).
    pub linkages: LinkageRanges,
    /// The linkages of a geared five-bar atlas (`[geared]`, instead of `[linkages]`).
    pub geared: Option<GearedRanges>,
    /// Circuits to trace, in order.
    pub circuits: Vec<Circuit>,
    /// The coupler-point grid.
    pub points: PointGrid,
    /// Sampling of the crank revolution.
    pub sampling: Sampling,
    /// Page settings (used when rendering pages).
    pub pages: PageSettings,
    /// Feature extraction for the index (`[features]`, see `docs/features.md`).
    pub features: FeatureSettings,
}

/// The spec as the index echoes it (`docs/index-schema.md`): every section as parsed,
/// and in `features` the dash angle its `dashes` were counted at, which is
/// `sampling.dash_deg` (one setting for pages and index; the echo keeps the index's
/// schema as it was).
impl Serialize for Spec {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let t = &self.features.tolerances;
        let features = FeaturesEcho {
            enabled: self.features.enabled,
            step_deg: t.step_deg,
            dash_deg: self.sampling.dash_deg,
            straight_pct: t.straight_pct,
            straight_min_span_deg: t.straight_min_span_deg,
            arc_pct: t.arc_pct,
            arc_min_span_deg: t.arc_min_span_deg,
            arc_min_turn_deg: t.arc_min_turn_deg,
            cusp_speed_ratio: t.cusp_speed_ratio,
            symmetry_tol: t.symmetry_tol,
        };
        let mut st = s.serialize_struct("Spec", 8)?;
        st.serialize_field("name", &self.name)?;
        st.serialize_field("title", &self.title)?;
        match &self.geared {
            None => st.serialize_field("linkages", &self.linkages)?,
            Some(g) => st.serialize_field("linkages", g)?,
        }
        st.serialize_field("circuits", &self.circuits)?;
        st.serialize_field("points", &self.points)?;
        st.serialize_field("sampling", &self.sampling)?;
        st.serialize_field("pages", &self.pages)?;
        st.serialize_field("features", &features)?;
        st.end()
    }
}

/// `[features]` as echoed in the index (see [`Spec`]'s `Serialize`).
#[derive(Serialize)]
struct FeaturesEcho {
    enabled: bool,
    step_deg: f64,
    dash_deg: f64,
    straight_pct: f64,
    straight_min_span_deg: f64,
    arc_pct: f64,
    arc_min_span_deg: f64,
    arc_min_turn_deg: f64,
    cusp_speed_ratio: f64,
    symmetry_tol: f64,
}

/// The coupler-point grid `u × v`, each optionally relative to the coupler length A.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PointGrid {
    /// Along the coupler.
    pub u: DecimalRange,
    /// Across the coupler.
    pub v: DecimalRange,
    /// Whether u is in units of A.
    pub u_relative: bool,
    /// Whether v is in units of A.
    pub v_relative: bool,
}

impl PointGrid {
    /// The grid's points for a coupler of length `a`: rows of constant v (v ascending),
    /// u ascending within a row.
    pub fn points(&self, a: f64) -> Vec<CouplerPoint> {
        let us = self.u.values();
        let vs = self.v.values();
        let scale = |x: Decimal, rel: bool| if rel { x.to_f64() * a } else { x.to_f64() };
        vs.iter()
            .flat_map(|&v| {
                us.iter().map(move |&u| {
                    CouplerPoint::new(scale(u, self.u_relative), scale(v, self.v_relative))
                })
            })
            .collect()
    }

    /// The points `first..first + count` of [`PointGrid::points`] (same order, same
    /// values), without making the others: a slice of a grid too large to hold.
    pub fn points_in(&self, a: f64, first: u64, count: u64) -> Vec<CouplerPoint> {
        let nu = self.u.len().max(1);
        let value = |r: &DecimalRange, k: u64, rel: bool| {
            let x = r
                .start
                .checked_add(
                    r.step
                        .checked_mul_int(i128::from(k))
                        .unwrap_or(Decimal::ZERO),
                )
                .unwrap_or(r.start)
                .to_f64();
            if rel { x * a } else { x }
        };
        (first..first.saturating_add(count).min(self.len()))
            .map(|i| {
                CouplerPoint::new(
                    value(&self.u, i % nu, self.u_relative),
                    value(&self.v, i / nu, self.v_relative),
                )
            })
            .collect()
    }

    /// Points per linkage.
    pub fn len(&self) -> u64 {
        self.u.len() * self.v.len()
    }

    /// True if the grid is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

// ---- raw TOML shape -------------------------------------------------------------------

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSpec {
    atlas: Spanned<RawAtlas>,
    #[serde(default)]
    linkages: Option<Spanned<RawLinkages>>,
    #[serde(default)]
    geared: Option<Spanned<RawGeared>>,
    #[serde(default)]
    points: Option<Spanned<RawPoints>>,
    #[serde(default)]
    curve: Option<Spanned<Vec<Spanned<RawCurve>>>>,
    #[serde(default)]
    sampling: Option<Spanned<RawSampling>>,
    #[serde(default)]
    pages: Option<Spanned<RawPages>>,
    #[serde(default)]
    features: Option<Spanned<toml::Table>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAtlas {
    name: Spanned<String>,
    #[serde(default)]
    title: Option<Spanned<String>>,
}

/// One `[[curve]]` entry of a full-curve page set.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCurve {
    name: Spanned<String>,
    /// `"four-bar"` (the default) or `"geared-fivebar"`.
    #[serde(default)]
    mechanism: Option<Spanned<String>>,
    #[serde(default)]
    coupler: Option<Spanned<f64>>,
    #[serde(default)]
    rocker: Option<Spanned<f64>>,
    #[serde(default)]
    ground: Option<Spanned<f64>>,
    #[serde(default)]
    l1: Option<Spanned<f64>>,
    #[serde(default)]
    l3: Option<Spanned<f64>>,
    #[serde(default)]
    l4: Option<Spanned<f64>>,
    #[serde(default)]
    l5: Option<Spanned<f64>>,
    #[serde(default)]
    ratio: Option<Spanned<String>>,
    #[serde(default)]
    phase: Option<Spanned<f64>>,
    u: Spanned<f64>,
    v: Spanned<f64>,
    #[serde(default)]
    trace: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLinkages {
    coupler: Spanned<RawRange>,
    rocker: Spanned<RawRange>,
    ground: Spanned<RawRange>,
    #[serde(default)]
    circuits: Option<Spanned<Vec<Spanned<String>>>>,
}

/// `[geared]`: a geared five-bar atlas's linkages.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGeared {
    l1: Spanned<RawRange>,
    l3: Spanned<RawRange>,
    l4: Spanned<RawRange>,
    l5: Spanned<RawRange>,
    ratios: Spanned<Vec<Spanned<String>>>,
    phases: Spanned<RawRange>,
    #[serde(default)]
    circuits: Option<Spanned<Vec<Spanned<String>>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRange {
    start: Spanned<f64>,
    end: Spanned<f64>,
    step: Spanned<f64>,
    #[serde(default)]
    relative: Option<Spanned<bool>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPoints {
    u: Spanned<RawRange>,
    v: Spanned<RawRange>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSampling {
    #[serde(default)]
    crank_step_deg: Option<Spanned<f64>>,
    #[serde(default)]
    dash_deg: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPages {
    #[serde(default)]
    curves_per_page: Option<Spanned<i64>>,
    #[serde(default)]
    size: Option<Spanned<String>>,
    #[serde(default)]
    orientation: Option<Spanned<String>>,
    #[serde(default)]
    dpi: Option<Spanned<i64>>,
}

struct Ctx<'a> {
    name: &'a str,
    text: &'a str,
}

impl Ctx<'_> {
    fn error(&self, span: Range<usize>, key: Option<&str>, message: String) -> SpecError {
        let at = span.start.min(self.text.len());
        let before = &self.text[..at];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map(|i| i + 1).unwrap_or(0);
        let column = self.text[line_start..at].chars().count() + 1;
        let snippet = self.text[line_start..]
            .lines()
            .next()
            .map(|s| s.trim_end().to_string())
            .filter(|s| !s.is_empty());
        SpecError {
            source_name: self.name.to_string(),
            line,
            column,
            key: key.map(str::to_string),
            message,
            snippet,
        }
    }

    /// Where `key` is assigned in the table that starts at `table` (the key's first
    /// character), searching down to the next table header; the table's span when it is
    /// not found (e.g. a key inside an inline table).
    fn key_in(&self, table: Range<usize>, key: &str) -> Range<usize> {
        let start = table.start.min(self.text.len());
        let mut at = start;
        for (k, line) in self.text[start..].split_inclusive('\n').enumerate() {
            let t = line.trim_start();
            if k > 0 && t.starts_with('[') {
                break;
            }
            if t.strip_prefix(key)
                .is_some_and(|rest| rest.trim_start().starts_with('='))
            {
                let col = line.len() - t.len();
                return at + col..at + col;
            }
            at += line.len();
        }
        table
    }

    fn number(&self, x: &Spanned<f64>, key: &str) -> Result<Decimal, SpecError> {
        Decimal::from_f64(*x.get_ref()).map_err(|_| {
            self.error(
                x.span(),
                Some(key),
                format!("must be a finite number, got {}", x.get_ref()),
            )
        })
    }

    fn range(
        &self,
        r: &Spanned<RawRange>,
        key: &str,
        positive: bool,
    ) -> Result<(DecimalRange, bool), SpecError> {
        let raw = r.get_ref();
        let start = self.number(&raw.start, &format!("{key}.start"))?;
        let end = self.number(&raw.end, &format!("{key}.end"))?;
        let step = self.number(&raw.step, &format!("{key}.step"))?;
        if step.signum() <= 0 {
            return Err(self.error(
                raw.step.span(),
                Some(&format!("{key}.step")),
                format!("step must be > 0, got {}", raw.step.get_ref()),
            ));
        }
        if end < start {
            return Err(self.error(
                raw.end.span(),
                Some(&format!("{key}.end")),
                format!(
                    "empty range: end {} is below start {}",
                    raw.end.get_ref(),
                    raw.start.get_ref()
                ),
            ));
        }
        if positive && start.signum() <= 0 {
            return Err(self.error(
                raw.start.span(),
                Some(&format!("{key}.start")),
                format!(
                    "link lengths must be > 0 (crank = 1), got {}",
                    raw.start.get_ref()
                ),
            ));
        }
        let range = DecimalRange { start, end, step };
        if positive && !fits_f64_exactly(&range) {
            return Err(self.error(
                r.span(),
                Some(key),
                format!(
                    "values from {} by {} need more than {MAX_DIGITS} significant digits, which a length cannot hold exactly",
                    raw.start.get_ref(),
                    raw.step.get_ref()
                ),
            ));
        }
        if range.len() > MAX_RANGE_VALUES {
            return Err(self.error(
                r.span(),
                Some(key),
                format!(
                    "range has {} values, more than the {MAX_RANGE_VALUES} allowed per range",
                    range.len()
                ),
            ));
        }
        let relative = raw.relative.as_ref().map(|s| *s.get_ref()).unwrap_or(false);
        if let (true, Some(rel)) = (positive, raw.relative.as_ref()) {
            return Err(self.error(
                rel.span(),
                Some(&format!("{key}.relative")),
                "`relative` applies to coupler points (u, v) only".into(),
            ));
        }
        Ok((range, relative))
    }

    fn divides_360(&self, x: &Spanned<f64>, key: &str) -> Result<f64, SpecError> {
        self.number(x, key)?;
        if !divides_turn(*x.get_ref()) {
            return Err(self.error(
                x.span(),
                Some(key),
                format!("must be > 0 and divide 360 exactly, got {}", x.get_ref()),
            ));
        }
        samples_per_turn(*x.get_ref()).map_err(|m| self.error(x.span(), Some(key), m))?;
        Ok(*x.get_ref())
    }
}

/// At most this many values in one range (a guard against typos like `step = 1e-9`).
pub const MAX_RANGE_VALUES: u64 = 100_000;

/// At most this many characters in an atlas name: it names the output folder and every
/// page file (`NAME-contents-1.png`, and while written `.NAME-0001.png.tmp-…`), and file
/// names are limited to 255 bytes.
pub const MAX_NAME_LEN: usize = 100;

/// Significant digits a link length may need: every value then reads back from its
/// `f64` as the same decimal, so classes decided on the decimals and on the lengths
/// agree (and the arithmetic counts of `count.rs` are exact).
const MAX_DIGITS: u32 = 15;

/// Whether every value of the range has at most [`MAX_DIGITS`] significant digits.
fn fits_f64_exactly(r: &DecimalRange) -> bool {
    let e = r.start.exponent().min(r.step.exponent());
    let scale = |d: Decimal| -> Option<i128> {
        let mut m = d.mantissa();
        for _ in 0..(d.exponent() - e) {
            m = m.checked_mul(10)?;
        }
        Some(m)
    };
    let (Some(start), Some(step)) = (scale(r.start), scale(r.step)) else {
        return false;
    };
    let last = start + step * (r.len().max(1) as i128 - 1);
    last.abs() < 10i128.pow(MAX_DIGITS)
}

/// What a spec file describes: a Hrones–Nelson grid (`[linkages]` and `[points]`), or a
/// full-curve page set (a list of `[[curve]]` entries, e.g. `atlas-spec/classics.toml`).
#[derive(Clone, Debug, PartialEq)]
pub enum AtlasSpec {
    /// A grid of crank-rockers and coupler points.
    Grid(Box<Spec>),
    /// Explicit named curves, each traced in full.
    Curves(CurveList),
}

impl AtlasSpec {
    /// Parses and validates either kind of spec; `source_name` is used in error messages.
    pub fn parse(text: &str, source_name: &str) -> Result<AtlasSpec, SpecError> {
        let cx = Ctx {
            name: source_name,
            text,
        };
        let raw: RawSpec = toml::from_str(text).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            let message = e.message().trim().to_string();
            let key = error_key_path(text, &span, &message);
            cx.error(span, key.as_deref(), message)
        })?;
        let (name, title) = cx.atlas(raw.atlas.get_ref())?;
        let sampling = cx.sampling(raw.sampling.as_ref())?;
        if let Some(g) = &raw.geared {
            return cx
                .geared_spec(&raw, g, name, title, sampling)
                .map(AtlasSpec::Grid);
        }
        match (&raw.linkages, &raw.points, &raw.curve) {
            (_, _, Some(curves)) => {
                if let Some(t) = &raw.linkages {
                    return Err(cx.error(t.span(), Some("linkages"), "a spec gives either a grid ([linkages] and [points]) or [[curve]] entries, not both".into()));
                }
                if let Some(t) = &raw.points {
                    return Err(cx.error(t.span(), Some("points"), "a spec gives either a grid ([linkages] and [points]) or [[curve]] entries, not both".into()));
                }
                if let Some(t) = &raw.features {
                    return Err(cx.error(t.span(), Some("features"), "[features] configures the index of a grid atlas; a [[curve]] page set measures each curve's straight runs (docs/spec-format.md)".into()));
                }
                let pages = cx.pages(raw.pages.as_ref(), false)?;
                let curves = cx.curves(curves)?;
                Ok(AtlasSpec::Curves(CurveList {
                    name,
                    title,
                    sampling,
                    pages,
                    curves,
                }))
            }
            (Some(l), Some(p), None) => {
                let pages = cx.pages(raw.pages.as_ref(), true)?;
                let features = cx.features(raw.features.as_ref())?;
                let (linkages, circuits) = cx.linkages(l.get_ref())?;
                let pr = p.get_ref();
                let (u, u_relative) = cx.range(&pr.u, "points.u", false)?;
                let (v, v_relative) = cx.range(&pr.v, "points.v", false)?;
                // One family per page (as in the 1951 atlas): unless the spec says
                // otherwise, a page holds one row of the grid (constant v).
                let per_page_given = raw
                    .pages
                    .as_ref()
                    .is_some_and(|p| p.get_ref().curves_per_page.is_some());
                let mut pages = pages;
                if !per_page_given {
                    pages.curves_per_page = u.len().clamp(1, 100) as u32;
                }
                Ok(AtlasSpec::Grid(Box::new(Spec {
                    name,
                    title,
                    linkages,
                    circuits,
                    points: PointGrid {
                        u,
                        v,
                        u_relative,
                        v_relative,
                    },
                    sampling,
                    pages,
                    features,
                    geared: None,
                })))
            }
            (l, _, None) => {
                let missing = if l.is_none() { "linkages" } else { "points" };
                Err(cx.error(
                    0..0,
                    Some(missing),
                    format!("missing field `{missing}` (a spec needs [linkages] and [points], or a list of [[curve]] entries)"),
                ))
            }
        }
    }
}

impl CurveList {
    /// Parses and validates a full-curve page set.
    ///
    /// ```
    /// let text = include_str!("../../../atlas-spec/classics.toml");
    /// let list = coupler_specs::CurveList::parse(text, "classics.toml").unwrap();
    /// assert_eq!(list.curves.len(), 6);
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

impl Ctx<'_> {
    fn atlas(&self, atlas: &RawAtlas) -> Result<(String, String), SpecError> {
        let name = atlas.name.get_ref().trim().to_string();
        if name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(self.error(atlas.name.span(), Some("atlas.name"), "name must be non-empty and use only ASCII letters, digits, `-` and `_` (it names files)".into()));
        }
        if name.len() > MAX_NAME_LEN {
            return Err(self.error(
                atlas.name.span(),
                Some("atlas.name"),
                format!(
                    "name is {} characters long, more than the {MAX_NAME_LEN} allowed (it names the output folder and every page file, and file names are limited to 255 bytes)",
                    name.len()
                ),
            ));
        }
        let title = atlas
            .title
            .as_ref()
            .map(|t| t.get_ref().clone())
            .unwrap_or_else(|| name.clone());
        Ok((name, title))
    }

    fn linkages(&self, l: &RawLinkages) -> Result<(LinkageRanges, Vec<Circuit>), SpecError> {
        let (coupler, _) = self.range(&l.coupler, "linkages.coupler", true)?;
        let (rocker, _) = self.range(&l.rocker, "linkages.rocker", true)?;
        let (ground, _) = self.range(&l.ground, "linkages.ground", true)?;
        let circuits = self.circuits(l.circuits.as_ref(), "linkages.circuits")?;
        Ok((
            LinkageRanges {
                coupler,
                rocker,
                ground,
            },
            circuits,
        ))
    }

    /// `[features]` of a grid atlas (four-bar or geared five-bar).
    fn features(&self, raw: Option<&Spanned<toml::Table>>) -> Result<FeatureSettings, SpecError> {
        let Some(t) = raw else {
            return Ok(FeatureSettings::DEFAULT);
        };
        if t.get_ref().contains_key("dash_deg") {
            return Err(self.error(
                self.key_in(t.span(), "dash_deg"),
                Some("features.dash_deg"),
                "the dash angle is one setting for the pages and the index's dash counts: set it as `[sampling] dash_deg`".into(),
            ));
        }
        FeatureSettings::from_table(t.get_ref())
            .map_err(|m| self.error(t.span(), Some("features"), m))
    }

    /// A geared five-bar atlas: `[geared]` and `[points]` (the grid relative to L3).
    fn geared_spec(
        &self,
        raw: &RawSpec,
        g: &Spanned<RawGeared>,
        name: String,
        title: String,
        sampling: Sampling,
    ) -> Result<Box<Spec>, SpecError> {
        let both = "a spec gives the linkages of one mechanism: [linkages] (four-bars) or [geared] (geared five-bars), not both";
        if let Some(t) = &raw.linkages {
            return Err(self.error(t.span(), Some("linkages"), both.into()));
        }
        if let Some(t) = &raw.curve {
            return Err(self.error(
                t.span(),
                Some("curve"),
                "a [geared] grid cannot also list [[curve]] entries".into(),
            ));
        }
        let Some(p) = &raw.points else {
            return Err(self.error(
                g.span(),
                Some("points"),
                "missing field `points` (a [geared] atlas needs a [points] grid)".into(),
            ));
        };
        let pages = self.pages(raw.pages.as_ref(), true)?;
        let features = self.features(raw.features.as_ref())?;
        let r = g.get_ref();
        let (l1, _) = self.range(&r.l1, "geared.l1", true)?;
        let (l3, _) = self.range(&r.l3, "geared.l3", true)?;
        let (l4, _) = self.range(&r.l4, "geared.l4", true)?;
        let (l5, _) = self.range(&r.l5, "geared.l5", true)?;
        let (phases, relative) = self.range(&r.phases, "geared.phases", false)?;
        if relative {
            return Err(self.error(
                r.phases.span(),
                Some("geared.phases.relative"),
                "`relative` applies to coupler points (u, v) only".into(),
            ));
        }
        if r.ratios.get_ref().is_empty() {
            return Err(self.error(
                r.ratios.span(),
                Some("geared.ratios"),
                "list is empty: give gear ratios such as \"-1\", \"2\", \"-1/2\"".into(),
            ));
        }
        let mut ratios = Vec::new();
        for t in r.ratios.get_ref() {
            let ratio: GearRatio = t.get_ref().parse().map_err(|e: GearedError| {
                self.error(t.span(), Some("geared.ratios"), e.to_string())
            })?;
            if ratios.contains(&ratio) {
                return Err(self.error(
                    t.span(),
                    Some("geared.ratios"),
                    format!("gear ratio {ratio} is listed twice"),
                ));
            }
            ratios.push(ratio);
        }
        let circuits = self.circuits(r.circuits.as_ref(), "geared.circuits")?;
        let pr = p.get_ref();
        let (u, u_relative) = self.range(&pr.u, "points.u", false)?;
        let (v, v_relative) = self.range(&pr.v, "points.v", false)?;
        let none = DecimalRange {
            start: Decimal::ZERO,
            end: Decimal::ZERO,
            step: Decimal::ZERO,
        };
        Ok(Box::new(Spec {
            name,
            title,
            linkages: LinkageRanges {
                coupler: none,
                rocker: none,
                ground: none,
            },
            geared: Some(GearedRanges {
                l1,
                l3,
                l4,
                l5,
                ratios,
                phases,
                enumerated: Default::default(),
            }),
            circuits,
            points: PointGrid {
                u,
                v,
                u_relative,
                v_relative,
            },
            sampling,
            pages,
            features,
        }))
    }

    fn circuits(
        &self,
        list: Option<&Spanned<Vec<Spanned<String>>>>,
        key: &str,
    ) -> Result<Vec<Circuit>, SpecError> {
        let circuits = match list {
            None => vec![Circuit::Open],
            Some(list) => {
                if list.get_ref().is_empty() {
                    return Err(self.error(
                        list.span(),
                        Some(key),
                        "list is empty: give `open`, `crossed` or both".into(),
                    ));
                }
                let mut out = Vec::new();
                for c in list.get_ref() {
                    let circuit: Circuit = c
                        .get_ref()
                        .parse()
                        .map_err(|m: String| self.error(c.span(), Some(key), m))?;
                    if out.contains(&circuit) {
                        return Err(self.error(
                            c.span(),
                            Some(key),
                            format!("`{circuit}` is listed twice"),
                        ));
                    }
                    out.push(circuit);
                }
                out
            }
        };
        Ok(circuits)
    }

    fn sampling(&self, raw: Option<&Spanned<RawSampling>>) -> Result<Sampling, SpecError> {
        let mut sampling = Sampling::DEFAULT;
        if let Some(s) = raw {
            let s = s.get_ref();
            if let Some(x) = &s.crank_step_deg {
                sampling.crank_step_deg = self.divides_360(x, "sampling.crank_step_deg")?;
            }
            if let Some(x) = &s.dash_deg {
                sampling.dash_deg = self.divides_360(x, "sampling.dash_deg")?;
            }
        }
        Ok(sampling)
    }

    /// `[pages]`; `per_page` says whether `curves_per_page` applies (a [[curve]] page set
    /// puts one curve on each page).
    fn pages(
        &self,
        raw: Option<&Spanned<RawPages>>,
        per_page: bool,
    ) -> Result<PageSettings, SpecError> {
        let mut pages = PageSettings {
            curves_per_page: if per_page { 10 } else { 1 },
            size: PaperSize::Tabloid,
            orientation: Orientation::Auto,
            dpi: 300,
        };
        let Some(raw_pages) = raw else {
            return Ok(pages);
        };
        let rp = raw_pages.get_ref();
        if let Some(n) = &rp.curves_per_page {
            if !per_page {
                return Err(self.error(
                    n.span(),
                    Some("pages.curves_per_page"),
                    "a [[curve]] page set puts one curve on each page".into(),
                ));
            }
            if !(1..=100).contains(n.get_ref()) {
                return Err(self.error(
                    n.span(),
                    Some("pages.curves_per_page"),
                    format!("must be from 1 to 100, got {}", n.get_ref()),
                ));
            }
            pages.curves_per_page = *n.get_ref() as u32;
        }
        if let Some(s) = &rp.size {
            pages.size = s.get_ref().parse().map_err(|_| {
                self.error(
                    s.span(),
                    Some("pages.size"),
                    format!(
                        "unknown page size `{}` (expected one of {})",
                        s.get_ref(),
                        PaperSize::ALL.map(|p| p.name()).join(", ")
                    ),
                )
            })?;
        }
        if let Some(o) = &rp.orientation {
            pages.orientation = o
                .get_ref()
                .parse()
                .map_err(|m| self.error(o.span(), Some("pages.orientation"), m))?;
        }
        if let Some(d) = &rp.dpi {
            let dpi = u32::try_from(*d.get_ref())
                .ok()
                .filter(|x| DPI_RANGE.contains(x))
                .ok_or_else(|| {
                    self.error(
                        d.span(),
                        Some("pages.dpi"),
                        format!(
                            "must be from {} to {}, got {}",
                            DPI_RANGE.start(),
                            DPI_RANGE.end(),
                            d.get_ref()
                        ),
                    )
                })?;
            pages.dpi = dpi;
        }
        Ok(pages)
    }

    /// The linkage of one `[[curve]]` entry: a four-bar's `coupler`, `rocker`, `ground`,
    /// or with `mechanism = "geared-fivebar"` a geared five-bar's `l1`, `l3`, `l4`, `l5`,
    /// `ratio` and `phase` (degrees, default 0); keys of the other mechanism are refused.
    fn curve_linkage(&self, entry: &Spanned<RawCurve>) -> Result<Linkage, SpecError> {
        let length = |x: &Spanned<f64>, key: &str| -> Result<f64, SpecError> {
            let v = *x.get_ref();
            if !v.is_finite() || v <= 0.0 {
                return Err(self.error(
                    x.span(),
                    Some(key),
                    format!("link lengths must be finite and > 0 (input link = 1), got {v}"),
                ));
            }
            Ok(v)
        };
        let c = entry.get_ref();
        let geared = match &c.mechanism {
            None => false,
            Some(m) if m.get_ref() == "four-bar" => false,
            Some(m) if m.get_ref() == "geared-fivebar" => true,
            Some(m) => {
                return Err(self.error(
                    m.span(),
                    Some("curve.mechanism"),
                    format!(
                        "must be `four-bar` or `geared-fivebar`, got `{}`",
                        m.get_ref()
                    ),
                ));
            }
        };
        let four = [
            ("coupler", c.coupler.as_ref()),
            ("rocker", c.rocker.as_ref()),
            ("ground", c.ground.as_ref()),
        ];
        let five = [
            ("l1", c.l1.as_ref()),
            ("l3", c.l3.as_ref()),
            ("l4", c.l4.as_ref()),
            ("l5", c.l5.as_ref()),
            ("phase", c.phase.as_ref()),
        ];
        let (mechanism, other) = if geared {
            ("a geared five-bar", &four[..])
        } else {
            ("a four-bar", &five[..])
        };
        if let Some((key, x)) = other.iter().find_map(|(k, x)| x.map(|x| (k, x))) {
            return Err(self.error(
                x.span(),
                Some(&format!("curve.{key}")),
                format!(
                    "`{key}` is not a dimension of {mechanism} (a four-bar takes coupler, rocker, ground; a geared five-bar, with mechanism = \"geared-fivebar\", takes l1, l3, l4, l5, ratio, phase)"
                ),
            ));
        }
        if !geared {
            if let Some(r) = &c.ratio {
                return Err(self.error(
                    r.span(),
                    Some("curve.ratio"),
                    "`ratio` is a geared five-bar's: add mechanism = \"geared-fivebar\"".into(),
                ));
            }
        }
        let need = |x: Option<&Spanned<f64>>, key: &str| -> Result<f64, SpecError> {
            match x {
                Some(x) => length(x, &format!("curve.{key}")),
                None => Err(self.error(
                    entry.span(),
                    Some("curve"),
                    format!(
                        "`{}` has no `{key}`: {mechanism} needs {}",
                        c.name.get_ref(),
                        if geared {
                            "l1, l3, l4, l5 and ratio (phase defaults to 0)"
                        } else {
                            "coupler, rocker and ground"
                        }
                    ),
                )),
            }
        };
        if !geared {
            let l = FourBar::new(
                need(four[0].1, "coupler")?,
                need(four[1].1, "rocker")?,
                need(four[2].1, "ground")?,
            )
            .map_err(|e| self.error(entry.span(), Some("curve"), e.to_string()))?;
            return Ok(Linkage::FourBar(l));
        }
        let (l1, l3, l4, l5) = (
            need(five[0].1, "l1")?,
            need(five[1].1, "l3")?,
            need(five[2].1, "l4")?,
            need(five[3].1, "l5")?,
        );
        let Some(ratio) = &c.ratio else {
            return Err(self.error(
                entry.span(),
                Some("curve"),
                format!(
                    "`{}` has no `ratio`: a geared five-bar needs its gear ratio, e.g. ratio = \"-1\"",
                    c.name.get_ref()
                ),
            ));
        };
        let ratio: GearRatio = ratio.get_ref().parse().map_err(|e: GearedError| {
            self.error(ratio.span(), Some("curve.ratio"), e.to_string())
        })?;
        let phase = match &c.phase {
            None => 0.0,
            Some(p) if p.get_ref().is_finite() => *p.get_ref(),
            Some(p) => {
                return Err(self.error(
                    p.span(),
                    Some("curve.phase"),
                    format!("must be a finite number of degrees, got {}", p.get_ref()),
                ));
            }
        };
        let g = GearedFiveBar::new(l1, l3, l4, l5, ratio, phase)
            .map_err(|e| self.error(entry.span(), Some("curve"), e.to_string()))?;
        Ok(Linkage::GearedFiveBar(g))
    }

    /// The `[[curve]]` entries: lengths > 0 and finite (input link = 1), finite point,
    /// a trace mode, and distinct names that can name files. An entry is a four-bar
    /// (`coupler`, `rocker`, `ground`) unless it says `mechanism = "geared-fivebar"`
    /// (`l1`, `l3`, `l4`, `l5`, `ratio`, `phase`, default 0).
    fn curves(&self, raw: &Spanned<Vec<Spanned<RawCurve>>>) -> Result<Vec<NamedCurve>, SpecError> {
        if raw.get_ref().is_empty() {
            return Err(self.error(
                raw.span(),
                Some("curve"),
                "the list of [[curve]] entries is empty".into(),
            ));
        }
        let mut out: Vec<NamedCurve> = Vec::new();
        for entry in raw.get_ref() {
            let c = entry.get_ref();
            let name = c.name.get_ref().trim().to_string();
            if name.is_empty() || name.chars().any(char::is_control) {
                return Err(self.error(
                    c.name.span(),
                    Some("curve.name"),
                    "name must be non-empty text (it titles the page)".into(),
                ));
            }
            if out.iter().any(|n| n.name == name) {
                return Err(self.error(
                    c.name.span(),
                    Some("curve.name"),
                    format!("`{name}` is used by an earlier [[curve]]"),
                ));
            }
            let linkage = self.curve_linkage(entry)?;
            for (x, key) in [(&c.u, "curve.u"), (&c.v, "curve.v")] {
                if !x.get_ref().is_finite() {
                    return Err(self.error(
                        x.span(),
                        Some(key),
                        format!("must be a finite number, got {}", x.get_ref()),
                    ));
                }
            }
            let trace = match &c.trace {
                None => TraceMode::Full,
                Some(t) if t.get_ref() == "full" => TraceMode::Full,
                Some(t) => TraceMode::Circuit(t.get_ref().parse().map_err(|_| {
                    self.error(
                        t.span(),
                        Some("curve.trace"),
                        format!("must be `full`, `open` or `crossed`, got `{}`", t.get_ref()),
                    )
                })?),
            };
            if let TraceMode::Circuit(circuit) = trace {
                let range = match &linkage {
                    Linkage::FourBar(l) => coupler_kinematics::input_range(l),
                    Linkage::GearedFiveBar(g) => g.input_range(),
                };
                if !matches!(range, coupler_kinematics::InputRange::Full) {
                    return Err(self.error(
                        c.trace.as_ref().map(|t| t.span()).unwrap_or(entry.span()),
                        Some("curve.trace"),
                        format!(
                            "`{circuit}` traces one circuit over a full turn of the input, but this linkage's input cannot turn fully (class {}): use `full`",
                            linkage.class().code()
                        ),
                    ));
                }
            }
            out.push(NamedCurve {
                name,
                linkage,
                point: CouplerPoint::new(*c.u.get_ref(), *c.v.get_ref()),
                trace,
            });
        }
        Ok(out)
    }
}

impl Spec {
    /// Parses and validates a grid spec; `source_name` is used in error messages. A
    /// full-curve page set (`[[curve]]` entries) is an error here: see [`AtlasSpec::parse`].
    pub fn parse(text: &str, source_name: &str) -> Result<Spec, SpecError> {
        match AtlasSpec::parse(text, source_name)? {
            AtlasSpec::Grid(spec) => Ok(*spec),
            AtlasSpec::Curves(_) => {
                let at = text.find("[[curve]]").unwrap_or(0);
                Err(Ctx {
                    name: source_name,
                    text,
                }
                .error(
                    at..at,
                    Some("curve"),
                    "this spec lists [[curve]] entries (a full-curve page set); a grid of [linkages] and [points] is needed here".into(),
                ))
            }
        }
    }

    /// The built-in default spec.
    pub fn default_atlas() -> Spec {
        Spec::parse(DEFAULT_SPEC_TEXT, DEFAULT_SPEC_SOURCE).expect("the built-in spec is valid")
    }

    /// Number of (A, B, C) combinations the ranges touch.
    pub fn combinations(&self) -> u64 {
        if let Some(g) = &self.geared {
            return g.combinations();
        }
        self.linkages.coupler.len() * self.linkages.rocker.len() * self.linkages.ground.len()
    }

    /// Enumerates the linkages: every (A, B, C) in the ranges (A outer, then B, then C,
    /// each ascending) that is a strict crank-rocker, and counts the others by class.
    /// This holds every linkage in memory: a run streams them instead
    /// ([`Spec::crank_rockers`]) and counts them arithmetically ([`Spec::count_linkages`]).
    pub fn enumerate(&self) -> Enumeration {
        if let Some(g) = &self.geared {
            let (linkages, skipped) = g.enumeration().clone();
            return Enumeration { linkages, skipped };
        }
        Enumeration {
            linkages: self.crank_rockers().collect(),
            skipped: self.skipped(),
        }
    }

    /// The strict crank-rockers in atlas order, one at a time (constant memory).
    pub fn crank_rockers(&self) -> CrankRockers {
        CrankRockers::new(&self.linkages)
    }

    /// The atlas's linkages in atlas order, one at a time: the strict crank-rockers of a
    /// four-bar grid (constant memory), or the fully turning five-bars of a `[geared]`
    /// grid (a geared grid is small: it is enumerated at once).
    pub fn atlas_linkages(&self) -> AtlasLinkages {
        match &self.geared {
            Some(g) => AtlasLinkages::Listed(g.enumeration().0.clone().into_iter()),
            None => AtlasLinkages::CrankRockers(Box::new(self.crank_rockers())),
        }
    }

    /// The number of the atlas's linkages: strict crank-rockers counted arithmetically
    /// (milliseconds, whatever the ranges: `docs/scale.md`), or a geared grid's fully
    /// turning five-bars.
    pub fn count_linkages(&self) -> u64 {
        match &self.geared {
            Some(g) => g.enumeration().0.len() as u64,
            None => count::count_crank_rockers(&self.linkages),
        }
    }

    /// The combinations that are not in the atlas, by class: for four-bars those that are
    /// not strict crank-rockers, by Barker class code, counted arithmetically (work grows
    /// with the number of coupler lengths A only); for a geared grid those whose input
    /// does not turn fully.
    pub fn skipped(&self) -> BTreeMap<String, u64> {
        if let Some(g) = &self.geared {
            return g.enumeration().1.clone();
        }
        count::count_by_class(&self.linkages)
            .into_iter()
            .filter(|(c, _)| *c != Class::Gcrr.code())
            .map(|(c, n)| (c.to_string(), n))
            .collect()
    }
}

/// The atlas's linkages in atlas order ([`Spec::atlas_linkages`]).
#[derive(Clone, Debug)]
pub enum AtlasLinkages {
    /// A four-bar grid's strict crank-rockers, made one at a time.
    CrankRockers(Box<CrankRockers>),
    /// A listed set (a geared grid's fully turning five-bars).
    Listed(std::vec::IntoIter<Linkage>),
}

impl Iterator for AtlasLinkages {
    type Item = Linkage;

    fn next(&mut self) -> Option<Linkage> {
        match self {
            AtlasLinkages::CrankRockers(c) => c.next(),
            AtlasLinkages::Listed(l) => l.next(),
        }
    }
}

/// The linkages a spec enumerates.
#[derive(Clone, Debug, PartialEq)]
pub struct Enumeration {
    /// The strict crank-rockers, in atlas order.
    pub linkages: Vec<Linkage>,
    /// Combinations skipped because they are not strict crank-rockers, by Barker class.
    pub skipped: BTreeMap<String, u64>,
}

/// The dotted path of the key a TOML/serde error points at: the enclosing `[table]`,
/// any inline tables open on the line before the error (`coupler = { start = …`), and the
/// last key assigned before it; for a `missing field` error, the missing field is
/// appended. Best effort: `None` when nothing key-like precedes the error.
fn error_key_path(text: &str, span: &Range<usize>, message: &str) -> Option<String> {
    let at = span.start.min(text.len());
    let line_start = text[..at].rfind('\n').map(|i| i + 1).unwrap_or(0);
    let line = &text[line_start..];
    let line = line.split('\n').next().unwrap_or("");
    let mut path: Vec<String> = Vec::new();
    let header = line.trim_start().starts_with('[');
    // serde reports a missing top-level table with an empty span at 0, or the whole text.
    let whole_document = span.start == 0 && (span.end == 0 || span.end >= text.trim_end().len());
    if whole_document {
        // An error about the document itself (e.g. a missing top-level table).
    } else if header {
        // The error is at a table header: the path is the header itself.
        let name = line.trim().trim_matches(['[', ']']).trim();
        if !name.is_empty() {
            path.push(name.to_string());
        }
    } else {
        if let Some(t) = text[..line_start]
            .lines()
            .rev()
            .map(str::trim)
            .find(|l| l.starts_with('[') && l.ends_with(']'))
        {
            path.push(t.trim_matches(['[', ']']).trim().to_string());
        }
        // Scan the line up to the error for `key =`, `{` and `}`.
        let upto = &text[line_start..at];
        let mut stack: Vec<String> = Vec::new();
        let mut ident = String::new();
        let mut last: Option<String> = None;
        let mut in_string = false;
        for ch in upto.chars() {
            if in_string {
                in_string = ch != '"';
                continue;
            }
            match ch {
                '"' => in_string = true,
                c if c.is_ascii_alphanumeric() || c == '_' || c == '-' => ident.push(c),
                '=' => {
                    if !ident.is_empty() {
                        last = Some(std::mem::take(&mut ident));
                    }
                }
                '{' => {
                    if let Some(k) = last.take() {
                        stack.push(k);
                    }
                }
                '}' => {
                    stack.pop();
                }
                c if c.is_whitespace() => {}
                _ => ident.clear(),
            }
        }
        path.extend(stack);
        if let Some(k) = last {
            path.push(k);
        } else {
            // The error is at a key itself (e.g. an unknown field): take the word there.
            let word: String = text[at..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '-')
                .collect();
            if !word.is_empty() {
                path.push(word);
            }
        }
    }
    if let Some(rest) = message.strip_prefix("missing field `") {
        if let Some(field) = rest.split('`').next() {
            path.push(field.to_string());
        }
    }
    (!path.is_empty()).then(|| path.join("."))
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUICK: &str = include_str!("../../../atlas-spec/quick.toml");
    const HD: &str = include_str!("../../../atlas-spec/hartenberg-denavit.toml");

    #[test]
    fn default_atlas_is_hrones_nelson_scale() {
        let spec = Spec::default_atlas();
        let e = spec.enumerate();
        let curves = e.linkages.len() as u64 * spec.points.len() * spec.circuits.len() as u64;
        assert!(curves >= 7000, "{curves}");
        assert_eq!(e.linkages.len(), 175);
        assert!(
            e.linkages
                .iter()
                .all(|l| l.four_bar().unwrap().is_crank_rocker())
        );
    }

    #[test]
    fn hartenberg_denavit_has_its_ten_crank_rockers() {
        let spec = Spec::parse(HD, "hd").unwrap();
        let got: Vec<(f64, f64, f64)> = spec
            .enumerate()
            .linkages
            .iter()
            .map(|l| {
                l.four_bar()
                    .map(|l| (l.coupler, l.rocker, l.ground))
                    .unwrap()
            })
            .collect();
        let mut want = Vec::new();
        for a in [2.0_f64, 3.0, 4.0] {
            for b in [2.0_f64, 3.0] {
                for c in 1..10 {
                    let c = c as f64;
                    if (a - b).abs() + 1.0 < c && c < a + b - 1.0 {
                        want.push((a, b, c));
                    }
                }
            }
        }
        assert_eq!(want.len(), 10);
        assert_eq!(got, want);
    }

    #[test]
    fn slices_of_the_grid_are_the_grid() {
        let spec = Spec::default_atlas();
        for a in [1.5, 3.0, 4.5] {
            let all = spec.points.points(a);
            assert_eq!(spec.points.points_in(a, 0, spec.points.len()), all);
            assert_eq!(spec.points.points_in(a, 7, 9), all[7..16].to_vec());
            // A slice that runs past the grid's end stops at it.
            let n = all.len();
            assert_eq!(
                spec.points.points_in(a, n as u64 - 3, 10),
                all[n - 3..].to_vec()
            );
        }
    }

    #[test]
    fn quick_is_small() {
        let spec = Spec::parse(QUICK, "quick").unwrap();
        let n =
            spec.enumerate().linkages.len() as u64 * spec.points.len() * spec.circuits.len() as u64;
        assert!(n > 0 && n < 200, "{n}");
    }

    fn err(text: &str) -> SpecError {
        Spec::parse(text, "t.toml").unwrap_err()
    }

    const GOOD: &str = "[atlas]\nname = \"t\"\n[linkages]\ncoupler = { start = 2, end = 3, step = 1 }\nrocker = { start = 2, end = 3, step = 1 }\nground = { start = 2, end = 3, step = 1 }\n[points]\nu = { start = 0, end = 1, step = 1 }\nv = { start = 0, end = 0, step = 1 }\n";

    #[test]
    fn good_spec_parses() {
        let s = Spec::parse(GOOD, "t.toml").unwrap();
        assert_eq!(s.points.len(), 2);
        assert_eq!(s.sampling.dash_deg, 10.0);
    }

    #[test]
    fn errors_name_line_and_key() {
        let e = err(&GOOD.replace(
            "rocker = { start = 2, end = 3, step = 1 }",
            "rocker = { start = 2, end = 3, step = 0 }",
        ));
        assert_eq!(
            (e.line, e.key.as_deref()),
            (5, Some("linkages.rocker.step")),
            "{e}"
        );
        assert!(e.to_string().starts_with("t.toml:5:"), "{e}");

        let e = err(&GOOD.replace(
            "ground = { start = 2, end = 3,",
            "ground = { start = 4, end = 3,",
        ));
        assert_eq!(
            (e.line, e.key.as_deref()),
            (6, Some("linkages.ground.end")),
            "{e}"
        );

        let e = err(&GOOD.replace("[points]\n", "[points]\ncolour = 3\n"));
        assert_eq!(
            (e.line, e.key.as_deref()),
            (8, Some("points.colour")),
            "{e}"
        );
        assert!(e.message.contains("colour"), "{e}");

        let e = err(&GOOD.replace(
            "start = 2, end = 3, step = 1 }\nrocker",
            "start = \"2\", end = 3, step = 1 }\nrocker",
        ));
        assert_eq!(e.line, 4, "{e}");

        let e = err(&GOOD.replace(
            "u = { start = 0, end = 1, step = 1 }",
            "u = { start = 0, end = nan, step = 1 }",
        ));
        assert_eq!((e.line, e.key.as_deref()), (8, Some("points.u.end")), "{e}");

        let e = err(&GOOD.replace("coupler = { start = 2,", "coupler = { start = -2,"));
        assert_eq!(e.key.as_deref(), Some("linkages.coupler.start"), "{e}");

        let e = err(&format!("{GOOD}[sampling]\ndash_deg = 7\n"));
        assert_eq!(
            (e.line, e.key.as_deref()),
            (11, Some("sampling.dash_deg")),
            "{e}"
        );

        let e = err(&format!("{GOOD}[pages]\nsize = \"b5\"\n"));
        assert_eq!(e.key.as_deref(), Some("pages.size"), "{e}");

        let e = err(&GOOD.replace("[points]", "[pointz]"));
        assert!(e.message.contains("pointz"), "{e}");

        let e = err("[atlas\nname = 1");
        assert_eq!(e.line, 1, "{e}");

        let e = err(&GOOD.replace("coupler = { start = 2,", "coupler = { start = \"2\","));
        assert_eq!(
            (e.line, e.key.as_deref()),
            (4, Some("linkages.coupler.start")),
            "{e}"
        );

        let e = err(&GOOD.replace("ground = { start = 2, end = 3, step = 1 }\n", ""));
        assert_eq!(e.key.as_deref(), Some("linkages.ground"), "{e}");

        let e = err(&format!("{GOOD}[plots]\nx = 1\n"));
        assert_eq!((e.line, e.key.as_deref()), (10, Some("plots")), "{e}");
    }
}

#[cfg(test)]
mod curve_list_tests {
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
