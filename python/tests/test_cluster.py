"""aepipe's clustering against scikit-learn (issue 39, part 3): the validity indices on the
same matrix and partition to 1e-9, k-means no worse than KMeans at the same restarts, the
Gaussian mixture's log-likelihood no worse than GaussianMixture's from the same start, and
`aepipe.cluster` on a features table equal to `aepipe cluster`'s."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aepipe
from conftest import aepipe_cli, need_module


def blobs(seed: int, n: int = 600, spread: float = 1.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centres = rng.normal(0, 4, (4, 5))
    return np.vstack([c + spread * rng.normal(size=(n // 4, 5)) for c in centres])


def test_validity_indices_equal_scikit_learns() -> None:
    m = need_module("sklearn.metrics")
    rng = np.random.default_rng(1)
    x = blobs(1, spread=2.5)
    for labels in (rng.integers(0, 3, len(x)), np.repeat(np.arange(4), len(x) // 4), rng.integers(0, 7, len(x))):
        got = aepipe.validity_indices(x, labels)
        want = {
            "davies_bouldin": m.davies_bouldin_score(x, labels),
            "silhouette": m.silhouette_score(x, labels),
            "calinski_harabasz": m.calinski_harabasz_score(x, labels),
        }
        for k, v in want.items():
            assert abs(got[k] - v) <= 1e-9 * max(1.0, abs(v)), (k, got[k], v)


def test_kmeans_is_no_worse_than_scikit_learns_at_the_same_restarts() -> None:
    cl = need_module("sklearn.cluster")
    # Separated blobs: both find the same optimum.
    x = blobs(2)
    frame = pl.DataFrame({f"f{i}": x[:, i] for i in range(5)})
    z = (x - x.mean(0)) / x.std(0)
    out, v = aepipe.cluster(frame, k=(2, 6), columns=frame.columns, validity=True)
    for row in v.iter_rows(named=True):
        sk = cl.KMeans(row["k"], n_init=10, random_state=0).fit(z).inertia_
        assert row["inertia"] <= sk * (1 + 1e-9), (row["k"], row["inertia"], sk)
    assert v.filter(pl.col("chosen"))["k"].to_list() == [4]
    # Overlapping clouds, where restarts matter: the mean over five seeds of each k.
    y = blobs(3, n=800, spread=3.5)
    fy = pl.DataFrame({f"f{i}": y[:, i] for i in range(5)})
    zy = (y - y.mean(0)) / y.std(0)
    ours = np.mean([aepipe.cluster(fy, k=(2, 8), columns=fy.columns, seed=s, validity=True)[1]["inertia"].to_numpy() for s in range(5)], axis=0)
    sk = np.mean([[cl.KMeans(k, n_init=10, random_state=s).fit(zy).inertia_ for k in range(2, 9)] for s in range(5)], axis=0)
    assert (ours <= sk * 1.01).all(), (ours, sk)


def test_mixture_likelihood_is_no_worse_than_scikit_learns_from_the_same_start() -> None:
    mix = need_module("sklearn.mixture")
    x = blobs(4, spread=1.5)
    frame = pl.DataFrame({f"f{i}": x[:, i] for i in range(5)})
    z = (x - x.mean(0)) / x.std(0)
    _, v = aepipe.cluster(frame, method="gmm", k=(2, 5), columns=frame.columns, seed=7, validity=True)
    for row in v.iter_rows(named=True):
        k = row["k"]
        # The start aepipe's mixture took: its k-means at the same k and seed.
        start = aepipe.cluster(frame, k=k, columns=frame.columns, seed=7)["cluster"].to_numpy()
        w = np.array([np.mean(start == c) for c in range(k)])
        mu = np.array([z[start == c].mean(0) for c in range(k)])
        prec = []
        for c in range(k):
            d = z[start == c] - mu[c]
            prec.append(np.linalg.inv(d.T @ d / len(d) + 1e-6 * np.eye(5)))
        g = mix.GaussianMixture(
            k, covariance_type="full", weights_init=w, means_init=mu, precisions_init=np.array(prec),
            reg_covar=1e-6, tol=1e-3, max_iter=100,
        ).fit(z)
        assert row["log_likelihood"] >= g.score(z) - 1e-9, (k, row["log_likelihood"], g.score(z))
        assert abs(row["bic"] - g.bic(z)) <= 1e-6 * abs(g.bic(z)) + 1e-6, (k, row["bic"], g.bic(z))


def test_the_python_clusters_are_the_command_lines(tmp_path: Path, labelled_features) -> None:
    feats, _ = labelled_features
    for method in ("kmeans", "gmm", "som-kmeans"):
        out = tmp_path / method
        aepipe_cli("cluster", feats, "--out", out, "--method", method, "--k", "2..4", "--seed", "3")
        cli = pl.read_parquet(out / "clusters.parquet")
        py = aepipe.cluster(feats, method=method, k=(2, 4), seed=3).select("experiment", "channel", "hit", "cluster", "cluster_distance", "cluster_probability")
        j = cli.join(py, on=["experiment", "channel", "hit"], suffix="_py")
        assert j.height == cli.height > 0
        assert (j["cluster"] == j["cluster_py"]).all(), method
        assert np.allclose(j["cluster_distance"], j["cluster_distance_py"], rtol=1e-12)
        validity = pl.read_parquet(out / "validity.parquet")
        assert validity["k"].to_list() == [2, 3, 4] and validity["chosen"].sum() == 1
    with pytest.raises(aepipe.ClusterError, match="k_min"):
        aepipe.cluster(pl.read_parquet(feats), k=(1, 3))
