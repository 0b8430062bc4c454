//! MISTRAS AEwin binary `.DTA` (Appendix II of the MISTRAS/PCI-2 manuals): a stream of
//! messages `u16 LEN, u8 MID, body` (MIDs 40–49 carry one more ID byte). This module walks
//! the stream and decodes what aepipe uses:
//!
//! * setup: the hit features' CHID list (MID 5 or sub-message 5 of MID 42), the time-driven
//!   set (MID/sub 6), partial-power segments (MID/sub 109), gains (MID/sub 23), the
//!   waveform hardware (sub 173,42: sample rate, pretrigger `TDLY`), the test start (MID 99),
//!   a continuation header (MID 8);
//! * hits (MID 1): time of test (6-byte RTOT, 0.25 µs ticks), channel, the CHID-listed
//!   features, the hit's parametric values;
//! * waveforms (MID 173, sub 1): time, channel, int16 counts → volts with the channel's gain;
//! * time-driven / user-forced rows (MID 2/3): time and parametric values.
//!
//! Every other MID is skipped by its length. A length that runs past the end of the file is
//! an error (the rest of the file is not guessed at), as is a feature whose CHID has no
//! known size. Nothing is allocated from a size read in the file beyond one message
//! (≤ 64 KiB).

use std::collections::BTreeMap;
use std::io::Read;

/// One RTOT tick, seconds.
pub const TICK_S: f64 = 0.25e-6;
/// Full scale of the waveform ADC, volts (MistrasDTA and the manual: ±10 V over ±32768).
pub const MAX_INPUT_V: f64 = 10.0;

/// What went wrong at a byte offset of the file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DtaError {
    #[error(
        "byte {offset}: message of {len} bytes runs past the end of the file ({left} bytes left)"
    )]
    Truncated { offset: u64, len: usize, left: u64 },
    #[error("byte {offset}: MID {mid}: {why}")]
    Malformed { offset: u64, mid: u8, why: String },
    #[error("read error: {0}")]
    Io(String),
}

/// A hit feature: the CHID, the vendor's name and its value in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feature {
    pub chid: u8,
    pub value: f64,
}

/// An AE hit (MID 1).
#[derive(Debug, Clone, PartialEq)]
pub struct DtaHit {
    /// Time of test in 0.25 µs ticks (the pairing key with waveforms, with the channel).
    pub ticks: u64,
    pub channel: u8,
    pub features: Vec<Feature>,
    /// Hit parametric inputs: (PID, volts).
    pub params: Vec<(u8, f64)>,
}

/// A waveform (MID 173, sub 1).
#[derive(Debug, Clone, PartialEq)]
pub struct DtaWave {
    pub ticks: u64,
    pub channel: u8,
    pub counts: Vec<i16>,
}

/// A time-driven (MID 2) or user-forced (MID 3) row: parametric inputs at a time.
#[derive(Debug, Clone, PartialEq)]
pub struct DtaParametric {
    pub ticks: u64,
    pub params: Vec<(u8, f64)>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    Hit(DtaHit),
    Wave(DtaWave),
    Parametric(DtaParametric),
}

/// Hardware of one channel's waveform path (sub-message 173,42).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaveSetup {
    pub sample_rate_hz: f64,
    /// Samples recorded before the trigger (−TDLY).
    pub pretrigger: u32,
}

/// What the setup messages said so far.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Setup {
    /// Hit features in message order.
    pub chids: Vec<u8>,
    /// Time-driven set: features per channel and parametric ids.
    pub demand_chids: Vec<u8>,
    pub demand_pids: Vec<u8>,
    pub partial_power_segments: usize,
    /// Channel → gain, dB.
    pub gain_db: BTreeMap<u8, f64>,
    pub wave: BTreeMap<u8, WaveSetup>,
    /// MID 99, as written (e.g. "Thu May 27 10:53:54 2021").
    pub test_start: Option<String>,
    /// MID 8 at the start: this file continues an earlier one.
    pub continued: bool,
    pub product: Option<String>,
}

/// Size in bytes of a hit feature, by CHID (the manual's table; 22 = partial powers).
fn chid_size(chid: u8, pp: usize) -> Option<usize> {
    Some(match chid {
        1..=4 => 2,
        5 => 4,
        6..=11 => 1,
        12 => 4,
        13 | 14 => 2,
        15 => 6,
        17..=19 => 2,
        20 | 21 => 4,
        22 => pp,
        23 | 24 => 2,
        _ => return None,
    })
}

/// The vendor's short name of a CHID (AEwin's column headings).
pub fn chid_name(chid: u8) -> &'static str {
    match chid {
        1 => "RISE",
        2 => "PCNTS",
        3 => "COUN",
        4 => "ENER",
        5 => "DURATION",
        6 => "AMP",
        7 => "RMS8",
        8 => "ASL",
        9 => "GAIN",
        10 => "THR",
        11 => "PAC",
        12 => "LOST",
        13 => "A-FRQ",
        14 => "DUR16",
        15 => "TOT",
        17 => "RMS",
        18 => "R-FRQ",
        19 => "I-FRQ",
        20 => "SIG STRENGTH",
        21 => "ABS-ENERGY",
        22 => "PARTIAL POWER",
        23 => "FRQ-C",
        24 => "P-FRQ",
        _ => "?",
    }
}

fn le(b: &[u8]) -> u64 {
    b.iter().rev().fold(0u64, |a, &x| (a << 8) | x as u64)
}

/// Decode one feature to SI units: µs → s, kHz → Hz, RMS16/5000 → V, signal strength ×3.05
/// → pV·s, absolute energy ×9.31e-4 → aJ; dB and counts as stored.
fn feature_value(chid: u8, b: &[u8]) -> f64 {
    match chid {
        1 | 5 | 14 => le(b) as f64 * 1e-6,
        7 => b[0] as f64 / 20.0,
        13 | 18 | 19 | 23 | 24 => le(b) as f64 * 1e3,
        17 => le(b) as f64 / 5000.0,
        20 => le(b) as f64 * 3.05,
        21 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64 * 9.31e-4,
        15 => le(b) as f64 * TICK_S,
        // Partial powers: the segments' percentages; reported as the first.
        22 => b.first().copied().unwrap_or(0) as f64,
        _ => le(b) as f64,
    }
}

/// Parametric counts → volts (±10 V full scale over a signed 16-bit value).
fn param_volts(lo: u8, hi: u8) -> f64 {
    i16::from_le_bytes([lo, hi]) as f64 * MAX_INPUT_V / 32768.0
}

/// Hit or time-driven parametric block: `PID, V lo, V hi` (3 bytes each; 4 when every
/// entry carries the cycle-counter MSB byte).
fn parametric_block(b: &[u8]) -> Vec<(u8, f64)> {
    let step = if !b.is_empty() && !b.len().is_multiple_of(3) && b.len().is_multiple_of(4) {
        4
    } else {
        3
    };
    b.chunks_exact(step)
        .map(|c| (c[0], param_volts(c[1], c[2])))
        .collect()
}

/// Walks the messages of one file.
pub struct MessageReader<R: Read> {
    r: R,
    /// Bytes left in the file.
    left: u64,
    offset: u64,
    buf: Vec<u8>,
    pub setup: Setup,
    done: bool,
    /// Messages seen by MID (for `inspect` and the manifest).
    pub counts: BTreeMap<u8, u64>,
}

impl<R: Read> MessageReader<R> {
    /// `len` is the file's size: no message may claim more than what is left of it.
    pub fn new(r: R, len: u64) -> MessageReader<R> {
        MessageReader {
            r,
            left: len,
            offset: 0,
            buf: Vec::with_capacity(1 << 16),
            setup: Setup::default(),
            done: false,
            counts: BTreeMap::new(),
        }
    }

    pub fn offset(&self) -> u64 {
        self.offset
    }

    fn malformed(&self, at: u64, mid: u8, why: impl Into<String>) -> DtaError {
        DtaError::Malformed {
            offset: at,
            mid,
            why: why.into(),
        }
    }

    /// The next message aepipe uses (setup messages are absorbed into [`Self::setup`]).
    pub fn next_message(&mut self) -> Option<Result<Message, DtaError>> {
        while !self.done {
            let at = self.offset;
            if self.left == 0 {
                self.done = true;
                return None;
            }
            if self.left < 2 {
                self.done = true;
                return Some(Err(DtaError::Truncated {
                    offset: at,
                    len: 2,
                    left: self.left,
                }));
            }
            let mut lb = [0u8; 2];
            if let Err(e) = self.r.read_exact(&mut lb) {
                self.done = true;
                return Some(Err(DtaError::Io(e.to_string())));
            }
            self.left -= 2;
            let len = u16::from_le_bytes(lb) as usize;
            if len as u64 > self.left {
                self.done = true;
                return Some(Err(DtaError::Truncated {
                    offset: at,
                    len,
                    left: self.left,
                }));
            }
            self.buf.resize(len, 0);
            if let Err(e) = self.r.read_exact(&mut self.buf) {
                self.done = true;
                return Some(Err(DtaError::Io(e.to_string())));
            }
            self.left -= len as u64;
            self.offset += 2 + len as u64;
            if len == 0 {
                continue;
            }
            let mid = self.buf[0];
            *self.counts.entry(mid).or_default() += 1;
            let body = std::mem::take(&mut self.buf);
            let r = self.decode(at, mid, &body[1..]);
            self.buf = body;
            match r {
                Ok(Some(m)) => return Some(Ok(m)),
                Ok(None) => continue,
                Err(e) => return Some(Err(e)),
            }
        }
        None
    }

    fn decode(&mut self, at: u64, mid: u8, b: &[u8]) -> Result<Option<Message>, DtaError> {
        let short = |need: usize| -> Result<(), DtaError> {
            if b.len() < need {
                Err(self.malformed(at, mid, format!("{} bytes, need at least {need}", b.len())))
            } else {
                Ok(())
            }
        };
        match mid {
            1 => {
                short(7)?;
                let ticks = le(&b[..6]);
                let channel = b[6];
                let mut p = 7;
                let mut features = Vec::with_capacity(self.setup.chids.len());
                for &chid in &self.setup.chids {
                    let n =
                        chid_size(chid, self.setup.partial_power_segments).ok_or_else(|| {
                            self.malformed(
                                at,
                                mid,
                                format!("hit feature CHID {chid} has no known size"),
                            )
                        })?;
                    if p + n > b.len() {
                        return Err(self.malformed(
                            at,
                            mid,
                            format!(
                                "hit ends inside feature CHID {chid} ({} of {} bytes)",
                                b.len() - p,
                                n
                            ),
                        ));
                    }
                    features.push(Feature {
                        chid,
                        value: feature_value(chid, &b[p..p + n]),
                    });
                    p += n;
                }
                Ok(Some(Message::Hit(DtaHit {
                    ticks,
                    channel,
                    features,
                    params: parametric_block(&b[p..]),
                })))
            }
            2 | 3 => {
                short(6)?;
                let ticks = le(&b[..6]);
                let n = self.setup.demand_pids.len() * 3;
                let params = parametric_block(&b[6..(6 + n).min(b.len())]);
                Ok(Some(Message::Parametric(DtaParametric { ticks, params })))
            }
            173 => {
                short(1)?;
                if b[0] != 1 {
                    return Ok(None); // other 173 sub-functions (setup echoes)
                }
                short(10)?;
                let ticks = le(&b[1..7]);
                let channel = b[7];
                let data = &b[9..];
                if !data.len().is_multiple_of(2) {
                    return Err(self.malformed(at, mid, "odd number of waveform bytes"));
                }
                let counts = data
                    .chunks_exact(2)
                    .map(|c| i16::from_le_bytes([c[0], c[1]]))
                    .collect();
                Ok(Some(Message::Wave(DtaWave {
                    ticks,
                    channel,
                    counts,
                })))
            }
            5 => {
                self.event_definition(b);
                Ok(None)
            }
            6 => {
                self.demand_definition(b);
                Ok(None)
            }
            8 => {
                if at == 0 {
                    self.setup.continued = true;
                }
                Ok(None)
            }
            23 => {
                if b.len() >= 2 {
                    self.setup.gain_db.insert(b[0], b[1] as f64);
                }
                Ok(None)
            }
            99 => {
                let s = String::from_utf8_lossy(b);
                self.setup.test_start = Some(
                    s.trim_matches(|c: char| c == '\0' || c.is_whitespace())
                        .to_string(),
                );
                Ok(None)
            }
            109 => {
                if b.len() >= 3 {
                    self.setup.partial_power_segments = le(&b[1..3]) as usize;
                }
                Ok(None)
            }
            41 => {
                // ID high byte, PVERN (2), text.
                if b.len() > 3 {
                    let s = String::from_utf8_lossy(&b[3..]);
                    self.setup.product = Some(
                        s.split(['\r', '\n'])
                            .next()
                            .unwrap_or("")
                            .trim()
                            .to_string(),
                    );
                }
                Ok(None)
            }
            42 => {
                // ID high byte, MVERN (2), then sub-messages `u16 LSUB, u8 SUBID, body`.
                let mut p = 3.min(b.len());
                while p + 3 <= b.len() {
                    let lsub = le(&b[p..p + 2]) as usize;
                    if lsub == 0 || p + 2 + lsub > b.len() {
                        return Err(self.malformed(
                            at,
                            mid,
                            format!("sub-message of {lsub} bytes at {p} runs past the message"),
                        ));
                    }
                    let sub = &b[p + 2..p + 2 + lsub];
                    self.sub_message(sub[0], &sub[1..]);
                    p += 2 + lsub;
                }
                Ok(None)
            }
            _ => Ok(None),
        }
    }

    fn event_definition(&mut self, b: &[u8]) {
        if let Some((&n, rest)) = b.split_first() {
            self.setup.chids = rest.iter().take(n as usize).copied().collect();
        }
    }

    fn demand_definition(&mut self, b: &[u8]) {
        if let Some((&n, rest)) = b.split_first() {
            let n = (n as usize).min(rest.len());
            self.setup.demand_chids = rest[..n].to_vec();
            if let Some((&k, pids)) = rest[n..].split_first() {
                self.setup.demand_pids = pids.iter().take(k as usize).copied().collect();
            }
        }
    }

    fn sub_message(&mut self, id: u8, b: &[u8]) {
        match id {
            5 => self.event_definition(b),
            6 => self.demand_definition(b),
            23 if b.len() >= 2 => {
                self.setup.gain_db.insert(b[0], b[1] as f64);
            }
            109 if b.len() >= 3 => self.setup.partial_power_segments = le(&b[1..3]) as usize,
            173 if b.len() >= 25 && b[0] == 42 => {
                // MVERN, b2, ADT, SETS, pad, SLEN(2), CHID, HLK(2), pad(2), SRATE(2, kHz),
                // TMODE(2), TSRC(2), TDLY(2, signed samples), MXIN(2), THRD(2).
                let h = &b[1..25];
                let chid = h[7];
                let srate_khz = le(&h[12..14]) as f64;
                let tdly = i16::from_le_bytes([h[18], h[19]]) as i64;
                if srate_khz > 0.0 {
                    self.setup.wave.insert(
                        chid,
                        WaveSetup {
                            sample_rate_hz: srate_khz * 1e3,
                            pretrigger: (-tdly).max(0) as u32,
                        },
                    );
                }
            }
            _ => {}
        }
    }
}

impl<R: Read> Iterator for MessageReader<R> {
    type Item = Result<Message, DtaError>;
    fn next(&mut self) -> Option<Self::Item> {
        self.next_message()
    }
}

/// Volts of a waveform's counts with the channel's gain (dB; 0 when the setup has none).
pub fn counts_to_volts(counts: &[i16], gain_db: f64) -> Vec<f32> {
    let k = MAX_INPUT_V / (10f64.powf(gain_db / 20.0) * 32768.0);
    counts.iter().map(|&c| (c as f64 * k) as f32).collect()
}

// ---------------------------------------------------------------------------------------
// The source reader: a chain of files (`X.DTA`, `X__2.DTA`, …) as one experiment.

use super::Source;
use crate::config::IngestConfig;
use crate::model::{AeRecord, HitRow, HitSource, Item, Note, Reject, Stage};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};

/// `X__2.DTA` → (`X`, 2); `X.DTA` → (`X`, 1).
pub fn chain_key(p: &Path) -> (String, u32) {
    let stem = p
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    if let Some((base, n)) = stem.rsplit_once("__") {
        if let Ok(k) = n.parse::<u32>() {
            return (base.to_string(), k);
        }
    }
    (stem, 1)
}

/// Whether the head of a file looks like a DTA message stream: a plausible first length
/// and a known first message (product definition, test label, setup, or a continuation).
pub fn looks_like_dta(head: &[u8]) -> bool {
    head.len() >= 3 && {
        let len = u16::from_le_bytes([head[0], head[1]]);
        len >= 1 && matches!(head[2], 7 | 8 | 38 | 41 | 42 | 44 | 99 | 128)
    }
}

/// How many hits or waveforms wait for their partner (same time and channel) at most.
const PAIR_WINDOW: usize = 256;

struct Pending {
    ticks: u64,
    channel: u8,
    hit: Option<HitRow>,
    /// Its `hit` is the waveform's number.
    wave: Option<AeRecord>,
}

struct DtaSource {
    experiment: String,
    files: VecDeque<PathBuf>,
    cfg: IngestConfig,
    current: Option<(String, MessageReader<std::io::BufReader<std::fs::File>>)>,
    setup: Setup,
    hits: u64,
    waves: u64,
    pending: VecDeque<Pending>,
    out: VecDeque<Item>,
    /// Last time-driven value of each parametric input (volts).
    params: BTreeMap<u8, f64>,
    noted_gain: std::collections::BTreeSet<u8>,
}

impl DtaSource {
    fn reject(&self, file: &str, record_id: String, reason: String) -> Item {
        Item::Reject(Reject {
            experiment: self.experiment.clone(),
            source_file: file.to_string(),
            record_id,
            stage: Stage::Read,
            reason,
        })
    }

    fn note(&self, file: &str, message: String) -> Item {
        Item::Note(Note {
            experiment: self.experiment.clone(),
            source_file: file.to_string(),
            message,
        })
    }

    /// Open the next file of the chain; false when none is left.
    fn open_next(&mut self) -> bool {
        while let Some(p) = self.files.pop_front() {
            let name = p.display().to_string();
            match std::fs::File::open(&p).and_then(|f| Ok((f.metadata()?.len(), f))) {
                Ok((len, f)) => {
                    let mut r = MessageReader::new(std::io::BufReader::new(f), len);
                    r.setup = std::mem::take(&mut self.setup);
                    self.current = Some((name, r));
                    return true;
                }
                Err(e) => {
                    let it = self.reject(&name, String::new(), format!("cannot read: {e}"));
                    self.out.push_back(it);
                }
            }
        }
        false
    }

    fn param_value(&self, params: &[(u8, f64)], pid: u8, scale: f64) -> Option<f64> {
        if pid == 0 {
            return None;
        }
        params
            .iter()
            .find(|p| p.0 == pid)
            .map(|p| p.1)
            .or_else(|| self.params.get(&pid).copied())
            .map(|v| v * scale)
    }

    fn hit_row(&self, file: &str, h: &DtaHit) -> HitRow {
        let mut row = HitRow {
            experiment: self.experiment.clone(),
            acquisition: 1,
            channel: h.channel as u32,
            hit: self.hits,
            time_s: Some(h.ticks as f64 * TICK_S),
            load_n: self.param_value(
                &h.params,
                self.cfg.mistras.load_param,
                self.cfg.mistras.load_n_per_v,
            ),
            extension_m: self.param_value(
                &h.params,
                self.cfg.mistras.extension_param,
                self.cfg.mistras.extension_m_per_v,
            ),
            source: HitSource::Mistras,
            source_file: file.to_string(),
            ..Default::default()
        };
        if !h.params.is_empty() {
            let m: BTreeMap<String, f64> = h
                .params
                .iter()
                .map(|(p, v)| (format!("PARA{p}"), *v))
                .collect();
            row.parametric = serde_json::to_string(&m).ok();
        }
        let mut other = BTreeMap::new();
        for f in &h.features {
            let v = Some(f.value);
            match f.chid {
                1 => row.rise_time_s = v,
                2 => row.counts_to_peak = Some(f.value as i64),
                3 => row.counts = Some(f.value as i64),
                4 => row.energy_counts = v,
                5 | 14 => row.duration_s = v,
                6 => row.amplitude_db = v,
                10 => row.threshold_db = v,
                13 => row.avg_freq_hz = v,
                7 | 17 => row.rms_v = v,
                20 => row.signal_strength_vs = Some(f.value * 1e-12),
                21 => row.abs_energy_aj = v,
                23 => row.centroid_freq_hz = v,
                24 => row.peak_freq_hz = v,
                c => {
                    other.insert(chid_name(c).to_string(), f.value);
                }
            }
        }
        if !other.is_empty() {
            row.vendor_features = serde_json::to_string(&other).ok();
        }
        row
    }

    fn record(&mut self, file: &str, w: DtaWave) -> Result<AeRecord, Box<Item>> {
        let Some(ws) = self
            .current
            .as_ref()
            .and_then(|c| c.1.setup.wave.get(&w.channel).copied())
        else {
            return Err(Box::new(self.reject(
                file,
                format!("ch{} waveform {}", w.channel, self.waves),
                format!(
                    "no waveform hardware setup (message 173,42) for channel {}: sample rate unknown",
                    w.channel
                ),
            )));
        };
        let gain = match self
            .current
            .as_ref()
            .and_then(|c| c.1.setup.gain_db.get(&w.channel).copied())
        {
            Some(g) => g,
            None => {
                if self.noted_gain.insert(w.channel) {
                    let n = self.note(
                        file,
                        format!("no gain for channel {} in the setup (a continuation file read alone?): 0 dB assumed", w.channel),
                    );
                    self.out.push_back(n);
                }
                0.0
            }
        };
        let t = w.ticks as f64 * TICK_S;
        let no_params: [(u8, f64); 0] = [];
        Ok(AeRecord {
            experiment: self.experiment.clone(),
            channel: w.channel as u32,
            hit: self.waves,
            time_s: Some(t),
            sample_rate_hz: ws.sample_rate_hz,
            pretrigger: ws.pretrigger.min(w.counts.len() as u32),
            samples: counts_to_volts(&w.counts, gain),
            load_n: self.param_value(
                &no_params,
                self.cfg.mistras.load_param,
                self.cfg.mistras.load_n_per_v,
            ),
            extension_m: self.param_value(
                &no_params,
                self.cfg.mistras.extension_param,
                self.cfg.mistras.extension_m_per_v,
            ),
            label: None,
            threshold_v: None,
            source_file: file.to_string(),
        })
    }

    /// Emit a pending pair (or a lone hit or waveform).
    fn emit(&mut self, p: Pending) {
        let Pending { hit, wave, .. } = p;
        let record = wave.map(|mut r| {
            // A paired waveform takes its hit's threshold, and its load where it has none.
            if let Some(h) = &hit {
                r.threshold_v = h.threshold_db.map(|db| 1e-6 * 10f64.powf(db / 20.0));
                r.load_n = r.load_n.or(h.load_n);
                r.extension_m = r.extension_m.or(h.extension_m);
            }
            r
        });
        if let Some(mut h) = hit {
            h.transient = record.as_ref().map(|r| r.hit);
            self.out.push_back(Item::Hit(Box::new(h)));
        }
        if let Some(r) = record {
            self.out.push_back(Item::Record(r));
        }
    }

    /// Pair a hit with the waveform of the same time and channel. Items leave in the order
    /// they were stored (a pair when its first part was): the front waits for its partner
    /// until [`PAIR_WINDOW`] later items have arrived, then goes out alone.
    fn pair(&mut self, ticks: u64, channel: u8, hit: Option<HitRow>, wave: Option<AeRecord>) {
        let open = |p: &Pending| {
            p.ticks == ticks
                && p.channel == channel
                && (hit.is_some() && p.hit.is_none() || wave.is_some() && p.wave.is_none())
        };
        if let Some(i) = self.pending.iter().position(open) {
            let p = &mut self.pending[i];
            if hit.is_some() {
                p.hit = hit;
            } else {
                p.wave = wave;
            }
        } else {
            self.pending.push_back(Pending {
                ticks,
                channel,
                hit,
                wave,
            });
        }
        while let Some(front) = self.pending.front() {
            let complete = front.hit.is_some() && front.wave.is_some();
            if !complete && self.pending.len() <= PAIR_WINDOW {
                break;
            }
            let p = self.pending.pop_front().expect("non-empty");
            self.emit(p);
        }
    }

    fn step(&mut self) -> bool {
        let Some((file, r)) = self.current.as_mut() else {
            return self.open_next();
        };
        let file = file.clone();
        match r.next_message() {
            None => {
                if let Some((f, r)) = self.current.take() {
                    if r.setup.continued && r.setup.chids.is_empty() {
                        let n = self.note(
                            &f,
                            "continuation file without the setup of its first file".into(),
                        );
                        self.out.push_back(n);
                    }
                    self.setup = r.setup;
                }
                true
            }
            Some(Err(e)) => {
                let at = r.offset();
                let it = self.reject(
                    &file,
                    format!("byte {at}"),
                    format!("the rest of the file is unreadable: {e}"),
                );
                self.out.push_back(it);
                if let Some((_, r)) = self.current.take() {
                    self.setup = r.setup;
                }
                true
            }
            Some(Ok(Message::Hit(h))) => {
                self.hits += 1;
                let row = self.hit_row(&file, &h);
                self.pair(h.ticks, h.channel, Some(row), None);
                true
            }
            Some(Ok(Message::Wave(w))) => {
                self.waves += 1;
                let (ticks, ch) = (w.ticks, w.channel);
                match self.record(&file, w) {
                    Ok(rec) => {
                        self.pair(ticks, ch, None, Some(rec));
                    }
                    Err(rej) => self.out.push_back(*rej),
                }
                true
            }
            Some(Ok(Message::Parametric(p))) => {
                for (pid, v) in p.params {
                    self.params.insert(pid, v);
                }
                true
            }
        }
    }
}

impl Iterator for DtaSource {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        loop {
            if let Some(it) = self.out.pop_front() {
                return Some(it);
            }
            if !self.step() {
                // Every file read: what still waits for a partner goes out alone.
                while let Some(p) = self.pending.pop_front() {
                    self.emit(p);
                }
                return self.out.pop_front();
            }
        }
    }
}

/// Open a MISTRAS source: its files as one chain, in chain order.
pub fn open(src: &Source, cfg: &IngestConfig) -> Box<dyn Iterator<Item = Item> + Send> {
    let mut files = src.files.clone();
    files.sort_by_key(|p| chain_key(p).1);
    Box::new(DtaSource {
        experiment: src.id.clone(),
        files: files.into(),
        cfg: cfg.clone(),
        current: None,
        setup: Setup::default(),
        hits: 0,
        waves: 0,
        pending: VecDeque::new(),
        out: VecDeque::new(),
        params: BTreeMap::new(),
        noted_gain: Default::default(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg(mid: u8, body: &[u8]) -> Vec<u8> {
        let mut v = ((body.len() + 1) as u16).to_le_bytes().to_vec();
        v.push(mid);
        v.extend_from_slice(body);
        v
    }

    #[test]
    fn hit_features_follow_the_chid_list() {
        // The manual's example: MID 5 lists 1,3,4,5,6,21,22,23 with 4 partial powers.
        let mut f = msg(5, &[8, 1, 3, 4, 5, 6, 21, 22, 23, 1]);
        f.extend(msg(109, &[0, 4, 0, 1, 0, 1, 0]));
        let hit = [
            0xEF, 0x11, 0x28, 0x01, 0x00, 0x00, 0x01, 0x62, 0x00, 0x10, 0x00, 0x1F, 0x00, 0x6C,
            0x00, 0x00, 0x00, 0x46, 0x1C, 0x14, 0x40, 0x4C, 0x00, 0x00, 0x01, 0x62, 0xC0, 0x00,
            0x01, 0x1F, 0x00,
        ];
        f.extend(msg(1, &hit));
        let n = f.len() as u64;
        let mut r = MessageReader::new(&f[..], n);
        let Some(Ok(Message::Hit(h))) = r.next() else {
            panic!("no hit")
        };
        assert_eq!(h.channel, 1);
        assert_eq!(h.ticks, 0x012811EF);
        let v: Vec<f64> = h.features.iter().map(|f| f.value).collect();
        assert!((v[0] - 98e-6).abs() < 1e-12); // rise time
        assert_eq!(v[1], 16.0); // counts
        assert_eq!(v[2], 31.0); // energy
        assert!((v[3] - 108e-6).abs() < 1e-12); // duration
        assert_eq!(v[4], 70.0); // amplitude dB
        assert!((v[5] / 46.878e3 - 1.0).abs() < 1e-4, "{}", v[5]); // abs energy
        assert_eq!(v[7], 192e3); // centroid, after 4 partial-power bytes
        assert_eq!(h.params.len(), 1);
        assert!((h.params[0].1 - 0.0095).abs() < 1e-4);
        assert!(r.next().is_none());
    }

    #[test]
    fn a_length_past_the_end_is_an_error_not_a_guess() {
        let mut f = msg(7, b"label");
        f.extend_from_slice(&[200, 0, 1, 2, 3]);
        let n = f.len() as u64;
        let r: Vec<_> = MessageReader::new(&f[..], n).collect();
        assert_eq!(r.len(), 1);
        assert!(
            matches!(r[0], Err(DtaError::Truncated { len: 200, .. })),
            "{r:?}"
        );
    }

    #[test]
    fn unknown_messages_are_skipped_by_length() {
        let mut f = msg(200, &[9; 40]);
        f.extend(msg(5, &[1, 6, 0]));
        f.extend(msg(1, &[1, 0, 0, 0, 0, 0, 3, 55]));
        let n = f.len() as u64;
        let r: Vec<_> = MessageReader::new(&f[..], n)
            .collect::<Result<_, _>>()
            .unwrap();
        assert_eq!(r.len(), 1);
        let Message::Hit(h) = &r[0] else { panic!() };
        assert_eq!((h.channel, h.features[0].value), (3, 55.0));
    }
}
