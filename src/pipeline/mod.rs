//! The staged streaming runner.
//!
//! ```text
//! discover ─► read (thread) ─► bounded channel of batches ─► workers (rayon pool, order kept)
//!          ─► bounded channel ─► sink (thread): table + rejects ─► rename ─► manifest.json
//! ```
//!
//! Memory is bounded by the channel capacities: at most `2·queue_batches + 3` batches of
//! `batch_size` records exist at once, whatever the number of hits. Batches keep the reading
//! order and workers keep the order inside a batch (`collect` of an indexed parallel
//! iterator), so the output is the same, byte for byte, for any thread count. Every record
//! ends as a row or a reject row; a panic inside a per-record transform becomes a reject row.

use crate::config::PipelineConfig;
use crate::features::{features_table, validate, FeatureExtractor};
use crate::ingest::{self, Discovery, Source};
use crate::model::{Item, Reject, Stage};
use crate::store::{
    self, reject_row, rejects_table, waveform_row, waveforms_table, Row, TableWriter,
};
use crate::util::{file_digest, num_cpus, utc_now, write_atomic, IoAt};
use rayon::prelude::*;
use serde_json::json;
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error(transparent)]
    Store(#[from] store::StoreError),
    #[error(transparent)]
    Io(#[from] IoAt),
    #[error("cannot start the worker pool: {0}")]
    Pool(String),
    #[error("no input given")]
    NoInput,
}

/// What a run produces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StreamJob {
    /// `features.parquet` + `rejects.parquet` + `manifest.json`.
    Features,
    /// `waveforms.parquet` (canonical waveforms) + `rejects.parquet` + `manifest.json`.
    Waveforms,
}

impl StreamJob {
    pub fn table_file(self) -> &'static str {
        match self {
            StreamJob::Features => "features.parquet",
            StreamJob::Waveforms => "waveforms.parquet",
        }
    }
    pub(crate) fn name(self) -> &'static str {
        match self {
            StreamJob::Features => "features",
            StreamJob::Waveforms => "waveforms",
        }
    }
}

#[derive(Debug, Clone)]
pub struct StreamOptions {
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Show a progress bar (only drawn when stderr is a terminal).
    pub progress: bool,
    /// [`run`]: reuse the finished, unchanged per-experiment parts of an earlier run.
    pub resume: bool,
    /// [`run`]: only this shard's experiments, published as a Hive-partitioned dataset.
    pub shard: Option<crate::util::Shard>,
}

impl Default for StreamOptions {
    fn default() -> Self {
        StreamOptions {
            threads: 0,
            progress: true,
            resume: false,
            shard: None,
        }
    }
}

/// Counts of one experiment. The accounting rule: hits in = `hits` (rows of
/// `hits.parquet`); transients in = `rows` + `rejects`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Counts {
    pub hits: u64,
    pub rows: u64,
    pub rejects: u64,
}

/// What a streaming run did.
#[derive(Debug, Clone, Default)]
pub struct StreamStats {
    /// Records the readers produced (before validation).
    pub records_read: u64,
    /// Rows of `hits.parquet`.
    pub hits: u64,
    pub rows: u64,
    pub rejects: u64,
    pub by_experiment: BTreeMap<String, Counts>,
    /// Rejects by stage.
    pub by_stage: BTreeMap<String, u64>,
    /// The first few reject lines, for the terminal.
    pub first_rejects: Vec<String>,
    /// What readers had to assume (at most 1 000, for the manifest).
    pub notes: Vec<crate::model::Note>,
    pub seconds: f64,
}

impl StreamStats {
    fn add_reject(&mut self, r: &Reject) {
        self.rejects += 1;
        self.by_experiment
            .entry(r.experiment.clone())
            .or_default()
            .rejects += 1;
        *self
            .by_stage
            .entry(r.stage.as_str().to_string())
            .or_default() += 1;
        if self.first_rejects.len() < 10 {
            let id = if r.record_id.is_empty() {
                String::new()
            } else {
                format!(" [{}]", r.record_id)
            };
            self.first_rejects
                .push(format!("{}{id}: {} ({})", r.source_file, r.reason, r.stage));
        }
    }
}

/// What [`run`] did, including where it wrote.
#[derive(Debug, Clone)]
pub struct RunReport {
    pub stats: StreamStats,
    pub table_path: PathBuf,
    pub hits_path: PathBuf,
    pub rejects_path: PathBuf,
    pub manifest_path: PathBuf,
    pub sources: Vec<Source>,
    pub skipped: Vec<(PathBuf, String)>,
}

enum Out {
    Row(String, Row),
    Hit(Box<crate::model::HitRow>),
    Reject(Reject),
    Note(crate::model::Note),
}

/// Per-worker states, checked out for a parallel job and returned afterwards, so that plans
/// and scratch buffers are made once per worker, not once per record.
pub struct StatePool<T> {
    free: Mutex<Vec<T>>,
}

/// A state checked out of a [`StatePool`]; returned to it when dropped.
pub struct Checkout<'a, T> {
    pool: &'a StatePool<T>,
    item: Option<T>,
}

impl<T> Default for StatePool<T> {
    fn default() -> Self {
        StatePool {
            free: Mutex::new(Vec::new()),
        }
    }
}

impl<T> std::ops::Deref for Checkout<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.item.as_ref().expect("checked out")
    }
}

impl<T> std::ops::DerefMut for Checkout<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        self.item.as_mut().expect("checked out")
    }
}

impl<T> StatePool<T> {
    /// A free state, or a new one from `make` when all are in use.
    pub fn checkout(&self, make: impl Fn() -> T) -> Checkout<'_, T> {
        let item = self
            .free
            .lock()
            .expect("pool lock")
            .pop()
            .unwrap_or_else(make);
        Checkout {
            pool: self,
            item: Some(item),
        }
    }
}

impl<T> Drop for Checkout<'_, T> {
    fn drop(&mut self) {
        if let Some(t) = self.item.take() {
            if let Ok(mut v) = self.pool.free.lock() {
                v.push(t);
            }
        }
    }
}

fn record_reject(r: &crate::model::AeRecord, stage: Stage, reason: String) -> Reject {
    Reject {
        experiment: r.experiment.clone(),
        source_file: r.source_file.clone(),
        record_id: format!("ch{} hit {}", r.channel, r.hit),
        stage,
        reason,
    }
}

fn process(job: StreamJob, ex: &mut FeatureExtractor, item: Item) -> Out {
    let rec = match item {
        Item::Reject(r) => return Out::Reject(r),
        Item::Hit(h) => return Out::Hit(h),
        Item::Note(n) => return Out::Note(n),
        Item::Record(r) => r,
    };
    if let Err(e) = validate(&rec, ex.config()) {
        return Out::Reject(record_reject(&rec, Stage::Validate, e.to_string()));
    }
    match job {
        StreamJob::Waveforms => Out::Row(rec.experiment.clone(), waveform_row(rec)),
        StreamJob::Features => {
            let res = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| ex.row(&rec)));
            match res {
                Ok(row) => Out::Row(rec.experiment.clone(), row),
                Err(p) => {
                    let msg = p
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default();
                    // The extractor may be mid-update: replace it.
                    *ex = FeatureExtractor::new(ex.config());
                    Out::Reject(record_reject(
                        &rec,
                        Stage::Features,
                        format!("internal error (please report): {msg}"),
                    ))
                }
            }
        }
    }
}

fn progress_bar(enabled: bool) -> indicatif::ProgressBar {
    if !enabled || !std::io::stderr().is_terminal() || std::env::var_os("CI").is_some() {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new_spinner();
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {pos} hits  {per_sec}  {elapsed}  {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    pb.enable_steady_tick(std::time::Duration::from_millis(200));
    pb
}

/// The Parquet key-value metadata of the job's table and of the other tables.
fn table_metadata(job: StreamJob, cfg: &PipelineConfig) -> (store::KeyValues, store::KeyValues) {
    let meta = vec![
        ("aepipe.config_sha256".to_string(), cfg.hash()),
        ("aepipe.job".to_string(), job.name().to_string()),
    ];
    let mut table_meta = meta.clone();
    if job == StreamJob::Features {
        table_meta.extend(crate::features::features_metadata(cfg));
    }
    (table_meta, meta)
}

/// Stream items through validation and the per-record transform into `out_dir`.
/// Writes the job's table and `rejects.parquet` atomically; returns the counts.
pub fn stream<I>(
    items: I,
    job: StreamJob,
    out_dir: &Path,
    cfg: &PipelineConfig,
    opts: &StreamOptions,
) -> Result<StreamStats, PipelineError>
where
    I: Iterator<Item = Item> + Send,
{
    let t0 = Instant::now();
    let threads = if opts.threads == 0 {
        num_cpus()
    } else {
        opts.threads
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("aepipe-worker-{i}"))
        .build()
        .map_err(|e| PipelineError::Pool(e.to_string()))?;
    let q = cfg.pipeline.queue_batches;
    let bs = cfg.pipeline.batch_size;
    let (table_meta, meta) = table_metadata(job, cfg);
    let table = match job {
        StreamJob::Features => features_table(cfg),
        StreamJob::Waveforms => waveforms_table(),
    };
    let mut table_w = TableWriter::create(
        &out_dir.join(job.table_file()),
        table,
        &table_meta,
        cfg.pipeline.row_group_rows,
    )?;
    let mut rej_w = TableWriter::create(
        &out_dir.join("rejects.parquet"),
        rejects_table(),
        &meta,
        cfg.pipeline.row_group_rows,
    )?;
    let mut hits_w = TableWriter::create(
        &out_dir.join("hits.parquet"),
        store::hits_table(),
        &meta,
        cfg.pipeline.row_group_rows,
    )?;
    let (tx_in, rx_in) = crossbeam_channel::bounded::<Vec<Item>>(q);
    let (tx_out, rx_out) = crossbeam_channel::bounded::<Vec<Out>>(q);
    let states: StatePool<FeatureExtractor> = StatePool::default();
    let pb = progress_bar(opts.progress);
    let read_count = std::sync::atomic::AtomicU64::new(0);

    let result: Result<StreamStats, PipelineError> = std::thread::scope(|s| {
        let read_count = &read_count;
        s.spawn(move || {
            let mut batch = Vec::with_capacity(bs);
            for it in items {
                if matches!(it, Item::Record(_)) {
                    read_count.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                }
                batch.push(it);
                if batch.len() >= bs
                    && tx_in
                        .send(std::mem::replace(&mut batch, Vec::with_capacity(bs)))
                        .is_err()
                {
                    return; // the sink stopped (an error): stop reading
                }
            }
            if !batch.is_empty() {
                let _ = tx_in.send(batch);
            }
        });
        let pb2 = pb.clone();
        let sink = s.spawn(move || -> Result<StreamStats, PipelineError> {
            let mut st = StreamStats::default();
            for outs in rx_out {
                for o in outs {
                    match o {
                        Out::Row(exp, row) => {
                            table_w.push(row)?;
                            st.rows += 1;
                            st.by_experiment.entry(exp).or_default().rows += 1;
                        }
                        Out::Hit(h) => {
                            hits_w.push(store::hit_row(&h))?;
                            st.hits += 1;
                            st.by_experiment.entry(h.experiment).or_default().hits += 1;
                        }
                        Out::Note(n) => {
                            if st.notes.len() < 1000 {
                                st.notes.push(n);
                            }
                        }
                        Out::Reject(r) => {
                            rej_w.push(reject_row(&r))?;
                            st.add_reject(&r);
                        }
                    }
                    pb2.inc(1);
                }
            }
            table_w.finish()?;
            rej_w.finish()?;
            hits_w.finish()?;
            Ok(st)
        });
        for batch in rx_in {
            let outs: Vec<Out> = pool.install(|| {
                batch
                    .into_par_iter()
                    .map_init(
                        || states.checkout(|| FeatureExtractor::new(cfg)),
                        |ex, item| process(job, ex, item),
                    )
                    .collect()
            });
            if tx_out.send(outs).is_err() {
                break;
            }
        }
        drop(tx_out);
        sink.join()
            .unwrap_or_else(|_| Err(PipelineError::Pool("the sink thread panicked".into())))
    });
    pb.finish_and_clear();
    let mut st = result?;
    st.records_read = read_count.into_inner();
    st.seconds = t0.elapsed().as_secs_f64();
    Ok(st)
}

/// What `OUT/parts/<key>/part.json` records of one finished experiment: enough to reuse
/// it on `--resume` only when nothing it depends on has changed.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize, PartialEq)]
struct PartRecord {
    tool_version: String,
    job: String,
    config_sha256: String,
    /// The source ids of the part (one experiment id).
    experiment: String,
    /// `(path, sha256)` of every input file the part read.
    inputs: Vec<(String, String)>,
    /// `(file name, sha256)` of each table in the part folder.
    outputs: Vec<(String, String)>,
    stats: PartStats,
}

/// The counts of one part (the serialisable half of [`StreamStats`]).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize, PartialEq)]
pub(crate) struct PartStats {
    records_read: u64,
    hits: u64,
    rows: u64,
    rejects: u64,
    by_experiment: BTreeMap<String, Counts>,
    by_stage: BTreeMap<String, u64>,
    first_rejects: Vec<String>,
    notes: Vec<(String, String, String)>,
}

impl PartStats {
    fn of(s: &StreamStats) -> PartStats {
        PartStats {
            records_read: s.records_read,
            hits: s.hits,
            rows: s.rows,
            rejects: s.rejects,
            by_experiment: s.by_experiment.clone(),
            by_stage: s.by_stage.clone(),
            first_rejects: s.first_rejects.clone(),
            notes: s
                .notes
                .iter()
                .map(|n| {
                    (
                        n.experiment.clone(),
                        n.source_file.clone(),
                        n.message.clone(),
                    )
                })
                .collect(),
        }
    }

    /// Add this part's counts to the batch's.
    pub(crate) fn add_to(&self, st: &mut StreamStats) {
        st.records_read += self.records_read;
        st.hits += self.hits;
        st.rows += self.rows;
        st.rejects += self.rejects;
        for (k, c) in &self.by_experiment {
            let e = st.by_experiment.entry(k.clone()).or_default();
            e.hits += c.hits;
            e.rows += c.rows;
            e.rejects += c.rejects;
        }
        for (k, n) in &self.by_stage {
            *st.by_stage.entry(k.clone()).or_default() += n;
        }
        for r in &self.first_rejects {
            if st.first_rejects.len() < 10 {
                st.first_rejects.push(r.clone());
            }
        }
        for (e, f, m) in &self.notes {
            if st.notes.len() < 1000 {
                st.notes.push(crate::model::Note {
                    experiment: e.clone(),
                    source_file: f.clone(),
                    message: m.clone(),
                });
            }
        }
    }
}

/// The folder of one experiment's part: its file-safe id and a short hash of the id itself,
/// so two ids that sanitise alike never share a folder.
fn part_dir(parts: &Path, id: &str) -> PathBuf {
    let h = crate::util::sha256_hex(id.as_bytes());
    parts.join(format!("{}-{}", crate::util::file_safe(id), &h[..8]))
}

/// The tables a part folder holds, in assembly order.
pub(crate) fn part_tables(job: StreamJob) -> [&'static str; 3] {
    [job.table_file(), "hits.parquet", "rejects.parquet"]
}

/// A finished part that may be reused: its record parses and matches `want` (tool, job,
/// config, inputs), and every table still has the hash it was written with.
fn reusable_part(dir: &Path, want: &PartRecord) -> Option<PartRecord> {
    let text = std::fs::read_to_string(dir.join("part.json")).ok()?;
    let rec: PartRecord = serde_json::from_str(&text).ok()?;
    if (
        &rec.tool_version,
        &rec.job,
        &rec.config_sha256,
        &rec.experiment,
        &rec.inputs,
    ) != (
        &want.tool_version,
        &want.job,
        &want.config_sha256,
        &want.experiment,
        &want.inputs,
    ) {
        return None;
    }
    for (name, sha) in &rec.outputs {
        match file_digest(&dir.join(name)) {
            Ok((_, h)) if &h == sha => {}
            _ => return None,
        }
    }
    Some(rec)
}

/// One experiment's finished part: where its three tables are and what it counted.
pub(crate) struct Part {
    pub(crate) id: String,
    /// The job's table, `hits.parquet`, `rejects.parquet`, in that order.
    pub(crate) tables: [PathBuf; 3],
    pub(crate) stats: PartStats,
    pub(crate) reused: bool,
    /// `(path, sha256)` of the files it read.
    pub(crate) inputs: Vec<(String, String)>,
    /// `(file name, sha256)` of its tables, as recorded when they were written.
    pub(crate) outputs: Vec<(String, String)>,
    pub(crate) dir: PathBuf,
}

/// Discovery, the input digests and every owned experiment streamed into its part.
pub(crate) struct Produced {
    pub(crate) sources: Vec<Source>,
    pub(crate) discover_rejects: Vec<Reject>,
    pub(crate) skipped: Vec<(PathBuf, String)>,
    /// The manifest's `inputs` entries of the owned experiments.
    pub(crate) inputs_json: Vec<serde_json::Value>,
    pub(crate) parts: Vec<Part>,
    pub(crate) t_discover: f64,
    pub(crate) t_hash: f64,
    pub(crate) t_stream: f64,
}

fn produce(
    job: StreamJob,
    inputs: &[PathBuf],
    out_dir: &Path,
    cfg: &PipelineConfig,
    opts: &StreamOptions,
) -> Result<Produced, PipelineError> {
    let t0 = Instant::now();
    let parts_root = out_dir.join("parts");
    if !opts.resume {
        let _ = std::fs::remove_dir_all(&parts_root);
    }
    let Discovery {
        mut sources,
        rejects: discover_rejects,
        skipped,
    } = ingest::discover(inputs, &cfg.ingest);
    if let Some(sh) = opts.shard {
        sources.retain(|s| sh.owns(&s.id));
    }
    let t_discover = t0.elapsed().as_secs_f64();

    let t1 = Instant::now();
    let files: Vec<(PathBuf, &Source)> = sources
        .iter()
        .flat_map(|s| s.all_files().map(move |f| (f.clone(), s)))
        .collect();
    let digested: Vec<(serde_json::Value, String)> = files
        .par_iter()
        .map(|(f, s)| {
            let (size, sha) = match file_digest(f) {
                Ok((n, h)) => (json!(n), h),
                Err(e) => (json!(null), format!("unreadable: {e}")),
            };
            (
                json!({"path": f.display().to_string(), "experiment": s.id, "format": s.format.as_str(), "size_bytes": size, "sha256": sha}),
                sha,
            )
        })
        .collect();
    let t_hash = t1.elapsed().as_secs_f64();
    let input_hash: BTreeMap<&Path, &str> = files
        .iter()
        .zip(&digested)
        .map(|((f, _), (_, h))| (f.as_path(), h.as_str()))
        .collect();

    let t2 = Instant::now();
    let config_sha256 = cfg.hash();
    let mut parts = Vec::new();
    // Sources are sorted by id: one part per run of equal ids.
    for g in sources.chunk_by(|a, b| a.id == b.id) {
        let id = g[0].id.clone();
        let dir = part_dir(&parts_root, &id);
        let want = PartRecord {
            tool_version: env!("CARGO_PKG_VERSION").into(),
            job: job.name().into(),
            config_sha256: config_sha256.clone(),
            experiment: id.clone(),
            inputs: g
                .iter()
                .flat_map(|s| s.all_files())
                .map(|f| {
                    (
                        f.display().to_string(),
                        input_hash
                            .get(f.as_path())
                            .copied()
                            .unwrap_or("")
                            .to_string(),
                    )
                })
                .collect(),
            outputs: Vec::new(),
            stats: PartStats::default(),
        };
        let reused = if opts.resume {
            reusable_part(&dir, &want)
        } else {
            None
        };
        let reused_flag = reused.is_some();
        let rec = match reused {
            Some(rec) => rec,
            None => {
                let _ = std::fs::remove_dir_all(&dir);
                std::fs::create_dir_all(&dir).map_err(|e| IoAt::new(&dir, e))?;
                let icfg = cfg.ingest.clone();
                let items = g.iter().flat_map(move |s| ingest::open(s, &icfg));
                let st = stream(items, job, &dir, cfg, opts)?;
                let mut rec = want;
                for name in part_tables(job) {
                    let p = dir.join(name);
                    let (_, h) = file_digest(&p).map_err(|e| IoAt::new(&p, e))?;
                    rec.outputs.push((name.to_string(), h));
                }
                rec.stats = PartStats::of(&st);
                let text = serde_json::to_string_pretty(&rec).expect("part record serialises");
                write_atomic(&dir.join("part.json"), text.as_bytes())?;
                rec
            }
        };
        parts.push(Part {
            tables: part_tables(job).map(|n| dir.join(n)),
            id,
            stats: rec.stats,
            reused: reused_flag,
            inputs: rec.inputs,
            outputs: rec.outputs,
            dir,
        });
    }
    Ok(Produced {
        discover_rejects,
        skipped,
        inputs_json: digested.into_iter().map(|(v, _)| v).collect(),
        parts,
        t_discover,
        t_hash,
        t_stream: t2.elapsed().as_secs_f64(),
        sources,
    })
}

/// The whole-batch tables (discovery's rejects, then every part in order) and the manifest.
pub(crate) fn assemble(
    job: StreamJob,
    out_dir: &Path,
    cfg: &PipelineConfig,
    opts: &StreamOptions,
    started: String,
    t0: Instant,
    p: Produced,
) -> Result<RunReport, PipelineError> {
    let table_path = out_dir.join(job.table_file());
    let rejects_path = out_dir.join("rejects.parquet");
    let hits_path = out_dir.join("hits.parquet");
    let manifest_path = out_dir.join("manifest.json");
    let mut stats = StreamStats::default();
    for r in &p.discover_rejects {
        stats.add_reject(r);
    }
    for part in &p.parts {
        part.stats.add_to(&mut stats);
    }
    let (table_meta, meta) = table_metadata(job, cfg);
    let table = match job {
        StreamJob::Features => features_table(cfg),
        StreamJob::Waveforms => waveforms_table(),
    };
    let schemas = [table, store::hits_table(), rejects_table()];
    let paths = [&table_path, &hits_path, &rejects_path];
    for (k, schema) in schemas.into_iter().enumerate() {
        let kv = if k == 0 { &table_meta } else { &meta };
        let mut w = TableWriter::create(paths[k], schema, kv, cfg.pipeline.row_group_rows)?;
        if k == 2 {
            for r in &p.discover_rejects {
                w.push(reject_row(r))?;
            }
        }
        for part in &p.parts {
            w.append_file(&part.tables[k])?;
        }
        w.finish()?;
    }
    stats.seconds = p.t_stream;

    let manifest = json!({
        "tool": {"name": "aepipe", "version": env!("CARGO_PKG_VERSION")},
        "job": job.name(),
        "started_utc": started,
        "finished_utc": utc_now(),
        "threads": if opts.threads == 0 { num_cpus() } else { opts.threads },
        "config_sha256": cfg.hash(),
        "config": serde_json::to_value(cfg).unwrap_or(json!(null)),
        "inputs": p.inputs_json,
        "parts": p.parts.iter().map(|x| json!({"experiment": x.id, "dir": x.dir.display().to_string(), "reused": x.reused})).collect::<Vec<_>>(),
        "skipped": p.skipped.iter().map(|(p, why)| json!({"path": p.display().to_string(), "reason": why})).collect::<Vec<_>>(),
        "experiments": p.sources.iter().map(|s| json!({"id": s.id, "format": s.format.as_str(), "files": s.files.len(), "companions": s.companions.iter().map(|p| p.display().to_string()).collect::<Vec<_>>()})).collect::<Vec<_>>(),
        "outputs": {
            "table": {"path": table_path.display().to_string(), "rows": stats.rows},
            "rejects": {"path": rejects_path.display().to_string(), "rows": stats.rejects},
            "hits": {"path": hits_path.display().to_string(), "rows": stats.hits},
        },
        "notes": stats.notes.iter().map(|n| json!({"experiment": n.experiment, "file": n.source_file, "note": n.message})).collect::<Vec<_>>(),
        "counts": {
            "records_read": stats.records_read,
            "hits_written": stats.hits,
            "rows_written": stats.rows,
            "rejects": stats.rejects,
            "rejects_by_stage": stats.by_stage,
            "by_experiment": stats.by_experiment,
        },
        "timings_s": {"discover": p.t_discover, "hash_inputs": p.t_hash, "stream": stats.seconds, "total": t0.elapsed().as_secs_f64()},
    });
    let text = serde_json::to_string_pretty(&manifest).expect("manifest serialises");
    write_atomic(&manifest_path, text.as_bytes())?;
    Ok(RunReport {
        stats,
        table_path,
        hits_path,
        rejects_path,
        manifest_path,
        sources: p.sources,
        skipped: p.skipped,
    })
}

/// Discover, read, transform and write: the whole `aepipe features` / `aepipe waveforms` job.
///
/// Each experiment is streamed into its own part folder (`OUT/parts/<id>-<hash>/`: the
/// tables and, written last, `part.json`), then the whole-batch tables are assembled from
/// the parts in experiment order. With `resume`, a part whose `part.json` matches the tool,
/// job, config and input hashes, and whose tables still have their recorded hashes, is
/// reused as it is; the rest are redone. The assembled tables are the same, byte for byte,
/// either way.
///
/// With `shard` = K/N only the experiments of shard K are done, and instead of whole-batch
/// tables the shard publishes its parts as a Hive-partitioned dataset
/// (`OUT/<table>/experiment=<id>/part-K.parquet`) with `OUT/shards/shard-K-of-N.json`;
/// [`merge`] assembles the batch from all N.
pub fn run(
    job: StreamJob,
    inputs: &[PathBuf],
    out_dir: &Path,
    cfg: &PipelineConfig,
    opts: &StreamOptions,
) -> Result<RunReport, PipelineError> {
    if inputs.is_empty() {
        return Err(PipelineError::NoInput);
    }
    let started = utc_now();
    let t0 = Instant::now();
    std::fs::create_dir_all(out_dir).map_err(|e| IoAt::new(out_dir, e))?;
    store::clean_stale_tmp(out_dir);
    // Outputs of an earlier run are removed first: the files in `out_dir` always belong to
    // one complete run (an interrupted run leaves none rather than a stale mixture). Parts
    // stay only for `--resume`, which checks each before reusing it.
    for f in [
        job.table_file(),
        "hits.parquet",
        "rejects.parquet",
        "manifest.json",
    ] {
        let _ = std::fs::remove_file(out_dir.join(f));
    }
    let produced = produce(job, inputs, out_dir, cfg, opts)?;
    match opts.shard {
        None => assemble(job, out_dir, cfg, opts, started, t0, produced),
        Some(sh) => shard::publish(job, inputs, out_dir, cfg, sh, started, produced),
    }
}

mod shard;
pub use shard::{merge, read_shards, MergeError, ShardExperiment, ShardManifest};
