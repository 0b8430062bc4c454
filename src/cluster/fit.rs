//! Fitting every k of the range on the standardised rows, the validity indices of each
//! partition, the choice of k, and a stable numbering of the chosen clusters.

use super::gmm::{gmm, Gmm, GmmParams};
use super::kmeans::{kmeans, nearest, KMeansParams};
use super::settings::{Choose, Method, ValidCluster};
use super::validity;
use super::ClusterError;
use crate::som::{Som, SomParams};
use ndarray::{Array2, ArrayView2};

/// One line of `validity.parquet`: a method's partition at one k.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidityRow {
    pub method: Method,
    pub k: usize,
    pub davies_bouldin: Option<f64>,
    pub silhouette: Option<f64>,
    /// Rows the silhouette was computed on (all fit rows, or a seeded sample).
    pub silhouette_rows: usize,
    pub calinski_harabasz: Option<f64>,
    /// Gaussian mixtures only.
    pub bic: Option<f64>,
    pub log_likelihood: Option<f64>,
    /// Σ squared distance of each row to its cluster's mean (z units).
    pub inertia: f64,
    /// Rows the partition was fitted on.
    pub rows: usize,
    pub chosen: bool,
}

/// How a row is given its cluster.
#[derive(Debug, Clone)]
pub enum Assigner {
    /// The nearest centre (k-means).
    Centers(Array2<f64>),
    /// The most probable component.
    Mixture(Gmm),
    /// The cluster of the row's best-matching node.
    Map { som: Som, node_cluster: Vec<usize> },
}

/// The chosen clustering: what assigns a standardised row, and the numbering.
#[derive(Debug, Clone)]
pub struct ClusterModel {
    pub method: Method,
    pub k: usize,
    pub assigner: Assigner,
    /// The fit's cluster index → the published number (0 = lowest ordering key).
    pub number: Vec<usize>,
    /// Per published cluster: the mean of its fit rows (z units) and its size.
    pub centroids: Vec<Vec<f64>>,
    pub sizes: Vec<usize>,
}

impl ClusterModel {
    /// The published cluster of a standardised row, its distance to that cluster's
    /// centroid (z units), and for a mixture the posterior probability of the component.
    pub fn assign(&self, z: &[f64], post: &mut Vec<f64>) -> (usize, f64, Option<f64>) {
        let (raw, prob) = match &self.assigner {
            Assigner::Centers(c) => (nearest(c, z).0, None),
            Assigner::Mixture(g) => {
                post.resize(g.weights.len(), 0.0);
                g.posterior(z, post);
                let (j, p) = post
                    .iter()
                    .enumerate()
                    .fold(
                        (0, f64::NEG_INFINITY),
                        |b, (j, &v)| if v > b.1 { (j, v) } else { b },
                    );
                (j, Some(p))
            }
            Assigner::Map { som, node_cluster } => (node_cluster[som.bmu(z).0], None),
        };
        let c = self.number[raw];
        let d = z
            .iter()
            .zip(&self.centroids[c])
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        (c, d, prob)
    }
}

/// The fit: the chosen model, every k's validity, and the fit rows' published clusters.
#[derive(Debug, Clone)]
pub struct Fitted {
    pub model: ClusterModel,
    pub validity: Vec<ValidityRow>,
    pub labels: Vec<usize>,
}

/// One k's partition and what assigns new rows to it.
struct Candidate {
    labels: Vec<usize>,
    assigner: Assigner,
    bic: Option<f64>,
    log_likelihood: Option<f64>,
}

/// Fit `cfg.method` for every k of its range on standardised rows `z`; choose k by
/// `cfg.choose`; number the chosen clusters by rising mean of `key` (one value per row, e.g.
/// the raw peak frequency; ties by size, larger first).
pub fn fit_matrix(
    z: ArrayView2<f64>,
    key: &[f64],
    cfg: &ValidCluster,
) -> Result<Fitted, ClusterError> {
    let n = z.nrows();
    if n < cfg.k_max.max(2) || key.len() != n {
        return Err(ClusterError::Data(format!(
            "{n} usable rows cannot be split into up to {} clusters",
            cfg.k_max
        )));
    }
    let z = z.as_standard_layout();
    // The map of som-kmeans is trained once; each k clusters its codebook.
    let map = match cfg.method {
        Method::SomKmeans => {
            let params = SomParams {
                rows: cfg.som_rows,
                cols: cfg.som_cols,
                seed: cfg.seed,
                ..SomParams::default()
            }
            .check()?;
            let som = Som::fit(&params, z.view())?;
            let bmu: Vec<usize> = z
                .rows()
                .into_iter()
                .map(|r| som.bmu(r.as_slice().expect("standard layout")).0)
                .collect();
            Some((som, bmu))
        }
        _ => None,
    };
    let mut cands = candidates(z.view(), map.as_ref(), cfg)?;
    // Rows the silhouette is computed on: all, or a seeded sample of silhouette_rows.
    let sample =
        crate::util::Rng::new(cfg.seed ^ 0x5111_0e77e).sample_sorted(n, cfg.silhouette_rows);
    let zs = z.select(ndarray::Axis(0), &sample);
    let parts: Vec<Vec<usize>> = cands
        .iter()
        .map(|(_, c)| sample.iter().map(|&i| c.labels[i]).collect())
        .collect();
    let sil = validity::silhouettes(zs.view(), &parts);
    let mut rows: Vec<ValidityRow> = cands
        .iter()
        .zip(sil)
        .map(|((k, c), s)| ValidityRow {
            method: cfg.method,
            k: *k,
            davies_bouldin: validity::davies_bouldin(z.view(), &c.labels),
            silhouette: s,
            silhouette_rows: sample.len(),
            calinski_harabasz: validity::calinski_harabasz(z.view(), &c.labels),
            bic: c.bic,
            log_likelihood: c.log_likelihood,
            inertia: validity::inertia(z.view(), &c.labels),
            rows: n,
            chosen: false,
        })
        .collect();
    let pick = choose(&rows, cfg.choose).ok_or_else(|| {
        ClusterError::Data(format!(
            "no k of {}..{} has a {} index",
            cfg.k_min,
            cfg.k_max,
            cfg.choose.as_str()
        ))
    })?;
    rows[pick].chosen = true;
    let (k, c) = cands.swap_remove(pick);
    let (number, centroids, sizes) = numbering(z.view(), &c.labels, k, key);
    let labels = c.labels.iter().map(|&l| number[l]).collect();
    Ok(Fitted {
        model: ClusterModel {
            method: cfg.method,
            k,
            assigner: c.assigner,
            number,
            centroids,
            sizes,
        },
        validity: rows,
        labels,
    })
}

/// Every k's partition of `z` by `cfg.method` (the map of som-kmeans trained once, given).
fn candidates(
    z: ArrayView2<f64>,
    map: Option<&(Som, Vec<usize>)>,
    cfg: &ValidCluster,
) -> Result<Vec<(usize, Candidate)>, ClusterError> {
    let mut cands: Vec<(usize, Candidate)> = Vec::new();
    for k in cfg.k_min..=cfg.k_max {
        let km = |x: ArrayView2<f64>| {
            kmeans(
                x,
                KMeansParams {
                    k,
                    n_init: cfg.n_init,
                    max_iter: 300,
                    tol: 1e-4,
                    seed: cfg.seed,
                },
            )
        };
        let c = match (map, cfg.method) {
            (Some((som, bmu)), _) => {
                let book = Array2::from_shape_vec((som.nodes(), som.dim), som.weights.clone())
                    .map_err(|e| ClusterError::Data(e.to_string()))?;
                let fit = km(book.view())?;
                Candidate {
                    labels: bmu.iter().map(|&b| fit.labels[b]).collect(),
                    assigner: Assigner::Map {
                        som: som.clone(),
                        node_cluster: fit.labels,
                    },
                    bic: None,
                    log_likelihood: None,
                }
            }
            (None, Method::Gmm) => {
                let start = km(z)?;
                let g = gmm(z.view(), &start.labels, k, GmmParams::default())?;
                Candidate {
                    labels: g.labels,
                    bic: Some(g.bic),
                    log_likelihood: Some(g.log_likelihood),
                    assigner: Assigner::Mixture(g.gmm),
                }
            }
            (None, _) => {
                let fit = km(z)?;
                Candidate {
                    labels: fit.labels,
                    assigner: Assigner::Centers(fit.centers),
                    bic: None,
                    log_likelihood: None,
                }
            }
        };
        cands.push((k, c));
    }
    Ok(cands)
}

/// The index of the chosen row: least DB or BIC, largest silhouette or CH; ties to the
/// smaller k.
fn choose(rows: &[ValidityRow], rule: Choose) -> Option<usize> {
    let score = |r: &ValidityRow| -> Option<f64> {
        match rule {
            Choose::DaviesBouldin => r.davies_bouldin,
            Choose::Silhouette => r.silhouette.map(|v| -v),
            Choose::CalinskiHarabasz => r.calinski_harabasz.map(|v| -v),
            Choose::Bic => r.bic,
        }
    };
    rows.iter()
        .enumerate()
        .filter_map(|(i, r)| score(r).filter(|v| v.is_finite()).map(|v| (i, v)))
        .fold(None, |b: Option<(usize, f64)>, (i, v)| match b {
            Some((_, bv)) if bv <= v => b,
            _ => Some((i, v)),
        })
        .map(|(i, _)| i)
}

/// Publish clusters by rising mean key (larger first on ties, then the fit's order; a
/// cluster without rows last): fit index → number, and per number the centroid and size.
fn numbering(
    z: ArrayView2<f64>,
    labels: &[usize],
    k: usize,
    key: &[f64],
) -> (Vec<usize>, Vec<Vec<f64>>, Vec<usize>) {
    let d = z.ncols();
    let mut sums = vec![vec![0.0; d]; k];
    let mut ks = vec![0.0; k];
    let mut n = vec![0usize; k];
    for (i, &l) in labels.iter().enumerate() {
        n[l] += 1;
        ks[l] += key[i];
        sums[l].iter_mut().zip(z.row(i)).for_each(|(a, b)| *a += b);
    }
    let mean_key = |c: usize| {
        if n[c] == 0 {
            f64::INFINITY
        } else {
            ks[c] / n[c] as f64
        }
    };
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&a, &b| {
        mean_key(a)
            .total_cmp(&mean_key(b))
            .then(n[b].cmp(&n[a]))
            .then(a.cmp(&b))
    });
    let mut number = vec![0; k];
    for (pos, &c) in order.iter().enumerate() {
        number[c] = pos;
    }
    let centroids = order
        .iter()
        .map(|&c| sums[c].iter().map(|s| s / n[c].max(1) as f64).collect())
        .collect();
    let sizes = order.iter().map(|&c| n[c]).collect();
    (number, centroids, sizes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::settings::ClusterConfig;

    /// Three separated blobs of different key: every method finds k = 3 by Davies–Bouldin,
    /// and the clusters are numbered by rising key whatever the fit's order.
    #[test]
    fn three_blobs_give_three_clusters_numbered_by_key() {
        let mut rng = crate::util::Rng::new(9);
        let c = [[0.0, 0.0], [6.0, 0.0], [0.0, 6.0]];
        let z = Array2::from_shape_fn((240, 2), |(i, j)| c[i / 80][j] + 0.3 * rng.normal());
        // Keys: blob 2 lowest, then blob 0, then blob 1.
        let key: Vec<f64> = (0..240).map(|i| [2.0, 3.0, 1.0][i / 80]).collect();
        for method in [Method::Kmeans, Method::Gmm, Method::SomKmeans] {
            let cfg = ClusterConfig {
                method,
                k_max: 5,
                som_rows: 5,
                som_cols: 5,
                ..Default::default()
            }
            .check()
            .unwrap();
            let f = fit_matrix(z.view(), &key, &cfg).unwrap();
            assert_eq!(f.model.k, 3, "{method:?}: {:?}", f.validity);
            assert_eq!(f.validity.len(), 4);
            assert_eq!(f.validity.iter().filter(|r| r.chosen).count(), 1);
            assert_eq!(
                (f.labels[0], f.labels[80], f.labels[160]),
                (1, 2, 0),
                "{method:?}"
            );
            let mut post = Vec::new();
            for i in [5, 85, 165] {
                let r = z.row(i).to_vec();
                assert_eq!(f.model.assign(&r, &mut post).0, f.labels[i]);
            }
        }
    }
}
