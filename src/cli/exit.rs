//! Exit codes (the README's table), from the kind of failure each room decides for its own
//! errors ([`crate::util::ErrorKind`], implemented next to every error enum, variant by
//! variant):
//!
//! | code | meaning |
//! |---|---|
//! | 0 | success |
//! | 1 | usage, configuration or input error ([`ErrorKind::Usage`]): a flag, a config/model/library file, a table or folder that is not what the command needs |
//! | 2 | `--strict` was given and at least one hit or file was rejected |
//! | 3 | the run failed ([`ErrorKind::Failed`]): an output could not be written, or a stage failed while running |

use crate::analysis::trend::TrendError;
use crate::bench::BenchError;
use crate::config::ConfigError;
use crate::ingest::IngestError;
use crate::live::WatchError;
use crate::pipeline::{MergeError, PipelineError};
use crate::plot::PlotError;
use crate::report::ReportError;
use crate::sim::SimError;
use crate::som::SomError;
use crate::store::shard::ShardSetError;
use crate::store::StoreError;
use crate::synth::SynthError;
use crate::util::{ErrorKind, HasKind, IoAt};
use crate::workflow::WorkflowError;

/// A command line that parsed but does not make sense (a malformed `--sweep`, an unknown
/// table name, `aepipe run` without a pipeline).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

impl HasKind for UsageError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Usage
    }
}

pub const USAGE: u8 = 1;
pub const STRICT: u8 = 2;
pub const FAILED: u8 = 3;

/// The exit code of a kind of failure.
pub fn code_of(k: ErrorKind) -> u8 {
    match k {
        ErrorKind::Usage => USAGE,
        ErrorKind::Failed => FAILED,
    }
}

/// The exit code of a failed command: its error's kind (an error of no room's: failed).
pub fn exit_code(e: &anyhow::Error) -> u8 {
    macro_rules! kind_of {
        ($($ty:ty),* $(,)?) => {
            $(if let Some(x) = e.downcast_ref::<$ty>() {
                return code_of(x.kind());
            })*
        };
    }
    kind_of!(
        UsageError,
        ConfigError,
        WorkflowError,
        PipelineError,
        MergeError,
        ShardSetError,
        StoreError,
        IngestError,
        TrendError,
        SomError,
        SimError,
        SynthError,
        PlotError,
        ReportError,
        BenchError,
        WatchError,
        IoAt,
    );
    FAILED
}
