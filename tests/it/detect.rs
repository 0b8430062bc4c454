//! Continuous recordings (issue 40): a synthetic two-channel stream made here from
//! reference-library bursts at known places and amplitudes — pairs 20–500 µs apart, noise
//! at a stated level, one clipped burst — written as WAV (float), RF64, `.npy` and raw
//! int16; `aepipe features` with `[detect] mode = "on"` cuts each into the same hits, and
//! those are the hits a plain per-sample reading of the rules gives on the same samples.

use crate::TempDir;
use std::path::Path;

const FS: f64 = 10e6;
/// One count is 1 µV; the threshold (40.1 dB_AE, 101.2 µV) sits between two counts.
const THRESHOLD_DB: f64 = 40.1;
const NOISE_COUNTS: f64 = 2.0;
/// The RF64 file is int16 at ±1 V full scale (as WAV integers are read): this much
/// preamplifier gain makes a count 1 µV again.
fn rf64_gain_db() -> f64 {
    20.0 * (1e6 / 32768.0f64).log10()
}

/// The rules read sample by sample (the detector's own code skips quiet chunks and works
/// block by block): the (first, last) crossing of every hit.
fn reference(x: &[i16], thr: f32, ddt: usize, rearm: usize, maxd: usize) -> Vec<(usize, usize)> {
    enum St {
        Armed,
        In(usize, usize),
        Blind(usize),
    }
    let (mut st, mut out, mut k) = (St::Armed, Vec::new(), 0usize);
    while k < x.len() {
        let hot = (x[k] as f32).abs() >= thr;
        match st {
            St::Armed => {
                if hot {
                    st = St::In(k, k);
                }
                k += 1;
            }
            St::In(f, l) => {
                if k <= (l + ddt).min(f + maxd - 1) {
                    if hot {
                        st = St::In(f, k);
                    }
                    k += 1;
                } else {
                    out.push((f, l));
                    st = St::Blind((l + ddt).min(f + maxd) + rearm);
                }
            }
            St::Blind(u) => {
                if k <= u {
                    k += 1;
                } else {
                    st = St::Armed;
                }
            }
        }
    }
    if let St::In(f, l) = st {
        out.push((f, l));
    }
    out
}

/// Two channels of 0.3 s: bursts at known places, the second channel the first delayed
/// 5 µs and at 60 %. Returns the interleaved counts and each burst's start on channel 1.
fn stream(lib: &aepipe::synth::Library) -> (Vec<i16>, Vec<usize>) {
    let n = (0.3 * FS) as usize;
    let mut rng = aepipe::util::Rng::new(12);
    let mut ch1: Vec<f64> = (0..n).map(|_| NOISE_COUNTS * rng.normal()).collect();
    let mut ch2: Vec<f64> = (0..n).map(|_| NOISE_COUNTS * rng.normal()).collect();
    // (start s, amplitude counts, signal): pairs 20, 150 and 500 µs apart, one burst
    // driven past the int16 range (clipped).
    let sig = |i: usize| -> &Vec<f64> {
        if i.is_multiple_of(2) {
            &lib.bond[i / 2 % lib.bond.len()].samples
        } else {
            &lib.fibre[i / 2 % lib.fibre.len()].samples
        }
    };
    let plan: Vec<(f64, f64)> = vec![
        (0.010, 3000.0),
        (0.040, 800.0),
        (0.040_020, 600.0),
        (0.090, 2000.0),
        (0.090_150, 1500.0),
        (0.150, 5000.0),
        (0.150_500, 900.0),
        (0.220, 90_000.0),
        (0.260, 400.0),
    ];
    let mut starts = Vec::new();
    for (i, (t, a)) in plan.iter().enumerate() {
        let s = sig(i);
        let at = (t * FS) as usize;
        starts.push(at);
        for (j, v) in s.iter().enumerate() {
            if at + j < n {
                ch1[at + j] += a * v;
            }
            if at + 50 + j < n {
                ch2[at + 50 + j] += 0.6 * a * v;
            }
        }
    }
    let q = |v: f64| v.round().clamp(-32768.0, 32767.0) as i16;
    let mut inter = Vec::with_capacity(2 * n);
    for k in 0..n {
        inter.push(q(ch1[k]));
        inter.push(q(ch2[k]));
    }
    (inter, starts)
}

fn write_all(dir: &Path, x: &[i16]) {
    std::fs::create_dir_all(dir).unwrap();
    // WAV float32 in volts.
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: FS as u32,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    std::fs::create_dir_all(dir.join("wav")).unwrap();
    let mut w = hound::WavWriter::create(dir.join("wav").join("s.wav"), spec).unwrap();
    for &c in x {
        w.write_sample((c as f64 * 1e-6) as f32).unwrap();
    }
    w.finalize().unwrap();
    // RF64 int16: ds64 holds the data size, the data chunk says 0xFFFFFFFF.
    let bytes: Vec<u8> = x.iter().flat_map(|c| c.to_le_bytes()).collect();
    let mut f = Vec::new();
    f.extend(b"RF64");
    f.extend(0xFFFF_FFFFu32.to_le_bytes());
    f.extend(b"WAVEds64");
    f.extend(28u32.to_le_bytes());
    f.extend(0u64.to_le_bytes()); // riff size (unused)
    f.extend((bytes.len() as u64).to_le_bytes());
    f.extend(0u64.to_le_bytes()); // sample count
    f.extend(0u32.to_le_bytes()); // table length
    f.extend(b"fmt ");
    f.extend(16u32.to_le_bytes());
    f.extend(1u16.to_le_bytes());
    f.extend(2u16.to_le_bytes());
    f.extend((FS as u32).to_le_bytes());
    f.extend((FS as u32 * 4).to_le_bytes());
    f.extend(4u16.to_le_bytes());
    f.extend(16u16.to_le_bytes());
    f.extend(b"data");
    f.extend(0xFFFF_FFFFu32.to_le_bytes());
    f.extend(&bytes);
    std::fs::create_dir_all(dir.join("rf64")).unwrap();
    std::fs::write(dir.join("rf64").join("s.wav"), &f).unwrap();
    // .npy, channels × samples, int16 with its scale beside it.
    let n = x.len() / 2;
    let mut npy = b"\x93NUMPY\x01\x00".to_vec();
    let mut h = format!("{{'descr': '<i2', 'fortran_order': False, 'shape': (2, {n}), }}");
    while (10 + h.len() + 1) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    npy.extend((h.len() as u16).to_le_bytes());
    npy.extend(h.as_bytes());
    for c in 0..2 {
        for k in 0..n {
            npy.extend(x[2 * k + c].to_le_bytes());
        }
    }
    std::fs::create_dir_all(dir.join("npy")).unwrap();
    std::fs::write(dir.join("npy").join("s.npy"), &npy).unwrap();
    std::fs::write(
        dir.join("npy").join("s.npy.toml"),
        "volts_per_unit = 1e-6\n",
    )
    .unwrap();
    // Raw interleaved int16 described by its TOML.
    std::fs::create_dir_all(dir.join("raw")).unwrap();
    std::fs::write(dir.join("raw").join("s.bin"), &bytes).unwrap();
    std::fs::write(
        dir.join("raw").join("s.bin.toml"),
        "dtype = \"int16\"\nchannels = 2\nsample_rate_hz = 10e6\nvolts_per_unit = 1e-6\n",
    )
    .unwrap();
}

fn config(gain_db: f64) -> aepipe::config::ValidConfig {
    let mut c = aepipe::config::PipelineConfig::default();
    c.ingest.sample_rate_hz = FS;
    c.ingest.gain_db = gain_db;
    c.detect.mode = aepipe::detect::DetectMode::On;
    c.detect.threshold_db = THRESHOLD_DB;
    c.detect.split_gap_s = 100e-6;
    c.check().unwrap()
}

/// (channel, first, last) of every cut hit, from hits.parquet, sorted.
fn cut_hits(out: &Path) -> Vec<(i64, usize, usize)> {
    let (names, rows) = crate::table_rows(&out.join("hits.parquet"));
    let col = |n: &str| names.iter().position(|c| c == n).unwrap();
    let (ch, t, d, src) = (
        col("channel"),
        col("time_s"),
        col("duration_s"),
        col("source"),
    );
    let mut v: Vec<(i64, usize, usize)> = rows
        .iter()
        .map(|r| {
            assert_eq!(r[src], "detect");
            let first = (r[t].parse::<f64>().unwrap() * FS).round() as usize;
            let dur = (r[d].parse::<f64>().unwrap() * FS).round() as usize;
            (r[ch].parse().unwrap(), first, first + dur)
        })
        .collect();
    v.sort();
    v
}

#[test]
fn a_stream_is_cut_as_the_rules_say_in_every_format() {
    let d = TempDir::new("detect");
    let lib = crate::e2e::small_library_seeded(d.path(), "lib", 41, 1);
    let lib = aepipe::synth::Library::read(&lib, FS).unwrap();
    let (x, starts) = stream(&lib);
    write_all(&d.path().join("in"), &x);
    // The reference on each channel: thresholds in counts.
    let thr = (1e-6 * 10f64.powf(THRESHOLD_DB / 20.0) / 1e-6) as f32;
    let dc = aepipe::detect::DetectConfig::default();
    let n = |s: f64| (s * FS).round() as usize;
    let mut want = Vec::new();
    for c in 0..2 {
        let chan: Vec<i16> = x.iter().skip(c).step_by(2).copied().collect();
        for (f, l) in reference(&chan, thr, n(dc.ddt_s), n(dc.rearm_s), n(dc.max_duration_s)) {
            want.push((c as i64 + 1, f, l));
        }
    }
    want.sort();
    // Every burst is found: a hit on channel 1 covers its first 20 µs.
    let ch1: Vec<&(i64, usize, usize)> = want.iter().filter(|h| h.0 == 1).collect();
    for s in &starts {
        assert!(
            ch1.iter().any(|h| h.1 <= s + 200 && h.2 + 1 >= *s),
            "burst at {s}: {ch1:?}"
        );
    }
    // The pairs 20 and 150 µs apart are one hit each (within ddt), 500 µs apart two; no
    // hit without a burst.
    assert_eq!(ch1.len(), starts.len() - 2, "{ch1:?}");
    for fmt in ["wav", "rf64", "npy", "raw"] {
        let out = d.path().join(format!("out-{fmt}"));
        let cfg = config(if fmt == "rf64" { rf64_gain_db() } else { 0.0 });
        aepipe::pipeline::run(
            aepipe::pipeline::StreamJob::Features,
            &[d.path().join("in").join(fmt)],
            &out,
            &cfg,
            &aepipe::pipeline::StreamOptions::with_threads(2),
        )
        .unwrap();
        assert_eq!(cut_hits(&out), want, "{fmt}");
        let m = aepipe::pipeline::Manifest::read(&out.join("manifest.json")).unwrap();
        assert_eq!(m.streams.len(), 1, "{fmt}");
        let s = &m.streams[0];
        assert_eq!(s.hits_cut as usize, want.len(), "{fmt}");
        assert_eq!(
            s.samples_read,
            if fmt == "npy" {
                x.len() as u64
            } else {
                x.len() as u64 / 2
            }
        );
        let inside: u64 = want.iter().map(|h| (h.2 - h.1 + 1) as u64).sum();
        assert_eq!(s.samples_in_hits, inside, "{fmt}");
        assert!(
            m.counts.unbalanced.is_empty(),
            "{fmt}: {:?}",
            m.counts.unbalanced
        );
        assert_eq!(m.counts.rows_written as usize, want.len(), "{fmt}");
    }
}

/// A stream cut short: the hits before its end are kept, and a reject names the sample.
#[test]
fn a_stream_cut_mid_block_keeps_what_came_before() {
    let d = TempDir::new("detect-short");
    let lib = crate::e2e::small_library_seeded(d.path(), "lib", 43, 1);
    let lib = aepipe::synth::Library::read(&lib, FS).unwrap();
    let (x, _) = stream(&lib);
    write_all(&d.path().join("in"), &x);
    let rf = d.path().join("in").join("rf64").join("s.wav");
    let full = std::fs::metadata(&rf).unwrap().len();
    // Cut at 0.2 s (mid-frame by one byte, so the last whole frame counts).
    let keep_frames = (0.2 * FS) as u64;
    let header = full - 2 * x.len() as u64;
    let f = std::fs::OpenOptions::new().write(true).open(&rf).unwrap();
    f.set_len(header + keep_frames * 4 + 1).unwrap();
    let out = d.path().join("out");
    let cfg = config(rf64_gain_db());
    aepipe::pipeline::run(
        aepipe::pipeline::StreamJob::Features,
        &[d.path().join("in").join("rf64")],
        &out,
        &cfg,
        &aepipe::pipeline::StreamOptions::with_threads(2),
    )
    .unwrap();
    let (names, rows) = crate::table_rows(&out.join("rejects.parquet"));
    let reason = names.iter().position(|n| n == "reason").unwrap();
    assert_eq!(rows.len(), 1);
    assert!(
        rows[0][reason].contains(&format!(
            "ends at sample {keep_frames} of the {}",
            x.len() / 2
        )),
        "{}",
        rows[0][reason]
    );
    let hits = cut_hits(&out);
    assert!(!hits.is_empty() && hits.iter().all(|h| (h.2 as u64) < keep_frames));
    let m = aepipe::pipeline::Manifest::read(&out.join("manifest.json")).unwrap();
    assert_eq!(m.streams[0].samples_read, keep_frames);
    assert_eq!(m.streams[0].samples_promised, x.len() as u64 / 2);
}

/// Records other readers read whole are cut too (`mode = "auto"` above `auto_min_samples`):
/// the stream's channels as rows of `waveforms.parquet`, and channel 1 as one Vallen TR
/// record (the continuous mode), give the stream's own hits, numbered record hit × 10⁶ + k,
/// with the manifest's counts balanced.
#[test]
fn long_records_of_other_formats_are_cut_alike() {
    let d = TempDir::new("detect-long");
    let lib = crate::e2e::small_library_seeded(d.path(), "lib", 44, 1);
    let lib = aepipe::synth::Library::read(&lib, FS).unwrap();
    let (x, _) = stream(&lib);
    write_all(&d.path().join("in"), &x);
    let run = |input: &Path, out: &Path, job, cfg: &aepipe::config::ValidConfig| {
        aepipe::pipeline::run(
            job,
            &[input.to_path_buf()],
            out,
            cfg,
            &aepipe::pipeline::StreamOptions::with_threads(2),
        )
        .unwrap()
    };
    let features = aepipe::pipeline::StreamJob::Features;
    // The stream file itself, cut.
    let want = {
        let out = d.path().join("npy-cut");
        run(
            &d.path().join("in").join("npy"),
            &out,
            features,
            &config(0.0),
        );
        cut_hits(&out)
    };
    // The stream read whole (mode off) into waveforms.parquet, then cut from there.
    let mut off = aepipe::config::PipelineConfig::default();
    off.ingest.sample_rate_hz = FS;
    let off = off.check().unwrap();
    let whole = d.path().join("whole");
    run(
        &d.path().join("in").join("npy"),
        &whole,
        aepipe::pipeline::StreamJob::Waveforms,
        &off,
    );
    let mut auto = config(0.0).into_inner();
    auto.detect.mode = aepipe::detect::DetectMode::Auto;
    let auto = auto.check().unwrap();
    let out = d.path().join("from-parquet");
    run(&whole.join("waveforms.parquet"), &out, features, &auto);
    assert_eq!(cut_hits(&out), want);
    let (names, rows) = crate::table_rows(&out.join("hits.parquet"));
    let hit = names.iter().position(|n| n == "hit").unwrap();
    let ch = names.iter().position(|n| n == "channel").unwrap();
    for r in &rows {
        let h: u64 = r[hit].parse().unwrap();
        assert_eq!(h / 1_000_000, 1, "the record's hit × 10⁶ + k: {h}");
        assert!(r[ch] == "1" || r[ch] == "2");
    }
    let m = aepipe::pipeline::Manifest::read(&out.join("manifest.json")).unwrap();
    assert!(m.counts.unbalanced.is_empty(), "{:?}", m.counts.unbalanced);
    assert_eq!(m.streams.len(), 2);

    // Channel 1 as one Vallen TR record of 3 M samples (1 µV a count), with its hit row.
    let ch1: Vec<f32> = x
        .iter()
        .step_by(2)
        .map(|&c| (c as f64 * 1e-6) as f32)
        .collect();
    let vdir = d.path().join("vallen");
    std::fs::create_dir_all(&vdir).unwrap();
    let hits = [aepipe::ingest::vallen::HitToWrite {
        channel: 1,
        trai: 1,
        time_s: 0.0,
        sample_rate_hz: FS,
        pretrigger: 0,
        samples_v: &ch1,
        restart: false,
        transient: true,
    }];
    aepipe::ingest::vallen::write_pair(&vdir.join("cont"), hits, &[], 1e-3, 1e-4).unwrap();
    let out = d.path().join("from-vallen");
    run(&vdir, &out, features, &auto);
    let (names, rows) = crate::table_rows(&out.join("hits.parquet"));
    let src = names.iter().position(|n| n == "source").unwrap();
    let vendor = rows.iter().filter(|r| r[src] == "vallen").count();
    assert_eq!(vendor, 1, "the system's own hit row stays");
    let got: Vec<(i64, usize, usize)> = {
        let (t, du) = (
            names.iter().position(|n| n == "time_s").unwrap(),
            names.iter().position(|n| n == "duration_s").unwrap(),
        );
        let mut v: Vec<_> = rows
            .iter()
            .filter(|r| r[src] == "detect")
            .map(|r| {
                let f = (r[t].parse::<f64>().unwrap() * FS).round() as usize;
                (
                    1,
                    f,
                    f + (r[du].parse::<f64>().unwrap() * FS).round() as usize,
                )
            })
            .collect();
        v.sort();
        v
    };
    let want1: Vec<_> = want.iter().filter(|h| h.0 == 1).copied().collect();
    assert_eq!(got, want1);
    let m = aepipe::pipeline::Manifest::read(&out.join("manifest.json")).unwrap();
    assert!(m.counts.unbalanced.is_empty(), "{:?}", m.counts.unbalanced);
}

/// Hostile stream headers: every size is checked before it is trusted, each bad file is a
/// reject naming what is wrong, and a good stream beside them is cut whole.
#[test]
fn bad_stream_headers_are_rejects_and_the_good_stream_is_cut() {
    let d = TempDir::new("detect-bad");
    let dir = d.path().join("in");
    std::fs::create_dir_all(&dir).unwrap();
    // A .npy promising 2 × 10¹² samples (16 bytes of data: 8 of channel 1, none of
    // channel 2, the shortest).
    let mut npy = b"\x93NUMPY\x01\x00".to_vec();
    let h = "{'descr': '<i2', 'fortran_order': False, 'shape': (2, 1000000000000), }\n";
    npy.extend((h.len() as u16).to_le_bytes());
    npy.extend(h.as_bytes());
    npy.extend([0u8; 16]);
    std::fs::write(dir.join("huge.npy"), &npy).unwrap();
    // A .npy of float64, and one in Fortran order.
    let mut f64npy = b"\x93NUMPY\x01\x00".to_vec();
    let h = "{'descr': '<f8', 'fortran_order': False, 'shape': (4,), }\n";
    f64npy.extend((h.len() as u16).to_le_bytes());
    f64npy.extend(h.as_bytes());
    f64npy.extend([0u8; 32]);
    std::fs::write(dir.join("f64.npy"), &f64npy).unwrap();
    // A raw stream whose description names an unknown dtype.
    std::fs::write(dir.join("bad.bin"), [0u8; 64]).unwrap();
    std::fs::write(
        dir.join("bad.bin.toml"),
        "dtype = \"int12\"\nsample_rate_hz = 1e6\n",
    )
    .unwrap();
    // The good stream: 1 s of zeros with three spikes, raw int16.
    let mut x = vec![0i16; 1_000_000];
    for k in [100_000usize, 400_000, 900_000] {
        x[k] = 500;
    }
    let bytes: Vec<u8> = x.iter().flat_map(|c| c.to_le_bytes()).collect();
    std::fs::write(dir.join("good.bin"), &bytes).unwrap();
    std::fs::write(
        dir.join("good.bin.toml"),
        "dtype = \"int16\"\nchannels = 1\nsample_rate_hz = 1e6\nvolts_per_unit = 1e-6\n",
    )
    .unwrap();
    let out = d.path().join("out");
    let mut cfg = aepipe::config::PipelineConfig::default();
    cfg.detect.mode = aepipe::detect::DetectMode::On;
    let cfg = cfg.check().unwrap();
    aepipe::pipeline::run(
        aepipe::pipeline::StreamJob::Features,
        &[dir],
        &out,
        &cfg,
        &aepipe::pipeline::StreamOptions::with_threads(1),
    )
    .unwrap();
    let (names, rows) = crate::table_rows(&out.join("rejects.parquet"));
    let (exp, reason) = (
        names.iter().position(|n| n == "experiment").unwrap(),
        names.iter().position(|n| n == "reason").unwrap(),
    );
    let why = |e: &str| {
        rows.iter()
            .find(|r| r[exp] == e)
            .map(|r| r[reason].clone())
            .unwrap_or_else(|| panic!("no reject for {e}: {rows:?}"))
    };
    assert!(
        why("huge").contains("ends at sample 0 of the 1000000000000"),
        "{}",
        why("huge")
    );
    assert!(why("f64").contains("int16 and float32"), "{}", why("f64"));
    assert!(why("bad").contains("int12"), "{}", why("bad"));
    let (names, rows) = crate::table_rows(&out.join("hits.parquet"));
    let t = names.iter().position(|n| n == "time_s").unwrap();
    let times: Vec<f64> = rows.iter().map(|r| r[t].parse().unwrap()).collect();
    assert_eq!(times, [0.1, 0.4, 0.9]);
}
