//! The streaming core: reader thread → bounded channel → worker pool (order kept) → sink
//! thread writing the job's tables.

use super::layout::PartTable;
use super::{PipelineError, StreamJob, StreamOptions, StreamStats};
use crate::config::{PipelineConfig, ValidConfig};
use crate::features::{validate, FeatureExtractor};
use crate::model::{Item, Reject, Stage};
use crate::store::{self, Row, TableWriter};
use crate::util::num_cpus;
use rayon::prelude::*;
use std::io::IsTerminal;
use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

enum Out {
    Row(String, Row),
    /// Any item that passes through the workers unchanged (hits, rejects, notes, parametric
    /// and marker rows, setups, tallies).
    Item(Item),
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

fn process(
    job: StreamJob,
    ex: &mut FeatureExtractor,
    waveforms: &store::Table<store::WaveformRow>,
    item: Item,
) -> Out {
    let rec = match item {
        Item::Record(r) => r,
        other => return Out::Item(other),
    };
    if let Err(e) = validate(&rec, &ex.config().validate) {
        return Out::Item(Item::Reject(Reject::of_record(
            &rec,
            Stage::Validate,
            e.to_string(),
        )));
    }
    match job {
        StreamJob::Waveforms => Out::Row(
            rec.experiment.clone(),
            waveforms.row(store::WaveformRow::from(rec)),
        ),
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
                    *ex = FeatureExtractor::new(ex.config().clone());
                    Out::Item(Item::Reject(Reject::of_record(
                        &rec,
                        Stage::Features,
                        format!("internal error (please report): {msg}"),
                    )))
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
pub(crate) fn table_metadata(
    job: StreamJob,
    cfg: &PipelineConfig,
) -> (store::KeyValues, store::KeyValues) {
    let meta = vec![
        ("aepipe.config_sha256".to_string(), cfg.hash()),
        ("aepipe.job".to_string(), job.name().to_string()),
    ];
    let mut table_meta = meta.clone();
    if job == StreamJob::Features {
        table_meta.extend(crate::features::features_metadata(&cfg.dsp));
    }
    (table_meta, meta)
}

/// The writers of the five tables a job streams ([`PartTable`] but `Events`, which the events step writes after), with the typed tables that make
/// their rows.
pub(crate) struct JobWriters {
    pub(crate) table: TableWriter,
    pub(crate) hits: TableWriter,
    pub(crate) rejects: TableWriter,
    pub(crate) parametric: TableWriter,
    pub(crate) markers: TableWriter,
    hit_rows: store::Table<crate::model::HitRow>,
    reject_rows: store::Table<Reject>,
    parametric_rows: store::Table<crate::model::ParametricRow>,
    marker_rows: store::Table<crate::model::MarkerRow>,
}

impl JobWriters {
    /// Create the five streamed tables of `job` in `dir`, under their [`PartTable`] names.
    pub(crate) fn create(
        job: StreamJob,
        dir: &Path,
        cfg: &PipelineConfig,
    ) -> Result<JobWriters, PipelineError> {
        let (table_meta, meta) = table_metadata(job, cfg);
        let rg = cfg.pipeline.row_group_rows;
        let mk = |t: PartTable| {
            let kv = if t == PartTable::Main {
                &table_meta
            } else {
                &meta
            };
            TableWriter::create(&dir.join(t.file_name(job)), t.schema(job, cfg), kv, rg)
        };
        Ok(JobWriters {
            table: mk(PartTable::Main)?,
            hits: mk(PartTable::Hits)?,
            rejects: mk(PartTable::Rejects)?,
            parametric: mk(PartTable::Parametric)?,
            markers: mk(PartTable::Markers)?,
            hit_rows: store::hits_table(cfg.crack_mode),
            reject_rows: store::rejects_table(),
            parametric_rows: store::parametric_table(),
            marker_rows: store::markers_table(),
        })
    }

    pub(crate) fn finish(self) -> Result<(), PipelineError> {
        for w in [
            self.table,
            self.hits,
            self.rejects,
            self.parametric,
            self.markers,
        ] {
            w.finish()?;
        }
        Ok(())
    }
}

/// Write one item that is not a feature/waveform row into its table and count it.
fn sink_item(w: &mut JobWriters, st: &mut StreamStats, it: Item) -> Result<(), PipelineError> {
    match it {
        Item::Record(_) => unreachable!("records become rows or rejects in the workers"),
        Item::Hit(h) => {
            st.add_hit(&h.experiment);
            w.hits.push(w.hit_rows.row(*h))?;
        }
        Item::Reject(r) => {
            st.add_reject(&r);
            w.rejects.push(w.reject_rows.row(r))?;
        }
        Item::Note(n) => st.add_note(n),
        Item::Parametric(p) => {
            st.add_parametric(&p.experiment);
            w.parametric.push(w.parametric_rows.row(*p))?;
        }
        Item::Marker(m) => {
            st.add_marker(&m.experiment, m.kind);
            w.markers.push(w.marker_rows.row(*m))?;
        }
        Item::Setup(s) => st.setups.push(*s),
        Item::Tally(t) => st.add_tally(&t),
    }
    Ok(())
}

/// Stream items through validation and the per-record transform into `out_dir`.
/// Writes the job's five streamed tables atomically; returns the counts.
pub fn stream<I>(
    items: I,
    job: StreamJob,
    out_dir: &Path,
    cfg: &ValidConfig,
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
    let mut writers = JobWriters::create(job, out_dir, cfg)?;
    let (tx_in, rx_in) = crossbeam_channel::bounded::<Vec<Item>>(q);
    let (tx_out, rx_out) = crossbeam_channel::bounded::<Vec<Out>>(q);
    let states: StatePool<FeatureExtractor> = StatePool::default();
    let waveforms = store::waveforms_table();
    let pb = progress_bar(opts.progress);
    let read_count = std::sync::atomic::AtomicU64::new(0);

    let control = opts.control.clone();
    let result: Result<StreamStats, PipelineError> = std::thread::scope(|s| {
        let read_count = &read_count;
        let reader_control = control.clone();
        s.spawn(move || {
            let mut batch = Vec::with_capacity(bs);
            for it in items {
                if crate::util::cancelled(&reader_control) {
                    return; // the caller stopped the job: the sink sees a short stream
                }
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
        let sink_control = control.clone();
        let sink = s.spawn(move || -> Result<StreamStats, PipelineError> {
            let mut st = StreamStats::default();
            for outs in rx_out {
                for o in outs {
                    match o {
                        Out::Row(exp, row) => {
                            writers.table.push(row)?;
                            st.add_row(&exp);
                            pb2.inc(1);
                            if let Some(c) = &sink_control {
                                c.add(1);
                            }
                        }
                        Out::Item(it) => {
                            if matches!(it, Item::Hit(_) | Item::Reject(_)) {
                                pb2.inc(1);
                            }
                            // The control counts records done: rows and rejects.
                            if let (Some(c), Item::Reject(_)) = (&sink_control, &it) {
                                c.add(1);
                            }
                            sink_item(&mut writers, &mut st, it)?;
                        }
                    }
                }
            }
            if crate::util::cancelled(&sink_control) {
                // A stopped job's tables are incomplete: never finished under their names.
                return Err(PipelineError::Cancelled);
            }
            writers.finish()?;
            Ok(st)
        });
        for batch in rx_in {
            let outs: Vec<Out> = pool.install(|| {
                batch
                    .into_par_iter()
                    .map_init(
                        || states.checkout(|| FeatureExtractor::new(cfg)),
                        |ex, item| process(job, ex, &waveforms, item),
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
