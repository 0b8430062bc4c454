//! SQLite's own `.recover` (the `sqlite3` on `PATH`) on the damaged files, against aepipe's
//! salvage and the page walk.

use super::{damaged, fixture, walk};
use crate::{read_all, real_data, TempDir};
use aepipe::ingest::vallen::Journal;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The first `name` on `PATH` that is an executable file.
fn on_path(name: &str) -> Option<PathBuf> {
    use std::os::unix::fs::PermissionsExt;
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| {
            std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
        })
}

/// `sqlite3 FILE .recover`: the SQL it writes; `Err` with its stderr when it exits non-zero.
fn recover_sql(sqlite3: &Path, file: &Path) -> Result<Vec<u8>, String> {
    let o = Command::new(sqlite3)
        .arg(file)
        .arg(".recover")
        .output()
        .map_err(|e| format!("{}: {e}", sqlite3.display()))?;
    if !o.status.success() {
        return Err(format!(
            "sqlite3 {} .recover: {}: {}",
            file.display(),
            o.status,
            String::from_utf8_lossy(&o.stderr).trim()
        ));
    }
    Ok(o.stdout)
}

/// `sql` loaded into a fresh database `db` by `sqlite3 -bail`; `Err` with its stderr when it
/// exits non-zero.
fn load_sql(sqlite3: &Path, sql: &[u8], db: &Path) -> Result<(), String> {
    use std::io::Write;
    let _ = std::fs::remove_file(db);
    let mut load = Command::new(sqlite3)
        .arg("-bail")
        .arg(db)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("{}: {e}", sqlite3.display()))?;
    load.stdin
        .take()
        .unwrap()
        .write_all(sql)
        .map_err(|e| format!("writing to the loader: {e}"))?;
    let o = load.wait_with_output().unwrap();
    if !o.status.success() {
        return Err(format!(
            "loading the recovered SQL: {}: {}",
            o.status,
            String::from_utf8_lossy(&o.stderr).trim()
        ));
    }
    Ok(())
}

/// What `.recover` gave back of `table` (`key`, `value` columns), recovered from `file` and
/// loaded into `scratch/recovered.db`: key → value. Any failure on the way is an `Err`,
/// never an empty set.
fn sqlite_recover(
    sqlite3: &Path,
    file: &Path,
    query: &str,
    scratch: &Path,
) -> Result<BTreeMap<i64, Option<Vec<u8>>>, String> {
    let sql = recover_sql(sqlite3, file)?;
    let db = scratch.join("recovered.db");
    load_sql(sqlite3, &sql, &db)?;
    let c = rusqlite::Connection::open(&db).map_err(|e| e.to_string())?;
    let mut st = c
        .prepare(query)
        .map_err(|e| format!("the recovered database: {e}"))?;
    let rows = st
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .map_err(|e| e.to_string())?
        .collect::<Result<_, _>>()
        .map_err(|e| e.to_string());
    rows
}

/// `.recover` against aepipe on one damaged file: `recovered` (SetID → Data) and `ours`
/// (the SetIDs aepipe salvaged), where `whole` are the SetIDs the page walk finds whole and
/// `intact` the intact file's rows. Every intact row `.recover` gives, aepipe gives too;
/// `.recover` gives none the walk does not find whole; where the walk finds records whole,
/// `.recover` gives at least one intact row (a recovery that failed gives none); aepipe gives
/// exactly the walk's. `Ok` says where aepipe gives more, and how many of `.recover`'s rows
/// are not the intact file's.
fn compare(
    recovered: &BTreeMap<i64, Option<Vec<u8>>>,
    ours: &BTreeSet<i64>,
    whole: &BTreeSet<i64>,
    intact: &BTreeMap<i64, Vec<u8>>,
) -> Result<String, String> {
    let theirs: BTreeSet<i64> = recovered
        .iter()
        .filter(|(id, d)| d.as_ref().is_some_and(|d| intact.get(id) == Some(d)))
        .map(|(id, _)| *id)
        .collect();
    let missed: Vec<&i64> = theirs.difference(ours).collect();
    if !missed.is_empty() {
        return Err(format!(
            "sqlite3 .recover gives back SetIDs {missed:?} that aepipe does not"
        ));
    }
    let unwalked: Vec<&i64> = theirs.difference(whole).collect();
    if !unwalked.is_empty() {
        return Err(format!(
            "sqlite3 .recover gives intact SetIDs {unwalked:?} whose pages the walk finds lost"
        ));
    }
    if ours != whole {
        return Err(format!(
            "aepipe gives {} SetIDs, the page walk finds {} whole",
            ours.len(),
            whole.len()
        ));
    }
    if !whole.is_empty() && theirs.is_empty() {
        return Err(format!(
            "sqlite3 .recover gives back none of the {} records whose pages are whole",
            whole.len()
        ));
    }
    let more: Vec<&i64> = ours.difference(&theirs).collect();
    Ok(format!(
        "sqlite3 .recover {} intact ({} not), aepipe {} (= the page walk's){}",
        theirs.len(),
        recovered.len() - theirs.len(),
        ours.len(),
        if more.is_empty() {
            String::new()
        } else {
            format!("; aepipe alone: {} SetIDs from {:?}", more.len(), more[0])
        }
    ))
}

/// The plants of [`sqlite_recover_gives_back_no_transient_that_aepipe_loses`] that need no
/// working `.recover`: a `.recover` that exits non-zero (a file in a folder that does not
/// exist) and a load of SQL that fails are each an `Err`, never an empty set.
fn plant_failures(sqlite3: &Path, scratch: &Path) {
    let nowhere = scratch.join("no-such-folder/x.tradb");
    assert!(
        sqlite_recover(sqlite3, &nowhere, "SELECT 1, 2", scratch).is_err(),
        "a .recover that failed gave an empty set"
    );
    let bad = b"CREATE TABLE tr_data (SetID INTEGER PRIMARY KEY, Data BLOB);\nINSERT INTO no_such_table VALUES (1);\n";
    assert!(
        load_sql(sqlite3, bad, &scratch.join("planted.db")).is_err(),
        "a load that failed passed"
    );
}

/// [`compare`] fed planted results, each of which it must reject: aepipe's set with one of
/// `.recover`'s rows dropped; `.recover` giving nothing where pages are whole; aepipe's set
/// with a record the walk finds lost added.
fn plant_comparisons(recovered: &BTreeMap<i64, Option<Vec<u8>>>, c: &Case) {
    let (ours, whole, intact) = (&c.ours, &c.whole, &c.rows);
    let theirs = recovered
        .iter()
        .find(|(id, d)| d.as_ref().is_some_and(|d| intact.get(id) == Some(d)))
        .map(|(id, _)| *id)
        .expect("a case where .recover gives an intact row");
    let mut dropped = ours.clone();
    dropped.remove(&theirs);
    assert!(compare(recovered, &dropped, whole, intact).is_err());
    assert!(compare(&BTreeMap::new(), ours, whole, intact).is_err());
    let lost = intact.keys().find(|id| !whole.contains(id));
    if let Some(lost) = lost {
        let mut more = ours.clone();
        more.insert(*lost);
        assert!(compare(recovered, &more, whole, intact).is_err());
    }
}

/// The `sqlite3` on `PATH` recovers an intact database the test writes (three rows):
/// `Err` with why not.
fn recover_works(sqlite3: &Path, scratch: &Path) -> Result<(), String> {
    let db = scratch.join("probe.db");
    let c = rusqlite::Connection::open(&db).unwrap();
    c.execute_batch("CREATE TABLE a (k INTEGER PRIMARY KEY, v BLOB); INSERT INTO a VALUES (1, x'01'), (2, x'02'), (3, x'03');")
        .unwrap();
    drop(c);
    let got = sqlite_recover(sqlite3, &db, "SELECT k, v FROM a", scratch)?;
    if got.len() != 3 {
        return Err(format!("it gave back {} of 3 rows", got.len()));
    }
    Ok(())
}

/// One damaged `.tradb` and its intact original: the intact rows (SetID → Data), the
/// SetIDs the page walk finds whole in the damaged file, and those aepipe salvages from it.
struct Case {
    rows: BTreeMap<i64, Vec<u8>>,
    whole: BTreeSet<i64>,
    ours: BTreeSet<i64>,
}

impl Case {
    fn of(intact: &Path, damaged: &Path) -> Case {
        let c = rusqlite::Connection::open(intact).unwrap();
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
        let cut = std::fs::metadata(damaged).unwrap().len() as usize;
        let w = walk(intact);
        let whole = w
            .records
            .iter()
            .filter(|(_, pages)| pages.iter().all(|p| (*p as usize) * w.page <= cut))
            .map(|(r, _)| *r)
            .collect();
        let (recs, _) = read_all(
            &[damaged.parent().unwrap().to_path_buf()],
            &aepipe::config::ValidConfig::default(),
        );
        let ours = recs.iter().map(|r| trai[&r.hit]).collect();
        Case { rows, whole, ours }
    }
}

/// The `sqlite3` has the `sqlite_dbpage` table (`Err`: its words when it has not).
fn has_dbpage(sqlite3: &Path) -> Result<(), String> {
    let o = Command::new(sqlite3)
        .args([":memory:", "SELECT count(*) FROM sqlite_dbpage"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    if err.contains("no such table: sqlite_dbpage") {
        return Err(err.trim().to_string());
    }
    Ok(())
}

/// The cases: (what, intact `.tradb`, damaged `.tradb`).
fn cases(t: &TempDir, name: &str) -> Vec<(String, PathBuf, PathBuf)> {
    let mut cases = Vec::new();
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
    if let Some(real) = real_data(name) {
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
    cases
}

/// The `sqlite3` on `PATH`, its `.recover` on the same damaged files: every intact row it
/// gives back, aepipe gives back too, and aepipe gives exactly the page walk's whole records;
/// `.recover` must succeed (its exit status and the loader's are checked), and where the
/// walk finds records whole it must give back intact rows, so a recovery that failed cannot
/// pass. Where aepipe gives more is printed. A `sqlite3` absent from `PATH`, or one built
/// without the `sqlite_dbpage` table `.recover` reads pages with (Debian 12's 3.40.1: its
/// `.recover` fails even on an intact database), cannot run the comparison: a skip, which
/// `AEPIPE_REQUIRE_ALL=1` fails. Plant (run before that skip, so on any `sqlite3`): a
/// `.recover` of a file that cannot be opened and a load of failing SQL are errors, not
/// empty sets; the comparison, which passes a stand-in recovery of every whole record of
/// the fixture cut at 60 %, rejects aepipe's result with one of the recovered rows dropped,
/// an empty recovery where pages are whole, and aepipe's result with a lost record added;
/// with a working `.recover` the same plants run on its own first result.
#[test]
fn sqlite_recover_gives_back_no_transient_that_aepipe_loses() {
    let name = "sqlite_recover_gives_back_no_transient_that_aepipe_loses";
    let Some(sqlite3) = on_path("sqlite3") else {
        crate::skip(name, "no sqlite3 on PATH (.ci/run installs Debian's)");
        return;
    };
    let t = TempDir::new("salvage-recover");
    plant_failures(&sqlite3, t.path());
    let cases = cases(&t, name);
    // The comparison itself, on a stand-in for a recovery that gives back every whole
    // record (the fixture cut at 60 %): it passes, and the planted results fail.
    let (_, intact, damaged) = &cases[1];
    let c = Case::of(intact, damaged);
    let perfect = c
        .whole
        .iter()
        .map(|id| (*id, Some(c.rows[id].clone())))
        .collect();
    compare(&perfect, &c.ours, &c.whole, &c.rows).unwrap();
    plant_comparisons(&perfect, &c);
    if let Err(e) = recover_works(&sqlite3, t.path()) {
        match has_dbpage(&sqlite3) {
            Err(why) => {
                crate::skip(
                    name,
                    &format!(
                        "{} has no sqlite_dbpage table (built without SQLITE_ENABLE_DBPAGE_VTAB: {why}), which its .recover reads pages with; its .recover of an intact database: {e}",
                        sqlite3.display()
                    ),
                );
                return;
            }
            Ok(()) => panic!("{}: .recover of an intact database: {e}", sqlite3.display()),
        }
    }
    let mut lines = Vec::new();
    let mut planted = false;
    for (what, intact, damaged) in cases {
        let c = Case::of(&intact, &damaged);
        let recovered = sqlite_recover(
            &sqlite3,
            &damaged,
            "SELECT SetID, Data FROM tr_data",
            t.path(),
        )
        .unwrap_or_else(|e| panic!("{what}: {e}"));
        let said = compare(&recovered, &c.ours, &c.whole, &c.rows)
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        if !planted && !c.whole.is_empty() {
            plant_comparisons(&recovered, &c);
            planted = true;
        }
        lines.push(format!("{what}: {said}"));
    }
    assert!(planted, "no case had a whole record to plant in");
    eprintln!("{}", lines.join("\n"));
}
