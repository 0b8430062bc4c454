//! What a streaming job's folder holds, by name: the six tables ([`PartTable`]), the
//! manifest, the per-experiment parts ([`PartDir`]) and, for a sharded run, the Hive
//! dataset. Every path of such a folder is spelled here and nowhere else.

use super::StreamJob;
use crate::config::PipelineConfig;
use crate::features::features_table;
use crate::store::{self, TableSchema};
use std::path::{Path, PathBuf};

/// The tables a streaming job writes — into each part folder, each shard's Hive dataset and
/// the whole-batch folder — in assembly order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum PartTable {
    /// `features.parquet` or `waveforms.parquet`, by job.
    Main,
    Hits,
    Rejects,
    Parametric,
    Markers,
    /// `events.parquet`, written by the events step after the stream.
    Events,
}

impl PartTable {
    pub const ALL: [PartTable; 6] = [
        PartTable::Main,
        PartTable::Hits,
        PartTable::Rejects,
        PartTable::Parametric,
        PartTable::Markers,
        PartTable::Events,
    ];

    /// The table's name: its file stem and its Hive folder.
    pub fn stem(self, job: StreamJob) -> &'static str {
        match self {
            PartTable::Main => job.name(),
            PartTable::Hits => "hits",
            PartTable::Rejects => "rejects",
            PartTable::Parametric => "parametric",
            PartTable::Markers => "markers",
            PartTable::Events => "events",
        }
    }

    pub fn file_name(self, job: StreamJob) -> &'static str {
        match self {
            PartTable::Main => job.table_file(),
            PartTable::Hits => "hits.parquet",
            PartTable::Rejects => "rejects.parquet",
            PartTable::Parametric => "parametric.parquet",
            PartTable::Markers => "markers.parquet",
            PartTable::Events => "events.parquet",
        }
    }

    pub fn schema(self, job: StreamJob, cfg: &PipelineConfig) -> TableSchema {
        match (self, job) {
            (PartTable::Main, StreamJob::Features) => {
                features_table(&cfg.dsp, cfg.crack_mode).schema()
            }
            (PartTable::Main, StreamJob::Waveforms) => store::waveforms_table().schema(),
            (PartTable::Hits, _) => store::hits_table(Default::default()).schema(),
            (PartTable::Rejects, _) => store::rejects_table().schema(),
            (PartTable::Parametric, _) => store::parametric_table().schema(),
            (PartTable::Markers, _) => store::markers_table().schema(),
            (PartTable::Events, _) => crate::events::events_table().schema(),
        }
    }
}

/// The output folder of a streaming job (`aepipe features|waveforms --out DIR`, a run's
/// `features/`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StreamDir(PathBuf);

impl StreamDir {
    pub fn new(p: impl Into<PathBuf>) -> StreamDir {
        StreamDir(p.into())
    }

    pub fn path(&self) -> &Path {
        &self.0
    }

    /// A whole-batch table.
    pub fn table(&self, t: PartTable, job: StreamJob) -> PathBuf {
        self.0.join(t.file_name(job))
    }

    pub fn manifest(&self) -> PathBuf {
        self.0.join("manifest.json")
    }

    /// The folder of the per-experiment parts.
    pub fn parts(&self) -> PathBuf {
        self.0.join("parts")
    }

    /// One experiment's part: its file-safe id and a short hash of the id itself, so two ids
    /// that sanitise alike never share a folder.
    pub fn part(&self, id: &str) -> PartDir {
        let h = crate::util::sha256_hex(id.as_bytes());
        PartDir(
            self.parts()
                .join(format!("{}-{}", crate::util::file_safe(id), &h[..8])),
        )
    }

    /// A sharded run's file of `table` for `experiment`, published by shard `k`
    /// (`DIR/<table>/experiment=<id>/part-K.parquet`).
    pub fn hive_file(&self, t: PartTable, job: StreamJob, experiment: &str, k: u32) -> PathBuf {
        store::shard::hive_file(&self.0, t.stem(job), experiment, k)
    }

    /// A sharded run's Hive folder of `table`.
    pub fn hive_dir(&self, t: PartTable, job: StreamJob) -> PathBuf {
        self.0.join(t.stem(job))
    }
}

/// One experiment's part folder: its six tables and `part.json`, written last.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PartDir(PathBuf);

impl PartDir {
    pub fn path(&self) -> &Path {
        &self.0
    }

    pub fn table(&self, t: PartTable, job: StreamJob) -> PathBuf {
        self.0.join(t.file_name(job))
    }

    pub fn record(&self) -> PathBuf {
        self.0.join("part.json")
    }
}
