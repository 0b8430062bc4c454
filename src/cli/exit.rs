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
//!
//! Every command returns [`Failure`], which any error that knows its kind converts into
//! (`?`): an error type without [`HasKind`] does not compile into a command, so the map
//! from errors to codes is exhaustive by construction — there is no list of types to keep.

use crate::util::{ErrorKind, HasKind};

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

/// How a command that did not fail ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    Success,
    /// `--strict` and something was rejected (exit 2).
    Rejected,
}

impl Outcome {
    pub fn code(self) -> u8 {
        match self {
            Outcome::Success => 0,
            Outcome::Rejected => STRICT,
        }
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

/// An error of any room, with its kind.
pub trait KindedError: std::error::Error + HasKind + Send + Sync + 'static {}

impl<T: std::error::Error + HasKind + Send + Sync + 'static> KindedError for T {}

/// Why a command failed: a room's typed error, kept whole.
#[derive(Debug)]
pub struct Failure(Box<dyn KindedError>);

impl<E: KindedError> From<E> for Failure {
    fn from(e: E) -> Failure {
        Failure(Box::new(e))
    }
}

impl Failure {
    /// The exit code of the README's table.
    pub fn code(&self) -> u8 {
        code_of(self.0.kind())
    }
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failure_keeps_its_rooms_kind() {
        let f: Failure = UsageError("x".into()).into();
        assert_eq!((f.code(), f.to_string().as_str()), (USAGE, "x"));
        let io = crate::util::IoAt::new(
            std::path::Path::new("/x"),
            std::io::Error::other("disk full"),
        );
        let f: Failure = io.into();
        assert_eq!(f.code(), FAILED);
        assert!(f.to_string().contains("disk full"));
    }
}
