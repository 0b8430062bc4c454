//! `manifest.json`: one typed struct, written by [`super::assemble`] and read back by the
//! same type (`aepipe report`, tests), so a key cannot be renamed on one side only.

use super::counts::{Counts, StreamStats};
use crate::config::PipelineConfig;
use crate::model::AcquisitionSetup;
use crate::util::write_atomic;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A `manifest.json` that cannot be read or is not one of this version.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ManifestError(pub String);

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tool {
    pub name: String,
    pub version: String,
}

impl Tool {
    pub fn this() -> Tool {
        Tool {
            name: "aepipe".into(),
            version: env!("CARGO_PKG_VERSION").into(),
        }
    }
}

/// One input file: where, which experiment, its size and digest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputFile {
    pub path: String,
    pub experiment: String,
    pub format: String,
    /// Null when the file could not be read.
    pub size_bytes: Option<u64>,
    /// The SHA-256, or `unreadable: …`.
    pub sha256: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartEntry {
    pub experiment: String,
    pub dir: String,
    pub reused: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Skipped {
    pub path: String,
    pub reason: String,
}

/// One source (experiment) as discovered, with what its recordings say of their setup.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExperimentEntry {
    pub id: String,
    pub format: String,
    pub files: usize,
    pub companions: Vec<String>,
    /// What the recordings say of the acquisition (product, channels' thresholds, gains,
    /// timing parameters, sample rates), one entry per file that says something.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub acquisition: Vec<AcquisitionSetup>,
}

#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TableOut {
    pub path: String,
    pub rows: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outputs {
    pub table: TableOut,
    pub rejects: TableOut,
    pub hits: TableOut,
    pub parametric: TableOut,
    pub markers: TableOut,
    #[serde(default)]
    pub events: TableOut,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoteEntry {
    pub experiment: String,
    pub file: String,
    pub note: String,
    /// Said on the terminal too (a fact about the whole experiment).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub said: bool,
}

/// One record type of one experiment whose `read` is not `rows + rejects`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Unbalanced {
    pub experiment: String,
    pub record_type: crate::model::RecordType,
    pub read: u64,
    pub rows: u64,
    pub rejects: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ManifestCounts {
    pub records_read: u64,
    pub hits_written: u64,
    pub rows_written: u64,
    pub rejects: u64,
    pub parametric_written: u64,
    pub markers_written: u64,
    pub rejects_by_stage: BTreeMap<String, u64>,
    pub by_experiment: BTreeMap<String, Counts>,
    /// Record types whose `read` is not `rows + rejects` (empty when everything read is
    /// accounted for).
    pub unbalanced: Vec<Unbalanced>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Timings {
    pub discover: f64,
    pub hash_inputs: f64,
    pub stream: f64,
    pub total: f64,
}

/// `manifest.json` (documented in `data-schema/manifest.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub tool: Tool,
    pub job: String,
    pub started_utc: String,
    pub finished_utc: String,
    pub threads: usize,
    pub config_sha256: String,
    pub config: PipelineConfig,
    pub inputs: Vec<InputFile>,
    pub parts: Vec<PartEntry>,
    pub skipped: Vec<Skipped>,
    pub experiments: Vec<ExperimentEntry>,
    pub outputs: Outputs,
    /// What the events step did per experiment: setup, its sources, counts.
    #[serde(default)]
    pub events: Vec<crate::events::EventsSummary>,
    pub notes: Vec<NoteEntry>,
    /// Per continuous recording cut by `[detect]`: samples read, hits cut, samples inside
    /// hits.
    #[serde(default)]
    pub streams: Vec<crate::model::StreamTally>,
    pub counts: ManifestCounts,
    pub timings_s: Timings,
    /// The reference map `aepipe run` classified with, by its cache key (added after the SOM
    /// stage; absent for a map not from the cache).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub som_map: Option<SomMapEntry>,
}

/// `manifest.json`'s `som_map`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SomMapEntry {
    pub cache_key: String,
    pub reused: bool,
}

/// Write a `manifest.json` (whole, by rename).
pub fn write_manifest(path: &std::path::Path, m: &Manifest) -> Result<(), crate::util::IoAt> {
    let text = serde_json::to_string_pretty(m).expect("manifest serialises");
    write_atomic(path, text.as_bytes())
}

impl Manifest {
    /// Read a `manifest.json`.
    pub fn read(path: &std::path::Path) -> Result<Manifest, ManifestError> {
        let text = std::fs::read_to_string(path).map_err(|e| ManifestError(e.to_string()))?;
        serde_json::from_str(&text).map_err(|e| ManifestError(e.to_string()))
    }

    /// The counts of the run, as [`StreamStats`] (what `aepipe report` needs of them).
    pub fn stats(&self) -> StreamStats {
        let c = &self.counts;
        StreamStats {
            records_read: c.records_read,
            hits: c.hits_written,
            rows: c.rows_written,
            rejects: c.rejects,
            parametric: c.parametric_written,
            markers: c.markers_written,
            by_experiment: c.by_experiment.clone(),
            by_stage: c.rejects_by_stage.clone(),
            events: self.events.clone(),
            streams: self.streams.clone(),
            ..Default::default()
        }
    }
}

impl ManifestCounts {
    pub fn of(stats: &StreamStats) -> ManifestCounts {
        ManifestCounts {
            records_read: stats.records_read,
            hits_written: stats.hits,
            rows_written: stats.rows,
            rejects: stats.rejects,
            parametric_written: stats.parametric,
            markers_written: stats.markers,
            rejects_by_stage: stats.by_stage.clone(),
            by_experiment: stats.by_experiment.clone(),
            unbalanced: stats
                .unbalanced()
                .into_iter()
                .map(|(experiment, record_type, c)| Unbalanced {
                    experiment,
                    record_type,
                    read: c.read.unwrap_or(0),
                    rows: c.rows,
                    rejects: c.rejects,
                })
                .collect(),
        }
    }
}
