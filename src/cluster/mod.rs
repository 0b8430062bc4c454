//! Clustering hits by their own features, the way most AE labs classify without a simulated
//! library (MISTRAS NOESIS; the AE pattern-recognition literature): standardised features,
//! k-means, Gaussian mixtures or a SOM's codebook clustered (Vesanto & Alhoniemi 2000), and
//! the number of clusters chosen by validity indices (Davies–Bouldin, silhouette,
//! Calinski–Harabasz, BIC).
//!
//! The fit is in memory on at most `max_fit_rows` rows (a seeded uniform sample of a larger
//! input, drawn while a first pass standardises every row); a second pass assigns every row
//! and writes `clusters.parquet`, so memory does not grow with the input.

pub mod fit;
pub mod gmm;
pub mod kmeans;
pub mod settings;
pub mod stage;
pub mod validity;

pub use fit::{fit_matrix, ClusterModel, Fitted, ValidityRow};
pub use settings::{Choose, ClusterConfig, ClusterSettingsError, Method, ValidCluster};
pub use stage::{cluster_matrix, cluster_tables, ClusterReport};

/// What went wrong clustering.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    #[error("{0}")]
    Data(String),
    #[error("{path}: {message}")]
    File { path: String, message: String },
    #[error("{path}: cannot write: {message}")]
    Write { path: String, message: String },
    #[error(transparent)]
    Settings(#[from] settings::ClusterSettingsError),
    /// The SOM of `som-kmeans` could not be trained.
    #[error(transparent)]
    Som(#[from] crate::som::SomError),
    /// A feature table could not be read past its schema (Parquet, I/O).
    #[error(transparent)]
    Store(#[from] crate::store::StoreError),
}

impl crate::util::HasKind for ClusterError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            ClusterError::Write { .. } => crate::util::ErrorKind::Failed,
            ClusterError::Som(e) => e.kind(),
            ClusterError::Store(e) => e.kind(),
            _ => crate::util::ErrorKind::Usage,
        }
    }
}
