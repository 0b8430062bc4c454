//! A `.pridb` cut short.

use super::{fixture, walk_table};
use crate::{real_data, TempDir};
use aepipe::ingest::vallen::Journal;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

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
