//! The vocabulary every room shares: one AE hit ([`AeRecord`]), the damage mechanisms
//! ([`Mechanism`]) and the reject record ([`Reject`]) that keeps a bad hit from being lost.
//!
//! SI units inside: seconds, hertz, volts, newtons, metres. Nothing in here depends on any
//! other module of the crate.

pub mod columns;
pub mod crack;

use std::fmt;

/// One acoustic-emission hit: a transient waveform and what is known about it.
#[derive(Debug, Clone, PartialEq)]
pub struct AeRecord {
    /// Experiment id: file stem of a Vallen pair or multi-hit file, folder name otherwise.
    pub experiment: String,
    /// Sensor channel (1-based as the acquisition system numbers them; 0 if unknown).
    pub channel: u32,
    /// Hit number inside the experiment (Vallen TRAI, AEwin hit #, event #; 1-based).
    pub hit: u64,
    /// Trigger time since the start of the acquisition, seconds (`None`: the format does not
    /// record it, e.g. WaveExplorer events, WAV and CSV files).
    pub time_s: Option<f64>,
    /// Sampling rate, Hz.
    pub sample_rate_hz: f64,
    /// Number of samples recorded before the trigger.
    pub pretrigger: u32,
    /// The waveform, volts at the sensor (after removing preamplifier gain where known).
    pub samples: Vec<f32>,
    /// Test-machine load at the hit time, newtons.
    pub load_n: Option<f64>,
    /// Test-machine extension at the hit time, metres.
    pub extension_m: Option<f64>,
    /// Ground-truth or user label (simulator mechanism, hand label), if any.
    pub label: Option<String>,
    /// Detection threshold the acquisition used, volts (Vallen `Thr`), if recorded.
    pub threshold_v: Option<f64>,
    /// The file the samples came from.
    pub source_file: String,
    /// Whether a hit of the acquisition points to this record, or it stands alone.
    pub kind: RecordKind,
}

/// Whether a transient record belongs to a hit (`features.parquet`/`waveforms.parquet`
/// column `record_kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RecordKind {
    /// The waveform of a hit (a hit row links to it, or the format has no hit list and the
    /// record is its own hit).
    #[default]
    Hit,
    /// A waveform no hit points to: a MISTRAS waveform message without its hit message
    /// (e.g. an automatic sensor test), a `.tradb` transient no `.pridb` hit links to.
    Standalone,
}

impl RecordKind {
    pub fn as_str(self) -> &'static str {
        match self {
            RecordKind::Hit => "hit",
            RecordKind::Standalone => "standalone",
        }
    }

    pub fn parse(s: &str) -> Option<RecordKind> {
        [RecordKind::Hit, RecordKind::Standalone]
            .into_iter()
            .find(|k| k.as_str() == s)
    }
}

impl AeRecord {
    /// A short id for messages: `experiment ch1 hit 17`.
    pub fn id(&self) -> String {
        format!("{} ch{} hit {}", self.experiment, self.channel, self.hit)
    }

    /// Duration of the record, seconds.
    pub fn duration_s(&self) -> f64 {
        self.samples.len() as f64 / self.sample_rate_hz
    }
}

/// A hit (or a whole file) that could not become a feature row, and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Reject {
    pub experiment: String,
    pub source_file: String,
    /// Which record: `ch1 hit 17`, `TRAI 12`, `event 3`, or empty for a whole file.
    pub record_id: String,
    /// Pipeline stage: `discover`, `read`, `validate`, `features`.
    pub stage: Stage,
    /// One line saying what is wrong.
    pub reason: String,
    /// What kind of record is lost: a transient (most rejects), a hit, a parametric or
    /// marker row, or a whole file (or the rest of one) of unknown content.
    #[serde(default)]
    pub record_type: RecordType,
}

impl Reject {
    /// A record (its transient) that a stage refused: `ch<channel> hit <hit>` of its file.
    pub fn of_record(r: &AeRecord, stage: Stage, reason: String) -> Reject {
        Reject {
            record_type: RecordType::Transient,
            experiment: r.experiment.clone(),
            source_file: r.source_file.clone(),
            record_id: format!("ch{} hit {}", r.channel, r.hit),
            stage,
            reason,
        }
    }
}

/// The kinds of record a recording holds, for the accounting of what was read and where it
/// went (`manifest.json` `counts.by_experiment.*.records`, `rejects.parquet` `record_type`).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    Hash,
    Default,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum RecordType {
    /// A hit (Vallen `SetType` 2, MISTRAS message 1, a row of a hit list).
    Hit,
    /// A transient waveform (Vallen `tr_data`, MISTRAS message 173, a file of a folder).
    #[default]
    Transient,
    /// A parametric / time-driven row (Vallen `SetType` 1, MISTRAS message 2/3, a row of
    /// the test machine's load file).
    Parametric,
    /// A status row (Vallen `SetType` 3).
    Status,
    /// A marker: label, date/time, section start (Vallen `SetType` 4–6); a MISTRAS
    /// start/stop/pause/comment message.
    Marker,
    /// A whole file, or the rest of one, whose records could not be told apart.
    File,
}

impl RecordType {
    pub const ALL: [RecordType; 6] = [
        RecordType::Hit,
        RecordType::Transient,
        RecordType::Parametric,
        RecordType::Status,
        RecordType::Marker,
        RecordType::File,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            RecordType::Hit => "hit",
            RecordType::Transient => "transient",
            RecordType::Parametric => "parametric",
            RecordType::Status => "status",
            RecordType::Marker => "marker",
            RecordType::File => "file",
        }
    }
}

impl fmt::Display for RecordType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Where in the pipeline a reject happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    Discover,
    Read,
    Validate,
    Features,
}

impl Stage {
    pub fn as_str(self) -> &'static str {
        match self {
            Stage::Discover => "discover",
            Stage::Read => "read",
            Stage::Validate => "validate",
            Stage::Features => "features",
        }
    }
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Which acquisition system recorded a hit row's features.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HitSource {
    /// Vallen `.pridb` (`ae_data`, `SetType` 2).
    Vallen,
    /// MISTRAS `.DTA` (message 1).
    Mistras,
    /// MISTRAS AEwin ASCII hit list (`<EXP>.TXT`).
    AewinList,
    /// A format without a hit list: the hit is its transient record, no hardware features.
    #[default]
    Record,
    /// Cut from a continuous recording by `[detect]`: the detector's time, duration and
    /// features.
    Detected,
}

impl HitSource {
    pub fn as_str(self) -> &'static str {
        match self {
            HitSource::Vallen => "vallen",
            HitSource::Mistras => "mistras",
            HitSource::AewinList => "aewin",
            HitSource::Record => "record",
            HitSource::Detected => "detect",
        }
    }
}

/// One hit as the acquisition system recorded it: a row of `hits.parquet`. The features
/// are the system's own (not recomputed), in SI units; `None` where the system does not
/// record one. `transient` is the `hit` of its transient record in the feature and waveform
/// tables, `None` when the hit has no transient.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HitRow {
    pub experiment: String,
    /// 1-based: a Vallen database restarted into the same file holds several.
    pub acquisition: u32,
    pub channel: u32,
    /// 1-based order of the hit in its experiment, as the system stored them.
    pub hit: u64,
    pub time_s: Option<f64>,
    pub amplitude_db: Option<f64>,
    pub threshold_db: Option<f64>,
    pub rise_time_s: Option<f64>,
    pub duration_s: Option<f64>,
    pub counts: Option<i64>,
    pub counts_to_peak: Option<i64>,
    /// Vallen energy, eu (1 eu = 1e-14 V²s).
    pub energy_eu: Option<f64>,
    /// MISTRAS `ENER`, the system's energy counts.
    pub energy_counts: Option<f64>,
    /// MISTRAS `ABS-ENERGY`, attojoules.
    pub abs_energy_aj: Option<f64>,
    pub signal_strength_vs: Option<f64>,
    pub rms_v: Option<f64>,
    pub avg_freq_hz: Option<f64>,
    pub centroid_freq_hz: Option<f64>,
    pub peak_freq_hz: Option<f64>,
    pub load_n: Option<f64>,
    pub extension_m: Option<f64>,
    /// The hit's parametric inputs as a JSON object of volts (`{"PA0": 1.2}`), if any.
    pub parametric: Option<String>,
    pub transient: Option<u64>,
    /// Vallen's transient index as stored (restarts with each acquisition).
    pub trai: Option<i64>,
    /// Further features the system recorded, as a JSON object under the vendor's names with
    /// their units (a Vallen `.trfdb`, MISTRAS CHIDs without a column here).
    pub vendor_features: Option<String>,
    pub source: HitSource,
    pub source_file: String,
    /// The system's hit flags as stored (Vallen `Status`).
    pub status: Option<i64>,
    /// An AEwin test with a hit list: `matched` (a list row and its waveform),
    /// `no_list_row` (a waveform the list lacks), `no_waveform` (a row without a waveform).
    pub list_status: Option<&'static str>,
}

impl HitRow {
    /// The hit row of a transient record from a format without a hit list.
    pub fn of_record(r: &AeRecord) -> HitRow {
        HitRow {
            experiment: r.experiment.clone(),
            acquisition: 1,
            channel: r.channel,
            hit: r.hit,
            time_s: r.time_s,
            threshold_db: r.threshold_v.filter(|t| *t > 0.0).map(db_ae),
            load_n: r.load_n,
            extension_m: r.extension_m,
            transient: Some(r.hit),
            source: HitSource::Record,
            source_file: r.source_file.clone(),
            ..Default::default()
        }
    }
}

/// Something a reader wants the manifest to say about a file (a default it had to assume).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Note {
    pub experiment: String,
    pub source_file: String,
    pub message: String,
    /// Said on the terminal too: a fact about the whole experiment a reader of its numbers
    /// must know (the rate an export implies, hits the machine log does not cover), one
    /// line that names the experiment.
    #[serde(default)]
    pub said: bool,
}

impl Note {
    /// A note as a reader's item: `source_file` the file it is about; `said` when the terminal
    /// says it too.
    pub fn item(experiment: &str, source_file: &str, message: String, said: bool) -> Item {
        Item::Note(Note {
            experiment: experiment.to_string(),
            source_file: source_file.to_string(),
            message,
            said,
        })
    }
}

/// Where a parametric row came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ParametricSource {
    /// Vallen `.pridb`, `SetType` 1.
    #[default]
    Vallen,
    /// MISTRAS `.DTA`, message 2 (time-driven) or 3 (user-forced).
    Mistras,
    /// The test machine's own load file (`[load]` in the pipeline TOML).
    LoadFile,
    /// An AEwin export's machine log (`Specimen_RawData_<n>.csv`).
    MachineLog,
}

impl ParametricSource {
    pub fn as_str(self) -> &'static str {
        match self {
            ParametricSource::Vallen => "vallen",
            ParametricSource::Mistras => "mistras",
            ParametricSource::LoadFile => "load_file",
            ParametricSource::MachineLog => "machine_log",
        }
    }
}

/// A parametric (time-driven) row: the test machine's inputs at a time, as recorded: a row
/// of `parametric.parquet`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParametricRow {
    pub experiment: String,
    /// 1-based order of the row in its experiment and source.
    pub row: u64,
    pub time_s: Option<f64>,
    /// The mapped load and extension (the pipeline's `[ingest.*]` or `[load]` mapping).
    pub load_n: Option<f64>,
    pub extension_m: Option<f64>,
    /// The raw inputs as a JSON object under the vendor's names (`{"PA0": 1492.4}` in mV for
    /// Vallen, `{"PARA1": 0.0095}` in V for MISTRAS, the file's columns for a load file).
    pub inputs: Option<String>,
    /// MISTRAS time-driven per-channel features, JSON `{"3": {"ASL": 25}}`; Vallen `PCTD`,
    /// `PCTA` counters and status flags as `{"PCTD": 0, "PCTA": 0, "Status": 12}`.
    pub extra: Option<String>,
    pub source: ParametricSource,
    pub source_file: String,
}

/// What a marker row marks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MarkerKind {
    /// Vallen label marker (`SetType` 4), MISTRAS user comment (message 7).
    #[default]
    Label,
    /// Vallen date/time marker (`SetType` 5), MISTRAS test start (message 99).
    Datetime,
    /// Vallen section marker (`SetType` 6): acquisition (re)started or settings changed.
    Section,
    /// Vallen status record (`SetType` 3): a channel's periodic state.
    Status,
    /// MISTRAS start/resume (128), stop (129), pause (130), abort (15).
    Start,
    Stop,
    Pause,
    Abort,
}

impl MarkerKind {
    pub fn as_str(self) -> &'static str {
        match self {
            MarkerKind::Label => "label",
            MarkerKind::Datetime => "datetime",
            MarkerKind::Section => "section",
            MarkerKind::Status => "status",
            MarkerKind::Start => "start",
            MarkerKind::Stop => "stop",
            MarkerKind::Pause => "pause",
            MarkerKind::Abort => "abort",
        }
    }
}

/// A marker or status record: a row of `markers.parquet`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MarkerRow {
    pub experiment: String,
    /// 1-based order of the row in its experiment.
    pub row: u64,
    pub time_s: Option<f64>,
    pub kind: MarkerKind,
    /// Status rows: the channel.
    pub channel: Option<u32>,
    /// Vallen marker number.
    pub number: Option<i64>,
    /// Label text, date/time.
    pub text: Option<String>,
    /// Status rows: threshold, energy, RMS, signal strength, status flags.
    pub threshold_db: Option<f64>,
    pub energy_eu: Option<f64>,
    pub rms_v: Option<f64>,
    pub signal_strength_vs: Option<f64>,
    pub flags: Option<i64>,
    pub source_file: String,
}

/// One channel's acquisition settings as the recording states them (the manifest's
/// `experiments[].acquisition.channels`). `None` where the file does not say.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ChannelSetup {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub threshold_db: Option<f64>,
    /// Gain the waveform volts are divided by (MISTRAS message 23).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gain_db: Option<f64>,
    /// Preamplifier gain (MISTRAS message 20, "reserved for recording pre-amp gain").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preamp_gain_db: Option<f64>,
    /// Peak definition, hit definition and hit lockout times.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pdt_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hdt_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hlt_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pretrigger_samples: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub samples_per_record: Option<u32>,
    /// Where a setting came from when not from the file itself (e.g. `pipeline TOML`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
}

/// What a recording says about its acquisition system and settings.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AcquisitionSetup {
    pub experiment: String,
    pub source_file: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub product: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub test_start: Option<String>,
    /// The hit features the system recorded (vendor names, in record order).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hit_features: Vec<String>,
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub channels: std::collections::BTreeMap<u32, ChannelSetup>,
    /// Vendor records seen, by type name (`MID 1`, `MID 173,1`, `SetType 2`, …).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub vendor_records: std::collections::BTreeMap<String, u64>,
}

/// What one continuous recording gave (`[detect]`): the manifest's `streams` entry.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StreamTally {
    pub experiment: String,
    pub file: String,
    pub channels: usize,
    pub sample_rate_hz: f64,
    /// Samples read per channel (summed over the channels of a `.npy` read plane by plane).
    pub samples_read: u64,
    /// Samples per channel the header promised.
    pub samples_promised: u64,
    pub hits_cut: u64,
    /// Samples from a hit's first to its last crossing, over all channels.
    pub samples_in_hits: u64,
    /// Hits flagged as two bursts in one record (`[detect] split_gap_s`).
    pub two_bursts: u64,
}

/// What a reader counted in its files, by record type, independently of the rows it
/// yielded: the manifest checks `read = rows + rejects` per type against it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Tally {
    pub experiment: String,
    pub read: std::collections::BTreeMap<RecordType, u64>,
    /// Rows a reader's transform added to what it counted: a record cut by `[detect]`
    /// into m hits adds m − 1 transients and m hits.
    pub added: std::collections::BTreeMap<RecordType, u64>,
    /// A continuous recording's accounting (the manifest's `streams`), from a stream
    /// reader.
    pub stream: Option<Box<StreamTally>>,
}

/// What a reader yields: a transient record, a hit row, the reason a record (or file)
/// could not be read, a note for the manifest, a parametric or marker row, what the
/// recording says of its setup, and what the reader counted.
#[derive(Debug, Clone)]
pub enum Item {
    Record(AeRecord),
    Hit(Box<HitRow>),
    Reject(Reject),
    Note(Note),
    Parametric(Box<ParametricRow>),
    Marker(Box<MarkerRow>),
    Setup(Box<AcquisitionSetup>),
    Tally(Tally),
}

/// The damage mechanisms of the thesis (ch. 4.7, Table 5.1) plus the two bookkeeping classes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Mechanism {
    /// Fibre/fibre bond failure: ~250 kHz and ~750 kHz components, the low one ringing longer.
    BondFailure,
    /// Fibre failure: a short (< 5 µs) pulse above 800 kHz at the start of the record.
    FibreFailure,
    /// A fibre-failure pulse followed by a bond-like wave.
    Both,
    /// Triggered early, two bursts, clipped or empty.
    Erroneous,
    /// None of the criteria matched.
    Unclassified,
}

impl Mechanism {
    pub const ALL: [Mechanism; 5] = [
        Mechanism::BondFailure,
        Mechanism::FibreFailure,
        Mechanism::Both,
        Mechanism::Erroneous,
        Mechanism::Unclassified,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Mechanism::BondFailure => "bond_failure",
            Mechanism::FibreFailure => "fibre_failure",
            Mechanism::Both => "both",
            Mechanism::Erroneous => "erroneous",
            Mechanism::Unclassified => "unclassified",
        }
    }

    pub fn parse(s: &str) -> Option<Mechanism> {
        Mechanism::ALL.into_iter().find(|m| m.as_str() == s)
    }

    /// A short tag for map nodes and legends: B, F, BF, E, U.
    pub fn short(self) -> &'static str {
        match self {
            Mechanism::BondFailure => "B",
            Mechanism::FibreFailure => "F",
            Mechanism::Both => "BF",
            Mechanism::Erroneous => "E",
            Mechanism::Unclassified => "U",
        }
    }
}

impl fmt::Display for Mechanism {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The SOM class of a hit farther from the map than its novelty threshold (`[som]
/// novelty_quantile`): like none of the references the map was labelled with. Its nearest
/// node's class stays in `node_label`; counts keep it apart from the mechanisms.
pub const UNLIKE_REFERENCES: &str = "unlike_references";

/// Amplitude in dB re 1 µV (dB_AE), the AE convention: `20·log10(|v| / 1 µV)`.
pub fn db_ae(volts: f64) -> f64 {
    20.0 * (volts.abs() / 1e-6).log10()
}

/// Volts of a level in dB_AE (the inverse of [`db_ae`]).
pub fn db_to_v(db: f64) -> f64 {
    1e-6 * 10f64.powf(db / 20.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn db_ae_of_known_amplitudes() {
        assert!((db_ae(1e-6) - 0.0).abs() < 1e-12);
        assert!((db_ae(1e-3) - 60.0).abs() < 1e-12);
        assert!((db_ae(-0.1) - 100.0).abs() < 1e-12);
    }

    #[test]
    fn mechanism_names_round_trip() {
        for m in Mechanism::ALL {
            assert_eq!(Mechanism::parse(m.as_str()), Some(m));
        }
        assert_eq!(Mechanism::parse("crack"), None);
    }
}

/// A channel's role in the event builder (VisualAE's channel functions, vallenae's
/// `ChannelFunction`).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum ChannelRole {
    /// Ignored entirely.
    Unused,
    /// Takes part and may open an event.
    Normal,
    /// Never opens an event; while no event is open its hit restarts the FHCDT timer (so the
    /// same source's later hits at normal sensors open none); joins an open event but is
    /// left out of location.
    Guard,
    /// A guard when it would be the first hit, a normal channel otherwise.
    Combined,
}

/// `[location] kind`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LocationKind {
    /// Along a line between two sensors (a strip): x only.
    Linear,
    /// On a plane from three or more sensors: x and y.
    Planar,
}
