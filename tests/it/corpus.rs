//! The bad-input corpus: every reader and every kind of input file, made broken here with
//! aepipe's own writers (and byte by byte). Recordings go through one `aepipe features` run
//! beside a good experiment: each broken one gives reject rows that name its file and the
//! cause (or is read, when the input is odd but valid), every good hit is written, nothing
//! panics and the counts add up. Definition files (pipeline TOML, Appendix-A, reference
//! library, SOM model) each give exit code 1 and one error line naming the file.
//!
//! `AEPIPE_CORPUS_OUT=DIR cargo test --test it corpus` also writes each case as a seed for
//! the fuzz target that reads its kind (`fuzz/run.sh` does this).

use crate::bad_input::aepipe_within;
use crate::dta::msg as dta_msg;
use crate::{table_rows, vallen_fixture, TempDir};
use aepipe::synth::Experiment;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What a broken recording must give.
#[derive(Debug)]
enum Expect {
    /// Reject rows naming the file, each reason containing every one of these words.
    Reject(&'static [&'static str]),
    /// Read as it is: this many rows in the features table, no reject naming the file.
    Rows(u64),
    /// This many rows, and the rest of its hits rejects containing these words.
    Partly(u64, &'static [&'static str]),
    /// Not a recording: passed over, listed in the manifest's `skipped` with this reason.
    Skipped(&'static str),
}

struct Case {
    name: &'static str,
    /// The experiment id the rows are counted under.
    experiment: String,
    /// The file whose name the reject rows carry.
    file: PathBuf,
    expect: Expect,
}

fn sql(db: &Path, stmt: &str) {
    rusqlite::Connection::open(db)
        .unwrap()
        .execute_batch(stmt)
        .unwrap();
}

fn truncate(p: &Path, frac: f64) {
    let len = std::fs::metadata(p).unwrap().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(p)
        .unwrap()
        .set_len((len as f64 * frac) as u64)
        .unwrap();
}

/// A FLAC stream of 16-bit mono samples in one frame of VERBATIM subframes (the simplest
/// valid FLAC; written here so the decoder is tested on bytes it did not make).
fn flac(samples: &[i16]) -> Vec<u8> {
    fn crc8(b: &[u8]) -> u8 {
        let mut c = 0u8;
        for &x in b {
            c ^= x;
            for _ in 0..8 {
                c = if c & 0x80 != 0 {
                    (c << 1) ^ 0x07
                } else {
                    c << 1
                };
            }
        }
        c
    }
    fn crc16(b: &[u8]) -> u16 {
        let mut c = 0u16;
        for &x in b {
            c ^= (x as u16) << 8;
            for _ in 0..8 {
                c = if c & 0x8000 != 0 {
                    (c << 1) ^ 0x8005
                } else {
                    c << 1
                };
            }
        }
        c
    }
    let n = samples.len();
    assert!((16..=65535).contains(&n));
    let mut out = b"fLaC".to_vec();
    out.extend([0x80, 0, 0, 34]); // last block, STREAMINFO, 34 bytes
    out.extend((n as u16).to_be_bytes()); // min block size
    out.extend((n as u16).to_be_bytes()); // max block size
    out.extend([0; 6]); // min/max frame size unknown
                        // 20 bits rate (10 MHz is past FLAC's 655 350 Hz limit: 96 kHz, the rate is the
                        // database's), 3 bits channels−1, 5 bits bps−1, 36 bits total samples.
    let rate: u64 = 96_000;
    let packed: u64 = (rate << 44) | (15 << 36) | n as u64;
    out.extend(packed.to_be_bytes());
    out.extend([0; 16]); // MD5 unknown
    let mut frame = vec![0xFF, 0xF8, 0x70, 0x08, 0x00];
    frame.extend(((n - 1) as u16).to_be_bytes());
    frame.push(crc8(&frame));
    frame.push(0x02); // VERBATIM subframe, no wasted bits
    for v in samples {
        frame.extend(v.to_be_bytes());
    }
    let c = crc16(&frame);
    frame.extend(c.to_be_bytes());
    out.extend(frame);
    out
}

/// Rewrite every transient of a Vallen `.tradb` as FLAC (what VisualAE writes by default).
fn to_flac(db: &Path) {
    let c = rusqlite::Connection::open(db).unwrap();
    let rows: Vec<(i64, Vec<u8>)> = c
        .prepare("SELECT TRAI, Data FROM tr_data WHERE DataFormat = 0")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap()
        .map(Result::unwrap)
        .collect();
    for (trai, raw) in rows {
        let s: Vec<i16> = raw
            .chunks_exact(2)
            .map(|b| i16::from_le_bytes([b[0], b[1]]))
            .collect();
        c.execute(
            "UPDATE tr_data SET DataFormat = 2, Data = ?1 WHERE TRAI = ?2",
            rusqlite::params![flac(&s), trai],
        )
        .unwrap();
    }
}

fn blob(db: &Path, trai: i64) -> Vec<u8> {
    rusqlite::Connection::open(db)
        .unwrap()
        .query_row("SELECT Data FROM tr_data WHERE TRAI = ?1", [trai], |r| {
            r.get(0)
        })
        .unwrap()
}

fn set_blob(db: &Path, trai: i64, b: Vec<u8>) {
    rusqlite::Connection::open(db)
        .unwrap()
        .execute(
            "UPDATE tr_data SET Data = ?1 WHERE TRAI = ?2",
            rusqlite::params![b, trai],
        )
        .unwrap();
}

#[test]
fn the_flac_fixture_writer_and_the_blob_decoder_agree() {
    let x: Vec<i16> = (0..700).map(|i| ((i * 37) % 2001 - 1000) as i16).collect();
    let got = aepipe::ingest::vallen::decode_blob(2, &flac(&x), 700).unwrap();
    assert_eq!(got, x.iter().map(|&v| v as i32).collect::<Vec<_>>());
    // One flipped bit in a sample: the frame's CRC-16 catches it.
    let mut b = flac(&x);
    b[100] ^= 0x10;
    assert!(aepipe::ingest::vallen::decode_blob(2, &b, 700).is_err());
}

pub(crate) fn wav_header(rate: u32, bits: u16, data_bytes: u32) -> Vec<u8> {
    let mut w = Vec::new();
    w.extend(b"RIFF");
    w.extend(data_bytes.wrapping_add(36).to_le_bytes());
    w.extend(b"WAVEfmt ");
    w.extend(16u32.to_le_bytes());
    w.extend(1u16.to_le_bytes());
    w.extend(1u16.to_le_bytes());
    w.extend(rate.to_le_bytes());
    w.extend(rate.wrapping_mul(bits as u32 / 8).to_le_bytes());
    w.extend((bits / 8).to_le_bytes());
    w.extend(bits.to_le_bytes());
    w.extend(b"data");
    w.extend(data_bytes.to_le_bytes());
    w
}

fn tone(n: usize) -> Vec<f32> {
    (0..n)
        .map(|i| {
            let t = i as f32 / 1e7;
            0.1 * (-(i as f32) / 300.0).exp() * (2.0 * std::f32::consts::PI * 3e5 * t).sin()
        })
        .collect()
}

fn values(n: usize) -> String {
    tone(n).iter().map(|v| format!("{v}\n")).collect()
}

/// Every broken recording, each in its own folder (its own experiment) under `batch`.
fn recordings(batch: &Path) -> Vec<Case> {
    let mut cases = Vec::new();
    let mut n = 0;
    let mut add = |name: &'static str, make: &dyn Fn(&Path, &str) -> (String, PathBuf), expect| {
        n += 1;
        let dir = batch.join(format!("c{n:02}_{name}"));
        std::fs::create_dir_all(&dir).unwrap();
        let (experiment, file) = make(&dir, &format!("c{n:02}_{name}"));
        cases.push(Case {
            name,
            experiment,
            file,
            expect,
        });
    };
    let folder = |d: &Path| d.file_name().unwrap().to_string_lossy().to_string();

    // --- Vallen .pridb/.tradb (SQLite, raw and FLAC blobs) ---
    add(
        "vallen_truncated_tradb",
        &|d, id| {
            let f = vallen_fixture(d, id, 20, 2);
            truncate(&f, 0.4);
            (id.into(), f)
        },
        Expect::Partly(0, &[]),
    );
    add(
        "vallen_truncated_pridb",
        &|d, id| {
            vallen_fixture(d, id, 10, 3);
            let p = d.join(format!("{id}.pridb"));
            truncate(&p, 0.3);
            (id.into(), p)
        },
        // The transients are read; the hit list is unreadable, and said so.
        Expect::Partly(10, &["not a readable SQLite database"]),
    );
    add(
        "vallen_tradb_not_sqlite",
        &|d, id| {
            let f = vallen_fixture(d, id, 5, 4);
            std::fs::write(&f, b"this is not an SQLite database at all, just text\n").unwrap();
            (id.into(), f)
        },
        Expect::Reject(&[]),
    );
    add(
        "vallen_unknown_dataformat",
        &|d, id| {
            let f = vallen_fixture(d, id, 6, 5);
            sql(&f, "UPDATE tr_data SET DataFormat = 7 WHERE TRAI = 2");
            (id.into(), f)
        },
        Expect::Partly(5, &["DataFormat 7"]),
    );
    add(
        "vallen_flac_good",
        &|d, id| {
            let f = vallen_fixture(d, id, 6, 16);
            to_flac(&f);
            (id.into(), f)
        },
        Expect::Rows(6),
    );
    add(
        "vallen_flac_bad_crc",
        &|d, id| {
            let f = vallen_fixture(d, id, 6, 6);
            to_flac(&f);
            let mut b = blob(&f, 3);
            let k = b.len() / 2;
            b[k] ^= 0x5a;
            set_blob(&f, 3, b);
            (id.into(), f)
        },
        Expect::Partly(5, &["FLAC"]),
    );
    add(
        "vallen_flac_wrong_length",
        &|d, id| {
            let f = vallen_fixture(d, id, 6, 7);
            to_flac(&f);
            sql(&f, "UPDATE tr_data SET Samples = 2000 WHERE TRAI = 4");
            (id.into(), f)
        },
        Expect::Partly(5, &["FLAC", "2000"]),
    );
    add(
        "vallen_flac_cut_short",
        &|d, id| {
            let f = vallen_fixture(d, id, 6, 17);
            to_flac(&f);
            let b = blob(&f, 2);
            set_blob(&f, 2, b[..b.len() * 2 / 3].to_vec());
            (id.into(), f)
        },
        Expect::Partly(5, &["FLAC"]),
    );
    add(
        "vallen_raw_wrong_length",
        &|d, id| {
            let f = vallen_fixture(d, id, 6, 8);
            sql(
                &f,
                "UPDATE tr_data SET DataFormat = 0, Data = X'0100020003', Samples = 512 WHERE TRAI = 1",
            );
            (id.into(), f)
        },
        Expect::Partly(5, &["raw blob", "5 bytes"]),
    );
    add(
        "vallen_zero_rate",
        &|d, id| {
            let f = vallen_fixture(d, id, 6, 9);
            sql(&f, "UPDATE tr_data SET SampleRate = 0 WHERE TRAI = 2");
            (id.into(), f)
        },
        Expect::Partly(5, &["SampleRate"]),
    );
    add(
        "vallen_negative_rate",
        &|d, id| {
            let f = vallen_fixture(d, id, 6, 10);
            sql(
                &f,
                "UPDATE tr_data SET SampleRate = -10000000 WHERE TRAI = 5",
            );
            (id.into(), f)
        },
        Expect::Partly(5, &["SampleRate"]),
    );
    add(
        "vallen_absurd_samples",
        &|d, id| {
            let f = vallen_fixture(d, id, 6, 11);
            sql(
                &f,
                "UPDATE tr_data SET Samples = 1000000000000 WHERE TRAI = 6",
            );
            (id.into(), f)
        },
        Expect::Partly(5, &["1000000000000", "max_samples_per_record"]),
    );
    add(
        "vallen_pretrigger_past_end",
        &|d, id| {
            let f = vallen_fixture(d, id, 6, 12);
            sql(&f, "UPDATE tr_data SET Pretrigger = 100000 WHERE TRAI = 1");
            (id.into(), f)
        },
        Expect::Partly(5, &["pretrigger"]),
    );
    add(
        "vallen_pridb_alone",
        &|d, id| {
            let f = vallen_fixture(d, id, 7, 13);
            std::fs::remove_file(&f).unwrap();
            (id.into(), d.join(format!("{id}.pridb")))
        },
        Expect::Reject(&["no .tradb"]),
    );
    add(
        "vallen_tr_data_dropped",
        &|d, id| {
            let f = vallen_fixture(d, id, 5, 14);
            sql(&f, "DROP VIEW view_tr_data; DROP TABLE tr_data;");
            (id.into(), f)
        },
        Expect::Reject(&[]),
    );
    add(
        "vallen_infinite_tr_mv",
        &|d, id| {
            let f = vallen_fixture(d, id, 5, 15);
            sql(&f, "UPDATE tr_params SET TR_mV = 1e400");
            (id.into(), f)
        },
        Expect::Reject(&["TR_mV"]),
    );

    // --- MISTRAS .DTA ---
    add(
        "dta_length_past_end",
        &|d, _| {
            let f = d.join("past_end.DTA");
            let mut b = dta_msg(99, b"Thu May 27 10:53:54 2021\n\0");
            b.extend(60000u16.to_le_bytes());
            b.push(1);
            b.extend([0u8; 20]);
            std::fs::write(&f, b).unwrap();
            ("past_end".into(), f)
        },
        Expect::Reject(&["runs past the end"]),
    );
    add(
        "dta_truncated_message",
        &|d, _| {
            let f = d.join("trunc.DTA");
            let mut b = dta_msg(99, b"Thu May 27 10:53:54 2021\n\0");
            let h = dta_msg(1, &[0u8; 30]);
            b.extend(&h[..h.len() - 7]);
            std::fs::write(&f, b).unwrap();
            ("trunc".into(), f)
        },
        Expect::Reject(&["past the end"]),
    );
    add(
        "dta_empty",
        &|d, _| {
            let f = d.join("empty.DTA");
            std::fs::write(&f, b"").unwrap();
            ("empty".into(), f)
        },
        Expect::Skipped("does not start like a MISTRAS message stream"),
    );
    add(
        "dta_random_bytes",
        &|d, _| {
            let f = d.join("noise.DTA");
            let mut r = aepipe::util::Rng::new(77);
            let b: Vec<u8> = (0..4096).map(|_| r.next_u64() as u8).collect();
            std::fs::write(&f, b).unwrap();
            ("noise".into(), f)
        },
        Expect::Skipped("does not start like a MISTRAS message stream"),
    );

    // --- AEwin waveform text ---
    add(
        "aewin_bad_value",
        &|d, _| {
            let f = d.join("EXPA_1_1_1000.txt");
            std::fs::write(&f, values(256) + "0.1\n1..2\n").unwrap();
            std::fs::write(d.join("EXPA_1_2_2000.txt"), values(256)).unwrap();
            // The experiment is the test the files name, not their folder.
            ("EXPA".into(), f)
        },
        Expect::Partly(1, &["1..2"]),
    );
    add(
        "aewin_empty_wave",
        &|d, _| {
            let f = d.join("EXPB_1_1_1000.txt");
            std::fs::write(&f, "").unwrap();
            std::fs::write(d.join("EXPB_1_2_2000.txt"), values(256)).unwrap();
            ("EXPB".into(), f)
        },
        Expect::Partly(1, &["0 samples"]),
    );
    add(
        "aewin_header_not_volts",
        &|d, _| {
            let head = |unit: &str, hit: u32| {
                format!(
                    "SOURCE FILE NAME: C.DTA\r\nSAMPLE INTERVAL (Seconds): 1.0E-07\r\nUNITS: {unit}\r\nCHANNEL NUMBER: 1\r\nHIT NUMBER: {hit}\r\nTIME OF TEST: {hit}.5\r\n\r\n"
                )
            };
            let f = d.join("EXPC_1_1_1500000.txt");
            std::fs::write(&f, head("mV", 1) + &values(256)).unwrap();
            std::fs::write(
                d.join("EXPC_1_2_2500000.txt"),
                head("Volts", 2) + &values(256),
            )
            .unwrap();
            ("EXPC".into(), f)
        },
        Expect::Partly(1, &["'mV' is not volts"]),
    );
    add(
        "aewin_header_points_lie",
        &|d, _| {
            let f = d.join("EXPD_1_1_1000.txt");
            std::fs::write(
                &f,
                "SAMPLE INTERVAL (Seconds): 1.0E-07\nSIGNAL UNITS: Volts\nNUMBER OF DATA POINTS PER WAVEFORM: 9999\nHIT NUMBER: 1\n\n".to_string()
                    + &values(256),
            )
            .unwrap();
            ("EXPD".into(), f)
        },
        Expect::Reject(&["declares 9999 data points; the file holds 256"]),
    );

    // --- Vallen TXT export ---
    add(
        "vallen_txt_bad_row",
        &|d, _| {
            let f = d.join("export_1.txt");
            let rows: String = (0..64)
                .map(|i| {
                    format!(
                        "{:.1}\t{}\r\r\n",
                        i as f64 * 0.2 - 2.0,
                        (i as f64 * 0.3).sin()
                    )
                })
                .collect();
            std::fs::write(
                &f,
                format!("Datafile: plateX.tradb, Trai: 1, Chan:1\r\r\nTime (microsec)\tAmplitude (mV)\r\r\n{rows}12.8\tclipped\r\r\n"),
            )
            .unwrap();
            ("plateX".into(), f)
        },
        Expect::Reject(&["'12.8\tclipped' is not a time and an amplitude"]),
    );
    add(
        "vallen_txt_unit_unknown",
        &|d, _| {
            let f = d.join("export_2.txt");
            std::fs::write(
                &f,
                "Datafile: plateY, Trai: 2, Chan:1\r\r\nTime (microsec)\tAmplitude (dB)\r\r\n0\t1\r\r\n0.2\t2\r\r\n",
            )
            .unwrap();
            ("plateY".into(), f)
        },
        Expect::Reject(&["amplitude unit 'dB' is not a voltage"]),
    );

    // --- WaveExplorer ---
    add(
        "waveexplorer_huge_event_count",
        &|d, _| {
            let f = d.join("a_wave.txt");
            std::fs::write(&f, "10\t1000000000000\t1024\t1\n0.1\n0.2\n").unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["1000000000000"]),
    );
    add(
        "waveexplorer_huge_event_length",
        &|d, _| {
            let f = d.join("b_wave.txt");
            std::fs::write(&f, "10\t2\t60000000000\t1\n0.1\n0.2\n").unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["60000000000"]),
    );
    add(
        "waveexplorer_truncated",
        &|d, _| {
            let f = d.join("c_wave.txt");
            std::fs::write(&f, format!("10\t3\t64\t1\n{}{}", values(64), values(10))).unwrap();
            ("c_wave".into(), f)
        },
        Expect::Partly(1, &["event"]),
    );
    add(
        "waveexplorer_zero_rate",
        &|d, _| {
            let f = d.join("d_wave.txt");
            std::fs::write(&f, format!("0\t1\t64\t1\n{}", values(64))).unwrap();
            ("d_wave".into(), f)
        },
        Expect::Reject(&["not a valid WaveExplorer header"]),
    );
    add(
        "waveexplorer_two_channels_short_line",
        &|d, _| {
            let f = d.join("scan.txt");
            let pair: String = (0..64).map(|i| format!("0.{i}\t-0.{i}\t\r\n")).collect();
            std::fs::write(&f, format!("10\t2\t64\t2\r\n{pair}0.1\t\r\n{pair}")).unwrap();
            ("scan".into(), f)
        },
        Expect::Partly(2, &["1 value(s) where the header promises 2 channels"]),
    );

    // --- WAV ---
    add(
        "wav_header_claims_4gib",
        &|d, _| {
            let f = d.join("huge.wav");
            std::fs::write(&f, wav_header(10_000_000, 16, 0xFFFF_FFF0)).unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["header promises"]),
    );
    add(
        "wav_zero_rate",
        &|d, _| {
            let f = d.join("zero_rate.wav");
            let mut b = wav_header(0, 16, 200);
            b.extend([1u8; 200]);
            std::fs::write(&f, b).unwrap();
            (folder(d), f)
        },
        Expect::Reject(&[]),
    );
    add(
        "wav_truncated_data",
        &|d, _| {
            let f = d.join("short.wav");
            let mut b = wav_header(10_000_000, 16, 4000);
            b.extend([3u8; 100]);
            std::fs::write(&f, b).unwrap();
            (folder(d), f)
        },
        Expect::Reject(&[]),
    );
    add(
        "wav_not_riff",
        &|d, _| {
            let f = d.join("text.wav");
            std::fs::write(&f, "RIFX but really a text file").unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["not a readable WAV"]),
    );
    add(
        "wav_empty",
        &|d, _| {
            let f = d.join("empty.wav");
            aepipe::ingest::wavfmt::write_wav_f32(&f, 10_000_000, &[]).unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["0 samples"]),
    );
    add(
        "wav_ten_million_samples",
        &|d, _| {
            let f = d.join("long.wav");
            // Over the corpus's max_samples_per_record (10⁶): refused with both numbers.
            aepipe::ingest::wavfmt::write_wav_f32(&f, 10_000_000, &vec![0.01f32; 10_000_000])
                .unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["10000000", "1000000"]),
    );
    add(
        "wav_one_sample",
        &|d, _| {
            let f = d.join("one.wav");
            aepipe::ingest::wavfmt::write_wav_f32(&f, 10_000_000, &[0.5]).unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["1 samples", "min_samples"]),
    );

    // --- CSV ---
    add(
        "csv_nan_inf",
        &|d, _| {
            let f = d.join("naninf.csv");
            std::fs::write(
                &f,
                "voltage_v\n0.1\nNaN\n0.2\ninf\n".to_string() + &values(60),
            )
            .unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["2 non-finite"]),
    );
    add(
        "csv_header_only",
        &|d, _| {
            let f = d.join("header.csv");
            std::fs::write(&f, "voltage_v\n").unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["0 samples"]),
    );
    add(
        "csv_decimal_commas",
        &|d, _| {
            let f = d.join("comma.csv");
            let body: String = tone(256)
                .iter()
                .enumerate()
                .map(|(i, v)| format!("{};{}\n", i as f64 * 1e-7, v).replace('.', ","))
                .collect();
            std::fs::write(&f, "time_s;voltage_v\n".to_string() + &body).unwrap();
            (folder(d), f)
        },
        Expect::Rows(1),
    );
    add(
        "csv_crlf",
        &|d, _| {
            let f = d.join("crlf.csv");
            let body: String = tone(256).iter().map(|v| format!("{v}\r\n")).collect();
            std::fs::write(&f, "voltage_v\r\n".to_string() + &body).unwrap();
            (folder(d), f)
        },
        Expect::Rows(1),
    );
    add(
        "csv_not_utf8",
        &|d, _| {
            let f = d.join("latin1.csv");
            let mut b = b"voltage_v\n0.1\n".to_vec();
            b.extend([0xff, 0xfe, b'\n']);
            b.extend(values(60).as_bytes());
            std::fs::write(&f, b).unwrap();
            (folder(d), f)
        },
        Expect::Reject(&[]),
    );
    add(
        "csv_long_ragged",
        &|d, _| {
            let f = d.join("long.csv");
            let mut s = String::from("hit,channel,voltage_v\n");
            for v in tone(128) {
                s.push_str(&format!("1,1,{v}\n"));
            }
            s.push_str("2,1\n");
            for v in tone(128) {
                s.push_str(&format!("3,1,{v}\n"));
            }
            std::fs::write(&f, s).unwrap();
            ("long".into(), f)
        },
        Expect::Partly(2, &["line 130"]),
    );

    // --- Plain text ---
    add(
        "text_bad_line",
        &|d, _| {
            let f = d.join("bad.txt");
            std::fs::write(&f, "0.1\n0.2\n0.3\nbanana\n0.4\n").unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["line 4", "banana"]),
    );
    add(
        "text_not_utf8",
        &|d, _| {
            let f = d.join("bin.txt");
            let mut b = values(40).into_bytes();
            b.extend([0xc3, 0x28, b'\n']);
            std::fs::write(&f, b).unwrap();
            (folder(d), f)
        },
        Expect::Reject(&[]),
    );
    add(
        "text_crlf",
        &|d, _| {
            let f = d.join("crlf.txt");
            std::fs::write(&f, values(256).replace('\n', "\r\n")).unwrap();
            (folder(d), f)
        },
        Expect::Rows(1),
    );
    add(
        "text_empty",
        &|d, _| {
            let f = d.join("empty.txt");
            std::fs::write(&f, "").unwrap();
            (folder(d), f)
        },
        Expect::Skipped("empty file"),
    );

    // --- Parquet (aepipe's waveforms table) ---
    add(
        "parquet_truncated",
        &|d, _| {
            let f = d.join("waveforms.parquet");
            let mut e = Experiment::new("pq", 5, 21);
            e.n_samples = 512;
            let items = e.records().map(aepipe::model::Item::Record);
            let tmp = d.join("w");
            std::fs::create_dir_all(&tmp).unwrap();
            aepipe::pipeline::stream(
                items,
                aepipe::pipeline::StreamJob::Waveforms,
                &tmp,
                &aepipe::config::ValidConfig::default(),
                &aepipe::pipeline::StreamOptions::with_threads(1),
            )
            .unwrap();
            std::fs::rename(tmp.join("waveforms.parquet"), &f).unwrap();
            std::fs::remove_dir_all(&tmp).unwrap();
            truncate(&f, 0.6);
            ("waveforms".into(), f)
        },
        Expect::Reject(&[]),
    );
    add(
        "parquet_not_parquet",
        &|d, _| {
            let f = d.join("fake.parquet");
            std::fs::write(&f, b"PAR1 and then nothing a Parquet reader wants").unwrap();
            ("fake".into(), f)
        },
        Expect::Reject(&[]),
    );

    // --- Folders and the file system ---
    add(
        "empty_folder",
        &|d, _| {
            std::fs::create_dir_all(d.join("nothing_here")).unwrap();
            (folder(d), d.join("nothing_here"))
        },
        Expect::Rows(0),
    );
    add(
        "symlink_loop",
        &|d, _| {
            std::os::unix::fs::symlink(d, d.join("again")).unwrap();
            std::os::unix::fs::symlink(d, d.join("and_again")).unwrap();
            std::fs::write(d.join("v.txt"), values(128)).unwrap();
            (folder(d), d.join("v.txt"))
        },
        Expect::Rows(1),
    );
    add(
        "dangling_symlink",
        &|d, _| {
            let f = d.join("gone.wav");
            std::os::unix::fs::symlink(d.join("no-such-file.wav"), &f).unwrap();
            (folder(d), f)
        },
        Expect::Reject(&["not a readable WAV", "No such file"]),
    );
    cases
}

/// Rejects as (experiment, file, record, stage, reason).
fn rejects(p: &Path) -> Vec<[String; 5]> {
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
    rows.into_iter()
        .map(|r| {
            [
                r[0].clone(),
                r[1].clone(),
                r[2].clone(),
                r[3].clone(),
                r[4].clone(),
            ]
        })
        .collect()
}

#[test]
#[cfg(unix)]
fn every_broken_recording_is_a_named_reject_and_every_good_hit_is_written() {
    let t = TempDir::new("corpus");
    let batch = t.path().join("batch");
    std::fs::create_dir_all(&batch).unwrap();
    vallen_fixture(&batch, "good", 30, 1);
    let cases = recordings(&batch);
    let cfg = t.path().join("corpus.toml");
    std::fs::write(&cfg, "[ingest]\nmax_samples_per_record = 1000000\n").unwrap();
    seeds_out(&cases);

    let out = t.path().join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .env("XDG_CACHE_HOME", crate::test_cache())
        .args(["features", "--quiet", "--config"])
        .arg(&cfg)
        .arg(&batch)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let by = &m["counts"]["by_experiment"];
    let rows = |e: &str| by[e]["rows"].as_u64().unwrap_or(0);
    let rej = rejects(&out.join("rejects.parquet"));

    // Nothing panicked; every reason is one line.
    for r in &rej {
        assert!(!r[4].contains("panick"), "{r:?}");
        assert!(!r[4].is_empty() && !r[4].contains('\n'), "{r:?}");
    }
    // Every good hit.
    assert_eq!(rows("good"), 30, "{by}");
    assert!(!rej.iter().any(|r| r[0] == "good"));

    let mut failures = Vec::new();
    let mut tally: BTreeMap<&str, usize> = BTreeMap::new();
    for c in &cases {
        let fname = c.file.file_name().unwrap().to_string_lossy().to_string();
        let about: Vec<&[String; 5]> = rej
            .iter()
            .filter(|r| r[1].ends_with(&format!("/{fname}")))
            .collect();
        let skipped: Vec<String> = m["skipped"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| s["path"].as_str().unwrap().ends_with(&format!("/{fname}")))
            .map(|s| s["reason"].as_str().unwrap().to_string())
            .collect();
        let ok = match &c.expect {
            Expect::Reject(words) => {
                !about.is_empty()
                    && rows(&c.experiment) == 0
                    && about.iter().all(|r| words.iter().all(|w| r[4].contains(w)))
            }
            Expect::Rows(n) => about.is_empty() && rows(&c.experiment) == *n,
            Expect::Skipped(why) => {
                about.is_empty() && skipped.len() == 1 && skipped[0].contains(why)
            }
            Expect::Partly(n, words) => {
                rows(&c.experiment) == *n
                    && !about.is_empty()
                    && about.iter().all(|r| words.iter().all(|w| r[4].contains(w)))
            }
        };
        *tally.entry(if ok { "ok" } else { "failed" }).or_default() += 1;
        if !ok {
            failures.push(format!(
                "{} ({:?}): rows {} of {}, rejects {:?}, skipped {:?}",
                c.name,
                c.expect,
                rows(&c.experiment),
                c.experiment,
                about,
                skipped
            ));
        }
    }
    // The truncated .tradb: its 20 hits are each a row or a reject.
    let tr = cases
        .iter()
        .find(|c| c.name == "vallen_truncated_tradb")
        .unwrap();
    let tr_rej = rej
        .iter()
        .filter(|r| r[0] == tr.experiment && !r[2].is_empty())
        .count() as u64;
    assert_eq!(rows(&tr.experiment) + tr_rej, 20);

    // The counts add up: the manifest's totals are the tables' rows, and per experiment.
    let (_, frows) = table_rows(&out.join("features.parquet"));
    assert_eq!(
        m["counts"]["rows_written"].as_u64().unwrap() as usize,
        frows.len()
    );
    assert_eq!(m["counts"]["rejects"].as_u64().unwrap() as usize, rej.len());
    let sum = |k: &str| -> u64 {
        by.as_object()
            .unwrap()
            .values()
            .map(|v| v[k].as_u64().unwrap())
            .sum()
    };
    assert_eq!(sum("rows") as usize, frows.len());
    assert_eq!(sum("rejects") as usize, rej.len());
    eprintln!(
        "corpus: {} recording cases, {tally:?}, {} reject rows",
        cases.len(),
        rej.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(cases.len() >= 40);
}

/// `AEPIPE_CORPUS_OUT`: each recording case's files as seeds of the fuzz target of its kind.
fn seeds_out(cases: &[Case]) {
    let Some(dir) = std::env::var_os("AEPIPE_CORPUS_OUT") else {
        return;
    };
    let dir = PathBuf::from(dir);
    // The seed's first byte picks the file name in fuzz/fuzz_targets/text_readers.rs's
    // NAMES: 0 `x_wave.txt`, 1 `hit.txt`, 2 `hit.csv`, 3 `long.csv`, 4 `hit.wav`, 6 AEwin.
    for c in cases {
        let Ok(bytes) = std::fs::read(&c.file) else {
            continue;
        };
        let fname = c.file.file_name().unwrap().to_string_lossy().to_lowercase();
        if fname.ends_with(".tradb") || fname.ends_with(".pridb") {
            // The salvage reader's seeds: the database file as it is.
            let d = dir.join("sqlite_salvage");
            std::fs::create_dir_all(&d).unwrap();
            std::fs::write(d.join(c.name), &bytes).unwrap();
        }
        if fname.ends_with(".tradb") {
            // The blob decoder's seeds: DataFormat byte, Samples (u32 LE), blob.
            let Ok(db) = rusqlite::Connection::open(&c.file) else {
                continue;
            };
            let Ok(mut q) = db.prepare("SELECT DataFormat, Samples, Data FROM tr_data LIMIT 2")
            else {
                continue;
            };
            let blobs: Vec<(i64, i64, Vec<u8>)> = q
                .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
                .map(|it| it.flatten().collect())
                .unwrap_or_default();
            let d = dir.join("vallen_blob");
            std::fs::create_dir_all(&d).unwrap();
            for (k, (f, n, b)) in blobs.into_iter().enumerate() {
                let mut seed = vec![f as u8];
                seed.extend((n as u32).to_le_bytes());
                seed.extend(b);
                std::fs::write(d.join(format!("{}_{k}", c.name)), seed).unwrap();
            }
            continue;
        }
        let (target, pick) = if fname.ends_with(".dta") {
            ("dta_messages", None)
        } else if fname.ends_with("_wave.txt") {
            ("text_readers", Some(0u8))
        } else if fname.ends_with(".wav") {
            ("text_readers", Some(4))
        } else if fname.starts_with("long") && fname.ends_with(".csv") {
            ("text_readers", Some(3))
        } else if fname.ends_with(".csv") {
            ("text_readers", Some(2))
        } else if c.name.starts_with("aewin") {
            ("text_readers", Some(6))
        } else if fname.ends_with(".txt") {
            ("text_readers", Some(1))
        } else {
            continue;
        };
        let d = dir.join(target);
        std::fs::create_dir_all(&d).unwrap();
        let mut seed = pick.map(|p| vec![p]).unwrap_or_default();
        seed.extend(bytes.iter().take(1 << 20));
        std::fs::write(d.join(c.name), seed).unwrap();
    }
}

#[test]
fn every_broken_definition_file_is_one_error_line_naming_it() {
    let t = TempDir::new("corpus-defs");
    let d = t.path();
    let s = |p: &Path| p.display().to_string();
    let data = d.join("data");
    vallen_fixture(&data, "exp", 40, 3);
    let feats = d.join("f");
    let model = d.join("model");
    for args in [
        vec!["features", &s(&data), "--out", &s(&feats), "--quiet"],
        vec![
            "som",
            "train",
            &s(&feats.join("features.parquet")),
            "--out",
            &s(&model),
        ],
    ] {
        let (c, _, e) = aepipe_within(&args, 120);
        assert_eq!(c, 0, "{e}");
    }
    let good_model = std::fs::read_to_string(model.join("model.json")).unwrap();

    // (case, file name, contents, command kind)
    let mut cases: Vec<(&str, &str, Vec<u8>, &str)> = vec![
        (
            "toml_syntax",
            "syntax.toml",
            b"[ingest\nx = 1\n".to_vec(),
            "pipeline",
        ),
        (
            "toml_unknown_key",
            "typo.toml",
            b"[ingest]\nsampel_rate_hz = 5\n".to_vec(),
            "pipeline",
        ),
        (
            "toml_n_windows_65",
            "windows.toml",
            b"[dsp.bins]\nn_windows = 65\n".to_vec(),
            "pipeline",
        ),
        (
            "toml_not_utf8",
            "latin1.toml",
            b"[ingest]\n# \xff\xfe\n".to_vec(),
            "pipeline",
        ),
        (
            "toml_nan_rate",
            "nan.toml",
            b"[ingest]\nsample_rate_hz = nan\n".to_vec(),
            "pipeline",
        ),
        (
            "toml_zero_limit",
            "limit.toml",
            b"[ingest]\nmax_samples_per_record = 0\n".to_vec(),
            "pipeline",
        ),
        (
            "toml_wrong_type",
            "type.toml",
            b"[som]\nrows = \"many\"\n".to_vec(),
            "pipeline",
        ),
        (
            "appendix_huge_iterations",
            "iters.txt",
            crate::sim::APPENDIX
                .replace(" 2000 IEuler", " 1000000000000000000000000000000 IEuler")
                .into_bytes(),
            "appendix",
        ),
        (
            "appendix_truncated",
            "cut.txt",
            crate::sim::APPENDIX.as_bytes()[..crate::sim::APPENDIX.len() / 2].to_vec(),
            "appendix",
        ),
        (
            "appendix_not_a_number",
            "word.txt",
            crate::sim::APPENDIX
                .replace("3.5E10 5.0E-04", "lots 5.0E-04")
                .into_bytes(),
            "appendix",
        ),
        (
            "appendix_negative_mass",
            "mass.txt",
            crate::sim::APPENDIX
                .replace("1 0.0 0.0 0 5.1E-12", "1 0.0 0.0 0 -5.1E-12")
                .into_bytes(),
            "appendix",
        ),
        (
            "reference_unknown_scenario",
            "nope.toml",
            b"[reference]\n[[reference.scenario]]\nname = \"nope\"\n".to_vec(),
            "reference",
        ),
        (
            "reference_not_toml",
            "ref.toml",
            b"reference = [[[\n".to_vec(),
            "reference",
        ),
        (
            "model_json_garbage",
            "model.json",
            b"{\"som\": 12".to_vec(),
            "model",
        ),
        (
            "cod_huge_header",
            "huge.cod",
            b"100000000 rect 100000 100000 gaussian\n".to_vec(),
            "model",
        ),
        (
            "cod_short_node",
            "short.cod",
            b"3 rect 2 1 gaussian\n0.1 0.2 0.3 a\n0.1 0.2\n".to_vec(),
            "model",
        ),
        (
            "cod_not_finite",
            "nan.cod",
            b"2 rect 1 1 gaussian\nnan 0.2 a\n".to_vec(),
            "model",
        ),
    ];
    // A model.json whose codebook lost a weight, and one with a non-finite scaling.
    let mut v: serde_json::Value = serde_json::from_str(&good_model).unwrap();
    v["som"]["weights"].as_array_mut().unwrap().pop();
    cases.push((
        "model_json_short_weights",
        "model.json",
        v.to_string().into_bytes(),
        "model",
    ));
    let mut v: serde_json::Value = serde_json::from_str(&good_model).unwrap();
    v["som"]["rows"] = serde_json::json!(1u64 << 40);
    cases.push((
        "model_json_huge_map",
        "model.json",
        v.to_string().into_bytes(),
        "model",
    ));

    let mut failures = Vec::new();
    for (i, (name, file, bytes, kind)) in cases.iter().enumerate() {
        let dir = d.join(format!("case{i:02}"));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join(file);
        std::fs::write(&f, bytes).unwrap();
        if file.ends_with(".cod") {
            // A codebook is read beside the model's model.json (columns, scaling).
            std::fs::write(dir.join("model.json"), &good_model).unwrap();
        }
        let out = dir.join("out");
        let (fs, os) = (s(&f), s(&out));
        let feat = s(&feats.join("features.parquet"));
        let args: Vec<&str> = match *kind {
            "pipeline" => vec!["features", "--config", &fs, feat.as_str(), "--out", &os],
            "appendix" => vec!["simulate", &fs, "--out", &os],
            "reference" => vec!["reference", "--config", &fs, "--out", &os],
            _ => vec!["som", "classify", &fs, &feat, "--out", &os],
        };
        let (code, _, err) = aepipe_within(&args, 60);
        let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
        let ok = code == 1 && lines.len() == 1 && lines[0].contains(*file);
        if !ok {
            failures.push(format!("{name}: exit {code}, stderr {err:?}"));
        }
        if let Some(dir) = std::env::var_os("AEPIPE_CORPUS_OUT") {
            let target = match *kind {
                "pipeline" => Some("pipeline_toml"),
                "appendix" => Some("appendix_a"),
                _ if file.ends_with(".cod") => Some("som_model"),
                _ => None,
            };
            if let Some(target) = target {
                let d = PathBuf::from(dir).join(target);
                std::fs::create_dir_all(&d).unwrap();
                std::fs::write(d.join(name), bytes).unwrap();
            }
        }
    }
    eprintln!("corpus: {} definition-file cases", cases.len());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
