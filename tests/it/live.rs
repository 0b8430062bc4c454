//! `aepipe watch` on a folder that receives WAV hits while it runs: killed with SIGKILL once
//! at a random point after its first commit and started again with the same arguments, it
//! must end with every hit a row exactly once, the live rows equal to the offline run's,
//! each hit's live SOM class equal to the offline run's, and its final tables byte-identical
//! to an `aepipe run` of the finished folder.

use super::{aepipe, files, table_rows, TempDir};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::time::{Duration, Instant};

const HITS: usize = 240;

fn start_watch(data: &Path, out: &Path, cfg: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .args([
            "watch",
            data.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .args(["--config", cfg.to_str().unwrap(), "--until-idle", "2"])
        .args(["--threads", "1"])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap()
}

/// Wait for a child, killing it after `limit`; its exit code and stdout.
fn wait_for(mut c: Child, limit: Duration) -> (Option<i32>, String) {
    let t = Instant::now();
    loop {
        if let Some(s) = c.try_wait().unwrap() {
            let mut out = String::new();
            use std::io::Read;
            c.stdout.take().unwrap().read_to_string(&mut out).unwrap();
            return (s.code(), out);
        }
        if t.elapsed() > limit {
            let _ = c.kill();
            panic!("aepipe watch did not end within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Rows by (experiment, channel, hit).
type Keyed = BTreeMap<(String, String, String), Vec<Vec<String>>>;

/// Rows of several tables with one header, keyed by (experiment, channel, hit).
fn keyed_rows(files: &[PathBuf]) -> (Vec<String>, Keyed) {
    let mut names = Vec::new();
    let mut rows: BTreeMap<_, Vec<Vec<String>>> = BTreeMap::new();
    for f in files {
        let (n, r) = table_rows(f);
        if !names.is_empty() {
            assert_eq!(n, names, "{}: another header", f.display());
        }
        names = n;
        let ix = |c: &str| names.iter().position(|x| x == c).unwrap();
        let (e, c, h) = (ix("experiment"), ix("channel"), ix("hit"));
        for row in r {
            rows.entry((row[e].clone(), row[c].clone(), row[h].clone()))
                .or_default()
                .push(row);
        }
    }
    (names, rows)
}

fn find(dir: &Path, name: &str) -> PathBuf {
    files(dir)
        .into_iter()
        .find(|e| e.file_name().is_some_and(|n| n == name))
        .unwrap_or_else(|| panic!("no {name} under {}", dir.display()))
}

#[test]
fn watch_a_folder_of_wav_hits_killed_and_restarted_exactly_once() {
    let t = TempDir::new("live-wav");
    let data = t.path().join("strip-7");
    std::fs::create_dir_all(&data).unwrap();
    let out = t.path().join("watch");
    let cfg = t.path().join("live.toml");
    std::fs::write(
        &cfg,
        // The synthetic hits' 500 pretrigger samples, which a WAV does not carry.
        "[ingest]\npretrigger_samples = 500\n[live]\nflush_s = 0.5\nsettle_s = 0.3\npoll_s = 0.05\n",
    )
    .unwrap();

    // The acquisition, started once the watcher is ready (its map trained, its page
    // written), as an operator starts the test: hits written in place (a file grows while
    // it is written) at ~80 hits/s, with a pause now and then.
    let writer_dir = data.clone();
    let page = out.join("live.html");
    let writer = std::thread::spawn(move || {
        let t0 = Instant::now();
        while !page.is_file() {
            assert!(
                t0.elapsed() < Duration::from_secs(180),
                "the watcher never got ready"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let e = aepipe::synth::Experiment::new("strip-7", HITS, 7);
        for (i, r) in e.records().enumerate() {
            let f = writer_dir.join(format!("hit_{:05}.wav", i + 1));
            aepipe::ingest::wavfmt::write_wav_f32(&f, r.sample_rate_hz as u32, &r.samples).unwrap();
            std::thread::sleep(Duration::from_millis(if i % 50 == 49 { 400 } else { 12 }));
        }
    });

    // A random kill point, printed so a failure can be replayed: after the first commit,
    // 0–1.5 s on.
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos();
    let delay = Duration::from_millis(u64::from(nanos % 1500));
    eprintln!("watch test: SIGKILL {delay:?} after the first commit");
    let mut first = start_watch(&data, &out, &cfg);
    let state = out.join("watch").join("state.json");
    let t0 = Instant::now();
    while !state.is_file() {
        assert!(
            t0.elapsed() < Duration::from_secs(180),
            "no commit within 180 s"
        );
        if let Some(s) = first.try_wait().unwrap() {
            panic!("aepipe watch ended early: {s}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(delay);
    first.kill().unwrap(); // SIGKILL
    first.wait().unwrap();
    let before: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&state).unwrap()).unwrap();
    eprintln!("killed with {} hits committed", before["hits"]);

    // Then a polite stop (SIGTERM, as Ctrl-C is SIGINT) once it has committed again: it
    // flushes what it read and exits 0.
    // The page is written once a watcher is ready (its signal handler installed, its map
    // loaded): a signal before that would be the default's, not the watcher's.
    let page = out.join("live.html");
    std::fs::remove_file(&page).unwrap();
    let second = start_watch(&data, &out, &cfg);
    let t1 = Instant::now();
    while !page.is_file() {
        assert!(
            t1.elapsed() < Duration::from_secs(120),
            "the restart never got ready"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let committed = |s: &Path| -> u64 {
        std::fs::read_to_string(s)
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|v| v["flushes"].as_u64())
            .unwrap_or(0)
    };
    let flushes_before = committed(&state);
    while committed(&state) < flushes_before + 2 && !writer.is_finished() {
        assert!(
            t1.elapsed() < Duration::from_secs(120),
            "no flush after the restart"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    unsafe { libc::kill(second.id() as i32, libc::SIGTERM) };
    let (code, said) = wait_for(second, Duration::from_secs(60));
    eprintln!("{said}");
    assert_eq!(code, Some(0), "SIGTERM: {said}");
    assert!(said.contains("stopped by a signal"), "{said}");
    assert!(
        !out.join("final").exists(),
        "a stopped watch is not the test's end"
    );

    let third = start_watch(&data, &out, &cfg);
    writer.join().unwrap();
    let (code, said) = wait_for(third, Duration::from_secs(300));
    eprintln!("{said}");
    assert_eq!(code, Some(0), "{said}");
    assert!(said.contains("watched: 240 hits"), "{said}");

    // Every hit a row exactly once, across the kill.
    let (names, live) = keyed_rows(&files(&out.join("features")));
    assert_eq!(live.len(), HITS, "distinct hits in the live parts");
    let dups: Vec<_> = live.iter().filter(|(_, v)| v.len() != 1).collect();
    assert!(
        dups.is_empty(),
        "hits written twice: {:?}",
        dups.first().map(|d| d.0)
    );
    let hits: BTreeSet<u64> = live.keys().map(|k| k.2.parse().unwrap()).collect();
    assert_eq!(hits, (1..=HITS as u64).collect(), "hit numbers 1..{HITS}");
    let (_, live_hits) = keyed_rows(&files(&out.join("hits")));
    assert_eq!(live_hits.len(), HITS);

    // The live rows are the offline run's, column by column.
    let final_features = find(&out.join("final"), "features.parquet");
    let (fnames, fin) = keyed_rows(std::slice::from_ref(&final_features));
    assert_eq!(fnames, names);
    assert_eq!(fin.len(), HITS);
    for (k, v) in &live {
        assert_eq!(&fin[k], v, "hit {k:?} differs between live and final");
    }

    // Each hit's live SOM class is the offline run's (the same map: trained on the same
    // reference library with the same seed).
    let (cn, live_cls) = keyed_rows(&files(&out.join("classification")));
    let (_, fin_cls) = keyed_rows(&[find(&out.join("final"), "classification.parquet")]);
    assert!(!live_cls.is_empty());
    assert_eq!(live_cls.len(), fin_cls.len(), "classified hits");
    let som = cn.iter().position(|c| c == "som_label").unwrap();
    for (k, v) in &live_cls {
        assert_eq!(v.len(), 1, "{k:?} classified twice");
        assert_eq!(v[0][som], fin_cls[k][0][som], "hit {k:?}'s class");
    }

    // The final tables are an offline `aepipe run`'s, byte for byte.
    let offline = t.path().join("offline");
    let (code, _, err) = aepipe(&[
        "run",
        "--config",
        cfg.to_str().unwrap(),
        data.to_str().unwrap(),
        "--out",
        offline.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    for name in [
        "features.parquet",
        "hits.parquet",
        "rejects.parquet",
        "classification.parquet",
    ] {
        let a = std::fs::read(find(&out.join("final"), name)).unwrap();
        let b = std::fs::read(find(&offline, name)).unwrap();
        assert!(
            a == b,
            "{name}: the watcher's final table differs from aepipe run's"
        );
    }

    // The live page is there, self-contained, reloading, and counts every hit.
    let html = std::fs::read_to_string(out.join("live.html")).unwrap();
    assert!(html.contains("http-equiv=\"refresh\""));
    assert!(html.contains(&format!("{HITS} hits")), "the page's count");
}

#[test]
fn watch_refuses_a_folder_written_with_other_settings() {
    let t = TempDir::new("live-cfg");
    let data = t.path().join("d");
    std::fs::create_dir_all(&data).unwrap();
    let out = t.path().join("w");
    std::fs::create_dir_all(out.join("watch")).unwrap();
    std::fs::write(
        out.join("watch").join("state.json"),
        r#"{"config_sha256":"0000","flushes":1,"parts":1,"hits":1,"rows":1,"rejects":0,"classes":{},"sources":{}}"#,
    )
    .unwrap();
    let (code, _, err) = aepipe(&[
        "watch",
        data.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--until-idle",
        "0",
    ]);
    assert_eq!(code, 1, "a usage error: {err}");
    assert!(err.contains("another configuration"), "{err}");
}
