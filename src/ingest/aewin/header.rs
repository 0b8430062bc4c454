//! The header of an AEwin waveform ASCII export: `KEY: value` lines, a blank line, then one
//! value per line. Two variants are known; their keys may come in any order:
//!
//! * `SOURCE FILE NAME`, `DATE`, `TIME`, `SAMPLE INTERVAL (Seconds)`, `UNITS`,
//!   `CHANNEL NUMBER`, `HIT NUMBER`, `TIME OF TEST`;
//! * `SOURCE FILE NAME`, `DATE`, `TIME`, `SAMPLE INTERVAL (Seconds)`, `SIGNAL UNITS`,
//!   `TIME UNITS`, `DATA TYPE`, `NUMBER OF DATA POINTS PER WAVEFORM`, `CHANNEL NUMBER`,
//!   `HIT NUMBER`, `TIME OF TEST`.
//!
//! A key aepipe does not know is kept (named in a manifest note), never a reason to refuse
//! the file.

use crate::ingest::sniff::seconds_per;
use crate::ingest::RecordError;

/// What the header says. `None` where a key is absent.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Header {
    pub source_file: Option<String>,
    /// Seconds between samples, in the unit the key names (`(Seconds)` when none).
    pub sample_interval_s: Option<f64>,
    /// `UNITS` or `SIGNAL UNITS`, as written.
    pub signal_units: Option<String>,
    /// `TIME UNITS`, as written: the unit of `TIME OF TEST`.
    pub time_units: Option<String>,
    pub data_type: Option<String>,
    pub points: Option<u64>,
    pub channel: Option<u32>,
    pub hit: Option<u64>,
    /// `TIME OF TEST` as written (seconds, or `h:mm:ss.ffff`).
    pub time_of_test: Option<String>,
    /// Keys aepipe does not know, as written.
    pub unknown: Vec<String>,
    /// Known keys found.
    pub known: usize,
    /// Lines the header takes (its key lines and the blank lines around them).
    pub lines: usize,
    /// A known key whose value could not be read: (key, value).
    pub unreadable: Vec<(String, String)>,
}

/// Known keys, normalised (upper case, single spaces, no unit in parentheses).
const KNOWN: &[&str] = &[
    "SOURCE FILE NAME",
    "DATE",
    "TIME",
    "SAMPLE INTERVAL",
    "UNITS",
    "SIGNAL UNITS",
    "TIME UNITS",
    "DATA TYPE",
    "NUMBER OF DATA POINTS PER WAVEFORM",
    "CHANNEL NUMBER",
    "HIT NUMBER",
    "TIME OF TEST",
];

/// `SAMPLE INTERVAL (Seconds)` → (`SAMPLE INTERVAL`, Some(`Seconds`)).
fn split_key(raw: &str) -> (String, Option<String>) {
    let (name, unit) = match raw.find('(') {
        Some(i) => (
            &raw[..i],
            Some(raw[i + 1..].trim_end_matches(')').trim().to_string()),
        ),
        None => (raw, None),
    };
    (
        name.split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
            .to_uppercase(),
        unit,
    )
}

/// A header line: `KEY: value` where KEY starts with a letter and is no number.
fn key_line(line: &str) -> Option<(&str, &str)> {
    let (k, v) = line.split_once(':')?;
    let k = k.trim();
    (k.chars().next()?.is_ascii_alphabetic()
        && k.chars()
            .all(|c| c.is_alphanumeric() || " ()_-/.#".contains(c)))
    .then_some((k, v.trim()))
}

/// The header at the start of `text`, or `None` when the text does not start with a
/// `KEY: value` line.
pub fn parse(text: &str) -> Option<Header> {
    let mut h = Header::default();
    let mut started = false;
    for line in text.split('\n') {
        let t = line.trim();
        if t.is_empty() {
            h.lines += 1;
            if started {
                break;
            }
            continue;
        }
        let Some((raw, value)) = key_line(t) else {
            break;
        };
        started = true;
        h.lines += 1;
        let (key, unit) = split_key(raw);
        if !KNOWN.contains(&key.as_str()) {
            h.unknown.push(raw.to_string());
            continue;
        }
        h.known += 1;
        let v = value.to_string();
        let mut bad = false;
        match key.as_str() {
            "SOURCE FILE NAME" => h.source_file = Some(v),
            "SAMPLE INTERVAL" => {
                let scale = unit.as_deref().map_or(Some(1.0), seconds_per);
                match (value.parse::<f64>().ok(), scale) {
                    (Some(x), Some(s)) if x > 0.0 && x.is_finite() => {
                        h.sample_interval_s = Some(x * s)
                    }
                    _ => bad = true,
                }
            }
            "UNITS" | "SIGNAL UNITS" => h.signal_units = Some(v),
            "TIME UNITS" => h.time_units = Some(v),
            "DATA TYPE" => h.data_type = Some(v),
            "NUMBER OF DATA POINTS PER WAVEFORM" => match value.parse() {
                Ok(n) => h.points = Some(n),
                Err(_) => bad = true,
            },
            "CHANNEL NUMBER" => match value.parse() {
                Ok(n) => h.channel = Some(n),
                Err(_) => bad = true,
            },
            "HIT NUMBER" => match value.parse() {
                Ok(n) => h.hit = Some(n),
                Err(_) => bad = true,
            },
            "TIME OF TEST" => h.time_of_test = Some(v),
            _ => {} // DATE, TIME: the wall clock, not used
        }
        if bad {
            h.unreadable.push((raw.to_string(), value.to_string()));
        }
    }
    started.then_some(h)
}

impl Header {
    /// An AEwin header: at least two of its keys.
    pub fn is_aewin(&self) -> bool {
        self.known >= 2
    }

    /// `TIME OF TEST` in seconds on the test's clock: a number in `TIME UNITS` (seconds
    /// when absent), or `h:mm:ss.ffff`.
    pub fn time_of_test_s(&self) -> Result<Option<f64>, RecordError> {
        self.time_of_test().map_err(RecordError)
    }

    fn time_of_test(&self) -> Result<Option<f64>, String> {
        let Some(t) = self.time_of_test.as_deref() else {
            return Ok(None);
        };
        let scale = match self.time_units.as_deref() {
            None => 1.0,
            Some(u) => {
                seconds_per(u).ok_or_else(|| format!("TIME UNITS '{u}' is not a time unit"))?
            }
        };
        if let Ok(x) = t.parse::<f64>() {
            return Ok(Some(x * scale));
        }
        let parts: Vec<&str> = t.split(':').collect();
        if (2..=3).contains(&parts.len()) {
            let mut s = 0.0;
            for (i, p) in parts.iter().enumerate() {
                let x: f64 = p
                    .trim()
                    .parse()
                    .map_err(|_| format!("TIME OF TEST '{t}' is not a time"))?;
                let last = i + 1 == parts.len();
                if x < 0.0 || (!last && x.fract() != 0.0) {
                    return Err(format!("TIME OF TEST '{t}' is not a time"));
                }
                s = s * 60.0 + x;
            }
            return Ok(Some(s));
        }
        Err(format!("TIME OF TEST '{t}' is not a time"))
    }

    /// The signal unit is volts (or absent): else the reason the file is refused.
    pub fn check_units(&self) -> Result<(), RecordError> {
        match self.signal_units.as_deref() {
            None => Ok(()),
            Some(u) if matches!(u.trim().to_lowercase().as_str(), "v" | "volt" | "volts") => Ok(()),
            Some(u) => Err(RecordError(format!(
                "signal unit '{u}' is not volts (aepipe reads AEwin exports in volts)"
            ))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_variants_in_any_order_with_an_unknown_key() {
        let a = "SOURCE FILE NAME: C:\\AE\\PLB.DTA\r\nDATE: Friday, March 13, 2015\r\nTIME: 10:30:12\r\nSAMPLE INTERVAL (Seconds): 2.000000E-07\r\nUNITS: Volts\r\nCHANNEL NUMBER: 3\r\nHIT NUMBER: 17\r\nTIME OF TEST: 12.3456789\r\n\r\n 0.00305176\r\n";
        let h = parse(a).unwrap();
        assert_eq!(h.sample_interval_s, Some(2e-7));
        assert_eq!((h.channel, h.hit), (Some(3), Some(17)));
        assert_eq!(h.time_of_test_s(), Ok(Some(12.3456789)));
        assert_eq!(h.source_file.as_deref(), Some("C:\\AE\\PLB.DTA"));
        assert_eq!((h.known, h.lines), (8, 9));
        assert!(h.check_units().is_ok());
        let b = "HIT NUMBER: 2\nTIME UNITS: Microseconds\nNUMBER OF DATA POINTS PER WAVEFORM: 1024\nLAB NOTE: aged\nSIGNAL UNITS: mV\nDATA TYPE: Float\nCHANNEL NUMBER: 1\nTIME OF TEST: 1500\nSAMPLE INTERVAL (µs): 0.1\n\n1\n";
        let h = parse(b).unwrap();
        assert_eq!(h.points, Some(1024));
        assert_eq!(h.unknown, ["LAB NOTE"]);
        assert!((h.sample_interval_s.unwrap() - 1e-7).abs() < 1e-20);
        assert_eq!(h.time_of_test_s(), Ok(Some(1500e-6)));
        assert!(h.check_units().unwrap_err().0.contains("'mV'"));
        // h:mm:ss
        let h = parse("TIME OF TEST: 0:01:02.5\nHIT NUMBER: 1\n\n0\n").unwrap();
        assert_eq!(h.time_of_test_s(), Ok(Some(62.5)));
        // Header-less values and a first value line are no header.
        assert_eq!(parse(" 0.003\n0.004\n"), None);
        assert_eq!(parse("\n\n-1e-3\n"), None);
        // A number that is not a number is said, not taken.
        let h = parse("SAMPLE INTERVAL (Seconds): fast\nHIT NUMBER: x\n\n0\n").unwrap();
        assert_eq!(h.sample_interval_s, None);
        assert_eq!(h.unreadable.len(), 2);
    }
}
