//! `aepipe bench watch`: an acquisition written at a steady rate and then in a burst while
//! `aepipe watch` follows it in the same process; the lag of every hit from its file's last
//! write to the moment its row is committed (the part's write time), median and p99, for
//! the steady phase and the burst apart.

use super::{WatchError, WatchOptions};
use crate::config::ValidConfig;
use crate::model::columns as cols;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant, SystemTime};

/// What was asked of the benchmark.
#[derive(Debug, Clone)]
pub struct WatchBench {
    /// Hits per second in the steady phase.
    pub rate: f64,
    /// Seconds of the steady phase.
    pub seconds: f64,
    /// Hits arriving at once after it (the final break): made beforehand and moved into
    /// the folder, each stamped with its arrival.
    pub burst: usize,
    pub threads: usize,
    /// The acquisition is a Vallen pair the writer appends to (two channels hearing each
    /// source, transients, a load channel), not a folder of WAV files.
    pub vallen: bool,
}

/// Lags of one phase, seconds.
#[derive(Debug, Clone, Default)]
pub struct Lags {
    pub hits: usize,
    pub median_s: f64,
    pub p99_s: f64,
    pub max_s: f64,
}

/// The benchmark's result.
#[derive(Debug, Clone)]
pub struct WatchBenchResult {
    pub steady: Lags,
    pub burst: Lags,
    /// Seconds the burst took to arrive.
    pub burst_write_s: f64,
    /// Hits per second the writer reached in the steady phase.
    pub steady_rate: f64,
    pub committed: u64,
    pub flushes: u32,
    /// Seconds from the burst's last write to its last row committed.
    pub burst_drain_s: f64,
}

impl WatchBenchResult {
    fn of(
        summary: &super::WatchSummary,
        steady_rate: f64,
        burst_write_s: f64,
        (steady, burst, burst_drain_s): (Lags, Lags, f64),
    ) -> WatchBenchResult {
        WatchBenchResult {
            steady,
            burst,
            burst_write_s,
            steady_rate,
            committed: summary.state.hits,
            flushes: summary.state.flushes,
            burst_drain_s,
        }
    }
}

fn lags(mut v: Vec<f64>) -> Lags {
    if v.is_empty() {
        return Lags::default();
    }
    v.sort_by(f64::total_cmp);
    let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    Lags {
        hits: v.len(),
        median_s: q(0.5),
        p99_s: q(0.99),
        max_s: *v.last().unwrap(),
    }
}

/// Run the benchmark in `out` (removed first).
pub fn watch_bench(
    b: &WatchBench,
    out: &Path,
    mut say: impl FnMut(&str),
) -> Result<WatchBenchResult, WatchError> {
    if b.vallen {
        return vallen_bench(b, out, say);
    }
    let _ = std::fs::remove_dir_all(out);
    let data = out.join("acquisition").join("test-1");
    std::fs::create_dir_all(&data).map_err(|e| crate::util::IoAt::new(&data, e))?;
    let staging = out.join("staging");
    std::fs::create_dir_all(&staging).map_err(|e| crate::util::IoAt::new(&staging, e))?;
    let watch_dir = out.join("watch");
    let cfg = ValidConfig::default()
        .with(|c| {
            c.ingest.pretrigger_samples = 500;
            c.report.enabled = false;
        })
        .map_err(crate::workflow::WorkflowError::Config)?;
    // 256 distinct synthetic hits (4 096 samples), cycled: the writer must not be the
    // bottleneck.
    let e = crate::synth::Experiment::new("test-1", 256, 11);
    let protos: Vec<(u32, Vec<f32>)> = e
        .records()
        .map(|r| (r.sample_rate_hz as u32, r.samples))
        .collect();
    let steady_n = (b.rate * b.seconds).round() as usize;
    let write_to = |dir: &Path, i: usize| -> Result<(), WatchError> {
        let (fs, x) = &protos[i % protos.len()];
        let f = dir.join(format!("hit_{:06}.wav", i + 1));
        crate::ingest::wavfmt::write_wav_f32(&f, *fs, x)
            .map_err(|e| crate::util::IoAt::new(&f, std::io::Error::other(e.to_string())))?;
        Ok(())
    };
    // The burst's files are made beforehand beside the folder, before the watcher starts
    // (its idle clock must not run out while they are written), and moved in at once, each
    // stamped with the moment it arrives: 20 000 hits in about a second is more than a
    // disk takes written from scratch while the watcher works on the other core.
    for i in steady_n..steady_n + b.burst {
        write_to(&staging, i)?;
    }
    let (summary, steady_rate, burst_write_s) =
        watch_while_writing(&cfg, &data, &watch_dir, b.threads, &mut say, || {
            let write = |i: usize| write_to(&data, i);
            let t0 = Instant::now();
            for i in 0..steady_n {
                let due = Duration::from_secs_f64(i as f64 / b.rate);
                if let Some(w) = due.checked_sub(t0.elapsed()) {
                    std::thread::sleep(w);
                }
                write(i)?;
            }
            let steady_rate = steady_n as f64 / t0.elapsed().as_secs_f64().max(1e-9);
            let t1 = Instant::now();
            for i in steady_n..steady_n + b.burst {
                let name = format!("hit_{:06}.wav", i + 1);
                let to = data.join(&name);
                std::fs::rename(staging.join(&name), &to)
                    .and_then(|_| std::fs::File::options().write(true).open(&to))
                    .and_then(|f| f.set_modified(SystemTime::now()))
                    .map_err(|e| crate::util::IoAt::new(&to, e))?;
            }
            Ok((steady_rate, t1.elapsed().as_secs_f64()))
        })?;
    // Each hit's lag: its part's write time − its file's last write.
    let lags = collect_lags(&watch_dir.join("features"), steady_n, |_, file| {
        std::fs::metadata(file)
            .and_then(|m| m.modified())
            .map_err(|e| crate::util::IoAt::new(Path::new(file), e).into())
    })?;
    Ok(WatchBenchResult::of(
        &summary,
        steady_rate,
        burst_write_s,
        lags,
    ))
}

/// The benchmark on a Vallen pair: the writer appends hit rows, their transients and a
/// parametric row every 10 hits in one transaction per 10 ms (rollback journal, as AMSY-6),
/// a source every two hits (channel 1, then channel 2 30 µs later), then the burst in
/// transactions of 1 000 hits as fast as SQLite takes them; the lag of a hit is its part's
/// write time − the commit of the transaction that wrote its transient.
fn vallen_bench(
    b: &WatchBench,
    out: &Path,
    mut say: impl FnMut(&str),
) -> Result<WatchBenchResult, WatchError> {
    use crate::ingest::vallen::{HitToWrite, Journal, PairWriter};
    let _ = std::fs::remove_dir_all(out);
    let data = out.join("acquisition");
    std::fs::create_dir_all(&data).map_err(|e| crate::util::IoAt::new(&data, e))?;
    let watch_dir = out.join("watch");
    let cfg = ValidConfig::default()
        .with(|c| {
            c.report.enabled = false;
            c.ingest.vallen.load_param = Some(crate::config::ParamInput(0));
            c.ingest.vallen.load_n_per_mv = 1.0;
        })
        .map_err(crate::workflow::WorkflowError::Config)?;
    let e = crate::synth::Experiment::new("test-1", 256, 11);
    let protos: Vec<crate::model::AeRecord> = e.records().collect();
    let steady_n = (b.rate * b.seconds).round() as usize;
    let total = steady_n + b.burst;
    let sql = |e: rusqlite::Error| {
        WatchError::Io(crate::util::IoAt::new(
            &data,
            std::io::Error::other(e.to_string()),
        ))
    };
    // Acquisition time: sources 2/rate apart in the steady phase, 500 µs apart in the burst.
    let time_of = |i: usize| -> f64 {
        let source = if i < steady_n {
            (i / 2) as f64 * 2.0 / b.rate
        } else {
            (steady_n / 2) as f64 * 2.0 / b.rate + ((i - steady_n) / 2) as f64 * 500e-6
        };
        0.01 + source + (i % 2) as f64 * 30e-6
    };
    // The load (N, written as mV at 1 N/mV): rising to 300 N at the end of the steady
    // phase, then falling to 120 N over the burst (the strip breaking).
    let t_peak = time_of(steady_n);
    let t_end = time_of(total);
    let load_at = |t: f64| -> f64 {
        if t <= t_peak {
            300.0 * t / t_peak
        } else {
            300.0 - 180.0 * (t - t_peak) / (t_end - t_peak).max(1e-9)
        }
    };
    let hit = |i: usize| {
        let r = &protos[i % protos.len()];
        HitToWrite {
            channel: 1 + (i % 2) as u32,
            trai: i as u64 + 1,
            time_s: time_of(i),
            sample_rate_hz: r.sample_rate_hz,
            pretrigger: r.pretrigger,
            samples_v: &r.samples,
            restart: false,
            transient: true,
        }
    };
    let write = |w: &PairWriter, from: usize, to: usize| -> rusqlite::Result<()> {
        w.batch(|w| {
            for i in from..to {
                let h = hit(i);
                if i % 10 == 0 {
                    w.parametric(h.time_s - 1e-5, load_at(h.time_s - 1e-5), 0.0)?;
                }
                w.hit(&h)?;
                w.transient(&h)?;
            }
            Ok(())
        })
    };
    let mut written: Vec<SystemTime> = vec![SystemTime::UNIX_EPOCH; total];
    let times = &mut written;
    let (summary, steady_rate, burst_write_s) =
        watch_while_writing(&cfg, &data, &watch_dir, b.threads, &mut say, || {
            let written = times;
            let w = PairWriter::create(&data.join("test-1"), 1e-3, 1e-4, Journal::Delete)
                .map_err(sql)?;
            let t0 = Instant::now();
            let mut i = 0;
            while i < steady_n {
                std::thread::sleep(Duration::from_millis(10));
                let due = ((t0.elapsed().as_secs_f64() * b.rate) as usize).min(steady_n);
                if due > i {
                    write(&w, i, due).map_err(sql)?;
                    let now = SystemTime::now();
                    written[i..due].iter_mut().for_each(|t| *t = now);
                    i = due;
                }
            }
            let steady_rate = steady_n as f64 / t0.elapsed().as_secs_f64().max(1e-9);
            let t1 = Instant::now();
            while i < total {
                let to = (i + 1000).min(total);
                write(&w, i, to).map_err(sql)?;
                let now = SystemTime::now();
                written[i..to].iter_mut().for_each(|t| *t = now);
                i = to;
            }
            // The acquisition's last parametric row, after the last hit.
            w.batch(|w| w.parametric(time_of(total) + 1e-3, load_at(t_end), 0.0))
                .map_err(sql)?;
            Ok((steady_rate, t1.elapsed().as_secs_f64()))
        })?;
    // Each transient's lag: its part's write time − its commit by the writer.
    let lags = collect_lags(&watch_dir.join("features"), steady_n, |hit, _| {
        Ok(written[(hit as usize).saturating_sub(1).min(total - 1)])
    })?;
    Ok(WatchBenchResult::of(
        &summary,
        steady_rate,
        burst_write_s,
        lags,
    ))
}

/// Each features row's lag, its part's write time − when its hit was written (`written`,
/// by the row's hit number and source file), for the steady phase and the burst (hit
/// numbers past `steady_n`) apart; and the seconds from the burst's last write to its last
/// row committed.
fn collect_lags(
    features: &Path,
    steady_n: usize,
    mut written: impl FnMut(u64, &str) -> Result<SystemTime, WatchError>,
) -> Result<(Lags, Lags, f64), WatchError> {
    let (mut steady, mut burst) = (Vec::new(), Vec::new());
    let (mut last_commit, mut burst_last_write): (Option<SystemTime>, Option<SystemTime>) =
        (None, None);
    for part in parts_of(features) {
        let committed = part
            .metadata()
            .and_then(|m| m.modified())
            .map_err(|e| crate::util::IoAt::new(&part, e))?;
        let (_, _, batches) = crate::store::read_parquet(&part)?;
        for rb in batches {
            let (Some(files), Some(hits)) = (
                rb.column_by_name("source_file"),
                rb.column_by_name(cols::HIT.name),
            ) else {
                continue;
            };
            let files = arrow::array::AsArray::as_string::<i32>(files.as_ref());
            let hits =
                arrow::array::AsArray::as_primitive::<arrow::datatypes::Int64Type>(hits.as_ref());
            for r in 0..rb.num_rows() {
                let hit = hits.value(r).max(0) as u64;
                let w = written(hit, files.value(r))?;
                let lag = committed.duration_since(w).map_or(0.0, |d| d.as_secs_f64());
                if hit as usize > steady_n {
                    burst.push(lag);
                    last_commit = Some(last_commit.map_or(committed, |c| c.max(committed)));
                    burst_last_write = Some(burst_last_write.map_or(w, |c| c.max(w)));
                } else {
                    steady.push(lag);
                }
            }
        }
    }
    let drain = match (last_commit, burst_last_write) {
        (Some(c), Some(w)) => c.duration_since(w).map_or(0.0, |d| d.as_secs_f64()),
        _ => 0.0,
    };
    Ok((lags(steady), lags(burst), drain))
}

/// Watch `data` into `watch_dir` (ending 3 s after the last new data) while `write`, the
/// acquisition, runs on a thread of its own from the watcher's first line on (its map
/// trained, its page written); the watch's summary and what `write` returns (the steady
/// rate it reached, the seconds the burst took).
fn watch_while_writing(
    cfg: &ValidConfig,
    data: &Path,
    watch_dir: &Path,
    threads: usize,
    say: &mut impl FnMut(&str),
    write: impl FnOnce() -> Result<(f64, f64), WatchError> + Send,
) -> Result<(super::WatchSummary, f64, f64), WatchError> {
    let stop = AtomicBool::new(false);
    let ready = AtomicBool::new(false);
    let o = WatchOptions {
        until_idle_s: Some(3.0),
        offline_at_end: false,
        threads,
        model: None,
    };
    let (summary, writes) = std::thread::scope(|s| {
        let ready = &ready;
        let writer = s.spawn(move || {
            while !ready.load(std::sync::atomic::Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(20));
            }
            write()
        });
        let inputs = [data.to_path_buf()];
        let summary = super::watch(cfg, &inputs, watch_dir, &o, &stop, |l| {
            ready.store(true, std::sync::atomic::Ordering::Relaxed);
            say(l)
        });
        (summary, writer.join().expect("writer thread"))
    });
    let summary = summary?;
    let (steady_rate, burst_write_s) = writes?;
    Ok((summary, steady_rate, burst_write_s))
}

/// The parts of a Hive table: `DIR/experiment=*/part-*.parquet`.
fn parts_of(table: &Path) -> Vec<std::path::PathBuf> {
    std::fs::read_dir(table)
        .into_iter()
        .flatten()
        .flatten()
        .flat_map(|e| std::fs::read_dir(e.path()).into_iter().flatten().flatten())
        .map(|p| p.path())
        .collect()
}
