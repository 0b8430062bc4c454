//! The clustering stage on feature tables: standardise, fit on a bounded sample, assign
//! every row, write `clusters.parquet`, `validity.parquet` and `model.json`.

use super::fit::{fit_matrix, Assigner, ValidityRow};
use super::settings::{ValidCluster, DEFAULT_COLUMNS};
use super::ClusterError;
use crate::model::columns as cols;
use crate::som::tables::Scaling;
use crate::store::{for_each_matrix, StoreError};
use crate::store::{ColType, ColumnSpec, HitKey, SourceRows, Table, TableScan, TableWriter, Value};
use ndarray::Array2;
use std::path::{Path, PathBuf};

/// What a clustering run did.
#[derive(Debug, Clone)]
pub struct ClusterReport {
    pub columns: Vec<String>,
    /// Rows clustered, and rows left out for a null or non-finite feature.
    pub rows: usize,
    pub skipped: usize,
    /// Rows the fit saw.
    pub fit_rows: usize,
    pub validity: Vec<ValidityRow>,
    pub k: usize,
    /// Rows per published cluster, over every row.
    pub sizes: Vec<usize>,
    pub clusters: PathBuf,
    pub validity_table: PathBuf,
    pub model: PathBuf,
}

/// One row of `clusters.parquet`.
pub struct ClusterRow {
    pub key: HitKey,
    pub cluster: usize,
    pub distance: f64,
    pub probability: Option<f64>,
}

/// `clusters.parquet`.
pub fn clusters_table() -> Table<ClusterRow> {
    Table::new("clusters")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"), |r: &ClusterRow| Value::Str(Some(r.key.0.clone())))
        .col(ColumnSpec::of(cols::CHANNEL, "", "sensor channel"), |r| Value::I32(Some(r.key.1)))
        .col(ColumnSpec::of(cols::HIT, "", "hit number"), |r| Value::I64(Some(r.key.2)))
        .col(ColumnSpec::new("cluster", ColType::Int32, "", "the hit's cluster at the chosen k, numbered 0.. by rising mean peak frequency of the cluster's fit rows (the first column's mean without peak_freq_hz), so numbers and colours repeat from run to run"), |r| Value::I32(Some(r.cluster as i32)))
        .col(ColumnSpec::new("cluster_distance", ColType::Float64, "1", "Euclidean distance of the hit's z-scored features to its cluster's centroid"), |r| Value::F64(Some(r.distance)))
        .col(ColumnSpec::new("cluster_probability", ColType::Float64, "1", "Gaussian mixtures: posterior probability of the hit's component; null for the other methods").nullable(), |r| Value::F64(r.probability))
}

/// `validity.parquet`.
pub fn validity_table() -> Table<ValidityRow> {
    let f = |n: &str, d: &str| ColumnSpec::new(n, ColType::Float64, "1", d).nullable();
    Table::new("validity")
        .col(ColumnSpec::new("method", ColType::Utf8, "", "kmeans, gmm or som-kmeans"), |r: &ValidityRow| Value::Str(Some(r.method.as_str().into())))
        .col(ColumnSpec::new("k", ColType::Int32, "", "number of clusters"), |r| Value::I32(Some(r.k as i32)))
        .col(f("davies_bouldin", "Davies–Bouldin index of the partition (lower is better; scikit-learn's davies_bouldin_score); null with fewer than 2 clusters"), |r| Value::F64(r.davies_bouldin))
        .col(f("silhouette", "mean silhouette (higher is better; scikit-learn's silhouette_score) on silhouette_rows rows"), |r| Value::F64(r.silhouette))
        .col(ColumnSpec::new("silhouette_rows", ColType::Int64, "rows", "rows the silhouette was computed on: every fit row up to cluster.silhouette_rows, else a seeded sample of that many"), |r| Value::I64(Some(r.silhouette_rows as i64)))
        .col(f("calinski_harabasz", "Calinski–Harabasz index (higher is better; scikit-learn's calinski_harabasz_score)"), |r| Value::F64(r.calinski_harabasz))
        .col(f("bic", "Bayesian information criterion of the mixture (lower is better; scikit-learn's GaussianMixture.bic); null for the other methods"), |r| Value::F64(r.bic))
        .col(f("log_likelihood", "mean log-likelihood per fit row under the mixture; null for the other methods"), |r| Value::F64(r.log_likelihood))
        .col(ColumnSpec::new("inertia", ColType::Float64, "1", "sum of squared distances of the fit rows to their cluster's mean (z units)"), |r| Value::F64(Some(r.inertia)))
        .col(ColumnSpec::new("rows", ColType::Int64, "rows", "rows the partition was fitted on (all usable rows up to cluster.max_fit_rows, else a seeded sample)"), |r| Value::I64(Some(r.rows as i64)))
        .col(ColumnSpec::new("chosen", ColType::Bool, "", "the k chosen by cluster.choose"), |r| Value::Bool(Some(r.chosen)))
}

fn ferr(p: &Path, m: impl std::fmt::Display) -> ClusterError {
    ClusterError::File {
        path: p.display().to_string(),
        message: m.to_string(),
    }
}

/// A feature table that cannot be read, in the clustering's words (the store's errors name
/// the file).
fn serr(e: StoreError) -> ClusterError {
    match e {
        StoreError::Read { path, message } => ClusterError::File { path, message },
        other => ClusterError::Store(other),
    }
}

fn werr(p: &Path, m: impl std::fmt::Display) -> ClusterError {
    ClusterError::Write {
        path: p.display().to_string(),
        message: m.to_string(),
    }
}

/// The columns to cluster on: the configured ones, else the defaults present in the first
/// table and its `pr_*` power ratios.
pub fn columns_of(first: &Path, cfg: &ValidCluster) -> Result<Vec<String>, ClusterError> {
    if !cfg.columns.is_empty() {
        return Ok(cfg.columns.clone());
    }
    let t = TableScan::open(first).map_err(serr)?;
    let names = t.column_names();
    let mut c: Vec<String> = DEFAULT_COLUMNS
        .iter()
        .filter(|n| names.iter().any(|m| m == *n))
        .map(|s| s.to_string())
        .collect();
    c.extend(names.into_iter().filter(|n| n.starts_with("pr_")));
    if c.is_empty() {
        return Err(ferr(
            first,
            "none of the default cluster columns is in the table; name them with --columns",
        ));
    }
    Ok(c)
}

/// Per-column running mean and sum of squared deviations (Welford).
struct Moments {
    n: f64,
    mean: Vec<f64>,
    m2: Vec<f64>,
}

impl Moments {
    fn add(&mut self, x: ndarray::ArrayView1<f64>) {
        self.n += 1.0;
        for ((m, s), v) in self.mean.iter_mut().zip(self.m2.iter_mut()).zip(x) {
            let d = v - *m;
            *m += d / self.n;
            *s += d * (v - *m);
        }
    }
    fn new(dim: usize) -> Moments {
        Moments {
            n: 0.0,
            mean: vec![0.0; dim],
            m2: vec![0.0; dim],
        }
    }

    /// The z-scoring of these moments: the means and the population standard deviations,
    /// 1 for a constant column (as scikit-learn's scaler and the SOM's `Scaling`).
    fn scaling(&self) -> Scaling {
        Scaling {
            mean: self.mean.clone(),
            std: self.scale(),
        }
    }

    fn scale(&self) -> Vec<f64> {
        self.m2
            .iter()
            .map(|s| {
                let sd = (s / self.n).sqrt();
                if sd > 0.0 && sd.is_finite() {
                    sd
                } else {
                    1.0
                }
            })
            .collect()
    }
}

/// Each row's (cluster, distance to its centroid, mixture probability).
pub type Assignment = (usize, f64, Option<f64>);

/// Cluster the rows of an in-memory matrix (every row finite; the Python package's
/// entry): z-score by the population moments, fit on at most `max_fit_rows` (a seeded
/// sample), assign every row. `key` orders the clusters (see [`fit_matrix`]). Returns the
/// fit and each row's (cluster, distance, probability).
pub fn cluster_matrix(
    x: ndarray::ArrayView2<f64>,
    key: &[f64],
    cfg: &ValidCluster,
) -> Result<(super::Fitted, Vec<Assignment>), ClusterError> {
    let (n, d) = x.dim();
    if key.len() != n || x.iter().any(|v| !v.is_finite()) {
        return Err(ClusterError::Data(format!(
            "{n} rows with {} keys, or a non-finite value: clustering needs finite rows",
            key.len()
        )));
    }
    let mut mom = Moments::new(d);
    x.rows().into_iter().for_each(|r| mom.add(r));
    let mut z = x.as_standard_layout().to_owned();
    mom.scaling().apply_rows(&mut z);
    let idx = crate::util::Rng::new(cfg.seed ^ 0x7e5e_7001).sample_sorted(n, cfg.max_fit_rows);
    let zs = z.select(ndarray::Axis(0), &idx);
    let ks: Vec<f64> = idx.iter().map(|&i| key[i]).collect();
    let fitted = fit_matrix(zs.view(), &ks, cfg)?;
    let mut post = Vec::new();
    let out = z
        .rows()
        .into_iter()
        .map(|r| {
            fitted
                .model
                .assign(r.as_slice().expect("standard layout"), &mut post)
        })
        .collect();
    Ok((fitted, out))
}

/// Pass 1 of [`cluster_tables`]: the moments of every usable row, and a seeded reservoir of
/// at most `max_fit_rows` of them.
struct Sampled {
    mom: Moments,
    sample: Vec<Vec<f64>>,
    seen: usize,
    skipped: usize,
}

fn sample_rows(
    paths: &[PathBuf],
    columns: &[String],
    cfg: &ValidCluster,
    sources: SourceRows,
) -> Result<Sampled, ClusterError> {
    let cap = cfg.max_fit_rows;
    let mut mom: Option<Moments> = None;
    let mut sample: Vec<Vec<f64>> = Vec::new();
    let (mut seen, mut skipped) = (0usize, 0usize);
    let mut rng = crate::util::Rng::new(cfg.seed ^ 0x7e5e_7001);
    for_each_matrix(paths, columns, None, sources, serr, |b| {
        skipped += b.skipped;
        let m = mom.get_or_insert_with(|| Moments::new(b.dim()));
        for r in b.data.rows() {
            m.add(r);
            if sample.len() < cap {
                sample.push(r.to_vec());
            } else {
                let j = (rng.next_u64() % (seen as u64 + 1)) as usize;
                if j < cap {
                    sample[j] = r.to_vec();
                }
            }
            seen += 1;
        }
        Ok(())
    })?;
    let mom = mom.filter(|m| m.n > 0.0).ok_or_else(|| {
        ClusterError::Data(format!(
            "no row of the tables has every column of {}",
            columns.join(", ")
        ))
    })?;
    Ok(Sampled {
        mom,
        sample,
        seen,
        skipped,
    })
}

/// Pass 2 of [`cluster_tables`]: every usable row's cluster, written to `clusters`; the
/// cluster sizes.
fn assign_rows(
    paths: &[PathBuf],
    columns: &[String],
    sources: SourceRows,
    sc: &Scaling,
    fitted: &super::Fitted,
    clusters: &Path,
    meta: &[(String, String)],
) -> Result<Vec<usize>, ClusterError> {
    let table = clusters_table();
    let mut w = TableWriter::create(clusters, table.schema(), meta, 16_384)
        .map_err(|e| werr(clusters, e))?;
    let mut sizes = vec![0usize; fitted.model.k];
    let (mut x, mut post) = (vec![0.0; sc.mean.len()], Vec::new());
    for_each_matrix(paths, columns, None, sources, serr, |b| {
        for (key, r) in b.keys.into_iter().zip(b.data.rows()) {
            x.iter_mut().zip(r).for_each(|(a, v)| *a = *v);
            sc.apply(&mut x);
            let (cluster, distance, probability) = fitted.model.assign(&x, &mut post);
            sizes[cluster] += 1;
            w.push(table.row(ClusterRow {
                key,
                cluster,
                distance,
                probability,
            }))
            .map_err(|e| werr(clusters, e))?;
        }
        Ok(())
    })?;
    w.finish().map_err(|e| werr(clusters, e))?;
    Ok(sizes)
}

/// Cluster the feature tables' usable rows into `out` (see the module). `config_sha256`
/// (the run's configuration hash) goes into the tables' metadata beside `aepipe.table`.
pub fn cluster_tables(
    paths: &[PathBuf],
    out: &Path,
    cfg: &ValidCluster,
    sources: SourceRows,
    config_sha256: &str,
) -> Result<ClusterReport, ClusterError> {
    let meta = [(
        "aepipe.config_sha256".to_string(),
        config_sha256.to_string(),
    )];
    let first = paths
        .first()
        .ok_or_else(|| ClusterError::Data("no feature table to cluster".into()))?;
    let columns = columns_of(first, cfg)?;
    let key_col = columns
        .iter()
        .position(|c| c == "peak_freq_hz")
        .unwrap_or(0);
    let Sampled {
        mom,
        sample,
        seen,
        skipped,
    } = sample_rows(paths, &columns, cfg, sources)?;
    let sc = mom.scaling();
    let dim = sc.mean.len();
    let key: Vec<f64> = sample.iter().map(|r| r[key_col.min(dim - 1)]).collect();
    let mut z = Array2::from_shape_vec((sample.len(), dim), sample.concat())
        .expect("every sampled row has the table's dimension");
    drop(sample);
    sc.apply_rows(&mut z);
    let fitted = fit_matrix(z.view(), &key, cfg)?;
    std::fs::create_dir_all(out).map_err(|e| werr(out, e))?;
    let clusters = out.join("clusters.parquet");
    let sizes = assign_rows(paths, &columns, sources, &sc, &fitted, &clusters, &meta)?;
    let validity_path = out.join("validity.parquet");
    let vt = validity_table();
    let mut vw = TableWriter::create(&validity_path, vt.schema(), &meta, 1024)
        .map_err(|e| werr(&validity_path, e))?;
    for r in &fitted.validity {
        vw.push(vt.row(r.clone()))
            .map_err(|e| werr(&validity_path, e))?;
    }
    vw.finish().map_err(|e| werr(&validity_path, e))?;
    let model = out.join("model.json");
    let json = model_json(&fitted, &columns, &sc.mean, &sc.std, cfg, seen, skipped);
    crate::util::write_atomic(&model, json.to_string().as_bytes()).map_err(|e| werr(&model, e))?;
    Ok(ClusterReport {
        columns,
        rows: seen,
        skipped,
        fit_rows: z.nrows(),
        validity: fitted.validity,
        k: fitted.model.k,
        sizes,
        clusters,
        validity_table: validity_path,
        model,
    })
}

/// `model.json`: what was clustered and how, enough to read the clusters back in feature
/// units (centroids un-standardised) and to redo the fit.
fn model_json(
    f: &super::Fitted,
    columns: &[String],
    mean: &[f64],
    scale: &[f64],
    cfg: &ValidCluster,
    rows: usize,
    skipped: usize,
) -> serde_json::Value {
    let raw: Vec<Vec<f64>> = f
        .model
        .centroids
        .iter()
        .map(|c| {
            c.iter()
                .zip(mean.iter().zip(scale))
                .map(|(z, (m, s))| z * s + m)
                .collect()
        })
        .collect();
    let mixture = match &f.model.assigner {
        Assigner::Mixture(g) => serde_json::to_value(g).ok(),
        _ => None,
    };
    serde_json::json!({
        "method": f.model.method.as_str(),
        "k": f.model.k,
        "choose": cfg.choose.as_str(),
        "columns": columns,
        "mean": mean,
        "scale": scale,
        "centroids_z": f.model.centroids,
        "centroids": raw,
        "fit_sizes": f.model.sizes,
        "numbering": "rising mean peak_freq_hz of the fit rows (the first column without it); ties: larger first",
        "rows": rows,
        "skipped": skipped,
        "settings": {
            "k_min": cfg.k_min, "k_max": cfg.k_max, "seed": cfg.seed, "n_init": cfg.n_init,
            "max_fit_rows": cfg.max_fit_rows, "silhouette_rows": cfg.silhouette_rows,
            "som_rows": cfg.som_rows, "som_cols": cfg.som_cols,
        },
        "mixture": mixture,
        "tool_version": env!("CARGO_PKG_VERSION"),
    })
}
