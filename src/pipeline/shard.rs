//! Sharded runs: a shard publishes its experiments' parts as a Hive-partitioned dataset with
//! a shard manifest ([`crate::store::shard`], the one mechanism the reference library uses
//! too); [`merge`] checks that all N shards agree and assembles the batch from them, the same
//! bytes an unsharded run writes.

use super::layout::{PartTable, StreamDir};
use super::{
    assemble, Part, PartStats, PipelineError, Produced, RunReport, StreamJob, StreamOptions,
    StreamStats,
};
use crate::config::PipelineConfig;
use crate::ingest::Source;
use crate::model::Reject;
use crate::store;
use crate::store::shard::{self as sh_store, ShardFile, ShardHeader, ShardKind, ShardSetError};
use crate::util::{utc_now, IoAt};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What a feature or waveform shard records besides its header: enough for [`merge`] to
/// assemble the batch without reading any input again.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ShardManifest {
    /// The effective pipeline definition (canonical TOML).
    pub config: String,
    pub inputs: Vec<PathBuf>,
    pub started_utc: String,
    pub finished_utc: String,
    pub seconds: f64,
    /// The shard's sources (experiments), in order.
    pub sources: Vec<Source>,
    pub experiments: Vec<ShardExperiment>,
    /// Discovery's own rejects (missing inputs, unknown files): the same in every shard;
    /// the merge takes shard 0's.
    pub discover_rejects: Vec<Reject>,
    pub skipped: Vec<(PathBuf, String)>,
    /// The manifest's `inputs` entries of the shard's files.
    pub input_files: Vec<super::InputFile>,
}

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ShardExperiment {
    pub id: String,
    stats: PartStats,
    pub inputs: Vec<(String, String)>,
}

/// The shard kind of a streaming job.
pub(crate) fn kind_of(job: StreamJob) -> ShardKind {
    match job {
        StreamJob::Features => ShardKind::Features,
        StreamJob::Waveforms => ShardKind::Waveforms,
    }
}

pub(super) fn publish(
    job: StreamJob,
    inputs: &[PathBuf],
    out: &StreamDir,
    cfg: &PipelineConfig,
    sh: crate::util::Shard,
    started: String,
    p: Produced,
) -> Result<RunReport, PipelineError> {
    let mut experiments = Vec::new();
    let mut files = Vec::new();
    let mut stats = StreamStats::default();
    for part in &p.parts {
        for t in PartTable::ALL {
            let dest = out.hive_file(t, job, &part.id, sh.k);
            let dir = dest.parent().expect("hive file has a folder");
            std::fs::create_dir_all(dir).map_err(|e| IoAt::new(dir, e))?;
            let tmp = crate::util::tmp_path_for(&dest);
            std::fs::copy(part.table(t), &tmp).map_err(|e| IoAt::new(&tmp, e))?;
            std::fs::rename(&tmp, &dest).map_err(|e| IoAt::new(&dest, e))?;
            // The copy carries the hash the part recorded when its table was written.
            let sha = part
                .outputs
                .iter()
                .find(|(n, _)| n == t.file_name(job))
                .map(|(_, h)| h.clone())
                .unwrap_or_default();
            let rel = dest.strip_prefix(out.path()).unwrap_or(&dest);
            files.push((rel.display().to_string(), sha));
        }
        part.stats.add_to(&mut stats);
        experiments.push(ShardExperiment {
            id: part.id.clone(),
            stats: part.stats.clone(),
            inputs: part.inputs.clone(),
        });
    }
    let m = ShardFile {
        header: ShardHeader {
            kind: kind_of(job),
            tool_version: env!("CARGO_PKG_VERSION").into(),
            definition_sha256: cfg.hash(),
            k: sh.k,
            n: sh.n,
            keys: p.parts.iter().map(|x| x.id.clone()).collect(),
            files,
        },
        payload: ShardManifest {
            config: cfg.to_toml(),
            inputs: inputs.to_vec(),
            started_utc: started,
            finished_utc: utc_now(),
            seconds: p.t_stream,
            sources: p.sources.clone(),
            experiments,
            discover_rejects: p.discover_rejects.clone(),
            skipped: p.skipped.clone(),
            input_files: p.inputs_json.clone(),
        },
    };
    let manifest_path = sh_store::write_manifest(out.path(), &m)?;
    stats.seconds = p.t_stream;
    Ok(RunReport {
        stats,
        table_path: out.hive_dir(PartTable::Main, job),
        hits_path: out.hive_dir(PartTable::Hits, job),
        rejects_path: out.hive_dir(PartTable::Rejects, job),
        parametric_path: out.hive_dir(PartTable::Parametric, job),
        markers_path: out.hive_dir(PartTable::Markers, job),
        events_path: out.hive_dir(PartTable::Events, job),
        manifest_path,
        sources: p.sources,
        skipped: p.skipped,
    })
}

/// Why the shards of a folder cannot be merged.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error(transparent)]
    Shards(#[from] ShardSetError),
    #[error("{path}: {message}")]
    Config { path: String, message: String },
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
}

impl crate::util::HasKind for MergeError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            MergeError::Shards(e) => e.kind(),
            MergeError::Config { .. } => crate::util::ErrorKind::Usage,
            MergeError::Pipeline(e) => e.kind(),
        }
    }
}

/// Read and check the shard manifests of a feature or waveform run in `dir` (see
/// [`crate::store::shard::read_shards`]).
pub fn read_shards(
    dir: &Path,
    job: StreamJob,
) -> Result<Vec<ShardFile<ShardManifest>>, MergeError> {
    Ok(sh_store::read_shards(dir, kind_of(job))?)
}

/// `aepipe merge`: the whole-batch tables and manifest of a sharded run, into `out_dir`,
/// the same bytes an unsharded run writes. The job is the shards' own; `only` refuses,
/// before writing anything, shards of another job (`aepipe merge` without `--tables-only`
/// runs the feature stages, which need feature shards). Returns the merged run, the shards'
/// configuration and the input paths the shards were given.
pub fn merge(
    dir: &Path,
    out_dir: &Path,
    threads: usize,
    only: Option<StreamJob>,
) -> Result<(RunReport, crate::config::ValidConfig, Vec<PathBuf>), MergeError> {
    let t0 = Instant::now();
    let started = utc_now();
    let kind = sh_store::detect(dir)?;
    let job = match kind {
        ShardKind::Features => StreamJob::Features,
        ShardKind::Waveforms => StreamJob::Waveforms,
        ShardKind::ReferenceLibrary => {
            return Err(ShardSetError::WrongKind {
                dir: dir.display().to_string(),
                found: kind.as_str(),
                want: "features",
            }
            .into())
        }
    };
    if let Some(j) = only.filter(|j| *j != job) {
        return Err(ShardSetError::WrongKind {
            dir: dir.display().to_string(),
            found: kind.as_str(),
            want: kind_of(j).as_str(),
        }
        .into());
    }
    let shards = read_shards(dir, job)?;
    let first = &shards[0].payload;
    let cfg = PipelineConfig::from_toml(&first.config).map_err(|e| MergeError::Config {
        path: sh_store::shards_dir(dir).display().to_string(),
        message: e.to_string(),
    })?;
    std::fs::create_dir_all(out_dir).map_err(|e| PipelineError::from(IoAt::new(out_dir, e)))?;
    store::clean_stale_tmp(out_dir);
    let src = StreamDir::new(dir);
    let mut parts = Vec::new();
    let mut sources = Vec::new();
    let mut inputs_json = Vec::new();
    for m in &shards {
        for e in &m.payload.experiments {
            let outputs = PartTable::ALL
                .iter()
                .map(|t| {
                    let f = src.hive_file(*t, job, &e.id, m.header.k);
                    let rel = f.strip_prefix(dir).unwrap_or(&f).display().to_string();
                    let sha = m
                        .header
                        .files
                        .iter()
                        .find(|(p, _)| *p == rel)
                        .map(|(_, h)| h.clone())
                        .unwrap_or_default();
                    (t.file_name(job).to_string(), sha)
                })
                .collect();
            parts.push(Part {
                tables: PartTable::ALL.map(|t| src.hive_file(t, job, &e.id, m.header.k)),
                id: e.id.clone(),
                stats: e.stats.clone(),
                reused: false,
                inputs: e.inputs.clone(),
                outputs,
                dir: src
                    .hive_file(PartTable::Main, job, &e.id, m.header.k)
                    .parent()
                    .map(Path::to_path_buf)
                    .unwrap_or_default(),
            });
        }
        sources.extend(m.payload.sources.iter().cloned());
        inputs_json.extend(m.payload.input_files.iter().cloned());
    }
    // The unsharded order: sources by (id, first file), parts by id.
    parts.sort_by(|a, b| a.id.cmp(&b.id));
    sources.sort_by(|a, b| (&a.id, a.all_files().next()).cmp(&(&b.id, b.all_files().next())));
    let produced = Produced {
        sources,
        discover_rejects: first.discover_rejects.clone(),
        skipped: first.skipped.clone(),
        inputs_json,
        parts,
        t_discover: 0.0,
        t_hash: 0.0,
        t_stream: shards.iter().map(|m| m.payload.seconds).sum(),
    };
    let opts = StreamOptions::with_threads(threads);
    let r = assemble(
        job,
        &StreamDir::new(out_dir),
        &cfg,
        &opts,
        started,
        t0,
        produced,
    )?;
    Ok((r, cfg, first.inputs.clone()))
}
