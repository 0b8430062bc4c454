//! The `.pridb`: hit index, acquisitions, parametric series and the hit rows.

use super::{columns, open_ro, time_base};
use crate::ingest::settings::{IngestConfig, ParamInput};
use crate::ingest::{file_err, IngestError, TimeSeries};
use crate::model::{db_ae, HitRow, HitSource};
use rusqlite::Connection;
use std::collections::HashMap;
use std::path::Path;

/// What the `.pridb` tells about the hits: their acquisitions, the transient each one
/// links to, and the parametric series.
#[derive(Debug, Default)]
pub struct PriInfo {
    /// Hits (`SetType` 2) in the file.
    pub hits: u64,
    /// First `SetID` of each acquisition after the first (a `TRAI` that does not rise; see
    /// [`Acquisitions`]).
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

/// The acquisitions of a `.pridb`, told set by set in storage order (the offline reader's
/// one pass and a growing pair's scans share it).
///
/// A `TRAI` that does not rise starts a new acquisition: the recording was restarted into
/// the file, and `TRAI` and the clock start again. A section-start marker (`SetType` 6)
/// alone does not: a recording suspended and resumed writes one too, and its `TRAI` goes on
/// rising (VisualAE and vallenae keep its numbers). Only where the hits carry no `TRAI` is a
/// section marker followed by a clock that went back taken as a restart.
#[derive(Debug, Default)]
pub(super) struct Acquisitions {
    seen_hit: bool,
    marker_pending: bool,
    pub(super) max_trai: i64,
    /// The latest hit time of the current acquisition, ticks.
    latest: i64,
    /// First `SetID` of each acquisition after the first.
    pub(super) starts: Vec<i64>,
    /// Largest TRAI of each finished acquisition.
    pub(super) max_trai_done: Vec<i64>,
}

impl Acquisitions {
    /// The 1-based acquisition of the set.
    pub(super) fn add(&mut self, setid: i64, set_type: i64, time: i64, trai: i64) -> u32 {
        match set_type {
            6 => self.marker_pending = true,
            2 => {
                let restart = trai > 0 && trai <= self.max_trai;
                let clock_back = self.marker_pending && trai <= 0 && time < self.latest;
                if self.seen_hit && (restart || clock_back) {
                    self.starts.push(setid);
                    self.max_trai_done.push(self.max_trai);
                    self.max_trai = 0;
                    self.latest = i64::MIN;
                }
                self.marker_pending = false;
                self.seen_hit = true;
                self.latest = self.latest.max(time);
                if trai > 0 {
                    self.max_trai = self.max_trai.max(trai);
                }
            }
            _ => {}
        }
        self.starts.len() as u32 + 1
    }
}

fn parametric_series(
    conn: &Connection,
    cols: &[String],
    param: Option<ParamInput>,
    time_base: f64,
    scale: f64,
) -> TimeSeries {
    let Some(param) = param.map(ParamInput::column) else {
        return TimeSeries::default();
    };
    if !cols.contains(&param) {
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
            Ok((
                r.get::<_, f64>(0)? * (1.0 / time_base),
                r.get::<_, Option<f64>>(1)?,
            ))
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
    let mut acq = Acquisitions::default();
    for row in rows {
        let (setid, set_type, time, chan, trai) =
            row.map_err(|e| file_err(path, format!("cannot read hits: {e}")))?;
        let a = acq.add(setid, set_type, time, trai);
        if set_type == 2 {
            info.hits += 1;
            if trai > 0 {
                info.link.insert((trai, chan, time), a);
            }
        }
    }
    info.acq_starts = acq.starts;
    info.acq_max_trai = acq.max_trai_done;
    info.acq_max_trai.push(acq.max_trai);
    (info.load, info.extension) = load_series(&conn, &cols, tb, cfg);
    Ok(info)
}

/// The configured load and extension series of a `.pridb` (`cols`: its `ae_data` columns).
pub(super) fn load_series(
    conn: &Connection,
    cols: &[String],
    time_base: f64,
    cfg: &IngestConfig,
) -> (TimeSeries, TimeSeries) {
    let v = &cfg.vallen;
    (
        parametric_series(conn, cols, v.load_param, time_base, v.load_n_per_mv),
        parametric_series(
            conn,
            cols,
            v.extension_param,
            time_base,
            v.extension_m_per_mv,
        ),
    )
}

/// The hit rows of a `.pridb`, read in chunks of 1 024 sets (bounded memory).
pub(super) struct HitRows {
    conn: Connection,
    sql: String,
    pub(super) path: String,
    time_base: f64,
    last_setid: i64,
    /// The last set to read (a watcher reads a growing file in windows).
    upto: i64,
    number: u64,
    done: bool,
}

impl HitRows {
    pub(super) fn open(path: &Path, time_base: f64) -> Result<HitRows, IngestError> {
        HitRows::window(path, time_base, i64::MIN, i64::MAX, 0)
    }

    /// The hits with `after < SetID <= upto`, numbered on from `numbered`.
    pub(super) fn window(
        path: &Path,
        time_base: f64,
        after: i64,
        upto: i64,
        numbered: u64,
    ) -> Result<HitRows, IngestError> {
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
        // The hit flags (bit 8: started after a hit timeout) decide which hit may open an
        // event; a database without the column gives null.
        let status = if columns(&conn, "ae_data").iter().any(|c| c == "Status") {
            "d.Status"
        } else {
            "NULL"
        };
        let sql = if view.is_empty() {
            format!(
                "SELECT d.SetID, d.Time, d.Chan, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, d.TRAI, {status} \
                 FROM ae_data d WHERE d.SetType = 2 AND d.SetID > ?1 AND d.SetID <= ?2 ORDER BY d.SetID LIMIT 1024"
            )
        } else {
            format!(
                "SELECT d.SetID, d.Time, d.Chan, {}, {}, {}, {}, {}, {}, {}, {}, d.TRAI, {status} \
                 FROM ae_data d JOIN view_ae_data v ON v.SetID = d.SetID \
                 WHERE d.SetType = 2 AND d.SetID > ?1 AND d.SetID <= ?2 ORDER BY d.SetID LIMIT 1024",
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
            last_setid: after,
            upto,
            number: numbered,
            done: false,
        })
    }

    /// The next chunk: (SetID, time ticks, hit row without experiment-level links).
    pub(super) fn chunk(&mut self) -> Result<Vec<(i64, i64, HitRow)>, String> {
        if self.done {
            return Ok(vec![]);
        }
        let mut st = self
            .conn
            .prepare_cached(&self.sql)
            .map_err(|e| e.to_string())?;
        let db = |uv: Option<f64>| uv.filter(|v| *v > 0.0).map(|v| db_ae(v * 1e-6));
        let rows: Vec<_> = st
            .query_map([self.last_setid, self.upto], |r| {
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
                    r.get::<_, Option<i64>>(12)?,
                ))
            })
            .and_then(|it| it.collect::<Result<Vec<_>, _>>())
            .map_err(|e| e.to_string())?;
        if rows.len() < 1024 {
            self.done = true;
        }
        let mut out = Vec::with_capacity(rows.len());
        for (setid, time, chan, thr, amp, rise, dur, eny, ss, rms, counts, trai, status) in rows {
            self.last_setid = setid;
            self.number += 1;
            out.push((
                setid,
                time,
                HitRow {
                    channel: chan.max(0) as u32,
                    hit: self.number,
                    time_s: Some(time as f64 * (1.0 / self.time_base)),
                    amplitude_db: db(amp),
                    threshold_db: db(thr),
                    rise_time_s: rise.map(|v| v * 1e-6),
                    duration_s: dur.map(|v| v * 1e-6),
                    counts,
                    energy_eu: eny,
                    signal_strength_vs: ss.map(|v| v * 1e-9),
                    rms_v: rms.map(|v| v * 1e-6),
                    trai: trai.filter(|t| *t > 0),
                    status,
                    source: HitSource::Vallen,
                    source_file: self.path.clone(),
                    ..Default::default()
                },
            ));
        }
        Ok(out)
    }
}
