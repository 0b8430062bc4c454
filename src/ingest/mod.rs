//! Sources: find the experiments in the inputs and read their hits lazily.
//!
//! [`discover`] walks files and folders and groups files into [`Source`]s (an experiment, or
//! for a waveforms Parquet file, a table that may hold several). [`open`] turns a source into
//! an iterator of [`Item`]s — records, or reject rows for what could not be read — in the
//! order (experiment, channel, hit). Nothing here holds more than one record's samples at a
//! time, except the small per-batch buffers of the Vallen reader.

mod aewin;
mod csvfmt;
mod discover;
pub mod dta;
pub mod loadfile;
mod parquetfmt;
pub mod salvage;
pub mod settings;
pub(crate) mod sniff;
pub mod stream;
mod text;
pub mod vallen;
mod waveexplorer;
pub mod wavfmt;

use crate::model::{HitRow, Item, Reject, Stage};
use settings::{LoadConfig, ReadSettings};
use std::path::{Path, PathBuf};

pub use aewin::MachineLog;
pub use discover::{discover, Discovery};
pub(crate) use sniff::head;

#[derive(Debug, thiserror::Error)]
pub enum IngestError {
    #[error("{path}: {message}")]
    File { path: String, message: String },
}

impl crate::util::HasKind for IngestError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            IngestError::File { .. } => crate::util::ErrorKind::Usage,
        }
    }
}

/// Why one record of a file cannot be read (its reject row's reason).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct RecordError(pub String);

pub(crate) fn file_err(path: &Path, message: impl std::fmt::Display) -> IngestError {
    IngestError::File {
        path: path.display().to_string(),
        message: message.to_string(),
    }
}

/// The recording formats aepipe reads.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub enum Format {
    /// Vallen AMSY `.pridb` (hits, parametric) + `.tradb` (waveforms, raw or FLAC).
    Vallen,
    /// MISTRAS AEwin ASCII export: one waveform text file per hit (+ hit list, machine log).
    Aewin,
    /// Digital Wave WaveExplorer text export: many events in one file.
    WaveExplorer,
    /// WAV files, one hit per file (each channel a record).
    Wav,
    /// CSV, one hit per file.
    CsvPerHit,
    /// CSV long table with a hit column.
    CsvLong,
    /// Plain text, one value per line, one hit per file.
    Text,
    /// aepipe's own `waveforms.parquet`.
    Parquet,
    /// MISTRAS AEwin binary `.DTA` (hits, waveforms, parametric rows), chains as one.
    Mistras,
    /// Vallen TXT exports of transients, one per file, grouped by the database they came
    /// from.
    VallenTxt,
    /// A continuous recording: a NumPy `.npy` array, or a raw binary with its `.toml`
    /// description (`[detect]` cuts it into hits).
    Stream,
}

/// How `aepipe watch` follows a format's recordings while the acquisition writes them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Follow {
    /// New files of a folder, each once it has settled, numbered on from the ones before.
    PerFile,
    /// A Vallen pair, set by set as its `.pridb` and `.tradb` grow.
    GrowingPair,
    /// A MISTRAS `.DTA` chain, message by message as it is appended to.
    GrowingChain,
    /// A raw continuous recording, cut as it grows (with `[detect]` on).
    GrowingStream,
    /// The whole recording, once all its files have settled.
    Whole,
}

/// What a format is, declared once by its reader module: its name, how its experiments
/// are made of files, how `aepipe watch` follows it, and its reader.
pub struct FormatSpec {
    /// The name the manifest and `aepipe inspect` use.
    pub name: &'static str,
    /// An experiment is a folder (or test) of one-hit files.
    pub one_hit_per_file: bool,
    /// A one-hit file's hit number is its place in its folder (a source of only some of
    /// the files numbers them on from [`Source::first_hit`]).
    pub numbered_by_place: bool,
    pub follow: Follow,
    /// The reader: records, hits, rejects and the rest, in order.
    pub open: fn(&Source, &ReadSettings) -> Items,
}

impl Format {
    /// The format's declaration (in its reader module).
    pub fn spec(self) -> &'static FormatSpec {
        match self {
            Format::Vallen => &vallen::FORMAT,
            Format::Aewin => &aewin::FORMAT,
            Format::WaveExplorer => &waveexplorer::FORMAT,
            Format::Wav => &wavfmt::FORMAT,
            Format::CsvPerHit => &csvfmt::PER_HIT_FORMAT,
            Format::CsvLong => &csvfmt::LONG_FORMAT,
            Format::Text => &text::FORMAT,
            Format::Parquet => &parquetfmt::FORMAT,
            Format::Mistras => &dta::FORMAT,
            Format::VallenTxt => &vallen::txt::FORMAT,
            Format::Stream => &stream::FORMAT,
        }
    }

    /// Formats whose experiment is a folder of one-hit files (its id is the folder's name).
    pub fn one_hit_per_file(self) -> bool {
        self.spec().one_hit_per_file
    }

    /// One-hit-per-file formats whose hit number is the file's place in its folder (an AEwin
    /// file carries its own in its name): a source of only some of its files numbers them
    /// on from [`Source::first_hit`].
    pub fn numbered_by_place(self) -> bool {
        self.spec().numbered_by_place
    }

    pub fn as_str(self) -> &'static str {
        self.spec().name
    }
}

/// What a companion file is to its source.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// A Vallen `.pridb`: the hit rows, parametric and marker rows.
    HitIndex,
    /// A VisualAE `.trfdb`: features per transient.
    TransientFeatures,
    /// A VisualAE `.vaex`: the event builder and location setup.
    Setup,
    /// An AEwin hit list `<test>.TXT`.
    HitList,
    /// A test machine's log (`Specimen_RawData_<n>.csv`).
    MachineLog,
}

/// A file a source reads besides its waveform files, with its role.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Companion {
    pub role: Role,
    pub path: PathBuf,
}

/// One unit of reading: an experiment (or a waveforms table), with the files it needs.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Source {
    /// Experiment id (for Parquet: the file stem; the rows carry their own experiment ids).
    pub id: String,
    pub format: Format,
    /// The waveform files, in reading order.
    pub files: Vec<PathBuf>,
    /// Companion files, by role: a Vallen `.pridb`, `.trfdb` and `.vaex`, an AEwin hit list
    /// and machine log.
    pub companions: Vec<Companion>,
    /// Hits before the first of `files` in a one-hit-per-file source (WAV, CSV per hit,
    /// plain text): its files are hits `first_hit + 1 …`. 0 for a whole source; a watcher
    /// reading a folder's new files sets it to the files it read before.
    pub first_hit: u64,
}

impl Source {
    /// A source of `files` alone.
    pub fn of(id: String, format: Format, files: Vec<PathBuf>) -> Source {
        Source {
            id,
            format,
            files,
            companions: vec![],
            first_hit: 0,
        }
    }

    /// The companion of `role`, if the source has one (the first).
    pub fn companion(&self, role: Role) -> Option<&Path> {
        self.companions
            .iter()
            .find(|c| c.role == role)
            .map(|c| c.path.as_path())
    }

    /// Every companion's path, as the manifest and `aepipe inspect` list them.
    pub fn companion_names(&self) -> Vec<String> {
        self.companions
            .iter()
            .map(|c| c.path.display().to_string())
            .collect()
    }

    /// Every companion of `role`.
    pub fn companions_of(&self, role: Role) -> impl Iterator<Item = &Path> {
        self.companions
            .iter()
            .filter(move |c| c.role == role)
            .map(|c| c.path.as_path())
    }

    /// The Vallen VisualAE setup (`.vaex`) beside the source, if discovery found one.
    pub fn vaex(&self) -> Option<&Path> {
        self.companion(Role::Setup)
    }

    /// Whether the source stores its hits apart from its transients (a Vallen `.pridb`, a
    /// MISTRAS stream); then its reader yields the hit rows, otherwise every transient is
    /// also its hit.
    pub fn has_hit_list(&self) -> bool {
        match self.format {
            Format::Vallen => self.companion(Role::HitIndex).is_some(),
            Format::Mistras | Format::Stream => true,
            // The AEwin reader makes the hit rows itself when a list lies beside the test.
            Format::Aewin => self.companion(Role::HitList).is_some(),
            _ => false,
        }
    }

    /// Every file this source reads (for the manifest).
    pub fn all_files(&self) -> impl Iterator<Item = &PathBuf> {
        self.files
            .iter()
            .chain(self.companions.iter().map(|c| &c.path))
    }
}

pub(crate) fn whole_file_reject(p: &Path, stage: Stage, reason: String) -> Reject {
    Reject {
        record_type: crate::model::RecordType::File,
        experiment: String::new(),
        source_file: p.display().to_string(),
        record_id: String::new(),
        stage,
        reason,
    }
}

/// What a reader yields: records, hits, rejects and the rest, in order.
pub type Items = Box<dyn Iterator<Item = Item> + Send>;

/// A reader under a guard: a panic inside it (while it opens its files or reads a record)
/// becomes one reject row for the rest of its source (stage `read`, the panic's message),
/// and the batch goes on with the next source.
struct Guarded {
    open: Option<Box<dyn FnOnce() -> Items + Send>>,
    inner: Option<Items>,
    experiment: String,
    file: String,
    done: bool,
}

impl Iterator for Guarded {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        if self.done {
            return None;
        }
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            if let Some(open) = self.open.take() {
                self.inner = Some(open());
            }
            self.inner.as_mut().and_then(|i| i.next())
        }));
        match r {
            Ok(it) => it,
            Err(p) => {
                self.done = true;
                self.inner = None;
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                Some(Item::Reject(Reject {
                    record_type: crate::model::RecordType::File,
                    experiment: self.experiment.clone(),
                    source_file: self.file.clone(),
                    record_id: String::new(),
                    stage: Stage::Read,
                    reason: format!(
                        "the reader failed (please report): {msg}; the rest of this source is not read"
                    ),
                }))
            }
        }
    }
}

/// Read a source: an iterator of records, hit rows, reject rows and the rest of what the
/// recording holds (parametric and marker rows, setup, notes, the reader's tally), in
/// (experiment, channel, hit) order. The reader runs under a guard (a panic is a reject
/// row); with `[load] file` set, the test machine's load file gives the load.
pub fn open(
    src: &Source,
    ingest: &ReadSettings,
    load: &LoadConfig,
) -> Box<dyn Iterator<Item = Item> + Send> {
    loadfile::attach(open_recording(src, ingest), src, load)
}

/// [`open`] without the load file: what the recording itself holds.
pub fn open_recording(src: &Source, cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
    let (s, c) = (src.clone(), cfg.clone());
    guarded(
        src,
        Box::new(move || stream::cut_long_records(open_format(&s, &c), &c)),
    )
}

/// One window of a Vallen pair still being written (`aepipe watch`): its rows as [`open`]
/// gives them for those sets.
pub fn open_window(
    src: &Source,
    w: &vallen::tail::Window,
    ingest: &ReadSettings,
    load: &LoadConfig,
) -> Box<dyn Iterator<Item = Item> + Send> {
    let (w, c) = (w.clone(), ingest.clone());
    loadfile::attach(
        guarded(
            src,
            Box::new(move || stream::cut_long_records(vallen::tail::read(&w, &c), &c)),
        ),
        src,
        load,
    )
}

/// Items already read from a recording (a growing MISTRAS chain, `aepipe watch`), with the
/// test machine's load file as [`open`] applies it.
pub fn with_load_file(
    items: Box<dyn Iterator<Item = Item> + Send>,
    src: &Source,
    load: &LoadConfig,
) -> Box<dyn Iterator<Item = Item> + Send> {
    loadfile::attach(items, src, load)
}

/// A reader opened on first use, a panic in it a reject row (the rest of the source
/// unread); every transient also a hit when the format has no hit list.
fn guarded(
    src: &Source,
    open: Box<dyn FnOnce() -> Items + Send>,
) -> Box<dyn Iterator<Item = Item> + Send> {
    let items: Box<dyn Iterator<Item = Item> + Send> = Box::new(Guarded {
        open: Some(open),
        inner: None,
        experiment: src.id.clone(),
        file: src
            .all_files()
            .next()
            .map(|p| p.display().to_string())
            .unwrap_or_default(),
        done: false,
    });
    if src.has_hit_list() {
        return items;
    }
    // A format without a hit list: each transient read is also its hit, unless the reader
    // gave the record its own hit row just before it (a WAV stream cut by `[detect]`).
    let mut own: Option<(String, u32, u64)> = None;
    Box::new(items.flat_map(move |it| match it {
        Item::Hit(h) => {
            own = Some((h.experiment.clone(), h.channel, h.hit));
            vec![Item::Hit(h)]
        }
        Item::Record(r) => {
            let key = (r.experiment.clone(), r.channel, r.hit);
            if own.take().as_ref() == Some(&key) {
                vec![Item::Record(r)]
            } else {
                vec![Item::Hit(Box::new(HitRow::of_record(&r))), Item::Record(r)]
            }
        }
        other => vec![other],
    }))
}

fn open_format(src: &Source, cfg: &ReadSettings) -> Items {
    (src.format.spec().open)(src, cfg)
}

/// A time series (test-machine load or extension) sampled at increasing times, read by
/// linear interpolation. Outside the recorded span the value is unknown (`None`): a load
/// extrapolated past the end of the log would be invented.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TimeSeries {
    pub t: Vec<f64>,
    pub v: Vec<f64>,
}

impl TimeSeries {
    pub fn from_pairs(mut pairs: Vec<(f64, f64)>) -> TimeSeries {
        pairs.retain(|(t, v)| t.is_finite() && v.is_finite());
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        TimeSeries {
            t: pairs.iter().map(|p| p.0).collect(),
            v: pairs.iter().map(|p| p.1).collect(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    pub fn at(&self, t: f64) -> Option<f64> {
        let n = self.t.len();
        if n == 0 || !(t >= self.t[0] && t <= self.t[n - 1]) {
            return None;
        }
        let i = self.t.partition_point(|&x| x <= t);
        if i == 0 {
            return Some(self.v[0]);
        }
        if i >= n {
            return Some(self.v[n - 1]);
        }
        let (t0, t1, v0, v1) = (self.t[i - 1], self.t[i], self.v[i - 1], self.v[i]);
        if t1 == t0 {
            return Some(v1);
        }
        Some(v0 + (v1 - v0) * (t - t0) / (t1 - t0))
    }
}

/// Which hits a load series covers: those before its first time and after its last get no
/// load, and a reader of the test's numbers must know how many (a machine log that stopped
/// early leaves most of a test without load, and a trend against load then rests on the few
/// hits before it stopped).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Coverage {
    pub hits: u64,
    pub before: u64,
    pub after: u64,
    /// The series' span on the AE clock.
    pub span: Option<(f64, f64)>,
}

impl Coverage {
    /// `span`: the series' first and last time on the AE clock (`None`: an empty series).
    pub fn new(series: &TimeSeries, offset_s: f64) -> Coverage {
        Coverage {
            span: series
                .t
                .first()
                .zip(series.t.last())
                .map(|(a, b)| (a + offset_s, b + offset_s)),
            ..Default::default()
        }
    }

    /// Count a hit at `t` (AE clock; a hit without a time is not counted as outside).
    pub fn count(&mut self, t: Option<f64>) {
        self.hits += 1;
        if let (Some(t), Some((a, b))) = (t, self.span) {
            self.before += u64::from(t < a);
            self.after += u64::from(t > b);
        }
    }

    /// `EXP3005: 69 of 72 hits after the machine log ends at 19.5 s: no load`, when any
    /// hit lies outside.
    pub fn note(&self, experiment: &str, what: &str) -> Option<String> {
        let (a, b) = self.span?;
        let mut parts = Vec::new();
        if self.after > 0 {
            parts.push(format!(
                "{} of {} hits after the {what} ends at {b:.1} s",
                self.after, self.hits
            ));
        }
        if self.before > 0 {
            parts.push(format!(
                "{} of {} hits before the {what} starts at {a:.1} s",
                self.before, self.hits
            ));
        }
        (!parts.is_empty()).then(|| format!("{experiment}: {}: no load", parts.join(", ")))
    }
}

/// Volts divided by a preamplifier gain in dB.
pub(crate) fn gain_factor(gain_db: f64) -> f64 {
    10f64.powf(-gain_db / 20.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_interpolates_inside_and_refuses_outside() {
        let s = TimeSeries::from_pairs(vec![(1.0, 10.0), (0.0, 0.0), (2.0, 30.0)]);
        assert_eq!(s.at(0.5), Some(5.0));
        assert_eq!(s.at(1.5), Some(20.0));
        assert_eq!(s.at(2.0), Some(30.0));
        assert_eq!(s.at(0.0), Some(0.0));
        assert_eq!(s.at(-0.1), None);
        assert_eq!(s.at(2.1), None);
        assert_eq!(TimeSeries::default().at(0.0), None);
    }

    #[test]
    fn natural_order_of_names() {
        let mut v = vec!["hit_10.wav", "hit_2.wav", "hit_1.wav"];
        v.sort_by_key(|s| discover::natural_key(s));
        assert_eq!(v, vec!["hit_1.wav", "hit_2.wav", "hit_10.wav"]);
    }

    #[test]
    fn a_panicking_reader_becomes_one_reject_and_ends_its_source() {
        let mut n = 0;
        let inner = std::iter::from_fn(move || {
            n += 1;
            if n == 2 {
                panic!("index out of bounds: the len is 3 but the index is 7");
            }
            Some(Item::Note(crate::model::Note {
                experiment: "e".into(),
                source_file: "f".into(),
                message: format!("item {n}"),
                said: false,
            }))
        });
        let g = Guarded {
            open: None,
            inner: Some(Box::new(inner)),
            experiment: "e".into(),
            file: "f.bin".into(),
            done: false,
        };
        let items: Vec<Item> = g.collect();
        assert_eq!(items.len(), 2);
        let Item::Reject(r) = &items[1] else {
            panic!("{:?}", items[1])
        };
        assert_eq!((r.stage, r.source_file.as_str()), (Stage::Read, "f.bin"));
        assert!(r.reason.contains("index out of bounds"), "{}", r.reason);
    }
}
