//! Plain text waveforms: one value per line (optionally a header line), one hit per file.
//! The rate and pretrigger come from `[ingest]`.

use super::sniff::{Head, Kind, Recogniser, Strength, Verdict};
use super::{gain_factor, Source};
use crate::ingest::settings::{FormatChoice, ReadSettings};
use crate::model::{AeRecord, Item, Reject, Stage};
use std::path::Path;

/// Most non-empty lines of the head parse as a single number.
pub fn looks_like_values(head: &str) -> bool {
    let lines: Vec<&str> = head
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .take(20)
        .collect();
    let numeric = lines.iter().filter(|l| l.parse::<f64>().is_ok()).count();
    numeric >= 2 && numeric + 1 >= lines.len()
}

fn recognise(h: &Head) -> Verdict {
    let name = u8::from(matches!(h.ext.as_str(), "txt" | "dat" | "asc"));
    if looks_like_values(&h.text) {
        return Verdict::mine(Kind::Text, Strength::Shape, name);
    }
    // Mostly single numbers, but more than a header line that is not: say which.
    let lines: Vec<&str> = h.filled_lines().take(20).collect();
    let numeric = lines.iter().filter(|l| l.parse::<f64>().is_ok()).count();
    if numeric * 2 > lines.len() {
        if let Some((i, l)) = lines
            .iter()
            .enumerate()
            .skip(1)
            .find(|(_, l)| l.parse::<f64>().is_err())
        {
            return Verdict::Near(format!(
                "resembles one value per line, but line {} of the filled lines, '{}', is not a number",
                i + 1,
                l.chars().take(40).collect::<String>()
            ));
        }
    }
    Verdict::No
}

/// Plain text, one value per line (a first line that is not a number is a header).
pub(crate) const RECOGNISER: Recogniser = Recogniser {
    what: "one value per line (rate from [ingest] sample_rate_hz)",
    format: FormatChoice::Text,
    recognise,
    forced: |h| looks_like_values(&h.text).then_some(Kind::Text),
};

/// Read one value per line; a first line that is not a number is taken as a header.
/// Any later line that is not a number is an error naming the line.
pub(crate) fn read_values(path: &Path) -> Result<Vec<f64>, super::RecordError> {
    let text = std::fs::read(path).map_err(|e| super::RecordError(format!("cannot read: {e}")))?;
    let text = String::from_utf8_lossy(&text);
    let mut out = Vec::with_capacity(text.len() / 10);
    for (i, l) in text.lines().enumerate() {
        let l = l.trim();
        if l.is_empty() {
            continue;
        }
        match l.parse::<f64>() {
            Ok(v) => out.push(v),
            Err(_) if i == 0 => {}
            Err(_) => {
                return Err(super::RecordError(format!(
                    "line {}: '{}' is not a number",
                    i + 1,
                    l.chars().take(40).collect::<String>()
                )))
            }
        }
    }
    Ok(out)
}

/// Plain text, one value per line, one hit per file.
pub(crate) const FORMAT: crate::ingest::FormatSpec = crate::ingest::FormatSpec {
    name: "text (one hit per file)",
    one_hit_per_file: true,
    numbered_by_place: true,
    follow: crate::ingest::Follow::PerFile,
    open,
};

pub fn open(src: &Source, cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
    let experiment = src.id.clone();
    let rate = cfg.sample_rate_hz;
    let pre = cfg.pretrigger_samples;
    let gain = gain_factor(cfg.gain_db);
    let files = src.files.clone();
    let first_hit = src.first_hit;
    Box::new(files.into_iter().enumerate().map(move |(i, p)| {
        let hit = first_hit + i as u64 + 1;
        match read_values(&p) {
            Ok(v) => Item::Record(AeRecord {
                kind: crate::model::RecordKind::Hit,
                experiment: experiment.clone(),
                channel: 0,
                hit,
                time_s: None,
                sample_rate_hz: rate,
                pretrigger: pre,
                samples: v.into_iter().map(|x| (x * gain) as f32).collect(),
                load_n: None,
                extension_m: None,
                label: None,
                threshold_v: None,
                source_file: p.display().to_string(),
            }),
            Err(e) => Item::Reject(Reject {
                record_type: crate::model::RecordType::Transient,
                experiment: experiment.clone(),
                source_file: p.display().to_string(),
                record_id: format!("hit {hit}"),
                stage: Stage::Read,
                reason: e.to_string(),
            }),
        }
    }))
}
