//! Property tests of the parsers that read user input (the same targets are fuzzed with
//! cargo-fuzz in `fuzz/`): no input makes them panic, and every error is located.

use coupler_atlas::{AtlasSpec, Decimal, Index, Spec};
use proptest::prelude::*;

const QUICK: &str = include_str!("../atlas-spec/quick.toml");
const HD: &str = include_str!("../atlas-spec/hartenberg-denavit.toml");
const CLASSICS: &str = include_str!("../atlas-spec/classics.toml");

/// A valid spec with one edit: a byte replaced, a line dropped or duplicated, or text
/// inserted — the kind of damage hand-written specs get.
fn mutated_spec() -> impl Strategy<Value = String> {
    let base = prop_oneof![
        Just(QUICK.to_string()),
        Just(HD.to_string()),
        Just(CLASSICS.to_string())
    ];
    (
        base,
        0usize..4,
        any::<prop::sample::Index>(),
        "[ -~\n]{0,12}",
    )
        .prop_map(|(text, op, at, insert)| {
            let lines: Vec<&str> = text.lines().collect();
            match op {
                0 => {
                    let mut b = text.clone().into_bytes();
                    let i = at.index(b.len());
                    b[i] = insert.bytes().next().unwrap_or(b'#');
                    String::from_utf8_lossy(&b).into_owned()
                }
                1 => {
                    let i = at.index(lines.len());
                    lines
                        .iter()
                        .enumerate()
                        .filter(|&(k, _)| k != i)
                        .map(|(_, l)| *l)
                        .collect::<Vec<_>>()
                        .join("\n")
                }
                2 => {
                    let i = at.index(lines.len());
                    let mut l = lines.clone();
                    l.insert(i, lines[i]);
                    l.join("\n")
                }
                _ => {
                    let i = at.index(text.len());
                    let i = (0..=i)
                        .rev()
                        .find(|&k| text.is_char_boundary(k))
                        .unwrap_or(0);
                    format!("{}{insert}{}", &text[..i], &text[i..])
                }
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1500, ..ProptestConfig::default() })]

    #[test]
    fn spec_parser_never_panics_and_locates_errors(text in mutated_spec()) {
        match AtlasSpec::parse(&text, "fuzz.toml") {
            Ok(AtlasSpec::Grid(spec)) => {
                // Whatever parses must also enumerate without panicking.
                let _ = spec.enumerate();
            }
            Ok(AtlasSpec::Curves(list)) => {
                // Every curve of a page set that parses has a valid linkage and point.
                for c in &list.curves {
                    prop_assert!(c.linkage.four_bar().is_some_and(|l| l.coupler > 0.0) && c.point.u.is_finite(), "{c:?}");
                }
            }
            Err(e) => {
                let lines = text.lines().count().max(1);
                prop_assert!(e.line >= 1 && e.line <= lines + 1, "line {} of {lines}: {e}", e.line);
                prop_assert!(e.to_string().starts_with("fuzz.toml:"), "{e}");
            }
        }
    }

    #[test]
    fn spec_parser_survives_arbitrary_text(text in "[ -~\n\t]{0,200}") {
        let _ = Spec::parse(&text, "fuzz.toml");
        let _ = AtlasSpec::parse(&text, "fuzz.toml");
    }

    #[test]
    fn decimal_parser_round_trips(m in -1_000_000_000_000i64..1_000_000_000_000, e in -30i32..30) {
        let d = Decimal::new(m as i128, e);
        let back: Decimal = d.to_string().parse().unwrap();
        prop_assert_eq!(back, d);
    }

    #[test]
    fn decimal_parser_never_panics(text in "[-+0-9.eE_a-z ]{0,40}") {
        let _ = text.parse::<Decimal>();
    }

    #[test]
    fn index_reader_survives_truncation_and_damage(cut in any::<prop::sample::Index>(), flip in any::<prop::sample::Index>(), byte in any::<u8>()) {
        let index = small_index();
        // Cut at least the closing `}\n` (dropping only the final newline leaves valid JSON).
        let cut = cut.index(index.len() - 2);
        prop_assert!(Index::from_slice(&index[..cut]).is_err(), "a truncated index must be refused");
        let mut damaged = index.clone();
        let i = flip.index(damaged.len());
        damaged[i] = byte;
        let _ = Index::from_slice(&damaged);
    }
}

fn small_index() -> Vec<u8> {
    use std::sync::OnceLock;
    static INDEX: OnceLock<Vec<u8>> = OnceLock::new();
    INDEX
        .get_or_init(|| {
            let out = Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
                .args([
                    "generate",
                    concat!(env!("CARGO_MANIFEST_DIR"), "/atlas-spec/quick.toml"),
                    "--no-pages",
                    "--quiet",
                    "--out",
                ])
                .arg(
                    std::env::temp_dir()
                        .join(format!("coupler-atlas-parsers-{}", std::process::id())),
                )
                .output()
                .unwrap();
            assert!(out.status.success());
            let dir =
                std::env::temp_dir().join(format!("coupler-atlas-parsers-{}", std::process::id()));
            let bytes = std::fs::read(dir.join("index.json")).unwrap();
            let _ = std::fs::remove_dir_all(&dir);
            assert!(Index::from_slice(&bytes).is_ok());
            bytes
        })
        .clone()
}

use std::process::Command;
