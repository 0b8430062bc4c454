//! The tensile machine's log beside an AEwin experiment: `Specimen_RawData_<n>.csv`
//! (semicolon separated, decimal comma, a units row under the header).

use crate::ingest::{file_err, IngestError, TimeSeries};
use std::path::Path;

/// A tensile-machine log has a `Time;…;Load` header (semicolon separated).
pub fn looks_like_machine_log(head: &str) -> bool {
    head.lines().any(|l| {
        let cells: Vec<String> = l.split(';').map(|c| c.trim().to_lowercase()).collect();
        cells.len() >= 2 && cells[0] == "time" && cells.iter().any(|c| c == "load")
    })
}

fn parse_decimal(s: &str) -> Option<f64> {
    s.trim().replace(',', ".").parse::<f64>().ok()
}

/// The test machine's log: load (N) and extension (m) against time (s).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MachineLog {
    pub load_n: TimeSeries,
    pub extension_m: TimeSeries,
    /// The log's rows on its own clock: (time s, load N, extension m, the numeric cells
    /// under their header names as JSON).
    pub rows: Vec<(f64, Option<f64>, Option<f64>, String)>,
}

impl MachineLog {
    /// Read a `Specimen_RawData_*.csv` log. Units are taken from the row under the header:
    /// load in N or kN, extension in mm or m, time in s (`sec`) or ms.
    pub fn read(path: &Path) -> Result<MachineLog, IngestError> {
        let text = std::fs::read(path).map_err(|e| file_err(path, format!("cannot read: {e}")))?;
        let text = String::from_utf8_lossy(&text);
        let mut lines = text.lines();
        let header: Vec<String> = loop {
            let Some(l) = lines.next() else {
                return Err(file_err(
                    path,
                    "no `Time;…;Load` header row: not a machine log",
                ));
            };
            let cells: Vec<String> = l.split(';').map(|c| c.trim().to_lowercase()).collect();
            if cells.len() >= 2 && cells[0] == "time" && cells.iter().any(|c| c == "load") {
                break cells;
            }
        };
        let col = |name: &str| header.iter().position(|c| c == name);
        let (ti, li, ei) = (col("time").unwrap_or(0), col("load"), col("extension"));
        let mut factors = (1.0, 1.0, 1e-3);
        let mut rows = Vec::new();
        let mut raw: Vec<String> = Vec::new();
        for l in lines {
            let cells: Vec<&str> = l.split(';').collect();
            if cells.len() < header.len() {
                continue;
            }
            if cells[ti].trim().starts_with('(') {
                let unit = |i: Option<usize>| {
                    i.map(|i| cells[i].trim().to_lowercase())
                        .unwrap_or_default()
                };
                factors.0 = if unit(Some(ti)).contains("ms") {
                    1e-3
                } else {
                    1.0
                };
                factors.1 = if unit(li).contains("kn") { 1e3 } else { 1.0 };
                factors.2 = match unit(ei).as_str() {
                    "(m)" => 1.0,
                    "(µm)" | "(um)" => 1e-6,
                    _ => 1e-3,
                };
                continue;
            }
            if let Some(t) = parse_decimal(cells[ti]) {
                let load = li.and_then(|i| parse_decimal(cells[i]));
                let ext = ei.and_then(|i| parse_decimal(cells[i]));
                rows.push((t, load, ext));
                let inputs: serde_json::Map<String, serde_json::Value> = header
                    .iter()
                    .zip(&cells)
                    .filter_map(|(h, c)| {
                        parse_decimal(c).map(|v| (h.clone(), serde_json::json!(v)))
                    })
                    .collect();
                raw.push(serde_json::Value::Object(inputs).to_string());
            }
        }
        if rows.is_empty() {
            return Err(file_err(path, "machine log has a header but no data rows"));
        }
        let (ft, fl, fe) = factors;
        Ok(MachineLog {
            load_n: TimeSeries::from_pairs(
                rows.iter()
                    .filter_map(|r| r.1.map(|v| (r.0 * ft, v * fl)))
                    .collect(),
            ),
            extension_m: TimeSeries::from_pairs(
                rows.iter()
                    .filter_map(|r| r.2.map(|v| (r.0 * ft, v * fe)))
                    .collect(),
            ),
            rows: rows
                .iter()
                .zip(raw)
                .map(|(r, j)| (r.0 * ft, r.1.map(|v| v * fl), r.2.map(|v| v * fe), j))
                .collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn machine_log_units_and_decimal_commas() {
        let dir = std::env::temp_dir().join(format!("aepipe-log-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("Specimen_RawData_1.csv");
        std::fs::write(
            &p,
            "Maximum Load;4,46;kN\n\nTime;Extension;Load\n(sec);(mm);(kN)\n0,0;0,00;0,5\n1,0;0,10;1,5\n",
        )
        .unwrap();
        let log = MachineLog::read(&p).unwrap();
        assert_eq!(log.load_n.at(0.5), Some(1000.0));
        assert!((log.extension_m.at(1.0).unwrap() - 1e-4).abs() < 1e-12);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
