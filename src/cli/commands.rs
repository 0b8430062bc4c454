//! One function per command, taking its checked argument struct whole: load what it needs,
//! call the library, print. Errors go up as a [`Failure`] holding the room's typed error.

use super::args::*;
use super::exit::{Failure, Outcome};
use super::inputs::{chain_file, user_cache};
use super::print;
use super::UsageError;
use crate::config::{PipelineConfig, ValidConfig};
use crate::pipeline::{StreamJob, StreamOptions};
use std::path::Path;

type Result<T> = std::result::Result<T, Failure>;

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
        Cmd::Inspect(a) => inspect(a),
        Cmd::Cwt(a) => cwt(a),
        Cmd::Trend(a) => trend(a),
        Cmd::Som(which) => som(which),
        Cmd::Cluster(a) => cluster(a),
        Cmd::Statistics(a) => statistics(a),
        Cmd::Export(ExportCmd::Trfdb(a)) => export_trfdb(a),
        Cmd::Schema(a) => schema(a),
        Cmd::Simulate(a) => simulate(a),
        Cmd::Reference(a) => reference(a),
        Cmd::Run(a) => run(a),
        Cmd::Merge(a) => merge(a),
        Cmd::Report(a) => report(a),
        Cmd::Thesis(a) => thesis(a),
        Cmd::Watch(a) => watch(a),
        Cmd::SynthExperiment(a) => synth_experiment(a),
        Cmd::Demo(a) => demo(a),
        Cmd::Bench(which) => super::bench::bench(which),
    }
}

fn cwt(a: CwtArgs) -> Result<Outcome> {
    let cfg = load_config(a.config.as_deref())?;
    let summary = crate::workflow::cwt_of_hit(
        &a.inputs,
        &cfg,
        a.experiment.as_deref(),
        a.channel,
        a.hit,
        &a.png,
    )?;
    println!("{summary}");
    println!("wrote {}", a.png.display());
    Ok(Outcome::Success)
}

fn schema(a: SchemaArgs) -> Result<Outcome> {
    let cfg = load_config(a.config.as_deref())?;
    let table = &a.table;
    let t = crate::workflow::table_schema(table, &cfg).ok_or_else(|| {
        UsageError(format!(
            "unknown table '{table}' ({})",
            crate::workflow::TABLES.join(", ")
        ))
    })?;
    print!("{}", t.markdown_columns());
    Ok(Outcome::Success)
}

fn simulate(a: SimulateArgs) -> Result<Outcome> {
    let job = crate::sim::SimJob {
        model: a.model,
        scenario: a.scenario,
        params: crate::sim::scenario::Params(a.params),
        sweep: a
            .sweep
            .iter()
            .map(|s| crate::sim::scenario::parse_sweep(s))
            .collect::<std::result::Result<_, _>>()?,
        solver: a.solver,
        out: a.out,
        run: crate::sim::SimOptions {
            trajectory_every: a.trajectories,
            snapshot_every: a.snapshots,
        },
        acquisition: crate::sim::output::Acquisition {
            scale_v_per_pa: a.scale,
            threshold_db: a.threshold_db,
            noise_db: a.noise_db,
            pretrigger: a.pretrigger,
            ..Default::default()
        },
    };
    let rep = crate::sim::run_job(&job)?;
    for l in &rep.lines {
        println!("{l}");
    }
    if let Some(t) = &rep.sweep {
        let (f, e) = (job.out.join("sweep.png"), job.out.join("envelopes.png"));
        crate::plot::sim::sweep_png(&f, t)?;
        crate::plot::sim::envelopes_png(&e, t)?;
        println!(
            "frequency and γ against {} → {}",
            t.keys.join(", "),
            f.display()
        );
        println!("envelopes and their fits → {}", e.display());
    }
    Ok(Outcome::Success)
}

/// `aepipe thesis`: every selected entry run, its line printed as it finishes.
fn thesis(a: ThesisArgs) -> Result<Outcome> {
    let entries = crate::thesis::select(&a.ids)?;
    println!("{}", print::thesis_header());
    let t0 = std::time::Instant::now();
    let mut n = [0usize; 4];
    let mut failing = None;
    for e in &entries {
        let o = crate::thesis::run(e, &a.out)?;
        n[match o.verdict {
            crate::thesis::Verdict::Agrees => 0,
            crate::thesis::Verdict::Departs => 1,
            crate::thesis::Verdict::Pinned => 2,
            crate::thesis::Verdict::Fails => 3,
        }] += 1;
        if o.verdict == crate::thesis::Verdict::Fails {
            failing.get_or_insert(e.id);
        }
        println!("{}", print::thesis_line(&o));
    }
    println!(
        "{} entries: {} agree, {} depart where a closed form or a finer step expects, \
         {} hold a regression pin, {} fail, in {:.1} s → {}",
        entries.len(),
        n[0],
        n[1],
        n[2],
        n[3],
        t0.elapsed().as_secs_f64(),
        a.out.display()
    );
    // A value the record neither agrees with nor expects is a failed check (exit 3).
    if let Some(id) = failing {
        return Err(crate::thesis::ThesisError::Measure {
            id,
            message: format!(
                "{} entr{} outside the thesis's tolerance and any departure the record expects",
                n[2],
                if n[2] == 1 { "y is" } else { "ies are" }
            ),
        }
        .into());
    }
    Ok(Outcome::Success)
}

fn reference(a: ReferenceArgs) -> Result<Outcome> {
    use crate::sim::reference::{build_library_part, LibraryDir, ReferenceFile};
    let (out, threads, shard) = (a.out.as_path(), a.threads, a.shard);
    let f = ReferenceFile::read(&a.config)?;
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

fn run(a: RunArgs) -> Result<Outcome> {
    let JobArgs {
        inputs,
        out,
        config,
        threads,
        resume,
        shard,
    } = a.job;
    let (out, truth, label) = (out.as_path(), a.truth.as_deref(), a.label);
    let cache = user_cache(a.no_cache);
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
        cache,
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

fn watch(a: WatchArgs) -> Result<Outcome> {
    let WatchArgs {
        inputs,
        out,
        config,
        model,
        until_idle,
        threads,
    } = a;
    let (inputs, out, config) = (inputs.as_slice(), out.as_path(), config.as_deref());
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
fn merge(a: MergeArgs) -> Result<Outcome> {
    use crate::store::shard::{detect, ShardKind};
    let (dir, truth, threads, tables_only) = (
        a.dir.as_path(),
        a.truth.as_deref(),
        a.threads,
        a.tables_only,
    );
    let out = a.out.unwrap_or_else(|| dir.join("merged"));
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

fn report(a: ReportArgs) -> Result<Outcome> {
    let (p, fit) = crate::workflow::rebuild_report(&a.run_dir)?;
    if let Some(n) = fit.note() {
        println!("{n}");
    }
    println!("report: {}", p.display());
    Ok(Outcome::Success)
}

fn synth_experiment(a: SynthExperimentArgs) -> Result<Outcome> {
    let chain = match &a.chain {
        None => None,
        Some(name) => Some(
            chain_file(a.chain_file.as_deref())?
                .get(name)
                .and_then(|c| c.check(crate::synth::SAMPLE_RATE_HZ))
                .map_err(crate::sim::SimError::from)?,
        ),
    };
    let s = crate::synth::synth_test_through(
        &a.out,
        &a.id,
        a.hits,
        a.seed,
        crate::synth::Shape {
            cycles: a.cycles,
            energy_exponent: a.energy_exponent,
            shares: a.shares,
        },
        a.library.as_deref(),
        chain.as_ref(),
        true,
    )?;
    println!("{s}");
    Ok(Outcome::Success)
}

fn demo(a: DemoArgs) -> Result<Outcome> {
    let d = crate::demo::run_demo(&crate::demo::DemoJob {
        root: &a.out,
        hits: a.hits,
        seed: a.seed,
        threads: a.threads,
        cross_model: !a.no_cross_model,
        report: !a.no_report,
        cache: user_cache(a.no_cache),
    })?;
    print::demo(&d, &a.out);
    Ok(Outcome::Success)
}

fn stream_job(job: StreamJob, a: StreamArgs) -> Result<Outcome> {
    let cfg = load_config(a.job.config.as_deref())?;
    let opts = StreamOptions {
        threads: a.job.threads,
        progress: !a.quiet,
        resume: a.job.resume,
        shard: a.job.shard,
        control: None,
    };
    let report = crate::pipeline::run(job, &a.job.inputs, &a.job.out, &cfg, &opts)?;
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

fn inspect(a: InspectArgs) -> Result<Outcome> {
    let cfg = load_config(a.config.as_deref())?;
    let paths = &a.paths;
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

fn statistics(a: StatisticsArgs) -> Result<Outcome> {
    std::fs::create_dir_all(&a.out).map_err(|e| crate::util::IoAt::new(&a.out, e))?;
    let out = a.out.join("statistics.parquet");
    let cfg = ValidConfig::default();
    let rows = crate::analysis::powerlaw::run_statistics(
        &a.features,
        &out,
        crate::store::SourceRows::default(),
        &cfg.hash(),
    )?;
    for r in &rows {
        match &r.fit {
            Some(f) => println!(
                "{}: α = {:.4} ± {:.4} above x_min {:.6e} eu ({} of {} energies), cumulative exponent {:.4}, KS {:.4}",
                r.experiment, f.alpha, f.alpha_se, f.x_min, f.n_tail, r.n, f.alpha - 1.0, f.ks_distance
            ),
            None => println!("{}: {} energies, too few for a power-law fit", r.experiment, r.n),
        }
    }
    println!("wrote {}", out.display());
    Ok(Outcome::Success)
}

fn export_trfdb(a: ExportTrfdbArgs) -> Result<Outcome> {
    let run = crate::workflow::layout::RunDir::new(&a.run_dir);
    let out = a.out.unwrap_or_else(|| run.export());
    let s = crate::export::export(&run.run_tables(), &out, a.force)?;
    print!("{}", print::export_summary(&s));
    Ok(Outcome::Success)
}

fn cluster(a: ClusterArgs) -> Result<Outcome> {
    let cfg = load_config(a.config.as_deref())?;
    let mut c = cfg.cluster.clone();
    c.method = a.method.unwrap_or(c.method);
    if let Some((lo, hi)) = a.k {
        (c.k_min, c.k_max) = (lo, hi);
    }
    if !a.columns.is_empty() {
        c.columns = a.columns;
    }
    c.choose = a.choose.unwrap_or(c.choose);
    c.seed = a.seed.unwrap_or(c.seed);
    c.n_init = a.n_init.unwrap_or(c.n_init);
    c.max_fit_rows = a.max_fit_rows.unwrap_or(c.max_fit_rows);
    // The flags override [cluster]'s values: the result is checked by [cluster]'s check.
    let c = c.check().map_err(crate::config::ConfigError::from)?;
    let rep =
        crate::cluster::cluster_tables(&a.features, &a.out, &c, cfg.source_rows(), &cfg.hash())?;
    print!("{}", print::cluster_report(&rep));
    let png = a.out.join("validity.png");
    crate::plot::validity_png(&png, &rep.validity)?;
    println!(
        "wrote {}, {}, {} and {}",
        rep.clusters.display(),
        rep.validity_table.display(),
        rep.model.display(),
        png.display()
    );
    Ok(Outcome::Success)
}

fn trend(a: TrendArgs) -> Result<Outcome> {
    use crate::analysis::trend;
    let (features, out) = (a.features.as_slice(), a.out.as_path());
    let opts = trend::TrendOptions {
        cutoff: a.cutoff,
        alpha: a.alpha,
        min_load_span_n: a.min_load_span_n,
        min_hits: a.min_hits,
        columns: a.columns,
        sources: crate::store::SourceRows::default(),
    };
    let mut plots = Vec::new();
    let lines = if a.no_plots { 0 } else { 4 };
    let rep = trend::run_trend_with(features, out, &opts, lines, usize::MAX, |pic| {
        let sel = pic.selection;
        let png = trend::TrendDir::new(out).png(&sel.experiment, sel.channel);
        crate::plot::trend_png(&png, pic)?;
        plots.push(png);
        Ok::<(), Failure>(())
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
    use crate::som::classify::classify_tables;
    use crate::som::tables::{load_model, train, TrainOptions, TrainingSet};
    match which {
        SomCmd::Train(SomTrainArgs {
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
        }) => {
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
        SomCmd::Classify(SomClassifyArgs {
            model,
            features,
            out,
            reference,
            read_erroneous,
            novelty_quantile,
        }) => {
            let m = load_model(&model)?;
            let reference = reference.unwrap_or_else(|| m.label_column.clone());
            let conf = classify_tables(
                &m,
                &features,
                Some(&reference),
                &out,
                crate::store::SourceRows::default(),
                // The flags are [som]'s keys: checked by [som]'s own check.
                crate::som::classify::ClassifyRules::of(
                    &crate::som::settings::SomConfig {
                        read_erroneous,
                        novelty_quantile,
                        ..Default::default()
                    }
                    .check()
                    .map_err(crate::config::ConfigError::from)?
                    .into_inner(),
                ),
            )?;
            println!("{}", conf.reading.describe());
            println!("{}", conf.novelty.describe());
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
        SomCmd::Show(SomShowArgs { model, png }) => {
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
