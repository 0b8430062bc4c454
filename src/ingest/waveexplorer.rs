//! Digital Wave WaveExplorer text export: a header line `rate_MHz n_events n_samples
//! n_channels` (tab separated), then `n_events × n_channels × n_samples` values, one per line,
//! event after event (channel blocks inside an event). The pretrigger comes from
//! `[ingest.waveexplorer]`. A token like `20deg` in the file name becomes the hit label (the
//! PLB angle of the labelled data set).

use super::{file_err, Source};
use crate::config::IngestConfig;
use crate::model::{AeRecord, Item, Reject, Stage};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// `(sample_rate_hz, events, samples, channels)` from the first line, if it is such a header.
pub fn parse_header(head: &str) -> Option<(f64, u64, usize, usize)> {
    let mut lines = head.lines();
    let first = lines.next()?;
    let w: Vec<&str> = first.split_whitespace().collect();
    if w.len() != 4 {
        return None;
    }
    let rate_mhz: f64 = w[0].parse().ok()?;
    let n: u64 = w[1].parse().ok()?;
    let len: usize = w[2].parse().ok()?;
    let ch: usize = w[3].parse().ok()?;
    let second_is_value = lines
        .next()
        .is_some_and(|l| l.trim().parse::<f64>().is_ok());
    (rate_mhz > 0.0 && n > 0 && len > 0 && (1..=64).contains(&ch) && second_is_value).then_some((
        rate_mhz * 1e6,
        n,
        len,
        ch,
    ))
}

/// A first line of four numbers over a value: a WaveExplorer header, valid or not. (An
/// invalid one — a zero rate, no events — is read by this reader, which says what is wrong,
/// rather than as plain text with a header line and the configured rate.)
pub fn looks_like_header(head: &str) -> bool {
    let mut lines = head.lines();
    let (Some(first), Some(second)) = (lines.next(), lines.next()) else {
        return false;
    };
    let w: Vec<&str> = first.split_whitespace().collect();
    w.len() == 4
        && w.iter().all(|t| t.parse::<f64>().is_ok())
        && second.trim().parse::<f64>().is_ok()
}

/// `220426_20deg_4mm_wave` → `20deg`.
fn label_from_name(p: &Path) -> Option<String> {
    let stem = p.file_stem()?.to_string_lossy().to_string();
    stem.split('_')
        .find(|t| {
            t.ends_with("deg")
                && t.len() > 3
                && t[..t.len() - 3].chars().all(|c| c.is_ascii_digit())
        })
        .map(str::to_string)
}

struct Reader {
    experiment: String,
    path: PathBuf,
    lines: std::io::Lines<BufReader<std::fs::File>>,
    line_no: usize,
    rate: f64,
    events: u64,
    len: usize,
    channels: usize,
    pretrigger: u32,
    label: Option<String>,
    event: u64,
    /// Records of the current event not yet handed out (channels > 1).
    queue: std::collections::VecDeque<Item>,
    failed: bool,
}

impl Reader {
    fn read_block(&mut self) -> Result<Vec<f32>, String> {
        let mut v = Vec::with_capacity(self.len);
        while v.len() < self.len {
            let Some(line) = self.lines.next() else {
                return Err(format!(
                    "file ends after {} of {} values of this event (header promised {} events)",
                    v.len(),
                    self.len,
                    self.events
                ));
            };
            self.line_no += 1;
            let line = line.map_err(|e| format!("line {}: {e}", self.line_no))?;
            let t = line.trim();
            if t.is_empty() {
                continue;
            }
            v.push(
                t.parse::<f32>()
                    .map_err(|_| format!("line {}: '{t}' is not a number", self.line_no))?,
            );
        }
        Ok(v)
    }
}

impl Iterator for Reader {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        if let Some(it) = self.queue.pop_front() {
            return Some(it);
        }
        if self.event >= self.events {
            return None;
        }
        self.event += 1;
        let ev = self.event;
        if self.failed {
            // After a structural error the rest of the events cannot be located: each is
            // reported, none is silently missing.
            return Some(Item::Reject(Reject {
                record_type: crate::model::RecordType::Transient,
                experiment: self.experiment.clone(),
                source_file: self.path.display().to_string(),
                record_id: format!("event {ev}"),
                stage: Stage::Read,
                reason: "not read: an earlier event of this file was malformed".into(),
            }));
        }
        for ch in 1..=self.channels {
            let item = match self.read_block() {
                Ok(samples) => Item::Record(AeRecord {
                    kind: crate::model::RecordKind::Hit,
                    experiment: self.experiment.clone(),
                    channel: ch as u32,
                    hit: ev,
                    time_s: None,
                    sample_rate_hz: self.rate,
                    pretrigger: self.pretrigger,
                    samples,
                    load_n: None,
                    extension_m: None,
                    label: self.label.clone(),
                    threshold_v: None,
                    source_file: self.path.display().to_string(),
                }),
                Err(reason) => {
                    self.failed = true;
                    Item::Reject(Reject {
                        record_type: crate::model::RecordType::Transient,
                        experiment: self.experiment.clone(),
                        source_file: self.path.display().to_string(),
                        record_id: format!("event {ev}"),
                        stage: Stage::Read,
                        reason,
                    })
                }
            };
            self.queue.push_back(item);
            if self.failed {
                break;
            }
        }
        self.queue.pop_front()
    }
}

pub fn open(src: &Source, cfg: &IngestConfig) -> Box<dyn Iterator<Item = Item> + Send> {
    let path = src.files[0].clone();
    let reject = |reason: String| -> Box<dyn Iterator<Item = Item> + Send> {
        Box::new(std::iter::once(Item::Reject(Reject {
            record_type: crate::model::RecordType::File,
            experiment: src.id.clone(),
            source_file: path.display().to_string(),
            record_id: String::new(),
            stage: Stage::Read,
            reason,
        })))
    };
    let file = match std::fs::File::open(&path) {
        Ok(f) => f,
        Err(e) => return reject(file_err(&path, e).to_string()),
    };
    let mut lines = BufReader::new(file).lines();
    let first = match lines.next() {
        Some(Ok(l)) => l,
        _ => return reject("empty file".into()),
    };
    let Some((rate, events, len, channels)) = parse_header(&format!("{first}\n0\n")) else {
        return reject(format!(
            "first line '{}' is not a valid WaveExplorer header (rate_MHz > 0, n_events ≥ 1, n_samples ≥ 1, n_channels 1–64)",
            first.trim()
        ));
    };
    // The header is a claim: every value takes at least two bytes ("0\n"), so the file
    // cannot hold more than half its size in values; and no record may exceed the limit.
    let file_len = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    let promised = (events as u128) * (len as u128) * (channels as u128);
    if promised > (file_len / 2) as u128 {
        return reject(format!(
            "header promises {events} events × {channels} channel(s) × {len} samples = {promised} values; the file of {file_len} bytes holds at most {}",
            file_len / 2
        ));
    }
    if len as u64 > cfg.max_samples_per_record {
        return reject(format!(
            "records of {len} samples exceed ingest.max_samples_per_record = {}",
            cfg.max_samples_per_record
        ));
    }
    Box::new(Reader {
        experiment: src.id.clone(),
        label: label_from_name(&path),
        path,
        lines,
        line_no: 1,
        rate,
        events,
        len,
        channels,
        pretrigger: cfg.waveexplorer.pretrigger_samples,
        event: 0,
        queue: Default::default(),
        failed: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_and_label() {
        assert_eq!(
            parse_header("10\t110\t1024\t1\t\r\n0.002\t\r\n"),
            Some((10e6, 110, 1024, 1))
        );
        assert_eq!(parse_header("10 110 1024\n0.1\n"), None);
        assert_eq!(parse_header("1\n2\n"), None);
        assert_eq!(
            label_from_name(Path::new("a/220426_20deg_4mm_wave.txt")),
            Some("20deg".into())
        );
        assert_eq!(label_from_name(Path::new("a/plain.txt")), None);
    }
}
