//! `search`: every result satisfies its filters according to the index itself, no curve
//! that satisfies them is missed, and the Hoeken linkage is found by `--straight`.

use coupler_atlas::{Circuit, Class, FourBar, IndexCurve, LinkageClass};
use coupler_atlas::{Query, SearchTable, SortKey, SpanFilter};
use proptest::prelude::*;
mod common;

use std::path::PathBuf;
use std::process::Command;
use std::sync::OnceLock;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
}

/// A small atlas that holds the Hoeken linkage (A = B = 2.5, C = 2, u = 2A, v = 0).
const SPEC: &str = r#"
[atlas]
name = "search-test"

[linkages]
coupler = { start = 2.5, end = 3.0, step = 0.5 }
rocker  = { start = 2.5, end = 3.0, step = 0.5 }
ground  = { start = 2.0, end = 3.0, step = 0.5 }
circuits = ["open", "crossed"]

[points]
u = { start = -0.5, end = 2.0, step = 0.5, relative = true }
v = { start = -0.5, end = 0.5, step = 0.5, relative = true }

[sampling]
crank_step_deg = 2.0
"#;

fn atlas() -> &'static (PathBuf, Vec<IndexCurve>, SearchTable) {
    static ATLAS: OnceLock<(PathBuf, Vec<IndexCurve>, SearchTable)> = OnceLock::new();
    ATLAS.get_or_init(|| {
        // Held by a static and never removed: kept in the build's scratch folder.
        let dir = common::shared_scratch("coupler-atlas-search-test");
        let spec = dir.join("spec.toml");
        std::fs::write(&spec, SPEC).unwrap();
        let out = dir.join("atlas");
        let st = bin()
            .args([
                "generate",
                spec.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--no-pages",
                "-q",
            ])
            .output()
            .unwrap();
        assert!(
            st.status.success(),
            "{}",
            String::from_utf8_lossy(&st.stderr)
        );
        let index = out.join("index.json");
        let text = std::fs::read_to_string(&index).unwrap();
        let curves = coupler_atlas::Index::from_slice(text.as_bytes())
            .unwrap()
            .curves;
        let table = SearchTable::from_index_text(&text).unwrap();
        (index, curves, table)
    })
}

/// Does curve `c` satisfy `q`, reading the index record directly?
fn satisfies(c: &IndexCurve, q: &Query) -> bool {
    let f = c.features.as_ref().unwrap();
    // The window's transmission, as the index writes it: [min, max] within [m, 180 − m].
    let window_ok = |tr: Option<[f64; 2]>| {
        q.min_window_transmission_deg.is_none_or(|m| {
            let [lo, hi] = tr.expect("the index has each window's transmission");
            lo >= m && hi <= 180.0 - m
        })
    };
    let seg_ok = |s: &coupler_atlas::StraightSegment| {
        window_ok(s.transmission_deg)
            && q.straight.is_none_or(|p| {
                s.span_deg >= p.min_span_deg && s.straightness_pct <= p.max_error_pct
            })
            && q.max_velocity_variation_pct
                .is_none_or(|m| s.velocity_variation_pct <= m)
    };
    let arc_ok = |a: &coupler_atlas::PseudoArc| {
        window_ok(a.transmission_deg)
            && q.arc
                .is_none_or(|p| a.span_deg >= p.min_span_deg && a.deviation_pct <= p.max_error_pct)
            && q.radius
                .is_none_or(|[lo, hi]| lo <= a.radius && a.radius <= hi)
            && q.min_turn_deg.is_none_or(|m| a.turn_deg >= m)
    };
    let segs: Vec<_> = f.straight_segments.iter().filter(|s| seg_ok(s)).collect();
    let arcs: Vec<_> = f.pseudo_arcs.iter().filter(|a| arc_ok(a)).collect();
    let mut ok = true;
    let want_straight = q.straight.is_some() || q.max_velocity_variation_pct.is_some();
    let want_arc = q.arc.is_some() || q.radius.is_some() || q.min_turn_deg.is_some();
    ok &= !want_straight || !segs.is_empty();
    ok &= !want_arc || !arcs.is_empty();
    // Alone, the window's transmission asks for a segment or an arc passing it.
    if q.min_window_transmission_deg.is_some() && !(want_straight || want_arc || q.double_dwell) {
        ok &= !segs.is_empty() || !arcs.is_empty();
    }
    // The index's own flag: curves of a pin are left out unless asked for.
    ok &= q.include_trivial || f.trivial.is_none();
    if q.double_dwell {
        let pair = arcs.iter().enumerate().any(|(i, a)| {
            arcs[i + 1..].iter().any(|b| {
                (a.radius - b.radius).abs() <= q.radius_tol_pct / 100.0 * a.radius.max(b.radius)
                    && a.concave == b.concave
            })
        });
        ok &= segs.len() >= 2 || pair;
    }
    if let Some(m) = q.min_transmission_deg {
        ok &= c.transmission_deg[0] >= m && c.transmission_deg[1] <= 180.0 - m;
    }
    ok &= q.class.is_none_or(|k| k == c.class);
    ok &= q.circuit.is_none_or(|k| k == c.circuit);
    ok &= q.symmetric <= f.symmetry.is_some();
    if let Some(l) = q.linkage {
        let c = c.linkage.four_bar().expect("a four-bar atlas");
        let l = l.four_bar().expect("a four-bar query");
        ok &= (c.coupler - l.coupler).abs() <= 1e-9
            && (c.rocker - l.rocker).abs() <= 1e-9
            && (c.ground - l.ground).abs() <= 1e-9;
    }
    ok
}

fn span_filter() -> impl Strategy<Value = Option<SpanFilter>> {
    prop_oneof![
        Just(None),
        (0.0..200.0f64, prop_oneof![Just(f64::INFINITY), 0.0..0.6f64]).prop_map(|(s, t)| Some(
            SpanFilter {
                min_span_deg: s,
                max_error_pct: t
            }
        )),
    ]
}

fn query() -> impl Strategy<Value = Query> {
    (
        span_filter(),
        span_filter(),
        any::<bool>(),
        prop_oneof![Just(None), (0.0..60.0f64).prop_map(Some)],
        prop_oneof![
            Just(None),
            Just(Some(Circuit::Open)),
            Just(Some(Circuit::Crossed))
        ],
        any::<bool>(),
        prop_oneof![
            Just(None),
            Just(Some(FourBar::new(2.5, 2.5, 2.0).unwrap().into())),
            Just(Some(FourBar::new(3.0, 2.5, 3.0).unwrap().into()))
        ],
        prop_oneof![Just(None), Just(Some(Class::Gcrr))],
        (
            any::<bool>(),
            prop_oneof![
                Just(None),
                (0.0..5.0f64, 0.0..20.0f64).prop_map(|(a, w)| Some([a, a + w]))
            ],
            prop_oneof![Just(None), (0.0..60.0f64).prop_map(Some)],
            prop_oneof![Just(None), (0.0..20.0f64).prop_map(Some)],
            prop_oneof![Just(None), (0.0..70.0f64).prop_map(Some)],
        ),
    )
        .prop_map(
            |(
                straight,
                arc,
                double_dwell,
                mt,
                circuit,
                symmetric,
                linkage,
                class,
                (include_trivial, radius, min_turn_deg, max_ev, window_mt),
            )| Query {
                straight,
                arc,
                double_dwell,
                radius_tol_pct: 2.0,
                min_transmission_deg: mt,
                min_window_transmission_deg: window_mt,
                class: class.map(LinkageClass::from),
                linkage,
                circuit,
                symmetric,
                include_trivial,
                radius,
                min_turn_deg,
                max_velocity_variation_pct: max_ev,
                sort: SortKey::Id,
                limit: 0,
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// Sound and complete: hits are exactly the curves that satisfy the query.
    #[test]
    fn results_satisfy_their_filters(q in query()) {
        let (_, curves, table) = atlas();
        let hits: Vec<u64> = table.search(&q).iter().map(|h| table.rows[h.row].id).collect();
        let expect: Vec<u64> = curves.iter().filter(|c| satisfies(c, &q)).map(|c| c.id).collect();
        prop_assert_eq!(hits, expect);
    }
}

#[test]
fn cache_round_trip() {
    let (_, _, table) = atlas();
    let key = |bytes, hash| coupler_atlas::IndexKey { bytes, hash };
    let bytes = table.to_cache_bytes(key(1, 2));
    assert_eq!(
        &SearchTable::from_cache_bytes(&bytes, key(1, 2)).unwrap(),
        table
    );
    // Another index (same length, other content), and a cut cache, are refused.
    assert!(SearchTable::from_cache_bytes(&bytes, key(1, 3)).is_err());
    assert!(SearchTable::from_cache_bytes(&bytes[..bytes.len() - 1], key(1, 2)).is_err());
}

/// docs/conventions.md §7: `search --straight` finds the Hoeken linkage, point (5, 0).
#[test]
fn hoeken_is_found_by_straight() {
    let (index, _, _) = atlas();
    let out = bin()
        .args([
            "search",
            index.to_str().unwrap(),
            "--straight",
            "120:0.5",
            "--format",
            "json",
            "--limit",
            "0",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let hits = j["hits"].as_array().unwrap();
    assert_eq!(j["total"].as_u64().unwrap() as usize, hits.len());
    let hoeken = hits.iter().find(|h| {
        h["linkage"] == serde_json::json!({"coupler": 2.5, "rocker": 2.5, "ground": 2.0})
            && h["point"] == serde_json::json!({"u": 5.0, "v": 0.0})
            && h["circuit"] == "open"
    });
    let h = hoeken.unwrap_or_else(|| panic!("Hoeken not among {} hits", hits.len()));
    let seg = &h["straight_segments"][0];
    assert!(seg["span_deg"].as_f64().unwrap() >= 120.0);
    assert!(seg["straightness_pct"].as_f64().unwrap() <= 0.5);
    // The table format runs too, from the columns `generate` wrote beside the index.
    let out = bin()
        .args(["search", index.to_str().unwrap(), "--straight", "120:0.5"])
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("from columns"));
}

/// `dwell --index --curve --arc K` designs from the indexed arc: its dwell is that arc's window.
#[test]
fn dwell_from_an_indexed_arc() {
    let (index, curves, _) = atlas();
    let mut designed = 0;
    for c in curves.iter().filter(|c| c.point.v != 0.0).take(12) {
        let f = c.features.as_ref().unwrap();
        for (k, arc) in f.pseudo_arcs.iter().enumerate() {
            let out = bin()
                .args([
                    "dwell",
                    "--index",
                    index.to_str().unwrap(),
                    "--curve",
                    &c.id.to_string(),
                    "--arc",
                ])
                .arg((k + 1).to_string())
                .args(["--format", "json"])
                .output()
                .unwrap();
            match out.status.code() {
                Some(0) => {
                    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
                    assert_eq!(j["dwells"][0]["span_deg"].as_f64().unwrap(), arc.span_deg);
                    assert_eq!(
                        j["dwells"][0]["start_deg"].as_f64().unwrap(),
                        arc.start_deg % 360.0
                    );
                    designed += 1;
                }
                // a design that cannot be built is a clear usage error, never a crash
                code => assert_eq!(code, Some(2), "{}", String::from_utf8_lossy(&out.stderr)),
            }
        }
    }
    assert!(designed >= 3, "only {designed} designs");
}

/// Trivial curves (the crank pin's circle, the rocker pin's arc) are perfect arcs, so an
/// arc search sorted by deviation used to list them all first. They are left out unless
/// `--include-trivial`; the total of matches is in the JSON and on stderr.
#[test]
fn trivial_curves_are_left_out_unless_asked() {
    let (index, curves, _) = atlas();
    let run = |extra: &[&str]| -> serde_json::Value {
        let out = bin()
            .args([
                "search",
                index.to_str().unwrap(),
                "--arc",
                "60:0.5",
                "--sort",
            ])
            .args(["deviation", "--format", "json", "--limit", "5"])
            .args(extra)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let err = String::from_utf8_lossy(&out.stderr);
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert!(
            err.contains(&format!("5 of {} matching curve(s) shown", j["total"])),
            "{err}"
        );
        j
    };
    let pin = |h: &serde_json::Value| {
        let (u, v) = (
            h["point"]["u"].as_f64().unwrap(),
            h["point"]["v"].as_f64().unwrap(),
        );
        v == 0.0 && (u == 0.0 || u == h["linkage"]["coupler"].as_f64().unwrap())
    };
    let pins = curves
        .iter()
        .filter(|c| c.features.as_ref().unwrap().trivial.is_some())
        .count();
    let mut groups: Vec<String> = curves
        .iter()
        .map(|c| format!("{:?} {}", c.linkage, c.circuit))
        .collect();
    groups.dedup();
    assert_eq!(
        pins,
        2 * groups.len(),
        "a crank pin and a rocker pin per group"
    );
    let without = run(&[]);
    let with = run(&["--include-trivial"]);
    assert!(without["hits"].as_array().unwrap().iter().all(|h| !pin(h)));
    // With them, the exact circles and arcs come first.
    assert!(with["hits"].as_array().unwrap().iter().all(pin));
    assert!(with["total"].as_u64().unwrap() > without["total"].as_u64().unwrap());
}

/// A tolerance tighter than the index's extraction tolerance is answered without
/// regenerating (candidates re-measured at query time), and the answer equals that of an
/// atlas generated at the tighter tolerance: `quick.toml` at the default 0.5 % against a
/// copy extracted at 0.2 %.
#[test]
fn tighter_tolerance_equals_regenerating() {
    let dir = std::env::temp_dir().join(format!("coupler-atlas-refine-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let quick = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("atlas-spec/quick.toml"),
    )
    .unwrap();
    let tight = dir.join("tight.toml");
    std::fs::write(
        &tight,
        format!("{quick}\n[features]\nstraight_pct = 0.2\narc_pct = 0.2\n"),
    )
    .unwrap();
    let generate = |spec: &std::path::Path, out: &str| {
        let out = dir.join(out);
        let st = bin()
            .arg("generate")
            .arg(spec)
            .arg("--out")
            .arg(&out)
            .args(["--no-pages", "-q"])
            .output()
            .unwrap();
        assert!(
            st.status.success(),
            "{}",
            String::from_utf8_lossy(&st.stderr)
        );
        out
    };
    let loose = generate(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("atlas-spec/quick.toml"),
        "loose",
    );
    let tight = generate(&tight, "tight");
    let search = |atlas: &std::path::Path, q: &[&str]| -> (serde_json::Value, String) {
        let out = bin()
            .arg("search")
            .arg(atlas)
            .args(q)
            .args(["--format", "json", "--limit", "0", "--include-trivial"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        (
            serde_json::from_slice(&out.stdout).unwrap(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let mut nonempty = 0;
    for q in [
        &["--straight", "30:0.2"][..],
        &["--arc", "60:0.2"],
        &["--arc", "40:0.1", "--sort", "deviation"],
        &[
            "--straight",
            "30:0.15",
            "--arc",
            "30:0.2",
            "--sort",
            "straight",
        ],
    ] {
        let (a, note) = search(&loose, q);
        let (b, _) = search(&tight, q);
        assert!(note.contains("refined"), "{q:?}: {note}");
        assert_eq!(a, b, "{q:?}");
        nonempty += (a["total"].as_u64().unwrap() > 0) as usize;
    }
    assert!(nonempty >= 3, "the queries must find something");
    let _ = std::fs::remove_dir_all(&dir);
}
