//! Back into the lab's tools (issue 41): aepipe's per-transient results written as a
//! VisualAE transient-feature database (`.trfdb`) beside a Vallen pair's own, or as a CSV
//! keyed by the vendor's hit id for the other systems.
//!
//! The room reads finished tables (features, classification, clusters, events) through
//! [`crate::store`] and knows nothing of how a run is laid out: the caller names the tables.

pub mod settings;
mod table;
pub mod trfdb;

pub use settings::ExportConfig;
pub use table::{Column, Results};
pub use trfdb::{export, ExportSummary, Exported, RunTables};

use crate::store::StoreError;
use crate::util::{ErrorKind, HasKind, IoAt};

/// Why an export could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A table could not be read.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// An output of that name exists (aepipe's own earlier export: `--force` replaces it).
    #[error("{path} exists: pass --force to replace it")]
    Exists { path: String },
    /// The features table is not there or lacks the columns an export needs.
    #[error("{0}")]
    Input(String),
    /// SQLite refused to write the database.
    #[error("{path}: {message}")]
    Sqlite { path: String, message: String },
    #[error("{path}: {message}")]
    Csv { path: String, message: String },
    #[error(transparent)]
    Io(#[from] IoAt),
}

impl HasKind for ExportError {
    fn kind(&self) -> ErrorKind {
        match self {
            ExportError::Store(e) => e.kind(),
            ExportError::Exists { .. } | ExportError::Input(_) => ErrorKind::Usage,
            ExportError::Sqlite { .. } | ExportError::Csv { .. } | ExportError::Io(_) => {
                ErrorKind::Failed
            }
        }
    }
}
