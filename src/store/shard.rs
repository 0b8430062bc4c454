//! One mechanism for sharded outputs (a Slurm array task each): the feature and waveform
//! jobs' experiments and the reference library's grid points alike. Shard K of N publishes
//! its files as a Hive-partitioned dataset and writes, last, `shards/shard-K-of-N.json`: a
//! [`ShardHeader`] (what made it, which keys it owns, the SHA-256 of every file it published)
//! and the job's own payload. [`read_shards`] checks a folder's shards before anything is
//! assembled: all N present, one kind, tool version and definition, every key in the shard it
//! hashes to, every file still as published.

use crate::util::{file_digest, Shard};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What a sharded folder holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShardKind {
    /// `aepipe features|run --shard`: per-experiment feature parts.
    Features,
    /// `aepipe waveforms --shard`: per-experiment waveform parts.
    Waveforms,
    /// `aepipe reference --shard`: grid points of the reference library.
    ReferenceLibrary,
}

impl ShardKind {
    pub fn as_str(self) -> &'static str {
        match self {
            ShardKind::Features => "features",
            ShardKind::Waveforms => "waveforms",
            ShardKind::ReferenceLibrary => "reference_library",
        }
    }
}

/// What every shard manifest records besides its job's payload.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardHeader {
    pub kind: ShardKind,
    pub tool_version: String,
    /// SHA-256 of what defines the job (the pipeline config's canonical TOML, the library
    /// definition): shards of different definitions never merge.
    pub definition_sha256: String,
    pub k: u32,
    pub n: u32,
    /// The keys the shard owns (experiment ids, grid points); each hashes to `k`.
    pub keys: Vec<String>,
    /// `(path relative to the output folder, sha256)` of every file the shard published.
    pub files: Vec<(String, String)>,
}

/// A shard manifest: the header and the job's payload, in one JSON object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardFile<P> {
    #[serde(flatten)]
    pub header: ShardHeader,
    #[serde(flatten)]
    pub payload: P,
}

/// Why the shards of a folder cannot be merged.
#[derive(Debug, thiserror::Error)]
pub enum ShardSetError {
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
    #[error("{dir}: shards of a {found} job, not {want}")]
    WrongKind {
        dir: String,
        found: &'static str,
        want: &'static str,
    },
    #[error("{path}: {message}")]
    Io { path: String, message: String },
}

impl crate::util::HasKind for ShardSetError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            // The folder is not a complete, consistent set of shards: the input is at fault.
            ShardSetError::NoShards { .. }
            | ShardSetError::Manifest { .. }
            | ShardSetError::Disagree { .. }
            | ShardSetError::Missing { .. }
            | ShardSetError::WrongKind { .. } => crate::util::ErrorKind::Usage,
            ShardSetError::Io { .. } => crate::util::ErrorKind::Failed,
        }
    }
}

/// The folder of the shard manifests.
pub fn shards_dir(out: &Path) -> PathBuf {
    out.join("shards")
}

/// `OUT/shards/shard-K-of-N.json`.
pub fn manifest_path(out: &Path, sh: Shard) -> PathBuf {
    shards_dir(out).join(format!("shard-{}-of-{}.json", sh.k, sh.n))
}

/// `OUT/<table>/experiment=<value>/part-K.parquet` (the value percent-encoded by
/// [`crate::util::hive_value`]).
pub fn hive_file(out: &Path, table: &str, partition: &str, k: u32) -> PathBuf {
    out.join(table)
        .join(format!("experiment={}", crate::util::hive_value(partition)))
        .join(format!("part-{k}.parquet"))
}

/// The `files` entry of a published file: its path relative to `out` and its SHA-256.
pub fn published(out: &Path, file: &Path) -> Result<(String, String), ShardSetError> {
    let (_, sha) = file_digest(file).map_err(|e| ShardSetError::Io {
        path: file.display().to_string(),
        message: e.to_string(),
    })?;
    let rel = file.strip_prefix(out).unwrap_or(file);
    Ok((rel.display().to_string(), sha))
}

/// Write shard `header.k`'s manifest, atomically (last, after every file it names).
pub fn write_manifest<P: Serialize>(
    out: &Path,
    file: &ShardFile<P>,
) -> Result<PathBuf, crate::util::IoAt> {
    let dir = shards_dir(out);
    std::fs::create_dir_all(&dir).map_err(|e| crate::util::IoAt::new(&dir, e))?;
    let p = manifest_path(
        out,
        Shard {
            k: file.header.k,
            n: file.header.n,
        },
    );
    let text = serde_json::to_string_pretty(file).expect("shard manifest serialises");
    crate::util::write_atomic(&p, text.as_bytes())?;
    Ok(p)
}

/// The kind of the shards in `dir` (from the first manifest found).
pub fn detect(dir: &Path) -> Result<ShardKind, ShardSetError> {
    #[derive(Deserialize)]
    struct Kind {
        kind: ShardKind,
    }
    let found = manifests(dir)?;
    let p = found.first().ok_or_else(|| ShardSetError::NoShards {
        dir: dir.display().to_string(),
    })?;
    let k: Kind = parse(p)?;
    Ok(k.kind)
}

fn manifests(dir: &Path) -> Result<Vec<PathBuf>, ShardSetError> {
    let mut out = Vec::new();
    if let Ok(rd) = std::fs::read_dir(shards_dir(dir)) {
        for e in rd.flatten() {
            let n = e.file_name().to_string_lossy().to_string();
            if n.starts_with("shard-") && n.ends_with(".json") {
                out.push(e.path());
            }
        }
    }
    out.sort();
    Ok(out)
}

fn parse<T: DeserializeOwned>(p: &Path) -> Result<T, ShardSetError> {
    let err = |m: String| ShardSetError::Manifest {
        path: p.display().to_string(),
        message: m,
    };
    let text = std::fs::read_to_string(p).map_err(|e| err(e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| err(e.to_string()))
}

/// Read and check the shard manifests of `dir`, which must be of `kind`: all N present, one
/// tool version and definition, each key in exactly the shard it hashes to, every published
/// file still with its recorded hash. In shard order.
pub fn read_shards<P: DeserializeOwned>(
    dir: &Path,
    kind: ShardKind,
) -> Result<Vec<ShardFile<P>>, ShardSetError> {
    let d = dir.display().to_string();
    let paths = manifests(dir)?;
    if paths.is_empty() {
        return Err(ShardSetError::NoShards { dir: d });
    }
    let mut found: Vec<(PathBuf, ShardFile<P>)> = Vec::new();
    for p in paths {
        let m: ShardFile<P> = parse(&p)?;
        found.push((p, m));
    }
    let first = found[0].1.header.clone();
    if first.kind != kind {
        return Err(ShardSetError::WrongKind {
            dir: d,
            found: first.kind.as_str(),
            want: kind.as_str(),
        });
    }
    for (p, m) in &found {
        let h = &m.header;
        let what = if h.kind != first.kind {
            Some(format!(
                "{} is a {} shard (another is {})",
                p.display(),
                h.kind.as_str(),
                first.kind.as_str()
            ))
        } else if h.n != first.n {
            Some(format!(
                "{} is of {} shards, another of {}",
                p.display(),
                h.n,
                first.n
            ))
        } else if h.definition_sha256 != first.definition_sha256 {
            Some(format!(
                "{} was run with another config (sha256 {} vs {})",
                p.display(),
                h.definition_sha256,
                first.definition_sha256
            ))
        } else if h.tool_version != first.tool_version {
            Some(format!(
                "{} was written by aepipe {} (another by {})",
                p.display(),
                h.tool_version,
                first.tool_version
            ))
        } else {
            None
        };
        if let Some(message) = what {
            return Err(ShardSetError::Disagree { dir: d, message });
        }
    }
    let n = first.n;
    let mut by_k: BTreeMap<u32, ShardFile<P>> = BTreeMap::new();
    for (_, m) in found {
        by_k.insert(m.header.k, m);
    }
    let missing: Vec<String> = (0..n)
        .filter(|k| !by_k.contains_key(k))
        .map(|k| k.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(ShardSetError::Missing {
            dir: d,
            missing: missing.join(", "),
            n,
        });
    }
    for m in by_k.values() {
        let h = &m.header;
        for key in &h.keys {
            if Shard::of(key, n) != h.k {
                return Err(ShardSetError::Disagree {
                    dir: d,
                    message: format!(
                        "{key:?} is in shard {} but hashes to shard {}",
                        h.k,
                        Shard::of(key, n)
                    ),
                });
            }
        }
        for (rel, sha) in &h.files {
            let f = dir.join(rel);
            match file_digest(&f) {
                Ok((_, got)) if &got == sha => {}
                _ => {
                    return Err(ShardSetError::Disagree {
                        dir: d,
                        message: format!(
                            "{} is missing or changed since shard {} wrote it: resubmit it",
                            f.display(),
                            h.k
                        ),
                    })
                }
            }
        }
    }
    Ok(by_k.into_values().collect())
}
