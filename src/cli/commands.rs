//! One function per command: load what it needs, call the library, print. Errors go up as
//! `anyhow::Error` holding the room's typed error, which [`super::exit_code`] maps.

use super::print;
use super::{BenchCmd, Cli, Cmd, InitArg, RunArgs, SomCmd, UsageError};
use crate::config::{PipelineConfig, ValidConfig};
use crate::pipeline::{StreamJob, StreamOptions};
use anyhow::Result;
use std::path::{Path, PathBuf};

/// How a command that did not fail ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    Success,
    /// `--strict` and something was rejected (exit 2).
    Rejected,
}

impl Outcome {
    pub fn code(self) -> u8 {
        match self {
            Outcome::Success => 0,
            Outcome::Rejected => super::exit::STRICT,
        }
    }
}

fn load_config(path: Option<&Path>) -> Result<ValidConfig> {
    Ok(match path {
        None => ValidConfig::default(),
        Some(p) => PipelineConfig::from_file(p)?,
    })
}

/// Run the parsed command: one function per command.
pub fn dispatch(cli: Cli) -> Result<Outcome> {
    match cli.cmd {
        Cmd::Waveforms(a) => stream_job(StreamJob::Waveforms, a),
        Cmd::Features(a) => stream_job(StreamJob::Features, a),
        Cmd::Inspect { paths, config } => inspect(&paths, config.as_deref()),
        Cmd::Cwt {
            inputs,
            hit,
            channel,
            experiment,
            png,
            config,
        } => cwt(
            &inputs,
            hit,
            channel,
            experiment.as_deref(),
            &png,
            config.as_deref(),
        ),
        Cmd::Trend {
            features,
            out,
            cutoff,
            alpha,
            columns,
            no_plots,
        } => trend(&features, &out, cutoff, alpha, columns, no_plots),
        Cmd::Som { which } => som(which),
        Cmd::Schema { table, config } => schema(&table, config.as_deref()),
        Cmd::Simulate {
            model,
            scenario,
            params,
            sweep,
            solver,
            out,
            trajectories,
            snapshots,
            scale,
            threshold_db,
            noise_db,
            pretrigger,
        } => simulate(crate::sim::SimJob {
            model,
            scenario,
            params: crate::sim::scenario::Params(params),
            sweep: sweep
                .as_deref()
                .map(crate::sim::scenario::parse_sweep)
                .transpose()?,
            solver,
            out,
            run: crate::sim::SimOptions {
                trajectory_every: trajectories,
                snapshot_every: snapshots,
            },
            acquisition: crate::sim::output::Acquisition {
                scale_v_per_pa: scale,
                threshold_db,
                noise_db,
                pretrigger,
                ..Default::default()
            },
        }),
        Cmd::Reference {
            config,
            out,
            threads,
            shard,
        } => reference(&config, &out, threads, shard),
        Cmd::Run {
            inputs,
            config,
            out,
            truth,
            threads,
            resume,
            shard,
            label,
        } => run(
            inputs,
            config,
            &out,
            truth.as_deref(),
            threads,
            resume,
            shard,
            label,
        ),
        Cmd::Merge {
            dir,
            out,
            truth,
            threads,
            tables_only,
        } => merge(&dir, out, truth.as_deref(), threads, tables_only),
        Cmd::Report { run_dir } => report(&run_dir),
        Cmd::Watch {
            inputs,
            out,
            config,
            model,
            until_idle,
            threads,
        } => watch(&inputs, &out, config.as_deref(), model, until_idle, threads),
        Cmd::SynthExperiment {
            out,
            hits,
            seed,
            library,
            id,
        } => synth_experiment(&out, &id, hits, seed, library.as_deref()),
        Cmd::Demo {
            out,
            hits,
            seed,
            threads,
        } => demo(&out, hits, seed, threads),
        Cmd::Bench { which } => bench(which),
    }
}

fn cwt(
    inputs: &[PathBuf],
    hit: u64,
    channel: Option<u32>,
    experiment: Option<&str>,
    png: &Path,
    config: Option<&Path>,
) -> Result<Outcome> {
    let cfg = load_config(config)?;
    let summary = crate::workflow::cwt_of_hit(inputs, &cfg, experiment, channel, hit, png)?;
    println!("{summary}");
    println!("wrote {}", png.display());
    Ok(Outcome::Success)
}

fn schema(table: &str, config: Option<&Path>) -> Result<Outcome> {
    let cfg = load_config(config)?;
    let t = crate::workflow::table_schema(table, &cfg).ok_or_else(|| {
        UsageError(format!(
            "unknown table '{table}' ({})",
            crate::workflow::TABLES.join(", ")
        ))
    })?;
    print!("{}", t.markdown_columns());
    Ok(Outcome::Success)
}

fn simulate(job: crate::sim::SimJob) -> Result<Outcome> {
    for l in crate::sim::run_job(&job)? {
        println!("{l}");
    }
    Ok(Outcome::Success)
}

fn reference(
    config: &Path,
    out: &Path,
    threads: usize,
    shard: Option<crate::util::Shard>,
) -> Result<Outcome> {
    use crate::sim::reference::{build_library_part, LibraryDir, ReferenceFile};
    let f = ReferenceFile::read(config)?;
    let (runs, n, secs) = crate::util::with_threads(threads, || {
        build_library_part(&f.reference, out, shard, true)
    })?;
    let dir = LibraryDir::new(out);
    let file = match shard {
        None => dir.waveforms(),
        Some(s) => dir.part(s.k),
    };
    println!(
        "{runs} simulations, {n} labelled signals → {} in {secs:.1} s",
        file.display()
    );
    Ok(Outcome::Success)
}

#[allow(clippy::too_many_arguments)]
fn run(
    inputs: Vec<PathBuf>,
    config: Option<PathBuf>,
    out: &Path,
    truth: Option<&Path>,
    threads: usize,
    resume: bool,
    shard: Option<crate::util::Shard>,
    label: Option<String>,
) -> Result<Outcome> {
    // `--config P IN…`, or the positional form `P IN…`.
    let (pipeline, inputs) = match config {
        Some(p) => (p, inputs),
        None if inputs.len() >= 2 => (inputs[0].clone(), inputs[1..].to_vec()),
        None => {
            return Err(UsageError(
                "aepipe run needs a pipeline definition (--config FILE) and at least one input"
                    .into(),
            )
            .into())
        }
    };
    let mut cfg = load_config(Some(&pipeline))?;
    if let Some(l) = label {
        // The flag is a value of the configuration: checked like one.
        cfg = cfg.with(|c| c.som.label = l)?;
    }
    let outcome = crate::workflow::run_or_shard(&crate::workflow::RunJob {
        truth,
        progress: true,
        resume,
        shard,
        ..crate::workflow::RunJob::new(&cfg, &inputs, out, threads)
    })?;
    match outcome {
        crate::workflow::RunOutcome::Whole(s) => {
            for l in crate::workflow::headline(&s) {
                println!("{l}");
            }
            if cfg.report.enabled {
                println!(
                    "report: {}",
                    crate::workflow::RunDir::new(out).report_html().display()
                );
            }
        }
        crate::workflow::RunOutcome::Shard(r) => print::shard_run(&r),
    }
    Ok(Outcome::Success)
}

/// Set by SIGINT/SIGTERM: `aepipe watch` flushes what it has read and exits 0.
static STOP: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

extern "C" fn on_stop_signal(_: libc::c_int) {
    // Only an atomic store: async-signal-safe.
    STOP.store(true, std::sync::atomic::Ordering::Relaxed);
}

fn watch(
    inputs: &[PathBuf],
    out: &Path,
    config: Option<&Path>,
    model: Option<PathBuf>,
    until_idle: Option<f64>,
    threads: usize,
) -> Result<Outcome> {
    if until_idle.is_some_and(|s| !(s.is_finite() && s >= 0.0)) {
        return Err(UsageError("--until-idle must be a number of seconds ≥ 0".into()).into());
    }
    let cfg = load_config(config)?;
    // SAFETY: the handler only stores to an atomic; installed before any worker thread.
    unsafe {
        libc::signal(
            libc::SIGINT,
            on_stop_signal as *const () as libc::sighandler_t,
        );
        libc::signal(
            libc::SIGTERM,
            on_stop_signal as *const () as libc::sighandler_t,
        );
    }
    let o = crate::live::WatchOptions {
        until_idle_s: until_idle,
        offline_at_end: true,
        threads,
        model,
    };
    let s = crate::live::watch(&cfg, inputs, out, &o, &STOP, |l| println!("{l}"))?;
    println!(
        "watched: {} hits, {} rows, {} rejects in {} flushes{}",
        s.state.hits,
        s.state.rows,
        s.state.rejects,
        s.state.flushes,
        if s.stopped_by_signal {
            " (stopped by a signal; run the same command to continue)"
        } else {
            ""
        }
    );
    if let Some(r) = &s.last {
        for l in crate::workflow::headline(r) {
            println!("{l}");
        }
    }
    Ok(Outcome::Success)
}

/// `aepipe merge`: the shards' own kind says which merge (feature run, tables only, library).
fn merge(
    dir: &Path,
    out: Option<PathBuf>,
    truth: Option<&Path>,
    threads: usize,
    tables_only: bool,
) -> Result<Outcome> {
    use crate::store::shard::{detect, ShardKind};
    let out = out.unwrap_or_else(|| dir.join("merged"));
    match detect(dir)? {
        ShardKind::ReferenceLibrary => {
            let n = crate::sim::reference::merge_library(dir, &out)?;
            println!(
                "{n} labelled signals → {}",
                crate::sim::reference::LibraryDir::new(&out)
                    .waveforms()
                    .display()
            );
        }
        ShardKind::Waveforms | ShardKind::Features if tables_only => {
            let (r, _, _) = crate::pipeline::merge(dir, &out, threads, None)?;
            print::stream_run(&r, "merged");
        }
        ShardKind::Waveforms | ShardKind::Features => {
            let s = crate::workflow::merge(dir, &out, truth, threads, true)?;
            for l in crate::workflow::headline(&s) {
                println!("{l}");
            }
            if s.config.report.enabled {
                println!(
                    "report: {}",
                    crate::workflow::RunDir::new(&out).report_html().display()
                );
            }
        }
    }
    Ok(Outcome::Success)
}

fn report(run_dir: &Path) -> Result<Outcome> {
    let p = crate::workflow::rebuild_report(run_dir)?;
    println!("report: {}", p.display());
    Ok(Outcome::Success)
}

fn synth_experiment(
    out: &Path,
    id: &str,
    hits: usize,
    seed: u64,
    library: Option<&Path>,
) -> Result<Outcome> {
    let s = crate::synth::synth_experiment(out, id, hits, seed, library, true)?;
    println!("{s}");
    Ok(Outcome::Success)
}

fn demo(out: &Path, hits: usize, seed: u64, threads: usize) -> Result<Outcome> {
    let d = crate::demo::run_demo(out, hits, seed, threads)?;
    print::demo(&d, out);
    Ok(Outcome::Success)
}

fn stream_job(job: StreamJob, a: RunArgs) -> Result<Outcome> {
    let cfg = load_config(a.config.as_deref())?;
    let opts = StreamOptions {
        threads: a.threads,
        progress: !a.quiet,
        resume: a.resume,
        shard: a.shard,
        control: None,
    };
    let report = crate::pipeline::run(job, &a.inputs, &a.out, &cfg, &opts)?;
    print::stream_run(&report, job.table_file());
    if a.strict && report.stats.rejects > 0 {
        eprintln!(
            "aepipe: {} rejects and --strict given",
            report.stats.rejects
        );
        return Ok(Outcome::Rejected);
    }
    Ok(Outcome::Success)
}

fn inspect(paths: &[PathBuf], config: Option<&Path>) -> Result<Outcome> {
    let cfg = load_config(config)?;
    let d = crate::ingest::discover(paths, &cfg.ingest);
    for s in &d.sources {
        println!("{}", crate::inspect::summarise(s, &cfg));
    }
    for r in &d.rejects {
        eprintln!("aepipe: {}: {}", r.source_file, r.reason);
    }
    if !d.skipped.is_empty() {
        println!("passed over (not recordings):");
        for (p, why) in &d.skipped {
            println!("  {}: {why}", p.display());
        }
    }
    if d.sources.is_empty() {
        return Err(UsageError(format!(
            "no recordings found in {}",
            paths
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ))
        .into());
    }
    Ok(Outcome::Success)
}

fn trend(
    features: &[PathBuf],
    out: &Path,
    cutoff: crate::config::Cutoff,
    alpha: f64,
    columns: Vec<String>,
    no_plots: bool,
) -> Result<Outcome> {
    use crate::analysis::trend;
    let opts = trend::TrendOptions {
        cutoff,
        alpha,
        columns,
        sources: crate::store::SourceRows::default(),
    };
    let mut plots = Vec::new();
    let lines = if no_plots { 0 } else { 4 };
    let rep = trend::run_trend_with(features, out, &opts, lines, usize::MAX, |pic| {
        let sel = pic.selection;
        let png = trend::TrendDir::new(out).png(&sel.experiment, sel.channel);
        crate::plot::trend_png(&png, pic)?;
        plots.push(png);
        Ok::<(), anyhow::Error>(())
    })?;
    print!("{}", trend::format_table(&rep));
    for png in plots {
        println!("plot: {}", png.display());
    }
    println!(
        "wrote {} and {}",
        rep.table_path.display(),
        trend::TrendDir::new(out).manifest().display()
    );
    Ok(Outcome::Success)
}

fn som(which: SomCmd) -> Result<Outcome> {
    use crate::som::tables::{classify_tables, load_model, train, TrainOptions, TrainingSet};
    match which {
        SomCmd::Train {
            features,
            label,
            out,
            columns,
            fraction,
            standardise,
            rows,
            cols,
            seed,
            init,
        } => {
            let o = TrainOptions {
                columns,
                label,
                standardise,
                rows,
                cols,
                seed,
                init: match init {
                    InitArg::Samples => crate::som::Init::Samples,
                    InitArg::Random => crate::som::Init::Random,
                    InitArg::Linear => crate::som::Init::Linear,
                },
                training: TrainingSet {
                    fraction,
                    ..Default::default()
                },
                sources: crate::store::SourceRows::default(),
            };
            let m = train(&features, &out, &o)?;
            print::som_trained(&m);
            crate::plot::u_matrix_png(&out.join("u_matrix.png"), &m.som)?;
            println!(
                "wrote {}/model.json, model.cod, train.dat, u_matrix.png",
                out.display()
            );
        }
        SomCmd::Classify {
            model,
            features,
            out,
            reference,
            read_erroneous,
        } => {
            let m = load_model(&model)?;
            let reference = reference.unwrap_or_else(|| m.label_column.clone());
            let conf = classify_tables(
                &m,
                &features,
                Some(&reference),
                &out,
                crate::store::SourceRows::default(),
                read_erroneous.into(),
            )?;
            println!("{}", conf.reading.describe());
            println!(
                "SOM class (rows) against {reference} (columns), share of the SOM class's hits:"
            );
            print!("{}", conf.format());
            let png = out.join("hit_maps.png");
            crate::plot::hit_maps_png(&png, &m.som, &conf.hits)?;
            println!(
                "wrote {} and {}",
                out.join("classification.parquet").display(),
                png.display()
            );
        }
        SomCmd::Show { model, png } => {
            let m = load_model(&model)?;
            print::som_map(&m);
            let dir = if model.is_dir() {
                model.clone()
            } else {
                model.parent().map(Path::to_path_buf).unwrap_or_default()
            };
            let png = png.unwrap_or_else(|| dir.join("u_matrix.png"));
            crate::plot::u_matrix_png(&png, &m.som)?;
            println!("wrote {}", png.display());
        }
    }
    Ok(Outcome::Success)
}

fn bench(which: BenchCmd) -> Result<Outcome> {
    match which {
        BenchCmd::Sim {
            masses,
            steps,
            repeats,
        } => {
            let rows = crate::bench::sim_scale(&masses, steps)?;
            print::sim_scale(&rows, steps);
            let t = crate::bench::sim_mesh(repeats)?;
            println!("mesh3x3-bond-failure, 250×250 grid, 40 µs (relaxation + 4 000 implicit steps + 400 FDTD steps): median {t:.3} s");
        }
        BenchCmd::Som {
            inputs,
            peers,
            python,
            repeats,
        } => {
            let (t, qe, te) = crate::bench::som_bench(&inputs, repeats)?;
            println!("aepipe SOM (1 thread): median {t:.4} s, QE {qe:.4}, TE8 {te:.4}");
            if let Some(peers) = peers {
                match crate::bench::run_minisom(&python, &peers) {
                    Ok((pt, pqe)) => println!("MiniSom (same run): median {pt:.4} s, QE {pqe:.4} -> aepipe is {:.1}x faster, QE {:+.2} %", pt / t, (qe / pqe - 1.0) * 100.0),
                    Err(e) => println!("MiniSom failed: {e}"),
                }
            }
        }
        BenchCmd::Cwt {
            inputs,
            peers,
            python,
            threads,
            repeats,
            skip_full,
        } => {
            let ours = crate::bench::cwt_bench(&inputs, &threads, repeats, skip_full)?;
            print::cwt_bench(&ours);
            if let Some(peers) = peers {
                print::cwt_peers(&ours, &python, &peers);
            }
        }
        BenchCmd::Stream {
            hits,
            samples,
            no_pretrigger,
            linwave,
            threads,
            out,
        } => {
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
        }
        BenchCmd::Analysis {
            rows,
            experiments,
            base,
            threads,
            out,
        } => {
            let b = crate::bench::analysis::analysis(
                rows,
                experiments,
                base.as_deref(),
                &out,
                threads,
            )?;
            print::analysis_bench(&b);
        }
        BenchCmd::Watch {
            rate,
            seconds,
            burst,
            threads,
            out,
            vallen,
        } => {
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
