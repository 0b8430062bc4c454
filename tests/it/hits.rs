//! `hits.parquet` and the accounting rule: hits in = hit rows; transients in = feature rows +
//! reject rows, for every reader. Vallen databases with two acquisitions (TRAI restart) and
//! missing transients, written by aepipe's own writer.

use crate::{table_rows, TempDir};
use aepipe::ingest::vallen::{write_pair, HitToWrite};
use aepipe::pipeline::{run, StreamJob, StreamOptions};
use std::collections::BTreeMap;
use std::path::Path;

fn opts() -> StreamOptions {
    StreamOptions::with_threads(2)
}

/// Column `name` of every row.
fn col<'a>(names: &[String], rows: &'a [Vec<String>], name: &str) -> Vec<&'a str> {
    let i = names
        .iter()
        .position(|n| n == name)
        .unwrap_or_else(|| panic!("no column {name}"));
    rows.iter().map(|r| r[i].as_str()).collect()
}

#[test]
fn two_acquisitions_and_missing_transients_keep_every_hit_and_link_each_transient() {
    let t = TempDir::new("acq");
    let sig = |k: usize| -> Vec<f32> {
        (0..512)
            .map(|i| {
                let a = if i >= 100 {
                    0.01 * (k as f32 + 1.0)
                } else {
                    0.0
                };
                a * (i as f32 * 0.3).sin()
            })
            .collect()
    };
    let sigs: Vec<Vec<f32>> = (0..9).map(sig).collect();
    // (channel, trai, time, restart, transient)
    let plan = [
        (1, 1, 0.10, false, true),
        (2, 2, 0.20, false, true),
        (1, 3, 0.30, false, false), // TRAI promised, transient missing
        (2, 0, 0.35, false, false), // a hit recorded without a transient
        (1, 4, 0.40, false, true),
        (2, 5, 0.50, false, true),
        (1, 1, 0.05, true, true), // recording restarted: TRAI and time start again
        (2, 2, 0.15, false, true),
        (1, 3, 0.25, false, true),
    ];
    let hits = plan
        .iter()
        .zip(&sigs)
        .map(|(&(ch, trai, time, restart, transient), s)| HitToWrite {
            channel: ch,
            trai,
            time_s: time,
            sample_rate_hz: 10e6,
            pretrigger: 100,
            samples_v: s,
            restart,
            transient,
        });
    let data = t.path().join("data");
    std::fs::create_dir_all(&data).unwrap();
    write_pair(&data.join("acq"), hits, &[], 1e-3, 1e-4).unwrap();

    let r = run(
        StreamJob::Features,
        &[data],
        &t.path().join("f"),
        &aepipe::config::ValidConfig::default(),
        &opts(),
    )
    .unwrap();
    // Every hit is a row, in storage order, with its acquisition.
    let (hn, hr) = table_rows(&r.hits_path);
    assert_eq!(hr.len(), 9);
    assert_eq!(
        col(&hn, &hr, "acquisition"),
        ["1", "1", "1", "1", "1", "1", "2", "2", "2"]
    );
    assert_eq!(
        col(&hn, &hr, "hit"),
        ["1", "2", "3", "4", "5", "6", "7", "8", "9"]
    );
    assert_eq!(
        col(&hn, &hr, "trai"),
        ["1", "2", "3", "", "4", "5", "1", "2", "3"]
    );
    // The second acquisition's transients are numbered after the first's largest TRAI (5).
    assert_eq!(
        col(&hn, &hr, "transient"),
        ["1", "2", "", "", "4", "5", "6", "7", "8"]
    );
    // Every transient is a feature row linked to the right hit: same channel and time.
    let (fnames, fr) = table_rows(&r.table_path);
    assert_eq!(fr.len(), 7);
    let hit_of: BTreeMap<&str, (&str, &str)> = col(&hn, &hr, "transient")
        .into_iter()
        .zip(
            col(&hn, &hr, "channel")
                .into_iter()
                .zip(col(&hn, &hr, "time_s")),
        )
        .filter(|(t, _)| !t.is_empty())
        .collect();
    for ((h, ch), time) in col(&fnames, &fr, "hit")
        .into_iter()
        .zip(col(&fnames, &fr, "channel"))
        .zip(col(&fnames, &fr, "time_s"))
    {
        assert_eq!(hit_of.get(h), Some(&(ch, time)), "feature row hit {h}");
    }
    // The missing transient is a reject that names its TRAI; the accounting adds up.
    let c = &r.stats.by_experiment["acq"];
    assert_eq!((c.hits, c.rows, c.rejects), (9, 7, 1));
    let (rn, rr) = table_rows(&r.rejects_path);
    assert!(
        col(&rn, &rr, "record_id")[0].starts_with("TRAI 3 ch1"),
        "{rr:?}"
    );
    // The manifest says the same.
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&r.manifest_path).unwrap()).unwrap();
    assert_eq!(m["counts"]["by_experiment"]["acq"]["hits"], 9);
    assert_eq!(m["counts"]["hits_written"], 9);
}

/// Independent counts of a Vallen pair with SQLite: (hits, transients held or promised).
fn vallen_counts(base: &Path) -> (u64, u64) {
    let pri = rusqlite::Connection::open(base.with_extension("pridb")).unwrap();
    let tra = rusqlite::Connection::open(base.with_extension("tradb")).unwrap();
    let hits: i64 = pri
        .query_row("SELECT count(*) FROM ae_data WHERE SetType = 2", [], |r| {
            r.get(0)
        })
        .unwrap();
    let held: std::collections::HashSet<(i64, i64, i64)> = tra
        .prepare("SELECT TRAI, Chan, Time FROM tr_data")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .unwrap()
        .map(Result::unwrap)
        .collect();
    let promised_missing = pri
        .prepare("SELECT TRAI, Chan, Time FROM ae_data WHERE SetType = 2 AND TRAI > 0")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .unwrap()
        .map(Result::unwrap)
        .filter(|k: &(i64, i64, i64)| !held.contains(k))
        .count();
    (hits as u64, (held.len() + promised_missing) as u64)
}

#[test]
fn the_accounting_rule_holds_on_every_real_data_set() {
    let Some(real) = crate::real_data("the_accounting_rule_holds_on_every_real_data_set") else {
        return;
    };
    let t = TempDir::new("acct");
    let r = run(
        StreamJob::Features,
        std::slice::from_ref(&real),
        t.path(),
        &aepipe::config::ValidConfig::default(),
        &opts(),
    )
    .unwrap();
    let by = &r.stats.by_experiment;
    // Independent counts: SQLite for Vallen, the header for WaveExplorer, the files and the
    // hit list for AEwin, the data README for MISTRAS.
    let mut expected: BTreeMap<String, (u64, u64)> = BTreeMap::new();
    for (dir, id) in [
        ("vallen/steel_plate", "sample"),
        ("vallen/bearing", "bearing"),
        ("plb_cfrp_vallen", "PLBS4_CP090_PCLO1"),
        ("plb_cfrp_vallen", "PLBS8_QI090_T1"),
        ("plb_cfrp_vallen", "PLBS8_QI090_ST1"),
    ] {
        expected.insert(id.into(), vallen_counts(&real.join(dir).join(id)));
    }
    // sample_plain.tradb has no .pridb of its own: each transient is its hit.
    let plain = vallen_counts(&real.join("vallen/steel_plate/sample")).1;
    expected.insert("sample_plain".into(), (plain, plain));
    for f in std::fs::read_dir(real.join("plb_angle_waveexplorer")).unwrap() {
        let p = f.unwrap().path();
        if p.to_string_lossy().ends_with("_wave.txt") {
            let head = std::fs::read_to_string(&p).unwrap();
            let n: u64 = head.split_whitespace().nth(1).unwrap().parse().unwrap();
            let id = p.file_stem().unwrap().to_string_lossy().to_string();
            expected.insert(id, (n, n));
        }
    }
    let aewin = std::fs::read_dir(real.join("aewin_cfrp_tensile/EXP2009"))
        .unwrap()
        .count() as u64;
    let list = std::fs::read_to_string(real.join("aewin_cfrp_tensile/EXP2009.TXT"))
        .unwrap()
        .lines()
        .filter(|l| {
            l.split_whitespace()
                .next()
                .is_some_and(|w| w.parse::<u32>().is_ok())
        })
        .count() as u64;
    assert_eq!(list, aewin);
    expected.insert("EXP2009".into(), (list, aewin));
    // MISTRAS: 8 hits and 8 waveforms, as MistrasDTA 0.1.7 reads them (the data README).
    expected.insert("210527-CH1-15".into(), (8, 8));
    assert_eq!(by.len(), expected.len(), "{by:?}");
    for (id, &(hits, transients)) in &expected {
        let c = by
            .get(id)
            .unwrap_or_else(|| panic!("no experiment {id}: {by:?}"));
        assert_eq!(c.hits, hits, "{id}: hits in = hit rows");
        assert_eq!(
            c.rows + c.rejects,
            transients,
            "{id}: transients in = rows + rejects"
        );
    }
    // Per record type (hits, transients, parametric, status and marker rows), what each
    // reader counted in its files is rows + rejects.
    assert!(
        r.stats.unbalanced().is_empty(),
        "{:?}",
        r.stats.unbalanced()
    );
    // PLBS4 holds 4 hits without a transient: rows, not losses.
    assert_eq!(by["PLBS4_CP090_PCLO1"].hits, 73);
    assert_eq!(by["PLBS4_CP090_PCLO1"].rows, 69);
}

#[test]
fn inspect_counts_hits_and_transients_without_decoding_a_waveform() {
    let t = TempDir::new("inspect-nodecode");
    let sig: Vec<f32> = (0..300).map(|i| (i as f32 * 0.2).sin() * 0.01).collect();
    let hits = (1..=5).map(|k| HitToWrite {
        channel: 1 + (k % 2) as u32,
        trai: k,
        time_s: k as f64 * 0.1,
        sample_rate_hz: 5e6,
        pretrigger: 50,
        samples_v: &sig,
        restart: false,
        transient: true,
    });
    let data = t.path().join("d");
    std::fs::create_dir_all(&data).unwrap();
    let (_, tradb) = write_pair(&data.join("x"), hits, &[], 1e-3, 1e-4).unwrap();
    // Break one waveform's blob: decoding it must fail, counting it must not.
    rusqlite::Connection::open(&tradb)
        .unwrap()
        .execute("UPDATE tr_data SET Data = x'00' WHERE TRAI = 3", [])
        .unwrap();
    let cfg = aepipe::config::ValidConfig::default();
    let d = aepipe::ingest::discover(std::slice::from_ref(&data), &cfg.ingest);
    let s = aepipe::inspect::summarise(&d.sources[0], &cfg);
    assert_eq!((s.hits, s.transients, s.rejects), (5, 5, 0), "{s}");
    assert_eq!((s.min_len, s.max_len), (300, 300));
    assert_eq!(
        s.sample_rates_hz.iter().copied().collect::<Vec<_>>(),
        [5_000_000]
    );
    // The feature run decodes it and rejects exactly that one.
    let r = run(
        StreamJob::Features,
        &[data],
        &t.path().join("f"),
        &cfg,
        &opts(),
    )
    .unwrap();
    let c = &r.stats.by_experiment["x"];
    assert_eq!((c.hits, c.rows, c.rejects), (5, 4, 1));
}

#[test]
fn the_steel_plate_trfdb_features_join_its_hits_by_trai() {
    let Some(real) = crate::real_data("the_steel_plate_trfdb_features_join_its_hits_by_trai")
    else {
        return;
    };
    let cfg = aepipe::config::ValidConfig::default();
    let dir = real.join("vallen/steel_plate");
    let d = aepipe::ingest::discover(std::slice::from_ref(&dir), &cfg.ingest);
    let src = d.sources.iter().find(|s| s.id == "sample").unwrap();
    assert!(
        src.companions
            .iter()
            .any(|c| c.path.ends_with("sample.trfdb")),
        "{src:?}"
    );
    assert!(d.skipped.iter().all(|(p, _)| !p.ends_with("sample.trfdb")));
    // Independent: the trf_data row of each TRAI, read here with SQLite.
    let trf = rusqlite::Connection::open(dir.join("sample.trfdb")).unwrap();
    let mut checked = 0;
    for it in aepipe::ingest::open(src, cfg.read_settings(), &cfg.load) {
        let aepipe::model::Item::Hit(h) = it else {
            continue;
        };
        let trai = h.trai.unwrap();
        let (cog, pa): (f64, f64) = trf
            .query_row(
                "SELECT FFT_CoG, PA FROM trf_data WHERE TRAI = ?1",
                [trai],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .unwrap();
        let v: serde_json::Value =
            serde_json::from_str(h.vendor_features.as_deref().unwrap()).unwrap();
        assert_eq!(v["FFT_CoG [kHz]"].as_f64(), Some(cog), "TRAI {trai}: {v}");
        assert_eq!(v["PA [mV]"].as_f64(), Some(pa), "TRAI {trai}: {v}");
        checked += 1;
    }
    assert_eq!(checked, 4);
}
