//! k-means: greedy k-means++ seeding (Arthur & Vassilvitskii 2007, with the local trials of
//! scikit-learn's `_kmeans_plusplus`), Lloyd iterations, `n_init` restarts keeping the
//! smallest inertia.
//!
//! Convergence is scikit-learn's: the labels stop changing, or the summed squared shift of
//! the centres falls to `tol` × the mean per-column variance of the data. An empty cluster
//! takes the row farthest from its centre. The final labels and inertia are those of the
//! final centres.

use super::ClusterError;
use crate::util::Rng;
use ndarray::{Array2, ArrayView2};
use rayon::prelude::*;

/// One k-means partition.
#[derive(Debug, Clone)]
pub struct KMeansFit {
    /// k × dim.
    pub centers: Array2<f64>,
    pub labels: Vec<usize>,
    /// Σ squared distance of each row to its centre.
    pub inertia: f64,
    pub iterations: usize,
}

/// Settings of one k-means fit.
#[derive(Debug, Clone, Copy)]
pub struct KMeansParams {
    pub k: usize,
    pub n_init: usize,
    pub max_iter: usize,
    /// Relative tolerance (scikit-learn's `tol`, 1e-4).
    pub tol: f64,
    pub seed: u64,
}

fn sq(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Index and squared distance of the nearest centre of `x`.
pub fn nearest(centers: &Array2<f64>, x: &[f64]) -> (usize, f64) {
    let mut best = (0, f64::INFINITY);
    for (j, c) in centers.rows().into_iter().enumerate() {
        let d = sq(x, c.as_slice().expect("standard layout"));
        if d < best.1 {
            best = (j, d);
        }
    }
    best
}

/// Fit k-means to the rows of `x` (standard layout), `n_init` times from seeds drawn from
/// `seed`; the fit of least inertia.
pub fn kmeans(x: ArrayView2<f64>, p: KMeansParams) -> Result<KMeansFit, ClusterError> {
    let n = x.nrows();
    if p.k == 0 || p.k > n {
        return Err(ClusterError::Data(format!(
            "k = {} clusters of {n} rows",
            p.k
        )));
    }
    // A view of the caller's rows (copied only if they are not in standard layout).
    let x = x.as_standard_layout();
    let x = x.view();
    let d = x.ncols();
    let mean_var = if n > 0 && d > 0 {
        x.var_axis(ndarray::Axis(0), 0.0).mean().unwrap_or(0.0)
    } else {
        0.0
    };
    let tol = p.tol * mean_var;
    let mut rng = Rng::new(p.seed);
    let mut best: Option<KMeansFit> = None;
    for _ in 0..p.n_init.max(1) {
        let seed = rng.next_u64();
        let init = plus_plus(x, p.k, seed);
        let fit = lloyd(x, init, p.max_iter, tol);
        if best.as_ref().is_none_or(|b| fit.inertia < b.inertia) {
            best = Some(fit);
        }
    }
    Ok(best.expect("n_init ≥ 1"))
}

fn row<'a>(x: ArrayView2<'a, f64>, i: usize) -> &'a [f64] {
    let d = x.ncols();
    &x.to_slice().expect("standard layout")[i * d..(i + 1) * d]
}

/// Greedy k-means++: each new centre is the best (least potential) of 2 + ⌊ln k⌋
/// candidates drawn with probability ∝ squared distance to the nearest centre so far.
pub fn plus_plus(x: ArrayView2<f64>, k: usize, seed: u64) -> Array2<f64> {
    let (n, d) = x.dim();
    let mut rng = Rng::new(seed);
    let trials = 2 + (k as f64).ln().floor() as usize;
    let mut centers = Array2::<f64>::zeros((k, d));
    let first = (rng.next_u64() % n as u64) as usize;
    centers.row_mut(0).assign(&x.row(first));
    let mut closest: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| sq(row(x, i), row(x, first)))
        .collect();
    for c in 1..k {
        let pot: f64 = closest.iter().sum();
        let mut cum = Vec::with_capacity(n);
        let mut acc = 0.0;
        for v in &closest {
            acc += v;
            cum.push(acc);
        }
        let mut best: Option<(usize, f64, Vec<f64>)> = None;
        for _ in 0..trials {
            let r = rng.uniform() * pot;
            // A potential of 0 (every row on a centre) draws uniformly.
            let cand = if pot > 0.0 {
                cum.partition_point(|&v| v <= r).min(n - 1)
            } else {
                (rng.next_u64() % n as u64) as usize
            };
            let next: Vec<f64> = (0..n)
                .into_par_iter()
                .map(|i| closest[i].min(sq(row(x, i), row(x, cand))))
                .collect();
            let p: f64 = next.iter().sum();
            if best.as_ref().is_none_or(|b| p < b.1) {
                best = Some((cand, p, next));
            }
        }
        let (cand, _, next) = best.expect("trials ≥ 2");
        centers.row_mut(c).assign(&x.row(cand));
        closest = next;
    }
    centers
}

/// Each row's nearest centre and squared distance.
fn assign(x: ArrayView2<f64>, centers: &Array2<f64>) -> Vec<(usize, f64)> {
    (0..x.nrows())
        .into_par_iter()
        .map(|i| nearest(centers, row(x, i)))
        .collect()
}

/// The means of the labelled rows; an empty cluster takes the row farthest from its own
/// centre (one row per empty cluster, each row at most once).
fn means(x: ArrayView2<f64>, lab: &[(usize, f64)], k: usize) -> Array2<f64> {
    let d = x.ncols();
    let mut sums = Array2::<f64>::zeros((k, d));
    let mut counts = vec![0usize; k];
    for (i, (j, _)) in lab.iter().enumerate() {
        counts[*j] += 1;
        let mut s = sums.row_mut(*j);
        s += &x.row(i);
    }
    let empty: Vec<usize> = (0..k).filter(|&j| counts[j] == 0).collect();
    if !empty.is_empty() {
        let mut far: Vec<usize> = (0..lab.len()).collect();
        far.sort_by(|a, b| lab[*b].1.total_cmp(&lab[*a].1));
        for (j, i) in empty.iter().zip(far) {
            sums.row_mut(*j).assign(&x.row(i));
            counts[*j] = 1;
        }
    }
    for (j, c) in counts.iter().enumerate() {
        let c = *c as f64;
        sums.row_mut(j).mapv_inplace(|v| v / c);
    }
    sums
}

fn lloyd(x: ArrayView2<f64>, mut centers: Array2<f64>, max_iter: usize, tol: f64) -> KMeansFit {
    let k = centers.nrows();
    let mut lab = assign(x, &centers);
    let mut it = 0;
    while it < max_iter.max(1) {
        it += 1;
        let next = means(x, &lab, k);
        let shift: f64 = next
            .rows()
            .into_iter()
            .zip(centers.rows())
            .map(|(a, b)| sq(a.as_slice().unwrap(), b.as_slice().unwrap()))
            .sum();
        centers = next;
        let new = assign(x, &centers);
        let same = new.iter().zip(&lab).all(|(a, b)| a.0 == b.0);
        lab = new;
        if same || shift <= tol {
            break;
        }
    }
    KMeansFit {
        inertia: lab.iter().map(|(_, d)| d).sum(),
        labels: lab.into_iter().map(|(j, _)| j).collect(),
        centers,
        iterations: it,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three tight, separated blobs: every restart finds them, the inertia is the blobs'
    /// own scatter, and the labels split by blob.
    #[test]
    fn three_blobs_are_found() {
        let mut rng = Rng::new(3);
        let c = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]];
        let x = Array2::from_shape_fn((300, 2), |(i, j)| c[i / 100][j] + 0.1 * rng.normal());
        let fit = kmeans(
            x.view(),
            KMeansParams {
                k: 3,
                n_init: 4,
                max_iter: 300,
                tol: 1e-4,
                seed: 1,
            },
        )
        .unwrap();
        for b in 0..3 {
            let l = fit.labels[b * 100];
            assert!(fit.labels[b * 100..(b + 1) * 100].iter().all(|&v| v == l));
        }
        // Inertia = Σ over blobs of the squared deviations from the blob's mean.
        let mut want = 0.0;
        for b in 0..3 {
            let blob = x.slice(ndarray::s![b * 100..(b + 1) * 100, ..]);
            let m = blob.mean_axis(ndarray::Axis(0)).unwrap();
            want += blob
                .rows()
                .into_iter()
                .map(|r| sq(r.as_slice().unwrap(), m.as_slice().unwrap()))
                .sum::<f64>();
        }
        assert!(
            (fit.inertia - want).abs() < 1e-9 * want,
            "{} vs {want}",
            fit.inertia
        );
        assert!(kmeans(
            x.view(),
            KMeansParams {
                k: 301,
                n_init: 1,
                max_iter: 10,
                tol: 1e-4,
                seed: 1
            }
        )
        .is_err());
    }
}
