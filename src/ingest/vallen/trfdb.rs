//! The VisualAE feature file beside a `.pridb` (`X.trfdb`): each transient's features by
//! TRAI, joined to the hits as `vendor_features`.

use super::{columns, open_ro};
use crate::ingest::{file_err, IngestError};
use std::collections::HashMap;
use std::path::Path;

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
    // Units are optional (a file without trf_fieldinfo names its features bare), but a
    // table that fails part-way is a damaged file: an error, so salvage can take over,
    // never a silently shorter read.
    let units: HashMap<String, String> = match conn.prepare("SELECT * FROM trf_fieldinfo") {
        Err(_) => HashMap::new(),
        Ok(mut st) => st
            .query_map([], |r| {
                Ok((r.get::<_, String>(0)?, r.get::<_, Option<String>>(2)?))
            })
            .and_then(|it| it.collect::<Result<Vec<_>, _>>())
            .map_err(|e| file_err(path, format!("cannot read trf_fieldinfo: {e}")))?
            .into_iter()
            .filter_map(|(n, u)| u.map(|u| (n, u.trim_matches(['[', ']']).to_string())))
            .collect(),
    };
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
    rows.collect::<Result<_, _>>()
        .map_err(|e| file_err(path, format!("cannot read trf_data: {e}")))
}
