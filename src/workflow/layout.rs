//! What an `aepipe run` folder holds, by name: every file a run writes, and every file
//! `aepipe report`, `aepipe merge` (and, later, a watcher or the Python `run()`) read.

use crate::analysis::trend::TrendDir;
use crate::pipeline::StreamDir;
use crate::sim::reference::LibraryDir;
use crate::som::layout::{ClassifyDir, ModelDir};
use crate::store::HitKey;
use std::path::{Path, PathBuf};

/// The folder of one `aepipe run` (or of the merge of a sharded one).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunDir(PathBuf);

impl RunDir {
    pub fn new(p: impl Into<PathBuf>) -> RunDir {
        RunDir(p.into())
    }

    pub fn path(&self) -> &Path {
        &self.0
    }

    /// The feature stage's tables and manifest.
    pub fn features(&self) -> StreamDir {
        StreamDir::new(self.0.join("features"))
    }

    /// The trend stage's table, manifest and plots.
    pub fn trend(&self) -> TrendDir {
        TrendDir::new(self.0.join("trend"))
    }

    /// The SOM stage's classification, damage profile and pictures.
    pub fn som(&self) -> ClassifyDir {
        ClassifyDir::new(self.0.join("som"))
    }

    /// The energy power law per experiment (`statistics.parquet`).
    pub fn statistics(&self) -> PathBuf {
        self.0.join("statistics.parquet")
    }

    /// The tests side by side, one row per experiment (`series.parquet`).
    pub fn series(&self) -> PathBuf {
        self.0.join("series.parquet")
    }

    /// The clustering stage's tables and pictures.
    pub fn cluster(&self) -> PathBuf {
        self.0.join("cluster")
    }

    /// `aepipe export trfdb`'s default folder (`[export] trfdb` in a run).
    pub fn export(&self) -> PathBuf {
        self.0.join("export")
    }

    /// The tables an export reads: the features, and the results the run wrote.
    pub fn run_tables(&self) -> crate::export::RunTables {
        let there = |p: PathBuf| p.is_file().then_some(p);
        let f = self.features();
        let job = crate::pipeline::StreamJob::Features;
        use crate::pipeline::PartTable;
        crate::export::RunTables {
            features: f.table(PartTable::Main, job),
            hits: there(f.table(PartTable::Hits, job)),
            classification: there(self.som().classification()),
            clusters: there(self.cluster().join("clusters.parquet")),
            events: there(f.table(PartTable::Events, job)),
        }
    }

    /// The trained map.
    pub fn som_model(&self) -> ModelDir {
        ModelDir::new(self.0.join("som").join("model"))
    }

    /// The reference library the run built (`[som] reference_library = ""`).
    pub fn reference(&self) -> LibraryDir {
        LibraryDir::new(self.0.join("reference"))
    }

    /// The reference library's features (the map's training input).
    pub fn reference_features(&self) -> StreamDir {
        StreamDir::new(self.0.join("reference-features"))
    }

    /// The CWT pictures of the report's gallery.
    pub fn gallery(&self) -> PathBuf {
        self.0.join("gallery")
    }

    /// One hit's gallery picture (the id made file-safe).
    pub fn gallery_png(&self, key: &HitKey) -> PathBuf {
        self.gallery_file(key, "")
    }
    /// The whole record's picture behind a gallery thumbnail.
    pub fn gallery_full_png(&self, key: &HitKey) -> PathBuf {
        self.gallery_file(key, "_full")
    }
    fn gallery_file(&self, key: &HitKey, suffix: &str) -> PathBuf {
        self.gallery().join(format!(
            "{}_ch{}_hit{}{suffix}.png",
            crate::util::file_safe(&key.0),
            key.1,
            key.2
        ))
    }

    /// Appendix B's pages (`[report] appendix_b_hits`).
    pub fn appendix_b(&self) -> PathBuf {
        self.0.join("appendix-b")
    }

    pub fn report_html(&self) -> PathBuf {
        self.0.join("report.html")
    }

    /// What `aepipe report` needs besides the tables: inputs, truth, config, timings.
    pub fn run_json(&self) -> PathBuf {
        self.0.join("run.json")
    }

    /// The folders a run writes tables into directly (their stale temporary files are
    /// removed before a run).
    pub fn table_dirs(&self) -> [PathBuf; 3] {
        [
            self.0.clone(),
            self.trend().path().to_path_buf(),
            self.som().path().to_path_buf(),
        ]
    }
}
