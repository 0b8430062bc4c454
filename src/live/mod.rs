//! `aepipe watch`: follow a test while it runs. Acquisition software that writes one file
//! per hit into a folder (WAV, CSV per hit, plain text) has each new file read once it has
//! stopped changing; a whole recording (a Vallen pair, a MISTRAS chain, a WaveExplorer or
//! long-CSV file, a Parquet table) is read once all its files have. Every `flush_s` the new
//! rows (features, hits, rejects, parametric, markers, and each hit's SOM class) are
//! written as Parquet parts in the Hive layout the shards use
//! (`DIR/<table>/experiment=<id>/part-N.parquet`), readable at any moment as one dataset,
//! and what has been read is committed with them (`DIR/watch/state.json`, written last and
//! atomically): a watcher killed at any point and started again with the same arguments
//! removes the parts of the flush it did not commit and reads on from the last commit, so
//! every hit is a row exactly once. `DIR/live.html` is rewritten at each flush.
//!
//! When the test ends (`until_idle_s` without new data) the finished files are run as
//! `aepipe run` would (`DIR/final`): the final tables are the offline run's, byte for byte.
//! The live rows are provisional in one way only: events and location are built there, on
//! the whole experiment.

pub mod bench;
mod follow;
mod page;
mod pending;
mod state;

use crate::config::ValidConfig;
use crate::model::columns as cols;
use crate::pipeline::{PartTable, StreamDir, StreamJob, StreamOptions};
use crate::som::tables::Model;
use crate::util::HasKind;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime};

pub use state::State;

/// Why watching failed.
#[derive(Debug, thiserror::Error)]
pub enum WatchError {
    /// The folder holds another watcher's state (another configuration), or the state
    /// cannot be read.
    #[error("{path}: {message}")]
    State { path: String, message: String },
    /// A map is needed and cannot be had (train_on = "criteria" needs the finished test).
    #[error("{0}")]
    Map(String),
    #[error(transparent)]
    Pipeline(#[from] crate::pipeline::PipelineError),
    #[error(transparent)]
    Store(#[from] crate::store::StoreError),
    #[error(transparent)]
    Som(#[from] crate::som::SomError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    #[error(transparent)]
    Workflow(#[from] crate::workflow::WorkflowError),
    #[error(transparent)]
    Events(#[from] crate::events::EventsError),
    #[error(transparent)]
    Io(#[from] crate::util::IoAt),
}

impl HasKind for WatchError {
    fn kind(&self) -> crate::util::ErrorKind {
        use crate::util::ErrorKind;
        match self {
            WatchError::State { .. } | WatchError::Map(_) => ErrorKind::Usage,
            WatchError::Pipeline(e) => e.kind(),
            WatchError::Store(e) => e.kind(),
            WatchError::Som(e) => e.kind(),
            WatchError::Plot(e) => e.kind(),
            WatchError::Workflow(e) => e.kind(),
            WatchError::Events(e) => e.kind(),
            WatchError::Io(_) => ErrorKind::Failed,
        }
    }
}

/// How `aepipe watch` follows its inputs (its timings are `[live]`).
#[derive(Debug, Clone, Default)]
pub struct WatchOptions {
    /// End when nothing new has come for this long…
    pub until_idle_s: Option<f64>,
    /// …then run the finished files as `aepipe run` does (`DIR/final`; the CLI always
    /// does, the lag benchmark does not).
    pub offline_at_end: bool,
    pub threads: usize,
    /// The map to classify with, as `[som] model` (over the configuration's); without
    /// either, one trained on the configured reference library at start.
    pub model: Option<PathBuf>,
}

/// One flush, as the terminal prints it.
#[derive(Debug, Clone, Default)]
pub struct Flush {
    pub number: u32,
    /// New hits and rows in this flush, and in all.
    pub hits: u64,
    pub rows: u64,
    pub rejects: u64,
    pub total_hits: u64,
    /// Hits per second over this flush's reading and computing.
    pub hits_per_s: f64,
    /// SOM class → new rows.
    pub classes: BTreeMap<String, u64>,
    /// Seconds from the newest file's last write to the commit, the longest in the flush.
    pub lag_s: f64,
    /// Events built (sources, when two or more channels hear them).
    pub events: u64,
    /// Each classified row with a time (for the page).
    pub points: Vec<LivePoint>,
}

/// A classified row as the page shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct LivePoint {
    pub key: crate::store::HitKey,
    pub class: String,
    pub time_s: f64,
    pub load_n: Option<f64>,
    pub amplitude_db: Option<f64>,
}

impl Flush {
    pub fn line(&self) -> String {
        let classes = if self.classes.is_empty() {
            String::new()
        } else {
            format!(" · {}", crate::util::tally(&self.classes))
        };
        let events = if self.events > 0 {
            format!(", {} events", self.events)
        } else {
            String::new()
        };
        format!(
            "flush {}: +{} hits ({} in all), {} rows, {} rejects{events}, {:.0} hits/s{classes}, lag {:.1} s",
            self.number,
            self.hits,
            self.total_hits,
            self.rows,
            self.rejects,
            self.hits_per_s,
            self.lag_s
        )
    }
}

/// What a watch did.
pub struct WatchSummary {
    pub state: State,
    /// The offline run of the finished files (with `until_idle_s`).
    pub last: Option<crate::workflow::RunSummary>,
    pub stopped_by_signal: bool,
}

/// The watcher's folders.
pub struct WatchDir(PathBuf);

impl WatchDir {
    pub fn new(p: impl Into<PathBuf>) -> WatchDir {
        WatchDir(p.into())
    }
    pub fn path(&self) -> &Path {
        &self.0
    }
    /// The Hive dataset of the streamed tables.
    pub fn tables(&self) -> StreamDir {
        StreamDir::new(&self.0)
    }
    /// The folders of the watcher's Hive tables (the only ones a restart cleans).
    pub fn table_dirs(&self) -> Vec<PathBuf> {
        let tables = self.tables();
        PartTable::ALL
            .iter()
            .map(|&t| tables.hive_dir(t, StreamJob::Features))
            .chain([self.0.join("classification")])
            .collect()
    }
    /// `DIR/classification/experiment=<id>/part-N.parquet`.
    pub fn classification_part(&self, experiment: &str, k: u32) -> PathBuf {
        crate::store::shard::hive_file(&self.0, "classification", experiment, k)
    }
    pub fn state(&self) -> PathBuf {
        self.0.join("watch").join("state.json")
    }
    fn scratch(&self) -> PathBuf {
        self.0.join("watch").join("flush")
    }
    pub fn map(&self) -> PathBuf {
        self.0.join("watch").join("map")
    }
    pub fn live_html(&self) -> PathBuf {
        self.0.join("live.html")
    }
    pub fn live_dir(&self) -> PathBuf {
        self.0.join("watch").join("live")
    }
    /// The offline run of the finished files.
    pub fn last(&self) -> PathBuf {
        self.0.join("final")
    }
}

/// The map the watcher classifies with.
fn the_map(
    cfg: &ValidConfig,
    threads: usize,
    dir: &WatchDir,
    inputs: &[PathBuf],
) -> Result<Option<Model>, WatchError> {
    use crate::som::settings::MapSource;
    match cfg.som.map_source() {
        MapSource::Given(m) => return Ok(Some(crate::som::tables::load_model(m)?)),
        _ if !cfg.som.enabled => return Ok(None),
        MapSource::Criteria => {
            return Err(WatchError::Map(
                "[som] train_on = \"criteria\" trains on the finished test's own hits: give a \
                 map (--model DIR, or [som] model) to classify while it runs"
                    .into(),
            ))
        }
        MapSource::Reference(_) => {}
    }
    let model_dir = dir.map();
    if model_dir.join("model.json").is_file() {
        return Ok(Some(crate::som::tables::load_model(&model_dir)?));
    }
    let reference_run = dir.path().join("watch").join("reference-run");
    let job = crate::workflow::RunJob::new(cfg, inputs, &reference_run, threads);
    let (model, _) = crate::workflow::train_reference_map(&job)?;
    crate::som::tables::save_model(&model, &model_dir, None)?;
    Ok(Some(model))
}

/// Follow `inputs` into `out` until `stop` is set (SIGINT, SIGTERM) or, with
/// `until_idle_s`, until nothing new has come for that long; `say` gets each flush's line.
pub fn watch(
    cfg: &ValidConfig,
    inputs: &[PathBuf],
    out: &Path,
    o: &WatchOptions,
    stop: &AtomicBool,
    mut say: impl FnMut(&str),
) -> Result<WatchSummary, WatchError> {
    let with_model = with_given_map(cfg, o)?;
    let cfg = with_model.as_ref().unwrap_or(cfg);
    let dir = WatchDir::new(out);
    std::fs::create_dir_all(dir.path().join("watch"))
        .map_err(|e| crate::util::IoAt::new(dir.path(), e))?;
    let mut state = State::recover(&dir, cfg)?;
    let model = the_map(cfg, o.threads, &dir, inputs)?;
    let mut follower = follow::Follower::new(cfg.live.settle_s, &state);
    let mut page = page::Page::new(&state);
    page.inputs = inputs
        .iter()
        .map(|p| format!("'{}'", p.display()))
        .collect::<Vec<_>>()
        .join(" ");
    page.write(&dir, &state, None, cfg)?;
    say(&format!(
        "watching {} input(s) into {} ({} hits committed before; live page {})",
        inputs.len(),
        dir.path().display(),
        state.hits,
        dir.live_html().display()
    ));
    let mut pending: Vec<pending::Pending> = Vec::new();
    let mut last_flush = Instant::now();
    let mut last_new = Instant::now();
    let mut stopped_by_signal = false;
    let mut backlog = false;
    loop {
        let signalled = stop.load(Ordering::Relaxed);
        // Between the slices of a backlog the inputs are not looked at again: what is
        // pending is flushed first.
        if !signalled && !backlog {
            let room = FLUSH_FILES.saturating_sub(pending.iter().map(|p| p.weight()).sum());
            let new = follower.poll(inputs, cfg, room);
            if !new.is_empty() {
                last_new = Instant::now();
            }
            pending.extend(new);
        }
        // Not idle while a growing pair holds hits waiting for their transients.
        let idle = o
            .until_idle_s
            .is_some_and(|s| last_new.elapsed() >= Duration::from_secs_f64(s))
            && !follower.waiting();
        let due = last_flush.elapsed() >= Duration::from_secs_f64(cfg.live.flush_s);
        // A full slice is not kept waiting for the flush time (a burst).
        let full = pending.iter().map(|p| p.weight()).sum::<usize>() >= FLUSH_FILES;
        if !pending.is_empty() && (due || signalled || idle || backlog || full) {
            // A burst is committed in slices: the hits that came first are readable
            // first, and a flush holds a bounded number of records.
            let (batch, rest) = take_files(std::mem::take(&mut pending), FLUSH_FILES);
            pending = rest;
            backlog = !pending.is_empty();
            let latest = batch.iter().rev().find_map(|p| page::latest_record(p, cfg));
            let f = flush(cfg, &dir, &mut state, &model, batch, o.threads)?;
            let cwt = latest.and_then(|r| page::draw_latest(&dir, cfg, &r, f.number));
            page.add(&f, &state, cwt);
            page.write(&dir, &state, Some(&f), cfg)?;
            say(&f.line());
            last_flush = Instant::now();
        }
        if signalled && pending.is_empty() {
            stopped_by_signal = true;
            break;
        }
        if backlog {
            continue;
        }
        if idle && pending.is_empty() {
            break;
        }
        std::thread::sleep(Duration::from_secs_f64(cfg.live.poll_s));
    }
    let last = if o.until_idle_s.is_some() && o.offline_at_end && !stopped_by_signal {
        Some(run_finished(cfg, inputs, &dir, o, &mut say)?)
    } else {
        None
    };
    Ok(WatchSummary {
        state,
        last,
        stopped_by_signal,
    })
}

/// The configuration with the given map (`--model`) as `[som] model`, if one is given.
fn with_given_map(cfg: &ValidConfig, o: &WatchOptions) -> Result<Option<ValidConfig>, WatchError> {
    // A given map is `[som] model`: the state's hash covers it (a restart with another map
    // is refused) and the final run uses it as `aepipe run` would.
    Ok(match &o.model {
        Some(m) => Some(
            cfg.clone()
                .with(|c| c.som.model = Some(m.clone()))
                .map_err(crate::workflow::WorkflowError::Config)?,
        ),
        None => None,
    })
}

/// At the end of the test, run the finished files as `aepipe run` does (`DIR/final`), so
/// the final tables are the offline run's.
fn run_finished(
    cfg: &ValidConfig,
    inputs: &[PathBuf],
    dir: &WatchDir,
    o: &WatchOptions,
    say: &mut impl FnMut(&str),
) -> Result<crate::workflow::RunSummary, WatchError> {
    say(&format!(
        "idle: running the finished files as aepipe run does into {}",
        dir.last().display()
    ));
    Ok(crate::workflow::run(&crate::workflow::RunJob::new(
        cfg,
        inputs,
        &dir.last(),
        o.threads,
    ))?)
}

/// One-hit-per-file records in one flush at most: a burst of 20 000 files is committed in
/// slices, each readable as soon as it is done.
const FLUSH_FILES: usize = 2000;

/// The first pending sources up to `limit` files (a one-hit-per-file source split, its hit
/// numbers carried on), and the rest.
fn take_files(
    pending: Vec<pending::Pending>,
    limit: usize,
) -> (Vec<pending::Pending>, Vec<pending::Pending>) {
    let mut take = Vec::new();
    let mut rest = Vec::new();
    let mut n = 0;
    for mut p in pending {
        if n >= limit {
            rest.push(p);
            continue;
        }
        if p.per_hit() && n + p.source.files.len() > limit {
            let tail = p.source.files.split_off(limit - n);
            let mut r = p.clone();
            r.source.first_hit = p.source.first_hit + p.source.files.len() as u64;
            r.source.files = tail;
            n = limit;
            take.push(p);
            rest.push(r);
            continue;
        }
        n += p.weight();
        take.push(p);
    }
    (take, rest)
}

/// Read the pending sources, write their rows as the next parts and commit.
fn flush(
    cfg: &ValidConfig,
    dir: &WatchDir,
    state: &mut State,
    model: &Option<Model>,
    batch: Vec<pending::Pending>,
    threads: usize,
) -> Result<Flush, WatchError> {
    let t0 = Instant::now();
    let mut f = Flush {
        number: state.flushes + 1,
        ..Default::default()
    };
    // One part per experiment, in id order.
    let mut by_exp: BTreeMap<String, Vec<pending::Pending>> = BTreeMap::new();
    for p in batch {
        by_exp.entry(p.source.id.clone()).or_default().push(p);
    }
    let scratch = dir.scratch();
    let mut newest_write: Option<SystemTime> = None;
    for (experiment, sources) in &by_exp {
        let _ = std::fs::remove_dir_all(&scratch);
        std::fs::create_dir_all(&scratch).map_err(|e| crate::util::IoAt::new(&scratch, e))?;
        let items = part_items(sources, cfg);
        let k = state.parts;
        let stream = StreamDir::new(&scratch);
        let mut after = continuation(state, experiment, sources);
        let run = crate::pipeline::run_part(
            experiment,
            items,
            sources.iter().find_map(|p| p.source.vaex()),
            StreamJob::Features,
            &scratch,
            cfg,
            &StreamOptions::with_threads(threads),
            &mut after,
        )?;
        let (st, ev) = (run.stats, run.events);
        state.events.insert(experiment.clone(), after.events_before);
        state.channels.insert(experiment.clone(), after.channels);
        f.events += ev.events;
        let tables = dir.tables();
        // A flush writes a part of every table a part of `aepipe run` has.
        for t in PartTable::ALL {
            let from = stream.table(t, StreamJob::Features);
            let to = tables.hive_file(t, StreamJob::Features, experiment, k);
            move_into(&from, &to)?;
        }
        if let Some(m) = model {
            let features = tables.hive_file(PartTable::Main, StreamJob::Features, experiment, k);
            classify_part(m, cfg, dir, experiment, k, features, &mut f)?;
        }
        state.parts += 1;
        f.hits += st.hits;
        f.rows += st.rows;
        f.rejects += st.rejects;
        for p in sources {
            state.mark(p);
            if let Some(w) = p.written {
                newest_write = Some(newest_write.map_or(w, |n: SystemTime| n.max(w)));
            }
        }
    }
    let _ = std::fs::remove_dir_all(&scratch);
    commit_flush(dir, state, &mut f, t0, newest_write)?;
    Ok(f)
}

/// The records of one experiment's pending sources, each read as far as it is pending (a
/// window of a growing Vallen pair, the items a MISTRAS chain held, or the whole source).
fn part_items<'a>(
    sources: &'a [pending::Pending],
    cfg: &'a ValidConfig,
) -> impl Iterator<Item = crate::model::Item> + Send + 'a {
    sources.iter().flat_map(|p| match &p.part {
        Some(pending::Part::Vallen(w)) => {
            crate::ingest::open_window(&p.source, w, cfg.read_settings(), &cfg.load)
        }
        Some(pending::Part::Dta { items, .. }) | Some(pending::Part::Stream { items, .. }) => {
            let items = std::mem::take(&mut *items.lock().expect("not poisoned"));
            crate::ingest::with_load_file(Box::new(items.into_iter()), &p.source, &cfg.load)
        }
        None => crate::ingest::open(&p.source, cfg.read_settings(), &cfg.load),
    })
}

/// Where the experiment's part goes on from (its channels taken out of the state until the
/// part gives them back), so that its events continue the experiment's.
fn continuation(
    state: &mut State,
    experiment: &str,
    sources: &[pending::Pending],
) -> crate::pipeline::Continuation {
    // Its sources are cut where no event spans the cut (growing pairs and chains), so
    // the part's events are the whole experiment's, numbered on.
    crate::pipeline::Continuation {
        events_before: state.events.get(experiment).copied().unwrap_or(0),
        channels: state.channels.remove(experiment).unwrap_or_default(),
        // The hit after the part's last hits (a later part of transients only has none).
        next_hit: sources
            .iter()
            .rev()
            .filter_map(|p| p.part.as_ref())
            .find(|p| p.hits() > 0)
            .and_then(|p| p.next_hit()),
    }
}

/// Classify the experiment's features part `k` (already in place) with the map: its
/// classification part moved into place, its classes counted and its points kept for the
/// page.
fn classify_part(
    m: &Model,
    cfg: &ValidConfig,
    dir: &WatchDir,
    experiment: &str,
    k: u32,
    features: PathBuf,
    f: &mut Flush,
) -> Result<(), WatchError> {
    let cls_dir = dir.scratch().join("som");
    match crate::som::classify::classify_tables(
        m,
        std::slice::from_ref(&features),
        Some(&cfg.som.label),
        &cls_dir,
        cfg.source_rows(),
        crate::som::classify::ClassifyRules::of(&cfg.som),
    ) {
        Ok(conf) => {
            for ((class, _), n) in &conf.counts {
                *f.classes.entry(class.clone()).or_default() += *n as u64;
            }
            let part = dir.classification_part(experiment, k);
            move_into(
                &crate::som::layout::ClassifyDir::new(&cls_dir).classification(),
                &part,
            )?;
            f.points.extend(class_points(experiment, &part, &features)?);
        }
        // A part whose rows are all unusable for the map (flat records): no
        // classification part. Any other error of the map is the run's.
        Err(crate::som::SomError::NoUsableRows) => {}
        Err(e) => return Err(e.into()),
    }
    Ok(())
}

/// Commit the flush: add its counts to the state and write the state (last), then the
/// flush's totals, speed and lag as of the commit.
fn commit_flush(
    dir: &WatchDir,
    state: &mut State,
    f: &mut Flush,
    t0: Instant,
    newest_write: Option<SystemTime>,
) -> Result<(), WatchError> {
    state.flushes += 1;
    state.hits += f.hits;
    state.rows += f.rows;
    state.rejects += f.rejects;
    for (k, v) in &f.classes {
        *state.classes.entry(k.clone()).or_default() += v;
    }
    state.commit(dir)?;
    f.total_hits = state.hits;
    f.hits_per_s = f.hits as f64 / t0.elapsed().as_secs_f64().max(1e-9);
    f.lag_s = newest_write
        .and_then(|w| SystemTime::now().duration_since(w).ok())
        .map_or(0.0, |d| d.as_secs_f64());
    Ok(())
}

/// Each classified row of `experiment`'s part as the page shows it: the classification part
/// joined with the features part on (channel, hit); rows without a time are left out.
fn class_points(
    experiment: &str,
    classification: &Path,
    features: &Path,
) -> Result<Vec<LivePoint>, WatchError> {
    use crate::store::TableScan;
    let f = TableScan::open(features)?;
    let df = f.columns(&[
        cols::CHANNEL.name,
        cols::HIT.name,
        cols::TIME_S.name,
        cols::LOAD_N.name,
        cols::PEAK_AMPLITUDE_DB.name,
    ])?;
    let (fc, fh) = (f.i32s(&df, cols::CHANNEL)?, f.i64s(&df, cols::HIT)?);
    let (ft, fl) = (f.floats(&df, cols::TIME_S)?, f.floats(&df, cols::LOAD_N)?);
    let fa = f.floats(&df, cols::PEAK_AMPLITUDE_DB)?;
    type At = (Option<f64>, Option<f64>, Option<f64>);
    let at: std::collections::HashMap<(i32, i64), At> = (0..df.height())
        .filter_map(|i| Some(((fc[i]?, fh[i]?), (ft[i], fl[i], fa[i]))))
        .collect();
    let c = TableScan::open(classification)?;
    let df = c.columns(&[cols::CHANNEL.name, cols::HIT.name, cols::SOM_LABEL.name])?;
    let (cc, ch, cl) = (
        c.i32s(&df, cols::CHANNEL)?,
        c.i64s(&df, cols::HIT)?,
        c.texts(&df, cols::SOM_LABEL)?,
    );
    Ok(cc
        .iter()
        .zip(&ch)
        .zip(cl)
        .filter_map(|((c, h), l)| {
            let (c, h) = ((*c)?, (*h)?);
            let (t, load, amp) = at.get(&(c, h))?;
            Some(LivePoint {
                key: (experiment.to_string(), c, h),
                class: l?,
                time_s: (*t)?,
                load_n: *load,
                amplitude_db: *amp,
            })
        })
        .collect())
}

/// Rename a finished table into its Hive place (the same disk: the scratch folder is in
/// `DIR`).
fn move_into(from: &Path, to: &Path) -> Result<(), WatchError> {
    if let Some(d) = to.parent() {
        std::fs::create_dir_all(d).map_err(|e| crate::util::IoAt::new(d, e))?;
    }
    std::fs::rename(from, to).map_err(|e| crate::util::IoAt::new(to, e))?;
    Ok(())
}
