//! `aepipe bench stream`: stream synthetic hits through the real feature pipeline and report
//! throughput and peak memory. Benchmarks print numbers; they never pass or fail on time.

use crate::config::PipelineConfig;
use crate::model::{Item, Mechanism};
use crate::pipeline::{stream, Job, RunOptions, StreamStats};
use crate::synth::{waveform, HitSpec, Rng};
use std::path::Path;

/// Peak resident set size of this process so far (VmHWM), bytes; `None` off Linux.
pub fn peak_rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Current resident set size (VmRSS), bytes.
pub fn rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// A lazy source of `n` synthetic hits of `len` samples: a few distinct waveforms are made
/// once and cycled, so the benchmark measures the pipeline, not the signal generator.
pub fn synthetic_items(n: u64, len: usize) -> impl Iterator<Item = Item> + Send {
    let mut rng = Rng::new(42);
    let protos: Vec<Vec<f32>> = [
        Mechanism::BondFailure,
        Mechanism::FibreFailure,
        Mechanism::Both,
        Mechanism::BondFailure,
    ]
    .iter()
    .map(|m| {
        let mut s = HitSpec::new(*m);
        s.n_samples = len;
        s.pretrigger = len.min(500);
        waveform(&s, &mut rng)
    })
    .collect();
    (0..n).map(move |i| {
        Item::Record(crate::model::AeRecord {
            experiment: "bench".into(),
            channel: 1,
            hit: i + 1,
            time_s: Some(i as f64 * 1e-3),
            sample_rate_hz: 10e6,
            pretrigger: len.min(500) as u32,
            samples: protos[(i % protos.len() as u64) as usize].clone(),
            load_n: None,
            extension_m: None,
            label: None,
            threshold_v: None,
            source_file: "synthetic".into(),
        })
    })
}

/// One benchmark point.
#[derive(Debug, Clone)]
pub struct StreamPoint {
    pub hits: u64,
    pub seconds: f64,
    pub hits_per_s: f64,
    pub peak_rss_mb: f64,
    pub stats: StreamStats,
}

/// Stream `hits` synthetic hits of `len` samples into `out_dir` (features job).
pub fn stream_point(
    hits: u64,
    len: usize,
    threads: usize,
    out_dir: &Path,
) -> Result<StreamPoint, crate::pipeline::PipelineError> {
    let cfg = PipelineConfig::default();
    std::fs::create_dir_all(out_dir).map_err(|source| crate::pipeline::PipelineError::Io {
        path: out_dir.display().to_string(),
        source,
    })?;
    let stats = stream(
        synthetic_items(hits, len),
        Job::Features,
        out_dir,
        &cfg,
        &RunOptions {
            threads,
            progress: false,
        },
    )?;
    Ok(StreamPoint {
        hits,
        seconds: stats.seconds,
        hits_per_s: hits as f64 / stats.seconds.max(1e-9),
        peak_rss_mb: peak_rss_bytes().unwrap_or(0) as f64 / 1048576.0,
        stats,
    })
}
