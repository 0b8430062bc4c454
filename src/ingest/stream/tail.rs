//! A raw stream followed while the acquisition writes it (`aepipe watch`): at each look the
//! new frames are cut, and the hits are handed out in the order of their first crossing up
//! to the last place a part may end — before a hit that comes more than the event
//! builder's reach after the one before it (no event spans two parts, and that hit closes
//! the part's last event as it will in the whole stream), or everything once the stream has
//! not grown for `[live] transient_wait_s`.
//!
//! Exactly-once across a restart: with the hits it hands out, the tail gives a
//! [`Position`] — the detectors' state after a block by which they had given no hit that
//! was not handed, the frames read then, the hits handed and the last one's key. A
//! restarted tail restores the detectors on the samples they held (read again from the
//! file), cuts on from there, and drops the cuts at or before that key: the detectors do
//! not depend on the blocks, and hits are released in the order of their first crossing,
//! so the hits after the key are the ones an uninterrupted tail would have handed.

use super::cutter::{Cutter, LiveCut};
use super::{Dtype, HitCounter, StreamError};
use crate::ingest::settings::ReadSettings;
use crate::ingest::Source;
use crate::model::{Item, RecordType, StreamTally, Tally};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// How far a growing stream has been handed out (what a watcher commits): the cutter's
/// own resumable state, declared beside it.
pub use super::cutter::Position;

/// Hits carried without a quiet gap after which a part is cut anyway (an event may be
/// split there: a stream whose hits never pause for the event builder's reach).
const FORCED_CUT: usize = 16_000;

/// What one look hands out.
pub struct Handed {
    pub items: Vec<Item>,
    pub hits: usize,
    /// Where the stream stands after them (what to commit with them).
    pub end: Position,
    /// The hit after them (time, channel), when one has been cut.
    pub next_hit: Option<(f64, u32)>,
}

/// A growing raw stream and its cutter.
pub struct StreamTail {
    path: PathBuf,
    experiment: String,
    cutter: Box<dyn LiveCut>,
    at: Position,
    frames: u64,
    grown: Instant,
}

impl StreamTail {
    /// Follow `src` (a raw stream described by its `.toml`) from `from`. A `.npy` has a
    /// fixed shape and is not followed.
    pub fn open(
        src: &Source,
        from: &Position,
        cfg: &ReadSettings,
    ) -> Result<StreamTail, StreamError> {
        let path = src.files.first().cloned().ok_or("no stream file")?;
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
        {
            return Err("a .npy stream is read once it has settled".into());
        }
        let layout = super::raw_layout(&path)?;
        let frames = layout.frames;
        let counter = HitCounter::new((src.first_hit + from.hits).into());
        let gain = crate::ingest::gain_factor(cfg.gain_db);
        let (e, d) = (src.id.clone(), cfg.detect().clone());
        let cutter: Box<dyn LiveCut> = match layout.dtype {
            Dtype::I16 => Box::new(Cutter::<i16>::following(layout, e, counter, d, gain, from)?),
            _ => Box::new(Cutter::<f32>::following(layout, e, counter, d, gain, from)?),
        };
        Ok(StreamTail {
            path,
            experiment: src.id.clone(),
            cutter,
            at: from.clone(),
            frames,
            grown: Instant::now(),
        })
    }

    /// Cut hits are waiting to be handed out.
    pub fn waiting(&mut self) -> bool {
        !self.cutter.live().ready.is_empty()
    }

    /// Cut what is new (about `max_records` hits at most) and hand out the hits up to the
    /// last place a part may end: where the next hit comes more than `gap_s` after the one
    /// before (0: anywhere), or all of them once the stream has not grown for `wait`.
    pub fn look(
        &mut self,
        wait: Duration,
        max_records: usize,
        gap_s: f64,
    ) -> Result<Handed, StreamError> {
        let frames = super::raw_layout(&self.path)?.frames;
        if frames > self.frames {
            (self.frames, self.grown) = (frames, Instant::now());
        }
        self.cutter.grow(frames);
        self.cutter.advance(max_records.max(1))?;
        let quiet = self.grown.elapsed() >= wait && self.cutter.read() >= self.frames;
        let live = self.cutter.live();
        let n = live.ready.len();
        let mut hand = 0;
        for i in 0..n {
            // The hit after the part is known (it closes the part's last event as in the
            // whole stream), or the stream has stopped.
            let far = live
                .ready
                .get(i + 1)
                .is_some_and(|r| r.time_s - live.ready[i].time_s > gap_s);
            if far || (i + 1 == n && quiet) {
                hand = i + 1;
            }
        }
        if n >= FORCED_CUT.min(max_records.max(1)) && hand == 0 {
            hand = n;
        }
        let taken: Vec<_> = live.ready.drain(..hand).collect();
        let next_hit = live.ready.front().map(|r| (r.time_s, r.key.1));
        let Some(through) = taken.last().map(|r| r.key).or(self.at.through) else {
            return Ok(self.nothing(next_hit));
        };
        // The latest snapshot by which every cut given was handed (older ones go).
        while live.snaps.len() > 1 && live.snaps[1].given.is_none_or(|g| g <= through) {
            live.snaps.pop_front();
        }
        if taken.is_empty() {
            return Ok(self.nothing(next_hit));
        }
        let snap = live
            .snaps
            .front()
            .filter(|s| s.given.is_none_or(|g| g <= through));
        let (frames, detectors) = match snap {
            Some(s) => (s.frames, s.detectors.clone()),
            None => (self.at.frames, self.at.detectors.clone()),
        };
        let hits = taken.len();
        let end = Position {
            frames,
            detectors,
            hits: self.at.hits + hits as u64,
            through: Some(through),
            counted: self.at.counted.max(frames),
        };
        let items = self.items(taken, &end);
        self.at = end.clone();
        Ok(Handed {
            items,
            hits,
            end,
            next_hit,
        })
    }

    fn nothing(&self, next_hit: Option<(f64, u32)>) -> Handed {
        Handed {
            items: Vec::new(),
            hits: 0,
            end: self.at.clone(),
            next_hit,
        }
    }

    /// The handed hits' rows and records, and a tally counting them and the samples read
    /// since the last hand-out.
    fn items(&self, taken: Vec<super::cutter::Ready>, end: &Position) -> Vec<Item> {
        let m = taken.len() as u64;
        let mut tally = StreamTally {
            experiment: self.experiment.clone(),
            file: self.path.display().to_string(),
            channels: end.detectors.len(),
            samples_read: end.counted - self.at.counted,
            hits_cut: m,
            ..Default::default()
        };
        let mut items = Vec::with_capacity(2 * taken.len() + 1);
        for r in taken {
            tally.sample_rate_hz = r.rec.sample_rate_hz;
            tally.samples_in_hits += r.samples_in_hit;
            tally.two_bursts += r.two_bursts as u64;
            items.push(Item::Hit(Box::new(r.row)));
            items.push(Item::Record(r.rec));
        }
        tally.samples_promised = tally.samples_read;
        items.push(Item::Tally(Tally {
            experiment: self.experiment.clone(),
            read: [(RecordType::Hit, m), (RecordType::Transient, m)].into(),
            stream: Some(Box::new(tally)),
            ..Default::default()
        }));
        items
    }
}
