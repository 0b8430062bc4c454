//! Whole jobs from Python: a simulation, a reference library, and `aepipe run`.

use crate::control;
use crate::errors;
use crate::frames::ArrowStream;
use aepipe::config::PipelineConfig;
use aepipe::sim::reference::{build_library_controlled, LibraryDir, ReferenceFile};
use aepipe::sim::{scenario::Params, SimError, SimJob, SimOptions};
use pyo3::prelude::*;
use std::path::PathBuf;

/// One simulation (a scenario by name, or a model file: Appendix-A sections or TOML):
/// `waveforms.parquet`'s rows, one per sensor, and the lines `aepipe simulate` prints.
#[pyfunction]
#[pyo3(signature = (scenario, params, model=None))]
pub fn simulate(
    py: Python<'_>,
    scenario: Option<String>,
    params: Vec<(String, f64)>,
    model: Option<PathBuf>,
) -> PyResult<(ArrowStream, Vec<String>)> {
    let done = control::run_in(py, None, move |_, dir| -> Result<_, SimError> {
        let job = SimJob {
            model,
            scenario,
            params: Params(params),
            sweep: Vec::new(),
            solver: None,
            out: dir.to_path_buf(),
            run: SimOptions::default(),
            acquisition: Default::default(),
        };
        let lines = aepipe::sim::run_job(&job)?.lines;
        let wf = job.out.join("waveforms.parquet");
        if !wf.is_file() {
            return Err(SimError::Model(
                "the model has no acoustic grid or sensors: it records no waveforms".into(),
            ));
        }
        let t = ArrowStream::read(&wf).map_err(|e| SimError::Io(e.to_string()))?;
        Ok((t, lines))
    })?;
    done.map_err(errors::sim)
}

/// A reference library (`pipelines/reference-library.toml`'s format; None: the embedded
/// default the demo uses): its `waveforms.parquet` rows.
#[pyfunction]
#[pyo3(signature = (path=None, threads=None, progress=false))]
pub fn reference_library(
    py: Python<'_>,
    path: Option<PathBuf>,
    threads: Option<usize>,
    progress: bool,
) -> PyResult<ArrowStream> {
    let f = match &path {
        Some(p) => ReferenceFile::read(p).map_err(errors::sim)?,
        None => ReferenceFile::default_library(),
    };
    let done = control::run_in(py, progress.then_some("simulations"), move |c, out| {
        aepipe::util::with_threads(threads.unwrap_or(0), || {
            build_library_controlled(&f.reference, out, None, false, Some(&c))?;
            ArrowStream::read(&LibraryDir::new(out).waveforms())
                .map_err(|e| SimError::Io(e.to_string()))
        })
    })?;
    done.map_err(errors::sim)
}

/// `aepipe run --config CONFIG INPUTS… --out OUT [--truth T]`: every enabled stage, the
/// report in `OUT/report.html`. Returns the summary as JSON text (the Python layer parses
/// it into a dict).
#[pyfunction]
#[pyo3(signature = (config, inputs, out, truth=None, threads=None, progress=false))]
pub fn run(
    py: Python<'_>,
    config: PathBuf,
    inputs: Vec<PathBuf>,
    out: PathBuf,
    truth: Option<PathBuf>,
    threads: Option<usize>,
    progress: bool,
) -> PyResult<String> {
    let cfg = PipelineConfig::from_file(&config).map_err(errors::config)?;
    let done = control::run(py, progress.then_some("records"), move |c| {
        let job = aepipe::workflow::RunJob {
            truth: truth.as_deref(),
            control: Some(c),
            ..aepipe::workflow::RunJob::new(&cfg, &inputs, &out, threads.unwrap_or(0))
        };
        aepipe::workflow::run(&job).map(|s| aepipe::workflow::summary_json(&s).to_string())
    })?;
    done.map_err(errors::workflow)
}
