//! The command line: the argument structs (clap, parsed in one place), the dispatch to the
//! library, the terminal printing, and the one map from an error to an exit code
//! ([`exit_code`], the README's table). `main.rs` only parses and calls [`dispatch`].

mod commands;
mod exit;
mod print;

pub use commands::{dispatch, Outcome};
pub use exit::{exit_code, UsageError};

use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "aepipe",
    version,
    about = "Acoustic-emission recordings of paper tensile tests -> Parquet features, trends, classes, reports"
)]
pub struct Cli {
    #[command(subcommand)]
    pub cmd: Cmd,
}

#[derive(clap::Args)]
pub struct RunArgs {
    /// Files or folders (searched recursively): Vallen .pridb/.tradb, AEwin, WaveExplorer, WAV, CSV, text, waveforms.parquet
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Output folder
    #[arg(long)]
    pub out: PathBuf,
    /// Pipeline definition (TOML, see pipelines/)
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Worker threads (0 = all cores)
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Exit with code 2 when any hit or file was rejected
    #[arg(long)]
    pub strict: bool,
    /// No progress bar
    #[arg(long)]
    pub quiet: bool,
    /// Reuse the per-experiment parts of an earlier, interrupted or partial run in --out
    /// that are finished and unchanged (tool, config, input and table hashes); redo the rest
    #[arg(long)]
    pub resume: bool,
    /// Do shard K of N (0 ≤ K < N): the experiments whose id hashes to K, written as a
    /// Hive-partitioned dataset (OUT/<table>/experiment=<id>/part-K.parquet) plus
    /// OUT/shards/shard-K-of-N.json; `aepipe merge OUT` assembles the batch
    #[arg(long)]
    pub shard: Option<crate::util::Shard>,
}

#[derive(Subcommand)]
pub enum Cmd {
    /// Convert recordings into the canonical waveform table DIR/waveforms.parquet
    Waveforms(RunArgs),
    /// Run the streaming feature pipeline: DIR/features.parquet, rejects.parquet, manifest.json
    Features(RunArgs),
    /// Summarise experiments: format, channels, hits, rates, lengths, time span, load/extension
    ///
    /// Text files are recognised by what they hold (Vallen TXT exports, AEwin waveform exports
    /// with or without a header, WaveExplorer exports, CSV, one value per line); the name
    /// only breaks ties, and `[ingest] format` forces a format. Every file passed over is
    /// listed with what was seen in it (first line, columns, numeric lines), what it
    /// resembles, and which format or `[ingest]` keys would read it; the manifest keeps the
    /// same line. Exit 1 when nothing can be read.
    Inspect {
        #[arg(required = true)]
        paths: Vec<PathBuf>,
        /// Pipeline TOML whose `[ingest]` (format, rates, gains) applies
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
        cutoff: crate::config::Cutoff,
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
        #[arg(long = "param", value_parser = crate::sim::scenario::Params::parse_one)]
        params: Vec<(String, f64)>,
        /// Run once per integer value: key=LO..HI (e.g. point=1..12), one hit each
        #[arg(long)]
        sweep: Option<String>,
        /// implicit-euler (the default), explicit-euler, rk4 or verlet
        #[arg(long)]
        solver: Option<crate::sim::model::Solver>,
        #[arg(long)]
        out: PathBuf,
        /// Write node trajectories every N mass/spring steps (DIR/trajectories.parquet)
        #[arg(long)]
        trajectories: Option<usize>,
        /// Write a pressure-field PNG every N acoustic steps (DIR/snapshots/)
        #[arg(long)]
        snapshots: Option<usize>,
        /// Sensor sensitivity, V/Pa (samples_v = pressure × this)
        #[arg(long, default_value_t = 3e-5)]
        scale: f64,
        /// Trigger threshold of the simulated AE system, dB_AE
        #[arg(long, default_value_t = 40.0)]
        threshold_db: f64,
        /// RMS of the white noise added to the samples, dB_AE (≤ −100: none)
        #[arg(long, default_value_t = 26.0)]
        noise_db: f64,
        /// Samples recorded before the trigger
        #[arg(long, default_value_t = 500)]
        pretrigger: usize,
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
        /// Simulate shard K of N of the scenario grid (by a hash of the grid index) into
        /// OUT/waveforms/experiment=reference/part-K.parquet; `aepipe merge OUT` joins them
        #[arg(long)]
        shard: Option<crate::util::Shard>,
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
        /// Inputs (files or folders). Without --config the first one is the pipeline
        /// definition (the older positional form: `aepipe run PIPELINE.toml INPUT…`)
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Pipeline definition (pipelines/notched-paper.toml, pipelines/demo.toml, …)
        #[arg(long)]
        config: Option<PathBuf>,
        #[arg(long)]
        out: PathBuf,
        /// Ground truth (truth.parquet of `aepipe synth-experiment`) to score the classes
        #[arg(long)]
        truth: Option<PathBuf>,
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Reuse the finished, unchanged per-experiment parts of an earlier run in --out
        /// (after a crash or kill, or with experiments added); redo the rest
        #[arg(long)]
        resume: bool,
        /// Do shard K of N (a Slurm array task: $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT):
        /// the features of the experiments whose id hashes to K, as a Hive-partitioned
        /// dataset in --out; `aepipe merge` then runs trend, SOM and report on all N
        #[arg(long)]
        shard: Option<crate::util::Shard>,
        /// The features column the map's classes are checked against (and, with
        /// `[som] train_on = "criteria"`, trained on): any column, e.g. criteria_label,
        /// label, experiment, channel (overrides `[som] label`)
        #[arg(long)]
        label: Option<String>,
    },
    /// Check the N shards of a sharded run folder (all present, one config and version) and
    /// run the whole-batch stages on their union: OUT/features/, trend, SOM, report — the
    /// outputs an unsharded `aepipe run` writes
    Merge {
        /// The --out folder of the `aepipe run --shard K/N` tasks
        dir: PathBuf,
        /// Where to write the merged run (default: DIR/merged)
        #[arg(long)]
        out: Option<PathBuf>,
        /// Ground truth (truth.parquet of `aepipe synth-experiment`) to score the classes
        #[arg(long)]
        truth: Option<PathBuf>,
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Only the whole-batch tables and manifest, in OUT itself (the shards of
        /// `aepipe features|waveforms --shard`): no trend, SOM or report
        #[arg(long)]
        tables_only: bool,
    },
    /// Follow a test while it runs: new files in the inputs (one hit per file: each file
    /// once its size is stable; a whole recording once all its files are) are read,
    /// featured and classified every `[live] flush_s`, written as Hive parts in OUT
    /// (OUT/features/experiment=ID/part-N.parquet, hits, rejects, classification) and
    /// committed, exactly once across a kill and restart; OUT/live.html reloads itself.
    /// Ctrl-C (or SIGTERM) flushes and exits 0
    Watch {
        /// Files or folders the acquisition writes into
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// The watcher's folder: the Hive parts, live.html, watch/state.json, and at the
        /// end final/ (the same command again continues it)
        #[arg(long)]
        out: PathBuf,
        /// Pipeline definition (the defaults without)
        #[arg(long)]
        config: Option<PathBuf>,
        /// The map to classify with (an `aepipe som train` folder); without it `[som]
        /// model`, else a map trained on the configured reference library at start
        #[arg(long)]
        model: Option<PathBuf>,
        /// End after this many seconds without new data, then run the finished files as
        /// `aepipe run` does into OUT/final
        #[arg(long)]
        until_idle: Option<f64>,
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
pub enum InitArg {
    Samples,
    Random,
    Linear,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum ReadErroneousArg {
    QualityCheck,
    Map,
}

impl From<ReadErroneousArg> for crate::config::ReadErroneous {
    fn from(a: ReadErroneousArg) -> Self {
        match a {
            ReadErroneousArg::QualityCheck => crate::config::ReadErroneous::QualityCheck,
            ReadErroneousArg::Map => crate::config::ReadErroneous::Map,
        }
    }
}

#[derive(Subcommand)]
pub enum SomCmd {
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
        #[arg(long, default_value_t = crate::config::som_defaults::FRACTION)]
        fraction: f64,
        /// Standardise each dimension (z-score on the training set)
        #[arg(long)]
        standardise: bool,
        #[arg(long, default_value_t = crate::config::som_defaults::ROWS)]
        rows: usize,
        #[arg(long, default_value_t = crate::config::som_defaults::COLS)]
        cols: usize,
        #[arg(long, default_value_t = crate::config::som_defaults::SEED)]
        seed: u64,
        /// Initial codebook: random training vectors, uniform random, or linear (PCA plane)
        #[arg(long, value_enum, default_value_t = InitArg::Samples)]
        init: InitArg,
    },
    /// Classify every hit: DIR/classification.parquet, the Table 5.4 confusion report, hit maps
    Classify {
        /// The model: its folder, its model.json, or a SOM_PAK .cod beside a model.json
        model: PathBuf,
        #[arg(required = true)]
        features: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
        /// Reference column for the confusion report, any column of the table (default: the
        /// model's label column)
        #[arg(long, visible_alias = "label")]
        reference: Option<String>,
        /// How the map's erroneous area is read: quality-check (erroneous iff the features'
        /// quality_fault is set; a sound hit on an erroneous node takes its nearest other
        /// node's class) or map (the BMU's label alone, as the thesis)
        #[arg(long, value_enum, default_value_t = ReadErroneousArg::QualityCheck)]
        read_erroneous: ReadErroneousArg,
    },
    /// Summarise a model and draw its U-matrix with node labels
    Show {
        /// The model: its folder, its model.json, or a SOM_PAK .cod beside a model.json
        model: PathBuf,
        #[arg(long)]
        png: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
pub enum BenchCmd {
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
        /// Fixed record length (10 MHz)
        #[arg(long, default_value_t = 4096)]
        samples: usize,
        /// Fixed-length records without a pretrigger
        #[arg(long)]
        no_pretrigger: bool,
        /// Variable record lengths like a Vallen LinWave test (2 250–220 000 samples, 5 MHz)
        /// instead of fixed ones
        #[arg(long)]
        linwave: bool,
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Where to write the (small) feature tables
        #[arg(long, default_value = "target/bench-stream")]
        out: PathBuf,
    },
    /// The whole-batch stages (trend, classification, damage profile, report) on a study of
    /// N feature rows made by repeating the demo's run: time and peak RSS per stage
    Analysis {
        /// Feature rows of the study
        #[arg(long, default_value_t = 100_000)]
        rows: u64,
        /// Experiments the rows are spread over (default: one per repetition of the demo's
        /// 1 302 rows)
        #[arg(long)]
        experiments: Option<u64>,
        /// A demo folder already written (`aepipe demo --out DIR`); default: OUT/base, built
        /// once and reused
        #[arg(long)]
        base: Option<PathBuf>,
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Where to write the study's run folder (OUT/run) and the base
        #[arg(long, default_value = "target/bench-analysis")]
        out: PathBuf,
    },
    /// `aepipe watch` following a folder that receives WAV hits at a steady rate and then a
    /// burst: each hit's lag from its file's last write to its row committed, median and p99
    Watch {
        /// Hits per second of the steady phase
        #[arg(long, default_value_t = 500.0)]
        rate: f64,
        /// Seconds of the steady phase
        #[arg(long, default_value_t = 20.0)]
        seconds: f64,
        /// Hits arriving at once after it (the final break): written beforehand beside the
        /// folder and moved in, each stamped with its arrival
        #[arg(long, default_value_t = 20_000)]
        burst: usize,
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Where the acquisition and the watcher's folder go (removed first)
        #[arg(long, default_value = "target/bench-watch")]
        out: PathBuf,
        /// The acquisition is a Vallen pair the writer appends to (two channels per source,
        /// transients, a load channel) instead of a folder of WAV files
        #[arg(long)]
        vallen: bool,
    },
}
