//! Vallen AMSY databases: `.tradb` (transient waveforms) joined with `.pridb` (hits and
//! parametric inputs).
//!
//! * Waveforms: `tr_data` rows; `DataFormat` 0 = raw little-endian int16, 2 = FLAC;
//!   volts = ADC × `TR_mV` · 1e-3 (`TR_mV` from `tr_params` by `ParamID`); time =
//!   `Time × (1 / TimeBase)` (`tr_globalinfo`, 10 MHz by default), as the files' own views
//!   (`Time*1E-7`) scale it.
//! * Hits: `ae_data` rows with `SetType = 2`; their `TRAI` links to the waveform. A hit whose
//!   TRAI has no waveform becomes a reject row, never a silent gap.
//! * Parametric rows (`SetType = 1`) carry `PA0`, `PA1`, … (ADC × `PAn_mV`); the config maps
//!   them to load and extension, interpolated at each hit's time.
//!
//! The reader first lists `(Chan, TRAI, SetID)` (integers only), then fetches each waveform by
//! its primary key: ordered output without asking SQLite to sort blobs, one waveform in memory.

use super::{file_err, IngestError, Source};
use crate::ingest::settings::{IngestConfig, ReadSettings};
use crate::model::{AeRecord, Item, Reject, Stage};
use rusqlite::{Connection, OpenFlags, OptionalExtension};
use std::collections::{HashMap, HashSet, VecDeque};
use std::path::{Path, PathBuf};

pub(crate) fn open_ro(path: &Path) -> Result<Connection, IngestError> {
    if !path.is_file() {
        return Err(file_err(path, "no such file"));
    }
    let conn = Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(|e| file_err(path, format!("not a readable SQLite database: {e}")))?;
    // Fails here (not later) when the header is garbage.
    conn.query_row("SELECT count(*) FROM sqlite_master", [], |r| {
        r.get::<_, i64>(0)
    })
    .map_err(|e| file_err(path, format!("not a readable SQLite database: {e}")))?;
    Ok(conn)
}

fn columns(conn: &Connection, table: &str) -> Vec<String> {
    let Ok(mut st) = conn.prepare(&format!("PRAGMA table_info({table})")) else {
        return vec![];
    };
    st.query_map([], |r| r.get::<_, String>(1))
        .map(|it| it.flatten().collect())
        .unwrap_or_default()
}

fn time_base(conn: &Connection, table: &str) -> f64 {
    conn.query_row(
        &format!("SELECT Value FROM {table} WHERE Key = 'TimeBase'"),
        [],
        |r| r.get::<_, rusqlite::types::Value>(0),
    )
    .optional()
    .ok()
    .flatten()
    .and_then(|v| match v {
        rusqlite::types::Value::Integer(i) => Some(i as f64),
        rusqlite::types::Value::Real(f) => Some(f),
        rusqlite::types::Value::Text(s) => s.trim().parse().ok(),
        _ => None,
    })
    .filter(|v| *v > 0.0)
    .unwrap_or(1e7)
}

/// Why a `tr_data` blob could not be decoded (the reason of the record's reject row).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BlobError(String);

/// Decode one `tr_data` blob into ADC counts. `samples` is the database's claim and is
/// checked against the blob, never trusted for an allocation. Public for `fuzz/`.
pub fn decode_blob(format: i64, data: &[u8], samples: usize) -> Result<Vec<i32>, BlobError> {
    let adc: Vec<i32> = match format {
        0 => {
            if samples.checked_mul(2) != Some(data.len()) {
                return Err(BlobError(format!(
                    "raw blob holds {} bytes, Samples says {samples} int16",
                    data.len(),
                )));
            }
            data.chunks_exact(2)
                .map(|c| i16::from_le_bytes([c[0], c[1]]) as i32)
                .collect()
        }
        2 => {
            let mut reader = claxon::FlacReader::new(std::io::Cursor::new(data))
                .map_err(|e| BlobError(format!("corrupt FLAC blob: {e}")))?;
            // `samples` is a claim of the database: never reserve more than the blob can hold
            // (FLAC of 16-bit samples is not smaller than 1/64 of them).
            let mut out = Vec::with_capacity(samples.min(data.len().saturating_mul(64)));
            for s in reader.samples() {
                out.push(s.map_err(|e| BlobError(format!("corrupt FLAC blob: {e}")))?);
                if out.len() > samples {
                    // The stream holds more than the database says: stop decoding here.
                    return Err(BlobError(format!(
                        "FLAC blob decodes to more than the {samples} samples Samples says"
                    )));
                }
            }
            if out.len() != samples {
                return Err(BlobError(format!(
                    "FLAC blob decodes to {} samples, Samples says {samples}",
                    out.len()
                )));
            }
            out
        }
        f => {
            return Err(BlobError(format!(
                "unknown DataFormat {f} (known: 0 raw int16, 2 FLAC)"
            )))
        }
    };
    Ok(adc)
}

/// A transient's columns: Time, Pretrigger, SampleRate, Samples, DataFormat, Data, TR_mV,
/// threshold µV.
type Fetched = (
    Option<i64>,
    Option<i64>,
    Option<f64>,
    Option<i64>,
    Option<i64>,
    Option<Vec<u8>>,
    Option<f64>,
    Option<f64>,
);

struct Reader {
    experiment: String,
    /// The rows of a `.tradb` SQLite refused, salvaged from its whole pages.
    salvaged: Option<salvaged::SalvagedTr>,
    hits: Option<HitRows>,
    pending_hits: VecDeque<Item>,
    tradb: PathBuf,
    conn: Option<Connection>,
    time_base: f64,
    /// (channel, transient number, SetID, TRAI), in output order.
    keys: VecDeque<(i64, u64, i64, i64)>,
    /// (TRAI, channel, time) of every transient in the `.tradb`.
    have: HashSet<(i64, i64, i64)>,
    offsets: TraiOffsets,
    info: PriInfo,
    max_samples: u64,
    /// `.trfdb` features per TRAI (applied only in a single-acquisition file, where TRAI
    /// is a key).
    trf: HashMap<i64, String>,
    /// Rejects to emit at the end: pridb hits whose transient the tradb does not hold.
    tail: VecDeque<Reject>,
    /// The `.pridb`'s markers, parametric and status rows (read before the hits).
    sets: Option<sets::SetRows>,
    /// Whether a `.pridb` lists the hits (then a transient no hit links to stands alone).
    has_pridb: bool,
    /// What the files hold by record type, and the last items (tally, setup), emitted once
    /// everything else is out.
    last: VecDeque<Item>,
}

impl Reader {
    /// The next chunk of markers, parametric and status rows; false when they are out.
    fn next_sets(&mut self) -> bool {
        let Some(s) = self.sets.as_mut() else {
            return false;
        };
        match s.chunk() {
            Ok(items) if items.is_empty() => {
                self.sets = None;
                false
            }
            Ok(items) => {
                self.pending_hits.extend(items);
                true
            }
            Err(e) => {
                let path = s.path().to_string();
                self.sets = None;
                self.pending_hits.push_back(Item::Reject(Reject {
                    record_type: crate::model::RecordType::File,
                    experiment: self.experiment.clone(),
                    source_file: path,
                    record_id: String::new(),
                    stage: Stage::Read,
                    reason: format!("parametric, status or marker rows unreadable: {e}"),
                }));
                true
            }
        }
    }

    fn next_hits(&mut self) -> bool {
        let Some(h) = self.hits.as_mut() else {
            return false;
        };
        match h.chunk() {
            Ok(rows) if rows.is_empty() => {
                self.hits = None;
                false
            }
            Ok(rows) => {
                for (setid, ticks, mut row) in rows {
                    row.experiment = self.experiment.clone();
                    row.acquisition = self.info.acquisition_of(setid);
                    if let Some(t) = row.trai {
                        if self.have.contains(&(t, row.channel as i64, ticks)) {
                            row.transient = Some(self.offsets.number(row.acquisition, t));
                        }
                    }
                    if self.info.acq_starts.is_empty() {
                        row.vendor_features = row.trai.and_then(|t| self.trf.get(&t).cloned());
                    }
                    row.load_n = row.time_s.and_then(|t| self.info.load.at(t));
                    row.extension_m = row.time_s.and_then(|t| self.info.extension.at(t));
                    self.pending_hits.push_back(Item::Hit(Box::new(row)));
                }
                true
            }
            Err(e) => {
                let path = h.path.clone();
                self.hits = None;
                self.pending_hits.push_back(Item::Reject(Reject {
                    record_type: crate::model::RecordType::File,
                    experiment: self.experiment.clone(),
                    source_file: path,
                    record_id: String::new(),
                    stage: Stage::Read,
                    reason: format!("hit rows after the first ones unreadable: {e}"),
                }));
                true
            }
        }
    }

    /// The columns of transient `setid`: from SQLite, or from the salvaged rows.
    fn query(&self, setid: i64) -> Result<Fetched, String> {
        if let Some(sv) = &self.salvaged {
            let r = sv.rows.get(&setid).ok_or("not among the salvaged rows")?;
            let (tr_mv, adc_uv) = r
                .param
                .and_then(|p| sv.params.get(&p))
                .copied()
                .unwrap_or((None, None));
            return Ok((
                r.time,
                r.pretrigger,
                r.sample_rate,
                r.samples,
                r.format,
                r.data.clone(),
                tr_mv,
                r.thr.zip(adc_uv).map(|(t, a)| t as f64 * a),
            ));
        }
        let conn = self.conn.as_ref().expect("open while keys remain");
        conn.query_row(
            "SELECT d.Time, d.Pretrigger, d.SampleRate, d.Samples, d.DataFormat, d.Data, p.TR_mV, d.Thr * p.\"ADC_µV\" \
             FROM tr_data d LEFT JOIN tr_params p ON p.ID = d.ParamID WHERE d.SetID = ?1",
            [setid],
            |r| {
                Ok((
                    r.get::<_, Option<i64>>(0)?,
                    r.get::<_, Option<i64>>(1)?,
                    r.get::<_, Option<f64>>(2)?,
                    r.get::<_, Option<i64>>(3)?,
                    r.get::<_, Option<i64>>(4)?,
                    r.get::<_, Option<Vec<u8>>>(5)?,
                    r.get::<_, Option<f64>>(6)?,
                    r.get::<_, Option<f64>>(7)?,
                ))
            },
        )
        .map_err(|e| e.to_string())
    }

    fn fetch(&mut self, chan: i64, number: u64, setid: i64, trai: i64) -> Item {
        let row = self.query(setid);
        let reject = |reason: String| {
            Item::Reject(Reject {
                record_type: crate::model::RecordType::Transient,
                experiment: self.experiment.clone(),
                source_file: self.tradb.display().to_string(),
                record_id: if number == trai as u64 {
                    format!("TRAI {trai}")
                } else {
                    format!("TRAI {trai} (transient {number})")
                },
                stage: Stage::Read,
                reason,
            })
        };
        let (time, pre, rate, n, fmt, data, tr_mv, thr_uv) = match row {
            Ok(r) => r,
            Err(e) => return reject(format!("cannot read the record: {e}")),
        };
        let Some(tr_mv) = tr_mv.filter(|v| v.is_finite() && *v != 0.0) else {
            return reject("no TR_mV scale for the record's ParamID in tr_params".into());
        };
        let Some(rate) = rate.filter(|r| *r > 0.0) else {
            return reject("SampleRate missing or not positive".into());
        };
        let n = n.unwrap_or(0).max(0) as u64;
        if n > self.max_samples {
            return reject(format!(
                "Samples = {n} exceeds ingest.max_samples_per_record = {}",
                self.max_samples
            ));
        }
        let n = n as usize;
        let adc = match decode_blob(fmt.unwrap_or(-1), data.as_deref().unwrap_or(&[]), n) {
            Ok(a) => a,
            Err(e) => return reject(e.to_string()),
        };
        // Volts as vallenae computes them (`np.multiply(adc, 1e-3 * TR_mV, dtype=float32)`):
        // the scale rounded to f32 and the product taken in f32, so that every sample, and so
        // every pick and feature, is the one vallenae's readers give.
        let scale = (1e-3 * tr_mv) as f32;
        // As the file's own view scales it (`Time*1E-7`): times a reciprocal, so that hit times
        // are those of VisualAE and vallenae to the last bit (event windows compare them).
        let time_s = time.map(|t| t as f64 * (1.0 / self.time_base));
        let linked =
            !self.has_pridb || time.is_some_and(|t| self.info.link.contains_key(&(trai, chan, t)));
        Item::Record(AeRecord {
            kind: if linked {
                crate::model::RecordKind::Hit
            } else {
                crate::model::RecordKind::Standalone
            },
            experiment: self.experiment.clone(),
            channel: chan.max(0) as u32,
            hit: number,
            time_s,
            sample_rate_hz: rate,
            pretrigger: pre.unwrap_or(0).max(0) as u32,
            samples: adc.into_iter().map(|a| a as f32 * scale).collect(),
            load_n: time_s.and_then(|t| self.info.load.at(t)),
            extension_m: time_s.and_then(|t| self.info.extension.at(t)),
            label: None,
            threshold_v: thr_uv.filter(|t| *t > 0.0).map(|t| t * 1e-6),
            source_file: self.tradb.display().to_string(),
        })
    }
}

impl Iterator for Reader {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        loop {
            if let Some(h) = self.pending_hits.pop_front() {
                return Some(h);
            }
            if !self.next_sets() && !self.next_hits() {
                break;
            }
        }
        if let Some((chan, number, setid, trai)) = self.keys.pop_front() {
            return Some(self.fetch(chan, number, setid, trai));
        }
        self.conn = None;
        if let Some(r) = self.tail.pop_front() {
            return Some(Item::Reject(r));
        }
        self.last.pop_front()
    }
}

/// Vallen AMSY `.pridb` (hits, parametric, markers) + `.tradb` (transients): followed set by set while it grows.
pub(crate) const FORMAT: crate::ingest::FormatSpec = crate::ingest::FormatSpec {
    name: "vallen",
    one_hit_per_file: false,
    numbered_by_place: false,
    follow: crate::ingest::Follow::GrowingPair,
    open,
};

/// Vallen pairs found by discovery: base path (folder + stem) → (`.pridb`, `.tradb`).
pub(crate) type Pairs = std::collections::BTreeMap<PathBuf, (Option<PathBuf>, Option<PathBuf>)>;

/// The sources of the pairs discovery found: the `.tradb` is the waveform file, the
/// `.pridb` the hit index, a `.trfdb` beside a `.pridb` the transients' features and a
/// `.vaex` beside either the setup (those two are read, so they are taken off `skipped`). A
/// `.pridb` alone is a source too: its reader makes each hit that should have a transient a
/// reject row.
pub(crate) fn pair_sources(pairs: &Pairs, skipped: &mut Vec<(PathBuf, String)>) -> Vec<Source> {
    use super::{Companion, Format, Role};
    let mut out = Vec::new();
    for (base, (pri, tra)) in pairs {
        if pri.is_none() && tra.is_none() {
            continue;
        }
        let mut companions = Vec::new();
        if let Some(pri) = pri {
            companions.push(Companion {
                role: Role::HitIndex,
                path: pri.clone(),
            });
            let trf = base.with_extension("trfdb");
            if tra.is_some() && trf.is_file() {
                skipped.retain(|(p, _)| p != &trf);
                companions.push(Companion {
                    role: Role::TransientFeatures,
                    path: trf,
                });
            }
        }
        if let Some(vaex) = vaex::beside(base) {
            skipped.retain(|(p, _)| p != &vaex);
            companions.push(Companion {
                role: Role::Setup,
                path: vaex,
            });
        }
        out.push(Source {
            id: base
                .file_name()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_default(),
            format: Format::Vallen,
            files: tra.iter().cloned().collect(),
            companions,
            first_hit: 0,
        });
    }
    out
}

/// Open a Vallen source: the hit rows of its `.pridb` (every acquisition), then its
/// transient records in (channel, transient number) order, then a reject for each hit whose
/// transient the `.tradb` lacks.
pub fn open(src: &Source, cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
    open_with(src, cfg, true)
}

/// The hit rows (and the rejects of missing transients) of a Vallen source, without
/// decoding a single waveform: what `aepipe inspect` reads.
pub fn open_hits(src: &Source, cfg: &IngestConfig) -> Box<dyn Iterator<Item = Item> + Send> {
    open_with(src, cfg, false)
}

/// What a `.tradb` holds, from its integer columns only.
#[derive(Debug, Clone, PartialEq)]
pub struct TransientStats {
    pub transients: u64,
    pub shortest: usize,
    pub longest: usize,
    pub sample_rates_hz: Vec<u64>,
    pub channels: Vec<u32>,
}

/// Count and describe the transients of a `.tradb` without decoding one.
pub fn transient_stats(tradb: &Path) -> Result<TransientStats, IngestError> {
    let conn = open_ro(tradb)?;
    let e = |x: rusqlite::Error| file_err(tradb, format!("not a Vallen .tradb: {x}"));
    let (n, lo, hi): (i64, Option<i64>, Option<i64>) = conn
        .query_row(
            "SELECT count(*), min(Samples), max(Samples) FROM tr_data",
            [],
            |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
        )
        .map_err(e)?;
    let list = |sql: &str| -> Result<Vec<i64>, IngestError> {
        let mut st = conn.prepare(sql).map_err(e)?;
        let v = st
            .query_map([], |r| r.get::<_, Option<i64>>(0))
            .map_err(e)?
            .filter_map(|x| x.ok().flatten())
            .collect();
        Ok(v)
    };
    let rates = list("SELECT DISTINCT SampleRate FROM tr_data ORDER BY 1")?;
    let chans = list("SELECT DISTINCT Chan FROM tr_data ORDER BY 1")?;
    Ok(TransientStats {
        transients: n.max(0) as u64,
        shortest: lo.unwrap_or(0).max(0) as usize,
        longest: hi.unwrap_or(0).max(0) as usize,
        sample_rates_hz: rates.into_iter().map(|r| r.max(0) as u64).collect(),
        channels: chans.into_iter().map(|c| c.max(0) as u32).collect(),
    })
}

fn open_with(
    src: &Source,
    cfg: &IngestConfig,
    decode: bool,
) -> Box<dyn Iterator<Item = Item> + Send> {
    let experiment = src.id.clone();
    let pridb = src.companion(super::Role::HitIndex).map(Path::to_path_buf);
    let tradb = src.files.first().cloned();
    let mut first: Vec<Item> = Vec::new();
    // A .pridb SQLite refuses is read from a copy rebuilt from its whole pages (removed once
    // the readers hold it open).
    let rebuilt = pridb
        .as_deref()
        .and_then(|p| salvaged::salvage_pridb(p, cfg, &experiment, &mut first));
    let read_pridb_at = rebuilt.as_ref().map(|r| r.path.clone()).or(pridb.clone());
    let (info, mut hits) = open_hit_index(read_pridb_at.as_deref(), cfg, &experiment, &mut first);
    if let (Some(h), Some(p)) = (hits.as_mut(), pridb.as_ref()) {
        h.path = p.display().to_string();
    }
    let pridb_name = pridb
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    let offsets = TraiOffsets::new(&info.acq_max_trai);
    // VisualAE features beside the .pridb (X.trfdb), joined to the hits by TRAI.
    let trf = open_features(pridb.as_deref(), info.hits, &experiment, &mut first);
    // Markers, parametric and status rows, and what the .pridb holds by set type.
    let (sets, mut read) = open_set_rows(
        read_pridb_at.as_deref(),
        hits.is_some(),
        &experiment,
        info.time_base,
        cfg,
        &mut first,
    );
    let sets = match (sets, pridb.as_deref()) {
        (Some(s), Some(p)) => Some(s.named(p)),
        (s, _) => s,
    };
    if let Some(r) = &rebuilt {
        let _ = std::fs::remove_file(&r.path);
    }
    let has_pridb = hits.is_some();
    let t = open_transients(
        tradb,
        decode,
        &info,
        &offsets,
        &experiment,
        &pridb_name,
        &mut first,
    );
    // The transients the files tell of: every record of the .tradb, and every one a .pridb
    // hit promises that the .tradb lacks.
    read.insert(
        crate::model::RecordType::Transient,
        t.in_tradb + t.tail.len() as u64,
    );
    let last: VecDeque<Item> = if decode {
        last_items(&experiment, pridb.as_ref().unwrap_or(&t.tradb), read)
    } else {
        VecDeque::new()
    };
    let r = Reader {
        experiment,
        hits,
        sets,
        has_pridb,
        last,
        pending_hits: VecDeque::new(),
        tradb: t.tradb,
        conn: t.conn,
        salvaged: t.salvaged,
        time_base: t.time_base,
        keys: t.keys,
        have: t.have,
        offsets,
        info,
        tail: t.tail,
        max_samples: cfg.max_samples_per_record,
        trf,
    };
    Box::new(first.into_iter().chain(r))
}

/// The reject of a whole file of a source: what `reason` says is lost with it.
fn file_reject(experiment: &str, p: &Path, reason: String) -> Reject {
    Reject {
        record_type: crate::model::RecordType::File,
        experiment: experiment.to_string(),
        source_file: p.display().to_string(),
        record_id: String::new(),
        stage: Stage::Read,
        reason,
    }
}

/// The `.pridb`'s info and hit rows, or none and a reject in `first` (the transients go on).
fn open_hit_index(
    pridb: Option<&Path>,
    cfg: &IngestConfig,
    experiment: &str,
    first: &mut Vec<Item>,
) -> (PriInfo, Option<HitRows>) {
    match pridb {
        Some(p) => match read_pridb(p, cfg).and_then(|i| {
            let h = HitRows::open(p, i.time_base)?;
            Ok((i, h))
        }) {
            Ok((i, h)) => (i, Some(h)),
            Err(e) => {
                first.push(Item::Reject(file_reject(
                    experiment,
                    p,
                    format!("hits and load ignored: {e}"),
                )));
                (PriInfo::default(), None)
            }
        },
        None => (PriInfo::default(), None),
    }
}

/// The `.trfdb` features by TRAI — from its whole pages when SQLite refuses it — or none
/// and a note in `first` (the hits stand without them). `hits`: the `.pridb`'s hit count.
fn open_features(
    pridb: Option<&Path>,
    hits: u64,
    experiment: &str,
    first: &mut Vec<Item>,
) -> HashMap<i64, String> {
    match pridb.map(|p| p.with_extension("trfdb")) {
        Some(t) if t.is_file() => match read_trfdb(&t).or_else(|e| {
            salvaged::salvage_trfdb(&t, &e, hits, experiment, first).map_err(|s| (e, s))
        }) {
            Ok(m) => m,
            Err((e, s)) => {
                let e = format!("{e}; salvage: {}", salvaged::sqlite_cause(&s.to_string()));
                first.push(crate::model::Note::item(
                    experiment,
                    &t.display().to_string(),
                    format!("features not joined: {e}"),
                    true,
                ));
                HashMap::new()
            }
        },
        _ => HashMap::new(),
    }
}

/// The `.pridb`'s marker, parametric and status rows and set counts, or a reject in `first`.
fn open_set_rows(
    pridb: Option<&Path>,
    has_hits: bool,
    experiment: &str,
    time_base: f64,
    cfg: &IngestConfig,
    first: &mut Vec<Item>,
) -> (
    Option<sets::SetRows>,
    std::collections::BTreeMap<crate::model::RecordType, u64>,
) {
    match (pridb, has_hits) {
        (Some(p), true) => match sets::SetRows::open(p, experiment, time_base, &cfg.vallen) {
            Ok(s) => {
                let counts = open_ro(p).map(|c| sets::set_counts(&c)).unwrap_or_default();
                (Some(s), counts)
            }
            Err(e) => {
                first.push(Item::Reject(file_reject(
                    experiment,
                    p,
                    format!("parametric, status and marker rows ignored: {e}"),
                )));
                (None, Default::default())
            }
        },
        _ => (None, Default::default()),
    }
}

/// What [`open_transients`] hands the [`Reader`]: the `.tradb`'s keys and the missing rejects.
struct Transients {
    tradb: PathBuf,
    conn: Option<Connection>,
    time_base: f64,
    keys: VecDeque<(i64, u64, i64, i64)>,
    have: HashSet<(i64, i64, i64)>,
    tail: VecDeque<Reject>,
    /// How many records the `.tradb` holds (0 when it is missing or unreadable).
    in_tradb: u64,
    /// The rows salvaged from a `.tradb` SQLite refused (then `conn` is `None`).
    salvaged: Option<salvaged::SalvagedTr>,
}

/// List the `.tradb`'s transients (each fetched by its key later) and reject the hits it lacks.
fn open_transients(
    tradb: Option<PathBuf>,
    decode: bool,
    info: &PriInfo,
    offsets: &TraiOffsets,
    experiment: &str,
    pridb_name: &str,
    first: &mut Vec<Item>,
) -> Transients {
    let missing = |have: &HashSet<(i64, i64, i64)>, why: &str| {
        missing_rejects(experiment, pridb_name, &info.link, have, why)
    };
    // The transients to read (none when the .tradb is missing or unreadable; then every
    // transient a hit promises is a reject that says why).
    let no_transients = |tradb: PathBuf, why: &str| Transients {
        tradb,
        conn: None,
        time_base: 1e7,
        keys: VecDeque::new(),
        have: HashSet::new(),
        tail: missing(&HashSet::new(), why),
        in_tradb: 0,
        salvaged: None,
    };
    match tradb {
        None => no_transients(PathBuf::new(), "no .tradb beside the .pridb"),
        Some(tradb) => match list_transients(&tradb) {
            Ok((conn, raw)) => {
                let in_tradb = raw.len() as u64;
                let have: HashSet<(i64, i64, i64)> = raw.iter().map(|k| (k.3, k.2, k.1)).collect();
                let mut keys = transient_keys(&raw, info, offsets);
                let tail = missing(&have, "it is not in the .tradb");
                if !decode {
                    keys.clear();
                }
                let tb = time_base(&conn, "tr_globalinfo");
                Transients {
                    tradb,
                    conn: Some(conn),
                    time_base: tb,
                    keys: keys.into(),
                    have,
                    tail,
                    in_tradb,
                    salvaged: None,
                }
            }
            Err(e) => match salvaged::transients(
                &tradb, &e, decode, info, offsets, experiment, pridb_name, first,
            ) {
                Some(t) => t,
                None => {
                    first.push(Item::Reject(file_reject(experiment, &tradb, e.to_string())));
                    no_transients(tradb, "the .tradb cannot be read")
                }
            },
        },
    }
}

/// The setup (records by type) and the tally: the items emitted once everything else is out.
fn last_items(
    experiment: &str,
    source_file: &Path,
    read: std::collections::BTreeMap<crate::model::RecordType, u64>,
) -> VecDeque<Item> {
    let mut vendor = std::collections::BTreeMap::new();
    for (t, n) in &read {
        vendor.insert(format!("{t}"), *n);
    }
    VecDeque::from([
        Item::Setup(Box::new(crate::model::AcquisitionSetup {
            experiment: experiment.to_string(),
            source_file: source_file.display().to_string(),
            vendor_records: vendor,
            ..Default::default()
        })),
        Item::Tally(crate::model::Tally {
            experiment: experiment.to_string(),
            read,
            ..Default::default()
        }),
    ])
}

/// The rejects of the hits (`link`: (TRAI, channel, time) → acquisition) whose transient
/// is not in `have`, in (acquisition, TRAI, channel, time) order.
fn missing_rejects(
    experiment: &str,
    pridb: &str,
    link: &HashMap<(i64, i64, i64), u32>,
    have: &HashSet<(i64, i64, i64)>,
    why: &str,
) -> VecDeque<Reject> {
    let mut m: Vec<(u32, i64, i64, i64)> = link
        .iter()
        .filter(|(k, _)| !have.contains(k))
        .map(|(&(t, c, time), &a)| (a, t, c, time))
        .collect();
    m.sort_unstable();
    m.into_iter()
        .map(|(a, t, c, _)| missing_reject(experiment, pridb, (a, t, c), why))
        .collect()
}

/// The reject of a hit (acquisition, TRAI, channel) whose transient is not there.
fn missing_reject(experiment: &str, pridb: &str, (a, t, c): (u32, i64, i64), why: &str) -> Reject {
    Reject {
        record_type: crate::model::RecordType::Transient,
        experiment: experiment.to_string(),
        source_file: pridb.to_string(),
        record_id: if a > 1 {
            format!("TRAI {t} ch{c} acquisition {a}")
        } else {
            format!("TRAI {t} ch{c}")
        },
        stage: Stage::Read,
        reason: format!("hit on channel {c} has no transient: {why}"),
    }
}

/// (SetID, Time, Chan, TRAI) of every transient of a `.tradb`, in storage order.
#[allow(clippy::type_complexity)]
fn list_transients(tradb: &Path) -> Result<(Connection, Vec<(i64, i64, i64, i64)>), IngestError> {
    let conn = open_ro(tradb)?;
    let mut st = conn
        .prepare("SELECT SetID, Time, Chan, TRAI FROM tr_data ORDER BY SetID")
        .map_err(|e| file_err(tradb, format!("not a Vallen .tradb: {e}")))?;
    let raw = st
        .query_map([], |r| {
            Ok((
                r.get::<_, i64>(0)?,
                r.get::<_, Option<i64>>(1)?.unwrap_or(0),
                r.get::<_, Option<i64>>(2)?.unwrap_or(0),
                r.get::<_, Option<i64>>(3)?.unwrap_or(0),
            ))
        })
        .and_then(|it| it.collect::<Result<Vec<_>, _>>())
        .map_err(|e| file_err(tradb, format!("cannot list records: {e}")))?;
    drop(st);
    Ok((conn, raw))
}

/// The output order of the transients, (channel, number, SetID, TRAI): a transient's number
/// comes through its hit's acquisition when the `.pridb` knows it, else from the `.tradb`'s
/// own TRAI restarts (a `.tradb` read alone).
fn transient_keys(
    raw: &[(i64, i64, i64, i64)],
    info: &PriInfo,
    offsets: &TraiOffsets,
) -> Vec<(i64, u64, i64, i64)> {
    // The .tradb's own acquisitions: a TRAI that does not rise adds the largest TRAI so far
    // to the offset (what TraiOffsets does for the .pridb's acquisitions).
    let (mut own_offset, mut own_max) = (0i64, 0i64);
    let mut keys: Vec<(i64, u64, i64, i64)> = Vec::with_capacity(raw.len());
    for &(setid, time, chan, trai) in raw {
        if trai > 0 && trai <= own_max {
            own_offset += own_max;
            own_max = 0;
        }
        own_max = own_max.max(trai);
        let number = match info.link.get(&(trai, chan, time)) {
            Some(&acq) => offsets.number(acq, trai),
            None => (trai + own_offset).max(0) as u64,
        };
        keys.push((chan, number, setid, trai));
    }
    keys.sort_unstable();
    keys
}

mod pridb;
mod salvaged;
mod trfdb;
pub use trfdb::read_trfdb;
mod sets;
pub mod tail;
pub mod txt;
pub mod vaex;
mod write;
use pridb::HitRows;
pub use pridb::{read_pridb, PriInfo, TraiOffsets};
pub use write::{write_pair, HitToWrite, Journal, PairWriter};
