//! Sharded runs: a shard publishes its experiments' parts as a Hive-partitioned dataset with
//! a shard manifest; [`merge`] checks that all N shards agree and assembles the batch from
//! them, the same bytes an unsharded run writes.

use super::{
    assemble, part_tables, Part, PartStats, PipelineError, Produced, RunReport, StreamJob,
    StreamOptions, StreamStats,
};
use crate::config::PipelineConfig;
use crate::ingest::Source;
use crate::model::Reject;
use crate::store;
use crate::util::{file_digest, utc_now, write_atomic, IoAt};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The Hive folder of `table` (`features`, `waveforms`, `hits`, `rejects`) in a sharded
/// output folder.
fn hive_file(out_dir: &Path, table: &str, experiment: &str, k: u32) -> PathBuf {
    out_dir
        .join(table)
        .join(format!(
            "experiment={}",
            crate::util::hive_value(experiment)
        ))
        .join(format!("part-{k}.parquet"))
}

fn table_stem(f: &str) -> &str {
    f.trim_end_matches(".parquet")
}

/// What `OUT/shards/shard-K-of-N.json` records: enough for [`merge`] to check the shards
/// agree and to assemble the batch without reading any input again.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ShardManifest {
    pub tool_version: String,
    pub job: String,
    pub config_sha256: String,
    /// The effective pipeline definition (canonical TOML).
    pub config: String,
    pub k: u32,
    pub n: u32,
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
    /// `(table, sha256)` of each published file.
    pub tables: Vec<(String, String)>,
    stats: PartStats,
    pub inputs: Vec<(String, String)>,
}

pub(super) fn publish(
    job: StreamJob,
    inputs: &[PathBuf],
    out_dir: &Path,
    cfg: &PipelineConfig,
    sh: crate::util::Shard,
    started: String,
    p: Produced,
) -> Result<RunReport, PipelineError> {
    let mut experiments = Vec::new();
    let mut stats = StreamStats::default();
    for part in &p.parts {
        for (k, name) in part_tables(job).iter().enumerate() {
            let dest = hive_file(out_dir, table_stem(name), &part.id, sh.k);
            let dir = dest.parent().expect("hive file has a folder");
            std::fs::create_dir_all(dir).map_err(|e| IoAt::new(dir, e))?;
            let tmp = crate::util::tmp_path_for(&dest);
            std::fs::copy(&part.tables[k], &tmp).map_err(|e| IoAt::new(&tmp, e))?;
            std::fs::rename(&tmp, &dest).map_err(|e| IoAt::new(&dest, e))?;
        }
        part.stats.add_to(&mut stats);
        // The copies carry the hashes the part recorded when its tables were written.
        experiments.push(ShardExperiment {
            id: part.id.clone(),
            tables: part.outputs.clone(),
            stats: part.stats.clone(),
            inputs: part.inputs.clone(),
        });
    }
    let m = ShardManifest {
        tool_version: env!("CARGO_PKG_VERSION").into(),
        job: job.name().into(),
        config_sha256: cfg.hash(),
        config: cfg.to_toml(),
        k: sh.k,
        n: sh.n,
        inputs: inputs.to_vec(),
        started_utc: started,
        finished_utc: utc_now(),
        seconds: p.t_stream,
        sources: p.sources.clone(),
        experiments,
        discover_rejects: p.discover_rejects.clone(),
        skipped: p.skipped.clone(),
        input_files: p.inputs_json.clone(),
    };
    let shards = out_dir.join("shards");
    std::fs::create_dir_all(&shards).map_err(|e| IoAt::new(&shards, e))?;
    let manifest_path = shards.join(format!("shard-{}-of-{}.json", sh.k, sh.n));
    let text = serde_json::to_string_pretty(&m).expect("shard manifest serialises");
    write_atomic(&manifest_path, text.as_bytes())?;
    stats.seconds = p.t_stream;
    Ok(RunReport {
        stats,
        table_path: out_dir.join(table_stem(job.table_file())),
        hits_path: out_dir.join("hits"),
        rejects_path: out_dir.join("rejects"),
        parametric_path: out_dir.join("parametric"),
        markers_path: out_dir.join("markers"),
        manifest_path,
        sources: p.sources,
        skipped: p.skipped,
    })
}

/// Why the shards of a folder cannot be merged.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error(
        "{dir}: no shard manifests (shards/shard-K-of-N.json): not the output of a --shard run"
    )]
    NoShards { dir: String },
    #[error("{path}: {message}")]
    Manifest { path: String, message: String },
    #[error("{dir}: the shards disagree: {message}")]
    Disagree { dir: String, message: String },
    #[error("{dir}: shard(s) {missing} of {n} missing (no shards/shard-K-of-{n}.json): resubmit those array tasks (--shard K/{n}), then merge again")]
    Missing {
        dir: String,
        missing: String,
        n: u32,
    },
    #[error("{dir}: shards of a {job} job: `aepipe merge --tables-only` assembles them")]
    WrongJob { dir: String, job: String },
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
}

/// Read and check the shard manifests of `dir`: all N present, one tool version, job and
/// config, each experiment in exactly the shard its id hashes to, every published table
/// still with its recorded hash.
pub fn read_shards(dir: &Path) -> Result<Vec<ShardManifest>, MergeError> {
    let sd = dir.join("shards");
    let mut found: Vec<(PathBuf, ShardManifest)> = Vec::new();
    if let Ok(rd) = std::fs::read_dir(&sd) {
        for e in rd.flatten() {
            let p = e.path();
            let n = p
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .to_string();
            if !(n.starts_with("shard-") && n.ends_with(".json")) {
                continue;
            }
            let text = std::fs::read_to_string(&p).map_err(|e| MergeError::Manifest {
                path: p.display().to_string(),
                message: e.to_string(),
            })?;
            let m: ShardManifest =
                serde_json::from_str(&text).map_err(|e| MergeError::Manifest {
                    path: p.display().to_string(),
                    message: e.to_string(),
                })?;
            found.push((p, m));
        }
    }
    if found.is_empty() {
        return Err(MergeError::NoShards {
            dir: dir.display().to_string(),
        });
    }
    let d = dir.display().to_string();
    let first = found[0].1.clone();
    for (p, m) in &found {
        let what = if m.n != first.n {
            Some(format!(
                "{} is of {} shards, another of {}",
                p.display(),
                m.n,
                first.n
            ))
        } else if m.config_sha256 != first.config_sha256 {
            Some(format!(
                "{} was run with another config (sha256 {} vs {})",
                p.display(),
                m.config_sha256,
                first.config_sha256
            ))
        } else if m.tool_version != first.tool_version {
            Some(format!(
                "{} was written by aepipe {} (another by {})",
                p.display(),
                m.tool_version,
                first.tool_version
            ))
        } else if m.job != first.job {
            Some(format!(
                "{} is a {} job (another is {})",
                p.display(),
                m.job,
                first.job
            ))
        } else {
            None
        };
        if let Some(message) = what {
            return Err(MergeError::Disagree { dir: d, message });
        }
    }
    let n = first.n;
    let mut by_k: BTreeMap<u32, ShardManifest> = BTreeMap::new();
    for (_, m) in found {
        by_k.insert(m.k, m);
    }
    let missing: Vec<String> = (0..n)
        .filter(|k| !by_k.contains_key(k))
        .map(|k| k.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(MergeError::Missing {
            dir: d,
            missing: missing.join(", "),
            n,
        });
    }
    for m in by_k.values() {
        for e in &m.experiments {
            if crate::util::Shard::of(&e.id, n) != m.k {
                return Err(MergeError::Disagree {
                    dir: d,
                    message: format!(
                        "experiment {:?} is in shard {} but hashes to shard {}",
                        e.id,
                        m.k,
                        crate::util::Shard::of(&e.id, n)
                    ),
                });
            }
            for (name, sha) in &e.tables {
                let f = hive_file(dir, table_stem(name), &e.id, m.k);
                match file_digest(&f) {
                    Ok((_, h)) if &h == sha => {}
                    _ => {
                        return Err(MergeError::Disagree {
                            dir: d,
                            message: format!(
                                "{} is missing or changed since shard {} wrote it: resubmit it",
                                f.display(),
                                m.k
                            ),
                        })
                    }
                }
            }
        }
    }
    Ok(by_k.into_values().collect())
}

/// `aepipe merge`: the whole-batch tables and manifest of a sharded run, into `out_dir`,
/// the same bytes an unsharded run writes.
///
/// `only`: refuse, before writing anything, shards of another job (`aepipe merge` without
/// `--tables-only` runs the feature stages, which need feature shards).
pub fn merge(
    dir: &Path,
    out_dir: &Path,
    threads: usize,
    only: Option<StreamJob>,
) -> Result<(RunReport, ShardManifest), MergeError> {
    let t0 = Instant::now();
    let started = utc_now();
    let shards = read_shards(dir)?;
    let first = shards[0].clone();
    let cfg = PipelineConfig::from_toml(&first.config).map_err(|e| MergeError::Manifest {
        path: dir.join("shards").display().to_string(),
        message: e.to_string(),
    })?;
    let job = if first.job == StreamJob::Waveforms.name() {
        StreamJob::Waveforms
    } else {
        StreamJob::Features
    };
    if only.is_some_and(|j| j != job) {
        return Err(MergeError::WrongJob {
            dir: dir.display().to_string(),
            job: first.job.clone(),
        });
    }
    std::fs::create_dir_all(out_dir).map_err(|e| PipelineError::from(IoAt::new(out_dir, e)))?;
    store::clean_stale_tmp(out_dir);
    let mut parts = Vec::new();
    let mut sources = Vec::new();
    let mut inputs_json = Vec::new();
    for m in &shards {
        for e in &m.experiments {
            parts.push(Part {
                tables: part_tables(job).map(|n| hive_file(dir, table_stem(n), &e.id, m.k)),
                id: e.id.clone(),
                stats: e.stats.clone(),
                reused: false,
                inputs: e.inputs.clone(),
                outputs: e.tables.clone(),
                dir: hive_file(dir, table_stem(job.table_file()), &e.id, m.k)
                    .parent()
                    .map(Path::to_path_buf)
                    .unwrap_or_default(),
            });
        }
        sources.extend(m.sources.iter().cloned());
        inputs_json.extend(m.input_files.iter().cloned());
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
        t_stream: shards.iter().map(|m| m.seconds).sum(),
    };
    let opts = StreamOptions {
        threads,
        progress: false,
        resume: false,
        shard: None,
    };
    let r = assemble(job, out_dir, &cfg, &opts, started, t0, produced)?;
    Ok((r, first))
}
