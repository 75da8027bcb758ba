//! Searching a full-curve page set (`curves.json`, written by `generate` on a spec of
//! `[[curve]]` entries such as `atlas-spec/classics.toml`). Its curves have no pseudo-arcs
//! or feature windows on a crank turn (many do not turn fully); what a page set measures
//! is each curve's longest straight run at ε_S ≤ 1 %, 0.1 % and 0.01 %. Those runs are the
//! curve's straight segments here; a query tolerance that is not one of the three is
//! answered exactly by re-measuring the run at it (a page set is a handful of curves:
//! tracing them again takes milliseconds).

use crate::search::{CurveRow, SearchError, SearchTable, SegmentRow};
use coupler_features::{
    ClassicCurve, NamedCurve, STRAIGHTNESS_TOLERANCES, StraightMeasure, TraceMode, Trivial,
};
use coupler_kinematics::{
    Circuit, CouplerPoint, FourBar, GearRatio, GearedFiveBar, Linkage, LinkageClass,
};
use serde_json::Value;

/// The `kind` of a page set's `curves.json`.
pub const PAGE_SET_KIND: &str = "full-curve page set";

/// Whether `text` starts like a page set's `curves.json` (its `kind` key).
pub fn is_page_set(text: &str) -> bool {
    text.chars()
        .take(4096)
        .collect::<String>()
        .contains(&format!("\"kind\": \"{PAGE_SET_KIND}\""))
}

impl SearchTable {
    /// The search table of a page set: one row per curve, its straight runs as segments
    /// (at 1 %, 0.1 %, 0.01 %, and at `straight_pct` too when given and not one of them,
    /// re-measured). Rows carry no arcs and no transmission range (NaN: a
    /// `--min-transmission` filter matches none); `circuit` is the traced circuit (open for
    /// `"full"`, which traces both).
    pub fn from_page_set(
        text: &str,
        straight_pct: Option<f64>,
    ) -> Result<SearchTable, SearchError> {
        let header = |m: &str| SearchError::Header(format!("curves.json: {m}"));
        let v: Value = serde_json::from_str(text).map_err(|e| header(&e.to_string()))?;
        if v["kind"] != PAGE_SET_KIND || v["schema_version"] != 1 {
            return Err(header("not a full-curve page set of schema version 1"));
        }
        let step = v["sampling"]["crank_step_deg"]
            .as_f64()
            .ok_or_else(|| header("no sampling.crank_step_deg"))?;
        let curves = v["curves"].as_array().ok_or_else(|| header("no curves"))?;
        let extra = straight_pct
            .map(|p| p / 100.0)
            .filter(|t| t.is_finite() && !STRAIGHTNESS_TOLERANCES.contains(t));
        let mut t = SearchTable::default();
        for (n, c) in curves.iter().enumerate() {
            let bad = |m: &str| SearchError::Line {
                line: n + 1,
                message: format!("curves.json curve {}: {m}", n + 1),
            };
            let num = |x: &Value, k: &str| x[k].as_f64().ok_or_else(|| bad(&format!("no {k}")));
            // A four-bar's {coupler, rocker, ground} or a geared five-bar's
            // {l1, l3, l4, l5, ratio, phase}, as curves.json records them.
            let l = &c["linkage"];
            let linkage: Linkage = if l.get("l1").is_some() {
                let ratio: GearRatio = l["ratio"]
                    .as_str()
                    .ok_or_else(|| bad("no ratio"))?
                    .parse()
                    .map_err(|e: coupler_kinematics::GearedError| bad(&e.to_string()))?;
                GearedFiveBar::new(
                    num(l, "l1")?,
                    num(l, "l3")?,
                    num(l, "l4")?,
                    num(l, "l5")?,
                    ratio,
                    num(l, "phase")?,
                )
                .map_err(|e| bad(&e.to_string()))?
                .into()
            } else {
                FourBar::new(num(l, "coupler")?, num(l, "rocker")?, num(l, "ground")?)
                    .map_err(|e| bad(&e.to_string()))?
                    .into()
            };
            let point = CouplerPoint::new(num(&c["point"], "u")?, num(&c["point"], "v")?);
            let trace = match c["trace"].as_str() {
                Some("full") => TraceMode::Full,
                Some(s) => TraceMode::Circuit(s.parse::<Circuit>().map_err(|e| bad(&e))?),
                None => return Err(bad("no trace")),
            };
            let class: LinkageClass = c["class"]
                .as_str()
                .ok_or_else(|| bad("no class"))?
                .parse()
                .map_err(|e: String| bad(&e))?;
            let mut runs: Vec<StraightMeasure> = c["straight"]
                .as_array()
                .ok_or_else(|| bad("no straight"))?
                .iter()
                .filter(|s| !s.is_null())
                .map(|s| serde_json::from_value::<StraightRun>(s.clone()).map(StraightRun::into))
                .collect::<Result<_, _>>()
                .map_err(|e| bad(&e.to_string()))?;
            if let Some(tol) = extra {
                let named = NamedCurve {
                    name: String::new(),
                    linkage,
                    point,
                    trace,
                };
                runs.extend(ClassicCurve::compute(&named, step).straight_at(tol));
            }
            let page = c["page"]["file"].as_str().map(|f| {
                let b = &c["page"]["bbox_px"];
                let px = |k: usize| b[k].as_f64().unwrap_or(0.0);
                (f.to_string(), [px(0), px(1), px(2), px(3)])
            });
            let page_index = match &page {
                Some((file, _)) => match t.pages.iter().position(|p| p == file) {
                    Some(i) => i as u32,
                    None => {
                        t.pages.push(file.clone());
                        (t.pages.len() - 1) as u32
                    }
                },
                None => u32::MAX,
            };
            t.rows.push(CurveRow {
                id: c["id"].as_u64().unwrap_or(n as u64),
                linkage,
                point: [point.u, point.v],
                circuit: match trace {
                    TraceMode::Circuit(c) => c,
                    TraceMode::Full => Circuit::Open,
                },
                class,
                transmission_deg: [f64::NAN; 2],
                page: page_index,
                page_bbox: page.map_or([0.0; 4], |p| p.1),
                seg_start: t.segments.len() as u32,
                seg_count: runs.len() as u32,
                arc_start: t.arcs.len() as u32,
                arc_count: 0,
                symmetric: false,
                crunodes: 0,
                cusps: 0,
                has_features: true,
                trivial: Trivial::of_linkage(point, &linkage).is_some(),
            });
            t.segments.extend(runs.iter().map(|r| {
                let [a, b] = r.ends;
                SegmentRow {
                    start_deg: r.input_deg[0],
                    span_deg: r.input_span_deg,
                    straightness_pct: r.straightness * 100.0,
                    velocity_variation_pct: f64::NAN,
                    length: r.extent,
                    direction_deg: (b[1] - a[1]).atan2(b[0] - a[0]).to_degrees(),
                    transmission_deg: [f64::NAN; 2],
                }
            }));
        }
        Ok(t)
    }
}

/// A run as `curves.json` writes it ([`StraightMeasure`]).
#[derive(serde::Deserialize)]
struct StraightRun {
    tolerance: f64,
    branch: usize,
    samples: [usize; 2],
    input_deg: [f64; 2],
    input_span_deg: f64,
    extent: f64,
    straightness: f64,
    ends: [[f64; 2]; 2],
}

impl From<StraightRun> for StraightMeasure {
    fn from(r: StraightRun) -> StraightMeasure {
        StraightMeasure {
            tolerance: r.tolerance,
            branch: r.branch,
            samples: r.samples,
            input_deg: r.input_deg,
            input_span_deg: r.input_span_deg,
            extent: r.extent,
            straightness: r.straightness,
            ends: r.ends,
        }
    }
}
