//! Formats aepipe reads, checked with fixtures it writes itself: WAV, CSV (per hit and long),
//! plain text, and detection of what is not a recording.

use crate::{read_all, TempDir};
use aepipe::config::PipelineConfig;
use aepipe::ingest::{discover, Format};

fn tone(n: usize, f: f64, fs: f64, a: f64) -> Vec<f32> {
    (0..n)
        .map(|i| (a * (2.0 * std::f64::consts::PI * f * i as f64 / fs).sin()) as f32)
        .collect()
}

#[test]
fn wav_folder_is_one_experiment_with_one_hit_per_file() {
    let t = TempDir::new("wav");
    let dir = t.path().join("wav_exp");
    std::fs::create_dir_all(&dir).unwrap();
    let a = tone(2000, 250e3, 10e6, 0.3);
    let b = tone(1000, 750e3, 10e6, 0.1);
    // Natural order: hit_2 before hit_10.
    aepipe::ingest::wavfmt::write_wav_f32(&dir.join("hit_10.wav"), 10_000_000, &b).unwrap();
    aepipe::ingest::wavfmt::write_wav_f32(&dir.join("hit_2.wav"), 10_000_000, &a).unwrap();
    // A 16-bit integer WAV: full scale maps to ±1 V.
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: 5_000_000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(dir.join("hit_11.wav"), spec).unwrap();
    for _ in 0..100 {
        w.write_sample(16384i16).unwrap(); // channel 1: +0.5 V
        w.write_sample(-32768i16).unwrap(); // channel 2: -1 V
    }
    w.finalize().unwrap();
    let (recs, rejs) = read_all(
        &[t.path().to_path_buf()],
        &aepipe::config::ValidConfig::default(),
    );
    assert!(rejs.is_empty(), "{rejs:?}");
    assert_eq!(recs.len(), 4);
    assert!(recs.iter().all(|r| r.experiment == "wav_exp"));
    assert_eq!(recs[0].samples, a);
    assert_eq!(recs[0].hit, 1);
    assert_eq!(recs[1].samples, b);
    assert_eq!(recs[2].sample_rate_hz, 5e6);
    assert_eq!((recs[2].channel, recs[3].channel), (1, 2));
    assert!(recs[2].samples.iter().all(|s| *s == 0.5));
    assert!(recs[3].samples.iter().all(|s| *s == -1.0));
}

#[test]
fn csv_per_hit_takes_rate_and_pretrigger_from_the_time_column() {
    let t = TempDir::new("csv");
    let dir = t.path().join("csv_exp");
    std::fs::create_dir_all(&dir).unwrap();
    let mut s = String::from("time_s;voltage_v\n");
    for i in -100..400 {
        s.push_str(&format!(
            "{:e};{}\n",
            i as f64 * 2e-7,
            (i as f64 * 0.001).sin()
        ));
    }
    std::fs::write(dir.join("a.csv"), s).unwrap();
    std::fs::write(dir.join("b.csv"), "0.5\n0.25\n-0.125\n").unwrap();
    let mut cfg = PipelineConfig::default();
    cfg.ingest.sample_rate_hz = 1e6;
    cfg.ingest.pretrigger_samples = 1;
    let cfg = cfg.check().unwrap();
    let (recs, rejs) = read_all(&[dir], &cfg);
    assert!(rejs.is_empty(), "{rejs:?}");
    assert_eq!(recs.len(), 2);
    assert!(
        (recs[0].sample_rate_hz - 5e6).abs() < 1e-3,
        "{}",
        recs[0].sample_rate_hz
    );
    assert_eq!(recs[0].pretrigger, 100);
    assert_eq!(recs[0].samples.len(), 500);
    assert_eq!(recs[1].samples, vec![0.5, 0.25, -0.125]);
    assert_eq!((recs[1].sample_rate_hz, recs[1].pretrigger), (1e6, 1));
}

#[test]
fn csv_long_table_groups_rows_by_hit_and_channel() {
    let t = TempDir::new("csvlong");
    let mut s = String::from("hit,channel,voltage_v\n");
    for (hit, ch, n) in [(1, 1, 30), (1, 2, 20), (2, 1, 25), (1, 1, 5)] {
        for i in 0..n {
            s.push_str(&format!("{hit},{ch},{}\n", i as f64 / 100.0));
        }
    }
    s.push_str("3,1,notanumber\n");
    let f = t.path().join("long.csv");
    std::fs::write(&f, s).unwrap();
    let d = discover(
        std::slice::from_ref(&f),
        &aepipe::config::ValidConfig::default().ingest,
    );
    assert_eq!(d.sources[0].format, Format::CsvLong);
    let (recs, rejs) = read_all(&[f], &aepipe::config::ValidConfig::default());
    let got: Vec<(u32, u64, usize)> = recs
        .iter()
        .map(|r| (r.channel, r.hit, r.samples.len()))
        .collect();
    assert_eq!(got, vec![(1, 1, 30), (2, 1, 20), (1, 2, 25)]);
    assert_eq!(rejs.len(), 2, "{rejs:?}");
    assert!(
        rejs[0].reason.contains("not contiguous"),
        "{}",
        rejs[0].reason
    );
    assert!(
        rejs[1].reason.contains("notanumber") && rejs[1].reason.contains("line"),
        "{}",
        rejs[1].reason
    );
}

#[test]
fn text_folder_uses_configured_rate_and_gain() {
    let t = TempDir::new("text");
    let dir = t.path().join("txt_exp");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("one.txt"), "1.0\n-2.0\n0.5\n").unwrap();
    let mut cfg = PipelineConfig::default();
    cfg.ingest.gain_db = 20.0;
    cfg.ingest.sample_rate_hz = 2e6;
    let cfg = cfg.check().unwrap();
    let (recs, _) = read_all(&[dir], &cfg);
    assert_eq!(recs.len(), 1);
    assert_eq!(recs[0].sample_rate_hz, 2e6);
    let want = [0.1f32, -0.2, 0.05];
    for (a, b) in recs[0].samples.iter().zip(want) {
        assert!((a - b).abs() < 1e-7);
    }
}
