//! The spatial order of the acoustic FDTD schemes: a word of the model file's grid that both
//! fields (plane and 3-D) read. It sits below the model file and the fields so that neither
//! field has to import the model file that builds it.

use serde::{Deserialize, Serialize};

/// Spatial order of the acoustic FDTD scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Order {
    /// Eq. 3.3.11, stable for α < 1/√2.
    Second,
    /// Eq. 3.3.13, stable for α < √(3/8).
    Fourth,
}
