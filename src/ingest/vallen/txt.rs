//! Vallen's TXT export of one transient, which labs keep when the databases stay on the
//! acquisition PC: a first line `Datafile: X, Trai: 1, Chan:1`, a column header
//! `Time (microsec)<TAB>Amplitude (mV)`, then one row per sample (line ends CR CR LF).
//!
//! One hit per file: `Trai` is its transient number, `Chan` its channel, the database's
//! stem its experiment. The time column gives the rate (and the pretrigger: the samples
//! before 0); the amplitude's unit is read from its header. The file does not say when the
//! hit came, so its `time_s` is null. When the `.tradb` an export came from lies beside it,
//! discovery passes the export over (the same transient is never read twice).

use crate::ingest::settings::{FormatChoice, ReadSettings};
use crate::ingest::sniff::{self, Head, Kind, Recogniser, Strength, Verdict};
use crate::ingest::{RecordError, Source};
use crate::model::{AeRecord, Item, Note, Reject, Stage};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The first line's keys.
#[derive(Debug, Clone, PartialEq)]
pub struct TxtHead {
    /// The database's stem (`C:\data\test.tradb` → `test`).
    pub datafile: String,
    pub trai: u64,
    pub chan: u32,
    /// `key: value` items aepipe does not know.
    pub unknown: Vec<String>,
}

/// The stem of a path as Windows or Unix writes it.
fn stem(s: &str) -> String {
    let name = s.rsplit(['\\', '/']).next().unwrap_or(s).trim();
    match name.rsplit_once('.') {
        Some((a, e)) if !a.is_empty() && !e.contains(' ') => a.to_string(),
        _ => name.to_string(),
    }
}

/// The first line: `None` when it is not `Datafile: …` with keys; else its keys or what is
/// missing.
pub fn parse_first_line(line: &str) -> Option<Result<TxtHead, String>> {
    let items: Vec<(String, &str)> = line
        .split(',')
        .filter_map(|it| {
            let (k, v) = it.split_once(':')?;
            Some((k.trim().to_lowercase(), v.trim()))
        })
        .collect();
    let datafile = items.iter().find(|(k, _)| k == "datafile")?.1;
    let get = |key: &str| items.iter().find(|(k, _)| k == key).map(|(_, v)| *v);
    let trai = get("trai").and_then(|v| v.parse::<u64>().ok());
    let chan = get("chan").and_then(|v| v.parse::<u32>().ok());
    Some(match (trai, chan) {
        (Some(trai), Some(chan)) if trai > 0 && !datafile.is_empty() => Ok(TxtHead {
            datafile: stem(datafile),
            trai,
            chan,
            unknown: items
                .iter()
                .filter(|(k, _)| !matches!(k.as_str(), "datafile" | "trai" | "chan"))
                .map(|(k, _)| k.clone())
                .collect(),
        }),
        _ => Err(format!(
            "its first line '{}' names a Datafile but no positive Trai and Chan",
            line.chars().take(60).collect::<String>()
        )),
    })
}

fn recognise(h: &Head) -> Verdict {
    match parse_first_line(h.first_line()) {
        None => Verdict::No,
        Some(Ok(t)) => Verdict::mine(
            Kind::VallenTxt {
                datafile: t.datafile,
            },
            Strength::Signature,
            u8::from(h.ext == "txt"),
        ),
        Some(Err(why)) => Verdict::Near(format!(
            "resembles a Vallen TXT transient export, but {why}"
        )),
    }
}

/// Vallen TXT exports of one transient.
pub(crate) const RECOGNISER: Recogniser = Recogniser {
    what: "Vallen TXT exports of a transient (Datafile: …, Trai: …, Chan: …)",
    format: FormatChoice::Vallen,
    recognise,
    forced: sniff::never,
};

/// The sources of the TXT exports discovery found, by their database's base path: one per
/// database, unless that database's `.tradb` is read (then the exports would be its
/// transients again: each is passed over, saying so).
pub(crate) fn export_sources(
    exports: BTreeMap<PathBuf, Vec<PathBuf>>,
    pairs: &super::Pairs,
    skipped: &mut Vec<(PathBuf, String)>,
) -> Vec<Source> {
    let mut out = Vec::new();
    for (base, files) in exports {
        if let Some((_, Some(tra))) = pairs.get(&base) {
            for p in files {
                skipped.push((
                    p,
                    format!(
                        "a Vallen TXT export of a transient of {}, which lies beside it and is read instead (the same transient is not read twice)",
                        tra.display()
                    ),
                ));
            }
            continue;
        }
        let id = base
            .file_name()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        out.push(Source::of(id, crate::ingest::Format::VallenTxt, files));
    }
    out
}

/// `Time (microsec)` → seconds per unit; `Amplitude (mV)` → volts per unit.
fn unit_of(cell: &str) -> Option<&str> {
    let a = cell.find(['(', '['])?;
    let b = cell[a..].find([')', ']'])? + a;
    Some(cell[a + 1..b].trim())
}

fn volts_per(unit: &str) -> Option<f64> {
    match unit {
        "V" | "v" | "volt" | "volts" => Some(1.0),
        "mV" | "mv" => Some(1e-3),
        "µV" | "μV" | "uV" | "uv" => Some(1e-6),
        _ => None,
    }
}

/// A number, a decimal comma accepted where there is no point.
fn number(s: &str) -> Option<f64> {
    let s = s.trim();
    s.parse::<f64>().ok().or_else(|| {
        (s.contains(',') && !s.contains('.'))
            .then(|| s.replacen(',', ".", 1).parse().ok())
            .flatten()
    })
}

/// One export: its keys, samples (volts), rate and pretrigger.
pub struct Transient {
    pub head: TxtHead,
    pub samples_v: Vec<f32>,
    pub sample_rate_hz: f64,
    pub pretrigger: u32,
}

/// Read one export; what is wrong with it is the reason of its reject row.
pub fn read(path: &Path, max_samples: u64) -> Result<Transient, RecordError> {
    read_text(path, max_samples).map_err(RecordError)
}

fn read_text(path: &Path, max_samples: u64) -> Result<Transient, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read: {e}"))?;
    let text = String::from_utf8_lossy(&bytes);
    let mut lines = text
        .split('\n')
        .map(str::trim)
        .enumerate()
        .filter(|(_, l)| !l.is_empty());
    let (_, first) = lines.next().ok_or("empty file")?;
    let head = match parse_first_line(first) {
        Some(r) => r?,
        None => {
            return Err(format!(
                "first line '{first}' is not 'Datafile: …, Trai: …, Chan: …'"
            ))
        }
    };
    let (hl, columns) = lines
        .next()
        .ok_or("no column header under the first line")?;
    let cols: Vec<&str> = sniff::cells(columns);
    if cols.len() < 2 {
        return Err(format!(
            "line {}: column header '{columns}' is not 'Time (unit)<TAB>Amplitude (unit)'",
            hl + 1
        ));
    }
    let t_unit = unit_of(cols[0]).unwrap_or("s");
    let v_unit = unit_of(cols[1]).unwrap_or("V");
    let t_scale = sniff::seconds_per(t_unit)
        .ok_or_else(|| format!("time unit '{t_unit}' is not one aepipe knows"))?;
    let v_scale =
        volts_per(v_unit).ok_or_else(|| format!("amplitude unit '{v_unit}' is not a voltage"))?;
    let (mut times, mut samples_v) = (Vec::new(), Vec::new());
    for (i, l) in lines {
        let c = sniff::cells(l);
        let (Some(t), Some(v)) = (
            c.first().and_then(|x| number(x)),
            c.get(1).and_then(|x| number(x)),
        ) else {
            return Err(format!(
                "line {}: '{}' is not a time and an amplitude",
                i + 1,
                l.chars().take(40).collect::<String>()
            ));
        };
        if samples_v.len() as u64 >= max_samples {
            return Err(format!(
                "more than ingest.max_samples_per_record = {max_samples} samples"
            ));
        }
        times.push(t * t_scale);
        samples_v.push((v * v_scale) as f32);
    }
    if times.len() < 2 {
        return Err(format!("{} sample(s): a rate needs two", times.len()));
    }
    let span = times[times.len() - 1] - times[0];
    if span.is_nan() || span <= 0.0 {
        return Err("the time column does not rise".into());
    }
    // The export rounds its times; the recorder's rates are whole hertz.
    let sample_rate_hz = ((times.len() - 1) as f64 / span).round();
    let pretrigger = times.iter().take_while(|&&t| t < 0.0).count() as u32;
    Ok(Transient {
        head,
        samples_v,
        sample_rate_hz,
        pretrigger,
    })
}

/// Reads a source's exports one file at a time; the keys no reader knows are said once,
/// after the last file.
struct Reader {
    experiment: String,
    files: std::vec::IntoIter<(u64, u32, PathBuf)>,
    max_samples: u64,
    unknown: BTreeMap<String, u64>,
}

impl Iterator for Reader {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        let Some((trai, chan, p)) = self.files.next() else {
            let (k, n) = self.unknown.pop_first()?;
            return Some(Item::Note(Note {
        said: false,
                experiment: self.experiment.clone(),
                source_file: String::new(),
                message: format!(
                    "Vallen TXT export key '{k}' is not one aepipe knows: kept, not used ({n} file(s))"
                ),
            }));
        };
        Some(match read(&p, self.max_samples) {
            Ok(t) => {
                for k in t.head.unknown {
                    *self.unknown.entry(k).or_insert(0) += 1;
                }
                Item::Record(AeRecord {
                    kind: crate::model::RecordKind::Hit,
                    experiment: self.experiment.clone(),
                    channel: t.head.chan,
                    hit: t.head.trai,
                    time_s: None,
                    sample_rate_hz: t.sample_rate_hz,
                    pretrigger: t.pretrigger,
                    samples: t.samples_v,
                    load_n: None,
                    extension_m: None,
                    label: None,
                    threshold_v: None,
                    source_file: p.display().to_string(),
                })
            }
            Err(reason) => Item::Reject(Reject {
                record_type: crate::model::RecordType::Transient,
                experiment: self.experiment.clone(),
                source_file: p.display().to_string(),
                record_id: format!("TRAI {trai} ch{chan}"),
                stage: Stage::Read,
                reason: reason.0,
            }),
        })
    }
}

/// Vallen TXT exports of transients, grouped by the database they came from.
pub(crate) const FORMAT: crate::ingest::FormatSpec = crate::ingest::FormatSpec {
    name: "vallen txt export",
    one_hit_per_file: false,
    numbered_by_place: false,
    follow: crate::ingest::Follow::Whole,
    open,
};

/// Read a source of exports: one record (or reject row) per file, in (channel, TRAI) order,
/// the order the `.tradb` reader gives its transients.
pub fn open(src: &Source, cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
    let mut files: Vec<(u64, u32, PathBuf)> = src
        .files
        .iter()
        .map(|p| {
            let (trai, chan) = Head::read(p)
                .ok()
                .and_then(|h| parse_first_line(h.first_line()).and_then(Result::ok))
                .map_or((0, 0), |t| (t.trai, t.chan));
            (trai, chan, p.clone())
        })
        .collect();
    files.sort_by_key(|(trai, chan, p)| (*chan, *trai, p.clone()));
    Box::new(Reader {
        experiment: src.id.clone(),
        files: files.into_iter(),
        max_samples: cfg.max_samples_per_record,
        unknown: BTreeMap::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_lines_and_units() {
        let t = parse_first_line("Datafile: C:\\AE\\sample.tradb, Trai: 12, Chan:3")
            .unwrap()
            .unwrap();
        assert_eq!((t.datafile.as_str(), t.trai, t.chan), ("sample", 12, 3));
        assert!(parse_first_line("Time (microsec)\tAmplitude (mV)").is_none());
        assert!(parse_first_line("Datafile: x, Trai: 0, Chan: 1")
            .unwrap()
            .is_err());
        assert_eq!(unit_of("Time (microsec)"), Some("microsec"));
        assert_eq!(unit_of("Amplitude [mV]"), Some("mV"));
        assert_eq!(number("0,125"), Some(0.125));
        assert_eq!(stem("/data/x.y/sample"), "sample");
    }
}
