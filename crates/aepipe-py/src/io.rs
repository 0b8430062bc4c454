//! Reading recordings: hit rows and waveforms of any input the command line reads.

use crate::control;
use crate::errors;
use crate::frames::ArrowStream;
use aepipe::config::{PipelineConfig, ValidConfig};
use aepipe::ingest::{self, discover};
use aepipe::model::{AeRecord, Item, RecordType, Reject};
use aepipe::store::{self, Row, TableSchema};
use aepipe::util::JobControl;
use numpy::{PyArray1, PyUntypedArrayMethods};
use pyo3::prelude::*;
use rayon::prelude::*;
use std::path::PathBuf;

/// Rows per Arrow batch handed to Python.
const BATCH_ROWS: usize = 4096;

/// The configuration: a pipeline TOML file, or the defaults.
pub fn config_of(config: Option<PathBuf>) -> PyResult<ValidConfig> {
    match config {
        Some(p) => PipelineConfig::from_file(&p).map_err(errors::config),
        None => Ok(ValidConfig::default()),
    }
}

/// A reject as Python sees it: (file, record, stage, reason).
pub type RejectTuple = (String, String, String, String);

pub fn reject_tuple(r: &Reject) -> RejectTuple {
    (
        r.source_file.clone(),
        r.record_id.clone(),
        r.stage.as_str().to_string(),
        r.reason.clone(),
    )
}

/// The sources under `paths`; inputs that cannot be read at all are rejects, and when
/// nothing at all can be read that is an `IngestError` naming why.
fn sources(
    paths: &[PathBuf],
    cfg: &ValidConfig,
) -> PyResult<(Vec<ingest::Source>, Vec<RejectTuple>)> {
    let d = discover(paths, &cfg.ingest);
    if d.sources.is_empty() {
        let why: Vec<String> = d
            .rejects
            .iter()
            .map(|r| format!("{}: {}", r.source_file, r.reason))
            .chain(
                d.skipped
                    .iter()
                    .map(|(p, w)| format!("{}: {w}", p.display())),
            )
            .collect();
        return Err(errors::IngestError::new_err(if why.is_empty() {
            "no recordings found in the inputs".to_string()
        } else {
            format!("no readable recording in the inputs: {}", why.join("; "))
        }));
    }
    let rejects = d.rejects.iter().map(reject_tuple).collect();
    Ok((d.sources, rejects))
}

/// Rows into batches of one table.
pub fn batches(schema: &TableSchema, rows: Vec<Row>) -> PyResult<ArrowStream> {
    let mut out = Vec::new();
    let mut rows = rows;
    while !rows.is_empty() {
        let rest = rows.split_off(rows.len().min(BATCH_ROWS));
        out.push(
            store::rows_to_batch(schema, &rows).map_err(|e| errors::store_msg(e.to_string()))?,
        );
        rows = rest;
    }
    Ok(ArrowStream::new(schema.arrow_schema(), out))
}

/// Every item of every source, in source order, read in parallel across sources; `keep`
/// turns an item into a row (or a reject) or drops it. Stops at the next item once the
/// caller cancels (`None`).
fn read_all(
    paths: &[PathBuf],
    cfg: &ValidConfig,
    lost: RecordType,
    control: &JobControl,
    keep: impl Fn(Item) -> Option<Result<Row, Reject>> + Sync,
) -> PyResult<Option<(Vec<Row>, Vec<RejectTuple>)>> {
    let (srcs, mut rejects) = sources(paths, cfg)?;
    let per: Vec<(Vec<Row>, Vec<RejectTuple>)> = srcs
        .par_iter()
        .map(|s| {
            let (mut rows, mut rej) = (Vec::new(), Vec::new());
            for it in ingest::open(s, cfg.read_settings(), &cfg.load) {
                if control.is_cancelled() {
                    break;
                }
                match it {
                    // Only what this call returns can be lost by it (a hit table does
                    // not miss a waveform; a file's loss counts for every call).
                    Item::Reject(r)
                        if r.record_type == lost || r.record_type == RecordType::File =>
                    {
                        rej.push(reject_tuple(&r))
                    }
                    Item::Reject(_) => {}
                    other => match keep(other) {
                        Some(Ok(row)) => {
                            rows.push(row);
                            control.add(1);
                        }
                        Some(Err(r)) => rej.push(reject_tuple(&r)),
                        None => {}
                    },
                }
            }
            (rows, rej)
        })
        .collect();
    if control.is_cancelled() {
        return Ok(None);
    }
    let mut rows = Vec::new();
    for (r, j) in per {
        rows.extend(r);
        rejects.extend(j);
    }
    Ok(Some((rows, rejects)))
}

/// The rows of a table read on a worker thread (see `control::run`), with the rejects.
fn read_table(
    py: Python<'_>,
    paths: Vec<PathBuf>,
    config: Option<PathBuf>,
    progress: bool,
    schema: TableSchema,
    lost: RecordType,
    keep: impl Fn(Item, &ValidConfig) -> Option<Result<Row, Reject>> + Send + Sync + 'static,
) -> PyResult<(ArrowStream, Vec<RejectTuple>)> {
    let cfg = config_of(config)?;
    let read = control::run(py, progress.then_some("records"), move |c| {
        read_all(&paths, &cfg, lost, &c, |it| keep(it, &cfg))
    })?;
    let Some((rows, rejects)) = read? else {
        return Err(pyo3::exceptions::PyKeyboardInterrupt::new_err(
            "aepipe: interrupted",
        ));
    };
    Ok((batches(&schema, rows)?, rejects))
}

/// `hits.parquet`'s rows of the inputs, and the rejects.
#[pyfunction]
#[pyo3(signature = (paths, config=None, progress=false))]
pub fn read_hits(
    py: Python<'_>,
    paths: Vec<PathBuf>,
    config: Option<PathBuf>,
    progress: bool,
) -> PyResult<(ArrowStream, Vec<RejectTuple>)> {
    // The RA–AF line of the given pipeline (`[crack_mode]`).
    let table = store::hits_table(config_of(config.clone())?.crack_mode);
    let schema = table.schema();
    read_table(
        py,
        paths,
        config,
        progress,
        schema,
        RecordType::Hit,
        move |it, _| match it {
            Item::Hit(h) => Some(Ok(table.row(*h))),
            _ => None,
        },
    )
}

/// A record the feature stage accepts, or its reject.
fn checked(r: AeRecord, cfg: &ValidConfig) -> Result<AeRecord, Reject> {
    match aepipe::features::validate(&r, &cfg.validate) {
        Ok(()) => Ok(r),
        Err(e) => Err(Reject::of_record(
            &r,
            aepipe::model::Stage::Validate,
            e.to_string(),
        )),
    }
}

/// `waveforms.parquet`'s rows (one per record, samples as a list), and the rejects.
#[pyfunction]
#[pyo3(signature = (paths, config=None, progress=false))]
pub fn read_waveforms(
    py: Python<'_>,
    paths: Vec<PathBuf>,
    config: Option<PathBuf>,
    progress: bool,
) -> PyResult<(ArrowStream, Vec<RejectTuple>)> {
    let table = store::waveforms_table();
    let schema = table.schema();
    read_table(
        py,
        paths,
        config,
        progress,
        schema,
        RecordType::Transient,
        move |it, cfg| match it {
            Item::Record(r) => {
                Some(checked(r, cfg).map(|r| table.row(store::WaveformRow::from(r))))
            }
            _ => None,
        },
    )
}

/// One waveform record; `samples` is a float32 NumPy array that owns the record's samples.
#[pyclass(module = "aepipe._aepipe", name = "Record", frozen)]
pub struct Record {
    #[pyo3(get)]
    experiment: String,
    #[pyo3(get)]
    channel: u32,
    #[pyo3(get)]
    hit: u64,
    #[pyo3(get)]
    time_s: Option<f64>,
    #[pyo3(get)]
    sample_rate_hz: f64,
    #[pyo3(get)]
    pretrigger_samples: u32,
    #[pyo3(get)]
    samples: Py<PyArray1<f32>>,
}

#[pymethods]
impl Record {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "Record(experiment={:?}, channel={}, hit={}, time_s={}, sample_rate_hz={}, pretrigger_samples={}, samples=<{} float32>)",
            self.experiment,
            self.channel,
            self.hit,
            self.time_s.map_or("None".to_string(), |t| t.to_string()),
            self.sample_rate_hz,
            self.pretrigger_samples,
            self.samples.bind(py).len()
        )
    }
}

type Items = Box<dyn Iterator<Item = Item> + Send>;

/// The records of the inputs, `batch_size` at a time: at most one batch in memory.
#[pyclass(module = "aepipe._aepipe", name = "WaveformIter")]
pub struct WaveformIter {
    /// Behind a lock only because a Python class must be shareable; one thread reads.
    items: std::sync::Mutex<Option<Items>>,
    cfg: ValidConfig,
    batch_size: usize,
    ready: std::collections::VecDeque<AeRecord>,
    rejects: Vec<RejectTuple>,
}

#[pymethods]
impl WaveformIter {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<Record>> {
        if self.ready.is_empty() {
            let (cfg, n) = (&self.cfg, self.batch_size);
            let mut guard = self.items.lock().unwrap_or_else(|p| p.into_inner());
            let Some(items) = guard.as_mut() else {
                return Ok(None);
            };
            let (batch, rejects, done) = py.detach(|| {
                let (mut batch, mut rejects) = (Vec::new(), Vec::new());
                while batch.len() < n {
                    match items.next() {
                        Some(Item::Record(r)) => match checked(r, cfg) {
                            Ok(r) => batch.push(r),
                            Err(j) => rejects.push(reject_tuple(&j)),
                        },
                        Some(Item::Reject(j))
                            if matches!(
                                j.record_type,
                                RecordType::Transient | RecordType::File
                            ) =>
                        {
                            rejects.push(reject_tuple(&j))
                        }
                        Some(_) => {}
                        None => return (batch, rejects, true),
                    }
                }
                (batch, rejects, false)
            });
            self.ready.extend(batch);
            self.rejects.extend(rejects);
            if done {
                *guard = None;
            }
            drop(guard);
            py.check_signals()?;
        }
        Ok(self.ready.pop_front().map(|r| Record {
            experiment: r.experiment,
            channel: r.channel,
            hit: r.hit,
            time_s: r.time_s,
            sample_rate_hz: r.sample_rate_hz,
            pretrigger_samples: r.pretrigger,
            samples: PyArray1::from_vec(py, r.samples).unbind(),
        }))
    }

    /// The rejects met so far: (file, record, stage, reason).
    #[getter]
    fn rejects(&self) -> Vec<RejectTuple> {
        self.rejects.clone()
    }

    /// Stop reading and let go of the open files now (also what dropping the iterator does).
    fn close(&mut self) {
        *self.items.lock().unwrap_or_else(|p| p.into_inner()) = None;
        self.ready.clear();
    }
}

#[pyfunction]
#[pyo3(signature = (paths, config=None, batch_size=256))]
pub fn iter_waveforms(
    paths: Vec<PathBuf>,
    config: Option<PathBuf>,
    batch_size: usize,
) -> PyResult<WaveformIter> {
    if batch_size == 0 {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "batch_size must be ≥ 1",
        ));
    }
    let cfg = config_of(config)?;
    let (srcs, rejects) = sources(&paths, &cfg)?;
    let c = cfg.clone();
    let items: Items = Box::new(
        srcs.into_iter()
            .flat_map(move |s| ingest::open(&s, c.read_settings(), &c.load)),
    );
    Ok(WaveformIter {
        items: std::sync::Mutex::new(Some(items)),
        cfg,
        batch_size,
        ready: Default::default(),
        rejects,
    })
}
