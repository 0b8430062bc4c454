//! MISTRAS AEwin ASCII exports: a folder of waveform files, one per hit, named
//! `<test>_<ch>_<hit>_<time µs>.txt` (or `.csv`), a hit list `<test>.TXT` beside it, and the
//! tensile machine's log `Specimen_RawData_<n>.csv` ([`log`]).
//!
//! A waveform file is one value per line (volts at the ADC, including the preamplifier),
//! either alone (rate and pretrigger from `[ingest.aewin]`, channel, hit and time from the
//! name) or after a `KEY: value` header ([`header`]) that gives the rate (`SAMPLE
//! INTERVAL`), channel, hit number and the hit's time on the test's clock (`TIME OF TEST`),
//! checked before the file is read: the signal unit must be volts and the declared number
//! of points must be the number of values. The files of one test in one folder are one
//! experiment, so `[events]` groups its channels.

pub mod header;
pub mod list;
mod log;
mod plan;

use super::sniff::{self, Head, Kind, Recogniser, Strength, Verdict};
use super::{gain_factor, text, Role, Source};
use crate::ingest::settings::{FormatChoice, ReadSettings};
use crate::model::{AeRecord, HitRow, Item, Note, Reject, Stage};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use log::{looks_like_machine_log, MachineLog};

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

/// An AEwin hit list starts with a header row like ` ID  PARA1  RISE  COUN  DURATION AMP …`,
/// its columns in any order: names only (no number), among them AMP, RISE or DURATION and
/// at least one more of AEwin's hit-feature names.
pub fn looks_like_hit_list(head: &str) -> bool {
    const NAMES: [&str; 13] = [
        "ID",
        "CH",
        "TIME",
        "PARA1",
        "RISE",
        "COUN",
        "DURATION",
        "AMP",
        "PCNTS",
        "ABS-ENERGY",
        "ENER",
        "THR",
        "A-FRQ",
    ];
    head.lines()
        .find(|l| !l.trim().is_empty())
        .is_some_and(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            w.iter().all(|x| sniff::parse_number(x).is_none())
                && w.iter()
                    .any(|x| *x == "AMP" || *x == "RISE" || *x == "DURATION")
                && w.iter().filter(|x| NAMES.contains(x)).count() >= 2
        })
}

/// How well a file's name fits an AEwin waveform file: its naming scheme (2), a text
/// extension (1).
fn name_fit(h: &Head, p: &Path) -> u8 {
    if parse_wave_name(p).is_some() {
        2
    } else {
        u8::from(matches!(h.ext.as_str(), "txt" | "csv"))
    }
}

/// The test a waveform file belongs to: its name before `_<ch>_<hit>_<time>`, else the
/// stem of its header's source file.
fn test_of(p: &Path, hd: Option<&header::Header>) -> Option<String> {
    parse_wave_name(p).map(|n| n.0).or_else(|| {
        let s = hd?.source_file.as_deref()?;
        let name = s.rsplit(['\\', '/']).next()?;
        let stem = name.rsplit_once('.').map_or(name, |(a, _)| a).trim();
        (!stem.is_empty()).then(|| stem.to_string())
    })
}

fn recognise_header(h: &Head) -> Verdict {
    let Some(hd) = header::parse(&h.text).filter(header::Header::is_aewin) else {
        return Verdict::No;
    };
    if hd.sample_interval_s.is_none() {
        return Verdict::Near(format!(
            "resembles an AEwin waveform export with a header ({} known key(s)), but it states no readable SAMPLE INTERVAL: `[ingest] format = \"aewin\"` reads it at `[ingest.aewin] sample_rate_hz`",
            hd.known
        ));
    }
    let p = Path::new(&h.name);
    Verdict::mine(
        Kind::AewinWave {
            test: test_of(p, Some(&hd)),
        },
        Strength::Signature,
        name_fit(h, p),
    )
}

/// Under `[ingest] format = "aewin"`: a header without a sample interval, or values.
fn forced_aewin(h: &Head) -> Option<Kind> {
    let hd = header::parse(&h.text).filter(header::Header::is_aewin);
    (hd.is_some() || text::looks_like_values(&h.text)).then(|| Kind::AewinWave {
        test: test_of(Path::new(&h.name), hd.as_ref()),
    })
}

/// AEwin waveform exports with a `KEY: value` header.
pub(crate) const HEADER_RECOGNISER: Recogniser = Recogniser {
    what: "AEwin waveform exports with a header (SAMPLE INTERVAL, CHANNEL NUMBER, HIT NUMBER, TIME OF TEST …)",
    format: FormatChoice::Aewin,
    recognise: recognise_header,
    forced: forced_aewin,
};

/// Header-less AEwin waveform files: one value per line, told from plain text only by
/// their name (or an empty file so named: a hit that lost its samples, which the reader
/// rejects).
pub(crate) const VALUES_RECOGNISER: Recogniser = Recogniser {
    what: "header-less AEwin waveform files named <test>_<ch>_<hit>_<time µs>",
    format: FormatChoice::Aewin,
    recognise: |h| {
        let p = Path::new(&h.name);
        let Some((test, ..)) = parse_wave_name(p) else {
            return Verdict::No;
        };
        let test = Some(test);
        if h.is_empty() {
            Verdict::mine(Kind::AewinWave { test }, Strength::Name, 2)
        } else if text::looks_like_values(&h.text) {
            Verdict::mine(Kind::AewinWave { test }, Strength::Shape, 2)
        } else {
            Verdict::No
        }
    },
    forced: sniff::never,
};

/// The AEwin hit list beside a waveform folder (a companion).
pub(crate) const HIT_LIST_RECOGNISER: Recogniser = Recogniser {
    what: "AEwin hit lists (ID PARA1 RISE COUN DURATION AMP …)",
    format: FormatChoice::Aewin,
    recognise: |h| {
        if looks_like_hit_list(&h.text) {
            Verdict::mine(Kind::AewinHitList, Strength::Signature, 1)
        } else {
            Verdict::No
        }
    },
    forced: sniff::never,
};

/// A tensile machine's log (a companion of the AEwin experiment whose id holds its number).
pub(crate) const MACHINE_LOG_RECOGNISER: Recogniser = Recogniser {
    what: "test-machine logs (Time;…;Load)",
    format: FormatChoice::Auto,
    recognise: |h| {
        if looks_like_machine_log(&h.text) {
            Verdict::mine(Kind::MachineLog, Strength::Signature, 1)
        } else if h.name.starts_with("Specimen_RawData") && h.ext == "csv" {
            Verdict::mine(Kind::MachineLog, Strength::Name, 2)
        } else {
            Verdict::No
        }
    },
    forced: sniff::never,
};

/// The companions of an AEwin test in `dir`: its hit list `<test>.TXT` and a machine log
/// `Specimen_RawData_<n>.csv` whose number appears in the test's name, each in the folder or
/// beside it. Those taken are marked in `used`.
pub(crate) fn adopt_companions(
    src: &mut Source,
    dir: &Path,
    hit_lists: &[PathBuf],
    logs: &[PathBuf],
    used: &mut std::collections::BTreeSet<PathBuf>,
) {
    use super::Companion;
    let near = |p: &Path| p.parent() == dir.parent() || p.parent() == Some(dir);
    let stem = |p: &Path| {
        p.file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default()
    };
    for h in hit_lists {
        if stem(h) == src.id && near(h) {
            src.companions.push(Companion {
                role: Role::HitList,
                path: h.clone(),
            });
            used.insert(h.clone());
        }
    }
    for l in logs {
        let digits: String = stem(l).chars().filter(|c| c.is_ascii_digit()).collect();
        if !digits.is_empty() && src.id.contains(&digits) && near(l) {
            src.companions.push(Companion {
                role: Role::MachineLog,
                path: l.clone(),
            });
            used.insert(l.clone());
        }
    }
}

/// One waveform file: its channel, hit and time as its name or header say.
#[derive(Debug, Clone)]
pub(super) struct WaveFile {
    channel: u32,
    hit: u64,
    /// Microseconds from the name (a header-less file), for the order and the time.
    name_time_us: Option<u64>,
    /// The file has no AEwin header (its rate is not its own), as [`identify`] read it.
    header_less: bool,
    path: PathBuf,
}

/// What a header-less file's name says, or a header's keys where the file has them. A
/// file that cannot be opened here keeps its name's numbers; its reader says why.
fn identify(p: &Path, place: usize) -> WaveFile {
    let named = parse_wave_name(p);
    let hd = Head::read(p)
        .ok()
        .and_then(|h| header::parse(&h.text))
        .filter(header::Header::is_aewin);
    let (mut channel, mut hit) = match &named {
        Some((_, ch, hit, _)) => (*ch, *hit),
        // Forced AEwin on files without the naming scheme: numbered in order.
        None => (0, place as u64 + 1),
    };
    if let Some(hd) = &hd {
        channel = hd.channel.unwrap_or(channel);
        hit = hd.hit.unwrap_or(hit);
    }
    WaveFile {
        channel,
        hit,
        name_time_us: named.map(|n| n.3),
        header_less: hd.is_none(),
        path: p.to_path_buf(),
    }
}

/// A waveform file's record: its header (checked), its values, rate and time.
struct Read {
    samples: Vec<f64>,
    rate: f64,
    /// The rate is the header's `SAMPLE INTERVAL`.
    from_header: bool,
    time_s: Option<f64>,
    notes: Vec<String>,
    unknown: Vec<String>,
}

fn read_wave(f: &WaveFile, default_rate: f64) -> Result<Read, String> {
    let bytes = std::fs::read(&f.path).map_err(|e| format!("cannot read: {e}"))?;
    let text = String::from_utf8_lossy(&bytes);
    let Some(hd) = header::parse(&text).filter(header::Header::is_aewin) else {
        // Header-less: one value per line, as it always was read.
        let samples = text::read_values(&f.path).map_err(|e| e.to_string())?;
        return Ok(Read {
            samples,
            rate: default_rate,
            from_header: false,
            time_s: f.name_time_us.map(|t| t as f64 * 1e-6),
            notes: vec![],
            unknown: vec![],
        });
    };
    hd.check_units().map_err(|e| e.0)?;
    if let Some((k, v)) = hd.unreadable.first() {
        return Err(format!("header key {k}: '{v}' cannot be read"));
    }
    let time_s = hd
        .time_of_test_s()
        .map_err(|e| e.0)?
        .or(f.name_time_us.map(|t| t as f64 * 1e-6));
    let mut samples = Vec::with_capacity(bytes.len() / 10);
    for (i, l) in text.split('\n').enumerate().skip(hd.lines) {
        let l = l.trim();
        if l.is_empty() {
            continue;
        }
        match sniff::parse_number(l) {
            Some(v) => samples.push(v),
            None => {
                return Err(format!(
                    "line {}: '{}' is not a number",
                    i + 1,
                    l.chars().take(40).collect::<String>()
                ))
            }
        }
    }
    if let Some(n) = hd.points {
        if n != samples.len() as u64 {
            return Err(format!(
                "the header declares {n} data points; the file holds {} values",
                samples.len()
            ));
        }
    }
    let mut notes = Vec::new();
    if let Some((_, ch, hit, _)) = parse_wave_name(&f.path) {
        if (ch, hit) != (f.channel, f.hit) {
            notes.push(format!(
                "{}: the name says channel {ch} hit {hit}, the header channel {} hit {}: the header's are used",
                f.path.display(),
                f.channel,
                f.hit
            ));
        }
    }
    let from_header = hd.sample_interval_s.is_some();
    let rate = match hd.sample_interval_s {
        Some(dt) => 1.0 / dt,
        None => {
            notes.push(format!(
                "{}: no SAMPLE INTERVAL in the header: read at [ingest.aewin] sample_rate_hz = {default_rate} Hz",
                f.path.display()
            ));
            default_rate
        }
    };
    Ok(Read {
        samples,
        rate,
        from_header,
        time_s,
        notes,
        unknown: hd.unknown,
    })
}

struct Reader {
    experiment: String,
    steps: std::vec::IntoIter<plan::Step>,
    /// The hit list whose values land (its match holds).
    list: Option<list::HitList>,
    /// Whether this reader makes the test's hit rows (a hit list lies beside it).
    hit_rows: bool,
    /// Hit rows made from waveforms alone (the list lacks them, or no list matched).
    added_hits: u64,
    last_channel: u32,
    rate: f64,
    pretrigger: u32,
    gain: f64,
    log: MachineLog,
    log_file: String,
    offset_s: f64,
    /// Notes waiting to be handed out, and header keys aepipe does not know, by file count.
    notes: std::collections::VecDeque<Item>,
    unknown: BTreeMap<String, u64>,
    /// The hits the machine log covers (a log that stopped early covers few).
    coverage: super::Coverage,
    done: bool,
}

impl Reader {
    fn note(&self, message: String) -> Item {
        Item::Note(Note {
            experiment: self.experiment.clone(),
            source_file: String::new(),
            message,
            said: false,
        })
    }

    /// The load and extension at a hit's time on the AE clock.
    fn load_at(&self, time_s: Option<f64>) -> (Option<f64>, Option<f64>) {
        let tm = time_s.map(|t| t - self.offset_s);
        (
            tm.and_then(|t| self.log.load_n.at(t)),
            tm.and_then(|t| self.log.extension_m.at(t)),
        )
    }

    /// The hit row of a list row: its values, its place in the test, its load.
    fn list_hit(&self, row: usize, order: u64, status: &'static str) -> HitRow {
        let list = self.list.as_ref().expect("a matched list");
        let r = &list.rows[row];
        let mut h = HitRow {
            experiment: self.experiment.clone(),
            acquisition: 1,
            channel: list.channel(r).unwrap_or(self.last_channel),
            hit: order,
            source: crate::model::HitSource::AewinList,
            source_file: list.path.display().to_string(),
            list_status: Some(status),
            ..Default::default()
        };
        list.fill(r, &mut h);
        (h.load_n, h.extension_m) = self.load_at(h.time_s);
        h
    }

    /// A waveform step: its hit row (when this reader makes them) and its record, or its
    /// reject.
    fn wave(&mut self, f: WaveFile, row: Option<usize>, order: u64) -> Vec<Item> {
        self.last_channel = f.channel;
        let r = match read_wave(&f, self.rate) {
            Ok(r) => r,
            Err(reason) => {
                let mut out = Vec::new();
                if let Some(row) = row {
                    // The list's row stays; its waveform is the reject below.
                    let mut h = self.list_hit(row, order, "matched");
                    h.channel = f.channel;
                    out.push(Item::Hit(Box::new(h)));
                }
                out.push(Item::Reject(Reject {
                    record_type: crate::model::RecordType::Transient,
                    experiment: self.experiment.clone(),
                    source_file: f.path.display().to_string(),
                    record_id: format!("ch{} hit {}", f.channel, f.hit),
                    stage: Stage::Read,
                    reason,
                }));
                return out;
            }
        };
        for k in r.unknown {
            *self.unknown.entry(k).or_insert(0) += 1;
        }
        for n in r.notes {
            let note = self.note(n);
            self.notes.push_back(note);
        }
        let (load_n, extension_m) = self.load_at(r.time_s);
        self.coverage.count(r.time_s);
        let rec = AeRecord {
            kind: crate::model::RecordKind::Hit,
            experiment: self.experiment.clone(),
            channel: f.channel,
            hit: f.hit,
            time_s: r.time_s,
            sample_rate_hz: r.rate,
            pretrigger: self.pretrigger,
            samples: r
                .samples
                .into_iter()
                .map(|v| (v * self.gain) as f32)
                .collect(),
            load_n,
            extension_m,
            label: None,
            threshold_v: None,
            source_file: f.path.display().to_string(),
        };
        let mut out = Vec::with_capacity(2);
        if self.hit_rows {
            let h = match (row, &self.list) {
                (Some(row), Some(_)) => {
                    let mut h = self.list_hit(row, order, "matched");
                    h.channel = rec.channel;
                    h.time_s = h.time_s.or(rec.time_s);
                    (h.load_n, h.extension_m) = self.load_at(h.time_s);
                    h.transient = Some(rec.hit);
                    h
                }
                _ => {
                    self.added_hits += 1;
                    let mut h = HitRow::of_record(&rec);
                    if self.list.is_some() {
                        h.hit = order;
                        h.list_status = Some("no_list_row");
                    }
                    h
                }
            };
            out.push(Item::Hit(Box::new(h)));
        }
        out.push(Item::Record(rec));
        out
    }
}

impl Iterator for Reader {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        loop {
            if let Some(n) = self.notes.pop_front() {
                return Some(n);
            }
            let Some(step) = self.steps.next() else {
                // After the last file: the header keys no reader knows, once each, and the
                // hit rows the waveforms added to the list's.
                if let Some((key, n)) = self.unknown.pop_first() {
                    return Some(self.note(format!(
                        "AEwin header key '{key}' is not one aepipe knows: kept, not used ({n} file(s))"
                    )));
                }
                if self.done {
                    return None;
                }
                self.done = true;
                if let Some(m) = self.coverage.note(&self.experiment, "machine log") {
                    self.notes.push_back(Item::Note(Note {
                        experiment: self.experiment.clone(),
                        source_file: self.log_file.clone(),
                        message: m,
                        said: true,
                    }));
                }
                if self.hit_rows {
                    self.notes.push_back(Item::Tally(crate::model::Tally {
                        experiment: self.experiment.clone(),
                        added: [(crate::model::RecordType::Hit, self.added_hits)].into(),
                        ..Default::default()
                    }));
                }
                continue;
            };
            let items = match step {
                plan::Step::Wave { file, row, order } => self.wave(file, row, order),
                plan::Step::RowOnly { row, order } => {
                    let h = self.list_hit(row, order, "no_waveform");
                    self.coverage.count(h.time_s);
                    vec![Item::Hit(Box::new(h))]
                }
            };
            self.notes.extend(items);
        }
    }
}

/// MISTRAS AEwin waveform exports, one file per hit: an experiment is a test in a folder.
pub(crate) const FORMAT: crate::ingest::FormatSpec = crate::ingest::FormatSpec {
    name: "aewin",
    one_hit_per_file: true,
    numbered_by_place: false,
    follow: crate::ingest::Follow::Whole,
    open,
};

pub fn open(src: &Source, cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
    let mut first = Vec::new();
    let mut files: Vec<WaveFile> = src
        .files
        .iter()
        .enumerate()
        .map(|(i, p)| identify(p, i))
        .collect();
    files.sort_by_key(|f| (f.channel, f.hit, f.name_time_us));
    let mut log = MachineLog::default();
    let mut log_file = String::new();
    for c in src.companions_of(Role::MachineLog) {
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
                    ..Default::default()
                }));
                log = l;
                log_file = c.display().to_string();
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
    let gain = gain_factor(cfg.aewin.preamp_gain_db);
    let hit_list = src.companion(Role::HitList);
    let p = plan::plan(&src.id, files, hit_list, &cfg.aewin, gain);
    first.extend(p.first);
    let coverage = super::Coverage::new(&log.load_n, cfg.aewin.log_time_offset_s);
    Box::new(first.into_iter().chain(Reader {
        coverage,
        log_file,
        experiment: src.id.clone(),
        steps: p.steps.into_iter(),
        list: p.list,
        hit_rows: hit_list.is_some(),
        added_hits: 0,
        last_channel: 1,
        rate: p.rate_hz,
        pretrigger: cfg.aewin.pretrigger_samples,
        gain,
        log,
        offset_s: cfg.aewin.log_time_offset_s,
        notes: Default::default(),
        unknown: Default::default(),
        done: false,
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
}
