//! Continuous recordings (issue 40): a stream file's layout read from its header — WAV
//! (RIFF, and RF64 beyond 4 GiB; PCM 16/24/32-bit or float), NumPy `.npy` (1-D, or channels ×
//! samples; int16 or float32) or a raw binary described by a `<file>.toml` beside it — and
//! the stream cut into hits by [`crate::detect`] block by block, in bounded memory.
//!
//! Every size a header states is checked against the file before anything is read: a
//! stream shorter than its header promises is read to its last whole frame, its hits kept,
//! and a reject names the sample where it ends. Each stream's accounting (samples read, hits
//! cut, samples inside hits) rides on the reader's tally into the manifest's `streams`.

mod cutter;
mod layout;
mod records;
pub mod tail;

pub(crate) use layout::{npy_layout, raw_layout, wav_layout};
pub use layout::{sidecar_path, RawDescription};
pub(crate) use records::cut_long_records;
pub use records::Cutting;

use crate::detect::{Sample, ValidDetect};
use crate::model::{AeRecord, HitRow, Item, RecordType, Reject, Stage};
use cutter::Cutter;
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
/// `[ingest] max_samples_per_record`). `aepipe watch` follows a raw stream while it grows
/// ([`tail`]); a `.npy` is read once it has settled.
pub(crate) const FORMAT: super::FormatSpec = super::FormatSpec {
    name: "stream",
    one_hit_per_file: false,
    numbered_by_place: false,
    follow: super::Follow::GrowingStream,
    open,
};

fn open(src: &super::Source, cfg: &super::settings::ReadSettings) -> super::Items {
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
    cfg: &super::settings::ReadSettings,
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
    if cfg.detect().cuts(layout.frames) {
        return cut(layout, experiment, counter, cfg.detect().clone(), gain);
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
