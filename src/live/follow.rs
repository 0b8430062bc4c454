//! Which files are ready: discovery run again at each look, a file taken once its size
//! and modification time have stayed the same for `settle_s`; a Vallen pair followed
//! while it grows, by `SetID` ([`crate::ingest::vallen::tail`]).

use super::pending::{Part, Pending};
use super::state::State;
use crate::config::ValidConfig;
use crate::ingest::dta::tail::{DtaTail, Position as DtaPosition};
use crate::ingest::stream::tail::{Position as StreamPosition, StreamTail};
use crate::ingest::vallen::tail::{Position, Tail};
use crate::ingest::{Follow, Source};
use crate::model::Item;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime};

impl Part {
    /// Hits in the part (a pair's window; a chain's hit rows).
    pub fn hits(&self) -> usize {
        match self {
            Part::Vallen(w) => w.hits as usize,
            Part::Dta { hits, .. } | Part::Stream { hits, .. } => *hits,
        }
    }

    /// The hit after the part (time, channel), when it ends before a known one.
    pub fn next_hit(&self) -> Option<(f64, u32)> {
        match self {
            Part::Vallen(w) => w.next_hit,
            Part::Dta { next_hit, .. } | Part::Stream { next_hit, .. } => *next_hit,
        }
    }
}

impl Pending {
    /// The source is one hit per file, numbered by place (else a whole recording).
    pub fn per_hit(&self) -> bool {
        self.part.is_none() && self.source.format.numbered_by_place()
    }

    /// How many records it is, about: its files, or its part's hits.
    pub fn weight(&self) -> usize {
        match &self.part {
            Some(Part::Vallen(w)) => w.weight(),
            Some(Part::Dta { records, .. }) => (*records).max(1),
            Some(Part::Stream { hits, .. }) => (*hits).max(1),
            None => self.source.files.len().max(1),
        }
    }
}

/// How a source is followed: as its format declares, a Vallen pair only with its `.pridb`
/// (a `.tradb` alone is read whole once it has settled).
fn follow_of(s: &Source) -> Follow {
    match s.format.spec().follow {
        Follow::GrowingPair if !s.has_hit_list() => Follow::Whole,
        f => f,
    }
}

/// A file as last seen: its size and modification time, and since when they have been so.
struct Seen {
    size: u64,
    modified: Option<SystemTime>,
    since: Instant,
}

/// Follows the inputs between looks.
pub struct Follower {
    settle: Duration,
    seen: HashMap<PathBuf, Seen>,
    /// One-hit-per-file sources' files handed out: committed before this process started
    /// (from the state) or since.
    handed: HashSet<PathBuf>,
    /// Per one-hit-per-file source, the hit number its next file gets (one more than the
    /// files handed out: a committed file removed from the folder does not free its number).
    next_hit: HashMap<String, u64>,
    /// Whole recordings handed out (committed before, or since).
    whole: HashSet<String>,
    /// Growing Vallen pairs: where the committed state left them, and their readers.
    positions: HashMap<String, Position>,
    tails: HashMap<String, Tail>,
    /// Growing MISTRAS chains, likewise.
    dta_positions: HashMap<String, DtaPosition>,
    dtas: HashMap<String, DtaTail>,
    /// Growing raw streams, likewise.
    stream_positions: HashMap<String, StreamPosition>,
    streams: HashMap<String, StreamTail>,
    /// Per growing source, the event builder's longest reach: its parts end only where
    /// the next hit comes later than that after every hit before (no event is split).
    gaps: HashMap<String, f64>,
}

/// The longest time an event can reach over (its first-hit discrimination time, and the
/// longest times to its first and from its previous hit), for `s` as the events step will
/// resolve it; 0 when events are switched off.
fn event_gap_s(cfg: &ValidConfig, s: &Source) -> f64 {
    if cfg.events.enabled == Some(false) {
        return 0.0;
    }
    let vaex = s.vaex().and_then(|p| {
        Some((
            p.display().to_string(),
            crate::ingest::vallen::vaex::read(p).ok()?,
        ))
    });
    let setup = crate::events::setup::resolve(
        &cfg.events,
        &cfg.location,
        vaex.as_ref().map(|(p, v)| (p.as_str(), v)),
        &Default::default(),
    );
    let p = &setup.params;
    p.fhcdt_s.max(p.dt1x_max_s).max(p.dtnx_max_s)
}

impl Follower {
    /// A follower that goes on from what `state` committed.
    pub fn new(settle_s: f64, state: &State) -> Follower {
        let mut f = Follower {
            settle: Duration::from_secs_f64(settle_s.max(0.0)),
            seen: HashMap::new(),
            handed: HashSet::new(),
            next_hit: HashMap::new(),
            whole: HashSet::new(),
            positions: HashMap::new(),
            tails: HashMap::new(),
            dta_positions: HashMap::new(),
            dtas: HashMap::new(),
            stream_positions: HashMap::new(),
            streams: HashMap::new(),
            gaps: HashMap::new(),
        };
        for (id, r) in &state.sources {
            if r.whole {
                f.whole.insert(id.clone());
            }
            if let Some(p) = r.vallen {
                f.positions.insert(id.clone(), p);
            }
            if let Some(p) = &r.dta {
                f.dta_positions.insert(id.clone(), p.clone());
            }
            if let Some(p) = &r.stream {
                f.stream_positions.insert(id.clone(), p.clone());
            }
            f.handed.extend(r.files.iter().map(PathBuf::from));
            f.next_hit.insert(id.clone(), r.files.len() as u64);
        }
        f
    }

    /// Look at the inputs; the sources (or, one hit per file, the files) that are new and
    /// settled, in discovery's order. A growing MISTRAS chain is read at the look, about
    /// `room` records of it at most (what the next flush has room for).
    pub fn poll(&mut self, inputs: &[PathBuf], cfg: &ValidConfig, room: usize) -> Vec<Pending> {
        let d = crate::ingest::discover(inputs, &cfg.ingest);
        let now = Instant::now();
        let mut out = Vec::new();
        for s in d.sources {
            let follow = follow_of(&s);
            if follow == Follow::PerFile {
                let mut new = Vec::new();
                let mut newest = None;
                let mut held = false;
                for f in &s.files {
                    if self.handed.contains(f) {
                        continue;
                    }
                    // Every file is looked at (its settle clock starts now), but they are
                    // taken in order: the first one still changing holds back the ones
                    // after it (their hit numbers follow it).
                    match self.settled(f, now) {
                        Some(w) if !held => {
                            newest = newest.max(w);
                            new.push(f.clone());
                        }
                        _ => held = true,
                    }
                }
                if new.is_empty() {
                    continue;
                }
                for f in &new {
                    self.seen.remove(f);
                    self.handed.insert(f.clone());
                }
                let next = self.next_hit.entry(s.id.clone()).or_insert(0);
                let first_hit = *next;
                *next += new.len() as u64;
                out.push(Pending {
                    source: Source {
                        files: new,
                        first_hit,
                        ..s
                    },
                    written: newest,
                    part: None,
                });
            } else {
                if self.whole.contains(&s.id) {
                    continue;
                }
                if follow == Follow::GrowingPair && self.follow(&s, cfg, &mut out) {
                    continue;
                }
                if follow == Follow::GrowingChain && self.follow_dta(&s, cfg, room, &mut out) {
                    continue;
                }
                if follow == Follow::GrowingStream && self.follow_stream(&s, cfg, room, &mut out) {
                    continue;
                }
                let mut newest = None;
                let mut ready = true;
                for f in s.all_files() {
                    match self.settled(f, now) {
                        Some(w) => newest = newest.max(w),
                        None => ready = false,
                    }
                }
                if !ready {
                    continue;
                }
                for f in s.all_files() {
                    self.seen.remove(f);
                }
                self.whole.insert(s.id.clone());
                out.push(Pending {
                    source: s,
                    written: newest,
                    part: None,
                });
            }
        }
        out
    }

    /// A growing pair holds sets or transients it has seen but not handed out yet.
    pub fn waiting(&mut self) -> bool {
        self.tails.values().any(Tail::waiting)
            || self.dtas.values().any(DtaTail::waiting)
            || self.streams.values_mut().any(StreamTail::waiting)
    }

    /// The ready windows of a growing Vallen pair; false when it cannot be followed (its
    /// `.pridb` is not a database yet, or never will be: then, once its files have settled,
    /// it is read whole, and the offline reader says what is wrong with it).
    fn follow(&mut self, s: &Source, cfg: &ValidConfig, out: &mut Vec<Pending>) -> bool {
        let tail = match self.tails.entry(s.id.clone()) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => {
                let from = self.positions.get(&s.id).copied();
                match Tail::open(s, from.unwrap_or_default(), &cfg.ingest) {
                    Ok(t) => e.insert(t),
                    // A pair read in part before is never read whole (that would read its
                    // first part twice): it is tried again at the next look.
                    Err(_) => return from.is_some(),
                }
            }
        };
        let l = &cfg.live;
        // A look that fails (a lock held past the busy wait, a file being replaced) is
        // tried again at the next one, from where this reader stands.
        let gap = *self
            .gaps
            .entry(s.id.clone())
            .or_insert_with(|| event_gap_s(cfg, s));
        let Ok(windows) = tail.look(
            Duration::from_secs_f64(l.transient_wait_s),
            self.settle,
            super::FLUSH_FILES,
            gap,
            &cfg.ingest,
        ) else {
            return true;
        };
        let written = newest_write(s.all_files().flat_map(|f| [f.to_path_buf(), wal(f)]));
        out.extend(windows.into_iter().map(|w| Pending {
            source: s.clone(),
            written,
            part: Some(Part::Vallen(Box::new(w))),
        }));
        true
    }

    /// What a growing MISTRAS chain holds past the last look; false when it cannot be
    /// followed (never read before: it is then read whole once settled).
    fn follow_dta(
        &mut self,
        s: &Source,
        cfg: &ValidConfig,
        room: usize,
        out: &mut Vec<Pending>,
    ) -> bool {
        let tail = match self.dtas.entry(s.id.clone()) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => {
                let from = self.dta_positions.get(&s.id).cloned();
                match DtaTail::open(s, &from.clone().unwrap_or_default(), &cfg.ingest) {
                    Ok(t) => e.insert(t),
                    Err(_) => return from.is_some(),
                }
            }
        };
        let wait = Duration::from_secs_f64(cfg.live.transient_wait_s);
        let gap = *self
            .gaps
            .entry(s.id.clone())
            .or_insert_with(|| event_gap_s(cfg, s));
        let Ok(crate::ingest::dta::tail::Handed {
            items,
            end,
            next_hit,
        }) = tail.look(&s.files, wait, room, gap)
        else {
            return true;
        };
        if items.is_empty() {
            return true;
        }
        let records = items
            .iter()
            .filter(|i| matches!(i, Item::Record(_) | Item::Hit(_)))
            .count();
        let hits = items.iter().filter(|i| matches!(i, Item::Hit(_))).count();
        let written = newest_write(s.all_files());
        out.push(Pending {
            source: s.clone(),
            written,
            part: Some(Part::Dta {
                items: Arc::new(Mutex::new(items)),
                records,
                hits,
                end,
                next_hit,
            }),
        });
        true
    }

    /// The hits a growing raw stream holds past the last look; false when it is not
    /// followed: `[detect]` does not cut it (yet, with `auto`) and it was never read in
    /// part, or it is not a raw stream (it is then read whole once settled).
    fn follow_stream(
        &mut self,
        s: &Source,
        cfg: &ValidConfig,
        room: usize,
        out: &mut Vec<Pending>,
    ) -> bool {
        let tail = match self.streams.entry(s.id.clone()) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => {
                let from = self.stream_positions.get(&s.id).cloned();
                let cuts = s.files.first().and_then(|f| {
                    let l = crate::ingest::stream::raw_layout(f).ok()?;
                    Some(cfg.read_settings().detect().cuts(l.frames))
                });
                if from.is_none() && cuts != Some(true) {
                    return false;
                }
                match StreamTail::open(s, &from.clone().unwrap_or_default(), cfg.read_settings()) {
                    Ok(t) => e.insert(t),
                    Err(_) => return from.is_some(),
                }
            }
        };
        let wait = Duration::from_secs_f64(cfg.live.transient_wait_s);
        let gap = *self
            .gaps
            .entry(s.id.clone())
            .or_insert_with(|| event_gap_s(cfg, s));
        let Ok(h) = tail.look(wait, room, gap) else {
            return true;
        };
        if h.items.is_empty() {
            return true;
        }
        let written = newest_write(s.all_files());
        out.push(Pending {
            source: s.clone(),
            written,
            part: Some(Part::Stream {
                items: Arc::new(Mutex::new(h.items)),
                hits: h.hits,
                end: Box::new(h.end),
                next_hit: h.next_hit,
            }),
        });
        true
    }

    /// The file's modification time if its size and time have not changed for the settle
    /// time (`Some(None)` when the system gives no time), else `None`.
    fn settled(&mut self, f: &Path, now: Instant) -> Option<Option<SystemTime>> {
        let m = std::fs::metadata(f).ok()?;
        let (size, modified) = (m.len(), m.modified().ok());
        let e = self.seen.entry(f.to_path_buf()).or_insert(Seen {
            size,
            modified,
            since: now,
        });
        if e.size != size || e.modified != modified {
            *e = Seen {
                size,
                modified,
                since: now,
            };
        }
        (now.duration_since(e.since) >= self.settle).then_some(modified)
    }
}

/// The newest modification time of `files` (the lag is counted from it).
fn newest_write<P: AsRef<Path>>(files: impl Iterator<Item = P>) -> Option<SystemTime> {
    files
        .filter_map(|f| std::fs::metadata(f).and_then(|m| m.modified()).ok())
        .max()
}

/// The write-ahead log beside a SQLite database (where a WAL-mode writer's new rows are).
fn wal(db: &Path) -> PathBuf {
    let mut name = db.as_os_str().to_owned();
    name.push("-wal");
    PathBuf::from(name)
}
