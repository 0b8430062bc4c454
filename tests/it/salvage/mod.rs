//! A `.tradb`, `.pridb` or `.trfdb` SQLite refuses (cut short, a page zeroed or overwritten)
//! is salvaged from its whole pages. Files the project's writer makes are damaged several
//! ways; what is read back must equal the intact file's, record for record, and be exactly
//! the records whose pages survived — found by a page walk written here ([`walk`]), from the
//! SQLite file format, not by the project's reader. On the real sets, cut short, the same.
//! Each checker is also fed a planted wrong result (a record dropped, duplicated, altered)
//! and must reject it.

use crate::{read_all, TempDir};
use aepipe::ingest::vallen::{HitToWrite, Journal, PairWriter};
use aepipe::model::AeRecord;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

mod pridb;
mod real;
mod recover;
mod trfdb;
mod walk;

use walk::{walk, walk_table};

/// A pair of `n` hits, each with a transient of 1 000–5 000 raw int16 samples (2–10 KB: one
/// to three overflow pages of a 4 KiB page).
fn fixture(dir: &Path, id: &str, n: u64, journal: Journal) -> (PairWriter, PathBuf) {
    std::fs::create_dir_all(dir).unwrap();
    let w = PairWriter::create(&dir.join(id), 1.0, 0.01, journal).unwrap();
    let mut rng = aepipe::util::Rng::new(n);
    add_hits(&w, 0..n, &mut rng);
    let tradb = w.paths().1;
    (w, tradb)
}

/// Hits `ks` (TRAI k + 1, SetID k + 1 in each file) with their transients, each hit and its
/// transient one transaction.
fn add_hits(w: &PairWriter, ks: std::ops::Range<u64>, rng: &mut aepipe::util::Rng) {
    for k in ks {
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
}

/// Records keyed by (channel, hit).
fn by_key(recs: Vec<AeRecord>) -> BTreeMap<(u32, u64), AeRecord> {
    recs.into_iter().map(|r| ((r.channel, r.hit), r)).collect()
}

/// The records read back against the intact ones: exactly the hits of `expect` (by TRAI =
/// hit here), each read once, each equal to the intact file's value for value (its
/// `source_file` aside). `Err` says how they differ; `Ok` gives them by key.
fn salvage_matches(
    recs: Vec<AeRecord>,
    intact: &BTreeMap<(u32, u64), AeRecord>,
    expect: &BTreeSet<u64>,
) -> Result<BTreeMap<(u32, u64), AeRecord>, String> {
    let n = recs.len();
    let got = by_key(recs);
    if got.len() != n {
        return Err(format!("{} record(s) read more than once", n - got.len()));
    }
    let hits: BTreeSet<u64> = got.keys().map(|k| k.1).collect();
    if &hits != expect {
        return Err(format!(
            "the transients salvaged: {} of {} expected; not expected {:?}, missing {:?}",
            hits.len(),
            expect.len(),
            hits.difference(expect).collect::<Vec<_>>(),
            expect.difference(&hits).collect::<Vec<_>>()
        ));
    }
    for (k, r) in &got {
        let mut want = intact
            .get(k)
            .ok_or_else(|| format!("{k:?} is not in the intact file"))?
            .clone();
        want.source_file = r.source_file.clone();
        if r != &want {
            return Err(format!("{k:?} differs from the intact file's"));
        }
    }
    Ok(got)
}

/// The transients read from `damaged_dir` pass [`salvage_matches`]; returned by key.
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
    salvage_matches(recs, intact, expect).unwrap_or_else(|e| panic!("{what}: {e}"))
}

/// The planted wrong readings of `got` (a record dropped, one read twice, one whose
/// samples differ), each of which [`salvage_matches`] must reject.
fn assert_plants_rejected(
    got: &BTreeMap<(u32, u64), AeRecord>,
    intact: &BTreeMap<(u32, u64), AeRecord>,
    expect: &BTreeSet<u64>,
    what: &str,
) {
    let recs: Vec<AeRecord> = got.values().cloned().collect();
    assert!(!recs.is_empty(), "{what}: nothing to plant in");
    let dropped = recs[1..].to_vec();
    let mut twice = recs.clone();
    twice.push(recs[0].clone());
    let mut altered = recs.clone();
    altered[0].samples[0] += 1e-3;
    for (plant, bad) in [("dropped", dropped), ("twice", twice), ("altered", altered)] {
        assert!(
            salvage_matches(bad, intact, expect).is_err(),
            "{what}: the planted reading ({plant}) passes the check"
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

/// A `.tradb` cut at every 10 %, or with one page (a leaf, an interior page, an overflow
/// page mid-chain, the schema page, a chain's last page) zeroed or overwritten with noise,
/// gives back exactly the records the page walk finds whole, each equal to the intact
/// file's. Plant: the reading of the file cut at 50 % with a record dropped, one read
/// twice, and one with a sample changed, each rejected by the same check.
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
    // SetID k+1 holds TRAI k+1. Cut at every 10 %: the records whose every page lies
    // before the cut.
    let rowid_hit = |rowid: i64| rowid as u64;
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
        let what = format!("cut at {tenth}0 %");
        let got = assert_salvaged(&d, &intact, &expect, &what);
        if tenth == 5 {
            assert_plants_rejected(&got, &intact, &expect, &what);
        }
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

/// A WAL-mode pair copied without its `-wal` files while the writer still holds them: the
/// writer's first 20 hits were checkpointed into the main files, 10 more committed to the
/// WAL alone. The copy gives back exactly those 20 — the page walk of the copied `.tradb`
/// finds their 20 records and no other — each equal to the writer's. Plant: the live pair
/// read with its WAL (all 30), and the copy's reading with a record dropped, each rejected
/// by the same check.
#[test]
fn a_wal_tradb_without_its_wal_keeps_what_the_main_file_holds() {
    let t = TempDir::new("salvage-wal");
    let src = t.path().join("live");
    let (w, tradb) = fixture(&src, "W", 20, Journal::Wal);
    for (name, path) in [("pridb", w.paths().0), ("tradb", tradb.clone())] {
        let (busy, _, _): (i64, i64, i64) = rusqlite::Connection::open(&path)
            .unwrap()
            .query_row("PRAGMA wal_checkpoint(TRUNCATE)", [], |r| {
                Ok((r.get(0)?, r.get(1)?, r.get(2)?))
            })
            .unwrap();
        assert_eq!(busy, 0, "the {name} checkpoint was blocked");
    }
    add_hits(&w, 20..30, &mut aepipe::util::Rng::new(30));
    let copy = t.path().join("copy");
    std::fs::create_dir_all(&copy).unwrap();
    std::fs::copy(src.join("W.pridb"), copy.join("W.pridb")).unwrap();
    std::fs::copy(&tradb, copy.join("W.tradb")).unwrap();
    drop(w);
    let cfg = aepipe::config::ValidConfig::default();
    let (live, _) = read_all(std::slice::from_ref(&src), &cfg);
    let intact = by_key(live.clone());
    assert_eq!(intact.len(), 30);
    let in_main: BTreeSet<u64> = walk(&copy.join("W.tradb"))
        .records
        .keys()
        .map(|r| *r as u64)
        .collect();
    let expect: BTreeSet<u64> = (1..=20).collect();
    assert_eq!(in_main, expect, "the page walk of the copied main file");
    let (recs, _) = read_all(&[copy], &cfg);
    let got = salvage_matches(recs.clone(), &intact, &expect)
        .unwrap_or_else(|e| panic!("the copy without its WAL: {e}"));
    assert_eq!(got.len(), 20);
    assert!(
        salvage_matches(live, &intact, &expect).is_err(),
        "the planted reading with the WAL's 10 hits passes"
    );
    assert!(
        salvage_matches(recs[1..].to_vec(), &intact, &expect).is_err(),
        "the planted reading with a record dropped passes"
    );
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
