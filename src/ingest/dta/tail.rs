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
use crate::config::IngestConfig;
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

/// Follows one growing chain.
pub struct DtaTail {
    src: DtaSource,
    chain: Vec<PathBuf>,
    /// The file being read (None before the first).
    k: Option<usize>,
    /// Bytes of that file handed to the reader.
    complete: u64,
    handed: Position,
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
            handed: Position::default(),
            grew: Instant::now(),
        };
        t.update_chain(&src.files);
        if *from != Position::default() {
            t.advance(usize::MAX, Some(from), &mut |_| {})?;
            if t.handed.file != from.file || t.handed.offset != from.offset {
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
        !self.src.pending.is_empty()
    }

    /// Read what is new, at most about `max_records` hits and waveforms; the items, and
    /// where the reading stands after them. `wait`: how long hits wait for their waveforms
    /// without the chain growing before they are let out alone.
    pub fn look(
        &mut self,
        files: &[PathBuf],
        wait: Duration,
        max_records: usize,
    ) -> Result<(Vec<Item>, Position), IngestError> {
        self.update_chain(files);
        let before = (self.handed.clone(), self.complete);
        let mut items = Vec::new();
        if max_records > 0 {
            self.advance(max_records, None, &mut |i| items.push(i))?;
        }
        let now = Instant::now();
        if (self.handed.clone(), self.complete) != before {
            self.grew = now;
        } else if self.waiting() && now.duration_since(self.grew) >= wait {
            self.drain(&mut |i| items.push(i));
        }
        Ok((items, self.handed.clone()))
    }

    /// Let the waiting hits and waveforms out alone (as at the end of the chain).
    fn drain(&mut self, sink: &mut impl FnMut(Item)) {
        while let Some(p) = self.src.pending.pop_front() {
            self.src.emit(p);
        }
        self.handed
            .drains
            .push((self.handed.file, self.handed.offset));
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
    ) -> Result<(), IngestError> {
        let mut records = 0usize;
        loop {
            if let Some(s) = stop {
                if s.drains.contains(&(self.handed.file, self.handed.offset))
                    && !self.src.pending.is_empty()
                    && !self
                        .handed
                        .drains
                        .contains(&(self.handed.file, self.handed.offset))
                {
                    self.drain(sink);
                }
                if self.handed.file == s.file && self.handed.offset == s.offset {
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
                self.handed.file = next;
                self.handed.offset = 0;
                if self.src.current.is_none() {
                    // Unreadable: its reject row is out, the chain goes on with the next.
                    for i in self.src.out.drain(..) {
                        sink(i);
                    }
                    continue;
                }
            }
            let progressed = self.src.step();
            for i in self.src.out.drain(..) {
                if matches!(i, Item::Record(_) | Item::Hit(_)) {
                    records += 1;
                }
                sink(i);
            }
            match &self.src.current {
                Some((_, r)) => self.handed.offset = r.offset(),
                // The file is done: the next one (if there is one yet) opens next time.
                None => continue,
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
            let upto = if finished { len } else { whole };
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
