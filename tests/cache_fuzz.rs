//! The search cache and the search columns (`index.columns`) are never trusted: random
//! damage (1–3 bytes changed, cut, grown), damage with the checksums recomputed (a
//! crafted file), a cache or columns of another index of the same size and time (also
//! once the index's key is remembered in its stamp), and corrupted counts read by
//! `search` and `dwell --index` — every case answers exactly as the index itself does
//! (or rebuilds), and nothing panics or aborts. Time-boxed and seeded: `COUPLER_FUZZ_SECONDS` (default 3) and
//! `COUPLER_FUZZ_SEED` (default fixed) change the budget and the seed.

use coupler_atlas::{
    ColumnTable, IndexKey, Query, SearchTable, SortKey, SpanFilter, cache_path, columns_path,
    load_table, stamp_path,
};
mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_coupler-atlas");

/// A small atlas with pages (so every column has content): its index path and bytes.
fn atlas() -> &'static (PathBuf, Vec<u8>) {
    static ATLAS: OnceLock<(PathBuf, Vec<u8>)> = OnceLock::new();
    ATLAS.get_or_init(|| {
        // Shared by every test of this file and never removed (a static): kept in the
        // build's own scratch folder rather than the system's temporary folder.
        let dir = common::shared_scratch("coupler-fuzz").join("atlas");
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
        Query {
            linkage: Some(coupler_atlas::FourBar::new(2.5, 2.5, 3.0).unwrap().into()),
            circuit: Some(coupler_atlas::Circuit::Open),
            include_trivial: true,
            ..Query::default()
        },
        Query {
            min_window_transmission_deg: Some(40.0),
            sort: SortKey::WindowTransmission,
            limit: 4,
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

/// Recomputes a columns file's checksums (every chunk's, the directory's, the trailer's)
/// after a change, as a crafted file would.
fn reseal_columns(b: &mut [u8]) {
    if b.len() < 192 {
        return;
    }
    let t = b.len() - 128;
    let u64_at = |b: &[u8], at: usize| u64::from_le_bytes(b[at..at + 8].try_into().unwrap());
    let (dir_at, dir_len) = (u64_at(b, t + 64) as usize, u64_at(b, t + 72) as usize);
    if dir_at.checked_add(dir_len) != Some(t) {
        return;
    }
    let groups = u32::from_le_bytes(b[t + 24..t + 28].try_into().unwrap()) as usize;
    if groups * (48 + 26 * 24) + 48 != dir_len {
        return;
    }
    let mut entries: Vec<usize> = Vec::new();
    for g in 0..groups {
        for c in 0..26 {
            entries.push(dir_at + g * (48 + 26 * 24) + 48 + c * 24);
        }
    }
    let pages = dir_at + groups * (48 + 26 * 24);
    entries.extend([pages, pages + 24]);
    for e in entries {
        if e + 24 > t {
            return;
        }
        let (at, len) = (u64_at(b, e) as usize, u64_at(b, e + 8) as usize);
        if at.checked_add(len).is_none_or(|end| end > b.len()) {
            continue;
        }
        let h = xxhash_rust::xxh3::xxh3_64(&b[at..at + len]);
        b[e + 16..e + 24].copy_from_slice(&h.to_le_bytes());
    }
    let d = xxhash_rust::xxh3::xxh3_64(&b[dir_at..t]);
    b[t + 80..t + 88].copy_from_slice(&d.to_le_bytes());
    let s = xxhash_rust::xxh3::xxh3_64(&b[t..t + 120]);
    b[t + 120..t + 128].copy_from_slice(&s.to_le_bytes());
}

/// What the index itself answers to `q`, as the columns answer it (the selected curves
/// as a table, and how many passed).
fn truth_select(table: &SearchTable, q: &Query) -> (SearchTable, usize) {
    let (hits, total) = table.search_counted(q);
    let mut rows: Vec<usize> = hits.iter().map(|h| h.row).collect();
    rows.sort_unstable();
    (table.subset(&rows), total)
}

/// The columns `generate` wrote answer every query exactly as the index does.
#[test]
fn generated_columns_answer_as_the_index() {
    let (index, text) = atlas();
    let table = SearchTable::from_index_text(std::str::from_utf8(text).unwrap()).unwrap();
    let cols = ColumnTable::open(&columns_path(index), key_of(text)).unwrap();
    assert_eq!(cols.len(), table.rows.len());
    for q in queries() {
        let (sub, total) = cols.select(&q).unwrap();
        assert_eq!(
            (&sub, total),
            (&truth_select(&table, &q).0, truth_select(&table, &q).1)
        );
        assert_eq!(
            sub.search(&q)
                .iter()
                .map(|h| sub.rows[h.row].id)
                .collect::<Vec<_>>(),
            table
                .search(&q)
                .iter()
                .map(|h| table.rows[h.row].id)
                .collect::<Vec<_>>()
        );
    }
    let last = table.rows.last().unwrap();
    let one = cols.find(last.id).unwrap().unwrap();
    assert_eq!(one, table.subset(&[table.rows.len() - 1]));
    // Another index's key: refused.
    assert!(ColumnTable::open(&columns_path(index), key_of(b"{}")).is_err());
}

/// Every filter and sort key, alone and with the others: the columns, which read only
/// the fields a query tests or sorts on, answer as the index (a field read but not
/// declared would read as NaN there and drop hits).
#[test]
fn columns_read_what_every_filter_and_sort_needs() {
    let (index, text) = atlas();
    let table = SearchTable::from_index_text(std::str::from_utf8(text).unwrap()).unwrap();
    let cols = ColumnTable::open(&columns_path(index), key_of(text)).unwrap();
    let f = |s: &str| s.parse::<SpanFilter>().unwrap();
    let sorts = [
        "id",
        "straight",
        "straightness",
        "arc",
        "deviation",
        "transmission",
        "window-transmission",
        "turn",
        "radius",
        "velocity",
    ];
    let filters: Vec<Query> = vec![
        Query::default(),
        Query {
            straight: Some(f("20:2")),
            ..Query::default()
        },
        Query {
            max_velocity_variation_pct: Some(40.0),
            ..Query::default()
        },
        Query {
            arc: Some(f("20:1")),
            ..Query::default()
        },
        Query {
            radius: Some([0.5, 4.0]),
            ..Query::default()
        },
        Query {
            min_turn_deg: Some(40.0),
            ..Query::default()
        },
        Query {
            double_dwell: true,
            radius_tol_pct: 10.0,
            ..Query::default()
        },
        Query {
            double_dwell: true,
            arc: Some(f("20")),
            radius_tol_pct: 10.0,
            ..Query::default()
        },
        Query {
            min_window_transmission_deg: Some(30.0),
            ..Query::default()
        },
        Query {
            straight: Some(f("20")),
            min_window_transmission_deg: Some(20.0),
            ..Query::default()
        },
        Query {
            arc: Some(f("20")),
            min_window_transmission_deg: Some(20.0),
            ..Query::default()
        },
        Query {
            symmetric: true,
            min_transmission_deg: Some(20.0),
            ..Query::default()
        },
        Query {
            class: Some(coupler_atlas::LinkageClass::ALL[14]),
            include_trivial: true,
            ..Query::default()
        },
    ];
    let mut matched = 0;
    for base in &filters {
        for sort in sorts {
            let q = Query {
                sort: sort.parse().unwrap(),
                limit: 7,
                ..base.clone()
            };
            let (sub, total) = cols.select(&q).unwrap();
            let (want, want_total) = truth_select(&table, &q);
            assert_eq!((&sub, total), (&want, want_total), "{q:?}");
            matched += total;
        }
    }
    assert!(matched > 0, "the queries match some curves");
}

/// Random damage to the columns: either refused (at opening or when the damaged chunk is
/// read) or every answer equal to the index's.
#[test]
fn damaged_columns_are_refused_or_harmless() {
    let (index, text) = atlas();
    let table = SearchTable::from_index_text(std::str::from_utf8(text).unwrap()).unwrap();
    let key = key_of(text);
    let good = std::fs::read(columns_path(index)).unwrap();
    let truth: Vec<_> = queries().iter().map(|q| truth_select(&table, q)).collect();
    let mut rng = Rng::seeded();
    let (start, budget) = (Instant::now(), budget());
    let (mut tried, mut answered) = (0u64, 0u64);
    while start.elapsed() < budget {
        let mut b = good.clone();
        damage(&mut rng, &mut b);
        tried += 1;
        let Ok(cols) = ColumnTable::from_vec(b, key) else {
            continue;
        };
        for (q, want) in queries().iter().zip(&truth) {
            if let Ok(got) = cols.select(q) {
                answered += 1;
                assert_eq!(&got, want, "iteration {tried}: damaged columns were served");
            }
        }
    }
    eprintln!("{tried} damaged columns files, {answered} answers (equal to the index's)");
    assert!(tried > 100, "only {tried} iterations");
}

/// Damage with every checksum recomputed: never a panic or an abort.
#[test]
fn crafted_columns_never_panic() {
    let (index, text) = atlas();
    let key = key_of(text);
    let good = std::fs::read(columns_path(index)).unwrap();
    let mut rng = Rng::seeded();
    let (start, budget) = (Instant::now(), budget());
    let (mut tried, mut opened) = (0u64, 0u64);
    let dir_at = {
        let t = good.len() - 128;
        u64::from_le_bytes(good[t + 64..t + 72].try_into().unwrap()) as usize
    };
    while start.elapsed() < budget {
        let mut b = good.clone();
        // Mostly the directory and trailer (counts, offsets, lengths), else anywhere.
        for _ in 0..1 + rng.below(3) {
            let at = if rng.below(2) == 0 {
                dir_at + rng.below(b.len() - dir_at)
            } else {
                rng.below(b.len())
            };
            b[at] = match rng.below(4) {
                0 => 0xff,
                1 => 0,
                _ => rng.next() as u8,
            };
        }
        reseal_columns(&mut b);
        tried += 1;
        if let Ok(cols) = ColumnTable::from_vec(b, key) {
            opened += 1;
            for q in queries() {
                let _ = cols.select(&q);
            }
            let _ = cols.find(7);
        }
    }
    eprintln!("{tried} crafted columns files, {opened} opened and searched");
    assert!(tried > 100, "only {tried} iterations");
}

/// Through the files: `search` and `dwell --index` beside damaged columns files, and
/// beside the columns of the index before it was changed in place (same size and
/// modification time, once with its key remembered in a stamp): each answers as the
/// index itself does, and never panics.
#[test]
fn damaged_or_stale_columns_in_search_and_dwell() {
    let (index, bytes) = atlas();
    let dir = index.parent().unwrap().join("fuzz-columns");
    std::fs::create_dir_all(&dir).unwrap();
    let idx = dir.join("index.json");
    std::fs::write(&idx, bytes).unwrap();
    let good = std::fs::read(columns_path(index)).unwrap();
    std::fs::write(columns_path(&idx), &good).unwrap();
    let run = |args: &[&str]| Command::new(BIN).args(args).output().unwrap();
    let search = |extra: &[&str]| {
        let mut a = vec![
            "search",
            idx.to_str().unwrap(),
            "--arc",
            "20",
            "--limit",
            "0",
        ];
        a.extend(extra);
        run(&a)
    };
    let truth = search(&["--no-cache"]);
    assert!(truth.status.success());
    let with_columns = search(&[]);
    assert_eq!(with_columns.stdout, truth.stdout);
    assert!(String::from_utf8_lossy(&with_columns.stderr).contains("(from columns)"));
    let text = String::from_utf8_lossy(&truth.stdout).into_owned();
    let curve = text
        .lines()
        .nth(1)
        .and_then(|l| l.split_whitespace().next())
        .unwrap()
        .to_string();
    let dwell = || {
        run(&[
            "dwell",
            "--index",
            idx.to_str().unwrap(),
            "--curve",
            &curve,
            "--arc",
            "1",
            "--format",
            "json",
        ])
    };
    let dwell_truth = dwell();
    assert!(dwell_truth.status.success());
    let check = |what: &str| {
        for (o, want) in [(search(&[]), &truth), (dwell(), &dwell_truth)] {
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(!err.contains("panicked"), "{what}: {err}");
            assert_eq!(o.status.code(), want.status.code(), "{what}: {err}");
            assert_eq!(o.stdout, want.stdout, "{what}: {err}");
        }
    };
    let mut rng = Rng::seeded();
    let start = Instant::now();
    let mut tried = 0;
    while start.elapsed() < budget() / 2 || tried < 10 {
        let mut b = good.clone();
        damage(&mut rng, &mut b);
        std::fs::write(columns_path(&idx), &b).unwrap();
        check(&format!("iteration {tried}"));
        tried += 1;
    }
    // Stale: the index changed in place (same size, same modification time) after its
    // key was remembered; the old columns must not answer for it.
    std::fs::write(columns_path(&idx), &good).unwrap();
    std::thread::sleep(coupler_atlas::SETTLED + Duration::from_millis(200));
    assert!(String::from_utf8_lossy(&search(&[]).stderr).contains("(from columns)"));
    assert!(stamp_path(&idx).is_file(), "a settled index is stamped");
    let mtime = std::fs::metadata(&idx).unwrap().modified().unwrap();
    let text = String::from_utf8(bytes.clone()).unwrap();
    let swapped = text.replace("\"ground\":3.0}", "\"ground\":3.5}");
    assert_ne!(swapped, text);
    assert_eq!(swapped.len(), text.len());
    std::fs::write(&idx, &swapped).unwrap();
    let f = std::fs::File::options().write(true).open(&idx).unwrap();
    f.set_modified(mtime).unwrap();
    drop(f);
    let fresh = search(&["--no-cache"]);
    assert_ne!(fresh.stdout, truth.stdout);
    let o = search(&[]);
    assert_eq!(o.stdout, fresh.stdout, "answered from stale columns");
    assert!(String::from_utf8_lossy(&o.stderr).contains("another index"));
}

/// A file refused as not an index gets no stamp (nor anything else) beside it, even once
/// it has settled; the same file's folder is left as it was. A real index, settled, is
/// stamped (so the test cannot pass by never stamping).
#[test]
fn refused_file_is_not_stamped() {
    let dir = std::env::temp_dir().join(format!("coupler-atlas-stamp-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let junk = dir.join("notes.json");
    std::fs::write(&junk, "{\"not\": \"an index\"}\n").unwrap();
    let good = dir.join("index.json");
    std::fs::write(&good, &atlas().1).unwrap();
    std::thread::sleep(coupler_atlas::SETTLED + Duration::from_millis(200));
    let search = |idx: &Path| {
        Command::new(BIN)
            .args(["search", idx.to_str().unwrap(), "--straight", "30:0.01"])
            .output()
            .unwrap()
    };
    let o = search(&junk);
    assert!(!o.status.success(), "a non-index was searched");
    assert!(!stamp_path(&junk).exists(), "refused file was stamped");
    let o = search(&good);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stamp_path(&good).is_file(), "a settled index is stamped");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert!(
        names.iter().all(|n| !n.starts_with("notes.json.")),
        "files written beside the refused file: {names:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A scan reads only the fields a query tests (`--arc 20`, no tolerance, reads no
/// deviation): a value it did not test is checked when its row is used. A NaN written
/// (with valid checksums) into the first arc's deviation is refused for a query that
/// shows that row (before, the scan read the deviation and the NaN failed `≤ ∞`: the
/// arc silently did not match).
#[test]
fn untested_values_of_the_rows_used_are_checked() {
    let (index, text) = atlas();
    let key = key_of(text);
    let mut b = std::fs::read(columns_path(index)).unwrap();
    let t = b.len() - 128;
    let u64_at = |b: &[u8], at: usize| u64::from_le_bytes(b[at..at + 8].try_into().unwrap());
    let dir_at = u64_at(&b, t + 64) as usize;
    // Group 0's `arc.dev` chunk (column 21): its first arc.
    let dev = u64_at(&b, dir_at + 48 + 21 * 24) as usize;
    b[dev..dev + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    reseal_columns(&mut b);
    let cols = ColumnTable::from_vec(b, key).unwrap();
    let f = |s: &str| s.parse::<SpanFilter>().unwrap();
    let shows_it = Query {
        arc: Some(f("0")),
        include_trivial: true,
        limit: 0,
        ..Query::default()
    };
    let err = cols.select(&shows_it).unwrap_err();
    assert!(err.to_string().contains("not valid"), "{err}");
}
