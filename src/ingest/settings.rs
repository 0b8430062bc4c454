//! `[ingest]` (and its per-format sections) and `[load]`: how recordings are read. The
//! ingest room owns these settings and their checks ([`IngestConfig::check`],
//! [`LoadConfig::check`]); `config` only gathers them into the pipeline file.

use crate::util::Checked;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// What is wrong with `[ingest]` or `[load]`: each variant names the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IngestSettingsError {
    #[error("{key} must be > 0, got {value}")]
    NotPositive { key: &'static str, value: f64 },
    #[error("ingest.max_samples_per_record must be ≥ 1")]
    NoSamples,
    #[error("ingest.mistras.chid_sizes: {chid} = {size}: sizes are at most 4096 bytes")]
    ChidSize { chid: u8, size: usize },
    #[error("ingest.mistras.sample_rate_hz must be ≥ 0, got {0}")]
    MistrasRate(f64),
    #[error("ingest.mistras: partial_power_segments and hit_parametrics are at most 255")]
    MistrasCounts,
    #[error("load: {0} is not a column (indices start at 1, names must not be empty)")]
    Column(ColumnRef),
    #[error("load.offset_s.{experiment} must be a finite number of seconds, got {value}")]
    Offset { experiment: String, value: f64 },
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

/// What every reader reads by: `[ingest]` and `[detect]` (how a continuous recording is cut
/// into hits), both checked. The pipeline file keeps each section once; this is the
/// checked view the configuration's check hands to the readers
/// (`ValidConfig::read_settings`), never edited in place: change the sections and check again.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ReadSettings {
    ingest: IngestConfig,
    detect: crate::detect::ValidDetect,
}

impl ReadSettings {
    pub fn new(ingest: Checked<IngestConfig>, detect: crate::detect::ValidDetect) -> ReadSettings {
        ReadSettings {
            ingest: ingest.into_inner(),
            detect,
        }
    }

    /// `[detect]`, checked.
    pub fn detect(&self) -> &crate::detect::ValidDetect {
        &self.detect
    }
}

impl std::ops::Deref for ReadSettings {
    type Target = IngestConfig;
    fn deref(&self) -> &IngestConfig {
        &self.ingest
    }
}

/// A MISTRAS characteristic id (CHID, 1–255): a key of `[ingest.mistras] chid_sizes`,
/// written as a string in TOML (`31 = 2`). A key that is not one is refused when the file
/// is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct Chid(pub u8);

impl Serialize for Chid {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(&self.0)
    }
}

impl<'de> Deserialize<'de> for Chid {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Chid, D::Error> {
        let s = String::deserialize(d)?;
        match s.trim().parse::<u8>() {
            Ok(c) if c > 0 => Ok(Chid(c)),
            _ => Err(serde::de::Error::custom(format!(
                "chid_sizes key {s:?}: keys are CHIDs 1–255"
            ))),
        }
    }
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
    pub chid_sizes: BTreeMap<Chid, usize>,
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
    /// [`Self::chid_sizes`] as (CHID, bytes).
    pub fn size_overrides(&self) -> Vec<(u8, usize)> {
        self.chid_sizes.iter().map(|(k, v)| (k.0, *v)).collect()
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

/// A Vallen parametric input (`PA0`, `PA1`, …): its column of `ae_data`. Written `"PA0"`
/// in TOML; `""` is none.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParamInput(pub u32);

impl ParamInput {
    /// The `ae_data` column (`PA0`).
    pub fn column(self) -> String {
        format!("PA{}", self.0)
    }
}

/// `Option<ParamInput>` as TOML writes it: `"PA0"`, or `""` for none (the file format
/// before the type existed, kept so the canonical TOML and its hash do not change).
mod param_input {
    use super::ParamInput;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(p: &Option<ParamInput>, s: S) -> Result<S::Ok, S::Error> {
        match p {
            Some(p) => s.serialize_str(&p.column()),
            None => s.serialize_str(""),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<ParamInput>, D::Error> {
        let s = String::deserialize(d)?;
        if s.is_empty() {
            return Ok(None);
        }
        s.strip_prefix("PA")
            .and_then(|n| n.parse::<u32>().ok())
            .map(|n| Some(ParamInput(n)))
            .ok_or_else(|| {
                serde::de::Error::custom(format!(
                    "parametric input must look like PA0, PA1, …; got {s:?}"
                ))
            })
    }
}

/// How Vallen parametric inputs (PA0, PA1, …) map to the test machine's load and extension.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VallenConfig {
    /// Parametric input carrying the load (e.g. "PA0"); empty = no load channel.
    #[serde(with = "param_input")]
    pub load_param: Option<ParamInput>,
    /// Newtons per mV of that parametric input.
    pub load_n_per_mv: f64,
    /// Parametric input carrying the extension (e.g. "PA1"); empty = none.
    #[serde(with = "param_input")]
    pub extension_param: Option<ParamInput>,
    /// Metres per mV of that parametric input.
    pub extension_m_per_mv: f64,
}

/// MISTRAS AEwin ASCII exports: a header-less waveform file carries neither rate nor
/// pretrigger; a file with a header carries the rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AewinConfig {
    /// The rate of header-less waveform files. Unset: the rate the test's hit list implies
    /// (its rise times against the waveforms), else [`AEWIN_DEFAULT_RATE_HZ`]. Set: this
    /// rate, even where the hit list implies another (which is said).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
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
            load_param: None,
            load_n_per_mv: 1.0,
            extension_param: None,
            extension_m_per_mv: 1e-6,
        }
    }
}

/// The rate of a header-less AEwin export when neither the pipeline file nor a hit list
/// says otherwise: that of the only AEwin export we have (aewin_cfrp_tensile, `Start.m`).
pub const AEWIN_DEFAULT_RATE_HZ: f64 = 5e6;

impl AewinConfig {
    /// The rate to read header-less files at before a hit list is consulted.
    pub fn configured_rate_hz(&self) -> f64 {
        self.sample_rate_hz.unwrap_or(AEWIN_DEFAULT_RATE_HZ)
    }
}

impl Default for AewinConfig {
    fn default() -> Self {
        // Values of the only AEwin export we have (aewin_cfrp_tensile: Start.m says
        // Fs = 5 MHz, PT = 20 µs, 40 dB preamplifier).
        AewinConfig {
            sample_rate_hz: None,
            pretrigger_samples: 100,
            preamp_gain_db: 40.0,
            log_time_offset_s: 0.0,
        }
    }
}

fn positive(v: f64, key: &'static str) -> Result<(), IngestSettingsError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(IngestSettingsError::NotPositive { key, value: v })
    }
}

impl IngestConfig {
    /// The checks serde cannot express.
    pub fn check(self) -> Result<Checked<IngestConfig>, IngestSettingsError> {
        if self.max_samples_per_record == 0 {
            return Err(IngestSettingsError::NoSamples);
        }
        positive(self.sample_rate_hz, "ingest.sample_rate_hz")?;
        if let Some(r) = self.aewin.sample_rate_hz {
            positive(r, "ingest.aewin.sample_rate_hz")?;
        }
        let m = &self.mistras;
        if let Some((c, s)) = m.chid_sizes.iter().find(|(_, s)| **s > 4096) {
            return Err(IngestSettingsError::ChidSize {
                chid: c.0,
                size: *s,
            });
        }
        if !(m.sample_rate_hz >= 0.0 && m.sample_rate_hz.is_finite()) {
            return Err(IngestSettingsError::MistrasRate(m.sample_rate_hz));
        }
        if m.partial_power_segments > 255 || m.hit_parametrics > 255 {
            return Err(IngestSettingsError::MistrasCounts);
        }
        Ok(Checked::new(self))
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
    #[serde(with = "crate::util::empty_is_none")]
    pub file: Option<PathBuf>,
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
    pub offset_s: BTreeMap<String, f64>,
}

impl Default for LoadConfig {
    fn default() -> Self {
        LoadConfig {
            file: None,
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

impl LoadConfig {
    /// The checks serde cannot express.
    pub fn check(self) -> Result<Checked<LoadConfig>, IngestSettingsError> {
        positive(self.time_scale_s, "load.time_scale_s")?;
        positive(self.load_scale_n, "load.load_scale_n")?;
        positive(self.extension_scale_m, "load.extension_scale_m")?;
        for c in [
            Some(&self.time_column),
            Some(&self.load_column),
            self.extension_column.as_ref(),
        ]
        .into_iter()
        .flatten()
        {
            if matches!(c, ColumnRef::Index(0))
                || matches!(c, ColumnRef::Name(n) if n.trim().is_empty())
            {
                return Err(IngestSettingsError::Column(c.clone()));
            }
        }
        if let Some((k, v)) = self.offset_s.iter().find(|(_, v)| !v.is_finite()) {
            return Err(IngestSettingsError::Offset {
                experiment: k.clone(),
                value: *v,
            });
        }
        Ok(Checked::new(self))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typed_keys_read_and_write_as_the_file_format_did() {
        let v: VallenConfig =
            toml::from_str("load_param = \"PA0\"\nextension_param = \"\"\n").unwrap();
        assert_eq!(
            (v.load_param, v.extension_param),
            (Some(ParamInput(0)), None)
        );
        let t = toml::to_string(&v).unwrap();
        assert!(t.contains("load_param = \"PA0\"") && t.contains("extension_param = \"\""));
        assert!(toml::from_str::<VallenConfig>("load_param = \"X7\"\n").is_err());
        let m: MistrasConfig = toml::from_str("[chid_sizes]\n31 = 2\n").unwrap();
        assert_eq!(m.size_overrides(), [(31, 2)]);
        assert!(toml::from_str::<MistrasConfig>("[chid_sizes]\n3x = 2\n").is_err());
        assert!(toml::from_str::<MistrasConfig>("[chid_sizes]\n0 = 2\n").is_err());
        let l: LoadConfig = toml::from_str("file = \"\"\n").unwrap();
        assert_eq!(l.file, None);
        assert!(toml::to_string(&l).unwrap().contains("file = \"\""));
    }
}
