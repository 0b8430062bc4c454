//! MISTRAS AEwin binary `.DTA` (Appendix II of the MISTRAS/PCI-2 manuals, with its AEwin
//! 32-bit supplement): a stream of messages, read as one experiment per chain of files
//! (`X.DTA`, `X__2.DTA`, …).
//!
//! * [`spec`]: the CHID table (sizes, names, scalings);
//! * [`walker`]: the message walker, each message decoded on its own;
//! * this module: the source reader: hits (message 1) paired with their waveforms (173) on
//!   (time, channel), every waveform a row whether a hit points to it or not, time-driven
//!   rows (2, 3) and markers (7, 15, 99, 128–130) as rows of their own tables, the hardware
//!   settings for the manifest, and a tally of every message read.
//!
//! Nothing is lost: every hit message is a hit row (with the fields it could decode), every
//! waveform message a record or a reject, every time-driven message a parametric row, and a
//! field or sub-function aepipe cannot decode is a manifest note with its count.

pub mod spec;
pub mod walker;

pub use spec::{chid_name, MAX_INPUT_V, TICK_S};
pub use walker::{
    counts_to_volts, DtaError, DtaHit, DtaParametric, DtaWave, Feature, Message, MessageReader,
    Setup, Undecoded, WaveSetup,
};

use super::Source;
use crate::ingest::settings::{IngestConfig, MistrasConfig, ReadSettings};
use crate::model::{
    AcquisitionSetup, AeRecord, ChannelSetup, HitRow, HitSource, Item, MarkerKind, MarkerRow, Note,
    ParametricRow, ParametricSource, RecordKind, RecordType, Reject, Stage, Tally,
};
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::{Path, PathBuf};
use walker::{count_name, seconds, DtaBad, DtaMarker};

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
    cfg: MistrasConfig,
    max_samples: u64,
    current: Option<(String, MessageReader<std::io::BufReader<std::fs::File>>)>,
    /// The setup carried from one file of the chain to the next.
    setup: Setup,
    hits: u64,
    waves: u64,
    param_rows: u64,
    markers: u64,
    pending: VecDeque<Pending>,
    out: VecDeque<Item>,
    /// Last time-driven value of each parametric input (volts).
    params: BTreeMap<u8, f64>,
    /// One-time notes already said.
    said: BTreeSet<String>,
    /// Notes said once at the end with their counts: (file, text) → count.
    counted: BTreeMap<(String, String), u64>,
    /// Messages read, by type, over the chain.
    read: BTreeMap<RecordType, u64>,
    /// A chain still being written ([`tail`]): a file is opened empty and grown by the
    /// follower, and its end is the end of the file only once `seal` is set.
    live: bool,
    seal: bool,
}

/// The record type a message stands for, if it carries a record.
fn record_type(key: u32) -> Option<RecordType> {
    let (mid, sub) = if key > 255 {
        (key / 256, Some(key % 256))
    } else {
        (key, None)
    };
    match (mid, sub) {
        (1, _) => Some(RecordType::Hit),
        (173, Some(42 | 29)) => None,
        (173, _) => Some(RecordType::Transient),
        (2 | 3, _) => Some(RecordType::Parametric),
        (7 | 15 | 99 | 128 | 129 | 130, _) => Some(RecordType::Marker),
        _ => None,
    }
}

impl DtaSource {
    fn reject(&self, file: &str, record_id: String, t: RecordType, reason: String) -> Item {
        Item::Reject(Reject {
            record_type: t,
            experiment: self.experiment.clone(),
            source_file: file.to_string(),
            record_id,
            stage: Stage::Read,
            reason,
        })
    }

    /// A note said once per source (keyed by its text).
    fn note_once(&mut self, file: &str, message: String) {
        if self.said.insert(message.clone()) {
            self.out.push_back(Item::Note(Note {
                said: false,
                experiment: self.experiment.clone(),
                source_file: file.to_string(),
                message,
            }));
        }
    }

    /// A note said at the end with the number of times it applied.
    fn count_note(&mut self, file: &str, message: String) {
        *self.counted.entry((file.to_string(), message)).or_default() += 1;
    }

    /// Open the next file of the chain; false when none is left.
    fn open_next(&mut self) -> bool {
        while let Some(p) = self.files.pop_front() {
            let name = p.display().to_string();
            match std::fs::File::open(&p).and_then(|f| Ok((f.metadata()?.len(), f))) {
                Ok((len, f)) => {
                    let len = if self.live { 0 } else { len };
                    let mut r = MessageReader::new(std::io::BufReader::new(f), len);
                    r.setup = std::mem::take(&mut self.setup);
                    r.setup.size_overrides = self.cfg.size_overrides();
                    r.setup.fallback = (!self.cfg.hit_chids.is_empty()).then(|| {
                        (
                            self.cfg.hit_chids.clone(),
                            self.cfg.hit_parametrics,
                            self.cfg.partial_power_segments,
                        )
                    });
                    self.current = Some((name, r));
                    return true;
                }
                Err(e) => {
                    let it = self.reject(
                        &name,
                        String::new(),
                        RecordType::File,
                        format!("cannot read: {e}"),
                    );
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

    fn load_ext(&self, params: &[(u8, f64)]) -> (Option<f64>, Option<f64>) {
        let c = &self.cfg;
        (
            self.param_value(params, c.load_param, c.load_n_per_v),
            self.param_value(params, c.extension_param, c.extension_m_per_v),
        )
    }

    fn hit_row(&mut self, file: &str, h: &DtaHit) -> HitRow {
        let (load_n, extension_m) = self.load_ext(&h.params);
        let mut row = HitRow {
            experiment: self.experiment.clone(),
            acquisition: 1,
            channel: h.channel as u32,
            hit: self.hits,
            time_s: Some(seconds(h.ticks)),
            load_n,
            extension_m,
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
                22 => {
                    for (k, p) in h.partial_powers.iter().enumerate() {
                        other.insert(format!("PARTIAL POWER {} [%]", k + 1), *p as f64);
                    }
                }
                c => {
                    other.insert(chid_name(c), f.value);
                }
            }
        }
        if !other.is_empty() {
            row.vendor_features = serde_json::to_string(&other).ok();
        }
        if let Some((c, n)) = h.sized_by_length {
            self.count_note(
                file,
                format!(
                    "hit feature {} has no size in the specification: {n} bytes from the message length (value under vendor_features), in",
                    chid_name(c)
                ),
            );
        }
        match &h.undecoded {
            Some(Undecoded::UnknownChid(c)) => self.count_note(
                file,
                format!(
                    "hit feature {} and the ones after it not decoded (no size in the specification, and more than one such field in the hit definition: the message length cannot tell them apart); the hits keep their time, channel and earlier features, in",
                    chid_name(*c)
                ),
            ),
            Some(Undecoded::ShortAt(c)) => self.count_note(
                file,
                format!(
                    "hit message ends inside feature {}: the hits keep the fields before it, in",
                    chid_name(*c)
                ),
            ),
            Some(Undecoded::NoDefinition) => self.count_note(
                file,
                "no hit definition (message 5) before the hits and none in [ingest.mistras] hit_chids: the hits keep their time and channel only, in".into(),
            ),
            None => {}
        }
        row
    }

    fn record(&mut self, file: &str, w: DtaWave) -> Result<AeRecord, Box<Item>> {
        let id = format!("ch{} waveform {}", w.channel, self.waves);
        let setup = &self.current.as_ref().expect("reading a file").1.setup;
        let ws = setup
            .wave
            .get(&w.channel)
            .or_else(|| setup.wave.get(&0))
            .copied();
        let gain = setup.gain_db(w.channel);
        let ws = match ws {
            Some(ws) => ws,
            None if self.cfg.sample_rate_hz > 0.0 => {
                self.note_once(
                    file,
                    format!(
                        "no waveform setup (message 173,42) for channel {}: sample rate {} Hz and pretrigger {} from [ingest.mistras]",
                        w.channel, self.cfg.sample_rate_hz, self.cfg.pretrigger_samples
                    ),
                );
                WaveSetup {
                    sample_rate_hz: self.cfg.sample_rate_hz,
                    pretrigger: self.cfg.pretrigger_samples,
                    samples: 0,
                    max_input_v: MAX_INPUT_V,
                    threshold_db: 0.0,
                }
            }
            None => {
                return Err(Box::new(self.reject(
                    file,
                    id,
                    RecordType::Transient,
                    format!(
                        "no waveform setup (message 173,42) for channel {}: sample rate unknown (a continuation file read alone? set [ingest.mistras] sample_rate_hz and pretrigger_samples)",
                        w.channel
                    ),
                )))
            }
        };
        if w.counts.len() as u64 > self.max_samples {
            return Err(Box::new(self.reject(
                file,
                id,
                RecordType::Transient,
                format!(
                    "{} samples exceed ingest.max_samples_per_record = {}",
                    w.counts.len(),
                    self.max_samples
                ),
            )));
        }
        let gain = match (gain, self.cfg.gain_db) {
            (Some(g), _) => g,
            (None, Some(g)) => {
                self.note_once(
                    file,
                    format!(
                        "no gain (message 23) for channel {}: {g} dB from [ingest.mistras] gain_db",
                        w.channel
                    ),
                );
                g
            }
            (None, None) => {
                self.note_once(
                    file,
                    format!(
                        "no gain for channel {} in the setup (a continuation file read alone?): 0 dB assumed (set [ingest.mistras] gain_db)",
                        w.channel
                    ),
                );
                0.0
            }
        };
        if w.subid != 1 {
            self.count_note(
                file,
                format!(
                    "waveform message 173,{} (not the documented 173,1): read with 173,1's layout (time, channel, alignment byte, int16 samples), in",
                    w.subid
                ),
            );
        }
        let (load_n, extension_m) = self.load_ext(&[]);
        Ok(AeRecord {
            experiment: self.experiment.clone(),
            channel: w.channel as u32,
            hit: self.waves,
            time_s: Some(seconds(w.ticks)),
            sample_rate_hz: ws.sample_rate_hz,
            pretrigger: ws.pretrigger.min(w.counts.len() as u32),
            samples: counts_to_volts(&w.counts, gain, ws.max_input_v),
            load_n,
            extension_m,
            label: None,
            threshold_v: (ws.threshold_db > 0.0).then(|| crate::model::db_to_v(ws.threshold_db)),
            source_file: file.to_string(),
            kind: RecordKind::Standalone,
        })
    }

    /// Emit a pending pair (or a lone hit or waveform).
    fn emit(&mut self, p: Pending) {
        let Pending { hit, wave, .. } = p;
        let record = wave.map(|mut r| {
            // A paired waveform is its hit's: it takes the hit's threshold, and its load
            // where it has none.
            if let Some(h) = &hit {
                r.kind = RecordKind::Hit;
                if let Some(db) = h.threshold_db {
                    r.threshold_v = Some(crate::model::db_to_v(db));
                }
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

    fn parametric(&mut self, file: &str, p: DtaParametric) {
        for (pid, v) in &p.params {
            self.params.insert(*pid, *v);
        }
        self.param_rows += 1;
        let (load_n, extension_m) = self.load_ext(&p.params);
        let inputs = (!p.params.is_empty()).then(|| {
            let m: BTreeMap<String, f64> = p
                .params
                .iter()
                .map(|(k, v)| (format!("PARA{k}"), *v))
                .collect();
            serde_json::to_string(&m).unwrap_or_default()
        });
        let mut extra = serde_json::Map::new();
        for (ch, fs) in &p.channels {
            let m: serde_json::Map<String, serde_json::Value> = fs
                .iter()
                .map(|f| (chid_name(f.chid), serde_json::json!(f.value)))
                .collect();
            extra.insert(ch.to_string(), serde_json::Value::Object(m));
        }
        if p.mid == 3 {
            extra.insert("user_forced".into(), serde_json::json!(true));
        }
        if let Some(Undecoded::UnknownChid(c)) = p.undecoded {
            self.count_note(
                file,
                format!(
                    "time-driven channel features not decoded: {} has no size in the specification, in",
                    chid_name(c)
                ),
            );
        }
        self.out.push_back(Item::Parametric(Box::new(ParametricRow {
            experiment: self.experiment.clone(),
            row: self.param_rows,
            time_s: Some(seconds(p.ticks)),
            load_n,
            extension_m,
            inputs,
            extra: (!extra.is_empty()).then(|| serde_json::Value::Object(extra).to_string()),
            source: ParametricSource::Mistras,
            source_file: file.to_string(),
        })));
    }

    fn marker(&mut self, file: &str, m: DtaMarker) {
        self.markers += 1;
        let kind = match m.mid {
            7 => MarkerKind::Label,
            99 => MarkerKind::Datetime,
            128 => MarkerKind::Start,
            129 => MarkerKind::Stop,
            130 => MarkerKind::Pause,
            _ => MarkerKind::Abort,
        };
        self.out.push_back(Item::Marker(Box::new(MarkerRow {
            experiment: self.experiment.clone(),
            row: self.markers,
            time_s: m.ticks.map(seconds),
            kind,
            text: m.text,
            source_file: file.to_string(),
            ..Default::default()
        })));
    }

    fn bad(&mut self, file: &str, b: DtaBad) {
        let t = match b.mid {
            1 => RecordType::Hit,
            2 | 3 => RecordType::Parametric,
            _ => RecordType::Transient,
        };
        let it = self.reject(file, format!("byte {} (MID {})", b.offset, b.mid), t, b.why);
        self.out.push_back(it);
    }

    /// A file of the chain is done: what it said of its setup, and its message counts.
    fn file_done(&mut self, file: &str, r: &MessageReader<std::io::BufReader<std::fs::File>>) {
        for (k, n) in &r.counts {
            if let Some(t) = record_type(*k) {
                *self.read.entry(t).or_default() += n;
            }
        }
        let s = &r.setup;
        let mut channels: BTreeMap<u32, ChannelSetup> = BTreeMap::new();
        for (&ch, c) in &s.channels {
            let e = channels.entry(ch as u32).or_default();
            e.threshold_db = c.threshold_db;
            e.gain_db = c.gain_db;
            e.preamp_gain_db = c.preamp_gain_db;
            e.hdt_s = c.hdt_s;
            e.hlt_s = c.hlt_s;
            e.pdt_s = c.pdt_s;
        }
        for (&ch, w) in &s.wave {
            let e = channels.entry(ch as u32).or_default();
            e.sample_rate_hz = Some(w.sample_rate_hz);
            e.pretrigger_samples = Some(w.pretrigger);
            e.samples_per_record = (w.samples > 0).then_some(w.samples);
        }
        let setup = AcquisitionSetup {
            experiment: self.experiment.clone(),
            source_file: file.to_string(),
            product: s.product.clone(),
            test_start: s.test_start.clone(),
            hit_features: s.chids.iter().map(|&c| chid_name(c)).collect(),
            channels,
            vendor_records: r.counts.iter().map(|(k, n)| (count_name(*k), *n)).collect(),
        };
        self.out.push_back(Item::Setup(Box::new(setup)));
    }

    fn step(&mut self) -> bool {
        let Some((file, r)) = self.current.as_mut() else {
            return self.open_next();
        };
        let file = file.clone();
        match r.next_message() {
            // A file still being written: what it holds so far is read.
            None if self.live && !self.seal => false,
            None => {
                self.seal = false;
                if let Some((f, r)) = self.current.take() {
                    if r.setup.continued && !r.setup.have_hit_definition {
                        self.note_once(
                            &f,
                            "continuation file without the setup of its first file".into(),
                        );
                    }
                    self.file_done(&f, &r);
                    self.setup = r.setup;
                }
                true
            }
            Some(Err(e)) => {
                let at = r.offset();
                let it = self.reject(
                    &file,
                    format!("byte {at}"),
                    RecordType::File,
                    format!("the rest of the file is unreadable: {e}"),
                );
                self.out.push_back(it);
                if let Some((f, r)) = self.current.take() {
                    self.file_done(&f, &r);
                    self.setup = r.setup;
                }
                true
            }
            Some(Ok(Message::Hit(h))) => {
                self.hits += 1;
                if h.definition_from_config {
                    self.note_once(
                        &file,
                        format!(
                            "no hit definition (message 5) in the stream (a continuation file read alone?): the hit features {:?} from [ingest.mistras] hit_chids",
                            self.cfg.hit_chids.iter().map(|&c| chid_name(c)).collect::<Vec<_>>()
                        ),
                    );
                }
                let row = self.hit_row(&file, &h);
                self.pair(h.ticks, h.channel, Some(row), None);
                true
            }
            Some(Ok(Message::Wave(w))) => {
                self.waves += 1;
                let (ticks, ch) = (w.ticks, w.channel);
                match self.record(&file, w) {
                    Ok(rec) => self.pair(ticks, ch, None, Some(rec)),
                    Err(rej) => self.out.push_back(*rej),
                }
                true
            }
            Some(Ok(Message::Parametric(p))) => {
                self.parametric(&file, p);
                true
            }
            Some(Ok(Message::Marker(m))) => {
                self.marker(&file, m);
                true
            }
            Some(Ok(Message::Bad(b))) => {
                self.bad(&file, b);
                true
            }
        }
    }

    /// Everything read: the pairs still waiting, the counted notes and the tally.
    fn finish(&mut self) {
        while let Some(p) = self.pending.pop_front() {
            self.emit(p);
        }
        for ((file, text), n) in std::mem::take(&mut self.counted) {
            self.out.push_back(Item::Note(Note {
                said: false,
                experiment: self.experiment.clone(),
                source_file: file,
                message: format!("{text} {n} message(s)"),
            }));
        }
        self.out.push_back(Item::Tally(Tally {
            experiment: self.experiment.clone(),
            read: std::mem::take(&mut self.read),
            ..Default::default()
        }));
    }
}

impl Iterator for DtaSource {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        loop {
            if let Some(it) = self.out.pop_front() {
                return Some(it);
            }
            if self.current.is_none() && self.files.is_empty() {
                if self.pending.is_empty() && self.counted.is_empty() && self.read.is_empty() {
                    return None;
                }
                self.finish();
                continue;
            }
            self.step();
        }
    }
}

/// The sources of the `.DTA` files discovery found, by (folder, base name): one chain each,
/// its files in chain order (`X.DTA`, `X__2.DTA`, …).
pub(crate) fn chain_sources(chains: BTreeMap<(PathBuf, String), Vec<PathBuf>>) -> Vec<Source> {
    chains
        .into_iter()
        .map(|((_, id), mut files)| {
            files.sort_by_key(|p| chain_key(p).1);
            Source::of(id, crate::ingest::Format::Mistras, files)
        })
        .collect()
}

/// MISTRAS binary `.DTA` streams, a chain read as one, followed message by message.
pub(crate) const FORMAT: crate::ingest::FormatSpec = crate::ingest::FormatSpec {
    name: "mistras dta",
    one_hit_per_file: false,
    numbered_by_place: false,
    follow: crate::ingest::Follow::GrowingChain,
    open,
};

/// Open a MISTRAS source: its files as one chain, in chain order.
pub fn open(src: &Source, cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
    Box::new(open_source(src, cfg))
}

fn open_source(src: &Source, cfg: &IngestConfig) -> DtaSource {
    let mut files = src.files.clone();
    files.sort_by_key(|p| chain_key(p).1);
    DtaSource {
        experiment: src.id.clone(),
        files: files.into(),
        cfg: cfg.mistras.clone(),
        max_samples: cfg.max_samples_per_record,
        current: None,
        setup: Setup::default(),
        hits: 0,
        waves: 0,
        param_rows: 0,
        markers: 0,
        pending: VecDeque::new(),
        out: VecDeque::new(),
        params: BTreeMap::new(),
        said: BTreeSet::new(),
        counted: BTreeMap::new(),
        read: BTreeMap::new(),
        live: false,
        seal: false,
    }
}

pub mod tail;
