//! The transients of a `.tradb` that SQLite refuses (issue 53), from the pages that are
//! whole ([`crate::ingest::salvage`]): each `tr_data` row keeps its SetID and TRAI, and is
//! taken only when its blob decodes to its `Samples`. Called only after SQLite failed on the
//! file: a sound file never reaches it.

use super::write::{AE_SCHEMA, TR_TABLES};
use crate::ingest::salvage::{salvage, Row, Salvage, Shape, Value};
use crate::ingest::{file_err, IngestError};
use std::collections::HashMap;
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
