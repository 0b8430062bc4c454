//! `aepipe thesis` against its record: every entry `docs/thesis.md` names is declared and
//! every declared entry is named there; each runs (all are cheap) and gives the verdict the
//! record states; an unknown entry is refused before anything runs.

use crate::{aepipe, TempDir};

/// (entry, verdict) of each row of docs/thesis.md's table.
fn record() -> Vec<(String, String)> {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/thesis.md")).unwrap();
    text.lines()
        .filter(|l| l.starts_with("| `"))
        .map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            (
                cells[1].trim_matches('`').to_string(),
                cells[cells.len() - 2].to_string(),
            )
        })
        .collect()
}

#[test]
fn every_entry_runs_and_gives_the_verdict_the_record_states() {
    let rows = record();
    let declared: Vec<&str> = aepipe::thesis::ENTRIES.iter().map(|e| e.id).collect();
    let named: Vec<&str> = rows.iter().map(|(id, _)| id.as_str()).collect();
    assert_eq!(
        named, declared,
        "docs/thesis.md and thesis::ENTRIES disagree"
    );
    let t = TempDir::new("thesis");
    for e in aepipe::thesis::ENTRIES {
        let o = aepipe::thesis::run(e, t.path()).unwrap();
        let want = &rows.iter().find(|(id, _)| id == e.id).unwrap().1;
        let got = if o.pass { "agrees" } else { "departs" };
        assert_eq!(
            got, want,
            "{}: aepipe {} against {}",
            e.id, o.aepipe, e.thesis
        );
        // Its figure and its data.
        let files: Vec<String> = std::fs::read_dir(&o.dir)
            .unwrap()
            .map(|f| f.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        for ext in [".parquet", ".png"] {
            assert!(
                files.iter().any(|f| f.ends_with(ext)),
                "{}: no {ext} in {files:?}",
                e.id
            );
        }
    }
    let (code, _, err) = aepipe(&["thesis", "fig-9.99", "--out", t.path().to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(
        err.contains("unknown entry") && err.contains("fig-3.14"),
        "{err}"
    );
}

/// docs/thesis.md covers chapters 3–6: every figure and table the thesis captions (read from
/// its text in `../shared/seed/`) has its row in the record's coverage table.
#[test]
fn the_record_names_every_figure_and_table() {
    let seed = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/seed/000_25ce7f3daeccd66a.txt");
    let Ok(thesis) = std::fs::read_to_string(&seed) else {
        crate::skip(
            "the_record_names_every_figure_and_table",
            &format!("{} is absent (the thesis's text)", seed.display()),
        );
        return;
    };
    let record =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/thesis.md")).unwrap();
    let rows: std::collections::BTreeSet<&str> = record
        .lines()
        .filter_map(|l| l.strip_prefix("| "))
        .filter_map(|l| l.split(" |").next())
        .collect();
    let mut captions = Vec::new();
    for line in thesis.lines() {
        for (word, short) in [("Figure ", "Fig. "), ("Table ", "Table ")] {
            let Some(rest) = line.strip_prefix(word) else {
                continue;
            };
            let Some((id, _)) = rest.split_once(':') else {
                continue;
            };
            let chapter = id.split('.').next().unwrap_or("");
            if ["3", "4", "5", "6"].contains(&chapter)
                && id.split('.').count() == 2
                && id.chars().all(|c| c.is_ascii_digit() || c == '.')
            {
                captions.push(format!("{short}{id}"));
            }
        }
    }
    captions.sort();
    captions.dedup();
    assert!(captions.len() > 80, "{} captions read", captions.len());
    let missing: Vec<&String> = captions
        .iter()
        .filter(|c| !rows.contains(c.as_str()))
        .collect();
    assert!(
        missing.is_empty(),
        "no row in docs/thesis.md for {missing:?}"
    );
}
