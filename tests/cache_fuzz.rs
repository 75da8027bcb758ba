//! The search cache is never trusted: random damage (1–3 bytes changed, cut, grown),
//! damage with the checksums recomputed (a crafted file), a cache of another index of the
//! same size and time, and corrupted counts read by `search` and `dwell --index` — every
//! case answers exactly as the index itself does (or rebuilds), and nothing panics or
//! aborts. Time-boxed and seeded: `COUPLER_FUZZ_SECONDS` (default 3) and
//! `COUPLER_FUZZ_SEED` (default fixed) change the budget and the seed.

use coupler_atlas::{IndexKey, Query, SearchTable, SortKey, SpanFilter, cache_path, load_table};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_coupler-atlas");

/// A small atlas with pages (so every column has content): its index path and bytes.
fn atlas() -> &'static (PathBuf, Vec<u8>) {
    static ATLAS: OnceLock<(PathBuf, Vec<u8>)> = OnceLock::new();
    ATLAS.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("coupler-fuzz-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("atlas-spec/quick.toml");
        let o = Command::new(BIN)
            .args([
                "generate",
                spec.to_str().unwrap(),
                "--dpi",
                "36",
                "--quiet",
                "--out",
            ])
            .arg(&dir)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let index = dir.join("index.json");
        let bytes = std::fs::read(&index).unwrap();
        (index, bytes)
    })
}

struct Rng(u64);

impl Rng {
    fn seeded() -> Rng {
        let seed = std::env::var("COUPLER_FUZZ_SEED")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(0x5eed_cafe_f00d_1234);
        eprintln!("cache fuzz seed {seed}");
        Rng(seed | 1)
    }
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

fn budget() -> Duration {
    let secs: f64 = std::env::var("COUPLER_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3.0);
    Duration::from_secs_f64(secs)
}

fn key_of(bytes: &[u8]) -> IndexKey {
    IndexKey::of_reader(bytes).unwrap()
}

/// Damages `b`: 1–3 bytes changed (a third of the time in the header and section table,
/// where lengths and offsets live), or cut, or grown.
fn damage(rng: &mut Rng, b: &mut Vec<u8>) {
    match rng.below(10) {
        0..=6 => {
            for _ in 0..1 + rng.below(3) {
                let at = if rng.below(3) == 0 {
                    rng.below(b.len().min(640))
                } else {
                    rng.below(b.len())
                };
                let old = b[at];
                while b[at] == old {
                    b[at] = rng.next() as u8;
                }
            }
        }
        7 | 8 => {
            let cut = rng.below(b.len());
            b.truncate(cut);
        }
        _ => {
            for _ in 0..1 + rng.below(100) {
                b.push(rng.next() as u8);
            }
        }
    }
}

/// Recomputes the container's checksums (payload, then header) after a change, as a
/// crafted file would: the checks behind them must hold on their own.
fn reseal(b: &mut [u8]) {
    if b.len() < 128 {
        return;
    }
    let n = u32::from_le_bytes(b[24..28].try_into().unwrap()) as usize;
    let off = u64::from_le_bytes(b[56..64].try_into().unwrap()) as usize;
    if n > 64 || off > b.len() || 128 + 32 * n > b.len() {
        return;
    }
    let payload = xxhash_rust::xxh3::xxh3_128(&b[off..]);
    b[72..88].copy_from_slice(&payload.to_le_bytes());
    let mut head = b[..88].to_vec();
    head.extend_from_slice(&b[128..128 + 32 * n]);
    let h = xxhash_rust::xxh3::xxh3_64(&head);
    b[88..96].copy_from_slice(&h.to_le_bytes());
}

fn queries() -> Vec<Query> {
    let f = |s: &str| s.parse::<SpanFilter>().unwrap();
    vec![
        Query::default(),
        Query {
            straight: Some(f("20:1")),
            sort: SortKey::Straight,
            limit: 5,
            ..Query::default()
        },
        Query {
            arc: Some(f("30:2")),
            sort: SortKey::Deviation,
            ..Query::default()
        },
        Query {
            double_dwell: true,
            radius_tol_pct: 5.0,
            sort: SortKey::Arc,
            ..Query::default()
        },
        Query {
            min_transmission_deg: Some(30.0),
            sort: SortKey::Transmission,
            limit: 3,
            ..Query::default()
        },
    ]
}

/// Random damage: every cache that is accepted is exactly the original table.
#[test]
fn random_damage_is_refused_or_harmless() {
    let (_, index) = atlas();
    let table = SearchTable::from_index_text(std::str::from_utf8(index).unwrap()).unwrap();
    let key = key_of(index);
    let good = table.to_cache_bytes(key);
    assert_eq!(SearchTable::from_cache_bytes(&good, key).unwrap(), table);
    let mut rng = Rng::seeded();
    let (start, budget) = (Instant::now(), budget());
    let (mut tried, mut accepted) = (0u64, 0u64);
    while start.elapsed() < budget {
        let mut b = good.clone();
        damage(&mut rng, &mut b);
        tried += 1;
        if let Ok(t) = SearchTable::from_cache_bytes(&b, key) {
            accepted += 1;
            assert_eq!(t, table, "iteration {tried}: a damaged cache was served");
        }
    }
    eprintln!("{tried} damaged caches, {accepted} accepted (equal to the original)");
    assert!(tried > 100, "only {tried} iterations");
}

/// Damage with the checksums recomputed: never a panic or an abort, and any table that
/// is accepted can be searched (its cross-references were checked).
#[test]
fn crafted_caches_never_panic() {
    let (_, index) = atlas();
    let table = SearchTable::from_index_text(std::str::from_utf8(index).unwrap()).unwrap();
    let key = key_of(index);
    let good = table.to_cache_bytes(key);
    let mut rng = Rng::seeded();
    let (start, budget) = (Instant::now(), budget());
    let (mut tried, mut accepted) = (0u64, 0u64);
    while start.elapsed() < budget {
        let mut b = good.clone();
        // Mostly counts, offsets and sizes (header and section table), else anywhere.
        for _ in 0..1 + rng.below(3) {
            let at = if rng.below(2) == 0 {
                16 + rng.below(b.len().min(640) - 16)
            } else {
                rng.below(b.len())
            };
            b[at] = match rng.below(4) {
                0 => 0xff,
                1 => 0,
                _ => rng.next() as u8,
            };
        }
        reseal(&mut b);
        tried += 1;
        if let Ok(t) = SearchTable::from_cache_bytes(&b, key) {
            accepted += 1;
            for q in queries() {
                let _ = t.search(&q);
            }
        }
    }
    eprintln!("{tried} crafted caches, {accepted} accepted and searched");
    assert!(tried > 100, "only {tried} iterations");
}

/// Through the files: a damaged cache beside the index gives the uncached answer to
/// every query, and is rebuilt.
#[test]
fn damaged_cache_files_answer_as_the_index() {
    let (index, bytes) = atlas();
    let dir = index.parent().unwrap().join("fuzz-files");
    std::fs::create_dir_all(&dir).unwrap();
    let idx = dir.join("index.json");
    std::fs::write(&idx, bytes).unwrap();
    let (truth, _) = load_table(&idx, false).unwrap();
    let (_, source) = load_table(&idx, true).unwrap();
    assert_eq!(source.name(), "index");
    let good = std::fs::read(cache_path(&idx)).unwrap();
    let mut rng = Rng::seeded();
    let start = Instant::now();
    let mut tried = 0;
    while start.elapsed() < budget() / 2 || tried < 20 {
        let mut b = good.clone();
        damage(&mut rng, &mut b);
        std::fs::write(cache_path(&idx), &b).unwrap();
        let (t, _) = load_table(&idx, true).unwrap();
        assert_eq!(t, truth, "iteration {tried}");
        for q in queries() {
            assert_eq!(t.search(&q), truth.search(&q));
        }
        // Rebuilt: the cache now verifies again.
        assert_eq!(load_table(&idx, true).unwrap().1.name(), "cache");
        tried += 1;
    }
}

/// An index replaced by another of the same size and modification time is not answered
/// from the old cache (the key is the content's hash, not size and time).
#[test]
fn same_size_same_time_other_index_is_not_answered_from_the_cache() {
    let (index, bytes) = atlas();
    let dir = index.parent().unwrap().join("fuzz-swap");
    std::fs::create_dir_all(&dir).unwrap();
    let idx = dir.join("index.json");
    std::fs::write(&idx, bytes).unwrap();
    let mtime = std::fs::metadata(&idx).unwrap().modified().unwrap();
    let (before, _) = load_table(&idx, true).unwrap();
    // Another index: one ground length changed, same number of bytes.
    let text = String::from_utf8(bytes.clone()).unwrap();
    let swapped = text.replacen("\"ground\":3.0}", "\"ground\":3.5}", 1);
    assert_ne!(swapped, text);
    assert_eq!(swapped.len(), text.len());
    std::fs::write(&idx, &swapped).unwrap();
    let f = std::fs::File::options().write(true).open(&idx).unwrap();
    f.set_modified(mtime).unwrap();
    drop(f);
    assert_eq!(std::fs::metadata(&idx).unwrap().modified().unwrap(), mtime);
    let (after, source) = load_table(&idx, true).unwrap();
    assert_eq!(source.name(), "index", "answered from the old cache");
    assert_ne!(after, before);
    assert!(
        after
            .rows
            .iter()
            .any(|r| r.linkage.four_bar().is_some_and(|l| l.ground == 3.5))
    );
}

/// `search` and `dwell --index` over a cache whose header fields (counts, lengths,
/// offsets) are overwritten: each answers as without the cache, and never panics.
#[test]
fn corrupted_cache_counts_in_search_and_dwell() {
    let (index, bytes) = atlas();
    let dir = index.parent().unwrap().join("fuzz-cli");
    std::fs::create_dir_all(&dir).unwrap();
    let idx = dir.join("index.json");
    std::fs::write(&idx, bytes).unwrap();
    let search = |cache: bool| {
        let mut c = Command::new(BIN);
        c.args([
            "search",
            idx.to_str().unwrap(),
            "--arc",
            "20",
            "--limit",
            "0",
        ]);
        if !cache {
            c.arg("--no-cache");
        }
        c.output().unwrap()
    };
    let truth = search(false);
    assert!(truth.status.success());
    // A curve with an arc, for dwell --index.
    let text = String::from_utf8_lossy(&truth.stdout).into_owned();
    let curve = text
        .lines()
        .nth(1)
        .and_then(|l| l.split_whitespace().next())
        .unwrap()
        .to_string();
    let dwell = || {
        Command::new(BIN)
            .args([
                "dwell",
                "--index",
                idx.to_str().unwrap(),
                "--curve",
                &curve,
                "--arc",
                "1",
            ])
            .args(["--format", "json"])
            .output()
            .unwrap()
    };
    assert!(search(true).status.success());
    let good = std::fs::read(cache_path(&idx)).unwrap();
    let dwell_truth = dwell();
    for at in (16..128).step_by(8) {
        let mut b = good.clone();
        b[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        for run in [0, 1] {
            std::fs::write(cache_path(&idx), &b).unwrap();
            let o = if run == 0 { search(true) } else { dwell() };
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(
                !err.contains("panicked") && !err.contains("memory allocation"),
                "{at}: {err}"
            );
            let want = if run == 0 { &truth } else { &dwell_truth };
            assert_eq!(o.status.code(), want.status.code(), "{at}: {err}");
            assert_eq!(o.stdout, want.stdout, "field at {at}");
        }
    }
}
