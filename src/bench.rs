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

/// Read a little-endian f32 or f64 binary file (the peers' `export_inputs.py` output).
fn read_f32(path: &Path) -> Result<Vec<f32>, String> {
    let b = std::fs::read(path).map_err(|e| {
        format!(
            "{}: {e} (run the peers' export_inputs.py first)",
            path.display()
        )
    })?;
    Ok(b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

fn read_f64(path: &Path) -> Result<Vec<f64>, String> {
    let b = std::fs::read(path).map_err(|e| {
        format!(
            "{}: {e} (run the peers' export_inputs.py first)",
            path.display()
        )
    })?;
    Ok(b.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect())
}

/// Median of `repeats` timed runs after one warm-up, seconds.
fn median_time(repeats: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut t: Vec<f64> = (0..repeats.max(1))
        .map(|_| {
            let t0 = std::time::Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Morlet ω0 as a Gabor FWHM in periods: σ_f = f/ω0 ⇔ FWHM = 2√(2 ln 2)·ω0/(2π) periods.
pub fn morlet_w0_to_fwhm_periods(w0: f64) -> f64 {
    2.354_820_045_030_949_4 * w0 / (2.0 * std::f64::consts::PI)
}

/// One line of the CWT benchmark table.
#[derive(Debug, Clone)]
pub struct CwtBenchRow {
    pub what: String,
    pub threads: usize,
    pub seconds: f64,
    pub per_signal_ms: f64,
}

/// W1 and the feature path on the peers' exact inputs (`dir` = output of their
/// `export_inputs.py`): 651 × 4096 samples at 10 MHz, 250 frequencies 10–2500 kHz, Morlet
/// ω0 = 6. The full-resolution CWT fills a preallocated float32 array (n, 250, 4096) of |W|²,
/// as the peers do.
pub fn cwt_bench(
    dir: &Path,
    threads_list: &[usize],
    repeats: usize,
    skip_full: bool,
) -> Result<Vec<CwtBenchRow>, String> {
    use crate::dsp::cwt::{Cwt, WaveletBank};
    use rayon::prelude::*;
    let x = read_f32(&dir.join("w1_signals_f32.bin"))?;
    let freqs = read_f64(&dir.join("w1_freqs_hz_f64.bin"))?;
    let n = 4096;
    let nsig = x.len() / n;
    let fs = 10e6;
    let bank = WaveletBank {
        freqs_hz: freqs.clone(),
        fwhm_periods: morlet_w0_to_fwhm_periods(6.0),
    };
    let nf = freqs.len();
    let mut out = vec![0.0f32; if skip_full { 0 } else { nsig * nf * n }];
    let mut rows = Vec::new();
    for &threads in threads_list.iter().filter(|_| !skip_full) {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| e.to_string())?;
        let states = crate::pipeline::StatePool::default();
        let t = median_time(repeats, || {
            pool.install(|| {
                out.par_chunks_mut(nf * n)
                    .zip(x.par_chunks(n))
                    .for_each_init(
                        || states.checkout(|| Cwt::new(bank.clone())),
                        |cwt, (o, sig)| {
                            cwt.load(sig, fs);
                            cwt.full_power(sig, fs, o);
                        },
                    )
            })
        });
        rows.push(CwtBenchRow {
            what: "W1 full-resolution CWT |W|² → (651, 250, 4096) f32".into(),
            threads,
            seconds: t,
            per_signal_ms: t * 1e3 / nsig as f64,
        });
    }
    drop(out);
    // The whole feature path (thesis defaults) on the same signals.
    let cfg = PipelineConfig::default();
    let recs: Vec<crate::model::AeRecord> = x
        .chunks(n)
        .enumerate()
        .map(|(i, s)| crate::model::AeRecord {
            experiment: "w1".into(),
            channel: 1,
            hit: i as u64 + 1,
            time_s: None,
            sample_rate_hz: fs,
            pretrigger: 500,
            samples: s.to_vec(),
            load_n: None,
            extension_m: None,
            label: None,
            threshold_v: None,
            source_file: String::new(),
        })
        .collect();
    for &threads in threads_list {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| e.to_string())?;
        let states = crate::pipeline::StatePool::default();
        let t = median_time(repeats, || {
            pool.install(|| {
                recs.par_iter().for_each_init(
                    || states.checkout(|| crate::features::FeatureExtractor::new(&cfg)),
                    |ex, r| {
                        std::hint::black_box(ex.row(r).expect("row"));
                    },
                )
            })
        });
        rows.push(CwtBenchRow {
            what: "feature path (spectrum, 25 ratios, 200 bins, hit features, label, row)".into(),
            threads,
            seconds: t,
            per_signal_ms: t * 1e3 / nsig as f64,
        });
    }
    // W2: spectrum + 25 band ratios only.
    let mut cwt = crate::dsp::cwt::Cwt::new(WaveletBank {
        freqs_hz: vec![],
        fwhm_periods: 2.0,
    });
    let mut ratios = vec![0.0; 25];
    let t = median_time(repeats * 4, || {
        for s in x.chunks(n) {
            cwt.load(s, fs);
            std::hint::black_box(crate::dsp::spectrum::power_ratios(
                cwt.spectrum(),
                n,
                fs,
                100e3,
                &mut ratios,
            ));
        }
    });
    rows.push(CwtBenchRow {
        what: "W2 spectrum + 25 band ratios".into(),
        threads: 1,
        seconds: t,
        per_signal_ms: t * 1e3 / nsig as f64,
    });
    Ok(rows)
}

/// Run one peer script in the same run (`python script args… --out tmp.json`) and return the
/// JSON it wrote.
fn peer_json(
    python: &Path,
    peers: &Path,
    script: &str,
    args: &[&str],
) -> Result<serde_json::Value, String> {
    let out = std::env::temp_dir().join(format!(
        "aepipe-peer-{}-{}.json",
        script.trim_end_matches(".py"),
        args.join("_")
    ));
    let st = std::process::Command::new(python)
        .arg(peers.join(script))
        .args(args)
        .arg("--out")
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .status()
        .map_err(|e| format!("{}: {e}", python.display()))?;
    if !st.success() {
        return Err(format!("peer {script} {args:?} failed ({st})"));
    }
    serde_json::from_str(&std::fs::read_to_string(&out).map_err(|e| e.to_string())?)
        .map_err(|e| e.to_string())
}

/// Run one peer script in the same run; returns the median seconds from its JSON.
pub fn run_peer(python: &Path, peers: &Path, script: &str, args: &[&str]) -> Result<f64, String> {
    let v = peer_json(python, peers, script, args)?;
    let med = v["timing"]["median_s"]
        .as_f64()
        .ok_or("no timing.median_s in the peer's JSON")?;
    // W2 reports the time of `inner` passes; per pass is what we compare.
    let inner = v["params"]["inner"].as_f64().unwrap_or(1.0);
    Ok(med / inner)
}

/// W3 on the peers' exact inputs: 651 × 200-D vectors, 10×10 map, the same initial codebook
/// and the two-stage schedule of Table 5.2. Returns (median seconds, QE, TE8).
pub fn som_bench(dir: &Path, repeats: usize) -> Result<(f64, f64, f64), String> {
    use crate::som::{Init, Som, SomParams};
    let data = read_f64(&dir.join("w3_som_data_f64.bin"))?;
    let init = read_f64(&dir.join("w3_som_init_f64.bin"))?;
    let params = SomParams {
        init: Init::Given(init),
        ..SomParams::default()
    }
    .check()
    .map_err(|e| e.to_string())?;
    let mut last = None;
    let t = median_time(repeats, || {
        last = Some(Som::fit_with(&params, &data, 200, false).expect("fit"))
    });
    // Quality is measured outside the timing, as the peers do.
    let som = last.expect("ran");
    Ok((
        t,
        som.quantisation_error(&data),
        som.topographic_error(&data),
    ))
}

/// Run the MiniSom peer; returns (median seconds, QE).
pub fn run_minisom(python: &Path, peers: &Path) -> Result<(f64, f64), String> {
    let v = peer_json(
        python,
        peers,
        "w3_som.py",
        &["--peer", "minisom", "--threads", "1"],
    )?;
    Ok((
        v["timing"]["median_s"]
            .as_f64()
            .ok_or("no timing.median_s in the peer's JSON")?,
        v["quality"]["qe"]
            .as_f64()
            .ok_or("no quality.qe in the peer's JSON")?,
    ))
}
