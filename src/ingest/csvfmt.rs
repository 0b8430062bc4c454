//! CSV waveforms.
//!
//! * One hit per file: a value column (`voltage_v`, `voltage`, `value`, `amplitude`,
//!   `signal`, `v`, …) and optionally a time column (`time_s`, `time`, `t`) from which the
//!   rate (and, for negative times, the pretrigger) is taken; or a single unnamed column.
//! * A long table: a hit column (`hit`, `hit_id`, `event`, `trai`) plus a value column,
//!   optionally `channel`/`chan` and a time column; the rows of one hit are contiguous.
//!
//! Delimiter `,`, `;` or tab, detected from the header.

use super::sniff::{Head, Kind, Recogniser, Strength, Verdict};
use super::{gain_factor, Source};
use crate::ingest::settings::{FormatChoice, IngestConfig, ReadSettings};
use crate::model::{AeRecord, Item, Reject, Stage};
use std::path::Path;

const VALUE: &[&str] = &[
    "voltage_v",
    "voltage",
    "volts",
    "v",
    "value",
    "amplitude",
    "amplitude_v",
    "signal",
    "sample",
    "samples_v",
    "u_v",
    "u",
];
/// Time columns: `time` or `t`, optionally with a unit (`time_us`, `time [ms]`, `t/ns`, …).
const TIME: &[&str] = &["time", "t"];
const HIT: &[&str] = &["hit", "hit_id", "hit_no", "event", "trai", "record"];
const CHAN: &[&str] = &["channel", "chan", "ch"];

pub enum Sniff {
    PerHit,
    Long,
    NotWaveform,
}

fn delimiter(line: &str) -> u8 {
    let count = |c| line.matches(c).count();
    if count('\t') > count(',') && count('\t') >= count(';') {
        b'\t'
    } else if count(';') > count(',') {
        b';'
    } else {
        b','
    }
}

#[derive(Debug, Clone)]
struct Layout {
    delim: u8,
    has_header: bool,
    value: usize,
    time: Option<usize>,
    /// Seconds per unit of the time column, when its header names the unit.
    time_unit: Option<f64>,
    hit: Option<usize>,
    chan: Option<usize>,
}

/// Split a header like `time_us`, `time (µs)`, `t [ms]`, `time/s` into its name and the
/// seconds per unit it names.
fn name_and_unit(h: &str) -> (String, Option<f64>) {
    let cut = h.find(['_', '(', '[', '/', ' ']).unwrap_or(h.len());
    let (name, rest) = h.split_at(cut);
    let unit = rest.trim_matches(|c: char| matches!(c, '_' | '(' | ')' | '[' | ']' | '/' | ' '));
    let scale = match unit {
        "s" | "sec" => Some(1.0),
        "ms" => Some(1e-3),
        "us" | "µs" | "μs" => Some(1e-6),
        "ns" => Some(1e-9),
        _ => None,
    };
    (name.to_string(), scale)
}

/// The time column: its index and the seconds per unit its header names.
fn time_column(header: &[String]) -> Option<(usize, Option<f64>)> {
    header.iter().enumerate().find_map(|(i, h)| {
        let (name, unit) = name_and_unit(h);
        (TIME.contains(&name.as_str()) && (unit.is_some() || name == *h)).then_some((i, unit))
    })
}

fn find(header: &[String], names: &[&str]) -> Option<usize> {
    names
        .iter()
        .find_map(|n| header.iter().position(|h| h == n))
}

fn layout(head: &str) -> Result<Layout, String> {
    let first = head
        .lines()
        .next()
        .unwrap_or("")
        .trim_start_matches('\u{feff}');
    let delim = delimiter(first);
    let header: Vec<String> = first
        .split(delim as char)
        .map(|c| c.trim().trim_matches('"').to_lowercase())
        .collect();
    if header.iter().all(|c| c.parse::<f64>().is_ok()) {
        return if header.len() == 1 {
            Ok(Layout {
                delim,
                has_header: false,
                value: 0,
                time: None,
                time_unit: None,
                hit: None,
                chan: None,
            })
        } else {
            Err(format!(
                "{} unnamed numeric columns: name the value column (e.g. voltage_v)",
                header.len()
            ))
        };
    }
    let value = find(&header, VALUE).or(if header.len() == 1 { Some(0) } else { None });
    let Some(value) = value else {
        return Err(format!(
            "no waveform column among [{}] (expected one of {})",
            header.join(", "),
            VALUE.join(", ")
        ));
    };
    let time = time_column(&header);
    Ok(Layout {
        delim,
        has_header: true,
        value,
        time: time.map(|t| t.0),
        time_unit: time.and_then(|t| t.1),
        hit: find(&header, HIT),
        chan: find(&header, CHAN),
    })
}

pub fn sniff(head: &str) -> Sniff {
    match layout(head) {
        Ok(l) if l.hit.is_some() => Sniff::Long,
        Ok(_) => Sniff::PerHit,
        Err(_) => Sniff::NotWaveform,
    }
}

/// A CSV waveform: a value column (and a hit column for a long table). A `.csv`/`.tsv`
/// file is claimed on its header alone (its reader rejects a value that is not a number,
/// naming the line); a file of another extension only when the head's value cells are all
/// numbers, so a text file of prose is never taken for a one-column CSV.
fn recognise(h: &Head) -> Verdict {
    let by_ext = matches!(h.ext.as_str(), "csv" | "tsv");
    match layout(&h.text) {
        Ok(l) => {
            if !by_ext && !values_are_numbers(h, &l) {
                return Verdict::No;
            }
            let kind = if l.hit.is_some() {
                Kind::CsvLong
            } else {
                Kind::CsvPerHit
            };
            Verdict::mine(kind, Strength::Shape, u8::from(by_ext))
        }
        Err(why) => {
            let tabular = h
                .filled_lines()
                .take(2)
                .all(|l| l.split(layout_delim(&h.text) as char).count() >= 2);
            if by_ext || tabular {
                Verdict::Near(format!("CSV is not a waveform: {why}"))
            } else {
                Verdict::No
            }
        }
    }
}

fn layout_delim(head: &str) -> u8 {
    delimiter(head.lines().next().unwrap_or(""))
}

/// The head's rows (after the header) hold a number in the value column, and there is one.
fn values_are_numbers(h: &Head, l: &Layout) -> bool {
    let rows: Vec<&str> = h
        .filled_lines()
        .skip(usize::from(l.has_header))
        .take(20)
        .collect();
    !rows.is_empty()
        && rows.iter().all(|r| {
            r.split(l.delim as char)
                .nth(l.value)
                .is_some_and(|c| c.trim().trim_matches('"').parse::<f64>().is_ok())
        })
}

/// CSV waveforms: one hit per file or a long table with a hit column.
pub(crate) const RECOGNISER: Recogniser = Recogniser {
    what: "CSV with a value column (voltage_v, value, …), one hit per file or a long table with a hit column",
    format: FormatChoice::Csv,
    recognise,
    forced: |h| match sniff(&h.text) {
        Sniff::Long => Some(Kind::CsvLong),
        Sniff::PerHit => Some(Kind::CsvPerHit),
        Sniff::NotWaveform => None,
    },
};

fn reader(path: &Path) -> Result<(Layout, csv::Reader<std::fs::File>), String> {
    let head = super::head(path, 4096).map_err(|e| format!("cannot read: {e}"))?;
    let l = layout(&head)?;
    let r = csv::ReaderBuilder::new()
        .delimiter(l.delim)
        .has_headers(l.has_header)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| format!("cannot read: {e}"))?;
    Ok((l, r))
}

/// Seconds per unit of a time column whose header names no unit: the first of s, µs, ms, ns
/// that puts the sampling rate between 100 kHz and 1 GHz (AE rates); seconds otherwise.
/// (A bare `time` column stepping by 0.1 is 0.1 µs at 10 MHz, not 0.1 s at 10 Hz.)
pub(crate) fn infer_time_unit(step: f64) -> f64 {
    [1.0, 1e-6, 1e-3, 1e-9]
        .into_iter()
        .find(|u| {
            let rate = 1.0 / (step * u);
            (1e5..=1e9).contains(&rate)
        })
        .unwrap_or(1.0)
}

/// Rate and pretrigger from sample times (in the column's unit, `unit` seconds each, or
/// inferred from the spacing): rate from the mean step, pretrigger = samples before t = 0.
fn timing(times: &[f64], unit: Option<f64>, default_rate: f64, default_pre: u32) -> (f64, u32) {
    if times.len() < 2 {
        return (default_rate, default_pre);
    }
    let span = times[times.len() - 1] - times[0];
    if span.is_nan() || span <= 0.0 {
        return (default_rate, default_pre);
    }
    let step = span / (times.len() - 1) as f64;
    let unit = unit.unwrap_or_else(|| infer_time_unit(step));
    let rate = 1.0 / (step * unit);
    let pre = if times[0] < 0.0 {
        times.iter().take_while(|t| **t < 0.0).count() as u32
    } else {
        default_pre
    };
    (rate, pre)
}

/// A number, with a decimal comma accepted (`0,0125` in a `;`- or tab-separated file).
fn cell(rec: &csv::StringRecord, i: usize, line: u64, what: &str) -> Result<f64, String> {
    let s = rec
        .get(i)
        .ok_or_else(|| format!("line {line}: missing {what} column"))?;
    s.parse::<f64>()
        .or_else(|e| {
            if s.contains(',') && !s.contains('.') {
                s.replacen(',', ".", 1).parse::<f64>()
            } else {
                Err(e)
            }
        })
        .map_err(|_| format!("line {line}: {what} '{s}' is not a number"))
}

fn read_per_hit(path: &Path, cfg: &IngestConfig) -> Result<(Vec<f32>, f64, u32), String> {
    let (l, mut r) = reader(path)?;
    let gain = gain_factor(cfg.gain_db);
    let mut v = Vec::new();
    let mut t = Vec::new();
    for rec in r.records() {
        let rec = rec.map_err(|e| format!("{e}"))?;
        let line = rec.position().map(|p| p.line()).unwrap_or(0);
        v.push((cell(&rec, l.value, line, "value")? * gain) as f32);
        if let Some(ti) = l.time {
            t.push(cell(&rec, ti, line, "time")?);
        }
    }
    let (rate, pre) = timing(&t, l.time_unit, cfg.sample_rate_hz, cfg.pretrigger_samples);
    Ok((v, rate, pre))
}

/// CSV, one hit per file, numbered by their place in the folder.
pub(crate) const PER_HIT_FORMAT: crate::ingest::FormatSpec = crate::ingest::FormatSpec {
    name: "csv (one hit per file)",
    one_hit_per_file: true,
    numbered_by_place: true,
    follow: crate::ingest::Follow::PerFile,
    open: open_per_hit,
};

pub fn open_per_hit(src: &Source, cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
    let experiment = src.id.clone();
    let cfg = cfg.clone();
    let files = src.files.clone();
    let first_hit = src.first_hit;
    Box::new(files.into_iter().enumerate().map(move |(i, p)| {
        let hit = first_hit + i as u64 + 1;
        match read_per_hit(&p, &cfg) {
            Ok((samples, rate, pre)) => Item::Record(AeRecord {
                kind: crate::model::RecordKind::Hit,
                experiment: experiment.clone(),
                channel: 0,
                hit,
                time_s: None,
                sample_rate_hz: rate,
                pretrigger: pre,
                samples,
                load_n: None,
                extension_m: None,
                label: None,
                threshold_v: None,
                source_file: p.display().to_string(),
            }),
            Err(reason) => Item::Reject(Reject {
                record_type: crate::model::RecordType::Transient,
                experiment: experiment.clone(),
                source_file: p.display().to_string(),
                record_id: format!("hit {hit}"),
                stage: Stage::Read,
                reason,
            }),
        }
    }))
}

struct LongReader {
    experiment: String,
    path: String,
    l: Layout,
    records: csv::StringRecordsIntoIter<std::fs::File>,
    /// The first row of the next hit, already read.
    peek: Option<csv::StringRecord>,
    seen: std::collections::HashSet<(i64, i64)>,
    cfg: IngestConfig,
    done: bool,
}

impl LongReader {
    fn key(&self, rec: &csv::StringRecord) -> Result<(i64, i64), String> {
        let line = rec.position().map(|p| p.line()).unwrap_or(0);
        let hit = cell(rec, self.l.hit.expect("long layout"), line, "hit")?;
        let ch = match self.l.chan {
            Some(c) => cell(rec, c, line, "channel")?,
            None => 0.0,
        };
        if hit.fract() != 0.0 || ch.fract() != 0.0 {
            return Err(format!(
                "line {line}: hit and channel must be whole numbers"
            ));
        }
        Ok((ch as i64, hit as i64))
    }

    fn reject(&self, id: String, reason: String) -> Item {
        Item::Reject(Reject {
            record_type: crate::model::RecordType::Transient,
            experiment: self.experiment.clone(),
            source_file: self.path.clone(),
            record_id: id,
            stage: Stage::Read,
            reason,
        })
    }
}

impl Iterator for LongReader {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        if self.done {
            return None;
        }
        let first = match self.peek.take() {
            Some(r) => r,
            None => match self.records.next() {
                None => return None,
                Some(Ok(r)) => r,
                Some(Err(e)) => {
                    self.done = true;
                    return Some(self.reject(
                        String::new(),
                        format!("{e}; the rest of the file is not read"),
                    ));
                }
            },
        };
        let key = match self.key(&first) {
            Ok(k) => k,
            Err(e) => return Some(self.reject(String::new(), e)),
        };
        let id = format!("ch{} hit {}", key.0, key.1);
        let gain = gain_factor(self.cfg.gain_db);
        let mut v = Vec::new();
        let mut t = Vec::new();
        let mut err = None;
        let mut push = |rec: &csv::StringRecord, l: &Layout, v: &mut Vec<f32>, t: &mut Vec<f64>| {
            let line = rec.position().map(|p| p.line()).unwrap_or(0);
            match cell(rec, l.value, line, "value") {
                Ok(x) => v.push((x * gain) as f32),
                Err(e) => {
                    err.get_or_insert(e);
                }
            }
            if let Some(ti) = l.time {
                match cell(rec, ti, line, "time") {
                    Ok(x) => t.push(x),
                    Err(e) => {
                        err.get_or_insert(e);
                    }
                }
            }
        };
        push(&first, &self.l, &mut v, &mut t);
        loop {
            match self.records.next() {
                None => break,
                Some(Ok(rec)) => {
                    if self.key(&rec).ok() == Some(key) {
                        push(&rec, &self.l, &mut v, &mut t);
                    } else {
                        self.peek = Some(rec);
                        break;
                    }
                }
                Some(Err(e)) => {
                    err.get_or_insert(e.to_string());
                    break;
                }
            }
        }
        if !self.seen.insert(key) {
            return Some(self.reject(
                id,
                "rows of this hit are not contiguous (it appears in two separate blocks)".into(),
            ));
        }
        if let Some(e) = err {
            return Some(self.reject(id, e));
        }
        let (rate, pre) = timing(
            &t,
            self.l.time_unit,
            self.cfg.sample_rate_hz,
            self.cfg.pretrigger_samples,
        );
        Some(Item::Record(AeRecord {
            kind: crate::model::RecordKind::Hit,
            experiment: self.experiment.clone(),
            channel: key.0.max(0) as u32,
            hit: key.1.max(0) as u64,
            time_s: None,
            sample_rate_hz: rate,
            pretrigger: pre,
            samples: v,
            load_n: None,
            extension_m: None,
            label: None,
            threshold_v: None,
            source_file: self.path.clone(),
        }))
    }
}

/// CSV long tables: one file, a hit column.
pub(crate) const LONG_FORMAT: crate::ingest::FormatSpec = crate::ingest::FormatSpec {
    name: "csv (long table)",
    one_hit_per_file: false,
    numbered_by_place: false,
    follow: crate::ingest::Follow::Whole,
    open: open_long,
};

pub fn open_long(src: &Source, cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
    let path = src.files[0].clone();
    match reader(&path) {
        Ok((l, r)) => Box::new(LongReader {
            experiment: src.id.clone(),
            path: path.display().to_string(),
            l,
            records: r.into_records(),
            peek: None,
            seen: Default::default(),
            cfg: IngestConfig::clone(cfg),
            done: false,
        }),
        Err(reason) => Box::new(std::iter::once(Item::Reject(Reject {
            record_type: crate::model::RecordType::File,
            experiment: src.id.clone(),
            source_file: path.display().to_string(),
            record_id: String::new(),
            stage: Stage::Read,
            reason,
        }))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sniffing() {
        assert!(matches!(sniff("voltage_v\n0.1\n"), Sniff::PerHit));
        assert!(matches!(sniff("time_s;voltage_v\n0;0.1\n"), Sniff::PerHit));
        assert!(matches!(sniff("0.5\n0.1\n"), Sniff::PerHit));
        assert!(matches!(
            sniff("hit,channel,voltage_v\n1,1,0.1\n"),
            Sniff::Long
        ));
        assert!(matches!(sniff("Event,Time\n1,6.519\n"), Sniff::NotWaveform));
        assert!(matches!(sniff("7.69,7.69,7.69\n"), Sniff::NotWaveform));
    }

    #[test]
    fn timing_from_times() {
        let t: Vec<f64> = (-3..7).map(|i| i as f64 * 1e-7).collect();
        let (rate, pre) = timing(&t, None, 1.0, 0);
        assert!((rate - 1e7).abs() < 1e-3);
        assert_eq!(pre, 3);
    }

    #[test]
    fn time_units_from_the_header_or_the_spacing() {
        let unit = |h: &str| layout(&format!("{h},voltage_v\n0,0\n")).unwrap().time_unit;
        assert_eq!(unit("time_us"), Some(1e-6));
        assert_eq!(unit("Time (µs)"), Some(1e-6));
        assert_eq!(unit("t [ms]"), Some(1e-3));
        assert_eq!(unit("time/ns"), Some(1e-9));
        assert_eq!(unit("time_s"), Some(1.0));
        assert_eq!(unit("time"), None);
        // The same 10 MHz record written in µs, ms, s and with a bare column.
        let steps = |d: f64| (-2..8).map(|i| i as f64 * d).collect::<Vec<_>>();
        for (times, u) in [
            (steps(0.1), Some(1e-6)),
            (steps(1e-4), Some(1e-3)),
            (steps(1e-7), Some(1.0)),
            (steps(0.1), None),
            (steps(1e-7), None),
        ] {
            let (rate, pre) = timing(&times, u, 1.0, 0);
            assert!((rate / 1e7 - 1.0).abs() < 1e-9, "{rate} from {u:?}");
            assert_eq!(pre, 2);
        }
        // A bare column stepping by 0.2 (ms would be 5 kHz, s 5 Hz): µs, 5 MHz.
        assert_eq!(infer_time_unit(0.2), 1e-6);
    }

    #[test]
    fn decimal_commas_in_a_semicolon_file() {
        let dir = std::env::temp_dir().join(format!("aepipe-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("h1.csv");
        std::fs::write(&p, "time_us;voltage_v\n-0,1;0,5\n0,0;-0,25\n0,1;1,0E-3\n").unwrap();
        let (v, rate, pre) = read_per_hit(&p, &IngestConfig::default()).unwrap();
        assert_eq!(v, vec![0.5, -0.25, 0.001]);
        assert!((rate / 1e7 - 1.0).abs() < 1e-9);
        assert_eq!(pre, 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
