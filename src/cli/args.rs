//! Every command's arguments, parsed in one place (clap): one struct per command, handed on
//! whole to its function in [`super::commands`]. Arguments several commands take are one
//! struct flattened into theirs ([`JobArgs`]), never declared twice.

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

/// A job over recordings (`features`, `waveforms`, `run`): inputs, output folder, pipeline,
/// threads, resume and shard.
#[derive(clap::Args)]
pub struct JobArgs {
    /// Files or folders (searched recursively): Vallen .pridb/.tradb, Vallen TXT exports,
    /// MISTRAS .DTA, AEwin, WaveExplorer, WAV, CSV, text, waveforms.parquet. For `aepipe run`
    /// without --config, the first one is the pipeline definition (the older positional
    /// form: `aepipe run PIPELINE.toml INPUT…`)
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Output folder
    #[arg(long)]
    pub out: PathBuf,
    /// Pipeline definition (TOML, see pipelines/: notched-paper.toml, demo.toml, …)
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Worker threads (0 = all cores)
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Reuse the finished, unchanged per-experiment parts (tool, config, input and table
    /// hashes) of an earlier run in --out (after a crash or kill, or with experiments
    /// added); redo the rest
    #[arg(long)]
    pub resume: bool,
    /// Do shard K of N (0 ≤ K < N; a Slurm array task: $SLURM_ARRAY_TASK_ID/
    /// $SLURM_ARRAY_TASK_COUNT): the experiments whose id hashes to K, written as a
    /// Hive-partitioned dataset (OUT/<table>/experiment=<id>/part-K.parquet) plus
    /// OUT/shards/shard-K-of-N.json; `aepipe merge OUT` assembles the batch (and, after
    /// `aepipe run`, runs trend, SOM and report on all N)
    #[arg(long)]
    pub shard: Option<crate::util::Shard>,
}

/// `aepipe features` and `aepipe waveforms`.
#[derive(clap::Args)]
pub struct StreamArgs {
    #[command(flatten)]
    pub job: JobArgs,
    /// Exit with code 2 when any hit or file was rejected
    #[arg(long)]
    pub strict: bool,
    /// No progress bar
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Subcommand)]
pub enum Cmd {
    /// Convert recordings into the canonical waveform table DIR/waveforms.parquet
    Waveforms(StreamArgs),
    /// Run the streaming feature pipeline: DIR/features.parquet, rejects.parquet, manifest.json
    Features(StreamArgs),
    /// Summarise experiments: format, channels, hits, rates, lengths, time span, load/extension
    ///
    /// Text files are recognised by what they hold (Vallen TXT exports, AEwin waveform exports
    /// with or without a header, WaveExplorer exports, CSV, one value per line); the name
    /// only breaks ties, and `[ingest] format` forces a format. Every file passed over is
    /// listed with what was seen in it (first line, columns, numeric lines), what it
    /// resembles, and which format or `[ingest]` keys would read it; the manifest keeps the
    /// same line. Exit 1 when nothing can be read.
    Inspect(InspectArgs),
    /// Draw one hit's waveform and full-resolution CWT into a PNG
    Cwt(CwtArgs),
    /// Trend statistics (ch. 4.5.5): r, p, slope, intercept of each power ratio vs AE number
    Trend(TrendArgs),
    /// Self-organising map (ch. 5): train, classify, show
    #[command(subcommand)]
    Som(SomCmd),
    /// Cluster hits by their own z-scored features (k-means++, Gaussian mixtures, or a SOM's
    /// codebook clustered), k chosen by a validity index: DIR/clusters.parquet,
    /// validity.parquet, model.json, validity.png
    Cluster(ClusterArgs),
    /// The AE energy's power law per experiment (Clauset et al. 2009: α by maximum
    /// likelihood, x_min by the Kolmogorov–Smirnov distance): DIR/statistics.parquet
    Statistics(StatisticsArgs),
    /// Print the column table of an output table (features, waveforms, rejects, trend, classification)
    Schema(SchemaArgs),
    /// Simulate AEs with the hybrid mass/spring + acoustic model (ch. 3–4): DIR/waveforms.parquet
    Simulate(SimulateArgs),
    /// Build the labelled reference library: the simulator over a grid of scenarios, in
    /// parallel, into DIR/waveforms.parquet
    Reference(ReferenceArgs),
    /// A synthetic notched-paper test built from reference-library signals: DIR/<id>.pridb,
    /// .tradb (Vallen) and DIR/truth.parquet
    SynthExperiment(SynthExperimentArgs),
    /// The whole method from a pipeline definition: features → trend → SOM → classification →
    /// DIR/report.html
    Run(RunArgs),
    /// Check the N shards of a sharded run folder (all present, one config and version) and
    /// run the whole-batch stages on their union: OUT/features/, trend, SOM, report — the
    /// outputs an unsharded `aepipe run` writes
    Merge(MergeArgs),
    /// Follow a test while it runs: new files in the inputs (one hit per file: each file
    /// once its size is stable; a whole recording once all its files are) are read,
    /// featured and classified every `[live] flush_s`, written as Hive parts in OUT
    /// (OUT/features/experiment=ID/part-N.parquet, hits, rejects, classification) and
    /// committed, exactly once across a kill and restart; OUT/live.html reloads itself.
    /// Ctrl-C (or SIGTERM) flushes and exits 0
    Watch(WatchArgs),
    /// Write RUN_DIR/report.html again from a finished `aepipe run` folder
    Report(ReportArgs),
    /// The thesis's computed results by one command: each entry (fig-3.14, table-3.8, …)
    /// runs what the thesis ran, writes OUT/ID/ (PNG and Parquet) and prints aepipe's value
    /// beside the thesis's, with the tolerance and a verdict (docs/thesis.md)
    Thesis(ThesisArgs),
    /// Write a finished run's results back for the lab's tools
    #[command(subcommand)]
    Export(ExportCmd),
    /// Make a synthetic experiment and run the pipeline on it (the README's first command)
    Demo(DemoArgs),
    /// Benchmarks (print numbers, never pass/fail)
    #[command(subcommand)]
    Bench(BenchCmd),
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum InitArg {
    Samples,
    Random,
    Linear,
}

#[derive(Subcommand)]
pub enum SomCmd {
    /// Train a map on a balanced ~10 % of the labelled hits (ch. 5.4): MODEL_DIR/model.json, model.cod, train.dat, u_matrix.png
    Train(SomTrainArgs),
    /// Classify every hit: DIR/classification.parquet, the Table 5.4 confusion report, hit maps
    Classify(SomClassifyArgs),
    /// Summarise a model and draw its U-matrix with node labels
    Show(SomShowArgs),
}

#[derive(Subcommand)]
pub enum BenchCmd {
    /// Simulator scale: implicit steps of random fibre networks (cost per spring), and the
    /// mesh3x3-bond-failure scenario with its 250×250 grid over 40 µs
    Sim(BenchSimArgs),
    /// W3 SOM training (651 × 200-D, 10×10, Table 5.2 schedule, the peers' initial codebook);
    /// with --peers, MiniSom in the same run
    Som(BenchSomArgs),
    /// W1 CWT + feature path + W2 spectrum on the peers' exact inputs; with --peers, runs
    /// fCWT, the numpy baseline and numpy rfft in the same run and prints the ratios
    Cwt(BenchCwtArgs),
    /// Stream synthetic hits through the feature pipeline: hits/s and peak RSS at growing hit counts
    Stream(BenchStreamArgs),
    /// The whole-batch stages (trend, classification, damage profile, report) on a study of
    /// N feature rows made by repeating the demo's run: time and peak RSS per stage
    Analysis(BenchAnalysisArgs),
    /// `aepipe cluster` (k-means, Gaussian mixture) against scikit-learn's KMeans and
    /// GaussianMixture on the same matrix of N rows × 20 columns, each a whole process:
    /// time and peak RSS in the same run
    Cluster(BenchClusterArgs),
    /// `aepipe watch` following a folder that receives WAV hits at a steady rate and then a
    /// burst: each hit's lag from its file's last write to its row committed, median and p99
    Watch(BenchWatchArgs),
    /// The `[detect]` stage alone on int16 streams in memory (MS/s per core, × real time
    /// at 10 MHz), then `aepipe features` on stream WAVs of growing length (hits/s, × real
    /// time, peak RSS)
    Detect(BenchDetectArgs),
    /// The report's explorable charts at growing numbers of feature rows: the page's size,
    /// the time to build it, and in headless Chromium the time to first paint and to load
    Report(BenchReportArgs),
    /// Leave one model family out: for each family (plane, 3-D) and each measurement chain, a
    /// map trained on the other families classifies a test made from the one left out,
    /// heard through the chain, at evaluation seeds; the map's and the ch. 4.7 criteria
    /// label's recalls to the terminal and OUT/transfer.parquet
    Transfer(BenchTransferArgs),
}

#[derive(clap::Args)]
pub struct BenchTransferArgs {
    /// Folder for the libraries, tests, runs and transfer.parquet
    #[arg(long)]
    pub out: PathBuf,
    /// Sources of each synthetic test
    #[arg(long, default_value_t = 651)]
    pub hits: usize,
    /// Evaluation seeds, comma-separated (each test library's material draws and the
    /// test's own); never used to choose anything
    #[arg(long, value_delimiter = ',', default_values_t = crate::workflow::transfer::EVALUATION_SEEDS)]
    pub seeds: Vec<u64>,
    /// Chains by name, comma-separated (default: every chain of the file)
    #[arg(long, value_delimiter = ',')]
    pub chains: Vec<String>,
    /// Chains file (default: the embedded pipelines/chains.toml)
    #[arg(long)]
    pub chain_file: Option<PathBuf>,
    /// Material draws per grid point of the training libraries (default: each library
    /// file's own)
    #[arg(long)]
    pub train_variants: Option<usize>,
    /// Material draws per grid point of each test's library
    #[arg(long, default_value_t = 1)]
    pub test_variants: usize,
    /// The tests' mechanism mix, by the truth's mechanism names (as synth-experiment's)
    #[arg(long, default_value = crate::workflow::transfer::SHARES)]
    pub shares: crate::synth::Shares,
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Make the maps and libraries anew (in OUT/cache, each map once) instead of reusing
    /// the user's cached ones
    #[arg(long)]
    pub no_cache: bool,
}

#[derive(clap::Args)]
pub struct BenchReportArgs {
    /// Feature rows, comma-separated
    #[arg(long, value_delimiter = ',', default_value = "10000,100000,1000000")]
    pub rows: Vec<usize>,
    /// Scratch folder
    #[arg(long, default_value = "bench-report")]
    pub dir: PathBuf,
    /// Python with websocket-client, and Chromium on the PATH: the browser's times (none:
    /// the size and build time alone)
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// The whole report (`aepipe report` on a synthetic run holding that many feature rows:
    /// trend, classes, clusters and pictures redone), not the explorable charts alone
    #[arg(long)]
    pub whole: bool,
}

#[derive(clap::Args)]
pub struct BenchDetectArgs {
    /// Threads (one 10 MHz channel each for the stage alone)
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Seconds of stream per channel for the stage alone (held in memory)
    #[arg(long, default_value_t = 5.0)]
    pub stage_seconds: f64,
    /// Stream lengths for the whole runs, s, comma-separated (2 bytes × 10 MHz each; 0: the
    /// stage alone)
    #[arg(long, value_delimiter = ',', default_value = "10,100")]
    pub seconds: Vec<f64>,
    /// Scratch folder for the stream files and outputs
    #[arg(long, default_value = "bench-detect")]
    pub dir: PathBuf,
    /// Python with NumPy: the same cut done the NumPy way on the same stream, in the same
    /// run (none: aepipe alone)
    #[arg(long)]
    pub python: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct InspectArgs {
    #[arg(required = true)]
    pub paths: Vec<PathBuf>,
    /// Pipeline TOML whose `[ingest]` (format, rates, gains) applies
    #[arg(long)]
    pub config: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct CwtArgs {
    /// Files or folders holding the hit
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Hit number (Vallen TRAI, AEwin hit #, event #)
    #[arg(long)]
    pub hit: u64,
    /// Channel (default: the first channel that has this hit)
    #[arg(long)]
    pub channel: Option<u32>,
    /// Experiment id (default: the first experiment that has this hit)
    #[arg(long)]
    pub experiment: Option<String>,
    #[arg(long)]
    pub png: PathBuf,
    #[arg(long)]
    pub config: Option<PathBuf>,
}

#[derive(Subcommand)]
pub enum ExportCmd {
    /// Per Vallen experiment a VisualAE transient-feature database
    /// DIR/<experiment>.aepipe.trfdb keyed by TRAI (SOM class, cluster, criteria label,
    /// novelty, quantization error, crack mode, RA, AF, event, zone, location, the 25 power
    /// ratios, with units and names in its field info); per experiment of another system
    /// DIR/<experiment>.aepipe.csv keyed by aepipe's hit, with the system's hit number
    Trfdb(ExportTrfdbArgs),
}

#[derive(clap::Args)]
pub struct ExportTrfdbArgs {
    /// A finished `aepipe run` folder
    pub run_dir: PathBuf,
    /// Where to write (default RUN_DIR/export)
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace aepipe's own earlier export of the same name (never the lab's .trfdb: the
    /// name says it is aepipe's)
    #[arg(long)]
    pub force: bool,
}

#[derive(clap::Args)]
pub struct StatisticsArgs {
    /// features.parquet (or hits.parquet) files with energy_eu
    #[arg(required = true)]
    pub features: Vec<PathBuf>,
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(clap::Args)]
pub struct ClusterArgs {
    /// features.parquet files
    #[arg(required = true)]
    pub features: Vec<PathBuf>,
    #[arg(long)]
    pub out: PathBuf,
    /// A pipeline TOML whose [cluster] gives the defaults the flags below override
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// kmeans | gmm | som-kmeans (as [cluster] method)
    #[arg(long, value_parser = serde_choice::<crate::cluster::Method>)]
    pub method: Option<crate::cluster::Method>,
    /// The number of clusters, or a range tried (2..8)
    #[arg(long, value_parser = crate::cluster::settings::parse_k)]
    pub k: Option<(usize, usize)>,
    /// Feature columns, comma-separated (default: the usual hit features, RA, AF, peak and
    /// centroid frequency and the power ratios; tf_bins adds the 200 bins)
    #[arg(long, value_delimiter = ',')]
    pub columns: Vec<String>,
    /// davies-bouldin | silhouette | calinski-harabasz | bic: how k is chosen (as [cluster] choose)
    #[arg(long, value_parser = serde_choice::<crate::cluster::Choose>)]
    pub choose: Option<crate::cluster::Choose>,
    #[arg(long)]
    pub seed: Option<u64>,
    /// k-means restarts
    #[arg(long)]
    pub n_init: Option<usize>,
    /// Rows the fit sees (a seeded sample of a larger input; every row is assigned)
    #[arg(long)]
    pub max_fit_rows: Option<usize>,
}

#[derive(clap::Args)]
pub struct TrendArgs {
    /// features.parquet files
    #[arg(required = true)]
    pub features: Vec<PathBuf>,
    #[arg(long)]
    pub out: PathBuf,
    /// none | peak-load | time:SECONDS | hits:N
    #[arg(long, default_value = "peak-load")]
    pub cutoff: crate::config::Cutoff,
    /// Significance level
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// A load channel spanning less than this, N, or within its own noise, is no load: no
    /// peak-load cut (`[trend] min_load_span_n`)
    #[arg(long, default_value_t = 1.0)]
    pub min_load_span_n: f64,
    /// Fewest hits a trend is stated on; fewer: `n = 3: too few hits for a trend`, r and p
    /// null (`[trend] min_hits`)
    #[arg(long, default_value_t = crate::analysis::settings::MIN_TREND_HITS, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(3..))]
    pub min_hits: usize,
    /// Columns to test (default: every pr_* power ratio), e.g. peak_freq_hz,centroid_freq_hz
    #[arg(long, value_delimiter = ',')]
    pub columns: Vec<String>,
    /// Skip the PNG plots
    #[arg(long)]
    pub no_plots: bool,
}

#[derive(clap::Args)]
pub struct SchemaArgs {
    #[arg(default_value = "features")]
    pub table: String,
    #[arg(long)]
    pub config: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct ThesisArgs {
    /// Entries to run (none: every one)
    pub ids: Vec<String>,
    #[arg(long, default_value = "thesis")]
    pub out: PathBuf,
}

#[derive(clap::Args)]
pub struct SimulateArgs {
    /// Model file: the thesis's sectioned format (Appendix A) or .toml
    pub model: Option<PathBuf>,
    /// Built-in scenario instead of a file: sho, five-mass-fibre, fibre-single-constraint,
    /// fibre-multiple-constraints, two-fibres,
    /// rubber-band, paper-fibre, mesh3x3-bond-failure, mesh3x3-damaged-bond-failure,
    /// structure2x1-fibre-failure,
    /// fibre-stiff-string, and in 3-D network3d-bond-failure, network3d-fibre-failure
    #[arg(long)]
    pub scenario: Option<String>,
    /// Scenario parameter key=value (repeatable), e.g. point=7, stretch=0.01, dt=1e-8
    #[arg(long = "param", value_parser = crate::sim::scenario::Params::parse_one)]
    pub params: Vec<(String, f64)>,
    /// Run once per value, one hit each: key=LO..HI for integers (point=1..12) or
    /// key=LO..HI:STEP for real values (stretch=0.010..0.020:0.002); repeated, every
    /// combination. Writes DIR/sweep.parquet and DIR/sweep.png
    #[arg(long)]
    pub sweep: Vec<String>,
    /// implicit-euler (the default), explicit-euler, rk4 or verlet
    #[arg(long)]
    pub solver: Option<crate::sim::model::Solver>,
    #[arg(long)]
    pub out: PathBuf,
    /// Write node trajectories every N mass/spring steps (DIR/trajectories.parquet)
    #[arg(long)]
    pub trajectories: Option<usize>,
    /// Write a pressure-field PNG every N acoustic steps (DIR/snapshots/)
    #[arg(long)]
    pub snapshots: Option<usize>,
    /// Sensor sensitivity, V/Pa (samples_v = pressure × this)
    #[arg(long, default_value_t = 3e-5)]
    pub scale: f64,
    /// Trigger threshold of the simulated AE system, dB_AE
    #[arg(long, default_value_t = 40.0)]
    pub threshold_db: f64,
    /// RMS of the white noise added to the samples, dB_AE (≤ −100: none)
    #[arg(long, default_value_t = 26.0)]
    pub noise_db: f64,
    /// Samples recorded before the trigger
    #[arg(long, default_value_t = 500)]
    pub pretrigger: usize,
}

#[derive(clap::Args)]
pub struct ReferenceArgs {
    /// Library definition (see pipelines/reference-library.toml)
    #[arg(long, default_value = "pipelines/reference-library.toml")]
    pub config: PathBuf,
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Simulate shard K of N of the scenario grid (by a hash of the grid index) into
    /// OUT/waveforms/experiment=reference/part-K.parquet; `aepipe merge OUT` joins them
    #[arg(long)]
    pub shard: Option<crate::util::Shard>,
}

#[derive(clap::Args)]
pub struct SynthExperimentArgs {
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 651)]
    pub hits: usize,
    #[arg(long, default_value_t = 2026)]
    pub seed: u64,
    /// Reference library (waveforms.parquet of `aepipe reference`); default: build the
    /// embedded pipelines/reference-library.toml into DIR/reference
    #[arg(long)]
    pub library: Option<PathBuf>,
    #[arg(long, default_value = "synthetic_notched_paper")]
    pub id: String,
    /// Load–unload–reload cycles (2–9; 0: a monotonic test to failure). The designed cycles
    /// and where AE resumes on each reload go to DIR/truth_cycles.parquet
    #[arg(long, default_value_t = 0)]
    pub cycles: usize,
    /// Draw the sources' amplitudes so that the hits' energies follow a power law of this
    /// exponent (1.35–3), for `statistics.parquet` to recover
    #[arg(long)]
    pub energy_exponent: Option<f64>,
    /// The sources' mechanism mix, by the truth's mechanism names (a name not given is 0;
    /// the shares sum to 1), e.g. bond_failure=0.45,fibre_failure=0.35,both=0.1,erroneous=0.1
    /// for a test that holds enough fibre failures to measure their recall
    #[arg(long, default_value_t = crate::synth::Shares::default())]
    pub shares: crate::synth::Shares,
    /// Record the test through this measurement chain (a sensor's response and the
    /// preamplifier's band; default: flat, as the libraries are recorded), e.g. resonant-150k
    #[arg(long)]
    pub chain: Option<String>,
    /// Chains file for --chain (default: the embedded pipelines/chains.toml)
    #[arg(long, requires = "chain")]
    pub chain_file: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub job: JobArgs,
    /// Ground truth (truth.parquet of `aepipe synth-experiment`) to score the classes
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// The features column the map's classes are checked against (and, with
    /// `[som] train_on = "criteria"`, trained on): any column, e.g. criteria_label,
    /// label, experiment, channel (overrides `[som] label`)
    #[arg(long)]
    pub label: Option<String>,
    /// Make the reference map anew instead of reusing the one cached under the same settings
    /// ($XDG_CACHE_HOME/aepipe, else ~/.cache/aepipe)
    #[arg(long)]
    pub no_cache: bool,
}

#[derive(clap::Args)]
pub struct MergeArgs {
    /// The --out folder of the `aepipe run --shard K/N` tasks
    pub dir: PathBuf,
    /// Where to write the merged run (default: DIR/merged)
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Ground truth (truth.parquet of `aepipe synth-experiment`) to score the classes
    #[arg(long)]
    pub truth: Option<PathBuf>,
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Only the whole-batch tables and manifest, in OUT itself (the shards of
    /// `aepipe features|waveforms --shard`): no trend, SOM or report
    #[arg(long)]
    pub tables_only: bool,
}

#[derive(clap::Args)]
pub struct WatchArgs {
    /// Files or folders the acquisition writes into
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// The watcher's folder: the Hive parts, live.html, watch/state.json, and at the
    /// end final/ (the same command again continues it)
    #[arg(long)]
    pub out: PathBuf,
    /// Pipeline definition (the defaults without)
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The map to classify with (an `aepipe som train` folder); without it `[som]
    /// model`, else a map trained on the configured reference library at start
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// End after this many seconds without new data, then run the finished files as
    /// `aepipe run` does into OUT/final
    #[arg(long)]
    pub until_idle: Option<f64>,
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

#[derive(clap::Args)]
pub struct ReportArgs {
    pub run_dir: PathBuf,
}

#[derive(clap::Args)]
pub struct DemoArgs {
    /// Folder for the demo's data and outputs
    #[arg(long, default_value = "aepipe-demo")]
    pub out: PathBuf,
    #[arg(long, default_value_t = 651)]
    pub hits: usize,
    #[arg(long, default_value_t = 2026)]
    pub seed: u64,
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Skip asking the classes about another model's signals (a 3-D library, ~35 s)
    #[arg(long)]
    pub no_cross_model: bool,
    /// Write no HTML report (its ~8 s of pictures): the tables, run.json and the printed
    /// figures are the same
    #[arg(long)]
    pub no_report: bool,
    /// Make the reference maps anew instead of reusing the cached ones
    #[arg(long)]
    pub no_cache: bool,
}

#[derive(clap::Args)]
pub struct SomTrainArgs {
    #[arg(required = true)]
    pub features: Vec<PathBuf>,
    /// Column holding the training labels (criteria_label, or label for simulator truth)
    #[arg(long, default_value = crate::model::columns::CRITERIA_LABEL.name)]
    pub label: String,
    #[arg(long)]
    pub out: PathBuf,
    /// Feature columns (tf_bins expands to its 200 elements; numeric scalars add one each)
    #[arg(long, default_value = "tf_bins", value_delimiter = ',')]
    pub columns: Vec<String>,
    /// Share of the hits in the training set
    #[arg(long, default_value_t = crate::config::som_defaults::FRACTION)]
    pub fraction: f64,
    /// Standardise each dimension (z-score on the training set)
    #[arg(long)]
    pub standardise: bool,
    #[arg(long, default_value_t = crate::config::som_defaults::ROWS)]
    pub rows: usize,
    #[arg(long, default_value_t = crate::config::som_defaults::COLS)]
    pub cols: usize,
    #[arg(long, default_value_t = crate::config::som_defaults::SEED)]
    pub seed: u64,
    /// Initial codebook: random training vectors, uniform random, or linear (PCA plane)
    #[arg(long, value_enum, default_value_t = InitArg::Samples)]
    pub init: InitArg,
}

#[derive(clap::Args)]
pub struct SomClassifyArgs {
    /// The model: its folder, its model.json, or a SOM_PAK .cod beside a model.json
    pub model: PathBuf,
    #[arg(required = true)]
    pub features: Vec<PathBuf>,
    #[arg(long)]
    pub out: PathBuf,
    /// Reference column for the confusion report, any column of the table (default: the
    /// model's label column)
    #[arg(long, visible_alias = "label")]
    pub reference: Option<String>,
    /// How the map's erroneous area is read: quality-check (erroneous iff the features'
    /// quality_fault is set; a sound hit on an erroneous node takes its nearest other
    /// node's class) or map (the BMU's label alone, as the thesis)
    #[arg(long, default_value = "quality-check", value_parser = serde_choice::<crate::config::ReadErroneous>)]
    pub read_erroneous: crate::config::ReadErroneous,
    /// A hit farther from its node than this conformal quantile of the held-out references'
    /// distances is unlike_references (0 < q ≤ 1; checked as [som] novelty_quantile)
    #[arg(long, default_value_t = crate::som::settings::som_defaults::NOVELTY_QUANTILE)]
    pub novelty_quantile: f64,
}

/// A choice read by the words its serde form uses — the pipeline file's — so a flag and its
/// TOML key accept the same words and a new variant needs no second parser.
fn serde_choice<T: serde::de::DeserializeOwned>(s: &str) -> Result<T, String> {
    crate::util::from_serde_name(s).map_err(|e| e.to_string())
}

#[derive(clap::Args)]
pub struct SomShowArgs {
    /// The model: its folder, its model.json, or a SOM_PAK .cod beside a model.json
    pub model: PathBuf,
    #[arg(long)]
    pub png: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct BenchSimArgs {
    #[arg(long, default_value = "1000,2500,5000,10000", value_delimiter = ',')]
    pub masses: Vec<usize>,
    #[arg(long, default_value_t = 200)]
    pub steps: usize,
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Also Tables 3.2/3.4: the SHO and the five-mass fibre by each solver
    #[arg(long)]
    pub solvers: bool,
    /// Also the 3-D acoustic field at N³ cells, comma-separated (e.g. 96,192)
    #[arg(long, value_delimiter = ',')]
    pub field3d: Vec<usize>,
    /// Steps of the 3-D field per size
    #[arg(long, default_value_t = 50)]
    pub field3d_steps: usize,
    /// Also the 3-D scenarios and the plane fine-grid fibre failure end to end at these cell
    /// sizes, µm, comma-separated (e.g. 72,36): wall time and peak memory
    #[arg(long, value_delimiter = ',')]
    pub network3d: Vec<f64>,
    /// Instead: whether the embedded reference library's signals have converged — each
    /// reference at three grid spacings, three time steps and fibre splits 1/2/3, its dominant
    /// frequency and 25 power ratios per resolution (DIR/convergence.parquet), and the
    /// coarsest resolution per axis within 5 % / 0.02 of the next finer
    #[arg(long)]
    pub convergence: bool,
    /// Where --convergence writes its table
    #[arg(long, default_value = "convergence")]
    pub out: PathBuf,
}

#[derive(clap::Args)]
pub struct BenchClusterArgs {
    /// Row counts, comma-separated
    #[arg(long, value_delimiter = ',', default_value = "10000,100000,1000000")]
    pub rows: Vec<usize>,
    #[arg(long, default_value_t = 4)]
    pub k: usize,
    /// Python with scikit-learn and Polars; none: aepipe alone
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// Scratch folder for the matrices and outputs
    #[arg(long, default_value = "bench-cluster")]
    pub dir: PathBuf,
}

#[derive(clap::Args)]
pub struct BenchSomArgs {
    /// Folder written by the peers' export_inputs.py
    #[arg(long)]
    pub inputs: PathBuf,
    #[arg(long)]
    pub peers: Option<PathBuf>,
    #[arg(long, default_value = "python3")]
    pub python: PathBuf,
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
}

#[derive(clap::Args)]
pub struct BenchCwtArgs {
    /// Folder written by the peers' export_inputs.py (w1_signals_f32.bin, w1_freqs_hz_f64.bin)
    #[arg(long)]
    pub inputs: PathBuf,
    /// The peers' folder (../shared/bench/peers or a writable copy) to run them too
    #[arg(long)]
    pub peers: Option<PathBuf>,
    /// Python with the peers' packages (their setup_env.sh venv)
    #[arg(long, default_value = "python3")]
    pub python: PathBuf,
    #[arg(long, default_value = "1,2", value_delimiter = ',')]
    pub threads: Vec<usize>,
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Leave out the full-resolution CWT (2.5 GB output): feature path and spectrum only
    #[arg(long)]
    pub skip_full: bool,
}

#[derive(clap::Args)]
pub struct BenchStreamArgs {
    /// Largest number of hits; the benchmark also runs 1/10 and 1/100 of it first
    #[arg(long, default_value_t = 100_000)]
    pub hits: u64,
    /// Fixed record length (10 MHz)
    #[arg(long, default_value_t = 4096)]
    pub samples: usize,
    /// Fixed-length records without a pretrigger
    #[arg(long)]
    pub no_pretrigger: bool,
    /// Variable record lengths like a Vallen LinWave test (2 250–220 000 samples, 5 MHz)
    /// instead of fixed ones
    #[arg(long)]
    pub linwave: bool,
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Where to write the (small) feature tables
    #[arg(long, default_value = "target/bench-stream")]
    pub out: PathBuf,
}

#[derive(clap::Args)]
pub struct BenchAnalysisArgs {
    /// Feature rows of the study
    #[arg(long, default_value_t = 100_000)]
    pub rows: u64,
    /// Experiments the rows are spread over (default: one per repetition of the demo's
    /// 1 302 rows)
    #[arg(long)]
    pub experiments: Option<u64>,
    /// A demo folder already written (`aepipe demo --out DIR`); default: OUT/base, built
    /// once and reused
    #[arg(long)]
    pub base: Option<PathBuf>,
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Where to write the study's run folder (OUT/run) and the base
    #[arg(long, default_value = "target/bench-analysis")]
    pub out: PathBuf,
}

#[derive(clap::Args)]
pub struct BenchWatchArgs {
    /// Hits per second of the steady phase
    #[arg(long, default_value_t = 500.0)]
    pub rate: f64,
    /// Seconds of the steady phase
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Hits arriving at once after it (the final break): written beforehand beside the
    /// folder and moved in, each stamped with its arrival
    #[arg(long, default_value_t = 20_000)]
    pub burst: usize,
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Where the acquisition and the watcher's folder go (removed first)
    #[arg(long, default_value = "target/bench-watch")]
    pub out: PathBuf,
    /// The acquisition is a Vallen pair the writer appends to (two channels per source,
    /// transients, a load channel) instead of a folder of WAV files
    #[arg(long)]
    pub vallen: bool,
}
