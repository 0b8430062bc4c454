//! The per-hit method from Python: the feature rows of files or of NumPy signals, the CWT of
//! one signal, and the four arrival pickers with their detection functions.

use crate::control::{self, ProgressLine};
use crate::errors;
use crate::frames::ArrowStream;
use crate::io::{batches, config_of};
use aepipe::dsp::cwt::{Cwt, WaveletBank};
use aepipe::dsp::pick::{self, PickScratch};
use aepipe::features::{features_table, validate, FeatureExtractor};
use aepipe::model::AeRecord;
use aepipe::pipeline::{StreamJob, StreamOptions};
use numpy::{PyArray1, PyArray2, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::prelude::*;
use std::path::PathBuf;

/// Signals computed between two looks for Ctrl-C (≈ 0.2 s on one thread).
const CHUNK: usize = 256;

/// A pool of `threads` workers (`None` or 0: all cores).
fn pool(threads: Option<usize>) -> PyResult<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()
        .map_err(|e| errors::AepipeError::new_err(e.to_string()))
}

/// `features.parquet` and `rejects.parquet` of the inputs, exactly as `aepipe features`
/// writes them (the same pipeline, into a temporary folder that is removed afterwards).
#[pyfunction]
#[pyo3(signature = (paths, config=None, threads=None, progress=false))]
pub fn features_of_paths(
    py: Python<'_>,
    paths: Vec<PathBuf>,
    config: Option<PathBuf>,
    threads: Option<usize>,
    progress: bool,
) -> PyResult<(ArrowStream, ArrowStream)> {
    let cfg = config_of(config)?;
    let done = control::run_in(py, progress.then_some("records"), move |c, out| {
        let opts = StreamOptions {
            threads: threads.unwrap_or(0),
            progress: false,
            control: Some(c),
            ..Default::default()
        };
        let report = aepipe::pipeline::run(StreamJob::Features, &paths, out, &cfg, &opts)?;
        Ok::<_, aepipe::pipeline::PipelineError>((
            ArrowStream::read(&report.table_path)?,
            ArrowStream::read(&report.rejects_path)?,
        ))
    })?;
    done.map_err(errors::pipeline)
}

/// Feature rows of signals given as arrays: experiment "array", channel 1, hit = 1-based
/// position, no trigger time.
#[pyfunction]
#[pyo3(signature = (signals, sample_rate_hz, pretrigger_samples=0, config=None, threads=None, progress=false))]
pub fn features_of_signals(
    py: Python<'_>,
    signals: Vec<PyReadonlyArray1<'_, f32>>,
    sample_rate_hz: f64,
    pretrigger_samples: u32,
    config: Option<PathBuf>,
    threads: Option<usize>,
    progress: bool,
) -> PyResult<ArrowStream> {
    let cfg = config_of(config)?;
    let pool = pool(threads)?;
    let table = features_table(&cfg.dsp, cfg.crack_mode);
    let mut rows = Vec::with_capacity(signals.len());
    let mut line = progress.then(|| ProgressLine::new("signals"));
    for (c, chunk) in signals.chunks(CHUNK).enumerate() {
        // The records own their samples: this chunk's are copied out of NumPy (one chunk
        // at a time, so the copy stays small), then computed without the interpreter.
        let recs: Vec<AeRecord> = chunk
            .iter()
            .enumerate()
            .map(|(i, a)| AeRecord {
                experiment: "array".into(),
                channel: 1,
                hit: (c * CHUNK + i + 1) as u64,
                time_s: None,
                sample_rate_hz,
                pretrigger: pretrigger_samples,
                samples: owned_samples(a),
                load_n: None,
                extension_m: None,
                label: None,
                threshold_v: None,
                source_file: String::new(),
                kind: Default::default(),
            })
            .collect();
        for r in &recs {
            validate(r, &cfg.validate)
                .map_err(|e| errors::FeatureError::new_err(format!("signal {}: {e}", r.hit - 1)))?;
        }
        let cfg = &cfg;
        let done: Vec<_> = py.detach(|| {
            pool.install(|| {
                recs.par_iter()
                    .map_init(|| FeatureExtractor::new(cfg), |ex, r| ex.row(r))
                    .collect()
            })
        });
        rows.extend(done);
        py.check_signals()?;
        if let Some(l) = &mut line {
            l.draw(py, rows.len() as u64)?;
        }
    }
    if let Some(l) = &mut line {
        l.end(py, rows.len() as u64)?;
    }
    batches(&table.schema(), rows)
}

/// |W(t, f)|² (or |W| with `power=false`) of one signal: frequencies × samples, float32.
#[pyfunction]
#[pyo3(signature = (x, sample_rate_hz, freqs_hz=None, fwhm_periods=2.0, power=true))]
pub fn cwt<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f32>,
    sample_rate_hz: f64,
    freqs_hz: Option<Vec<f64>>,
    fwhm_periods: f64,
    power: bool,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return Err(PyValueError::new_err(
            "sample_rate_hz must be a positive number",
        ));
    }
    if !(fwhm_periods.is_finite() && fwhm_periods > 0.0) {
        return Err(PyValueError::new_err(
            "fwhm_periods must be a positive number",
        ));
    }
    let freqs = match freqs_hz {
        Some(f) => f,
        None => WaveletBank::from_config(&aepipe::config::CwtConfig::default()).freqs_hz,
    };
    if freqs.is_empty() || freqs.iter().any(|f| !(f.is_finite() && *f > 0.0)) {
        return Err(PyValueError::new_err(
            "freqs_hz must be positive, finite frequencies",
        ));
    }
    let samples = &owned_samples(&x)[..];
    if samples.iter().any(|v| !v.is_finite()) {
        return Err(PyValueError::new_err("x holds a non-finite sample"));
    }
    let (nf, n) = (freqs.len(), samples.len());
    let out = py.detach(|| {
        let mut c = Cwt::new(WaveletBank {
            freqs_hz: freqs,
            fwhm_periods,
        });
        let mut out = vec![0f32; nf * n];
        if n > 0 {
            c.load(samples, sample_rate_hz);
            c.full_power(samples, sample_rate_hz, &mut out);
        }
        if !power {
            out.iter_mut().for_each(|v| *v = v.sqrt());
        }
        out
    });
    // The result's buffer becomes the array's (no copy).
    let a = ndarray::Array2::from_shape_vec((nf, n), out)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(PyArray2::from_owned_array(py, a))
}

/// A copy of a signal's samples (a memcpy when contiguous). Copied because the work runs
/// without the interpreter, while another Python thread could write to the array.
fn owned_samples(x: &PyReadonlyArray1<'_, f32>) -> Vec<f32> {
    match x.as_slice() {
        Ok(s) => s.to_vec(),
        Err(_) => x.as_array().iter().copied().collect(),
    }
}

/// vallenae's `hinkley(arr, alpha=5)`: (S as float64, index of its first minimum).
#[pyfunction]
#[pyo3(signature = (x, alpha=5.0))]
pub fn pick_hinkley<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f32>,
    alpha: f64,
) -> PyResult<(Bound<'py, PyArray1<f64>>, usize)> {
    if !(alpha.is_finite() && alpha > 0.0) {
        return Err(PyValueError::new_err("alpha must be a positive number"));
    }
    let s = &owned_samples(&x)[..];
    let (values, at) = py.detach(|| {
        let mut scratch = PickScratch::default();
        let mut v = Vec::new();
        pick::function::hinkley(s, alpha, &mut scratch, &mut v);
        (v, pick::hinkley(s, alpha, &mut scratch))
    });
    let at = at.ok_or_else(|| PyValueError::new_err("hinkley of an empty signal"))?;
    Ok((PyArray1::from_vec(py, values), at))
}

/// vallenae's `aic(arr)`: (AIC as float64, its last element NaN; index of the first
/// minimum).
#[pyfunction]
pub fn pick_aic<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f32>,
) -> PyResult<(Bound<'py, PyArray1<f64>>, usize)> {
    let s = &owned_samples(&x)[..];
    let (values, at) = py.detach(|| {
        let mut scratch = PickScratch::default();
        let mut v = Vec::new();
        pick::function::aic(s, &mut scratch, &mut v);
        (v, pick::aic(s, &mut scratch))
    });
    let at = at.ok_or_else(|| PyValueError::new_err("aic needs at least 2 samples"))?;
    Ok((PyArray1::from_vec(py, values), at))
}

/// vallenae's `energy_ratio(arr, win_len=100)` (`modified = false`) or
/// `modified_energy_ratio(arr, win_len=100)`: (values as float32, index of the first
/// maximum; 0 when the signal holds no two windows).
#[pyfunction]
#[pyo3(signature = (x, win_len=100, modified=false))]
pub fn pick_energy_ratio<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f32>,
    win_len: usize,
    modified: bool,
) -> PyResult<(Bound<'py, PyArray1<f32>>, usize)> {
    if win_len == 0 {
        return Err(PyValueError::new_err("win_len must be ≥ 1"));
    }
    let s = &owned_samples(&x)[..];
    let (er, mer, at) = py.detach(|| {
        let mut scratch = PickScratch::default();
        let (mut er, mut mer) = (Vec::new(), Vec::new());
        pick::function::ratios(s, win_len, &mut scratch, &mut er, &mut mer);
        let at = if modified {
            pick::modified_energy_ratio(s, win_len, &mut scratch)
        } else {
            pick::energy_ratio(s, win_len, &mut scratch)
        };
        (er, mer, at.unwrap_or(0))
    });
    let values = if modified { mer } else { er };
    Ok((PyArray1::from_vec(py, values), at))
}

/// Cut channels (float32 volts, one array per channel) into hits as `[detect]` of the
/// pipeline text `config_toml` says: the hits table (`hits.parquet`'s columns, source
/// `detect`) and each hit's record, in order of first crossing.
#[pyfunction]
#[pyo3(signature = (channels, sample_rate_hz, config_toml))]
pub fn detect<'py>(
    py: Python<'py>,
    channels: Vec<PyReadonlyArray1<'py, f32>>,
    sample_rate_hz: f64,
    config_toml: &str,
) -> PyResult<(ArrowStream, Vec<Bound<'py, PyArray1<f32>>>)> {
    if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return Err(PyValueError::new_err(format!(
            "sample_rate_hz must be > 0, got {sample_rate_hz}"
        )));
    }
    let cfg = aepipe::config::PipelineConfig::from_toml(config_toml).map_err(errors::config)?;
    let owned: Vec<Vec<f32>> = channels.iter().map(owned_samples).collect();
    let cutting = aepipe::ingest::stream::Cutting {
        experiment: "array",
        file: "",
        rate_hz: sample_rate_hz,
    };
    let detect = cfg.read_settings().detect();
    let items = py.detach(|| {
        let views: Vec<&[f32]> = owned.iter().map(Vec::as_slice).collect();
        cutting.cut_channels(&views, detect)
    });
    let table = aepipe::store::hits_table(cfg.crack_mode);
    let rows = items.iter().map(|(h, _)| table.row(h.clone())).collect();
    let waves = items
        .into_iter()
        .map(|(_, r)| PyArray1::from_vec(py, r.samples))
        .collect();
    Ok((batches(&table.schema(), rows)?, waves))
}
