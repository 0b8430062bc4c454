//! Gaussian mixtures with full covariances, by expectation–maximisation, as scikit-learn's
//! `GaussianMixture(covariance_type="full")`: started from a hard partition (k-means),
//! `reg_covar` added to each covariance's diagonal, stopped when the mean log-likelihood
//! changes by less than `tol`, then one more E-step so labels and probabilities are those
//! of the final parameters.

use super::ClusterError;
use ndarray::{Array2, ArrayView2};
use rayon::prelude::*;

/// Settings of one mixture fit.
#[derive(Debug, Clone, Copy)]
pub struct GmmParams {
    pub reg_covar: f64,
    pub tol: f64,
    pub max_iter: usize,
}

impl Default for GmmParams {
    fn default() -> Self {
        GmmParams {
            reg_covar: 1e-6,
            tol: 1e-3,
            max_iter: 100,
        }
    }
}

/// A fitted mixture.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Gmm {
    pub weights: Vec<f64>,
    /// k × dim, row-major.
    pub means: Vec<Vec<f64>>,
    /// Per component, the lower Cholesky factor of its covariance (dim × dim, row-major).
    pub chol: Vec<Vec<f64>>,
    pub dim: usize,
}

/// The fit and what it says of its rows.
#[derive(Debug, Clone)]
pub struct GmmFit {
    pub gmm: Gmm,
    /// Most probable component of each row, and its posterior probability.
    pub labels: Vec<usize>,
    pub probability: Vec<f64>,
    /// Mean log-likelihood per row under the final parameters.
    pub log_likelihood: f64,
    /// −2·n·mean log-likelihood + parameters·ln n (scikit-learn's `bic`).
    pub bic: f64,
    pub iterations: usize,
    pub converged: bool,
}

const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// Lower Cholesky factor of the symmetric `a` (d × d, row-major); `None` if not positive
/// definite.
fn cholesky(a: &[f64], d: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; d * d];
    for i in 0..d {
        for j in 0..=i {
            let mut s = a[i * d + j];
            for k in 0..j {
                s -= l[i * d + k] * l[j * d + k];
            }
            if i == j {
                if s <= 0.0 || !s.is_finite() {
                    return None;
                }
                l[i * d + i] = s.sqrt();
            } else {
                l[i * d + j] = s / l[j * d + j];
            }
        }
    }
    Some(l)
}

impl Gmm {
    /// Per component: ln weight + ln N(x | mean, cov).
    fn log_joint(&self, x: &[f64], y: &mut [f64], out: &mut [f64]) {
        let d = self.dim;
        for (c, o) in out.iter_mut().enumerate() {
            let (m, l) = (&self.means[c], &self.chol[c]);
            // Solve L y = x − m; the Mahalanobis distance is |y|², ln det cov = 2 Σ ln Lᵢᵢ.
            let mut maha = 0.0;
            let mut logdet = 0.0;
            for i in 0..d {
                let mut s = x[i] - m[i];
                for k in 0..i {
                    s -= l[i * d + k] * y[k];
                }
                y[i] = s / l[i * d + i];
                maha += y[i] * y[i];
                logdet += l[i * d + i].ln();
            }
            *o = self.weights[c].ln() - 0.5 * (d as f64 * LN_2PI + maha) - logdet;
        }
    }

    /// Posterior probabilities of each component for `x` (into `out`), and ln p(x).
    pub fn posterior(&self, x: &[f64], out: &mut [f64]) -> f64 {
        let mut y = vec![0.0; self.dim];
        self.log_joint(x, &mut y, out);
        let mx = out.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let s: f64 = out.iter().map(|v| (v - mx).exp()).sum();
        let lse = mx + s.ln();
        out.iter_mut().for_each(|v| *v = (*v - lse).exp());
        lse
    }

    /// Free parameters of a full-covariance mixture.
    pub fn n_parameters(&self) -> usize {
        let (k, d) = (self.weights.len(), self.dim);
        k * d * (d + 1) / 2 + k * d + k - 1
    }

    /// The M-step: weights, means and covariances from responsibilities (n × k).
    fn from_resp(x: ArrayView2<f64>, resp: &Array2<f64>, reg: f64) -> Result<Gmm, ClusterError> {
        let (n, d) = x.dim();
        let k = resp.ncols();
        let eps = 10.0 * f64::EPSILON;
        let nk: Vec<f64> = (0..k).map(|c| resp.column(c).sum() + eps).collect();
        // Per component: its mean and the Cholesky factor of its covariance.
        type Component = Result<(Vec<f64>, Vec<f64>), ClusterError>;
        let comps: Vec<Component> = (0..k)
            .into_par_iter()
            .map(|c| {
                let mut mean = vec![0.0; d];
                for i in 0..n {
                    let r = resp[[i, c]];
                    for (m, v) in mean.iter_mut().zip(x.row(i)) {
                        *m += r * v;
                    }
                }
                mean.iter_mut().for_each(|m| *m /= nk[c]);
                let mut cov = vec![0.0; d * d];
                let mut diff = vec![0.0; d];
                for i in 0..n {
                    let r = resp[[i, c]];
                    if r == 0.0 {
                        continue;
                    }
                    for (t, (v, m)) in diff.iter_mut().zip(x.row(i).iter().zip(&mean)) {
                        *t = v - m;
                    }
                    for a in 0..d {
                        let ra = r * diff[a];
                        for b in 0..=a {
                            cov[a * d + b] += ra * diff[b];
                        }
                    }
                }
                for a in 0..d {
                    for b in 0..=a {
                        cov[a * d + b] /= nk[c];
                        cov[b * d + a] = cov[a * d + b];
                    }
                    cov[a * d + a] += reg;
                }
                let l = cholesky(&cov, d).ok_or_else(|| {
                    ClusterError::Data(format!(
                        "component {c}'s covariance is not positive definite (a cluster of too few or collinear rows); raise reg_covar or lower k"
                    ))
                })?;
                Ok((mean, l))
            })
            .collect();
        let mut means = Vec::with_capacity(k);
        let mut chol = Vec::with_capacity(k);
        for c in comps {
            let (m, l) = c?;
            means.push(m);
            chol.push(l);
        }
        Ok(Gmm {
            weights: nk.iter().map(|v| v / n as f64).collect(),
            means,
            chol,
            dim: d,
        })
    }

    /// The E-step: responsibilities and the mean log-likelihood.
    fn e_step(&self, x: ArrayView2<f64>) -> (Array2<f64>, f64) {
        let k = self.weights.len();
        let rows: Vec<(Vec<f64>, f64)> = (0..x.nrows())
            .into_par_iter()
            .map(|i| {
                let mut p = vec![0.0; k];
                let r = x.row(i);
                let lp = match r.as_slice() {
                    Some(s) => self.posterior(s, &mut p),
                    None => self.posterior(&r.to_vec(), &mut p),
                };
                (p, lp)
            })
            .collect();
        let mut resp = Array2::<f64>::zeros((x.nrows(), k));
        let mut ll = 0.0;
        for (i, (p, lp)) in rows.into_iter().enumerate() {
            resp.row_mut(i).assign(&ndarray::Array1::from(p));
            ll += lp;
        }
        (resp, ll / x.nrows().max(1) as f64)
    }
}

/// Fit a k-component mixture to `x`, started from the hard partition `start` (labels
/// 0..k, as scikit-learn's `init_params="kmeans"` starts from its k-means labels).
pub fn gmm(
    x: ArrayView2<f64>,
    start: &[usize],
    k: usize,
    p: GmmParams,
) -> Result<GmmFit, ClusterError> {
    let n = x.nrows();
    if start.len() != n || k == 0 || start.iter().any(|&l| l >= k) {
        return Err(ClusterError::Data(format!(
            "a start of {} labels below {k} for {n} rows",
            start.len()
        )));
    }
    let mut resp = Array2::<f64>::zeros((n, k));
    for (i, &l) in start.iter().enumerate() {
        resp[[i, l]] = 1.0;
    }
    let mut model = Gmm::from_resp(x, &resp, p.reg_covar)?;
    let mut lower = f64::NEG_INFINITY;
    let (mut it, mut converged) = (0, false);
    while it < p.max_iter {
        it += 1;
        let (r, ll) = model.e_step(x);
        model = Gmm::from_resp(x, &r, p.reg_covar)?;
        let change = ll - lower;
        lower = ll;
        if change.abs() < p.tol {
            converged = true;
            break;
        }
    }
    // Final E-step: labels, probabilities and likelihood of the final parameters.
    let (resp, ll) = model.e_step(x);
    let (labels, probability): (Vec<usize>, Vec<f64>) = resp
        .rows()
        .into_iter()
        .map(|r| {
            r.iter().enumerate().fold(
                (0, f64::NEG_INFINITY),
                |b, (j, &v)| if v > b.1 { (j, v) } else { b },
            )
        })
        .unzip();
    let bic = -2.0 * ll * n as f64 + model.n_parameters() as f64 * (n as f64).ln();
    Ok(GmmFit {
        gmm: model,
        labels,
        probability,
        log_likelihood: ll,
        bic,
        iterations: it,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::Rng;

    /// One component: the fit is the sample's mean and (biased) covariance, and the mean
    /// log-likelihood is the analytic one of a Gaussian at its own MLE: −(d/2)(ln 2π + 1)
    /// − ½ ln det Σ.
    #[test]
    fn one_component_is_the_sample_gaussian() {
        let mut rng = Rng::new(5);
        let x = Array2::from_shape_fn((2000, 2), |(_, j)| {
            if j == 0 {
                2.0 * rng.normal()
            } else {
                0.5 * rng.normal() + 1.0
            }
        });
        let fit = gmm(
            x.view(),
            &vec![0; 2000],
            1,
            GmmParams {
                reg_covar: 0.0,
                ..Default::default()
            },
        )
        .unwrap();
        let m = x.mean_axis(ndarray::Axis(0)).unwrap();
        let c = x.t().dot(&x) / 2000.0
            - ndarray::arr2(&[[m[0] * m[0], m[0] * m[1]], [m[1] * m[0], m[1] * m[1]]]);
        let det = c[[0, 0]] * c[[1, 1]] - c[[0, 1]] * c[[1, 0]];
        let want = -(LN_2PI + 1.0) - 0.5 * det.ln();
        assert!(
            (fit.log_likelihood - want).abs() < 1e-9,
            "{} vs {want}",
            fit.log_likelihood
        );
        assert!((fit.gmm.means[0][0] - m[0]).abs() < 1e-12);
        // BIC: 5 parameters (3 covariance, 2 mean, 0 weights).
        assert_eq!(fit.gmm.n_parameters(), 5);
        assert!((fit.bic - (-2.0 * want * 2000.0 + 5.0 * 2000f64.ln())).abs() < 1e-6);
        assert!(fit.probability.iter().all(|p| (p - 1.0).abs() < 1e-12));
    }
}
