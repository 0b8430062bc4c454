//! A MISTRAS `.DTA` chain that the acquisition is still writing (`aepipe watch`).
//!
//! The files are read by the offline reader itself ([`super::DtaSource`]), handed only
//! whole messages: at each look the follower finds how far the current file holds complete
//! messages (each one's 2-byte length, the file never written to or locked) and lets the
//! reader on to there. A file of the chain is finished once the next one (`X__2.DTA`, …)
//! exists: then its end is read as the offline reader reads it (a message cut short is its
//! reject row). The items are the offline reader's, in its order; a hit that waits for its
//! waveform (they are paired on time and channel) is let out alone once the chain has not
//! grown for `wait`, as the offline reader lets the last ones out at the end.
//!
//! The committed [`Position`] (file of the chain, byte offset after the last message read,
//! and where waiting hits were let out) is where a restarted watcher goes on from: it reads
//! the chain again up to there, dropping the items (committed before), so that the setup
//! messages, counters and waiting pairs are as they were.

use super::{chain_key, DtaSource};
use crate::ingest::settings::IngestConfig;
use crate::ingest::{file_err, IngestError, Source};
use crate::model::Item;
use serde::{Deserialize, Serialize};
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Where the reading of a growing chain stands.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Position {
    /// The file of the chain (0 = `X.DTA`), and the byte offset after the last message read.
    pub file: usize,
    pub offset: u64,
    /// Where the hits waiting for their waveforms were let out (file, offset).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub drains: Vec<(usize, u64)>,
}

/// Hits and waveforms carried without a quiet gap after which a part is cut anyway (an
/// event may be split there: a chain that never pauses for the builder's reach).
const FORCED_CUT: usize = 16_000;

/// The offset of a file the reader has finished (its closing items, a cut message's reject
/// included, are behind it).
const FILE_DONE: u64 = u64::MAX;

/// What one look hands out.
pub struct Handed {
    pub items: Vec<Item>,
    /// Where the reading stands after them (what to commit with them).
    pub end: Position,
    /// The hit after them (time, channel) when they end before a known one: it closes
    /// their last event.
    pub next_hit: Option<(f64, u32)>,
}

/// Follows one growing chain.
pub struct DtaTail {
    src: DtaSource,
    chain: Vec<PathBuf>,
    /// The file being read (None before the first).
    k: Option<usize>,
    /// Bytes of that file handed to the reader.
    complete: u64,
    /// Items read but not handed out (after the last place a part may end), and after
    /// which of them the reader stood where: (items before, position).
    carry: Vec<Item>,
    steps: Vec<(usize, Position)>,
    /// Where the items handed out end.
    handed_at: Position,
    /// Where the reader stands (after the last message it read).
    at: Position,
    grew: Instant,
}

impl DtaTail {
    /// Start following `src` from `from` (what a watcher committed; the default for a new
    /// one): the chain is read again up to there.
    pub fn open(src: &Source, from: &Position, cfg: &IngestConfig) -> Result<DtaTail, IngestError> {
        let mut reader = super::open_source(src, cfg);
        reader.live = true;
        reader.files.clear();
        let mut t = DtaTail {
            src: reader,
            chain: Vec::new(),
            k: None,
            complete: 0,
            at: Position::default(),
            carry: Vec::new(),
            steps: Vec::new(),
            handed_at: from.clone(),
            grew: Instant::now(),
        };
        t.update_chain(&src.files);
        if *from != Position::default() {
            t.advance(usize::MAX, Some(from), &mut |_| {}, &mut |_, _| {})?;
            if t.at.file != from.file || t.at.offset != from.offset {
                return Err(file_err(
                    t.chain.get(from.file).map_or(Path::new(&src.id), |p| p.as_path()),
                    format!(
                        "holds less than was read of it before (file {} of the chain to byte {}): replaced, not appended to",
                        from.file + 1,
                        from.offset
                    ),
                ));
            }
        }
        Ok(t)
    }

    /// The chain as discovery lists it now (the files there are); a file seen before keeps
    /// its place.
    fn update_chain(&mut self, files: &[PathBuf]) {
        let mut f: Vec<PathBuf> = files.iter().filter(|p| p.is_file()).cloned().collect();
        f.sort_by_key(|p| chain_key(p).1);
        if f.len() > self.chain.len() && f[..self.chain.len()] == self.chain[..] {
            self.chain = f;
        }
    }

    /// Hits wait for their waveforms: the test is not idle.
    pub fn waiting(&self) -> bool {
        !self.src.pending.is_empty() || !self.carry.is_empty()
    }

    /// Read what is new, about `max_records` hits and waveforms at most, and hand out the
    /// items up to the last place a part may end: where the next hit comes more than
    /// `gap_s` after every hit before it (the event builder's longest reach: no event spans
    /// two parts; 0: anywhere), or the end once the chain has not grown for `wait`. The
    /// items, and where the reading stands after them (what to commit with them). Hits
    /// waiting for their waveforms are let out alone once the chain has not grown for
    /// `wait`.
    pub fn look(
        &mut self,
        files: &[PathBuf],
        wait: Duration,
        max_records: usize,
        gap_s: f64,
    ) -> Result<Handed, IngestError> {
        self.update_chain(files);
        let before = (self.at.clone(), self.complete);
        let carried = records(&self.carry);
        if max_records > carried {
            let mut got = Vec::new();
            let mut steps = Vec::new();
            let n0 = self.carry.len();
            let read = self.advance(
                max_records - carried,
                None,
                &mut |i| got.push(i),
                &mut |n, p| steps.push((n0 + n, p)),
            );
            // What was read before a failure is kept: the reader has moved past it.
            self.carry.extend(got);
            self.steps.extend(steps);
            read?;
        }
        let now = Instant::now();
        // Quiet: nothing new although the reader was let on (not when the carried items
        // already fill the part and nothing was read).
        let quiet = if (self.at.clone(), self.complete) != before {
            self.grew = now;
            false
        } else {
            max_records > carried && now.duration_since(self.grew) >= wait
        };
        if quiet && !self.src.pending.is_empty() {
            let mut got = Vec::new();
            self.drain(&mut |i| got.push(i));
            self.carry.extend(got);
            let n = self.carry.len();
            self.steps.push((n, self.at.clone()));
        }
        // The last place a part may end.
        let end = if quiet || gap_s <= 0.0 {
            self.steps.last().cloned().map(|(n, p)| (n, p, None))
        } else {
            last_cut(&self.carry, &self.steps, gap_s)
                // A run with no quiet gap at all is not held forever.
                .or_else(|| {
                    (records(&self.carry) > FORCED_CUT)
                        .then(|| self.steps.last().cloned().map(|(n, p)| (n, p, None)))
                        .flatten()
                })
        };
        let Some((n, at, next_hit)) = end else {
            return Ok(Handed {
                items: Vec::new(),
                end: self.handed_at.clone(),
                next_hit: None,
            });
        };
        let rest = self.carry.split_off(n);
        let out = std::mem::replace(&mut self.carry, rest);
        self.steps.retain(|(k, _)| *k > n);
        for s in &mut self.steps {
            s.0 -= n;
        }
        self.handed_at = at.clone();
        Ok(Handed {
            items: out,
            end: at,
            next_hit,
        })
    }

    /// Let the waiting hits and waveforms out alone (as at the end of the chain).
    fn drain(&mut self, sink: &mut impl FnMut(Item)) {
        while let Some(p) = self.src.pending.pop_front() {
            self.src.emit(p);
        }
        self.at.drains.push((self.at.file, self.at.offset));
        for i in self.src.out.drain(..) {
            sink(i);
        }
    }

    /// Step the reader through the whole messages there are, up to `max_records` records
    /// or to `stop` (replaying a committed position).
    fn advance(
        &mut self,
        max_records: usize,
        stop: Option<&Position>,
        sink: &mut impl FnMut(Item),
        step_done: &mut impl FnMut(usize, Position),
    ) -> Result<(), IngestError> {
        let mut records = 0usize;
        let mut items = 0usize;
        loop {
            if let Some(s) = stop {
                if s.drains.contains(&(self.at.file, self.at.offset))
                    && !self.src.pending.is_empty()
                    && !self.at.drains.contains(&(self.at.file, self.at.offset))
                {
                    self.drain(sink);
                }
                if self.at.file == s.file && self.at.offset == s.offset {
                    return Ok(());
                }
            }
            if self.src.current.is_none() {
                let next = self.k.map_or(0, |k| k + 1);
                let Some(path) = self.chain.get(next).cloned() else {
                    return Ok(());
                };
                self.src.files.push_back(path);
                self.src.open_next();
                self.k = Some(next);
                self.complete = 0;
                self.at.file = next;
                self.at.offset = 0;
                if self.src.current.is_none() {
                    // Unreadable: its reject row is out, the chain goes on with the next.
                    let had = items;
                    for i in self.src.out.drain(..) {
                        items += 1;
                        sink(i);
                    }
                    if items > had {
                        step_done(items, self.at.clone());
                    }
                    continue;
                }
            }
            let progressed = self.src.step();
            let had = items;
            for i in self.src.out.drain(..) {
                if matches!(i, Item::Record(_) | Item::Hit(_)) {
                    records += 1;
                }
                items += 1;
                sink(i);
            }
            self.at.offset = match &self.src.current {
                Some((_, r)) => r.offset(),
                None => FILE_DONE,
            };
            if items > had {
                step_done(items, self.at.clone());
            }
            if self.src.current.is_none() {
                // The file is done: the next one (if there is one yet) opens next time.
                continue;
            }
            if records >= max_records {
                return Ok(());
            }
            if progressed {
                continue;
            }
            // What the reader was given is read: let it on to the whole messages there are
            // now; a file with a later one in the chain is finished, read to its end (a
            // message cut short included, as offline).
            let k = self.k.expect("a file is open");
            let (whole, len) = whole_messages(&self.chain[k], self.complete)?;
            let finished = k + 1 < self.chain.len();
            let mut upto = if finished { len } else { whole };
            if let Some(s) = stop {
                // Replaying: the reader stops at each place the committed reading stood
                // (where waiting hits were let out, and its end), whatever came after.
                let next = s
                    .drains
                    .iter()
                    .filter(|d| d.0 == k)
                    .map(|d| d.1)
                    .chain((s.file == k).then_some(s.offset))
                    .filter(|&o| o > self.complete && o != FILE_DONE)
                    .min();
                if let Some(o) = next {
                    upto = upto.min(o);
                }
            }
            if upto > self.complete {
                if let Some((_, r)) = self.src.current.as_mut() {
                    r.grow(upto - self.complete);
                }
                self.complete = upto;
                continue;
            }
            if finished && !self.src.seal {
                self.src.seal = true;
                continue;
            }
            return Ok(());
        }
    }
}

/// How many bytes of the file from `from` on are whole messages (`from` is a message
/// boundary), and the file's length.
fn whole_messages(path: &Path, from: u64) -> Result<(u64, u64), IngestError> {
    let e = |x: std::io::Error| file_err(path, format!("cannot read: {x}"));
    let mut f = std::fs::File::open(path).map_err(e)?;
    let len = f.metadata().map_err(e)?.len();
    let mut at = from;
    let mut r = std::io::BufReader::with_capacity(1 << 12, &mut f);
    r.seek(SeekFrom::Start(at)).map_err(e)?;
    while at + 2 <= len {
        let mut lb = [0u8; 2];
        r.read_exact(&mut lb).map_err(e)?;
        let n = u16::from_le_bytes(lb) as u64;
        if at + 2 + n > len {
            break;
        }
        at += 2 + n;
        r.seek_relative(n as i64).map_err(e)?;
    }
    Ok((at, len))
}

/// Hits and waveforms among the items.
fn records(items: &[Item]) -> usize {
    items
        .iter()
        .filter(|i| matches!(i, Item::Record(_) | Item::Hit(_)))
        .count()
}

/// The last step boundary after which the next hit comes more than `gap_s` after every hit
/// before it: (items before, position, the next hit's time and channel).
#[allow(clippy::type_complexity)]
fn last_cut(
    items: &[Item],
    steps: &[(usize, Position)],
    gap_s: f64,
) -> Option<(usize, Position, Option<(f64, u32)>)> {
    // Latest hit time up to each item, and the first hit from each item on.
    let time = |i: &Item| match i {
        Item::Hit(h) => h.time_s.filter(|t| t.is_finite()).map(|t| (t, h.channel)),
        _ => None,
    };
    let mut next = vec![None; items.len() + 1];
    for k in (0..items.len()).rev() {
        next[k] = time(&items[k]).or(next[k + 1]);
    }
    let mut best = None;
    let (mut latest, mut k) = (f64::NEG_INFINITY, 0usize);
    for (n, p) in steps {
        while k < *n {
            if let Some((t, _)) = time(&items[k]) {
                latest = latest.max(t);
            }
            k += 1;
        }
        if let Some((t, c)) = next[*n] {
            if latest > f64::NEG_INFINITY && t > latest + gap_s {
                best = Some((*n, p.clone(), Some((t, c))));
            }
        }
    }
    best
}
