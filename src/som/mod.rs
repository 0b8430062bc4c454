//! Self-organising map (Kohonen; thesis ch. 5.3–5.4).
//!
//! A rectangular map of `rows × cols` nodes, each a weight vector of the input dimension.
//! Online training (Eq. 5.3.3): one random input per iteration, best-matching unit by
//! Euclidean distance (Eq. 5.3.1), Gaussian neighbourhood on grid distance
//! `h = α(t)·exp(−d²/2σ(t)²)` (Eq. 5.3.2), α decaying linearly to 0 and σ linearly to 1 in
//! each stage. Default stages: Table 5.2 (ordering α 0.05, σ 10, 1 000 iterations;
//! convergence α 0.01, σ 3, 10 000 iterations). A seed makes training reproducible bit for bit.
//!
//! Hyper-parameters are checked once into [`SomParams::check`] → [`ValidParams`] (linfa's
//! way), then [`Som::fit`] trains and [`Som::bmu`] / [`Som::classify`] predict.

pub mod classify;
mod codebook;
pub mod layout;
pub mod novelty;
pub mod profile;
pub mod settings;
pub mod tables;

use crate::util::Rng;
use ndarray::{Array2, ArrayView2};

#[derive(Debug, thiserror::Error)]
pub enum SomError {
    #[error("som: {0}")]
    Params(String),
    #[error("som: {0}")]
    Data(String),
    /// No row of the feature tables can be put on the map (every one flat or unlabelled): a
    /// caller classifying part by part (`aepipe watch`) goes on to the next part.
    #[error("som: no usable rows in the feature tables")]
    NoUsableRows,
    /// A model or feature table could not be read.
    #[error("{path}: {message}")]
    File { path: String, message: String },
    /// A model, classification or picture could not be written.
    #[error("{path}: {message}")]
    Write { path: String, message: String },
    #[error("SOM_PAK codebook: {0}")]
    Codebook(String),
    /// A temporary (spill) file of a whole-batch stage could not be written or read.
    #[error(transparent)]
    Store(#[from] crate::store::StoreError),
}

impl crate::util::HasKind for SomError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            SomError::Params(_)
            | SomError::Data(_)
            | SomError::NoUsableRows
            | SomError::File { .. }
            | SomError::Codebook(_) => crate::util::ErrorKind::Usage,
            SomError::Write { .. } => crate::util::ErrorKind::Failed,
            SomError::Store(e) => crate::util::HasKind::kind(e),
        }
    }
}

/// One training stage.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrainingStage {
    pub alpha: f64,
    pub sigma: f64,
    pub iterations: usize,
}

/// How the codebook starts.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Init {
    /// Random training vectors (seeded).
    Samples,
    /// Uniform random in the bounding box of the training data (seeded).
    Random,
    /// Linear (PCA) initialisation: the codebook spans the plane of the two leading principal
    /// components, node (r, c) at `mean + a_r·√λ₁·e₁ + b_c·√λ₂·e₂` with a, b evenly spaced in
    /// [−1, 1]; the longer grid side follows the first component. Training from it needs
    /// less ordering (Kohonen's linear init; MiniSom's `pca_weights_init` without its
    /// missing mean).
    Linear,
    /// A given codebook (`rows·cols × dim`, row-major, node r·cols + c).
    Given(Vec<f64>),
}

/// The two leading principal components of `data` (`n × dim`): mean, and (eigenvalue,
/// unit eigenvector) pairs of the sample covariance, by power iteration with deflation on the
/// centred data (no `dim × dim` matrix is formed). Seeded start vectors; deterministic.
pub fn principal_components(
    data: &[f64],
    dim: usize,
    seed: u64,
) -> (Vec<f64>, Vec<(f64, Vec<f64>)>) {
    let n = data.len() / dim;
    let mut mean = vec![0.0; dim];
    for x in data.chunks(dim) {
        for (m, v) in mean.iter_mut().zip(x) {
            *m += v;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n.max(1) as f64);
    let centred: Vec<f64> = data
        .chunks(dim)
        .flat_map(|x| x.iter().zip(&mean).map(|(v, m)| v - m))
        .collect();
    let mut rng = Rng::new(seed ^ 0x9e37_79b9_7f4a_7c15);
    let mut found: Vec<(f64, Vec<f64>)> = Vec::new();
    let denom = (n.max(2) - 1) as f64;
    for _ in 0..2.min(dim) {
        let mut v: Vec<f64> = (0..dim).map(|_| rng.range(-1.0, 1.0)).collect();
        let mut lambda = 0.0;
        for _ in 0..500 {
            // w = Cv = Xᵀ(Xv)/(n−1), minus the components already found.
            let mut w = vec![0.0; dim];
            for x in centred.chunks(dim) {
                let s: f64 = x.iter().zip(&v).map(|(a, b)| a * b).sum();
                for (wk, xk) in w.iter_mut().zip(x) {
                    *wk += s * xk;
                }
            }
            w.iter_mut().for_each(|x| *x /= denom);
            for (l, e) in &found {
                let s: f64 = e.iter().zip(&v).map(|(a, b)| a * b).sum();
                for (wk, ek) in w.iter_mut().zip(e) {
                    *wk -= l * s * ek;
                }
            }
            let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm == 0.0 {
                lambda = 0.0;
                break;
            }
            w.iter_mut().for_each(|x| *x /= norm);
            let change: f64 = w.iter().zip(&v).map(|(a, b)| (a - b).abs()).sum();
            v = w;
            let converged = (norm - lambda).abs() <= 1e-12 * norm && change < 1e-9;
            lambda = norm;
            if converged {
                break;
            }
        }
        found.push((lambda, v));
    }
    (mean, found)
}

#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SomParams {
    pub rows: usize,
    pub cols: usize,
    pub stages: Vec<TrainingStage>,
    pub seed: u64,
    pub init: Init,
}

pub use settings::som_defaults as defaults;

impl Default for SomParams {
    fn default() -> Self {
        SomParams {
            rows: defaults::ROWS,
            cols: defaults::COLS,
            stages: vec![
                TrainingStage {
                    alpha: 0.05,
                    sigma: 10.0,
                    iterations: 1000,
                },
                TrainingStage {
                    alpha: 0.01,
                    sigma: 3.0,
                    iterations: 10_000,
                },
            ],
            seed: defaults::SEED,
            init: Init::Samples,
        }
    }
}

/// Parameters that passed [`SomParams::check`].
#[derive(Debug, Clone, PartialEq)]
pub struct ValidParams(SomParams);

impl SomParams {
    pub fn check(self) -> Result<ValidParams, SomError> {
        if self.rows == 0 || self.cols == 0 {
            return Err(SomError::Params(format!(
                "map must have ≥ 1 row and column, got {}×{}",
                self.rows, self.cols
            )));
        }
        if self.stages.is_empty() {
            return Err(SomError::Params("at least one training stage".into()));
        }
        for (i, s) in self.stages.iter().enumerate() {
            let ok = s.alpha > 0.0 && s.alpha <= 1.0 && s.sigma > 0.0 && s.iterations > 0;
            if !ok {
                return Err(SomError::Params(format!(
                    "stage {}: need 0 < alpha ≤ 1, sigma > 0, iterations ≥ 1; got {s:?}",
                    i + 1
                )));
            }
        }
        Ok(ValidParams(self))
    }
}

pub use codebook::{MAX_CODEBOOK_VALUES, MAX_MAP_NODES};

/// What training did.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrainingLog {
    pub n_inputs: usize,
    /// Quantisation error before training and after each stage.
    pub qe: Vec<f64>,
    pub topographic_error: f64,
}

/// A trained map.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Som {
    pub rows: usize,
    pub cols: usize,
    pub dim: usize,
    /// `rows·cols × dim`, node `r·cols + c`.
    pub weights: Vec<f64>,
    /// Node labels (majority vote of training hits; unlabelled nodes take their nearest
    /// labelled node in weight space). Empty until [`Som::label_nodes`].
    pub labels: Vec<String>,
    pub params: SomParams,
    pub log: Option<TrainingLog>,
}

use kernel::sq_dist;

/// Class-balanced votes of labelled rows for the nodes they map to, gathered one row at a
/// time (each row of class c votes 1 / (rows of c)) so that a calibration set need not be in
/// memory; the same sums in the same order as voting over the whole set at once.
#[derive(Debug, Clone)]
pub struct Votes {
    sizes: std::collections::BTreeMap<String, usize>,
    votes: Vec<std::collections::BTreeMap<String, f64>>,
}

impl Votes {
    /// Votes for `som`'s nodes, with the class sizes of the whole calibration set.
    pub fn new(som: &Som, sizes: std::collections::BTreeMap<String, usize>) -> Votes {
        Votes {
            sizes,
            votes: vec![Default::default(); som.nodes()],
        }
    }

    /// One row (in the map's scaling) of class `label` votes for its BMU.
    pub fn add(&mut self, som: &Som, x: &[f64], label: &str) {
        let w = 1.0 / self.sizes.get(label).copied().unwrap_or(1).max(1) as f64;
        let b = som.bmu(x).0;
        match self.votes[b].get_mut(label) {
            Some(v) => *v += w,
            None => {
                self.votes[b].insert(label.to_string(), 0.0 + w);
            }
        }
    }

    /// Each node's winning label (`None`: no row reached it); ties go to the label that
    /// sorts first.
    fn winners(&self) -> Vec<Option<String>> {
        self.votes
            .iter()
            .map(|v| {
                v.iter()
                    .fold(None, |m: Option<(&String, f64)>, (l, &c)| match m {
                        Some((_, mc)) if mc >= c => m,
                        _ => Some((l, c)),
                    })
                    .map(|(l, _)| l.clone())
            })
            .collect()
    }
}

/// The hot loops of training. Each sum runs in 8 fixed lanes, so the compiler can keep them
/// in SIMD registers and the result does not depend on the vector width. The update uses
/// `mul_add`, which is one rounding on every machine: the AVX2+FMA build of the same code
/// (picked at run time) and the portable build give bit-identical weights. (On an x86 CPU
/// without FMA, i.e. older than ~2013, the portable build's `mul_add` is a slow library call.)
mod kernel {
    /// Squared Euclidean distance.
    #[inline(always)]
    pub fn sq_dist(a: &[f64], b: &[f64]) -> f64 {
        let mut acc = [0.0f64; 8];
        let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
        let (ra, rb) = (ca.remainder(), cb.remainder());
        for (x, y) in ca.zip(cb) {
            for k in 0..8 {
                let d = x[k] - y[k];
                acc[k] += d * d;
            }
        }
        let mut s: f64 = acc.iter().sum();
        for (x, y) in ra.iter().zip(rb) {
            s += (x - y) * (x - y);
        }
        s
    }

    /// `w += h·(x − w)`, returning the squared distance of the updated `w` to `y`.
    #[inline(always)]
    fn update_dist(w: &mut [f64], h: f64, x: &[f64], y: &[f64]) -> f64 {
        let mut acc = [0.0f64; 8];
        let split = w.len() / 8 * 8;
        let (w8, wr) = w.split_at_mut(split);
        for ((wc, xc), yc) in w8
            .chunks_exact_mut(8)
            .zip(x.chunks_exact(8))
            .zip(y.chunks_exact(8))
        {
            for k in 0..8 {
                let nw = h.mul_add(xc[k] - wc[k], wc[k]);
                wc[k] = nw;
                let d = yc[k] - nw;
                acc[k] = d.mul_add(d, acc[k]);
            }
        }
        let mut s: f64 = acc.iter().sum();
        for ((wv, &xv), &yv) in wr.iter_mut().zip(&x[split..]).zip(&y[split..]) {
            *wv += h * (xv - *wv);
            s += (yv - *wv) * (yv - *wv);
        }
        s
    }

    #[inline(always)]
    pub(super) fn step_generic(
        weights: &mut [f64],
        dim: usize,
        h: &[f64],
        x: &[f64],
        y: &[f64],
    ) -> (usize, f64) {
        let mut best = (0usize, f64::INFINITY);
        for (j, w) in weights.chunks_exact_mut(dim).enumerate() {
            let d = if h[j] > 0.0 {
                update_dist(w, h[j], x, y)
            } else {
                sq_dist(y, w)
            };
            if d < best.1 {
                best = (j, d);
            }
        }
        best
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn step_avx2(
        weights: &mut [f64],
        dim: usize,
        h: &[f64],
        x: &[f64],
        y: &[f64],
    ) -> (usize, f64) {
        step_generic(weights, dim, h, x, y)
    }

    /// One online update of every node with weight `h[j]` towards `x` (Eq. 5.3.3), fused with
    /// the search for `y`'s best-matching unit in the updated codebook. Returns that unit and
    /// its squared distance.
    pub fn step(weights: &mut [f64], dim: usize, h: &[f64], x: &[f64], y: &[f64]) -> (usize, f64) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { step_avx2(weights, dim, h, x, y) };
        }
        step_generic(weights, dim, h, x, y)
    }
}

/// The codebook before training (`Init`): given, uniform in the data's bounding box, the
/// plane of the two leading principal components, or random training vectors. Draws from
/// `rng` first, so training continues the same stream.
fn initial_codebook(
    p: &SomParams,
    data: &[f64],
    dim: usize,
    rng: &mut Rng,
) -> Result<Vec<f64>, SomError> {
    let n = data.len() / dim;
    let nodes = p.rows * p.cols;
    Ok(match &p.init {
        Init::Given(w) => {
            if w.len() != nodes * dim {
                return Err(SomError::Params(format!(
                    "initial codebook has {} values, need {}",
                    w.len(),
                    nodes * dim
                )));
            }
            w.clone()
        }
        Init::Random => {
            let (mut lo, mut hi) = (vec![f64::INFINITY; dim], vec![f64::NEG_INFINITY; dim]);
            for x in data.chunks(dim) {
                for k in 0..dim {
                    lo[k] = lo[k].min(x[k]);
                    hi[k] = hi[k].max(x[k]);
                }
            }
            (0..nodes * dim)
                .map(|i| rng.range(lo[i % dim], hi[i % dim]))
                .collect()
        }
        Init::Linear => {
            let (mean, pcs) = principal_components(data, dim, p.seed);
            let spread = |i: usize, len: usize| {
                if len < 2 {
                    0.0
                } else {
                    2.0 * i as f64 / (len - 1) as f64 - 1.0
                }
            };
            let axis = |k: usize| {
                pcs.get(k)
                    .map(|(l, e)| e.iter().map(|x| x * l.max(0.0).sqrt()).collect())
                    .unwrap_or_else(|| vec![0.0; dim])
            };
            // The longer side of the grid follows the first component.
            let (row_axis, col_axis): (Vec<f64>, Vec<f64>) = if p.rows >= p.cols {
                (axis(0), axis(1))
            } else {
                (axis(1), axis(0))
            };
            let mut w = Vec::with_capacity(nodes * dim);
            for j in 0..nodes {
                let (a, b) = (spread(j / p.cols, p.rows), spread(j % p.cols, p.cols));
                w.extend((0..dim).map(|k| mean[k] + a * row_axis[k] + b * col_axis[k]));
            }
            w
        }
        Init::Samples => (0..nodes)
            .flat_map(|_| {
                let i = (rng.next_u64() % n as u64) as usize;
                data[i * dim..(i + 1) * dim].to_vec()
            })
            .collect(),
    })
}

impl Som {
    pub fn nodes(&self) -> usize {
        self.rows * self.cols
    }

    pub fn node(&self, j: usize) -> &[f64] {
        &self.weights[j * self.dim..(j + 1) * self.dim]
    }

    /// The codebook, `nodes × dim` (node `r·cols + c`), a view of the weights.
    pub fn codebook(&self) -> ArrayView2<'_, f64> {
        ArrayView2::from_shape((self.nodes(), self.dim), &self.weights).expect("nodes × dim")
    }

    /// Train on `data` (`n × dim`), logging the quantisation error before training and after
    /// each stage, and the final topographic error.
    pub fn fit(params: &ValidParams, data: ArrayView2<f64>) -> Result<Som, SomError> {
        Som::fit_with(params, data, true)
    }

    /// [`Som::fit`] with the quality passes optional: each costs as much as ~600 training
    /// iterations, so the benchmark times training alone, as its peers do, and measures the
    /// quality afterwards. The weights are the same either way.
    pub fn fit_with(
        params: &ValidParams,
        data: ArrayView2<f64>,
        track_quality: bool,
    ) -> Result<Som, SomError> {
        let dim = data.ncols();
        let data = data.as_standard_layout();
        let data = data.as_slice().expect("standard layout");
        let p = &params.0;
        if dim == 0 || data.is_empty() || !data.len().is_multiple_of(dim) {
            return Err(SomError::Data(format!(
                "{} values do not make rows of dimension {dim}",
                data.len()
            )));
        }
        if data.iter().any(|v| !v.is_finite()) {
            return Err(SomError::Data(
                "training data holds NaN or infinite values".into(),
            ));
        }
        let n = data.len() / dim;
        let mut rng = Rng::new(p.seed);
        let weights = initial_codebook(p, data, dim, &mut rng)?;
        let mut som = Som {
            rows: p.rows,
            cols: p.cols,
            dim,
            weights,
            labels: Vec::new(),
            params: p.clone(),
            log: None,
        };
        let qe = som.train_stages(data, &mut rng, track_quality);
        if track_quality {
            som.log = Some(TrainingLog {
                n_inputs: n,
                qe,
                topographic_error: som.topographic_error_of(data),
            });
        }
        Ok(som)
    }

    /// The online training of Table 5.2's stages (Eq. 5.3.3), continuing `rng`; returns the
    /// quantisation error before training and after each stage (empty unless tracked).
    fn train_stages(&mut self, data: &[f64], rng: &mut Rng, track_quality: bool) -> Vec<f64> {
        let p = self.params.clone();
        let (dim, nodes) = (self.dim, self.nodes());
        let n = data.len() / dim;
        let som = self;
        let mut qe = Vec::new();
        if track_quality {
            qe.push(som.quantisation_error_of(data));
        }
        // The sample of every iteration is drawn one step ahead, so that the pass that updates
        // the weights also finds the next sample's BMU (one sweep over the codebook per
        // iteration instead of two). The draw order is unchanged.
        let mut draw = || (rng.next_u64() % n as u64) as usize;
        let total: usize = p.stages.iter().map(|s| s.iterations).sum();
        let mut i = draw();
        let mut b = som.bmu(&data[i * dim..(i + 1) * dim]).0;
        let mut h = vec![0.0f64; nodes];
        let (mut row_f, mut col_f) = (vec![0.0f64; p.rows], vec![0.0f64; p.cols]);
        let mut done = 0usize;
        for st in &p.stages {
            let t_max = st.iterations as f64;
            for t in 0..st.iterations {
                let frac = t as f64 / t_max;
                let alpha = st.alpha * (1.0 - frac);
                let sigma = st.sigma + (1.0 - st.sigma) * frac;
                // The Gaussian of the grid distance factors into a row and a column part,
                // so rows + cols exponentials serve all rows·cols nodes.
                let (br, bc) = (b / p.cols, b % p.cols);
                let inv = -1.0 / (2.0 * sigma * sigma);
                let gauss = |d: f64| (d * d * inv).exp();
                for (r, f) in row_f.iter_mut().enumerate() {
                    *f = alpha * gauss(r as f64 - br as f64);
                }
                for (c, f) in col_f.iter_mut().enumerate() {
                    *f = gauss(c as f64 - bc as f64);
                }
                for (j, hj) in h.iter_mut().enumerate() {
                    let v = row_f[j / p.cols] * col_f[j % p.cols];
                    // Below 1e-12 an update cannot change a weight in double precision.
                    *hj = if v < 1e-12 { 0.0 } else { v };
                }
                done += 1;
                let next = if done < total { draw() } else { i };
                b = kernel::step(
                    &mut som.weights,
                    dim,
                    &h,
                    &data[i * dim..(i + 1) * dim],
                    &data[next * dim..(next + 1) * dim],
                )
                .0;
                i = next;
            }
            if track_quality {
                qe.push(som.quantisation_error_of(data));
            }
        }
        qe
    }

    /// Best-matching unit and its Euclidean distance (Eq. 5.3.1).
    pub fn bmu(&self, x: &[f64]) -> (usize, f64) {
        let mut best = (0, f64::INFINITY);
        for j in 0..self.nodes() {
            let d = sq_dist(x, self.node(j));
            if d < best.1 {
                best = (j, d);
            }
        }
        (best.0, best.1.sqrt())
    }

    /// The nearest node among those `keep` accepts, and its distance; `None` when it accepts
    /// none. With every node kept this is [`Som::bmu`].
    pub fn bmu_among(&self, x: &[f64], keep: impl Fn(usize) -> bool) -> Option<(usize, f64)> {
        let mut best = None;
        for j in (0..self.nodes()).filter(|&j| keep(j)) {
            let d = sq_dist(x, self.node(j));
            if best.is_none_or(|(_, b)| d < b) {
                best = Some((j, d));
            }
        }
        best.map(|(j, d)| (j, d.sqrt()))
    }

    /// Mean distance of each input to its BMU (Eq. 5.4.1).
    pub fn quantisation_error(&self, data: ArrayView2<f64>) -> f64 {
        let data = data.as_standard_layout();
        self.quantisation_error_of(data.as_slice().expect("standard layout"))
    }

    fn quantisation_error_of(&self, data: &[f64]) -> f64 {
        let n = data.len() / self.dim;
        data.chunks(self.dim).map(|x| self.bmu(x).1).sum::<f64>() / n.max(1) as f64
    }

    fn adjacent(&self, a: usize, b: usize) -> bool {
        let (ar, ac) = ((a / self.cols) as i64, (a % self.cols) as i64);
        let (br, bc) = ((b / self.cols) as i64, (b % self.cols) as i64);
        (ar - br).abs() <= 1 && (ac - bc).abs() <= 1 && a != b
    }

    /// Share of inputs whose best and second-best units are not neighbours on the grid
    /// (8-neighbourhood, as MiniSom).
    pub fn topographic_error(&self, data: ArrayView2<f64>) -> f64 {
        let data = data.as_standard_layout();
        self.topographic_error_of(data.as_slice().expect("standard layout"))
    }

    fn topographic_error_of(&self, data: &[f64]) -> f64 {
        if self.nodes() < 2 {
            return 0.0;
        }
        let n = data.len() / self.dim;
        let bad = data
            .chunks(self.dim)
            .filter(|x| {
                let mut d: Vec<(f64, usize)> = (0..self.nodes())
                    .map(|j| (sq_dist(x, self.node(j)), j))
                    .collect();
                d.select_nth_unstable_by(1, |a, b| a.0.total_cmp(&b.0));
                let (first, second) = if d[0].0 <= d[1].0 {
                    (d[0].1, d[1].1)
                } else {
                    (d[1].1, d[0].1)
                };
                !self.adjacent(first, second)
            })
            .count();
        bad as f64 / n.max(1) as f64
    }

    /// U-matrix (Ultsch): for each node, the mean distance of its weight vector to those of
    /// its 4-neighbours on the grid, `rows × cols`.
    pub fn u_matrix(&self) -> Array2<f64> {
        let u: Vec<f64> = (0..self.nodes())
            .map(|j| {
                let (r, c) = ((j / self.cols) as i64, (j % self.cols) as i64);
                let nb: Vec<usize> = [(r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)]
                    .into_iter()
                    .filter(|&(a, b)| {
                        a >= 0 && b >= 0 && (a as usize) < self.rows && (b as usize) < self.cols
                    })
                    .map(|(a, b)| a as usize * self.cols + b as usize)
                    .collect();
                nb.iter()
                    .map(|&k| sq_dist(self.node(j), self.node(k)).sqrt())
                    .sum::<f64>()
                    / nb.len().max(1) as f64
            })
            .collect();
        Array2::from_shape_vec((self.rows, self.cols), u).expect("rows × cols")
    }

    /// The votes of labelled inputs for the nodes they map to, each input of class c voting
    /// 1 / `sizes[c]` (1 for a class `sizes` does not name).
    fn votes(
        &self,
        data: ArrayView2<f64>,
        labels: &[String],
        sizes: std::collections::BTreeMap<String, usize>,
    ) -> Result<Votes, SomError> {
        let data = data.as_standard_layout();
        let data = data.as_slice().expect("standard layout");
        if data.len() / self.dim != labels.len() {
            return Err(SomError::Data(format!(
                "{} inputs but {} labels",
                data.len() / self.dim,
                labels.len()
            )));
        }
        let mut votes = Votes::new(self, sizes);
        for (x, l) in data.chunks(self.dim).zip(labels) {
            votes.add(self, x, l);
        }
        Ok(votes)
    }

    /// Label nodes by majority vote of the labelled inputs mapped to them (ties: the label
    /// that sorts first); nodes that won no input take the label of the nearest labelled node
    /// in weight space.
    pub fn label_nodes(
        &mut self,
        data: ArrayView2<f64>,
        labels: &[String],
    ) -> Result<(), SomError> {
        let voted = self.votes(data, labels, Default::default())?.winners();
        if voted.iter().all(Option::is_none) {
            return Err(SomError::Data("no labelled input".into()));
        }
        self.labels = (0..self.nodes())
            .map(|j| match &voted[j] {
                Some(l) => l.clone(),
                None => {
                    let k = (0..self.nodes())
                        .filter(|&k| voted[k].is_some())
                        .min_by(|&a, &b| {
                            sq_dist(self.node(j), self.node(a))
                                .total_cmp(&sq_dist(self.node(j), self.node(b)))
                        })
                        .expect("some labelled");
                    voted[k].clone().expect("labelled")
                }
            })
            .collect();
        Ok(())
    }

    /// Relabel the nodes that win at least one of these labelled inputs by their
    /// class-balanced majority (ties: the label that sorts first); the other nodes keep
    /// their labels. Reading a trained map's areas with a calibration set: where it has no
    /// evidence, the training labels stand.
    pub fn relabel_where_hit(
        &mut self,
        data: ArrayView2<f64>,
        labels: &[String],
    ) -> Result<usize, SomError> {
        if self.labels.len() != self.nodes() {
            return Err(SomError::Data("the nodes carry no labels to keep".into()));
        }
        // Each row votes 1 / (rows of its class): every class has the same total say, so a
        // class the calibration set holds many of does not win a node by numbers alone.
        let mut sizes: std::collections::BTreeMap<String, usize> = Default::default();
        for l in labels {
            *sizes.entry(l.clone()).or_default() += 1;
        }
        let votes = self.votes(data, labels, sizes)?;
        self.relabel_with(votes)
    }

    /// [`Som::relabel_where_hit`]'s second half: apply the votes gathered row by row (a
    /// calibration set streamed in batches). Returns how many nodes changed label.
    pub fn relabel_with(&mut self, votes: Votes) -> Result<usize, SomError> {
        if self.labels.len() != self.nodes() {
            return Err(SomError::Data("the nodes carry no labels to keep".into()));
        }
        let mut changed = 0;
        for (j, v) in votes.winners().into_iter().enumerate() {
            if let Some(l) = v {
                if self.labels[j] != l {
                    self.labels[j] = l;
                    changed += 1;
                }
            }
        }
        Ok(changed)
    }

    /// BMU, distance and the BMU's label.
    pub fn classify(&self, x: &[f64]) -> (usize, f64, Option<&str>) {
        let (b, d) = self.bmu(x);
        (b, d, self.labels.get(b).map(String::as_str))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(data: &[f64], dim: usize) -> ArrayView2<'_, f64> {
        ArrayView2::from_shape((data.len() / dim, dim), data).unwrap()
    }

    /// An anisotropic Gaussian cloud (σ 3 along (1,1)/√2, σ 1 across, centred at (5, −2)):
    /// PCA recovers the axes and variances, and the linear codebook spans ±σ along them.
    #[test]
    fn linear_init_spans_the_principal_plane() {
        let mut rng = Rng::new(11);
        let (n, dim) = (4000, 3);
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let mut data = Vec::with_capacity(n * dim);
        for _ in 0..n {
            let (a, b) = (3.0 * rng.normal(), rng.normal());
            data.extend([5.0 + s * (a - b), -2.0 + s * (a + b), 0.1 * rng.normal()]);
        }
        let (mean, pcs) = principal_components(&data, dim, 1);
        assert!((mean[0] - 5.0).abs() < 0.15 && (mean[1] + 2.0).abs() < 0.15);
        assert!((pcs[0].0 - 9.0).abs() < 0.6, "λ1 {}", pcs[0].0);
        assert!((pcs[1].0 - 1.0).abs() < 0.1, "λ2 {}", pcs[1].0);
        assert!((pcs[0].1[0] * s + pcs[0].1[1] * s).abs() > 0.999);
        assert!((pcs[1].1[0] * s - pcs[1].1[1] * s).abs() > 0.999);
        let params = SomParams {
            rows: 6,
            cols: 4,
            // A stage too weak to move a weight (h < 1e-12 is skipped): the codebook stays
            // as initialised.
            stages: vec![TrainingStage {
                alpha: 1e-13,
                sigma: 1.0,
                iterations: 1,
            }],
            init: Init::Linear,
            ..Default::default()
        }
        .check()
        .unwrap();
        let som = Som::fit(&params, m(&data, dim)).unwrap();
        // First and last row along e1: 2·√λ1 ≈ 6 apart; first and last column ≈ 2 apart.
        let d = |a: usize, b: usize| sq_dist(som.node(a), som.node(b)).sqrt();
        assert!((d(0, 5 * 4) - 6.0).abs() < 0.3, "{}", d(0, 20));
        assert!((d(0, 3) - 2.0).abs() < 0.15, "{}", d(0, 3));
        // The linear start is already a good map: QE far below a random start.
        let random = Som::fit(
            &SomParams {
                init: Init::Random,
                ..params.0.clone()
            }
            .check()
            .unwrap(),
            m(&data, dim),
        )
        .unwrap();
        assert!(
            som.quantisation_error(m(&data, dim)) < 0.5 * random.quantisation_error(m(&data, dim))
        );
    }

    /// The run-time dispatched kernel gives the same bits as the portable one, and the fused
    /// step equals an update followed by a separate distance search.
    #[test]
    fn fused_step_is_exact_and_width_independent() {
        let (nodes, dim) = (12, 203); // 203 = 25·8 + 3 exercises the remainder
        let mut rng = Rng::new(7);
        let w0: Vec<f64> = (0..nodes * dim).map(|_| rng.range(-1.0, 1.0)).collect();
        let x: Vec<f64> = (0..dim).map(|_| rng.range(-1.0, 1.0)).collect();
        let y: Vec<f64> = (0..dim).map(|_| rng.range(-1.0, 1.0)).collect();
        let h: Vec<f64> = (0..nodes)
            .map(|j| if j % 5 == 0 { 0.0 } else { 0.01 * j as f64 })
            .collect();
        let (mut a, mut b) = (w0.clone(), w0.clone());
        let ra = kernel::step(&mut a, dim, &h, &x, &y);
        let rb = kernel::step_generic(&mut b, dim, &h, &x, &y);
        assert_eq!(ra.0, rb.0);
        assert_eq!(ra.1.to_bits(), rb.1.to_bits());
        assert!(a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()));
        // Reference: plain update, then the nearest node to y.
        let mut c = w0.clone();
        for (j, w) in c.chunks_mut(dim).enumerate() {
            for (wv, xv) in w.iter_mut().zip(&x) {
                *wv += h[j] * (xv - *wv);
            }
        }
        let (best, d) = (0..nodes)
            .map(|j| (j, sq_dist(&y, &c[j * dim..(j + 1) * dim])))
            .min_by(|p, q| p.1.total_cmp(&q.1))
            .unwrap();
        assert_eq!(ra.0, best);
        assert!((ra.1 - d).abs() <= 1e-12 * d);
        assert!(a.iter().zip(&c).all(|(p, q)| (p - q).abs() <= 1e-15));
        // Nodes with h = 0 are untouched.
        assert_eq!(&a[..dim], &w0[..dim]);
    }

    /// Calibration relabels only the nodes it reaches, by a class-balanced majority.
    #[test]
    fn calibration_relabels_the_nodes_it_reaches() {
        let mut rng = Rng::new(3);
        let data: Vec<f64> = (0..300)
            .map(|i| [0.0, 5.0, 10.0][i % 3] + 0.1 * rng.normal())
            .collect();
        let params = SomParams {
            rows: 1,
            cols: 3,
            ..SomParams::default()
        }
        .check()
        .unwrap();
        let mut som = Som::fit(&params, m(&data, 1)).unwrap();
        let node = |x: f64, som: &Som| som.bmu(&[x]).0;
        assert_eq!(
            [node(0.0, &som), node(5.0, &som), node(10.0, &som)]
                .iter()
                .collect::<std::collections::BTreeSet<_>>()
                .len(),
            3
        );
        let train: Vec<String> = data
            .iter()
            .map(|&x| if x < 7.5 { "a" } else { "b" }.to_string())
            .collect();
        som.label_nodes(m(&data, 1), &train).unwrap();
        // Calibration: class "a" has 10 rows (8 at 0, 2 at 5), class "e" one row at 5.
        let cal: Vec<f64> = [vec![0.0; 8], vec![5.0, 5.0, 5.0]].concat();
        let labels: Vec<String> = [vec!["a"; 10], vec!["e"]]
            .concat()
            .into_iter()
            .map(String::from)
            .collect();
        let changed = som.relabel_where_hit(m(&cal, 1), &labels).unwrap();
        assert_eq!(changed, 1);
        assert_eq!(som.classify(&[0.0]).2, Some("a"));
        // At 5: "e" has 1/1 of its rows there, "a" 2/10 of its: "e" wins the node.
        assert_eq!(som.classify(&[5.0]).2, Some("e"));
        // No calibration row reaches 10: the training label stands.
        assert_eq!(som.classify(&[10.0]).2, Some("b"));
        // The nearest node among the kept ones: leaving "e" out, 5.0 goes to a neighbour.
        let (j, _) = som.bmu_among(&[5.0], |j| som.labels[j] != "e").unwrap();
        assert_ne!(som.labels[j], "e");
        assert_eq!(
            som.bmu_among(&[5.0], |_| true).map(|b| b.0),
            Some(som.bmu(&[5.0]).0)
        );
        assert_eq!(som.bmu_among(&[5.0], |_| false), None);
    }

    #[test]
    fn bad_parameters_are_refused_once() {
        assert!(SomParams {
            rows: 0,
            ..Default::default()
        }
        .check()
        .is_err());
        assert!(SomParams {
            stages: vec![TrainingStage {
                alpha: 0.0,
                sigma: 1.0,
                iterations: 5
            }],
            ..Default::default()
        }
        .check()
        .is_err());
        assert!(SomParams::default().check().is_ok());
    }

    #[test]
    fn uniform_square_unfolds() {
        // Thesis Fig. 5.7: 2-D inputs uniform on [0,10]², 10×10 map.
        let mut rng = Rng::new(1);
        let data: Vec<f64> = (0..2000).map(|_| rng.range(0.0, 10.0)).collect();
        let som = Som::fit(&SomParams::default().check().unwrap(), m(&data, 2)).unwrap();
        let te = som.log.as_ref().unwrap().topographic_error;
        assert!(te < 0.05, "topographic error {te}");
        // Neighbouring weights roughly evenly spaced: spacing ≈ 10/10 = 1, spread small.
        let mut d = Vec::new();
        for r in 0..10 {
            for c in 0..9 {
                d.push(sq_dist(som.node(r * 10 + c), som.node(r * 10 + c + 1)).sqrt());
            }
        }
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let sd = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
        assert!(
            (0.7..1.3).contains(&mean) && sd / mean < 0.35,
            "spacing {mean} ± {sd}"
        );
    }

    #[test]
    fn separated_clusters_classify_perfectly_and_qe_falls() {
        let mut rng = Rng::new(2);
        let centres: Vec<Vec<f64>> = (0..3)
            .map(|_| (0..20).map(|_| 5.0 * rng.normal()).collect())
            .collect();
        let (mut data, mut labels) = (Vec::new(), Vec::new());
        for i in 0..300 {
            let k = i % 3;
            data.extend(centres[k].iter().map(|c| c + 0.3 * rng.normal()));
            labels.push(format!("class{k}"));
        }
        let random = SomParams {
            init: Init::Random,
            ..Default::default()
        }
        .check()
        .unwrap();
        let qe = Som::fit(&random, m(&data, 20)).unwrap().log.unwrap().qe;
        assert!(qe[0] > qe[1] && qe[1] > qe[2], "QE does not fall: {qe:?}");
        let mut som = Som::fit(&SomParams::default().check().unwrap(), m(&data, 20)).unwrap();
        som.label_nodes(m(&data, 20), &labels).unwrap();
        let right = data
            .chunks(20)
            .zip(&labels)
            .filter(|(x, l)| som.classify(x).2 == Some(l.as_str()))
            .count();
        assert_eq!(right, 300);
        // Bit-for-bit reproducible with the seed.
        let again = Som::fit(&SomParams::default().check().unwrap(), m(&data, 20)).unwrap();
        assert_eq!(again.weights, som.weights);
        // A SOM_PAK codebook written and read back classifies the same.
        let back = Som::from_cod(&som.to_cod()).unwrap();
        assert_eq!(back.labels, som.labels);
        assert!(data
            .chunks(20)
            .all(|x| back.classify(x).0 == som.classify(x).0));
        // The U-matrix shows the cluster borders: its maximum is well above its median.
        let mut u = som.u_matrix().into_raw_vec_and_offset().0;
        u.sort_by(f64::total_cmp);
        assert!(u[u.len() - 1] > 3.0 * u[u.len() / 2]);
    }
}
