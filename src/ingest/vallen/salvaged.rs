//! The transients of a `.tradb` that SQLite refuses (issue 53), from the pages that are
//! whole ([`crate::ingest::salvage`]): each `tr_data` row keeps its SetID and TRAI, and is
//! taken only when its blob decodes to its `Samples`. Called only after SQLite failed on the
//! file: a sound file never reaches it.

use super::write::{AE_SCHEMA, TR_TABLES};
use crate::ingest::salvage::{salvage, Row, Salvage, Shape, Value};
use crate::ingest::settings::IngestConfig;
use crate::ingest::{file_err, IngestError};
use crate::model::{Item, Note};
use std::collections::{HashMap, HashSet};
use std::path::Path;

/// One `tr_data` row as salvaged, with the columns the reader uses.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct TrRow {
    pub time: Option<i64>,
    pub trai: Option<i64>,
    pub chan: Option<i64>,
    pub param: Option<i64>,
    pub pretrigger: Option<i64>,
    pub thr: Option<i64>,
    pub sample_rate: Option<f64>,
    pub samples: Option<i64>,
    pub format: Option<i64>,
    pub data: Option<Vec<u8>>,
}

/// What salvage gave of a `.tradb`.
#[derive(Debug, Clone, Default)]
pub(super) struct SalvagedTr {
    /// By SetID.
    pub rows: HashMap<i64, TrRow>,
    /// ParamID → (TR_mV, ADC_µV).
    pub params: HashMap<i64, (Option<f64>, Option<f64>)>,
    pub time_base: f64,
    /// Whole pages, and the pages the header says the file had (0: unknown).
    pub pages: u64,
    pub declared_pages: u64,
    /// Rows whose record was whole but whose blob did not decode to its `Samples`.
    pub undecodable: u64,
    /// Cells whose record was not whole.
    pub partial: u64,
    /// What was found, table by table ([`Salvage::describe_tables`]).
    pub tables: String,
}

/// The shapes of the `.tradb` tables (the writer's own declarations).
pub(super) fn tradb_shapes() -> Vec<Shape> {
    TR_TABLES.split(';').filter_map(Shape::from_sql).collect()
}

fn column(s: &Salvage, table: &str, row: &Row, name: &str) -> Option<Value> {
    s.column(table, name)
        .and_then(|i| row.values.get(i))
        .cloned()
}

/// `28 of 42 pages` (the header's count known), else `28 whole page(s)`.
fn pages_of(whole: u64, declared: u64) -> String {
    match declared {
        0 => format!("{whole} whole page(s)"),
        d => format!("{} of {d} pages", whole.min(d)),
    }
}

/// Salvage a damaged `.tradb`; an error when not one transient is whole.
pub(super) fn salvage_tradb(path: &Path) -> Result<SalvagedTr, IngestError> {
    let bytes = std::fs::read(path).map_err(|e| file_err(path, format!("cannot read: {e}")))?;
    let s = salvage(&bytes, &tradb_shapes())
        .map_err(|e| file_err(path, format!("nothing salvaged: {e}")))?;
    let int = |r: &Row, c: &str| column(&s, "tr_data", r, c).and_then(|v| v.int());
    let mut out = SalvagedTr {
        pages: s.pages,
        declared_pages: s.declared_pages,
        partial: s.partial_records,
        tables: s.describe_tables(),
        time_base: 1e7,
        ..Default::default()
    };
    for r in s.rows("tr_params") {
        let real = |c: &str| column(&s, "tr_params", r, c).and_then(|v| v.real());
        out.params.insert(r.rowid, (real("TR_mV"), real("ADC_µV")));
    }
    for r in s.rows("tr_globalinfo") {
        let k = column(&s, "tr_globalinfo", r, "Key");
        if k == Some(Value::Text("TimeBase".into())) {
            let v = match column(&s, "tr_globalinfo", r, "Value") {
                Some(Value::Text(t)) => t.trim().parse().ok(),
                Some(v) => v.real(),
                None => None,
            };
            if let Some(v) = v.filter(|v: &f64| *v > 0.0) {
                out.time_base = v;
            }
        }
    }
    for r in s.rows("tr_data") {
        let data = match column(&s, "tr_data", r, "Data") {
            Some(Value::Blob(b)) => Some(b),
            _ => None,
        };
        let row = TrRow {
            time: int(r, "Time"),
            trai: int(r, "TRAI"),
            chan: int(r, "Chan"),
            param: int(r, "ParamID"),
            pretrigger: int(r, "Pretrigger"),
            thr: int(r, "Thr"),
            sample_rate: column(&s, "tr_data", r, "SampleRate").and_then(|v| v.real()),
            samples: int(r, "Samples"),
            format: int(r, "DataFormat"),
            data,
        };
        // A blob is whole when it decodes to the samples its row claims.
        let n = row.samples.unwrap_or(-1);
        let decodes = usize::try_from(n).is_ok_and(|n| {
            super::decode_blob(
                row.format.unwrap_or(-1),
                row.data.as_deref().unwrap_or(&[]),
                n,
            )
            .is_ok()
        });
        if decodes {
            out.rows.insert(r.rowid, row);
        } else {
            out.undecodable += 1;
        }
    }
    if out.rows.is_empty() {
        return Err(file_err(
            path,
            format!(
                "no transient is whole in its {} page(s) ({} partial record(s))",
                s.pages, s.partial_records
            ),
        ));
    }
    Ok(out)
}

/// What a damaged `.pridb` gave back, rebuilt into a fresh file its reader opens.
#[derive(Debug, Clone)]
pub(super) struct RebuiltPri {
    pub path: std::path::PathBuf,
    /// Hits (`ae_data` rows of SetType 2) and all `ae_data` rows salvaged.
    pub hits: u64,
    pub sets: u64,
    pub pages: u64,
    pub declared_pages: u64,
    pub tables: String,
    pub partial: u64,
}

/// Salvage a `.pridb` SQLite refuses and rebuild its rows (with its own schema, else the
/// writer's) into `to`, which the ordinary reader then reads.
pub(super) fn rebuild_pridb(path: &Path, to: &Path) -> Result<RebuiltPri, IngestError> {
    let bytes = std::fs::read(path).map_err(|e| file_err(path, format!("cannot read: {e}")))?;
    let shapes: Vec<Shape> = AE_SCHEMA.split(';').filter_map(Shape::from_sql).collect();
    let s =
        salvage(&bytes, &shapes).map_err(|e| file_err(path, format!("nothing salvaged: {e}")))?;
    let set_type = s.column("ae_data", "SetType");
    let sets = s.rows("ae_data").count() as u64;
    let hits = s
        .rows("ae_data")
        .filter(|r| set_type.and_then(|i| r.values.get(i)) == Some(&Value::Int(2)))
        .count() as u64;
    if sets == 0 {
        return Err(file_err(
            path,
            format!("no set is whole in its {} page(s)", s.pages),
        ));
    }
    let fallback: Vec<&str> = AE_SCHEMA
        .split(';')
        .filter(|x| !x.trim().is_empty())
        .collect();
    super::super::salvage::rebuild(&s, &fallback, to)
        .map_err(|e| file_err(to, format!("cannot write the salvaged rows: {e}")))?;
    Ok(RebuiltPri {
        path: to.to_path_buf(),
        hits,
        sets,
        pages: s.pages,
        declared_pages: s.declared_pages,
        tables: s.describe_tables(),
        partial: s.partial_records,
    })
}

/// The `.tradb`'s transients from its whole pages after SQLite failed with `e` (`None`:
/// nothing whole), said in `first`; each hit whose transient is lost a reject naming the
/// file and the cause.
#[allow(clippy::too_many_arguments)]
pub(super) fn transients(
    tradb: &Path,
    e: &IngestError,
    decode: bool,
    info: &super::PriInfo,
    offsets: &super::TraiOffsets,
    experiment: &str,
    pridb_name: &str,
    first: &mut Vec<Item>,
) -> Option<super::Transients> {
    let sv = salvage_tradb(tradb).ok()?;
    let mut raw: Vec<(i64, i64, i64, i64)> = sv
        .rows
        .iter()
        .map(|(id, r)| {
            (
                *id,
                r.time.unwrap_or(0),
                r.chan.unwrap_or(0),
                r.trai.unwrap_or(0),
            )
        })
        .collect();
    raw.sort_unstable();
    let have: HashSet<(i64, i64, i64)> = raw.iter().map(|k| (k.3, k.2, k.1)).collect();
    let name = tradb
        .file_name()
        .map_or(String::new(), |n| n.to_string_lossy().to_string());
    let of = info.link.len().max(raw.len());
    let pages = pages_of(sv.pages, sv.declared_pages);
    let cause = sqlite_cause(&e.to_string());
    let file = tradb.display().to_string();
    let note = |message: String, said: bool| Note::item(experiment, &file, message, said);
    first.push(note(
        format!(
            "{experiment}: salvaged {} of ≥ {of} transients from a damaged {name} ({pages}; SQLite: {cause})",
            raw.len()
        ),
        true,
    ));
    first.push(note(
        format!(
            "salvage of {name}: tables found: {}; {} record(s) of its table-leaf pages not whole (a cell, an overflow page or a value lost), {} blob(s) that do not decode to their Samples: not taken",
            sv.tables, sv.partial, sv.undecodable
        ),
        false,
    ));
    let why =
        format!("the damaged {name} lost it (SQLite: {cause}; its whole pages do not hold it)");
    let mut keys = super::transient_keys(&raw, info, offsets);
    if !decode {
        keys.clear();
    }
    Some(super::Transients {
        tail: super::missing_rejects(experiment, pridb_name, &info.link, &have, &why),
        in_tradb: raw.len() as u64,
        time_base: sv.time_base,
        conn: None,
        keys: keys.into(),
        have,
        tradb: tradb.to_path_buf(),
        salvaged: Some(sv),
    })
}

/// A copy of a `.pridb` SQLite refuses, rebuilt from its whole pages (`None`: the file is
/// sound, or nothing in it is whole — then the ordinary reader says why). What was salvaged
/// is said in `first`.
pub(super) fn salvage_pridb(
    p: &Path,
    cfg: &IngestConfig,
    experiment: &str,
    first: &mut Vec<Item>,
) -> Option<RebuiltPri> {
    let why = match super::read_pridb(p, cfg) {
        Ok(_) => return None,
        Err(e) => e.to_string(),
    };
    let to = temp_copy("pridb");
    let name = p
        .file_name()
        .map_or(String::new(), |n| n.to_string_lossy().to_string());
    let file = p.display().to_string();
    let note = |message: String, said: bool| Note::item(experiment, &file, message, said);
    let r = match rebuild_pridb(p, &to) {
        Ok(r) => r,
        Err(e) => {
            first.push(note(
                format!(
                    "{experiment}: nothing salvaged from a damaged {name} (SQLite: {}; {})",
                    sqlite_cause(&why),
                    sqlite_cause(&e.to_string())
                ),
                true,
            ));
            return None;
        }
    };
    let pages = pages_of(r.pages, r.declared_pages);
    first.push(note(
        format!(
            "{experiment}: salvaged {} hits ({} sets) from a damaged {name} ({pages}; SQLite: {})",
            r.hits,
            r.sets,
            sqlite_cause(&why)
        ),
        true,
    ));
    first.push(note(
        format!(
            "salvage of {name}: tables found: {}; {} record(s) of its table-leaf pages not whole: not taken",
            r.tables, r.partial
        ),
        false,
    ));
    Some(r)
}

/// A fresh temporary path for a rebuilt copy (`aepipe-salvage-<pid>-<n>.<ext>`).
fn temp_copy(ext: &str) -> std::path::PathBuf {
    static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    std::env::temp_dir().join(format!(
        "aepipe-salvage-{}-{}.{ext}",
        std::process::id(),
        N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ))
}

/// The features of a `.trfdb` SQLite refuses, from its whole pages: the rows are rebuilt
/// into a temporary file under the file's own schema and read there by
/// [`super::read_trfdb`], so a salvaged row is read exactly as a sound one. The schema page
/// must be whole: `trf_data`'s columns are the features the writer chose, and no known shape
/// names them otherwise. `hits` is the `.pridb`'s hit count (the "of"); what was salvaged is
/// said in `first`.
pub(super) fn salvage_trfdb(
    path: &Path,
    sqlite: &IngestError,
    hits: u64,
    experiment: &str,
    first: &mut Vec<Item>,
) -> Result<HashMap<i64, String>, IngestError> {
    let bytes = std::fs::read(path).map_err(|e| file_err(path, format!("cannot read: {e}")))?;
    let s = salvage(&bytes, &[]).map_err(|e| file_err(path, format!("nothing salvaged: {e}")))?;
    if !s.schema_whole || !s.tables.contains_key("trf_data") {
        return Err(file_err(
            path,
            format!(
                "nothing salvaged: its schema page is lost, so trf_data's feature columns cannot be named ({} whole page(s))",
                s.pages
            ),
        ));
    }
    let to = temp_copy("trfdb");
    let rebuilt = super::super::salvage::rebuild(&s, &[], &to)
        .map_err(|e| file_err(&to, format!("cannot write the salvaged rows: {e}")))
        .and_then(|_| super::read_trfdb(&to));
    let _ = std::fs::remove_file(&to);
    let features = rebuilt?;
    let name = path
        .file_name()
        .map_or(String::new(), |n| n.to_string_lossy().to_string());
    let of = hits.max(features.len() as u64);
    let file = path.display().to_string();
    let note = |message: String, said: bool| Note::item(experiment, &file, message, said);
    first.push(note(
        format!(
            "{experiment}: salvaged the features of {} of ≥ {of} transients from a damaged {name} ({}; SQLite: {}); a hit without its row stands without vendor_features",
            features.len(),
            pages_of(s.pages, s.declared_pages),
            sqlite_cause(&sqlite.to_string())
        ),
        true,
    ));
    first.push(note(
        format!(
            "salvage of {name}: tables found: {}; {} record(s) of its table-leaf pages not whole: not taken",
            s.describe_tables(),
            s.partial_records
        ),
        false,
    ));
    Ok(features)
}

/// SQLite's own words from an error that carries the file's name before them.
pub(super) fn sqlite_cause(e: &str) -> String {
    let tail = e.rsplit(": ").next().unwrap_or(e);
    tail.to_string()
}
