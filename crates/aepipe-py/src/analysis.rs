//! The whole-batch analysis from Python: the trend statistics of a feature table and the
//! self-organising map (fit, predict, save and load in `aepipe som train`'s model folder).

use crate::control::TempDir;
use crate::errors;
use crate::frames::ArrowStream;
use aepipe::analysis::trend::{run_trend, TrendOptions};
use aepipe::config::Cutoff;
use aepipe::som::novelty::Novelty;
use aepipe::som::tables::{load_model, save_model, Composition, Model, Scaling, TrainingSet};
use aepipe::som::{Som, SomParams};
use aepipe::store::SourceRows;
use numpy::{PyArray1, PyArray2, PyArray3, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::PathBuf;

/// `trend.parquet`'s rows for feature tables (files written by aepipe, or by the Python
/// layer from a frame).
#[allow(clippy::too_many_arguments)] // one per keyword argument of the Python function
#[pyfunction]
#[pyo3(signature = (paths, cutoff="peak-load".to_string(), columns=None, alpha=0.01, exclude_outside=false, min_load_span_n=1.0, min_hits=10))]
pub fn trend(
    py: Python<'_>,
    paths: Vec<PathBuf>,
    cutoff: String,
    columns: Option<Vec<String>>,
    alpha: f64,
    exclude_outside: bool,
    min_load_span_n: f64,
    min_hits: usize,
) -> PyResult<ArrowStream> {
    if min_hits < 3 {
        return Err(errors::config(
            aepipe::config::AnalysisSettingsError::MinHits(min_hits).into(),
        ));
    }
    let cutoff: Cutoff = cutoff
        .parse()
        .map_err(|e: aepipe::config::AnalysisSettingsError| errors::config(e.into()))?;
    let opts = TrendOptions {
        cutoff,
        alpha,
        columns: columns.unwrap_or_default(),
        sources: SourceRows { exclude_outside },
        min_load_span_n,
        min_hits,
    };
    let dir = TempDir::new()?;
    let out = dir.path().to_path_buf();
    let table = py.detach(|| -> Result<_, aepipe::analysis::trend::TrendError> {
        let rep = run_trend(&paths, &out, &opts)?;
        Ok(ArrowStream::read(&rep.table_path)?)
    });
    table.map_err(errors::trend)
}

/// Best-matching nodes and their distances, one each per row.
type NodesAndDistances<'py> = (Bound<'py, PyArray1<i64>>, Bound<'py, PyArray1<f64>>);

/// A self-organising map with what is needed to apply it to feature tables: the model of
/// `MODEL_DIR/model.json`.
#[pyclass(module = "aepipe._aepipe", name = "SomModel", frozen)]
pub struct SomModel {
    model: Model,
}

/// A finite `n × dim` matrix in the map's scaling.
fn scaled(model: &Model, x: &PyReadonlyArray2<'_, f64>) -> PyResult<ndarray::Array2<f64>> {
    let mut a = x.as_array().as_standard_layout().into_owned();
    if a.ncols() != model.som.dim {
        return Err(errors::SomError::new_err(format!(
            "som: the map's nodes have {} values, the rows {}",
            model.som.dim,
            a.ncols()
        )));
    }
    if let Some(i) = a.iter().position(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "row {} holds a non-finite value",
            i / model.som.dim.max(1)
        )));
    }
    if let Some(s) = &model.scaling {
        s.apply_rows(&mut a);
    }
    Ok(a)
}

/// Train a map on `x` (rows are inputs) with the Table 5.2 stages; label its nodes with
/// `labels` (rows whose label is `None` train but do not vote).
#[pyfunction]
#[pyo3(signature = (x, labels, rows, cols, seed, columns, label_column, standardise))]
#[allow(clippy::too_many_arguments)]
pub fn som_fit(
    py: Python<'_>,
    x: PyReadonlyArray2<'_, f64>,
    labels: Option<Vec<Option<String>>>,
    rows: usize,
    cols: usize,
    seed: u64,
    columns: Vec<String>,
    label_column: String,
    standardise: bool,
) -> PyResult<SomModel> {
    let mut data = x.as_array().as_standard_layout().into_owned();
    if data.nrows() == 0 || data.ncols() == 0 {
        return Err(errors::SomError::new_err("som: no rows to train on"));
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "row {} holds a non-finite value",
            i / data.ncols()
        )));
    }
    if let Some(l) = &labels {
        if l.len() != data.nrows() {
            return Err(PyValueError::new_err(format!(
                "{} labels for {} rows",
                l.len(),
                data.nrows()
            )));
        }
    }
    let params = SomParams {
        rows,
        cols,
        seed,
        ..SomParams::default()
    }
    .check()
    .map_err(errors::som)?;
    let scaling = standardise.then(|| Scaling::fit(data.view()));
    if let Some(s) = &scaling {
        s.apply_rows(&mut data);
    }
    let model = py.detach(move || -> Result<Model, aepipe::som::SomError> {
        let mut som = Som::fit(&params, data.view())?;
        // Every row given is a reference (and its own source): each held out once for the
        // novelty threshold.
        let origin: Vec<usize> = (0..data.nrows()).collect();
        let novelty = Novelty::calibrate(&params, data.view(), &origin, &origin, seed)?;
        let mut composition = Composition::new();
        if let Some(l) = &labels {
            let keep: Vec<usize> = (0..l.len()).filter(|&i| l[i].is_some()).collect();
            let voters = data.select(ndarray::Axis(0), &keep);
            let names: Vec<String> = keep
                .iter()
                .map(|&i| l[i].clone().unwrap_or_default())
                .collect();
            for n in &names {
                let e = composition.entry(n.clone()).or_insert((0, 0));
                e.0 += 1;
                e.1 += 1;
            }
            som.label_nodes(voters.view(), &names)?;
        }
        Ok(Model {
            som,
            columns,
            label_column,
            scaling,
            // Every row given was a training row: no sampling, no balancing, no
            // calibration (what the caller chose to pass is the training set).
            training: TrainingSet {
                fraction: 1.0,
                exclude: Vec::new(),
                balance: false,
                seed,
                calibrate: false,
                calibration_exclude: Vec::new(),
            },
            composition,
            calibration: Composition::new(),
            novelty,
            tool_version: env!("CARGO_PKG_VERSION").into(),
        })
    });
    Ok(SomModel {
        model: model.map_err(errors::som)?,
    })
}

#[pymethods]
impl SomModel {
    /// Read `MODEL_DIR` (or its `model.json`, or a SOM_PAK `.cod` beside one), as
    /// `aepipe som classify` does.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<SomModel> {
        Ok(SomModel {
            model: load_model(&path).map_err(errors::som)?,
        })
    }

    /// Write `model.json` and `model.cod` into `dir`, which `aepipe som classify` reads.
    fn save(&self, dir: PathBuf) -> PyResult<()> {
        save_model(&self.model, &dir, None).map_err(errors::som)
    }

    #[getter]
    fn rows(&self) -> usize {
        self.model.som.rows
    }
    #[getter]
    fn cols(&self) -> usize {
        self.model.som.cols
    }
    #[getter]
    fn dim(&self) -> usize {
        self.model.som.dim
    }
    #[getter]
    fn seed(&self) -> u64 {
        self.model.som.params.seed
    }
    /// The feature columns the map's input is made of (a list column such as `tf_bins`
    /// gives its elements).
    #[getter]
    fn columns(&self) -> Vec<String> {
        self.model.columns.clone()
    }
    #[getter]
    fn label_column(&self) -> String {
        self.model.label_column.clone()
    }
    /// Node labels, node `r·cols + c`; empty for an unlabelled map.
    #[getter]
    fn labels(&self) -> Vec<String> {
        self.model.som.labels.clone()
    }
    /// Whether inputs are standardised (per-column mean and standard deviation of the
    /// training rows) before they meet the nodes.
    #[getter]
    fn standardised(&self) -> bool {
        self.model.scaling.is_some()
    }
    /// The quantisation error before training and after each stage (None for a map read
    /// from a SOM_PAK codebook).
    #[getter]
    fn training_qe(&self) -> Option<Vec<f64>> {
        self.model.som.log.as_ref().map(|l| l.qe.clone())
    }

    /// The novelty threshold for a quantile in (0, 1]: the conformal quantile of the
    /// distances of references held out of the map (`aepipe::som::novelty`); None when the
    /// map carries no calibration.
    fn novelty_threshold(&self, quantile: f64) -> PyResult<Option<f64>> {
        if !(quantile > 0.0 && quantile <= 1.0) {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "quantile {quantile} is not in (0, 1]"
            )));
        }
        Ok(self.model.novelty.as_ref().map(|n| n.threshold(quantile)))
    }

    /// The weights as rows × cols × dim (in the map's scaled space).
    fn codebook<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let s = &self.model.som;
        let a = ndarray::Array3::from_shape_vec((s.rows, s.cols, s.dim), s.weights.clone())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(PyArray3::from_owned_array(py, a))
    }

    /// Best-matching node of each row (r·cols + c) and its distance.
    fn bmu<'py>(
        &self,
        py: Python<'py>,
        x: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<NodesAndDistances<'py>> {
        let a = scaled(&self.model, &x)?;
        let (nodes, dist): (Vec<i64>, Vec<f64>) = py.detach(|| {
            a.rows()
                .into_iter()
                .map(|r| {
                    let (j, d) = self.model.som.bmu(r.as_slice().expect("standard layout"));
                    (j as i64, d)
                })
                .unzip()
        });
        Ok((PyArray1::from_vec(py, nodes), PyArray1::from_vec(py, dist)))
    }

    /// Mean distance of the rows to their best-matching nodes.
    fn quantization_error(&self, py: Python<'_>, x: PyReadonlyArray2<'_, f64>) -> PyResult<f64> {
        let a = scaled(&self.model, &x)?;
        Ok(py.detach(|| self.model.som.quantisation_error(a.view())))
    }

    /// Share of rows whose two best nodes are not neighbours.
    fn topographic_error(&self, py: Python<'_>, x: PyReadonlyArray2<'_, f64>) -> PyResult<f64> {
        let a = scaled(&self.model, &x)?;
        Ok(py.detach(|| self.model.som.topographic_error(a.view())))
    }

    /// The U-matrix: each node's mean distance to its 4 grid neighbours, rows × cols.
    fn umatrix<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        PyArray2::from_owned_array(py, self.model.som.u_matrix())
    }
}

/// One `validity.parquet` row: (method, k, davies_bouldin, silhouette, silhouette_rows,
/// calinski_harabasz, bic, log_likelihood, inertia, rows, chosen).
type ValidityTuple = (
    String,
    usize,
    Option<f64>,
    Option<f64>,
    usize,
    Option<f64>,
    Option<f64>,
    Option<f64>,
    f64,
    usize,
    bool,
);

/// Each row's cluster, distance to its centroid and (mixtures) probability.
type Assigned<'py> = (
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
);

/// Cluster the finite rows of `x` (z-scored here): `aepipe cluster` on a matrix. `key`
/// orders the clusters (the raw peak frequency). Returns (cluster, distance, probability —
/// NaN for the methods without one) per row, and the validity rows of every k.
#[pyfunction]
#[pyo3(signature = (x, key, method="kmeans", k_min=2, k_max=8, seed=2008, n_init=10, choose="davies-bouldin", max_fit_rows=50_000, silhouette_rows=5_000))]
#[allow(clippy::too_many_arguments)]
pub fn cluster_fit<'py>(
    py: Python<'py>,
    x: PyReadonlyArray2<'py, f64>,
    key: Vec<f64>,
    method: &str,
    k_min: usize,
    k_max: usize,
    seed: u64,
    n_init: usize,
    choose: &str,
    max_fit_rows: usize,
    silhouette_rows: usize,
) -> PyResult<(Assigned<'py>, Vec<ValidityTuple>)> {
    use aepipe::cluster::{ClusterConfig, Method};
    let method = Method::parse(method).ok_or_else(|| {
        PyValueError::new_err(format!("method {method}: kmeans, gmm or som-kmeans"))
    })?;
    let choose = aepipe::cluster::Choose::parse(choose).ok_or_else(|| {
        PyValueError::new_err(format!(
            "choose {choose}: davies-bouldin, silhouette, calinski-harabasz or bic"
        ))
    })?;
    let cfg = ClusterConfig {
        method,
        k_min,
        k_max,
        seed,
        n_init,
        choose,
        max_fit_rows,
        silhouette_rows,
        ..ClusterConfig::default()
    }
    .check()
    .map_err(|e| errors::cluster(e.into()))?;
    let a = x.as_array().to_owned();
    let (fitted, rows) = py
        .detach(|| aepipe::cluster::cluster_matrix(a.view(), &key, &cfg))
        .map_err(errors::cluster)?;
    let c: Vec<i64> = rows.iter().map(|r| r.0 as i64).collect();
    let d: Vec<f64> = rows.iter().map(|r| r.1).collect();
    let p: Vec<f64> = rows.iter().map(|r| r.2.unwrap_or(f64::NAN)).collect();
    let v = fitted
        .validity
        .iter()
        .map(|r| {
            (
                r.method.as_str().to_string(),
                r.k,
                r.davies_bouldin,
                r.silhouette,
                r.silhouette_rows,
                r.calinski_harabasz,
                r.bic,
                r.log_likelihood,
                r.inertia,
                r.rows,
                r.chosen,
            )
        })
        .collect();
    Ok((
        (
            PyArray1::from_vec(py, c),
            PyArray1::from_vec(py, d),
            PyArray1::from_vec(py, p),
        ),
        v,
    ))
}

/// Davies–Bouldin, silhouette, Calinski–Harabasz (None below 2 clusters) and inertia.
type Indices = (Option<f64>, Option<f64>, Option<f64>, f64);

/// The validity indices of a given partition of `x` (as is, not standardised):
/// (davies_bouldin, silhouette, calinski_harabasz, inertia), the silhouette exact.
#[pyfunction]
pub fn cluster_validity(
    py: Python<'_>,
    x: PyReadonlyArray2<'_, f64>,
    labels: Vec<usize>,
) -> PyResult<Indices> {
    use aepipe::cluster::validity as v;
    let a = x.as_array().to_owned();
    if labels.len() != a.nrows() {
        return Err(PyValueError::new_err(format!(
            "{} labels for {} rows",
            labels.len(),
            a.nrows()
        )));
    }
    Ok(py.detach(|| {
        (
            v::davies_bouldin(a.view(), &labels),
            v::silhouette(a.view(), &labels),
            v::calinski_harabasz(a.view(), &labels),
            v::inertia(a.view(), &labels),
        )
    }))
}
