//! The message walker: `u16 LEN, u8 MID, body` (MIDs 40–49 carry one more ID byte), each
//! message decoded on its own. A message carries its length, so what one message holds
//! (an unknown CHID, a short body) costs that message only; only a length that runs past the
//! end of the file ends the walk, and nothing is allocated from a size read in the file
//! beyond one message (≤ 64 KiB).

use super::spec::{self, le, parametric_block, Sizes, TICK_S};
use std::collections::BTreeMap;
use std::io::Read;

/// What stopped the walk at a byte offset of the file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DtaError {
    #[error(
        "byte {offset}: message of {len} bytes runs past the end of the file ({left} bytes left)"
    )]
    Truncated { offset: u64, len: usize, left: u64 },
    #[error("read error: {0}")]
    Io(String),
}

/// A hit feature: the CHID and its value in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feature {
    pub chid: u8,
    pub value: f64,
}

/// Why some of a message's fields were not decoded (the message itself was).
#[derive(Debug, Clone, PartialEq)]
pub enum Undecoded {
    /// A CHID whose size neither the specification nor the message length tells: it and
    /// the fields after it are left out.
    UnknownChid(u8),
    /// The message ends inside this CHID's field.
    ShortAt(u8),
    /// No hit definition (message 5) before the hit: only time and channel are known.
    NoDefinition,
}

/// An AE hit (message 1).
#[derive(Debug, Clone, PartialEq)]
pub struct DtaHit {
    /// Time of test in 0.25 µs ticks (the pairing key with waveforms, with the channel).
    pub ticks: u64,
    pub channel: u8,
    pub features: Vec<Feature>,
    /// Hit parametric inputs: (PID, volts).
    pub params: Vec<(u8, f64)>,
    /// A CHID whose size came from the message length: (CHID, bytes).
    pub sized_by_length: Option<(u8, usize)>,
    pub undecoded: Option<Undecoded>,
    /// Partial powers, one percentage per segment (CHID 22).
    pub partial_powers: Vec<u8>,
    /// Decoded with the hit definition of the pipeline TOML (the stream holds none).
    pub definition_from_config: bool,
}

/// A waveform (message 173, sub-function 1, or another sub-function of the same layout).
#[derive(Debug, Clone, PartialEq)]
pub struct DtaWave {
    pub subid: u8,
    pub ticks: u64,
    pub channel: u8,
    pub counts: Vec<i16>,
}

/// A time-driven (2) or user-forced (3) row: parametric inputs and per-channel features.
#[derive(Debug, Clone, PartialEq)]
pub struct DtaParametric {
    pub mid: u8,
    pub ticks: u64,
    pub params: Vec<(u8, f64)>,
    /// Channel → its time-driven features (CHIDs of the demand definition).
    pub channels: Vec<(u8, Vec<Feature>)>,
    pub undecoded: Option<Undecoded>,
}

/// A message that marks a moment: start/resume (128), stop (129), pause (130), abort
/// (15), a comment or test label (7), the test's start date and time (99).
#[derive(Debug, Clone, PartialEq)]
pub struct DtaMarker {
    pub mid: u8,
    pub ticks: Option<u64>,
    pub text: Option<String>,
}

/// A message that should carry a record but cannot be read as one (message 1 or 173 too
/// short, a 173 sub-function of unknown layout).
#[derive(Debug, Clone, PartialEq)]
pub struct DtaBad {
    pub mid: u8,
    pub offset: u64,
    pub why: String,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    Hit(DtaHit),
    Wave(DtaWave),
    Parametric(DtaParametric),
    Marker(DtaMarker),
    /// A hit (MID 1) or waveform (MID 173) message that is not one.
    Bad(DtaBad),
}

/// Hardware of one channel's waveform path (sub-message 173,42).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaveSetup {
    pub sample_rate_hz: f64,
    /// Samples recorded before the trigger (−TDLY).
    pub pretrigger: u32,
    /// Samples per record (HLK × 1024).
    pub samples: u32,
    /// Full-scale input, volts (MXIN; 10 V when the setup says 0).
    pub max_input_v: f64,
    /// Waveform trigger threshold, dB_AE.
    pub threshold_db: f64,
}

/// One channel's hit settings (messages 20, 22–26).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ChannelSettings {
    pub threshold_db: Option<f64>,
    pub gain_db: Option<f64>,
    pub preamp_gain_db: Option<f64>,
    pub hdt_s: Option<f64>,
    pub hlt_s: Option<f64>,
    pub pdt_s: Option<f64>,
}

/// What the setup messages said so far.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Setup {
    /// Hit features in message order (message 5), and whether a definition was seen.
    pub chids: Vec<u8>,
    pub have_hit_definition: bool,
    /// Hit parametrics per hit (the last byte of message 5).
    pub hit_parametrics: usize,
    /// Time-driven set: features per channel and parametric ids.
    pub demand_chids: Vec<u8>,
    pub demand_pids: Vec<u8>,
    pub partial_power_segments: usize,
    pub channels: BTreeMap<u8, ChannelSettings>,
    pub wave: BTreeMap<u8, WaveSetup>,
    /// Message 99, as written (e.g. "Thu May 27 10:53:54 2021").
    pub test_start: Option<String>,
    /// Message 8 at the start: this file continues an earlier one.
    pub continued: bool,
    pub product: Option<String>,
    /// CHID sizes the pipeline TOML states (`[ingest.mistras] chid_sizes`).
    pub size_overrides: Vec<(u8, usize)>,
    /// The hit definition (CHIDs, hit parametrics, partial-power segments) the pipeline TOML
    /// gives for a stream that holds none (`[ingest.mistras] hit_chids`).
    pub fallback: Option<(Vec<u8>, usize, usize)>,
}

impl Setup {
    /// The gain of a channel, dB (message 23).
    pub fn gain_db(&self, ch: u8) -> Option<f64> {
        self.channels.get(&ch).and_then(|c| c.gain_db)
    }

    fn channel(&mut self, ch: u8) -> &mut ChannelSettings {
        self.channels.entry(ch).or_default()
    }
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
    /// Messages seen by MID (173 by sub-function: key 173·256 + SUBID), for `inspect` and
    /// the manifest.
    pub counts: BTreeMap<u32, u64>,
}

/// The `counts` key of a message.
pub fn count_key(mid: u8, subid: Option<u8>) -> u32 {
    match subid {
        Some(s) => mid as u32 * 256 + s as u32,
        None => mid as u32,
    }
}

/// The name of a `counts` key: `MID 1`, `MID 173,1`.
pub fn count_name(key: u32) -> String {
    if key > 255 {
        format!("MID {},{}", key / 256, key % 256)
    } else {
        format!("MID {key}")
    }
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b)
        .trim_matches(|c: char| c == '\0' || c.is_whitespace() || c == '\u{1a}')
        .to_string()
}

fn ticks6(b: &[u8]) -> u64 {
    le(&b[..6])
}

/// A message that should carry a record but cannot be read as one (a reject, not a gap).
fn bad_message(mid: u8, at: u64, why: String) -> Option<Message> {
    Some(Message::Bad(DtaBad {
        mid,
        offset: at,
        why,
    }))
}

/// A waveform of sub-function `s` (`d`: after that byte), its samples sized by the message.
fn wave_message(at: u64, s: u8, d: &[u8]) -> Option<Message> {
    let bad = |why: String| bad_message(173, at, why);
    // Sub-function 1 is the digital AE waveform: time, channel, alignment
    // byte, then int16 samples to the end of the message (real files carry no
    // sample count). Other sub-functions with a waveform's layout are read
    // the same way; the source notes which.
    if d.len() < 8 {
        return bad(format!(
            "waveform message (173,{s}) of {} bytes: no time and channel",
            d.len()
        ));
    }
    let data = &d[8..];
    if !data.len().is_multiple_of(2) {
        return bad(format!(
            "waveform message (173,{s}) with an odd number ({}) of sample bytes",
            data.len()
        ));
    }
    if data.is_empty() {
        return bad(format!("waveform message (173,{s}) without samples"));
    }
    Some(Message::Wave(DtaWave {
        subid: s,
        ticks: ticks6(d),
        channel: d[6],
        counts: data
            .chunks_exact(2)
            .map(|c| i16::from_le_bytes([c[0], c[1]]))
            .collect(),
    }))
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

    /// `more` bytes were appended to the file (a recording still being written): read on
    /// into them. The caller hands out whole messages only.
    pub fn grow(&mut self, more: u64) {
        if more > 0 {
            self.left += more;
            self.done = false;
        }
    }

    /// The next message that carries a record (setup messages are absorbed into
    /// [`Self::setup`], others skipped by their length).
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
            let body = std::mem::take(&mut self.buf);
            let m = self.decode(at, &body);
            self.buf = body;
            if let Some(m) = m {
                return Some(Ok(m));
            }
        }
        None
    }

    /// Decode one whole message (`b[0]` is its MID).
    fn decode(&mut self, at: u64, msg: &[u8]) -> Option<Message> {
        let mid = msg[0];
        // MIDs 40–49 carry the high byte of a two-byte ID.
        let b = if (40..=49).contains(&mid) && msg.len() >= 2 {
            &msg[2..]
        } else {
            &msg[1..]
        };
        let subid = (mid == 173).then(|| b.first().copied()).flatten();
        *self.counts.entry(count_key(mid, subid)).or_default() += 1;
        let bad = |why: String| bad_message(mid, at, why);
        match mid {
            1 => {
                if b.len() < 7 {
                    return bad(format!(
                        "hit message of {} bytes: no time and channel",
                        b.len()
                    ));
                }
                Some(Message::Hit(self.hit(b)))
            }
            2 | 3 => {
                if b.len() < 6 {
                    return bad(format!("time-driven message of {} bytes: no time", b.len()));
                }
                Some(Message::Parametric(self.demand(mid, b)))
            }
            173 => self.decode_173(at, subid, b),
            7 => Some(Message::Marker(DtaMarker {
                mid,
                ticks: None,
                text: Some(text(b)),
            })),
            99 => {
                let t = text(b);
                self.setup.test_start = Some(t.clone());
                Some(Message::Marker(DtaMarker {
                    mid,
                    ticks: None,
                    text: Some(t),
                }))
            }
            15 | 128 | 129 | 130 => Some(Message::Marker(DtaMarker {
                mid,
                ticks: (b.len() >= 6).then(|| ticks6(b)),
                text: None,
            })),
            8 => {
                if at == 0 {
                    self.setup.continued = true;
                }
                None
            }
            41 => {
                self.product_version(b);
                None
            }
            42 => {
                self.setup_block(b);
                None
            }
            211 => {
                // Time mark; an extended one carries a whole message after RTOT and its
                // length (gain and threshold changes of mGCC ≥ 1.54).
                if b.len() > 8 {
                    let inner = &b[8..];
                    if !inner.is_empty() && inner[0] != 211 {
                        return self.decode(at, inner);
                    }
                }
                None
            }
            _ => {
                self.setup_message(mid, b);
                None
            }
        }
    }

    /// Message 173 by sub-function: a waveform, the waveform setup, or a filter (skipped).
    fn decode_173(&mut self, at: u64, subid: Option<u8>, b: &[u8]) -> Option<Message> {
        let bad = |why: String| bad_message(173, at, why);
        match subid {
            None => bad("waveform message without a sub-function".into()),
            Some(42) => {
                self.wave_setup(&b[1..]);
                None
            }
            Some(29) => None, // waveform filter definition (172/173,29)
            Some(s) => wave_message(at, s, &b[1..]),
        }
    }

    /// Message 41: the product and its version, one line of text, into the setup.
    fn product_version(&mut self, b: &[u8]) {
        // PVERN (2), text: product name CR/LF version.
        if b.len() > 2 {
            let s = String::from_utf8_lossy(&b[2..]);
            let lines: Vec<&str> = s
                .split(['\r', '\n'])
                .map(|l| l.trim_matches(|c: char| c == '\0' || c == '\u{1a}').trim())
                .filter(|l| !l.is_empty())
                .collect();
            self.setup.product = Some(lines.join(" "));
        }
    }

    /// Message 42: its embedded setup messages, walked within its own length only.
    fn setup_block(&mut self, b: &[u8]) {
        // MVERN (2), then sub-messages `u16 LSUB, u8 SUBID, body`, each an embedded
        // message; the walk stays inside this message's own length.
        let mut p = 2.min(b.len());
        while p + 3 <= b.len() {
            let lsub = le(&b[p..p + 2]) as usize;
            if lsub == 0 || p + 2 + lsub > b.len() {
                break; // the rest of this message only
            }
            let sub = &b[p + 2..p + 2 + lsub];
            self.setup_message(sub[0], &sub[1..]);
            p += 2 + lsub;
        }
    }

    /// A setup message, standalone or inside message 42 (the same layouts).
    fn setup_message(&mut self, id: u8, b: &[u8]) {
        let u16at = |i: usize| (b.len() >= i + 2).then(|| le(&b[i..i + 2]) as f64);
        match id {
            5 => {
                if let Some((&n, rest)) = b.split_first() {
                    let n = (n as usize).min(rest.len());
                    self.setup.chids = rest[..n].to_vec();
                    self.setup.hit_parametrics = rest.get(n).copied().unwrap_or(0) as usize;
                    self.setup.have_hit_definition = true;
                }
            }
            6 => {
                if let Some((&n, rest)) = b.split_first() {
                    let n = (n as usize).min(rest.len());
                    self.setup.demand_chids = rest[..n].to_vec();
                    if let Some((&k, pids)) = rest[n..].split_first() {
                        self.setup.demand_pids = pids.iter().take(k as usize).copied().collect();
                    }
                }
            }
            20 if b.len() >= 2 => self.setup.channel(b[0]).preamp_gain_db = Some(b[1] as f64),
            22 if b.len() >= 2 => {
                // MSBit: floating threshold flag; the level is the low 7 bits.
                self.setup.channel(b[0]).threshold_db = Some((b[1] & 0x7f) as f64)
            }
            23 if b.len() >= 2 => self.setup.channel(b[0]).gain_db = Some(b[1] as f64),
            24 => {
                if let (Some(&c), Some(v)) = (b.first(), u16at(1)) {
                    self.setup.channel(c).hdt_s = Some(v * 2.0 / 1e6);
                }
            }
            25 => {
                if let (Some(&c), Some(v)) = (b.first(), u16at(1)) {
                    self.setup.channel(c).hlt_s = Some(v * 2.0 / 1e6);
                }
            }
            26 => {
                if let (Some(&c), Some(v)) = (b.first(), u16at(1)) {
                    self.setup.channel(c).pdt_s = Some(v / 1e6);
                }
            }
            109 if b.len() >= 3 => self.setup.partial_power_segments = le(&b[1..3]) as usize,
            173 if b.first() == Some(&42) => self.wave_setup(&b[1..]),
            _ => {}
        }
    }

    /// Sub-function 173,42: `MVERN(2) ADT(1) SETS(1) pad(1) SLEN(2)` then SETS structs of
    /// SLEN (17) bytes: `CH HLK(2) HITS(2) SRATE(2, kHz) TMODE(2) TSRC(2) TDLY(2, signed
    /// samples) MXIN(2, V) THRD(2, dB)`. Channel 0 sets every channel.
    fn wave_setup(&mut self, b: &[u8]) {
        if b.len() < 7 + 17 {
            return;
        }
        let sets = (b[3] as usize).max(1);
        let slen = (le(&b[5..7]) as usize).max(17);
        for k in 0..sets {
            let Some(h) = b.get(7 + k * slen..7 + k * slen + 17) else {
                break;
            };
            let ch = h[0];
            let srate_khz = le(&h[5..7]) as f64;
            let tdly = i16::from_le_bytes([h[11], h[12]]) as i64;
            let mxin = le(&h[13..15]) as f64;
            if srate_khz <= 0.0 {
                continue;
            }
            let w = WaveSetup {
                sample_rate_hz: srate_khz * 1e3,
                pretrigger: (-tdly).max(0) as u32,
                samples: le(&h[1..3]) as u32 * 1024,
                max_input_v: if mxin > 0.0 { mxin } else { spec::MAX_INPUT_V },
                threshold_db: le(&h[15..17]) as f64,
            };
            if ch == 0 {
                let known: Vec<u8> = self.setup.wave.keys().copied().collect();
                for c in known {
                    self.setup.wave.insert(c, w);
                }
                self.setup.wave.insert(0, w);
            } else {
                self.setup.wave.insert(ch, w);
            }
        }
    }

    fn hit(&self, b: &[u8]) -> DtaHit {
        let mut h = DtaHit {
            ticks: ticks6(b),
            channel: b[6],
            features: Vec::new(),
            params: Vec::new(),
            sized_by_length: None,
            undecoded: None,
            partial_powers: Vec::new(),
            definition_from_config: false,
        };
        let s = &self.setup;
        let (chids, hit_parametrics, pp) = if s.have_hit_definition {
            (&s.chids, s.hit_parametrics, s.partial_power_segments)
        } else if let Some((c, hp, pp)) = &s.fallback {
            h.definition_from_config = true;
            (c, *hp, *pp)
        } else {
            h.undecoded = Some(Undecoded::NoDefinition);
            return h;
        };
        let body = &b[7..];
        let param_bytes = 3 * hit_parametrics;
        let avail = body.len().saturating_sub(param_bytes);
        let (sizes, upto) = match spec::sizes(chids, pp, &s.size_overrides, avail) {
            Sizes::All(v) => (v, chids.len()),
            Sizes::FromLength(v, c, n) => {
                h.sized_by_length = Some((c, n));
                (v, chids.len())
            }
            Sizes::StopAt(v, c) => {
                h.undecoded = Some(Undecoded::UnknownChid(c));
                let i = v.len();
                (v, i)
            }
        };
        let mut p = 0;
        for (k, &chid) in chids[..upto].iter().enumerate() {
            let n = sizes[k];
            if p + n > body.len() {
                h.undecoded = Some(Undecoded::ShortAt(chid));
                return h;
            }
            let f = &body[p..p + n];
            if chid == 22 {
                h.partial_powers = f.to_vec();
            }
            h.features.push(Feature {
                chid,
                value: spec::feature_value(chid, f),
            });
            p += n;
        }
        if h.undecoded.is_none() {
            h.params = parametric_block(&body[p..]);
        }
        h
    }

    fn demand(&self, mid: u8, b: &[u8]) -> DtaParametric {
        let s = &self.setup;
        let mut r = DtaParametric {
            mid,
            ticks: ticks6(b),
            params: Vec::new(),
            channels: Vec::new(),
            undecoded: None,
        };
        let rest = &b[6..];
        let n = (s.demand_pids.len() * 3).min(rest.len());
        r.params = parametric_block(&rest[..n]);
        let mut blocks = &rest[n..];
        // Channel blocks: CID, then the demand CHIDs' values.
        let per = match spec::sizes(
            &s.demand_chids,
            s.partial_power_segments,
            &s.size_overrides,
            usize::MAX / 2,
        ) {
            Sizes::All(v) => v,
            Sizes::FromLength(_, c, _) | Sizes::StopAt(_, c) => {
                if !blocks.is_empty() {
                    r.undecoded = Some(Undecoded::UnknownChid(c));
                }
                return r;
            }
        };
        let block = 1 + per.iter().sum::<usize>();
        while blocks.len() >= block {
            let ch = blocks[0];
            let mut p = 1;
            let mut fs = Vec::with_capacity(per.len());
            for (k, &chid) in s.demand_chids.iter().enumerate() {
                fs.push(Feature {
                    chid,
                    value: spec::feature_value(chid, &blocks[p..p + per[k]]),
                });
                p += per[k];
            }
            if !fs.is_empty() {
                r.channels.push((ch, fs));
            }
            blocks = &blocks[block..];
        }
        r
    }
}

impl<R: Read> Iterator for MessageReader<R> {
    type Item = Result<Message, DtaError>;
    fn next(&mut self) -> Option<Self::Item> {
        self.next_message()
    }
}

/// Volts of a waveform's counts with the channel's gain (dB) and full-scale input (V).
pub fn counts_to_volts(counts: &[i16], gain_db: f64, max_input_v: f64) -> Vec<f32> {
    let k = max_input_v / (10f64.powf(gain_db / 20.0) * 32768.0);
    counts.iter().map(|&c| (c as f64 * k) as f32).collect()
}

/// Seconds of a tick count.
pub fn seconds(ticks: u64) -> f64 {
    ticks as f64 * TICK_S
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
        // The supplement's example: MID 5 lists 1,3,4,5,6,21,22,23 with 4 partial powers.
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
        assert!((seconds(h.ticks) - 4.85081175).abs() < 1e-12);
        let v: Vec<f64> = h.features.iter().map(|f| f.value).collect();
        assert!((v[0] - 98e-6).abs() < 1e-12); // rise time
        assert_eq!(v[1], 16.0); // counts
        assert_eq!(v[2], 31.0); // energy
        assert!((v[3] - 108e-6).abs() < 1e-12); // duration
        assert_eq!(v[4], 70.0); // amplitude dB
        assert!((v[5] / 46.878e3 - 1.0).abs() < 1e-4, "{}", v[5]); // abs energy
        assert_eq!(h.partial_powers, [0, 0, 1, 98]);
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
        assert_eq!(r.len(), 2, "{r:?}");
        assert!(matches!(r[0], Ok(Message::Marker(_))), "{r:?}");
        assert!(
            matches!(r[1], Err(DtaError::Truncated { len: 200, .. })),
            "{r:?}"
        );
    }

    #[test]
    fn an_unknown_chid_costs_its_own_message_only() {
        // RISE, CHID 31, CHID 16, AMP: two sizes unknown, so hits keep RISE only; the next
        // message is read as usual.
        let mut f = msg(5, &[4, 1, 31, 16, 6, 0]);
        f.extend(msg(1, &[1, 0, 0, 0, 0, 0, 3, 7, 0, 9, 9, 9, 9, 55]));
        f.extend(msg(5, &[3, 1, 31, 6, 0]));
        // One unknown: CHID 31 takes the 3 bytes the length leaves.
        f.extend(msg(1, &[2, 0, 0, 0, 0, 0, 3, 7, 0, 1, 2, 3, 56]));
        let n = f.len() as u64;
        let r: Vec<_> = MessageReader::new(&f[..], n)
            .collect::<Result<_, _>>()
            .unwrap();
        let [Message::Hit(a), Message::Hit(b)] = &r[..] else {
            panic!("{r:?}")
        };
        assert_eq!(a.features.len(), 1);
        assert_eq!(a.undecoded, Some(Undecoded::UnknownChid(31)));
        assert_eq!(b.sized_by_length, Some((31, 3)));
        assert_eq!(b.features[2].value, 56.0);
        assert_eq!(b.features[1].value, (1 + 2 * 256 + 3 * 65536) as f64);
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
