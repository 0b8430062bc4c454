//! The one map from an error to the process's exit code (the README's table):
//!
//! | code | meaning |
//! |---|---|
//! | 0 | success |
//! | 1 | usage, configuration or input error: a flag, a config/model/library file, a table or folder that is not what the command needs |
//! | 2 | `--strict` was given and at least one hit or file was rejected |
//! | 3 | the run failed: an output could not be written, or a stage failed while running |
//!
//! Every room's error enum is matched here variant by variant (no catch-all arm inside a
//! room), so a new variant cannot be added without deciding its code.

use crate::analysis::trend::TrendError;
use crate::bench::BenchError;
use crate::config::ConfigError;
use crate::pipeline::{MergeError, PipelineError};
use crate::plot::PlotError;
use crate::report::ReportError;
use crate::sim::SimError;
use crate::som::SomError;
use crate::store::StoreError;
use crate::synth::SynthError;
use crate::util::IoAt;
use crate::workflow::WorkflowError;

/// A command line that parsed but does not make sense (a malformed `--sweep`, an unknown
/// table name, `aepipe run` without a pipeline).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

pub const USAGE: u8 = 1;
pub const STRICT: u8 = 2;
pub const FAILED: u8 = 3;

fn store(e: &StoreError) -> u8 {
    match e {
        StoreError::Read { .. } => USAGE,
        StoreError::Io { .. }
        | StoreError::Parquet { .. }
        | StoreError::Arrow { .. }
        | StoreError::Schema { .. } => FAILED,
    }
}

fn pipeline(e: &PipelineError) -> u8 {
    match e {
        PipelineError::Store(s) => store(s),
        PipelineError::Io(_) | PipelineError::Pool(_) => FAILED,
        PipelineError::NoInput => USAGE,
    }
}

fn trend(e: &TrendError) -> u8 {
    match e {
        TrendError::Read { .. } | TrendError::Usage(_) => USAGE,
        TrendError::Store(s) => store(s),
    }
}

fn som(e: &SomError) -> u8 {
    match e {
        SomError::Params(_) | SomError::Data(_) | SomError::File { .. } | SomError::Codebook(_) => {
            USAGE
        }
        SomError::Write { .. } => FAILED,
    }
}

fn sim(e: &SimError) -> u8 {
    match e {
        SimError::Model(_) | SimError::Parse { .. } | SimError::Read(_) => USAGE,
        SimError::Solver(_) | SimError::Io(_) => FAILED,
    }
}

fn synth(e: &SynthError) -> u8 {
    match e {
        SynthError::Library { .. } => USAGE,
        SynthError::Sim(s) => sim(s),
        SynthError::Vallen { .. } => FAILED,
        SynthError::Store(s) => store(s),
    }
}

fn plot(e: &PlotError) -> u8 {
    match e {
        PlotError::Font { .. } => USAGE,
        PlotError::Draw { .. } => FAILED,
    }
}

fn report(e: &ReportError) -> u8 {
    match e {
        ReportError::Write(_) => FAILED,
    }
}

fn merge(e: &MergeError) -> u8 {
    match e {
        // The folder is not a complete, consistent set of shards: the input is at fault.
        MergeError::NoShards { .. }
        | MergeError::Manifest { .. }
        | MergeError::Disagree { .. }
        | MergeError::Missing { .. }
        | MergeError::WrongJob { .. } => USAGE,
        MergeError::Pipeline(x) => pipeline(x),
    }
}

fn workflow(e: &WorkflowError) -> u8 {
    match e {
        WorkflowError::Merge(x) => merge(x),
        WorkflowError::Config(_) | WorkflowError::Input { .. } | WorkflowError::NoHit(_) => USAGE,
        WorkflowError::Pipeline(x) => pipeline(x),
        WorkflowError::Trend(x) => trend(x),
        WorkflowError::Som(x) => som(x),
        WorkflowError::Sim(x) => sim(x),
        WorkflowError::Synth(x) => synth(x),
        WorkflowError::Store(x) => store(x),
        WorkflowError::Report(x) => report(x),
        WorkflowError::Plot(x) => plot(x),
        WorkflowError::Write(_) => FAILED,
    }
}

fn bench(e: &BenchError) -> u8 {
    match e {
        BenchError::Input { .. } => USAGE,
        BenchError::Peer(_) | BenchError::Run(_) => FAILED,
    }
}

/// The exit code of a failed command.
pub fn exit_code(e: &anyhow::Error) -> u8 {
    macro_rules! try_map {
        ($($ty:ty => $f:expr),* $(,)?) => {
            $(if let Some(x) = e.downcast_ref::<$ty>() {
                return $f(x);
            })*
        };
    }
    try_map!(
        UsageError => |_| USAGE,
        ConfigError => |_| USAGE,
        WorkflowError => workflow,
        PipelineError => pipeline,
        MergeError => merge,
        StoreError => store,
        TrendError => trend,
        SomError => som,
        SimError => sim,
        SynthError => synth,
        PlotError => plot,
        ReportError => report,
        BenchError => bench,
        IoAt => |_| FAILED,
    );
    FAILED
}
