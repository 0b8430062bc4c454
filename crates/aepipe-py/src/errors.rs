//! One Python exception per error enum of the library, all under `AepipeError`, each
//! carrying the message the command line prints. A job the caller interrupted (Ctrl-C)
//! becomes `KeyboardInterrupt`, as Python code expects.

use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;

pyo3::create_exception!(
    _aepipe,
    AepipeError,
    pyo3::exceptions::PyException,
    "Base of every aepipe error; the message is the one the command line prints."
);

/// Declares the subclasses and the function that registers them all.
macro_rules! subclasses {
    ($($name:ident: $doc:literal,)*) => {
        $(pyo3::create_exception!(_aepipe, $name, AepipeError, $doc);)*

        pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
            let py = m.py();
            m.add("AepipeError", py.get_type::<AepipeError>())?;
            $(m.add(stringify!($name), py.get_type::<$name>())?;)*
            Ok(())
        }
    };
}

subclasses! {
    ConfigError: "A pipeline definition (TOML) that cannot be read or holds a value out of range (the key is named).",
    IngestError: "An input that cannot be read at all.",
    FeatureError: "A record the feature stage cannot take (a non-finite sample, a bad rate, …).",
    StoreError: "A Parquet table that cannot be written or read, or is not the table asked for.",
    ShardSetError: "The shards of a sharded run or library do not make one.",
    PipelineError: "The streaming feature pipeline failed (no input, an output it cannot write, …).",
    MergeError: "`aepipe merge` refused or failed.",
    TrendError: "The trend statistics could not run (a column that is not there, a bad cut-off, …).",
    ClusterError: "Clustering that cannot run (bad settings, too few or non-finite rows).",
    SomError: "A SOM that cannot be trained, loaded, saved or applied (bad parameters, a dimension mismatch, a model file that is not one).",
    SimError: "A simulation model or reference-library definition that is wrong, or a simulation that failed.",
    SynthError: "A synthetic experiment that cannot be built.",
    PlotError: "A picture that could not be drawn.",
    ReportError: "The HTML report could not be written.",
    WorkflowError: "`aepipe run` failed outside any one stage (an input folder that is not what it should be, …).",
    BenchError: "A benchmark could not run.",
}

pub fn config(e: aepipe::config::ConfigError) -> PyErr {
    ConfigError::new_err(e.to_string())
}

pub fn store(e: aepipe::store::StoreError) -> PyErr {
    StoreError::new_err(e.to_string())
}

pub fn store_msg(msg: String) -> PyErr {
    StoreError::new_err(msg)
}

pub fn pipeline(e: aepipe::pipeline::PipelineError) -> PyErr {
    use aepipe::pipeline::PipelineError as P;
    match e {
        P::Cancelled => PyKeyboardInterrupt::new_err("aepipe: interrupted"),
        P::Store(s) => store(s),
        // No recording in the inputs: the input's fault, as a file that cannot be read.
        e @ P::NothingToRead { .. } => IngestError::new_err(e.to_string()),
        other => PipelineError::new_err(other.to_string()),
    }
}

pub fn trend(e: aepipe::analysis::trend::TrendError) -> PyErr {
    TrendError::new_err(e.to_string())
}

pub fn cluster(e: aepipe::cluster::ClusterError) -> PyErr {
    ClusterError::new_err(e.to_string())
}

pub fn som(e: aepipe::som::SomError) -> PyErr {
    SomError::new_err(e.to_string())
}

pub fn sim(e: aepipe::sim::SimError) -> PyErr {
    use aepipe::sim::SimError as S;
    match e {
        S::Cancelled => PyKeyboardInterrupt::new_err("aepipe: interrupted"),
        S::Shards(s) => ShardSetError::new_err(s.to_string()),
        other => SimError::new_err(other.to_string()),
    }
}

/// A run's error, by the stage it came from.
pub fn workflow(e: aepipe::workflow::WorkflowError) -> PyErr {
    use aepipe::workflow::WorkflowError as W;
    match e {
        W::Config(x) => config(x),
        W::Pipeline(x) => pipeline(x),
        W::Merge(x) => MergeError::new_err(x.to_string()),
        W::Trend(x) => trend(x),
        W::Som(x) => som(x),
        W::Sim(x) => sim(x),
        W::Synth(x) => SynthError::new_err(x.to_string()),
        W::Store(x) => store(x),
        W::Report(x) => ReportError::new_err(x.to_string()),
        W::Plot(x) => PlotError::new_err(x.to_string()),
        other => WorkflowError::new_err(other.to_string()),
    }
}
