//! The pipeline file: every room's settings gathered into one [`PipelineConfig`] (what
//! `pipelines/*.toml` may say, with defaults), read once, checked by each room's own check
//! into a [`ValidConfig`] (linfa's validated hyper-parameters), hashed for the manifest.
//!
//! Each room owns its section and its checks, next to its code: `[ingest]`/`[load]`
//! ([`crate::ingest::settings`]), `[dsp]`/`[onset]` ([`crate::dsp::settings`]),
//! `[criteria]`/`[validate]` ([`crate::features::settings`]), `[events]`/`[location]`
//! ([`crate::events::settings`]), `[trend]`/`[evolution]` ([`crate::analysis::settings`]),
//! `[som]` ([`crate::som::settings`]). The sections of the rooms that read the whole
//! configuration and so stand above this one — `[pipeline]` (the streaming runner),
//! `[report]` and `[live]` — are declared here, beside the aggregate. Unknown keys are
//! errors, so a typo in a lab's TOML is reported instead of silently ignored.

use serde::{Deserialize, Serialize};
use std::path::Path;

pub use crate::analysis::settings::{AnalysisSettingsError, Cutoff, EvolutionConfig, TrendConfig};
pub use crate::dsp::settings::{
    BinsConfig, CwtConfig, DspConfig, DspSettingsError, HitConfig, OnsetConfig, Picker,
};
pub use crate::events::settings::{EventsConfig, EventsSettingsError, LocationConfig, ZoneSpec};
pub use crate::features::settings::{CriteriaConfig, FeatureSettingsError, ValidateConfig};
pub use crate::ingest::settings::{
    AewinConfig, Chid, ColumnRef, FormatChoice, IngestConfig, IngestSettingsError, LoadConfig,
    MistrasConfig, ParamInput, VallenConfig, WaveExplorerConfig,
};
pub use crate::model::{ChannelRole, LocationKind};
pub use crate::som::settings::{
    som_defaults, MapSource, ReadErroneous, SomConfig, SomSettingsError, TrainOn,
};

/// A value a room's check refused, by room: each names its key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SettingsError {
    #[error(transparent)]
    Ingest(#[from] IngestSettingsError),
    #[error(transparent)]
    Dsp(#[from] DspSettingsError),
    #[error(transparent)]
    Features(#[from] FeatureSettingsError),
    #[error(transparent)]
    Events(#[from] EventsSettingsError),
    #[error(transparent)]
    Analysis(#[from] AnalysisSettingsError),
    #[error(transparent)]
    Som(#[from] SomSettingsError),
    #[error(transparent)]
    CrackMode(#[from] crate::model::crack::CrackModeError),
    #[error(transparent)]
    Detect(#[from] crate::detect::DetectSettingsError),
    #[error(transparent)]
    Cluster(#[from] crate::cluster::ClusterSettingsError),
    /// `[pipeline]` or `[live]`.
    #[error("{key} {rule}, got {value}")]
    Run {
        key: &'static str,
        rule: &'static str,
        value: f64,
    },
}

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{path}: cannot read config: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    /// The TOML does not parse, or a key is unknown or of the wrong type (serde's words).
    #[error("{path}: {message}")]
    Parse { path: String, message: String },
    /// A value out of range: the file it came from (`config` for text) and the room's
    /// error naming the key.
    #[error("{}: {source}", path.as_deref().unwrap_or("config"))]
    Invalid {
        path: Option<String>,
        source: SettingsError,
    },
}

impl crate::util::HasKind for ConfigError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            ConfigError::Read { .. } | ConfigError::Parse { .. } | ConfigError::Invalid { .. } => {
                crate::util::ErrorKind::Usage
            }
        }
    }
}

/// A room's check error as the configuration's (no file named yet).
macro_rules! invalid_from {
    ($($t:ty),*) => {$(
        impl From<$t> for ConfigError {
            fn from(e: $t) -> ConfigError {
                ConfigError::Invalid {
                    path: None,
                    source: e.into(),
                }
            }
        }
    )*};
}

invalid_from!(
    SettingsError,
    IngestSettingsError,
    DspSettingsError,
    FeatureSettingsError,
    EventsSettingsError,
    AnalysisSettingsError,
    SomSettingsError,
    crate::cluster::ClusterSettingsError
);

#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PipelineConfig {
    pub ingest: IngestConfig,
    /// Cutting continuous recordings into hits (`off` unless set).
    pub detect: crate::detect::DetectConfig,
    pub pipeline: RunConfig,
    pub validate: ValidateConfig,
    pub dsp: DspConfig,
    pub criteria: CriteriaConfig,
    /// The RA–AF crack-mode line (`features`/`hits` `crack_mode`).
    pub crack_mode: crate::model::crack::CrackModeConfig,
    /// Arrival-time picking (`features.parquet` onset columns and `arrival_s`).
    pub onset: OnsetConfig,
    /// Hits → events (the event builder) and where their sources are.
    pub events: EventsConfig,
    pub location: LocationConfig,
    /// Cumulative counts, b- and Ib-value over the test (`evolution.parquet`).
    pub evolution: EvolutionConfig,
    /// `aepipe run` stages after the features.
    pub trend: TrendConfig,
    pub som: SomConfig,
    /// Clustering by the hits' own features (`aepipe cluster`; `aepipe run` with
    /// `enabled = true`).
    pub cluster: crate::cluster::ClusterConfig,
    /// Results written back for the lab's tools (`aepipe export`).
    pub export: crate::export::ExportConfig,
    pub report: ReportConfig,
    /// The test machine's own load file beside the AE files.
    pub load: LoadConfig,
    /// `aepipe watch`: how a running test is followed.
    pub live: LiveConfig,
}

/// `[live]`: how `aepipe watch` follows a test while it runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LiveConfig {
    /// Seconds between flushes: the new rows are written as Parquet parts and committed.
    pub flush_s: f64,
    /// A file is read once its size and modification time have not changed for this long
    /// (an acquisition still writing it would otherwise be read half-written).
    pub settle_s: f64,
    /// Seconds between looks at the inputs.
    pub poll_s: f64,
    /// A hit of a Vallen pair still being written waits this long for its transient (the
    /// acquisition writes it to the `.tradb` a little after the hit) and for the parametric
    /// row after it (its load); then it is read as the offline reader would read it (a hit
    /// without its transient is a reject row).
    pub transient_wait_s: f64,
}

impl Default for LiveConfig {
    fn default() -> Self {
        LiveConfig {
            flush_s: 2.0,
            settle_s: 1.0,
            poll_s: 0.25,
            transient_wait_s: 5.0,
        }
    }
}

/// The HTML report of `aepipe run`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReportConfig {
    pub enabled: bool,
    /// CWT thumbnails per class in the gallery (Appendix B style).
    pub gallery_per_class: usize,
    /// Pictures drawn per kind (trend, damage profile, evolution, location) for at most this
    /// many series, the first in order (experiment, channel): a study of thousands of
    /// experiments keeps its tables whole and its report readable. The report says how
    /// many series it has pictures of.
    pub series_figures: usize,
    /// Hits whose waveform and CWT the explorable charts open on a click, taken from the
    /// gallery across classes in turn (at most the gallery's hits); any other hit shows the
    /// `aepipe cwt` command that draws it.
    pub explorable_hits: usize,
    /// Appendix B: the CWT of every hit, in key order, up to this many, on pages of 100
    /// thumbnails linked from the report (`appendix-b/`); 0: none. Each picture costs an
    /// analysis and a drawing (~25 ms), so a whole test is asked for, not drawn by default.
    pub appendix_b_hits: usize,
}

impl Default for ReportConfig {
    fn default() -> Self {
        ReportConfig {
            enabled: true,
            gallery_per_class: 6,
            series_figures: 24,
            explorable_hits: 48,
            appendix_b_hits: 0,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunConfig {
    /// Records per batch handed to the worker pool.
    pub batch_size: usize,
    /// Batches in flight between stages (bounds memory: about
    /// `(2·queue_batches + 2) · batch_size` waveforms at most).
    pub queue_batches: usize,
    /// Rows per Parquet row group. A reader holds the footer, ~400 bytes per row group and
    /// column, so large tables want large groups; a writer holds one group (~15 MB of
    /// feature rows at 16 384).
    pub row_group_rows: usize,
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            batch_size: 256,
            queue_batches: 2,
            row_group_rows: 16_384,
        }
    }
}

impl RunConfig {
    fn check(&self) -> Result<(), SettingsError> {
        for (key, v) in [
            ("pipeline.batch_size", self.batch_size),
            ("pipeline.queue_batches", self.queue_batches),
            ("pipeline.row_group_rows", self.row_group_rows),
        ] {
            if v == 0 {
                return Err(SettingsError::Run {
                    key,
                    rule: "must be ≥ 1",
                    value: 0.0,
                });
            }
        }
        Ok(())
    }
}

impl LiveConfig {
    fn check(&self) -> Result<(), SettingsError> {
        for (v, key) in [
            (self.flush_s, "live.flush_s"),
            (self.settle_s, "live.settle_s"),
            (self.poll_s, "live.poll_s"),
            (self.transient_wait_s, "live.transient_wait_s"),
        ] {
            if !(v.is_finite() && (0.0..=3600.0).contains(&v)) {
                return Err(SettingsError::Run {
                    key,
                    rule: "must be 0–3600 seconds",
                    value: v,
                });
            }
        }
        if self.poll_s <= 0.0 {
            return Err(SettingsError::Run {
                key: "live.poll_s",
                rule: "must be above 0 seconds",
                value: self.poll_s,
            });
        }
        Ok(())
    }
}

/// A checked pipeline configuration (linfa's "validated hyper-parameters"): only
/// [`PipelineConfig::check`] (and [`PipelineConfig::from_toml`], [`PipelineConfig::from_file`],
/// which call it) makes one, after every room's own check passed, so every stage that takes
/// a `&ValidConfig` works on values that passed them. It reads as a [`PipelineConfig`]
/// (`Deref`); to change a value, take it out with [`ValidConfig::into_inner`] and check it
/// again.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidConfig {
    cfg: PipelineConfig,
    /// `[cluster]` as its own check made it, handed on to the clustering stage as it is.
    cluster: crate::cluster::ValidCluster,
    /// `[ingest]` and `[detect]` as their checks made them, handed on to the readers.
    read: crate::ingest::settings::ReadSettings,
}

impl std::ops::Deref for ValidConfig {
    type Target = PipelineConfig;
    fn deref(&self) -> &PipelineConfig {
        &self.cfg
    }
}

impl Default for ValidConfig {
    fn default() -> Self {
        PipelineConfig::default()
            .check()
            .expect("the default configuration passes its checks")
    }
}

impl ValidConfig {
    pub fn into_inner(self) -> PipelineConfig {
        self.cfg
    }

    /// `[cluster]`, checked once with the rest.
    pub fn cluster(&self) -> &crate::cluster::ValidCluster {
        &self.cluster
    }

    /// `[ingest]` with `[detect]`, checked once with the rest: what every reader reads by.
    pub fn read_settings(&self) -> &crate::ingest::settings::ReadSettings {
        &self.read
    }

    /// The same configuration with `edit` applied, checked again.
    pub fn with(self, edit: impl FnOnce(&mut PipelineConfig)) -> Result<ValidConfig, ConfigError> {
        let mut c = self.cfg;
        edit(&mut c);
        c.check()
    }
}

/// What the per-record transform reads (`FeatureExtractor::new(&cfg)`).
impl From<&ValidConfig> for crate::features::settings::FeatureSettings {
    fn from(c: &ValidConfig) -> Self {
        crate::features::settings::FeatureSettings {
            dsp: c.dsp.clone(),
            criteria: c.criteria.clone(),
            crack_mode: c.crack_mode,
            onset: c.onset.clone(),
            validate: c.validate.clone(),
        }
    }
}

/// What the events step reads (`events::run_part(&tables, &cfg.into())`).
impl From<&ValidConfig> for crate::events::settings::EventsSettings {
    fn from(c: &ValidConfig) -> Self {
        crate::events::settings::EventsSettings {
            events: c.events.clone(),
            location: c.location.clone(),
            picker: c.onset.picker,
            row_group_rows: c.pipeline.row_group_rows,
        }
    }
}

impl PipelineConfig {
    /// Which rows analysis counts, as `[location] exclude_outside` says.
    pub fn source_rows(&self) -> crate::store::SourceRows {
        crate::store::SourceRows {
            exclude_outside: self.location.exclude_outside,
        }
    }

    /// Every room's check, in the file's order: the configuration every stage may rely on.
    /// The rooms' checked values are the sections themselves (checking does not change a
    /// value), so they are handed back whole.
    pub fn check(self) -> Result<ValidConfig, ConfigError> {
        let PipelineConfig {
            ingest,
            detect,
            pipeline,
            validate,
            dsp,
            criteria,
            crack_mode,
            onset,
            events,
            location,
            evolution,
            trend,
            som,
            cluster,
            export,
            report,
            load,
            live,
        } = self;
        pipeline.check()?;
        live.check()?;
        crack_mode.check().map_err(SettingsError::from)?;
        // The readers cut streams as `[detect]` says: they get both sections checked.
        let read = crate::ingest::settings::ReadSettings::new(
            ingest.clone().check()?,
            detect.clone().check().map_err(SettingsError::from)?,
        );
        let dsp = dsp.check()?.into_inner();
        let criteria = criteria.check()?.into_inner();
        let onset = onset.check()?.into_inner();
        let events = events.check()?.into_inner();
        let location = location.check()?.into_inner();
        let evolution = evolution.check()?.into_inner();
        let trend = trend.check()?.into_inner();
        let som = som.check()?.into_inner();
        let valid_cluster = cluster.check().map_err(SettingsError::from)?;
        let load = load.check()?.into_inner();
        Ok(ValidConfig {
            cluster: valid_cluster.clone(),
            read,
            cfg: PipelineConfig {
                ingest,
                detect,
                pipeline,
                validate,
                dsp,
                criteria,
                crack_mode,
                onset,
                events,
                location,
                evolution,
                trend,
                som,
                cluster: valid_cluster.into_inner(),
                export,
                report,
                load,
                live,
            },
        })
    }

    /// Read and check a pipeline TOML file.
    pub fn from_file(path: &Path) -> Result<ValidConfig, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_toml(&text).map_err(|e| match e {
            ConfigError::Parse { message, .. } => ConfigError::Parse {
                path: path.display().to_string(),
                message,
            },
            // A value out of range names the file it came from, like a syntax error.
            ConfigError::Invalid { source, .. } => ConfigError::Invalid {
                path: Some(path.display().to_string()),
                source,
            },
            other => other,
        })
    }

    /// Parse and check TOML text (unknown keys are errors).
    pub fn from_toml(text: &str) -> Result<ValidConfig, ConfigError> {
        let cfg: PipelineConfig = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: "<config>".into(),
            message: e.to_string().replace('\n', " "),
        })?;
        cfg.check()
    }

    /// Canonical TOML of the effective configuration (what the manifest records).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("config serialises")
    }

    /// SHA-256 of the canonical TOML: the same effective settings give the same hash,
    /// whatever the comments or key order of the file they came from.
    pub fn hash(&self) -> String {
        crate::util::sha256_hex(self.to_toml().as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `[detect]` is written once (top level) and the readers see it only through the
    /// checked view: a changed section reaches them, a bad one never does.
    #[test]
    fn the_readers_read_detect_as_the_file_says_it() {
        let cfg = PipelineConfig::from_toml("[detect]\nmode = \"on\"\n").unwrap();
        assert_eq!(
            cfg.read_settings().detect().mode,
            crate::detect::DetectMode::On
        );
        assert_eq!(&**cfg.read_settings().detect(), &cfg.detect);
        let off = cfg
            .clone()
            .with(|c| c.detect.mode = crate::detect::DetectMode::Off)
            .unwrap();
        assert_eq!(
            off.read_settings().detect().mode,
            crate::detect::DetectMode::Off
        );
        assert!(cfg.with(|c| c.detect.block_samples = 0).is_err());
    }

    #[test]
    fn empty_toml_is_the_default() {
        assert_eq!(
            PipelineConfig::from_toml("").unwrap().into_inner(),
            PipelineConfig::default()
        );
    }

    #[test]
    fn typo_is_an_error_naming_the_key() {
        let err = PipelineConfig::from_toml("[ingest]\nsample_rate = 5e6\n").unwrap_err();
        assert!(err.to_string().contains("sample_rate"), "{err}");
    }

    #[test]
    fn hash_ignores_comments_but_not_values() {
        let a = PipelineConfig::from_toml("# hi\n[ingest]\nsample_rate_hz = 5e6\n").unwrap();
        let b = PipelineConfig::from_toml("[ingest]\nsample_rate_hz = 5000000.0\n").unwrap();
        let c = PipelineConfig::from_toml("[ingest]\nsample_rate_hz = 2e6\n").unwrap();
        assert_eq!(a.hash(), b.hash());
        assert_ne!(a.hash(), c.hash());
    }

    #[test]
    fn typed_values_read_and_write_as_their_toml_words() {
        let c = PipelineConfig::from_toml(
            "[trend]\ncutoff = \"time:2.5\"\n[som]\ntrain_on = \"criteria\"\n",
        )
        .unwrap();
        assert_eq!(c.trend.cutoff, Cutoff::Time(2.5));
        assert_eq!(c.som.train_on, TrainOn::Criteria);
        let t = c.to_toml();
        assert!(t.contains("cutoff = \"time:2.5\""), "{t}");
        assert!(t.contains("train_on = \"criteria\""), "{t}");
        assert!(PipelineConfig::from_toml("[som]\ntrain_on = \"maybe\"\n").is_err());
        assert_eq!(c.som.read_erroneous, ReadErroneous::QualityCheck);
        let m = PipelineConfig::from_toml("[som]\nread_erroneous = \"map\"\n").unwrap();
        assert_eq!(m.som.read_erroneous, ReadErroneous::Map);
        assert!(m.to_toml().contains("read_erroneous = \"map\""));
        assert!(PipelineConfig::from_toml("[som]\nread_erroneous = \"both\"\n").is_err());
        let e = PipelineConfig::from_toml("[trend]\ncutoff = \"soon\"\n").unwrap_err();
        assert!(e.to_string().contains("cutoff"), "{e}");
    }

    #[test]
    fn bad_values_are_rejected() {
        assert!(PipelineConfig::from_toml("[ingest]\nsample_rate_hz = -1.0\n").is_err());
        assert!(PipelineConfig::from_toml("[ingest.vallen]\nload_param = \"X7\"\n").is_err());
        assert!(PipelineConfig::from_toml("[pipeline]\nbatch_size = 0\n").is_err());
        assert!(PipelineConfig::from_toml("[criteria]\nclip_min_steps = -1.0\n").is_err());
        assert!(PipelineConfig::from_toml("[criteria]\nclip_min_steps = nan\n").is_err());
        for q in ["0.0", "1.5", "-0.1", "nan"] {
            let t = format!("[som]\nnovelty_quantile = {q}\n");
            let e = PipelineConfig::from_toml(&t).unwrap_err();
            assert!(e.to_string().contains("novelty_quantile"), "{q}: {e}");
        }
        let c = PipelineConfig::from_toml("[som]\nnovelty_quantile = 1.0\n").unwrap();
        assert_eq!(c.som.novelty_quantile, 1.0);
        assert!(c.to_toml().contains("novelty_quantile = 1.0"));
    }

    #[test]
    fn layouts_that_would_leave_bins_empty_are_refused() {
        let mut c = PipelineConfig::default();
        c.dsp.bins.n_windows = 65;
        assert!(c.check().unwrap_err().to_string().contains("n_windows"));
        let mut c = PipelineConfig::default();
        c.dsp.bins.band_hz = 1e13; // band_max / band_hz ≈ 2.5e-7: zero bands
        assert!(c.check().is_err());
        let mut c = PipelineConfig::default();
        c.dsp.band_hz = 1e13;
        assert!(c.check().is_err());
        assert!(PipelineConfig::default().check().is_ok());
    }
}
