//! Continuous recordings (issue 40): a stream file's layout read from its header — WAV
//! (RIFF, and RF64 beyond 4 GiB; PCM 16/24/32-bit or float), NumPy `.npy` (1-D, or channels ×
//! samples; int16 or float32) or a raw binary described by a `<file>.toml` beside it — and
//! the stream cut into hits by [`crate::detect`] block by block, in bounded memory.
//!
//! Every size a header states is checked against the file before anything is read: a
//! stream shorter than its header promises is read to its last whole frame, its hits kept,
//! and a reject names the sample where it ends. Each stream's accounting (samples read, hits
//! cut, samples inside hits) rides on the reader's tally into the manifest's `streams`.

use crate::detect::{Cut, Detector, Sample, ValidDetect};
use crate::model::{
    db_ae, AeRecord, HitRow, HitSource, Item, RecordType, Reject, Stage, StreamTally, Tally,
};
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Why a stream file's header or description cannot be read (the reject's reason).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StreamError {
    /// What the header or the `.toml` description says that cannot be read.
    #[error("{0}")]
    Header(String),
}

impl From<String> for StreamError {
    fn from(s: String) -> StreamError {
        StreamError::Header(s)
    }
}

impl From<&str> for StreamError {
    fn from(s: &str) -> StreamError {
        StreamError::Header(s.to_string())
    }
}

/// How a stream's samples are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dtype {
    I16,
    I24,
    I32,
    F32,
    F64,
}

impl Dtype {
    fn bytes(self) -> usize {
        match self {
            Dtype::I16 => 2,
            Dtype::I24 => 3,
            Dtype::I32 | Dtype::F32 => 4,
            Dtype::F64 => 8,
        }
    }
}

/// Where a stream's samples are and what they mean.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamLayout {
    pub path: PathBuf,
    pub data_offset: u64,
    /// Samples per channel the header promises.
    pub frames: u64,
    pub channels: usize,
    pub rate_hz: f64,
    pub dtype: Dtype,
    /// Channels interleaved frame by frame (WAV, raw), or one after another (`.npy` 2-D).
    pub interleaved: bool,
    /// Volts per stored unit (before the preamplifier gain is divided out).
    pub unit_v: f64,
    /// The cut is the source's own count of hits and transients (a stream file); false for
    /// a WAV, whose folder's other files are one record each: its cut hits are *added* rows.
    pub counted: bool,
}

fn le_u16(b: &[u8]) -> u16 {
    u16::from_le_bytes([b[0], b[1]])
}
fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}
fn le_u64(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    u64::from_le_bytes(a)
}

/// A WAV or RF64 file's layout: integers are ±1 V full scale, floats volts (as
/// [`super::wavfmt`] reads a one-hit WAV).
pub(crate) fn wav_layout(path: &Path) -> Result<StreamLayout, StreamError> {
    let mut f = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let len = f.metadata().map_err(|e| e.to_string())?.len();
    let mut head = [0u8; 12];
    f.read_exact(&mut head)
        .map_err(|_| "shorter than a WAV header".to_string())?;
    let rf64 = match &head[0..4] {
        b"RIFF" => false,
        b"RF64" => true,
        _ => return Err("not a RIFF/RF64 file".into()),
    };
    if &head[8..12] != b"WAVE" {
        return Err("not a WAVE file".into());
    }
    let (mut fmt, mut ds64_data, mut at) = (None, None, 12u64);
    // Chunks until `data`; each size checked against the file.
    loop {
        let mut ch = [0u8; 8];
        f.seek(SeekFrom::Start(at)).map_err(|e| e.to_string())?;
        f.read_exact(&mut ch)
            .map_err(|_| "no data chunk before the file ends".to_string())?;
        let size = le_u32(&ch[4..8]) as u64;
        let body = at + 8;
        match &ch[0..4] {
            b"ds64" if rf64 => {
                let mut b = [0u8; 16];
                f.read_exact(&mut b)
                    .map_err(|_| "a ds64 chunk cut short".to_string())?;
                ds64_data = Some(le_u64(&b[8..16]));
            }
            b"fmt " => {
                if size < 16 || body + size > len {
                    return Err(format!("a fmt chunk of {size} bytes").into());
                }
                let mut b = vec![0u8; size.min(40) as usize];
                f.read_exact(&mut b).map_err(|e| e.to_string())?;
                fmt = Some(b);
            }
            b"data" => {
                let fmt = fmt.ok_or("a data chunk before the fmt chunk")?;
                let declared = match (rf64, size) {
                    (true, 0xFFFF_FFFF) => ds64_data.ok_or("RF64 without a ds64 size")?,
                    _ => size,
                };
                return wav_fmt(path, &fmt, body, declared);
            }
            _ => {}
        }
        let next = body + size + (size & 1);
        if next <= at || next > len {
            return Err(format!("a chunk at byte {at} runs past the file's end").into());
        }
        at = next;
    }
}

fn wav_fmt(path: &Path, fmt: &[u8], data: u64, declared: u64) -> Result<StreamLayout, StreamError> {
    let mut tag = le_u16(&fmt[0..2]);
    let channels = le_u16(&fmt[2..4]) as usize;
    let rate = le_u32(&fmt[4..8]) as f64;
    let bits = le_u16(&fmt[14..16]);
    if tag == 0xFFFE && fmt.len() >= 26 {
        tag = le_u16(&fmt[24..26]); // WAVE_FORMAT_EXTENSIBLE: the sub-format's tag
    }
    let dtype = match (tag, bits) {
        (1, 16) => Dtype::I16,
        (1, 24) => Dtype::I24,
        (1, 32) => Dtype::I32,
        (3, 32) => Dtype::F32,
        (3, 64) => Dtype::F64,
        _ => return Err(format!("WAV format tag {tag} with {bits} bits is not read").into()),
    };
    if channels == 0 || rate <= 0.0 {
        return Err(format!("{channels} channels at {rate} Hz").into());
    }
    let frame = (channels * dtype.bytes()) as u64;
    let unit_v = match dtype {
        Dtype::F32 | Dtype::F64 => 1.0,
        d => 1.0 / 2f64.powi(d.bytes() as i32 * 8 - 1),
    };
    Ok(StreamLayout {
        path: path.to_path_buf(),
        data_offset: data,
        frames: declared / frame,
        channels,
        rate_hz: rate,
        dtype,
        interleaved: true,
        unit_v,
        counted: false,
    })
}

/// A NumPy `.npy` array's layout: `shape` (n,) or (channels, n), little-endian int16 or
/// float32, C order (a Fortran-order array is refused). Its rate and scale come from
/// `[ingest] sample_rate_hz` and, for int16, a `.toml` beside it (`volts_per_unit`; else
/// the ±1 V full scale of a WAV).
pub(crate) fn npy_layout(path: &Path, rate_hz: f64) -> Result<StreamLayout, StreamError> {
    let mut f = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut pre = [0u8; 10];
    f.read_exact(&mut pre)
        .map_err(|_| "shorter than a .npy header".to_string())?;
    if &pre[0..6] != b"\x93NUMPY" {
        return Err("not a .npy file".into());
    }
    let (hlen, at) = match pre[6] {
        1 => (le_u16(&pre[8..10]) as u64, 10u64),
        2 | 3 => {
            let mut b = [0u8; 2];
            f.read_exact(&mut b).map_err(|e| e.to_string())?;
            (le_u32(&[pre[8], pre[9], b[0], b[1]]) as u64, 12u64)
        }
        v => return Err(format!(".npy version {v}").into()),
    };
    if hlen > 1 << 20 {
        return Err(format!("a .npy header of {hlen} bytes").into());
    }
    let mut h = vec![0u8; hlen as usize];
    f.seek(SeekFrom::Start(at)).map_err(|e| e.to_string())?;
    f.read_exact(&mut h)
        .map_err(|_| "a .npy header cut short".to_string())?;
    let h = String::from_utf8_lossy(&h).replace(' ', "");
    let field = |k: &str| {
        h.split(&format!("'{k}':"))
            .nth(1)
            .map(|r| r.to_string())
            .ok_or(format!("no '{k}' in the .npy header"))
    };
    let descr = field("descr")?;
    let dtype = if descr.starts_with("'<i2'") {
        Dtype::I16
    } else if descr.starts_with("'<f4'") {
        Dtype::F32
    } else {
        return Err(format!(
            "dtype {} (int16 and float32 are read)",
            descr.split(',').next().unwrap_or("")
        )
        .into());
    };
    if field("fortran_order")?.starts_with("True") {
        return Err("a Fortran-order array".into());
    }
    let shape = field("shape")?;
    let inner = shape
        .trim_start_matches('(')
        .split(')')
        .next()
        .unwrap_or("");
    let dims: Vec<u64> = inner
        .split(',')
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<u64>().map_err(|_| format!("shape ({inner})")))
        .collect::<Result<_, _>>()?;
    let (channels, frames) = match dims[..] {
        [n] => (1usize, n),
        [c, n] if c > 0 && c <= 4096 => (c as usize, n),
        _ => return Err(format!("shape ({inner}): 1-D or channels × samples").into()),
    };
    let toml = sidecar(path)?;
    let unit_v = match dtype {
        Dtype::I16 => unit_of(toml.and_then(|t| t.volts_per_unit), dtype)?,
        _ => 1.0,
    };
    Ok(StreamLayout {
        path: path.to_path_buf(),
        data_offset: at + hlen,
        frames,
        channels,
        rate_hz,
        dtype,
        interleaved: false,
        unit_v,
        counted: true,
    })
}

/// `<file>.toml` beside a raw stream (or a `.npy`): what the bytes are.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDescription {
    /// `int16` or `float32` (raw only).
    #[serde(default)]
    pub dtype: Option<String>,
    #[serde(default)]
    pub channels: Option<usize>,
    #[serde(default)]
    pub sample_rate_hz: Option<f64>,
    /// Volts per stored unit.
    #[serde(default)]
    pub volts_per_unit: Option<f64>,
    /// Bytes before the first sample.
    #[serde(default)]
    pub header_bytes: u64,
}

/// Where a stream file's description would be: `x.bin` → `x.bin.toml`.
pub fn sidecar_path(path: &Path) -> PathBuf {
    let mut p = path.as_os_str().to_owned();
    p.push(".toml");
    PathBuf::from(p)
}

/// The description beside a stream file, if there is one.
pub(crate) fn sidecar(path: &Path) -> Result<Option<RawDescription>, StreamError> {
    let p = sidecar_path(path);
    if !p.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
    toml::from_str(&text)
        .map(Some)
        .map_err(|e| format!("{}: {}", p.display(), e.to_string().replace('\n', " ")).into())
}

/// Volts per stored unit: as described (finite, > 0), else int16 at ±1 V full scale (as a
/// WAV's integers) and floats as volts.
fn unit_of(described: Option<f64>, dtype: Dtype) -> Result<f64, StreamError> {
    match described {
        Some(v) if v.is_finite() && v > 0.0 => Ok(v),
        Some(v) => Err(format!("volts_per_unit must be a number > 0, got {v}").into()),
        None => Ok(match dtype {
            Dtype::I16 => 1.0 / 32768.0,
            _ => 1.0,
        }),
    }
}

/// A raw binary stream's layout from its `.toml` description (interleaved channels).
pub(crate) fn raw_layout(path: &Path) -> Result<StreamLayout, StreamError> {
    let d = sidecar(path)?.ok_or("no .toml description beside the raw stream")?;
    let dtype = match d.dtype.as_deref() {
        Some("int16") => Dtype::I16,
        Some("float32") => Dtype::F32,
        other => return Err(format!("dtype {other:?}: int16 or float32").into()),
    };
    let channels = d.channels.unwrap_or(1);
    let rate = d
        .sample_rate_hz
        .ok_or("no sample_rate_hz in the description")?;
    if channels == 0 || channels > 4096 || !(rate.is_finite() && rate > 0.0) {
        return Err(format!("{channels} channels at {rate} Hz").into());
    }
    let len = std::fs::metadata(path).map_err(|e| e.to_string())?.len();
    let frame = (channels * dtype.bytes()) as u64;
    Ok(StreamLayout {
        path: path.to_path_buf(),
        data_offset: d.header_bytes,
        frames: len.saturating_sub(d.header_bytes) / frame,
        channels,
        rate_hz: rate,
        dtype,
        interleaved: true,
        unit_v: unit_of(d.volts_per_unit, dtype)?,
        counted: true,
    })
}

/// The experiment's hit numbers so far, shared by its files' readers (each cut hit takes
/// the next).
pub type HitCounter = std::sync::Arc<std::sync::atomic::AtomicU64>;

/// Cut a stream into hit rows and records, numbered on from `counter` (lazily: a block is
/// read when the items before it are taken).
pub fn cut(
    layout: StreamLayout,
    experiment: String,
    counter: HitCounter,
    detect: ValidDetect,
    gain: f64,
) -> Box<dyn Iterator<Item = Item> + Send> {
    match layout.dtype {
        Dtype::I16 => Box::new(Cutter::<i16>::new(
            layout, experiment, counter, detect, gain,
        )),
        _ => Box::new(Cutter::<f32>::new(
            layout, experiment, counter, detect, gain,
        )),
    }
}

/// A continuous recording as a source: `[detect]` cuts it (with `mode = off`, or `auto`
/// below `auto_min_samples`, each channel is one record as recorded, if it fits
/// `[ingest] max_samples_per_record`).
pub(crate) const FORMAT: super::FormatSpec = super::FormatSpec {
    name: "stream",
    one_hit_per_file: false,
    numbered_by_place: false,
    follow: super::Follow::Whole,
    open,
};

fn open(src: &super::Source, cfg: &super::settings::IngestConfig) -> super::Items {
    let Some(path) = src.files.first().cloned() else {
        return Box::new(std::iter::empty());
    };
    let npy = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    let layout = match npy {
        true => npy_layout(&path, cfg.sample_rate_hz),
        false => raw_layout(&path),
    };
    let counter = HitCounter::new(src.first_hit.into());
    open_layout(layout, &path, src.id.clone(), counter, cfg)
}

/// A stream (or a long record) by its layout: cut, or read whole, or a reject saying why
/// not.
pub(crate) fn open_layout(
    layout: Result<StreamLayout, StreamError>,
    path: &Path,
    experiment: String,
    counter: HitCounter,
    cfg: &super::settings::IngestConfig,
) -> super::Items {
    let reject = |reason: String| -> super::Items {
        Box::new(std::iter::once(Item::Reject(Reject {
            experiment: experiment.clone(),
            source_file: path.display().to_string(),
            record_id: String::new(),
            stage: Stage::Read,
            reason,
            record_type: RecordType::File,
        })))
    };
    let layout = match layout {
        Ok(l) => l,
        Err(why) => return reject(why.to_string()),
    };
    let gain = super::gain_factor(cfg.gain_db);
    if cfg.detect.cuts(layout.frames) {
        return cut(layout, experiment, counter, cfg.detect.clone(), gain);
    }
    if layout.frames > cfg.max_samples_per_record {
        return reject(format!(
            "a continuous recording of {} samples per channel exceeds ingest.max_samples_per_record = {}: set [detect] mode = \"on\" or \"auto\" to cut it into hits",
            layout.frames, cfg.max_samples_per_record
        ));
    }
    match whole(&layout, gain) {
        Ok(chans) => {
            let hit = counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            let pre = cfg.pretrigger_samples;
            Box::new(chans.into_iter().enumerate().flat_map(move |(c, samples)| {
                let rec = AeRecord {
                    kind: crate::model::RecordKind::Hit,
                    experiment: experiment.clone(),
                    channel: c as u32 + 1,
                    hit,
                    time_s: None,
                    sample_rate_hz: layout.rate_hz,
                    pretrigger: pre,
                    samples,
                    load_n: None,
                    extension_m: None,
                    label: None,
                    threshold_v: None,
                    source_file: layout.path.display().to_string(),
                };
                // A stream file's reader gives every record its hit row (the guard adds
                // none for this format).
                [
                    Item::Hit(Box::new(HitRow::of_record(&rec))),
                    Item::Record(rec),
                ]
            }))
        }
        Err(why) => reject(why),
    }
}

/// Every channel of a stream as volts (its size already checked against the limit).
fn whole(l: &StreamLayout, gain: f64) -> Result<Vec<Vec<f32>>, String> {
    let mut f = std::fs::File::open(&l.path).map_err(|e| e.to_string())?;
    let sb = l.dtype.bytes();
    let len = f.metadata().map_err(|e| e.to_string())?.len();
    let n = l
        .frames
        .checked_mul((l.channels * sb) as u64)
        .filter(|n| l.data_offset.saturating_add(*n) <= len)
        .ok_or_else(|| {
            format!(
                "the file holds fewer than the {} samples per channel its header promises",
                l.frames
            )
        })? as usize;
    let mut bytes = vec![0u8; n];
    f.seek(SeekFrom::Start(l.data_offset))
        .map_err(|e| e.to_string())?;
    f.read_exact(&mut bytes).map_err(|_| {
        format!(
            "the file holds fewer than the {} samples per channel its header promises",
            l.frames
        )
    })?;
    let mut chans = vec![Vec::with_capacity(l.frames as usize); l.channels];
    let unit = l.unit_v * gain;
    for (k, s) in bytes.chunks_exact(sb).enumerate() {
        let c = if l.interleaved {
            k % l.channels
        } else {
            k / l.frames.max(1) as usize
        };
        chans[c].push((<f32 as Decode>::decode(l.dtype, s) as f64 * unit) as f32);
    }
    Ok(chans)
}

/// Samples of channel plane `plane` (interleaved: every channel) a file of `len` bytes holds,
/// at most the header's; sizes from the header in checked arithmetic.
fn available(l: &StreamLayout, len: u64, plane: usize) -> u64 {
    let sb = l.dtype.bytes() as u64;
    let data = len.saturating_sub(l.data_offset);
    if l.interleaved {
        return l.frames.min(data / (sb * l.channels as u64));
    }
    let start = (plane as u64).saturating_mul(l.frames);
    (data / sb).saturating_sub(start).min(l.frames)
}

/// Decode `n` samples of `dtype` from little-endian bytes into `T`'s units.
trait Decode: Sample + Default {
    fn decode(dtype: Dtype, b: &[u8]) -> Self;
}

impl Decode for i16 {
    fn decode(_: Dtype, b: &[u8]) -> i16 {
        i16::from_le_bytes([b[0], b[1]])
    }
}

impl Decode for f32 {
    fn decode(dtype: Dtype, b: &[u8]) -> f32 {
        match dtype {
            Dtype::I16 => i16::from_le_bytes([b[0], b[1]]) as f32,
            Dtype::I24 => (i32::from_le_bytes([0, b[0], b[1], b[2]]) >> 8) as f32,
            Dtype::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            Dtype::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            Dtype::F64 => {
                let mut a = [0u8; 8];
                a.copy_from_slice(&b[..8]);
                f64::from_le_bytes(a) as f32
            }
        }
    }
}

struct Cutter<T: Decode> {
    layout: StreamLayout,
    experiment: String,
    counter: HitCounter,
    detect: ValidDetect,
    file: Option<std::fs::File>,
    /// Channels being cut: all (interleaved), or the one whose plane is read.
    detectors: Vec<Detector<T>>,
    plane: usize,
    /// Frames (per channel) the file holds, and read so far of the current pass.
    frames: u64,
    read: u64,
    bytes: Vec<u8>,
    chans: Vec<Vec<T>>,
    out: std::collections::VecDeque<Item>,
    tally: StreamTally,
    done: bool,
    gain: f64,
}

impl<T: Decode> Cutter<T> {
    fn new(
        layout: StreamLayout,
        experiment: String,
        counter: HitCounter,
        detect: ValidDetect,
        gain: f64,
    ) -> Cutter<T> {
        let file_name = layout.path.display().to_string();
        let mut out = std::collections::VecDeque::new();
        let len = std::fs::metadata(&layout.path)
            .map(|m| m.len())
            .unwrap_or(0);
        let planes = if layout.interleaved {
            1
        } else {
            layout.channels
        };
        // The shortest channel the file holds (a plane of a .npy may be cut short).
        let frames = (0..planes)
            .map(|p| available(&layout, len, p))
            .min()
            .unwrap_or(0);
        let first_plane = available(&layout, len, 0);
        if frames < layout.frames {
            out.push_back(Item::Reject(Reject {
                experiment: experiment.clone(),
                source_file: file_name.clone(),
                record_id: format!("sample {frames}"),
                stage: Stage::Read,
                reason: format!(
                    "the stream ends at sample {frames} of the {} per channel its header promises; the hits before it are kept",
                    layout.frames
                ),
                record_type: RecordType::File,
            }));
        }
        let file = std::fs::File::open(&layout.path).ok();
        let n_det = if layout.interleaved {
            layout.channels
        } else {
            1
        };
        let unit = layout.unit_v * gain;
        let p = detect.at_rate(layout.rate_hz);
        let tally = StreamTally {
            experiment: experiment.clone(),
            file: file_name,
            channels: layout.channels,
            sample_rate_hz: layout.rate_hz,
            samples_promised: layout.frames,
            ..Default::default()
        };
        Cutter {
            detectors: (0..n_det)
                .map(|_| Detector::new(p, unit, layout.rate_hz))
                .collect(),
            plane: 0,
            frames: first_plane,
            read: 0,
            bytes: Vec::new(),
            chans: vec![Vec::new(); n_det],
            experiment,
            counter,
            detect,
            file,
            layout,
            out,
            tally,
            done: false,
            gain,
        }
    }

    /// The channel of detector `d`.
    fn channel(&self, d: usize) -> u32 {
        if self.layout.interleaved {
            d as u32 + 1
        } else {
            self.plane as u32 + 1
        }
    }

    /// Read and cut the next block; false at the end of the stream.
    fn step(&mut self) -> Result<bool, String> {
        let l = &self.layout;
        let planes = if l.interleaved { 1 } else { l.channels };
        if self.plane >= planes {
            return Ok(false);
        }
        let per = self.detect.block_samples as u64;
        let n = per.min(self.frames - self.read) as usize;
        let width = if l.interleaved { l.channels } else { 1 };
        let sb = l.dtype.bytes();
        // Within what `available` found in the file: no overflow below its length.
        let at = l.data_offset.saturating_add(if l.interleaved {
            self.read * (width * sb) as u64
        } else {
            (self.plane as u64)
                .saturating_mul(l.frames)
                .saturating_add(self.read)
                .saturating_mul(sb as u64)
        });
        let f = self.file.as_mut().ok_or("cannot open the stream")?;
        self.bytes.resize(n * width * sb, 0);
        f.seek(SeekFrom::Start(at)).map_err(|e| e.to_string())?;
        f.read_exact(&mut self.bytes).map_err(|e| e.to_string())?;
        for c in &mut self.chans {
            c.clear();
        }
        let dtype = l.dtype;
        for (k, s) in self.bytes.chunks_exact(sb).enumerate() {
            self.chans[k % width].push(T::decode(dtype, s));
        }
        self.read += n as u64;
        let mut cuts: Vec<(usize, Cut)> = Vec::new();
        let mut buf = Vec::new();
        let last = self.read >= self.frames;
        for (d, det) in self.detectors.iter_mut().enumerate() {
            det.push(&self.chans[d], &mut buf);
            if last {
                det.finish(&mut buf);
            }
            cuts.extend(buf.drain(..).map(|c| (d, c)));
        }
        cuts.sort_by_key(|(d, c)| (c.first, *d));
        for (d, c) in cuts {
            let ch = self.channel(d);
            self.emit(ch, c);
        }
        if last {
            self.tally.samples_read += self.read;
            self.plane += 1;
            self.read = 0;
            if self.plane < planes {
                let len = std::fs::metadata(&self.layout.path).map_or(0, |m| m.len());
                self.frames = available(&self.layout, len, self.plane);
                let p = self.detect.at_rate(self.layout.rate_hz);
                let unit = self.layout.unit_v * self.gain;
                self.detectors = vec![Detector::new(p, unit, self.layout.rate_hz)];
            }
        }
        Ok(true)
    }

    fn emit(&mut self, channel: u32, c: Cut) {
        let hit = self
            .counter
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
            + 1;
        self.tally.hits_cut += 1;
        self.tally.samples_in_hits += c.last - c.first + 1;
        self.tally.two_bursts += c.two_bursts as u64;
        let at = Cutting {
            experiment: &self.experiment,
            file: &self.tally.file,
            rate_hz: self.layout.rate_hz,
        };
        let (row, rec) = at.items(channel, hit, c);
        self.out.push_back(Item::Hit(Box::new(row)));
        self.out.push_back(Item::Record(rec));
    }
}

/// Where cut hits come from: their experiment, file and rate.
pub struct Cutting<'a> {
    pub experiment: &'a str,
    pub file: &'a str,
    pub rate_hz: f64,
}

impl Cutting<'_> {
    /// A cut hit's row of `hits.parquet` (the detector's features) and its record.
    pub fn items(&self, channel: u32, hit: u64, c: Cut) -> (HitRow, AeRecord) {
        let rate = self.rate_hz;
        let t = |k: u64| k as f64 / rate;
        let ended = if c.at_stream_end {
            "stream_end"
        } else if c.by_max_duration {
            "max_duration"
        } else {
            "ddt"
        };
        let row = HitRow {
            experiment: self.experiment.to_string(),
            acquisition: 1,
            channel,
            hit,
            time_s: Some(t(c.first)),
            amplitude_db: (c.peak_v > 0.0).then(|| db_ae(c.peak_v)),
            threshold_db: (c.threshold_v > 0.0).then(|| db_ae(c.threshold_v)),
            rise_time_s: Some(t(c.peak - c.first)),
            duration_s: Some(t(c.last - c.first)),
            counts: Some(c.counts),
            energy_eu: Some(c.energy_eu),
            transient: Some(hit),
            vendor_features: Some(format!(
                "{{\"two_bursts\": {}, \"ended_by\": \"{ended}\", \"first_sample\": {}, \"last_sample\": {}}}",
                c.two_bursts, c.first, c.last
            )),
            source: HitSource::Detected,
            source_file: self.file.to_string(),
            ..Default::default()
        };
        let rec = AeRecord {
            kind: crate::model::RecordKind::Hit,
            experiment: self.experiment.to_string(),
            channel,
            hit,
            time_s: Some(t(c.first)),
            sample_rate_hz: rate,
            pretrigger: (c.first - c.start) as u32,
            samples: c.samples,
            load_n: None,
            extension_m: None,
            label: None,
            threshold_v: Some(c.threshold_v),
            source_file: self.file.to_string(),
        };
        (row, rec)
    }

    /// Cut channels held in memory (volts, one slice per channel, channel k + 1): the hits
    /// in order of their first crossing, numbered 1…, as a stream file's would be.
    pub fn cut_channels(
        &self,
        channels: &[&[f32]],
        detect: &ValidDetect,
    ) -> Vec<(HitRow, AeRecord)> {
        let p = detect.at_rate(self.rate_hz);
        let mut cuts: Vec<(u32, Cut)> = Vec::new();
        for (k, x) in channels.iter().enumerate() {
            let mut d = Detector::<f32>::new(p, 1.0, self.rate_hz);
            let mut out = Vec::new();
            for b in x.chunks(detect.block_samples) {
                d.push(b, &mut out);
            }
            d.finish(&mut out);
            cuts.extend(out.into_iter().map(|c| (k as u32 + 1, c)));
        }
        cuts.sort_by_key(|(ch, c)| (c.first, *ch));
        cuts.into_iter()
            .enumerate()
            .map(|(i, (ch, c))| self.items(ch, i as u64 + 1, c))
            .collect()
    }
}

impl<T: Decode> Cutter<T> {
    /// The stream's tally: every cut hit is a hit and a transient read.
    fn push_tally(&mut self) {
        let cut = self.tally.hits_cut;
        let n: std::collections::BTreeMap<RecordType, u64> =
            [(RecordType::Hit, cut), (RecordType::Transient, cut)].into();
        let (read, added) = match self.layout.counted {
            true => (n, Default::default()),
            false => (Default::default(), n),
        };
        self.out.push_back(Item::Tally(Tally {
            experiment: self.experiment.clone(),
            read,
            added,
            stream: Some(Box::new(std::mem::take(&mut self.tally))),
        }));
    }
}

impl<T: Decode> Iterator for Cutter<T> {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        loop {
            if let Some(it) = self.out.pop_front() {
                return Some(it);
            }
            if self.done {
                return None;
            }
            match self.step() {
                Ok(true) => {}
                Ok(false) => {
                    self.done = true;
                    self.push_tally();
                }
                Err(e) => {
                    self.done = true;
                    self.out.push_back(Item::Reject(Reject {
                        experiment: self.experiment.clone(),
                        source_file: self.layout.path.display().to_string(),
                        record_id: format!("sample {}", self.tally.samples_read + self.read),
                        stage: Stage::Read,
                        reason: format!("the stream could not be read on: {e}"),
                        record_type: RecordType::File,
                    }));
                    self.tally.samples_read += self.read;
                    self.push_tally();
                }
            }
        }
    }
}

/// Records that other readers read whole (a Vallen TR record of the continuous mode, a long
/// row of `waveforms.parquet`, …) cut when `[detect]` says so: each cut hit is numbered
/// `record hit × 10⁶ + k` (traceable to its record, unique), timed from the record's first
/// sample, and a hit row and record of its own. A cut record counts as the transients it
/// became (a tally of the extra ones); one with no hit is a reject saying so. WAV and
/// stream files are cut by their own readers, block by block.
pub(crate) fn cut_long_records(
    items: super::Items,
    cfg: &super::settings::IngestConfig,
) -> super::Items {
    if cfg.detect.mode == crate::detect::DetectMode::Off {
        return items;
    }
    let detect = cfg.detect.clone();
    // A record just cut from a stream (its detected hit row right before it) is not cut
    // again.
    let mut cut: Option<(u32, u64)> = None;
    Box::new(items.flat_map(move |it| match it {
        Item::Hit(h) => {
            cut = (h.source == HitSource::Detected).then_some((h.channel, h.hit));
            vec![Item::Hit(h)]
        }
        Item::Record(r) => {
            let fresh = cut.take() != Some((r.channel, r.hit));
            if fresh && detect.cuts(r.samples.len() as u64) {
                cut_record(r, &detect)
            } else {
                vec![Item::Record(r)]
            }
        }
        other => vec![other],
    }))
}

/// The hits of one record held in memory.
fn cut_record(r: AeRecord, detect: &ValidDetect) -> Vec<Item> {
    let rate = r.sample_rate_hz;
    let at = Cutting {
        experiment: &r.experiment,
        file: &r.source_file,
        rate_hz: rate,
    };
    let p = detect.at_rate(rate);
    let mut d = Detector::<f32>::new(p, 1.0, rate);
    let mut cuts = Vec::new();
    for b in r.samples.chunks(detect.block_samples) {
        d.push(b, &mut cuts);
    }
    d.finish(&mut cuts);
    // Hit numbers record hit × 10⁶ + k stay unique below 10⁶ hits a record.
    const MAX_CUTS: usize = 999_999;
    let dropped = cuts.len().saturating_sub(MAX_CUTS);
    cuts.truncate(MAX_CUTS);
    // The record's first sample; a record without a time starts at 0 s, as a stream does.
    let t0 = r.time_s.map_or(0.0, |t| t - r.pretrigger as f64 / rate);
    let mut tally = StreamTally {
        experiment: r.experiment.clone(),
        file: format!("{} (ch{} hit {})", r.source_file, r.channel, r.hit),
        channels: 1,
        sample_rate_hz: rate,
        samples_read: r.samples.len() as u64,
        samples_promised: r.samples.len() as u64,
        ..Default::default()
    };
    let mut out = Vec::with_capacity(2 * cuts.len() + 1);
    let m = cuts.len() as u64;
    for (k, c) in cuts.into_iter().enumerate() {
        tally.hits_cut += 1;
        tally.samples_in_hits += c.last - c.first + 1;
        tally.two_bursts += c.two_bursts as u64;
        let hit = r.hit.saturating_mul(1_000_000).saturating_add(k as u64 + 1);
        let (mut row, mut rec) = at.items(r.channel, hit, c);
        row.time_s = row.time_s.map(|t| t0 + t);
        rec.time_s = row.time_s;
        (row.load_n, row.extension_m) = (r.load_n, r.extension_m);
        (rec.load_n, rec.extension_m) = (r.load_n, r.extension_m);
        out.push(Item::Hit(Box::new(row)));
        out.push(Item::Record(rec));
    }
    if dropped > 0 {
        out.push(Item::Note(crate::model::Note {
            experiment: r.experiment.clone(),
            source_file: r.source_file.clone(),
            message: format!(
                "ch{} hit {}: {dropped} hits beyond the {MAX_CUTS} a record can number were not cut",
                r.channel, r.hit
            ),
        }));
    }
    if m == 0 {
        out.push(Item::Reject(Reject {
            experiment: r.experiment.clone(),
            source_file: r.source_file.clone(),
            record_id: format!("ch{} hit {}", r.channel, r.hit),
            stage: Stage::Read,
            reason: format!(
                "a continuous record of {} samples with no hit at [detect]'s threshold",
                r.samples.len()
            ),
            record_type: RecordType::Transient,
        }));
    }
    let added = [
        (RecordType::Transient, m.saturating_sub(1)),
        (RecordType::Hit, m),
    ];
    out.push(Item::Tally(Tally {
        experiment: r.experiment.clone(),
        added: added.into_iter().filter(|(_, n)| *n > 0).collect(),
        stream: Some(Box::new(tally)),
        ..Default::default()
    }));
    out
}
