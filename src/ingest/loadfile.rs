//! The test machine's own load file (`[load]` in the pipeline TOML): a delimited text export
//! of an MTS, Zwick or Instron frame that logs on its own clock beside the AE files.
//!
//! The reader finds the layout itself: a UTF-8 or UTF-16 byte-order mark, the separator
//! (`;`, tab, `,` or `|`, the one that splits the most lines into the same number of
//! cells), quoted cells, a decimal comma, lines before the header (specimen data), a units
//! line under it. Each hit and record gets the load and extension interpolated at its time
//! (null outside the file's span, counted in a note); the file's rows become
//! `parametric.parquet` rows. A missing or unreadable file is a note, never a lost hit.

use super::{Source, TimeSeries};
use crate::ingest::settings::{ColumnRef, LoadConfig};
use crate::model::{Item, Note, ParametricRow, ParametricSource, RecordType, Reject, Stage, Tally};
use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};

/// Why a load file cannot be used (one line).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct LoadFileError(pub String);

impl From<String> for LoadFileError {
    fn from(s: String) -> Self {
        LoadFileError(s)
    }
}

impl From<&str> for LoadFileError {
    fn from(s: &str) -> Self {
        LoadFileError(s.to_string())
    }
}

/// A delimited table as read: header, optional units line, and the data lines' cells.
#[derive(Debug, Clone, PartialEq)]
pub struct Delimited {
    pub separator: u8,
    pub header: Vec<String>,
    pub units: Option<Vec<String>>,
    /// (1-based line number, cells) of every line after the header (and units).
    pub rows: Vec<(usize, Vec<String>)>,
}

/// Decode the file's bytes as text, honouring a UTF-8 or UTF-16 byte-order mark.
fn decode_text(bytes: &[u8]) -> String {
    match bytes {
        [0xEF, 0xBB, 0xBF, rest @ ..] => String::from_utf8_lossy(rest).into_owned(),
        [0xFF, 0xFE, rest @ ..] => String::from_utf16_lossy(
            &rest
                .chunks_exact(2)
                .map(|c| u16::from_le_bytes([c[0], c[1]]))
                .collect::<Vec<_>>(),
        ),
        [0xFE, 0xFF, rest @ ..] => String::from_utf16_lossy(
            &rest
                .chunks_exact(2)
                .map(|c| u16::from_be_bytes([c[0], c[1]]))
                .collect::<Vec<_>>(),
        ),
        _ => String::from_utf8_lossy(bytes).into_owned(),
    }
}

/// Split one line on `sep`, honouring double quotes (`""` inside quotes is a quote).
fn split_line(line: &str, sep: char) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '"' if quoted && chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            '"' => quoted = !quoted,
            c if c == sep && !quoted => out.push(std::mem::take(&mut cur)),
            c => cur.push(c),
        }
    }
    out.push(cur);
    out.into_iter().map(|c| c.trim().to_string()).collect()
}

/// A number as a test machine writes it: `1.5`, `1,5` (decimal comma), `1.5e3`, `-0,25`.
pub fn parse_number(s: &str) -> Option<f64> {
    let t = s.trim();
    if t.is_empty() {
        return None;
    }
    if let Ok(v) = t.parse::<f64>() {
        return v.is_finite().then_some(v);
    }
    if t.matches(',').count() == 1 && !t.contains('.') {
        return t
            .replace(',', ".")
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite());
    }
    None
}

/// The separator that splits the most of the first lines into one count (≥ 2) of cells.
fn detect_separator(lines: &[&str]) -> Option<char> {
    let sample: Vec<&str> = lines
        .iter()
        .filter(|l| !l.trim().is_empty())
        .take(40)
        .copied()
        .collect();
    let mut best: Option<(usize, usize, char)> = None;
    for sep in [';', '\t', ',', '|'] {
        let mut by_count: BTreeMap<usize, usize> = BTreeMap::new();
        for l in &sample {
            let n = split_line(l, sep).len();
            if n >= 2 {
                *by_count.entry(n).or_default() += 1;
            }
        }
        // The most common cell count, and how many lines have it.
        if let Some((&cells, &lines)) = by_count.iter().max_by_key(|(c, n)| (**n, **c)) {
            let key = (lines, cells, sep);
            if best.is_none_or(|b| (key.0, key.1) > (b.0, b.1)) {
                best = Some(key);
            }
        }
    }
    best.map(|b| b.2)
}

/// A units line: every non-empty cell a bracketed unit (`(s)`, `[mm]`) or a unit token.
fn is_units(cells: &[String]) -> bool {
    const UNITS: [&str; 24] = [
        "s", "sec", "ms", "min", "h", "mm", "m", "µm", "um", "in", "n", "kn", "lbf", "kgf", "mpa",
        "pa", "%", "v", "mv", "-", "mm/min", "n/mm²", "n/mm2", "°c",
    ];
    let mut any = false;
    for c in cells.iter().map(|c| c.trim()).filter(|c| !c.is_empty()) {
        any = true;
        let bracketed =
            (c.starts_with('(') && c.ends_with(')')) || (c.starts_with('[') && c.ends_with(']'));
        if !bracketed && !UNITS.contains(&c.to_lowercase().as_str()) {
            return false;
        }
    }
    any
}

fn is_data(cells: &[String]) -> bool {
    cells.iter().filter(|c| parse_number(c).is_some()).count() * 2 > cells.len()
}

/// Read a delimited table: the header is the last non-numeric line before the first data
/// line (lines before it, e.g. specimen data, are passed over); a non-numeric line right
/// under the header is its units line.
pub fn read_delimited(path: &Path) -> Result<Delimited, LoadFileError> {
    let bytes = std::fs::read(path).map_err(|e| LoadFileError(format!("cannot read: {e}")))?;
    let text = decode_text(&bytes);
    let lines: Vec<&str> = text.lines().collect();
    let sep = detect_separator(&lines)
        .ok_or("no line splits into two or more cells on ; tab , or |: not a delimited table")?;
    let cells: Vec<(usize, Vec<String>)> = lines
        .iter()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| (i + 1, split_line(l, sep)))
        .collect();
    let first_data = cells
        .iter()
        .position(|(_, c)| c.len() >= 2 && is_data(c))
        .ok_or("no data line (a line of numbers)")?;
    // The header: the last line of ≥ 2 cells above the first data line, unless that line is
    // a units line (then the one above it).
    let above: Vec<usize> = (0..first_data).filter(|&i| cells[i].1.len() >= 2).collect();
    let (header_i, units_i) = match above.as_slice() {
        [] => return Err("no header line above the first data line".into()),
        [.., h, u] if is_units(&cells[*u].1) => (*h, Some(*u)),
        [.., h] => (*h, None),
    };
    Ok(Delimited {
        separator: sep as u8,
        header: cells[header_i].1.clone(),
        units: units_i.map(|u| cells[u].1.clone()),
        rows: cells[first_data..].to_vec(),
    })
}

impl Delimited {
    /// The 0-based index of a column, or why there is none.
    pub fn column(&self, c: &ColumnRef) -> Result<usize, LoadFileError> {
        match c {
            ColumnRef::Index(i) if *i >= 1 && *i <= self.header.len() => Ok(i - 1),
            ColumnRef::Index(i) => Err(LoadFileError(format!(
                "column {i}: the header has {} columns",
                self.header.len()
            ))),
            ColumnRef::Name(n) => self
                .header
                .iter()
                .position(|h| h.trim() == n.trim())
                .ok_or_else(|| {
                    LoadFileError(format!("no column {n:?} in the header {:?}", self.header))
                }),
        }
    }
}

/// The load file of a source, its path resolved (`{experiment}`, `{stem}`, relative to the
/// folder holding the experiment's recordings).
pub fn path_for(src: &Source, cfg: &LoadConfig) -> Option<PathBuf> {
    let file = cfg.file.as_ref()?;
    let first = src.all_files().next()?;
    let dir = first.parent().map(Path::to_path_buf).unwrap_or_default();
    let stem = if src.format == super::Format::VallenTxt {
        src.id.clone()
    } else if src.format.one_hit_per_file() {
        dir.file_name()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default()
    } else if src.format == super::Format::Mistras {
        super::dta::chain_key(first).0
    } else {
        first
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default()
    };
    let rel = file
        .to_string_lossy()
        .replace("{experiment}", &src.id)
        .replace("{stem}", &stem);
    let p = PathBuf::from(rel);
    Some(if p.is_absolute() { p } else { dir.join(p) })
}

/// Load and extension of one load file on the AE clock, and its rows.
pub struct LoadSeries {
    pub load_n: TimeSeries,
    pub extension_m: TimeSeries,
    pub rows: Vec<ParametricRow>,
    /// Lines that are not rows of numbers (with why), after the header.
    pub bad: Vec<(usize, String)>,
}

/// Read `path` as `cfg` says, for `experiment` (whose `offset_s` applies).
pub fn read_series(
    path: &Path,
    experiment: &str,
    cfg: &LoadConfig,
) -> Result<LoadSeries, LoadFileError> {
    let t = read_delimited(path)?;
    let ti = t.column(&cfg.time_column)?;
    let li = t.column(&cfg.load_column)?;
    let ei = cfg
        .extension_column
        .as_ref()
        .map(|c| t.column(c))
        .transpose()?;
    let offset = cfg.offset_s.get(experiment).copied().unwrap_or(0.0);
    let file = path.display().to_string();
    let (mut rows, mut bad) = (Vec::new(), Vec::new());
    let (mut lp, mut ep) = (Vec::new(), Vec::new());
    for (line, cells) in &t.rows {
        let cell = |i: usize| cells.get(i).map(String::as_str).unwrap_or("");
        let (Some(time), Some(load)) = (parse_number(cell(ti)), parse_number(cell(li))) else {
            bad.push((
                *line,
                format!(
                    "time {:?} and load {:?} are not both numbers",
                    cell(ti),
                    cell(li)
                ),
            ));
            continue;
        };
        let t_ae = time * cfg.time_scale_s + offset;
        let load_n = load * cfg.load_scale_n;
        let ext = ei
            .and_then(|i| parse_number(cell(i)))
            .map(|v| v * cfg.extension_scale_m);
        lp.push((t_ae, load_n));
        if let Some(e) = ext {
            ep.push((t_ae, e));
        }
        let inputs: serde_json::Map<String, serde_json::Value> = t
            .header
            .iter()
            .zip(cells)
            .filter_map(|(h, c)| parse_number(c).map(|v| (h.clone(), serde_json::json!(v))))
            .collect();
        rows.push(ParametricRow {
            experiment: experiment.to_string(),
            row: rows.len() as u64 + 1,
            time_s: Some(t_ae),
            load_n: Some(load_n),
            extension_m: ext,
            inputs: Some(serde_json::Value::Object(inputs).to_string()),
            extra: None,
            source: ParametricSource::LoadFile,
            source_file: file.clone(),
        });
    }
    if rows.is_empty() {
        return Err("no row with a numeric time and load".into());
    }
    Ok(LoadSeries {
        load_n: TimeSeries::from_pairs(lp),
        extension_m: TimeSeries::from_pairs(ep),
        rows,
        bad,
    })
}

/// Wraps a source's items: the load file's rows first, then every hit and record with the
/// load and extension at its time, then the notes.
struct WithLoad {
    inner: Box<dyn Iterator<Item = Item> + Send>,
    series: Option<(TimeSeries, TimeSeries)>,
    front: VecDeque<Item>,
    experiment: String,
    file: String,
    /// Hits / records outside the file's time span, or without a time.
    outside: (u64, u64),
    untimed: (u64, u64),
    /// The hits the file's span covers, said on the terminal when it misses some.
    coverage: super::Coverage,
    ended: bool,
}

impl WithLoad {
    fn at(&self, t: Option<f64>) -> Option<(Option<f64>, Option<f64>)> {
        let (l, e) = self.series.as_ref()?;
        Some(t.map_or((None, None), |t| (l.at(t), e.at(t))))
    }
}

impl Iterator for WithLoad {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        if let Some(it) = self.front.pop_front() {
            return Some(it);
        }
        match self.inner.next() {
            Some(Item::Hit(mut h)) => {
                self.coverage.count(h.time_s);
                if let Some((l, e)) = self.at(h.time_s) {
                    match h.time_s {
                        None => self.untimed.0 += 1,
                        Some(_) if l.is_none() => self.outside.0 += 1,
                        _ => {}
                    }
                    (h.load_n, h.extension_m) = (l, e);
                }
                Some(Item::Hit(h))
            }
            Some(Item::Record(mut r)) => {
                if let Some((l, e)) = self.at(r.time_s) {
                    match r.time_s {
                        None => self.untimed.1 += 1,
                        Some(_) if l.is_none() => self.outside.1 += 1,
                        _ => {}
                    }
                    (r.load_n, r.extension_m) = (l, e);
                }
                Some(Item::Record(r))
            }
            Some(other) => Some(other),
            None if !self.ended => {
                self.ended = true;
                let note = |what: &str, (h, r): (u64, u64)| {
                    (h + r > 0).then(|| {
                        Item::Note(Note {
        said: false,
                            experiment: self.experiment.clone(),
                            source_file: self.file.clone(),
                            message: format!(
                                "load file: {h} hit(s) and {r} record(s) {what}: load and extension null"
                            ),
                        })
                    })
                };
                let said = self.coverage.note(&self.experiment, "load file").map(|m| {
                    Item::Note(Note {
                        experiment: self.experiment.clone(),
                        source_file: self.file.clone(),
                        message: m,
                        said: true,
                    })
                });
                let mut v: VecDeque<Item> = [
                    said,
                    note("outside its time span", self.outside),
                    note("without a time", self.untimed),
                ]
                .into_iter()
                .flatten()
                .collect();
                let first = v.pop_front();
                self.front = v;
                first
            }
            None => None,
        }
    }
}

/// Give a source's items the load file's load and extension (when `[load] file` is set).
pub fn attach(
    items: Box<dyn Iterator<Item = Item> + Send>,
    src: &Source,
    cfg: &LoadConfig,
) -> Box<dyn Iterator<Item = Item> + Send> {
    let Some(path) = path_for(src, cfg) else {
        return items;
    };
    let file = path.display().to_string();
    let note = |message: String| {
        Item::Note(Note {
            said: false,
            experiment: src.id.clone(),
            source_file: file.clone(),
            message,
        })
    };
    let mut front = VecDeque::new();
    let series = match read_series(&path, &src.id, cfg) {
        Ok(s) => {
            let mut read = BTreeMap::new();
            read.insert(RecordType::Parametric, (s.rows.len() + s.bad.len()) as u64);
            front.push_back(note(format!(
                "load and extension from the load file ({} rows, {:.3}–{:.3} s on the AE clock)",
                s.rows.len(),
                s.load_n.t.first().copied().unwrap_or(0.0),
                s.load_n.t.last().copied().unwrap_or(0.0)
            )));
            front.extend(s.rows.into_iter().map(|r| Item::Parametric(Box::new(r))));
            front.extend(s.bad.into_iter().map(|(line, why)| {
                Item::Reject(Reject {
                    record_type: RecordType::Parametric,
                    experiment: src.id.clone(),
                    source_file: file.clone(),
                    record_id: format!("line {line}"),
                    stage: Stage::Read,
                    reason: why,
                })
            }));
            front.push_back(Item::Tally(Tally {
                experiment: src.id.clone(),
                read,
                ..Default::default()
            }));
            Some((s.load_n, s.extension_m))
        }
        Err(e) => {
            front.push_back(note(format!(
                "load file not used: {e}; the hits keep the load of the recording itself (if any)"
            )));
            None
        }
    };
    let coverage = series
        .as_ref()
        .map(|(l, _)| super::Coverage::new(l, 0.0))
        .unwrap_or_default();
    Box::new(WithLoad {
        inner: items,
        coverage,
        series,
        front,
        experiment: src.id.clone(),
        file,
        outside: (0, 0),
        untimed: (0, 0),
        ended: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_as_test_machines_write_them() {
        assert_eq!(parse_number("1,5"), Some(1.5));
        assert_eq!(parse_number(" -0,25 "), Some(-0.25));
        assert_eq!(parse_number("1.5e3"), Some(1500.0));
        assert_eq!(parse_number("1,234.5"), None);
        assert_eq!(parse_number("kN"), None);
        assert_eq!(parse_number("NaN"), None);
    }

    #[test]
    fn quoted_cells_keep_their_separators() {
        assert_eq!(
            split_line("\"Time; s\";\"1,5\";2", ';'),
            vec!["Time; s", "1,5", "2"]
        );
        assert_eq!(split_line("\"a\"\"b\",c", ','), vec!["a\"b", "c"]);
    }
}
