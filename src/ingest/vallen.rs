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
use crate::model::{AeRecord, Item, Reject, Stage};
use rusqlite::{Connection, OpenFlags, OptionalExtension};
use std::collections::{BTreeMap, VecDeque};
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

/// What the `.pridb` tells about the hits: TRAI → channel, and the parametric series.
#[derive(Debug, Default)]
pub struct PriInfo {
    /// TRAI → channel of every hit that should have a waveform.
    pub trai_chan: BTreeMap<i64, i64>,
    /// Hits without a transient record (TRAI 0 or null).
    pub hits_without_waveform: u64,
    pub load: TimeSeries,
    pub extension: TimeSeries,
    /// Parametric inputs present (`PA0`, `PA1`, …).
    pub parametric: Vec<String>,
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
        parametric: cols
            .iter()
            .filter(|c| c.starts_with("PA"))
            .cloned()
            .collect(),
        ..Default::default()
    };
    let mut st = conn
        .prepare("SELECT TRAI, Chan FROM ae_data WHERE SetType = 2")
        .map_err(|e| file_err(path, format!("cannot read hits: {e}")))?;
    let rows = st
        .query_map([], |r| {
            Ok((r.get::<_, Option<i64>>(0)?, r.get::<_, Option<i64>>(1)?))
        })
        .map_err(|e| file_err(path, format!("cannot read hits: {e}")))?;
    for row in rows {
        let (trai, chan) = row.map_err(|e| file_err(path, format!("cannot read hits: {e}")))?;
        match trai {
            Some(t) if t > 0 => {
                info.trai_chan.insert(t, chan.unwrap_or(0));
            }
            _ => info.hits_without_waveform += 1,
        }
    }
    let v = &cfg.vallen;
    info.load = parametric_series(&conn, &cols, &v.load_param, tb, v.load_n_per_mv);
    info.extension = parametric_series(&conn, &cols, &v.extension_param, tb, v.extension_m_per_mv);
    Ok(info)
}

/// Decode one `tr_data` blob into ADC counts.
pub(crate) fn decode_blob(format: i64, data: &[u8], samples: usize) -> Result<Vec<i32>, String> {
    let adc: Vec<i32> = match format {
        0 => {
            if data.len() != samples * 2 {
                return Err(format!(
                    "raw blob holds {} bytes, Samples says {samples} int16 ({} bytes)",
                    data.len(),
                    samples * 2
                ));
            }
            data.chunks_exact(2)
                .map(|c| i16::from_le_bytes([c[0], c[1]]) as i32)
                .collect()
        }
        2 => {
            let mut reader = claxon::FlacReader::new(std::io::Cursor::new(data))
                .map_err(|e| format!("corrupt FLAC blob: {e}"))?;
            let mut out = Vec::with_capacity(samples);
            for s in reader.samples() {
                out.push(s.map_err(|e| format!("corrupt FLAC blob: {e}"))?);
            }
            if out.len() != samples {
                return Err(format!(
                    "FLAC blob decodes to {} samples, Samples says {samples}",
                    out.len()
                ));
            }
            out
        }
        f => {
            return Err(format!(
                "unknown DataFormat {f} (known: 0 raw int16, 2 FLAC)"
            ))
        }
    };
    Ok(adc)
}

struct Reader {
    experiment: String,
    tradb: PathBuf,
    conn: Option<Connection>,
    time_base: f64,
    keys: VecDeque<(i64, i64, i64)>,
    info: PriInfo,
    /// Rejects to emit at the end: pridb hits whose TRAI the tradb does not hold.
    tail: VecDeque<Reject>,
}

impl Reader {
    fn fetch(&mut self, chan: i64, trai: i64, setid: i64) -> Item {
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
                record_id: format!("TRAI {trai}"),
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
        let n = n.unwrap_or(0).max(0) as usize;
        let adc = match decode_blob(fmt.unwrap_or(-1), data.as_deref().unwrap_or(&[]), n) {
            Ok(a) => a,
            Err(e) => return reject(e),
        };
        let scale = tr_mv * 1e-3;
        let time_s = time.map(|t| t as f64 / self.time_base);
        Item::Record(AeRecord {
            experiment: self.experiment.clone(),
            channel: chan.max(0) as u32,
            hit: trai as u64,
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
        if let Some((chan, trai, setid)) = self.keys.pop_front() {
            return Some(self.fetch(chan, trai, setid));
        }
        self.conn = None;
        self.tail.pop_front().map(Item::Reject)
    }
}

/// Open a Vallen source (its `.tradb`, and the `.pridb` when present).
pub fn open(src: &Source, cfg: &IngestConfig) -> Box<dyn Iterator<Item = Item> + Send> {
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
    let info = match &pridb {
        Some(p) => match read_pridb(p, cfg) {
            Ok(i) => i,
            Err(e) => {
                first.push(Item::Reject(file_reject(
                    p,
                    format!("hits and load ignored: {e}"),
                )));
                PriInfo::default()
            }
        },
        None => PriInfo::default(),
    };
    let pridb_name = pridb
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    let missing =
        |info: &PriInfo, have: &std::collections::HashSet<i64>, why: &str| -> VecDeque<Reject> {
            info.trai_chan
                .iter()
                .filter(|(t, _)| !have.contains(t))
                .map(|(t, c)| Reject {
                    experiment: experiment.clone(),
                    source_file: pridb_name.clone(),
                    record_id: format!("TRAI {t}"),
                    stage: Stage::Read,
                    reason: format!("hit on channel {c} has no waveform: {why}"),
                })
                .collect()
        };
    let Some(tradb) = tradb else {
        let tail = missing(&info, &Default::default(), "no .tradb beside the .pridb");
        return Box::new(first.into_iter().chain(tail.into_iter().map(Item::Reject)));
    };
    let opened = open_ro(&tradb).and_then(|conn| {
        let mut st = conn
            .prepare("SELECT Chan, TRAI, SetID FROM tr_data ORDER BY Chan, TRAI, SetID")
            .map_err(|e| file_err(&tradb, format!("not a Vallen .tradb: {e}")))?;
        let keys = st
            .query_map([], |r| {
                Ok((
                    r.get::<_, Option<i64>>(0)?.unwrap_or(0),
                    r.get::<_, Option<i64>>(1)?.unwrap_or(0),
                    r.get::<_, i64>(2)?,
                ))
            })
            .and_then(|it| it.collect::<Result<VecDeque<_>, _>>())
            .map_err(|e| file_err(&tradb, format!("cannot list records: {e}")))?;
        drop(st);
        Ok((conn, keys))
    });
    match opened {
        Ok((conn, keys)) => {
            let have: std::collections::HashSet<i64> = keys.iter().map(|k| k.1).collect();
            let tail = missing(&info, &have, "its TRAI is not in the .tradb");
            let tb = time_base(&conn, "tr_globalinfo");
            Box::new(first.into_iter().chain(Reader {
                experiment: experiment.clone(),
                tradb,
                conn: Some(conn),
                time_base: tb,
                keys,
                info,
                tail,
            }))
        }
        Err(e) => {
            first.push(Item::Reject(file_reject(&tradb, e.to_string())));
            let tail = missing(&info, &Default::default(), "the .tradb cannot be read");
            Box::new(first.into_iter().chain(tail.into_iter().map(Item::Reject)))
        }
    }
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
    let mut rows: Vec<Row> = parametric
        .iter()
        .map(|&(t, a, b)| Row::Par(t, a, b))
        .collect();
    rows.extend(hits.into_iter().map(Row::Hit));
    let t_of = |r: &Row| match r {
        Row::Par(t, ..) => *t,
        Row::Hit(h) => h.time_s,
    };
    rows.sort_by(|a, b| t_of(a).total_cmp(&t_of(b)));
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
    ptx.commit()?;
    ttx.commit()?;
    Ok((pri_path, tra_path))
}
