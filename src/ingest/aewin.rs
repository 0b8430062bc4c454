//! MISTRAS AEwin ASCII exports: a folder of `<EXP>_<ch>_<hit>_<time µs>.txt` waveform files
//! (one value per line, volts at the ADC including the preamplifier), a hit list `<EXP>.TXT`
//! beside it, and the tensile machine's log `Specimen_RawData_<n>.csv` (semicolon separated,
//! decimal comma, a units row under the header).
//!
//! Sample rate and pretrigger are not in the files; they come from `[ingest.aewin]`.

use super::{file_err, gain_factor, text, IngestError, Source, TimeSeries};
use crate::config::IngestConfig;
use crate::model::{AeRecord, Item, Reject, Stage};
use std::path::{Path, PathBuf};

/// `EXP2009_1_10_16557000.txt` → (experiment, channel, hit, time µs).
pub fn parse_wave_name(p: &Path) -> Option<(String, u32, u64, u64)> {
    let stem = p.file_stem()?.to_string_lossy().to_string();
    let parts: Vec<&str> = stem.rsplitn(4, '_').collect();
    if parts.len() != 4 || parts[3].is_empty() {
        return None;
    }
    let time_us = parts[0].parse::<u64>().ok()?;
    let hit = parts[1].parse::<u64>().ok()?;
    let ch = parts[2].parse::<u32>().ok()?;
    Some((parts[3].to_string(), ch, hit, time_us))
}

/// An AEwin hit list starts with a header row like ` ID  PARA1  RISE  COUN  DURATION AMP …`.
pub fn looks_like_hit_list(head: &str) -> bool {
    head.lines()
        .find(|l| !l.trim().is_empty())
        .is_some_and(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            w.first() == Some(&"ID")
                && w.iter()
                    .any(|x| *x == "AMP" || *x == "RISE" || *x == "DURATION")
        })
}

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

struct Reader {
    experiment: String,
    files: std::vec::IntoIter<(u32, u64, u64, PathBuf)>,
    rate: f64,
    pretrigger: u32,
    gain: f64,
    log: MachineLog,
    offset_s: f64,
}

impl Iterator for Reader {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        let (ch, hit, time_us, path) = self.files.next()?;
        Some(match text::read_values(&path) {
            Ok(values) => {
                let t = time_us as f64 * 1e-6;
                let tm = t - self.offset_s;
                Item::Record(AeRecord {
                    kind: crate::model::RecordKind::Hit,
                    experiment: self.experiment.clone(),
                    channel: ch,
                    hit,
                    time_s: Some(t),
                    sample_rate_hz: self.rate,
                    pretrigger: self.pretrigger,
                    samples: values.into_iter().map(|v| (v * self.gain) as f32).collect(),
                    load_n: self.log.load_n.at(tm),
                    extension_m: self.log.extension_m.at(tm),
                    label: None,
                    threshold_v: None,
                    source_file: path.display().to_string(),
                })
            }
            Err(e) => Item::Reject(Reject {
                record_type: crate::model::RecordType::Transient,
                experiment: self.experiment.clone(),
                source_file: path.display().to_string(),
                record_id: format!("ch{ch} hit {hit}"),
                stage: Stage::Read,
                reason: e.to_string(),
            }),
        })
    }
}

pub fn open(src: &Source, cfg: &IngestConfig) -> Box<dyn Iterator<Item = Item> + Send> {
    let mut first = Vec::new();
    let mut files: Vec<(u32, u64, u64, PathBuf)> = Vec::new();
    for (i, p) in src.files.iter().enumerate() {
        match parse_wave_name(p) {
            Some((_, ch, hit, t)) => files.push((ch, hit, t, p.clone())),
            // Forced AEwin on files without the naming scheme: number them in order.
            None => files.push((0, i as u64 + 1, 0, p.clone())),
        }
    }
    files.sort_by_key(|f| (f.0, f.1, f.2));
    let mut log = MachineLog::default();
    for c in &src.companions {
        if looks_like_machine_log(&super::head(c, 4096).unwrap_or_default()) {
            match MachineLog::read(c) {
                Ok(mut l) => {
                    // The log's rows, on the AE clock (AE time = log time + offset).
                    let off = cfg.aewin.log_time_offset_s;
                    let n = l.rows.len() as u64;
                    for (k, (t, load, ext, inputs)) in
                        std::mem::take(&mut l.rows).into_iter().enumerate()
                    {
                        first.push(Item::Parametric(Box::new(crate::model::ParametricRow {
                            experiment: src.id.clone(),
                            row: k as u64 + 1,
                            time_s: Some(t + off),
                            load_n: load,
                            extension_m: ext,
                            inputs: Some(inputs),
                            extra: None,
                            source: crate::model::ParametricSource::MachineLog,
                            source_file: c.display().to_string(),
                        })));
                    }
                    first.push(Item::Tally(crate::model::Tally {
                        experiment: src.id.clone(),
                        read: [(crate::model::RecordType::Parametric, n)].into(),
                    }));
                    log = l;
                }
                Err(e) => first.push(Item::Reject(Reject {
                    record_type: crate::model::RecordType::File,
                    experiment: src.id.clone(),
                    source_file: c.display().to_string(),
                    record_id: String::new(),
                    stage: Stage::Read,
                    reason: format!("load and extension ignored: {e}"),
                })),
            }
        }
    }
    Box::new(first.into_iter().chain(Reader {
        experiment: src.id.clone(),
        files: files.into_iter(),
        rate: cfg.aewin.sample_rate_hz,
        pretrigger: cfg.aewin.pretrigger_samples,
        gain: gain_factor(cfg.aewin.preamp_gain_db),
        log,
        offset_s: cfg.aewin.log_time_offset_s,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wave_names_parse() {
        assert_eq!(
            parse_wave_name(Path::new("x/EXP2009_1_10_16557000.txt")),
            Some(("EXP2009".into(), 1, 10, 16557000))
        );
        assert_eq!(
            parse_wave_name(Path::new("x/my_exp_2_3_44.txt")),
            Some(("my_exp".into(), 2, 3, 44))
        );
        assert_eq!(parse_wave_name(Path::new("x/hit_3.txt")), None);
    }

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
