//! The `aepipe` command: parse flags (here, in one place), call the library, print.
//!
//! Exit codes: 0 success; 1 usage or configuration error; 2 some inputs were rejected and
//! `--strict` was given; 3 the run failed (an output could not be written).

use aepipe::config::PipelineConfig;
use aepipe::pipeline::{run, Job, RunOptions, RunReport};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "aepipe",
    version,
    about = "Acoustic-emission recordings of paper tensile tests -> Parquet features, trends, classes, reports"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(clap::Args)]
struct RunArgs {
    /// Files or folders (searched recursively): Vallen .pridb/.tradb, AEwin, WaveExplorer, WAV, CSV, text, waveforms.parquet
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output folder
    #[arg(long)]
    out: PathBuf,
    /// Pipeline definition (TOML, see pipelines/)
    #[arg(long)]
    config: Option<PathBuf>,
    /// Worker threads (0 = all cores)
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Exit with code 2 when any hit or file was rejected
    #[arg(long)]
    strict: bool,
    /// No progress bar
    #[arg(long)]
    quiet: bool,
}

#[derive(Subcommand)]
enum Cmd {
    /// Convert recordings into the canonical waveform table DIR/waveforms.parquet
    Waveforms(RunArgs),
    /// Run the streaming feature pipeline: DIR/features.parquet, rejects.parquet, manifest.json
    Features(RunArgs),
    /// Summarise experiments: format, channels, hits, rates, lengths, time span, load/extension
    Inspect {
        #[arg(required = true)]
        paths: Vec<PathBuf>,
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Draw one hit's waveform and full-resolution CWT into a PNG
    Cwt {
        /// Files or folders holding the hit
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Hit number (Vallen TRAI, AEwin hit #, event #)
        #[arg(long)]
        hit: u64,
        /// Channel (default: the first channel that has this hit)
        #[arg(long)]
        channel: Option<u32>,
        /// Experiment id (default: the first experiment that has this hit)
        #[arg(long)]
        experiment: Option<String>,
        #[arg(long)]
        png: PathBuf,
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Trend statistics (ch. 4.5.5): r, p, slope, intercept of each power ratio vs AE number
    Trend {
        /// features.parquet files
        #[arg(required = true)]
        features: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
        /// none | peak-load | time:SECONDS | hits:N
        #[arg(long, default_value = "peak-load")]
        cutoff: String,
        /// Significance level
        #[arg(long, default_value_t = 0.01)]
        alpha: f64,
        /// Columns to test (default: every pr_* power ratio), e.g. peak_freq_hz,centroid_freq_hz
        #[arg(long, value_delimiter = ',')]
        columns: Vec<String>,
        /// Skip the PNG plots
        #[arg(long)]
        no_plots: bool,
    },
    /// Self-organising map (ch. 5): train, classify, show
    Som {
        #[command(subcommand)]
        which: SomCmd,
    },
    /// Print the column table of an output table (features, waveforms, rejects, trend, classification)
    Schema {
        #[arg(default_value = "features")]
        table: String,
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Simulate AEs with the hybrid mass/spring + acoustic model (ch. 3–4): DIR/waveforms.parquet
    Simulate {
        /// Model file: the thesis's sectioned format (Appendix A) or .toml
        model: Option<PathBuf>,
        /// Built-in scenario instead of a file: sho, five-mass-fibre, fibre-single-constraint,
        /// rubber-band, paper-fibre, mesh3x3-bond-failure, structure2x1-fibre-failure
        #[arg(long)]
        scenario: Option<String>,
        /// Scenario parameter key=value (repeatable), e.g. point=7, stretch=0.01, dt=1e-8
        #[arg(long = "param", value_parser = aepipe::sim::scenario::Params::parse_one)]
        params: Vec<(String, f64)>,
        /// Run once per integer value: key=LO..HI (e.g. point=1..12), one hit each
        #[arg(long)]
        sweep: Option<String>,
        #[arg(long, value_enum)]
        solver: Option<aepipe::sim::model::Solver>,
        #[arg(long)]
        out: PathBuf,
        /// Write node trajectories every N mass/spring steps (DIR/trajectories.parquet)
        #[arg(long)]
        trajectories: Option<usize>,
        /// Write a pressure-field PNG every N acoustic steps (DIR/snapshots/)
        #[arg(long)]
        snapshots: Option<usize>,
        /// Sensor sensitivity, V/Pa (samples_v = pressure × this)
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
    },
    /// Build the labelled reference library: the simulator over a grid of scenarios, in
    /// parallel, into DIR/waveforms.parquet
    Reference {
        /// Library definition (see pipelines/reference-library.toml)
        #[arg(long, default_value = "pipelines/reference-library.toml")]
        config: PathBuf,
        #[arg(long)]
        out: PathBuf,
        #[arg(long, default_value_t = 0)]
        threads: usize,
    },
    /// A synthetic notched-paper test built from reference-library signals: DIR/<id>.pridb,
    /// .tradb (Vallen) and DIR/truth.parquet
    SynthExperiment {
        #[arg(long)]
        out: PathBuf,
        #[arg(long, default_value_t = 651)]
        hits: usize,
        #[arg(long, default_value_t = 2026)]
        seed: u64,
        /// Reference library (waveforms.parquet of `aepipe reference`); default: build the
        /// embedded pipelines/reference-library.toml into DIR/reference
        #[arg(long)]
        library: Option<PathBuf>,
        #[arg(long, default_value = "synthetic_notched_paper")]
        id: String,
    },
    /// The whole method from a pipeline definition: features → trend → SOM → classification →
    /// DIR/report.html
    Run {
        /// Pipeline definition (pipelines/notched-paper.toml, pipelines/demo.toml, …)
        pipeline: PathBuf,
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
        /// Ground truth (truth.parquet of `aepipe synth-experiment`) to score the classes
        #[arg(long)]
        truth: Option<PathBuf>,
        #[arg(long, default_value_t = 0)]
        threads: usize,
    },
    /// Write RUN_DIR/report.html again from a finished `aepipe run` folder
    Report { run_dir: PathBuf },
    /// Make a synthetic experiment and run the pipeline on it (the README's first command)
    Demo {
        /// Folder for the demo's data and outputs
        #[arg(long, default_value = "aepipe-demo")]
        out: PathBuf,
        #[arg(long, default_value_t = 651)]
        hits: usize,
        #[arg(long, default_value_t = 2026)]
        seed: u64,
        #[arg(long, default_value_t = 0)]
        threads: usize,
    },
    /// Benchmarks (print numbers, never pass/fail)
    Bench {
        #[command(subcommand)]
        which: BenchCmd,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum InitArg {
    Samples,
    Random,
    Linear,
}

#[derive(Subcommand)]
enum SomCmd {
    /// Train a map on a balanced ~10 % of the labelled hits (ch. 5.4): MODEL_DIR/model.json, model.cod, train.dat, u_matrix.png
    Train {
        #[arg(required = true)]
        features: Vec<PathBuf>,
        /// Column holding the training labels (criteria_label, or label for simulator truth)
        #[arg(long, default_value = "criteria_label")]
        label: String,
        #[arg(long)]
        out: PathBuf,
        /// Feature columns (tf_bins expands to its 200 elements; numeric scalars add one each)
        #[arg(long, default_value = "tf_bins", value_delimiter = ',')]
        columns: Vec<String>,
        /// Share of the hits in the training set
        #[arg(long, default_value_t = 0.1)]
        fraction: f64,
        /// Standardise each dimension (z-score on the training set)
        #[arg(long)]
        standardise: bool,
        #[arg(long, default_value_t = 10)]
        rows: usize,
        #[arg(long, default_value_t = 10)]
        cols: usize,
        #[arg(long, default_value_t = 2008)]
        seed: u64,
        /// Initial codebook: random training vectors, uniform random, or linear (PCA plane)
        #[arg(long, value_enum, default_value_t = InitArg::Samples)]
        init: InitArg,
    },
    /// Classify every hit: DIR/classification.parquet, the Table 5.4 confusion report, hit maps
    Classify {
        model: PathBuf,
        #[arg(required = true)]
        features: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
        /// Reference column for the confusion report (default: the model's label column)
        #[arg(long)]
        reference: Option<String>,
    },
    /// Summarise a model and draw its U-matrix with node labels
    Show {
        model: PathBuf,
        #[arg(long)]
        png: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
enum BenchCmd {
    /// Simulator scale: implicit steps of random fibre networks (cost per spring), and the
    /// mesh3x3-bond-failure scenario with its 250×250 grid over 40 µs
    Sim {
        #[arg(long, default_value = "1000,2500,5000,10000", value_delimiter = ',')]
        masses: Vec<usize>,
        #[arg(long, default_value_t = 200)]
        steps: usize,
        #[arg(long, default_value_t = 3)]
        repeats: usize,
    },
    /// W3 SOM training (651 × 200-D, 10×10, Table 5.2 schedule, the peers' initial codebook);
    /// with --peers, MiniSom in the same run
    Som {
        /// Folder written by the peers' export_inputs.py
        #[arg(long)]
        inputs: PathBuf,
        #[arg(long)]
        peers: Option<PathBuf>,
        #[arg(long, default_value = "python3")]
        python: PathBuf,
        #[arg(long, default_value_t = 5)]
        repeats: usize,
    },
    /// W1 CWT + feature path + W2 spectrum on the peers' exact inputs; with --peers, runs
    /// fCWT, the numpy baseline and numpy rfft in the same run and prints the ratios
    Cwt {
        /// Folder written by the peers' export_inputs.py (w1_signals_f32.bin, w1_freqs_hz_f64.bin)
        #[arg(long)]
        inputs: PathBuf,
        /// The peers' folder (../shared/bench/peers or a writable copy) to run them too
        #[arg(long)]
        peers: Option<PathBuf>,
        /// Python with the peers' packages (their setup_env.sh venv)
        #[arg(long, default_value = "python3")]
        python: PathBuf,
        #[arg(long, default_value = "1,2", value_delimiter = ',')]
        threads: Vec<usize>,
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// Leave out the full-resolution CWT (2.5 GB output): feature path and spectrum only
        #[arg(long)]
        skip_full: bool,
    },
    /// Stream synthetic hits through the feature pipeline: hits/s and peak RSS at growing hit counts
    Stream {
        /// Largest number of hits; the benchmark also runs 1/10 and 1/100 of it first
        #[arg(long, default_value_t = 100_000)]
        hits: u64,
        #[arg(long, default_value_t = 4096)]
        samples: usize,
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Where to write the (small) feature tables
        #[arg(long, default_value = "target/bench-stream")]
        out: PathBuf,
    },
}

fn load_config(path: Option<&Path>) -> Result<PipelineConfig, ExitCode> {
    match path {
        None => Ok(PipelineConfig::default()),
        Some(p) => PipelineConfig::from_file(p).map_err(|e| {
            eprintln!("aepipe: {e}");
            ExitCode::from(1)
        }),
    }
}

fn print_run(report: &RunReport, what: &str) {
    let s = &report.stats;
    println!(
        "{what}: {} rows, {} rejects, {} records read, {:.2} s ({:.0} hits/s)",
        s.rows,
        s.rejects,
        s.records_read,
        s.seconds,
        s.rows as f64 / s.seconds.max(1e-9)
    );
    for (exp, c) in &s.by_experiment {
        println!(
            "  {:<40} {:>7} rows {:>6} rejects",
            if exp.is_empty() {
                "(no experiment)"
            } else {
                exp
            },
            c.rows,
            c.rejects
        );
    }
    if !report.skipped.is_empty() {
        println!("  {} file(s) in the input folders are not recordings and were passed over (listed in the manifest)", report.skipped.len());
    }
    for r in &s.first_rejects {
        eprintln!("  reject: {r}");
    }
    if s.rejects as usize > s.first_rejects.len() {
        eprintln!(
            "  … {} more in {}",
            s.rejects as usize - s.first_rejects.len(),
            report.rejects_path.display()
        );
    }
    println!(
        "  wrote {}, {}, {}",
        report.table_path.display(),
        report.rejects_path.display(),
        report.manifest_path.display()
    );
}

fn run_job(job: Job, a: RunArgs) -> ExitCode {
    let cfg = match load_config(a.config.as_deref()) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let opts = RunOptions {
        threads: a.threads,
        progress: !a.quiet,
    };
    match run(job, &a.inputs, &a.out, &cfg, &opts) {
        Ok(report) => {
            print_run(&report, job.table_file());
            if a.strict && report.stats.rejects > 0 {
                eprintln!(
                    "aepipe: {} rejects and --strict given",
                    report.stats.rejects
                );
                return ExitCode::from(2);
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("aepipe: {e}");
            ExitCode::from(3)
        }
    }
}

fn run_som(which: SomCmd) -> ExitCode {
    use aepipe::som::run;
    let fail = |e: &dyn std::fmt::Display| {
        eprintln!("aepipe: {e}");
        ExitCode::from(1)
    };
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
            let o = run::TrainOptions {
                columns,
                label,
                standardise,
                rows,
                cols,
                seed,
                init: match init {
                    InitArg::Samples => aepipe::som::Init::Samples,
                    InitArg::Random => aepipe::som::Init::Random,
                    InitArg::Linear => aepipe::som::Init::Linear,
                },
                training: run::TrainingSet {
                    fraction,
                    ..Default::default()
                },
            };
            match run::train(&features, &out, &o) {
                Ok(m) => {
                    println!(
                        "trained a {}×{} map on {}-D inputs",
                        m.som.rows, m.som.cols, m.som.dim
                    );
                    println!(
                        "training set ({} rows):",
                        m.composition.values().map(|c| c.1).sum::<usize>()
                    );
                    for (c, (distinct, rows)) in &m.composition {
                        println!(
                            "  {c:<16} {distinct:>4} hits, {rows:>4} rows{}",
                            if rows > distinct {
                                format!(" (repeated ×{:.1})", *rows as f64 / *distinct as f64)
                            } else {
                                String::new()
                            }
                        );
                    }
                    if let Some(l) = &m.som.log {
                        println!(
                            "quantisation error: {}",
                            l.qe.iter()
                                .map(|q| format!("{q:.5}"))
                                .collect::<Vec<_>>()
                                .join(" → ")
                        );
                        println!("topographic error: {:.4}", l.topographic_error);
                    }
                    let png = out.join("u_matrix.png");
                    match aepipe::plot::u_matrix_png(&png, &m.som) {
                        Ok(()) => println!(
                            "wrote {}/model.json, model.cod, train.dat, u_matrix.png",
                            out.display()
                        ),
                        Err(e) => eprintln!("aepipe: picture skipped: {e}"),
                    }
                    ExitCode::SUCCESS
                }
                Err(e) => fail(&e),
            }
        }
        SomCmd::Classify {
            model,
            features,
            out,
            reference,
        } => {
            let m = match run::load_model(&model) {
                Ok(m) => m,
                Err(e) => return fail(&e),
            };
            let reference = reference.unwrap_or_else(|| m.label_column.clone());
            match run::classify(&m, &features, Some(&reference), &out) {
                Ok(conf) => {
                    println!("SOM class (rows) against {reference} (columns), share of the SOM class's hits:");
                    print!("{}", conf.format());
                    let png = out.join("hit_maps.png");
                    if let Err(e) = aepipe::plot::hit_maps_png(&png, &m.som, &conf.hits) {
                        eprintln!("aepipe: picture skipped: {e}");
                    }
                    println!(
                        "wrote {} and {}",
                        out.join("classification.parquet").display(),
                        png.display()
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => fail(&e),
            }
        }
        SomCmd::Show { model, png } => {
            let m = match run::load_model(&model) {
                Ok(m) => m,
                Err(e) => return fail(&e),
            };
            println!(
                "{}×{} map, {}-D inputs ({}), labels from {}",
                m.som.rows,
                m.som.cols,
                m.som.dim,
                m.columns.join(", "),
                m.label_column
            );
            for r in 0..m.som.rows {
                let row: Vec<String> = (0..m.som.cols)
                    .map(|c| {
                        format!(
                            "{:>14}",
                            m.som
                                .labels
                                .get(r * m.som.cols + c)
                                .map(String::as_str)
                                .unwrap_or("-")
                        )
                    })
                    .collect();
                println!("{}", row.join(""));
            }
            let png = png.unwrap_or_else(|| model.join("u_matrix.png"));
            match aepipe::plot::u_matrix_png(&png, &m.som) {
                Ok(()) => {
                    println!("wrote {}", png.display());
                    ExitCode::SUCCESS
                }
                Err(e) => fail(&e),
            }
        }
    }
}

/// `key=LO..HI` with integer bounds.
fn parse_sweep(s: &str) -> Result<(String, i64, i64), String> {
    let bad = || format!("--sweep {s}: expected key=LO..HI with integers, e.g. point=1..12");
    let (k, r) = s.split_once('=').ok_or_else(bad)?;
    let (lo, hi) = r.split_once("..").ok_or_else(bad)?;
    Ok((
        k.trim().to_string(),
        lo.trim().parse().map_err(|_| bad())?,
        hi.trim().parse().map_err(|_| bad())?,
    ))
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 1 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    match cli.cmd {
        Cmd::Waveforms(a) => run_job(Job::Waveforms, a),
        Cmd::Features(a) => run_job(Job::Features, a),
        Cmd::Inspect { paths, config } => {
            let cfg = match load_config(config.as_deref()) {
                Ok(c) => c,
                Err(code) => return code,
            };
            let d = aepipe::ingest::discover(&paths, &cfg.ingest);
            for s in &d.sources {
                println!("{}", aepipe::inspect::summarise(s, &cfg.ingest));
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
                eprintln!(
                    "aepipe: no recordings found in {}",
                    paths
                        .iter()
                        .map(|p| p.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
                return ExitCode::from(1);
            }
            ExitCode::SUCCESS
        }
        Cmd::Cwt {
            inputs,
            hit,
            channel,
            experiment,
            png,
            config,
        } => {
            let cfg = match load_config(config.as_deref()) {
                Ok(c) => c,
                Err(code) => return code,
            };
            match aepipe::plot::cwt_of_hit(&inputs, &cfg, experiment.as_deref(), channel, hit, &png)
            {
                Ok(summary) => {
                    println!("{summary}");
                    println!("wrote {}", png.display());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    ExitCode::from(1)
                }
            }
        }
        Cmd::Trend {
            features,
            out,
            cutoff,
            alpha,
            columns,
            no_plots,
        } => {
            use aepipe::analysis::trend;
            let cutoff: trend::Cutoff = match cutoff.parse() {
                Ok(c) => c,
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    return ExitCode::from(1);
                }
            };
            let opts = trend::TrendOptions {
                cutoff,
                alpha,
                columns,
            };
            match trend::run_trend(&features, &out, &opts) {
                Ok(rep) => {
                    print!("{}", trend::format_table(&rep));
                    if !no_plots {
                        for sel in &rep.selections {
                            let png =
                                out.join(format!("trend_{}_ch{}.png", sel.experiment, sel.channel));
                            match aepipe::plot::trend_png(
                                &png,
                                &rep,
                                &sel.experiment,
                                sel.channel,
                                4,
                            ) {
                                Ok(true) => println!("plot: {}", png.display()),
                                Ok(false) => {}
                                Err(e) => eprintln!("aepipe: plot skipped: {e}"),
                            }
                        }
                    }
                    println!(
                        "wrote {} and {}",
                        rep.table_path.display(),
                        out.join("trend_manifest.json").display()
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    ExitCode::from(1)
                }
            }
        }
        Cmd::Som { which } => run_som(which),
        Cmd::Schema { table, config } => {
            let cfg = match load_config(config.as_deref()) {
                Ok(c) => c,
                Err(code) => return code,
            };
            let t = match table.as_str() {
                "features" => aepipe::features::features_table(&cfg),
                "waveforms" => aepipe::store::waveforms_table(),
                "rejects" => aepipe::store::rejects_table(),
                "trend" => aepipe::analysis::trend::trend_table(),
                "classification" => aepipe::som::run::classification_table(),
                "sim_waveforms" => aepipe::sim::output::sim_waveforms_table(),
                "sim_trajectories" => aepipe::sim::output::trajectory_table(),
                "truth" => aepipe::synth::truth_table(),
                other => {
                    eprintln!("aepipe: unknown table '{other}' (features, waveforms, rejects, trend, classification, sim_waveforms, sim_trajectories, truth)");
                    return ExitCode::from(1);
                }
            };
            print!("{}", t.markdown_columns());
            ExitCode::SUCCESS
        }
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
        } => {
            let sweep = match sweep.as_deref().map(parse_sweep).transpose() {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    return ExitCode::from(1);
                }
            };
            let job = aepipe::sim::Job {
                model,
                scenario,
                params: aepipe::sim::scenario::Params(params),
                sweep,
                solver,
                out,
                run: aepipe::sim::RunOptions {
                    trajectory_every: trajectories,
                    snapshot_every: snapshots,
                },
                scale_v_per_pa: scale,
            };
            match aepipe::sim::run_job(&job) {
                Ok(lines) => {
                    for l in lines {
                        println!("{l}");
                    }
                    ExitCode::SUCCESS
                }
                Err(
                    e @ (aepipe::sim::SimError::Model(_) | aepipe::sim::SimError::Parse { .. }),
                ) => {
                    eprintln!("aepipe: {e}");
                    ExitCode::from(1)
                }
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    ExitCode::from(3)
                }
            }
        }
        Cmd::Reference {
            config,
            out,
            threads,
        } => {
            use aepipe::sim::reference::{build_library, ReferenceFile};
            let f = match ReferenceFile::read(&config) {
                Ok(f) => f,
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    return ExitCode::from(1);
                }
            };
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
            let run = || build_library(&f.reference, &out, true);
            let r = match pool {
                Ok(p) => p.install(run),
                Err(_) => run(),
            };
            match r {
                Ok((runs, n, secs)) => {
                    println!(
                        "{runs} simulations, {n} labelled signals → {} in {secs:.1} s",
                        out.join("waveforms.parquet").display()
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    ExitCode::from(3)
                }
            }
        }
        Cmd::Run {
            pipeline,
            inputs,
            out,
            truth,
            threads,
        } => {
            let cfg = match load_config(Some(&pipeline)) {
                Ok(c) => c,
                Err(code) => return code,
            };
            let job = aepipe::workflow::Job {
                config: &cfg,
                inputs: &inputs,
                out: &out,
                truth: truth.as_deref(),
                threads,
                progress: true,
            };
            match aepipe::workflow::run(&job) {
                Ok(s) => {
                    for l in aepipe::workflow::headline(&s) {
                        println!("{l}");
                    }
                    if cfg.report.enabled {
                        println!("report: {}", out.join("report.html").display());
                    }
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    ExitCode::from(3)
                }
            }
        }
        Cmd::Report { run_dir } => match aepipe::workflow::rebuild_report(&run_dir) {
            Ok(p) => {
                println!("report: {}", p.display());
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("aepipe: {e}");
                ExitCode::from(1)
            }
        },
        Cmd::SynthExperiment {
            out,
            hits,
            seed,
            library,
            id,
        } => match aepipe::synth::synth_experiment(&out, &id, hits, seed, library.as_deref(), true)
        {
            Ok(s) => {
                println!("{s}");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("aepipe: {e}");
                ExitCode::from(3)
            }
        },
        Cmd::Demo {
            out,
            hits,
            seed,
            threads,
        } => match aepipe::demo::run_demo(&out, hits, seed, threads) {
            Ok(d) => {
                println!("aepipe demo: synthetic notched-paper experiment built from simulated reference signals");
                println!("{}\n", d.synth);
                for s in &d.inspect {
                    println!("{s}");
                }
                print_run(&d.run.features, "features");
                println!();
                for l in aepipe::workflow::headline(&d.run) {
                    println!("{l}");
                }
                println!("report: {}", out.join("run/report.html").display());
                println!("\ndemo finished in {:.1} s", d.seconds);
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("aepipe: {e}");
                ExitCode::from(3)
            }
        },
        Cmd::Bench {
            which:
                BenchCmd::Sim {
                    masses,
                    steps,
                    repeats,
                },
        } => {
            let rows = match aepipe::bench::sim_scale(&masses, steps) {
                Ok(r) => r,
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    return ExitCode::from(3);
                }
            };
            println!(
                "implicit Euler on random fibre networks (Δt 10 ns, {steps} steps, 1 thread):"
            );
            println!(
                "{:>8} {:>8} {:>10} {:>14} {:>13} {:>22}",
                "masses",
                "springs",
                "ms/step",
                "µs/step/1k sp",
                "BiCGSTAB it",
                "ns/spring/iteration"
            );
            for r in &rows {
                println!(
                    "{:>8} {:>8} {:>10.3} {:>14.2} {:>13.1} {:>22.2}",
                    r.masses,
                    r.springs,
                    r.seconds_per_step * 1e3,
                    r.seconds_per_step * 1e6 / (r.springs as f64 / 1e3),
                    r.solver_iterations_per_step,
                    r.seconds_per_step * 1e9
                        / (r.springs as f64 * r.solver_iterations_per_step.max(1.0))
                );
            }
            match aepipe::bench::sim_mesh(repeats) {
                Ok(t) => println!("mesh3x3-bond-failure, 250×250 grid, 40 µs (relaxation + 4 000 implicit steps + 400 FDTD steps): median {t:.3} s"),
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    return ExitCode::from(3);
                }
            }
            ExitCode::SUCCESS
        }
        Cmd::Bench {
            which:
                BenchCmd::Som {
                    inputs,
                    peers,
                    python,
                    repeats,
                },
        } => {
            let (t, qe, te) = match aepipe::bench::som_bench(&inputs, repeats) {
                Ok(r) => r,
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    return ExitCode::from(1);
                }
            };
            println!("aepipe SOM (1 thread): median {t:.4} s, QE {qe:.4}, TE8 {te:.4}");
            if let Some(peers) = peers {
                match aepipe::bench::run_minisom(&python, &peers) {
                    Ok((pt, pqe)) => println!("MiniSom (same run): median {pt:.4} s, QE {pqe:.4} -> aepipe is {:.1}x faster, QE {:+.2} %", pt / t, (qe / pqe - 1.0) * 100.0),
                    Err(e) => println!("MiniSom failed: {e}"),
                }
            }
            ExitCode::SUCCESS
        }
        Cmd::Bench {
            which:
                BenchCmd::Cwt {
                    inputs,
                    peers,
                    python,
                    threads,
                    repeats,
                    skip_full,
                },
        } => {
            let ours = match aepipe::bench::cwt_bench(&inputs, &threads, repeats, skip_full) {
                Ok(r) => r,
                Err(e) => {
                    eprintln!("aepipe: {e}");
                    return ExitCode::from(1);
                }
            };
            println!(
                "{:<72} {:>7} {:>9} {:>11}",
                "aepipe (651 signals × 4096 samples)", "threads", "median s", "ms/signal"
            );
            for r in &ours {
                println!(
                    "{:<72} {:>7} {:>9.3} {:>11.3}",
                    r.what, r.threads, r.seconds, r.per_signal_ms
                );
            }
            if let Some(peers) = peers {
                let find = |prefix: &str, t: usize| {
                    ours.iter()
                        .find(|r| r.what.starts_with(prefix) && r.threads == t)
                        .map(|r| r.seconds)
                };
                println!(
                    "\n{:<40} {:>9} {:>34}",
                    "peer (same inputs, same run)", "median s", "peer / aepipe (same threads)"
                );
                let jobs: [(&str, &str, &[&str], &str, usize); 5] = [
                    (
                        "fCWT 0.1.18 f32, 1 thread",
                        "w1_cwt.py",
                        &["--peer", "fcwt", "--threads", "1"],
                        "W1",
                        1,
                    ),
                    (
                        "fCWT 0.1.18 f32 + wisdom, 2 threads",
                        "w1_cwt.py",
                        &["--peer", "fcwt_opt", "--threads", "2"],
                        "W1",
                        2,
                    ),
                    (
                        "numpy.fft baseline c128, 1 thread",
                        "w1_cwt.py",
                        &["--peer", "numpy", "--threads", "1"],
                        "W1",
                        1,
                    ),
                    (
                        "scipy.fft c64, 1 thread",
                        "w1_cwt.py",
                        &["--peer", "scipy_f32", "--threads", "1"],
                        "W1",
                        1,
                    ),
                    (
                        "W2 numpy rfft batched",
                        "w2_spectrum.py",
                        &["--peer", "numpy_rfft"],
                        "W2",
                        1,
                    ),
                ];
                for (name, script, args, w, t) in jobs {
                    match aepipe::bench::run_peer(&python, &peers, script, args) {
                        Ok(secs) => {
                            let ratio = find(w, t)
                                .map(|o| format!("{:.2}x", secs / o))
                                .unwrap_or_else(|| "–".into());
                            println!("{name:<40} {secs:>9.3} {ratio:>34}");
                        }
                        Err(e) => println!("{name:<40} failed: {e}"),
                    }
                }
            }
            ExitCode::SUCCESS
        }
        Cmd::Bench {
            which:
                BenchCmd::Stream {
                    hits,
                    samples,
                    threads,
                    out,
                },
        } => {
            println!("streaming synthetic hits of {samples} samples through the feature pipeline (threads: {})", if threads == 0 { aepipe::pipeline::num_cpus() } else { threads });
            println!(
                "{:>10} {:>10} {:>12} {:>14}",
                "hits", "seconds", "hits/s", "peak RSS MiB"
            );
            let mut sizes = vec![hits / 100, hits / 10, hits];
            sizes.retain(|&n| n > 0);
            sizes.dedup();
            for n in sizes {
                match aepipe::bench::stream_point(n, samples, threads, &out) {
                    Ok(p) => println!(
                        "{:>10} {:>10.2} {:>12.0} {:>14.1}",
                        p.hits, p.seconds, p.hits_per_s, p.peak_rss_mb
                    ),
                    Err(e) => {
                        eprintln!("aepipe: {e}");
                        return ExitCode::from(3);
                    }
                }
            }
            ExitCode::SUCCESS
        }
    }
}
