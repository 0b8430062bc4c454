//! `[cluster]` of the pipeline TOML and the flags of `aepipe cluster`: checked once into a
//! [`ValidCluster`], then used.

/// A `[cluster]` value out of range, naming its key (or a `--k` that does not parse).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("cluster settings: {0}")]
pub struct ClusterSettingsError(pub String);
use serde::{Deserialize, Serialize};

/// How hits are clustered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// k-means++ with `n_init` restarts.
    #[default]
    Kmeans,
    /// Full-covariance Gaussian mixtures by EM, started from k-means.
    Gmm,
    /// A SOM trained on the rows, its codebook clustered by k-means; each hit takes its
    /// node's cluster (Vesanto & Alhoniemi 2000).
    SomKmeans,
}

impl Method {
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Kmeans => "kmeans",
            Method::Gmm => "gmm",
            Method::SomKmeans => "som-kmeans",
        }
    }

    /// The method named by its `[cluster] method` word.
    pub fn parse(s: &str) -> Option<Method> {
        crate::util::from_serde_name(s).ok()
    }
}

/// The rule that picks k from the validity curves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Choose {
    /// The least Davies–Bouldin index.
    #[default]
    DaviesBouldin,
    /// The largest mean silhouette.
    Silhouette,
    /// The largest Calinski–Harabasz index.
    CalinskiHarabasz,
    /// The least BIC (Gaussian mixtures only).
    Bic,
}

impl Choose {
    pub fn as_str(self) -> &'static str {
        match self {
            Choose::DaviesBouldin => "davies-bouldin",
            Choose::Silhouette => "silhouette",
            Choose::CalinskiHarabasz => "calinski-harabasz",
            Choose::Bic => "bic",
        }
    }

    /// The rule named by its `[cluster] choose` word.
    pub fn parse(s: &str) -> Option<Choose> {
        crate::util::from_serde_name(s).ok()
    }
}

/// The default feature columns: the usual hit features, RA and AF, peak and centroid
/// frequency; the power ratios (`pr_*`) are added from the table (the band layout is the
/// run's).
pub const DEFAULT_COLUMNS: [&str; 10] = [
    "peak_amplitude_db",
    "rise_time_s",
    "duration_s",
    "counts",
    "energy_eu",
    "rms_v",
    "ra_ms_per_v",
    "af_khz",
    "peak_freq_hz",
    "centroid_freq_hz",
];

/// `[cluster]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClusterConfig {
    /// `aepipe run` clusters too.
    pub enabled: bool,
    pub method: Method,
    /// The range of k tried (2 ≤ k_min ≤ k_max ≤ 20).
    pub k_min: usize,
    pub k_max: usize,
    /// Feature columns (z-scored); empty: [`DEFAULT_COLUMNS`] and every `pr_*` column.
    /// `tf_bins` (the 200 bins) may be named.
    pub columns: Vec<String>,
    pub choose: Choose,
    pub seed: u64,
    /// k-means restarts (best inertia kept), also for the GMM's start and the codebook.
    pub n_init: usize,
    /// Rows the fit sees: all of a smaller input, else a seeded uniform sample.
    pub max_fit_rows: usize,
    /// The silhouette is exact up to this many rows and computed on a seeded sample of
    /// this size beyond (the table says which).
    pub silhouette_rows: usize,
    /// The SOM of `som-kmeans`.
    pub som_rows: usize,
    pub som_cols: usize,
}

impl Default for ClusterConfig {
    fn default() -> Self {
        ClusterConfig {
            enabled: false,
            method: Method::Kmeans,
            k_min: 2,
            k_max: 8,
            columns: Vec::new(),
            choose: Choose::DaviesBouldin,
            seed: 2008,
            n_init: 10,
            max_fit_rows: 50_000,
            silhouette_rows: 5_000,
            som_rows: 10,
            som_cols: 10,
        }
    }
}

/// A checked [`ClusterConfig`].
#[derive(Debug, Clone, PartialEq)]
pub struct ValidCluster(ClusterConfig);

impl ValidCluster {
    pub fn into_inner(self) -> ClusterConfig {
        self.0
    }
}

impl std::ops::Deref for ValidCluster {
    type Target = ClusterConfig;
    fn deref(&self) -> &ClusterConfig {
        &self.0
    }
}

impl ClusterConfig {
    /// The checks serde cannot express, each naming its key.
    pub fn check(self) -> Result<ValidCluster, ClusterSettingsError> {
        let bad = |m: String| Err(ClusterSettingsError(m));
        if self.k_min < 2 || self.k_max < self.k_min || self.k_max > 20 {
            return bad(format!(
                "cluster.k_min ({}) and k_max ({}) must satisfy 2 ≤ k_min ≤ k_max ≤ 20",
                self.k_min, self.k_max
            ));
        }
        if self.n_init == 0 {
            return bad("cluster.n_init must be ≥ 1".into());
        }
        if self.max_fit_rows < self.k_max.max(10) {
            return bad(format!(
                "cluster.max_fit_rows ({}) must be at least 10 and k_max",
                self.max_fit_rows
            ));
        }
        if self.silhouette_rows < 10 {
            return bad("cluster.silhouette_rows must be ≥ 10".into());
        }
        if self.choose == Choose::Bic && self.method != Method::Gmm {
            return bad("cluster.choose = \"bic\" needs method = \"gmm\"".into());
        }
        if self.method == Method::SomKmeans && self.som_rows * self.som_cols < self.k_max {
            return bad(format!(
                "a {}×{} map has fewer nodes than k_max = {}",
                self.som_rows, self.som_cols, self.k_max
            ));
        }
        if self.columns.iter().any(|c| c.trim().is_empty()) {
            return bad("cluster.columns holds an empty name".into());
        }
        Ok(ValidCluster(self))
    }
}

/// `--k 4` or `--k 2..8`: (k_min, k_max).
pub fn parse_k(s: &str) -> Result<(usize, usize), ClusterSettingsError> {
    let num = |t: &str| {
        t.trim()
            .parse::<usize>()
            .map_err(|e| ClusterSettingsError(format!("--k {t}: {e}")))
    };
    match s.split_once("..") {
        Some((a, b)) => Ok((num(a)?, num(b.trim_start_matches('='))?)),
        None => num(s).map(|k| (k, k)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_are_checked_and_k_parses() {
        assert!(ClusterConfig::default().check().is_ok());
        let bad = |f: &dyn Fn(&mut ClusterConfig)| {
            let mut c = ClusterConfig::default();
            f(&mut c);
            c.check().unwrap_err().to_string()
        };
        assert!(bad(&|c| c.k_min = 1).contains("k_min"));
        assert!(bad(&|c| c.k_max = 21).contains("k_max"));
        assert!(bad(&|c| c.choose = Choose::Bic).contains("gmm"));
        assert!(bad(&|c| c.n_init = 0).contains("n_init"));
        assert_eq!(parse_k("2..8").unwrap(), (2, 8));
        assert_eq!(parse_k("4").unwrap(), (4, 4));
        assert_eq!(parse_k("3..=5").unwrap(), (3, 5));
        assert!(parse_k("x").is_err());
        assert_eq!(Method::parse("som-kmeans"), Some(Method::SomKmeans));
        // The words printed are the words parsed (serde's), for every variant.
        for m in [Method::Kmeans, Method::Gmm, Method::SomKmeans] {
            assert_eq!(Method::parse(m.as_str()), Some(m));
        }
        for c in [
            Choose::DaviesBouldin,
            Choose::Silhouette,
            Choose::CalinskiHarabasz,
            Choose::Bic,
        ] {
            assert_eq!(Choose::parse(c.as_str()), Some(c));
        }
        assert_eq!(Method::parse("k-means"), None);
    }
}
