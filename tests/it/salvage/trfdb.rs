//! A damaged `.trfdb`.

use super::{fixture, overwrite, walk_table};
use crate::TempDir;
use aepipe::ingest::vallen::Journal;
use std::collections::{BTreeMap, BTreeSet};

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
