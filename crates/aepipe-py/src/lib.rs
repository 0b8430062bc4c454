//! `aepipe._aepipe`: the Python edge of aepipe. Everything here converts — Python paths and
//! NumPy arrays in, Arrow C streams (`__arrow_c_stream__`) and NumPy arrays out — and calls
//! the core library, which knows nothing of Python. The typed, documented API is the thin
//! Python layer in `python/aepipe/`.
//!
//! Long calls leave the interpreter: jobs run on a worker thread while the caller looks for
//! Ctrl-C every 100 ms (`control`), and per-record work detaches in chunks of a few hundred
//! records; an interrupted call asks the core to stop (`aepipe::util::JobControl`) and
//! raises `KeyboardInterrupt` within a second.

mod analysis;
mod compute;
mod control;
mod errors;
mod frames;
mod io;
mod jobs;

use pyo3::prelude::*;

#[pymodule]
fn _aepipe(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<frames::ArrowStream>()?;
    m.add_class::<io::Record>()?;
    m.add_class::<io::WaveformIter>()?;
    m.add_class::<analysis::SomModel>()?;
    m.add_function(wrap_pyfunction!(io::read_hits, m)?)?;
    m.add_function(wrap_pyfunction!(io::read_waveforms, m)?)?;
    m.add_function(wrap_pyfunction!(io::iter_waveforms, m)?)?;
    m.add_function(wrap_pyfunction!(compute::features_of_paths, m)?)?;
    m.add_function(wrap_pyfunction!(compute::features_of_signals, m)?)?;
    m.add_function(wrap_pyfunction!(compute::cwt, m)?)?;
    m.add_function(wrap_pyfunction!(compute::pick_hinkley, m)?)?;
    m.add_function(wrap_pyfunction!(compute::pick_aic, m)?)?;
    m.add_function(wrap_pyfunction!(compute::pick_energy_ratio, m)?)?;
    m.add_function(wrap_pyfunction!(compute::detect, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::trend, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::som_fit, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::cluster_fit, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::cluster_validity, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::reference_library, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::run, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "CLUSTER_DEFAULT_COLUMNS",
        aepipe::cluster::settings::DEFAULT_COLUMNS.to_vec(),
    )?;
    Ok(())
}
