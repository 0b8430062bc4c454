//! Bad inputs become reject rows (or one clear error line); the good hits beside them are all
//! written. Every fixture is made here with aepipe's own writers.

use crate::{table_rows, vallen_fixture, TempDir};
use aepipe::pipeline::{run, StreamJob, StreamOptions};
use aepipe::synth::Experiment;
use std::path::Path;

struct Rejects {
    rows: Vec<(String, String, String, String, String)>,
}

impl Rejects {
    fn read(p: &Path) -> Rejects {
        let (names, rows) = table_rows(p);
        assert_eq!(
            names,
            [
                "experiment",
                "source_file",
                "record_id",
                "stage",
                "reason",
                "record_type"
            ]
        );
        Rejects {
            rows: rows
                .into_iter()
                .map(|r| {
                    (
                        r[0].clone(),
                        r[1].clone(),
                        r[2].clone(),
                        r[3].clone(),
                        r[4].clone(),
                    )
                })
                .collect(),
        }
    }
    fn about(&self, needle: &str) -> Vec<&(String, String, String, String, String)> {
        self.rows.iter().filter(|r| r.1.contains(needle)).collect()
    }
}

#[test]
fn each_bad_input_becomes_a_clear_reject_and_good_hits_are_all_written() {
    let t = TempDir::new("bad");
    let d = t.path().join("batch");
    std::fs::create_dir_all(&d).unwrap();
    // Good experiment.
    vallen_fixture(&d, "good", 30, 1);
    // Truncated .tradb.
    vallen_fixture(&d, "trunc", 20, 2);
    let tra = d.join("trunc.tradb");
    let len = std::fs::metadata(&tra).unwrap().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&tra)
        .unwrap()
        .set_len(len * 2 / 5)
        .unwrap();
    // A corrupt FLAC blob in one record of an otherwise good pair.
    vallen_fixture(&d, "flacbad", 10, 3);
    {
        let c = rusqlite::Connection::open(d.join("flacbad.tradb")).unwrap();
        let n = c
            .execute(
                "UPDATE tr_data SET DataFormat = 2, Data = X'664C614300000022' WHERE TRAI = 3",
                [],
            )
            .unwrap();
        assert_eq!(n, 1);
    }
    // A .pridb without its .tradb.
    vallen_fixture(&d, "orphan", 8, 4);
    std::fs::remove_file(d.join("orphan.tradb")).unwrap();
    // NaN/inf samples, an empty record, a zero-length WAV, an unreadable (dangling) file.
    let csvdir = d.join("csv_exp");
    std::fs::create_dir_all(&csvdir).unwrap();
    std::fs::write(
        csvdir.join("h1.csv"),
        "voltage_v\n0.1\nNaN\n0.2\ninf\n".to_string() + &"0.0\n".repeat(40),
    )
    .unwrap();
    std::fs::write(csvdir.join("h2.csv"), "voltage_v\n").unwrap();
    std::fs::write(
        csvdir.join("h3.csv"),
        "voltage_v\n".to_string() + &"0.001\n".repeat(64),
    )
    .unwrap();
    let wavdir = d.join("wav_exp");
    std::fs::create_dir_all(&wavdir).unwrap();
    aepipe::ingest::wavfmt::write_wav_f32(&wavdir.join("empty.wav"), 10_000_000, &[]).unwrap();
    std::os::unix::fs::symlink(
        t.path().join("does-not-exist.wav"),
        wavdir.join("broken.wav"),
    )
    .unwrap();
    // An unknown file named explicitly.
    let unknown = t.path().join("notes.xyz");
    std::fs::write(&unknown, "hello").unwrap();

    let out = t.path().join("out");
    let r = run(
        StreamJob::Features,
        &[d.clone(), unknown.clone(), t.path().join("missing_folder")],
        &out,
        &aepipe::config::ValidConfig::default(),
        &StreamOptions::with_threads(2),
    )
    .unwrap();
    let rej = Rejects::read(&r.rejects_path);
    let by_exp = &r.stats.by_experiment;

    // Good hits are all written.
    assert_eq!(by_exp["good"].rows, 30);
    assert_eq!(by_exp["flacbad"].rows, 9);
    assert_eq!(by_exp["csv_exp"].rows, 1);

    // Corrupt FLAC: exactly the one record, named, with the decoder's complaint.
    let flac = rej.about("flacbad.tradb");
    assert_eq!(flac.len(), 1, "{flac:?}");
    assert_eq!(flac[0].2, "TRAI 3");
    assert!(flac[0].4.contains("FLAC"), "{}", flac[0].4);

    // Truncated: every one of its 20 hits is a row or a per-hit reject; the file is named.
    let trunc_hits = rej
        .rows
        .iter()
        .filter(|r| r.0 == "trunc" && !r.2.is_empty())
        .count() as u64;
    let trunc_rows = by_exp.get("trunc").map(|c| c.rows).unwrap_or(0);
    assert_eq!(trunc_rows + trunc_hits, 20, "{:?}", rej.rows);
    assert!(trunc_hits > 0);
    assert!(
        rej.rows.iter().any(|r| r.1.ends_with("trunc.tradb")
            && (r.4.contains("malformed")
                || r.4.contains("not a readable")
                || r.4.contains("cannot"))),
        "{:?}",
        rej.about("trunc")
    );

    // .pridb without .tradb: its 8 hits are rejects that say so.
    let orphan: Vec<_> = rej.rows.iter().filter(|r| r.0 == "orphan").collect();
    assert_eq!(orphan.len(), 8);
    assert!(orphan
        .iter()
        .all(|r| r.4.contains("no .tradb") && r.2.starts_with("TRAI ")));

    // NaN/inf and empty records are validate-stage rejects.
    let nan = rej.about("h1.csv");
    assert_eq!(nan.len(), 1);
    assert_eq!(nan[0].3, "validate");
    assert!(nan[0].4.contains("2 non-finite"), "{}", nan[0].4);
    let empty = rej.about("h2.csv");
    assert!(empty[0].4.contains("0 samples"), "{:?}", empty);
    let ew = rej.about("empty.wav");
    assert!(ew[0].4.contains("0 samples"), "{:?}", ew);

    // Unreadable (dangling link) and unknown files.
    let broken = rej.about("broken.wav");
    assert_eq!(broken.len(), 1);
    assert!(
        broken[0].4.contains("not a readable WAV"),
        "{}",
        broken[0].4
    );
    let unk = rej.about("notes.xyz");
    assert_eq!(unk.len(), 1);
    assert_eq!(unk[0].3, "discover");
    assert!(unk[0].4.contains(".xyz"));
    let missing = rej.about("missing_folder");
    assert!(missing[0].4.contains("no such file"));

    // Nothing lost: the manifest's counts add up.
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&r.manifest_path).unwrap()).unwrap();
    assert_eq!(m["counts"]["rows_written"].as_u64().unwrap(), r.stats.rows);
    assert_eq!(
        m["counts"]["rejects"].as_u64().unwrap(),
        rej.rows.len() as u64
    );
    // Every reject reason is one line.
    assert!(rej
        .rows
        .iter()
        .all(|r| !r.4.contains('\n') && !r.4.is_empty()));
}

#[test]
fn malformed_text_lines_are_named() {
    let t = TempDir::new("badtext");
    let dir = t.path().join("txt");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("a.txt"), "0.1\n0.2\n0.3\nbanana\n0.4\n").unwrap();
    let (recs, rejs) = crate::read_all(&[dir], &aepipe::config::ValidConfig::default());
    assert!(recs.is_empty());
    assert_eq!(rejs.len(), 1);
    assert!(
        rejs[0].reason.contains("line 4") && rejs[0].reason.contains("banana"),
        "{}",
        rejs[0].reason
    );
}

#[test]
fn truncated_waveexplorer_file_reports_every_missing_event() {
    let t = TempDir::new("badwe");
    let f = t.path().join("x_wave.txt");
    // Header promises 3 events of 4 samples; only 1.5 events are present.
    std::fs::write(&f, "10\t3\t4\t1\n0.1\n0.2\n0.3\n0.4\n0.5\n0.6\n").unwrap();
    let (recs, rejs) = crate::read_all(&[f], &aepipe::config::ValidConfig::default());
    assert_eq!(recs.len(), 1);
    assert_eq!(rejs.len(), 2);
    assert!(
        rejs[0].reason.contains("ends after 2 of 4"),
        "{}",
        rejs[0].reason
    );
    assert_eq!(rejs[1].record_id, "event 3");
}

/// Run the binary with a time limit: a hang (a symlink loop, a header promising 10¹²
/// values) fails the test instead of stalling it.
pub(crate) fn aepipe_within(args: &[&str], secs: u64) -> (i32, String, String) {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .env("XDG_CACHE_HOME", crate::test_cache())
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if t0.elapsed().as_secs() > secs {
            let _ = child.kill();
            panic!("aepipe {} still running after {secs} s", args.join(" "));
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let o = child.wait_with_output().unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
#[cfg(unix)]
fn hostile_sizes_and_symlink_loops_are_rejects_and_the_batch_goes_on() {
    let t = TempDir::new("hostile");
    let d = t.path().join("in");
    std::fs::create_dir_all(&d).unwrap();
    vallen_fixture(&d, "good", 10, 1);
    // Two links back to the folder itself: read once, not recursively forever.
    std::os::unix::fs::symlink(&d, d.join("loop1")).unwrap();
    std::os::unix::fs::symlink(&d, d.join("loop2")).unwrap();
    // A WaveExplorer header promising 10¹² events in a few bytes.
    std::fs::write(
        d.join("huge_wave.txt"),
        "10\t1000000000000\t1024\t1\n0.1\n0.2\n",
    )
    .unwrap();
    // A Vallen record whose Samples claims 10¹² (FLAC): checked before anything is reserved.
    vallen_fixture(&d, "bigsamples", 3, 2);
    rusqlite::Connection::open(d.join("bigsamples.tradb"))
        .unwrap()
        .execute(
            "UPDATE tr_data SET Samples = 1000000000000, DataFormat = 2 WHERE TRAI = 2",
            [],
        )
        .unwrap();
    // A 44-byte WAV whose data chunk claims 4 GiB.
    let w = d.join("wav");
    std::fs::create_dir_all(&w).unwrap();
    let wav = crate::corpus::wav_header(10_000_000, 16, 0xFFFF_FFF0);
    std::fs::write(w.join("bad.wav"), &wav).unwrap();

    let out = t.path().join("out");
    let (c, _, se) = aepipe_within(
        &[
            "features",
            d.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ],
        120,
    );
    assert_eq!(c, 0, "{se}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let by = &m["counts"]["by_experiment"];
    // Every good hit once (not once per link).
    assert_eq!(by["good"]["rows"], 10, "{by}");
    assert_eq!(by["good"]["hits"], 10, "{by}");
    assert_eq!(by["bigsamples"]["rows"], 2, "{by}");
    let skipped = m["skipped"].to_string();
    assert!(skipped.contains("already read"), "{skipped}");
    let rej = Rejects::read(&out.join("rejects.parquet"));
    let huge = rej.about("huge_wave.txt");
    assert_eq!(huge.len(), 1, "{huge:?}");
    assert!(
        huge[0].4.contains("promises") && huge[0].4.contains("1000000000000"),
        "{huge:?}"
    );
    let big = rej.about("bigsamples.tradb");
    assert_eq!(big.len(), 1, "{big:?}");
    assert!(big[0].4.contains("max_samples_per_record"), "{big:?}");
    let bad = rej.about("bad.wav");
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(bad[0].4.contains("header promises"), "{bad:?}");
}

#[test]
fn an_experiment_id_never_writes_outside_the_output_folder() {
    let t = TempDir::new("escape");
    let mut e = Experiment::new("x", 30, 4);
    e.n_samples = 512;
    let items = e.records().map(|mut r| {
        r.experiment = "../../escape".into();
        aepipe::model::Item::Record(r)
    });
    let f = t.path().join("a/b/f");
    std::fs::create_dir_all(&f).unwrap();
    aepipe::pipeline::stream(
        items,
        StreamJob::Features,
        &f,
        &aepipe::config::ValidConfig::default(),
        &StreamOptions::with_threads(2),
    )
    .unwrap();
    let out = t.path().join("a/b/trend");
    let (c, _, se) = aepipe_within(
        &[
            "trend",
            f.join("features.parquet").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--cutoff",
            "none",
        ],
        60,
    );
    assert_eq!(c, 0, "{se}");
    // Whatever the trend drew is inside `out`, and nothing appeared two levels up.
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    assert!(names.iter().any(|n| n == "trend.parquet"), "{names:?}");
    for dir in [t.path().to_path_buf(), t.path().join("a")] {
        for e in std::fs::read_dir(dir).unwrap() {
            let n = e.unwrap().file_name().to_string_lossy().to_string();
            assert!(
                !n.contains("escape"),
                "{n} written outside the output folder"
            );
        }
    }
}

/// `aepipe cluster` on tables it cannot use says so in its own words, naming the file once:
/// not Parquet, a column it lacks, and a method word that is not `[cluster] method`'s.
#[test]
fn cluster_reads_its_tables_with_its_own_errors() {
    let t = crate::TempDir::new("cluster-bad");
    let junk = t.path().join("junk.parquet");
    std::fs::write(&junk, b"x").unwrap();
    let out = t.path().join("out");
    let s = |p: &std::path::Path| p.display().to_string();
    let (code, _, err) = crate::aepipe(&["cluster", &s(&junk), "--out", &s(&out)]);
    assert_eq!(code, 1, "{err}");
    assert_eq!(err.matches(&s(&junk)).count(), 1, "{err}");
    assert!(!err.contains("som"), "{err}");
    let data = t.path().join("data");
    crate::vallen_fixture(&data, "x", 30, 3);
    let feats = t.path().join("f");
    let (code, so, err) = crate::aepipe(&["features", &s(&data), "--out", &s(&feats)]);
    assert_eq!(code, 0, "{so}{err}");
    let table = feats.join("features.parquet");
    let (code, _, err) = crate::aepipe(&[
        "cluster",
        &s(&table),
        "--out",
        &s(&out),
        "--columns",
        "nope",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("no column nope"), "{err}");
    let (code, _, err) = crate::aepipe(&[
        "cluster",
        &s(&table),
        "--out",
        &s(&out),
        "--method",
        "k-means",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("expected one of `kmeans`, `gmm`, `som-kmeans`"),
        "{err}"
    );
}
