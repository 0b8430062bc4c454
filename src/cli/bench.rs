//! `aepipe bench …`: the benchmarks, each printing its ratios against the peers on the same
//! workload in the same run (and `bench transfer`, the leave-one-family-out table).

use super::args::*;
use super::exit::Outcome;
use super::inputs::{chain_file, user_cache};
use super::print;
use std::path::Path;

type Result<T> = std::result::Result<T, super::exit::Failure>;

/// `aepipe bench …`: one function per benchmark.
pub(super) fn bench(which: BenchCmd) -> Result<Outcome> {
    match which {
        BenchCmd::Sim(BenchSimArgs {
            masses,
            steps,
            repeats,
            field3d,
            field3d_steps,
            solvers,
            network3d,
            convergence,
            out,
        }) => {
            if convergence {
                use crate::sim::convergence as cv;
                let c = cv::convergence(&crate::sim::reference::ReferenceFile::default_library())?;
                std::fs::create_dir_all(&out).map_err(|e| {
                    crate::bench::BenchError::Run(format!("{}: {e}", out.display()))
                })?;
                let path = out.join("convergence.parquet");
                let n = cv::write(&path, &c)?;
                for l in cv::lines(&c) {
                    println!("{l}");
                }
                println!("{n} rows → {}", path.display());
                return Ok(Outcome::Success);
            }
            let rows = crate::bench::sim_scale(&masses, steps)?;
            print::sim_scale(&rows, steps);
            let t = crate::bench::sim_mesh(repeats)?;
            println!("mesh3x3-bond-failure, 250×250 grid, 40 µs (relaxation + 4 000 implicit steps + 400 FDTD steps): median {t:.3} s");
            if solvers {
                print::solver_table(&crate::bench::solver_table(repeats)?);
            }
            if !field3d.is_empty() {
                print::field3d(&crate::bench::field3d(&field3d, field3d_steps)?);
            }
            if !network3d.is_empty() {
                print::network3d(&crate::bench::network3d(&network3d)?);
            }
        }
        BenchCmd::Som(a) => bench_som(a)?,
        BenchCmd::Cluster(a) => bench_cluster(a)?,
        BenchCmd::Cwt(BenchCwtArgs {
            inputs,
            peers,
            python,
            threads,
            repeats,
            skip_full,
        }) => {
            let ours = crate::bench::cwt_bench(&inputs, &threads, repeats, skip_full)?;
            print::cwt_bench(&ours);
            if let Some(peers) = peers {
                print::cwt_peers(&ours, &python, &peers);
            }
        }
        BenchCmd::Stream(a) => bench_stream(a)?,
        BenchCmd::Analysis(BenchAnalysisArgs {
            rows,
            experiments,
            base,
            threads,
            out,
        }) => {
            let b = crate::bench::analysis::analysis(
                rows,
                experiments,
                base.as_deref(),
                &out,
                threads,
            )?;
            print::analysis_bench(&b);
        }
        BenchCmd::Detect(a) => bench_detect(a)?,
        BenchCmd::Report(a) => bench_report(a)?,
        BenchCmd::Transfer(a) => bench_transfer(a)?,
        BenchCmd::Watch(BenchWatchArgs {
            rate,
            seconds,
            burst,
            threads,
            out,
            vallen,
        }) => {
            let r = crate::live::bench::watch_bench(
                &crate::live::bench::WatchBench {
                    rate,
                    seconds,
                    burst,
                    threads,
                    vallen,
                },
                &out,
                |l| println!("{l}"),
            )?;
            print::watch_bench(&r);
        }
    }
    Ok(Outcome::Success)
}

/// `aepipe bench transfer`: the leave-one-family-out table.
fn bench_transfer(a: BenchTransferArgs) -> Result<()> {
    let rows = crate::workflow::transfer::transfer(&crate::workflow::transfer::TransferJob {
        out: &a.out,
        hits: a.hits,
        seeds: a.seeds,
        chains: a.chains,
        chain_file: chain_file(a.chain_file.as_deref())?,
        train_variants: a.train_variants,
        test_variants: a.test_variants,
        shares: a.shares,
        threads: a.threads,
        cache: user_cache(a.no_cache),
    })?;
    print!("{}", crate::workflow::transfer::format(&rows));
    println!("table: {}", a.out.join("transfer.parquet").display());
    Ok(())
}

/// `aepipe bench report`: the explorable charts alone, or with `--whole` the whole report.
fn bench_report(a: BenchReportArgs) -> Result<()> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/browser_report.py");
    let rows = if a.whole {
        let exe =
            std::env::current_exe().map_err(|e| crate::bench::BenchError::Run(e.to_string()))?;
        crate::bench::report::bench_whole_report(
            &exe,
            &a.rows,
            &a.dir,
            a.python.as_deref(),
            &script,
        )?
    } else {
        crate::bench::report::bench_report(&a.rows, &a.dir, a.python.as_deref(), &script)?
    };
    print!("{}", print::report_bench(&rows, a.whole));
    Ok(())
}

fn bench_detect(a: BenchDetectArgs) -> Result<()> {
    use crate::bench::detect as d;
    let threads = a.threads.max(1);
    print::detect_stage(&d::detect_stage(threads, a.stage_seconds), a.stage_seconds);
    if let Some(py) = &a.python {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/bench_detect.py");
        let one = d::detect_stage(1, a.stage_seconds);
        print::detect_peer(&one, d::numpy_peer(py, &script, &a.dir, a.stage_seconds));
    }
    let seconds: Vec<f64> = a.seconds.iter().copied().filter(|s| *s > 0.0).collect();
    if seconds.is_empty() {
        return Ok(());
    }
    let exe = std::env::current_exe().map_err(|e| crate::bench::BenchError::Run(e.to_string()))?;
    print::detect_runs(&d::stream_runs(&exe, &a.dir, &seconds, threads)?, threads);
    Ok(())
}

fn bench_cluster(a: BenchClusterArgs) -> Result<()> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/bench_cluster.py");
    let rows =
        crate::bench::cluster::bench_cluster(&a.rows, a.k, a.python.as_deref(), &script, &a.dir)?;
    println!(
        "aepipe cluster vs scikit-learn, k = {}, {} columns, whole processes (read, z-score, fit, write; aepipe also computes the validity indices)",
        a.k,
        crate::bench::cluster::DIM
    );
    println!(
        "{:>9} {:<7} {:>10} {:>9} {:>12} {:>9} {:>8}",
        "rows", "method", "aepipe s", "MB", "sklearn s", "MB", "ratio"
    );
    let mb = |b: u64| b as f64 / 1048576.0;
    for r in rows {
        let (t, m) = r.aepipe;
        match &r.peer {
            Some(Ok((pt, pm))) => println!(
                "{:>9} {:<7} {:>10.2} {:>9.0} {:>12.2} {:>9.0} {:>7.1}x",
                r.rows,
                r.method,
                t,
                mb(m),
                pt,
                mb(*pm),
                pt / t
            ),
            Some(Err(e)) => println!(
                "{:>9} {:<7} {:>10.2} {:>9.0}  scikit-learn failed: {e}",
                r.rows,
                r.method,
                t,
                mb(m)
            ),
            None => println!("{:>9} {:<7} {:>10.2} {:>9.0}", r.rows, r.method, t, mb(m)),
        }
    }
    Ok(())
}

fn bench_som(a: BenchSomArgs) -> Result<()> {
    let BenchSomArgs {
        inputs,
        peers,
        python,
        repeats,
    } = a;
    let (t, qe, te) = crate::bench::som_bench(&inputs, repeats)?;
    println!("aepipe SOM (1 thread): median {t:.4} s, QE {qe:.4}, TE8 {te:.4}");
    if let Some(peers) = peers {
        match crate::bench::run_minisom(&python, &peers) {
            Ok((pt, pqe)) => println!("MiniSom (same run): median {pt:.4} s, QE {pqe:.4} -> aepipe is {:.1}x faster, QE {:+.2} %", pt / t, (qe / pqe - 1.0) * 100.0),
            Err(e) => println!("MiniSom failed: {e}"),
        }
    }
    Ok(())
}

/// `aepipe bench stream`: stream a hundredth, a tenth and all of the hits through the
/// feature pipeline and print the speed and peak memory of each.
fn bench_stream(a: BenchStreamArgs) -> Result<()> {
    let BenchStreamArgs {
        hits,
        samples,
        no_pretrigger,
        linwave,
        threads,
        out,
    } = a;
    let w = if linwave {
        crate::bench::Workload::LinWave
    } else {
        crate::bench::Workload::Fixed {
            len: samples,
            pretrigger: !no_pretrigger,
        }
    };
    println!(
        "streaming synthetic hits through the feature pipeline ({}; threads: {})",
        w.describe(),
        if threads == 0 {
            crate::util::num_cpus()
        } else {
            threads
        }
    );
    println!(
        "{:>10} {:>10} {:>12} {:>14}",
        "hits", "seconds", "hits/s", "peak RSS MiB"
    );
    let mut sizes = vec![hits / 100, hits / 10, hits];
    sizes.retain(|&n| n > 0);
    sizes.dedup();
    for n in sizes {
        let p = crate::bench::stream_point(n, w, threads, &out)?;
        println!(
            "{:>10} {:>10.2} {:>12.0} {:>14.1}",
            p.hits, p.seconds, p.hits_per_s, p.peak_rss_mb
        );
    }
    Ok(())
}
