//! Vallen AMSY databases: `.tradb` (transient waveforms) joined with `.pridb` (hits and
//! parametric inputs).
//!
//! * Waveforms: `tr_data` rows; `DataFormat` 0 = raw little-endian int16, 2 = FLAC;
//!   volts = ADC × `TR_mV` · 1e-3 (`TR_mV` from `tr_params` by `ParamID`); time =
//!   `Time / TimeBase` (`tr_globalinfo`, 10 MHz by default).
//! * Hits: `ae_data` rows with `SetType = 2`; their `TRAI` links to the waveform. A hit whose
//!   TRAI has no waveform becomes a reject row, never a silent gap.
//! * Parametric rows (`SetType = 1`) carry `PA0`, `PA1`, … (ADC × `PAn_mV`); the config maps
//!   them to load and extension, interpolated at each hit's time.
//!
//! The reader first lists `(Chan, TRAI, SetID)` (integers only), then fetches each waveform by
//! its primary key: ordered output without asking SQLite to sort blobs, one waveform in memory.

use super::{file_err, IngestError, Source, TimeSeries};
use crate::config::IngestConfig;
use crate::model::{db_ae, AeRecord, HitRow, HitSource, Item, Reject, Stage};
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

/// What the `.pridb` tells about the hits: their acquisitions, the transient each one
/// links to, and the parametric series.
#[derive(Debug, Default)]
pub struct PriInfo {
    /// Hits (`SetType` 2) in the file.
    pub hits: u64,
    /// First `SetID` of each acquisition after the first (a section-start marker, or a
    /// `TRAI` that does not rise).
    pub acq_starts: Vec<i64>,
    /// Largest `TRAI` of each acquisition.
    pub acq_max_trai: Vec<i64>,
    /// (TRAI, channel, time in ticks) → acquisition of every hit that has a transient index.
    pub link: HashMap<(i64, i64, i64), u32>,
    pub load: TimeSeries,
    pub extension: TimeSeries,
    /// Parametric inputs present (`PA0`, `PA1`, …).
    pub parametric: Vec<String>,
    /// Ticks per second of the `Time` column (`ae_globalinfo`).
    pub time_base: f64,
}

impl PriInfo {
    /// 1-based acquisition of the set `setid`.
    pub fn acquisition_of(&self, setid: i64) -> u32 {
        self.acq_starts.partition_point(|&s| s <= setid) as u32 + 1
    }
}

/// Transient numbers unique in an experiment: `TRAI` in the first acquisition, `TRAI` plus
/// the largest `TRAI` of the earlier acquisitions after a restart.
#[derive(Debug, Clone, Default)]
pub struct TraiOffsets(Vec<i64>);

impl TraiOffsets {
    pub fn new(acq_max_trai: &[i64]) -> TraiOffsets {
        let mut off = Vec::with_capacity(acq_max_trai.len());
        let mut sum = 0i64;
        for &m in acq_max_trai {
            off.push(sum);
            sum += m.max(0);
        }
        TraiOffsets(off)
    }
    pub fn number(&self, acquisition: u32, trai: i64) -> u64 {
        let k = (acquisition.max(1) - 1) as usize;
        (trai + self.0.get(k).copied().unwrap_or(0)).max(0) as u64
    }
}

fn parametric_series(
    conn: &Connection,
    cols: &[String],
    param: &str,
    time_base: f64,
    scale: f64,
) -> TimeSeries {
    if param.is_empty() || !cols.iter().any(|c| c == param) {
        return TimeSeries::default();
    }
    let has_mv = columns(conn, "ae_params")
        .iter()
        .any(|c| c == &format!("{param}_mV"));
    let value = if has_mv {
        format!("d.{param} * p.{param}_mV")
    } else {
        format!("d.{param}")
    };
    let sql = format!(
        "SELECT d.Time, {value} FROM ae_data d LEFT JOIN ae_params p ON p.ID = d.ParamID \
         WHERE d.SetType = 1 AND d.{param} IS NOT NULL ORDER BY d.Time"
    );
    let Ok(mut st) = conn.prepare(&sql) else {
        return TimeSeries::default();
    };
    let pairs: Vec<(f64, f64)> = st
        .query_map([], |r| {
            Ok((r.get::<_, f64>(0)? / time_base, r.get::<_, Option<f64>>(1)?))
        })
        .map(|it| {
            it.flatten()
                .filter_map(|(t, v)| v.map(|v| (t, v * scale)))
                .collect()
        })
        .unwrap_or_default();
    TimeSeries::from_pairs(pairs)
}

/// Read the hit index and parametric series of a `.pridb`.
pub fn read_pridb(path: &Path, cfg: &IngestConfig) -> Result<PriInfo, IngestError> {
    let conn = open_ro(path)?;
    let cols = columns(&conn, "ae_data");
    if cols.is_empty() {
        return Err(file_err(path, "no ae_data table: not a Vallen .pridb"));
    }
    let tb = time_base(&conn, "ae_globalinfo");
    let mut info = PriInfo {
        time_base: tb,
        parametric: cols
            .iter()
            .filter(|c| c.starts_with("PA"))
            .cloned()
            .collect(),
        ..Default::default()
    };
    // One pass over the sets in storage order: section-start markers (SetType 6) and a
    // TRAI that does not rise begin a new acquisition.
    let mut st = conn
        .prepare("SELECT SetID, SetType, Time, Chan, TRAI FROM ae_data ORDER BY SetID")
        .map_err(|e| file_err(path, format!("cannot read hits: {e}")))?;
    let rows = st
        .query_map([], |r| {
            Ok((
                r.get::<_, i64>(0)?,
                r.get::<_, Option<i64>>(1)?.unwrap_or(0),
                r.get::<_, Option<i64>>(2)?.unwrap_or(0),
                r.get::<_, Option<i64>>(3)?.unwrap_or(0),
                r.get::<_, Option<i64>>(4)?.unwrap_or(0),
            ))
        })
        .map_err(|e| file_err(path, format!("cannot read hits: {e}")))?;
    let (mut seen_hit, mut marker_pending, mut max_trai) = (false, false, 0i64);
    for row in rows {
        let (setid, set_type, time, chan, trai) =
            row.map_err(|e| file_err(path, format!("cannot read hits: {e}")))?;
        match set_type {
            6 => marker_pending = true,
            2 => {
                let restart = trai > 0 && trai <= max_trai;
                if seen_hit && (marker_pending || restart) {
                    info.acq_starts.push(setid);
                    info.acq_max_trai.push(max_trai);
                    max_trai = 0;
                }
                marker_pending = false;
                seen_hit = true;
                info.hits += 1;
                if trai > 0 {
                    max_trai = max_trai.max(trai);
                    let acq = info.acq_starts.len() as u32 + 1;
                    info.link.insert((trai, chan, time), acq);
                }
            }
            _ => {}
        }
    }
    info.acq_max_trai.push(max_trai);
    let v = &cfg.vallen;
    info.load = parametric_series(&conn, &cols, &v.load_param, tb, v.load_n_per_mv);
    info.extension = parametric_series(&conn, &cols, &v.extension_param, tb, v.extension_m_per_mv);
    Ok(info)
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

/// The features of a VisualAE `.trfdb` beside the `.pridb`, per TRAI, as JSON objects keyed
/// `name [unit]` (the file's own `trf_fieldinfo`). Empty when there is none.
pub fn read_trfdb(path: &Path) -> Result<HashMap<i64, String>, IngestError> {
    let conn = open_ro(path)?;
    let cols = columns(&conn, "trf_data");
    if !cols.iter().any(|c| c == "TRAI") {
        return Err(file_err(
            path,
            "no trf_data table with a TRAI: not a .trfdb",
        ));
    }
    let units: HashMap<String, String> = conn
        .prepare("SELECT * FROM trf_fieldinfo")
        .and_then(|mut st| {
            st.query_map([], |r| {
                Ok((r.get::<_, String>(0)?, r.get::<_, Option<String>>(2)?))
            })
            .map(|it| {
                it.flatten()
                    .filter_map(|(n, u)| u.map(|u| (n, u.trim_matches(['[', ']']).to_string())))
                    .collect()
            })
        })
        .unwrap_or_default();
    let names: Vec<&String> = cols.iter().filter(|c| *c != "TRAI").collect();
    let sql = format!(
        "SELECT TRAI, {} FROM trf_data",
        names
            .iter()
            .map(|c| format!("\"{c}\""))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let mut st = conn
        .prepare(&sql)
        .map_err(|e| file_err(path, format!("cannot read trf_data: {e}")))?;
    let rows = st
        .query_map([], |r| {
            let trai: i64 = r.get(0)?;
            let mut m = serde_json::Map::new();
            for (k, name) in names.iter().enumerate() {
                if let Some(v) = r.get::<_, Option<f64>>(k + 1)? {
                    let key = match units.get(*name) {
                        Some(u) if !u.is_empty() => format!("{name} [{u}]"),
                        _ => name.to_string(),
                    };
                    m.insert(key, serde_json::json!(v));
                }
            }
            Ok((trai, serde_json::Value::Object(m).to_string()))
        })
        .map_err(|e| file_err(path, format!("cannot read trf_data: {e}")))?;
    Ok(rows.flatten().collect())
}

/// The hit rows of a `.pridb`, read in chunks of 1 024 sets (bounded memory).
struct HitRows {
    conn: Connection,
    sql: String,
    path: String,
    time_base: f64,
    last_setid: i64,
    number: u64,
    done: bool,
}

impl HitRows {
    fn open(path: &Path, time_base: f64) -> Result<HitRows, IngestError> {
        let conn = open_ro(path)?;
        let view = columns(&conn, "view_ae_data");
        // The view applies the file's own scaling (ae_params, ae_fieldinfo); a column the
        // view lacks is null.
        let pick = |c: &str| {
            if view.iter().any(|v| v == c) {
                format!("v.{c}")
            } else {
                "NULL".to_string()
            }
        };
        let sql = if view.is_empty() {
            "SELECT d.SetID, d.Time, d.Chan, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, d.TRAI \
             FROM ae_data d WHERE d.SetType = 2 AND d.SetID > ?1 ORDER BY d.SetID LIMIT 1024"
                .to_string()
        } else {
            format!(
                "SELECT d.SetID, d.Time, d.Chan, {}, {}, {}, {}, {}, {}, {}, {}, d.TRAI \
                 FROM ae_data d JOIN view_ae_data v ON v.SetID = d.SetID \
                 WHERE d.SetType = 2 AND d.SetID > ?1 ORDER BY d.SetID LIMIT 1024",
                pick("Thr"),
                pick("Amp"),
                pick("RiseT"),
                pick("Dur"),
                pick("Eny"),
                pick("SS"),
                pick("RMS"),
                pick("Counts"),
            )
        };
        Ok(HitRows {
            conn,
            sql,
            path: path.display().to_string(),
            time_base,
            last_setid: i64::MIN,
            number: 0,
            done: false,
        })
    }

    /// The next chunk: (SetID, time ticks, hit row without experiment-level links).
    fn chunk(&mut self) -> Result<Vec<(i64, i64, HitRow)>, String> {
        if self.done {
            return Ok(vec![]);
        }
        let mut st = self
            .conn
            .prepare_cached(&self.sql)
            .map_err(|e| e.to_string())?;
        let db = |uv: Option<f64>| uv.filter(|v| *v > 0.0).map(|v| db_ae(v * 1e-6));
        let rows: Vec<_> = st
            .query_map([self.last_setid], |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, Option<i64>>(1)?.unwrap_or(0),
                    r.get::<_, Option<i64>>(2)?.unwrap_or(0),
                    r.get::<_, Option<f64>>(3)?,
                    r.get::<_, Option<f64>>(4)?,
                    r.get::<_, Option<f64>>(5)?,
                    r.get::<_, Option<f64>>(6)?,
                    r.get::<_, Option<f64>>(7)?,
                    r.get::<_, Option<f64>>(8)?,
                    r.get::<_, Option<f64>>(9)?,
                    r.get::<_, Option<i64>>(10)?,
                    r.get::<_, Option<i64>>(11)?,
                ))
            })
            .and_then(|it| it.collect::<Result<Vec<_>, _>>())
            .map_err(|e| e.to_string())?;
        if rows.len() < 1024 {
            self.done = true;
        }
        let mut out = Vec::with_capacity(rows.len());
        for (setid, time, chan, thr, amp, rise, dur, eny, ss, rms, counts, trai) in rows {
            self.last_setid = setid;
            self.number += 1;
            out.push((
                setid,
                time,
                HitRow {
                    channel: chan.max(0) as u32,
                    hit: self.number,
                    time_s: Some(time as f64 / self.time_base),
                    amplitude_db: db(amp),
                    threshold_db: db(thr),
                    rise_time_s: rise.map(|v| v * 1e-6),
                    duration_s: dur.map(|v| v * 1e-6),
                    counts,
                    energy_eu: eny,
                    signal_strength_vs: ss.map(|v| v * 1e-9),
                    rms_v: rms.map(|v| v * 1e-6),
                    trai: trai.filter(|t| *t > 0),
                    source: HitSource::Vallen,
                    source_file: self.path.clone(),
                    ..Default::default()
                },
            ));
        }
        Ok(out)
    }
}

struct Reader {
    experiment: String,
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
}

impl Reader {
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

    fn fetch(&mut self, chan: i64, number: u64, setid: i64, trai: i64) -> Item {
        let conn = self.conn.as_ref().expect("open while keys remain");
        let row = conn.query_row(
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
        );
        let reject = |reason: String| {
            Item::Reject(Reject {
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
        let scale = tr_mv * 1e-3;
        let time_s = time.map(|t| t as f64 / self.time_base);
        Item::Record(AeRecord {
            experiment: self.experiment.clone(),
            channel: chan.max(0) as u32,
            hit: number,
            time_s,
            sample_rate_hz: rate,
            pretrigger: pre.unwrap_or(0).max(0) as u32,
            samples: adc.into_iter().map(|a| (a as f64 * scale) as f32).collect(),
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
            if !self.next_hits() {
                break;
            }
        }
        if let Some((chan, number, setid, trai)) = self.keys.pop_front() {
            return Some(self.fetch(chan, number, setid, trai));
        }
        self.conn = None;
        self.tail.pop_front().map(Item::Reject)
    }
}

/// Open a Vallen source: the hit rows of its `.pridb` (every acquisition), then its
/// transient records in (channel, transient number) order, then a reject for each hit whose
/// transient the `.tradb` lacks.
pub fn open(src: &Source, cfg: &IngestConfig) -> Box<dyn Iterator<Item = Item> + Send> {
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
    let pridb = src.companions.first().cloned();
    let tradb = src.files.first().cloned();
    let mut first: Vec<Item> = Vec::new();
    let file_reject = |p: &Path, reason: String| Reject {
        experiment: experiment.clone(),
        source_file: p.display().to_string(),
        record_id: String::new(),
        stage: Stage::Read,
        reason,
    };
    let (info, hits) = match &pridb {
        Some(p) => match read_pridb(p, cfg).and_then(|i| {
            let h = HitRows::open(p, i.time_base)?;
            Ok((i, h))
        }) {
            Ok((i, h)) => (i, Some(h)),
            Err(e) => {
                first.push(Item::Reject(file_reject(
                    p,
                    format!("hits and load ignored: {e}"),
                )));
                (PriInfo::default(), None)
            }
        },
        None => (PriInfo::default(), None),
    };
    let pridb_name = pridb
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    let missing =
        |info: &PriInfo, have: &HashSet<(i64, i64, i64)>, why: &str| -> VecDeque<Reject> {
            let mut m: Vec<(u32, i64, i64, i64)> = info
                .link
                .iter()
                .filter(|(k, _)| !have.contains(k))
                .map(|(&(t, c, time), &a)| (a, t, c, time))
                .collect();
            m.sort_unstable();
            m.into_iter()
                .map(|(a, t, c, _)| Reject {
                    experiment: experiment.clone(),
                    source_file: pridb_name.clone(),
                    record_id: if a > 1 {
                        format!("TRAI {t} ch{c} acquisition {a}")
                    } else {
                        format!("TRAI {t} ch{c}")
                    },
                    stage: Stage::Read,
                    reason: format!("hit on channel {c} has no transient: {why}"),
                })
                .collect()
        };
    let offsets = TraiOffsets::new(&info.acq_max_trai);
    // VisualAE features beside the .pridb (X.trfdb), joined to the hits by TRAI.
    let trf = match pridb.as_ref().map(|p| p.with_extension("trfdb")) {
        Some(t) if t.is_file() => match read_trfdb(&t) {
            Ok(m) => m,
            Err(e) => {
                first.push(Item::Note(crate::model::Note {
                    experiment: experiment.clone(),
                    source_file: t.display().to_string(),
                    message: format!("features not joined: {e}"),
                }));
                HashMap::new()
            }
        },
        _ => HashMap::new(),
    };
    let reader = |tradb: PathBuf,
                  conn: Option<Connection>,
                  time_base: f64,
                  keys: VecDeque<(i64, u64, i64, i64)>,
                  have: HashSet<(i64, i64, i64)>,
                  tail: VecDeque<Reject>,
                  info: PriInfo| Reader {
        experiment: experiment.clone(),
        hits,
        pending_hits: VecDeque::new(),
        tradb,
        conn,
        time_base,
        keys,
        have,
        offsets: offsets.clone(),
        info,
        tail,
        max_samples: cfg.max_samples_per_record,
        trf: trf.clone(),
    };
    // The transients to read (none when the .tradb is missing or unreadable; then every
    // transient a hit promises is a reject that says why).
    let no_transients = |why: &str| {
        (
            None,
            1e7,
            VecDeque::new(),
            HashSet::new(),
            missing(&info, &HashSet::new(), why),
        )
    };
    let (tradb, (conn, tb, keys, have, tail)) = match tradb {
        None => (PathBuf::new(), no_transients("no .tradb beside the .pridb")),
        Some(tradb) => match list_transients(&tradb) {
            Ok((conn, raw)) => {
                let have: HashSet<(i64, i64, i64)> = raw.iter().map(|k| (k.3, k.2, k.1)).collect();
                let mut keys = transient_keys(&raw, &info, &offsets);
                let tail = missing(&info, &have, "it is not in the .tradb");
                if !decode {
                    keys.clear();
                }
                let tb = time_base(&conn, "tr_globalinfo");
                (tradb, (Some(conn), tb, keys.into(), have, tail))
            }
            Err(e) => {
                first.push(Item::Reject(file_reject(&tradb, e.to_string())));
                (tradb, no_transients("the .tradb cannot be read"))
            }
        },
    };
    let r = reader(tradb, conn, tb, keys, have, tail, info);
    Box::new(first.into_iter().chain(r))
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

/// One hit to write into a Vallen pair (see [`write_pair`]).
pub struct HitToWrite<'a> {
    pub channel: u32,
    pub trai: u64,
    pub time_s: f64,
    pub sample_rate_hz: f64,
    pub pretrigger: u32,
    /// Volts; quantised to int16 with the pair's `TR_mV`.
    pub samples_v: &'a [f32],
    /// Recording was restarted into the database before this hit: a section-start marker
    /// (`SetType` 6) precedes it, and the caller restarts `trai` and `time_s`.
    pub restart: bool,
    /// Write the transient (`tr_data` row); `false` leaves the hit without one.
    pub transient: bool,
}

/// Write a Vallen `.pridb`/`.tradb` pair (raw int16 waveforms, `DataFormat` 0) with the
/// tables and views of the real AMSY-6 files, so that aepipe's own reader and vallenae read
/// it. `parametric` rows are `(time_s, pa0_mv, pa1_mv)`. Used for fixtures, the demo and the
/// synthetic experiment. Returns the two paths.
pub fn write_pair<'a>(
    base: &Path,
    hits: impl IntoIterator<Item = HitToWrite<'a>>,
    parametric: &[(f64, f64, f64)],
    tr_mv: f64,
    threshold_v: f64,
) -> rusqlite::Result<(PathBuf, PathBuf)> {
    let pri_path = base.with_extension("pridb");
    let tra_path = base.with_extension("tradb");
    for p in [&pri_path, &tra_path] {
        let _ = std::fs::remove_file(p);
    }
    let pri = Connection::open(&pri_path)?;
    let tra = Connection::open(&tra_path)?;
    let adc_uv = tr_mv * 1e3 / 2.0f64.powi(11); // arbitrary but consistent hit-feature ADC step
    pri.execute_batch(&format!(
        "PRAGMA journal_mode=OFF; PRAGMA synchronous=OFF;
        CREATE TABLE ae_data (\"SetID\" INTEGER PRIMARY KEY,\"SetType\" INT,\"Time\" INT,\"Chan\" INT,\"Status\" INT,\"ParamID\" INT,\"Thr\" INT,\"Amp\" INT,\"RiseT\" INT,\"Dur\" INT,\"Eny\" INT,\"SS\" INT,\"RMS\" INT,\"Counts\" INT,\"TRAI\" INT,\"PCTD\" INT,\"PCTA\" INT,\"PA0\" INT,\"PA1\" INT);
        CREATE TABLE acq_setup(ID INTEGER PRIMARY KEY, Data TEXT);
        CREATE TABLE ae_markers (\"SetID\" INT UNIQUE,\"Number\" INT,\"Data\" TEXT);
        CREATE TABLE ae_globalinfo(Key UNIQUE, Value);
        CREATE TABLE ae_fieldinfo (field,Unit,SetTypes,Parameter,Factor);
        CREATE TABLE ae_params (\"ID\" INTEGER PRIMARY KEY,\"SetupID\" INT,\"Chan\" INT,\"ADC_µV\" REAL,\"ADC_TE\" REAL,\"ADC_SS\" REAL,\"PA0_mV\" REAL,\"PA1_mV\" REAL);
        CREATE TABLE data_integrity(TableName TEXT PRIMARY KEY UNIQUE, HashV1 INT, LastRow INT);
        CREATE VIEW view_ae_data as select (d.SetID) as SetID,(d.SetType) as SetType,(d.Time*1E-7) as Time,(d.Chan) as Chan,(d.Status) as Status,(d.Thr*p.ADC_µV) as Thr,(d.Amp*p.ADC_µV) as Amp,(d.RiseT*0.1) as RiseT,(d.Dur*0.1) as Dur,(d.Eny*p.ADC_TE) as Eny,(d.SS*p.ADC_SS) as SS,(d.RMS*0.0065536*p.ADC_µV) as RMS,(d.Counts) as Counts,(d.TRAI) as TRAI,(d.PCTD) as PCTD,(d.PCTA) as PCTA,(d.PA0*p.PA0_mV) as PA0,(d.PA1*p.PA1_mV) as PA1 from ae_data d  left join ae_params p on p.ID=d.ParamID;
        CREATE VIEW view_ae_markers as select m.*, l.SetType, l.Time*1E-7 as Time from ae_markers m cross join ae_data l on l.SetID = m.SetID;
        INSERT INTO ae_globalinfo VALUES ('Version', 1), ('FileStatus', 0), ('TimeBase', 10000000), ('WriterName', 'aepipe');
        INSERT INTO ae_fieldinfo VALUES ('Time','[s]',NULL,NULL,1e-07),('Thr','[µV]',12,'ADC_µV',NULL),('Amp','[µV]',4,'ADC_µV',NULL),('RiseT','[µs]',4,NULL,0.1),('Dur','[µs]',4,NULL,0.1),('Eny','[eu]',12,'ADC_TE',NULL),('SS','[nVs]',12,'ADC_SS',NULL),('RMS','[µV]',12,'ADC_µV',0.0065536),('PA0','[mV]',2,'PA0_mV',NULL),('PA1','[mV]',2,'PA1_mV',NULL);
        INSERT INTO ae_params VALUES (1, 1, 0, 0.0, 0.0, 0.0, 0.001, 0.001), (2, 1, 1, {adc_uv}, 1.0, 1.0, 0.0, 0.0);"
    ))?;
    tra.execute_batch(&format!(
        "PRAGMA journal_mode=OFF; PRAGMA synchronous=OFF;
        CREATE TABLE tr_data (\"SetID\" INTEGER PRIMARY KEY,\"Time\" INT,\"TRAI\" INT,\"Status\" INT,\"ParamID\" INT,\"Chan\" INT,\"Pretrigger\" INT,\"Thr\" INT,\"SampleRate\" INT,\"Samples\" INT,\"DataFormat\" INT,\"Data\" BLOB);
        CREATE TABLE tr_globalinfo(Key UNIQUE, Value);
        CREATE TABLE tr_fieldinfo (field,Unit,Parameter);
        CREATE TABLE tr_params (\"ID\" INTEGER PRIMARY KEY,\"SetupID\" INT,\"Chan\" INT,\"ADC_µV\" REAL,\"TR_mV\" REAL);
        CREATE INDEX idx_TRAI on tr_data (TRAI);
        CREATE VIEW view_tr_data as select (d.SetID) as SetID,(d.Time*1E-7) as Time,(d.TRAI) as TRAI,(d.Status) as Status,(d.Chan) as Chan,(d.Pretrigger) as Pretrigger,(d.Thr*p.ADC_µV) as Thr,(d.SampleRate) as SampleRate,(d.Samples) as Samples,(d.DataFormat) as DataFormat,p.TR_mV as TR_mV,(d.Data) as Data from tr_data d  left join tr_params p on p.ID=d.ParamID;
        INSERT INTO tr_globalinfo VALUES ('Version', 1), ('FileStatus', 0), ('TimeBase', 10000000), ('WriterName', 'aepipe');
        INSERT INTO tr_fieldinfo VALUES ('Time','[s]',NULL),('Thr','[µV]','ADC_µV'),('SampleRate','[Hz]',NULL);
        INSERT INTO tr_params VALUES (1, 1, 0, 0.0, 0.0), (2, 1, 1, {adc_uv}, {tr_mv});"
    ))?;
    // Merge hits and parametric rows in time order, as the acquisition would have.
    enum Row<'a> {
        Par(f64, f64, f64),
        Hit(HitToWrite<'a>),
    }
    // Each acquisition in time order; the parametric rows belong to the first.
    let mut acquisitions: Vec<Vec<Row>> = vec![parametric
        .iter()
        .map(|&(t, a, b)| Row::Par(t, a, b))
        .collect()];
    for h in hits {
        if h.restart {
            acquisitions.push(Vec::new());
        }
        acquisitions.last_mut().expect("one").push(Row::Hit(h));
    }
    let t_of = |r: &Row| match r {
        Row::Par(t, ..) => *t,
        Row::Hit(h) => h.time_s,
    };
    for a in &mut acquisitions {
        a.sort_by(|a, b| t_of(a).total_cmp(&t_of(b)));
    }
    let to_ticks = |t: f64| (t * 1e7).round() as i64;
    let scale = 1e3 / tr_mv; // volts -> ADC counts
    let thr_adc = (threshold_v * 1e6 / adc_uv).round() as i64;
    let ptx = pri.unchecked_transaction()?;
    let ttx = tra.unchecked_transaction()?;
    {
        let mut ins_pri = ptx.prepare(
            "INSERT INTO ae_data (SetType, Time, Chan, Status, ParamID, Thr, Amp, RiseT, Dur, Eny, SS, RMS, Counts, TRAI, PA0, PA1) \
             VALUES (?1, ?2, ?3, 0, ?4, ?5, ?6, 0, 0, 0, 0, 0, 0, ?7, ?8, ?9)",
        )?;
        let mut ins_tra = ttx.prepare(
            "INSERT INTO tr_data (Time, TRAI, Status, ParamID, Chan, Pretrigger, Thr, SampleRate, Samples, DataFormat, Data) \
             VALUES (?1, ?2, 0, 2, ?3, ?4, ?5, ?6, ?7, 0, ?8)",
        )?;
        let mut blob = Vec::new();
        let mut marker = ptx.prepare("INSERT INTO ae_data (SetType, Time) VALUES (6, 0)")?;
        for (k, rows) in acquisitions.into_iter().enumerate() {
            if k > 0 {
                marker.execute([])?;
                ptx.execute(
                    "INSERT INTO ae_markers (SetID, Number, Data) VALUES (last_insert_rowid(), ?1, '')",
                    [k as i64 + 1],
                )?;
            }
            for r in rows {
                match r {
                    Row::Par(t, a, b) => {
                        ins_pri.execute(rusqlite::params![
                            1,
                            to_ticks(t),
                            Option::<i64>::None,
                            1,
                            Option::<i64>::None,
                            Option::<i64>::None,
                            Option::<i64>::None,
                            (a * 1e3).round() as i64,
                            (b * 1e3).round() as i64
                        ])?;
                    }
                    Row::Hit(h) => {
                        blob.clear();
                        let mut peak = 0i64;
                        for &v in h.samples_v {
                            let q = (v as f64 * scale).round().clamp(-32768.0, 32767.0) as i16;
                            peak = peak.max((q as i64).abs());
                            blob.extend_from_slice(&q.to_le_bytes());
                        }
                        let amp = (peak as f64 * tr_mv * 1e3 / adc_uv).round() as i64;
                        ins_pri.execute(rusqlite::params![
                            2,
                            to_ticks(h.time_s),
                            h.channel,
                            2,
                            thr_adc,
                            amp,
                            h.trai as i64,
                            Option::<i64>::None,
                            Option::<i64>::None
                        ])?;
                        if h.transient {
                            ins_tra.execute(rusqlite::params![
                                to_ticks(h.time_s),
                                h.trai as i64,
                                h.channel,
                                h.pretrigger,
                                thr_adc,
                                h.sample_rate_hz.round() as i64,
                                h.samples_v.len() as i64,
                                &blob
                            ])?;
                        }
                    }
                }
            }
        }
    }
    ptx.commit()?;
    ttx.commit()?;
    Ok((pri_path, tra_path))
}
