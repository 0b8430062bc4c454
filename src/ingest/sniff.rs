//! Telling a text file's format by what it holds.
//!
//! Discovery reads a text file's first kilobytes once ([`Head`]) and asks every text reader
//! whether the file is its own (each reader module declares its [`Recogniser`] next to its
//! code, so the next export variant is that reader's business; discovery lists them). A
//! reader answers with a [`Verdict`]: the file is its own, with a [`Strength`] (a
//! signature no other format writes beats a generic shape such as "one number per line"),
//! or it resembles its format but something is missing (said in words, with what would
//! read it), or no. The file's name only breaks ties between equally strong claims (an
//! AEwin name `<test>_<ch>_<hit>_<time>` over a plain extension, `.csv` over `.txt` for a
//! column of numbers). `[ingest] format` forces a format: that format's readers are asked
//! first, and take a file they do not recognise where they can read it and say what is wrong.
//!
//! A file no reader claims is passed over with one line saying what it saw (first line,
//! columns, numeric lines), what it resembles and which format or `[ingest]` keys would
//! read it; `aepipe inspect` prints the same line the manifest keeps.

use crate::ingest::settings::FormatChoice;
use std::path::Path;

/// How much of a file the sniffer reads.
pub(crate) const HEAD_BYTES: usize = 4096;

/// Extensions of the text formats: only these are sniffed (binary formats are told by
/// their extension and magic bytes).
pub(crate) const TEXT_EXTENSIONS: &[&str] = &["csv", "txt", "dat", "tsv", "asc"];

/// Read up to `n` bytes of the head of a file as text (lossy).
pub(crate) fn head(p: &Path, n: usize) -> std::io::Result<String> {
    use std::io::Read;
    let mut f = std::fs::File::open(p)?;
    let mut buf = vec![0u8; n];
    let mut got = 0;
    while got < n {
        let k = f.read(&mut buf[got..])?;
        if k == 0 {
            break;
        }
        got += k;
    }
    buf.truncate(got);
    Ok(String::from_utf8_lossy(&buf).into_owned())
}

/// The first kilobytes of a file, as text.
#[derive(Debug, Clone)]
pub(crate) struct Head {
    /// The file name.
    pub name: String,
    /// Its extension, lower case.
    pub ext: String,
    /// The head, decoded lossily, without a byte-order mark.
    pub text: String,
    /// The head holds a NUL byte: binary data, not text.
    pub binary: bool,
    /// The file is longer than the head (its last line may be cut).
    pub cut: bool,
}

impl Head {
    pub fn read(p: &Path) -> std::io::Result<Head> {
        use std::io::Read;
        let mut f = std::fs::File::open(p)?;
        let mut buf = vec![0u8; HEAD_BYTES + 1];
        let mut got = 0;
        while got < buf.len() {
            let k = f.read(&mut buf[got..])?;
            if k == 0 {
                break;
            }
            got += k;
        }
        let cut = got > HEAD_BYTES;
        buf.truncate(got.min(HEAD_BYTES));
        Ok(Head::of_bytes(p, &buf, cut))
    }

    pub fn of_bytes(p: &Path, bytes: &[u8], cut: bool) -> Head {
        let text = String::from_utf8_lossy(bytes);
        Head {
            name: p
                .file_name()
                .map(|n| n.to_string_lossy().to_string())
                .unwrap_or_default(),
            ext: p
                .extension()
                .map(|e| e.to_string_lossy().to_lowercase())
                .unwrap_or_default(),
            text: text.trim_start_matches('\u{feff}').to_string(),
            binary: bytes.contains(&0),
            cut,
        }
    }

    /// The head's lines, line ends (LF, CRLF, CR CR LF) and trailing blanks removed; the
    /// last line dropped when the head cuts it.
    pub fn lines(&self) -> impl Iterator<Item = &str> {
        let mut all: Vec<&str> = self.text.split('\n').collect();
        if self.cut && all.len() > 1 {
            all.pop();
        }
        all.into_iter().map(|l| l.trim_end())
    }

    /// The non-empty lines, trimmed.
    pub fn filled_lines(&self) -> impl Iterator<Item = &str> {
        self.lines().map(str::trim).filter(|l| !l.is_empty())
    }

    pub fn first_line(&self) -> &str {
        self.filled_lines().next().unwrap_or("")
    }

    pub fn is_empty(&self) -> bool {
        self.text.trim().is_empty()
    }
}

/// Cells of a data line: split by tab, `;`, `,` or runs of spaces, empty cells at the end
/// (a trailing tab) dropped.
pub(crate) fn cells(line: &str) -> Vec<&str> {
    let line = line.trim();
    let mut v: Vec<&str> = if line.contains('\t') {
        line.split('\t').map(str::trim).collect()
    } else if line.contains(';') {
        line.split(';').map(str::trim).collect()
    } else if line.contains(',') {
        line.split(',').map(str::trim).collect()
    } else {
        line.split_whitespace().collect()
    };
    while v.last().is_some_and(|c| c.is_empty()) {
        v.pop();
    }
    v
}

/// How sure a reader is that a file is its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Strength {
    /// Only the file's name says so.
    Name,
    /// A generic shape other formats share (one number per line; a CSV value column).
    Shape,
    /// A signature only this format writes (a header line or keys of its own).
    Signature,
}

/// What one text file is, as discovery groups it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Kind {
    CsvPerHit,
    CsvLong,
    MachineLog,
    AewinHitList,
    /// An AEwin waveform file; `test`: the test it belongs to (its name before
    /// `_<ch>_<hit>_<time>`, else its header's source file), `None`: its folder's.
    AewinWave {
        test: Option<String>,
    },
    WaveExplorer,
    /// A Vallen TXT export of one transient; `datafile`: the database it came from (stem).
    VallenTxt {
        datafile: String,
    },
    Text,
}

/// A reader's answer about one file.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Verdict {
    /// The file is the reader's. `name`: how well its name fits the reader (0: not at
    /// all; 1: the extension; 2: a naming scheme of the format's own); it breaks ties.
    Mine {
        kind: Kind,
        strength: Strength,
        name: u8,
    },
    /// The file resembles the reader's format but cannot be read as it is: what it
    /// resembles, what is missing, and what would read it.
    Near(String),
    No,
}

impl Verdict {
    pub fn mine(kind: Kind, strength: Strength, name: u8) -> Verdict {
        Verdict::Mine {
            kind,
            strength,
            name,
        }
    }
}

/// One text reader's recogniser.
pub(crate) struct Recogniser {
    /// What it reads, in the words `aepipe inspect` uses.
    pub what: &'static str,
    /// The `[ingest] format` that is this reader's.
    pub format: FormatChoice,
    pub recognise: fn(&Head) -> Verdict,
    /// Under `[ingest] format` = [`Self::format`]: the kind a file it does not recognise is
    /// read as, when its reader can read it or say what is wrong with it.
    pub forced: fn(&Head) -> Option<Kind>,
}

/// Never a forced reading.
pub(crate) fn never(_: &Head) -> Option<Kind> {
    None
}

/// Why no text reader takes a file: the one line the manifest and `aepipe inspect` show.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub(crate) struct PassedOver(pub String);

/// A text file's kind as `readers` (in the order that breaks a tie no name breaks) tell
/// it, or the line that says why none takes it.
pub(crate) fn sniff(
    readers: &[&Recogniser],
    head: &Head,
    forced: FormatChoice,
) -> Result<Kind, PassedOver> {
    sniff_with(readers, head, forced).map_err(PassedOver)
}

fn sniff_with(readers: &[&Recogniser], head: &Head, forced: FormatChoice) -> Result<Kind, String> {
    if head.binary {
        return Err(format!(
            "binary data, not text ({})",
            describe(head).unwrap_or_default()
        ));
    }
    let verdicts: Vec<Verdict> = readers.iter().map(|r| (r.recognise)(head)).collect();
    if forced != FormatChoice::Auto {
        let own = || {
            readers
                .iter()
                .zip(&verdicts)
                .filter(|(r, _)| r.format == forced)
        };
        if let Some(kind) = best(own().map(|(_, v)| v)) {
            return Ok(kind);
        }
        if let Some(kind) = own().find_map(|(r, _)| (r.forced)(head)) {
            return Ok(kind);
        }
    }
    if let Some(kind) = best(verdicts.iter()) {
        return Ok(kind);
    }
    if head.is_empty() {
        return Err("empty file".into());
    }
    let seen = describe(head).unwrap_or_default();
    let near: Vec<&str> = verdicts
        .iter()
        .filter_map(|v| match v {
            Verdict::Near(s) => Some(s.as_str()),
            _ => None,
        })
        .collect();
    Err(if near.is_empty() {
        format!(
            "text that is no format aepipe reads ({seen}); it reads {}",
            readers
                .iter()
                .map(|r| r.what)
                .collect::<Vec<_>>()
                .join("; ")
        )
    } else {
        format!("{} ({seen})", near.join("; "))
    })
}

/// The strongest claim; the name breaks ties, then the readers' order.
fn best<'a>(verdicts: impl Iterator<Item = &'a Verdict>) -> Option<Kind> {
    let mut top: Option<(Strength, u8, &Kind)> = None;
    for v in verdicts {
        if let Verdict::Mine {
            kind,
            strength,
            name,
        } = v
        {
            if top.is_none_or(|(s, n, _)| (*strength, *name) > (s, n)) {
                top = Some((*strength, *name, kind));
            }
        }
    }
    top.map(|t| t.2.clone())
}

/// What the head shows, in a few words: its first line, its columns and how many lines are
/// numeric.
pub(crate) fn describe(head: &Head) -> Option<String> {
    if head.binary {
        return Some(format!(
            "first bytes {}",
            head.text
                .bytes()
                .take(8)
                .map(|b| format!("{b:02x}"))
                .collect::<Vec<_>>()
                .join(" ")
        ));
    }
    let lines: Vec<&str> = head.filled_lines().take(64).collect();
    let first = *lines.first()?;
    let shown: String = first.chars().take(60).collect();
    let ellipsis = if first.chars().count() > 60 {
        "…"
    } else {
        ""
    };
    let data = &lines[1.min(lines.len())..];
    let numeric = data
        .iter()
        .filter(|l| {
            let c = cells(l);
            !c.is_empty() && c.iter().all(|x| parse_number(x).is_some())
        })
        .count();
    let mut widths: Vec<usize> = data.iter().map(|l| cells(l).len()).collect();
    widths.sort_unstable();
    widths.dedup();
    let sep = if first.contains('\t') {
        "tab-separated "
    } else if first.contains(';') {
        "semicolon-separated "
    } else if first.contains(',') {
        "comma-separated "
    } else {
        ""
    };
    let columns = match (widths.as_slice(), cells(first).len()) {
        ([], n) => format!("{n} {sep}column(s)"),
        ([w], _) => format!("{w} {sep}column(s)"),
        (ws, _) => format!("{}–{} {sep}columns", ws[0], ws.last().copied().unwrap_or(0)),
    };
    Some(format!(
        "first line '{shown}{ellipsis}', {columns}, {numeric} of the next {} lines numeric",
        data.len()
    ))
}

/// Seconds per unit of a time unit as exports write it.
pub(crate) fn seconds_per(unit: &str) -> Option<f64> {
    match unit.trim().to_lowercase().as_str() {
        "s" | "sec" | "secs" | "second" | "seconds" => Some(1.0),
        "ms" | "msec" | "millisecond" | "milliseconds" => Some(1e-3),
        "us" | "µs" | "μs" | "usec" | "microsec" | "microsecond" | "microseconds" => Some(1e-6),
        "ns" | "nsec" | "nanosecond" | "nanoseconds" => Some(1e-9),
        _ => None,
    }
}

/// A number as exports write it: `1.5`, ` -0.003`, `1.2E-07`.
pub(crate) fn parse_number(s: &str) -> Option<f64> {
    s.trim().parse::<f64>().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn head(name: &str, text: &str) -> Head {
        Head::of_bytes(Path::new(name), text.as_bytes(), false)
    }

    fn mine(kind: Kind, strength: Strength, name: u8) -> Verdict {
        Verdict::mine(kind, strength, name)
    }

    static A: Recogniser = Recogniser {
        what: "A",
        format: FormatChoice::Text,
        recognise: |_| mine(Kind::Text, Strength::Shape, 1),
        forced: never,
    };
    static B: Recogniser = Recogniser {
        what: "B",
        format: FormatChoice::Aewin,
        recognise: |h| {
            if h.name.starts_with("b_") {
                mine(Kind::AewinWave { test: None }, Strength::Shape, 2)
            } else {
                mine(Kind::AewinWave { test: None }, Strength::Shape, 0)
            }
        },
        forced: never,
    };
    static C: Recogniser = Recogniser {
        what: "C",
        format: FormatChoice::Waveexplorer,
        recognise: |h| {
            if h.first_line() == "SIG" {
                mine(Kind::WaveExplorer, Strength::Signature, 0)
            } else {
                Verdict::Near("resembles C without SIG".into())
            }
        },
        forced: |_| Some(Kind::WaveExplorer),
    };

    #[test]
    fn the_strongest_claim_wins_and_the_name_breaks_ties() {
        let readers: &[&Recogniser] = &[&A, &B, &C];
        // Equal shape claims: the reader whose name fits best.
        assert_eq!(
            sniff_with(readers, &head("x.txt", "1\n2\n"), FormatChoice::Auto),
            Ok(Kind::Text)
        );
        assert_eq!(
            sniff_with(readers, &head("b_1.txt", "1\n2\n"), FormatChoice::Auto),
            Ok(Kind::AewinWave { test: None })
        );
        // A signature beats any name.
        assert_eq!(
            sniff_with(readers, &head("b_1.txt", "SIG\n2\n"), FormatChoice::Auto),
            Ok(Kind::WaveExplorer)
        );
        // A forced format asks its own readers first, then takes the file for its reader.
        assert_eq!(
            sniff_with(
                readers,
                &head("b_1.txt", "1\n2\n"),
                FormatChoice::Waveexplorer
            ),
            Ok(Kind::WaveExplorer)
        );
        assert_eq!(
            sniff_with(readers, &head("x.txt", "1\n2\n"), FormatChoice::Aewin),
            Ok(Kind::AewinWave { test: None })
        );
    }

    #[test]
    fn a_file_no_reader_takes_says_what_it_saw_and_what_it_resembles() {
        let readers: &[&Recogniser] = &[&C];
        let e = sniff_with(
            readers,
            &head("x.txt", "Event\tTime\t\r\n1\t2.5\t\r\n2\t3.5\t\r\n"),
            FormatChoice::Auto,
        )
        .unwrap_err();
        assert!(e.starts_with("resembles C without SIG ("), "{e}");
        assert!(
            e.contains("first line 'Event\tTime', 2 tab-separated column(s), 2 of the next 2 lines numeric"),
            "{e}"
        );
        let bin = Head::of_bytes(Path::new("x.dat"), b"\x00\x01\x02rest", false);
        let e = sniff_with(readers, &bin, FormatChoice::Auto).unwrap_err();
        assert!(
            e.starts_with("binary data, not text (first bytes 00 01 02"),
            "{e}"
        );
        let e = sniff_with(&[], &head("x.txt", " \n"), FormatChoice::Auto).unwrap_err();
        assert_eq!(e, "empty file");
    }

    #[test]
    fn lines_lose_every_line_end_and_a_cut_last_line() {
        let h = head("x.txt", "a\r\r\nb\r\n\nc");
        assert_eq!(h.lines().collect::<Vec<_>>(), ["a", "b", "", "c"]);
        let cut = Head::of_bytes(Path::new("x.txt"), b"1\n2\n3", true);
        assert_eq!(cut.lines().collect::<Vec<_>>(), ["1", "2"]);
        assert_eq!(cells(" 0.1\t0.2\t"), ["0.1", "0.2"]);
        assert_eq!(cells("10 63  1024 2"), ["10", "63", "1024", "2"]);
    }
}
