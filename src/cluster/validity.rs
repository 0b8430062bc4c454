//! Cluster validity indices, as scikit-learn computes them (`davies_bouldin_score`,
//! `calinski_harabasz_score`, `silhouette_score`): the tests compare to 1e-9.
//!
//! Clusters are the labels present (an empty cluster does not count), as scikit-learn's
//! label encoding does.

use ndarray::{Array2, ArrayView2};
use rayon::prelude::*;

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// Labels renumbered 0..m over the labels present, and m.
fn encode(labels: &[usize]) -> (Vec<usize>, usize) {
    let mut present: Vec<usize> = labels.to_vec();
    present.sort_unstable();
    present.dedup();
    let idx = |l: usize| present.binary_search(&l).expect("present");
    (labels.iter().map(|&l| idx(l)).collect(), present.len())
}

/// Per cluster: size and mean row.
fn centroids(x: ArrayView2<f64>, labels: &[usize], m: usize) -> (Vec<usize>, Array2<f64>) {
    let mut c = Array2::<f64>::zeros((m, x.ncols()));
    let mut n = vec![0usize; m];
    for (i, &l) in labels.iter().enumerate() {
        n[l] += 1;
        let mut r = c.row_mut(l);
        r += &x.row(i);
    }
    for (j, &k) in n.iter().enumerate() {
        c.row_mut(j).mapv_inplace(|v| v / k as f64);
    }
    (n, c)
}

/// Σ squared distance of each row to its cluster's mean.
pub fn inertia(x: ArrayView2<f64>, labels: &[usize]) -> f64 {
    let (lab, m) = encode(labels);
    let (_, c) = centroids(x, &lab, m);
    x.rows()
        .into_iter()
        .zip(&lab)
        .map(|(r, &l)| {
            r.iter()
                .zip(c.row(l))
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
        })
        .sum()
}

/// Davies–Bouldin: the mean over clusters of the largest (sᵢ + sⱼ) / dᵢⱼ, s the mean
/// distance of a cluster's rows to its centroid, d between centroids (lower is better).
/// `None` with fewer than 2 clusters.
pub fn davies_bouldin(x: ArrayView2<f64>, labels: &[usize]) -> Option<f64> {
    let (lab, m) = encode(labels);
    if m < 2 {
        return None;
    }
    let (n, c) = centroids(x, &lab, m);
    let mut intra = vec![0.0; m];
    for (r, &l) in x.rows().into_iter().zip(&lab) {
        intra[l] += dist(
            r.as_slice().expect("standard layout"),
            c.row(l).as_slice().unwrap(),
        );
    }
    for (s, k) in intra.iter_mut().zip(&n) {
        *s /= *k as f64;
    }
    let cd = |i: usize, j: usize| dist(c.row(i).as_slice().unwrap(), c.row(j).as_slice().unwrap());
    if intra.iter().all(|s| *s == 0.0) {
        return Some(0.0);
    }
    let mut total = 0.0;
    for i in 0..m {
        let mut worst: f64 = 0.0;
        for j in 0..m {
            if i != j {
                let d = cd(i, j);
                // scikit-learn: a zero centroid distance gives inf, then set to 0.
                let v = (intra[i] + intra[j]) / d;
                worst = worst.max(if v.is_finite() { v } else { 0.0 });
            }
        }
        total += worst;
    }
    Some(total / m as f64)
}

/// Calinski–Harabasz: between- over within-cluster dispersion, each per its degrees of
/// freedom (higher is better). `None` with fewer than 2 clusters or as many as rows.
pub fn calinski_harabasz(x: ArrayView2<f64>, labels: &[usize]) -> Option<f64> {
    let (lab, m) = encode(labels);
    let n = x.nrows();
    if m < 2 || m >= n {
        return None;
    }
    let (cnt, c) = centroids(x, &lab, m);
    let mean = x.mean_axis(ndarray::Axis(0))?;
    let extra: f64 = (0..m)
        .map(|j| {
            cnt[j] as f64
                * c.row(j)
                    .iter()
                    .zip(&mean)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
        })
        .sum();
    let intra = inertia(x, &lab);
    Some(if intra == 0.0 {
        1.0
    } else {
        extra * (n - m) as f64 / (intra * (m - 1) as f64)
    })
}

/// The mean silhouette of each partition of the same rows, in one pass over the row pairs
/// (the distances do not depend on the partition): for a row, a = mean distance to the
/// other rows of its cluster, b = the least mean distance to another cluster's rows,
/// s = (b − a) / max(a, b), 0 for a row alone in its cluster. `None` for a partition of
/// fewer than 2 or more than n − 1 clusters. O(n²·dim): the caller bounds n.
pub fn silhouettes(x: ArrayView2<f64>, partitions: &[Vec<usize>]) -> Vec<Option<f64>> {
    let n = x.nrows();
    let enc: Vec<(Vec<usize>, usize)> = partitions.iter().map(|p| encode(p)).collect();
    let sizes: Vec<Vec<usize>> = enc
        .iter()
        .map(|(l, m)| {
            let mut s = vec![0usize; *m];
            l.iter().for_each(|&v| s[v] += 1);
            s
        })
        .collect();
    let x = x.as_standard_layout();
    let d = x.ncols();
    let xs = x.as_slice().expect("standard layout");
    // Per partition: Σ s(i) over the rows.
    let sums: Vec<f64> = (0..n)
        .into_par_iter()
        .map_init(
            || enc.iter().map(|(_, m)| vec![0.0; *m]).collect::<Vec<_>>(),
            |acc, i| {
                acc.iter_mut()
                    .for_each(|a| a.iter_mut().for_each(|v| *v = 0.0));
                let xi = &xs[i * d..(i + 1) * d];
                for j in 0..n {
                    if j == i {
                        continue;
                    }
                    let dij = dist(xi, &xs[j * d..(j + 1) * d]);
                    for (a, (l, _)) in acc.iter_mut().zip(&enc) {
                        a[l[j]] += dij;
                    }
                }
                let mut out = vec![0.0; enc.len()];
                for (p, ((l, m), a)) in enc.iter().zip(acc.iter()).enumerate() {
                    let own = l[i];
                    let sz = sizes[p][own];
                    if sz <= 1 || *m < 2 {
                        continue;
                    }
                    let a_i = a[own] / (sz - 1) as f64;
                    let b_i = (0..*m)
                        .filter(|&c| c != own)
                        .map(|c| a[c] / sizes[p][c] as f64)
                        .fold(f64::INFINITY, f64::min);
                    let den = a_i.max(b_i);
                    out[p] = if den > 0.0 { (b_i - a_i) / den } else { 0.0 };
                }
                out
            },
        )
        // Each row's silhouettes in row order, summed in that order: the same bits whatever
        // the threads (a parallel reduce adds in the order the work was split).
        .collect::<Vec<Vec<f64>>>()
        .into_iter()
        .fold(vec![0.0; enc.len()], |mut a, b| {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
            a
        });
    enc.iter()
        .zip(sums)
        .map(|((_, m), s)| (*m >= 2 && *m < n).then(|| s / n as f64))
        .collect()
}

/// The silhouette of one partition.
pub fn silhouette(x: ArrayView2<f64>, labels: &[usize]) -> Option<f64> {
    silhouettes(x, &[labels.to_vec()])[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Worked by hand on four points of a line: {0, 1} and {10, 12}.
    #[test]
    fn indices_by_hand() {
        let x = Array2::from_shape_vec((4, 1), vec![0.0, 1.0, 10.0, 12.0]).unwrap();
        let l = [0, 0, 1, 1];
        // Centroids 0.5 and 11; s = 0.5 and 1; d = 10.5: DB = (1.5 / 10.5) both ways.
        assert!((davies_bouldin(x.view(), &l).unwrap() - 1.5 / 10.5).abs() < 1e-15);
        // Within: 0.25·2 + 1·2 = 2.5; between: 2·(5.25)² + 2·(5.25)² = 110.25 (mean 5.75);
        // CH = 110.25·(4 − 2) / (2.5·1) = 88.2.
        assert!((calinski_harabasz(x.view(), &l).unwrap() - 88.2).abs() < 1e-12);
        assert!((inertia(x.view(), &l) - 2.5).abs() < 1e-15);
        // Silhouettes: point 0: a = 1, b = (10 + 12)/2 = 11 → 10/11; point 1: a = 1,
        // b = (9 + 11)/2 = 10 → 0.9; point 10: a = 2, b = (10 + 9)/2 = 9.5 → 7.5/9.5;
        // point 12: a = 2, b = (12 + 11)/2 = 11.5 → 9.5/11.5.
        let want = (10.0 / 11.0 + 0.9 + 7.5 / 9.5 + 9.5 / 11.5) / 4.0;
        assert!((silhouette(x.view(), &l).unwrap() - want).abs() < 1e-15);
        // Labels need not be 0-based or dense; one cluster has no index.
        assert_eq!(
            silhouette(x.view(), &[5, 5, 9, 9]),
            silhouette(x.view(), &l)
        );
        assert_eq!(davies_bouldin(x.view(), &[1, 1, 1, 1]), None);
    }
}
