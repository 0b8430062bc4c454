//! `[som]`: where the run's map comes from, its size, seed and label column, and how its
//! erroneous area is read — the SOM room's settings and their checks.

use crate::model::columns as cols;
use crate::util::Checked;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What is wrong with `[som]`: each variant names the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SomSettingsError {
    #[error("som.label must name a column of the features table")]
    NoLabel,
    #[error("som.novelty_quantile must be in (0, 1], not {0}")]
    NoveltyQuantile(f64),
}

/// What the SOM of `aepipe run` is trained on (ch. 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TrainOn {
    /// A simulated reference library (labels = the simulator's mechanisms, ch. 3–4).
    #[default]
    Reference,
    /// A balanced subset of the run's own hits labelled by a column (the ch. 4.7 criteria:
    /// the thesis's ch. 5.4 procedure).
    Criteria,
}

/// The SOM stage of `aepipe run` (ch. 5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SomConfig {
    pub enabled: bool,
    /// `reference`: train on a simulated reference library (labels = mechanism, ch. 3–4);
    /// `criteria`: train on a balanced subset of the run's own hits labelled by the ch. 4.7
    /// criteria (the thesis's ch. 5.4 procedure).
    pub train_on: TrainOn,
    /// Reference library `waveforms.parquet`; empty: build the embedded
    /// `pipelines/reference-library.toml` into the run's folder.
    #[serde(with = "crate::util::empty_is_none")]
    pub reference_library: Option<PathBuf>,
    /// A trained map to classify with instead of training one (a model folder written by
    /// `aepipe som train`, a run's `som/model`, or the Python package's `Som.save`); empty:
    /// train as `train_on` says. A study classified with one lab map, a live test, a
    /// benchmark.
    #[serde(with = "crate::util::empty_is_none")]
    pub model: Option<PathBuf>,
    /// Share of the hits in the training set (ch. 5.4: 10 %; a reference library is used
    /// whole).
    pub fraction: f64,
    pub rows: usize,
    pub cols: usize,
    pub seed: u64,
    /// The features column the classes are checked against in the confusion report and,
    /// with `train_on = "criteria"`, trained on: any column (criteria_label, label,
    /// experiment, channel, …).
    pub label: String,
    /// How the map's erroneous area is read (issue 24): `quality-check` (default) — a hit
    /// is erroneous when the features' time-domain quality check (`quality_fault`) found a
    /// fault, and a sound hit whose BMU is labelled erroneous takes the class of its
    /// nearest node labelled otherwise; `map` — the BMU's label alone, as the thesis read
    /// it (ch. 5.4).
    pub read_erroneous: ReadErroneous,
    /// Novelty (issue 39): a hit farther from its node than this conformal quantile of the
    /// distances of references held out of the map (`som::novelty`) is `unlike_references`.
    /// 0 < q ≤ 1; 1 marks only hits beyond every held-out reference.
    pub novelty_quantile: f64,
}

/// How the SOM stage reads the map's erroneous area (`[som] read_erroneous`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReadErroneous {
    /// Erroneous iff the time-domain quality check found a fault; the map decides among
    /// the other classes. Maps with no node labelled erroneous are read as `Map`.
    #[default]
    QualityCheck,
    /// The BMU's label alone (the thesis's reading).
    Map,
}

impl ReadErroneous {
    pub fn as_str(self) -> &'static str {
        match self {
            ReadErroneous::QualityCheck => "quality-check",
            ReadErroneous::Map => "map",
        }
    }
}

impl Default for SomConfig {
    fn default() -> Self {
        SomConfig {
            label: cols::CRITERIA_LABEL.name.into(),
            enabled: true,
            train_on: TrainOn::Reference,
            reference_library: None,
            model: None,
            fraction: som_defaults::FRACTION,
            rows: som_defaults::ROWS,
            cols: som_defaults::COLS,
            seed: som_defaults::SEED,
            read_erroneous: ReadErroneous::default(),
            novelty_quantile: som_defaults::NOVELTY_QUANTILE,
        }
    }
}

/// The map's defaults, in one place (Table 5.2 and ch. 5.4): the library's
/// `som::SomParams`, `som::tables::TrainOptions`, `[som]` of the pipeline TOML and the CLI's
/// `som train` flags all take them from here.
pub mod som_defaults {
    /// A 10×10 map.
    pub const ROWS: usize = 10;
    pub const COLS: usize = 10;
    /// The seed of the map's initialisation and sample order.
    pub const SEED: u64 = 2008;
    /// Share of the hits in the training set (ch. 5.4: 64 of 651 ≈ 10 %).
    pub const FRACTION: f64 = 0.1;
    /// The seed of `som train`'s training-set draw (a run draws with [`SEED`]).
    pub const TRAINING_SEED: u64 = 5;
    /// `[som] novelty_quantile`: a reference-like hit is novel with chance ≤ 1 %.
    pub const NOVELTY_QUANTILE: f64 = 0.99;
}

/// Where the run's map comes from: `[som] model`, else `train_on` and `reference_library`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapSource<'a> {
    /// A trained map is given: classify with it.
    Given(&'a Path),
    /// Train on a simulated reference library: the named `waveforms.parquet`, or (`None`)
    /// the embedded `pipelines/reference-library.toml` built into the run.
    Reference(Option<&'a Path>),
    /// Train on a balanced subset of the run's own hits labelled by `label` (ch. 5.4).
    Criteria,
}

impl SomConfig {
    /// The checks serde cannot express.
    pub fn check(self) -> Result<Checked<SomConfig>, SomSettingsError> {
        if self.label.trim().is_empty() {
            return Err(SomSettingsError::NoLabel);
        }
        if !(self.novelty_quantile > 0.0 && self.novelty_quantile <= 1.0) {
            return Err(SomSettingsError::NoveltyQuantile(self.novelty_quantile));
        }
        Ok(Checked::new(self))
    }

    /// Where the map comes from.
    pub fn map_source(&self) -> MapSource<'_> {
        match (&self.model, self.train_on) {
            (Some(m), _) => MapSource::Given(m),
            (None, TrainOn::Reference) => MapSource::Reference(self.reference_library.as_deref()),
            (None, TrainOn::Criteria) => MapSource::Criteria,
        }
    }
}
