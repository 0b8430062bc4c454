//! The `.pridb` sets that are not hits: markers (`SetType` 4–6: label, date/time, section)
//! and status rows (3), numbered together in file order, and parametric rows (1), read in
//! chunks of 1 024 sets (bounded memory); and the count of every set type for the
//! manifest's accounting.

use super::{columns, open_ro};
use crate::ingest::settings::VallenConfig;
use crate::ingest::IngestError;
use crate::model::{
    db_ae, Item, MarkerKind, MarkerRow, ParametricRow, ParametricSource, RecordType,
};
use rusqlite::Connection;
use std::collections::BTreeMap;
use std::path::Path;

/// How many sets of each type a `.pridb` holds, as record types.
pub fn set_counts(conn: &Connection) -> BTreeMap<RecordType, u64> {
    let mut out = BTreeMap::new();
    let Ok(mut st) = conn.prepare("SELECT SetType, count(*) FROM ae_data GROUP BY SetType") else {
        return out;
    };
    let rows = st.query_map([], |r| {
        Ok((r.get::<_, Option<i64>>(0)?, r.get::<_, i64>(1)?))
    });
    if let Ok(rows) = rows {
        for (t, n) in rows.flatten() {
            let ty = match t {
                Some(1) => RecordType::Parametric,
                Some(2) => RecordType::Hit,
                Some(3) => RecordType::Status,
                Some(4..=6) => RecordType::Marker,
                _ => continue,
            };
            *out.entry(ty).or_default() += n.max(0) as u64;
        }
    }
    out
}

/// The sets to read, `after < SetID <= upto`, and the marker (with status) and parametric
/// rows before them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SetWindow {
    pub after: i64,
    pub upto: i64,
    pub marker_rows: u64,
    pub parametric_rows: u64,
}

impl Default for SetWindow {
    /// Every set of the file.
    fn default() -> Self {
        SetWindow {
            after: i64::MIN,
            upto: i64::MAX,
            marker_rows: 0,
            parametric_rows: 0,
        }
    }
}

/// Which kind of set a chunk reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    /// Markers and status rows, in file order.
    Markers,
    Parametric,
    Done,
}

/// The non-hit sets of a `.pridb`, as items.
pub struct SetRows {
    conn: Connection,
    experiment: String,
    path: String,
    time_base: f64,
    stage: Stage,
    last: i64,
    /// The window read: `after < SetID <= upto` (all of them offline).
    after: i64,
    upto: i64,
    markers_sql: String,
    parametric_sql: String,
    /// Names of the parametric inputs, in the order of `parametric_sql`'s columns.
    inputs: Vec<String>,
    cfg: VallenConfig,
    marker_rows: u64,
    parametric_rows: u64,
}

impl SetRows {
    /// The rows name `file` as their source (a salvaged file is read from its rebuilt copy).
    pub(super) fn named(mut self, file: &Path) -> SetRows {
        self.path = file.display().to_string();
        self
    }

    pub fn open(
        path: &Path,
        experiment: &str,
        time_base: f64,
        cfg: &VallenConfig,
    ) -> Result<SetRows, IngestError> {
        SetRows::window(path, experiment, time_base, cfg, &SetWindow::default())
    }

    /// The sets of one window of a growing file, their rows numbered on from the window's.
    pub fn window(
        path: &Path,
        experiment: &str,
        time_base: f64,
        cfg: &VallenConfig,
        w: &SetWindow,
    ) -> Result<SetRows, IngestError> {
        let conn = open_ro(path)?;
        let cols = columns(&conn, "ae_data");
        let has = |c: &str| cols.iter().any(|x| x == c);
        let raw = |c: &str| {
            if has(c) {
                format!("d.{c}")
            } else {
                "NULL".into()
            }
        };
        let params = columns(&conn, "ae_params");
        let inputs: Vec<String> = cols
            .iter()
            .filter(|c| c.starts_with("PA") && c[2..].parse::<u32>().is_ok())
            .cloned()
            .collect();
        let pa: Vec<String> = inputs
            .iter()
            .map(|c| {
                if params.iter().any(|p| p == &format!("{c}_mV")) {
                    format!("d.{c} * p.{c}_mV")
                } else {
                    format!("d.{c}")
                }
            })
            .collect();
        let parametric_sql = format!(
            "SELECT d.SetID, d.Time, {}, {}, {}{}{} FROM ae_data d \
             LEFT JOIN ae_params p ON p.ID = d.ParamID \
             WHERE d.SetType = 1 AND d.SetID > ?1 AND d.SetID <= ?2 ORDER BY d.SetID LIMIT 1024",
            raw("Status"),
            raw("PCTD"),
            raw("PCTA"),
            if pa.is_empty() { "" } else { ", " },
            pa.join(", ")
        );
        // Markers with their number and text, status rows with the file's own scaling
        // (view_ae_data, as for hits), in one pass so that `row` is the order in the file.
        let view = columns(&conn, "view_ae_data");
        let pick = |c: &str| {
            if view.iter().any(|v| v == c) {
                format!("v.{c}")
            } else {
                "NULL".to_string()
            }
        };
        let (mark_cols, mark_join) = if columns(&conn, "ae_markers").is_empty() {
            ("NULL, NULL", "")
        } else {
            (
                "m.Number, m.Data",
                "LEFT JOIN ae_markers m ON m.SetID = d.SetID",
            )
        };
        let view_join = if view.is_empty() {
            ""
        } else {
            "LEFT JOIN view_ae_data v ON v.SetID = d.SetID"
        };
        let markers_sql = format!(
            "SELECT d.SetID, d.SetType, d.Time, {mark_cols}, {}, {}, {}, {}, {}, {} FROM ae_data d \
             {mark_join} {view_join} \
             WHERE d.SetType IN (3, 4, 5, 6) AND d.SetID > ?1 AND d.SetID <= ?2 \
             ORDER BY d.SetID LIMIT 1024",
            raw("Chan"),
            raw("Status"),
            pick("Thr"),
            pick("Eny"),
            pick("SS"),
            pick("RMS"),
        );
        Ok(SetRows {
            conn,
            experiment: experiment.to_string(),
            path: path.display().to_string(),
            time_base,
            stage: Stage::Markers,
            last: w.after,
            after: w.after,
            upto: w.upto,
            markers_sql,
            parametric_sql,
            inputs,
            cfg: cfg.clone(),
            marker_rows: w.marker_rows,
            parametric_rows: w.parametric_rows,
        })
    }

    pub fn path(&self) -> &str {
        &self.path
    }

    /// The next chunk of items (empty when every set is read).
    pub(super) fn chunk(&mut self) -> Result<Vec<Item>, String> {
        loop {
            let out = match self.stage {
                Stage::Done => return Ok(vec![]),
                Stage::Markers => self.markers()?,
                Stage::Parametric => self.parametric()?,
            };
            if out.len() < 1024 {
                self.stage = match self.stage {
                    Stage::Markers => Stage::Parametric,
                    _ => Stage::Done,
                };
                self.last = self.after;
            }
            if !out.is_empty() {
                return Ok(out);
            }
        }
    }

    fn seconds(&self, ticks: Option<i64>) -> Option<f64> {
        ticks.map(|t| t as f64 * (1.0 / self.time_base))
    }

    fn markers(&mut self) -> Result<Vec<Item>, String> {
        let mut st = self
            .conn
            .prepare_cached(&self.markers_sql)
            .map_err(|e| e.to_string())?;
        #[allow(clippy::type_complexity)]
        let rows: Vec<(
            i64,
            i64,
            Option<i64>,
            Option<i64>,
            Option<String>,
            Option<i64>,
            Option<i64>,
            [Option<f64>; 4],
        )> = st
            .query_map([self.last, self.upto], |r| {
                Ok((
                    r.get(0)?,
                    r.get::<_, Option<i64>>(1)?.unwrap_or(0),
                    r.get(2)?,
                    r.get(3)?,
                    r.get(4)?,
                    r.get(5)?,
                    r.get(6)?,
                    [r.get(7)?, r.get(8)?, r.get(9)?, r.get(10)?],
                ))
            })
            .and_then(|it| it.collect())
            .map_err(|e| e.to_string())?;
        drop(st);
        let mut out = Vec::with_capacity(rows.len());
        for (setid, ty, time, number, data, chan, status, [thr, eny, ss, rms]) in rows {
            self.last = setid;
            self.marker_rows += 1;
            let row = if ty == 3 {
                MarkerRow {
                    experiment: self.experiment.clone(),
                    row: self.marker_rows,
                    time_s: self.seconds(time),
                    kind: MarkerKind::Status,
                    channel: chan.map(|c| c.max(0) as u32),
                    threshold_db: thr.filter(|v| *v > 0.0).map(|v| db_ae(v * 1e-6)),
                    energy_eu: eny,
                    rms_v: rms.map(|v| v * 1e-6),
                    signal_strength_vs: ss.map(|v| v * 1e-9),
                    flags: status,
                    source_file: self.path.clone(),
                    ..Default::default()
                }
            } else {
                MarkerRow {
                    experiment: self.experiment.clone(),
                    row: self.marker_rows,
                    time_s: self.seconds(time),
                    kind: match ty {
                        4 => MarkerKind::Label,
                        5 => MarkerKind::Datetime,
                        _ => MarkerKind::Section,
                    },
                    number,
                    text: data,
                    source_file: self.path.clone(),
                    ..Default::default()
                }
            };
            out.push(Item::Marker(Box::new(row)));
        }
        Ok(out)
    }

    fn parametric(&mut self) -> Result<Vec<Item>, String> {
        let n_in = self.inputs.len();
        let mut st = self
            .conn
            .prepare_cached(&self.parametric_sql)
            .map_err(|e| e.to_string())?;
        #[allow(clippy::type_complexity)]
        let rows: Vec<(i64, Option<i64>, [Option<i64>; 3], Vec<Option<f64>>)> = st
            .query_map([self.last, self.upto], |r| {
                let mut v = Vec::with_capacity(n_in);
                for k in 0..n_in {
                    v.push(r.get::<_, Option<f64>>(5 + k)?);
                }
                Ok((r.get(0)?, r.get(1)?, [r.get(2)?, r.get(3)?, r.get(4)?], v))
            })
            .and_then(|it| it.collect())
            .map_err(|e| e.to_string())?;
        drop(st);
        let mut out = Vec::with_capacity(rows.len());
        for (setid, time, [status, pctd, pcta], values) in rows {
            self.last = setid;
            self.parametric_rows += 1;
            let value = |name: &str| {
                self.inputs
                    .iter()
                    .position(|c| c == name)
                    .and_then(|k| values[k])
            };
            let c = &self.cfg;
            let inputs: serde_json::Map<String, serde_json::Value> = self
                .inputs
                .iter()
                .zip(&values)
                .filter_map(|(n, v)| v.map(|v| (n.clone(), serde_json::json!(v))))
                .collect();
            let mut extra = serde_json::Map::new();
            for (k, v) in [("Status", status), ("PCTD", pctd), ("PCTA", pcta)] {
                if let Some(v) = v {
                    extra.insert(k.into(), serde_json::json!(v));
                }
            }
            out.push(Item::Parametric(Box::new(ParametricRow {
                experiment: self.experiment.clone(),
                row: self.parametric_rows,
                time_s: self.seconds(time),
                load_n: c
                    .load_param
                    .and_then(|p| value(&p.column()))
                    .map(|v| v * c.load_n_per_mv),
                extension_m: c
                    .extension_param
                    .and_then(|p| value(&p.column()))
                    .map(|v| v * c.extension_m_per_mv),
                inputs: (!inputs.is_empty()).then(|| serde_json::Value::Object(inputs).to_string()),
                extra: (!extra.is_empty()).then(|| serde_json::Value::Object(extra).to_string()),
                source: ParametricSource::Vallen,
                source_file: self.path.clone(),
            })));
        }
        Ok(out)
    }
}
