//! Issue 53: a `.tradb` SQLite refuses (cut short, a page zeroed or overwritten) is salvaged
//! from its whole pages. Files the project's writer makes are damaged several ways; the
//! transients read back must equal the intact file's, record for record, and exactly the
//! ones whose pages survived — counted by a page walk written here, from the SQLite file
//! format, not by the project's reader. On the real sets, cut at 30/60/90 %, the same.

use crate::{read_all, real_data, TempDir};
use aepipe::ingest::vallen::{HitToWrite, Journal, PairWriter};
use aepipe::model::AeRecord;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A pair of `n` hits, each with a transient of 1 000–5 000 raw int16 samples (2–10 KB: one
/// to three overflow pages of a 4 KiB page).
fn fixture(dir: &Path, id: &str, n: u64, journal: Journal) -> (PairWriter, PathBuf) {
    std::fs::create_dir_all(dir).unwrap();
    let w = PairWriter::create(&dir.join(id), 1.0, 0.01, journal).unwrap();
    let mut rng = aepipe::util::Rng::new(n);
    for k in 0..n {
        let len = 1000 + ((k * 397) % 4000) as usize;
        let v: Vec<f32> = (0..len)
            .map(|i| (0.3 * (i as f64 * 0.21).sin() + 0.01 * rng.normal()) as f32)
            .collect();
        let h = HitToWrite {
            channel: 1 + (k % 2) as u32,
            trai: k + 1,
            time_s: 1.0 + 0.1 * k as f64,
            sample_rate_hz: 10e6,
            pretrigger: 100,
            samples_v: &v,
            restart: false,
            transient: true,
        };
        w.batch(|w| {
            w.hit(&h)?;
            w.transient(&h)
        })
        .unwrap();
    }
    let tradb = w.paths().1;
    (w, tradb)
}

/// What a page walk of a SQLite file finds, written here from the file format: the page
/// size, and for every `tr_data` record its rowid and the pages it occupies (its leaf page
/// and overflow chain), and the pages of each kind.
struct Walk {
    page: usize,
    records: BTreeMap<i64, Vec<u64>>,
    leaves: BTreeSet<u64>,
    interior: BTreeSet<u64>,
    overflow_mid: BTreeSet<u64>,
    overflow_last: BTreeSet<u64>,
}

fn be(b: &[u8], at: usize, n: usize) -> u64 {
    b[at..at + n].iter().fold(0, |v, x| (v << 8) | *x as u64)
}

fn varint(b: &[u8], at: usize) -> (u64, usize) {
    let mut v = 0u64;
    for i in 0..8 {
        v = (v << 7) | (b[at + i] & 0x7f) as u64;
        if b[at + i] < 0x80 {
            return (v, i + 1);
        }
    }
    ((v << 8) | b[at + 8] as u64, 9)
}

/// The walk of an intact file's `tr_data` tree (rooted where sqlite_master says).
fn walk(file: &Path) -> Walk {
    walk_table(file, "tr_data")
}

fn walk_table(file: &Path, table: &str) -> Walk {
    let root: i64 = rusqlite::Connection::open(file)
        .unwrap()
        .query_row(
            "SELECT rootpage FROM sqlite_master WHERE name = ?1",
            [table],
            |r| r.get(0),
        )
        .unwrap();
    let b = std::fs::read(file).unwrap();
    let page = match be(&b, 16, 2) {
        1 => 65536,
        p => p as usize,
    };
    let usable = page - b[20] as usize;
    let pg = |n: u64| &b[(n as usize - 1) * page..n as usize * page];
    let mut w = Walk {
        page,
        records: BTreeMap::new(),
        leaves: BTreeSet::new(),
        interior: BTreeSet::new(),
        overflow_mid: BTreeSet::new(),
        overflow_last: BTreeSet::new(),
    };
    let mut stack = vec![root as u64];
    while let Some(n) = stack.pop() {
        let p = pg(n);
        let h = if n == 1 { 100 } else { 0 };
        let cells = be(p, h + 3, 2) as usize;
        let interior = p[h] == 5;
        let ptrs = h + if interior { 12 } else { 8 };
        if interior {
            w.interior.insert(n);
            stack.push(be(p, h + 8, 4));
        } else {
            assert_eq!(p[h], 13);
            w.leaves.insert(n);
        }
        for i in 0..cells {
            let off = be(p, ptrs + 2 * i, 2) as usize;
            if interior {
                stack.push(be(p, off, 4));
                continue;
            }
            let (size, a) = varint(p, off);
            let (rowid, c) = varint(p, off + a);
            let size = size as usize;
            let x = usable - 35;
            let m = (usable - 12) * 32 / 255 - 23;
            let local = if size <= x {
                size
            } else {
                let k = m + (size - m) % (usable - 4);
                if k <= x {
                    k
                } else {
                    m
                }
            };
            let mut pages = vec![n];
            if size > local {
                let mut next = be(p, off + a + c + local, 4);
                let mut left = size - local;
                while left > 0 {
                    pages.push(next);
                    let o = pg(next);
                    left = left.saturating_sub(usable - 4);
                    if left > 0 {
                        w.overflow_mid.insert(next);
                    } else {
                        w.overflow_last.insert(next);
                    }
                    next = be(o, 0, 4);
                }
            }
            w.records.insert(rowid as i64, pages);
        }
    }
    w
}

/// Records keyed by (channel, hit).
fn by_key(recs: Vec<AeRecord>) -> BTreeMap<(u32, u64), AeRecord> {
    recs.into_iter().map(|r| ((r.channel, r.hit), r)).collect()
}

/// The transients read from `damaged` are the intact ones of `expect` (by TRAI = hit
/// here), value for value, and no other; returned.
fn assert_salvaged(
    damaged_dir: &Path,
    intact: &BTreeMap<(u32, u64), AeRecord>,
    expect: &BTreeSet<u64>,
    what: &str,
) -> BTreeMap<(u32, u64), AeRecord> {
    let (recs, _) = read_all(
        &[damaged_dir.to_path_buf()],
        &aepipe::config::ValidConfig::default(),
    );
    let got = by_key(recs);
    let hits: BTreeSet<u64> = got.keys().map(|k| k.1).collect();
    assert_eq!(&hits, expect, "{what}: the transients salvaged");
    for (k, r) in &got {
        let mut want = intact[k].clone();
        want.source_file = r.source_file.clone();
        assert_eq!(r, &want, "{what}: {k:?}");
    }
    got
}

/// Each salvaged transient equals vallenae's reading of the intact `.tradb` (by channel and
/// TRAI): its sample count, first and last 32 samples, and the sum and sum of squares of
/// all of them (vallenae's float64 volts against aepipe's float32: to 1e-6 of the largest).
fn assert_as_vallenae_reads(
    got: &BTreeMap<(u32, u64), AeRecord>,
    vallenae: &serde_json::Value,
    what: &str,
) {
    let theirs: BTreeMap<(u32, u64), &serde_json::Value> = vallenae
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            let n = |k: &str| v[k].as_u64().unwrap();
            ((n("channel") as u32, n("trai")), v)
        })
        .collect();
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    for (k, r) in got {
        let v = theirs
            .get(k)
            .unwrap_or_else(|| panic!("{what}: vallenae has no {k:?}"));
        let s = &r.samples;
        assert_eq!(
            s.len() as u64,
            v["n"].as_u64().unwrap(),
            "{what}: {k:?} samples"
        );
        let big = s.iter().fold(1e-12f64, |m, x| m.max(f64::from(x.abs())));
        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-6 * scale;
        let ends = s
            .iter()
            .take(32)
            .chain(s.iter().skip(s.len().saturating_sub(32)));
        let want = v["first"]
            .as_array()
            .unwrap()
            .iter()
            .chain(v["last"].as_array().unwrap());
        for (a, b) in ends.zip(want) {
            assert!(close(f64::from(*a), f(b), big), "{what}: {k:?}: {a} vs {b}");
        }
        let sum: f64 = s.iter().map(|x| f64::from(*x)).sum();
        let sumsq: f64 = s.iter().map(|x| f64::from(*x).powi(2)).sum();
        assert!(
            close(sum, f(&v["sum"]), big * s.len() as f64),
            "{what}: {k:?} sum"
        );
        assert!(
            close(sumsq, f(&v["sumsq"]), big * big * s.len() as f64),
            "{what}: {k:?} sum of squares"
        );
    }
}

/// Page `p` (1-based, `page` bytes) overwritten with `fill`: "zeros" or "noise".
fn overwrite(b: &mut [u8], p: u64, page: usize, fill: &str, rng: &mut aepipe::util::Rng) {
    for x in &mut b[(p as usize - 1) * page..p as usize * page] {
        *x = if fill == "zeros" {
            0
        } else {
            (rng.uniform() * 256.0) as u8
        };
    }
}

/// Copy the pair into `to` with the `.tradb` passed through `damage`.
fn damaged(from: &Path, to: &Path, id: &str, damage: impl FnOnce(&mut Vec<u8>)) -> PathBuf {
    std::fs::create_dir_all(to).unwrap();
    let pridb = from.join(format!("{id}.pridb"));
    if pridb.is_file() {
        std::fs::copy(&pridb, to.join(format!("{id}.pridb"))).unwrap();
    }
    let mut b = std::fs::read(from.join(format!("{id}.tradb"))).unwrap();
    damage(&mut b);
    std::fs::write(to.join(format!("{id}.tradb")), b).unwrap();
    to.to_path_buf()
}

#[test]
fn a_damaged_tradb_gives_back_exactly_the_records_whose_pages_survived() {
    let t = TempDir::new("salvage-fixture");
    let src = t.path().join("intact");
    let (w, tradb) = fixture(&src, "S", 60, Journal::Delete);
    drop(w);
    let walk = walk(&tradb);
    assert!(
        !walk.interior.is_empty() && walk.overflow_mid.len() >= 5,
        "the fixture has an interior page and overflow chains"
    );
    let (recs, rejs) = read_all(
        std::slice::from_ref(&src),
        &aepipe::config::ValidConfig::default(),
    );
    assert!(rejs.is_empty());
    let intact = by_key(recs);
    assert_eq!(intact.len(), 60);
    let all: BTreeSet<u64> = (1..=60).collect();
    let len = std::fs::metadata(&tradb).unwrap().len() as usize;
    let page = walk.page;
    let rowid_hit = |rowid: i64| rowid as u64; // SetID k+1 holds TRAI k+1
                                               // Cut at every 10 %: the records whose every page lies before the cut.
    for tenth in 1..10 {
        let cut = len * tenth / 10;
        let whole_pages = (cut / page) as u64;
        let expect: BTreeSet<u64> = walk
            .records
            .iter()
            .filter(|(_, pages)| pages.iter().all(|p| *p <= whole_pages))
            .map(|(r, _)| rowid_hit(*r))
            .collect();
        let d = damaged(&src, &t.path().join(format!("cut{tenth}")), "S", |b| {
            b.truncate(cut)
        });
        assert_salvaged(&d, &intact, &expect, &format!("cut at {tenth}0 %"));
    }
    // One page zeroed, or overwritten with noise: a leaf (its records lost), an interior
    // page (nothing lost: its leaves are told by their records' shape), an overflow page in
    // the middle of a chain (that record lost), the schema page (nothing lost).
    let leaf = *walk.leaves.iter().nth(walk.leaves.len() / 2).unwrap();
    let interior = *walk.interior.iter().next().unwrap();
    let overflow = *walk
        .overflow_mid
        .iter()
        .nth(walk.overflow_mid.len() / 2)
        .unwrap();
    let on = |p: u64| -> BTreeSet<u64> {
        walk.records
            .iter()
            .filter(|(_, pages)| !pages.contains(&p))
            .map(|(r, _)| rowid_hit(*r))
            .collect()
    };
    let mut rng = aepipe::util::Rng::new(5);
    for (name, p, expect) in [
        ("leaf", leaf, on(leaf)),
        ("interior", interior, all.clone()),
        ("overflow", overflow, on(overflow)),
        ("schema", 1, all.clone()),
    ] {
        assert!(expect.len() < 60 || name == "interior" || name == "schema");
        for fill in ["zeros", "noise"] {
            let d = damaged(&src, &t.path().join(format!("{name}-{fill}")), "S", |b| {
                overwrite(b, p, page, fill, &mut rng)
            });
            assert_salvaged(&d, &intact, &expect, &format!("{name} page {p} {fill}"));
        }
    }
    // The last page of a chain zeroed or overwritten, in a file cut at 90 % (so SQLite
    // refuses it): zeros that end the chain as a last page would, or a next pointer that
    // does not end it, lose that record.
    let cut = len * 9 / 10;
    let last = *walk
        .overflow_last
        .iter()
        .find(|p| (**p as usize) * page <= cut)
        .unwrap();
    let expect: BTreeSet<u64> = walk
        .records
        .iter()
        .filter(|(_, pages)| {
            !pages.contains(&last) && pages.iter().all(|p| (*p as usize) * page <= cut)
        })
        .map(|(r, _)| rowid_hit(*r))
        .collect();
    for fill in ["zeros", "noise"] {
        let d = damaged(&src, &t.path().join(format!("last-{fill}")), "S", |b| {
            overwrite(b, last, page, fill, &mut rng);
            b.truncate(cut);
        });
        assert_salvaged(
            &d,
            &intact,
            &expect,
            &format!("last overflow page {last} {fill}"),
        );
    }
}

/// The salvage is said on the terminal and in the manifest, and every hit whose transient
/// was lost is a reject naming the damaged file.
#[test]
fn a_salvage_is_said_and_every_lost_transient_is_a_reject() {
    let t = TempDir::new("salvage-said");
    let src = t.path().join("intact");
    let (w, tradb) = fixture(&src, "S", 40, Journal::Delete);
    drop(w);
    let len = std::fs::metadata(&tradb).unwrap().len() as usize;
    let d = damaged(&src, &t.path().join("cut"), "S", |b| b.truncate(len / 2));
    let out = t.path().join("out");
    let so = crate::aepipe_ok(&[
        "features",
        d.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let line = so
        .lines()
        .find(|l| l.contains("salvaged"))
        .unwrap_or_else(|| panic!("{so}"));
    let n: usize = line
        .split("salvaged ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        line.contains(&format!(
            "S: salvaged {n} of ≥ 40 transients from a damaged S.tradb ("
        )),
        "{line}"
    );
    assert!(
        line.contains("SQLite: database disk image is malformed"),
        "{line}"
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let c = &m["counts"]["by_experiment"]["S"]["records"]["transient"];
    assert_eq!(c["rows"].as_u64().unwrap() as usize, n);
    assert_eq!(c["rejects"].as_u64().unwrap() as usize, 40 - n);
    assert!(m["counts"]["unbalanced"].as_array().unwrap().is_empty());
}

/// A WAL-mode `.tradb` copied without its `-wal` while the writer still holds it: what the
/// main file holds is read (by SQLite or salvage), each record equal to the writer's.
#[test]
fn a_wal_tradb_without_its_wal_keeps_what_the_main_file_holds() {
    let t = TempDir::new("salvage-wal");
    let src = t.path().join("live");
    let (w, tradb) = fixture(&src, "W", 30, Journal::Wal);
    let copy = t.path().join("copy");
    std::fs::create_dir_all(&copy).unwrap();
    std::fs::copy(src.join("W.pridb"), copy.join("W.pridb")).unwrap();
    std::fs::copy(&tradb, copy.join("W.tradb")).unwrap();
    drop(w);
    let (recs, _) = read_all(
        std::slice::from_ref(&src),
        &aepipe::config::ValidConfig::default(),
    );
    let intact = by_key(recs);
    assert_eq!(intact.len(), 30);
    let (recs, _) = read_all(&[copy], &aepipe::config::ValidConfig::default());
    for r in recs {
        let mut want = intact[&(r.channel, r.hit)].clone();
        want.source_file = r.source_file.clone();
        assert_eq!(r, want);
    }
}

/// The real Vallen sets cut at 30, 60 and 90 %: the salvaged transients equal the intact
/// file's (as aepipe reads it — equal to vallenae's, `vendor::vallenae_reads_the_same`), and
/// their number is the page walk's count of records whose pages survived.
#[test]
fn the_real_tradbs_cut_short_give_back_what_their_pages_hold() {
    let Some(real) = real_data("the_real_tradbs_cut_short_give_back_what_their_pages_hold") else {
        return;
    };
    let t = TempDir::new("salvage-real");
    let mut report = Vec::new();
    for (dir, id) in [
        ("vallen/bearing", "bearing"),
        ("vallen/steel_plate", "sample"),
        ("vallen/steel_plate", "sample_plain"),
        ("plb_cfrp_vallen", "PLBS4_CP090_PCLO1"),
    ] {
        let src = real.join(dir);
        let tradb = src.join(format!("{id}.tradb"));
        let walk = walk(&tradb);
        let Some(vallenae) = crate::vendor::python(
            "the real tradbs cut short, against vallenae",
            "vallenae_tradb.py",
            &[&tradb],
        ) else {
            return;
        };
        let vallenae: serde_json::Value = serde_json::from_str(&vallenae).unwrap();
        let only = t.path().join(format!("{id}-intact"));
        let d = damaged(&src, &only, id, |_| {});
        let (recs, _) = read_all(&[d], &aepipe::config::ValidConfig::default());
        let intact = by_key(recs);
        // SetID → the hit of its record in aepipe's numbering (TRAI here: one acquisition).
        let trai: BTreeMap<i64, u64> = rusqlite::Connection::open(&tradb)
            .unwrap()
            .prepare("SELECT SetID, TRAI FROM tr_data")
            .unwrap()
            .query_map([], |r| Ok((r.get(0)?, r.get::<_, i64>(1)? as u64)))
            .unwrap()
            .map(Result::unwrap)
            .collect();
        let len = std::fs::metadata(&tradb).unwrap().len() as usize;
        for pct in [30, 60, 90] {
            let cut = len * pct / 100;
            let whole = (cut / walk.page) as u64;
            let expect: BTreeSet<u64> = walk
                .records
                .iter()
                .filter(|(_, pages)| pages.iter().all(|p| *p <= whole))
                .map(|(r, _)| trai[r])
                .collect();
            let d = damaged(&src, &t.path().join(format!("{id}-{pct}")), id, |b| {
                b.truncate(cut)
            });
            let what = format!("{id} cut at {pct} %");
            let got = assert_salvaged(&d, &intact, &expect, &what);
            assert_as_vallenae_reads(&got, &vallenae, &what);
            report.push(format!(
                "{id} {pct} %: {} of {}",
                expect.len(),
                walk.records.len()
            ));
        }
    }
    eprintln!("salvaged: {}", report.join("; "));
}

/// The rows of `tr_data` SQLite's own `.recover` gives back from `tradb` that are the
/// intact file's own (SetID → its Data), by SetID; `None` when it recovers no such table.
fn sqlite_recover(
    sqlite3: &Path,
    tradb: &Path,
    intact: &BTreeMap<i64, Vec<u8>>,
    scratch: &Path,
) -> BTreeSet<i64> {
    let out = std::process::Command::new(sqlite3)
        .arg(tradb)
        .arg(".recover")
        .output()
        .unwrap();
    let db = scratch.join("recovered.db");
    let _ = std::fs::remove_file(&db);
    let mut load = std::process::Command::new(sqlite3)
        .arg(&db)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    use std::io::Write;
    let _ = load.stdin.take().unwrap().write_all(&out.stdout);
    load.wait().unwrap();
    let Ok(c) = rusqlite::Connection::open(&db) else {
        return BTreeSet::new();
    };
    let Ok(mut st) = c.prepare("SELECT SetID, Data FROM tr_data") else {
        return BTreeSet::new();
    };
    st.query_map([], |r| {
        Ok((r.get::<_, i64>(0)?, r.get::<_, Option<Vec<u8>>>(1)?))
    })
    .unwrap()
    .filter_map(Result::ok)
    .filter(|(id, d)| d.as_ref().is_some_and(|d| intact.get(id) == Some(d)))
    .map(|(id, _)| id)
    .collect()
}

/// Debian's `sqlite3 .recover` on the same damaged files: every intact row it gives back,
/// aepipe gives back too; where aepipe gives more is printed (the closing note's numbers).
#[test]
fn sqlite_recover_gives_back_no_transient_that_aepipe_loses() {
    let Some(sqlite3) = ["/usr/bin/sqlite3", "/usr/local/bin/sqlite3"]
        .iter()
        .map(Path::new)
        .find(|p| p.is_file())
    else {
        crate::skip(
            "sqlite_recover_gives_back_no_transient_that_aepipe_loses",
            "Debian's sqlite3 is not installed (.ci/run installs it)",
        );
        return;
    };
    let t = TempDir::new("salvage-recover");
    let mut cases: Vec<(String, PathBuf, PathBuf)> = Vec::new();
    let src = t.path().join("intact");
    let (w, tradb) = fixture(&src, "S", 60, Journal::Delete);
    drop(w);
    let len = std::fs::metadata(&tradb).unwrap().len() as usize;
    for tenth in [3, 6, 9] {
        let d = damaged(&src, &t.path().join(format!("cut{tenth}")), "S", |b| {
            b.truncate(len * tenth / 10)
        });
        cases.push((
            format!("fixture cut at {tenth}0 %"),
            tradb.clone(),
            d.join("S.tradb"),
        ));
    }
    if let Some(real) = real_data("sqlite_recover_gives_back_no_transient_that_aepipe_loses") {
        for (dir, id) in [
            ("vallen/bearing", "bearing"),
            ("plb_cfrp_vallen", "PLBS4_CP090_PCLO1"),
        ] {
            let from = real.join(dir);
            let intact = from.join(format!("{id}.tradb"));
            let len = std::fs::metadata(&intact).unwrap().len() as usize;
            for pct in [30, 60, 90] {
                let d = damaged(&from, &t.path().join(format!("{id}-{pct}")), id, |b| {
                    b.truncate(len * pct / 100)
                });
                cases.push((
                    format!("{id} cut at {pct} %"),
                    intact.clone(),
                    d.join(format!("{id}.tradb")),
                ));
            }
        }
    }
    let mut lines = Vec::new();
    for (what, intact, damaged) in cases {
        let c = rusqlite::Connection::open(&intact).unwrap();
        let rows: BTreeMap<i64, Vec<u8>> = c
            .prepare("SELECT SetID, Data FROM tr_data")
            .unwrap()
            .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
            .unwrap()
            .map(Result::unwrap)
            .collect();
        let trai: BTreeMap<u64, i64> = c
            .prepare("SELECT TRAI, SetID FROM tr_data")
            .unwrap()
            .query_map([], |r| Ok((r.get::<_, i64>(0)? as u64, r.get(1)?)))
            .unwrap()
            .map(Result::unwrap)
            .collect();
        let recovered = sqlite_recover(sqlite3, &damaged, &rows, t.path());
        let (recs, _) = read_all(
            &[damaged.parent().unwrap().to_path_buf()],
            &aepipe::config::ValidConfig::default(),
        );
        let ours: BTreeSet<i64> = recs.iter().map(|r| trai[&r.hit]).collect();
        let missed: Vec<&i64> = recovered.difference(&ours).collect();
        assert!(
            missed.is_empty(),
            "{what}: sqlite3 .recover gives back SetIDs {missed:?} that aepipe does not"
        );
        lines.push(format!(
            "{what}: sqlite3 .recover {}, aepipe {}",
            recovered.len(),
            ours.len()
        ));
    }
    eprintln!("{}", lines.join("\n"));
}

/// A `.pridb` cut short (the real bearing test's at 70, 80, 90 %, the fixture's at every
/// 10 %): its hits, parametric rows and markers are read from the pages that survived, each
/// equal to the intact file's, and the hits are exactly those the page walk finds whole.
#[test]
fn a_pridb_cut_short_gives_back_the_hits_its_pages_hold() {
    let t = TempDir::new("salvage-pridb");
    let mut cases: Vec<(PathBuf, String, Vec<usize>)> = Vec::new();
    let src = t.path().join("intact");
    let (w, _) = fixture(&src, "S", 400, Journal::Delete);
    drop(w);
    cases.push((src, "S".into(), (1..10).map(|k| k * 10).collect()));
    if let Some(real) = real_data("a_pridb_cut_short_gives_back_the_hits_its_pages_hold") {
        cases.push((
            real.join("vallen/bearing"),
            "bearing".into(),
            vec![70, 80, 90],
        ));
    }
    let table = |dir: &Path, name: &str| -> Vec<BTreeMap<String, String>> {
        let mut rows = crate::table_maps(&dir.join(format!("{name}.parquet")));
        for r in &mut rows {
            r.retain(|k, _| !["source_file", "hit", "row", "transient"].contains(&k.as_str()));
        }
        rows
    };
    let mut report = Vec::new();
    for (dir, id, cuts) in cases {
        let pridb = dir.join(format!("{id}.pridb"));
        let walk = walk_table(&pridb, "ae_data");
        let hit_setids: BTreeSet<i64> = rusqlite::Connection::open(&pridb)
            .unwrap()
            .prepare("SELECT SetID FROM ae_data WHERE SetType = 2")
            .unwrap()
            .query_map([], |r| r.get(0))
            .unwrap()
            .map(Result::unwrap)
            .collect();
        let intact_out = t.path().join(format!("{id}-intact-out"));
        crate::aepipe_ok(&[
            "features",
            dir.to_str().unwrap(),
            "--out",
            intact_out.to_str().unwrap(),
        ]);
        let len = std::fs::metadata(&pridb).unwrap().len() as usize;
        for pct in cuts {
            let cut = len * pct / 100;
            let whole = (cut / walk.page) as u64;
            let expect = walk
                .records
                .iter()
                .filter(|(r, pages)| hit_setids.contains(r) && pages.iter().all(|p| *p <= whole))
                .count();
            let d = t.path().join(format!("{id}-{pct}"));
            std::fs::create_dir_all(&d).unwrap();
            std::fs::copy(
                dir.join(format!("{id}.tradb")),
                d.join(format!("{id}.tradb")),
            )
            .unwrap();
            let mut b = std::fs::read(&pridb).unwrap();
            b.truncate(cut);
            std::fs::write(d.join(format!("{id}.pridb")), b).unwrap();
            let out = t.path().join(format!("{id}-{pct}-out"));
            let so = crate::aepipe_ok(&[
                "features",
                d.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ]);
            for name in ["hits", "parametric", "markers"] {
                let want = table(&intact_out, name);
                for r in table(&out, name) {
                    if name == "hits" && r["trai"].is_empty() {
                        continue; // a transient whose hit was lost stands alone
                    }
                    assert!(
                        want.contains(&r),
                        "{id} cut at {pct} %: a {name} row not in the intact file: {r:?}"
                    );
                }
            }
            let got = table(&out, "hits")
                .iter()
                .filter(|r| !r["trai"].is_empty())
                .count();
            assert_eq!(got, expect, "{id} cut at {pct} %: hits salvaged");
            if got > 0 && got < hit_setids.len() {
                assert!(so.contains(&format!("{id}: salvaged {got} hits (")), "{so}");
            }
            report.push(format!("{id} {pct} %: {got} of {}", hit_setids.len()));
        }
    }
    eprintln!("pridb salvaged: {}", report.join("; "));
}

/// A `.trfdb` (VisualAE's features beside the `.pridb`) SQLite refuses gives back the
/// feature rows its whole pages hold, joined to their hits exactly as the intact file's are;
/// a hit whose row is lost stands without `vendor_features`. The file is aepipe's own
/// write-back (`aepipe export trfdb`) of a run on the fixture pair, cut at every 10 % and
/// with a leaf page zeroed; with its schema page lost nothing is taken, and that is said.
#[test]
fn a_damaged_trfdb_gives_back_the_feature_rows_its_pages_hold() {
    let t = TempDir::new("salvage-trfdb");
    let src = t.path().join("pair");
    let (w, _) = fixture(&src, "S", 300, Journal::Delete);
    drop(w);
    let run = t.path().join("run");
    crate::aepipe_ok(&[
        "features",
        src.to_str().unwrap(),
        "--out",
        run.join("features").to_str().unwrap(),
    ]);
    crate::aepipe_ok(&["export", "trfdb", run.to_str().unwrap()]);
    let trfdb = run.join("export/S.aepipe.trfdb");
    let walk = walk_table(&trfdb, "trf_data");
    let trai: BTreeMap<i64, String> = rusqlite::Connection::open(&trfdb)
        .unwrap()
        .prepare("SELECT rowid, TRAI FROM trf_data")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get::<_, i64>(1)?.to_string())))
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert_eq!(trai.len(), 300);
    assert!(walk.leaves.len() > 3, "{:?}", walk.leaves);
    // The pair with the trfdb beside it, `damage`d; its hits' TRAI → vendor_features, and
    // what was said.
    let features = |name: &str, damage: &dyn Fn(&mut Vec<u8>)| {
        let d = t.path().join(name);
        std::fs::create_dir_all(&d).unwrap();
        for ext in ["pridb", "tradb"] {
            std::fs::copy(src.join(format!("S.{ext}")), d.join(format!("S.{ext}"))).unwrap();
        }
        let mut b = std::fs::read(&trfdb).unwrap();
        damage(&mut b);
        std::fs::write(d.join("S.trfdb"), b).unwrap();
        let out = t.path().join(format!("{name}-out"));
        let so = crate::aepipe_ok(&[
            "features",
            d.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let got: BTreeMap<String, String> = crate::table_maps(&out.join("hits.parquet"))
            .into_iter()
            .map(|r| (r["trai"].clone(), r["vendor_features"].clone()))
            .collect();
        (got, so)
    };
    let (intact, said) = features("intact", &|_| {});
    assert_eq!(intact.len(), 300);
    assert!(intact.values().all(|v| v.starts_with('{')), "{intact:?}");
    assert!(!said.contains("salvaged"), "{said}");
    // The hits whose feature row survived carry the intact file's features, the others none.
    let check = |what: &str, whole: &dyn Fn(&[u64]) -> bool, damage: &dyn Fn(&mut Vec<u8>)| {
        let (got, said) = features(what, damage);
        let keep: BTreeSet<&String> = walk
            .records
            .iter()
            .filter(|(_, pages)| whole(pages))
            .map(|(r, _)| &trai[r])
            .collect();
        for (k, v) in &got {
            let want = if keep.contains(k) { &intact[k] } else { "" };
            assert_eq!(v, want, "{what}: TRAI {k}");
        }
        if keep.len() < 300 {
            assert!(
                said.contains(&format!(
                    "S: salvaged the features of {} of ≥ 300 transients from a damaged S.trfdb (",
                    keep.len()
                )),
                "{what}: {said}"
            );
        }
        keep.len()
    };
    let len = std::fs::metadata(&trfdb).unwrap().len() as usize;
    let mut report = Vec::new();
    for pct in (1..10).map(|k| k * 10) {
        let cut = len * pct / 100;
        let pages = (cut / walk.page) as u64;
        let n = check(
            &format!("cut at {pct} %"),
            &|p| p.iter().all(|p| *p <= pages),
            &|b| b.truncate(cut),
        );
        report.push(format!("{pct} %: {n}"));
    }
    let leaf = *walk.leaves.iter().nth(walk.leaves.len() / 2).unwrap();
    let n = check(
        &format!("leaf page {leaf} zeroed"),
        &|p| !p.contains(&leaf),
        &|b| overwrite(b, leaf, walk.page, "zeros", &mut aepipe::util::Rng::new(7)),
    );
    assert!(n > 0 && n < 300, "{n}");
    // The schema page lost: the feature columns cannot be named, nothing is taken.
    let (got, said) = features("schema-lost", &|b| {
        overwrite(b, 1, walk.page, "zeros", &mut aepipe::util::Rng::new(1))
    });
    assert!(got.values().all(String::is_empty), "{got:?}");
    assert!(
        said.contains("features not joined") && said.contains("schema page are lost"),
        "{said}"
    );
    eprintln!("trfdb salvaged (of 300): {}", report.join("; "));
}

/// `aepipe watch` on a pair whose files arrive by a copy that knows nothing of SQLite's
/// locks (a share synced from the acquisition PC while it records): each look sees a prefix
/// of the finished files, cut anywhere, its last page half-written. The windows' rows are
/// the offline reader's rows on the finished pair, each once: nothing a half page or a
/// missing overflow page would make, and nothing lost for having been seen early.
#[test]
fn a_pair_arriving_by_a_copy_is_followed_without_reading_a_half_page() {
    use aepipe::ingest::vallen::tail::{read, Position, Tail};
    use std::time::Duration;
    let t = TempDir::new("salvage-live");
    let (w, _) = fixture(&t.path().join("done"), "S", 160, Journal::Delete);
    drop(w);
    let dir = t.path().join("watched");
    std::fs::create_dir_all(&dir).unwrap();
    let done = |ext: &str| std::fs::read(t.path().join(format!("done/S.{ext}"))).unwrap();
    let (pridb, tradb) = (done("pridb"), done("tradb"));
    let cfg = aepipe::config::ValidConfig::default();
    let src = aepipe::ingest::Source {
        id: "S".into(),
        format: aepipe::ingest::Format::Vallen,
        files: vec![dir.join("S.tradb")],
        companions: vec![aepipe::ingest::Companion {
            role: aepipe::ingest::Role::HitIndex,
            path: dir.join("S.pridb"),
        }],
        first_hit: 0,
    };
    let show = |items: Vec<aepipe::model::Item>| -> Vec<String> {
        let mut v: Vec<String> = items
            .into_iter()
            .filter(|i| {
                matches!(
                    i,
                    aepipe::model::Item::Record(_) | aepipe::model::Item::Reject(_)
                )
            })
            .map(|i| format!("{i:?}"))
            .collect();
        v.sort();
        v
    };
    let long = Duration::from_secs(3600);
    let mut tail: Option<Tail> = None;
    let mut got = Vec::new();
    let mut looks = 0;
    // The copy goes on in steps of an odd number of bytes: most prefixes end inside a page,
    // many inside an overflow chain.
    let steps = 23;
    for k in 1..=steps + 1 {
        let upto = |b: &[u8]| (b.len() * k.min(steps) / steps + 1237 * (k % 3)).min(b.len());
        std::fs::write(dir.join("S.pridb"), &pridb[..upto(&pridb)]).unwrap();
        std::fs::write(dir.join("S.tradb"), &tradb[..upto(&tradb)]).unwrap();
        let (wait, settle) = if k > steps {
            (Duration::ZERO, Duration::ZERO)
        } else {
            (long, long)
        };
        if tail.is_none() {
            tail = Tail::open(&src, Position::default(), &cfg.ingest).ok();
        }
        let Some(tl) = tail.as_mut() else { continue };
        for _ in 0..3 {
            if let Ok(ws) = tl.look(wait, settle, 16, 0.0, &cfg.ingest) {
                looks += 1;
                for w in ws {
                    got.extend(read(&w, &cfg.ingest));
                }
            }
        }
    }
    assert!(looks > 0);
    let offline: Vec<aepipe::model::Item> =
        aepipe::ingest::open(&src, cfg.read_settings(), &cfg.load).collect();
    let (got, offline) = (show(got), show(offline));
    assert_eq!(offline.len(), 160, "{offline:?}");
    let extra: Vec<&String> = got.iter().filter(|g| !offline.contains(g)).collect();
    let lost: Vec<&String> = offline.iter().filter(|o| !got.contains(o)).collect();
    let differ = |a: &str, b: &str| {
        let at = a.bytes().zip(b.bytes()).take_while(|(x, y)| x == y).count();
        let part = |s: &str| {
            String::from_utf8_lossy(&s.as_bytes()[at.saturating_sub(80)..(at + 80).min(s.len())])
                .to_string()
        };
        format!("…{} | …{}", part(a), part(b))
    };
    if let (Some(e), Some(l)) = (extra.first(), lost.first()) {
        eprintln!("first difference: {}", differ(e, l));
    }
    assert!(
        extra.is_empty() && lost.is_empty(),
        "rows the watcher made that the finished pair does not hold: {:?}\nrows it lost: {:?}",
        extra.iter().take(3).collect::<Vec<_>>(),
        lost.iter().take(3).collect::<Vec<_>>()
    );
    assert_eq!(got, offline);
}
