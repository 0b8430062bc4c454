//! Which files are ready: discovery run again at each look, a file taken once its size
//! and modification time have stayed the same for `settle_s`.

use super::state::State;
use crate::config::ValidConfig;
use crate::ingest::{Format, Source};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

/// Sources to read at the next flush.
#[derive(Debug, Clone)]
pub struct Pending {
    /// For a one-hit-per-file source only its new files, numbered on from `first_hit`.
    pub source: Source,
    /// The source is one hit per file (else a whole recording).
    pub per_hit: bool,
    /// The newest modification time of its files (for the lag).
    pub written: Option<SystemTime>,
}

impl Pending {
    /// Whether `other` reads the same files (it was found again before a flush).
    pub fn same_files(&self, other: &Pending) -> bool {
        self.source.id == other.source.id
            && self.source.files == other.source.files
            && self.source.companions == other.source.companions
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
    /// Files handed out: committed before (loaded from the state once per source) or in
    /// this process.
    handed: std::collections::HashSet<PathBuf>,
    /// Sources whose committed files are in `handed`.
    loaded: std::collections::HashSet<String>,
}

/// Whether a format stores one hit per file.
pub fn per_hit(f: Format) -> bool {
    matches!(f, Format::Wav | Format::CsvPerHit | Format::Text)
}

impl Follower {
    pub fn new(settle_s: f64) -> Follower {
        Follower {
            settle: Duration::from_secs_f64(settle_s.max(0.0)),
            seen: HashMap::new(),
            handed: Default::default(),
            loaded: Default::default(),
        }
    }

    /// Look at the inputs; the sources (or, one hit per file, the files) that are new and
    /// settled, in discovery's order.
    pub fn poll(&mut self, inputs: &[PathBuf], cfg: &ValidConfig, state: &State) -> Vec<Pending> {
        let d = crate::ingest::discover(inputs, &cfg.ingest);
        let now = Instant::now();
        let mut out = Vec::new();
        for s in d.sources {
            let read = state.sources.get(&s.id);
            if per_hit(s.format) {
                // Files committed before this process started count as handed out: one set
                // looked up by path, not rebuilt at each look.
                if self.loaded.insert(s.id.clone()) {
                    if let Some(r) = read {
                        self.handed.extend(r.files.iter().map(PathBuf::from));
                    }
                }
                let mut first_hit = 0;
                let mut new = Vec::new();
                let mut newest = None;
                let mut held = false;
                for f in &s.files {
                    if self.handed.contains(f) {
                        first_hit += 1;
                        continue;
                    }
                    // Every file is looked at (its settle clock starts now), but they are
                    // taken in order: the first one still changing holds back the ones
                    // after it (their hit numbers follow it).
                    let settled = self.settled(f, now);
                    match settled {
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
                out.push(Pending {
                    source: Source {
                        files: new,
                        first_hit,
                        ..s
                    },
                    per_hit: true,
                    written: newest,
                });
            } else {
                if read.is_some_and(|r| r.whole) || s.all_files().any(|f| self.handed.contains(f)) {
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
                    self.handed.insert(f.clone());
                }
                out.push(Pending {
                    source: s,
                    per_hit: false,
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
