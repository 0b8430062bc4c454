//! Which files are ready: discovery run again at each look, a file taken once its size
//! and modification time have stayed the same for `settle_s`.

use super::state::State;
use crate::config::ValidConfig;
use crate::ingest::Source;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

/// Sources to read at the next flush.
#[derive(Debug, Clone)]
pub struct Pending {
    /// For a one-hit-per-file source only its new files, numbered on from `first_hit`.
    pub source: Source,
    /// The newest modification time of its files (for the lag).
    pub written: Option<SystemTime>,
}

impl Pending {
    /// The source is one hit per file, numbered by place (else a whole recording).
    pub fn per_hit(&self) -> bool {
        self.source.format.numbered_by_place()
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
        };
        for (id, r) in &state.sources {
            if r.whole {
                f.whole.insert(id.clone());
            }
            f.handed.extend(r.files.iter().map(PathBuf::from));
            f.next_hit.insert(id.clone(), r.files.len() as u64);
        }
        f
    }

    /// Look at the inputs; the sources (or, one hit per file, the files) that are new and
    /// settled, in discovery's order.
    pub fn poll(&mut self, inputs: &[PathBuf], cfg: &ValidConfig) -> Vec<Pending> {
        let d = crate::ingest::discover(inputs, &cfg.ingest);
        let now = Instant::now();
        let mut out = Vec::new();
        for s in d.sources {
            if s.format.numbered_by_place() {
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
                });
            } else {
                if self.whole.contains(&s.id) {
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
                });
            }
        }
        out
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
