//! A damaged `.trfdb`.

use super::{fixture, overwrite, walk_table};
use crate::TempDir;
use aepipe::ingest::vallen::Journal;
use std::collections::{BTreeMap, BTreeSet};

type Hits = Vec<(String, String)>;

/// A run's hits (TRAI, `vendor_features`, in file order) against the intact run's: each of
/// the intact run's hits exactly once, those whose TRAI is in `keep` with the intact file's
/// features, the others with none. `Err` says how they differ; `Ok` counts the hits with
/// features.
fn features_match(
    got: &Hits,
    intact: &BTreeMap<String, String>,
    keep: &BTreeSet<&String>,
) -> Result<usize, String> {
    let trais: BTreeSet<&String> = got.iter().map(|(k, _)| k).collect();
    if got.len() != intact.len() || trais.len() != got.len() {
        return Err(format!(
            "{} hits ({} TRAIs), the intact run {}",
            got.len(),
            trais.len(),
            intact.len()
        ));
    }
    for (k, v) in got {
        let want = match intact.get(k) {
            None => return Err(format!("TRAI {k} is not the intact run's")),
            Some(w) if keep.contains(k) => w.as_str(),
            Some(_) => "",
        };
        if v != want {
            return Err(format!(
                "TRAI {k}: vendor_features {v:?}, expected {want:?}"
            ));
        }
    }
    Ok(got.iter().filter(|(_, v)| !v.is_empty()).count())
}

/// Planted wrong runs, each of which [`features_match`] must reject: every hit's features
/// dropped, no hits at all, a hit dropped, and two hits' features swapped.
fn plants(got: &Hits, intact: &BTreeMap<String, String>, keep: &BTreeSet<&String>) {
    let blank: Hits = got
        .iter()
        .map(|(k, _)| (k.clone(), String::new()))
        .collect();
    let mut swapped = got.clone();
    let (a, b) = (
        swapped.iter().position(|(k, _)| keep.contains(k)).unwrap(),
        swapped.iter().rposition(|(k, _)| keep.contains(k)).unwrap(),
    );
    let va = swapped[a].1.clone();
    swapped[a].1 = swapped[b].1.clone();
    swapped[b].1 = va;
    assert_ne!(a, b, "two hits with features to swap");
    for (plant, bad) in [
        ("no features", blank),
        ("no hits", Hits::new()),
        ("a hit dropped", got[1..].to_vec()),
        ("two hits' features swapped", swapped),
    ] {
        assert!(
            features_match(&bad, intact, keep).is_err(),
            "the planted run ({plant}) passes"
        );
    }
}

/// A `.trfdb` (VisualAE's features beside the `.pridb`) SQLite refuses gives back the
/// feature rows its whole pages hold, joined to their hits exactly as the intact file's are;
/// a hit whose row is lost stands without `vendor_features`. The file is aepipe's own
/// write-back (`aepipe export trfdb`) of a run on the fixture pair, cut at every 10 % and
/// with a leaf page zeroed; with its schema page lost nothing is taken, and that is said.
/// Every run has the 300 hits, each once ([`features_match`]). Plant: the run on the file
/// cut at 50 % with every hit's features dropped, with no hits, with a hit dropped, and
/// with two hits' features swapped, each rejected.
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
        let got: Hits = crate::table_maps(&out.join("hits.parquet"))
            .into_iter()
            .map(|r| (r["trai"].clone(), r["vendor_features"].clone()))
            .collect();
        (got, so)
    };
    let (intact, said) = features("intact", &|_| {});
    let intact: BTreeMap<String, String> = intact.into_iter().collect();
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
        let n = features_match(&got, &intact, &keep).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_eq!(n, keep.len(), "{what}");
        if what == "cut at 50 %" {
            plants(&got, &intact, &keep);
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
    assert_eq!(features_match(&got, &intact, &BTreeSet::new()), Ok(0));
    assert!(
        said.contains("features not joined") && said.contains("schema page are lost"),
        "{said}"
    );
    eprintln!("trfdb salvaged (of 300): {}", report.join("; "));
}
