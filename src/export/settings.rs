//! `[export]`: what `aepipe run` writes back for the lab's own tools.

use serde::{Deserialize, Serialize};

/// `[export]` in the pipeline file.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExportConfig {
    /// Write `RUN_DIR/export/<experiment>.aepipe.trfdb` per Vallen experiment (and a CSV per
    /// experiment of the other vendors) at the end of `aepipe run`, as `aepipe export
    /// trfdb` does.
    pub trfdb: bool,
}
