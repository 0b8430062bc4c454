//! SQLite's own `.recover` on the damaged files.

use super::{damaged, fixture};
use crate::{read_all, real_data, TempDir};
use aepipe::ingest::vallen::Journal;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

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
