//! Digital Wave WaveExplorer text export: a header line `rate_MHz n_events n_samples
//! n_channels` (tab separated), then one line per sample, event after event, each line
//! holding one value per channel (a tab after each value, CRLF line ends). The Daly lab's
//! reader (`ae_measure2.read_ae_file2`) reads channel k as the k-th value of each line. The
//! pretrigger comes from `[ingest.waveexplorer]`. A token like `20deg` in the file name
//! becomes the hit label (the PLB angle of the labelled data set). Any file name: the
//! header and the lines under it tell the format.

use super::sniff::{cells, Head, Kind, Recogniser, Strength, Verdict};
use super::{file_err, Source};
use crate::ingest::settings::{FormatChoice, ReadSettings};
use crate::model::{AeRecord, Item, Reject, Stage};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// The header's cells: four numbers separated by tabs or spaces (never commas: that is a
/// CSV row).
fn header_cells(line: &str) -> Option<Vec<&str>> {
    if line.contains(',') || line.contains(';') {
        return None;
    }
    let w: Vec<&str> = line.split_whitespace().collect();
    (w.len() == 4 && w.iter().all(|t| t.parse::<f64>().is_ok())).then_some(w)
}

/// The first two non-empty lines of a head.
fn first_two(head: &str) -> (Option<&str>, Option<&str>) {
    let mut lines = head.lines().map(str::trim).filter(|l| !l.is_empty());
    (lines.next(), lines.next())
}

/// `(sample_rate_hz, events, samples, channels)` from the first line, if it is a valid
/// header over a line of `channels` values.
#[cfg(test)]
fn parse_header(head: &str) -> Option<(f64, u64, usize, usize)> {
    let (first, second) = first_two(head);
    let h = header_values(first?)?;
    let values = cells(second?);
    (values.len() == h.3 && values.iter().all(|v| v.parse::<f64>().is_ok())).then_some(h)
}

/// The header line's values when they are valid: rate > 0, at least one event and sample,
/// 1–64 channels.
fn header_values(first: &str) -> Option<(f64, u64, usize, usize)> {
    let w = header_cells(first)?;
    let rate_mhz: f64 = w[0].parse().ok()?;
    let n: u64 = w[1].parse().ok()?;
    let len: usize = w[2].parse().ok()?;
    let ch: usize = w[3].parse().ok()?;
    (rate_mhz > 0.0 && n > 0 && len > 0 && (1..=64).contains(&ch)).then_some((
        rate_mhz * 1e6,
        n,
        len,
        ch,
    ))
}

/// A first line of four numbers over a line of values: a WaveExplorer header, valid or not.
/// (An invalid one — a zero rate, no events — is read by this reader, which says what is
/// wrong, rather than as plain text with a header line and the configured rate.)
pub fn looks_like_header(head: &str) -> bool {
    let (Some(first), Some(second)) = first_two(head) else {
        return false;
    };
    let values = cells(second);
    header_cells(first).is_some()
        && (1..=64).contains(&values.len())
        && values.iter().all(|v| v.parse::<f64>().is_ok())
}

fn recognise(h: &Head) -> Verdict {
    if !looks_like_header(&h.text) {
        return Verdict::No;
    }
    let name = if h.name.ends_with("_wave.txt") {
        2
    } else {
        u8::from(h.ext == "txt")
    };
    Verdict::mine(Kind::WaveExplorer, Strength::Signature, name)
}

/// WaveExplorer exports, by their header line.
pub(crate) const RECOGNISER: Recogniser = Recogniser {
    what: "WaveExplorer exports (header 'rate_MHz events samples channels', a line per sample)",
    format: FormatChoice::Waveexplorer,
    recognise,
    forced: |_| Some(Kind::WaveExplorer),
};

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
    /// One event: `len` lines of one value per channel, the channels' samples apart.
    fn read_event(&mut self) -> Result<Vec<Vec<f32>>, String> {
        let mut v = vec![Vec::with_capacity(self.len); self.channels];
        let mut got = 0;
        while got < self.len {
            let Some(line) = self.lines.next() else {
                return Err(format!(
                    "file ends after {got} of {} values of this event (header promised {} events)",
                    self.len, self.events
                ));
            };
            self.line_no += 1;
            let line = line.map_err(|e| format!("line {}: {e}", self.line_no))?;
            let t = line.trim();
            if t.is_empty() {
                continue;
            }
            if self.channels == 1 {
                v[0].push(
                    t.parse::<f32>()
                        .map_err(|_| format!("line {}: '{t}' is not a number", self.line_no))?,
                );
            } else {
                let mut k = 0;
                for c in t.split_whitespace() {
                    if k == self.channels {
                        break;
                    }
                    v[k].push(
                        c.parse::<f32>()
                            .map_err(|_| format!("line {}: '{c}' is not a number", self.line_no))?,
                    );
                    k += 1;
                }
                if k < self.channels {
                    return Err(format!(
                        "line {}: {k} value(s) where the header promises {} channels",
                        self.line_no, self.channels
                    ));
                }
            }
            got += 1;
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
        match self.read_event() {
            Ok(channels) => {
                for (ch, samples) in channels.into_iter().enumerate() {
                    self.queue.push_back(Item::Record(AeRecord {
                        kind: crate::model::RecordKind::Hit,
                        experiment: self.experiment.clone(),
                        channel: ch as u32 + 1,
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
                    }));
                }
            }
            Err(reason) => {
                self.failed = true;
                self.queue.push_back(Item::Reject(Reject {
                    record_type: crate::model::RecordType::Transient,
                    experiment: self.experiment.clone(),
                    source_file: self.path.display().to_string(),
                    record_id: format!("event {ev}"),
                    stage: Stage::Read,
                    reason,
                }));
            }
        }
        self.queue.pop_front()
    }
}

/// Digital Wave WaveExplorer exports: many events in one file.
pub(crate) const FORMAT: crate::ingest::FormatSpec = crate::ingest::FormatSpec {
    name: "waveexplorer",
    one_hit_per_file: false,
    numbered_by_place: false,
    follow: crate::ingest::Follow::Whole,
    open,
};

pub fn open(src: &Source, cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
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
    let Some((rate, events, len, channels)) = header_values(first.trim()) else {
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
