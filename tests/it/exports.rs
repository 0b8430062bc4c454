//! Other labs' text exports, recognised by what they hold: AEwin waveform exports with a
//! header (both variants, any key order, CRLF or LF, `.txt` or `.csv`), WaveExplorer
//! exports of 1–4 channels under any name, Vallen TXT transient exports alone and beside
//! their `.tradb`, a Vallen recording paused and resumed (not a restart), and the word
//! aepipe gives on a file it cannot read. Every fixture is written here, by the tests' own
//! writers below; what is read back must equal what was written.

use crate::{aepipe, read_all, table_rows, TempDir};
use aepipe::config::ValidConfig;
use aepipe::ingest::vallen::{HitToWrite, Journal, PairWriter};
use aepipe::model::{AeRecord, Reject};
use aepipe::pipeline::{run, StreamJob, StreamOptions};
use std::path::{Path, PathBuf};

/// The samples as the export writes them: `(text, value the text holds)`.
fn burst(n: usize, seed: u64, scale: f64, decimals: usize) -> Vec<(String, f64)> {
    let mut rng = aepipe::util::Rng::new(seed);
    (0..n)
        .map(|i| {
            let env = if i >= n / 8 {
                (-((i - n / 8) as f64) / (n as f64 / 6.0)).exp()
            } else {
                0.02
            };
            let v = scale * env * ((i as f64) * 0.7).sin() + scale * 1e-3 * rng.normal();
            let text = format!("{v:.decimals$}");
            let value: f64 = text.trim().parse().unwrap();
            (text, value)
        })
        .collect()
}

/// An AEwin waveform export with a header.
struct AewinExport<'a> {
    /// 1: `UNITS`, no point count; 2: `SIGNAL UNITS`, `TIME UNITS`, `DATA TYPE`, points.
    variant: u8,
    channel: u32,
    hit: u64,
    time_s: f64,
    interval_s: f64,
    values: &'a [(String, f64)],
    unit: &'a str,
    /// The point count the header declares (variant 2), when it is not the truth.
    points_lie: Option<usize>,
    crlf: bool,
    reversed: bool,
    extra_key: Option<&'a str>,
}

impl AewinExport<'_> {
    fn write(&self, path: &Path) {
        let mut keys: Vec<String> = vec![
            "SOURCE FILE NAME: C:\\AEWIN\\DATA\\PLB.DTA".into(),
            "DATE: Friday, March 13, 2015".into(),
            "TIME: 10:30:12".into(),
            format!("SAMPLE INTERVAL (Seconds): {:.6E}", self.interval_s),
        ];
        if self.variant == 1 {
            keys.push(format!("UNITS: {}", self.unit));
        } else {
            keys.push(format!("SIGNAL UNITS: {}", self.unit));
            keys.push("TIME UNITS: Seconds".into());
            keys.push("DATA TYPE: Float".into());
            keys.push(format!(
                "NUMBER OF DATA POINTS PER WAVEFORM: {}",
                self.points_lie.unwrap_or(self.values.len())
            ));
        }
        keys.push(format!("CHANNEL NUMBER: {}", self.channel));
        keys.push(format!("HIT NUMBER: {}", self.hit));
        keys.push(format!("TIME OF TEST: {:.7}", self.time_s));
        if let Some(k) = self.extra_key {
            keys.push(k.into());
        }
        if self.reversed {
            keys.reverse();
        }
        let eol = if self.crlf { "\r\n" } else { "\n" };
        let mut s = keys.join(eol);
        s.push_str(eol);
        s.push_str(eol);
        for (t, _) in self.values {
            // AEwin pads positive values with a space.
            if t.starts_with('-') {
                s.push_str(t);
            } else {
                s.push(' ');
                s.push_str(t);
            }
            s.push_str(eol);
        }
        std::fs::write(path, s).unwrap();
    }
}

fn aewin_name(test: &str, ch: u32, hit: u64, time_s: f64, ext: &str) -> String {
    format!("{test}_{ch}_{hit}_{}.{ext}", (time_s * 1e6).round() as u64)
}

/// Configuration: no preamplifier to divide out (the values are compared as written).
fn no_gain() -> ValidConfig {
    ValidConfig::default()
        .with(|c| c.ingest.aewin.preamp_gain_db = 0.0)
        .unwrap()
}

fn record(recs: &[AeRecord], ch: u32, hit: u64) -> &AeRecord {
    recs.iter()
        .find(|r| r.channel == ch && r.hit == hit)
        .unwrap_or_else(|| panic!("no record ch{ch} hit {hit} among {}", recs.len()))
}

fn assert_samples(r: &AeRecord, values: &[(String, f64)], volts_per_unit: f64) {
    assert_eq!(r.samples.len(), values.len(), "{}", r.source_file);
    for (i, (s, (_, v))) in r.samples.iter().zip(values).enumerate() {
        assert_eq!(
            *s,
            (v * volts_per_unit) as f32,
            "sample {i} of {}",
            r.source_file
        );
    }
}

#[test]
fn aewin_exports_with_either_header_read_as_written() {
    let t = TempDir::new("aewin-headers");
    let dir = t.path().join("lab");
    std::fs::create_dir_all(&dir).unwrap();
    let a = burst(1024, 1, 0.2, 8);
    let b = burst(2048, 2, 0.05, 8);
    let c = burst(512, 3, 0.1, 8);
    // Variant 1, CRLF, .txt; variant 2, LF, keys reversed, an unknown key, .csv.
    let files = [
        (
            AewinExport {
                variant: 1,
                channel: 1,
                hit: 1,
                time_s: 12.345_678_9,
                interval_s: 1e-7,
                values: &a,
                unit: "Volts",
                points_lie: None,
                crlf: true,
                reversed: false,
                extra_key: None,
            },
            "txt",
        ),
        (
            AewinExport {
                variant: 2,
                channel: 2,
                hit: 2,
                time_s: 13.5,
                interval_s: 2e-7,
                values: &b,
                unit: "V",
                points_lie: None,
                crlf: false,
                reversed: true,
                extra_key: Some("OPERATOR: J. Smith"),
            },
            "csv",
        ),
        (
            AewinExport {
                variant: 2,
                channel: 3,
                hit: 3,
                time_s: 14.0,
                interval_s: 1e-7,
                values: &c,
                unit: "Volts",
                points_lie: None,
                crlf: true,
                reversed: false,
                extra_key: None,
            },
            "txt",
        ),
    ];
    for (f, ext) in &files {
        f.write(&dir.join(aewin_name("PLB", f.channel, f.hit, f.time_s, ext)));
    }
    // A unit that is not volts, and a point count that lies: each one reject, no more.
    let bad_unit = burst(256, 4, 0.1, 6);
    AewinExport {
        variant: 1,
        channel: 4,
        hit: 4,
        time_s: 15.0,
        interval_s: 1e-7,
        values: &bad_unit,
        unit: "mV",
        points_lie: None,
        crlf: true,
        reversed: false,
        extra_key: None,
    }
    .write(&dir.join(aewin_name("PLB", 4, 4, 15.0, "txt")));
    AewinExport {
        variant: 2,
        channel: 1,
        hit: 5,
        time_s: 16.0,
        interval_s: 1e-7,
        values: &bad_unit,
        unit: "Volts",
        points_lie: Some(300),
        crlf: false,
        reversed: false,
        extra_key: None,
    }
    .write(&dir.join(aewin_name("PLB", 1, 5, 16.0, "txt")));

    let cfg = no_gain();
    let d = aepipe::ingest::discover(std::slice::from_ref(&dir), &cfg.ingest);
    assert_eq!(d.sources.len(), 1, "{:?} {:?}", d.sources, d.skipped);
    assert_eq!(d.sources[0].id, "PLB", "the test's name is the experiment");
    assert_eq!(d.sources[0].format, aepipe::ingest::Format::Aewin);
    assert_eq!(d.sources[0].files.len(), 5);

    let (recs, rejs) = read_all(std::slice::from_ref(&dir), &cfg);
    assert_eq!(recs.len(), 3, "{rejs:?}");
    for (f, _) in &files {
        let r = record(&recs, f.channel, f.hit);
        assert_eq!(r.experiment, "PLB");
        assert_eq!(r.time_s, Some(f.time_s), "TIME OF TEST is the hit's time");
        assert!(
            (r.sample_rate_hz - 1.0 / f.interval_s).abs() < 1e-6,
            "{} vs {}",
            r.sample_rate_hz,
            1.0 / f.interval_s
        );
        assert_samples(r, f.values, 1.0);
    }
    assert_eq!(rejs.len(), 2, "{rejs:?}");
    let why = |ch: u32| -> &Reject {
        rejs.iter()
            .find(|r| r.record_id.starts_with(&format!("ch{ch} ")))
            .unwrap()
    };
    assert!(
        why(4).reason.contains("'mV' is not volts"),
        "{}",
        why(4).reason
    );
    assert!(
        why(1)
            .reason
            .contains("declares 300 data points; the file holds 256"),
        "{}",
        why(1).reason
    );

    // The unknown key is named in a manifest note; the accounting adds up.
    let r = run(
        StreamJob::Features,
        std::slice::from_ref(&dir),
        &t.path().join("f"),
        &cfg,
        &StreamOptions::with_threads(1),
    )
    .unwrap();
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&r.manifest_path).unwrap()).unwrap();
    let notes = m["notes"].to_string();
    assert!(
        notes.contains(
            "AEwin header key 'OPERATOR' is not one aepipe knows: kept, not used (1 file(s))"
        ),
        "{notes}"
    );
    let c = &r.stats.by_experiment["PLB"];
    // Without a hit list, each record read is its hit: a file refused is a reject, no hit.
    assert_eq!((c.hits, c.rows, c.rejects), (3, 3, 2));
}

#[test]
fn four_channels_of_an_aewin_export_are_one_event_in_the_written_order() {
    let t = TempDir::new("aewin-event");
    let dir = t.path().join("exports");
    std::fs::create_dir_all(&dir).unwrap();
    // One source heard by four sensors: channel 3 first, then 1, 4, 2.
    let t0 = 20.5;
    let arrivals = [(3u32, 0.0), (1, 12e-6), (4, 25e-6), (2, 40e-6)];
    for (k, &(ch, dt)) in arrivals.iter().enumerate() {
        let v = burst(1024, 10 + k as u64, 0.3, 8);
        let time_s = t0 + dt;
        AewinExport {
            variant: 1 + (k % 2) as u8,
            channel: ch,
            hit: k as u64 + 1,
            time_s,
            interval_s: 1e-7,
            values: &v,
            unit: "Volts",
            points_lie: None,
            crlf: true,
            reversed: k == 2,
            extra_key: None,
        }
        .write(&dir.join(aewin_name("CFRP1", ch, k as u64 + 1, time_s, "txt")));
    }
    let r = run(
        StreamJob::Features,
        std::slice::from_ref(&dir),
        &t.path().join("f"),
        &no_gain(),
        &StreamOptions::with_threads(1),
    )
    .unwrap();
    let ev = crate::events::read_events(&r.events_path);
    assert_eq!(ev.len(), 1, "{ev:?}");
    assert_eq!(ev[0].experiment, "CFRP1");
    assert_eq!(ev[0].channels, [3, 1, 4, 2]);
    // The times after the first hit's, as the headers give them.
    assert_eq!(ev[0].dt.len(), 3);
    for (got, (_, want)) in ev[0].dt.iter().zip(&arrivals[1..]) {
        assert!((got - want).abs() < 1e-9, "{:?}", ev[0].dt);
    }
    assert!((ev[0].time_s - t0).abs() < 1e-9);
}

/// A WaveExplorer export: header `rate events samples channels`, then a line per sample
/// with a tab after each channel's value, CRLF.
fn write_waveexplorer(path: &Path, rate_mhz: u32, events: &[Vec<Vec<(String, f64)>>]) {
    let channels = events[0].len();
    let len = events[0][0].len();
    let mut s = format!("{rate_mhz}\t{}\t{len}\t{channels}\r\n", events.len());
    for ev in events {
        for i in 0..len {
            for ch in ev {
                s.push_str(&ch[i].0);
                s.push('\t');
            }
            s.push_str("\r\n");
        }
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn waveexplorer_exports_of_one_to_four_channels_under_any_name() {
    let t = TempDir::new("wx");
    let cfg = ValidConfig::default();
    for (channels, name) in [
        (1usize, "plb_run1.txt"),
        (2, "two_sensors.txt"),
        (3, "scan.dat"),
        (4, "220426_20deg_4mm_wave.txt"),
    ] {
        let dir = t.path().join(format!("c{channels}"));
        std::fs::create_dir_all(&dir).unwrap();
        let events: Vec<Vec<Vec<(String, f64)>>> = (0..3)
            .map(|e| {
                (0..channels)
                    .map(|c| burst(256, (100 * e + c) as u64, 0.01, 4))
                    .collect()
            })
            .collect();
        write_waveexplorer(&dir.join(name), 10, &events);
        let d = aepipe::ingest::discover(std::slice::from_ref(&dir), &cfg.ingest);
        assert_eq!(
            d.sources.iter().map(|s| s.format).collect::<Vec<_>>(),
            [aepipe::ingest::Format::WaveExplorer],
            "{name}: {:?}",
            d.skipped
        );
        let (recs, rejs) = read_all(&[dir], &cfg);
        assert!(rejs.is_empty(), "{name}: {rejs:?}");
        assert_eq!(recs.len(), 3 * channels, "{name}");
        for (e, ev) in events.iter().enumerate() {
            for (c, values) in ev.iter().enumerate() {
                let r = record(&recs, c as u32 + 1, e as u64 + 1);
                assert_eq!(r.sample_rate_hz, 10e6);
                assert_eq!(r.samples.len(), values.len());
                for (s, (text, _)) in r.samples.iter().zip(values) {
                    assert_eq!(*s, text.parse::<f32>().unwrap(), "{name} ch{c} ev{e}");
                }
            }
        }
    }
    // A line short of the header's channels is a reject naming it, and so is every event
    // after it.
    let dir = t.path().join("short");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("x.txt"),
        "10\t2\t3\t2\r\n0.1\t0.2\t\r\n0.1\t\r\n0.3\t0.4\t\r\n0.1\t0.2\t\r\n0.1\t0.2\t\r\n0.1\t0.2\t\r\n",
    )
    .unwrap();
    let (recs, rejs) = read_all(&[dir], &cfg);
    assert!(recs.is_empty());
    assert_eq!(rejs.len(), 2, "{rejs:?}");
    assert!(
        rejs[0]
            .reason
            .contains("line 3: 1 value(s) where the header promises 2 channels"),
        "{}",
        rejs[0].reason
    );
}

/// A Vallen TXT export of one transient (line ends CR CR LF); `values` in mV.
fn write_vallen_txt(
    path: &Path,
    datafile: &str,
    trai: u64,
    chan: u32,
    rate_hz: f64,
    pretrigger: usize,
    values_mv: &[(String, f64)],
) {
    let mut s = format!("Datafile: {datafile}, Trai: {trai}, Chan:{chan}\r\r\n");
    s.push_str("Time (microsec)\tAmplitude (mV)\r\r\n");
    for (i, (v, _)) in values_mv.iter().enumerate() {
        let t_us = (i as f64 - pretrigger as f64) / rate_hz * 1e6;
        s.push_str(&format!("{t_us:.2}\t{v}\r\r\n"));
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn vallen_txt_exports_alone_and_beside_their_tradb() {
    let t = TempDir::new("vallen-txt");
    let cfg = ValidConfig::default();
    // Alone: three transients of `plate`, two channels.
    let alone = t.path().join("alone");
    std::fs::create_dir_all(&alone).unwrap();
    let sigs: Vec<Vec<(String, f64)>> = (0..3).map(|k| burst(1000, 30 + k, 20.0, 4)).collect();
    let plan = [(1u64, 1u32), (2, 2), (3, 1)];
    for (&(trai, chan), v) in plan.iter().zip(&sigs) {
        write_vallen_txt(
            &alone.join(format!("export_{trai}.txt")),
            "C:\\Vallen\\Data\\plate.tradb",
            trai,
            chan,
            5e6,
            200,
            v,
        );
    }
    let d = aepipe::ingest::discover(std::slice::from_ref(&alone), &cfg.ingest);
    assert_eq!(d.sources.len(), 1, "{:?}", d.skipped);
    assert_eq!(d.sources[0].id, "plate");
    assert_eq!(d.sources[0].format.as_str(), "vallen txt export");
    let (recs, rejs) = read_all(std::slice::from_ref(&alone), &cfg);
    assert!(rejs.is_empty(), "{rejs:?}");
    // In (channel, TRAI) order, as the .tradb reader gives them.
    let order = [0usize, 2, 1];
    assert_eq!(
        recs.iter().map(|r| (r.hit, r.channel)).collect::<Vec<_>>(),
        order.map(|k| plan[k])
    );
    for (r, v) in recs.iter().zip(order.map(|k| &sigs[k])) {
        assert_eq!((r.sample_rate_hz, r.pretrigger), (5e6, 200));
        assert_eq!(r.time_s, None, "the export does not say when");
        assert_samples(r, v, 1e-3);
    }

    // Beside the .tradb they came from: the pair is read, the exports are passed over.
    let beside = t.path().join("beside");
    std::fs::create_dir_all(&beside).unwrap();
    let volts: Vec<Vec<f32>> = sigs
        .iter()
        .map(|s| s.iter().map(|(_, v)| (v * 1e-3) as f32).collect())
        .collect();
    let hits: Vec<HitToWrite> = plan
        .iter()
        .zip(&volts)
        .enumerate()
        .map(|(k, (&(trai, chan), v))| HitToWrite {
            channel: chan,
            trai,
            time_s: 0.1 * (k + 1) as f64,
            sample_rate_hz: 5e6,
            pretrigger: 200,
            samples_v: v,
            restart: false,
            transient: true,
        })
        .collect();
    // TR_mV 1e-3 mV: ±32.8 mV in int16.
    aepipe::ingest::vallen::write_pair(&beside.join("plate"), hits, &[], 1e-3, 1e-3).unwrap();
    for (&(trai, chan), v) in plan.iter().zip(&sigs) {
        write_vallen_txt(
            &beside.join(format!("plate_TRAI{trai}.txt")),
            "plate.tradb",
            trai,
            chan,
            5e6,
            200,
            v,
        );
    }
    let d = aepipe::ingest::discover(std::slice::from_ref(&beside), &cfg.ingest);
    assert_eq!(
        d.sources.iter().map(|s| s.format).collect::<Vec<_>>(),
        [aepipe::ingest::Format::Vallen]
    );
    let passed: Vec<&(PathBuf, String)> = d
        .skipped
        .iter()
        .filter(|(p, _)| p.extension().is_some_and(|e| e == "txt"))
        .collect();
    assert_eq!(passed.len(), 3, "{:?}", d.skipped);
    assert!(
        passed[0]
            .1
            .contains("is read instead (the same transient is not read twice)"),
        "{}",
        passed[0].1
    );
    // The exports, read alone, equal the database's transients within the database's
    // quantisation (half of TR_mV = 1e-3 mV) and f32 rounding.
    let (from_db, rejs) = read_all(&[beside], &cfg);
    assert!(rejs.is_empty(), "{rejs:?}");
    for (db, txt) in from_db.iter().zip(&recs) {
        assert_eq!(
            (db.hit, db.channel, db.pretrigger),
            (txt.hit, txt.channel, txt.pretrigger)
        );
        assert_eq!(db.sample_rate_hz, txt.sample_rate_hz);
        let worst = db
            .samples
            .iter()
            .zip(&txt.samples)
            .map(|(a, b)| (a - b).abs())
            .fold(0f32, f32::max);
        assert!(worst <= 5.1e-7, "{worst} V");
    }
}

/// Hit `trai` of a paused or restarted pair.
fn hit(trai: u64, chan: u32, time_s: f64, v: &[f32]) -> HitToWrite<'_> {
    HitToWrite {
        channel: chan,
        trai,
        time_s,
        sample_rate_hz: 10e6,
        pretrigger: 100,
        samples_v: v,
        restart: false,
        transient: true,
    }
}

#[test]
fn a_paused_vallen_recording_keeps_its_trai_and_a_restart_still_renumbers() {
    let t = TempDir::new("pause");
    let data = t.path().join("data");
    std::fs::create_dir_all(&data).unwrap();
    let v: Vec<Vec<f32>> = (0..6)
        .map(|k| {
            (0..512)
                .map(|i| {
                    if i >= 100 {
                        0.01 * (k as f32 + 1.0) * (i as f32 * 0.3).sin()
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect();
    // Paused: TRAI 1-3, a section marker, TRAI 4-6 on the same clock.
    let w = PairWriter::create(&data.join("paused"), 1e-3, 1e-4, Journal::Off).unwrap();
    for (k, s) in v.iter().enumerate() {
        if k == 3 {
            w.section(2).unwrap();
        }
        let h = hit(k as u64 + 1, 1, 0.1 * (k + 1) as f64, s);
        w.hit(&h).unwrap();
        w.transient(&h).unwrap();
    }
    drop(w);
    // Restarted: TRAI 1-3, a section marker, TRAI 1-3 again and the clock from 0.
    let w = PairWriter::create(&data.join("restarted"), 1e-3, 1e-4, Journal::Off).unwrap();
    for (k, s) in v.iter().enumerate() {
        if k == 3 {
            w.section(2).unwrap();
        }
        let h = hit((k % 3) as u64 + 1, 1, 0.1 * ((k % 3) + 1) as f64, s);
        w.hit(&h).unwrap();
        w.transient(&h).unwrap();
    }
    drop(w);
    let r = run(
        StreamJob::Features,
        &[data],
        &t.path().join("f"),
        &ValidConfig::default(),
        &StreamOptions::with_threads(1),
    )
    .unwrap();
    let (hn, hr) = table_rows(&r.hits_path);
    let col = |name: &str, exp: &str| -> Vec<String> {
        let i = hn.iter().position(|n| n == name).unwrap();
        let e = hn.iter().position(|n| n == "experiment").unwrap();
        hr.iter()
            .filter(|r| r[e] == exp)
            .map(|r| r[i].clone())
            .collect()
    };
    assert_eq!(col("transient", "paused"), ["1", "2", "3", "4", "5", "6"]);
    assert_eq!(col("acquisition", "paused"), ["1"; 6]);
    assert_eq!(
        col("transient", "restarted"),
        ["1", "2", "3", "4", "5", "6"]
    );
    assert_eq!(
        col("acquisition", "restarted"),
        ["1", "1", "1", "2", "2", "2"]
    );
    assert_eq!(col("trai", "restarted"), ["1", "2", "3", "1", "2", "3"]);
    // The features keep the pause's TRAI as the hit number.
    let (fnames, fr) = table_rows(&r.table_path);
    let (e, h) = (
        fnames.iter().position(|n| n == "experiment").unwrap(),
        fnames.iter().position(|n| n == "hit").unwrap(),
    );
    let paused: Vec<&str> = fr
        .iter()
        .filter(|r| r[e] == "paused")
        .map(|r| r[h].as_str())
        .collect();
    assert_eq!(paused, ["1", "2", "3", "4", "5", "6"]);
    // The pause is still in markers.parquet.
    let (mn, mr) = table_rows(&r.markers_path);
    let (me, mk) = (
        mn.iter().position(|n| n == "experiment").unwrap(),
        mn.iter().position(|n| n == "kind").unwrap(),
    );
    assert_eq!(
        mr.iter()
            .filter(|r| r[me] == "paused" && r[mk] == "section")
            .count(),
        1,
        "{mr:?}"
    );
}

#[test]
fn a_file_no_reader_takes_is_described_and_a_run_of_nothing_is_an_input_error() {
    let t = TempDir::new("nothing");
    let dir = t.path().join("lab");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("picks.txt"),
        "Event\tFirst Arrival\tPeak\r\n1\t2.5\t0.1\r\n2\t3.5\t0.2\r\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("hit_7.txt"),
        "SOURCE FILE NAME: X.DTA\r\nCHANNEL NUMBER: 1\r\nHIT NUMBER: 7\r\n\r\n 0.1\r\n 0.2\r\n",
    )
    .unwrap();
    let dir_s = dir.to_string_lossy().to_string();
    let (code, out, err) = aepipe(&["inspect", &dir_s]);
    assert_eq!(code, 1, "{out}{err}");
    // What it saw and what it resembles, and what would read it.
    assert!(
        out.contains("first line 'Event\tFirst Arrival\tPeak', 3 tab-separated column(s), 2 of the next 2 lines numeric"),
        "{out}"
    );
    assert!(
        out.contains("CSV is not a waveform: no waveform column"),
        "{out}"
    );
    assert!(
        out.contains("resembles an AEwin waveform export with a header (3 known key(s)), but it states no readable SAMPLE INTERVAL: `[ingest] format = \"aewin\"` reads it"),
        "{out}"
    );
    // A run that reads something lists the same line in its manifest.
    let mixed = t.path().join("mixed");
    std::fs::create_dir_all(&mixed).unwrap();
    std::fs::copy(dir.join("picks.txt"), mixed.join("picks.txt")).unwrap();
    std::fs::write(mixed.join("hit.dat"), "0.1\n0.2\n-0.1\n0.05\n").unwrap();
    let r = run(
        StreamJob::Features,
        std::slice::from_ref(&mixed),
        &t.path().join("mixed-out"),
        &ValidConfig::default(),
        &StreamOptions::with_threads(1),
    )
    .unwrap();
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&r.manifest_path).unwrap()).unwrap();
    let reason = m["skipped"][0]["reason"].as_str().unwrap().to_string();
    let (_, inspect_out, _) = aepipe(&["inspect", &mixed.to_string_lossy()]);
    assert!(
        inspect_out.contains(&format!("picks.txt: {reason}")),
        "{inspect_out}\n{reason}"
    );
    // A run that reads nothing is an input error naming what was passed over, and writes
    // no table.
    let out_dir = t.path().join("out");
    let (code, _, err) = aepipe(&["features", &dir_s, "--out", &out_dir.to_string_lossy()]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("no recording aepipe reads in"), "{err}");
    assert!(err.contains("picks.txt: "), "{err}");
    assert!(!out_dir.join("features.parquet").exists());
    let missing = t.path().join("nonexistent");
    let (code, _, err) = aepipe(&[
        "features",
        &missing.to_string_lossy(),
        "--out",
        &out_dir.to_string_lossy(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("no such file or folder"), "{err}");
    // Forcing the format reads the header export at the configured rate.
    let cfg = t.path().join("aewin.toml");
    std::fs::write(
        &cfg,
        "[ingest]\nformat = \"aewin\"\n[ingest.aewin]\nsample_rate_hz = 2e6\n",
    )
    .unwrap();
    let (recs, _) = read_all(
        &[dir.join("hit_7.txt")],
        &aepipe::config::PipelineConfig::from_file(&cfg).unwrap(),
    );
    assert_eq!(recs.len(), 1);
    assert_eq!((recs[0].hit, recs[0].sample_rate_hz), (7, 2e6));
}
