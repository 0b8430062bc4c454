//! The streaming pipeline: determinism across thread counts, schema files as a contract,
//! round trips through `waveforms.parquet`, and no half-written output after a kill.

use crate::{real_data, table_rows, TempDir};
use aepipe::config::PipelineConfig;
use aepipe::pipeline::{run, StreamJob, StreamOptions};
use aepipe::store::{arrow_doc_name, parse_schema_markdown, read_parquet};
use aepipe::synth::Experiment;
use std::path::{Path, PathBuf};

fn opts(threads: usize) -> StreamOptions {
    StreamOptions::with_threads(threads)
}

/// A synthetic Vallen experiment written with aepipe's writer.
fn synthetic(dir: &Path, id: &str, hits: usize, seed: u64) -> PathBuf {
    let mut e = Experiment::new(id, hits, seed);
    e.n_samples = 1024;
    e.write_vallen(dir).unwrap();
    dir.to_path_buf()
}

fn demo_cfg() -> aepipe::config::ValidConfig {
    let mut cfg = PipelineConfig::default();
    cfg.ingest.vallen.load_param = Some(aepipe::config::ParamInput(0));
    cfg.ingest.vallen.extension_param = Some(aepipe::config::ParamInput(1));
    cfg.pipeline.batch_size = 7; // many small batches: ordering is exercised
    cfg.check().unwrap()
}

#[test]
fn features_are_byte_identical_for_one_and_two_threads() {
    let t = TempDir::new("det");
    let data = synthetic(&t.path().join("data"), "exp_a", 300, 1);
    synthetic(&t.path().join("data"), "exp_b", 50, 2);
    let mut inputs = vec![data];
    if let Some(real) = real_data("features_are_byte_identical_for_one_and_two_threads (real part)")
    {
        inputs.push(real);
    }
    let cfg = demo_cfg();
    let r1 = run(
        StreamJob::Features,
        &inputs,
        &t.path().join("t1"),
        &cfg,
        &opts(1),
    )
    .unwrap();
    let r2 = run(
        StreamJob::Features,
        &inputs,
        &t.path().join("t2"),
        &cfg,
        &opts(2),
    )
    .unwrap();
    assert!(r1.stats.rows >= 350);
    let a = std::fs::read(&r1.table_path).unwrap();
    let b = std::fs::read(&r2.table_path).unwrap();
    assert!(a == b, "features.parquet differs between --threads 1 and 2");
    assert_eq!(
        std::fs::read(&r1.rejects_path).unwrap(),
        std::fs::read(&r2.rejects_path).unwrap()
    );
    // And the order is (experiment, channel, hit) inside each source; a MISTRAS stream
    // keeps its storage (time) order, where the transient numbers rise.
    let (names, rows) = table_rows(&r1.table_path);
    let (e, c, h) = (
        names.iter().position(|n| n == "experiment").unwrap(),
        names.iter().position(|n| n == "channel").unwrap(),
        names.iter().position(|n| n == "hit").unwrap(),
    );
    let stream_ordered = |exp: &str| exp == "210527-CH1-15";
    let keys: Vec<(String, i64, i64)> = rows
        .iter()
        .map(|r| {
            let ch = if stream_ordered(&r[e]) {
                0
            } else {
                r[c].parse().unwrap()
            };
            (r[e].clone(), ch, r[h].parse().unwrap())
        })
        .collect();
    let mut sorted = keys.clone();
    sorted.sort();
    assert_eq!(keys, sorted);
}

pub fn check_against_schema_file(parquet: &Path, schema_md: &str) {
    let (schema, kv, _) = read_parquet(parquet).unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("data-schema")
            .join(schema_md),
    )
    .unwrap();
    let doc = parse_schema_markdown(&text);
    let written: Vec<(String, String, bool)> = schema
        .fields()
        .iter()
        .map(|f| {
            (
                f.name().clone(),
                arrow_doc_name(f.data_type()),
                f.is_nullable(),
            )
        })
        .collect();
    assert_eq!(
        written,
        doc,
        "{} drifted from data-schema/{schema_md}",
        parquet.display()
    );
    let table = kv
        .iter()
        .find(|(k, _)| k == "aepipe.table")
        .map(|(_, v)| v.clone());
    assert_eq!(table.as_deref(), Some(schema_md.trim_end_matches(".md")));
    assert!(kv
        .iter()
        .any(|(k, v)| k == "aepipe.config_sha256" && v.len() == 64));
}

#[test]
fn schema_files_match_written_tables() {
    let t = TempDir::new("schema");
    let data = synthetic(&t.path().join("data"), "exp", 20, 3);
    let cfg = demo_cfg();
    let f = run(
        StreamJob::Features,
        std::slice::from_ref(&data),
        &t.path().join("f"),
        &cfg,
        &opts(2),
    )
    .unwrap();
    let w = run(
        StreamJob::Waveforms,
        &[data],
        &t.path().join("w"),
        &cfg,
        &opts(2),
    )
    .unwrap();
    check_against_schema_file(&f.table_path, "features.md");
    check_against_schema_file(&f.rejects_path, "rejects.md");
    check_against_schema_file(&f.hits_path, "hits.md");
    check_against_schema_file(&w.table_path, "waveforms.md");
    check_against_schema_file(&w.hits_path, "hits.md");
    check_against_schema_file(&f.events_path, "events.md");
    // The manifest records the same config hash as the Parquet metadata.
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&f.manifest_path).unwrap()).unwrap();
    assert_eq!(m["config_sha256"].as_str().unwrap(), cfg.hash());
    assert_eq!(m["counts"]["rows_written"], 20);
    assert_eq!(m["inputs"].as_array().unwrap().len(), 2);
    for key in [
        "tool",
        "job",
        "started_utc",
        "finished_utc",
        "threads",
        "config",
        "skipped",
        "experiments",
        "outputs",
        "timings_s",
    ] {
        assert!(!m[key].is_null(), "manifest lacks {key}");
    }
}

#[test]
fn waveforms_parquet_round_trips_into_identical_features() {
    let t = TempDir::new("roundtrip");
    let data = synthetic(&t.path().join("data"), "exp", 40, 4);
    let cfg = demo_cfg();
    let w = run(
        StreamJob::Waveforms,
        std::slice::from_ref(&data),
        &t.path().join("w"),
        &cfg,
        &opts(2),
    )
    .unwrap();
    let direct = run(
        StreamJob::Features,
        &[data],
        &t.path().join("direct"),
        &cfg,
        &opts(2),
    )
    .unwrap();
    let via = run(
        StreamJob::Features,
        std::slice::from_ref(&w.table_path),
        &t.path().join("via"),
        &cfg,
        &opts(2),
    )
    .unwrap();
    let (n1, r1) = table_rows(&direct.table_path);
    let (n2, r2) = table_rows(&via.table_path);
    assert_eq!(n1, n2);
    assert_eq!(r1.len(), 40);
    // Every column equal (source_file too: the waveform table carries the original file).
    assert_eq!(r1, r2);
    // Load and extension survive (PA0/PA1 of the synthetic test machine).
    let li = n1.iter().position(|n| n == "load_n").unwrap();
    assert!(r1.iter().all(|r| !r[li].is_empty()), "load missing");
}

#[test]
fn synthetic_load_is_read_back_from_parametric_rows() {
    let t = TempDir::new("load");
    let data = synthetic(&t.path().join("data"), "exp", 60, 5);
    let (recs, rejs) = crate::read_all(&[data], &demo_cfg());
    assert!(rejs.is_empty(), "{rejs:?}");
    let e = Experiment::new("exp", 60, 5);
    let t_peak = 0.8 * e.duration_s;
    for r in &recs {
        let t = r.time_s.unwrap();
        // PA0 is sampled at 10 Hz and quantised to 1 µV: linear interpolation of a smooth
        // curve is within a few mN of it.
        let want = aepipe::synth::load_curve(t, t_peak, 60.0);
        assert!(
            (r.load_n.unwrap() - want).abs() < 0.02,
            "t {t}: {} vs {want}",
            r.load_n.unwrap()
        );
        assert!((r.extension_m.unwrap() - 1e-3 * t / e.duration_s).abs() < 1e-8);
        assert!(r.label.is_none()); // Vallen files carry no label
    }
}

#[test]
fn killing_a_run_leaves_no_features_file_and_the_rerun_succeeds() {
    let t = TempDir::new("kill");
    let data = t.path().join("data");
    let mut e = Experiment::new("big", 6000, 9);
    e.n_samples = 4096;
    e.write_vallen(&data).unwrap();
    let out = t.path().join("out");
    let bin = env!("CARGO_BIN_EXE_aepipe");
    let mut child = std::process::Command::new(bin)
        .env("XDG_CACHE_HOME", crate::test_cache())
        .args([
            "features",
            data.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--threads",
            "1",
            "--quiet",
        ])
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Wait until the run has started writing (its temporary table exists), then kill it.
    let t0 = std::time::Instant::now();
    let mut killed_mid_run = false;
    while t0.elapsed().as_secs() < 60 {
        let tmp_exists = std::fs::read_dir(&out)
            .map(|rd| {
                rd.flatten()
                    .any(|e| e.file_name().to_string_lossy().contains(".tmp-"))
            })
            .unwrap_or(false);
        if tmp_exists {
            std::thread::sleep(std::time::Duration::from_millis(50));
            killed_mid_run = child.try_wait().unwrap().is_none();
            child.kill().unwrap();
            break;
        }
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let _ = child.wait();
    if killed_mid_run {
        assert!(
            !out.join("features.parquet").exists(),
            "a killed run left features.parquet"
        );
        assert!(!out.join("manifest.json").exists());
    } else {
        eprintln!("note: the run finished before it could be killed; only the rerun is checked");
    }
    let st = std::process::Command::new(bin)
        .env("XDG_CACHE_HOME", crate::test_cache())
        .args([
            "features",
            data.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .status()
        .unwrap();
    assert!(st.success());
    assert!(out.join("features.parquet").exists());
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    let (_, rows) = table_rows(&out.join("features.parquet"));
    assert_eq!(rows.len(), 6000);
}

#[test]
fn every_shipped_pipeline_file_parses() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap().flatten() {
        if e.path().extension().is_some_and(|x| x == "toml") {
            let text = std::fs::read_to_string(e.path()).unwrap();
            if text.lines().any(|l| l.trim() == "[[chain]]") {
                // Measurement chains (synth-experiment --chain, bench transfer), each
                // checked at the synthetic tests' sample rate.
                let f = aepipe::sim::chain::ChainFile::parse(&text).unwrap();
                for c in &f.chain {
                    c.check(aepipe::synth::SAMPLE_RATE_HZ)
                        .unwrap_or_else(|err| panic!("{err}"));
                }
            } else if text.lines().any(|l| l.trim() == "[reference]") {
                // A reference-library definition (aepipe reference), not a pipeline.
                aepipe::sim::reference::ReferenceFile::read(&e.path())
                    .unwrap_or_else(|err| panic!("{err}"));
            } else {
                PipelineConfig::from_file(&e.path()).unwrap_or_else(|err| panic!("{err}"));
            }
            n += 1;
        }
    }
    assert!(n >= 3);
    // The thesis-defaults file states the built-in defaults of every section it shares with
    // them (the Vallen parametric mapping is the one deliberate difference).
    let mut np = PipelineConfig::from_file(&dir.join("notched-paper.toml"))
        .unwrap()
        .into_inner();
    np.ingest.vallen = PipelineConfig::default().ingest.vallen;
    assert_eq!(np, PipelineConfig::default());
}

#[test]
fn python_readers_open_every_table() {
    if crate::reference(
        "python_readers_open_every_table",
        "pip install polars pandas pyarrow; .ci/run does",
        std::process::Command::new("python3").args(["-c", "import polars, pandas, pyarrow"]),
    )
    .is_none()
    {
        return;
    }
    let t = TempDir::new("py");
    let data = synthetic(&t.path().join("data"), "exp", 25, 11);
    let cfg = demo_cfg();
    run(
        StreamJob::Features,
        std::slice::from_ref(&data),
        &t.path().join("f"),
        &cfg,
        &opts(2),
    )
    .unwrap();
    run(
        StreamJob::Waveforms,
        &[data],
        &t.path().join("w"),
        &cfg,
        &opts(2),
    )
    .unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/check_tables.py");
    let o = std::process::Command::new("python3")
        .arg(script)
        .arg(t.path())
        .output()
        .unwrap();
    let so = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{so}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // features, waveforms, and the hits, rejects, parametric, marker and event rows of each
    // run; each again in the run's one per-experiment part (`parts/`).
    assert_eq!(
        so.lines().filter(|l| l.starts_with("ok ")).count(),
        24,
        "{so}"
    );
}

/// Issue 39 part 4: the RA–AF columns of both tables follow from their own rise time,
/// amplitude, counts and duration, and `[crack_mode] af_per_ra` moves the line: each hit's
/// mode is the side of the line its (RA, AF) lies on, recomputed here.
#[test]
fn ra_af_and_crack_mode_follow_from_each_row_and_the_configured_line() {
    let t = crate::TempDir::new("crack-mode");
    for (slope, name) in [(1.0, "one"), (2000.0, "steep")] {
        let cfg = aepipe::config::PipelineConfig::from_toml(&format!(
            "[crack_mode]\naf_per_ra = {slope}\n"
        ))
        .unwrap();
        let feats = crate::synthetic_features(&t.path().join(name), "crk", 60, 4, &cfg, 1);
        // The system's own hit features: the real Vallen set's (aepipe's synthetic .pridb
        // stores no rise time or duration, so its hits have no RA–AF).
        let mut tables = vec![(feats.clone(), "peak_amplitude_v")];
        if let Some(real) = crate::real_data("ra_af_and_crack_mode_follow_from_each_row") {
            let r = aepipe::pipeline::run(
                aepipe::pipeline::StreamJob::Features,
                &[real.join("vallen")],
                &t.path().join(name).join("real"),
                &cfg,
                &aepipe::pipeline::StreamOptions::with_threads(1),
            )
            .unwrap();
            tables.push((r.table_path.with_file_name("hits.parquet"), "amplitude_db"));
        }
        for (table, amp) in tables {
            let (rise, counts, dur) = ("rise_time_s", "counts", "duration_s");
            let (names, rows) = crate::table_rows(&table);
            let k = |n: &str| names.iter().position(|c| c == n).unwrap();
            let num = |r: &Vec<String>, n: &str| r[k(n)].parse::<f64>().ok();
            let (mut tensile, mut shear) = (0, 0);
            for r in &rows {
                let a = num(r, amp).map(|a| {
                    if amp == "amplitude_db" {
                        1e-6 * 10f64.powf(a / 20.0)
                    } else {
                        a
                    }
                });
                let ra = match (num(r, rise), a) {
                    (Some(x), Some(a)) if a > 0.0 => Some(x * 1e3 / a),
                    _ => None,
                };
                let af = match (num(r, counts), num(r, dur)) {
                    (Some(c), Some(d)) if d > 0.0 => Some(c / (d * 1e3)),
                    _ => None,
                };
                let close = |got: Option<f64>, want: Option<f64>| match (got, want) {
                    (Some(g), Some(w)) => (g - w).abs() <= 1e-9 * w.abs().max(1e-12),
                    (None, None) => true,
                    _ => false,
                };
                assert!(
                    close(num(r, "ra_ms_per_v"), ra),
                    "{}: RA {r:?}",
                    table.display()
                );
                assert!(close(num(r, "af_khz"), af), "{}: AF {r:?}", table.display());
                let want = match (ra, af) {
                    (Some(x), Some(y)) if y > slope * x => "tensile",
                    (Some(_), Some(_)) => "shear",
                    _ => "",
                };
                assert_eq!(r[k("crack_mode")], want, "{r:?}");
                tensile += usize::from(want == "tensile");
                shear += usize::from(want == "shear");
            }
            // Each line splits this test's hits into both modes somewhere, or the test
            // would not tell a moved line from a fixed one.
            if slope > 1.0 {
                assert!(
                    shear > 0,
                    "{}: no shear hit at slope {slope}",
                    table.display()
                );
            } else {
                assert!(
                    tensile > 0,
                    "{}: no tensile hit at slope {slope}",
                    table.display()
                );
            }
        }
    }
    assert!(aepipe::config::PipelineConfig::from_toml("[crack_mode]\naf_per_ra = 0\n").is_err());
}

/// Issue 39 part 3: `aepipe cluster` writes the tables its schema files document, one
/// validity row per k with one chosen, and a cluster for every usable row; bad settings
/// are usage errors naming the key.
#[test]
fn cluster_command_writes_the_documented_tables() {
    let t = crate::TempDir::new("cluster-cli");
    let feats = crate::synthetic_features(
        t.path(),
        "clu",
        120,
        6,
        &aepipe::config::ValidConfig::default(),
        1,
    );
    let out = t.path().join("c");
    let (code, so, se) = crate::aepipe(&[
        "cluster",
        feats.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--method",
        "gmm",
        "--k",
        "2..5",
    ]);
    assert_eq!(code, 0, "{so}{se}");
    check_against_schema_file(&out.join("clusters.parquet"), "clusters.md");
    check_against_schema_file(&out.join("validity.parquet"), "validity.md");
    let (names, rows) = table_rows(&out.join("validity.parquet"));
    let k = |n: &str| names.iter().position(|c| c == n).unwrap();
    let ks: Vec<&str> = rows.iter().map(|r| r[k("k")].as_str()).collect();
    assert_eq!(ks, ["2", "3", "4", "5"]);
    assert_eq!(rows.iter().filter(|r| r[k("chosen")] == "true").count(), 1);
    assert!(rows.iter().all(|r| !r[k("bic")].is_empty()));
    let (_, feat_rows) = table_rows(&feats);
    let (cn, crows) = table_rows(&out.join("clusters.parquet"));
    let p = cn.iter().position(|c| c == "cluster_probability").unwrap();
    assert!(crows
        .iter()
        .all(|r| r[p].parse::<f64>().is_ok_and(|v| (0.0..=1.0).contains(&v))));
    // Every row of the synthetic set has every default column: all clustered.
    assert_eq!(crows.len(), feat_rows.len());
    assert!(so.contains("hits per cluster"), "{so}");
    let (code, _, se) = crate::aepipe(&[
        "cluster",
        feats.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--k",
        "1..3",
    ]);
    assert_eq!(code, 1);
    assert!(se.contains("k_min"), "{se}");
}

/// Issue 39 part 5: `aepipe statistics` writes the documented table, one row per
/// experiment, and says when there are too few energies for a fit.
#[test]
fn statistics_command_writes_the_documented_table() {
    let t = crate::TempDir::new("statistics-cli");
    let feats = crate::synthetic_features(
        t.path(),
        "stat",
        80,
        2,
        &aepipe::config::ValidConfig::default(),
        1,
    );
    let out = t.path().join("s");
    let (code, so, se) = crate::aepipe(&[
        "statistics",
        feats.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{so}{se}");
    check_against_schema_file(&out.join("statistics.parquet"), "statistics.md");
    let (names, rows) = table_rows(&out.join("statistics.parquet"));
    assert_eq!(rows.len(), 1);
    let k = |n: &str| names.iter().position(|c| c == n).unwrap();
    assert_eq!(rows[0][k("n_energy")], "80");
    // 80 energies: a fit of at least 50 above x_min, α > 1.
    let a: f64 = rows[0][k("energy_alpha")].parse().unwrap();
    assert!(a > 1.0, "{so}");
    assert!(so.contains("α = "), "{so}");
}
