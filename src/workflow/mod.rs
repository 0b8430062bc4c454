//! `aepipe run`: the whole staged method from one pipeline definition — features → trend →
//! SOM (trained on a reference library or on criteria-labelled hits) → classification →
//! accuracy against ground truth when there is one → the HTML report. Also the commands
//! that read inputs to draw (`aepipe cwt`) and rebuild a report from a run folder.

use crate::analysis::trend::{TrendError, TrendReport};
use crate::config::{ConfigError, PipelineConfig, ValidConfig};
use crate::pipeline::{PipelineError, RunReport, StreamOptions};
use crate::report::{Gallery, Gathered};
pub use crate::report::{RunSummary, SomStage, TruthScore};
use crate::som::classify::Confusion;
use crate::som::SomError;
use crate::store::{HitKey, StoreError, TableScan};
use crate::util::IoAt;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Why a run (or a report rebuild, or a drawing) failed; each stage's own error inside.
#[derive(Debug, thiserror::Error)]
pub enum WorkflowError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    #[error(transparent)]
    Merge(#[from] crate::pipeline::MergeError),
    #[error(transparent)]
    Trend(#[from] TrendError),
    #[error(transparent)]
    Som(#[from] SomError),
    #[error(transparent)]
    Cluster(#[from] crate::cluster::ClusterError),
    #[error(transparent)]
    Sim(#[from] crate::sim::SimError),
    #[error(transparent)]
    Synth(#[from] crate::synth::SynthError),
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Report(#[from] crate::report::ReportError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    #[error(transparent)]
    Export(#[from] crate::export::ExportError),
    #[error(transparent)]
    Write(#[from] IoAt),
    /// A folder or file given to a command is not what it should be (e.g. not a run folder).
    #[error("{path}: {message}")]
    Input { path: String, message: String },
    /// The hit asked for is not in the inputs, or cannot be analysed.
    #[error("{0}")]
    NoHit(String),
    /// A map to train before the test (`aepipe watch`) needs `[som] train_on = "reference"`.
    #[error("config: som.train_on is not \"reference\"")]
    NotReferenceTraining,
}

impl crate::util::HasKind for WorkflowError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            WorkflowError::Merge(x) => x.kind(),
            WorkflowError::Config(_)
            | WorkflowError::Input { .. }
            | WorkflowError::NoHit(_)
            | WorkflowError::NotReferenceTraining => crate::util::ErrorKind::Usage,
            WorkflowError::Pipeline(x) => x.kind(),
            WorkflowError::Trend(x) => x.kind(),
            WorkflowError::Som(x) => x.kind(),
            WorkflowError::Cluster(x) => x.kind(),
            WorkflowError::Sim(x) => x.kind(),
            WorkflowError::Synth(x) => x.kind(),
            WorkflowError::Store(x) => x.kind(),
            WorkflowError::Report(x) => x.kind(),
            WorkflowError::Plot(x) => x.kind(),
            WorkflowError::Export(x) => x.kind(),
            WorkflowError::Write(_) => crate::util::ErrorKind::Failed,
        }
    }
}

/// What `aepipe run` is given besides the pipeline definition.
pub struct RunJob<'a> {
    pub config: &'a ValidConfig,
    pub inputs: &'a [PathBuf],
    pub out: &'a Path,
    pub truth: Option<&'a Path>,
    pub threads: usize,
    pub progress: bool,
    /// Reuse the finished, unchanged per-experiment parts of an earlier run in `out`.
    pub resume: bool,
    /// Only this shard's experiments, features only, as a Hive-partitioned dataset in `out`
    /// (`aepipe merge` runs the whole-batch stages).
    pub shard: Option<crate::util::Shard>,
    /// A caller's stop request and progress count (see [`crate::util::JobControl`]): the
    /// feature stream checks it per record, the run between its stages.
    pub control: Option<std::sync::Arc<crate::util::JobControl>>,
    /// The cache root for the reference map (`[som] train_on = "reference"`): reused when
    /// its key matches, kept when made ([`mapcache`]). `None`: made every run (`--no-cache`,
    /// and every caller that does not ask).
    pub cache: Option<PathBuf>,
}

impl<'a> RunJob<'a> {
    /// A run of `inputs` into `out` with `config` on `threads` workers (0 = all cores):
    /// no truth, progress bar, resume, shard or caller's control (set those by struct
    /// update).
    pub fn new(
        config: &'a ValidConfig,
        inputs: &'a [PathBuf],
        out: &'a Path,
        threads: usize,
    ) -> RunJob<'a> {
        RunJob {
            config,
            inputs,
            out,
            truth: None,
            threads,
            progress: false,
            resume: false,
            shard: None,
            control: None,
            cache: None,
        }
    }
}

impl RunJob<'_> {
    /// The run's folder.
    pub fn dir(&self) -> RunDir {
        RunDir::new(self.out)
    }

    /// How the run's own feature stage streams (threads, progress, resume, shard).
    pub fn stream_options(&self) -> StreamOptions {
        StreamOptions {
            threads: self.threads,
            progress: self.progress,
            resume: self.resume,
            shard: self.shard,
            control: self.control.clone(),
        }
    }

    /// `Err(Cancelled)` once the caller has asked the run to stop.
    fn go_on(&self) -> Result<(), WorkflowError> {
        if crate::util::cancelled(&self.control) {
            Err(WorkflowError::Pipeline(PipelineError::Cancelled))
        } else {
            Ok(())
        }
    }
}

/// What a sharded `aepipe run` did: its part of the features, nothing else.
pub enum RunOutcome {
    Whole(Box<RunSummary>),
    Shard(Box<crate::pipeline::RunReport>),
}

/// Run every enabled stage (or, with a shard, its features).
pub fn run_or_shard(job: &RunJob) -> Result<RunOutcome, WorkflowError> {
    match job.shard {
        None => Ok(RunOutcome::Whole(Box::new(run(job)?))),
        Some(_) => Ok(RunOutcome::Shard(Box::new(crate::pipeline::run(
            crate::pipeline::StreamJob::Features,
            job.inputs,
            job.out,
            job.config,
            &job.stream_options(),
        )?))),
    }
}

/// Remove the temporary files of a killed earlier run (every output is written under a
/// temporary name, then renamed): never read.
fn clean_stale(dir: &RunDir) {
    for d in dir.table_dirs() {
        crate::store::clean_stale_tmp(&d);
    }
}

/// `aepipe merge DIR`: check the N shards of a sharded run, assemble the whole-batch tables
/// into `OUT/features/` and run the whole-batch stages (trend, SOM, classification, report)
/// exactly as an unsharded `aepipe run` does.
pub fn merge(
    dir: &Path,
    out: &Path,
    truth: Option<&Path>,
    threads: usize,
    progress: bool,
) -> Result<RunSummary, WorkflowError> {
    let run_dir = RunDir::new(out);
    clean_stale(&run_dir);
    let t = std::time::Instant::now();
    let (features, cfg, inputs) = crate::pipeline::merge(
        dir,
        run_dir.features().path(),
        threads,
        Some(crate::pipeline::StreamJob::Features),
    )?;
    let job = RunJob {
        truth,
        progress,
        ..RunJob::new(&cfg, &inputs, out, threads)
    };
    let mut log = StageLog::default();
    log.seconds
        .push(("merge".to_string(), t.elapsed().as_secs_f64()));
    analyse(&job, features, log)
}

/// Run every enabled stage.
pub fn run(job: &RunJob) -> Result<RunSummary, WorkflowError> {
    clean_stale(&job.dir());
    let mut log = StageLog::default();
    let features = log.time("features", || {
        crate::pipeline::run(
            crate::pipeline::StreamJob::Features,
            job.inputs,
            job.dir().features().path(),
            job.config,
            &job.stream_options(),
        )
    })?;
    analyse(job, features, log)
}

/// The map `[som] train_on = "reference"` trains (on the configured or embedded reference
/// library, in `job.out`), without a test's hits: what `aepipe watch` classifies with while
/// a test runs.
pub fn train_reference_map(
    job: &RunJob,
) -> Result<(crate::som::tables::Model, String), WorkflowError> {
    if job.config.som.train_on != crate::config::TrainOn::Reference {
        return Err(WorkflowError::NotReferenceTraining);
    }
    stages::train_stage(job, &[]).map(|(m, on, _)| (m, on))
}

/// The whole-batch stages on feature tables already written (a run's, a merge's, or a
/// benchmark's), in their order: trend, SOM (training or the given map, classification,
/// damage profile with evolution and location), truth, report, run.json. Each stage's time
/// and peak memory go into `log` and the summary.
pub fn analyse(
    job: &RunJob,
    features: crate::pipeline::RunReport,
    mut log: StageLog,
) -> Result<RunSummary, WorkflowError> {
    let cfg = job.config;
    let dir = job.dir();
    let feats = vec![features.table_path.clone()];

    let (mut trend, mut trend_plots) = (None, Vec::new());
    if cfg.trend.enabled {
        job.go_on()?;
        let (rep, plots) = log.time("trend", || trend_stage(cfg, &feats, &dir.trend()))?;
        trend = Some(rep);
        trend_plots = plots;
    }

    let statistics = log.time("statistics", || {
        crate::analysis::powerlaw::run_statistics(
            &feats,
            &dir.statistics(),
            cfg.source_rows(),
            &cfg.hash(),
        )
    })?;
    let mut som = None;
    if cfg.som.enabled {
        job.go_on()?;
        som = Some(som_stage(job, &feats, &features, &mut log)?);
        if let Some(c) = som.as_ref().and_then(|m| m.map_cache.as_ref()) {
            mapcache::name_in_manifest(&features.manifest_path, c)?;
        }
    }
    let cluster = if cfg.cluster.enabled {
        job.go_on()?;
        let dir = job.dir().cluster();
        Some(log.time("clustering", || {
            cluster::cluster_stage(cfg, &feats, &features, &dir, som.as_ref())
        })?)
    } else {
        None
    };
    // Written back for the lab's tools; the run's own folder, so an earlier run's export
    // there is replaced.
    let export = match cfg.export.trfdb {
        true => Some(log.time("export", || {
            crate::export::export(&dir.run_tables(), &dir.export(), true)
        })?),
        false => None,
    };
    let (truth, sources) = match job.truth {
        Some(_) => log.time("truth", || {
            truth::scores(job.truth, som.as_ref(), &features, cfg)
        })?,
        None => (None, None),
    };
    let mut summary = RunSummary {
        out: job.out.to_path_buf(),
        inputs: job.inputs.to_vec(),
        features,
        trend,
        trend_plots,
        som,
        cluster,
        export,
        statistics,
        truth,
        sources,
        config: cfg.clone(),
        seconds: Vec::new(),
        peak_rss: Vec::new(),
        series: None,
        page: None,
    };
    summary.series = Some(log.time("series", || series::series_stage(&summary, &dir.series()))?);
    if cfg.report.enabled {
        job.go_on()?;
        // The report shows the stages before it; its own time goes into run.json.
        summary.seconds = log.seconds.clone();
        summary.peak_rss = log.peak_rss.clone();
        let fit = log.time("report", || -> Result<_, WorkflowError> {
            let g = gather(&summary)?;
            Ok(crate::report::write(&summary, &g, &dir.report_html())?)
        })?;
        summary.page = Some(fit);
    }
    summary.seconds = log.seconds;
    summary.peak_rss = log.peak_rss;
    write_run_json(&summary)?;
    Ok(summary)
}

fn input_err(p: &Path, m: impl std::fmt::Display) -> WorkflowError {
    WorkflowError::Input {
        path: p.display().to_string(),
        message: m.to_string(),
    }
}

mod cluster;
mod cluster_views;
pub mod explore;
mod headline;
pub mod layout;
pub mod mapcache;
mod pictures;
mod runfile;
mod schema;
pub mod series;
mod sources;
mod stages;
pub mod transfer;
mod truth;
pub use headline::{headline, summary_json};
pub use layout::RunDir;
pub use mapcache::MapCache;
use pictures::gather;
pub use pictures::{burst_picture, cwt_of_hit};
pub use runfile::rebuild_report;
use runfile::write_run_json;
pub use schema::{table_schema, TABLES};
pub use stages::StageLog;
use stages::{som_stage, trend_stage};
