//! `aepipe bench detect`: the detection stage alone on an int16 stream in memory (MS/s per
//! core, and the real-time factor at 10 MHz), and whole `aepipe features` runs on stream
//! WAV files of growing length, each a child process (wall time, hits/s, real-time factor,
//! peak RSS from `wait4`). With a Python holding NumPy, the same cut done the NumPy way
//! (vectorised crossings grouped by ddt) on the same samples, in the same run.

use super::BenchError;
use crate::detect::{DetectConfig, DetectMode, Detector};
use crate::util::Rng;
use std::path::Path;

/// The streams' rate, Hz.
pub const RATE_HZ: f64 = 10e6;
/// One count is 1 µV (so 40 dB_AE is 100 counts).
const UNIT_V: f64 = 1e-6;

/// The stream generator: int16 noise of σ = 2 counts from a table, with a burst (a
/// decaying 300 kHz sine of 300–3 000 counts, 80 µs) every 10 ms on average.
pub struct StreamMaker {
    noise: Vec<i16>,
    burst: Vec<f32>,
    rng: Rng,
    next_burst: u64,
    pos: u64,
}

impl StreamMaker {
    pub fn new(seed: u64) -> StreamMaker {
        let mut rng = Rng::new(seed);
        let noise = (0..1 << 20)
            .map(|_| (2.0 * rng.normal()).round() as i16)
            .collect();
        let burst = (0..800)
            .map(|j| {
                let t = j as f64 / RATE_HZ;
                ((-t / 20e-6).exp() * (2.0 * std::f64::consts::PI * 300e3 * t).sin()) as f32
            })
            .collect();
        StreamMaker {
            noise,
            burst,
            rng,
            next_burst: 1000,
            pos: 0,
        }
    }

    /// The next `out.len()` samples.
    pub fn fill(&mut self, out: &mut [i16]) {
        let off = (self.rng.next_u64() % (self.noise.len() as u64 / 2)) as usize;
        for (k, o) in out.iter_mut().enumerate() {
            *o = self.noise[(off + k) % self.noise.len()];
        }
        let end = self.pos + out.len() as u64;
        while self.next_burst < end {
            let a = 300.0 + 2700.0 * self.rng.uniform() as f32;
            for (j, b) in self.burst.iter().enumerate() {
                let k = self.next_burst + j as u64;
                if k >= self.pos && k < end {
                    let o = &mut out[(k - self.pos) as usize];
                    *o = o.saturating_add((a * b).round() as i16);
                }
            }
            self.next_burst += (RATE_HZ * 0.02 * self.rng.uniform()) as u64 + 1000;
        }
        self.pos = end;
    }
}

/// The detector alone: `channels` streams of `seconds` each, cut on `threads` threads.
#[derive(Debug, Clone)]
pub struct StageResult {
    pub threads: usize,
    pub samples: u64,
    pub seconds: f64,
    pub hits: usize,
}

impl StageResult {
    /// Million samples per second per core.
    pub fn ms_per_core(&self) -> f64 {
        self.samples as f64 / self.seconds / 1e6 / self.threads as f64
    }
}

/// Cut `threads` channels of `seconds` of stream each (made before the clock starts, in
/// memory), one channel per thread.
pub fn detect_stage(threads: usize, seconds: f64) -> StageResult {
    use rayon::prelude::*;
    let n = (seconds * RATE_HZ) as usize;
    let chans: Vec<Vec<i16>> = (0..threads)
        .map(|c| {
            let mut x = vec![0i16; n];
            StreamMaker::new(c as u64 + 1).fill(&mut x);
            x
        })
        .collect();
    let cfg = DetectConfig {
        mode: DetectMode::On,
        ..Default::default()
    }
    .check()
    .expect("the defaults are valid");
    let p = cfg.at_rate(RATE_HZ);
    let block = cfg.block_samples;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool");
    let t0 = std::time::Instant::now();
    let hits: usize = pool.install(|| {
        chans
            .par_iter()
            .map(|x| {
                let mut d = Detector::<i16>::new(p, UNIT_V, RATE_HZ);
                let mut out = Vec::new();
                let mut hits = 0;
                for b in x.chunks(block) {
                    d.push(b, &mut out);
                    hits += out.len();
                    out.clear();
                }
                d.finish(&mut out);
                hits + out.len()
            })
            .sum()
    });
    StageResult {
        threads,
        samples: (n * threads) as u64,
        seconds: t0.elapsed().as_secs_f64(),
        hits,
    }
}

/// The NumPy peer on the first channel of the stage's stream (`seed` 1, `seconds` long),
/// written as a `.npy` into `dir`: its cut alone, seconds and hits.
pub fn numpy_peer(
    python: &Path,
    script: &Path,
    dir: &Path,
    seconds: f64,
) -> Result<(f64, usize), BenchError> {
    std::fs::create_dir_all(dir).map_err(BenchError::run)?;
    let n = (seconds * RATE_HZ) as usize;
    let mut x = vec![0i16; n];
    StreamMaker::new(1).fill(&mut x);
    let npy = dir.join("stage.npy");
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    let mut h = format!("{{'descr': '<i2', 'fortran_order': False, 'shape': ({n},), }}");
    while (10 + h.len() + 1) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    b.extend((h.len() as u16).to_le_bytes());
    b.extend(h.as_bytes());
    b.extend(x.iter().flat_map(|v| v.to_le_bytes()));
    std::fs::write(&npy, &b).map_err(BenchError::run)?;
    let thr = 10f64.powf(40.0 / 20.0); // 40 dB_AE in counts of 1 µV
    let out = std::process::Command::new(python)
        .arg(script)
        .arg(&npy)
        .arg(thr.to_string())
        .output()
        .map_err(|e| BenchError::Peer(e.to_string()))?;
    let _ = std::fs::remove_file(&npy);
    let text = String::from_utf8_lossy(&out.stdout);
    let mut w = text
        .split_whitespace()
        .skip_while(|t| *t != "numpy")
        .skip(1);
    match (
        w.next().and_then(|s| s.parse().ok()),
        w.next().and_then(|s| s.parse().ok()),
    ) {
        (Some(s), Some(h)) => Ok((s, h)),
        _ => Err(BenchError::Peer(format!(
            "{}: {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        ))),
    }
}

/// Write `seconds` of one-channel int16 stream as a WAV at 10 MHz (±1 V full scale, as a
/// WAV's integers are read).
pub fn write_stream_wav(path: &Path, seconds: f64, seed: u64) -> Result<(), BenchError> {
    use std::io::Write;
    let n = (seconds * RATE_HZ) as u64;
    let bytes = n * 2;
    if bytes > u32::MAX as u64 - 36 {
        return Err(BenchError::Run(format!(
            "{seconds} s does not fit a RIFF WAV"
        )));
    }
    let f = std::fs::File::create(path).map_err(BenchError::run)?;
    let mut w = std::io::BufWriter::with_capacity(1 << 22, f);
    let mut h = Vec::with_capacity(44);
    h.extend(b"RIFF");
    h.extend((36 + bytes as u32).to_le_bytes());
    h.extend(b"WAVEfmt ");
    h.extend(16u32.to_le_bytes());
    h.extend(1u16.to_le_bytes());
    h.extend(1u16.to_le_bytes());
    h.extend((RATE_HZ as u32).to_le_bytes());
    h.extend((RATE_HZ as u32 * 2).to_le_bytes());
    h.extend(2u16.to_le_bytes());
    h.extend(16u16.to_le_bytes());
    h.extend(b"data");
    h.extend((bytes as u32).to_le_bytes());
    w.write_all(&h).map_err(BenchError::run)?;
    let mut m = StreamMaker::new(seed);
    let mut buf = vec![0i16; 1 << 20];
    let mut left = n;
    let mut out = Vec::with_capacity(buf.len() * 2);
    while left > 0 {
        let k = left.min(buf.len() as u64) as usize;
        m.fill(&mut buf[..k]);
        out.clear();
        out.extend(buf[..k].iter().flat_map(|v| v.to_le_bytes()));
        w.write_all(&out).map_err(BenchError::run)?;
        left -= k as u64;
    }
    w.flush().map_err(BenchError::run)
}

/// The pipeline definition the whole runs use: cut on, a count 1 µV (29.7 dB of gain
/// divided out of the ±1 V full scale).
pub const STREAM_PIPELINE: &str =
    "[ingest]\ngain_db = 29.691001300805642\n\n[detect]\nmode = \"on\"\nthreshold_db = 40.0\n";

/// One whole `aepipe features` run on a stream file.
#[derive(Debug, Clone)]
pub struct RunResult {
    pub stream_s: f64,
    pub wall_s: f64,
    pub hits: u64,
    pub peak_rss: u64,
}

/// For each length: write the stream, run `aepipe features` on it as a child process.
pub fn stream_runs(
    exe: &Path,
    dir: &Path,
    seconds: &[f64],
    threads: usize,
) -> Result<Vec<RunResult>, BenchError> {
    std::fs::create_dir_all(dir).map_err(BenchError::run)?;
    let cfg = dir.join("stream.toml");
    std::fs::write(&cfg, STREAM_PIPELINE).map_err(BenchError::run)?;
    let mut out = Vec::new();
    for &s in seconds {
        let input = dir.join(format!("stream-{s}s"));
        std::fs::create_dir_all(&input).map_err(BenchError::run)?;
        let wav = input.join("stream.wav");
        write_stream_wav(&wav, s, 7)?;
        let o = dir.join(format!("out-{s}s"));
        let (wall, rss) = super::cluster::run_measured(
            std::process::Command::new(exe)
                .arg("features")
                .arg("--config")
                .arg(&cfg)
                .arg("--threads")
                .arg(threads.to_string())
                .arg(&input)
                .arg("--out")
                .arg(&o),
        )?;
        let m =
            crate::pipeline::Manifest::read(&o.join("manifest.json")).map_err(BenchError::run)?;
        out.push(RunResult {
            stream_s: s,
            wall_s: wall,
            hits: m.counts.hits_written,
            peak_rss: rss,
        });
        let _ = std::fs::remove_file(&wav);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bench's stream holds what it says: bursts every ~10 ms, found by the detector.
    #[test]
    fn the_bench_stream_has_its_bursts() {
        let r = detect_stage(1, 0.5);
        // 0.5 s at one burst per 1000 + U(0, 200 000) samples: ~49 bursts.
        assert!((30..=70).contains(&r.hits), "{}", r.hits);
        assert_eq!(r.samples, 5_000_000);
    }
}
