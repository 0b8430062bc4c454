//! A Vallen `.pridb`/`.tradb` pair that the acquisition is still writing, read in windows
//! of sets (`aepipe watch`).
//!
//! New sets are found by `SetID` (integers only, in chunks; each query is its own short
//! read transaction, so a writer in rollback-journal mode is never held up for longer than
//! one chunk, and one in WAL mode not at all). A window is the run of sets from the last
//! one handed out up to the last *ready* hit: its transient is in the `.tradb` (the
//! acquisition writes it a little after the hit) and a parametric row at or after its time
//! is in the `.pridb` (so that its load is interpolated as the offline reader does), or it
//! has waited `wait` for them, after which it is accounted as the offline reader accounts
//! it (a hit without its transient is a reject row). A window is read by the offline
//! reader itself ([`super::Reader`]) over those sets only, its hits and rows numbered on
//! from the window before: a window's rows are the offline reader's rows.
//!
//! A transient that no hit links to is read as a standalone transient once the `.tradb`
//! has gone past it (a later transient of a hit was handed out) or the pair has stopped
//! growing for `settle`.
//!
//! What the window's rows depend on is decided by the sets up to its end: the committed
//! [`Position`] is enough to start again after a kill.

use super::pridb::{Acquisitions, HitRows, PriInfo, TraiOffsets};
use super::sets::{SetRows, SetWindow};
use super::{columns, missing_reject, missing_rejects, open_ro, time_base, Reader};
use crate::ingest::settings::IngestConfig;
use crate::ingest::{file_err, IngestError, Source, TimeSeries};
use crate::model::{Item, Reject};
use rusqlite::Connection;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap, HashSet, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Where the reading of a growing pair stands: what has been handed out (and, once
/// committed, what a restarted watcher goes on from).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Position {
    /// The last `.pridb` set read.
    pub pridb_set: i64,
    /// The last `.tradb` record read as a standalone transient (0: none).
    pub tradb_set: i64,
    /// Hits, marker and status rows, parametric rows read (the next window numbers on).
    pub hits: u64,
    pub marker_rows: u64,
    pub parametric_rows: u64,
}

/// (TRAI, channel, time in ticks): how a hit names its transient.
type Key = (i64, i64, i64);

/// A `.pridb` set not yet handed out.
struct Set {
    setid: i64,
    set_type: i64,
    time: i64,
    chan: i64,
    trai: i64,
    acquisition: u32,
    seen: Instant,
}

/// A `.tradb` record not yet handed out.
struct Arrived {
    key: Key,
    /// Its number when no hit links it (the `.tradb`'s own TRAI restarts).
    own_number: u64,
}

/// A transient of a window: (channel, number, `.tradb` SetID, TRAI), the reader's key.
type TransientKey = (i64, u64, i64, i64);

/// One window of a growing pair: what [`read`] turns into the offline reader's rows.
#[derive(Debug, Clone)]
pub struct Window {
    experiment: String,
    pridb: PathBuf,
    tradb: PathBuf,
    sets: SetWindow,
    /// Hits before the window.
    first_hit: u64,
    transients: Vec<TransientKey>,
    /// The window's hits' transients: key → acquisition.
    link: HashMap<Key, u32>,
    missing: Vec<Reject>,
    acq_starts: Vec<i64>,
    offsets: TraiOffsets,
    load: Arc<(TimeSeries, TimeSeries)>,
    pridb_time_base: f64,
    tradb_time_base: f64,
    max_samples: u64,
    /// Hits (`.pridb` hit rows) and transients in the window.
    pub hits: u64,
    /// Where the reading stands after this window.
    pub end: Position,
    /// The hit after the window (time, channel), when the window ends before a known one:
    /// it closes the window's last event.
    pub next_hit: Option<(f64, u32)>,
}

impl Window {
    /// Hits and standalone transients: how much reading the window is.
    pub fn weight(&self) -> usize {
        (self.hits as usize).max(self.transients.len()).max(1)
    }
}

/// How many rows one look reads at most from each file (the rest at the next look).
const SCAN_ROWS: i64 = 100_000;

/// Follows one growing pair.
pub struct Tail {
    experiment: String,
    pridb_path: PathBuf,
    tradb_path: PathBuf,
    pridb: Connection,
    tradb: Option<Connection>,
    pridb_time_base: f64,
    tradb_time_base: f64,
    /// `ae_data` has the configured load/extension columns: a hit waits for a parametric
    /// row at or after its time.
    scan_sql: String,
    needs_load: bool,
    handed: Position,
    scanned_pridb: i64,
    scanned_tradb: i64,
    acquisitions: Acquisitions,
    queue: VecDeque<Set>,
    /// Every hit's transient key seen, and whether the hit has been handed out.
    linked: HashMap<Key, bool>,
    /// `.tradb` records not handed out, by SetID.
    arrived: BTreeMap<i64, Arrived>,
    by_key: HashMap<Key, i64>,
    /// The `.tradb`'s own acquisitions (TRAI restarts), for standalone numbers.
    own_offset: i64,
    own_max: i64,
    /// The last `.tradb` record of a hit handed out.
    tradb_reached: i64,
    /// Time in ticks of the last parametric row holding the configured inputs.
    load_until: Option<i64>,
    grew: Instant,
    /// The latest hit time scanned, and the most a hit stored later has begun before one
    /// stored earlier (ticks): a window ends only where no hit still to come can belong
    /// to its last event.
    newest: i64,
    inversion: i64,
}

impl Tail {
    /// Start following `src` (a Vallen source with its `.pridb`) from `from` (what a
    /// watcher committed; the default for a new one).
    pub fn open(src: &Source, from: Position, cfg: &IngestConfig) -> Result<Tail, IngestError> {
        let pridb_path = src
            .companion(crate::ingest::Role::HitIndex)
            .map(Path::to_path_buf)
            .ok_or_else(|| file_err(Path::new(&src.id), "no .pridb to follow"))?;
        let tradb_path = src.files.first().cloned().unwrap_or_default();
        let pridb = open_live(&pridb_path)?;
        let cols = columns(&pridb, "ae_data");
        if cols.is_empty() {
            return Err(file_err(&pridb_path, "no ae_data table (yet)"));
        }
        let v = &cfg.vallen;
        let params: Vec<String> = [v.load_param, v.extension_param]
            .into_iter()
            .flatten()
            .map(|p| p.column())
            .filter(|p| cols.contains(p))
            .collect();
        let has_load = if params.is_empty() {
            "0".to_string()
        } else {
            params
                .iter()
                .map(|p| format!("{p} IS NOT NULL"))
                .collect::<Vec<_>>()
                .join(" AND ")
        };
        let scan_sql = format!(
            "SELECT SetID, SetType, Time, Chan, TRAI, {has_load} FROM ae_data \
             WHERE SetID > ?1 ORDER BY SetID LIMIT {SCAN_ROWS}"
        );
        let pridb_time_base = time_base(&pridb, "ae_globalinfo");
        let (tradb, tradb_time_base) = match open_live(&tradb_path) {
            Ok(c) if !columns(&c, "tr_data").is_empty() => {
                let tb = time_base(&c, "tr_globalinfo");
                (Some(c), tb)
            }
            _ => (None, 1e7),
        };
        Ok(Tail {
            experiment: src.id.clone(),
            pridb_path,
            tradb_path,
            pridb,
            tradb,
            pridb_time_base,
            tradb_time_base,
            scan_sql,
            needs_load: !params.is_empty(),
            handed: from,
            scanned_pridb: i64::MIN,
            scanned_tradb: i64::MIN,
            acquisitions: Acquisitions::default(),
            queue: VecDeque::new(),
            linked: HashMap::new(),
            arrived: BTreeMap::new(),
            by_key: HashMap::new(),
            own_offset: 0,
            own_max: 0,
            tradb_reached: i64::MIN,
            load_until: None,
            grew: Instant::now(),
            newest: i64::MIN,
            inversion: 0,
        })
    }

    /// Read what is new in the files and hand out the windows that are ready, each of about
    /// `max_hits` hits. `wait`: how long a hit waits for its transient and load; `settle`:
    /// how long the pair must not grow before a transient no hit links to is read as
    /// standalone; `gap_s`: a window ends only where the next hit comes more than this
    /// after every hit before it (the event builder's longest reach, so that no event spans
    /// two windows; 0: anywhere).
    pub fn look(
        &mut self,
        wait: Duration,
        settle: Duration,
        max_hits: usize,
        gap_s: f64,
        cfg: &IngestConfig,
    ) -> Result<Vec<Window>, IngestError> {
        // A file that ends inside a page is being written by something that does not take
        // SQLite's locks (a copy, a sync of a share): SQLite would read the missing part of
        // that page as zeros. Nothing is read until its pages are whole again.
        whole_pages(&self.pridb_path)?;
        whole_pages(&self.tradb_path)?;
        let now = Instant::now();
        // Each file to its end, the .pridb first: a transient is judged (linked or
        // standalone) only against the hits of every set before it.
        let mut grew = false;
        while let n @ 1.. = self.scan_pridb(now)? {
            grew = true;
            if n < SCAN_ROWS as usize {
                break;
            }
        }
        while let n @ 1.. = self.scan_tradb()? {
            grew = true;
            if n < SCAN_ROWS as usize {
                break;
            }
        }
        if grew {
            self.grew = now;
        }
        // The sets that are ready, in windows ending where no event can span the end.
        let gap = (gap_s.max(0.0) * self.pridb_time_base).ceil() as i64;
        let plan = self.plan(now, wait, gap, max_hits.max(1) as u64);
        let mut windows: Vec<Window> = Vec::new();
        if !plan.is_empty() {
            let load = Arc::new(read_load(&self.pridb, cfg));
            for sets in plan {
                let mut w = self.window(load.clone(), cfg);
                for _ in 0..sets {
                    let s = self.queue.pop_front().expect("planned");
                    self.take(s, &mut w);
                }
                // The hit that comes next in time closes the window's last event.
                w.next_hit = self
                    .queue
                    .iter()
                    .filter(|s| s.set_type == 2)
                    .min_by_key(|s| (s.time, s.setid))
                    .map(|s| {
                        (
                            s.time as f64 * (1.0 / self.pridb_time_base),
                            s.chan.max(0) as u32,
                        )
                    });
                windows.push(w);
            }
        }
        // Transients no hit links to, once the .tradb has gone past them (or the pair
        // stopped growing with nothing waiting).
        let quiet = self.queue.is_empty() && now.duration_since(self.grew) >= settle;
        let standalone: Vec<i64> = self
            .arrived
            .iter()
            .filter(|(&set, a)| {
                (quiet || set < self.tradb_reached) && !self.linked.contains_key(&a.key)
            })
            .map(|(&set, _)| set)
            .collect();
        if !standalone.is_empty() {
            if windows.is_empty() {
                let load = Arc::new(read_load(&self.pridb, cfg));
                windows.push(self.window(load, cfg));
            }
            let w = windows.last_mut().expect("one");
            for set in standalone {
                let a = self.arrived.remove(&set).expect("listed");
                self.by_key.remove(&a.key);
                w.transients.push((a.key.1, a.own_number, set, a.key.0));
                self.handed.tradb_set = self.handed.tradb_set.max(set);
            }
            w.end = self.handed;
        }
        for w in &mut windows {
            w.transients.sort_unstable();
        }
        Ok(windows)
    }

    /// Sets or transients are read but not yet handed out (waiting for a transient, a
    /// load or the pair to settle): the test is not idle.
    pub fn waiting(&self) -> bool {
        !self.queue.is_empty()
            || self
                .arrived
                .values()
                .any(|a| !self.linked.contains_key(&a.key))
    }

    /// How many sets each window takes: the run of ready sets from the front of the queue,
    /// cut where the next hit comes more than `gap` ticks after every hit before it, each
    /// window the longest such run of at most `max_hits` hits (longer if no cut comes
    /// sooner: an event is never split). The end of the ready run is a cut once nothing
    /// waits behind it and its last hit has waited `wait` for a next one.
    fn plan(&self, now: Instant, wait: Duration, gap: i64, max_hits: u64) -> Vec<usize> {
        // The earliest hit time from each set of the queue on (hits stored later may have
        // begun earlier).
        let mut later = vec![i64::MAX; self.queue.len() + 1];
        for (i, s) in self.queue.iter().enumerate().rev() {
            later[i] = if s.set_type == 2 {
                later[i + 1].min(s.time)
            } else {
                later[i + 1]
            };
        }
        // (sets before the cut, hits before it)
        let mut cuts: Vec<(usize, u64)> = Vec::new();
        let (mut hits, mut max_time, mut end) = (0u64, i64::MIN, 0usize);
        let mut last_seen = None;
        let mut stopped = false;
        for (i, s) in self.queue.iter().enumerate() {
            if s.set_type == 2 {
                // Every hit queued after the cut, and any still to come (no earlier than
                // the latest one less the largest inversion seen), beyond the reach.
                let reach = max_time.saturating_add(gap);
                let clear = later[i] > reach && self.newest.saturating_sub(self.inversion) > reach;
                if hits > 0 && (gap == 0 || clear) {
                    cuts.push((i, hits));
                }
                if !self.ready(s, now, wait) {
                    stopped = true;
                    break;
                }
                hits += 1;
                max_time = max_time.max(s.time);
                last_seen = Some(s.seen);
            }
            end = i + 1;
        }
        if !stopped && end > 0 {
            let quiet = last_seen.is_none_or(|t| now.duration_since(t) >= wait);
            if gap == 0 || quiet {
                cuts.push((end, hits));
            }
        }
        let mut plan = Vec::new();
        let (mut sets0, mut hits0, mut k) = (0usize, 0u64, 0usize);
        while k < cuts.len() {
            let mut j = k;
            while j + 1 < cuts.len() && cuts[j + 1].1 - hits0 <= max_hits {
                j += 1;
            }
            if cuts[j].0 > sets0 {
                plan.push(cuts[j].0 - sets0);
            }
            (sets0, hits0, k) = (cuts[j].0, cuts[j].1, j + 1);
        }
        plan
    }

    /// Whether a hit can be read as the offline reader would read it.
    fn ready(&self, s: &Set, now: Instant, wait: Duration) -> bool {
        if now.duration_since(s.seen) >= wait {
            return true;
        }
        let transient = s.trai <= 0 || self.by_key.contains_key(&(s.trai, s.chan, s.time));
        let load = !self.needs_load || self.load_until.is_some_and(|t| t >= s.time);
        transient && load
    }

    /// A new window starting after what was handed out.
    fn window(&self, load: Arc<(TimeSeries, TimeSeries)>, cfg: &IngestConfig) -> Window {
        let mut max_trai = self.acquisitions.max_trai_done.clone();
        max_trai.push(self.acquisitions.max_trai);
        Window {
            experiment: self.experiment.clone(),
            pridb: self.pridb_path.clone(),
            tradb: self.tradb_path.clone(),
            sets: SetWindow {
                after: self.handed.pridb_set,
                upto: self.handed.pridb_set,
                marker_rows: self.handed.marker_rows,
                parametric_rows: self.handed.parametric_rows,
            },
            first_hit: self.handed.hits,
            transients: Vec::new(),
            link: HashMap::new(),
            missing: Vec::new(),
            acq_starts: self.acquisitions.starts.clone(),
            offsets: TraiOffsets::new(&max_trai),
            load,
            pridb_time_base: self.pridb_time_base,
            tradb_time_base: self.tradb_time_base,
            max_samples: cfg.max_samples_per_record,
            hits: 0,
            end: self.handed,
            next_hit: None,
        }
    }

    /// Hand the set out in `w`.
    fn take(&mut self, s: Set, w: &mut Window) {
        match s.set_type {
            1 => self.handed.parametric_rows += 1,
            2 => {
                self.handed.hits += 1;
                w.hits += 1;
                if s.trai > 0 {
                    let key = (s.trai, s.chan, s.time);
                    self.linked.insert(key, true);
                    match self.by_key.remove(&key) {
                        Some(set) => {
                            self.arrived.remove(&set);
                            self.tradb_reached = self.tradb_reached.max(set);
                            w.link.insert(key, s.acquisition);
                            w.transients.push((
                                s.chan,
                                w.offsets.number(s.acquisition, s.trai),
                                set,
                                s.trai,
                            ));
                        }
                        None => w.missing.push(missing_reject(
                            &self.experiment,
                            &self.pridb_path.display().to_string(),
                            (s.acquisition, s.trai, s.chan),
                            if self.tradb.is_some() {
                                "it is not in the .tradb"
                            } else {
                                "no .tradb beside the .pridb"
                            },
                        )),
                    }
                }
            }
            3..=6 => self.handed.marker_rows += 1,
            _ => {}
        }
        self.handed.pridb_set = s.setid;
        w.sets.upto = s.setid;
        w.end = self.handed;
    }

    /// New `.pridb` sets (a chunk of at most [`SCAN_ROWS`]); how many.
    fn scan_pridb(&mut self, now: Instant) -> Result<usize, IngestError> {
        let rows = {
            let mut st = self
                .pridb
                .prepare_cached(&self.scan_sql)
                .map_err(|e| file_err(&self.pridb_path, format!("cannot list sets: {e}")))?;
            let rows: Vec<(i64, i64, i64, i64, i64, bool)> = st
                .query_map([self.scanned_pridb], |r| {
                    Ok((
                        r.get(0)?,
                        r.get::<_, Option<i64>>(1)?.unwrap_or(0),
                        r.get::<_, Option<i64>>(2)?.unwrap_or(0),
                        r.get::<_, Option<i64>>(3)?.unwrap_or(0),
                        r.get::<_, Option<i64>>(4)?.unwrap_or(0),
                        r.get::<_, Option<bool>>(5)?.unwrap_or(false),
                    ))
                })
                .and_then(|it| it.collect::<Result<Vec<_>, _>>())
                .map_err(|e| file_err(&self.pridb_path, format!("cannot list sets: {e}")))?;
            rows
        };
        let n = rows.len();
        for (setid, set_type, time, chan, trai, has_load) in rows {
            self.scanned_pridb = setid;
            if set_type == 2 {
                // Hits are stored as they end: one stored later may have begun earlier.
                self.inversion = self.inversion.max(self.newest.saturating_sub(time));
                self.newest = self.newest.max(time);
            }
            let acquisition = self.acquisitions.add(setid, set_type, time, trai);
            if set_type == 1 && has_load {
                self.load_until = Some(self.load_until.map_or(time, |t| t.max(time)));
            }
            let committed = setid <= self.handed.pridb_set;
            if set_type == 2 && trai > 0 {
                self.linked.insert((trai, chan, time), committed);
            }
            if !committed {
                self.queue.push_back(Set {
                    setid,
                    set_type,
                    time,
                    chan,
                    trai,
                    acquisition,
                    seen: now,
                });
            }
        }
        Ok(n)
    }

    /// New `.tradb` records (a chunk of at most [`SCAN_ROWS`]); how many.
    fn scan_tradb(&mut self) -> Result<usize, IngestError> {
        if self.tradb.is_none() {
            // The acquisition may create the .tradb after the .pridb.
            match open_live(&self.tradb_path) {
                Ok(c) if !columns(&c, "tr_data").is_empty() => {
                    self.tradb_time_base = time_base(&c, "tr_globalinfo");
                    self.tradb = Some(c);
                }
                _ => return Ok(0),
            }
        }
        let conn = self.tradb.as_ref().expect("opened");
        let rows: Vec<(i64, i64, i64, i64)> = {
            let mut st = conn
                .prepare_cached(&format!(
                    "SELECT SetID, Time, Chan, TRAI FROM tr_data WHERE SetID > ?1 \
                     ORDER BY SetID LIMIT {SCAN_ROWS}"
                ))
                .map_err(|e| file_err(&self.tradb_path, format!("cannot list records: {e}")))?;
            let rows = st
                .query_map([self.scanned_tradb], |r| {
                    Ok((
                        r.get(0)?,
                        r.get::<_, Option<i64>>(1)?.unwrap_or(0),
                        r.get::<_, Option<i64>>(2)?.unwrap_or(0),
                        r.get::<_, Option<i64>>(3)?.unwrap_or(0),
                    ))
                })
                .and_then(|it| it.collect::<Result<Vec<_>, _>>())
                .map_err(|e| file_err(&self.tradb_path, format!("cannot list records: {e}")))?;
            rows
        };
        let n = rows.len();
        for (setid, time, chan, trai) in rows {
            self.scanned_tradb = setid;
            // The .tradb's own acquisitions, as `transient_keys` numbers them.
            if trai > 0 && trai <= self.own_max {
                self.own_offset += self.own_max;
                self.own_max = 0;
            }
            self.own_max = self.own_max.max(trai);
            let key = (trai, chan, time);
            match self.linked.get(&key) {
                // Its hit was handed out (with it, or without it after the wait).
                Some(true) => {
                    self.tradb_reached = self.tradb_reached.max(setid);
                    continue;
                }
                // Read as standalone before.
                None if setid <= self.handed.tradb_set => continue,
                _ => {}
            }
            self.by_key.insert(key, setid);
            self.arrived.insert(
                setid,
                Arrived {
                    key,
                    own_number: (trai + self.own_offset).max(0) as u64,
                },
            );
        }
        Ok(n)
    }
}

/// An error when `path` (if there) ends inside a page: its header's page size does not
/// divide its length.
fn whole_pages(path: &Path) -> Result<(), IngestError> {
    use std::io::Read;
    let Ok(mut f) = std::fs::File::open(path) else {
        return Ok(());
    };
    let mut head = [0u8; 18];
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    if len == 0 {
        return Ok(()); // created, not written yet: SQLite reads it as empty
    }
    if f.read_exact(&mut head).is_err() {
        return Err(file_err(
            path,
            "shorter than a SQLite header: being written",
        ));
    }
    let page = match u16::from_be_bytes([head[16], head[17]]) {
        1 => 65536,
        p => u64::from(p),
    };
    if page < 512 || len % page != 0 {
        return Err(file_err(
            path,
            format!(
                "ends inside a page ({len} bytes, pages of {page}): its last page is being written"
            ),
        ));
    }
    Ok(())
}

/// A read-only connection to a database another process writes: a lock it meets waits up
/// to 2 s (a writer's commit) instead of failing the look.
fn open_live(path: &Path) -> Result<Connection, IngestError> {
    let c = open_ro(path)?;
    c.busy_timeout(Duration::from_secs(2))
        .map_err(|e| file_err(path, e.to_string()))?;
    Ok(c)
}

/// The load and extension series of everything the `.pridb` holds now.
fn read_load(conn: &Connection, cfg: &IngestConfig) -> (TimeSeries, TimeSeries) {
    super::pridb::load_series(
        conn,
        &columns(conn, "ae_data"),
        time_base(conn, "ae_globalinfo"),
        cfg,
    )
}

/// The window's latest transient (the last the `.tradb` stored), read alone: what the live
/// page draws.
pub fn last_record(w: &Window, cfg: &IngestConfig) -> Option<crate::model::AeRecord> {
    let last = *w.transients.iter().max_by_key(|t| t.2)?;
    let one = Window {
        sets: SetWindow {
            after: w.sets.upto,
            ..w.sets
        },
        transients: vec![last],
        missing: Vec::new(),
        ..w.clone()
    };
    read(&one, cfg).find_map(|i| match i {
        Item::Record(r) => Some(r),
        _ => None,
    })
}

/// The rows of one window, as the offline reader gives them for its sets.
pub fn read(w: &Window, cfg: &IngestConfig) -> Box<dyn Iterator<Item = Item> + Send> {
    let mut first: Vec<Item> = Vec::new();
    let file_reject = |p: &Path, reason: String| {
        Item::Reject(Reject {
            record_type: crate::model::RecordType::File,
            experiment: w.experiment.clone(),
            source_file: p.display().to_string(),
            record_id: String::new(),
            stage: crate::model::Stage::Read,
            reason,
        })
    };
    let (mut hits, mut sets) = (None, None);
    if w.sets.upto > w.sets.after {
        match HitRows::window(
            &w.pridb,
            w.pridb_time_base,
            w.sets.after,
            w.sets.upto,
            w.first_hit,
        ) {
            Ok(h) => hits = Some(h),
            Err(e) => first.push(file_reject(&w.pridb, format!("hits ignored: {e}"))),
        }
        match SetRows::window(
            &w.pridb,
            &w.experiment,
            w.pridb_time_base,
            &cfg.vallen,
            &w.sets,
        ) {
            Ok(s) => sets = Some(s),
            Err(e) => first.push(file_reject(
                &w.pridb,
                format!("parametric, status and marker rows ignored: {e}"),
            )),
        }
    }
    let mut keys: VecDeque<TransientKey> = w.transients.iter().copied().collect();
    let mut tail: VecDeque<Reject> = w.missing.iter().cloned().collect();
    let conn = if keys.is_empty() {
        None
    } else {
        match open_ro(&w.tradb) {
            Ok(c) => Some(c),
            Err(e) => {
                // As the offline reader: every transient the window's hits promise is a
                // reject saying why.
                first.push(file_reject(&w.tradb, e.to_string()));
                keys.clear();
                tail.extend(missing_rejects(
                    &w.experiment,
                    &w.pridb.display().to_string(),
                    &w.link,
                    &HashSet::new(),
                    "the .tradb cannot be read",
                ));
                None
            }
        }
    };
    let (load, extension) = (*w.load).clone();
    let info = PriInfo {
        acq_starts: w.acq_starts.clone(),
        link: w.link.clone(),
        load,
        extension,
        time_base: w.pridb_time_base,
        ..Default::default()
    };
    Box::new(first.into_iter().chain(Reader {
        experiment: w.experiment.clone(),
        hits,
        sets,
        has_pridb: true,
        last: VecDeque::new(),
        pending_hits: VecDeque::new(),
        tradb: w.tradb.clone(),
        conn,
        salvaged: None,
        time_base: w.tradb_time_base,
        keys,
        have: w.link.keys().copied().collect::<HashSet<Key>>(),
        offsets: w.offsets.clone(),
        info,
        tail,
        max_samples: w.max_samples,
        trf: HashMap::new(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ingest::vallen::{HitToWrite, Journal, PairWriter};

    /// A new pair `id` (WAL) in a folder of its own, its writer, and the source that reads it.
    pub(super) fn growing_pair(id: &str) -> (std::path::PathBuf, PairWriter, Source) {
        let dir = std::env::temp_dir().join(format!("aepipe-tail-{id}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let w = PairWriter::create(&dir.join(id), 1e-3, 1e-4, Journal::Wal).unwrap();
        let (pridb, tradb) = w.paths();
        let src = Source {
            id: id.into(),
            format: crate::ingest::Format::Vallen,
            files: vec![tradb],
            companions: vec![crate::ingest::Companion {
                role: crate::ingest::Role::HitIndex,
                path: pridb,
            }],
            first_hit: 0,
        };
        (dir, w, src)
    }

    fn describe(items: impl IntoIterator<Item = Item>) -> Vec<String> {
        let mut v: Vec<String> = items
            .into_iter()
            .filter(|i| !matches!(i, Item::Setup(_) | Item::Tally(_)))
            .map(|i| format!("{i:?}"))
            .collect();
        v.sort();
        v
    }

    /// A pair written in steps (WAL, the writer's connection open throughout): hits, their
    /// transients one step later, parametric rows, status rows, a restart of the recording,
    /// a hit without a transient index and one whose transient never comes. Read in
    /// windows, with the reader dropped once and opened again from its last window's end
    /// (a watcher killed after a commit), the windows' rows are the offline reader's on
    /// the finished pair, each once.
    #[test]
    fn windows_of_a_growing_pair_are_the_offline_rows() {
        let (dir, w, src) = growing_pair("t");
        let mut cfg = IngestConfig::default();
        cfg.vallen.load_param = Some(crate::ingest::settings::ParamInput(0));
        let e = crate::synth::Experiment::new("t", 36, 5);
        let recs: Vec<_> = e.records().collect();
        let hit = |k: usize| {
            let r = &recs[k];
            // Acquisition 2 from hit 24 on: TRAI starts again (its clock goes on: the
            // parametric series is one across acquisitions, offline as live).
            let (trai, t0) = if k < 24 { (k + 1, 0.0) } else { (k - 23, 0.0) };
            HitToWrite {
                channel: 1 + (k % 2) as u32,
                trai: if k == 7 { 0 } else { trai as u64 },
                time_s: t0 + 0.05 * (k + 1) as f64,
                sample_rate_hz: r.sample_rate_hz,
                pretrigger: r.pretrigger,
                samples_v: &r.samples,
                restart: false,
                transient: k != 7 && k != 13,
            }
        };
        let long = Duration::from_secs(3600);
        let mut tail = Tail::open(&src, Position::default(), &cfg).unwrap();
        // Nothing is there yet.
        assert!(tail.look(long, long, 5, 0.0, &cfg).unwrap().is_empty());
        let mut got = Vec::new();
        let mut last_end = Position::default();
        let take = |ws: Vec<Window>, got: &mut Vec<Item>, last_end: &mut Position| {
            for w in ws {
                assert!(w.hits <= 5, "a window of {} hits", w.hits);
                *last_end = w.end;
                got.extend(read(&w, &cfg));
            }
        };
        for step in 0..6 {
            let hits: Vec<usize> = (step * 6..step * 6 + 6).collect();
            w.batch(|w| {
                if step == 4 {
                    w.section(2)?;
                }
                for &k in &hits {
                    let h = hit(k);
                    w.parametric(h.time_s - 0.01, k as f64, 0.0)?;
                    w.hit(&h)?;
                }
                w.status(0.05 * (step * 6 + 6) as f64, 1, 1e-5)?;
                Ok(())
            })
            .unwrap();
            // A hit waits for its transient and for the parametric row after it.
            take(
                tail.look(long, long, 5, 0.0, &cfg).unwrap(),
                &mut got,
                &mut last_end,
            );
            assert!(
                last_end.hits <= (step * 6) as u64,
                "step {step}: a hit read before its transient was written"
            );
            w.batch(|w| {
                for &k in &hits {
                    let h = hit(k);
                    if h.transient {
                        w.transient(&h)?;
                    }
                }
                Ok(())
            })
            .unwrap();
            if step == 2 {
                // Killed after committing its last window: the next reader goes on from
                // there.
                tail = Tail::open(&src, last_end, &cfg).unwrap();
            }
            let ws = tail.look(long, long, 5, 0.0, &cfg).unwrap();
            // Hit 13's transient never comes: it (and every hit after it) waits.
            take(ws, &mut got, &mut last_end);
            // The step's last hit waits for the parametric row after it (its load).
            assert!(
                last_end.hits < (step * 6 + 6) as u64,
                "step {step}: a hit read before its load could be interpolated"
            );
            if step >= 2 {
                assert_eq!(last_end.hits, 13, "hit 14 read before hit 13's wait ended");
            } else {
                assert_eq!(last_end.hits, (step * 6 + 5) as u64);
            }
        }
        // The wait ends: the rest is read, hit 13 as the offline reader accounts for it.
        let ws = tail
            .look(Duration::ZERO, Duration::ZERO, 5, 0.0, &cfg)
            .unwrap();
        take(ws, &mut got, &mut last_end);
        assert!(tail
            .look(Duration::ZERO, Duration::ZERO, 5, 0.0, &cfg)
            .unwrap()
            .is_empty());
        assert_eq!(last_end.hits, 36);
        drop(w);
        let read =
            crate::ingest::settings::ReadSettings::new(cfg.check().unwrap(), Default::default());
        let offline = describe(super::super::open(&src, &read));
        let live = describe(got);
        assert_eq!(live.len(), offline.len(), "rows in the windows and offline");
        for (a, b) in live.iter().zip(&offline) {
            assert_eq!(a, b);
        }
        assert!(offline.iter().any(|r| r.contains("has no transient")));
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[cfg(test)]
mod cut_tests {
    use super::*;
    use crate::ingest::vallen::HitToWrite;

    /// Hits are stored as they end: a long hit that began first may be stored after a
    /// short one of a later source. A window must not end between it and its event's
    /// first hit, and the hit that comes next in time closes the window's last event.
    #[test]
    fn a_hit_stored_late_with_an_earlier_time_stays_with_its_event() {
        let (dir, w, src) = super::tests::growing_pair("c");
        let cfg = IngestConfig::default();
        let samples = vec![0.0f32; 256];
        let hit = |ch: u32, trai: u64, t: f64| HitToWrite {
            channel: ch,
            trai,
            time_s: t,
            sample_rate_hz: 1e7,
            pretrigger: 0,
            samples_v: &samples,
            restart: false,
            transient: true,
        };
        // P (ch1, 0 s, short), X (ch3, 5 ms), then Q (ch2, 0.05 ms: P's event, long, so
        // stored after X).
        for h in [hit(1, 1, 0.0), hit(3, 2, 5e-3), hit(2, 3, 0.05e-3)] {
            w.batch(|w| {
                w.hit(&h)?;
                w.transient(&h)
            })
            .unwrap();
        }
        let long = Duration::from_secs(3600);
        let gap = 1e-3;
        let mut tail = Tail::open(&src, Position::default(), &cfg).unwrap();
        // By SetID, X comes more than the reach after P; but Q, stored later, began within
        // it, and more may come as early as 5 ms − 4.95 ms: no window yet.
        assert!(tail.look(long, long, 100, gap, &cfg).unwrap().is_empty());
        // R (ch1, 20 ms) comes long after every one of them.
        let r = hit(1, 4, 20e-3);
        w.batch(|w| {
            w.hit(&r)?;
            w.transient(&r)
        })
        .unwrap();
        let ws = tail.look(long, long, 100, gap, &cfg).unwrap();
        assert_eq!(ws.len(), 1);
        assert_eq!(ws[0].hits, 3, "P, X and Q in one window");
        let (t, ch) = ws[0].next_hit.unwrap();
        assert!(
            (t - 20e-3).abs() < 1e-9 && ch == 1,
            "R closes the last event"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
