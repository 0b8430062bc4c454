//! The staged streaming runner.
//!
//! ```text
//! discover ─► read (thread) ─► bounded channel of batches ─► workers (rayon pool, order kept)
//!          ─► bounded channel ─► sink (thread): table + rejects ─► rename ─► manifest.json
//! ```
//!
//! Memory is bounded by the channel capacities: at most `2·queue_batches + 3` batches of
//! `batch_size` records exist at once, whatever the number of hits. Batches keep the reading
//! order and workers keep the order inside a batch (`collect` of an indexed parallel
//! iterator), so the output is the same, byte for byte, for any thread count. Every record
//! ends as a row or a reject row; a panic inside a per-record transform becomes a reject row.

use crate::config::ValidConfig;
use crate::ingest::Source;
use crate::store;
use crate::util::{utc_now, IoAt};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error(transparent)]
    Store(#[from] store::StoreError),
    #[error(transparent)]
    Io(#[from] IoAt),
    #[error("cannot start the worker pool: {0}")]
    Pool(String),
    #[error("no input given")]
    NoInput,
    /// Discovery found no recording in the inputs: what it passed over or could not open,
    /// one line each.
    #[error("no recording aepipe reads in {inputs}{}", passed_over.iter().map(|l| format!("\n  {l}")).collect::<String>())]
    NothingToRead {
        inputs: String,
        passed_over: Vec<String>,
    },
    #[error(transparent)]
    Events(#[from] crate::events::EventsError),
    /// The caller asked the job to stop ([`StreamOptions::control`]); nothing was published.
    #[error("interrupted")]
    Cancelled,
}

impl crate::util::HasKind for PipelineError {
    fn kind(&self) -> crate::util::ErrorKind {
        use crate::util::ErrorKind;
        match self {
            PipelineError::Store(s) => s.kind(),
            PipelineError::Io(_) | PipelineError::Pool(_) | PipelineError::Cancelled => {
                ErrorKind::Failed
            }
            PipelineError::NoInput | PipelineError::NothingToRead { .. } => ErrorKind::Usage,
            PipelineError::Events(e) => e.kind(),
        }
    }
}

/// What a run produces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StreamJob {
    /// `features.parquet` + `rejects.parquet` + `manifest.json`.
    Features,
    /// `waveforms.parquet` (canonical waveforms) + `rejects.parquet` + `manifest.json`.
    Waveforms,
}

impl StreamJob {
    pub fn table_file(self) -> &'static str {
        match self {
            StreamJob::Features => "features.parquet",
            StreamJob::Waveforms => "waveforms.parquet",
        }
    }
    pub(crate) fn name(self) -> &'static str {
        match self {
            StreamJob::Features => "features",
            StreamJob::Waveforms => "waveforms",
        }
    }
}

#[derive(Debug, Clone)]
pub struct StreamOptions {
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Show a progress bar (only drawn when stderr is a terminal).
    pub progress: bool,
    /// [`run`]: reuse the finished, unchanged per-experiment parts of an earlier run.
    pub resume: bool,
    /// [`run`]: only this shard's experiments, published as a Hive-partitioned dataset.
    pub shard: Option<crate::util::Shard>,
    /// A caller's stop request and progress count (the Python package's Ctrl-C and
    /// progress bar); checked once per record read.
    pub control: Option<std::sync::Arc<crate::util::JobControl>>,
}

impl StreamOptions {
    /// A plain stream on `threads` workers (0 = all cores): no progress bar, resume, shard
    /// or caller's control.
    pub fn with_threads(threads: usize) -> StreamOptions {
        StreamOptions {
            threads,
            progress: false,
            resume: false,
            shard: None,
            control: None,
        }
    }
}

impl Default for StreamOptions {
    fn default() -> Self {
        StreamOptions {
            threads: 0,
            progress: true,
            resume: false,
            shard: None,
            control: None,
        }
    }
}

/// What [`run`] did, including where it wrote.
#[derive(Debug, Clone)]
pub struct RunReport {
    pub stats: StreamStats,
    pub table_path: PathBuf,
    pub hits_path: PathBuf,
    pub rejects_path: PathBuf,
    pub parametric_path: PathBuf,
    pub markers_path: PathBuf,
    pub events_path: PathBuf,
    pub manifest_path: PathBuf,
    pub sources: Vec<Source>,
    pub skipped: Vec<(PathBuf, String)>,
}

impl RunReport {
    /// The whole-batch tables and manifest of a stream folder, with `stats` (no sources
    /// or skipped files listed).
    pub fn of_tables(dir: &StreamDir, job: StreamJob, stats: StreamStats) -> RunReport {
        RunReport {
            stats,
            table_path: dir.table(PartTable::Main, job),
            hits_path: dir.table(PartTable::Hits, job),
            rejects_path: dir.table(PartTable::Rejects, job),
            parametric_path: dir.table(PartTable::Parametric, job),
            markers_path: dir.table(PartTable::Markers, job),
            events_path: dir.table(PartTable::Events, job),
            manifest_path: dir.manifest(),
            sources: vec![],
            skipped: vec![],
        }
    }
}

/// Discover, read, transform and write: the whole `aepipe features` / `aepipe waveforms` job.
///
/// Each experiment is streamed into its own part folder (`OUT/parts/<id>-<hash>/`: the
/// tables and, written last, `part.json`), then the whole-batch tables are assembled from
/// the parts in experiment order. With `resume`, a part whose `part.json` matches the tool,
/// job, config and input hashes, and whose tables still have their recorded hashes, is
/// reused as it is; the rest are redone. The assembled tables are the same, byte for byte,
/// either way.
///
/// With `shard` = K/N only the experiments of shard K are done, and instead of whole-batch
/// tables the shard publishes its parts as a Hive-partitioned dataset
/// (`OUT/<table>/experiment=<id>/part-K.parquet`) with `OUT/shards/shard-K-of-N.json`;
/// [`merge`] assembles the batch from all N.
pub fn run(
    job: StreamJob,
    inputs: &[PathBuf],
    out_dir: &Path,
    cfg: &ValidConfig,
    opts: &StreamOptions,
) -> Result<RunReport, PipelineError> {
    if inputs.is_empty() {
        return Err(PipelineError::NoInput);
    }
    let started = utc_now();
    let t0 = Instant::now();
    std::fs::create_dir_all(out_dir).map_err(|e| IoAt::new(out_dir, e))?;
    store::clean_stale_tmp(out_dir);
    // Outputs of an earlier run are removed first: the files in `out_dir` always belong to
    // one complete run (an interrupted run leaves none rather than a stale mixture). Parts
    // stay only for `--resume`, which checks each before reusing it.
    let out = StreamDir::new(out_dir);
    for t in PartTable::ALL {
        let _ = std::fs::remove_file(out.table(t, job));
    }
    let _ = std::fs::remove_file(out.manifest());
    let produced = produce(job, inputs, &out, cfg, opts)?;
    match opts.shard {
        None => assemble(job, &out, cfg, opts, started, t0, produced),
        Some(sh) => shard::publish(job, inputs, &out, cfg, sh, started, produced),
    }
}

mod assemble;
mod counts;
pub mod layout;
mod manifest;
mod part;
mod parts;
mod shard;
mod stream;
pub(crate) use assemble::assemble;
pub(crate) use counts::PartStats;
pub use counts::{Counts, RecordCounts, StreamStats, MAX_NOTES};
pub use layout::{PartDir, PartTable, StreamDir};
pub use manifest::{write_manifest, InputFile, Manifest, SomMapEntry};
pub use part::{run_part, Continuation, PartRun};
use parts::produce;
pub(crate) use parts::{Part, Produced};
pub use shard::{merge, read_shards, MergeError, ShardExperiment, ShardManifest};
pub use stream::{stream, Checkout, StatePool};
