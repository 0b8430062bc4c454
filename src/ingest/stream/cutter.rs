//! A stream cut block by block: each channel's detector sees the samples in order, a hit
//! across a block boundary stays whole, and the items come out lazily.

use super::{available, Cutting, Decode, HitCounter, StreamLayout};
use crate::detect::{Cut, Detector, Snapshot, ValidDetect};
use crate::model::{Item, RecordType, Reject, Stage, StreamTally, Tally};
use std::io::{Read, Seek, SeekFrom};

pub(super) struct Cutter<T: Decode> {
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
    /// Cuts the detectors gave (first crossing, channel), held until no channel can still
    /// cut an earlier one: hits are numbered in the order of their first crossing, whatever
    /// the blocks.
    held: Vec<((u64, u32), Cut)>,
    /// Following a stream that grows ([`super::tail`]).
    pub(super) live: Option<Live>,
    tally: StreamTally,
    done: bool,
    gain: f64,
}

/// A released cut of a growing stream, waiting to be handed out.
pub(super) struct Ready {
    /// First crossing, channel; the time of the first crossing.
    pub key: (u64, u32),
    pub time_s: f64,
    pub samples_in_hit: u64,
    pub two_bursts: bool,
    pub row: crate::model::HitRow,
    pub rec: crate::model::AeRecord,
}

/// The detectors' state after a block, and the latest cut they had given by then.
pub(super) struct Snap {
    pub frames: u64,
    pub detectors: Vec<Snapshot>,
    pub given: Option<(u64, u32)>,
}

/// How far a growing stream has been handed out (what a watcher commits).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Position {
    /// Frames read when the detectors were in `detectors` (none: from the start).
    pub frames: u64,
    pub detectors: Vec<Snapshot>,
    /// Hits handed out, and the last one's first crossing and channel.
    pub hits: u64,
    pub through: Option<(u64, u32)>,
    /// Frames whose samples the manifest has counted.
    pub counted: u64,
}

/// What a cutter following a growing stream keeps besides.
#[derive(Default)]
pub(super) struct Live {
    /// Cuts at or before this key were handed out before a restart: cut again, dropped.
    pub skip_through: Option<(u64, u32)>,
    /// The latest key the detectors have given.
    pub given: Option<(u64, u32)>,
    /// A snapshot after each block since the last one a commit can use.
    pub snaps: std::collections::VecDeque<Snap>,
    pub ready: std::collections::VecDeque<Ready>,
}

impl<T: Decode> Cutter<T> {
    pub(super) fn new(
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
            held: Vec::new(),
            live: None,
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

    /// Read and cut the next block; false at the end of the stream.
    fn step(&mut self) -> Result<bool, String> {
        let l = &self.layout;
        let planes = if l.interleaved { 1 } else { l.channels };
        if self.plane >= planes || (self.live.is_some() && self.read >= self.frames) {
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
        let mut buf = Vec::new();
        let last = self.read >= self.frames && self.live.is_none();
        let (interleaved, plane) = (l.interleaved, self.plane as u32);
        for (d, det) in self.detectors.iter_mut().enumerate() {
            det.push(&self.chans[d], &mut buf);
            if last {
                det.finish(&mut buf);
            }
            let ch = if interleaved { d as u32 + 1 } else { plane + 1 };
            self.held.extend(buf.drain(..).map(|c| ((c.first, ch), c)));
        }
        self.release();
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

    /// Number and hand on the held cuts no channel can still precede (all of them once the
    /// detectors have finished); while following, note the detectors' state.
    fn release(&mut self) {
        let u = self.detectors.iter().map(Detector::frontier).min();
        let u = u.unwrap_or(u64::MAX);
        if let Some(live) = &mut self.live {
            live.given = self.held.iter().map(|(k, _)| *k).chain(live.given).max();
        }
        self.held.sort_by_key(|(k, _)| *k);
        let n = self.held.partition_point(|((first, _), _)| *first < u);
        let out: Vec<_> = self.held.drain(..n).collect();
        for ((_, ch), c) in out {
            self.emit(ch, c);
        }
        if let Some(live) = &mut self.live {
            live.snaps.push_back(Snap {
                frames: self.read,
                detectors: self.detectors.iter().map(Detector::snapshot).collect(),
                given: live.given,
            });
        }
    }

    fn emit(&mut self, channel: u32, c: Cut) {
        if let Some(live) = &mut self.live {
            if live.skip_through.is_some_and(|k| (c.first, channel) <= k) {
                return;
            }
        }
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
        let (key, span, two) = ((c.first, channel), c.last - c.first + 1, c.two_bursts);
        let (row, rec) = at.items(channel, hit, c);
        if let Some(live) = &mut self.live {
            live.ready.push_back(Ready {
                key,
                time_s: key.0 as f64 / self.layout.rate_hz,
                samples_in_hit: span,
                two_bursts: two,
                row,
                rec,
            });
            return;
        }
        self.out.push_back(Item::Hit(Box::new(row)));
        self.out.push_back(Item::Record(rec));
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

impl<T: Decode> Cutter<T> {
    /// A cutter following a growing interleaved stream from `from` (its detectors restored
    /// on the samples they held, read again from the file), hits numbered on from `counter`.
    pub(super) fn following(
        layout: StreamLayout,
        experiment: String,
        counter: HitCounter,
        detect: ValidDetect,
        gain: f64,
        from: &Position,
    ) -> Result<Cutter<T>, String> {
        let mut c = Cutter::<T>::new(layout, experiment, counter, detect, gain);
        c.out.clear();
        c.live = Some(Live {
            skip_through: from.through,
            given: from.through,
            ..Default::default()
        });
        c.read = from.frames;
        if from.detectors.is_empty() {
            return Ok(c);
        }
        if from.detectors.len() != c.detectors.len() {
            return Err(format!(
                "the committed position has {} channels, the stream {}",
                from.detectors.len(),
                c.detectors.len()
            ));
        }
        let lo = from.detectors.iter().map(|s| s.history().start).min();
        let lo = lo.unwrap_or(from.frames);
        let width = c.layout.channels;
        let sb = c.layout.dtype.bytes();
        let n = (from.frames - lo.min(from.frames)) as usize;
        let mut bytes = vec![0u8; n * width * sb];
        let at = c.layout.data_offset + lo * (width * sb) as u64;
        let f = c.file.as_mut().ok_or("cannot open the stream")?;
        f.seek(SeekFrom::Start(at)).map_err(|e| e.to_string())?;
        f.read_exact(&mut bytes).map_err(|e| e.to_string())?;
        let mut chans = vec![Vec::with_capacity(n); width];
        for (k, s) in bytes.chunks_exact(sb).enumerate() {
            chans[k % width].push(T::decode(c.layout.dtype, s));
        }
        let p = c.detect.at_rate(c.layout.rate_hz);
        let unit = c.layout.unit_v * c.gain;
        c.detectors = from
            .detectors
            .iter()
            .zip(&chans)
            .map(|(s, x)| {
                let h = s.history();
                let part = &x[(h.start - lo) as usize..(h.end - lo) as usize];
                Detector::restore(p, unit, c.layout.rate_hz, s.clone(), part)
            })
            .collect::<Option<_>>()
            .ok_or("the committed position does not match the stream")?;
        Ok(c)
    }
}

/// A cutter following a growing stream, whatever its sample type.
pub(super) trait LiveCut: Send {
    /// The stream now holds `frames` frames.
    fn grow(&mut self, frames: u64);
    /// Cut what the stream holds, block by block, until `max_ready` cuts wait.
    fn advance(&mut self, max_ready: usize) -> Result<(), String>;
    fn live(&mut self) -> &mut Live;
    /// Frames read so far.
    fn read(&self) -> u64;
}

impl<T: Decode> LiveCut for Cutter<T> {
    fn grow(&mut self, frames: u64) {
        self.frames = self.frames.max(frames);
    }

    fn advance(&mut self, max_ready: usize) -> Result<(), String> {
        while self.live().ready.len() < max_ready && self.step()? {}
        Ok(())
    }

    fn live(&mut self) -> &mut Live {
        self.live.as_mut().expect("a following cutter")
    }

    fn read(&self) -> u64 {
        self.read
    }
}
