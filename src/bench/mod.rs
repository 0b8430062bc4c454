//! `aepipe bench stream`: stream synthetic hits through the real feature pipeline and report
//! throughput and peak memory. Benchmarks print numbers; they never pass or fail on time.

use crate::model::{Item, Mechanism};
use crate::pipeline::{stream, StreamJob, StreamOptions, StreamStats};
use crate::synth::{waveform, HitSpec, Rng};
use std::path::Path;

/// Why a benchmark could not run (benchmarks print numbers; they never pass or fail on time).
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// An input the peers' `export_inputs.py` writes is missing or unreadable.
    #[error("{path}: {message} (run the peers' export_inputs.py first)")]
    Input { path: String, message: String },
    #[error("peer: {0}")]
    Peer(String),
    #[error("{0}")]
    Run(String),
}

impl crate::util::HasKind for BenchError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            BenchError::Input { .. } => crate::util::ErrorKind::Usage,
            BenchError::Peer(_) | BenchError::Run(_) => crate::util::ErrorKind::Failed,
        }
    }
}

impl BenchError {
    fn run(e: impl std::fmt::Display) -> BenchError {
        BenchError::Run(e.to_string())
    }
}

pub mod analysis;
pub mod cluster;
pub mod detect;
pub mod report;
pub mod space;
pub use space::{field3d, network3d, Field3dRow, Network3dRow};

pub use crate::util::{peak_rss_bytes, rss_bytes};

/// What the streaming benchmark feeds the pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Workload {
    /// Every record `len` samples at 10 MHz, with 500 pretrigger samples or none.
    Fixed { len: usize, pretrigger: bool },
    /// Record lengths like a Vallen LinWave/AMSY-6 test (records last until the hit ends):
    /// 2 250 to 220 000 samples at 5 MHz, mostly short — 80 % log-uniform in 2 250–8 000,
    /// 15 % in 8 000–50 000, 5 % in 50 000–220 000 — with 400 pretrigger samples.
    LinWave,
}

impl Workload {
    pub fn describe(&self) -> String {
        match self {
            Workload::Fixed { len, pretrigger } => format!(
                "{len}-sample records at 10 MHz, {}",
                if *pretrigger {
                    "500 pretrigger samples"
                } else {
                    "no pretrigger"
                }
            ),
            Workload::LinWave => "LinWave-like records: 2 250–220 000 samples at 5 MHz (80 % under 8 000), 400 pretrigger samples".into(),
        }
    }
}

/// A lazy source of `n` synthetic hits: a few distinct waveforms per length class are made
/// once and reused (cut to each record's length), so the benchmark measures the pipeline,
/// not the signal generator.
pub fn synthetic_items(n: u64, w: Workload) -> impl Iterator<Item = Item> + Send {
    let mut rng = Rng::new(42);
    let (fs, pre, max_len) = match w {
        Workload::Fixed { len, pretrigger } => {
            (10e6, if pretrigger { len.min(500) } else { 0 }, len)
        }
        Workload::LinWave => (5e6, 400, 220_000),
    };
    let protos: Vec<Vec<f32>> = [
        Mechanism::BondFailure,
        Mechanism::FibreFailure,
        Mechanism::Both,
        Mechanism::BondFailure,
    ]
    .iter()
    .map(|m| {
        let mut s = HitSpec::new(*m);
        s.sample_rate_hz = fs;
        s.n_samples = max_len;
        s.pretrigger = pre.max(1).min(max_len);
        waveform(&s, &mut rng)
    })
    .collect();
    let mut lrng = Rng::new(7);
    (0..n).map(move |i| {
        let len = match w {
            Workload::Fixed { len, .. } => len,
            Workload::LinWave => {
                let u = lrng.uniform();
                let (lo, hi) = if u < 0.80 {
                    (2_250.0f64, 8_000.0f64)
                } else if u < 0.95 {
                    (8_000.0, 50_000.0)
                } else {
                    (50_000.0, 220_000.0)
                };
                (lo.ln() + (hi.ln() - lo.ln()) * lrng.uniform())
                    .exp()
                    .round() as usize
            }
        };
        let proto = &protos[(i % protos.len() as u64) as usize];
        Item::Record(crate::model::AeRecord {
            kind: crate::model::RecordKind::Hit,
            experiment: "bench".into(),
            channel: 1,
            hit: i + 1,
            time_s: Some(i as f64 * 1e-3),
            sample_rate_hz: fs,
            pretrigger: pre as u32,
            samples: proto[..len.min(proto.len())].to_vec(),
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
    workload: Workload,
    threads: usize,
    out_dir: &Path,
) -> Result<StreamPoint, crate::pipeline::PipelineError> {
    let cfg = crate::config::ValidConfig::default();
    std::fs::create_dir_all(out_dir).map_err(|e| crate::util::IoAt::new(out_dir, e))?;
    let stats = stream(
        synthetic_items(hits, workload),
        StreamJob::Features,
        out_dir,
        &cfg,
        &StreamOptions::with_threads(threads),
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
fn read_f32(path: &Path) -> Result<Vec<f32>, BenchError> {
    let b = std::fs::read(path).map_err(|e| BenchError::Input {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    Ok(b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

fn read_f64(path: &Path) -> Result<Vec<f64>, BenchError> {
    let b = std::fs::read(path).map_err(|e| BenchError::Input {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    Ok(b.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect())
}

/// Median of `repeats` timed runs after one warm-up, seconds.
fn median_time(repeats: usize, f: impl FnMut()) -> f64 {
    timed_runs(repeats, f).median
}

/// Wall times of `repeats` runs after a warm-up run.
#[derive(Debug, Clone, Copy)]
pub struct Runs {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

fn timed_runs(repeats: usize, mut f: impl FnMut()) -> Runs {
    f();
    let mut t: Vec<f64> = (0..repeats.max(1))
        .map(|_| {
            let t0 = std::time::Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    Runs {
        median: t[t.len() / 2],
        min: t[0],
        max: t[t.len() - 1],
    }
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
    /// Fastest and slowest of the timed runs.
    pub spread: (f64, f64),
}

impl CwtBenchRow {
    fn of(what: &str, threads: usize, runs: Runs, nsig: usize) -> CwtBenchRow {
        CwtBenchRow {
            what: what.into(),
            threads,
            seconds: runs.median,
            per_signal_ms: runs.median * 1e3 / nsig as f64,
            spread: (runs.min, runs.max),
        }
    }
}

/// The row of W1 computed with one full-length inverse FFT per frequency (the peers' ratios are
/// also printed against it).
pub const W1_EXACT_ROW: &str = "W1 same, exact: one 4096-point inverse FFT per frequency";

/// `aepipe bench cwt`: our rows, and how far the fast full-resolution CWT is from one
/// full-length inverse FFT per frequency on the same signals.
#[derive(Debug, Clone)]
pub struct CwtBench {
    pub rows: Vec<CwtBenchRow>,
    /// Largest |fast − exact| over the signals compared, relative to the peak of its
    /// frequency's row, and relative to the peak of its signal's scalogram.
    pub fast_error: Option<FastErrorSummary>,
}

#[derive(Debug, Clone, Copy)]
pub struct FastErrorSummary {
    pub signals: usize,
    pub of_row_peak: f64,
    pub of_scalogram_peak: f64,
}

/// A pool of `threads` workers for one benchmark row.
fn bench_pool(threads: usize) -> Result<rayon::ThreadPool, BenchError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(BenchError::run)
}

/// The fast path's error against the exact one on the first `count` signals.
fn fast_error(
    x: &[f32],
    n: usize,
    fs: f64,
    bank: &crate::dsp::cwt::WaveletBank,
    count: usize,
) -> FastErrorSummary {
    let mut cwt = crate::dsp::cwt::Cwt::new(bank.clone());
    let mut e = FastErrorSummary {
        signals: 0,
        of_row_peak: 0.0,
        of_scalogram_peak: 0.0,
    };
    for sig in x.chunks_exact(n).take(count) {
        cwt.load(sig, fs);
        let f = cwt.fast_path_error(sig, fs);
        for r in f.rows.iter().filter(|r| r.peak > 0.0) {
            e.of_row_peak = e.of_row_peak.max(r.err / r.peak);
            e.of_scalogram_peak = e.of_scalogram_peak.max(r.err / f.peak);
        }
        e.signals += 1;
    }
    e
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
) -> Result<CwtBench, BenchError> {
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
    let full_rows = [
        (true, "W1 full-resolution CWT |W|² → (651, 250, 4096) f32"),
        (false, W1_EXACT_ROW),
    ];
    for (fast, what) in full_rows.into_iter().filter(|_| !skip_full) {
        for &threads in threads_list {
            let pool = bench_pool(threads)?;
            let states = crate::pipeline::StatePool::default();
            let runs = timed_runs(repeats, || {
                pool.install(|| {
                    out.par_chunks_mut(nf * n)
                        .zip(x.par_chunks(n))
                        .for_each_init(
                            || states.checkout(|| Cwt::new(bank.clone())),
                            |cwt, (o, sig)| {
                                cwt.load(sig, fs);
                                if fast {
                                    cwt.full_power(sig, fs, o);
                                } else {
                                    cwt.full_power_exact(sig, fs, o);
                                }
                            },
                        )
                })
            });
            rows.push(CwtBenchRow::of(what, threads, runs, nsig));
        }
    }
    drop(out);
    // The whole feature path (thesis defaults) on the same signals.
    let cfg = crate::config::ValidConfig::default();
    let recs: Vec<crate::model::AeRecord> = x
        .chunks(n)
        .enumerate()
        .map(|(i, s)| crate::model::AeRecord {
            kind: crate::model::RecordKind::Hit,
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
        let pool = bench_pool(threads)?;
        let states = crate::pipeline::StatePool::default();
        let runs = timed_runs(repeats, || {
            pool.install(|| {
                recs.par_iter().for_each_init(
                    || states.checkout(|| crate::features::FeatureExtractor::new(&cfg)),
                    |ex, r| {
                        std::hint::black_box(ex.row(r));
                    },
                )
            })
        });
        rows.push(CwtBenchRow::of(
            "feature path (spectrum, 25 ratios, 200 bins, hit features, pickers, label, row)",
            threads,
            runs,
            nsig,
        ));
    }
    // W2: spectrum + 25 band ratios only.
    let mut cwt = crate::dsp::cwt::Cwt::new(WaveletBank {
        freqs_hz: vec![],
        fwhm_periods: 2.0,
    });
    let mut ratios = vec![0.0; 25];
    let runs = timed_runs(repeats * 4, || {
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
    rows.push(CwtBenchRow::of(
        "W2 spectrum + 25 band ratios",
        1,
        runs,
        nsig,
    ));
    let fast_error = (!skip_full).then(|| fast_error(&x, n, fs, &bank, 32));
    Ok(CwtBench { rows, fast_error })
}

/// Run one peer script in the same run (`python script args… --out tmp.json`) and return the
/// JSON it wrote.
fn peer_json(
    python: &Path,
    peers: &Path,
    script: &str,
    args: &[&str],
) -> Result<serde_json::Value, BenchError> {
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
        .map_err(|e| BenchError::Peer(format!("{}: {e}", python.display())))?;
    if !st.success() {
        return Err(BenchError::Peer(format!("{script} {args:?} failed ({st})")));
    }
    serde_json::from_str(&std::fs::read_to_string(&out).map_err(BenchError::run)?)
        .map_err(BenchError::run)
}

/// One peer job of `aepipe bench cwt --peers`: which script, its arguments, and which of
/// our rows (workload prefix, threads) it is compared with.
pub struct PeerJob {
    pub name: &'static str,
    pub script: &'static str,
    pub args: &'static [&'static str],
    pub workload: &'static str,
    pub threads: usize,
}

/// The CWT/spectrum peers, run in the same invocation as our rows.
pub const CWT_PEERS: &[PeerJob] = &[
    PeerJob {
        name: "fCWT 0.1.18 f32, 1 thread",
        script: "w1_cwt.py",
        args: &["--peer", "fcwt", "--threads", "1"],
        workload: "W1",
        threads: 1,
    },
    PeerJob {
        name: "fCWT 0.1.18 f32 + wisdom, 2 threads",
        script: "w1_cwt.py",
        args: &["--peer", "fcwt_opt", "--threads", "2"],
        workload: "W1",
        threads: 2,
    },
    PeerJob {
        name: "numpy.fft baseline c128, 1 thread",
        script: "w1_cwt.py",
        args: &["--peer", "numpy", "--threads", "1"],
        workload: "W1",
        threads: 1,
    },
    PeerJob {
        name: "scipy.fft c64, 1 thread",
        script: "w1_cwt.py",
        args: &["--peer", "scipy_f32", "--threads", "1"],
        workload: "W1",
        threads: 1,
    },
    PeerJob {
        name: "W2 numpy rfft batched",
        script: "w2_spectrum.py",
        args: &["--peer", "numpy_rfft"],
        workload: "W2",
        threads: 1,
    },
];

/// Run one peer script in the same run; returns its median, fastest and slowest timed run
/// from its JSON.
pub fn run_peer(
    python: &Path,
    peers: &Path,
    script: &str,
    args: &[&str],
) -> Result<Runs, BenchError> {
    let v = peer_json(python, peers, script, args)?;
    // W2 reports the time of `inner` passes; per pass is what we compare.
    let inner = v["params"]["inner"].as_f64().unwrap_or(1.0);
    let get = |key: &str| {
        v["timing"][key]
            .as_f64()
            .map(|t| t / inner)
            .ok_or_else(|| BenchError::Peer(format!("no timing.{key} in the peer's JSON")))
    };
    let median = get("median_s")?;
    Ok(Runs {
        median,
        min: get("min_s").unwrap_or(median),
        max: get("max_s").unwrap_or(median),
    })
}

/// W3 on the peers' exact inputs: 651 × 200-D vectors, 10×10 map, the same initial codebook
/// and the two-stage schedule of Table 5.2. Returns (median seconds, QE, TE8).
pub fn som_bench(dir: &Path, repeats: usize) -> Result<(f64, f64, f64), BenchError> {
    use crate::som::{Init, Som, SomParams};
    let data = read_f64(&dir.join("w3_som_data_f64.bin"))?;
    let init = read_f64(&dir.join("w3_som_init_f64.bin"))?;
    let params = SomParams {
        init: Init::Given(init),
        ..SomParams::default()
    }
    .check()
    .map_err(BenchError::run)?;
    let mut last = None;
    let t = median_time(repeats, || {
        last = Some(
            Som::fit_with(
                &params,
                ndarray::ArrayView2::from_shape((data.len() / 200, 200), &data).expect("n × 200"),
                false,
            )
            .expect("fit"),
        )
    });
    // Quality is measured outside the timing, as the peers do.
    let som = last.expect("ran");
    Ok((
        t,
        som.quantisation_error(
            ndarray::ArrayView2::from_shape((data.len() / 200, 200), &data).expect("n × 200"),
        ),
        som.topographic_error(
            ndarray::ArrayView2::from_shape((data.len() / 200, 200), &data).expect("n × 200"),
        ),
    ))
}

/// Run the MiniSom peer; returns (median seconds, QE).
pub fn run_minisom(python: &Path, peers: &Path) -> Result<(f64, f64), BenchError> {
    let v = peer_json(
        python,
        peers,
        "w3_som.py",
        &["--peer", "minisom", "--threads", "1"],
    )?;
    Ok((
        v["timing"]["median_s"]
            .as_f64()
            .ok_or_else(|| BenchError::Peer("no timing.median_s in the peer's JSON".into()))?,
        v["quality"]["qe"]
            .as_f64()
            .ok_or_else(|| BenchError::Peer("no quality.qe in the peer's JSON".into()))?,
    ))
}

/// A random fibre network: straight 1 mm fibres of 20 masses at random positions and angles
/// in a square sized for about 3 crossings per fibre; each node is bonded by a spring, as stiff
/// as one fibre segment, to its nearest node of another fibre within one node spacing. Fibre
/// ends and nodes within 2 % of the square's edge are fixed. Paper-fibre material (Table 4.1).
pub fn random_network(masses: usize, seed: u64) -> crate::sim::model::ModelFile {
    use crate::sim::model::*;
    use crate::sim::scenario::{FIBRE_E, FIBRE_NU, FIBRE_RHO, FIBRE_T, FIBRE_W};
    let per = 20usize;
    let fibres = (masses / per).max(1);
    let len = 1e-3;
    let a = len / (per - 1) as f64;
    let side = len * (fibres as f64 / 4.0).sqrt().max(1.0);
    let mut rng = crate::util::Rng::new(seed);
    let m = FIBRE_RHO * FIBRE_T * FIBRE_W * a;
    let mut nodes = Vec::with_capacity(fibres * per);
    let mut springs = Vec::new();
    let mut owner = Vec::new();
    for f in 0..fibres {
        let (cx, cy) = (rng.range(0.0, side), rng.range(0.0, side));
        let th = rng.range(0.0, std::f64::consts::PI);
        let (dx, dy) = (th.cos(), th.sin());
        let base = nodes.len();
        for k in 0..per {
            let s = (k as f64 / (per - 1) as f64 - 0.5) * len;
            let (x, y) = (cx + s * dx, cy + s * dy);
            let edge = x < 0.02 * side || y < 0.02 * side || x > 0.98 * side || y > 0.98 * side;
            nodes.push(NodeSpec {
                x,
                y,
                z: None,
                mass: m,
                fixed: edge || k == 0 || k == per - 1,
            });
            owner.push(f);
            if k > 0 {
                springs.push(SpringSpec {
                    a: base + k - 1,
                    b: base + k,
                    e: FIBRE_E,
                    length: None,
                    t: FIBRE_T,
                    w: FIBRE_W,
                    poisson: FIBRE_NU,
                    fibre: f as u32,
                });
            }
        }
    }
    // Bonds through a cell list of width a.
    let cells = (side / a).ceil() as usize + 3;
    let key = |x: f64, y: f64| {
        (
            ((x / a).floor() as i64 + 1).clamp(0, cells as i64 - 1) as usize,
            ((y / a).floor() as i64 + 1).clamp(0, cells as i64 - 1) as usize,
        )
    };
    let mut grid: std::collections::HashMap<(usize, usize), Vec<usize>> = Default::default();
    for (i, nd) in nodes.iter().enumerate() {
        grid.entry(key(nd.x, nd.y)).or_default().push(i);
    }
    for i in 0..nodes.len() {
        let (ci, cj) = key(nodes[i].x, nodes[i].y);
        let mut best: Option<(f64, usize)> = None;
        for di in ci.saturating_sub(1)..=ci + 1 {
            for dj in cj.saturating_sub(1)..=cj + 1 {
                for &j in grid.get(&(di, dj)).map(|v| v.as_slice()).unwrap_or(&[]) {
                    if j <= i || owner[j] == owner[i] {
                        continue;
                    }
                    let d = ((nodes[j].x - nodes[i].x).powi(2) + (nodes[j].y - nodes[i].y).powi(2))
                        .sqrt();
                    if d < a && d > 1e-3 * a && best.is_none_or(|b| d < b.0) {
                        best = Some((d, j));
                    }
                }
            }
        }
        if let Some((d, j)) = best {
            // A bond as stiff as one fibre segment whatever the gap (E scaled by d/a in
            // k = E·t·w/L): near-coincident nodes would otherwise give springs thousands of
            // times stiffer than the fibres, and an ill-conditioned system.
            springs.push(SpringSpec {
                a: i,
                b: j,
                e: FIBRE_E * d / a,
                length: None,
                t: FIBRE_T,
                w: FIBRE_W,
                poisson: FIBRE_NU,
                fibre: u32::MAX,
            });
        }
    }
    ModelFile {
        name: format!("random-network-{masses}"),
        label: None,
        system: System {
            dt: 1e-8,
            damping: 1.5e-6,
            iterations: 0,
            solver: Solver::ImplicitEuler,
            relax: false,
        },
        nodes,
        springs,
        initial: vec![],
        forces: vec![],
        damage: vec![],
        grid: None,
        sensors: vec![],
    }
}

/// One row of the simulator scale benchmark.
#[derive(Debug, Clone)]
pub struct SimScale {
    pub masses: usize,
    pub springs: usize,
    pub seconds_per_step: f64,
    pub solver_iterations_per_step: f64,
}

/// Implicit-Euler steps of random fibre networks (ch. 6.2: the thesis's solver crawled above
/// 1 000 elements). Each network is stretched 1 % (every node moved away from the centre)
/// and given random velocities, then stepped `steps` times at Δt = 10 ns.
pub fn sim_scale(sizes: &[usize], steps: usize) -> Result<Vec<SimScale>, BenchError> {
    use crate::sim::mech::Mech;
    let mut rows = Vec::new();
    for &n in sizes {
        let model = random_network(n, 7);
        model.check().map_err(BenchError::run)?;
        let mut mech = Mech::<2>::new(&model);
        let side = model
            .nodes
            .iter()
            .fold(0.0f64, |s, nd| s.max(nd.x).max(nd.y));
        let mut rng = crate::util::Rng::new(11);
        for i in 0..mech.len() {
            mech.r[i] = [
                mech.r[i][0] + 0.01 * (mech.r[i][0] - side / 2.0),
                mech.r[i][1] + 0.01 * (mech.r[i][1] - side / 2.0),
            ];
            if !mech.held[i] {
                mech.u[i] = [rng.range(-0.1, 0.1), rng.range(-0.1, 0.1)];
            }
        }
        mech.freeze_areas();
        // One step to build the pattern, then the timed ones.
        mech.step(crate::sim::model::Solver::ImplicitEuler, 1e-8, 0.0)
            .map_err(BenchError::run)?;
        let it0 = mech.solver_iterations();
        let t0 = std::time::Instant::now();
        for k in 0..steps {
            mech.step(
                crate::sim::model::Solver::ImplicitEuler,
                1e-8,
                k as f64 * 1e-8,
            )
            .map_err(BenchError::run)?;
        }
        let secs = t0.elapsed().as_secs_f64() / steps as f64;
        rows.push(SimScale {
            masses: mech.len(),
            springs: model.springs.len(),
            seconds_per_step: secs,
            solver_iterations_per_step: (mech.solver_iterations() - it0) as f64 / steps as f64,
        });
    }
    Ok(rows)
}

/// One row of Tables 3.2/3.4: a scenario run by one solver.
#[derive(Debug, Clone)]
pub struct SolverRow {
    pub scenario: &'static str,
    pub solver: crate::sim::model::Solver,
    pub dt: f64,
    pub iterations: usize,
    /// Median wall time of the whole run, s.
    pub seconds: f64,
}

/// Tables 3.2 and 3.4 as the thesis ran them: the SHO of Table 3.1 and the five-mass fibre
/// of Table 3.3 (no acoustics), each by the three explicit solvers at Δt = 0.01 s for 10 000
/// steps and by implicit Euler at 0.5 s for 200; median of `repeats` runs.
pub fn solver_table(repeats: usize) -> Result<Vec<SolverRow>, BenchError> {
    use crate::sim::model::Solver;
    let mut out = Vec::new();
    for scenario in ["sho", "five-mass-fibre"] {
        for (solver, dt, iterations) in [
            (Solver::ExplicitEuler, 0.01, 10_000),
            (Solver::Rk4, 0.01, 10_000),
            (Solver::Verlet, 0.01, 10_000),
            (Solver::ImplicitEuler, 0.5, 200),
        ] {
            let p = crate::sim::scenario::Params(vec![
                ("grid".into(), 0.0),
                ("dt".into(), dt),
                ("iterations".into(), iterations as f64),
            ]);
            let mut m = crate::sim::scenario::build(scenario, &p).map_err(BenchError::run)?;
            m.system.solver = solver;
            let mut err = None;
            let seconds = median_time(repeats, || {
                if let Err(e) = crate::sim::simulate(&m, &Default::default()) {
                    err = Some(e);
                }
            });
            if let Some(e) = err {
                return Err(BenchError::run(e));
            }
            out.push(SolverRow {
                scenario,
                solver,
                dt,
                iterations,
                seconds,
            });
        }
    }
    Ok(out)
}

/// `mesh3x3-bond-failure` end to end (relaxation, 4 000 implicit steps, 400 steps of the
/// 250 × 250 4th-order grid): median seconds of `repeats` runs.
pub fn sim_mesh(repeats: usize) -> Result<f64, BenchError> {
    let model = crate::sim::scenario::build("mesh3x3-bond-failure", &Default::default())
        .map_err(BenchError::run)?;
    let mut err = None;
    let t = median_time(repeats, || {
        if let Err(e) = crate::sim::simulate(&model, &Default::default()) {
            err = Some(e);
        }
    });
    match err {
        Some(e) => Err(BenchError::run(e)),
        None => Ok(t),
    }
}
