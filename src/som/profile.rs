//! The damage profile (Fig. 6.1, the thesis's future work): per experiment and channel, the
//! classified hits in time order with the test machine's load and the running count of
//! each class, so that "fibre failures occur before final fracture" can be read off a test.

use super::SomError;
use crate::analysis::load::{LoadCheck, LoadVerdict};
use crate::model::columns as cols;
use crate::model::Mechanism;
use crate::store::spill::{Dec, Enc, Sorted, Sorter, Span, Spill};
use crate::store::{ColType, ColumnSpec, HitKey, StoreError, Table, TableScan, Value};
use std::collections::BTreeMap;
use std::path::Path;

/// The classes with a column of their own; the hits unlike the references count in
/// `n_unlike_references`, any other class (e.g. `unclassified` from a map labelled by
/// criteria) in `n_other`.
pub const CLASSES: [Mechanism; 3] = [
    Mechanism::BondFailure,
    Mechanism::FibreFailure,
    Mechanism::Erroneous,
];

/// `damage_profile.parquet`.
pub fn profile_table() -> Table<ProfileRow> {
    let mut t = Table::new("damage_profile")
        .col(
            ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"),
            |r: &ProfileRow| Value::Str(Some(r.key.0.clone())),
        )
        .col(
            ColumnSpec::of(cols::CHANNEL, "", "sensor channel; 0: the experiment's events (one hit per event, whichever sensor heard it first)"),
            |r| Value::I32(Some(r.key.1)),
        )
        .col(
            ColumnSpec::of(cols::HIT, "", "hit number"),
            |r| Value::I64(Some(r.key.2)),
        )
        .col(
            ColumnSpec::new(
                cols::TIME_S.name,
                ColType::Float64,
                "s",
                "hit time (null: the format records none; rows are then in hit order)",
            )
            .nullable(),
            |r| Value::F64(r.time_s),
        )
        .col(
            ColumnSpec::new(
                cols::LOAD_N.name,
                ColType::Float64,
                "N",
                "test-machine load at the hit (null: no load channel, or one that is no load: it spans less than trend.min_load_span_n or stays within its noise)",
            )
            .nullable(),
            |r| Value::F64(r.load_n),
        )
        .col(
            ColumnSpec::new(
                cols::EXTENSION_M.name,
                ColType::Float64,
                "m",
                "test-machine extension at the hit (null: none)",
            )
            .nullable(),
            |r| Value::F64(r.extension_m),
        )
        .col(
            ColumnSpec::new("class", ColType::Utf8, "", "the SOM's class of the hit"),
            |r| Value::Str(Some(r.class.clone())),
        )
        .col(
            ColumnSpec::new(
                "before_peak_load",
                ColType::Bool,
                "",
                "the hit comes before the experiment × channel's largest load (null: no load)",
            )
            .nullable(),
            |r| Value::Bool(r.before_peak_load),
        );
    for (k, c) in CLASSES.iter().enumerate() {
        t = t.col(
            ColumnSpec::new(
                format!("n_{c}"),
                ColType::Int64,
                "hits",
                &format!("{c} hits of this experiment × channel up to and including this one"),
            ),
            move |r: &ProfileRow| Value::I64(Some(r.counts[k] as i64)),
        );
    }
    t.col(
        ColumnSpec::new(
            "n_unlike_references",
            ColType::Int64,
            "hits",
            "hits unlike the map's references (classification.novel) up to and including this one; counted apart from the mechanisms",
        ),
        |r| Value::I64(Some(r.counts[UNLIKE] as i64)),
    )
    .col(
        ColumnSpec::new(
            "n_other",
            ColType::Int64,
            "hits",
            "hits of any other class up to and including this one",
        ),
        |r| Value::I64(Some(r.counts[OTHER] as i64)),
    )
}

/// The slot of the hits unlike the references in [`ProfileRow::counts`].
pub const UNLIKE: usize = CLASSES.len();
/// The slot of "any other class" in [`ProfileRow::counts`].
pub const OTHER: usize = CLASSES.len() + 1;
/// Slots of [`ProfileRow::counts`].
pub const SLOTS: usize = OTHER + 1;

/// The name of each slot of [`ProfileRow::counts`]: the [`CLASSES`], `unlike_references`,
/// `other`.
pub fn slot_names() -> [&'static str; SLOTS] {
    let mut n = [crate::model::UNLIKE_REFERENCES; SLOTS];
    for (k, c) in CLASSES.iter().enumerate() {
        n[k] = c.as_str();
    }
    n[OTHER] = "other";
    n
}

/// One classified hit of the profile.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileRow {
    pub key: HitKey,
    pub time_s: Option<f64>,
    pub load_n: Option<f64>,
    pub extension_m: Option<f64>,
    pub class: String,
    pub before_peak_load: Option<bool>,
    /// Running counts of [`CLASSES`], the hits unlike the references (at [`UNLIKE`]), then
    /// "other" (at [`OTHER`]).
    pub counts: [u64; SLOTS],
    /// Not columns of the profile; what the damage evolution adds up: the row's peak
    /// amplitude (dB_AE) and energy (eu), and the hits of its source (an event's; 1 for a
    /// hit outside events).
    pub amplitude_db: Option<f64>,
    pub energy_eu: Option<f64>,
    pub source_hits: u64,
    /// The event the row opened (None: a hit outside events).
    pub event: Option<i64>,
}

/// Per experiment × channel: the class totals and how many came before the peak load.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileSummary {
    pub experiment: String,
    pub channel: i32,
    pub peak_load_n: Option<f64>,
    pub peak_time_s: Option<f64>,
    /// Class → (hits, hits before the peak load).
    pub classes: BTreeMap<String, (u64, u64)>,
    /// Time of the last fibre failure, s.
    pub last_fibre_s: Option<f64>,
    /// Time of the last hit, s (final fracture is at or after it).
    pub last_hit_s: Option<f64>,
    /// Why the series' load channel is treated as absent (it spans less than
    /// `trend.min_load_span_n`, or stays within its noise): no peak, no profile against load.
    pub load_note: Option<String>,
}

impl ProfileSummary {
    /// One line for the terminal.
    pub fn line(&self) -> String {
        let mut parts: Vec<String> = Vec::new();
        for (c, (n, before)) in &self.classes {
            parts.push(if self.peak_load_n.is_some() {
                format!("{c} {n} ({before} before the peak load)")
            } else {
                format!("{c} {n}")
            });
        }
        let peak = match (self.peak_load_n, self.peak_time_s, &self.load_note) {
            (Some(l), Some(t), _) => format!("peak load {l:.1} N at {t:.1} s; "),
            (Some(l), None, _) => format!("peak load {l:.1} N; "),
            (None, _, Some(why)) => format!("no load ({why}); "),
            _ => String::new(),
        };
        format!(
            "damage profile {} ch{}: {peak}{}",
            self.experiment,
            self.channel,
            parts.join(", ")
        )
    }
}

fn slot(class: &str) -> usize {
    if class == crate::model::UNLIKE_REFERENCES {
        return UNLIKE;
    }
    Mechanism::parse(class)
        .and_then(|m| CLASSES.iter().position(|c| *c == m))
        .unwrap_or(OTHER)
}

/// A classified row on its way into the profile: its series (experiment, group channel), the
/// order within it (time, null last; hit; position in the features table), and what the
/// profile and the evolution read.
#[derive(Debug, Clone, PartialEq)]
struct Rec {
    experiment: String,
    channel: i32,
    time_s: Option<f64>,
    hit: i64,
    seq: u64,
    /// The hit's own channel (its key in the tables).
    hit_channel: i32,
    load_n: Option<f64>,
    extension_m: Option<f64>,
    amplitude_db: Option<f64>,
    energy_eu: Option<f64>,
    event: Option<i64>,
    first: Option<bool>,
    class: String,
    source_hits: u64,
}

impl Rec {
    fn time_key(&self) -> f64 {
        self.time_s.unwrap_or(f64::NAN)
    }
}

impl Eq for Rec {}
impl PartialOrd for Rec {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Rec {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        (self.experiment.as_str(), self.channel)
            .cmp(&(o.experiment.as_str(), o.channel))
            .then(self.time_key().total_cmp(&o.time_key()))
            .then(self.hit.cmp(&o.hit))
            .then(self.seq.cmp(&o.seq))
    }
}

impl Spill for Rec {
    fn encode(&self, out: &mut Vec<u8>) {
        Enc(out)
            .str(&self.experiment)
            .i32(self.channel)
            .opt_f64(self.time_s)
            .i64(self.hit)
            .u64(self.seq)
            .i32(self.hit_channel)
            .opt_f64(self.load_n)
            .opt_f64(self.extension_m)
            .opt_f64(self.amplitude_db)
            .opt_f64(self.energy_eu)
            .opt_i64(self.event)
            .opt_bool(self.first)
            .str(&self.class)
            .u64(self.source_hits);
    }
    fn decode(b: &mut Dec<'_>) -> Option<Self> {
        Some(Rec {
            experiment: b.str()?,
            channel: b.i32()?,
            time_s: b.opt_f64()?,
            hit: b.i64()?,
            seq: b.u64()?,
            hit_channel: b.i32()?,
            load_n: b.opt_f64()?,
            extension_m: b.opt_f64()?,
            amplitude_db: b.opt_f64()?,
            energy_eu: b.opt_f64()?,
            event: b.opt_i64()?,
            first: b.opt_bool()?,
            class: b.str()?,
            source_hits: b.u64()?,
        })
    }
    fn mem_bytes(&self) -> usize {
        std::mem::size_of::<Self>() + self.experiment.len() + self.class.len()
    }
}

/// A features row that belongs to an event, sorted by (experiment, event, position): the
/// runs count each event's hits; a classified row carries its profile record along.
#[derive(Debug, Clone, PartialEq, Eq)]
struct EventRow {
    experiment: String,
    event: i64,
    seq: u64,
    rec: Option<Box<Rec>>,
}

impl PartialOrd for EventRow {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for EventRow {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        (self.experiment.as_str(), self.event, self.seq).cmp(&(
            o.experiment.as_str(),
            o.event,
            o.seq,
        ))
    }
}

impl Spill for EventRow {
    fn encode(&self, out: &mut Vec<u8>) {
        Enc(out)
            .str(&self.experiment)
            .i64(self.event)
            .u64(self.seq)
            .u8(self.rec.is_some() as u8);
        if let Some(r) = &self.rec {
            r.encode(out);
        }
    }
    fn decode(b: &mut Dec<'_>) -> Option<Self> {
        let (experiment, event, seq) = (b.str()?, b.i64()?, b.u64()?);
        let rec = match b.u8()? {
            0 => None,
            _ => Some(Box::new(Rec::decode(b)?)),
        };
        Some(EventRow {
            experiment,
            event,
            seq,
            rec,
        })
    }
    fn mem_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.experiment.len()
            + self.rec.as_ref().map_or(0, |r| r.mem_bytes())
    }
}

/// A features row's key, sorted to find a key the table repeats.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
struct Key(HitKey);

impl Spill for Key {
    fn encode(&self, out: &mut Vec<u8>) {
        Enc(out).str(&self.0 .0).i32(self.0 .1).i64(self.0 .2);
    }
    fn decode(b: &mut Dec<'_>) -> Option<Self> {
        Some(Key((b.str()?, b.i32()?, b.i64()?)))
    }
    fn mem_bytes(&self) -> usize {
        std::mem::size_of::<Self>() + self.0 .0.len()
    }
}

/// The classification's (key, class) rows, read a batch at a time in file order.
struct ClassStream {
    t: TableScan,
    spans: std::vec::IntoIter<crate::store::read::BatchSpan>,
    ready: std::collections::VecDeque<(HitKey, String)>,
}

impl ClassStream {
    fn open(path: &Path) -> Result<ClassStream, StoreError> {
        let t = TableScan::open(path)?;
        t.require(
            &[
                cols::EXPERIMENT.name,
                cols::CHANNEL.name,
                cols::HIT.name,
                cols::SOM_LABEL.name,
            ],
            "",
        )?;
        Ok(ClassStream {
            spans: t.batch_spans().into_iter(),
            t,
            ready: Default::default(),
        })
    }

    /// The next (key, class), without taking it.
    fn peek(&mut self) -> Result<Option<&(HitKey, String)>, StoreError> {
        while self.ready.is_empty() {
            let Some(span) = self.spans.next() else {
                return Ok(None);
            };
            let sel = [
                cols::EXPERIMENT.name,
                cols::CHANNEL.name,
                cols::HIT.name,
                cols::SOM_LABEL.name,
            ];
            for b in self.t.span_reader(&span, &sel)? {
                let (_, df) = b?;
                let keys = self.t.hit_keys(&df)?;
                let vals = self.t.texts(&df, cols::SOM_LABEL)?;
                self.ready.extend(
                    keys.into_iter()
                        .zip(vals.into_iter().map(Option::unwrap_or_default)),
                );
            }
        }
        Ok(self.ready.front())
    }

    /// The class of `key` if it is the next classified row (the join of two tables in the
    /// same order: a features row the classification skipped gets `None`).
    fn take_if(&mut self, key: &HitKey) -> Result<Option<String>, StoreError> {
        match self.peek()? {
            Some((k, _)) if k == key => Ok(self.ready.pop_front().map(|(_, c)| c)),
            _ => Ok(None),
        }
    }
}

/// The damage profile of a classified feature table, sorted into its series: every series'
/// rows can be emitted (and re-read) in order without holding the table.
pub struct Profile {
    sorted: Sorted<Rec>,
    groups: Vec<((String, i32), Span)>,
}

/// Build the profile from a feature table (time, load, extension) and the classification
/// table (`som_label`) made from it: the classification's rows are a subsequence of the
/// features' rows in the same order (it classifies the features table's rows in order), so
/// the two are joined as they stream. Rows are read a batch at a time and sorted into their
/// series within a memory budget, spilling under `spill_dir`.
pub fn open(features: &Path, classification: &Path, spill_dir: &Path) -> Result<Profile, SomError> {
    let serr = SomError::Store;
    let t = TableScan::open(features).map_err(serr)?;
    let sel = profile_columns(&t)?;
    let mut classes = ClassStream::open(classification).map_err(serr)?;
    let mut sorting = Sorting::new(spill_dir);
    for batch in t.batches(&sel) {
        let (_, df) = batch.map_err(serr)?;
        let columns = BatchColumns::read(&t, &df)?;
        sorting.push_batch(columns, &mut classes)?;
    }
    check_all_joined(&mut classes, features, classification)?;
    let Sorting {
        mut series,
        events,
        keys_seen,
        ..
    } = sorting;
    check_keys_once(keys_seen, features)?;
    count_event_hits(events, &mut series)?;
    let sorted = series.finish()?;
    let groups = sorted.groups(|r| (r.experiment.clone(), r.channel))?;
    Ok(Profile { sorted, groups })
}

/// The features' columns the profile reads: the required ones (checked, else the error
/// says what the damage profile needs), then whichever optional ones the table has.
fn profile_columns(t: &TableScan) -> Result<Vec<&'static str>, SomError> {
    let serr = SomError::Store;
    let required = [
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        cols::TIME_S.name,
        cols::LOAD_N.name,
        cols::EXTENSION_M.name,
    ];
    t.require(&required, "for the damage profile")
        .map_err(serr)?;
    let mut sel = required.to_vec();
    if t.dtype(cols::EVENT_FIRST.name).is_some() {
        sel.push(cols::EVENT_FIRST.name);
    }
    let has = |c: &str| t.dtype(c).is_some();
    let optional = [
        cols::PEAK_AMPLITUDE_DB.name,
        cols::ENERGY_EU.name,
        cols::EVENT.name,
    ];
    for c in optional {
        if has(c) {
            sel.push(c);
        }
    }
    Ok(sel)
}

/// One batch of the features' columns the profile reads (an optional column the table
/// lacks reads as nulls), so that each row's record can be made from it.
struct BatchColumns {
    keys: Vec<HitKey>,
    first: Vec<Option<bool>>,
    amp: Vec<Option<f64>>,
    energy: Vec<Option<f64>>,
    event: Vec<Option<f64>>,
    time: Vec<Option<f64>>,
    load: Vec<Option<f64>>,
    ext: Vec<Option<f64>>,
}

impl BatchColumns {
    /// Read the columns of batch `df` of the features table `t`.
    fn read(t: &TableScan, df: &polars::prelude::DataFrame) -> Result<BatchColumns, SomError> {
        let serr = SomError::Store;
        let has = |c: &str| t.dtype(c).is_some();
        let keys = t.hit_keys(df).map_err(serr)?;
        let first = t.event_first(df).map_err(serr)?;
        let opt = |c: &str| -> Result<Vec<Option<f64>>, SomError> {
            if has(c) {
                t.f64s(df, c).map_err(serr)
            } else {
                Ok(vec![None; df.height()])
            }
        };
        let (amp, energy, event) = (
            opt(cols::PEAK_AMPLITUDE_DB.name)?,
            opt(cols::ENERGY_EU.name)?,
            opt(cols::EVENT.name)?,
        );
        let time = t.floats(df, cols::TIME_S).map_err(serr)?;
        let load = t.floats(df, cols::LOAD_N).map_err(serr)?;
        let ext = t.floats(df, cols::EXTENSION_M).map_err(serr)?;
        Ok(BatchColumns {
            keys,
            first,
            amp,
            energy,
            event,
            time,
            load,
            ext,
        })
    }

    /// The profile record of row `i` (key `k`, number `seq` in the table), classified as
    /// `class`, in its series with its event.
    fn rec(&self, i: usize, k: &HitKey, seq: u64, event_no: Option<i64>, class: String) -> Rec {
        let first = &self.first;
        Rec {
            channel: crate::store::group_channel(k.1, first[i]),
            time_s: self.time[i],
            hit: k.2,
            seq,
            hit_channel: k.1,
            load_n: self.load[i],
            extension_m: self.ext[i],
            amplitude_db: self.amp[i],
            energy_eu: self.energy[i],
            event: event_no,
            first: first[i],
            class,
            source_hits: 1,
            experiment: k.0.clone(),
        }
    }
}

/// What the features' rows are sorted into as they stream (each within its own memory
/// budget): the classified rows outside events into their series, every event's rows, and
/// every key, numbered by `seq`, their position in the table.
struct Sorting {
    series: Sorter<Rec>,
    events: Sorter<EventRow>,
    keys_seen: Sorter<Key>,
    seq: u64,
}

impl Sorting {
    /// Empty sorters spilling under `spill_dir`.
    fn new(spill_dir: &Path) -> Sorting {
        let series: Sorter<Rec> = Sorter::new(spill_dir);
        let events: Sorter<EventRow> = Sorter::new(spill_dir);
        // The join below pairs the two tables' rows by key in order, which needs each key once.
        let keys_seen: Sorter<Key> = Sorter::new(spill_dir);
        Sorting {
            series,
            events,
            keys_seen,
            seq: 0,
        }
    }

    /// Sort one batch's rows, each joined with its class from `classes` (the next
    /// classified row, if it is this one).
    fn push_batch(
        &mut self,
        mut c: BatchColumns,
        classes: &mut ClassStream,
    ) -> Result<(), SomError> {
        let serr = SomError::Store;
        for (i, k) in std::mem::take(&mut c.keys).into_iter().enumerate() {
            self.keys_seen.push(Key(k.clone()))?;
            let class = classes.take_if(&k).map_err(serr)?;
            let event_no = c.event[i].map(|e| e as i64);
            let rec = class.map(|class| c.rec(i, &k, self.seq, event_no, class));
            match event_no {
                // Hits per event, over every row (all sensors, classified or not): an event's
                // rows meet in the event sort, which also carries the classified one along.
                Some(e) => self.events.push(EventRow {
                    experiment: k.0,
                    event: e,
                    seq: self.seq,
                    rec: rec.map(Box::new),
                })?,
                None => {
                    if let Some(r) = rec {
                        self.series.push(r)?;
                    }
                }
            }
            self.seq += 1;
        }
        Ok(())
    }
}

/// Fail if a classified row is left over after the features' last row: the classification
/// was not made from this features table.
fn check_all_joined(
    classes: &mut ClassStream,
    features: &Path,
    classification: &Path,
) -> Result<(), SomError> {
    if let Some((k, _)) = classes.peek().map_err(SomError::Store)? {
        return Err(SomError::Data(format!(
            "{}: hit ({}, {}, {}) is not among the rows of {} in their order (the \
             classification was not made from this features table)",
            classification.display(),
            k.0,
            k.1,
            k.2,
            features.display()
        )));
    }
    Ok(())
}

/// Fail on a key the features table holds twice (the join by key in order needs each once).
fn check_keys_once(keys_seen: Sorter<Key>, features: &Path) -> Result<(), SomError> {
    let mut last: Option<Key> = None;
    for k in keys_seen.finish()?.iter() {
        let k = k?;
        if last.as_ref() == Some(&k) {
            return Err(SomError::Data(format!(
                "{}: hit ({}, {}, {}) is there twice; the damage profile needs each hit once",
                features.display(),
                k.0 .0,
                k.0 .1,
                k.0 .2
            )));
        }
        last = Some(k);
    }
    Ok(())
}

/// Count each event's hits (its run in the sorted events' rows) into its classified
/// first row's `source_hits`, and move the event's classified rows into the series.
fn count_event_hits(events: Sorter<EventRow>, series: &mut Sorter<Rec>) -> Result<(), SomError> {
    // One pass over the events' rows in order: each event's run, counted, then its
    // classified rows (a few hits an event) into the series.
    let events = events.finish()?;
    let mut run: Vec<EventRow> = Vec::new();
    let flush = |run: &mut Vec<EventRow>, series: &mut Sorter<Rec>| -> Result<(), SomError> {
        let n = run.len() as u64;
        for r in run.drain(..) {
            if let Some(mut rec) = r.rec {
                if rec.first == Some(true) {
                    rec.source_hits = n;
                }
                series.push(*rec)?;
            }
        }
        Ok(())
    };
    for r in events.iter() {
        let r = r?;
        if run
            .last()
            .is_some_and(|l| (l.experiment.as_str(), l.event) != (r.experiment.as_str(), r.event))
        {
            flush(&mut run, series)?;
        }
        run.push(r);
    }
    flush(&mut run, series)?;
    drop(events);
    Ok(())
}

impl Profile {
    /// The series (experiment, channel), in order.
    pub fn series(&self) -> impl Iterator<Item = &(String, i32)> {
        self.groups.iter().map(|(g, _)| g)
    }

    /// Rows in series `g`.
    pub fn len(&self, g: usize) -> u64 {
        self.groups[g].1.len
    }

    /// Emit series `g`: `row` gets each row in time order (hit order where there is no
    /// time), with the running counts; returns its summary. Two passes: the peak load first.
    /// A load channel that spans less than `min_load_span_n` or stays within its noise
    /// ([`LoadCheck`]) is no load: the rows' load is left out (null) and there is no peak.
    pub fn emit<E: From<SomError>>(
        &self,
        g: usize,
        min_load_span_n: f64,
        mut row: impl FnMut(&ProfileRow) -> Result<(), E>,
    ) -> Result<ProfileSummary, E> {
        let ((experiment, channel), span) = &self.groups[g];
        let serr = SomError::Store;
        // The first largest finite load, and where it is.
        let mut peak: Option<(u64, f64, Option<f64>)> = None;
        let mut load_check = LoadCheck::new();
        for (pos, r) in self.sorted.span_iter(*span).enumerate() {
            let r = r.map_err(serr)?;
            if let Some(l) = r.load_n.filter(|l| l.is_finite()) {
                load_check.push(l);
                if !matches!(peak, Some((_, ml, _)) if ml >= l) {
                    peak = Some((pos as u64, l, r.time_s));
                }
            }
        }
        let load_note = match load_check.verdict(min_load_span_n) {
            LoadVerdict::Noise(why) => Some(why),
            LoadVerdict::Absent | LoadVerdict::Load => None,
        };
        if load_note.is_some() {
            peak = None;
        }
        let mut counts = [0u64; SLOTS];
        let mut summary = ProfileSummary {
            experiment: experiment.clone(),
            channel: *channel,
            peak_load_n: peak.map(|p| p.1),
            peak_time_s: peak.and_then(|p| p.2),
            classes: BTreeMap::new(),
            last_fibre_s: None,
            last_hit_s: None,
            load_note: load_note.clone(),
        };
        for (pos, r) in self.sorted.span_iter(*span).enumerate() {
            let r = r.map_err(serr)?;
            let k = slot(&r.class);
            counts[k] += 1;
            let before = peak.map(|p| (pos as u64) < p.0);
            let e = summary.classes.entry(r.class.clone()).or_insert((0, 0));
            e.0 += 1;
            if before == Some(true) {
                e.1 += 1;
            }
            if CLASSES.get(k) == Some(&Mechanism::FibreFailure) {
                summary.last_fibre_s = r.time_s.or(summary.last_fibre_s);
            }
            summary.last_hit_s = r.time_s.or(summary.last_hit_s);
            row(&ProfileRow {
                key: (r.experiment, r.channel, r.hit),
                time_s: r.time_s,
                load_n: r.load_n.filter(|_| load_note.is_none()),
                extension_m: r.extension_m,
                class: r.class,
                before_peak_load: before,
                counts,
                amplitude_db: r.amplitude_db,
                energy_eu: r.energy_eu,
                source_hits: r.source_hits,
                event: match (r.first, r.event) {
                    (Some(true), Some(e)) => Some(e),
                    _ => None,
                },
            })?;
        }
        Ok(summary)
    }
}
