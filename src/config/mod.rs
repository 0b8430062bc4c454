//! Pipeline configuration: what `pipelines/*.toml` may say, with defaults.
//!
//! Parsed once into a checked [`PipelineConfig`] (linfa's "validated hyper-parameters" idea):
//! unknown keys are errors, so a typo in a lab's TOML is reported instead of silently ignored.

use serde::{Deserialize, Serialize};
use std::path::Path;

mod sources;
pub use sources::{
    ChannelRole, EventsConfig, EvolutionConfig, LocationConfig, LocationKind, OnsetConfig, Picker,
    ZoneSpec,
};

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{path}: cannot read config: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Parse { path: String, message: String },
    #[error("config: {0}")]
    Invalid(String),
}

impl crate::util::HasKind for ConfigError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            ConfigError::Read { .. } | ConfigError::Parse { .. } | ConfigError::Invalid(_) => {
                crate::util::ErrorKind::Usage
            }
        }
    }
}

/// Which hits enter the statistics (in TOML and on the command line: `none`, `peak-load`,
/// `time:SECONDS`, `hits:N`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Cutoff {
    None,
    /// Hits up to (and including) the one at the highest load.
    PeakLoad,
    /// Hits with `time_s ≤` this.
    Time(f64),
    /// The first N hits.
    Hits(usize),
}

impl std::fmt::Display for Cutoff {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Cutoff::None => f.write_str("none"),
            Cutoff::PeakLoad => f.write_str("peak-load"),
            Cutoff::Time(t) => write!(f, "time:{t}"),
            Cutoff::Hits(n) => write!(f, "hits:{n}"),
        }
    }
}

impl TryFrom<String> for Cutoff {
    type Error = ConfigError;
    fn try_from(s: String) -> Result<Cutoff, ConfigError> {
        s.parse()
    }
}

impl From<Cutoff> for String {
    fn from(c: Cutoff) -> String {
        c.to_string()
    }
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

impl std::str::FromStr for Cutoff {
    type Err = ConfigError;
    fn from_str(s: &str) -> Result<Cutoff, ConfigError> {
        let bad = || {
            ConfigError::Invalid(format!(
                "cut-off '{s}': expected none, peak-load, time:SECONDS or hits:N"
            ))
        };
        match s {
            "none" => Ok(Cutoff::None),
            "peak-load" => Ok(Cutoff::PeakLoad),
            _ => match s.split_once(':') {
                Some(("time", v)) => v.parse().map(Cutoff::Time).map_err(|_| bad()),
                Some(("hits", v)) => v.parse().map(Cutoff::Hits).map_err(|_| bad()),
                _ => Err(bad()),
            },
        }
    }
}

/// Input format, detected from the files unless forced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum FormatChoice {
    #[default]
    Auto,
    Vallen,
    Aewin,
    Waveexplorer,
    Wav,
    Csv,
    Text,
    Parquet,
    Mistras,
}

#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PipelineConfig {
    pub ingest: IngestConfig,
    pub pipeline: RunConfig,
    pub validate: ValidateConfig,
    pub dsp: DspConfig,
    pub criteria: CriteriaConfig,
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

/// A column of a delimited file: its header name (surrounding spaces trimmed) or its
/// 1-based index.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ColumnRef {
    Index(usize),
    Name(String),
}

impl std::fmt::Display for ColumnRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ColumnRef::Index(i) => write!(f, "column {i}"),
            ColumnRef::Name(n) => write!(f, "column {n:?}"),
        }
    }
}

/// `[load]`: a test machine (MTS, Zwick, Instron…) that logs load and extension on its own
/// clock into a delimited text file beside the AE recordings. Each hit gets the load and
/// extension interpolated at its time; the file's rows go to `parametric.parquet`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LoadConfig {
    /// Path of the load file relative to the folder that holds the experiment's recordings
    /// (or absolute); `{experiment}` is replaced by the experiment id, `{stem}` by the
    /// recording's file stem (folder name for a folder of one-hit files). Empty: no file.
    pub file: String,
    /// Header name or 1-based index of the time column.
    pub time_column: ColumnRef,
    pub load_column: ColumnRef,
    /// Optional: the extension column.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub extension_column: Option<ColumnRef>,
    /// Multiply the file's time by this to get seconds.
    pub time_scale_s: f64,
    /// Multiply the file's load by this to get newtons (1000 for kN).
    pub load_scale_n: f64,
    /// Multiply the file's extension by this to get metres (0.001 for mm).
    pub extension_scale_m: f64,
    /// Per experiment id: test-machine time = AE time − offset, seconds (0 where absent).
    pub offset_s: std::collections::BTreeMap<String, f64>,
}

impl Default for LoadConfig {
    fn default() -> Self {
        LoadConfig {
            file: String::new(),
            time_column: ColumnRef::Name("Time".into()),
            load_column: ColumnRef::Name("Load".into()),
            extension_column: None,
            time_scale_s: 1.0,
            load_scale_n: 1.0,
            extension_scale_m: 1.0,
            offset_s: Default::default(),
        }
    }
}

/// The trend stage of `aepipe run` (ch. 4.5.5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrendConfig {
    pub enabled: bool,
    /// `none`, `peak-load` (ch. 4.5.5: only hits before the load falls), `time:S`, `hits:N`.
    pub cutoff: Cutoff,
    /// Significance level (Table 4.2: 1 %).
    pub alpha: f64,
}

impl Default for TrendConfig {
    fn default() -> Self {
        TrendConfig {
            enabled: true,
            cutoff: Cutoff::PeakLoad,
            alpha: 0.01,
        }
    }
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
    pub reference_library: String,
    /// A trained map to classify with instead of training one (a model folder written by
    /// `aepipe som train`, a run's `som/model`, or the Python package's `Som.save`); empty:
    /// train as `train_on` says. A study classified with one lab map, a live test, a
    /// benchmark.
    pub model: String,
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
            label: "criteria_label".into(),
            enabled: true,
            train_on: TrainOn::Reference,
            reference_library: String::new(),
            model: String::new(),
            fraction: som_defaults::FRACTION,
            rows: som_defaults::ROWS,
            cols: som_defaults::COLS,
            seed: som_defaults::SEED,
            read_erroneous: ReadErroneous::default(),
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
}

impl Default for ReportConfig {
    fn default() -> Self {
        ReportConfig {
            enabled: true,
            gallery_per_class: 6,
            series_figures: 24,
        }
    }
}

/// Signal processing (thesis ch. 4.5.5, 5.2; DESIGN §4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DspConfig {
    /// Width of one power-ratio band, Hz (Eq. 4.5.4: Δf = 100 kHz).
    pub band_hz: f64,
    /// Upper end of the power-ratio range, Hz (Eq. 4.5.4: 2500 kHz → 25 bands).
    pub band_max_hz: f64,
    pub cwt: CwtConfig,
    pub bins: BinsConfig,
    pub hit: HitConfig,
}

/// The continuous wavelet transform: complex Gabor (Morlet) wavelet on a linear grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CwtConfig {
    pub f_min_hz: f64,
    pub f_max_hz: f64,
    pub n_freqs: usize,
    /// Full width at half maximum of the Gaussian envelope, in periods of the centre
    /// frequency (AGU-Vallen style Gabor wavelet; 2 periods → Δf/f ≈ 0.44). Morlet with
    /// ω0 = 6 is 2.2487 periods.
    pub fwhm_periods: f64,
}

/// The time/frequency bins of ch. 5.2 (Fig. 5.2): normalised |W|² summed over windows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BinsConfig {
    /// Window length in time, s (thesis: 5 µs).
    pub window_s: f64,
    /// Number of time windows from the trigger (8 × 5 µs = 40 µs).
    pub n_windows: usize,
    /// Frequency band of one bin, Hz (thesis: 100 kHz); bands cover 0..dsp.band_max_hz.
    pub band_hz: f64,
}

/// Standard hit features (vallenae / ASTM E1316 conventions).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HitConfig {
    /// Detection threshold, dB_AE, used when the recording does not carry its own
    /// (Vallen records do; they are used unless `use_record_threshold = false`).
    pub threshold_db: f64,
    pub use_record_threshold: bool,
}

/// The ch. 4.7 criteria that label a hit from its CWT (every threshold here).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CriteriaConfig {
    /// The two bond-failure frequencies, Hz (≈250 and ≈750 kHz).
    pub bond_low_hz: f64,
    pub bond_high_hz: f64,
    /// How far a dominant frequency may be from them, Hz (Fig. 4.7: ±10 % of the material
    /// properties moves a fibre's frequency by less than ±150 kHz).
    pub bond_tolerance_hz: f64,
    /// A fibre failure's dominant frequency is above this, Hz (800 kHz).
    pub fibre_min_hz: f64,
    /// …lasts less than this above half power, s (5 µs).
    pub fibre_max_duration_s: f64,
    /// …and arrives within this time of the trigger, s.
    pub fibre_max_arrival_s: f64,
    /// A component counts as present when its peak power is at least this share of the
    /// dominant component's (0.05 in power ≈ 0.22 in amplitude: clearly visible in a CWT).
    pub component_min_ratio: f64,
    /// "both": a bond-like component peaking at least this long after the fibre pulse, s.
    pub both_min_delay_s: f64,
    /// "both": the pulse's peak power is at least this share of the dominant component's
    /// (ch. 5.4: the pulse is "comparable" to the wave; 0.25 in power = 0.5 in amplitude).
    /// A weaker flash at the onset of a wave is the onset, not a fibre failure.
    pub both_min_ratio: f64,
    /// Triggered early: the signal already exceeds the threshold this long before the
    /// trigger, s.
    pub early_trigger_s: f64,
    /// Triggered before the front (ch. 5.4, Fig. 5.8c): the signal first reaches the
    /// threshold this long after the trigger, s (an AE system's own trigger is the first
    /// crossing, so a record whose front comes later was triggered by something else).
    pub late_front_s: f64,
    /// Two bursts: the envelope falls below `burst_quiet_ratio` of the peak for at least
    /// `burst_gap_s`, then rises above `burst_level_ratio` of the peak again.
    pub burst_gap_s: f64,
    pub burst_quiet_ratio: f64,
    pub burst_level_ratio: f64,
    /// Clipped: this many consecutive samples at the record's extreme value…
    pub clip_run: usize,
    /// …or this many samples at it in all (0: off; issue 24: a 250 kHz wave at 10 MHz
    /// clipped at 90 % of its peak sits at the rail 2–3 samples a half-cycle, so the run
    /// alone missed it)…
    pub clip_count: usize,
    /// …when the extreme is at least this many quantisation steps (the smallest gap between
    /// the record's distinct values): a weak record spanning a few ADC codes repeats its top
    /// code without being clipped.
    pub clip_min_steps: f64,
}

impl Default for DspConfig {
    fn default() -> Self {
        DspConfig {
            band_hz: 100e3,
            band_max_hz: 2500e3,
            cwt: CwtConfig::default(),
            bins: BinsConfig::default(),
            hit: HitConfig::default(),
        }
    }
}

impl Default for CwtConfig {
    fn default() -> Self {
        CwtConfig {
            f_min_hz: 10e3,
            f_max_hz: 2500e3,
            n_freqs: 250,
            fwhm_periods: 2.0,
        }
    }
}

impl Default for BinsConfig {
    fn default() -> Self {
        BinsConfig {
            window_s: 5e-6,
            n_windows: 8,
            band_hz: 100e3,
        }
    }
}

impl Default for HitConfig {
    fn default() -> Self {
        HitConfig {
            threshold_db: 40.0,
            use_record_threshold: true,
        }
    }
}

impl Default for CriteriaConfig {
    fn default() -> Self {
        CriteriaConfig {
            bond_low_hz: 250e3,
            bond_high_hz: 750e3,
            bond_tolerance_hz: 150e3,
            fibre_min_hz: 800e3,
            fibre_max_duration_s: 5e-6,
            fibre_max_arrival_s: 5e-6,
            component_min_ratio: 0.05,
            both_min_delay_s: 2e-6,
            both_min_ratio: 0.25,
            early_trigger_s: 10e-6,
            late_front_s: 5e-6,
            burst_gap_s: 5e-6,
            burst_quiet_ratio: 0.25,
            burst_level_ratio: 0.5,
            clip_run: 3,
            clip_count: 8,
            clip_min_steps: 100.0,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IngestConfig {
    /// Force one format for every input file (`auto` detects per file).
    pub format: FormatChoice,
    /// Sampling rate for files that do not carry one (plain text, CSV without a time column).
    /// Thesis: 10 MHz.
    pub sample_rate_hz: f64,
    /// Pretrigger samples for files that do not carry one.
    pub pretrigger_samples: u32,
    /// Preamplifier gain (dB) to divide out of text/CSV/WAV volts (0 = already at the sensor).
    pub gain_db: f64,
    /// The longest record accepted, samples: a size read from a file (a Vallen `Samples`, a
    /// WaveExplorer or WAV header) above it is a reject, checked before anything is
    /// allocated. 50 M samples = 10 s at 5 MHz (200 MiB as f32).
    pub max_samples_per_record: u64,
    pub vallen: VallenConfig,
    pub aewin: AewinConfig,
    pub waveexplorer: WaveExplorerConfig,
    pub mistras: MistrasConfig,
}

/// How MISTRAS `.DTA` parametric inputs (PID 1 = PARA1, …) map to load and extension.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MistrasConfig {
    /// Parametric input carrying the load (PID, e.g. 1 for PARA1); 0 = no load channel.
    pub load_param: u8,
    /// Newtons per volt of that input.
    pub load_n_per_v: f64,
    /// Parametric input carrying the extension; 0 = none.
    pub extension_param: u8,
    /// Metres per volt of that input.
    pub extension_m_per_v: f64,
    /// Sizes of CHIDs the specification leaves open (reserved or undefined ones, e.g.
    /// `31 = 2`), bytes. Without one, a single such CHID in a hit takes what the message
    /// length leaves; two or more end the decoding of that message's features.
    pub chid_sizes: std::collections::BTreeMap<String, usize>,
    /// For a continuation file read alone (its setup is in the base file): the hit features
    /// (CHIDs in record order), hit parametrics per hit and partial-power segments, used only
    /// when the stream holds no hit definition of its own (a manifest note says so).
    pub hit_chids: Vec<u8>,
    pub hit_parametrics: usize,
    pub partial_power_segments: usize,
    /// …the waveform sample rate (Hz, 0 = none) and pretrigger (samples), used for channels
    /// without a waveform setup (message 173,42);
    pub sample_rate_hz: f64,
    pub pretrigger_samples: u32,
    /// …and the gain (dB) for channels without a gain message (23). Unset: 0 dB, noted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gain_db: Option<f64>,
}

impl MistrasConfig {
    /// [`Self::chid_sizes`] as (CHID, bytes); keys are checked by [`PipelineConfig::validate`].
    pub fn size_overrides(&self) -> Vec<(u8, usize)> {
        self.chid_sizes
            .iter()
            .filter_map(|(k, v)| k.trim().parse::<u8>().ok().map(|c| (c, *v)))
            .collect()
    }
}

impl Default for MistrasConfig {
    fn default() -> Self {
        MistrasConfig {
            load_param: 0,
            load_n_per_v: 1.0,
            extension_param: 0,
            extension_m_per_v: 1e-3,
            chid_sizes: Default::default(),
            hit_chids: Vec::new(),
            hit_parametrics: 0,
            partial_power_segments: 0,
            sample_rate_hz: 0.0,
            pretrigger_samples: 0,
            gain_db: None,
        }
    }
}

/// How Vallen parametric inputs (PA0, PA1, …) map to the test machine's load and extension.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VallenConfig {
    /// Parametric column carrying the load (e.g. "PA0"); empty = no load channel.
    pub load_param: String,
    /// Newtons per mV of that parametric input.
    pub load_n_per_mv: f64,
    /// Parametric column carrying the extension (e.g. "PA1"); empty = none.
    pub extension_param: String,
    /// Metres per mV of that parametric input.
    pub extension_m_per_mv: f64,
}

/// MISTRAS AEwin ASCII exports carry neither rate nor pretrigger in the waveform files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AewinConfig {
    pub sample_rate_hz: f64,
    pub pretrigger_samples: u32,
    /// The exported volts include the preamplifier (typically 40 dB); divided out on read.
    pub preamp_gain_db: f64,
    /// AE clock minus test-machine clock, seconds (the two systems start separately).
    pub log_time_offset_s: f64,
}

/// Digital Wave WaveExplorer text exports give the rate in their header, not the pretrigger.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WaveExplorerConfig {
    pub pretrigger_samples: u32,
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

/// Checks that turn a hit into a reject row instead of a feature row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ValidateConfig {
    /// Fewer samples than this is a reject ("too short").
    pub min_samples: usize,
}

impl Default for IngestConfig {
    fn default() -> Self {
        IngestConfig {
            format: FormatChoice::Auto,
            sample_rate_hz: 10e6,
            pretrigger_samples: 0,
            gain_db: 0.0,
            max_samples_per_record: 50_000_000,
            vallen: VallenConfig::default(),
            aewin: AewinConfig::default(),
            waveexplorer: WaveExplorerConfig::default(),
            mistras: MistrasConfig::default(),
        }
    }
}

impl Default for VallenConfig {
    fn default() -> Self {
        VallenConfig {
            load_param: String::new(),
            load_n_per_mv: 1.0,
            extension_param: String::new(),
            extension_m_per_mv: 1e-6,
        }
    }
}

impl Default for AewinConfig {
    fn default() -> Self {
        // Values of the only AEwin export we have (aewin_cfrp_tensile: Start.m says
        // Fs = 5 MHz, PT = 20 µs, 40 dB preamplifier).
        AewinConfig {
            sample_rate_hz: 5e6,
            pretrigger_samples: 100,
            preamp_gain_db: 40.0,
            log_time_offset_s: 0.0,
        }
    }
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

impl Default for ValidateConfig {
    fn default() -> Self {
        ValidateConfig { min_samples: 16 }
    }
}

/// A checked pipeline configuration (linfa's "validated hyper-parameters"): only
/// [`PipelineConfig::check`] (and [`PipelineConfig::from_toml`], [`PipelineConfig::from_file`],
/// which call it) makes one, so every stage that takes a `&ValidConfig` works on values that
/// passed every check. It reads as a [`PipelineConfig`] (`Deref`); to change a value, take
/// it out with [`ValidConfig::into_inner`] and check it again.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidConfig(PipelineConfig);

impl std::ops::Deref for ValidConfig {
    type Target = PipelineConfig;
    fn deref(&self) -> &PipelineConfig {
        &self.0
    }
}

impl Default for ValidConfig {
    fn default() -> Self {
        PipelineConfig::default()
            .check()
            .expect("the default configuration passes its checks")
    }
}

/// A finite, positive number, or the error naming the key.
fn positive(v: f64, what: &str) -> Result<(), ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ConfigError::Invalid(format!("{what} must be > 0, got {v}")))
    }
}

impl ValidConfig {
    pub fn into_inner(self) -> PipelineConfig {
        self.0
    }

    /// The same configuration with `edit` applied, checked again.
    pub fn with(self, edit: impl FnOnce(&mut PipelineConfig)) -> Result<ValidConfig, ConfigError> {
        let mut c = self.0;
        edit(&mut c);
        c.check()
    }
}

impl PipelineConfig {
    /// Check every value serde cannot check: the configuration every stage may rely on.
    pub fn check(self) -> Result<ValidConfig, ConfigError> {
        self.problems()?;
        Ok(ValidConfig(self))
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
            ConfigError::Invalid(message) => ConfigError::Parse {
                path: path.display().to_string(),
                message,
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

    /// The checks that serde cannot express.
    fn problems(&self) -> Result<(), ConfigError> {
        if self.ingest.max_samples_per_record == 0 {
            return Err(ConfigError::Invalid(
                "ingest.max_samples_per_record must be ≥ 1".into(),
            ));
        }
        positive(self.ingest.sample_rate_hz, "ingest.sample_rate_hz")?;
        positive(
            self.ingest.aewin.sample_rate_hz,
            "ingest.aewin.sample_rate_hz",
        )?;
        if self.som.label.trim().is_empty() {
            return Err(ConfigError::Invalid(
                "som.label must name a column of the features table".into(),
            ));
        }
        if !(self.trend.alpha > 0.0 && self.trend.alpha < 1.0) {
            return Err(ConfigError::Invalid(format!(
                "trend.alpha must be in (0, 1), got {}",
                self.trend.alpha
            )));
        }
        if self.pipeline.batch_size == 0 {
            return Err(ConfigError::Invalid(
                "pipeline.batch_size must be ≥ 1".into(),
            ));
        }
        if self.pipeline.queue_batches == 0 {
            return Err(ConfigError::Invalid(
                "pipeline.queue_batches must be ≥ 1".into(),
            ));
        }
        if self.pipeline.row_group_rows == 0 {
            return Err(ConfigError::Invalid(
                "pipeline.row_group_rows must be ≥ 1".into(),
            ));
        }
        let m = self.criteria.clip_min_steps;
        if !(m.is_finite() && m >= 0.0) {
            return Err(ConfigError::Invalid(format!(
                "criteria.clip_min_steps must be a number ≥ 0, got {m}"
            )));
        }
        let d = &self.dsp;
        positive(d.band_hz, "dsp.band_hz")?;
        positive(d.band_max_hz, "dsp.band_max_hz")?;
        positive(d.cwt.f_min_hz, "dsp.cwt.f_min_hz")?;
        positive(d.cwt.fwhm_periods, "dsp.cwt.fwhm_periods")?;
        positive(d.bins.window_s, "dsp.bins.window_s")?;
        positive(d.bins.band_hz, "dsp.bins.band_hz")?;
        if d.cwt.f_max_hz < d.cwt.f_min_hz || d.cwt.n_freqs == 0 {
            return Err(ConfigError::Invalid(
                "dsp.cwt: need f_max_hz ≥ f_min_hz and n_freqs ≥ 1".into(),
            ));
        }
        // The feature path sums at most 64 windows (a fixed edge table): more would leave
        // the later bins silently zero.
        if d.bins.n_windows == 0 || d.bins.n_windows > 64 {
            return Err(ConfigError::Invalid(format!(
                "dsp.bins.n_windows must be 1 to 64, got {}",
                d.bins.n_windows
            )));
        }
        let bands = d.band_max_hz / d.band_hz;
        if (bands - bands.round()).abs() > 1e-9 || bands.round() > 1000.0 || bands.round() < 1.0 {
            return Err(ConfigError::Invalid(format!(
                "dsp.band_max_hz / dsp.band_hz must be a whole number of bands (≤ 1000), got {bands}"
            )));
        }
        let bin_bands = d.band_max_hz / d.bins.band_hz;
        if (bin_bands - bin_bands.round()).abs() > 1e-9 || bin_bands.round() < 1.0 {
            return Err(ConfigError::Invalid(format!(
                "dsp.band_max_hz / dsp.bins.band_hz must be a whole number, got {bin_bands}"
            )));
        }
        sources::check(&self.onset, &self.events, &self.location)?;
        sources::check_evolution(&self.evolution)?;
        let l = &self.live;
        for (v, name) in [
            (l.flush_s, "live.flush_s"),
            (l.settle_s, "live.settle_s"),
            (l.poll_s, "live.poll_s"),
            (l.transient_wait_s, "live.transient_wait_s"),
        ] {
            if !(v.is_finite() && (0.0..=3600.0).contains(&v)) {
                return Err(ConfigError::Invalid(format!(
                    "{name} must be 0–3600 seconds, got {v}"
                )));
            }
        }
        if l.poll_s <= 0.0 {
            return Err(ConfigError::Invalid(format!(
                "live.poll_s must be above 0 seconds, got {}",
                l.poll_s
            )));
        }
        let m = &self.ingest.mistras;
        for (k, v) in &m.chid_sizes {
            if k.trim().parse::<u8>().map_or(true, |c| c == 0) || *v > 4096 {
                return Err(ConfigError::Invalid(format!(
                    "ingest.mistras.chid_sizes: {k:?} = {v}: keys are CHIDs 1–255, sizes at most 4096 bytes"
                )));
            }
        }
        if !(m.sample_rate_hz >= 0.0 && m.sample_rate_hz.is_finite()) {
            return Err(ConfigError::Invalid(format!(
                "ingest.mistras.sample_rate_hz must be ≥ 0, got {}",
                m.sample_rate_hz
            )));
        }
        if m.partial_power_segments > 255 || m.hit_parametrics > 255 {
            return Err(ConfigError::Invalid(
                "ingest.mistras: partial_power_segments and hit_parametrics are at most 255".into(),
            ));
        }
        let l = &self.load;
        positive(l.time_scale_s, "load.time_scale_s")?;
        positive(l.load_scale_n, "load.load_scale_n")?;
        positive(l.extension_scale_m, "load.extension_scale_m")?;
        for c in [
            Some(&l.time_column),
            Some(&l.load_column),
            l.extension_column.as_ref(),
        ]
        .into_iter()
        .flatten()
        {
            if matches!(c, ColumnRef::Index(0))
                || matches!(c, ColumnRef::Name(n) if n.trim().is_empty())
            {
                return Err(ConfigError::Invalid(format!(
                    "load: {c} is not a column (indices start at 1, names must not be empty)"
                )));
            }
        }
        if let Some((k, v)) = l.offset_s.iter().find(|(_, v)| !v.is_finite()) {
            return Err(ConfigError::Invalid(format!(
                "load.offset_s.{k} must be a finite number of seconds, got {v}"
            )));
        }
        for p in [
            &self.ingest.vallen.load_param,
            &self.ingest.vallen.extension_param,
        ] {
            let well_formed =
                p.is_empty() || (p.starts_with("PA") && p[2..].parse::<u32>().is_ok());
            if !well_formed {
                return Err(ConfigError::Invalid(format!(
                    "ingest.vallen: parametric input must look like PA0, PA1, …; got {p:?}"
                )));
            }
        }
        Ok(())
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
