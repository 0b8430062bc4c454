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
        .env("XDG_CACHE_HOME", crate::test_cache())
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
    let (t, data, out, cfg) = watch_test(
        "live-wav",
        "strip-7",
        // The synthetic hits' 500 pretrigger samples, which a WAV does not carry.
        "[ingest]\npretrigger_samples = 500\n[live]\nflush_s = 0.5\nsettle_s = 0.3\npoll_s = 0.05\n",
    );

    // The acquisition, started once the watcher is ready (its map trained, its page
    // written), as an operator starts the test: hits written in place (a file grows while
    // it is written) at ~80 hits/s, with a pause now and then.
    let writer_dir = data.clone();
    let writer = write_once_ready(&out, move || {
        let e = aepipe::synth::Experiment::new("strip-7", HITS, 7);
        for (i, r) in e.records().enumerate() {
            let f = writer_dir.join(format!("hit_{:05}.wav", i + 1));
            aepipe::ingest::wavfmt::write_wav_f32(&f, r.sample_rate_hz as u32, &r.samples).unwrap();
            std::thread::sleep(Duration::from_millis(if i % 50 == 49 { 400 } else { 12 }));
        }
    });

    kill_after_first_commit(&data, &out, &cfg, 1500);
    let state = out.join("watch").join("state.json");

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
    same_as_aepipe_run(
        t.path(),
        &cfg,
        &data,
        &out.join("final"),
        &[
            "features.parquet",
            "hits.parquet",
            "rejects.parquet",
            "classification.parquet",
        ],
    );

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

/// Rows of several tables keyed by one column (parametric and marker rows by `row`).
fn rows_by(files: &[PathBuf], key: &str) -> BTreeMap<(String, String), Vec<Vec<String>>> {
    let mut out: BTreeMap<_, Vec<Vec<String>>> = BTreeMap::new();
    for f in files {
        let (n, r) = table_rows(f);
        let (e, k) = (
            n.iter().position(|x| x == "experiment").unwrap(),
            n.iter().position(|x| x == key).unwrap(),
        );
        for row in r {
            out.entry((row[e].clone(), row[k].clone()))
                .or_default()
                .push(row);
        }
    }
    out
}

const PAIR_HITS: usize = 2400;

/// The acquisition of a Vallen pair as AMSY-6 writes it (rollback journal): hit rows in
/// small transactions at a few hundred hits/s (a source every 10 ms heard by two channels), its transient ~100 ms later, a parametric row (the load)
/// every 10 hits, a status row per channel every second; every 300th hit has no transient
/// index and hit 1 000's transient never comes.
fn write_growing_pair(base: &Path) {
    use aepipe::ingest::vallen::{HitToWrite, Journal, PairWriter};
    let e = aepipe::synth::Experiment::new("strip-9", PAIR_HITS, 9);
    let recs: Vec<_> = e.records().collect();
    // A source every 10 ms, heard by channel 1 and, 0–60 µs later, channel 2 (one event).
    let hit = |k: usize| HitToWrite {
        channel: 1 + (k % 2) as u32,
        trai: if k % 300 == 299 { 0 } else { k as u64 + 1 },
        time_s: 0.01 + 0.01 * (k / 2) as f64 + (k % 2) as f64 * 1e-6 * ((k / 2) % 61) as f64,
        sample_rate_hz: recs[k].sample_rate_hz,
        pretrigger: recs[k].pretrigger,
        samples_v: &recs[k].samples,
        restart: false,
        transient: k % 300 != 299 && k != 999,
    };
    let w = PairWriter::create(base, 1e-3, 1e-4, Journal::Delete).unwrap();
    let t0 = Instant::now();
    let mut transients: std::collections::VecDeque<(Instant, usize)> = Default::default();
    let mut next_status = 0.0;
    for chunk in (0..PAIR_HITS).collect::<Vec<_>>().chunks(5) {
        w.batch(|w| {
            for &k in chunk {
                let h = hit(k);
                if k % 10 == 0 {
                    w.parametric(h.time_s - 0.001, 0.1 * k as f64, 0.0)?;
                }
                w.hit(&h)?;
                if h.time_s >= next_status {
                    w.status(h.time_s, 1, 2e-5)?;
                    w.status(h.time_s, 2, 2e-5)?;
                    next_status += 1.0;
                }
                transients.push_back((Instant::now() + Duration::from_millis(100), k));
            }
            Ok(())
        })
        .unwrap();
        let now = Instant::now();
        w.batch(|w| {
            while transients.front().is_some_and(|(at, _)| *at <= now) {
                let h = hit(transients.pop_front().unwrap().1);
                if h.transient {
                    w.transient(&h)?;
                }
            }
            Ok(())
        })
        .unwrap();
        std::thread::sleep(Duration::from_millis(15));
    }
    std::thread::sleep(Duration::from_millis(100));
    w.batch(|w| {
        for (_, k) in transients.drain(..) {
            let h = hit(k);
            if h.transient {
                w.transient(&h)?;
            }
        }
        // The acquisition's last parametric row, after the last hit.
        w.parametric(0.02 + 0.01 * PAIR_HITS as f64, 0.1 * PAIR_HITS as f64, 0.0)
    })
    .unwrap();
    eprintln!("writer: {PAIR_HITS} hits in {:?}", t0.elapsed());
}

/// `aepipe watch` follows a Vallen pair while the acquisition appends to it (a few hundred
/// hits/s, transients a little after their hits, parametric and status rows), is killed
/// with SIGKILL once at a random point and started again: every hit a row exactly once,
/// the live rows (hits, features, rejects, parametric, markers) equal to the offline
/// run's, the final tables byte-identical to `aepipe run` of the finished pair.
#[test]
fn watch_a_growing_vallen_pair_killed_and_restarted_exactly_once() {
    let (t, data, out, cfg) = watch_test(
        "live-vallen",
        "acq",
        "[ingest.vallen]\nload_param = \"PA0\"\nload_n_per_mv = 1.0\n\
         [live]\nflush_s = 0.5\nsettle_s = 0.3\npoll_s = 0.05\ntransient_wait_s = 3\n\
         [location]\nkind = \"linear\"\nvelocity_m_s = 700\nsensors = { 1 = [-0.020], 2 = [0.020] }\n\
         zone = [-0.015, 0.015]\nexclude_outside = true\n",
    );
    let base = data.join("strip-9");
    kill_once_and_finish(&data, &out, &cfg, move || write_growing_pair(&base));

    // Every hit a row exactly once across the kill, every transient a features row once,
    // each equal to the final run's, the events columns included: the watcher's windows end
    // only where no event can span the end, so its events are the offline run's.
    let last = out.join("final");
    live_rows_are_the_final_ones(&out, &last, PAIR_HITS, PAIR_HITS - PAIR_HITS / 300 - 1);
    same_events_and_classes(&out, &last);
    page_draws_a_latest_hit(&out, true);
    // Located live: sources inside and outside the zone.
    let (zn, zr) = table_rows_of(&files(&out.join("events")));
    let zone = zn.iter().position(|c| c == "zone").unwrap();
    for z in ["inside", "outside"] {
        assert!(zr.iter().any(|r| r[zone] == z), "a source {z} the zone");
    }
    for (table, key) in [
        ("parametric", "row"),
        ("markers", "row"),
        ("events", "event"),
    ] {
        let live = rows_by(&files(&out.join(table)), key);
        let fin = rows_by(&[find(&last, &format!("{table}.parquet"))], key);
        assert!(!fin.is_empty(), "{table}: the pair holds some");
        for (k, v) in &live {
            assert_eq!(Some(v), fin.get(k), "{table} {k:?}");
        }
        assert_eq!(live, fin, "{table}: live rows and final rows");
    }
    let (_, live_rejects) = table_rows_of(&files(&out.join("rejects")));
    let missing: Vec<_> = live_rejects
        .iter()
        .filter(|r| r.iter().any(|c| c.contains("has no transient")))
        .collect();
    assert_eq!(
        missing.len(),
        1,
        "hit 1 000's missing transient, once: {missing:?}"
    );
    assert!(
        missing[0].iter().any(|c| c == "TRAI 1000 ch2"),
        "{missing:?}"
    );

    // The final tables are an offline `aepipe run`'s, byte for byte.
    same_as_aepipe_run(
        t.path(),
        &cfg,
        &data,
        &last,
        &[
            "features.parquet",
            "hits.parquet",
            "rejects.parquet",
            "parametric.parquet",
            "markers.parquet",
            "events.parquet",
            "classification.parquet",
        ],
    );
}

/// All rows of several tables with one header.
fn table_rows_of(files: &[PathBuf]) -> (Vec<String>, Vec<Vec<String>>) {
    let mut names = Vec::new();
    let mut rows = Vec::new();
    for f in files {
        let (n, r) = table_rows(f);
        names = n;
        rows.extend(r);
    }
    (names, rows)
}

const DTA_HITS: usize = 1200;

/// A MISTRAS acquisition: a `.DTA` appended in pieces cut anywhere (inside messages), a
/// source every 10 ms heard by two channels (a hit and its waveform each), hit 500 without a waveform, and a new chain
/// file (`X__2.DTA`, the setup again) from hit 700 on.
fn write_growing_dta(dir: &Path) {
    use super::dta::{hit, msg, setup, wave};
    use std::io::Write;
    let e = aepipe::synth::Experiment::new("X", DTA_HITS, 11);
    let chans = [(1u8, 0u8), (2, 0)];
    // Volts → counts at 0 dB: 10 V full scale over 32 768 counts.
    let counts = |v: &[f32]| -> Vec<i16> {
        v.iter()
            .map(|x| (*x as f64 * 3276.8).round().clamp(-32768.0, 32767.0) as i16)
            .collect()
    };
    let mut file = dir.join("X.DTA");
    let mut pending = setup(&chans, true);
    let append = |path: &Path, bytes: &[u8]| {
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .unwrap();
        f.write_all(bytes).unwrap();
    };
    let t0 = Instant::now();
    for (k, r) in e.records().enumerate() {
        if k == 700 {
            append(&file, &pending);
            pending = msg(8, &[0; 8]);
            pending.extend(setup(&chans, true));
            file = dir.join("X__2.DTA");
        }
        // A source every 10 ms, heard by channel 1 and 40 µs later channel 2.
        let (t, ch) = (
            1.0 + 0.01 * (k / 2) as f64 + (k % 2) as f64 * 40e-6,
            1 + (k % 2) as u8,
        );
        pending.extend(hit(t, ch, 60 + (k % 20) as u8, 5));
        if k != 500 {
            // The setup's 128 pretrigger samples (the synthetic record has 500).
            let skip = (r.pretrigger as usize).saturating_sub(128);
            pending.extend(wave(t, ch, &counts(&r.samples[skip..])));
        }
        if k % 5 == 4 {
            // All but a cut piece of the last message; the rest with the next hits.
            let cut = pending.len() - 100;
            append(&file, &pending[..cut]);
            pending.drain(..cut);
            std::thread::sleep(Duration::from_millis(15));
        }
    }
    append(&file, &pending);
    eprintln!("writer: {DTA_HITS} hits in {:?}", t0.elapsed());
}

/// `aepipe watch` follows a MISTRAS chain while the acquisition appends to it (pieces cut
/// inside messages, a new chain file midway), is killed with SIGKILL once at a random point
/// and started again: every hit a row exactly once, the live rows equal to the offline
/// run's, the final tables byte-identical to `aepipe run` of the finished chain.
#[test]
fn watch_a_growing_dta_chain_killed_and_restarted_exactly_once() {
    let (t, data, out, cfg) = watch_test(
        "live-dta",
        "acq",
        "[live]\nflush_s = 0.5\nsettle_s = 0.3\npoll_s = 0.05\ntransient_wait_s = 3\n",
    );
    let dir = data.clone();
    kill_once_and_finish(&data, &out, &cfg, move || write_growing_dta(&dir));

    // Every hit and waveform once, equal to the final run's (events included).
    let last = out.join("final");
    live_rows_are_the_final_ones(&out, &last, DTA_HITS, DTA_HITS - 1);
    assert_eq!(
        rows_by(&files(&out.join("events")), "event"),
        rows_by(&[find(&last, "events.parquet")], "event"),
        "events: live rows and final rows"
    );
    same_events_and_classes(&out, &last);
    page_draws_a_latest_hit(&out, false);

    // The final tables are an offline `aepipe run`'s, byte for byte.
    same_as_aepipe_run(
        t.path(),
        &cfg,
        &data,
        &last,
        &[
            "features.parquet",
            "hits.parquet",
            "rejects.parquet",
            "events.parquet",
            "classification.parquet",
        ],
    );
}

/// The live page shows the CWT of a latest hit (read from the growing pair or chain).
fn page_draws_a_latest_hit(out: &Path, with_load: bool) {
    let html = std::fs::read_to_string(out.join("live.html")).unwrap();
    let at = html
        .find("watch/live/latest-")
        .expect("a latest hit's CWT on the page");
    let png = &html[at..at + html[at..].find('?').unwrap()];
    assert!(out.join(png).is_file(), "{png}");
    // The damage profile so far: with a load channel, the peak load and rows per class
    // before and after it.
    assert_eq!(html.contains("Damage profile so far"), with_load);
    assert_eq!(html.contains("before the peak load"), with_load);
}

/// The live events are the final run's (some built: two channels hear each source), and
/// each classified row's live SOM class is the final run's (one row per event: the same
/// map, the same first hits).
fn same_events_and_classes(out: &Path, last: &Path) {
    let (en, _) = table_rows(&files(&out.join("events"))[0]);
    let live = rows_by(&files(&out.join("events")), "event");
    let chans = en.iter().position(|c| c == "channels").unwrap();
    let two = live.values().filter(|v| v[0][chans] == "[1, 2]").count();
    assert!(
        two > live.len() / 2,
        "sources heard by both channels: {two} of {}",
        live.len()
    );
    let (cn, live_cls) = keyed_rows(&files(&out.join("classification")));
    let (_, fin_cls) = keyed_rows(&[find(last, "classification.parquet")]);
    assert_eq!(live_cls.len(), fin_cls.len(), "classified rows");
    let som = cn.iter().position(|c| c == "som_label").unwrap();
    for (k, v) in &live_cls {
        assert_eq!(v.len(), 1, "{k:?} classified twice");
        assert_eq!(v[0][som], fin_cls[k][0][som], "{k:?}'s class");
    }
}

/// Start the watcher on `data`, start the acquisition (`write`) once the watcher is ready,
/// SIGKILL the watcher at a random moment 0–3 s after its first commit (printed, so that a
/// failure can be replayed), start it again with the same arguments and let it run to
/// idle: it must end with exit 0.
fn kill_once_and_finish(
    data: &Path,
    out: &Path,
    cfg: &Path,
    write: impl FnOnce() + Send + 'static,
) {
    let writer = write_once_ready(out, write);
    kill_after_first_commit(data, out, cfg, 3000);
    let again = start_watch(data, out, cfg);
    writer.join().unwrap();
    let (code, said) = wait_for(again, Duration::from_secs(300));
    eprintln!("{said}");
    assert_eq!(code, Some(0), "{said}");
}

/// A test's folders: the acquisition's (`data_name`), the watcher's, and its configuration
/// (`toml`).
fn watch_test(name: &str, data_name: &str, toml: &str) -> (TempDir, PathBuf, PathBuf, PathBuf) {
    let t = TempDir::new(name);
    let data = t.path().join(data_name);
    std::fs::create_dir_all(&data).unwrap();
    let (out, cfg) = (t.path().join("watch"), t.path().join("live.toml"));
    std::fs::write(&cfg, toml).unwrap();
    (t, data, out, cfg)
}

/// Run the acquisition (`write`) on a thread of its own once the watcher writing into
/// `out` is ready (its map trained, its page written), as an operator starts the test.
fn write_once_ready(
    out: &Path,
    write: impl FnOnce() + Send + 'static,
) -> std::thread::JoinHandle<()> {
    let page = out.join("live.html");
    std::thread::spawn(move || {
        let t0 = Instant::now();
        while !page.is_file() {
            assert!(
                t0.elapsed() < Duration::from_secs(180),
                "the watcher never got ready"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        write();
    })
}

/// Start the watcher and SIGKILL it at a random moment 0–`max_ms` ms after its first
/// commit (printed, so that a failure can be replayed).
fn kill_after_first_commit(data: &Path, out: &Path, cfg: &Path, max_ms: u32) {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos();
    let delay = Duration::from_millis(u64::from(nanos % max_ms));
    eprintln!("watch test: SIGKILL {delay:?} after the first commit");
    let mut first = start_watch(data, out, cfg);
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
    eprintln!(
        "killed with {} hits committed, at {}",
        before["hits"], before["sources"]
    );
}

/// `aepipe run` of the finished acquisition (into `root/offline`) writes the tables `names`
/// byte for byte as the watcher's final run (`last`) did.
fn same_as_aepipe_run(root: &Path, cfg: &Path, data: &Path, last: &Path, names: &[&str]) {
    let offline = root.join("offline");
    let (code, _, err) = aepipe(&[
        "run",
        "--config",
        cfg.to_str().unwrap(),
        data.to_str().unwrap(),
        "--out",
        offline.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    for name in names {
        let a = std::fs::read(find(last, name)).unwrap();
        let b = std::fs::read(find(&offline, name)).unwrap();
        assert!(
            a == b,
            "{name}: the watcher's final table differs from aepipe run's"
        );
    }
}

/// Across all flushes' parts: hits 1..=`hits` each one row, `records` distinct features
/// rows each once, and every live hits and features row equal to the final run's (all
/// columns).
fn live_rows_are_the_final_ones(out: &Path, last: &Path, hits: usize, records: usize) {
    let (_, live_hits) = keyed_rows(&files(&out.join("hits")));
    assert_eq!(live_hits.len(), hits, "distinct hits in the live parts");
    assert!(
        live_hits.values().all(|v| v.len() == 1),
        "a hit written twice"
    );
    let numbers: BTreeSet<u64> = live_hits.keys().map(|k| k.2.parse().unwrap()).collect();
    assert_eq!(numbers, (1..=hits as u64).collect());
    let (names, live) = keyed_rows(&files(&out.join("features")));
    assert_eq!(live.len(), records, "distinct records in the live parts");
    assert!(
        live.values().all(|v| v.len() == 1),
        "a record written twice"
    );
    let (fnames, fin) = keyed_rows(&[find(last, "features.parquet")]);
    assert_eq!(fnames, names);
    assert_eq!(fin.len(), live.len());
    for (k, v) in &live {
        assert_eq!(&fin[k], v, "record {k:?} differs between live and final");
    }
    let (_, fin_hits) = keyed_rows(&[find(last, "hits.parquet")]);
    for (k, v) in &live_hits {
        assert_eq!(&fin_hits[k], v, "hit {k:?} differs between live and final");
    }
}

const STREAM_RATE: f64 = 5e6;
const STREAM_SOURCES: usize = 150;

/// A digitiser writing a raw two-channel int16 stream (10 µV a count, noise of 2 counts):
/// a source every 10 ms from 50 ms on, a decaying 300 kHz burst of 300–3 000 counts heard
/// by channel 1 and 40 µs later, at 70 %, by channel 2. The `.toml` first, then the
/// samples appended in pieces of about 0.7 MB cut anywhere (inside a frame, inside a
/// sample), one every 60 ms (about 3 s: the watcher is killed while the stream grows).
fn write_growing_stream(dir: &Path) {
    use std::io::Write;
    std::fs::write(
        dir.join("s.bin.toml"),
        "dtype = \"int16\"\nchannels = 2\nsample_rate_hz = 5e6\nvolts_per_unit = 1e-5\n",
    )
    .unwrap();
    let n = (1.6 * STREAM_RATE) as usize;
    let mut rng = aepipe::util::Rng::new(5);
    let mut ch: [Vec<f64>; 2] = [0, 1].map(|_| (0..n).map(|_| 2.0 * rng.normal()).collect());
    for k in 0..STREAM_SOURCES {
        let a = 300.0 + 2700.0 * ((k * 37) % 100) as f64 / 100.0;
        let t0 = 0.05 + 0.01 * k as f64;
        for (c, (delay, gain)) in [(0.0, 1.0), (40e-6, 0.7)].into_iter().enumerate() {
            let at = ((t0 + delay) * STREAM_RATE) as usize;
            for j in 0..(400e-6 * STREAM_RATE) as usize {
                let t = j as f64 / STREAM_RATE;
                ch[c][at + j] +=
                    gain * a * (-t / 30e-6).exp() * (2.0 * std::f64::consts::PI * 300e3 * t).sin();
            }
        }
    }
    let bytes: Vec<u8> = (0..n)
        .flat_map(|k| [ch[0][k], ch[1][k]])
        .flat_map(|v| (v.round().clamp(-32768.0, 32767.0) as i16).to_le_bytes())
        .collect();
    let mut f = std::fs::File::create(dir.join("s.bin")).unwrap();
    let mut at = 0;
    let t0 = Instant::now();
    while at < bytes.len() {
        let piece = (700_001 + (at * 7919) % 131_071).min(bytes.len() - at);
        f.write_all(&bytes[at..at + piece]).unwrap();
        f.flush().unwrap();
        at += piece;
        std::thread::sleep(Duration::from_millis(60));
    }
    eprintln!("writer: {} bytes in {:?}", bytes.len(), t0.elapsed());
}

/// `aepipe watch` cuts a raw stream while the digitiser writes it (`[detect]` on), is
/// killed with SIGKILL once at a random point and started again: every burst on each channel
/// one hit, each exactly once and numbered as the offline cut numbers it (in the order of
/// first crossings), the live rows and events equal to the final run's, and the final
/// tables byte-identical to `aepipe run` of the finished stream.
#[test]
fn watch_a_growing_stream_killed_and_restarted_exactly_once() {
    let (t, data, out, cfg) = watch_test(
        "live-stream",
        "acq",
        "[live]\nflush_s = 0.5\nsettle_s = 0.3\npoll_s = 0.05\ntransient_wait_s = 2\n\n\
         [detect]\nmode = \"on\"\nthreshold_db = 50.0\nblock_samples = 65536\n",
    );
    let dir = data.clone();
    kill_once_and_finish(&data, &out, &cfg, move || write_growing_stream(&dir));
    let last = out.join("final");
    let hits = 2 * STREAM_SOURCES;
    live_rows_are_the_final_ones(&out, &last, hits, hits);
    assert_eq!(
        rows_by(&files(&out.join("events")), "event"),
        rows_by(&[find(&last, "events.parquet")], "event"),
        "events: live rows and final rows"
    );
    same_events_and_classes(&out, &last);
    same_as_aepipe_run(
        t.path(),
        &cfg,
        &data,
        &last,
        &[
            "features.parquet",
            "hits.parquet",
            "rejects.parquet",
            "events.parquet",
        ],
    );
    // live.html draws the same explorable charts, in a browser with no error.
    if let Some(v) = crate::explore::browser(&out.join("live.html")) {
        assert_eq!(v["errors"], serde_json::json!([]), "{v}");
        assert_eq!(v["requests"], serde_json::json!([]), "{v}");
        let charts = v["charts"].as_array().expect("the explorer ran");
        assert!(charts.len() >= 3, "{v}");
        for c in charts {
            assert_eq!(c["drawn"], true, "{c}");
            assert!(c["points"].as_u64().unwrap() > 0, "{c}");
        }
        // A click on a point names that hit (none is embedded: the command draws it).
        let click = &v["clicks"][1];
        assert_eq!(click["key"], click["expected"], "{v}");
        assert!(
            click["command"].as_str().unwrap().contains("aepipe cwt '"),
            "{v}"
        );
    }
}
