//! MISTRAS `.DTA`: the real file against MistrasDTA (the independent reader on PyPI), and
//! files written here byte by byte: a chain, four channels with their gains, a hit without a
//! waveform, a waveform without a hit, hits out of time order, a truncated last message and
//! a continuation file read alone.

use crate::{table_rows, TempDir};
use aepipe::model::{AeRecord, HitRow, Item};
use aepipe::pipeline::{run, StreamJob, StreamOptions};
use std::path::{Path, PathBuf};

/// Every item the ingest yields for `inputs`.
fn items(inputs: &[PathBuf]) -> (Vec<HitRow>, Vec<AeRecord>, Vec<String>, Vec<String>) {
    let cfg = aepipe::config::ValidConfig::default();
    let d = aepipe::ingest::discover(inputs, &cfg.ingest);
    let (mut h, mut r, mut rej, mut notes) = (vec![], vec![], vec![], vec![]);
    for s in &d.sources {
        for it in aepipe::ingest::open(s, cfg.read_settings(), &cfg.load) {
            match it {
                Item::Hit(x) => h.push(*x),
                Item::Record(x) => r.push(x),
                Item::Reject(x) => rej.push(format!("{} {}", x.record_id, x.reason)),
                Item::Note(n) => notes.push(n.message),
                _ => {}
            }
        }
    }
    (h, r, rej, notes)
}

#[test]
fn the_real_dta_gives_the_hits_and_samples_mistrasdta_gives() {
    let Some(real) = crate::real_data("the_real_dta_gives_the_hits_and_samples_mistrasdta_gives")
    else {
        return;
    };
    let file = real.join("mistras_dta/210527-CH1-15.DTA");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/mistras_read.py");
    let Some(out) = crate::reference(
        "MistrasDTA comparison",
        "pip install MistrasDTA",
        std::process::Command::new("python3")
            .arg(&script)
            .arg(&file),
    ) else {
        return;
    };
    let theirs: serde_json::Value = serde_json::from_slice(&out).unwrap();
    let (hits, recs, rejects, _) = items(std::slice::from_ref(&file));
    assert!(rejects.is_empty(), "{rejects:?}");
    let th = theirs["hits"].as_array().unwrap();
    assert_eq!(hits.len(), th.len());
    assert_eq!(hits.len(), 8);
    for (h, t) in hits.iter().zip(th) {
        let f = |k: &str| t[k].as_f64().unwrap();
        assert!((h.time_s.unwrap() - f("SSSSSSSS.mmmuuun")).abs() < 1e-9);
        assert_eq!(h.channel as f64, f("CH"));
        assert_eq!(h.amplitude_db, Some(f("AMP")));
        assert_eq!(h.counts, Some(f("COUN") as i64));
        assert_eq!(h.energy_counts, Some(f("ENER")));
        assert!((h.duration_s.unwrap() - f("DURATION") * 1e-6).abs() < 1e-12);
        assert!((h.rise_time_s.unwrap() - f("RISE") * 1e-6).abs() < 1e-12);
        assert!(
            (h.abs_energy_aj.unwrap() - f("ABS-ENERGY")).abs()
                <= 1e-9 * f("ABS-ENERGY").abs().max(1.0)
        );
        assert_eq!(h.centroid_freq_hz, Some(f("FRQ-C") * 1e3));
        assert_eq!(h.peak_freq_hz, Some(f("P-FRQ") * 1e3));
        // Each hit is paired with the waveform of the same time and channel.
        let r = &recs[(h.transient.unwrap() - 1) as usize];
        assert_eq!((r.channel, r.time_s), (h.channel, h.time_s));
    }
    let tw = theirs["waves"].as_array().unwrap();
    assert_eq!(recs.len(), tw.len());
    for (r, t) in recs.iter().zip(tw) {
        assert!((r.time_s.unwrap() - t["time"].as_f64().unwrap()).abs() < 1e-9);
        assert_eq!(r.channel as i64, t["ch"].as_i64().unwrap());
        assert_eq!(r.sample_rate_hz, t["srate"].as_f64().unwrap());
        assert_eq!(r.pretrigger as i64, -t["tdly"].as_i64().unwrap());
        let v = t["v"].as_array().unwrap();
        assert!(v.len() <= r.samples.len() && v.len() > 3000, "{}", v.len());
        // The message holds 3 072 samples (its length, not MistrasDTA's truncated bytes).
        assert_eq!(r.samples.len(), 3072);
        for (a, b) in r.samples.iter().zip(v) {
            let b = b.as_f64().unwrap();
            assert!(
                (*a as f64 - b).abs() <= 1e-7 * b.abs().max(1e-6),
                "{a} vs {b}"
            );
        }
    }
    // Through the pipeline: hits.parquet holds the 8 hits, each linked to its transient.
    let t = TempDir::new("dta-real");
    let run = run(
        StreamJob::Features,
        &[file],
        t.path(),
        &aepipe::config::ValidConfig::default(),
        &StreamOptions::with_threads(2),
    )
    .unwrap();
    let c = &run.stats.by_experiment["210527-CH1-15"];
    assert_eq!((c.hits, c.rows, c.rejects), (8, 8, 0));
    let (names, rows) = table_rows(&run.hits_path);
    let tr = names.iter().position(|n| n == "transient").unwrap();
    assert!(rows.iter().all(|r| !r[tr].is_empty()));
}

// --- A DTA writer for fixtures (the message layout of Appendix II) -----------------------

pub(crate) fn msg(mid: u8, body: &[u8]) -> Vec<u8> {
    let two_byte_id = (40..=49).contains(&mid);
    let len = body.len() + 1 + two_byte_id as usize;
    let mut v = (len as u16).to_le_bytes().to_vec();
    v.push(mid);
    if two_byte_id {
        v.push(0);
    }
    v.extend_from_slice(body);
    v
}

fn ticks(t_s: f64) -> [u8; 6] {
    let t = (t_s / 0.25e-6).round() as u64;
    let b = t.to_le_bytes();
    [b[0], b[1], b[2], b[3], b[4], b[5]]
}

/// The features the fixtures record: RISE, COUN, DURATION, AMP, ABS-ENERGY, FRQ-C.
const CHIDS: [u8; 6] = [1, 3, 5, 6, 21, 23];

/// Product, start time and hardware setup: the CHID list, each channel's gain (unless
/// `gains` is false) and waveform hardware (10 MHz, 128 pretrigger samples).
pub(crate) fn setup(channels: &[(u8, u8)], gains: bool) -> Vec<u8> {
    let mut f = msg(41, &[200, 0, b'T', b'E', b'S', b'T', b'\r', b'\n']);
    f.extend(msg(99, b"Thu May 27 10:53:54 2021\n\0"));
    let mut body = vec![103, 0];
    let mut sub = |id: u8, b: &[u8]| {
        body.extend(((b.len() + 1) as u16).to_le_bytes());
        body.push(id);
        body.extend_from_slice(b);
    };
    let mut ev = vec![CHIDS.len() as u8];
    ev.extend(CHIDS);
    ev.push(0);
    sub(5, &ev);
    for &(ch, g) in channels {
        if gains {
            sub(23, &[ch, g]);
        }
        let mut hw = vec![42, 1, 0, 0, 0, 0];
        hw.extend(0u16.to_le_bytes()); // SLEN
        hw.push(ch);
        hw.extend(0u16.to_le_bytes()); // HLK
        hw.extend([0, 0]);
        hw.extend(10_000u16.to_le_bytes()); // SRATE, kHz
        hw.extend(0u16.to_le_bytes());
        hw.extend(0u16.to_le_bytes());
        hw.extend((-128i16).to_le_bytes()); // TDLY
        hw.extend(0u16.to_le_bytes());
        hw.extend(0u16.to_le_bytes());
        sub(173, &hw);
    }
    f.extend(msg(42, &body));
    f.extend(msg(128, &[0; 6]));
    f
}

/// A hit: rise 10 µs, counts, duration 100 µs, amplitude, absolute energy, centroid.
pub(crate) fn hit(t: f64, ch: u8, amp: u8, counts: u16) -> Vec<u8> {
    let mut b = ticks(t).to_vec();
    b.push(ch);
    b.extend(10u16.to_le_bytes());
    b.extend(counts.to_le_bytes());
    b.extend(100u32.to_le_bytes());
    b.push(amp);
    b.extend(1000.0f32.to_le_bytes());
    b.extend(300u16.to_le_bytes());
    msg(1, &b)
}

pub(crate) fn wave(t: f64, ch: u8, counts: &[i16]) -> Vec<u8> {
    let mut b = vec![1];
    b.extend(ticks(t));
    b.push(ch);
    b.push(0);
    for c in counts {
        b.extend(c.to_le_bytes());
    }
    msg(173, &b)
}

pub(crate) fn counts(k: i16) -> Vec<i16> {
    (0..1024)
        .map(|i| ((i % 37) as i16 - 18) * (k + 1))
        .collect()
}

#[test]
fn written_dta_files_four_channels_a_chain_and_bad_endings() {
    let t = TempDir::new("dta");
    let dir = t.path().join("run");
    std::fs::create_dir_all(&dir).unwrap();
    let chans = [(1u8, 0u8), (2, 20), (3, 40), (4, 6)];
    // First file of the chain: 4 channels; hit 3 has no waveform; a waveform without a hit;
    // hits 4 and 5 stored out of time order, each after its waveform.
    let mut a = setup(&chans, true);
    a.extend(wave(1.0, 1, &counts(0)));
    a.extend(hit(1.0, 1, 60, 5));
    a.extend(hit(2.0, 2, 61, 6));
    a.extend(wave(2.0, 2, &counts(1)));
    a.extend(hit(3.0, 3, 62, 7)); // no waveform
    a.extend(wave(3.5, 4, &counts(3))); // no hit
    a.extend(wave(5.0, 4, &counts(4)));
    a.extend(hit(5.0, 4, 64, 9));
    a.extend(wave(4.0, 3, &counts(2)));
    a.extend(hit(4.0, 3, 63, 8));
    std::fs::write(dir.join("X.DTA"), &a).unwrap();
    // Continuation: MID 8, the setup again, two hits; its last message is cut short.
    let mut b = msg(8, &[0; 8]);
    b.extend(setup(&chans, true));
    b.extend(wave(6.0, 2, &counts(5)));
    b.extend(hit(6.0, 2, 65, 10));
    let cut = wave(7.0, 1, &counts(6));
    b.extend(&cut[..cut.len() / 2]);
    std::fs::write(dir.join("X__2.DTA"), &b).unwrap();

    let (hits, recs, rejects, notes) = items(std::slice::from_ref(&dir));
    assert!(notes.is_empty(), "{notes:?}");
    // One experiment: 6 hits in storage order, numbers running across the chain.
    assert_eq!(
        hits.iter().map(|h| h.hit).collect::<Vec<_>>(),
        [1, 2, 3, 4, 5, 6]
    );
    assert!(hits.iter().all(|h| h.experiment == "X"));
    assert_eq!(
        hits.iter()
            .map(|h| h.amplitude_db.unwrap())
            .collect::<Vec<_>>(),
        [60.0, 61.0, 62.0, 64.0, 63.0, 65.0]
    );
    assert_eq!(hits[0].counts, Some(5));
    assert!((hits[0].rise_time_s.unwrap() - 10e-6).abs() < 1e-15);
    assert!((hits[0].duration_s.unwrap() - 100e-6).abs() < 1e-15);
    assert_eq!(hits[0].centroid_freq_hz, Some(300e3));
    assert!((hits[0].abs_energy_aj.unwrap() - 1000.0 * 9.31e-4).abs() < 1e-9);
    // Hit 3 has no transient; every other hit is linked to the waveform of its time/channel.
    assert_eq!(hits[2].transient, None);
    for h in hits.iter().filter(|h| h.transient.is_some()) {
        let r = recs.iter().find(|r| Some(r.hit) == h.transient).unwrap();
        assert_eq!(
            (r.channel, r.time_s),
            (h.channel, h.time_s),
            "hit {}",
            h.hit
        );
    }
    // Six waveforms read (one without a hit); the cut one is a reject naming its byte.
    assert_eq!(recs.len(), 6);
    assert!(recs.iter().any(|r| r.time_s == Some(3.5)));
    assert_eq!(rejects.len(), 1, "{rejects:?}");
    assert!(
        rejects[0].starts_with("byte ") && rejects[0].contains("past the end"),
        "{rejects:?}"
    );
    // Volts = counts × 10 V / (10^(gain/20) × 32 768), with each channel's own gain.
    for r in &recs {
        let gain = chans.iter().find(|c| c.0 as u32 == r.channel).unwrap().1 as f64;
        // The first count of each written waveform is −18·(k + 1), k by its time.
        let k = [(1.0, 0), (2.0, 1), (4.0, 2), (3.5, 3), (5.0, 4), (6.0, 5)]
            .iter()
            .find(|(t, _)| Some(*t) == r.time_s)
            .unwrap()
            .1;
        let c0 = r.samples[0] as f64 * 10f64.powf(gain / 20.0) * 32768.0 / 10.0;
        assert!(
            (c0 + 18.0 * (k as f64 + 1.0)).abs() < 1e-3 * (k as f64 + 1.0) * 18.0,
            "ch{} {c0}",
            r.channel
        );
        assert_eq!(r.sample_rate_hz, 10e6);
        assert_eq!(r.pretrigger, 128);
    }

    // The continuation file read alone, without gains in its setup: its hits and waveform
    // are read, 0 dB assumed and said.
    let alone = t.path().join("alone");
    std::fs::create_dir_all(&alone).unwrap();
    let mut c = msg(8, &[0; 8]);
    c.extend(setup(&chans, false));
    c.extend(wave(6.0, 2, &counts(5)));
    c.extend(hit(6.0, 2, 65, 10));
    std::fs::write(alone.join("Y__3.DTA"), &c).unwrap();
    let (h2, r2, rej2, notes2) = items(std::slice::from_ref(&alone));
    assert_eq!((h2.len(), r2.len(), rej2.len()), (1, 1, 0));
    assert_eq!(h2[0].experiment, "Y");
    assert!(
        notes2.iter().any(|n| n.contains("0 dB assumed")),
        "{notes2:?}"
    );
    let c0 = r2[0].samples[0] as f64 * 32768.0 / 10.0;
    assert!((c0 - (-18.0 * 6.0)).abs() < 1e-3, "{c0}");

    // Through the pipeline: the accounting rule, and the note in the manifest.
    let r = run(
        StreamJob::Features,
        &[dir, alone],
        &t.path().join("out"),
        &aepipe::config::ValidConfig::default(),
        &StreamOptions::with_threads(2),
    )
    .unwrap();
    let x = &r.stats.by_experiment["X"];
    assert_eq!((x.hits, x.rows + x.rejects), (6, 7));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&r.manifest_path).unwrap()).unwrap();
    assert!(
        m["notes"][0]["note"].as_str().unwrap().contains("0 dB"),
        "{}",
        m["notes"]
    );
}

/// Items as comparable text (the setup and tally, said once per file or chain, apart).
fn described(items: impl IntoIterator<Item = aepipe::model::Item>) -> Vec<String> {
    use aepipe::model::Item;
    let mut v: Vec<String> = items
        .into_iter()
        .filter(|i| !matches!(i, Item::Setup(_) | Item::Tally(_) | Item::Note(_)))
        .map(|i| format!("{i:?}"))
        .collect();
    v.sort();
    v
}

/// Append `bytes` to `path` in pieces of `piece` bytes (cut anywhere, messages included),
/// calling `look` after each.
fn append_in_pieces(path: &Path, bytes: &[u8], piece: usize, mut look: impl FnMut()) {
    use std::io::Write;
    for c in bytes.chunks(piece) {
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .unwrap();
        f.write_all(c).unwrap();
        drop(f);
        look();
    }
}

/// A `.DTA` chain read while it is written — the real file appended in pieces cut inside
/// messages, then a written chain whose first file ends in a cut message and whose second
/// appears later — with the reader dropped once and opened again from its last position
/// (a watcher killed after a commit): the items are the offline reader's on the finished
/// files, each once.
#[test]
fn a_growing_dta_chain_read_in_pieces_gives_the_offline_items() {
    use aepipe::ingest::dta::tail::{DtaTail, Position};
    use aepipe::ingest::{Format, Source};
    use std::time::Duration;
    let cfg = aepipe::config::ValidConfig::default()
        .read_settings()
        .clone();
    let long = Duration::from_secs(3600);
    let t = TempDir::new("dta-tail");

    // The real file, 773 306 bytes, in pieces of 7 919.
    let Some(real) = super::real_data("a_growing_dta_chain_read_in_pieces_gives_the_offline_items")
    else {
        return;
    };
    let bytes = std::fs::read(real.join("mistras_dta/210527-CH1-15.DTA")).unwrap();
    let g = t.path().join("real");
    std::fs::create_dir_all(&g).unwrap();
    let path = g.join("210527-CH1-15.DTA");
    let src = Source {
        id: "210527-CH1-15".into(),
        format: Format::Mistras,
        files: vec![path.clone()],
        companions: vec![],
        first_hit: 0,
    };
    let mut got = Vec::new();
    let mut tail: Option<DtaTail> = None;
    let mut last = Position::default();
    let mut looks = 0;
    append_in_pieces(&path, &bytes, 7919, || {
        looks += 1;
        let t = tail.get_or_insert_with(|| DtaTail::open(&src, &last, &cfg).unwrap());
        let h = t.look(&src.files, long, 3, 1e-3).unwrap();
        got.extend(h.items);
        last = h.end;
        // Killed once, after committing what it had.
        if looks == 40 {
            tail = None;
        }
    });
    let mut t2 = tail.unwrap_or_else(|| DtaTail::open(&src, &last, &cfg).unwrap());
    loop {
        let items = t2.look(&src.files, Duration::ZERO, 3, 1e-3).unwrap().items;
        if items.is_empty() {
            break;
        }
        got.extend(items);
    }
    let live = described(got);
    let offline = described(aepipe::ingest::dta::open(&src, &cfg));
    let n = |p: &str| live.iter().filter(|r| r.starts_with(p)).count();
    assert_eq!(
        (n("Hit("), n("Record(")),
        (8, 8),
        "8 hits and their 8 waveforms"
    );
    assert!(n("Parametric(") > 10_000, "the time-driven rows");
    assert_eq!(live, offline);

    // A written chain: X.DTA ends in a cut waveform (a reject once X__2.DTA exists); hits
    // wait for their waveforms across looks.
    let w = t.path().join("chain");
    std::fs::create_dir_all(&w).unwrap();
    let chans = [(1u8, 0u8), (2, 20)];
    let mut a = setup(&chans, true);
    for k in 0..40 {
        let (tk, ch) = (1.0 + k as f64 * 0.01, 1 + (k % 2) as u8);
        if k % 3 == 0 {
            a.extend(wave(tk, ch, &counts(k as i16)));
            a.extend(hit(tk, ch, 60, 5));
        } else {
            a.extend(hit(tk, ch, 61, 6));
            if k != 17 {
                a.extend(wave(tk, ch, &counts(k as i16)));
            }
        }
    }
    let cut = wave(2.0, 1, &counts(3));
    a.extend(&cut[..cut.len() / 3]);
    let mut b = msg(8, &[0; 8]);
    b.extend(setup(&chans, true));
    for k in 0..30 {
        let (tk, ch) = (3.0 + k as f64 * 0.01, 1 + (k % 2) as u8);
        b.extend(hit(tk, ch, 62, 7));
        b.extend(wave(tk, ch, &counts(k as i16)));
    }
    let files = [w.join("X.DTA"), w.join("X__2.DTA")];
    let chain = Source {
        id: "X".into(),
        format: Format::Mistras,
        files: files.to_vec(),
        companions: vec![],
        first_hit: 0,
    };
    let mut tail = DtaTail::open(&chain, &Position::default(), &cfg).unwrap();
    let mut got = Vec::new();
    append_in_pieces(&files[0], &a, 1000, || {
        got.extend(tail.look(&files[..1], long, 5, 0.0).unwrap().items);
    });
    // X.DTA alone: its cut end waits (it may still be written).
    assert!(!described(got.clone())
        .iter()
        .any(|r| r.contains("past the end")));
    let at = tail.look(&files[..1], long, 5, 0.0).unwrap().end;
    let mut tail = DtaTail::open(&chain, &at, &cfg).unwrap();
    append_in_pieces(&files[1], &b, 1500, || {
        got.extend(tail.look(&files, long, 5, 0.0).unwrap().items);
    });
    loop {
        let items = tail.look(&files, Duration::ZERO, 5, 0.0).unwrap().items;
        if items.is_empty() {
            break;
        }
        got.extend(items);
    }
    let live = described(got);
    let offline = described(aepipe::ingest::dta::open(&chain, &cfg));
    assert!(
        offline.iter().any(|r| r.contains("past the end")),
        "the cut waveform's reject"
    );
    assert_eq!(live.len(), offline.len());
    assert_eq!(live, offline);
}

/// A watcher killed after each commit of a growing chain — its position after a message
/// that carries no record, where waiting hits were let out, and after a finished file whose
/// last message is cut — and started again from there each time reads every hit, waveform
/// and reject exactly once.
#[test]
fn a_dta_tail_restarted_after_every_commit_reads_nothing_twice() {
    use aepipe::ingest::dta::tail::{DtaTail, Position};
    use aepipe::ingest::{Format, Source};
    use std::io::Write;
    use std::time::Duration;
    let cfg = aepipe::config::ValidConfig::default()
        .read_settings()
        .clone();
    let t = TempDir::new("dta-restarts");
    let files = [t.path().join("X.DTA"), t.path().join("X__2.DTA")];
    let src = Source {
        id: "X".into(),
        format: Format::Mistras,
        files: files.to_vec(),
        companions: vec![],
        first_hit: 0,
    };
    let chans = [(1u8, 0u8), (2, 0)];
    let append = |f: &Path, b: &[u8]| {
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(f)
            .unwrap()
            .write_all(b)
            .unwrap()
    };
    // A hit with its waveform, a hit whose waveform is not written yet, a time mark.
    let mut a = setup(&chans, true);
    a.extend(wave(1.0, 1, &counts(1)));
    a.extend(hit(1.0, 1, 60, 5));
    a.extend(hit(1.1, 2, 61, 5));
    a.extend(msg(211, &[0; 6]));
    append(&files[0], &a);
    let mut got = Vec::new();
    let mut tail = DtaTail::open(&src, &Position::default(), &cfg).unwrap();
    let look = |tail: &mut DtaTail, got: &mut Vec<Item>, max: usize| -> Position {
        let h = tail.look(&src.files, Duration::ZERO, max, 0.0).unwrap();
        got.extend(h.items);
        h.end
    };
    look(&mut tail, &mut got, 100);
    // Quiet: the waiting hit is let out alone, after the time mark; committed there.
    let at = look(&mut tail, &mut got, 100);
    assert!(!at.drains.is_empty(), "the waiting hit was let out: {at:?}");
    // The chain goes on: the late waveform, a hit, a cut message ending X.DTA, X__2.DTA.
    let mut b = wave(1.1, 2, &counts(2));
    b.extend(hit(1.2, 1, 62, 5));
    b.extend(wave(1.2, 1, &counts(3)));
    let cut = wave(1.3, 2, &counts(4));
    b.extend(&cut[..cut.len() / 2]);
    append(&files[0], &b);
    let mut c = msg(8, &[0; 8]);
    c.extend(setup(&chans, true));
    c.extend(hit(2.0, 1, 63, 5));
    c.extend(wave(2.0, 1, &counts(5)));
    append(&files[1], &c);
    // Killed after every other commit (looks of one record at most; the second look of a
    // tail may find the chain quiet and let waiting hits out), started again from it.
    let mut at = at;
    let mut idle = 0;
    let mut positions = Vec::new();
    while idle < 3 {
        let mut tail = DtaTail::open(&src, &at, &cfg).unwrap_or_else(|e| panic!("{at:?}: {e}"));
        let n = got.len();
        for _ in 0..2 {
            at = look(&mut tail, &mut got, 1);
            positions.push(at.clone());
        }
        idle = if got.len() == n { idle + 1 } else { 0 };
    }
    let text: Vec<String> = got
        .iter()
        .filter(|i| !matches!(i, Item::Setup(_) | Item::Tally(_) | Item::Note(_)))
        .map(|i| format!("{i:?}"))
        .collect();
    let set: std::collections::BTreeSet<&String> = text.iter().collect();
    assert_eq!(set.len(), text.len(), "an item read twice: {text:#?}");
    let n = |p: &str| text.iter().filter(|r| r.starts_with(p)).count();
    assert_eq!((n("Hit("), n("Record(")), (4, 4), "{text:#?}");
    assert_eq!(n("Reject("), 1, "the cut message, once");
    assert!(positions.iter().any(|p| p.file == 1), "{positions:?}");
    // Committed right after X.DTA was finished (its cut message's reject handed out): a
    // restart from there does not say it again.
    let done = Position {
        file: 0,
        offset: u64::MAX,
        drains: vec![(0, 2252)],
    };
    let mut tail = DtaTail::open(&src, &done, &cfg).unwrap();
    let mut again = Vec::new();
    for _ in 0..3 {
        look(&mut tail, &mut again, 100);
    }
    assert!(
        !again.iter().any(|i| matches!(i, Item::Reject(_))),
        "{again:?}"
    );
    assert_eq!(
        again.iter().filter(|i| matches!(i, Item::Hit(_))).count(),
        2,
        "hits 1.2 and 2.0"
    );
}
