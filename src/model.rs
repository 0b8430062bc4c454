//! The vocabulary every room shares: one AE hit ([`AeRecord`]), the damage mechanisms
//! ([`Mechanism`]) and the reject record ([`Reject`]) that keeps a bad hit from being lost.
//!
//! SI units inside: seconds, hertz, volts, newtons, metres. Nothing in here depends on any
//! other module of the crate.

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
}

impl HitSource {
    pub fn as_str(self) -> &'static str {
        match self {
            HitSource::Vallen => "vallen",
            HitSource::Mistras => "mistras",
            HitSource::AewinList => "aewin",
            HitSource::Record => "record",
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
#[derive(Debug, Clone, PartialEq)]
pub struct Note {
    pub experiment: String,
    pub source_file: String,
    pub message: String,
}

/// What a reader yields: a transient record, a hit row, the reason a transient (or file)
/// could not be read, or a note for the manifest.
#[derive(Debug, Clone)]
pub enum Item {
    Record(AeRecord),
    Hit(Box<HitRow>),
    Reject(Reject),
    Note(Note),
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
}

impl fmt::Display for Mechanism {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

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
