//! A `.pridb` cut short: its hits, parametric rows and markers, row for row, against the
//! page walk of `ae_data`.

use super::{add_hits, walk_table};
use crate::{real_data, TempDir};
use aepipe::ingest::vallen::{Journal, PairWriter};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

type Row = BTreeMap<String, String>;
type Tables = BTreeMap<&'static str, Vec<Row>>;

/// The features tables compared, with the `SetType`s of the `ae_data` sets each is read
/// from.
const TABLES: [(&str, &[i64]); 3] = [
    ("hits", &[2]),
    ("parametric", &[1]),
    ("markers", &[3, 4, 5, 6]),
];

/// Columns a salvage renumbers (the order of a row among those read, the file read).
const RENUMBERED: [&str; 4] = ["source_file", "hit", "row", "transient"];

/// A pair of `n` hits (as [`super::fixture`]'s) after a section-start marker, with eight
/// parametric rows after every hit (so that `ae_data` fills most of the file's pages, and a
/// cut at 30 % already keeps sets) and a channel's status row after every 25th.
fn fixture(dir: &Path, id: &str, n: u64) {
    std::fs::create_dir_all(dir).unwrap();
    let w = PairWriter::create(&dir.join(id), 1.0, 0.01, Journal::Delete).unwrap();
    let mut rng = aepipe::util::Rng::new(n);
    w.section(1).unwrap();
    for k in 0..n {
        add_hits(&w, k..k + 1, &mut rng);
        let t = 1.0 + 0.1 * k as f64;
        for j in 0..8 {
            let at = t + 0.01 * (j + 1) as f64;
            w.parametric(at, 10.0 + k as f64, -(j as f64)).unwrap();
        }
        if k % 25 == 0 {
            w.status(t + 0.07, 1 + (k % 2) as u32, 1e-3 * (1 + k) as f64)
                .unwrap();
        }
    }
}

/// An `ae_data` set: its SetType, time (s) and TRAI.
type Set = (i64, f64, Option<i64>);

/// The sets of a `.pridb` as SQLite reads them, by SetID.
fn sets(pridb: &Path) -> BTreeMap<i64, Set> {
    let c = rusqlite::Connection::open(pridb).unwrap();
    let base: f64 = c
        .query_row(
            "SELECT Value FROM ae_globalinfo WHERE Key = 'TimeBase'",
            [],
            |r| r.get::<_, rusqlite::types::Value>(0),
        )
        .map(|v| match v {
            rusqlite::types::Value::Integer(i) => i as f64,
            rusqlite::types::Value::Real(f) => f,
            rusqlite::types::Value::Text(t) => t.trim().parse().unwrap(),
            v => panic!("TimeBase {v:?}"),
        })
        .unwrap();
    let mut st = c
        .prepare("SELECT SetID, SetType, Time, TRAI FROM ae_data")
        .unwrap();
    let sets = st
        .query_map([], |r| {
            let t: Option<i64> = r.get(2)?;
            Ok((
                r.get(0)?,
                (r.get(1)?, t.unwrap_or(0) as f64 / base, r.get(3)?),
            ))
        })
        .unwrap()
        .map(Result::unwrap)
        .collect();
    sets
}

/// The rows of the intact run in `out`, by table and SetID: the k-th row of a table (in the
/// order of its `hit`, else `row`, column) is the k-th set of its `SetType`s in SetID order —
/// checked by its time and, for a hit, its TRAI. The renumbered columns are left out.
fn by_setid(out: &Path, sets: &BTreeMap<i64, Set>) -> BTreeMap<&'static str, BTreeMap<i64, Row>> {
    let mut all = BTreeMap::new();
    for (name, types) in TABLES {
        let mut rows = crate::table_maps(&out.join(format!("{name}.parquet")));
        let order = if name == "hits" { "hit" } else { "row" };
        rows.sort_by_key(|r| r[order].parse::<u64>().unwrap());
        let ids: Vec<(&i64, &Set)> = sets.iter().filter(|(_, s)| types.contains(&s.0)).collect();
        assert_eq!(rows.len(), ids.len(), "the intact run's {name} rows");
        let mut by = BTreeMap::new();
        for (mut r, (id, (_, time, trai))) in rows.into_iter().zip(ids) {
            let t: f64 = r["time_s"].parse().unwrap();
            assert!(
                (t - time).abs() <= 1e-9 * time.abs().max(1.0),
                "{name}: SetID {id} at {time} s, its row at {t} s"
            );
            if name == "hits" {
                assert_eq!(r["trai"], trai.unwrap().to_string(), "SetID {id}");
            }
            r.retain(|k, _| !RENUMBERED.contains(&k.as_str()));
            by.insert(*id, r);
        }
        all.insert(name, by);
    }
    all
}

/// A run's tables, the renumbered columns left out, and its transients (`features.parquet`)
/// as `"transients"`: each by channel, time and `record_kind`.
fn tables(out: &Path) -> Tables {
    let mut all = Tables::new();
    for (name, _) in TABLES {
        for mut r in crate::table_maps(&out.join(format!("{name}.parquet"))) {
            r.retain(|k, _| !RENUMBERED.contains(&k.as_str()));
            all.entry(name).or_default().push(r);
        }
    }
    for mut r in crate::table_maps(&out.join("features.parquet")) {
        r.retain(|k, _| ["channel", "time_s", "record_kind"].contains(&k.as_str()));
        all.entry("transients").or_default().push(r);
    }
    all
}

/// Each table of `got` holds exactly the rows of `want`, each as many times (the order
/// aside). `Err` names the first table that differs.
fn rows_match(got: &Tables, want: &Tables) -> Result<(), String> {
    let names: BTreeSet<&&str> = got.keys().chain(want.keys()).collect();
    for name in names {
        let sorted = |t: &Tables| {
            let mut v: Vec<Row> = t.get(*name).cloned().unwrap_or_default();
            v.sort();
            v
        };
        let (g, w) = (sorted(got), sorted(want));
        if g != w {
            let extra = g.iter().find(|r| !w.contains(r));
            let lost = w.iter().find(|r| !g.contains(r));
            return Err(format!(
                "{name}: {} rows, {} expected; a row not expected: {extra:?}; a row missing: {lost:?}",
                g.len(),
                w.len()
            ));
        }
    }
    Ok(())
}

/// Some set of `ae_data` (`records`, by the page walk) lies whole in the first `whole` pages.
fn any_set(records: &BTreeMap<i64, Vec<u64>>, whole: u64) -> bool {
    records
        .values()
        .any(|pages| pages.iter().all(|p| *p <= whole))
}

/// What a run on the pridb cut after page `whole` must give: the intact run's row of every
/// set whose pages (`records`, by the page walk) all lie before the cut, and every one of
/// the intact run's `transients` (the `.tradb` is whole): a `hit` while its hit (by channel
/// and time) survives, a `standalone` one when it was lost — unless the cut keeps no set at
/// all: then there is no hit list, and the transients are read as without one.
fn expected(
    intact: &BTreeMap<&'static str, BTreeMap<i64, Row>>,
    transients: &[Row],
    records: &BTreeMap<i64, Vec<u64>>,
    whole: u64,
) -> Tables {
    let kept = |id: &i64| records[id].iter().all(|p| *p <= whole);
    let mut want = Tables::new();
    for (name, rows) in intact {
        for (_, r) in rows.iter().filter(|(id, _)| kept(id)) {
            want.entry(*name).or_default().push(r.clone());
        }
    }
    let hit_of = |r: &Row| {
        intact["hits"]
            .iter()
            .find(|(_, h)| h["channel"] == r["channel"] && h["time_s"] == r["time_s"])
            .map(|(id, _)| *id)
    };
    let some = any_set(records, whole);
    for r in transients {
        let mut r = r.clone();
        if let (true, Some(id)) = (some, hit_of(&r)) {
            let kind = if kept(&id) { "hit" } else { "standalone" };
            r.insert("record_kind".into(), kind.into());
        }
        want.entry("transients").or_default().push(r);
    }
    want
}

/// Planted wrong runs, each of which [`rows_match`] must reject: the parametric rows all
/// dropped, a marker dropped, one hit read twice and another dropped.
fn plants(got: &Tables, want: &Tables, what: &str) {
    let mut none = got.clone();
    none.remove("parametric");
    let mut marker = got.clone();
    marker.get_mut("markers").unwrap().pop();
    let mut twice = got.clone();
    let hits = twice.get_mut("hits").unwrap();
    hits[0] = hits[1].clone();
    for (plant, bad) in [
        ("no parametric rows", none),
        ("a marker dropped", marker),
        ("a hit twice, one dropped", twice),
    ] {
        assert!(
            rows_match(&bad, want).is_err(),
            "{what}: the planted run ({plant}) passes"
        );
    }
}

/// The cases: (folder, id, cuts in %).
fn cases(t: &TempDir) -> Vec<(PathBuf, String, Vec<usize>)> {
    let src = t.path().join("intact");
    fixture(&src, "S", 400);
    let mut cases = vec![(src, "S".to_string(), (1..10).map(|k| k * 10).collect())];
    if let Some(real) = real_data("a_pridb_cut_short_gives_back_the_hits_its_pages_hold") {
        cases.push((
            real.join("vallen/bearing"),
            "bearing".into(),
            vec![70, 80, 90],
        ));
    }
    cases
}

/// A `.pridb` cut short (the real bearing test's at 70, 80, 90 %, the fixture's — hits,
/// parametric rows, status rows and a section marker — at every 10 %) gives back, table by
/// table, exactly the intact run's rows of the sets whose pages survived, each once: hits,
/// parametric rows and markers by the page walk of `ae_data` (each row's set told by its
/// order in the intact file, checked by its time and TRAI). Every transient of the whole
/// `.tradb` is read, a hit's while its hit survives, else standalone (when no set survives,
/// there is no hit list, and that is said). The other tables the rows draw on
/// (`ae_params`, `ae_markers`, …) lie before every cut that keeps a set (checked). Plant: the
/// fixture's run at 50 % with its parametric rows dropped, a marker dropped, or one hit read
/// twice and another dropped, each rejected.
#[test]
fn a_pridb_cut_short_gives_back_the_hits_its_pages_hold() {
    let t = TempDir::new("salvage-pridb");
    let mut report = Vec::new();
    for (dir, id, cuts) in cases(&t) {
        let pridb = dir.join(format!("{id}.pridb"));
        let walk = walk_table(&pridb, "ae_data");
        let sets = sets(&pridb);
        let hits = sets.values().filter(|s| s.0 == 2).count();
        let intact_out = t.path().join(format!("{id}-intact-out"));
        crate::aepipe_ok(&[
            "features",
            dir.to_str().unwrap(),
            "--out",
            intact_out.to_str().unwrap(),
        ]);
        let intact = by_setid(&intact_out, &sets);
        let transients = tables(&intact_out).remove("transients").unwrap();
        assert!(
            transients.iter().all(|r| r["record_kind"] == "hit"),
            "{id}: every intact transient is a hit's"
        );
        let len = std::fs::metadata(&pridb).unwrap().len() as usize;
        // The last page of the other tables' records.
        let others = ["ae_params", "ae_markers", "ae_globalinfo", "ae_fieldinfo"]
            .map(|name| {
                walk_table(&pridb, name)
                    .records
                    .into_values()
                    .flatten()
                    .max()
                    .unwrap_or(0)
            })
            .into_iter()
            .max()
            .unwrap();
        for pct in cuts {
            let cut = len * pct / 100;
            let whole = (cut / walk.page) as u64;
            let want = expected(&intact, &transients, &walk.records, whole);
            assert!(
                whole >= others || !any_set(&walk.records, whole),
                "{id} cut at {pct} %: sets survive but the other tables reach page {others}"
            );
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
            let got = tables(&out);
            let what = format!("{id} cut at {pct} %");
            rows_match(&got, &want).unwrap_or_else(|e| panic!("{what}: {e}\n{so}"));
            if !any_set(&walk.records, whole) {
                let said = format!("{id}: nothing salvaged from a damaged {id}.pridb (");
                assert!(so.contains(&said), "{what}: {so}");
            }
            let n = |t: &Tables, k: &str| t.get(k).map_or(0, Vec::len);
            if id == "S" && pct == 50 {
                plants(&got, &want, &what);
            }
            if n(&got, "hits") > 0 && n(&got, "hits") < hits {
                let said = format!("{id}: salvaged {} hits (", n(&got, "hits"));
                assert!(so.contains(&said), "{what}: {so}");
            }
            report.push(format!(
                "{id} {pct} %: {} of {hits} hits, {} parametric, {} markers",
                n(&got, "hits"),
                n(&got, "parametric"),
                n(&got, "markers")
            ));
        }
    }
    eprintln!("pridb salvaged: {}", report.join("; "));
}
